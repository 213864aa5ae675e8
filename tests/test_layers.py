"""The package's layers: imports only go down (import-linter's contract in pyproject.toml), and no module cycles."""

import ast
import shutil
import subprocess
import sys
from pathlib import Path

import networkx as nx

CORE = Path(__file__).resolve().parent.parent / "core"


def imports() -> nx.DiGraph:
    """Module → module edges of ``core/``, from every import statement (in functions too), read with ``ast``."""
    modules = {f.stem for f in CORE.glob("*.py") if f.stem != "__init__"}
    graph = nx.DiGraph()
    graph.add_nodes_from(modules)
    for name in modules:
        for node in ast.walk(ast.parse((CORE / f"{name}.py").read_text())):
            found = []
            if isinstance(node, ast.ImportFrom) and node.level == 1:
                found = [node.module.split(".")[0]] if node.module else [a.name for a in node.names]
            elif isinstance(node, ast.Import):
                found = [a.name.split(".")[1] for a in node.names if a.name.startswith("lagrangian.")]
            graph.add_edges_from((name, other) for other in found if other in modules and other != name)
    return graph


def test_no_module_takes_part_in_an_import_cycle():
    cycles = [sorted(c) for c in nx.strongly_connected_components(imports()) if len(c) > 1]
    assert cycles == []


def test_the_layer_contract_holds():
    command = shutil.which("lint-imports", path=str(Path(sys.executable).parent))
    assert command, "import-linter is a test dependency (pip install -e '.[test]')"
    run = subprocess.run([command, "--no-cache"], capture_output=True, text=True, cwd=CORE.parent, timeout=300)
    assert run.returncode == 0, run.stdout[-3000:]
    assert "0 broken" in run.stdout
