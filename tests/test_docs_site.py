"""The documentation site's sources stay true to the README and the package: every guide page includes a slice of
the README that is there, the pages together hold every section of it once, and the API reference lists names
that import (``make docs`` builds it all; these checks run without Sphinx)."""

from __future__ import annotations

import importlib
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()
GUIDE = ROOT / "docs" / "guide"
INCLUDE = re.compile(r'```\{include\} \.\./\.\./README\.md\n:start-after: "(.*?)"\n(?::end-before: "(.*?)"\n)?```')


def _slices() -> list[tuple[str, int, int]]:
    """(page, start, end) of the README each guide page includes, in the order of the guide's table of contents."""
    order = re.search(r"```\{toctree\}\n(?::[^\n]*\n)*\n?(.*?)```", (GUIDE / "index.md").read_text(), re.S).group(1).split()
    out = []
    for page in order:
        (start, end), = INCLUDE.findall((GUIDE / f"{page}.md").read_text())
        assert README.count(start) == 1, f"{page}: {start!r} is not in the README once"
        begin = README.index(start) + len(start)
        stop = README.index(end) if end else len(README)
        assert begin < stop, page
        out.append((page, begin, stop))
    return out


def test_the_guide_pages_hold_every_section_of_the_readme_once():
    slices = _slices()
    for (page, _, stop), (following, begin, _) in zip(slices, slices[1:]):
        # each page ends where the next begins: between them only the heading the next one starts after
        assert "\n" not in README[stop:begin].strip() and README[stop:begin].strip().startswith("#"), (page, following)
    assert slices[0][1] == README.index("<!-- guide: start -->") + len("<!-- guide: start -->")  # from the title on
    assert slices[-1][2] == len(README)  # to the end

@pytest.mark.parametrize("name", re.findall(r"^   (lagrangian[\w.]*)$", (ROOT / "docs" / "api.rst").read_text(), re.M))
def test_the_api_reference_lists_names_users_import(name):
    module, _, attr = name.rpartition(".")
    try:
        importlib.import_module(name)  # a public module (lagrangian.frequency)
    except ImportError:
        assert hasattr(importlib.import_module(module), attr), name
