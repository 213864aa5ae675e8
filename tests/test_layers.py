"""The package's layers: imports only go down (import-linter's contract in pyproject.toml), and no module cycles."""

import ast
import os
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
    assert fresh(code).strip() == "ok"


def fresh(code: str, env: dict | None = None) -> str:
    """The standard output of ``code`` run in a fresh interpreter, which must succeed and write no error."""
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, env=env)
    assert run.returncode == 0 and not run.stderr, run.stderr
    return run.stdout


HEAVY = ("sympy", "scipy", "numpy", "networkx", "matplotlib", "pint", "dask", "PySpice", "pandas", "xarray", "mpmath")


@pytest.mark.parametrize("start", ["import lagrangian", "import lagrangian.cli as c\ntry:\n    c.main(['--help'])\n"
                                                       "except SystemExit:\n    pass"])
def test_import_and_cli_help_load_no_heavy_library_until_a_name_is_used(start):
    """SPEC 1: ``import lagrangian`` and ``lagrangian --help`` load none of the heavy libraries (SymPy, SciPy, NumPy,
    networkx, matplotlib, pint, Dask, PySpice, pandas, xarray); every public name then resolves, to the object its
    module defines."""
    code = (
        f"import sys, importlib\n{start}\n"
        f"loaded = sorted({{m.split('.')[0] for m in sys.modules}} & set({HEAVY!r}))\n"
        "import lagrangian\n"
        "for name in lagrangian.__all__:\n"
        "    assert getattr(lagrangian, name) is not None, name\n"
        "assert lagrangian.Model is importlib.import_module('lagrangian.model').Model\n"
        "assert lagrangian.load == lagrangian.Model.load and lagrangian.t.name == 't'\n"
        "print(loaded)\n"
    )
    out = fresh(code)
    assert out.strip().splitlines()[-1] == "[]", out


def test_eager_import_loads_every_public_name_at_once():
    """``EAGER_IMPORT=1`` (SPEC 1's check that the lazy names all exist) imports every module behind them."""
    code = ("import sys, lagrangian\nprint(all(f'lagrangian.{m}' in sys.modules for m in ('model', 'base.component', "
            "'analysis.fitting', 'numerics.simulation', 'plugin.registry')))")
    assert fresh(code, env={**os.environ, "EAGER_IMPORT": "1"}).strip() == "True"


SYMBOLIC_WORK = """
import json, sys
{first}
import numpy as np
import lagrangian as lg
m = lg.Model("driven")
m.add("mass", "m1", "p", m=0.3)
m.add("spring", "k1", ("ground", "p"), k=40.0)
m.add("damper", "c1", ("ground", "p"), c=0.2)
m.add("force", "F", "p", F="1.5*sin(7*t)")
res = m.simulate(2.0, initial={{"x_p": 0.01}}, velocity={{"x_p": 0.0}}, points=5, rtol=1e-10, atol=1e-13)
exact = lg.linear.simulate_exact(m, 2.0, initial={{"x_p": 0.01}}, velocity={{"x_p": 0.0}}, points=5)
tf = lg.frequency.transfer_function(m, "F", "x_p")
x = m.coordinates[0].function
print(json.dumps({{"x": res["x_p"].tolist(), "exact": exact["x_p"].tolist(), "power": float(res.quantity(
    40.0 * x ** 2 / 2)[-1]), "eq": str(m.equations[0]), "latex": m.latex()[:60], "tf": str(tf.expr),
    "dc": complex(tf.dc_gain).real, "t": type(lg.t).__name__, "s": type(lg.frequency.s).__name__}}))
"""


@pytest.mark.slow
def test_symbolic_work_begun_without_sympy_is_the_same_as_with_it():
    # the package's modules hold stand-ins for SymPy and its symbols until SymPy is first used
    # (lagrangian.base.deferred): a process that imports SymPy first and one that never does give the same equations,
    # LaTeX, transfer function and runs; the run agrees with the exact solution, and the DC gain is 1/k
    import json

    cold = json.loads(fresh(SYMBOLIC_WORK.format(first="")).strip().splitlines()[-1])
    warm = json.loads(fresh(SYMBOLIC_WORK.format(first="import sympy")).strip().splitlines()[-1])
    assert cold == warm
    assert cold["t"] == cold["s"] == "Symbol"
    assert max(abs(a - b) for a, b in zip(cold["x"], cold["exact"])) < 1e-8 * 0.05
    assert cold["dc"] == pytest.approx(1 / 40.0, rel=1e-12)


def test_registering_the_plugins_and_adding_numbers_load_no_heavy_library_but_numpy():
    # every installed plugin (the example third-party one included) registers, and a model of plain numbers is
    # built, without SymPy, SciPy, networkx, mpmath, matplotlib, pint, Dask, PySpice, pandas or xarray
    code = (
        "import sys, lagrangian as lg\n"
        "registry = lg.default_registry()\n"
        "m = lg.Model('rlc')\n"
        "m.add('voltage_source', 'V1', ('in', '0'), E=1.5)\n"
        "m.add('resistor', 'R1', ('in', 'a'), R=220.0)\n"
        "m.add('inductor', 'L1', ('a', 'b'), L=7e-3)\n"
        "m.add('capacitor', 'C1', ('b', '0'), C=2.2e-6)\n"
        f"print(len(registry.kinds), sorted({{m.split('.')[0] for m in sys.modules}} & set({HEAVY!r}) - {{'numpy'}}))\n"
    )
    kinds, loaded = fresh(code).strip().splitlines()[-1].split(" ", 1)
    assert int(kinds) > 40 and loaded == "[]"


def test_constant_loads_in_numbers_run_exactly_without_sympy():
    # a mass on a spring with a rest length, under gravity along −x, and a rotor on a torsion spring with a rest
    # angle: their constant loads join the numeric assembly, so the exact run imports neither SymPy nor SciPy, and
    # each oscillates about its equilibrium (x = ℓ₀ − m g / k, θ = θ₀) as the closed form says
    m, k, rest, g, J, kt, angle = 0.3, 20.0, 0.1, 9.81, 0.01, 2.0, 0.3
    code = (
        "import json, sys, lagrangian as lg\n"
        "m = lg.Model('loads')\n"
        f"m.add('mass', 'm1', 'p', m={m})\n"
        f"m.add('spring', 'k1', ('ground', 'p'), k={k}, rest_length={rest})\n"
        f"m.add('gravity', 'g', g={g})\n"
        f"m.add('inertia', 'J', 's', J={J})\n"
        f"m.add('torsion_spring', 'ks', ('ground', 's'), k={kt}, rest_angle={angle})\n"
        "res = m.simulate(1.0, initial={'x_p': 0.0, 'theta_s': 0.0}, velocity={'x_p': 0.0, 'theta_s': 0.0}, "
        "points=11, method='auto')\n"
        "print(json.dumps({'method': res.method, 'x': res['x_p'].tolist(), 'theta': res['theta_s'].tolist(), "
        "'t': res.t.tolist(), 'loaded': sorted({n.split('.')[0] for n in sys.modules} & {'sympy', 'scipy', 'mpmath'})}))\n"
    )
    import json

    import numpy as np

    out = json.loads(fresh(code).strip().splitlines()[-1])
    t = np.array(out["t"])
    x_eq = rest - m * g / k
    assert out["method"] == "exact" and out["loaded"] == []
    np.testing.assert_allclose(out["x"], x_eq * (1 - np.cos(np.sqrt(k / m) * t)), rtol=0, atol=1e-12)
    np.testing.assert_allclose(out["theta"], angle * (1 - np.cos(np.sqrt(kt / J) * t)), rtol=0, atol=1e-12)
