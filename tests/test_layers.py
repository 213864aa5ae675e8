"""The package's layers: imports only go down (import-linter's contract in pyproject.toml), and no module cycles."""

import ast
import shutil
import subprocess
import sys
from pathlib import Path

import networkx as nx
import pytest

CORE = Path(__file__).resolve().parent.parent / "core"


def imports() -> nx.DiGraph:
    """Module → module edges of ``core/`` (by dotted name under ``lagrangian``), from every import statement (in
    functions too), read with ``ast``."""
    files = {}
    for f in CORE.rglob("*.py"):
        parts = [p for p in f.relative_to(CORE).with_suffix("").parts if p != "__init__"]
        files[".".join(["lagrangian", *parts])] = f
    graph = nx.DiGraph()
    graph.add_nodes_from(files)
    for name, f in files.items():
        package = name.split(".") if f.name == "__init__.py" else name.split(".")[:-1]
        for node in ast.walk(ast.parse(f.read_text())):
            targets = []
            if isinstance(node, ast.ImportFrom):
                base = ".".join(package[: len(package) - node.level + 1]) if node.level else ""
                module = ".".join(p for p in (base, node.module or "") if p)
                targets = [module, *(f"{module}.{a.name}" for a in node.names)]
            elif isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            graph.add_edges_from((name, t) for t in targets if t in files and t != name)
    return graph


@pytest.mark.slow
def test_no_module_takes_part_in_an_import_cycle():
    graph = imports()
    assert len(graph) > 40 and graph.number_of_edges() > 100  # it reads the package
    cycles = [sorted(c) for c in nx.strongly_connected_components(graph) if len(c) > 1]
    assert cycles == []


def test_the_layer_contract_holds():
    command = shutil.which("lint-imports", path=str(Path(sys.executable).parent))
    assert command, "import-linter is a test dependency (pip install -e '.[test]')"
    run = subprocess.run([command, "--no-cache"], capture_output=True, text=True, cwd=CORE.parent, timeout=300)
    assert run.returncode == 0, run.stdout[-3000:]
    assert "0 broken" in run.stdout


@pytest.mark.slow
def test_every_module_keeps_its_short_name():
    """``lagrangian.routh`` is ``lagrangian.analysis.routh`` — the same object, imported when first asked for — in a
    fresh process, by ``import``, ``from … import`` and attribute access."""
    code = (
        "import importlib, sys, lagrangian\n"
        "for layer, names in lagrangian.MODULES.items():\n"
        "    for name in names:\n"
        "        full = f'lagrangian.{layer}.{name}'\n"
        "        short = importlib.import_module(f'lagrangian.{name}')\n"
        "        assert short is importlib.import_module(full) is getattr(lagrangian, name), name\n"
        "        assert short.__name__ == full and short.__spec__.name == full, name\n"
        "from lagrangian.routh import reduce\n"
        "from lagrangian.analysis.routh import reduce as same\n"
        "assert reduce is same\n"
        "try:\n"
        "    import lagrangian.nonexistent\n"
        "except ModuleNotFoundError:\n"
        "    print('ok')\n"
    )
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    assert run.stdout.strip() == "ok"
