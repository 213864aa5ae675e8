"""Constraints on velocities (nonholonomic) in the Lagrange–d'Alembert form: a knife-edge sled checked against
sympy.physics.mechanics' KanesMethod with the same velocity constraint, and against its closed form; the analyses
that do not cover such constraints refuse them by name; an impact keeps them."""

import functools
import math

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me
from hypothesis import given, settings
from hypothesis import strategies as st

import lagrangian as lg


def decade(lo, hi):
    return st.floats(math.log10(lo), math.log10(hi)).map(lambda e: float(f"{10 ** e:.3g}"))


def sled(m, I, push=0.0, tau=0.0):
    """A planar body on a free joint whose reference point cannot slide across the body's axis (a knife edge or a
    skate): −sin θ ẋ + cos θ ẏ = 0; pushed along x with a constant force and turned by a constant torque."""
    model = lg.Model("sled", dim=2)
    model.add("body", "b", "b", m=m, inertia=I)
    model.add("free", "j", ("ground", "b"))
    th = lg.coordinate("theta_j")
    model.add("velocity_constraint", "edge", c=-sp.sin(th) * lg.rate("x_j") + sp.cos(th) * lg.rate("y_j"))
    if push:
        model.add("force", "push", "b", F=[push, 0])
    if tau:
        model.add("body_torque", "turn", "b", tau=tau)
    return model


@functools.lru_cache(maxsize=1)
def kane_sled():
    """The sled in sympy.physics.mechanics: speeds u1 = ẋ, u3 = θ̇ independent, u2 = ẏ dependent through the same
    constraint; the accelerations (ẍ, ÿ, θ̈) as functions of (θ, u1, u2, u3, m, I, F, τ)."""
    x, y, th = me.dynamicsymbols("x y th")
    u1, u2, u3 = me.dynamicsymbols("u1 u2 u3")
    m, I, F, tau = sp.symbols("m I F tau")
    N = me.ReferenceFrame("N")
    B = N.orientnew("B", "Axis", (th, N.z))
    B.set_ang_vel(N, u3 * N.z)
    P = me.Point("P")
    P.set_vel(N, u1 * N.x + u2 * N.y)
    body = me.RigidBody("b", P, B, m, (me.inertia(B, 0, 0, I), P))
    km = me.KanesMethod(N, q_ind=[x, y, th], u_ind=[u1, u3], u_dependent=[u2],
                        kd_eqs=[x.diff() - u1, y.diff() - u2, th.diff() - u3],
                        velocity_constraints=[-sp.sin(th) * u1 + sp.cos(th) * u2])
    km.kanes_equations([body], [(P, F * N.x), (B, tau * N.z)])
    rhs = km.rhs()  # q̇ (3), then u̇ in the order u1, u3, u2
    return sp.lambdify((th, u1, u2, u3, m, I, F, tau), [rhs[3], rhs[5], rhs[4]])


@settings(max_examples=15)
@given(decade(0.05, 20), decade(1e-4, 1), st.floats(-10, 10), st.floats(-2, 2), st.floats(-math.pi, math.pi),
       st.floats(-5, 5), st.floats(-5, 5))
@pytest.mark.slow
def test_knife_edge_accelerations_match_kane_over_decades(m, I, push, tau, theta, speed, omega):
    model = sled(m, I, push, tau)
    y = np.array([0.3, -0.2, theta, speed * math.cos(theta), speed * math.sin(theta), omega])
    ours = model.numeric().rhs(0.0, y)[3:]
    reference = kane_sled()(theta, speed * math.cos(theta), speed * math.sin(theta), omega, m, I, push, tau)
    # the accelerations' own size, and the round-off of the constraint's residual (about speed × ε, which its
    # stabilization turns into an acceleration: 4e-16 at speed 5 with nothing pushing, turning or moving)
    scale = abs(push) / m + abs(tau) / I + abs(speed * omega) + 1e-5 * abs(speed) + 1e-12
    assert np.max(np.abs(ours - np.array(reference, dtype=float))) <= 1e-9 * scale


def test_a_free_sled_turns_on_a_circle_and_keeps_its_energy():
    v, w, th0 = 1.5, 0.8, 0.3
    model = sled(2.0, 0.1)
    res = model.simulate(6.0, initial={"x_j": 0.0, "y_j": 0.0, "theta_j": th0},
                         velocity={"x_j": v * math.cos(th0), "y_j": v * math.sin(th0), "theta_j": w},
                         points=61, rtol=1e-12, atol=1e-14)
    th = th0 + w * res.t
    assert np.max(np.abs(res["theta_j"] - th)) < 1e-11
    assert np.max(np.abs(res["x_j"] - v / w * (np.sin(th) - math.sin(th0)))) < 1e-11
    assert np.max(np.abs(res["y_j"] + v / w * (np.cos(th) - math.cos(th0)))) < 1e-11
    assert np.ptp(res.E) < 1e-11 * res.E[0]  # the edge's force does no work
    assert any(note.startswith("energy (Jacobi integral) kept to") for note in res.notes)  # and the run checks it
    moving = lg.Model("sled on a turning track", dim=2)  # an edge whose direction is driven: its force does work
    moving.add("body", "b", "b", m=2.0, inertia=0.1)
    moving.add("free", "j", ("ground", "b"))
    moving.add("velocity_constraint", "edge", c=-sp.sin(0.5 * lg.t) * lg.rate("x_j") + sp.cos(0.5 * lg.t) * lg.rate("y_j"))
    run = moving.simulate(1.0, initial={"x_j": 0, "y_j": 0, "theta_j": 0}, velocity={"x_j": 1.0, "y_j": 0, "theta_j": 0},
                          method="auto", points=11)
    assert any("constraints move with time" in note for note in run.notes)
    assert not any(note.startswith("energy (Jacobi integral) kept") for note in run.notes)
    from lagrangian import routh

    assert routh.jacobi_integral(model).conserved  # the fixed edge keeps the Jacobi integral
    moved = routh.jacobi_integral(moving)
    assert not moved.conserved and "constraint on velocities moves with time (from 'edge')" in moved.reasons[0]


def test_the_start_must_satisfy_the_constraint_and_the_analyses_that_do_not_cover_it_say_so():
    from lagrangian import routh
    from lagrangian.operating import equilibria
    from lagrangian.scene import Scene
    from lagrangian.sweep import sweep

    model = sled(2.0, 0.1)
    with pytest.raises(lg.ModelError, match=r"violate the constraints on velocities of 'edge'.*give rates that satisfy"):
        model.simulate(1.0, initial={"x_j": 0, "y_j": 0, "theta_j": 0.3}, velocity={"x_j": 1, "y_j": 1, "theta_j": 0})
    for call in (lambda: equilibria(model),
                 lambda: Scene(model, ["x_j"], 1.0), lambda: model.simulate(1.0, method="exact"),
                 lambda: sweep(model, {"m_b": [1.0, 2.0]}, client="serial", t_end=1.0, progress=False)):
        with pytest.raises(lg.ModelError, match="nonholonomic"):
            call()
    with pytest.raises(lg.ReductionError, match=r"nonholonomic.*'edge'"):
        routh.reduce(model)
    with pytest.raises(lg.ModelError, match="holds no rate"):
        bad = lg.Model("bad")
        bad.add("mass", "m1", "p", m=1)
        bad.add("velocity_constraint", "c", c=lg.coordinate("x_p") - 1)
        bad.equations
    with pytest.raises(lg.ModelError, match="not linear in the rates"):
        bad = lg.Model("bad")
        bad.add("mass", "m1", "p", m=1)
        bad.add("mass", "m2", "q", m=1)
        bad.add("velocity_constraint", "c", c=lg.rate("x_p") * lg.rate("x_q"))
        bad.equations


def test_a_blow_across_the_edge_leaves_the_sled_moving_along_it():
    """An impulse P across a sled at rest: the edge's reaction cancels the part across it, so the sled starts along
    its axis with speed P·e / m (e the axis) and turns with the moment about its reference point (here none)."""
    from lagrangian import impulse

    th0, m = 0.4, 2.0
    model = sled(m, 0.1)
    P = np.array([0.5, 1.2])
    at = {"x_j": 0.0, "y_j": 0.0, "theta_j": th0}
    jump = impulse.velocity_jump(model, [impulse.Impulse("b", tuple(P))], at=at,
                                 velocity={"x_j": 0.0, "y_j": 0.0, "theta_j": 0.0})
    after = {k: float(x) for k, x in jump.after.items()}
    e = np.array([math.cos(th0), math.sin(th0)])
    speed = float(P @ e) / m
    assert after["x_j"] == pytest.approx(speed * e[0], rel=1e-12)
    assert after["y_j"] == pytest.approx(speed * e[1], rel=1e-12)
    assert after["theta_j"] == pytest.approx(0.0, abs=1e-14)
    assert float(jump.T_after) == pytest.approx(0.5 * m * speed**2, rel=1e-12)


def test_the_knife_edge_kind_is_the_written_constraint_and_off_the_centre_is_chaplygins_sled():
    """The built-in knife_edge at the centre of mass gives the sled written by hand; at a distance a ahead of it,
    Chaplygin's sled: u̇ = −a ω², (I + m a²) ω̇ = a m u ω, so the forward speed u = −U tanh(a m U t / J − atanh(u₀/U))
    with J = I + m a² and U² = 2E/m."""
    m, I, a = 2.0, 0.1, 0.3
    written = sled(m, I, push=0.7, tau=0.2)
    built = lg.Model("sled", dim=2)
    built.add("body", "b", "b", m=m, inertia=I)
    built.add("free", "j", ("ground", "b"))
    built.add("knife_edge", "edge", "b")
    built.add("force", "push", "b", F=[0.7, 0])
    built.add("body_torque", "turn", "b", tau=0.2)
    rng = np.random.default_rng(3)
    for _ in range(5):
        th, speed, w = rng.uniform(-3, 3), rng.uniform(-2, 2), rng.uniform(-2, 2)
        y = np.array([0.1, 0.2, th, speed * math.cos(th), speed * math.sin(th), w])
        assert np.allclose(built.numeric().rhs(0.0, y), written.numeric().rhs(0.0, y), rtol=1e-13, atol=1e-13)

    chaplygin = lg.Model("Chaplygin sled", dim=2)
    chaplygin.add("body", "b", "b", m=m, inertia=I, points={"edge": (a, 0)})
    chaplygin.add("free", "j", ("ground", "b"))
    chaplygin.add("knife_edge", "edge", "b.edge")
    th0, u0, w0 = 0.2, 0.4, 1.5
    e, n = np.array([math.cos(th0), math.sin(th0)]), np.array([-math.sin(th0), math.cos(th0)])
    v0 = u0 * e - a * w0 * n  # the centre's velocity: the edge point moves along e only
    res = chaplygin.simulate(6.0, initial={"x_j": 0.0, "y_j": 0.0, "theta_j": th0},
                             velocity={"x_j": v0[0], "y_j": v0[1], "theta_j": w0}, points=121, rtol=1e-12, atol=1e-14)
    th = res["theta_j"]
    u = np.cos(th) * res.velocity("x_j") + np.sin(th) * res.velocity("y_j")
    J = I + m * a**2
    U = math.sqrt(u0**2 + J * w0**2 / m)
    exact = -U * np.tanh(a * m * U * res.t / J - math.atanh(u0 / U))
    assert np.max(np.abs(u - exact)) < 1e-9 * U
    assert np.ptp(res.E) < 1e-10 * res.E[0]
