"""Rolling without slipping on the ground: :class:`Rolling`, a wheel (a disc touching the ground at its rim) or a
ball, in the plane or in space."""

from __future__ import annotations

import sympy as sp

from lagrangian import Component, Contribution, Example, ModelError, Parameter

from .checks import _need_dim

SHAPES = ("disc", "sphere")


class Rolling(Component):
    """A body rolling without slipping on the ground: the plane through the origin normal to the last axis (y in
    2-D, z in 3-D: the plane gravity presses on by default), touched by a disc at its rim (a wheel; ``shape="disc"``)
    or by a ball (``shape="sphere"``), centred on the body's origin, of ``radius``.

    Two kinds of constraint, both kept with multipliers (the ground's normal and friction forces):

    - *holonomic*: the centre stays at its height above the ground, ``z = r`` for a ball and ``z = r √(1 − n_z²)``
      for a disc whose axis ``n`` leans (``y = r`` in the plane);
    - *on velocities* (nonholonomic): the body's material point at the contact does not slide,
      ``v_centre + ω × (contact − centre) = 0`` along the ground (two components in space, one in the plane).

    On a ``turntable`` (the ground turning at Ω about the vertical through the origin; in space) the contact moves
    with the ground's point under it, ``Ω ẑ × contact``, instead of resting: a ball released on it circles at
    2Ω/7.  In the plane the second is integrable (``x + r θ`` stays constant) but is kept as given.  In space a disc's
    contact lies on its rim, below the centre, in the disc's plane: ``contact − centre = r (c n − ẑ)/√(1 − c²)``,
    ``c = n · ẑ``; a disc lying flat (``c = ±1``) is outside the model.  ``axis`` is the disc's axis in the body's
    frame (the z axis of a :class:`~lagrangian.plugins.multibody.Disc`).  Nothing is assumed of the body's mass:
    the body kinds give it (a ``disc``, a ``body`` with a sphere's inertia).

    The methods that need a Lagrangian system without constraints on velocities (the Routhian, linearization,
    equilibria, scenes, sweeps, the exact solution) refuse a model that rolls in space, by name; energy and the
    Jacobi integral are kept (the constraints do no work), and impulses respect them.

    >>> import lagrangian as lg
    >>> m = lg.Model("rolling disc", dim=3)
    >>> _ = m.add("disc", "d", "d", m=0.3, radius=0.1)
    >>> _ = m.add("free", "j", ("ground", "d"), sequence="zxz")
    >>> _ = m.add("rolling", "roll", "d", radius=0.1)
    >>> _ = m.add("gravity", "g")
    >>> m.coordinate_names
    ['x_j', 'y_j', 'z_j', 'phi_j', 'theta_j', 'psi_j']
    >>> len(m.eq.constraints), len(m.eq.velocity_constraints)
    (1, 2)
    """

    kind = "rolling"
    domain = "mechanical"
    terminals = ("body",)
    multibody = True
    parameters = {
        "radius": Parameter("rolling radius", unit="m"),
        "shape": Parameter("'disc' (a wheel, touching the ground at its rim) or 'sphere' (a ball)", default="disc",
                           shape="name"),
        "axis": Parameter("a disc's axis in the body's frame (space only)", default=(0, 0, 1), shape="vector",
                          symbolic=False),
        "turntable": Parameter("the ground's angular velocity about the vertical through the origin (space only; "
                               "a signal of t)", default=0, check="real", shape="signal", unit="rad/s"),
    }

    def __init__(self, name, nodes, params):
        shape = params.get("shape", "disc")
        if shape not in SHAPES:
            raise ModelError(f"rolling {name!r}: shape is 'disc' or 'sphere', got {shape!r:.40}.")
        super().__init__(name, nodes, params)

    def contribute(self, ctx) -> Contribution:
        dim = _need_dim(self, ctx.view, (2, 3))
        body = self.nodes[0]
        if "." in body:
            raise ModelError(f"rolling {self.name!r}: attach it to a body (its centre is the body's origin), not to "
                             f"the point {body!r}.")
        pose = ctx.view.pose(body)
        r = self.radius
        centre, v = pose.p, ctx.view.velocity(body)
        if dim == 2:  # a circle on the line y = 0: ω ẑ × (0, −r) = (ω r, 0)
            if self.turntable != 0:
                raise ModelError(f"rolling {self.name!r}: a turntable turns the ground of a model in space (dim=3).")
            return Contribution(constraints=[centre[1] - r], velocity_constraints=[v[0] + pose.omega * r])
        if self.shape == "sphere":
            reach = sp.Matrix([0, 0, -r])
            height = r
        else:
            a = sp.Matrix(self.axis) if self.axis is not None else sp.Matrix([0, 0, 1])
            if len(a) != 3 or all(x == 0 for x in a):
                raise ModelError(f"rolling {self.name!r}: axis is a nonzero vector of 3 components in the body's "
                                 f"frame, got {list(a)}.")
            n = pose.R * (a / sp.sqrt(a.dot(a)))
            c = n[2]
            s = sp.sqrt(1 - c**2)
            reach = r * (c * n - sp.Matrix([0, 0, 1])) / s
            height = r * s
        slip = v + pose.omega.cross(reach)
        if self.turntable != 0:  # the ground turns under the contact: its point there moves at Ω ẑ × contact
            contact = centre + reach
            slip = slip - sp.Matrix([-self.turntable * contact[1], self.turntable * contact[0], 0])
        return Contribution(constraints=[centre[2] - height], velocity_constraints=[slip[0], slip[1]])

    @classmethod
    def example(cls) -> Example:
        return Example("d", {"radius": 0.5},
                       context=[("disc", "d", "d", {"m": 1, "radius": 0.5}), ("free", "j", ("ground", "d"), {}),
                                ("gravity", "g", (), {})], options={"dim": 2})
