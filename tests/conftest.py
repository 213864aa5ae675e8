"""Test settings shared by every test module.

Property-based tests (hypothesis) draw parameters over decades; they run
without a deadline (symbolic work varies in time, and tests assert nothing
about wall time) and derandomized, so that `make test` on any machine tries
the examples CI tries and a run can be repeated.  `make test-explore`
(``HYPOTHESIS_PROFILE=explore``) draws new examples on every run, to search
further.
"""

import contextlib
import io
import os
import runpy
import sys
import types
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

import lagrangian as lg

settings.register_profile(
    "default",
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.differing_executors],
)
settings.register_profile("ci", parent=settings.get_profile("default"), derandomize=True, print_blob=True)
settings.register_profile("explore", parent=settings.get_profile("default"), print_blob=True)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))


@pytest.fixture
def registry_with():
    """``registry_with(Component, ...)``: a registry with the installed plugins and one more, registered in-process,
    providing the given component classes (a plugin a test writes)."""
    def build(*classes):
        plugin = types.ModuleType("test_plugin")

        @lg.hookimpl
        def register_component_types(register):
            for cls in classes:
                register(cls)

        plugin.register_component_types = register_component_types
        return lg.Registry(plugins={"test_plugin": plugin})

    return build


#: Modules whose tests run subprocesses, ngspice, clusters or long property searches: `make test-fast` skips them,
#: every test named for ngspice, and the tests marked ``@pytest.mark.slow`` one by one (those that take more than
#: about half a second: examples, processes, derivations checked against another engine); `make test` and CI run
#: everything.
SLOW_MODULES = {"test_examples", "test_sweep_dask", "test_transducer_spice", "test_fuzz", "test_robustness",
                "test_ngspice", "test_spatial_chains", "test_untrusted_code", "test_compare_params", "test_site",
                "test_notebook"}


#: Modules whose tests take longest (seconds of the whole suite, measured with ``--durations=0``), run first: workers
#: of pytest-xdist take tests in the order collected, and a long test started last keeps one worker busy while the
#: other idles (the documentation build alone takes half a minute).
LONGEST_FIRST = ("test_site", "test_spatial_chains", "test_notebook", "test_sweep_dask", "test_untrusted_code",
                 "test_cli", "test_fuzz", "test_robustness", "test_examples", "test_bicycle", "test_multibody")


def _module(item) -> str:
    return item.nodeid.split("::")[0].rsplit("/", 1)[-1].removesuffix(".py")


def pytest_collection_modifyitems(config, items):
    for item in items:
        if _module(item) in SLOW_MODULES or "ngspice" in item.name:
            item.add_marker(pytest.mark.slow)
    rank = {name: i for i, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(_module(item), len(rank)))  # stable: the rest keep their order


def _run_script(path: Path, *args: str, cwd: Path) -> str:
    """Run the script ``path`` with ``args`` in ``cwd`` as ``python path args...`` runs it — its own ``__main__``,
    ``sys.argv`` and working directory — in this process; its standard output.  A nonzero exit fails with its
    error output."""
    import matplotlib

    matplotlib.use("Agg")  # as a process without a display: charts to files only
    import matplotlib.pyplot as plt

    out, err = io.StringIO(), io.StringIO()
    saved = sys.argv
    sys.argv = [str(path), *map(str, args)]
    try:
        with contextlib.chdir(cwd), contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                runpy.run_path(str(path), run_name="__main__")
            except SystemExit as exc:
                if exc.code not in (None, 0):
                    raise AssertionError(f"{Path(path).name} exited with status {exc.code}:\n{err.getvalue()}") from None
    finally:
        sys.argv = saved
        plt.close("all")
    return out.getvalue()


@pytest.fixture(scope="session")
def run_script():
    """``run_script(path, *args, cwd=...)``: an example script run in this process (:func:`_run_script`).  A process
    per example would spend a second of CPU importing NumPy, SymPy and the package before the example's own work;
    the README's demo, the command line and the scripts that start process pools still run as processes."""
    return _run_script


EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


@pytest.fixture(scope="session")
def example(tmp_path_factory):
    """``example(script, *args) -> (output, directory)``: an example of ``examples/`` run in this process once per
    session and arguments (``"{dir}"`` in an argument is its own directory, where it writes its files), its output
    shared by the tests that read it."""
    done: dict[tuple, tuple[str, Path]] = {}

    def run(script: str, *args: str) -> tuple[str, Path]:
        key = (script, *args)
        if key not in done:
            where = tmp_path_factory.mktemp(Path(script).stem)
            done[key] = _run_script(EXAMPLES / script, *(a.replace("{dir}", str(where)) for a in args), cwd=where), where
        return done[key]

    return run


def _kane_gear_train(J1, J2, J3, n2, n3, k, theta, omega, time) -> float:
    """θ̈1 of a train of three gears on one axis (inertias ``J``, θ2 = n2 θ1 and θ3 = n3 θ1 put in by hand), θ1
    driven by the torque sin t and the last gear held by a torsion spring ``k`` to ground, from
    sympy.physics.mechanics' KanesMethod with θ1 its one coordinate."""
    import sympy as sp
    import sympy.physics.mechanics as me

    th, w = me.dynamicsymbols("th w")
    N = me.ReferenceFrame("N")
    O = me.Point("O")
    O.set_vel(N, 0)
    frames = [N.orientnew(f"B{i}", "Axis", (ratio * th, N.z)) for i, ratio in enumerate((1, n2, n3))]
    bodies = []
    for i, (B, J, ratio) in enumerate(zip(frames, (J1, J2, J3), (1, n2, n3))):
        B.set_ang_vel(N, ratio * w * N.z)
        bodies.append(me.RigidBody(f"b{i}", O, B, 1.0, (me.inertia(B, 0, 0, J), O)))
    loads = [(frames[0], sp.sin(me.dynamicsymbols._t) * N.z), (frames[2], -k * n3 * th * N.z)]
    km = me.KanesMethod(N, q_ind=[th], u_ind=[w], kd_eqs=[th.diff() - w])
    fr, frstar = km.kanes_equations(bodies, loads)
    return float(sp.solve(fr + frstar, w.diff())[w.diff()].subs({th: theta, w: omega, me.dynamicsymbols._t: time}))


@pytest.fixture(scope="session")
def kane_gear_train():
    """``kane_gear_train(J1, J2, J3, n2, n3, k, theta, omega, time)``: the independent reference of gear trains
    (:func:`_kane_gear_train`)."""
    return _kane_gear_train


def _kane_rack(m, k, J, r, c, F=0.0):
    """θ̈ of a rack (mass ``m``, spring ``k`` and damper ``c`` to ground, force ``F``) driven by a pinion
    (inertia ``J``, radius ``r``) as a function of (θ, θ̇), from sympy.physics.mechanics' KanesMethod with the
    pinion angle θ its one coordinate (x = r θ put in by hand)."""
    import sympy as sp
    import sympy.physics.mechanics as me

    th, w = me.dynamicsymbols("th w")
    N = me.ReferenceFrame("N")
    O = me.Point("O")
    O.set_vel(N, 0)
    P = O.locatenew("P", r * th * N.x)
    P.set_vel(N, r * w * N.x)
    B = N.orientnew("B", "Axis", (th, N.z))
    B.set_ang_vel(N, w * N.z)
    wheel = me.RigidBody("wheel", O, B, 1.0, (me.inertia(B, 0, 0, J), O))
    mass = me.Particle("rack", P, m)
    km = me.KanesMethod(N, q_ind=[th], u_ind=[w], kd_eqs=[th.diff() - w])
    fr, frstar = km.kanes_equations([wheel, mass], [(P, (F - k * r * th - c * r * w) * N.x)])
    wdot = sp.solve(fr + frstar, w.diff())[w.diff()]
    return sp.lambdify((th, w), wdot)


@pytest.fixture(scope="session")
def kane_rack():
    """``kane_rack(m, k, J, r, c, F=0)(θ, θ̇)``: the independent reference of a rack and pinion (:func:`_kane_rack`)."""
    return _kane_rack
