"""A quick numeric probe of an expression: its value and a bound on its rounding, in floats or with mpmath.

:func:`float_value` evaluates sums, products, powers, numbers, ``sin``, ``cos``,
``tan`` and ``exp`` at given values of the symbols, each shared sub-expression
once, together with the same evaluation on absolute values, which bounds the
rounding error relative to the working precision; it gives up (``None``) on
anything else.
"""

from __future__ import annotations

import functools
import math

from ..base import deferred as _deferred

sp = _deferred.module("sympy", globals())

__all__ = ["float_value"]


@functools.cache
def _float_funcs():
    return {sp.sin: math.sin, sp.cos: math.cos, sp.exp: math.exp, sp.tan: math.tan}


@functools.cache
def _mp_funcs():
    return {sp.sin: "sin", sp.cos: "cos", sp.exp: "exp", sp.tan: "tan"}


def float_value(expr, values: dict, digits: int | None = None) -> tuple[float, float] | None:
    """``(value, magnitude)`` of ``expr`` with ``values`` for its symbols, in floating point (or with ``digits``
    decimal digits, by mpmath), where ``magnitude`` — the same evaluation with every addend's absolute value —
    bounds the rounding error relative to the working precision; None when ``expr`` has nodes other than sums,
    products, powers, numbers, ``sin``, ``cos``, ``tan`` and ``exp``.  Shared sub-expressions are evaluated once."""
    if digits is None:
        num, fsum, funcs = float, math.fsum, _float_funcs()
    else:
        import mpmath

        ctx = mpmath.MPContext()
        ctx.dps = digits
        num, fsum = ctx.mpf, ctx.fsum
        funcs = {f: getattr(ctx, name) for f, name in _mp_funcs().items()}
        values = {s: ctx.mpf(x) for s, x in values.items()}
    memo: dict = {}

    def ev(e):
        out = memo.get(e)
        if out is not None:
            return out
        if e.is_Symbol:
            x = values[e]
            out = (x, abs(x))
        elif e.is_Rational:
            x = num(e.p) / e.q
            out = (x, abs(x))
        elif e.is_Float or e.is_NumberSymbol:  # 9.81, pi
            x = num(e.evalf(digits + 5)._mpf_) if digits is not None else float(e)
            out = (x, abs(x))
        elif e.is_Add:
            parts = [ev(a) for a in e.args]
            out = (fsum(p[0] for p in parts), fsum(p[1] for p in parts))
        elif e.is_Mul:
            x = m = num(1)
            for a in e.args:
                xa, ma = ev(a)
                x *= xa
                m *= ma
            out = (x, m)
        elif e.is_Pow:
            (xb, mb), (xe, _) = ev(e.args[0]), ev(e.args[1])
            if xb < 0 and not e.args[1].is_integer:
                raise ValueError
            x = xb**xe
            out = (x, max(abs(x), mb**xe if mb > 0 else num(0)))
        elif e.func in funcs:
            xa, ma = ev(e.args[0])
            x = funcs[e.func](xa)
            slope = {sp.sin: 1, sp.cos: 1, sp.exp: abs(x), sp.tan: 1 + x * x}[e.func]
            out = (x, abs(x) + slope * ma)  # the argument's rounding, carried through
        else:
            raise ValueError
        memo[e] = out
        return out

    try:
        return ev(expr)
    except (ValueError, KeyError, ZeroDivisionError, OverflowError, TypeError):
        return None
