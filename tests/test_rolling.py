"""Rolling without slipping (the ``rolling`` kind): a disc rolling on the ground in space against
sympy.physics.mechanics' KanesMethod (contact-point coordinates, two velocity constraints) with masses and radii
over decades; the upright disc's lean against its closed form (stable above v² = g r / 3, oscillating at
ω² = 4/5 (3 Ω² − g/r)); energy kept; a wheel in the plane and a ball pushed at their closed forms; bad input refused."""

import functools
import math

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me
from hypothesis import given, settings
from hypothesis import strategies as st

import lagrangian as lg

G = 9.81


def decade(lo, hi):
    return st.floats(math.log10(lo), math.log10(hi)).map(lambda e: float(f"{10 ** e:.3g}"))


def disc(m, r):
    """A uniform disc on a free joint (z-x-z angles: yaw φ, lean θ from the vertical axis, spin ψ) rolling on z = 0."""
    model = lg.Model("rolling disc", dim=3)
    model.add("disc", "d", "d", m=m, radius=r)
    model.add("free", "j", ("ground", "d"), sequence="zxz")
    model.add("rolling", "roll", "d", radius=r)
    model.add("gravity", "g", g=G)
    return model


@functools.lru_cache(maxsize=1)
def kane_disc():
    """The rolling disc in sympy.physics.mechanics, built apart from ours: coordinates (φ, θ, ψ, x, y) with (x, y)
    the contact point, speeds u1..u3 = (φ̇, θ̇, ψ̇) independent and u4, u5 = (ẋ, ẏ) dependent through the disc's
    point at the contact not sliding.  Returns numeric functions of (m, r, φ, θ, ψ, u1, u2, u3): the angles'
    accelerations, and the centre's position and velocity (what our state holds)."""
    phi, theta, psi, x, y = me.dynamicsymbols("phi theta psi x y")
    u = me.dynamicsymbols("u1:6")
    m, r = sp.symbols("m r", positive=True)
    N = me.ReferenceFrame("N")
    A = N.orientnew("A", "Body", [phi, theta, psi], "zxz")
    L = N.orientnew("L", "Body", [phi, theta, 0], "zxz")  # yawed and leant, not spun: L.y points up the disc
    A.set_ang_vel(N, A.ang_vel_in(N).subs({phi.diff(): u[0], theta.diff(): u[1], psi.diff(): u[2]}))
    O = me.Point("O")
    O.set_vel(N, 0)
    P = O.locatenew("P", x * N.x + y * N.y)
    P.set_vel(N, u[3] * N.x + u[4] * N.y)
    Gc = P.locatenew("G", r * L.y)
    rates = {phi.diff(): u[0], theta.diff(): u[1], psi.diff(): u[2], x.diff(): u[3], y.diff(): u[4]}
    Gc.set_vel(N, Gc.pos_from(O).dt(N).subs(rates))
    slip = Gc.vel(N) + A.ang_vel_in(N).cross(P.pos_from(Gc))  # the disc's material point at the contact
    km = me.KanesMethod(N, q_ind=[phi, theta, psi, x, y], u_ind=u[:3], u_dependent=u[3:],
                        kd_eqs=[q.diff() - ui for q, ui in zip([phi, theta, psi, x, y], u)],
                        velocity_constraints=[slip.dot(N.x), slip.dot(N.y)])
    body = me.RigidBody("D", Gc, A, m, (me.inertia(A, m * r**2 / 4, m * r**2 / 4, m * r**2 / 2), Gc))
    km.kanes_equations([body], [(Gc, -m * G * N.z)])
    dep = sp.solve([slip.dot(N.x), slip.dot(N.y)], u[3:], dict=True)[0]
    args = (m, r, phi, theta, psi, *u[:3])
    # the full mass matrix and forcing (kinematic rows, dynamic rows, the constraints' rows), solved numerically
    full = sp.lambdify((*args, *u[3:]), [km.mass_matrix_full, km.forcing_full], "numpy", cse=True)
    dependent = sp.lambdify(args, [dep[u[3]], dep[u[4]]], "numpy", cse=True)

    def accelerations(*values):
        M, f = full(*values, *dependent(*values))
        return np.linalg.solve(np.asarray(M, float), np.asarray(f, float).ravel())[5:8]  # u̇1..u̇3

    centre = [e.subs({x: 0, y: 0}) for e in Gc.pos_from(O).to_matrix(N)]
    velocity = [e.subs(dep) for e in Gc.vel(N).to_matrix(N)]
    return accelerations, sp.lambdify(args, centre, "numpy"), sp.lambdify(args, velocity, "numpy")


def state(m, r, angles, rates):
    """Our state (x, y, z, φ, θ, ψ and their rates) for the disc touching the ground at the origin."""
    _, centre, velocity = kane_disc()
    args = (m, r, *angles, *rates)
    return np.array([*np.ravel(centre(*args)), *angles, *np.ravel(velocity(*args)), *rates], dtype=float)


@settings(max_examples=8, deadline=None)
@given(decade(1e-2, 1e2), decade(1e-2, 1e1), st.floats(-math.pi, math.pi), st.floats(0.3, 2.8),
       st.floats(-math.pi, math.pi), st.tuples(st.floats(-3, 3), st.floats(-3, 3), st.floats(-30, 30)))
@pytest.mark.slow
def test_rolling_disc_accelerations_match_kane_over_decades(m, r, phi, theta, psi, w):
    rates = (w[0], w[1], w[2] / max(r, 0.1))
    model = disc(m, r)
    y = state(m, r, (phi, theta, psi), rates)
    ours = model.numeric().rhs(0.0, y)[9:]
    accel, _, _ = kane_disc()
    theirs = np.array(accel(m, r, phi, theta, psi, *rates), dtype=float)
    scale = G / r + sum(x * x for x in rates)
    assert np.max(np.abs(ours - theirs)) <= 1e-10 * scale


def upright(m, r, Omega, lean, t_end, points=401):
    """The disc rolling straight along x, upright but for ``lean`` rad, spinning at ``Omega`` (v = Ω r)."""
    model = disc(m, r)
    angles, rates = (0.0, math.pi / 2 + lean, 0.0), (0.0, 0.0, -Omega)
    y = state(m, r, angles, rates)
    names = model.coordinate_names
    res = model.simulate(t_end, initial=dict(zip(names, y[:6])), velocity=dict(zip(names, y[6:])), points=points,
                         rtol=1e-11, atol=1e-13)
    return model, res


def test_upright_disc_rolls_steadily_above_the_critical_speed_and_leans_at_the_closed_form_frequency():
    m, r = 0.3, 0.07
    Omega = math.sqrt(2 * G / (3 * r))  # v² = 2 g r / 3: twice the critical v² = g r / 3
    w_lean = math.sqrt(0.8 * (3 * Omega**2 - G / r))
    period = 2 * math.pi / w_lean
    _, res = upright(m, r, Omega, 1e-4, 3 * period, points=3001)
    lean = res["theta_j"] - math.pi / 2
    assert np.max(np.abs(lean)) < 4e-4  # it stays upright (the lean swings about that of a steady turn)
    # upward crossings of the swing's middle: one period of the closed form apart
    lean = lean - (lean.max() + lean.min()) / 2
    up = np.flatnonzero((lean[:-1] < 0) & (lean[1:] >= 0))
    times = res.t[up] - lean[up] * (res.t[up + 1] - res.t[up]) / (lean[up + 1] - lean[up])
    assert len(times) >= 2
    assert np.diff(times).mean() == pytest.approx(period, rel=1e-4)
    assert res["x_j"][-1] == pytest.approx(Omega * r * res.t[-1], rel=1e-5)  # v = Ω r (the lean turns it a little)


def test_upright_disc_below_the_critical_speed_falls_at_the_closed_form_rate():
    m, r = 0.3, 0.07
    Omega = math.sqrt(0.5 * G / (3 * r))  # v² = g r / 6: below the critical g r / 3
    rate = math.sqrt(0.8 * (G / r - 3 * Omega**2))
    t_end = 4.0 / rate
    _, res = upright(m, r, Omega, 1e-6, t_end, points=201)
    lean = res["theta_j"] - math.pi / 2
    assert abs(lean[-1]) > 20 * abs(lean[0])  # it falls
    # lean = A e^{λt} + B e^{−λt} + C (C: a steady turn's lean): its differences g over a stride h have
    # g(t + h) + g(t − h) = 2 cosh(λh) g(t)
    h = 10
    g = lean[h:] - lean[:-h]
    k = len(g) - 1 - h
    grown = math.acosh((g[k + h] + g[k - h]) / (2 * g[k])) / (res.t[h] - res.t[0])
    assert grown == pytest.approx(rate, rel=1e-4)  # λ² = 4/5 (g/r − 3 Ω²), while the lean is still small


def test_a_tumbling_disc_keeps_its_energy_and_never_slides():
    m, r = 0.25, 0.12
    model = disc(m, r)
    y = state(m, r, (0.4, 1.2, -0.3), (0.7, -0.5, 9.0))
    names = model.coordinate_names
    res = model.simulate(1.5, initial=dict(zip(names, y[:6])), velocity=dict(zip(names, y[6:])), points=301,
                         rtol=1e-11, atol=1e-13)
    E = res.E
    assert np.max(np.abs(E - E[0])) < 1e-8 * abs(E[0])
    assert np.max(np.abs(res["z_j"] - r * np.sin(res["theta_j"]))) < 1e-8 * r


def test_a_wheel_in_the_plane_pushed_at_its_centre_accelerates_at_the_closed_form():
    m, r, F = 0.4, 0.15, 1.3
    model = lg.Model("wheel", dim=2)
    model.add("disc", "d", "d", m=m, radius=r)
    model.add("free", "j", ("ground", "d"))
    model.add("rolling", "roll", "d", radius=r)
    model.add("gravity", "g", g=G)
    model.add("force", "push", "d", F=[F, 0])
    res = model.simulate(2.0, initial={"x_j": 0.0, "y_j": r, "theta_j": 0.0}, velocity={"x_j": 0, "y_j": 0, "theta_j": 0},
                         points=21, rtol=1e-12, atol=1e-14)
    a = F / (m + (m * r**2 / 2) / r**2)  # F / (m + I/r²)
    assert np.max(np.abs(res["x_j"] - a * res.t**2 / 2)) < 1e-10
    assert np.max(np.abs(res["theta_j"] + res["x_j"] / r)) < 1e-10


def test_a_ball_pushed_along_the_ground_accelerates_at_five_sevenths():
    m, r, F = 0.17, 0.03, 0.2
    model = lg.Model("ball", dim=3)
    I = 2 * m * r**2 / 5
    model.add("body", "b", "b", m=m, inertia=(I, I, I))
    model.add("free", "j", ("ground", "b"))
    model.add("rolling", "roll", "b", radius=r, shape="sphere")
    model.add("gravity", "g", g=G)
    model.add("force", "push", "b", F=[0, F, 0])
    names = model.coordinate_names
    res = model.simulate(1.0, initial={**dict.fromkeys(names, 0.0), "z_j": r}, velocity=dict.fromkeys(names, 0.0),
                         points=11, rtol=1e-12, atol=1e-14)
    assert np.max(np.abs(res["y_j"] - 5 / 7 * F / m * res.t**2 / 2)) < 1e-10
    assert np.max(np.abs(res["x_j"])) < 1e-12 and np.max(np.abs(res["z_j"] - r)) < 1e-12


def test_rolling_refuses_an_unknown_shape_a_point_and_a_flat_axis():
    model = lg.Model("bad", dim=3)
    with pytest.raises(lg.ModelError, match="shape is 'disc' or 'sphere'"):
        model.add("rolling", "roll", "d", radius=0.1, shape="cube")
    m2 = disc(1.0, 0.1)
    m2.add("rolling", "roll2", "d.rim", radius=0.1)
    with pytest.raises(lg.ModelError, match="attach it to a body"):
        m2.eq  # noqa: B018
    m3 = lg.Model("bad axis", dim=3)
    m3.add("disc", "d", "d", m=1.0, radius=0.1)
    m3.add("free", "j", ("ground", "d"))
    m3.add("rolling", "roll", "d", radius=0.1, axis=(0, 0, 0))
    with pytest.raises(lg.ModelError, match="axis is a nonzero vector"):
        m3.eq  # noqa: B018


def test_the_routhian_refuses_a_rolling_disc_by_name():
    from lagrangian import routh

    with pytest.raises(lg.ModelError, match="roll"):
        routh.reduce(disc(1.0, 0.1))


def test_a_disc_struck_at_its_top_rolls_off_at_four_thirds_of_the_blow_over_its_mass():
    """An upright disc at rest struck horizontally in its plane at its top: about the contact (where the ground's
    impulses act) P · 2r = (I + m r²) ω, so it rolls off at v = ω r = 4P / 3m, neither leaning nor turning."""
    from lagrangian import impulse

    m, r, P = 0.3, 0.07, 0.011
    model = lg.Model("struck disc", dim=3)
    model.add("disc", "d", "d", m=m, radius=r, points={"top": (0, r, 0)})  # upright (θ = π/2): body y is up
    model.add("free", "j", ("ground", "d"), sequence="zxz")
    model.add("rolling", "roll", "d", radius=r)
    model.add("gravity", "g", g=G)
    names = model.coordinate_names
    at = {**dict.fromkeys(names, 0.0), "z_j": r, "theta_j": math.pi / 2}
    jump = impulse.velocity_jump(model, [impulse.Impulse("d.top", (P, 0.0, 0.0))], at=at,
                                 velocity=dict.fromkeys(names, 0.0))
    after = {k: float(x) for k, x in jump.after.items()}
    assert after["x_j"] == pytest.approx(4 * P / (3 * m), rel=1e-12)
    assert after["psi_j"] == pytest.approx(-4 * P / (3 * m * r), rel=1e-12)  # spinning about its axis, -y
    for k in ("y_j", "z_j", "phi_j", "theta_j"):
        assert abs(after[k]) < 1e-14 * after["x_j"] / r
    assert float(jump.T_after) == pytest.approx(0.75 * m * after["x_j"] ** 2, rel=1e-12)  # ½(m + I/r²)v²


def test_a_ball_on_a_turntable_circles_at_two_sevenths_of_its_rate():
    """A uniform ball on a table turning at Ω: v̇ = (2/7) Ω ẑ × v (friction turns it, I/(I + m r²) = 2/7), so
    released at (a, 0) with velocity (0, u) its centre runs on a circle at k = 2Ω/7:
    x = a + (u/k)(cos kt − 1), y = (u/k) sin kt."""
    m, r, Omega, a, u = 0.05, 0.02, 3.3, 0.4, 0.15
    I = 2 * m * r**2 / 5
    model = lg.Model("ball on a turntable", dim=3)
    model.add("body", "b", "b", m=m, inertia=(I, I, I))
    model.add("free", "j", ("ground", "b"))  # x-y-z angles: at zero, their rates are ω's components
    model.add("rolling", "roll", "b", radius=r, shape="sphere", turntable=Omega)
    model.add("gravity", "g", g=G)
    names = model.coordinate_names
    spin = 0.7  # about the vertical: kept, the contact's forces have no moment about it
    res = model.simulate(10.0, initial={**dict.fromkeys(names, 0.0), "x_j": a, "z_j": r},
                         velocity={**dict.fromkeys(names, 0.0), "y_j": u, "alpha_j": (Omega * a - u) / r, "gamma_j": spin},
                         points=101, rtol=1e-12, atol=1e-14)
    k = 2 * Omega / 7
    assert np.max(np.abs(res["x_j"] - (a + u / k * (np.cos(k * res.t) - 1)))) < 1e-8
    assert np.max(np.abs(res["y_j"] - u / k * np.sin(k * res.t))) < 1e-8
    with pytest.raises(lg.ModelError, match="turntable turns the ground of a model in space"):
        planar = lg.Model("planar", dim=2)
        planar.add("disc", "d", "d", m=1.0, radius=0.1)
        planar.add("free", "j", ("ground", "d"))
        planar.add("rolling", "roll", "d", radius=0.1, turntable=1.0)
        planar.eq  # noqa: B018


def test_consistent_initial_solves_the_centre_from_the_turning_rates():
    """The disc's height from its lean, and its centre's velocity from its turning rates through the contact's not
    sliding: the state the KanesMethod model gives for the same angles and rates."""
    from lagrangian.plugins.multibody import consistent_initial, constraint_residual

    m, r = 0.3, 0.07
    model = disc(m, r)
    angles, rates = (0.2, 1.3, 0.4), (0.5, 0.1, -20.0)
    start = consistent_initial(model, {"x_j": 0.0, "y_j": 0.0, "z_j": 0.05, **dict(zip(["phi_j", "theta_j", "psi_j"], angles))},
                               dict(zip(["phi_j", "theta_j", "psi_j"], rates)),
                               independent=["x_j", "y_j", "phi_j", "theta_j", "psi_j"])
    want = state(m, r, angles, rates)
    names = model.coordinate_names
    assert start.initial["z_j"] == pytest.approx(want[2], rel=1e-12)
    assert [start.velocity[n] for n in names] == pytest.approx(list(want[6:]), rel=1e-10, abs=1e-12)
    res = model.simulate(0.5, initial=start.initial, velocity=start.velocity, points=11)
    assert constraint_residual(model, res) < 1e-9
    with pytest.raises(lg.ModelError, match=r"cannot satisfy the constraints on velocities of 'roll'"):
        consistent_initial(model, start.initial, {**dict(zip(["phi_j", "theta_j", "psi_j"], rates)), "x_j": 5.0, "y_j": 0.0},
                           independent=["x_j", "y_j", "phi_j", "theta_j", "psi_j"])


def test_consistent_initial_holds_a_knife_edge_without_loops():
    from lagrangian.plugins.multibody import consistent_initial

    model = lg.Model("sled", dim=2)
    model.add("body", "b", "b", m=2.0, inertia=0.1)
    model.add("free", "j", ("ground", "b"))
    model.add("knife_edge", "edge", "b")
    start = consistent_initial(model, {"x_j": 0.0, "y_j": 0.0, "theta_j": 0.4}, {"x_j": 1.0, "theta_j": 0.3})
    assert start.velocity["y_j"] == pytest.approx(math.tan(0.4), rel=1e-12)  # along the edge: ẏ/ẋ = tan θ
    assert start.velocity["theta_j"] == 0.3


def test_consistent_initial_names_a_rolling_contact_as_the_component_it_is():
    from lagrangian.plugins.multibody import consistent_initial

    model = disc(0.3, 0.07)
    with pytest.raises(lg.ModelError, match=r"the constraints do not hold .* at component 'roll'\)"):
        consistent_initial(model, {"x_j": 0, "y_j": 0, "z_j": 0.05, "phi_j": 0.2, "theta_j": 1.3, "psi_j": 0.0})
