"""Events: zero-crossings of a function of time and state that stop a run or change its state.

``Model.simulate(events=[...])`` takes :class:`Event` objects.  An event's
``when`` is a function of time and state whose zero is the event: text or a
SymPy expression in the coordinates and ``t`` (``"theta_j1"``,
``"x_p - 0.45"``), or a callable ``when(t, q, v)`` of the time and the
coordinates and velocities by name.  ``direction`` counts only rising (+1)
or falling (−1) crossings; ``terminal`` ends the run there; ``action(t, q,
v)`` returns the new ``(q, v)`` (dicts by name; names left out keep their
values) and the run goes on from them — a velocity reversed at a wall.

Each step is searched for crossings inside it, not only at its ends, so that
a function that dips below zero and comes back within one step is seen:
besides its values at points of the step, it is evaluated where the
polynomial through them turns towards zero.  Adaptive methods sample their
dense output at :data:`SAMPLES` − 1 points inside each step, which places
the turns of a function that is a polynomial of degree :data:`SAMPLES` or
less along the step (one linear in the state, on a quartic dense output);
fixed-step methods, for which a point inside a step costs a step of the
method, take the values at the two step points before (the step's midpoint
on the first step after a start) and a step only to where that cubic turns.
Adaptive methods are stepped through the integrator contract's ``start``
(scipy's solvers, and ``dopri5_c`` whose steps and dense output are C),
fixed-step ones through ``stepper`` (``rk4_c`` and ``verlet_c`` take each
step in C).  Every crossing is located to ``xtol`` (default
``1e-14·max(1, |t|)``) by Brent's method: on the dense output, or on the
method's own step taken from the last step point with the length being
solved for, so that the time found is where the method's solution crosses,
not where an interpolant does.  All the events of a step are recorded, in
order of time, up to a terminal one or one whose action changes the state.
``Result.events`` lists what happened.

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

import functools
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..base.component import t as time_symbol
from ..base.text import parse_expression
from ..errors import IntegrationError, ModelError
from ..plugin.contracts import Solution
from ..base import deferred as _deferred

sp = _deferred.module("sympy", globals())

__all__ = ["Event", "Occurrence", "StateCondition"]

#: at most this many events in one run (a chattering event would otherwise never end)
MAX_OCCURRENCES = 100_000
#: the pieces an adaptive step is cut into to search it for crossings (:func:`solve`'s ``samples``)
SAMPLES = 4


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


@functools.lru_cache(maxsize=8)
def _lobatto(samples: int) -> tuple[float, ...]:
    """``samples`` + 1 points on [0, 1], the ends included, bunched towards them (Chebyshev–Lobatto)."""
    return tuple(float(x) for x in (1 - np.cos(np.pi * np.arange(samples + 1) / samples)) / 2)


#: values within this much of each other, relative, are one value to rounding
_ROUNDING = 8 * float(np.finfo(float).eps)


@functools.lru_cache(maxsize=64)
def _slopes(nodes: tuple[float, ...]) -> tuple[np.ndarray, np.ndarray]:
    """The matrices mapping values at ``nodes`` to the coefficients of the derivative of the polynomial through them:
    of 1, s, s², ..., and of the Bernstein polynomials of [0, 1] (whose signs, when all alike, are its sign there)."""
    x = np.asarray(nodes)
    power = np.arange(1, x.size)[:, None] * np.linalg.inv(np.vander(x, x.size, increasing=True))[1:]
    m = x.size - 2  # the derivative's degree
    bernstein = np.array([[math.comb(k, j) / math.comb(m, j) if j <= k else 0.0 for j in range(m + 1)]
                          for k in range(m + 1)])
    return power, bernstein @ power


@functools.lru_cache(maxsize=8)
def _powers(degree: int) -> tuple[np.ndarray, np.ndarray]:
    """A grid on [0, 1] and its powers 0 … ``degree``, to evaluate a polynomial on it."""
    grid = np.linspace(0.0, 1.0, 16 * (degree + 1) + 1)
    return grid, grid[:, None] ** np.arange(degree + 1)


def _zeros(c: list[float]) -> list[float]:
    """The simple real zeros of ``c[0] + c[1] s + c[2] s²`` (``c`` of length 2 or 3)."""
    c0, c1, c2 = (*c, 0.0)[:3]
    if c2 == 0.0:
        return [-c0 / c1] if c1 != 0.0 else []
    disc = c1 * c1 - 4 * c2 * c0
    if disc <= 0.0:  # none, or a double zero: no turn
        return []
    q = -0.5 * (c1 + math.copysign(math.sqrt(disc), c1))
    return [q / c2, c0 / q]


def _turns(nodes: tuple[float, ...], values: list[float], before: float, after: float) -> list[float]:
    """Where in (0, 1) the polynomial through ``values`` at ``nodes`` turns towards zero: a minimum where the step
    starts or ends above zero, a maximum where it starts or ends below.  None where the values are one to rounding."""
    hi, lo = max(values), min(values)
    if len(values) < 3 or hi - lo <= _ROUNDING * max(hi, -lo):
        return []
    power, bernstein = _slopes(nodes)
    v = np.array(values, dtype=float)
    b = (bernstein @ v).tolist()
    if min(b) > 0 or max(b) < 0:  # monotone over the step: no turn
        return []
    c = (power @ v).tolist()
    if len(c) <= 3:  # the derivative is a line or a parabola: its zeros in closed form
        turns = [(s, c[1] + 2 * c[2] * s > 0 if len(c) == 3 else c[1] > 0) for s in _zeros(c) if 0.0 < s < 1.0]
    else:  # where its sign changes on a grid
        grid, powers = _powers(len(c) - 1)
        d = powers @ np.array(c)
        up = d > 0
        turns = [(float(grid[i] - d[i] * (grid[i + 1] - grid[i]) / (d[i + 1] - d[i])), bool(up[i + 1]))
                 for i in np.nonzero(up[:-1] != up[1:])[0]]
    return [s for s, minimum in turns if (max(before, after) > 0 if minimum else min(before, after) < 0)]


class _Run:
    """Outputs, occurrences and the bookkeeping shared by the adaptive and the fixed-step loops."""

    def __init__(self, problem, t_eval: np.ndarray, conditions: list[_Condition], samples: int = SAMPLES,
                 xtol: float | None = None):
        self.problem, self.t_eval, self.conditions = problem, t_eval, conditions
        self.samples, self.xtol = max(1, int(samples)), xtol
        self.Y = np.full((problem.dim, t_eval.size), np.nan)
        self.next = 0  # the first output not yet written
        self.occurrences: list[Occurrence] = []
        self.values: list[float] = []
        self.quiet: int | None = None  # the condition just handled, not searched until its next sample
        self.past: list[tuple[float, list[float]]] = []  # the step points before the last of a fixed-step run
        self.notes: list[str] = []

    def start(self, t: float, y: np.ndarray, quiet: _Condition | None = None) -> None:
        """The conditions' values at a (re)start; ``quiet`` (the event just handled) is not searched between the
        restart and the first point sampled after it (where it is zero, to rounding)."""
        self.values = [c(t, y) for c in self.conditions]
        self.quiet = None if quiet is None else self.conditions.index(quiet)
        self.past = []

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

    def crossings(self, t_old: float, t_new: float, y_new: np.ndarray, state_at, stepped: bool = False
                  ) -> list[tuple[float, int]]:
        """Every event in ``(t_old, t_new]`` as ``(time, condition)`` in order of time, each located to ``xtol`` on
        ``state_at``; the values are updated to ``t_new``.

        Each condition is searched at the ends, at ``samples`` − 1 points inside the step, and where the
        polynomial through its values there turns towards zero.  ``stepped``: ``state_at`` is a fixed step of the
        method itself, a step's cost to evaluate; the values at the two step points before stand for the points
        inside (the step's midpoint on the first step after a start), so that only a turn costs a step.
        """
        after = [c(t_new, y_new) for c in self.conditions]
        span = t_new - t_old
        known: dict[float, np.ndarray] = {}  # states on state_at, for the conditions after the first

        def at(s: float) -> np.ndarray:
            if s not in known:
                known[s] = state_at(s)
            return known[s]

        searched = self.samples > 1 and bool(self.conditions)
        inner: list[float] = []
        nodes: tuple[float, ...] = (0.0, 1.0)
        # the step points before, within eight of this step's length (a last, short step is fitted without them)
        past = [(t, v) for t, v in self.past if t_old - t <= 8 * span] if stepped else []
        if searched and past:
            nodes = (*(round((t - t_old) / span, 9) for t, _ in past), 0.0, 1.0)
        elif searched:
            nodes = (0.0, 0.5, 1.0) if stepped else _lobatto(self.samples)
            inner = [t_old + x * span for x in nodes[1:-1]]
        if inner and hasattr(state_at, "t_min"):  # SciPy's dense output, which takes every time at once
            states = list(np.asarray(state_at(np.array(inner)), dtype=float).T)
            known.update(zip(inner, states))
        else:
            states = [at(s) for s in inner]
        found, xtol = [], self.xtol if self.xtol is not None else _xtol(t_new)
        for k, c in enumerate(self.conditions):
            before, inside = self.values[k], [c(s, y) for s, y in zip(inner, states)]
            times, values = [t_old, *inner, t_new], [before, *inside, after[k]]
            if searched:
                turns = _turns(nodes, [*(v[k] for _, v in past), *values], before, after[k])
                for x in turns:
                    s = t_old + x * span
                    if t_old < s < t_new:
                        times.append(s)
                        values.append(c(s, at(s)))
                if turns:
                    order = sorted(range(len(times)), key=times.__getitem__)
                    times, values = [times[i] for i in order], [values[i] for i in order]
            for i in self._signs(k, times, values):
                a, b, fa, fb = times[i], times[i + 1], values[i], values[i + 1]
                if fb == 0.0:
                    found.append((b, k))
                    continue
                from scipy.optimize import brentq  # on the first crossing: scipy.optimize costs 0.3 s to import

                def g(s: float, c=c, a=a, b=b, fa=fa, fb=fb) -> float:
                    return fa if s == a else fb if s == b else c(s, at(s))

                found.append((brentq(g, a, b, xtol=xtol, rtol=4 * np.finfo(float).eps), k))
        if stepped:
            self.past = [*self.past, (t_old, self.values)][-2:]
        self.values, self.quiet = after, None
        return sorted(found)

    def _signs(self, k: int, times: list[float], values: list[float]) -> list[int]:
        """The pieces ``i`` (from ``times[i]`` to ``times[i + 1]``) over which condition ``k`` crosses zero."""
        c = self.conditions[k]
        return [i for i in range(len(times) - 1) if not (i == 0 and k == self.quiet) and times[i] < times[i + 1]
                and c.crosses(values[i], values[i + 1])]

    def happen(self, hits: list[tuple[float, int]], state_at) -> tuple[str, float, np.ndarray, _Condition] | None:
        """Record the events ``hits`` in order up to a terminal one (``("stop", t, y, condition)``: the run ends
        there) or one with an action (``("restart", t, y after the action, condition)``); ``None``: the run goes on
        through the step."""
        for t_hit, k in hits:
            y_hit = np.array(state_at(t_hit), dtype=float)
            self.write(t_hit, state_at)
            self.record(t_hit, y_hit, k)
            cond = self.conditions[k]
            if cond.event.terminal:
                if self.next < self.t_eval.size:  # the run ends at the event: it is the last output
                    self.t_eval = np.concatenate([self.t_eval[: self.next], [t_hit]])
                    self.Y = np.concatenate([self.Y[:, : self.next], y_hit[:, None]], axis=1)
                    self.next += 1
                return "stop", t_hit, y_hit, cond
            if cond.event.action is not None:
                return "restart", t_hit, _apply(cond, t_hit, y_hit), cond
        return None

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
          conditions: Sequence[_Condition] = (), samples: int = SAMPLES, xtol: float | None = None
          ) -> tuple[Solution, list[Occurrence]]:
    """Integrate with ``events`` (see the module docstring): the solution up to the end or a terminal event.

    Drivers built on events add ``conditions`` (:class:`StateCondition`); each step of an adaptive method is
    searched at ``samples`` − 1 points inside it besides its ends (``samples=1``: at its ends only, for every
    method), and crossings are located to ``xtol`` in time.
    """
    notes: list[str] = []
    conditions = [_Condition(e, i, problem) for i, e in enumerate(events)] + list(conditions)
    run = _Run(problem, np.asarray(t_eval, dtype=float), conditions, samples, xtol)
    run.notes = notes
    start = problem.nfev
    if integrator.kind == "fixed-step" and callable(getattr(integrator, "stepper", None)):
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
        outcome = run.happen(run.crossings(t_old, t_new, y_new, dense), dense)
        if outcome is None:
            run.write(t_new, dense)
            if solver.status == "finished":
                return 0, ""
            continue
        what, t_hit, y_after, cond = outcome
        if what == "stop" or t_hit >= t1:
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
    while t1 - t > 1e-12 * max(1.0, abs(t1)):
        tau = min(h, t1 - t)
        y_new = advance(t, y, tau)
        if not np.all(np.isfinite(y_new)):
            return -1, f"the state became non-finite at t={t + tau:g}", h
        t_new = t1 if tau == t1 - t else t + h

        def state_at(s: float, t=t, y=y, t_new=t_new, y_new=y_new) -> np.ndarray:
            return y_new if s >= t_new else y if s <= t else advance(t, y, s - t)

        outcome = run.happen(run.crossings(t, t_new, y_new, state_at, stepped=True), state_at)
        if outcome is None:
            run.write(t_new, state_at)
            t, y = t_new, y_new
            continue
        what, t_hit, y_after, cond = outcome
        if what == "stop":
            return 0, "", h
        t, y = t_hit, y_after
        run.start(t, y, quiet=cond)
    run.write(t1, lambda s: y)
    return 0, "", h
