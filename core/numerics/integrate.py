"""Integrators as plugins: the contract, the problem an integrator solves, the driver, ``method="auto"``.

A model's equations ``M(q, t) q̈ = f`` are integrated as the first-order
system ``y' = F(t, y)`` on ``y = (q, q̇_inertial)`` (see
:mod:`lagrangian.simulation`).  Integrators come from plugins (hook
``register_integrators``) and are chosen by name,
``Model.simulate(method="verlet", step=0.01)``.  Each follows the numbered
contract of :class:`Integrator`; fixed-step ones usually subclass
:class:`FixedStepIntegrator`, which owns the stepping loop (output times,
interpolation, progress, divergence) and leaves one step to the subclass.

An integrator receives a :class:`Problem`: ``rhs`` and its Jacobian for any
method and, for structure-preserving ones, the pieces of the Lagrangian —
the momentum ``p = ∂L/∂q̇`` and its inverse, ``∂L/∂q``, the
non-conservative forces, the mass matrix — with :class:`Structure`, which
says what the model is (separable? conservative? linear time-invariant?) so
that a method can refuse a model it cannot integrate, saying why.

:func:`choose` is ``method="auto"``: it reads the eigenvalues of the
linearization at the initial state, whether the model conserves energy, and
the tolerance asked, and says what it picked and why.

>>> import lagrangian as lg
>>> m = lg.Model("oscillator")
>>> _ = m.add("mass", "m", "p", m=1)
>>> _ = m.add("spring", "k", ("ground", "p"), k=4)
>>> res = m.simulate(3.0, initial={"x_p": 1}, velocity={"x_p": 0}, method="verlet", step=1e-3, points=4)
>>> bool(abs(res["x_p"][-1] - np.cos(6.0)) < 1e-5)
True
>>> res.step
0.001
"""

from __future__ import annotations

import functools
import math
import sys
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import sympy as sp

from ..base.component import t as time_symbol
from ..errors import IntegrationError, LagrangianError, ModelError, SingularMassMatrixError, closest
from ..plugin.contracts import KINDS, RESERVED, Integrator, Solution, integrator_problem, resolve
from ..base.identity import depends_on, is_zero
from .events import solve as solve_with_events
from .simulation import NumericModel, Result, _lambdify

__all__ = [
    "Integrator",
    "FixedStepIntegrator",
    "Stepper",
    "Problem",
    "Structure",
    "Spectrum",
    "Solution",
    "Choice",
    "EnergyDriftWarning",
    "integrate",
    "choose",
    "resolve",
    "integrator_problem",
    "KINDS",
    "RESERVED",
]

#: ``method="auto"`` calls a model stiff when its fastest linearized rate exceeds its slowest (or ``1/span``) this much.
STIFFNESS_RATIO = 1e3
#: ... and a conservative run long when it spans this many periods of its fastest mode: RK45's energy error
#: grows by about 0.01–1.5 rtol per period (measured on an oscillator and a double pendulum, rtol 1e-3 to 1e-6),
#: so over this many periods it is 1–150 times the bounded error of a symplectic method stepped for rtol.
LONG_RUN_PERIODS = 100
#: ``choose`` reads the spectrum along a probe run of this many RK45 steps (a start at rest away from equilibrium
#: has a linearization without the frequency of the motion).
PROBE_STEPS = 48
#: A fixed-step run takes at most this many steps.
MAX_STEPS = 100_000_000
#: ... and has diverged when its state grows beyond this many times its initial size (or 1).
_DIVERGED = 1e30
#: Central differences: the step (relative to max(1, |y_j|)) that balances truncation and round-off, eps^(1/3).
_CENTRAL_STEP = float(np.finfo(float).eps ** (1 / 3))


class EnergyDriftWarning(UserWarning):
    """A run of a conservative model did not keep its energy (Jacobi integral) within the tolerance."""


class StiffnessWarning(UserWarning):
    """An explicit method was asked to integrate a stiff model: it will take very many steps."""


#: The stiffness check before an explicit run looks at models of at most this many state variables (an
#: eigenvalue problem of the linearization; larger models are not checked).
STIFFNESS_CHECK_DIM = 400
#: ... and warns when the run is stiff and would take at least this many explicit steps (span · |λ|max),
STIFFNESS_CHECK_STEPS = 1e5
#: ... and refuses the run (it would not end) from this many on.
STIFFNESS_REFUSE_STEPS = 1e10
#: A fixed-step run of a conservative model whose energy changes by more than this (relative) has passed a
#: singularity or gone unstable: its state is not a solution, and the run is an IntegrationError.
EXPLODED = 1.0


# ---------------------------------------------------------------------------
# The contract
# ---------------------------------------------------------------------------


# ---------------------------------------------------------------------------
# The problem an integrator solves
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class Structure:
    """What kind of Lagrangian system a problem is; each ``False`` has its reason in ``why``.

    - ``constant_mass``: ``M`` depends neither on ``q`` nor on ``t``;
    - ``velocity_free``: the forcing ``f(q, q̇, t)`` does not depend on ``q̇``
      (no dissipation, no gyroscopic or velocity-dependent forces);
    - ``separable``: both, every coordinate has inertia and there are no
      constraints — ``L = ½ q̇ᵀ M q̇ − V(q, t)``, what Störmer–Verlet needs;
    - ``conservative``: no dissipation ``D``, no generalized forces ``Q``,
      ``L`` independent of ``t`` — the Jacobi integral ``h = p·q̇ − L``
      (``T + V`` for fixed constraints) is constant;
    - ``autonomous``: the equations do not depend on ``t``;
    - ``linear``: autonomous and affine in the state, ``y' = F y + c`` —
      every one-step map of a fixed-step method is then one constant
      affine map;
    - ``quadratic``: ``L`` is at most quadratic in ``q̇`` (so ``p = M q̇ + p₀``
      is inverted by one linear solve);
    - ``first_order``, ``constrained``: coordinates without inertia, and
      loop-closure constraints.
    """

    first_order: tuple[str, ...]
    constrained: bool
    constant_mass: bool
    velocity_free: bool
    conservative: bool
    autonomous: bool
    linear: bool
    quadratic: bool
    why: Mapping[str, str] = field(default_factory=dict)

    @property
    def separable(self) -> bool:
        return self.constant_mass and self.velocity_free and not self.first_order and not self.constrained

    def why_not_separable(self) -> str:
        """The reasons the Lagrangian is not ``½ q̇ᵀ M q̇ − V(q)`` with constant ``M``, as one phrase."""
        reasons = [self.why[k] for k in ("first_order", "constrained", "constant_mass", "velocity_free") if k in self.why]
        return "; ".join(reasons)


@dataclass(frozen=True)
class Spectrum:
    """Eigenvalues of a linearization, those zero up to its accuracy marked (:meth:`Problem.spectrum`).

    ``scale`` is the 2-norm of the balanced Jacobian, ``error`` the estimated
    norm of its error (same units); ``nonzero`` the eigenvalues that count,
    ``rho`` the largest of their magnitudes (0 when none) and ``slowest``
    the smallest (0 when none).
    """

    eigenvalues: np.ndarray
    zero: np.ndarray
    scale: float
    error: float

    @property
    def nonzero(self) -> np.ndarray:
        return self.eigenvalues[~self.zero]

    @property
    def rho(self) -> float:
        mags = np.abs(self.nonzero)
        return float(mags.max()) if mags.size else 0.0

    @property
    def slowest(self) -> float:
        mags = np.abs(self.nonzero)
        return float(mags.min()) if mags.size else 0.0


class Problem:
    """What an integrator integrates: ``y' = rhs(t, y)`` on ``y = (q, q̇_inertial)``, with the model's structure.

    Built from a :class:`~lagrangian.simulation.NumericModel` (the model with
    numeric parameter values).  ``n`` coordinates named ``names``, ``nI``
    of them inertial; ``dim = n + nI`` is the length of the state.  Every
    evaluation of a model function counts in ``nfev``.

    >>> import lagrangian as lg
    >>> m = lg.Model("osc")
    >>> _ = m.add("mass", "m", "p", m=2)
    >>> _ = m.add("spring", "k", ("ground", "p"), k=8)
    >>> pb = Problem(m.numeric())
    >>> pb.structure.separable, pb.structure.conservative, pb.structure.linear
    (True, True, True)
    >>> pb.momentum(0.0, np.array([0.1]), np.array([3.0]))   # p = m q̇
    array([6.])
    >>> pb.acceleration(0.0, np.array([0.1]))                # −k q / m
    array([-0.4])
    """

    def __init__(self, numeric: NumericModel, name: str = "model"):
        self.numeric = numeric
        self.name = name
        eq = numeric.eq
        self.names: list[str] = list(eq.names)
        self.n = numeric.n
        self.nI = numeric.nI
        self.dim = self.n + self.nI
        self.inertial: list[int] = list(eq.inertial)
        self.first_order: list[str] = [eq.names[i] for i in eq.first_order]
        self.constrained = len(getattr(eq, "constraints", ())) > 0
        self.nfev = 0
        self._report: Callable[[float], None] | None = None

    # -- every method -----------------------------------------------------------
    def rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        """``F(t, y)``: the velocities of all coordinates, then the inertial accelerations."""
        self.nfev += 1
        if self._report is not None:
            self._report(t)
        return self.numeric.rhs(t, y)

    def jacobian(self, t: float, y: np.ndarray, f0: np.ndarray | None = None) -> np.ndarray:
        """``∂F/∂y`` at ``(t, y)`` by forward differences (``dim`` evaluations, one more without ``f0``)."""
        y = np.asarray(y, dtype=float)
        f0 = self.rhs(t, y) if f0 is None else f0
        J = np.empty((f0.size, y.size))
        for j in range(y.size):
            h = 1.5e-8 * max(1.0, abs(y[j]))
            yj = y.copy()
            yj[j] += h
            J[:, j] = (self.rhs(t, yj) - f0) / h
        return J

    def eigenvalues(self, t: float, y: np.ndarray) -> np.ndarray:
        """Eigenvalues of the linearization ``∂F/∂y`` at ``(t, y)``."""
        if self.dim == 0:
            return np.zeros(0, dtype=complex)
        return np.linalg.eigvals(self.jacobian(t, y))

    def _central_jacobian(self, t: float, y: np.ndarray, widen: float = 1.0) -> np.ndarray:
        J = np.empty((self.dim, self.dim))
        for j in range(self.dim):
            h = widen * _CENTRAL_STEP * max(1.0, abs(y[j]))
            up, down = y.copy(), y.copy()
            up[j] += h
            down[j] -= h
            J[:, j] = (self.rhs(t, up) - self.rhs(t, down)) / (up[j] - down[j])
        return J

    def spectrum(self, t: float, y: np.ndarray) -> Spectrum:
        """The eigenvalues of ``∂F/∂y`` at ``(t, y)``, with those that are zero up to the Jacobian's accuracy marked.

        The Jacobian is taken by central differences (``4·dim`` evaluations:
        two step sizes, whose difference estimates its error).  An ignorable
        coordinate gives a zero eigenvalue, usually in a 2 × 2 Jordan block
        with its momentum; an error ``ε`` in the Jacobian splits such a block
        into ``±√ε`` — about 1e-8 of the spectrum for forward differences —
        so no threshold on ``|λ|`` separates it from a slow mode.  The
        number of zero eigenvalues is counted instead by ranks, which an
        error ``ε`` moves by ``ε`` only: ``z = dim − rank(Bᵏ)`` once it stops
        growing with ``k``, where ``B`` is the balanced Jacobian (units of
        the state made comparable) and singular values count as zero below
        ``k·τ·‖B‖ᵏ⁻¹``, ``τ`` 100 times the estimated error (at least
        ``1e3·dim·eps·‖B‖``).  The ``z`` eigenvalues smallest in magnitude
        are the zero ones.  No decision rests on ``λ == 0``.

        >>> import lagrangian as lg
        >>> m = lg.Model("free and bound")
        >>> _ = m.add("mass", "m1", "a", m=0.3)
        >>> _ = m.add("mass", "m2", "b", m=0.3)
        >>> _ = m.add("spring", "k", ("ground", "b"), k=0.7)
        >>> sp_ = Problem(m.numeric()).spectrum(0.0, np.array([0.2, 0.1, 1.5, 0.0]))
        >>> int(sp_.zero.sum()), round(sp_.rho, 6), round((0.7 / 0.3) ** 0.5, 6)   # a's drift: two zeros
        (2, 1.527525, 1.527525)
        """
        y = np.asarray(y, dtype=float)
        if self.dim == 0:
            return Spectrum(np.zeros(0, dtype=complex), np.zeros(0, dtype=bool), 0.0, 0.0)
        J = self._central_jacobian(t, y)
        J2 = self._central_jacobian(t, y, 2.0)
        if not (np.all(np.isfinite(J)) and np.all(np.isfinite(J2))):
            raise IntegrationError(f"the linearization of model {self.name!r} at t={t:g} is not finite: the state is a singular configuration.")
        from scipy.linalg import matrix_balance

        # entries at the level of rounding (a coordinate the model does not depend on, through sines and cosines
        # that cancel) are zero: balancing would otherwise scale them up by orders of magnitude
        floor = 100.0 * np.abs(J - J2) + 64.0 * np.finfo(float).eps * float(np.max(np.abs(J)))
        J = np.where(np.abs(J) <= floor, 0.0, J)
        B, T = matrix_balance(J)
        E = np.linalg.solve(T, (J - J2) @ T)
        scale = float(np.linalg.norm(B, 2))
        lam = np.linalg.eigvals(J)
        zero = np.zeros(lam.size, dtype=bool)
        if not scale > 0.0:  # the zero matrix: every eigenvalue is zero
            return Spectrum(lam, ~zero, 0.0, 0.0)
        error = float(np.linalg.norm(E, 2))
        tau = 100.0 * max(error, 10.0 * self.dim * np.finfo(float).eps * scale)
        count, power = 0, np.eye(self.dim)
        for k in range(1, self.dim + 1):
            power = power @ B
            sv = np.linalg.svd(power, compute_uv=False)
            now = int(np.sum(sv <= k * tau * scale ** (k - 1)))
            if now <= count:
                break
            count = now
        zero[np.argsort(np.abs(lam), kind="stable")[:count]] = True
        return Spectrum(lam, zero, scale, error)

    def report(self, t: float) -> None:
        """Tell whoever watches (``progress=``) that the integration has reached ``t``."""
        if self._report is not None:
            self._report(t)

    # -- structure --------------------------------------------------------------
    @functools.cached_property
    def _sym(self) -> dict[str, Any]:
        eq, numeric = self.numeric.eq, self.numeric
        subs = {s: sp.Float(v) for s, v in numeric.values.items()}
        L = eq.L.xreplace(subs)
        D = eq.D.xreplace(subs)
        Q = eq.Q.xreplace(subs)
        q, v = list(eq.sym.q), list(eq.sym.v)
        diff = eq._derivation.calc.diff  # the derivation's differentiator: the same derivatives, far faster than sp.diff
        Lq = sp.Matrix([diff(eq.L, x) for x in q]).xreplace(subs)
        Lv = sp.Matrix([diff(eq.L, x) for x in v]).xreplace(subs)
        M = eq.M.xreplace(subs)
        Qnc = sp.Matrix([Q[i] - diff(eq.D, v[i]).xreplace(subs) for i in range(len(q))])
        return {"L": L, "D": D, "Q": Q, "G": eq.G.xreplace(subs), "Lq": Lq, "Lv": Lv, "M": M, "Qnc": Qnc,
                "f": eq.f.xreplace(subs), "A": eq.A.xreplace(subs), "b": eq.b.xreplace(subs), "q": q, "v": v}

    @functools.cached_property
    def _conservative(self) -> tuple[bool, str]:
        """Whether the energy is conserved, and why not (the cheap part of :attr:`structure`, which the energy
        check needs on every run: no derivatives taken)."""
        eq, values = self.numeric.eq, self.numeric.values
        subs = {s: sp.Float(v) for s, v in values.items()}
        reasons = []
        if not is_zero(eq.D.xreplace(subs)):
            reasons.append("it dissipates energy (Rayleigh function D ≠ 0)")
        if not all(is_zero(x.xreplace(subs)) for x in eq.Q):
            reasons.append("applied forces or sources do work on it (generalized forces Q ≠ 0)")
        if depends_on(eq.L.xreplace(subs), time_symbol):
            reasons.append("its Lagrangian depends on time (prescribed motions or time-varying parameters)")
        return not reasons and not self.constrained, "; ".join(reasons)

    @functools.cached_property
    def structure(self) -> Structure:
        """The :class:`Structure` of this problem (derived symbolically once)."""
        s = self._sym
        q, v, names = s["q"], s["v"], self.names
        why: dict[str, str] = {}

        def listed(symbols) -> str:
            return ", ".join(names[i] for i in range(self.n) if q[i] in symbols or v[i] in symbols)

        if self.first_order:
            why["first_order"] = f"coordinate(s) {', '.join(self.first_order)} have no inertia (first-order)"
        if self.constrained:
            why["constrained"] = "it has loop-closure constraints kept with Lagrange multipliers"
        M = s["M"]
        m_dep = _dependence(M, q)
        constant_mass = not m_dep and not _dependence(M, [time_symbol])
        if not constant_mass:
            why["constant_mass"] = (
                f"its mass matrix depends on {listed(m_dep)}" if m_dep else "its mass matrix depends on time"
            )
        f_dep = _dependence(s["f"], v)
        velocity_free = not f_dep
        if not velocity_free:
            sources = []
            if not is_zero(s["D"]):
                sources.append("dissipation (dampers, resistors)")
            if not is_zero(s["G"]):
                sources.append("velocity-linear couplings (transducers, gyroscopic terms)")
            if not constant_mass:
                sources.append("the inertial forces of a configuration-dependent mass matrix")
            if not sources:
                sources.append("velocity-dependent applied forces")
            why["velocity_free"] = f"its forces depend on the velocities of {listed(f_dep)} through {' and '.join(sources)}"
        conservative, reasons = self._conservative
        if reasons:
            why["conservative"] = reasons
        A, b = s["A"], s["b"]
        autonomous = not A.has(time_symbol) and not b.has(time_symbol)
        state = q + [v[i] for i in self.inertial]
        linear = False
        if autonomous and not self.constrained and not (A.free_symbols & set(state)) and \
                all(e.is_polynomial(*state) for e in b):  # a cheap screen before differentiating every entry
            J = b.jacobian(state)
            linear = not (J.free_symbols & set(state))
        quadratic = not _dependence(M, v)
        return Structure(tuple(self.first_order), self.constrained, constant_mass, velocity_free, conservative,
                         autonomous, linear, quadratic, why)

    # -- the Lagrangian's pieces ------------------------------------------------
    @functools.cached_property
    def _pieces_fn(self):
        s = self._sym
        return _lambdify((time_symbol, s["q"], s["v"]), [s["Lq"], s["Lv"], s["M"], s["Qnc"]], self.numeric.signals)

    def pieces(self, t: float, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(∂L/∂q, ∂L/∂q̇, M, Q_nc)`` at ``(t, q, q̇)`` in one evaluation; ``Q_nc = Q − ∂D/∂q̇`` (loads and dissipation)."""
        self.nfev += 1
        Lq, Lv, M, Qnc = self._pieces_fn(t, q, v)
        n = self.n
        return (np.asarray(Lq, dtype=float).reshape(n), np.asarray(Lv, dtype=float).reshape(n),
                np.asarray(M, dtype=float).reshape(n, n), np.asarray(Qnc, dtype=float).reshape(n))

    def lagrangian_gradient(self, t: float, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(∂L/∂q, ∂L/∂q̇)`` at ``(t, q, q̇)``."""
        Lq, Lv, _, _ = self.pieces(t, q, v)
        return Lq, Lv

    def momentum(self, t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """The generalized momentum ``p = ∂L/∂q̇`` (``M q̇`` plus any gyroscopic or moving-frame part)."""
        return self.pieces(t, q, v)[1]

    def mass(self, t: float, q: np.ndarray) -> np.ndarray:
        """The mass matrix ``M(q, t) = ∂²L/∂q̇²``."""
        return self.pieces(t, q, np.zeros(self.n))[2]

    def forces(self, t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """The non-conservative generalized forces ``Q − ∂D/∂q̇`` (loads and dissipation)."""
        return self.pieces(t, q, v)[3]

    def velocity(self, t: float, q: np.ndarray, p: np.ndarray) -> np.ndarray:
        """The inverse of :meth:`momentum`: ``q̇ = M⁻¹ (p − p₀(q, t))`` for a Lagrangian quadratic in ``q̇``."""
        _, p0, M, _ = self.pieces(t, q, np.zeros(self.n))
        try:
            return np.linalg.solve(M, p - p0)
        except np.linalg.LinAlgError:
            raise SingularMassMatrixError(self.numeric._singular_message(t, M)) from None

    @property
    def canonical(self) -> bool:
        """Whether the problem has canonical coordinates ``(q, p)``: every coordinate inertial, no constraints, ``L`` quadratic in ``q̇``."""
        return not self.first_order and not self.constrained and self.structure.quadratic

    def to_canonical(self, t: float, y: np.ndarray) -> np.ndarray:
        """``(q, q̇) ↦ (q, p)``."""
        q = y[: self.n]
        return np.concatenate([q, self.momentum(t, q, y[self.n :])])

    def from_canonical(self, t: float, z: np.ndarray) -> np.ndarray:
        """``(q, p) ↦ (q, q̇)``."""
        q = z[: self.n]
        return np.concatenate([q, self.velocity(t, q, z[self.n :])])

    def canonical_rhs(self, t: float, z: np.ndarray) -> np.ndarray:
        """Hamilton's equations with forcing on ``z = (q, p)``: ``q̇ = M⁻¹(p − p₀)``, ``ṗ = ∂L/∂q + Q − ∂D/∂q̇``."""
        q, p = z[: self.n], z[self.n :]
        v = self.velocity(t, q, p)
        Lq, _, _, Qnc = self.pieces(t, q, v)
        return np.concatenate([v, Lq + Qnc])

    @functools.cached_property
    def _acceleration_fn(self):
        s = self._sym
        if not self.structure.separable:
            raise ModelError(f"model {self.name!r} is not separable ({self.structure.why_not_separable()}): "
                             f"its accelerations depend on more than the positions.")
        M = np.array(s["M"].tolist(), dtype=float)
        try:
            Minv = np.linalg.inv(M)
        except np.linalg.LinAlgError:
            raise SingularMassMatrixError(self.numeric._singular_message(0.0, M)) from None
        fn = _lambdify((time_symbol, s["q"]), list(s["f"]), self.numeric.signals)
        if np.array_equal(Minv, np.diag(np.diag(Minv))):
            inverse_masses = np.diag(Minv).copy()
            return lambda t, q: inverse_masses * np.array(fn(t, q), dtype=float)
        return lambda t, q: Minv @ np.array(fn(t, q), dtype=float)

    @functools.cached_property
    def _affine(self):
        """``(f₀, C)`` with ``f = f₀(q, t) − C(q, t) q̇`` as expressions, or None when ``f`` is not affine in ``q̇``."""

        s = self._sym
        v = s["v"]
        C = -s["f"].jacobian(v)
        for entry in C:
            for x in entry.free_symbols & set(v):
                if depends_on(entry, x):
                    return None
        return s["f"].xreplace({x: 0 for x in v}), C

    @property
    def velocity_affine(self) -> bool:
        """Whether the forcing is affine in the velocities, ``f = f₀(q, t) − C(q, t) q̇`` (dampers, resistors, gyroscopic terms)."""
        return self._affine is not None

    @functools.cached_property
    def _affine_fn(self):
        if self._affine is None:
            raise ModelError(f"model {self.name!r}: its forces are not affine in the velocities.")
        f0, C = self._affine
        s = self._sym
        return _lambdify((time_symbol, s["q"]), [f0, C], self.numeric.signals)

    def affine_forces(self, t: float, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(f₀(q, t), C(q, t))`` with ``M q̈ = f₀ − C q̇``, for forces affine in the velocities (:attr:`velocity_affine`).

        >>> import lagrangian as lg
        >>> m = lg.Model("damped")
        >>> _ = m.add("mass", "m", "p", m=0.3)
        >>> _ = m.add("spring", "k", ("ground", "p"), k=0.7)
        >>> _ = m.add("damper", "c", ("ground", "p"), c=0.05)
        >>> f0, C = Problem(m.numeric()).affine_forces(0.0, np.array([0.2]))
        >>> f0.round(12).tolist(), C.round(12).tolist()      # −k q and c
        ([-0.14], [[0.05]])
        """
        self.nfev += 1
        f0, C = self._affine_fn(t, q)
        n = self.n
        return np.asarray(f0, dtype=float).reshape(n), np.asarray(C, dtype=float).reshape(n, n)

    def acceleration(self, t: float, q: np.ndarray) -> np.ndarray:
        """``q̈ = M⁻¹ f(q, t)`` of a separable problem (``structure.separable``); ModelError otherwise."""
        self.nfev += 1
        return self._acceleration_fn(t, q)

    @functools.cached_property
    def _jacobi_fn(self):
        s = self._sym
        h = sum((vi * pi for vi, pi in zip(s["v"], s["Lv"])), sp.Integer(0)) - s["L"]
        return _lambdify((time_symbol, s["q"], s["v"]), h, self.numeric.signals)

    def jacobi(self, t: np.ndarray, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """The Jacobi integral ``h = p·q̇ − L`` at many states (``q``, ``v``: ``n × N``); ``T + V`` for fixed constraints."""
        t = np.asarray(t, dtype=float)
        fast = getattr(self.numeric, "_fast", None)  # compiled code in use (lagrangian.codegen)
        if fast is not None and t.ndim == 1:
            return fast.jacobi(t, q, v)
        return np.broadcast_to(np.asarray(self._jacobi_fn(t, q, v), dtype=float), t.shape).copy()


def _dependence(exprs, symbols) -> set:
    """The ``symbols`` some entry of ``exprs`` really depends on (:func:`lagrangian.identity.depends_on`:
    a dependence that cancels, ``sin²φ + cos²φ`` with floating-point coefficients, is none)."""
    found = set()
    entries = list(exprs)
    for x in symbols:
        if any(x in e.free_symbols and depends_on(e, x) for e in entries):
            found.add(x)
    return found


# ---------------------------------------------------------------------------
# Fixed-step methods: one step from the subclass, the loop from here
# ---------------------------------------------------------------------------


def _identity(t: float, y: np.ndarray) -> np.ndarray:
    return y


@dataclass
class Stepper:
    """One step of a fixed-step method, prepared for one run with step size ``h``.

    ``step(t, z)`` maps the method's internal state at ``t`` to that at
    ``t + h`` (it may update ``z`` in place and return it: the driver
    copies what it keeps); ``to_internal(t, y)`` and ``to_state(t, z)`` convert between
    the model's state ``y = (q, q̇_inertial)`` and the internal one (for
    example ``(q, p)``, or ``(q, q̇, q̈)`` to reuse an acceleration).
    """

    step: Callable[[float, np.ndarray], np.ndarray]
    to_internal: Callable[[float, np.ndarray], np.ndarray] = _identity
    to_state: Callable[[float, np.ndarray], np.ndarray] = _identity


class FixedStepIntegrator(Integrator):
    """A fixed-step method: subclasses provide :meth:`stepper`; this class runs the steps.

    ``solve`` takes ``step`` (required: the largest step size) and
    ``fast_linear`` (default True).  The steps are uniform, ``h = span / N``
    with ``N = ⌈span / step⌉``; when the output times are evenly spaced and
    no closer than ``step``, ``h`` divides their spacing instead, so that
    every output is a step.  Outputs between steps are cubic Hermite
    interpolants (error O(h⁴); noted in ``Result.notes``).

    For a linear time-invariant model (``problem.structure.linear``) the
    one-step map is one constant affine map ``z ↦ R z + r``, whatever the
    method; with ``fast_linear`` it is measured by applying :meth:`stepper`'s
    own step to the unit vectors, and outputs ``k`` steps apart are
    advanced by ``[R r; 0 1]^k`` — the same iterates, in O(log k) work,
    which makes runs of 10⁵ periods cheap.
    """

    kind = "fixed-step"

    def stepper(self, problem: Problem, h: float, **options: Any) -> Stepper:
        """The :class:`Stepper` of this method for ``problem`` with step size ``h``."""
        raise NotImplementedError

    def solve(self, problem, t_span, y0, t_eval, *, step=None, fast_linear=True, **options):
        """Integrate with uniform steps of at most ``step`` (see the class documentation)."""
        t0, t1 = map(float, t_span)
        t_eval = np.asarray(t_eval, dtype=float)
        h, N, notes = _grid(self.name, problem, t0, t1, t_eval, step, np.asarray(y0, dtype=float))
        stepper = self.stepper(problem, h, **options)
        k_float = (t_eval - t0) / h
        k_round = np.rint(k_float)
        on_grid = np.abs(k_float - k_round) < 1e-7
        lo = np.where(on_grid, k_round, np.floor(k_float)).astype(np.int64).clip(0, N)
        hi = np.where(on_grid, lo, np.minimum(lo + 1, N))
        needed = np.unique(np.concatenate([lo, hi]))
        start = problem.nfev
        z0 = np.array(stepper.to_internal(t0, np.array(y0, dtype=float)), dtype=float)
        if fast_linear and problem.structure.linear:
            store, status, message = _march_linear(stepper, t0, h, z0, needed)
            notes.append(
                f"{self.name}: the model is linear time-invariant, so the one-step map is a constant matrix; "
                f"outputs were advanced by its powers ({N} steps of h = {h:.6g}; fast_linear=False steps one by one)"
            )
        else:
            store, status, message = _march(stepper, problem, t0, h, N, z0, needed)
        Y = np.full((problem.dim, t_eval.size), np.nan)
        states = {k: stepper.to_state(t0 + k * h, z) for k, z in store.items()}
        interpolated = 0
        slopes: dict[int, np.ndarray] = {}
        for i in range(t_eval.size):
            a, b = int(lo[i]), int(hi[i])
            if a not in states or b not in states:
                break
            if a == b:
                Y[:, i] = states[a]
                continue
            for k in (a, b):
                if k not in slopes:
                    slopes[k] = problem.rhs(t0 + k * h, states[k])
            s = (t_eval[i] - (t0 + a * h)) / h
            h00, h10, h01, h11 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s, -2 * s**3 + 3 * s**2, s**3 - s**2
            Y[:, i] = h00 * states[a] + h10 * h * slopes[a] + h01 * states[b] + h11 * h * slopes[b]
            interpolated += 1
        if interpolated:
            notes.append(f"{interpolated} output time(s) fall between steps: cubic Hermite interpolation (error O(h⁴))")
        done = np.all(np.isfinite(Y), axis=0)
        count = int(np.argmin(done)) if not done.all() else t_eval.size
        return Solution(t_eval[:count], Y[:, :count], problem.nfev - start, status, message, notes, h)


def _grid(name, problem, t0, t1, t_eval, step, y0) -> tuple[float, int, list[str]]:
    """Step size and count for a fixed-step run; a clear error without a usable ``step``."""
    span = t1 - t0
    if step is None:
        raise _missing_step(name, problem, t0, y0)
    try:
        step = float(step)
    except (TypeError, ValueError):
        raise ModelError(f"step must be a positive number, got {step!r}.") from None
    if not (step > 0 and math.isfinite(step)):
        raise ModelError(f"step must be a positive number, got {step!r}.")
    notes = []
    d = np.diff(t_eval)
    uniform = d.size > 0 and np.allclose(d, d[0], rtol=1e-9, atol=0) and abs(t_eval[0] - t0) <= 1e-12 * max(1.0, abs(t0)) + 1e-12 * span
    if uniform and d[0] >= step * (1 - 1e-12) and abs(t_eval[-1] - t1) <= 1e-9 * span:
        m = math.ceil(d[0] / step - 1e-9)
        h = float(d[0] / m)
        N = m * d.size
    else:
        N = math.ceil(span / step - 1e-9)
        h = span / N
    if N > MAX_STEPS:
        raise ModelError(f"{name}: step={step:g} over a span of {span:g} takes {N:,} steps (more than {MAX_STEPS:,}); use a larger step.")
    if abs(h - step) > 1e-9 * step:
        notes.append(f"{name}: step {step:.6g} shortened to {h:.6g} so that {N} equal steps land on the output times")
    return h, N, notes


def _missing_step(name: str, problem: Problem, t0: float, y0: np.ndarray) -> ModelError:
    hint = ""
    try:
        lam = problem.eigenvalues(t0, y0)
        rho = float(np.max(np.abs(lam))) if lam.size else 0.0
    except Exception:  # the hint is a courtesy; the error is the message
        rho = 0.0
    if rho > 0:
        hint = (f", e.g. step={2 * math.pi / rho / 50:.3g} (1/50 of the shortest period 2π/|λ|max = {2 * math.pi / rho:.3g} "
                f"of the linearization at t={t0:g})")
    return ModelError(f"{name} is a fixed-step method: give its step size, simulate(..., method={name!r}, step=...){hint}.")


def _march(stepper: Stepper, problem: Problem, t0: float, h: float, N: int, z: np.ndarray, needed: np.ndarray):
    """Take ``N`` steps, keeping the internal states at the step indices ``needed``."""
    store: dict[int, np.ndarray] = {}
    wanted = [int(k) for k in needed]
    pos = 0
    if wanted and wanted[0] == 0:
        store[0] = z.copy()
        pos = 1
    nxt = wanted[pos] if pos < len(wanted) else N + 1
    check = max(1, min(1000, N // 50))
    step = stepper.step
    limit = _DIVERGED * max(1.0, float(np.max(np.abs(z))) if z.size else 1.0)
    with np.errstate(over="ignore", invalid="ignore"):
        for k in range(1, N + 1):
            z = step(t0 + (k - 1) * h, z)
            if k == nxt:
                store[k] = z.copy()
                pos += 1
                nxt = wanted[pos] if pos < len(wanted) else N + 1
            if k % check == 0:
                problem.report(t0 + k * h)
                if not np.all(np.abs(z) < limit):
                    return store, -1, f"the state diverged (beyond 1e30 times its initial size, or non-finite) by t={t0 + k * h:g} (step {k} of {N})"
    if not np.all(np.abs(z) < limit):
        return store, -1, f"the state diverged (beyond 1e30 times its initial size, or non-finite) by t={t0 + N * h:g}"
    return store, 0, ""


def _march_linear(stepper: Stepper, t0: float, h: float, z0: np.ndarray, needed: np.ndarray):
    """The same iterates as :func:`_march` for an affine time-invariant step map, by powers of that map."""
    d = z0.size
    r = np.array(stepper.step(t0, np.zeros(d)), dtype=float)
    R = np.empty((d, d))
    for j in range(d):
        e = np.zeros(d)
        e[j] = 1.0
        R[:, j] = np.array(stepper.step(t0, e), dtype=float) - r
    P = np.zeros((d + 1, d + 1))
    P[:d, :d], P[:d, d], P[d, d] = R, r, 1.0
    powers: dict[int, np.ndarray] = {}
    store: dict[int, np.ndarray] = {}
    z, at = np.append(z0, 1.0), 0
    limit = _DIVERGED * max(1.0, float(np.max(np.abs(z0))) if d else 1.0)
    with np.errstate(over="ignore", invalid="ignore"):
        for k in (int(x) for x in needed):
            if k > at:
                gap = k - at
                if gap not in powers:
                    powers[gap] = np.linalg.matrix_power(P, gap)
                z = powers[gap] @ z
                at = k
            if not np.all(np.abs(z[:d]) < limit):
                return store, -1, f"the state diverged (beyond 1e30 times its initial size, or non-finite) by t={t0 + k * h:g} (step {k})"
            store[k] = z[:d].copy()
    return store, 0, ""


# ---------------------------------------------------------------------------
# The driver: Model.simulate's numerical path
# ---------------------------------------------------------------------------


def integrate(
    problem: Problem,
    integrator: Any,
    t_span: tuple[float, float],
    y0: np.ndarray,
    *,
    t_eval: np.ndarray,
    options: Mapping[str, Any],
    model: str,
    defaulted: list[str],
    integrators: Mapping[str, Any] | None = None,
    notes: Sequence[str] = (),
    energy_tol: float | bool | None = None,
    progress: bool | Callable[[float, float], None] = False,
    events: Sequence[Any] = (),
) -> Result:
    """Integrate ``problem`` with ``integrator`` into a :class:`~lagrangian.Result`.

    Refuses first-order coordinates for methods that cannot take them
    (listing those that can, from ``integrators``), runs the method's
    ``check``, checks the options, fails early on a non-finite start, turns
    a failed run into :class:`~lagrangian.IntegrationError`, and checks the
    energy of a conservative model: a Jacobi integral that drifts by more
    than ``energy_tol`` (relative; default ``max(1e-6, 1000 rtol)`` for
    adaptive methods, ``1e-2`` for fixed-step ones; False to skip) gives an
    :class:`EnergyDriftWarning`.
    """
    name = integrator.name
    integrators = integrators or {}
    if problem.first_order and not integrator.first_order:
        able = sorted(n for n, m in integrators.items() if m.first_order)
        raise ModelError(
            f"{name} cannot integrate model {model!r}: coordinate(s) {', '.join(problem.first_order)} have no inertia "
            f"(first-order), and {name} needs inertia for every coordinate. Methods that handle first-order "
            f"coordinates: {', '.join(able) or '(none registered)'}."
        )
    check = getattr(integrator, "check", None)
    if callable(check):
        check(problem)
    allowed = set(KINDS[integrator.kind]) | set(getattr(integrator, "options", {}) or {})
    if integrator.kind == "fixed-step":
        allowed.add("fast_linear")
    for key in options:
        if key not in allowed:
            raise ModelError(
                f"method {name!r} ({integrator.kind}) does not take the option {key!r}.{closest(key, allowed)} "
                f"Its options: {', '.join(sorted(allowed)) or '(none)'}."
            )
    y0 = np.asarray(y0, dtype=float)
    if integrator.kind == "fixed-step" and options.get("step") is None:
        raise _missing_step(name, problem, t_span[0], y0)
    start = problem.rhs(t_span[0], y0)  # fail early, with a clear message, on a singular start
    if not np.all(np.isfinite(start)):
        names = problem.names
        bad = [f"{names[i]}'" if i < problem.n else f"{names[problem.inertial[i - problem.n]]}''"
               for i in np.flatnonzero(~np.isfinite(start))]
        raise IntegrationError(
            f"the equations of model {model!r} are not finite at the initial state ({', '.join(bad)} evaluate to "
            f"{start[~np.isfinite(start)][0]}): the start is a singular configuration of some component "
            f"(e.g. a 2-D spring or damper of zero length). Start elsewhere."
        )
    stiff_note = _stiffness_note(problem, integrator, t_span, y0, model)
    if stiff_note:
        notes = [*notes, "WARNING: " + stiff_note]
        warnings.warn(stiff_note, StiffnessWarning, stacklevel=4)
    problem.nfev = 0
    problem._report = _reporter(t_span, model, progress) if progress else None
    cuts, cut_note = _cuts(problem, integrator, t_span) if not events else ([], None)
    if cut_note:
        notes = [*notes, cut_note]
    occurrences: list = []
    try:
        if events:
            sol, occurrences = solve_with_events(integrator, problem, t_span, y0, t_eval, options, events)
        elif cuts:
            sol = _solve_pieces(integrator, problem, t_span, y0, t_eval, options, cuts)
        else:
            sol = integrator.solve(problem, t_span, y0, t_eval, **options)
    finally:
        problem._report = None
    if not isinstance(sol, Solution):
        raise IntegrationError(f"integrator {name!r} returned {type(sol).__name__}, not a lagrangian.integrate.Solution.")
    sol_t = np.asarray(sol.t, dtype=float)
    sol_y = np.asarray(sol.y, dtype=float).reshape(problem.dim, -1)
    end = sol_t[-1] if sol_t.size else t_span[0]
    if callable(progress):
        progress(end, t_span[1])
    elif progress:
        print(f"\rsimulating {model!r}: done, {sol.nfev} evaluations{' ' * 20}", file=sys.stderr)
    if sol.status < 0:
        advice = (
            "The model may be stiff (try method='Radau' or 'BDF') or singular there."
            if integrator.kind == "adaptive"
            else _fixed_step_advice(problem, integrator, t_span[0], y0, sol.step)
        )
        raise IntegrationError(f"{name} failed on model {model!r} at t={end:g}: {sol.message}. {advice}")
    if (sol_t.size != t_eval.size and not (occurrences and sol.status == 0)) or not np.all(np.isfinite(sol_y)):
        bad = int(np.argmax(~np.all(np.isfinite(sol_y), axis=0))) if sol_y.size else 0
        at = sol_t[bad] if sol_t.size else t_span[0]
        raise IntegrationError(f"the solution of model {model!r} by {name} became non-finite at t={at:g}.")
    numeric = problem.numeric
    n = problem.n
    v = numeric.velocities_many(sol_t, sol_y)
    q = sol_y[:n]
    T, V, D = numeric.energies(sol_t, q, v)
    all_notes = [*notes, *sol.notes]
    acted = any(getattr(e, "action", None) is not None for e in events) and bool(occurrences)
    if acted:  # an action changed the state: the energy of the model alone need not be kept
        all_notes.append("energy not checked: event actions changed the state")
    if problem._conservative[0] and sol_t.size > 1 and not acted:
        _explosion_check(problem, integrator, sol_t, q, v, T, V, model)
    if problem._conservative[0] and sol_t.size > 1 and energy_tol is not False and not acted:
        all_notes.append(_energy_check(problem, integrator, sol_t, q, v, T, V, options, energy_tol, model))
    return Result(
        evaluator=numeric.evaluate,
        t=sol_t,
        q={name_: q[i] for i, name_ in enumerate(problem.names)},
        v={name_: v[i] for i, name_ in enumerate(problem.names)},
        T=T,
        V=V,
        D=D,
        model=model,
        defaulted=defaulted,
        nfev=int(sol.nfev),
        method=name,
        notes=all_notes,
        step=sol.step,
        events=occurrences,
    )


def _cuts(problem: Problem, integrator, t_span) -> tuple[list[float], str | None]:
    """Where an adaptive run restarts: the times in ``t_span`` at which an input of ``t`` switches branch.

    An error estimate taken across a kink (a pulse's corner) can be small by chance, and the step that straddles it
    wrong by 1e-6 at ``rtol=1e-11``; restarting at each switch keeps every step smooth.  Fixed-step methods step
    through (their error is the step's).  Returns the times and a note when they could not be found.
    """
    if integrator.kind != "adaptive":
        return [], None
    try:
        cuts = problem.numeric.switching_times(*t_span)
    except ValueError as exc:
        return [], f"inputs switch at times that could not be found ({exc}): steps across them rely on error control"
    width = t_span[1] - t_span[0]
    kept: list[float] = []
    for c in cuts:  # one restart per corner: two conditions may find the same one a rounding apart
        if t_span[0] + 1e-12 * width < c < t_span[1] - 1e-12 * width and (not kept or c - kept[-1] > 1e-12 * width):
            kept.append(c)
    return kept, None


def _solve_pieces(integrator, problem: Problem, t_span, y0: np.ndarray, t_eval: np.ndarray, options, cuts) -> Solution:
    """``integrator.solve`` on each piece between ``cuts``, each piece starting from where the last one ended."""
    edges = [t_span[0], *[c for c in cuts if c < t_eval[-1]], t_span[1]]  # nothing to restart past the last output
    ts, ys, nfev, notes = [], [], 0, []
    y = np.asarray(y0, dtype=float)
    for i, (a, b) in enumerate(zip(edges[:-1], edges[1:])):
        last = i == len(edges) - 2
        inside = t_eval[(t_eval >= a) & ((t_eval <= b) if last else (t_eval < b))]
        grid = inside if last else np.append(inside, b)  # b: where the next piece starts
        sol = integrator.solve(problem, (a, b), y, grid, **options)
        nfev += int(sol.nfev)
        notes += [n for n in sol.notes if n not in notes]
        sol_t = np.asarray(sol.t, dtype=float)
        sol_y = np.asarray(sol.y, dtype=float).reshape(problem.dim, -1)
        keep = sol_t.size if last else min(inside.size, sol_t.size)
        ts.append(sol_t[:keep])
        ys.append(sol_y[:, :keep])
        if sol.status < 0 or sol_t.size < grid.size:
            message = sol.message or f"stopped at t={sol_t[-1] if sol_t.size else a:g}"
            return Solution(np.concatenate(ts), np.concatenate(ys, axis=1), nfev, min(sol.status, -1), message, notes)
        y = sol_y[:, -1]
    notes.append(f"restarted at {len(edges) - 2} switching time(s) of the inputs (pulse corners, steps)")
    return Solution(np.concatenate(ts), np.concatenate(ys, axis=1), nfev, 0, "", notes, None)


def _stiffness_note(problem: Problem, integrator, t_span, y0, model) -> str | None:
    """Why an explicit adaptive method will crawl on this model (its linearization at the start is stiff), or
    ``None``: explicit methods need steps of about 1/|λ|max, so a span of many slow time scales takes
    ``span·|λ|max`` evaluations and more."""
    if integrator.kind != "adaptive" or integrator.implicit or integrator.stiff or problem.dim > STIFFNESS_CHECK_DIM:
        return None
    try:
        spec = problem.spectrum(float(t_span[0]), np.asarray(y0, dtype=float))
    except Exception:  # advice only: a model the linearization cannot take is not refused here
        return None
    span = float(t_span[1]) - float(t_span[0])
    slow = max(spec.slowest, 1.0 / span) if span > 0 else spec.slowest
    steps = span * spec.rho if np.isfinite(spec.rho) else math.inf
    if steps >= STIFFNESS_REFUSE_STEPS:
        raise IntegrationError(
            f"model {model!r} has a rate of {spec.rho:.3g} 1/s in its linearization at the start: the explicit method "
            f"{integrator.name} would need some {steps:.3g} steps over this run, which would not end. Use "
            f"method='auto' or method='Radau' (implicit), or check the parameter values (a damper of c = 1e308?)."
        )
    if not (slow > 0 and spec.rho / slow > STIFFNESS_RATIO and steps >= STIFFNESS_CHECK_STEPS):
        return None
    return (f"model {model!r} is stiff: the linearization at the start has rates from {spec.slowest:.3g} to "
            f"{spec.rho:.3g} 1/s (ratio {spec.rho / slow:.3g}), so the explicit method {integrator.name} needs steps of "
            f"about {1 / spec.rho:.3g} s, some {span * spec.rho:.3g} of them or more over this run; use method='auto' "
            f"(which picks an implicit method here) or method='Radau'.")


def _drift(problem, t, q, v, T, V):
    """The Jacobi integral along a run, its scale and its largest change relative to that scale."""
    h = problem.jacobi(t, q, v)
    scale = max(abs(h[0]), float(np.max(np.abs(T))), float(np.max(np.abs(V))), np.finfo(float).tiny)
    return h, scale, float(np.max(np.abs(h - h[0])) / scale)


def _explosion_check(problem, integrator, t, q, v, T, V, model) -> None:
    """A fixed-step explicit run of a conservative model whose energy left its start by more than its size there:
    an :class:`IntegrationError` (the states are not a solution), whatever ``energy_tol`` says."""
    if integrator.kind == "adaptive" or integrator.implicit:
        return
    h, scale, _ = _drift(problem, t, q, v, T, V)
    # against the energy at the start (the run's own scale when the start has none): a run that gained or lost
    # more than that passed a singularity or went unstable
    start = max(abs(h[0]), abs(float(T[0])), abs(float(V[0])))
    reference = start if start > 1e-3 * scale else scale
    change = float(np.max(np.abs(h - h[0]))) / reference
    if change > EXPLODED:
        where = int(np.argmax(np.abs(h - h[0]) > EXPLODED * reference))
        raise IntegrationError(
            f"the state of model {model!r} exploded under {integrator.name}: its energy (Jacobi integral), "
            f"conserved by the model, changed by {change:.3g} times its size at the start by t={t[where]:g}, so "
            f"the run passed a singularity or went unstable and its states are not a solution. Reduce step=, or "
            f"use an adaptive method (method='auto')."
        )


def _energy_check(problem, integrator, t, q, v, T, V, options, energy_tol, model) -> str:
    h, scale, drift = _drift(problem, t, q, v, T, V)
    if energy_tol is None:
        energy_tol = max(1e-6, 1e3 * float(options.get("rtol", 0.0))) if integrator.kind == "adaptive" else 1e-2
    note = f"energy (Jacobi integral) kept to {drift:.2e} relative over the run (tolerance {energy_tol:.1e})"
    if drift > energy_tol:
        where = int(np.argmax(np.abs(h - h[0]) > energy_tol * scale))
        if integrator.symplectic:
            fix = "reduce step= (the energy error of a symplectic method is bounded but grows with the step)"
        else:
            symplectic = "a symplectic method (gauss_legendre, variational, verlet)"
            fix = (f"tighten rtol, or for long runs use {symplectic}" if integrator.kind == "adaptive"
                   else f"reduce step=, or use {symplectic}")
        message = (
            f"model {model!r} is conservative, but its energy (Jacobi integral) drifted by {drift:.2e} relative "
            f"under {integrator.name} (tolerance {energy_tol:.1e}, first exceeded at t={t[where]:g}): {fix}. "
            f"Set energy_tol= to change the tolerance, or energy_tol=False to skip the check."
        )
        warnings.warn(message, EnergyDriftWarning, stacklevel=5)
        note = "WARNING: " + message
    return note


def _fixed_step_advice(problem: Problem, integrator, t0: float, y0: np.ndarray, h: float | None) -> str:
    try:
        lam = problem.eigenvalues(t0, y0)
        rho = float(np.max(np.abs(lam))) if lam.size else 0.0
    except Exception:  # advice only
        rho = 0.0
    if not h or not rho:
        return "Reduce step=."
    kind = "explicit" if not integrator.implicit else "implicit"
    return (
        f"With step {h:.3g} and the fastest mode of the linearization at the start, |λ|max = {rho:.3g}, "
        f"h·|λ|max = {h * rho:.3g}: the {kind} method {integrator.name} is probably unstable (explicit methods need "
        f"h·|λ|max of order 1–3). Reduce step= below {2 / rho:.3g}, or use a stiff method (Radau, BDF, gauss_legendre)."
    )


def _reporter(t_span, model: str, progress) -> Callable[[float], None]:
    """Report progress through ``t_span`` every 5 %: to ``progress(t, t_end)`` or on standard error."""
    t0, t1 = t_span
    report = progress if callable(progress) else None
    state = {"next": 0.0}

    def seen(time: float) -> None:
        fraction = (time - t0) / (t1 - t0)
        if fraction >= state["next"]:
            state["next"] = fraction + 0.05
            if report is not None:
                report(time, t1)
            else:
                print(f"\rsimulating {model!r}: {100 * fraction:5.1f} % (t = {time:.4g} of {t1:.4g})",
                      end="", file=sys.stderr, flush=True)

    return seen


# ---------------------------------------------------------------------------
# method="auto"
# ---------------------------------------------------------------------------


@dataclass
class Choice:
    """What ``method="auto"`` picked: the method's name, options for it, and why (``notes``)."""

    method: str
    options: dict[str, Any]
    notes: list[str]
    eigenvalues: np.ndarray
    stiff: bool = False


def choose(
    problem: Problem,
    t_span: tuple[float, float],
    y0: np.ndarray,
    *,
    rtol: float = 1e-9,
    linear_exact: bool = False,
    integrators: Mapping[str, Any] | None = None,
) -> Choice:
    """Pick a method for ``problem`` from its properties; say why in ``Choice.notes``.

    The spectrum is that of the linearization at the initial state without
    its zero eigenvalues (:meth:`Problem.spectrum`: an ignorable coordinate
    or a free drift is no time scale): ``|λ|max`` is the fastest rate,
    ``|λ|min`` the slowest.

    1. ``linear_exact`` (the model is linear time-invariant with inputs the
       exact solver takes): ``"exact"`` — no integration error at all.
    2. Stiff — ``|λ|max`` exceeds ``max(|λ|min, 1/span)`` more than
       :data:`STIFFNESS_RATIO` times: ``LSODA``, whose BDF formulas take
       over once it detects the stiffness (on the stiff benchmarks it
       needed 2–10 times fewer evaluations than ``Radau`` and ``BDF`` at
       tolerances from 1e-3 to 1e-9).  Never an explicit method.
    3. Conservative (no dissipation, no applied forces, ``L`` independent
       of ``t``) at a loose tolerance (``rtol ≥ 1e-6``), and a run of at
       least :data:`LONG_RUN_PERIODS` periods of the fastest mode: a
       symplectic fixed-step method, whose energy error stays bounded
       instead of drifting — ``verlet`` with ``h·ω = √(8 rtol)`` for a
       separable Lagrangian, ``gauss_legendre`` with ``h·ω = rtol^¼``
       otherwise (their energy errors are about ``(hω)²/8`` and
       ``(hω)⁴``) — unless that takes more than 2·10⁶ steps.  The fastest
       mode is the largest ``|λ|`` at the initial state and at a few states
       of a short probe run (:data:`PROBE_STEPS` steps of RK45): a start at
       rest away from equilibrium (a pendulum let go from the horizontal)
       has a linearization with no frequency in it at all.
    4. Otherwise ``DOP853`` for ``rtol ≤ 1e-6`` and ``RK45`` above
       (scipy's advice for high and moderate precision).

    >>> import lagrangian as lg
    >>> m = lg.Model("pendulum", dim=2)
    >>> _ = m.add("link", "arm", "arm", points={"bob": (0.7, 0)})
    >>> _ = m.add("revolute", "pin", ("ground", "arm"))
    >>> _ = m.add("mass", "bob", "arm.bob", m=0.3)
    >>> _ = m.add("gravity", "g")
    >>> choose(Problem(m.numeric()), (0.0, 1000.0), np.zeros(2), rtol=1e-4).method   # let go from the horizontal
    'verlet'
    >>> choose(Problem(m.numeric()), (0.0, 2.0), np.zeros(2), rtol=1e-4).method
    'RK45'
    """
    t0, t1 = map(float, t_span)
    span = t1 - t0
    y0 = np.asarray(y0, dtype=float)
    structure = problem.structure
    spec = problem.spectrum(t0, y0)
    lam = spec.eigenvalues
    rho, slowest = spec.rho, spec.slowest
    slow = max(slowest, 1.0 / span)
    ratio = rho / slow
    stiff = ratio > STIFFNESS_RATIO
    what = "conservative" if structure.conservative else "not conservative (" + structure.why.get("conservative", "constraints") + ")"
    zeros = int(spec.zero.sum())
    spectrum = (
        f"eigenvalues of the linearization at t={t0:g}: |λ| from {slowest:.3g} to {rho:.3g}"
        + (f" and {zeros} zero (ignorable coordinates, drifts)" if zeros else "")
        + f" (ratio to max(slowest, 1/span) {ratio:.3g}; stiff above {STIFFNESS_RATIO:.0e})"
    )
    available = integrators if integrators is not None else {}

    def pick(method: str, reason: str, options: dict | None = None) -> Choice:
        if integrators is not None and method not in available and method != "exact":
            raise ModelError(f"method='auto' picked {method!r} ({reason}), but no installed plugin provides it.")
        note = f"auto: picked {method!r}: {reason}; {spectrum}; model {what}; rtol {rtol:.1e}"
        return Choice(method, options or {}, [note], lam, stiff)

    if linear_exact:
        return pick("exact", "the model is linear time-invariant, so it is solved exactly by matrix exponentials (no tolerance applies)")
    if stiff:
        return pick("LSODA", "stiff, so an implicit method (LSODA: BDF formulas with Newton iterations once stiffness is detected)")
    if structure.conservative and rtol >= 1e-6:
        fastest, probed = _fastest_rate(problem, (t0, t1), y0, rtol, rho)
        periods = fastest * span / (2 * math.pi)
        if periods >= LONG_RUN_PERIODS:
            if structure.separable:
                method, hw = "verlet", min(0.5, math.sqrt(8 * rtol))
            else:
                method, hw = "gauss_legendre", min(0.5, rtol**0.25)
            h = hw / fastest
            steps = span / h
            if steps <= 2e6 and (integrators is None or method in available):
                where = (f"|λ|max = {fastest:.3g}, the largest at the start and at {probed} states of a short probe run"
                         if probed else f"|λ|max = {fastest:.3g}")
                return pick(method, f"a long conservative run ({periods:.3g} periods of the fastest mode, {where}) at a "
                                    f"loose tolerance: a symplectic method keeps the energy error bounded (about rtol) "
                                    f"instead of drifting; step h = {h:.3g} (h·|λ|max = {hw:.3g}, {steps:.3g} steps)",
                            {"step": h})
    if rtol <= 1e-6:
        return pick("DOP853", "not stiff, tight tolerance: explicit Runge–Kutta of order 8")
    return pick("RK45", "not stiff, moderate tolerance: explicit Runge–Kutta of order 5(4)")


def _fastest_rate(problem: Problem, t_span: tuple[float, float], y0: np.ndarray, rtol: float, rho: float) -> tuple[float, int]:
    """The largest ``|λ|`` (zeros excluded) at the start and along a short RK45 probe run; how many probe states were read.

    The probe takes at most :data:`PROBE_STEPS` steps (never beyond the
    span) and reads the spectrum every quarter of them; a probe that fails
    (a singular state) leaves the estimate from the start.
    """
    from scipy.integrate import RK45

    t0, t1 = t_span
    fastest, probed = rho, 0
    try:
        with np.errstate(all="ignore"):
            solver = RK45(problem.rhs, t0, y0, t1, rtol=rtol, atol=rtol * max(1.0, float(np.max(np.abs(y0)))) * 1e-3)
            every = max(1, PROBE_STEPS // 4)
            for k in range(1, PROBE_STEPS + 1):
                if solver.status != "running":
                    break
                solver.step()
                if k % every == 0 or solver.status != "running":
                    if not np.all(np.isfinite(solver.y)):
                        break
                    fastest = max(fastest, problem.spectrum(solver.t, solver.y).rho)
                    probed += 1
    except (LagrangianError, ArithmeticError, ValueError, np.linalg.LinAlgError):
        pass  # the probe only refines the estimate from the start
    return fastest, probed
