"""The light multigraph of :mod:`lagrangian.base.network` against networkx's ``MultiGraph``: the same nodes and
edges in the same order, and the same normal trees, loops, node potentials and topology verdicts from the
algorithms that read either (a model solved in numbers builds the light one, without networkx)."""

from __future__ import annotations

import networkx as nx
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lagrangian.base.network import Multigraph, check_topology, fundamental_loops, normal_tree, tree_potentials
from lagrangian.errors import TopologyError

NODES = ["ground", "a", "b", "c", "d", "e"]
edges_strategy = st.lists(st.tuples(st.sampled_from(NODES), st.sampled_from(NODES),
                                    st.sampled_from(["across", "through", None]), st.integers(0, 3)),
                          min_size=1, max_size=14)


def _both(edges):
    light, heavy = Multigraph(), nx.MultiGraph()
    for g in (light, heavy):
        g.add_node("ground")
    roles, priority = {}, {}
    for i, (a, b, role, prio) in enumerate(edges):
        key = f"E{i}"
        roles[key], priority[key] = role, {"across": 0, "through": float("inf")}.get(role, prio + 1)
        for g in (light, heavy):
            g.add_edge(a, b, key=key, a=a, b=b)
    return light, heavy, roles, priority


def _verdict(graph, roles):
    try:
        check_topology(graph, "ground", roles.get)
    except TopologyError as exc:  # FloatingNetworkError is one
        return type(exc).__name__, str(exc)
    return None


@settings(max_examples=200, deadline=None)
@given(edges=edges_strategy)
def test_the_light_multigraph_reads_as_networkx_and_gives_the_same_trees_loops_and_verdicts(edges):
    light, heavy, roles, priority = _both(edges)
    assert light.nodes == list(heavy.nodes)
    assert light.edges(keys=True, data=True) == list(heavy.edges(keys=True, data=True))
    assert light.edges() == list(heavy.edges())
    assert _verdict(light, roles) == _verdict(heavy, roles)
    tree = normal_tree(light, "ground", priority.get)
    assert tree == normal_tree(heavy, "ground", priority.get)
    for algorithm in (lambda g: fundamental_loops(g, tree), lambda g: tree_potentials(g, tree, "ground")):
        outcomes = []
        for g in (light, heavy):
            try:
                outcomes.append(("ok", algorithm(g)))
            except TopologyError as exc:
                outcomes.append(("error", str(exc)))
        assert outcomes[0] == outcomes[1]


def test_tree_potentials_against_hand_worked_signs():
    # ground -V1-> a -R1-> b, C1 from b to ground: φ_a = −drop(V1)·… as a → b orientation says
    g = Multigraph()
    g.add_edge("ground", "a", key="V1", a="ground", b="a")
    g.add_edge("a", "b", key="R1", a="a", b="b")
    g.add_edge("b", "ground", key="C1", a="b", b="ground")
    assert tree_potentials(g, {"V1", "R1"}, "ground") == {"ground": [], "a": [("V1", -1)], "b": [("V1", -1), ("R1", -1)]}
    with pytest.raises(TopologyError, match="closes no loop"):
        fundamental_loops(g.networkx(), set())  # no tree at all: the chords' ends are in different trees
