"""Events: zero-crossings of a function of time and state that stop a run or change its state.

``Model.simulate(events=[...])`` takes :class:`Event` objects.  An event's
``when`` is a function of time and state whose zero is the event: text or a
SymPy expression in the coordinates and ``t`` (``"theta_j1"``,
``"x_p - 0.45"``), or a callable ``when(t, q, v)`` of the time and the
coordinates and velocities by name.  ``direction`` counts only rising (+1)
or falling (−1) crossings; ``terminal`` ends the run there; ``action(t, q,
v)`` returns the new ``(q, v)`` (dicts by name; names left out keep their
values) and the run goes on from them — a velocity reversed at a wall.

Every crossing is located to ``xtol`` (default ``1e-14·max(1, |t|)``) by
Brent's method: adaptive methods on their dense output between two steps
(through the integrator contract's ``start``: scipy's solvers, and
``dopri5_c`` whose steps and dense output are C); fixed-step methods on the
method's own step taken from the last step point with the length being
solved for (through ``stepper``: ``rk4_c`` and ``verlet_c`` take that step
in C), so that the time found is where the method's solution crosses, not
where an interpolant does.  ``Result.events`` lists what happened.

>>> import lagrangian as lg
>>> m = lg.Model("drop")
>>> _ = m.add("mass", "m", "p", m=0.3)
>>> _ = m.add("gravity", "g", g=9.81)
>>> res = m.simulate(2, initial={"x_p": 1.2}, velocity={"x_p": 0}, rtol=1e-12, atol=1e-14,
...                  events=[lg.Event("x_p", direction=-1, terminal=True, name="floor")])
>>> hit = res.events[0]
>>> hit.name, round(hit.t, 12), round((2 * 1.2 / 9.81) ** 0.5, 12)    # t = √(2h/g)
('floor', 0.494619366829, 0.494619366829)
>>> bool(res.t[-1] == hit.t)
True
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import sympy as sp

from ..base.component import t as time_symbol
from ..base.text import parse_expression
from ..errors import IntegrationError, ModelError
from ..plugin.contracts import Solution

__all__ = ["Event", "Occurrence", "StateCondition"]

#: at most this many events in one run (a chattering event would otherwise never end)
MAX_OCCURRENCES = 100_000


@dataclass(frozen=True)
class Event:
    """A zero-crossing of ``when`` (text, a SymPy expression, or ``when(t, q, v)``); see the module docstring."""

    when: Any
    direction: int = 0
    terminal: bool = False
    action: Callable[[float, dict, dict], tuple[Mapping, Mapping]] | None = None
    name: str = ""

    def __post_init__(self):
        if self.direction not in (-1, 0, 1) or isinstance(self.direction, bool):
            raise ModelError(f"event {self.label}: direction must be -1 (falling), 0 (both) or +1 (rising), "
                             f"got {self.direction!r}.")
        if not isinstance(self.terminal, bool):
            raise ModelError(f"event {self.label}: terminal must be True or False, got {self.terminal!r}.")
        if self.action is not None and not callable(self.action):
            raise ModelError(f"event {self.label}: action must be a callable action(t, q, v) -> (q, v), "
                             f"got {self.action!r}.")
        if self.action is not None and self.terminal:
            raise ModelError(f"event {self.label}: a terminal event ends the run; it cannot also have an action.")
        if not isinstance(self.name, str):
            raise ModelError(f"an event's name must be text, got {self.name!r}.")

    @property
    def label(self) -> str:
        return repr(self.name) if self.name else repr(self.when) if isinstance(self.when, str) else "(unnamed)"


@dataclass(frozen=True)
class Occurrence:
    """An event that happened: its ``name`` (or its index), the time ``t``, and ``q``, ``v`` just before any action."""

    name: str
    t: float
    q: dict[str, float] = field(repr=False)
    v: dict[str, float] = field(repr=False)
    #: the integrator's state vector there (``y = (q, q̇_inertial)``), for drivers that restart from it
    state: np.ndarray | None = field(default=None, repr=False, compare=False)


def check(events: Any) -> tuple[Event, ...]:
    """``events`` as a tuple of :class:`Event`; a :class:`~lagrangian.ModelError` for anything else."""
    if events is None:
        return ()
    if isinstance(events, Event):
        return (events,)
    if isinstance(events, (str, bytes, Mapping)) or not isinstance(events, Sequence):
        raise ModelError(f"events must be a list of lagrangian.Event, got {events!r:.60}.")
    bad = [e for e in events if not isinstance(e, Event)]
    if bad:
        raise ModelError(f"events must be lagrangian.Event objects, e.g. lg.Event('x_p', direction=-1, terminal=True); "
                         f"got {bad[0]!r:.60}.")
    return tuple(events)


class _Condition:
    """One event's function ``g(t, y)`` of the integrator's state ``y = (q, q̇_inertial)``."""

    def __init__(self, event: Event, index: int, problem):
        self.event, self.name = event, event.name or str(index)
        self.problem = problem
        names = problem.names
        when = event.when
        if callable(when) and not isinstance(when, sp.Basic):
            self._call = when
            self._fn = None
            return
        eq = problem.numeric.eq
        symbols = {n: q for n, q in zip(names, eq.sym.q)} | {"t": time_symbol}
        what = f"event {event.label}"
        if isinstance(when, str):
            expr = parse_expression(when, what, names=symbols)
        elif isinstance(when, sp.Expr):
            expr = eq.symbolic(when)
        else:
            raise ModelError(f"{what}: when must be text, a SymPy expression or a callable when(t, q, v), got {when!r}.")
        expr = sp.sympify(expr).xreplace({s: sp.Float(v) for s, v in problem.numeric.values.items()})
        unknown = expr.free_symbols - set(eq.sym.q) - set(eq.sym.v) - {time_symbol}
        if unknown:
            raise ModelError(f"{what}: {', '.join(sorted(map(str, unknown)))} is not a coordinate, velocity or t of "
                             f"model {problem.name!r}; coordinates: {', '.join(names)}.")
        self._fn = sp.lambdify((time_symbol, list(eq.sym.q), list(eq.sym.v)), expr, modules="numpy")
        self._call = None

    def state(self, t: float, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        n = self.problem.n
        if not self.problem.first_order:  # every velocity is in the state
            return y[:n], y[n:]
        v, _ = self.problem.numeric.velocities(t, y)
        return y[:n], np.asarray(v, dtype=float)

    def __call__(self, t: float, y: np.ndarray) -> float:
        q, v = self.state(t, y)
        if self._fn is not None:
            value = self._fn(t, q, v)
        else:
            names = self.problem.names
            value = self._call(t, dict(zip(names, map(float, q))), dict(zip(names, map(float, v))))
        try:
            out = float(value)
        except (TypeError, ValueError):
            raise ModelError(f"event {self.event.label}: when(t, q, v) must return a number, got {value!r}.") from None
        if not math.isfinite(out):
            raise IntegrationError(f"event {self.event.label}: its function is not finite ({out}) at t={t:g}.")
        return out

    def crosses(self, before: float | None, after: float) -> bool:
        if before is None or before == 0.0 or after == before:
            return False
        if (before < 0) == (after < 0) and after != 0.0:
            return False
        rising = after > before
        return self.event.direction == 0 or (self.event.direction > 0) == rising


class StateCondition(_Condition):
    """A terminal condition given as ``g(t, y)`` of the integrator's state, for drivers built on events.

    The hybrid impact simulation stops on these: a contact's gap falling to zero, a resting contact's force
    falling below zero.  ``direction`` as for :class:`Event`.
    """

    def __init__(self, name: str, g: Callable[[float, np.ndarray], float], problem, direction: int = -1):
        self.event = Event(g, direction=direction, terminal=True, name=name)
        self.name, self.problem, self._g = name, problem, g

    def __call__(self, t: float, y: np.ndarray) -> float:
        out = float(self._g(t, y))
        if not math.isfinite(out):
            raise IntegrationError(f"condition {self.name!r} is not finite ({out}) at t={t:g}.")
        return out


def _apply(cond: _Condition, t: float, y: np.ndarray) -> np.ndarray:
    """The state after ``cond``'s action at ``t``."""
    problem = cond.problem
    names, n = problem.names, problem.n
    q, v = cond.state(t, y)
    q_by, v_by = dict(zip(names, map(float, q))), dict(zip(names, map(float, v)))
    result = cond.event.action(t, dict(q_by), dict(v_by))
    if not (isinstance(result, tuple) and len(result) == 2 and all(isinstance(r, Mapping) for r in result)):
        raise ModelError(f"event {cond.event.label}: action(t, q, v) must return a pair of dicts (q, v), got {result!r}.")
    new_q, new_v = result
    for given, label in ((new_q, "coordinate"), (new_v, "velocity")):
        for k, value in given.items():
            if k not in names:
                raise ModelError(f"event {cond.event.label}: the action returned an unknown {label} {k!r}; "
                                 f"coordinates: {', '.join(names)}.")
            if not isinstance(value, (int, float, np.floating, np.integer)) or not math.isfinite(float(value)):
                raise ModelError(f"event {cond.event.label}: the action returned {label} {k}={value!r}, not a finite "
                                 f"number.")
    out = np.array(y, dtype=float)
    for i, k in enumerate(names):
        out[i] = float(new_q.get(k, q_by[k]))
    for j, i in enumerate(problem.inertial):
        out[n + j] = float(new_v.get(names[i], v_by[names[i]]))
    return out


def _xtol(t: float) -> float:
    return 1e-14 * max(1.0, abs(t))


class _Run:
    """Outputs, occurrences and the bookkeeping shared by the adaptive and the fixed-step loops."""

    def __init__(self, problem, t_eval: np.ndarray, conditions: list[_Condition], samples: int = 1,
                 xtol: float | None = None):
        self.problem, self.t_eval, self.conditions = problem, t_eval, conditions
        self.samples, self.xtol = samples, xtol
        self.Y = np.full((problem.dim, t_eval.size), np.nan)
        self.next = 0  # the first output not yet written
        self.occurrences: list[Occurrence] = []
        self.values: list[float | None] = []
        self.notes: list[str] = []

    def start(self, t: float, y: np.ndarray, quiet: _Condition | None = None) -> None:
        """The conditions' values at a (re)start; ``quiet`` (the event just handled) waits for a step first."""
        self.values = [None if c is quiet else c(t, y) for c in self.conditions]

    def noted(self, solver) -> None:
        """Keep what a solver or stepper says of itself (a compiled method running its Python sibling)."""
        for note in getattr(solver, "notes", None) or ():
            if note not in self.notes:
                self.notes.append(note)

    def write(self, upto: float, state_at: Callable[[float], np.ndarray], inclusive: bool = True) -> None:
        te = self.t_eval
        while self.next < te.size and (te[self.next] <= upto if inclusive else te[self.next] < upto):
            self.Y[:, self.next] = state_at(float(te[self.next]))
            self.next += 1

    def first_crossing(self, t_old: float, t_new: float, y_new: np.ndarray, state_at) -> tuple[float, int] | None:
        """The earliest event in ``(t_old, t_new]``, located to ``xtol``; the values are updated to ``t_new``.

        With ``samples`` > 1 the conditions are also sampled inside the step (on ``state_at``), so that a
        function that dips below zero and comes back within one step is still seen.
        """
        found = None
        after = [c(t_new, y_new) for c in self.conditions]
        times = [t_old, t_new]
        rows = [[before, now] for before, now in zip(self.values, after)]
        if self.samples > 1 and self.conditions:
            inner = [float(s) for s in np.linspace(t_old, t_new, self.samples + 1)[1:-1]]
            states = [state_at(s) for s in inner]
            times = [t_old, *inner, t_new]
            rows = [[self.values[k], *(c(s, y) for s, y in zip(inner, states)), after[k]]
                    for k, c in enumerate(self.conditions)]
        xtol = self.xtol if self.xtol is not None else _xtol(t_new)
        for k, c in enumerate(self.conditions):
            values = rows[k]
            for i in range(len(times) - 1):
                if not c.crosses(values[i], values[i + 1]):
                    continue
                a, b = times[i], times[i + 1]
                from scipy.optimize import brentq  # on the first crossing: scipy.optimize costs 0.3 s to import

                root = b if values[i + 1] == 0.0 else brentq(lambda s, c=c: c(s, state_at(s)), a, b, xtol=xtol,
                                                               rtol=4 * np.finfo(float).eps)
                if found is None or root < found[0]:
                    found = (root, k)
                break
        self.values = after
        return found

    def record(self, t: float, y: np.ndarray, k: int) -> None:
        c = self.conditions[k]
        q, v = c.state(t, y)
        names = self.problem.names
        self.occurrences.append(Occurrence(c.name, t, dict(zip(names, map(float, q))), dict(zip(names, map(float, v))),
                                           np.array(y, dtype=float)))
        if len(self.occurrences) > MAX_OCCURRENCES:
            raise IntegrationError(f"more than {MAX_OCCURRENCES} events in one run of model {self.problem.name!r} "
                                   f"(event {c.event.label} chatters): make it terminal, or give it a direction.")

    def solution(self, nfev: int, status: int, message: str, notes: list[str], step=None) -> Solution:
        done = self.next
        return Solution(self.t_eval[:done], self.Y[:, :done], nfev, status, message, notes, step)


def solve(integrator, problem, t_span, y0, t_eval, options: Mapping[str, Any], events: Sequence[Event], *,
          conditions: Sequence[_Condition] = (), samples: int = 1, xtol: float | None = None
          ) -> tuple[Solution, list[Occurrence]]:
    """Integrate with ``events`` (see the module docstring): the solution up to the end or a terminal event.

    Drivers built on events add ``conditions`` (:class:`StateCondition`), sample every condition at
    ``samples`` − 1 points inside each adaptive step besides its ends (on the dense output; a fixed step is
    checked at its ends, as sampling inside it would cost a step per point), and locate crossings to
    ``xtol`` in time.
    """
    notes: list[str] = []
    conditions = [_Condition(e, i, problem) for i, e in enumerate(events)] + list(conditions)
    run = _Run(problem, np.asarray(t_eval, dtype=float), conditions, samples, xtol)
    run.notes = notes
    start = problem.nfev
    if integrator.kind == "fixed-step" and callable(getattr(integrator, "stepper", None)):
        run.samples = 1
        status, message, h = _fixed(integrator, problem, t_span, np.asarray(y0, dtype=float), options, run)
    elif callable(getattr(integrator, "start", None)):
        status, message, h = (*_adaptive(integrator, problem, t_span, np.asarray(y0, dtype=float), options, run), None)
    else:
        raise ModelError(f"method {integrator.name!r} cannot stop for events: it has no step interface (start() for "
                         f"adaptive methods, stepper() for fixed-step ones). Methods that can: RK45, DOP853, Radau, "
                         f"BDF, LSODA, rk4, verlet, ...")
    if run.occurrences:
        notes.append(f"events: {len(run.occurrences)} occurred, the first {run.occurrences[0].name!r} at "
                     f"t={run.occurrences[0].t:.12g}")
    return run.solution(problem.nfev - start, status, message, notes, h), run.occurrences


def _adaptive(integrator, problem, t_span, y0, options, run: _Run) -> tuple[int, str]:
    t0, t1 = map(float, t_span)
    solver = integrator.start(problem, t0, y0, t1, **options)
    run.noted(solver)
    run.start(t0, y0)
    run.write(t0, lambda s: y0)
    while True:
        message = solver.step()
        if solver.status == "failed":
            return -1, str(message or "the step failed")
        t_old, t_new, y_new = float(solver.t_old), float(solver.t), np.array(solver.y, dtype=float)
        dense = solver.dense_output()
        hit = run.first_crossing(t_old, t_new, y_new, dense)
        if hit is None:
            run.write(t_new, dense)
            if solver.status == "finished":
                return 0, ""
            continue
        t_hit, k = hit
        y_hit = np.array(dense(t_hit), dtype=float)
        run.write(t_hit, dense)
        run.record(t_hit, y_hit, k)
        cond = run.conditions[k]
        if cond.event.terminal:
            if run.next < run.t_eval.size:  # the run ends at the event: it is the last output
                run.t_eval = np.concatenate([run.t_eval[: run.next], [t_hit]])
                run.Y = np.concatenate([run.Y[:, : run.next], y_hit[:, None]], axis=1)
                run.next += 1
            return 0, ""
        if cond.event.action is None:
            run.write(t_new, dense)
            if solver.status == "finished":
                return 0, ""
            continue
        y_after = _apply(cond, t_hit, y_hit)
        if t_hit >= t1:
            return 0, ""
        solver = integrator.start(problem, t_hit, y_after, t1, **options)
        run.start(t_hit, y_after, quiet=cond)


def _fixed(integrator, problem, t_span, y0, options, run: _Run) -> tuple[int, str, float]:
    t0, t1 = map(float, t_span)
    options = dict(options)
    h = float(options.pop("step"))
    options.pop("fast_linear", None)
    steppers: dict[float, Any] = {}

    def advance(t: float, y: np.ndarray, tau: float) -> np.ndarray:
        """One step of length ``tau`` from ``(t, y)``: the method's own map."""
        st = steppers.get(tau)
        if st is None:
            if len(steppers) > 64:
                steppers.clear()
            st = steppers[tau] = integrator.stepper(problem, tau, **options)
            run.noted(st)
        z = np.array(st.to_internal(t, np.array(y, dtype=float)), dtype=float)
        return np.array(st.to_state(t + tau, st.step(t, z)), dtype=float)

    t, y = t0, np.array(y0, dtype=float)
    run.start(t, y)
    run.write(t, lambda s: y)
    steps = 0
    while t1 - t > 1e-12 * max(1.0, abs(t1)):
        tau = min(h, t1 - t)
        y_new = advance(t, y, tau)
        steps += 1
        if not np.all(np.isfinite(y_new)):
            return -1, f"the state became non-finite at t={t + tau:g}", h
        t_new = t1 if tau == t1 - t else t + h

        def state_at(s: float, t=t, y=y, t_new=t_new, y_new=y_new) -> np.ndarray:
            return y_new if s >= t_new else y if s <= t else advance(t, y, s - t)

        hit = run.first_crossing(t, t_new, y_new, state_at)
        if hit is None:
            run.write(t_new, state_at)
            t, y = t_new, y_new
            continue
        t_hit, k = hit
        y_hit = state_at(t_hit)
        run.write(t_hit, state_at)
        run.record(t_hit, y_hit, k)
        cond = run.conditions[k]
        if cond.event.terminal:
            if run.next < run.t_eval.size:
                run.t_eval = np.concatenate([run.t_eval[: run.next], [t_hit]])
                run.Y = np.concatenate([run.Y[:, : run.next], y_hit[:, None]], axis=1)
                run.next += 1
            return 0, "", h
        if cond.event.action is None:
            run.write(t_new, state_at)
            t, y = t_new, y_new
            continue
        t, y = t_hit, _apply(cond, t_hit, y_hit)
        run.start(t, y, quiet=cond)
    run.write(t1, lambda s: y)
    return 0, "", h
