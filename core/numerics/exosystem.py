"""Inputs as outputs of an exosystem: the input class the exact solution of :mod:`lagrangian.numerics.linear` takes.

An input that is a combination of constants, powers of ``t``, ``exp(α t)``,
``sin``/``cos(ω t + φ)`` and their products is ``s = C w`` with ``ẇ = S w``:
a rotation block per frequency and a nilpotent chain per power of ``t``.
:func:`_exosystem` finds ``S``, ``C`` and ``w(0)`` from the inputs' SymPy
expressions (expanded into exponentials, under a wall-time budget for inputs
with nested functions of ``t``) and checks them against the expressions.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..base.budget import BudgetExceeded, interruptible
from ..base import waveforms as _waveforms
from ..base.component import t
from ..base import deferred as _deferred

sp = _deferred.module("sympy", globals())


class _Unrepresentable(Exception):
    """An input term outside the exosystem class: ``args = (term,)`` or ``(term, channel index)``."""


class _TooLarge(_Unrepresentable):
    """An input that could not be expanded into exponentials within :data:`EXPAND_SECONDS` (``sin(sin(sin(t)))``,
    whose expansion grows without end, is never of the form anyway)."""


#: Wall time in which an input with nested functions of ``t`` or high powers must expand into exponentials;
#: past it the input counts as not of the exact solver's form (``method="auto"`` then integrates it).
EXPAND_SECONDS = 1.5
#: A power of a function of ``t`` up to this is expanded without a budget (a flat input never takes long).
_FLAT_POWER = 8


@dataclass
class _Exosystem:
    """``ẇ = S w``, ``w(0) = w0``, ``s(τ) = C w(τ)``; one block per (α, ω), ``order`` powers of τ each."""

    S: np.ndarray
    C: np.ndarray
    w0: np.ndarray
    modes: list[tuple[float, float, int]]

    def states(self, taus: np.ndarray) -> np.ndarray:
        """``w(τ) = e^{S τ} w0`` at many ``τ`` in closed form, one row each (``w0`` is :meth:`basis` at 0)."""
        cols = []
        for alpha, omega, order in self.modes:
            env = np.exp(alpha * taus)
            for k in range(order + 1):
                p = taus**k / math.factorial(k) * env
                cols += [p * np.cos(omega * taus), p * np.sin(omega * taus)] if omega else [p]
        return np.column_stack(cols) if cols else np.zeros((np.size(taus), 0))

    def basis(self, tau: float) -> np.ndarray:
        """``w(τ)`` in closed form (for checking)."""
        with np.errstate(over="ignore", invalid="ignore"):
            return self.states(np.array([float(tau)]))[0]


def _flat(expr: sp.Expr) -> bool:
    """Whether ``expr`` expands quickly: no function of ``t`` inside another's argument, no high power of one."""
    timed = [f for f in expr.atoms(sp.Function) if t in f.free_symbols]
    if any(g is not f and t in g.free_symbols for f in timed for a in f.args for g in a.atoms(sp.Function)):
        return False
    return not any(p.exp.is_Number and abs(p.exp) > _FLAT_POWER and t in p.base.free_symbols
                   for p in expr.atoms(sp.Pow))


def _exp_terms(expr: sp.Expr) -> dict[tuple[int, complex], complex]:
    """``expr`` as ``Σ c τ^k e^{λτ}`` (``t`` plays τ): a map ``(k, λ) → c``; raises :class:`_Unrepresentable`, or
    :class:`_TooLarge` when an input that is not flat does not expand within :data:`EXPAND_SECONDS`."""
    expr = sp.sympify(expr)
    read = _read_off(expr)
    if read is not None:
        return read
    if _flat(expr):
        return _terms(expr)
    try:
        return interruptible(_terms, expr, seconds=EXPAND_SECONDS)
    except BudgetExceeded:
        raise _TooLarge(expr) from None


def _read_off(expr: sp.Expr) -> dict[tuple[int, complex], complex] | None:
    """:func:`_exp_terms` of a sum whose every term is a constant times a power of ``t`` and at most one ``sin``,
    ``cos`` or ``exp`` of ``a t + b``, read off the expression as it stands: no rewriting into exponentials and no
    expansion (for ``sin(300 t)``, 1 ms against 15 ms).  ``None`` for any other form, which :func:`_terms` expands.
    """
    out: dict[tuple[int, complex], complex] = {}
    for term in sp.Add.make_args(expr):
        constants, power, wave = [], 0, None
        for factor in sp.Mul.make_args(term):
            if t not in factor.free_symbols:
                constants.append(factor)
            elif factor == t:
                power += 1
            elif factor.is_Pow and factor.base == t and factor.exp.is_Integer and factor.exp > 0:
                power += int(factor.exp)
            elif wave is None and isinstance(factor, (sp.sin, sp.cos, sp.exp)):
                offset, varying = factor.args[0].as_independent(t, as_Add=True)
                slope, rest = varying.as_independent(t, as_Add=False)
                if rest != t:
                    return None
                wave = (factor.func, slope, offset)
            else:
                return None
        if power > _FLAT_POWER:  # a high power of t: the expansion's path, with its budget and checks
            return None
        try:
            c = complex(sp.Mul(*constants))
            if wave is not None:
                slope, offset = complex(wave[1]), complex(wave[2])
        except (TypeError, ValueError):
            return None
        if wave is None:
            parts = [(0j, c)]
        elif wave[0] is sp.exp:
            parts = [(slope, c * np.exp(offset))]
        else:  # cos z = (e^{iz} + e^{−iz}) / 2, sin z = (e^{iz} − e^{−iz}) / 2i
            plus, minus = c * np.exp(1j * offset) / 2, c * np.exp(-1j * offset) / 2
            parts = [(1j * slope, plus), (-1j * slope, minus)] if wave[0] is sp.cos else \
                [(1j * slope, plus / 1j), (-1j * slope, -minus / 1j)]
        for lam, coeff in parts:
            if not (np.isfinite(lam) and np.isfinite(coeff)):
                return None
            out[power, lam] = out.get((power, lam), 0) + coeff
    return out


def _terms(expr: sp.Expr) -> dict[tuple[int, complex], complex]:
    """:func:`_exp_terms` without a budget."""
    out: dict[tuple[int, complex], complex] = {}
    expanded = sp.expand(expr.rewrite(sp.exp))
    for term in sp.Add.make_args(expanded):
        coeff, power, lam = sp.Integer(1), 0, sp.Integer(0)
        for factor in sp.Mul.make_args(term):
            if t not in factor.free_symbols:
                coeff *= factor
            elif factor == t:
                power += 1
            elif factor.is_Pow and factor.base == t and factor.exp.is_Integer and factor.exp > 0:
                power += int(factor.exp)
            elif isinstance(factor, sp.exp):
                arg = sp.expand(factor.args[0])
                if not arg.is_polynomial(t) or sp.degree(arg, t) > 1:
                    raise _Unrepresentable(term)
                slope = arg.coeff(t, 1)
                lam += slope
                coeff *= sp.exp(sp.expand(arg - slope * t))
            else:
                raise _Unrepresentable(term)
        try:
            c, lam_c = complex(sp.N(coeff)), complex(sp.N(lam))
        except (TypeError, ValueError):
            raise _Unrepresentable(term) from None
        if not (np.isfinite(c) and np.isfinite(lam_c)):
            raise _Unrepresentable(term)
        key = (power, lam_c)
        out[key] = out.get(key, 0) + c
    return out


def _exosystem(channels: Sequence[sp.Expr], length: float) -> _Exosystem:
    """The exosystem whose output is ``channels`` (expressions of τ = ``t``); raises :class:`_Unrepresentable`."""
    terms_of = []
    for i, expr in enumerate(channels):
        try:
            terms_of.append(_exp_terms(expr))
        except _Unrepresentable as exc:
            raise type(exc)(exc.args[0], i) from None
    exo = _from_terms(terms_of)
    _check_exosystem(exo, channels, terms_of, length)
    return exo


def numeric_exosystem(inputs: list, a: float, b: float) -> _Exosystem:
    """The exosystem of inputs given in numbers (waveforms and constants: :mod:`lagrangian.base.waveforms`) on the
    piece ``[a, b]``, in the piece's time ``τ = t − a``; its output checked against the waveforms' values at a few
    times of the piece (a guard, as for expressions)."""
    terms_of = _waveforms.piece_terms(inputs, a, b)
    exo = _from_terms(terms_of)
    taus = np.array([0.25, 0.3819660112501051, 0.9]) * (b - a)  # inside the piece: its ends are switching times
    with np.errstate(over="ignore", invalid="ignore"):
        got = exo.C @ exo.states(taus).T if exo.w0.size else np.zeros((len(inputs), taus.size))
    ref = _waveforms.values(inputs, a + taus)
    for i, terms in enumerate(terms_of):
        scale = np.array([sum(abs(c) * tau**k * math.exp(lam.real * tau) for (k, lam), c in terms.items())
                          for tau in taus])
        ok = ~np.isfinite(scale) | (np.abs(got[i] - ref[i]) <= 1e-9 * scale + 1e-300)
        if not np.all(ok):
            raise _Unrepresentable(inputs[i], i)
    return exo


def _from_terms(terms_of: list[dict[tuple[int, complex], complex]]) -> _Exosystem:
    """The exosystem whose outputs are the channels ``Σ c τ^k e^{λτ}`` (``{(k, λ): c}`` each)."""
    real: list[dict[tuple[float, float, int, int], float]] = []
    for terms in terms_of:
        coeffs: dict[tuple[float, float, int, int], float] = {}
        for (k, lam), c in terms.items():
            if c == 0:  # a term that is not there (a sine's zero offset): no mode for it, which would resonate
                continue  # with a slow mode of the model and cost the particular solution (Propagator)
            alpha, omega, fact = lam.real, lam.imag, math.factorial(k)
            # Re(c τ^k e^{(α+iω)τ}) = τ^k e^{ατ} (Re c cos ωτ − Im c sin ωτ); the input is real.
            key = (alpha, abs(omega), k)
            coeffs[key + (0,)] = coeffs.get(key + (0,), 0.0) + c.real * fact
            if omega:
                sin = -c.imag if omega > 0 else c.imag
                coeffs[key + (1,)] = coeffs.get(key + (1,), 0.0) + sin * fact
        real.append(coeffs)
    orders: dict[tuple[float, float], int] = {}
    for coeffs in real:
        for alpha, omega, k, _ in coeffs:
            orders[(alpha, omega)] = max(orders.get((alpha, omega), 0), k)
    modes = [(a, w, orders[(a, w)]) for a, w in sorted(orders)]
    index: dict[tuple[float, float, int, int], int] = {}
    blocks = []
    for alpha, omega, order in modes:
        width = 2 if omega else 1
        start = len(index)
        for k in range(order + 1):
            for part in range(width):
                index[(alpha, omega, k, part)] = start + width * k + part
        size = width * (order + 1)
        block = np.zeros((size, size))
        for k in range(order + 1):
            if omega:
                c, s_ = 2 * k, 2 * k + 1
                block[c, c] = block[s_, s_] = alpha
                block[c, s_], block[s_, c] = -omega, omega  # d/dτ (cos, sin) = ω (−sin, cos)
                if k:
                    block[c, c - 2] = block[s_, s_ - 2] = 1.0  # d/dτ τ^k/k! = τ^{k−1}/(k−1)!
            else:
                block[k, k] = alpha
                if k:
                    block[k, k - 1] = 1.0
        blocks.append((start, block))
    nw = len(index)
    S = np.zeros((nw, nw))
    for start, block in blocks:
        S[start : start + block.shape[0], start : start + block.shape[0]] = block
    C = np.zeros((len(terms_of), nw))
    for i, coeffs in enumerate(real):
        for key, value in coeffs.items():
            C[i, index[key]] += value
    w0 = np.zeros(nw)
    for alpha, omega, _ in modes:
        w0[index[(alpha, omega, 0, 0)]] = 1.0
    return _Exosystem(S, C, w0, modes)


def _check_exosystem(exo: _Exosystem, channels, terms_of, length: float) -> None:
    """The exosystem's output equals each channel at a few times in ``[0, length]`` (a guard, not a proof)."""
    for tau in (0.0, 0.3819660112501051 * length, length):
        w = exo.basis(tau)
        for i, expr in enumerate(channels):
            try:
                ref = complex(sp.N(expr.xreplace({t: sp.Float(tau)})))
            except (TypeError, ValueError):
                raise _Unrepresentable(expr, i) from None
            got = float(exo.C[i] @ w) if w.size else 0.0
            scale = sum(abs(c) * tau**k * math.exp(lam.real * tau) for (k, lam), c in terms_of[i].items())
            if not (np.isfinite(ref) and np.isfinite(scale)):
                continue
            if abs(got - ref.real) > 1e-9 * scale + 1e-300 or abs(ref.imag) > 1e-9 * scale + 1e-300:
                raise _Unrepresentable(expr, i)
