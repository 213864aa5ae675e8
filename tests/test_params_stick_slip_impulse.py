"""A parameter given as a number and given another value in ``params=`` at run time reaches every part of a stick–slip
run and of an impact: the stuck rows and the friction limits of :func:`lagrangian.stick_slip.simulate`, the mass
matrix, gaps, constraints and kinetic energy of :func:`lagrangian.impulse.simulate_with_impacts`, :func:`impact` and
:func:`velocity_jump`.  Every model is built with one value and run with another; the expected values are the closed
forms for the value of the run.

Closed forms:

- a uniform disc (I = m r²/2) launched sliding at v₀ without spin skids at ṡ = −3μg until t* = v₀/3μg, then rolls
  at 2v₀/3 spinning at ω = −2v₀/(3r), the heat m v₀²/6 (only the spin depends on r);
- a block at rest pushed by F = c t against dry friction (static limit F_s, sliding force F_c) slips at t* = F_s/c,
  then m ẍ = c t − F_c: x = [c (t³ − t*³)/6 − c t*² (t − t*)/2 − F_c (t − t*)²/2] / m, the heat F_c x;
- in one dimension a mass m_a at u hits a mass m_b at rest with restitution e: v_a = (m_a − e m_b) u/(m_a + m_b),
  v_b = (1 + e) m_a u/(m_a + m_b);
- a rod (mass m, length 2L, I = m L²/3 about its centre) falling flat at speed v onto the ground at a point a from its
  centre takes the impulse J = (1 + e) v/(1/m + a²/I): its centre leaves at −v + J/m, spinning at J a/I.
"""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import lagrangian as lg
from lagrangian.errors import UnknownNameError
from lagrangian.impulse import Impulse, between, ground, impact, simulate_with_impacts, velocity_jump
from lagrangian.stick_slip import simulate

G = 9.81


def decade(lo, hi):
    return st.floats(math.log10(lo), math.log10(hi)).map(lambda e: float(f"{10 ** e:.3g}"))


# -- stick–slip --------------------------------------------------------------------------------------


def wheel(m, r, mu):
    """A uniform disc on a free planar joint, on y = 0, sliding against F_c = μ m g (stick–slip), gravity on."""
    model = lg.Model("wheel", dim=2)
    model.add("disc", "d", "d", m=m, radius=r)
    model.add("free", "j", ("ground", "d"))
    model.add("rolling", "roll", "d", F_c=mu * m * G, stick_slip=True)
    model.add("gravity", "g", g=G)
    return model


def check_wheel_run_on_another_radius(m, built, run, v0, mu):
    stop = v0 / (3 * mu * G)
    res = simulate(wheel(m, built, mu), 2 * stop, initial={"x_j": 0.0, "y_j": run, "theta_j": 0.0},
                   velocity={"x_j": v0, "y_j": 0.0, "theta_j": 0.0}, params={"radius_d": run}, points=21,
                   method="Radau", rtol=1e-12, atol=1e-14)
    assert [(s.component, s.before, s.after) for s in res.switches] == [("roll", "slip+", "stick")]
    assert res.switches[0].t == pytest.approx(stop, rel=1e-8)
    assert res.v["x_j"][-1] == pytest.approx(2 * v0 / 3, rel=1e-8)
    assert res.v["theta_j"][-1] == pytest.approx(-2 * v0 / (3 * run), rel=1e-8)
    assert np.max(np.abs(res["y_j"] - run)) < 1e-9 * run  # on the run's rim throughout
    assert res.heat[-1] == pytest.approx(m * v0**2 / 6, rel=1e-8)


@pytest.mark.slow
def test_a_wheel_built_with_one_radius_and_run_with_another_rolls_on_the_runs_radius():
    """Built with r = 0.07 m, run with r = 0.12 m: it sticks at v₀/3μg and spins at −2v₀/(3 · 0.12 m)."""
    check_wheel_run_on_another_radius(0.3, 0.07, 0.12, 1.5, 0.2)


@settings(max_examples=5, deadline=None)
@given(decade(1e-2, 1e2), decade(1e-2, 1), decade(1e-2, 1), decade(0.1, 10), decade(0.05, 1))
@pytest.mark.slow
def test_a_wheel_run_on_another_radius_sticks_at_the_closed_form_spin_over_decades(m, built, run, v0, mu):
    check_wheel_run_on_another_radius(m, built, run, v0, mu)


def ramp(m, c, F_c, F_s):
    """A block at rest on a rough floor (stick–slip) pushed by F = c t."""
    model = lg.Model("pushed block")
    model.add("mass", "m1", "p", m=m)
    model.add("force", "push", "p", F=c * lg.t)
    model.add("coulomb_friction", "f", ("ground", "p"), F_c=F_c, F_s=F_s, stick_slip=True)
    return model


def check_ramp_run_with_other_friction(m, c, F_c, F_s):
    """Built with F_c = 1 N, F_s = 1.5 N, run with ``F_c`` and ``F_s``: it slips at F_s/c, heat F_c x."""
    slips = F_s / c
    res = simulate(ramp(m, c, 1.0, 1.5), 2 * slips, initial={"x_p": 0.0}, velocity={"x_p": 0.0},
                   params={"F_c_f": F_c, "F_s_f": F_s}, points=21)
    assert [(s.before, s.after) for s in res.switches] == [("stick", "slip+")]
    assert res.switches[0].t == pytest.approx(slips, rel=1e-8)
    assert res.switches[0].force == pytest.approx(-F_s, rel=1e-8)  # the floor held the push back: −c t*
    t = res.t
    d = np.maximum(t - slips, 0.0)
    x = (c * (np.maximum(t, slips) ** 3 - slips**3) / 6 - c * slips**2 * d / 2 - F_c * d**2 / 2) / m
    scale = c * slips**3 / m
    assert np.max(np.abs(res["x_p"] - x)) < 1e-8 * scale
    assert np.max(np.abs(res.heat - F_c * x)) < 1e-8 * F_c * scale


def test_a_block_run_with_other_friction_forces_slips_at_the_runs_static_limit():
    """Built with F_c = 1 N, F_s = 1.5 N; run with 0.8 N and 2.4 N, pushed at 3 N/s: it slips at t = 0.8 s."""
    check_ramp_run_with_other_friction(0.3, 3.0, 0.8, 2.4)


@settings(max_examples=8, deadline=None)
@given(decade(1e-2, 1e2), decade(1e-1, 1e2), decade(1e-2, 1e2), st.floats(1.0, 3.0))
@pytest.mark.slow
def test_a_block_run_with_other_friction_forces_slips_and_heats_as_the_closed_form_over_decades(m, c, F_c, ratio):
    check_ramp_run_with_other_friction(m, c, F_c, F_c * ratio)


def test_a_block_whose_static_limit_the_run_raises_above_the_push_stays_stuck():
    """Built with F_s = 1.5 N, run with F_s = 4 N; pushed up to 3 N within the run: it never slips."""
    res = simulate(ramp(0.3, 3.0, 1.0, 1.5), 1.0, initial={"x_p": 0.0}, velocity={"x_p": 0.0},
                   params={"F_s_f": 4.0}, points=11)
    assert res.switches == []
    assert np.all(res["x_p"] == 0.0) and res.heat[-1] == 0.0


# -- impacts -----------------------------------------------------------------------------------------


def pair(m_a, m_b):
    model = lg.Model("pair")
    model.add("mass", "a", "A", m=m_a)
    model.add("mass", "b", "B", m=m_b)
    return model


def check_pair_run_with_other_masses(m_a, m_b, e, u):
    gap = 0.03
    res = simulate_with_impacts(pair(0.3, 0.3), 2 * gap / u, [between("A", "B", distance=0.07, e=e)],
                                initial={"x_A": 0.0, "x_B": 0.07 + gap}, velocity={"x_A": u, "x_B": 0.0},
                                params={"m_a": m_a, "m_b": m_b}, points=5)
    first = res.impacts[0]
    assert first.time == pytest.approx(gap / u, rel=1e-9)
    assert first.after["x_A"] == pytest.approx((m_a - e * m_b) * u / (m_a + m_b), rel=1e-9, abs=1e-12 * u)
    assert first.after["x_B"] == pytest.approx((1 + e) * m_a * u / (m_a + m_b), rel=1e-9)
    assert first.T_before == pytest.approx(m_a * u**2 / 2, rel=1e-9)
    lost = (1 - e**2) * m_a * m_b * u**2 / (2 * (m_a + m_b))
    assert first.energy_lost == pytest.approx(lost, rel=1e-9, abs=1e-12 * m_a * u**2)


def test_two_masses_built_equal_and_run_unequal_collide_as_the_runs_masses():
    """Built 0.3 kg each, run with 0.9 kg striking 0.3 kg at 1 m/s, e = 1: they leave at 0.5 m/s and 1.5 m/s."""
    check_pair_run_with_other_masses(0.9, 0.3, 1.0, 1.0)


@settings(max_examples=10, deadline=None)
@given(decade(1e-2, 1e2), decade(1e-2, 1e2), st.just(0.0) | st.floats(0.01, 1.0), decade(0.1, 10))
@pytest.mark.slow
def test_two_masses_run_with_other_masses_collide_as_the_closed_form_over_decades(m_a, m_b, e, u):
    """(A rebound slower than 10⁻⁶ of the approach is a resting contact, plastic: e is 0 or at least 0.01.)"""
    check_pair_run_with_other_masses(m_a, m_b, e, u)


def rod(L, a):
    """A free rod (length 2L, 0.3 kg) whose point P lies a from its centre, gravity on."""
    model = lg.Model("rod", dim=2)
    model.add("rod", "rod", "rod", m=0.3, length=2 * L, points={"P": (L + a, 0)})
    model.add("free", "fly", ("ground", "rod"), child_point=(L, 0))
    model.add("gravity", "g", g=G)
    return model


def rod_rebound(L, a, e, v):
    """The centre's vertical velocity and the spin after the rod, falling flat at v, hits the ground at P."""
    m = 0.3
    inertia = m * L**2 / 3
    J = (1 + e) * v / (1 / m + a**2 / inertia)
    return -v + J / m, J * a / inertia


def test_a_rod_whose_contact_point_the_run_moves_rebounds_as_the_runs_geometry():
    """Built with P 0.1 m from the centre of a 0.5 m rod; run with P 0.2 m out (points_rod_P_0 = L + 0.2): dropped
    flat from 0.07 m, P meets the ground at √(2h/g) and the rod leaves at the closed form for a = 0.2 m."""
    L, h, e = 0.25, 0.07, 0.5
    res = simulate_with_impacts(rod(L, 0.1), 1.2 * math.sqrt(2 * h / G), [ground("rod.P", e=e)],
                                initial={"x_fly": 0.0, "y_fly": h, "theta_fly": 0.0},
                                velocity={"x_fly": 0.0, "y_fly": 0.0, "theta_fly": 0.0},
                                params={"points_rod_P_0": L + 0.2}, points=5)
    first = res.impacts[0]
    assert first.time == pytest.approx(math.sqrt(2 * h / G), rel=1e-9)
    vy, w = rod_rebound(L, 0.2, e, math.sqrt(2 * G * h))
    assert first.after["y_fly"] == pytest.approx(vy, rel=1e-8)
    assert first.after["theta_fly"] == pytest.approx(w, rel=1e-8)


def check_impact_with_another_geometry(L, built, run, e, v):
    """impact() on the rod built with P at built·L from the centre and given run·L in params=: the closed form."""
    model = rod(L, built * L)
    hit = impact(model, [ground("rod.P", e=e)], at={"x_fly": 0, "y_fly": 0, "theta_fly": 0},
                 velocity={"y_fly": -v}, params={"points_rod_P_0": L + run * L})
    vy, w = rod_rebound(L, run * L, e, v)
    assert hit.after["y_fly"] == pytest.approx(vy, rel=1e-9, abs=1e-12 * v)
    assert hit.after["theta_fly"] == pytest.approx(w, rel=1e-9)
    assert hit.normal_after["ground(rod.P)"] == pytest.approx(e * v, rel=1e-9, abs=1e-12 * v)


def test_impact_takes_a_geometry_given_as_a_number_from_params():
    """A 0.5 m rod built with P 0.1 m from its centre, run with P 0.2 m out, hitting at 1.2 m/s with e = 0.6."""
    check_impact_with_another_geometry(0.25, 0.4, 0.8, 0.6, 1.2)


@settings(max_examples=10, deadline=None)
@given(decade(1e-2, 1), st.floats(0.05, 1.0), st.floats(0.05, 1.0), st.floats(0.0, 1.0), decade(0.1, 10))
@pytest.mark.slow
def test_impact_takes_a_geometry_from_params_as_the_closed_form_over_decades(L, built, run, e, v):
    check_impact_with_another_geometry(L, built, run, e, v)


def test_velocity_jump_takes_a_mass_given_as_a_number_from_params_exactly():
    """A 2 kg cart run as 3 kg, struck with 6 N·s from rest: it leaves at 2 m/s, with 6 J (exact numbers in, out)."""
    cart = lg.Model("cart")
    cart.add("mass", "M", "cart", m=2)
    jump = velocity_jump(cart, [Impulse("cart", 6)], params={"m_M": 3})
    assert jump.exact and jump.after == {"x_cart": 2} and jump.T_after == 6


def test_impact_refuses_an_unknown_parameter_naming_those_it_takes():
    cart = lg.Model("cart")
    cart.add("mass", "M", "cart", m=0.3)
    with pytest.raises(UnknownNameError, match=r"'m_MM'.*m_M"):
        impact(cart, [ground("cart")], at={"x_cart": 0}, velocity={"x_cart": -1}, params={"m_MM": 0.5})
