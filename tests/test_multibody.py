"""Rigid bodies and joints against independent derivations.

Expected values come from outside the code under test: the same mechanisms
built in ``sympy.physics.mechanics`` (an independent Lagrange/Kane engine,
its own frames, kinematics and energies), closed forms derived by hand in the
comments, conservation laws, and SciPy integrating hand-written ODEs.

Coordinate conventions mirrored in the SymPy models (see the multibody plugin's
docstring): a planar revolute angle turns the child relative to its parent
(``absolute=True``: the child's angle to the fixed x axis), a rod lies along
its body x axis from its origin; the spherical joint uses body-fixed x-y-z
Euler angles, R = Rx(α) Ry(β) Rz(γ).

Thresholds.  M and f are compared at random states to 1e-10 relative to the
largest entry (both engines evaluate the same physics in floating point; a
convention error — a sign, a swapped axis, a wrong inertia term — shows as
O(1)).  Energy and momenta: DOP853 at rtol=1e-12, atol=1e-14 keeps drifts
~1e-11 over these runs (measured); we assert < 1e-8.  Loop closure is held by
Baumgarte stabilization from a consistent start; measured ~1e-12, asserted
< 1e-8.
"""

from __future__ import annotations

import math
import re
import warnings

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me
from scipy.integrate import solve_ivp
from scipy.special import ellipk

import lagrangian as lg
from lagrangian.plugins.multibody import consistent_initial, constraint_residual, independent_coordinates

t = lg.t
TIGHT = {"rtol": 1e-12, "atol": 1e-14}
RNG = np.random.default_rng(20240607)
G = 9.81


@pytest.fixture(autouse=True)
def _quiet_initial_conditions():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lg.InitialConditionWarning)
        yield


# ---------------------------------------------------------------------------
# Helpers
# ---------------------------------------------------------------------------


def ours(model: lg.Model):
    """M(q, q̇, t) and f(q, q̇, t) of the model as NumPy functions of (q, v), with our coordinate order."""
    eq = model.eq
    M = sp.lambdify((eq.sym.q, eq.sym.v), eq.M.subs(t, 0), "numpy")
    f = sp.lambdify((eq.sym.q, eq.sym.v), eq.f.subs(t, 0), "numpy")
    return lambda q, v: np.asarray(M(q, v), dtype=float), lambda q, v: np.asarray(f(q, v), dtype=float).reshape(-1)


def theirs(mass_matrix, forcing, q, qd):
    """SymPy mechanics' mass matrix and forcing in the dynamicsymbols ``q`` (velocities ``qd``) as NumPy functions."""
    Q = sp.symbols(f"Q0:{len(q)}")
    U = sp.symbols(f"U0:{len(q)}")
    subs = {**dict(zip(qd, U)), **{qi.diff(t_mech()): u for qi, u in zip(q, U)}}
    mm = mass_matrix.xreplace({**subs, **dict(zip(q, Q))})
    ff = forcing.xreplace({**subs, **dict(zip(q, Q))})
    M = sp.lambdify((Q, U), mm, "numpy", cse=True)
    f = sp.lambdify((Q, U), ff, "numpy", cse=True)
    return lambda a, b: np.asarray(M(a, b), dtype=float), lambda a, b: np.asarray(f(a, b), dtype=float).reshape(-1)


def t_mech():
    return me.dynamicsymbols._t


def agree(model, ref_M, ref_f, states=8, scale_q=math.pi, scale_v=2.0):
    """Largest relative difference of M and f between the model and the reference at random states."""
    M, f = ours(model)
    n = len(model.coordinate_names)
    worst = 0.0
    for _ in range(states):
        q = RNG.uniform(-scale_q, scale_q, n)
        v = RNG.uniform(-scale_v, scale_v, n)
        for a, b in ((M(q, v), ref_M(q, v)), (f(q, v), ref_f(q, v))):
            worst = max(worst, float(np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300)))
    return worst


def planar_lagrange(bodies, particles, V, q, N):
    """Mass matrix and forcing from SymPy's LagrangesMethod for L = Σ T − V."""
    T = sum((b.kinetic_energy(N) for b in bodies + particles), sp.Integer(0))
    lm = me.LagrangesMethod(T - V, q)
    lm.form_lagranges_equations()
    return lm.mass_matrix, lm.forcing


def fn(name):
    return sp.Function(name, real=True)(t)


# ---------------------------------------------------------------------------
# Builders (plain model construction; no expected values)
# ---------------------------------------------------------------------------


def double_pendulum(m1=1.0, L1=1.0, m2=0.7, L2=1.3, bob=0.4, g=G) -> lg.Model:
    """Two uniform rods with absolute angles, a point mass at the free end, gravity −y."""
    m = lg.Model("double pendulum", dim=2)
    m.add("rod", "r1", "r1", m=m1, length=L1)
    m.add("rod", "r2", "r2", m=m2, length=L2)
    m.add("revolute", "j1", ("ground", "r1"), absolute=True)
    m.add("revolute", "j2", ("r1", "r2"), parent_point=(L1, 0), absolute=True)
    if bob:
        m.add("mass", "bob", "r2.end", m=bob)
    m.add("gravity", "g", g=g)
    return m


CHAIN = {"m": [1.0, 0.8, 1.2, 0.6, 0.9], "L": [1.0, 0.7, 1.1, 0.5, 0.8], "k": [3.0, 2.0, 1.5, 1.0, 0.5], "c": [0.3, 0.2, 0.1, 0.4, 0.25]}


def chain(n=5) -> lg.Model:
    """n rods, relative angles, a rotational spring and damper across every joint, gravity −y."""
    m = lg.Model(f"{n}-link chain", dim=2)
    parent = "ground"
    for i in range(n):
        m.add("rod", f"r{i}", f"r{i}", m=CHAIN["m"][i], length=CHAIN["L"][i])
        point = (0, 0) if parent == "ground" else (CHAIN["L"][i - 1], 0)
        m.add("revolute", f"j{i}", (parent, f"r{i}"), parent_point=point)
        m.add("rotational_spring", f"k{i}", (parent, f"r{i}"), k=CHAIN["k"][i])
        m.add("rotational_damper", f"c{i}", (parent, f"r{i}"), c=CHAIN["c"][i])
        parent = f"r{i}"
    m.add("gravity", "g", g=G)
    return m


BP = {"m": 2.0, "I": 0.35, "com": (0.3, 0.1), "tip": (1.0, -0.2), "pin": (0.5, 1.0), "at": (0.1, 0.2), "anchor": (2.0, 0.0),
      "k": 7.0, "l0": 0.5}


def body_pendulum() -> lg.Model:
    """A planar rigid body pinned off its centre of mass at (0.5, 1); a spring from a point of a frame welded to
    the ground (a link on a fixed joint) to the body's tip."""
    m = lg.Model("body pendulum", dim=2)
    m.add("body", "b", "b", m=BP["m"], inertia=BP["I"], com=BP["com"], points={"tip": BP["tip"]})
    m.add("link", "frame", "frame", points={"anchor": BP["anchor"]})
    m.add("fixed", "weld", ("ground", "frame"))
    m.add("revolute", "pin", ("ground", "b"), parent_point=BP["pin"], child_point=BP["at"])
    m.add("spring", "k", ("frame.anchor", "b.tip"), k=BP["k"], rest_length=BP["l0"])
    m.add("gravity", "g", g=G)
    return m


SB = {"m": 1.5, "I": [[0.9, 0.05, -0.1], [0.05, 1.2, 0.08], [-0.1, 0.08, 1.6]], "com": (0.1, -0.2, 0.3),
      "pivot": (0.2, 0.1, 1.0), "at": (0.05, 0.1, 0.6)}


def spherical_body(g=G) -> lg.Model:
    """A 3-D rigid body with a full inertia tensor on a spherical joint away from its centre of mass."""
    m = lg.Model("spherical body", dim=3)
    m.add("body", "b", "b", m=SB["m"], inertia=SB["I"], com=SB["com"])
    m.add("spherical", "ball", ("ground", "b"), parent_point=SB["pivot"], child_point=SB["at"])
    if g:
        m.add("gravity", "g", g=g)
    return m


def four_bar(crank=1.0, coupler=3.0, rocker=2.0, ground=3.0, driven=None) -> lg.Model:
    m = lg.Model("four-bar", dim=2)
    for name, length in (("crank", crank), ("coupler", coupler), ("rocker", rocker)):
        m.add("rod", name, name, m=1.0, length=length)
    kw = {} if driven is None else {"angle": driven}
    m.add("revolute", "A", ("ground", "crank"), absolute=True, **kw)
    m.add("revolute", "B", ("crank", "coupler"), parent_point=(crank, 0), absolute=True)
    m.add("revolute", "D", ("ground", "rocker"), parent_point=(ground, 0), absolute=True)
    m.add("revolute", "C", ("coupler", "rocker"), parent_point=(coupler, 0), child_point=(rocker, 0))
    m.add("gravity", "g", g=G)
    return m


def slider_crank(r=1.0, l=3.0, driven=None) -> lg.Model:
    m = lg.Model("slider-crank", dim=2)
    m.add("rod", "crank", "crank", m=1.0, length=r)
    m.add("rod", "rod", "rod", m=0.5, length=l)
    m.add("body", "slider", "slider", m=2.0, inertia=0.1)
    kw = {} if driven is None else {"angle": driven}
    m.add("revolute", "O", ("ground", "crank"), absolute=True, **kw)
    m.add("revolute", "A", ("crank", "rod"), parent_point=(r, 0), absolute=True)
    m.add("prismatic", "P", ("ground", "slider"))
    m.add("revolute", "B", ("rod", "slider"), parent_point=(l, 0))
    m.add("gravity", "g", g=G)
    return m


# ---------------------------------------------------------------------------
# Equations of motion against sympy.physics.mechanics
# ---------------------------------------------------------------------------


def test_double_pendulum_matches_sympy_mechanics():
    m1, L1, m2, L2, mb = 1.0, 1.0, 0.7, 1.3, 0.4
    q1, q2 = me.dynamicsymbols("q1 q2")
    N = me.ReferenceFrame("N")
    A = N.orientnew("A", "Axis", (q1, N.z))
    B = N.orientnew("B", "Axis", (q2, N.z))
    O = me.Point("O")
    O.set_vel(N, 0)
    G1, P1 = O.locatenew("G1", L1 / 2 * A.x), O.locatenew("P1", L1 * A.x)
    G2, P2 = P1.locatenew("G2", L2 / 2 * B.x), P1.locatenew("P2", L2 * B.x)
    for P in (G1, P1, G2, P2):
        P.set_vel(N, P.pos_from(O).dt(N))
    rod1 = me.RigidBody("rod1", G1, A, m1, (me.inertia(A, 0, m1 * L1**2 / 12, m1 * L1**2 / 12), G1))
    rod2 = me.RigidBody("rod2", G2, B, m2, (me.inertia(B, 0, m2 * L2**2 / 12, m2 * L2**2 / 12), G2))
    bob = me.Particle("bob", P2, mb)
    V = G * (m1 * G1.pos_from(O).dot(N.y) + m2 * G2.pos_from(O).dot(N.y) + mb * P2.pos_from(O).dot(N.y))
    MM, F = planar_lagrange([rod1, rod2], [bob], V, [q1, q2], N)
    model = double_pendulum(m1, L1, m2, L2, mb)
    assert model.coordinate_names == ["theta_j1", "theta_j2"]
    assert agree(model, *theirs(MM, F, [q1, q2], [q1.diff(), q2.diff()])) < 1e-10


@pytest.mark.slow
def test_five_link_chain_with_joint_springs_and_dampers_matches_sympy_mechanics():
    n = 5
    q = me.dynamicsymbols(f"q0:{n}")
    N = me.ReferenceFrame("N")
    O = me.Point("O")
    O.set_vel(N, 0)
    frames, bodies, V = [], [], sp.Integer(0)
    joint, total = O, sp.Integer(0)
    loads = []
    for i in range(n):
        total = total + q[i]  # relative angles: frame i is turned by q0 + … + qi
        F = N.orientnew(f"F{i}", "Axis", (total, N.z))
        L, mass = CHAIN["L"][i], CHAIN["m"][i]
        Gi = joint.locatenew(f"G{i}", L / 2 * F.x)
        Gi.set_vel(N, Gi.pos_from(O).dt(N))
        bodies.append(me.RigidBody(f"r{i}", Gi, F, mass, (me.inertia(F, 0, mass * L**2 / 12, mass * L**2 / 12), Gi)))
        V += mass * G * Gi.pos_from(O).dot(N.y) + CHAIN["k"][i] * q[i] ** 2 / 2
        # a torsional damper across joint i: torque −c q̇ᵢ on body i, +c q̇ᵢ on its parent
        tau = -CHAIN["c"][i] * q[i].diff()
        loads.append((F, tau * N.z))
        if i:
            loads.append((frames[-1], -tau * N.z))
        frames.append(F)
        joint = joint.locatenew(f"J{i + 1}", L * F.x)
    T = sum((b.kinetic_energy(N) for b in bodies), sp.Integer(0))
    lm = me.LagrangesMethod(T - V, list(q), forcelist=loads, frame=N)
    lm.form_lagranges_equations()
    model = chain(n)
    assert model.coordinate_names == [f"theta_j{i}" for i in range(n)]
    assert agree(model, *theirs(lm.mass_matrix, lm.forcing, list(q), [qi.diff() for qi in q]), states=4) < 1e-10


def test_planar_body_pendulum_with_spring_matches_sympy_mechanics():
    th = me.dynamicsymbols("th")
    N = me.ReferenceFrame("N")
    A = N.orientnew("A", "Axis", (th, N.z))
    O = me.Point("O")
    O.set_vel(N, 0)
    pin = O.locatenew("pin", BP["pin"][0] * N.x + BP["pin"][1] * N.y)
    origin = pin.locatenew("Ob", -(BP["at"][0] * A.x + BP["at"][1] * A.y))
    Gc = origin.locatenew("G", BP["com"][0] * A.x + BP["com"][1] * A.y)
    tip = origin.locatenew("tip", BP["tip"][0] * A.x + BP["tip"][1] * A.y)
    Gc.set_vel(N, Gc.pos_from(O).dt(N))
    body = me.RigidBody("b", Gc, A, BP["m"], (me.inertia(A, 0, 0, BP["I"]), Gc))
    d = tip.pos_from(O) - BP["anchor"][0] * N.x - BP["anchor"][1] * N.y
    V = BP["m"] * G * Gc.pos_from(O).dot(N.y) + BP["k"] * (sp.sqrt(d.dot(d)) - BP["l0"]) ** 2 / 2
    MM, F = planar_lagrange([body], [], V, [th], N)
    model = body_pendulum()
    assert model.coordinate_names == ["theta_pin"]
    assert agree(model, *theirs(MM, F, [th], [th.diff()])) < 1e-10


@pytest.mark.slow
def test_spatial_body_on_spherical_joint_matches_sympy_kane():
    a, b, c = me.dynamicsymbols("a b c")
    ua, ub, uc = me.dynamicsymbols("ua ub uc")
    N = me.ReferenceFrame("N")
    B = me.ReferenceFrame("B")
    B.orient_body_fixed(N, (a, b, c), "xyz")
    O = me.Point("O")
    O.set_vel(N, 0)
    pivot = O.locatenew("P", sum((x * e for x, e in zip(SB["pivot"], (N.x, N.y, N.z))), sp.S(0) * N.x))
    origin = pivot.locatenew("Ob", -sum((x * e for x, e in zip(SB["at"], (B.x, B.y, B.z))), sp.S(0) * B.x))
    Gc = origin.locatenew("G", sum((x * e for x, e in zip(SB["com"], (B.x, B.y, B.z))), sp.S(0) * B.x))
    Gc.set_vel(N, Gc.pos_from(O).dt(N))
    I = SB["I"]
    body = me.RigidBody("b", Gc, B, SB["m"], (me.inertia(B, I[0][0], I[1][1], I[2][2], I[0][1], I[1][2], I[2][0]), Gc))
    kane = me.KanesMethod(N, q_ind=[a, b, c], u_ind=[ua, ub, uc], kd_eqs=[a.diff() - ua, b.diff() - ub, c.diff() - uc])
    kane.kanes_equations([body], [(Gc, -SB["m"] * G * N.z)])
    model = spherical_body()
    assert model.coordinate_names == ["alpha_ball", "beta_ball", "gamma_ball"]
    # stay off gimbal lock (|β| < π/2) where both sides are finite
    assert agree(model, *theirs(kane.mass_matrix, kane.forcing, [a, b, c], [ua, ub, uc]), scale_q=1.3) < 1e-10


# ---------------------------------------------------------------------------
# Conservation laws
# ---------------------------------------------------------------------------


def test_double_pendulum_conserves_energy_over_many_periods():
    model = double_pendulum()
    # small-oscillation periods are ~1.4 s and ~3.6 s; 40 s is > 10 of the slow one, and the motion is chaotic-ish
    res = model.simulate(40, initial={"theta_j1": -math.pi / 2 + 1.2, "theta_j2": -math.pi / 2 - 0.8},
                         velocity={"theta_j1": 0.5, "theta_j2": -1.0}, points=2001, **TIGHT)
    assert res.energy_drift() < 1e-8
    assert np.ptp(res["theta_j2"]) > 1.0  # it really swung


def euler_xyz(a, b, c):
    """R = Rx(a) Ry(b) Rz(c), written out by hand (the documented convention)."""
    Rx = sp.Matrix([[1, 0, 0], [0, sp.cos(a), -sp.sin(a)], [0, sp.sin(a), sp.cos(a)]])
    Ry = sp.Matrix([[sp.cos(b), 0, sp.sin(b)], [0, 1, 0], [-sp.sin(b), 0, sp.cos(b)]])
    Rz = sp.Matrix([[sp.cos(c), -sp.sin(c), 0], [sp.sin(c), sp.cos(c), 0], [0, 0, 1]])
    return Rx * Ry * Rz


def angular_momentum(R, I):
    """L = R I ω_body with ω_body the vee of Rᵀ Ṙ: needs nothing but the rotation matrix."""
    W = R.T * R.diff(t)
    w_body = sp.Matrix([W[2, 1], W[0, 2], W[1, 0]])
    return R * sp.Matrix(I) * w_body


@pytest.mark.slow
def test_torque_free_spinning_body_conserves_energy_and_angular_momentum():
    I = [[2.0, 0.1, 0.0], [0.1, 1.5, -0.2], [0.0, -0.2, 1.0]]
    model = lg.Model("spinning body", dim=3)
    model.add("body", "b", "b", m=1.0, inertia=I)
    model.add("spherical", "ball", ("ground", "b"))
    res = model.simulate(30, initial={"alpha_ball": 0.1, "beta_ball": -0.2, "gamma_ball": 0.3},
                         velocity={"alpha_ball": 0.3, "beta_ball": 0.2, "gamma_ball": 4.0}, points=1501, **TIGHT)
    assert np.max(np.abs(res["beta_ball"])) < 1.3  # away from gimbal lock throughout
    assert np.ptp(res["gamma_ball"]) > 20  # several turns
    assert res.energy_drift() < 1e-8
    R = euler_xyz(fn("alpha_ball"), fn("beta_ball"), fn("gamma_ball"))
    L = np.array([res.quantity(c) for c in angular_momentum(R, I)])
    assert np.linalg.norm(L[:, 0]) > 1.0
    assert np.max(np.abs(L - L[:, :1])) / np.linalg.norm(L[:, 0]) < 1e-8
    # the same with the library's own pose (rotation and angular velocity in the fixed frame): L = R I Rᵀ ω
    pose = model.assembly.views["mechanical"].pose("b")
    L2 = np.array([res.quantity(c) for c in pose.R * sp.Matrix(I) * pose.R.T * pose.omega])
    assert np.max(np.abs(L2 - L)) < 1e-10 * np.linalg.norm(L[:, 0])


def test_free_planar_pair_without_gravity_conserves_momenta():
    """A body on a free planar joint with a second body pinned to it through a rotational spring.

    With no gravity and nothing attached to the ground, x and y of the free joint are ignorable: the linear
    momentum (total mass × centre-of-mass velocity) is conserved, and by rotation invariance so is the angular
    momentum about the origin, Σ m (r_G × v_G) + Σ I φ̇ — all written here from hand-built positions.
    """
    mA, IA, cA, P = 2.0, 0.3, (0.2, 0.1), (1.0, 0.0)
    mB, IB, cB = 1.0, 0.1, (0.4, -0.1)
    model = lg.Model("free pair", dim=2)
    model.add("body", "A", "A", m=mA, inertia=IA, com=cA)
    model.add("body", "B", "B", m=mB, inertia=IB, com=cB)
    model.add("planar", "f", ("ground", "A"))
    model.add("revolute", "j", ("A", "B"), parent_point=P)
    model.add("rotational_spring", "k", ("A", "B"), k=5.0, rest_angle=0.3)
    assert model.coordinate_names == ["x_f", "y_f", "theta_f", "theta_j"]
    res = model.simulate(20, initial={"x_f": 0.1, "y_f": -0.2, "theta_f": 0.4, "theta_j": 1.0},
                         velocity={"x_f": 0.3, "y_f": 0.1, "theta_f": -1.0, "theta_j": 2.0}, points=801, **TIGHT)
    x, y, th, ph = (fn(n) for n in model.coordinate_names)
    rot = lambda a: sp.Matrix([[sp.cos(a), -sp.sin(a)], [sp.sin(a), sp.cos(a)]])  # noqa: E731
    phiB = th + ph
    gA = sp.Matrix([x, y]) + rot(th) * sp.Matrix(cA)
    gB = sp.Matrix([x, y]) + rot(th) * sp.Matrix(P) + rot(phiB) * sp.Matrix(cB)
    p = mA * gA.diff(t) + mB * gB.diff(t)
    cross = lambda r, v: r[0] * v[1] - r[1] * v[0]  # noqa: E731
    Lz = mA * cross(gA, gA.diff(t)) + mB * cross(gB, gB.diff(t)) + IA * th.diff(t) + IB * phiB.diff(t)
    for expr in (p[0], p[1], Lz):
        series = res.quantity(expr)
        assert abs(series[0]) > 0.1
        assert np.max(np.abs(series - series[0])) < 1e-8 * abs(series[0])
    assert np.ptp(res["theta_j"]) > 0.5 and res.energy_drift() < 1e-8


# ---------------------------------------------------------------------------
# Closed loops: consistent starts, closure along a run, closed-form kinematics
# ---------------------------------------------------------------------------


def circle_intersection(p, r1, c, r2, sign):
    """The point at distance r1 from p and r2 from c (2-D), on the side ``sign`` of the line p → c."""
    p, c = np.asarray(p, float), np.asarray(c, float)
    d = np.linalg.norm(c - p, axis=0)
    a = (r1**2 - r2**2 + d**2) / (2 * d)
    h = np.sqrt(r1**2 - a**2)
    u = (c - p) / d
    return p + a * u + sign * h * np.array([-u[1], u[0]])


def four_bar_closure(qA, qB, qD, a=1.0, b=3.0, c=2.0, d=3.0):
    """Crank tip + coupler − (ground pivot + rocker): zero when the loop closes (hand geometry)."""
    return np.array([a * np.cos(qA) + b * np.cos(qB) - d - c * np.cos(qD), a * np.sin(qA) + b * np.sin(qB) - c * np.sin(qD)])


def test_consistent_initial_closes_the_four_bar_at_the_given_crank_angle():
    model = four_bar()
    for crank in (0.3, 2.0, -2.5):
        q0, v0 = consistent_initial(model, {"theta_A": crank, "theta_D": 1.5, "theta_B": 0.3}, {"theta_A": 1.3},
                                    independent=["theta_A"])
        assert q0["theta_A"] == crank and v0["theta_A"] == 1.3
        # the rocker tip by hand: 3 from the crank tip, 2 from the pivot (3, 0), on the upper side
        P = np.array([math.cos(crank), math.sin(crank)])
        Q = circle_intersection(P, 3.0, [3.0, 0.0], 2.0, 1)
        assert q0["theta_D"] == pytest.approx(math.atan2(Q[1], Q[0] - 3.0), abs=1e-12)
        assert q0["theta_B"] == pytest.approx(math.atan2(Q[1] - P[1], Q[0] - P[0]), abs=1e-12)
        # velocities: the closure's time derivative vanishes (central differences of the hand closure)
        h = 1e-6
        q = np.array([q0["theta_A"], q0["theta_B"], q0["theta_D"]])
        v = np.array([v0["theta_A"], v0["theta_B"], v0["theta_D"]])
        rate = (four_bar_closure(*(q + h * v)) - four_bar_closure(*(q - h * v))) / (2 * h)
        assert np.max(np.abs(rate)) < 1e-8
    # a full consistent state passes through unchanged; inconsistent velocities of held coordinates do not
    again = consistent_initial(model, q0, v0)
    assert again.initial == q0 and again.velocity == pytest.approx(v0, abs=1e-15)
    with pytest.raises(lg.ModelError, match=r"velocities cannot satisfy the constraints of joint 'C'"):
        consistent_initial(model, q0, {**v0, "theta_D": v0["theta_D"] + 0.1})
    part = independent_coordinates(model, q0)
    assert (part.dof, part.rank, part.constraints) == (1, 2, 2)
    assert set(part.independent + part.dependent) == {"theta_A", "theta_B", "theta_D"} and len(part.independent) == 1
    assert part.residual < 1e-12


def test_four_bar_stays_closed_and_conserves_energy():
    model = four_bar()
    q0, v0 = consistent_initial(model, {"theta_A": 1.0, "theta_D": 1.5, "theta_B": 0.3}, {"theta_A": 3.0},
                                independent="theta_A")
    res = model.simulate(10, initial=q0, velocity=v0, points=1001, **TIGHT)
    assert np.ptp(np.unwrap(res["theta_A"])) > 2 * math.pi  # the crank turns round
    residual = constraint_residual(model, res)
    hand = np.max(np.abs(four_bar_closure(res["theta_A"], res["theta_B"], res["theta_D"])))
    assert residual == pytest.approx(hand, abs=1e-13)  # constraint_residual measures the loop gap
    assert residual < 1e-8
    assert res.energy_drift() < 1e-8


def test_driven_four_bar_follows_closed_form_position_analysis():
    """Crank driven at 2 rad/s: no degree of freedom is left; the rocker angle is pure geometry."""
    model = four_bar(driven=0.5 + 2 * t)
    assert model.coordinate_names == ["theta_D", "theta_B"]
    q0, v0 = consistent_initial(model, {"theta_D": 1.5, "theta_B": 0.3}, {}, independent=[])
    res = model.simulate(6, initial=q0, velocity=v0, points=301)
    crank = 0.5 + 2 * res.t
    Q = circle_intersection(np.array([np.cos(crank), np.sin(crank)]), 3.0, np.array([[3.0], [0.0]]), 2.0, 1)
    assert np.max(np.abs(np.unwrap(res["theta_D"]) - np.unwrap(np.arctan2(Q[1], Q[0] - 3.0)))) < 1e-7


def test_slider_crank_stays_closed_and_driven_slider_follows_closed_form():
    model = slider_crank()
    q0, v0 = consistent_initial(model, {"theta_O": 0.5, "s_P": 3.5, "theta_A": -0.1}, {"theta_O": 4.0},
                                independent=["theta_O"])
    # by hand: x = r cos θ + √(l² − r² sin² θ)
    assert q0["s_P"] == pytest.approx(math.cos(0.5) + math.sqrt(9 - math.sin(0.5) ** 2), abs=1e-12)
    res = model.simulate(8, initial=q0, velocity=v0, points=801, **TIGHT)
    assert np.ptp(np.unwrap(res["theta_O"])) > 2 * math.pi
    assert constraint_residual(model, res) < 1e-8
    assert res.energy_drift() < 1e-8

    driven = slider_crank(driven=3 * t)
    assert driven.coordinate_names == ["s_P", "theta_A"]
    q0, v0 = consistent_initial(driven, {"s_P": 4.0, "theta_A": 0.0}, {}, independent=[])
    res = driven.simulate(5, initial=q0, velocity=v0, points=251)
    th = 3 * res.t
    assert np.max(np.abs(res["s_P"] - (np.cos(th) + np.sqrt(9 - np.sin(th) ** 2)))) < 1e-7
    assert constraint_residual(driven, res) < 1e-8


def test_consistent_initial_reports_what_it_cannot_do():
    model = four_bar()
    with pytest.raises(lg.ModelError, match=r"2 coordinates of the loops are held \(theta_A, theta_D\).*only 1 degree"):
        consistent_initial(model, {"theta_A": 0.3, "theta_D": 1.5}, {})
    with pytest.raises(lg.UnknownNameError, match="Did you mean 'theta_A'"):
        consistent_initial(model, {"theta_AA": 0.3}, {})
    with pytest.raises(lg.ModelError, match="need a value"):
        consistent_initial(model, {}, {}, independent=["theta_A"])
    # crank 2, coupler 1, rocker 1, ground 3: with the crank pointing away (θ = π) the tip is 5 from the rocker's
    # pivot, out of reach of coupler + rocker = 2
    short = four_bar(crank=2.0, coupler=1.0, rocker=1.0, ground=3.0)
    q0, _ = consistent_initial(short, {"theta_A": 0.0, "theta_D": 2.0, "theta_B": 1.0}, {}, independent="theta_A")
    assert np.max(np.abs(four_bar_closure(q0["theta_A"], q0["theta_B"], q0["theta_D"], 2, 1, 1, 3))) < 1e-12
    with pytest.raises(lg.ModelError, match=r"loop closed by joint 'C' cannot be closed with theta_A = 3\.14159"):
        consistent_initial(short, {"theta_A": math.pi, "theta_D": 2.0, "theta_B": 1.0}, {}, independent="theta_A")
    # a slider-crank at top dead centre: the slider's position cannot be chosen there (its rate is zero whatever
    # the crank does), so holding it leaves the crank undetermined
    sc = slider_crank()
    with pytest.raises(lg.ModelError, match=r"holding s_P does not fix the loop here.*theta_O, theta_A undetermined.*Hold theta_O instead"):
        consistent_initial(sc, {"s_P": 4.0, "theta_O": 0.0, "theta_A": 0.0}, {}, independent=["s_P"])


def rod_pinned_twice() -> lg.Model:
    """A rod pinned to the ground at both ends (its length equals the pins' distance): one equation too many."""
    m = lg.Model("pinned twice", dim=2)
    m.add("rod", "bar", "bar", m=1, length=1)
    m.add("revolute", "left", ("ground", "bar"))
    m.add("revolute", "right", ("bar", "ground"), parent_point=(1, 0), child_point=(1, 0))
    m.add("gravity", "g")
    return m


def double_parallelogram() -> lg.Model:
    """Three parallel cranks of length 1 at x = 0, 1, 2 carrying one coupler: the third crank is redundant."""
    m = lg.Model("double parallelogram", dim=2)
    for i in range(3):
        m.add("rod", f"c{i}", f"c{i}", m=1, length=1)
        m.add("revolute", f"g{i}", ("ground", f"c{i}"), parent_point=(i, 0), absolute=True)
    m.add("rod", "top", "top", m=1, length=2, points={"mid": (1, 0)})
    m.add("revolute", "t0", ("c0", "top"), parent_point=(1, 0), absolute=True)
    m.add("revolute", "t1", ("top", "c1"), parent_point=(1, 0), child_point=(1, 0))
    m.add("revolute", "t2", ("top", "c2"), parent_point=(2, 0), child_point=(1, 0))
    m.add("gravity", "g")
    return m


def test_over_constrained_loops_are_errors_naming_the_joints():
    with pytest.raises(lg.ModelError, match=r"constraints of joint 'right' are dependent .*rank 1 of Φ_q for 2.*over-constrained"):
        independent_coordinates(rod_pinned_twice(), {"theta_left": 0.0})
    model = double_parallelogram()
    up = {"theta_g0": 1.2, "theta_g1": 1.2, "theta_g2": 1.2, "theta_t0": 0.0}
    assert np.max(np.abs(model.eq.constraints.subs(dict(zip(model.eq.sym.q, [up[n] for n in model.eq.names]))))) < 1e-15
    with pytest.raises(lg.ModelError, match=r"joint 't1', joint 't2' are dependent.*rank 3 of Φ_q for 4"):
        independent_coordinates(model, up)
    with pytest.raises(lg.ModelError, match="over-constrained"):
        consistent_initial(model, up, {"theta_g0": 1.0}, independent=["theta_g0"])
    # simulating it anyway: the multipliers are not determined, the system matrix is singular
    with pytest.raises(lg.SingularMassMatrixError):
        model.simulate(1, initial=up, velocity={})


# ---------------------------------------------------------------------------
# Kinematics of body points against hand formulas
# ---------------------------------------------------------------------------


def test_body_point_positions_and_velocities_match_hand_kinematics():
    model = double_pendulum(L1=1.0, L2=1.3)
    view = model.assembly.views["mechanical"]
    q1, q2 = fn("theta_j1"), fn("theta_j2")
    tip = view.position("r2.end")
    mid = view.position("r2.center")
    rates, values = {q1.diff(t): 0.4, q2.diff(t): -1.5}, {q1: 0.7, q2: -2.1}
    ev = lambda e: np.array([float(x) for x in e.subs(rates).subs(values)])  # noqa: E731
    a, b, da, db = 0.7, -2.1, 0.4, -1.5
    assert ev(tip) == pytest.approx([math.cos(a) + 1.3 * math.cos(b), math.sin(a) + 1.3 * math.sin(b)], abs=1e-14)
    assert ev(mid) == pytest.approx([math.cos(a) + 0.65 * math.cos(b), math.sin(a) + 0.65 * math.sin(b)], abs=1e-14)
    assert ev(view.velocity("r2.end")) == pytest.approx(
        [-math.sin(a) * da - 1.3 * math.sin(b) * db, math.cos(a) * da + 1.3 * math.cos(b) * db], abs=1e-14)

    # 3-D: a point of a body on a spherical joint, r = pivot + R (point − joint point), R = Rx Ry Rz
    m3 = lg.Model("3-D points", dim=3)
    m3.add("body", "b", "b", m=1, inertia=(1, 2, 2), points={"p": (0.3, -0.4, 1.1)})
    m3.add("spherical", "ball", ("ground", "b"), parent_point=(1, 2, 3), child_point=(0.1, 0.2, -0.5))
    m3.add("prismatic", "slide", ("b", "c"), parent_point=(0.3, -0.4, 1.1), axis=(1, 1, 0))
    m3.add("body", "c", "c", m=1, inertia=(1, 1, 1))
    assert m3.coordinate_names == ["alpha_ball", "beta_ball", "gamma_ball", "s_slide"]
    v3 = m3.assembly.views["mechanical"]
    angles = (0.3, -0.7, 1.9)
    rates = np.array([0.5, -0.2, 1.1])

    def rot(a, b, c):
        Rx = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
        Ry = np.array([[np.cos(b), 0, np.sin(b)], [0, 1, 0], [-np.sin(b), 0, np.cos(b)]])
        Rz = np.array([[np.cos(c), -np.sin(c), 0], [np.sin(c), np.cos(c), 0], [0, 0, 1]])
        return Rx @ Ry @ Rz

    def point(ang, s=0.0):
        R = rot(*ang)
        base = np.array([1, 2, 3]) + R @ (np.array([0.3, -0.4, 1.1]) - np.array([0.1, 0.2, -0.5]))
        return base, base + R @ (np.array([1, 1, 0]) / math.sqrt(2) * s)

    funcs = [fn(n) for n in m3.coordinate_names]
    subs = {**{f.diff(t): r for f, r in zip(funcs[:3], rates)}, funcs[3].diff(t): 0.7}
    subs2 = {**dict(zip(funcs[:3], angles)), funcs[3]: 0.25}
    num = lambda e: np.array([float(x) for x in e.subs(subs).subs(subs2)])  # noqa: E731
    p_hand, c_hand = point(angles, 0.25)
    assert num(v3.position("b.p")) == pytest.approx(p_hand, abs=1e-14)
    assert num(v3.position("c.origin")) == pytest.approx(c_hand, abs=1e-14)
    h = 1e-6  # velocity: the hand position differentiated numerically along (q̇, ṡ)
    vel = (point(np.array(angles) + h * rates, 0.25 + h * 0.7)[1] - point(np.array(angles) - h * rates, 0.25 - h * 0.7)[1]) / (2 * h)
    assert num(v3.velocity("c.origin")) == pytest.approx(vel, abs=1e-8)


def test_spring_between_points_of_two_moving_bodies_couples_two_pendulums():
    """Two point-mass pendulums (massless links, pivots d apart) whose bobs are joined by a spring of rest length
    d.  Linearized about hanging (by hand): M = m L² I, K = m g L I + k L² [[1, −1], [−1, 1]], so the normal
    modes have ω² = g/L (in phase) and g/L + 2k/m (in antiphase)."""
    mass, L, d, k = 0.5, 0.9, 0.6, 2.0
    model = lg.Model("coupled pendulums", dim=2)
    for i in (1, 2):
        model.add("link", f"p{i}", f"p{i}", points={"bob": (L, 0)})
        model.add("revolute", f"j{i}", ("ground", f"p{i}"), parent_point=((i - 1) * d, 0), absolute=True)
        model.add("mass", f"m{i}", f"p{i}.bob", m=mass)
    model.add("spring", "k", ("p1.bob", "p2.bob"), k=k, rest_length=d)
    model.add("gravity", "g", g=G)
    eq = model.eq
    at = {**{q: -math.pi / 2 for q in eq.sym.q}, **{v: 0 for v in eq.sym.v}, t: 0}
    M = np.array(eq.M.subs(at), dtype=float)
    K = -np.array(eq.f.jacobian(eq.sym.q).subs(at), dtype=float)
    assert np.max(np.abs(np.array(eq.f.subs(at), dtype=float))) < 1e-12  # hanging is an equilibrium
    w2 = np.sort(np.linalg.eigvals(np.linalg.solve(M, K)).real)
    assert w2 == pytest.approx([G / L, G / L + 2 * k / mass], rel=1e-12)


# ---------------------------------------------------------------------------
# Driven joints, rotational springs, dampers and torques
# ---------------------------------------------------------------------------


def test_bead_in_a_tube_driven_round_at_constant_speed_moves_as_cosh():
    """A tube driven round a vertical axis at Ω (no coordinate) with a bead sliding in it, no gravity in the
    plane: r̈ = Ω² r, so r = r₀ cosh Ω t from rest."""
    W = 1.5
    m = lg.Model("bead in a tube", dim=2)
    m.add("link", "tube", "tube")
    m.add("body", "bead", "bead", m=0.2, inertia=0.01)
    m.add("revolute", "spin", ("ground", "tube"), angle=W * t)
    m.add("prismatic", "slide", ("tube", "bead"))
    assert m.coordinate_names == ["s_slide"]
    res = m.simulate(2, initial={"s_slide": 0.1}, velocity={"s_slide": 0.0}, points=201)
    assert np.max(np.abs(res["s_slide"] - 0.1 * np.cosh(W * res.t))) < 1e-7 * 0.1 * np.cosh(3)


def cart_pendulum(motion, m=1.0, L=1.5) -> lg.Model:
    """A uniform rod pinned to a cart whose position along x is prescribed; absolute angle from the x axis."""
    model = lg.Model("cart and pendulum", dim=2)
    model.add("link", "cart", "cart")
    model.add("rod", "rod", "rod", m=m, length=L)
    model.add("prismatic", "rail", ("ground", "cart"), displacement=motion)
    model.add("revolute", "pivot", ("cart", "rod"), absolute=True)
    model.add("gravity", "g", g=G)
    return model


@pytest.mark.parametrize("accel", [0.0, 2.0])
def test_pendulum_on_a_cart_with_prescribed_motion_obeys_the_hand_equation(accel):
    """Cart at X(t) = v t + a t²/2.  By hand (rod of mass m, length L, absolute angle θ, centre at X + L/2 (cos θ,
    sin θ)): (m L²/3) θ̈ = (m L/2) a sin θ − (m g L/2) cos θ; at constant speed (a = 0) the cart's motion drops out."""
    mass, L = 1.0, 1.5
    model = cart_pendulum(0.8 * t + accel * t**2 / 2, mass, L)
    assert model.coordinate_names == ["theta_pivot"]
    th = sp.Symbol("th")
    M, f = model.eq.M[0, 0], model.eq.f[0]
    hand_M, hand_f = mass * L**2 / 3, mass * L / 2 * accel * sp.sin(th) - mass * G * L / 2 * sp.cos(th)
    qs, vs = model.eq.sym.q[0], model.eq.sym.v[0]
    for value in np.linspace(-3, 3, 7):
        at = {qs: value, vs: 0.9 * value, t: 0.3 * value}
        assert float(M.subs(at)) == pytest.approx(hand_M, rel=1e-12)
        assert float(f.subs(at)) == pytest.approx(float(hand_f.subs(th, value)), rel=1e-12, abs=1e-12)
    res = model.simulate(5, initial={"theta_pivot": -1.0}, velocity={"theta_pivot": 0.0}, points=101)
    ref = solve_ivp(lambda _, y: [y[1], (mass * L / 2 * accel * np.sin(y[0]) - mass * G * L / 2 * np.cos(y[0])) / hand_M],
                    (0, 5), [-1.0, 0.0], t_eval=res.t, rtol=1e-11, atol=1e-12, method="DOP853")
    assert np.max(np.abs(res["theta_pivot"] - ref.y[0])) < 1e-7


def test_rotational_spring_and_damper_on_a_disc_give_the_damped_oscillator():
    """A disc (I = ½ m r² about its pinned centre) with k and c to the ground: I θ̈ + c θ̇ + k θ = τ."""
    mass, r, k, c, tau = 2.0, 0.5, 3.0, 0.2, 0.6
    m = lg.Model("disc", dim=2)
    m.add("disc", "d", "d", m=mass, radius=r)
    m.add("revolute", "axle", ("ground", "d"))
    m.add("rotational_spring", "k", ("ground", "d"), k=k, rest_angle=0.1)
    m.add("rotational_damper", "c", ("ground", "d"), c=c)
    m.add("body_torque", "tau", "d", tau=tau)
    I = mass * r**2 / 2
    res = m.simulate(10, initial={"theta_axle": 0.0}, velocity={"theta_axle": 0.0}, points=201)
    # θ∞ = 0.1 + τ/k; θ = θ∞ − θ∞ e^{−ζω t}(cos ω_d t + ζω/ω_d sin ω_d t) from rest at 0
    w0, z = math.sqrt(k / I), c / (2 * math.sqrt(k * I))
    wd, inf = w0 * math.sqrt(1 - z**2), 0.1 + tau / k
    exact = inf - inf * np.exp(-z * w0 * res.t) * (np.cos(wd * res.t) + z * w0 / wd * np.sin(wd * res.t))
    assert np.max(np.abs(res["theta_axle"] - exact)) < 1e-7


def test_rotational_spring_between_two_bodies_acts_on_the_relative_angle():
    """Two discs on separate axles joined by a torsional spring: the relative angle oscillates at
    ω² = k (1/I₁ + 1/I₂) and I₁ θ̇₁ + I₂ θ̇₂ is conserved (nothing else exerts a torque)."""
    m = lg.Model("two discs", dim=2)
    m.add("disc", "d1", "d1", m=1.0, radius=0.4)
    m.add("disc", "d2", "d2", m=3.0, radius=0.3)
    m.add("revolute", "a1", ("ground", "d1"))
    m.add("revolute", "a2", ("ground", "d2"), parent_point=(2, 0))
    m.add("rotational_spring", "k", ("d1", "d2"), k=2.0)
    I1, I2 = 0.5 * 1.0 * 0.4**2, 0.5 * 3.0 * 0.3**2
    res = m.simulate(5, initial={"theta_a1": 0.1, "theta_a2": 0.0}, velocity={"theta_a1": 0.0, "theta_a2": 0.0}, points=101)
    w = math.sqrt(2.0 * (1 / I1 + 1 / I2))
    assert np.max(np.abs(res["theta_a1"] - res["theta_a2"] - 0.1 * np.cos(w * res.t))) < 1e-8
    assert np.max(np.abs(I1 * res.velocity("theta_a1") + I2 * res.velocity("theta_a2"))) < 1e-9


def test_spatial_body_torque_about_a_principal_axis_spins_it_up():
    """Torque τ about the fixed z axis on a body at rest whose principal axes are the fixed ones: it turns about
    z alone, γ = τ t² / (2 I_z), α = β = 0."""
    m = lg.Model("torque", dim=3)
    m.add("body", "b", "b", m=1, inertia=(1.0, 2.0, 2.5))
    m.add("spherical", "ball", ("ground", "b"))
    m.add("body_torque", "tau", "b", tau=(0, 0, 0.5))
    res = m.simulate(2, initial={}, velocity={}, points=51)
    assert np.max(np.abs(res["gamma_ball"] - 0.5 * res.t**2 / (2 * 2.5))) < 1e-9
    assert np.max(np.abs(res["alpha_ball"])) < 1e-12 and np.max(np.abs(res["beta_ball"])) < 1e-12


# ---------------------------------------------------------------------------
# Errors
# ---------------------------------------------------------------------------


def test_joint_to_an_unknown_body_suggests_the_closest():
    m = lg.Model("typo", dim=2)
    m.add("rod", "arm", "arm", m=1, length=1)
    m.add("revolute", "pin", ("ground", "arm"))
    m.add("revolute", "elbow", ("arm", "farearm"))
    m.add("rod", "forearm", "forearm", m=1, length=1)
    with pytest.raises(lg.UnknownNameError, match=r"unknown body for joint 'elbow' 'farearm'\. Did you mean 'forearm'\?"):
        m.coordinate_names


@pytest.mark.parametrize("inertia, message", [
    ((1.0, -1.0, 1.0), "not positive definite"),
    ([[1.0, 2.0, 0.0], [2.0, 1.0, 0.0], [0.0, 0.0, 1.0]], "not positive definite"),
    ((1.0, 1.0, 3.0), "triangle inequality"),
    ([[1.0, 0.5, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], "symmetric"),
])
def test_a_body_with_an_impossible_inertia_is_a_parameter_error(inertia, message):
    m = lg.Model("bad body", dim=3)
    with pytest.raises(lg.ParameterError, match=f"component 'b', parameter 'inertia'.*{message}"):
        m.add("body", "b", "b", m=1, inertia=inertia)
    with pytest.raises(lg.ParameterError, match="parameter 'inertia'"):
        lg.Model("flat", dim=2).add("body", "b", "b", m=1, inertia=-0.5)


def test_gimbal_lock_at_the_start_is_a_singular_mass_matrix():
    m = lg.Model("gimbal lock", dim=3)
    m.add("body", "b", "b", m=1, inertia=(1, 2, 3))
    m.add("spherical", "ball", ("ground", "b"), child_point=(0, 0, -1))
    m.add("gravity", "g")
    with pytest.raises(lg.SingularMassMatrixError, match="alpha_ball, gamma_ball"):
        m.simulate(1, initial={"alpha_ball": 0.1, "beta_ball": math.pi / 2, "gamma_ball": 0.2}, velocity={"gamma_ball": 1.0})


def test_joint_declared_backwards_is_an_error_saying_swap():
    m = lg.Model("backwards", dim=2)
    m.add("rod", "a", "a", m=1, length=1)
    m.add("rod", "b", "b", m=1, length=1)
    m.add("revolute", "j1", ("ground", "a"))
    m.add("revolute", "j2", ("b", "a"), child_point=(1, 0))
    with pytest.raises(lg.ModelError, match=r"joint 'j2' is declared \(parent='b', child='a'\).*swap its nodes"):
        m.coordinate_names


def test_declaration_order_of_the_joints_does_not_matter():
    """The four-bar with its joints declared D, A, C, B: the tree search meets the loop-closing joint C from its
    child side first; it must still close the loop (not be taken for a joint declared backwards), and the
    equations must be those of the usual order, up to the order of the coordinates."""
    usual = four_bar()
    shuffled = lg.Model("four-bar, shuffled", dim=2)
    for name, length in (("crank", 1.0), ("coupler", 3.0), ("rocker", 2.0)):
        shuffled.add("rod", name, name, m=1.0, length=length)
    shuffled.add("revolute", "D", ("ground", "rocker"), parent_point=(3.0, 0), absolute=True)
    shuffled.add("revolute", "A", ("ground", "crank"), absolute=True)
    shuffled.add("revolute", "C", ("coupler", "rocker"), parent_point=(3.0, 0), child_point=(2.0, 0))
    shuffled.add("revolute", "B", ("crank", "coupler"), parent_point=(1.0, 0), absolute=True)
    shuffled.add("gravity", "g", g=G)
    assert sorted(shuffled.coordinate_names) == sorted(usual.coordinate_names)
    perm = [shuffled.coordinate_names.index(n) for n in usual.coordinate_names]
    M1, f1 = ours(usual)
    M2, f2 = ours(shuffled)
    for _ in range(5):
        q, v = RNG.uniform(-3, 3, 3), RNG.uniform(-2, 2, 3)
        q2, v2 = np.empty(3), np.empty(3)
        q2[perm], v2[perm] = q, v
        assert M2(q2, v2)[np.ix_(perm, perm)] == pytest.approx(M1(q, v), abs=1e-12)
        assert f2(q2, v2)[perm] == pytest.approx(f1(q, v), abs=1e-12)
        closure = lambda m, x: np.array(m.eq.constraints.subs(dict(zip(m.eq.sym.q, x))), dtype=float).ravel()  # noqa: E731
        assert closure(shuffled, q2) == pytest.approx(four_bar_closure(q[0], q[2], q[1]), abs=1e-12)


def test_body_without_a_path_of_joints_to_ground_is_an_error():
    m = lg.Model("loose", dim=2)
    m.add("rod", "a", "a", m=1, length=1)
    m.add("rod", "b", "b", m=1, length=1)
    m.add("revolute", "j1", ("ground", "a"))
    with pytest.raises(lg.ModelError, match="body 'b' is not connected to ground by joints"):
        m.coordinate_names


def test_a_point_the_body_does_not_have_suggests_the_closest():
    m = lg.Model("points", dim=2)
    m.add("body", "arm", "arm", m=1, inertia=0.1, points={"tip": (1, 0)})
    m.add("revolute", "pin", ("ground", "arm"))
    m.add("spring", "k", ("ground", "arm.tpi"), k=1)
    with pytest.raises(lg.UnknownNameError, match=r"unknown point of body 'arm' 'tpi'\. Did you mean 'tip'\?"):
        m.coordinate_names
    r = lg.Model("rod points", dim=2)
    r.add("rod", "arm", "arm", m=1, length=1)
    r.add("revolute", "pin", ("ground", "arm"))
    r.add("mass", "bob", "arm.ned", m=1)
    with pytest.raises(lg.UnknownNameError, match="Did you mean 'end'"):
        r.coordinate_names


# ---------------------------------------------------------------------------
# Examples: each script runs as a user would run it (short horizons) and prints what it promises
# ---------------------------------------------------------------------------

SCRIPTS = {
    "pendulums": ["--t-end", "5", "--links", "4"],
    "spherical_pendulum": ["--t-end", "5"],
    "cart_pendulum": ["--t-end", "5"],
    "four_bar": ["--t-end", "3"],
    "slider_crank": ["--t-end", "3"],
    "spinning_body": ["--t-end", "17"],
}


@pytest.fixture
def examples(example):
    return example


def run_example(examples, name: str) -> str:
    out, where = examples(f"{name}.py", *SCRIPTS[name], "--out", f"{{dir}}/{name}.png")
    png = (where / f"{name}.png").read_bytes()
    assert png.startswith(b"\x89PNG") and len(png) > 10_000
    return out


def figures(pattern: str, out: str) -> list[float]:
    found = re.findall(pattern, out)
    assert found, f"{pattern!r} not in the output:\n{out}"
    return [float(x) for x in (found[0] if isinstance(found[0], tuple) else found)]


@pytest.mark.slow
def test_example_pendulums(examples):
    out = run_example(examples, "pendulums")
    sim, exact = figures(r"period simulated (\S+) s, exact 4√\(L/g\) K\(sin²\(A/2\)\) = (\S+) s", out)
    L, A = 0.8, 2.0  # as in the script
    assert exact == pytest.approx(4 * math.sqrt(L / G) * ellipk(math.sin(A / 2) ** 2), rel=1e-9)
    assert sim == pytest.approx(exact, rel=1e-7)
    drifts = [float(x) for x in re.findall(r"relative energy drift (\S+)", out)]
    assert len(drifts) == 3 and max(drifts) < 1e-8
    assert "4-link pendulum (4 coordinates" in out


def test_example_spherical_pendulum(examples):
    out = run_example(examples, "spherical_pendulum")
    (omega,) = figures(r"Ω = √\(g / \(L cos θ\)\) = (\S+) rad/s", out)
    assert omega == pytest.approx(math.sqrt(G / (1.2 * math.cos(0.6))), rel=1e-9)
    (stray,) = figures(r"polar angle stays within (\S+) rad of θ", out)
    (rate,) = figures(r"simulated rate of turn (\S+) rad/s", out)
    assert stray < 1e-8 and rate == pytest.approx(omega, rel=1e-8)
    (lz_drift,) = figures(r"L_z = \S+, relative drift (\S+);", out)
    drifts = [float(x) for x in re.findall(r"relative energy drift (\S+)", out)]
    assert lz_drift < 1e-8 and len(drifts) == 2 and max(drifts) < 1e-8
    (beta,) = figures(r"\|β\| stays below (\S+) rad", out)
    assert beta < 1.2


def test_example_cart_pendulum(examples):
    out = run_example(examples, "cart_pendulum")
    sim, closed = figures(r"ω simulated (\S+) rad/s, closed form √\(g \(M \+ m\) / \(M L\)\) = (\S+) rad/s", out)
    assert closed == pytest.approx(math.sqrt(G * 2.5 / (2.0 * 0.7)), rel=1e-8)
    assert sim == pytest.approx(closed, rel=1e-5)  # amplitude 1e-3 rad: the nonlinear shift is ~1e-7
    (p_drift,) = figures(r"momentum p = \S+, relative drift (\S+);", out)
    (gap,) = figures(r"max \|θ − fixed-pivot pendulum .*\| = (\S+) rad", out)
    assert p_drift < 1e-8 and gap < 1e-8
    assert "cart at constant speed 1.5 m/s: coordinates ['theta_pivot']" in out
    h_drift, e_drift = figures(r"relative drift of h (\S+), of the total energy T \+ V (\S+)", out)
    assert h_drift < 1e-9 and e_drift > 1e-2  # the Jacobi integral is conserved, the energy is not


@pytest.mark.slow
def test_example_four_bar(examples):
    out = run_example(examples, "four_bar")
    assert "independent ['theta_A'], dependent ['theta_D', 'theta_B'], 1 degree of freedom" in out
    residuals = [float(x) for x in re.findall(r"loop-closure residual max \|Φ\| = (\S+)", out)]
    assert len(residuals) == 2 and max(residuals) < 1e-8
    (drift,) = figures(r"relative energy drift (\S+)", out)
    (gap,) = figures(r"max \|rocker angle − closed-form position analysis\| = (\S+) rad", out)
    assert drift < 1e-8 and gap < 1e-7


def test_example_slider_crank(examples):
    out = run_example(examples, "slider_crank")
    (gap,) = figures(r"max \|x − \(r cos θ \+ √\(l² − r² sin² θ\)\)\| = (\S+) m", out)
    residuals = [float(x) for x in re.findall(r"loop-closure residual max \|Φ\| = (\S+)", out)]
    (drift,) = figures(r"relative energy drift (\S+)", out)
    (s0,) = figures(r"consistent start theta_O = 0.300000, s_P = (\S+),", out)
    assert s0 == pytest.approx(math.cos(0.3) + math.sqrt(9 - math.sin(0.3) ** 2), abs=1e-6)
    assert gap < 1e-7 and len(residuals) == 2 and max(residuals) < 1e-8 and drift < 1e-8


def test_example_spinning_body(examples):
    out = run_example(examples, "spinning_body")
    blocks = dict(re.findall(r"spin about the (\w+) axis[^\n]*\n((?:  [^\n]*\n)+)", out))
    assert set(blocks) == {"major", "intermediate", "minor"}
    for axis, text in blocks.items():
        energy, momentum = figures(r"energy (\S+), angular momentum (\S+)", text)
        assert energy < 1e-8 and momentum < 1e-8
        lo, hi = figures(r"ranges over \[(\S+), (\S+)\]", text)
        if axis == "intermediate":
            assert lo < -0.99 and hi > 0.99  # flipped over
        else:
            assert lo > 0.99  # stable: the spin axis stays with L
    sim, closed = figures(r"time between flips: simulated (\S+) s, closed form 2K\(k\)/p = (\S+) s", blocks["intermediate"])
    assert sim == pytest.approx(closed, rel=1e-5)


def test_an_initial_state_off_the_loop_is_refused():
    """Started with guessed dependent angles, a four-bar would be dragged onto its loop by the stabilization."""
    model = four_bar()
    with pytest.raises(lg.ModelError, match="does not satisfy its kinematic loops.*consistent_initial"):
        model.simulate(1, initial={"theta_A": 1.0, "theta_D": 1.5, "theta_B": 0.3}, velocity={"theta_A": 1.3})
    q0, v0 = consistent_initial(model, {"theta_A": 1.0, "theta_D": 1.5, "theta_B": 0.3}, {"theta_A": 1.3},
                                independent=["theta_A"])
    res = model.simulate(1, initial=q0, velocity=v0, rtol=1e-11, atol=1e-13)
    assert constraint_residual(model, res) < 1e-8


def test_bodies_and_circuit_elements_share_one_model():
    """A rod pendulum and an LC tank in one Lagrangian: each keeps its own closed-form behaviour."""
    m = lg.Model("mixed", dim=2)
    m.add("rod", "arm", "arm", m=1, length=1)
    m.add("revolute", "pin", ("ground", "arm"), absolute=True)
    m.add("gravity", "g")
    m.add("inductor", "L1", ("n1", "0"), L=1)
    m.add("capacitor", "C1", ("n1", "0"), C=1)
    assert m.coordinate_names == ["theta_pin", "q_L1"]
    res = m.simulate(2, initial={"theta_pin": -1.0, "q_L1": 0.1}, velocity={"theta_pin": 0, "q_L1": 0},
                     rtol=1e-11, atol=1e-13)
    assert np.allclose(res["q_L1"], 0.1 * np.cos(res.t), atol=1e-9)  # LC tank: q = q0 cos(t/√(LC))
    assert res.energy_drift() < 1e-8


# ---------------------------------------------------------------------------
# Angle sequences of spherical (and free) joints
# ---------------------------------------------------------------------------
# References: sympy.physics.mechanics frames oriented with orient_body_fixed(parent, angles, sequence), whose
# rotation is R = R_1(q1) R_2(q2) R_3(q3) about the body's axes in turn — the convention the joint documents.

ALL_SEQUENCES = ("xyz", "xzy", "yxz", "yzx", "zxy", "zyx", "zxz", "zyz", "xyx", "xzx", "yxy", "yzy")


def heavy_top(inertia=(0.25, 0.25, 0.5), m=0.3, l=0.4, sequence="zxz") -> lg.Model:
    """A symmetric top: pivot at the ground origin, centre of mass l up its body z axis, gravity along −z."""
    top = lg.Model("heavy top", dim=3)
    top.add("body", "top", "top", m=m, inertia=inertia, com=(0, 0, l))
    top.add("spherical", "ball", ("ground", "top"), sequence=sequence)
    top.add("gravity", "g", g=G, direction=(0, 0, -1))
    return top


def kane_body_on_ball(sequence, mass, I, com, pivot=(0, 0, 0), at=(0, 0, 0), g_dir=(0, 0, -1)):
    """KanesMethod for a rigid body whose frame is oriented body-fixed by ``sequence`` (u = q̇)."""
    q = me.dynamicsymbols("q1:4")
    u = me.dynamicsymbols("u1:4")
    N = me.ReferenceFrame("N")
    B = me.ReferenceFrame("B")
    B.orient_body_fixed(N, q, sequence)
    O = me.Point("O")
    O.set_vel(N, 0)
    vec = lambda xs, F: sum((x * e for x, e in zip(xs, (F.x, F.y, F.z))), sp.S(0) * F.x)  # noqa: E731
    Gc = O.locatenew("P", vec(pivot, N)).locatenew("Ob", -vec(at, B)).locatenew("G", vec(com, B))
    Gc.set_vel(N, Gc.pos_from(O).dt(N))
    I = sp.Matrix(I) if not isinstance(I[0], (int, float)) else sp.diag(*I)
    body = me.RigidBody("b", Gc, B, mass, (me.inertia(B, I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[1, 2], I[2, 0]), Gc))
    kane = me.KanesMethod(N, q_ind=list(q), u_ind=list(u), kd_eqs=[qi.diff() - ui for qi, ui in zip(q, u)])
    kane.kanes_equations([body], [(Gc, mass * G * vec(g_dir, N))])
    return kane.mass_matrix, kane.forcing, list(q), list(u)


def test_heavy_top_in_zxz_angles_has_precession_and_spin_ignorable():
    """Classical Euler angles: L of a symmetric top depends on θ only (T = ½ I₁(θ̇² + φ̇² sin²θ) +
    ½ I₃(ψ̇ + φ̇ cos θ)², V = m g l cos θ), so φ and ψ are both ignorable."""
    from lagrangian import routh

    top = heavy_top()  # exactly representable moments: the structural verdict alone
    assert top.coordinate_names == ["phi_ball", "theta_ball", "psi_ball"]
    assert sorted(routh.ignorable(top)) == ["phi_ball", "psi_ball"]
    assert sorted(routh.ignorable(heavy_top(inertia=(0.3, 0.3, 0.5)))) == ["phi_ball", "psi_ball"]
    # the default x-y-z angles: only the spin about the body's own z axis, γ, is ignorable
    assert routh.ignorable(heavy_top(sequence="xyz")) == ["gamma_ball"]
    # and the Lagrangian is the textbook one
    I1, I3, m, l = 0.25, 0.5, 0.3, 0.4
    eq = top.eq
    ph, th, ps = eq.sym.q
    dph, dth, dps = eq.sym.v
    textbook = (I1 + m * l**2) / 2 * (dth**2 + dph**2 * sp.sin(th) ** 2) + I3 / 2 * (dps + dph * sp.cos(th)) ** 2 \
        - m * G * l * sp.cos(th)
    diff = sp.lambdify((eq.sym.q, eq.sym.v), eq.L - textbook)
    for _ in range(5):
        q, v = RNG.uniform(-3, 3, 3), RNG.uniform(-2, 2, 3)
        assert abs(diff(q, v)) < 1e-12 * (1 + np.abs(v).max() ** 2)


def test_heavy_top_in_zxz_angles_keeps_both_textbook_momenta_along_a_run():
    """p_ψ = I₃(ψ̇ + φ̇ cos θ) and p_φ = (I₁ + m l²) φ̇ sin²θ + p_ψ cos θ are constant for the heavy top."""
    I1, I3, m, l = 0.3, 0.5, 0.3, 0.4
    res = heavy_top(inertia=(I1, I1, I3), m=m, l=l).simulate(
        3.0, initial={"phi_ball": 0.2, "theta_ball": 0.7, "psi_ball": -0.4},
        velocity={"phi_ball": 0.9, "theta_ball": -0.3, "psi_ball": 11.0}, method="DOP853", **TIGHT)
    th, dph, dps = res["theta_ball"], res.v["phi_ball"], res.v["psi_ball"]
    p_psi = I3 * (dps + dph * np.cos(th))
    p_phi = (I1 + m * l**2) * dph * np.sin(th) ** 2 + p_psi * np.cos(th)
    assert np.ptp(th) > 0.05  # it nutates
    assert np.ptp(p_psi) < 1e-8 * abs(p_psi[0]) and np.ptp(p_phi) < 1e-8 * abs(p_phi[0])


@pytest.mark.slow
def test_heavy_top_in_zxz_angles_matches_sympy_kane():
    MM, F, q, u = kane_body_on_ball("zxz", 0.3, (0.3, 0.3, 0.5), (0, 0, 0.4))
    assert agree(heavy_top(inertia=(0.3, 0.3, 0.5)), *theirs(MM, F, q, u)) < 1e-12


@pytest.mark.parametrize("sequence", ["zxz", "zyx", "yzy", "xzy"])
@pytest.mark.slow
def test_general_body_on_a_spherical_joint_matches_sympy_kane_in_each_family(sequence):
    """A full inertia tensor, the pivot away from the body origin and the centre of mass: every term of M and f."""
    MM, F, q, u = kane_body_on_ball(sequence, SB["m"], SB["I"], SB["com"], SB["pivot"], SB["at"])
    model = lg.Model("body", dim=3)
    model.add("body", "b", "b", m=SB["m"], inertia=SB["I"], com=SB["com"])
    model.add("spherical", "ball", ("ground", "b"), parent_point=SB["pivot"], child_point=SB["at"], sequence=sequence)
    model.add("gravity", "g", g=G, direction=(0, 0, -1))
    names = ("phi", "theta", "psi") if sequence[0] == sequence[2] else [{"x": "alpha", "y": "beta", "z": "gamma"}[a]
                                                                           for a in sequence]
    assert model.coordinate_names == [f"{n}_ball" for n in names]
    assert agree(model, *theirs(MM, F, q, u)) < 1e-12


def test_free_joint_takes_a_sequence_too():
    m = lg.Model("flying top", dim=3)
    m.add("body", "b", "b", m=0.3, inertia=(0.25, 0.25, 0.5))
    m.add("free", "fly", ("ground", "b"), sequence="zxz")
    assert m.coordinate_names == ["x_fly", "y_fly", "z_fly", "phi_fly", "theta_fly", "psi_fly"]
    from lagrangian import routh

    # no gravity: the three translations, precession and spin are ignorable; nutation is not
    assert sorted(routh.ignorable(m)) == ["phi_fly", "psi_fly", "x_fly", "y_fly", "z_fly"]


@pytest.mark.parametrize("bad", ["zxx", "xx", "abc", "x y z", "ZXZ", "__import__('os').system('true')", 3, ("z", "x", "z"), ""])
def test_a_bad_sequence_is_a_parameter_error_listing_the_twelve(bad):
    m = lg.Model("bad", dim=3)
    m.add("body", "b", "b", m=0.3, inertia=(0.25, 0.25, 0.5))
    with pytest.raises(lg.ParameterError, match=r"component 'ball', parameter 'sequence'.*spherical joint 'ball'.*"
                                                 r"not an angle sequence.*'zxz'.*'xyz'") as info:
        m.add("spherical", "ball", ("ground", "b"), sequence=bad)
    assert repr(bad) in str(info.value)
    with pytest.raises(lg.ParameterError, match="free joint 'fly'"):
        m.add("free", "fly", ("ground", "b"), sequence=bad)


def test_the_sequence_names_its_gimbal_lock_in_the_coordinate_descriptions():
    top = heavy_top()
    text = {c.name: c.description for c in top.coordinates}
    assert '"zxz"' in text["phi_ball"] and "theta_ball = 0 or ±π" in text["phi_ball"]
    assert all("'" not in d.replace("'ball'", "").replace("'s ", "") for d in text.values())  # only the owner quoted
    assert "second angle (about the body's x axis) of spherical joint 'ball'" in text["theta_ball"]
    xyz = {c.name: c.description for c in heavy_top(sequence="xyz").coordinates}
    assert "beta_ball = ±π/2" in xyz["gamma_ball"]


@pytest.mark.slow
def test_multibody_docstrings_run():
    import doctest

    import lagrangian.plugins.multibody as mb

    result = doctest.testmod(mb, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert result.failed == 0 and result.attempted > 10


# Property: for every sequence, random angles, rates and body parameters over decades, the joint's kinematics
# (rotation, angular velocity) and the body's kinetic energy agree with sympy.physics.vector's for that sequence.

_SYM = sp.symbols("m_b I1 I2 I3 cx cy cz", positive=True)


def _kinematics(sequence):
    """(ours, theirs): functions (q, v, params) → (R, ω, T), each built once per sequence with symbolic parameters."""
    if sequence in _KIN:
        return _KIN[sequence]
    mb, I1, I2, I3, cx, cy, cz = _SYM
    model = lg.Model("ball", dim=3)
    model.add("body", "b", "b", m=mb, inertia=(I1, I2, I3), com=(cx, cy, cz))
    model.add("spherical", "j", ("ground", "b"), sequence=sequence)
    eq = model.eq
    pose = model.assembly.views["mechanical"].poses["b"]
    funcs = [c.function for c in model.coordinates]
    to_plain = {**{f.diff(t): vi for f, vi in zip(funcs, eq.sym.v)}, **dict(zip(funcs, eq.sym.q))}
    R, w = pose.R.subs(to_plain), pose.omega.subs(to_plain)
    ours_fn = sp.lambdify((eq.sym.q, eq.sym.v, _SYM), [R, w, eq.T], "numpy")
    q = me.dynamicsymbols("q1:4")
    N, B = me.ReferenceFrame("N"), me.ReferenceFrame("B")
    B.orient_body_fixed(N, q, sequence)
    O = me.Point("O")
    O.set_vel(N, 0)
    Gc = O.locatenew("G", cx * B.x + cy * B.y + cz * B.z)
    Gc.set_vel(N, Gc.pos_from(O).dt(N))
    body = me.RigidBody("b", Gc, B, mb, (me.inertia(B, I1, I2, I3), Gc))
    Q, U = sp.symbols("Q1:4"), sp.symbols("U1:4")
    plain = lambda e: e.xreplace({**{qi.diff(t_mech()): ui for qi, ui in zip(q, U)}, **dict(zip(q, Q))})  # noqa: E731
    theirs_fn = sp.lambdify((Q, U, _SYM), [plain(N.dcm(B)), plain(B.ang_vel_in(N).to_matrix(N)),
                                           plain(body.kinetic_energy(N))], "numpy")
    _KIN[sequence] = (ours_fn, theirs_fn)
    return _KIN[sequence]


_KIN: dict = {}


def _log_uniform(lo, hi):
    from hypothesis import strategies as st

    return st.floats(math.log10(lo), math.log10(hi)).map(lambda e: 10.0**e)


def _signed(lo, hi):
    from hypothesis import strategies as st

    return st.tuples(_log_uniform(lo, hi), st.sampled_from((-1.0, 1.0))).map(lambda p: p[0] * p[1])


def _property_test():
    from hypothesis import given, settings
    from hypothesis import strategies as st

    angles = st.tuples(*[st.floats(-math.pi, math.pi)] * 3)
    rates = st.tuples(*[_signed(1e-2, 1e2)] * 3)
    # principal moments over four decades that make a body (triangle inequality): I3 ≤ I1 + I2
    moments = st.tuples(_log_uniform(1e-3, 1e1), _log_uniform(1e-3, 1e1), st.floats(0.05, 1.0))
    params = st.tuples(_log_uniform(1e-2, 1e2), moments, st.tuples(*[_signed(1e-2, 1e1)] * 3))

    @settings(max_examples=30)
    @given(sequence=st.sampled_from(ALL_SEQUENCES), q=angles, v=rates, p=params)
    @pytest.mark.slow
    def test_joint_kinematics_and_body_energy_match_sympy_vector_for_every_sequence(sequence, q, v, p):
        mass, (I1, I2, frac), com = p
        values = (mass, I1, I2, frac * (I1 + I2), *com)
        ours_fn, theirs_fn = _kinematics(sequence)
        (R, w, T), (R_ref, w_ref, T_ref) = ours_fn(q, v, values), theirs_fn(q, v, values)
        R, w, R_ref, w_ref = (np.asarray(x, dtype=float).reshape(-1) for x in (R, w, R_ref, w_ref))
        assert np.max(np.abs(R - R_ref)) < 1e-13
        assert np.max(np.abs(w - w_ref)) < 1e-13 * np.max(np.abs(v))
        assert abs(float(T) - float(T_ref)) < 1e-12 * float(T_ref)

    return test_joint_kinematics_and_body_energy_match_sympy_vector_for_every_sequence


test_joint_kinematics_and_body_energy_match_sympy_vector_for_every_sequence = _property_test()
