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
from typing import TYPE_CHECKING

import numpy as np

from ..base.waveforms import numeric, value_at
from ..base.component import t
from ..derivation.numeric import assemble_numeric
from ..derivation.stamps import NotStampable
from ..errors import ModelError
from ..model import Model
from .deck import _Parsed
from ..base import deferred as _deferred

sp = _deferred.module("sympy", globals())

if TYPE_CHECKING:
    import scipy.sparse as sps

#: Up to this many entries (8 MB), the linear systems here are dense NumPy arrays, solved as they always were, and
#: SciPy is not loaded; a larger one is sparse (:func:`_large`): its size follows the netlist's, not its square.
_DENSE_ENTRIES = 1_000_000


def _large(rows: int, columns: int) -> bool:
    """Whether ``rows`` conditions in ``columns`` unknowns (with a ``rows × rows`` weight) are held sparse."""
    return rows * max(rows, columns) > _DENSE_ENTRIES


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
    :class:`~lagrangian.errors.ModelError` naming the nodes or elements; it is
    found from the circuit's graph (:func:`_no_operating_point`), before the
    system is solved (:func:`_solved`: sparse when large, so its memory follows
    the netlist's size; a dense matrix and its SVD made 4,000 nodes and branches
    take 90 s, and 10⁵ of them would need 80 GB).
    """
    elements = [e for e in deck.elements if e.letter in "rlcvi"]
    nodes = sorted({n for e in elements for n in e.nodes if n not in ("0", "gnd")})
    index = {n: i for i, n in enumerate(nodes)}
    branches = [e for e in elements if e.letter in "vl"] + [n for n in deck.node_ic if n in index]
    _no_operating_point(deck, nodes, elements, [n for n in branches if isinstance(n, str)])
    size = len(nodes) + len(branches)
    rows: list[int] = []
    cols: list[int] = []
    entries: list[float] = []
    b = np.zeros(size)
    components = model.components

    def value(e) -> float:
        raw = components[e.name].params.raw("E" if e.letter == "v" else "I")
        return value_at(raw, 0.0) if numeric(raw) else float(sp.sympify(raw).subs(t, 0))

    def stamp(i, j, x):
        if i is not None and j is not None:
            rows.append(i)
            cols.append(j)
            entries.append(x)

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
    row_of: dict[str, int] = {}
    for k, e in enumerate(branches):
        row = len(nodes) + k
        if isinstance(e, str):  # a .ic node held at its voltage
            stamp(row, index[e], 1.0)
            stamp(index[e], row, 1.0)
            b[row] = deck.node_ic[e]
            continue
        row_of[e.name] = row
        a, c = (index.get(n) for n in e.nodes)
        for node, sign in ((a, 1.0), (c, -1.0)):
            stamp(node, row, sign)  # the branch current leaves a, enters c
            stamp(row, node, sign)  # v_a − v_c = E (0 for an inductor)
        b[row] = value(e) if e.letter == "v" else 0.0
    if size and not b.any() and all(float(e.value) > 0 for e in elements if e.letter == "r"):
        x = np.zeros(size)  # no source at t = 0 (a sine from zero): positive conductances on a graph that passed
        # _no_operating_point make the system regular, so its solution is zero, with no solve (602 unknowns: 22 ms)
    elif size:
        x = _solved(rows, cols, entries, b)
        if not np.all(np.isfinite(x)):
            raise ModelError(
                f"netlist {deck.title!r} has no DC operating point (SPICE's starting state without 'uic'): its equations "
                f"are singular or beyond a float's range for these element values. Add 'uic' to the .tran line to start "
                f"from the ic= values.")
    else:
        x = np.zeros(0)
    voltage = {n: x[i] for n, i in index.items()}
    out = {}
    for e in elements:
        if e.letter == "c":
            out[e.name] = float(voltage.get(e.nodes[0], 0.0) - voltage.get(e.nodes[1], 0.0))
        elif e.letter == "l":
            out[e.name] = float(x[row_of[e.name]])
    return out


def _solved(rows: list[int], cols: list[int], entries: list[float], b: np.ndarray) -> np.ndarray:
    """The solution of the square system with entries ``entries`` at ``(rows, cols)`` (repeated ones summed) and
    right side ``b``: dense when small, a sparse LU factorization when large; NaN where it is singular."""
    size = len(b)
    if not _large(size, size):
        A = np.zeros((size, size))
        np.add.at(A, (rows, cols), entries)
        try:
            return np.linalg.solve(A, b)
        except np.linalg.LinAlgError:
            return np.full(size, np.nan)
    import scipy.sparse as sps  # imported by what uses it: the package, and small decks, load no SciPy
    import scipy.sparse.linalg as spla

    try:
        return spla.splu(sps.csc_matrix((entries, (rows, cols)), shape=(size, size))).solve(b)
    except RuntimeError:  # exactly singular
        return np.full(size, np.nan)


def _no_operating_point(deck: _Parsed, nodes: list[str], elements: list, held: list[str]) -> None:
    """Refuse, naming them, what makes the operating point's equations singular, from the circuit's graph (its
    conductances are positive, so nothing else can): a loop of voltage sources, inductors and ``.ic``-held nodes
    (each a source to ground), or nodes that no path of resistors, voltage sources, inductors and held nodes joins
    to the ground.  Linear in the netlist's size (union-find)."""
    parent: dict[str, str] = {}

    def root(n: str) -> str:
        n = "0" if n == "gnd" else n
        parent.setdefault(n, n)
        while parent[n] != n:
            parent[n] = parent[parent[n]]
            n = parent[n]
        return n

    def refuse_singular(involved: list[str], why: str) -> None:
        shown = ", ".join(involved[:20]) + (f", ... ({len(involved)} in all)" if len(involved) > 20 else "")
        raise ModelError(
            f"netlist {deck.title!r} has no DC operating point (SPICE's starting state without 'uic'): its equations "
            f"are singular in {shown} ({why}). Add 'uic' to the .tran line to start from the ic= values.")

    # the voltage-defined branches first: a spanning forest of them, and the first one that closes a loop
    forest: dict[str, list[tuple[str, str]]] = {}
    fixed = [(e.name, *e.nodes) for e in elements if e.letter in "vl"] + [(f".ic v({n})", n, "0") for n in held]
    for name, a, c in fixed:
        a, c = ("0" if n == "gnd" else n for n in (a, c))
        if root(a) == root(c):
            refuse_singular([name, *_path(forest, a, c)], "a loop of voltage sources and inductors")
        parent[root(a)] = root(c)
        forest.setdefault(a, []).append((c, name))
        forest.setdefault(c, []).append((a, name))
    for e in elements:
        if e.letter == "r":
            a, c = e.nodes
            parent[root(a)] = root(c)
    ground = root("0")
    floating = [n for n in nodes if root(n) != ground]
    if floating:
        refuse_singular(floating, "a node that only capacitors or current sources reach")


def _path(forest: dict[str, list[tuple[str, str]]], start: str, goal: str) -> list[str]:
    """The names of the edges on the path from ``start`` to ``goal`` in ``forest`` (which joins them)."""
    came: dict[str, tuple[str, str] | None] = {start: None}
    queue = [start]
    for node in queue:
        if node == goal:
            break
        for other, name in forest.get(node, ()):
            if other not in came:
                came[other] = (node, name)
                queue.append(other)
    out = []
    node = goal
    while came.get(node) is not None:
        node, name = came[node]
        out.append(name)
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
    a coordinate has neither inertia nor dissipation): then the symbolic view answers.  A row is sparse,
    ``{coordinate index: coefficient}``: the conditions on 10⁴ elements over 10⁴ coordinates are not a dense
    10⁴ × 10⁴ matrix."""
    try:
        asm = assemble_numeric(model)
    except NotStampable:
        return None
    inertial = asm.inertial()
    if not np.all(inertial | asm.dissipative()):
        return None
    return asm.names, asm.branch.__getitem__, np.flatnonzero(inertial)


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
    mutuals = _mutuals(model)
    if formulation == "charge":
        positions = [(n, position(n), float(components[n].C) * ic[n]) for n in capacitors]
        rates = [(n, rate(n), ic[n]) for n in inductors]
    else:
        positions = []
        for n in inductors:
            flux = sum((float(m) * ic[other] for other, m in mutuals.get(n, ())), float(components[n].L) * ic[n])
            positions.append((n, position(n), flux))
        rates = [(n, rate(n), ic[n]) for n in capacitors]
    q0 = _solve(positions, q, model, formulation, "position")
    moved: dict[str, float] = {}
    if formulation == "flux":
        # capacitor voltages that break Kirchhoff's voltage law around a loop of capacitors and voltage sources (a
        # capacitor across a source) cannot be held: the sources move charge through them at t = 0, as a circuit
        # does, and that charge is conserved at every node the sources do not hold.  The voltages that conserve it
        # are those least far from the ones asked in the capacitors' energy norm, Σ C (ΔV)².  (W is diagonal, and
        # sparse when large: 10⁵ capacitors in parallel made it a dense 10⁵ × 10⁵ matrix, 80 GB.)
        n = len(capacitors)
        weight = _matrix(list(range(n)), list(range(n)), [math.sqrt(float(components[c].C)) for c in capacitors],
                         (n, n), _large(n, len(v)))
    else:
        # the dual: inductor currents that break Kirchhoff's current law with current sources (an inductor in
        # series with one) jump at t = 0, the flux linkage around every loop the sources do not drive kept: the
        # currents nearest the ones asked in the inductors' energy norm, ΔIᵀ 𝐋 ΔI (𝐋 with the mutual inductances).
        weight = _inductance_root(model, inductors, mutuals, _large(len(inductors), len(v)))
    v0, moved = _jump(rates, v, weight)
    return [float(x) + 0.0 for x in q0], v0, moved


def _inductance_root(model: Model, inductors: list[str], mutuals: Mapping[str, list], sparse: bool):
    """``W`` with ``WᵀW = 𝐋``, the inductance matrix of ``inductors`` (L on the diagonal, k√(L₁L₂) between coupled
    ones), found block by block: √L for an inductor without couplings, the root of its small matrix
    (:func:`_root`) for each group of coupled ones — not the eigendecomposition of the whole n × n matrix; a SciPy
    sparse matrix if ``sparse``, else a NumPy array."""
    components = model.components
    index = {n: i for i, n in enumerate(inductors)}
    parent = list(range(len(inductors)))

    def root_of(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for n in inductors:
        for other, _ in mutuals.get(n, ()):
            if other in index:
                parent[root_of(index[n])] = root_of(index[other])
    groups: dict[int, list[int]] = {}
    for i in range(len(inductors)):
        groups.setdefault(root_of(i), []).append(i)
    rows: list[int] = []
    cols: list[int] = []
    values: list[float] = []
    for members in groups.values():
        if len(members) == 1:
            i = members[0]
            rows.append(i)
            cols.append(i)
            values.append(math.sqrt(max(float(components[inductors[i]].L), 0.0)))
            continue
        local = {inductors[i]: a for a, i in enumerate(members)}
        block = np.diag([float(components[inductors[i]].L) for i in members])
        for name, a in local.items():
            for other, m in mutuals.get(name, ()):
                if other in local:
                    block[a, local[other]] = float(m)
        root = _root(block)
        for a, i in enumerate(members):
            for b, j in enumerate(members):
                rows.append(i)
                cols.append(j)
                values.append(root[a, b])
    return _matrix(rows, cols, values, (len(inductors), len(inductors)), sparse)


def _matrix(rows: list[int], cols: list[int], values: list[float], shape: tuple[int, int], sparse: bool):
    """The matrix of ``shape`` with ``values`` at ``(rows, cols)``: SciPy CSR if ``sparse``, else a NumPy array."""
    if sparse:
        import scipy.sparse as sps  # imported by what uses it

        return sps.csr_matrix((values, (rows, cols)), shape=shape)
    out = np.zeros(shape)
    out[rows, cols] = values
    return out


def _root(matrix: np.ndarray) -> np.ndarray:
    """``W`` with ``WᵀW = matrix`` (symmetric, positive semidefinite: a perfect coupling's zero direction kept)."""
    if not matrix.size:
        return matrix
    w, V = np.linalg.eigh(matrix)
    return (V * np.sqrt(np.clip(w, 0.0, None))).T


def _jump(rows: list[tuple[str, sp.Expr, float]], unknowns: list[sp.Symbol], weight: np.ndarray | sps.spmatrix):
    """``(x, moved)``: the rates at ``t = 0`` nearest to the elements' ``rows`` (capacitor voltages, inductor
    currents) in the norm ``|W (A x − b)|`` of the ``weight`` W (dense or sparse), and the elements that do not
    start where asked, with the value they start at."""
    A, b = _linear(rows, unknowns)
    x = _lstsq(weight @ A, weight @ b) if len(unknowns) and len(rows) else np.zeros(len(unknowns))
    got = A @ x - b
    scale = max(np.abs(b).max(initial=0.0), _largest(A) * np.abs(x).max(initial=0.0), 1e-300)
    moved = {rows[r][0]: float(rows[r][2] + got[r]) for r in np.flatnonzero(np.abs(got) > 1e-9 * scale)}
    return x, moved


def _linear(rows: list[tuple[str, sp.Expr, float]], unknowns: list[sp.Symbol]) -> tuple[np.ndarray, np.ndarray]:
    """``(A, b)`` of the linear conditions ``expr = value`` in ``unknowns``, one row each: from numeric rows
    (``{unknown index: coefficient}``) a sparse ``A`` when large (:func:`_large`), otherwise, and from expressions
    (the symbolic path, of small models), a dense one."""
    b = np.zeros(len(rows))
    if rows and all(isinstance(expr, dict) for _, expr, _ in rows) and _large(len(rows), len(unknowns)):
        r, c, v = [], [], []
        for k, (_, expr, value) in enumerate(rows):
            r += [k] * len(expr)
            c += list(expr)
            v += list(expr.values())
            b[k] = value
        return _matrix(r, c, v, (len(rows), len(unknowns)), True), b
    A = np.zeros((len(rows), len(unknowns)))
    for r, (name, expr, value) in enumerate(rows):
        if isinstance(expr, dict):  # a row over the unknowns already
            A[r, list(expr)], b[r] = list(expr.values()), value
            continue
        expr = sp.expand(expr)
        for j, u in enumerate(unknowns):
            A[r, j] = float(expr.coeff(u))
        b[r] = value - float(expr.xreplace({u: 0 for u in unknowns}))
    return A, b


def _lstsq(A, b: np.ndarray) -> np.ndarray:
    """The least-squares solution of least norm of ``A x = b`` (``numpy.linalg.lstsq``'s), for a sparse ``A`` block
    by block: the unknowns and rows that no entry joins are independent problems (each pair of coupled coils, each
    capacitor's node), solved dense one at a time, so the work follows the blocks' sizes and not the product of the
    numbers of rows and unknowns.  Unknowns in no row stay zero (least norm).  A dense ``A`` is solved whole."""
    if isinstance(A, np.ndarray):
        return np.linalg.lstsq(A, b, rcond=None)[0]
    import scipy.sparse as sps  # imported by what uses it
    from scipy.sparse.csgraph import connected_components

    A = sps.csr_matrix(A)
    A.eliminate_zeros()
    m, n = A.shape
    x = np.zeros(n)
    if not A.nnz:
        return x
    pattern = sps.csr_matrix((np.ones(A.nnz), A.indices, A.indptr), shape=(m, n))
    count, label = connected_components(sps.bmat([[None, pattern], [pattern.T, None]], format="csr"), directed=False)
    rows_of, cols_of = _members(label[:m], count), _members(label[m:], count)
    A = A.tocsc()
    for block in range(count):
        cols = cols_of[block]
        if not len(cols):
            continue  # a row with no unknown (nothing to choose; its residual is reported by the caller)
        rows = rows_of[block]
        sub = A[:, cols][rows, :].toarray()
        x[cols] = np.linalg.lstsq(sub, b[rows], rcond=None)[0]
    return x


def _members(label: np.ndarray, count: int) -> list[np.ndarray]:
    """The indices of each label ``0 .. count − 1``, in order."""
    order = np.argsort(label, kind="stable")
    return np.split(order, np.searchsorted(label[order], np.arange(1, count)))


def _largest(A) -> float:
    """The largest magnitude of an entry of ``A`` (sparse or dense; 0 when it has none)."""
    if not isinstance(A, np.ndarray):  # a SciPy sparse matrix
        return float(abs(A).max()) if A.nnz else 0.0
    return float(np.abs(A).max(initial=0.0))


def _mutuals(model: Model) -> dict[str, list[tuple[str, sp.Expr]]]:
    """``(other inductor, M)`` for every coupling of each coupled inductor, by its name: one pass over the model (not
    one per inductor, which made 10⁴ inductors 10⁸ steps)."""
    out: dict[str, list[tuple[str, sp.Expr]]] = {}
    components = model.components
    for comp in components.values():
        if comp.kind == "coupling":
            a, b = comp.inductor_names
            m = comp.k * sp.sqrt(components[a].L * components[b].L)
            out.setdefault(a, []).append((b, m))
            out.setdefault(b, []).append((a, m))
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
               if abs(value - (0.0 if isinstance(expr, dict) else float(expr))) > 0] if rows else []
        if bad:
            raise ModelError(f"model {model.name!r}: " + _TROUBLE[formulation, level].format(names=", ".join(bad)))
        return np.zeros(n)
    A, b = _linear(rows, unknowns)
    x = _lstsq(A, b)
    residual = np.abs(A @ x - b)
    scale = np.abs(b).max() + _largest(A) * np.abs(x).max()
    bad = [rows[r][0] for r in np.flatnonzero(residual > 1e-9 * scale)]
    if bad:
        raise ModelError(f"model {model.name!r}: " + _TROUBLE[formulation, level].format(names=", ".join(bad)))
    return x
