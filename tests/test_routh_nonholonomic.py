"""Routhian reduction of the coordinates a constraint on velocities (nonholonomic) leaves alone: a knife-edge sled
carrying a flywheel on a revolute joint.  The flywheel's relative angle is ignorable and no constraint holds it; the
reduced model keeps the edge with its multiplier.  Checked against the full model's own simulation (the same
initial state, the momentum C = I_w (θ̇_j + θ̇_r) written by hand), the flywheel's momentum conserved along the full
run, and closed forms: with the edge at the centre of mass the sled turns at a constant rate on a circle of radius
u/ω; off it, Chaplygin's sled of the total mass M = m + m_w and the sled's own inertia I (the flywheel, pivoted at
its centre of mass, spins apart: its absolute rate is C/I_w), u = −U tanh(a M U t / J − atanh(u₀/U)), J = I + M a²,
U² = u₀² + J ω₀²/M.  The coordinates the edge couples, and models whose every coordinate it couples, are refused by
name, and so are the analyses of a reduced model that do not cover a constraint on velocities."""

import math

import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

import lagrangian as lg
from lagrangian import routh

TIGHT = {"rtol": 1e-12, "atol": 1e-14}


def decade(lo, hi):
    return st.floats(math.log10(lo), math.log10(hi)).map(lambda e: float(f"{10 ** e:.3g}"))


def flywheel_sled(m, I, mw, Iw, a=0.0, hub=(0.0, 0.0)):
    """A planar sled (mass m, inertia I about its centre of mass, the body's origin) on a free joint, with a knife
    edge at a distance ``a`` ahead of the centre along the body's x axis, carrying a flywheel (mass mw, inertia Iw
    about its own centre) on a revolute joint at ``hub`` in the sled's frame: coordinates x_j, y_j, theta_j of the
    sled, theta_r the flywheel's angle relative to it."""
    model = lg.Model("flywheel sled", dim=2)
    model.add("body", "b", "b", m=m, inertia=I, points={"edge": (a, 0.0)})
    model.add("free", "j", ("ground", "b"))
    model.add("knife_edge", "edge", "b.edge")
    model.add("body", "w", "w", m=mw, inertia=Iw)
    model.add("revolute", "r", ("b", "w"), parent_point=hub)
    return model


def start(a, theta0, u0, w0, wr0):
    """A state the edge allows: the edge point moves along the body's axis e at u0, so the centre moves at
    u0 e − a ω n (n the edge's normal); the flywheel turns at wr0 relative to the sled."""
    e = np.array([math.cos(theta0), math.sin(theta0)])
    n = np.array([-math.sin(theta0), math.cos(theta0)])
    v = u0 * e - a * w0 * n
    initial = {"x_j": 0.1, "y_j": -0.2, "theta_j": theta0, "theta_r": 0.4}
    velocity = {"x_j": float(v[0]), "y_j": float(v[1]), "theta_j": w0, "theta_r": wr0}
    return initial, velocity


@pytest.mark.slow
def test_the_flywheel_angle_is_reduced_and_the_edge_stays_with_its_owner():
    model = flywheel_sled(2.0, 0.1, 0.3, 7e-3, a=0.2, hub=(0.1, 0.05))
    report = routh.ignorability(model)
    assert report["theta_r"].ignorable
    assert "nonholonomic, from 'edge'" in report["x_j"].reason
    red = routh.reduce(model)
    assert red.ignored == ["theta_r"]
    assert red.coordinate_names == ["x_j", "y_j", "theta_j"]
    assert red.eq.velocity_owners == ["edge"]
    # the edge's row, unchanged: the same A(q)·q̇ at random states of the sled
    rng = np.random.default_rng(7)
    full_eq = model.eq
    for _ in range(5):
        point = {s: float(x) for s, x in zip([*full_eq.sym.q, *full_eq.sym.v], rng.uniform(-2, 2, 8))}
        ours = float(red.eq.velocity_constraints[0].xreplace(point))
        theirs = float(full_eq.velocity_constraints[0].xreplace(point))
        assert ours == pytest.approx(theirs, rel=1e-13, abs=1e-15)
    # the flywheel's rate from its momentum: C = I_w (θ̇_j + θ̇_r), so θ̇_r = C/I_w − θ̇_j
    C, w = sp.Symbol("C_theta_r", real=True), sp.Symbol("w")
    rate = red.rates["theta_r"].subs(sp.Derivative(lg.coordinate("theta_j"), lg.t), w)
    assert float(rate.subs({C: 0.021, w: 1.3})) == pytest.approx(0.021 / 7e-3 - 1.3, rel=1e-12)


@settings(max_examples=8, deadline=None)
@given(decade(0.05, 20), decade(1e-3, 1), decade(1e-2, 5), decade(1e-5, 0.1), st.floats(-0.4, 0.4),
       st.floats(-0.3, 0.3), st.floats(-0.3, 0.3), st.floats(-math.pi, math.pi), st.floats(-2, 2), st.floats(-2, 2),
       st.floats(-20, 20))
@pytest.mark.slow
def test_the_reduced_sled_moves_as_the_full_one_and_reconstructs_the_flywheel(m, I, mw, Iw, a, hx, hy, theta0, u0,
                                                                                w0, wr0):
    model = flywheel_sled(m, I, mw, Iw, a=a, hub=(hx, hy))
    initial, velocity = start(a, theta0, u0, w0, wr0)
    C = Iw * (w0 + wr0)  # the flywheel's angular momentum about its centre, by hand
    red = routh.reduce(model)
    assert red.momenta_from(initial, velocity)["theta_r"] == pytest.approx(C, rel=1e-12, abs=1e-15)
    T = 3.0
    full = model.simulate(T, initial=initial, velocity=velocity, points=31, **TIGHT)
    ours = red.simulate(T, initial=initial, velocity={k: x for k, x in velocity.items() if k != "theta_r"},
                        momenta={"theta_r": C}, reconstruct=True, points=31, **TIGHT)
    scale = 1.0 + math.hypot(velocity["x_j"], velocity["y_j"]) * T
    for name in ("x_j", "y_j"):
        assert np.max(np.abs(ours[name] - full[name])) <= 1e-9 * scale
    spin = 1.0 + (abs(w0) + abs(wr0) + abs(u0 / (a if abs(a) > 1e-3 else 1.0))) * T
    for name in ("theta_j", "theta_r"):
        assert np.max(np.abs(ours[name] - full[name])) <= 1e-9 * spin
    # physics: no torque acts on the flywheel, so its momentum is conserved along the full run
    p = Iw * (full.velocity("theta_j") + full.velocity("theta_r"))
    assert np.max(np.abs(p - C)) <= 1e-10 * (abs(C) + Iw * (abs(w0) + 1.0))


@pytest.mark.slow
def test_with_the_edge_at_the_centre_of_mass_the_sled_turns_on_a_circle():
    """Edge and hub at the sled's centre: the edge's force passes through the centre of mass of sled and flywheel, so
    θ̇ = ω₀ and the speed u₀ stay, and the centre runs on a circle of radius u₀/ω₀; the flywheel's absolute rate is
    C/I_w, so θ_r = θ_r0 + (C/I_w − ω₀) t."""
    m, I, mw, Iw = 2.0, 0.1, 0.3, 7e-3
    theta0, u0, w0, wr0 = 0.3, 1.5, 0.8, -4.0
    model = flywheel_sled(m, I, mw, Iw)
    initial, velocity = start(0.0, theta0, u0, w0, wr0)
    red = routh.reduce(model)
    res = red.simulate(6.0, initial=initial, velocity=velocity, reconstruct=True, points=61, **TIGHT)
    th = theta0 + w0 * res.t
    assert np.max(np.abs(res["theta_j"] - th)) < 1e-10
    assert np.max(np.abs(res["x_j"] - 0.1 - u0 / w0 * (np.sin(th) - math.sin(theta0)))) < 1e-10
    assert np.max(np.abs(res["y_j"] + 0.2 + u0 / w0 * (np.cos(th) - math.cos(theta0)))) < 1e-10
    C = Iw * (w0 + wr0)
    assert np.max(np.abs(res["theta_r"] - 0.4 - (C / Iw - w0) * res.t)) < 1e-9


@settings(max_examples=6, deadline=None)
@given(decade(0.05, 20), decade(1e-3, 1), decade(1e-2, 5), decade(1e-5, 0.1), st.floats(0.05, 0.5),
       st.floats(-math.pi, math.pi), st.floats(-1.5, 1.5), st.floats(0.1, 2), st.sampled_from([1, -1]),
       st.floats(-20, 20))
@pytest.mark.slow
def test_off_the_centre_the_reduced_sled_is_chaplygins_sled_of_the_total_mass(m, I, mw, Iw, a, theta0, u0, turn, sign,
                                                                                wr0):
    w0 = sign * turn  # turning (|u0| < U): without a turn it runs straight at u0
    model = flywheel_sled(m, I, mw, Iw, a=a)
    initial, velocity = start(a, theta0, u0, w0, wr0)
    red = routh.reduce(model)
    res = red.simulate(4.0, initial=initial, velocity=velocity, points=41, **TIGHT)
    th = res["theta_j"]
    u = np.cos(th) * res.velocity("x_j") + np.sin(th) * res.velocity("y_j")  # the centre's (and the edge's) speed along e
    M = m + mw
    J = I + M * a**2
    U = math.sqrt(u0**2 + J * w0**2 / M)
    exact = -U * np.tanh(a * M * U * res.t / J - math.atanh(u0 / U))
    assert np.max(np.abs(u - exact)) < 1e-8 * U


@pytest.mark.slow
def test_a_blow_across_the_edge_of_the_reduced_sled_leaves_it_moving_along_the_edge():
    """An impulse P at the centre of the sled at rest, its flywheel spinning: the edge cancels the part across it,
    so the sled starts along its axis e at P·e / (m + m_w), not turning; the flywheel's momentum is untouched."""
    from lagrangian import impulse

    m, I, mw, Iw, th0 = 2.0, 0.1, 0.3, 7e-3, 0.4
    red = routh.reduce(flywheel_sled(m, I, mw, Iw))
    P = np.array([0.5, 1.2])
    jump = impulse.velocity_jump(red, [impulse.Impulse("b", tuple(P))], at={"x_j": 0.0, "y_j": 0.0, "theta_j": th0},
                                 velocity={"x_j": 0.0, "y_j": 0.0, "theta_j": 0.0}, params={"C_theta_r": 0.02})
    after = {k: float(x) for k, x in jump.after.items()}
    e = np.array([math.cos(th0), math.sin(th0)])
    speed = float(P @ e) / (m + mw)
    assert after["x_j"] == pytest.approx(speed * e[0], rel=1e-12)
    assert after["y_j"] == pytest.approx(speed * e[1], rel=1e-12)
    assert after["theta_j"] == pytest.approx(0.0, abs=1e-14)


def test_coordinates_the_edge_couples_are_refused_by_name_and_why():
    model = flywheel_sled(2.0, 0.1, 0.3, 7e-3)
    for name in ("x_j", "y_j", "theta_j"):
        with pytest.raises(lg.ReductionError, match=rf"coordinate '{name}'.*cannot be reduced.*nonholonomic.*'edge'"
                                                   rf".*force acts along it.*not conserved.*theta_r"):
            routh.reduce(model, [name, "theta_r"])
    plain = lg.Model("sled", dim=2)
    plain.add("body", "b", "b", m=2.0, inertia=0.1)
    plain.add("free", "j", ("ground", "b"))
    plain.add("knife_edge", "edge", "b")
    with pytest.raises(lg.ReductionError, match=r"no ignorable coordinate.*constraints on velocities of 'edge' couple "
                                               r"every coordinate"):
        routh.reduce(plain)
    with pytest.raises(lg.ReductionError, match=r"'theta_j'.*'edge'.*no ignorable coordinate to reduce"):
        routh.reduce(plain, "theta_j")


@pytest.mark.slow
def test_the_rolling_disc_is_still_refused_naming_its_constraint():
    model = lg.Model("rolling disc", dim=3)
    model.add("disc", "d", "d", m=1.0, radius=0.1)
    model.add("free", "j", ("ground", "d"), sequence="zxz")
    model.add("rolling", "roll", "d", radius=0.1)
    model.add("gravity", "g", g=9.81)
    with pytest.raises(lg.ReductionError, match=r"no ignorable coordinate.*constraints on velocities of 'roll'"):
        routh.reduce(model)


@pytest.mark.slow
def test_the_reduced_model_checks_its_start_and_the_analyses_it_is_outside_refuse_it():
    from lagrangian.operating import equilibria

    red = routh.reduce(flywheel_sled(2.0, 0.1, 0.3, 7e-3))
    with pytest.raises(lg.ModelError, match=r"violate the constraints on velocities of 'edge'"):
        red.simulate(1.0, initial={"x_j": 0, "y_j": 0, "theta_j": 0.3}, velocity={"x_j": 1, "y_j": 0, "theta_j": 0},
                     momenta={"theta_r": 0.01})
    (rest,) = red.steady_motions()  # no force on it: the edge holds it at rest anywhere, turned any way
    assert all(str(rest.coordinates[n]) == f"{n}_0" for n in ("x_j", "y_j", "theta_j"))
    by_hand = routh.SteadyMotion(red, {"x_j": 0, "y_j": 0, "theta_j": 0}, {"theta_r": 0.01}, {"theta_r": 1.0})
    with pytest.raises(lg.ReductionError, match=r"nonholonomic: 'edge'.*stability\(\) linearizes on the constraints"):
        by_hand.perturbation()
    verdict = by_hand.stability()  # at rest, free: every push along the edge, every turn, persists
    assert verdict.verdict == "marginal" and np.max(np.abs(verdict.eigenvalues)) <= 1e-12
    with pytest.raises(lg.ModelError, match=r"nonholonomic: 'edge'"):
        equilibria(red, params={"C_theta_r": 0.01})


@settings(max_examples=5, deadline=None)
@given(m=decade(0.1, 10.0), I=decade(1e-3, 1.0), k=decade(1e-2, 10.0))
def test_a_sled_held_by_a_torsion_spring_turns_on_its_edge_at_the_closed_form_frequency(m, I, k):
    """The flywheel sled at rest, its edge at its centre of mass, a torsion spring k to the ground: on the edge it
    turns at ω² = k / I (the flywheel spins apart, its mass on the axis adds nothing), and slides along the edge
    freely: marginal, with the pair ±i√(k/I) beside zeros."""
    model = flywheel_sled(m, I, 0.3, 7e-3)
    model.add("rotational_spring", "k", ("ground", "b"), k=k)
    red = routh.reduce(model)
    motion = routh.SteadyMotion(red, {"x_j": 0, "y_j": 0, "theta_j": 0}, {"theta_r": 0.02}, {"theta_r": 1.0})
    verdict = motion.stability()
    lam = verdict.eigenvalues
    omega = math.sqrt(k / I)
    assert verdict.verdict == "marginal"
    assert np.sort(np.abs(lam))[-2:] == pytest.approx([omega, omega], rel=1e-9)
    assert np.max(np.abs(lam.real)) <= 1e-9 * omega


@settings(max_examples=5, deadline=None)
@given(m=decade(0.1, 10.0), I=decade(1e-3, 1.0), k=decade(1e-2, 10.0), kt=decade(1e-2, 10.0),
       y0=st.floats(-1.0, 1.0))
def test_springs_across_the_edge_leave_a_family_of_rests_the_edge_holds(m, I, k, kt, y0):
    """A spring from the ground to the centre (k) and a torsion spring (kt): at rest the spring's pull across the
    edge is held by the edge's force, so the sled rests anywhere on the line x = 0, square to it (θ = 0): a family in
    y.  About any of them it slides along the edge at ω² = k / (m + m_w) and turns at ω² = kt / I."""
    model = flywheel_sled(m, I, 0.3, 7e-3)
    model.add("spring", "ks", ("ground", "b"), k=k)
    model.add("rotational_spring", "kt", ("ground", "b"), k=kt)
    red = routh.reduce(model)
    (rest,) = red.steady_motions()
    assert float(rest.coordinates["x_j"]) == pytest.approx(0.0, abs=1e-12)
    assert float(rest.coordinates["theta_j"]) == pytest.approx(0.0, abs=1e-12)
    assert str(rest.coordinates["y_j"]) == "y_j_0"
    with pytest.raises(lg.ReductionError, match="symbolic in y_j_0"):
        rest.stability()
    verdict = rest.stability(values={"y_j_0": y0, "C_theta_r": 0.02})
    lam = verdict.eigenvalues
    assert verdict.verdict == "marginal"  # the family: a zero eigenvalue
    for omega in (math.sqrt(k / (m + 0.3)), math.sqrt(kt / I)):
        assert np.min(np.abs(lam - 1j * omega)) <= 1e-9 * omega
