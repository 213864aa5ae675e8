"""Physics of lagrangian models against independent derivations.

Every expected value here comes from physics written out in this file: closed
forms derived by hand (derivations in the comments), or SciPy integrating an
ODE written by hand.  Nothing expected is taken from the library's own output.

Numerical thresholds are derived from the integrator tolerances: ``simulate``
uses DOP853 with ``rtol=1e-9, atol=1e-12`` by default.  DOP853 controls the
local error per step; over the few hundred steps of these runs the global
error of a well-conditioned linear oscillator stays a small multiple of
``rtol`` times the solution's scale (measured here: at most ~5e-9 for an
O(1) amplitude over ten periods, ~1e-9 typically).  We assert ``< 1e-7``
times the solution's scale: a twentyfold margin over the worst case, yet
five orders of magnitude below any modelling error (a wrong sign, a missing
factor 2, a 0.1 % wrong frequency all give errors of 1e-3 or more).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp
from scipy.integrate import quad, solve_ivp
from scipy.linalg import eigh
from scipy.special import ellipk

import lagrangian as lg

t = lg.t

#: Bound on the global error of a default-tolerance simulation, per unit of solution scale (see module docstring).
DEFAULT_TOL = 1e-7
#: Tight integration tolerances for the energy tests.
TIGHT = {"rtol": 1e-12, "atol": 1e-14}


def max_err(actual: np.ndarray, expected: np.ndarray) -> float:
    return float(np.max(np.abs(np.asarray(actual) - np.asarray(expected))))


def residual_is_zero(expr: sp.Expr) -> bool:
    return sp.simplify(sp.expand(expr)) == 0


def fn(name: str) -> sp.Expr:
    """The coordinate ``name`` as the library names it: a real function of t (``Coordinate.named``)."""
    return sp.Function(name, real=True)(t)


# ---------------------------------------------------------------------------
# Builders (plain model construction; no expected values here)
# ---------------------------------------------------------------------------


def oscillator(m, k, c=None, F=None) -> lg.Model:
    """ground —k— p (mass m), optional damper c to ground and force F on p."""
    model = lg.Model("oscillator")
    model.add("mass", "m1", "p", m=m)
    model.add("spring", "k1", ("ground", "p"), k=k)
    if c is not None:
        model.add("damper", "c1", ("ground", "p"), c=c)
    if F is not None:
        model.add("force", "f1", "p", F=F)
    return model


def series_rlc(R, L, C, E, source_nodes=("n1", "0")) -> lg.Model:
    """source (n1, 0) — R (n1, n2) — L (n2, n3) — C (n3, 0), charge formulation."""
    model = lg.Model("series-rlc", formulation="charge")
    model.add("voltage_source", "V1", source_nodes, E=E)
    model.add("resistor", "R1", ("n1", "n2"), R=R)
    model.add("inductor", "L1", ("n2", "n3"), L=L)
    model.add("capacitor", "C1", ("n3", "0"), C=C)
    return model


def parallel_rlc(R, L, C, I) -> lg.Model:
    """Current source driving I from ground into n1; R, L, C from n1 to ground; flux formulation."""
    model = lg.Model("parallel-rlc", formulation="flux")
    model.add("current_source", "I1", ("0", "n1"), I=I)
    model.add("resistor", "R1", ("n1", "0"), R=R)
    model.add("inductor", "L1", ("n1", "0"), L=L)
    model.add("capacitor", "C1", ("n1", "0"), C=C)
    return model


# ---------------------------------------------------------------------------
# 1. Equations of motion, symbolically, against hand derivations
# ---------------------------------------------------------------------------


def test_mass_spring_damper_equation_is_m_xdd_plus_c_xd_plus_k_x_equals_F():
    # L = ½ m ẋ² − ½ k x², D = ½ c ẋ², Q = F(t):
    #   d/dt(m ẋ) + k x + c ẋ = F   ⇔   m ẍ + c ẋ + k x − F = 0
    m, k, c, F0, W = sp.symbols("m k c F0 Omega", positive=True)
    F = F0 * sp.cos(W * t)
    model = oscillator(m, k, c=c, F=F)
    x = fn("x_p")
    assert model.coordinate_names == ["x_p"]
    (eq,) = model.equations
    hand = m * x.diff(t, 2) + c * x.diff(t) + k * x - F
    assert residual_is_zero(eq.lhs - eq.rhs - hand)
    # and the pieces it came from
    assert residual_is_zero(model.lagrangian - (m * x.diff(t) ** 2 / 2 - k * x**2 / 2))
    assert residual_is_zero(model.rayleigh - c * x.diff(t) ** 2 / 2)
    assert residual_is_zero(model.mass_matrix[0, 0] - m)


def test_mass_spring_equation_with_a_callable_force_keeps_it_as_a_function_of_t():
    # A Python callable force appears as an undefined function F(t) with coefficient +1 in m ẍ + k x = F(t).
    m, k = sp.symbols("m k", positive=True)
    model = oscillator(m, k, F=lambda time: math.sin(time))
    x = fn("x_p")
    (eq,) = model.equations
    residual = sp.expand(eq.lhs - eq.rhs - (m * x.diff(t, 2) + k * x))
    # what is left is −F(t) for the one undefined function that is not the coordinate
    signals = [f for f in residual.atoms(sp.core.function.AppliedUndef) if f != x]
    assert len(signals) == 1
    assert residual_is_zero(residual + signals[0])


@pytest.mark.parametrize(
    "source_nodes, sign",
    [
        # v_n1 − v_0 = E: E pushes current n1 → R → L → C → ground, i.e. along q_L1 (n2 → n3).
        (("n1", "0"), +1),
        # v_0 − v_n1 = E: the source is reversed, so it drives the loop the other way.
        (("0", "n1"), -1),
    ],
    ids=["source n1→0", "source 0→n1"],
)
def test_series_rlc_charge_equation_is_L_qdd_plus_R_qd_plus_q_over_C_equals_E(source_nodes, sign):
    # Kirchhoff's voltage law round the loop, with q the charge through L from n2 to n3
    # (= through R from n1 to n2 = through C from n3 to ground):
    #   v_n1 = ±E,  v_n1 − v_n2 = R q̇,  v_n2 − v_n3 = L q̈,  v_n3 = q / C
    #   ⇒  L q̈ + R q̇ + q / C = ±E(t)
    R, L, C, E0, W = sp.symbols("R L C E0 Omega", positive=True)
    E = E0 * sp.sin(W * t)
    model = series_rlc(R, L, C, E, source_nodes)
    assert model.coordinate_names == ["q_L1"]
    q = fn("q_L1")
    (eq,) = model.equations
    hand = L * q.diff(t, 2) + R * q.diff(t) + q / C - sign * E
    assert residual_is_zero(eq.lhs - eq.rhs - hand)
    assert residual_is_zero(model.kinetic_energy - L * q.diff(t) ** 2 / 2)
    assert residual_is_zero(model.potential_energy - q**2 / (2 * C))
    assert residual_is_zero(model.rayleigh - R * q.diff(t) ** 2 / 2)


def test_parallel_rlc_flux_equation_is_C_lamdd_plus_lamd_over_R_plus_lam_over_L_equals_I():
    # KCL at n1, current I entering from the source, v = λ̇ the node voltage:
    #   C v̇ + v / R + (1/L) ∫ v dt = I   ⇒   C λ̈ + λ̇ / R + λ / L = I(t)
    R, L, C, I0, W = sp.symbols("R L C I0 Omega", positive=True)
    I = I0 * sp.sin(W * t)
    model = parallel_rlc(R, L, C, I)
    assert model.coordinate_names == ["lambda_n1"]
    lam = fn("lambda_n1")
    (eq,) = model.equations
    hand = C * lam.diff(t, 2) + lam.diff(t) / R + lam / L - I
    assert residual_is_zero(eq.lhs - eq.rhs - hand)


# ---------------------------------------------------------------------------
# 2. Single oscillators against their closed forms
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("m, k, x0, v0", [(2.0, 8.0, 0.3, -0.5), (1.0, 1.0, 1.0, 0.0), (0.5, 12.5, 0.0, 2.0)])
def test_undamped_oscillator_is_x0_cos_wt_plus_v0_over_w_sin_wt(m, k, x0, v0):
    w = math.sqrt(k / m)
    t_end = 10 * 2 * math.pi / w  # ten periods
    res = oscillator(m, k).simulate(t_end, initial={"x_p": x0}, velocity={"x_p": v0})
    T = res.t
    scale = math.hypot(x0, v0 / w)  # amplitude
    assert max_err(res["x_p"], x0 * np.cos(w * T) + v0 / w * np.sin(w * T)) < DEFAULT_TOL * scale
    assert max_err(res.velocity("x_p"), -x0 * w * np.sin(w * T) + v0 * np.cos(w * T)) < DEFAULT_TOL * scale * w
    assert res.defaulted == []


@pytest.mark.parametrize("m, k, c", [(1.0, 4.0, 0.4), (2.0, 50.0, 3.0)])
def test_underdamped_oscillator_matches_closed_form(m, k, c):
    # m ẍ + c ẋ + k x = 0, ζ < 1:  α = c / 2m,  ω_d = √(k/m − α²)
    #   x = e^{−αt} (x0 cos ω_d t + (v0 + α x0)/ω_d sin ω_d t)
    x0, v0 = 0.7, 0.2
    alpha = c / (2 * m)
    wd = math.sqrt(k / m - alpha**2)
    res = oscillator(m, k, c=c).simulate(8.0, initial={"x_p": x0}, velocity={"x_p": v0})
    T = res.t
    B = (v0 + alpha * x0) / wd
    expected = np.exp(-alpha * T) * (x0 * np.cos(wd * T) + B * np.sin(wd * T))
    expected_v = np.exp(-alpha * T) * ((wd * B - alpha * x0) * np.cos(wd * T) - (wd * x0 + alpha * B) * np.sin(wd * T))
    assert max_err(res["x_p"], expected) < DEFAULT_TOL
    assert max_err(res.velocity("x_p"), expected_v) < DEFAULT_TOL * math.sqrt(k / m)


def test_forced_undamped_oscillator_off_resonance_matches_closed_form():
    # m ẍ + k x = F0 cos Ωt, x(0) = ẋ(0) = 0:
    #   x = F0 / (m (ω² − Ω²)) (cos Ωt − cos ωt)
    m, k, F0, W = 1.0, 9.0, 0.5, 1.3
    w = math.sqrt(k / m)
    res = oscillator(m, k, F=F0 * sp.cos(W * t)).simulate(15.0, initial={"x_p": 0.0}, velocity={"x_p": 0.0})
    expected = F0 / (m * (w**2 - W**2)) * (np.cos(W * res.t) - np.cos(w * res.t))
    assert max_err(res["x_p"], expected) < DEFAULT_TOL


def test_callable_force_gives_the_same_motion_as_the_symbolic_one():
    # Same physics (F = F0 cos Ωt), given as a Python callable: same closed form as above.
    m, k, F0, W = 1.0, 9.0, 0.5, 1.3
    w = math.sqrt(k / m)
    res = oscillator(m, k, F=lambda time: F0 * math.cos(W * time)).simulate(
        15.0, initial={"x_p": 0.0}, velocity={"x_p": 0.0}
    )
    expected = F0 / (m * (w**2 - W**2)) * (np.cos(W * res.t) - np.cos(w * res.t))
    assert max_err(res["x_p"], expected) < DEFAULT_TOL


def test_forced_oscillator_started_late_sees_the_force_at_absolute_time():
    # A span (t0, t1) starts the state at t0; the force F0 cos Ωt is evaluated at absolute t.
    # Reference: SciPy on the hand-written ODE ẍ = (F0 cos Ωt − k x)/m from the same state at t0.
    m, k, F0, W, t0, t1 = 1.0, 9.0, 0.5, 1.3, 2.0, 10.0
    res = oscillator(m, k, F=F0 * sp.cos(W * t)).simulate((t0, t1), initial={"x_p": 0.1}, velocity={"x_p": 0.0})
    assert res.t[0] == t0
    ref = solve_ivp(
        lambda s, y: [y[1], (F0 * math.cos(W * s) - k * y[0]) / m],
        (t0, t1), [0.1, 0.0], t_eval=res.t, method="DOP853", rtol=1e-12, atol=1e-14,
    )
    assert max_err(res["x_p"], ref.y[0]) < DEFAULT_TOL


# ---------------------------------------------------------------------------
# 3. Two-mass chain: normal modes
# ---------------------------------------------------------------------------

M1, M2, K1, K2 = 1.0, 2.0, 3.0, 5.0


def two_mass_chain() -> lg.Model:
    model = lg.Model("chain")
    model.add("spring", "k1", ("ground", "n1"), k=K1)
    model.add("mass", "m1", "n1", m=M1)
    model.add("spring", "k2", ("n1", "n2"), k=K2)
    model.add("mass", "m2", "n2", m=M2)
    return model


def chain_modes() -> list[tuple[float, np.ndarray]]:
    """By hand: M = diag(m1, m2), K = [[k1+k2, −k2], [−k2, k2]].

    det(K − ω² M) = 0  ⇔  m1 m2 ω⁴ − (m1 k2 + m2 (k1 + k2)) ω² + k1 k2 = 0.
    Mode shape from the first row: (k1 + k2 − ω² m1) a1 = k2 a2.
    """
    a, b, c = M1 * M2, M1 * K2 + M2 * (K1 + K2), K1 * K2
    disc = math.sqrt(b * b - 4 * a * c)
    modes = []
    for w2 in ((b - disc) / (2 * a), (b + disc) / (2 * a)):
        shape = np.array([1.0, (K1 + K2 - w2 * M1) / K2])
        modes.append((math.sqrt(w2), shape))
    return modes


def test_two_mass_chain_eigenfrequencies_from_mass_and_stiffness_matrices():
    model = two_mass_chain()
    assert model.coordinate_names == ["x_n1", "x_n2"]
    q = [fn(n) for n in model.coordinate_names]
    M = np.array(model.mass_matrix.tolist(), dtype=float)
    # linear model: f = −K q, so K = −∂f/∂q
    K = np.array((-model.forcing.jacobian(q)).tolist(), dtype=float)
    np.testing.assert_allclose(M, np.diag([M1, M2]), rtol=0, atol=1e-14)
    np.testing.assert_allclose(K, [[K1 + K2, -K2], [-K2, K2]], rtol=0, atol=1e-14)
    w_model = np.sqrt(eigh(K, M, eigvals_only=True))
    w_hand = [w for w, _ in chain_modes()]
    np.testing.assert_allclose(w_model, w_hand, rtol=1e-12)


@pytest.mark.parametrize("mode", [0, 1], ids=["slow mode", "fast mode"])
def test_two_mass_chain_started_in_a_normal_mode_moves_as_a_pure_cosine(mode):
    w, shape = chain_modes()[mode]
    amplitude = 0.2
    a = amplitude * shape
    res = two_mass_chain().simulate(
        6 * 2 * math.pi / w,
        initial={"x_n1": a[0], "x_n2": a[1]},
        velocity={"x_n1": 0.0, "x_n2": 0.0},
    )
    scale = float(np.max(np.abs(a)))
    for name, ai in zip(["x_n1", "x_n2"], a):
        assert max_err(res[name], ai * np.cos(w * res.t)) < DEFAULT_TOL * scale


# ---------------------------------------------------------------------------
# 4. Circuits against closed forms
# ---------------------------------------------------------------------------


@pytest.mark.parametrize(
    "q0, E0",
    [(2e-3, 0.0), (0.0, 1.0), (-1e-3, 2.5)],
    ids=["free response of a charged capacitor", "step from rest", "step with initial charge"],
)
def test_series_rlc_step_and_free_response_match_closed_form(q0, E0):
    # L q̈ + R q̇ + q/C = E0 (constant from t = 0), q(0) = q0, q̇(0) = 0.
    # Steady state q∞ = C E0; with α = R/2L, ω_d = √(1/LC − α²):
    #   q = C E0 + (q0 − C E0) e^{−αt} (cos ω_d t + α/ω_d sin ω_d t)      (q̇(0) = 0 ✓)
    #   i = q̇ = −(q0 − C E0) (ω0²/ω_d) e^{−αt} sin ω_d t
    R, L, C = 10.0, 0.1, 1e-3  # α = 50 /s, ω0 = 100 rad/s, ω_d = 86.6 rad/s
    alpha, w0 = R / (2 * L), 1 / math.sqrt(L * C)
    wd = math.sqrt(w0**2 - alpha**2)
    res = series_rlc(R, L, C, E0).simulate(0.15, initial={"q_L1": q0}, velocity={"q_L1": 0.0})
    T = res.t
    env = np.exp(-alpha * T)
    expected = C * E0 + (q0 - C * E0) * env * (np.cos(wd * T) + alpha / wd * np.sin(wd * T))
    expected_i = -(q0 - C * E0) * (w0**2 / wd) * env * np.sin(wd * T)
    scale = max(abs(q0), abs(C * E0))
    assert max_err(res["q_L1"], expected) < DEFAULT_TOL * scale
    assert max_err(res.velocity("q_L1"), expected_i) < DEFAULT_TOL * scale * w0


def parallel_rlc_closed_form(R, L, C, I0, W, T):
    """λ and v = λ̇ for C λ̈ + λ̇/R + λ/L = I0 sin Ωt (Ω > 0) or I0 (Ω = 0, a step), from rest.

    Particular solution: for the step λ_p = L I0 (all the current in the inductor);
    for the sinusoid λ_p = P sin Ωt + Q cos Ωt with a = 1/L − CΩ², b = Ω/R:
      a P − b Q = I0,  b P + a Q = 0  ⇒  P = a I0/(a² + b²),  Q = −b I0/(a² + b²).
    Homogeneous part e^{−αt}(A cos ω_d t + B sin ω_d t), α = 1/2RC, ω_d = √(1/LC − α²),
    with λ(0) = 0 ⇒ A = −λ_p(0), λ̇(0) = 0 ⇒ ω_d B − α A + λ̇_p(0) = 0.
    """
    alpha = 1 / (2 * R * C)
    wd = math.sqrt(1 / (L * C) - alpha**2)
    if W == 0:
        lp, dlp = L * I0 * np.ones_like(T), np.zeros_like(T)
        lp0, dlp0 = L * I0, 0.0
    else:
        a, b = 1 / L - C * W**2, W / R
        P, Q = a * I0 / (a * a + b * b), -b * I0 / (a * a + b * b)
        lp, dlp = P * np.sin(W * T) + Q * np.cos(W * T), W * (P * np.cos(W * T) - Q * np.sin(W * T))
        lp0, dlp0 = Q, W * P
    A = -lp0
    B = (alpha * A - dlp0) / wd
    env = np.exp(-alpha * T)
    lam = lp + env * (A * np.cos(wd * T) + B * np.sin(wd * T))
    v = dlp + env * ((wd * B - alpha * A) * np.cos(wd * T) - (wd * A + alpha * B) * np.sin(wd * T))
    return lam, v


@pytest.mark.parametrize("W", [0.0, 0.7, 3.0], ids=["current step", "sinusoid below resonance", "sinusoid above resonance"])
def test_parallel_rlc_flux_formulation_matches_closed_form(W):
    R, L, C, I0 = 2.0, 0.5, 0.25, 0.8  # α = 1 /s, ω0 = 2.83 rad/s
    I = I0 * sp.sin(W * t) if W else sp.Float(I0)
    res = parallel_rlc(R, L, C, I).simulate(12.0, initial={"lambda_n1": 0.0}, velocity={"lambda_n1": 0.0})
    lam, v = parallel_rlc_closed_form(R, L, C, I0, W, res.t)
    scale = float(np.max(np.abs(lam)))
    assert max_err(res["lambda_n1"], lam) < DEFAULT_TOL * scale
    assert max_err(res.velocity("lambda_n1"), v) < DEFAULT_TOL * float(np.max(np.abs(v)))


def test_parallel_rlc_sinusoidal_steady_state_node_voltage_amplitude_and_phase():
    # Phasors: V = I / Y with Y = 1/R + j(ΩC − 1/(ΩL)); after the transient (e^{−αt}, α = 1/2RC)
    # has decayed, v(t) = |I0/Y| sin(Ωt − arg Y).
    R, L, C, I0, W = 2.0, 0.5, 0.25, 0.8, 1.7
    Y = 1 / R + 1j * (W * C - 1 / (W * L))
    alpha = 1 / (2 * R * C)
    t0 = 30 / alpha  # transient down by e^{-30} ≈ 1e-13
    T = np.linspace(t0, t0 + 2 * 2 * math.pi / W, 401)
    res = parallel_rlc(R, L, C, I0 * sp.sin(W * t)).simulate(
        (0.0, T[-1]), t_eval=T, initial={"lambda_n1": 0.0}, velocity={"lambda_n1": 0.0}
    )
    v = I0 / abs(Y) * np.sin(W * T - np.angle(Y))
    assert max_err(res.velocity("lambda_n1"), v) < DEFAULT_TOL * 10 * I0 / abs(Y)  # 60 s of integration: 10× margin


def test_series_rlc_in_flux_formulation_gives_the_same_capacitor_voltage():
    # Same circuit and closed form as the charge-formulation step test (q0 = 0): the capacitor voltage
    # v_C = q / C = C E0 [1 − e^{−αt}(cos ω_d t + α/ω_d sin ω_d t)] / C.  In the flux formulation the
    # capacitor (n3 → ground) is a tree branch, so its node's flux rate λ̇_n3 is v_C; the resistor's
    # flux λ_R1 (no capacitance across it) is first-order.
    R, L, C, E0 = 10.0, 0.1, 1e-3, 1.0
    model = lg.Model("series-rlc-flux", formulation="flux")
    model.add("voltage_source", "V1", ("n1", "0"), E=E0)
    model.add("resistor", "R1", ("n1", "n2"), R=R)
    model.add("inductor", "L1", ("n2", "n3"), L=L)
    model.add("capacitor", "C1", ("n3", "0"), C=C)
    assert sorted(model.coordinate_names) == ["lambda_R1", "lambda_n3"]
    assert model.first_order == ["lambda_R1"]
    res = model.simulate(0.15, initial={"lambda_n3": 0.0, "lambda_R1": 0.0}, velocity={"lambda_n3": 0.0})
    alpha, w0 = R / (2 * L), 1 / math.sqrt(L * C)
    wd = math.sqrt(w0**2 - alpha**2)
    T = res.t
    vC = E0 * (1 - np.exp(-alpha * T) * (np.cos(wd * T) + alpha / wd * np.sin(wd * T)))
    i = C * E0 * (w0**2 / wd) * np.exp(-alpha * T) * np.sin(wd * T)  # = q̇
    assert max_err(res.velocity("lambda_n3"), vC) < DEFAULT_TOL * E0
    assert max_err(res.velocity("lambda_R1"), R * i) < DEFAULT_TOL * E0  # Ohm: v_R = R i


def test_parallel_rlc_in_charge_formulation_gives_the_same_branch_currents():
    # Same circuit and closed form as the flux-formulation step test: the inductor current is λ/L and the
    # resistor current v/R.  Charge formulation: the capacitor is the tree, R1 and L1 are chords, so
    # q̇_L1 and q̇_R1 are those currents (n1 → ground); q_R1 is first-order.
    R, L, C, I0 = 2.0, 0.5, 0.25, 0.8
    model = lg.Model("parallel-rlc-charge", formulation="charge")
    model.add("current_source", "I1", ("0", "n1"), I=I0)
    model.add("resistor", "R1", ("n1", "0"), R=R)
    model.add("inductor", "L1", ("n1", "0"), L=L)
    model.add("capacitor", "C1", ("n1", "0"), C=C)
    assert sorted(model.coordinate_names) == ["q_L1", "q_R1"]
    assert model.first_order == ["q_R1"]
    res = model.simulate(12.0, initial={"q_L1": 0.0, "q_R1": 0.0}, velocity={"q_L1": 0.0})
    lam, v = parallel_rlc_closed_form(R, L, C, I0, 0.0, res.t)
    assert max_err(res.velocity("q_L1"), lam / L) < DEFAULT_TOL * I0
    assert max_err(res.velocity("q_R1"), v / R) < DEFAULT_TOL * I0


# ---------------------------------------------------------------------------
# 5. Energy
# ---------------------------------------------------------------------------


def hand_energy_drift(E: np.ndarray, T: np.ndarray, V: np.ndarray) -> float:
    """max |E − E(0)| relative to the energy scale of the motion (max of |T|, |V|, |E0|)."""
    scale = max(abs(E[0]), float(np.max(np.abs(T))), float(np.max(np.abs(V))))
    return float(np.max(np.abs(E - E[0])) / scale)


SPRING_PENDULUM = {"m": 1.0, "k": 20.0, "l0": 1.0, "g": 9.81}


def spring_pendulum(dim: int, c: float | None = None) -> lg.Model:
    """A bob on a spring of rest length ℓ0 hung from ground, under gravity; optionally a damper alongside."""
    p = SPRING_PENDULUM
    model = lg.Model("spring-pendulum", dim=dim)
    model.add("mass", "m1", "bob", m=p["m"])
    model.add("spring", "k1", ("ground", "bob"), k=p["k"], rest_length=p["l0"])
    if c is not None:
        model.add("damper", "c1", ("ground", "bob"), c=c)
    model.add("gravity", "g", g=p["g"])
    return model


def spring_pendulum_state(res, dim):
    """Position and velocity arrays (dim × n) of the bob."""
    axes = "xyz"[:dim]
    return (np.array([res[f"{a}_bob"] for a in axes]), np.array([res.velocity(f"{a}_bob") for a in axes]))


def spring_pendulum_energy(r, v):
    """By hand: T = ½ m |ṙ|², V = ½ k (|r| − ℓ0)² + m g r_last (gravity along minus the last axis)."""
    p = SPRING_PENDULUM
    T = p["m"] * np.sum(v**2, axis=0) / 2
    V = p["k"] * (np.linalg.norm(r, axis=0) - p["l0"]) ** 2 / 2 + p["m"] * p["g"] * r[-1]
    return T, V


PENDULUM_START = {
    2: ({"x_bob": 0.4, "y_bob": -1.3}, {"x_bob": 0.5, "y_bob": 0.0}),
    3: ({"x_bob": 0.4, "y_bob": 0.2, "z_bob": -1.3}, {"x_bob": 0.0, "y_bob": 0.8, "z_bob": 0.0}),
}


@pytest.mark.parametrize("dim", [2, 3])
def test_spring_pendulum_with_gravity_conserves_energy(dim):
    initial, velocity = PENDULUM_START[dim]
    res = spring_pendulum(dim).simulate(10.0, initial=initial, velocity=velocity, **TIGHT)
    r, v = spring_pendulum_state(res, dim)
    T, V = spring_pendulum_energy(r, v)
    # the trajectory is genuinely nonlinear: the spring length varies by a good fraction of ℓ0 and the bob swings
    assert np.ptp(np.linalg.norm(r, axis=0)) > 0.2 and np.ptp(r[0]) > 0.5
    assert hand_energy_drift(T + V, T, V) < 1e-8
    # the library's energies are the same functions of the state
    np.testing.assert_allclose(res.T, T, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(res.V, V, rtol=1e-12, atol=1e-12)
    assert res.energy_drift() < 1e-8


@pytest.mark.parametrize("formulation, name", [("charge", "q_L1"), ("flux", "lambda_n1")])
def test_lc_tank_conserves_energy(formulation, name):
    # ω = 1/√(LC); energy ½ L i² + q²/2C (charge) or ½ C v² + λ²/2L (flux).
    L, C = 0.5, 2e-3
    model = lg.Model("lc", formulation=formulation)
    model.add("inductor", "L1", ("n1", "0"), L=L)
    model.add("capacitor", "C1", ("n1", "0"), C=C)
    assert model.coordinate_names == [name]
    w = 1 / math.sqrt(L * C)
    res = model.simulate(20 * 2 * math.pi / w, initial={name: 1e-3}, velocity={name: 0.05}, **TIGHT)
    x, xd = res[name], res.velocity(name)
    if formulation == "charge":
        T, V = L * xd**2 / 2, x**2 / (2 * C)
    else:
        T, V = C * xd**2 / 2, x**2 / (2 * L)
    assert hand_energy_drift(T + V, T, V) < 1e-8
    np.testing.assert_allclose(res.E, T + V, rtol=1e-12)


def damped_oscillator_run(t_end, n):
    m, k, c = 1.0, 4.0, 0.5
    res = oscillator(m, k, c=c).simulate(t_end, initial={"x_p": 1.0}, velocity={"x_p": 0.0}, points=n, **TIGHT)
    x, xd = res["x_p"], res.velocity("x_p")
    # by hand: E = ½ m ẋ² + ½ k x²; dissipated power ẋ ∂D/∂ẋ = c ẋ² = 2D
    return res, m * xd**2 / 2 + k * x**2 / 2, c * xd**2


def damped_pendulum_run(t_end, n):
    c = 0.3
    initial, velocity = PENDULUM_START[2]
    res = spring_pendulum(2, c=c).simulate(t_end, initial=initial, velocity=velocity, points=n, **TIGHT)
    r, v = spring_pendulum_state(res, 2)
    T, V = spring_pendulum_energy(r, v)
    # by hand: the damper resists the rate of change of its length, ṡ = r·ṙ/|r|; power c ṡ² = 2D
    sdot = np.sum(r * v, axis=0) / np.linalg.norm(r, axis=0)
    return res, T + V, c * sdot**2


@pytest.mark.parametrize("run", [damped_oscillator_run, damped_pendulum_run], ids=["1-D oscillator", "2-D spring pendulum"])
def test_energy_loss_equals_integrated_dissipation(run):
    # Lagrange with Rayleigh: d/dt (T + V) = −Σ q̇ ∂D/∂q̇ = −2D (D quadratic in q̇, scleronomic, unforced),
    # so E(0) − E(t) = ∫₀ᵗ 2D dt'.
    t_end, n = 10.0, 20001
    res, E, P = run(t_end, n)
    np.testing.assert_allclose(res.D, P / 2, rtol=1e-10, atol=1e-14)  # the library's D is the same function
    h = t_end / (n - 1)
    lost = np.concatenate([[0.0], np.cumsum((P[1:] + P[:-1]) * h / 2)])  # trapezoid rule
    # Composite trapezoid error: Σ h³/12 P''(ξ_i) ≈ (h²/12) ∫ P'' dt, bounded by (h²/12) ∫ |P''| dt, with P''
    # estimated by finite differences on the same grid (~5e-7 for h = 5e-4 here; we allow a factor 2 for the
    # estimate).  The integration error (rtol 1e-12) and round-off are orders of magnitude smaller.
    P2 = np.abs(np.gradient(np.gradient(P, h), h))
    bound = h * h / 12 * float(np.sum(P2) * h)
    assert 1e-9 < bound < 1e-5
    assert max_err(E[0] - E, lost) < 2 * bound
    # the dissipated energy is far above the tolerance, so a wrong D (a factor 2, a wrong rate) cannot pass
    assert lost[-1] > 1e4 * bound


# ---------------------------------------------------------------------------
# 6. Symbolic parameters
# ---------------------------------------------------------------------------


def test_symbolic_parameters_stay_symbolic_and_are_required_for_simulation():
    m, k, c = sp.symbols("m k c", positive=True)
    model = oscillator(m, k, c=c)
    x = fn("x_p")
    assert {m, k} <= model.lagrangian.free_symbols
    assert c in model.rayleigh.free_symbols
    assert residual_is_zero(model.lagrangian - (m * x.diff(t) ** 2 / 2 - k * x**2 / 2))
    assert model.parameters == [c, k, m]
    with pytest.raises(lg.ModelError, match="symbolic parameters"):
        model.simulate(1.0, initial={"x_p": 1.0}, velocity={"x_p": 0.0})
    with pytest.raises(lg.ModelError, match=r"without values: c\b"):
        model.simulate(1.0, initial={"x_p": 1.0}, velocity={"x_p": 0.0}, params={"m": 1.0, "k": 4.0})


@pytest.mark.parametrize("values", [{"m": 1.0, "k": 4.0, "c": 0.4}, {"m": 2.0, "k": 50.0, "c": 3.0}])
def test_symbolic_model_with_params_matches_numeric_model_and_closed_form(values):
    m, k, c = sp.symbols("m k c", positive=True)
    ic = {"initial": {"x_p": 0.7}, "velocity": {"x_p": 0.2}}
    sym = oscillator(m, k, c=c).simulate(5.0, params=values, **ic)
    num = oscillator(values["m"], values["k"], c=values["c"]).simulate(5.0, **ic)
    np.testing.assert_allclose(sym["x_p"], num["x_p"], rtol=0, atol=1e-12)
    # independent: the underdamped closed form (see test_underdamped_oscillator_matches_closed_form)
    alpha = values["c"] / (2 * values["m"])
    wd = math.sqrt(values["k"] / values["m"] - alpha**2)
    expected = np.exp(-alpha * sym.t) * (0.7 * np.cos(wd * sym.t) + (0.2 + alpha * 0.7) / wd * np.sin(wd * sym.t))
    assert max_err(sym["x_p"], expected) < DEFAULT_TOL


def test_symbolic_circuit_parameters_and_symbolic_source_amplitude():
    R, L, C, E0 = sp.symbols("R L C E0", positive=True)
    model = series_rlc(R, L, C, E0)
    assert model.parameters == [C, E0, L, R]
    vals = {"R": 10.0, "L": 0.1, "C": 1e-3, "E0": 1.0}
    res = model.simulate(0.15, params=vals, initial={"q_L1": 0.0}, velocity={"q_L1": 0.0})
    alpha, w0 = vals["R"] / (2 * vals["L"]), 1 / math.sqrt(vals["L"] * vals["C"])
    wd = math.sqrt(w0**2 - alpha**2)
    qinf = vals["C"] * vals["E0"]
    expected = qinf * (1 - np.exp(-alpha * res.t) * (np.cos(wd * res.t) + alpha / wd * np.sin(wd * res.t)))
    assert max_err(res["q_L1"], expected) < DEFAULT_TOL * qinf


# ---------------------------------------------------------------------------
# 7. Prescribed motion and gravity
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("v", [0.5, -2.0])
def test_mass_dragged_by_a_spring_from_a_support_moving_at_constant_speed(v):
    # support at s(t) = v t; m ẍ = −k (x − v t).  With u = x − v t: ü = −ω² u, u(0) = 0, u̇(0) = −v
    #   ⇒ u = −(v/ω) sin ωt,  x = v t − (v/ω) sin ωt,  ẋ = v (1 − cos ωt)
    m, k = 2.0, 18.0
    w = math.sqrt(k / m)
    model = lg.Model("dragged")
    model.add("prescribed_motion", "drive", "support", position=v * t)
    model.add("spring", "k1", ("support", "p"), k=k)
    model.add("mass", "m1", "p", m=m)
    assert model.coordinate_names == ["x_p"]  # the support has no coordinate
    res = model.simulate(10.0, initial={"x_p": 0.0}, velocity={"x_p": 0.0})
    scale = abs(v) * 10.0
    assert max_err(res["x_p"], v * res.t - v / w * np.sin(w * res.t)) < DEFAULT_TOL * scale
    assert max_err(res.velocity("x_p"), v * (1 - np.cos(w * res.t))) < DEFAULT_TOL * scale


def test_prescribed_sinusoidal_base_motion_gives_the_base_excitation_response():
    # support s = S sin Ωt; m ẍ = −k (x − s), from rest:
    #   x = S ω²/(ω² − Ω²) (sin Ωt − (Ω/ω) sin ωt)
    m, k, S, W = 1.0, 16.0, 0.1, 1.5
    w = math.sqrt(k / m)
    model = lg.Model("base")
    model.add("prescribed_motion", "drive", "support", position=S * sp.sin(W * t))
    model.add("spring", "k1", ("support", "p"), k=k)
    model.add("mass", "m1", "p", m=m)
    res = model.simulate(12.0, initial={"x_p": 0.0}, velocity={"x_p": 0.0})
    expected = S * w**2 / (w**2 - W**2) * (np.sin(W * res.t) - W / w * np.sin(w * res.t))
    assert max_err(res["x_p"], expected) < DEFAULT_TOL


@pytest.mark.parametrize(
    "m, k, g, direction, u",
    [
        (2.0, 50.0, 9.81, None, -1),  # default: −x in 1-D
        (0.5, 3.0, 1.62, None, -1),
        (1.0, 10.0, 9.81, [3.0], +1),  # a given direction is normalized: [3] is the unit vector +x
        (1.0, 10.0, 9.81, [-0.5], -1),
    ],
)
def test_hanging_mass_sags_by_m_g_over_k_along_gravity(m, k, g, direction, u):
    # 1-D: gravity along u = ±1, V = ½ k x² − m g u x ⇒ equilibrium x* = u m g / k.
    # Released at rest from x = 0 it oscillates about x*: x = x* (1 − cos ωt).
    model = lg.Model("hanging")
    model.add("spring", "k1", ("ground", "p"), k=k)
    model.add("mass", "m1", "p", m=m)
    if direction is None:
        model.add("gravity", "g", g=g)
    else:
        model.add("gravity", "g", g=g, direction=direction)
    x = fn("x_p")
    xstar = u * m * g / k
    assert abs(float(model.forcing[0].subs(x, xstar))) < 1e-12  # equilibrium
    assert float(model.forcing[0].subs(x, 0)) == pytest.approx(u * m * g, rel=1e-12)  # the weight, along u
    res = model.simulate(5.0, initial={"x_p": 0.0}, velocity={"x_p": 0.0})
    w = math.sqrt(k / m)
    assert max_err(res["x_p"], xstar * (1 - np.cos(w * res.t))) < DEFAULT_TOL * abs(xstar)
    # started at equilibrium it stays there
    still = model.simulate(5.0, initial={"x_p": xstar}, velocity={"x_p": 0.0})
    assert max_err(still["x_p"], xstar) < 1e-12


@pytest.mark.parametrize(
    "dim, direction, unit",
    [
        (2, None, (0, -1)),  # default: minus the last axis
        (3, None, (0, 0, -1)),
        (2, [1.0, 1.0], (2**-0.5, 2**-0.5)),  # normalized
        (3, [0.0, -2.0, 0.0], (0, -1, 0)),
    ],
)
def test_free_fall_follows_g_t_squared_over_2_along_gravity(dim, direction, unit):
    # No spring: r(t) = ½ g û t² from rest at the origin, whatever the mass.
    g = 9.81
    model = lg.Model("fall", dim=dim)
    model.add("mass", "m1", "p", m=1.5)
    if direction is None:
        model.add("gravity", "g", g=g)
    else:
        model.add("gravity", "g", g=g, direction=direction)
    names = model.coordinate_names
    assert names == [f"{a}_p" for a in "xyz"[:dim]]
    res = model.simulate(2.0, initial={n: 0.0 for n in names}, velocity={n: 0.0 for n in names})
    for n, ui in zip(names, unit):
        assert max_err(res[n], ui * g * res.t**2 / 2) < DEFAULT_TOL * g * 2


# ---------------------------------------------------------------------------
# 8. First-order coordinates
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("R, C, E", [(1e3, 1e-3, 5.0), (2.0, 0.5, -1.0)])
def test_rc_charging_is_first_order_and_exponential(R, C, E):
    # source (n1, 0), R (n1, n2), C (n2, 0).  The normal tree takes the source and the capacitor, so the
    # coordinate is the charge q_R1 that has flowed n1 → n2 through R1 — the charge stored on C1 (n2 → ground).
    # KVL: E = R q̇ + q / C, q(0) = 0  ⇒  q = C E (1 − e^{−t/RC}),  i = q̇ = (E/R) e^{−t/RC}
    model = lg.Model("rc", formulation="charge")
    model.add("voltage_source", "V1", ("n1", "0"), E=E)
    model.add("resistor", "R1", ("n1", "n2"), R=R)
    model.add("capacitor", "C1", ("n2", "0"), C=C)
    assert model.coordinate_names == ["q_R1"]
    assert model.first_order == ["q_R1"]
    tau = R * C
    res = model.simulate(6 * tau, initial={"q_R1": 0.0})
    assert res.defaulted == []  # a first-order coordinate has no initial velocity to give
    expected = C * E * (1 - np.exp(-res.t / tau))
    assert max_err(res["q_R1"], expected) < DEFAULT_TOL * abs(C * E)
    assert max_err(res.velocity("q_R1"), E / R * np.exp(-res.t / tau)) < DEFAULT_TOL * abs(E / R)


def test_spring_and_damper_in_series_with_a_mass_matches_hand_written_ode():
    # ground —k— a —c— p (mass m).  Node a is massless, so force balance there is
    #   k x_a = c (ẋ_p − ẋ_a)   ⇒   ẋ_a = ẋ_p − (k/c) x_a         (first order)
    # and the mass feels the damper force, equal to the spring force:
    #   m ẍ_p = −c (ẋ_p − ẋ_a) = −k x_a
    m, k, c = 1.0, 4.0, 0.8
    model = lg.Model("maxwell")
    model.add("spring", "k1", ("ground", "a"), k=k)
    model.add("damper", "c1", ("a", "p"), c=c)
    model.add("mass", "m1", "p", m=m)
    assert sorted(model.coordinate_names) == ["x_a", "x_p"]
    assert model.first_order == ["x_a"]
    xa0, xp0, vp0 = 0.1, 0.3, 1.0

    def rhs(_, y):
        xa, xp, vp = y
        return [vp - k / c * xa, vp, -k * xa / m]

    res = model.simulate(10.0, initial={"x_a": xa0, "x_p": xp0}, velocity={"x_p": vp0})
    ref = solve_ivp(rhs, (0, 10.0), [xa0, xp0, vp0], t_eval=res.t, method="DOP853", rtol=1e-12, atol=1e-14)
    assert ref.success
    assert max_err(res["x_a"], ref.y[0]) < DEFAULT_TOL
    assert max_err(res["x_p"], ref.y[1]) < DEFAULT_TOL
    assert max_err(res.velocity("x_p"), ref.y[2]) < DEFAULT_TOL
    assert max_err(res.velocity("x_a"), ref.y[2] - k / c * ref.y[0]) < DEFAULT_TOL


@pytest.mark.parametrize("v", [0.5, -1.5])
def test_massless_node_dragged_through_a_damper_by_a_moving_support(v):
    # support s = v t —c— a —k— ground, no mass at a: c (ṡ − ẋ_a) = k x_a, x_a(0) = 0
    #   ⇒ x_a = (c v / k)(1 − e^{−k t / c})  (the damper force c v is balanced by the spring at steady state)
    k, c = 4.0, 2.0
    model = lg.Model("dragged-damper")
    model.add("prescribed_motion", "drive", "support", position=v * t)
    model.add("damper", "c1", ("support", "a"), c=c)
    model.add("spring", "k1", ("a", "ground"), k=k)
    assert model.coordinate_names == ["x_a"]
    assert model.first_order == ["x_a"]
    res = model.simulate(5.0, initial={"x_a": 0.0})
    xs = c * v / k
    assert max_err(res["x_a"], xs * (1 - np.exp(-k * res.t / c))) < DEFAULT_TOL * abs(xs)
    assert max_err(res.velocity("x_a"), v * np.exp(-k * res.t / c)) < DEFAULT_TOL * abs(v)


# ---------------------------------------------------------------------------
# 9. Third-party plugin: the cubic (Duffing) spring
# ---------------------------------------------------------------------------


def duffing_period(m, k, k3, A) -> float:
    """T = 4 ∫₀ᴬ dx / √(2 (V(A) − V(x)) / m),  V = ½ k x² + ¼ k3 x⁴.

    x = A sin θ removes the endpoint singularity: V(A) − V(x) = (A² − x²)(k/2 + k3 (A² + x²)/4)
    and A² − x² = A² cos²θ, dx = A cos θ dθ, so
      T = 4 ∫₀^{π/2} dθ / √((k + k3 A² (1 + sin²θ) / 2) / m),   a smooth integrand.
    """
    integrand = lambda th: 1.0 / math.sqrt((k + k3 * A * A * (1 + math.sin(th) ** 2) / 2) / m)  # noqa: E731
    value, err = quad(integrand, 0.0, math.pi / 2, epsabs=1e-14, epsrel=1e-13)
    assert err < 1e-12
    return 4 * value


def test_duffing_quadrature_agrees_with_elliptic_integral_closed_form():
    # Cross-check of the reference itself: T = 4 √(m/(k + k3 A²)) K(μ), μ = k3 A² / (2 (k + k3 A²)).
    m, k, k3, A = 1.3, 2.0, 5.0, 0.9
    mu = k3 * A * A / (2 * (k + k3 * A * A))
    assert duffing_period(m, k, k3, A) == pytest.approx(4 * math.sqrt(m / (k + k3 * A * A)) * ellipk(mu), rel=1e-12)
    assert duffing_period(m, k, 0.0, A) == pytest.approx(2 * math.pi * math.sqrt(m / k), rel=1e-13)


def duffing_model(m, k, k3) -> lg.Model:
    model = lg.Model("duffing")
    model.add("mass", "m1", "p", m=m)
    model.add("cubic_spring", "s", ("ground", "p"), k=k, k3=k3)
    return model


def test_cubic_spring_energy_is_quadratic_plus_quartic():
    k, k3 = sp.symbols("k k3", positive=True)
    model = duffing_model(1, k, k3)
    x = fn("x_p")
    assert residual_is_zero(model.potential_energy - (k * x**2 / 2 + k3 * x**4 / 4))
    (eq,) = model.equations
    assert residual_is_zero(eq.lhs - eq.rhs - (x.diff(t, 2) + k * x + k3 * x**3))


@pytest.mark.parametrize("A", [0.1, 1.0, 2.5], ids=["small amplitude", "moderate", "strongly nonlinear"])
def test_duffing_period_from_amplitude_matches_quadrature(A):
    m, k, k3 = 1.0, 1.0, 2.0
    period = duffing_period(m, k, k3, A)
    linear = 2 * math.pi * math.sqrt(m / k)
    assert period < linear  # hardening spring: faster than linear (and for A = 2.5 by a factor ~3)
    # Released from rest at x = A: x = 0 at T/4 and 3T/4, x = −A at T/2, back to (A, 0) at T.
    checkpoints = np.array([0.25, 0.5, 0.75, 1.0]) * period
    grid = np.union1d(np.linspace(0, 3 * period, 3001), checkpoints)
    res = duffing_model(m, k, k3).simulate(
        (0.0, grid[-1]), t_eval=grid, initial={"x_p": A}, velocity={"x_p": 0.0}, **TIGHT
    )
    x = dict(zip(res.t, res["x_p"]))
    v = dict(zip(res.t, res.velocity("x_p")))
    # |x(T/4)| ≈ v_max |δT|/4 for a period error δT, so this pins the period to ~1e-9 relative.
    # With rtol = 1e-12 over three periods the integration error is ~1e-12·A (1000× margin).
    vmax = math.sqrt(2 * (k * A**2 / 2 + k3 * A**4 / 4) / m)
    tol = 1e-9 * A
    for frac, xe in [(0.25, 0.0), (0.5, -A), (0.75, 0.0), (1.0, A)]:
        assert abs(x[frac * period] - xe) < tol, frac
    assert abs(v[period]) < 1e-9 * vmax
    # and measured from the zero crossings of x over three periods (linear interpolation; ẍ = 0 at x = 0,
    # so the interpolation error is third order in the grid step)
    xs, ts = res["x_p"], res.t
    idx = np.nonzero(np.sign(xs[:-1]) != np.sign(xs[1:]))[0]
    crossings = ts[idx] - xs[idx] * (ts[idx + 1] - ts[idx]) / (xs[idx + 1] - xs[idx])
    assert len(crossings) == 6
    measured = (crossings[-1] - crossings[0]) / 2.5  # six crossings span 2.5 periods
    assert measured == pytest.approx(period, rel=1e-9)


# --- parameters written as strings -----------------------------------------------


def test_string_parameters_are_plain_symbols_and_t_is_time():
    """'E' is a symbol (not Euler's number), 'beta' a symbol (not the beta function), 't' is lagrangian.t;
    a symbol 'k' written as a string and one built with assumptions share one value."""
    m = lg.Model("strings")
    m.add("mass", "m1", "p", m="beta")
    m.add("spring", "k1", ("ground", "p"), k=sp.Symbol("k", positive=True))
    m.add("spring", "k2", ("ground", "p"), k="k")
    m.add("force", "F", "p", F="E*sin(2*t)")
    assert {s.name for s in m.parameters} == {"E", "beta", "k"}
    assert m.generalized_forces[0] == sp.Symbol("E") * sp.sin(2 * lg.t)
    # beta x'' + 2k x = E sin(2t), from rest: x = E/(beta(w^2 - 4)) (sin 2t - (2/w) sin wt), w^2 = 2k/beta
    beta, k, E = 2.0, 9.0, 0.5
    w = np.sqrt(2 * k / beta)
    res = m.simulate(5, initial={"x_p": 0}, velocity={"x_p": 0}, params={"beta": beta, "k": k, "E": E})
    exact = E / (beta * (w**2 - 4)) * (np.sin(2 * res.t) - 2 / w * np.sin(w * res.t))
    assert np.max(np.abs(res["x_p"] - exact)) < 1e-7 * np.max(np.abs(exact))


def test_a_foreign_time_symbol_is_refused():
    with pytest.raises(lg.ParameterError, match="lagrangian.t"):
        lg.Model().add("force", "F", "p", F=sp.sin(sp.Symbol("t")))


def test_progress_is_reported_monotonically_up_to_the_end():
    m = lg.Model("progress")
    m.add("mass", "m", "p", m=1)
    m.add("spring", "k", ("ground", "p"), k=1)
    seen = []  # stepped in Python (NumPy): reported at every step
    m.simulate(10, initial={"x_p": 1}, velocity={"x_p": 0}, compiled=False,
               progress=lambda now, end: seen.append((now, end)))
    times = [now for now, _ in seen]
    assert len(seen) >= 10 and times == sorted(times)
    assert seen[-1] == (10.0, 10.0)
    # DOP853's loop in C is watched from its own thread every 0.05 s: a run over in less reports its end
    # (tests/test_run_health.py has a long one reported on the way)
    seen.clear()
    m.simulate(10, initial={"x_p": 1}, velocity={"x_p": 0}, progress=lambda now, end: seen.append((now, end)))
    times = [now for now, _ in seen]
    assert times == sorted(times) and seen[-1] == (10.0, 10.0)
