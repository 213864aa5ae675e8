"""Events: crossing times against closed forms to 1e-10, terminal stops, actions at a wall, clear refusals."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.special import ellipk

import lagrangian as lg

ADAPTIVE = ["RK45", "DOP853", "Radau", "LSODA", "dopri5_c"]
FIXED = ["rk4", "verlet", "rk4_c"]


def drop(m=0.3, g=9.81):
    model = lg.Model("drop")
    model.add("mass", "m", "p", m=m)
    model.add("gravity", "g", g=g)
    return model


def pendulum(L, m=0.3, g=9.81):
    model = lg.Model("pendulum", dim=2)
    model.add("link", "arm", "arm", points={"bob": (L, 0)})
    model.add("revolute", "pin", ("ground", "arm"), absolute=True)
    model.add("mass", "bob", "arm.bob", m=m)
    model.add("gravity", "g", g=g)
    return model


def tight(method, h=1e-3):
    return {"step": h} if method in FIXED else {"rtol": 1e-12, "atol": 1e-14}


@pytest.mark.parametrize("method", ADAPTIVE + FIXED)
def test_a_falling_mass_stops_at_the_floor_at_the_closed_form_time(method):
    height, g = 1.37, 9.81
    res = drop(g=g).simulate(2.0, initial={"x_p": height}, velocity={"x_p": 0.0}, method=method,
                             events=[lg.Event("x_p", direction=-1, terminal=True, name="floor")], **tight(method))
    want = math.sqrt(2 * height / g)
    [hit] = res.events
    assert hit.name == "floor" and abs(hit.t - want) < 1e-10
    assert res.t[-1] == hit.t and abs(res["x_p"][-1]) < 1e-9
    assert abs(hit.v["x_p"] + g * want) < 1e-8  # v = −g t at the floor
    assert np.all(np.diff(res.t) > 0) and res.t[-2] < hit.t


@pytest.mark.parametrize("method", ["DOP853", "RK45", "rk4", "verlet", "dopri5_c", "rk4_c", "verlet_c"])
@pytest.mark.slow
def test_a_pendulum_passes_the_vertical_after_a_quarter_of_its_elliptic_period(method):
    """From rest at α from the vertical: T/4 = K(sin²(α/2)) / √(g/L) (complete elliptic integral)."""
    L, g, alpha = 0.7, 9.81, 1.1
    model = pendulum(L, g=g)
    # the methods' own errors below 1e-10: rk4's (ω h)⁴, Störmer–Verlet's (ω h)²
    step = {"rk4": {"step": 2e-4}, "verlet": {"step": 2e-5}}.get(method.removesuffix("_c"), {"rtol": 1e-12, "atol": 1e-14})
    res = model.simulate(0.6, initial={"theta_pin": -math.pi / 2 + alpha}, velocity={"theta_pin": 0.0},
                         method=method, events=[lg.Event("theta_pin + pi/2", direction=-1, terminal=True)], **step)
    want = ellipk(math.sin(alpha / 2) ** 2) / math.sqrt(g / L)
    assert len(res.events) == 1 and abs(res.events[0].t - want) < 1e-10


@settings(max_examples=10, deadline=None)
@given(m=st.floats(0.01, 100.0), k=st.floats(0.1, 1e4), A=st.floats(1e-3, 10.0),
       method=st.sampled_from(["DOP853", "RK45", "rk4"]))
@pytest.mark.slow
def test_every_zero_crossing_of_an_oscillator_is_found(m, k, A, method):
    """x = A cos ωt crosses zero at (j + ½) π/ω: a non-terminal event records each, and the run goes on."""
    m, k, A = (float(f"{x:.3g}") for x in (m, k, A))
    w = math.sqrt(k / m)
    model = lg.Model("oscillator")
    model.add("mass", "m", "p", m=m)
    model.add("spring", "k", ("ground", "p"), k=k)
    t_end = 4.2 * math.pi / w
    opts = {"step": 1e-3 / w} if method == "rk4" else {"rtol": 1e-12, "atol": 1e-14 * A}
    res = model.simulate(t_end, initial={"x_p": A}, velocity={"x_p": 0.0}, method=method,
                         events=[lg.Event("x_p", name="zero")], **opts)
    want = [(j + 0.5) * math.pi / w for j in range(4)]
    got = [e.t for e in res.events]
    assert len(got) == 4
    assert np.allclose(got, want, rtol=0, atol=1e-10 * max(1.0, t_end))
    assert res.t[-1] == pytest.approx(t_end) and np.allclose(res["x_p"], A * np.cos(w * res.t), rtol=0, atol=1e-7 * A)


@pytest.mark.parametrize("compiled, sibling, options", [("dopri5_c", "RK45", {"rtol": 1e-10, "atol": 1e-12}),
                                                        ("rk4_c", "rk4", {"step": 3e-3}),
                                                        ("verlet_c", "verlet", {"step": 3e-3})])
def test_compiled_loops_stop_for_events_in_c_with_the_steps_of_their_python_sibling(compiled, sibling, options):
    """dopri5_c is scipy's RK45 (pair, error norm, step control, dense output) with the loop in C; rk4_c and
    verlet_c are rk4 and verlet.  With events they step in C one step at a time: the same steps and the same
    crossings as the Python methods, with no note of a fallback."""
    model = pendulum(0.45, m=0.7)
    events = [lg.Event("theta_pin + pi/2", name="vertical"), lg.Event(lambda t, q, v: v["theta_pin"], direction=-1, name="turn")]
    runs = {}
    for method in (compiled, sibling):
        runs[method] = model.simulate(3.0, initial={"theta_pin": -0.4}, velocity={"theta_pin": 0.0}, method=method,
                                      events=events, points=31, compiled="auto", **options)
    c, py = runs[compiled], runs[sibling]
    if not any("sibling" in note or "no C compiler" in note for note in c.notes):  # a machine with a C compiler
        assert not any("sibling" in note for note in c.notes)
        if compiled == "dopri5_c":  # the same steps, rejected ones included
            assert c.nfev == py.nfev
    assert [e.name for e in c.events] == [e.name for e in py.events] and len(c.events) >= 6
    np.testing.assert_allclose([e.t for e in c.events], [e.t for e in py.events], rtol=0, atol=1e-12)
    np.testing.assert_allclose(c["theta_pin"], py["theta_pin"], rtol=0, atol=1e-11)


@pytest.mark.parametrize("method", ["DOP853", "rk4", "dopri5_c", "rk4_c"])
def test_a_velocity_reversed_at_a_wall(method):
    """A mass sliding at v₀ towards a wall at L bounces with restitution e: hits at (L − x₀)/v₀, then x = L − e v₀ (t − t₁)."""
    x0, v0, wall, e = 0.12, 0.83, 0.5, 0.7
    model = lg.Model("slider")
    model.add("mass", "m", "p", m=0.3)

    def bounce(t, q, v):
        return q, {"x_p": -e * v["x_p"]}

    res = model.simulate(1.5, initial={"x_p": x0}, velocity={"x_p": v0}, method=method, points=301,
                         events=[lg.Event(f"x_p - {wall}", direction=1, action=bounce, name="wall")], **tight(method))
    t1 = (wall - x0) / v0
    assert [ev.name for ev in res.events] == ["wall"]
    assert abs(res.events[0].t - t1) < 1e-10
    want = np.where(res.t <= t1, x0 + v0 * res.t, wall - e * v0 * (res.t - t1))
    assert np.allclose(res["x_p"], want, rtol=0, atol=1e-9)
    assert res.velocity("x_p")[-1] == pytest.approx(-e * v0, abs=1e-10)


def test_a_callable_condition_sees_coordinates_and_velocities_by_name():
    model = drop()
    res = model.simulate(2.0, initial={"x_p": 1.0}, velocity={"x_p": 2.0}, rtol=1e-12, atol=1e-14,
                         events=[lg.Event(lambda t, q, v: v["x_p"], direction=-1, terminal=True, name="apex")])
    assert abs(res.events[0].t - 2.0 / 9.81) < 1e-10  # v = v₀ − g t = 0
    assert res.events[0].q["x_p"] == pytest.approx(1.0 + 2.0**2 / (2 * 9.81), abs=1e-10)


@pytest.mark.parametrize("bad,message", [
    (dict(when="x_p", direction=2), "direction must be -1"),
    (dict(when="x_p", terminal=True, action=lambda t, q, v: (q, v)), "cannot also have an action"),
    (dict(when="x_p", action="reverse"), "action must be a callable"),
    (dict(when="x_p", terminal=1), "terminal must be True or False"),
])
def test_a_malformed_event_is_refused_when_made(bad, message):
    with pytest.raises(lg.ModelError, match=message):
        lg.Event(**bad)


@pytest.mark.parametrize("events,method,message", [
    ([lg.Event("x_p")], "exact", "takes no events"),
    ([lg.Event("y_p")], "DOP853", "not a coordinate"),
    ([lg.Event("__import__('os')")], "DOP853", "event"),
    ("x_p", "DOP853", "events must be a list"),
    ([("x_p", 1)], "DOP853", "lagrangian.Event objects"),
    ([lg.Event("x_p", action=lambda t, q, v: 3)], "DOP853", "must return a pair of dicts"),
    ([lg.Event("x_p", action=lambda t, q, v: (q, {"z": 1.0}))], "DOP853", "unknown velocity 'z'"),
    ([lg.Event(lambda t, q, v: "low")], "DOP853", "must return a number"),
])
def test_events_that_cannot_run_get_a_clear_error(events, method, message):
    with pytest.raises(lg.LagrangianError, match=message):
        drop().simulate(1.0, initial={"x_p": 1.0}, velocity={"x_p": -3.0}, method=method, events=events)


@pytest.mark.parametrize("method", ["DOP853", "rk4"])
def test_a_ball_bouncing_with_restitution_hits_when_the_closed_form_says(method):
    """Dropped from h: t₁ = √(2h/g); each bounce leaves at e times the speed it came with, so the next hit is
    2 eᵏ v₁ / g later (v₁ = g t₁)."""
    height, g, e = 0.85, 9.81, 0.6
    bounce = lg.Event("x_p", direction=-1, action=lambda t, q, v: (q, {"x_p": -e * v["x_p"]}), name="floor")
    res = drop(g=g).simulate(1.3, initial={"x_p": height}, velocity={"x_p": 0.0}, method=method, events=[bounce],
                             **tight(method))
    t1 = math.sqrt(2 * height / g)
    want = [t1 + sum(2 * e**k * g * t1 / g for k in range(1, j + 1)) for j in range(4)]
    want = [w for w in want if w < 1.3]
    assert [ev.t for ev in res.events] == pytest.approx(want, abs=1e-9)
    assert np.all(res["x_p"] > -1e-9)  # never below the floor
    assert not any("drifted" in n for n in res.notes)  # the energy check knows actions change the energy


def test_a_chattering_event_is_stopped(monkeypatch):
    from lagrangian.numerics import events

    monkeypatch.setattr(events, "MAX_OCCURRENCES", 3)
    model = lg.Model("oscillator")
    model.add("mass", "m", "p", m=0.3)
    model.add("spring", "k", ("ground", "p"), k=7.0)
    with pytest.raises(lg.IntegrationError, match="chatters"):
        model.simulate(10.0, initial={"x_p": 0.1}, velocity={"x_p": 0.0}, events=[lg.Event("x_p", name="zero")])


@pytest.mark.parametrize("compiled, sibling", [("dopri5_c", "RK45"), ("dop853_c", "DOP853")])
def test_the_dense_output_of_a_compiled_step_keeps_its_own_copy_of_the_step(compiled, sibling, monkeypatch):
    """Events interpolate each step after the stepper has gone on: the step's dense output must hold on to the
    coefficients it reads, whatever reuses the memory in between (here blocks of the same size filled with NaN)."""
    from lagrangian.numerics.compiled_loops import CompiledSteps

    plain = CompiledSteps.dense_output

    def churned(self):
        state = plain(self)
        junk = [np.full(self._work.size, np.nan) for _ in range(64)]
        del junk
        return state

    model = pendulum(0.45, m=0.7)
    events = [lg.Event("theta_pin + pi/2", name="vertical")]
    runs = {}
    for method in (compiled, sibling):
        monkeypatch.setattr(CompiledSteps, "dense_output", churned)
        runs[method] = model.simulate(2.0, initial={"theta_pin": -0.4}, velocity={"theta_pin": 0.0}, method=method,
                                      events=events, points=21, compiled="auto", rtol=1e-10, atol=1e-12)
    c, py = runs[compiled], runs[sibling]
    assert len(c.events) == len(py.events) >= 2
    np.testing.assert_allclose([e.t for e in c.events], [e.t for e in py.events], rtol=0, atol=1e-9)
    np.testing.assert_allclose(c["theta_pin"], py["theta_pin"], rtol=0, atol=1e-8)
