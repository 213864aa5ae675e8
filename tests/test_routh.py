"""Routhian reduction, the Jacobi integral, steady motion and its stability.

Closed forms are the lecture notes' (eqs. 2.79–2.96) and textbook results derived by hand here:
the spherical pendulum (θ from the downward vertical, φ about it) and the central-force problem
(r, θ in the plane).
"""

from __future__ import annotations

import math
import re
import sys
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from sympy.core.function import AppliedUndef

import lagrangian as lg
from lagrangian import models, routh

m_, l_, g_, k_, C_ = sp.symbols("m l g k C", positive=True)
G = 9.81


def spherical(m=1.0, l=1.0, g=G) -> lg.Model:
    """φ = theta_turn about the vertical, θ = theta_tilt from the downward vertical."""
    return models.spherical_pendulum(m, l, g)


def central(m=1.0, k=1.0, n=2) -> lg.Model:
    """A particle on a massless arm turning about the origin (θ = theta_orbit) at distance s_radius."""
    model = lg.Model("central force", dim=2)
    model.add("link", "arm", "arm")
    model.add("revolute", "orbit", ("ground", "arm"), absolute=True)
    model.add("link", "bead", "bead")
    model.add("prismatic", "radius", ("arm", "bead"))
    model.add("mass", "planet", "bead", m=m)
    model.add("central_force", "sun", ("ground", "bead"), k=k, n=n)
    return model


@pytest.fixture(scope="module")
def sph_symbolic():
    return routh.reduce(spherical(m_, l_, g_))


@pytest.fixture(scope="module")
def sph():
    model = spherical()
    return model, routh.reduce(model)


@pytest.fixture(scope="module")
def kepler():
    model = central()
    return model, routh.reduce(model)


def same(a, b) -> bool:
    """Symbolic equality, matching symbols by name (the model adds assumptions) and floats as rationals."""
    def plain(e):
        e = sp.nsimplify(sp.sympify(e), rational=True)
        e = e.replace(lambda x: isinstance(x, AppliedUndef), lambda x: sp.Function(x.func.__name__)(*x.args))
        return e.xreplace({s: sp.Symbol(s.name) for s in e.free_symbols if s.name != "t"})

    return sp.simplify(plain(a) - plain(b)) == 0


def unabs(expr):
    """On r > 0: |r| = r, sign(r) = 1."""
    return expr.replace(sp.Abs, lambda x: x).replace(sp.sign, lambda x: sp.Integer(1))


def fn(name):
    return sp.Function(name)(lg.t)


# -- ignorable coordinates ----------------------------------------------------------------------------


def test_spherical_pendulum_has_phi_ignorable_and_says_why_theta_is_not(sph):
    model, _ = sph
    report = routh.ignorability(model)
    assert report["theta_turn"].ignorable and not report["theta_tilt"].ignorable
    assert "kinetic energy" in report["theta_tilt"].reason and "'bob'" in report["theta_tilt"].reason
    assert routh.ignorable(model) == ["theta_turn"]


def test_cyclic_in_T_but_driven_by_a_torque_or_damped_is_not_ignorable():
    model = spherical()
    model.add("body_torque", "motor", "yoke", tau=(0, 0, 0.3))
    report = routh.ignorability(model)["theta_turn"]
    assert not report.ignorable and "generalized force" in report.reason and "'motor'" in report.reason
    damped = lg.Model("damped turntable", dim=2)
    damped.add("disc", "plate", "plate", m=1, radius=0.2)
    damped.add("revolute", "hinge", ("ground", "plate"))
    damped.add("rotational_damper", "drag", ("ground", "plate"), c=0.1)
    report = routh.ignorability(damped)["theta_hinge"]
    assert not report.ignorable and "dissipation" in report.reason and "'drag'" in report.reason


def test_potential_and_first_order_coordinates_are_not_ignorable():
    model = lg.Model("oscillator")
    model.add("mass", "m", "p", m=1)
    model.add("spring", "k", ("ground", "p"), k=2)
    assert "potential energy" in routh.ignorability(model)["x_p"].reason
    rc = lg.Model("rc")
    rc.add("resistor", "R1", ("a", "0"), R=1)
    rc.add("capacitor", "C1", ("a", "0"), C=1)
    rc.add("inductor", "L1", ("a", "b"), L=1)
    rc.add("resistor", "R2", ("b", "0"), R=1)
    reasons = {n: r.reason for n, r in routh.ignorability(rc).items()}
    assert any("no inertia" in r for r in reasons.values()) or all("ignorable" not in r for r in reasons.values())
    with pytest.raises(lg.ReductionError, match="no ignorable coordinate"):
        routh.reduce(model)
    with pytest.raises(lg.ReductionError, match="'x_p' .* not ignorable: the potential energy"):
        routh.reduce(model, ["x_p"])
    with pytest.raises(lg.UnknownNameError, match="x_q"):
        routh.reduce(model, ["x_q"])


# -- the Routhian: the notes' results symbolically ---------------------------------------------------


@pytest.mark.slow
def test_spherical_pendulum_routhian_equation_and_effective_potential(sph_symbolic):
    red = sph_symbolic
    th = fn("theta_tilt")
    C = red.momenta["theta_turn"]
    # R = C²/(2 m l² sin²θ) − ½ m l² θ̇² − m g l cos θ   (notes, before 2.94)
    assert same(red.routhian, C**2 / (2 * m_ * l_**2 * sp.sin(th) ** 2) - m_ * l_**2 * th.diff(lg.t) ** 2 / 2 - m_ * g_ * l_ * sp.cos(th))
    # (2.95)
    assert same(red.effective_potential, C**2 / (2 * m_ * l_**2 * sp.sin(th) ** 2) - m_ * g_ * l_ * sp.cos(th))
    # (2.94): m l² θ̈ − C² cos θ / (m l² sin³ θ) + m g l sin θ = 0
    (eq,) = red.equations
    notes = m_ * l_**2 * th.diff(lg.t, 2) - C**2 * sp.cos(th) / (m_ * l_**2 * sp.sin(th) ** 3) + m_ * g_ * l_ * sp.sin(th)
    assert same(eq.lhs - eq.rhs, notes)
    # (2.93): φ̇ = C / (m l² sin² θ)
    assert same(red.rates["theta_turn"], C / (m_ * l_**2 * sp.sin(th) ** 2))
    assert red.gyroscopic == 0
    (singular,) = red.singularities
    assert same(singular, sp.sin(th))


@pytest.mark.slow
def test_spherical_pendulum_steady_motion_and_perturbation_equation(sph_symbolic):
    red = sph_symbolic
    motions = red.steady_motions(solve_for=["C_theta_turn"])
    assert len(motions) == 2  # both senses of rotation
    th0 = sp.Symbol("theta_tilt_0", real=True)
    for sm in motions:
        assert sm.coordinates == {"theta_tilt": th0}
        C = sm.momenta["theta_turn"]
        assert same(C**2 * sp.cos(th0), m_**2 * g_ * l_**3 * sp.sin(th0) ** 4)  # the condition before (2.96)
        assert same(l_ * sm.rates["theta_turn"] ** 2, g_ / sp.cos(th0))  # (2.96): l φ̇₀² = g sec θ₀
        pert = sm.perturbation()
        # s̈ + (g/l)(3 cos θ₀ + sec θ₀) s = 0
        assert same(pert.frequency_squared, g_ / l_ * (3 * sp.cos(th0) + 1 / sp.cos(th0)))
        (eq,) = pert.equations
        s = fn("s_theta_tilt")
        assert same(eq.lhs.coeff(s.diff(lg.t, 2)) * g_ / l_ * (3 * sp.cos(th0) + 1 / sp.cos(th0)), eq.lhs.coeff(s))


def test_central_force_routhian_and_equation_2_89():
    red = routh.reduce(central(m_, k_))
    r = fn("s_radius")
    C = red.momenta["theta_orbit"]
    # R = −½ m ṙ² + C²/(2 m r²) + V(r), V = −k/r
    assert same(unabs(red.routhian), -m_ * r.diff(lg.t) ** 2 / 2 + C**2 / (2 * m_ * r**2) - k_ / r)
    (eq,) = red.equations
    # (2.89): m r̈ − C²/(m r³) + V'(r) = 0
    assert same(unabs(eq.lhs - eq.rhs), m_ * r.diff(lg.t, 2) - C**2 / (m_ * r**3) + k_ / r**2)
    circular = [sm for sm in red.steady_motions() if sp.sympify(sm.coordinates["s_radius"]).could_extract_minus_sign() is False]
    (sm,) = circular
    r0 = C**2 / (m_ * k_)
    assert same(sm.coordinates["s_radius"], r0)
    # radial oscillation about the circular orbit: ω_r² = V_eff''(r0)/m = k/(m r0³) (= θ̇₀²: the orbit closes)
    assert same(sm.perturbation().frequency_squared, k_ / (m_ * r0**3))
    assert same(sm.rates["theta_orbit"] ** 2, k_ / (m_ * r0**3))
    # symbolic reconstruction along the circular orbit: θ = θ₀ + C t / (m r0²)
    theta = red.quadrature(sm)["theta_orbit"]
    assert same(theta, sp.Symbol("theta_orbit_0", real=True) + C * lg.t / (m_ * r0**2))


def test_two_ignorable_coordinates_reduce_together():
    """A free particle in space under gravity on two sliders (x, y) and height z: x and y are ignorable."""
    model = lg.Model("projectile", dim=3)
    model.add("mass", "ball", "ball", m=2)
    model.add("gravity", "g", g=G)
    assert routh.ignorable(model) == ["x_ball", "y_ball"]
    red = routh.reduce(model)
    z = fn("z_ball")
    Cx, Cy = red.momenta["x_ball"], red.momenta["y_ball"]
    assert same(red.effective_potential, (Cx**2 + Cy**2) / 4 + 2 * G * z)
    assert same(red.rates["x_ball"], Cx / 2) and same(red.rates["y_ball"], Cy / 2)
    res = red.simulate(1.0, initial={"z_ball": 0, "x_ball": 1, "y_ball": -1}, velocity={"z_ball": 3, "x_ball": 0.5, "y_ball": 2},
                       reconstruct=True, points=11)
    assert np.allclose(res["x_ball"], 1 + 0.5 * res.t, atol=1e-10)
    assert np.allclose(res["y_ball"], -1 + 2 * res.t, atol=1e-10)
    assert np.allclose(res["z_ball"], 3 * res.t - G * res.t**2 / 2, atol=1e-10)


# -- numbers against closed forms ----------------------------------------------------------------------


def crossings(t, x, level):
    d = x - level
    i = np.flatnonzero((d[:-1] < 0) & (d[1:] >= 0))
    return t[i] - d[i] * (t[i + 1] - t[i]) / (d[i + 1] - d[i])


def test_kepler_period_from_the_reduced_model(kepler):
    _, red = kepler
    m, k = 1.0, 1.0
    r0, v0, C = 1.0, 0.2, 0.9  # start at r = 1 moving outwards, angular momentum 0.9
    E = 0.5 * m * v0**2 + C**2 / (2 * m * r0**2) - k / r0
    a = -k / (2 * E)
    period = 2 * math.pi * math.sqrt(m * a**3 / k)
    res = red.simulate(4 * period, initial={"s_radius": r0}, velocity={"s_radius": v0}, momenta={"theta_orbit": C},
                       points=40001, rtol=1e-12, atol=1e-13)
    # radial period from successive maxima of r (crossings of ṙ = 0 downwards)
    rdot = res.v["s_radius"]
    ups = crossings(res.t, -rdot, 0.0)
    assert len(ups) >= 3
    assert np.mean(np.diff(ups)) == pytest.approx(period, rel=1e-8)
    # the reduced energy (2.90) is the total energy
    assert np.max(np.abs(res.E - E)) < 1e-10


def test_radial_frequency_about_a_circular_orbit(kepler):
    _, red = kepler
    C = 1.2
    (sm,) = [s for s in red.steady_motions(momenta={"theta_orbit": C}) if float(s.coordinates["s_radius"]) > 0]
    r0 = C**2  # m = k = 1
    assert float(sm.coordinates["s_radius"]) == pytest.approx(r0, rel=1e-14)
    st = sm.stability()
    assert st.verdict == "stable"
    omega = math.sqrt(1 / r0**3)
    assert st.frequencies[0] == pytest.approx(omega, rel=1e-12)
    res = red.simulate(30, initial={"s_radius": r0 + 1e-4}, velocity={"s_radius": 0}, momenta={"theta_orbit": C},
                       points=30001, rtol=1e-12, atol=1e-14)
    ups = crossings(res.t, res["s_radius"], r0)
    assert 2 * math.pi / np.mean(np.diff(ups)) == pytest.approx(omega, rel=1e-4)


def test_spherical_pendulum_oscillates_about_steady_motion_at_the_predicted_frequency(sph):
    model, red = sph
    th0 = 0.7
    rate = math.sqrt(G / math.cos(th0))  # (2.96) with l = 1
    C = math.sin(th0) ** 2 * rate
    (sm,) = [s for s in red.steady_motions(momenta={"theta_turn": C}) if float(s.coordinates["theta_tilt"]) > 0]
    assert float(sm.coordinates["theta_tilt"]) == pytest.approx(th0, abs=1e-12)
    st = sm.stability()
    predicted = math.sqrt(G * (3 * math.cos(th0) + 1 / math.cos(th0)))
    assert st.verdict == "stable" and st.frequencies[0] == pytest.approx(predicted, rel=1e-12)
    # a full-model simulation started slightly off the steady motion
    res = model.simulate(20, initial={"theta_tilt": th0 + 1e-4, "theta_turn": 0}, velocity={"theta_tilt": 0, "theta_turn": rate},
                         points=20001, rtol=1e-12, atol=1e-14)
    mean = np.mean(res["theta_tilt"])
    ups = crossings(res.t, res["theta_tilt"], mean)
    assert 2 * math.pi / np.mean(np.diff(ups)) == pytest.approx(predicted, rel=1e-4)


# -- reduced + reconstructed = full ---------------------------------------------------------------------


@pytest.mark.parametrize("case", ["kepler", "spherical"])
def test_reduced_plus_reconstructed_equals_full(case, kepler, sph):
    if case == "kepler":
        model, red = kepler
        initial = {"theta_orbit": 0.3, "s_radius": 1.0}
        velocity = {"theta_orbit": 0.8, "s_radius": 0.15}
    else:
        model, red = sph
        initial = {"theta_turn": 0.2, "theta_tilt": 0.9}
        velocity = {"theta_turn": 1.7, "theta_tilt": -0.4}
    tight = {"rtol": 1e-12, "atol": 1e-13, "points": 2001}
    full = model.simulate(10, initial=initial, velocity=velocity, **tight)
    reduced = red.simulate(10, initial=initial, velocity=velocity, reconstruct=True, **tight)
    assert set(reduced.names) == set(full.names)
    for name in full.names:
        assert np.max(np.abs(reduced[name] - full[name])) < 1e-8, name
    assert np.max(np.abs(reduced.v[red.coordinate_names[0]] - full.v[red.coordinate_names[0]])) < 1e-8


def test_momenta_from_the_full_state_equal_the_conserved_momentum(sph):
    model, red = sph
    th = 0.9
    assert red.momenta_from({"theta_tilt": th}, {"theta_turn": 1.7})["theta_turn"] == pytest.approx(math.sin(th) ** 2 * 1.7, rel=1e-14)
    with pytest.raises(lg.ReductionError, match="both a velocity and a momentum"):
        red.simulate(1, initial={"theta_tilt": th}, velocity={"theta_turn": 1.0}, momenta={"theta_turn": 1.0})
    with pytest.raises(lg.ReductionError, match="has no value"):
        red.simulate(1, initial={"theta_tilt": th})
    with pytest.raises(lg.UnknownNameError, match="'C_theta_trun'"):
        red.simulate(1, initial={"theta_tilt": th}, params={"C_theta_turn": 1.0, "C_theta_trun": 1.0})
    with pytest.raises(lg.ModelError, match="derived from model"):
        red.add("mass", "extra", "p", m=1)


# -- the Jacobi integral ----------------------------------------------------------------------------------


def cart(speed=None, M=2.0, m=0.5, L=0.7):
    model = lg.Model("cart", dim=2)
    model.add("body", "cart", "cart", m=M, inertia=0.1)
    model.add("link", "arm", "arm", points={"bob": (L, 0)})
    model.add("prismatic", "rail", ("ground", "cart"), **({} if speed is None else {"displacement": speed * lg.t}))
    model.add("revolute", "pivot", ("cart", "arm"), absolute=True)
    model.add("mass", "bob", "arm.bob", m=m)
    model.add("gravity", "g", g=G)
    return model


@pytest.mark.slow
def test_cart_at_constant_speed_conserves_the_jacobi_integral_but_not_the_energy():
    M, m, L, v = 2.0, 0.5, 0.7, 1.5
    model = cart(v, M, m, L)
    h = routh.jacobi_integral(model)
    assert h.conserved and not h.energy_conserved
    th = fn("theta_pivot")
    # by hand: T = ½(M + m)v² − m v L sin θ θ̇ + ½ m L² θ̇²  ⇒  h − (T + V) = −T₁ − 2T₀
    assert same(h.difference, m * v * L * sp.sin(th) * th.diff(lg.t) - (M + m) * v**2)
    res = model.simulate(10, initial={"theta_pivot": -1.0}, velocity={"theta_pivot": 0.0}, rtol=1e-12, atol=1e-13)
    assert h.drift(res) < 1e-9
    assert res.energy_drift() > 1e-2
    free = routh.jacobi_integral(cart(None))
    assert free.conserved and free.energy_conserved


def test_jacobi_integral_not_conserved_with_dissipation_forcing_or_time_dependence():
    model = lg.Model("damped")
    model.add("mass", "m", "p", m=1)
    model.add("spring", "k", ("ground", "p"), k=1)
    model.add("damper", "c", ("ground", "p"), c=0.2)
    h = routh.jacobi_integral(model)
    assert not h.conserved and "dissipates" in h.reasons[0] and "'c'" in h.reasons[0]
    res = model.simulate(5, initial={"x_p": 1}, velocity={"x_p": 0})
    assert h.drift(res) > 0.1  # it decays, as it should
    forced = lg.Model("forced")
    forced.add("mass", "m", "p", m=1)
    forced.add("force", "F", "p", F=sp.sin(lg.t))
    h = routh.jacobi_integral(forced)
    assert not h.conserved and "'F'" in " ".join(h.reasons)
    shaken = lg.Model("shaken")
    shaken.add("prescribed_motion", "drive", "s", position=sp.sin(2 * lg.t))
    shaken.add("spring", "k", ("s", "p"), k=1)
    shaken.add("mass", "m", "p", m=1)
    h = routh.jacobi_integral(shaken)
    assert not h.conserved and "explicitly on time" in h.reasons[0]


# -- where methods fail ------------------------------------------------------------------------------------


def test_spherical_pendulum_pole_infinite_barrier_and_zero_momentum_passage(sph):
    model, red = sph
    with pytest.raises(lg.ReductionError, match=r"sin\(theta_tilt\(t\)\) = 0.*infinite"):
        red.simulate(1, initial={"theta_tilt": 0.0}, velocity={"theta_tilt": 1.0}, momenta={"theta_turn": 0.5})
    # C ≠ 0: the barrier keeps θ away from the pole
    res = red.simulate(1, initial={"theta_tilt": 0.3}, velocity={"theta_tilt": -3.0}, momenta={"theta_turn": 0.05},
                       rtol=1e-11, atol=1e-13, points=100001)
    assert np.all(np.isfinite(res["theta_tilt"])) and np.min(res["theta_tilt"]) > 0
    # by hand: closest approach where ½θ̇² + V_eff = E, V_eff = C²/(2 sin²θ) − g cos θ
    E = 0.5 * 9.0 + 0.05**2 / (2 * math.sin(0.3) ** 2) - G * math.cos(0.3)
    from scipy.optimize import brentq
    turn = brentq(lambda x: 0.05**2 / (2 * math.sin(x) ** 2) - G * math.cos(x) - E, 1e-6, 0.3)
    assert np.min(res["theta_tilt"]) == pytest.approx(turn, rel=1e-3)
    # C = 0: still valid — the reduced model swings through the pole (θ changes sign) as a plane pendulum
    res = red.simulate(3, initial={"theta_tilt": 0.5, "theta_turn": 0.0}, velocity={"theta_tilt": 0.0}, momenta={"theta_turn": 0.0},
                       reconstruct=True, rtol=1e-11, atol=1e-13)
    assert np.min(res["theta_tilt"]) < -0.49
    from scipy.integrate import solve_ivp
    plane = solve_ivp(lambda _, y: [y[1], -G * math.sin(y[0])], (0, 3), [0.5, 0.0], t_eval=res.t, rtol=1e-12, atol=1e-13)
    assert np.max(np.abs(res["theta_tilt"] - plane.y[0])) < 1e-8
    assert np.all(res["theta_turn"] == 0.0)
    assert np.max(np.abs(res.E - res.E[0])) < 1e-9


def test_unsolvable_momentum_equations_are_diagnosed():
    """Two sliders in series along x carry one mass: only ẋ₁ + ẋ₂ has inertia."""
    model = lg.Model("two sliders", dim=2)
    model.add("link", "a", "a")
    model.add("prismatic", "p1", ("ground", "a"))
    model.add("link", "b", "b")
    model.add("prismatic", "p2", ("a", "b"))
    model.add("mass", "m", "b", m=1)
    model.add("prismatic", "lift", ("ground", "c"), axis=(0, 1))
    model.add("body", "c", "c", m=1, inertia=1)
    model.add("spring", "k", ("ground", "c"), k=1)
    with pytest.raises(lg.ReductionError, match="p_s_p1 and p_s_p2 are not independent"):
        routh.reduce(model, ["s_p1", "s_p2"])


@pytest.mark.slow
def test_steady_motion_at_a_bifurcation_is_marginal_and_stability_changes_across_it():
    """Central force k/rⁿ: circular orbits are stable for n < 3, unstable for n > 3, and at n = 3 they exist only
    for C² = m k, at every radius — a zero eigenvalue the linearization cannot decide."""
    red = routh.reduce(central(n=3))
    assert red.steady_motions(momenta={"theta_orbit": 1.2}, search={"s_radius": (0.1, 10)}) == []
    family = red.steady_motions(solve_for=["C_theta_orbit"])
    assert sorted(float(sm.momenta["theta_orbit"]) for sm in family) == [-1.0, 1.0]
    st = family[0].stability({"s_radius_0": 1.5})
    assert st.verdict == "marginal" and "zero eigenvalue" in st.reason
    for n, verdict in ((2.5, "stable"), (3.5, "unstable")):
        red = routh.reduce(central(n=n))
        (sm,) = red.steady_motions(momenta={"theta_orbit": 1.0}, search={"s_radius": (0.1, 10)})
        st = sm.stability()
        assert st.verdict == verdict, (n, st)
        # V_eff'' ∝ (3 − n): the curvature agrees
        assert (st.curvature[0] > 0) == (n < 3)


def test_numeric_steady_motions_find_every_branch(sph):
    _, red = sph
    C = 0.4
    found = sorted(float(s.coordinates["theta_tilt"]) for s in red.steady_motions(momenta={"theta_turn": C}))
    # by hand: C² cos θ = g sin⁴ θ (l = m = 1) has one root in (0, π/2) and its mirror image
    from scipy.optimize import brentq
    root = brentq(lambda x: C**2 * math.cos(x) - G * math.sin(x) ** 4, 1e-3, math.pi / 2)
    assert found == pytest.approx([-root, root], abs=1e-12)


def test_stability_needs_values_for_symbolic_steady_motions(sph_symbolic):
    (sm, _) = sph_symbolic.steady_motions(solve_for=["C_theta_turn"])
    with pytest.raises(lg.ReductionError, match="give values"):
        sm.stability()
    st = sm.stability({"theta_tilt_0": 0.7, "m": 1, "l": 1, "g": G})
    assert st.frequencies[0] == pytest.approx(math.sqrt(G * (3 * math.cos(0.7) + 1 / math.cos(0.7))), rel=1e-12)
    with pytest.raises(lg.UnknownNameError, match="theta_tilt_9"):
        sm.stability({"theta_tilt_9": 1})


# -- the example scripts ------------------------------------------------------------------------------------



@pytest.fixture
def scripts(example):
    return example


def output(scripts, name: str) -> str:
    out, where = scripts(f"{name}.py", "--out", f"{{dir}}/{name}.png")
    assert (where / f"{name}.png").read_bytes().startswith(b"\x89PNG")
    return out


@pytest.mark.slow
def test_example_kepler(scripts):
    out = output(scripts, "kepler")
    lin, closed, sim = map(float, re.search(r"radial frequency: linear (\S+), closed form .* = (\S+), simulated (\S+) rad/s", out).groups())
    assert closed == pytest.approx(1 / 1.2**3, rel=1e-9) and lin == pytest.approx(closed, rel=1e-9)
    assert sim == pytest.approx(closed, rel=1e-5)
    radial, kepler_period = map(float, re.search(r"radial period (\S+) s, Kepler 2π√\(m a³/k\) = (\S+) s", out).groups())
    E = 0.5 * (0.3**2 + 0.75**2) - 1
    assert kepler_period == pytest.approx(2 * math.pi * (-1 / (2 * E)) ** 1.5, rel=1e-9)
    assert radial == pytest.approx(kepler_period, rel=1e-8)
    assert float(re.search(r"reduced \+ reconstructed θ vs full model: max difference (\S+)", out).group(1)) < 1e-8
    assert "k/r^3.0: circular orbits only for C = [-1.0, 1.0], at any radius: marginal" in out
    assert "k/r^2.5: circular orbit r0 = 1.000000: stable" in out and "k/r^3.5: circular orbit r0 = 1.000000: unstable" in out


@pytest.mark.slow
def test_example_spherical_steady(scripts):
    out = output(scripts, "spherical_steady")
    assert "equals (g/l)(3 cos θ₀ + sec θ₀): True" in out
    assert "l φ̇₀² = g/cos(theta_tilt_0)" in out
    lin, closed, sim = map(float, re.search(r"linear (\S+), closed form (\S+), full-model simulation (\S+) rad/s", out).groups())
    assert closed == pytest.approx(math.sqrt(G * (3 * math.cos(0.7) + 1 / math.cos(0.7))), rel=1e-8)
    assert lin == pytest.approx(closed, rel=1e-8) and sim == pytest.approx(closed, rel=1e-4)
    assert "ReductionError: the initial state" in out
    turn, through = map(float, re.search(r"θ turns back at (\S+) rad .* θ reaches (\S+) rad through the pole", out).groups())
    assert 0 < turn < 0.05 and through < -1.0


@pytest.mark.slow
def test_steady_motions_solved_symbolically_keep_to_the_search_ranges():
    """Kepler (k/r²) circular orbits r₀ = C²/(m k), solved exactly: the radius coordinate s may be negative
    (the bead across the axis), so s = ±r₀; search= keeps those in its range."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "examples"))
    from kepler import central

    m, k, C = 0.599, 0.0706, 0.5
    r0 = C**2 / (m * k)
    red = routh.reduce(central(m, k, 2))
    both = sorted(float(s.coordinates["s_radius"]) for s in red.steady_motions(momenta={"theta_orbit": C}))
    assert both == pytest.approx([-r0, r0], rel=1e-12)
    (one,) = red.steady_motions(momenta={"theta_orbit": C}, search={"s_radius": (r0 / 30, 30 * r0)})
    assert float(one.coordinates["s_radius"]) == pytest.approx(r0, rel=1e-12)
    with pytest.raises(lg.UnknownNameError, match="theta_orbit"):
        red.steady_motions(momenta={"theta_orbit": C}, search={"theta_orbit": (0, 1)})
