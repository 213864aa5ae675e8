"""The integrators plugin's explicit fixed-step methods: :class:`ExplicitRungeKutta` from a Butcher tableau
(:data:`RK4`, the classical ``rk4``) and :class:`StormerVerlet` (``verlet``, in its classical and damped forms)."""

from __future__ import annotations

import numpy as np

from lagrangian import IntegrationError, ModelError
from lagrangian.integrate import FixedStepIntegrator, Stepper


_GENERAL = "'variational' or 'gauss_legendre' (symplectic, any Lagrangian, dissipation and forces included), or an adaptive method (DOP853, Radau)"


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
