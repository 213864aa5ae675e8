"""The documentation site builds from the sources with no Sphinx warning (what `make docs` does, here without
running the gallery's examples: tests/test_examples.py runs them)."""

import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("sphinx")
pytest.importorskip("myst_parser")

ROOT = Path(__file__).resolve().parents[1]


def test_the_documentation_builds_without_warnings(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "sphinx", "-b", "html", "-W", "--keep-going", "-q", "-D", "plot_gallery=0", "-d",
                           str(tmp_path / "doctrees"), str(ROOT / "docs"), str(tmp_path / "html")],
                          capture_output=True, text=True, timeout=600, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    index = (tmp_path / "html" / "index.html").read_text()
    assert "Writing a plugin" in index and "API reference" in index
    api = tmp_path / "html" / "_api"
    assert (api / "lagrangian.analysis.sweep.html").exists() and (api / "lagrangian.model.html").exists()
    guide = (tmp_path / "html" / "guide.html").read_text()
    assert "Sweeps and ensembles on Dask" in guide
    gallery = (tmp_path / "html" / "gallery" / "index.html").read_text()
    order = [gallery.index(f"sphx_glr_{name}_thumb") for name in ("kepler", "spherical_steady", "four_bar", "stability_map")]
    assert order == sorted(order)  # the notes' worked examples first
