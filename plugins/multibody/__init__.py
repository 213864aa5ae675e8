"""Built-in plugin: rigid bodies and joints, in the plane (``dim=2``) and in space (``dim=3``).

Bodies are nodes of the mechanical domain; joints are branches between two
bodies (``ground`` is the fixed frame).  The joints of a spanning tree rooted
at ground give every body its pose — rotation ``R`` and origin ``p`` — as
functions of the joint coordinates (or of time, for a driven joint); every
other joint closes a kinematic loop and becomes a holonomic constraint kept
with a Lagrange multiplier.  Points of a body are nodes named
``"<body>.<point>"`` (``"<body>.com"`` and ``"<body>.origin"`` always exist),
so springs, dampers, forces and point masses of the mechanics plugin attach
to them unchanged.

Conventions.  A joint ``(parent, child)`` sits at ``parent_point`` (in the
parent's frame) and ``child_point`` (in the child's frame), which coincide.
Planar: a revolute joint's angle ``θ`` turns the child by ``θ`` relative to
the parent (``absolute=True``: ``θ`` is the child's angle to the fixed x
axis); a prismatic joint slides the child by ``s`` along ``axis`` (parent
frame).  Spatial: revolute about ``axis`` (parent frame); spherical and free
joints use three body-fixed angles in the ``sequence`` given (default ``"xyz"``:
``alpha``, ``beta``, ``gamma``, singular at ``beta = ±π/2``; a proper Euler
sequence such as ``"zxz"``: ``phi``, ``theta``, ``psi``, singular at
``theta = 0`` or ``π``) — see :class:`Spherical`.

>>> import lagrangian as lg, sympy as sp
>>> m = lg.Model("pendulum", dim=2)
>>> _ = m.add("rod", "arm", "arm", m=1, length=2)
>>> _ = m.add("revolute", "pin", ("ground", "arm"), absolute=True)
>>> _ = m.add("gravity", "g", g=9.81, direction=(0, -1))
>>> m.coordinate_names
['theta_pin']
>>> sp.trigsimp(m.mass_matrix)  # m L²/3 about the pin
Matrix([[4/3]])
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from typing import Any

import sympy as sp

from lagrangian import (
    GROUND,
    Component,
    Contribution,
    Coordinate,
    Example,
    Load,
    ModelError,
    Parameter,
    UnknownNameError,
    dot,
    hookimpl,
    t,
)
from lagrangian.derive import time_derivative, trig

__all__ = [
    "Pose", "Body", "Link", "Rod", "Disc", "Revolute", "Prismatic", "Spherical", "PlanarJoint", "Fixed", "Free",
    "CoordinatePartition", "ConsistentStart", "independent_coordinates", "consistent_initial", "constraint_residual",
]


@dataclass
class Pose:
    """Rotation ``R`` (dim × dim), origin ``p`` and angular velocity ``omega`` (planar: scalar; spatial: 3-vector in
    the fixed frame) of a body, as expressions of the coordinates and time."""

    R: sp.Matrix
    p: sp.Matrix
    omega: Any
    angle: Any = None  # planar only


def _rot2(phi) -> sp.Matrix:
    c, s = trig(sp.cos, phi), trig(sp.sin, phi)
    return sp.Matrix([[c, -s], [s, c]])


def _rot3(axis: sp.Matrix, angle) -> sp.Matrix:
    """Rotation by ``angle`` about the unit vector ``axis`` (Rodrigues); exact for the coordinate axes."""
    ax = [sp.nsimplify(a) if a.is_number else a for a in axis]
    if ax == [1, 0, 0]:
        return sp.Matrix([[1, 0, 0], [0, sp.cos(angle), -sp.sin(angle)], [0, sp.sin(angle), sp.cos(angle)]])
    if ax == [0, 1, 0]:
        return sp.Matrix([[sp.cos(angle), 0, sp.sin(angle)], [0, 1, 0], [-sp.sin(angle), 0, sp.cos(angle)]])
    if ax == [0, 0, 1]:
        return sp.Matrix([[sp.cos(angle), -sp.sin(angle), 0], [sp.sin(angle), sp.cos(angle), 0], [0, 0, 1]])
    k = sp.Matrix([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return sp.eye(3) + sp.sin(angle) * k + (1 - sp.cos(angle)) * k * k


E3 = [sp.Matrix([1, 0, 0]), sp.Matrix([0, 1, 0]), sp.Matrix([0, 0, 1])]


def _vec(value, dim: int, comp: Component, pname: str, default=None) -> sp.Matrix:
    if value is None:
        return sp.zeros(dim, 1) if default is None else default
    if not isinstance(value, sp.MatrixBase) or value.shape != (dim, 1):
        raise ModelError(f"{comp.kind} {comp.name!r}: parameter {pname!r} must be a vector of {dim} entries in a {dim}-D model.")
    return sp.Matrix(value)


def _unit(value, comp: Component, pname: str) -> sp.Matrix:
    norm = sp.sqrt(dot(value, value))
    if norm == 0:
        raise ModelError(f"{comp.kind} {comp.name!r}: parameter {pname!r} must not be the zero vector.")
    return value / norm


def _need_dim(comp: Component, view, dims: tuple[int, ...]) -> int:
    if view.dim not in dims:
        raise ModelError(
            f"{comp.kind} {comp.name!r} needs a model of dimension {' or '.join(map(str, dims))} "
            f"(lg.Model(dim=...)); this model has dim={view.dim}."
        )
    return view.dim


# -- bodies ---------------------------------------------------------------------------------------


class _BodyBase(Component):
    domain = "mechanical"
    terminals = ("body",)
    multibody = True

    #: named points every body of the kind has besides ``origin`` and ``com``
    extra_points: tuple[str, ...] = ()

    def point_names(self) -> list[str]:
        """Names of the body's points (``"<body>.<name>"`` are nodes)."""
        return list(dict.fromkeys(["origin", "com", *self.extra_points, *(self.params.get("points") or {})]))

    def branches(self) -> list[tuple[str, str]]:
        """The body's branch to the ground (as for every one-terminal component), and one joining each named point
        to the body: a rigid body holds its points together, so a spring between points of two bodies is connected."""
        body = self.nodes[0]
        return [(body, GROUND)] + [(f"{body}.{p}", body) for p in self.point_names()]

    def point_offsets(self, dim: int) -> dict[str, sp.Matrix]:
        """Named points in the body frame: ``origin``, ``com`` and the body's own."""
        points = {"origin": sp.zeros(dim, 1), "com": self.com_offset(dim)}
        for name, value in (self.params.get("points") or {}).items():
            points[name] = _vec(value, dim, self, f"points[{name!r}]")
        return points

    def com_offset(self, dim: int) -> sp.Matrix:
        return sp.zeros(dim, 1)

    def inertia_matrix(self, dim: int):
        return None

    @property
    def mass_value(self):
        return 0

    @property
    def gravitational_mass(self):
        return (f"{self.nodes[0]}.com", self.mass_value) if self.mass_value != 0 else None

    def contribute(self, ctx) -> Contribution:
        view = ctx.view
        dim = _need_dim(self, view, (2, 3))
        if self.mass_value == 0:
            return Contribution()
        pose = view.pose(self.nodes[0])
        v = view.velocity(f"{self.nodes[0]}.com")
        I = self.inertia_matrix(dim)
        if dim == 2:
            rot = I * pose.omega**2 / 2
        else:
            wb = pose.R.T * pose.omega
            rot = (wb.T * I * wb)[0, 0] / 2
        return Contribution(T=self.mass_value * dot(v, v) / 2 + rot)


def _points_param():
    return Parameter("named points in the body frame: {name: vector}", default=None, shape="mapping")


class Body(_BodyBase):
    """Rigid body: mass ``m``, centre of mass ``com`` and inertia about it (planar: a scalar; spatial: three
    principal moments or a 3 × 3 matrix), with named ``points``; T = ½ m |v_G|² + ½ ωᵀ I ω."""

    kind = "body"
    parameters = {
        "m": Parameter("mass", unit="kg"),
        "inertia": Parameter("inertia about the centre of mass (planar: scalar; spatial: 3 or 3 × 3)", shape="tensor"),
        "com": Parameter("centre of mass in the body frame", default=None, shape="vector", unit="m"),
        "points": _points_param(),
    }

    def __init__(self, name, nodes, params):
        super().__init__(name, nodes, params)
        I = self.params["inertia"]
        matrix = I if isinstance(I, sp.MatrixBase) else None
        if matrix is not None and matrix.shape == (3, 1):
            matrix = sp.diag(*matrix)
        if matrix is None:
            if not isinstance(I, sp.Expr) or (I.is_number and float(I) <= 0) or I.is_positive is False:
                raise lg_param_error(name, "inertia", f"a planar moment of inertia must be positive, got {I}.")
        else:
            if matrix.shape != (3, 3) or matrix != matrix.T:
                raise lg_param_error(name, "inertia", "a spatial inertia must be 3 principal moments or a symmetric 3 × 3 matrix.")
            if all(e.is_number for e in matrix):
                eig = [complex(e).real for e in matrix.evalf().eigenvals(multiple=True)]
                if min(eig) <= 0:
                    raise lg_param_error(
                        name, "inertia", f"the inertia matrix is not positive definite (eigenvalues {', '.join(f'{e:g}' for e in eig)})."
                    )
                d = sorted(eig)
                if d[0] + d[1] < d[2] * (1 - 1e-12):
                    raise lg_param_error(name, "inertia", f"principal moments {d} violate the triangle inequality I1 + I2 ≥ I3: no body has them.")

    @property
    def _inertia(self):
        """The inertia as a 3 × 3 matrix (spatial) or a scalar (planar), from the parameter (a symbolic view's too)."""
        I = self.params["inertia"]
        return sp.diag(*I) if isinstance(I, sp.MatrixBase) and I.shape == (3, 1) else I

    @property
    def mass_value(self):
        return self.m

    def com_offset(self, dim):
        return _vec(self.params.get("com"), dim, self, "com")

    def inertia_matrix(self, dim):
        if dim == 2:
            if isinstance(self._inertia, sp.MatrixBase):
                raise ModelError(f"body {self.name!r}: a planar body takes a scalar moment of inertia.")
            return self._inertia
        if not isinstance(self._inertia, sp.MatrixBase):
            raise ModelError(f"body {self.name!r}: a spatial body takes 3 principal moments or a 3 × 3 inertia matrix.")
        return self._inertia

    @classmethod
    def example(cls) -> Example:
        return Example(
            "b", {"m": 2, "inertia": sp.Rational(1, 3), "com": (1, 0), "points": {"tip": (2, 0)}},
            context=[("revolute", "j", ("ground", "b"), {}), ("gravity", "g", (), {})], options={"dim": 2},
        )


def lg_param_error(component, parameter, message):
    from lagrangian import ParameterError

    return ParameterError(component, parameter, message)


class Link(_BodyBase):
    """A massless frame with named points (rods of a point-mass pendulum, a crank's geometry)."""

    kind = "link"
    structural = True
    parameters = {"points": _points_param()}

    @classmethod
    def example(cls) -> Example:
        return Example(
            "l", {"points": {"end": (1, 0)}},
            context=[("revolute", "j", ("ground", "l"), {}), ("mass", "bob", "l.end", {"m": 1}), ("gravity", "g", (), {})],
            options={"dim": 2},
        )


class Rod(_BodyBase):
    """Slender uniform rod along the body's x axis from ``start`` (the origin) to ``end``; points ``start``,
    ``center``, ``end``; I = m L²/12 about its centre."""

    kind = "rod"
    extra_points = ("start", "center", "end")
    parameters = {
        "m": Parameter("mass", unit="kg"),
        "length": Parameter("length", unit="m"),
        "points": _points_param(),
    }

    @property
    def mass_value(self):
        return self.m

    def point_offsets(self, dim):
        points = super().point_offsets(dim)
        e = sp.zeros(dim, 1)
        e[0] = self.length
        points.update(start=sp.zeros(dim, 1), center=e / 2, end=e)
        return points

    def com_offset(self, dim):
        e = sp.zeros(dim, 1)
        e[0] = self.length / 2
        return e

    def inertia_matrix(self, dim):
        i = self.m * self.length**2 / 12
        return i if dim == 2 else sp.diag(0, i, i)

    @classmethod
    def example(cls) -> Example:
        return Example("r", {"m": 1, "length": 2}, context=[("revolute", "j", ("ground", "r"), {}), ("gravity", "g", (), {})],
                       options={"dim": 2})


class Disc(_BodyBase):
    """Thin uniform disc of ``radius`` centred on the origin, its axis the body's z axis; I = ½ m r² about the
    axis (¼ m r² about a diameter); points ``center`` and ``rim`` (on +x)."""

    kind = "disc"
    extra_points = ("center", "rim")
    parameters = {
        "m": Parameter("mass", unit="kg"),
        "radius": Parameter("radius", unit="m"),
        "points": _points_param(),
    }

    @property
    def mass_value(self):
        return self.m

    def point_offsets(self, dim):
        points = super().point_offsets(dim)
        e = sp.zeros(dim, 1)
        e[0] = self.radius
        points.update(center=sp.zeros(dim, 1), rim=e)
        return points

    def inertia_matrix(self, dim):
        axial = self.m * self.radius**2 / 2
        return axial if dim == 2 else sp.diag(axial / 2, axial / 2, axial)

    @classmethod
    def example(cls) -> Example:
        return Example("d", {"m": 1, "radius": sp.Rational(1, 2)},
                       context=[("revolute", "j", ("ground", "d"), {"child_point": (sp.Rational(1, 2), 0)}),
                                ("gravity", "g", (), {})], options={"dim": 2})


# -- joints ---------------------------------------------------------------------------------------


class _Joint(Component):
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
        "angle": Parameter("prescribed angle (an expression of t): a driven joint", default=None, check="real", shape="signal"),
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
        axis = _unit(_vec(self.params.get("axis"), 3, self, "axis", E3[2]), self, "axis")
        return _rot3(axis, theta), sp.zeros(3, 1), axis * theta.diff(t)

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
        "displacement": Parameter("prescribed displacement (expression of t)", default=None, check="real", shape="signal"),
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


#: The twelve body-fixed angle sequences: proper Euler (first and last axis the same) and Tait–Bryan (three axes).
PROPER_EULER = ("zxz", "zyz", "xyx", "xzx", "yxy", "yzy")
TAIT_BRYAN = ("xyz", "xzy", "yxz", "yzx", "zxy", "zyx")
SEQUENCES = TAIT_BRYAN + PROPER_EULER


def _check_sequence(kind: str, name: str, value) -> str:
    """The angle sequence of a spherical or free joint, checked against the twelve (never evaluated)."""
    if isinstance(value, str) and value in SEQUENCES:
        return value
    hint = ""
    if isinstance(value, str) and value.strip().lower() in SEQUENCES:
        hint = f" Write it in lowercase without spaces: {value.strip().lower()!r} (the rotations are body-fixed)."
    from lagrangian import ParameterError

    raise ParameterError(
        name, "sequence",
        f"{kind} joint {name!r}: {value!r} is not an angle sequence.{hint} Give one of the 12 body-fixed sequences: "
        f"proper Euler {', '.join(map(repr, PROPER_EULER))} (angles phi, theta, psi) or Tait–Bryan "
        f"{', '.join(map(repr, TAIT_BRYAN))} (angles alpha, beta, gamma); the default is 'xyz'.",
    )


def _angle_names(sequence: str) -> tuple[str, str, str]:
    return ("phi", "theta", "psi") if sequence in PROPER_EULER else ("alpha", "beta", "gamma")


def _lock(sequence: str) -> str:
    """Where the middle angle of a sequence puts the first and last rotation axes in line."""
    return "0 or ±π" if sequence in PROPER_EULER else "±π/2"


def _elsewhere(sequence: str) -> tuple[str, str]:
    """A sequence whose gimbal lock is a quarter turn away from that of ``sequence``, and where it locks.

    ``"aba"`` locks with the body's a axis along the parent's a axis; ``"cba"`` (Tait–Bryan, c the axis after a in
    x → y → z → x) with the body's a axis along the parent's c axis.  ``"abc"`` locks with the body's c axis along
    the parent's a axis; ``"cbc"`` with it along the parent's c axis."""
    a, b, c = sequence
    if a == c:
        c = "xyz"[("xyz".index(a) + 1) % 3]
        other = c + ({"x", "y", "z"} - {a, c}).pop() + a
        return other, f"the body's {a} axis along the parent's {c} axis"
    return c + b + c, f"the body's {c} axis along the parent's {c} axis"


def _angle_descriptions(kind: str, name: str, sequence: str, names: list[str]) -> list[str]:
    """Coordinate descriptions of a joint's three angles: which rotation each is, then (after a semicolon) the
    sequence's gimbal lock and a sequence that locks elsewhere."""
    a, c = sequence[0], sequence[2]
    other, where = _elsewhere(sequence)
    # sequences in double quotes: a quoted 'name' in a description is the component that owns the coordinate
    lock = (f'sequence "{sequence}" is in gimbal lock where {names[1]} = {_lock(sequence)} (the body\'s {c} axis along '
            f'the parent\'s {a} axis: {names[0]} and {names[2]} then turn about one axis); sequence="{other}" locks '
            f'elsewhere ({where})')
    order = ("first", "second", "third")
    return [f"{order[k]} angle (about the body's {sequence[k]} axis) of {kind} joint {name!r}; {lock}" for k in range(3)]


def _euler(sequence: str, a, b, c):
    """Rotation ``R = R_1(a) R_2(b) R_3(c)`` (body-fixed rotations about the axes named by ``sequence``) and the
    angular velocity in the parent frame, ``e_1 ȧ + R_1 e_2 ḃ + R_1 R_2 e_3 ċ``."""
    e1, e2, e3 = (E3["xyz".index(axis)] for axis in sequence)
    R1, R2, R3 = _rot3(e1, a), _rot3(e2, b), _rot3(e3, c)
    omega = e1 * a.diff(t) + R1 * e2 * b.diff(t) + R1 * R2 * e3 * c.diff(t)
    return R1 * R2 * R3, omega


def _sequence_param():
    return Parameter("body-fixed angle sequence: 'xyz' (default) or another of the 12 Euler / Tait–Bryan sequences",
                     default="xyz", shape="name")


class Spherical(_Joint):
    """Spherical (ball) joint, spatial: three body-fixed angles in the order ``sequence`` (default ``"xyz"``).

    ``sequence`` is one of the twelve body-fixed rotation sequences, read left to right: the child's rotation
    relative to its parent is ``R = R_1(q1) R_2(q2) R_3(q3)``, a turn about the parent's (= the body's first)
    axis, then about the once-turned body's second axis, then about the twice-turned body's third axis.

    * Tait–Bryan sequences ``"xyz"`` (the default), ``"xzy"``, ``"yxz"``, ``"yzx"``, ``"zxy"``, ``"zyx"``
      (three different axes): coordinates ``alpha_<joint>``, ``beta_<joint>``, ``gamma_<joint>`` for the
      first, second and third angle; gimbal lock where ``beta = ±π/2`` (the first and third axes in line).
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

    >>> top.simulate(0.1, initial={"phi_ball": 0, "theta_ball": 0, "psi_ball": 0}, velocity={"psi_ball": 7})
    Traceback (most recent call last):
    ...
    lagrangian.errors.SingularMassMatrixError: the mass matrix is singular at t=0 at phi_ball = 0, theta_ball = 0, psi_ball = 0 (...): the motion of phi_ball, psi_ball is not determined there ... sequence "zxz" is in gimbal lock where theta_ball = 0 or ±π ...; sequence="xyz" locks elsewhere ...
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
        return _rot3(E3[2], theta), sp.Matrix([x, y, 0]), E3[2] * theta.diff(t)

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

    @classmethod
    def example(cls) -> Example:
        return Example(("ground", "b"), {},
                       context=[("body", "b", "b", {"m": 1, "inertia": (1, 2, 2)})], options={"dim": 3})


# -- loads on bodies ------------------------------------------------------------------------------


class BodyTorque(Component):
    """A torque on a body (planar: scalar about z; spatial: a vector in the fixed frame)."""

    kind = "body_torque"
    domain = "mechanical"
    terminals = ("body",)
    role = "through"
    multibody = True
    parameters = {"tau": Parameter("torque (a signal; spatial: a vector)", check="real", shape="signal", unit="N m")}

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


# -- kinematics -----------------------------------------------------------------------------------


def build_kinematics(network, view) -> None:
    """Give ``view`` the pose of every body and the position of every body point; add joint coordinates and
    loop-closure constraints.  Called by the mechanical domain when the model has bodies or joints."""
    dim = view.dim
    comps = network.components
    if any(getattr(c, "multibody", False) for c in comps) and dim not in (2, 3):
        culprit = next(c for c in comps if getattr(c, "multibody", False))
        raise ModelError(f"{culprit.kind} {culprit.name!r}: rigid bodies and joints need lg.Model(dim=2) or dim=3.")
    bodies = {c.nodes[0]: c for c in comps if isinstance(c, _BodyBase)}
    duplicate = [c for c in comps if isinstance(c, _BodyBase) and bodies[c.nodes[0]] is not c]
    if duplicate:
        raise ModelError(f"node {duplicate[0].nodes[0]!r} has two bodies ({duplicate[0].name!r} and {bodies[duplicate[0].nodes[0]].name!r}).")
    joints = [c for c in comps if isinstance(c, _Joint)]
    for j in joints:
        for n in j.nodes:
            if n != GROUND and n not in bodies:
                raise UnknownNameError(f"body for joint {j.name!r}", n, bodies)
    ground_pose = Pose(sp.eye(dim), sp.zeros(dim, 1), sp.Integer(0) if dim == 2 else sp.zeros(3, 1),
                       angle=sp.Integer(0) if dim == 2 else None)
    view.poses[GROUND] = ground_pose
    # breadth-first from ground along joints followed parent → child: tree joints give poses, the rest close loops
    # (a joint met child-first is left to close a loop, so the order of declaration does not matter)
    children: dict[str, list] = {}
    for j in joints:
        children.setdefault(j.nodes[0], []).append(j)
    used, queue = set(), deque([GROUND])
    while queue:
        body = queue.popleft()
        for j in children.get(body, []):
            child = j.nodes[1]
            if child in view.poses:
                continue
            used.add(j.name)
            view.poses[child] = _child_pose(j, view, dim, body, child, bodies)
            view.positions[child] = view.poses[child].p
            queue.append(child)
    loose = [b for b in bodies if b not in view.poses]
    if loose:
        for j in joints:
            if j.name not in used and j.nodes[1] in view.poses and j.nodes[0] not in view.poses:
                raise ModelError(
                    f"joint {j.name!r} is declared (parent={j.nodes[0]!r}, child={j.nodes[1]!r}) but {j.nodes[1]!r} is "
                    f"nearer the ground in the joint tree, and {j.nodes[0]!r} is reached only through this joint: swap its "
                    f"nodes (and its parent_point and child_point)."
                )
        raise ModelError(f"body {loose[0]!r} is not connected to ground by joints: add a joint (a free joint if it flies).")
    view.closures = []  # (joint name, number of constraint rows), in the order of view.constraints
    for j in joints:
        if j.name not in used:
            rows = _closure(j, view, dim, bodies)
            view.constraints.extend(rows)
            view.closures.append((j.name, len(rows)))
    view.bodies = bodies
    for node in network.nodes:
        body, _, point = node.partition(".")
        if point and body in bodies:
            view.position(node)  # resolves (and checks) the point


def _child_pose(j: _Joint, view, dim: int, parent: str, child: str, bodies) -> Pose:
    driven = j.driven()
    if driven is not None:
        q = [sp.sympify(d) for d in driven]
        if any(not isinstance(d, sp.Expr) for d in q) or j.signals():
            raise ModelError(f"joint {j.name!r}: a driven joint needs its motion as a SymPy expression of t.")
    else:
        names = j.names(dim)
        texts = j.coordinate_descriptions(dim, names) or [f"{n.split('_')[0]} of {j.kind} joint {j.name!r}" for n in names]
        coords = [Coordinate.named(n, text) for n, text in zip(names, texts)]
        view.coordinates.extend(coords)
        q = [c.function for c in coords]
    P, C = j.points(dim)
    pp = view.poses[parent]
    R_rel, d, w_rel = j.relative(dim, q)
    rel = R_rel
    if dim == 2:
        angle = rel if getattr(j, "absolute_angle", False) else pp.angle + rel
        R = _rot2(angle)
        p = transform(transform(pp.p, pp.R, P + d), R, -C)
        return Pose(R, p, time_derivative(sp.sympify(angle), t), angle)
    R = pp.R * R_rel
    omega = pp.omega + pp.R * w_rel
    p = transform(transform(pp.p, pp.R, P + d), R, -C)
    return Pose(R, p, omega)


def transform(p: sp.Matrix, R: sp.Matrix, x: sp.Matrix) -> sp.Matrix:
    """``p + R x`` (a point given in a body frame, in the fixed frame), without products by zero entries of ``x``."""
    x = list(x)
    cols = [k for k, e in enumerate(x) if e != 0]
    if not cols:
        return sp.Matrix(p)
    return sp.Matrix([sp.Add(p[i], *[R[i, k] * x[k] for k in cols]) for i in range(R.rows)])


def _closure(j: _Joint, view, dim: int, bodies) -> list[sp.Expr]:
    """Loop-closure constraints of a joint outside the tree: its two points coincide (and, for a planar
    prismatic joint, the orientation and the offset across the axis are held)."""
    if j.kind not in ("revolute", "spherical") or j.driven() is not None:
        raise ModelError(
            f"joint {j.name!r} closes a kinematic loop; loops can be closed by a revolute (planar) or spherical joint: "
            f"choose the loop-closing joint among those (declare the others first)."
        )
    if dim == 3 and j.kind == "revolute":
        raise ModelError(f"joint {j.name!r}: in space, close loops with a spherical joint.")
    P, C = j.points(dim)
    pa, pb = view.poses[j.nodes[0]], view.poses[j.nodes[1]]
    gap = (pa.p + pa.R * P) - (pb.p + pb.R * C)
    return [g for g in gap]


@hookimpl
def register_component_types(register):
    for cls in (Body, Link, Rod, Disc, Revolute, Prismatic, Spherical, PlanarJoint, Fixed, Free, BodyTorque,
                RotationalSpring, RotationalDamper):
        register(cls)


# -- consistent initial conditions ----------------------------------------------------------------


@dataclass
class CoordinatePartition:
    """The coordinates of a constrained model split at one configuration (see :func:`independent_coordinates`).

    ``independent``: coordinates that can be chosen freely there; ``dependent``: those the loop-closure
    constraints then fix; ``dof`` degrees of freedom (= len(independent)); ``rank`` of the constraint
    Jacobian Φ_q; ``constraints``: number of constraint equations; ``residual``: max |Φ| at the configuration.
    """

    independent: list[str]
    dependent: list[str]
    dof: int
    rank: int
    constraints: int
    residual: float


class ConsistentStart(tuple):
    """``(initial, velocity)``: coordinate values and velocities by name, satisfying the constraints
    (see :func:`consistent_initial`); unpacks as a pair and passes straight to ``Model.simulate``."""

    __slots__ = ()

    def __new__(cls, initial: dict, velocity: dict):
        return super().__new__(cls, (initial, velocity))

    @property
    def initial(self) -> dict[str, float]:
        return self[0]

    @property
    def velocity(self) -> dict[str, float]:
        return self[1]


class _Closure:
    """Numeric Φ(q, t), Φ_q and Φ_t of a model's constraints, and the joint owning each row."""

    def __init__(self, model, params):
        import numpy as np

        eq = model.eq
        self.names = list(eq.names)
        self.m = len(eq.constraints)
        self.owners: list[str | None] = []
        for view in model.assembly.views.values():
            closures = getattr(view, "closures", None)
            rows = [name for name, k in closures or [] for _ in range(k)]
            self.owners += rows if len(rows) == len(view.constraints) else [None] * len(view.constraints)
        if not self.m:
            self.structure = np.zeros((0, len(self.names)), dtype=bool)
            return
        values = model.numeric(params).values
        subs = {s: sp.Float(v) for s, v in values.items()}
        Phi = eq.constraints.xreplace(subs)
        J = Phi.jacobian(eq.sym.q)
        self.structure = np.array([[J[k, i] != 0 for i in range(J.cols)] for k in range(J.rows)], dtype=bool)
        free = (Phi.free_symbols | J.free_symbols) - set(eq.sym.q) - {t}
        if free:  # pragma: no cover - Model.numeric has asked for every parameter already
            raise ModelError(f"the constraints need values for {', '.join(sorted(map(str, free)))}.")
        self._fn = sp.lambdify((t, eq.sym.q), [Phi, J, Phi.diff(t)], modules="numpy", cse=True)

    def __call__(self, time: float, q):
        import numpy as np

        Phi, J, Pt = self._fn(float(time), list(q))
        return (np.asarray(Phi, dtype=float).reshape(self.m), np.asarray(J, dtype=float).reshape(self.m, len(self.names)),
                np.asarray(Pt, dtype=float).reshape(self.m))

    def joints(self, rows) -> str:
        labels = dict.fromkeys(f"joint {self.owners[k]!r}" if self.owners[k] else f"constraint {k}" for k in rows)
        return ", ".join(labels)

    def check_rank(self, J, q) -> int:
        """The rank of Φ_q; a :class:`ModelError` naming the joints of dependent rows when it is below their number."""
        import numpy as np

        U, s, _ = np.linalg.svd(J)
        rank = _rank(s)
        if rank < self.m:
            rows = sorted({k for col in range(rank, self.m) for k in np.flatnonzero(np.abs(U[:, col]) > 1e-8)})
            at = ", ".join(f"{n} = {v:.6g}" for n, v, used in zip(self.names, q, self.structure.any(axis=0)) if used)
            raise ModelError(
                f"the loop-closure constraints of {self.joints(rows)} are dependent at {at} (rank {rank} of Φ_q for "
                f"{self.m} equations): the loop is over-constrained — one of those joints repeats what the others "
                f"already impose, so its reaction is not determined — or the configuration is singular (links in line, "
                f"a dead centre). Remove or replace the redundant joint, or choose a configuration away from the singular one."
            )
        return rank


def _rank(s) -> int:
    import numpy as np

    if not len(s) or s[0] == 0:
        return 0
    return int(np.sum(s > 1e-9 * s[0]))


def _check_names(given, names, what="coordinate") -> None:
    for name in given:
        if name not in names:
            raise UnknownNameError(what, name, names)


def independent_coordinates(model, at=None, *, params=None, time: float = 0.0) -> CoordinatePartition:
    """Which coordinates are independent and which dependent at the configuration ``at`` (coordinate values by
    name; missing ones are 0), from a pivoted QR factorization of the constraint Jacobian Φ_q: its ``rank``
    pivot columns are the dependent coordinates (the best-conditioned set the constraints can solve for), the
    remaining ``dof`` columns the independent ones.  An over-constrained loop — Φ_q of rank below the number
    of constraints — is a :class:`~lagrangian.ModelError` naming its joints.

    A rod pinned to the ground at both ends keeps one angle and two equations:

    >>> import lagrangian as lg
    >>> from lagrangian.plugins.multibody import independent_coordinates
    >>> m = lg.Model("pinned twice", dim=2)
    >>> _ = m.add("rod", "bar", "bar", m=1, length=1)
    >>> _ = m.add("revolute", "left", ("ground", "bar"))
    >>> _ = m.add("revolute", "right", ("bar", "ground"), parent_point=(1, 0), child_point=(1, 0))
    >>> independent_coordinates(m, {"theta_left": 0})
    Traceback (most recent call last):
    ...
    lagrangian.errors.ModelError: the loop-closure constraints of joint 'right' are dependent at theta_left = 0 (rank 1 of Φ_q for 2 equations): the loop is over-constrained ...

    The four-bar of :func:`consistent_initial` has one degree of freedom.
    """
    import numpy as np
    from scipy.linalg import qr

    eq = model.eq
    names = list(eq.names)
    at = dict(at or {})
    _check_names(at, names)
    cl = _Closure(model, params)
    q = np.array([float(at.get(n, 0.0)) for n in names])
    if not cl.m:
        return CoordinatePartition(names, [], len(names), 0, 0, 0.0)
    Phi, J, _ = cl(time, q)
    rank = cl.check_rank(J, q)
    _, _, piv = qr(J, pivoting=True, mode="economic")
    dependent = sorted(piv[:rank])
    return CoordinatePartition(
        independent=[n for i, n in enumerate(names) if i not in dependent],
        dependent=[names[i] for i in dependent],
        dof=len(names) - rank,
        rank=rank,
        constraints=cl.m,
        residual=float(np.max(np.abs(Phi))),
    )


def consistent_initial(model, initial, velocity=None, *, independent=None, params=None, time: float = 0.0,
                       tol: float = 1e-12, max_iter: int = 50) -> ConsistentStart:
    """Initial values and velocities that satisfy the model's loop-closure constraints.

    The coordinates in ``independent`` (by default: those given in ``initial``) keep their values; the others
    that take part in a constraint are solved from Φ(q, t) = 0 by Newton's method, starting from their values
    in ``initial`` (a guess; 0 when absent — the guess picks the assembly mode, e.g. a four-bar's open or
    crossed form).  Velocities follow from Φ_q q̇ + Φ_t = 0 the same way: those of the held coordinates are kept
    (0 when absent), the others corrected as little as possible.  Returns ``(initial, velocity)`` for every
    coordinate, ready for ``model.simulate(..., initial=..., velocity=...)``.

    No solution near the guess (held values that put a loop out of reach), more coordinates held than the loop
    leaves free, held coordinates the constraints tie together, or an over-constrained loop: a
    :class:`~lagrangian.ModelError` naming the joints.

    A four-bar (crank 1, coupler 3, rocker 2, ground link 3) with the crank held upright and turning at 1 rad/s:

    >>> import lagrangian as lg
    >>> from lagrangian.plugins.multibody import consistent_initial, independent_coordinates
    >>> m = lg.Model("four-bar", dim=2)
    >>> for name, length in (("crank", 1), ("coupler", 3), ("rocker", 2)):
    ...     _ = m.add("rod", name, name, m=1, length=length)
    >>> _ = m.add("revolute", "A", ("ground", "crank"), absolute=True)
    >>> _ = m.add("revolute", "B", ("crank", "coupler"), parent_point=(1, 0), absolute=True)
    >>> _ = m.add("revolute", "D", ("ground", "rocker"), parent_point=(3, 0), absolute=True)
    >>> _ = m.add("revolute", "C", ("coupler", "rocker"), parent_point=(3, 0), child_point=(2, 0))
    >>> m.coordinate_names
    ['theta_A', 'theta_D', 'theta_B']
    >>> q0, v0 = consistent_initial(m, {"theta_A": 1.5707963, "theta_D": 1.5}, {"theta_A": 1}, independent=["theta_A"])
    >>> {k: round(x, 6) for k, x in q0.items()}
    {'theta_A': 1.570796, 'theta_D': 1.655424, 'theta_B': 0.337307}
    >>> {k: round(x, 6) for k, x in v0.items()}
    {'theta_A': 1.0, 'theta_D': 0.487298, 'theta_B': -0.029099}
    >>> independent_coordinates(m, q0)
    CoordinatePartition(independent=['theta_A'], dependent=['theta_D', 'theta_B'], dof=1, rank=2, constraints=2, residual=...)
    >>> consistent_initial(m, {"theta_A": 1.5707963, "theta_D": 1.5, "theta_B": 0})
    Traceback (most recent call last):
    ...
    lagrangian.errors.ModelError: the loop-closure constraints do not hold at the values given (max |Φ| = 0.995 at joint 'C'), and every coordinate they involve is held (theta_A, theta_D, theta_B). Pass independent=[...] ...
    """
    import numpy as np

    eq = model.eq
    names = list(eq.names)
    initial, velocity = dict(initial or {}), dict(velocity or {})
    _check_names(initial, names)
    _check_names(velocity, names)
    if independent is None:
        held = [n for n in names if n in initial]
    else:
        held = [independent] if isinstance(independent, str) else list(independent)
        _check_names(held, names)
        missing = [n for n in held if n not in initial]
        if missing:
            raise ModelError(f"independent coordinate(s) {', '.join(missing)} need a value in `initial`.")

    def number(given, name, what):
        try:
            out = float(given.get(name, 0.0))
        except (TypeError, ValueError):
            raise ModelError(f"initial {what} of {name!r} must be a number, got {given[name]!r}.") from None
        if not np.isfinite(out):
            raise ModelError(f"initial {what} of {name!r} must be finite, got {given[name]!r}.")
        return out

    q = np.array([number(initial, n, "value") for n in names])
    v = np.array([number(velocity, n, "velocity") for n in names])
    cl = _Closure(model, params)

    def result():
        inertial = {names[i] for i in eq.inertial}
        return ConsistentStart({n: float(x) for n, x in zip(names, q)},
                               {n: float(x) for n, x in zip(names, v) if n in inertial})

    if not cl.m:
        return result()
    involved = cl.structure.any(axis=0)
    unknown = [i for i, n in enumerate(names) if involved[i] and n not in held]
    fixed = [n for i, n in enumerate(names) if involved[i] and n in held]
    Phi, J, _ = cl(time, q)
    scale = max(1.0, float(np.max(np.abs(J))))
    res = float(np.max(np.abs(Phi)))
    if not unknown and res > 1e-10 * scale:
        rank = cl.check_rank(J, q)
        raise ModelError(
            f"the loop-closure constraints do not hold at the values given (max |Φ| = {res:.3g} at "
            f"{cl.joints([int(np.argmax(np.abs(Phi)))])}), and every coordinate they involve is held ({', '.join(fixed)}). "
            f"Pass independent=[...] with the {int(involved.sum()) - rank} coordinate(s) to keep; the others are then "
            f"solved for, from their given values as guesses."
        )
    if unknown and len(unknown) < cl.m:
        rank = cl.check_rank(J, q)
        raise ModelError(
            f"{len(fixed)} coordinates of the loops are held ({', '.join(fixed)}) but the constraints of "
            f"{cl.joints(range(cl.m))} leave only {int(involved.sum()) - rank} degree(s) of freedom: hold at most that "
            f"many (independent=[...]); the others are solved for, from their given values as guesses."
        )
    iterations, stalled = 0, False
    while unknown and res > tol * scale and iterations < max_iter:
        iterations += 1
        step = np.linalg.lstsq(J[:, unknown], -Phi, rcond=None)[0]
        lam = 1.0
        while True:  # backtracking: accept the first fraction of the step that lowers the residual
            trial = q.copy()
            trial[unknown] += lam * step
            Phi_t, J_t, _ = cl(time, trial)
            new = float(np.max(np.abs(Phi_t))) if np.all(np.isfinite(Phi_t)) else np.inf
            if new < res or lam < 1e-6:
                break
            lam /= 2
        if not new < res:
            stalled = True
            break
        q, Phi, J, res = trial, Phi_t, J_t, new
    if res > 1e-10 * scale:
        worst = int(np.argmax(np.abs(Phi)))
        given = ", ".join(f"{n} = {q[i]:.6g}" for i, n in enumerate(names) if involved[i] and n in held) or "nothing held"
        inline = _rank(np.linalg.svd(J[:, unknown], compute_uv=False)) < min(cl.m, len(unknown)) if unknown else False
        raise ModelError(
            f"the loop closed by {cl.joints([worst])} cannot be closed with {given}: Newton's method from the guess "
            f"{'stalled' if stalled else 'stopped'} after {iterations} iteration(s) at max |Φ| = {res:.3g}"
            f"{' with the links in line' if inline else ''}. No configuration near the guess satisfies the constraints — "
            f"the held values may put the loop out of reach (links too short to meet), or the guess is far off: change "
            f"the held values or give better guesses for {', '.join(names[i] for i in unknown)} in `initial`."
        )
    rank = cl.check_rank(J, q)  # an over-constrained loop, or a singular configuration
    if unknown and _rank(np.linalg.svd(J[:, unknown], compute_uv=False)) < rank:
        suggestion = independent_coordinates(model, dict(zip(names, q)), params=params, time=time).independent
        raise ModelError(
            f"holding {', '.join(fixed)} does not fix the loop here: the constraints of {cl.joints(range(cl.m))} leave "
            f"{', '.join(names[i] for i in unknown)} undetermined (at this configuration the held coordinates are not "
            f"independent). Hold {', '.join(n for n in suggestion if involved[names.index(n)])} instead (independent=[...])."
        )
    # velocities: Φ_q q̇ + Φ_t = 0, the unknown velocities corrected from their given values as little as possible
    Phi, J, Pt = cl(time, q)
    if unknown:
        rhs = -(J @ v + Pt)
        v[unknown] += np.linalg.lstsq(J[:, unknown], rhs, rcond=None)[0]
    gap = float(np.max(np.abs(J @ v + Pt)))
    if gap > 1e-9 * max(1.0, scale * float(np.max(np.abs(v), initial=0.0))):
        raise ModelError(
            f"the velocities cannot satisfy the constraints of {cl.joints(range(cl.m))} (max |Φ_q q̇ + Φ_t| = {gap:.3g}): "
            f"the held velocities are inconsistent with each other; hold fewer coordinates."
        )
    return result()


def constraint_residual(model, result) -> float:
    """The largest |Φ| of the model's loop-closure constraints along a simulation ``result`` (0 without loops).

    >>> import lagrangian as lg
    >>> from lagrangian.plugins.multibody import consistent_initial, constraint_residual
    >>> m = lg.Model("slider-crank", dim=2)
    >>> _ = m.add("rod", "crank", "crank", m=1, length=1)
    >>> _ = m.add("rod", "rod", "rod", m=1, length=3)
    >>> _ = m.add("body", "slider", "slider", m=1, inertia=1)
    >>> _ = m.add("revolute", "O", ("ground", "crank"), absolute=True)
    >>> _ = m.add("revolute", "A", ("crank", "rod"), parent_point=(1, 0), absolute=True)
    >>> _ = m.add("prismatic", "P", ("ground", "slider"))
    >>> _ = m.add("revolute", "B", ("rod", "slider"), parent_point=(3, 0))
    >>> start = consistent_initial(m, {"theta_O": 0.5, "s_P": 3.5}, {"theta_O": 2.0}, independent="theta_O")
    >>> res = m.simulate(2.0, initial=start.initial, velocity=start.velocity)
    >>> constraint_residual(m, res) < 1e-8
    True
    """
    import numpy as np

    eq = model.eq
    if not len(eq.constraints):
        return 0.0
    return float(max(np.max(np.abs(result.quantity(eq.display(c)))) for c in eq.constraints))
