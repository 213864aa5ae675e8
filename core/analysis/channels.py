"""Inputs and outputs of a linearization: which components drive it, which quantities it reports.

An input is a component with a signal parameter (a source, a force, a
torque, a prescribed motion), named ``"V1"``, ``"F.F"`` or ``"F[0]"`` (one
entry of a vector); :func:`_with_inputs` gives a copy of the model in which
each input's parameter carries the rate of an input function ``w(t)``
(:meth:`lagrangian.Component.with_input`).  An output is a coordinate
(``"x_p"``, ``"x_p'"``, ``"x_p''"``; one a constraint eliminated too: its solution, an expression of the
remaining coordinates and ``t``), a quantity a component names
(``"v(C1)"``, ``"i(L1)"``: :meth:`lagrangian.Component.quantity`), a circuit
node's voltage to ground (``"v(n3)"``: the element voltages along a path to
ground) or a
SymPy expression of the coordinates; :func:`_outputs` linearizes each into
rows by power of ``s``.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..base.component import GROUND, t
from ..base.domain import Context
from ..base.units import coordinate_unit
from ..derivation.assembly import driven
from ..derivation.calculus import atoms_of
from ..derivation.numeric import assemble_numeric
from ..derivation.stamps import NotStampable
from ..errors import ModelError, UnknownNameError
from ..model import Model
from ..base import deferred as _deferred

sp = _deferred.module("sympy", globals())

_BRANCH = re.compile(r"^\s*([A-Za-z]\w*)\s*\(\s*([^()\s]+)\s*\)\s*$")
_PRIMES = re.compile(r"^(.*?)('{0,2})$")
_INPUT = re.compile(r"^\s*([^.\[\]\s]+)(?:\.(\w+))?(?:\[(\d+)\])?\s*$")


def _label(output: Any) -> str:
    return output if isinstance(output, str) else str(output)


def _with_inputs(model: Model, inputs: Sequence[str] | None) -> tuple[Model, dict[Any, tuple[str, int, Any]]]:
    """A copy of ``model`` whose input components carry ``u(t)``; ``channels`` maps each input function to
    ``(name, column, operating value)``."""
    chosen = _chosen(model, inputs)
    if not chosen:  # nothing to drive: the model itself (a reduced or derived model keeps its own equations)
        return model, {}
    twin, functions = driven(model, chosen)
    channels: dict[Any, tuple[str, int, Any]] = {}
    for name in functions:  # in the model's order of components
        pname, index, label = chosen[name]
        original = model.components[name].params[pname]
        channels[functions[name]] = (label, len(channels), original if index is None else original[index])
    return twin, channels


def _chosen(model: Model, inputs: Sequence[str] | str | None) -> dict[str, tuple[str, int | None, str]]:
    """The input components by name, each as ``(signal parameter, index or None, label)``: those of ``inputs``
    (checked), every source and load by default."""
    components = model.components
    if inputs is None:  # every source and load (a joint's free angle is no input)
        inputs = [c.name for c in components.values()
                  if _signal_of(c) is not None and c.params.get(_signal_of(c)) is not None
                  and not isinstance(c.params[_signal_of(c)], sp.MatrixBase)]
    elif isinstance(inputs, str):
        inputs = [inputs]
    chosen: dict[str, tuple[str, int | None, str]] = {}
    for item in inputs:
        if not isinstance(item, str):
            raise ModelError(f"inputs are component names (or 'name.param', 'name[0]'), got {item!r}.")
        spec = _INPUT.match(item)
        if spec is None:
            raise ModelError(f"input {item!r} is not a component name, 'name.param' or 'name[index]'.")
        name, pname, index = spec.group(1), spec.group(2) or "", spec.group(3)
        comp = model.component(name)
        pname = pname or _signal_of(comp)
        if pname is not None and comp.params.raw(pname) is None:
            raise ModelError(f"{comp.kind} {name!r} has no value for {pname!r} to drive (a free joint): give it one "
                             f"(0 for a joint held at its reference) to make it an input.")
        if pname is None:
            signals = [c.name for c in components.values() if _signal_of(c) is not None]
            raise ModelError(f"{comp.kind} {name!r} has no signal parameter to drive; components that do: "
                             f"{', '.join(signals) or '(none)'}.")
        if name in chosen:
            raise ModelError(f"input {name!r} is listed twice.")
        chosen[name] = (pname, None if index is None else int(index), item.strip())
    return chosen


def _signal_of(comp) -> str | None:
    signals = [p for p, spec in comp.parameters.items() if spec.shape == "signal"]
    return signals[0] if len(signals) == 1 else None


def _atoms(exprs, channels) -> set:
    """The applications ``w(…)`` and derivatives of input functions in ``exprs`` (of every undefined function when
    ``channels`` is empty), each distinct sub-expression visited once."""
    found = set()
    for e in atoms_of([sp.sympify(e, strict=True) for e in exprs], sp.Derivative, sp.core.function.AppliedUndef):
        if isinstance(e, sp.Derivative):
            if isinstance(e.expr, sp.core.function.AppliedUndef) and (not channels or e.expr.func in channels):
                found.add(e)
        elif not channels or e.func in channels:
            found.add(e)
    return found


def _channel(expr, channels) -> tuple[int, int]:
    if isinstance(expr, sp.Derivative):
        return expr.derivative_count, channels[expr.expr.func][1]
    return 0, channels[expr.func][1]


def _outputs(twin: Model, eq, outputs, usym, channels, at_point):
    """Rows ``Cq_k`` (by power of s) and ``Dw_k`` (by derivative of the input function ``w``: ``Dw_k`` multiplies
    ``s^(k−1) u``) of each output, and its value at the point."""
    names = eq.names
    n = len(names)
    eliminated = getattr(eq, "eliminated", {})
    exprs = [(label, _solved(e, eliminated)) for label, e in
             (_output_expr(twin, eq, o) for o in (outputs if outputs is not None else names))]
    q, v, a = list(eq.sym.q), list(eq.sym.v), list(eq.sym.a)
    to_sym: dict[Any, Any] = {}
    for c, qs, vs, as_ in zip(eq.coordinates, q, v, a):
        f = c.function
        to_sym[sp.Derivative(f, (t, 2))] = as_
        to_sym[sp.Derivative(f, t)] = vs
        to_sym[f] = qs
    rows_q = [sp.zeros(len(exprs), n) for _ in range(3)]
    rows_u = [sp.zeros(len(exprs), len(channels)) for _ in range(2)]
    y0 = {}
    for r, (label, expr) in enumerate(exprs):
        e = sp.sympify(expr, strict=True)
        e = e.xreplace({d: to_sym[d] for d in e.atoms(sp.Derivative) if d in to_sym})
        e = e.xreplace({f: to_sym[f] for f in e.atoms(sp.core.function.AppliedUndef) if f in to_sym})
        e = e.xreplace({a: sp.Integer(0) for a in e.atoms(sp.core.function.AppliedUndef) if a.func in channels and a.args != (t,)})
        ins = {}
        for d in e.atoms(sp.Derivative):
            if isinstance(d.expr, sp.core.function.AppliedUndef) and d.expr.func in channels:
                col, k = channels[d.expr.func][1], d.derivative_count
                ins[d] = (usym(col, k), col, k)
        e = e.xreplace({d: sym for d, (sym, _, _) in ins.items()})
        bare = {a: (usym(channels[a.func][1], 0), channels[a.func][1], 0) for a in e.atoms(sp.core.function.AppliedUndef) if a.func in channels}
        e = e.xreplace({d: sym for d, (sym, _, _) in bare.items()})
        ins.update(bare)
        left = e.atoms(sp.Derivative) | e.atoms(sp.core.function.AppliedUndef)
        if left:
            raise ModelError(f"output {label!r} depends on {sorted(map(str, left))[0]}, which is neither a "
                             f"coordinate, its first two derivatives, nor an input.")
        free = e.free_symbols
        for j in range(n):
            for k, syms in enumerate((q, v, a)):
                if syms[j] in free:
                    rows_q[k][r, j] = at_point(sp.diff(e, syms[j]))
        for sym, col, k in ins.values():  # the k-th derivative of w is s^(k−1) u: rows_u[k] (rows_u[0]: u/s)
            while k >= len(rows_u):
                rows_u.append(sp.zeros(len(exprs), len(channels)))
            rows_u[k][r, col] += at_point(sp.diff(e, sym))
        rest = {x: sp.Integer(0) for x in free & (set(v) | set(a))}
        rest.update({sym: sp.Integer(0) for sym, _, _ in ins.values()})
        y0[label] = at_point(e.xreplace(rest))
    while len(rows_q) > 1 and all(x == 0 for x in rows_q[-1]):
        rows_q.pop()
    return rows_q, rows_u, y0


def _output_expr(model: Model, eq, output: Any) -> tuple[str, Any]:
    """``(label, expression in q(t) and derivatives)`` of one output."""
    names = eq.names
    if isinstance(output, sp.Basic):
        return str(output), output
    if not isinstance(output, str):
        raise ModelError(f"outputs are coordinate names, quantities such as 'v(C1)', or SymPy expressions; got {output!r:.80}.")
    branch = _BRANCH.match(output)
    if branch:
        quantity, name = branch.groups()
        if name not in model.components and quantity.lower() == "v" and name in model.nodes:
            return output, _node_voltage(model, name)
        if name not in model.components and quantity.lower() == "v":
            raise UnknownNameError("component or node", name, [*model.components, *model.nodes])
        comp, views = model.component(name), _views(model)
        return output, views[name].quantity(_context(model, comp, views), quantity.lower())
    base, primes = _PRIMES.match(output.strip()).groups()
    eliminated = getattr(eq, "eliminated", {})
    if base in eliminated:  # its solution is put in by _solved
        f = eliminated[base].function
    elif base not in names:
        raise UnknownNameError("output (a coordinate, with ' for its rate)", base, [*names, *eliminated])
    else:
        f = eq.coordinates[names.index(base)].function
    return output, f if not primes else sp.Derivative(f, (t, len(primes)))


def output_series(model: Model, result: Any, label: str, params: Mapping[str, Any] | None = None) -> Any:
    """The values along ``result`` (a :class:`~lagrangian.Result` of ``model``) of the output ``label``: a
    coordinate (``"x_p"``) or its rate (``"x_p'"``), a quantity a component names (``"v(C1)"``, ``"i(L1)"``) or a
    circuit node's voltage to ground (``"v(n3)"``), as :func:`~lagrangian.frequency.linearize` reads outputs.  A
    quantity that needs accelerations (an inductor's voltage in loop charges) is refused by name: a result holds
    coordinates and rates.  ``params``: the values the run was given (``simulate(params=...)``), which its
    quantities take too.

    >>> import lagrangian as lg
    >>> c = lg.Model("rc", formulation="charge")
    >>> _ = c.add("voltage_source", "V1", ("in", "0"), E=1.0)
    >>> _ = c.add("resistor", "R1", ("in", "out"), R=1e3)
    >>> _ = c.add("capacitor", "C1", ("out", "0"), C=1e-6)
    >>> res = c.simulate(5e-3, initial={"q_R1": 0.0}, points=3)
    >>> v = output_series(c, res, "v(out)")       # 1 − exp(−t/RC)
    >>> bool(abs(v[-1] - (1 - 2.718281828459045 ** -5)) < 1e-6)
    True
    """
    if not isinstance(label, str):
        raise ModelError(f"an output is a name such as 'x_p', \"x_p'\", 'v(C1)' or 'v(n3)'; got {label!r:.80}.")
    base, primes = _PRIMES.match(label.strip()).groups()
    if base in result.names or base in result.derived:
        if not primes:
            return result[base]
        if len(primes) == 1:
            return result.velocity(base)
    found = None if params else _in_numbers(model, result, label)  # (numbers: the model's own values)
    if found is not None:
        return found
    eq = _Coordinates(model.coordinate_names, model.coordinates, model.assembly.eliminated)
    _, expr = _output_expr(model, eq, label)
    expr = _solved(expr, eq.eliminated)
    accelerations = [d for d in sp.sympify(expr, strict=True).atoms(sp.Derivative) if d.derivative_count > 1]
    if accelerations:
        raise ModelError(f"output {label!r} depends on an acceleration ({accelerations[0]}), and a result holds "
                         f"coordinates and rates only: give a quantity of those (a capacitor's voltage, an inductor's "
                         f"current, a node voltage along capacitors).")
    return result.quantity(expr)


def _in_numbers(model: Model, result: Any, label: str) -> Any:
    """``label``'s values from the model's numeric assembly (:func:`~lagrangian.derivation.numeric.assemble_numeric`,
    kept from the run when it was solved exactly): nothing symbolic is assembled or derived.  ``None`` where the
    numbers do not say it (a component without numbers, a quantity of accelerations or of a source's own signal,
    a coordinate the result does not hold): the symbolic path then evaluates or refuses it."""
    branch = _BRANCH.match(label)
    if not branch:
        return None
    quantity, name = branch.group(1).lower(), branch.group(2)
    if name in model.components:
        path = [(model.components[name], 1)]
    elif quantity == "v" and name in model.nodes:
        try:
            path = _voltage_path(model, name)
        except ModelError:
            return None
    else:
        return None
    try:
        asm = assemble_numeric(model)
    except NotStampable:
        return None
    if any(nm not in result.q for nm in asm.names):
        return None
    n = len(asm.names)
    row_q, row_v = np.zeros(n), np.zeros(n)
    for comp, sign in path:
        got = asm.quantity(comp, quantity)
        if got is None:
            return None
        rows, signal = got
        if signal or any(np.any(r) for r in rows[2:]):
            return None
        row_q += sign * rows[0]
        if len(rows) > 1:
            row_v += sign * rows[1]
    out = np.zeros(len(result.t))
    for row, series in ((row_q, result.q), (row_v, result.v)):  # the coordinates the output reads, no others
        for i in np.flatnonzero(row):
            out += row[i] * series[asm.names[i]]
    return out


@dataclass(frozen=True)
class _Coordinates:
    """What :func:`_output_expr` reads of a model's equations, from the model alone (nothing derived)."""

    names: list
    coordinates: list
    eliminated: dict


def _solved(expr: Any, eliminated) -> Any:
    """``expr`` with each coordinate a constraint eliminated, ``x(t)``, and its derivatives replaced by its solution
    (an expression of the remaining coordinates and ``t``) and the solution's derivatives."""
    if not eliminated:
        return expr
    expr = sp.sympify(expr, strict=True)
    by_function = {e.function: e for e in eliminated.values()}
    rates = {d: sp.diff(by_function[d.expr].solution, t, d.derivative_count) for d in expr.atoms(sp.Derivative)
             if d.expr in by_function and set(d.variables) == {t}}
    expr = expr.xreplace(rates) if rates else expr
    return expr.xreplace({f: by_function[f].solution for f in expr.atoms(sp.core.function.AppliedUndef) if f in by_function})


def _views(model: Model) -> dict[str, Any]:
    """Every component's symbolic view by name: quantities taken of them come out in the parameters' symbols, as
    the contributions do (a run, a linearization put in their values, ``params=`` among them)."""
    return {name: c.symbolic_view() for name, c in model.components.items()}


def _context(model: Model, comp, views: dict[str, Any]) -> Context:
    """The context of ``comp``'s quantities among ``views`` (:func:`_views`: each component sees the others' views,
    so a coupling finds its inductors among them)."""
    asm = model.assembly
    return Context(asm.views.get(comp.domain), asm.views, model.options, list(views.values()), values=asm.values)


def _node_voltage(model: Model, node: str) -> sp.Expr:
    """The voltage of circuit node ``node`` to ground: the element voltages along a path of two-terminal elements
    that name theirs (``v_a − v_b``, with the sign of the direction walked)."""
    total, views = sp.Integer(0), _views(model)
    for comp, sign in _voltage_path(model, node):
        total += sign * views[comp.name].quantity(_context(model, comp, views), "v")
    return total


def _voltage_graph(model: Model) -> dict:
    """The two-terminal elements that name their voltage (what :func:`_voltage_path` walks), as adjacency: node →
    {neighbour: element} (the last element added between two nodes)."""
    graph: dict = {}
    for comp in model.components.values():
        if len(comp.nodes) == 2 and "v" in comp.quantities:
            a, b = comp.nodes
            graph.setdefault(a, {})[b] = comp
            graph.setdefault(b, {})[a] = comp
    return graph


def _voltage_path(model: Model, node: str, graph: dict | None = None) -> list[tuple[Any, int]]:
    """The two-terminal elements that name their voltage along a shortest path from ``node`` to ground, each with
    the sign of the direction walked (+1 from its ``a`` to its ``b``); ``graph``: :func:`_voltage_graph`, when made
    already."""
    graph = _voltage_graph(model) if graph is None else graph
    path = None
    if node in graph and GROUND in graph:  # breadth first from the node
        came = {node: None}
        queue = [node]
        for here in queue:
            if here == GROUND:
                path = [here]
                while came[path[-1]] is not None:
                    path.append(came[path[-1]])
                path.reverse()
                break
            for other in graph[here]:
                if other not in came:
                    came[other] = here
                    queue.append(other)
    if path is None:
        raise ModelError(f"node {node!r} has no path of circuit elements to ground, so it has no voltage to report; "
                         f"give a voltage across an element, 'v(<element>)'.")
    out = []
    for a, b in zip(path, path[1:]):
        comp = graph[a][b]
        out.append((comp, 1 if comp.nodes == (a, b) else -1))
    return out


def _unit(label: str) -> str:
    """The unit of an output label (``"V"`` for ``v(…)``, ``"m/s"`` for ``"x_p'"``), or ``""`` when unknown."""
    branch = _BRANCH.match(label)
    if branch:
        return {"v": "V", "i": "A"}.get(branch.group(1).lower(), "")
    base, primes = _PRIMES.match(label.strip()).groups()
    unit = coordinate_unit(base)
    return unit + ("", "/s", "/s²")[len(primes)] if unit else ""


def _input_unit(comp, pname: str) -> str:
    """The unit of an input: its signal parameter's (an angle in rad, a displacement in m when it names none)."""
    unit = comp.parameters[pname].unit
    return unit or {"angle": "rad", "displacement": "m"}.get(pname, "")
