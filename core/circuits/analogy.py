"""Analogies: a model of one domain mapped onto another, and back.

An :class:`Analogy` (registered by a plugin) names a source and a target
domain and says whether it keeps the graph (``dual=False``: nodes map to
nodes, as in the force–current analogy) or goes through the planar dual
graph (``dual=True``: nodes become meshes and meshes nodes, as in the
force–voltage analogy).  Plugins declare, per component kind, how it maps
(``register_analogues``).  :func:`map_model` builds the analogue model and a
record of which element came from which component and how every coordinate
of the analogue is expressed in the original's.

The identification that makes it exact: an element that stands for branch
``i`` of a component carries the same *branch quantity* (charge, flux
linkage, position difference) as that branch.  Solving those identities for
the analogue's coordinates gives the coordinate map; substituting it into
the analogue's Lagrangian gives back the original's (tests check this
symbolically).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..base.arguments import check_mapping
from ..base.component import GROUND, Component, _CallableSignal, t
from ..base.text import as_expr
from ..derivation.numeric import numeric_branches
from ..derivation.stamps import NotStampable
from ..plugin.contracts import AnalogueBuilder, Analogy, Element, Ports
from ..errors import ModelError, UnknownNameError
from ..model import Model
from ..base import deferred as _deferred

nx = _deferred.module("networkx", globals())
sp = _deferred.module("sympy", globals())

__all__ = ["Analogy", "Element", "Ports", "Mapped", "AnalogyError", "map_model", "dual_branches"]


class AnalogyError(ModelError):
    """A model cannot be mapped through the requested analogy."""


@dataclass
class Mapped:
    """The result of :func:`map_model`.

    ``model`` is the analogue; ``origin`` maps each of its component names to
    the source component it came from; ``coordinates`` maps each of its
    coordinate functions to an expression in the source model's coordinates;
    ``analogy`` and ``direction`` (``"forward"`` source → target, or
    ``"inverse"``) say how it was made.
    """

    model: Model
    source: Model
    analogy: Analogy
    direction: str
    origin: dict[str, str]
    #: the map, or what solves for it when first asked for (:attr:`coordinates`)
    _map: dict[sp.Expr, sp.Expr] | Callable[[], dict[sp.Expr, sp.Expr]]

    @property
    def coordinates(self) -> dict[sp.Expr, sp.Expr]:
        """Each coordinate function of the analogue as an expression in the source model's coordinates (solved
        exactly on first use; :func:`map_model` has checked in numbers that the branches fix it)."""
        if callable(self._map):
            self._map = self._map()
        return self._map

    def to_source(self, expr: Any) -> sp.Expr:
        """Rewrite an expression in the analogue's coordinates in terms of the source model's."""
        return as_expr(expr, "the expression to rewrite", names=self._names()).subs(self.coordinates).doit()

    def _names(self) -> dict[str, sp.Basic]:
        """The analogue's coordinates (and t) by name, for text given to :meth:`to_source`."""
        return {c.name: c.function for c in self.model.coordinates} | {"t": t}

    def initial(self, initial: Mapping[str, float], velocity: Mapping[str, float], params=None) -> tuple[dict, dict]:
        """Initial coordinates and velocities of the analogue from those of the source model."""
        src = self.source
        funcs = {c.name: c.function for c in src.coordinates}
        initial = check_mapping("initial", initial, list(funcs))
        velocity = check_mapping("velocity", velocity, list(funcs))
        for given in (initial, velocity):
            for name in given:
                if name not in funcs:
                    raise UnknownNameError(f"coordinate of model {src.name!r}", name, funcs)
        at0: dict[Any, float] = {t: 0.0}
        for name, f in funcs.items():
            at0[f.diff(t)] = _number(velocity, name, "velocity")
        for name, f in funcs.items():
            at0[f] = _number(initial, name, "value")
        values = {s: v for s, v in src._values(params or {}).items()}
        first = set(self.model.first_order)
        q0, v0 = {}, {}
        for c in self.model.coordinates:
            expr = self.coordinates[c.function].xreplace(values)
            q0[c.name] = float(expr.subs(at0))
            if c.name not in first:
                v0[c.name] = float(expr.diff(t).subs(at0))
        return q0, v0


def _number(given: Mapping[str, Any], name: str, what: str) -> float:
    """The initial ``what`` of coordinate ``name`` (0 when not given) as a finite float."""
    value = given.get(name, 0.0)
    try:
        if isinstance(value, (str, bytes, bool)) or value is None:
            raise TypeError
        out = float(value)
    except (TypeError, ValueError):  # text, a list, an expression of t, ...
        raise ModelError(f"initial {what} of {name!r} must be a number, got {value!r:.60} of type "
                         f"{type(value).__name__}.") from None
    except OverflowError:
        out = math.inf
    if not math.isfinite(out):
        raise ModelError(f"initial {what} of {name!r} must be a finite number, got {value!r:.40}.")
    return out


def _planar_dual(graph: nx.MultiGraph, ground_faces: Callable[[list[set[str]]], int]) -> tuple[dict[str, tuple[str, str]], list]:
    """Dual branches ``{edge key: (face_right, face_left)}`` named ``m1, m2, ...`` (the chosen face is ground).

    Parallel branches do not change planarity: the embedding is found for the simple graph of the nodes they join
    (networkx's LR test), and each bundle of parallel branches is laid side by side in its one edge, with a face
    between each two neighbours.  A bundle of ``k`` branches from ``u`` to ``v``: the first borders the face on the
    ``u → v`` side of the simple edge, the last the face on its ``v → u`` side.  (A mass, a spring and a damper on
    one node: one edge, not six half-edges through mid-points; a fifth of the time.)"""
    bundles: dict[frozenset, list[tuple[str, str, str]]] = {}
    for _, _, k, d in graph.edges(keys=True, data=True):
        a, b = d["a"], d["b"]
        if a == b:
            raise AnalogyError(f"branch {k!r} joins node {a!r} to itself: it has no dual branch.")
        bundles.setdefault(frozenset((a, b)), []).append((k, a, b))
    simple = nx.Graph()
    simple.add_nodes_from(graph.nodes)
    for pair in bundles:
        simple.add_edge(*pair)
    planar, embedding = nx.check_planarity(simple)
    if not planar:
        raise AnalogyError(
            "the network is not planar, so it has no dual graph and no force–voltage analogue: "
            "use the force–current analogy, which keeps the topology."
        )
    # faces numbered: those between neighbours in a bundle, bundle by bundle, then the simple graph's
    face_of: dict[tuple, int] = {}
    count = sum(len(bundle) - 1 for bundle in bundles.values())
    for u, v in embedding.edges():
        if (u, v) in face_of:
            continue
        nodes = embedding.traverse_face(u, v)
        for i, n in enumerate(nodes):
            face_of[(n, nodes[(i + 1) % len(nodes)])] = count
        count += 1
    edge_faces = {}
    between = 0
    for bundle in bundles.values():
        u, v = bundle[0][1], bundle[0][2]
        sides = [face_of[(u, v)]] + list(range(between, between + len(bundle) - 1)) + [face_of[(v, u)]]
        between += len(bundle) - 1
        for i, (k, a, b) in enumerate(bundle):  # branch i between sides i (its u → v side) and i + 1
            edge_faces[k] = (sides[i], sides[i + 1]) if (a, b) == (u, v) else (sides[i + 1], sides[i])
    face_edges = [set() for _ in range(count)]
    for k, (r, l) in edge_faces.items():
        face_edges[r].add(k)
        face_edges[l].add(k)
    ground = ground_faces(face_edges)
    order = [ground] + [i for i in range(count) if i != ground]
    names = {f: (GROUND if f == ground else f"m{n}") for n, f in enumerate(order)}
    return {k: (names[r], names[l]) for k, (r, l) in edge_faces.items()}, face_edges


def dual_branches(graph: nx.MultiGraph, must_touch_ground: set[str] = frozenset()) -> dict[str, tuple[str, str]]:
    """For each edge of a planar ``graph``, the two dual nodes (meshes) on either side of it.

    The mesh adjacent to every edge of ``must_touch_ground`` (and to the most
    edges among those that qualify) becomes ``ground``; a current from the
    first dual node to the second equals the rate ``a → b`` across the edge.

    Three elements in parallel become three in series (one loop of three meshes):

    >>> g = nx.MultiGraph()
    >>> for k in ("m", "k", "c"):
    ...     _ = g.add_edge("p", "ground", key=k, a="p", b="ground")
    >>> loop = nx.MultiGraph(list(dual_branches(g, {"m"}).values()))
    >>> sorted(d for _, d in loop.degree()), len(nx.cycle_basis(nx.Graph(loop)))
    ([2, 2, 2], 1)
    """

    def choose(face_edges: list[set[str]]) -> int:
        ok = [i for i, edges in enumerate(face_edges) if must_touch_ground <= edges]
        if not ok:
            raise AnalogyError(
                f"no mesh of the network touches all of {', '.join(sorted(must_touch_ground))}, which must all "
                f"attach to the reference in the analogue: use the other analogy."
            )
        return max(ok, key=lambda i: (len(face_edges[i]), -i))

    return _planar_dual(graph, choose)[0]


def _key(name: str, index: int) -> str:
    return name if index == 0 else f"{name}#{index}"


def _branch_value(model: Model, key: str) -> sp.Expr:
    """The branch quantity of edge ``key``, from the view of the domain the branch lies in."""
    name, _, index = key.partition("#")
    comp = model.component(name)
    a, b = comp.branches()[int(index or 0)]
    node = a if a != GROUND else b
    domain = comp.node_domain(comp.nodes.index(node)) if node in comp.nodes else comp.domain
    return model.assembly.views[domain].branch_value(key)


def _user_params(comp: Component) -> dict[str, Any]:
    """The component's parameters as given (callable signals as their callables)."""
    return {k: v.func if isinstance(v, _CallableSignal) else v for k, v in comp.params.items() if v is not None}


def map_model(model: Model, analogy: str, *, name: str | None = None) -> Mapped:
    """Map ``model`` through the analogy called ``analogy`` (either direction, chosen by the model's domain).

    >>> import lagrangian as lg
    >>> m = lg.Model("msd")
    >>> _ = m.add("mass", "m", "p", m=2)
    >>> _ = m.add("spring", "k", ("ground", "p"), k=8)
    >>> circuit = map_model(m, "force-current")
    >>> sorted(c.kind for c in circuit.model.components.values())
    ['capacitor', 'inductor']
    >>> circuit.coordinates
    {lambda_p(t): x_p(t)}
    """

    registry = model.registry
    if analogy not in registry.analogies:
        raise UnknownNameError("analogy", analogy, registry.analogies)
    an = registry.analogies[analogy]
    domains = {d for c in model.components.values() for d in c.domains}
    if domains == {an.source}:
        direction, mapped_domain, target, options = "forward", an.source, an.target, dict(an.options)
    elif domains == {an.target}:
        direction, mapped_domain, target, options = "inverse", an.target, an.source, dict(an.inverse_options)
    elif domains == {an.source, an.target}:
        # a coupled model: its source-domain part is mapped, its target-domain part kept as it is
        direction, mapped_domain, target = "forward", an.source, an.target
        options = {**{k: v for k, v in model._options.items() if k in registry.domains[target].options}, **an.options}
        kept = model.options
        clash = [k for k, v in an.options.items() if kept.get(k) != v]
        if clash:
            raise AnalogyError(
                f"model {model.name!r} couples domains; its {target} part is kept as it is, but the {analogy} analogue "
                f"needs {', '.join(f'{k}={an.options[k]!r}' for k in clash)} (it has "
                f"{', '.join(f'{k}={kept.get(k)!r}' for k in clash)}): build the model that way, or use the other analogy."
            )
    else:
        raise AnalogyError(
            f"the {analogy} analogy maps {an.source} models to {an.target} models and back; model {model.name!r} has "
            f"components of the domains {', '.join(sorted(domains))}."
        )
    kept_as_is = {c.name for c in model.components.values() if set(c.domains) == {target}}
    missing = [
        c for c in model.components.values() if c.name not in kept_as_is and (c.kind, analogy) not in registry.analogues
    ]
    if missing:
        kinds = sorted({c.kind for c in missing})
        raise AnalogyError(
            f"no plugin declares a {analogy} analogue for {', '.join(kinds)} (component {missing[0].name!r}); "
            f"a plugin adds one with the register_analogues hook."
        )
    graph = model._graph.graph(domain=mapped_domain)
    if an.dual:
        anchored = {
            c.name
            for c in model.components.values()
            if c.name not in kept_as_is and getattr(registry.analogues[c.kind, analogy][1], "anchored", False)
        }
        ports = dual_branches(graph, anchored)
    else:
        ports = {k: (d["a"], d["b"]) for _, _, k, d in graph.edges(keys=True, data=True)}
    for comp in model.components.values():  # branches of the part kept as it is
        for i, (a, b) in enumerate(comp.branches()):
            ports.setdefault(_key(comp.name, i), (a, b))

    target_model = Model(name or f"{model.name} ({analogy} analogue)", registry=registry, **options)
    origin: dict[str, str] = {}
    identities: list[tuple[str, str, int]] = []
    for comp in model.components.values():
        if comp.name in kept_as_is:
            target_model.add(comp.kind, comp.name, comp.nodes, **_user_params(comp))
            origin[comp.name] = comp.name
            identities += [(_key(comp.name, i), _key(comp.name, i), 1) for i in range(len(comp.branches()))]
            continue
        build = registry.analogues[comp.kind, analogy][1]
        try:
            elements = build(comp, Ports(comp, ports, GROUND, model))
        except ModelError:
            raise
        except Exception as exc:
            raise AnalogyError(f"the {analogy} analogue of {comp.kind} {comp.name!r} failed: {exc.__class__.__name__}: {exc}") from exc
        for el in elements:
            target_model.add(el.kind, el.name, el.nodes, **dict(el.params))
            origin[el.name] = comp.name
            for mine, theirs in el.pairs():
                identities.append((_key(el.name, mine), _key(comp.name, theirs), el.sign))

    checked = _checked_in_numbers(model, target_model, identities, analogy)
    if checked:  # the map is consistent and determined: its expressions are solved for when first asked for
        return Mapped(target_model, model, an, direction, origin,
                      lambda: _coordinate_map(model, target_model, identities, analogy))
    return Mapped(target_model, model, an, direction, origin, _coordinate_map(model, target_model, identities, analogy))


def _checked_in_numbers(model: Model, target: Model, identities: list[tuple[str, str, int]], analogy: str) -> bool:
    """Check, in numbers, that the identities of branches fix the analogue's coordinates as linear functions of the
    model's (:mod:`lagrangian.derivation.numeric`), raising what :func:`_coordinate_map` would; ``False`` when
    either model is not assembled in numbers (the symbolic map then checks)."""
    try:
        (mine, mine_rows), (theirs, theirs_rows) = numeric_branches(target), numeric_branches(model)
    except NotStampable:  # (a model without coordinates among them: the symbolic map says so)
        return False
    A, B = np.zeros((len(identities), len(mine))), np.zeros((len(identities), len(theirs)))
    for r, (el, src, sign) in enumerate(identities):
        for j, c in mine_rows[el].items():
            A[r, j] = c
        for j, c in theirs_rows[src].items():
            B[r, j] = sign * c
    X, _, rank, _ = np.linalg.lstsq(A, B, rcond=None)  # its rank: the one SVD, with matrix_rank's tolerance
    scale = max(np.abs(B).max(initial=0.0), np.abs(A).max(initial=0.0) * np.abs(X).max(initial=0.0), 1e-300)
    if np.abs(A @ X - B).max(initial=0.0) > 1e-9 * scale:
        raise AnalogyError(f"the {analogy} analogue of model {model.name!r} has no consistent coordinate map.")
    if rank < len(mine):
        raise AnalogyError(f"the {analogy} analogue of model {model.name!r} has coordinates no source branch determines.")
    return True


def _no_coordinates(model: Model, analogy: str, have: list[str]) -> None:
    has = (f"while the model has {', '.join(have)}" if have else
           "and neither has the model: no branch lies on a loop or meets a free node, as with a lone inductor")
    raise AnalogyError(
        f"the {analogy} analogue of model {model.name!r} has no generalized coordinates ({has}), so there is "
        f"nothing to map: close the network (a loop through ground, a mass or capacitor on a free node), or use "
        f"the other analogy."
    )


def _coordinate_map(model: Model, target_model: Model, identities: list[tuple[str, str, int]],
                    analogy: str) -> dict[sp.Expr, sp.Expr]:
    """Each coordinate of the analogue as an expression of the model's, from the identities of branches, solved
    exactly; an :class:`AnalogyError` when they do not fix it."""
    unknowns = [c.function for c in target_model.coordinates]
    plain = {f: sp.Dummy(str(f.func)) for f in unknowns}
    equations = [
        _branch_value(target_model, el).xreplace(plain) - sign * _branch_value(model, src)
        for el, src, sign in identities
    ]
    if not unknowns:  # nothing to solve for (and sympy.linsolve needs unknowns)
        _no_coordinates(model, analogy, [c.name for c in model.coordinates])
    solution = sp.linsolve(equations, [plain[f] for f in unknowns])
    if not solution or solution == sp.EmptySet:
        raise AnalogyError(f"the {analogy} analogue of model {model.name!r} has no consistent coordinate map.")
    (values,) = solution
    free = set().union(*(v.free_symbols for v in values)) & set(plain.values())
    if free:
        raise AnalogyError(f"the {analogy} analogue of model {model.name!r} has coordinates no source branch determines.")
    return dict(zip(unknowns, values))
