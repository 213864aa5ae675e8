"""Joints of the multibody plugin, branches between two bodies: :class:`Revolute`, :class:`Prismatic`,
:class:`Spherical`, :class:`PlanarJoint`, :class:`Fixed` and :class:`Free`, each giving the child's pose relative to
its parent in terms of its coordinates."""

from __future__ import annotations

from typing import Any

from lagrangian import Component, Contribution, Example, ModelError, Parameter
from lagrangian.base.component import t

from .checks import _unit, _vec, lg_param_error
from .rotations import unit_vectors, _angle_descriptions, _angle_names, _check_sequence, _euler, _euler_body, _rot3
from lagrangian.base import deferred as _deferred

sp = _deferred.module("sympy", globals())


class _Joint(Component):
    distinct_terminals = True
    domain = "mechanical"
    terminals = ("parent", "child")
    multibody = True
    structural = True

    def coordinate_names(self, dim: int) -> list[str]:
        raise NotImplementedError

    def names(self, dim: int) -> list[str]:
        given = self.params.get("coordinates")
        default = self.coordinate_names(dim)
        if given is None:
            return default
        names = [n.strip() for n in str(given).split(",")]
        if len(names) != len(default):
            raise lg_param_error(self.name, "coordinates", f"needs {len(default)} comma-separated names, got {given!r}.")
        return names

    def coordinate_descriptions(self, dim: int, names: list[str]) -> list[str] | None:
        """What each coordinate is (one text per name), or None for the plain "<kind> of <joint>"."""
        return None

    def points(self, dim: int) -> tuple[sp.Matrix, sp.Matrix]:
        return (_vec(self.params.get("parent_point"), dim, self, "parent_point"),
                _vec(self.params.get("child_point"), dim, self, "child_point"))

    def relative(self, dim: int, q: list) -> tuple[Any, sp.Matrix, Any]:
        """Planar: ``(relative angle, translation in the parent frame, None)``; spatial: ``(R_rel, translation in
        the parent frame, relative angular velocity in the parent frame)``."""
        raise NotImplementedError

    def relative_body_rate(self, q: list, R_rel: sp.Matrix, w_rel: sp.Matrix) -> sp.Matrix:
        """Spatial: the relative angular velocity in the child's frame, ``R_relᵀ w_rel``; joints whose rotations
        have a shorter form give it (a turn about an axis leaves the axis where it is)."""
        if all(e == 0 for e in w_rel):
            return sp.zeros(3, 1)
        return R_rel.T * w_rel

    def driven(self) -> list | None:
        """Prescribed coordinate values (expressions of t) for a driven joint, else None."""
        return None

    def contribute(self, ctx) -> Contribution:
        return Contribution()


def _joint_params(extra: dict) -> dict:
    return {
        "parent_point": Parameter("joint location in the parent's frame", default=None, shape="vector", unit="m"),
        "child_point": Parameter("joint location in the child's frame", default=None, shape="vector", unit="m"),
        "coordinates": Parameter("names of the joint coordinates, comma-separated", default=None, shape="name"),
        **extra,
    }


class Revolute(_Joint):
    """Revolute (pin) joint: one angle; planar, or about ``axis`` in space; ``angle=`` drives it."""

    kind = "revolute"
    parameters = _joint_params({
        "axis": Parameter("rotation axis in the parent frame (spatial)", default=None, shape="vector", symbolic=False),
        "absolute": Parameter("planar: the angle is the child's absolute angle", default=False, shape="flag"),
        "angle": Parameter("prescribed angle (an expression of t): a driven joint", default=None, check="real", shape="signal",
                           vector=False),
    })

    def coordinate_names(self, dim):
        return [f"theta_{self.name}"]

    @property
    def absolute_angle(self) -> bool:
        return bool(self.params.get("absolute"))

    def driven(self):
        return None if self.params.get("angle") is None else [self.angle]

    def relative(self, dim, q):
        (theta,) = q
        if dim == 2:
            return theta, sp.zeros(2, 1), None
        axis = _unit(_vec(self.params.get("axis"), 3, self, "axis", unit_vectors()[2]), self, "axis")
        return _rot3(axis, theta), sp.zeros(3, 1), axis * theta.diff(t)

    def relative_body_rate(self, q, R_rel, w_rel):
        return w_rel  # the axis is its own image under the turn about it

    @classmethod
    def example(cls) -> Example:
        return Example(("ground", "b"), {"child_point": (-1, 0)},
                       context=[("body", "b", "b", {"m": 1, "inertia": 1}), ("gravity", "g", (), {})], options={"dim": 2})


class Prismatic(_Joint):
    """Prismatic (slider) joint: one displacement ``s`` along ``axis`` (parent frame; default x); ``displacement=``
    drives it."""

    kind = "prismatic"
    parameters = _joint_params({
        "axis": Parameter("sliding direction in the parent frame", default=None, shape="vector", symbolic=False),
        "displacement": Parameter("prescribed displacement (expression of t)", default=None, check="real", shape="signal",
                                  vector=False),
    })

    def coordinate_names(self, dim):
        return [f"s_{self.name}"]

    def driven(self):
        return None if self.params.get("displacement") is None else [self.displacement]

    def relative(self, dim, q):
        (s,) = q
        e = sp.zeros(dim, 1)
        e[0] = 1
        axis = _unit(_vec(self.params.get("axis"), dim, self, "axis", e), self, "axis")
        return (sp.Integer(0), axis * s, None) if dim == 2 else (sp.eye(3), axis * s, sp.zeros(3, 1))

    @classmethod
    def example(cls) -> Example:
        return Example(("ground", "cart"), {},
                       context=[("body", "cart", "cart", {"m": 2, "inertia": 1}),
                                ("spring", "k", ("ground", "cart.origin"), {"k": 3})], options={"dim": 2})


def _sequence_param():
    return Parameter("body-fixed angle sequence: 'xyz' (default) or another of the 12 Euler / Tait–Bryan sequences",
                     default="xyz", shape="name")


class Spherical(_Joint):
    """Spherical (ball) joint, spatial: three body-fixed angles in the order ``sequence`` (default ``"xyz"``).

    ``sequence`` is one of the twelve body-fixed rotation sequences, read left to right: the child's rotation
    relative to its parent is ``R = R_1(q1) R_2(q2) R_3(q3)``, a turn about the parent's (= the body's first)
    axis, then about the once-turned body's second axis, then about the twice-turned body's third axis.

    * Tait–Bryan sequences ``"xyz"`` (the default), ``"xzy"``, ``"yxz"``, ``"yzx"``, ``"zxy"``, ``"zyx"``
      (three different axes): each angle named after the axis it turns about, ``alpha_<joint>`` about x,
      ``beta_<joint>`` about y, ``gamma_<joint>`` about z, in the sequence's order (``"xyz"``: alpha, beta,
      gamma; ``"zyx"``, yaw–pitch–roll: gamma, beta, alpha); gimbal lock where the second angle is ``±π/2``
      (the first and third axes in line: ``beta = ±π/2`` for ``"xyz"`` and ``"zyx"``).
    * Proper Euler sequences ``"zxz"``, ``"zyz"``, ``"xyx"``, ``"xzx"``, ``"yxy"``, ``"yzy"`` (first axis
      repeated): ``phi_<joint>`` (precession), ``theta_<joint>`` (nutation), ``psi_<joint>`` (spin); gimbal
      lock where ``theta = 0`` or ``±π``.  With ``"zxz"`` and a vertical z axis, a symmetric top's
      precession ``phi`` and spin ``psi`` are both ignorable.

    At a gimbal lock the first and third angles turn the body about one axis, the mass matrix is singular
    there and a simulation stops with a :class:`~lagrangian.SingularMassMatrixError`; pick the sequence
    whose lock the motion avoids.  Space-fixed (extrinsic) rotations about axes ``a, b, c`` are the
    body-fixed sequence ``c, b, a`` with the angles in reverse order.

    A heavy symmetric top (mass 0.3 kg, centre of mass 0.4 m up its axis) on a ball joint at the ground:

    >>> import lagrangian as lg
    >>> from lagrangian import routh
    >>> top = lg.Model("top", dim=3)
    >>> _ = top.add("body", "top", "top", m=0.3, inertia=(0.25, 0.25, 0.5), com=(0, 0, 0.4))
    >>> _ = top.add("spherical", "ball", ("ground", "top"), sequence="zxz")
    >>> _ = top.add("gravity", "g", g=9.81, direction=(0, 0, -1))
    >>> top.coordinate_names
    ['phi_ball', 'theta_ball', 'psi_ball']
    >>> routh.ignorable(top)
    ['phi_ball', 'psi_ball']

    Started upright (``theta = 0``, the lock of ``"zxz"``), the top cannot be simulated in these angles; the
    error names the lock and a sequence that locks elsewhere (``"xyz"``: upright is far from its lock):

    >>> top.simulate(0.1, initial={"phi_ball": 0, "theta_ball": 0, "psi_ball": 0}, velocity={"phi_ball": 0, "theta_ball": 0,
    ...                                                                                  "psi_ball": 7})
    Traceback (most recent call last):
    ...
    lagrangian.errors.SingularMassMatrixError: the mass matrix is singular at t=0 at phi_ball = 0, theta_ball = 0, psi_ball = 0 (...): the motion of phi_ball, psi_ball is not determined there ... sequence "zxz" is in gimbal lock where theta_ball = 0 or ±π ...; sequence="xyz" locks elsewhere ...
    >>> yaw_pitch_roll = lg.Model("aircraft", dim=3)
    >>> _ = yaw_pitch_roll.add("body", "plane", "plane", m=0.3, inertia=(0.1, 0.2, 0.25))
    >>> _ = yaw_pitch_roll.add("spherical", "j", ("ground", "plane"), sequence="zyx")
    >>> yaw_pitch_roll.coordinate_names  # about z, then y, then x
    ['gamma_j', 'beta_j', 'alpha_j']
    >>> lg.Model("m", dim=3).add("spherical", "j", ("ground", "b"), sequence="zxx")
    Traceback (most recent call last):
    ...
    lagrangian.errors.ParameterError: component 'j', parameter 'sequence': spherical joint 'j': 'zxx' is not an angle sequence. Give one of the 12 ...
    """

    kind = "spherical"
    parameters = _joint_params({"sequence": _sequence_param()})

    def __init__(self, name, nodes, params):
        _check_sequence(self.kind, name, params.get("sequence", "xyz"))
        super().__init__(name, nodes, params)

    @property
    def sequence(self) -> str:
        return self.params["sequence"]

    def coordinate_names(self, dim):
        return [f"{a}_{self.name}" for a in _angle_names(self.sequence)]

    def coordinate_descriptions(self, dim, names):
        return _angle_descriptions(self.kind, self.name, self.sequence, names)

    def relative(self, dim, q):
        if dim != 3:
            raise ModelError(f"spherical joint {self.name!r} needs a spatial model (dim=3); in the plane use a revolute joint.")
        R, omega = _euler(self.sequence, *q)
        return R, sp.zeros(3, 1), omega

    def relative_body_rate(self, q, R_rel, w_rel):
        return _euler_body(self.sequence, *q)

    @classmethod
    def example(cls) -> Example:
        return Example(("ground", "top"), {"child_point": (0, 0, -1)},
                       context=[("body", "top", "top", {"m": 1, "inertia": (1, 1, 1)}), ("gravity", "g", (), {})],
                       options={"dim": 3})


class PlanarJoint(_Joint):
    """Planar joint (3 DOF in the plane): translations ``x``, ``y`` in the parent frame and a rotation ``theta``."""

    kind = "planar"
    parameters = _joint_params({})

    def coordinate_names(self, dim):
        return [f"x_{self.name}", f"y_{self.name}", f"theta_{self.name}"]

    def relative(self, dim, q):
        x, y, theta = q
        if dim == 2:
            return theta, sp.Matrix([x, y]), None
        return _rot3(unit_vectors()[2], theta), sp.Matrix([x, y, 0]), unit_vectors()[2] * theta.diff(t)

    def relative_body_rate(self, q, R_rel, w_rel):
        return w_rel  # a turn about z leaves z where it is

    @classmethod
    def example(cls) -> Example:
        return Example(("ground", "b"), {},
                       context=[("body", "b", "b", {"m": 1, "inertia": 1}), ("gravity", "g", (), {})], options={"dim": 2})


class Fixed(_Joint):
    """Fixed (weld) joint: no coordinates; the child keeps the parent's orientation (turned by ``angle`` in the plane)."""

    kind = "fixed"
    parameters = _joint_params({"angle": Parameter("planar: fixed relative angle", default=0, check="real")})

    def coordinate_names(self, dim):
        return []

    def relative(self, dim, q):
        if dim == 2:
            return self.angle, sp.zeros(2, 1), None
        return sp.eye(3), sp.zeros(3, 1), sp.zeros(3, 1)

    @classmethod
    def example(cls) -> Example:
        return Example(("a", "b"), {"parent_point": (1, 0)},
                       context=[("body", "a", "a", {"m": 1, "inertia": 1}), ("body", "b", "b", {"m": 1, "inertia": 1}),
                                ("revolute", "j", ("ground", "a"), {}), ("gravity", "g", (), {})], options={"dim": 2})


class Free(_Joint):
    """Free joint: all the child's degrees of freedom (planar: x, y, theta; spatial: x, y, z in the parent frame
    and three angles in the body-fixed ``sequence``, named and singular as for :class:`Spherical`)."""

    kind = "free"
    parameters = _joint_params({"sequence": _sequence_param()})

    def __init__(self, name, nodes, params):
        _check_sequence(self.kind, name, params.get("sequence", "xyz"))
        super().__init__(name, nodes, params)

    @property
    def sequence(self) -> str:
        return self.params["sequence"]

    def coordinate_names(self, dim):
        if dim == 2:
            return [f"x_{self.name}", f"y_{self.name}", f"theta_{self.name}"]
        return [f"{a}_{self.name}" for a in ("x", "y", "z", *_angle_names(self.sequence))]

    def coordinate_descriptions(self, dim, names):
        if dim == 2:
            return None
        return [f"{n.split('_')[0]} of {self.kind} joint {self.name!r}" for n in names[:3]] + _angle_descriptions(
            self.kind, self.name, self.sequence, names[3:])

    def relative(self, dim, q):
        if dim == 2:
            x, y, theta = q
            return theta, sp.Matrix([x, y]), None
        R, omega = _euler(self.sequence, *q[3:])
        return R, sp.Matrix(q[:3]), omega

    def relative_body_rate(self, q, R_rel, w_rel):
        return _euler_body(self.sequence, *q[3:])

    @classmethod
    def example(cls) -> Example:
        return Example(("ground", "b"), {},
                       context=[("body", "b", "b", {"m": 1, "inertia": (1, 2, 2)})], options={"dim": 3})
