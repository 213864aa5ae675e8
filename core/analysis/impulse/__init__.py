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

>>> import sympy as sp
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

from .contacts import (
    Contact,
    ContactError,
    GrazingImpactError,
    ImpactError,
    Impulse,
    Lock,
    SingularImpactError,
    between,
    fix,
    ground,
    lock,
    plane,
    wall,
)
from .hybrid import ImpactRecord, ImpactResult, simulate_with_impacts
from .jump import Jump, generalized_impulse, impact, velocity_jump

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
