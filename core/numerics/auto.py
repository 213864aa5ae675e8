"""``method="auto"``: a method picked from the model's properties, and why (:func:`choose`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import LagrangianError, ModelError
from .problem import Problem


#: ``method="auto"`` calls a model stiff when its fastest linearized rate exceeds its slowest (or ``1/span``) this much.
STIFFNESS_RATIO = 1e3
#: ... and a conservative run long when it spans this many periods of its fastest mode: RK45's energy error
#: grows by about 0.01–1.5 rtol per period (measured on an oscillator and a double pendulum, rtol 1e-3 to 1e-6),
#: so over this many periods it is 1–150 times the bounded error of a symplectic method stepped for rtol.
LONG_RUN_PERIODS = 100
#: ``choose`` reads the spectrum along a probe run of this many RK45 steps (a start at rest away from equilibrium
#: has a linearization without the frequency of the motion).
PROBE_STEPS = 48

# ---------------------------------------------------------------------------
# method="auto"
# ---------------------------------------------------------------------------


@dataclass
class Choice:
    """What ``method="auto"`` picked: the method's name, options for it, and why (``notes``)."""

    method: str
    options: dict[str, Any]
    notes: list[str]
    eigenvalues: np.ndarray
    stiff: bool = False


def choose(
    problem: Problem,
    t_span: tuple[float, float],
    y0: np.ndarray,
    *,
    rtol: float = 1e-9,
    linear_exact: bool = False,
    integrators: Mapping[str, Any] | None = None,
) -> Choice:
    """Pick a method for ``problem`` from its properties; say why in ``Choice.notes``.

    The spectrum is that of the linearization at the initial state without
    its zero eigenvalues (:meth:`Problem.spectrum`: an ignorable coordinate
    or a free drift is no time scale): ``|λ|max`` is the fastest rate,
    ``|λ|min`` the slowest.

    1. ``linear_exact`` (the model is linear time-invariant with inputs the
       exact solver takes): ``"exact"`` — no integration error at all.
    2. Stiff — ``|λ|max`` exceeds ``max(|λ|min, 1/span)`` more than
       :data:`STIFFNESS_RATIO` times: ``LSODA``, whose BDF formulas take
       over once it detects the stiffness (on the stiff benchmarks it
       needed 2–10 times fewer evaluations than ``Radau`` and ``BDF`` at
       tolerances from 1e-3 to 1e-9).  Never an explicit method.
    3. Conservative (no dissipation, no applied forces, ``L`` independent
       of ``t``) at a loose tolerance (``rtol ≥ 1e-6``), and a run of at
       least :data:`LONG_RUN_PERIODS` periods of the fastest mode: a
       symplectic fixed-step method, whose energy error stays bounded
       instead of drifting — ``verlet`` with ``h·ω = √(8 rtol)`` for a
       separable Lagrangian, ``gauss_legendre`` with ``h·ω = rtol^¼``
       otherwise (their energy errors are about ``(hω)²/8`` and
       ``(hω)⁴``) — unless that takes more than 2·10⁶ steps.  The fastest
       mode is the largest ``|λ|`` at the initial state and at a few states
       of a short probe run (:data:`PROBE_STEPS` steps of RK45): a start at
       rest away from equilibrium (a pendulum let go from the horizontal)
       has a linearization with no frequency in it at all.
    4. Otherwise ``DOP853`` for ``rtol ≤ 1e-6`` and ``RK45`` above
       (scipy's advice for high and moderate precision).

    >>> import lagrangian as lg
    >>> m = lg.Model("pendulum", dim=2)
    >>> _ = m.add("link", "arm", "arm", points={"bob": (0.7, 0)})
    >>> _ = m.add("revolute", "pin", ("ground", "arm"))
    >>> _ = m.add("mass", "bob", "arm.bob", m=0.3)
    >>> _ = m.add("gravity", "g")
    >>> choose(Problem(m.numeric()), (0.0, 1000.0), np.zeros(2), rtol=1e-4).method   # let go from the horizontal
    'verlet'
    >>> choose(Problem(m.numeric()), (0.0, 2.0), np.zeros(2), rtol=1e-4).method
    'RK45'
    """
    t0, t1 = map(float, t_span)
    span = t1 - t0
    y0 = np.asarray(y0, dtype=float)
    structure = problem.structure
    spec = problem.spectrum(t0, y0)
    lam = spec.eigenvalues
    rho, slowest = spec.rho, spec.slowest
    slow = max(slowest, 1.0 / span)
    ratio = rho / slow
    stiff = ratio > STIFFNESS_RATIO
    what = "conservative" if structure.conservative else "not conservative (" + structure.why.get("conservative", "constraints") + ")"
    zeros = int(spec.zero.sum())
    spectrum = (
        f"eigenvalues of the linearization at t={t0:g}: |λ| from {slowest:.3g} to {rho:.3g}"
        + (f" and {zeros} zero (ignorable coordinates, drifts)" if zeros else "")
        + f" (ratio to max(slowest, 1/span) {ratio:.3g}; stiff above {STIFFNESS_RATIO:.0e})"
    )
    available = integrators if integrators is not None else {}

    def pick(method: str, reason: str, options: dict | None = None) -> Choice:
        if integrators is not None and method not in available and method != "exact":
            raise ModelError(f"method='auto' picked {method!r} ({reason}), but no installed plugin provides it.")
        note = f"auto: picked {method!r}: {reason}; {spectrum}; model {what}; rtol {rtol:.1e}"
        return Choice(method, options or {}, [note], lam, stiff)

    if linear_exact:
        return pick("exact", "the model is linear time-invariant, so it is solved exactly by matrix exponentials (no tolerance applies)")
    if stiff:
        return pick("LSODA", "stiff, so an implicit method (LSODA: BDF formulas with Newton iterations once stiffness is detected)")
    if structure.conservative and rtol >= 1e-6:
        fastest, probed = _fastest_rate(problem, (t0, t1), y0, rtol, rho)
        periods = fastest * span / (2 * math.pi)
        if periods >= LONG_RUN_PERIODS:
            if structure.separable:
                method, hw = "verlet", min(0.5, math.sqrt(8 * rtol))
            else:
                method, hw = "gauss_legendre", min(0.5, rtol**0.25)
            h = hw / fastest
            steps = span / h
            if steps <= 2e6 and (integrators is None or method in available):
                where = (f"|λ|max = {fastest:.3g}, the largest at the start and at {probed} states of a short probe run"
                         if probed else f"|λ|max = {fastest:.3g}")
                return pick(method, f"a long conservative run ({periods:.3g} periods of the fastest mode, {where}) at a "
                                    f"loose tolerance: a symplectic method keeps the energy error bounded (about rtol) "
                                    f"instead of drifting; step h = {h:.3g} (h·|λ|max = {hw:.3g}, {steps:.3g} steps)",
                            {"step": h})
    if rtol <= 1e-6:
        return pick("DOP853", "not stiff, tight tolerance: explicit Runge–Kutta of order 8")
    return pick("RK45", "not stiff, moderate tolerance: explicit Runge–Kutta of order 5(4)")


def _fastest_rate(problem: Problem, t_span: tuple[float, float], y0: np.ndarray, rtol: float, rho: float) -> tuple[float, int]:
    """The largest ``|λ|`` (zeros excluded) at the start and along a short RK45 probe run; how many probe states were read.

    The probe takes at most :data:`PROBE_STEPS` steps (never beyond the
    span) and reads the spectrum every quarter of them; a probe that fails
    (a singular state) leaves the estimate from the start.
    """
    from scipy.integrate import RK45

    t0, t1 = t_span
    fastest, probed = rho, 0
    try:
        with np.errstate(all="ignore"):
            solver = RK45(problem.rhs, t0, y0, t1, rtol=rtol, atol=rtol * max(1.0, float(np.max(np.abs(y0)))) * 1e-3)
            every = max(1, PROBE_STEPS // 4)
            for k in range(1, PROBE_STEPS + 1):
                if solver.status != "running":
                    break
                solver.step()
                if k % every == 0 or solver.status != "running":
                    if not np.all(np.isfinite(solver.y)):
                        break
                    fastest = max(fastest, problem.spectrum(solver.t, solver.y).rho)
                    probed += 1
    except (LagrangianError, ArithmeticError, ValueError, np.linalg.LinAlgError):
        pass  # the probe only refines the estimate from the start
    return fastest, probed
