"""Built-in plugin: integrators, and the benchmark problems of ``lagrangian bench``.

Adaptive (``rtol``, ``atol``, ``max_step``), from :func:`scipy.integrate.solve_ivp`:
``RK23``, ``RK45``, ``DOP853`` (explicit), ``Radau``, ``BDF`` (implicit, for
stiff models) and ``LSODA`` (switches between Adams and BDF).  ``DOP853``
steps in C where the model has compiled code (SciPy's steps, see
``dop853_c`` below); ``DOP853_scipy`` is SciPy's own.

Fixed-step (``step=``), written here on the contract of
:class:`lagrangian.integrate.FixedStepIntegrator`:

- ``rk4`` — classical Runge–Kutta, explicit, order 4;
- ``verlet`` — Störmer–Verlet (leapfrog), explicit, symplectic, order 2,
  for separable Lagrangians ``½ q̇ᵀ M q̇ − V(q, t)`` with constant ``M``;
- ``implicit_midpoint`` and ``gauss_legendre`` — Gauss–Legendre
  collocation with ``stages`` = 1, 2, 3 (order 2s), implicit, symplectic and
  A-stable, for any model: on canonical coordinates ``(q, p)`` when every
  coordinate has inertia (symplectic even with a configuration-dependent
  mass matrix), on ``(q, q̇)`` otherwise;
- ``variational`` — a variational integrator: the discrete Lagrangian
  ``L_d(q_k, q_{k+1}, h)`` by the midpoint (default) or trapezoidal rule,
  the discrete Euler–Lagrange equations solved for ``q_{k+1}`` by Newton's
  method, and dissipation and applied forces through the discrete
  Lagrange–d'Alembert principle.  Order 2, symplectic for conservative
  models.

With the stepping loop compiled to C (:mod:`lagrangian.codegen`; the
Python sibling runs, with a note, when there is no C compiler):
``dopri5_c`` (adaptive, the Dormand–Prince pair of ``RK45`` with its dense
output), ``dop853_c`` (adaptive, ``DOP853`` with its 7th-order dense output),
``rk4_c`` and ``verlet_c`` (fixed-step, the same steps and
refusals as ``rk4`` and ``verlet``).

The plugin's modules: :mod:`.adaptive` (SciPy's methods), :mod:`.explicit`
(``rk4``, ``verlet``), :mod:`.implicit` (``implicit_midpoint``,
``gauss_legendre``, ``variational``), :mod:`.benchmarks` (the problems of
``lagrangian bench``) and :mod:`.hooks` (the registered integrators and the
hook implementations); this package re-exports their public names.

>>> import lagrangian as lg
>>> m = lg.Model("osc")
>>> _ = m.add("mass", "m", "p", m=0.3)
>>> _ = m.add("spring", "k", ("ground", "p"), k=0.7)
>>> _ = m.add("damper", "c", ("ground", "p"), c=0.05)
>>> res = m.simulate(1, initial={"x_p": 1}, velocity={"x_p": 0}, method="verlet", step=0.01, points=3)
>>> res.method, res.step                 # the damped form: (M + h/2 C) v' = M v½ + h/2 f₀
('verlet', 0.01)
>>> p = lg.Model("double pendulum", dim=2)
>>> for i in (1, 2):
...     _ = p.add("link", f"l{i}", f"l{i}", points={"end": (0.7, 0)})
...     _ = p.add("mass", f"m{i}", f"l{i}.end", m=0.3)
>>> _ = p.add("revolute", "j1", ("ground", "l1"), absolute=True)
>>> _ = p.add("revolute", "j2", ("l1", "l2"), parent_point=(0.7, 0), absolute=True)
>>> _ = p.add("gravity", "g")
>>> start = {"initial": {"theta_j1": -1.0, "theta_j2": 0.0}, "velocity": {"theta_j1": 0.0, "theta_j2": 0.0}}
>>> p.simulate(1, **start, method="verlet", step=0.01)
Traceback (most recent call last):
...
lagrangian.errors.ModelError: verlet (Störmer–Verlet) needs a constant mass matrix ... its mass matrix depends on theta_j1, theta_j2. Use 'variational' with rule='trapezoidal' ...
>>> res = p.simulate(1, **start, method="variational", rule="trapezoidal", step=0.01)
>>> res.method, res.step
('variational', 0.01)
"""

import types as _types

import numpy as np  # noqa: F401 - the examples run from here through __test__ use it (kepler_orbit's), as before

# the public names of the modules, all importable from here as before the split (some outside __all__)
from .adaptive import ScipyMethod
from .benchmarks import BENCHMARKS, KEPLER_E, TWO_PI, InverseSquare, kepler_orbit  # noqa: F401
from .explicit import RK4, ExplicitRungeKutta, StormerVerlet  # noqa: F401
from .hooks import INTEGRATORS, register_benchmarks, register_integrators  # noqa: F401 - pluggy registers this module
from .implicit import GaussLegendre, Variational, gauss_legendre_tableau  # noqa: F401

__all__ = ["ScipyMethod", "ExplicitRungeKutta", "StormerVerlet", "GaussLegendre", "Variational", "INTEGRATORS"]

# doctest.testmod(lagrangian.plugins.integrators) finds the examples of what a module defines; those of the classes
# and functions re-exported here run with this module's through __test__.
__test__ = {
    name: obj for name, obj in globals().items()
    if not name.startswith("_") and isinstance(obj, (type, _types.FunctionType))
}
