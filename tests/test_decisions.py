"""Structural decisions on ordinary inputs: the same verdict whether parameters are numbers or symbols.

Expected values come from closed forms (the spherical pendulum's and the
heavy symmetric top's effective potentials, the frequency of small
oscillations about a steady precession), from a simulation (the Jacobi
integral stays constant), or from the same model built with symbols.
Parameters are drawn log-uniformly over decades, as users type them.
"""

import math

import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

import lagrangian as lg
from lagrangian import models, routh
from lagrangian.identity import depends_on, equal, is_zero


def decades(lo, hi):
    """Floats drawn log-uniformly between lo and hi, rounded to 3 significant digits as users type them."""
    return st.floats(math.log10(lo), math.log10(hi)).map(lambda e: float(f"{10 ** e:.3g}"))


x, y, v = sp.symbols("x y v", real=True)


# -- the identity tests themselves ------------------------------------------------------------------


@settings(max_examples=60)
@given(a=decades(1e-4, 1e4), b=decades(1e-4, 1e4), c=decades(1e-3, 1e3))
def test_round_off_between_float_coefficients_is_not_a_term(a, b, c):
    # p and M·v built along two paths: equal as real numbers, not always as floats
    p = (a * b) * c * sp.sin(x) ** 2 * v
    Mv = a * (b * c) * sp.sin(x) ** 2 * v
    assert equal(p, Mv)
    assert not equal(p, Mv * (1 + 1e-6))


@settings(max_examples=60)
@given(a=decades(1e-4, 1e4), b=decades(1e-3, 1e3), small=st.floats(-16, -12.5), large=st.floats(-6, -1))
def test_floating_expressions_are_decided_in_double_precision_as_in_fifty_digits(a, b, small, large):
    """An identity with float amplitudes (the angle-sum formula, a rotation's cos² + sin²) is zero, with a residue
    far below FLOAT_TOLERANCE of its size too; a term above it is not, whatever precision decides.  The zero
    verdicts come from double precision alone (the 50-digit context is not asked for)."""
    identity = a * (sp.sin(x + y) - sp.sin(x) * sp.cos(y) - sp.cos(x) * sp.sin(y)) * v \
        + b * ((v * sp.cos(x) - y * sp.sin(x)) ** 2 + (v * sp.sin(x) + y * sp.cos(x)) ** 2 - v ** 2 - y ** 2)
    size = (a + b) * sp.sin(x) * sp.cos(y) * v
    assert not is_zero(identity + 10 ** large * size)
    import lagrangian.base.identity as identity_module

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(identity_module, "_context", lambda: pytest.fail("decided in 50 digits"))
        assert is_zero(identity) and is_zero(identity + 10 ** small * size)
        assert not depends_on(identity + b * y ** 2, x)


@settings(max_examples=40)
@given(a=decades(1e-4, 1e4), w=decades(1e-2, 1e2))
@pytest.mark.slow
def test_trigonometric_identities_with_float_amplitudes(a, w):
    t = lg.t
    assert is_zero(a * sp.sin(w * t) ** 2 + a * sp.cos(w * t) ** 2 - a)
    assert not depends_on(a * sp.sin(w * t) ** 2 + a * sp.cos(w * t) ** 2 + x, t)
    assert depends_on(a * sp.sin(w * t) ** 2 + x, t)
    assert not is_zero(a * sp.sin(w * t) - a * w * t)


@settings(max_examples=40)
@given(k=decades(1e-9, 1e9))
def test_tiny_and_huge_parameters_are_not_mistaken_for_zero(k):
    # capacitances of picofarads and stiffnesses of meganewtons per metre are ordinary values
    assert not is_zero(k * x * v)
    assert not is_zero(k * sp.sin(x) - k * x)


def test_values_fix_symbols_others_are_generic():
    k = sp.Symbol("k", positive=True)
    assert is_zero((k - 0.3) * x, {k: 0.3})
    assert not is_zero((k - 0.3) * x)
    assert not is_zero((k - 0.3) * x, {k: 0.31})


def test_expressions_off_their_real_domain_are_decided_where_they_are_real():
    assert is_zero(sp.sqrt(x - 5) ** 2 - (x - 5))
    assert not is_zero(sp.sqrt(x - 5) - 1)


# -- the spherical pendulum and the heavy top with ordinary values ----------------------------------


spherical = models.spherical_pendulum
heavy_top = models.heavy_top


def effective_potential_at(red, theta, C, values=None):
    """V_eff of a reduced model at a coordinate value, numerically."""
    eq = red.reconstructing(False).eq
    at = {eq.sym.q[0]: theta} | {red.momenta[n]: c for n, c in C.items()} | dict(values or {})
    return float(eq.V.xreplace(at))


@pytest.mark.slow
def test_readme_spherical_pendulum_reduces_with_ordinary_values():
    m, length, g = 0.3, 0.7, 9.81
    red = routh.reduce(spherical(m, length, g))
    for theta in (0.3, 1.1, 2.5):
        for C in (0.0, 0.21, 1.7):
            expected = C**2 / (2 * m * length**2 * math.sin(theta) ** 2) - m * g * length * math.cos(theta)
            assert effective_potential_at(red, theta, {"theta_turn": C}) == pytest.approx(expected, rel=1e-12)


@settings(max_examples=8)
@given(m=decades(1e-2, 1e2), length=decades(1e-2, 1e2), g=decades(0.1, 100), theta0=st.floats(0.15, 1.4))
@pytest.mark.slow
def test_spherical_pendulum_steady_precession_over_decades(m, length, g, theta0):
    """Steady precession at θ₀: Ω² = g/(l cos θ₀); small oscillations ω² = (g/l)(3 cos θ₀ + sec θ₀): stable."""
    red = routh.reduce(spherical(m, length, g))
    Omega = math.sqrt(g / (length * math.cos(theta0)))
    C = m * length**2 * math.sin(theta0) ** 2 * Omega
    motions = red.steady_motions(momenta={"theta_turn": C}, search={"theta_tilt": (0.01, 3.13)})
    found = [s for s in motions if abs(float(s.coordinates["theta_tilt"]) - theta0) < 1e-6]
    assert len(found) == 1
    stability = found[0].stability()
    assert stability.verdict == "stable"
    expected = math.sqrt(g / length * (3 * math.cos(theta0) + 1 / math.cos(theta0)))
    assert stability.frequencies[0] == pytest.approx(expected, rel=1e-7)


@pytest.mark.slow
def test_heavy_symmetric_top_reduces_with_ordinary_values():
    """Two ignorable angles; V_eff = (C_φ − C_ψ cos θ)²/(2 A sin²θ) + C_ψ²/(2 I₃) + m g l cos θ, A = I₁ + m l²."""
    m, l, I1, I3, g = 0.3, 0.4, 0.3, 0.5, 9.81
    red = routh.reduce(heavy_top(m, l, I1, I3, g))
    assert sorted(red.ignored) == ["theta_precession", "theta_spin"]
    A = I1 + m * l**2
    for theta in (0.4, 1.3, 2.2):
        for Cphi, Cpsi in ((0.7, 2.9), (-0.2, 0.05), (0.0, 0.0)):
            expected = (Cphi - Cpsi * math.cos(theta)) ** 2 / (2 * A * math.sin(theta) ** 2) \
                + Cpsi**2 / (2 * I3) + m * g * l * math.cos(theta)
            got = effective_potential_at(red, theta, {"theta_precession": Cphi, "theta_spin": Cpsi})
            assert got == pytest.approx(expected, rel=1e-11)


@pytest.mark.slow
def test_heavy_top_numbers_and_symbols_give_one_verdict():
    values = {"m": 0.3, "l": 0.4, "I1": 0.3, "I3": 0.5, "g": 9.81}
    symbols = {k: sp.Symbol(k, positive=True) for k in values}
    momenta = {"theta_precession": 1.3, "theta_spin": 2.9}
    search = {"theta_nutation": (0.05, 3.1)}
    verdicts = []
    for model, params in ((heavy_top(**values), None), (heavy_top(**symbols), values)):
        red = routh.reduce(model)
        assert red.effective_potential is not None
        motions = red.steady_motions(params=params, momenta=momenta, search=search)
        verdicts.append([(float(s.coordinates["theta_nutation"]), s.stability()) for s in motions])
    (numeric, symbolic) = verdicts
    assert len(numeric) == len(symbolic) >= 1
    for (a, sa), (b, sb) in zip(numeric, symbolic):
        assert a == pytest.approx(b, rel=1e-10)
        assert sa.verdict == sb.verdict
        np.testing.assert_allclose(sa.curvature, sb.curvature, rtol=1e-10)
        np.testing.assert_allclose(np.sort_complex(sa.eigenvalues), np.sort_complex(sb.eigenvalues), rtol=1e-8, atol=1e-10)


@settings(max_examples=6)
@given(m=decades(1e-2, 1e2), R=decades(1e-2, 1e1))
@pytest.mark.slow
def test_verdict_does_not_flip_with_m_r_squared(m, R):
    """A bead on a hoop turning freely about its vertical diameter (the hoop's inertia J): steady motion at
    the bottom is stable or unstable by the sign of g/R − Ω², never 'marginal' for want of an effective
    potential (there is no gyroscopic term)."""
    g, J = 9.81, 0.05
    model = lg.Model("bead on a free hoop", dim=3)
    model.add("body", "hoop", "hoop", m=0.1, inertia=(J, J, J))
    model.add("revolute", "spin", ("ground", "hoop"), axis=(0, 0, 1))
    model.add("link", "arm", "arm", points={"bead": (0, 0, -R)})
    model.add("revolute", "slide", ("hoop", "arm"), axis=(1, 0, 0))
    model.add("mass", "bead", "arm.bead", m=m)
    model.add("gravity", "g", g=g)
    red = routh.reduce(model)
    assert red.effective_potential is not None
    assert is_zero(red._r_parts["G"])
    for Omega in (0.5 * math.sqrt(g / R), 2.0 * math.sqrt(g / R)):
        C = J * Omega  # the bead at the bottom adds no inertia about the axis
        bottom = [s for s in red.steady_motions(momenta={"theta_spin": C}, search={"theta_slide": (-0.5, 0.5)})
                  if abs(float(s.coordinates["theta_slide"])) < 1e-9]
        assert len(bottom) == 1
        verdict = bottom[0].stability().verdict
        assert verdict == ("stable" if Omega**2 < g / R else "unstable")


# -- the Jacobi integral of a rheonomic model whose time dependence cancels -------------------------


@pytest.mark.slow
def test_jacobi_integral_conserved_when_time_dependence_cancels():
    w, A, k = 1.7, 0.05, 3.0
    model = lg.Model("mass between two supports turning on a circle", dim=2)
    model.add("mass", "m", "p", m=0.3)
    c = sp.Matrix([A * sp.cos(w * lg.t), A * sp.sin(w * lg.t)])
    model.add("prescribed_motion", "s1", "s1", position=c)
    model.add("prescribed_motion", "s2", "s2", position=-c)
    model.add("spring", "k1", ("s1", "p"), k=k)
    model.add("spring", "k2", ("s2", "p"), k=k * 1.0000000000000002)  # the same stiffness, typed another way
    h = routh.jacobi_integral(model)
    assert h.conserved, h.reasons
    res = model.simulate(10, initial={"x_p": 0.1, "y_p": -0.02}, velocity={"x_p": 0.0, "y_p": 0.3},
                         rtol=1e-12, atol=1e-14)
    values = h.values(res)
    assert np.ptp(values) / abs(values[0]) < 1e-9


def test_jacobi_integral_of_a_truly_rheonomic_model_is_not_conserved():
    model = lg.Model("mass on a support turning on a circle", dim=2)
    model.add("mass", "m", "p", m=0.3)
    model.add("prescribed_motion", "s", "s", position=sp.Matrix([0.05 * sp.cos(1.7 * lg.t), 0.05 * sp.sin(1.7 * lg.t)]))
    model.add("spring", "k", ("s", "p"), k=3.0)
    h = routh.jacobi_integral(model)
    assert not h.conserved
    assert "time" in " ".join(h.reasons)


# -- symbolic work under a budget -------------------------------------------------------------------


def test_symbolic_steady_motion_solve_stops_at_its_budget_with_advice():
    # solving the heavy top's conditions for a momentum takes SymPy seconds; a budget of 0.2 s stops it
    red = routh.reduce(heavy_top(0.3, 0.4, 0.3, 0.5, 9.81))
    with pytest.raises(lg.ReductionError, match=r"budget of 0.2 s: give numeric params= and momenta="):
        red.steady_motions(solve_for=["C_theta_precession"], budget=0.2)


def test_jacobi_integral_of_the_spherical_pendulum_is_its_energy_without_round_off_residues():
    h = routh.jacobi_integral(spherical(0.3, 0.7, 9.81))
    assert h.conserved and h.energy_conserved
    assert min(abs(float(f)) for f in h.expr.atoms(sp.Float)) > 1e-6  # no 1e-17 "terms" left in the display


# -- numbers are values of symbols ------------------------------------------------------------------


def oscillator_chain(m1, m2, k1, k2, c, F):
    model = lg.Model("two masses")
    model.add("mass", "m1", "a", m=m1)
    model.add("mass", "m2", "b", m=m2)
    model.add("spring", "k1", ("ground", "a"), k=k1)
    model.add("spring", "k2", ("a", "b"), k=k2)
    model.add("damper", "c", ("a", "b"), c=c)
    model.add("force", "F", "b", F=F)
    return model


@settings(max_examples=15)
@given(m1=decades(1e-3, 1e2), m2=decades(1e-3, 1e2), k1=decades(1e-1, 1e6), k2=decades(1e-1, 1e6),
       c=decades(1e-4, 1e2), F=decades(1e-3, 1e3))
def test_numbers_and_symbols_give_the_same_equations(m1, m2, k1, k2, c, F):
    given_ = {"m1": m1, "m2": m2, "k1": k1, "k2": k2, "c": c, "F": F}
    symbols = {k: sp.Symbol(k, positive=True) for k in given_}
    numeric = oscillator_chain(**given_)
    twin = oscillator_chain(**symbols)
    values = {symbols[k]: v for k, v in given_.items()}
    assert numeric.coordinate_names == twin.coordinate_names
    assert numeric.first_order == twin.first_order
    assert equal(numeric.eq.M, twin.eq.M.xreplace(values))
    assert equal(numeric.eq.f, twin.eq.f.xreplace(values))
    assert routh.jacobi_integral(numeric).conserved == routh.jacobi_integral(twin).conserved is False


def test_the_derivation_sees_symbols_and_the_equations_the_values():
    model = oscillator_chain(0.3, 7e-3, 40.0, 2.2e3, 0.05, 1.5)
    generic = model.assembly.energy("T", generic=True) + model.assembly.energy("V", generic=True)
    assert not generic.atoms(sp.Float)  # 0.3 kg, 7e-3 kg, ... are symbols while the equations are derived
    assert model.parameters == []  # ... and values once they are: nothing is left to give
    assert model.eq.M[0, 0] == sp.Float(0.3) and model.eq.M[1, 1] == sp.Float(7e-3)
    spring = model.component("k1")
    assert spring.k == sp.Float(40.0) and spring.symbolic_view().k in spring.values


def test_piecewise_signals_are_decided_branch_by_branch():
    # a pulse vanishes on whole intervals, where random points could all fall: never decided by points alone
    t = lg.t
    pulse = sp.Piecewise((0, t < 0.1), (5 * t, t < 0.2), (1, True))
    assert depends_on(pulse * x, t)
    assert not is_zero(pulse)
    assert is_zero(pulse * x - x * pulse)
    assert not is_zero(sp.Heaviside(t - 1) * x)
    assert equal(sp.Piecewise((x, t < 1), (2 * x, True)) * 0.3, sp.Piecewise((0.3 * x, t < 1), (0.6 * x, True)))


def test_a_budget_exception_swallowed_once_still_stops_the_call():
    """The timer's exception can be raised where Python swallows it (a gc callback) or code catches it: the
    budget fires again until the call stops."""
    import time

    from lagrangian.base.budget import BudgetExceeded, interruptible

    def stubborn():
        try:
            time.sleep(30)
        except BudgetExceeded:  # as a gc callback's swallowed exception would be
            pass
        time.sleep(30)
        return "ran on"

    with pytest.raises(BudgetExceeded, match="budget of 0.1 s"):
        interruptible(stubborn, seconds=0.1)
