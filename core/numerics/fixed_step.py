"""Fixed-step methods: one step from the subclass (:class:`Stepper`), the loop from :class:`FixedStepIntegrator`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import ModelError
from ..plugin.contracts import Integrator, Solution
from .problem import Problem


#: A fixed-step run takes at most this many steps.
MAX_STEPS = 100_000_000
#: ... and has diverged when its state grows beyond this many times its initial size (or 1).
_DIVERGED = 1e30

# ---------------------------------------------------------------------------
# Fixed-step methods: one step from the subclass, the loop from here
# ---------------------------------------------------------------------------


def _identity(t: float, y: np.ndarray) -> np.ndarray:
    return y


@dataclass
class Stepper:
    """One step of a fixed-step method, prepared for one run with step size ``h``.

    ``step(t, z)`` maps the method's internal state at ``t`` to that at
    ``t + h`` (it may update ``z`` in place and return it: the driver
    copies what it keeps); ``to_internal(t, y)`` and ``to_state(t, z)`` convert between
    the model's state ``y = (q, q̇_inertial)`` and the internal one (for
    example ``(q, p)``, or ``(q, q̇, q̈)`` to reuse an acceleration).
    """

    step: Callable[[float, np.ndarray], np.ndarray]
    to_internal: Callable[[float, np.ndarray], np.ndarray] = _identity
    to_state: Callable[[float, np.ndarray], np.ndarray] = _identity


class FixedStepIntegrator(Integrator):
    """A fixed-step method: subclasses provide :meth:`stepper`; this class runs the steps.

    ``solve`` takes ``step`` (required: the largest step size) and
    ``fast_linear`` (default True).  The steps are uniform, ``h = span / N``
    with ``N = ⌈span / step⌉``; when the output times are evenly spaced and
    no closer than ``step``, ``h`` divides their spacing instead, so that
    every output is a step.  Outputs between steps are cubic Hermite
    interpolants (error O(h⁴); noted in ``Result.notes``).

    For a linear time-invariant model (``problem.structure.linear``) the
    one-step map is one constant affine map ``z ↦ R z + r``, whatever the
    method; with ``fast_linear`` it is measured by applying :meth:`stepper`'s
    own step to the unit vectors, and outputs ``k`` steps apart are
    advanced by ``[R r; 0 1]^k`` — the same iterates, in O(log k) work,
    which makes runs of 10⁵ periods cheap.
    """

    kind = "fixed-step"

    def stepper(self, problem: Problem, h: float, **options: Any) -> Stepper:
        """The :class:`Stepper` of this method for ``problem`` with step size ``h``."""
        raise NotImplementedError

    def solve(self, problem, t_span, y0, t_eval, *, step=None, fast_linear=True, **options):
        """Integrate with uniform steps of at most ``step`` (see the class documentation)."""
        t0, t1 = map(float, t_span)
        t_eval = np.asarray(t_eval, dtype=float)
        h, N, notes = _grid(self.name, problem, t0, t1, t_eval, step, np.asarray(y0, dtype=float))
        stepper = self.stepper(problem, h, **options)
        k_float = (t_eval - t0) / h
        k_round = np.rint(k_float)
        on_grid = np.abs(k_float - k_round) < 1e-7
        lo = np.where(on_grid, k_round, np.floor(k_float)).astype(np.int64).clip(0, N)
        hi = np.where(on_grid, lo, np.minimum(lo + 1, N))
        needed = np.unique(np.concatenate([lo, hi]))
        start = problem.nfev
        z0 = np.array(stepper.to_internal(t0, np.array(y0, dtype=float)), dtype=float)
        if fast_linear and problem.structure.linear:
            store, status, message = _march_linear(stepper, t0, h, z0, needed)
            notes.append(
                f"{self.name}: the model is linear time-invariant, so the one-step map is a constant matrix; "
                f"outputs were advanced by its powers ({N} steps of h = {h:.6g}; fast_linear=False steps one by one)"
            )
        else:
            store, status, message = _march(stepper, problem, t0, h, N, z0, needed)
        Y = np.full((problem.dim, t_eval.size), np.nan)
        states = {k: stepper.to_state(t0 + k * h, z) for k, z in store.items()}
        interpolated = 0
        slopes: dict[int, np.ndarray] = {}
        for i in range(t_eval.size):
            a, b = int(lo[i]), int(hi[i])
            if a not in states or b not in states:
                break
            if a == b:
                Y[:, i] = states[a]
                continue
            for k in (a, b):
                if k not in slopes:
                    slopes[k] = problem.rhs(t0 + k * h, states[k])
            s = (t_eval[i] - (t0 + a * h)) / h
            h00, h10, h01, h11 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s, -2 * s**3 + 3 * s**2, s**3 - s**2
            Y[:, i] = h00 * states[a] + h10 * h * slopes[a] + h01 * states[b] + h11 * h * slopes[b]
            interpolated += 1
        if interpolated:
            notes.append(f"{interpolated} output time(s) fall between steps: cubic Hermite interpolation (error O(h⁴))")
        done = np.all(np.isfinite(Y), axis=0)
        count = int(np.argmin(done)) if not done.all() else t_eval.size
        return Solution(t_eval[:count], Y[:, :count], problem.nfev - start, status, message, notes, h)


def _grid(name, problem, t0, t1, t_eval, step, y0) -> tuple[float, int, list[str]]:
    """Step size and count for a fixed-step run; a clear error without a usable ``step``."""
    span = t1 - t0
    if step is None:
        raise _missing_step(name, problem, t0, y0)
    try:
        step = float(step)
    except (TypeError, ValueError):
        raise ModelError(f"step must be a positive number, got {step!r}.") from None
    if not (step > 0 and math.isfinite(step)):
        raise ModelError(f"step must be a positive number, got {step!r}.")
    notes = []
    d = np.diff(t_eval)
    uniform = d.size > 0 and np.allclose(d, d[0], rtol=1e-9, atol=0) and abs(t_eval[0] - t0) <= 1e-12 * max(1.0, abs(t0)) + 1e-12 * span
    if uniform and d[0] >= step * (1 - 1e-12) and abs(t_eval[-1] - t1) <= 1e-9 * span:
        m = math.ceil(d[0] / step - 1e-9)
        h = float(d[0] / m)
        N = m * d.size
    else:
        N = math.ceil(span / step - 1e-9)
        h = span / N
    if N > MAX_STEPS:
        raise ModelError(f"{name}: step={step:g} over a span of {span:g} takes {N:,} steps (more than {MAX_STEPS:,}); use a larger step.")
    if abs(h - step) > 1e-9 * step:
        notes.append(f"{name}: step {step:.6g} shortened to {h:.6g} so that {N} equal steps land on the output times")
    return h, N, notes


def _missing_step(name: str, problem: Problem, t0: float, y0: np.ndarray) -> ModelError:
    hint = ""
    try:
        lam = problem.eigenvalues(t0, y0)
        rho = float(np.max(np.abs(lam))) if lam.size else 0.0
    except Exception:  # the hint is a courtesy; the error is the message
        rho = 0.0
    if rho > 0:
        hint = (f", e.g. step={2 * math.pi / rho / 50:.3g} (1/50 of the shortest period 2π/|λ|max = {2 * math.pi / rho:.3g} "
                f"of the linearization at t={t0:g})")
    return ModelError(f"{name} is a fixed-step method: give its step size, simulate(..., method={name!r}, step=...){hint}.")


def _march(stepper: Stepper, problem: Problem, t0: float, h: float, N: int, z: np.ndarray, needed: np.ndarray):
    """Take ``N`` steps, keeping the internal states at the step indices ``needed``."""
    store: dict[int, np.ndarray] = {}
    wanted = [int(k) for k in needed]
    pos = 0
    if wanted and wanted[0] == 0:
        store[0] = z.copy()
        pos = 1
    nxt = wanted[pos] if pos < len(wanted) else N + 1
    check = max(1, min(1000, N // 50))
    step = stepper.step
    limit = _DIVERGED * max(1.0, float(np.max(np.abs(z))) if z.size else 1.0)
    with np.errstate(over="ignore", invalid="ignore"):
        for k in range(1, N + 1):
            z = step(t0 + (k - 1) * h, z)
            if k == nxt:
                store[k] = z.copy()
                pos += 1
                nxt = wanted[pos] if pos < len(wanted) else N + 1
            if k % check == 0:
                problem.report(t0 + k * h)
                if not np.all(np.abs(z) < limit):
                    return store, -1, f"the state diverged (beyond 1e30 times its initial size, or non-finite) by t={t0 + k * h:g} (step {k} of {N})"
    if not np.all(np.abs(z) < limit):
        return store, -1, f"the state diverged (beyond 1e30 times its initial size, or non-finite) by t={t0 + N * h:g}"
    return store, 0, ""


def _march_linear(stepper: Stepper, t0: float, h: float, z0: np.ndarray, needed: np.ndarray):
    """The same iterates as :func:`_march` for an affine time-invariant step map, by powers of that map."""
    d = z0.size
    r = np.array(stepper.step(t0, np.zeros(d)), dtype=float)
    R = np.empty((d, d))
    for j in range(d):
        e = np.zeros(d)
        e[j] = 1.0
        R[:, j] = np.array(stepper.step(t0, e), dtype=float) - r
    P = np.zeros((d + 1, d + 1))
    P[:d, :d], P[:d, d], P[d, d] = R, r, 1.0
    powers: dict[int, np.ndarray] = {}
    store: dict[int, np.ndarray] = {}
    z, at = np.append(z0, 1.0), 0
    limit = _DIVERGED * max(1.0, float(np.max(np.abs(z0))) if d else 1.0)
    with np.errstate(over="ignore", invalid="ignore"):
        for k in (int(x) for x in needed):
            if k > at:
                gap = k - at
                if gap not in powers:
                    powers[gap] = np.linalg.matrix_power(P, gap)
                z = powers[gap] @ z
                at = k
            if not np.all(np.abs(z[:d]) < limit):
                return store, -1, f"the state diverged (beyond 1e30 times its initial size, or non-finite) by t={t0 + k * h:g} (step {k})"
            store[k] = z[:d].copy()
    return store, 0, ""
