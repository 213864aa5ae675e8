"""The problem an integrator solves: the model's state equations with its structure, spectrum and pieces.

See :class:`Problem`; the integrator contract is :class:`lagrangian.contracts.Integrator`.
"""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..base.component import t as time_symbol
from ..base.identity import depends_on, is_zero
from ..derivation.calculus import symbols_of
from ..errors import IntegrationError, ModelError, SingularMassMatrixError, warn
from .c_source import programs
from .simulation import NumericModel, _lambdify
from ..base import deferred as _deferred

sp = _deferred.module("sympy", globals())

#: Central differences: the step (relative to max(1, |y_j|)) that balances truncation and round-off, eps^(1/3).
_CENTRAL_STEP = float(np.finfo(float).eps ** (1 / 3))
#: LAPACK's DGEBAL constants: scaling by powers of 2, a step taken when it lowers a row's and column's norms by 5 %,
#: and never to a factor whose product with the others passes these bounds.
_SFMIN1 = float(np.finfo(float).tiny / np.finfo(float).eps)
_SFMAX1, _SFMIN2 = 1.0 / _SFMIN1, _SFMIN1 * 2.0
_SFMAX2 = 1.0 / _SFMIN2


def balance(A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(B, d)``: ``B = D⁻¹ A D`` with ``D = diag(d)``, powers of 2 that make each row's and column's 2-norms
    comparable; LAPACK's DGEBAL scaling (version 3.5 on), as ``scipy.linalg.matrix_balance(A, permute=False)``
    computes it, to the bit (tests/test_integrators.py compares them on matrices over 16 decades).  Written out
    here because importing ``scipy.linalg`` for it cost every run 0.15 s of CPU (a second process running a cached
    model spent a tenth of its time on that import alone).

    >>> B, d = balance(np.array([[1.0, 1e6], [1e-6, 1.0]]))
    >>> d.tolist(), B.tolist()
    ([8192.0, 0.015625], [[1.0, 1.9073486328125], [0.524288, 1.0]])
    """
    B = np.array(A, dtype=float)
    d = np.ones(B.shape[0])
    again = True
    while again:
        again = False
        for i in range(B.shape[0]):
            c, r = float(np.linalg.norm(B[:, i])), float(np.linalg.norm(B[i, :]))
            ca, ra = float(np.max(np.abs(B[:, i]))), float(np.max(np.abs(B[i, :])))
            if c == 0.0 or r == 0.0:
                continue
            g, f, s = r / 2.0, 1.0, c + r
            while not (c >= g or max(f, c, ca) >= _SFMAX2 or min(r, g, ra) <= _SFMIN2):
                f, c, ca, r, g, ra = f * 2.0, c * 2.0, ca * 2.0, r / 2.0, g / 2.0, ra / 2.0
            g = c / 2.0
            while not (g < r or max(r, ra) >= _SFMAX2 or min(f, c, g, ca) <= _SFMIN2):
                f, c, g, ca, r, ra = f / 2.0, c / 2.0, g / 2.0, ca / 2.0, r * 2.0, ra * 2.0
            if (c + r >= 0.95 * s or (f < 1.0 and d[i] < 1.0 and f * d[i] <= _SFMIN1)
                    or (f > 1.0 and d[i] > 1.0 and d[i] >= _SFMAX1 / f)):
                continue
            d[i] *= f
            B[i, :] /= f
            B[:, i] *= f
            again = True
    return B, d

# ---------------------------------------------------------------------------
# The problem an integrator solves
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class Structure:
    """What kind of Lagrangian system a problem is; each ``False`` has its reason in ``why``.

    - ``constant_mass``: ``M`` depends neither on ``q`` nor on ``t``;
    - ``velocity_free``: the forcing ``f(q, q̇, t)`` does not depend on ``q̇``
      (no dissipation, no gyroscopic or velocity-dependent forces);
    - ``separable``: both, every coordinate has inertia and there are no
      constraints — ``L = ½ q̇ᵀ M q̇ − V(q, t)``, what Störmer–Verlet needs;
    - ``conservative``: no dissipation ``D``, no generalized forces ``Q``,
      ``L`` independent of ``t`` — the Jacobi integral ``h = p·q̇ − L``
      (``T + V`` for fixed constraints) is constant;
    - ``autonomous``: the equations do not depend on ``t``;
    - ``linear``: autonomous and affine in the state, ``y' = F y + c`` —
      every one-step map of a fixed-step method is then one constant
      affine map;
    - ``quadratic``: ``L`` is at most quadratic in ``q̇`` (so ``p = M q̇ + p₀``
      is inverted by one linear solve);
    - ``first_order``, ``constrained``: coordinates without inertia, and
      loop-closure constraints.
    """

    first_order: tuple[str, ...]
    constrained: bool
    constant_mass: bool
    velocity_free: bool
    conservative: bool
    autonomous: bool
    linear: bool
    quadratic: bool
    why: Mapping[str, str] = field(default_factory=dict)

    @property
    def separable(self) -> bool:
        return self.constant_mass and self.velocity_free and not self.first_order and not self.constrained

    def why_not_separable(self) -> str:
        """The reasons the Lagrangian is not ``½ q̇ᵀ M q̇ − V(q)`` with constant ``M``, as one phrase."""
        reasons = [self.why[k] for k in ("first_order", "constrained", "constant_mass", "velocity_free") if k in self.why]
        return "; ".join(reasons)


@dataclass(frozen=True)
class Spectrum:
    """Eigenvalues of a linearization, those zero up to its accuracy marked (:meth:`Problem.spectrum`).

    ``scale`` is the 2-norm of the balanced Jacobian, ``error`` the estimated
    norm of its error (same units); ``nonzero`` the eigenvalues that count,
    ``rho`` the largest of their magnitudes (0 when none) and ``slowest``
    the smallest (0 when none).
    """

    eigenvalues: np.ndarray
    zero: np.ndarray
    scale: float
    error: float

    @property
    def nonzero(self) -> np.ndarray:
        return self.eigenvalues[~self.zero]

    def copy(self) -> "Spectrum":
        """The same spectrum with arrays of its own."""
        return Spectrum(self.eigenvalues.copy(), self.zero.copy(), self.scale, self.error)

    @property
    def rho(self) -> float:
        mags = np.abs(self.nonzero)
        return float(mags.max()) if mags.size else 0.0

    @property
    def slowest(self) -> float:
        mags = np.abs(self.nonzero)
        return float(mags.min()) if mags.size else 0.0


#: A run is judged on its pace every PACE_EVERY + 1 evaluations, once it has taken PACE_MIN of them ...
PACE_EVERY = 0x3FFF
PACE_MIN = 1 << 17
#: ... and refused when it would need more than this many evaluations in all (hours of Python).
MAX_EVALUATIONS = 1e9
#: A run not reporting its progress that, after LONG_RUN_AFTER seconds, would at its pace take more than LONG_RUN
#: seconds in all says so once (:class:`SlowRunWarning`): it is not stuck, and the warning says how long it will be.
LONG_RUN = 60.0
LONG_RUN_AFTER = 2.0
#: How many spectra a problem keeps (:meth:`Problem.spectrum`): those of the starts of the last few runs.
SPECTRA_KEPT = 16


class SlowRunWarning(UserWarning):
    """A run will take long at its pace (it is not stuck): how long, and how to follow or shorten it."""


def inside(s: float, a: float, b: float) -> float:
    """``s`` moved inside ``[a, b]`` by 16 units in the last place at either end, as the loops in C do: an input that
    switches at ``a`` or ``b`` (a pulse's corner, where an adaptive run restarts) is read on this piece's side of
    the corner.  The last stage of a step ending at ``b`` feeds that step's dense output: read on the next piece's
    side, it bent the outputs of an RC circuit between two corners of a square wave by 18 %.

    >>> inside(1.0, 1.0, 2.0) > 1.0, inside(2.0, 1.0, 2.0) < 2.0, inside(1.5, 1.0, 2.0)
    (True, True, 1.5)
    """
    ma, mb = 16.0 * math.ulp(abs(a)), 16.0 * math.ulp(abs(b))
    if not b - a > 4.0 * (ma + mb):
        return s
    return a + ma if s < a + ma else b - mb if s > b - mb else s


class Problem:
    """What an integrator integrates: ``y' = rhs(t, y)`` on ``y = (q, q̇_inertial)``, with the model's structure.

    Built from a :class:`~lagrangian.simulation.NumericModel` (the model with
    numeric parameter values).  ``n`` coordinates named ``names``, ``nI``
    of them inertial; ``dim = n + nI`` is the length of the state.  Every
    evaluation of a model function counts in ``nfev``.

    >>> import lagrangian as lg
    >>> m = lg.Model("osc")
    >>> _ = m.add("mass", "m", "p", m=2)
    >>> _ = m.add("spring", "k", ("ground", "p"), k=8)
    >>> pb = Problem(m.numeric())
    >>> pb.structure.separable, pb.structure.conservative, pb.structure.linear
    (True, True, True)
    >>> pb.momentum(0.0, np.array([0.1]), np.array([3.0]))   # p = m q̇
    array([6.])
    >>> pb.acceleration(0.0, np.array([0.1]))                # −k q / m
    array([-0.4])
    """

    def __init__(self, numeric: NumericModel, name: str = "model"):
        self.numeric = numeric
        self.name = name
        eq = numeric.eq
        self.names: list[str] = list(eq.names)
        self.n = numeric.n
        self.nI = numeric.nI
        self.dim = self.n + self.nI
        self.inertial: list[int] = list(eq.inertial)
        self.first_order: list[str] = [eq.names[i] for i in eq.first_order]
        self.constrained = len(getattr(eq, "constraints", ())) + len(getattr(eq, "velocity_constraints", ())) > 0
        self.nfev = 0
        self._report: Callable[[float], None] | None = None
        self._pace: tuple[float, float, int, str] | None = None  # (t0, t1, nfev at the start, model) of a run
        self._began, self._told = 0.0, False  # when the run began; whether it has said it is slow
        #: ``(a, b)`` while an adaptive run restarted at switching times integrates the piece between them: times
        #: are read inside it (:func:`inside`)
        self.window: tuple[float, float] | None = None
        #: spectra at starts seen (:meth:`spectrum`), by (t, y's bytes, the evaluator's id), oldest first
        self._spectra: dict[tuple[float, bytes, int], Spectrum] = {}
        #: outcomes of the stiffness check before a run (:func:`lagrangian.integrate._stiffness_note_once`)
        self._stiffness_notes: dict[tuple, str | None] = {}

    # -- every method -----------------------------------------------------------
    def rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        """``F(t, y)``: the velocities of all coordinates, then the inertial accelerations."""
        self.nfev += 1
        if self._report is not None:
            self._report(t)
        if self._pace is not None and not self.nfev & PACE_EVERY:
            self._check_pace(t)
        if self.window is not None:
            t = inside(t, *self.window)
        return self.numeric.rhs(t, y)

    def watch(self, t_span: tuple[float, float] | None, model: str = "model", limit: float | None = None) -> None:
        """Refuse, from now on, a run over ``t_span`` that at its pace would need more than ``limit`` evaluations
        (default :data:`MAX_EVALUATIONS`; ``t_span=None``: stop watching)."""
        limit = MAX_EVALUATIONS if limit is None else float(limit)
        self._pace = None if t_span is None else (float(t_span[0]), float(t_span[1]), self.nfev, model, limit)
        self._began, self._told = time.perf_counter(), False

    def _check_pace(self, t: float) -> None:
        t0, t1, start, model, limit = self._pace
        used = self.nfev - start
        if not t1 > t0:
            return
        done = (float(t) - t0) / (t1 - t0)
        if not self._told and self._report is None:
            self._tell_if_slow(t, done, used)
        if used < min(PACE_MIN, limit):
            return
        projected = used / done if done > 0 else np.inf
        if projected > limit:
            self._pace = None
            raise self.pace_error(t, used, projected, (t0, t1, start, model, limit))

    def _tell_if_slow(self, t: float, done: float, used: int) -> None:
        """Warn once (:class:`SlowRunWarning`) when the run, some seconds in, would take more than :data:`LONG_RUN`."""
        elapsed = time.perf_counter() - self._began
        if elapsed < LONG_RUN_AFTER or not done > 0 or elapsed / done <= LONG_RUN:
            return
        self._told = True
        t0, t1, _, model, _ = self._pace
        warn(
            f"the run of model {model!r} has come to t={t:.6g} of [{t0:.6g}, {t1:.6g}] in {elapsed:.1f} s and "
            f"{used} evaluations: at this pace it will take some {elapsed / done:.3g} s in all. It is not stuck. "
            f"progress=True reports how far it has come; a method stepped in C (method='DOP853', the default, or "
            f"'dop853_c') steps much faster than one stepped in Python; a shorter run or fewer points of a fast "
            f"part ends sooner; max_evaluations bounds it.",
            SlowRunWarning,
        )

    def pace_error(self, t: float, used: int, projected: float, pace: tuple | None = None) -> IntegrationError:
        """The refusal of a run that at its pace would need ``projected`` evaluations (also raised for compiled loops
        that judge their own pace)."""
        t0, t1, _, model, limit = pace or self._pace
        return IntegrationError(
            f"the run of model {model!r} has come to t={t:.6g} of [{t0:.6g}, {t1:.6g}] in {used} evaluations: at "
            f"this pace it would need some {projected:.3g}, and would not end. Its solution changes on a time "
            f"scale of about {max(float(t) - t0, 0.0) / used:.3g} s per evaluation: a part many orders of magnitude "
            f"faster than the run (a length of 1e-96, an inertia of 1e-30?) or a state running into a "
            f"singularity. Check the parameter values, shorten the run, or try method='Radau' if it is stiff"
            + (f"; or allow more than max_evaluations={limit:.3g}." if limit != MAX_EVALUATIONS else ".")
        )

    def jacobian(self, t: float, y: np.ndarray, f0: np.ndarray | None = None) -> np.ndarray:
        """``∂F/∂y`` at ``(t, y)`` by forward differences (``dim`` evaluations, one more without ``f0``)."""
        y = np.asarray(y, dtype=float)
        f0 = self.rhs(t, y) if f0 is None else f0
        J = np.empty((f0.size, y.size))
        for j in range(y.size):
            h = 1.5e-8 * max(1.0, abs(y[j]))
            yj = y.copy()
            yj[j] += h
            J[:, j] = (self.rhs(t, yj) - f0) / h
        return J

    def eigenvalues(self, t: float, y: np.ndarray) -> np.ndarray:
        """Eigenvalues of the linearization ``∂F/∂y`` at ``(t, y)``."""
        if self.dim == 0:
            return np.zeros(0, dtype=complex)
        return np.linalg.eigvals(self.jacobian(t, y))

    def _central_jacobian(self, t: float, y: np.ndarray, widen: float = 1.0) -> np.ndarray:
        J = np.empty((self.dim, self.dim))
        for j in range(self.dim):
            h = widen * _CENTRAL_STEP * max(1.0, abs(y[j]))
            up, down = y.copy(), y.copy()
            up[j] += h
            down[j] -= h
            J[:, j] = (self.rhs(t, up) - self.rhs(t, down)) / (up[j] - down[j])
        return J

    def spectrum(self, t: float, y: np.ndarray) -> Spectrum:
        """The eigenvalues of ``∂F/∂y`` at ``(t, y)``, with those that are zero up to the Jacobian's accuracy marked.

        The Jacobian is taken by central differences (``4·dim`` evaluations:
        two step sizes, whose difference estimates its error).  An ignorable
        coordinate gives a zero eigenvalue, usually in a 2 × 2 Jordan block
        with its momentum; an error ``ε`` in the Jacobian splits such a block
        into ``±√ε`` — about 1e-8 of the spectrum for forward differences —
        so no threshold on ``|λ|`` separates it from a slow mode.  The
        number of zero eigenvalues is counted instead by ranks, which an
        error ``ε`` moves by ``ε`` only: ``z = dim − rank(Bᵏ)`` once it stops
        growing with ``k``, where ``B`` is the balanced Jacobian (units of
        the state made comparable) and singular values count as zero below
        ``k·τ·‖B‖ᵏ⁻¹``, ``τ`` 100 times the estimated error (at least
        ``1e3·dim·eps·‖B‖``).  The ``z`` eigenvalues smallest in magnitude
        are the zero ones.  No decision rests on ``λ == 0``.

        >>> import lagrangian as lg
        >>> m = lg.Model("free and bound")
        >>> _ = m.add("mass", "m1", "a", m=0.3)
        >>> _ = m.add("mass", "m2", "b", m=0.3)
        >>> _ = m.add("spring", "k", ("ground", "b"), k=0.7)
        >>> sp_ = Problem(m.numeric()).spectrum(0.0, np.array([0.2, 0.1, 1.5, 0.0]))
        >>> int(sp_.zero.sum()), round(sp_.rho, 6), round((0.7 / 0.3) ** 0.5, 6)   # a's drift: two zeros
        (2, 1.527525, 1.527525)
        """
        y = np.asarray(y, dtype=float)
        if self.dim == 0:
            return Spectrum(np.zeros(0, dtype=complex), np.zeros(0, dtype=bool), 0.0, 0.0)
        # a pure function of (t, y) and the evaluator of the right-hand side (compiled or NumPy: the same equations,
        # perhaps not the same last bits) outside a run: kept for the next call, which a fit makes with the same start
        quiet = self._report is None and self._pace is None and self.window is None
        if not quiet:
            return self._spectrum(t, y)
        kept = self._spectra
        hit = kept.get((float(t), y.tobytes(), id(getattr(self.numeric, "_fast", None))))
        if hit is not None:
            return hit.copy()
        spec = self._spectrum(t, y)
        _forget_oldest(kept, SPECTRA_KEPT)
        # (the evaluator after the run: an unpickled model's deferred one has put the built one in its place)
        kept[(float(t), y.tobytes(), id(getattr(self.numeric, "_fast", None)))] = spec.copy()
        return spec

    def _spectrum(self, t: float, y: np.ndarray) -> Spectrum:
        J = self._central_jacobian(t, y)
        J2 = self._central_jacobian(t, y, 2.0)
        if not (np.all(np.isfinite(J)) and np.all(np.isfinite(J2))):
            raise IntegrationError(f"the linearization of model {self.name!r} at t={t:g} is not finite: the state is a singular configuration.")
        # entries at the level of rounding (a coordinate the model does not depend on, through sines and cosines
        # that cancel) are zero: balancing would otherwise scale them up by orders of magnitude.  Rounding is
        # judged within each row (one equation, one unit): against the whole matrix, the exact 1 of q' = v next to
        # g/L = 2e96 (a pendulum 4.9e-96 m long) was taken for rounding and the ±1e48 i pair lost
        rows = np.max(np.abs(J), axis=1, keepdims=True)
        floor = 100.0 * np.abs(J - J2) + 64.0 * np.finfo(float).eps * rows
        J = np.where(np.abs(J) <= floor, 0.0, J)
        B, d = balance(J)
        E = (J - J2) * d[None, :] / d[:, None]
        scale = float(np.linalg.norm(B, 2))
        lam = np.linalg.eigvals(J)
        zero = np.zeros(lam.size, dtype=bool)
        if not scale > 0.0:  # the zero matrix: every eigenvalue is zero
            return Spectrum(lam, ~zero, 0.0, 0.0)
        error = float(np.linalg.norm(E, 2))
        tau = 100.0 * max(error, 10.0 * self.dim * np.finfo(float).eps * scale)
        # sv(Bᵏ) ≤ k·τ·‖B‖ᵏ⁻¹ read as sv((B/‖B‖)ᵏ) ≤ k·τ/‖B‖: the same test, with powers that never overflow
        # (‖B‖ᵏ⁻¹ passes a float for a stiff model of many states: a mass of 1e-300, a stiffness of 1e150)
        count, power, unit = 0, np.eye(self.dim), B / scale
        for k in range(1, self.dim + 1):
            power = power @ unit
            sv = np.linalg.svd(power, compute_uv=False)
            now = int(np.sum(sv <= k * tau / scale))
            if now <= count:
                break
            count = now
        zero[np.argsort(np.abs(lam), kind="stable")[:count]] = True
        return Spectrum(lam, zero, scale, error)

    def report(self, t: float) -> None:
        """Tell whoever watches (``progress=``) that the integration has reached ``t``."""
        if self._report is not None:
            self._report(t)

    # -- structure --------------------------------------------------------------
    @functools.cached_property
    def _sym(self) -> dict[str, Any]:
        eq, numeric = self.numeric.eq, self.numeric
        subs = {s: sp.Float(v) for s, v in numeric.values.items()}
        L = eq.L.xreplace(subs)
        D = eq.D.xreplace(subs)
        Q = eq.Q.xreplace(subs)
        q, v = list(eq.sym.q), list(eq.sym.v)
        diff = eq._derivation.calc.diff  # the derivation's differentiator: the same derivatives, far faster than sp.diff
        Lq = sp.Matrix([diff(eq.L, x) for x in q]).xreplace(subs)
        Lv = sp.Matrix([diff(eq.L, x) for x in v]).xreplace(subs)
        M = eq.M.xreplace(subs)
        Qnc = sp.Matrix([Q[i] - diff(eq.D, v[i]).xreplace(subs) for i in range(len(q))])
        return {"L": L, "D": D, "Q": Q, "G": eq.G.xreplace(subs), "Lq": Lq, "Lv": Lv, "M": M, "Qnc": Qnc,
                "f": eq.f.xreplace(subs), "A": eq.A.xreplace(subs), "b": eq.b.xreplace(subs), "q": q, "v": v}

    @functools.cached_property
    def _conservative(self) -> tuple[bool, str]:
        """Whether the energy is conserved, and why not (the cheap part of :attr:`structure`, which the energy
        check needs on every run: no derivatives taken)."""
        # decided with the run's values (a turntable given as 0 and turned in params= moves its constraint)
        eq, values = self.numeric.eq, self.numeric.values
        generic = eq.generic()
        subs = {s: sp.Float(v) for s, v in values.items()}
        reasons = []
        # Evidence first (:meth:`_sampled`): a D clearly nonzero at a state, or an L that changes with t alone, is
        # proof; an L without t among its symbols cannot depend on it.  Only what remains undecided substitutes
        # the values into the whole of D or L (seconds for a chain of 10⁴ masses).
        D, L = sp.sympify(generic["D"]), sp.sympify(generic["L"])
        sampled = self._sampled() if D != 0 or time_symbol in symbols_of([L]) else None
        if D != 0 and ((sampled is not None and sampled["dissipates"]) or not is_zero(D.xreplace(subs))):
            reasons.append("it dissipates energy (Rayleigh function D ≠ 0)")
        if not all(is_zero(x.xreplace(subs)) for x in generic["Q"]):
            reasons.append("applied forces or sources do work on it (generalized forces Q ≠ 0)")
        if time_symbol in symbols_of([L]) and ((sampled is not None and sampled["timed"])
                                               or depends_on(L.xreplace(subs), time_symbol)):
            reasons.append("its Lagrangian depends on time (prescribed motions or time-varying parameters)")
        # constraints fixed in time (Φ(q), A(q)·q̇ = 0) do no work: their forces are perpendicular to every motion
        # they allow; moving ones (a driven loop, A(q, t)·q̇ + b(q, t)) put energy in or take it out
        velocity = generic.get("velocity_constraints", sp.zeros(0, 1))
        at_rest = {x: 0 for x in eq.sym.v}
        if any(depends_on(c.xreplace(subs), time_symbol) for c in [*generic["constraints"], *velocity]) or \
                any(not is_zero(c.xreplace(subs).xreplace(at_rest)) for c in velocity):
            reasons.append("its constraints move with time, and their forces do work")
        return not reasons, "; ".join(reasons)

    def _sampled(self) -> dict[str, bool] | None:
        """``dissipates`` (D clearly nonzero) and ``timed`` (L changes with t alone) at a random state, from the
        model's energy tape with the run's values (:func:`lagrangian.numerics.c_source.programs`), or ``None``
        when it cannot be had.  Only proofs: a value within rounding of zero, or not finite, proves nothing."""
        try:
            _, energy = programs(self.numeric)
            n = self.numeric.n
            rng = np.random.default_rng(7)
            q, v = rng.uniform(-0.5, 0.5, n), rng.uniform(-0.5, 0.5, n)
            a = np.array(energy.evaluate([0.37, *q, *v])[:4])
            b = np.array(energy.evaluate([1.91, *q, *v])[:4])
        except Exception:  # (a model the tape cannot hold, a state outside its domain: no evidence)
            return None
        if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
            return None
        size = max(float(np.max(np.abs(a[:3]))), float(np.max(np.abs(b[:3]))), np.finfo(float).tiny)
        return {"dissipates": abs(a[2]) > 1e-9 * size, "timed": abs(a[3] - b[3]) > 1e-9 * size}

    @functools.cached_property
    def structure(self) -> Structure:
        """The :class:`Structure` of this problem (derived symbolically once)."""
        s = self._sym
        q, v, names = s["q"], s["v"], self.names
        why: dict[str, str] = {}

        def listed(symbols) -> str:
            return ", ".join(names[i] for i in range(self.n) if q[i] in symbols or v[i] in symbols)

        if self.first_order:
            why["first_order"] = f"coordinate(s) {', '.join(self.first_order)} have no inertia (first-order)"
        if self.constrained:
            why["constrained"] = "it has constraints kept with Lagrange multipliers"
        M = s["M"]
        m_dep = _dependence(M, q)
        constant_mass = not m_dep and not _dependence(M, [time_symbol])
        if not constant_mass:
            why["constant_mass"] = (
                f"its mass matrix depends on {listed(m_dep)}" if m_dep else "its mass matrix depends on time"
            )
        f_dep = _dependence(s["f"], v)
        velocity_free = not f_dep
        if not velocity_free:
            sources = []
            if not is_zero(s["D"]):
                sources.append("dissipation (dampers, resistors)")
            if not is_zero(s["G"]):
                sources.append("velocity-linear couplings (transducers, gyroscopic terms)")
            if not constant_mass:
                sources.append("the inertial forces of a configuration-dependent mass matrix")
            if not sources:
                sources.append("velocity-dependent applied forces")
            why["velocity_free"] = f"its forces depend on the velocities of {listed(f_dep)} through {' and '.join(sources)}"
        conservative, reasons = self._conservative
        if reasons:
            why["conservative"] = reasons
        A, b = s["A"], s["b"]
        autonomous = not A.has(time_symbol) and not b.has(time_symbol)
        state = q + [v[i] for i in self.inertial]
        linear = False
        if autonomous and not self.constrained and not (A.free_symbols & set(state)) and \
                all(e.is_polynomial(*state) for e in b):  # a cheap screen before differentiating every entry
            J = b.jacobian(state)
            linear = not (J.free_symbols & set(state))
        quadratic = not _dependence(M, v)
        return Structure(tuple(self.first_order), self.constrained, constant_mass, velocity_free, conservative,
                         autonomous, linear, quadratic, why)

    # -- the Lagrangian's pieces ------------------------------------------------
    @functools.cached_property
    def _pieces_fn(self):
        s = self._sym
        return _lambdify((time_symbol, s["q"], s["v"]), [s["Lq"], s["Lv"], s["M"], s["Qnc"]], self.numeric.signals)

    def pieces(self, t: float, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(∂L/∂q, ∂L/∂q̇, M, Q_nc)`` at ``(t, q, q̇)`` in one evaluation; ``Q_nc = Q − ∂D/∂q̇`` (loads and dissipation)."""
        self.nfev += 1
        Lq, Lv, M, Qnc = self._pieces_fn(t, q, v)
        n = self.n
        return (np.asarray(Lq, dtype=float).reshape(n), np.asarray(Lv, dtype=float).reshape(n),
                np.asarray(M, dtype=float).reshape(n, n), np.asarray(Qnc, dtype=float).reshape(n))

    def lagrangian_gradient(self, t: float, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(∂L/∂q, ∂L/∂q̇)`` at ``(t, q, q̇)``."""
        Lq, Lv, _, _ = self.pieces(t, q, v)
        return Lq, Lv

    def momentum(self, t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """The generalized momentum ``p = ∂L/∂q̇`` (``M q̇`` plus any gyroscopic or moving-frame part)."""
        return self.pieces(t, q, v)[1]

    def mass(self, t: float, q: np.ndarray) -> np.ndarray:
        """The mass matrix ``M(q, t) = ∂²L/∂q̇²``."""
        return self.pieces(t, q, np.zeros(self.n))[2]

    def forces(self, t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """The non-conservative generalized forces ``Q − ∂D/∂q̇`` (loads and dissipation)."""
        return self.pieces(t, q, v)[3]

    def velocity(self, t: float, q: np.ndarray, p: np.ndarray) -> np.ndarray:
        """The inverse of :meth:`momentum`: ``q̇ = M⁻¹ (p − p₀(q, t))`` for a Lagrangian quadratic in ``q̇``."""
        _, p0, M, _ = self.pieces(t, q, np.zeros(self.n))
        try:
            return np.linalg.solve(M, p - p0)
        except np.linalg.LinAlgError:
            raise SingularMassMatrixError(self.numeric._singular_message(t, M)) from None

    @property
    def canonical(self) -> bool:
        """Whether the problem has canonical coordinates ``(q, p)``: every coordinate inertial, no constraints, ``L`` quadratic in ``q̇``."""
        return not self.first_order and not self.constrained and self.structure.quadratic

    def to_canonical(self, t: float, y: np.ndarray) -> np.ndarray:
        """``(q, q̇) ↦ (q, p)``."""
        q = y[: self.n]
        return np.concatenate([q, self.momentum(t, q, y[self.n :])])

    def from_canonical(self, t: float, z: np.ndarray) -> np.ndarray:
        """``(q, p) ↦ (q, q̇)``."""
        q = z[: self.n]
        return np.concatenate([q, self.velocity(t, q, z[self.n :])])

    def canonical_rhs(self, t: float, z: np.ndarray) -> np.ndarray:
        """Hamilton's equations with forcing on ``z = (q, p)``: ``q̇ = M⁻¹(p − p₀)``, ``ṗ = ∂L/∂q + Q − ∂D/∂q̇``."""
        q, p = z[: self.n], z[self.n :]
        v = self.velocity(t, q, p)
        Lq, _, _, Qnc = self.pieces(t, q, v)
        return np.concatenate([v, Lq + Qnc])

    @functools.cached_property
    def _acceleration_fn(self):
        s = self._sym
        if not self.structure.separable:
            raise ModelError(f"model {self.name!r} is not separable ({self.structure.why_not_separable()}): "
                             f"its accelerations depend on more than the positions.")
        M = np.array(s["M"].tolist(), dtype=float)
        try:
            Minv = np.linalg.inv(M)
        except np.linalg.LinAlgError:
            raise SingularMassMatrixError(self.numeric._singular_message(0.0, M)) from None
        # (velocity-free within rounding: a residual such as 1e-17·q̇ of cancelled couplings is its value at rest)
        f = s["f"].xreplace({v: 0 for v in s["v"]})
        fn = _lambdify((time_symbol, s["q"]), list(f), self.numeric.signals)
        if np.array_equal(Minv, np.diag(np.diag(Minv))):
            inverse_masses = np.diag(Minv).copy()
            return lambda t, q: inverse_masses * np.array(fn(t, q), dtype=float)
        return lambda t, q: Minv @ np.array(fn(t, q), dtype=float)

    @functools.cached_property
    def _affine(self):
        """``(f₀, C)`` with ``f = f₀(q, t) − C(q, t) q̇`` as expressions, or None when ``f`` is not affine in ``q̇``."""

        s = self._sym
        v = s["v"]
        C = -s["f"].jacobian(v)
        for entry in C:
            for x in entry.free_symbols & set(v):
                if depends_on(entry, x):
                    return None
        return s["f"].xreplace({x: 0 for x in v}), C

    @property
    def velocity_affine(self) -> bool:
        """Whether the forcing is affine in the velocities, ``f = f₀(q, t) − C(q, t) q̇`` (dampers, resistors, gyroscopic terms)."""
        return self._affine is not None

    @functools.cached_property
    def _affine_fn(self):
        if self._affine is None:
            raise ModelError(f"model {self.name!r}: its forces are not affine in the velocities.")
        f0, C = self._affine
        s = self._sym
        return _lambdify((time_symbol, s["q"]), [f0, C], self.numeric.signals)

    def affine_forces(self, t: float, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(f₀(q, t), C(q, t))`` with ``M q̈ = f₀ − C q̇``, for forces affine in the velocities (:attr:`velocity_affine`).

        >>> import lagrangian as lg
        >>> m = lg.Model("damped")
        >>> _ = m.add("mass", "m", "p", m=0.3)
        >>> _ = m.add("spring", "k", ("ground", "p"), k=0.7)
        >>> _ = m.add("damper", "c", ("ground", "p"), c=0.05)
        >>> f0, C = Problem(m.numeric()).affine_forces(0.0, np.array([0.2]))
        >>> f0.round(12).tolist(), C.round(12).tolist()      # −k q and c
        ([-0.14], [[0.05]])
        """
        self.nfev += 1
        f0, C = self._affine_fn(t, q)
        n = self.n
        return np.asarray(f0, dtype=float).reshape(n), np.asarray(C, dtype=float).reshape(n, n)

    def acceleration(self, t: float, q: np.ndarray) -> np.ndarray:
        """``q̈ = M⁻¹ f(q, t)`` of a separable problem (``structure.separable``); ModelError otherwise."""
        self.nfev += 1
        return self._acceleration_fn(t, q)

    @functools.cached_property
    def _jacobi_fn(self):
        s = self._sym
        h = sum((vi * pi for vi, pi in zip(s["v"], s["Lv"])), sp.Integer(0)) - s["L"]
        return _lambdify((time_symbol, s["q"], s["v"]), h, self.numeric.signals)

    def jacobi(self, t: np.ndarray, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """The Jacobi integral ``h = p·q̇ − L`` at many states (``q``, ``v``: ``n × N``); ``T + V`` for fixed constraints."""
        t = np.asarray(t, dtype=float)
        fast = getattr(self.numeric, "_fast", None)  # compiled code in use (lagrangian.codegen)
        if fast is not None and t.ndim == 1:
            return fast.jacobi(t, q, v)
        tape = getattr(self.numeric, "_energy_tape", None)  # (a recursion's energy tape: T, V, D, L, p)
        if tape is not None:
            q, v = np.asarray(q, dtype=float), np.asarray(v, dtype=float)
            out = tape.evaluate_many(np.vstack([np.broadcast_to(t, q.shape[1:])[None], q, v]))
            return np.sum(out[4:] * v, axis=0) - out[3]
        return np.broadcast_to(np.asarray(self._jacobi_fn(t, q, v), dtype=float), t.shape).copy()


def _forget_oldest(kept: dict, most: int) -> None:
    """Make room in ``kept`` (oldest first) for one more entry of at most ``most``; safe when another thread that
    shares the model does the same."""
    while len(kept) >= most:
        try:
            kept.pop(next(iter(kept)), None)
        except (StopIteration, RuntimeError):  # emptied or changed by another thread meanwhile
            break


def _dependence(exprs, symbols) -> set:
    """The ``symbols`` some entry of ``exprs`` really depends on (:func:`lagrangian.identity.depends_on`:
    a dependence that cancels, ``sin²φ + cos²φ`` with floating-point coefficients, is none)."""
    found = set()
    entries = list(exprs)
    for x in symbols:
        if any(x in e.free_symbols and depends_on(e, x) for e in entries):
            found.add(x)
    return found
