"""Ignorable coordinates, Routhian reduction, the Jacobi integral, steady motion and its stability.

A coordinate ``q_i`` that appears in the Lagrangian only through its
velocity — and on which no dissipation, generalized force or loop
constraint acts — is *ignorable* (cyclic): its momentum ``p_i = ∂L/∂q̇_i``
is a constant ``C_i``.  Solving ``p_i = C_i`` for the ignorable velocities
and forming the Routhian

    R = Σ C_i q̇_i − L

leaves ``n − m`` coordinates whose equations of motion are Lagrange's with
``−R`` as their Lagrangian; the ignorable coordinates follow by quadrature,
``q_i(t) = q_i(t₀) + ∫ ∂R/∂C_i dt``.  ``−R`` splits by degree in the
remaining velocities into a kinetic energy, velocity-linear (gyroscopic)
terms and ``−V_eff``: the *effective potential* (the potential energy plus
the kinetic energy locked in the ignorable motion).

>>> import lagrangian as lg
>>> from lagrangian import routh
>>> m = lg.Model("spherical pendulum", dim=3)
>>> _ = m.add("link", "yoke", "yoke")
>>> _ = m.add("revolute", "turn", ("ground", "yoke"), axis=(0, 0, 1))
>>> _ = m.add("link", "arm", "arm", points={"bob": (0, 0, -1)})
>>> _ = m.add("revolute", "tilt", ("yoke", "arm"), axis=(1, 0, 0))
>>> _ = m.add("mass", "bob", "arm.bob", m=1)
>>> _ = m.add("gravity", "g", g=9.81)
>>> routh.ignorable(m)
['theta_turn']
>>> red = routh.reduce(m)
>>> red.routhian
C_theta_turn**2/(2*sin(theta_tilt(t))**2) - 9.81*cos(theta_tilt(t)) - Derivative(theta_tilt(t), t)**2/2
>>> red.effective_potential
C_theta_turn**2/(2*sin(theta_tilt(t))**2) - 9.81*cos(theta_tilt(t))

``jacobi_integral`` gives ``h = Σ q̇ ∂L/∂q̇ − L`` for any model and says
whether it is conserved (and whether it equals the total energy);
:meth:`ReducedModel.steady_motions` solves ``∂R/∂q_k = 0`` with the reduced
velocities zero, and :meth:`SteadyMotion.stability` linearizes about a
steady motion.  Reduced models are :class:`~lagrangian.Model` objects:
``simulate`` works as for the full model, the momenta given as values
(``momenta=``) or from the full model's initial velocities.

The package holds one concept per module, each importing only those below
it: :mod:`.reduction` (:class:`ReducedModel`, :func:`reduce`) and
:mod:`.jacobi` (the Jacobi integral) on top, then :mod:`.steady` (steady
motions), :mod:`.stability` (their linearization and verdict), and at the
bottom :mod:`.cyclic` (ignorable coordinates), :mod:`.cache` (reductions kept
by structure) and :mod:`.tidy` (cosmetic simplification).  Every name is
available here, as it was when this was one module.
"""

from .cache import CACHE_SIZE, _CACHE, _CACHE_LOCK, _by_structure, _put
from .cyclic import Ignorability, _components, _depends, _named, ignorability, ignorable
from .jacobi import JacobiIntegral, _without_residues, jacobi_integral
from .reduction import ReducedModel, reduce
from .stability import Perturbation, Stability, _fmt, _off_singular
from .steady import SteadyMotion, _is_angle, _numeric_roots, _solve
from .tidy import TIDY_SECONDS, _drop, _factors_vanishing, _simplified, _terms, _tidy

__all__ = [
    "Ignorability",
    "ignorability",
    "ignorable",
    "reduce",
    "ReducedModel",
    "JacobiIntegral",
    "jacobi_integral",
    "SteadyMotion",
    "Perturbation",
    "Stability",
]
