"""What the mechanical domain draws of a model in an animation (:meth:`lagrangian.Result.animate`): its
:class:`~lagrangian.Shape` s, in world coordinates, as expressions of the coordinates."""

from __future__ import annotations

from lagrangian import GROUND, ModelError, Shape
from lagrangian.base import deferred as _deferred

sp = _deferred.module("sympy", globals())

__all__ = ["shapes", "RIM"]

#: Points on a disc's rim drawn in an animation (a polygon of this many sides).
RIM = 32


def shapes(view) -> list[Shape]:
    """The mechanism of a mechanical view in space, for an animation: each rigid body from its geometry (a rod as
    its length, a disc as its rim and a radius to ``rim``, any other body as its centre of mass joined to its
    named points and to the points its joints hold), springs and dampers as links between their ends, point
    masses, joints at their child's point, and the ground.  World coordinates, as expressions of the coordinates.

    >>> import lagrangian as lg
    >>> m = lg.Model("pendulum", dim=2)
    >>> _ = m.add("rod", "r", "r", m=0.3, length=0.5)
    >>> _ = m.add("revolute", "j", ("ground", "r"))
    >>> [(s.name, s.kind, s.points.shape) for s in m.assembly.views["mechanical"].shapes()]
    [('ground', 'ground', (2, 1)), ('r', 'line', (2, 2)), ('j', 'joint', (2, 1))]
    """
    out = [Shape(GROUND, "ground", _planar(sp.zeros(view.dim, 1), view.dim))]
    for node, body in view.bodies.items():
        pose = view.poses.get(node)
        if pose is None:
            continue
        offsets = body.point_offsets(view.dim)
        if body.kind == "rod":
            local = [offsets["start"], offsets["end"]]
        elif body.kind == "disc":
            r = body.radius
            angles = [2 * sp.pi * k / RIM for k in range(RIM + 1)]
            local = [sp.Matrix([r * sp.cos(a), r * sp.sin(a), 0][: view.dim]) for a in angles]
            local += [offsets["center"], offsets["rim"]]
        else:  # its centre of mass, joined to its named points and the points its joints hold
            com = offsets["com"]
            out.append(Shape(f"{body.name}.com", "point", _place(pose, com)))
            held = [j.points(view.dim)[k] for j in getattr(view, "joints", {}).values()
                    for k in (0, 1) if j.nodes[k] == node]
            ends = [o for n, o in offsets.items() if n not in ("origin", "com")] + held
            if not ends:
                continue
            local = [e for o in ends for e in (com, o)]
        out.append(Shape(body.name, "line", sp.Matrix.hstack(*[_place(pose, o) for o in local])))
    for name, joint in getattr(view, "joints", {}).items():
        child = view.poses.get(joint.nodes[1])
        if child is not None:
            out.append(Shape(name, "joint", _place(child, joint.points(view.dim)[1])))
    for key, (a, b) in view.edges.items():
        if key not in view.links:
            continue
        try:
            ends = [view.position(a), view.position(b)]
        except ModelError:  # an end that is no point in space (a rotational node)
            continue
        out.append(Shape(key, "link", _planar(sp.Matrix.hstack(*ends), view.dim)))
    for node, position in view.positions.items():
        if "." not in node and node not in view.poses:
            out.append(Shape(node, "point", _planar(position, view.dim)))
    return out


def _place(pose, offset: sp.Matrix) -> sp.Matrix:
    """A point given in a body's frame, in the fixed frame."""
    from lagrangian.plugins.multibody import transform

    return transform(pose.p, pose.R, offset)


def _planar(points: sp.Matrix, dim: int) -> sp.Matrix:
    """Points of a line (1-D) drawn in the plane: the line is the x axis."""
    return points if dim > 1 else sp.Matrix.vstack(points, sp.zeros(1, points.cols))
