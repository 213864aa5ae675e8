"""Loads on the multibody plugin's bodies: a :class:`BodyTorque`, a planar :class:`RotationalSpring` and
:class:`RotationalDamper` between two bodies, a planar :class:`KnifeEdge`, and :class:`JointFriction` on a joint's
coordinate."""

from __future__ import annotations

from lagrangian import Component, Contribution, Example, Load, ModelError, Parameter, rate
from lagrangian.base.component import t

from .checks import _need_dim
from lagrangian.plugins.mechanics import STICK_SLIP, _check_phase, friction_contribution
from lagrangian.base import deferred as _deferred

sp = _deferred.module("sympy", globals())


class BodyTorque(Component):
    """A torque on a body (planar: scalar about z; spatial: a vector in the fixed frame): a signal of t, or an
    expression of the state (:func:`lagrangian.coordinate`, :func:`lagrangian.rate`)."""

    kind = "body_torque"
    domain = "mechanical"
    terminals = ("body",)
    role = "through"
    multibody = True
    parameters = {"tau": Parameter("torque (a signal; spatial: a vector)", check="real", shape="signal", unit="N m",
                                   state=True)}

    def contribute(self, ctx) -> Contribution:
        pose = ctx.view.pose(self.nodes[0])
        return Contribution(loads=[Load(self.tau, pose.omega)])

    @classmethod
    def example(cls) -> Example:
        return Example("b", {"tau": sp.sin(t)},
                       context=[("body", "b", "b", {"m": 1, "inertia": 1}), ("revolute", "j", ("ground", "b"), {}),
                                ("rotational_spring", "k", ("ground", "b"), {"k": 2})], options={"dim": 2})


class RotationalSpring(Component):
    """Planar torsional spring between two bodies: V = ½ k (φ_b − φ_a − θ₀)² (at a joint: its angle)."""

    distinct_terminals = True

    kind = "rotational_spring"
    domain = "mechanical"
    terminals = ("a", "b")
    multibody = True
    parameters = {"k": Parameter("torsional stiffness", unit="N m/rad"),
                  "rest_angle": Parameter("relative angle at rest", default=0, check="real", unit="rad")}

    def contribute(self, ctx) -> Contribution:
        _need_dim(self, ctx.view, (2,))
        rel = ctx.view.pose(self.nodes[1]).angle - ctx.view.pose(self.nodes[0]).angle
        return Contribution(V=self.k * (rel - self.rest_angle) ** 2 / 2)

    @classmethod
    def example(cls) -> Example:
        return Example(("ground", "b"), {"k": 2},
                       context=[("body", "b", "b", {"m": 1, "inertia": 1}), ("revolute", "j", ("ground", "b"), {})],
                       options={"dim": 2})


class RotationalDamper(Component):
    """Planar torsional damper between two bodies: D = ½ c (φ̇_b − φ̇_a)²."""

    distinct_terminals = True

    kind = "rotational_damper"
    domain = "mechanical"
    terminals = ("a", "b")
    multibody = True
    parameters = {"c": Parameter("torsional damping", check="nonnegative", unit="N m s/rad")}

    def contribute(self, ctx) -> Contribution:
        _need_dim(self, ctx.view, (2,))
        rate = ctx.view.pose(self.nodes[1]).omega - ctx.view.pose(self.nodes[0]).omega
        return Contribution(D=self.c * rate**2 / 2)

    @classmethod
    def example(cls) -> Example:
        return Example(("ground", "b"), {"c": 0.5},
                       context=[("body", "b", "b", {"m": 1, "inertia": 1}), ("revolute", "j", ("ground", "b"), {}),
                                ("rotational_spring", "k", ("ground", "b"), {"k": 2})], options={"dim": 2})


class KnifeEdge(Component):
    """A knife edge, a skate or a sled's runner at a point of a planar body: the point cannot move across the edge
    (``direction``, in the body's frame; its x axis by default) — a constraint on velocities (nonholonomic),
    ``n · v_point = 0`` with ``n`` the edge's normal, kept with a multiplier (the edge's sideways force).  At a
    point off the centre of mass it is Chaplygin's sled.

    >>> import lagrangian as lg
    >>> m = lg.Model("sled", dim=2)
    >>> _ = m.add("body", "b", "b", m=2.0, inertia=0.1)
    >>> _ = m.add("free", "j", ("ground", "b"))
    >>> _ = m.add("knife_edge", "edge", "b")
    >>> m.eq.velocity_constraints
    Matrix([[-v_x_j*sin(q_theta_j) + v_y_j*cos(q_theta_j)]])
    """

    kind = "knife_edge"
    domain = "mechanical"
    terminals = ("point",)
    multibody = True
    parameters = {"direction": Parameter("the edge's direction in the body's frame", default=(1, 0), shape="vector",
                                         symbolic=False)}

    def contribute(self, ctx) -> Contribution:
        _need_dim(self, ctx.view, (2,))
        body = self.nodes[0].partition(".")[0]
        e = sp.Matrix(self.direction) if self.direction is not None else sp.Matrix([1, 0])
        if len(e) != 2 or all(x == 0 for x in e):
            raise ModelError(f"knife_edge {self.name!r}: direction is a nonzero vector of 2 components in the body's "
                             f"frame, got {list(e)}.")
        e = ctx.view.pose(body).R * (e / sp.sqrt(e.dot(e)))
        v = ctx.view.velocity(self.nodes[0])
        return Contribution(velocity_constraints=[-e[1] * v[0] + e[0] * v[1]])

    @classmethod
    def example(cls) -> Example:
        return Example("b.tip", {},
                       context=[("body", "b", "b", {"m": 1, "inertia": 0.2, "points": {"tip": (0.3, 0)}}),
                                ("free", "j", ("ground", "b"), {}), ("force", "F", "b", {"F": (1, 0.5)})],
                       options={"dim": 2})


class JointFriction(Component):
    """Dry (Coulomb) friction on one coordinate — a prismatic joint's slide, a revolute joint's turn — regularized as
    ``coulomb_friction`` is: the generalized force ``−F_c tanh(q̇ / v_s)``, with ``F_c`` the sliding friction force
    (``μ N``, or a torque on an angle) and ``v_s`` the rate below which it fades.  A load held below ``F_c`` creeps
    at ``v_s atanh(F/F_c)`` rather than sticking; with ``stick_slip=True`` it sticks and slips instead, in
    :func:`lagrangian.stick_slip.simulate` (``F_s``: the largest force sticking holds).  Its power
    (``Model.load_power``) is the rate it turns energy into heat.

    A block on a slide inclined at α, with friction μ m g cos α on the slide:

    >>> import math, lagrangian as lg
    >>> m = lg.Model("block on an incline", dim=2)
    >>> _ = m.add("body", "b", "b", m=0.3, inertia=1e-3)
    >>> _ = m.add("prismatic", "slide", ("ground", "b"), axis=(math.cos(0.5), -math.sin(0.5)))
    >>> _ = m.add("gravity", "g")
    >>> _ = m.add("joint_friction", "f", coordinate="s_slide", F_c=0.2 * 0.3 * 9.81 * math.cos(0.5), v_s=1e-6)
    >>> res = m.simulate(1.0, initial={"s_slide": 0}, velocity={"s_slide": 0}, points=3, method="Radau")
    >>> round(float(res["s_slide"][-1]), 4), round(9.81 * (math.sin(0.5) - 0.2 * math.cos(0.5)) / 2, 4)
    (1.4907, 1.4907)
    """

    kind = "joint_friction"
    domain = "mechanical"
    terminals = ()
    parameters = {
        "coordinate": Parameter("the coordinate it acts on (one of Model.coordinate_names)", shape="name"),
        "F_c": Parameter("sliding friction force μ N (a torque on an angle)", unit="N", check="nonnegative"),
        "v_s": Parameter("rate below which the friction fades (regularization)", default=1e-4, unit="m/s"),
        **STICK_SLIP,
    }

    def __init__(self, name, nodes, params):
        _check_phase(self.kind, name, params)
        super().__init__(name, nodes, params)

    def sliding_rate(self, ctx):
        """The rate the friction opposes (the stick–slip driver's contract, with ``phase`` and ``F_s``)."""
        return rate(self.coordinate)

    def contribute(self, ctx) -> Contribution:
        return friction_contribution(self, self.sliding_rate(ctx))

    @classmethod
    def example(cls) -> Example:
        return Example((), {"coordinate": "s_p", "F_c": 0.3, "v_s": 0.05},
                       context=[("body", "b", "b", {"m": 1, "inertia": 1}), ("prismatic", "p", ("ground", "b"), {}),
                                ("force", "F", "b", {"F": (1, 0)})], options={"dim": 2})
