"""Built-in plugin: rotational mechanics about fixed parallel axes.

The ``rotational`` domain gives every rotational node one coordinate, its
angle ``theta_<node>`` (rad, counter-clockwise positive about the common
axis); ``ground`` is the fixed frame, at angle 0.  A node with a prescribed
rotation has no coordinate: its angle is a known function of time.  It is the
one-dimensional translational domain with angles for positions, torques for
forces and moments of inertia for masses:

- ``inertia`` (node): T = ½ J θ̇²
- ``torsion_spring`` (a, b): V = ½ k (θ_b − θ_a − θ₀)²
- ``rotary_damper`` (a, b): D = ½ c (θ̇_b − θ̇_a)²
- ``torque`` (node): generalized force τ(t) on θ
- ``prescribed_rotation`` (node): θ = angle(t)

>>> import lagrangian as lg
>>> m = lg.Model("torsional oscillator")
>>> _ = m.add("inertia", "J1", "disc", J=2)
>>> _ = m.add("torsion_spring", "k1", ("ground", "disc"), k=8)
>>> m.coordinate_names
['theta_disc']
>>> m.equations
[Eq(2*Derivative(theta_disc(t), (t, 2)), -8*theta_disc(t))]
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from lagrangian import (
    Component,
    Contribution,
    Coordinate,
    Domain,
    DomainView,
    Example,
    Incidence,
    Linear,
    LinearContext,
    Load,
    ModelError,
    Network,
    Parameter,
    hookimpl,
)
from lagrangian.base.component import t
from lagrangian.base import deferred as _deferred

sp = _deferred.module("sympy", globals())


@dataclass
class RotationalView(DomainView):
    """Angles of rotational nodes: ``angle(node)`` and ``angular_velocity(node)`` are scalars (``ground``: 0)."""

    angles: dict[str, sp.Expr] = field(default_factory=dict)
    edges: dict[str, tuple[str, str]] = field(default_factory=dict)

    def branch_value(self, key: str) -> sp.Expr:
        """``θ_a − θ_b`` of the branch ``key`` (an edge of the component graph)."""
        a, b = self.edges[key]
        return self.angle(a) - self.angle(b)

    def angle(self, node: str) -> sp.Expr:
        """The angle of ``node`` (a coordinate, a prescribed function of t, or 0 for ``ground``)."""
        return self.angles.get(node, sp.Integer(0))

    def angular_velocity(self, node: str) -> sp.Expr:
        """dθ/dt of ``node``."""
        return self.angle(node).diff(t)


class RotationalDomain(Domain):
    """Rotation about fixed parallel axes: one angle per node."""

    name = "rotational"
    options = {}

    def build(self, network: Network, options: dict[str, Any]) -> RotationalView:
        prescribed = {c.nodes[0]: c for c in network.components if c.role == "across" and c.domain == self.name}
        view = RotationalView()
        view.edges = {k: (d["a"], d["b"]) for _, _, k, d in network.graph.edges(keys=True, data=True)}
        for node in network.nodes:
            if node in prescribed:
                view.angles[node] = prescribed[node].prescribed_angle()
                continue
            coord = Coordinate.named(f"theta_{node}", f"angle of rotational node {node!r}")
            view.coordinates.append(coord)
            view.angles[node] = coord.function
        return view


    def incidence(self, network: Network, options: dict[str, Any]) -> Incidence:
        """The coordinates ``theta_<node>`` and each branch's ``θ_a − θ_b``, in numbers (a prescribed node's branches
        are prescribed)."""
        prescribed = {c.nodes[0] for c in network.components if c.role == "across" and c.domain == self.name}
        return Incidence.of_nodes(network, prescribed, "theta")


class _Rotational(Component):
    domain = "rotational"


class Inertia(_Rotational):
    """Rotor of moment of inertia J about the common axis: T = ½ J θ̇²."""

    kind = "inertia"
    terminals = ("node",)
    parameters = {"J": Parameter("moment of inertia about the axis", unit="kg m²")}

    def contribute(self, ctx) -> Contribution:
        w = ctx.view.angular_velocity(self.nodes[0])
        return Contribution(T=self.J * w**2 / 2)

    def linear(self, ctx: LinearContext) -> Linear | None:
        J = ctx.number(self, "J")
        return None if J is None else Linear(T={(0, 0): J})

    @classmethod
    def example(cls) -> Example:
        return Example("s", {"J": 2}, context=[("torsion_spring", "k", ("ground", "s"), {"k": 3})])


class TorsionSpring(_Rotational):
    """Linear torsion spring (a shaft) between two nodes: V = ½ k (θ_b − θ_a − θ₀)²."""

    distinct_terminals = True

    kind = "torsion_spring"
    parameters = {
        "k": Parameter("torsional stiffness", unit="N m/rad"),
        "rest_angle": Parameter("relative angle θ_b − θ_a at which it is relaxed", default=0, check="real", unit="rad"),
    }

    def contribute(self, ctx) -> Contribution:
        twist = ctx.view.angle(self.nodes[1]) - ctx.view.angle(self.nodes[0]) - self.rest_angle
        return Contribution(V=self.k * twist**2 / 2)

    def linear(self, ctx: LinearContext) -> Linear | None:
        """``½ k (x + θ₀)²`` over the branch ``x = θ_a − θ_b``: ``½ k x²``, the constant torque ``−k θ₀`` of a rest
        angle and the constant ``½ k θ₀²``."""
        k, rest = ctx.number(self, "k"), ctx.number(self, "rest_angle")
        if k is None or rest is None:
            return None
        return Linear(V={(0, 0): k}, load={0: -k * rest} if rest else {}, constant=k * rest * rest / 2)

    @classmethod
    def example(cls) -> Example:
        return Example(("ground", "s"), {"k": 5, "rest_angle": 0.5}, context=[("inertia", "J", "s", {"J": 1})])


class RotaryDamper(_Rotational):
    """Linear viscous rotary damper (a drag cup, bearing friction) between two nodes: D = ½ c (θ̇_b − θ̇_a)²."""

    distinct_terminals = True

    kind = "rotary_damper"
    parameters = {"c": Parameter("rotary damping coefficient", check="nonnegative", unit="N m s/rad")}

    def contribute(self, ctx) -> Contribution:
        rate = ctx.view.angular_velocity(self.nodes[1]) - ctx.view.angular_velocity(self.nodes[0])
        return Contribution(D=self.c * rate**2 / 2)

    def linear(self, ctx: LinearContext) -> Linear | None:
        c = ctx.number(self, "c")
        return None if c is None else Linear(D={(0, 0): c})

    @classmethod
    def example(cls) -> Example:
        return Example(
            ("ground", "s"),
            {"c": 0.4},
            context=[("inertia", "J", "s", {"J": 1}), ("torsion_spring", "k", ("ground", "s"), {"k": 2})],
        )


class Torque(_Rotational):
    """Applied torque on a node (positive in the +θ sense): a number, a SymPy expression of t, or a Python callable of t;
    or an expression of the state too (:func:`lagrangian.coordinate`, :func:`lagrangian.rate`)."""

    kind = "torque"
    terminals = ("node",)
    role = "through"
    parameters = {"tau": Parameter("torque", check="real", shape="signal", unit="N m", state=True, vector=False)}

    def contribute(self, ctx) -> Contribution:
        if isinstance(self.tau, sp.MatrixBase):
            raise ModelError(f"torque {self.name!r}: tau must be a scalar (rotation is about one axis), got {list(self.tau)}.")
        return Contribution(loads=[Load(self.tau, ctx.view.angular_velocity(self.nodes[0]))])

    def linear(self, ctx: LinearContext) -> Linear | None:
        """A torque of time alone: the generalized force ``τ`` on its node's angle."""
        if isinstance(self.tau, sp.MatrixBase) or self.state("tau") or self.signals():
            return None
        return Linear(force={0: 1.0})

    @classmethod
    def example(cls) -> Example:
        return Example(
            "s",
            {"tau": sp.sin(2 * t)},
            context=[("inertia", "J", "s", {"J": 1}), ("torsion_spring", "k", ("ground", "s"), {"k": 2})],
        )


class PrescribedRotation(_Rotational):
    """A node turned along a given ``angle(t)`` (a rheonomic constraint, e.g. a speed-controlled drive); the node has no coordinate."""

    kind = "prescribed_rotation"
    terminals = ("node",)
    role = "across"
    parameters = {"angle": Parameter("angle as a function of t", check="real", shape="signal", unit="rad", vector=False)}

    def prescribed_angle(self) -> sp.Expr:
        if not isinstance(self.angle, sp.Expr) or self.signals():
            raise ModelError(
                f"prescribed_rotation {self.name!r}: the angle must be a scalar SymPy expression of t "
                f"(it is differentiated symbolically), not a Python callable or a vector."
            )
        return self.angle

    def contribute(self, ctx) -> Contribution:
        return Contribution()

    @classmethod
    def example(cls) -> Example:
        return Example(
            "drive",
            {"angle": t / 2},
            context=[("inertia", "J", "s", {"J": 1}), ("torsion_spring", "k", ("drive", "s"), {"k": 2})],
        )


@hookimpl
def register_domains(register):
    register(RotationalDomain())


@hookimpl
def register_component_types(register):
    for cls in (Inertia, TorsionSpring, RotaryDamper, Torque, PrescribedRotation):
        register(cls)


# -- analogies ------------------------------------------------------------------------------------
# Torque–voltage: inertia → inductor, torsion spring → capacitor (C = 1/k), rotary damper →
# resistor, torque → voltage source, prescribed rotation → current source; angular velocity ↔ loop
# current.  Torque–current: inertia → capacitor, torsion spring → inductor (L = 1/k), damper →
# resistor (R = 1/c), torque → current source, prescribed rotation → voltage source; angular
# velocity ↔ node voltage.  The same as the translational analogies, for shafts.

from lagrangian.analogy import Analogy, AnalogyError, Element  # noqa: E402


def _relaxed_at_zero(spring) -> None:
    if spring.rest_angle != 0:
        raise AnalogyError(
            f"torsion_spring {spring.name!r} has a rest angle; its analogue is linear about zero: "
            f"measure angles from the relaxed configuration (rest_angle=0)."
        )


def _rate_from_zero(motion) -> sp.Expr:
    angle = motion.prescribed_angle()
    if angle.subs(t, 0) != 0:
        raise AnalogyError(f"prescribed_rotation {motion.name!r} starts at {angle.subs(t, 0)}, not 0: shift the angles.")
    return angle.diff(t)


def _damping(damper, invert: bool):
    if damper.c == 0:
        raise AnalogyError(f"rotary_damper {damper.name!r} has c = 0 and contributes nothing: remove it.")
    return 1 / damper.c if invert else damper.c


TORQUE_VOLTAGE = {
    "inertia": lambda c, p: [Element("inductor", f"L_{c.name}", p.branch(), {"L": c.J})],
    "torsion_spring": lambda c, p: (_relaxed_at_zero(c), [Element("capacitor", f"C_{c.name}", p.branch(), {"C": 1 / c.k})])[1],
    "rotary_damper": lambda c, p: [Element("resistor", f"R_{c.name}", p.branch(), {"R": _damping(c, False)})],
    "torque": lambda c, p: [Element("voltage_source", f"V_{c.name}", p.branch()[::-1], {"E": c.tau}, branch=None)],
    "prescribed_rotation": lambda c, p: [
        Element("current_source", f"I_{c.name}", p.branch(), {"I": _rate_from_zero(c)}, branch=None)
    ],
}

TORQUE_CURRENT = {
    "inertia": lambda c, p: [Element("capacitor", f"C_{c.name}", p.branch(), {"C": c.J})],
    "torsion_spring": lambda c, p: (_relaxed_at_zero(c), [Element("inductor", f"L_{c.name}", p.branch(), {"L": 1 / c.k})])[1],
    "rotary_damper": lambda c, p: [Element("resistor", f"R_{c.name}", p.branch(), {"R": _damping(c, True)})],
    "torque": lambda c, p: [Element("current_source", f"I_{c.name}", p.branch()[::-1], {"I": c.tau}, branch=None)],
    "prescribed_rotation": lambda c, p: [
        Element("voltage_source", f"V_{c.name}", p.branch(), {"E": _rate_from_zero(c)}, branch=None)
    ],
}


@hookimpl
def register_analogies(register):
    register(Analogy("torque-voltage", "rotational", "electrical", dual=True, options={"formulation": "charge"},
                     doc="inertia ↔ inductor, torsion spring ↔ capacitor, rotary damper ↔ resistor, torque ↔ voltage"))
    register(Analogy("torque-current", "rotational", "electrical", dual=False, options={"formulation": "flux"},
                     doc="inertia ↔ capacitor, torsion spring ↔ inductor, rotary damper ↔ conductance, torque ↔ current"))


@hookimpl
def register_analogues(register):
    for analogy, table in (("torque-voltage", TORQUE_VOLTAGE), ("torque-current", TORQUE_CURRENT)):
        for kind, build in table.items():
            register(kind, analogy, build)
