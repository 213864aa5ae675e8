"""Sphinx configuration of lagrangian's documentation: the README as the guide, the API from the docstrings."""

import lagrangian

project = "lagrangian"
author = "the lagrangian maintainers"
release = version = lagrangian.__version__
extensions = ["sphinx.ext.autodoc", "sphinx.ext.autosummary", "sphinx.ext.napoleon", "sphinx.ext.viewcode",
              "myst_parser", "sphinx_gallery.gen_gallery"]

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
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
autosummary_generate = True
autodoc_default_options = {"members": True, "undoc-members": False, "show-inheritance": True}
autodoc_typehints = "description"
autodoc_member_order = "bysource"
myst_heading_anchors = 3
exclude_patterns = ["_build", "gallery/*.ipynb", "gallery/*.py"]
html_theme = "alabaster"
html_title = f"lagrangian {release}"
suppress_warnings = ["myst.xref_missing",  # the README links files of the repository, not pages
                     "ref.python",  # names exported twice (lagrangian.Model is lagrangian.model.Model)
                     "config.cache"]  # the gallery's configuration holds functions: it is not cached
