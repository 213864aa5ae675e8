"""Stick–slip: dry friction that sticks and slips, run phase by phase with events.

A component with a stick–slip option (``coulomb_friction``, ``joint_friction`` and a ``rolling`` contact in the
plane with ``stick_slip=True``) follows a small contract: a parameter ``phase`` — ``"slip+"`` and ``"slip-"``
(sliding forward or back: a constant force ``∓F_c`` on the rate it opposes), ``"stick"`` (that rate held at zero by
a constraint on velocities, whose multiplier is the friction force) — a static limit ``F_s`` (``None``: ``F_c``),
and ``sliding_rate(ctx)``.
:func:`simulate` integrates the model with every such component in its phase, stops at the first event, switches
and goes on:

- sliding, when the rate comes to zero: the component sticks if the force sticking would take stays within
  ``F_s``, else it slides on the other way;
- stuck, when that force reaches ``F_s``: it slides, against the force.

Each phase's model is derived once (the phases change no coordinate) and the events are located by the
integrator's own dense output (:mod:`lagrangian.numerics.events`).  The result is a :class:`StickSlipResult`: the
run on the requested times plus every switch, the switches themselves, and the heat the friction made.

A block pushed along a rough floor by a force F that stops at t = 1 s: it slides at a = (F − F_c)/m, then
decelerates at F_c/m and sticks at t = 1 + m v(1) / F_c, having slid ½ a + m v(1)²/2F_c:

>>> import sympy as sp, lagrangian as lg
>>> from lagrangian.stick_slip import simulate
>>> m = lg.Model("pushed block")
>>> _ = m.add("mass", "m1", "p", m=0.5)
>>> _ = m.add("force", "push", "p", F=sp.Piecewise((2.0, lg.t < 1), (0.0, True)))
>>> _ = m.add("coulomb_friction", "f", ("ground", "p"), F_c=1.0, stick_slip=True)
>>> res = simulate(m, 3.0, initial={"x_p": 0}, velocity={"x_p": 0})
>>> [(round(s.t, 9), s.component, s.before, s.after) for s in res.switches]
[(0.0, 'f', 'stick', 'slip+'), (2.0, 'f', 'slip+', 'stick')]
>>> round(float(res["x_p"][-1]), 9), round(float(res.heat[-1]), 9)     # the heat: F_c times the path
(2.0, 2.0)
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..base.component import t
from ..derivation.assembly import refuse_eliminated
from ..errors import ModelError, UnknownNameError
from ..model import Model
from ..numerics.events import Event
from ..numerics.result import Result
from ..base import deferred as _deferred

sp = _deferred.module("sympy", globals())

__all__ = ["StickSlipResult", "Switch", "simulate"]

#: At most this many switches in one run (a friction that chatters between stick and slip would never end).
MAX_SWITCHES = 10_000


@dataclass(frozen=True)
class Switch:
    """A change of phase: at time ``t``, ``component`` went from ``before`` to ``after`` (``"stick"``, ``"slip+"``,
    ``"slip-"``); ``force`` is the friction force sticking would take there (its multiplier)."""

    t: float
    component: str
    before: str
    after: str
    force: float


@dataclass(repr=False)
class StickSlipResult(Result):
    """A :class:`~lagrangian.Result` of :func:`simulate`: ``switches`` in time order, and ``heat`` — the work the
    friction has turned into heat by each output time (``F_c`` times the distance slid, summed over the
    components)."""

    switches: list[Switch] = field(default_factory=list)
    heat: np.ndarray = field(default_factory=lambda: np.zeros(0))


class _Phases:
    """The model in each combination of phases (built on first use), and the numbers the driver needs of one."""

    def __init__(self, model: Model, params: Mapping[str, float] | None):
        self.model, self.params = model, dict(params or {})
        self.frictions = [c for c in model.components.values() if getattr(c, "stick_slip", False)]
        if not self.frictions:
            raise ModelError(f"model {model.name!r} has no component that sticks and slips: give a friction "
                             f"stick_slip=True (coulomb_friction, joint_friction, rolling in the plane), or run it "
                             f"with Model.simulate.")
        self.names = [c.name for c in self.frictions]
        self._models: dict[tuple[str, ...], Model] = {}
        self._numbers: dict[tuple[str, ...], Any] = {}

    def model_in(self, phases: tuple[str, ...]) -> Model:
        if phases not in self._models:
            source = self.model
            variant = Model(source.name, registry=source.registry, **source.options)
            chosen = dict(zip(self.names, phases))
            for name, comp in source.components.items():  # as the user gave them (a default of None left out)
                params = {p: comp.given(p) for p, value in comp.params.items() if value is not None}
                if name in chosen:
                    params["phase"] = chosen[name]
                variant.add(comp.kind, name, comp.nodes, **params)
            self._models[phases] = variant
        return self._models[phases]

    def params_of(self, model: Model) -> dict[str, float]:
        """The values of ``params`` that the model in one combination of phases takes: a parameter only sliding uses
        (a symbolic ``F_c``) is not one of a stuck model's; a name no phase takes is refused."""
        def names(m: Model) -> set[str]:
            return {s.name for s in m.parameters} | set(m.parameter_values)

        if not hasattr(self, "_known"):
            self._known = names(self.model_in(("stick",) * len(self.names))) | names(
                self.model_in(("slip+",) * len(self.names)))
            unknown = [k for k in self.params if k not in self._known]
            if unknown:
                raise UnknownNameError("parameter", unknown[0], sorted(self._known))
        own = names(model)
        return {k: x for k, x in self.params.items() if k in own}

    def number(self, comp, pname: str, numeric) -> float:
        """A friction's ``F_c`` or ``F_s`` as a number in this run: one given as a number takes its value from the
        run's values (``params=`` may give it another), a symbol its value from ``params`` by name (a symbol only
        sliding uses is not one of a stuck model's parameters)."""
        value = comp.symbolic_view().params[pname]  # a number given is a symbol there, valued by ``numeric``
        expr = sp.sympify(value, strict=True).xreplace({s: sp.Float(x) for s, x in numeric.values.items()})
        expr = expr.xreplace({s: sp.Float(self.params[s.name]) for s in expr.free_symbols if s.name in self.params})
        if expr.free_symbols:
            raise ModelError(f"{comp.name}: {pname} needs a value: give params={{{', '.join(sorted(repr(s.name) for s in expr.free_symbols))}: ...}}.")
        return float(expr)

    def numbers(self, phases: tuple[str, ...]):
        """``(numeric, rows)`` of the model in ``phases``: its numeric form and, per component, ``(a, b, k, limit,
        F_c, exact)`` — its rate ``a(t, q)·q̇ + b(t, q)``, where its multiplier sits in the solve when it sticks
        (else ``None``), its static limit, its sliding force, and ``a`` as numbers when it is constant and ``b``
        zero (else ``None``)."""
        if phases not in self._numbers:
            model = self.model_in(phases)
            numeric = model.numeric(self.params_of(model))
            eq = numeric.eq
            q, v = list(eq.sym.q), list(eq.sym.v)
            held = self.model_in(("stick",) * len(self.names))  # every rate as a constraint row: its a and b
            stuck = held.eq
            # the rows with the parameters given as numbers still symbols, and this run's values in (params= included)
            values = {s: sp.Float(x) for s, x in held.numeric(self.params_of(held)).values.items()}  # its own symbols
            generic = stuck.generic()["velocity_constraints"]
            rows = []
            for j, comp in enumerate(self.frictions):
                r = generic[stuck.velocity_owners.index(comp.name)].xreplace(values)
                grad = [r.diff(x) for x in v]
                rest = r.xreplace(dict.fromkeys(v, 0))
                a = sp.lambdify((t, q), grad, modules="numpy")
                b = sp.lambdify((t, q), rest, modules="numpy")
                # a rate a·q̇ with a constant: the distance slid is a·Δq, exactly (else the rate is integrated)
                exact = np.array([float(g) for g in grad]) if rest == 0 and all(g.is_number for g in grad) else None
                k = None
                if phases[j] == "stick":
                    k = (len(eq.inertial) + len(eq.first_order) + len(eq.constraints)
                         + eq.velocity_owners.index(comp.name))
                own = model.components[comp.name]
                rows.append((a, b, k, self.number(own, "F_c" if own.F_s is None else "F_s", numeric),
                             self.number(own, "F_c", numeric), exact))
            self._numbers[phases] = (numeric, rows)
        return self._numbers[phases]


def _rate(row, time: float, q: np.ndarray, v: np.ndarray) -> float:
    a, b = row[0], row[1]
    return float(np.dot(np.asarray(a(time, q), dtype=float), v) + float(b(time, q)))


def simulate(model: Model, t_end: float | tuple[float, float], *, initial: Mapping[str, float] | None = None,
             velocity: Mapping[str, float] | None = None, params: Mapping[str, float] | None = None,
             points: int = 1001, method: Any = "DOP853", rtol: float = 1e-10, atol: float = 1e-12,
             max_step: float = math.inf) -> StickSlipResult:
    """Run ``model`` with its stick–slip frictions sticking and slipping (see the module documentation).

    ``initial``, ``velocity``, ``params``, ``method`` and the tolerances are those of ``Model.simulate`` (each
    phase runs through it); ``points`` output times evenly spaced over the span, to which every switch is
    added.  A component starts stuck when its rate is zero and the force sticking takes stays within ``F_s``.
    """
    phases_of = _Phases(model, params)
    span = Model._span(t_end)
    t0, t1 = span
    grid = np.linspace(t0, t1, int(points))
    base = phases_of.model_in(("stick",) * len(phases_of.names))
    names = base.coordinate_names
    refuse_eliminated(base.assembly.eliminated, initial=initial, velocity=velocity)
    given_q, given_v = dict(initial or {}), dict(velocity or {})
    q = np.array([float(given_q.get(n, 0.0)) for n in names])
    v = np.array([float(given_v.get(n, 0.0)) for n in names])
    defaulted = [n for n in names if n not in given_q] + [f"{n}'" for n in names if n not in given_v]
    tt = t0
    phases = tuple("slip+" for _ in phases_of.names)  # a placeholder: each is decided from the state just below
    switches: list[Switch] = []
    phases = _decide(phases_of, phases, range(len(phases)), tt, q, v, switches, start=True)
    out_t, out_q, out_v, T, V, D, heat = [], [], [], [], [], [], []
    nfev, notes, made = 0, [], 0.0
    while True:
        variant = phases_of.model_in(phases)
        numeric, rows = phases_of.numbers(phases)
        v = _onto(rows, phases, tt, q, v)
        events = [_event(numeric, rows[j], phases[j], j) for j in range(len(phases))]
        times = grid[grid > tt]
        res = variant.simulate((tt, t1), initial=dict(zip(names, q)), velocity=dict(zip(names, v)), params=phases_of.params_of(variant),
                               t_eval=np.concatenate([[tt], times]) if times.size else np.array([tt, t1]),
                               method=method, rtol=rtol, atol=atol, max_step=max_step, events=events,
                               energy_tol=False)
        nfev += res.nfev
        Q = np.array([res.q[n] for n in names])
        Vv = np.array([res.v[n] for n in names])
        part = np.full(res.t.size, made)
        for j, ph in enumerate(phases):  # the heat: F_c times the distance slid (the rate keeps its sign here)
            if ph == "stick":
                continue
            exact = rows[j][5]
            if exact is not None:
                part += rows[j][4] * np.abs(exact @ (Q - Q[:, :1]))
            else:  # trapezoids on the output times
                speed = np.abs([_rate(rows[j], s, Q[:, i], Vv[:, i]) for i, s in enumerate(res.t)])
                part += rows[j][4] * np.concatenate([[0.0], np.cumsum(np.diff(res.t) * (speed[1:] + speed[:-1]) / 2)])
        keep = slice(1, None) if out_t else slice(None)
        out_t.append(res.t[keep]); out_q.append(Q[:, keep]); out_v.append(Vv[:, keep])
        T.append(res.T[keep]); V.append(res.V[keep]); D.append(res.D[keep]); heat.append(part[keep])
        made = float(part[-1])
        hit = res.events[-1] if res.events and res.t[-1] < t1 else None
        if hit is None:
            break
        j = int(hit.name.split()[-1])
        tt, q, v = hit.t, Q[:, -1].copy(), Vv[:, -1].copy()
        phases = _decide(phases_of, phases, [j], tt, q, v, switches)
        if len(switches) > MAX_SWITCHES:
            raise ModelError(f"model {model.name!r}: more than {MAX_SWITCHES} switches between sticking and slipping "
                             f"by t = {tt:.6g}: the friction chatters (a static limit F_s below the sliding force F_c, "
                             f"or a stiff spring on it).")
    notes.append(f"{len(switches)} switch(es) between sticking and slipping; each phase run by {res.method}")
    return StickSlipResult(
        t=np.concatenate(out_t), q=dict(zip(names, np.hstack(out_q))), v=dict(zip(names, np.hstack(out_v))),
        T=np.concatenate(T), V=np.concatenate(V), D=np.concatenate(D), model=model.name, defaulted=defaulted,
        nfev=nfev, method=f"{res.method} + stick–slip", notes=notes, switches=switches, heat=np.concatenate(heat),
        evaluator=_evaluator(phases_of), derived={n: e.function for n, e in base.assembly.eliminated.items()},
    )


def _evaluator(phases_of: _Phases):
    """``Result.quantity`` of a stick–slip run: an expression of the coordinates, their rates, ``t`` and the
    parameters is the same in every phase; evaluated with the model sliding (which holds every parameter)."""
    def evaluate(expr, result):
        sliding = phases_of.model_in(("slip+",) * len(phases_of.names))
        return sliding.numeric(phases_of.params_of(sliding)).evaluate(expr, result)

    return evaluate


def _onto(rows, phases, time: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``v`` with the rate of every stuck component set to zero, changed as little as possible."""
    v = v.copy()
    for row, ph in zip(rows, phases):
        if ph == "stick":
            a = np.asarray(row[0](time, q), dtype=float)
            v -= a * _rate(row, time, q, v) / float(a @ a)
    return v


def _event(numeric, row, phase: str, j: int) -> Event:
    """The event ending ``phase``: the rate through zero (sliding), the sticking force reaching its limit (stuck)."""
    if phase == "stick":
        k, limit = row[2], row[3]
        eq = numeric.eq
        inertial = eq.inertial
        names = eq.names

        def force(time, q, v):
            qv = np.array([q[n] for n in names])
            vI = np.array([v[names[i]] for i in inertial])
            return abs(float(numeric.solve(time, qv, vI)[k])) - limit

        return Event(force, direction=1, terminal=True, name=f"slips {j}")
    names = numeric.eq.names

    def moving(time, q, v):
        return _rate(row, time, np.array([q[n] for n in names]), np.array([v[n] for n in names]))

    return Event(moving, direction=-1 if phase == "slip+" else 1, terminal=True, name=f"stops {j}")


def _decide(phases_of: _Phases, phases: tuple[str, ...], which, time: float, q: np.ndarray, v: np.ndarray,
            switches: list[Switch], start: bool = False) -> tuple[str, ...]:
    """The new phase of each component in ``which``: sliding on while its rate is not zero (at the start), else stuck
    if the force that takes stays within its limit, else sliding against that force."""
    new = list(phases)
    for j in which:
        trial = tuple("stick" if i == j else p for i, p in enumerate(new))
        numeric, rows = phases_of.numbers(trial)
        moving = _rate(rows[j], time, q, v)
        scale = float(np.max(np.abs(v), initial=0.0)) + 1e-300
        if start and abs(moving) > 1e-12 * max(scale, 1.0):  # sliding from the start: no switch
            new[j] = "slip+" if moving > 0 else "slip-"
            continue
        else:
            held = _onto(rows, trial, time, q, v)
            eq = numeric.eq
            u = numeric.solve(time, q, held[eq.inertial])
            force = float(u[rows[j][2]])
            if phases[j] == "stick" and not start:  # its force has reached the limit: it slides, against the force
                after = "slip-" if force > 0 else "slip+"
            else:
                after = "stick" if abs(force) <= rows[j][3] else ("slip-" if force > 0 else "slip+")
        before = "stick" if start else phases[j]  # at rest at the start: stuck until it slips
        if after != before:
            switches.append(Switch(float(time), phases_of.names[j], before, after, force))
        new[j] = after
    return tuple(new)
