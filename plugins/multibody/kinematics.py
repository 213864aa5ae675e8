"""Kinematics of the multibody plugin: the joint tree from ground gives every body its pose and every body point
its position; the joints outside the tree close loops as holonomic constraints (:func:`build_kinematics`)."""

from __future__ import annotations

from collections import deque

from lagrangian import GROUND, Coordinate, ModelError, UnknownNameError
from lagrangian.base.component import t
from lagrangian.derive import cross, time_derivative

from .bodies import _BodyBase
from .joints import _Joint
from .recursive import offer
from .rotations import Pose, _rot2, product, transform
from lagrangian.base import deferred as _deferred

sp = _deferred.module("sympy", globals())


def build_kinematics(network, view, dynamics: str = "auto") -> None:
    """Give ``view`` the pose of every body and the position of every body point; add joint coordinates and
    loop-closure constraints; offer recursive dynamics (``view.recursive``, :mod:`.recursive`) for a tree, as the
    model's ``dynamics`` option says.  Called by the mechanical domain when the model has bodies or joints."""
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
                       angle=sp.Integer(0) if dim == 2 else None, omega_body=None if dim == 2 else sp.zeros(3, 1),
                       v_body=None if dim == 2 else sp.zeros(3, 1))
    view.poses[GROUND] = ground_pose
    # breadth-first from ground along joints followed parent → child: tree joints give poses, the rest close loops
    # (a joint met child-first is left to close a loop, so the order of declaration does not matter)
    children: dict[str, list] = {}
    for j in joints:
        children.setdefault(j.nodes[0], []).append(j)
    used, queue, tree_order = set(), deque([GROUND]), []
    while queue:
        body = queue.popleft()
        for j in children.get(body, []):
            child = j.nodes[1]
            if child in view.poses:
                continue
            used.add(j.name)
            tree_order.append(j.name)
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
    view.joints = {j.name: j for j in joints}
    for node in network.nodes:
        body, _, point = node.partition(".")
        if point and body in bodies:
            view.position(node)  # resolves (and checks) the point
    order = {name: k for k, name in enumerate(tree_order)}
    view.recursive = offer(sorted((j for j in joints if j.name in used), key=lambda j: order[j.name]), bodies, dim,
                           list(comps), view.coordinates, dynamics)


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
    R = product(pp.R, R_rel)
    omega = pp.omega + product(pp.R, w_rel)
    # in the body's frame, joint by joint: never Rᵀ ω of two long products whose cancellation SymPy cannot see
    carried = product(R_rel.T, pp.omega_body) if any(e != 0 for e in pp.omega_body) else sp.zeros(3, 1)
    omega_body = carried + j.relative_body_rate(q, R_rel, w_rel)
    p = transform(transform(pp.p, pp.R, P + d), R, -C)
    r = P + d
    vj = pp.v_body + sp.Matrix(cross(pp.omega_body, r)) + d.applyfunc(lambda e: time_derivative(e, t))
    v_body = product(R_rel.T, vj) - sp.Matrix(cross(omega_body, C))
    return Pose(R, p, omega, omega_body=omega_body, v_body=v_body)


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
