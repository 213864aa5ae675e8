"""A rolling contact that slides (``rolling`` with ``F_c``): a wheel launched skidding, with and without backspin,
sticks at the closed-form time and rolls on at the speed the angular momentum about the contact keeps, its heat the
kinetic energy lost; a wheel pushed ever harder skids when the friction rolling needs reaches F_s; a ball launched
sliding and spinning in space (smooth friction, small v_s) follows the closed-form path and its energy lost is the
friction's work; an upright disc in space skids as the planar wheel does; the smooth planar friction agrees with
stick–slip within O(v_s); bad input refused by name.

Closed forms (the ground's forces act at the contact, so the angular momentum about any fixed point of the ground
is kept): in the plane L = I ω − m r v, and rolling (v = −ω r) it is −(m r + I/r) v, so a disc (I = m r²/2)
launched at v₀ with spin ω₀ ends rolling at v = (v₀ − I ω₀/(m r)) / (1 + I/(m r²)); while it slides at the slip
rate s = v + ω r > 0 the force −F_c gives ṡ = −F_c (1/m + r²/I) = −3 μ g, so it sticks at t* = (v₀ + ω₀ r)/3μg.
In space a ball (I = 2/5 m r²) slides straight against its slip s⃗ = v⃗ + ω⃗ × (−r ẑ), whose direction stays
(v⃗̇ and the slip's rate are both along the force), at ṡ = −(7/2) μ g, and ends rolling at
v⃗ = 5/7 v⃗₀ + 2/7 r ω⃗₀ × ẑ."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import lagrangian as lg
from lagrangian.stick_slip import simulate

G = 9.81


def decade(lo, hi):
    return st.floats(math.log10(lo), math.log10(hi)).map(lambda e: float(f"{10 ** e:.3g}"))


def wheel(m, r, **friction):
    """A uniform disc on a free planar joint rolling (or sliding) on y = 0, gravity on."""
    model = lg.Model("wheel", dim=2)
    model.add("disc", "d", "d", m=m, radius=r)
    model.add("free", "j", ("ground", "d"))
    model.add("rolling", "roll", "d", radius=r, **friction)
    model.add("gravity", "g", g=G)
    return model


def launch(r, v0, w0=0.0):
    return {"initial": {"x_j": 0.0, "y_j": r, "theta_j": 0.0}, "velocity": {"x_j": v0, "y_j": 0.0, "theta_j": w0}}


def skid(m, r, mu, v0, w0, points=201):
    """A wheel launched at v₀ with spin ω₀ (ω₀ > 0: backspin), run with stick–slip over twice its sliding time."""
    stop = (v0 + w0 * r) / (3 * mu * G)
    model = wheel(m, r, F_c=mu * m * G, stick_slip=True)
    # Radau: its dense output locates the switch as exactly as DOP853's, and the phases are polynomials in t
    return stop, simulate(model, 2 * stop, **launch(r, v0, w0), points=points, method="Radau", rtol=1e-12,
                          atol=1e-14)


def check_skid(m, r, mu, v0, w0):
    I = m * r**2 / 2
    stop, res = skid(m, r, mu, v0, w0)
    final = (v0 - I * w0 / (m * r)) / (1 + I / (m * r**2))
    assert [(s.component, s.before, s.after) for s in res.switches] == [("roll", "slip+", "stick")]
    assert res.switches[0].t == pytest.approx(stop, rel=1e-8)
    assert abs(res.switches[0].force) < 1e-9 * mu * m * G  # rolling on at a steady speed takes no friction
    assert res.v["x_j"][-1] == pytest.approx(final, rel=1e-8, abs=1e-10 * v0)
    assert res.v["theta_j"][-1] == pytest.approx(-final / r, rel=1e-8, abs=1e-10 * v0 / r)
    t, x = res.t, res["x_j"]
    at_stop = v0 * stop - mu * G * stop**2 / 2
    want = np.where(t <= stop, v0 * t - mu * G * t**2 / 2, at_stop + final * (t - stop))
    assert np.max(np.abs(x - want)) < 1e-9 * (v0 + w0 * r) * stop
    lost = m * v0**2 / 2 + I * w0**2 / 2 - (m + I / r**2) * final**2 / 2
    assert res.heat[-1] == pytest.approx(lost, rel=1e-8)
    assert res.E[0] - res.E[-1] == pytest.approx(lost, rel=1e-8)


@settings(max_examples=6, deadline=None)
@given(decade(1e-2, 1e2), decade(1e-2, 1), decade(0.1, 10), decade(0.05, 1))
@pytest.mark.slow
def test_a_wheel_launched_skidding_rolls_on_at_two_thirds_after_the_closed_form_time(m, r, v0, mu):
    """No spin: it skids until t* = v₀/3μg, then rolls at 2v₀/3, having turned m v₀²/6 into heat."""
    check_skid(m, r, mu, v0, 0.0)


@settings(max_examples=4, deadline=None)
@given(decade(1e-2, 1e2), decade(1e-2, 1), decade(0.1, 10), decade(0.05, 1), st.floats(2.2, 10.0))
@pytest.mark.slow
def test_a_wheel_launched_with_backspin_comes_back_at_the_speed_its_angular_momentum_keeps(m, r, v0, mu, spin):
    """Backspin ω₀ = spin · v₀/r with spin > 2: I ω₀/(m r) > v₀, so it ends rolling back at
    (v₀ − I ω₀/(m r)) / (1 + I/(m r²)) = (2 v₀ − r ω₀)/3 < 0."""
    w0 = spin * v0 / r
    assert (2 * v0 - r * w0) / 3 < 0
    check_skid(m, r, mu, v0, w0)


def test_a_wheel_pushed_ever_harder_skids_when_the_friction_rolling_needs_reaches_the_static_limit():
    """Pushed at its centre by F = k t from rest it rolls (a = F/(m + I/r²)) on a friction F/3, until that reaches
    F_s at t_s = 3 F_s / k; then it skids: m v̇ = k t − F_c, and the slip grows."""
    m, r, k, F_c, F_s = 0.4, 0.15, 2.0, 0.5, 0.65
    model = wheel(m, r, F_c=F_c, F_s=F_s, stick_slip=True)
    model.add("force", "push", "d", F=[k * lg.t, 0])
    slips = 3 * F_s / k
    t_end = 2 * slips
    res = simulate(model, t_end, **launch(r, 0.0), points=101, method="Radau", rtol=1e-12, atol=1e-14)
    assert [(s.before, s.after) for s in res.switches] == [("stick", "slip+")]
    assert res.switches[0].t == pytest.approx(slips, rel=1e-8)
    assert abs(res.switches[0].force) == pytest.approx(F_s, rel=1e-8)
    v_slips = k * slips**2 / (2 * 1.5 * m)
    v_end = v_slips + (k * (t_end**2 - slips**2) / 2 - F_c * (t_end - slips)) / m
    assert res.v["x_j"][-1] == pytest.approx(v_end, rel=1e-9)
    w_end = -v_slips / r - 2 * F_c * (t_end - slips) / (m * r)  # I ω̇ = −F_c r, I = m r²/2
    assert res.v["theta_j"][-1] == pytest.approx(w_end, rel=1e-9)


def test_the_smooth_planar_friction_acts_on_the_slip_rate_as_coulomb_friction_does():
    """Sliding, m ẍ = −F_c tanh(s/v_s) and I θ̈ = −r F_c tanh(s/v_s) with s = ẋ + r θ̇, the height held; its power
    is −F_c s tanh(s/v_s).  Without F_c the wheel rolls as before: one constraint on velocities, no load."""
    m, r, F_c, v_s = 0.3, 0.07, 0.6, 1e-3
    model = wheel(m, r, F_c=F_c, v_s=v_s)
    assert len(model.eq.constraints) == 1 and len(model.eq.velocity_constraints) == 0
    x, xd, wd = 0.2, 0.4, -3.0
    s = xd + r * wd
    acc = model.numeric().rhs(0.0, np.array([x, r, 0.1, xd, 0.0, wd]))[3:]
    I = m * r**2 / 2
    assert acc == pytest.approx([-F_c * math.tanh(s / v_s) / m, 0.0, -r * F_c * math.tanh(s / v_s) / I], rel=1e-12,
                                abs=1e-12)
    power = model.load_power("roll")
    rates = {lg.rate("x_j"): xd, lg.rate("theta_j"): wd}
    got = float(power.subs(rates))
    assert got == pytest.approx(-F_c * s * math.tanh(s / v_s), rel=1e-12)
    plain = wheel(m, r)
    assert len(plain.eq.velocity_constraints) == 1 and plain.eq.load_shares == []


@pytest.mark.slow
def test_the_smooth_planar_friction_agrees_with_stick_slip_within_its_regularization():
    """With v_s small the smooth friction follows the stick–slip run: the same path while sliding, and after the
    switch, once the slip has decayed (at rate 3μg/v_s), the same rolling speed and a path behind by O(v_s²/μg)."""
    m, r, mu, v0, v_s = 0.3, 0.07, 0.2, 2.0, 1e-5
    stop, exact = skid(m, r, mu, v0, 0.0, points=401)
    smooth = wheel(m, r, F_c=mu * m * G, v_s=v_s).simulate(2 * stop, **launch(r, v0), t_eval=exact.t, method="Radau",
                                                            rtol=1e-11, atol=1e-13)
    after = exact.t > stop + 50 * v_s / (3 * mu * G)
    assert np.max(np.abs(smooth.v["x_j"][after] - exact.v["x_j"][after])) < v_s
    assert np.max(np.abs(smooth["x_j"] - exact["x_j"])) < 10 * v_s**2 / (mu * G) + 1e-10 * v0 * stop
    assert smooth.v["x_j"][-1] == pytest.approx(2 * v0 / 3, rel=1e-9)


@pytest.mark.slow
def test_a_ball_launched_sliding_and_spinning_in_space_follows_the_closed_form_and_loses_the_frictions_work():
    m, r, mu, v_s = 6.0, 0.11, 0.1, 1e-6  # a bowling ball; turning well within a radian (the x-y-z angles' reach)
    I = 2 * m * r**2 / 5
    v0, w0 = np.array([0.3, -0.1]), np.array([2.0, 1.5, 0.7])  # ω₀ about x, y and the vertical
    model = lg.Model("ball", dim=3)
    model.add("body", "b", "b", m=m, inertia=(I, I, I))
    model.add("free", "j", ("ground", "b"))  # x-y-z angles: at zero, their rates are ω's components
    model.add("rolling", "roll", "b", radius=r, shape="sphere", F_c=mu * m * G, v_s=v_s)
    model.add("gravity", "g", g=G)
    names = model.coordinate_names
    w_cross_z = np.array([w0[1], -w0[0]])  # ω⃗₀ × ẑ along the ground
    s0 = v0 - r * w_cross_z
    stop = np.linalg.norm(s0) / (3.5 * mu * G)
    res = model.simulate(3 * stop, initial={**dict.fromkeys(names, 0.0), "z_j": r},
                         velocity={**dict.fromkeys(names, 0.0), "x_j": v0[0], "y_j": v0[1], "alpha_j": w0[0],
                                   "beta_j": w0[1], "gamma_j": w0[2]},
                         points=2001, method="Radau", rtol=1e-10, atol=1e-12)
    final = 5 / 7 * v0 + 2 / 7 * r * w_cross_z
    t = res.t[:, None]
    a = -mu * G * s0 / np.linalg.norm(s0)
    want = np.where(t <= stop, v0 * t + a * t**2 / 2, v0 * stop + a * stop**2 / 2 + final * (t - stop))
    got = np.stack([res["x_j"], res["y_j"]], axis=1)
    # the regularization lags the switch by ~ v_s/(7μg/2) and shifts the path by O(v_s²/μg): far below 1e-9 m
    assert np.max(np.abs(got - want)) < 1e-9
    assert [res.v["x_j"][-1], res.v["y_j"][-1]] == pytest.approx(list(final), rel=1e-6)
    assert np.max(np.abs(res["z_j"] - r)) < 1e-12
    lost = m * v0 @ v0 / 2 + I * w0 @ w0 / 2 - (m + I / r**2) * final @ final / 2 - I * w0[2] ** 2 / 2
    assert res.E[0] - res.E[-1] == pytest.approx(lost, rel=1e-8)
    # the energy balance: what it lost is the friction's work (Simpson on the output times, error ~ 1/points²)
    work = res.cumulative(model.load_power("roll"))
    assert res.E[-1] - res.E[0] == pytest.approx(work[-1], rel=1e-6)
    assert np.max(np.abs(res.E - res.E[0] - work)) < 1e-6 * lost


@pytest.mark.slow
def test_an_upright_disc_in_space_launched_skidding_in_its_plane_moves_as_the_planar_wheel_does():
    """Smooth friction on a disc in space (its contact on the rim): launched upright along its plane without spin,
    it stays upright and in its plane, skids until v₀/3μg and rolls on at 2v₀/3, as in the plane."""
    m, r, mu, v0, v_s = 0.3, 0.07, 0.2, 2.0, 1e-6
    model = lg.Model("skidding disc", dim=3)
    model.add("disc", "d", "d", m=m, radius=r)
    model.add("free", "j", ("ground", "d"), sequence="zxz")  # θ = π/2: upright, its axis along −y
    model.add("rolling", "roll", "d", radius=r, F_c=mu * m * G, v_s=v_s)
    model.add("gravity", "g", g=G)
    names = model.coordinate_names
    stop = v0 / (3 * mu * G)
    res = model.simulate(2 * stop, initial={**dict.fromkeys(names, 0.0), "z_j": r, "theta_j": math.pi / 2},
                         velocity={**dict.fromkeys(names, 0.0), "x_j": v0}, points=401, method="Radau", rtol=1e-10,
                         atol=1e-12)
    t = res.t
    want = np.where(t <= stop, v0 * t - mu * G * t**2 / 2, v0 * stop - mu * G * stop**2 / 2 + 2 * v0 / 3 * (t - stop))
    assert np.max(np.abs(res["x_j"] - want)) < 1e-9 * v0 * stop  # the regularization: O(v_s²/μg)
    assert res.v["x_j"][-1] == pytest.approx(2 * v0 / 3, rel=1e-9)
    assert abs(res.v["psi_j"][-1]) * r == pytest.approx(2 * v0 / 3, rel=1e-9)
    assert np.max(np.abs(res["theta_j"] - math.pi / 2)) < 1e-12 and np.max(np.abs(res["y_j"])) < 1e-12 * v0 * stop
    assert res.E[0] - res.E[-1] == pytest.approx(m * v0**2 / 6, rel=1e-9)


def test_bad_friction_on_a_rolling_contact_is_refused_by_name():
    with pytest.raises(lg.ParameterError, match="component 'roll', parameter 'F_c': must be zero or positive"):
        wheel(0.3, 0.07, F_c=-1.0)
    with pytest.raises(lg.ModelError, match="rolling 'roll': phase is one of 'smooth', 'stick', 'slip\\+', 'slip-'"):
        wheel(0.3, 0.07, F_c=1.0, phase="sliding")
    for alone in ({"stick_slip": True}, {"F_s": 0.5}, {"phase": "stick"}):
        name = next(iter(alone))
        with pytest.raises(lg.ModelError, match=f"rolling 'roll': {name} is for a contact that slides: give F_c "
                                                f".*or drop {name} to roll without slipping"):
            wheel(0.3, 0.07, **alone)
    with pytest.raises(lg.ModelError, match=r"rolling 'roll' sticks and slips \(stick_slip=True\): run the model "
                                            r"with lagrangian.stick_slip.simulate"):
        wheel(0.3, 0.07, F_c=1.0, stick_slip=True).simulate(0.1, **launch(0.07, 1.0))
    space = lg.Model("ball", dim=3)
    space.add("body", "b", "b", m=0.1, inertia=(4e-5, 4e-5, 4e-5))
    space.add("free", "j", ("ground", "b"))
    space.add("rolling", "roll", "b", radius=0.03, shape="sphere", F_c=0.3, stick_slip=True)
    space.add("gravity", "g")
    refusal = (r"rolling 'roll': sticking and slipping \(stick_slip=True, phase\) is for a contact in the plane "
               r"\(dim=2\); in space drop stick_slip for the smooth friction \(F_c, v_s\)")
    with pytest.raises(lg.ModelError, match=refusal):
        space.eq  # noqa: B018
    with pytest.raises(lg.ModelError, match=refusal):
        simulate(space, 0.1)


def test_a_turntable_given_as_zero_in_the_plane_is_no_turntable():
    """A number given is a symbol standing for it while the model is derived: 0 given is still no turntable (the
    stick–slip driver gives every parameter again to each phase's model)."""
    model = wheel(0.3, 0.07, turntable=0)
    assert len(model.eq.velocity_constraints) == 1
    with pytest.raises(lg.ModelError, match="a turntable turns the ground of a model in space"):
        wheel(0.3, 0.07, turntable=0.5).eq  # noqa: B018
