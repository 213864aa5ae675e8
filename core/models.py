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

from .model import Model

__all__ = ["spherical_pendulum", "heavy_top", "double_pendulum", "loudspeaker", "rlc_ladder"]


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
