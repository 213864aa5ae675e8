"""Rigid bodies of the multibody plugin: the general :class:`Body`, the massless :class:`Link`, the uniform
:class:`Rod` and :class:`Disc`; each a node of the mechanical domain with named points."""

from __future__ import annotations

from lagrangian import GROUND, Component, Contribution, Example, ModelError, MovingFrame, Parameter, dot
from lagrangian.derive import cross

from .checks import _need_dim, _vec, lg_param_error
from lagrangian.base import deferred as _deferred

sp = _deferred.module("sympy", globals())


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
        if dim == 3 and pose.v_body is not None:
            v = pose.v_body + sp.Matrix(cross(pose.omega_body, self.com_offset(3)))
        else:
            v = view.velocity(f"{self.nodes[0]}.com")
        I = self.inertia_matrix(dim)
        if dim == 2:
            return Contribution(T=self.mass_value * dot(v, v) / 2 + I * pose.omega**2 / 2)
        wb = pose.omega_body
        rot = (wb.T * I * wb)[0, 0] / 2
        return Contribution(T=self.mass_value * dot(v, v) / 2 + rot, frames=[MovingFrame(wb, (v,))])


def _points_param():
    return Parameter("named points in the body frame: {name: vector}", default=None, shape="mapping")


class Body(_BodyBase):
    """Rigid body: mass ``m``, centre of mass ``com`` and inertia about it (planar: a scalar; spatial: three
    principal moments or a 3 × 3 matrix), with named ``points``; ``T = ½ m |v_G|² + ½ ωᵀ I ω``."""

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
