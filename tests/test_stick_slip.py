"""Dry friction that sticks and slips (``stick_slip=True``, run by :func:`lagrangian.stick_slip.simulate`): a block
thrown up a slope stops at the closed-form time and stays (tan α < μ_s) or slides back (tan α > μ_s), its heat
μ_k m g cos α times its path; a block dragged through a spring by a support moving at constant speed sticks and
slips with the closed-form period; bad input refused by name."""

import math

import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import brentq

import lagrangian as lg
from lagrangian.stick_slip import simulate

G = 9.81


def decade(lo, hi):
    return st.floats(math.log10(lo), math.log10(hi)).map(lambda e: float(f"{10 ** e:.3g}"))


def slope(m, alpha, mu_k, mu_s):
    """A block on a slide inclined at α (s down the slope), kinetic friction μ_k m g cos α, static μ_s m g cos α."""
    model = lg.Model("block on a slope", dim=2)
    model.add("body", "b", "b", m=m, inertia=1e-3)
    model.add("prismatic", "slide", ("ground", "b"), axis=(math.cos(alpha), -math.sin(alpha)))
    model.add("gravity", "g", g=G)
    N = m * G * math.cos(alpha)
    model.add("joint_friction", "f", coordinate="s_slide", F_c=mu_k * N, F_s=mu_s * N, stick_slip=True)
    return model


@settings(max_examples=10)
@given(decade(0.01, 100), st.floats(0.1, 1.2), st.floats(0.05, 0.6), st.floats(0.0, 0.5), decade(0.1, 10),
       st.booleans())
@pytest.mark.slow
def test_a_block_thrown_up_a_slope_stops_at_the_closed_form_time_then_stays_or_slides_back(m, alpha, mu_k, extra, v0,
                                                                                             stays):
    """Up the slope it decelerates at g (sin α + μ_k cos α) and stops at t* = v₀ / that; there it sticks for good
    when tan α ≤ μ_s, else slides back at g (sin α − μ_k cos α).  The switch is located to the event tolerance."""
    mu_s = mu_k + extra
    tan = math.tan(alpha)
    if stays:
        mu_s = max(mu_s, 1.05 * tan)
    elif tan <= 1.05 * mu_s:
        mu_s = min(mu_s, tan / 1.05)
        mu_k = min(mu_k, mu_s)
    up, down = G * (math.sin(alpha) + mu_k * math.cos(alpha)), G * (math.sin(alpha) - mu_k * math.cos(alpha))
    stop = v0 / up
    model = slope(m, alpha, mu_k, mu_s)
    res = simulate(model, 2 * stop, initial={"s_slide": 0.0}, velocity={"s_slide": -v0}, points=201, rtol=1e-12,
                   atol=1e-14)
    assert res.switches[0].t == pytest.approx(stop, rel=1e-10)
    assert (res.switches[0].before, res.switches[0].after) == ("slip-", "stick" if stays else "slip+")
    assert len(res.switches) == 1
    s, t = res["s_slide"], res.t
    top = -v0 * stop + up * stop**2 / 2
    want = np.where(t <= stop, -v0 * t + up * t**2 / 2, top + (0.0 if stays else down * (t - stop) ** 2 / 2))
    assert np.max(np.abs(s - want)) < 1e-9 * v0 * stop
    path = np.where(t <= stop, v0 * t - up * t**2 / 2, -top + (0.0 if stays else down * (t - stop) ** 2 / 2))
    assert np.max(np.abs(res.heat - mu_k * m * G * math.cos(alpha) * path)) < 1e-9 * m * v0**2


def dragged(m=0.4, k=25.0, V=0.05, F_s=1.2, F_c=0.8):
    """A block on a rough floor pulled through a spring whose far end moves at V (a classic stick–slip oscillator)."""
    model = lg.Model("dragged block")
    model.add("mass", "m1", "p", m=m)
    model.add("prescribed_motion", "drive", "d", position=V * lg.t)
    model.add("spring", "k1", ("d", "p"), k=k)
    model.add("coulomb_friction", "f", ("ground", "p"), F_c=F_c, F_s=F_s, stick_slip=True)
    return model


def test_a_block_dragged_through_a_spring_sticks_and_slips_with_the_closed_form_period():
    """Stuck until the spring's pull k(Vt − x) reaches F_s; sliding, x − (Vt − F_c/k) swings at ω = √(k/m) from
    −(F_s − F_c)/k with rate −V until ẋ = 0; stuck again until the pull is back at F_s."""
    m, k, V, F_s, F_c = 0.4, 25.0, 0.05, 1.2, 0.8
    w = math.sqrt(k / m)
    y0, yd0 = -(F_s - F_c) / k, -V

    def speed(tau):  # ẋ during a slip, τ after it starts
        return -y0 * w * math.sin(w * tau) + yd0 * math.cos(w * tau) + V

    slip = brentq(speed, 0.5 * math.pi / w, 2 * math.pi / w)  # ẋ > 0 from the start, back to zero within a swing
    y_end = y0 * math.cos(w * slip) + yd0 / w * math.sin(w * slip)
    stretch_end = F_c / k - y_end  # V t − x at the end of the slip
    stick = (F_s / k - stretch_end) / V
    first = F_s / (k * V)  # from rest with the spring slack: stuck until k V t = F_s
    res = simulate(dragged(m, k, V, F_s, F_c), first + 3 * (slip + stick) + 0.1, initial={"x_p": 0.0},
                   velocity={"x_p": 0.0}, points=501, rtol=1e-12, atol=1e-14)
    starts = [s.t for s in res.switches if s.after == "slip+"]
    stops = [s.t for s in res.switches if s.before == "slip+"]
    assert starts[0] == pytest.approx(first, rel=1e-10)
    assert np.diff(starts) == pytest.approx([slip + stick] * (len(starts) - 1), rel=1e-8)
    assert np.array(stops) - np.array(starts[: len(stops)]) == pytest.approx([slip] * len(stops), rel=1e-8)
    assert all(abs(s.force) == pytest.approx(F_s, rel=1e-9) for s in res.switches if s.after == "slip+")


def test_stick_slip_input_is_checked():
    model = lg.Model("block")
    model.add("mass", "m1", "p", m=0.5)
    model.add("coulomb_friction", "f", ("ground", "p"), F_c=1.0, stick_slip=True)
    with pytest.raises(lg.ModelError, match=r"sticks and slips \(stick_slip=True\): run the model with "
                                            r"lagrangian.stick_slip.simulate"):
        model.simulate(1.0, initial={"x_p": 0}, velocity={"x_p": 1.0})
    with pytest.raises(lg.ModelError, match="phase is one of"):
        model.add("coulomb_friction", "f2", ("ground", "p"), F_c=1.0, phase="sliding")
    # a static limit on a smooth friction would be silently unused: refused, for every kind that takes it
    for kind, where, extra in (("coulomb_friction", ("ground", "p"), {}), ("joint_friction", (), {"coordinate": "x_p"})):
        with pytest.raises(lg.ModelError, match=rf"{kind} 'f3': F_s .* is for stick_slip=True: add stick_slip=True"):
            model.add(kind, "f3", where, F_c=1.0, F_s=1.5, **extra)
    plain = lg.Model("plain")
    plain.add("mass", "m1", "p", m=0.5)
    plain.add("coulomb_friction", "f", ("ground", "p"), F_c=1.0)
    with pytest.raises(lg.ModelError, match="no component that sticks and slips"):
        simulate(plain, 1.0)
    # a block held by a force below the static limit never moves; above it, it slides at once
    held = lg.Model("held")
    held.add("mass", "m1", "p", m=0.5)
    held.add("force", "F", "p", F=sp.Float(0.9))
    held.add("coulomb_friction", "f", ("ground", "p"), F_c=0.7, F_s=1.0, stick_slip=True)
    res = simulate(held, 2.0, initial={"x_p": 0.0}, velocity={"x_p": 0.0}, points=11)
    assert res.switches == [] and np.all(res["x_p"] == 0.0) and np.all(res.heat == 0.0)


def test_a_symbolic_friction_force_given_in_params_runs_as_the_number_does():
    """F_c as a symbol (only the sliding phases use it) with its value in params: the same switches and heat as the
    number; without a value, or with a name no phase has, a clear refusal."""
    def pushed(F_c):
        model = lg.Model("pushed block")
        model.add("mass", "m1", "p", m=0.5)
        model.add("force", "push", "p", F=sp.Piecewise((2.0, lg.t < 1), (0.0, True)))
        model.add("coulomb_friction", "f", ("ground", "p"), F_c=F_c, F_s=1.0, stick_slip=True)
        return model

    run = {"initial": {"x_p": 0.0}, "velocity": {"x_p": 0.0}, "points": 31}
    number = simulate(pushed(0.8), 3.0, **run)
    symbol = simulate(pushed(sp.Symbol("Fc", positive=True)), 3.0, params={"Fc": 0.8}, **run)
    assert [s.after for s in symbol.switches] == [s.after for s in number.switches]
    assert [s.t for s in symbol.switches] == pytest.approx([s.t for s in number.switches], rel=1e-12)
    assert symbol.heat == pytest.approx(number.heat, rel=1e-12)
    with pytest.raises(lg.ModelError, match=r"F_c needs a value: give params=\{'Fc': ...\}"):
        simulate(pushed(sp.Symbol("Fc", positive=True)), 3.0, **run)
    with pytest.raises(lg.ModelError, match="unknown parameter 'bogus'"):
        simulate(pushed(sp.Symbol("Fc", positive=True)), 3.0, params={"Fc": 0.8, "bogus": 1.0}, **run)
