"""SPICE's source waveforms in numbers: what a netlist's ``SIN`` and ``PULSE`` sources hold.

A waveform is a signal of time given by numbers alone.  It gives its values on a grid, the times at which it
switches between pieces, and on each piece its terms ``Σ c τ^k e^{λτ}`` in the piece's own time ``τ = t − a`` (the
exponential modes the exact solution's exosystem is built from: :mod:`lagrangian.numerics.exosystem`), all in
floating point, without SymPy.  Its SymPy expression of ``t`` (:meth:`Waveform.expr`, what the symbolic
derivation, LaTeX and the SPICE deck read) is made when first asked for; SymPy reads a waveform as that
expression (``_sympy_``).  The semantics are ngspice's (39): ``SIN(VO VA FREQ TD THETA PHASE)`` holds
``VO + VA sin(PHASE)`` until ``TD``, then ``VO + VA e^{−THETA (t − TD)} sin(2π FREQ (t − TD) + PHASE)``, the phase in
degrees; ``PULSE(V1 V2 TD TR TF PW PER NP)`` is a trapezoid repeated every ``PER`` from ``TD`` (``NP`` times where
``NP > 0``).

>>> import numpy as np
>>> w = Sine(0.5, 2.0, 50.0, delay=0.01)
>>> w(np.array([0.0, 0.015]))                       # VO until the delay, a quarter period after it the crest
array([0.5, 2.5])
>>> w.cuts(0.0, 1.0)
[0.01]
>>> p = Pulse(0.0, 5.0, 1e-3, 1e-4, 1e-4, 4e-4, 1e-3)
>>> p(np.array([0.5e-3, 1.05e-3, 1.3e-3, 1.55e-3, 1.8e-3]))
array([0. , 2.5, 5. , 2.5, 0. ])
"""

from __future__ import annotations

import cmath
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from . import deferred as _deferred

__all__ = ["Pulse", "Sine", "Waveform", "cuts", "is_numeric", "numeric", "piece_terms", "value_at", "values"]

sp = _deferred.module("sympy", globals())

#: At most this many switching times of one waveform within one run (a pulse train of a 1 µs period over 10 s would
#: be 4·10⁷ pieces): past it the run is refused, as the exact solution refuses other piecewise inputs.
MAX_CUTS = 200_000


class Waveform:
    """A signal of time given in numbers (see the module documentation): frozen, hashable, comparable."""

    def __call__(self, times: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def cuts(self, lo: float, hi: float) -> list[float]:
        """The times in ``(lo, hi)`` at which the waveform switches between pieces, increasing."""
        raise NotImplementedError

    def terms(self, a: float, b: float) -> dict[tuple[int, complex], complex]:
        """The waveform on the piece ``[a, b]`` (no switch inside) as ``{(k, λ): c}``: ``Σ c τ^k e^{λτ}``,
        ``τ = t − a``."""
        raise NotImplementedError

    def expr(self) -> Any:
        """The SymPy expression of :data:`lagrangian.t` this waveform stands for (made on first call)."""
        made = self.__dict__.get("_expr")
        if made is None:
            made = self._expression(_deferred.time_symbol())
            object.__setattr__(self, "_expr", made)
        return made

    def _expression(self, t: Any) -> Any:
        raise NotImplementedError

    def _sympy_(self) -> Any:
        return self.expr()

    def __getstate__(self) -> dict:
        return {k: v for k, v in self.__dict__.items() if k != "_expr"}

    def __setstate__(self, state: dict) -> None:
        for k, v in state.items():
            object.__setattr__(self, k, v)


@dataclass(frozen=True, eq=True)
class Sine(Waveform):
    """SPICE's ``SIN(VO VA FREQ TD THETA PHASE)``: ``offset``, ``amplitude``, ``frequency`` (Hz), ``delay`` (s),
    ``damping`` (1/s), ``phase`` (degrees)."""

    offset: float
    amplitude: float
    frequency: float
    delay: float = 0.0
    damping: float = 0.0
    phase: float = 0.0

    def __call__(self, times: np.ndarray) -> np.ndarray:
        times = np.asarray(times, dtype=float)
        phi = math.radians(self.phase)
        x = times - self.delay
        with np.errstate(over="ignore"):
            body = self.offset + self.amplitude * np.exp(-self.damping * x) * np.sin(2 * math.pi * self.frequency * x + phi)
        if self.delay > 0:
            return np.where(times <= self.delay, self.offset + self.amplitude * math.sin(phi), body)
        return body

    def cuts(self, lo: float, hi: float) -> list[float]:
        return [self.delay] if self.delay > 0 and lo < self.delay < hi else []

    def terms(self, a: float, b: float) -> dict[tuple[int, complex], complex]:
        phi = math.radians(self.phase)
        if self.delay > 0 and (a + b) / 2 <= self.delay:
            return {(0, 0j): complex(self.offset + self.amplitude * math.sin(phi))}
        # VA e^{−θx} sin(ωx + φ), x = τ + x0: (VA/2i) (e^{iφ'} e^{λτ} − e^{−iφ'} e^{λ̄τ}), λ = −θ + iω
        x0 = a - self.delay
        omega = 2 * math.pi * self.frequency
        scale = self.amplitude * math.exp(-self.damping * x0)
        turn = cmath.exp(1j * (omega * x0 + phi))
        out = {(0, 0j): complex(self.offset)}
        if scale:
            if omega:
                out[(0, complex(-self.damping, omega))] = scale * turn / 2j
                out[(0, complex(-self.damping, -omega))] = -scale * turn.conjugate() / 2j
            else:
                out[(0, complex(-self.damping, 0.0))] = complex(scale * math.sin(phi))
        return out

    def _expression(self, t: Any) -> Any:
        phi = sp.Float(self.phase) * sp.pi / 180
        x = t - sp.Float(self.delay)
        damping = sp.exp(-sp.Float(self.damping) * x) if self.damping else 1
        vo, va = sp.Float(self.offset), sp.Float(self.amplitude)
        body = vo + va * sp.sin(2 * sp.pi * sp.Float(self.frequency) * x + phi) * damping
        if self.delay > 0:
            return sp.Piecewise((vo + va * sp.sin(phi), t <= sp.Float(self.delay)), (body, True))
        return body


@dataclass(frozen=True, eq=True)
class Pulse(Waveform):
    """SPICE's ``PULSE(V1 V2 TD TR TF PW PER NP)``: ``low``, ``high``, ``delay``, ``rise``, ``fall``, ``width``,
    ``period`` (s), ``count`` (periods, perhaps a fraction: the pulse stops ``count`` periods after the delay; 0:
    repeated for ever); ``rise`` and ``fall`` positive."""

    low: float
    high: float
    delay: float
    rise: float
    fall: float
    width: float
    period: float
    count: float = 0.0

    def _edges(self) -> tuple[float, float, float]:
        return self.rise, self.rise + self.width, self.rise + self.width + self.fall

    def __call__(self, times: np.ndarray) -> np.ndarray:
        times = np.asarray(times, dtype=float)
        up, top, down = self._edges()
        s = np.mod(times - self.delay, self.period)
        out = np.select(
            [s < up, s <= top, s < down],
            [self.low + (self.high - self.low) * s / self.rise, np.full(times.shape, self.high),
             self.high + (self.low - self.high) * (s - top) / self.fall],
            self.low,
        )
        off = times <= self.delay
        if self.count > 0:
            off |= times >= self.delay + self.count * self.period
        return np.where(off, self.low, out)

    def cuts(self, lo: float, hi: float) -> list[float]:
        up, top, down = self._edges()
        first = max(0, math.floor((lo - self.delay) / self.period))
        last = math.floor((hi - self.delay) / self.period)
        if self.count > 0:
            last = min(last, math.ceil(self.count) - 1)
        if last - first + 1 > MAX_CUTS // 4:
            raise ValueError(f"a pulse of period {self.period:g} s switches more than {MAX_CUTS} times in "
                             f"[{lo:g}, {hi:g}]")
        out = []
        for k in range(first, last + 1):
            start = self.delay + k * self.period
            out += [start, start + up, start + top, start + down]
        if self.count > 0:
            out.append(self.delay + self.count * self.period)
        return sorted({c for c in out if lo < c < hi})

    def terms(self, a: float, b: float) -> dict[tuple[int, complex], complex]:
        mid = (a + b) / 2
        up, top, down = self._edges()
        if mid <= self.delay or (self.count > 0 and mid >= self.delay + self.count * self.period):
            return {(0, 0j): complex(self.low)}
        start = self.delay + math.floor((mid - self.delay) / self.period) * self.period
        s = a - start  # the piece's start within its period
        m = mid - start
        if m < up:
            slope = (self.high - self.low) / self.rise
            return {(0, 0j): complex(self.low + slope * s), (1, 0j): complex(slope)}
        if m <= top:
            return {(0, 0j): complex(self.high)}
        if m < down:
            slope = (self.low - self.high) / self.fall
            return {(0, 0j): complex(self.high + slope * (s - top)), (1, 0j): complex(slope)}
        return {(0, 0j): complex(self.low)}

    def _expression(self, t: Any) -> Any:
        v1, v2, td, tr, tf, pw, per = map(sp.Float, (self.low, self.high, self.delay, self.rise, self.fall,
                                                      self.width, self.period))
        s = sp.Mod(t - td, per)
        pieces = [(v1, t <= td)]
        if self.count > 0:
            pieces.append((v1, t >= td + sp.Float(self.count) * per))
        pieces += [
            (v1 + (v2 - v1) * s / tr, s < tr),
            (v2, s <= tr + pw),
            (v2 + (v1 - v2) * (s - tr - pw) / tf, s < tr + pw + tf),
            (v1, True),
        ]
        return sp.Piecewise(*pieces)


def numeric(x: Any) -> bool:
    """Whether ``x`` is a waveform or a plain number (a Python ``int`` or ``float``): a signal given in numbers."""
    return type(x) in (int, float) or isinstance(x, Waveform)


def value_at(x: Any, time: float) -> float:
    """The signal ``x`` given in numbers (:func:`numeric`) at ``time``."""
    return float(x(np.array([float(time)]))[0]) if isinstance(x, Waveform) else float(x)


def is_numeric(inputs: Any) -> bool:
    """Whether every input is a waveform or a plain number: what :func:`values`, :func:`cuts` and
    :func:`piece_terms` take."""
    return all(numeric(x) for x in inputs)


def values(inputs: list, times: np.ndarray) -> np.ndarray:
    """The inputs at ``times``, one row each."""
    times = np.asarray(times, dtype=float)
    return np.array([x(times) if isinstance(x, Waveform) else np.full(times.shape, float(x)) for x in inputs]
                    ).reshape(len(inputs), times.size)


def cuts(inputs: list, lo: float, hi: float) -> list[float]:
    """The switching times of all the inputs in ``(lo, hi)``, increasing."""
    found = sorted({c for x in inputs if isinstance(x, Waveform) for c in x.cuts(lo, hi)})
    if len(found) > MAX_CUTS:
        raise ValueError(f"the inputs switch more than {MAX_CUTS} times in [{lo:g}, {hi:g}]")
    return found


def piece_terms(inputs: list, a: float, b: float) -> list[dict[tuple[int, complex], complex]]:
    """Each input on the piece ``[a, b]`` as ``{(k, λ): c}`` (see :meth:`Waveform.terms`)."""
    return [x.terms(a, b) if isinstance(x, Waveform) else ({(0, 0j): complex(x)} if x else {}) for x in inputs]
