"""The exact (matrix-exponential) solution of linear time-invariant models.

Every expected value comes from physics written out here: closed forms derived
by hand (derivations in the comments), or ``Model.simulate`` (an independent
path: numerical integration of the nonlinear-capable equations) at tight
tolerances.  Nothing expected is taken from :mod:`lagrangian.linear` itself.

Thresholds: the exact solution differs from the closed form only by rounding.
A step multiplies the state by ``e^{Z h}``, accurate to a few ulps, so over N
steps of an undamped oscillation the error grows to about ``N · 1e-17`` times
the amplitude (measured: 4e-14 over 2,000 steps, 9e-14 over 4,000 at
resonance).  We assert ``1e-12`` times the solution's scale — a tenfold
margin or more, and three orders of magnitude below what the default
integrator achieves (``1e-9``).  Against
``Model.simulate`` at ``rtol=1e-12`` the integrator's own error dominates;
there we assert ``1e-9`` of the scale.
"""

from __future__ import annotations

import math
import types
import warnings

import numpy as np
import pytest
import scipy.linalg
import sympy as sp
from hypothesis import assume, example, given, settings
from hypothesis import strategies as st

import lagrangian as lg
from lagrangian.linear import simulate_exact, state_space

t = lg.t

#: Bound on the error of the exact solution, per unit of solution scale (see module docstring).
EXACT_TOL = 1e-12
#: Bound on |exact − DOP853 at TIGHT|, per unit of solution scale.
VS_SIMULATE_TOL = 1e-9
TIGHT = {"rtol": 1e-12, "atol": 1e-15}


@pytest.fixture(autouse=True)
def _quiet_defaults():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lg.InitialConditionWarning)
        yield


def _decades(low, high):
    """Three-digit decimals drawn log-uniformly between 10^low and 10^high."""
    return st.floats(low, high).map(lambda x: float(f"{10 ** x:.3g}"))


def max_err(actual, expected) -> float:
    return float(np.max(np.abs(np.asarray(actual) - np.asarray(expected))))


# ---------------------------------------------------------------------------
# Builders
# ---------------------------------------------------------------------------


def oscillator(m, k, c=None, F=None) -> lg.Model:
    model = lg.Model("oscillator")
    model.add("mass", "m1", "p", m=m)
    model.add("spring", "k1", ("ground", "p"), k=k)
    if c is not None:
        model.add("damper", "c1", ("ground", "p"), c=c)
    if F is not None:
        model.add("force", "f1", "p", F=F)
    return model


def series_rlc(R, L, C, E) -> lg.Model:
    model = lg.Model("series-rlc", formulation="charge")
    model.add("voltage_source", "V1", ("n1", "0"), E=E)
    model.add("resistor", "R1", ("n1", "n2"), R=R)
    model.add("inductor", "L1", ("n2", "n3"), L=L)
    model.add("capacitor", "C1", ("n3", "0"), C=C)
    return model


def rc(R, C, E) -> lg.Model:
    """source (n1, 0), R (n1, n2), C (n2, 0): one first-order coordinate q_R1, the charge on C."""
    model = lg.Model("rc", formulation="charge")
    model.add("voltage_source", "V1", ("n1", "0"), E=E)
    model.add("resistor", "R1", ("n1", "n2"), R=R)
    model.add("capacitor", "C1", ("n2", "0"), C=C)
    return model


def rlc_ladder(sections: int, seed: int, E) -> lg.Model:
    """E — [R_i — L_i — node i, C_i to ground] × sections, charge formulation, random values."""
    rng = np.random.default_rng(seed)
    model = lg.Model("ladder", formulation="charge")
    model.add("voltage_source", "V1", ("in", "0"), E=E)
    prev = "in"
    for i in range(1, sections + 1):
        model.add("resistor", f"R{i}", (prev, f"m{i}"), R=float(rng.uniform(0.2, 2.0)))
        model.add("inductor", f"L{i}", (f"m{i}", f"n{i}"), L=float(rng.uniform(0.5, 2.0)))
        model.add("capacitor", f"C{i}", (f"n{i}", "0"), C=float(rng.uniform(0.2, 1.0)))
        prev = f"n{i}"
    return model


# ---------------------------------------------------------------------------
# 1. The state-space form
# ---------------------------------------------------------------------------


def test_state_space_of_a_series_rlc_is_the_companion_form():
    # L q̈ + R q̇ + q/C = E(t)  ⇒  d/dt (q, q̇) = [[0, 1], [−1/LC, −R/L]] (q, q̇) + (0, E/L)
    R, L, C = 10.0, 0.1, 1e-3
    ss = state_space(series_rlc(R, L, C, 2 * sp.sin(3 * t)))
    assert ss.states == ["q_L1", "q_L1'"]
    assert ss.first_order == [] and ss.inertial == ["q_L1"]
    np.testing.assert_allclose(ss.F, [[0, 1], [-1 / (L * C), -R / L]], rtol=1e-14)
    assert sp.simplify(ss.g[0]) == 0
    assert sp.simplify(ss.g[1] - 2 * sp.sin(3 * t) / L) == 0


def test_state_space_of_a_spring_and_damper_in_series_has_a_first_order_coordinate():
    # ground —k— a —c— p (mass m): ẋ_a = ẋ_p − (k/c) x_a,  m ẍ_p = −k x_a  (see test_physics)
    m, k, c = 2.0, 4.0, 0.8
    model = lg.Model("maxwell")
    model.add("spring", "k1", ("ground", "a"), k=k)
    model.add("damper", "c1", ("a", "p"), c=c)
    model.add("mass", "m1", "p", m=m)
    ss = state_space(model)
    assert ss.first_order == ["x_a"]
    order = {name: i for i, name in enumerate(ss.states)}  # (x_a, x_p, x_p')
    F = np.zeros((3, 3))
    F[order["x_a"], [order["x_a"], order["x_p'"]]] = [-k / c, 1]
    F[order["x_p"], order["x_p'"]] = 1
    F[order["x_p'"], order["x_a"]] = -k / m
    np.testing.assert_allclose(ss.F, F, rtol=1e-14, atol=1e-15)
    assert ss.inputs.shape == (0, 1)
    assert ss.g == sp.zeros(3, 1)


def test_state_space_takes_symbolic_parameter_values():
    m, k = sp.symbols("m k", positive=True)
    ss = state_space(oscillator(m, k), params={"m": 2.0, "k": 8.0})
    np.testing.assert_allclose(ss.F, [[0, 1], [-4, 0]])
    with pytest.raises(lg.ModelError, match="without values"):
        state_space(oscillator(m, k), params={"m": 2.0})


# ---------------------------------------------------------------------------
# 2. Oscillators against closed forms
# ---------------------------------------------------------------------------


def test_undamped_oscillator_with_a_cosine_force_is_exact():
    # m ẍ + k x = F0 cos Ωt, x(0) = x0, ẋ(0) = v0, ω² = k/m ≠ Ω²:
    #   A = F0 / (m (ω² − Ω²)),  x = (x0 − A) cos ωt + (v0/ω) sin ωt + A cos Ωt
    m, k, F0, W, x0, v0 = 1.5, 6.0, 0.7, 1.3, 0.2, -0.4
    w = math.sqrt(k / m)
    A = F0 / (m * (w**2 - W**2))
    res = simulate_exact(oscillator(m, k, F=F0 * sp.cos(W * t)), 20 * 2 * math.pi / w, initial={"x_p": x0},
                         velocity={"x_p": v0}, points=2001)
    T = res.t
    x = (x0 - A) * np.cos(w * T) + v0 / w * np.sin(w * T) + A * np.cos(W * T)
    xd = -(x0 - A) * w * np.sin(w * T) + v0 * np.cos(w * T) - A * W * np.sin(W * T)
    scale = abs(x0 - A) + abs(v0 / w) + abs(A)
    assert max_err(res["x_p"], x) < EXACT_TOL * scale
    assert max_err(res.velocity("x_p"), xd) < EXACT_TOL * scale * w
    # the energies are the library's functions of the exact state: T = ½ m ẋ², V = ½ k x²
    np.testing.assert_allclose(res.T, m * xd**2 / 2, rtol=0, atol=EXACT_TOL * m * (scale * w) ** 2)
    np.testing.assert_allclose(res.V, k * x**2 / 2, rtol=0, atol=EXACT_TOL * k * scale**2)
    assert res.method == "exact" and res.defaulted == []


@settings(max_examples=25, deadline=None)
@given(st.floats(-1, 1).map(lambda e: float(f"{10 ** e:.3g}")), st.floats(0, 3).map(lambda e: float(f"{10 ** e:.3g}")),
       st.floats(0.0, 2.0), st.sampled_from([9.81, 1.62]), st.floats(-0.5, 0.5))
def test_a_mass_hanging_on_a_spring_with_a_rest_length_under_gravity_is_exact_in_numbers(m, k, rest, g, x0):
    # V = ½ k (x − ℓ₀)² + m g x (gravity along −x): rest at x* = ℓ₀ − m g / k, so x = x* + (x0 − x*) cos ωt with
    # ω² = k/m, and T + V keeps its start value.  The constant loads are in the numeric stamps: nothing derived.
    from lagrangian.derivation.numeric import numeric_stamps

    model = lg.Model("hanging")
    model.add("mass", "m", "p", m=m)
    model.add("spring", "k", ("ground", "p"), k=k, rest_length=rest)
    model.add("gravity", "g", g=g)
    assert numeric_stamps(model).inputs == [1]
    w, star = math.sqrt(k / m), rest - m * g / k
    res = model.simulate(20 * 2 * math.pi / w, initial={"x_p": x0}, velocity={"x_p": 0.0}, points=801, method="exact")
    x = star + (x0 - star) * np.cos(w * res.t)
    scale = abs(star) + abs(x0 - star)
    assert max_err(res["x_p"], x) < EXACT_TOL * scale
    energy = k * (x0 - rest) ** 2 / 2 + m * g * x0
    V = k * (x - rest) ** 2 / 2 + m * g * x
    assert max_err(res.V, V) < EXACT_TOL * k * scale**2
    assert max_err(res.T + res.V, np.full_like(x, energy)) < EXACT_TOL * k * scale**2


def test_undamped_oscillator_driven_at_resonance_grows_linearly():
    # ẍ + ω² x = (F0/m) cos ωt from rest: x = F0 t sin ωt / (2 m ω) — the input's frequency is an
    # eigenvalue of F; the augmented exponential needs no special case.
    m, k, F0 = 2.0, 8.0, 0.6
    w = math.sqrt(k / m)
    res = simulate_exact(oscillator(m, k, F=F0 * sp.cos(w * t)), 40.0, initial={"x_p": 0.0}, velocity={"x_p": 0.0},
                         points=4001)
    x = F0 * res.t * np.sin(w * res.t) / (2 * m * w)
    assert max_err(res["x_p"], x) < EXACT_TOL * float(np.max(np.abs(x)))


def damped_forced(m, c, k, F0, W, x0, v0, T):
    """m ẍ + c ẋ + k x = F0 sin Ωt, underdamped, from (x0, v0).

    Particular a sin Ωt + b cos Ωt:  (k − mΩ²) a − cΩ b = F0,  cΩ a + (k − mΩ²) b = 0
      ⇒ a = F0 (k − mΩ²)/Δ,  b = −F0 cΩ/Δ,  Δ = (k − mΩ²)² + (cΩ)².
    Homogeneous e^{−γt}(c1 cos ω_d t + c2 sin ω_d t), γ = c/2m, ω_d = √(k/m − γ²):
      x(0) = x0 ⇒ c1 = x0 − b;  ẋ(0) = v0 ⇒ aΩ − γ c1 + ω_d c2 = v0.
    """
    d = (k - m * W**2) ** 2 + (c * W) ** 2
    a, b = F0 * (k - m * W**2) / d, -F0 * c * W / d
    g = c / (2 * m)
    wd = math.sqrt(k / m - g * g)
    c1 = x0 - b
    c2 = (v0 - a * W + g * c1) / wd
    env = np.exp(-g * T)
    x = a * np.sin(W * T) + b * np.cos(W * T) + env * (c1 * np.cos(wd * T) + c2 * np.sin(wd * T))
    xd = a * W * np.cos(W * T) - b * W * np.sin(W * T) + env * (
        (wd * c2 - g * c1) * np.cos(wd * T) - (wd * c1 + g * c2) * np.sin(wd * T)
    )
    return x, xd


@pytest.mark.parametrize("m, c, k, W", [(1.0, 0.4, 4.0, 1.5), (2.0, 3.0, 50.0, 7.0)])
def test_damped_oscillator_with_a_sine_force_is_exact(m, c, k, W):
    F0, x0, v0 = 0.8, 0.1, 0.3
    res = simulate_exact(oscillator(m, k, c=c, F=F0 * sp.sin(W * t)), 20.0, initial={"x_p": x0},
                         velocity={"x_p": v0}, points=2001)
    x, xd = damped_forced(m, c, k, F0, W, x0, v0, res.t)
    scale = float(np.max(np.abs(x)))
    assert max_err(res["x_p"], x) < EXACT_TOL * scale
    assert max_err(res.velocity("x_p"), xd) < EXACT_TOL * float(np.max(np.abs(xd)))
    # Rayleigh function ½ c ẋ²
    np.testing.assert_allclose(res.D, c * xd**2 / 2, rtol=0, atol=EXACT_TOL * c * float(np.max(xd**2)))


def test_a_late_start_sees_the_force_at_absolute_time():
    # m ẍ + k x = F0 cos Ωt from (x0, v0) at t0: with A = F0/(m(ω² − Ω²)), s = t − t0,
    #   x = A cos Ωt + (x0 − A cos Ωt0) cos ωs + (v0 + AΩ sin Ωt0)/ω sin ωs
    m, k, F0, W, t0, t1, x0, v0 = 1.0, 9.0, 0.5, 1.3, 2.0, 10.0, 0.1, 0.0
    w = math.sqrt(k / m)
    A = F0 / (m * (w**2 - W**2))
    res = simulate_exact(oscillator(m, k, F=F0 * sp.cos(W * t)), (t0, t1), initial={"x_p": x0}, velocity={"x_p": v0})
    assert res.t[0] == t0 and res.t[-1] == t1
    s = res.t - t0
    x = A * np.cos(W * res.t) + (x0 - A * math.cos(W * t0)) * np.cos(w * s) + (v0 + A * W * math.sin(W * t0)) / w * np.sin(w * s)
    assert max_err(res["x_p"], x) < EXACT_TOL


def test_non_uniform_output_times_are_exact():
    # free damped oscillator at random times (see test_damped_oscillator_with_a_sine_force_is_exact, F0 = 0)
    m, c, k = 1.0, 0.5, 9.0
    grid = np.sort(np.random.default_rng(3).uniform(0, 15, 300))
    res = simulate_exact(oscillator(m, k, c=c), 15.0, t_eval=grid, initial={"x_p": 1.0}, velocity={"x_p": 0.0})
    x, xd = damped_forced(m, c, k, 0.0, 1.0, 1.0, 0.0, grid)
    np.testing.assert_array_equal(res.t, grid)
    assert max_err(res["x_p"], x) < EXACT_TOL
    assert max_err(res.velocity("x_p"), xd) < EXACT_TOL * 3


@settings(max_examples=12, deadline=None, derandomize=True)
@given(m=_decades(-2, 2), k=_decades(-1, 4), zeta=_decades(-3, -0.05), r=_decades(-1, 0.7), F0=_decades(-2, 2),
       seed=st.integers(0, 2**16))
@pytest.mark.slow
def test_uneven_output_times_under_a_sine_force_are_exact(m, k, zeta, r, F0, seed):
    """Outputs at uneven times (ngspice's time points, say) are evaluated at once from the eigendecomposition of F
    and the particular solution; against the closed form they are as exact as stepping on an even grid, for
    masses and stiffnesses over decades, damping from 1e-3 to 0.9 of critical, forcing below and above resonance."""
    c = float(f"{2 * zeta * math.sqrt(k * m):.3g}")
    w0 = math.sqrt(k / m)
    W = float(f"{r * w0:.3g}")
    t_end = 12 * 2 * math.pi / w0
    grid = np.sort(np.random.default_rng(seed).uniform(0, t_end, 400))
    res = simulate_exact(oscillator(m, k, c=c, F=F0 * sp.sin(W * t)), t_end, t_eval=grid, initial={"x_p": 0.37},
                         velocity={"x_p": -0.2})
    x, xd = damped_forced(m, c, k, F0, W, 0.37, -0.2, grid)
    assert max_err(res["x_p"], x) < 1e-11 * float(np.max(np.abs(x)))
    assert max_err(res.velocity("x_p"), xd) < 1e-11 * float(np.max(np.abs(xd)))


# ---------------------------------------------------------------------------
# 3. Circuits against closed forms
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("q0, E0", [(2e-3, 0.0), (0.0, 1.0), (-1e-3, 2.5)])
def test_series_rlc_step_response_is_exact(q0, E0):
    # L q̈ + R q̇ + q/C = E0, q(0) = q0, q̇(0) = 0; α = R/2L, ω_d = √(1/LC − α²):
    #   q = C E0 + (q0 − C E0) e^{−αt} (cos ω_d t + α/ω_d sin ω_d t),  i = −(q0 − C E0)(ω0²/ω_d) e^{−αt} sin ω_d t
    R, L, C = 10.0, 0.1, 1e-3
    alpha, w0 = R / (2 * L), 1 / math.sqrt(L * C)
    wd = math.sqrt(w0**2 - alpha**2)
    res = simulate_exact(series_rlc(R, L, C, E0), 0.15, initial={"q_L1": q0}, velocity={"q_L1": 0.0})
    T = res.t
    env = np.exp(-alpha * T)
    q = C * E0 + (q0 - C * E0) * env * (np.cos(wd * T) + alpha / wd * np.sin(wd * T))
    i = -(q0 - C * E0) * (w0**2 / wd) * env * np.sin(wd * T)
    scale = max(abs(q0), abs(C * E0))
    assert max_err(res["q_L1"], q) < EXACT_TOL * scale
    assert max_err(res.velocity("q_L1"), i) < EXACT_TOL * scale * w0


def test_series_rlc_switched_on_later_by_a_heaviside_step():
    # E = E0 H(t − ts): at rest until ts, then the step response of the previous test shifted by ts.
    R, L, C, E0, ts = 10.0, 0.1, 1e-3, 1.0, 0.0123
    alpha, w0 = R / (2 * L), 1 / math.sqrt(L * C)
    wd = math.sqrt(w0**2 - alpha**2)
    res = simulate_exact(series_rlc(R, L, C, E0 * sp.Heaviside(t - ts)), 0.15, initial={"q_L1": 0.0},
                         velocity={"q_L1": 0.0})
    s = np.maximum(res.t - ts, 0.0)
    q = C * E0 * (1 - np.exp(-alpha * s) * (np.cos(wd * s) + alpha / wd * np.sin(wd * s)))
    assert max_err(res["q_L1"], q) < EXACT_TOL * C * E0


def rc_sine(R, C, E0, W, T):
    """R q̇ + q/C = E0 sin Ωt, q(0) = 0.

    q_p = A sin Ωt + B cos Ωt:  A/C − RΩB = E0,  RΩA + B/C = 0  ⇒  A = E0 C/(1 + (RCΩ)²),  B = −RCΩ A;
    q = q_p − B e^{−t/RC}.
    """
    A = E0 * C / (1 + (R * C * W) ** 2)
    B = -R * C * W * A
    tau = R * C
    q = A * np.sin(W * T) + B * np.cos(W * T) - B * np.exp(-T / tau)
    i = A * W * np.cos(W * T) - B * W * np.sin(W * T) + B / tau * np.exp(-T / tau)
    return q, i


@pytest.mark.parametrize("R, C", [(1e3, 1e-3), (2.0, 0.5)])
def test_rc_with_a_step_and_with_a_sine_is_exact(R, C):
    # step: R q̇ + q/C = E, q(0) = 0  ⇒  q = C E (1 − e^{−t/RC}),  i = (E/R) e^{−t/RC}
    E, tau = 5.0, R * C
    res = simulate_exact(rc(R, C, E), 6 * tau, initial={"q_R1": 0.0})
    assert res.defaulted == []
    assert max_err(res["q_R1"], C * E * (1 - np.exp(-res.t / tau))) < EXACT_TOL * C * E
    # the velocity of the first-order coordinate is an output of the solve, not a state
    assert max_err(res.velocity("q_R1"), E / R * np.exp(-res.t / tau)) < EXACT_TOL * E / R
    W = 3.0 / tau
    res = simulate_exact(rc(R, C, E * sp.sin(W * t)), 10 * tau, initial={"q_R1": 0.0})
    q, i = rc_sine(R, C, E, W, res.t)
    assert max_err(res["q_R1"], q) < EXACT_TOL * C * E
    assert max_err(res.velocity("q_R1"), i) < EXACT_TOL * E / R
    # energy stored in the capacitor q²/2C, dissipated power 2D = R i²
    np.testing.assert_allclose(res.V, q**2 / (2 * C), rtol=0, atol=EXACT_TOL * C * E**2)
    np.testing.assert_allclose(2 * res.D, R * i**2, rtol=0, atol=EXACT_TOL * E**2 / R)


def rc_piecewise_linear(R, C, knots, values, T, q0=0.0):
    """R q̇ + q/C = E(t), E linear between ``knots`` (values ``values``), marched piece by piece.

    On a piece E = α + β s (s = t − a): q_p = C(α + β s) − β R C² solves R q̇_p + q_p/C = E
    (R C β + α + β s − β R C = α + β s), so q = q_p + (q(a) − q_p(0)) e^{−s/RC}.
    """
    out = np.full(T.shape, np.nan)
    q, tau = q0, R * C
    for a, b, ea, eb in zip(knots[:-1], knots[1:], values[:-1], values[1:]):
        if b <= a:
            continue
        beta, alpha = (eb - ea) / (b - a), ea

        def q_at(s, q=q, alpha=alpha, beta=beta):
            p0 = C * alpha - beta * R * C * C
            return C * (alpha + beta * s) - beta * R * C * C + (q - p0) * np.exp(-s / tau)

        inside = (T >= a) & (T <= b)
        out[inside] = q_at(T[inside] - a)
        q = q_at(b - a)
    return out


@pytest.mark.slow
def test_rc_driven_by_a_periodic_trapezoidal_pulse_matches_the_piecewise_closed_form():
    # SPICE PULSE(V1 V2 TD TR TF PW PER) written with Mod: rise, flat top, fall, flat bottom each period.
    V1, V2, TD, TR, TF, PW, PER = -0.5, 1.0, 0.1, 0.05, 0.1, 0.3, 1.0
    tau = sp.Mod(t - TD, PER)
    E = sp.Piecewise(
        (V1, t < TD),
        (V1 + (V2 - V1) * tau / TR, tau < TR),
        (V2, tau < TR + PW),
        (V2 - (V2 - V1) * (tau - TR - PW) / TF, tau < TR + PW + TF),
        (V1, True),
    )
    R, C = 1.0, 0.2
    res = simulate_exact(rc(R, C, E), 6.0, initial={"q_R1": 0.0}, points=1501)
    knots, values = [0.0, TD], [V1, V1]
    for k in range(7):
        base = TD + k * PER
        for dt, v in [(TR, V2), (TR + PW, V2), (TR + PW + TF, V1), (PER, V1)]:
            knots.append(base + dt)
            values.append(v)
    q = rc_piecewise_linear(R, C, np.array(knots), np.array(values), res.t)
    assert max_err(res["q_R1"], q) < EXACT_TOL * C * V2


def test_rc_driven_by_rectangular_pulses_given_as_a_plain_piecewise():
    # E = 1 on [0.5, 1.5) and [3, 3.2), else 0; from q(0) = 0.1
    E = sp.Piecewise((0, t < 0.5), (1, t < 1.5), (0, t < 3), (1, t < 3.2), (0, True))
    R, C = 0.5, 1.0
    res = simulate_exact(rc(R, C, E), 5.0, initial={"q_R1": 0.1}, points=777)
    knots = [0, 0.5, 0.5, 1.5, 1.5, 3, 3, 3.2, 3.2, 5]
    values = [0, 0, 1, 1, 0, 0, 1, 1, 0, 0]
    q = rc_piecewise_linear(R, C, np.array(knots, float), np.array(values, float), res.t, q0=0.1)
    assert max_err(res["q_R1"], q) < EXACT_TOL


def test_series_rlc_driven_by_a_damped_sine_is_exact():
    # SPICE SIN(0 VA f 0 θ): E = VA e^{−θt} sin ωt = Im(VA e^{st}), s = −θ + iω.
    # L q̈ + R q̇ + q/C = Im(VA e^{st}):  q_p = Im(VA e^{st} / P(s)), P(r) = L r² + R r + 1/C.
    # Homogeneous a e^{r1 t} + b e^{r2 t} (roots of P) with a + b = −q_p(0), r1 a + r2 b = −q̇_p(0).
    R, L, C, VA, theta, w = 1.0, 0.5, 0.1, 2.0, 0.8, 5.0
    E = VA * sp.exp(-theta * t) * sp.sin(w * t)
    res = simulate_exact(series_rlc(R, L, C, E), 12.0, initial={"q_L1": 0.0}, velocity={"q_L1": 0.0}, points=2401)
    s = complex(-theta, w)
    P = L * s * s + R * s + 1 / C
    r1, r2 = np.roots([L, R, 1 / C])
    qp0, dqp0 = (VA / P).imag, (VA * s / P).imag
    a = (-dqp0 + r2 * qp0) / (r1 - r2)
    b = -qp0 - a
    T = res.t
    q = (VA * np.exp(s * T) / P).imag + (a * np.exp(r1 * T) + b * np.exp(r2 * T)).real
    i = (VA * s * np.exp(s * T) / P).imag + (a * r1 * np.exp(r1 * T) + b * r2 * np.exp(r2 * T)).real
    assert max_err(res["q_L1"], q) < EXACT_TOL * float(np.max(np.abs(q)))
    assert max_err(res.velocity("q_L1"), i) < EXACT_TOL * float(np.max(np.abs(i)))


def test_parallel_rlc_in_flux_linkages_driven_by_a_cosine_current():
    # C λ̈ + λ̇/R + λ/L = I0 cos Ωt (KCL at n1, see test_physics); phasor particular solution
    #   λ_p = Re(I0 e^{iΩt} / P(iΩ)), P(r) = C r² + r/R + 1/L; homogeneous as in the damped-sine test.
    R, L, C, I0, W = 2.0, 0.5, 0.25, 0.8, 1.7
    model = lg.Model("parallel-rlc", formulation="flux")
    model.add("current_source", "I1", ("0", "n1"), I=I0 * sp.cos(W * t))
    model.add("resistor", "R1", ("n1", "0"), R=R)
    model.add("inductor", "L1", ("n1", "0"), L=L)
    model.add("capacitor", "C1", ("n1", "0"), C=C)
    res = simulate_exact(model, 12.0, initial={"lambda_n1": 0.0}, velocity={"lambda_n1": 0.0})
    s = 1j * W
    P = C * s * s + s / R + 1 / L
    r1, r2 = np.roots([C, 1 / R, 1 / L])
    lp0, dlp0 = (I0 / P).real, (I0 * s / P).real
    a = (-dlp0 + r2 * lp0) / (r1 - r2)
    b = -lp0 - a
    T = res.t
    lam = (I0 * np.exp(s * T) / P).real + (a * np.exp(r1 * T) + b * np.exp(r2 * T)).real
    assert max_err(res["lambda_n1"], lam) < EXACT_TOL * float(np.max(np.abs(lam)))


# ---------------------------------------------------------------------------
# 4. Mechanisms with several coordinates, prescribed motion
# ---------------------------------------------------------------------------


M1, M2, K1, K2 = 1.0, 2.0, 3.0, 5.0


def chain_modes():
    """M = diag(m1, m2), K = [[k1+k2, −k2], [−k2, k2]]: m1 m2 ω⁴ − (m1 k2 + m2(k1 + k2)) ω² + k1 k2 = 0;
    mode shape from the first row (k1 + k2 − ω² m1) a1 = k2 a2."""
    a, b, c = M1 * M2, M1 * K2 + M2 * (K1 + K2), K1 * K2
    disc = math.sqrt(b * b - 4 * a * c)
    return [(math.sqrt(w2), np.array([1.0, (K1 + K2 - w2 * M1) / K2])) for w2 in ((b - disc) / (2 * a), (b + disc) / (2 * a))]


@pytest.mark.parametrize("mode", [0, 1], ids=["slow mode", "fast mode"])
def test_two_mass_chain_started_in_a_normal_mode_is_a_pure_cosine(mode):
    model = lg.Model("chain")
    model.add("spring", "k1", ("ground", "n1"), k=K1)
    model.add("mass", "m1", "n1", m=M1)
    model.add("spring", "k2", ("n1", "n2"), k=K2)
    model.add("mass", "m2", "n2", m=M2)
    w, shape = chain_modes()[mode]
    a = 0.2 * shape
    res = simulate_exact(model, 30 * 2 * math.pi / w, initial={"x_n1": a[0], "x_n2": a[1]},
                         velocity={"x_n1": 0.0, "x_n2": 0.0}, points=3001)
    for name, ai in zip(["x_n1", "x_n2"], a):
        assert max_err(res[name], ai * np.cos(w * res.t)) < EXACT_TOL * float(np.max(np.abs(a)))
        assert max_err(res.velocity(name), -ai * w * np.sin(w * res.t)) < EXACT_TOL * float(np.max(np.abs(a))) * w
    # the eigenvalues of F are ±iω for both modes
    eig = np.sort(np.abs(np.linalg.eigvals(state_space(model).F).imag))
    np.testing.assert_allclose(eig[::2], [wi for wi, _ in chain_modes()], rtol=1e-12)


def test_prescribed_motion_quadratic_in_time_is_an_input():
    # support s = t²; m ẍ = −k (x − s) ⇒ ẍ + ω² x = ω² t²; from rest:
    #   x = t² − 2/ω² + (2/ω²) cos ωt
    m, k = 2.0, 18.0
    w2 = k / m
    model = lg.Model("dragged")
    model.add("prescribed_motion", "drive", "support", position=t**2)
    model.add("spring", "k1", ("support", "p"), k=k)
    model.add("mass", "m1", "p", m=m)
    res = simulate_exact(model, 5.0, initial={"x_p": 0.0}, velocity={"x_p": 0.0})
    x = res.t**2 - 2 / w2 + 2 / w2 * np.cos(math.sqrt(w2) * res.t)
    assert max_err(res["x_p"], x) < EXACT_TOL * 25


def test_a_ramp_started_later_through_a_damper():
    # support s = v max(0, t − 1) —c— a —k— ground, no mass at a: c (ṡ − ẋ_a) = k x_a, ṡ = v H(t − 1).
    # Before t = 1 nothing moves; for t > 1, u = t − 1:  x_a = (c v / k)(1 − e^{−k u / c}).
    k, c, v = 4.0, 2.0, 0.5
    model = lg.Model("late ramp")
    model.add("prescribed_motion", "drive", "support", position=v * sp.Max(0, t - 1))
    model.add("damper", "c1", ("support", "a"), c=c)
    model.add("spring", "k1", ("a", "ground"), k=k)
    res = simulate_exact(model, 5.0, initial={"x_a": 0.0})
    u = np.maximum(res.t - 1, 0)
    assert max_err(res["x_a"], c * v / k * (1 - np.exp(-k * u / c))) < EXACT_TOL
    off_jump = res.t != 1.0  # ṡ jumps at t = 1 (where SymPy's H(0) = ½)
    expected_v = v * np.exp(-k * u / c) * (res.t > 1)
    assert max_err(res.velocity("x_a")[off_jump], expected_v[off_jump]) < EXACT_TOL


def test_an_impulsive_input_is_refused():
    # the same ramp written with Heaviside: SymPy's derivative carries (t − 1) δ(t − 1)
    model = lg.Model("late ramp")
    model.add("prescribed_motion", "drive", "support", position=0.5 * (t - 1) * sp.Heaviside(t - 1))
    model.add("damper", "c1", ("support", "a"), c=2.0)
    model.add("spring", "k1", ("a", "ground"), k=4.0)
    with pytest.raises(lg.ModelError, match=r"equation of x_a contains an impulse \(DiracDelta\).*Max, Min or Piecewise"):
        simulate_exact(model, 5.0, initial={"x_a": 0.0})


# ---------------------------------------------------------------------------
# 5. Against numerical integration
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("seed", [1, 2])
def test_random_rlc_ladder_agrees_with_tight_numerical_integration(seed):
    E = sp.Rational(3, 2) + sp.sin(2 * t) * sp.cos(t / 3) + sp.exp(-t / 2) * t
    model = rlc_ladder(5, seed, E)
    names = model.coordinate_names
    assert len(names) == 5 and model.first_order == []
    rng = np.random.default_rng(seed + 100)
    ic = {"initial": dict(zip(names, rng.normal(size=5))), "velocity": dict(zip(names, rng.normal(size=5)))}
    exact = simulate_exact(model, 15.0, points=601, **ic)
    ref = model.simulate(15.0, points=601, **ic, **TIGHT)
    for name in names:
        scale = float(np.max(np.abs(ref[name])))
        assert max_err(exact[name], ref[name]) < VS_SIMULATE_TOL * scale
        assert max_err(exact.velocity(name), ref.velocity(name)) < VS_SIMULATE_TOL * float(np.max(np.abs(ref.velocity(name))))
    for key in ("T", "V", "D"):
        scale = float(np.max(np.abs(getattr(ref, key))))
        assert max_err(getattr(exact, key), getattr(ref, key)) < VS_SIMULATE_TOL * scale


@pytest.mark.slow
def test_square_wave_drive_with_a_first_order_coordinate_agrees_with_integration_between_switches():
    # parallel RLC in the charge formulation (q_R1 first-order), current source 0.8 sign(sin 2t):
    # the square wave switches at t = kπ/2.  Reference: Model.simulate restarted at each switch,
    # carrying the state over, so that no step straddles a discontinuity.
    model = lg.Model("parallel-rlc-charge", formulation="charge")
    model.add("current_source", "I1", ("0", "n1"), I=0.8 * sp.sign(sp.sin(2 * t)))
    model.add("resistor", "R1", ("n1", "0"), R=2.0)
    model.add("inductor", "L1", ("n1", "0"), L=0.5)
    model.add("capacitor", "C1", ("n1", "0"), C=0.25)
    assert model.first_order == ["q_R1"]
    grid = np.linspace(0.0, 8.0, 401)
    exact = simulate_exact(model, 8.0, t_eval=grid, initial={"q_L1": 0.0, "q_R1": 0.0}, velocity={"q_L1": 0.0})
    switches = [k * math.pi / 2 for k in range(1, 6)]
    edges = [0.0, *switches, 8.0]
    state = {"q_L1": 0.0, "q_R1": 0.0}, {"q_L1": 0.0}
    for a, b in zip(edges[:-1], edges[1:]):
        inside = grid[(grid > a) & (grid < b)]
        piece = model.simulate((a, b), t_eval=[a, *inside, b], initial=state[0], velocity=state[1], **TIGHT)
        mask = (grid > a) & (grid < b)
        for name in ("q_L1", "q_R1"):
            assert max_err(exact[name][mask], piece[name][1:-1]) < VS_SIMULATE_TOL
            assert max_err(exact.velocity(name)[mask], piece.velocity(name)[1:-1]) < VS_SIMULATE_TOL
        state = {n: piece[n][-1] for n in ("q_L1", "q_R1")}, {"q_L1": piece.velocity("q_L1")[-1]}


@pytest.mark.skipif(
    "exact" not in (lg.Model.simulate.__doc__ or ""),
    reason="Model.simulate does not route method='exact' to lagrangian.linear yet",
)
def test_model_simulate_with_method_exact_is_the_exact_solution():
    m, c, k, W, F0, x0, v0 = 1.0, 0.4, 4.0, 1.5, 0.8, 0.1, 0.3
    model = oscillator(m, k, c=c, F=F0 * sp.sin(W * t))
    res = model.simulate(20.0, initial={"x_p": x0}, velocity={"x_p": v0}, method="exact")
    x, _ = damped_forced(m, c, k, F0, W, x0, v0, res.t)
    assert res.method == "exact"
    assert max_err(res["x_p"], x) < EXACT_TOL


# ---------------------------------------------------------------------------
# 6. Refusals
# ---------------------------------------------------------------------------


def _chain_in_mpmath(ms, ks, cs, F0, W, x0, times, digits=40):
    """x(t) of M x'' + C x' + K x = F0 cos(W t) e_last (x'(0) = 0) by mpmath's expm of the augmented system at
    ``digits`` digits: a reference independent of double-precision exponentials."""
    import mpmath as mp

    n = len(ms)
    with mp.workdps(digits):
        M = mp.diag([mp.mpf(m) for m in ms])
        K, C = mp.zeros(n), mp.zeros(n)
        for i in range(n):
            for mat, val in ((K, ks[i]), (C, cs[i])):
                mat[i, i] += mp.mpf(val)
                if i:
                    mat[i - 1, i - 1] += mp.mpf(val)
                    mat[i, i - 1] -= mp.mpf(val)
                    mat[i - 1, i] -= mp.mpf(val)
        Mi = mp.inverse(M)
        Z = mp.zeros(2 * n + 2)
        B, D = -Mi * K, -Mi * C
        for i in range(n):
            Z[i, n + i] = 1
            for j in range(n):
                Z[n + i, j], Z[n + i, n + j] = B[i, j], D[i, j]
            Z[n + i, 2 * n] = Mi[i, n - 1] * mp.mpf(F0)
        Z[2 * n, 2 * n + 1], Z[2 * n + 1, 2 * n] = -mp.mpf(W), mp.mpf(W)  # (cos, sin)' = W (−sin, cos)
        z0 = mp.matrix([mp.mpf(x) for x in x0] + [0] * n + [1, 0])
        states = [mp.expm(Z * mp.mpf(tt)) * z0 for tt in times]
        return np.array([[float(z[i]) for z in states] for i in range(n)])


@settings(max_examples=6, deadline=None, derandomize=True)
@given(ms=st.lists(_decades(-2, 2), min_size=3, max_size=3), ks=st.lists(_decades(-1, 3), min_size=3, max_size=3),
       cs=st.lists(_decades(-4, 1), min_size=3, max_size=3), F0=_decades(-1, 2), r=st.sampled_from([0.0, 0.37, 1.58]))
@example(ms=[0.12, 13.2, 0.00999], ks=[164.0, 0.144, 198.0], cs=[5.62, 1.39, 0.635], F0=72.4, r=0.0)
@example(ms=[0.296, 7.78, 0.00736], ks=[1740.0, 2.24, 7320.0], cs=[0.237, 10.9, 0.193], F0=43.2, r=0.0)
@example(ms=[2.33, 0.000158, 1.0], ks=[0.0279, 281.0, 1.0], cs=[7.43e-05, 0.00018, 1.0], F0=1.82, r=1.58)
@pytest.mark.slow
def test_badly_scaled_chains_under_a_constant_or_harmonic_force_are_exact(ms, ks, cs, F0, r):
    """Masses, springs and dampers drawn over four decades (a 1e-4 kg mass next to 2 kg, say): the particular
    solution of the input keeps the error at rounding, where expm of the augmented matrix lost 4e-9 to 2e-8
    of the peak on such chains (the examples; which steps it loses them on is erratic, so the output grid
    is the one those cases were found on).  Reference: the same system in mpmath at 40 digits."""
    n = 3
    M, K = np.diag(ms), np.zeros((n, n))
    for i in range(n):
        K[i, i] += ks[i]
        if i:
            K[i - 1, i - 1] += ks[i]
            K[i, i - 1] = K[i - 1, i] = -ks[i]
    w_min = math.sqrt(min(scipy.linalg.eigh(K, M, eigvals_only=True)))
    W, x0 = float(f"{r * w_min:.3g}"), [0.821, -0.309, -0.808]
    model = lg.Model("chain")
    prev = "ground"
    for i in range(n):
        model.add("mass", f"m{i}", f"p{i}", m=ms[i])
        model.add("spring", f"k{i}", (prev, f"p{i}"), k=ks[i])
        model.add("damper", f"c{i}", (prev, f"p{i}"), c=cs[i])
        prev = f"p{i}"
    model.add("force", "F", prev, F=F0 * sp.cos(W * t))
    t_end = 5 * 2 * math.pi / w_min
    times = np.linspace(0, t_end, 11)
    res = simulate_exact(model, t_end, initial={f"x_p{i}": x0[i] for i in range(n)}, t_eval=times)
    want = _chain_in_mpmath(ms, ks, cs, F0, W, x0, times)
    got = np.array([res[f"x_p{i}"] for i in range(n)])
    assert max_err(got, want) <= 1e-10 * float(np.max(np.abs(want)))


def test_a_two_dimensional_spring_pendulum_is_refused_as_nonlinear():
    model = lg.Model("spring-pendulum", dim=2)
    model.add("mass", "m1", "bob", m=1.0)
    model.add("spring", "k1", ("ground", "bob"), k=20.0, rest_length=1.0)
    model.add("gravity", "g", g=9.81)
    with pytest.raises(lg.ModelError, match=r"not linear time-invariant.*equation of x_bob is nonlinear.*model\.simulate"):
        simulate_exact(model, 1.0, initial={"x_bob": 0.4, "y_bob": -1.3})


def test_a_cubic_spring_is_refused_as_nonlinear_and_names_the_coordinate():
    model = lg.Model("duffing")
    model.add("mass", "m1", "p", m=1.0)
    model.add("cubic_spring", "s", ("ground", "p"), k=1.0, k3=0.5)
    with pytest.raises(lg.ModelError, match=r"equation of x_p is nonlinear in x_p.*depends on x_p"):
        state_space(model)


def test_a_zero_length_spring_in_two_dimensions_is_linear():
    # V = ½ k (x² + y²): two independent oscillators, x = x0 cos ωt, y = y0 cos ωt
    model = lg.Model("planar", dim=2)
    model.add("mass", "m1", "p", m=1.0)
    model.add("spring", "k1", ("ground", "p"), k=4.0)
    res = simulate_exact(model, 10.0, initial={"x_p": 0.3, "y_p": -0.2}, velocity={"x_p": 0.0, "y_p": 0.0})
    assert max_err(res["x_p"], 0.3 * np.cos(2 * res.t)) < EXACT_TOL
    assert max_err(res["y_p"], -0.2 * np.cos(2 * res.t)) < EXACT_TOL


class GrowingMass(lg.Component):
    """A mass that grows with time (a rocket in reverse): T = ½ m (1 + t/10) |v|²."""

    kind, domain, terminals = "growing_mass", "mechanical", ("node",)
    parameters = {"m": lg.Parameter("initial mass", unit="kg")}

    def contribute(self, ctx):
        v = ctx.view.velocity(self.nodes[0])
        return lg.Contribution(T=self.m * (1 + t / 10) * lg.dot(v, v) / 2)

    @classmethod
    def example(cls):
        return lg.Example("p", {"m": 1}, context=[("spring", "k", ("ground", "p"), {"k": 1})])


class PumpedSpring(lg.Component):
    """A spring whose stiffness is modulated (Mathieu): V = ½ k (1 + ε cos 2t) x²."""

    kind, domain = "pumped_spring", "mechanical"
    parameters = {"k": lg.Parameter("mean stiffness"), "eps": lg.Parameter("modulation depth", check="nonnegative")}

    def contribute(self, ctx):
        e = (ctx.view.position(self.nodes[1]) - ctx.view.position(self.nodes[0]))[0]
        return lg.Contribution(V=self.k * (1 + self.eps * sp.cos(2 * t)) * e**2 / 2)

    @classmethod
    def example(cls):
        return lg.Example(("ground", "p"), {"k": 1, "eps": 0.1}, context=[("mass", "m", "p", {"m": 1})])


@lg.hookimpl
def _register_time_varying(register):
    register(GrowingMass)
    register(PumpedSpring)


@pytest.fixture(scope="module")
def time_varying_registry():
    plugin = types.ModuleType("time_varying_plugin")
    plugin.register_component_types = _register_time_varying
    return lg.Registry(plugins={"time_varying_plugin": plugin})


def test_a_mass_that_varies_with_time_is_refused(time_varying_registry):
    model = lg.Model("growing", registry=time_varying_registry)
    model.add("growing_mass", "m1", "p", m=1.0)
    model.add("spring", "k1", ("ground", "p"), k=1.0)
    with pytest.raises(lg.ModelError, match=r"equation of x_p, the coefficient of x_p'' varies with time"):
        simulate_exact(model, 1.0, initial={"x_p": 1.0}, velocity={"x_p": 0.0})
    # Model.simulate still handles it
    assert np.all(np.isfinite(model.simulate(1.0, initial={"x_p": 1.0}, velocity={"x_p": 0.0}, points=5)["x_p"]))


def test_a_stiffness_that_varies_with_time_is_refused(time_varying_registry):
    model = lg.Model("mathieu", registry=time_varying_registry)
    model.add("mass", "m1", "p", m=1.0)
    model.add("pumped_spring", "k1", ("ground", "p"), k=1.0, eps=0.2)
    with pytest.raises(lg.ModelError, match=r"equation of x_p the coefficient of x_p varies with time.*not an input"):
        state_space(model)


def test_a_callable_force_is_refused_with_a_pointer_to_simulate():
    model = oscillator(1.0, 4.0, F=lambda time: math.sin(time))
    with pytest.raises(lg.ModelError, match=r"Python callable.*SymPy expression.*model\.simulate"):
        simulate_exact(model, 1.0, initial={"x_p": 0.0}, velocity={"x_p": 0.0})


@pytest.mark.parametrize("F", [1 / (1 + t), sp.sin(t**2), sp.tanh(t)], ids=["rational", "chirp", "tanh"])
def test_an_input_outside_the_exosystem_class_is_refused(F):
    model = oscillator(1.0, 4.0, F=F)
    with pytest.raises(lg.ModelError, match=r"equation of x_p has no exact solution.*model\.simulate"):
        simulate_exact(model, 1.0, initial={"x_p": 0.0}, velocity={"x_p": 0.0})


def test_bad_time_grids_are_refused():
    model = oscillator(1.0, 4.0)
    with pytest.raises(lg.ModelError, match="end after it starts"):
        simulate_exact(model, (2.0, 1.0))
    with pytest.raises(lg.ModelError, match="within the time span"):
        simulate_exact(model, 1.0, t_eval=[0.0, 2.0])
    with pytest.raises(lg.ModelError, match="sorted"):
        simulate_exact(model, 1.0, t_eval=[0.5, 0.1])


def test_missing_initial_conditions_default_to_zero_and_are_reported():
    with pytest.warns(lg.InitialConditionWarning, match="x_p'"):
        res = simulate_exact(oscillator(1.0, 4.0), 1.0, initial={"x_p": 1.0}, points=3)
    assert res.defaulted == ["x_p'"]


def _ladder_reference(values, amplitude, w, times):
    """Capacitor voltages of an RLC ladder from rest under ``amplitude · sin(w t)``, from its state equations
    (inductor currents i_k, capacitor voltages v_k): L_k i_k' = v_(k−1) − R_k i_k − v_k (v_(−1) the source),
    C_k v_k' = i_k − i_(k+1); the steady response (a phasor solve) plus the free response that starts the state at
    zero, by the eigenvectors of the state matrix."""
    n = len(values)
    A = np.zeros((2 * n, 2 * n))
    b = np.zeros(2 * n)
    for k, (R, L, C) in enumerate(values):
        A[k, k], A[k, n + k] = -R / L, -1 / L
        if k:
            A[k, n + k - 1] = 1 / L
        A[n + k, k] = 1 / C
        if k + 1 < n:
            A[n + k, k + 1] = -1 / C
    b[0] = amplitude / values[0][1]
    z = np.linalg.solve(1j * w * np.eye(2 * n) - A, b)
    lam, V = np.linalg.eig(A)
    c = np.linalg.solve(V, -np.imag(z))
    free = np.real((V * c) @ np.exp(lam[:, None] * times[None, :]))
    return np.imag(z[:, None] * np.exp(1j * w * times[None, :]))[n:] + free[n:]


@settings(max_examples=3, deadline=None)
@given(seed=st.integers(0, 2**16), amplitude=_decades(-2, 1), w=_decades(-1, 0.5))
def test_a_ladder_of_many_states_on_a_long_uniform_grid_is_exact(seed, amplitude, w):
    # 70 sections: 140 states, past the size up to which blocks of powers are used, and 600 uniform steps: the
    # march that advances many states at once.  Every capacitor's voltage against the state equations' solution.
    rng = np.random.default_rng(seed)
    values = [(float(f"{rng.uniform(0.2, 2.0):.3g}"), float(f"{rng.uniform(0.05, 0.5):.3g}"),
               float(f"{rng.uniform(0.1, 1.0):.3g}")) for _ in range(70)]
    model = lg.Model("ladder")
    model.add("voltage_source", "V1", ("in", "0"), E=amplitude * sp.sin(w * t))
    prev = "in"
    for k, (R, L, C) in enumerate(values):
        model.add("resistor", f"R{k}", (prev, f"m{k}"), R=R)
        model.add("inductor", f"L{k}", (f"m{k}", f"n{k}"), L=L)
        model.add("capacitor", f"C{k}", (f"n{k}", "0"), C=C)
        prev = f"n{k}"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lg.InitialConditionWarning)  # from rest
        res = simulate_exact(model, 30.0, points=601)
    reference = _ladder_reference(values, amplitude, w, res.t)
    scale = float(np.max(np.abs(reference)))
    for k in (0, 35, 69):  # q_Lk: the charge through inductor k; capacitor k holds q_Lk − q_L(k+1)
        charge = res[f"q_L{k}"] - (res[f"q_L{k + 1}"] if k + 1 < len(values) else 0.0)
        assert max_err(charge / values[k][2], reference[k]) < EXACT_TOL * scale


@settings(max_examples=40, deadline=None)
@given(n=st.integers(1, 6), scale=st.floats(-3, 2.7), stable=st.booleans(), seed=st.integers(0, 2**16))
def test_our_matrix_exponential_errs_no_more_than_scipys_against_forty_digits(n, scale, stable, seed):
    # lagrangian.numerics.propagation.expm (NumPy; what the dense exact solution uses) and scipy.linalg.expm, each
    # against mpmath's exponential at 40 digits: ours within 4× SciPy's error, plus the rounding any scaling and
    # squaring makes, a few ulps times ‖A‖ (the exponential's condition; the two choose their scalings apart, and
    # each is the better one on some matrices: 5,000 draws of this family, at most 0.36 of this bound)
    import mpmath as mp

    from lagrangian.numerics.propagation import expm

    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, n)) * 10**scale
    if stable:  # a damped system's: eigenvalues in the left half-plane
        A -= (np.abs(A).sum(axis=1).max() + 10**scale) * np.eye(n)
    with mp.workdps(40):
        exact = np.array(mp.expm(mp.matrix(A.tolist())).tolist(), dtype=float)
    assume(np.all(np.isfinite(exact)))  # e^A within a float's range
    norm = np.linalg.norm(exact, 1)
    ours = np.linalg.norm(expm(A) - exact, 1) / norm
    theirs = np.linalg.norm(scipy.linalg.expm(A) - exact, 1) / norm
    assert ours <= 4 * theirs + 8 * np.finfo(float).eps * max(1.0, np.linalg.norm(A, 1))


@settings(max_examples=20, deadline=None)
@given(n=st.integers(2, 12), scale=st.floats(-2, 1.5), seed=st.integers(0, 2**16), log_count=st.integers(1, 6))
def test_a_propagators_jump_is_the_exponential_over_the_longer_step(n, scale, seed, log_count):
    # Φ^B by squaring Φ = e^{Z h} (what the lanes of a long march multiply by) against mpmath's e^{Z h B} at 40
    # digits, for a damped system with couplings decaying over hundreds of orders (entries flushed below 1e-100 of
    # the largest): the error stays at rounding of the norm
    import mpmath as mp

    from lagrangian.numerics.propagation import Propagator

    rng = np.random.default_rng(seed)
    Z = rng.normal(size=(n, n)) * 10**scale
    Z -= (np.abs(Z).sum(axis=1).max() + 10**scale) * np.eye(n)
    h, count = 0.7 / 10**scale, 2**log_count
    with mp.workdps(40):
        exact = np.array(mp.expm(mp.matrix((Z * h * count).tolist())).tolist(), dtype=float)
    norm = np.linalg.norm(exact, 1)
    got = Propagator(Z).jump(h, count)
    assert np.linalg.norm(got - exact, 1) <= 1e-12 * norm


_signal_terms = st.tuples(
    st.sampled_from(["const", "sin", "cos", "exp"]), st.floats(-3, 3).map(lambda e: float(f"{10 ** e:.3g}")),
    st.floats(-5, 5), st.floats(-3, 3), st.integers(0, 2))


@settings(max_examples=60, deadline=None)
@given(terms=st.lists(_signal_terms, min_size=1, max_size=4))
def test_an_input_read_off_as_it_stands_is_its_expression(terms):
    # a sum of c·t^k·(1 | sin | cos | exp)(a t + b), with the values users type: its exponential terms read off the
    # expression (no expansion) give the expression's own values (SymPy's evaluation at 30 digits) at several times
    from lagrangian.numerics.exosystem import _read_off

    expr = sp.Integer(0)
    for kind, c, a, b, k in terms:
        wave = {"const": sp.Integer(1), "sin": sp.sin(a * t + b), "cos": sp.cos(a * t + b), "exp": sp.exp(-abs(a) * t + b)}[kind]
        expr += c * t**k * wave
    read = _read_off(expr)
    assert read is not None
    for tau in (0.0, 0.37, 1.9):
        got = sum(coeff * tau**k * np.exp(lam * tau) for (k, lam), coeff in read.items())
        want = complex(expr.subs(t, tau).evalf(30))
        scale = sum(abs(c) * tau**k * np.exp(abs(a) * tau + abs(b)) for _, c, a, b, k in terms)
        assert abs(got - want) <= 1e-12 * max(scale, 1.0)


@settings(max_examples=60, deadline=None)
@given(n=st.integers(1, 8), seed=st.integers(0, 2**16), skew=_decades(-2, 2), w=_decades(-2, 2),
       horizon=_decades(-1, 3))
def test_a_gap_shown_by_the_resolvent_is_there(n, seed, skew, w, horizon):
    # whenever the resolvent's norm shows every exosystem eigenvalue farther than 1/horizon from F's spectrum
    # (lagrangian.numerics.propagation._far), F's eigenvalues (LAPACK's) say so too: on damped, non-normal matrices
    # (a random similarity of condition up to 1e6) and a sine's ±iω with a constant
    from lagrangian.numerics.propagation import _far

    rng = np.random.default_rng(seed)
    D = np.diag(-rng.uniform(0.01, 3.0, n)) + np.diag(rng.normal(size=n - 1), 1) if n > 1 else -np.eye(1)
    V = np.eye(n) + skew * rng.normal(size=(n, n)) / n
    assume(np.linalg.cond(V) < 1e6)
    F = V @ D @ np.linalg.inv(V)
    lam_S = np.array([1j * w, -1j * w, 0.0])
    if _far(F, lam_S, horizon):
        assert np.min(np.abs(np.linalg.eigvals(F)[:, None] - lam_S[None, :])) > 1 / horizon


def test_a_sine_without_offset_drives_no_constant_mode():
    # SIN(0 1.7 60): the exosystem holds the rotation of the sine alone (a zero offset is no term), so a model with
    # a slow mode near zero still gets the particular solution of the sine
    from lagrangian.base.waveforms import Sine
    from lagrangian.numerics.exosystem import numeric_exosystem

    assert numeric_exosystem([Sine(0.0, 1.7, 60.0)], 0.0, 1.0).S.shape == (2, 2)
    assert numeric_exosystem([Sine(0.3, 1.7, 60.0)], 0.0, 1.0).S.shape == (3, 3)


def test_a_stiff_chain_under_a_constant_force_with_a_slow_mode_is_exact():
    # three masses of about a gram on springs from 0.139 to 3,930 N/m, a damper of 1.08 N·s/m on the first (a slow
    # mode at −0.13 1/s) and 34.1 N on the last, over 2.8 s from a displaced rest (benchmarks/robustness.py
    # --seed 61): the particular solution is used although the slow mode is near the force's constant, and the
    # run agrees with mpmath's exponential of the first-order system at 40 digits (it erred 6e-9 of the peak)
    import mpmath as mp

    ms, ks, cs, F0 = (0.00109, 0.00101, 0.00204), (0.139, 3930.0, 3760.0), (1.08, 0.0319, 0.000167), 34.1
    x0 = (0.109, -0.995, 0.534)
    model = lg.Model("stiff chain")
    prev = "ground"
    for i in range(3):
        model.add("mass", f"m{i + 1}", f"p{i + 1}", m=ms[i])
        model.add("spring", f"k{i + 1}", (prev, f"p{i + 1}"), k=ks[i])
        model.add("damper", f"c{i + 1}", (prev, f"p{i + 1}"), c=cs[i])
        prev = f"p{i + 1}"
    model.add("force", "F", prev, F=F0)
    times = np.linspace(0, 2.8, 11)
    res = simulate_exact(model, 2.8, initial={f"x_p{i + 1}": x0[i] for i in range(3)},
                         velocity={f"x_p{i + 1}": 0.0 for i in range(3)}, t_eval=times)
    with mp.workdps(40):
        M = mp.diag([mp.mpf(m) for m in ms])
        K, C = mp.zeros(3), mp.zeros(3)
        for i, (k, c) in enumerate(zip(ks, cs)):  # element i joins node i−1 (ground for the first) and node i
            for D, x in ((K, k), (C, c)):
                D[i, i] += x
                if i:
                    D[i - 1, i - 1] += x
                    D[i, i - 1] -= x
                    D[i - 1, i] -= x
        A = mp.zeros(6)
        A[:3, 3:] = mp.eye(3)
        A[3:, :3], A[3:, 3:] = -(M**-1) * K, -(M**-1) * C
        rest = mp.lu_solve(K, mp.matrix([0, 0, F0]))
        y0 = mp.matrix([*(mp.mpf(x) - rest[i] for i, x in enumerate(x0)), 0, 0, 0])
        ref = np.array([[float(rest[i] + (mp.expm(A * mp.mpf(float(s))) * y0)[i]) for s in times] for i in range(3)])
    got = np.array([res[f"x_p{i + 1}"] for i in range(3)])
    assert np.max(np.abs(got - ref)) <= 1e-10 * np.max(np.abs(ref))


def test_an_input_past_a_floats_range_is_refused_naming_the_model():
    # a force of 1e600·t (SymPy's floats hold it, a double does not): a clear error, not a ValueError from the
    # matrix exponential
    model = lg.Model("huge push")
    model.add("mass", "m", "p", m=0.3)
    model.add("spring", "k", ("ground", "p"), k=2.0)
    model.add("force", "F", "p", F=sp.Float("1e600") * t)
    with pytest.raises(lg.IntegrationError, match="'huge push'.*not finite in floating point"):
        simulate_exact(model, 1.0, initial={"x_p": 0.0}, velocity={"x_p": 0.0}, points=5)


def test_a_matrix_whose_powers_pass_a_floats_range_takes_scipys_scaling_first():
    # a mass of 3e-90 kg on a spring and damper: the state matrix holds 1e90, whose fourth power overflows before
    # any scaling; the exponential is SciPy's, which scales first, and no NaN reaches the norms of the powers
    from lagrangian.numerics.propagation import expm

    A = np.array([[0.0, 1.0], [-2.0 / 2.77e-90, -1.89 / 2.77e-90]]) * 1e-3
    with np.errstate(all="ignore"):
        np.testing.assert_array_equal(expm(A), scipy.linalg.expm(A))
