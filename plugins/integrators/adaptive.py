"""The integrators plugin's adaptive methods: :class:`ScipyMethod`, one method of :func:`scipy.integrate.solve_ivp`
(``RK23``, ``RK45``, ``DOP853``, ``Radau``, ``BDF``, ``LSODA``), error-controlled by ``rtol`` and ``atol``."""

from __future__ import annotations

import contextlib

import numpy as np

from lagrangian import IntegrationError
from lagrangian.integrate import Integrator, Solution


class ScipyMethod(Integrator):
    """One method of :func:`scipy.integrate.solve_ivp`, error-controlled by ``rtol`` and ``atol``."""

    kind = "adaptive"
    options = {"first_step": "initial step size (default: chosen by scipy)"}

    def __init__(self, name: str, order: int, description: str, *, implicit: bool = False, stiff: bool = False,
                 method: str | None = None):
        self.name, self.order, self.description = name, order, description
        self.implicit, self.stiff = implicit, stiff
        self.method = method or name  # SciPy's name of it

    def solve(self, problem, t_span, y0, t_eval, *, rtol=1e-9, atol=1e-12, max_step=np.inf, first_step=None):
        """Integrate with :func:`scipy.integrate.solve_ivp` (``method=self.name``)."""
        from scipy.integrate import solve_ivp

        extra = {} if first_step is None else {"first_step": first_step}
        with self._failures(problem):
            sol = solve_ivp(problem.rhs, t_span, y0, method=self.method, t_eval=t_eval, rtol=rtol, atol=atol,
                            max_step=max_step, **extra)
        return Solution(sol.t, sol.y, sol.nfev, sol.status, sol.message)

    @contextlib.contextmanager
    def _failures(self, problem):
        """A ValueError out of SciPy's solver for a Jacobian (of an implicit method) or a state that is not finite
        becomes an :class:`IntegrationError`, as compiled code reports it; any other stands (SciPy's own error)."""
        try:
            yield
        except ValueError as exc:
            text = str(exc).lower()
            if "finite" not in text and not ("inf" in text and "nan" in text):  # "array must not contain infs or NaNs"
                raise
            model = getattr(problem, "name", "") or "the model"
            raise IntegrationError(
                f"{self.name} failed on model {model!r}: its Jacobian or state is not finite ({exc}) — a mass matrix "
                f"nearly singular (an inertia, mass or inductance many orders of magnitude below the others), or "
                f"equations that overflow. Give every coordinate an inertia comparable to the others, or start "
                f"elsewhere."
            ) from None

    def start(self, problem, t0, y0, t_bound, *, rtol=1e-9, atol=1e-12, max_step=np.inf, first_step=None):
        """SciPy's solver object from ``(t0, y0)`` towards ``t_bound``, stepped by the driver (events)."""
        import scipy.integrate

        extra = {} if first_step is None else {"first_step": first_step}
        with self._failures(problem):
            solver = getattr(scipy.integrate, self.method)(problem.rhs, t0, y0, t_bound, rtol=rtol, atol=atol,
                                                         max_step=max_step, **extra)
        step = solver.step

        def checked_step():  # each step the driver takes fails as solve() does
            with self._failures(problem):
                return step()

        solver.step = checked_step
        return solver
