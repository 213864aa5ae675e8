"""The cosmetic tidy of reductions: exact (equal to what it was given at random points), and the identities it
uses shorten what they should."""

import math

import numpy as np
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from lagrangian.analysis.routh.tidy import _squares_to_one, _tidy

a, b = sp.symbols("a b", real=True)
m, r = sp.symbols("m r", positive=True)
ATOMS = [sp.sin(a), sp.cos(a), sp.sin(b), sp.cos(b), sp.sinh(a), sp.cosh(a), m, r, sp.Float(0.3), sp.Integer(2)]


@st.composite
def expressions(draw):
    """Small sums of products of trigonometric and hyperbolic functions, symbols and numbers."""
    terms = []
    for _ in range(draw(st.integers(1, 4))):
        factors = [ATOMS[draw(st.integers(0, len(ATOMS) - 1))] ** draw(st.integers(1, 3))
                   for _ in range(draw(st.integers(1, 3)))]
        terms.append(draw(st.sampled_from([-1, 1, 3])) * sp.Mul(*factors))
    return sp.Add(*terms)


@settings(max_examples=60)
@given(expressions(), st.floats(-3, 3), st.floats(-3, 3), st.floats(0.01, 100), st.floats(0.01, 100))
def test_the_tidy_is_exact(expr, x, y, mass, radius):
    point = {a: x, b: y, m: mass, r: radius}
    for out in (_tidy(expr), _squares_to_one(expr)):
        want, got = float(expr.xreplace(point)), float(out.xreplace(point))
        assert math.isclose(got, want, rel_tol=1e-9, abs_tol=1e-9 * (1 + abs(want)))


def test_the_squares_of_sine_and_cosine_add_to_one_and_hyperbolic_ones_differ_by_one():
    assert _tidy(m * r**2 * sp.sin(a) ** 2 + m * r**2 * sp.cos(a) ** 2) == m * r**2
    assert _squares_to_one(sp.cosh(a) ** 2 - sp.sinh(a) ** 2) == 1
    # a mass matrix's determinant with sin² + cos²: the tidy leaves one term, floats kept as given
    det = 0.3 * r**2 * (sp.sin(a) ** 2 + sp.cos(a) ** 2) * m
    assert sp.count_ops(_tidy(sp.expand(det))) <= 3 and _tidy(sp.expand(det)).has(sp.Float(0.3))
    x = np.linspace(-2, 2, 5)
    f = sp.lambdify(a, _squares_to_one(sp.sin(a) ** 4 + 2 * sp.sin(a) ** 2 * sp.cos(a) ** 2 + sp.cos(a) ** 4))
    assert np.allclose(f(x), 1.0)
