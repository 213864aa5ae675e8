"""Closed forms of rational functions of ``s``: their roots (the poles and zeros of a transfer function) and their
inverse Laplace transforms (its step and impulse responses), with symbolic coefficients or numbers.

The inverse transform goes by partial fractions over the denominator's roots, term by term from the table
``1/(s − p)^k ↔ t^(k−1) e^(p t)/(k − 1)!``: SymPy's ``inverse_laplace_transform`` looks the whole function up
instead, which on a series RLC with symbols took seconds and returned integrals unevaluated.
"""

from __future__ import annotations

import math

import numpy as np

from ..base.component import t
from ..errors import ModelError
from ..base import deferred as _deferred

sp = _deferred.module("sympy", globals())
_s = _deferred.symbol("s")  # the Laplace variable (lagrangian.linearize.s)

__all__ = ["CLOSED_DEGREE", "cancel_pairs", "closed_roots", "inverse_laplace", "polynomial_roots", "sorted_roots"]

#: Highest degree of a symbolic numerator or denominator whose roots :meth:`TransferFunction.poles` gives in closed
#: form (the quartic's formula; beyond, none in radicals in general, Abel–Ruffini).
CLOSED_DEGREE = 4


def closed_roots(poly: sp.Expr, what: str) -> list:
    """The roots of a polynomial in :data:`s`, each repeated by its multiplicity, in closed form: factors first
    (``s²`` and a quadratic are found as such at any degree), each factor up to :data:`CLOSED_DEGREE`; ``what``
    names them in a refusal ("the poles of …").

    >>> a, s = sp.Symbol("a", positive=True), sp.Symbol("s")
    >>> closed_roots(s**3 + a * s, "the roots")
    [0, -I*sqrt(a), I*sqrt(a)]
    """
    p = sp.Poly(poly, _s)
    out: list = []
    for factor, multiplicity in sp.factor_list(p)[1]:
        degree = factor.degree()
        if degree > CLOSED_DEGREE:
            raise ModelError(f"{what} are the roots of a factor of degree {degree} in s, which has no "
                             f"closed form in general: give the parameters numbers (params=), or ask for a smaller "
                             f"model.")
        found = sp.roots(factor, cubics=True, quartics=True)
        if sum(found.values()) != degree:
            raise ModelError(f"{what}: SymPy found no closed form for the roots of {factor.as_expr()} "
                             f"in s: give the parameters numbers (params=).")
        for root, k in found.items():
            out.extend([root] * (k * multiplicity))
    return out


#: A symbolic partial fraction's coefficient of at most this many operations is simplified (a series RLC's step
#: response: ``1`` for ``1/(C L p₊ p₋)``); larger ones (a quartic's roots) are left as they are, simplifying them
#: takes seconds.
SIMPLIFY_OPS = 120


def inverse_laplace(F: sp.Expr, what: str) -> sp.Expr:
    """``f(t)`` for ``t ≥ 0`` whose Laplace transform is the rational function ``F(s)``, by partial fractions: the
    polynomial part gives ``DiracDelta`` and its derivatives, each pole ``p`` of multiplicity ``m`` the terms
    ``c_j t^(m−1−j) e^(p t)/(m−1−j)!``, ``c_j = (1/j!) d^j/ds^j [(s − p)^m F(s)]`` at ``s = p``.  With numbers, a
    complex pair is written as ``e^(a t) (α cos b t + β sin b t)``; with symbols the terms are left as SymPy gives
    them (``sp.simplify`` or ``sp.expand_complex`` rewrite them).  ``what`` names the function in a refusal.

    >>> a, s = sp.Symbol("a", positive=True), sp.Symbol("s")
    >>> inverse_laplace(1 / (s * (s + a)), "f")
    1/a - exp(-a*t)/a
    """
    num, den = sp.fraction(sp.cancel(sp.together(F)))
    q, r = sp.div(sp.Poly(num, _s), sp.Poly(den, _s))
    out = sp.Add(*[c * (sp.DiracDelta(t, k) if k else sp.DiracDelta(t)) for (k,), c in q.terms() if c != 0])
    den_poly = sp.Poly(den, _s)
    numeric = not (num.free_symbols | den.free_symbols) - {_s}
    lc = den_poly.LC()
    roots: dict = {}
    for root in closed_roots(den, f"the poles of {what}"):
        roots[root] = roots.get(root, 0) + 1
    terms = []
    for p, m in roots.items():
        others = sp.Mul(*[(_s - pj) ** mj for pj, mj in roots.items() if pj != p])
        G = r.as_expr() / (lc * others)
        for j in range(m):
            c = sp.diff(G, _s, j).subs(_s, p) / math.factorial(j)
            if not numeric and sp.count_ops(c) <= SIMPLIFY_OPS:
                c = sp.simplify(c)
            terms.append((c, p, m - 1 - j))
    if numeric:
        out += _real_terms(terms)
    else:
        out += sp.Add(*[c * t ** k / math.factorial(k) * sp.exp(p * t) for c, p, k in terms])
    return out


def _real_terms(terms: list) -> sp.Expr:
    """``Σ c t^k/k! e^(p t)`` with number coefficients, a conjugate pair's two terms as one real one."""
    out = sp.Integer(0)
    for c, root, k in terms:
        c, p = complex(sp.N(c)), complex(sp.N(root))
        power = t ** k / math.factorial(k)
        if root.is_real:  # decided on the root as SymPy gives it (a real Float, or a pair with I), not on a float
            out += sp.Float(c.real) * power * sp.exp(sp.Float(p.real) * t)
        elif p.imag < 0:
            continue  # its conjugate's term holds it
        else:  # 2 Re(c e^(p t)) = 2 e^(a t) (Re c cos b t − Im c sin b t)
            out += 2 * power * sp.exp(sp.Float(p.real) * t) * (sp.Float(c.real) * sp.cos(sp.Float(p.imag) * t)
                                                            - sp.Float(c.imag) * sp.sin(sp.Float(p.imag) * t))
    return out


def cancel_pairs(zeros: np.ndarray, poles: np.ndarray, w0: float, tol: float = 1e-7) -> tuple[np.ndarray, np.ndarray]:
    """Zeros and poles with the pairs that coincide (within ``tol`` of ``w0`` or of their size) removed: modes the
    input does not reach or the output does not see."""
    zeros, poles = list(zeros), list(poles)
    for z in list(zeros):
        near = [i for i, p in enumerate(poles) if abs(p - z) <= tol * max(w0, abs(z))]
        if near:
            poles.pop(near[0])
            zeros.remove(z)
    return np.array(zeros, dtype=complex), np.array(poles, dtype=complex)


def polynomial_roots(expr: sp.Expr) -> np.ndarray:
    """The roots of a polynomial in :data:`s` with number coefficients; a factor ``s^k`` gives ``k`` exact zeros."""
    coeffs = [complex(c) for c in sp.Poly(expr, _s).all_coeffs()]
    k = 0
    while len(coeffs) > 1 and coeffs[-1] == 0:  # exact zeros: the coefficients come from exact arithmetic
        coeffs.pop()
        k += 1
    roots = np.roots(coeffs) if len(coeffs) > 1 else np.zeros(0, dtype=complex)
    return np.concatenate([roots.astype(complex), np.zeros(k, dtype=complex)])


def sorted_roots(roots: np.ndarray) -> np.ndarray:
    """Roots by size, then imaginary part; those real to rounding made real."""
    roots = np.where(np.abs(roots.imag) <= 1e-12 * np.abs(roots), roots.real + 0j, roots)
    return roots[np.lexsort((roots.imag, np.abs(roots)))]
