"""Recursive rigid-body dynamics (the articulated-body algorithm, ``lagrangian.plugins.multibody.recursive``) against
the closed-form Lagrange equations of the same mechanisms: an independent derivation (energies differentiated,
``M q̈ = f`` solved by LU) of the same accelerations, energies and momenta."""

from __future__ import annotations

import pickle
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import lagrangian as lg
from lagrangian import models
from lagrangian.plugins.multibody import recursive

# (runs started at rest without saying so: the rates are zero, as the warning says)
pytestmark = pytest.mark.filterwarnings("ignore::lagrangian.InitialConditionWarning")

PLANAR_JOINTS = ("revolute", "prismatic", "planar", "fixed")
SPATIAL_JOINTS = ("revolute", "prismatic", "spherical", "free", "planar", "fixed")
SEQUENCES = ("xyz", "zyx", "zxz", "yzy")


def _decade(draw, lo=-1.0, hi=1.0):
    return float(10 ** draw(st.floats(lo, hi)))


@st.composite
def trees(draw, dim):
    """A random tree of 2–5 bodies on random joints (each joint's parent one of the bodies before it), masses and
    sizes over two decades, with a spring, a damper and gravity along a random direction."""
    n = draw(st.integers(2, 5 if dim == 2 else 4))
    kinds = draw(st.lists(st.sampled_from(PLANAR_JOINTS if dim == 2 else SPATIAL_JOINTS), min_size=n, max_size=n))
    if all(k == "fixed" for k in kinds):
        kinds[0] = "revolute"
    spec = []
    for k in range(n):
        parent = "ground" if k == 0 else f"b{draw(st.integers(0, k - 1))}"
        # (in space, not a rod: it has no inertia about its own axis, and a turn about it is not determined)
        body = draw(st.sampled_from(("body", "rod", "disc") if dim == 2 else ("body", "disc")))
        length = _decade(draw, -1.0, 0.5)
        m = _decade(draw)
        point = tuple(draw(st.floats(-0.6, 0.6)) for _ in range(dim))
        child = tuple(draw(st.sampled_from((-1, 1))) * draw(st.floats(0.05, 0.3)) for _ in range(dim))
        axis = tuple(draw(st.sampled_from((-1.0, 0.0, 0.5, 1.0))) for _ in range(dim))
        if not any(axis):
            axis = (1.0,) + (0.0,) * (dim - 1)
        spec.append((parent, kinds[k], body, m, length, point, child, axis, draw(st.sampled_from(SEQUENCES))))
    direction = tuple(draw(st.floats(-1, 1)) for _ in range(dim - 1)) + (-1.0,)
    return dim, spec, _decade(draw, 0, 2), _decade(draw, -2, 0), direction


def build(tree, dynamics):
    dim, spec, k, c, direction = tree
    m = lg.Model("tree", dim=dim, dynamics=dynamics)
    for i, (parent, kind, body, mass, length, point, child, axis, seq) in enumerate(spec):
        name = f"b{i}"
        if body == "rod":
            m.add("rod", name, name, m=mass, length=length)
        elif body == "disc":
            m.add("disc", name, name, m=mass, radius=length / 2)
        else:
            inertia = mass * length**2 / 12 if dim == 2 else tuple(mass * length**2 * f for f in (0.1, 0.12, 0.15))
            m.add("body", name, name, m=mass, inertia=inertia, com=tuple(x / 3 for x in child))
        extra = {}
        if kind in ("revolute", "prismatic") and (dim == 3 or kind == "prismatic"):
            extra["axis"] = axis
        if kind in ("spherical", "free") and dim == 3:
            extra["sequence"] = seq
        if kind == "fixed" and dim == 2:
            extra["angle"] = 0.3
        m.add(kind, f"j{i}", (parent, name), parent_point=point if parent != "ground" else None, child_point=child, **extra)
    last = f"b{len(spec) - 1}"
    m.add("spring", "k", ("ground", f"{last}.com"), k=k)
    m.add("damper", "c", ("ground", "b0.com"), c=c)  # (the centre of mass is off the joint: never a zero length)
    m.add("gravity", "g", g=9.81, direction=direction)
    return m


def rhs_both(tree, states):
    fast, closed = build(tree, "recursive"), build(tree, "closed")
    assert fast.eq.recursion is not None and closed.eq.recursion is None
    f, c = fast.numeric().compile("tape"), closed.numeric().compile("tape")
    return fast, closed, [(f.rhs(0.4, y), c.rhs(0.4, y)) for y in states]


def _check(tree):
    rng = np.random.default_rng(0)
    n = None
    fast = build(tree, "recursive")
    n = len(fast.coordinate_names)
    states = [np.concatenate([rng.uniform(-0.6, 0.6, n), rng.uniform(-1, 1, n)]) for _ in range(3)]
    fast, closed, pairs = rhs_both(tree, states)
    for a, b in pairs:
        scale = np.max(np.abs(b)) + 1e-300
        assert np.max(np.abs(a - b)) <= 1e-9 * scale, (a, b)
    Y = np.array(states).T  # n × N
    times = np.full(Y.shape[1], 0.4)
    f, c = fast.numeric().compile("tape"), closed.numeric().compile("tape")
    e_fast = [*f.energies(times, Y[:n], Y[n:]), f.jacobi(times, Y[:n], Y[n:])]
    e_closed = [*c.energies(times, Y[:n], Y[n:]), c.jacobi(times, Y[:n], Y[n:])]
    scale = np.abs(e_closed[0]) + np.abs(e_closed[1])
    for x, z in zip(e_fast, e_closed):  # T, V, D and the Jacobi integral p·q̇ − L (the momenta through it)
        assert np.all(np.abs(x - z) <= 1e-9 * scale), (x, z)


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(trees(2))
def test_planar_trees_agree_with_the_closed_form(tree):
    _check(tree)


@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(trees(3))
def test_spatial_trees_agree_with_the_closed_form(tree):
    _check(tree)


def chain(n, dynamics="auto"):
    return models.pendulum_chain(n, m=[0.3 + 0.05 * k for k in range(n)], length=0.7, dynamics=dynamics)


def test_auto_takes_the_recursion_from_the_measured_size_and_says_so():
    small, large = chain(recursive.RECURSIVE_FROM - 1), chain(recursive.RECURSIVE_FROM)
    assert small.eq.recursion is None
    assert large.eq.recursion is not None
    n = recursive.RECURSIVE_FROM
    res = large.simulate(0.5, initial={f"theta_j{k}": 0.1 for k in range(n)}, points=3)
    assert any("articulated-body algorithm" in note and f"from {n} joint coordinates" in note for note in res.notes)
    assert not any("articulated-body" in note for note in small.simulate(0.1, points=2).notes)


def test_a_run_keeps_the_energy_of_a_conservative_chain():
    """Physics, not the closed form: a frictionless chain under gravity keeps T + V."""
    m = chain(10, "recursive")
    init = {f"theta_j{k}": 0.2 * (-1) ** k for k in range(10)}
    res = m.simulate(2.0, initial=init, rtol=1e-10, atol=1e-12, points=50)
    assert np.max(np.abs(res.E - res.E[0])) <= 1e-7 * np.max(np.abs(res.V))


def test_symbolic_parameters_give_the_same_structure_and_the_closed_form_on_demand():
    import sympy as sp

    L, mass = sp.symbols("L m", positive=True)
    m = lg.Model("pendulum", dim=2, dynamics="recursive")
    m.add("rod", "a", "a", m=mass, length=L)
    m.add("revolute", "j", ("ground", "a"))
    m.add("gravity", "g", g=9.81)
    assert m.eq.recursion is not None
    assert sp.simplify(m.mass_matrix[0, 0] - mass * L**2 / 3) == 0  # derived when asked for


@pytest.mark.parametrize("case, words", [
    ("loop", "closes a loop"),
    ("driven", "is driven"),
    ("point mass", "acts on 'bob', not a rigid body"),
    ("massless end", "have no inertia about their joints' axes"),
])
def test_what_the_recursion_cannot_serve_is_refused_by_name(case, words):
    m = chain(3, "recursive")
    if case == "loop":
        m.add("revolute", "close", ("r2", "r0"), parent_point=(0.7, 0), child_point=(0.3, 0))
    elif case == "driven":
        m.add("rod", "d", "d", m=0.1, length=0.2)
        m.add("revolute", "jd", ("r2", "d"), angle=lg.t)
    elif case == "point mass":
        m.add("mass", "bob", "r2.end", m=0.2)
    else:
        m.add("link", "l", "l", points={"tip": (0.2, 0)})
        m.add("revolute", "jl", ("r2", "l"), parent_point=(0.7, 0))
    with pytest.raises(lg.ModelError, match=words):
        m.eq


def test_auto_falls_back_to_the_closed_form_where_the_recursion_cannot_serve():
    m = chain(recursive.RECURSIVE_FROM)
    m.add("mass", "bob", f"r{recursive.RECURSIVE_FROM - 1}.end", m=0.2)
    assert m.eq.recursion is None
    res = m.simulate(0.2, points=2)
    assert res.t[-1] == pytest.approx(0.2)


def test_a_recursive_model_pickles_and_runs_in_a_fresh_process(tmp_path):
    m = chain(9)
    init = {f"theta_j{k}": 0.05 * k for k in range(9)}
    here = m.simulate(0.3, initial=init, points=4)["theta_j8"]
    path = tmp_path / "m.pickle"
    path.write_bytes(pickle.dumps(m))
    code = (f"import pickle, numpy as np; m = pickle.load(open({str(path)!r}, 'rb')); "
            f"assert m.eq.recursion is not None; "
            f"print(repr(m.simulate(0.3, initial={init!r}, points=4)['theta_j8'].tolist()))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert np.allclose(eval(out), here, rtol=1e-12, atol=0)  # noqa: S307 - our own child's list of floats


def test_a_sweep_of_a_recursive_chain_is_a_loop_of_simulate_to_the_last_bit():
    """The compiled form a sweep ships (parameters read at run time) holds the same recursion as a run's."""
    from lagrangian.sweep import DONE, sweep

    m = chain(9)
    init = {f"theta_j{k}": 0.1 * (-1) ** k for k in range(9)}
    masses = [0.31, 0.74]
    ds = sweep(m, {"m_r3": masses}, design="zip", initial=init, velocity={n: 0.0 for n in init},
               outputs=["theta_j8"], t_end=0.5, points=11, client="serial")
    assert (ds.status == DONE).all()
    for i, mass in enumerate(masses):
        res = m.simulate(0.5, params={"m_r3": mass}, initial=init, velocity={n: 0.0 for n in init}, points=11)
        assert np.array_equal(ds.theta_j8.values[i], res["theta_j8"])


@pytest.mark.skipif(lg.codegen.compiler() is None, reason="no C compiler")
def test_native_code_in_parts_gives_the_tapes_numbers_to_the_bit(monkeypatch, tmp_path):
    """A long tape printed as C in parts (functions of at most C_PART instructions, their shared results in a
    scratch array) computes what the tape interpreter does, operation for operation."""
    from lagrangian.numerics import c_units, tape

    monkeypatch.setattr(tape, "C_PART", 40)
    lg.codegen.set_cache_dir(tmp_path)
    try:
        numeric = chain(9).numeric()
        source = lg.codegen.generate_source(numeric)
        assert "matrix_part_3" in source and "energy_part_3" in source
        units = c_units.split(source)  # the parts in units of their own, compiled side by side, then linked
        defined = [sum(line.startswith("LG_PART void") and line.endswith("{") for line in u.splitlines()) for u in units]
        assert defined[0] == 0 and len(units) > 2 and all(1 <= d <= c_units.UNIT_PARTS for d in defined[1:])
        native, _ = lg.codegen.compile_model(numeric, "native")
        tape, _ = lg.codegen.compile_model(numeric, "tape")
        assert native.kind == "native"
        rng = np.random.default_rng(4)
        for _ in range(5):
            y = rng.uniform(-1, 1, 18)
            assert np.array_equal(native.rhs(0.3, y), tape.rhs(0.3, y))
            q, v = y[:9, None], y[9:, None]
            assert np.array_equal(native._energies([0.3], q, v), tape._energies([0.3], q, v))
    finally:
        lg.codegen.set_cache_dir(None)


@pytest.mark.parametrize("n, m, words", [("3", 1.0, "got '3'"), (0, 1.0, "got 0"), (2.5, 1.0, "got 2.5"),
                                         (3, [1.0, 2.0], "2 masses given for a chain of 3")])
def test_pendulum_chain_refuses_what_is_no_chain(n, m, words):
    with pytest.raises(lg.ModelError, match=words):
        models.pendulum_chain(n, m=m)


def test_a_gimbal_lock_of_a_recursive_model_is_named_as_the_closed_forms_is():
    """At β = π/2 the recursion divides by a zero pivot; the run is refused as singular, naming the lock."""
    import sys as _sys
    from pathlib import Path

    _sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    import spatial

    m = spatial.ours(3)
    assert m.eq.recursion is not None
    initial = {n: 0.1 for n in m.coordinate_names} | {"beta_j1": np.pi / 2}
    with pytest.raises(lg.SingularMassMatrixError, match=r"gimbal lock.*beta_j1 = ±π/2"):
        m.simulate(0.1, initial=initial, velocity={n: 0.0 for n in m.coordinate_names})


def test_rotational_springs_dampers_torques_and_forces_enter_as_generalized_forces():
    def build(dynamics):
        m = models.pendulum_chain(3, m=[0.3, 0.4, 0.5], length=0.6, dynamics=dynamics)
        m.add("rotational_spring", "ks", ("r0", "r1"), k=2.0)
        m.add("rotational_damper", "cs", ("r1", "r2"), c=0.3)
        m.add("body_torque", "tq", "r2", tau=0.7 * lg.t)
        m.add("force", "F", "r2.end", F=(0.2, -0.1))
        return m

    fast, closed = build("recursive"), build("closed")
    assert fast.eq.recursion is not None
    y = np.array([0.3, -0.4, 0.2, 0.5, -0.7, 0.9])
    a, b = fast.numeric().compile("tape").rhs(0.8, y), closed.numeric().rhs(0.8, y)
    assert np.max(np.abs(a - b)) <= 1e-12 * np.max(np.abs(b))
