"""The component graph: nodes are connection points, components attach to them.

Held in a networkx ``MultiGraph`` whose edges are the components' branches,
keyed by component name.  Components with no terminals (uniform gravity)
attach to the model as a whole.
"""

from __future__ import annotations

import contextlib
import functools
from collections.abc import Callable, Iterable, Iterator
from typing import Any


from .component import GROUND, GROUND_ALIASES, Component
from .network import Multigraph
from ..errors import DanglingNodeError, DomainError, DuplicateNameError, ModelError, TopologyError, UnknownNodeError
from . import deferred as _deferred

nx = _deferred.module("networkx", globals())

__all__ = ["ComponentGraph", "unchanged_while_running"]


class ComponentGraph:
    """Components, the nodes they attach to, and the graph that joins them.

    >>> g = ComponentGraph()
    >>> g.normalize_node("0")
    'ground'
    """

    #: Bumped by every change (a component added, a node declared): a run compares it before and after, and so
    #: notices a model changed while it ran (a signal's callable adding a component).  A class attribute too, for a
    #: graph unpickled from before it was kept.
    version: int = 0

    def __init__(self) -> None:
        self.components: dict[str, Component] = {}
        self.declared: list[str] = []
        self.version = 0

    @staticmethod
    def normalize_node(node: Any) -> str:
        if not isinstance(node, (str, int)) or isinstance(node, bool) or str(node).strip() == "":
            raise ModelError(f"node names must be non-empty strings, got {node!r}.")
        name = str(node)
        return GROUND if name.lower() in GROUND_ALIASES else name

    def declare(self, node: Any) -> str:
        name = self.normalize_node(node)
        if name not in self.declared and name != GROUND:
            self.declared.append(name)
            self.version += 1
        return name

    def add(self, component: Component) -> None:
        """Add ``component``; :class:`DuplicateNameError` for a name in use, :class:`TopologyError` for one whose
        branch joins a node to itself (:meth:`Component.self_loop`)."""
        loop = component.self_loop()
        if loop is not None:
            first, second, node = loop
            fix = (f"('ground', {node!r}) acts between node {node!r} and the reference" if node != GROUND
                   else "('ground', 'n1') acts between the reference and node 'n1'")
            raise TopologyError(
                f"{component.kind} {component.name!r}: its terminals {first}, {second} are all node {node!r}, a branch "
                f"from that node to itself, so it would act on nothing. Join different nodes: {fix}."
            )
        if component.name in self.components:
            other = self.components[component.name]
            raise DuplicateNameError(
                f"component name {component.name!r} is already used by a {other.kind} at "
                f"{', '.join(other.nodes) or '(global)'}: give the new {component.kind} another name."
            )
        self.components[component.name] = component
        self.version += 1

    @contextlib.contextmanager
    def unchanged(self, model: str, run: str) -> Iterator[None]:
        """Refuse with a :class:`ModelError` a graph changed within the block — a run (``run`` of ``model``) during
        which code it called (a signal's or load's Python callable) added a component or declared a node: the run
        used the equations from before the change, and its result would describe a model that no longer exists.
        An error the block raised after such a change is chained to the refusal."""
        # (the graph only grows, in order: counts tell what was added, at no cost per run)
        before, components, nodes = self.version, len(self.components), len(self.declared)
        try:
            yield
        except Exception as exc:
            if self.version != before:
                raise self._changed(model, run, components, nodes) from exc
            raise
        if self.version != before:
            raise self._changed(model, run, components, nodes)

    def _changed(self, model: str, run: str, components: int, nodes: int) -> ModelError:
        added = [f"component {n!r} (a {c.kind})" for n, c in list(self.components.items())[components:]]
        declared = [f"node {n!r}" for n in self.declared[nodes:]]
        return ModelError(
            f"model {model!r} was changed during {run}: {', '.join(added + declared) or 'its components'} added "
            f"while it ran, by code the run called (a signal's or load's Python callable). The run integrated the "
            f"equations from before the change, so its result is discarded; the model now holds the change. Build "
            f"the model completely before {run}, and let callables only compute values."
        )

    def nodes(self) -> list[str]:
        """All nodes in order of first use, ground first."""
        seen = {GROUND: None}
        for name in self.declared:
            seen.setdefault(name)
        for comp in self.components.values():
            for n in comp.nodes:
                seen.setdefault(n)
        return list(seen)

    def check_node(self, node: Any) -> str:
        """The normalized name of an existing node, or :class:`UnknownNodeError`."""
        name = self.normalize_node(node)
        if name not in self.nodes():
            raise UnknownNodeError(name, self.nodes())
        return name

    def node_domains(self) -> dict[str, str]:
        """The domain of every non-ground node; raises if domains meet at a node or a node is bare."""
        domains: dict[str, tuple[str, str]] = {}
        for comp in self.components.values():
            for i, n in enumerate(comp.nodes):
                if n == GROUND:
                    continue
                mine = comp.node_domain(i)
                if n in domains and domains[n][0] != mine:
                    dom, other = domains[n]
                    raise DomainError(
                        f"node {n!r} joins {comp.kind} {comp.name!r} ({mine}) and component {other!r} ({dom}); "
                        f"a node belongs to one domain. Couple domains with a transducer component instead."
                    )
                domains.setdefault(n, (mine, comp.name))
        bare = [n for n in self.declared if n not in domains]
        if bare:
            raise DanglingNodeError(
                f"node {bare[0]!r} has nothing attached: attach a component to it or do not declare it."
            )
        return {n: d for n, (d, _) in domains.items()}

    def graph(self, components: Iterable[Component] | None = None, domain: str | None = None, *,
              light: bool = False) -> nx.MultiGraph:
        """A ``MultiGraph`` of the given components' branches (all components by default).

        Edges are keyed by component name (``name#i`` for a component's
        branch ``i > 0``).  With ``domain``, only nodes and branches of that
        domain are included.  ``light``: a :class:`lagrangian.base.network.Multigraph` (no networkx).
        """
        g = Multigraph() if light else nx.MultiGraph()
        g.add_node(GROUND)
        for comp in self.components.values() if components is None else components:
            if domain is None:  # every node and branch
                g.add_nodes_from(comp.nodes)
                for i, (a, b) in enumerate(comp.branches()):
                    g.add_edge(a, b, key=comp.name if i == 0 else f"{comp.name}#{i}", a=a, b=b, component=comp)
                continue
            node_domain = {n: comp.node_domain(i) for i, n in enumerate(comp.nodes) if n != GROUND}
            g.add_nodes_from(n for n in comp.nodes if node_domain.get(n, domain) == domain)
            for i, (a, b) in enumerate(comp.branches()):
                if any(node_domain.get(n, domain) != domain for n in (a, b)):
                    continue
                key = comp.name if i == 0 else f"{comp.name}#{i}"
                g.add_edge(a, b, key=key, a=a, b=b, component=comp)
        return g


def unchanged_while_running(method: Callable) -> Callable:
    """``method`` of a model (an object holding its graph as ``_graph`` and its ``name``), refused when the model
    changed while it ran (:meth:`ComponentGraph.unchanged`)."""

    @functools.wraps(method)
    def run(self, *args: Any, **kwargs: Any) -> Any:
        with self._graph.unchanged(self.name, method.__name__):
            return method(self, *args, **kwargs)

    return run
