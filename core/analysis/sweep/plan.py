"""From a model and its samples to what the workers run: the compiled form, one parameter vector and one initial
state per sample, the outputs, and the samples refused before any run (a value that breaks a parameter's rule).

Names in a sweep are a model's parameters (``"k_k1"``, as
``Model.parameter_values`` and ``simulate(params=...)`` name them, or a
symbolic parameter's name), a coordinate's initial value (``"x_p(0)"``) or
initial rate (``"x_p'(0)"``).  Outputs are coordinates (``"x_p"``), their
rates (``"x_p'"``), the energies ``"T"``, ``"V"``, ``"D"``, ``"E"`` (= T + V)
and the Jacobi integral ``"h"``, a branch quantity (``"v(C1)"``,
``"i(L1)"``, a node voltage ``"v(n2)"``), or an expression in coordinates,
rates and parameters (text, read by a whitelist, or SymPy).
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...base.arguments import check_grid, check_positive, check_span
from ...base.component import _CHECKS, LARGEST, t
from ...base.text import parse_expression
from ...errors import ModelError, ParameterError, UnknownNameError, warn
from ...model import Model
from ...numerics.ensemble import METHODS, CompiledForm, RunSpec, compile_form
from ...numerics.problem import Problem
from ...numerics.simulation import InitialConditionWarning, initial_state
from ..channels import _BRANCH, _PRIMES, _output_expr, _unit
from .designs import Samples
from ...base import deferred as _deferred

sp = _deferred.module("sympy", globals())

__all__ = ["Plan", "plan", "ENERGIES"]

#: Outputs that are energies of the run, with their units.
ENERGIES = {"T": "J", "V": "J", "D": "W", "E": "J", "h": "J"}

_INITIAL = re.compile(r"^(.+?)('?)\(0\)$")


@dataclass
class Plan:
    """What a sweep of simulations runs (see :func:`plan`)."""

    form: CompiledForm
    P: np.ndarray
    Y0: np.ndarray
    spec: RunSpec
    outputs: list[str]
    units: dict[str, str]
    refused: dict[int, str]
    notes: list[str] = field(default_factory=list)
    parameter_units: dict[str, str] = field(default_factory=dict)


def _roles(model: Model, names: Sequence[str]) -> dict[str, tuple[str, Any]]:
    """What each swept or fixed name sets: ``("param", name)``, ``("q0", index)`` or ``("v0", index)``."""
    coords = model.coordinate_names
    known = {s.name for s in [*model.parameters, *model.assembly.values]}
    roles = {}
    for name in names:
        initial = _INITIAL.match(name)
        if initial and initial.group(1) in coords:
            base, prime = initial.groups()
            i = coords.index(base)
            if prime and i in model.eq.first_order:
                raise ModelError(f"sweep: coordinate {base!r} is first-order (it has no inertia): its rate follows "
                                 f"from the equations and cannot be given an initial value ({name!r}).")
            roles[name] = ("v0", model.eq.inertial.index(i)) if prime else ("q0", i)
        elif name in known:
            roles[name] = ("param", name)
        else:
            raise UnknownNameError("parameter (or a coordinate's initial value 'x(0)' or rate \"x'(0)\")", name,
                                   sorted(known | {f"{c}(0)" for c in coords}))
    return roles


def _refusals(model: Model, symbols: dict[sp.Symbol, np.ndarray], count: int) -> dict[int, str]:
    """The samples whose values break a parameter's rule (positive, in (0, 1], ...), with the message that
    ``simulate`` would raise: checked for all samples at once."""
    swept = {s for s, v in symbols.items() if np.ndim(v)}
    refused: dict[int, str] = {}

    def refuse(bad: np.ndarray, values: np.ndarray, comp, pname: str, rule: str) -> None:
        for k in np.flatnonzero(bad):
            if int(k) not in refused:
                refused[int(k)] = str(ParameterError(comp.name, pname, f"{rule} (got {values[k]:g})."))

    for comp in model.components.values():
        standing = getattr(comp, "_symbols", {})
        for pname, spec in comp.parameters.items():
            symbol, value = standing.get(pname), comp.params.get(pname)
            if isinstance(symbol, sp.Symbol):
                expr = symbol
            elif isinstance(value, sp.Expr) and not isinstance(value, sp.MatrixBase) and value.free_symbols - {t}:
                expr = value
            else:
                if symbol is not None:  # entries of a vector: each keeps the sign it was given with
                    entries = symbol.values() if isinstance(symbol, Mapping) else [symbol]
                    for entry in {s for e in entries for s in sp.sympify(e, strict=True).free_symbols if s in swept}:
                        x = np.broadcast_to(symbols[entry], (count,))
                        sign = "positive" if entry.is_positive else "negative"
                        bad = ~(x > 0) if entry.is_positive else ~(x < 0)
                        refuse(bad, x, comp, pname, f"entry {entry.name!r} was given as a {sign} number and must stay {sign}")
                continue
            free = sorted(expr.free_symbols & set(symbols), key=sp.default_sort_key)
            if not set(free) & swept or t in expr.free_symbols:
                continue
            fn = sp.lambdify(free, expr, "numpy")
            with np.errstate(all="ignore"):
                x = np.asarray(np.broadcast_to(fn(*(symbols[s] for s in free)), (count,)), dtype=complex)
            test, rule = _CHECKS[spec.check]
            real = np.isfinite(x) & (x.imag == 0)
            refuse(~real, x.real, comp, pname, "must be a finite real number")
            xr = x.real
            refuse(real & ~np.vectorize(test, otypes=[bool])(xr), xr, comp, pname, rule)
            refuse(real & (np.abs(xr) > LARGEST), xr, comp, pname, f"is beyond {LARGEST:g}")
    return refused


def _base(model: Model, given: dict[str, Any], count: int) -> tuple[dict[str, float], dict[sp.Symbol, float]]:
    """One sample's values by name and every parameter's value by symbol (names checked, symbolic parameters
    without values refused): the first sample whose values the parameters' rules accept."""
    first = None
    for k in range(min(count, 64)):
        base = {name: float(np.broadcast_to(v, (count,))[k]) for name, v in given.items()}
        try:
            return base, model._values(base, overrides=True)
        except ParameterError as exc:
            first = first or exc
    raise ModelError(f"sweep: no sample among the first {min(count, 64)} has values the model accepts; the first "
                     f"says: {first}")


def _outputs(model: Model, outputs: Sequence[Any] | None, form_parameters: dict[str, sp.Symbol]):
    """``(names, keep rows, expressions recorded as a tape, units)`` of the outputs asked for."""
    eq = model.eq
    names = eq.names
    if outputs is None:
        outputs = list(names)
    if isinstance(outputs, (str, sp.Basic)):
        outputs = [outputs]
    labels, keep, exprs, units = [], [], {}, {}
    for output in outputs:
        label = str(output)
        if label in labels:
            continue
        if isinstance(output, str) and output in ENERGIES and output not in names:
            keep.append((output,))
            units[label] = ENERGIES[output]
        else:
            base, primes = _PRIMES.match(label.strip()).groups() if isinstance(output, str) else (None, "")
            if isinstance(output, str) and base in names and len(primes) <= 1:
                i = names.index(base)
                keep.append(("v" if primes else "q", i))
            else:
                if isinstance(output, str) and base in names:
                    raise ModelError(f"sweep: output {label!r}: accelerations are not kept by sweeps; keep the "
                                     f"rate {base + chr(39)!r} and differentiate it, or sweep an analysis.")
                if isinstance(output, str) and not _BRANCH.match(output):
                    coordinates = {c.name: c.function for c in eq.coordinates}
                    expr = parse_expression(output, f"sweep output {label!r}", names={**coordinates, **form_parameters})
                else:
                    label, expr = _output_expr(model, eq, output)
                plain = eq.symbolic(expr)
                bad = plain.free_symbols - set(eq.sym.q) - set(eq.sym.v) - {t} - set(form_parameters.values())
                if bad or plain.atoms(sp.Derivative):
                    what = ", ".join(sorted(map(str, bad))) or "a derivative beyond the rates"
                    raise ModelError(f"sweep: output {label!r} depends on {what}, which is not a coordinate, a rate or "
                                     f"a parameter.")
                keep.append(("out", len(exprs)))
                exprs[label] = plain
            units[label] = _unit(label) if not keep[-1][0] == "out" or _BRANCH.match(label) else ""
        labels.append(label)
    return labels, keep, exprs, units


def plan(model: Model, samples: Samples, *, initial: Mapping[str, float] | None = None,
         velocity: Mapping[str, float] | None = None, outputs: Sequence[Any] | None = None,
         t_end: Any = 10.0, points: int = 201, t_eval: Sequence[float] | None = None, method: str = "DOP853",
         rtol: float | None = None, atol: float | None = None, max_step: float | None = None,
         max_evaluations: float | None = None) -> Plan:
    """The :class:`Plan` of a sweep of ``model.simulate`` over ``samples`` (see :func:`lagrangian.sweep.sweep`)."""
    if method not in METHODS:
        raise ModelError(f"sweep: method {method!r} does not run in a sweep's compiled loop; use one of "
                         f"{', '.join(map(repr, METHODS))} (the default, DOP853, is Model.simulate's), or sweep "
                         f"another method as an analysis: sweep(model, ..., analysis=fn) with fn(model, values) "
                         f"calling model.simulate(..., method={method!r}).")
    swept = {**samples.table, **samples.fixed}
    roles = _roles(model, list(swept))
    count = samples.count
    base, values = _base(model, {name: v for name, v in swept.items() if roles[name][0] == "param"}, count)
    form_parameters = {s.name: s for s in values}
    names, keep, exprs, units = _outputs(model, outputs, form_parameters)
    numeric = model.numeric(base)
    conservative = Problem(numeric, model.name).structure.conservative
    form = compile_form(model.eq, values, name=model.name, outputs=exprs, conservative=conservative)
    columns: dict[sp.Symbol, np.ndarray | float] = dict(values)
    for name, given in swept.items():
        if roles[name][0] == "param":
            for s in values:
                if s.name == name:
                    columns[s] = given
    P = np.empty((count, len(form.parameters)))
    for j, (pname, s) in enumerate(zip(form.parameters, sorted(values, key=sp.default_sort_key))):
        P[:, j] = columns[s]
    refused = _refusals(model, {s: np.asarray(v, dtype=float) for s, v in columns.items()}, count)
    eq = model.eq
    y0, defaulted = initial_state(eq, dict(initial or {}), dict(velocity or {}), warn=False)
    Y0 = np.tile(y0, (count, 1))
    for name, given in swept.items():
        role, index = roles[name]
        if role == "q0":
            Y0[:, index] = given
        elif role == "v0":
            Y0[:, form.n + index] = given
    swept_initial = {f"{eq.names[i]}" if r == "q0" else f"{eq.names[eq.inertial[i]]}'" for r, i in
                     (roles[n] for n in swept) if r != "param"}
    defaulted = [d for d in defaulted if d not in swept_initial]
    if defaulted:
        warn(f"sweep: initial conditions not given, set to zero: {', '.join(defaulted[:40])}", InitialConditionWarning)
    span = check_span(t_end)
    grid = check_grid(span, points, t_eval, len(y0) * max(count, 1))
    rtol = check_positive("rtol", rtol)
    atol_value = 1e-12 if atol is None else atol
    if np.ndim(atol_value) or not (isinstance(atol_value, (int, float)) and math.isfinite(atol_value) and atol_value > 0):
        raise ModelError(f"sweep: atol must be one positive number, got {atol!r:.60}.")
    cap = check_positive("max_step", max_step)
    budget = check_positive("max_evaluations", max_evaluations, infinite=True)
    spec = RunSpec(span=span, t_eval=np.asarray(grid, dtype=float), method=method, rtol=1e-9 if rtol is None else rtol,
                   atol=float(atol_value), max_step=math.inf if cap is None else cap,
                   budget=1e9 if budget is None else (0.0 if math.isinf(budget) else budget), keep=tuple(keep))
    notes = []
    if eq.time_switches():
        notes.append("the equations switch at times of their own (piecewise signals): the loop steps across them "
                     "without a restart, so results near a switch are as accurate as the tolerances allow")
    parameter_units = {}
    for comp in model.components.values():
        for pname, sym in getattr(comp, "_symbols", {}).items():
            if isinstance(sym, sp.Symbol) and sym.name in swept and comp.parameters[pname].unit:
                parameter_units[sym.name] = comp.parameters[pname].unit
    return Plan(form, P, Y0, spec, names, units, refused, notes, parameter_units)
