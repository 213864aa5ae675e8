"""Sphinx configuration of lagrangian's documentation: the README as the guide, page by page; the gallery; the notes'
notebook, executed; the API by the names users import, from the docstrings."""

import shutil
from pathlib import Path

import lagrangian

HERE = Path(__file__).resolve().parent
# the notebook is rendered from a copy beside the pages, executed as the site is built (examples/notes.ipynb holds
# no outputs: the tests run it in a kernel)
shutil.copyfile(HERE.parent / "examples" / "notes.ipynb", HERE / "notes.ipynb")

project = "lagrangian"
author = "the lagrangian maintainers"
copyright = "2026, the lagrangian maintainers"
release = version = lagrangian.__version__
extensions = ["sphinx.ext.autodoc", "sphinx.ext.autosummary", "sphinx.ext.napoleon", "sphinx.ext.viewcode",
              "myst_nb", "sphinx_gallery.gen_gallery"]

#: The notes' worked examples first (Jacobi integral, spherical pendulum, steady motion, four-bar, impulses, the
#: analogies), then transducers, the frequency domain, scenes and sweeps.
GALLERY_ORDER = ["kepler.py", "spherical_steady.py", "spherical_pendulum.py", "four_bar.py", "impulses.py",
                 "demo.py", "parallel_rlc_flux.py", "two_mass_chain.py", "pendulums.py", "cart_pendulum.py",
                 "slider_crank.py", "spinning_body.py", "impacts.py", "loudspeaker.py", "dc_motor.py", "solenoid.py",
                 "electrostatic_pullin.py", "loudspeaker_impedance.py", "isolator_transmissibility.py",
                 "ladder_filter_bode.py", "coupled_tanks_modes.py", "duffing_plugin.py", "stability_map.py"]


class _Order:
    """sphinx-gallery's order of the examples: GALLERY_ORDER, then any other by name."""

    def __init__(self, src_dir):
        self.src_dir = src_dir

    def __call__(self, filename):
        return (GALLERY_ORDER.index(filename) if filename in GALLERY_ORDER else len(GALLERY_ORDER), filename)

    def __repr__(self):  # sphinx-gallery keys its cache on the repr
        return "<the notes' examples first>"


def _argv(gallery_conf, script_vars):
    """The arguments an example runs with in the gallery: its chart written next to it, where it takes --out."""
    source = script_vars["src_file"]
    with open(source, encoding="utf-8") as fh:
        takes_out = '"--out"' in fh.read()
    return ["--out", source.rsplit("/", 1)[-1][:-3] + ".png"] if takes_out else []


sphinx_gallery_conf = {
    "examples_dirs": "../examples",
    "gallery_dirs": "gallery",
    "filename_pattern": r"\.py$",  # every example runs
    "ignore_pattern": r"machine\.py$|/plugins/",
    "within_subsection_order": _Order,
    "download_all_examples": False,
    "reset_argv": _argv,
    "matplotlib_animations": False,
}
source_suffix = {".rst": "restructuredtext", ".md": "myst-nb", ".ipynb": "myst-nb"}
nb_execution_mode = "force"
nb_execution_timeout = 600
nb_execution_raise_on_error = True
templates_path = ["_templates"]
autosummary_generate = True
autodoc_default_options = {"members": True, "undoc-members": False, "show-inheritance": True}
autodoc_typehints = "description"
autodoc_member_order = "bysource"
myst_heading_anchors = 3
exclude_patterns = ["_build", "gallery/*.ipynb", "gallery/*.py", "jupyter_execute"]
html_theme = "alabaster"
html_title = f"lagrangian {release}"
suppress_warnings = ["myst.xref_missing",  # the README links files of the repository, not pages
                     "myst.header",  # a guide page's title, then the README's subsections (### under its #)
                     "ref.python",  # names exported twice (lagrangian.Model is lagrangian.model.Model)
                     "config.cache"]  # the gallery's configuration holds functions: it is not cached


def _no_gallery_no_pictures(app, config):
    """Built without running the gallery (``-D plot_gallery=0``, as the tests build the site), the guide's charts
    from the gallery are not there to read: that is expected, not a warning."""
    if str(config.plot_gallery).lower() in ("0", "false"):
        config.suppress_warnings = [*config.suppress_warnings, "image.not_readable"]


def setup(app):
    app.connect("config-inited", _no_gallery_no_pictures, priority=900)
