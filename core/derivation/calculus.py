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

from collections.abc import Callable, Iterable

import sympy as sp
from sympy.core.function import AppliedUndef

from ..errors import ModelError

__all__ = ["Calculus", "Rewriter", "atoms_of", "cross", "nodes", "symbols_of", "time_derivative", "trig"]

_ZERO = sp.Integer(0)
_ONE = sp.Integer(1)
_TWO = sp.Integer(2)
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
        d = self._deps.get(e)
        if d is None:
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
            self._deps[e] = d
        return d

    def diff(self, e, s):
        if s not in self.deps(e):
            return _ZERO
        key = (e, s)
        out = self._diff.get(key)
        if out is None:
            out = self._rule(e, s)
            self._diff[key] = out
        return out

    def _rule(self, e, s):
        if e == s:
            return _ONE
        if e.is_Add:
            if len(e.args) > _INDEXED:  # a sum over the whole model (V, D): its addends by symbol, found once
                index = self._addends.get(e)
                if index is None:
                    index = self._addends[e] = {}
                    for a in e.args:
                        for x in self.deps(a):
                            index.setdefault(x, []).append(a)
                return sp.Add(*[self.diff(a, s) for a in index.get(s, ())])
            return sp.Add(*[self.diff(a, s) for a in e.args if s in self.deps(a)])
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
                    return sp.Mul(_TWO, base, db)
                return sp.Mul(exp, sp.Pow(base, exp - 1), db)
        elif isinstance(e, sp.sin):
            return sp.Mul(trig(sp.cos, e.args[0]), self.diff(e.args[0], s))
        elif isinstance(e, sp.cos):
            return sp.Mul(-_ONE, trig(sp.sin, e.args[0]), self.diff(e.args[0], s))
        return sp.diff(e, s)


def nodes(exprs: Iterable) -> set:
    """Every distinct sub-expression of ``exprs`` (expressions or matrices), each visited once.

    SymPy's ``atoms`` and ``free_symbols`` visit a shared sub-expression once per occurrence: exponential in the
    nesting depth for expressions such as a spatial chain's, where each body's velocity is nested in every body's
    beyond it (16.5 million visits for the equations of four bodies on spherical joints, against 3,267 here).
    Nodes that bind symbols (an integral's variable) are kept whole and not entered."""
    seen: set = set()
    stack = [e for x in exprs for e in (x if isinstance(x, sp.MatrixBase) else (x,))]
    while stack:
        e = stack.pop()
        if e in seen:
            continue
        seen.add(e)
        if e.args and not getattr(e, "bound_symbols", None):
            stack.extend(e.args)
    return seen


def atoms_of(exprs: Iterable, *types) -> set:
    """``atoms(*types)`` of ``exprs``, visiting each distinct sub-expression once (:func:`nodes`)."""
    return {e for e in nodes(exprs) if isinstance(e, types)}


def symbols_of(exprs: Iterable) -> set:
    """The free symbols of ``exprs``, visiting each distinct sub-expression once (:func:`nodes`)."""
    out: set = set()
    for e in nodes(exprs):
        if e.is_Symbol:
            out.add(e)
        elif e.args and getattr(e, "bound_symbols", None):
            out |= e.free_symbols
    return out


def cross(a, b) -> list:
    """``a × b`` of two 3-vectors (sequences or column matrices), as a list, without products by zero entries.

    >>> x, y = sp.symbols("x y")
    >>> cross([x, 0, 0], [0, y, 0])
    [0, 0, x*y]
    """
    def term(x, y):
        return _ZERO if x == 0 or y == 0 else sp.Mul(x, y)
    return [sp.Add(term(a[1], b[2]), -term(a[2], b[1])), sp.Add(term(a[2], b[0]), -term(a[0], b[2])),
            sp.Add(term(a[0], b[1]), -term(a[1], b[0]))]


def trig(func, arg):
    """``func(arg)`` for ``sin`` or ``cos``, skipping SymPy's evaluation (slow, ~0.1 ms) when ``arg`` is a symbol or
    an undefined function — where it leaves the call unchanged anyway."""
    if (arg.is_Symbol or isinstance(arg, AppliedUndef)) and not (arg.is_extended_real and arg.is_finite is False):
        return func(arg, evaluate=False)
    return func(arg)


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
        return _ZERO
    key = (e, t)
    out = _DT_CACHE.get(key)
    if out is not None:
        return out
    if e == t:
        out = _ONE
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
        out = sp.Mul(exp, sp.Pow(base, exp - 1), _dt(base, t)) if exp != 2 else sp.Mul(_TWO, base, _dt(base, t))
    elif isinstance(e, sp.sin):
        out = sp.Mul(trig(sp.cos, e.args[0]), _dt(e.args[0], t))
    elif isinstance(e, sp.cos):
        out = sp.Mul(-_ONE, trig(sp.sin, e.args[0]), _dt(e.args[0], t))
    elif isinstance(e, AppliedUndef) and e.args == (t,):
        out = sp.Derivative(e, t, evaluate=False)  # what diff gives, without its checks
    elif isinstance(e, sp.Derivative) and isinstance(e.expr, AppliedUndef) and e.expr.args == (t,) and e.variables == (t,) * len(e.variables):
        out = sp.Derivative(e.expr, (t, len(e.variables) + 1), evaluate=False)
    else:
        out = e.diff(t)
    _DT_CACHE[key] = out
    return out


# -- memoized substitution ------------------------------------------------------------------------


_TRIG = (sp.sin, sp.cos)


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
            elif e.func in _TRIG:
                out = trig(e.func, new[0])
            else:
                out = e.func(*new)
            self._memo[e] = out
        return out
