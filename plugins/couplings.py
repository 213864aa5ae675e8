"""Built-in plugin, mechanics: the constraint kinds between coordinates (``constraint``, ``velocity_constraint``,
``gear``, ``rack_and_pinion``).  The mechanics plugin registers them (``lagrangian plugins`` lists them under it);
each holonomic kind keeps its constraint with a Lagrange multiplier, or ``eliminate=`` solves it for one coordinate.

>>> import lagrangian as lg
>>> m = lg.Model("gear pair")
>>> _ = m.add("inertia", "J1", "s1", J=0.01)
>>> _ = m.add("inertia", "J2", "s2", J=0.04)
>>> _ = m.add("gear", "mesh", a="theta_s1", b="theta_s2", teeth_a=12, teeth_b=36, eliminate="theta_s2")
>>> m.coordinate_names
['theta_s1']
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from lagrangian import Component, Contribution, Example, ModelError, Parameter, coordinate, rate
from lagrangian.base.component import t
from lagrangian.base import deferred as _deferred

sp = _deferred.module("sympy", globals())

__all__ = ["Constraint", "Gear", "RackAndPinion", "VelocityConstraint"]


class Constraint(Component):
    """A holonomic constraint ``f(q, t) = 0`` between coordinates, written in :func:`lagrangian.coordinate` (one
    expression, or a list of them: one constraint each): rolling without slipping (``x − R θ``), a cam, a
    prescribed relation.  It is kept with a Lagrange multiplier as a closed loop's closure is, so
    ``independent_coordinates``, ``consistent_initial`` and ``constraint_residual`` cover it.  Or
    ``eliminate="<coordinate>"`` solves it for that coordinate — ``f = a·x + g``, linear in ``x``, ``a`` free of
    the coordinates and not zero — and puts ``x = −g / a`` and its rate everywhere (energies, loads, frames, the
    other constraints): one coordinate and no multiplier less, ``x`` still in results (``res["x"]``, not in
    ``initial=``).  One constraint (not a list) per component then; chains are solved in order, cycles refused.

    >>> import lagrangian as lg
    >>> m = lg.Model("rolling", dim=1)
    >>> _ = m.add("mass", "m1", "p", m=0.3)
    >>> _ = m.add("inertia", "J", "wheel", J=2e-3)
    >>> _ = m.add("constraint", "roll", f=lg.coordinate("x_p") - 0.05 * lg.coordinate("theta_wheel"))
    >>> m.eq.constraints
    Matrix([[-0.05*q_theta_wheel + q_x_p]])
    >>> e = lg.Model("rolling, eliminated", dim=1)
    >>> _ = e.add("mass", "m1", "p", m=0.3), e.add("inertia", "J", "wheel", J=2e-3)
    >>> _ = e.add("constraint", "roll", f=m.component("roll").f, eliminate="theta_wheel")
    >>> e.coordinate_names, e.mass_matrix  # m + J / R²
    (['x_p'], Matrix([[1.1]]))
    """

    kind = "constraint"
    domain = "mechanical"
    terminals = ()

    @dataclass(frozen=True)
    class Eliminate(Parameter):
        """The name of the coordinate to eliminate, or None (given, as by default: kept with a multiplier)."""
        def coerce(self, value: Any, component: str, name: str) -> Any:
            return None if value is None else super().coerce(value, component, name)

    parameters = {
        "f": Parameter("f(q, t), kept at zero (a list: one constraint each)", check="real", shape="signal", state=True),
        "eliminate": Eliminate("coordinate solved from the constraint and substituted everywhere (default None: "
                               "kept with a multiplier)", default=None, shape="name"),
    }

    def contribute(self, ctx) -> Contribution:
        rows = list(self.f) if isinstance(self.f, sp.MatrixBase) else [self.f]
        for e in rows:
            if any(isinstance(d, sp.Derivative) for d in sp.preorder_traversal(e)):
                raise ModelError(f"constraint {self.name!r}: {e} holds a rate; a holonomic constraint is written in "
                                 f"coordinates and t alone (a constraint on velocities is nonholonomic).")
            if not any(f.args == (t,) for f in e.atoms(sp.core.function.AppliedUndef)):
                raise ModelError(f"constraint {self.name!r}: {e} holds no coordinate (lagrangian.coordinate): it "
                                 f"constrains nothing.")
        return Contribution(constraints=rows)

    @classmethod
    def example(cls) -> Example:
        return Example((), {"f": coordinate("x_a") - 2 * coordinate("x_b")},
                       context=[("mass", "ma", "a", {"m": 1}), ("mass", "mb", "b", {"m": 2}),
                                ("spring", "k", ("ground", "a"), {"k": 3})])


class VelocityConstraint(Component):
    """A constraint on velocities ``A(q, t)·q̇ + b(q, t) = 0`` that no relation between positions integrates
    (nonholonomic): a knife edge or a skate that cannot slide sideways, a wheel that rolls without slipping in the
    plane.  Written in :func:`lagrangian.coordinate` and :func:`lagrangian.rate` (a list: one constraint each), it
    enters Lagrange's equations with a multiplier (the Lagrange–d'Alembert form).  The Routhian, linearization,
    equilibria, scenes and the exact solution refuse a model holding one, by name; impulses respect it.

    >>> import lagrangian as lg, sympy as sp
    >>> m = lg.Model("sled", dim=2)
    >>> _ = m.add("body", "b", "b", m=2.0, inertia=0.1)
    >>> _ = m.add("free", "j", ("ground", "b"))
    >>> th = lg.coordinate("theta_j")
    >>> _ = m.add("velocity_constraint", "edge", c=-sp.sin(th) * lg.rate("x_j") + sp.cos(th) * lg.rate("y_j"))
    >>> m.eq.velocity_constraints
    Matrix([[-v_x_j*sin(q_theta_j) + v_y_j*cos(q_theta_j)]])
    """

    kind = "velocity_constraint"
    domain = "mechanical"
    terminals = ()
    parameters = {"c": Parameter("A(q, t)·q̇ + b(q, t), kept at zero (a list: one constraint each)", check="real",
                                 shape="signal", state=True)}

    def contribute(self, ctx) -> Contribution:
        rows = list(self.c) if isinstance(self.c, sp.MatrixBase) else [self.c]
        return Contribution(velocity_constraints=rows)

    @classmethod
    def example(cls) -> Example:
        return Example((), {"c": rate("x_a") - coordinate("x_b") * rate("x_b")},
                       context=[("mass", "ma", "a", {"m": 1}), ("mass", "mb", "b", {"m": 2}),
                                ("spring", "k", ("ground", "a"), {"k": 3})])


class Gear(Component):
    """A gear pair between two angle coordinates: ``N_a θ_a + N_b θ_b = 0`` (external mesh, the gears turn in opposite
    senses) or ``N_a θ_a = N_b θ_b`` (``internal=True``: a ring gear), ``N`` their teeth (or radii); kept with a
    multiplier, whose value is the tooth force times the radius; or ``eliminate=`` ``a`` or ``b`` solves it for
    that angle (see ``constraint``).

    >>> import lagrangian as lg
    >>> m = lg.Model("gear pair")
    >>> _ = m.add("inertia", "J1", "s1", J=0.01)
    >>> _ = m.add("inertia", "J2", "s2", J=0.04)
    >>> _ = m.add("gear", "mesh", a="theta_s1", b="theta_s2", teeth_a=12, teeth_b=36)
    >>> m.eq.constraints
    Matrix([[12*q_theta_s1 + 36*q_theta_s2]])
    >>> e = lg.Model("gear pair, eliminated")
    >>> for s, J in (("s1", 0.01), ("s2", 0.04)): _ = e.add("inertia", "J" + s, s, J=J)
    >>> _ = e.add("gear", "mesh", a="theta_s1", b="theta_s2", teeth_a=12, teeth_b=36, eliminate="theta_s2")
    >>> e.coordinate_names, e.mass_matrix  # J1 + J2 (12/36)²
    (['theta_s1'], Matrix([[0.0144444444444444]]))
    """

    kind = "gear"
    domain = "mechanical"
    terminals = ()
    parameters = {
        "a": Parameter("angle coordinate of the first gear", shape="name"),
        "b": Parameter("angle coordinate of the second gear", shape="name"),
        "teeth_a": Parameter("teeth (or pitch radius) of the first gear", symbolic=False),
        "teeth_b": Parameter("teeth (or pitch radius) of the second gear", symbolic=False),
        "internal": Parameter("the second gear is a ring gear (both turn the same way)", default=False, shape="flag"),
        "eliminate": Constraint.parameters["eliminate"],
    }

    def contribute(self, ctx) -> Contribution:
        a, b = coordinate(self.a), coordinate(self.b)
        sign = -1 if self.internal else 1
        return Contribution(constraints=[self.teeth_a * a + sign * self.teeth_b * b])

    @classmethod
    def example(cls) -> Example:
        return Example((), {"a": "x_a", "b": "x_b", "teeth_a": 12, "teeth_b": 30},
                       context=[("mass", "ma", "a", {"m": 1}), ("mass", "mb", "b", {"m": 2}),
                                ("spring", "k", ("ground", "a"), {"k": 3})])


class RackAndPinion(Component):
    """A rack driven by a pinion: ``x = r θ`` between a position coordinate and an angle coordinate (the rack moves
    +x as the pinion turns +θ); kept with a multiplier, whose value is the tooth force, or ``eliminate=`` the rack
    or the pinion coordinate solves it for that one (see ``constraint``): the pinion's angle eliminated, the rack
    moves with the effective mass ``m + J / r²``.

    >>> import lagrangian as lg
    >>> m = lg.Model("rack")
    >>> _ = m.add("mass", "rack", "p", m=0.5)
    >>> _ = m.add("inertia", "J", "s", J=1e-3)
    >>> _ = m.add("rack_and_pinion", "mesh", rack="x_p", pinion="theta_s", radius=0.02)
    >>> m.eq.constraints
    Matrix([[-0.02*q_theta_s + q_x_p]])
    >>> e = lg.Model("rack, eliminated")
    >>> _ = e.add("mass", "rack", "p", m=0.5), e.add("inertia", "J", "s", J=1e-3)
    >>> _ = e.add("rack_and_pinion", "mesh", rack="x_p", pinion="theta_s", radius=0.02, eliminate="theta_s")
    >>> e.coordinate_names, e.mass_matrix  # m + J / r²
    (['x_p'], Matrix([[3.0]]))
    """

    kind = "rack_and_pinion"
    domain = "mechanical"
    terminals = ()
    parameters = {
        "rack": Parameter("position coordinate of the rack", shape="name"),
        "pinion": Parameter("angle coordinate of the pinion", shape="name"),
        "radius": Parameter("pitch radius of the pinion", unit="m", symbolic=False),
        "eliminate": Constraint.parameters["eliminate"],
    }

    def contribute(self, ctx) -> Contribution:
        return Contribution(constraints=[coordinate(self.rack) - self.radius * coordinate(self.pinion)])

    @classmethod
    def example(cls) -> Example:
        return Example((), {"rack": "x_a", "pinion": "x_b", "radius": 0.5},
                       context=[("mass", "ma", "a", {"m": 1}), ("mass", "mb", "b", {"m": 2}),
                                ("spring", "k", ("ground", "a"), {"k": 3})])
