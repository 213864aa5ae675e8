"""Rotational mechanics and electromechanical transducers against physics derived by hand.

Expected values come from derivations written out here: Lagrangians and
Euler–Lagrange equations built by hand with SymPy, closed-form solutions,
energy balances, and SciPy integrating ODEs written by hand.  Nothing
expected is read from the library's own output.

Conventions under test (see ``lagrangian.plugins.transducers``): a
transducer's electrical branch runs ``a → b``; a current ``i`` from ``a``
to ``b`` pushes the moving node in +x (+θ) with ``Bl·i`` (``K·i``), and a
velocity ``ẋ`` induces ``v_a − v_b = Bl·ẋ``.  The coupling term in the
Lagrangian is ``Bl·x·q̇``.

Numerical tolerances: simulations run with ``rtol`` 1e-10 or tighter; the
global error of these small, smooth, well-damped systems is then below
~1e-8 of the solution's scale, so ``1e-6`` relative assertions keep a wide
margin while a wrong sign or factor (errors of order 1) cannot pass.
"""

from __future__ import annotations

import doctest
import math

import numpy as np
import pytest
import sympy as sp
from scipy.integrate import simpson, solve_ivp

import lagrangian as lg
from lagrangian import models
from lagrangian.plugins import rotational, transducers
from lagrangian.plugins.transducers import GapClosedError, PullInError, electrostatic_equilibria, simulate_checked

t = lg.t
TIGHT = {"rtol": 1e-11, "atol": 1e-13}

pytestmark = pytest.mark.filterwarnings("ignore::lagrangian.InitialConditionWarning")


def fn(name: str) -> sp.Expr:
    """The coordinate ``name`` as the library names it: a real function of t."""
    return sp.Function(name, real=True)(t)


def is_zero(expr: sp.Expr) -> bool:
    return sp.simplify(sp.expand(expr)) == 0


def euler_lagrange(L: sp.Expr, D: sp.Expr, Q: list, coords: list) -> list[sp.Expr]:
    """d/dt ∂L/∂q̇ − ∂L/∂q + ∂D/∂q̇ − Q for each coordinate, by SymPy differentiation (independent of the library)."""
    return [sp.diff(L, q.diff(t)).diff(t) - sp.diff(L, q) + sp.diff(D, q.diff(t)) - Qi for q, Qi in zip(coords, Q)]


def assert_equations(model: lg.Model, hand: list[sp.Expr]) -> None:
    """The model's equations M q̈ − f = 0 are, one by one, the hand-derived residuals."""
    eqs = model.equations
    assert len(eqs) == len(hand)
    for eq, h in zip(eqs, hand):
        assert is_zero(eq.lhs - eq.rhs - h), (eq, h)


# ---------------------------------------------------------------------------
# rotational mechanics
# ---------------------------------------------------------------------------


def test_rotor_on_torsion_spring_with_damper_and_torque_obeys_J_thetadd_c_thetad_k_theta_tau():
    # L = ½ J θ̇² − ½ k (θ − θ₀)², D = ½ c θ̇², Q = τ(t):  J θ̈ + c θ̇ + k (θ − θ₀) = τ
    J, k, c, tau0, W, th0 = sp.symbols("J k c tau0 Omega theta0", positive=True)
    m = lg.Model("rotor")
    m.add("inertia", "J1", "disc", J=J)
    m.add("torsion_spring", "k1", ("ground", "disc"), k=k, rest_angle=th0)
    m.add("rotary_damper", "c1", ("ground", "disc"), c=c)
    m.add("torque", "tau", "disc", tau=tau0 * sp.sin(W * t))
    th = fn("theta_disc")
    assert m.coordinate_names == ["theta_disc"]
    assert is_zero(m.lagrangian - (J * th.diff(t) ** 2 / 2 - k * (th - th0) ** 2 / 2))
    assert is_zero(m.rayleigh - c * th.diff(t) ** 2 / 2)
    assert_equations(m, [J * th.diff(t, 2) + c * th.diff(t) + k * (th - th0) - tau0 * sp.sin(W * t)])


def test_torsional_oscillator_swings_at_sqrt_k_over_J():
    # J θ̈ + k θ = 0, θ(0) = θ0, θ̇(0) = 0  ⇒  θ = θ0 cos(√(k/J) t)
    J, k, th0 = 0.5, 8.0, 0.3
    m = lg.Model("torsional oscillator")
    m.add("inertia", "J1", "disc", J=J)
    m.add("torsion_spring", "k1", ("ground", "disc"), k=k)
    res = m.simulate(10, initial={"theta_disc": th0}, velocity={"theta_disc": 0}, **TIGHT)
    w = math.sqrt(k / J)
    assert np.max(np.abs(res["theta_disc"] - th0 * np.cos(w * res.t))) < 1e-8 * th0
    assert res.energy_drift() < 1e-9


def test_two_rotors_on_a_shaft_twist_at_sqrt_k_times_sum_of_inverse_inertias():
    # Free-free J1 —k— J2: with zero total angular momentum the twist φ = θ2 − θ1 obeys
    # φ̈ = −k (1/J1 + 1/J2) φ, and J1 θ1 + J2 θ2 stays 0.
    J1, J2, k = 1.0, 3.0, 6.0
    m = lg.Model("two rotors")
    m.add("inertia", "A", "s1", J=J1)
    m.add("inertia", "B", "s2", J=J2)
    m.add("torsion_spring", "shaft", ("s1", "s2"), k=k)
    th1 = 0.3
    th2 = -J1 * th1 / J2
    res = m.simulate(8, initial={"theta_s1": th1, "theta_s2": th2}, velocity={"theta_s1": 0, "theta_s2": 0}, **TIGHT)
    w = math.sqrt(k * (1 / J1 + 1 / J2))
    twist = res["theta_s2"] - res["theta_s1"]
    assert np.max(np.abs(twist - (th2 - th1) * np.cos(w * res.t))) < 1e-8
    assert np.max(np.abs(J1 * res["theta_s1"] + J2 * res["theta_s2"])) < 1e-9


def test_prescribed_rotation_drives_a_rotor_through_a_shaft():
    # The drive node has no coordinate; L = ½ J θ̇² − ½ k (θ − Ωt)²  ⇒  J θ̈ + k (θ − Ω t) = 0.
    J, k, W = sp.symbols("J k Omega", positive=True)
    m = lg.Model("driven rotor")
    m.add("prescribed_rotation", "drive", "motor", angle=W * t)
    m.add("torsion_spring", "shaft", ("motor", "disc"), k=k)
    m.add("inertia", "J1", "disc", J=J)
    th = fn("theta_disc")
    assert m.coordinate_names == ["theta_disc"]
    assert_equations(m, [J * th.diff(t, 2) + k * (th - W * t)])
    # numerically: θ = Ω t − (Ω/ω) sin(ω t) from rest at 0, ω = √(k/J)
    res = m.simulate(5, initial={"theta_disc": 0}, velocity={"theta_disc": 0}, params={"J": 2, "k": 8, "Omega": 3}, **TIGHT)
    assert np.max(np.abs(res["theta_disc"] - (3 * res.t - 1.5 * np.sin(2 * res.t)))) < 1e-8


def test_rotational_mistakes_are_clear_errors():
    m = lg.Model("callable drive")
    m.add("prescribed_rotation", "drive", "motor", angle=lambda time: time)
    m.add("torsion_spring", "shaft", ("motor", "disc"), k=1)
    m.add("inertia", "J1", "disc", J=1)
    with pytest.raises(lg.ModelError, match="prescribed_rotation 'drive'.*SymPy expression of t"):
        m.coordinates
    m = lg.Model("mixed node")
    m.add("inertia", "J1", "p", J=1)
    m.add("spring", "k1", ("ground", "p"), k=1)
    with pytest.raises(lg.DomainError, match="node 'p'"):
        m.coordinates
    with pytest.raises(lg.ParameterError, match="'J'"):
        lg.Model().add("inertia", "J1", "p", J=-1)


# ---------------------------------------------------------------------------
# moving coil
# ---------------------------------------------------------------------------


def loudspeaker(Re, Le, Bl, m, k, c, E, formulation="charge") -> lg.Model:
    """E (n1, 0) — Re (n1, n2) — Le (n2, n3) — coil (n3, 0; cone); cone: mass, suspension spring and damper."""
    return models.loudspeaker(Re, Le, Bl, m, k, c, E, formulation=formulation)


def test_moving_coil_lagrangian_and_equations_match_the_hand_derivation():
    # One loop: i = q̇ flows n2 → n3 through Le, then n3 → 0 through the coil (a → b), back through E and Re.
    # L = ½ Le q̇² + ½ m ẋ² − ½ k x² + Bl x q̇,  D = ½ Re q̇² + ½ c ẋ²,  Q_q = E (source drives the loop), Q_x = 0:
    #   Le q̈ + Re q̇ + Bl ẋ = E        (back-emf Bl ẋ)
    #   m ẍ + c ẋ + k x = Bl q̇         (Lorentz force Bl i)
    Re, Le, Bl, m, k, c, E0, W = sp.symbols("R_e L_e Bl m k c E0 Omega", positive=True)
    E = E0 * sp.cos(W * t)
    model = loudspeaker(Re, Le, Bl, m, k, c, E)
    q, x = fn("q_Le"), fn("x_cone")
    assert model.coordinate_names == ["q_Le", "x_cone"]
    L_hand = Le * q.diff(t) ** 2 / 2 + m * x.diff(t) ** 2 / 2 - k * x**2 / 2 + Bl * x * q.diff(t)
    D_hand = Re * q.diff(t) ** 2 / 2 + c * x.diff(t) ** 2 / 2
    assert is_zero(model.lagrangian - L_hand)
    assert is_zero(model.rayleigh - D_hand)
    written = [Le * q.diff(t, 2) + Re * q.diff(t) + Bl * x.diff(t) - E, m * x.diff(t, 2) + c * x.diff(t) + k * x - Bl * q.diff(t)]
    assert_equations(model, written)
    # Euler–Lagrange on the hand Lagrangian gives the written equations ...
    el = euler_lagrange(L_hand, D_hand, [E, 0], [q, x])
    assert all(is_zero(a - b) for a, b in zip(el, written))
    # ... and so does the other form −Bl ẋ q, which differs from Bl x q̇ by d/dt(Bl x q)
    L_other = L_hand - Bl * x * q.diff(t) - Bl * x.diff(t) * q
    el_other = euler_lagrange(L_other, D_hand, [E, 0], [q, x])
    assert all(is_zero(a - b) for a, b in zip(el_other, written))
    # the canonical momentum of the charge is the coil's flux linkage L i + Bl x
    assert is_zero(model.eq.display(model.eq.p[0]) - (Le * q.diff(t) + Bl * x))


def test_current_through_the_coil_from_a_to_b_pushes_the_node_in_plus_x():
    # A current source drives I0 from ground into n1, then n1 → 0 through the coil (a → b):
    # L = ½ m ẋ² − ½ k x² + Bl x I0  ⇒  m ẍ + k x = Bl I0, so the static deflection is +Bl I0 / k.
    Bl, m_, k, I0 = sp.symbols("Bl m k I0", positive=True)
    model = lg.Model("coil on a spring")
    model.add("current_source", "I", ("0", "n1"), I=I0)
    model.add("moving_coil", "coil", ("n1", "0", "p"), Bl=Bl)
    model.add("mass", "m", "p", m=m_)
    model.add("spring", "k", ("ground", "p"), k=k)
    x = fn("x_p")
    assert model.coordinate_names == ["x_p"]
    assert_equations(model, [m_ * x.diff(t, 2) + k * x - Bl * I0])


def test_moving_the_coil_in_plus_x_raises_v_a_above_v_b_by_Bl_times_velocity():
    # The coil's node is moved at constant speed U (prescribed motion); a resistor R closes the loop across
    # a, b.  As a generator the coil makes v_a − v_b = Bl U, so the resistor (a → b) carries +Bl U / R.
    Bl, R, U = 2.0, 4.0, 3.0
    model = lg.Model("generator")
    model.add("moving_coil", "coil", ("n1", "0", "p"), Bl=Bl)
    model.add("resistor", "R", ("n1", "0"), R=R)
    model.add("prescribed_motion", "drive", "p", position=U * t)
    assert model.first_order == model.coordinate_names  # one loop charge, no inductance
    res = model.simulate(1, points=11)
    (name,) = model.coordinate_names
    branch = model.assembly.views["electrical"].branch  # the resistor's charge in terms of the loop charge
    sign = float(sp.diff(branch["R"], fn(name)))
    assert np.allclose(sign * res.velocity(name), Bl * U / R, rtol=1e-12)


def test_moving_coil_conserves_power_along_a_simulation():
    # Electrical power into the coil (E − Re i − Le di/dt)·i, integrated: ∫(E − Re i) i dt − Δ(½ Le i²);
    # mechanical power out of it, integrated: Δ(½ m ẋ² + ½ k x²) + ∫ c ẋ² dt.  An ideal gyrator stores nothing,
    # so the two agree, and both equal ∫ Bl ẋ i dt.
    Re, Le, Bl, m, k, c = 6.0, 0.5e-3, 7.0, 0.02, 2000.0, 1.5
    f = 40.0
    model = loudspeaker(Re, Le, Bl, m, k, c, sp.sin(2 * sp.pi * f * t))
    res = model.simulate(0.1, points=8001, **TIGHT)
    i, x, v = res.velocity("q_Le"), res["x_cone"], res.velocity("x_cone")
    E = np.sin(2 * np.pi * f * res.t)
    electrical = simpson((E - Re * i) * i, x=res.t) - Le * (i[-1] ** 2 - i[0] ** 2) / 2
    mechanical = (m * (v[-1] ** 2 - v[0] ** 2) + k * (x[-1] ** 2 - x[0] ** 2)) / 2 + simpson(c * v**2, x=res.t)
    coupling = simpson(Bl * v * i, x=res.t)
    scale = simpson(np.abs(E * i), x=res.t)
    assert abs(coupling) > 0.1 * scale  # the coil does carry power
    assert abs(electrical - mechanical) < 1e-6 * scale
    assert abs(electrical - coupling) < 1e-6 * scale


def test_without_losses_the_stored_energy_is_T_plus_V():
    # Le, coil, mass, spring: the conserved Jacobi integral is ½ Le i² + ½ m ẋ² + ½ k x²; the coupling term
    # Bl x i is the gyroscopic part G of L = T − V + G, which stores nothing, so res.T + res.V is that energy.
    Le, Bl, m, k = 0.5, 1.5, 2.0, 3.0
    model = lg.Model("lossless")
    model.add("inductor", "Le", ("n1", "0"), L=Le)
    model.add("moving_coil", "coil", ("n1", "0", "p"), Bl=Bl)
    model.add("mass", "m", "p", m=m)
    model.add("spring", "k", ("ground", "p"), k=k)
    (q_name, x_name) = model.coordinate_names
    res = model.simulate(10, initial={q_name: 0, x_name: 0.2}, velocity={q_name: 0.5, x_name: 0}, **TIGHT)
    i, x, v = res.velocity(q_name), res[x_name], res.velocity(x_name)
    stored = Le * i**2 / 2 + m * v**2 / 2 + k * x**2 / 2
    assert np.allclose(res.T + res.V, stored, rtol=0, atol=1e-12)
    assert np.allclose(res.E, stored, rtol=0, atol=1e-12)
    assert np.max(np.abs(stored - stored[0])) < 1e-8 * stored[0]
    assert np.ptp(Bl * x * i) > 0.05 * stored[0]  # the correction is not negligible


def impedance_from_equations(model: lg.Model, omega: float, params: dict, source: sp.Symbol, charge: str) -> complex:
    """E/I at ω from the model's (linear) equations M q̈ = f: (−ω² M + jω C + K) Q = B E with
    C = −∂f/∂q̇, K = −∂f/∂q, B = ∂f/∂E; I = jω Q_charge."""
    eq = model.eq
    subs = {s: v for s, v in ((sp.Symbol(n, positive=True), val) for n, val in params.items())}
    M = np.array(eq.M.xreplace(subs), dtype=float)
    Cm = np.array((-eq.f.jacobian(eq.sym.v)).xreplace(subs), dtype=float)
    Km = np.array((-eq.f.jacobian(eq.sym.q)).xreplace(subs), dtype=float)
    B = np.array(eq.f.diff(source).xreplace(subs), dtype=float).reshape(-1)
    Q = np.linalg.solve(-(omega**2) * M + 1j * omega * Cm + Km, B)
    return 1 / (1j * omega * Q[eq.names.index(charge)])


LOUDSPEAKER = {"R_e": 6.0, "L_e": 0.5e-3, "Bl": 7.0, "m": 0.02, "k": 2000.0, "c": 1.5}


def closed_form_impedance(f, R_e, L_e, Bl, m, k, c):
    """Z(jω) = Re + jωLe + Bl²/(c + jωm + k/jω), from E = (Re + jωLe) I + Bl U and (c + jωm + k/jω) U = Bl I."""
    jw = 2j * np.pi * f
    return R_e + jw * L_e + Bl**2 / (c + jw * m + k / jw)


def test_loudspeaker_impedance_from_the_model_equations_matches_the_closed_form():
    Re, Le, Bl, m, k, c, E = sp.symbols("R_e L_e Bl m k c E", positive=True)
    model = loudspeaker(Re, Le, Bl, m, k, c, E)
    fs = math.sqrt(LOUDSPEAKER["k"] / LOUDSPEAKER["m"]) / (2 * math.pi)
    for f in (10.0, 30.0, fs, 80.0, 500.0, 5000.0):
        z = impedance_from_equations(model, 2 * math.pi * f, LOUDSPEAKER, E, "q_Le")
        assert z == pytest.approx(closed_form_impedance(f, **LOUDSPEAKER), rel=1e-12)
    # the peak is at the mechanical resonance and worth Re + Bl²/c
    zs = impedance_from_equations(model, 2 * math.pi * fs, LOUDSPEAKER, E, "q_Le")
    assert zs.real == pytest.approx(LOUDSPEAKER["R_e"] + LOUDSPEAKER["Bl"] ** 2 / LOUDSPEAKER["c"], rel=1e-12)
    near = [abs(impedance_from_equations(model, 2 * math.pi * f, LOUDSPEAKER, E, "q_Le")) for f in (0.95 * fs, 1.05 * fs)]
    assert abs(zs) > max(near)


@pytest.mark.parametrize("f", [50.329, 120.0])
def test_loudspeaker_steady_state_impedance_from_simulation(f):
    # Drive E = sin(ωt) from rest; the slowest transient decays like e^{−250 t}; fit i(t) over the last two periods.
    model = loudspeaker(**{"Re": 6.0, "Le": 0.5e-3, "Bl": 7.0, "m": 0.02, "k": 2000.0, "c": 1.5}, E=sp.sin(2 * sp.pi * f * t))
    w, period = 2 * np.pi * f, 1 / f
    cycles = math.ceil(0.15 / period)
    t_fit = np.linspace((cycles - 2) * period, cycles * period, 200)
    res = model.simulate((0, cycles * period), t_eval=t_fit, method="LSODA", rtol=1e-10, atol=1e-13)
    basis = np.column_stack([np.cos(w * t_fit), np.sin(w * t_fit)])
    (a, b), *_ = np.linalg.lstsq(basis, res.velocity("q_Le"), rcond=None)
    z = -1j / (a - 1j * b)  # phasors: sin(ωt) ↔ −j, a cos + b sin ↔ a − jb
    assert z == pytest.approx(closed_form_impedance(f, **LOUDSPEAKER), rel=1e-6)


def test_moving_coil_refuses_what_it_cannot_model():
    with pytest.raises(lg.ModelError, match=r"moving_coil 'coil'.*flux formulation.*formulation='charge'"):
        loudspeaker(6, 1e-3, 7, 0.02, 2000, 1.5, 1, formulation="flux").equations
    m = lg.Model("planar", dim=2)
    m.add("voltage_source", "E", ("n1", "0"), E=1)
    m.add("inductor", "L", ("n1", "n2"), L=1)
    m.add("moving_coil", "coil", ("n2", "0", "p"), Bl=1)
    m.add("mass", "m", "p", m=1)
    with pytest.raises(lg.ModelError, match=r"moving_coil 'coil' acts along one axis.*dim=1"):
        m.equations
    with pytest.raises(lg.ModelError, match=r"moving_coil 'coil'.*moving terminal 'p' is ground"):
        lg.Model().add("moving_coil", "coil", ("n1", "n2", "0"), Bl=1)
    with pytest.raises(lg.DomainError, match="node 'n2'"):
        m = lg.Model()
        m.add("moving_coil", "coil", ("n1", "0", "n2"), Bl=1)
        m.add("inductor", "L", ("n1", "n2"), L=1)
        m.coordinates


# ---------------------------------------------------------------------------
# DC motor
# ---------------------------------------------------------------------------


def dc_motor(V, R, La, K, J, b) -> lg.Model:
    m = lg.Model("dc motor")
    m.add("voltage_source", "V", ("n1", "0"), E=V)
    m.add("resistor", "R", ("n1", "n2"), R=R)
    if La is None:
        m.add("dc_motor", "M", ("n2", "0", "shaft"), K=K)
    else:
        m.add("inductor", "La", ("n2", "n3"), L=La)
        m.add("dc_motor", "M", ("n3", "0", "shaft"), K=K)
    m.add("inertia", "J", "shaft", J=J)
    m.add("rotary_damper", "b", ("ground", "shaft"), c=b)
    return m


def test_dc_motor_equations_match_the_hand_derivation():
    # L = ½ La q̇² + ½ J θ̇² + K θ q̇, D = ½ R q̇² + ½ b θ̇², Q_q = V:
    #   La q̈ + R q̇ + K θ̇ = V,   J θ̈ + b θ̇ = K q̇
    V, R, La, K, J, b = sp.symbols("V R L_a K J b", positive=True)
    model = dc_motor(V, R, La, K, J, b)
    q, th = fn("q_La"), fn("theta_shaft")
    assert model.coordinate_names == ["q_La", "theta_shaft"]
    L_hand = La * q.diff(t) ** 2 / 2 + J * th.diff(t) ** 2 / 2 + K * th * q.diff(t)
    assert is_zero(model.lagrangian - L_hand)
    assert_equations(model, [La * q.diff(t, 2) + R * q.diff(t) + K * th.diff(t) - V, J * th.diff(t, 2) + b * th.diff(t) - K * q.diff(t)])


def test_dc_motor_spin_up_matches_the_second_order_closed_form():
    # From rest: ω = ω_ss (1 + (s2 e^{s1 t} − s1 e^{s2 t})/(s1 − s2)), s1,2 roots of La J s² + (R J + La b) s + R b + K²,
    # ω_ss = K V / (R b + K²).
    V, R, La, K, J, b = 12.0, 1.0, 0.5e-3, 0.05, 1e-4, 1e-5
    res = dc_motor(V, R, La, K, J, b).simulate(0.25, points=501, method="LSODA", **TIGHT)
    s1, s2 = np.roots([La * J, R * J + La * b, R * b + K**2])
    w_ss = K * V / (R * b + K**2)
    exact = w_ss * (1 + (s2 * np.exp(s1 * res.t) - s1 * np.exp(s2 * res.t)) / (s1 - s2))
    assert np.max(np.abs(res.velocity("theta_shaft") - exact)) < 1e-7 * w_ss
    assert res.velocity("theta_shaft")[-1] == pytest.approx(w_ss, rel=2e-3)  # 6 time constants: e^{-6}


def test_dc_motor_without_inductance_spins_up_with_the_mechanical_time_constant():
    # La = 0: i = (V − K ω)/R (first-order loop charge) and J ω̇ + b ω = K i
    #   ⇒ ω = ω_ss (1 − e^{−t/τ}),  τ = J R / (R b + K²).
    V, R, K, J, b = 6.0, 2.0, 0.1, 2e-4, 1e-5
    model = dc_motor(V, R, None, K, J, b)
    assert model.first_order == ["q_M"]
    res = model.simulate(0.5, points=201, **TIGHT)
    tau = J * R / (R * b + K**2)
    w_ss = K * V / (R * b + K**2)
    assert np.max(np.abs(res.velocity("theta_shaft") - w_ss * (1 - np.exp(-res.t / tau)))) < 1e-8 * w_ss
    # the armature current is the loop current: i = (V − K ω)/R
    assert np.allclose(res.velocity("q_M"), (V - K * res.velocity("theta_shaft")) / R, rtol=0, atol=1e-9 * V / R)


def test_dc_motor_needs_the_charge_formulation():
    with pytest.raises(lg.ModelError, match=r"dc_motor 'M'.*flux formulation.*formulation='charge'"):
        m = lg.Model("flux motor", formulation="flux")
        m.add("voltage_source", "V", ("n1", "0"), E=1)
        m.add("resistor", "R", ("n1", "n2"), R=1)
        m.add("dc_motor", "M", ("n2", "0", "shaft"), K=1)
        m.add("inertia", "J", "shaft", J=1)
        m.equations


# ---------------------------------------------------------------------------
# variable capacitor (electrostatic actuator)
# ---------------------------------------------------------------------------


def actuator(V, R, eps_A, gap, m, k, c, formulation="charge") -> lg.Model:
    """V (n1, 0) — R (n1, n2) — plate capacitor (n2, 0; plate); plate: mass, spring, damper."""
    model = lg.Model("actuator", formulation=formulation)
    model.add("voltage_source", "V", ("n1", "0"), E=V)
    model.add("resistor", "R", ("n1", "n2"), R=R)
    model.add("variable_capacitor", "Cx", ("n2", "0", "plate"), eps_A=eps_A, gap=gap)
    model.add("mass", "m", "plate", m=m)
    model.add("spring", "k", ("ground", "plate"), k=k)
    model.add("damper", "c", ("ground", "plate"), c=c)
    return model


def test_variable_capacitor_charge_formulation_matches_the_hand_derivation():
    # q: charge on the plate capacitor (the loop charge, first-order: no inductance).  C(x) = εA/(gap − x):
    # L = ½ m ẋ² − ½ k x² − q² (gap − x)/(2 εA),  D = ½ R q̇² + ½ c ẋ²,  Q_q = V:
    #   R q̇ + q (gap − x)/εA = V,   m ẍ + c ẋ + k x = q²/(2 εA)   (attraction towards the electrode, +x)
    V, R, eA, g, m, k, c = sp.symbols("V R epsA gap m k c", positive=True)
    model = actuator(V, R, eA, g, m, k, c)
    q, x = fn("q_R"), fn("x_plate")
    assert model.coordinate_names == ["q_R", "x_plate"]
    assert model.first_order == ["q_R"]
    assert is_zero(model.lagrangian - (m * x.diff(t) ** 2 / 2 - k * x**2 / 2 - q**2 * (g - x) / (2 * eA)))
    assert_equations(model, [R * q.diff(t) + q * (g - x) / eA - V, m * x.diff(t, 2) + c * x.diff(t) + k * x - q**2 / (2 * eA)])


def test_variable_capacitor_flux_formulation_matches_the_hand_derivation():
    # Current source I into node n1, conductance 1/R and the plate capacitor from n1 to ground; λ: node flux, λ̇ = v.
    # L = ½ C(x) λ̇² + ½ m ẋ² − ½ k x²,  D = λ̇²/(2R),  Q_λ = I:
    #   d/dt(C(x) λ̇) + λ̇/R = I,   m ẍ + k x = ½ C'(x) λ̇² = εA λ̇² / (2 (gap − x)²)
    I, R, eA, g, m, k = sp.symbols("I R epsA gap m k", positive=True)
    model = lg.Model("flux actuator", formulation="flux")
    model.add("current_source", "I", ("0", "n1"), I=I)
    model.add("resistor", "R", ("n1", "0"), R=R)
    model.add("variable_capacitor", "Cx", ("n1", "0", "plate"), eps_A=eA, gap=g)
    model.add("mass", "m", "plate", m=m)
    model.add("spring", "k", ("ground", "plate"), k=k)
    lam, x = fn("lambda_n1"), fn("x_plate")
    assert model.coordinate_names == ["lambda_n1", "x_plate"]
    C = eA / (g - x)
    assert is_zero(model.kinetic_energy - (C * lam.diff(t) ** 2 / 2 + m * x.diff(t) ** 2 / 2))
    assert_equations(
        model,
        [(C * lam.diff(t)).diff(t) + lam.diff(t) / R - I, m * x.diff(t, 2) + k * x - eA * lam.diff(t) ** 2 / (2 * (g - x) ** 2)],
    )


def test_variable_capacitor_moves_the_same_in_both_formulations_and_as_a_hand_written_ode():
    # A voltage step below pull-in, from rest and uncharged.  Hand ODE (charge form, see above):
    #   q̇ = (V − q (gap − x)/εA)/R,  ẍ = (q²/(2εA) − k x − c ẋ)/m
    p = {"V": 0.4, "R": 0.2, "eps_A": 1.0, "gap": 1.0, "m": 1.0, "k": 1.0, "c": 0.7}
    charge = actuator(*p.values()).simulate(15, points=301, **TIGHT)
    flux = actuator(*p.values(), formulation="flux").simulate(15, points=301, **TIGHT)

    def rhs(_, y):
        q, x, v = y
        return [(p["V"] - q * (p["gap"] - x) / p["eps_A"]) / p["R"], v, (q**2 / (2 * p["eps_A"]) - p["k"] * x - p["c"] * v) / p["m"]]

    hand = solve_ivp(rhs, (0, 15), [0, 0, 0], t_eval=charge.t, method="LSODA", rtol=1e-12, atol=1e-14)
    assert np.max(np.abs(charge["x_plate"] - hand.y[1])) < 1e-8
    assert np.max(np.abs(flux["x_plate"] - hand.y[1])) < 1e-8
    assert np.max(np.abs(charge["q_R"] - hand.y[0])) < 1e-8
    assert np.max(hand.y[1]) > 0.1  # the plate did move


@pytest.mark.parametrize(("k", "gap", "eps_A"), [(1.0, 1.0, 1.0), (5.0, 2e-3, 3e-9), (0.3, 4.0, 10.0)])
def test_pull_in_voltage_and_displacement_match_the_closed_form(k, gap, eps_A):
    # k x = εA V²/(2 (gap − x)²) has a stable root only while V ≤ V_pi = sqrt(8 k gap³/(27 εA)), where x = gap/3.
    model = actuator(1.0, 1.0, eps_A, gap, 1.0, k, 1.0)
    v_pi = math.sqrt(8 * k * gap**3 / (27 * eps_A))
    report = electrostatic_equilibria(model, "Cx", 0.5 * v_pi)
    assert report.pull_in_voltage == pytest.approx(v_pi, rel=1e-9)
    assert report.pull_in_displacement == pytest.approx(gap / 3, rel=1e-7)
    # equilibria at V < V_pi: the real roots below the gap of k x (gap − x)² − εA V²/2, the smaller one stable
    for ratio in (0.3, 0.7, 0.99):
        V = ratio * v_pi
        roots = np.roots([k, -2 * k * gap, k * gap**2, -eps_A * V**2 / 2])
        expected = sorted(r.real for r in roots if abs(r.imag) < 1e-9 * gap and r.real < gap)
        found = electrostatic_equilibria(model, "Cx", V)
        assert [e.x for e in found.equilibria] == pytest.approx(expected, rel=1e-9)
        assert [e.stable for e in found.equilibria] == [True, False]
        assert found.position == pytest.approx(expected[0], rel=1e-9)
    # existence switches at V_pi (the bisection criterion)
    assert electrostatic_equilibria(model, "Cx", (1 - 1e-6) * v_pi).stable
    assert not electrostatic_equilibria(model, "Cx", (1 + 1e-6) * v_pi).stable


def test_past_pull_in_there_is_no_stable_equilibrium_and_the_report_says_so():
    model = actuator(1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0)
    v_pi = math.sqrt(8 / 27)
    report = electrostatic_equilibria(model, "Cx", 1.2 * v_pi)
    assert report.equilibria == []
    assert "no stable equilibrium" in str(report) and f"{v_pi:.6g}" in str(report)
    with pytest.raises(PullInError, match=r"variable_capacitor 'Cx': no stable equilibrium at V = .*V_pull-in = 0\.544331") as info:
        report.position
    assert isinstance(info.value, lg.ModelError)
    # the sign of the voltage does not matter (the force goes with V²)
    assert electrostatic_equilibria(model, "Cx", -0.5).position == pytest.approx(electrostatic_equilibria(model, "Cx", 0.5).position)


def test_electrostatic_equilibria_with_symbolic_parameters_and_bad_input():
    k, g = sp.symbols("k gap", positive=True)
    model = actuator(1.0, 1.0, 1.0, g, 1.0, k, 1.0)
    report = electrostatic_equilibria(model, "Cx", 0.1, params={"k": 2.0, "gap": 0.5})
    assert report.pull_in_voltage == pytest.approx(math.sqrt(8 * 2.0 * 0.5**3 / 27), rel=1e-9)
    with pytest.raises(lg.ModelError, match="without values: gap, k"):
        electrostatic_equilibria(model, "Cx", 0.1)
    with pytest.raises(lg.ModelError, match="'R' is a resistor, not a variable_capacitor"):
        electrostatic_equilibria(model, "R", 0.1, params={"k": 2.0, "gap": 0.5})
    free = actuator(1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0)
    free.add("mass", "m2", "other", m=1)
    free.add("spring", "k2", ("ground", "other"), k=1)
    with pytest.raises(lg.ModelError, match="one coordinate, the plate's"):
        electrostatic_equilibria(free, "Cx", 0.1)


def test_simulation_below_pull_in_settles_at_the_stable_equilibrium():
    V = 0.9 * math.sqrt(8 / 27)
    model = actuator(V, 0.1, 1.0, 1.0, 1.0, 1.0, 1.0)
    res = simulate_checked(model, 60, points=61, **TIGHT)
    roots = np.roots([1, -2, 1, -V**2 / 2])  # k x (gap − x)² = εA V²/2 with k = gap = εA = 1
    stable = min(r.real for r in roots if abs(r.imag) < 1e-12)
    assert res["x_plate"][-1] == pytest.approx(stable, rel=1e-6)


@pytest.mark.parametrize("formulation", ["charge", "flux"])
def test_simulation_past_pull_in_ends_in_a_gap_closed_error_at_the_contact_time(formulation):
    # Hand ODE with an event at x = gap gives the contact time independently.
    p = {"V": 1.05 * math.sqrt(8 / 27), "R": 0.1, "eps_A": 1.0, "gap": 1.0, "m": 1.0, "k": 1.0, "c": 1.0}
    model = actuator(*p.values(), formulation=formulation)

    def rhs(_, y):
        q, x, v = y
        return [(p["V"] - q * (p["gap"] - x) / p["eps_A"]) / p["R"], v, (q**2 / (2 * p["eps_A"]) - p["k"] * x - p["c"] * v) / p["m"]]

    def contact(_, y):
        return p["gap"] - y[1]

    contact.terminal = True
    hand = solve_ivp(rhs, (0, 40), [0, 0, 0], events=contact, method="LSODA", rtol=1e-12, atol=1e-14)
    (t_contact,) = hand.t_events[0]
    with pytest.raises(GapClosedError, match=r"variable_capacitor 'Cx': the plate reached the fixed electrode at t = ") as info:
        simulate_checked(model, 40, **TIGHT)
    assert isinstance(info.value, lg.NumericalError)
    assert info.value.component == "Cx"
    assert info.value.time == pytest.approx(t_contact, rel=1e-6)
    # up to just before contact the plain simulation is fine and closes in on the electrode ...
    res = model.simulate(0.999 * t_contact, points=3, **TIGHT)
    assert 0.9 < res["x_plate"][-1] < 1.0
    # ... while just past it, it quietly returns a plate behind the electrode, which simulate_checked refuses
    assert model.simulate(1.01 * t_contact, points=3, **TIGHT)["x_plate"][-1] > 1.0
    with pytest.raises(GapClosedError) as info:
        simulate_checked(model, 1.01 * t_contact, points=3, **TIGHT)
    assert info.value.time == pytest.approx(t_contact, rel=1e-6)


def test_simulate_checked_refuses_a_plate_that_starts_behind_the_electrode():
    model = actuator(0.1, 0.1, 1.0, 1.0, 1.0, 1.0, 1.0)
    with pytest.raises(GapClosedError, match="starts at x_plate = 1.5"):
        simulate_checked(model, 1, initial={"x_plate": 1.5})


# ---------------------------------------------------------------------------
# solenoid (variable inductance)
# ---------------------------------------------------------------------------


def test_solenoid_charge_formulation_matches_the_hand_derivation():
    # L(x) = L0/(1 + x/x0).  L = ½ L(x) q̇² + ½ m ẋ² − ½ k x², D = ½ R q̇², Q_q = V:
    #   d/dt(L(x) q̇) + R q̇ = V,   m ẍ + k x = ½ L'(x) q̇² = −L0 q̇² / (2 x0 (1 + x/x0)²)
    V, R, L0, x0, m, k = sp.symbols("V R L0 x0 m k", positive=True)
    model = lg.Model("solenoid")
    model.add("voltage_source", "V", ("n1", "0"), E=V)
    model.add("resistor", "R", ("n1", "n2"), R=R)
    model.add("solenoid", "S", ("n2", "0", "armature"), L0=L0, x0=x0)
    model.add("mass", "m", "armature", m=m)
    model.add("spring", "k", ("ground", "armature"), k=k)
    q, x = fn("q_S"), fn("x_armature")
    assert model.coordinate_names == ["q_S", "x_armature"]
    Lx = L0 / (1 + x / x0)
    assert is_zero(model.lagrangian - (Lx * q.diff(t) ** 2 / 2 + m * x.diff(t) ** 2 / 2 - k * x**2 / 2))
    assert_equations(
        model,
        [(Lx * q.diff(t)).diff(t) + R * q.diff(t) - V, m * x.diff(t, 2) + k * x + L0 * q.diff(t) ** 2 / (2 * x0 * (1 + x / x0) ** 2)],
    )


def test_solenoid_flux_formulation_matches_the_hand_derivation():
    # Current source I into n1, capacitor C and the solenoid from n1 to ground; λ the node flux (the coil's linkage):
    # L = ½ C λ̇² + ½ m ẋ² − λ² (1 + x/x0)/(2 L0) − ½ k x²:
    #   C λ̈ + λ (1 + x/x0)/L0 = I,   m ẍ + k x + λ²/(2 L0 x0) = 0   (the same force: λ = L(x) i)
    I, C, L0, x0, m, k = sp.symbols("I C L0 x0 m k", positive=True)
    model = lg.Model("solenoid flux", formulation="flux")
    model.add("current_source", "I", ("0", "n1"), I=I)
    model.add("capacitor", "C", ("n1", "0"), C=C)
    model.add("solenoid", "S", ("n1", "0", "armature"), L0=L0, x0=x0)
    model.add("mass", "m", "armature", m=m)
    model.add("spring", "k", ("ground", "armature"), k=k)
    lam, x = fn("lambda_n1"), fn("x_armature")
    assert model.coordinate_names == ["lambda_n1", "x_armature"]
    assert is_zero(model.potential_energy - (lam**2 * (1 + x / x0) / (2 * L0) + k * x**2 / 2))
    assert_equations(model, [C * lam.diff(t, 2) + lam * (1 + x / x0) / L0 - I, m * x.diff(t, 2) + k * x + lam**2 / (2 * L0 * x0)])


def solenoid_circuit(formulation: str) -> lg.Model:
    model = lg.Model("solenoid", formulation=formulation)
    model.add("current_source", "I", ("0", "n1"), I=sp.sin(3 * t))
    model.add("capacitor", "C", ("n1", "0"), C=0.5)
    model.add("solenoid", "S", ("n1", "0", "armature"), L0=2.0, x0=1.5)
    model.add("mass", "m", "armature", m=1.0)
    model.add("spring", "k", ("ground", "armature"), k=4.0)
    return model


def test_solenoid_moves_the_same_in_both_formulations_and_pulls_towards_smaller_x():
    # Both start at rest with no current and no charge: q_S = q̇_S = 0 ⇔ λ = λ̇ = 0.
    charge = solenoid_circuit("charge").simulate(10, points=201, **TIGHT)
    flux = solenoid_circuit("flux").simulate(10, points=201, **TIGHT)
    x = charge["x_armature"]
    assert np.max(np.abs(x - flux["x_armature"])) < 1e-8
    assert np.max(np.abs(x)) > 1e-2 and np.mean(x) < 0  # the force −½ i² L0/(x0 (1 + x/x0)²) only pulls in −x


def test_lossless_solenoid_conserves_T_plus_V():
    # No gyroscopic term here: T is the co-energy ½ L(x) i² + ½ m ẋ², and T + V is the conserved energy.
    model = lg.Model("lossless solenoid")
    model.add("capacitor", "C", ("n1", "0"), C=0.5)
    model.add("solenoid", "S", ("n1", "0", "armature"), L0=2.0, x0=1.5)
    model.add("mass", "m", "armature", m=1.0)
    model.add("spring", "k", ("ground", "armature"), k=4.0)
    (q_name, x_name) = model.coordinate_names
    res = model.simulate(10, initial={q_name: 0.5, x_name: 0.1}, velocity={q_name: 0.3, x_name: 0}, **TIGHT)
    assert res.energy_drift() < 1e-9
    assert np.ptp(res[x_name]) > 1e-2


# ---------------------------------------------------------------------------
# documentation and examples
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("module", [rotational, transducers], ids=lambda m: m.__name__)
@pytest.mark.slow
def test_plugin_docstring_examples_run(module):
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert result.attempted > 0 and result.failed == 0


def run_example(example, script: str, *args: str) -> str:
    out, where = example(script, "--out", "{dir}/chart.png", *args)
    assert (where / "chart.png").read_bytes().startswith(b"\x89PNG")
    return out


@pytest.mark.slow
def test_loudspeaker_example_finds_the_impedance_peak_at_resonance(example):
    import re

    out = run_example(example, "loudspeaker.py", "--points", "3")
    worst = float(re.search(r"max relative difference simulated vs closed-form impedance: (\S+)", out).group(1))
    assert worst < 1e-6
    peak, at = map(float, re.search(r"\|Z\| = (\S+) Ω at (\S+) Hz", out).groups())
    assert at == pytest.approx(math.sqrt(2000 / 0.02) / (2 * math.pi), rel=1e-4)
    assert peak == pytest.approx(6 + 49 / 1.5, rel=1e-4)


@pytest.mark.slow
def test_dc_motor_example_matches_its_closed_form(example):
    import re

    out = run_example(example, "dc_motor.py")
    rel = float(re.search(r"\((\S+) of ω_ss\)", out).group(1))
    assert rel < 1e-6
    assert "ω_ss = K V / (R b + K²) = 239.043825 rad/s" in out  # 0.05·12/(1e-5 + 0.0025)


@pytest.mark.slow
def test_electrostatic_pullin_example_reports_pull_in_and_contact(example):
    import re

    out = run_example(example, "electrostatic_pullin.py")
    v_pi = float(re.search(r"pull-in voltage:\s+computed (\S+),", out).group(1))
    assert v_pi == pytest.approx(math.sqrt(8 / 27), rel=1e-9)
    assert "no stable equilibrium" in out and "raises PullInError" in out
    assert "GapClosedError: variable_capacitor 'Cx': the plate reached the fixed electrode" in out
