"""The circuit bridge: map_model, compare_with_ngspice and read_netlist against closed forms, NumPy and ngspice.

Families:

- ``map_model``: a mass–spring–damper chain of 1–3 masses under a constant
  force and an inertia–torsion spring shaft of 1–2 inertias under a harmonic
  torque, each mapped under both of its analogies (force/torque–voltage and
  –current), and a series or parallel RLC circuit mapped back to its
  mechanism.  References: the element table written out from the drawn
  values (L = m, C = 1/k, R = c; C = m, L = 1/k, R = 1/c), ω² = k/m and
  ζ = c/(2√(km)) for one degree of freedom, the generalized eigenvalues of
  (K, M) and the eigenvalues of the damped first-order matrix computed with
  NumPy/SciPy from the drawn values, and the response: closed form for one
  degree of freedom, ``scipy.linalg.expm`` of the drawn matrices otherwise.
- ``compare_with_ngspice``: a series RLC driven by a DC step, a SIN or a
  single trapezoidal pulse; an RC or RL driven by a periodic pulse; a
  mass–spring–damper through its force–voltage or force–current analogue.
  References: the closed-form response at every ngspice time point (ours to
  3e-7 of the peak at the library's default DOP853 tolerances, ngspice's to
  its discretization error, 1e-4), and the library's own verdict that the two
  agree.  ngspice's step cap is 0.005 of the fastest time scale.
- ``read_netlist``: decks written here from the drawn values the way users
  write them (engineering suffixes in any case, unit letters, ``MEG`` and
  SPICE's ``M`` = milli, comments, continuation lines, ``gnd``) for a series
  RLC (DC/SIN/PULSE voltage source), a parallel RLC tank (DC/SIN current
  source) and an RC divider with a periodic PULSE and a ``.ic`` line.  Every
  parsed value is checked against the value parsed here, the simulation
  against the closed form, and the same text is run in ngspice (PySpice).

Every family also builds its symbolic twin — the same model from
``sympy.Symbol`` parameters, values given in ``params=`` — cached per
worker, and checks it gives the same structure and the same numbers.

Closed forms: an LTI system ``a₂ y'' + a₁ y' + y = u(t)`` (``a₂ = 0``: first
order) driven by sums of steps, ramps and damped sinusoids, each starting
from rest at its own time (a trapezoidal pulse is four ramps), plus the free
response from the initial state, written so that it stays accurate through
critical damping and on long overdamped runs (see :meth:`Lti.free`).
"""

from __future__ import annotations

import logging
import math
import random
import re
import traceback
from decimal import Decimal
from functools import lru_cache

import numpy as np
import scipy.linalg
import sympy as sp

import lagrangian as lg
from lagrangian.analogy import map_model
from lagrangian.compare import compare_with_ngspice
from lagrangian.linear import state_space
from lagrangian.netlist import read_netlist

from . import Case, Mismatch, close, decades, same, uniform

t = lg.t
#: ngspice's trapezoidal error is about 0.3 (ω h)² of the peak; every run here caps its step at h = 0.005/ω_max
#: (a few 1e-6), and a kink of the input (a pulse's corners) adds a little: 1e-4 of the peak is a real disagreement.
NGSPICE_REL = 1e-4
#: our own solutions against the closed forms, relative to the signal's peak
OURS_REL = 1e-8
#: compare_with_ngspice's own solution, at its default DOP853 rtol=1e-11, atol=1e-13 (the settings a user gets): DOP853's
#: global error at that rtol reaches 1e-7 of the peak on smooth overdamped runs (SciPy's DOP853 alone, same settings,
#: 7e-8), so 3e-7 is what the defaults promise
OURS_REL_DOP853 = 3e-7
#: ngspice's step cap relative to the fastest time scale of a run
CAP = 0.005


def r3(x: float) -> float:
    """``x`` as a three-significant-digit decimal (what a user types)."""
    return float(f"{x:.3g}")


# -- closed forms -----------------------------------------------------------------------------------


class Lti:
    """``a2 y'' + a1 y' + y = u(t)`` (``a2 = 0``: ``a1 y' + y = u``), solved in closed form.

    ``u`` is a list of terms, each starting from rest at time ``at``: ``("step", at, U)``,
    ``("ramp", at, slope)`` or ``("exp", at, A, lam)`` for ``Im(A e^{lam (t − at)})``.
    """

    def __init__(self, a2: float, a1: float):
        self.a2, self.a1 = float(a2), float(a1)
        if self.a2 > 0:
            self.alpha = self.a1 / (2 * self.a2)
            self.beta2 = self.alpha**2 - 1 / self.a2

    def free(self, s: np.ndarray, y0: float, dy0: float) -> tuple[np.ndarray, np.ndarray]:
        """The free response from ``y(0) = y0, y'(0) = dy0`` (first order: ``dy0`` is ignored).

        ``y = A e^{−αs} cosh βs + B e^{−αs} sinh(βs)/β``, ``A = y0``, ``B = y0' + α y0``; overdamped, through
        the two real exponentials (the slow rate β − α = −(1/a₂)/(α + β) without cancellation, no overflow on
        long runs); near critical damping through expm1, and sin(βs)/β → s."""
        s = np.asarray(s, dtype=float)
        if self.a2 == 0:
            y = y0 * np.exp(-s / self.a1)
            return y, -y / self.a1
        a, b2 = self.alpha, self.beta2
        A, B = y0, dy0 + a * y0
        if b2 > 0:
            b = math.sqrt(b2)
            E1, E2 = np.exp(-(1 / self.a2) / (a + b) * s), np.exp(-(a + b) * s)
            ch = (E1 + E2) / 2
            x = 2 * b * s
            sh = np.where(x < 1, E2 * np.expm1(np.minimum(x, 1)) / (2 * b), (E1 - E2) / (2 * b))
        else:
            w = math.sqrt(-b2)
            decay = np.exp(-a * s)
            ch = decay * np.cos(w * s)
            sh = decay * (np.sin(w * s) / w if w > 0 else s)
        return A * ch + B * sh, (B - a * A) * ch + (A * b2 - a * B) * sh

    def _particular(self, term, s):
        kind = term[0]
        if kind == "step":
            return np.full_like(s, term[2]), np.zeros_like(s)
        if kind == "ramp":
            return term[2] * (s - self.a1), np.full_like(s, term[2])
        A, lam = term[2], term[3]
        H = 1 / (self.a2 * lam**2 + self.a1 * lam + 1)
        e = A * H * np.exp(lam * s)
        return e.imag, (lam * e).imag

    def response(self, times: np.ndarray, y0: float, dy0: float, terms) -> tuple[np.ndarray, np.ndarray]:
        """``y`` and ``y'`` at ``times`` from ``y(0) = y0, y'(0) = dy0`` with the input ``terms``."""
        times = np.asarray(times, dtype=float)
        y, dy = self.free(times, y0, dy0)
        for term in terms:
            at = term[1]
            on = times >= at
            s = times[on] - at
            p, dp = self._particular(term, s)
            p0, dp0 = self._particular(term, np.zeros(1))
            h, dh = self.free(s, -p0[0], -dp0[0])
            y[on] += p + h
            dy[on] += dp + dh
        return y, dy


def pulse_terms(v1: float, v2: float, td: float, tr: float, tf: float, pw: float, per: float | None, t_end: float):
    """SPICE's PULSE as steps and ramps: v1, then a trapezoid from td (repeating every ``per`` up to ``t_end``)."""
    if per is not None and not math.isfinite(t_end):
        raise ValueError("a periodic pulse needs the end of the run")
    terms = [("step", 0.0, v1)]
    rise, fall = (v2 - v1) / tr, (v2 - v1) / tf
    start = td
    while start < t_end:
        terms += [("ramp", start, rise), ("ramp", start + tr, -rise),
                  ("ramp", start + tr + pw, -fall), ("ramp", start + tr + pw + tf, fall)]
        if per is None:
            break
        start += per
    return terms


def pulse_value(times, v1, v2, td, tr, tf, pw, per=None):
    """SPICE's PULSE at ``times`` (ngspice semantics), written out here."""
    times = np.asarray(times, dtype=float)
    s = times - td
    if per is not None:
        s = np.where(s > 0, np.mod(s, per), s)
    return np.select(
        [s <= 0, s < tr, s <= tr + pw, s < tr + pw + tf],
        [v1, v1 + (v2 - v1) * s / tr, v2, v2 + (v1 - v2) * (s - tr - pw) / tf],
        v1,
    )


def sin_terms(vo: float, va: float, freq: float, td: float = 0.0, theta: float = 0.0, phase: float = 0.0):
    """SPICE's SIN(vo va freq td theta phase): vo + va sin φ up to td,
    then vo + va e^(−θ(t−td)) sin(2πf(t−td) + φ)."""
    phi = math.radians(phase)
    terms = [("step", 0.0, vo + va * math.sin(phi))]
    if va:
        # from td on, add Im(va e^{iφ} e^{λ s}) − va sin φ, λ = −θ + 2πi f; it starts at 0 at td
        terms += [("exp", td, va * complex(math.cos(phi), math.sin(phi)), complex(-theta, 2 * math.pi * freq)),
                  ("step", td, -va * math.sin(phi))]
    return terms


def sin_value(times, vo, va, freq, td=0.0, theta=0.0, phase=0.0):
    times = np.asarray(times, dtype=float)
    phi = math.radians(phase)
    s = times - td
    on = vo + va * np.exp(-theta * s) * np.sin(2 * math.pi * freq * s + phi)
    return np.where(s <= 0, vo + va * math.sin(phi), on)


def second_order_rates(a2: float, a1: float) -> tuple[float, float]:
    """(slowest decay or oscillation rate, fastest rate) of a₂ y'' + a₁ y' + y = 0."""
    if a2 == 0:
        return 1 / a1, 1 / a1
    w0 = 1 / math.sqrt(a2)
    zeta = a1 * w0 / 2
    if zeta <= 1:
        return w0, w0
    root = math.sqrt(zeta**2 - 1)
    return w0 / (zeta + root), w0 * (zeta + root)


def peak_gap(got, want, what: str, rel: float, scale: float | None = None) -> None:
    """Raise :class:`Mismatch` unless ``got`` is within ``rel`` of the peak of ``want`` everywhere."""
    got, want = np.asarray(got, dtype=float), np.asarray(want, dtype=float)
    peak = float(np.max(np.abs(want))) if scale is None else scale
    if got.shape != want.shape:
        raise Mismatch(f"{what}: {got.shape} values, expected {want.shape}")
    err = np.abs(got - want)
    if not (np.all(np.isfinite(got)) and float(np.max(err)) <= rel * peak):
        i = int(np.argmax(np.where(np.isfinite(err), err, np.inf)))
        raise Mismatch(f"{what}: off by {float(np.max(err)):.3e} = {float(np.max(err)) / (peak or 1.0):.3e} of the peak "
                       f"{peak:.4g} (allowed {rel:g}); worst at sample {i}: got {got[i]!r}, expected {want[i]!r}")


def signed_gap(got, want, what: str, rel: float) -> None:
    """As :func:`peak_gap`, up to a sign: an element's orientation in a dual graph is the dual's choice."""
    got, want = np.asarray(got, dtype=float), np.asarray(want, dtype=float)
    sign = 1.0 if float(np.dot(got, want)) >= 0 else -1.0
    peak_gap(sign * got, want, what + (" (orientation reversed)" if sign < 0 else ""), rel)


class Findings:
    """Runs every check of a draw to the end and reports all disagreements at once, so one does not hide another.

    ``findings(fn, ...)`` runs one check; a :class:`Mismatch` is recorded, any other exception stops the draw's
    further checks.  ``done()`` re-raises a lone exception as it was, or raises one Mismatch listing everything."""

    def __init__(self):
        self.found: list[str] = []
        self.error: BaseException | None = None

    def __call__(self, fn, *args, **kwargs):
        if self.error is not None:
            return None
        try:
            return fn(*args, **kwargs)
        except Mismatch as exc:
            self.found.append(str(exc))
        except Exception as exc:  # noqa: BLE001 - reported by done(), with its type
            self.error = exc
        return None

    def done(self) -> None:
        if self.error is not None and not self.found:
            raise self.error
        if self.error is not None:
            where = traceback.extract_tb(self.error.__traceback__)[-1]
            place = f"{where.filename.rsplit('/', 1)[-1]}:{where.lineno}"
            self.found.append(f"then {type(self.error).__name__}: {self.error} ({place})")
        if self.found:
            raise Mismatch(" || ".join(self.found))


# -- reference matrices for linear chains -----------------------------------------------------------


def chain_matrices(ms, ks, cs):
    """M, C, K of a chain: element i between node i−1 (ground for i = 0) and node i."""
    n = len(ms)
    M = np.diag(np.asarray(ms, dtype=float))
    K, C = np.zeros((n, n)), np.zeros((n, n))
    for i in range(n):
        for mat, val in ((K, ks[i]), (C, cs[i])):
            mat[i, i] += val
            if i > 0:
                mat[i - 1, i - 1] += val
                mat[i, i - 1] -= val
                mat[i - 1, i] -= val
    return M, C, K


def first_order_matrix(M, C, K) -> np.ndarray:
    n = len(M)
    Minv = np.linalg.inv(M)
    return np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ K, -Minv @ C]])


def mck_response(M, C, K, F, Fc, Omega, x0, times):
    """Displacements of M x'' + C x' + K x = F + Fc cos(Ω t) from x(0) = x0, x'(0) = 0 (SciPy's expm)."""
    n = len(M)
    A = first_order_matrix(M, C, K)
    xs = np.linalg.solve(K, F)
    X = np.linalg.solve(K - Omega**2 * M + 1j * Omega * C, Fc.astype(complex)) if np.any(Fc) else np.zeros(n, complex)

    def particular(s):
        e = X * np.exp(1j * Omega * s)
        return np.concatenate([xs + e.real, (1j * Omega * e).real])

    # the free part e^{A s} y0 on a uniform grid: one exponential, applied step by step
    step = scipy.linalg.expm(A * (times[1] - times[0]))
    free, out = np.concatenate([x0, np.zeros(n)]) - particular(0.0), []
    for s in times:
        out.append((particular(s) + free)[:n])
        free = step @ free
    return np.array(out).T


def match_eigenvalues(got, want, what: str, rel: float, floor: float) -> None:
    """Every eigenvalue of ``want`` has one of ``got`` within ``rel`` of itself plus ``floor`` (greedy matching)."""
    got, want = list(np.asarray(got, dtype=complex)), list(np.asarray(want, dtype=complex))
    same(len(got), len(want), f"{what}: number of eigenvalues")
    for w in sorted(want, key=abs, reverse=True):
        j = int(np.argmin([abs(g - w) for g in got]))
        if abs(got[j] - w) > rel * abs(w) + floor:
            raise Mismatch(f"{what}: eigenvalue {w:.10g} has no match (nearest {got[j]:.10g}); all: {np.sort_complex(got)}")
        got.pop(j)


def coordinate_matrix(mapped, source: lg.Model) -> np.ndarray:
    """T with (analogue coordinates) = T (source coordinates), read off the map's linear expressions."""
    funcs = [c.function for c in source.coordinates]
    rows = []
    for c in mapped.model.coordinates:
        expr = sp.expand(mapped.coordinates[c.function])
        rows.append([float(expr.coeff(f)) for f in funcs])
    return np.array(rows)


# ================================================================================================
# map_model
# ================================================================================================

CHAIN_ANALOGIES = ("force-voltage", "force-current")
SHAFT_ANALOGIES = ("torque-voltage", "torque-current")

#: (source kind, analogy) -> (element kind, its parameter, value as a function of the source's value)
ANALOGUE = {
    ("mass", "force-voltage"): ("inductor", "L", lambda v: v),
    ("spring", "force-voltage"): ("capacitor", "C", lambda v: 1 / v),
    ("damper", "force-voltage"): ("resistor", "R", lambda v: v),
    ("force", "force-voltage"): ("voltage_source", "E", lambda v: v),
    ("mass", "force-current"): ("capacitor", "C", lambda v: v),
    ("spring", "force-current"): ("inductor", "L", lambda v: 1 / v),
    ("damper", "force-current"): ("resistor", "R", lambda v: 1 / v),
    ("force", "force-current"): ("current_source", "I", lambda v: v),
}
for (_kind, _analogy), _row in list(ANALOGUE.items()):  # the rotational analogies are the same tables
    _rot = {"mass": "inertia", "spring": "torsion_spring", "damper": "rotary_damper", "force": "torque"}[_kind]
    ANALOGUE[_rot, _analogy.replace("force", "torque")] = _row
PREFIX = {"inductor": "L", "capacitor": "C", "resistor": "R", "voltage_source": "V", "current_source": "I"}
PARAM = {"mass": "m", "spring": "k", "damper": "c", "force": "F", "inertia": "J", "torsion_spring": "k",
         "rotary_damper": "c", "torque": "tau"}


def chain_model(n: int, ms, ks, cs, F) -> lg.Model:
    """Masses m_i at p_i, each tied to the previous node (ground for the first) by k_i and c_i; F on the last."""
    model = lg.Model(f"chain of {n}")
    prev = "ground"
    for i in range(n):
        node = f"p{i + 1}"
        model.add("mass", f"m{i + 1}", node, m=ms[i])
        model.add("spring", f"k{i + 1}", (prev, node), k=ks[i])
        model.add("damper", f"c{i + 1}", (prev, node), c=cs[i])
        prev = node
    model.add("force", "F", prev, F=F)
    return model


def shaft_model(n: int, Js, ks, cs, T0, Omega) -> lg.Model:
    """Inertias J_i at a_i on torsion springs k_i and rotary dampers c_i to the previous node; T0 cos Ωt on the last."""
    model = lg.Model(f"shaft of {n}")
    prev = "ground"
    for i in range(n):
        node = f"a{i + 1}"
        model.add("inertia", f"J{i + 1}", node, J=Js[i])
        model.add("torsion_spring", f"k{i + 1}", (prev, node), k=ks[i])
        model.add("rotary_damper", f"c{i + 1}", (prev, node), c=cs[i])
        prev = node
    model.add("torque", "T", prev, tau=T0 * sp.cos(Omega * t))
    return model


def chain_values(v):
    n = int(v["n"])
    return n, *([v[f"{p}{i}"] for i in range(1, n + 1)] for p in "mkc")


@lru_cache(maxsize=None)
def chain_twin(family: str, n: int, analogy: str):
    """The family built from positive symbols and mapped (once per worker)."""
    m, k, c = ([sp.Symbol(f"{p}{i + 1}", positive=True) for i in range(n)] for p in "mkc")
    if family == "chain":
        model = chain_model(n, m, k, c, sp.Symbol("F0", positive=True))
    else:
        model = shaft_model(n, m, k, c, sp.Symbol("T0", positive=True), sp.Symbol("Omega", positive=True))
    return model, map_model(model, analogy)


def element_table(source: lg.Model, mapped, analogy: str, values: dict[str, float] | None = None) -> None:
    """Each source component became the element the analogy's table names, with the value it gives."""
    comps = mapped.model.components
    values = None if values is None else {s: sp.Float(x) for s, x in values.items()}
    for comp in source.components.values():
        kind, pname, f = ANALOGUE[comp.kind, analogy]
        mine = [name for name, src in mapped.origin.items() if src == comp.name]
        same(len(mine), 1, f"{analogy}: elements standing for {comp.name}")
        el = comps[mine[0]]
        same((el.kind, el.name), (kind, f"{PREFIX[kind]}_{comp.name}"), f"{analogy}: analogue of {comp.kind} {comp.name}")
        given = comp.params[PARAM[comp.kind]]
        if comp.kind in ("force", "torque"):
            got, want = sp.sympify(el.params[pname]), sp.sympify(given)
            if values is not None:
                got, want = got.xreplace(values), want.xreplace(values)
            for x in (0.0, 0.37, 1.9):
                close(float(got.subs(t, x)), float(want.subs(t, x)), f"{analogy}: {el.name} at t = {x}", rel=1e-14)
            continue
        want = f(float(given if values is None else sp.sympify(given).xreplace(values)))
        got = sp.sympify(el.params[pname])
        got = float(got if values is None else got.xreplace(values))
        close(got, want, f"{analogy}: {pname} of {el.name}", rel=1e-14)


def check_linear_map(family: str, v: dict, analogy: str, M, C, K, F, Fc, Omega, x0, model, twin) -> None:
    n = len(M)
    mapped = map_model(model, analogy)
    same(mapped.direction, "forward", f"{analogy}: direction")
    same(mapped.model.options["formulation"], "charge" if analogy.endswith("voltage") else "flux",
         f"{analogy}: formulation of the analogue")
    element_table(model, mapped, analogy)

    # natural frequencies and damping: the analogue's first-order matrix against the drawn M, C, K
    ss = state_space(mapped.model)
    same((len(ss.states), ss.first_order), (2 * n, []), f"{analogy}: states of the analogue (all inertial)")
    w2_ref = scipy.linalg.eigh(K, M, eigvals_only=True)
    w2 = np.linalg.eigvals(-ss.F[n:, :n]).real
    match_eigenvalues(w2, w2_ref, f"{analogy}: ω² of the analogue (generalized eigenvalues of K, M)",
                      rel=1e-9, floor=1e-13 * max(w2_ref))
    lam_ref = np.linalg.eigvals(first_order_matrix(M, C, K))
    lam = np.linalg.eigvals(ss.F)
    match_eigenvalues(lam, lam_ref, f"{analogy}: damped eigenvalues of the analogue",
                      rel=1e-8, floor=1e-12 * max(abs(lam_ref)))
    if n == 1:
        m_, k_, c_ = M[0, 0], K[0, 0], C[0, 0]
        # ω² = det F, 2ζω = −tr F for x'' + 2ζω x' + ω² x
        w = math.sqrt(ss.F[1, 0] * ss.F[0, 1] * -1 + ss.F[0, 0] * ss.F[1, 1])
        close(w, math.sqrt(k_ / m_), f"{analogy}: ω = √(k/m)", rel=1e-12)
        close(-(ss.F[0, 0] + ss.F[1, 1]) / (2 * w), c_ / (2 * math.sqrt(k_ * m_)), f"{analogy}: ζ = c/(2√(km))",
              rel=1e-12)

    # the response, through the coordinate map, against the drawn matrices
    w_min = math.sqrt(min(w2_ref))
    t_end = 5 * 2 * math.pi / w_min
    times = np.linspace(0, t_end, 11)
    names = [c.name for c in model.coordinates]
    q0, v0 = mapped.initial(dict(zip(names, x0)), {})
    res = mapped.model.simulate(t_end, initial=q0, velocity=v0, t_eval=times, method="exact")
    T = coordinate_matrix(mapped, model)
    X = np.linalg.solve(T, np.array([res[c.name] for c in mapped.model.coordinates]))
    want = mck_response(M, C, K, F, Fc, Omega, np.asarray(x0), times)
    if n == 1:  # and the closed form
        lti = Lti(M[0, 0] / K[0, 0], C[0, 0] / K[0, 0])
        terms = [("step", 0.0, F[0] / K[0, 0])]
        if Fc[0]:
            terms += [("exp", 0.0, 1j * Fc[0] / K[0, 0], 1j * Omega)]  # Im(i e^{iΩt}) = cos Ωt
        closed, _ = lti.response(times, x0[0], 0.0, terms)
        peak_gap(want[0], closed, "SciPy's expm against the closed form (the reference itself)", rel=1e-9)
    scale = float(np.max(np.abs(want)))
    for i in range(n):
        peak_gap(X[i], want[i], f"{analogy}: {names[i]} from the analogue's response", rel=1e-9, scale=scale)

    # the symbolic twin: same elements, same map, same matrix and response with the values given at run time
    sym_model, sym = twin
    same(sorted((e.name, e.kind, e.nodes) for e in sym.model.components.values()),
         sorted((e.name, e.kind, e.nodes) for e in mapped.model.components.values()), f"{analogy}: twin's elements")
    same(sym.origin, mapped.origin, f"{analogy}: twin's origins")
    same(sp.sstr(sym.coordinates), sp.sstr(mapped.coordinates), f"{analogy}: twin's coordinate map")
    params = twin_params(family, v)
    subs = {s: params[s.name] for s in sym_model.parameters}
    element_table(sym_model, sym, analogy, subs)
    circuit_params = {s.name: params[s.name] for s in sym.model.parameters}
    ss_sym = state_space(sym.model, circuit_params)
    same(ss_sym.states, ss.states, f"{analogy}: twin's states")
    peak_gap(ss_sym.F.ravel(), ss.F.ravel(), f"{analogy}: twin's first-order matrix", rel=1e-10)
    q0s, v0s = sym.initial(dict(zip(names, x0)), {}, params)
    res_sym = sym.model.simulate(t_end, initial=q0s, velocity=v0s, t_eval=times, method="exact", params=circuit_params)
    for c in mapped.model.coordinates:
        peak_gap(res_sym[c.name], res[c.name], f"{analogy}: twin's {c.name}", rel=1e-10,
                 scale=float(np.max(np.abs(res[c.name]))) or 1.0)


def twin_params(family: str, v: dict) -> dict[str, float]:
    n, ms, ks, cs = chain_values(v)
    out = {f"{p}{i + 1}": vals[i] for p, vals in zip("mkc", (ms, ks, cs)) for i in range(n)}
    if family == "chain":
        out["F0"] = v["F0"]
    else:
        out["T0"] = v["F0"]
        out["Omega"] = shaft_omega(v)
    return out


def map_chain(v):
    """Masses on springs and dampers in a chain, a constant force on the last: both analogies."""
    n, ms, ks, cs = chain_values(v)
    M, C, K = chain_matrices(ms, ks, cs)
    F = np.zeros(n)
    F[-1] = v["F0"]
    x0 = [v[f"x{i}"] for i in range(1, n + 1)]
    model = chain_model(n, ms, ks, cs, v["F0"])
    for analogy in CHAIN_ANALOGIES:
        check_linear_map("chain", v, analogy, M, C, K, F, np.zeros(n), 0.0, x0, model, chain_twin("chain", n, analogy))


def shaft_omega(v) -> float:
    """The torque's frequency: r times the slowest natural frequency, as a three-digit decimal."""
    _, Js, ks, cs = chain_values(v)
    M, _, K = chain_matrices(Js, ks, cs)
    return r3(v["r"] * math.sqrt(min(scipy.linalg.eigh(K, M, eigvals_only=True))))


def map_shaft(v):
    """Inertias on torsion springs and rotary dampers, a harmonic torque T0 cos Ωt on the last: both analogies."""
    n, Js, ks, cs = chain_values(v)
    M, C, K = chain_matrices(Js, ks, cs)
    Omega = shaft_omega(v)
    Fc = np.zeros(n)
    Fc[-1] = v["F0"]
    x0 = [v[f"x{i}"] for i in range(1, n + 1)]
    model = shaft_model(n, Js, ks, cs, v["F0"], Omega)
    for analogy in SHAFT_ANALOGIES:
        check_linear_map("shaft", v, analogy, M, C, K, np.zeros(n), Fc, Omega, x0, model, chain_twin("shaft", n, analogy))


def rlc_circuit(parallel: bool, R, L, C, S) -> lg.Model:
    """Series: V1 → R1 → L1 → C1 (loop charges).  Parallel: I1 into n1, R1, L1, C1 from n1 to ground (node fluxes)."""
    if parallel:
        model = lg.Model("parallel rlc", formulation="flux")
        model.add("current_source", "I1", ("0", "n1"), I=S)
        for kind, name, key, value in (("resistor", "R1", "R", R), ("inductor", "L1", "L", L), ("capacitor", "C1", "C", C)):
            model.add(kind, name, ("n1", "0"), **{key: value})
        return model
    model = lg.Model("series rlc")
    model.add("voltage_source", "V1", ("in", "0"), E=S)
    model.add("resistor", "R1", ("in", "a"), R=R)
    model.add("inductor", "L1", ("a", "b"), L=L)
    model.add("capacitor", "C1", ("b", "0"), C=C)
    return model


def rlc_values(v):
    """(parallel, R, L, C): R from the drawn damping ratio, a three-digit decimal."""
    parallel = v["kind"] >= 1
    L, C = v["L"], v["C"]
    Z0 = math.sqrt(L / C)
    R = r3(Z0 / (2 * v["zeta"])) if parallel else r3(2 * v["zeta"] * Z0)
    return parallel, R, L, C


@lru_cache(maxsize=None)
def rlc_twin(parallel: bool):
    R, L, C, S = sp.symbols("R L C S", positive=True)
    model = rlc_circuit(parallel, R, L, C, S)
    return model, map_model(model, "force-current" if parallel else "force-voltage")


def map_rlc(v):
    """A series RLC (force–voltage) or a parallel RLC (force–current) mapped back to its mechanism:
    mass L (C), spring 1/C (1/L), damper R (1/R); ω0 = 1/√(LC), ζ = (R/2)√(C/L) (series)
    or √(L/C)/(2R) (parallel)."""
    parallel, R, L, C = rlc_values(v)
    S = v["S"]
    Z0 = math.sqrt(L / C)
    circuit = rlc_circuit(parallel, R, L, C, S)
    analogy = "force-current" if parallel else "force-voltage"
    mapped = map_model(circuit, analogy)
    same(mapped.direction, "inverse", "direction")
    kinds = {name: c.kind for name, c in mapped.model.components.items()}
    want = {"m_C1": "mass", "k_L1": "spring", "c_R1": "damper"} if parallel else \
        {"m_L1": "mass", "k_C1": "spring", "c_R1": "damper"}
    same({k: kinds.get(k) for k in want}, want, "elements of the mechanism")
    forces = [name for name, kind in kinds.items() if kind == "force"]
    same((len(forces), len(kinds)), (1, 4), "one force for the source (its other end is ground), four elements")
    comps = mapped.model.components
    mass, spring, damper = (comps[k] for k in want)
    close(float(mass.m), C if parallel else L, "mass", rel=1e-14)
    close(float(spring.k), 1 / L if parallel else 1 / C, "stiffness", rel=1e-14)
    close(float(damper.c), 1 / R if parallel else R, "damping", rel=1e-14)
    close(abs(float(comps[forces[0]].F)), S, "force", rel=1e-14)

    w0 = 1 / math.sqrt(L * C)
    zeta = Z0 / (2 * R) if parallel else R / 2 / Z0
    ss = state_space(mapped.model)
    same((len(ss.states), ss.first_order), (2, []), "states of the mechanism")
    w = math.sqrt(-ss.F[1, 0])
    close(w, w0, "ω0 = 1/√(LC)", rel=1e-12)
    close(-ss.F[1, 1] / (2 * w), zeta, "ζ", rel=1e-12)

    # the response, mapped back to the circuit's coordinate, against the circuit's closed form
    a2, a1 = L * C, (L / R if parallel else R * C)
    slow, _ = second_order_rates(a2, a1)
    t_end = 5 * 2 * math.pi / slow
    times = np.linspace(0, t_end, 11)
    if parallel:  # i_L: LC i'' + (L/R) i' + i = S; the coordinate is λ = L i_L, its rate the voltage
        I0, V0 = r3(v["y0"] * S), r3(v["dy0"] * S * Z0)
        y, _ = Lti(a2, a1).response(times, I0, V0 / L, [("step", 0.0, S)])
        name, closed = "lambda_n1", L * y
        initial, velocity = {name: L * I0}, {name: V0}
    else:  # v_C: LC v'' + RC v' + v = E; the coordinate is the loop charge q = C v_C, its rate the current
        V0, I0 = r3(v["y0"] * S), r3(v["dy0"] * S / Z0)
        y, _ = Lti(a2, a1).response(times, V0, I0 / C, [("step", 0.0, S)])
        name, closed = "q_L1", C * y
        initial, velocity = {name: C * V0}, {name: I0}
    same(circuit.coordinate_names, [name], "the circuit's coordinate")
    x0, xv0 = mapped.initial(initial, velocity)
    res = mapped.model.simulate(t_end, initial=x0, velocity=xv0, t_eval=times, method="exact")
    T = coordinate_matrix(mapped, circuit)  # mechanism coordinate = T · circuit coordinate
    (xname,) = mapped.model.coordinate_names
    peak_gap(res[xname] / T[0, 0], closed, f"{name} from the mechanism's response", rel=1e-9)

    _, sym = rlc_twin(parallel)
    same(sorted((e.name, e.kind, e.nodes) for e in sym.model.components.values()),
         sorted((e.name, e.kind, e.nodes) for e in mapped.model.components.values()), "twin's elements")
    same(sp.sstr(sym.coordinates), sp.sstr(mapped.coordinates), "twin's coordinate map")
    params = {"R": R, "L": L, "C": C, "S": S}
    ss_sym = state_space(sym.model, params)
    peak_gap(ss_sym.F.ravel(), ss.F.ravel(), "twin's first-order matrix", rel=1e-10)
    x0s, xv0s = sym.initial(initial, velocity, params)
    res_sym = sym.model.simulate(t_end, initial=x0s, velocity=xv0s, t_eval=times, method="exact", params=params)
    peak_gap(res_sym[xname], res[xname], "twin's response", rel=1e-10)


# ================================================================================================
# compare_with_ngspice
# ================================================================================================


def check_comparison(found: Findings, cmp, want: dict[str, np.ndarray], what: str, signed: bool = False) -> None:
    """The library reports agreement; its solution matches the closed form to 1e-8 and ngspice's to its tolerance."""
    if sorted(cmp.ours) != sorted(want):
        return found(same, sorted(cmp.ours), sorted(want), f"{what}: quantities compared")
    if not cmp.worst_rel < NGSPICE_REL:
        found.found.append(f"{what}: the library reports disagreement with ngspice, worst {cmp.worst_rel:.3e}: "
                           + " ".join(cmp.table().split()))
    gap = signed_gap if signed else peak_gap
    for label, ref in want.items():
        found(gap, cmp.ours[label], ref, f"{what}: our {label} against the closed form", OURS_REL_DOP853)
        found(gap, cmp.spice[label], ref, f"{what}: ngspice's {label} against the closed form", NGSPICE_REL)


def check_twin_comparison(found: Findings, run, cmp, what: str) -> None:
    """The symbolic twin's comparison (``run()``): the same quantities, the same ngspice run (the same netlist text:
    1e-9), the same solution to what DOP853 promises (its steps across a pulse's corners differ by round-off)."""
    twin = found(run)
    if twin is None:
        return
    if sorted(twin.ours) != sorted(cmp.ours) or twin.time.size != cmp.time.size:
        return found(same, (sorted(twin.ours), twin.time.size), (sorted(cmp.ours), cmp.time.size),
                     f"{what}: twin's quantities and ngspice time points")
    for label in cmp.ours:
        found(peak_gap, twin.spice[label], cmp.spice[label], f"{what}: twin's ngspice {label}", 1e-9)
        found(peak_gap, twin.ours[label], cmp.ours[label], f"{what}: twin's own {label}", OURS_REL_DOP853)


def twin_values(model: lg.Model, values: dict[str, float]) -> dict[str, float]:
    """``values`` for exactly the twin's symbols."""
    return {s.name: values[s.name] for s in model.parameters}


def series_wave(wave: int, p) -> sp.Expr:
    """The source of the series RLC: E (a step at t = 0), vo + E sin(2πf t + φ), or one trapezoid vo → E → vo."""
    if wave == 0:
        return p["E"]
    if wave == 1:
        return p["vo"] + p["E"] * sp.sin(2 * sp.pi * p["f"] * t + p["ph"] * sp.pi / 180)
    vo, E, td, tr, pw, tf = (p[k] for k in ("vo", "E", "td", "tr", "pw", "tf"))
    return sp.Piecewise((vo, t < td), (vo + (E - vo) * (t - td) / tr, t < td + tr), (E, t < td + tr + pw),
                        (E + (vo - E) * (t - td - tr - pw) / tf, t < td + tr + pw + tf), (vo, True))


@lru_cache(maxsize=None)
def series_twin(wave: int) -> lg.Model:
    p = {k: sp.Symbol(k, positive=True) for k in ("R", "L", "C", "E", "f", "tr", "pw", "tf")}
    p |= {"vo": sp.Symbol("vo", real=True), "ph": sp.Symbol("ph", real=True), "td": sp.Symbol("td", nonnegative=True)}
    return rlc_circuit(False, p["R"], p["L"], p["C"], series_wave(wave, p))


def compare_series(v):
    """Series RLC, v_C from LC v'' + RC v' + v = E(t), i = C v'."""
    L, C, E = v["L"], v["C"], v["E"]
    Z0 = math.sqrt(L / C)
    R = r3(2 * v["zeta"] * Z0)
    w0 = 1 / math.sqrt(L * C)
    T0 = 2 * math.pi / w0
    wave = int(v["wave"])
    p = {"R": R, "L": L, "C": C, "E": E, "vo": r3(v["off"] * E), "f": r3(v["fr"] / T0), "ph": r3(v["ph"])}
    p |= {k: r3(v[k] * T0) for k in ("td", "tr", "pw", "tf")}
    if wave == 0:
        terms, w_in, name = [("step", 0.0, E)], 0.0, "DC step"
    elif wave == 1:
        terms, w_in, name = sin_terms(p["vo"], E, p["f"], phase=p["ph"]), 2 * math.pi * p["f"], "SIN"
    else:
        terms, w_in, name = pulse_terms(p["vo"], E, p["td"], p["tr"], p["tf"], p["pw"], None, math.inf), 0.0, "pulse"
    V0, I0 = r3(v["v0"] * E), r3(v["i0"] * E / Z0)
    _, fast = second_order_rates(L * C, R * C)
    t_end = 5 * T0
    cap = CAP / max(fast, w_in, w0)
    state = {"initial": {"q_L1": C * V0}, "velocity": {"q_L1": I0}}
    cmp = compare_with_ngspice(rlc_circuit(False, R, L, C, series_wave(wave, p)), t_end, max_step=cap, **state)
    vc, dvc = Lti(L * C, R * C).response(cmp.time, V0, I0 / C, terms)
    what = f"series RLC, {name}"
    found = Findings()
    check_comparison(found, cmp, {"v(C1)": vc, "i(L1)": C * dvc}, what)
    twin = series_twin(wave)
    check_twin_comparison(found, lambda: compare_with_ngspice(twin, t_end, max_step=cap, params=twin_values(twin, p),
                                                              **state), cmp, what)
    found.done()


def first_order_circuit(rl: bool, R, X, E) -> lg.Model:
    model = lg.Model("rl" if rl else "rc")
    model.add("voltage_source", "V1", ("in", "0"), E=E)
    model.add("resistor", "R1", ("in", "out"), R=R)
    if rl:
        model.add("inductor", "L1", ("out", "0"), L=X)
    else:
        model.add("capacitor", "C1", ("out", "0"), C=X)
    return model


def periodic_pulse(v1, v2, td, tr, tf, pw, per):
    """A SPICE PULSE written with SymPy as a user would: a trapezoid in Mod(t − td, per)."""
    s = sp.Mod(t - td, per)
    return sp.Piecewise((v1, t <= td), (v1 + (v2 - v1) * s / tr, s < tr), (v2, s <= tr + pw),
                        (v2 + (v1 - v2) * (s - tr - pw) / tf, s < tr + pw + tf), (v1, True))


def compare_first_order(v):
    """RC (v_C) or RL (i_L) under a periodic pulse: τ y' + y = u, τ = RC or L/R."""
    rl = v["kind"] >= 1
    R, V = v["R"], v["E"]
    X = r3(v["tau"] * R) if rl else r3(v["tau"] / R)  # L = τR, C = τ/R
    tau = X / R if rl else R * X
    v1 = r3(v["off"] * V)
    td, tr, tf, pw = (r3(v[k] * tau) for k in ("td", "tr", "tf", "pw"))
    per = r3(tr + pw + tf + v["gap"] * tau)
    expr = periodic_pulse(v1, V, td, tr, tf, pw, per)
    t_end = td + 2.5 * per
    y0 = r3(v["y0"] * V)  # the capacitor's voltage, or R times the inductor's current
    cap = CAP * min(tau, 5 * tr, 5 * tf)  # ngspice rounds a pulse's corners by about h²/(8 τ t_r)
    terms = pulse_terms(v1, V, td, tr, tf, pw, per, t_end)
    if rl:
        i0 = r3(y0 / R)
        state = {"initial": {"q_L1": 0.0}, "velocity": {"q_L1": i0}}
        cmp = compare_with_ngspice(first_order_circuit(True, R, X, expr), t_end, max_step=cap, **state)
        y, _ = Lti(0.0, tau).response(cmp.time, R * i0, 0.0, terms)
        want = {"i(L1)": y / R}
    else:
        state = {"initial": {"q_R1": X * y0}}
        cmp = compare_with_ngspice(first_order_circuit(False, R, X, expr), t_end, max_step=cap, **state)
        y, _ = Lti(0.0, tau).response(cmp.time, y0, 0.0, terms)
        want = {"v(C1)": y}
    what = f"{'RL' if rl else 'RC'} under a periodic pulse"
    found = Findings()
    check_comparison(found, cmp, want, what)
    # the twin: R and L (C) symbolic; the pulse keeps its numbers, as a deck's PULSE does
    Rs, Xs = sp.symbols("R X", positive=True)
    check_twin_comparison(found, lambda: compare_with_ngspice(first_order_circuit(rl, Rs, Xs, expr), t_end, max_step=cap,
                                                              params={"R": R, "X": X}, **state), cmp, what)
    found.done()


def msd_model(m, k, c, F) -> lg.Model:
    model = lg.Model("msd")
    model.add("mass", "m", "p", m=m)
    model.add("spring", "k", ("ground", "p"), k=k)
    model.add("damper", "c", ("ground", "p"), c=c)
    model.add("force", "F", "p", F=F)
    return model


@lru_cache(maxsize=None)
def msd_twin(harmonic: bool) -> lg.Model:
    m, k, c, F0, Omega = sp.symbols("m k c F0 Omega", positive=True)
    return msd_model(m, k, c, F0 * sp.sin(Omega * t) if harmonic else F0)


def compare_msd(v):
    """m x'' + c x' + k x = F(t) through its analogue: i(L_m) or v(C_m) is ẋ, v(C_k) or i(L_k) is k x (up to
    the orientation the analogue gives each element)."""
    analogy = "force-current" if v["kind"] >= 1 else "force-voltage"
    m, k, F0 = v["m"], v["k"], v["F0"]
    c = r3(2 * v["zeta"] * math.sqrt(k * m))
    w0 = math.sqrt(k / m)
    T0 = 2 * math.pi / w0
    harmonic = v["wave"] >= 1
    Omega = r3(v["fr"] * w0)
    F = F0 * sp.sin(Omega * t) if harmonic else F0
    terms = [("exp", 0.0, F0 / k, 1j * Omega)] if harmonic else [("step", 0.0, F0 / k)]
    x0, v0 = r3(v["x0"] * F0 / k), r3(v["v0"] * F0 / math.sqrt(k * m))
    _, fast = second_order_rates(m / k, c / k)
    t_end = 5 * T0
    cap = CAP / max(fast, w0, Omega if harmonic else 0.0)
    state = {"initial": {"x_p": x0}, "velocity": {"x_p": v0}}
    cmp = compare_with_ngspice(msd_model(m, k, c, F), t_end, analogy=analogy, max_step=cap, **state)
    x, dx = Lti(m / k, c / k).response(cmp.time, x0, v0, terms)
    want = {"i(L_m)": dx, "v(C_k)": k * x} if analogy == "force-voltage" else {"v(C_m)": dx, "i(L_k)": k * x}
    what = f"mass–spring–damper via {analogy}"
    found = Findings()
    check_comparison(found, cmp, want, what, signed=True)
    twin = msd_twin(harmonic)
    params = twin_values(twin, {"m": m, "k": k, "c": c, "F0": F0, "Omega": Omega})
    check_twin_comparison(found, lambda: compare_with_ngspice(twin, t_end, analogy=analogy, max_step=cap,
                                                              params=params, **state), cmp, what)
    found.done()


# ================================================================================================
# read_netlist
# ================================================================================================

#: SPICE's scale suffixes, parsed here (not with the library); letters after a number or a suffix are units
SUFFIXES = (("meg", 6), ("mil", None), ("t", 12), ("g", 9), ("k", 3), ("m", -3), ("u", -6), ("n", -9), ("p", -12),
            ("f", -15))
_NUM = re.compile(r"([+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)([A-Za-z]*)\Z")


def parse_spice(text: str) -> float:
    """A SPICE number, parsed here independently of lagrangian.netlist.parse_number (no mil: never written)."""
    match = _NUM.match(text)
    if not match:
        raise ValueError(text)
    mantissa, letters = match.groups()
    exp = next((e for s, e in SUFFIXES if letters.lower().startswith(s)), 0)
    return float(Decimal(mantissa).scaleb(exp))


class Writer:
    """Numbers and words as users write them: 4.7k, 4700, 4.7e3, 10uF, 1MEG, 5M (SPICE's milli), mixed case."""

    NAMES = {12: ["t", "T"], 9: ["g", "G"], 6: ["meg", "MEG", "Meg"], 3: ["k", "K"], 0: [""], -3: ["m", "M"],
             -6: ["u", "U"], -9: ["n", "N"], -12: ["p", "P"], -15: ["f", "F"]}

    def __init__(self, seed: float):
        self.rng = random.Random(repr(seed))

    def __call__(self, x: float, unit: str = "") -> str:
        x = float(x)
        if x == 0:
            return "0"
        e3 = max(-15, min(12, 3 * math.floor(math.log10(abs(x)) / 3)))
        style = self.rng.random()
        if style < 0.15:  # exponent notation, never with a unit after it (a trailing F would be femto)
            s = re.sub(r"e([+-])0*(\d)", lambda m: "e" + ("-" if m.group(1) == "-" else "") + m.group(2), f"{x:.3g}")
            return s.replace("e", self.rng.choice("eE"))
        if style < 0.35 and e3 - 3 >= -15:  # the next suffix down: 4700u
            e3 -= 3
        mantissa = format(Decimal(repr(x)).scaleb(-e3).normalize(), "f")
        suffix = self.rng.choice(self.NAMES[e3])
        if unit and suffix and self.rng.random() < 0.5:
            return mantissa + suffix + unit
        if unit and not suffix and unit[0].lower() not in "fmgtpnuk" and self.rng.random() < 0.5:
            return mantissa + unit
        return mantissa + suffix

    def case(self, word: str) -> str:
        return self.rng.choice([word.lower(), word.upper(), word[:1].upper() + word[1:].lower()])

    def chance(self, p: float) -> bool:
        return self.rng.random() < p


class Deck:
    """A netlist being written, with the text of every number in it (to check the parse against)."""

    def __init__(self, seed: float, title: str):
        self.w = Writer(seed)
        self.lines = ([""] if self.w.chance(0.3) else []) + [title]  # the title is the first non-blank line
        self.numbers: list[tuple[str, float, str]] = []

    def num(self, what: str, x: float, unit: str = "") -> str:
        text = self.w(x, unit)
        self.numbers.append((what, x, text))
        return text

    def comment(self, text: str) -> None:
        if self.w.chance(0.6):
            self.lines.append(f"* {text}")

    def blank(self) -> None:
        if self.w.chance(0.2):
            self.lines.append("")

    def line(self, tokens: list[str], note: str = "") -> None:
        """One line, split over a continuation line now and then, with an end-of-line comment sometimes."""
        cut = self.w.rng.randrange(3, len(tokens)) if len(tokens) > 3 and self.w.chance(0.4) else None
        tail = f" ; {note}" if note and self.w.chance(0.5) else ""
        if cut is None:
            self.lines.append(" ".join(tokens) + tail)
        else:
            self.lines += [" ".join(tokens[:cut]), "+ " + " ".join(tokens[cut:]) + tail]
        self.blank()

    def ground(self) -> str:
        return self.w.rng.choice(["0", "0", "gnd", "GND"])

    def tran(self, t_end: float, cap: float) -> tuple[float, float, float]:
        """A ``.tran step stop 0 tmax uic`` line; returns (step, stop, tmax) as drawn."""
        step, stop, tmax = r3(t_end / 500), r3(t_end), r3(cap)
        self.line([self.w.case(".tran"), self.num(".tran step", step, "s"), self.num(".tran stop", stop, "s"), "0",
                   self.num(".tran tmax", tmax, "s"), self.w.case("uic")])
        return step, stop, tmax

    def text(self) -> str:
        tail = ["* nothing after .end is read", "R99 x y 1"] if self.w.chance(0.2) else []
        return "\n".join(self.lines + [self.w.case(".end"), *tail, ""])

    def check_numbers(self) -> None:
        """The writer's own texts read back here as the drawn values (a check of this file, not of the library)."""
        for what, x, text in self.numbers:
            if parse_spice(text) != x:
                raise RuntimeError(f"benchmark writer: {what} {x!r} written as {text!r}")


def ngspice(text: str) -> dict[str, np.ndarray]:
    """Run ``text`` in ngspice's shared library (PySpice); every vector of its transient plot by lower-case name."""
    from PySpice.Spice.NgSpice.Shared import NgSpiceShared

    logging.getLogger("PySpice").setLevel(logging.ERROR)
    ng = NgSpiceShared.new_instance()
    ng.load_circuit(text)
    try:
        ng.run()
        plot = ng.plot(None, ng.last_plot)
        return {name.lower(): np.asarray(vec._data, dtype=float) for name, vec in plot.items()}
    finally:
        ng.destroy()
        ng.remove_circuit()


def source_spec(deck: Deck, v, amp: float, T: float, allow_pulse: bool, plain: bool, until: float):
    """The drawn source as SPICE text; returns (text, closed-form terms, value function, symbolic twin's
    expression and values, fastest rate, kind).

    ``plain``: a SIN without delay or damping.  A source the formulation fixes a coordinate with (a voltage
    source in node fluxes, a current source in loop charges) is integrated by SymPy when the deck is read: in
    milliseconds for a plain sine, in seconds with a delay or damping (see the report), too slow for a
    thousand draws — so the other formulation gets plain sines only."""
    w = deck.w
    wave = int(v["wave"])
    if wave == 2 and not allow_pulse:
        wave = 1
    if wave == 0:
        text = deck.num("DC value", amp)
        A = sp.Symbol("A", real=True)
        return (f"{w.case('dc')} {text}" if w.chance(0.5) else text), [("step", 0.0, amp)], \
            (lambda times: np.full_like(times, amp)), (A, {"A": amp}), 0.0, "DC"
    vo = r3(v["off"] * amp)
    if wave == 1:
        freq, phase = r3(v["fr"] / T), r3(v["ph"])
        td, theta = (0.0, 0.0) if plain else (r3(v["td"] * T), r3(v["theta"] / T))
        args = [deck.num("SIN offset", vo), deck.num("SIN amplitude", amp), deck.num("SIN frequency", freq, "Hz")]
        if td or theta or phase:
            args += [deck.num("SIN delay", td, "s"), deck.num("SIN damping", theta), deck.num("SIN phase", phase)]
        spec = f"{w.case('sin')}({' '.join(args)})" if w.chance(0.8) else f"{w.case('sin')} {' '.join(args)}"
        s = {k: sp.Symbol(k, real=True) for k in ("vo", "va", "ph")}
        s |= {"f": sp.Symbol("f", positive=True), "td": sp.Symbol("td", nonnegative=True),
              "theta": sp.Symbol("theta", nonnegative=True)}
        phi = s["ph"] * sp.pi / 180
        if plain:
            expr = s["vo"] + s["va"] * sp.sin(2 * sp.pi * s["f"] * t + phi)
        else:
            x = t - s["td"]
            expr = sp.Piecewise((s["vo"] + s["va"] * sp.sin(phi), t <= s["td"]),
                                (s["vo"] + s["va"] * sp.exp(-s["theta"] * x) * sp.sin(2 * sp.pi * s["f"] * x + phi), True))
        values = {"vo": vo, "va": amp, "f": freq, "ph": phase, "td": td, "theta": theta}
        return spec, sin_terms(vo, amp, freq, td, theta, phase), \
            (lambda times: sin_value(times, vo, amp, freq, td, theta, phase)), (expr, values), \
            2 * math.pi * freq + theta, "SIN" if plain else "delayed damped SIN"
    td, tr, tf, pw = (r3(v[k] * T) for k in ("td", "tr", "tf", "pw"))
    per = r3(tr + pw + tf + v["gap"] * T)
    args = [deck.num("PULSE v1", vo), deck.num("PULSE v2", amp), deck.num("PULSE delay", td, "s"),
            deck.num("PULSE rise", tr, "s"), deck.num("PULSE fall", tf, "s"), deck.num("PULSE width", pw, "s"),
            deck.num("PULSE period", per, "s")]
    sep = ", " if w.chance(0.2) else " "
    s = {k: sp.Symbol(k, real=True) for k in ("v1", "v2")}
    s |= {k: sp.Symbol(k, positive=True) for k in ("tr", "tf", "pw", "per")} | {"td": sp.Symbol("td", nonnegative=True)}
    expr = periodic_pulse(s["v1"], s["v2"], s["td"], s["tr"], s["tf"], s["pw"], s["per"])
    values = {"v1": vo, "v2": amp, "td": td, "tr": tr, "tf": tf, "pw": pw, "per": per}
    return f"{w.case('pulse')}({sep.join(args)})", pulse_terms(vo, amp, td, tr, tf, pw, per, until), \
        (lambda times: pulse_value(times, vo, amp, td, tr, tf, pw, per)), (expr, values), 0.0, "PULSE"


def expect_pulse_refused(text: str, formulation: str, element: str, what: str) -> None:
    """A PULSE source that this formulation would have to integrate is refused, naming the line and the way out."""
    try:
        read_netlist(text, formulation=formulation)
    except lg.ModelError as exc:
        other = "charge" if formulation == "flux" else "flux"
        if not re.search(rf"line \d+ \({re.escape(element)}\).*PULSE.*formulation='{other}'", str(exc)):
            raise Mismatch(f"{what}: the refusal does not name the line and the other formulation: {exc}") from None
    else:
        raise Mismatch(f"{what}: a PULSE source the {formulation} formulation must integrate was read, not refused")


def check_source(net, name: str, value, stop: float, amp: float, what: str) -> None:
    """The parsed source's waveform against SPICE's semantics, written out here, on a grid over the run."""
    comp = net.model.component(name)
    expr = comp.E if comp.kind == "voltage_source" else comp.I
    grid = np.linspace(0, stop, 211)
    got = np.broadcast_to(np.asarray(sp.lambdify(t, expr, "numpy")(grid), dtype=float), grid.shape)
    peak_gap(got, value(grid), f"{what}: the waveform of {name}", 1e-12, scale=abs(amp))


def check_values(comps, names: dict[str, str], values: dict[str, tuple[str, float]], deck: Deck, what: str) -> None:
    """Every element value read from the deck is the drawn value (the deck's text parsed here gives it exactly)."""
    for key, (pname, want) in values.items():
        got = float(getattr(comps[names[key]], pname))
        if got != want:
            texts = [text for label, _, text in deck.numbers if label == key]
            raise Mismatch(f"{what}: {names[key]} written {texts[0]!r} (that is {want!r}) read as {got!r}")


def check_against_ngspice(found: Findings, text: str, net, ours, probes: dict, what: str) -> None:
    """The same text in ngspice: each probe ``label: (vector, closed form)`` against the closed form on all of
    ngspice's time points, and our solution (``ours(result)``, solved again on 300 of ngspice's points) against
    ngspice's there."""
    spice = found(ngspice, text)
    if spice is None:
        return
    tt = spice["time"]
    for label, (vector, closed) in probes.items():
        found(peak_gap, spice[vector], closed(tt), f"{what}: ngspice's {label} against the closed form", NGSPICE_REL)
    pick = np.unique(np.linspace(0, np.searchsorted(tt, net.tran.stop, side="right") - 1, 300).astype(int))
    mine = found(lambda: ours(net.simulate(t_eval=tt[pick], method="exact")))
    for label, (vector, _) in probes.items() if mine is not None else ():
        found(peak_gap, mine[label], spice[vector][pick], f"{what}: our {label} against ngspice's", NGSPICE_REL,
              scale=float(np.max(np.abs(spice[vector]))))


def check_deck_twin(net, res, twin: lg.Model, params: dict, what: str) -> None:
    """The same circuit built in Python from symbols, values in params=: same coordinates, same run to 1e-10."""
    ours = {n.lower(): n for n in net.model.coordinate_names}
    same([n.lower() for n in twin.coordinate_names], list(ours), f"{what}: twin's coordinates")
    initial = {n: net.initial[ours[n.lower()]] for n in twin.coordinate_names}
    velocity = {n: net.velocity[ours[n.lower()]] for n in twin.coordinate_names if ours[n.lower()] in net.velocity}
    got = twin.simulate(net.tran.stop, initial=initial, velocity=velocity, params=twin_values(twin, params),
                        t_eval=res.t, method="exact")
    for n in twin.coordinate_names:
        want = res[ours[n.lower()]]
        peak_gap(got[n], want, f"{what}: twin's {n}", 1e-10, scale=float(np.max(np.abs(want))) or 1.0)


@lru_cache(maxsize=None)
def rlc_deck_twin(parallel: bool, formulation: str, kind: str) -> lg.Model:
    """The deck's circuit from symbols R1, L1, C1 and the source's own symbols (SPICE semantics written here)."""
    v = {"wave": {"DC": 0, "SIN": 1, "delayed damped SIN": 1, "PULSE": 2}[kind], "off": 0.5, "fr": 1, "ph": 1,
         "td": 0.1, "theta": 0.1, "tr": 0.1, "tf": 0.1, "pw": 0.1, "gap": 0.1}
    expr = source_spec(Deck(0.5, ""), v, 1.0, 1.0, True, kind == "SIN", 1.0)[3][0]
    R, L, C = (sp.Symbol(n, positive=True) for n in ("R1", "L1", "C1"))
    model = lg.Model("twin", formulation=formulation)
    if parallel:
        model.add("current_source", "I1", ("0", "n1"), I=expr)
        nodes = {"R1": ("n1", "0"), "L1": ("n1", "0"), "C1": ("n1", "0")}
    else:
        model.add("voltage_source", "V1", ("in", "0"), E=expr)
        nodes = {"R1": ("in", "a"), "L1": ("a", "b"), "C1": ("b", "0")}
    model.add("resistor", "R1", nodes["R1"], R=R)
    model.add("inductor", "L1", nodes["L1"], L=L)
    model.add("capacitor", "C1", nodes["C1"], C=C)
    return model


def read_rlc(v, parallel: bool):
    """A series RLC deck (V1 → R1 → L1 → C1; v_C from LC v'' + RC v' + v = E) or a parallel RLC tank deck
    (I1 into n1; R1, L1, C1 to ground; i_L from LC i'' + (L/R) i' + i = I), ic= on L1 and C1; read in the
    formulation where the source is a load, or in the other one, where it fixes a coordinate."""
    L, C, S = v["L"], v["C"], v["E"]
    Z0 = math.sqrt(L / C)
    R = r3(Z0 / (2 * v["zeta"])) if parallel else r3(2 * v["zeta"] * Z0)
    T0 = 2 * math.pi * math.sqrt(L * C)
    natural, other = ("flux", "charge") if parallel else ("charge", "flux")
    deck = Deck(v["style"], f"{'Parallel' if parallel else 'Series'} RLC: R={R:g} L={L:g} C={C:g}")
    w = deck.w
    formulation = other if v["form"] >= 1 else natural
    integrated = formulation == other  # the source fixes a coordinate: SymPy integrates it when reading
    deck.comment("generated from drawn values")
    spec, terms, value, (_, source_values), w_in, kind = source_spec(deck, v, S, T0, True, integrated, 5 * T0)
    g = deck.ground()
    names = {k: w.case(k) for k in ("V1", "I1", "R1", "L1", "C1")}
    src = names["I1"] if parallel else names["V1"]
    ic = w.case("ic") + "="
    if parallel:
        I0, V0 = r3(v["i0"] * S), r3(v["v0"] * S * Z0)
        node = w.case("n1")
        deck.line([src, g, node, *spec.split(" ")], "drives its current into n1")
        deck.line([names["R1"], node, g, deck.num("R1", R, w.case("ohm"))])
        deck.comment("the tank")
        deck.line([names["L1"], node, g, deck.num("L1", L, "H"), ic + deck.num("L1 ic", I0, "A")])
        deck.line([names["C1"], w.case("n1"), g, deck.num("C1", C, "F"), ic + deck.num("C1 ic", V0, "V")], "charged")
        lti, y0, dy0 = Lti(L * C, L / R), I0, V0 / L
        probes = {"v(C1)": ("n1", lambda r: L * r[1]), "i(L1)": ("l1#branch", lambda r: r[0])}
    else:
        V0, I0 = r3(v["v0"] * S), r3(v["i0"] * S / Z0)
        deck.line([src, w.case("in"), g, *spec.split(" ")], "the source")
        deck.line([names["R1"], w.case("in"), w.case("a"), deck.num("R1", R, w.case("ohm"))])
        deck.line([names["L1"], "a", w.case("b"), deck.num("L1", L, "H"), ic + deck.num("L1 ic", I0, "A")], "a current")
        deck.line([names["C1"], w.case("b"), g, deck.num("C1", C, "F"), ic + deck.num("C1 ic", V0, "V")])
        lti, y0, dy0 = Lti(L * C, R * C), V0, I0 / C
        probes = {"v(C1)": ("b", lambda r: r[0]), "i(L1)": ("l1#branch", lambda r: C * r[1])}
    _, fast = second_order_rates(L * C, lti.a1)
    step, stop, tmax = deck.tran(5 * T0, CAP / max(fast, w_in, 2 * math.pi / T0))
    text = deck.text()
    deck.check_numbers()
    what = f"{'parallel' if parallel else 'series'} RLC deck, {kind}, {formulation}"
    if kind == "PULSE" and integrated:
        return expect_pulse_refused(text, formulation, src, what)

    net = read_netlist(text, formulation=formulation)
    comps = net.model.components
    same(sorted(comps), sorted([src, names["R1"], names["L1"], names["C1"]]), f"{what}: components, named as written")
    found = Findings()
    found(check_values, comps, names, {"R1": ("R", R), "L1": ("L", L), "C1": ("C", C)}, deck, what)
    found(same, net.ic, {names["L1"]: I0, names["C1"]: V0}, f"{what}: ic= values")
    found(same, (net.tran.step, net.tran.stop, net.tran.max_step, net.tran.uic), (step, stop, tmax, True),
          f"{what}: .tran")
    found(check_source, net, src, value, stop, S, what)
    # our run on the .tran grid, solved exactly (it is linear time-invariant), against the closed form
    res = net.simulate(method="exact")
    closed = lti.response(res.t, y0, dy0, terms)

    def quantities(r):
        return {"v(C1)": net.capacitor_voltage(r, names["C1"]), "i(L1)": net.inductor_current(r, names["L1"])}

    ours = quantities(res)
    for label, (_, pick) in probes.items():
        found(peak_gap, ours[label], pick(closed), f"{what}: our {label} against the closed form", OURS_REL)
    check_against_ngspice(found, text, net, quantities, {
        label: (vec, lambda tt, pick=pick: pick(lti.response(tt, y0, dy0, terms))) for label, (vec, pick) in probes.items()
    }, what)
    found(check_deck_twin, net, res, rlc_deck_twin(parallel, formulation, kind),
          {"R1": R, "L1": L, "C1": C} | source_values, what)
    found.done()


def read_series(v):
    read_rlc(v, parallel=False)


def read_parallel(v):
    read_rlc(v, parallel=True)


@lru_cache(maxsize=None)
def divider_twin() -> lg.Model:
    R1, R2, C1 = (sp.Symbol(n, positive=True) for n in ("R1", "R2", "C1"))
    v = {"wave": 2, "off": 0.5, "td": 0.1, "tr": 0.1, "tf": 0.1, "pw": 0.1, "gap": 0.1}
    expr = source_spec(Deck(0.5, ""), v, 1.0, 1.0, True, False, 1.0)[3][0]
    model = lg.Model("divider twin")
    model.add("voltage_source", "V1", ("in", "0"), E=expr)
    model.add("resistor", "R1", ("in", "out"), R=R1)
    model.add("resistor", "R2", ("out", "0"), R=R2)
    model.add("capacitor", "C1", ("out", "0"), C=C1)
    return model


def read_divider(v):
    """An RC divider under a periodic PULSE, the capacitor started by a .ic line: τ v' + v = g u,
    g = R2/(R1 + R2), τ = C R1 R2/(R1 + R2)."""
    R1, C1, V = v["R"], v["C"], v["E"]
    R2 = r3(v["ratio"] * R1)
    g = R2 / (R1 + R2)
    tau = C1 * R1 * R2 / (R1 + R2)
    V0 = r3(v["v0"] * V)
    deck = Deck(v["style"], "RC divider with a pulse")
    w = deck.w
    deck.comment("a periodic pulse into a loaded RC")
    until = (v["td"] + 2.5 * (1 + v["pw"] + v["gap"])) * tau
    spec, terms, value, (_, source_values), _, _ = source_spec(deck, dict(v, wave=2), V, tau, True, False, until)
    gnd = deck.ground()
    names = {k: w.case(k) for k in ("V1", "R1", "R2", "C1")}
    deck.line([names["V1"], w.case("in"), gnd, *spec.split(" ")], "PULSE(v1 v2 td tr tf pw per)")
    deck.line([names["R1"], w.case("in"), w.case("out"), deck.num("R1", R1, w.case("ohm"))])
    deck.line([names["R2"], w.case("out"), deck.ground(), deck.num("R2", R2, w.case("ohm"))], "the load")
    deck.line([names["C1"], "out", gnd, deck.num("C1", C1, "F")])
    deck.line([w.case(".ic"), f"{w.case('v')}({w.case('out')})={deck.num('.ic v(out)', V0)}"])
    step, stop, tmax = deck.tran(source_values["td"] + 2.5 * source_values["per"],
                                 CAP * min(tau, 5 * source_values["tr"], 5 * source_values["tf"]))
    text = deck.text()
    deck.check_numbers()
    what = "RC divider deck, periodic PULSE, .ic"
    net = read_netlist(text)
    comps = net.model.components
    same(sorted(comps), sorted(names.values()), f"{what}: components, named as written")
    found = Findings()
    found(check_values, comps, names, {"R1": ("R", R1), "R2": ("R", R2), "C1": ("C", C1)}, deck, what)
    found(same, net.ic, {names["C1"]: V0}, f"{what}: the capacitor's initial voltage from .ic")
    found(same, (net.tran.step, net.tran.stop, net.tran.max_step, net.tran.uic), (step, stop, tmax, True),
          f"{what}: .tran")
    found(check_source, net, names["V1"], value, stop, V, what)
    res = net.simulate(method="exact")
    lti = Lti(0.0, tau)
    gained = [(term[0], term[1], g * term[2]) for term in terms]
    ours = net.capacitor_voltage(res, names["C1"])
    found(peak_gap, ours, lti.response(res.t, V0, 0.0, gained)[0], f"{what}: our v(C1) against the closed form", OURS_REL)
    check_against_ngspice(found, text, net, lambda r: {"v(C1)": net.capacitor_voltage(r, names["C1"])},
                          {"v(C1)": ("out", lambda tt: lti.response(tt, V0, 0.0, gained)[0])}, what)
    found(check_deck_twin, net, res, divider_twin(), {"R1": R1, "R2": R2, "C1": C1} | source_values, what)
    found.done()


# ================================================================================================

CHAIN_SPACE = {"n": uniform(1, 3.99)} | {f"m{i}": decades(1e-3, 1e2) for i in (1, 2, 3)} \
    | {f"k{i}": decades(1e-1, 1e4) for i in (1, 2, 3)} | {f"c{i}": decades(1e-4, 1e2) for i in (1, 2, 3)} \
    | {f"x{i}": uniform(-1, 1) for i in (1, 2, 3)} | {"F0": decades(1e-2, 1e2)}
SHAFT_SPACE = {"n": uniform(1, 2.99)} | {f"m{i}": decades(1e-4, 1e1) for i in (1, 2)} \
    | {f"k{i}": decades(1e-2, 1e3) for i in (1, 2)} | {f"c{i}": decades(1e-5, 1e1) for i in (1, 2)} \
    | {f"x{i}": uniform(-3, 3) for i in (1, 2)} | {"F0": decades(1e-2, 1e2), "r": decades(0.1, 10)}
# the damping ratio is drawn (R follows as a three-digit decimal): ζ beyond 3 makes the fast and slow time
# scales 36 apart and an ngspice run at a step cap fit for the fast one over five slow ones too long
SERIES_SPACE = {"L": decades(1e-6, 1e-1), "C": decades(1e-9, 1e-3), "zeta": decades(0.05, 3), "E": decades(0.1, 100),
                "v0": uniform(-1, 1), "i0": uniform(-1, 1), "wave": uniform(0, 2.99), "off": uniform(-1, 1),
                "fr": decades(0.2, 5), "ph": uniform(-180, 180), "td": uniform(0, 0.5), "tr": decades(0.05, 0.5),
                "tf": decades(0.05, 0.5), "pw": uniform(0.5, 2)}

CASES = [
    Case("map_model", "mass-spring-damper chain", CHAIN_SPACE, map_chain),
    Case("map_model", "inertia-torsion spring shaft", SHAFT_SPACE, map_shaft),
    Case("map_model", "RLC circuit to mechanism",
         {"kind": uniform(0, 1.99), "L": decades(1e-6, 1e-1), "C": decades(1e-9, 1e-3), "zeta": decades(0.01, 10),
          "S": decades(0.01, 100), "y0": uniform(-1, 1), "dy0": uniform(-1, 1)}, map_rlc),
    Case("compare_with_ngspice", "series RLC", SERIES_SPACE, compare_series),
    Case("compare_with_ngspice", "RC or RL under a periodic pulse",
         {"kind": uniform(0, 1.99), "R": decades(1, 1e5), "tau": decades(1e-7, 1e1), "E": decades(0.1, 100),
          "off": uniform(-1, 1), "y0": uniform(-1, 1), "td": uniform(0, 1), "tr": decades(0.05, 0.5),
          "tf": decades(0.05, 0.5), "pw": uniform(0.5, 3), "gap": uniform(0.5, 3)}, compare_first_order),
    Case("compare_with_ngspice", "mass-spring-damper via its analogue",
         {"kind": uniform(0, 1.99), "m": decades(1e-3, 1e2), "k": decades(1e-1, 1e5), "zeta": decades(0.05, 3),
          "F0": decades(1e-2, 1e2), "wave": uniform(0, 1.99), "fr": decades(0.2, 5), "x0": uniform(-1, 1),
          "v0": uniform(-1, 1)}, compare_msd),
    Case("read_netlist", "series RLC deck",
         SERIES_SPACE | {"style": uniform(0, 1), "form": uniform(0, 1.99), "theta": decades(0.01, 1),
                         "gap": uniform(0.5, 3)}, read_series),
    Case("read_netlist", "parallel RLC tank deck",
         SERIES_SPACE | {"style": uniform(0, 1), "form": uniform(0, 1.99), "theta": decades(0.01, 1),
                         "gap": uniform(0.5, 3)}, read_parallel),
    Case("read_netlist", "RC divider deck with a PULSE and .ic",
         {"R": decades(1, 1e5), "ratio": decades(0.1, 10), "C": decades(1e-9, 1e-3), "E": decades(0.1, 100),
          "v0": uniform(-1, 1), "off": uniform(-1, 1), "td": uniform(0, 1), "tr": decades(0.05, 0.5),
          "tf": decades(0.05, 0.5), "pw": uniform(0.5, 3), "gap": uniform(0.5, 3), "style": uniform(0, 1)},
         read_divider),
]
