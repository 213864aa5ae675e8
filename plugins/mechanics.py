"""Built-in plugin: translational mechanics.

The ``mechanical`` domain gives every mechanical node a position in 1, 2 or 3
dimensions (model option ``dim``); ``ground`` is the fixed origin.  Node
coordinates are named ``x_<node>`` (and ``y_<node>``, ``z_<node>``).  A node
with a prescribed motion has no coordinate: its position is a known function
of time (a rheonomic constraint).

>>> import lagrangian as lg
>>> m = lg.Model("pendulum-free", dim=2)
>>> _ = m.add("mass", "m1", "bob", m=1)
>>> _ = m.add("gravity", "g", g=9.81)
>>> m.coordinate_names
['x_bob', 'y_bob']
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from typing import Any

from lagrangian import (
    UnknownNameError,
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
    Option,
    Parameter,
    Potential,
    Shape,
    dot,
    hookimpl,
    rate,
)
from lagrangian.base.component import t
from lagrangian.derive import time_derivative
from lagrangian.plugins import drawing as _drawing
from lagrangian.plugins.couplings import Constraint, Gear, RackAndPinion, VelocityConstraint
from lagrangian.base import deferred as _deferred

sp = _deferred.module("sympy", globals())

AXES = "xyz"


@dataclass
class MechanicalView(DomainView):
    """Positions of mechanical nodes: ``position(node)`` and ``velocity(node)`` are ``dim × 1`` matrices."""

    dim: int = 1
    positions: dict[str, sp.Matrix] = field(default_factory=dict)
    edges: dict[str, tuple[str, str]] = field(default_factory=dict)
    poses: dict[str, Any] = field(default_factory=dict)
    bodies: dict[str, Any] = field(default_factory=dict)
    #: the springs, dampers and other elements acting between two points (drawn as links between them)
    links: set[str] = field(default_factory=set)

    def pose(self, body: str):
        """Rotation, origin, angular velocity (and planar angle) of a rigid body (see the multibody plugin)."""
        if body not in self.poses:
            raise UnknownNameError("rigid body", body, [b for b in self.poses if b != "ground"])
        return self.poses[body]

    def branch_meaning(self, key: str, rate: bool = False) -> str:
        """``"x_a − x_b of k1 [m]"`` (its rate in m/s)."""
        return f"x_a − x_b of {key} [{'m/s' if rate else 'm'}]"

    def branch_value(self, key: str) -> sp.Expr:
        """``x_a − x_b`` of the branch ``key`` (one dimension only)."""
        if self.dim != 1:
            raise ModelError("branch quantities of mechanical branches are defined in one dimension only (dim=1).")
        a, b = self.edges[key]
        return self.position(a)[0] - self.position(b)[0]

    def position(self, node: str) -> sp.Matrix:
        if node in self.positions:
            return self.positions[node]
        body, _, point = node.partition(".")
        if point and body in self.bodies:  # a point of a rigid body: its origin plus the rotated offset
            offsets = self.bodies[body].point_offsets(self.dim)
            if point not in offsets:
                raise UnknownNameError(f"point of body {body!r}", point, offsets)
            from lagrangian.plugins.multibody import transform

            pose = self.poses[body]
            self.positions[node] = transform(pose.p, pose.R, offsets[point])
            return self.positions[node]
        if node == "ground":
            return sp.zeros(self.dim, 1)
        raise UnknownNameError("mechanical node", node, self.positions)

    def velocity(self, node: str) -> sp.Matrix:
        return sp.Matrix([time_derivative(e, t) for e in self.position(node)])

    def shapes(self) -> list[Shape]:
        """The mechanism in space, for an animation (:func:`lagrangian.plugins.drawing.shapes`)."""
        return _drawing.shapes(self)


class MechanicalDomain(Domain):
    """Point positions in 1, 2 or 3 dimensions."""

    name = "mechanical"
    options = {
        "dim": Option(1, "spatial dimension of mechanical nodes", choices=(1, 2, 3)),
        "dynamics": Option("auto", "rigid-body trees: 'closed' (closed-form equations), 'recursive' (the articulated-"
                           "body algorithm) or 'auto' (recursive from lagrangian.plugins.multibody.RECURSIVE_FROM joint "
                           "coordinates)", choices=("auto", "closed", "recursive")),
    }

    def build(self, network: Network, options: dict[str, Any]) -> MechanicalView:
        dim = options["dim"]
        prescribed = {c.nodes[0]: c for c in network.components if c.role == "across"}
        view = MechanicalView(dim=dim)
        view.edges = {k: (d["a"], d["b"]) for _, _, k, d in network.graph.edges(keys=True, data=True)}
        view.links = {c.name for c in network.components if len(c.nodes) == 2 and not getattr(c, "multibody", False)}
        if any(getattr(c, "multibody", False) for c in network.components):
            from lagrangian.plugins.multibody import build_kinematics

            build_kinematics(network, view, options.get("dynamics", "auto"))
        for node in network.nodes:
            if node in view.positions:  # a body, or a point of one
                if node in prescribed:
                    raise ModelError(f"node {node!r} belongs to a rigid body: drive its joint instead of prescribing its motion.")
                continue
            if node in prescribed:
                view.positions[node] = prescribed[node].prescribed_position(dim)
                continue
            coords = [Coordinate.named(f"{AXES[i]}_{node}", f"{AXES[i]} position of node {node!r}") for i in range(dim)]
            view.coordinates.extend(coords)
            view.positions[node] = sp.Matrix([c.function for c in coords])
        return view


    def incidence(self, network: Network, options: dict[str, Any]) -> Incidence | None:
        """In one dimension, without rigid bodies: the coordinates ``x_<node>`` and each branch's ``x_a − x_b``, in
        numbers (a prescribed node's branches are prescribed)."""
        if options["dim"] != 1 or any(getattr(c, "multibody", False) for c in network.components):
            return None
        return Incidence.of_nodes(network, {c.nodes[0] for c in network.components if c.role == "across"}, "x")


def _one_axis(ctx: LinearContext) -> bool:
    """Whether the model is one-dimensional, where the numeric assembly reads mechanical branches."""
    return ctx.options.get("dim", 1) == 1


def _vector(value: Any, dim: int, component: Component, pname: str) -> sp.Matrix:
    """A parameter as a ``dim × 1`` matrix: scalars are accepted in one dimension."""
    if isinstance(value, sp.MatrixBase):
        if value.shape != (dim, 1):
            raise ModelError(
                f"{component.kind} {component.name!r}: parameter {pname!r} has {value.shape[0]} entries "
                f"but the model's mechanical dimension is {dim}."
            )
        return sp.Matrix(value)
    if dim != 1:
        raise ModelError(
            f"{component.kind} {component.name!r}: parameter {pname!r} must be a vector of {dim} entries "
            f"in a {dim}-dimensional model (got the scalar {value})."
        )
    return sp.Matrix([value])


def _half_square(c: sp.Expr, e: sp.Expr) -> sp.Expr:
    """``½ c e²``.  For a sum ``e`` the product is left as built: multiplied out, SymPy would evaluate ``e²`` again
    and ask each term of a two-term sum whether it is infinite (about 1 ms a spring or damper of a chain, half of
    assembling it).  Sums and derivatives of it evaluate as usual."""
    if e.is_Add:
        return sp.Mul(sp.Mul(sp.Rational(1, 2), c), sp.Pow(e, 2, evaluate=False), evaluate=False)
    return c * e**2 / 2


class Mass(Component):
    """Point mass: T = ½ m |v|²."""

    kind = "mass"
    domain = "mechanical"
    terminals = ("node",)
    parameters = {"m": Parameter("mass", unit="kg")}

    @property
    def gravitational_mass(self) -> tuple[str, sp.Expr]:
        """``(node, m)``: what uniform gravity acts on."""
        return self.nodes[0], self.m

    def contribute(self, ctx) -> Contribution:
        v = ctx.view.velocity(self.nodes[0])
        return Contribution(T=sp.Mul(sp.Rational(1, 2), self.m, sp.Add(*[e**2 for e in v])))  # ½ m v·v

    def linear(self, ctx: LinearContext) -> Linear | None:
        m = ctx.number(self, "m")
        return Linear(T={(0, 0): m}) if m is not None and _one_axis(ctx) else None

    @classmethod
    def example(cls) -> Example:
        return Example("p", {"m": 2}, context=[("spring", "k", ("ground", "p"), {"k": 3})])


@functools.cache
def _spring_energy() -> sp.Expr:
    """A 1-D spring's energy ``½ k e² + ¼ β e⁴`` over its branch ``x = x_a − x_b``, whose extension
    ``x_b − x_a − ℓ₀`` is ``−(x + ℓ₀)``: one expression for every spring (``p0, p1, p2`` = ``k, ℓ₀, β``)."""
    (x,), (k, rest, beta) = Potential.placeholders(1, 3)
    e = x + rest
    return k * e**2 / 2 + beta * e**4 / 4


class Spring(Component):
    """Spring along the line between its nodes: V = ½ k e² + ¼ β e⁴ for its extension e = |r_b − r_a| − ℓ₀.

    In one dimension the signed extension ``x_b − x_a − ℓ₀`` is used; with
    ``rest_length = 0`` (the default) the spring is a zero-length spring
    ``V = ½ k |r_b − r_a|²`` in any dimension.  ``beta`` (default 0: linear)
    adds a cubic force ``β e³`` to the linear ``k e``: hardening for
    ``β > 0``, softening for ``β < 0`` — a Duffing oscillator, or the
    bonds of a Fermi–Pasta–Ulam–Tsingou β chain.

    >>> import lagrangian as lg
    >>> m = lg.Model("duffing")
    >>> _ = m.add("mass", "m", "p", m=0.3)
    >>> _ = m.add("spring", "k", ("ground", "p"), k=40, beta=2e4)
    >>> m.equations[0]
    Eq(0.3*Derivative(x_p(t), (t, 2)), -20000.0*x_p(t)**3 - 40*x_p(t))
    """

    distinct_terminals = True

    kind = "spring"
    domain = "mechanical"
    parameters = {
        "k": Parameter("stiffness", unit="N/m"),
        # its zero removes the square root of the spring's length: it decides the form, so it stays a number
        "rest_length": Parameter("rest length", default=0, check="nonnegative", unit="m", symbolic=False),
        "beta": Parameter("cubic stiffness: the force β e³ added to k e (hardening > 0, softening < 0)", default=0,
                          check="real", unit="N/m^3"),
    }

    def extension(self, ctx) -> sp.Expr:
        d = ctx.view.position(self.nodes[1]) - ctx.view.position(self.nodes[0])
        if ctx.view.dim == 1:
            return d[0] - self.rest_length
        if self.rest_length == 0:
            return sp.sqrt(dot(d, d))
        return sp.sqrt(dot(d, d)) - self.rest_length

    def contribute(self, ctx) -> Contribution:
        if ctx.view.dim > 1 and self.rest_length == 0:
            d = ctx.view.position(self.nodes[1]) - ctx.view.position(self.nodes[0])
            square = dot(d, d)
            quartic = self.beta * square**2 / 4 if self.beta != 0 else 0
            return Contribution(V=self.k * square / 2 + quartic)
        e = self.extension(ctx)
        quartic = self.beta * sp.Pow(e, 4, evaluate=False) / 4 if self.beta != 0 else 0
        return Contribution(V=_half_square(self.k, e) + quartic)

    def linear(self, ctx: LinearContext) -> Linear | None:
        """``½ k (x + ℓ₀)²`` in numbers over the branch ``x = x_a − x_b``: ``½ k x²``, the constant force ``−k ℓ₀``
        of a rest length and the constant ``½ k ℓ₀²``.  With a ``beta`` given (even 0, which ``params=`` may
        change: a cubic force), the whole energy as a :class:`~lagrangian.Potential` of the branch, which only the
        numeric runs of large models take (the linear analyses refuse it)."""
        k = ctx.number(self, "k")
        if k is None or not _one_axis(ctx):
            return None
        rest = ctx.number(self, "rest_length")
        if rest is None:
            return None
        if "beta" not in self._given:
            return Linear(V={(0, 0): k}, load={0: -k * rest} if rest else {}, constant=k * rest * rest / 2)
        beta = ctx.number(self, "beta")
        if beta is None:
            return None
        return Linear(potential=Potential(_spring_energy(), (k, rest, beta)))

    @classmethod
    def example(cls) -> Example:
        return Example(("ground", "p"), {"k": 5, "rest_length": 0.5}, context=[("mass", "m", "p", {"m": 1})])


class Damper(Component):
    """Linear viscous damper along the line between its nodes: D = ½ c (d/dt |r_b − r_a|)²."""

    distinct_terminals = True

    kind = "damper"
    domain = "mechanical"
    parameters = {"c": Parameter("damping coefficient", unit="N s/m", check="nonnegative")}

    def contribute(self, ctx) -> Contribution:
        d = ctx.view.position(self.nodes[1]) - ctx.view.position(self.nodes[0])
        dv = sp.Matrix([time_derivative(e, t) for e in d])
        rate = dv[0] if ctx.view.dim == 1 else dot(d, dv) / sp.sqrt(dot(d, d))
        return Contribution(D=_half_square(self.c, rate))

    def linear(self, ctx: LinearContext) -> Linear | None:
        c = ctx.number(self, "c")
        return Linear(D={(0, 0): c}) if c is not None and _one_axis(ctx) else None

    @classmethod
    def example(cls) -> Example:
        return Example(
            ("ground", "p"),
            {"c": 0.4},
            context=[("mass", "m", "p", {"m": 1}), ("spring", "k", ("ground", "p"), {"k": 2})],
        )


#: The parameters of friction with a stick–slip option (coulomb_friction, joint_friction).
STICK_SLIP = {
    "F_s": Parameter("static friction: the largest force sticking holds (stick_slip; default F_c)", default=None,
                     check="nonnegative", unit="N"),
    "stick_slip": Parameter("stick and slip (event-based, lagrangian.stick_slip.simulate) instead of the smooth "
                            "regularization", default=False, shape="flag"),
    "phase": Parameter("'smooth', or the phase stick_slip.simulate runs it in: 'stick', 'slip+', 'slip-'",
                       default="smooth", shape="name"),
}
PHASES = ("smooth", "stick", "slip+", "slip-")


def _check_phase(kind: str, name: str, params) -> None:
    phase = params.get("phase", "smooth")
    if phase not in PHASES:
        raise ModelError(f"{kind} {name!r}: phase is one of {', '.join(map(repr, PHASES))}, got {phase!r:.40}.")
    if params.get("F_s") is not None and not params.get("stick_slip", False):
        raise ModelError(f"{kind} {name!r}: F_s (the largest force sticking holds) is for stick_slip=True: add "
                         f"stick_slip=True to stick and slip, or drop F_s for the smooth friction (which never "
                         f"sticks).")


def friction_contribution(comp: Component, rate) -> Contribution:
    """Dry friction on ``rate`` in the component's phase: smooth (``−F_c tanh(rate/v_s)``), sliding (``∓F_c``), or
    stuck (``rate = 0``, a constraint on velocities whose multiplier is the friction force)."""
    if comp.phase == "stick":
        return Contribution(velocity_constraints=[rate])
    if comp.phase in ("slip+", "slip-"):
        return Contribution(loads=[Load(-comp.F_c if comp.phase == "slip+" else comp.F_c, rate)])
    if comp.stick_slip:
        raise ModelError(f"{comp.kind} {comp.name!r} sticks and slips (stick_slip=True): run the model with "
                         f"lagrangian.stick_slip.simulate(model, t_end, ...), or drop stick_slip for the smooth "
                         f"(regularized) friction Model.simulate runs.")
    return Contribution(loads=[Load(-comp.F_c * sp.tanh(rate / comp.v_s), rate)])


class CoulombFriction(Component):
    """Dry (Coulomb) friction between two nodes in one dimension, regularized: the force ``−F_c tanh(v / v_s)`` on
    the relative velocity ``v = ẋ_b − ẋ_a``, with ``F_c = μ N`` the sliding friction force and ``v_s`` the speed
    below which it fades (smooth, so any integrator runs it; the smaller ``v_s``, the stiffer the equations once the
    motion stops, where an implicit method such as ``"Radau"`` or ``"LSODA"`` takes far fewer steps).  A block held
    by a force ``F < F_c`` creeps at ``v_s atanh(F/F_c)`` instead of sticking.  With ``stick_slip=True`` it sticks
    and slips instead (event-based), run by :func:`lagrangian.stick_slip.simulate`: sliding, the force is ``∓F_c``;
    stopped, the nodes move together for as long as the force that takes stays within ``F_s`` (default ``F_c``).
    Its power (``Model.load_power``) is the rate it turns energy into heat.

    >>> import lagrangian as lg
    >>> m = lg.Model("block")
    >>> _ = m.add("mass", "m1", "p", m=0.3)
    >>> _ = m.add("coulomb_friction", "f", ("ground", "p"), F_c=0.6, v_s=1e-3)
    >>> m.equations
    [Eq(0.3*Derivative(x_p(t), (t, 2)), -0.6*tanh(1000.0*Derivative(x_p(t), t)))]
    """

    distinct_terminals = True

    kind = "coulomb_friction"
    domain = "mechanical"
    parameters = {"F_c": Parameter("sliding friction force μ N", unit="N", check="nonnegative"),
                  "v_s": Parameter("speed below which the friction fades (regularization)", default=1e-4, unit="m/s"),
                  **STICK_SLIP}

    def __init__(self, name, nodes, params):
        _check_phase(self.kind, name, params)
        super().__init__(name, nodes, params)

    def sliding_rate(self, ctx):
        """The relative velocity the friction opposes (the stick–slip driver's contract, with ``phase``, ``F_s``)."""
        if ctx.view.dim != 1:
            raise ModelError(f"coulomb_friction {self.name!r} acts along one dimension (Model(dim=1)); in a plane "
                             f"use joint_friction on a joint's coordinate, or write the force of the state with "
                             f"lagrangian.rate(...).")
        return ctx.view.velocity(self.nodes[1])[0] - ctx.view.velocity(self.nodes[0])[0]

    def contribute(self, ctx) -> Contribution:
        return friction_contribution(self, self.sliding_rate(ctx))

    @classmethod
    def example(cls) -> Example:
        return Example(("ground", "p"), {"F_c": 0.3, "v_s": 0.05},
                       context=[("mass", "m", "p", {"m": 1}), ("spring", "k", ("ground", "p"), {"k": 2})])


class Gravity(Component):
    """Uniform gravity acting on every mass of the model: V = −Σ m g (u · r).

    ``direction`` defaults to minus the last axis (−x in 1-D, −y in 2-D, −z in 3-D).
    """

    kind = "gravity"
    domain = "mechanical"
    terminals = ()
    parameters = {
        "g": Parameter("gravitational acceleration", default=9.81, unit="m/s²"),
        "direction": Parameter("direction of gravity (normalized)", default=None, shape="vector", symbolic=False),
    }

    def field_acceleration(self, dim: int) -> sp.Matrix:
        """The field's acceleration ``g u`` (``dim × 1``): a uniform field acting on every gravitational mass (what
        recursive rigid-body dynamics take as the ground's acceleration, ``−g u``)."""
        return self._direction(dim) * self.g

    def _direction(self, dim: int) -> sp.Matrix:
        if self.direction is None:
            u = sp.zeros(dim, 1)
            u[dim - 1] = -1
        else:
            u = _vector(self.direction, dim, self, "direction")
            norm = sp.sqrt(dot(u, u))
            if norm == 0:
                raise ModelError(f"gravity {self.name!r}: direction must not be the zero vector.")
            u = u / norm
        return u

    def contribute(self, ctx) -> Contribution:
        dim = ctx.view.dim
        u = self._direction(dim)
        terms = []  # summed once: adding term by term rebuilds the sum each time (quadratic in the masses)
        for comp in ctx.components:
            held = getattr(comp, "gravitational_mass", None)
            if held is not None:
                node, mass = held
                terms.append(-mass * self.g * sp.Add(*[a * b for a, b in zip(u, ctx.view.position(node)) if a != 0]))
        return Contribution(V=sp.Add(*terms))  # −Σ m g (u · r)

    def linear(self, ctx: LinearContext) -> Linear | None:
        """In one dimension, a constant force ``m g u`` on the coordinate of each mass (``V = −Σ m g u x``), over
        the masses' branches; ``None`` where a mass or ``g`` has no number."""
        g = ctx.number(self, "g")
        if g is None or not _one_axis(ctx):
            return None
        u = -1.0 if self.params.raw("direction") is None else float(self._direction(1)[0])  # default: −x
        branches, load = [], {}
        for comp in ctx.components.values():
            mass = ctx.number(comp, "m") if isinstance(comp, Mass) else None  # a point mass's, read as a number
            if mass is None:
                held = getattr(comp, "gravitational_mass", None)
                if held is None:
                    continue
                mass = held[1]
            if not isinstance(mass, (int, float)) and not getattr(mass, "is_number", False):
                return None
            load[len(branches)] = float(mass) * g * u
            branches.append((comp.name, 0))
        return Linear(branches=tuple(branches), load=load)

    @classmethod
    def example(cls) -> Example:
        return Example((), {"g": 9.81}, context=[("mass", "m", "p", {"m": 1}), ("spring", "k", ("ground", "p"), {"k": 2})])


class Force(Component):
    """Applied force on a node: a number, a SymPy expression of t, or a Python callable of t; or an expression of the
    state too (coordinates and rates, :func:`lagrangian.coordinate` and :func:`lagrangian.rate`): drag, a
    controller's feedback.

    >>> import lagrangian as lg
    >>> m = lg.Model("drag")
    >>> _ = m.add("mass", "m1", "p", m=0.3)
    >>> _ = m.add("force", "drag", "p", F=-0.05 * lg.rate("x_p") ** 3)
    >>> m.equations
    [Eq(0.3*Derivative(x_p(t), (t, 2)), -0.05*Derivative(x_p(t), t)**3)]
    """

    kind = "force"
    domain = "mechanical"
    terminals = ("node",)
    role = "through"
    parameters = {"F": Parameter("force (vector in 2-D/3-D)", check="real", shape="signal", unit="N", state=True)}

    def contribute(self, ctx) -> Contribution:
        F = _vector(self.F, ctx.view.dim, self, "F")
        return Contribution(loads=[Load(F, ctx.view.velocity(self.nodes[0]))])

    def linear(self, ctx: LinearContext) -> Linear | None:
        """A force of time alone on one axis: the generalized force ``F`` on its node's coordinate."""
        if not _one_axis(ctx) or isinstance(self.F, sp.MatrixBase) or self.state("F") or self.signals():
            return None
        return Linear(force={0: 1.0})

    @classmethod
    def example(cls) -> Example:
        return Example(
            "p",
            {"F": sp.sin(2 * t)},
            context=[("mass", "m", "p", {"m": 1}), ("spring", "k", ("ground", "p"), {"k": 2})],
        )


class GeneralizedForce(Component):
    """A generalized force ``Q`` on one coordinate — a force on a position, a torque on an angle — as a number, a
    signal of t, or an expression of the state: a controller's feedback ``−K θ − D θ̇`` on a joint, a drag on a
    slider.  Its virtual power is ``Q q̇``; it is compiled with the rest of the model and its power
    (``Model.load_power``) is the work it does per unit time.

    >>> import lagrangian as lg
    >>> m = lg.Model("pd pendulum", dim=2)
    >>> _ = m.add("link", "l1", "l1", points={"end": (0.7, 0)})
    >>> _ = m.add("mass", "bob", "l1.end", m=0.3)
    >>> _ = m.add("revolute", "j1", ("ground", "l1"))
    >>> th = lg.coordinate("theta_j1")
    >>> _ = m.add("generalized_force", "pd", coordinate="theta_j1", Q=-2.0 * th - 0.4 * lg.rate("theta_j1"))
    >>> m.equations
    [Eq(0.147*Derivative(theta_j1(t), (t, 2)), -2.0*theta_j1(t) - 0.4*Derivative(theta_j1(t), t))]
    """

    kind = "generalized_force"
    domain = "mechanical"
    terminals = ()
    parameters = {
        "coordinate": Parameter("the coordinate it acts on (one of Model.coordinate_names)", shape="name"),
        "Q": Parameter("generalized force (N on a position, N m on an angle)", check="real", shape="signal", state=True),
    }

    def contribute(self, ctx) -> Contribution:
        if isinstance(self.Q, sp.MatrixBase):
            raise ModelError(f"generalized_force {self.name!r}: Q is one number or expression (it acts on one "
                             f"coordinate), got {list(self.Q)}.")
        return Contribution(loads=[Load(self.Q, rate(self.coordinate))])

    @classmethod
    def example(cls) -> Example:
        return Example((), {"coordinate": "x_p", "Q": -0.5 * rate("x_p") - sp.sin(t)},
                       context=[("mass", "m", "p", {"m": 1}), ("spring", "k", ("ground", "p"), {"k": 2})])


class CentralForce(Component):
    """Central attraction between two nodes, of magnitude ``k / rⁿ`` (``r``: their distance).

    ``V = −k / ((n − 1) rⁿ⁻¹)`` for ``n ≠ 1`` and ``V = k ln r`` for ``n = 1``;
    ``n = 2`` (the default) is Newtonian gravitation or Coulomb attraction,
    ``V = −k / r`` (``k = G m₁ m₂``); ``k < 0`` repels.  For a zero-length
    linear spring (``n = −1``) use ``spring``.  Singular where the nodes meet.

    >>> import lagrangian as lg
    >>> m = lg.Model("kepler", dim=2)
    >>> _ = m.add("mass", "planet", "p", m=1)
    >>> _ = m.add("central_force", "sun", ("ground", "p"), k=4)
    >>> m.potential_energy
    -4/sqrt(x_p(t)**2 + y_p(t)**2)
    """

    distinct_terminals = True

    kind = "central_force"
    domain = "mechanical"
    parameters = {
        "k": Parameter("strength: the force is k / rⁿ towards the other node", check="nonzero", unit="N m^n"),
        "n": Parameter("exponent of the distance in the force law", default=2, check="real", symbolic=False),
    }

    def contribute(self, ctx) -> Contribution:
        if ctx.view.dim == 1:
            raise ModelError(
                f"central_force {self.name!r}: a central force needs a plane or space (Model(..., dim=2) or dim=3); "
                f"in one dimension use a spring or a force."
            )
        d = ctx.view.position(self.nodes[1]) - ctx.view.position(self.nodes[0])
        if all(sp.sympify(e) == 0 for e in d):  # the same point by construction (structurally 0), not by values
            raise ModelError(
                f"central_force {self.name!r}: its nodes {self.nodes[0]!r} and {self.nodes[1]!r} are the same point, so "
                f"their distance is 0 and the force k/rⁿ infinite at every instant. Join two different nodes."
            )
        r = sp.sqrt(dot(d, d))
        n = sp.sympify(self.n)
        if n.is_Float:  # 3.0 → 3, 2.5 → 5/2: exact exponents keep the algebra exact
            n = sp.nsimplify(n)
        if n == 1:
            return Contribution(V=self.k * sp.log(r))
        return Contribution(V=-self.k / ((n - 1) * r ** (n - 1)))

    @classmethod
    def example(cls) -> Example:
        return Example(("ground", "p"), {"k": -0.5, "n": 2}, context=[("mass", "m", "p", {"m": 1})],
                       options={"dim": 2})


class PrescribedMotion(Component):
    """A node moved along a given path ``position(t)`` (a rheonomic constraint); the node has no coordinate."""

    kind = "prescribed_motion"
    domain = "mechanical"
    terminals = ("node",)
    role = "across"
    parameters = {"position": Parameter("position as a function of t (vector in 2-D/3-D)", check="real", shape="signal", unit="m")}

    def prescribed_position(self, dim: int) -> sp.Matrix:
        if not isinstance(self.position, (sp.Expr, sp.MatrixBase)) or self.signals():
            raise ModelError(
                f"prescribed_motion {self.name!r}: the position must be a SymPy expression of t "
                f"(it is differentiated symbolically), not a Python callable."
            )
        return _vector(self.position, dim, self, "position")

    def contribute(self, ctx) -> Contribution:
        return Contribution()

    @classmethod
    def example(cls) -> Example:
        return Example(
            "support",
            {"position": t / 2},
            context=[("mass", "m", "p", {"m": 1}), ("spring", "k", ("support", "p"), {"k": 2})],
        )


@hookimpl
def register_domains(register):
    register(MechanicalDomain())


@hookimpl
def register_component_types(register):
    for cls in (Mass, Spring, Damper, CoulombFriction, Gravity, Force, GeneralizedForce, Constraint,
                VelocityConstraint, Gear, RackAndPinion, CentralForce, PrescribedMotion):
        register(cls)


# -- analogies ------------------------------------------------------------------------------------
# Force–voltage: mass → inductor, spring → capacitor (C = 1/k), damper → resistor, force → voltage
# source, prescribed motion → current source; velocity ↔ loop current, displacement ↔ charge.
# Force–current: mass → capacitor, spring → inductor (L = 1/k), damper → resistor (R = 1/c),
# force → current source, prescribed motion → voltage source; velocity ↔ node voltage,
# displacement ↔ flux linkage.  Builders get the target nodes of each branch from ``ports``.

from lagrangian.analogy import Analogy, AnalogyError, Element  # noqa: E402


def _no_rest_length(spring) -> None:
    if spring.rest_length != 0:
        raise AnalogyError(
            f"spring {spring.name!r} has a rest length; its analogue is a linear element about zero: "
            f"measure positions from the rest configuration (rest_length=0)."
        )
    beta = spring.params.get("beta", 0)
    if sp.sympify(getattr(spring, "values", {}).get(beta, beta)).is_zero is not True:  # (a number given stands
        # for a symbol here; sp.Float(0.0) != 0 in SymPy)
        raise AnalogyError(
            f"spring {spring.name!r} has a cubic stiffness (beta); its analogue would be a nonlinear capacitor or "
            f"inductor, which the circuits plugin does not have: map the linear model (beta=0)."
        )


def _starts_at_zero(motion) -> sp.Expr:
    X = motion.prescribed_position(1)[0]
    if X.subs(t, 0) != 0:
        raise AnalogyError(
            f"prescribed_motion {motion.name!r} starts at {X.subs(t, 0)}, not 0: its analogue source integrates "
            f"from zero; shift the coordinates so that it starts at 0."
        )
    return X.diff(t)


def _damping(damper, invert: bool):
    if damper.c == 0:
        raise AnalogyError(f"damper {damper.name!r} has c = 0 and contributes nothing: remove it.")
    return 1 / damper.c if invert else damper.c


def _weight(mass, ports) -> sp.Expr:
    """The total 1-D gravitational force on a mass from every gravity component of the model."""
    total = sp.Integer(0)
    for g in ports.model.components.values():
        if isinstance(g, Gravity):
            u = -1 if g.direction is None else sp.sign(_vector(g.direction, 1, g, "direction")[0])
            total += mass.m * g.g * u
    return total


def _mass_force_voltage(mass, ports) -> list:
    """An inductor, in series with a voltage source for its weight when the model has gravity."""
    a, b = ports.branch()
    weight = _weight(mass, ports)
    if weight == 0:
        return [Element("inductor", f"L_{mass.name}", (a, b), {"L": mass.m})]
    mid = f"{a}_{mass.name}"
    return [
        Element("inductor", f"L_{mass.name}", (a, mid), {"L": mass.m}),
        Element("voltage_source", f"V_{mass.name}_weight", (b, mid), {"E": weight}, branch=None),
    ]


def _source(force) -> Any:
    """A force's value as the analogue's source: a signal of time (a Python callable stays one); a force of the state
    would be a controlled source, which the analogies do not map."""
    held = force.state("F") or [str(f) for f in force.state_callables()]
    if held:
        raise AnalogyError(f"force {force.name!r} depends on the state ({', '.join(map(str, held))}): its analogue "
                           f"would be a controlled source, which the analogies do not map. Map the model without it, "
                           f"or give the force as a function of t.")
    return force.given("F")


def _mass_force_current(mass, ports) -> list:
    """A capacitor, with a current source for its weight in parallel when the model has gravity."""
    a, b = ports.branch()
    weight = _weight(mass, ports)
    out = [Element("capacitor", f"C_{mass.name}", (a, b), {"C": mass.m})]
    if weight != 0:
        out.append(Element("current_source", f"I_{mass.name}_weight", (b, a), {"I": weight}, branch=None))
    return out


FORCE_VOLTAGE = {
    "mass": _mass_force_voltage,
    "spring": lambda c, p: (_no_rest_length(c), [Element("capacitor", f"C_{c.name}", p.branch(), {"C": 1 / c.k})])[1],
    "damper": lambda c, p: [Element("resistor", f"R_{c.name}", p.branch(), {"R": _damping(c, False)})],
    "force": lambda c, p: [Element("voltage_source", f"V_{c.name}", p.branch()[::-1], {"E": _source(c)}, branch=None)],
    "prescribed_motion": lambda c, p: [
        Element("current_source", f"I_{c.name}", p.branch(), {"I": _starts_at_zero(c)}, branch=None)
    ],
    "gravity": lambda c, p: [],  # carried by each mass's analogue (_weight)
}

FORCE_CURRENT = {
    "mass": _mass_force_current,
    "spring": lambda c, p: (_no_rest_length(c), [Element("inductor", f"L_{c.name}", p.branch(), {"L": 1 / c.k})])[1],
    "damper": lambda c, p: [Element("resistor", f"R_{c.name}", p.branch(), {"R": _damping(c, True)})],
    "force": lambda c, p: [Element("current_source", f"I_{c.name}", p.branch()[::-1], {"I": _source(c)}, branch=None)],
    "prescribed_motion": lambda c, p: [
        Element("voltage_source", f"V_{c.name}", p.branch(), {"E": _starts_at_zero(c)}, branch=None)
    ],
    "gravity": lambda c, p: [],  # carried by each mass's analogue (_weight)
}


@hookimpl
def register_analogies(register):
    register(
        Analogy(
            "force-voltage", "mechanical", "electrical", dual=True,
            options={"formulation": "charge"}, inverse_options={"dim": 1},
            doc="mass ↔ inductor, spring ↔ capacitor (C = 1/k), damper ↔ resistor, force ↔ voltage; velocity ↔ current",
        )
    )
    register(
        Analogy(
            "force-current", "mechanical", "electrical", dual=False,
            options={"formulation": "flux"}, inverse_options={"dim": 1},
            doc="mass ↔ capacitor, spring ↔ inductor (L = 1/k), damper ↔ conductance 1/c, force ↔ current; velocity ↔ voltage",
        )
    )


@hookimpl
def register_analogues(register):
    for analogy, table in (("force-voltage", FORCE_VOLTAGE), ("force-current", FORCE_CURRENT)):
        for kind, build in table.items():
            register(kind, analogy, build)
