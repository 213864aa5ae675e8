"""Steady motions of a reduced model: the remaining coordinates constant, the ignorable ones uniform.

:class:`SteadyMotion` is one solution of the steady-motion conditions
``∂R/∂q_k = 0`` (found by :meth:`ReducedModel.steady_motions`), with its
linearization and its stability; :func:`_solve` finds every real branch of the
conditions symbolically, splitting ``|x|`` and ``sign(x)`` into their cases,
:func:`_numeric_roots` every root numerically within search ranges, and
:func:`_is_angle` tells which coordinates get ``(−π, π)`` as a default search range.
A reduced model that keeps constraints on velocities (nonholonomic) has no
perturbation equations of this form (:meth:`SteadyMotion.perturbation` refuses
it); :meth:`SteadyMotion.stability` linearizes it on its constraints.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from ...base import display
from ...base.identity import is_zero
from ...errors import LagrangianError, ReductionError, UnknownNameError
from ..linearize import linearize
from .stability import Perturbation, Stability, _fmt, _off_singular
from ...base import deferred as _deferred

sp = _deferred.module("sympy", globals())


@dataclass(repr=False)
class SteadyMotion:
    """One steady motion: constant remaining coordinates, constant momenta and ignorable rates."""

    # the annotation names .reduction's ReducedModel, which imports this module: a string, never evaluated
    model: ReducedModel = field(repr=False)  # noqa: F821
    coordinates: dict[str, sp.Expr]
    momenta: dict[str, sp.Expr]
    rates: dict[str, sp.Expr]
    values: dict[sp.Symbol, sp.Expr] = field(default_factory=dict, repr=False)

    def __str__(self) -> str:
        parts = [f"{k} = {v}" for k, v in self.coordinates.items()]
        parts += [f"C_{k} = {v}" for k, v in self.momenta.items() if v != sp.Symbol(f"C_{k}", real=True)]
        parts += [f"{k}' = {v}" for k, v in self.rates.items()]
        return "steady motion: " + ", ".join(parts)

    def __repr__(self) -> str:
        return f"<SteadyMotion {str(self).partition(': ')[2]}>"

    def _repr_html_(self) -> str:
        """The steady motion's coordinates, momenta and rates, and its stability where it is numeric (Jupyter)."""
        rows = [[k, str(v)] for k, v in self.coordinates.items()]
        rows += [[f"C_{k}", str(v)] for k, v in self.momenta.items()]
        rows += [[f"{k}'", str(v)] for k, v in self.rates.items()]
        parts = [display.table(["", "value"], rows)]
        try:
            parts.append(self.stability()._repr_html_())
        except LagrangianError as exc:  # symbolic: the verdict needs values
            parts.append(f"<p><small>stability: {display.escape(exc)}</small></p>")
        return display.block("steady motion", *parts)

    def perturbation(self) -> Perturbation:
        """``M s̈ + C ṡ + K s = 0`` about this steady motion (symbolic where the steady motion is).  A reduced model
        that keeps constraints on velocities has no such form: :meth:`stability` linearizes it on them."""
        self.model._holonomic_only("the perturbation equations M s̈ + C ṡ + K s = 0 (stability() linearizes on the "
                                   "constraints instead)", ReductionError)
        eq = self.model.reconstructing(False).eq
        q, v = eq.sym.q, eq.sym.v
        at = {q[i]: self.coordinates[n] for i, n in enumerate(eq.names)} | dict.fromkeys(v, sp.Integer(0))
        subs = self._substitutions()
        f = eq.f.xreplace(subs)
        M = eq.M.xreplace(subs)
        K = (-f.jacobian(q)).xreplace(at).applyfunc(_off_singular)
        Cm = (-f.jacobian(v)).xreplace(at).applyfunc(_off_singular)
        return Perturbation(M.xreplace(at).applyfunc(_off_singular), Cm, K, list(eq.names))

    def _substitutions(self) -> dict:
        subs = dict(self.values)
        for n, C in zip(self.model.ignored, self.model._r_parts["C"]):
            if isinstance(C, sp.Symbol):
                subs[C] = self.momenta[n]
        return subs

    def stability(self, values: Mapping[str, float] | None = None) -> Stability:
        """Linear stability: eigenvalues of the perturbation equations, with a verdict.

        ``values`` gives numbers to whatever is still symbolic (parameters,
        momenta ``C_<name>``, coordinate symbols ``<name>_0``).  The verdict
        is *unstable* if an eigenvalue has a positive real part,
        *asymptotically stable* if all are negative, *marginal* when an
        eigenvalue is zero (a bifurcation: the linearization cannot decide)
        or when the oscillation is only gyroscopically stabilized (the
        effective potential is not a minimum), and *stable* when every mode
        oscillates and ``V_eff`` has a strict minimum there (the energy
        integral then bounds the perturbation).

        A reduced model that keeps constraints on velocities (a sled's knife
        edge) is linearized on them (:func:`lagrangian.frequency.linearize`,
        Kane's independent coordinates and speeds): its verdict comes from
        those eigenvalues, and an undamped one is *marginal* (no effective
        potential bounds the motion there).
        """
        if self.model.assembly.velocity_constraint_list(generic=True):
            return _on_constraints(self, values)
        pert = self.perturbation()
        needed = {str(s) for m in (pert.M, pert.C, pert.K) for s in m.free_symbols}
        names = {str(s): s for e in [*self.coordinates.values(), *self.momenta.values(), pert.M, pert.C, pert.K]
                 for s in sp.sympify(e).free_symbols}
        given = dict(values or {})
        unknown = [k for k in given if k not in names]
        if unknown:
            raise UnknownNameError("symbol", unknown[0], names)
        missing = sorted(needed - set(given))
        if missing:
            raise ReductionError(f"the steady motion is symbolic in {', '.join(missing)}: give values=... for them.")
        subs = {names[k]: float(val) for k, val in given.items()}
        try:
            M, Cm, K = (np.array(m.xreplace(subs).evalf(), dtype=float) for m in (pert.M, pert.C, pert.K))
        except TypeError:
            raise ReductionError("the perturbation equations are not finite at this steady motion (a singular point of the reduction).") from None
        if not (np.all(np.isfinite(M)) and np.all(np.isfinite(K)) and np.all(np.isfinite(Cm))):
            raise ReductionError("the perturbation equations are not finite at this steady motion (a singular point of the reduction).")
        n = len(pert.names)
        A = np.block([[np.zeros((n, n)), np.eye(n)], [-np.linalg.solve(M, K), -np.linalg.solve(M, Cm)]])
        lam = np.linalg.eigvals(A)
        # Tolerances relative to the spectrum (1/s) and to the curvature (energy/coordinate²) separately: a
        # zero eigenvalue of a double root (a Jordan block) comes out of eigvals only to about √ε of the scale.
        scale = float(np.max(np.abs(lam))) if lam.size else 0.0
        tol = 1e-7 * scale
        curvature = None
        if self.model._r_parts["quadratic"]:
            eq = self.model.reconstructing(False).eq
            Veff = eq.V.xreplace(self._substitutions())
            at = {eq.sym.q[i]: self.coordinates[nm] for i, nm in enumerate(eq.names)}
            H = sp.hessian(Veff, eq.sym.q).xreplace(at).xreplace(subs)
            try:
                curvature = np.linalg.eigvalsh(np.array(H.evalf(), dtype=float))
            except TypeError:
                curvature = None
        minimum = curvature is not None and bool(np.all(curvature > 1e-9 * float(np.max(np.abs(curvature)))))
        freqs = np.sort(np.abs(lam.imag[lam.imag > tol]))
        gyroscopic = not is_zero(self.model._r_parts["G"])
        if scale > 0.0 and np.any(lam.real > tol):
            verdict, reason = "unstable", f"an eigenvalue with positive real part ({_fmt(lam[np.argmax(lam.real)])})"
        elif scale == 0.0 or np.any(np.abs(lam) <= tol):
            verdict, reason = "marginal", ("a zero eigenvalue: the linearization cannot decide (a bifurcation point of "
                                           "the steady motions, or a neutral direction); the nonlinear terms do")
        elif np.all(lam.real < -tol):
            verdict, reason = "asymptotically stable", "every eigenvalue has a negative real part"
        elif minimum:
            verdict = "stable"
            reason = ("every mode oscillates and the effective potential has a strict minimum (curvature "
                      f"{', '.join(f'{c:.6g}' for c in curvature)}): the energy integral bounds the motion")
        elif curvature is None:
            verdict = "marginal"
            reason = ("the linearized motion oscillates without growth, but the reduced Lagrangian is not quadratic in "
                      "the velocities, so no effective potential bounds the motion: linear analysis is inconclusive")
        elif gyroscopic:
            verdict = "marginal"
            reason = ("the linearized motion oscillates without growth, but the effective potential is not a minimum "
                      f"(curvature {', '.join(f'{c:.6g}' for c in curvature)}; gyroscopic stabilization): linear "
                      "analysis is inconclusive for the full motion")
        else:
            verdict = "marginal"
            reason = ("the linearized motion oscillates without growth, but the effective potential is not a strict "
                      f"minimum (curvature {', '.join(f'{c:.6g}' for c in curvature)}): linear analysis is inconclusive")
        if curvature is not None and verdict == "unstable" and minimum and is_zero(self.model.eq.D):
            reason += "; the effective potential has a minimum there, yet a mode grows (non-conservative forces)"
        return Stability(verdict, lam, freqs, curvature, reason)


def _on_constraints(motion: SteadyMotion, values: Mapping[str, float] | None) -> Stability:
    """:meth:`SteadyMotion.stability` of a reduced model with constraints on velocities: the eigenvalues of Kane's
    state space of its linearization at the steady motion, the momenta and ``values`` as parameters."""
    given = {str(k): v for k, v in (values or {}).items()}
    params = {str(k): float(v) for k, v in motion.values.items() if isinstance(v, (int, float)) or v.is_number}
    known = {p.name for p in motion.model.parameters} | set(motion.model.parameter_values)
    params = {k: v for k, v in params.items() if k in known}
    # a momentum the reduced equations do not hold (a flywheel spinning apart from the sled) is no parameter of them
    params.update({f"C_{n}": c for n, c in motion.momenta.items() if not isinstance(c, sp.Symbol) and f"C_{n}" in known})
    params.update({k: v for k, v in given.items() if k in known})  # the others name a family's coordinates
    numbers = {sp.Symbol(k, real=True): v for k, v in given.items()}
    at = {}
    for name, x in motion.coordinates.items():
        x = sp.sympify(x).xreplace(numbers) if isinstance(x, sp.Basic) else x
        if isinstance(x, sp.Basic) and not x.is_number:
            raise ReductionError(f"the steady motion is symbolic in {', '.join(sorted(map(str, x.free_symbols)))}: "
                                 f"give values=... for them.")
        at[name] = float(x)
    missing = sorted(p.name for p in motion.model.parameters if p.name not in params)
    if missing:
        raise ReductionError(f"the steady motion is symbolic in {', '.join(missing)}: give values=... for them.")
    lin = linearize(motion.model, at=at, params=params, inputs=[], symbolic=False)
    A = lin.state_space()[0]
    lam = np.linalg.eigvals(A) if A.size else np.zeros(0, dtype=complex)
    scale = float(np.max(np.abs(lam), initial=0.0))
    tol = 1e-7 * scale
    freqs = np.sort(np.abs(lam.imag[lam.imag > tol]))
    if scale > 0.0 and np.any(lam.real > tol):
        return Stability("unstable", lam, freqs, None,
                         f"an eigenvalue with positive real part ({_fmt(lam[np.argmax(lam.real)])})")
    if scale == 0.0 or np.any(np.abs(lam) <= tol):
        return Stability("marginal", lam, freqs, None,
                         "a zero eigenvalue: the linearization on the constraints on velocities cannot decide (a "
                         "neutral direction, such as a family of motions the constraints allow)")
    if np.all(lam.real < -tol):
        return Stability("asymptotically stable", lam, freqs, None, "every eigenvalue has a negative real part")
    return Stability("marginal", lam, freqs, None,
                     "the motion on the constraints on velocities oscillates without growth, and no effective "
                     "potential bounds it there: linear analysis is inconclusive")


def _is_angle(coordinate) -> bool:
    text = f"{coordinate.name} {coordinate.description}".lower()
    return any(w in text for w in ("angle", "revolute", "theta", "phi", "alpha", "beta", "gamma"))


def _numeric_roots(model: str, coordinates, exprs, names, q, search) -> list[dict]:
    """Every root of the steady-motion conditions ``exprs`` (in ``q``) within the ``search`` ranges, ends included
    (default ``(−π, π]`` for angles, the whole turn, ``−π`` being ``π``): bracketed in one coordinate, by Newton
    from a grid of starts in several."""
    from scipy.optimize import brentq, root

    ranges, turns = [], []
    for i, n in enumerate(names):
        turns.append(n not in search and _is_angle(coordinates[i]))
        if n in search:
            lo, hi = map(float, search[n])
        elif turns[-1]:
            lo, hi = -math.pi, math.pi
        else:
            raise ReductionError(
                f"give a search range for coordinate {n!r} of {model!r}: steady_motions(..., search={{{n!r}: (lo, hi)}})."
            )
        ranges.append((lo, hi))
    fn = sp.lambdify([q], exprs, modules="numpy")
    found: list[np.ndarray] = []
    if len(q) == 1:
        lo, hi = ranges[0]
        grid = np.linspace(lo, hi, 4001)
        with np.errstate(all="ignore"):
            vals = np.array([fn([x])[0] for x in grid], dtype=float)
        for a, b, fa, fb in zip(grid[:-1], grid[1:], vals[:-1], vals[1:]):
            if not (np.isfinite(fa) and np.isfinite(fb)):
                continue
            if fa == 0:
                found.append(np.array([a]))
            elif fa * fb < 0:
                x = brentq(lambda s: fn([s])[0], a, b, xtol=1e-14, rtol=1e-14)
                scale = max(abs(fa), abs(fb))
                with np.errstate(all="ignore"):
                    if abs(fn([x])[0]) < 1e-8 * max(1.0, scale):  # a root, not a pole
                        found.append(np.array([x]))
        # a root on an end of the range (π on the default one) need not change sign inside it: it is one when the
        # value there is negligible against its neighbour's (a simple root's f'·h, h the grid's step)
        for end, inner in ((0, 1), (-1, -2)):
            fa, fb = vals[end], vals[inner]
            if np.isfinite(fa) and np.isfinite(fb) and abs(fa) <= 1e-8 * abs(fb):
                found.append(np.array([grid[end]]))
    else:
        jac = sp.lambdify([q], sp.Matrix(exprs).jacobian(q), modules="numpy")
        axes = [np.linspace(lo, hi, 9) for lo, hi in ranges]
        for start in np.array(np.meshgrid(*axes)).reshape(len(q), -1).T:
            with np.errstate(all="ignore"):
                sol = root(lambda x: np.asarray(fn(x), dtype=float), start,
                           jac=lambda x: np.asarray(jac(x), dtype=float), tol=1e-13)
            if not sol.success:
                continue
            x = np.array([lo + (xi - lo) % (2 * math.pi) if turn else xi
                          for xi, turn, (lo, hi) in zip(sol.x, turns, ranges)])
            if all(lo <= xi <= hi for xi, (lo, hi) in zip(x, ranges)):
                found.append(x)
    # on a whole turn −π is π: one steady motion, reported at π
    found = [np.array([hi if turn and xi - lo < 1e-9 else xi for xi, turn, (lo, hi) in zip(x, turns, ranges)])
             for x in found]
    unique: list[np.ndarray] = []
    for x in found:
        if not any(np.allclose(x, y, atol=1e-9) for y in unique):
            unique.append(x)
    return [{qi: sp.Float(float(xi)) for qi, xi in zip(q, x)} for x in unique]


def _solve(exprs: list[sp.Expr], unknowns: list[sp.Symbol]) -> list[dict] | None:
    """All real solutions SymPy finds, or None when it cannot solve.

    ``|x|`` and ``sign(x)`` of an unknown (a distance ``√(s²)``) are split into their two
    branches, each solved, and the solutions kept where the branch's sign holds.
    """
    folds = sorted({a.args[0] for e in exprs for a in e.atoms(sp.Abs, sp.sign) if a.args[0].free_symbols & set(unknowns)},
                   key=sp.default_sort_key)
    if folds and len(folds) <= 3:
        out = []
        for signs in itertools.product((1, -1), repeat=len(folds)):
            rule = {}
            for x, sgn in zip(folds, signs):
                rule[sp.Abs(x)] = sgn * x
                rule[sp.sign(x)] = sp.Integer(sgn)
            branch = _solve([e.xreplace(rule) for e in exprs], unknowns)
            if branch is None:
                return None
            for sol in branch:
                if any((sgn * x.xreplace(sol)).is_negative for x, sgn in zip(folds, signs)):
                    continue
                if sol not in out:
                    out.append(sol)
        return out
    try:
        sols = sp.solve(exprs, unknowns, dict=True)
    except (NotImplementedError, ValueError, TypeError):
        return None
    if not sols and any(e.free_symbols for e in exprs):
        return None if any(not e.is_rational_function(*unknowns) for e in exprs) else []
    sols += _half_turns(exprs, unknowns, sols)
    out = []
    for sol in sols:
        if any(val.is_real is False for val in sol.values()):
            continue
        if any(val.has(sp.I) and val.is_number and abs(sp.im(sp.N(val))) > 1e-12 for val in sol.values()):
            continue
        out.append({k: (sp.re(v) if v.is_number else v) for k, v in sol.items()})
    return out


def _half_turns(exprs: list[sp.Expr], unknowns: list[sp.Symbol], sols: list[dict]) -> list[dict]:
    """The solutions at ``x = π`` of an unknown ``x`` inside trigonometric functions that ``sols`` lacks.

    SymPy solves trigonometric equations through ``u = tan(x/2)``, which
    cannot reach ``x = π``: ``sin x (a cos x − g) = 0`` comes back without
    the bead at the top of its hoop.  Each such unknown is set to ``π`` and
    the conditions solved for the others (checked identically zero when
    none is left).
    """
    trig = (sp.sin, sp.cos, sp.tan, sp.cot, sp.sec, sp.csc)
    out = []
    for x in unknowns:
        if not any(f.args[0].has(x) for e in exprs for f in e.atoms(*trig)):
            continue
        if any(x in sol and sp.sympify(sol[x]).is_number and is_zero(sp.cos(sol[x]) + 1) for sol in sols):
            continue
        if any(x not in sol for sol in sols):  # left free by a solution (a family of rests): π is one of them
            continue
        at = [sp.sympify(e).xreplace({x: sp.pi}) for e in exprs]
        others = [u for u in unknowns if u != x]
        if not others:
            if all(is_zero(e) for e in at):
                out.append({x: sp.pi})
            continue
        rest = _solve(at, others)
        out += [{x: sp.pi, **sol} for sol in rest or []]
    return out
