"""Built-in plugin: integrators, and the benchmark problems of ``lagrangian bench``.

Adaptive (``rtol``, ``atol``, ``max_step``), from :func:`scipy.integrate.solve_ivp`:
``RK23``, ``RK45``, ``DOP853`` (explicit), ``Radau``, ``BDF`` (implicit, for
stiff models) and ``LSODA`` (switches between Adams and BDF).

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
output), ``rk4_c`` and ``verlet_c`` (fixed-step, the same steps and
refusals as ``rk4`` and ``verlet``).

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
>>> p.simulate(1, initial={"theta_j1": -1.0}, method="verlet", step=0.01)
Traceback (most recent call last):
...
lagrangian.errors.ModelError: verlet (Störmer–Verlet) needs a constant mass matrix ... its mass matrix depends on theta_j1, theta_j2. Use 'variational' with rule='trapezoidal' ...
>>> res = p.simulate(1, initial={"theta_j1": -1.0}, method="variational", rule="trapezoidal", step=0.01)
>>> res.method, res.step
('variational', 0.01)
"""

from __future__ import annotations

import functools
import math
import types

import numpy as np
import sympy as sp

from lagrangian import Component, Contribution, Example, IntegrationError, ModelError, Parameter, dot, hookimpl
from lagrangian.bench import Benchmark
from lagrangian.compiled_loops import CompiledDormandPrince, CompiledFixedStep
from lagrangian.integrate import FixedStepIntegrator, Integrator, Solution, Stepper

__all__ = ["ScipyMethod", "ExplicitRungeKutta", "StormerVerlet", "GaussLegendre", "Variational", "INTEGRATORS"]

_GENERAL = "'variational' or 'gauss_legendre' (symplectic, any Lagrangian, dissipation and forces included), or an adaptive method (DOP853, Radau)"


# ---------------------------------------------------------------------------
# Adaptive: scipy
# ---------------------------------------------------------------------------


class ScipyMethod(Integrator):
    """One method of :func:`scipy.integrate.solve_ivp`, error-controlled by ``rtol`` and ``atol``."""

    kind = "adaptive"
    options = {"first_step": "initial step size (default: chosen by scipy)"}

    def __init__(self, name: str, order: int, description: str, *, implicit: bool = False, stiff: bool = False):
        self.name, self.order, self.description = name, order, description
        self.implicit, self.stiff = implicit, stiff

    def solve(self, problem, t_span, y0, t_eval, *, rtol=1e-9, atol=1e-12, max_step=np.inf, first_step=None):
        """Integrate with :func:`scipy.integrate.solve_ivp` (``method=self.name``)."""
        from scipy.integrate import solve_ivp

        extra = {} if first_step is None else {"first_step": first_step}
        try:
            sol = solve_ivp(problem.rhs, t_span, y0, method=self.name, t_eval=t_eval, rtol=rtol, atol=atol,
                            max_step=max_step, **extra)
        except ValueError as exc:
            error = self._failure(problem, exc)
            if error is None:
                raise
            raise error from None
        return Solution(sol.t, sol.y, sol.nfev, sol.status, sol.message)

    def _failure(self, problem, exc: ValueError) -> IntegrationError | None:
        """The error for a ValueError out of SciPy's solver: a Jacobian (of an implicit method) or a state that is
        not finite is an :class:`IntegrationError`, as compiled code reports it; ``None`` for any other (SciPy's
        own error stands)."""
        text = str(exc).lower()
        if "finite" not in text and not ("inf" in text and "nan" in text):  # "array must not contain infs or NaNs"
            return None
        model = getattr(problem, "name", "") or "the model"
        return IntegrationError(
            f"{self.name} failed on model {model!r}: its Jacobian or state is not finite ({exc}) — a mass matrix "
            f"nearly singular (an inertia, mass or inductance many orders of magnitude below the others), or "
            f"equations that overflow. Give every coordinate an inertia comparable to the others, or start elsewhere."
        )

    def start(self, problem, t0, y0, t_bound, *, rtol=1e-9, atol=1e-12, max_step=np.inf, first_step=None):
        """SciPy's solver object from ``(t0, y0)`` towards ``t_bound``, stepped by the driver (events)."""
        import scipy.integrate

        extra = {} if first_step is None else {"first_step": first_step}
        try:
            solver = getattr(scipy.integrate, self.name)(problem.rhs, t0, y0, t_bound, rtol=rtol, atol=atol,
                                                         max_step=max_step, **extra)
        except ValueError as exc:
            error = self._failure(problem, exc)
            if error is None:
                raise
            raise error from None
        step = solver.step

        def checked_step():  # each step the driver takes fails as solve() does
            try:
                return step()
            except ValueError as exc:
                error = self._failure(problem, exc)
                if error is None:
                    raise
                raise error from None

        solver.step = checked_step
        return solver


# ---------------------------------------------------------------------------
# Explicit Runge–Kutta with a fixed step: a tableau
# ---------------------------------------------------------------------------


class ExplicitRungeKutta(FixedStepIntegrator):
    """An explicit Runge–Kutta method given by its Butcher tableau ``(A, b, c)``."""

    symplectic = implicit = stiff = False
    first_order = True
    options = {}

    def __init__(self, name: str, A, b, c, order: int, description: str):
        self.name, self.order, self.description = name, order, description
        self.A, self.b, self.c = [list(map(float, row)) for row in A], list(map(float, b)), list(map(float, c))

    def stability(self, z: complex) -> complex:
        """The stability function ``R(z)``: one step maps ``y' = λ y`` to ``R(hλ) y``."""
        s = len(self.b)
        A, b = np.array([row + [0.0] * (s - len(row)) for row in self.A]), np.array(self.b)
        return complex(1 + z * b @ np.linalg.solve(np.eye(s) - z * A, np.ones(s)))

    def stepper(self, problem, h):
        """One step of the tableau on the model's state."""
        A, b, c, rhs = self.A, self.b, self.c, problem.rhs
        s = len(b)

        def step(t, y):
            K = []
            for i in range(s):
                yi = y
                for j, a in enumerate(A[i][:i]):
                    if a:
                        yi = yi + (h * a) * K[j]
                K.append(rhs(t + c[i] * h, yi))
            out = y
            for i in range(s):
                if b[i]:
                    out = out + (h * b[i]) * K[i]
            return out

        return Stepper(step)


RK4 = ExplicitRungeKutta(
    "rk4",
    A=[[], [0.5], [0, 0.5], [0, 0, 1]],
    b=[1 / 6, 1 / 3, 1 / 3, 1 / 6],
    c=[0, 0.5, 0.5, 1],
    order=4,
    description="classical Runge–Kutta, explicit, order 4",
)


# ---------------------------------------------------------------------------
# Störmer–Verlet
# ---------------------------------------------------------------------------


class StormerVerlet(FixedStepIntegrator):
    """Störmer–Verlet (velocity form of leapfrog): explicit, order 2, symplectic on conservative models.

    For ``M q̈ = f(q, q̇, t)`` with a constant mass matrix ``M``:

        v½ = v + h/2 a,   q' = q + h v½,   v' = v½ + h/2 M⁻¹ f(q', v', t + h),   a' = M⁻¹ f(q', v', t + h)

    When the forces do not depend on the velocities (a separable Lagrangian
    ``½ q̇ᵀ M q̇ − V(q, t)``, with loads ``Q(q, t)``) the last kick is
    explicit: one evaluation per step, the classical method, symplectic.
    When they are affine in the velocities, ``f = f₀(q, t) − C(q, t) q̇``
    (dampers, resistors, gyroscopic couplings), the last kick is one linear
    solve, ``(M + h/2 C) v' = M v½ + h/2 f₀``: the damped Störmer–Verlet
    scheme (Newmark's explicit central-difference method, β = 0, γ = ½),
    still order 2 and explicit in the positions, which reduces to the
    classical method when ``C = 0``.  Linearly stable for ``h·ω_max < 2``.
    A configuration-dependent mass matrix, forces not affine in the
    velocities and loop constraints are refused, saying what to use.

    ``strict=True`` accepts separable models only (the loop compiled in C,
    ``verlet_c``, runs the classical method).
    """

    name = "verlet"
    order = 2
    symplectic = True
    implicit = stiff = first_order = False
    description = ("Störmer–Verlet (leapfrog), explicit, order 2; symplectic without dissipation; constant mass "
                   "matrix, forces affine in the velocities (damped and forced)")
    options = {}

    def __init__(self, *, strict: bool = False):
        self.strict = strict
        if strict:
            self.description = "Störmer–Verlet (leapfrog), explicit, symplectic, order 2; separable Lagrangians only"

    def check(self, problem):
        """Refuse a model whose mass matrix is not constant or whose forces are not affine in the velocities, saying why."""
        structure = problem.structure
        if structure.separable:
            return
        if self.strict:
            raise ModelError(
                f"verlet (Störmer–Verlet) needs a separable Lagrangian L = ½ q̇ᵀMq̇ − V(q, t) with a constant mass "
                f"matrix and forces that do not depend on velocities, but model {problem.name!r} is not separable: "
                f"{structure.why_not_separable()}. Use {_GENERAL}"
                + (", or 'verlet' (its damped form takes forces linear in the velocities)."
                   if not problem.constrained and structure.constant_mass and problem.velocity_affine else ".")
            )
        reasons = [structure.why[k] for k in ("constrained", "constant_mass") if k in structure.why]
        if not reasons and not problem.velocity_affine:
            reasons.append(f"its forces are not affine in the velocities ({structure.why['velocity_free']})")
        if not reasons:
            return
        use = ("'variational' with rule='trapezoidal' (Störmer–Verlet generalized to any Lagrangian: implicit, "
               "symplectic, order 2), 'gauss_legendre' (symplectic, order 4), or an adaptive method (DOP853, Radau)")
        if problem.constrained:
            use = "'gauss_legendre' (symplectic, handles loop constraints) or an adaptive method (DOP853, Radau)"
        raise ModelError(
            f"verlet (Störmer–Verlet) needs a constant mass matrix and forces affine in the velocities "
            f"(M q̈ = f₀(q, t) − C(q, t) q̇), but model {problem.name!r} does not have them: {'; '.join(reasons)}. "
            f"Use {use}."
        )

    def stepper(self, problem, h):
        """Kick–drift–kick on ``(q, q̇, q̈)``; the acceleration is carried over to the next step."""
        if problem.structure.separable:
            return self._classical(problem, h)
        return self._damped(problem, h)

    @staticmethod
    def _classical(problem, h):
        n, acc, half = problem.n, problem.acceleration, 0.5 * h

        def to_internal(t, y):
            return np.concatenate([y, acc(t, y[:n])])

        def to_state(t, z):
            return z[: 2 * n]

        def step(t, z):  # in place: z = (q, v, a)
            q, v, a = z[:n], z[n : 2 * n], z[2 * n :]
            v += half * a
            q += h * v
            a[:] = acc(t + h, q)
            v += half * a
            return z

        return Stepper(step, to_internal, to_state)

    @staticmethod
    def _damped(problem, h):
        n, half, affine = problem.n, 0.5 * h, problem.affine_forces
        M = problem.mass(0.0, np.zeros(n))

        def to_internal(t, y):
            f0, C = affine(t, y[:n])
            return np.concatenate([y, np.linalg.solve(M, f0 - C @ y[n:])])

        def to_state(t, z):
            return z[: 2 * n]

        def step(t, z):  # in place: z = (q, v, a)
            q, v, a = z[:n], z[n : 2 * n], z[2 * n :]
            v += half * a
            q += h * v
            f0, C = affine(t + h, q)
            try:
                v1 = np.linalg.solve(M + half * C, M @ v + half * f0)
            except np.linalg.LinAlgError:
                raise IntegrationError(f"verlet: M + h/2·C is singular at t={t + h:g} (step {h:g}); reduce step=.") from None
            a[:] = (v1 - v) / half
            v[:] = v1
            return z

        return Stepper(step, to_internal, to_state)


# ---------------------------------------------------------------------------
# Newton's method with a reused Jacobian, for the implicit methods
# ---------------------------------------------------------------------------


class _Newton:
    """Simplified Newton iterations for ``G(x) = 0``, reusing a factorized matrix from step to step.

    The matrix (``matrix(t, z)``: the Jacobian of ``G`` near the solution) is
    rebuilt when the iteration contracts slowly; with a fresh one the
    iteration must converge (correction ≤ ``tol`` relative to the state's
    size) within ``maxiter`` iterations, or :class:`IntegrationError` says so.
    """

    def __init__(self, method: str, h: float, tol: float, maxiter: int, matrix):
        if not (tol > 0) or not (isinstance(maxiter, int) and maxiter >= 1):
            raise ModelError(f"{method}: newton_tol must be positive and newton_maxiter a positive int, got {tol!r}, {maxiter!r}.")
        self.method, self.h, self.tol, self.maxiter, self.matrix = method, h, tol, maxiter, matrix
        self.lu = None

    def solve(self, G, x0: np.ndarray, t: float, z: np.ndarray) -> np.ndarray:
        from scipy.linalg import lu_factor, lu_solve

        scale = max(1.0, float(np.max(np.abs(z))))
        last, iterations = np.inf, 0
        for fresh in (self.lu is None, True):
            if fresh:
                with np.errstate(all="ignore"):
                    self.lu = lu_factor(self.matrix(t, z), check_finite=False)
            x, prev = x0.copy(), np.inf
            for it in range(self.maxiter):
                r = G(x)
                dx = lu_solve(self.lu, -r, check_finite=False)
                x = x + dx
                last, iterations = float(np.max(np.abs(dx))) / scale, it + 1
                if not math.isfinite(last):
                    break
                if last <= self.tol:
                    return x
                if it and last > (0.9 if fresh else 0.5) * prev:
                    break
                prev = last
            if fresh:
                break
        raise IntegrationError(
            f"{self.method}: the Newton iteration of the step from t={t:g} did not converge (last correction "
            f"{last:.2e} relative, after {iterations} iteration(s) with a fresh Jacobian; tolerance {self.tol:.1e}). "
            f"Reduce step= (now {self.h:.3g}), or loosen newton_tol= / raise newton_maxiter="
        )


def _fd_jacobian(fun, t: float, z: np.ndarray, f0: np.ndarray | None = None) -> np.ndarray:
    f0 = fun(t, z) if f0 is None else f0
    J = np.empty((f0.size, z.size))
    for j in range(z.size):
        d = 1.5e-8 * max(1.0, abs(z[j]))
        zj = z.copy()
        zj[j] += d
        J[:, j] = (fun(t, zj) - f0) / d
    return J


_NEWTON_OPTIONS = {
    "newton_tol": "Newton iterations stop when the correction is below this, relative to max(1, |state|) (default 1e-12)",
    "newton_maxiter": "most Newton iterations per step before failing (default 50)",
}


# ---------------------------------------------------------------------------
# Gauss–Legendre collocation (implicit midpoint is its one-stage case)
# ---------------------------------------------------------------------------


def gauss_legendre_tableau(stages: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Butcher tableau ``(A, b, c)`` of the ``stages``-stage Gauss–Legendre method (order ``2·stages``).

    >>> A, b, c = gauss_legendre_tableau(1)
    >>> A.tolist(), b.tolist(), c.tolist()
    ([[0.5]], [1.0], [0.5])
    """
    if stages == 1:
        return np.array([[0.5]]), np.array([1.0]), np.array([0.5])
    if stages == 2:
        r = math.sqrt(3) / 6
        return np.array([[0.25, 0.25 - r], [0.25 + r, 0.25]]), np.array([0.5, 0.5]), np.array([0.5 - r, 0.5 + r])
    if stages == 3:
        r = math.sqrt(15)
        A = np.array([
            [5 / 36, 2 / 9 - r / 15, 5 / 36 - r / 30],
            [5 / 36 + r / 24, 2 / 9, 5 / 36 - r / 24],
            [5 / 36 + r / 30, 2 / 9 + r / 15, 5 / 36],
        ])
        return A, np.array([5 / 18, 4 / 9, 5 / 18]), np.array([0.5 - r / 10, 0.5, 0.5 + r / 10])
    raise ModelError(f"gauss_legendre: stages must be 1, 2 or 3, got {stages!r}.")


class GaussLegendre(FixedStepIntegrator):
    """Gauss–Legendre collocation: implicit, symplectic, A-stable, order ``2·stages``.

    The stage increments ``Z_i = h Σ_j a_ij F(t + c_j h, z + Z_j)`` are found
    by simplified Newton iterations; ``z' = z + Σ_i d_i Z_i`` with
    ``d = b A⁻¹``.  On ``(q, p)`` (``problem.canonical_rhs``) when the
    problem has canonical coordinates, so the map is symplectic for any
    mass matrix; on ``(q, q̇_inertial)`` otherwise (first-order coordinates
    or constraints).  Conserves quadratic invariants exactly (the energy of
    a linear oscillator, angular momentum).
    """

    implicit = stiff = symplectic = first_order = True

    def __init__(self, name: str, stages: int, description: str, *, fixed: bool = False):
        self.name, self.stages, self.description = name, stages, description
        self.order = 2 * stages
        self.options = dict(_NEWTON_OPTIONS) if fixed else {"stages": "1, 2 or 3 (order 2, 4, 6)", **_NEWTON_OPTIONS}

    def stepper(self, problem, h, *, stages=None, newton_tol=1e-12, newton_maxiter=50):
        """Collocation step with ``stages`` stages."""
        s = self.stages if stages is None else stages
        A, b, c = gauss_legendre_tableau(s)
        d_coef = np.linalg.solve(A.T, b)  # d = b A⁻¹
        if problem.canonical:
            F, to_internal, to_state = problem.canonical_rhs, problem.to_canonical, problem.from_canonical
        else:
            F, to_internal, to_state = problem.rhs, (lambda t, y: y), (lambda t, y: y)
        dim = problem.dim
        hA = h * A

        def matrix(t, z):
            J = _fd_jacobian(F, t, z)
            return np.eye(s * dim) - np.kron(hA, J)

        newton = _Newton(self.name, h, newton_tol, newton_maxiter, matrix)
        last = {"Z": np.zeros(s * dim)}  # the previous step's stages start the iteration (they change by O(h) a step)

        def step(t, z):
            times = t + c * h

            def G(x):
                Z = x.reshape(s, dim)
                FZ = np.array([F(times[i], z + Z[i]) for i in range(s)])
                return (Z - hA @ FZ).ravel()

            Zflat = newton.solve(G, last["Z"], t, z)
            last["Z"] = Zflat
            return z + d_coef @ Zflat.reshape(s, dim)

        return Stepper(step, to_internal, to_state)


# ---------------------------------------------------------------------------
# The variational integrator
# ---------------------------------------------------------------------------


class Variational(FixedStepIntegrator):
    """A variational integrator from the discrete Lagrangian ``L_d(q_k, q_{k+1}, h) ≈ ∫ L dt``.

    ``rule="midpoint"``: ``L_d = h L((q_k + q_{k+1})/2, (q_{k+1} − q_k)/h, t_k + h/2)``;
    ``rule="trapezoidal"``: ``L_d = h/2 [L(q_k, w, t_k) + L(q_{k+1}, w, t_{k+1})]``,
    ``w = (q_{k+1} − q_k)/h``.  In position–momentum form, with the
    discrete forces ``F±`` of the Lagrange–d'Alembert principle (the
    non-conservative forces ``Q − ∂D/∂q̇`` by the same quadrature):

        p_k = −D₁L_d(q_k, q_{k+1}) − F⁻(q_k, q_{k+1})      (solved for q_{k+1} by Newton)
        p_{k+1} = D₂L_d(q_k, q_{k+1}) + F⁺(q_k, q_{k+1})

    Symplectic (and momentum-preserving for symmetries) when the model is
    conservative; order 2.  The midpoint rule is the implicit midpoint rule
    on ``(q, p)`` when ``M`` is constant; the trapezoidal rule is
    Störmer–Verlet for a separable Lagrangian.  Every coordinate needs
    inertia; constrained models are refused.
    """

    name = "variational"
    order = 2
    symplectic = implicit = True
    stiff = first_order = False
    description = "variational integrator (discrete Lagrangian, midpoint or trapezoidal rule), symplectic, order 2"
    options = {"rule": "'midpoint' (default) or 'trapezoidal' quadrature of the discrete Lagrangian", **_NEWTON_OPTIONS}

    def check(self, problem):
        """Refuse constrained models and Lagrangians not quadratic in the velocities."""
        if problem.constrained:
            raise ModelError(
                f"variational cannot integrate model {problem.name!r}: it has loop-closure constraints (Lagrange "
                f"multipliers), which this integrator does not discretize. Use an adaptive method (DOP853, Radau)."
            )
        if not problem.structure.quadratic:
            raise ModelError(f"variational needs a Lagrangian quadratic in the velocities; model {problem.name!r}'s is not.")

    def stepper(self, problem, h, *, rule="midpoint", newton_tol=1e-12, newton_maxiter=50):
        """One step of the discrete Euler–Lagrange (Lagrange–d'Alembert) equations."""
        if rule not in ("midpoint", "trapezoidal"):
            raise ModelError(f"variational: rule must be 'midpoint' or 'trapezoidal', got {rule!r}.")
        n, half, pieces = problem.n, 0.5 * h, problem.pieces

        def residual(t, q, p, q1):
            w = (q1 - q) / h
            if rule == "midpoint":
                Lq, Lv, _, Qnc = pieces(t + half, 0.5 * (q + q1), w)
                return Lv - half * (Lq + Qnc) - p
            Lq0, Lv0, _, Q0 = pieces(t, q, w)
            _, Lv1, _, _ = pieces(t + h, q1, w)
            return 0.5 * (Lv0 + Lv1) - half * (Lq0 + Q0) - p

        state = {}

        def matrix(t, z):
            q, p, q1 = z[:n], z[n:], state["guess"]
            return _fd_jacobian(lambda _, x: residual(t, q, p, x), t, q1)

        newton = _Newton(self.name, h, newton_tol, newton_maxiter, matrix)

        def step(t, z):
            q, p = z[:n], z[n:]
            guess = q + h * problem.velocity(t, q, p)
            state["guess"] = guess
            q1 = newton.solve(lambda x: residual(t, q, p, x), guess, t, z)
            w = (q1 - q) / h
            if rule == "midpoint":
                Lq, Lv, _, Qnc = pieces(t + half, 0.5 * (q + q1), w)
                p1 = Lv + half * (Lq + Qnc)
            else:
                _, Lv0, _, _ = pieces(t, q, w)
                Lq1, Lv1, _, Q1 = pieces(t + h, q1, w)
                p1 = 0.5 * (Lv0 + Lv1) + half * (Lq1 + Q1)
            return np.concatenate((q1, p1))

        return Stepper(step, problem.to_canonical, problem.from_canonical)


_RK45 = ScipyMethod("RK45", 5, "scipy: explicit Runge–Kutta 5(4) (Dormand–Prince)")
_VERLET = StormerVerlet()
_VERLET_SEPARABLE = StormerVerlet(strict=True)  # what the loop in C runs

INTEGRATORS: tuple[Integrator, ...] = (
    ScipyMethod("RK23", 3, "scipy: explicit Runge–Kutta 3(2) (Bogacki–Shampine)"),
    _RK45,
    ScipyMethod("DOP853", 8, "scipy: explicit Runge–Kutta of order 8 (Dormand–Prince)"),
    ScipyMethod("Radau", 5, "scipy: implicit Runge–Kutta Radau IIA of order 5, for stiff models", implicit=True, stiff=True),
    ScipyMethod("BDF", 5, "scipy: implicit backward differentiation formulas of order 1–5, for stiff models", implicit=True, stiff=True),
    ScipyMethod("LSODA", 12, "scipy: Adams/BDF switching on detected stiffness (ODEPACK)", implicit=True, stiff=True),
    RK4,
    _VERLET,
    GaussLegendre("implicit_midpoint", 1, "implicit midpoint rule (1-stage Gauss–Legendre), symplectic, A-stable, order 2", fixed=True),
    GaussLegendre("gauss_legendre", 2, "Gauss–Legendre collocation (stages=1, 2, 3; default 2), symplectic, A-stable, order 2·stages"),
    Variational(),
    # the stepping loop in C (lagrangian.codegen); the Python sibling runs when there is no C compiler
    CompiledDormandPrince(_RK45),
    CompiledFixedStep("rk4", RK4),
    CompiledFixedStep("verlet", _VERLET_SEPARABLE),
)


@hookimpl
def register_integrators(register):
    for integrator in INTEGRATORS:
        register(integrator)


# ---------------------------------------------------------------------------
# Benchmark problems
# ---------------------------------------------------------------------------


class InverseSquare(Component):
    """Inverse-square attraction between two nodes: V = −k / |r_b − r_a| (a fixed sun's gravity, Coulomb).

    Registered only in the registry of the ``kepler`` benchmark.
    """

    kind = "inverse_square"
    domain = "mechanical"
    parameters = {"k": Parameter("strength (G m₁ m₂)", unit="N m²")}

    def contribute(self, ctx) -> Contribution:
        d = ctx.view.position(self.nodes[1]) - ctx.view.position(self.nodes[0])
        return Contribution(V=-self.k / sp.sqrt(dot(d, d)))

    @classmethod
    def example(cls) -> Example:
        return Example(("ground", "p"), {"k": 1}, context=[("mass", "m", "p", {"m": 1})], options={"dim": 2})


@functools.cache
def _kepler_registry():
    import lagrangian as lg

    plugin = types.ModuleType("lagrangian_kepler_benchmark")
    plugin.register_component_types = hookimpl(lambda register: register(InverseSquare))
    return lg.Registry(plugins={"kepler_benchmark": plugin})


def _oscillator():
    import lagrangian as lg

    m = lg.Model("harmonic oscillator")
    m.add("mass", "m", "p", m=1)
    m.add("spring", "k", ("ground", "p"), k=1)
    return m


def _kepler():
    import lagrangian as lg

    m = lg.Model("Kepler orbit", dim=2, registry=_kepler_registry())
    m.add("mass", "m", "planet", m=1)
    m.add("inverse_square", "sun", ("ground", "planet"), k=1)
    return m


KEPLER_E = 0.5


def kepler_orbit(times: np.ndarray, e: float = KEPLER_E) -> dict[str, np.ndarray]:
    """The exact orbit ``x, y`` for ``μ = a = 1`` from pericenter ``(1 − e, 0)`` at ``t = 0`` (Kepler's equation by Newton).

    >>> xy = kepler_orbit(np.array([0.0, 2 * np.pi]))
    >>> np.allclose(xy["x_planet"], 0.5) and np.allclose(xy["y_planet"], 0.0)
    True
    """
    M = np.asarray(times, dtype=float)  # mean anomaly, n = 1
    E = M + e * np.sin(M)
    for _ in range(50):
        dE = (E - e * np.sin(E) - M) / (1 - e * np.cos(E))
        E = E - dE
        if np.max(np.abs(dE)) < 1e-15:
            break
    return {"x_planet": np.cos(E) - e, "y_planet": math.sqrt(1 - e * e) * np.sin(E)}


def _duffing():
    import lagrangian as lg

    m = lg.Model("Duffing oscillator")
    m.add("mass", "m", "p", m=1)
    m.add("cubic_spring", "s", ("ground", "p"), k=1, k3=1)
    return m


def _rlc_ladder():
    """Three RLC sections driven by a sine; the middle inductance is tiny, so one mode decays ~10⁴ times faster."""
    import lagrangian as lg

    m = lg.Model("stiff RLC ladder", formulation="charge")
    m.add("voltage_source", "V1", ("n1", "0"), E=sp.sin(2 * lg.t))
    m.add("resistor", "R1", ("n1", "n2"), R=1.0)
    m.add("inductor", "L1", ("n2", "n3"), L=1.0)
    m.add("capacitor", "C1", ("n3", "0"), C=1.0)
    m.add("resistor", "R2", ("n3", "n4"), R=1.0)
    m.add("inductor", "L2", ("n4", "n5"), L=1e-4)
    m.add("capacitor", "C2", ("n5", "0"), C=1.0)
    m.add("resistor", "R3", ("n5", "n6"), R=0.5)
    m.add("inductor", "L3", ("n6", "n7"), L=2.0)
    m.add("capacitor", "C3", ("n7", "0"), C=0.5)
    return m


TWO_PI = 2 * math.pi
_FIXED = ("rk4", "verlet", "implicit_midpoint", "gauss_legendre", "variational")
_METHODS = ("RK45", "DOP853", "Radau", "BDF", "LSODA", *_FIXED)

BENCHMARKS = (
    Benchmark(
        "oscillator",
        "harmonic oscillator m = k = 1 over 10 periods, x(0) = 1; exact x = cos t",
        _oscillator, t_end=10 * TWO_PI, initial={"x_p": 1.0}, velocity={"x_p": 0.0}, points=81,
        exact=lambda times: {"x_p": np.cos(times)},
        steps=tuple(TWO_PI / k for k in (8, 16, 32, 64, 128, 256, 512)), methods=_METHODS,
    ),
    Benchmark(
        "kepler",
        f"Kepler orbit, e = {KEPLER_E}, μ = a = 1, 5 revolutions from pericenter; exact from Kepler's equation",
        _kepler, t_end=5 * TWO_PI, initial={"x_planet": 1 - KEPLER_E, "y_planet": 0.0},
        velocity={"x_planet": 0.0, "y_planet": math.sqrt((1 + KEPLER_E) / (1 - KEPLER_E))}, points=321,
        exact=kepler_orbit,
        steps=tuple(TWO_PI / k for k in (64, 128, 256, 512, 1024, 2048)), methods=_METHODS,
    ),
    Benchmark(
        "duffing",
        "Duffing oscillator x'' = −x − x³ from x = 1 over 20 time units; reference DOP853 at rtol 1e-13",
        _duffing, t_end=20.0, initial={"x_p": 1.0}, velocity={"x_p": 0.0}, points=81,
        steps=tuple(1 / k for k in (4, 8, 16, 32, 64, 128, 256)), requires=("cubic_spring",), methods=_METHODS,
    ),
    Benchmark(
        "rlc_ladder",
        "stiff RLC ladder (three sections, one with L = 1e-4: a decay rate 1e4 beside modes of order 1), sine "
        "drive, 10 time units; reference: the exact solution",
        _rlc_ladder, t_end=10.0, initial={}, points=51,
        reference={"method": "exact"},
        tolerances=(1e-3, 1e-5, 1e-7, 1e-9),
        steps=tuple(10 / k for k in (50, 100, 200, 400, 1000, 2000, 4000, 40000)),
        methods=("RK45", "DOP853", "Radau", "BDF", "LSODA", "rk4", "implicit_midpoint", "gauss_legendre", "variational"),
    ),
    Benchmark(
        "energy",
        "long-time energy: harmonic oscillator over 1000 periods, error = largest relative energy error; fixed-step "
        "methods advance by powers of their one-step map (fast_linear)",
        _oscillator, t_end=1000 * TWO_PI, initial={"x_p": 1.0}, velocity={"x_p": 0.0}, points=2001,
        measure="energy", tolerances=(1e-4, 1e-6, 1e-8),
        steps=tuple(TWO_PI / k for k in (8, 16, 32, 64, 128)),
        options={name: {"fast_linear": True} for name in _FIXED},
        methods=("RK45", "DOP853", *_FIXED),
    ),
)


@hookimpl
def register_benchmarks(register):
    for benchmark in BENCHMARKS:
        register(benchmark)
