"""Every Python block of the README runs on its own, as written: in a fresh interpreter, from a directory holding
the repository's ``examples`` (its netlists are read by their paths, as from a clone's root) and, for the block that
registers "the module above", that module saved as ``my_plugin.py`` (as the README says)."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BLOCKS = re.findall(r"```python\n(.*?)```", (ROOT / "README.md").read_text(), re.S)
PLUGIN = next(b for b in BLOCKS if "register_component_types" in b)


def _label(block: str) -> str:
    first = next((line for line in block.splitlines() if line.strip() and not line.startswith(("import", "from"))), "")
    return re.sub(r"\W+", "_", first.split("#")[0])[:40].strip("_")


@pytest.mark.parametrize("block", BLOCKS, ids=[f"{i}-{_label(b)}" for i, b in enumerate(BLOCKS)])
def test_a_readme_block_runs_on_its_own(block, tmp_path):
    (tmp_path / "examples").symlink_to(ROOT / "examples")
    (tmp_path / "my_plugin.py").write_text(PLUGIN)
    env = {**os.environ, "MPLBACKEND": "Agg", "PYTHONPATH": str(tmp_path)}
    run = subprocess.run([sys.executable, "-c", block], capture_output=True, text=True, cwd=tmp_path, env=env,
                         timeout=600)
    assert run.returncode == 0, run.stderr[-3000:]
