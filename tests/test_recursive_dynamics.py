"""Recursive rigid-body dynamics (the articulated-body algorithm, ``lagrangian.plugins.multibody.recursive``) against
the closed-form Lagrange equations of the same mechanisms: an independent derivation (energies differentiated,
``M q̈ = f`` solved by LU) of the same accelerations, energies and momenta."""

from __future__ import annotations

import pickle
import subprocess
import sys

import numpy as np
import sympy as sp
import pytest
from hypothesis import HealthCheck, example, given, settings
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
    sizes over two decades, with a point mass on one body, a spring, a damper and gravity along a random
    direction."""
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
    # a point mass on a point of one body (folded into its inertia by the recursion), over two decades
    bob = (draw(st.integers(0, n - 1)), _decade(draw), tuple(draw(st.floats(-0.5, 0.5)) for _ in range(dim)))
    return dim, spec, _decade(draw, 0, 2), _decade(draw, -2, 0), direction, bob


def build(tree, dynamics):
    dim, spec, k, c, direction, (carrier, bob, tip) = tree
    m = lg.Model("tree", dim=dim, dynamics=dynamics)
    for i, (parent, kind, body, mass, length, point, child, axis, seq) in enumerate(spec):
        name = f"b{i}"
        points = {"points": {"tip": tip}} if i == carrier else {}
        if body == "rod":
            m.add("rod", name, name, m=mass, length=length, **points)
        elif body == "disc":
            m.add("disc", name, name, m=mass, radius=length / 2, **points)
        else:
            inertia = mass * length**2 / 12 if dim == 2 else tuple(mass * length**2 * f for f in (0.1, 0.12, 0.15))
            m.add("body", name, name, m=mass, inertia=inertia, com=tuple(x / 3 for x in child), **points)
        extra = {}
        if kind in ("revolute", "prismatic") and (dim == 3 or kind == "prismatic"):
            extra["axis"] = axis
        if kind in ("spherical", "free") and dim == 3:
            extra["sequence"] = seq
        if kind == "fixed" and dim == 2:
            extra["angle"] = 0.3
        m.add(kind, f"j{i}", (parent, name), parent_point=point if parent != "ground" else None, child_point=child, **extra)
    m.add("mass", "bob", f"b{carrier}.tip", m=bob)
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


@st.composite
def looped(draw, dim):
    """A random tree (:func:`trees`) with a loop closed by a revolute (planar) or spherical joint between its last
    body and an earlier body or the ground, at random points, and a constraint of the user's own on two
    coordinates: loops of every joint kind, and over-constrained ones (refused as redundant, as the closed form's
    solve is singular)."""
    tree = draw(trees(dim))
    n = len(tree[1])
    depth = {"ground": 0}
    for i, (parent, *_) in enumerate(tree[1]):
        depth[f"b{i}"] = depth[parent] + 1
    # the joint tree is found from the ground outwards, along joints from parent to child: the new joint goes from
    # the last body to one no farther from the ground (or from the ground, when the last body hangs from it), so
    # that it closes the loop and every body keeps its own joint
    last = f"b{n - 1}"
    other = draw(st.sampled_from([b for b in depth if b != last and 0 < depth[b] <= depth[last]]
                                 + (["ground"] if depth[last] == 1 else [])))
    points = [tuple(draw(st.floats(-0.4, 0.4)) for _ in range(dim)) for _ in range(2)]
    pair = ("ground", last) if other == "ground" else (last, other)
    return tree, (*pair, points, draw(st.floats(0.5, 2.0)))


def build_looped(spec, dynamics):
    tree, (a, b, (pa, pb), ratio) = spec
    m = build(tree, dynamics)
    m.add("revolute" if tree[0] == 2 else "spherical", "close", (a, b),
          parent_point=pa if a != "ground" else (0.3,) * tree[0], child_point=pb)
    names = m.coordinate_names
    m.add("constraint", "gear", f=lg.coordinate(names[0]) - ratio * lg.coordinate(names[-1]))
    return m


def _check_looped(spec):
    closed = build_looped(spec, "closed")
    n = len(closed.coordinate_names)
    rng = np.random.default_rng(1)
    states = [np.concatenate([rng.uniform(-0.6, 0.6, n), rng.uniform(-1, 1, n)]) for _ in range(3)]
    c = closed.numeric().compile("tape")
    systems = [c.matrix(0.4, y[:n], y[n:]) for y in states]
    try:
        fast = build_looped(spec, "recursive")
        fast.eq
    except lg.ModelError as exc:  # redundant constraints: the closed form's solve is singular as well
        assert "not independent" in str(exc)
        assert all(np.linalg.cond(A) > 1e9 for A, _ in systems)
        return
    f = fast.numeric().compile("tape")
    for y, (A, b) in zip(states, systems):
        if np.linalg.cond(A) > 1e8:  # (near a singular configuration: both are right to rounding alone)
            continue
        u_closed = np.linalg.solve(A, b)
        I, u = f.matrix(0.4, y[:n], y[n:])
        assert np.array_equal(I, np.eye(len(u))) and u.shape == u_closed.shape  # accelerations, then multipliers
        assert np.max(np.abs(u - u_closed)) <= 1e-8 * (np.max(np.abs(u_closed)) + 1e-300), (u, u_closed)


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(looped(2))
def test_planar_loops_and_constraints_on_the_recursion_agree_with_the_closed_form(spec):
    """The tree's accelerations and M⁻¹Jᵀ by the recursion, the constraint forces from a k × k solve: the same
    accelerations and multipliers as the closed form's solve of M q̈ − Jᵀλ = f, J q̈ = rhs."""
    _check_looped(spec)


@settings(max_examples=5, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(looped(3))
def test_spatial_loops_and_constraints_on_the_recursion_agree_with_the_closed_form(spec):
    _check_looped(spec)


def four_bar(dynamics):
    m = lg.Model("four-bar", dim=2, dynamics=dynamics)
    for name, length, mass in (("crank", 0.3, 0.21), ("coupler", 0.9, 0.47), ("rocker", 0.6, 0.33)):
        m.add("rod", name, name, m=mass, length=length)
    m.add("revolute", "A", ("ground", "crank"))
    m.add("revolute", "B", ("crank", "coupler"), parent_point=(0.3, 0))
    m.add("revolute", "D", ("ground", "rocker"), parent_point=(0.9, 0))
    m.add("revolute", "C", ("coupler", "rocker"), parent_point=(0.9, 0), child_point=(0.6, 0))
    m.add("gravity", "g", g=9.81)
    return m


def test_a_four_bar_on_the_recursion_keeps_its_loop_and_its_energy_and_says_how():
    """Physics: T + V of a frictionless four-bar under gravity is kept, the loop stays closed (the rocker tip by
    hand geometry), and the report names the constraint solve."""
    from lagrangian.plugins.multibody.constraints import consistent_initial

    m = four_bar("recursive")
    q0, v0 = consistent_initial(m, {"theta_A": 0.6, "theta_D": 1.5, "theta_B": 0.3}, {"theta_A": 1.3},
                                independent=["theta_A"])
    res = m.simulate(3.0, initial=q0, velocity=v0, rtol=1e-10, atol=1e-12, points=200)
    assert any("forces of 2 constraints from a 2 × 2 solve" in note for note in res.notes)
    assert np.max(np.abs(res.E - res.E[0])) <= 1e-8 * np.max(np.abs(res.V))
    A, B, D = res["theta_A"], res["theta_B"], res["theta_D"]
    gap = np.hypot(0.3 * np.cos(A) + 0.9 * np.cos(A + B) - 0.9 - 0.6 * np.cos(D),
                   0.3 * np.sin(A) + 0.9 * np.sin(A + B) - 0.6 * np.sin(D))
    assert np.max(gap) <= 1e-8


@pytest.mark.parametrize("kind", ["tape", "native"])
def test_a_four_bar_folded_flat_is_a_singular_configuration_named_so(kind):
    """Crank, coupler and rocker along one line: the loop's two rows of J are parallel, J M⁻¹ Jᵀ is singular, so
    the constraint forces are not determined (the closed form's solve is singular there too)."""
    if kind == "native" and lg.codegen.compiler() is None:
        pytest.skip("no C compiler")
    fast = four_bar("recursive").numeric().compile(kind)
    flat = np.zeros(6)
    A, b = four_bar("closed").numeric().compile("tape").matrix(0.0, flat[:3], flat[3:])
    assert np.linalg.matrix_rank(A) < A.shape[0]
    with pytest.raises(lg.SingularMassMatrixError, match="constraints are not independent at t=0"):
        fast.rhs(0.0, flat)
    assert np.all(np.isfinite(fast.rhs(0.0, np.array([0.6, 1.5, 0.3, 0.0, 0.0, 0.0]))))


def test_a_knife_edge_on_the_recursion_runs_as_the_closed_form():
    """A constraint on velocities (Chaplygin's sleigh) on the recursion: the same run as the closed form."""
    runs = []
    for dynamics in ("recursive", "closed"):
        m = lg.Model("sleigh", dim=2, dynamics=dynamics)
        m.add("body", "b", "b", m=0.7, inertia=0.03, com=(0.1, 0.0), points={"edge": (-0.2, 0.0)})
        m.add("free", "j", ("ground", "b"))
        m.add("knife_edge", "k", "b.edge")
        th, U, w = 0.2, 0.5, 0.8  # (the edge 0.2 behind the origin moves along the body: v·n = 0.2 ω across it)
        runs.append(m.simulate(2.0, initial={"x_j": 0.0, "y_j": 0.0, "theta_j": th},
                               velocity={"x_j": U * np.cos(th) - 0.2 * w * np.sin(th),
                                         "y_j": U * np.sin(th) + 0.2 * w * np.cos(th), "theta_j": w},
                               rtol=1e-11, atol=1e-13, points=50))
    assert runs[0].notes != runs[1].notes
    for name in ("x_j", "y_j", "theta_j"):
        assert np.max(np.abs(runs[0][name] - runs[1][name])) <= 1e-8


def _check_linearization(tree):
    """The closed form's linearization about the rest point its Newton iteration finds, and the recursion's about the
    same point (forward derivatives through its steps): the same M, C, K and input matrices."""
    from hypothesis import assume

    from lagrangian import frequency

    def driven(dynamics):  # inputs: a force on the last body, a generalized force on the first coordinate
        m = build(tree, dynamics)
        m.add("force", "F", f"b{len(tree[1]) - 1}.com", F=(0.0,) * tree[0])
        m.add("generalized_force", "tq", coordinate=m.coordinate_names[0], Q=0.0)
        return m

    inputs = {"inputs": ["F[0]", "tq"]}
    try:
        closed = frequency.linearize(driven("closed"), **inputs)
    except lg.ModelError:  # no rest point found from the origin (a tree that topples): nothing to compare
        assume(False)
    fast = driven("recursive")
    from lagrangian.analysis import linearize as module

    taken, real = [], module._by_recursion
    with pytest.MonkeyPatch.context() as mp:  # (which path gave the result: the twin with inputs is a model of its own)
        mp.setattr(module, "_by_recursion", lambda *a, **k: taken.append(real(*a, **k)) or taken[-1])
        lin = frequency.linearize(fast, closed.at, **inputs)
    if taken and np.linalg.cond(closed.M) < 1e8:  # (none: a linear tree, read off its stamps; at a gimbal lock the
        assert taken[0] is not None                 # recursion's pivots vanish and the closed form decides)
    pairs = [(getattr(lin, k), getattr(closed, k), k) for k in ("M", "C", "K", "Bi")]
    assert len(lin.B) == len(closed.B)
    # a damping matrix is compared on the scale of damping the tree has, √(|M| |K|): a C of rounding residues
    # (1e-35 beside an M of 1, from offsets of 1e-38) is zero, however its residues differ
    damping = np.sqrt(np.max(np.abs(closed.M)) * np.max(np.abs(closed.K), initial=0.0))
    for a, b, name in pairs + [(x, y, "B") for x, y in zip(lin.B, closed.B)]:
        scale = np.max(np.abs(b), initial=0.0) + (damping if name == "C" else 0.0)
        assert np.max(np.abs(a - b), initial=0.0) <= 1e-8 * (scale + 1e-300), name


@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(trees(2))
def test_planar_trees_linearize_through_the_recursion_as_in_closed_form(tree):
    _check_linearization(tree)


@settings(max_examples=4, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(trees(3))
@example(tree=(3, [("ground", "spherical", "body", 1.0, 1.0, (-0.5714543451377666, 0.3783662814481119, -1.1132995860788424e-66),
                    (-0.171461979723528, -0.24630976845955932, -0.20947200535279725), (-1.0, -1.0, -1.0), "xyz"),
                   ("b0", "revolute", "body", 1.0, 1.023292992280754, (0.19294068934185615, 0.10031017902347816,
                    -0.4455915671692971), (-0.2968065684648368, 0.23297786989120894, 0.2259533262559184),
                    (0.0, 1.0, 1.0), "zxz")],
               21.55327415420814, 0.07543171272615329, (0.625816912578308, -0.11695063328534228, -1.0),
               (0, 1.0, (-0.2673958417786823, -1.1754943508222875e-38, 5.4272840442434254e-117))))
def test_spatial_trees_linearize_through_the_recursion_as_in_closed_form(tree):
    _check_linearization(tree)


def test_a_hanging_chain_of_forty_rods_swings_at_the_continuous_chains_frequencies():
    """Physics: a chain of n rods of total length L hanging under gravity tends to the continuous chain, whose modes
    swing at ω_k = (j_k / 2) √(g / L), j_k the zeros of J₀ (Bernoulli, Euler); at n = 40 the first two are within
    2e-5 and 7e-4.  The linearization comes from the recursion: the closed form of 40 links is never derived."""
    from scipy.special import jn_zeros

    from lagrangian import frequency

    n, length = 40, 0.2
    m = models.pendulum_chain(n, m=0.3, length=length)
    m.add("force", "F", f"r{n - 1}.end", F=(0.0, 0.0))
    lin = frequency.linearize(m, {"theta_j0": -np.pi / 2}, inputs=["F[0]"])
    assert m.eq.recursion is not None and "M" not in m.eq._generic
    # a horizontal force F at the free end: on the relative angle θ_i it acts through the n − i rods beyond joint i,
    # each hanging straight down (absolute angle −π/2): ∂x_end/∂θ_i = (n − i) L
    assert np.allclose(lin.B[0][:, 0], length * (n - np.arange(n)), rtol=1e-12)
    w = np.sqrt(np.sort(np.linalg.eigvals(np.linalg.solve(lin.M, lin.K)).real))[:2]
    continuous = jn_zeros(0, 2) / 2 * np.sqrt(9.81 / (n * length))
    assert abs(w[0] / continuous[0] - 1) < 1e-4 and abs(w[1] / continuous[1] - 1) < 2e-3


def test_the_numpy_path_runs_the_recursion_and_never_the_closed_form():
    """compiled=False (as where no C compiler is at hand): the recursion's steps as NumPy code, its energies and
    Jacobi integral from the energy tape on NumPy arrays; the same run as the tape interpreter's."""
    m = chain(9, "recursive")
    init = {f"theta_j{k}": 0.2 * (-1) ** k for k in range(9)}
    rates = {f"theta_j{k}": 0.1 * k for k in range(9)}
    a = m.simulate(0.3, initial=init, velocity=rates, points=5, compiled=False, rtol=1e-10, atol=1e-12)
    assert "M" not in m.eq._generic  # (the closed form of nine links is never derived)
    b = m.simulate(0.3, initial=init, velocity=rates, points=5, compiled="tape", rtol=1e-10, atol=1e-12)
    for name in m.coordinate_names:
        assert np.max(np.abs(a[name] - b[name])) <= 1e-12
    assert np.max(np.abs(a.E - b.E)) <= 1e-12 * np.max(np.abs(b.V))
    assert "energy (Jacobi integral) kept" in a.notes[-1]


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
    ("loop closed twice", "constraints are not independent"),
    ("driven", "is driven"),
    ("mass on a spring", "acts on 'bob', not a rigid body"),
    ("massless end", "have no inertia about their joints' axes"),
])
def test_what_the_recursion_cannot_serve_is_refused_by_name(case, words):
    m = chain(3, "recursive")
    if case == "loop closed twice":
        m.add("revolute", "close", ("r2", "r0"), parent_point=(0.7, 0), child_point=(0.3, 0))
        m.add("revolute", "again", ("r2", "r0"), parent_point=(0.7, 0), child_point=(0.3, 0))
    elif case == "driven":
        m.add("rod", "d", "d", m=0.1, length=0.2)
        m.add("revolute", "jd", ("r2", "d"), angle=lg.t)
    elif case == "mass on a spring":
        m.add("mass", "bob", "hung", m=0.2)
        m.add("spring", "s", ("r2.end", "hung"), k=30.0)
    else:
        m.add("link", "l", "l", points={"tip": (0.2, 0)})
        m.add("revolute", "jl", ("r2", "l"), parent_point=(0.7, 0))
    with pytest.raises(lg.ModelError, match=words):
        m.eq


def test_auto_falls_back_to_the_closed_form_where_the_recursion_cannot_serve():
    m = chain(recursive.RECURSIVE_FROM)
    m.add("mass", "bob", "hung", m=0.2)
    m.add("spring", "s", (f"r{recursive.RECURSIVE_FROM - 1}.end", "hung"), k=30.0)
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


def spatial_chain(n, first_mass=0.3):
    m = lg.Model(f"{n} bodies", dim=3)
    parent = "ground"
    for k in range(n):
        m.add("body", f"B{k}", f"B{k}", m=0.3 + 0.07 * k if k else first_mass, inertia=(0.02, 0.03, 0.04), com=(0, 0, -0.25))
        m.add("spherical", f"j{k}", (parent, f"B{k}"), **({"parent_point": (0, 0, -0.5)} if k else {}))
        parent = f"B{k}"
    m.add("gravity", "g", g=9.81)
    return m


@pytest.mark.timeout(300)
def test_the_displayed_equations_and_jacobi_integral_of_a_large_spatial_chain_hold_for_the_recursions_motion():
    """Six bodies on spherical joints (18 coordinates, the recursion's): ``m.equations`` (the closed form, unevaluated
    products of its large entries) are satisfied by the accelerations of the articulated-body algorithm, and the
    Jacobi integral, conserved, equals the energy tape's T + V; deciding either walked the whole trees before."""
    from lagrangian.derivation.derive import Rewriter
    from lagrangian.numerics.tape import record
    from lagrangian import routh

    m = spatial_chain(6)
    numeric = m.numeric()
    eq = m.eq
    assert eq.recursion is not None
    n = len(eq.names)
    back = Rewriter({**eq._to_sym, **{sp.Derivative(c.function, (lg.t, 2)): a
                                      for c, a in zip(eq.coordinates, eq.sym.a)}})
    rows = [back(sp.Add(e.lhs, sp.Mul(-1, e.rhs, evaluate=False), evaluate=False)) for e in m.equations]
    sizes = [back(e.lhs) for e in m.equations]
    h = routh.jacobi_integral(m)
    assert h.conserved and h.energy_conserved
    tape = record([*rows, *sizes, back(h.expr)], [*eq.sym.q, *eq.sym.v, *eq.sym.a])
    rng = np.random.default_rng(3)
    for _ in range(3):
        q, v = rng.uniform(-0.6, 0.6, n), rng.uniform(-1.0, 1.0, n)
        a = numeric.rhs(0.0, np.concatenate([q, v]))[n:]
        out = np.array(tape.evaluate([*q, *v, *a]))
        residual, size, jacobi = out[:n], out[n:2 * n], out[-1]
        assert np.max(np.abs(residual)) <= 1e-9 * max(np.max(np.abs(size)), 1.0)
        T, V, _ = numeric.energies(np.array([0.0]), q[:, None], v[:, None])
        assert abs(jacobi - (T[0] + V[0])) <= 1e-10 * (abs(T[0]) + abs(V[0]))


@pytest.mark.parametrize("compiled, wrt", [("auto", "m_r3"), (False, "theta_j0")])
def test_sensitivities_of_a_chain_the_recursion_serves_equal_differences_of_runs(compiled, wrt):
    """Forward sensitivities of a 10-link chain (the recursion's by default) to a mass (compiled code) and an initial
    angle (NumPy), against central differences of runs (an independent reference) and the closed form's; the
    recursion's solve was taken for the closed form's before, and gave sensitivities wrong by a factor of 10⁴ on
    NumPy and a false singular matrix in C."""
    m = chain(10)
    assert m.eq.recursion is not None
    init = {f"theta_j{k}": 0.1 + 0.02 * k for k in range(10)}
    kw = dict(points=4, rtol=1e-11, atol=1e-13)
    res = m.simulate(0.3, initial=init, sensitivities=[wrt], compiled=compiled, **kw)
    assert res.notes[0].startswith("sensitivities: from the model's closed-form equations")
    h = 1e-6
    runs = []
    for sign in (1, -1):
        if wrt == "m_r3":
            runs.append(m.simulate(0.3, initial=init, params={"m_r3": m.parameter_values["m_r3"] + sign * h}, **kw))
        else:
            runs.append(m.simulate(0.3, initial={**init, wrt: init[wrt] + sign * h}, **kw))
    for name in ("theta_j0", "theta_j5", "theta_j9"):
        reference = (runs[0][name] - runs[1][name]) / (2 * h)
        got = res.sensitivity(name, wrt)
        assert np.max(np.abs(got - reference)) <= 1e-5 * max(np.max(np.abs(reference)), 1e-3), name
    if wrt == "m_r3":
        closed = chain(10, "closed").simulate(0.3, initial=init, sensitivities=[wrt], **kw)
        assert np.max(np.abs(closed.sensitivity("theta_j5", wrt) - res.sensitivity("theta_j5", wrt))) <= 1e-9


@pytest.mark.timeout(300)
def test_a_large_spatial_chain_linearizes_symbolically_as_the_recursion_does_in_numbers():
    """Six bodies on spherical joints, the first one's mass a symbol: the closed form's linearization (forward
    derivatives at the point), with the mass given afterwards, equals the articulated-body algorithm's tangents for
    the same mass in numbers (an independent derivation).  The numeric chain is linearized first, so the symbolic
    one's forces share parts with its derivation: lookups by equality compared those as trees (10⁷ comparisons)."""
    from lagrangian import frequency

    n = 6
    numbers = spatial_chain(n)
    rest = {f"{a}_j{k}": 0.0 for k in range(n) for a in ("alpha", "beta", "gamma")}
    reference = frequency.linearize(numbers, rest)
    m0 = sp.Symbol("m0", positive=True)
    lin = frequency.linearize(spatial_chain(n, first_mass=m0), rest)
    assert lin.symbolic and m0 in lin.parameters
    value = 0.3  # (spatial_chain's first mass)
    for name in ("M", "C", "K"):
        got = np.array(sp.Matrix(getattr(lin, name)).xreplace({m0: value}), dtype=float)
        want = np.asarray(getattr(reference, name), dtype=float)
        assert np.max(np.abs(got - want)) <= 1e-10 * np.max(np.abs(want)), name
