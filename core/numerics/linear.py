"""Exact solution of linear time-invariant models by the matrix exponential.

Many models are linear networks with constant parameters: masses, linear
springs and dampers, inductors, capacitors, resistors, driven by sources that
are known functions of time.  Their solve ``A u = b`` (see
:mod:`lagrangian.equations`) has a constant ``A`` and a ``b`` affine in the
state ``y = (q, q̇_inertial)``, so the state obeys

    ẏ = F y + G s(t)

with constant ``F`` and ``G`` and the inputs ``s(t)`` — the part of ``b``
that does not depend on the state.  :func:`state_space` detects this form (or
says which term of which equation breaks it) and :func:`simulate_exact`
solves it exactly on the output grid:

- an input that is a combination of constants, powers of ``t``, ``exp(α t)``,
  ``sin``/``cos(ω t + φ)`` and their products is the output ``s = C w`` of a
  linear autonomous *exosystem* ``ẇ = S w`` (a rotation block per frequency,
  a nilpotent chain per power of ``t``); the augmented matrix
  ``Z = [[F, G C], [0, S]]`` gives the exact step ``(y, w) ↦ e^{Z h} (y, w)``
  with the input's contribution included (Van Loan);
- a piecewise input (``Piecewise``, ``Heaviside``, ``sign``, ``Abs``,
  ``Min``/``Max``, ``floor``, ``Mod``: pulses, steps, square waves) is split
  at its switching times, found symbolically, and solved piece by piece;
- on a uniform grid one ``e^{Z h}`` per piece serves every step.

Anything else — a nonlinear or time-varying term, an input given as a
Python callable — is refused with a :class:`~lagrangian.errors.ModelError`
that names the equation and the term, and points to ``Model.simulate``.

>>> import numpy as np
>>> import lagrangian as lg
>>> from lagrangian.linear import simulate_exact, state_space
>>> m = lg.Model("oscillator")
>>> _ = m.add("mass", "m1", "p", m=1)
>>> _ = m.add("spring", "k1", ("ground", "p"), k=4)
>>> _ = m.add("force", "F", "p", F=3 * lg.t)
>>> ss = state_space(m)
>>> ss.states
['x_p', "x_p'"]
>>> ss.F
array([[ 0.,  1.],
       [-4.,  0.]])
>>> ss.g.T
Matrix([[0, 3.0*t]])
>>> res = simulate_exact(m, 2.0, initial={"x_p": 1}, velocity={"x_p": 0}, points=5)
>>> exact = np.cos(2 * res.t) + 3 * (res.t / 4 - np.sin(2 * res.t) / 8)   # x'' + 4x = 3t
>>> bool(np.max(np.abs(res["x_p"] - exact)) < 1e-14)
True
"""

from __future__ import annotations

import contextlib
import logging
import sys
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..base.arguments import check_grid, check_mapping, check_span
from ..base.component import t
from ..errors import IntegrationError, ModelError, SingularMassMatrixError
from ..base.identity import depends_on, is_zero
from .exosystem import EXPAND_SECONDS, _Exosystem, _exosystem, _TooLarge, _Unrepresentable, numeric_exosystem
from ..derivation.assembly import refuse_eliminated
from ..derivation.numeric import numeric_stamps
from ..derivation.stamps import NotStampable, Stamps, stamps
from .propagation import SPECTRAL_MIN, Propagator, march, spectral_states
from .krylov import KrylovPropagator, SparseSpace, dense_unknowns, input_values
from .simulation import Result, initial_state
from ..base import waveforms as _waveforms
from ..base.switching import switches as _switches
from ..base.switching import resolve as _resolve
from ..base.switching import switching_times as _switching_times
from ..base import deferred as _deferred

sp = _deferred.module("sympy", globals())

__all__ = ["StateSpace", "state_space", "simulate_exact", "stamped"]

_log = logging.getLogger("lagrangian")

_EPS = np.finfo(float).eps
#: Functions that switch an input between expressions; their switching times split the time axis.
_ADVICE = "use model.simulate(...) (numerical integration) instead"
_USE = "Use model.simulate(...) (numerical integration) instead"


# ---------------------------------------------------------------------------
# The state-space form
# ---------------------------------------------------------------------------


@dataclass
class StateSpace:
    """The first-order linear form ``ẏ = F y + g(t)`` of a linear time-invariant model.

    ``y = (q, q̇_inertial)``: every coordinate, then the velocities of the
    inertial ones; ``states`` names them (a velocity as ``"x_p'"``).
    ``g = G s(t)``: ``inputs`` is the column ``s(t)`` of state-free terms of
    the equations (sources, applied forces, prescribed motions, gravity),
    ``G`` the constant matrix through which they enter; ``g`` is the product,
    a SymPy column in ``t``.

    The first ``n`` rows of ``ẏ`` are the velocities of all coordinates,
    first-order ones included, so ``q̇ = F[:n] y + G[:n] s(t)``
    (:meth:`velocities`).
    """

    F: np.ndarray
    G: np.ndarray
    inputs: sp.Matrix
    states: list[str]
    names: list[str]
    inertial: list[str]
    first_order: list[str]
    equations: list[str] = field(default_factory=list)
    _pieces: dict = field(default_factory=dict, repr=False, compare=False)
    _propagators: dict = field(default_factory=dict, repr=False, compare=False)
    _input_fn: Any = field(default=None, repr=False, compare=False)
    _cuts: dict = field(default_factory=dict, repr=False, compare=False)

    @property
    def g(self) -> sp.Matrix:
        """The input column ``g(t) = G s(t)`` of ``ẏ = F y + g(t)``."""
        if not self.inputs:
            return sp.zeros(len(self.states), 1)
        return sp.Matrix(self.G) * self.inputs

    def velocities(self, y: np.ndarray, s: np.ndarray | Callable[[], np.ndarray]) -> np.ndarray:
        """Velocities of all coordinates from states ``y`` (``len(states) × N``) and input values ``s`` (``len(inputs) × N``,
        or what returns them, called only when needed): an inertial coordinate's is its state (``y`` holds it), the
        others' are ``F y + G s`` on their rows."""
        n = len(self.names)
        index = {name: i for i, name in enumerate(self.names)}
        inertial = [index[name] for name in self.inertial]
        if inertial == list(range(n)) and len(y) == 2 * n:  # every coordinate inertial, in order: y's second half
            return y[n:]
        rest = sorted(set(range(n)) - set(inertial))
        out = np.empty((n, *y.shape[1:]))
        out[inertial] = y[n : n + len(inertial)]
        if rest:
            out[rest] = self.F[rest] @ y
            if self.G.shape[1]:
                out[rest] += self.G[rest] @ (s() if callable(s) else s)
        return out

    def input_values(self, times: np.ndarray) -> np.ndarray:
        """The inputs ``s(t)`` at ``times``, as a ``len(inputs) × len(times)`` array."""
        return input_values(self, times)


def state_space(model, params: Mapping[str, float] | None = None) -> StateSpace:
    """The linear state-space form of ``model`` with the given parameter values (cached until the model changes).

    Raises :class:`~lagrangian.errors.ModelError` naming the equation and the
    term when the model is not linear time-invariant: a coefficient of an
    acceleration (or first-order velocity) that depends on the state or on
    ``t``, or a term of the forcing that is nonlinear in the state or has a
    time-varying coefficient.  Inputs (state-free terms) may be any function
    of ``t`` here; :func:`simulate_exact` says which ones it can solve exactly.

    >>> import lagrangian as lg
    >>> m = lg.Model("rc")
    >>> _ = m.add("voltage_source", "V1", ("n1", "0"), E=1)
    >>> _ = m.add("resistor", "R1", ("n1", "n2"), R=2)
    >>> _ = m.add("capacitor", "C1", ("n2", "0"), C=0.5)
    >>> ss = state_space(m)
    >>> ss.states, ss.first_order, ss.F, ss.g.T     # R q' + q/C = E:  q' = -q + 1/2
    (['q_R1'], ['q_R1'], array([[-1.]]), Matrix([[0.5]]))
    """
    values = model._values(params or {}, overrides=True)
    key = ("state_space", tuple(sorted((s.name, v) for s, v in values.items())))
    return model._get(key, lambda: _build(model, values))


def _build(model, values: Mapping[sp.Symbol, float]) -> StateSpace:
    eq = model.eq
    model._holonomic_only("the exact solution by the matrix exponential")
    model._no_state_callables("the exact solution by the matrix exponential")
    if len(eq.constraints):
        owners = sorted({o for o in getattr(eq, "constraint_owners", ()) if o})
        what = f"the constraints of {', '.join(map(repr, owners))}" if owners else "loop-closure constraints"
        raise ModelError(f"model {model.name!r} has {what} between its coordinates, kept with multipliers: the exact "
                         f"solution by the matrix exponential covers unconstrained models. {_USE}.")
    subs = {s: sp.Float(v) for s, v in values.items()}
    generic = eq.generic()  # the values given as numbers come from ``values`` too (they may be given anew)
    A = generic["A"].xreplace(subs)
    b = generic["b"].xreplace(subs)
    names = eq.names
    n, inertial, first = len(names), list(eq.inertial), list(eq.first_order)
    nI = len(inertial)
    state = list(eq.sym.q) + [eq.sym.v[i] for i in inertial]
    state_set = set(state)
    state_names = names + [f"{names[i]}'" for i in inertial]
    unknowns = [f"{names[i]}''" for i in inertial] + [f"{names[i]}'" for i in first]
    where = f"model {model.name!r} is not linear time-invariant, so it has no exact solution by the matrix exponential"

    def show(expr) -> str:
        text = sp.sstr(eq.display(expr))
        return text if len(text) <= 160 else text[:157] + "..."

    def time_varying(expr) -> bool:
        return bool(expr.atoms(sp.core.function.AppliedUndef, sp.Derivative) or _dependence(expr, {t}))

    for i in range(n):
        for j in range(A.shape[1]):
            entry = A[i, j]
            dep = _dependence(entry, state_set)
            if dep:
                raise ModelError(
                    f"{where}: in the equation of {names[i]}, the coefficient of {unknowns[j]} depends on "
                    f"{_state_list(dep, eq)} (nonlinear): {show(entry)}. {_USE}."
                )
            if time_varying(entry):
                raise ModelError(
                    f"{where}: in the equation of {names[i]}, the coefficient of {unknowns[j]} varies with time "
                    f"(a time-varying inertia or damping): {show(entry)}. {_USE}."
                )
    J = b.jacobian(state)
    for i in range(n):
        for j in range(len(state)):
            entry = J[i, j]
            if entry == 0:
                continue
            dep = _dependence(entry, state_set)
            if dep:
                raise ModelError(
                    f"{where}: the equation of {names[i]} is nonlinear in {state_names[j]}: its forcing has "
                    f"∂f/∂{state_names[j]} = {show(entry)}, which depends on {_state_list(dep, eq)} "
                    f"(a nonlinear spring, damper or geometry). {_USE}."
                )
            if time_varying(entry):
                raise ModelError(
                    f"{where}: in the equation of {names[i]} the coefficient of {state_names[j]} varies with time "
                    f"({show(entry)}): a time-varying parameter, not an input. {_USE}."
                )
    s = b.xreplace({x: sp.Integer(0) for x in state})
    leftover = s.free_symbols - {t}
    if leftover:  # pragma: no cover - parameters are all given values by Model._values
        raise ModelError(f"parameters without values: {', '.join(sorted(map(str, leftover)))}")
    constant = {x: sp.Integer(0) for x in state} | {t: sp.Integer(0)}  # what remains of them cancels out
    try:
        A_num = np.array(A.xreplace(constant).tolist(), dtype=float)
        J_num = np.array(J.xreplace(constant).tolist(), dtype=float)
    except TypeError:  # pragma: no cover - every symbol was checked above
        raise ModelError(f"{where}: the coefficients do not evaluate to numbers.") from None
    if not (np.all(np.isfinite(A_num)) and np.all(np.isfinite(J_num))):
        raise ModelError(f"model {model.name!r}: its equations have non-finite coefficients with these parameter values.")
    if np.linalg.cond(A_num) > 1 / (_EPS * 16):
        _, sv, vt = np.linalg.svd(A_num)
        involved = [unknowns[k] for k, w in enumerate(vt[-1]) if abs(w) > 1e-8]
        raise SingularMassMatrixError(
            f"the mass matrix of model {model.name!r} is singular (smallest singular value {sv[-1]:.3g}): "
            f"{', '.join(involved)} are not determined by the equations. Check for coordinates without inertia "
            f"coupled only through constraints, or choose another formulation."
        )
    Ainv = np.linalg.solve(A_num, np.eye(n))
    AJ = Ainv @ J_num
    ny = len(state)
    F = np.zeros((ny, ny))
    G = np.zeros((ny, n))
    for p, i in enumerate(inertial):
        F[i, n + p] = 1.0
        F[n + p] = AJ[p]
        G[n + p] = Ainv[p]
    for r, i in enumerate(first):
        F[i] = AJ[nI + r]
        G[i] = Ainv[nI + r]
    active = [i for i in range(n) if not is_zero(s[i])]
    return StateSpace(
        F=F,
        G=G[:, active],
        inputs=sp.Matrix([s[i] for i in active]) if active else sp.Matrix(0, 1, []),
        states=state_names,
        names=list(names),
        inertial=[names[i] for i in inertial],
        first_order=[names[i] for i in first],
        equations=[names[i] for i in active],
    )


#: Models with at least this many coordinates are assembled numerically from their components' symbolic stamps
#: (:mod:`lagrangian.derivation.stamps`) when every parameter has a value, instead of deriving their equations
#: symbolically; at 40 masses the stamps take 0.02 s, the symbolic state space 0.3 s.  A model the numeric
#: assembly covers (:mod:`lagrangian.derivation.numeric`, no ``params``) takes its stamps at any size: nothing
#: symbolic is built (a moving-coil loudspeaker's exact run, 2 coordinates: 90 ms of CPU instead of 116 ms).
STAMPS_MIN = 40
#: Past this many states the exact solution works on sparse matrices (:mod:`lagrangian.numerics.krylov`) instead of
#: dense matrix exponentials (a dense ``e^{F h}`` of 2,000 states is 32 MB, and costs seconds).
DENSE_MAX = 1200


def stamped(model, params: Mapping[str, float] | None = None) -> Stamps | None:
    """The model's stamps with these parameter values (cached), or ``None``: fewer than :data:`STAMPS_MIN`
    coordinates outside the numeric assembly, or a model that is not linear time-invariant in the stamps' sense
    (the reason is logged).

    Without ``params``, from the numeric assembly where it applies (:func:`lagrangian.derivation.numeric.
    numeric_stamps`: nothing symbolic is built); else from the components' symbolic energies."""
    if not params:
        try:
            st = numeric_stamps(model)
        except NotStampable as exc:
            _log.debug("%s: not assembled in numbers: %s", model.name, exc)
        else:
            return st
    if len(model.assembly.coordinates) < STAMPS_MIN:
        return None
    values = model._values(params or {}, overrides=True)

    def build():
        try:
            return stamps(model.assembly, values)
        except (NotStampable, ArithmeticError, TypeError, ValueError) as exc:  # the symbolic path decides, and says
            _log.debug("%s: not assembled from stamps: %s", model.name, exc)
            return None

    return model._get(("stamps", tuple(sorted((s.name, v) for s, v in values.items()))), build)


def prepared(model, params, exact: bool, initial, velocity) -> tuple[Stamps | None, list[str], dict, bool]:
    """What ``Model.simulate`` starts from: ``(stamps or None, coordinate names, params checked, in numbers)``.
    Without ``params``, a model whose numeric assembly applies is not assembled symbolically at all (nothing to
    eliminate: no component said in numbers eliminates a coordinate); else the names, eliminated coordinates and
    ``params`` are checked against the symbolic assembly, and the stamps come from it (``exact``: only then)."""
    st = stamped(model) if exact and not params else None
    if st is not None and "assembly" not in model._cache:
        return st, list(st.names), {}, True
    refuse_eliminated(model.assembly.eliminated, model.assembly.values, initial=initial, velocity=velocity)
    params = check_mapping("params", params, sorted({s.name for s in [*model.parameters, *model.assembly.values]}))
    return (stamped(model, params) if exact else None), model.coordinate_names, params, False


def _from_stamps(st: Stamps) -> StateSpace | SparseSpace:
    """The state space of a stamped model: dense up to :data:`DENSE_MAX` states, sparse beyond."""
    space = st.__dict__.get("_space")
    if space is None:
        space = st.__dict__["_space"] = _space(st)
    return space


def _space(st: Stamps) -> StateSpace | SparseSpace:
    names = list(st.names)
    n, I = st.n, st.inertial
    if n + len(I) > DENSE_MAX:
        return SparseSpace(st)
    A, R, B, Sel, E = dense_unknowns(st)
    if np.linalg.cond(A) > 1 / (_EPS * 16):
        raise NotStampable("the matrix of the unknowns is singular")
    U = np.linalg.solve(A, np.hstack([R, B]))
    ny = R.shape[1]
    with np.errstate(invalid="ignore", over="ignore"):  # a number past a float's range: refused by the solution
        F, G = Sel @ U[:, :ny] + E, Sel @ U[:, ny:]
    return StateSpace(
        F=F,
        G=G,
        inputs=list(st.inputs),
        states=names + [f"{names[i]}'" for i in I],
        names=names,
        inertial=[names[i] for i in I],
        first_order=[names[i] for i in st.first_order],
        equations=[names[r] for r in st.input_rows],
    )


def _dependence(expr: sp.Expr, symbols: set) -> set:
    """The symbols of ``symbols`` that ``expr`` really depends on (a derivative not identically zero, decided by
    :func:`lagrangian.identity.depends_on`: round-off between coefficients is not a dependence)."""
    return {s for s in expr.free_symbols & symbols if depends_on(expr, s)}


def _state_list(symbols: set, eq) -> str:
    names = {q: n for q, n in zip(eq.sym.q, eq.names)} | {v: f"{n}'" for v, n in zip(eq.sym.v, eq.names)}
    return ", ".join(sorted(names.get(s, str(s)) for s in symbols))


#: Up to this many states, the dense exact solution runs BLAS on one thread: measured on a 200-section ladder (400
#: states, 30 s, 3,001 points), a second thread saves no wall time (0.17–0.30 s against 0.19 s) and doubles the CPU
#: time (0.32–0.58 s against 0.27 s); at 1,000 states it saves a fifth of the wall time for twice the CPU.
SINGLE_THREAD_MAX = 600
#: Below this many states nothing is set: OpenBLAS multiplies matrices smaller than 64³ on one thread anyway, and
#: threadpoolctl's look at the loaded libraries costs more than a small model's whole solution (8 ms of a
#: loudspeaker's 30 ms, with SciPy loaded).
SINGLE_THREAD_MIN = 64


def _blas_threads(st: Stamps | None):
    """A context in which BLAS runs on one thread, for a stamped model of :data:`SINGLE_THREAD_MIN` to
    :data:`SINGLE_THREAD_MAX` states (threadpoolctl); a context that changes nothing otherwise."""
    if st is None or not SINGLE_THREAD_MIN <= st.n + len(st.inertial) <= SINGLE_THREAD_MAX:
        return contextlib.nullcontext()
    from threadpoolctl import threadpool_limits  # imported by what uses it: a process that never solves exactly

    return threadpool_limits(1, user_api="blas")


def simulate_exact(
    model,
    t_end: float | tuple[float, float] = 10.0,
    *,
    initial: Mapping[str, float] | None = None,
    velocity: Mapping[str, float] | None = None,
    params: Mapping[str, float] | None = None,
    points: int = 1001,
    t_eval: Sequence[float] | None = None,
    progress: bool | Callable[[float, float], None] = False,
) -> Result:
    """Solve a linear time-invariant model exactly on the output grid; a :class:`~lagrangian.Result` like ``Model.simulate``.

    Arguments are those of :meth:`lagrangian.Model.simulate` (no tolerances:
    there is no integration error).  The state is advanced by matrix
    exponentials of the state-space form augmented with an exosystem that
    generates the inputs (see the module documentation); piecewise inputs
    are solved piece by piece between their switching times.  The result is
    exact up to rounding: errors of order 1e-15 relative per step, growing
    at most linearly with the number of steps.

    Raises :class:`~lagrangian.errors.ModelError` when the model is not
    linear time-invariant (see :func:`state_space`) or an input is not a
    combination of polynomials, exponentials, sines and cosines of ``t``
    (piecewise ones included) — an input given as a Python callable, say;
    ``Model.simulate`` integrates those numerically.

    >>> import numpy as np, sympy as sp, lagrangian as lg
    >>> c = lg.Model("rc pulse")
    >>> _ = c.add("voltage_source", "V1", ("n1", "0"), E=sp.Piecewise((1, lg.t < 1), (0, True)))
    >>> _ = c.add("resistor", "R1", ("n1", "n2"), R=1)
    >>> _ = c.add("capacitor", "C1", ("n2", "0"), C=1)
    >>> res = simulate_exact(c, 2.0, initial={"q_R1": 0}, points=3)     # charge 1 s, discharge 1 s
    >>> bool(np.allclose(res["q_R1"], [0, 1 - np.exp(-1), (1 - np.exp(-1)) * np.exp(-1)], rtol=0, atol=1e-15))
    True
    >>> res.method
    'exact'
    """
    span = check_span(t_end)
    st = stamped(model, params)
    in_numbers = st is not None and not params and "assembly" not in model._cache  # assembled in numbers: nothing
    if not in_numbers:  # to eliminate (no component of such a model eliminates a coordinate), names from the stamps
        refuse_eliminated(model.assembly.eliminated, model.assembly.values, initial=initial, velocity=velocity)
    names = st.names if in_numbers else model.coordinate_names
    initial = check_mapping("initial", initial, names)
    velocity = check_mapping("velocity", velocity, names)
    with _blas_threads(st):  # one BLAS thread where a second costs more CPU than it saves (SINGLE_THREAD_MAX)
        ss = None
        if st is not None:
            try:
                ss = _from_stamps(st)
            except NotStampable as exc:
                _log.debug("%s: not solved from stamps: %s", model.name, exc)
                st = None
        eq = st if st is not None else model.eq
        grid = check_grid(span, points, t_eval, len(eq.names) + len(eq.inertial))
        if ss is None:
            ss = state_space(model, params)
        y0, defaulted = initial_state(eq, initial or {}, velocity or {})
        inputs = list(ss.inputs)
        ny = len(ss.states)
        numeric = _waveforms.is_numeric(inputs)  # constants and waveforms only: no SymPy (lagrangian.base.waveforms)
        if not numeric:
            inputs = [sp.sympify(e) for e in inputs]

        for expr, eqname in zip([] if numeric else inputs, ss.equations):
            bad = expr.atoms(sp.core.function.AppliedUndef, sp.Derivative)
            if bad:
                raise ModelError(
                    f"model {model.name!r}: the input {sp.sstr(next(iter(bad)))} in the equation of {eqname} is a Python "
                    f"callable, which has no exact solution; give it as a SymPy expression of t "
                    f"(polynomials, exponentials, sines, cosines, piecewise), or {_ADVICE}."
                )
            if expr.has(sp.DiracDelta):
                raise ModelError(
                    f"model {model.name!r}: the input {sp.sstr(expr)} in the equation of {eqname} contains an impulse "
                    f"(DiracDelta), from differentiating a Heaviside step or kink (in a prescribed motion, say); "
                    f"the exact solution needs bounded inputs: write kinks with Max, Min or Piecewise, whose "
                    f"derivatives have no impulse, and steps in position as steep ramps."
                )

        cuts = ss._cuts.get(span)
        if cuts is None:
            try:
                cuts = _waveforms.cuts(inputs, *span) if numeric else _switching_times(inputs, *span)
            except (TypeError, ValueError) as exc:
                raise ModelError(
                    f"model {model.name!r}: a piecewise input cannot be split into pieces ({exc}); {_ADVICE}."
                ) from None
            if len(ss._cuts) > 64:
                ss._cuts.clear()
            ss._cuts[span] = cuts
        tol = 8 * _EPS * max(abs(span[0]), abs(span[1]))
        bounds = [span[0]]
        for c in cuts:
            if c - bounds[-1] > tol and span[1] - c > tol:
                bounds.append(c)
        bounds.append(span[1])

        uniform = None
        if grid.size > 2:
            h = (grid[-1] - grid[0]) / (grid.size - 1)
            if h > 0 and np.max(np.abs(np.diff(grid) - h)) <= 64 * _EPS * max(abs(grid[0]), abs(grid[-1])):
                uniform = h

        Y = np.empty((ny, grid.size))
        y = y0.astype(float)
        j = 0
        for p, (a, b) in enumerate(zip(bounds[:-1], bounds[1:])):
            exo = _piece(ss, model.name, inputs, a, b)
            nw = exo.w0.size
            if isinstance(ss, SparseSpace):
                prop = KrylovPropagator(ss, exo.S, exo.C) if nw else KrylovPropagator(ss)
                z = np.concatenate([y, exo.w0])
                k = j
                while k < grid.size and grid[k] <= b:
                    k += 1
                here = a
                if k > j:
                    states = prop.states(z, a, grid[j:k], uniform)
                    Y[:, j:k] = states[:, :ny].T
                    z, here = states[-1], grid[k - 1]
                if p != len(bounds) - 2 and b > here:
                    z = prop.advance(z, b - here)
                y, j = z[:ny], k
                if callable(progress):
                    progress(b, span[1])
                continue
            if nw:
                Z = np.zeros((ny + nw, ny + nw))
                Z[:ny, :ny] = ss.F
                with np.errstate(invalid="ignore", over="ignore"):  # (not finite: refused below, naming the model)
                    Z[:ny, ny:] = ss.G @ exo.C
                Z[ny:, ny:] = exo.S
            else:
                Z = ss.F
            if not np.all(np.isfinite(Z)):
                raise IntegrationError(
                    f"the exact solution of model {model.name!r} cannot be computed on [{a:g}, {b:g}]: its state matrix "
                    f"or an input's coefficient is not finite in floating point (a parameter or an input far past a "
                    f"float's range): check the magnitudes of the values given.")
            key = Z.tobytes()
            prop = ss._propagators.get(key)
            if prop is None:
                if len(ss._propagators) > 256:
                    ss._propagators.clear()
                prop = ss._propagators[key] = Propagator(Z, ny if nw else None, b - a)
            z = np.concatenate([y, exo.w0])
            last = p == len(bounds) - 2
            k = j
            while k < grid.size and grid[k] <= b:
                k += 1
            if k > j:
                states = None
                if uniform is None and k - j >= SPECTRAL_MIN:
                    states = spectral_states(prop, exo, z, a, grid[j:k])
                if states is None:
                    states = march(prop, z, a, grid[j:k], uniform)
                Y[:, j:k] = states[:, :ny].T
                z = states[-1]
                here = grid[k - 1]
            else:
                here = a
            if not last and b > here:
                z = prop(b - here) @ z
            y = z[:ny]
            j = k
            if callable(progress):
                progress(b, span[1])
        if not np.all(np.isfinite(Y)):
            bad = int(np.argmax(~np.all(np.isfinite(Y), axis=0)))
            raise IntegrationError(f"the exact solution of model {model.name!r} overflows at t={grid[bad]:g}.")
        if progress is True:
            print(f"simulating {model.name!r} exactly: done, {len(bounds) - 1} piece(s)", file=sys.stderr)

        n = len(ss.names)
        q = Y[:n]
        v = ss.velocities(Y, lambda: ss.input_values(grid))  # the inputs on the grid only where a velocity reads them
        if st is not None:
            qv = Y if len(Y) == 2 * n and np.may_share_memory(v, Y) else np.vstack([q, v])  # (y = (q, q̇): itself)
            T, V, D = (st.energies[part].values(grid, qv) for part in "TVD")
            evaluator = _LazyEvaluator(model, params)
        else:
            numeric = model.numeric(params)  # the energies
            T, V, D = numeric.energies(grid, q, v)
            evaluator = numeric.evaluate
        return Result(
            t=grid,
            q={name: q[i] for i, name in enumerate(ss.names)},
            v={name: v[i] for i, name in enumerate(ss.names)},
            T=T,
            V=V,
            D=D,
            model=model.name,
            defaulted=defaulted,
            nfev=0,
            method="exact",
            evaluator=evaluator,
            derived={} if in_numbers else {name: e.function for name, e in model.assembly.eliminated.items()},
            notes=[f"solved exactly from the components' stamps: {n} coordinates, "
                   f"{'sparse (expm_multiply)' if isinstance(ss, SparseSpace) else 'dense'} matrices"] if st is not None else [],
        )


class _LazyEvaluator:
    """``Result.quantity`` of a stamped run: the model's numeric functions, derived on the first request only (a
    class, not a closure, so that the result pickles with its model)."""

    def __init__(self, model, params):
        self.model, self.params = model, params

    def __call__(self, expr, result):
        return self.model.numeric(self.params).evaluate(expr, result)


def _piece(ss: StateSpace, model: str, inputs: list[sp.Expr], a: float, b: float) -> _Exosystem:
    """The exosystem generating the inputs on ``[a, b]`` in the local time ``τ = t − a`` (cached)."""
    exo = ss._pieces.get((a, b))
    if exo is not None:
        return exo
    if _waveforms.is_numeric(inputs):
        try:
            exo = numeric_exosystem(inputs, a, b)
        except _Unrepresentable as exc:
            raise ModelError(f"model {model!r}: the input {exc.args[0]!r} in the equation of {ss.equations[exc.args[1]]} "
                             f"is not reproduced by its exponential modes on [{a:g}, {b:g}]; {_ADVICE}.") from None
        if len(ss._pieces) > 8192:
            ss._pieces.clear()
        ss._pieces[(a, b)] = exo
        return exo
    try:
        resolved = [_resolve(e, (a + b) / 2) for e in inputs] if any(e.has(*_switches()) for e in inputs) else inputs
    except (TypeError, ValueError) as exc:
        raise ModelError(f"model {model!r}: a piecewise input cannot be evaluated on [{a:g}, {b:g}] ({exc}); {_ADVICE}.") from None
    local = tuple(e.xreplace({t: sp.Float(a) + t}) if a else e for e in resolved)
    exo = ss._pieces.get((local, b - a))  # the same expression on another piece of a pulse train
    if exo is None:
        try:
            exo = _exosystem(local, b - a)
        except _Unrepresentable as exc:
            term, i = exc.args
            local_time = f" (in the local time t − {a:g} of the piece [{a:g}, {b:g}])" if a else ""
            if isinstance(exc, _TooLarge):
                shown = sp.sstr(inputs[i])
                raise ModelError(
                    f"model {model!r}: the input {shown if len(shown) <= 200 else shown[:197] + '...'} in the equation "
                    f"of {ss.equations[i]} did not expand into exponentials within {EXPAND_SECONDS:g} s{local_time} "
                    f"(functions of t nested in one another, or high powers, are not combinations of constants, "
                    f"powers of t, exp(α t), sin and cos(ω t + φ)); {_ADVICE}."
                ) from None
            raise ModelError(
                f"model {model!r}: the input {sp.sstr(inputs[i])} in the equation of {ss.equations[i]} has no exact "
                f"solution: its term {sp.sstr(term)}{local_time} is not a combination of constants, powers of t, "
                f"exp(α t), sin and cos(ω t + φ) and their products (piecewise ones included); {_ADVICE}."
            ) from None
    if len(ss._pieces) > 8192:
        ss._pieces.clear()
    ss._pieces[(local, b - a)] = ss._pieces[(a, b)] = exo
    return exo
