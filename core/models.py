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

from .model import Model

__all__ = ["spherical_pendulum", "heavy_top", "double_pendulum"]


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
