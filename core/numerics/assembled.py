"""Runs of large models assembled in numbers: nothing derived symbolically, each kind of potential derived once.

A model of many lumped components (a chain of 10⁴ masses, springs and
dampers; a Fermi–Pasta–Ulam–Tsingou chain) whose components all say their
energies in numbers (:mod:`lagrangian.base.linear`: quadratic forms, and
nonlinear energies as a :class:`~lagrangian.Potential` of their variables)
is integrated from its numeric assembly
(:func:`lagrangian.derivation.numeric.assemble_local`):

    M q̈ = B s(t) − C q̇ − K q − Σ_c R_cᵀ ∇V_c(R_c q; p_c)

where ``R_c`` maps the coordinates to component ``c``'s variables.  The
components whose potentials have the same expression (every cubic spring of
a chain) share one derivation: its gradient is taken once by SymPy and
evaluated for all of them at once, on arrays of their variables and
parameters.  The matrices are sparse and ``M`` is factorized once, so the
derivation costs nothing per component and an evaluation is linear in their
number.  SciPy's ``DOP853`` steps the run (the method ``DOP853`` asked for,
as the symbolic path steps it in C), and ``Result.notes`` says so.

This is what ``Model.simulate`` runs with its default method, no ``params``,
events or sensitivities, and compiled code not asked for, on a model of at
least :data:`ASSEMBLED_MIN` coordinates that every component describes in
numbers, all with inertia (:func:`stamps_for_run`); anything else takes the
symbolic path.  Measured by ``benchmarks/assembled_choice.py`` (a cubic chain
and a linear one, 1 s runs, each path in a fresh process).
"""

from __future__ import annotations

import functools
import logging
from collections.abc import Mapping
from typing import Any

import numpy as np

from ..base.arguments import RunOptions, check_grid
from ..base.component import t as _t
from ..base.linear import Potential
from ..base.switching import switching_times as _switching_times
from ..derivation.numeric import NumericAssembly, assemble_local, local_stamps
from ..derivation.stamps import NotStampable, Stamps
from .integrate import integrate
from .problem import Problem, Structure
from .result import Result
from .simulation import initial_state
from .tape import TapeError, record
from ..base import deferred as _deferred

sp = _deferred.module("sympy", globals())

_log = logging.getLogger(__name__)

__all__ = ["ASSEMBLED_MIN", "AssembledModel", "AssembledProblem", "simulate_assembled", "stamps_for_run", "wanted"]

#: Models with at least this many coordinates run from their numeric assembly (when it applies): chosen by
#: ``benchmarks/assembled_choice.py``, from where the assembled path costs no more CPU than the symbolic one for a
#: first 1 s run and for a 20 s run after it, on a cubic chain and a linear one.  At 400 masses the cubic chain
#: took 0.44 s + 1.37 s against 1.34 s + 0.97 s (the symbolic model steps faster in C once derived); at 200,
#: 0.94 s + 1.32 s against 1.39 s + 0.58 s; at 2,000, 0.65 s + 2.3 s against 6.3 s + 4.9 s.
ASSEMBLED_MIN = 400
#: The method these runs serve: the default one.
METHOD = "DOP853"


def wanted(method: Any, params: Mapping | None, events: Any, sensitivities: Any, compiled: Any,
           step: Any = None) -> bool:
    """Whether a run with these arguments may take the assembled path: the default method, no ``params`` (values
    given at run time go through the symbolic model), no events or sensitivities, no ``step`` (which the symbolic
    path refuses for an adaptive method, saying why), and neither compiled code nor the tape asked for
    (``compiled=True``, ``"native"``, ``"tape"``: the symbolic model's)."""
    return (isinstance(method, str) and method == METHOD and not params and not events and not sensitivities
            and step is None and compiled is not True and compiled not in ("native", "tape"))


def stamps_for_run(model) -> Stamps | None:
    """The model's :func:`~lagrangian.derivation.numeric.local_stamps` when the assembled path applies to it (at
    least :data:`ASSEMBLED_MIN` coordinates, each with inertia), else ``None`` (the reason logged)."""
    try:
        st = local_stamps(model)
    except NotStampable as exc:
        _log.debug("%s: not run from its numeric assembly: %s", model.name, exc)
        return None
    if st.n < ASSEMBLED_MIN or st.first_order:
        return None
    return st


class _Kernel:
    """One potential expression and every component that gives it: the rows of their variables (``R_k``, one
    sparse matrix per variable, a row per component) and their parameters (``P``, a row per parameter, a column per
    component).  The expression and its gradient are recorded once on tapes (:func:`~lagrangian.numerics.tape.record`:
    integer powers as products; NumPy's ``power`` of a negative base cost 70 µs for 1,000 springs, the tape's
    products 19 µs) and run on all the components at once (:meth:`~lagrangian.numerics.tape.Program.evaluate_many`)."""

    def __init__(self, energy: sp.Expr, rows: list, P: np.ndarray, names: list[str]):
        self.energy, self.rows, self.P, self.names = energy, rows, P, names
        x, p = Potential.placeholders(len(rows), P.shape[0])
        try:  # (the expression holds placeholders only: never a user's text)
            self._grad = record([energy.diff(xk) for xk in x], [*x, *p])
            self._V = record([energy], [*x, *p])
        except TapeError as exc:
            raise NotStampable(f"the potential of {names[0]!r} (and {len(names) - 1} more): {exc}") from None
        self._T = [R.T.tocsr() for R in rows]

    def force(self, q: np.ndarray) -> np.ndarray:
        """``Σ_c R_cᵀ ∇V_c`` at coordinates ``q``."""
        grads = self._grad.evaluate_many(np.vstack([*(R @ q for R in self.rows), self.P]))
        out = self._T[0] @ grads[0]
        for RT, g in zip(self._T[1:], grads[1:]):
            out += RT @ g
        return out

    def energies(self, Q: np.ndarray) -> np.ndarray:
        """``Σ_c V_c`` at each column of ``Q``."""
        X = [R @ Q for R in self.rows]
        m, N = X[0].shape
        inputs = np.vstack([*(x.reshape(1, m * N) for x in X), np.repeat(self.P, N, axis=1)])
        return self._V.evaluate_many(inputs)[0].reshape(m, N).sum(axis=0)


def kernels(asm: NumericAssembly) -> list[_Kernel]:
    """The potentials of ``asm`` grouped by expression: one :class:`_Kernel` per kind and structure."""
    import scipy.sparse as sps  # (imported by what uses it, as the stamps do)

    n = len(asm.names)
    groups: dict[tuple[sp.Expr, int, int], list[str]] = {}
    for name, pot in asm.potentials.items():
        groups.setdefault((pot.energy, len(asm.rows[name]), len(pot.values)), []).append(name)
    out = []
    for (energy, nvars, npars), names in groups.items():
        rows = []
        for k in range(nvars):
            r, c, v = [], [], []
            for i, name in enumerate(names):
                for j, cj in asm.rows[name][k].items():
                    r.append(i)
                    c.append(j)
                    v.append(cj)
            rows.append(sps.csr_matrix((v, (r, c)), shape=(len(names), n)))
        P = np.array([asm.potentials[name].values for name in names], dtype=float).reshape(len(names), npars).T.copy()
        out.append(_Kernel(energy, rows, P, names))
    return out


class AssembledModel:
    """What :class:`~lagrangian.numerics.problem.Problem` reads of a model (as of a
    :class:`~lagrangian.simulation.NumericModel`), from its numeric assembly: ``rhs``, the energies, the velocities,
    the inputs' switching times; the symbolic model only for ``Result.quantity`` (derived on that first request)."""

    python_only = True  # (no compiled code: DOP853 takes SciPy's steps)
    _fast = None

    def __init__(self, model, st: Stamps):
        asm = assemble_local(model)
        self.model, self.st, self.eq = model, st, st
        self.n = st.n
        self.nI = len(st.inertial)
        self.values: dict = {}
        self.signals: dict = {}
        self.kernels = kernels(asm)
        M = st.M.tocsr()
        diagonal = M.nnz == int(np.count_nonzero(M.diagonal()))
        if diagonal:
            self._solve = functools.partial(np.multiply, 1.0 / M.diagonal())
        else:
            import scipy.sparse.linalg as spla

            self._solve = spla.splu(M.tocsc()).solve
        self.diagonal = diagonal
        self.C, self.K, self.B = st.C.tocsr(), st.K.tocsr(), st.B.tocsr()
        self._inputs = [sp.lambdify(_t, shape, modules="numpy") if shape.free_symbols else float(shape)
                        for shape in map(sp.sympify, st.inputs)]

    def __getstate__(self) -> dict[str, Any]:
        """The model and its stamps: the rest (a factorization, the inputs' functions) is built again."""
        return {"model": self.model, "st": self.st}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__init__(state["model"], state["st"])

    def input_values(self, time: float) -> np.ndarray:
        return np.array([f(time) if callable(f) else f for f in self._inputs], dtype=float)

    def rhs(self, time: float, y: np.ndarray) -> np.ndarray:
        """``(q̇, q̈)`` at ``(time, y)``, ``y = (q, q̇)``."""
        n = self.n
        q, v = y[:n], y[n:]
        r = -(self.K @ q) - (self.C @ v)
        if self._inputs:
            r += self.B @ self.input_values(time)
        for kernel in self.kernels:
            r -= kernel.force(q)
        out = np.empty(2 * n)
        out[:n] = v
        out[n:] = self._solve(r)
        return out

    def velocities_many(self, times: np.ndarray, Y: np.ndarray) -> np.ndarray:
        return np.array(Y[self.n:], dtype=float)

    def energies(self, time: np.ndarray, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, ...]:
        times = np.broadcast_to(np.asarray(time, dtype=float), np.shape(q)[1:])
        Z = np.vstack([q, v])
        T, V, D = (self.st.energies[part].values(times, Z) for part in "TVD")
        for kernel in self.kernels:
            V = V + kernel.energies(q)
        return T, V, D

    def switching_times(self, lo: float, hi: float) -> list[float]:
        return _switching_times([e for e in map(sp.sympify, self.st.inputs) if e.free_symbols == {_t}], lo, hi)

    def evaluate(self, expr: Any, res: Any) -> np.ndarray:
        """``Result.quantity``: the symbolic model's numeric functions, derived on this first request."""
        return self.model.numeric().evaluate(expr, res)

    def note(self) -> str:
        kinds = len(self.kernels)
        shared = sum(len(k.names) for k in self.kernels)
        return (f"the model assembled in numbers, nothing derived symbolically (the default from {ASSEMBLED_MIN} "
                f"coordinates on, for components that say their energies in numbers): {self.n} coordinates, sparse "
                f"matrices ({'diagonal' if self.diagonal else 'factorized'} mass matrix)"
                + (f", {shared} nonlinear potentials derived once for each of their {kinds} expression(s)"
                   if kinds else "") + "; SciPy's DOP853 steps")


class AssembledProblem(Problem):
    """The :class:`~lagrangian.numerics.problem.Problem` of an :class:`AssembledModel`: its structure read off the
    assembly (no symbolic work), the Jacobi integral ``T + V`` (no constraint moves, no coupling stores energy)."""

    def __init__(self, numeric: AssembledModel, name: str = "model"):
        super().__init__(numeric, name)  # type: ignore[arg-type]

    @functools.cached_property
    def _conservative(self) -> tuple[bool, str]:
        st, reasons = self.numeric.st, []
        if st.energies["D"].H.nnz:
            reasons.append("it dissipates energy (Rayleigh function D ≠ 0)")
        if st.B.nnz:
            reasons.append("applied forces or sources do work on it (generalized forces Q ≠ 0)")
        return not reasons, "; ".join(reasons)

    @functools.cached_property
    def structure(self) -> Structure:
        st, conservative = self.numeric.st, self._conservative
        why = {"conservative": conservative[1]} if not conservative[0] else {}
        timed = any(sp.sympify(e).free_symbols for e in st.inputs)
        linear = not self.numeric.kernels and not timed
        if self.numeric.C.nnz:
            why["velocity_free"] = "the forces depend on the velocities (dampers, gyroscopic couplings)"
        return Structure(first_order=(), constrained=False, constant_mass=True, velocity_free=not self.numeric.C.nnz,
                         conservative=conservative[0], autonomous=not timed, linear=linear, quadratic=True, why=why)

    def jacobi(self, t: np.ndarray, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        T, V, _ = self.numeric.energies(t, q, v)
        return T + V


def simulate_assembled(model, run: RunOptions, st: Stamps, integrators: Mapping[str, Any]) -> Result:
    """``Model.simulate`` on the assembled path (see the module documentation): a :class:`~lagrangian.Result`.
    The model's :class:`AssembledProblem` is kept with it until it changes."""
    problem = model._get(("assembled", id(st)), lambda: AssembledProblem(AssembledModel(model, st), model.name))
    y0, defaulted = initial_state(st, run.initial, run.velocity)
    grid = check_grid(run.span, run.points, run.t_eval, len(y0))
    options = {"rtol": 1e-9 if run.rtol is None else run.rtol, "atol": 1e-12 if run.atol is None else run.atol,
               "max_step": np.inf if run.max_step is None else run.max_step, **run.options}
    return integrate(problem, integrators[METHOD], run.span, y0, t_eval=grid, options=options, model=model.name,
                     defaulted=defaulted, integrators=integrators, notes=[*run.notes, problem.numeric.note()],
                     energy_tol=run.energy_tol, progress=run.progress, max_evaluations=run.max_evaluations)
