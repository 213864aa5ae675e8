"""Pruning a scene's model by its component graph, before anything is assembled or derived.

A scene needs only the components its outputs can depend on.  For a model
of point masses — ``mass``, ``spring``, ``damper``, ``force``,
``central_force``, smooth ``coulomb_friction``, ``prescribed_motion`` and
``gravity`` — and of rotors on a common axis — ``inertia``,
``torsion_spring``, ``rotary_damper``, ``torque``, ``prescribed_rotation``
— which ones those are follows from the graph alone: a component acts on
the nodes it joins, and neither ground nor a node whose motion is
prescribed passes anything from the components on one side to those on the
other.  Pruning there spares the scene the symbolic work of
everything it drops: the shaker of ``benchmarks/scenes.py`` (ten
assemblies hanging from a shaken deck, 40 coordinates) is assembled and
derived as the 4 coordinates of the one assembly asked about, where
deriving the whole model to find that took longer than simulating it.

Anything else keeps the whole model, and the planner finds what to drop
from its equations: rigid bodies and joints, constraints, couplings,
circuits, a load given as a callable of the state or as an expression of
coordinates, friction that sticks, events, and outputs other than
coordinates and their rates (an energy, a branch quantity, an expression).

>>> import lagrangian as lg
>>> m = lg.Model("two carts")
>>> for k in (1, 2):
...     _ = m.add("mass", f"m{k}", f"p{k}", m=0.3 * k)
...     _ = m.add("spring", f"k{k}", ("ground", f"p{k}"), k=40.0)
>>> pruned = prune(m, ["x_p2"], events=())
>>> sorted(pruned.model.components), pruned.dropped["k1"]
(['k2', 'm2'], "joins only nodes the outputs' nodes do not reach (ground and nodes whose motion is prescribed pass nothing on)")
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from ..base.component import GROUND, t
from ..model import Model
from ..base import deferred as _deferred

sp = _deferred.module("sympy", globals())

__all__ = ["Pruned", "prune"]

#: Components that act on the nodes they join and on nothing else (their positions' or angles' coordinates).
POINT_KINDS = frozenset({"mass", "spring", "damper", "force", "central_force", "coulomb_friction", "prescribed_motion"})
ROTOR_KINDS = frozenset({"inertia", "torsion_spring", "rotary_damper", "torque", "prescribed_rotation"})
_PRESCRIBED = frozenset({"prescribed_motion", "prescribed_rotation"})
#: Components without nodes that act on every mass where it is (kept with whatever masses are kept).
FIELD_KINDS = frozenset({"gravity"})
_AXES = "xyz"
_WHY = "joins only nodes the outputs' nodes do not reach (ground and nodes whose motion is prescribed pass nothing on)"


@dataclass
class Pruned:
    """The model of the components the outputs can depend on, and what the whole model has: the components dropped
    (name → why), its coordinates' and its parameters' names (what ``initial=``, ``velocity=`` and ``params=`` of a
    scene may name)."""

    model: Model
    dropped: dict[str, str]
    coordinates: list[str]
    parameters: set[str]


def prune(model: Model, outputs: Sequence[Any], events: Sequence[Any]) -> Pruned | None:
    """``model`` pruned to the components ``outputs`` can depend on, or ``None`` where the graph cannot tell (see
    the module's text) or nothing would be dropped."""
    components = list(model.components.values())
    if events or not components or not _local(components):
        return None
    dim = int(model.options.get("dim", 1))
    held = {c.nodes[0] for c in components if c.kind in _PRESCRIBED}
    nodes = [n for n in model.nodes if n != GROUND and n not in held]
    rotor = {n for c in components if c.kind in ROTOR_KINDS for n in c.nodes}
    names = {n: ([f"theta_{n}"] if n in rotor else [f"{_AXES[i]}_{n}" for i in range(dim)]) for n in nodes}
    seeds = _nodes_of(outputs, names)
    if seeds is None:
        return None
    at: dict[str, list] = {}
    for c in components:
        for n in c.nodes:
            at.setdefault(n, []).append(c)
    reached, frontier, kept = set(seeds), list(seeds), set()
    while frontier:
        for c in at.get(frontier.pop(), []):
            if c.name in kept:
                continue
            kept.add(c.name)
            for n in c.nodes:
                if n != GROUND and n not in reached:
                    reached.add(n)
                    if n not in held:  # a prescribed node passes nothing on; its prescription is kept below
                        frontier.append(n)
    kept |= {c.name for c in components if c.kind in FIELD_KINDS or (c.kind in _PRESCRIBED and c.nodes[0] in reached)}
    if len(kept) == len(components):
        return None
    sub = Model(model.name, registry=model.registry, **model.options)
    for c in components:
        if c.name in kept:
            sub._graph.add(c)  # the component itself: its parameters' symbols and values stay the model's
    sub._changed()
    coordinates = [name for n in nodes for name in names[n]]
    # the names Model.parameter_values gives (its components' symbols for numbers), without assembling the model
    parameters = {s.name for c in components for s in c.values} | {
        s.name for c in components for v in c.params.values() if isinstance(v, sp.Basic) for s in v.free_symbols if s != t}
    return Pruned(sub, {c.name: _WHY for c in components if c.name not in kept}, coordinates, parameters)


def _local(components: list) -> bool:
    """Whether every component is a point-mass kind that acts only on its own nodes: no callable of the state, no
    coordinate in its parameters, no friction that sticks."""
    for c in components:
        if c.kind not in POINT_KINDS | ROTOR_KINDS | FIELD_KINDS or c.state_callables():
            return False
        if c.kind == "coulomb_friction" and (c.params.get("stick_slip") or c.params.get("phase", "smooth") != "smooth"):
            return False
        for v in c.params.values():
            if isinstance(v, (sp.Basic, sp.MatrixBase)) and v.atoms(sp.core.function.AppliedUndef):
                return False
    return True


def _nodes_of(outputs: Sequence[Any], names: dict[str, list[str]]) -> set[str] | None:
    """The nodes whose coordinates ``outputs`` name (``x_p``, ``y_p'``, ``theta_s``), or ``None`` for any other
    output.  ``names``: each node's coordinates."""
    owner = {name: n for n, own in names.items() for name in own}
    seeds = set()
    for output in outputs:
        label = output.strip() if isinstance(output, str) else None
        if label is not None and label.endswith("'"):
            label = label[:-1]
        if label not in owner:
            return None
        seeds.add(owner[label])
    return seeds
