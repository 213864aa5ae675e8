"""Rolling on the ground: :class:`Rolling`, a wheel (a disc touching the ground at its rim) or a ball, in the plane
or in space, without slipping or, given a friction force ``F_c``, sliding against dry friction."""

from __future__ import annotations

from lagrangian import Component, Contribution, Example, Load, ModelError, Parameter
from lagrangian.plugins.mechanics import STICK_SLIP, _check_phase, friction_contribution

from .bodies import _BodyBase
from .checks import _need_dim, lg_param_error
from lagrangian.base import deferred as _deferred

sp = _deferred.module("sympy", globals())

SHAPES = ("disc", "sphere")


def _shown(value) -> str:
    return f"{float(value):g}" if value.is_number else sp.sstr(value)


def _same(a, b) -> bool:
    """Whether two radii given (numbers, or expressions of the same symbols) are the same radius."""
    if a.is_number and b.is_number:
        return abs(float(a) - float(b)) <= 1e-12 * max(abs(float(a)), abs(float(b)))
    return sp.expand(a - b) == 0


def _withdraw(ctx, value) -> None:
    """Take the symbol standing for a number given to a parameter the contribution does not use out of the model's
    values: it is then no parameter of the model (``parameter_values``), and ``params=`` refuses it by name rather than
    take a value that would change nothing."""
    if isinstance(ctx.values, dict) and isinstance(value, sp.Symbol):
        ctx.values.pop(value, None)


class Rolling(Component):
    """A body rolling on the ground without slipping (or sliding against dry friction, given ``F_c``): the plane
    through the origin normal to the last axis (y in 2-D, z in 3-D: the plane gravity presses on by default), touched
    by a disc at its rim (a wheel; ``shape="disc"``) or by a ball (``shape="sphere"``), centred on the body's origin,
    of ``radius``.

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

    A body with a radius of its own (a ``disc``) rolls on it: ``radius`` may be left out, and the contact takes the
    disc's.  Given to both, the two must be the same (else a :class:`~lagrangian.ParameterError` naming both
    components and both values), and the radius is then one parameter of the model, the disc's: another value in
    ``params=`` (``{"radius_<disc>": ...}``) moves the disc's inertia and its rim on the ground together, and the
    rolling's own name (``radius_<rolling>``) is no parameter of the model, which ``params=`` refuses.  A body
    without one (a ``body`` with a sphere's inertia) needs ``radius``, a parameter of the rolling.

    ``turntable`` given as a number, 0 included (as an integer or a float alike), is a parameter of a model in space:
    ``params={"turntable_<rolling>": Ω}`` turns the ground at Ω.  In the plane the ground cannot turn: a turntable
    given as 0 is none, and no parameter of the model (``params=`` refuses it); any other is refused.

    The methods that need a Lagrangian system without constraints on velocities (the Routhian, linearization,
    equilibria, scenes, sweeps, the exact solution) refuse a model that rolls in space, by name; energy and the
    Jacobi integral are kept (the constraints do no work), and impulses respect them.

    Given ``F_c``, the sliding friction force μ N at the contact, the contact may slide: the constraints on velocities
    give way to dry friction on the slip velocity ``s`` of the body's point at the contact (the height stays held).
    Smooth by default, as ``coulomb_friction``: ``−F_c tanh(s / v_s)`` in the plane, and in space the isotropic
    ``−F_c s⃗ / √(|s⃗|² + v_s²)`` on the slip along the ground; its power (``Model.load_power``) is the heat it makes.
    In the plane ``stick_slip=True`` sticks and slips instead, in :func:`lagrangian.stick_slip.simulate`: stuck, it
    rolls without slipping (the constraint's multiplier the friction force, up to ``F_s``), sliding, the force is
    ``∓F_c``.  A wheel launched sliding at v₀ without spin skids until t = v₀/3μg, then rolls at 2v₀/3, having turned
    m v₀²/6 into heat:

    >>> import lagrangian as lg
    >>> from lagrangian.stick_slip import simulate
    >>> w = lg.Model("skidding wheel", dim=2)
    >>> _ = w.add("disc", "d", "d", m=0.3, radius=0.1)
    >>> _ = w.add("free", "j", ("ground", "d"))
    >>> _ = w.add("rolling", "roll", "d", radius=0.1, F_c=0.2 * 0.3 * 9.81, stick_slip=True)
    >>> _ = w.add("gravity", "g", g=9.81)
    >>> res = simulate(w, 1.0, initial={"x_j": 0, "y_j": 0.1, "theta_j": 0},
    ...                velocity={"x_j": 3.0, "y_j": 0, "theta_j": 0}, points=11, method="Radau")
    >>> [(s.before, s.after, round(s.t, 9)) for s in res.switches], round(3.0 / (3 * 0.2 * 9.81), 9)
    ([('slip+', 'stick', 0.509683996)], 0.509683996)
    >>> round(float(res.v["x_j"][-1]), 9), round(float(res.heat[-1]), 9)
    (2.0, 0.45)

    Rolling without slipping, in space:

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
        "radius": Parameter("rolling radius (default: the body's own, a disc's radius)", default=None, unit="m"),
        "shape": Parameter("'disc' (a wheel, touching the ground at its rim) or 'sphere' (a ball)", default="disc",
                           shape="name"),
        "axis": Parameter("a disc's axis in the body's frame (space only)", default=(0, 0, 1), shape="vector",
                          symbolic=False),
        "turntable": Parameter("the ground's angular velocity about the vertical through the origin (space only; "
                               "a signal of t)", default=0, check="real", shape="signal", unit="rad/s", vector=False),
        "F_c": Parameter("sliding friction force μ N at the contact (None: it rolls without slipping)", default=None,
                         check="nonnegative", unit="N"),
        "v_s": Parameter("slip speed below which the friction fades (regularization)", default=1e-4, unit="m/s"),
        **STICK_SLIP,
    }

    def __init__(self, name, nodes, params):
        shape = params.get("shape", "disc")
        if shape not in SHAPES:
            raise ModelError(f"rolling {name!r}: shape is 'disc' or 'sphere', got {shape!r:.40}.")
        if params.get("F_c") is None:
            given = [p for p in ("F_s", "stick_slip", "phase") if params.get(p) not in (None, False, "smooth")]
            if given:
                raise ModelError(f"rolling {name!r}: {given[0]} is for a contact that slides: give F_c (the sliding "
                                 f"friction force μ N), or drop {given[0]} to roll without slipping.")
        _check_phase(self.kind, name, params)
        super().__init__(name, nodes, params)

    def sliding_rate(self, ctx):
        """The slip velocity of the contact in the plane, ``v_x + ω r`` (the stick–slip driver's contract, with
        ``phase`` and ``F_s``); in space the contact slides along a plane and there is no one rate."""
        if _need_dim(self, ctx.view, (2, 3)) != 2:
            raise ModelError(f"rolling {self.name!r}: sticking and slipping (stick_slip=True, phase) is for a contact "
                             f"in the plane (dim=2); in space drop stick_slip for the smooth friction (F_c, v_s) that "
                             f"Model.simulate runs.")
        pose = ctx.view.pose(self.nodes[0])
        return ctx.view.velocity(self.nodes[0])[0] + pose.omega * self.rolling_radius(ctx)

    def rolling_radius(self, ctx):
        """The radius the contact rolls on: that of the body (a disc) when it has one, checked against ``radius``
        when both are given (the rolling's own number then withdrawn: the body's is the one parameter), else
        ``radius``; a :class:`~lagrangian.ParameterError` when they differ or neither is given."""
        body = self.nodes[0]
        own = self.params.get("radius")
        bodies = [c for c in ctx.components if isinstance(c, _BodyBase) and tuple(c.nodes) == (body,)
                  and c.params.get("radius") is not None]
        if not bodies:
            if own is None:
                raise lg_param_error(self.name, "radius", f"required: rolling {self.name!r} rolls on body {body!r}, "
                                     f"which has no radius of its own (a disc has one): give the contact's radius=.")
            return own
        disc = bodies[0]
        theirs = sp.sympify(disc.params["radius"])
        for other in [*bodies[1:], *([self] if own is not None else [])]:
            given = sp.sympify(other.params["radius"])
            a, b = given.xreplace(other.values), theirs.xreplace(disc.values)  # each component's own numbers
            if not _same(a, b):
                where = (f"rolls on {disc.kind} {disc.name!r}" if other is self
                         else f"is on body {body!r}, as is {disc.kind} {disc.name!r}")
                fix = (f"Leave radius= out of rolling {self.name!r} (it then takes the {disc.kind}'s), or give both "
                       f"the same value" if other is self else "Give both the same value")
                raise lg_param_error(
                    self.name, "radius",
                    f"{other.kind} {other.name!r} has radius {_shown(a)} but {where}, whose radius is {_shown(b)}: a "
                    f"body rolls on its own rim. {fix}.")
        if own is not None and own != theirs:
            _withdraw(ctx, own)
        return theirs

    def contribute(self, ctx) -> Contribution:
        dim = _need_dim(self, ctx.view, (2, 3))
        body = self.nodes[0]
        if "." in body:
            raise ModelError(f"rolling {self.name!r}: attach it to a body (its centre is the body's origin), not to "
                             f"the point {body!r}.")
        pose = ctx.view.pose(body)
        r = self.rolling_radius(ctx)
        centre, v = pose.p, ctx.view.velocity(body)
        # the turntable's rate: a number given (0 or 0.0 alike) is a symbol standing for it here, so structurally
        # zero only where not given
        turntable = sp.sympify(self.turntable, strict=True)
        if dim == 2:  # a circle on the line y = 0: ω ẑ × (0, −r) = (ω r, 0)
            if turntable.xreplace(self.values).is_zero is not True:
                raise ModelError(f"rolling {self.name!r}: a turntable turns the ground of a model in space (dim=3).")
            _withdraw(ctx, turntable)  # 0 given: no turntable, and no parameter that params= could set
            if self.F_c is None:
                return Contribution(constraints=[centre[1] - r], velocity_constraints=[v[0] + pose.omega * r])
            friction = friction_contribution(self, self.sliding_rate(ctx))
            return Contribution(constraints=[centre[1] - r], velocity_constraints=friction.velocity_constraints,
                                loads=friction.loads)
        if self.F_c is not None and (self.stick_slip or self.phase != "smooth"):
            self.sliding_rate(ctx)  # refused in space
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
        if turntable != 0:  # the ground turns under the contact: its point there moves at Ω ẑ × contact
            contact = centre + reach
            slip = slip - sp.Matrix([-turntable * contact[1], turntable * contact[0], 0])
        if self.F_c is None:
            return Contribution(constraints=[centre[2] - height], velocity_constraints=[slip[0], slip[1]])
        # sliding along the ground: an isotropic force against the slip, regularized below v_s
        slip = sp.Matrix([slip[0], slip[1]])
        force = -self.F_c * slip / sp.sqrt(slip.dot(slip) + self.v_s**2)
        return Contribution(constraints=[centre[2] - height], loads=[Load(force, slip)])

    @classmethod
    def example(cls) -> Example:
        return Example("d", {"radius": 0.5},
                       context=[("disc", "d", "d", {"m": 1, "radius": 0.5}), ("free", "j", ("ground", "d"), {}),
                                ("gravity", "g", (), {})], options={"dim": 2})
