"""Memoized operations on expression trees: partial derivatives, time derivatives and substitution.

SymPy's ``diff`` and ``xreplace`` are general but slow, and the equations of a
mechanism apply them to the same few sub-expressions again and again.
:class:`Calculus` differentiates with memoized rules for sums, products,
powers, ``sin`` and ``cos`` (anything else falls back to SymPy), pruning by
which symbols each sub-expression depends on; :func:`time_derivative` does the
same for ``d/dt`` of expressions in functions ``q(t)``; :class:`Rewriter`
substitutes with a memo shared between calls; :func:`trig` builds ``sin`` and
``cos`` without SymPy's evaluation where it would change nothing.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping

from ..base.identity import entries, nodes, symbols_of  # noqa: F401 - (defined there; named here too)
from ..errors import ModelError
from ..base import deferred as _deferred

sp = _deferred.module("sympy", globals())

__all__ = ["Calculus", "Rewriter", "atoms_of", "cross", "nodes", "symbols_of", "time_derivative", "time_integral", "trig"]

_EMPTY: frozenset = frozenset()


#: A sum of more addends than this is differentiated through an index of its addends by symbol: ``∂/∂q_i`` of the
#: potential of an n-spring chain then visits the two addends holding ``q_i``, not all n (quadratic in n).
_INDEXED = 32


class Calculus:
    """Memoized partial derivatives with respect to a fixed set of symbols.

    ``deps(e)`` is the set of those symbols ``e`` contains; ``diff(e, s)`` is
    ``∂e/∂s`` (0 at once when ``s`` is not in ``deps(e)``).
    """

    def __init__(self, symbols: Iterable[sp.Symbol]):
        self.symbols = frozenset(symbols)
        self._deps: dict = {}
        self._diff: dict = {}
        self._addends: dict = {}

    def deps(self, e) -> frozenset:
        # by identity (the memo holds ``e``): a lookup by equality compares an equal expression built apart from
        # the stored one as a tree, exponential in its depth where its parts are shared (10⁷ comparisons for the
        # forces of six spatial bodies whose parts came partly from another model's derivation)
        found = self._deps.get(id(e))
        if found is not None:
            return found[1]
        if not isinstance(e, sp.Basic):  # (a plain number of the caller's)
            return _EMPTY
        if e.is_Symbol:
            d = frozenset((e,)) if e in self.symbols else _EMPTY
        elif not e.args:
            d = _EMPTY
        else:
            d = _EMPTY
            for a in e.args:
                da = self.deps(a)
                if da:
                    d = d | da if d else da
        self._deps[id(e)] = (e, d)
        return d

    def diff(self, e, s):
        if s not in self.deps(e):
            return sp.S.Zero
        key = (e, s)
        out = self._diff.get(key)
        if out is None:
            out = self._rule(e, s)
            self._diff[key] = out
        return out

    def along(self, e, rates: Mapping, memo: dict):
        """``Σ_s ∂e/∂s · rates[s]``: the derivative of ``e`` along the direction ``rates`` (``{q_i: q̇_i, t: 1}``
        for the total time derivative at fixed ``q̇``), in one pass over ``e``'s shared sub-expressions (forward
        mode), where the gradient symbol by symbol takes one pass per symbol.  ``memo`` is the caller's, one per
        direction.

        >>> x, y = sp.symbols("x y")
        >>> Calculus([x, y]).along(sp.sin(x) * y, {x: 2, y: 3}, {})
        2*y*cos(x) + 3*sin(x)
        """
        if self.deps(e).isdisjoint(rates):
            return sp.S.Zero
        out = memo.get(e)
        if out is not None:
            return out
        if e.is_Symbol:
            out = sp.sympify(rates[e], strict=True)  # (an expression of the caller's, never text)
        elif e.is_Add:
            out = sp.Add(*[self.along(a, rates, memo) for a in e.args])
        elif e.is_Mul:
            args = e.args
            terms = []
            for k, a in enumerate(args):
                da = self.along(a, rates, memo)
                if da != 0:
                    terms.append(sp.Mul(*args[:k], da, *args[k + 1:]))
            out = sp.Add(*terms)
        elif e.is_Pow and self.deps(e.args[1]).isdisjoint(rates):
            base, exp = e.args
            db = self.along(base, rates, memo)
            out = sp.Mul(sp.S(2), base, db) if exp == 2 else sp.Mul(exp, sp.Pow(base, exp - 1), db)
        elif isinstance(e, sp.sin):
            out = sp.Mul(trig(sp.cos, e.args[0]), self.along(e.args[0], rates, memo))
        elif isinstance(e, sp.cos):
            out = sp.Mul(-sp.S.One, trig(sp.sin, e.args[0]), self.along(e.args[0], rates, memo))
        else:
            out = sp.Add(*[sp.Mul(self.diff(e, s), rates[s]) for s in self.deps(e) if s in rates])
        memo[e] = out
        return out

    def at(self, e, s, value: Callable, memo: dict):
        """``∂e/∂s`` at a point, where ``value(x)`` is the value of a sub-expression ``x`` there (a memoized
        :class:`Rewriter`): the rules act on values, so the derivative is never built as an expression of the
        symbols (forward mode at the point, one pass over ``e``'s shared sub-expressions that depend on ``s``).
        ``∂/∂q`` of the closed-form forces of six spatial bodies, all of them, took 15 s built and then evaluated;
        here the intermediate results stay the size of a value.  ``memo`` is the caller's, one per point.

        >>> x, y, a = sp.symbols("x y a")
        >>> Calculus([x, y]).at(sp.sin(x) * y + a * x**3, x, Rewriter({x: sp.Integer(0), y: sp.Integer(2)}), {})
        2
        """
        if s not in self.deps(e):
            return sp.S.Zero
        key = (e, s)
        out = memo.get(key)
        if out is not None:
            return out
        if e.is_Symbol:
            out = sp.S.One
        elif e.is_Add:
            out = sp.Add(*[self.at(a, s, value, memo) for a in self._holding(e, s)])
        elif e.is_Mul:
            args, terms = e.args, []
            for k, a in enumerate(args):
                if s in self.deps(a):
                    da = self.at(a, s, value, memo)
                    if da != 0:
                        terms.append(sp.Mul(*[value(b) for b in args[:k]], da, *[value(b) for b in args[k + 1:]]))
            out = sp.Add(*terms)
        elif e.is_Pow and s not in self.deps(e.args[1]):
            base, exp = value(e.args[0]), value(e.args[1])
            out = sp.Mul(exp, sp.Pow(base, exp - 1), self.at(e.args[0], s, value, memo))
        elif isinstance(e, sp.sin):
            out = sp.Mul(sp.cos(value(e.args[0])), self.at(e.args[0], s, value, memo))
        elif isinstance(e, sp.cos):
            out = sp.Mul(-sp.S.One, sp.sin(value(e.args[0])), self.at(e.args[0], s, value, memo))
        else:
            out = value(sp.diff(e, s))
        memo[key] = out
        return out

    def affine(self, exprs: Iterable, memo: dict | None = None) -> bool:
        """Whether every expression of ``exprs`` is affine in the symbols (a sum of terms each of degree at most
        one in them), read off the structure: a product of two of them, a power or a function of one is not.  A
        structure that SymPy would cancel on expanding counts as it stands.

        >>> x, y, a = sp.symbols("x y a")
        >>> c = Calculus([x, y])
        >>> c.affine([a * x + sp.sin(a) * y, sp.Integer(3)]), c.affine([x * y]), c.affine([sp.cos(x)])
        (True, False, False)
        """
        memo = {} if memo is None else memo

        def degree(e) -> int:  # 0, 1, or 2 for anything beyond one
            if not self.deps(e):
                return 0
            d = memo.get(e)
            if d is None:
                if e.is_Symbol:
                    d = 1
                elif e.is_Add:
                    d = max(degree(a) for a in e.args)
                elif e.is_Mul:
                    d = min(2, sum(degree(a) for a in e.args))
                elif e.is_Pow and e.args[1].is_Integer and int(e.args[1]) >= 0 and not self.deps(e.args[1]):
                    d = min(2, degree(e.args[0]) * int(e.args[1]))
                else:
                    d = 2
                memo[e] = d
            return d

        return all(degree(sp.sympify(e, strict=True)) <= 1 for e in exprs)

    def _holding(self, e, s) -> Iterable:
        """The addends of the sum ``e`` that hold ``s``; for a sum over the whole model (V, D: more than
        :data:`_INDEXED` addends) through an index of its addends by symbol, found once."""
        if len(e.args) <= _INDEXED:
            return [a for a in e.args if s in self.deps(a)]
        index = self._addends.get(e)
        if index is None:
            index = self._addends[e] = {}
            for a in e.args:
                for x in self.deps(a):
                    index.setdefault(x, []).append(a)
        return index.get(s, ())

    def _rule(self, e, s):
        if e == s:
            return sp.S.One
        if e.is_Add:
            return sp.Add(*[self.diff(a, s) for a in self._holding(e, s)])
        if e.is_Mul:
            args = e.args
            terms = []
            for k, a in enumerate(args):
                if s in self.deps(a):
                    da = self.diff(a, s)
                    if da != 0:
                        terms.append(sp.Mul(*args[:k], da, *args[k + 1 :]))
            return sp.Add(*terms)
        if e.is_Pow:
            base, exp = e.args
            if s not in self.deps(exp):
                db = self.diff(base, s)
                if exp == 2:
                    return sp.Mul(sp.S(2), base, db)
                return sp.Mul(exp, sp.Pow(base, exp - 1), db)
        elif isinstance(e, sp.sin):
            return sp.Mul(trig(sp.cos, e.args[0]), self.diff(e.args[0], s))
        elif isinstance(e, sp.cos):
            return sp.Mul(-sp.S.One, trig(sp.sin, e.args[0]), self.diff(e.args[0], s))
        return sp.diff(e, s)


def from_entries(rows: int, cols: int, found: dict) -> sp.Matrix:
    """A SymPy matrix of ``rows × cols`` with the entries ``found`` (``{(i, j): value}``), zero elsewhere, built
    from its sparse store: ``sp.Matrix(rows, cols, flat_list)`` walks every entry, microseconds each (a minute for
    10⁴ × 10⁴ zeros).

    >>> x = sp.Symbol("x")
    >>> from_entries(2, 2, {(0, 0): x, (1, 1): 2})
    Matrix([
    [x, 0],
    [0, 2]])
    """
    return sp.MutableDenseMatrix._fromrep(sp.SparseMatrix(rows, cols, found)._rep)


def dense(matrix: sp.MatrixBase) -> list:
    """The entries of ``matrix`` row by row, as ``list(matrix)`` gives them, built from its sparse store (one step
    per nonzero entry and a list of its size, against microseconds an entry for indexing)."""
    flat = [sp.S.Zero] * (matrix.rows * matrix.cols)
    cols = matrix.cols
    for (i, j), value in matrix.todok().items():
        flat[i * cols + j] = value
    return flat


def atoms_of(exprs: Iterable, *types) -> set:
    """``atoms(*types)`` of ``exprs``, visiting each distinct sub-expression once (:func:`nodes`)."""
    return {e for e in nodes(exprs) if isinstance(e, types)}


def cross(a, b) -> list:
    """``a × b`` of two 3-vectors (sequences or column matrices), as a list, without products by zero entries.

    >>> x, y = sp.symbols("x y")
    >>> cross([x, 0, 0], [0, y, 0])
    [0, 0, x*y]
    """
    def term(x, y):
        return sp.S.Zero if x == 0 or y == 0 else sp.Mul(x, y)
    return [sp.Add(term(a[1], b[2]), -term(a[2], b[1])), sp.Add(term(a[2], b[0]), -term(a[0], b[2])),
            sp.Add(term(a[0], b[1]), -term(a[1], b[0]))]


def trig(func, arg):
    """``func(arg)`` for ``sin`` or ``cos``, skipping SymPy's evaluation (slow, ~0.1 ms, and 3 ms for the sum of
    the 100 angles of a planar chain's last link, which it scans for multiples of π) when ``arg`` is a symbol or an
    undefined function, or a sum of them — where it leaves the call unchanged anyway."""
    if _plain(arg) or (arg.is_Add and all(_plain(a) for a in arg.args)):
        return func(arg, evaluate=False)
    return func(arg)


def _plain(arg) -> bool:
    """A symbol or an undefined function that is not known to be infinite."""
    return (arg.is_Symbol or isinstance(arg, sp.core.function.AppliedUndef)) and not (arg.is_extended_real and arg.is_finite is False)


# -- time derivative of expressions in q(t) -------------------------------------------------------

_DT_CACHE: dict = {}
_HAS_T: dict = {}


def _has_t(e, t) -> bool:
    key = (e, t)
    out = _HAS_T.get(key)
    if out is None:
        if e.is_Symbol:
            out = e == t
        elif not e.args:
            out = False
        else:
            out = any(_has_t(a, t) for a in e.args)
        _HAS_T[key] = out
    return out


def time_derivative(expr, t: sp.Symbol):
    """``d expr/dt`` for an expression in functions ``q(t)``, ``t`` and constants (SymPy's ``diff(expr, t)``,
    memoized, with fast rules for sums, products, powers, ``sin`` and ``cos``).

    >>> from sympy import Function, Symbol, sin
    >>> t = Symbol("t"); q = Function("q")(t)
    >>> time_derivative(3 * sin(q), t)
    3*cos(q(t))*Derivative(q(t), t)
    """
    if isinstance(expr, (str, bytes)):  # text is never read as code
        raise ModelError(f"time_derivative takes a SymPy expression, not text: {expr!r:.60}.")
    if len(_DT_CACHE) > 200_000:  # bound the memory held between models
        _DT_CACHE.clear()
        _HAS_T.clear()
    return _dt(sp.sympify(expr, strict=True), t)


def _dt(e, t):
    if not _has_t(e, t):
        return sp.S.Zero
    key = (e, t)
    out = _DT_CACHE.get(key)
    if out is not None:
        return out
    if e == t:
        out = sp.S.One
    elif e.is_Add:
        out = sp.Add(*[_dt(a, t) for a in e.args])
    elif e.is_Mul:
        args = e.args
        terms = []
        for k, a in enumerate(args):
            da = _dt(a, t)
            if da != 0:
                terms.append(sp.Mul(*args[:k], da, *args[k + 1 :]))
        out = sp.Add(*terms)
    elif e.is_Pow and not _has_t(e.args[1], t):
        base, exp = e.args
        out = sp.Mul(exp, sp.Pow(base, exp - 1), _dt(base, t)) if exp != 2 else sp.Mul(sp.S(2), base, _dt(base, t))
    elif isinstance(e, sp.sin):
        out = sp.Mul(trig(sp.cos, e.args[0]), _dt(e.args[0], t))
    elif isinstance(e, sp.cos):
        out = sp.Mul(-sp.S.One, trig(sp.sin, e.args[0]), _dt(e.args[0], t))
    elif isinstance(e, sp.core.function.AppliedUndef) and e.args == (t,):
        out = sp.Derivative(e, t, evaluate=False)  # what diff gives, without its checks
    elif isinstance(e, sp.Derivative) and isinstance(e.expr, sp.core.function.AppliedUndef) and e.expr.args == (t,) and e.variables == (t,) * len(e.variables):
        out = sp.Derivative(e.expr, (t, len(e.variables) + 1), evaluate=False)
    else:
        out = e.diff(t)
    _DT_CACHE[key] = out
    return out


# -- memoized substitution ------------------------------------------------------------------------


class Rewriter:
    """``expr.xreplace(mapping)`` with a memo shared between calls (shared sub-expressions are rebuilt once).

    ``check(node)`` is called on every node not in the mapping before its arguments are visited.
    """

    def __init__(self, mapping: dict, check: Callable | None = None):
        self.mapping = mapping
        self.check = check
        self._memo: dict = {}

    def __call__(self, e):
        out = self.mapping.get(e)
        if out is not None:
            return out
        if not e.args:
            return e
        out = self._memo.get(e)
        if out is None:
            if self.check is not None:
                self.check(e)
            args = e.args
            new = [self(a) for a in args]
            if all(x is y for x, y in zip(new, args)):
                out = e
            elif e.func in (sp.sin, sp.cos):
                out = trig(e.func, new[0])
            else:
                out = e.func(*new)
            self._memo[e] = out
        return out


def time_integral(expr, t: sp.Symbol):
    """``∫₀ᵗ expr dτ`` in closed form for the waveforms of sources, or ``None`` when ``expr`` is not one of them.

    The forms: sums of terms ``c · tⁿ``, ``c · exp(a t + b)``, ``c · sin(w t + p)`` or ``cos``, ``c · exp(a t + b)
    · sin(w t + p)`` or ``cos`` (``a``, ``b``, ``c``, ``w``, ``p`` free of ``t``), ``c · d/dt f(t)``; and
    ``Piecewise`` of such sums under conditions ``t ≤ c₁ < c₂ < …`` (``0 ≤ c₁``) ending in ``True``, whose
    integral carries each piece's total into the next.  SymPy's ``integrate`` finds the same integrals, but a SIN
    source of SPICE with a delay and a damping (``exp(−θ t) sin(ω t + φ)`` with floating-point coefficients)
    took it 2.4 s, where these rules take milliseconds.  Anything else is left to SymPy (``None``).

    >>> import sympy as sp
    >>> t = sp.Symbol("t")
    >>> time_integral(2 * sp.cos(3 * t), t)
    2*sin(3*t)/3
    >>> time_integral(sp.Piecewise((1, t <= 2), (0, True)), t)
    Piecewise((t, t <= 2), (2, True))
    >>> time_integral(sp.log(t), t) is None
    True
    """
    if isinstance(expr, (str, bytes)):  # text is never read as code
        raise ModelError(f"time_integral takes a SymPy expression, not text: {expr!r:.60}.")
    expr = sp.sympify(expr, strict=True)
    if isinstance(expr, sp.Piecewise):
        return _piecewise_integral(expr, t)
    F = _antiderivative(expr, t)
    return None if F is None else F - F.subs(t, sp.S.Zero)


def _piecewise_integral(expr: sp.Piecewise, t: sp.Symbol):
    bounds, pieces = [], []
    for value, cond in expr.args:
        if cond is sp.true:
            bounds.append(None)
        elif isinstance(cond, (sp.LessThan, sp.StrictLessThan)) and cond.lhs == t and cond.rhs.is_number:
            bounds.append(cond.rhs)
        else:
            return None
        F = _antiderivative(value, t)
        if F is None:
            return None
        pieces.append((F, cond))
    numbers = [float(b) for b in bounds[:-1] if b is not None]
    if bounds[-1] is not None or None in bounds[:-1] or any(not math.isfinite(x) for x in numbers) \
            or not (numbers == sorted(set(numbers)) and (not numbers or numbers[0] >= 0.0)):
        return None
    out, start, carried = [], sp.S.Zero, sp.S.Zero
    for (F, cond), bound in zip(pieces, bounds):
        total = carried + F - F.subs(t, start)
        out.append((total, cond))
        if bound is not None:
            carried, start = total.subs(t, bound), bound
    return sp.Piecewise(*out)


def _linear(e, t):
    """``(a, b)`` with ``e = a t + b``, ``a`` and ``b`` free of ``t``; ``None`` otherwise."""
    a = e.diff(t)
    if a.has(t):
        return None
    return a, e.subs(t, sp.S.Zero)


def _antiderivative(expr, t):
    """An antiderivative of ``expr`` in ``t`` by the rules of :func:`time_integral`, or ``None``."""
    total = []
    for term in sp.Add.make_args(sp.expand(expr, trig=False, log=False, power_base=False, power_exp=False)):
        if not term.has(t):
            total.append(term * t)
            continue
        coeff, rest = term.as_independent(t, as_Add=False)
        if rest == sp.S.One:
            total.append(coeff * t)
            continue
        if isinstance(rest, sp.Derivative) and rest.variables == (t,) and not coeff.has(t):
            total.append(coeff * rest.expr)
            continue
        growth, wave, power = sp.S.Zero, None, 0
        for f in sp.Mul.make_args(rest):
            if isinstance(f, sp.exp):
                growth += f.args[0]
            elif isinstance(f, (sp.sin, sp.cos)) and wave is None:
                wave = f
            elif f == t:
                power += 1
            elif f.is_Pow and f.base == t and f.exp.is_Integer and f.exp > 0:
                power += int(f.exp)
            else:
                return None
        if power:
            if growth != sp.S.Zero or wave is not None:
                return None
            total.append(coeff * t ** (power + 1) / (power + 1))
            continue
        ab = _linear(growth, t) if growth != sp.S.Zero else (sp.S.Zero, sp.S.Zero)
        wp = _linear(wave.args[0], t) if wave is not None else None
        if ab is None or (wave is not None and (wp is None or wp[0] == sp.S.Zero)):
            return None
        a = ab[0]
        if wave is None:
            if a == sp.S.Zero:
                return None
            total.append(coeff * sp.exp(growth) / a)
            continue
        w, s, c = wp[0], sp.sin(wave.args[0]), sp.cos(wave.args[0])
        if a == sp.S.Zero:
            total.append(coeff * (-c if isinstance(wave, sp.sin) else s) / w)
            continue
        rate = a * s - w * c if isinstance(wave, sp.sin) else a * c + w * s
        total.append(coeff * sp.exp(growth) * rate / (a ** 2 + w ** 2))
    return sp.Add(*total)
