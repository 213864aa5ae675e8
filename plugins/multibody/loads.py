"""Loads on the multibody plugin's bodies: a :class:`BodyTorque`, and a planar :class:`RotationalSpring` and
:class:`RotationalDamper` between two bodies."""

from __future__ import annotations

import sympy as sp

from lagrangian import Component, Contribution, Example, Load, Parameter, t

from .checks import _need_dim


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
