"""What impulses act through: the errors, applied impulses, contacts (ground, wall, plane, between), locks, and
the points of a model they name.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...base.component import t
from ...errors import ModelError, NumericalError, SingularMassMatrixError, UnknownNameError, closest
from ...errors import ExpressionError
from ...base.text import as_expr
from ...base import deferred as _deferred

sp = _deferred.module("sympy", globals())

# -- errors ----------------------------------------------------------------------------------------


class ContactError(ModelError):
    """An impulse, contact or sudden constraint is described wrongly: an unknown point or joint, a
    coefficient of restitution outside [0, 1], a contact that is not closing, a bad normal."""


class ImpactError(NumericalError):
    """An impact cannot be resolved, or a hybrid simulation cannot go on."""


class SingularImpactError(ImpactError, SingularMassMatrixError):
    """The impulse is not determined: singular mass matrix, dependent constraints, or a contact whose point
    cannot move along its normal (infinite effective mass)."""


class GrazingImpactError(ImpactError):
    """The contact point meets the surface with (almost) no normal velocity: there is no impact to resolve."""


# -- what is applied -------------------------------------------------------------------------------


@dataclass(frozen=True)
class Impulse:
    """An impulse ``P̂ = ∫F dt`` applied at a point of the model (a node, or a body point ``"<body>.<point>"``).

    ``vector`` has one entry per spatial axis (a plain number in one dimension); numbers or SymPy expressions.

    >>> Impulse("cart", 3)
    Impulse(point='cart', vector=3)
    """

    point: str
    vector: Any


def _contact_name(given, default):
    if given is None:
        return default
    if not isinstance(given, str) or not given:
        raise ContactError(f"contact names must be non-empty strings, got {given!r}.")
    return given


def _restitution(e, name):
    try:
        e = as_expr(e, f"contact {name!r}: the coefficient of restitution")
    except ExpressionError:
        raise ContactError(f"contact {name!r}: the coefficient of restitution must be a number in [0, 1], got {e!r}.") from None
    if not isinstance(e, sp.Expr) or e.is_real is False:
        raise ContactError(f"contact {name!r}: the coefficient of restitution must be a real number in [0, 1], got {e!r}.")
    if e.is_number and not 0 <= float(e) <= 1:
        raise ContactError(
            f"contact {name!r}: the coefficient of restitution e = {e} is outside [0, 1]; use e between 0 (plastic: "
            f"the point stays on the surface) and 1 (elastic: it leaves as fast as it came)."
        )
    return e


def _as_vector(value, dim, what) -> sp.Matrix:
    if isinstance(value, sp.MatrixBase):
        entries = list(value)
    elif isinstance(value, (list, tuple, np.ndarray)):
        entries = list(np.asarray(value, dtype=object).reshape(-1))
    else:
        entries = [value]
    vec = sp.Matrix([as_expr(x, what) for x in entries])  # each entry read first: text is never sympified
    if vec.shape != (dim, 1):
        raise ContactError(f"{what} must have {dim} entr{'y' if dim == 1 else 'ies'} (one per axis of this {dim}-D model), got {value!r}.")
    return vec


class Contact:
    """A frictionless unilateral contact ``g(q, t) ≥ 0`` with coefficient of restitution ``e``.

    Made by :func:`ground`, :func:`wall`, :func:`plane` and :func:`between`; ``gap(model)`` is the gap in
    terms of the model's coordinates, positive while the contact is open.
    """

    name: str
    e: Any

    def gap(self, model, *, generic: bool = False) -> sp.Expr:  # pragma: no cover - every contact overrides it
        """The gap ``g`` in terms of the coordinate functions ``q(t)``; ``generic``: with the model's parameters given
        as numbers still the symbols standing for them (a run puts in its own values, ``params=`` included)."""
        raise NotImplementedError

    def __repr__(self) -> str:
        return f"<contact {self.name!r}, e={self.e}>"


class _Plane(Contact):
    def __init__(self, point, normal, through, e, name):
        self.point, self.normal, self.through = point, normal, through
        self.name = _contact_name(name, f"plane({point})")
        self.e = _restitution(e, self.name)

    def gap(self, model, *, generic: bool = False):
        view = _view(model, self.name, generic)
        n = _as_vector(self.normal, view.dim, f"contact {self.name!r}: the normal")
        norm = sp.sqrt(sum(x**2 for x in n))
        if norm == 0:
            raise ContactError(f"contact {self.name!r}: the normal must not be the zero vector.")
        a = sp.zeros(view.dim, 1) if self.through is None else _as_vector(self.through, view.dim, f"contact {self.name!r}: the point on the surface")
        r = _position(model, self.point, self.name, generic)
        return sp.Add(*[ni * (ri - ai) for ni, ri, ai in zip(n / norm, r, a) if ni != 0])


class _Between(Contact):
    def __init__(self, a, b, distance, e, name):
        self.a, self.b, self.distance = a, b, as_expr(distance, "between(): distance")
        self.name = _contact_name(name, f"between({a}, {b})")
        self.e = _restitution(e, self.name)

    def gap(self, model, *, generic: bool = False):
        view = _view(model, self.name, generic)
        d = _position(model, self.b, self.name, generic) - _position(model, self.a, self.name, generic)
        if view.dim == 1:
            return d[0] - self.distance
        if self.distance == 0:
            raise ContactError(
                f"contact {self.name!r}: in {view.dim}-D two points meet along no defined normal; give the contact "
                f"distance (the sum of the radii) as distance=... > 0."
            )
        return sp.sqrt(sum(x**2 for x in d)) - self.distance


def plane(point: str, normal, through=None, *, e=1, name: str | None = None) -> Contact:
    """Contact of ``point`` with the plane (a line in 2-D, a point in 1-D) through ``through`` (default the origin)
    with unit ``normal`` pointing to the free side: ``g = n · (r − a)``.

    >>> plane("bob", (1, 1), e=0.5)
    <contact 'plane(bob)', e=0.500000000000000>
    """
    return _Plane(point, normal, through, e, name)


class _Ground(Contact):
    def __init__(self, point, level, e, name):
        self.point, self.level = point, as_expr(level, "ground(): level")
        self.name = _contact_name(name, f"ground({point})")
        self.e = _restitution(e, self.name)

    def gap(self, model, *, generic: bool = False):
        view = _view(model, self.name, generic)
        return _position(model, self.point, self.name, generic)[view.dim - 1] - self.level


class _Wall(Contact):
    def __init__(self, point, x, side, e, name):
        self.name = _contact_name(name, f"wall({point})")
        if side not in (-1, 1):
            raise ContactError(f"contact {self.name!r}: side must be -1 (the point at x < wall) or +1 (x > wall), got {side!r}.")
        self.point, self.x, self.side = point, as_expr(x, "wall(): x"), side
        self.e = _restitution(e, self.name)

    def gap(self, model, *, generic: bool = False):
        return self.side * (_position(model, self.point, self.name, generic)[0] - self.x)


def ground(point: str, *, e=1, level=0, name: str | None = None) -> Contact:
    """Contact of ``point`` with the ground: the plane ``height = level`` of the last axis (x in 1-D, y in 2-D,
    z in 3-D), free side up — against the default direction of gravity.

    >>> ground("ball", e=0.8).name
    'ground(ball)'
    """
    return _Ground(point, level, e, name)


def wall(point: str, x, *, side: int, e=1, name: str | None = None) -> Contact:
    """Contact of ``point`` with the wall ``x = x_wall`` (first axis); ``side`` says where the point is:
    ``-1`` for ``x < x_wall``, ``+1`` for ``x > x_wall``.

    >>> wall("bob", 0, side=+1, e=0.9).name
    'wall(bob)'
    """
    return _Wall(point, x, side, e, name)


def between(a: str, b: str, *, distance=0, e=1, name: str | None = None) -> Contact:
    """Contact between two points of the model at ``distance`` (balls of radii r₁, r₂: r₁ + r₂):
    ``g = |r_b − r_a| − distance``; in 1-D the signed ``x_b − x_a − distance`` (``b`` ahead of ``a``).

    >>> between("m1", "m2", distance=0.1, e=1).name
    'between(m1, m2)'
    """
    return _Between(a, b, distance, e, name)


class Lock:
    """A sudden bilateral constraint ``J(q, t) q̇⁺ + b(q, t) = 0`` (perfectly plastic); made by :func:`fix` and
    :func:`lock`.  ``rows(model)`` gives ``(J, b)`` in the coordinate functions' symbols (``generic=True``: with the
    parameters given as numbers still the symbols standing for them)."""

    name: str

    def rows(self, model, *, generic: bool = False) -> tuple[sp.Matrix, sp.Matrix]:  # pragma: no cover - overridden
        raise NotImplementedError

    def __repr__(self) -> str:
        return f"<sudden constraint {self.name!r}>"


class _Fix(Lock):
    def __init__(self, point, name):
        self.point = point
        self.name = _contact_name(name, f"fix({point})")

    def rows(self, model, *, generic: bool = False):
        eq = model.eq
        r = _position(model, self.point, self.name, generic)
        return r.jacobian(eq.sym.q), r.diff(t)


class _LockJoint(Lock):
    def __init__(self, joint, name):
        self.joint = joint
        self.name = _contact_name(name, f"lock({joint})")

    def rows(self, model, *, generic: bool = False):
        eq = model.eq
        try:
            comp = model.component(self.joint)
        except UnknownNameError as exc:
            raise ContactError(f"sudden constraint {self.name!r}: {exc}") from None
        if tuple(getattr(comp, "terminals", ())) != ("parent", "child") or not hasattr(comp, "names"):
            raise ContactError(f"sudden constraint {self.name!r}: {comp.kind} {self.joint!r} is not a joint; lock a joint (revolute, prismatic, ...).")
        view = _view(model, self.name, generic)
        if comp.kind == "revolute" and view.dim == 2:  # the relative angular velocity, whatever the angle's reference
            rel = view.pose(comp.nodes[1]).omega - view.pose(comp.nodes[0]).omega
            w = eq.symbolic(rel)
            return sp.Matrix([[w.diff(v) for v in eq.sym.v]]), sp.Matrix([w.xreplace({v: 0 for v in eq.sym.v})])
        names = comp.names(view.dim)
        missing = [n for n in names if n not in eq.names]
        if missing:
            raise ContactError(
                f"sudden constraint {self.name!r}: joint {self.joint!r} has no free coordinates (it is driven, or closes a "
                f"loop); lock a joint of the tree that has coordinates."
            )
        rows = sp.zeros(len(names), len(eq.names))
        for k, n in enumerate(names):
            rows[k, eq.names.index(n)] = 1
        return rows, sp.zeros(len(names), 1)


def fix(point: str, *, name: str | None = None) -> Lock:
    """A point of the model suddenly fixed (caught): its velocity becomes zero.

    >>> fix("rod.end")
    <sudden constraint 'fix(rod.end)'>
    """
    return _Fix(point, name)


def lock(joint: str, *, name: str | None = None) -> Lock:
    """A joint suddenly locked: its relative motion stops (the bodies it joins move on as one).

    >>> lock("elbow")
    <sudden constraint 'lock(elbow)'>
    """
    return _LockJoint(joint, name)


# -- the model's points ----------------------------------------------------------------------------


def _view(model, who, generic: bool = False):
    """The domain view that knows point positions (the mechanical one); ``generic``: the one built in the symbols
    standing for the parameters given as numbers (what a run with other values in ``params=`` evaluates)."""
    assembly = model.assembly
    for view in (assembly.generic_views if generic else assembly.views).values():
        if callable(getattr(view, "position", None)) and hasattr(view, "dim"):
            return view
    raise ContactError(f"{who}: model {model.name!r} has no points with positions (no mechanical nodes); give impulses per coordinate instead.")


def _known_points(model, view) -> list[str]:
    points = [n for n in model.nodes if n != "ground"]
    for body, comp in getattr(view, "bodies", {}).items():
        points += [f"{body}.{p}" for p in comp.point_offsets(view.dim)]
    return list(dict.fromkeys(points))


def _position(model, point, who, generic: bool = False) -> sp.Matrix:
    """The position of ``point`` in the plain coordinate symbols of ``model.eq`` (``generic``: see :func:`_view`)."""
    view = _view(model, who, generic)
    if not isinstance(point, str):
        raise ContactError(f"{who}: points are named by strings (a node, or '<body>.<point>'), got {point!r}.")
    try:
        pos = view.position(point)
    except (UnknownNameError, ModelError):
        known = _known_points(model, view)
        raise ContactError(
            f"{who}: unknown point {point!r}.{closest(point, known)} Points of model {model.name!r}: {', '.join(known)} "
            f"(a body's named points are '<body>.<point>'; add a point with the body's points={{...}})."
        ) from None
    return model.eq.symbolic(sp.Matrix(pos))


def _check_names(model, given: Mapping, what: str) -> None:
    for name in given:
        if name not in model.eq.names:
            raise UnknownNameError(what, name, model.eq.names)
