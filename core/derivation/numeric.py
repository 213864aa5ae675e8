"""Linear time-invariant models assembled in numbers from the components' own numeric description.

Where :mod:`lagrangian.derivation.stamps` differentiates each component's
symbolic energy, this module reads what components and domains say in
numbers (:mod:`lagrangian.base.linear`, :meth:`lagrangian.Domain.incidence`)
and builds no expression at all: a branch quantity is a row of coefficients
over the coordinates, each component's ``T``, ``V``, ``D`` and ``G`` are
scattered through the rows of its branches, and each source's force is one
more row.  With ``e_i`` the row of variable ``x_i``,

    M += Σ T_ij e_i e_jᵀ,   K += Σ V_ij e_i e_jᵀ,   C += Σ D_ij e_i e_jᵀ + Σ G_ij (e_j e_iᵀ − e_i e_jᵀ),

and a source's signal ``s`` adds ``s · Σ f_i e_i`` to the right-hand side
(``L ∋ G_ij x_i ẋ_j`` gives ``G_ij (ẋ_i e_j − ẋ_j e_i)`` on the left).
Measured on a 100-section RLC ladder (301 components): 6.3 ms, where the
symbolic assembly and the stamps took 114 ms.

Anything not said in numbers — a component or domain without a numeric
description, a branch a source fixes, a parameter without a value — raises
:class:`~lagrangian.derivation.stamps.NotStampable`, and callers take the
symbolic path, whose messages name the fault.

>>> import lagrangian as lg
>>> from lagrangian.derivation.numeric import assemble_numeric
>>> m = lg.Model("rlc")
>>> _ = m.add("voltage_source", "V1", ("in", "0"), E=0)
>>> _ = m.add("resistor", "R1", ("in", "a"), R=10.0)
>>> _ = m.add("inductor", "L1", ("a", "b"), L=7e-3)
>>> _ = m.add("capacitor", "C1", ("b", "0"), C=2.2e-6)
>>> asm = assemble_numeric(m)
>>> asm.names, asm.M, asm.C, asm.forces["V1"]     # L q̈ + R q̇ + q/C = E
(['q_L1'], array([[0.007]]), array([[10.]]), array([1.]))
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..base.component import GROUND, Component, _CallableSignal
from ..base.component import t as _t
from ..base.domain import Network
from ..base.linear import Linear, LinearContext, Potential, Quantity
from ..base.network import check_topology
from ..base.waveforms import numeric
from .stamps import NotStampable, Quadratic, Stamps
from ..base import deferred as _deferred

sp = _deferred.module("sympy", globals())

__all__ = ["NumericAssembly", "NumericStamps", "assemble_local", "assemble_numeric", "local_stamps", "numeric_branches", "numeric_stamps"]


@dataclass
class NumericAssembly:
    """A linear time-invariant model in numbers: ``M q̈ + C q̇ + K q = Σ_c forces[c] · s_c(t)``.

    ``names``: the coordinates; ``entries``: ``M``, ``C``, ``K`` and ``Cd``
    (the share of ``C`` from dissipation alone, for the dissipation
    function's values) as ``(rows, columns, values)``, each entry summed
    once (:meth:`dense` and :meth:`sparse` give the matrices: a chain of
    10,000 masses is never held dense); ``forces``: by component name, the
    column its signal ``s_c`` multiplies; ``linears``: each component's
    :class:`~lagrangian.base.linear.Linear`; ``rows``: each variable of each
    component (by name) as ``{coordinate index: coefficient}``, for its
    quantities; ``branch``: every branch quantity by edge key, likewise;
    ``potentials``: the nonlinear energies of the components that give one
    (:class:`~lagrangian.base.linear.Potential`), by name: only
    :func:`assemble_local` keeps a model that has any.  ``loads``: the
    constant generalized forces (gravity along the axis, springs' rest
    lengths), which the stamps take as an input of shape ``1``.
    """

    names: list[str]
    entries: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]
    forces: dict[str, np.ndarray] = field(default_factory=dict)
    linears: dict[str, Linear] = field(default_factory=dict)
    rows: dict[str, list[dict[int, float]]] = field(default_factory=dict)
    branch: dict[str, dict[int, float]] = field(default_factory=dict)
    potentials: dict[str, Potential] = field(default_factory=dict)
    #: the constant generalized forces (``Linear.load`` of every component, by coordinate), and ``V``'s constant
    loads: np.ndarray | None = None
    constant: float = 0.0

    def dense(self, which: str) -> np.ndarray:
        """Matrix ``which`` (``"M"``, ``"C"``, ``"K"``, ``"Cd"``) as a read-only array, made on first use."""
        key = f"_dense_{which}"
        if key not in self.__dict__:
            n = len(self.names)
            out = np.zeros((n, n))
            r, c, v = self.entries[which]
            out[r, c] = v
            out.setflags(write=False)
            self.__dict__[key] = out
        return self.__dict__[key]

    def sparse(self, which: str):
        """Matrix ``which`` as a SciPy CSR matrix."""
        import scipy.sparse as sps  # imported by what uses it, as the stamps do

        n = len(self.names)
        r, c, v = self.entries[which]
        return sps.csr_matrix((v, (r, c)), shape=(n, n))

    @property
    def M(self) -> np.ndarray:
        return self.dense("M")

    @property
    def C(self) -> np.ndarray:
        return self.dense("C")

    @property
    def K(self) -> np.ndarray:
        return self.dense("K")

    def inertial(self) -> np.ndarray:
        """Whether each coordinate has inertia (a nonzero row of ``M``)."""
        return self._touched("M", 0)

    def dissipative(self) -> np.ndarray:
        """Whether each coordinate's rate enters the equations through ``C`` (a nonzero column)."""
        return self._touched("C", 1)

    def _touched(self, which: str, axis: int) -> np.ndarray:
        out = np.zeros(len(self.names), dtype=bool)
        out[self.entries[which][axis]] = True
        return out

    def branch_row(self, key: str) -> np.ndarray:
        """Branch ``key``'s quantity as a dense row over the coordinates."""
        return _dense(self.branch[key], len(self.names))

    def quantity(self, component: Component, name: str) -> tuple[list[np.ndarray], float] | None:
        """Component quantity ``name`` as rows by derivative order (``Σ_o rows[o] · dᵒq/dtᵒ``) and the coefficient
        of the component's signal; ``None`` when the component does not give it in numbers."""
        q: Quantity | None = self.linears[component.name].quantities.get(name)
        if q is None:
            return None
        n = len(self.names)
        out = [np.zeros(n) for _ in range(1 + max((o for _, o, _ in q.terms), default=0))]
        for k, order, c in q.terms:
            for j, cj in self.rows[component.name][k].items():
                out[order][j] += c * cj
        return out, q.signal


def assemble_numeric(model: Any) -> NumericAssembly:
    """The :class:`lagrangian.Model` ``model`` in numbers (see the module documentation), or
    :class:`NotStampable` saying why not (a component with a nonlinear potential among them: see
    :func:`assemble_local`).

    The topology is checked as the symbolic assembly checks it (the same
    errors); coordinates come in the order of the symbolic assembly's.  The
    result (or the refusal) is kept with the model until it changes, its
    arrays read-only: a netlist's initial state, a linearization and an
    analogy's check share one assembly.
    """
    asm = assemble_local(model)
    if asm.potentials:
        name = next(iter(asm.potentials))
        raise NotStampable(f"{model._graph.components[name].kind} {name!r} is nonlinear (its energy is a potential "
                           f"of its variables, not a quadratic form)")
    return asm


def assemble_local(model: Any) -> NumericAssembly:
    """:func:`assemble_numeric`, also for a model whose components give nonlinear energies as
    :class:`~lagrangian.base.linear.Potential` (in :attr:`NumericAssembly.potentials`): what the runs of
    :mod:`lagrangian.numerics.assembled` read.  Kept with the model.

    >>> import lagrangian as lg
    >>> from lagrangian import models
    >>> chain = models.spring_chain(2, m=0.3, k=40.0, beta=2e4)
    >>> asm = assemble_local(chain)
    >>> sorted(asm.potentials), asm.potentials["k1"].values, asm.rows["k1"]      # k, ℓ₀, β; x_p0 − x_p1
    (['k0', 'k1'], (40.0, 0.0, 20000.0), [{0: 1.0, 1: -1.0}])
    """
    return _kept(model, "numeric", _assemble)


def _kept(model: Any, key: str, build) -> Any:
    """``build(model)``, kept with the model under ``key`` until it changes; a refusal (:class:`NotStampable`) is
    kept too, and raised again."""
    got = model._cache.get(key)
    if got is None:
        try:
            got = build(model)
        except NotStampable as exc:
            got = exc
        model._cache[key] = got
    if isinstance(got, NotStampable):
        raise NotStampable(*got.args)
    return got


def numeric_branches(model: Any) -> tuple[list[str], dict[str, dict[int, float]]]:
    """``(coordinate names, every branch quantity by edge key as {coordinate index: coefficient})`` of ``model``
    from its domains' incidences alone (no component's numbers are read: what :func:`assemble_numeric` starts
    from, and all a map between two models' branches needs), or :class:`NotStampable`.  Kept with the model."""
    return _kept(model, "numeric_branches", _branches)


def _branches(model: Any) -> tuple[list[str], dict[str, dict[int, float]]]:
    model._check_node_names()  # the symbolic assembly's warnings, said here too
    graph, registry, options = model._graph, model.registry, model.options
    components = list(graph.components.values())
    if not components:
        raise NotStampable("the model has no components")
    graph.node_domains()
    domains = list(dict.fromkeys(d for c in components for d in c.domains))
    light = all(getattr(registry.domains.get(d), "light_incidence", False) for d in domains)  # no networkx
    whole = graph.graph(light=light)
    roles = {k: d["component"].role for _, _, k, d in whole.edges(keys=True, data=True)}
    check_topology(whole, GROUND, roles.get)
    names: list[str] = []
    branch: dict[str, dict[int, float]] = {}
    for dname in domains:
        domain = registry.domains.get(dname)
        if domain is None:
            raise NotStampable(f"no domain {dname!r}")
        members = [c for c in components if dname in c.domains]
        opts = {name: options.get(name, opt.default) for name, opt in domain.options.items()}
        network = whole if len(domains) == 1 else graph.graph(members, domain=dname, light=light)  # one: the whole
        inc = domain.incidence(Network(network, members), opts)
        if inc is None:
            raise NotStampable(f"the {dname} domain gives no incidence in numbers")
        if inc.prescribed:
            raise NotStampable(f"sources fix the branches {', '.join(sorted(inc.prescribed)[:3])}")
        offset = len(names)
        names.extend(inc.coordinates)
        for key, row in inc.branch.items():
            branch[key] = {offset + i: c for i, c in row.items()}
    n = len(names)
    if not n or len(set(names)) != n:
        raise NotStampable("no coordinates, or one named twice")
    return names, branch


def _assemble(model: Any) -> NumericAssembly:
    names, branch = numeric_branches(model)
    graph, options = model._graph, model.options
    components = list(graph.components.values())
    n = len(names)
    ctx = LinearContext(options, graph.components)
    M, C, K, Cd = ([], [], []), ([], [], []), ([], [], []), ([], [], [])
    out = NumericAssembly(list(names), {}, branch=branch)
    for comp in components:
        lin = comp.linear(ctx)
        if lin is None:
            raise NotStampable(f"{comp.kind} {comp.name!r} gives no linear contribution in numbers")
        refs = lin.branches if lin.branches is not None else [(comp.name, i) for i in range(len(comp.branches()))]
        sparse = []
        for cname, i in refs:
            row = branch.get(cname if i == 0 else f"{cname}#{i}")
            if row is None:
                raise NotStampable(f"{comp.kind} {comp.name!r} names branch {i} of {cname!r}, which is no branch")
            sparse.append(row)
        for part, target in ((lin.T, M), (lin.V, K), (lin.D, C), (lin.D, Cd)):
            for (i, j), c in part.items():
                _scatter(target, sparse[i], sparse[j], c)
        for (i, j), g in lin.G.items():
            _scatter(C, sparse[j], sparse[i], g)
            _scatter(C, sparse[i], sparse[j], -g)
        if lin.force:
            force = np.zeros(n)
            for i, f in lin.force.items():
                for j, c in sparse[i].items():
                    force[j] += f * c
            out.forces[comp.name] = force
        if lin.load:
            loads = out.loads if out.loads is not None else np.zeros(n)
            for i, f in lin.load.items():
                for j, c in sparse[i].items():
                    loads[j] += f * c
            out.loads = loads
        out.constant += float(lin.constant)
        if lin.potential is not None:
            _check_potential(comp, lin.potential, len(sparse))
            out.potentials[comp.name] = lin.potential
        out.linears[comp.name] = lin
        out.rows[comp.name] = sparse
    out.entries = {which: _summed(*triplets, n) for which, triplets in (("M", M), ("C", C), ("K", K), ("Cd", Cd))}
    for array in [*out.forces.values(), *([] if out.loads is None else [out.loads])]:
        array.setflags(write=False)
    return out



def _check_potential(comp: Component, potential: Any, variables: int) -> None:
    """Refuse a potential that is not an expression in the placeholders of ``variables`` variables and as many
    parameters as it gives values, each a finite number (a plugin's fault, named)."""
    where = f"{comp.kind} {comp.name!r}"
    if not isinstance(potential, Potential) or not isinstance(potential.energy, sp.Expr):
        raise NotStampable(f"{where}: its potential is not a lagrangian.Potential of a SymPy expression")
    values = potential.values
    if not isinstance(values, tuple) or not all(isinstance(v, float) and np.isfinite(v) for v in values):
        raise NotStampable(f"{where}: its potential's values are not a tuple of finite floats")
    x, p = Potential.placeholders(variables, len(values))
    stray = potential.energy.free_symbols - set(x) - set(p)
    if stray:
        raise NotStampable(f"{where}: its potential holds {', '.join(sorted(map(str, stray)))[:80]}, which is no "
                           f"placeholder of its {variables} variable(s) and {len(values)} value(s)")


def _scatter(target: tuple[list, list, list], a: dict[int, float], b: dict[int, float], c: float) -> None:
    """Entries of ``c · a bᵀ`` for sparse rows ``a``, ``b`` (a branch crosses few loops), added to the triplets
    ``target``."""
    rows, cols, vals = target
    for i, ca in a.items():
        for j, cb in b.items():
            rows.append(i)
            cols.append(j)
            vals.append(c * ca * cb)


#: An entry that sums to less than this many ε of the sum of its addends' sizes is round-off, zero (as the stamps
#: decide: a mutual term and its opposite cancel to nothing, not to 1e-19).
_ROUNDOFF = 64 * np.finfo(float).eps


def _summed(rows: list, cols: list, vals: list, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The triplets summed per entry, round-off residuals dropped, as ``(rows, columns, values)``."""
    if len(vals) <= 256:  # a small model: a dictionary costs less than NumPy's sorting
        sums: dict[tuple[int, int], float] = {}
        sizes: dict[tuple[int, int], float] = {}
        for i, j, value in zip(rows, cols, vals):
            sums[i, j] = sums.get((i, j), 0.0) + value
            sizes[i, j] = sizes.get((i, j), 0.0) + abs(value)
        kept = [(i, j, x) for (i, j), x in sums.items() if abs(x) > _ROUNDOFF * sizes[i, j]]
        return (np.array([e[0] for e in kept], dtype=np.intp), np.array([e[1] for e in kept], dtype=np.intp),
                np.array([e[2] for e in kept], dtype=float))
    key = np.asarray(rows, dtype=np.int64) * n + np.asarray(cols, dtype=np.int64)
    vals = np.asarray(vals, dtype=float)
    order = np.argsort(key, kind="stable")
    key, vals = key[order], vals[order]
    first = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    sums = np.add.reduceat(vals, first)
    sizes = np.add.reduceat(np.abs(vals), first)
    keep = np.abs(sums) > _ROUNDOFF * sizes
    key = key[first][keep]
    return (key // n).astype(np.intp), (key % n).astype(np.intp), sums[keep]


def _dense(row: dict[int, float], n: int) -> np.ndarray:
    out = np.zeros(n)
    for j, c in row.items():
        out[j] = c
    return out


def numeric_stamps(model: Any) -> Stamps:
    """The :class:`~lagrangian.derivation.stamps.Stamps` of ``model`` (what the exact time-domain solution reads)
    from its numeric assembly: ``M``, ``C``, ``K``; each source's signal split, as the stamps split it, into
    distinct shapes of ``t`` and their coefficients (``B``); the energies' quadratic forms.  Kept with the model;
    :class:`NotStampable` where the numeric assembly does not apply or a signal is a Python callable.

    >>> import sympy as sp, lagrangian as lg
    >>> m = lg.Model("rc")
    >>> _ = m.add("voltage_source", "V1", ("in", "0"), E=2 * sp.sin(3 * lg.t) + 1)
    >>> _ = m.add("resistor", "R1", ("in", "out"), R=1e3)
    >>> _ = m.add("capacitor", "C1", ("out", "0"), C=2.2e-6)
    >>> st = numeric_stamps(m)
    >>> st.inputs, st.B.toarray()        # R q̇ + q/C = 1 + 2 sin 3t
    ([1, sin(3*t)], array([[1., 2.]]))
    """
    return _kept(model, "numeric_stamps", lambda m: _stamps(m, assemble_numeric(m)))


def local_stamps(model: Any) -> Stamps:
    """:func:`numeric_stamps` of :func:`assemble_local`: ``M``, ``C``, ``K``, ``B`` and the quadratic energies of a
    model that may hold potentials besides (which the stamps leave out).  Kept with the model."""
    return _kept(model, "local_stamps", lambda m: _stamps(m, assemble_local(m)))


def _stamps(model: Any, asm: NumericAssembly) -> Stamps:
    n = len(asm.names)
    columns: dict[Any, int] = {}  # input shape → column: 1 (a constant), a waveform, an expression of t
    entries: list[tuple[int, np.ndarray]] = []
    for cname, force in asm.forces.items():
        comp = model._graph.components[cname]
        signals = [p for p, spec in comp.parameters.items() if spec.shape == "signal"]
        raw = comp.params.raw(signals[0]) if len(signals) == 1 else None
        if numeric(raw):  # held as given: read without SymPy
            if raw != 0 and force.any():
                shape, coeff = (1, float(raw)) if type(raw) in (int, float) else (raw, 1.0)
                entries.append((columns.setdefault(shape, len(columns)), coeff * force))
            continue
        value = comp.params.get(signals[0]) if len(signals) == 1 else None
        if value is None or isinstance(value, _CallableSignal) or not isinstance(value, (sp.Expr, int, float)):
            raise NotStampable(f"{comp.kind} {cname!r}: its signal is not an expression of t")
        for term in sp.Add.make_args(sp.sympify(value, strict=True)):
            coeff, shape = term.as_coeff_Mul()
            if coeff == 0 or not force.any():
                continue
            if shape.free_symbols - {_t}:
                raise NotStampable(f"{comp.kind} {cname!r}: its signal holds symbols other than t")
            entries.append((columns.setdefault(shape, len(columns)), float(coeff) * force))
    loaded = [] if asm.loads is None else [int(i) for i in np.flatnonzero(asm.loads)]
    if loaded:  # constant loads: an input of shape 1, as a DC source's
        entries.append((columns.setdefault(1, len(columns)), np.array(asm.loads)))
    B = np.zeros((n, len(columns)))
    for col, values in entries:
        B[:, col] += values
    # over z = (q, q̇): T = ½ q̇ᵀ M q̇, V = ½ qᵀ K q, D = ½ q̇ᵀ Cd q̇
    forms = {"T": Quadratic(_Placed(asm, "M", n)),
             "V": Quadratic(_Placed(asm, "K", 0), [(i, float(-asm.loads[i])) for i in loaded], float(asm.constant)),
             "D": Quadratic(_Placed(asm, "Cd", n))}
    inertial = [int(i) for i in np.flatnonzero(asm.inertial())]
    first = [int(i) for i in np.flatnonzero(~asm.inertial())]
    if not np.all(asm.inertial() | asm.dissipative()):
        raise NotStampable("a coordinate without inertia or dissipation")
    B.setflags(write=False)
    return NumericStamps(asm, B, list(columns), forms, inertial, first,
                         [int(np.flatnonzero(B[:, c])[0]) if B[:, c].any() else 0 for c in range(B.shape[1])])


class NumericStamps(Stamps):
    """The :class:`~lagrangian.derivation.stamps.Stamps` of a numeric assembly: ``M``, ``C``, ``K`` and ``B`` as
    SciPy CSR matrices made when first read (SciPy imported then), and as dense arrays by :meth:`dense`, which
    the dense exact solution reads: a model solved in numbers up to its dense size imports no ``scipy.sparse``
    (0.1 s of CPU, as much as NumPy)."""

    def __init__(self, asm: NumericAssembly, B: np.ndarray, inputs: list, energies: dict, inertial: list[int],
                 first_order: list[int], input_rows: list[int]):
        self.names, self.inputs, self.energies = list(asm.names), inputs, energies
        self.inertial, self.first_order, self.input_rows = inertial, first_order, input_rows
        self._asm, self._B, self._made = asm, B, {}

    def dense(self, which: str) -> np.ndarray:
        """Matrix ``which`` (``"M"``, ``"C"``, ``"K"``, ``"B"``) as a dense read-only array."""
        return self._B if which == "B" else self._asm.dense(which)

    def _csr(self, which: str):
        made = self._made.get(which)
        if made is None:
            import scipy.sparse as sps  # imported by what uses it, as the stamps do

            made = self._made[which] = sps.csr_matrix(self._B) if which == "B" else self._asm.sparse(which)
        return made

    M = property(lambda self: self._csr("M"))
    C = property(lambda self: self._csr("C"))
    K = property(lambda self: self._csr("K"))
    B = property(lambda self: self._csr("B"))


class _Placed:
    """Matrix ``which`` of an assembly placed at row and column ``at`` of a ``2n × 2n`` matrix over ``z = (q, q̇)``
    (an energy's form): its product with states and its count of entries in NumPy, dense up to the dense exact
    solution's size; anything else of a CSR matrix made when first asked for (SciPy imported then)."""

    def __init__(self, asm: NumericAssembly, which: str, at: int):
        self.asm, self.which, self.at = asm, which, at
        self.shape = (2 * len(asm.names), 2 * len(asm.names))

    @property
    def nnz(self) -> int:
        return int(self.asm.entries[self.which][2].size)

    def __matmul__(self, Z: np.ndarray) -> np.ndarray:
        n, at = len(self.asm.names), self.at
        if n > _DENSE_FORMS:
            return self._csr() @ Z
        out = np.zeros((2 * n, *np.shape(Z)[1:]))
        out[at : at + n] = self.asm.dense(self.which) @ np.asarray(Z)[at : at + n]
        return out

    def form(self, Z: np.ndarray) -> np.ndarray:
        """``zᵀ H z`` for each column ``z`` of ``Z`` (``2n × N``): entry by entry where the matrix is sparse (a
        200-section ladder's three forms over 3,001 times, one BLAS thread: 6 ms against 16 ms for dense
        products), as a dense product otherwise."""
        n, at = len(self.asm.names), self.at
        r, c, v = self.asm.entries[self.which]
        Z = np.asarray(Z)
        if v.size > _SPARSE_FORMS * n:
            return np.einsum("ij,ij->j", Z, self @ Z)
        if Z.ndim == 1:
            return v @ (Z[at + r] * Z[at + c])
        out = np.empty(Z.shape[1])
        step = max(1, 2**16 // max(v.size, 1))  # columns at a time: 2**16 products (512 KiB), in cache, reused
        for j in range(0, Z.shape[1], step):
            block = Z[:, j : j + step]
            out[j : j + step] = v @ (block[at + r] * block[at + c])
        return out

    def _csr(self):
        made = self.__dict__.get("_made")
        if made is None:
            import scipy.sparse as sps

            n = len(self.asm.names)
            r, c, v = self.asm.entries[self.which]
            made = self.__dict__["_made"] = sps.csr_matrix((v, (r + self.at, c + self.at)), shape=(2 * n, 2 * n))
        return made

    def __getattr__(self, attr: str) -> Any:
        if attr.startswith("__"):
            raise AttributeError(attr)
        return getattr(self._csr(), attr)


#: Up to this many coordinates an energy's form multiplies states as a dense matrix (the dense exact solution's
#: sizes); beyond, as a CSR matrix.
_DENSE_FORMS = 1200
#: Up to this many entries per coordinate an energy's form is evaluated entry by entry (:meth:`_Placed.form`).
_SPARSE_FORMS = 4
