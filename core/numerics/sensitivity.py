"""Forward sensitivities of a run: ``∂x(t)/∂p`` for parameters ``p`` and ``∂x(t)/∂x(0)``, ``∂x(t)/∂ẋ(0)``.

``Model.simulate(t_end, ..., sensitivities=["k_k1", "x_p", "x_p'"])`` integrates, with the state
``y = (q, q̇_inertial)`` of the run, one sensitivity ``S_θ = ∂y/∂θ`` per name — a parameter's name as in
``Model.parameter_values`` (or a symbolic parameter's, valued in ``params=``), a coordinate's name for its initial
value, the name with a prime for its initial rate — and ``Result.sensitivity(name, wrt)`` gives ``∂name(t)/∂wrt``
for a coordinate ``name`` (``"x_p"``) or its rate (``"x_p'"``).  The derivatives are exact up to the integration's
tolerance: no finite differences anywhere.

**The equations.**  A run integrates ``y' = F(t, y, p)`` with ``F = (q̇, u_inertial)``, where
``u = (q̈_inertial, q̇_first_order)`` solves ``A(t, q, q̇_I, p) u = b(t, q, q̇_I, p)`` (the generic solve of
:mod:`lagrangian.derivation.equations`: ``A`` is the mass matrix, with the dissipation's columns for coordinates
without inertia).  Differentiating ``A u = b``,

    ∂u/∂z = A⁻¹ (∂b/∂z − (∂A/∂z) u)      for z in q, q̇_I and p,

so that ``S_θ' = J S_θ + ∂F/∂θ`` (``J = ∂F/∂y``) is, with ``G = [∂b/∂z − (∂A/∂z)·u]_z`` and ``R = G_y S_θ + G_θ``,
``(∂q/∂θ)' = (∂q̇_I/∂θ, rows of A⁻¹R for the first-order rates)``, ``(∂q̇_I/∂θ)' = rows of A⁻¹R for the
accelerations``; ``S_θ(0) = 0`` for a parameter and a unit vector for an initial value.  ``G`` is derived
symbolically once per model and set of parameters (``u`` a vector of symbols, parameters given as numbers kept
as the placeholder symbols the generic equations hold) and recorded as a tape (:mod:`lagrangian.numerics.tape`)
whose parameters' values are put in per run; one factorization of ``A`` per evaluation serves the state and every
sensitivity.

**How it is integrated.**  The augmented system (``dim × (1 + number of sensitivities)`` variables) is stepped by
the runtime library's ``DOP853`` loop in C (``dopri5_c``: its Dormand–Prince 5(4) loop), calling an augmented
right-hand side in C that runs the model's tape of ``A`` and ``b`` and the tape of ``G`` on the tape interpreter
(a small library, compiled once per machine and cached as the runtime library is).  Without a C compiler, with
``compiled=False``, with ``atol`` given per state, or for SciPy's methods (``RK45``, ``RK23``, ``DOP853_scipy``,
``Radau``, ``BDF``, ``LSODA``), :func:`scipy.integrate.solve_ivp` integrates it with NumPy functions of the same
expressions.  Either way the error control covers the sensitivities: each is integrated scaled, ``θ·∂y/∂θ`` (a
parameter's effect of a change by its own size, in the units of the state; an initial value's by the size of the
start), so that one ``atol`` fits all.  The run restarts at the switching times of its inputs, as a plain run
does; it makes no energy check (``energy_tol`` does not apply) and no stiffness check.

**Constraints.**  A constrained model's solve holds the multipliers too (``u = (q̈_I, q̇_F, λ)``, the
Baumgarte-stabilized rows of its loops, rolling and nonholonomic constraints): the same derivative of ``A u = b``
gives their sensitivities, and ``m`` counts them.  The start must satisfy the constraints (as a plain run's must),
so a parameter they hold (a loop's joint position, a wheel's radius) or the initial value or rate of a coordinate
they hold cannot change alone: asking for one is refused, naming the constraints.

Refused with a :class:`~lagrangian.ModelError` naming what: what constraints hold (above), events (impacts), Python-callable signals or loads, fixed-step methods and ``method="exact"`` or ``"auto"``, and
a function that jumps where a state or an asked parameter crosses a value (``sign`` of a rate, a pulse whose time
is the parameter: the sensitivities jump there).  Functions that bend without jumping (``Abs``, ``Max``) and inputs
that switch in time alone are taken.

The undamped oscillator ``m ẍ + k x = 0`` from ``x(0) = 1``: ``x = cos ωt``, ``∂x/∂x(0) = cos ωt``,
``∂x/∂k = −t sin(ωt) / (2 m ω)`` (ω = √(k/m) = 2):

>>> import lagrangian as lg, numpy as np
>>> m = lg.Model("osc")
>>> _ = m.add("mass", "m", "p", m=1)
>>> _ = m.add("spring", "k", ("ground", "p"), k=4)
>>> res = m.simulate(1, initial={"x_p": 1}, velocity={"x_p": 0}, points=3, rtol=1e-11,
...                  sensitivities=["k_k", "x_p"])
>>> res.sensitivity_names
['k_k', 'x_p']
>>> bool(np.allclose(res.sensitivity("x_p", "k_k"), -res.t * np.sin(2 * res.t) / 4, rtol=1e-8, atol=1e-13))
True
>>> bool(np.allclose(res.sensitivity("x_p", "x_p"), np.cos(2 * res.t), rtol=1e-8))
True
"""

from __future__ import annotations

import contextlib
import functools
import math
import sys
import threading
import weakref
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..base.arguments import check_grid
from ..base.component import t as time_symbol
from ..derivation.assembly import twin
from ..derivation.calculus import Calculus
from ..errors import IntegrationError, ModelError, SingularMassMatrixError, UnknownNameError
from ..plugin.contracts import resolve
from .c_source import _Unavailable
from .compiled_loops import _watched
from .problem import MAX_EVALUATIONS, inside
from .sensitivity_c import _Compiled, _library
from .result import Result
from .simulation import NumericModel, _EPS, _lambdify, check_start, initial_state
from .tape import Program, TapeError, record
from ..base import deferred as _deferred

sp = _deferred.module("sympy", globals())

__all__ = ["SCIPY_METHODS", "asked", "plan", "refuse", "simulate"]

#: SciPy's methods a sensitivity run takes, by the name :func:`scipy.integrate.solve_ivp` knows them.
SCIPY_METHODS = ("RK23", "RK45", "DOP853", "Radau", "BDF", "LSODA")


def asked(names: Any) -> bool:
    """Whether ``sensitivities=names`` asks for any: ``None`` and an empty list do not (a plain run)."""
    if names is None:
        return False
    try:
        return len(names) > 0
    except TypeError:  # an iterator: read by plan()
        return True


@dataclass(frozen=True)
class _Wrt:
    """One sensitivity asked for: ``name`` as given; a parameter's ``symbols`` (every symbol of that name: they
    share its value) or an initial value's index ``state`` in ``y``; ``scale``, what it is integrated scaled by."""

    name: str
    symbols: tuple = ()
    state: int = -1
    scale: float = 1.0


def plan(eq, numeric: NumericModel, names: Any, y0: np.ndarray, model: str = "model") -> list[_Wrt]:
    """The sensitivities ``names`` asks for, checked against ``eq`` and the run's values (``numeric``), each with the
    scale it is integrated at: ``|θ|`` for a parameter (1 for a zero one), ``|y0_k|`` for an initial value (else the
    largest of the start, else 1).  An unknown name is an :class:`UnknownNameError` listing the known ones."""
    if isinstance(names, (str, bytes)) or not isinstance(names, Sequence) and not hasattr(names, "__iter__"):
        raise ModelError(f"sensitivities must be a list of names (parameters, coordinates for their initial values, "
                         f"coordinates with a prime for their initial rates), got {names!r:.80}.")
    names = list(dict.fromkeys(names))
    for name in names:
        if not isinstance(name, str):
            raise ModelError(f"sensitivities: each name must be a string, got {name!r:.60}.")
    by_name: dict[str, list[sp.Symbol]] = {}
    for s in sorted(numeric.values, key=sp.default_sort_key):
        by_name.setdefault(s.name, []).append(s)
    n = len(eq.names)
    states = {c: i for i, c in enumerate(eq.names)}
    states |= {f"{eq.names[i]}'": n + j for j, i in enumerate(eq.inertial)}
    first = {f"{eq.names[i]}'" for i in eq.first_order}
    eliminated = set(getattr(eq, "eliminated", {}))
    start = float(np.max(np.abs(y0), initial=0.0))
    out = []
    for name in names:
        if name in by_name and name in states:
            raise ModelError(f"sensitivities: {name!r} names both a parameter and a coordinate of model {model!r}; "
                             f"rename one of them.")
        if name in by_name:
            value = abs(float(numeric.values[by_name[name][0]]))
            out.append(_Wrt(name, symbols=tuple(by_name[name]), scale=value if 0 < value < math.inf else 1.0))
        elif name in states:
            k = states[name]
            size = abs(float(y0[k]))
            out.append(_Wrt(name, state=k, scale=size if size > 0 else start if start > 0 else 1.0))
        elif name in first:
            raise ModelError(f"sensitivities: coordinate {name[:-1]!r} of model {model!r} is first-order (it has no "
                             f"inertia): its rate follows from the equations and is no initial condition; ask for "
                             f"{name[:-1]!r} (its initial value) instead.")
        elif name.rstrip("'") in eliminated:
            raise ModelError(f"sensitivities: {name.rstrip(chr(39))!r} was eliminated by a constraint (eliminate=) "
                             f"and has no initial value of its own in model {model!r}; ask for the coordinates it "
                             f"follows from.")
        else:
            raise UnknownNameError("sensitivity (a parameter, a coordinate for its initial value, or a coordinate "
                                   "with ' for its initial rate)", name, [*by_name, *states])
    return out


def refuse(model, numeric: NumericModel, events: Sequence = ()) -> None:
    """A :class:`ModelError` naming what a sensitivity run of ``model`` cannot take: events, Python-callable signals
    or loads (what constraints refuse is :func:`_held`'s)."""
    eq = numeric.eq
    name = getattr(model, "name", "model")
    if events:
        raise ModelError(f"sensitivities: the run of model {name!r} has events "
                         f"({', '.join(repr(getattr(e, 'name', e)) for e in events)}): the sensitivities jump where an "
                         f"event occurs, which is not computed yet; run without events (or impacts).")
    callables = sorted({*eq.scan()["callables"], *(getattr(f, "__name__", str(f)) for f in numeric.signals)})
    if callables:
        raise ModelError(f"sensitivities: model {name!r} has signals or loads given as Python callables "
                         f"({', '.join(callables)}), which have no derivatives to take; write them as SymPy expressions "
                         f"of t (and of lagrangian.coordinate(...), lagrangian.rate(...) for a load).")


def _held(eq, wrt: Sequence[_Wrt], model: str) -> None:
    """A :class:`ModelError` for a sensitivity that would move the start off the constraints: the start must satisfy
    them (:func:`~lagrangian.numerics.simulation.check_start`), so a parameter they hold, or the initial value or rate
    of a coordinate they hold, cannot change alone — its derivative, the start held, is not a run's."""
    if not len(eq.constraints) and not len(eq.velocity_constraints):
        return
    g = eq.generic()
    q, v = list(eq.sym.q), list(eq.sym.v)
    rows = [(e, o) for e, o in zip(g["constraints"], getattr(eq, "constraint_owners", [None] * len(g["constraints"])))]
    rows += [(e, o) for e, o in zip(g["velocity_constraints"],
                                    getattr(eq, "velocity_owners", [None] * len(g["velocity_constraints"])))]
    for w in wrt:
        if w.symbols:
            held = {*w.symbols}
        else:
            k = w.state
            held = {q[k]} if k < len(q) else {q[eq.inertial[k - len(q)]], v[eq.inertial[k - len(q)]]}
        owners = sorted({o or "its kinematic loops" for e, o in rows if e.free_symbols & held},
                        key=lambda o: (o == "its kinematic loops", o))
        if owners:
            what = "a parameter of" if w.symbols else "an initial value held by"
            raise ModelError(f"sensitivities: {w.name!r} is {what} the constraints of model {model!r} "
                             f"({', '.join(o if o == 'its kinematic loops' else repr(o) for o in owners)}): the start "
                             f"must satisfy them, so it cannot change alone. Ask for parameters and initial values the "
                             f"constraints do not hold, or central differences of runs from consistent starts "
                             f"(lagrangian.plugins.multibody.consistent_initial).")


# ---------------------------------------------------------------------------------------------------------------
# The derivatives, symbolically once; their tapes


def _groups(wrt: Sequence[_Wrt]) -> tuple[tuple[sp.Symbol, ...], ...]:
    return tuple(w.symbols for w in wrt if w.symbols)


def _expressions(eq, groups: tuple) -> tuple[list[sp.Expr], list[sp.Symbol], int]:
    """``G`` (row-major, ``m × (dim + len(groups))``) in ``t``, ``q``, ``q̇_I``, the symbols ``u`` and the generic
    parameters; ``u``; the number of columns.  Cached on ``eq`` by ``groups``."""
    cache = eq.__dict__.setdefault("_sensitivity_exprs", {})
    if groups in cache:
        return cache[groups]
    g = eq.generic()
    A, b = g["A"], g["b"]
    m = A.shape[0]
    q = list(eq.sym.q)
    vI = [eq.sym.v[i] for i in eq.inertial]
    u = [sp.Symbol(f"_sensitivity_u{k}", real=True) for k in range(m)]
    every = [s for group in groups for s in group]
    _refuse_switches(eq, [A, b], {*q, *vI, *every})
    calc = Calculus([*q, *vI, *every])

    def partial(r: int, symbols) -> sp.Expr:
        terms = []
        for z in symbols:
            terms.append(calc.diff(b[r], z))
            terms += [-calc.diff(A[r, c], z) * u[c] for c in range(m) if z in calc.deps(A[r, c])]
        return sp.Add(*[e for e in terms if e != 0])

    columns = [(z,) for z in [*q, *vI]] + list(groups)
    exprs = [partial(r, col) for r in range(m) for col in columns]
    cache[groups] = (exprs, u, len(columns))
    return cache[groups]


#: Functions that jump where their argument (a Piecewise: its conditions) crosses a value.  Abs, Min and Max bend
#: but do not jump: the sensitivity equations hold through them.


@functools.cache
def _jumps():
    return (sp.Piecewise, sp.Heaviside, sp.sign, sp.floor, sp.ceiling, sp.frac, sp.Mod)


def _refuse_switches(eq, exprs, symbols: set) -> None:
    """A :class:`ModelError` for a function in ``exprs`` that jumps where a state or an asked parameter crosses a
    value (a Coulomb friction's sign of a rate, a pulse whose time is the parameter): there the sensitivities jump
    by what the linear equations do not give."""
    for atom in sorted({a for e in exprs for a in e.atoms(*_jumps())}, key=sp.default_sort_key):
        switching = [c for _, c in atom.args] if isinstance(atom, sp.Piecewise) else list(atom.args)
        held = set().union(*(sp.sympify(c).free_symbols for c in switching)) & symbols
        if held:
            raise ModelError(f"sensitivities: the equations switch on {eq.display(atom)} (where "
                             f"{', '.join(sorted(str(eq.display(x)) for x in held))} crosses a value): the sensitivities "
                             f"jump there, which is not computed yet; leave that parameter out, or write the switch "
                             f"as a smooth function.")


def _tape(eq, numeric: NumericModel, groups: tuple) -> Program:
    """The tape of ``G`` from ``(t, q, q̇_I, u)``, recorded once per model and ``groups`` (the parameters as run-time
    constants), with ``numeric``'s values put in."""
    cache = eq.__dict__.setdefault("_sensitivity_tapes", {})
    parameters = tuple(sorted(numeric.values, key=sp.default_sort_key))
    key = (groups, parameters)
    if key not in cache:
        exprs, u, _ = _expressions(eq, groups)
        inputs = [time_symbol, *eq.sym.q, *(eq.sym.v[i] for i in eq.inertial), *u]
        try:
            cache[key] = record(exprs, inputs, parameters)
        except TapeError as exc:
            raise _not_evaluable(exc) from None
    return cache[key].with_values(numeric.values)


def _not_evaluable(exc: Exception) -> ModelError:
    return ModelError(f"sensitivities: the derivatives of the equations cannot be evaluated ({exc}): a function "
                      f"whose derivative is an impulse or has no value here; leave that parameter out of "
                      f"sensitivities=, or write the function as a smooth one.")


class _Layout:
    """The shapes of a sensitivity run: ``n`` coordinates, ``nI`` inertial, ``m`` unknowns of the solve, ``dim`` the
    state's length; per sensitivity the column of ``G`` of its parameter (``-1``: an initial value) and its scale."""

    def __init__(self, eq, wrt: Sequence[_Wrt], ncol: int, m: int):
        self.n, self.nI, self.m = len(eq.names), len(eq.inertial), m
        self.inertial, self.first = list(eq.inertial), list(eq.first_order)
        self.dim, self.ns, self.ncol = self.n + self.nI, len(wrt), ncol
        column = iter(range(self.dim, ncol))
        self.pcol = [next(column) if w.symbols else -1 for w in wrt]
        self.pscale = [w.scale if w.symbols else 0.0 for w in wrt]
        self.scales = np.array([w.scale for w in wrt])

    def start(self, y0: np.ndarray, wrt: Sequence[_Wrt]) -> np.ndarray:
        """The augmented start: the state, then each scaled sensitivity (0, or its scale at its initial value)."""
        Y = np.zeros(self.dim * (1 + self.ns))
        Y[: self.dim] = y0
        for s, w in enumerate(wrt):
            if w.state >= 0:
                Y[self.dim * (1 + s) + w.state] = w.scale
        return Y


# per model with values (NumericModel) and sensitivities asked: what a run evaluates (never pickled with the model)
_BUILT: "weakref.WeakKeyDictionary[NumericModel, dict]" = weakref.WeakKeyDictionary()


_LOCK = threading.Lock()


def _built(numeric: NumericModel, key: tuple, make):
    with _LOCK:
        store = _BUILT.setdefault(numeric, {})
    if key not in store:
        store[key] = make()
    return store[key]


# ---------------------------------------------------------------------------------------------------------------
# The augmented right-hand side in NumPy (no C compiler, compiled=False, SciPy's methods)

# per model (its Equations): G lambdified with the parameters as arguments (not kept on the equations, which pickle)
_GENERIC: "weakref.WeakKeyDictionary[Any, dict]" = weakref.WeakKeyDictionary()


class _Python:
    """The augmented right-hand side with NumPy: ``A``, ``b`` and ``G`` lambdified from the same expressions."""

    def __init__(self, numeric: NumericModel, layout: _Layout, groups: tuple):
        eq = numeric.eq
        parameters = tuple(sorted(numeric.values, key=sp.default_sort_key))
        found = _GENERIC.setdefault(eq, {})
        if (groups, parameters) not in found:  # lambdified once per model: the values are arguments
            exprs, u, _ = _expressions(eq, groups)
            if any(e.has(sp.DiracDelta) for e in exprs):
                raise _not_evaluable(TapeError("a DiracDelta"))
            q, vI = list(eq.sym.q), [eq.sym.v[i] for i in eq.inertial]
            found[(groups, parameters)] = _lambdify((time_symbol, q, vI, u, list(parameters)), exprs, numeric.signals)
        generic, values = found[(groups, parameters)], [numeric.values[s] for s in parameters]
        self.G = lambda t, q, vI, u: generic(t, q, vI, u, values)
        self.numeric, self.layout = numeric, layout
        from scipy.linalg import lapack

        self._lu = lapack.dgetrf, lapack.dgetrs  # (LAPACK's own: SciPy's lu_solve costs a millisecond a call)

    def __call__(self, t: float, Y: np.ndarray) -> tuple[int, np.ndarray]:
        L, numeric = self.layout, self.numeric
        n, nI, dim = L.n, L.nI, L.dim
        y = Y[:dim]
        q, vI = y[:n], y[n:]
        with np.errstate(all="ignore"):
            A, b = numeric._solve_fn(t, q, vI)
            try:
                A = np.asarray(A, dtype=float).reshape(L.m, L.m)
                b = np.asarray(b, dtype=float).reshape(L.m)
            except (TypeError, ValueError):
                return 2, np.full_like(Y, np.nan)
            if not (np.all(np.isfinite(A)) and np.all(np.isfinite(b))):
                return 2, np.full_like(Y, np.nan)
            getrf, getrs = self._lu
            lu, piv, _ = getrf(A)
            if not np.min(np.abs(np.diagonal(lu))) > L.m * _EPS * np.max(np.abs(A)):
                return 1, np.full_like(Y, np.nan)
            u = getrs(lu, piv, b)[0]
            G = np.array(self.G(t, q, vI, u), dtype=float).reshape(L.m, L.ncol)
            S = Y[dim:].reshape(L.ns, dim).T
            R = G[:, :dim] @ S
            for s, (pc, scale) in enumerate(zip(L.pcol, L.pscale)):
                if pc >= 0:
                    R[:, s] += scale * G[:, pc]
            Z = getrs(lu, piv, R)[0]
        dY = np.empty_like(Y)
        v = np.empty(n)
        v[L.inertial] = vI
        v[L.first] = u[nI:n]  # (after them: the multipliers of the constraints)
        dY[:n], dY[n:dim] = v, u[:nI]
        dS = np.empty((dim, L.ns))
        dS[L.inertial] = S[n:]
        dS[n:] = Z[:nI]
        dS[L.first] = Z[nI:n]
        dY[dim:] = dS.T.ravel()
        return (0 if np.all(np.isfinite(dY)) else 2), dY


# ---------------------------------------------------------------------------------------------------------------
# The run


def _method(method: Any, integrators: Mapping[str, Any]) -> tuple[str | None, str, str]:
    """``(variant of the loop in C or None, SciPy's method, name)`` of ``method``, or a :class:`ModelError`."""
    supported = "DOP853 (the default), dop853_c, dopri5_c, or SciPy's RK45, RK23, DOP853_scipy, Radau, BDF, LSODA"
    if isinstance(method, str) and method in ("auto", "exact"):
        raise ModelError(f"sensitivities: method={method!r} is not taken by a sensitivity run; use {supported}.")
    integrator = resolve(method, integrators)
    variant = getattr(integrator, "variant", None)
    if variant in ("dop853", "dopri5"):
        return variant, "DOP853" if variant == "dop853" else "RK45", integrator.name
    scipy_name = getattr(integrator, "method", None)
    if getattr(integrator, "kind", None) == "adaptive" and scipy_name in SCIPY_METHODS:
        return None, scipy_name, integrator.name
    raise ModelError(f"sensitivities: method {getattr(integrator, 'name', method)!r} "
                     f"({getattr(integrator, 'kind', 'unknown kind')}) is not taken by a sensitivity run: it integrates "
                     f"the augmented system with an adaptive method, {supported}.")


def simulate(model, run, names: Sequence[str]):
    """``Model.simulate`` with ``sensitivities=names``: the run ``run`` (a checked
    :class:`~lagrangian.base.arguments.RunOptions`) of ``model`` with the forward sensitivities, as a
    :class:`~lagrangian.Result` whose :meth:`~lagrangian.Result.sensitivity` gives them (see the module)."""
    if getattr(model.eq, "recursion", None) is not None:  # (the recursion's accelerations carry no derivatives)
        # (a twin with the same components and dynamics="closed": the derivatives of A u = b are its)
        res = simulate(model._get(("closed twin",), lambda: twin(model, dynamics="closed")), run, names)
        res.notes.insert(0, "sensitivities: from the model's closed-form equations (its runs take the recursion's "
                            "accelerations, which give no derivatives)")
        return res
    name = model.name
    variant, scipy_method, method_name = _method(run.method, model.registry.integrators)
    numeric = model.numeric(run.params)
    eq = numeric.eq
    refuse(model, numeric, run.events)
    notes = list(run.notes)
    note = numeric.use_compiled(run.compiled)
    if note:
        notes.append(note)
    if run.compiled in (True, "native"):
        notes.append("sensitivities: the augmented right-hand side runs on the tape interpreter (no native code is "
                     "generated for it); the model's own native code evaluates its outputs")
    y0, defaulted = initial_state(eq, run.initial, run.velocity)
    check_start(numeric, name, run.span[0], y0, params=run.params)
    wrt = plan(eq, numeric, names, y0, name)
    options = dict(run.options)
    first_step = options.pop("first_step", None)
    if options:
        raise ModelError(f"sensitivities: method {method_name!r} takes no option {next(iter(options))!r} in a sensitivity "
                         f"run (first_step is the one it takes).")
    if run.step is not None:
        raise ModelError("sensitivities: a sensitivity run is adaptive: step= does not apply (give rtol, atol, max_step).")
    rtol = 1e-9 if run.rtol is None else float(run.rtol)
    atol = 1e-12 if run.atol is None else run.atol
    max_step = np.inf if run.max_step is None else float(run.max_step)
    groups = _groups(wrt)
    _held(eq, wrt, name)
    _, u, ncol = _expressions(eq, groups)
    layout = _Layout(eq, wrt, ncol, len(u))
    Y0 = layout.start(y0, wrt)
    rhs, loops = None, None
    per_state = np.ndim(atol) > 0
    if variant is not None and not numeric.python_only and not per_state:
        compiled = numeric.compile("tape")
        if compiled is None:
            notes.append(f"sensitivities: {numeric.compile_note}; SciPy's {scipy_method} integrated them instead")
        else:
            try:
                lib = _library()
                sens = _built(numeric, ("tape", groups), lambda: _tape(eq, numeric, groups))
                rhs = _built(numeric, ("C", tuple(w.name for w in wrt), tuple(layout.pscale)),
                             lambda: _Compiled(lib, numeric, layout, sens))
                loops = compiled
            except (_Unavailable, OSError) as exc:
                notes.append(f"sensitivities: their compiled code is not usable here ({exc}); SciPy's {scipy_method} "
                             f"integrated them instead")
    elif variant is not None and per_state:
        notes.append(f"sensitivities: atol given per state, which the loop in C does not take; SciPy's {scipy_method} "
                     f"integrated them instead")
    if rhs is None:
        rhs = _built(numeric, ("python", groups, tuple(w.name for w in wrt), tuple(layout.pscale)),
                     lambda: _Python(numeric, layout, groups))
    grid = np.asarray(_grid(run), dtype=float)
    progress = _reporter(run.progress, name)
    status, dY = rhs(run.span[0], Y0)
    _check(status, dY, numeric, loops, run.span[0], Y0, layout, name, start=True)
    budget = MAX_EVALUATIONS if run.max_evaluations is None else float(run.max_evaluations)
    atol_all = np.tile(np.asarray(atol, dtype=float), 1 + layout.ns) if per_state else float(atol)
    pieces, cut_note = _pieces(numeric, run.span, grid)
    if cut_note:
        notes.append(cut_note)
    with contextlib.nullcontext() if loops is not None else _one_blas_thread():
        sol_t, sol_Y, nfev, steps = _integrate(pieces, grid, loops, rhs, variant, scipy_method, Y0, rtol, atol_all,
                                               max_step, first_step, budget, progress, numeric, layout, name,
                                               method_name)
        if len(pieces) > 1:
            notes.append(f"restarted at {len(pieces) - 1} switching time(s) of the inputs (pulse corners, steps)")
        if callable(run.progress):
            run.progress(float(sol_t[-1]), run.span[1])
        elif run.progress:
            print(f"\rsimulating {name!r} with sensitivities: done, {nfev} evaluations{' ' * 20}", file=sys.stderr)
        return _result(model, numeric, wrt, layout, rhs, sol_t, sol_Y, nfev, method_name, notes, defaulted,
                       loops is not None, steps)


def _one_blas_thread():
    """BLAS on one thread (threadpoolctl) while NumPy steps a sensitivity run: its solves and products are of the
    state's size, and waking BLAS's other threads for each (a solve with several right-hand sides) cost milliseconds
    a call on a busy machine, where the work is microseconds."""
    from threadpoolctl import threadpool_limits

    return threadpool_limits(1, user_api="blas")


def _integrate(pieces, grid, loops, rhs, variant, scipy_method, Y0, rtol, atol_all, max_step, first_step, budget,
               progress, numeric, layout, name, method_name):
    """The pieces of a run one after the other: ``(t, Y, nfev, steps)`` on the output times."""
    ts, ys, nfev, steps = [], [], 0, 0
    Y = Y0
    for k, (a, b) in enumerate(pieces):
        last = k == len(pieces) - 1
        within = grid[(grid >= a) & ((grid <= b) if last else (grid < b))]
        out_t = within if last else np.append(within, b)  # b: where the next piece starts
        if loops is not None:
            T, Ys, used, taken = _run_c(loops, rhs, variant, (a, b), Y, out_t, rtol, atol_all, max_step, first_step,
                                        budget - nfev, progress, numeric, layout, name, method_name)
        else:
            T, Ys, used, taken = _run_scipy(rhs, scipy_method, (a, b), Y, out_t, rtol, atol_all, max_step, first_step,
                                            budget - nfev, progress, numeric, layout, name, method_name)
        nfev, steps = nfev + used, steps + taken
        keep = within.size
        ts.append(T[:keep])
        ys.append(Ys[:, :keep])
        Y = Ys[:, -1]
    return np.concatenate(ts), np.concatenate(ys, axis=1), nfev, steps


def _reporter(progress, model: str):
    """``progress(t, t_end)``: the caller's, or a line on standard error for ``progress=True``, or None."""
    if callable(progress) or not progress:
        return progress or None
    return lambda t, t1: print(f"\rsimulating {model!r} with sensitivities: t = {t:.4g} of {t1:.4g}", end="",
                               file=sys.stderr, flush=True)


def _grid(run) -> np.ndarray:
    return check_grid(run.span, run.points, run.t_eval, 1)


def _pieces(numeric: NumericModel, span, grid) -> tuple[list[tuple[float, float]], str | None]:
    """The run's span cut at the switching times of its inputs (as a plain adaptive run is)."""
    t0, t1 = map(float, span)
    try:
        cuts = numeric.switching_times(t0, t1)
    except ValueError as exc:
        return [(t0, t1)], f"inputs switch at times that could not be found ({exc}): steps across them rely on error control"
    width = t1 - t0
    kept: list[float] = []
    for c in cuts:
        if t0 + 1e-12 * width < c < min(t1, grid[-1]) - 1e-12 * width and (not kept or c - kept[-1] > 1e-12 * width):
            kept.append(c)
    edges = [t0, *kept, t1]
    return list(zip(edges[:-1], edges[1:])), None


def _check(status: int, dY, numeric, loops, t: float, Y, layout: _Layout, model: str, start: bool = False) -> None:
    """Raise what ``status`` of the augmented right-hand side at ``(t, Y)`` means (0: nothing)."""
    if status == 0 and np.all(np.isfinite(dY)):
        return
    y = np.asarray(Y[: layout.dim], dtype=float)
    if status == 1:  # the model's own message for a singular mass matrix, from its compiled code or NumPy
        if loops is not None:
            loops._raise(1, t, y)
        A, _ = numeric._solve_fn(t, y[: layout.n], y[layout.n:])
        raise SingularMassMatrixError(numeric._singular_message(t, np.asarray(A, dtype=float), y[: layout.n]))
    where = "at the initial state" if start else f"at t={t:g}"
    raise IntegrationError(f"the sensitivity equations of model {model!r} are not finite {where} (state "
                           f"{np.array2string(y, precision=4)}): a singular configuration of some component, or a "
                           f"diverging solution.")


_MESSAGES = {
    2: "the sensitivity equations became non-finite at t={t:g}",
    3: "the step size fell below the resolution of t at t={t:g} (the model may be stiff or singular there)",
    4: "the state or its sensitivities diverged (beyond 1e30 times their initial size) by t={t:g}",
    5: "out of memory for the stepping loop",
    6: "stopped at t={t:g}: at its pace the run would need more evaluations than its budget (max_evaluations)",
    7: "stopped at t={t:g} (interrupted)",
}


def _run_c(compiled, rhs: _Compiled, variant: str, span, Y0, t_out, rtol, atol, max_step, first_step, budget, progress,
           numeric, layout: _Layout, model: str, method: str):
    """One piece by the runtime library's loop in C on ``lg_sens_rhs``: ``(t, Y, nfev, steps)``.  Watched as a plain
    run's loop in C is (:func:`lagrangian.numerics.compiled_loops._watched`: a short run on the caller's thread, a
    long one, or one reporting its progress, on a thread of its own; Ctrl-C stops it)."""
    size = Y0.size
    t_out = np.ascontiguousarray(t_out, dtype=float)
    Y0 = np.ascontiguousarray(Y0, dtype=float)
    loop = compiled.loops.lg_dop853 if variant == "dop853" else compiled.loops.lg_dopri5

    def call(watch=None):  # (new arrays per call: a run stopped at its deadline is run again from its start)
        Ys = np.full((t_out.size, size), np.nan)
        counts = np.zeros(3, dtype=np.int64)
        fail = np.zeros(size + 1)
        status = loop(rhs.ptr, rhs.ctx, size, float(span[0]), float(span[1]), Y0.ctypes.data, t_out.size,
                      t_out.ctypes.data, float(rtol), float(atol), float(max_step) if math.isfinite(max_step) else 1e300,
                      float(first_step or 0.0), float(max(budget, 1.0)), None if watch is None else watch.ctypes.data,
                      Ys.ctypes.data, counts.ctypes.data, fail.ctypes.data)
        return status, Ys, counts, fail

    watcher = _Watcher(progress, model, size, float(span[1]))
    status, Ys, counts, fail = _watched(call, watcher, key=("sensitivities", variant, *map(float, span), float(rtol)))
    if status:
        t = float(fail[0])
        if status == 1:
            _check(1, None, numeric, compiled, t, fail[1:], layout, model)
        if status == 7:
            raise KeyboardInterrupt
        raise IntegrationError(f"{method} failed on the sensitivity run of model {model!r}: "
                               f"{_MESSAGES.get(status, 'status {status}').format(t=t, status=status)}.")
    return t_out, Ys.T, int(counts[0]), int(counts[1])


class _Watcher:
    """What :func:`~lagrangian.numerics.compiled_loops._watched` reads of a run (a :class:`Problem`'s): its name,
    size, and the progress it reports."""

    def __init__(self, progress, name: str, dim: int, t1: float):
        self._report, self.name, self.dim, self._t1 = progress, name, dim, t1

    def report(self, t: float) -> None:
        if self._report is not None:
            self._report(t, self._t1)


def _run_scipy(rhs, method: str, span, Y0, t_out, rtol, atol, max_step, first_step, budget, progress, numeric,
               layout: _Layout, model: str, name: str):
    """One piece by :func:`scipy.integrate.solve_ivp`: ``(t, Y, nfev, steps)``."""
    from scipy.integrate import solve_ivp

    count = [0]

    def f(t, Y):
        count[0] += 1
        if count[0] > budget:
            raise IntegrationError(f"{name}: the sensitivity run of model {model!r} stopped at t={t:g}: it needs more "
                                   f"evaluations than its budget (max_evaluations).")
        if callable(progress) and not count[0] % 1000:
            progress(float(t), float(span[1]))
        status, dY = rhs(inside(t, *span), Y)  # inputs read on this piece's side of its corners, as in C
        if status:
            _check(status, dY, numeric, None, t, Y, layout, model)
        return dY

    extra = {} if first_step is None else {"first_step": first_step}
    sol = solve_ivp(f, span, Y0, method=method, t_eval=t_out, rtol=rtol, atol=atol, max_step=max_step, **extra)
    if sol.status < 0 or sol.t.size != t_out.size:
        raise IntegrationError(f"{name} failed on the sensitivity run of model {model!r}: {sol.message}")
    return sol.t, sol.y, int(sol.nfev), int(sol.t.size)


def _result(model, numeric: NumericModel, wrt, layout: _Layout, rhs, t, Y, nfev, method, notes, defaulted, in_c: bool,
            steps: int) -> Result:
    eq = numeric.eq
    n, dim = layout.n, layout.dim
    if not np.all(np.isfinite(Y)):
        bad = int(np.argmax(~np.all(np.isfinite(Y), axis=0)))
        raise IntegrationError(f"the sensitivity run of model {model.name!r} by {method} became non-finite at t={t[bad]:g}.")
    y = Y[:dim]
    v = numeric.velocities_many(t, y)
    q = y[:n]
    T, V, D = numeric.energies(t, q, v)
    names = eq.names
    rates = None
    if layout.first:  # a first-order coordinate's rate is no state: its sensitivity is the derivative of its own
        rates = np.empty((layout.ns, n, t.size))
        for k in range(t.size):
            status, dY = rhs(t[k], Y[:, k])
            _check(status, dY, numeric, None, t[k], Y[:, k], layout, model.name)
            rates[:, :, k] = dY[dim:].reshape(layout.ns, dim)[:, :n]
    sensitivities: dict[str, dict[str, np.ndarray]] = {}
    for s, w in enumerate(wrt):
        S = Y[dim * (1 + s): dim * (2 + s)] / w.scale
        series = {c: S[i].copy() for i, c in enumerate(names)}
        for i, c in enumerate(names):
            if i in layout.inertial:
                series[f"{c}'"] = S[n + layout.inertial.index(i)].copy()
            else:
                series[f"{c}'"] = rates[s, i] / w.scale
        sensitivities[w.name] = series
    how = (f"{steps} steps in compiled code, the augmented right-hand side on the tape interpreter" if in_c
           else "stepped by SciPy, the augmented right-hand side in NumPy")
    notes = [*notes, f"sensitivities to {', '.join(w.name for w in wrt)}: the forward sensitivity equations integrated "
                     f"with the state ({dim * (1 + layout.ns)} variables, error-controlled together) by {method}, {how}"]
    return Result(evaluator=numeric.evaluate, t=t, q={c: q[i] for i, c in enumerate(names)},
                  v={c: v[i] for i, c in enumerate(names)}, T=T, V=V, D=D, model=model.name, defaulted=defaulted,
                  nfev=int(nfev), method=method, notes=notes,
                  derived={c: e.function for c, e in getattr(eq, "eliminated", {}).items()},
                  sensitivities=sensitivities)
