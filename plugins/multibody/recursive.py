"""Recursive dynamics of a tree of rigid bodies: Featherstone's articulated-body algorithm, written as a sequence of
small symbolic steps (:class:`lagrangian.Recursion`) that the tape records as it is, so that the work per evaluation,
the tape and the generated C all grow linearly with the number of joints.

Every joint is split into elementary ones, each turning about or sliding along one axis (a spherical joint is its
three body-fixed turns, with massless frames between them; a free joint three slides and three turns), so that the
coordinates are the model's own.  Quantities are spatial vectors in each frame's own axes: motions ``(ω, v)`` with
``v`` the velocity of the point at the frame's origin, forces ``(n, f)`` with ``n`` the moment about it, inertias in
3 × 3 blocks ``[[J, H], [Hᵀ, M]]``.  Three passes (R. Featherstone, *Rigid Body Dynamics Algorithms*, 2008, §7.3):

1. out from the ground: each frame's velocity ``v_i = X_i v_λ + S_i q̇_i``, its velocity product ``c_i = v_i × S_i q̇_i``
   and its bias force ``p_i = v_i ×* I_i v_i``;
2. in towards the ground: the articulated inertia ``I^A_i`` and bias ``p^A_i``; for the joint, ``U_i = I^A_i S_i``,
   the pivot ``D_i = S_iᵀ U_i`` and ``u_i = τ_i − S_iᵀ p^A_i``; what the parent sees, ``I^A_i − U_i U_iᵀ / D_i`` and
   ``p^A_i + I^a_i c_i + U_i u_i / D_i``, carried into its frame;
3. out again: ``a'_i = X_i a_λ + c_i``, ``q̈_i = (u_i − U_iᵀ a'_i) / D_i``, ``a_i = a'_i + S_i q̈_i``, from the ground's
   ``a_0 = −g`` (uniform gravity as an acceleration of the ground).

Constraints (closed loops, constraints on positions or velocities) need ``M⁻¹ c`` for each column ``c`` of ``Jᵀ``:
passes 2 and 3 again with ``τ = c``, at rest and without gravity, on the articulated inertias already there
(:meth:`Tree._response`); the core solves for the constraint forces (:mod:`lagrangian.derivation.recursion`).

The kinetic energy ``Σ ½ v_iᵀ I_i v_i`` and the momenta ``∂T/∂q̇_i = S_iᵀ h_i`` (``h_i``: the momentum of the bodies
beyond joint ``i``) come from the same passes.  Entries that are exactly zero (a planar mechanism's out-of-plane
motion, an axis along a frame's axis) fold away as the steps are written.

Point masses on a body's node or points are folded into its inertia (:func:`_point_masses`).

``Model(dynamics="recursive")`` asks for it at any size, ``"closed"`` never; the default, ``"auto"``, takes it from
:data:`RECURSIVE_FROM` joint coordinates.  A double pendulum both ways:

>>> import lagrangian as lg, numpy as np
>>> def pendulum(dynamics):
...     m = lg.Model("double pendulum", dim=2, dynamics=dynamics)
...     _ = m.add("rod", "a", "a", m=0.3, length=0.7)
...     _ = m.add("revolute", "j0", ("ground", "a"))
...     _ = m.add("rod", "b", "b", m=0.2, length=0.5)
...     _ = m.add("revolute", "j1", ("a", "b"), parent_point=(0.7, 0))
...     _ = m.add("gravity", "g", g=9.81)
...     return m
>>> y = np.array([0.3, -0.2, 1.1, 0.4])
>>> fast, closed = pendulum("recursive").numeric(), pendulum("closed").numeric()
>>> bool(np.allclose(fast.compile("tape").rhs(0.0, y), closed.rhs(0.0, y), rtol=1e-12))
True
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from lagrangian import GROUND, ModelError, Recursion, RecursiveDynamics

from .rotations import unit_vectors
from lagrangian.base import deferred as _deferred

sp = _deferred.module("sympy", globals())

#: The fewest joint coordinates for which ``dynamics="auto"`` (the default) takes the recursive form.  Measured by
#: ``benchmarks/dynamics_choice.py`` (one evaluation in a C loop, closed form / recursion): planar 8 links 3.2 / 3.3 µs
#: on the tape, 0.51 / 0.30 µs native; planar 9 links 4.2 / 3.8 and 0.65 / 0.35 µs; three spatial bodies (9
#: coordinates) 9.5 / 6.9 and 0.92 / 0.42 µs, each built (derivation and tapes) in the same time within 3 %; from
#: there on the recursion wins by more with every size (planar 16: 2.2× on the tape, 4.6× native, half the build).
RECURSIVE_FROM = 9

EPS = 2.0**-52


class _Steps:
    """The definitions of a recursion: each expression that is not an atom becomes a new symbol defined by it."""

    def __init__(self):
        self.definitions: list[tuple[sp.Symbol, sp.Expr]] = []

    def __call__(self, e: sp.Expr) -> sp.Expr:
        if e.is_Atom or (e.is_Mul and len(e.args) == 2 and e.args[0].is_Number and e.args[1].is_Atom):
            return e
        w = sp.Dummy("w")
        self.definitions.append((w, e))
        return w

    def vec(self, v: list) -> list:
        return [self(e) for e in v]

    def mat(self, A: list) -> list:
        return [[self(e) for e in row] for row in A]


# -- 3-vectors and 3 × 3 matrices as lists of SymPy expressions ----------------------------------------------------
# Products by an exact zero are never formed: SymPy's 0 · x asks whether x may be infinite, a walk of x's whole
# expression (0.8 ms a product on a chain of 30 bodies).
def _mul(*factors):
    if any(f == 0 for f in factors):
        return sp.S.Zero
    return sp.Mul(*factors)


def _add(a, b):
    return [x + y for x, y in zip(a, b)]


def _sub(a, b):
    return [x - y for x, y in zip(a, b)]


def _scale(k, a):
    return [_mul(k, x) for x in a]


def _dot(a, b):
    return sp.Add(*[x * y for x, y in zip(a, b) if x != 0 and y != 0])


def _cross(a, b):
    return [_mul(a[1], b[2]) - _mul(a[2], b[1]), _mul(a[2], b[0]) - _mul(a[0], b[2]), _mul(a[0], b[1]) - _mul(a[1], b[0])]


def _mv(A, x):
    return [_dot(row, x) for row in A]


def _mtv(A, x):  # Aᵀ x
    return [_dot([A[k][i] for k in range(3)], x) for i in range(3)]


def _mm(A, B):
    return [[_dot(A[i], [B[k][j] for k in range(3)]) for j in range(3)] for i in range(3)]


def _t(A):
    return [[A[j][i] for j in range(3)] for i in range(3)]


def _skew(c):
    return [[sp.S.Zero, -c[2], c[1]], [c[2], sp.S.Zero, -c[0]], [-c[1], c[0], sp.S.Zero]]


def _msub(A, B):
    return [[A[i][j] - B[i][j] for j in range(3)] for i in range(3)]


def _madd(A, B):
    return [[A[i][j] + B[i][j] for j in range(3)] for i in range(3)]


def _outer(a, b, k):
    return [[_mul(a[i], b[j], k) for j in range(3)] for i in range(3)]


def _eye():
    return [[sp.S.One if i == j else sp.S.Zero for j in range(3)] for i in range(3)]


def _zeros():
    return [[sp.S.Zero] * 3 for _ in range(3)]


def _rotation(axis, c, s):
    """Rotation by the angle of cosine ``c`` and sine ``s`` about the unit ``axis`` (Rodrigues)."""
    k = _skew(axis)
    kk = _mm(k, k)
    return [[(sp.S.One if i == j else sp.S.Zero) + _mul(s, k[i][j]) + _mul(1 - c, kk[i][j]) for j in range(3)] for i in range(3)]


def _pad(v, dim: int) -> list:
    v = list(v)
    return v + [sp.S.Zero] * (3 - len(v)) if dim == 2 else v


@dataclass
class _Elem:
    """An elementary joint: its frame's parent (−1: ground), a turn about or a slide along ``axis`` (parent frame) at
    ``P`` (parent frame), the child's point ``C`` on it (child frame), a fixed turn ``R0`` (fixed joints), the
    coordinate's name (None: fixed) and the body carried, a list of parts ``(m, c, Ic)`` (the body's own, and the
    point masses on its points, ``Ic`` zero) or None (a massless frame)."""

    parent: int
    kind: str
    axis: list
    P: list
    C: list
    R0: Any
    coord: str | None
    body: tuple | None


def _elements(joint, dim: int, parent: int, base: int) -> list[_Elem]:
    """The elementary joints of a tree joint, the first at ``parent`` (its frames numbered from ``base``)."""
    P, C = (_pad(v, dim) for v in joint.points(dim))
    names = joint.names(dim)
    kind = joint.kind
    zero = [sp.S.Zero] * 3
    steps: list[tuple[str, list, str | None]] = []  # (kind, axis, coordinate)
    if kind == "revolute":
        steps = [("revolute", [sp.S.Zero, sp.S.Zero, sp.S.One] if dim == 2 else _revolute_axis(joint), names[0])]
    elif kind == "prismatic":
        _, d, _ = joint.relative(dim, [sp.S.One])
        steps = [("prismatic", _pad(d, dim), names[0])]
    elif kind in ("planar", "free") and dim == 2 or kind == "planar":
        steps = [("prismatic", list(unit_vectors()[0]), names[0]), ("prismatic", list(unit_vectors()[1]), names[1]),
                 ("revolute", list(unit_vectors()[2]), names[2])]
    elif kind == "spherical":
        steps = [("revolute", list(unit_vectors()["xyz".index(a)]), n) for a, n in zip(joint.sequence, names)]
    elif kind == "free":
        steps = [("prismatic", list(unit_vectors()[k]), names[k]) for k in range(3)]
        steps += [("revolute", list(unit_vectors()["xyz".index(a)]), n) for a, n in zip(joint.sequence, names[3:])]
    elif kind == "fixed":
        R0 = _rotation([sp.S.Zero, sp.S.Zero, sp.S.One], sp.cos(joint.angle), sp.sin(joint.angle)) if dim == 2 else None
        return [_Elem(parent, "fixed", zero, P, C, R0, None, None)]
    else:  # pragma: no cover - every joint kind of the plugin is listed
        raise ModelError(f"joint {joint.name!r}: no recursive form for a {kind} joint.")
    out = []
    for k, (what, axis, coord) in enumerate(steps):
        out.append(_Elem(parent if k == 0 else base + k - 1, what, axis, P if k == 0 else zero,
                         C if k == len(steps) - 1 else zero, None, coord, None))
    return out


def _revolute_axis(joint) -> list:
    from .checks import _unit, _vec

    return list(_unit(_vec(joint.params.get("axis"), 3, joint, "axis", unit_vectors()[2]), joint, "axis"))


def _body(body, dim: int, points: list) -> list | None:
    """The parts of a body's inertia in its frame: its own ``(m, c, Ic)`` and the point masses ``(m, offset)`` on
    its points (``points``), or None when none has mass."""
    parts = []
    m = body.mass_value
    if m != 0:
        c = _pad(body.com_offset(dim), dim)
        I = body.inertia_matrix(dim)
        if dim == 2:
            Ic = [[sp.S.Zero, sp.S.Zero, sp.S.Zero], [sp.S.Zero, sp.S.Zero, sp.S.Zero], [sp.S.Zero, sp.S.Zero, I]]
        else:
            Ic = [[I[i, j] for j in range(3)] for i in range(3)]
        parts.append((m, c, Ic))
    parts += [(mp, _pad(offset, dim), _zeros()) for mp, offset in points]
    return parts or None


class Tree:
    """A tree of rigid bodies as elementary joints, and its articulated-body recursion (``__call__``: the ``build``
    of :class:`lagrangian.RecursiveDynamics`)."""

    def __init__(self, joints: list, bodies: dict, dim: int, fields: list, points: dict | None = None):
        self.dim = dim
        self.fields = fields  # the accelerations of uniform fields (gravity), dim × 1 each
        self.elems: list[_Elem] = []
        frame = {GROUND: -1}
        for j in joints:  # parent before child
            parent = frame[j.nodes[0]]
            self.elems.extend(_elements(j, dim, parent, len(self.elems)))
            frame[j.nodes[1]] = len(self.elems) - 1
            body = bodies.get(j.nodes[1])
            if body is not None:
                self.elems[-1].body = _body(body, dim, (points or {}).get(j.nodes[1], []))
        self.names = tuple(e.coord for e in self.elems if e.coord is not None)

    def __call__(self, q, v, tau, columns=()) -> Recursion:
        index = {n: k for k, n in enumerate(self.names)}
        w = _Steps()
        N = len(self.elems)
        E, r, S, vel, cor = [None] * N, [None] * N, [None] * N, [None] * N, [None] * N
        IA, pA, h = [None] * N, [None] * N, [None] * N
        T = []
        for i, e in enumerate(self.elems):  # pass 1: out from the ground
            k = index.get(e.coord)
            if e.kind == "revolute":
                c, s = w(sp.cos(q[k])), w(sp.sin(q[k]))
                R = w.mat(_rotation(e.axis, c, s))
                r[i] = w.vec(_sub(e.P, _mv(R, e.C)))
                S[i] = (e.axis, _cross(e.C, e.axis))
            elif e.kind == "prismatic":
                R = _eye()
                r[i] = w.vec(_sub(_add(e.P, _scale(q[k], e.axis)), e.C))
                S[i] = ([sp.S.Zero] * 3, e.axis)
            else:
                R = e.R0 if e.R0 is not None else _eye()
                r[i] = w.vec(_sub(e.P, _mv(R, e.C)))
            E[i] = R  # the child's axes in the parent's: X maps (ω, v) to (Rᵀ ω, Rᵀ (v − r × ω))
            if e.parent < 0:
                om, vv = [sp.S.Zero] * 3, [sp.S.Zero] * 3
            else:
                om0, v0 = vel[e.parent]
                om = _mtv(R, om0)
                vv = _mtv(R, _sub(v0, _cross(r[i], om0)))
            if S[i] is not None:
                sw, sv = _scale(v[k], S[i][0]), _scale(v[k], S[i][1])
                om, vv = w.vec(_add(om, sw)), w.vec(_add(vv, sv))
                cor[i] = w.vec(_cross(om, sw)) + w.vec(_add(_cross(om, sv), _cross(vv, sw)))
            else:
                om, vv = w.vec(om), w.vec(vv)
                cor[i] = [sp.S.Zero] * 6
            vel[i] = (om, vv)
            if e.body is not None:
                J, H, M = _zeros(), _zeros(), _zeros()
                for m, cc, Ic in e.body:  # (about the frame's origin: Ic − m [c×]², m [c×], m 1)
                    X = _skew(cc)
                    J = _madd(J, _msub(Ic, [[_mul(m, x) for x in row] for row in _mm(X, X)]))
                    H = _madd(H, [[_mul(m, x) for x in row] for row in X])
                    M = _madd(M, [[m if a == b else sp.S.Zero for b in range(3)] for a in range(3)])
                J, H = w.mat(J), w.mat(H)
                hw = w.vec(_add(_mv(J, om), _mv(H, vv)))
                hv = w.vec(_add(_mtv(H, om), _mv(M, vv)))
                T.append((_dot(om, hw) + _dot(vv, hv)) / 2)
                IA[i] = [J, H, M]
                pA[i] = w.vec(_add(_cross(om, hw), _cross(vv, hv))) + w.vec(_cross(om, hv))
                h[i] = hw + hv
            else:
                IA[i] = [_zeros(), _zeros(), _zeros()]
                pA[i] = [sp.S.Zero] * 6
                h[i] = [sp.S.Zero] * 6
        U, Dinv, u = [None] * N, [None] * N, [None] * N
        momenta, pivots = [sp.S.Zero] * len(self.names), [sp.S.Zero] * len(self.names)
        for i in reversed(range(N)):  # pass 2: in towards the ground
            e = self.elems[i]
            J, H, M = IA[i]
            if S[i] is not None:
                k = index[e.coord]
                sw, sv = S[i]
                Uw = w.vec(_add(_mv(J, sw), _mv(H, sv)))
                Uv = w.vec(_add(_mtv(H, sw), _mv(M, sv)))
                D = w(_dot(sw, Uw) + _dot(sv, Uv))
                pivots[k] = D
                # a pivot within rounding of zero (against |S|² times the traces of the blocks, which bound the
                # articulated inertia's largest eigenvalue within a factor of 6) is a singular mass matrix: NaN, which
                # the run reports as such, never accelerations of 1e30 at a gimbal lock
                size = _dot(sw, sw) * (J[0][0] + J[1][1] + J[2][2]) + _dot(sv, sv) * (M[0][0] + M[1][1] + M[2][2])
                Dinv[i] = w(sp.Piecewise((1 / D, D > 16 * N * EPS * size)))
                u[i] = w(tau[k] - _dot(sw, pA[i][:3]) - _dot(sv, pA[i][3:]))
                momenta[k] = _dot(sw, h[i][:3]) + _dot(sv, h[i][3:])
                U[i] = (Uw, Uv)
                Ja = _msub(J, _outer(Uw, Uw, Dinv[i]))
                Ha = _msub(H, _outer(Uw, Uv, Dinv[i]))
                Ma = _msub(M, _outer(Uv, Uv, Dinv[i]))
                Ja, Ha, Ma = w.mat(Ja), w.mat(Ha), w.mat(Ma)
                cw, cv = cor[i][:3], cor[i][3:]
                pa = _add(pA[i], [*_add(_mv(Ja, cw), _mv(Ha, cv)), *_add(_mtv(Ha, cw), _mv(Ma, cv))])
                pa = w.vec(_add(pa, _scale(u[i] * Dinv[i], [*Uw, *Uv])))
            else:
                Ja, Ha, Ma, pa = J, H, M, pA[i]
            if e.parent < 0:
                continue
            R, rr = E[i], _skew(r[i])
            # into the parent's frame: turned (R · Rᵀ), then moved by r (parent frame)
            Jr, Hr, Mr = _mm(_mm(R, Ja), _t(R)), _mm(_mm(R, Ha), _t(R)), _mm(_mm(R, Ma), _t(R))
            Jr, Hr, Mr = w.mat(Jr), w.mat(Hr), w.mat(Mr)
            Jp = _add3(Jr, _msub(_mm(rr, _t(Hr)), _mm(Hr, rr)), [[-x for x in row] for row in _mm(_mm(rr, Mr), rr)])
            Hp = _madd(Hr, _mm(rr, Mr))
            P0, P1 = IA[e.parent], pA[e.parent]
            IA[e.parent] = [w.mat(_madd(P0[0], Jp)), w.mat(_madd(P0[1], Hp)), w.mat(_madd(P0[2], Mr))]
            fv = _mv(R, pa[3:])
            pA[e.parent] = w.vec(_add(P1, [*_add(_mv(R, pa[:3]), _cross(r[i], fv)), *fv]))
            hv = _mv(R, h[i][3:])
            h[e.parent] = w.vec(_add(h[e.parent], [*_add(_mv(R, h[i][:3]), _cross(r[i], hv)), *hv]))
        g = [sp.S.Zero] * 3
        for f in self.fields:
            g = _add(g, _pad(f, self.dim))
        acc: list = [None] * N
        qdd = [sp.S.Zero] * len(self.names)
        for i, e in enumerate(self.elems):  # pass 3: out again
            if e.parent < 0:
                aw, av = [sp.S.Zero] * 3, [-x for x in g]
            else:
                aw, av = acc[e.parent]
            R = E[i]
            aw2 = _mtv(R, aw)
            av2 = _mtv(R, _sub(av, _cross(r[i], aw)))
            aw2, av2 = w.vec(_add(aw2, cor[i][:3])), w.vec(_add(av2, cor[i][3:]))
            if S[i] is not None:
                k = index[e.coord]
                Uw, Uv = U[i]
                qdd[k] = w((u[i] - _dot(Uw, aw2) - _dot(Uv, av2)) * Dinv[i])
                aw2, av2 = w.vec(_add(aw2, _scale(qdd[k], S[i][0]))), w.vec(_add(av2, _scale(qdd[k], S[i][1])))
            acc[i] = (aw2, av2)
        responses = [self._response(w, index, c, E, r, S, U, Dinv) for c in columns]
        return Recursion(w.definitions, qdd, sp.Add(*T), momenta, pivots, responses)

    def _response(self, w: _Steps, index: dict, tau: list, E, r, S, U, Dinv) -> list:
        """``M⁻¹ τ``: the accelerations the generalized forces ``τ`` alone give the tree at rest, without gravity
        (passes 2 and 3 again, on the articulated inertias already there; Featherstone's §7.3 with ``v = 0``)."""
        N = len(self.elems)
        pA: list = [[sp.S.Zero] * 6 for _ in range(N)]
        u: list = [sp.S.Zero] * N
        for i in reversed(range(N)):  # in: the bias of τ alone
            e = self.elems[i]
            pa = pA[i]
            if S[i] is not None:
                sw, sv = S[i]
                u[i] = w(tau[index[e.coord]] - _dot(sw, pa[:3]) - _dot(sv, pa[3:]))
                Uw, Uv = U[i]
                pa = w.vec(_add(pa, _scale(_mul(u[i], Dinv[i]), [*Uw, *Uv])))
            if e.parent < 0:
                continue
            R = E[i]
            fv = _mv(R, pa[3:])
            pA[e.parent] = w.vec(_add(pA[e.parent], [*_add(_mv(R, pa[:3]), _cross(r[i], fv)), *fv]))
        acc: list = [None] * N
        qdd = [sp.S.Zero] * len(self.names)
        for i, e in enumerate(self.elems):  # out: from a ground at rest
            aw, av = ([sp.S.Zero] * 3, [sp.S.Zero] * 3) if e.parent < 0 else acc[e.parent]
            R = E[i]
            aw2, av2 = w.vec(_mtv(R, aw)), w.vec(_mtv(R, _sub(av, _cross(r[i], aw))))
            if S[i] is not None:
                k = index[e.coord]
                Uw, Uv = U[i]
                qdd[k] = w(_mul(u[i] - _dot(Uw, aw2) - _dot(Uv, av2), Dinv[i]))
                aw2, av2 = w.vec(_add(aw2, _scale(qdd[k], S[i][0]))), w.vec(_add(av2, _scale(qdd[k], S[i][1])))
            acc[i] = (aw2, av2)
        return qdd


def _add3(A, B, C):
    return [[A[i][j] + B[i][j] + C[i][j] for j in range(3)] for i in range(3)]


def _point_masses(components: list, bodies: dict, dim: int) -> dict:
    """``[(body node, offset, component)]``: the point masses (``mass``) on a body's node or one of its points, which
    the recursion folds into that body's inertia."""
    out = []
    for c in components:
        if getattr(c, "kind", None) != "mass" or getattr(c, "gravitational_mass", None) is None:
            continue
        node = c.nodes[0]
        body, _, point = node.partition(".")
        offsets = bodies[body].point_offsets(dim) if body in bodies else {}
        if body in bodies and (not point or point in offsets):
            out.append((body, list(offsets[point or "origin"]), c))
    return out


def offer(joints: list, bodies: dict, dim: int, components: list, coordinates: list, choice: str) -> RecursiveDynamics | None:
    """The multibody plugin's offer of recursive dynamics for a tree of ``joints`` (parent before child), or None:
    ``choice`` is the model's ``dynamics`` option (``"auto"``: from :data:`RECURSIVE_FROM` joint coordinates)."""
    if choice == "closed":
        return None
    why = None
    fields, covers = [], {b.name for b in bodies.values()} | {j.name for j in joints}
    points = _point_masses(components, bodies, dim)
    covers |= {c.name for _, _, c in points}
    for c in components:
        if hasattr(c, "field_acceleration"):
            held = [o for o in components if getattr(o, "gravitational_mass", None) is not None]
            others = [o.name for o in held if o not in bodies.values() and o.name not in covers]
            if others:
                why = (f"gravity {c.name!r} acts on {', '.join(map(repr, others))}, "
                       f"{'not a rigid body' if len(others) == 1 else 'not rigid bodies'} of the tree")
            fields.append(c.field_acceleration(dim))
            covers.add(c.name)
    for j in joints:
        if j.driven() is not None:
            why = f"joint {j.name!r} is driven"
        elif getattr(j, "absolute_angle", False):
            why = f"joint {j.name!r} measures an absolute angle"
    if why is None and choice == "auto" and len(coordinates) < RECURSIVE_FROM:
        return None
    if why is not None:
        if choice == "recursive":
            raise ModelError(f"dynamics='recursive' needs a tree of joints with coordinates relative to their parents "
                             f"and uniform gravity on the bodies alone: {why}. Use dynamics='closed' (or 'auto').")
        return None
    carried: dict = {}
    for node, offset, c in points:
        carried.setdefault(node, []).append((c.gravitational_mass[1], offset))
    tree = Tree(joints, bodies, dim, fields, carried)
    why = "dynamics='recursive'" if choice == "recursive" else f"the default from {RECURSIVE_FROM} joint coordinates on"
    return RecursiveDynamics(frozenset(covers), tree.names, tree,
                             f"the accelerations by the articulated-body algorithm ({len(tree.names)} joint "
                             f"coordinates, {len(tree.elems)} elementary joints: {why})", forced=choice == "recursive",
                             responds=True)
