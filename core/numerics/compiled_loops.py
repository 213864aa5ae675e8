"""Integrators whose stepping loop is C: ``DOP853`` (where it can), ``dop853_c``, ``dopri5_c``, ``rk4_c``, ``verlet_c``.

The loops live in the runtime library of :mod:`lagrangian.codegen` and call
a model's compiled right-hand side (its tape or its native library) without
returning to Python per step.  The built-in integrators plugin registers
them; each falls back to its Python sibling (``DOP853_scipy``, ``RK45``,
``rk4``, ``verlet``) when the model cannot be compiled, with a note except
for ``DOP853``, whose loop in C is how it runs, not what was asked.

A whole run's loop is watched (:func:`_watched`): progress is reported, Ctrl-C
stops it, and ``max_evaluations`` bounds it, as for a run stepped in Python.
A long run (or one asked for its progress) runs on a thread of its own,
watched from the caller's; a short one on the caller's, no thread started,
under a deadline past which it goes to a thread of its own.

Runs with events (:mod:`lagrangian.numerics.events`) take the same C steps
one at a time: ``DOP853`` and ``dopri5_c`` through
:meth:`CompiledDormandPrince.start` (one accepted step per call, its dense
output evaluated in C for the event search), ``rk4_c`` and ``verlet_c`` through
:meth:`CompiledFixedStep.stepper` (one step of any length per call).
"""

from __future__ import annotations

import functools
import logging
import math
import os
import threading
import time

import numpy as np

from .codegen import CompiledModel
from ..errors import IntegrationError, ModelError
from ..plugin.contracts import Integrator, Solution
from .fixed_step import FixedStepIntegrator, Stepper, _grid

_log = logging.getLogger("lagrangian")



def _compiled_or_note(problem, name: str, sibling) -> tuple[CompiledModel | None, str | None]:
    compiled = problem.numeric.compile()
    if compiled is None:
        note = (f"{name}: {problem.numeric.compile_note}; ran its Python sibling "
                f"{getattr(sibling, 'name', sibling)!r} instead")
        _log.info(note)
        return None, note
    return compiled, None


#: Seconds between two looks at a loop in C that runs on its own thread (progress, an interrupt).
POLL = 0.05
#: A loop in C runs first on the caller's thread, no thread started (a thread's start and join cost a warm run of a
#: few steps ten times its C, more on a busy machine): one still running after SHORT seconds is stopped there and run
#: again from its start on a thread of its own, watched as :func:`_watched` says.  Ctrl-C (or another signal whose
#: handler raises) during those first SHORT seconds takes effect once they are over.
SHORT = 0.02
#: A fixed-step loop in C known to need more evaluations than this goes to its own thread at once.
SHORT_EVALUATIONS = 20_000
#: Kinds of run (model name and size, method, time span, tolerance or step) found long: the next one goes straight to
#: a thread of its own.  A hint only (a wrong one costs a thread's start), kept for at most _LONG_KEPT kinds.
_LONG: dict[tuple, None] = {}
_LONG_KEPT = 256


class _Deadlines:
    """The process's one thread that stops loops in C run on their caller's thread once they pass their deadline
    (it sets ``watch[1]``, as Ctrl-C does for a loop on a thread of its own).  Started on first use; while no such
    loop runs it waits on a condition (no polling), and while one runs it wakes at that loop's deadline only.  An
    entry left behind (an interrupt between a loop's return and its removal) is dropped at its deadline."""

    def __init__(self) -> None:
        self._cond = threading.Condition(threading.Lock())
        self._runs: dict[int, tuple[float, np.ndarray]] = {}
        self._thread: threading.Thread | None = None
        self._due = math.inf  # the deadline the thread waits for (inf: idle)

    def add(self, watch: np.ndarray, seconds: float) -> None:
        deadline = time.monotonic() + seconds
        with self._cond:
            self._runs[id(watch)] = (deadline, watch)
            if self._thread is None:
                self._thread = threading.Thread(target=self._loop, name="lagrangian-deadlines", daemon=True)
                self._thread.start()
            elif deadline < self._due:
                self._cond.notify()

    def remove(self, watch: np.ndarray) -> None:
        with self._cond:
            self._runs.pop(id(watch), None)

    def _loop(self) -> None:
        with self._cond:
            while True:
                now = time.monotonic()
                for key, (deadline, watch) in list(self._runs.items()):
                    if deadline <= now:
                        watch[1] = 1.0  # the loop stops after its current step
                        del self._runs[key]
                self._due = min((d for d, _ in self._runs.values()), default=math.inf)
                self._cond.wait(None if self._due == math.inf else self._due - now)


_DEADLINES = _Deadlines()
if hasattr(os, "register_at_fork"):  # a forked child has no such thread, and perhaps a lock held at the fork
    os.register_at_fork(after_in_child=_DEADLINES.__init__)


def _watched(run, problem, key=None, expected: float = 0.0):
    """``run(watch=...)``, a loop in C, interruptible (Ctrl-C) and watched (progress) as a run stepped in Python is.

    A run asked for its ``progress``, one known to be long (``expected`` evaluations beyond
    :data:`SHORT_EVALUATIONS`, or a run of this ``key`` of a model of this name stopped at its deadline before) runs
    on a thread of its own (:func:`_on_thread`).  Any other runs on the caller's thread with no thread started: a call
    from the main thread with a deadline of :data:`SHORT` seconds, past which it is stopped and run again from its
    start on a thread of its own (the same steps, so the same numbers); a call from another thread without one
    (Python delivers signals to the main thread only, so no interrupt can reach it there)."""
    if getattr(problem, "_report", None) is not None or expected > SHORT_EVALUATIONS:
        return _on_thread(run, problem)
    if threading.current_thread() is not threading.main_thread():
        return run(watch=None)
    if key is not None:
        key = (getattr(problem, "name", None), getattr(problem, "dim", None), *key)
        if key in _LONG:
            return _on_thread(run, problem)
    watch = np.zeros(2)
    _DEADLINES.add(watch, SHORT)
    try:
        out = run(watch=watch)
    finally:
        _DEADLINES.remove(watch)
    if not watch[1]:
        return out
    # past its deadline (or, rarely, stopped just as it ended): from the start, where Ctrl-C can stop it
    if key is not None:
        if len(_LONG) >= _LONG_KEPT:
            del _LONG[next(iter(_LONG))]  # the oldest
        _LONG[key] = None
    return _on_thread(run, problem)


def _on_thread(run, problem):
    """``run(watch=...)`` (a loop in C) on a thread of its own, while this one reports its progress and, on an
    interrupt (Ctrl-C), asks it to stop and raises ``KeyboardInterrupt`` once it has: a long run in C stays as
    interruptible, and as watched, as one stepped in Python.  The loop needs no Python (ctypes releases the GIL)."""
    watch = np.zeros(2)
    out: list = []

    def target():
        try:
            out.append(run(watch=watch))
        except BaseException as exc:  # raised again on the caller's thread (a singular mass matrix, ...)
            out.append(exc)

    thread = threading.Thread(target=target, name="lagrangian-loop", daemon=True)
    thread.start()
    try:
        while True:
            thread.join(POLL)
            if not thread.is_alive():
                break
            problem.report(float(watch[0]))  # the end is reported by the caller
    except KeyboardInterrupt:
        watch[1] = 1.0
        thread.join()
        raise
    if isinstance(out[0], BaseException):
        raise out[0]
    return out[0]


#: Evaluations beyond which a run on the tape says that native code would be worth its compilation.
LONG_RUN = 500_000


def _long_run_hint(compiled: CompiledModel, nfev: int) -> list[str]:
    if compiled.kind != "tape" or nfev < LONG_RUN:
        return []
    return [f"a long run ({nfev} evaluations): compiled=True builds native code for this model, about twice as fast "
            f"per evaluation as the tape, compiled once (0.1–0.5 s) and then kept in the cache for every later run"]


class CompiledSteps:
    """``dopri5_c`` or ``dop853_c`` one accepted step at a time: the interface of SciPy's ``OdeSolver`` that the
    events driver uses (``step()``, ``status``, ``t_old``, ``t``, ``y``, ``dense_output()``), each step and each
    dense-output evaluation one call into C."""

    def __init__(self, compiled: CompiledModel, problem, name: str, t0: float, y0, t_bound: float, *, rtol: float,
                 atol: float, max_step: float, first_step: float | None, variant: str = "dopri5"):
        dim = compiled.dim
        self._c, self._problem, self.name, self._dim = compiled, problem, name, dim
        self._variant = variant
        self._work = np.zeros((30 if variant == "dop853" else 13) * max(dim, 1))
        self._work[:dim] = y0
        self._scalars = np.zeros(3)  # next step to try, the last step's length, its end
        self._counts = np.zeros(2, dtype=np.int64)  # nfev, rejected steps
        self._fail = np.zeros(dim + 1)
        self._ptrs = [a.ctypes.data for a in (self._work, self._scalars, self._counts, self._fail)]
        self._tol = (float(rtol), float(atol), float(max_step) if math.isfinite(max_step) else 1e300)
        self.t = self.t_old = float(t0)
        self.t_bound = float(t_bound)
        self.y = np.array(y0, dtype=float)
        self._limit = 1e30 * max(1.0, float(np.max(np.abs(self.y), initial=0.0)))
        self._shift, self._seen, self.notes = 0, 0, []
        self.status = "running" if self.t < self.t_bound else "finished"
        work, scalars, counts, fail = self._ptrs
        if variant == "dop853":
            rc = compiled.loops.lg_dop853_begin(compiled._rhs_ptr, compiled._ctx, dim, self.t, self.t_bound,
                                                self._tol[0], self._tol[1], self._tol[2], float(first_step or 0.0), work,
                                                scalars, counts, fail)
        else:
            rc = compiled.loops.lg_dopri5_begin(compiled._rhs_ptr, compiled._ctx, dim, self.t, self.t_bound,
                                                self._tol[0], self._tol[1], float(first_step or 0.0), work, scalars,
                                                counts, fail)
        self._count()
        if rc:
            compiled._raise(rc, self.t, self.y)

    def _count(self) -> None:
        self._problem.nfev += int(self._counts[0]) - self._seen
        self._seen = int(self._counts[0])

    def step(self) -> str | None:
        """One accepted step; ``None``, or the message of a failure (then ``status`` is ``"failed"``)."""
        c, (work, scalars, counts, fail) = self._c, self._ptrs
        step = c.loops.lg_dop853_step if self._variant == "dop853" else c.loops.lg_dopri5_step
        rc = step(c._rhs_ptr, c._ctx, self._dim, self._shift, self.t, self.t_bound, *self._tol, work, scalars,
                  scalars + 8, scalars + 16, counts, fail)
        self._shift = 1
        self._count()
        if rc:
            self.status = "failed"
            return c._run(rc, self._fail, self.name)
        self.t_old, self.t = self.t, float(self._scalars[2])
        self.y = self._work[self._dim: 2 * self._dim].copy()
        if not np.all(np.abs(self.y) < self._limit):
            self.status = "failed"
            return f"the state diverged (beyond 1e30 times its initial size, or non-finite) by t={self.t:g}"
        self._problem.report(self.t)
        if getattr(self._problem, "_pace", None) is not None:
            self._problem._check_pace(self.t)
        if self.t >= self.t_bound:
            self.status = "finished"
        return None

    def dense_output(self):
        """The last step's dense output (quartic; of order 7 for ``dop853_c``, which evaluates the model three more
        times for it), ``state(s)`` for ``t_old ≤ s ≤ t``."""
        c, hstep, t_old, t_new, y_new, dim = self._c, float(self._scalars[1]), self.t_old, self.t, self.y, self._dim
        if self._variant == "dop853":
            work, scalars, counts, fail = self._ptrs
            rc = c.loops.lg_dop853_prepare(c._rhs_ptr, c._ctx, dim, t_old, hstep, work, counts, fail)
            self._count()
            if rc:
                c._raise(rc, t_old, self.y)
            work = self._work.copy()
            ptr = work.ctypes.data

            def state(s: float, _work: np.ndarray = work) -> np.ndarray:  # _work: the C code reads it through ptr
                if s == t_new:
                    return y_new.copy()
                out = np.empty(dim)
                c.loops.lg_dop853_dense(dim, ptr, (s - t_old) / hstep, out.ctypes.data)
                return out

            return state
        work = self._work.copy()
        dense, ptr = c.loops.lg_dopri5_dense, work.ctypes.data

        def state(s: float, _work: np.ndarray = work) -> np.ndarray:  # _work: the C code reads it through ptr
            if s == t_new:
                return y_new.copy()
            out = np.empty(dim)
            dense(dim, ptr, hstep, (s - t_old) / hstep, out.ctypes.data)
            return out

        return state


class CompiledDormandPrince(Integrator):
    """Dormand–Prince 5(4) (scipy's ``RK45``), or with ``variant="dop853"`` Hairer's 8(5,3) (scipy's ``DOP853``),
    with its whole stepping loop in C.

    The same pair, error norm, step-size control and initial step as
    :class:`scipy.integrate.RK45` (:class:`scipy.integrate.DOP853`), and its
    dense output at the output times (quartic; of order 7), so it takes the
    same steps as SciPy's method up to rounding; no Python runs per step.
    Needs a C compiler: without one (or for a model with Python-callable
    signals) it runs ``fallback`` (``RK45``, ``DOP853``) and says so in
    ``Result.notes``.
    """

    kind = "adaptive"
    order = 5
    needs_compiled = True
    symplectic = implicit = stiff = False
    first_order = True
    options = {"first_step": "initial step size (default: chosen as scipy does)"}

    def __init__(self, fallback: Integrator, name: str = "dopri5_c", variant: str = "dopri5", *, quiet: bool = False):
        if variant not in ("dopri5", "dop853"):
            raise ModelError(f"CompiledDormandPrince: variant must be 'dopri5' or 'dop853', got {variant!r}.")
        self.name, self.fallback, self.variant = name, fallback, variant
        # quiet: the method by its own name (DOP853), which runs in C where it can and as SciPy's otherwise, without
        # a note — compiled code is how it runs, not what was asked (a note comes from compiled=True unmet)
        self.quiet, self.needs_compiled = quiet, not quiet
        self.order = 8 if variant == "dop853" else 5
        self.description = ("Dormand–Prince 5(4) (as RK45)" if variant == "dopri5" else "explicit Runge–Kutta of order 8 "
                            "(as DOP853)") + " with the stepping loop compiled to C; explicit, adaptive"
        if quiet:
            self.description = (f"explicit Runge–Kutta of order {self.order}, SciPy's steps; the stepping loop in C "
                                f"where the model has compiled code, else {fallback.name}")

    def _compiled(self, problem, atol):
        """The model's compiled code and the note of a fallback (``None`` for a quiet one, which also runs its
        fallback for ``compiled=False``); ``atol`` as one number (the loop in C takes no per-state ones)."""
        if self.quiet and getattr(problem.numeric, "python_only", False):
            return None, None, atol
        tol = np.asarray(atol, dtype=float)
        if tol.ndim and tol.size and np.all(tol == tol.flat[0]):
            atol = float(tol.flat[0])
        elif tol.ndim:
            note = f"{self.name}: a per-state atol; ran {self.fallback.name!r} instead (the loop in C takes one atol)"
            return None, None if self.quiet else note, atol
        compiled, note = _compiled_or_note(problem, self.name, self.fallback)
        return compiled, None if self.quiet else note, atol

    def solve(self, problem, t_span, y0, t_eval, *, rtol=1e-9, atol=1e-12, max_step=np.inf, first_step=None):
        """Integrate in C (see the class documentation)."""
        compiled, note, atol = self._compiled(problem, atol)
        if compiled is None:
            sol = self.fallback.solve(problem, t_span, y0, t_eval, rtol=rtol, atol=atol, max_step=max_step, first_step=first_step)
            if note:
                sol.notes.insert(0, note)
            return sol
        if not (rtol > 0 and atol >= 0):
            raise ModelError(f"{self.name}: rtol must be positive and atol non-negative, got rtol={rtol!r}, atol={atol!r}.")
        if not (max_step > 0):
            raise ModelError(f"{self.name}: max_step must be positive, got {max_step!r}.")
        if first_step is not None and not (0 < first_step <= t_span[1] - t_span[0]):
            raise ModelError(f"{self.name}: first_step must be positive and within the time span, got {first_step!r}.")
        pace = getattr(problem, "_pace", None)
        run = functools.partial(compiled.dopri5, t_span, y0, t_eval, rtol=rtol, atol=atol, max_step=max_step,
                                first_step=first_step, variant=self.variant, budget=pace[4] if pace else 0.0)
        key = (self.name, float(t_span[0]), float(t_span[1]), float(rtol))  # runs alike in length, as a hint
        Y, nfev, nstep, status, message, reached = _watched(run, problem, key)
        if status == 6:  # judged on its pace in C, refused as in Python
            raise problem.pace_error(reached, nfev, nfev * (t_span[1] - t_span[0]) / (reached - t_span[0]))
        problem.nfev += nfev
        problem.report(float(t_span[1]))
        done = np.all(np.isfinite(Y), axis=0)
        count = int(np.argmin(done)) if not done.all() else t_eval.size
        notes = [f"{self.name}: {nstep} steps in compiled code, the model evaluated by {compiled.describe()}",
                 *_long_run_hint(compiled, nfev)]
        return Solution(np.asarray(t_eval)[:count], Y[:, :count], nfev, -1 if message else 0, message, notes)

    def start(self, problem, t0, y0, t_bound, *, rtol=1e-9, atol=1e-12, max_step=np.inf, first_step=None):
        """The same steps one at a time, for the events driver (:class:`CompiledSteps`); without compiled code,
        the Python sibling's solver, with the note in its ``notes``."""
        compiled, note, atol = self._compiled(problem, atol)
        if compiled is None:
            solver = self.fallback.start(problem, t0, y0, t_bound, rtol=rtol, atol=atol, max_step=max_step,
                                         first_step=first_step)
            solver.notes = [note] if note else []
            return solver
        return CompiledSteps(compiled, problem, self.name, t0, y0, t_bound, rtol=rtol, atol=atol, max_step=max_step,
                             first_step=first_step, variant=self.variant)


class CompiledFixedStep(FixedStepIntegrator):
    """A fixed-step method whose stepping loop is C: ``rk4`` (classical Runge–Kutta) or ``verlet`` (Störmer–Verlet).

    The same steps as the Python sibling ``fallback`` (uniform ``h`` from
    ``step``, outputs on the steps or by cubic Hermite interpolation between
    them), the same refusals (``fallback.check``: Störmer–Verlet refuses
    models that are not separable).  Without a C compiler it runs
    ``fallback`` and says so in ``Result.notes``.  Linear models are not
    advanced by powers of the one-step map: every step is taken.
    """

    def __init__(self, method: str, fallback: FixedStepIntegrator):
        if method not in ("rk4", "verlet"):
            raise ModelError(f"CompiledFixedStep: method must be 'rk4' or 'verlet', got {method!r}.")
        self.method, self.fallback, self.name = method, fallback, f"{method}_c"
        self.needs_compiled = True
        for attr in ("order", "symplectic", "implicit", "stiff", "first_order"):
            setattr(self, attr, getattr(fallback, attr))
        self.options = {}
        self.description = f"{fallback.description}; stepping loop compiled to C"

    def check(self, problem):
        """The sibling's refusals, under this method's name."""
        try:
            self.fallback.check(problem)
        except ModelError as exc:
            raise ModelError(str(exc).replace(f"{self.fallback.name} (", f"{self.name} (", 1)) from None

    def stepper(self, problem, h, **options):
        """One step of length ``h`` in C (the events driver steps with this); the sibling's without compiled code."""
        compiled, note = _compiled_or_note(problem, self.name, self.fallback)
        if compiled is None:
            stepper = self.fallback.stepper(problem, h, **options)
            stepper.notes = [note]
            return stepper
        self.check(problem)
        dim, code = compiled.dim, {"rk4": 0, "verlet": 1}[self.method]
        work, counts, fail = np.zeros(8 * max(dim, 1)), np.zeros(1, dtype=np.int64), np.zeros(dim + 1)
        ptrs = (work.ctypes.data, counts.ctypes.data, fail.ctypes.data)
        step_c, name = compiled.loops.lg_fixed_step, self.name

        def step(t: float, y: np.ndarray) -> np.ndarray:
            work[:dim] = y
            before = int(counts[0])
            rc = step_c(compiled._rhs_ptr, compiled._ctx, compiled.n, dim, code, float(t), float(h), *ptrs)
            problem.nfev += int(counts[0]) - before
            if rc:
                compiled._run(rc, fail, name)  # a singular mass matrix raises; anything else is a state that is not finite
                return np.full(dim, np.nan)
            return work[dim: 2 * dim].copy()

        return Stepper(step)

    def solve(self, problem, t_span, y0, t_eval, *, step=None, fast_linear=True, **options):
        """Integrate in C with uniform steps of at most ``step`` (``fast_linear`` is accepted and ignored)."""
        compiled, note = _compiled_or_note(problem, self.name, self.fallback)
        if compiled is None:
            sol = self.fallback.solve(problem, t_span, y0, t_eval, step=step, fast_linear=fast_linear, **options)
            sol.notes.insert(0, note)
            return sol
        t0, t1 = map(float, t_span)
        t_eval = np.asarray(t_eval, dtype=float)
        h, N, notes = _grid(self.name, problem, t0, t1, t_eval, step, np.asarray(y0, dtype=float))
        pace = getattr(problem, "_pace", None)
        needed = N * (4 if self.method == "rk4" else 1) + 1
        if pace is not None and needed > pace[4]:  # its evaluations are known before it starts
            raise IntegrationError(
                f"{self.name}: {N} steps of {h:.3g} over [{t0:g}, {t1:g}] need {needed} evaluations, more than the "
                f"run's budget (max_evaluations={pace[4]:.3g}): take a longer step= or allow more evaluations.")
        Y, nfev, message = _watched(functools.partial(compiled.fixed, self.method, t0, h, N, y0, t_eval), problem,
                                    (self.name, t0, t1, h), expected=needed)
        problem.nfev += nfev
        problem.report(t1)
        done = np.all(np.isfinite(Y), axis=0)
        count = int(np.argmin(done)) if not done.all() else t_eval.size
        k = (t_eval - t0) / h
        between = int(np.sum(np.abs(k - np.rint(k)) >= 1e-7))
        if between:
            notes.append(f"{between} output time(s) fall between steps: cubic Hermite interpolation (error O(h⁴))")
        notes.append(f"{self.name}: {N} steps in compiled code, the model evaluated by {compiled.describe()}")
        notes += _long_run_hint(compiled, nfev)
        return Solution(t_eval[:count], Y[:, :count], nfev, -1 if message else 0, message, notes, h)
