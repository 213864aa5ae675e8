"""The multibody plugin's hook implementation: it registers the body, joint and load component types."""

from __future__ import annotations

from lagrangian import hookimpl

from .bodies import Body, Disc, Link, Rod
from .joints import Fixed, Free, PlanarJoint, Prismatic, Revolute, Spherical
from .loads import BodyTorque, JointFriction, KnifeEdge, RotationalDamper, RotationalSpring
from .rolling import Rolling


@hookimpl
def register_component_types(register):
    for cls in (Body, Link, Rod, Disc, Revolute, Prismatic, Spherical, PlanarJoint, Fixed, Free, BodyTorque,
                RotationalSpring, RotationalDamper, KnifeEdge, JointFriction, Rolling):
        register(cls)
