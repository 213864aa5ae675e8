"""Events whose function crosses zero and comes back within one step: found by every method, at closed-form times.

A mass thrown up at v₀ under gravity is at x = v₀t − ½gt²; a level ``a`` below the apex H = v₀²/2g is passed
at t = (v₀ ∓ √(v₀² − 2ga))/g.  The one-step methods reproduce this motion exactly (its solution is a quadratic in
t; the multistep ones to their tolerance), and a free flight lets adaptive methods take long steps, so both
passages of a level just below the apex fall inside one step.  A fast oscillator x = A cos ωt with long steps
(x − a dipping below zero near the trough and coming back at t = (π ∓ arccos(−a/A))/ω) does the same with a
motion the methods only approximate.
"""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import lagrangian as lg

REGISTRY = lg.default_registry()
#: every method that can stop for events: adaptive ones step through start(), fixed-step ones through stepper()
METHODS = sorted(name for name, method in REGISTRY.integrators.items()
                 if callable(getattr(method, "start", None)) or callable(getattr(method, "stepper", None)))
FIXED = {name for name in METHODS if REGISTRY.integrators[name].kind == "fixed-step"}
#: multistep methods, which start at order 1 and so do not reproduce a motion quadratic in t exactly
MULTISTEP = {"BDF", "LSODA"}
G = 9.81
RTOL = 1e-10


def throw(m=0.3, g=G):
    model = lg.Model("throw")
    model.add("mass", "m", "p", m=m)
    model.add("gravity", "g", g=g)
    return model


def passages(v0, a, g=G):
    """The times x = v₀t − ½gt² equals ``a`` (below the apex), rising then falling."""
    root = math.sqrt(v0 * v0 - 2 * g * a)
    return (v0 - root) / g, (v0 + root) / g


def long_steps(method, t_apex):
    """Options under which a step spans the apex: a fixed step of 0.7 t_apex (points at 0.7 and 1.4 t_apex); an
    adaptive method's first step 0.3 t_apex, after which a free flight (zero error estimate) lets it grow tenfold."""
    if method in FIXED:
        return {"step": 0.7 * t_apex}
    return {"rtol": RTOL, "atol": 1e-12, "first_step": 0.3 * t_apex}


def assert_passages(method, got, want, v0, a, g=G):
    """Times to 1e-11 relative; a multistep method's positions are good to about ``rtol`` of the apex's height,
    which moves a passage by that over the speed there, √(2g(H − a))."""
    if method in MULTISTEP:
        apex = v0 * v0 / (2 * g)
        np.testing.assert_allclose(got, want, rtol=0, atol=RTOL * apex / math.sqrt(2 * g * (apex - a)))
    else:
        np.testing.assert_allclose(got, want, rtol=1e-11, atol=0)


def test_every_method_that_takes_events_is_checked():
    assert {"RK45", "DOP853", "Radau", "BDF", "LSODA", "dopri5_c", "dop853_c"} <= set(METHODS) - FIXED
    assert {"rk4", "verlet", "rk4_c", "verlet_c", "implicit_midpoint", "gauss_legendre", "variational"} <= FIXED


@pytest.mark.parametrize("method", METHODS)
def test_a_level_passed_up_and_down_within_one_step_is_found_twice(method):
    v0 = 4.2
    t_apex, apex = v0 / G, v0 * v0 / (2 * G)
    a = 0.999 * apex  # passed at t_apex (1 ∓ 0.0316): both inside the step that spans the apex
    res = throw().simulate(2 * t_apex, initial={"x_p": 0.0}, velocity={"x_p": v0}, method=method, points=5,
                           energy_tol=False, events=[lg.Event(f"x_p - {a!r}", name="level")],
                           **long_steps(method, t_apex))
    assert [e.name for e in res.events] == ["level", "level"]
    assert_passages(method, [e.t for e in res.events], passages(v0, a), v0, a)
    rising, falling = res.events
    assert rising.v["x_p"] > 0 > falling.v["x_p"]
    assert rising.q["x_p"] == pytest.approx(a, rel=1e-11) and falling.q["x_p"] == pytest.approx(a, rel=1e-11)


@pytest.mark.parametrize("method", METHODS)
def test_a_level_passed_twice_within_the_first_step_is_found_twice(method):
    """A first step of 1.5 t_apex spans the apex (and the last one, to 2 t_apex, is shorter than the others)."""
    v0 = 2.3
    t_apex, apex = v0 / G, v0 * v0 / (2 * G)
    a = 0.995 * apex
    step = {"step": 1.5 * t_apex} if method in FIXED else {"rtol": RTOL, "atol": 1e-12, "first_step": 1.5 * t_apex}
    res = throw().simulate(2 * t_apex, initial={"x_p": 0.0}, velocity={"x_p": v0}, method=method, points=5,
                           energy_tol=False, events=[lg.Event(f"x_p - {a!r}", name="level")], **step)
    assert [e.name for e in res.events] == ["level", "level"]
    assert_passages(method, [e.t for e in res.events], passages(v0, a), v0, a)


@pytest.mark.parametrize("method", ["RK45", "DOP853", "Radau", "dopri5_c", "rk4", "rk4_c", "verlet",
                                    "implicit_midpoint"])
def test_a_band_passed_within_the_first_step_after_a_wall_is_found(method):
    """A mass sliding at v₀ from 0 passes the band |x − c| < δ, bounces at the wall L with restitution e at
    t₁ = L/v₀, and passes the band again at t₁ + (L − c ∓ δ)/(e v₀): within the first step after the bounce."""
    v0, wall, e, c, delta = 0.83, 0.5, 0.7, 0.45, 0.01
    model = lg.Model("slider")
    model.add("mass", "m", "p", m=0.3)
    bounce = lg.Event(f"x_p - {wall}", direction=1, action=lambda t, q, v: (q, {"x_p": -e * v["x_p"]}), name="wall")
    band = lg.Event(f"(x_p - {c})**2 - {delta * delta!r}", name="band")
    step = {"step": 0.35} if method in FIXED else {"rtol": RTOL, "atol": 1e-12, "first_step": 0.35}
    res = model.simulate(1.0, initial={"x_p": 0.0}, velocity={"x_p": v0}, method=method, points=5,
                         events=[bounce, band], **step)
    t1 = wall / v0
    back = [t1 + (wall - c - delta) / (e * v0), t1 + (wall - c + delta) / (e * v0)]
    want = [(c - delta) / v0, (c + delta) / v0, t1, *back]
    assert [ev.name for ev in res.events] == ["band", "band", "wall", "band", "band"]
    np.testing.assert_allclose([ev.t for ev in res.events], want, rtol=1e-12, atol=0)


@pytest.mark.parametrize("method", ["RK45", "DOP853", "Radau", "dopri5_c", "rk4", "rk4_c", "verlet_c",
                                    "gauss_legendre"])
@pytest.mark.parametrize("direction", [1, -1])
def test_a_terminal_event_stops_at_the_passage_of_its_direction(method, direction):
    v0 = 3.1
    t_apex, apex = v0 / G, v0 * v0 / (2 * G)
    a = 0.998 * apex
    res = throw().simulate(2 * t_apex, initial={"x_p": 0.0}, velocity={"x_p": v0}, method=method, points=5,
                           energy_tol=False,
                           events=[lg.Event(f"x_p - {a!r}", direction=direction, terminal=True, name="stop")],
                           **long_steps(method, t_apex))
    want = passages(v0, a)[0 if direction > 0 else 1]
    [hit] = res.events
    assert hit.t == pytest.approx(want, rel=1e-11)
    assert res.t[-1] == hit.t and res["x_p"][-1] == pytest.approx(a, rel=1e-11)


@pytest.mark.parametrize("method", ["RK45", "DOP853", "LSODA", "dop853_c", "rk4", "verlet", "variational"])
def test_events_of_two_levels_passed_within_one_step_are_all_recorded_in_order(method):
    """Levels a₁ < a₂ below the apex: passed a₁ ↑, a₂ ↑, a₂ ↓, a₁ ↓, two by two within the step over the apex."""
    v0 = 4.2
    t_apex, apex = v0 / G, v0 * v0 / (2 * G)
    a1, a2 = 0.997 * apex, 0.9993 * apex
    res = throw().simulate(2 * t_apex, initial={"x_p": 0.0}, velocity={"x_p": v0}, method=method, points=5,
                           energy_tol=False,
                           events=[lg.Event(f"x_p - {a1!r}", name="low"), lg.Event(f"x_p - {a2!r}", name="high")],
                           **long_steps(method, t_apex))
    (r1, f1), (r2, f2) = passages(v0, a1), passages(v0, a2)
    assert [e.name for e in res.events] == ["low", "high", "high", "low"]
    assert_passages(method, [e.t for e in res.events][::3], [r1, f1], v0, a1)
    assert_passages(method, [e.t for e in res.events][1:3], [r2, f2], v0, a2)


@settings(max_examples=12, deadline=None)
@given(m=st.floats(1e-3, 1e3), g=st.floats(0.1, 100.0), v0=st.floats(1e-2, 1e2), depth=st.floats(1e-6, 0.3),
       method=st.sampled_from(["DOP853", "RK45", "rk4_c", "verlet"]))
def test_both_passages_of_a_level_below_the_apex_over_decades(m, g, v0, depth, method):
    m, g, v0, depth = (float(f"{x:.3g}") for x in (m, g, v0, depth))
    t_apex, apex = v0 / g, v0 * v0 / (2 * g)
    a = (1 - depth) * apex
    opts = ({"step": 0.7 * t_apex} if method in FIXED
            else {"rtol": 1e-10, "atol": 1e-12 * apex, "first_step": 0.3 * t_apex})
    res = throw(m, g).simulate(2 * t_apex, initial={"x_p": 0.0}, velocity={"x_p": v0}, method=method, points=5,
                               energy_tol=False, events=[lg.Event(f"x_p - {a!r}", name="level")], **opts)
    want = passages(v0, a, g)
    # a level deeper below the apex is passed faster: the time of a passage is as good as x/ẋ there
    tol = 1e-10 * t_apex / math.sqrt(depth)
    assert len(res.events) == 2
    np.testing.assert_allclose([e.t for e in res.events], want, rtol=0, atol=tol)


def oscillator(m=0.3, k=470.0):
    model = lg.Model("oscillator")
    model.add("mass", "m", "p", m=m)
    model.add("spring", "k", ("ground", "p"), k=k)
    return model


#: per step of ωh = θ on x'' = −ω²x: a method's phase error, and how much of its amplitude it loses (the symplectic
#: ones keep it): rk4's R(iθ) = 1 + iθ − θ²/2 − iθ³/6 + θ⁴/24 has arg θ − θ⁵/120 and modulus 1 − θ⁶/144; Störmer–Verlet
#: turns by arccos(1 − θ²/2) = θ + θ³/24; the s-stage Gauss–Legendre rule by θ − (s!)²/((2s)!(2s+1)!) θ^(2s+1)
PER_STEP = {"rk4": (lambda x: x**5 / 120, lambda x: x**6 / 144), "verlet": (lambda x: x**3 / 24, lambda x: 0.0),
            "implicit_midpoint": (lambda x: x**3 / 12, lambda x: 0.0),
            "gauss_legendre": (lambda x: x**5 / 720, lambda x: 0.0)}


@pytest.mark.parametrize("method, K", [("rk4", 12), ("rk4_c", 12), ("gauss_legendre", 12), ("verlet", 60),
                                       ("verlet_c", 60), ("implicit_midpoint", 60)])
def test_a_fast_oscillator_dipping_below_a_level_between_two_steps(method, K):
    """x = A cos ωt dips below a = −A cos d around the trough t = π/ω, from (π − d)/ω to (π + d)/ω; the step
    h = π/((K + ½)ω) puts the trough halfway between two step points, π/ω ∓ h/2, and d = 0.4 ωh inside them.  Over
    the K + 1 steps to the trough the method's phase error moves the crossings by as much, and a lost fraction δ of
    the amplitude by δ / sin d (x' = Aω sin d there)."""
    m, k, A = 0.3, 470.0, 0.05
    w = math.sqrt(k / m)
    h = math.pi / ((K + 0.5) * w)
    d = 0.4 * w * h
    a = -A * math.cos(d)
    res = oscillator(m, k).simulate((K + 3) * h, initial={"x_p": A}, velocity={"x_p": 0.0}, method=method,
                                    points=5, step=h, energy_tol=False, events=[lg.Event(f"x_p - ({a!r})", name="dip")])
    want = [(math.pi - d) / w, (math.pi + d) / w]
    phase, amplitude = (f(w * h) * (K + 1) for f in PER_STEP[method.removesuffix("_c")])
    tol = 2 * (phase + amplitude / math.sin(d))
    assert [e.name for e in res.events] == ["dip", "dip"]
    np.testing.assert_allclose([e.t for e in res.events], want, rtol=0, atol=tol / w)
    assert tol < 0.1 * d  # the check tells the two crossings apart: each is placed within a tenth of the dip


@pytest.mark.parametrize("method, rtol", [("RK45", 1e-6), ("DOP853", 1e-7), ("Radau", 2e-6), ("BDF", 2e-6),
                                          ("LSODA", 5e-7), ("dopri5_c", 1e-6), ("dop853_c", 1e-7)])
def test_a_fast_oscillator_dipping_below_a_level_within_an_adaptive_step(method, rtol):
    """x = A cos ωt dips below a = −A cos d around the trough t = π/ω; SciPy's own solver, with the same
    tolerances, shows how far from the trough its nearest step point is, and d is 0.6 of that: the dip lies inside
    one step."""
    from scipy.integrate import solve_ivp

    m, k, A = 0.3, 470.0, 0.05
    w = math.sqrt(k / m)
    opts = {"rtol": rtol, "atol": 1e-3 * rtol * A}
    scipy_method = {"dopri5_c": "RK45", "dop853_c": "DOP853"}.get(method, method)
    steps = solve_ivp(lambda t, y: [y[1], -w * w * y[0]], (0, 1.2 * math.pi / w), [A, 0.0], method=scipy_method,
                      **opts).t
    gap = float(np.min(np.abs(steps * w - math.pi)))
    assert gap > 0.02, "a step point falls next to the trough: choose rtol so that it does not"
    d = 0.6 * gap
    a = -A * math.cos(d)
    res = oscillator(m, k).simulate(1.2 * math.pi / w, initial={"x_p": A}, velocity={"x_p": 0.0}, method=method,
                                    points=5, energy_tol=False, events=[lg.Event(f"x_p - ({a!r})", name="dip")], **opts)
    want = [(math.pi - d) / w, (math.pi + d) / w]
    # an error of x of a few rtol·A (the local errors over the steps to the trough) moves a crossing by that / |ẋ|
    tol = 4 * rtol / (w * math.sin(d))
    assert [e.name for e in res.events] == ["dip", "dip"]
    np.testing.assert_allclose([e.t for e in res.events], want, rtol=0, atol=tol)
    assert tol < 0.1 * d / w
