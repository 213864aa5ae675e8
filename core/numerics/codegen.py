"""Compiled models: the right-hand side in C, without compiling anything per model unless asked.

This module runs compiled code (:func:`compile_model`, :class:`CompiledModel`); the C it runs is written by
:mod:`lagrangian.numerics.c_source` and built and cached by :mod:`lagrangian.numerics.c_build`, whose public
functions (:func:`runtime`, :func:`compiler`, :func:`set_compiler`, :func:`cache_dir`, :func:`set_cache_dir`,
:func:`generate_source`, :func:`programs`) are also here.

A :class:`~lagrangian.simulation.NumericModel` is recorded as two tapes
(:mod:`lagrangian.tape`, :func:`programs`): straight-line programs for the
entries of ``A(t, q, q̇)`` and ``b(t, q, q̇)`` of the solve ``A u = b`` (see
:mod:`lagrangian.equations`), and for ``T, V, D, L`` and the momenta (the
energies and the Jacobi integral), every common subexpression computed
once.  Recording takes about a millisecond.  The tapes are then run one of
two ways (:func:`compile_model`'s ``kind``):

- **the tape interpreter** (``"tape"``), a loop over the instructions in the
  *runtime library* — C that is the same for every model, compiled once per
  compiler and kept in the cache: a model runs the moment its equations are
  derived;
- **native code** (``"native"``), the tapes printed as straight-line C and
  compiled into the model's own library: about twice as fast per evaluation,
  after a C compilation of 0.1–0.5 s (once: the library is cached).

``"auto"`` takes the native library when it is already in the cache, else
the tape.  Either way the solve itself is done in C by a small dense LU
factorization with partial pivoting (``M⁻¹`` is never formed symbolically),
or for a large system whose renumbered unknowns keep its matrix in a narrow
band, a banded one (:mod:`lagrangian.numerics.band`: the tape then records
the nonzero entries of ``A`` only),
so that one call gives the derivative of the state ``(q, q̇_inertial)``; and
the runtime library holds stepping loops in C — an adaptive Dormand–Prince
5(4) pair with dense output, classical Runge–Kutta and Störmer–Verlet —
which the integrators ``dopri5_c``, ``rk4_c`` and ``verlet_c``
(:mod:`lagrangian.compiled_loops`, registered by the built-in integrators
plugin) run without returning to Python per step.

The system C compiler (``cc``, ``gcc`` or ``clang``; :func:`set_compiler`
or the environment variable ``LAGRANGIAN_CC`` choose another) builds shared
libraries (``-O3 -ffp-contract=off -shared -fPIC``: no fused multiply–adds and no reassociation, so that native code and the tape give the same numbers; -O3 runs the stepping loops about 7 % faster than -O2) loaded with :mod:`ctypes`: no dependency
beyond a C compiler.  Libraries are cached on disk, keyed by a hash of their
source (for a native library: the model's expressions with its numeric
parameter values), the compiler and its flags.  :func:`runtime` builds the
runtime library ahead of time (as an installation step would).

Measured on the planar n-link pendulum (``benchmarks/rhs.py``), n = 3–10:
one evaluation in C takes 0.2–1.2 µs on the tape and 0.1–0.5 µs native (a
hand-written C function of the same system with the same LU takes about as
long as native); called from Python, 1.2–2.2 µs and 1.1–1.5 µs.  The cache
lives in ``$LAGRANGIAN_CACHE_DIR``, else ``$XDG_CACHE_HOME/lagrangian``,
else ``~/.cache/lagrangian`` (:func:`cache_dir`, :func:`set_cache_dir`); it
is safe to delete at any time — a missing or corrupt entry is rebuilt, and
entries are written to a temporary file and renamed, so that two processes
never see half a library.

When no compiler is found, compilation fails, or the model uses a time
signal given as a Python callable (which C cannot call) or a function the
tape does not know, nothing crashes: :func:`compile_model` returns ``None``
with the reason, which ``Model.simulate`` logs and puts in
``Result.notes`` before using the NumPy path.  A singular matrix met in C
raises :class:`~lagrangian.SingularMassMatrixError`, a non-finite
derivative :class:`~lagrangian.NumericalError`.

>>> import tempfile, lagrangian as lg
>>> set_cache_dir(tempfile.mkdtemp())          # a private cache for this example
>>> m = lg.Model("oscillator")
>>> _ = m.add("mass", "m", "p", m=2)
>>> _ = m.add("spring", "k", ("ground", "p"), k=8)
>>> compiled, note = compile_model(m.numeric(), "tape")  # (None, why) without a C compiler
>>> rhs = compiled.rhs if compiled is not None else m.numeric().rhs
>>> rhs(0.0, np.array([1.0, 0.5]))                # (q̇, q̈ = −k q / m)
array([ 0.5, -4. ])
>>> res = m.simulate(1.0, initial={"x_p": 1}, velocity={"x_p": 0}, method="dopri5_c", rtol=1e-10, points=3)
>>> bool(abs(res["x_p"][-1] - np.cos(2.0)) < 1e-8)
True
>>> set_cache_dir(None)
"""

from __future__ import annotations

import ctypes
import math
import threading
import time
from pathlib import Path

import numpy as np

from ..errors import ModelError, NumericalError, SingularMassMatrixError
from .c_build import (
    FLAGS,
    _cache,
    _key,
    _libraries,
    _log,
    _present,
    _runtime_library,
    _settings,  # noqa: F401 - the settings, under their old name too
    cache_dir,
    compiler,
    runtime,
    set_cache_dir,
    set_compiler,
    wanted_compiler,
)
from .c_source import _runtime_source, _Unavailable, band_of, generate_source, programs, solve_size
from .tape import Program

__all__ = [
    "CompiledModel",
    "compile_model",
    "generate_source",
    "programs",
    "run_program",
    "runtime",
    "cache_dir",
    "set_cache_dir",
    "compiler",
    "set_compiler",
    "FLAGS",
]

KINDS = ("native", "tape", "auto")


def compile_model(numeric, kind: str = "native") -> tuple[CompiledModel | None, str | None]:
    """``(CompiledModel, note)`` for ``numeric``, or ``(None, reason)`` when it cannot be compiled here; the note
    is ``None`` unless a private directory stood in for a cache directory that is untrusted (see
    :func:`cache_dir`) or cannot be written (read-only, full).

    ``kind``: ``"native"`` — the model's tapes printed as C and compiled
    into a library of its own (from the cache when built before; else a C
    compilation of 0.1–0.5 s); ``"tape"`` — the tapes run by the runtime
    library's interpreter, which is the same for every model (compiled once
    per compiler, then cached), so nothing is compiled per model; ``"auto"``
    — the native library when it is already in the cache, else the tape.

    Never raises for a missing compiler, a failed compilation, an
    unwritable cache or callable signals: the reason comes back (and is
    logged) so that the caller can use the NumPy path.
    """
    if kind not in KINDS:
        raise ModelError(f"compile_model: kind must be one of {', '.join(map(repr, KINDS))}, not {kind!r}.")
    start = time.perf_counter()
    try:
        programs(numeric)
        source = generate_source(numeric) if kind != "tape" else None
        codegen_s = time.perf_counter() - start
        cc = compiler()
        if cc is None:
            wanted = wanted_compiler()
            raise _Unavailable(f"no C compiler found ({f'{wanted!r} is not a program on the PATH' if wanted else 'none of cc, gcc, clang on the PATH'}); "
                               f"install one or set LAGRANGIAN_CC")
        directory, cache_note = _cache()
        runtime = _runtime_source()
        libraries = {"runtime": ("runtime-" + _key(runtime, cc), runtime)}
        if source is not None:
            key = _key(source, cc)
            if kind == "native" or _present(directory, key):
                libraries["model"] = (key, source)
        try:
            built = _libraries(directory, libraries, cc)
        except OSError as exc:
            raise _Unavailable(f"the cache directory {directory} is not usable ({exc}); set LAGRANGIAN_CACHE_DIR") from None
    except _Unavailable as exc:
        note = f"compiled code not used ({exc}): the NumPy path evaluates the model instead"
        _log.info(note)
        return None, note
    name = "model" if "model" in built else "runtime"
    lib, from_cache, path = built[name].lib, built[name].from_cache, built[name].path
    cache_note = cache_note or built[name].note or built["runtime"].note  # a cache that could not be written
    try:
        compiled = CompiledModel(numeric, built["runtime"].lib, lib if name == "model" else None, libraries[name][0],
                                 path, from_cache=from_cache, codegen_seconds=codegen_s,
                                 build_seconds=time.perf_counter() - start)
    except AttributeError as exc:  # a library without the functions it should have: not ours, or damaged
        note = (f"compiled code not used (the library in {directory} lacks {exc}; delete it to rebuild): the NumPy "
                f"path evaluates the model instead")
        _log.warning(note)
        return None, note
    return compiled, cache_note


class _Prog(ctypes.Structure):
    _fields_ = [("nin", ctypes.c_int), ("nconst", ctypes.c_int), ("ninstr", ctypes.c_int), ("nout", ctypes.c_int),
                ("consts", ctypes.c_void_p), ("code", ctypes.c_void_p), ("out", ctypes.c_void_p)]


class _Tape(ctypes.Structure):
    _fields_ = [("nq", ctypes.c_int), ("ni", ctypes.c_int), ("nf", ctypes.c_int), ("nm", ctypes.c_int),
                ("inertial", ctypes.c_void_p), ("first", ctypes.c_void_p), ("matrix", _Prog), ("energy", _Prog)]


def _solve_note(numeric, band) -> str | None:
    """How the accelerations are had, when not by the dense solve: a recursion's note, or the banded solve."""
    taken = numeric.eq.recursion
    if taken is not None:
        return taken.note
    return None if band is None else _banded(band)


def _banded(band) -> str:
    return (f"the solve banded: {band.nm} unknowns within {band.kl} + {band.ku} diagonals of the main one after "
            f"renumbering")


class _BandTape(ctypes.Structure):
    _fields_ = [("tape", _Tape), ("kl", ctypes.c_int), ("ku", ctypes.c_int), ("nnz", ctypes.c_int),
                ("slot", ctypes.c_void_p), ("perm", ctypes.c_void_p), ("row", ctypes.c_void_p), ("col", ctypes.c_void_p)]


def _array(values, dtype, keep: list) -> int:
    """The address of ``values`` as a C array (one element at least), the array kept alive in ``keep``."""
    a = np.ascontiguousarray(values if len(values) else [0], dtype=dtype)
    keep.append(a)
    return a.ctypes.data


def _prog(p: Program, keep: list) -> _Prog:
    """The interpreter's view of a tape, pointing into arrays kept alive in ``keep``."""
    return _Prog(p.n_inputs, len(p.constants), len(p.code), p.n_outputs, _array(p.constants, np.float64, keep),
                 _array(p.code.ravel(), np.int32, keep), _array(p.outputs, np.int32, keep))


def run_program(program: Program, inputs) -> np.ndarray:
    """Run a tape (:class:`lagrangian.tape.Program`) in the runtime library's C interpreter: ``inputs`` one row
    per evaluation (``N × n_inputs``, or one row), the outputs ``N × n_outputs`` (or one row).  The interpreter
    models run on, exposed for checking tapes against other evaluations.

    >>> import sympy as sp
    >>> from lagrangian.tape import record
    >>> x = sp.Symbol("x")
    >>> tape = record([sp.cos(x) ** 2 + sp.sin(x) ** 2, x ** 3], [x])
    >>> out = run_program(tape, [[0.5], [2.0]]) if compiler() else np.array([tape.evaluate([0.5]), tape.evaluate([2.0])])
    >>> out.round(12).tolist()                         # (the Python reference when there is no C compiler)
    [[1.0, 0.125], [1.0, 8.0]]
    """
    lib = _runtime_library().lib
    rows = np.atleast_2d(np.asarray(inputs, dtype=float))
    if rows.shape[1] != program.n_inputs:
        raise ModelError(f"run_program: the tape has {program.n_inputs} inputs, the rows have {rows.shape[1]}.")
    rows = np.ascontiguousarray(rows)
    keep: list = []
    prog = _prog(program, keep)
    out = np.empty((rows.shape[0], program.n_outputs))
    lib.lg_prog_eval.argtypes, lib.lg_prog_eval.restype = [ctypes.c_void_p, ctypes.c_long, ctypes.c_void_p, ctypes.c_void_p], ctypes.c_int
    if lib.lg_prog_eval(ctypes.addressof(prog), rows.shape[0], rows.ctypes.data, out.ctypes.data):
        raise NumericalError("run_program: out of memory for the tape's registers")
    return out if np.ndim(inputs) == 2 else out[0]


class CompiledModel:
    """The compiled functions of one :class:`~lagrangian.simulation.NumericModel` (see :func:`compile_model`).

    ``kind`` is ``"native"`` (the model's own library) or ``"tape"`` (its
    tapes run by the shared interpreter); ``from_cache`` says whether the
    library came from the disk cache (else it was just built); ``path`` is
    the library; ``key`` its cache key; ``codegen_seconds`` and
    ``build_seconds`` the time spent recording and printing the tapes and,
    in all, getting the library.
    """

    def __init__(self, numeric, runtime: ctypes.CDLL, lib: ctypes.CDLL | None, key: str, path: Path, *,
                 from_cache: bool, codegen_seconds: float, build_seconds: float):
        self.numeric, self.loops, self.lib, self.key, self.path = numeric, runtime, lib, key, path
        self.kind = "tape" if lib is None else "native"
        self.from_cache, self.codegen_seconds, self.build_seconds = from_cache, codegen_seconds, build_seconds
        self.n, self.nI, self.dim = numeric.n, numeric.nI, numeric.n + numeric.nI
        self.m = solve_size(numeric.eq)
        self.band = band_of(numeric.eq)  # (a banded solve: lagrangian.numerics.band)
        dbl, ptr, lng, cint = ctypes.c_double, ctypes.c_void_p, ctypes.c_long, ctypes.c_int
        if lib is not None:
            dims = (ctypes.c_int * 5)()
            lib.lg_dims(dims)
            if (dims[0], dims[1], dims[2]) != (self.n, self.nI, self.m):  # pragma: no cover - a stale or foreign library
                raise NumericalError(f"the compiled library {path} does not belong to this model; delete it and retry.")
            rhs, matrix, energies = lib.lg_rhs, lib.lg_matrix, lib.lg_energies
            self._ctx = None
        elif self.band is not None:
            rhs, matrix, energies = runtime.lg_band_rhs, runtime.lg_band_matrix, runtime.lg_tape_energies
            self._ctx, self._keep = self._tape(numeric)
        else:
            rhs, matrix, energies = runtime.lg_tape_rhs, runtime.lg_tape_matrix, runtime.lg_tape_energies
            self._ctx, self._keep = self._tape(numeric)
        rhs.argtypes, rhs.restype = [ptr, dbl, ptr, ptr], cint
        matrix.argtypes, matrix.restype = [ptr, dbl, ptr, ptr, ptr, ptr], cint
        energies.argtypes, energies.restype = [ptr, lng, ptr, ptr, ptr, ptr], None
        runtime.lg_velocities.argtypes, runtime.lg_velocities.restype = [ptr, ptr, cint, cint, lng, ptr, ptr, ptr], lng
        runtime.lg_dopri5.argtypes = [ptr, ptr, cint, dbl, dbl, ptr, lng, ptr, dbl, dbl, dbl, dbl, dbl, ptr, ptr, ptr, ptr]
        runtime.lg_dopri5.restype = cint
        runtime.lg_fixed.argtypes = [ptr, ptr, cint, cint, cint, dbl, dbl, lng, ptr, lng, ptr, ptr, ptr, ptr, ptr]
        runtime.lg_fixed.restype = cint
        runtime.lg_dopri5_begin.argtypes = [ptr, ptr, cint, dbl, dbl, dbl, dbl, dbl, ptr, ptr, ptr, ptr]
        runtime.lg_dopri5_begin.restype = cint
        runtime.lg_dopri5_step.argtypes = [ptr, ptr, cint, cint, dbl, dbl, dbl, dbl, dbl, ptr, ptr, ptr, ptr, ptr, ptr]
        runtime.lg_dopri5_step.restype = cint
        runtime.lg_dopri5_dense.argtypes, runtime.lg_dopri5_dense.restype = [cint, ptr, dbl, dbl, ptr], None
        runtime.lg_dop853.argtypes = [ptr, ptr, cint, dbl, dbl, ptr, lng, ptr, dbl, dbl, dbl, dbl, dbl, ptr, ptr, ptr, ptr]
        runtime.lg_dop853.restype = cint
        runtime.lg_dop853_begin.argtypes = [ptr, ptr, cint, dbl, dbl, dbl, dbl, dbl, dbl, ptr, ptr, ptr, ptr]
        runtime.lg_dop853_begin.restype = cint
        runtime.lg_dop853_step.argtypes = [ptr, ptr, cint, cint, dbl, dbl, dbl, dbl, dbl, ptr, ptr, ptr, ptr, ptr, ptr]
        runtime.lg_dop853_step.restype = cint
        runtime.lg_dop853_prepare.argtypes = [ptr, ptr, cint, dbl, dbl, ptr, ptr, ptr]
        runtime.lg_dop853_prepare.restype = cint
        runtime.lg_dop853_dense.argtypes, runtime.lg_dop853_dense.restype = [cint, ptr, dbl, ptr], None
        runtime.lg_fixed_step.argtypes = [ptr, ptr, cint, cint, cint, dbl, dbl, ptr, ptr, ptr]
        runtime.lg_fixed_step.restype = cint
        self._rhs_c, self._matrix_c, self._energies_c = rhs, matrix, energies
        self._rhs_ptr = ctypes.cast(rhs, ctypes.c_void_p).value  # what the loops call
        self._local = threading.local()  # rhs() buffers, one pair per thread: a model may be shared by threads

    def _tape(self, numeric) -> tuple[int, list]:
        """The interpreter's description of this model (a C struct pointing into arrays kept alive here)."""
        eq = numeric.eq
        keep: list = []
        matrix, energy = programs(numeric)
        tape = _Tape(self.n, self.nI, len(eq.first_order), self.m, _array(eq.inertial, np.int32, keep),
                     _array(list(eq.first_order), np.int32, keep), _prog(matrix, keep), _prog(energy, keep))
        if self.band is not None:
            b = self.band
            tape = _BandTape(tape, b.kl, b.ku, len(b.pattern), _array(b.slot, np.int32, keep),
                             _array(b.perm, np.int32, keep), _array(b.rows, np.int32, keep), _array(b.cols, np.int32, keep))
        keep.append(tape)
        return ctypes.addressof(tape), keep

    def describe(self) -> str:
        """What evaluates the model: ``native code (<key>.so, from the cache)`` or ``the tape interpreter (…)``."""
        note = _solve_note(self.numeric, self.band)
        if self.kind == "native":
            solve = "" if note is None else f"; {note}"
            return (f"native code ({self.path.name}{', from the cache' if self.from_cache else ', built for this model'}"
                    f"{solve})")
        matrix, _ = programs(self.numeric)
        solve = "" if note is None else f", {note}"
        return (f"the tape interpreter ({len(matrix.code)} instructions per evaluation{solve}; nothing compiled for "
                f"this model)")

    # -- one state ----------------------------------------------------------------
    def rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        """``dy/dt`` at ``(t, y)``, ``y = (q, q̇_inertial)``: the same as ``NumericModel.rhs``, in C."""
        buffers = getattr(self._local, "buffers", None)
        if buffers is None:
            y_in, dy_out = np.zeros(max(self.dim, 1)), np.zeros(max(self.dim, 1))
            buffers = self._local.buffers = (y_in, dy_out, y_in.ctypes.data, dy_out.ctypes.data)
        y_in, dy_out, yp, dyp = buffers
        y_in[: self.dim] = y
        rc = self._rhs_c(self._ctx, t, yp, dyp)
        if rc:
            self._raise(rc, t, y_in[: self.dim].copy())
        return dy_out[: self.dim].copy()

    def matrix(self, t: float, q: np.ndarray, vI: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``A`` and ``b`` of the solve ``A u = b`` at ``(t, q, q̇_inertial)``."""
        A, b = np.zeros((self.m, self.m)), np.zeros(self.m)
        q = np.ascontiguousarray(q, dtype=float)
        vI = np.ascontiguousarray(vI, dtype=float)
        self._matrix_c(self._ctx, t, q.ctypes.data, vI.ctypes.data if vI.size else None, A.ctypes.data, b.ctypes.data)
        return A, b

    def _raise(self, rc: int, t: float, y: np.ndarray):
        if rc == 1:
            A, _ = self.matrix(t, y[: self.n], y[self.n :])
            raise SingularMassMatrixError(self.numeric._singular_message(t, A, y[: self.n]))
        if self.numeric.eq.recursion is not None and np.all(np.isfinite(y)):
            # a recursion divides by its pivots: a singular mass matrix shows as a result that is not finite
            M = self._recursive_mass(t, y[: self.n])
            s = np.linalg.svd(M, compute_uv=False) if np.all(np.isfinite(M)) else np.zeros(1)
            if not s[-1] > 1e3 * self.n * np.finfo(float).eps * s[0]:
                raise SingularMassMatrixError(self.numeric._singular_message(t, M, y[: self.n]))
            if self.numeric.eq.recursion.multipliers:  # (a pivot of the constraints' solve: J M⁻¹ Jᵀ singular)
                raise SingularMassMatrixError(
                    f"the constraints are not independent at t={t:g} (state "
                    f"{np.array2string(y, precision=4)}): their forces are not determined there, as at a dead point of "
                    f"a loop. Start elsewhere, or remove a redundant constraint.")
        raise NumericalError(
            f"the equations are not finite at t={t:g} (state {np.array2string(y, precision=4)}): a singular "
            f"configuration of some component, or a diverging solution. Start elsewhere or reduce the step."
        )

    def _recursive_mass(self, t: float, q: np.ndarray) -> np.ndarray:
        """The mass matrix of a model whose recursion gives its accelerations, column by column from the momenta
        ``p = M q̇`` of its energy tape (in Python: for the message of a failed run)."""
        _, energy = programs(self.numeric)
        rates = np.eye(self.n)
        with np.errstate(all="ignore"):
            return np.array([energy.evaluate([t, *q, *rates[j]])[4:] for j in range(self.n)], dtype=float).T

    # -- many states ------------------------------------------------------------
    def velocities_many(self, times: np.ndarray, Y: np.ndarray) -> np.ndarray:
        """All generalized velocities (``n × N``) at the states ``Y`` (columns)."""
        times = np.ascontiguousarray(times, dtype=float)
        rows = np.ascontiguousarray(np.asarray(Y, dtype=float).T)
        out = np.empty((times.size, self.n))
        k = self.loops.lg_velocities(self._rhs_ptr, self._ctx, self.n, self.dim, times.size, times.ctypes.data, rows.ctypes.data,
                                     out.ctypes.data)
        if k >= 0:
            dy = np.empty(self.dim)
            self._raise(self._rhs_c(self._ctx, times[k], rows[k].ctypes.data, dy.ctypes.data) or 2, times[k], rows[k])
        return out.T.copy()

    def _energies(self, times, q, v) -> np.ndarray:
        times = np.ascontiguousarray(np.broadcast_to(np.asarray(times, dtype=float), (np.shape(q)[1],)))
        qr = np.ascontiguousarray(np.asarray(q, dtype=float).T)
        vr = np.ascontiguousarray(np.asarray(v, dtype=float).T)
        out = np.empty((times.size, 4))
        self._energies_c(self._ctx, times.size, times.ctypes.data, qr.ctypes.data, vr.ctypes.data, out.ctypes.data)
        return out

    def energies(self, times: np.ndarray, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``T``, ``V``, ``D`` at many states (``q``, ``v``: ``n × N``)."""
        out = self._energies(times, q, v)
        return out[:, 0].copy(), out[:, 1].copy(), out[:, 2].copy()

    def jacobi(self, times: np.ndarray, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """The Jacobi integral ``h = p·q̇ − L`` at many states (``q``, ``v``: ``n × N``)."""
        return self._energies(times, q, v)[:, 3].copy()

    # -- stepping loops -----------------------------------------------------------
    def _run(self, status: int, fail: np.ndarray, what: str) -> str:
        t, y = float(fail[0]), fail[1:]
        if status == 1:
            self._raise(1, t, y)
        return {
            2: f"the equations became non-finite at t={t:g}",
            3: f"{what}: the step size fell below the resolution of t at t={t:g} (the model may be stiff or singular there)",
            4: f"the state diverged (beyond 1e30 times its initial size, or non-finite) by t={t:g}",
            5: f"{what}: out of memory for the stepping loop's {13 * self.dim} numbers",
            6: f"{what}: stopped at t={t:g}: at its pace the run would need more evaluations than its budget",
            7: f"{what}: stopped at t={t:g} (interrupted)",
        }[status]

    def dopri5(self, t_span, y0, t_eval, *, rtol: float, atol: float, max_step: float, first_step: float | None,
               variant: str = "dopri5", budget: float = 0.0, watch: np.ndarray | None = None):
        """Dormand–Prince 5(4) (``variant="dop853"``: DOP853) in C from ``y0``; ``(Y (dim × len), nfev, steps,
        status, message, t)`` with ``t`` where a failure stopped it; output stops at a failure.  It stops with
        status 6 where at its pace the run would need more than ``budget`` evaluations (0: no budget), and
        with 7 when ``watch[1]`` is set (by another thread) while it runs; it writes the time reached to
        ``watch[0]`` after each step."""
        t_eval = np.ascontiguousarray(t_eval, dtype=float)
        y0 = np.ascontiguousarray(y0, dtype=float)
        Y = np.full((t_eval.size, self.dim), np.nan)
        counts = np.zeros(3, dtype=np.int64)  # long is 64-bit on the platforms we build on
        fail = np.zeros(self.dim + 1)
        extra = (float(budget), None if watch is None else watch.ctypes.data)
        loop = self.loops.lg_dop853 if variant == "dop853" else self.loops.lg_dopri5
        status = loop(self._rhs_ptr, self._ctx, self.dim, float(t_span[0]), float(t_span[1]), y0.ctypes.data, t_eval.size, t_eval.ctypes.data,
                      float(rtol), float(atol), float(max_step) if math.isfinite(max_step) else 1e300,
                      float(first_step or 0.0), *extra, Y.ctypes.data, counts.ctypes.data, fail.ctypes.data)
        message = self._run(status, fail, f"{variant}_c") if status and status not in (6, 7) else ""
        return Y.T, int(counts[0]), int(counts[1]), status, message, float(fail[0])

    def fixed(self, method: str, t0: float, h: float, N: int, y0, t_eval, watch: np.ndarray | None = None):
        """``N`` steps of ``rk4`` or ``verlet`` in C; ``(Y (dim × len), nfev, message)``; it stops (status 7) when
        ``watch[1]`` is set while it runs, and writes the time reached to ``watch[0]`` after each step."""
        t_eval = np.ascontiguousarray(t_eval, dtype=float)
        y0 = np.ascontiguousarray(y0, dtype=float)
        Y = np.full((t_eval.size, self.dim), np.nan)
        counts = np.zeros(2, dtype=np.int64)
        fail = np.zeros(self.dim + 1)
        code = {"rk4": 0, "verlet": 1}[method]
        status = self.loops.lg_fixed(self._rhs_ptr, self._ctx, self.n, self.dim, code, float(t0), float(h), int(N), y0.ctypes.data, t_eval.size, t_eval.ctypes.data,
                                   None if watch is None else watch.ctypes.data, Y.ctypes.data, counts.ctypes.data, fail.ctypes.data)
        message = self._run(status, fail, method) if status else ""
        return Y.T, int(counts[0]), message
