"""Integrators as plugins: the driver that runs them, with what they share re-exported here.

The contract is :class:`~lagrangian.contracts.Integrator`; the problem an
integrator solves is :mod:`lagrangian.numerics.problem`; fixed-step methods
subclass :mod:`lagrangian.numerics.fixed_step`; ``method="auto"`` is
:mod:`lagrangian.numerics.auto`; events are :mod:`lagrangian.numerics.events`.

A model's equations ``M(q, t) q̈ = f`` are integrated as the first-order
system ``y' = F(t, y)`` on ``y = (q, q̇_inertial)`` (see
:mod:`lagrangian.simulation`).  Integrators come from plugins (hook
``register_integrators``) and are chosen by name,
``Model.simulate(method="verlet", step=0.01)``.  Each follows the numbered
contract of :class:`Integrator`; fixed-step ones usually subclass
:class:`FixedStepIntegrator`, which owns the stepping loop (output times,
interpolation, progress, divergence) and leaves one step to the subclass.

An integrator receives a :class:`Problem`: ``rhs`` and its Jacobian for any
method and, for structure-preserving ones, the pieces of the Lagrangian —
the momentum ``p = ∂L/∂q̇`` and its inverse, ``∂L/∂q``, the
non-conservative forces, the mass matrix — with :class:`Structure`, which
says what the model is (separable? conservative? linear time-invariant?) so
that a method can refuse a model it cannot integrate, saying why.

:func:`choose` is ``method="auto"``: it reads the eigenvalues of the
linearization at the initial state, whether the model conserves energy, and
the tolerance asked, and says what it picked and why.

>>> import lagrangian as lg
>>> m = lg.Model("oscillator")
>>> _ = m.add("mass", "m", "p", m=1)
>>> _ = m.add("spring", "k", ("ground", "p"), k=4)
>>> res = m.simulate(3.0, initial={"x_p": 1}, velocity={"x_p": 0}, method="verlet", step=1e-3, points=4)
>>> bool(abs(res["x_p"][-1] - np.cos(6.0)) < 1e-5)
True
>>> res.step
0.001
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from ..errors import IntegrationError, ModelError, closest, warn
from ..plugin.contracts import KINDS, RESERVED, Integrator, Solution, integrator_problem, resolve
from .auto import STIFFNESS_RATIO, Choice, choose
from .codegen import CompiledModel
from .events import solve as solve_with_events
from .fixed_step import FixedStepIntegrator, Stepper, _missing_step
from .problem import Problem, Spectrum, Structure, _forget_oldest
from .simulation import Result

__all__ = [
    "Integrator",
    "FixedStepIntegrator",
    "Stepper",
    "Problem",
    "Structure",
    "Spectrum",
    "Solution",
    "Choice",
    "EnergyDriftWarning",
    "integrate",
    "choose",
    "resolve",
    "integrator_problem",
    "KINDS",
    "RESERVED",
]



class EnergyDriftWarning(UserWarning):
    """A run of a conservative model did not keep its energy (Jacobi integral) within the tolerance."""


class StiffnessWarning(UserWarning):
    """An explicit method was asked to integrate a stiff model: it will take very many steps."""


#: The stiffness check before an explicit run looks at models of at most this many state variables (an
#: eigenvalue problem of the linearization; larger models are not checked).
STIFFNESS_CHECK_DIM = 400
#: ... and warns when the run is stiff and would take at least this many explicit steps (span · ``|λ|max``),
STIFFNESS_CHECK_STEPS = 1e5
#: ... and refuses the run (it would not end) from this many on,
STIFFNESS_REFUSE_STEPS = 1e10
#: ... or from this many when the fastest rate is a decay that an implicit method steps over (a damper of
#: c = 1e7 on 0.3 kg: 3.3e8 explicit steps, about 80 minutes of DOP853, against 0.05 s of Radau).
STIFF_DECAY_REFUSE_STEPS = 1e6
#: A fixed-step run of a conservative model whose energy changes by more than this (relative) has passed a
#: singularity or gone unstable: its state is not a solution, and the run is an IntegrationError.
EXPLODED = 1.0


# ---------------------------------------------------------------------------
# The contract
# ---------------------------------------------------------------------------


# ---------------------------------------------------------------------------
# The driver: Model.simulate's numerical path
# ---------------------------------------------------------------------------


def integrate(
    problem: Problem,
    integrator: Any,
    t_span: tuple[float, float],
    y0: np.ndarray,
    *,
    t_eval: np.ndarray,
    options: Mapping[str, Any],
    model: str,
    defaulted: list[str],
    integrators: Mapping[str, Any] | None = None,
    notes: Sequence[str] = (),
    energy_tol: float | bool | None = None,
    progress: bool | Callable[[float, float], None] = False,
    events: Sequence[Any] = (),
    max_evaluations: float | None = None,
) -> Result:
    """Integrate ``problem`` with ``integrator`` into a :class:`~lagrangian.Result`.

    Refuses first-order coordinates for methods that cannot take them
    (listing those that can, from ``integrators``), runs the method's
    ``check``, checks the options, fails early on a non-finite start, turns
    a failed run into :class:`~lagrangian.IntegrationError`, and checks the
    energy of a conservative model: a Jacobi integral that drifts by more
    than ``energy_tol`` (relative; default ``max(1e-6, 1000 rtol)`` for
    adaptive methods, ``1e-2`` for fixed-step ones; False to skip) gives an
    :class:`EnergyDriftWarning`.
    """
    name = integrator.name
    integrators = integrators or {}
    if problem.first_order and not integrator.first_order:
        able = sorted(n for n, m in integrators.items() if m.first_order)
        raise ModelError(
            f"{name} cannot integrate model {model!r}: coordinate(s) {', '.join(problem.first_order)} have no inertia "
            f"(first-order), and {name} needs inertia for every coordinate. Methods that handle first-order "
            f"coordinates: {', '.join(able) or '(none registered)'}."
        )
    check = getattr(integrator, "check", None)
    if callable(check):
        check(problem)
    allowed = set(KINDS[integrator.kind]) | set(getattr(integrator, "options", {}) or {})
    if integrator.kind == "fixed-step":
        allowed.add("fast_linear")
    for key in options:
        if key not in allowed:
            raise ModelError(
                f"method {name!r} ({integrator.kind}) does not take the option {key!r}.{closest(key, allowed)} "
                f"Its options: {', '.join(sorted(allowed)) or '(none)'}."
            )
    y0 = np.asarray(y0, dtype=float)
    if integrator.kind == "fixed-step" and options.get("step") is None:
        raise _missing_step(name, problem, t_span[0], y0)
    start = problem.rhs(t_span[0], y0)  # fail early, with a clear message, on a singular start
    if not np.isfinite(start).all():
        names = problem.names
        bad = [f"{names[i]}'" if i < problem.n else f"{names[problem.inertial[i - problem.n]]}''"
               for i in np.flatnonzero(~np.isfinite(start))]
        raise IntegrationError(
            f"the equations of model {model!r} are not finite at the initial state ({', '.join(bad)} evaluate to "
            f"{start[~np.isfinite(start)][0]}): the start is a singular configuration of some component "
            f"(e.g. a 2-D spring or damper of zero length). Start elsewhere."
        )
    stiff_note = _stiffness_note_once(problem, integrator, t_span, y0, model)
    if stiff_note:
        notes = [*notes, "WARNING: " + stiff_note]
        warn(stiff_note, StiffnessWarning)
    problem.nfev = 0
    problem._report = _reporter(t_span, model, progress) if progress else None
    problem.watch(t_span, model, max_evaluations)
    cuts, cut_note = _cuts(problem, integrator, t_span) if not events else ([], None)
    if cut_note:
        notes = [*notes, cut_note]
    occurrences: list = []
    try:
        if events:
            sol, occurrences = solve_with_events(integrator, problem, t_span, y0, t_eval, options, events)
        elif cuts:
            sol = _solve_pieces(integrator, problem, t_span, y0, t_eval, options, cuts)
        else:
            sol = integrator.solve(problem, t_span, y0, t_eval, **options)
    finally:
        problem._report = None
        problem.watch(None)
    if not isinstance(sol, Solution):
        raise IntegrationError(f"integrator {name!r} returned {type(sol).__name__}, not a lagrangian.integrate.Solution.")
    sol_t = np.asarray(sol.t, dtype=float)
    sol_y = np.asarray(sol.y, dtype=float).reshape(problem.dim, -1)
    end = sol_t[-1] if sol_t.size else t_span[0]
    if callable(progress):
        progress(end, t_span[1])
    elif progress:
        print(f"\rsimulating {model!r}: done, {sol.nfev} evaluations{' ' * 20}", file=sys.stderr)
    if sol.status < 0:
        advice = (
            "The model may be stiff (try method='Radau' or 'BDF') or singular there."
            if integrator.kind == "adaptive"
            else _fixed_step_advice(problem, integrator, t_span[0], y0, sol.step)
        )
        raise IntegrationError(f"{name} failed on model {model!r} at t={end:g}: {sol.message}. {advice}")
    if (sol_t.size != t_eval.size and not (occurrences and sol.status == 0)) or not np.isfinite(sol_y).all():
        bad = int(np.argmax(~np.all(np.isfinite(sol_y), axis=0))) if sol_y.size else 0
        at = sol_t[bad] if sol_t.size else t_span[0]
        raise IntegrationError(f"the solution of model {model!r} by {name} became non-finite at t={at:g}.")
    numeric = problem.numeric
    n = problem.n
    v = numeric.velocities_many(sol_t, sol_y)
    q = sol_y[:n]
    T, V, D, h = _energies(numeric, sol_t, q, v)
    all_notes = [*notes, *sol.notes]
    acted = any(getattr(e, "action", None) is not None for e in events) and bool(occurrences)
    if acted:  # an action changed the state: the energy of the model alone need not be kept
        all_notes.append("energy not checked: event actions changed the state")
    if problem._conservative[0] and sol_t.size > 1 and not acted:
        _explosion_check(problem, integrator, sol_t, q, v, T, V, model, h)
    if problem._conservative[0] and sol_t.size > 1 and energy_tol is not False and not acted:
        all_notes.append(_energy_check(problem, integrator, sol_t, q, v, T, V, options, energy_tol, model, h))
    return Result(
        evaluator=numeric.evaluate,
        t=sol_t,
        q={name_: q[i] for i, name_ in enumerate(problem.names)},
        v={name_: v[i] for i, name_ in enumerate(problem.names)},
        T=T,
        V=V,
        D=D,
        model=model,
        defaulted=defaulted,
        nfev=int(sol.nfev),
        method=name,
        notes=all_notes,
        step=sol.step,
        events=occurrences,
        derived={name_: e.function for name_, e in getattr(numeric.eq, "eliminated", {}).items()},
    )


def _cuts(problem: Problem, integrator, t_span) -> tuple[list[float], str | None]:
    """Where an adaptive run restarts: the times in ``t_span`` at which an input of ``t`` switches branch.

    An error estimate taken across a kink (a pulse's corner) can be small by chance, and the step that straddles it
    wrong by 1e-6 at ``rtol=1e-11``; restarting at each switch keeps every step smooth.  Fixed-step methods step
    through (their error is the step's).  Returns the times and a note when they could not be found.
    """
    if integrator.kind != "adaptive":
        return [], None
    try:
        cuts = problem.numeric.switching_times(*t_span)
    except ValueError as exc:
        return [], f"inputs switch at times that could not be found ({exc}): steps across them rely on error control"
    width = t_span[1] - t_span[0]
    kept: list[float] = []
    for c in cuts:  # one restart per corner: two conditions may find the same one a rounding apart
        if t_span[0] + 1e-12 * width < c < t_span[1] - 1e-12 * width and (not kept or c - kept[-1] > 1e-12 * width):
            kept.append(c)
    return kept, None


def _solve_pieces(integrator, problem: Problem, t_span, y0: np.ndarray, t_eval: np.ndarray, options, cuts) -> Solution:
    """``integrator.solve`` on each piece between ``cuts``, each piece starting from where the last one ended."""
    edges = [t_span[0], *[c for c in cuts if c < t_eval[-1]], t_span[1]]  # nothing to restart past the last output
    ts, ys, nfev, notes = [], [], 0, []
    y = np.asarray(y0, dtype=float)
    for i, (a, b) in enumerate(zip(edges[:-1], edges[1:])):
        last = i == len(edges) - 2
        inside = t_eval[(t_eval >= a) & ((t_eval <= b) if last else (t_eval < b))]
        grid = inside if last else np.append(inside, b)  # b: where the next piece starts
        problem.window = (a, b)  # inputs read on this piece's side of its corners (loops in C do so at any run's ends)
        try:
            sol = integrator.solve(problem, (a, b), y, grid, **options)
        finally:
            problem.window = None
        nfev += int(sol.nfev)
        notes += [n for n in sol.notes if n not in notes]
        sol_t = np.asarray(sol.t, dtype=float)
        sol_y = np.asarray(sol.y, dtype=float).reshape(problem.dim, -1)
        keep = sol_t.size if last else min(inside.size, sol_t.size)
        ts.append(sol_t[:keep])
        ys.append(sol_y[:, :keep])
        if sol.status < 0 or sol_t.size < grid.size:
            message = sol.message or f"stopped at t={sol_t[-1] if sol_t.size else a:g}"
            return Solution(np.concatenate(ts), np.concatenate(ys, axis=1), nfev, min(sol.status, -1), message, notes)
        y = sol_y[:, -1]
    notes.append(f"restarted at {len(edges) - 2} switching time(s) of the inputs (pulse corners, steps)")
    return Solution(np.concatenate(ts), np.concatenate(ys, axis=1), nfev, 0, "", notes, None)


#: How many outcomes of the stiffness check a problem keeps (:func:`_stiffness_note_once`).
STIFFNESS_NOTES_KEPT = 16
_UNKNOWN = object()


def _stiffness_note_once(problem: Problem, integrator, t_span, y0, model) -> str | None:
    """:func:`_stiffness_note`, kept on the problem (the model with its parameter values) for the next run of the same
    method from the same start over the same span, which a fit makes thousands of times: it then costs a look-up.
    A refusal is not kept (it is raised again, the spectrum behind it kept by :meth:`Problem.spectrum`)."""
    kept = getattr(problem, "_stiffness_notes", None)
    if kept is None:
        return _stiffness_note(problem, integrator, t_span, y0, model)
    y0 = np.asarray(y0, dtype=float)
    key = (getattr(integrator, "name", None), getattr(integrator, "kind", None),
           bool(getattr(integrator, "implicit", False)), bool(getattr(integrator, "stiff", False)), float(t_span[0]),
           float(t_span[1]), y0.tobytes(), model, id(getattr(problem.numeric, "_fast", None)),
           (STIFFNESS_CHECK_DIM, STIFFNESS_CHECK_STEPS, STIFFNESS_REFUSE_STEPS, STIFF_DECAY_REFUSE_STEPS))
    note = kept.get(key, _UNKNOWN)
    if note is not _UNKNOWN:
        return note
    note = _stiffness_note(problem, integrator, t_span, y0, model)
    _forget_oldest(kept, STIFFNESS_NOTES_KEPT)
    kept[key] = note
    return note


def _stiffness_note(problem: Problem, integrator, t_span, y0, model) -> str | None:
    """Why an explicit adaptive method will crawl on this model (its linearization at the start is stiff), or
    ``None``: explicit methods need steps of about ``1/|λ|max``, so a span of many slow time scales takes
    ``span·|λ|max`` evaluations and more."""
    if integrator.kind != "adaptive" or integrator.implicit or integrator.stiff or problem.dim > STIFFNESS_CHECK_DIM:
        return None
    try:
        spec = problem.spectrum(float(t_span[0]), np.asarray(y0, dtype=float))
    except Exception:  # advice only: a model the linearization cannot take is not refused here
        return None
    span = float(t_span[1]) - float(t_span[0])
    slow = max(spec.slowest, 1.0 / span) if span > 0 else spec.slowest
    steps = span * spec.rho if np.isfinite(spec.rho) else math.inf
    if steps >= STIFFNESS_REFUSE_STEPS and np.max(np.abs(spec.nonzero.imag), initial=0.0) >= 0.5 * spec.rho:
        raise IntegrationError(
            f"model {model!r} oscillates at {spec.rho:.3g} rad/s in its linearization at the start: this run spans "
            f"some {steps / (2 * math.pi):.3g} periods, which no method steps through. Check the parameter values "
            f"(a length of 1e-96, a capacitance of 1e-93?) or shorten the run."
        )
    if steps >= STIFFNESS_REFUSE_STEPS:
        raise IntegrationError(
            f"model {model!r} has a rate of {spec.rho:.3g} 1/s in its linearization at the start: the explicit method "
            f"{integrator.name} would need some {steps:.3g} steps over this run, which would not end. Use "
            f"method='auto' or method='Radau' (implicit), or check the parameter values (a damper of c = 1e308?)."
        )
    fastest = spec.nonzero[np.argmax(np.abs(spec.nonzero))] if spec.nonzero.size else 0.0
    if steps >= STIFF_DECAY_REFUSE_STEPS and fastest.real < 0 and abs(fastest.imag) < 0.5 * abs(fastest):
        raise IntegrationError(
            f"model {model!r} is stiff: its linearization at the start decays at {spec.rho:.3g} 1/s, and the explicit "
            f"method {integrator.name} would need some {steps:.3g} steps over this run, where an implicit one steps "
            f"over the decay. Use method='auto' (which picks an implicit method here) or method='Radau'."
        )
    if not (slow > 0 and spec.rho / slow > STIFFNESS_RATIO and steps >= STIFFNESS_CHECK_STEPS):
        return None
    return (f"model {model!r} is stiff: the linearization at the start has rates from {spec.slowest:.3g} to "
            f"{spec.rho:.3g} 1/s (ratio {spec.rho / slow:.3g}), so the explicit method {integrator.name} needs steps of "
            f"about {1 / spec.rho:.3g} s, some {span * spec.rho:.3g} of them or more over this run; use method='auto' "
            f"(which picks an implicit method here) or method='Radau'.")


def _energies(numeric, t: np.ndarray, q: np.ndarray, v: np.ndarray):
    """``T``, ``V``, ``D`` along a run and, where compiled code evaluates them, the Jacobi integral too (its fourth
    column of the same call, which :meth:`Problem.jacobi` would make again), else ``None``."""
    fast = getattr(numeric, "_fast", None)
    if fast is not None and t.ndim == 1 and isinstance(fast, CompiledModel):
        out = fast._energies(t, q, v)
        return out[:, 0].copy(), out[:, 1].copy(), out[:, 2].copy(), out[:, 3].copy()
    T, V, D = numeric.energies(t, q, v)
    return T, V, D, None


_TINY = np.finfo(float).tiny


def _drift(problem, t, q, v, T, V, h=None):
    """The Jacobi integral along a run (``h`` when it is known), its scale and its largest change relative to that
    scale."""
    h = problem.jacobi(t, q, v) if h is None else h
    scale = max(abs(h[0]), float(np.abs(T).max()), float(np.abs(V).max()), _TINY)
    return h, scale, float(np.abs(h - h[0]).max() / scale)


def _explosion_check(problem, integrator, t, q, v, T, V, model, jacobi=None) -> None:
    """A fixed-step explicit run of a conservative model whose energy left its start by more than its size there:
    an :class:`IntegrationError` (the states are not a solution), whatever ``energy_tol`` says."""
    if integrator.kind == "adaptive" or integrator.implicit:
        return
    h, scale, _ = _drift(problem, t, q, v, T, V, jacobi)
    # against the energy at the start (the run's own scale when the start has none): a run that gained or lost
    # more than that passed a singularity or went unstable
    start = max(abs(h[0]), abs(float(T[0])), abs(float(V[0])))
    reference = start if start > 1e-3 * scale else scale
    change = float(np.max(np.abs(h - h[0]))) / reference
    if change > EXPLODED:
        where = int(np.argmax(np.abs(h - h[0]) > EXPLODED * reference))
        raise IntegrationError(
            f"the state of model {model!r} exploded under {integrator.name}: its energy (Jacobi integral), "
            f"conserved by the model, changed by {change:.3g} times its size at the start by t={t[where]:g}, so "
            f"the run passed a singularity or went unstable and its states are not a solution. Reduce step=, or "
            f"use an adaptive method (method='auto')."
        )


def _energy_check(problem, integrator, t, q, v, T, V, options, energy_tol, model, jacobi=None) -> str:
    h, scale, drift = _drift(problem, t, q, v, T, V, jacobi)
    if energy_tol is None:
        energy_tol = max(1e-6, 1e3 * float(options.get("rtol", 0.0))) if integrator.kind == "adaptive" else 1e-2
    note = f"energy (Jacobi integral) kept to {drift:.2e} relative over the run (tolerance {energy_tol:.1e})"
    if drift > energy_tol:
        where = int(np.argmax(np.abs(h - h[0]) > energy_tol * scale))
        if integrator.symplectic:
            fix = "reduce step= (the energy error of a symplectic method is bounded but grows with the step)"
        else:
            symplectic = "a symplectic method (gauss_legendre, variational, verlet)"
            fix = (f"tighten rtol, or for long runs use {symplectic}" if integrator.kind == "adaptive"
                   else f"reduce step=, or use {symplectic}")
        message = (
            f"model {model!r} is conservative, but its energy (Jacobi integral) drifted by {drift:.2e} relative "
            f"under {integrator.name} (tolerance {energy_tol:.1e}, first exceeded at t={t[where]:g}): {fix}. "
            f"Set energy_tol= to change the tolerance, or energy_tol=False to skip the check."
        )
        warn(message, EnergyDriftWarning)
        note = "WARNING: " + message
    return note


def _fixed_step_advice(problem: Problem, integrator, t0: float, y0: np.ndarray, h: float | None) -> str:
    try:
        lam = problem.eigenvalues(t0, y0)
        rho = float(np.max(np.abs(lam))) if lam.size else 0.0
    except Exception:  # advice only
        rho = 0.0
    if not h or not rho:
        return "Reduce step=."
    kind = "explicit" if not integrator.implicit else "implicit"
    return (
        f"With step {h:.3g} and the fastest mode of the linearization at the start, |λ|max = {rho:.3g}, "
        f"h·|λ|max = {h * rho:.3g}: the {kind} method {integrator.name} is probably unstable (explicit methods need "
        f"h·|λ|max of order 1–3). Reduce step= below {2 / rho:.3g}, or use a stiff method (Radau, BDF, gauss_legendre)."
    )


def _reporter(t_span, model: str, progress) -> Callable[[float], None]:
    """Report progress through ``t_span`` every 5 %: to ``progress(t, t_end)`` or on standard error."""
    t0, t1 = t_span
    report = progress if callable(progress) else None
    state = {"next": 0.0}

    def seen(time: float) -> None:
        fraction = (time - t0) / (t1 - t0)
        if fraction >= state["next"]:
            state["next"] = fraction + 0.05
            if report is not None:
                report(time, t1)
            else:
                print(f"\rsimulating {model!r}: {100 * fraction:5.1f} % (t = {time:.4g} of {t1:.4g})",
                      end="", file=sys.stderr, flush=True)

    return seen

