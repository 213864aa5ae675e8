"""The frequency domain: linearization, transfer functions, impedances, frequency response and modes.

Expected values come from closed forms (series and parallel RLC, transmissibility, coupled LC tanks, a
parallelogram linkage, hand-derived H(s)) and from sympy.physics.mechanics' Linearizer.
"""

import functools
import warnings

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me
from hypothesis import given, settings
from hypothesis import strategies as st

import lagrangian as lg
from lagrangian.frequency import (decades, frequency_response, impedance, linearize, modes, s, transfer_function)

G = 9.81


def decade(lo, hi):
    """A value drawn log-uniformly between ``lo`` and ``hi``."""
    return st.floats(np.log10(lo), np.log10(hi)).map(lambda e: float(f"{10 ** e:.4g}"))


def series_rlc(R, L, C, formulation="charge"):
    m = lg.Model("series rlc", formulation=formulation)
    m.add("voltage_source", "V1", ("in", "0"), E=0)
    m.add("resistor", "R1", ("in", "a"), R=R)
    m.add("inductor", "L1", ("a", "b"), L=L)
    m.add("capacitor", "C1", ("b", "0"), C=C)
    return m


def relative(a, b):
    return np.max(np.abs(np.asarray(a) - np.asarray(b)) / np.abs(np.asarray(b)))


def roots_distance(found, expected):
    """Largest distance, relative to the root's size, from each expected root to the nearest found one (the
    same count required): round-off may order a conjugate pair either way."""
    found, expected = np.asarray(found), np.asarray(expected)
    assert len(found) == len(expected), (found, expected)
    return max((np.min(np.abs(found - r)) / abs(r) for r in expected), default=0.0)


# -- closed forms -----------------------------------------------------------------------------------------


def test_series_rlc_transfer_functions_and_impedance_are_the_hand_forms_in_symbols():
    R, L, C = sp.symbols("R L C", positive=True)
    m = series_rlc(R, L, C)
    den = L * C * s**2 + R * C * s + 1
    assert sp.simplify(transfer_function(m, "V1", "i(L1)").expr - C * s / den) == 0
    assert sp.simplify(transfer_function(m, "V1", "v(C1)").expr - 1 / den) == 0
    assert sp.simplify(transfer_function(m, "V1", "v(L1)").expr - L * C * s**2 / den) == 0
    assert sp.simplify(impedance(m, "V1").expr - (R + L * s + 1 / (C * s))) == 0


@settings(max_examples=25)
@given(decade(0.1, 1e4), decade(1e-6, 1.0), decade(1e-9, 1e-3))
@pytest.mark.slow
def test_series_rlc_impedance_poles_and_zeros_match_the_closed_form(R, L, C):
    m = series_rlc(R, L, C)
    Z = impedance(m, "V1")
    w = 1 / np.sqrt(L * C) * np.array([0.01, 0.3, 1.0, 7.0, 300.0])
    assert relative(Z(1j * w), R + 1j * w * L + 1 / (1j * w * C)) < 1e-9
    H = transfer_function(m, "V1", "v(C1)")
    roots = np.roots([L * C, R * C, 1])
    assert roots_distance(H.poles(), roots) < 1e-7
    assert len(H.zeros()) == 0 and H.dc_gain == pytest.approx(1.0, rel=1e-9)
    assert Z.dc_gain == np.inf and np.abs(Z.poles()).max() < 1e-9 * np.abs(roots).min()
    # node fluxes: the source fixes a flux linkage to ∫E dt (its integral enters); the same transfer function
    flux = transfer_function(series_rlc(R, L, C, "flux"), "V1", "v(C1)")
    assert relative(flux(1j * w), H(1j * w)) < 1e-9
    assert flux.dc_gain == pytest.approx(1.0, rel=1e-9)
    num, den = sp.fraction(flux.expr)
    assert sp.degree(den, s) == 2 and sp.degree(num, s) == 0  # the flux gauge's pole at 0 cancels exactly


@settings(max_examples=25)
@given(decade(1.0, 1e4), decade(1e-5, 1.0), decade(1e-9, 1e-3))
@pytest.mark.slow
def test_parallel_rlc_impedance_seen_by_a_current_source_in_both_formulations(R, L, C):
    w = 1 / np.sqrt(L * C) * np.array([0.02, 0.5, 1.0, 2.0, 50.0])
    closed = 1 / (1 / R + 1j * w * C + 1 / (1j * w * L))
    for formulation in ("flux", "charge"):
        m = lg.Model("parallel rlc", formulation=formulation)
        m.add("current_source", "I1", ("0", "n"), I=0)
        m.add("resistor", "R1", ("n", "0"), R=R)
        m.add("inductor", "L1", ("n", "0"), L=L)
        m.add("capacitor", "C1", ("n", "0"), C=C)
        if formulation == "charge":  # the current source's voltage is not a function of loop charges
            with pytest.raises(lg.ModelError, match="formulation='flux'"):
                impedance(m, "I1")
            continue
        assert relative(impedance(m, "I1")(1j * w), closed) < 1e-9


@settings(max_examples=25)
@given(decade(0.01, 100.0), decade(0.1, 1e5), st.floats(0.005, 3.0))
@pytest.mark.slow
def test_transmissibility_of_a_base_excited_mass_spring_damper(mass, k, zeta):
    c = 2 * zeta * np.sqrt(k * mass)
    m = lg.Model("isolator")
    m.add("prescribed_motion", "base", "b", position=0)
    m.add("mass", "m", "p", m=mass)
    m.add("spring", "k", ("b", "p"), k=k)
    m.add("damper", "c", ("b", "p"), c=c)
    wn = np.sqrt(k / mass)
    f = decades(wn / 2 / np.pi / 100, wn / 2 / np.pi * 100, 10)
    r = 2 * np.pi * f / wn
    closed = np.sqrt(1 + (2 * zeta * r) ** 2) / np.sqrt((1 - r**2) ** 2 + (2 * zeta * r) ** 2)
    resp = frequency_response(m, f, inputs=["base"], outputs=["x_p"])
    assert relative(np.abs(resp["x_p"]), closed) < 1e-9
    with pytest.raises(lg.ModelError, match="derivatives"):
        linearize(m, inputs=["base"]).state_space()  # the base drives the damper through its velocity


@settings(max_examples=20)
@given(decade(1e-6, 1.0), decade(1e-12, 1e-3), st.floats(0.01, 0.95))
@pytest.mark.slow
def test_normal_modes_of_two_inductively_coupled_lc_tanks(L, C, k):
    closed = np.sort(1 / np.sqrt(np.array([1 + k, 1 - k]) * L * C))
    for formulation in ("charge", "flux"):
        m = lg.Model("coupled tanks", formulation=formulation)
        for i in (1, 2):
            m.add("inductor", f"L{i}", (f"n{i}", "0"), L=L)
            m.add("capacitor", f"C{i}", (f"n{i}", "0"), C=C)
        m.add("coupling", "K1", inductor1="L1", inductor2="L2", k=k)
        found = modes(m)
        assert relative(found.omega, closed) < 1e-9
        assert np.all(np.abs(found.damping) < 1e-9)
        assert np.allclose(np.abs(found.shapes), 1.0, rtol=1e-9)  # in phase and in antiphase


@settings(max_examples=25)
@given(decade(1e-3, 1e3), decade(1e-3, 1e3), decade(1e-2, 1e6), decade(1e-3, 1e3))
def test_free_coordinates_are_rigid_modes_and_real_eigenvalues_are_decays_not_frequencies(m1, m2, k, c):
    """Two free masses on a spring: a rigid-body mode (λ = 0, which rounding leaves at about √ε of the other) and
    ω² = k (1/m1 + 1/m2); a free mass on a damper: a rigid mode and a decay at c/m, not "0 Hz (ζ=1)"."""
    pair = lg.Model("pair")
    pair.add("mass", "m1", "a", m=m1)
    pair.add("mass", "m2", "b", m=m2)
    pair.add("spring", "k", ("a", "b"), k=k)
    found = modes(pair)
    assert found.kinds == ["rigid", "oscillatory"]
    assert relative(found.omega[1:], np.array([np.sqrt(k * (1 / m1 + 1 / m2))])) < 1e-9
    assert repr(found).startswith("<Modes of 'pair': rigid (λ = 0), ")
    html = found._repr_html_()
    assert "<td>rigid</td>" in html and "<td>oscillatory</td>" in html and f"<td>{found.frequencies[1]:.6g}</td>" in html
    drag = lg.Model("drag")
    drag.add("mass", "m", "p", m=m1)
    drag.add("damper", "c", ("ground", "p"), c=c)
    found = modes(drag)
    assert found.kinds == ["rigid", "real"]
    assert abs(found.eigenvalues[1] + c / m1) <= 1e-9 * c / m1
    assert f"decays by e in {m1 / c:.4g} s" in repr(found)


@pytest.mark.slow
def test_parallelogram_linkage_swings_as_its_closed_form_through_its_loop_constraints():
    """Two equal cranks (uniform rods m_c, L) and a coupler (m_p) that translates: ω² = g (m_c + m_p) / (L (2/3 m_c + m_p))."""
    mc, mp, L, d = 0.35, 0.8, 0.6, 1.1
    m = lg.Model("parallelogram", dim=2)
    m.add("rod", "crank", "crank", m=mc, length=L)
    m.add("rod", "coupler", "coupler", m=mp, length=d)
    m.add("rod", "rocker", "rocker", m=mc, length=L)
    m.add("revolute", "A", ("ground", "crank"), absolute=True)
    m.add("revolute", "B", ("crank", "coupler"), parent_point=(L, 0), absolute=True)
    m.add("revolute", "D", ("ground", "rocker"), parent_point=(d, 0), absolute=True)
    m.add("revolute", "C", ("coupler", "rocker"), parent_point=(d, 0), child_point=(L, 0))
    m.add("gravity", "g", g=G)
    assert len(m.eq.constraints) == 2
    hanging = {"theta_A": -np.pi / 2, "theta_B": 0.0, "theta_D": -np.pi / 2}
    found = modes(m, at=hanging)
    assert len(found.omega) == 1
    assert found.omega[0] == pytest.approx(np.sqrt(G * (mc + mp) / (L * (2 / 3 * mc + mp))), rel=1e-10)
    lin = linearize(m, hanging)
    A, B, C, D, states = lin.state_space()  # in independent coordinates: one angle and its rate
    assert len(states) == 2 and states[0] in lin.coordinates and states[1] == states[0] + "'"
    assert np.sort(np.abs(np.linalg.eigvals(A))) == pytest.approx([found.omega[0]] * 2, rel=1e-10)
    assert np.allclose(lin.independent().Phi.shape, (0, 1))
    # a force on the coupler: the state space in independent coordinates and the exact Laplace form agree
    m.add("force", "F", "coupler", F=(0, 0))
    driven = linearize(m, hanging, inputs=["F[0]"], outputs=["theta_A", "theta_D'"])
    A, B, C, D, _ = driven.state_space()
    for out, row in (("theta_A", 0), ("theta_D'", 1)):
        H = transfer_function(driven, "F[0]", out)
        for w in (0.5, 3.0, 20.0):
            ss = (C @ np.linalg.solve(1j * w * np.eye(len(A)) - A, B) + D)[row, 0]
            assert H(1j * w) == pytest.approx(ss, rel=1e-10)
    with pytest.raises(lg.ModelError, match="kinematic loops"):
        linearize(m, {**hanging, "theta_B": 0.2})


def test_symbolic_transfer_function_of_a_two_mass_chain_equals_the_hand_derived_one():
    m1, m2, k1, k2, c2 = sp.symbols("m1 m2 k1 k2 c2", positive=True)
    m = lg.Model("two masses")
    m.add("mass", "M1", "p1", m=m1)
    m.add("mass", "M2", "p2", m=m2)
    m.add("spring", "K1", ("ground", "p1"), k=k1)
    m.add("spring", "K2", ("p1", "p2"), k=k2)
    m.add("damper", "C2", ("p1", "p2"), c=c2)
    m.add("force", "F", "p2", F=0)
    # (m1 s² + c2 s + k1 + k2) X1 − (c2 s + k2) X2 = 0;  −(c2 s + k2) X1 + (m2 s² + c2 s + k2) X2 = F
    a, b, c = m1 * s**2 + c2 * s + k1 + k2, c2 * s + k2, m2 * s**2 + c2 * s + k2
    det = a * c - b**2
    assert sp.simplify(transfer_function(m, "F", "x_p2").expr - a / det) == 0
    assert sp.simplify(transfer_function(m, "F", "x_p1").expr - b / det) == 0
    assert sp.simplify(transfer_function(m, "F", "x_p1''").expr - s**2 * b / det) == 0


@settings(max_examples=15)
@given(decade(0.05, 20.0), decade(0.05, 20.0), decade(1.0, 1e4), decade(1e-3, 10.0))
@pytest.mark.slow
def test_a_model_given_numbers_and_its_symbolic_twin_linearize_alike(m1, m2, k, c):
    def build(values):
        m = lg.Model("chain")
        m.add("mass", "M1", "p1", m=values[0])
        m.add("mass", "M2", "p2", m=values[1])
        m.add("spring", "K", ("p1", "p2"), k=values[2])
        m.add("spring", "K0", ("ground", "p1"), k=values[2])
        m.add("damper", "C", ("ground", "p2"), c=values[3])
        m.add("force", "F", "p1", F=0)
        return m

    names = sp.symbols("m1 m2 k c", positive=True)
    numeric = linearize(build([m1, m2, k, c]), inputs=["F"], outputs=["x_p2", "x_p1'"])
    symbolic = linearize(build(names), inputs=["F"], outputs=["x_p2", "x_p1'"])
    assert symbolic.symbolic and not numeric.symbolic
    given = dict(zip(names, (m1, m2, k, c)))
    for mine, theirs in ((numeric.M, symbolic.M), (numeric.C, symbolic.C), (numeric.K, symbolic.K),
                         (numeric.B[0], symbolic.B[0]), (numeric.Cq[1], symbolic.Cq[1])):
        assert np.allclose(mine, np.array(theirs.subs(given), dtype=float), rtol=1e-12, atol=0)
    valued = linearize(build(names), inputs=["F"], outputs=["x_p2", "x_p1'"], params={"m1": m1, "m2": m2, "k": k, "c": c})
    assert not valued.symbolic and np.allclose(valued.K, numeric.K, rtol=1e-14)


# -- against sympy.physics.mechanics ----------------------------------------------------------------------


def kane_cart_double_pendulum(Mc, m1, L1, m2, L2):
    x, q1, q2 = me.dynamicsymbols("x q1 q2")
    u0, u1, u2 = me.dynamicsymbols("u0 u1 u2")
    F = me.dynamicsymbols("F")
    N = me.ReferenceFrame("N")
    O = me.Point("O")
    O.set_vel(N, 0)
    P0 = O.locatenew("P0", x * N.x)
    P0.set_vel(N, u0 * N.x)
    A1 = N.orientnew("A1", "Axis", (q1, N.z))
    A1.set_ang_vel(N, u1 * N.z)
    A2 = N.orientnew("A2", "Axis", (q2, N.z))
    A2.set_ang_vel(N, u2 * N.z)
    P1 = P0.locatenew("P1", L1 * A1.x)
    P1.v2pt_theory(P0, N, A1)
    P2 = P1.locatenew("P2", L2 * A2.x)
    P2.v2pt_theory(P1, N, A2)
    particles = [me.Particle("cart", P0, Mc), me.Particle("b1", P1, m1), me.Particle("b2", P2, m2)]
    loads = [(P0, F * N.x - Mc * G * N.y), (P1, -m1 * G * N.y), (P2, -m2 * G * N.y)]
    km = me.KanesMethod(N, q_ind=[x, q1, q2], u_ind=[u0, u1, u2], kd_eqs=[x.diff() - u0, q1.diff() - u1, q2.diff() - u2])
    km.kanes_equations(particles, loads)
    return km, (x, q1, q2, u0, u1, u2)


@pytest.mark.parametrize("side", [-1, 1], ids=["hanging", "inverted"])
@pytest.mark.slow
def test_cart_with_a_double_pendulum_linearizes_as_sympy_mechanics_linearizer(side):
    angle = side * np.pi / 2
    Mc, m1, L1, m2, L2 = 1.7, 0.4, 0.8, 0.25, 0.55
    m = lg.Model("cart double pendulum", dim=2)
    m.add("body", "cart", "cart", m=Mc, inertia=0.1)
    m.add("prismatic", "rail", ("ground", "cart"))
    m.add("link", "a1", "a1", points={"tip": (L1, 0)})
    m.add("link", "a2", "a2", points={"tip": (L2, 0)})
    m.add("revolute", "j1", ("cart", "a1"), absolute=True)
    m.add("revolute", "j2", ("a1", "a2"), parent_point=(L1, 0), absolute=True)
    m.add("mass", "b1", "a1.tip", m=m1)
    m.add("mass", "b2", "a2.tip", m=m2)
    m.add("force", "F", "cart", F=(0, 0))
    m.add("gravity", "g", g=G)
    lin = linearize(m, {"theta_j1": angle, "theta_j2": angle}, inputs=["F[0]"], outputs=["s_rail"])
    A, B, C, D, states = lin.state_space()
    assert states[:3] == ["s_rail", "theta_j1", "theta_j2"]
    km, (x, q1, q2, u0, u1, u2) = kane_cart_double_pendulum(Mc, m1, L1, m2, L2)
    op = {x: 0, q1: side * sp.pi / 2, q2: side * sp.pi / 2, u0: 0, u1: 0, u2: 0}  # exact: floats leave u̇ terms
    Ak, Bk = km.to_linearizer().linearize(op_point=op, A_and_B=True, simplify=False)
    Ak, Bk = np.array(Ak.evalf(), dtype=float), np.array(Bk.evalf(), dtype=float)
    # the same coordinates (cart position, absolute angles): the same matrices
    assert np.allclose(A, Ak, rtol=1e-12, atol=1e-12 * np.abs(Ak).max())
    assert np.allclose(B, Bk, rtol=1e-12, atol=1e-12 * np.abs(Bk).max())
    H = transfer_function(lin, "F[0]", "s_rail")
    for w in (0.3, 2.0, 11.0):
        theirs = np.linalg.solve(1j * w * np.eye(6) - Ak, Bk)[0, 0]
        assert H(1j * w) == pytest.approx(theirs, rel=1e-10)
    assert np.allclose(np.sort_complex(np.linalg.eigvals(A)), np.sort_complex(np.linalg.eigvals(Ak)), atol=1e-9)


# -- state space, outputs, errors -------------------------------------------------------------------------


def test_state_space_of_a_mass_spring_damper_and_of_a_first_order_circuit():
    m = lg.Model("msd")
    m.add("mass", "m", "p", m=0.3)
    m.add("spring", "k", ("ground", "p"), k=40.0)
    m.add("damper", "c", ("ground", "p"), c=0.5)
    m.add("force", "F", "p", F=0)
    A, B, C, D, states = linearize(m, inputs=["F"], outputs=["x_p", "x_p'", "x_p''"]).state_space()
    assert states == ["x_p", "x_p'"]
    assert np.allclose(A, [[0, 1], [-40 / 0.3, -0.5 / 0.3]], rtol=1e-14)
    assert np.allclose(B, [[0], [1 / 0.3]], rtol=1e-14)
    assert np.allclose(C, [[1, 0], [0, 1], [-40 / 0.3, -0.5 / 0.3]], rtol=1e-14)
    assert np.allclose(D, [[0], [0], [1 / 0.3]], rtol=1e-14)
    rc = lg.Model("rc")
    rc.add("voltage_source", "V1", ("in", "0"), E=5)
    rc.add("resistor", "R1", ("in", "a"), R=2.2e3)
    rc.add("capacitor", "C1", ("a", "0"), C=4.7e-6)
    lin = linearize(rc, at={"q_R1": 5 * 4.7e-6}, inputs=["V1"], outputs=["v(C1)"])
    assert lin.first_order == ["q_R1"] and lin.y0["v(C1)"] == pytest.approx(5.0, rel=1e-12)
    A, B, C, D, _ = lin.state_space()
    tau = 2.2e3 * 4.7e-6
    assert A[0, 0] == pytest.approx(-1 / tau, rel=1e-12) and (C @ B)[0, 0] == pytest.approx(1 / tau, rel=1e-12)


def test_a_point_that_is_not_an_equilibrium_is_refused_naming_the_coordinate():
    m = lg.Model("pendulum", dim=2)
    m.add("rod", "r", "r", m=0.3, length=0.7)
    m.add("revolute", "j", ("ground", "r"), absolute=True)
    m.add("gravity", "g", g=G)
    with pytest.raises(lg.ModelError, match=r"not at rest.*theta_j"):
        linearize(m, {"theta_j": -1.0})
    bottom = modes(m, at={"theta_j": -np.pi / 2})
    assert bottom.omega[0] == pytest.approx(np.sqrt(3 * G / (2 * 0.7)), rel=1e-12)  # a rod: ω² = 3g / 2l
    top = modes(m, at={"theta_j": np.pi / 2})
    assert top.eigenvalues.real.max() == pytest.approx(bottom.omega[0], rel=1e-12)  # unstable: a real positive root


def test_values_a_parameter_refuses_are_refused_as_simulate_refuses_them():
    R = sp.Symbol("R", positive=True)
    m = series_rlc(R, 7e-3, 2.2e-6)
    with pytest.raises(lg.ParameterError, match=r"'R1'.*positive"):
        frequency_response(m, [1e3], inputs=["V1"], outputs=["v(C1)"], params={"R": -10.0})
    with pytest.raises(lg.ParameterError, match=r"'L1'.*positive"):
        linearize(series_rlc(10.0, 7e-3, 2.2e-6), params={"L_L1": -7e-3})
    with pytest.raises(lg.ParameterError, match=r"'R1'.*positive"):
        m.simulate(1e-3, params={"R": -10.0})


def test_bad_names_and_values_get_clear_errors():
    m = series_rlc(10.0, 7e-3, 2.2e-6)
    with pytest.raises(lg.UnknownNameError, match="V2"):
        linearize(m, inputs=["V2"])
    with pytest.raises(lg.ModelError, match="signal"):
        linearize(m, inputs=["R1"])
    with pytest.raises(lg.UnknownNameError, match="q_L2"):
        linearize(m, outputs=["q_L2"])
    with pytest.raises(lg.ParameterError, match="no such quantity"):
        linearize(m, outputs=["w(R1)"])
    with pytest.raises(lg.UnknownNameError, match="q_x"):
        linearize(m, at={"q_x": 1.0})
    with pytest.raises(lg.ModelError, match="finite"):
        linearize(m, at={"q_L1": float("nan")})
    with pytest.raises(lg.ModelError, match="frequencies"):
        frequency_response(m, "1k")
    with pytest.raises(lg.ModelError, match="dec sweep needs 0 < start < stop"):
        decades(100, 10)
    symbolic = series_rlc(*sp.symbols("R L C", positive=True))
    with pytest.raises(lg.ModelError, match="params="):
        modes(symbolic)
    with pytest.raises(lg.ModelError, match="vector"):
        linearize(lg_force_2d(), inputs=["F"])


def lg_force_2d():
    m = lg.Model("plane", dim=2)
    m.add("mass", "m", "p", m=1.0)
    m.add("spring", "k", ("ground", "p"), k=1.0)
    m.add("force", "F", "p", F=(0, 0))
    return m


def test_responses_carry_units_for_their_charts():
    m = lg.Model("msd")
    m.add("mass", "m", "p", m=0.3)
    m.add("spring", "k", ("ground", "p"), k=40.0)
    m.add("force", "F", "p", F=0)
    resp = frequency_response(m, [1.0, 2.0], outputs=["x_p", "x_p'", "x_p''"])
    assert [resp.unit(o, "F") for o in resp.outputs] == ["m/N", "m/(s N)", "m/(s² N)"]
    rlc = frequency_response(series_rlc(10.0, 7e-3, 2.2e-6), [1.0], outputs=["v(C1)", "i(L1)", "q_L1"])
    assert [rlc.unit(o, "V1") for o in rlc.outputs] == ["V/V", "A/V", "C/V"]
    assert frequency_response(series_rlc(10.0, 7e-3, 2.2e-6), [1.0], outputs=[sp.Symbol("z") * 0]).unit("0", "V1") == ""


R_, L_, C_ = sp.symbols("R L C", positive=True)


@settings(max_examples=20)
@given(decade(1e-2, 1e4), decade(1e-6, 1.0), decade(1e-12, 1e-3))
def test_a_symbolic_transfer_functions_poles_zeros_and_gain_are_closed_forms(R, L, C):
    """A series RLC with symbols: the poles of v(C)/V are the quadratic formula's, valued at numbers drawn over
    decades they are the roots of L s² + R s + 1/C (NumPy's, from its companion matrix); i/V has a zero at s = 0,
    and gain 1/L."""
    H = transfer_function(series_rlc(R_, L_, C_), "V1", "v(C1)")
    values = {R_: R, L_: L, C_: C}
    poles = np.sort_complex(np.array([complex(p.subs(values)) for p in H.poles()]))
    expected = np.sort_complex(np.roots([L, R, 1 / C]).astype(complex))
    assert np.allclose(poles, expected, rtol=1e-9, atol=1e-12 * np.abs(expected).max())
    assert H.zeros() == [] and sp.simplify(H.gain - 1 / (L_ * C_)) == 0
    current = transfer_function(series_rlc(R_, L_, C_), "V1", "i(L1)")
    assert current.zeros() == [0] and sp.simplify(current.gain - 1 / L_) == 0


@functools.lru_cache(maxsize=1)
def _symbolic_rlc_responses():
    """The series RLC's v(C)/V step and impulse responses with symbols R, L, C (derived once)."""
    H = transfer_function(series_rlc(R_, L_, C_), "V1", "v(C1)")
    return H.step_response(), H.impulse_response()


@settings(max_examples=15)
@given(decade(1.0, 1e3), decade(1e-4, 1e-1), decade(1e-9, 1e-4))
def test_step_and_impulse_responses_in_closed_form_are_the_exact_solution(R, L, C):
    """A series RLC over decades (under- and overdamped): v(C) after a unit step of V1, and after a unit impulse
    (which leaves the loop's current at 1/L), in closed form from the transfer function (in numbers, and with
    symbols valued afterwards) against the exact solution of the circuit by the matrix exponential."""
    w0, alpha = 1 / np.sqrt(L * C), R / (2 * L)
    slowest = alpha if alpha < w0 else alpha - np.sqrt(alpha**2 - w0**2)
    times = np.linspace(0, 8 / slowest, 41)
    symbolic = dict(zip(("step", "impulse"), _symbolic_rlc_responses()))
    for kind in ("step", "impulse"):
        circuit = lg.Model("series rlc")
        circuit.add("voltage_source", "V1", ("in", "0"), E=1.0 if kind == "step" else 0.0)
        circuit.add("resistor", "R1", ("in", "a"), R=R)
        circuit.add("inductor", "L1", ("a", "b"), L=L)
        circuit.add("capacitor", "C1", ("b", "0"), C=C)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", lg.InitialConditionWarning)
            run = circuit.simulate(times[-1], t_eval=times, method="exact",
                                   velocity={"q_L1": 0.0 if kind == "step" else 1 / L})
        exact = run["q_L1"] / C
        scale = np.abs(exact).max()
        H = transfer_function(series_rlc(R, L, C), "V1", "v(C1)")
        closed = H.step_response() if kind == "step" else H.impulse_response()
        got = sp.lambdify(lg.t, closed, "numpy")(times)
        assert np.abs(got - exact).max() <= 1e-8 * scale, kind
        valued = symbolic[kind].subs({R_: R, L_: L, C_: C})
        got = np.real(sp.lambdify(lg.t, valued, "numpy")(times + 0j))
        assert np.abs(got - exact).max() <= 1e-8 * scale, kind


@settings(max_examples=15)
@given(decade(1e-3, 1e3), decade(1e-2, 1e6))
def test_a_root_locus_is_the_roots_of_the_characteristic_polynomial_at_each_value(m, k):
    """A mass on a spring and a damper, the damping swept over six decades around critical: at each value the
    poles are the roots of m s² + c s + k (their polynomial's coefficients, to 1e-9); the chart draws every one."""
    from lagrangian.frequency import pole_zero_map, root_locus
    import matplotlib.pyplot as plt

    osc = lg.Model("oscillator")
    osc.add("mass", "m", "p", m=m)
    osc.add("spring", "k", ("ground", "p"), k=k)
    osc.add("damper", "c", ("ground", "p"), c=1.0)
    cs = 2 * np.sqrt(k * m) * np.geomspace(1e-3, 1e3, 13)
    locus = root_locus(osc, "c_c", cs)
    assert locus.poles.shape == (13, 2)
    w0 = np.sqrt(k / m)
    for c, row in zip(cs, locus.poles):  # (the polynomial's coefficients: a double root is known to √ε only)
        assert np.max(np.abs(np.real(np.poly(row)) - [1.0, c / m, k / m]) / (np.maximum(w0, c / m) ** np.arange(3))) <= 1e-9
    fig = locus.plot()
    assert len(fig.axes[0].collections[0].get_offsets()) == 26
    osc.add("force", "F", "p", F=0)
    H = transfer_function(osc, "F", "x_p'")
    fig2 = pole_zero_map(H.poles(), H.zeros(), repr(H))
    poles_line, zeros_line = fig2.axes[0].get_lines()[:2]
    assert np.allclose(np.sort(poles_line.get_xdata()), np.sort(H.poles().real))
    assert np.allclose(zeros_line.get_xdata(), [0.0])  # s / (m s² + c s + k)
    with pytest.raises(lg.UnknownNameError, match="c_x"):
        root_locus(osc, "c_x", cs)
    plt.close("all")


def test_a_symbolic_two_mass_chains_poles_are_its_modes_and_six_poles_are_refused_by_name():
    """Undamped masses m1, m2 on springs k1 (to ground), k2 (between): the poles are ±i ω of K φ = ω² M φ (NumPy's
    eigenvalues at numbers); a third mass makes the denominator a cubic in s², degree 6: no closed form, said."""
    m1, m2, k1, k2, k3 = sp.symbols("m1 m2 k1 k2 k3", positive=True)
    chain = lg.Model("chain")
    chain.add("force", "F", "a", F=0)
    chain.add("mass", "ma", "a", m=m1)
    chain.add("mass", "mb", "b", m=m2)
    chain.add("spring", "ka", ("ground", "a"), k=k1)
    chain.add("spring", "kb", ("a", "b"), k=k2)
    poles = transfer_function(chain, "F", "x_b").poles()
    values = {m1: 0.3, m2: 0.7, k1: 40.0, k2: 25.0}
    found = np.sort(np.array([complex(p.subs(values)) for p in poles]).imag)
    w2 = np.linalg.eigvals(np.linalg.solve(np.diag([0.3, 0.7]), np.array([[65.0, -25.0], [-25.0, 25.0]])))
    expected = np.sort(np.concatenate([np.sqrt(w2), -np.sqrt(w2)]))
    assert np.allclose(found, expected, rtol=1e-12)
    chain.add("mass", "mc", "c", m=m1)
    chain.add("spring", "kc", ("b", "c"), k=k3)
    with pytest.raises(lg.ModelError, match="degree 6 in s, which has no closed form"):
        transfer_function(chain, "F", "x_c").poles()


def test_a_response_goes_to_xarray_and_pandas_with_its_labels_units_bounds_and_sensitivities():
    """Two inputs driving a mass (a force and a base motion) and three outputs: every value lands under its labels."""
    m = lg.Model("isolator")
    m.add("prescribed_motion", "base", "b", position=0)
    m.add("mass", "m", "p", m=0.3)
    m.add("spring", "k", ("b", "p"), k=40.0)
    m.add("damper", "c", ("b", "p"), c=0.5)
    m.add("force", "F", "p", F=0)
    f = decades(0.1, 100, 7)
    resp = frequency_response(m, f, inputs=["F", "base"], outputs=["x_p", "x_p'", "x_p''"])
    ds = resp.to_xarray()
    assert list(ds.output.values) == resp.outputs and list(ds.input.values) == resp.inputs == ["base", "F"]
    assert np.array_equal(ds.frequency.values, f) and ds.attrs["model"] == "isolator"
    for o in resp.outputs:
        for i in resp.inputs:
            assert np.array_equal(ds.H.sel(output=o, input=i).values, resp[o, i])
            assert ds.unit.sel(output=o, input=i).item() == resp.unit(o, i)
    assert np.array_equal(ds.error.values, resp.error)
    df = resp.to_pandas()
    assert df.columns.names == ["output", "input"] and df.index.name == "frequency"
    assert np.array_equal(df[("x_p'", "base")].to_numpy(), resp["x_p'", "base"])
    one = frequency_response(m, f, inputs=["F"], outputs=["x_p"], sensitivities=["k_k"])
    assert list(one.to_pandas().columns) == ["x_p"]
    assert np.array_equal(one.to_xarray()["dH/dk_k"].values, one.sensitivities["k_k"])


@settings(max_examples=10)
@given(decade(1e-6, 1e6))
def test_a_nyquist_chart_is_scaled_to_its_curve_not_to_the_critical_point(scale):
    """An RC low-pass scaled by ``scale`` (a gain, or a current per volt): the chart spans the curve (its diameter
    ``scale``), and −1 is marked only when it falls in that view."""
    import matplotlib.pyplot as plt

    m = lg.Model("rc")
    m.add("current_source", "I1", ("0", "a"), I=0)
    m.add("resistor", "R1", ("a", "0"), R=scale)
    m.add("capacitor", "C1", ("a", "0"), C=1e-3 / scale)
    resp = frequency_response(m, decades(0.01, 1e4, 60), inputs=["I1"], outputs=["v(C1)"])  # R / (1 + s R C)
    fig = resp.plot("nyquist")
    ax = fig.axes[0]
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    assert x0 <= 0 and x1 >= 0.99 * scale and -0.5 * scale >= y0  # the curve, with its mirror, in view
    assert max(x1 - x0, y1 - y0) <= 3 * scale  # and nothing else: not stretched to −1
    plt.close(fig)


@pytest.mark.slow
def test_frequency_response_charts_are_written(tmp_path):
    m = series_rlc(10.0, 7e-3, 2.2e-6)
    resp = frequency_response(m, decades(10, 1e5, 20), outputs=["v(C1)", "i(L1)"])
    assert resp.H.shape == (2, 1, len(resp.frequencies))
    peak = resp.frequencies[np.argmax(np.abs(resp["i(L1)"]))]
    assert peak == pytest.approx(1 / (2 * np.pi * np.sqrt(7e-3 * 2.2e-6)), rel=0.06)  # the grid's resolution
    for kind in ("bode", "nyquist"):
        path = tmp_path / f"{kind}.png"
        resp.plot(kind, path=str(path))
        assert path.stat().st_size > 10_000
    modes(m).plot(path=str(tmp_path / "modes.png"))
    assert (tmp_path / "modes.png").stat().st_size > 10_000
