"""Graph algorithms on the component graph: topology checks, normal trees, loops.

Edges are keyed by component name and carry their orientation ``a → b``.
Everything here works on networkx ``MultiGraph`` s, so parallel components
(two capacitors between the same nodes) are handled: each is its own edge,
and on :class:`Multigraph`, the part of that interface these algorithms and
the built-in circuit domain read (nodes, edges with keys and data, in
networkx's order), which a model solved in numbers builds without importing
networkx (0.15 s of CPU, more than NumPy).
"""

from __future__ import annotations

from collections.abc import Callable, Hashable


from ..errors import FloatingNetworkError, TopologyError
from . import deferred as _deferred

nx = _deferred.module("networkx", globals())

__all__ = ["Multigraph", "check_topology", "normal_tree", "fundamental_loops", "tree_potentials"]


class Multigraph:
    """An undirected multigraph with keyed edges: networkx's ``MultiGraph`` as far as the algorithms here read it
    (``add_node``, ``add_nodes_from``, ``add_edge``, ``nodes``, ``edges(keys=, data=)``, in networkx's order:
    nodes as added, each edge once, from its first node's adjacency), and :meth:`networkx` for the rest.

    >>> g = Multigraph()
    >>> _ = g.add_edge("a", "b", key="R1"); _ = g.add_edge("c", "d", key="R2"); _ = g.add_edge("a", "e", key="R3")
    >>> [k for _, _, k in g.edges(keys=True)] == [k for _, _, k in g.networkx().edges(keys=True)]
    True
    """

    def __init__(self):
        self._adj: dict = {}

    def add_node(self, node: Hashable) -> None:
        self._adj.setdefault(node, {})

    def add_nodes_from(self, nodes) -> None:
        for node in nodes:
            self._adj.setdefault(node, {})

    def add_edge(self, u: Hashable, v: Hashable, key: Hashable, **data) -> Hashable:
        self.add_node(u)
        self.add_node(v)
        self._adj[u].setdefault(v, {})[key] = data
        if u != v:
            self._adj[v].setdefault(u, {})[key] = data
        return key

    @property
    def nodes(self) -> list:
        return list(self._adj)

    def __contains__(self, node: Hashable) -> bool:
        return node in self._adj

    def edges(self, keys: bool = False, data: bool = False) -> list[tuple]:
        out, seen = [], set()
        for node, neighbours in self._adj.items():
            for other, by_key in neighbours.items():
                if other in seen:
                    continue
                for key, attributes in by_key.items():
                    out.append((node, other) + ((key,) if keys else ()) + ((attributes,) if data else ()))
            seen.add(node)
        return out

    def networkx(self):
        """The same graph as a networkx ``MultiGraph`` (networkx imported then)."""
        g = nx.MultiGraph()
        g.add_nodes_from(self._adj)
        for u, v, key, data in self.edges(keys=True, data=True):
            g.add_edge(u, v, key=key, **data)
        return g


def _edges(graph: nx.MultiGraph):
    for u, v, key, data in graph.edges(keys=True, data=True):
        yield u, v, key, data


def check_topology(graph: nx.MultiGraph, ground: str, role: Callable[[str], str | None]) -> None:
    """Raise if part of ``graph`` has no path to ``ground``, if ideal across-sources
    form a loop, or if ideal through-sources form a cut-set.

    ``role(key)`` gives ``"across"``, ``"through"`` or ``None`` for each edge key.

    >>> g = nx.MultiGraph()
    >>> g.add_edge("n1", "ground", key="V1", a="n1", b="ground")
    'V1'
    >>> g.add_edge("n1", "ground", key="V2", a="n1", b="ground")
    'V2'
    >>> check_topology(g, "ground", lambda k: "across")
    Traceback (most recent call last):
    ...
    lagrangian.errors.TopologyError: ideal across-sources V1, V2 form a loop (...) ...
    """
    if _sound(graph, ground, role):
        return
    if isinstance(graph, Multigraph):  # something to say: networkx's searches name it
        graph = graph.networkx()
    for part in nx.connected_components(graph):
        if ground not in part:
            names = sorted({k for u, v, k in graph.subgraph(part).edges(keys=True)})
            raise FloatingNetworkError(
                f"nodes {', '.join(sorted(map(str, part)))} (components {', '.join(names) or 'none'}) "
                f"have no path to the reference node 'ground': connect one of them to ground."
            )
    forest = nx.MultiGraph()
    forest.add_nodes_from(graph.nodes)
    for u, v, key, _ in _edges(graph):
        if role(key) != "across":
            continue
        if nx.has_path(forest, u, v):
            path = nx.shortest_path(forest, u, v)
            loop = [key] + [next(iter(forest.get_edge_data(p, q))) for p, q in zip(path, path[1:])]
            raise TopologyError(
                f"ideal across-sources {', '.join(sorted(loop))} form a loop ({' - '.join(map(str, path + [path[0]]))}): "
                f"their values cannot all hold. Remove one, or put an impedance (a resistor, a spring) in the loop."
            )
        forest.add_edge(u, v, key=key)
    rest = nx.MultiGraph()
    rest.add_nodes_from(graph.nodes)
    rest.add_edges_from((u, v, k) for u, v, k, _ in _edges(graph) if role(k) != "through")
    for part in nx.connected_components(rest):
        if ground not in part:
            cut = sorted(k for u, v, k, _ in _edges(graph) if role(k) == "through" and ((u in part) != (v in part)))
            raise TopologyError(
                f"ideal through-sources {', '.join(cut)} form a cut-set isolating nodes {', '.join(sorted(map(str, part)))}: "
                f"they are the only elements joining those nodes to the rest, so they alone would set the flow through "
                f"the cut (a current source's current; in a mechanism, force sources acting on a part held by nothing "
                f"else), and nothing else carries it. Add a path (an element: a resistor, a spring, a damper) between "
                f"those nodes and the rest."
            )


def _sound(graph: nx.MultiGraph, ground: str, role: Callable[[str], str | None]) -> bool:
    """Whether :func:`check_topology` has nothing to say, by union–find over the edges in one pass each (every
    node joined to ground; no loop of across-sources; every node joined to ground without through-sources): a
    tenth of the time of networkx's searches on a 300-element ladder.  ``False`` sends the check to those
    searches, which name what is wrong."""
    edges = [(u, v, role(k)) for u, v, k in graph.edges(keys=True)]
    nodes = list(graph.nodes)

    def joined(kept) -> dict:
        parent = {n: n for n in nodes}

        def find(x):
            while parent[x] != x:
                parent[x] = parent[parent[x]]
                x = parent[x]
            return x

        for u, v, r in edges:
            if kept(r):
                a, b = find(u), find(v)
                if a == b and r == "across" and kept is _across:
                    return {}
                parent[a] = b
        return {n: find(n) for n in nodes}

    # (every node joined to ground without through-sources is joined to it at all: no pass over every edge)
    for kept in (_across, _not_through):
        roots = joined(kept)
        if not roots:
            return False  # a loop of across-sources
        if kept is _not_through and len({roots[n] for n in nodes} | {roots[ground]}) != 1:
            return False
    return True


def _across(r) -> bool:
    return r == "across"


def _not_through(r) -> bool:
    return r != "through"


def normal_tree(graph: nx.MultiGraph, ground: str, priority: Callable[[Hashable], float]) -> set[str]:
    """Keys of a spanning forest chosen greedily by ``priority`` (lower first; ``inf`` never).

    With priority across-sources < capacitive < resistive < inductive <
    through-sources this is the *normal tree* of circuit theory.  Ties go to
    edges touching ``ground``, then to insertion order, so results are
    deterministic.

    >>> g = nx.MultiGraph()
    >>> for key, a, b in [("L", "n1", "ground"), ("C", "n1", "ground")]:
    ...     _ = g.add_edge(a, b, key=key, a=a, b=b)
    >>> sorted(normal_tree(g, "ground", {"L": 3, "C": 1}.get))
    ['C']
    """
    order = sorted(
        ((priority(k), 0 if ground in (u, v) else 1, i, u, v, k) for i, (u, v, k) in enumerate(graph.edges(keys=True))),
        key=lambda item: item[:3],
    )
    parent = {n: n for n in graph.nodes}  # union–find with path halving (networkx's UnionFind: twice the time)

    def find(x):
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    tree = set()
    for prio, _, _, u, v, k in order:
        if prio == float("inf"):
            continue
        a, b = find(u), find(v)
        if a != b:
            parent[a] = b
            tree.add(k)
    return tree


def fundamental_loops(graph: nx.MultiGraph, tree: set[str]) -> dict[str, list[tuple[str, int]]]:
    """For each chord (non-tree edge), its loop as ``[(edge key, ±1), ...]``.

    The loop is oriented along the chord (``a → b``); the sign says whether
    each edge is traversed along (+1) or against (−1) its own orientation.
    The tree is rooted once (parents and depths by breadth-first search), and
    each loop is the chord plus the tree's one path from ``b`` up to the
    nodes' common ancestor and down to ``a``: linear in the loop's length,
    where a search per chord (networkx's ``shortest_path``) cost five times as
    much on a 100-section ladder.
    """
    edges = list(_edges(graph))
    adjacent = _tree_adjacency(graph, edges, tree)
    parent: dict[Hashable, tuple | None] = {}
    depth: dict[Hashable, int] = {}
    root: dict[Hashable, Hashable] = {}
    for start in graph.nodes:
        if start in depth:
            continue
        depth[start], parent[start], root[start] = 0, None, start
        queue = [start]
        for node in queue:
            for other, k, a, b in adjacent[node]:
                if other not in depth:
                    depth[other], parent[other], root[other] = depth[node] + 1, (node, k, a, b), start
                    queue.append(other)

    def signed(p, step) -> tuple[str, int]:  # the tree edge of ``step``, walked from p to the other node
        q, k, a, b = step
        return k, 1 if (a, b) == (p, q) else -1

    loops = {}
    for u, v, k, d in edges:
        if k in tree:
            continue
        a, b = d["a"], d["b"]
        if root[a] != root[b]:  # nothing else of this domain joins its nodes (a body's point is another's)
            raise TopologyError(
                f"component {k!r} closes no loop: nothing else of its domain joins its nodes {a!r} and {b!r}, so "
                f"what flows through it (a current source's current) has no path back. Join them by another element "
                f"of its domain, or attach it to nodes of its domain (not a point of a body)."
            )
        up, down = [], []  # from b up; from a up (walked down, reversed, at the end)
        x, y = b, a
        while depth[x] > depth[y]:
            up.append(signed(x, parent[x]))
            x = parent[x][0]
        while depth[y] > depth[x]:
            down.append(parent[y])
            y = parent[y][0]
        while x != y:
            up.append(signed(x, parent[x]))
            x = parent[x][0]
            down.append(parent[y])
            y = parent[y][0]
        loop = [(k, 1), *up]
        for p, k2, ea, eb in reversed(down):  # down the tree from the ancestor p to its child
            loop.append((k2, 1 if (ea, eb) == (p, _child(p, k2, ea, eb)) else -1))
        loops[k] = loop
    return loops


def _tree_adjacency(graph, edges: list, tree: set[str]) -> dict[Hashable, list]:
    """Each node's tree edges, in the edges' order, as ``(other end, key, a, b)``."""
    adjacent: dict[Hashable, list] = {n: [] for n in graph.nodes}
    for u, v, k, d in edges:
        if k in tree:
            adjacent[u].append((v, k, d["a"], d["b"]))
            adjacent[v].append((u, k, d["a"], d["b"]))
    return adjacent


def _child(p, k: str, a, b):
    """The other end of tree edge ``k`` (``a → b``) from node ``p``."""
    return b if a == p else a


def tree_potentials(graph: nx.MultiGraph, tree: set[str], ground: str) -> dict[str, list[tuple[str, int]]]:
    """For each node, its potential as a signed sum of tree-branch drops, from ``ground``.

    A branch drop is ``φ_a − φ_b``; so ``φ_node = Σ sign · drop``.
    """
    adjacent = _tree_adjacency(graph, list(_edges(graph)), tree)
    result = {ground: []}
    queue = [ground] if ground in adjacent else []
    for parent in queue:  # breadth first from ground
        for child, key, _, b in adjacent[parent]:
            if child not in result:
                # φ_child = φ_parent - drop if child is b (a=parent), + drop if child is a
                result[child] = result[parent] + [(key, -1 if b == child else 1)]
                queue.append(child)
    cut = sorted(set(graph.nodes) - set(result), key=str)
    if cut:  # joined to ground only through elements kept out of the tree (sources of their through quantity)
        names = sorted({k for u, v, k, _ in _edges(graph) if u in cut or v in cut})
        raise TopologyError(
            f"nodes {', '.join(map(repr, cut))} reach ground in their domain only through {', '.join(map(repr, names))}, "
            f"which fix what flows (current sources): nothing sets their potential. Join them to ground by another "
            f"element of their domain, or attach the sources to nodes of their domain (not a point of a body)."
        )
    return result
