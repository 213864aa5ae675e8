"""The documentation site's sources build with no Sphinx warning: every page read (the API from the docstrings,
by public names; the README as the guide, page by page; the notes' notebook, not executed here:
tests/test_notebook.py runs it; the gallery's pages without running its examples: tests/test_examples.py runs
them) and every cross-reference resolved.  Sphinx's ``dummy`` builder does all of that and writes no HTML, a third less work
than the ``html`` builder; `make docs` builds the HTML itself, with warnings as errors too."""

import pickle
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("sphinx")
pytest.importorskip("myst_parser")
pytest.importorskip("myst_nb")

ROOT = Path(__file__).resolve().parents[1]


def test_the_documentation_builds_without_warnings(tmp_path):
    trees = tmp_path / "doctrees"
    proc = subprocess.run([sys.executable, "-m", "sphinx", "-b", "dummy", "-W", "--keep-going", "-q", "-D", "plot_gallery=0",
                           "-D", "nb_execution_mode=off",
                           "-d", str(trees), str(ROOT / "docs"), str(tmp_path / "out")],
                          capture_output=True, text=True, timeout=600, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    with open(trees / "environment.pickle", "rb") as fh:
        env = pickle.load(fh)
    titles = [env.titles[doc].astext() for doc in env.toctree_includes["index"]]
    assert {"Guide", "Writing a plugin", "API reference"} <= set(titles)
    assert any("worked examples, in a notebook" in title for title in titles)
    assert {"_api/lagrangian.sweep", "_api/lagrangian.frequency", "_api/lagrangian.Model"} <= env.found_docs
    assert not any(doc.startswith("_api/lagrangian.analysis") for doc in env.found_docs)  # public names only

    def page(doc: str) -> str:
        with open(trees / f"{doc}.doctree", "rb") as fh:
            return str(pickle.load(fh))

    assert "Sweeps and ensembles on Dask" in page("guide/sweeps")
    assert "res.animate" in page("guide/mechanisms") and "Installing outside a clone" in page("guide/setup")
    gallery = page("gallery/index")
    order = [gallery.index(f"sphx_glr_{name}_thumb") for name in ("kepler", "spherical_steady", "four_bar", "stability_map")]
    assert order == sorted(order)  # the notes' worked examples first
