"""The linearization of a linear time-invariant model, assembled in numbers or read off its stamps, not derived.

:func:`numeric` takes a model whose components and domains say their
contributions in numbers (:mod:`lagrangian.derivation.numeric`): nothing
symbolic is built at all, and a 100-section RLC ladder is linearized in
about 7 ms.  :func:`stamped`, next, differentiates each component's own
symbolic energy (the stamps) where the model is linear time-invariant but
not said in numbers.

A model whose parameters all have values, with no loop-closure or other
constraint, whose components contribute energies quadratic in the state
with constant coefficients (:mod:`lagrangian.derivation.stamps`: masses,
springs, dampers, inductors, capacitors, resistors, sources, couplings),
has the same linearization about every point, and its matrices are the
stamps themselves: ``M``, ``C``, ``K``, and ``B`` split by input and by
power of ``s``.  :func:`stamped` assembles them numerically, component by
component, where :func:`lagrangian.frequency.linearize` would otherwise
derive the model's equations symbolically and differentiate them.  On an
RLC ladder of 100 sections (300 components, ``benchmarks/ac.py``: built,
linearized and solved at 1,000 frequencies) the linearization takes 0.13 s
where the derivation takes 0.39 s, with the same matrices; what is left is
the assembly (symbolic contributions) and the stamps' differentiation of
each.

Anything the stamps refuse (a coefficient that depends on the state or on
``t``, an input multiplied by a function of ``t``, constraints, parameters
without values) returns ``None``, and the symbolic linearization runs, with
its messages.

>>> import lagrangian as lg
>>> from lagrangian.frequency import linearize
>>> m = lg.Model("rc")
>>> _ = m.add("voltage_source", "V1", ("in", "0"), E=0)
>>> _ = m.add("resistor", "R1", ("in", "out"), R=1e3)
>>> _ = m.add("capacitor", "C1", ("out", "0"), C=2.2e-6)
>>> lin = linearize(m, inputs=["V1"], outputs=["v(C1)"])
>>> lin.C, lin.K, lin.B[0]          # R q̇ + q/C = E: read off the stamps
(array([[1000.]]), array([[454545.45454545]]), array([[1.]]))
"""

from __future__ import annotations

from collections.abc import Mapping
from types import SimpleNamespace
from typing import Any

import numpy as np

from ..base import waveforms as _waveforms
from ..base.component import _CallableSignal, t
from ..derivation.numeric import NumericAssembly, assemble_numeric
from ..derivation.stamps import NotStampable, stamps
from ..errors import ModelError
from ..model import Model
from .channels import _BRANCH, _PRIMES, _chosen, _label, _outputs, _signal_of, _voltage_graph, _voltage_path
from ..base import deferred as _deferred

sp = _deferred.module("sympy", globals())

__all__ = ["numeric", "stamped"]


def _column(shape: sp.Expr, channels: Mapping[Any, tuple]) -> tuple[int, int] | None:
    """``(column, k)`` when ``shape`` is the ``k``-th derivative of an input function, ``None`` when it holds no input
    (an operating value: a constant load, a bias, a signal of ``t``)."""
    if isinstance(shape, sp.core.function.AppliedUndef) and shape.func in channels and shape.args == (t,):
        return channels[shape.func][1], 0
    if (isinstance(shape, sp.Derivative) and isinstance(shape.expr, sp.core.function.AppliedUndef) and shape.expr.func in channels
            and set(shape.variables) == {t}):
        return channels[shape.expr.func][1], shape.derivative_count
    if any(f.func in channels for f in shape.atoms(sp.core.function.AppliedUndef)):
        raise NotStampable(f"an input enters as {shape}, not alone")
    return None


def _rest(K: np.ndarray, b0: np.ndarray) -> np.ndarray:
    """Where ``K x = b0`` holds, by least squares (SPICE's operating point of a linear circuit); zeros when nothing
    does (a singular stiffness the forces do not balance: a DC current through an inductor), as the derived path's
    Newton iteration from the origin leaves it."""
    x = np.zeros(K.shape[0])
    scale = max(float(np.abs(K).max(initial=0.0)), 1e-300)
    if np.abs(b0).max(initial=0.0) <= 1e-12 * scale:
        return x
    step, *_ = np.linalg.lstsq(K, b0, rcond=None)
    if not np.all(np.isfinite(step)) or np.abs(K @ step - b0).max() > 1e-9 * max(np.abs(b0).max(), 1e-300):
        return x
    return step


def _number(expr, model: str) -> float:
    """``expr`` (an entry at the operating point) as a float; a :class:`~lagrangian.errors.ModelError` when it is not
    a finite number."""
    try:
        value = float(expr)
    except TypeError:
        raise ModelError(f"model {model!r}: {expr} does not evaluate to a number at the operating point "
                         f"(a parameter without a value?).") from None
    if not np.isfinite(value):
        raise ModelError(f"model {model!r}: the equations are not finite at this operating point ({expr}): "
                         f"a singular configuration; linearize about another point.")
    return value


def stamped(twin: Model, channels: Mapping[Any, tuple], values: Mapping[sp.Symbol, Any],
            at: Mapping[str, Any] | None, time: float, outputs=None) -> dict | None:
    """The pieces of the linearization of ``twin`` (the model with its inputs driven by the functions of
    ``channels``) from its stamps, or ``None`` when it is not linear time-invariant in their sense.

    Returns ``M``, ``C``, ``K`` (arrays), ``Bw`` (input columns by derivative
    of the input function ``w``: ``Bw[k]`` multiplies ``s^(k−1) u``),
    ``point`` (the operating point: ``at``, else where the model rests with
    the inputs at their operating values), ``names``, ``first_order`` and
    ``rows``, the rows of ``outputs`` by power of ``s`` and their values at
    the point (:func:`lagrangian.analysis.channels._outputs`).
    """
    asm = twin.assembly
    try:
        st = stamps(asm, values, inputs=frozenset(channels), energies=False)
        n = st.n
        order = 1
        Bw: dict[int, np.ndarray] = {}
        b0 = np.zeros(n)
        B = st.B.toarray()
        for j, shape in enumerate(st.inputs):
            # w(0), from integrating a source over [0, t] (a voltage source in node fluxes): 0 at the point
            shape = shape.xreplace({a: sp.Integer(0) for a in shape.atoms(sp.core.function.AppliedUndef)
                                    if a.func in channels and a.args != (t,)})
            if shape == 0:
                continue
            where = _column(shape, channels)
            if where is None:  # the forcing at the operating point: its value at t₀
                value = shape.xreplace({t: sp.Float(time)}) if shape.has(t) else shape
                if not value.is_number:
                    raise NotStampable(f"the input shape {shape} has no value at t = {time:g}")
                b0 += B[:, j] * float(value)
                continue
            col, k = where
            order = max(order, k)
            Bw.setdefault(k, np.zeros((n, len(channels))))[:, col] += B[:, j]
    except (NotStampable, TypeError, ValueError):
        return None
    names = st.names
    K = st.K.toarray()
    if at is None:
        x = _rest(K, b0)
        point = {nm: sp.Float(v) if v else sp.Integer(0) for nm, v in zip(names, x)}
    else:
        point = dict(at)
    coordinates = list(asm.coordinates)
    eq = SimpleNamespace(names=names, coordinates=coordinates, eliminated=dict(asm.eliminated),
                         sym=SimpleNamespace(q=[sp.Symbol(f"q_{c}", real=True) for c in names],
                                             v=[sp.Symbol(f"v_{c}", real=True) for c in names],
                                             a=[sp.Symbol(f"a_{c}", real=True) for c in names]))
    symbol_of: dict[tuple[int, int], sp.Symbol] = {}

    def usym(col: int, k: int) -> sp.Symbol:
        if (col, k) not in symbol_of:
            symbol_of[col, k] = sp.Dummy(f"u{col}_{k}", real=True)
        return symbol_of[col, k]

    subs = {**{qs: point[nm] for qs, nm in zip(eq.sym.q, names)}, **{vs: sp.Integer(0) for vs in eq.sym.v},
            t: sp.Float(time) if time else sp.Integer(0), **{sym: sp.Float(val) for sym, val in values.items()}}

    def at_point(expr):
        inputs = dict.fromkeys(symbol_of.values(), sp.Integer(0))
        return _number(sp.sympify(expr, strict=True).xreplace({**subs, **inputs}), twin.name)

    return {"M": st.M.toarray(), "C": st.C.toarray(), "K": K, "point": point, "names": names,
            "Bw": [Bw.get(k, np.zeros((n, len(channels)))) for k in range(order + 1)],
            "first_order": [names[i] for i in st.first_order],
            "rows": _outputs(twin, eq, outputs, usym, channels, at_point)}


def numeric(model: Model, inputs, outputs, time: float) -> dict | None:
    """The pieces of the linearization of ``model`` about its rest, assembled in numbers
    (:mod:`lagrangian.derivation.numeric`): nothing symbolic is built.  ``None`` when a component, a domain, an
    input or an output is not given in numbers; the caller then takes the symbolic path.

    Returns what :func:`stamped` does, plus ``channels`` (by input name: ``(label, column, operating value)``).
    """
    chosen = _chosen(model, inputs)  # bad inputs are refused here as on the symbolic path
    components = model.components
    try:
        asm = assemble_numeric(model)
        n = len(asm.names)
        channels = {}
        Bw = [np.zeros((n, len(chosen))), np.zeros((n, len(chosen)))]
        b0 = np.zeros(n)
        signal: dict[str, float] = {}  # each source's signal at t₀
        for cname, force in asm.forces.items():
            comp = components[cname]
            pname = _signal_of(comp)
            if pname is None:
                raise NotStampable(f"{comp.kind} {cname!r} has a force but no one signal")
            signal[cname] = _at(comp.params.raw(pname), time)
            b0 += force * signal[cname]
        if asm.loads is not None:  # constant loads (gravity, rest lengths) move the rest point
            b0 += asm.loads
        for cname, (pname, index, label) in chosen.items():
            comp = components[cname]
            if index is not None or pname != _signal_of(comp):
                raise NotStampable(f"input {label!r} is not its component's one signal")
            col = len(channels)
            channels[cname] = (label, col, comp.params.raw(pname))  # as held: a number, a waveform, an expression
            if cname in asm.forces:
                Bw[1][:, col] = asm.forces[cname]
        inertial = asm.inertial()
        idle = [nm for nm, m, c in zip(asm.names, inertial, asm.dissipative()) if not m and not c]
        if idle:
            raise NotStampable(f"coordinates without inertia or dissipation: {', '.join(idle[:5])}")
        x = _rest(asm.K, b0)
        rows = _numeric_outputs(model, asm, outputs, channels, signal, x, time)
    except NotStampable:
        return None
    point = {nm: float(v) for nm, v in zip(asm.names, x)}
    return {"M": asm.M, "C": asm.C, "K": asm.K, "point": point, "names": asm.names, "Bw": Bw,
            "first_order": [nm for nm, m in zip(asm.names, inertial) if not m], "rows": rows, "channels": channels}


def _at(value: Any, time: float) -> float:
    """A signal's value at ``t₀`` as a float, or :class:`NotStampable` (a Python callable, a symbol)."""
    if isinstance(value, _CallableSignal):
        raise NotStampable("a signal given as a Python callable")
    if _waveforms.numeric(value):  # held as given (lagrangian.base.params)
        value = _waveforms.value_at(value, time)
    elif isinstance(value, sp.Basic) and value.has(t):
        value = value.xreplace({t: sp.Float(time)})
    try:
        out = float(value)
    except (TypeError, ValueError):
        raise NotStampable(f"the signal {value} has no value") from None
    if not np.isfinite(out):
        raise NotStampable(f"the signal {value} is not finite at t = {time:g}")
    return out


def _numeric_outputs(model: Model, asm: NumericAssembly, outputs, channels, signal, x, time) -> tuple:
    """``(Cq, Dw, y0)`` as :func:`lagrangian.analysis.channels._outputs` gives them, from the numeric assembly:
    coordinates and their rates, component quantities and node voltages; :class:`NotStampable` for anything else
    (an expression, an eliminated coordinate), which the symbolic path reads."""
    names = asm.names
    wanted = list(outputs) if outputs is not None else list(names)
    n, m = len(names), len(wanted)
    Cq = [np.zeros((m, n)) for _ in range(3)]
    Dw = [np.zeros((m, len(channels))) for _ in range(2)]
    y0 = {}
    graph = None  # of the elements naming their voltage, made for the first node voltage asked for
    components, nodes = model.components, set(model.nodes)
    for r, output in enumerate(wanted):
        if not isinstance(output, str):
            raise NotStampable(f"output {output!r} is an expression")
        terms: list[tuple[Any, int, list[np.ndarray], float]] = []  # (component, sign, rows by order, signal)
        branch = _BRANCH.match(output)
        if branch:
            quantity, name = branch.group(1).lower(), branch.group(2)
            if name not in components and quantity == "v" and name in nodes:
                graph = graph if graph is not None else _voltage_graph(model)
                path = _voltage_path(model, name, graph)
            elif name in components:
                path = [(components[name], 1)]
            else:
                raise NotStampable(f"output {output!r} names no component")
            for comp, sign in path:
                got = asm.quantity(comp, quantity)
                if got is None:
                    raise NotStampable(f"{comp.kind} {comp.name!r} gives no {quantity!r} in numbers")
                terms.append((comp, sign, *got))
        else:
            base, primes = _PRIMES.match(output.strip()).groups()
            if base not in names:
                raise NotStampable(f"output {output!r} is no coordinate")
            row = [np.zeros(n) for _ in range(len(primes) + 1)]
            row[-1][names.index(base)] = 1.0
            terms.append((None, 1, row, 0.0))
        value = 0.0
        for comp, sign, rows, coeff in terms:
            if len(rows) > 3:
                raise NotStampable(f"output {output!r} holds a third derivative")
            for order, row in enumerate(rows):
                Cq[order][r] += sign * row
            if coeff:
                if comp.name in channels:
                    Dw[1][r, channels[comp.name][1]] += sign * coeff
                value += sign * coeff * (signal[comp.name] if comp.name in signal
                                         else _at(comp.params[_signal_of(comp)], time))
        y0[_label(output)] = float(Cq[0][r] @ x) + value
    while len(Cq) > 1 and not Cq[-1].any():
        Cq.pop()
    return Cq, Dw, y0
