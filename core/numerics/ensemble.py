"""One model, many sets of parameter values: compiled once, run anywhere (the engine of :mod:`lagrangian.sweep`).

:func:`compile_form` turns a model's equations into a :class:`CompiledForm`:
a picklable object holding its native library — its tapes printed as C that
reads the parameter values at run time from an array
(:func:`lagrangian.numerics.c_source.parametric_source`), so that one
library serves every set of values — and the runtime library with the
stepping loops, both as source and as compiled bytes, plus a tape of the
outputs asked for.  A process that receives it (a Dask worker, on this
machine or another) loads the libraries once (:func:`bind`; from its own
cache, else from the bytes shipped, else by compiling the source shipped)
and runs samples with :func:`run_chunk`: nothing is derived or recorded
again, and SymPy is never called.

Each sample is one run of the Dormand–Prince loop in C (``DOP853`` or
``dopri5``, as ``Model.simulate`` runs them) from its own initial state
with its own parameter vector.  A sample that fails (a singular mass
matrix, a diverging state, a run beyond its budget of evaluations) is
recorded with its message and does not stop the others.
"""

from __future__ import annotations

import ctypes
import math
import threading
import uuid
from collections import OrderedDict
from dataclasses import dataclass, field

import numpy as np

from ..base.component import t as time_symbol
from ..errors import ModelError
from .c_build import _cache, _key, _libraries, _shipped, check_key, compiler
from .c_source import _runtime_source, _Unavailable, parametric_source, solve_size
from .codegen import _prog
from .tape import Program, TapeError, record
from ..base import deferred as _deferred

sp = _deferred.module("sympy", globals())

__all__ = ["CompiledForm", "RunSpec", "compile_form", "bind", "run_chunk", "METHODS", "LOOP_MESSAGES"]

#: The stepping loops a compiled form runs (the names of ``Model.simulate``'s integrators that step in C).
METHODS = ("DOP853", "dopri5")

#: What a loop's status means (as :meth:`lagrangian.codegen.CompiledModel._run` says it for one run).
LOOP_MESSAGES = {
    1: "the mass matrix is singular at t={t:g}",
    2: "the equations became non-finite at t={t:g}",
    3: "the step size fell below the resolution of t at t={t:g} (the model may be stiff or singular there)",
    4: "the state diverged (beyond 1e30 times its initial size, or non-finite) by t={t:g}",
    5: "out of memory for the stepping loop",
    6: "stopped at t={t:g}: at its pace the run would need more evaluations than its budget (max_evaluations)",
    7: "interrupted at t={t:g}",
}


@dataclass(frozen=True)
class Library:
    """A shared library shipped by value: its cache key, its C source and, when built here, its bytes."""

    key: str
    source: str
    data: bytes | None


@dataclass(frozen=True)
class CompiledForm:
    """A model's equations compiled once for any parameter values (see the module's text).

    ``parameters`` names the entries of a parameter vector (``values`` are
    the model's own), ``outputs`` the outputs of ``output_tape`` (a tape from
    ``(t, q, q̇)``), ``checks`` a tape of the loop-closure residuals and their
    rates (``None`` without loops); ``conservative`` says whether the Jacobi
    integral is an integral of motion (its drift is then reported).
    """

    name: str
    coordinates: tuple[str, ...]
    inertial: tuple[int, ...]
    first: tuple[int, ...]
    m: int
    parameters: tuple[str, ...]
    values: tuple[float, ...]
    outputs: tuple[str, ...]
    output_tape: Program | None
    checks: Program | None
    conservative: bool
    runtime: Library
    model: Library
    token: str = field(default_factory=lambda: uuid.uuid4().hex)

    @property
    def n(self) -> int:
        return len(self.coordinates)

    @property
    def dim(self) -> int:
        return self.n + len(self.inertial)

    def __repr__(self) -> str:
        return (f"CompiledForm({self.name!r}: {self.n} coordinates, {len(self.parameters)} parameters, "
                f"{len(self.outputs)} extra outputs, library {self.model.key})")


@dataclass(frozen=True)
class RunSpec:
    """How every sample runs: the span, the output times, the loop and its tolerances, the budget, and the
    quantities kept (``("q", i)``, ``("v", i)``, ``("T",)``, ``("V",)``, ``("D",)``, ``("E",)``, ``("h",)`` or
    ``("out", j)``, one row each)."""

    span: tuple[float, float]
    t_eval: np.ndarray
    method: str = "DOP853"
    rtol: float = 1e-9
    atol: float = 1e-12
    max_step: float = math.inf
    budget: float = 1e9
    keep: tuple[tuple, ...] = ()
    check_tol: float = 1e-8


def compile_form(eq, values: dict, *, name: str, outputs: dict[str, sp.Expr] | None = None,
                 conservative: bool = False) -> CompiledForm:
    """The compiled form of ``eq`` (:class:`~lagrangian.equations.Equations`) for parameter vectors over the
    symbols of ``values`` (symbol → the model's value), with ``outputs`` (name → expression of the plain
    symbols ``t``, ``q``, ``q̇`` and the parameters) as an extra tape.

    Raises :class:`~lagrangian.ModelError` when it cannot be compiled here: no C compiler, time signals given
    as Python callables, a function the tape does not know."""
    parameters = tuple(sorted(values, key=sp.default_sort_key))
    if len(getattr(eq, "velocity_constraints", ())):
        raise ModelError(f"model {name!r} has constraints on velocities (nonholonomic), whose start a sweep does not "
                         f"check yet: run its samples with Model.simulate, which does.")
    q, v = list(eq.sym.q), list(eq.sym.v)
    outputs = dict(outputs or {})
    cc = compiler()
    if cc is None:
        raise ModelError("sweeps run compiled code, and no C compiler was found (none of cc, gcc, clang on the PATH, "
                         "or LAGRANGIAN_CC): install one.")
    try:
        source = parametric_source(eq, parameters)
        output_tape = record(list(outputs.values()), [time_symbol, *q, *v], parameters) if outputs else None
        checks = None
        if len(eq.constraints):
            Phi = eq.generic()["constraints"]
            rate = Phi.jacobian(q) * sp.Matrix(v) + Phi.diff(time_symbol)
            checks = record([*Phi, *rate], [time_symbol, *q, *v], parameters)
    except (_Unavailable, TapeError) as exc:
        raise ModelError(f"model {name!r} cannot be compiled for a sweep: {exc}.") from None
    directory, _ = _cache()
    runtime_source = _runtime_source()
    wanted = {"runtime": ("runtime-" + _key(runtime_source, cc), runtime_source), "model": (_key(source, cc), source)}
    try:
        built = _libraries(directory, wanted, cc)
    except (_Unavailable, OSError) as exc:
        raise ModelError(f"model {name!r} could not be compiled for a sweep: {exc}.") from None
    libraries = {k: Library(key, text, built[k].data) for k, (key, text) in wanted.items()}  # the bytes loaded here
    return CompiledForm(
        name=name, coordinates=tuple(eq.names), inertial=tuple(eq.inertial), first=tuple(eq.first_order),
        m=solve_size(eq), parameters=tuple(s.name for s in parameters),
        values=tuple(float(values[s]) for s in parameters), outputs=tuple(outputs), output_tape=output_tape,
        checks=checks, conservative=bool(conservative), runtime=libraries["runtime"], model=libraries["model"],
    )


# -- in the process that runs samples ------------------------------------------------------------------------------
class _Bound:
    """A compiled form's libraries loaded in this process, with the loops' argument types set."""

    def __init__(self, form: CompiledForm):
        self.form = form
        self.runtime = _load(form.runtime)
        self.model = _load(form.model)
        dims = (ctypes.c_int * 5)()
        self.model.lg_dims(dims)
        if (dims[0], dims[1], dims[2], dims[4]) != (form.n, len(form.inertial), form.m, len(form.parameters)):
            raise ModelError(f"the library {form.model.key} does not belong to model {form.name!r}: delete it from the "
                             f"cache of this machine ({_cache()[0]}) and run again.")
        dbl, ptr, lng, cint = ctypes.c_double, ctypes.c_void_p, ctypes.c_long, ctypes.c_int
        self.rhs = self.model.lg_rhs
        self.rhs.argtypes, self.rhs.restype = [ptr, dbl, ptr, ptr], cint
        self.rhs_ptr = ctypes.cast(self.rhs, ctypes.c_void_p).value
        self.energies = self.model.lg_energies
        self.energies.argtypes, self.energies.restype = [ptr, lng, ptr, ptr, ptr, ptr], None
        rt = self.runtime
        for loop in (rt.lg_dop853, rt.lg_dopri5):
            loop.argtypes = [ptr, ptr, cint, dbl, dbl, ptr, lng, ptr, dbl, dbl, dbl, dbl, dbl, ptr, ptr, ptr, ptr]
            loop.restype = cint
        rt.lg_velocities.argtypes, rt.lg_velocities.restype = [ptr, ptr, cint, cint, lng, ptr, ptr, ptr], lng
        rt.lg_prog_eval.argtypes, rt.lg_prog_eval.restype = [ptr, lng, ptr, ptr], cint
        rt.lg_ensemble.argtypes = [cint, ptr, ptr, lng, cint, ptr, cint, cint, dbl, dbl, ptr, lng, ptr, dbl, dbl, dbl,
                                   dbl, ptr, ptr, ptr, ptr, ptr, ptr]
        rt.lg_ensemble.restype = None
        self.energies_ptr = ctypes.cast(self.energies, ctypes.c_void_p).value
        self.lock = threading.Lock()  # one sample at a time per bound form: its tapes' constants are patched

    def tape(self, program: Program | None, P: np.ndarray, rows: np.ndarray) -> np.ndarray | None:
        """``program`` with the parameter vector ``P`` in its constants, run on ``rows`` of ``(t, q, q̇)``."""
        if program is None:
            return None
        consts = program.constants.copy()
        index = {name: k for k, name in enumerate(self.form.parameters)}
        for symbol, slot in program.parameters.items():
            consts[slot] = P[index[symbol.name]]
        keep: list = []
        prog = _prog(Program(program.n_inputs, consts, program.code, program.outputs, {}), keep)
        rows = np.ascontiguousarray(rows, dtype=float)
        out = np.empty((rows.shape[0], program.n_outputs))
        if self.runtime.lg_prog_eval(ctypes.addressof(prog), rows.shape[0], rows.ctypes.data, out.ctypes.data):
            raise MemoryError("out of memory for a tape's registers")
        return out


def _load(library: Library) -> ctypes.CDLL:
    """``library`` in this process: from this machine's cache (when sound: its digest the one recorded), else from
    the bytes shipped (stored in the cache first), else compiled here from its source.  Its key is checked before
    any path is made from it (:func:`~lagrangian.numerics.c_build.check_key`)."""
    check_key(library.key)
    directory, _ = _cache()
    try:
        return _shipped(library.key, library.source, library.data)
    except (OSError, ValueError):  # not loadable here (another platform): compile the source with this machine's cc
        cc = compiler()
        if cc is None:
            raise ModelError(f"the compiled form's library {library.key} does not load on this machine and no C compiler "
                             f"was found to build it from its source: install one (cc, gcc or clang).") from None
        key = ("runtime-" if library.key.startswith("runtime-") else "") + _key(library.source, cc)
        try:
            return _libraries(directory, {"lib": (key, library.source)}, cc)["lib"][0]
        except _Unavailable as exc:
            raise ModelError(f"the compiled form's library could not be built on this machine: {exc}.") from None


_BOUND: OrderedDict[str, _Bound] = OrderedDict()
_BOUND_LOCK = threading.Lock()


def bind(form: CompiledForm) -> _Bound:
    """``form``'s libraries loaded in this process (once per form; the last 8 forms are kept)."""
    with _BOUND_LOCK:
        bound = _BOUND.get(form.token)
        if bound is None:
            bound = _BOUND[form.token] = _Bound(form)
            while len(_BOUND) > 8:
                _BOUND.popitem(last=False)
        _BOUND.move_to_end(form.token)
        return bound


@dataclass
class Chunk:
    """The samples of one chunk: ``data`` (samples × rows of ``RunSpec.keep`` × times), ``status`` (0: done,
    1: failed), ``errors`` (the message of each failed sample, else ""), ``nfev`` and, for a conservative
    model, ``drift`` (the Jacobi integral's largest relative departure; NaN otherwise)."""

    data: np.ndarray
    status: np.ndarray
    errors: list[str]
    nfev: np.ndarray
    drift: np.ndarray


def run_chunk(form: CompiledForm, P: np.ndarray, Y0: np.ndarray, spec: RunSpec) -> Chunk:
    """Run the samples whose parameter vectors are the rows of ``P`` and initial states the rows of ``Y0``."""
    bound = bind(form)
    P, Y0 = np.atleast_2d(np.asarray(P, dtype=float)), np.atleast_2d(np.asarray(Y0, dtype=float))
    count, N = P.shape[0], spec.t_eval.size
    chunk = Chunk(np.full((count, len(spec.keep), N), np.nan), np.zeros(count, dtype=np.int8), [""] * count,
                  np.zeros(count, dtype=np.int64), np.full(count, np.nan))
    run = _Run(bound, spec)
    with bound.lock:
        if run.batch:  # every sample in one call of the loop in C: no Python between samples
            run.many(np.ascontiguousarray(P), np.ascontiguousarray(Y0), chunk)
            return chunk
        for k in range(count):
            try:
                run.sample(np.ascontiguousarray(P[k]), np.ascontiguousarray(Y0[k]), chunk, k)
            except Exception as exc:  # recorded, never sinks the others
                chunk.status[k], chunk.errors[k] = 1, f"{type(exc).__name__}: {exc}"
    return chunk


class _Run:
    """The buffers and fixed arguments of the samples of one chunk (made once: a sample's run is then the loop in
    C and a few array operations, about 20 µs beside it)."""

    def __init__(self, bound: _Bound, spec: RunSpec):
        form = self.form = bound.form
        self.bound, self.spec = bound, spec
        self.t_eval = np.ascontiguousarray(spec.t_eval, dtype=float)
        self.Y = np.empty((self.t_eval.size, form.dim))
        self.counts = np.zeros(3, dtype=np.int64)
        self.fail = np.zeros(form.dim + 1)
        self.loop = bound.runtime.lg_dop853 if spec.method == "DOP853" else bound.runtime.lg_dopri5
        self.fixed = (float(spec.rtol), float(spec.atol), float(spec.max_step) if math.isfinite(spec.max_step) else 1e300,
                      0.0, float(spec.budget), None, self.Y.ctypes.data, self.counts.ctypes.data, self.fail.ctypes.data)
        kinds = {key[0] for key in spec.keep}
        self.energies = form.conservative or bool(kinds & {"T", "V", "D", "E", "h"})
        self.rates = self.energies or bool(kinds & {"v", "out"}) or form.checks is not None
        # the rates of inertial coordinates are in the state; only first-order ones need the equations
        self.inertial_only = not form.first
        self.order = [form.n + form.inertial.index(i) for i in range(form.n)] if self.inertial_only else None
        # one call for the whole chunk where the state holds every rate in order and nothing is checked per sample
        self.batch = self.inertial_only and form.inertial == tuple(range(form.n)) and form.checks is None

    def many(self, P: np.ndarray, Y0: np.ndarray, chunk: Chunk) -> None:
        """All samples of the chunk through ``lg_ensemble``: the runs and their energies in C, then the kept rows
        and the drift for all at once."""
        form, bound, spec, t_eval = self.form, self.bound, self.spec, self.t_eval
        S, N, n, dim = P.shape[0], t_eval.size, form.n, form.dim
        Y = np.full((S, N, dim), np.nan)
        counts = np.zeros((S, 3), dtype=np.int64)
        fail = np.zeros((S, dim + 1))
        status = np.zeros(S, dtype=np.int32)
        E = np.full((S, N, 4), np.nan) if self.energies else None
        scratch = np.empty(2 * N * max(n, 1))
        t0, t1 = spec.span
        bound.runtime.lg_ensemble(int(spec.method == "DOP853"), bound.rhs_ptr, bound.energies_ptr if E is not None else None,
                                  S, len(form.parameters), P.ctypes.data if P.size else None, n, dim, float(t0), float(t1),
                                  Y0.ctypes.data, N, t_eval.ctypes.data, *self.fixed[:3], self.fixed[4], Y.ctypes.data,
                                  counts.ctypes.data, fail.ctypes.data, status.ctypes.data,
                                  None if E is None else E.ctypes.data, scratch.ctypes.data)
        chunk.nfev[:] = counts[:, 0]
        for k in np.flatnonzero(status):
            chunk.status[k] = 1
            chunk.errors[k] = "ArithmeticError: " + LOOP_MESSAGES.get(
                int(status[k]), "the loop failed (status {status}) at t={t:g}").format(t=float(fail[k, 0]), status=int(status[k]))
        ok = status == 0
        out = None
        if any(key[0] == "out" for key in spec.keep):
            out = np.full((S, N, form.output_tape.n_outputs), np.nan)
            for k in np.flatnonzero(ok):
                out[k] = bound.tape(form.output_tape, P[k], np.column_stack([t_eval, Y[k, :, :n], Y[k, :, n:]]))
        for row, key in enumerate(spec.keep):
            kind = key[0]
            chunk.data[ok, row] = (Y[ok, :, key[1]] if kind == "q" else Y[ok, :, n + key[1]] if kind == "v"
                                   else out[ok, :, key[1]] if kind == "out" else
                                   E[ok, :, 0] + E[ok, :, 1] if kind == "E" else E[ok, :, "TVDh".index(kind)])
        if form.conservative and ok.any():
            h = E[ok, :, 3]
            scale = np.maximum.reduce([np.abs(h[:, 0]), np.max(np.abs(E[ok, :, 0]), axis=1),
                                       np.max(np.abs(E[ok, :, 1]), axis=1), np.full(h.shape[0], np.finfo(float).tiny)])
            chunk.drift[ok] = np.max(np.abs(h - h[:, :1]), axis=1) / scale

    def sample(self, P: np.ndarray, y0: np.ndarray, chunk: Chunk, k: int) -> None:
        form, bound, spec = self.form, self.bound, self.spec
        n, ctx, t_eval, Y = form.n, P.ctypes.data, self.t_eval, self.Y
        t0, t1 = spec.span
        if form.checks is not None:  # the loops must close at the start, as Model.simulate asks
            v0 = _rates(bound, ctx, np.array([t0]), y0[None, :])[0]
            gap = np.abs(bound.tape(form.checks, P, np.concatenate([[t0], y0[:n], v0])[None, :])[0])
            m = len(gap) // 2
            if not (gap[:m].max(initial=0) <= spec.check_tol and gap[m:].max(initial=0) <= spec.check_tol):
                raise ModelError(f"the initial state does not close the kinematic loops (|Φ| = {gap[:m].max():.3g}, "
                                 f"|dΦ/dt| = {gap[m:].max():.3g}) with these parameter values")
        status = self.loop(bound.rhs_ptr, ctx, form.dim, float(t0), float(t1), y0.ctypes.data, t_eval.size,
                           t_eval.ctypes.data, *self.fixed)
        chunk.nfev[k] = self.counts[0]
        if status:
            raise ArithmeticError(LOOP_MESSAGES.get(status, "the loop failed (status {status}) at t={t:g}").format(
                t=float(self.fail[0]), status=status))
        Q = Y[:, :n]
        V = None
        if self.rates:  # every coordinate's rate (first-order ones from the equations)
            V = Y[:, self.order] if self.inertial_only else _rates(bound, ctx, t_eval, Y)
        E = None
        if self.energies:
            E = np.empty((t_eval.size, 4))
            Qc, Vc = np.ascontiguousarray(Q), np.ascontiguousarray(V)
            bound.energies(ctx, t_eval.size, t_eval.ctypes.data, Qc.ctypes.data, Vc.ctypes.data, E.ctypes.data)
        out = None
        if form.output_tape is not None and any(key[0] == "out" for key in spec.keep):
            out = bound.tape(form.output_tape, P, np.column_stack([t_eval, Q, V]))
        for row, key in enumerate(spec.keep):
            kind = key[0]
            chunk.data[k, row] = (Q[:, key[1]] if kind == "q" else V[:, key[1]] if kind == "v"
                                  else out[:, key[1]] if kind == "out" else
                                  E[:, 0] + E[:, 1] if kind == "E" else E[:, "TVDh".index(kind)])
        if form.conservative:
            h = E[:, 3]
            scale = max(abs(h[0]), float(np.max(np.abs(E[:, 0]))), float(np.max(np.abs(E[:, 1]))), np.finfo(float).tiny)
            chunk.drift[k] = float(np.max(np.abs(h - h[0])) / scale)


def _rates(bound: _Bound, ctx: int, times: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """Every coordinate's rate at the states ``Y`` (rows): the inertial ones are in the state, first-order ones
    come from the right-hand side."""
    form = bound.form
    times = np.ascontiguousarray(times, dtype=float)
    rows = np.ascontiguousarray(Y, dtype=float)
    out = np.empty((times.size, form.n))
    failed = bound.runtime.lg_velocities(bound.rhs_ptr, ctx, form.n, form.dim, times.size, times.ctypes.data,
                                         rows.ctypes.data, out.ctypes.data)
    if failed >= 0:
        raise ArithmeticError(f"the equations are not finite at t={times[failed]:g}")
    return out
