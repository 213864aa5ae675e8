"""Eigenvalues of a steady motion against its speed: a bicycle's weave and capsize, a rolling disc's lean.

A steady motion whose rates are ``v`` times fixed ones (``velocity=`` at unit
speed) linearizes, in Kane's independent coordinates and speeds
(:meth:`~lagrangian.analysis.linearize.LinearModel.state_space`), to a state
matrix ``A(v)`` that is a polynomial of degree two in ``v``: the forcing is
quadratic in the rates, the constraints on velocities linear, the mass
matrix free of them.  :func:`speed_sweep` therefore linearizes the model at
three speeds only, checks the quadratic law at a fourth (a model whose
forces are not polynomial in the rates — dry friction, a callable load —
is linearized at every speed instead), and evaluates ``A(v)`` wherever it
is asked: a hundred speeds cost four linearizations.  Measured on the
Whipple bicycle (``benchmarks/bicycle.py``): 2.0 s for 101 speeds and the
weave and capsize speeds, against 1.4 s for each speed linearized apart.

:meth:`SpeedSweep.crossings` finds the speeds where a mode changes
stability: a real part that changes sign along a branch, refined by
Brent's method on ``A(v)`` — for a complex pair its real part (weave), for a
real root the coefficient of the characteristic polynomial that vanishes
with it (capsize), which unlike the root itself does not mix with the
zero eigenvalues of ignorable coordinates.

>>> import math
>>> import lagrangian as lg
>>> from lagrangian.frequency import speed_sweep
>>> disc = lg.Model("rolling disc", dim=3)
>>> _ = disc.add("disc", "d", "d", m=0.3, radius=0.07)
>>> _ = disc.add("free", "j", ("ground", "d"), sequence="zxz")
>>> _ = disc.add("rolling", "roll", "d", radius=0.07)
>>> _ = disc.add("gravity", "g", g=9.81)
>>> sweep = speed_sweep(disc, [0.1, 0.3, 0.5], at={"z_j": 0.07, "theta_j": math.pi / 2},
...                     velocity={"x_j": 1.0, "psi_j": -1 / 0.07})      # v = 1 m/s: spin v / r
>>> [round(c.speed, 9) for c in sweep.crossings()], round(math.sqrt(9.81 * 0.07 / 3), 9)   # v² = g r / 3
([0.478434949], 0.478434949)
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..base import charts
from ..errors import ModelError
from ..model import Model
from .linearize import linearize

__all__ = ["Crossing", "SpeedSweep", "speed_sweep"]

#: Largest number of principal minors summed for a real root's crossing (beyond it: the root itself).
MINORS_MAX = 20_000


@dataclass(frozen=True)
class Crossing:
    """A speed where a mode changes stability: ``kind`` ``"oscillatory"`` (a complex pair crosses the imaginary
    axis, at ``frequency`` rad/s) or ``"real"`` (a real root passes through zero); ``becomes`` ``"stable"`` or
    ``"unstable"`` as the speed grows."""

    speed: float
    kind: str
    becomes: str
    frequency: float = 0.0


@dataclass
class SpeedSweep:
    """The eigenvalues of a steady motion over ``speeds`` (speeds × states, each row sorted by real part), the state
    names, and the state matrix at any speed (:meth:`state_matrix`)."""

    model: str
    speeds: np.ndarray
    states: list[str]
    eigenvalues: np.ndarray
    coefficients: tuple  # A(v) = A0 + v A1 + v² A2, or None (linearized at every speed)
    exact: bool
    _direct: Any = None

    def __repr__(self) -> str:
        how = "A(v) quadratic in v" if self.exact else "linearized at every speed"
        return (f"<SpeedSweep of {self.model!r}: {len(self.speeds)} speeds from {self.speeds.min():g} to "
                f"{self.speeds.max():g}, {len(self.states)} states, {how}>")

    def state_matrix(self, speed: float) -> np.ndarray:
        """Kane's state matrix ``A(v)`` at ``speed``."""
        if self.coefficients is None:
            return self._direct(float(speed))
        A0, A1, A2 = self.coefficients
        return A0 + speed * A1 + speed * speed * A2

    def _trivial(self) -> int:
        """How many eigenvalues are zero at every speed (ignorable coordinates, the family of steady motions)."""
        scale = max(float(np.max(np.abs(self.eigenvalues), initial=0.0)), 1e-300)
        counts = [int(np.sum(np.abs(row) <= 1e-6 * scale)) for row in self.eigenvalues]
        return max(set(counts), key=counts.count)  # the most common: a speed on a crossing has one more

    def crossings(self) -> list[Crossing]:
        """The speeds inside the sweep where a mode changes stability, refined to round-off, slowest first."""
        import scipy.optimize

        out: list[Crossing] = []
        k = self._trivial()
        n = len(self.states)
        for i in range(len(self.speeds) - 1):
            a, b = float(self.speeds[i]), float(self.speeds[i + 1])
            la, lb = self._nontrivial(self.eigenvalues[i], k), self._nontrivial(self.eigenvalues[i + 1], k)
            # complex pairs: the largest real part among them
            ca, cb = la[la.imag > 1e-9 * np.abs(la)], lb[lb.imag > 1e-9 * np.abs(lb)]
            if len(ca) and len(cb) and len(ca) == len(cb):
                for za in ca:
                    zb = cb[np.argmin(np.abs(cb - za))]
                    if _sign(za) * _sign(zb) < 0:  # a real part of round-off (an undamped pair) has no sign
                        f = self._pair_real(za)
                        v = scipy.optimize.brentq(f, a, b, xtol=1e-15, rtol=4 * np.finfo(float).eps)
                        z = self._nearest(v, za)
                        out.append(Crossing(v, "oscillatory", "unstable" if zb.real > 0 else "stable",
                                            float(abs(z.imag))))
            # real roots through zero: the characteristic polynomial's coefficient of λ^k changes sign
            ra, rb = (sum(_sign(z) > 0 for z in row[np.abs(row.imag) <= 1e-9 * np.abs(row)]) for row in (la, lb))
            if ra != rb and math.comb(n, k) <= MINORS_MAX:
                g = self._coefficient(k)
                if np.sign(g(a)) != np.sign(g(b)):
                    v = scipy.optimize.brentq(g, a, b, xtol=1e-15, rtol=4 * np.finfo(float).eps)
                    out.append(Crossing(v, "real", "unstable" if rb > ra else "stable"))
        return sorted(out, key=lambda c: c.speed)

    @staticmethod
    def _nontrivial(row: np.ndarray, k: int) -> np.ndarray:
        return row[np.argsort(np.abs(row))][k:]

    def _nearest(self, v: float, z: complex) -> complex:
        lam = np.linalg.eigvals(self.state_matrix(v))
        return lam[np.argmin(np.abs(lam - z))]

    def _pair_real(self, z0: complex):
        def f(v):
            lam = np.linalg.eigvals(self.state_matrix(v))
            upper = lam[lam.imag > 0]
            return float(upper[np.argmin(np.abs(upper - z0))].real) if len(upper) else float("nan")
        return f

    def _coefficient(self, k: int):
        """``v ↦`` the sum of the principal minors of order ``n − k`` of ``A(v)``: the coefficient of ``λ^k`` of its
        characteristic polynomial (up to sign), which vanishes where one more eigenvalue is zero."""
        n = len(self.states)
        subsets = [list(c) for c in itertools.combinations(range(n), n - k)]

        def g(v):
            A = self.state_matrix(v)
            return float(sum(np.linalg.det(A[np.ix_(c, c)]) for c in subsets)) if subsets else 1.0
        return g

    @charts.plain
    def plot(self, path: str | None = None, ax=None, ylim: tuple[float, float] | None = None):
        """Real and imaginary parts of the eigenvalues against speed (the bicycle's chart), the zeros every speed shares
        (ignorable coordinates) left out, the speeds where every other mode decays shaded, the crossings marked;
        drawn on ``ax`` when given (a new figure otherwise), ``ylim`` the range of eigenvalues shown; returns the
        Figure."""
        fig, ax = charts.subplots(figsize=(7, 4.5)) if ax is None else (ax.figure, ax)
        k = self._trivial()  # the zeros of ignorable coordinates: left out
        kept = np.array([self._nontrivial(row, k) for row in self.eigenvalues])
        v = np.repeat(self.speeds, kept.shape[1])
        lam = kept.ravel()
        stable = np.all(kept.real < 0, axis=1) if kept.size else np.zeros(len(self.speeds), bool)
        if np.any(stable):
            ax.fill_between(self.speeds, 0, 1, where=stable, transform=ax.get_xaxis_transform(), color="C2",
                            alpha=0.12, label="stable", step="mid")
        ax.plot(v, lam.real, ".", ms=3, label="real part (1/s)")
        ax.plot(v[lam.imag > 0], lam.imag[lam.imag > 0], ".", ms=3, color="0.6", label="imaginary part (rad/s)")
        for c in self.crossings():
            ax.axvline(c.speed, color="C3", lw=0.8, ls="--")
            ax.annotate(f"{c.speed:.4f}", (c.speed, 0), xytext=(3, 6), textcoords="offset points", fontsize=8)
        ax.axhline(0, color="k", lw=0.5)
        ax.set_xlabel("speed")
        ax.set_ylabel("eigenvalue")
        ax.set_title(f"{self.model}: eigenvalues against speed")
        if ylim is not None:
            ax.set_ylim(*ylim)
        ax.legend(fontsize=8)
        fig.tight_layout()
        if path is not None:
            fig.savefig(path, dpi=110)
        return fig


def _sign(z: complex) -> int:
    """The sign of an eigenvalue's real part, 0 when it is round-off against the eigenvalue (an undamped mode)."""
    return 0 if abs(z.real) <= 1e-9 * abs(z) else (1 if z.real > 0 else -1)


def speed_sweep(model: Model, speeds: Sequence[float], *, at: Mapping[str, Any] | None = None,
                velocity: Mapping[str, Any], params: Mapping[str, Any] | None = None, time: float = 0.0,
                tol: float = 1e-8) -> SpeedSweep:
    """Eigenvalues of the steady motion ``at``, with rates ``v · velocity``, for each ``v`` of ``speeds``.

    ``velocity`` gives the rates at unit speed (the bicycle: ``{"x_frame": 1, "theta_rear": 1 / rR,
    "theta_front": 1 / rF}``); ``at``, ``params``, ``time`` and ``tol`` are as for
    :func:`~lagrangian.analysis.linearize.linearize`.  At most 10⁶ speeds.
    """
    v = np.asarray(speeds, dtype=float).ravel() if not isinstance(speeds, (str, bytes)) else np.array([np.nan])
    if not (1 <= v.size <= 1_000_000) or not np.all(np.isfinite(v)):
        raise ModelError(f"speeds must be 1 to 10⁶ finite numbers, got {len(v)} (or a value that is not finite).")
    if not isinstance(velocity, Mapping) or not velocity:
        raise ModelError("velocity= gives the rates of the steady motion at unit speed: a mapping of coordinate names "
                         "to rates, not empty.")
    unit = {k: float(x) for k, x in velocity.items()}

    def lin_at(speed: float):
        lin = linearize(model, at, velocity={k: speed * x for k, x in unit.items()}, inputs=[], outputs=[],
                        params=params, time=time, tol=tol)
        if lin.symbolic:
            raise ModelError(f"model {model.name!r} has parameters without values "
                             f"({', '.join(p.name for p in lin.parameters)}): give them in params=.")
        return lin.state_space()

    lo, hi = float(v.min()), float(v.max())
    nodes = [lo, (lo + hi) / 2, hi] if hi > lo else [lo - 1.0, lo, lo + 1.0]
    built = [lin_at(x) for x in nodes]
    states = built[0][4]
    if any(b[4] != states for b in built):
        raise ModelError(f"model {model.name!r}: its independent speeds change with the speed of the motion "
                         f"({states} against {[b[4] for b in built if b[4] != states][0]}); sweep a narrower range.")
    A = [np.asarray(b[0]) for b in built]
    # A(v) = A0 + v A1 + v² A2 through the three nodes (Newton's divided differences)
    (x0, x1, x2) = nodes
    d01, d12 = (A[1] - A[0]) / (x1 - x0), (A[2] - A[1]) / (x2 - x1)
    A2 = (d12 - d01) / (x2 - x0)
    A1 = d01 - A2 * (x0 + x1)
    A0 = A[0] - A1 * x0 - A2 * x0 * x0
    probe = lo + 0.61803398875 * (hi - lo) if hi > lo else lo + 2.5
    check = np.asarray(lin_at(probe)[0])
    scale = max(float(np.max(np.abs(check))), 1e-300)
    exact = float(np.max(np.abs(A0 + probe * A1 + probe**2 * A2 - check))) <= 1e-9 * scale
    sweep = SpeedSweep(model.name, v, list(states), np.zeros((len(v), len(states)), dtype=complex),
                       (A0, A1, A2) if exact else None, exact, _direct=lambda x: np.asarray(lin_at(x)[0]))
    for i, x in enumerate(v):
        lam = np.linalg.eigvals(sweep.state_matrix(float(x)))
        sweep.eigenvalues[i] = lam[np.lexsort((lam.imag, lam.real))]
    return sweep
