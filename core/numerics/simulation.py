"""Numeric code from the equations, and the result object.

The solve ``A(t, q, q̇) u = b(t, q, q̇)`` (see :mod:`lagrangian.equations`) is
turned into one NumPy function with common-subexpression elimination; the
state is ``(q, q̇_inertial)``.  Integrating it is :mod:`lagrangian.integrate`'s
job (integrators are plugins).  Numerical trouble — a singular mass matrix,
an integrator failure, non-finite values — raises a
:class:`~lagrangian.errors.NumericalError` saying where and when.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from .band import recursive_arrays
from .codegen import _Unavailable, compile_model, programs
from .result import Result
from ..base.component import StateCall, refuse_unpicklable, t
from ..derivation.assembly import Signals, refuse_eliminated
from ..derivation.equations import Equations
from ..errors import (ExpressionError, LagrangianError, ModelError, NumericalError, ParameterError,
                      SingularMassMatrixError, UnknownNameError)
from ..errors import warn as _warn
from ..base.switching import switching_times
from ..base.text import as_expr, parse_expression
from ..base import deferred as _deferred

sp = _deferred.module("sympy", globals())

__all__ = ["NumericModel", "Result", "InitialConditionWarning", "initial_state", "check_start"]


def _is_angle(coordinate) -> bool:
    """A coordinate that is an angle (a revolute joint's, a spherical joint's), by its name and description."""
    text = f"{coordinate.name} {coordinate.description}".lower()
    return any(w in text for w in ("angle", "revolute", "spherical", "theta", "phi", "psi"))


class InitialConditionWarning(UserWarning):
    """Some initial conditions were not given and default to zero."""


def _checked_signal(name: str, fn: Callable, owner: tuple[str, str] | None = None) -> Callable:
    """A user's callable signal, whose value must be one number per time (a scalar, or an array shaped as ``t``);
    a load's callable of the state is called with ``(t, q, v)`` (:class:`~lagrangian.base.component.StateCall`),
    one state at a time.  ``owner``, the ``(component, parameter)`` it was given for, makes what it does wrong a
    :class:`ParameterError` naming them."""
    if isinstance(fn, StateCall):
        return _checked_state(name, fn, owner)

    def signal(time):
        value = _called(fn, f"the signal {name}(t)", time, owner=owner)
        text = _text_in(value)
        if text:
            raise _refused(owner, f"the signal {name}(t), a Python callable, returned {value!r:.60} ({text}) at "
                                  f"t={time!r:.30}: it must return a number (an int, a float or an array of them, one "
                                  f"per time), not text.")
        try:
            if value is None:
                raise TypeError
            out = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise _refused(owner, f"the signal {name}(t), a Python callable, returned {value!r:.60} at "
                                  f"t={time!r:.30}: it must return a number.") from None
        if out.shape not in ((), np.shape(time)):
            raise _refused(owner, f"the signal {name}(t), a Python callable, returned an array of shape {out.shape} "
                                  f"at t={time!r:.30}: it must return one number per time.")
        if not np.all(np.isfinite(out)):
            raise _refused(owner, f"the signal {name}(t), a Python callable, returned {value!r:.60} at "
                                  f"t={time!r:.30}: it must return a finite number.")
        return out

    return signal


def _refused(owner: tuple[str, str] | None, message: str) -> ModelError:
    """The error for what a user's callable did: a :class:`ParameterError` naming the component and parameter it
    was given for, where known (a :class:`ModelError` otherwise)."""
    return ParameterError(*owner, message) if owner else ModelError(message)


def _text_in(value: Any) -> str | None:
    """What kind of text ``value`` is or holds (``"a str"``, ``"an array of <U1"``) where a number was wanted —
    which NumPy would read as one (``float("1")``) — or None."""
    if isinstance(value, (str, bytes, bytearray)):
        return f"a {type(value).__name__}"
    if isinstance(value, (list, tuple, np.ndarray)):
        try:
            kind = np.asarray(value)
        except Exception:  # noqa: BLE001 - ragged or odd: refused as not a number by the caller
            return None
        if kind.dtype.kind in "SUV":
            return f"an array of {kind.dtype}"
        if kind.dtype.kind == "O" and any(isinstance(x, (str, bytes, bytearray)) for x in kind.flat):
            return "a sequence holding text"
    return None


def _called(fn: Callable, what: str, time, *args, owner: tuple[str, str] | None = None) -> Any:
    """``fn(time, *args)``; an exception the user's callable raises is told as a :class:`ModelError` naming it and
    the time (the original chained), so that a run, a deck or an export ends with the project's error."""
    try:
        return fn(time, *args)
    except LagrangianError:
        raise
    except Exception as exc:
        raise _refused(owner, f"{what}, a Python callable, raised {type(exc).__name__}: {str(exc)[:200]} at "
                              f"t={time!r:.30}; make it return a finite number for every time of the run.") from exc


def _checked_state(name: str, call: StateCall, owner: tuple[str, str] | None = None) -> Callable:
    """A load's callable ``f(t, q, v)``: called once per state (many states are taken one at a time), its value
    one finite number."""

    def one(time, args):
        value = _called(call, f"the load {name}(t, q, v)", time, *args, owner=owner)
        text = _text_in(value)
        try:
            out = np.nan if text else float(value)  # None and arrays are refused here, text above
        except (TypeError, ValueError):
            out = np.nan
        if not np.isfinite(out):
            raise _refused(owner, f"the load {name}(t, q, v), a Python callable, returned {value!r:.60}"
                                  f"{f' ({text})' if text else ''} at t={time!r:.30}: it must return one finite "
                                  f"number{', not text' if text else ''}.")
        return out

    def signal(time, *args):
        if np.ndim(time) == 0 and all(np.ndim(a) == 0 for a in args):
            return one(float(time), [float(a) for a in args])
        arrays = np.broadcast_arrays(time, *args)
        return np.array([one(float(x[0]), [float(a) for a in x[1:]])
                         for x in zip(*(a.ravel() for a in arrays))]).reshape(arrays[0].shape)

    return signal


_SCIPY: dict[str, Any] = {}


def _scipy(part: str) -> Any:
    """What this module calls from SciPy, imported on first use: ``"special"``, the functions an expression may call
    (:data:`lagrangian.text.FUNCTIONS`) that NumPy lacks, ``erf`` and ``erfc`` (they take arrays, where lambdify
    would otherwise find the scalar ``math.erf``); ``"lapack"``, LAPACK's LU factorization and solve
    (:meth:`NumericModel.solve`).  Each is imported when first needed rather than with the module: ``scipy.linalg``
    and ``scipy.special`` are 0.2 s of CPU that a process running compiled code, or evaluating outputs without
    ``erf``, never needs."""
    if part not in _SCIPY:
        if part == "special":
            import scipy.special

            _SCIPY[part] = {"erf": scipy.special.erf, "erfc": scipy.special.erfc}
        else:
            import scipy.linalg

            _SCIPY[part] = {"getrf": scipy.linalg.lapack.dgetrf, "getrs": scipy.linalg.lapack.dgetrs}
    return _SCIPY[part]


_EPS = np.finfo(float).eps


def constraint_scales(A: np.ndarray, multipliers: int) -> np.ndarray:
    """Powers of two ``d`` (one per unknown, for one matrix or a stack of them) that scale the last ``multipliers``
    unknowns of ``A u = b`` — the constraints' multipliers — so that each constraint's row of ``A`` (and its
    multiplier's column) is as large as the largest entry of the rest of ``A``; the other unknowns' factors are 1.

    The solve is then ``(D A D) y = D b``, ``u = D y``: a constraint written with a factor of 1e-9 or 1e30 is the same
    constraint, and the singularity test (pivots against ``size·eps·max|A|``) judges its solve as it does the
    factor 1's, where unscaled it called 1e-9 and 1e15 singular.  Powers of two scale exactly; compiled code's solve
    (``balance`` in :mod:`lagrangian.numerics.c_source`) takes the same factors.

    >>> A = np.array([[0.3, 0.0, -1e-9], [0.0, 0.5, 1e-9], [1e-9, -1e-9, 0.0]])
    >>> d = constraint_scales(A, 1)
    >>> d.tolist() == [1.0, 1.0, 2.0 ** 29], bool(np.linalg.cond(A) > 1e15), bool(np.linalg.cond(A * np.outer(d, d)) < 10)
    (True, True, True)
    """
    d = np.ones(A.shape[:-1])
    size = A.shape[-1]
    k = size - multipliers
    if multipliers <= 0 or k <= 0:
        return d
    with np.errstate(all="ignore"):
        mu = np.max(np.abs(A[..., :k, :k]), axis=(-2, -1))[..., None]
        row = np.max(np.abs(A[..., k:, :]), axis=-1)
        ok = (mu > 0) & (mu <= np.finfo(float).max) & (row > 0) & (row <= np.finfo(float).max)
        e = np.frexp(np.where(ok, mu, 1.0))[1] - np.frexp(np.where(ok, row, 1.0))[1]
    d[..., k:] = np.ldexp(1.0, np.clip(np.where(ok, e, 0), -1000, 1000))
    return d
#: Integers beyond this are not exact in a float; beyond 2**63 NumPy holds them as Python objects, which its
#: functions refuse (``np.tan(10**30)`` is a TypeError).
_EXACT = 2**53


def _floated(exprs: Any) -> Any:
    """``exprs`` (an expression, a matrix, or a list or tuple of them) with every integer or fraction too large for
    float arithmetic written as a float, as the tape and compiled code read it (``cot(10**30)`` is
    ``cot(1.0e30)``); a number beyond a float becomes an infinite float.  Nothing changes when there is none."""
    if isinstance(exprs, (list, tuple)):
        return type(exprs)(_floated(e) for e in exprs)
    if not isinstance(exprs, (sp.Basic, sp.MatrixBase)):
        return exprs
    big = {r: sp.Float(r) for r in exprs.atoms(sp.Rational) if abs(r.p) > _EXACT or r.q > _EXACT}
    return exprs.xreplace(big) if big else exprs


def _lambdify(args, exprs, signals, definitions=()):
    """A NumPy function of ``exprs``; ``definitions`` (``(symbol, expression)`` in order, a recursion's steps) are
    computed first, in that order, as the function's common sub-expressions."""
    every = [e for e in (exprs if isinstance(exprs, (list, tuple)) else [exprs]) if hasattr(e, "has")]
    if any(e.has(sp.zoo, sp.nan) for e in every):
        raise ModelError("the equations of motion hold an undefined constant (a division by zero that SymPy wrote as "
                         "zoo or nan, whatever the state): a component's energy or force is infinite everywhere, "
                         "such as one joining a node to itself. Check the components' nodes and parameters.")
    special = [_scipy("special")] if any(e.has(sp.erf, sp.erfc) for e in every) else []
    owners = getattr(signals, "owners", {})
    modules = [{f.__name__: _checked_signal(f.__name__, fn, owners.get(f.__name__)) for f, fn in signals.items()},
               *special, "numpy"]
    if definitions:
        steps = [(w, _floated(e)) for w, e in definitions]
        return sp.lambdify(args, _floated(exprs), modules=modules, cse=lambda e: (steps, e))
    return sp.lambdify(args, _floated(exprs), modules=modules, cse=True)


def _not_finite(time: float, state: np.ndarray, why: str) -> str:
    """The message of equations that cannot be evaluated at a state (as compiled code words it)."""
    shown = np.array2string(np.asarray(state, dtype=float), precision=4)
    return (f"the equations cannot be evaluated at t={time:g} (state {shown}; {why}): a singular configuration of "
            f"some component, a signal singular at that time (1/t at t=0), or a diverging solution. Start elsewhere "
            f"or reduce the step.")


class _Deferred:
    """The compiled code an unpickled :class:`NumericModel` used, built on first use (from the disk cache when
    it is there): whichever method is called first puts the built one, or None, in its place."""

    def __init__(self, numeric: "NumericModel", kind: str):
        self.numeric, self.kind = numeric, kind

    def __getattr__(self, name: str) -> Any:
        numeric = self.numeric
        numeric._fast = numeric.compile(self.kind)  # None: cannot be compiled here, NumPy as use_compiled() has it
        return getattr(numeric._fast if numeric._fast is not None else numeric, name)


class NumericModel:
    """Compiled (NumPy) functions of one model with numeric parameter values.

    It pickles without its compiled code and lambdified functions, which are rebuilt on first use after
    unpickling (see ``_UNPICKLED``).
    """

    def __init__(self, eq: Equations, values: Mapping[sp.Symbol, float], signals: Mapping[Any, Any]):
        self.eq = eq
        q, v = eq.sym.q, eq.sym.v
        self.vI = [v[i] for i in eq.inertial]
        leftover = eq.parameter_symbols() - set(values)
        if leftover:  # pragma: no cover - caught earlier by Model.simulate
            raise ModelError(f"parameters without values: {', '.join(sorted(map(str, leftover)))}")
        derivatives = eq.scan()["derivatives"]
        if derivatives:
            raise ModelError(
                f"the equations need the time derivative {derivatives[0]} of a callable signal; give that signal as "
                f"a SymPy expression of t."
            )
        self._flat_fn = None  # entries of A and b, for many states at once (built on first use)
        self.n = len(q)
        self.nI = len(eq.inertial)
        self.values = dict(values)
        self.signals = Signals(signals)  # (with whose each callable is, where the assembly says)
        self._builds: dict[str, Any] = {}  # kind → lagrangian.codegen.CompiledModel (or None: cannot), see compile()
        self._mode = "auto"  # what compile() builds when a method with a compiled loop asks (use_compiled sets it)
        self.python_only = False  # compiled=False was asked (use_compiled sets it)
        self.compile_note: str | None = None
        self._fast: Any = None  # the CompiledModel that rhs() and energies() use (use_compiled)

    #: What a pickle leaves out: compiled code (native libraries, tape programs, ctypes handles) and the NumPy
    #: functions lambdified from the equations, all rebuilt on first use where it is unpickled (native code from
    #: the disk cache, or compiled again) — never unpickled as machine code.
    _UNPICKLED = ("_builds", "_fast", "_flat_fn", "_solve_fn", "_energy_fn", "_energy_tape", "_tapes_by_layout")

    def __getstate__(self) -> dict[str, Any]:
        for f, fn in self.signals.items():  # (a load's callable of the state is held by a StateCall)
            refuse_unpicklable(fn.func if isinstance(fn, StateCall) else fn,
                               f"the signal {f} (a parameter given as a Python callable)")
        state = {k: v for k, v in self.__dict__.items() if k not in self._UNPICKLED}
        state["_fast_kind"] = None if self._fast is None else self._mode  # the compiled code rhs() used
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        kind = state.pop("_fast_kind", None)
        self.__dict__.update(state)
        self._builds, self._flat_fn, self._fast = {}, None, None
        if kind is not None:
            self._fast = _Deferred(self, kind)

    @functools.cached_property
    def _solve_args(self):
        """The generic equations with the values in, for the NumPy functions (large: built only when they are)."""
        subs = {s: sp.Float(v) for s, v in self.values.items()}
        generic = self.eq.generic()  # values given as numbers are symbols there: every value comes from ``values``
        if self.eq.recursion is not None:  # the recursion's steps (in _solve_fn), never the closed form's A and b
            _, u, _ = recursive_arrays(self.eq)
            A, b = sp.eye(len(u)), sp.Matrix(u).xreplace(subs)
        else:
            A, b = generic["A"].xreplace(subs), generic["b"].xreplace(subs)
        energies = [generic[k].xreplace(subs) for k in ("T", "V", "D")]
        q, v = self.eq.sym.q, self.eq.sym.v
        return (t, q, self.vI), [A, b], (t, q, v), energies

    def switching_times(self, lo: float, hi: float) -> list[float]:
        """Times in ``(lo, hi)`` where a function of ``t`` in the equations switches branch, with these values.

        Raises ``ValueError`` when they cannot be found (a switch at the root of a transcendental function).
        """
        switches = self.eq.time_switches()
        if not switches:
            return []
        subs = {s: sp.Float(v) for s, v in self.values.items()}
        timed = [a.xreplace(subs) for a in switches]
        return switching_times([a for a in timed if a.free_symbols == {t}], lo, hi)

    @property
    def _flat_exprs(self):
        (args, (A, b), _, _) = self._solve_args
        return list(A), list(b), args, self.signals

    @functools.cached_property
    def _solve_fn(self):
        args, exprs, _, _ = self._solve_args
        steps = ()
        if self.eq.recursion is not None:  # (a tree of 30 bodies in work linear in its size, on NumPy too)
            subs = {s: sp.Float(v) for s, v in self.values.items()}
            steps = [(w, e.xreplace(subs)) for w, e in self.eq.recursion.recursion.definitions]
        return _lambdify(args, exprs, self.signals, steps)

    @functools.cached_property
    def _energy_fn(self):
        _, _, args, energies = self._solve_args
        return _lambdify(args, energies, self.signals)

    # -- compiled code (lagrangian.codegen) ------------------------------------------
    def compile(self, kind: str | None = None) -> Any:
        """This model's compiled functions (a :class:`lagrangian.codegen.CompiledModel`), built once per kind:
        ``"native"`` (its own C library, compiled or from the disk cache), ``"tape"`` (the shared tape
        interpreter: nothing compiled for this model), ``"auto"`` (native when already built or in the cache,
        else the tape); ``None``: the kind :meth:`use_compiled` chose.  ``None`` comes back when the model cannot
        be compiled here (no C compiler, Python-callable signals, ...), with the reason in ``compile_note``."""
        kind = kind or self._mode
        if kind == "auto" and self._builds.get("native") is not None:
            return self._builds["native"]
        if kind not in self._builds:
            built, note = compile_model(self, kind)
            self._builds[kind] = built
            if built is not None:
                self._builds.setdefault(built.kind, built)
            if note:
                self.compile_note = note
        return self._builds[kind]

    def use_compiled(self, compiled: bool | str) -> str | None:
        """Evaluate :meth:`rhs`, :meth:`velocities_many` and :meth:`energies` with compiled code (``True`` or
        ``"native"``: native; ``"tape"``: the tape interpreter; ``"auto"``: whichever :meth:`compile` has at
        once) or NumPy (``False``); see ``Model.simulate``.  A note when compiled code was asked for
        but cannot be used."""
        kinds = {True: "native", "native": "native", "tape": "tape", "auto": "auto", False: None}
        if not any(compiled is k or (isinstance(k, str) and compiled == k) for k in kinds):
            raise ModelError(f"compiled must be True, False, 'auto', 'native' or 'tape', not {compiled!r}.")
        kind = kinds[compiled]
        self._mode = kind or "auto"
        self.python_only = kind is None  # compiled=False: NumPy, and no loop in C for a method that may choose one
        self._fast = self.compile(kind) if kind else None
        return self.compile_note if compiled not in (False, "auto") and self._fast is None else None

    def solve(self, time: float, qv: np.ndarray, vI: np.ndarray) -> np.ndarray:
        """``u = (q̈_inertial, q̇_first_order)`` at one instant."""
        try:
            A, b = self._solve_fn(time, qv, vI)
        except (ZeroDivisionError, OverflowError, FloatingPointError) as exc:  # Python arithmetic on the scalar time
            raise NumericalError(_not_finite(time, np.concatenate([qv, vI]), str(exc))) from None
        try:
            A = np.asarray(A, dtype=float)
            b = np.asarray(b, dtype=float).reshape(-1)
        except (TypeError, ValueError, OverflowError):  # a complex value (a negative number to a fractional power)
            raise NumericalError(_not_finite(time, np.concatenate([qv, vI]), "not a real number")) from None
        if A.size and np.all(np.isfinite(A)):
            # LU with partial pivoting, and compiled code's rule for a singular matrix: a pivot at most
            # size·eps·max|A| (a mass of 1e-141 next to one of 1 is none, whatever the rounding leaves), judged with
            # the constraints' rows scaled as the rest of A (constraint_scales): the scale a constraint is written
            # in decides nothing
            d = constraint_scales(A, self._multipliers(A.shape[0]))
            S = A * d[:, None] * d[None, :]
            lapack = _scipy("lapack")
            lu, piv, _ = lapack["getrf"](S)
            if not np.min(np.abs(np.diagonal(lu))) > S.shape[0] * _EPS * np.max(np.abs(S)):
                raise SingularMassMatrixError(self._singular_message(time, A, qv))
            return d * lapack["getrs"](lu, piv, d * b)[0]
        try:
            return np.linalg.solve(A, b)
        except np.linalg.LinAlgError:
            raise SingularMassMatrixError(self._singular_message(time, A, qv)) from None

    def _multipliers(self, size: int) -> int:
        """How many of the ``size`` unknowns of the solve are constraints' multipliers (the last ones; 0 when the
        matrix is the mass matrix alone)."""
        return max(0, size - self.nI - len(self.eq.first_order))

    def _singular_message(self, time: float, A: np.ndarray, q: np.ndarray | None = None) -> str:
        """Which case a singular solve ``A u = b`` is, at whose fault, and what to do.

        The cases, tried in turn: dependent loop-closure constraints (an over-constrained loop, or a loop at a
        singular position); first-order coordinates whose dissipation fixes only part of their rates; a
        coordinate held only by a loop that does not fix it; a direction of the coordinates with no inertia at
        any configuration (a massless coordinate: ``A`` is singular at random states too); a direction lost only
        at this configuration (a gimbal lock of the chosen angles, a pole).  ``A`` may also be the mass matrix
        alone (a problem without constraints or first-order coordinates); ``q``, when given, is quoted.
        """
        eq = self.eq
        A = np.asarray(A, dtype=float)
        nI, nF, m = len(eq.inertial), len(eq.first_order), len(eq.multipliers)
        if A.shape[0] == nI + nF + m:
            names = [eq.names[i] for i in eq.inertial + eq.first_order] + [f"multiplier {k}" for k in range(m)]
            d = constraint_scales(A, m)  # the matrix the solve judged: constraints' rows scaled as the rest
            A = A * d[:, None] * d[None, :]
        else:  # the mass matrix of all the coordinates
            names, nI, nF, m = list(eq.names)[: A.shape[0]], A.shape[0], 0, 0
        _, s, vt = np.linalg.svd(A)
        null = vt[-1]
        involved = [n for n, w in zip(names, null) if abs(w) > 1e-8] or names
        coords = [n for n in involved if not n.startswith("multiplier")]
        if not coords:  # only multipliers: name the coordinates their constraints hold, never no one
            rows = [nI + nF + k for k in range(m) if f"multiplier {k}" in involved]
            coords = [n for j, n in enumerate(names[: nI + nF]) if any(A[r, j] != 0 for r in rows)] \
                or names[: nI + nF] or list(eq.names)
            involved = coords
        at = ""
        if q is not None and len(q) == len(eq.names):
            at = " at " + ", ".join(f"{n} = {float(x):.6g}" for n, x in zip(eq.names, q))
        head = f"the mass matrix is singular at t={time:g}{at} (smallest singular value {s[-1]:.3g}): "
        if m:
            J = A[nI + nF :, :nI]
            U, sj, _ = np.linalg.svd(J)
            rank = int(np.sum(sj > 1e-9 * max(float(sj[0]) if sj.size else 0.0, 1e-300)))
            if rank < m:
                rows = sorted({k for col in range(rank, m) for k in np.flatnonzero(np.abs(U[:, col]) > 1e-8)})
                on = [eq.names[i] for j, i in enumerate(eq.inertial) if np.any(np.abs(J[:, j]) > 1e-12)]
                where = (
                    "at every configuration: an over-constrained loop — a redundant joint repeats what the others "
                    "already impose, so its reaction is not determined. Remove the redundant joint, or replace it by "
                    "one that imposes less"
                    if self._singular_everywhere(time, A.shape[0]) else
                    "at this configuration only: a loop at a singular position (links in line, a dead centre), where "
                    "the constraints lose a direction. Start away from that position"
                )
                return head + (
                    f"the loop-closure constraints on {', '.join(on) or 'the coordinates'} (rows "
                    f"{', '.join(map(str, rows))} of the {m} of Φ) are dependent {where}. "
                    f"(lagrangian.plugins.multibody.independent_coordinates(model, state) names the joints.)"
                )
        first = [eq.names[i] for i in eq.first_order if eq.names[i] in involved]
        if first and len(first) == len(coords):
            return head + (
                f"the motion of {', '.join(first)} is not determined there: they have no inertia, and their "
                f"dissipation fixes only part of their rates (a damper alone between massless nodes fixes their "
                f"relative velocity). Give one of them a mass, or a damper to ground."
            )
        # no inertia at all: a row of M identically zero (a coordinate held only by a loop), not just here
        massless = [eq.names[i] for i in getattr(eq, "held", []) if eq.names[i] in involved]
        if massless:
            return head + (
                f"the motion of {', '.join(massless)} is not determined there: no inertia of its own, and the loop "
                f"constraints do not fix it (a massless coordinate). Give it a mass, or a damper so that it moves as a "
                f"first-order coordinate."
            )
        described = {c.name: c.description for c in eq.coordinates}
        whose = "; ".join(f"{n}: {described[n].split(';')[0]}" for n in coords if described.get(n))
        whose = f" ({whose})" if whose else ""
        sign = 1.0 if null[int(np.argmax(np.abs(null)))] > 0 else -1.0
        direction = " ".join(f"{'+' if sign * w > 0 else '−'} {abs(w):.3g}·{n}" for n, w in zip(names, null)
                             if n in coords and abs(w) > 1e-8).lstrip("+ ")
        if self._singular_everywhere(time, A.shape[0]):
            return head + (
                f"the motion of {', '.join(coords)}{whose} is not determined: no inertia along {direction or 'them'}, "
                f"at any configuration (a massless coordinate, or a direction without inertia — a massless link "
                f"between two joints, a slender rod's spin about its own axis). Give it inertia (a mass, a body with "
                f"a moment about that axis), make it first-order with a damper, or remove the coordinate (a joint "
                f"with fewer degrees of freedom)."
            )
        angles = [c.name for c in eq.coordinates if c.name in coords and _is_angle(c)]
        if angles and len(angles) == len(coords):
            notes = list(dict.fromkeys(described[n].split(";", 1)[1].strip() for n in coords if ";" in described.get(n, "")))
            return head + (
                f"the motion of {', '.join(angles)} is not determined there{whose}: the angles lose a direction in "
                f"this configuration only (a gimbal lock of the chosen angles, or a pole, such as a spherical pendulum "
                f"hanging straight down in azimuth–tilt angles). "
                + (f"{'; '.join(notes)}. " if notes else "")
                + "Start away from it, or describe the rotation with other angles (a spherical or free joint: "
                "another sequence=, whose lock the motion avoids)."
            )
        return head + (
            f"the motion of {', '.join(involved)}{whose} is not determined there (a direction lost at this "
            f"configuration only). Check for coordinates without inertia coupled only through constraints, start "
            f"elsewhere, or choose other coordinates."
        )

    def _singular_everywhere(self, time: float, size: int, probes: int = 3) -> bool:
        """Whether the solve's matrix is singular at random states as well (a structural singularity), not only at
        the one where it failed; False when no random state could be evaluated."""
        if getattr(self.eq, "recursion", None) is not None:  # (taken only when its pivots were positive at random)
            return False
        rng = np.random.default_rng(12345)
        seen = 0
        for _ in range(4 * probes):
            q = rng.uniform(0.2, 1.3, self.n) * rng.choice((-1.0, 1.0), self.n)
            vI = rng.uniform(-1.0, 1.0, self.nI)
            try:
                with np.errstate(all="ignore"):
                    A = np.asarray(self._solve_fn(time, q, vI)[0], dtype=float)
            except Exception:  # a signal or function that cannot be evaluated there: not evidence either way
                continue
            if not np.all(np.isfinite(A)):
                continue
            if A.shape[0] != size:  # the caller's matrix is M alone: the same coordinates, no multipliers
                A = A[:size, :size]
            d = constraint_scales(A, self._multipliers(A.shape[0]))
            sv = np.linalg.svd(A * d[:, None] * d[None, :], compute_uv=False)
            if sv[-1] > 1e-10 * sv[0]:
                return False
            seen += 1
            if seen == probes:
                return True
        return False

    def velocities(self, time: float, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """All generalized velocities and the inertial accelerations at one state."""
        qv, vI = y[: self.n], y[self.n :]
        u = self.solve(time, qv, vI)
        v = np.empty(self.n)
        v[self.eq.inertial] = vI
        v[self.eq.first_order] = u[self.nI : self.nI + len(self.eq.first_order)]
        return v, u[: self.nI]

    def velocities_many(self, times: np.ndarray, Y: np.ndarray) -> np.ndarray:
        """All generalized velocities at many states ``Y`` (columns), with one batched solve (none when every
        coordinate is inertial: the velocities are then part of the state)."""
        n, N = self.n, times.size
        if not self.eq.first_order:
            v = np.empty((n, N))
            v[self.eq.inertial] = Y[n:]
            return v
        if self._fast is not None:
            return self._fast.velocities_many(times, Y)
        v = np.empty((n, N))
        v[self.eq.inertial] = Y[n:]
        if self._flat_fn is None:
            a_entries, b_entries, args, signals = self._flat_exprs
            self._flat_fn = _lambdify(args, a_entries + b_entries, signals)
        m = self.eq.A.shape[0]  # unknowns: accelerations, first-order rates, multipliers
        out = [np.broadcast_to(np.asarray(e, dtype=float), (N,)) for e in self._flat_fn(times, Y[:n], Y[n:])]
        A = np.stack(out[: m * m], axis=-1).reshape(N, m, m)
        b = np.stack(out[m * m :], axis=-1)
        d = constraint_scales(A, self._multipliers(m))
        S = A * d[..., :, None] * d[..., None, :]
        try:
            u = d * np.linalg.solve(S, (d * b)[..., None])[..., 0]
        except np.linalg.LinAlgError:
            k = next(i for i in range(N) if np.linalg.matrix_rank(S[i]) < m)
            raise SingularMassMatrixError(self._singular_message(times[k], A[k], Y[:n, k])) from None
        v[self.eq.first_order] = u[:, self.nI : self.nI + len(self.eq.first_order)].T
        return v

    def rhs(self, time: float, y: np.ndarray) -> np.ndarray:
        if self._fast is not None:
            return self._fast.rhs(time, y)
        v, acc = self.velocities(time, y)
        return np.concatenate([v, acc])

    def evaluate(self, expr: Any, res: Result) -> np.ndarray:
        """An expression in ``q(t)``, ``q̇(t)``, ``t`` and parameters, along a result of this model (a matrix of them:
        an array of its shape followed by the time's); :class:`~lagrangian.ExpressionError` for one that is not a
        finite real number."""
        eq = self.eq
        if isinstance(expr, sp.MatrixBase):  # entry by entry
            out = np.empty(expr.shape + res.t.shape)
            for (i, j), entry in np.ndenumerate(np.array(expr.tolist(), dtype=object).reshape(expr.shape)):
                out[i, j] = self.evaluate(entry, res)
            return out
        given = expr
        if isinstance(expr, str):  # text: coordinate names stand for the coordinates, parameters for their values
            names = {c.name: c.function for c in eq.coordinates} | {s.name: s for s in self.values}
            expr = parse_expression(expr, "the quantity", names=names)
        else:
            expr = as_expr(expr, "the quantity")
        accelerations = sorted((d for d in expr.atoms(sp.Derivative) if d.derivative_count > 1), key=str)
        if accelerations:
            d = accelerations[0]
            named = d.expr.func.__name__ + "'" * d.derivative_count if isinstance(d.expr, sp.core.function.AppliedUndef) else sp.sstr(d)
            raise ModelError(f"the quantity {sp.sstr(expr)[:80]!r} holds an acceleration ({named}), "
                             f"and a result holds coordinates and rates only: give a quantity of those, or the "
                             f"accelerations' expression from the equations of motion.")
        plain = eq.symbolic(expr)
        bad = plain.free_symbols - set(eq.sym.q) - set(eq.sym.v) - {t} - set(self.values)
        if bad:
            raise ModelError(f"cannot evaluate {expr}: {', '.join(sorted(map(str, bad)))} are not coordinates, rates or parameters.")
        plain = plain.xreplace({s: sp.Float(v) for s, v in self.values.items()})
        shown = given if isinstance(given, str) else sp.sstr(expr)
        shown = repr(shown if len(shown) <= 80 else shown[:77] + "...")
        if plain.has(sp.zoo, sp.oo, -sp.oo, sp.nan):
            raise ExpressionError(f"the quantity {shown} is not finite ({sp.sstr(plain)[:60]}): write one that is "
                                  f"(no division by zero).")
        huge = [r for r in plain.atoms(sp.Number) if not np.isfinite(float(r))]
        if huge:
            raise ExpressionError(f"the quantity {shown} holds the number {str(huge[0])[:30]}..., beyond a float "
                                  f"(±1.8e308): write it in units that keep it finite.")
        fn = _lambdify((t, eq.sym.q, eq.sym.v), plain, self.signals)
        q = np.array([res.q[n] for n in eq.names])
        v = np.array([res.v[n] for n in eq.names])
        with np.errstate(all="ignore"):
            try:
                value = np.asarray(fn(res.t, q, v))
            except (ZeroDivisionError, OverflowError, FloatingPointError) as exc:
                raise ExpressionError(f"the quantity {shown} cannot be evaluated along the result ({exc}).") from None
        if np.iscomplexobj(value):
            if np.any(value.imag != 0):
                raise ExpressionError(f"the quantity {shown} takes complex values along the result: write a real one "
                                      f"(sqrt and log of negative numbers are complex; take abs() first).")
            value = value.real
        try:
            out = np.asarray(value, dtype=float)
        except (TypeError, ValueError, OverflowError):
            raise ExpressionError(f"the quantity {shown} does not evaluate to real numbers along the result.") from None
        return np.broadcast_to(out, res.t.shape).copy()

    def energies(self, time: np.ndarray, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, ...]:
        if self._fast is not None:
            return self._fast.energies(time, q, v)
        if self._energy_tape is not None:  # (a recursion's energies: the tape's steps, not the trees of T and V)
            times = np.broadcast_to(np.asarray(time, dtype=float), np.shape(q)[1:])
            out = self._energy_tape.evaluate_many(np.vstack([times[None], np.asarray(q, float), np.asarray(v, float)]))
            return tuple(np.array(out[k]) for k in range(3))
        out = self._energy_fn(time, q, v)
        return tuple(np.broadcast_to(np.asarray(e, dtype=float), time.shape).copy() for e in out)

    @functools.cached_property
    def _energy_tape(self):
        """The energy tape of a model its recursion serves (NumPy on every point at once), or None: the energies
        of a tree written out as expressions (lambdified, walked as trees) grow exponentially with its depth."""
        if self.eq.recursion is None:
            return None
        try:
            return programs(self)[1]
        except _Unavailable:  # (Python-callable signals: the expressions, as for any other model)
            return None


def initial_state(
    eq: Equations, initial: Mapping[str, float], velocity: Mapping[str, float], *, warn: bool = True
) -> tuple[np.ndarray, list[str]]:
    """The state vector ``(q, q̇_inertial)`` from initial values by name; missing ones are zero and reported."""
    names = eq.names
    refuse_eliminated(getattr(eq, "eliminated", {}), getattr(eq, "values", None), initial=initial, velocity=velocity)
    for label, given in (("coordinate", initial), ("coordinate", velocity)):
        for name in given:
            if name not in names:
                raise UnknownNameError(label, name, names)
    first = [names[i] for i in eq.first_order]
    for name in velocity:
        if name in first:
            raise ModelError(
                f"coordinate {name!r} is first-order (it has no inertia): its velocity follows from the equations "
                f"and cannot be given as an initial condition."
            )
    inertial = [names[i] for i in eq.inertial]

    def number(given: Mapping[str, float], name: str, what: str) -> float:
        value = given.get(name, 0.0)
        try:
            out = float(value)
        except (TypeError, ValueError):
            raise ModelError(f"initial {what} of {name!r} must be a number, got {value!r:.80}.") from None
        except OverflowError:  # an integer (or fraction) beyond a float
            raise ModelError(f"initial {what} of {name!r} must be finite (within ±1.8e308), "
                             f"got {value!r:.40}.") from None
        if not np.isfinite(out):
            raise ModelError(f"initial {what} of {name!r} must be finite, got {value!r}.")
        return out

    y0 = [number(initial, n, "value") for n in names] + [number(velocity, n, "velocity") for n in inertial]
    defaulted = [n for n in names if n not in initial] + [f"{n}'" for n in inertial if n not in velocity]
    if defaulted and warn:
        _warn(
            f"initial conditions not given, set to zero: {', '.join(defaulted[:40])}"
            + (f", … ({len(defaulted) - 40} more)" if len(defaulted) > 40 else ""), InitialConditionWarning
        )
    return np.array(y0), defaulted


def check_start(numeric: NumericModel, model: str, t0: float, y0: np.ndarray, *, params: Mapping[str, Any] | None = None,
                tol: float = 1e-8) -> None:
    """Refuse an initial state that violates the model's constraints on positions (loop closures, a rolling body's
    height) or on velocities, or the rates of those on positions: a :class:`ModelError` naming the components.

    The constraints are the generic ones, with ``numeric``'s parameter values put in: those of the run (another value
    given in ``params=`` to a parameter given as a number counts, as it does in the equations); ``params``, the run's,
    go into the advice the refusal gives."""
    eq = numeric.eq
    if not len(eq.constraints) and not len(eq.velocity_constraints):
        return
    q, v = eq.sym.q, eq.sym.v
    generic = eq.generic()
    subs = {s: sp.Float(x) for s, x in numeric.values.items()}
    v0, _ = numeric.velocities(t0, y0)
    point = {**dict(zip(q, y0[: numeric.n])), **dict(zip(v, v0)), t: t0}

    def sizes(jacobian: sp.Matrix) -> list[float]:
        """The largest entry of each constraint's gradient at the start (1 where it is zero or cannot be had): what
        its violation is measured against, so that a constraint written as ``1e-12·(x_a − x_b)`` or
        ``1e30·(x_a − x_b)`` is held to the same distance from the start as ``x_a − x_b`` is."""
        out = []
        for k in range(jacobian.rows):
            try:
                big = max((abs(float(g.xreplace(point))) for g in jacobian.row(k) if g != 0), default=0.0)
            except (TypeError, ValueError, ArithmeticError):
                big = 0.0
            out.append(big if 0.0 < big < np.inf else 1.0)
        return out

    if len(eq.velocity_constraints):  # nonholonomic: the start's rates must satisfy them
        c = generic["velocity_constraints"].xreplace(subs)
        raw = [abs(float(e.xreplace(point))) for e in c]
        gaps = [g / size for g, size in zip(raw, sizes(c.jacobian(v)))]
        held = sorted({o for o, g in zip(eq.velocity_owners, gaps) if g > tol})
        if held:
            raise ModelError(
                f"the initial rates of model {model!r} violate the constraints on velocities of "
                f"{', '.join(map(repr, held))} (|c| = {max(raw):.3g}): give rates that satisfy "
                f"{'; '.join(f'{eq.display(e)} = 0' for e, g in zip(c, gaps) if g > tol)}.")
    if not len(eq.constraints):
        return
    Phi = generic["constraints"].xreplace(subs)
    J = Phi.jacobian(q)
    rate = J * sp.Matrix(v) + Phi.diff(t)
    gaps = [max(abs(float(a.xreplace(point))), abs(float(b.xreplace(point)))) / size
            for a, b, size in zip(Phi, rate, sizes(J))]
    gap = max(abs(float(e.xreplace(point))) for e in Phi)
    gap_rate = max(abs(float(e.xreplace(point))) for e in rate)
    if max(gaps) > tol:
        owners = getattr(eq, "constraint_owners", [None] * len(gaps))
        held = sorted({owner for owner, g in zip(owners, gaps) if owner and g > tol})
        what = "its kinematic loops" if not held else (
            f"the constraints of {', '.join(repr(h) for h in held)}"
            + (" and its kinematic loops" if any(o is None and g > tol for o, g in zip(owners, gaps)) else ""))
        raise ModelError(
            f"the initial state of model {model!r} does not satisfy {what} (|Φ| = {gap:.3g}, "
            f"|dΦ/dt| = {gap_rate:.3g}): solve the dependent coordinates first with "
            f"lagrangian.plugins.multibody.consistent_initial(model, initial, velocity{', params=params' if params else ''})."
        )
