"""Impulsive motion: generalized impulses, velocity jumps, impacts with restitution, hybrid simulation.

Integrating Lagrange's equations over an impact of vanishing duration, with
the coordinates continuous and the velocities bounded (notes, eqs. 2.97–2.99),
leaves

    Δp_k = Q̂_k,    i.e.  M(q, t) (q̇⁺ − q̇⁻) = Q̂        (coordinates held fixed),

with the generalized impulse found like a generalized force, from the virtual
impulsive work of impulses P̂ applied at points: ``Q̂_k = Σ P̂ · ∂r/∂q_k``.
No differential equation is solved: the post-impulse velocities come from one
linear system.  Loop-closure constraints ``Φ(q, t) = 0`` add their own
impulses ``Φ_qᵀ μ`` and keep ``Φ_q q̇⁺ + Φ_t = 0``; sudden constraints (a point
suddenly fixed: :func:`fix`, a joint suddenly locked: :func:`lock`) do the
same for rows of their own (a perfectly plastic velocity projection).

A **contact** (:func:`ground`, :func:`wall`, :func:`plane`, :func:`between`)
is a frictionless unilateral constraint ``g(q, t) ≥ 0`` (the gap) with a
coefficient of restitution ``e ∈ [0, 1]``.  Its impulse acts along the gap's
gradient, ``Q̂ = ∇_q g · Λ`` with ``Λ ≥ 0``, and Newton's law fixes its size:
the normal velocity ``ġ = ∇_q g · q̇ + ∂g/∂t`` becomes ``ġ⁺ = −e ġ⁻``.
Several simultaneous contacts are solved jointly: with the *Delassus matrix*
``G = Wᵀ M⁻¹ W`` (on the constrained motions), the impulses solve the linear
complementarity problem ``ġ⁺ + e ġ⁻ = ġ_free + e ġ⁻ + G Λ ≥ 0``, ``Λ ≥ 0``,
complementary (a closed contact that is separating keeps ``ġ⁺ ≥ 0``: it must
not be pushed into its surface).  It is solved by active sets, not by an LCP
library: start with the approaching contacts, solve them as equalities, drop
the most negative impulse or add the most violated contact, repeat; should
that ever cycle, every active set is tried in turn (a handful of contacts at
most).  An active contact that was approaching loses ``½ Λ (1 − e) |ġ⁻|`` of
kinetic energy, so a single contact never gains energy for ``e ≤ 1`` and keeps
it for ``e = 1`` (scleronomic model).  At several contacts Newton's law can
create energy (a separating contact pushed back by the others); when it would,
the impact uses the plastic impulses ``Λ⁰`` (the M-projection of the velocity
onto the admissible cone) times ``1 + s``, ``s ≤ min e`` and small enough to
keep every normal velocity ġ⁺ ≥ 0: then ``T⁺ = ½|v⁰|² + ½ s²|Δv⁰|² ≤ T⁻``, and
the :class:`Jump` notes say so.

A point struck at rest — a free rod hit at one end turns about the point at
two thirds of its length from the struck end:

>>> import lagrangian as lg
>>> from lagrangian.impulse import Impulse, velocity_jump
>>> m = lg.Model("rod", dim=2)
>>> _ = m.add("rod", "rod", "rod", m=1, length=2)
>>> _ = m.add("free", "fly", ("ground", "rod"), child_point=(1, 0))
>>> jump = velocity_jump(m, [Impulse("rod.end", (0, 1))], at={"theta_fly": 0})
>>> jump.after   # v_G = P/m, ω = 6P/(m ℓ)
{'x_fly': 0, 'y_fly': 1, 'theta_fly': 3}
>>> jump.energy_lost   # the impulse does work: T = P²/(2m) + ½ (mℓ²/12) ω² = 2 P²/m
-2

A ball dropped onto the ground, with ``e = 1/2`` (all exact, since every
number given is):

>>> from lagrangian.impulse import ground, impact
>>> ball = lg.Model("ball")
>>> _ = ball.add("mass", "m", "ball", m=2)
>>> _ = ball.add("gravity", "g")
>>> hit = impact(ball, [ground("ball", e=sp.Rational(1, 2))], at={"x_ball": 0}, velocity={"x_ball": -4})
>>> hit.after, hit.impulses, hit.energy_lost
({'x_ball': 2}, {'ground(ball)': 12}, 12)

The hybrid simulation (:func:`simulate_with_impacts`) integrates between
impacts, stops where a gap reaches zero while closing, applies the impact map
and goes on; when impacts accumulate (a bouncing ball with ``e < 1``: Zeno
behaviour) it switches the contact to resting contact.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import sympy as sp

from ..base.component import t
from ..errors import ModelError, NumericalError, SingularMassMatrixError, UnknownNameError, IntegrationError, closest
from ..errors import ExpressionError
from ..numerics.simulation import Result, initial_state
from ..model import Model
from ..base.text import as_expr

__all__ = [
    "Impulse",
    "Contact",
    "Lock",
    "ground",
    "wall",
    "plane",
    "between",
    "fix",
    "lock",
    "generalized_impulse",
    "velocity_jump",
    "impact",
    "Jump",
    "simulate_with_impacts",
    "ImpactRecord",
    "ImpactResult",
    "ContactError",
    "ImpactError",
    "SingularImpactError",
    "GrazingImpactError",
]


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

    def gap(self, model) -> sp.Expr:  # pragma: no cover - every contact overrides it
        """The gap ``g`` in terms of the coordinate functions ``q(t)``."""
        raise NotImplementedError

    def __repr__(self) -> str:
        return f"<contact {self.name!r}, e={self.e}>"


class _Plane(Contact):
    def __init__(self, point, normal, through, e, name):
        self.point, self.normal, self.through = point, normal, through
        self.name = _contact_name(name, f"plane({point})")
        self.e = _restitution(e, self.name)

    def gap(self, model):
        view = _view(model, self.name)
        n = _as_vector(self.normal, view.dim, f"contact {self.name!r}: the normal")
        norm = sp.sqrt(sum(x**2 for x in n))
        if norm == 0:
            raise ContactError(f"contact {self.name!r}: the normal must not be the zero vector.")
        a = sp.zeros(view.dim, 1) if self.through is None else _as_vector(self.through, view.dim, f"contact {self.name!r}: the point on the surface")
        r = _position(model, self.point, self.name)
        return sp.Add(*[ni * (ri - ai) for ni, ri, ai in zip(n / norm, r, a) if ni != 0])


class _Between(Contact):
    def __init__(self, a, b, distance, e, name):
        self.a, self.b, self.distance = a, b, as_expr(distance, "between(): distance")
        self.name = _contact_name(name, f"between({a}, {b})")
        self.e = _restitution(e, self.name)

    def gap(self, model):
        view = _view(model, self.name)
        d = _position(model, self.b, self.name) - _position(model, self.a, self.name)
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

    def gap(self, model):
        view = _view(model, self.name)
        return _position(model, self.point, self.name)[view.dim - 1] - self.level


class _Wall(Contact):
    def __init__(self, point, x, side, e, name):
        self.name = _contact_name(name, f"wall({point})")
        if side not in (-1, 1):
            raise ContactError(f"contact {self.name!r}: side must be -1 (the point at x < wall) or +1 (x > wall), got {side!r}.")
        self.point, self.x, self.side = point, as_expr(x, "wall(): x"), side
        self.e = _restitution(e, self.name)

    def gap(self, model):
        return self.side * (_position(model, self.point, self.name)[0] - self.x)


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
    :func:`lock`.  ``rows(model)`` gives ``(J, b)`` in the coordinate functions' symbols."""

    name: str

    def rows(self, model) -> tuple[sp.Matrix, sp.Matrix]:  # pragma: no cover - overridden
        raise NotImplementedError

    def __repr__(self) -> str:
        return f"<sudden constraint {self.name!r}>"


class _Fix(Lock):
    def __init__(self, point, name):
        self.point = point
        self.name = _contact_name(name, f"fix({point})")

    def rows(self, model):
        eq = model.eq
        r = _position(model, self.point, self.name)
        return r.jacobian(eq.sym.q), r.diff(t)


class _LockJoint(Lock):
    def __init__(self, joint, name):
        self.joint = joint
        self.name = _contact_name(name, f"lock({joint})")

    def rows(self, model):
        eq = model.eq
        try:
            comp = model.component(self.joint)
        except UnknownNameError as exc:
            raise ContactError(f"sudden constraint {self.name!r}: {exc}") from None
        if tuple(getattr(comp, "terminals", ())) != ("parent", "child") or not hasattr(comp, "names"):
            raise ContactError(f"sudden constraint {self.name!r}: {comp.kind} {self.joint!r} is not a joint; lock a joint (revolute, prismatic, ...).")
        view = _view(model, self.name)
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


def _view(model, who):
    """The domain view that knows point positions (the mechanical one)."""
    for view in model.assembly.views.values():
        if callable(getattr(view, "position", None)) and hasattr(view, "dim"):
            return view
    raise ContactError(f"{who}: model {model.name!r} has no points with positions (no mechanical nodes); give impulses per coordinate instead.")


def _known_points(model, view) -> list[str]:
    points = [n for n in model.nodes if n != "ground"]
    for body, comp in getattr(view, "bodies", {}).items():
        points += [f"{body}.{p}" for p in comp.point_offsets(view.dim)]
    return list(dict.fromkeys(points))


def _position(model, point, who) -> sp.Matrix:
    """The position of ``point`` in the plain coordinate symbols of ``model.eq``."""
    view = _view(model, who)
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


def _applied(model, impulses) -> sp.Matrix:
    """``Q̂`` of the applied impulses (point impulses and per-coordinate ones) in plain symbols."""
    eq = model.eq
    n = len(eq.names)
    Q = sp.zeros(n, 1)
    if impulses is None:
        return Q
    if isinstance(impulses, (Impulse, Mapping)):
        impulses = [impulses]
    for item in impulses:
        if isinstance(item, Impulse):
            who = f"impulse at {item.point!r}"
            r = _position(model, item.point, who)
            P = _as_vector(item.vector, r.rows, f"{who}: the impulse vector")
            Q += r.jacobian(eq.sym.q).T * P  # Q̂_k = P̂ · ∂r/∂q_k
        elif isinstance(item, Mapping):
            _check_names(model, item, "coordinate (generalized impulse)")
            for name, value in item.items():
                Q[eq.names.index(name)] += as_expr(value, f"the generalized impulse on {name!r}")
        else:
            raise ContactError(f"impulses are lagrangian.impulse.Impulse(point, vector) or {{coordinate: value}} mappings, got {item!r}.")
    return Q


def generalized_impulse(model, impulses, *, at: Mapping[str, Any] | None = None, params: Mapping[str, Any] | None = None,
                        coordinates: Mapping[str, Any] | None = None) -> dict[str, sp.Expr]:
    """The generalized impulses ``Q̂_k = Σ P̂ · ∂r/∂q_k`` of ``impulses`` (a list of :class:`Impulse` and/or
    ``{coordinate: value}`` mappings), by coordinate name, in terms of the coordinates ``q(t)`` (or of the
    values given in ``at``; ``params`` substitutes parameters by name).

    ``coordinates`` expresses them in other generalized coordinates: it gives each model coordinate as a
    function of the new ones (SymPy symbols), and the result is keyed by the new symbols' names,
    ``Q̂_ξ = Σ_k Q̂_k ∂q_k/∂ξ`` (the virtual impulsive work of one δξ at a time).

    >>> import lagrangian as lg
    >>> m = lg.Model("pendulum", dim=2)
    >>> _ = m.add("link", "arm", "arm", points={"bob": (2, 0)})
    >>> _ = m.add("revolute", "pin", ("ground", "arm"), absolute=True)
    >>> _ = m.add("mass", "m", "arm.bob", m=1)
    >>> generalized_impulse(m, [Impulse("arm.bob", (1, 0))])
    {'theta_pin': -2*sin(theta_pin(t))}
    """
    eq = model.eq
    Q = _applied(model, impulses)
    subs = _substitution(model, at or {}, {}, params or {}, None)
    Q = Q.xreplace(subs)
    if coordinates is None:
        return {n: eq.display(x) for n, x in zip(eq.names, Q)}
    _check_names(model, coordinates, "coordinate")
    missing = [n for n in eq.names if n not in coordinates]
    if missing:
        raise ContactError(f"`coordinates` must give every model coordinate in terms of the new ones; missing: {', '.join(missing)}.")
    exprs = [as_expr(coordinates[n], f"coordinates[{n!r}]") for n in eq.names]
    new = sorted(set().union(*(e.free_symbols for e in exprs)) - set(_param_symbols(model)) - {t}, key=str)
    back = {s: e for s, e in zip(eq.sym.q, exprs)}
    Q = Q.applyfunc(lambda x: eq.symbolic(x).xreplace(back))
    return {s.name: sp.simplify(sum(Q[k] * exprs[k].diff(s) for k in range(len(exprs)))) for s in new}


def _param_symbols(model) -> list[sp.Symbol]:
    return list(model.parameters)


def _geometry_symbols(model) -> list[sp.Symbol]:
    """Symbols the user gave in components' parameters (a point's position along a body, say) that the
    equations may not contain: contacts and impulses at those points still need their values."""
    out: set[sp.Symbol] = set()

    def walk(value):
        if isinstance(value, dict):
            for item in value.values():
                walk(item)
        elif isinstance(value, (sp.Basic, sp.MatrixBase)):
            out.update(s for s in value.free_symbols if isinstance(s, sp.Symbol) and s != t)

    for comp in model.components.values():
        walk(comp.params)
    return sorted(out, key=lambda s: s.name)


def _substitution(model, at, velocity, params, time) -> dict:
    """Values for the plain symbols: given coordinates, velocities (0 when absent), parameters by name, time."""
    eq = model.eq
    _check_names(model, at, "coordinate")
    _check_names(model, velocity, "coordinate")
    subs: dict = {}
    for q, name in zip(eq.sym.q, eq.names):
        subs[q] = as_expr(at[name], f"at[{name!r}]") if name in at else eq.display(q)
    for v, name in zip(eq.sym.v, eq.names):
        subs[v] = as_expr(velocity.get(name, 0), f"velocity[{name!r}]")
    by_name: dict[str, list] = {}
    for s in [*model.parameters, *_geometry_symbols(model)]:  # also symbols only in points (where impulses act)
        if s not in by_name.get(s.name, []):
            by_name.setdefault(s.name, []).append(s)
    for name, value in params.items():
        if name not in by_name:
            raise UnknownNameError("parameter", name, by_name)
        for s in by_name[name]:
            subs[s] = as_expr(value, f"params[{name!r}]")
    if time is not None:
        subs[t] = as_expr(time, "time")
    return subs


# -- the jump --------------------------------------------------------------------------------------


@dataclass
class Jump:
    """The outcome of an impulse, impact or sudden constraint at one instant (coordinates unchanged).

    ``before`` and ``after``: generalized velocities q̇⁻, q̇⁺ by coordinate; ``generalized``: the total
    generalized impulse ``Δp = M Δq̇`` (applied + contact + constraint impulses); ``impulses``: each
    contact's normal impulse ``Λ ≥ 0`` (a sudden constraint: the tuple of its rows' impulses);
    ``normal_before`` / ``normal_after``: each contact's normal velocity ġ⁻, ġ⁺; ``T_before``, ``T_after``:
    kinetic energy; ``exact``: SymPy results (something was symbolic or every input exact) rather than floats;
    ``notes``: what the solution wants known (contacts that separated, redundant contacts).
    """

    before: dict[str, Any]
    after: dict[str, Any]
    generalized: dict[str, Any]
    impulses: dict[str, Any]
    normal_before: dict[str, Any]
    normal_after: dict[str, Any]
    T_before: Any
    T_after: Any
    exact: bool
    notes: list[str] = field(default_factory=list)

    @property
    def energy_lost(self):
        """``T⁻ − T⁺`` (negative when applied impulses do work)."""
        lost = self.T_before - self.T_after
        return sp.simplify(lost) if self.exact else lost

    def change(self, name: str):
        """``q̇⁺ − q̇⁻`` of one coordinate."""
        if name not in self.after:
            raise UnknownNameError("coordinate", name, self.after)
        d = self.after[name] - self.before[name]
        return sp.simplify(d) if self.exact else d


class _Setup:
    """Everything of an impulse problem in the plain symbols of ``model.eq``."""

    def __init__(self, model, contacts=(), impulses=None):
        eq = self.eq = model.eq
        self.model = model
        q = eq.sym.q
        self.contacts = [c for c in contacts if isinstance(c, Contact)]
        self.locks = [c for c in contacts if isinstance(c, Lock)]
        bad = [c for c in contacts if not isinstance(c, (Contact, Lock))]
        if bad:
            raise ContactError(
                f"{bad[0]!r} is not a contact or sudden constraint: make contacts with ground(), wall(), plane() or "
                f"between(), sudden constraints with fix() or lock() (lagrangian.impulse)."
            )
        names = [c.name for c in contacts]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise ContactError(f"two contacts are named {dup[0]!r}: give them distinct names (name=...).")
        self.Q = _applied(model, impulses)
        if eq.first_order:
            raise ContactError(
                f"coordinates {', '.join(eq.names[i] for i in eq.first_order)} of model {model.name!r} have no inertia: "
                f"an impulse would change their velocity without bound. Give them inertia (a mass, an inductor)."
            )
        self.gaps = [sp.sympify(eq.symbolic(c.gap(model))) for c in self.contacts]
        self.W = sp.Matrix.hstack(*[sp.Matrix([g.diff(s) for s in q]) for g in self.gaps]) if self.gaps else sp.zeros(len(q), 0)
        self.gt = sp.Matrix([g.diff(t) for g in self.gaps]) if self.gaps else sp.zeros(0, 1)
        rows, rhs = [], []
        if len(eq.constraints):
            rows.append(eq.constraints.jacobian(q))
            rhs.append(eq.constraints.diff(t))
        self.lock_rows = []
        for lk in self.locks:
            J, b = lk.rows(model)
            keep = [k for k in range(J.rows) if any(x != 0 for x in J.row(k))]
            self.lock_rows.append((lk.name, len(keep)))
            rows.append(J.extract(keep, list(range(J.cols))) if keep else sp.zeros(0, len(q)))
            rhs.append(b.extract(keep, [0]) if keep else sp.zeros(0, 1))
        self.C = sp.Matrix.vstack(*rows) if rows else sp.zeros(0, len(q))
        self.c = sp.Matrix.vstack(*rhs) if rhs else sp.zeros(0, 1)
        self.loops = len(eq.constraints)
        self.e = [c.e for c in self.contacts]

    def row_owner(self, k: int) -> str:
        if k < self.loops:
            return "the loop-closure constraints"
        k -= self.loops
        for name, count in self.lock_rows:
            if k < count:
                return f"sudden constraint {name!r}"
            k -= count
        return "a constraint"  # pragma: no cover


def _numbers(*mats) -> bool:
    return all(all(x.is_number and x.is_real is not False for x in m) for m in mats)


def _arr(x: sp.Matrix) -> np.ndarray:
    return np.array(x.tolist(), dtype=float).reshape(x.shape) if x.rows * x.cols else np.zeros(x.shape)


def _resolve(setup: _Setup, subs: dict, approaching_only: bool, simplify: bool) -> Jump:
    """Solve the jump at the substituted configuration: numerically (with the active-set LCP) when every
    entry is a number, exactly (SymPy) when something is symbolic or every number is exact."""
    eq = setup.eq
    names, contacts = eq.names, [c.name for c in setup.contacts]
    M, W, gt, C, c, Q = (x.xreplace(subs) for x in (eq.M, setup.W, setup.gt, setup.C, setup.c, setup.Q))
    vb = sp.Matrix([subs[v] for v in eq.sym.v])
    e = sp.Matrix([sp.sympify(x).xreplace(subs) for x in setup.e])
    T_before = eq.T.xreplace(subs)
    mats = (M, W, gt, C, c, Q, vb, e)
    n, m, k = M.rows, C.rows, W.cols
    active, notes = list(range(k)), []
    if _numbers(*mats):
        va, lam, mu, notes, active = _solve_numeric(
            _arr(M), _arr(W), _arr(C), _arr(gt).reshape(-1), _arr(c).reshape(-1), _arr(Q).reshape(-1),
            _arr(vb).reshape(-1), _arr(e).reshape(-1), setup, approaching_only)
        if any(x.has(sp.Float) for mat in mats for x in mat):
            vsub = {**subs, **dict(zip(eq.sym.v, map(sp.Float, va)))}
            Wn, vn = _arr(W), _arr(vb).reshape(-1)
            return Jump(
                before=dict(zip(names, map(float, vn))), after=dict(zip(names, map(float, va))),
                generalized=dict(zip(names, map(float, _arr(M) @ (va - vn)))),
                impulses=_impulse_dict(setup, [float(x) for x in lam], [float(x) for x in mu]),
                normal_before=dict(zip(contacts, map(float, Wn.T @ vn + _arr(gt).reshape(-1)))),
                normal_after=dict(zip(contacts, map(float, Wn.T @ va + _arr(gt).reshape(-1)))),
                T_before=float(T_before), T_after=float(eq.T.xreplace(vsub)), exact=False, notes=notes,
            )
    else:
        gb0 = W.T * vb + gt
        if approaching_only:
            for j, name in enumerate(contacts):
                if gb0[j].is_number and gb0[j] > 0:
                    raise ContactError(
                        f"contact {name!r} is not closing: its normal velocity is {gb0[j]} (separating), so there is no "
                        f"impact to resolve. Check the sign of the velocity given, or the contact's side/normal.")
        if k > 1:
            notes.append("exact solution with every contact given taken as active (each impulse assumed ≥ 0)")
    # exact, with the active contacts as equalities
    Wa = W.extract(list(range(n)), active) if active else sp.zeros(n, 0)
    gb = W.T * vb + gt
    ka = len(active)
    K = sp.Matrix(sp.BlockMatrix([[M, -C.T, -Wa], [C, sp.zeros(m, m), sp.zeros(m, ka)],
                                  [Wa.T, sp.zeros(ka, m), sp.zeros(ka, ka)]])) if m + ka else M
    rows = sp.Matrix([-gt[j] - e[j] * gb[j] for j in active]) if active else sp.zeros(0, 1)
    rhs = sp.Matrix.vstack(M * vb + Q, -c, rows)
    u = _exact_solve(K, rhs)
    if u is None:
        raise SingularImpactError(_singular_symbolic(setup, M, C, W))
    tidy = sp.simplify if simplify else (lambda x: x)
    u = u.applyfunc(tidy)
    va = u[:n, 0]
    mu = list(u[n:n + m, 0])
    lam = [sp.Integer(0)] * k
    for j, x in zip(active, u[n + m:, 0]):
        lam[j] = x
    vsub = {**subs, **dict(zip(eq.sym.v, va))}
    return Jump(
        before={nm: eq.display(x) for nm, x in zip(names, vb)},
        after={nm: eq.display(x) for nm, x in zip(names, va)},
        generalized={nm: eq.display(tidy(x)) for nm, x in zip(names, M * (va - vb))},
        impulses={key: (eq.display(x) if isinstance(x, sp.Basic) else tuple(eq.display(y) for y in x))
                  for key, x in _impulse_dict(setup, lam, mu).items()},
        normal_before={nm: eq.display(tidy(x)) for nm, x in zip(contacts, gb)},
        normal_after={nm: eq.display(tidy(x)) for nm, x in zip(contacts, W.T * va + gt)},
        T_before=eq.display(tidy(T_before)), T_after=eq.display(tidy(eq.T.xreplace(vsub))), exact=True, notes=notes,
    )


def _exact_solve(K: sp.Matrix, rhs: sp.Matrix) -> sp.Matrix | None:
    """``K⁻¹ rhs`` exactly, or None if ``K`` is singular.  Functions (sin θ, cos θ, q(t)) and fractional powers
    become plain symbols so that the solve runs over a field of rational functions (no expression swell)."""
    from sympy.polys.matrices import DomainMatrix

    atoms = set()
    for x in (*K, *rhs):
        atoms |= {a for a in sp.preorder_traversal(x) if isinstance(a, (sp.Function, sp.Derivative))
                  or (isinstance(a, sp.Pow) and not a.exp.is_Integer)}
    # the outermost ones only (an atom inside another goes with it)
    outer = {a: sp.Dummy(f"a{i}") for i, a in enumerate(sorted(atoms, key=sp.default_sort_key))
             if not any(b != a and b.has(a) for b in atoms)}
    Kp, rp = K.xreplace(outer), rhs.xreplace(outer)
    try:
        A = DomainMatrix.from_Matrix(Kp)
        B = DomainMatrix.from_Matrix(rp)
        A, B = A.unify(B)
        A, B = A.to_field(), B.to_field()
        if A.rank() < A.shape[0]:
            return None
        u = A.lu_solve(B).to_Matrix()
    except (ZeroDivisionError, ValueError, sp.matrices.exceptions.NonInvertibleMatrixError):
        return None
    back = {d: a for a, d in outer.items()}
    return u.xreplace(back)


def _impulse_dict(setup, lam, mu) -> dict:
    out = dict(zip((c.name for c in setup.contacts), lam))
    k = setup.loops
    for name, count in setup.lock_rows:
        out[name] = tuple(mu[k:k + count])
        k += count
    return out


def _singular_symbolic(setup, M, C, W) -> str:
    if M.rank() < M.rows and (C.rows == 0 or sp.Matrix.vstack(M, C).rank() < M.rows):
        return (f"the mass matrix of model {setup.model.name!r} is singular here: some motion has no inertia, so no finite "
                f"impulse determines it. Give every coordinate inertia, or choose a configuration away from the singular one.")
    if C.rows and C.rank() < C.rows:
        return (f"the constraint rows ({', '.join(dict.fromkeys(setup.row_owner(k) for k in range(C.rows)))}) are dependent "
                f"here: their impulses are not determined. Drop a redundant sudden constraint, or move off the singular configuration.")
    return (f"the contacts {', '.join(c.name for c in setup.contacts)} cannot be resolved: a contact point cannot move "
            f"along its normal (infinite effective mass: the normal is blocked by the constraints, or the gap does not "
            f"change with any coordinate here), or two contacts repeat each other. Remove the redundant contact.")


def _solve_numeric(M, W, C, gt, c, Q, vb, e, setup, approaching_only, tol=1e-10, names=None):
    """Numeric impulse solution with the active-set LCP; returns ``(q̇⁺, Λ, μ, notes, active)``."""
    n, m, k = M.shape[0], C.shape[0], W.shape[1]
    notes: list[str] = []
    Kb = np.block([[M, -C.T], [C, np.zeros((m, m))]]) if m else M
    _check_bilateral(Kb, M, C, setup)
    free = np.linalg.solve(Kb, np.concatenate([M @ vb + Q, -c]))
    vf, muf = free[:n], free[n:]
    if not k:
        return vf, [], list(muf), notes, []
    X = np.linalg.solve(Kb, np.vstack([W, np.zeros((m, k))]))
    Xv, Xmu = X[:n], X[n:]
    G = W.T @ Xv
    gb = W.T @ vb + gt
    gf = W.T @ vf + gt
    speed = max(1e-300, float(np.max(np.abs(gb))), float(np.max(np.abs(vb)) if n else 0.0))
    names = [c.name for c in setup.contacts] if names is None else names
    if approaching_only:
        closing = [j for j in range(k) if gb[j] < -tol * speed]
        if not closing:
            j = int(np.argmin(gb))
            if gb[j] > tol * speed:
                raise ContactError(
                    f"contact {names[j]!r} is not closing: its normal velocity is {gb[j]:+.6g} (separating), so there is no "
                    f"impact to resolve. Check the sign of the velocity given, or the contact's side/normal."
                )
            raise GrazingImpactError(
                f"contact {names[j]!r} is grazing: its normal velocity {gb[j]:+.3g} is zero to within {tol:g} of the "
                f"velocity scale, so no impulse is needed. If the point should stay on the surface, it is a resting "
                f"contact (simulate_with_impacts switches to one); otherwise nothing happens."
            )
    scale = np.linalg.norm(M, 2)
    for j in range(k):
        wn = float(np.linalg.norm(W[:, j]))
        if wn == 0.0 or G[j, j] <= 1e-12 * wn**2 / scale:
            why = ("its gap does not change with any coordinate at this configuration (the normal is tangent to every "
                   "possible motion of the point)" if wn == 0.0 else
                   "its point cannot move along the normal: that motion is blocked by the constraints (infinite effective mass)")
            raise SingularImpactError(
                f"contact {names[j]!r} cannot be resolved: {why}, so no finite impulse satisfies the restitution law. "
                f"Move the contact, or choose a configuration where the point can move along the normal."
            )
    candidates = list(range(k))  # every closed contact: a separating one must not be pushed into the surface
    lam, active = _lcp(G, gb, gf, e, candidates, tol, speed, names)
    if len(active) > 1 and np.linalg.matrix_rank(G[np.ix_(active, active)]) < len(active):
        notes.append(f"contacts {', '.join(names[j] for j in active)} are redundant: the impulses shown are the smallest "
                     f"(least-squares) split among them; the velocities are determined")
    dv = Xv @ lam
    gain = (vf + dv - vb) @ M @ (vf + dv + vb) / 2 - (vf - vb) @ M @ (vf + vb) / 2  # the contacts' share of ΔT
    if k > 1 and gain > 1e-12 * max(1e-300, float(vb @ M @ vb)):
        # Newton's law at several contacts can create energy when a separating contact is pushed back; use the
        # plastic impulses Λ⁰ scaled by 1 + s instead: with v⁰ the M-projection, T⁺ = ½|v⁰|² + ½ s² |Δv⁰|² ≤ T⁻
        lam0, active = _lcp(G, gb, gf, np.zeros(k), candidates, tol, speed, names)
        g0, d = gf + G @ lam0, G @ lam0
        s = min((e[j] for j in active), default=0.0)
        for j in range(k):
            if d[j] < 0:
                s = min(s, max(g0[j], 0.0) / -d[j])
        lam = (1 + s) * lam0
        notes.append(f"Newton's law at the simultaneous contacts would create kinetic energy ({gain:.3g}); used the "
                     f"plastic impulses times 1 + {s:.6g} instead (energy-consistent restitution)")
    for j in candidates:
        if j not in active:
            notes.append(f"contact {names[j]!r} separates (no impulse)")
    va = vf + Xv @ lam
    mu = muf + Xmu @ lam
    return va, list(lam), list(mu), notes, sorted(active)


def _lcp(G, gb, gf, e, candidates, tol, speed, names):
    """Impulses ``Λ ≥ 0`` with ``ġ⁺ = gf + G Λ ≥ −e ġ⁻`` (for closing contacts; ≥ 0 otherwise), complementary: active
    sets (add the most violated contact, drop the most negative impulse), else every active set in turn."""
    k = len(gb)
    target = -e * np.minimum(gb, 0.0) - gf  # required G Λ so that ġ⁺ = −e ġ⁻ on active contacts

    def solve(active):
        lam = np.zeros(k)
        if active:
            A = G[np.ix_(active, active)]
            sol, *_ = np.linalg.lstsq(A, target[active], rcond=None)
            if np.max(np.abs(A @ sol - target[active]), initial=0) > 1e-9 * max(1.0, float(np.max(np.abs(target[active])))):
                return None
            lam[active] = sol
        return lam

    def ok(lam):
        post = G @ lam - target
        return (np.all(lam[candidates] >= -tol * max(1.0, np.max(np.abs(lam)))) and
                np.all(post[candidates] >= -tol * speed))

    active = [j for j in candidates if gb[j] < -tol * speed] or list(candidates)
    lam = None
    for _ in range(4 * k + 4):
        lam = solve(active)
        if lam is None or ok(lam):
            break
        post = G @ lam - target
        neg = [j for j in active if lam[j] < 0]
        if neg:
            active.remove(min(neg, key=lambda j: lam[j]))
            continue
        viol = [j for j in candidates if j not in active and post[j] < -tol * speed]
        if not viol:
            break
        active.append(min(viol, key=lambda j: post[j]))
    if lam is None or not ok(lam):
        lam = None
        for size in range(len(candidates), -1, -1):  # every active set in turn
            for subset in itertools.combinations(candidates, size):
                trial = solve(list(subset))
                if trial is not None and ok(trial):
                    lam, active = trial, list(subset)
                    break
            if lam is not None:
                break
    if lam is None:
        raise SingularImpactError(
            f"the simultaneous contacts {', '.join(names[j] for j in candidates)} admit no consistent set of impulses "
            f"(the restitution targets contradict each other through redundant contacts). Give the contacts one "
            f"coefficient of restitution, or remove a redundant contact."
        )
    return np.maximum(lam, 0.0), [j for j in active if lam[j] > 0] if len(active) else []


def _check_bilateral(Kb, M, C, setup) -> None:
    s = np.linalg.svd(Kb, compute_uv=False)
    if s[-1] > 1e-12 * max(s[0], 1e-300):
        return
    names = setup.eq.names
    if C.shape[0]:
        _, sc, vt = np.linalg.svd(C)
        if len(sc) < C.shape[0] or sc[-1] <= 1e-10 * max(sc[0], 1e-300):
            uc = np.linalg.svd(C)[0][:, -1]
            owners = dict.fromkeys(setup.row_owner(r) for r in np.flatnonzero(np.abs(uc) > 1e-8))
            raise SingularImpactError(
                f"the constraints ({', '.join(owners)}) are dependent at this configuration: their impulses are not "
                f"determined. Drop a redundant sudden constraint, or move off the singular configuration (links in line)."
            )
    _, sm, vt = np.linalg.svd(M)
    null = vt[-1]
    involved = [nm for nm, w in zip(names, null) if abs(w) > 1e-8]
    raise SingularImpactError(
        f"the mass matrix of model {setup.model.name!r} is singular here (smallest singular value {sm[-1]:.3g}): the motion "
        f"of {', '.join(involved)} has no inertia, so an impulse would change it without bound. Give it inertia, or "
        f"choose a configuration away from the singular one."
    )


def velocity_jump(model, impulses, *, at: Mapping[str, Any] | None = None, velocity: Mapping[str, Any] | None = None,
                  params: Mapping[str, Any] | None = None, constraints: Sequence[Lock] = (), time=0,
                  simplify: bool = True) -> Jump:
    """The velocities just after ``impulses`` (a list of :class:`Impulse` and/or ``{coordinate: value}``),
    from ``Δp = M Δq̇ = Q̂`` with the coordinates fixed at ``at`` (by name; those not given stay symbolic).

    ``velocity`` gives q̇⁻ by name (0 when absent: from rest); ``params`` substitutes parameters by name;
    ``constraints`` adds sudden constraints (:func:`fix`, :func:`lock`).  Loop-closure constraints keep
    ``Φ_q q̇⁺ + Φ_t = 0`` through their own impulses.  Numbers in, floats out (``Jump.exact`` False); any
    symbol or exact rational in, SymPy expressions out (simplified when ``simplify``).

    >>> import lagrangian as lg, sympy as sp
    >>> P, m = sp.symbols("P m", positive=True)
    >>> cart = lg.Model("cart")
    >>> _ = cart.add("mass", "M", "cart", m=m)
    >>> velocity_jump(cart, [Impulse("cart", P)]).after
    {'x_cart': P/m}
    """
    setup = _Setup(model, list(constraints), impulses)
    subs = _substitution(model, at or {}, velocity or {}, params or {}, time)
    return _resolve(setup, subs, approaching_only=False, simplify=simplify)


def impact(model, contacts, *, at: Mapping[str, Any] | None = None, velocity: Mapping[str, Any] | None = None,
           params: Mapping[str, Any] | None = None, impulses=None, time=0, simplify: bool = True) -> Jump:
    """Resolve an impact: ``contacts`` (from :func:`ground`, :func:`wall`, :func:`plane`, :func:`between`, and
    sudden constraints from :func:`fix`, :func:`lock`) are closed at the configuration ``at``, the model moving
    with ``velocity`` (by name, 0 when absent); optional ``impulses`` act at the same instant.

    Each contact's impulse ``Λ ≥ 0`` acts along the gap's gradient and gives ``ġ⁺ = −e ġ⁻``.  Numerically,
    simultaneous contacts are solved as a complementarity problem (a contact that would need a pull separates
    instead, see the module's docstring); symbolically every contact given is taken as active.  A contact that
    is separating is a :class:`ContactError`; one with no normal velocity a :class:`GrazingImpactError`; a
    contact whose point cannot move along its normal a :class:`SingularImpactError`.

    The notes' rod (mass m, length 2L) falling flat at speed v onto a knife edge at L/2 from its centre:

    >>> import lagrangian as lg, sympy as sp
    >>> m, L, v, e = sp.symbols("m L v e", positive=True)
    >>> rod = lg.Model("rod", dim=2)
    >>> _ = rod.add("rod", "rod", "rod", m=m, length=2 * L, points={"P": (3 * L / 2, 0)})
    >>> _ = rod.add("free", "fly", ("ground", "rod"), child_point=(L, 0))
    >>> hit = impact(rod, [ground("rod.P", e=e)], at={"theta_fly": 0}, velocity={"y_fly": -v})
    >>> hit.after
    {'x_fly': 0, 'y_fly': v*(4*e - 3)/7, 'theta_fly': 6*v*(e + 1)/(7*L)}
    """
    contacts = list(contacts) if isinstance(contacts, Iterable) and not isinstance(contacts, (Contact, Lock)) else [contacts]
    if not contacts:
        raise ContactError("impact() needs at least one contact (ground(), wall(), plane(), between()) or sudden constraint.")
    setup = _Setup(model, contacts, impulses)
    subs = _substitution(model, at or {}, velocity or {}, params or {}, time)
    return _resolve(setup, subs, approaching_only=bool(setup.contacts) and impulses is None, simplify=simplify)


# -- hybrid simulation -----------------------------------------------------------------------------


@dataclass
class ImpactRecord:
    """One impact of a hybrid simulation: its ``time``, the ``contacts`` closed there, each one's normal
    impulse (``impulses``), the generalized velocities ``before`` and ``after``, the contacts' normal
    velocities, the kinetic energy before and after, and a ``note`` (e.g. a switch to resting contact)."""

    time: float
    contacts: list[str]
    impulses: dict[str, float]
    before: dict[str, float]
    after: dict[str, float]
    normal_before: dict[str, float]
    normal_after: dict[str, float]
    T_before: float
    T_after: float
    note: str = ""

    @property
    def energy_lost(self) -> float:
        """``T⁻ − T⁺`` at the impact."""
        return self.T_before - self.T_after


@dataclass
class ImpactResult(Result):
    """A :class:`~lagrangian.Result` with the impacts of a hybrid run (:func:`simulate_with_impacts`).

    The output grid holds every impact time twice, with the states just before and just after.
    ``impacts``: :class:`ImpactRecord` s in time order; ``resting``: ``(time, contact)`` where a contact
    switched to resting contact; ``liftoffs``: ``(time, contact)`` where a resting contact let go.
    """

    impacts: list[ImpactRecord] = field(default_factory=list)
    resting: list[tuple[float, str]] = field(default_factory=list)
    liftoffs: list[tuple[float, str]] = field(default_factory=list)

    @property
    def impact_times(self) -> np.ndarray:
        """Times of the impacts."""
        return np.array([r.time for r in self.impacts])

    @property
    def energy_lost(self) -> float:
        """Kinetic energy lost in all impacts together."""
        return float(sum(r.energy_lost for r in self.impacts))


def _fn(args, expr: sp.Matrix, shape):
    """A NumPy function of ``args`` returning a float array of ``shape`` (empty shapes allowed)."""
    if 0 in shape:
        return lambda *a: np.zeros(shape)
    f = sp.lambdify(args, expr, modules="numpy", cse=True)
    return lambda *a: np.asarray(f(*a), dtype=float).reshape(shape)


class _Hybrid:
    """Numeric pieces of a model with contacts (parameters substituted), and the impact map."""

    def __init__(self, model, contacts, params):
        self.numeric = numeric = model.numeric(params)
        self.setup = setup = _Setup(model, contacts)
        if setup.locks:
            raise ContactError(
                f"simulate_with_impacts takes contacts only; {setup.locks[0].name!r} is a sudden constraint: resolve it "
                f"with impact(), then simulate the constrained model."
            )
        if not setup.contacts:
            raise ContactError("simulate_with_impacts needs at least one contact (ground(), wall(), plane(), between()).")
        eq = self.eq = setup.eq
        vals = {s: sp.Float(v) for s, v in numeric.values.items()}
        self.e = []
        for cont in setup.contacts:
            e = sp.sympify(cont.e).xreplace({s: v for s, v in vals.items()})
            by_name = {s.name: x for s, x in numeric.values.items()}
            e = e.xreplace({s: by_name[s.name] for s in e.free_symbols if s.name in by_name})
            if not e.is_number:
                raise ContactError(f"contact {cont.name!r}: the coefficient of restitution {cont.e} needs a number to simulate.")
            self.e.append(float(e))
        self.e = np.array(self.e)
        n, k, m = len(eq.names), len(setup.contacts), setup.C.rows
        self.n, self.k, self.m = n, k, m
        q, v = list(eq.sym.q), list(eq.sym.v)
        sub = lambda x: x.xreplace(vals)
        self.M = _fn((t, q), sub(eq.M), (n, n))
        self.C = _fn((t, q), sub(setup.C), (m, n))
        self.c = _fn((t, q), sub(setup.c), (m,))
        self.Phi = _fn((t, q), sub(eq.constraints), (m,)) if m else (lambda *a: np.zeros(0))
        self.W = _fn((t, q), sub(setup.W), (n, k))
        self.gt = _fn((t, q), sub(setup.gt), (k,))
        self.gaps = _fn((t, q), sub(sp.Matrix(setup.gaps)), (k,))
        gdot = setup.W.T * sp.Matrix(v) + setup.gt
        h = gdot.jacobian(q) * sp.Matrix(v) + gdot.diff(t)
        self.h = _fn((t, q, v), sub(h), (k,))
        self.T = _fn((t, q, v), sub(sp.Matrix([eq.T])), (1,))
        self.names = [c.name for c in setup.contacts]
        self.rate = float(eq.constraint_rate)

    def Kb(self, tt, q):
        M, C = self.M(tt, q), self.C(tt, q)
        return (np.block([[M, -C.T], [C, np.zeros((self.m, self.m))]]) if self.m else M), M, C

    def rest_force(self, tt, y, a_free, R):
        """Multipliers ``λ`` holding the resting contacts ``R`` at zero gap, and the acceleration they add."""
        n = self.n
        q, v = y[:n], y[n:]
        Kb, _, _ = self.Kb(tt, q)
        W = self.W(tt, q)[:, R]
        X = np.linalg.solve(Kb, np.vstack([W, np.zeros((self.m, len(R)))]))[:n]
        G = W.T @ X
        g = self.gaps(tt, q)[R]
        gd = W.T @ v + self.gt(tt, q)[R]
        w = self.rate
        rhs = -(W.T @ a_free + self.h(tt, q, v)[R] + 2 * w * gd + w**2 * g)
        lam = np.linalg.lstsq(G, rhs, rcond=None)[0]
        return lam, X @ lam

    def rhs(self, tt, y, R):
        yd = self.numeric.rhs(tt, y)
        if R:
            _, acc = self.rest_force(tt, y, yd[self.n:], R)
            yd[self.n:] += acc
        return yd

    def resolve(self, tt, y, closed, e):
        """The impact map over the ``closed`` contacts with restitution ``e`` (an array over them)."""
        n = self.n
        q, v = y[:n], y[n:]
        _, M, C = self.Kb(tt, q)
        W = self.W(tt, q)[:, closed]
        gt = self.gt(tt, q)[closed]
        return _solve_numeric(M, W, C, gt, self.c(tt, q), np.zeros(n), v, e, self.setup, False,
                              names=[self.names[j] for j in closed])


def simulate_with_impacts(
    model,
    t_end: float | tuple[float, float],
    contacts: Sequence[Contact],
    *,
    initial: Mapping[str, float] | None = None,
    velocity: Mapping[str, float] | None = None,
    params: Mapping[str, float] | None = None,
    points: int = 1001,
    method: str = "DOP853",
    rtol: float = 1e-10,
    atol: float = 1e-12,
    max_step: float = np.inf,
    event_tol: float = 1e-12,
    rest_velocity: float | None = None,
    zeno_time: float | None = None,
    max_impacts: int = 10_000,
) -> ImpactResult:
    """Simulate ``model`` with ``contacts``: integrate, stop where a gap closes, apply the impact map, go on.

    Between impacts the model's equations are integrated by a SciPy solver (``method``: ``"DOP853"``,
    ``"RK45"``, ``"Radau"``, ...; ``rtol``, ``atol``, ``max_step``), stepped one step at a time: after each
    step the gaps are sampled on the step's dense output and a gap changing sign from positive to zero or
    below is located by Brent's method to ``event_tol`` in time.  There the contacts that are closed are
    resolved together (:func:`impact`), and integration restarts from the post-impact state.

    **Resting contact.**  A contact whose normal velocity after an impact is below ``rest_velocity``
    (default 10⁻⁶ of the fastest impact on it so far), or whose impacts come in a shrinking geometric
    sequence predicted to accumulate within ``zeno_time`` (default 10⁻⁶ of the time span; Zeno behaviour:
    a bouncing ball with ``e < 1`` has infinitely many impacts in finite time), switches to resting
    contact — a last plastic impact, then the gap is held at zero by a constraint force (Baumgarte
    stabilized) for as long as that force pushes; where it would pull, the contact lifts off.  A grazing
    contact (no normal velocity) falls under the same rule.  More than ``max_impacts`` impacts and switches
    is an :class:`ImpactError` (chattering), never an endless loop.

    Returns an :class:`ImpactResult`: the trajectory on ``points`` evenly spaced times plus every impact
    (twice: before and after), ``impacts`` with time, impulse, velocities and energy lost of each.

    A ball dropped from 1 m onto the ground (e = 0.5), first impact at √(2h/g):

    >>> import math, lagrangian as lg
    >>> ball = lg.Model("ball")
    >>> _ = ball.add("mass", "m", "ball", m=1)
    >>> _ = ball.add("gravity", "g", g=9.81)
    >>> res = simulate_with_impacts(ball, 1.0, [ground("ball", e=0.5)], initial={"x_ball": 1.0}, velocity={"x_ball": 0})
    >>> round(res.impacts[0].time, 10) == round(math.sqrt(2 / 9.81), 10)
    True
    >>> round(res.impacts[0].after["x_ball"] / math.sqrt(2 * 9.81), 10)   # e·√(2gh)
    0.5
    """
    from scipy import integrate as ivp
    from scipy.optimize import brentq

    hy = _Hybrid(model, contacts, params)
    eq, n, k = hy.eq, hy.n, hy.k
    span = Model._span(t_end)
    solver_cls = getattr(ivp, method, None) if isinstance(method, str) else method
    if not (isinstance(solver_cls, type) and issubclass(solver_cls, ivp.OdeSolver)):
        raise ModelError(f"method {method!r} is not a SciPy ODE solver; use one of RK45, RK23, DOP853, Radau, BDF, LSODA.")
    if not event_tol > 0:
        raise ModelError(f"event_tol must be a positive time, got {event_tol!r}.")
    y, defaulted = initial_state(eq, initial or {}, velocity or {})
    t0, t1 = span
    if hy.m and np.max(np.abs(hy.Phi(t0, y[:n]))) > 1e-8:
        raise ModelError(
            f"the initial state of model {model.name!r} does not close its kinematic loops: solve the dependent "
            f"coordinates first with lagrangian.plugins.multibody.consistent_initial(model, initial, velocity)."
        )
    zeno_time = 1e-6 * (t1 - t0) if zeno_time is None else float(zeno_time)
    grid = np.linspace(t0, t1, points)
    out_t: list[float] = []
    out_y: list[np.ndarray] = []
    gi = 0  # next grid index to output
    resting: list[int] = []
    history: dict[int, list[float]] = {j: [] for j in range(k)}
    fastest = np.zeros(k)
    records: list[ImpactRecord] = []
    rests: list[tuple[float, str]] = []
    lifts: list[tuple[float, str]] = []
    notes: list[str] = []
    nfev = 0
    switches = 0

    def scale_v(yy):
        return max(1.0, float(np.max(np.abs(yy[n:]), initial=0.0)))

    def state_gdot(tt, yy):
        q, v = yy[:n], yy[n:]
        return hy.W(tt, q).T @ v + hy.gt(tt, q)

    def settle(tt, yy, closed, candidates):
        """Resolve the impact on ``closed`` again with the contacts that come to rest (``candidates`` and those
        resting already) made plastic; keep those whose holding force pushes.  Returns the state and the rest set."""
        R = sorted(set(resting) | set(candidates))
        while True:
            e = np.array([0.0 if j in R else hy.e[j] for j in closed])
            va, lam, *_ = hy.resolve(tt, yy, closed, e)
            trial = np.concatenate([yy[:n], va])
            if not R:
                return trial, [], lam
            a_free = hy.numeric.rhs(tt, trial)[n:]
            force, _ = hy.rest_force(tt, trial, a_free, R)
            pulling = [j for j, f in zip(R, force) if f < 0]
            if not pulling:
                return trial, R, lam
            R = [j for j in R if j != min(pulling, key=lambda j: force[R.index(j)])]

    def handle_impact(tt, yy):
        nonlocal resting, switches
        q, v = yy[:n], yy[n:]
        g = hy.gaps(tt, q)
        gd = state_gdot(tt, yy)
        tol_gap = 4 * event_tol * np.abs(gd) + 1e-10 * (1 + float(np.max(np.abs(q)) if n else 0.0))
        closed = sorted(set(j for j in range(k) if g[j] <= tol_gap[j]) | set(resting))
        va, lam, _, sol_notes, active = hy.resolve(tt, yy, closed, hy.e[closed])
        post = np.concatenate([q, va])
        gd_post = state_gdot(tt, post)
        lam = dict(zip(closed, lam))
        note = []
        to_rest = []
        for j in closed:
            if j in resting:
                if gd_post[j] > 1e-9 * scale_v(post):
                    continue  # pushed off by the others: it lets go
                to_rest.append(j)
                continue
            if gd[j] < 0:
                fastest[j] = max(fastest[j], -gd[j])
                if lam.get(j, 0) > 0:
                    history[j].append(tt)
            limit = rest_velocity if rest_velocity is not None else max(1e-6 * fastest[j], 1e-9)
            if gd_post[j] <= limit:
                to_rest.append(j)
                note.append(f"{hy.names[j]}: normal velocity after impact {gd_post[j]:.3g} ≤ {limit:.3g}"
                            + (" (grazing)" if abs(gd[j]) <= limit else ""))
                continue
            h = history[j]
            if len(h) >= 3:
                d1, d2 = h[-2] - h[-3], h[-1] - h[-2]
                r = d2 / d1 if d1 > 0 else 1.0
                if 0 < r < 1 and d2 * r / (1 - r) < zeno_time:
                    to_rest.append(j)
                    note.append(f"{hy.names[j]}: impacts accumulate (interval ratio {r:.4g}; Zeno point predicted at "
                                f"t = {tt + d2 * r / (1 - r):.12g})")
        before_rest = list(resting)
        if to_rest:
            post, resting, lam_list = settle(tt, yy, closed, to_rest)
            lam = dict(zip(closed, lam_list))
        else:
            resting = [j for j in resting if gd_post[j] <= 1e-9 * scale_v(post)]
        for j in resting:
            if j not in before_rest:
                rests.append((tt, hy.names[j]))
                switches += 1
        for j in before_rest:
            if j not in resting:
                lifts.append((tt, hy.names[j]))
        if note and resting != before_rest:
            notes.append(f"t = {tt:.12g}: resting contact from here — " + "; ".join(note))
        va = post[n:]
        T0, T1 = float(hy.T(tt, q, v)[0]), float(hy.T(tt, q, va)[0])
        records.append(ImpactRecord(
            time=float(tt), contacts=[hy.names[j] for j in closed],
            impulses={hy.names[j]: float(lam.get(j, 0.0)) for j in closed},
            before=dict(zip(eq.names, map(float, v))), after=dict(zip(eq.names, map(float, va))),
            normal_before={hy.names[j]: float(gd[j]) for j in closed},
            normal_after={hy.names[j]: float(x) for j, x in zip(range(k), state_gdot(tt, post)) if j in closed},
            T_before=T0, T_after=T1,
            note="; ".join(sol_notes + (["resting contact: " + ", ".join(hy.names[j] for j in resting)] if resting != before_rest and resting else [])),
        ))
        return post

    def first_step_after(tt, yy):
        """A first step short enough not to jump over a short flight right after an impact."""
        gd = state_gdot(tt, yy)
        acc = hy.rhs(tt, yy, resting)[n:]
        gdd = hy.W(tt, yy[:n]).T @ acc + hy.h(tt, yy[:n], yy[n:])
        steps = [2 * gd[j] / -gdd[j] / 8 for j in range(k) if j not in resting and gd[j] > 0 and gdd[j] < 0]
        return min(steps) if steps else None

    tt = t0
    g0 = hy.gaps(t0, y[:n])
    for j in range(k):
        if g0[j] < -1e-9 * (1 + float(np.max(np.abs(y[:n])))):
            raise ContactError(
                f"contact {hy.names[j]!r} starts closed past the surface (gap {g0[j]:.6g} < 0): start the model on the "
                f"free side (gap ≥ 0), or check the contact's side/normal."
            )
    first = None
    if np.any(g0 <= 1e-10 * (1 + float(np.max(np.abs(y[:n]))))):
        out_t.append(tt)
        out_y.append(y.copy())
        gi = 1 if grid[0] <= tt else 0
        y = handle_impact(tt, y)
        if records and records[-1].impulses and all(x == 0 for x in records[-1].impulses.values()):
            records.pop()  # touching at rest: no impact
        first = first_step_after(tt, y)
    while tt < t1:
        mode = list(resting)
        first = min(first, t1 - tt) if first and t1 - tt > 0 else None
        solver = solver_cls(lambda s, yy: hy.rhs(s, yy, mode), tt, y, t1, rtol=rtol, atol=atol, max_step=max_step,
                            **({"first_step": first} if first else {}))
        first, event = None, None
        while solver.status == "running":
            try:
                solver.step()
            except (np.linalg.LinAlgError, SingularMassMatrixError) as exc:
                raise ImpactError(f"the integration of model {model.name!r} failed at t = {solver.t:.6g}: {exc}") from None
            if solver.status == "failed":
                raise IntegrationError(f"{method} failed at t = {solver.t:.6g} in model {model.name!r}: the step size became too small.")
            ta, tb = solver.t_old, solver.t
            dense = solver.dense_output()
            ts = np.linspace(ta, tb, 7)
            Y = dense(ts)
            roots = []
            G = np.array([hy.gaps(s, Y[:n, i]) for i, s in enumerate(ts)]).T  # (k, samples)
            for j in range(k):
                if j in mode:
                    continue
                for i in range(len(ts) - 1):
                    if G[j, i] > 0 and G[j, i + 1] <= 0:
                        f = lambda s, j=j: float(hy.gaps(s, dense(s)[:n])[j])
                        r = ts[i + 1] if G[j, i + 1] == 0 else brentq(f, ts[i], ts[i + 1], xtol=event_tol)
                        roots.append((r, "impact", j))
                        break
            if mode:
                def lam_at(s):
                    yy = dense(s)
                    return hy.rest_force(s, yy, hy.numeric.rhs(s, yy)[n:], mode)[0]

                L = np.array([lam_at(s) for s in ts]).T
                for jj, j in enumerate(mode):
                    for i in range(len(ts) - 1):
                        if L[jj, i] >= 0 > L[jj, i + 1]:
                            r = brentq(lambda s, jj=jj: float(lam_at(s)[jj]), ts[i], ts[i + 1], xtol=event_tol)
                            roots.append((r, "liftoff", j))
                            break
            stop = tb
            if roots:
                event = min(roots)
                stop = event[0]
            while gi < len(grid) and grid[gi] <= stop:
                if grid[gi] >= tt:
                    out_t.append(float(grid[gi]))
                    out_y.append(dense(grid[gi]))
                gi += 1
            if event:
                break
        nfev += solver.nfev
        if event is None:
            tt = t1
            break
        tt, kind, j = event
        y = dense(tt)
        if kind == "liftoff":
            resting = [r for r in resting if r != j]
            lifts.append((tt, hy.names[j]))
            notes.append(f"t = {tt:.12g}: contact {hy.names[j]!r} lifts off (its holding force would pull)")
            switches += 1
        else:
            out_t.append(tt)
            out_y.append(y.copy())
            y = handle_impact(tt, y)
            out_t.append(tt)
            out_y.append(y.copy())
            first = first_step_after(tt, y)
        if len(records) + switches > max_impacts:
            worst = max(range(k), key=lambda j: len(history[j]))
            raise ImpactError(
                f"more than {max_impacts} impacts and contact switches by t = {tt:.6g} in model {model.name!r} (most on "
                f"contact {hy.names[worst]!r}): the contacts chatter. Raise rest_velocity or zeno_time so that they settle "
                f"into resting contact sooner, or max_impacts if the impacts are real."
            )
    T_arr = np.array(out_t)
    Y = np.array(out_y).T
    Tk, Vp, Dr = hy.numeric.energies(T_arr, Y[:n], Y[n:])
    if resting:
        notes.append("resting at the end: " + ", ".join(hy.names[j] for j in resting))
    return ImpactResult(
        t=T_arr, q={nm: Y[i] for i, nm in enumerate(eq.names)}, v={nm: Y[n + i] for i, nm in enumerate(eq.names)},
        T=Tk, V=Vp, D=Dr, model=model.name, defaulted=defaulted, nfev=nfev, method=f"{getattr(solver_cls, '__name__', method)} + impacts",
        evaluator=hy.numeric.evaluate, notes=notes, impacts=records, resting=rests, liftoffs=lifts,
    )
