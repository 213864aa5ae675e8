"""Canonical systems, built through the public API: for examples, tests and benchmarks.

Each function returns a new :class:`~lagrangian.Model`; parameters may be
numbers or SymPy symbols.

>>> from lagrangian import models, routh
>>> routh.ignorable(models.spherical_pendulum(m=0.3, length=0.7))
['theta_turn']
>>> sorted(routh.ignorable(models.heavy_top()))
['theta_precession', 'theta_spin']
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .base.text import as_expr
from .errors import ModelError
from .model import Model
from .base import deferred as _deferred

sp = _deferred.module("sympy", globals())

__all__ = ["spherical_pendulum", "heavy_top", "double_pendulum", "pendulum_chain", "spring_chain", "loudspeaker",
           "rlc_ladder", "whipple_bicycle"]


def spherical_pendulum(m: Any = 1.0, length: Any = 1.0, g: Any = 9.81) -> Model:
    """A bob of mass ``m`` on a massless arm of ``length`` under gravity ``g``, in the notes' angles.

    Two revolute joints: ``turn`` about the vertical (φ, ignorable) and
    ``tilt`` about the turning horizontal axis (θ from the downward
    vertical), so that ``L = ½ m l² (θ̇² + φ̇² sin²θ) + m g l cos θ``.

    >>> spherical_pendulum(0.3, 0.7).coordinate_names
    ['theta_turn', 'theta_tilt']
    """
    model = Model("spherical pendulum", dim=3)
    model.add("link", "yoke", "yoke")
    model.add("revolute", "turn", ("ground", "yoke"), axis=(0, 0, 1))
    model.add("link", "arm", "arm", points={"bob": (0, 0, -length)})
    model.add("revolute", "tilt", ("yoke", "arm"), axis=(1, 0, 0))
    model.add("mass", "bob", "arm.bob", m=m)
    model.add("gravity", "g", g=g)
    return model


def double_pendulum(m1: Any = 1.0, m2: Any = 1.0, l1: Any = 1.0, l2: Any = 1.0, g: Any = 9.81) -> Model:
    """The planar double pendulum: point masses ``m1``, ``m2`` at the ends of massless links of lengths ``l1``,
    ``l2``, angles ``theta_j1``, ``theta_j2`` absolute (from the x axis), gravity ``g`` along −y.  Its
    parameters given as numbers are named ``m_m1``, ``m_m2``, ``points_l1_end_0``, ``points_l2_end_0``,
    ``parent_point_j2_0`` and ``g_g`` (``simulate(params=...)``, sweeps).

    >>> double_pendulum(0.3, 0.2).coordinate_names
    ['theta_j1', 'theta_j2']
    """
    model = Model("double pendulum", dim=2)
    for i, (mass, length) in enumerate(((m1, l1), (m2, l2)), start=1):
        model.add("link", f"l{i}", f"l{i}", points={"end": (length, 0)})
        model.add("mass", f"m{i}", f"l{i}.end", m=mass)
    model.add("revolute", "j1", ("ground", "l1"), absolute=True)
    model.add("revolute", "j2", ("l1", "l2"), parent_point=(l1, 0), absolute=True)
    model.add("gravity", "g", g=g)
    return model


def heavy_top(m: Any = 0.3, l: Any = 0.4, I1: Any = 0.3, I3: Any = 0.5, g: Any = 9.81) -> Model:
    """A heavy symmetric top: mass ``m``, centre of mass at ``l`` along its axis, inertia ``(I1, I1, I3)``
    about the centre of mass, on a fixed point; Euler angles from three revolute joints z, x, z.

    ``precession`` (φ) and ``spin`` (ψ) are ignorable; ``nutation`` (θ) is
    the tilt of the axis from the upward vertical.  ``V_eff = (C_φ − C_ψ cos θ)²
    / (2 A sin²θ) + C_ψ² / (2 I₃) + m g l cos θ`` with ``A = I₁ + m l²``.

    >>> heavy_top().coordinate_names
    ['theta_precession', 'theta_nutation', 'theta_spin']
    """
    model = Model("heavy symmetric top", dim=3)
    model.add("link", "a", "a")
    model.add("link", "b", "b")
    model.add("body", "top", "top", m=m, inertia=(I1, I1, I3), com=(0, 0, l))
    model.add("revolute", "precession", ("ground", "a"), axis=(0, 0, 1))
    model.add("revolute", "nutation", ("a", "b"), axis=(1, 0, 0))
    model.add("revolute", "spin", ("b", "top"), axis=(0, 0, 1))
    model.add("gravity", "g", g=g)
    return model


def loudspeaker(Re: Any = 6.0, Le: Any = 0.5e-3, Bl: Any = 7.0, m: Any = 0.02, k: Any = 2000.0, c: Any = 1.5,
                E: Any = 0, formulation: str = "charge") -> Model:
    """A moving-coil loudspeaker: a voltage source ``E`` driving the voice coil's resistance ``Re`` and inductance
    ``Le`` into a moving coil of force factor ``Bl`` on the cone (mass ``m`` on a suspension of stiffness ``k`` and
    damping ``c``), in loop charges (``formulation``) and the cone's position.

    >>> model = loudspeaker()
    >>> model.coordinate_names
    ['q_Le', 'x_cone']
    """
    model = Model("loudspeaker", formulation=formulation)
    model.add("voltage_source", "E", ("n1", "0"), E=E)
    model.add("resistor", "Re", ("n1", "n2"), R=Re)
    model.add("inductor", "Le", ("n2", "n3"), L=Le)
    model.add("moving_coil", "coil", ("n3", "0", "cone"), Bl=Bl)
    model.add("mass", "m", "cone", m=m)
    model.add("spring", "k", ("ground", "cone"), k=k)
    model.add("damper", "c", ("ground", "cone"), c=c)
    return model


def pendulum_chain(n: int, m: Any = 1.0, length: Any = 0.5, g: Any = 9.81, dynamics: str = "auto") -> Model:
    """A planar chain of ``n`` uniform rods ``r0 … r<n-1>`` of mass ``m`` (a number, or one per rod) and ``length``
    on revolute joints ``j0 … j<n-1>`` (``theta_j<k>``: each rod's angle to the one before it; the first's to the x
    axis), under gravity ``g`` along −y.  ``dynamics``: the model's option (from 9 links, ``"auto"`` takes the
    articulated-body algorithm).

    >>> chain = pendulum_chain(12, m=[0.3 + 0.05 * k for k in range(12)], length=0.7)
    >>> chain.coordinate_names[:3], chain.eq.recursion is not None
    (['theta_j0', 'theta_j1', 'theta_j2'], True)
    """
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 1 <= n <= 100_000:
        raise ModelError(f"pendulum_chain: n must be a whole number from 1 to 100000, got {n!r}.")
    masses = _each(m, n, "masses")
    model = Model(f"{n}-link planar chain", dim=2, dynamics=dynamics)
    parent = "ground"
    for k in range(n):
        model.add("rod", f"r{k}", f"r{k}", m=masses[k], length=length)
        model.add("revolute", f"j{k}", (parent, f"r{k}"), **({"parent_point": (length, 0)} if k else {}))
        parent = f"r{k}"
    model.add("gravity", "g", g=g)
    return model


def spring_chain(n: int, m: Any = 1.0, k: Any = 1.0, c: Any = None, beta: Any = None, force: Any = None) -> Model:
    """A chain of ``n`` masses ``m0 … m<n-1>`` at nodes ``p0 … p<n-1>`` (coordinates ``x_p<k>``), each tied to the one
    before it (the first to ground) by a spring ``k<k>`` of stiffness ``k`` (cubic stiffness ``beta`` when given)
    and, when ``c`` is given, a damper ``c<k>``; ``force``: a force ``F`` on the last mass.  ``m`` and ``k`` are
    numbers, or one per mass.

    >>> chain = spring_chain(3, m=[0.3, 0.31, 0.32], k=40.0, c=0.02)
    >>> chain.coordinate_names, sorted(chain.components)[:3]
    (['x_p0', 'x_p1', 'x_p2'], ['c0', 'c1', 'c2'])
    """
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 1 <= n <= 1_000_000:
        raise ModelError(f"spring_chain: n must be a whole number from 1 to 1000000, got {n!r}.")
    masses, stiffness = (_each(value, n, what) for value, what in ((m, "masses"), (k, "stiffnesses")))
    model = Model("chain")
    prev = "ground"
    for i in range(n):
        model.add("mass", f"m{i}", f"p{i}", m=masses[i])
        model.add("spring", f"k{i}", (prev, f"p{i}"), k=stiffness[i], **({} if beta is None else {"beta": beta}))
        if c is not None:
            model.add("damper", f"c{i}", (prev, f"p{i}"), c=c)
        prev = f"p{i}"
    if force is not None:
        model.add("force", "F", prev, F=force)
    return model


def _each(value: Any, n: int, what: str) -> list:
    """``value`` once per element of a chain of ``n``: a number repeated, or a sequence of ``n``."""
    values = list(value) if isinstance(value, (list, tuple, np.ndarray)) else [value] * n
    if len(values) != n:
        raise ModelError(f"{len(values)} {what} given for a chain of {n}: give one, or one per element.")
    return values


def rlc_ladder(sections: int, seed: int = 1, E: Any = 0) -> Model:
    """An RLC ladder of ``sections`` sections driven by a voltage source ``V1`` (value ``E``): each a series
    resistor ``R<k>`` (0.2–1 Ω) and inductor ``L<k>`` (0.5–2 H) into a shunt capacitor ``C<k>`` (0.2–1 F) at node
    ``n<k>``, values drawn with the random ``seed`` and rounded to three digits, as a user types them.

    >>> ladder = rlc_ladder(3)
    >>> ladder.coordinate_names, str(ladder.components["L0"].L)
    (['q_L0', 'q_L1', 'q_L2'], '1.93000000000000')
    """
    rng = np.random.default_rng(seed)
    model = Model(f"ladder{sections}")
    model.add("voltage_source", "V1", ("in", "0"), E=E)
    prev = "in"
    for k in range(sections):
        R, L, C = (float(f"{x:.3g}") for x in (rng.uniform(0.2, 1.0), rng.uniform(0.5, 2.0), rng.uniform(0.2, 1.0)))
        model.add("resistor", f"R{k}", (prev, f"m{k}"), R=R)
        model.add("inductor", f"L{k}", (f"m{k}", f"n{k}"), L=L)
        model.add("capacitor", f"C{k}", (f"n{k}", "0"), C=C)
        prev = f"n{k}"
    return model


def whipple_bicycle(w: Any = 1.02, c: Any = 0.08, lam: Any = None, g: Any = 9.81,
                    rR: Any = 0.3, mR: Any = 2.0, IRxx: Any = 0.0603, IRyy: Any = 0.12,
                    xB: Any = 0.3, zB: Any = -0.9, mB: Any = 85.0,
                    IB: Any = ((9.2, 0, 2.4), (0, 11.0, 0), (2.4, 0, 2.8)),
                    xH: Any = 0.9, zH: Any = -0.7, mH: Any = 4.0,
                    IH: Any = ((0.05892, 0, -0.00756), (0, 0.06, 0), (-0.00756, 0, 0.00708)),
                    rF: Any = 0.35, mF: Any = 3.0, IFxx: Any = 0.1405, IFyy: Any = 0.28) -> Model:
    """The Whipple bicycle: a rear frame with its rider, a front fork and handlebar, and two wheels rolling on level
    ground without slipping, the benchmark of Meijaard, Papadopoulos, Ruina and Schwab (Proc. R. Soc. A 463, 2007).

    The parameters are the benchmark's, its Table 1 the defaults, in its axes: x forward, y to the right, z down,
    origin at the rear contact, in the upright reference configuration.  The model is built in the ground's axes
    (x forward, y to the left, z up, gravity along −z; the ground is z = 0).  Four bodies: ``frame`` on a ``free``
    joint to the ground, its origin at the rear axle and its axes the *steer axes* (z along the steer axis, upward;
    y along the rear axle, to the left), so that upright its pitch is −λ; ``rear_wheel`` on a ``revolute`` about the
    frame's y axis at the axle; ``fork`` on a ``revolute`` about the frame's z axis (the steer axis), its origin on
    the steer axis level with the front axle in the steer axes; ``front_wheel`` on a ``revolute`` about the fork's y
    axis at the front axle.  Both wheels roll (``rolling``, shape ``"disc"``, axis y) and ``gravity`` pulls.  Each
    wheel's height is a holonomic constraint, the rear one keeping ``z_frame``, the front one closing the loop
    (``theta_pitch`` follows from ``theta_roll`` and ``theta_steer``), and each contact's not sliding two constraints
    on velocities: three degrees of freedom in velocity (lean, steer and the rear wheel's spin).

    Each parameter may be a number or a SymPy expression.  Those given as numbers are folded into the bodies'
    centres of mass, inertias and points (``parameter_values``), not kept under these names; symbols are kept
    (``simulate(..., params={"lam": ...})``).

    Parameters
    ----------
    w, c, lam, g
        Wheelbase, trail, steer axis tilt from the vertical (default π/10) and gravity.
    rR, mR, IRxx, IRyy
        Rear wheel: radius, mass, moments of inertia about a diameter (IRzz = IRxx) and about the axle.
    xB, zB, mB, IB
        Rear frame and rider: centre of mass in the benchmark's axes, mass, inertia about the centre of mass
        (3 × 3, the benchmark's axes and signs).
    xH, zH, mH, IH
        Front fork and handlebar, as the rear frame.
    rF, mF, IFxx, IFyy
        Front wheel, as the rear wheel.

    Returns
    -------
    Model
        Nine coordinates, in this order: ``x_frame``, ``y_frame``, ``z_frame`` (the rear axle's position);
        ``theta_yaw``, ``theta_roll``, ``theta_pitch`` (the frame's body-fixed z-x-y angles, ``sequence="zxy"``:
        heading about the vertical, lean about the forward axis, positive to the right, and pitch of the steer
        axes about the rear axle, −λ upright; gimbal lock only at a lean of ±π/2); ``theta_rear`` (the rear wheel's
        turn in the frame, positive rolling forwards); ``theta_steer`` (the fork's turn about the steer axis,
        positive to the left); ``theta_front`` (the front wheel's turn in the fork, positive rolling forwards).

    Notes
    -----
    Upright, running straight at speed ``v`` (the other coordinates and rates 0)::

        initial = {"z_frame": rR, "theta_pitch": -lam}
        velocity = {"x_frame": v, "theta_rear": v / rR, "theta_front": v / rF}

    Leaning or
    steered, or with a lean or steer rate, :func:`~lagrangian.plugins.multibody.consistent_initial` holding
    ``x_frame``, ``y_frame``, ``theta_yaw``, ``theta_roll``, ``theta_rear``, ``theta_steer`` and ``theta_front``
    (with the rates of ``theta_roll``, ``theta_steer`` and ``theta_rear`` given) finds the pitch, the height and
    the other rates.

    Examples
    --------
    >>> m = whipple_bicycle()
    >>> m.coordinate_names
    ['x_frame', 'y_frame', 'z_frame', 'theta_yaw', 'theta_roll', 'theta_pitch', 'theta_rear', 'theta_steer', 'theta_front']
    >>> sorted(m.components)
    ['fork', 'frame', 'front', 'front_roll', 'front_wheel', 'g', 'ground_frame', 'rear', 'rear_roll', 'rear_wheel', 'steer']
    """
    def value(e):
        e = as_expr(e, "whipple_bicycle")  # text is read as data (lagrangian.text), never run
        return (float(e) if e != 0 else 0) if e.is_number else e

    lam = sp.pi / 10 if lam is None else as_expr(lam, "whipple_bicycle(lam=)")
    w, c, rR, rF = (as_expr(e, f"whipple_bicycle({n}=)") for e, n in ((w, "w"), (c, "c"), (rR, "rR"), (rF, "rF")))
    cl, sl = sp.cos(lam), sp.sin(lam)
    # the steer axes in the ground's (x forward, y left, z up), upright: x_s = (cos λ, 0, sin λ), z_s = (−sin λ, 0, cos λ)
    R = sp.Matrix([[cl, 0, -sl], [0, 1, 0], [sl, 0, cl]])
    flip = sp.diag(1, -1, -1)  # the benchmark's axes (z down, y right) to the ground's

    def steer_axes(x, z):
        """A point of the benchmark's plane of symmetry (from the rear contact), from the rear axle in steer axes."""
        return R.T * (flip * sp.Matrix([x, 0, z]) - sp.Matrix([0, 0, rR]))

    def inertia(I):
        I = R.T * flip * sp.Matrix(I) * flip * R
        return [[value((I[i, j] + I[j, i]) / 2) for j in range(3)] for i in range(3)]

    # the steer axis meets the ground at the trail c ahead of the front contact; the front axle lies d3 ahead of it
    d1 = (w + c) * cl - rR * sl  # the steer axis, ahead of the rear axle
    front_axle = steer_axes(w, -rF)
    head = sp.Matrix([d1, 0, front_axle[2]])  # the fork's origin, on the steer axis
    d3 = front_axle[0] - d1  # = rF sin λ − c cos λ
    model = Model("Whipple bicycle", dim=3)
    model.add("body", "frame", "frame", m=mB, inertia=inertia(IB), com=[value(e) for e in steer_axes(xB, zB)])
    model.add("body", "fork", "fork", m=mH, inertia=inertia(IH), com=[value(e) for e in steer_axes(xH, zH) - head])
    model.add("body", "rear_wheel", "rear_wheel", m=mR, inertia=(IRxx, IRyy, IRxx))
    model.add("body", "front_wheel", "front_wheel", m=mF, inertia=(IFxx, IFyy, IFxx))
    model.add("free", "ground_frame", ("ground", "frame"), sequence="zxy",
              coordinates="x_frame,y_frame,z_frame,theta_yaw,theta_roll,theta_pitch")
    model.add("revolute", "rear", ("frame", "rear_wheel"), axis=(0, 1, 0))
    model.add("revolute", "steer", ("frame", "fork"), axis=(0, 0, 1), parent_point=[value(e) for e in head])
    model.add("revolute", "front", ("fork", "front_wheel"), axis=(0, 1, 0), parent_point=(value(d3), 0, 0))
    model.add("rolling", "rear_roll", "rear_wheel", radius=rR, shape="disc", axis=(0, 1, 0))
    model.add("rolling", "front_roll", "front_wheel", radius=rF, shape="disc", axis=(0, 1, 0))
    model.add("gravity", "g", g=g)
    return model
