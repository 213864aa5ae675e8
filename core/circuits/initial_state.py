"""The initial state of a netlist read into a model, as coordinates and velocities.

:func:`_initial_values` gives every capacitor its initial voltage and every
inductor its initial current in SPICE's ``uic`` state (``ic=``, else the
``.ic`` node voltages, else zero); :func:`_operating_point` gives them at
the DC operating point, SPICE's start without ``uic``; :func:`_initial_state` finds coordinate values and inertial velocities
at ``t = 0`` that put them there, as the least-norm solution of the linear
relations of the charge or flux formulation, and names the elements when the
formulation cannot take that state.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
import sympy as sp

from ..base.component import t
from ..derivation.numeric import assemble_numeric
from ..derivation.stamps import NotStampable
from ..errors import ModelError
from ..model import Model
from .deck import _Parsed


def _initial_values(deck: _Parsed) -> dict[str, float]:
    """The initial voltage of every capacitor and current of every inductor (SPICE's uic rule)."""
    out = {}
    for e in deck.elements:
        if e.letter == "c":
            a, b = (deck.node_ic.get(n, 0.0) for n in e.nodes)
            out[e.name] = e.ic if e.ic is not None else a - b
        elif e.letter == "l":
            out[e.name] = e.ic if e.ic is not None else 0.0
    return out


def _operating_point(model: Model, deck: _Parsed) -> dict[str, float]:
    """The DC operating point at ``t = 0``, as SPICE computes it for a ``.tran`` without ``uic``: every capacitor's
    voltage and every inductor's current, by element name.

    Modified nodal analysis with the sources at their values at ``t = 0``:
    capacitors open, inductors shorted (a voltage source of 0 V, whose
    current is the inductor's), nodes named on a ``.ic`` line held at their
    voltages.  A singular system (a node that only capacitors or current
    sources reach, a loop of voltage sources and inductors) raises a
    :class:`~lagrangian.errors.ModelError` naming the nodes or elements.
    """
    elements = [e for e in deck.elements if e.letter in "rlcvi"]
    nodes = sorted({n for e in elements for n in e.nodes if n not in ("0", "gnd")})
    index = {n: i for i, n in enumerate(nodes)}
    branches = [e for e in elements if e.letter in "vl"] + [n for n in deck.node_ic if n in index]
    size = len(nodes) + len(branches)
    A = np.zeros((size, size))
    b = np.zeros(size)
    components = model.components

    def value(e) -> float:
        expr = components[e.name].E if e.letter == "v" else components[e.name].I
        return float(sp.sympify(expr).subs(t, 0))

    def stamp(i, j, x):
        if i is not None and j is not None:
            A[i, j] += x

    for e in elements:
        a, c = (index.get(n) for n in e.nodes)
        if e.letter == "r":
            g = 1.0 / float(e.value)
            for i, j, sign in ((a, a, 1), (c, c, 1), (a, c, -1), (c, a, -1)):
                stamp(i, j, sign * g)
        elif e.letter == "i":  # I drives current from a through the source to c: it leaves a, enters c
            if a is not None:
                b[a] -= value(e)
            if c is not None:
                b[c] += value(e)
    for k, e in enumerate(branches):
        row = len(nodes) + k
        if isinstance(e, str):  # a .ic node held at its voltage
            A[row, index[e]] = A[index[e], row] = 1.0
            b[row] = deck.node_ic[e]
            continue
        a, c = (index.get(n) for n in e.nodes)
        for node, sign in ((a, 1.0), (c, -1.0)):
            if node is not None:
                A[node, row] += sign  # the branch current leaves a, enters c
                A[row, node] += sign  # v_a − v_c = E (0 for an inductor)
        b[row] = value(e) if e.letter == "v" else 0.0
    if size:
        u, sv, vt = np.linalg.svd(A)
        if sv[-1] <= 1e-12 * sv[0]:
            names = nodes + [e if isinstance(e, str) else e.name for e in branches]
            involved = [names[i] for i in np.flatnonzero(np.abs(vt[-1]) > 1e-8)]
            raise ModelError(
                f"netlist {deck.title!r} has no DC operating point (SPICE's starting state without 'uic'): its equations "
                f"are singular in {', '.join(involved)} (a node that only capacitors or current sources reach, or a "
                f"loop of voltage sources and inductors). Add 'uic' to the .tran line to start from the ic= values.")
        x = np.linalg.solve(A, b)
    else:
        x = np.zeros(0)
    voltage = {n: x[i] for n, i in index.items()}
    out = {}
    for e in elements:
        if e.letter == "c":
            out[e.name] = float(voltage.get(e.nodes[0], 0.0) - voltage.get(e.nodes[1], 0.0))
        elif e.letter == "l":
            out[e.name] = float(x[len(nodes) + branches.index(e)])
    return out


def _initial_state(model: Model, ic: Mapping[str, float]) -> tuple[dict[str, float], dict[str, float], dict[str, float]]:
    """Coordinates and inertial velocities at ``t = 0`` that put every capacitor and inductor at ``ic``, and the
    elements the sources move away from theirs (flux formulation: capacitors in a loop with voltage sources;
    charge formulation: inductors in series with current sources), with the value each starts at."""
    numeric = _numeric(model)
    if numeric is not None:
        return _from_rows(model, ic, *numeric)
    view = model.assembly.views["electrical"]
    eq = model.eq
    coords = model.coordinates
    q = [sp.Dummy(f"q{i}") for i in range(len(coords))]
    v = [sp.Dummy(f"v{i}") for i in range(len(coords))]
    to_symbols = {}
    for c, qi, vi in zip(coords, q, v):
        to_symbols[c.function.diff(t)] = vi
        to_symbols[c.function] = qi

    def at_zero(expr: sp.Expr) -> sp.Expr:
        return sp.sympify(expr).xreplace(to_symbols).subs(t, 0)

    initial, v0, moved = _conditions(model, ic, view.formulation, lambda n: at_zero(view.branch[n]),
                                     lambda n: at_zero(view.branch[n].diff(t)), q, v)
    return ({c.name: x for c, x in zip(coords, initial)}, {eq.names[i]: float(v0[i]) + 0.0 for i in eq.inertial},
            moved)


def _numeric(model: Model) -> tuple | None:
    """``(coordinate names, the row of an element's branch quantity by its name, inertial coordinates)`` from the numeric
    assembly (:mod:`lagrangian.derivation.numeric`), or ``None`` where it does not apply (a source fixes a branch,
    a coordinate has neither inertia nor dissipation): then the symbolic view answers."""
    try:
        asm = assemble_numeric(model)
    except NotStampable:
        return None
    inertial = asm.inertial()
    if not np.all(inertial | asm.dissipative()):
        return None
    return asm.names, asm.branch_row, np.flatnonzero(inertial)


def _from_rows(model: Model, ic, names, row, inertial):
    """:func:`_initial_state` from numeric rows: a branch's quantity and its rate are the same row of the
    coordinates and of their rates.  Every element at rest (an AC deck, a run from zero) is the state at rest: its
    conditions are homogeneous, so their least-norm solution is zero and nothing moves."""
    if not any(ic.values()):
        return {n: 0.0 for n in names}, {names[i]: 0.0 for i in inertial}, {}
    unknowns = list(range(len(names)))
    initial, v0, moved = _conditions(model, ic, model.options["formulation"], row, row, unknowns, unknowns)
    return {n: x for n, x in zip(names, initial)}, {names[i]: float(v0[i]) + 0.0 for i in inertial}, moved


def _conditions(model: Model, ic, formulation: str, position, rate, q, v):
    """``(coordinate values, inertial velocities, moved)``: the conditions that put every capacitor and inductor at
    ``ic``, from ``position(name)`` and ``rate(name)`` (a branch quantity and its rate at ``t = 0``: expressions in
    ``q`` and ``v``, or rows over them), solved."""
    components = model.components
    capacitors = [n for n in ic if components[n].kind == "capacitor"]
    inductors = [n for n in ic if components[n].kind == "inductor"]
    if formulation == "charge":
        positions = [(n, position(n), float(components[n].C) * ic[n]) for n in capacitors]
        rates = [(n, rate(n), ic[n]) for n in inductors]
    else:
        positions = []
        for n in inductors:
            flux = sum((float(m) * ic[other] for other, m in _mutuals(model, n)), float(components[n].L) * ic[n])
            positions.append((n, position(n), flux))
        rates = [(n, rate(n), ic[n]) for n in capacitors]
    q0 = _solve(positions, q, model, formulation, "position")
    moved: dict[str, float] = {}
    if formulation == "flux":
        # capacitor voltages that break Kirchhoff's voltage law around a loop of capacitors and voltage sources (a
        # capacitor across a source) cannot be held: the sources move charge through them at t = 0, as a circuit
        # does, and that charge is conserved at every node the sources do not hold.  The voltages that conserve it
        # are those least far from the ones asked in the capacitors' energy norm, Σ C (ΔV)².
        weight = np.diag([math.sqrt(float(components[n].C)) for n in capacitors])
    else:
        # the dual: inductor currents that break Kirchhoff's current law with current sources (an inductor in
        # series with one) jump at t = 0, the flux linkage around every loop the sources do not drive kept: the
        # currents nearest the ones asked in the inductors' energy norm, ΔIᵀ 𝐋 ΔI (𝐋 with the mutual inductances).
        weight = _root(_inductances(model, inductors))
    v0, moved = _jump(rates, v, weight)
    return [float(x) + 0.0 for x in q0], v0, moved


def _inductances(model: Model, inductors: list[str]) -> np.ndarray:
    """The inductance matrix of ``inductors``: L on the diagonal, k√(L₁L₂) between coupled ones."""
    components = model.components
    index = {n: i for i, n in enumerate(inductors)}
    out = np.diag([float(components[n].L) for n in inductors])
    for n in inductors:
        for other, m in _mutuals(model, n):
            if other in index:
                out[index[n], index[other]] = float(m)
    return out


def _root(matrix: np.ndarray) -> np.ndarray:
    """``W`` with ``WᵀW = matrix`` (symmetric, positive semidefinite: a perfect coupling's zero direction kept)."""
    if not matrix.size:
        return matrix
    w, V = np.linalg.eigh(matrix)
    return (V * np.sqrt(np.clip(w, 0.0, None))).T


def _jump(rows: list[tuple[str, sp.Expr, float]], unknowns: list[sp.Symbol], weight: np.ndarray):
    """``(x, moved)``: the rates at ``t = 0`` nearest to the elements' ``rows`` (capacitor voltages, inductor
    currents) in the norm ``|W (A x − b)|`` of the ``weight`` W, and the elements that do not start where asked,
    with the value they start at."""
    A, b = _linear(rows, unknowns)
    x = np.linalg.lstsq(weight @ A, weight @ b, rcond=None)[0] if len(unknowns) and len(rows) else np.zeros(len(unknowns))
    got = A @ x - b
    scale = max(np.abs(b).max(initial=0.0), np.abs(A).max(initial=0.0) * np.abs(x).max(initial=0.0), 1e-300)
    moved = {rows[r][0]: float(rows[r][2] + got[r]) for r in np.flatnonzero(np.abs(got) > 1e-9 * scale)}
    return x, moved


def _linear(rows: list[tuple[str, sp.Expr, float]], unknowns: list[sp.Symbol]) -> tuple[np.ndarray, np.ndarray]:
    """``(A, b)`` of the linear conditions ``expr = value`` in ``unknowns``, one row each."""
    A = np.zeros((len(rows), len(unknowns)))
    b = np.zeros(len(rows))
    for r, (name, expr, value) in enumerate(rows):
        if isinstance(expr, np.ndarray):  # a row over the unknowns already
            A[r], b[r] = expr, value
            continue
        expr = sp.expand(expr)
        for j, u in enumerate(unknowns):
            A[r, j] = float(expr.coeff(u))
        b[r] = value - float(expr.xreplace({u: 0 for u in unknowns}))
    return A, b


def _mutuals(model: Model, inductor: str) -> list[tuple[str, sp.Expr]]:
    """``(other inductor, M)`` for every coupling of ``inductor``."""
    out = []
    components = model.components
    for comp in components.values():
        if comp.kind == "coupling" and inductor in comp.inductor_names:
            a, b = comp.inductor_names
            other = b if a == inductor else a
            out.append((other, comp.k * sp.sqrt(components[a].L * components[b].L)))
    return out


_TROUBLE = {
    ("charge", "position"): (
        "capacitors {names} cannot start at these voltages in the charge formulation: their charges would not "
        "balance at a node where only capacitors (and current sources) meet, and charge is conserved there. "
        "Check their ic= values and the .ic line, or use formulation='flux'."
    ),
    ("flux", "position"): (
        "inductors {names} cannot start at these currents in the flux formulation: their flux linkages would not "
        "add up to zero around a loop of inductors and voltage sources. Check their ic= values, or use "
        "formulation='charge'."
    ),
}


def _solve(
    rows: list[tuple[str, sp.Expr, float]], unknowns: list[sp.Symbol], model: Model, formulation: str, level: str
) -> np.ndarray:
    """Least-norm solution of the linear conditions ``expr = value``; a ModelError naming the elements if there is none."""
    n = len(unknowns)
    if not rows or not n:
        bad = [name for name, expr, value in rows
               if abs(value - (0.0 if isinstance(expr, np.ndarray) else float(expr))) > 0] if rows else []
        if bad:
            raise ModelError(f"model {model.name!r}: " + _TROUBLE[formulation, level].format(names=", ".join(bad)))
        return np.zeros(n)
    A, b = _linear(rows, unknowns)
    x = np.linalg.lstsq(A, b, rcond=None)[0]
    residual = np.abs(A @ x - b)
    scale = np.abs(b).max() + np.abs(A).max() * np.abs(x).max()
    bad = [rows[r][0] for r in np.flatnonzero(residual > 1e-9 * scale)]
    if bad:
        raise ModelError(f"model {model.name!r}: " + _TROUBLE[formulation, level].format(names=", ".join(bad)))
    return x
