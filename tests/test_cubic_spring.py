"""A spring's cubic stiffness (``beta``): V = ½ k e² + ¼ β e⁴.  The Duffing oscillator's period against its
quadrature, energy kept, symbols and numbers alike, and no circuit analogue."""

import math

import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings, strategies as st
from scipy.integrate import quad

import lagrangian as lg
from lagrangian.circuits.analogy import AnalogyError, map_model


def duffing(m, k, beta):
    model = lg.Model("duffing")
    model.add("mass", "m", "p", m=m)
    model.add("spring", "k", ("ground", "p"), k=k, beta=beta)
    return model


def period(m, k, beta, A):
    """T = 4 ∫₀^A dx / √(2 (V(A) − V(x)) / m), written with x = A sin θ so that the end point is regular."""
    V = lambda x: k * x**2 / 2 + beta * x**4 / 4  # noqa: E731
    integrand = lambda th: A * math.cos(th) / math.sqrt(2 * (V(A) - V(A * math.sin(th))) / m)  # noqa: E731
    return 4 * quad(integrand, 0, math.pi / 2, epsabs=0, epsrel=1e-12, limit=200)[0]


def decades(low, high):
    return st.floats(math.log10(low), math.log10(high)).map(lambda e: 10.0**e)


@settings(max_examples=10, deadline=None)
@given(m=decades(1e-3, 10.0), k=decades(1.0, 1e4), ratio=decades(1e-2, 1e2), A=decades(1e-3, 1.0),
       hardening=st.booleans())
def test_the_duffing_period_is_its_quadrature_and_the_energy_is_kept(m, k, ratio, A, hardening):
    """β chosen so that the cubic force at the amplitude is ``ratio`` times the linear one (softening: at most
    a third of it, so that the potential still rises to the turning point)."""
    beta = ratio * k / A**2 if hardening else -min(ratio, 1 / 3) * k / A**2
    T = period(m, k, beta, A)
    model = duffing(m, k, beta)
    res = model.simulate(3 * T, initial={"x_p": A}, velocity={"x_p": 0.0}, points=3001, rtol=1e-11, atol=1e-14 * A)
    x, t = res["x_p"], res.t
    crossings = [t[i] - x[i] * (t[i + 1] - t[i]) / (x[i + 1] - x[i]) for i in range(t.size - 1)
                 if x[i] > 0 >= x[i + 1]]  # downward zero crossings: a quarter period, then one per period
    assert len(crossings) >= 2
    assert crossings[0] == pytest.approx(T / 4, rel=1e-6)
    assert np.diff(crossings) == pytest.approx([T] * (len(crossings) - 1), rel=1e-6)
    E = res.T + res.V
    assert np.max(np.abs(E - E[0])) <= 1e-8 * E[0]
    assert res.V[0] == pytest.approx(k * A**2 / 2 + beta * A**4 / 4, rel=1e-12)


def test_a_symbolic_beta_gives_the_same_equations_and_run():
    b = sp.Symbol("b", real=True)
    numbers, symbols = duffing(0.3, 40.0, 2e4), duffing(0.3, 40.0, b)
    assert sp.simplify(symbols.equations[0].rhs.subs(b, 2e4) - numbers.equations[0].rhs) == 0
    kw = dict(initial={"x_p": 0.05}, velocity={"x_p": 0.0}, points=51, rtol=1e-11)
    np.testing.assert_allclose(symbols.simulate(1.0, params={"b": 2e4}, **kw)["x_p"],
                               numbers.simulate(1.0, **kw)["x_p"], rtol=0, atol=1e-12)


def test_a_cubic_spring_has_no_circuit_analogue_and_says_so():
    with pytest.raises(AnalogyError, match="spring 'k' has a cubic stiffness"):
        map_model(duffing(0.3, 40.0, 2e4), "force-current")
    assert map_model(duffing(0.3, 40.0, 0.0), "force-current").model.components  # (beta given as zero: linear)
