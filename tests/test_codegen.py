"""Compiled models (lagrangian.codegen): the C right-hand side (native and on the tape interpreter), its disk
cache, the compiled stepping loops.

References are independent of the code under test: the NumPy path
(``sympy.lambdify`` + ``numpy.linalg.solve``) for the right-hand side,
scipy's ``RK45`` and the Python ``rk4``/``verlet`` for the loops, closed
forms for the orders of convergence.  Nothing here asserts on wall time.
"""

from __future__ import annotations

import math
import re
import shutil

import numpy as np
import pytest
import sympy as sp

import lagrangian as lg
from lagrangian import codegen, compiled_loops
from lagrangian.numerics import c_build
from lagrangian.errors import NumericalError, SingularMassMatrixError
from lagrangian.simulation import NumericModel

pytestmark = pytest.mark.skipif(codegen.compiler() is None, reason="no C compiler on this machine")


@pytest.fixture(scope="module", autouse=True)
def cache(tmp_path_factory):
    """A private cache directory for this module; the setting is restored afterwards."""
    path = tmp_path_factory.mktemp("lagrangian-cache")
    codegen.set_cache_dir(path)
    yield path
    codegen.set_cache_dir(None)
    codegen.set_compiler(None)


# -- models -----------------------------------------------------------------------------------------


def pendulum(n: int) -> lg.Model:
    m = lg.Model(f"{n}-link pendulum", dim=2)
    parent = "ground"
    for k in range(n):
        m.add("link", f"L{k}", f"L{k}", points={"end": (1, 0)})
        m.add("revolute", f"j{k}", (parent, f"L{k}"), absolute=True, **({"parent_point": (1, 0)} if k else {}))
        m.add("mass", f"m{k}", f"L{k}.end", m=1)
        parent = f"L{k}"
    m.add("gravity", "g", g=9.81)
    return m


def four_bar() -> lg.Model:
    """A closed loop: kept with Lagrange multipliers."""
    m = lg.Model("four-bar", dim=2)
    for name, length in (("crank", 1), ("coupler", 3), ("rocker", 2)):
        m.add("rod", name, name, m=1, length=length)
    m.add("revolute", "A", ("ground", "crank"), absolute=True)
    m.add("revolute", "B", ("crank", "coupler"), parent_point=(1, 0), absolute=True)
    m.add("revolute", "D", ("ground", "rocker"), parent_point=(3, 0), absolute=True)
    m.add("revolute", "C", ("coupler", "rocker"), parent_point=(3, 0), child_point=(2, 0))
    m.add("gravity", "g")
    return m


def rc_ladder() -> lg.Model:
    """A circuit with first-order coordinates (a capacitor node without inductance), driven by sin t."""
    m = lg.Model("rc")
    m.add("voltage_source", "V1", ("in", "0"), E=sp.sin(lg.t))
    m.add("resistor", "R1", ("in", "a"), R=2)
    m.add("capacitor", "C1", ("a", "0"), C=sp.Rational(1, 3))
    m.add("resistor", "R2", ("a", "b"), R=1)
    m.add("inductor", "L2", ("b", "0"), L=sp.Rational(1, 2))
    return m


def speaker() -> lg.Model:
    """Electromechanical: a moving-coil loudspeaker (coil coupling Bl·x·q̇), driven by a sine."""
    m = lg.Model("speaker")
    m.add("voltage_source", "V", ("n1", "0"), E=sp.sin(3 * lg.t))
    m.add("resistor", "Re", ("n1", "n2"), R=4.0)
    m.add("inductor", "Le", ("n2", "n3"), L=0.5)
    m.add("moving_coil", "coil", ("n3", "0", "cone"), Bl=7.0)
    m.add("mass", "mc", "cone", m=0.02)
    m.add("spring", "ks", ("ground", "cone"), k=2000.0)
    m.add("damper", "cs", ("ground", "cone"), c=1.5)
    return m


def oscillator(k: float = 4.0) -> lg.Model:
    m = lg.Model("oscillator")
    m.add("mass", "m", "p", m=1)
    m.add("spring", "k", ("ground", "p"), k=k)
    return m


MODELS = {"pendulum3": lambda: pendulum(3), "four_bar": four_bar, "rc_ladder": rc_ladder, "speaker": speaker}


@pytest.fixture(scope="module")
def built():
    """Each model with its NumPy and native compiled functions (compiled once for the whole module)."""
    out = {}
    for name, build in MODELS.items():
        model = build()
        numeric = model.numeric()
        compiled, note = codegen.compile_model(numeric)
        assert compiled is not None and compiled.kind == "native", note
        out[name] = (model, numeric, compiled)
    return out


@pytest.fixture(scope="module")
def tapes(built):
    """The same models on the tape interpreter."""
    out = {}
    for name, (_, numeric, _) in built.items():
        compiled, note = codegen.compile_model(numeric, "tape")
        assert compiled is not None and compiled.kind == "tape", note
        out[name] = compiled
    return out


@pytest.fixture(params=["native", "tape"])
def kind(request):
    return request.param


def pick(built, tapes, name, kind):
    model, numeric, native = built[name]
    return model, numeric, native if kind == "native" else tapes[name]


# -- the right-hand side ----------------------------------------------------------------------------


@pytest.mark.parametrize("name", list(MODELS))
@pytest.mark.slow
def test_compiled_rhs_equals_the_numpy_rhs_on_random_states(built, tapes, name, kind):
    model, numeric, compiled = pick(built, tapes, name, kind)
    numeric.use_compiled(False)  # the reference: NumPy
    eq = model.eq
    assert name != "four_bar" or len(eq.multipliers) > 0
    assert name != "rc_ladder" or eq.first_order
    rng = np.random.default_rng(3)
    for _ in range(20):
        y = rng.uniform(-2, 2, numeric.n + numeric.nI)
        time = rng.uniform(0, 5)
        expected = numeric.rhs(time, y)
        got = compiled.rhs(time, y)
        assert np.allclose(got, expected, rtol=1e-12, atol=1e-12 * max(1.0, np.max(np.abs(expected))))


@pytest.mark.parametrize("name", list(MODELS))
@pytest.mark.slow
def test_compiled_energies_and_velocities_equal_the_numpy_ones(built, tapes, name, kind):
    _, numeric, compiled = pick(built, tapes, name, kind)
    numeric.use_compiled(False)  # the reference: NumPy
    rng = np.random.default_rng(4)
    N = 7
    times = rng.uniform(0, 5, N)
    Y = rng.uniform(-2, 2, (numeric.n + numeric.nI, N))
    v_np = numeric.velocities_many(times, Y)
    v_c = compiled.velocities_many(times, Y)
    assert np.allclose(v_c, v_np, rtol=1e-12, atol=1e-12)
    for e_c, e_np in zip(compiled.energies(times, Y[: numeric.n], v_np), numeric.energies(times, Y[: numeric.n], v_np)):
        assert np.allclose(e_c, e_np, rtol=1e-12, atol=1e-12)
    h_np = lg.integrate.Problem(numeric).jacobi(times, Y[: numeric.n], v_np)  # NumPy: no compiled code in use
    assert np.allclose(compiled.jacobi(times, Y[: numeric.n], v_np), h_np, rtol=1e-12, atol=1e-12)


def test_every_choice_of_compiled_matches_numpy_and_auto_runs_the_tape_until_native_is_built(built):
    model = pendulum(2)
    init = {"theta_j0": 0.4, "theta_j1": -0.2}
    vel = {"theta_j0": 0.0, "theta_j1": 0.0}
    plain = model.simulate(2.0, initial=init, velocity=vel, points=21, compiled=False)
    assert model.numeric()._fast is None
    auto = model.simulate(2.0, initial=init, velocity=vel, points=21)  # the default: nothing built yet → the tape
    assert model.numeric()._fast.kind == "tape"
    native = model.simulate(2.0, initial=init, velocity=vel, points=21, compiled=True)
    assert model.numeric()._fast.kind == "native" and not model.numeric()._fast.from_cache
    tape = model.simulate(2.0, initial=init, velocity=vel, points=21, compiled="tape")
    assert model.numeric()._fast.kind == "tape"
    for res in (auto, native, tape):
        for name in plain.names:
            assert np.allclose(res[name], plain[name], rtol=0, atol=1e-9)
        assert np.allclose(res.E, plain.E, atol=1e-9)
    again = pendulum(2)  # a new model object: "auto" now finds the native library in the disk cache
    looped = again.simulate(2.0, initial=init, velocity=vel, points=21, method="dopri5_c")
    assert again.numeric()._fast.kind == "native" and again.numeric()._fast.from_cache
    assert any("native code" in n and "from the cache" in n for n in looped.notes)
    with pytest.raises(lg.ModelError, match="compiled must be True, False, 'auto', 'native' or 'tape'"):
        model.simulate(1.0, initial=init, velocity=vel, compiled="yes")
    with pytest.raises(lg.ModelError, match="kind must be one of"):
        codegen.compile_model(model.numeric(), "fast")


@pytest.mark.slow
def test_the_tape_compiles_nothing_per_model_and_the_runtime_is_built_once(tmp_path, monkeypatch):
    monkeypatch.setattr(c_build, "_settings", {"cache_dir": str(tmp_path), "compiler": None})
    path = codegen.runtime()
    assert path.exists() and path.parent == tmp_path and path.name.startswith("runtime-")
    assert codegen.runtime() == path  # from the cache the second time
    for k in (2.0, 3.0, 5.0):
        res = oscillator(k).simulate(1.0, initial={"x_p": 1.0}, velocity={"x_p": 0.0}, points=5, method="dopri5_c",
                                     rtol=1e-10, atol=1e-12)
        assert any("tape interpreter" in n for n in res.notes)
        assert np.allclose(res["x_p"], np.cos(math.sqrt(k) * res.t), atol=1e-8)
    assert sorted(p.suffix for p in tmp_path.iterdir() if not p.name.startswith(".")) == [".c", ".json", ".so"]
    monkeypatch.setenv("LAGRANGIAN_CC", "/nonexistent/lagrangian-test-cc")
    with pytest.raises(lg.ModelError, match="no C compiler"):
        codegen.runtime()


def test_a_long_run_on_the_tape_says_native_code_would_pay(monkeypatch):
    monkeypatch.setattr(compiled_loops, "LONG_RUN", 1000)
    kw = dict(initial={"x_p": 1.0}, velocity={"x_p": 0.0}, points=5, method="dopri5_c", rtol=1e-10, atol=1e-12)
    model = oscillator(7.0)
    on_tape = model.simulate(20.0, compiled="tape", **kw)
    assert on_tape.nfev > 1000 and any("compiled=True builds native code" in n for n in on_tape.notes)
    native = model.simulate(20.0, compiled=True, **kw)
    assert not any("compiled=True builds native code" in n for n in native.notes)
    assert np.allclose(native["x_p"], on_tape["x_p"], rtol=0, atol=1e-12)


def test_a_singular_matrix_in_c_raises_the_same_error_as_numpy(built, tapes, kind):
    _, numeric, compiled = pick(built, tapes, "four_bar", kind)
    numeric.use_compiled(False)
    y = np.zeros(numeric.n + numeric.nI)  # all links along x: the loop's Jacobian loses rank
    with pytest.raises(SingularMassMatrixError) as numpy_error:
        numeric.rhs(0.0, y)
    with pytest.raises(SingularMassMatrixError) as c_error:
        compiled.rhs(0.0, y)
    assert str(c_error.value) == str(numpy_error.value)
    assert "singular" in str(c_error.value)


def test_non_finite_values_raise_a_numerical_error(built, tapes, kind):
    _, numeric, compiled = pick(built, tapes, "pendulum3", kind)
    y = np.zeros(numeric.n + numeric.nI)
    y[0] = np.inf
    with pytest.raises(NumericalError, match="not finite"):
        compiled.rhs(0.0, y)


# -- the cache --------------------------------------------------------------------------------------


def test_second_build_of_the_same_model_comes_from_the_cache(built, cache):
    model, numeric, first = built["pendulum3"]
    again = NumericModel(model.eq, numeric.values, numeric.signals)  # a fresh object: nothing shared in memory
    second, note = codegen.compile_model(again)
    assert note is None and second.from_cache and second.key == first.key
    assert second.path.parent == cache and second.path.exists()
    symbolic = lg.Model("symbolic oscillator")
    symbolic.add("mass", "m", "p", m=1)
    symbolic.add("spring", "k", ("ground", "p"), k=sp.Symbol("k"))
    one, two = (codegen.compile_model(symbolic.numeric({"k": k}))[0] for k in (4.0, 5.0))
    assert one.key != two.key  # parameter values are part of the key
    assert np.allclose(two.rhs(0.0, np.array([1.0, 0.0])), [0.0, -5.0])


@pytest.mark.slow
def test_cache_directory_is_configurable_and_safe_to_delete(tmp_path, monkeypatch):
    model = oscillator()
    monkeypatch.setattr(c_build, "_settings", {"cache_dir": None, "compiler": None})
    monkeypatch.setenv("LAGRANGIAN_CACHE_DIR", str(tmp_path / "env-cache"))
    assert codegen.cache_dir() == tmp_path / "env-cache"
    monkeypatch.delenv("LAGRANGIAN_CACHE_DIR")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert codegen.cache_dir() == tmp_path / "xdg" / "lagrangian"
    codegen.set_cache_dir(tmp_path / "mine")
    assert codegen.cache_dir() == tmp_path / "mine"
    compiled, _ = codegen.compile_model(model.numeric())
    assert not compiled.from_cache and compiled.path.parent == tmp_path / "mine"
    shutil.rmtree(tmp_path / "mine")  # delete it all: the next build simply rebuilds
    fresh = NumericModel(model.eq, model.numeric().values, {})
    rebuilt, note = codegen.compile_model(fresh)
    assert note is None and not rebuilt.from_cache and rebuilt.path.exists()
    assert np.allclose(rebuilt.rhs(0.0, np.array([1.0, 0.0])), [0.0, -4.0])


@pytest.mark.slow
def test_a_corrupt_cache_entry_is_rebuilt(tmp_path, monkeypatch):
    monkeypatch.setattr(c_build, "_settings", {"cache_dir": str(tmp_path), "compiler": None})
    model = oscillator(k=9.0)
    compiled, _ = codegen.compile_model(model.numeric())
    compiled.path.unlink()  # (never overwrite a loaded library in place: its pages are mapped)
    compiled.path.write_bytes(b"this is not a shared library")
    fresh = NumericModel(model.eq, model.numeric().values, {})
    rebuilt, note = codegen.compile_model(fresh)
    assert note is None and not rebuilt.from_cache
    assert compiled.path.read_bytes().startswith(b"\x7fELF") or compiled.path.stat().st_size > 100
    assert np.allclose(rebuilt.rhs(0.0, np.array([1.0, 0.0])), [0.0, -9.0])
    assert codegen.compile_model(NumericModel(model.eq, model.numeric().values, {}))[0].from_cache


# -- falling back -----------------------------------------------------------------------------------


def test_without_a_compiler_simulate_falls_back_to_numpy_with_a_note(monkeypatch, caplog):
    monkeypatch.setattr(c_build, "_settings", {"cache_dir": c_build._settings["cache_dir"], "compiler": None})
    monkeypatch.setenv("LAGRANGIAN_CC", "/nonexistent/lagrangian-test-cc")
    assert codegen.compiler() is None
    model = oscillator()
    with caplog.at_level("INFO", logger="lagrangian"):
        res = model.simulate(1.0, initial={"x_p": 1.0}, velocity={"x_p": 0.0}, points=5, compiled=True)
    assert any("no C compiler found" in note for note in res.notes)
    assert "no C compiler found" in caplog.text
    assert np.allclose(res["x_p"], np.cos(2 * res.t), atol=1e-8)
    loop = oscillator().simulate(1.0, initial={"x_p": 1.0}, velocity={"x_p": 0.0}, points=5, method="dopri5_c")
    assert any("ran its Python sibling 'RK45'" in note for note in loop.notes)
    assert np.allclose(loop["x_p"], np.cos(2 * loop.t), atol=1e-7)


@pytest.mark.slow
def test_python_callable_signals_fall_back_with_a_note():
    model = lg.Model("forced")
    model.add("mass", "m", "p", m=1)
    model.add("spring", "k", ("ground", "p"), k=9)
    model.add("force", "f", "p", F=lambda time: 0.5 * math.cos(1.3 * time))
    compiled, note = codegen.compile_model(model.numeric())
    assert compiled is None and "Python callables" in note
    res = model.simulate(2.0, initial={"x_p": 0.0}, velocity={"x_p": 0.0}, points=5, method="rk4_c", step=1e-3)
    assert any("Python callables" in n and "'rk4'" in n for n in res.notes)


# -- the compiled stepping loops --------------------------------------------------------------------

INIT3 = {"theta_j0": 0.6, "theta_j1": 0.2, "theta_j2": -0.3}
VEL3 = {"theta_j0": 0.0, "theta_j1": 0.5, "theta_j2": 0.0}


@pytest.fixture(scope="module")
def pend3(built):
    model = built["pendulum3"][0]
    ref = model.simulate(2.0, initial=INIT3, velocity=VEL3, points=11, method="DOP853", rtol=1e-13, atol=1e-13,
                         compiled=True)
    return model, ref


def max_error(res, ref) -> float:
    return max(float(np.max(np.abs(res[n] - ref[n]))) for n in ref.names)


def test_dopri5_c_agrees_with_scipys_rk45(pend3):
    model, ref = pend3
    kw = dict(initial=INIT3, velocity=VEL3, points=11, rtol=1e-7, atol=1e-9)
    c = model.simulate(2.0, method="dopri5_c", **kw)
    py = model.simulate(2.0, method="RK45", **kw)
    assert c.method == "dopri5_c" and any("compiled code" in n for n in c.notes)
    assert abs(c.nfev - py.nfev) <= 0.05 * py.nfev  # the same pair and controller: (nearly) the same steps
    assert max_error(c, py) < 1e-8
    assert max_error(c, ref) < 1e-5


def test_dopri5_c_error_falls_with_the_tolerance(pend3):
    model, ref = pend3
    errors = [max_error(model.simulate(2.0, initial=INIT3, velocity=VEL3, points=11, method="dopri5_c", rtol=r, atol=r), ref)
              for r in (1e-5, 1e-7, 1e-9, 1e-11)]
    assert all(b < a for a, b in zip(errors, errors[1:]))
    assert errors[-1] < 1e-8


def elastic_pendulum() -> lg.Model:
    """A point mass on a spring of rest length 1 under gravity, in the plane: nonlinear and separable."""
    m = lg.Model("elastic pendulum", dim=2)
    m.add("mass", "m", "p", m=1)
    m.add("spring", "k", ("ground", "p"), k=20, rest_length=1)
    m.add("gravity", "g", g=9.81)
    return m


ELASTIC = {"initial": {"x_p": 0.5, "y_p": -1.2}, "velocity": {"x_p": 0.0, "y_p": 0.3}}


@pytest.fixture(scope="module")
def elastic():
    model = elastic_pendulum()
    ref = model.simulate(2.0, points=11, method="DOP853", rtol=1e-13, atol=1e-13, compiled=True, **ELASTIC)
    return model, ref


def test_dopri5_c_converges_at_order_five_with_its_step_held_fixed(pend3):
    model, ref = pend3
    errors = []
    for h in (0.025, 0.0125, 0.00625):  # a tolerance it always meets, and max_step = first_step = h: uniform steps
        kw = dict(initial=INIT3, velocity=VEL3, points=11, rtol=1e6, atol=1e6, max_step=h, first_step=h, energy_tol=False)
        res = model.simulate(2.0, method="dopri5_c", **kw)
        errors.append(max_error(res, ref))
        assert max_error(res, model.simulate(2.0, method="RK45", **kw)) < 1e-12  # the same steps as scipy's
    rates = [math.log2(a / b) for a, b in zip(errors, errors[1:])]
    assert all(abs(r - 5) < 0.75 for r in rates), rates


@pytest.mark.parametrize("method, order", [("rk4_c", 4), ("verlet_c", 2)])
@pytest.mark.slow
def test_fixed_step_loops_converge_at_their_order_and_agree_with_python(pend3, elastic, method, order):
    model, ref = pend3 if method == "rk4_c" else elastic
    start = {"initial": INIT3, "velocity": VEL3} if method == "rk4_c" else ELASTIC
    steps = (0.02, 0.01, 0.005)
    errors = [max_error(model.simulate(2.0, points=11, method=method, step=h, energy_tol=False, **start), ref)
              for h in steps]
    rates = [math.log2(a / b) for a, b in zip(errors, errors[1:])]
    assert all(abs(r - order) < 0.35 for r in rates), rates
    python = method[:-2]
    for kw in ({"points": 11}, {"t_eval": np.linspace(0, 2.0, 7) ** 1.5 / 2.0**0.5}):  # on steps, and between them
        c = model.simulate(2.0, method=method, step=0.01, energy_tol=False, **start, **kw)
        py = model.simulate(2.0, method=python, step=0.01, energy_tol=False, compiled=False, **start, **kw)
        assert c.step == py.step and c.t.size == py.t.size
        assert max_error(c, py) < 1e-11


def test_verlet_c_keeps_the_energy_bounded_and_refuses_non_separable_models(built, elastic):
    model = elastic[0]
    kw = dict(points=2001, step=0.02, **ELASTIC)
    res = model.simulate(2000.0, method="verlet_c", **kw)
    drift = np.abs(res.E - res.E[0]) / abs(res.E[0])
    assert drift.max() < 1e-2 and drift[-200:].max() < 2 * drift[:200].max()  # bounded, not growing
    rk4 = model.simulate(2000.0, method="rk4_c", energy_tol=False, **kw)
    rk4_drift = np.abs(rk4.E - rk4.E[0]) / abs(rk4.E[0])
    assert rk4_drift[-200:].max() > 5 * rk4_drift[:200].max()  # a non-symplectic method drifts
    with pytest.raises(lg.ModelError, match=r"verlet_c \(Störmer–Verlet\) needs a separable Lagrangian"):
        built["speaker"][0].simulate(1.0, method="verlet_c", step=1e-3, initial={"x_cone": 0, "q_Le": 0},
                                     velocity={"x_cone": 0, "q_Le": 0})
    with pytest.raises(lg.ModelError, match="first-order"):
        built["rc_ladder"][0].simulate(1.0, method="verlet_c", step=1e-3, initial={"q_L2": 0, "q_R1": 0},
                                       velocity={"q_L2": 0})


def test_compiled_loops_report_singular_matrices_and_divergence(built, tapes, kind):
    _, numeric, compiled = pick(built, tapes, "four_bar", kind)
    y0 = np.zeros(numeric.n + numeric.nI)  # all links along x: the loop's Jacobian loses rank
    with pytest.raises(SingularMassMatrixError, match="singular"):
        compiled.dopri5((0.0, 1.0), y0, np.array([0.0, 1.0]), rtol=1e-6, atol=1e-9, max_step=np.inf, first_step=None)
    with pytest.raises(SingularMassMatrixError, match="singular"):
        compiled.fixed("rk4", 0.0, 0.1, 10, y0, np.array([0.0, 1.0]))
    with pytest.raises(lg.IntegrationError, match="diverged"):
        pendulum(2).simulate(50.0, initial={"theta_j0": 1.0, "theta_j1": 1.0}, velocity={"theta_j0": 0, "theta_j1": 0},
                             method="rk4_c", step=0.5, energy_tol=False)


def _two_links(m0: float | None, m1: float) -> lg.Model:
    """Two links on absolute angles, lengths 0.7 and 0.25 m; a point mass at each end (none at the first when ``m0``
    is None: the 2 × 2 mass matrix is then singular wherever the links are aligned)."""
    m = lg.Model("two links", dim=2)
    m.add("link", "L0", "L0", points={"end": (0.7, 0)})
    m.add("revolute", "j0", ("ground", "L0"), absolute=True)
    m.add("link", "L1", "L1", points={"end": (0.25, 0)})
    m.add("revolute", "j1", ("L0", "L1"), absolute=True, parent_point=(0.7, 0))
    if m0 is not None:
        m.add("mass", "m0", "L0.end", m=m0)
    m.add("mass", "m1", "L1.end", m=m1)
    m.add("gravity", "g", g=9.81)
    return m


@pytest.mark.parametrize("kind", ["native", "tape"])
def test_two_by_two_solves_match_numpy_over_decades_of_mass_ratio(kind):
    """The 2 × 2 mass matrix is solved in closed form in C: accurate to its conditioning against NumPy's LAPACK
    solve, for masses 0.3 kg against 7e-3 kg and 2e-5 kg against 40 kg (a condition number of about 1e6)."""
    rng = np.random.default_rng(7)
    for m0, m1 in ((0.3, 7e-3), (2e-5, 40.0), (3.0, 3.0)):
        numeric = _two_links(m0, m1).numeric()
        compiled, note = codegen.compile_model(numeric, kind)
        assert compiled is not None, note
        numeric.use_compiled(False)
        for _ in range(10):
            y = rng.uniform(-2, 2, 4)
            expected = numeric.rhs(0.0, y)
            c = m1 * 0.7 * 0.25 * math.cos(y[0] - y[1])  # the mass matrix, by hand
            cond = np.linalg.cond([[(m0 + m1) * 0.7 ** 2, c], [c, m1 * 0.25 ** 2]])
            assert np.allclose(compiled.rhs(0.0, y), expected, rtol=1e-14 * cond, atol=0)


@pytest.mark.parametrize("kind", ["native", "tape"])
def test_a_singular_two_by_two_matrix_in_c_raises_the_same_error_as_numpy(kind):
    numeric = _two_links(None, 0.3).numeric()
    compiled, note = codegen.compile_model(numeric, kind)
    assert compiled is not None, note
    numeric.use_compiled(False)
    y = np.array([0.4, 0.4, 1.0, -2.0])  # the links aligned: the mass matrix has rank 1
    with pytest.raises(SingularMassMatrixError) as numpy_error:
        numeric.rhs(0.0, y)
    with pytest.raises(SingularMassMatrixError) as c_error:
        compiled.rhs(0.0, y)
    # the same message, but for the smallest singular value quoted, of matrices that differ in rounding
    assert re.sub(r"value \S+\)", "", str(c_error.value)) == re.sub(r"value \S+\)", "", str(numpy_error.value))
    y[1] = 0.41  # beside it: both solve, and agree
    assert np.allclose(compiled.rhs(0.0, y), numeric.rhs(0.0, y), rtol=1e-9, atol=0)


def test_zero_entries_of_the_matrix_are_cleared_once_not_stored_one_by_one():
    """A chain of 12 masses of 0.3–0.41 kg on springs: its mass matrix is diagonal (132 of 144 entries zero); the
    native library clears the matrix with one ``memset`` and writes only what is not +0.0, and its accelerations
    equal NumPy's.  A double pendulum's matrix has no zero: it is written whole, with no ``memset``."""
    from lagrangian.numerics.c_source import generate_source

    model = lg.Model("chain")
    for i in range(12):
        model.add("mass", f"m{i}", f"p{i}", m=0.3 + 0.01 * i)
        model.add("spring", f"k{i}", ("ground" if i == 0 else f"p{i - 1}", f"p{i}"), k=40.0 + 3 * i)
    numeric = model.numeric()
    source = generate_source(numeric)
    body = source[source.index("static int matrix_terms("):source.index("int lg_matrix(")]
    stores = re.findall(r"^\s+A\[(\d+)\] = ", body, re.M)
    assert "memset(A, 0, sizeof(double) * NM * NM);" in body
    assert sorted(map(int, stores)) == [13 * i for i in range(12)]  # the diagonal, by the physics of point masses
    compiled, note = codegen.compile_model(numeric, "native")
    assert compiled is not None, note
    numeric.use_compiled(False)
    y = np.random.default_rng(3).uniform(-0.1, 0.1, 24)
    assert np.allclose(compiled.rhs(0.0, y), numeric.rhs(0.0, y), rtol=1e-13, atol=0)
    assert "memset(A" not in generate_source(_two_links(0.3, 7e-3).numeric())  # a full matrix is written whole
