"""A component whose branch joins a node to itself is refused when added, for every kind of two or more terminals.

Parametrized over ``lg.default_registry().kinds`` as the conformance suite is: each kind's own ``example()`` is
built with the two terminals of one of its branches given the same node (under one name, and ground under two of
its names), and must be refused by name — a spring, a resistor, a source or a transducer's coil from a node to
itself acts on nothing.
"""

from __future__ import annotations

import re

import pytest

import lagrangian as lg

REGISTRY = lg.default_registry()
KINDS = sorted(kind for kind in REGISTRY.kinds if len(REGISTRY.component_type(kind).terminals) >= 2)


def test_the_kinds_of_two_or_more_terminals_are_all_here():
    assert {"spring", "damper", "resistor", "capacitor", "inductor", "voltage_source", "current_source",
            "torsion_spring", "revolute", "moving_coil", "gyrator", "dc_motor", "cubic_spring"} <= set(KINDS)


def joined(kind: str, ground: bool = False) -> tuple[tuple[str, ...], str, tuple[str, str]]:
    """The example's nodes with the second terminal of its first branch given the first's node (``ground``: both
    given ground, as ``"ground"`` and ``"0"``); that node and the two terminals' names."""
    cls = REGISTRY.component_type(kind)
    ex = cls.example()
    model = lg.Model("example", **dict(ex.options))
    nodes = list(model.add(kind, "K", ex.nodes, **dict(ex.params)).nodes)
    component = model.component("K")
    for a, b in component.branches():
        ends = [(i, j) for i, x in enumerate(nodes) for j, y in enumerate(nodes)
                if i < j and {x, y} == {a, b} and component.node_domain(i) == component.node_domain(j)]
        if ends:
            i, j = ends[0]
            break
    else:  # pragma: no cover - every built-in kind has a branch between two of its terminals
        raise AssertionError(f"{kind}: no branch between two of its terminals")
    if ground:
        nodes[i], nodes[j] = "ground", "0"
        node = "ground"
    else:
        node = nodes[i] if nodes[i] != "ground" else nodes[j]
        nodes[i] = nodes[j] = node
    return tuple(nodes), node, (cls.terminals[i], cls.terminals[j])


@pytest.mark.parametrize("ground", [False, True], ids=["node", "ground"])
@pytest.mark.parametrize("kind", KINDS)
def test_a_branch_from_a_node_to_itself_is_refused_by_name(kind, ground):
    nodes, node, (first, second) = joined(kind, ground)
    ex = REGISTRY.component_type(kind).example()
    model = lg.Model("self-joined", **dict(ex.options))
    message = (rf"^{kind} 'K': its terminals {first}, {second} are all node '{node}'.*itself.*act on nothing\. "
               rf"Join different nodes: \('ground', ")
    with pytest.raises(lg.TopologyError, match=message):
        model.add(kind, "K", nodes, **dict(ex.params))
    assert "K" not in model.components and model.nodes == ["ground"]


def test_a_node_shared_by_two_branches_is_no_self_loop():
    """A gyrator from n1 to ground and from n2 to ground has ground at two terminals, on different branches."""
    model = lg.Model("two-port")
    gyrator = model.add("gyrator", "G", ("n1", "0", "n2", "gnd"), r=3.3)
    assert gyrator.nodes == ("n1", "ground", "n2", "ground") and gyrator.self_loop() is None


def test_a_moving_coil_whose_moving_node_is_ground_is_refused_by_its_own_rule():
    """Its second branch (the moving node against the frame) joins ground to itself when the moving node is ground,
    but with no two terminals of one domain there: the coil's own, more precise, refusal stands."""
    model = lg.Model("coil")
    with pytest.raises(lg.ModelError, match="moving terminal 'p' is ground, so nothing can move") as refusal:
        model.add("moving_coil", "M", ("n1", "0", "0"), Bl=2.0)
    assert not isinstance(refusal.value, lg.TopologyError)


def test_a_kind_may_allow_a_branch_from_a_node_to_itself(registry_with):
    """A plugin kind that sets ``distinct_terminals = False`` (a ring of charge on one node, say) is accepted."""

    class Ring(lg.Component):
        """A term ½ k x² on one node, drawn as a loop from it to itself."""

        kind, domain, distinct_terminals = "ring", "mechanical", False
        parameters = {"k": lg.Parameter("stiffness", unit="N/m")}

        def contribute(self, ctx):
            x = ctx.view.position(self.nodes[0])[0]
            return lg.Contribution(V=self.k * x**2 / 2)

        @classmethod
        def example(cls):
            return lg.Example(("p", "p"), {"k": 7.0}, context=[("mass", "m", "p", {"m": 0.3})])

    model = lg.Model("ring", registry=registry_with(Ring))
    model.add("mass", "m", "p", m=0.3)
    ring = model.add("ring", "R", ("p", "p"), k=7.0)
    assert ring.self_loop() is None and "R" in model.components


def test_the_refusal_names_the_fix_for_ground():
    model = lg.Model("grounded")
    with pytest.raises(lg.TopologyError, match=re.escape("('ground', 'n1') acts between the reference and node 'n1'")):
        model.add("resistor", "R1", ("gnd", "0"), R=4.7e3)
