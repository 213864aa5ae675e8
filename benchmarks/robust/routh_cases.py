"""Routhian reduction, steady motion, stability and the Jacobi integral against closed forms.

Families: the spherical pendulum (φ ignorable), the heavy symmetric top (φ
and ψ ignorable), a central force k/rⁿ (θ ignorable), a bead on a hoop that
turns freely about its vertical diameter, and a mass between supports that
move on a circle (time dependence that cancels, or does not).  References
are the closed forms written out here from the Lagrangians in the
docstrings — effective potentials, circular orbits, precession rates,
small-oscillation frequencies, Jacobi integrals — and the same model built
from symbols then given the values (the symbolic twin, reduced once per
worker).
"""

from __future__ import annotations

import math
import sys
from functools import lru_cache
from pathlib import Path

import numpy as np
import sympy as sp
from sympy.core.function import AppliedUndef

import lagrangian as lg
from lagrangian import models, routh

from . import Case, Mismatch, close, decades, same, uniform

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "examples"))
from kepler import central  # noqa: E402

SPHERICAL = ("m", "length", "g")
TOP = ("m", "l", "I1", "I3", "g")


def at_state(expr, q: dict[str, float], v: dict[str, float] | None = None, extra: dict | None = None) -> float:
    """A displayed expression (in q(t), q̇(t)) at a state given by coordinate name."""
    expr = sp.sympify(expr)
    rule = {}
    for d in expr.atoms(sp.Derivative):
        rule[d] = sp.Float((v or {})[d.expr.func.__name__])
    for f in expr.atoms(AppliedUndef):
        rule[f] = sp.Float(q[f.func.__name__])
    value = expr.xreplace(rule).xreplace({sp.Symbol(k, real=True): val for k, val in (extra or {}).items()})
    return float(value.evalf(30))


def momentum_symbols(red) -> dict[str, sp.Symbol]:
    return {s.name: s for s in red.momenta.values() if isinstance(s, sp.Symbol)}


def values_of(red, names: tuple[str, ...], values: dict) -> dict[sp.Symbol, float]:
    by_name = {s.name: s for s in red.parameters}
    return {by_name[n]: values[n] for n in names}


@lru_cache(maxsize=None)
def twin(family: str):
    """The family built from positive symbols and reduced (once per worker)."""
    if family == "spherical":
        return routh.reduce(models.spherical_pendulum(*sp.symbols(" ".join(SPHERICAL), positive=True)))
    if family == "top":
        return routh.reduce(models.heavy_top(*sp.symbols(" ".join(TOP), positive=True)))
    if family == "hoop":
        return routh.reduce(hoop(*sp.symbols("m R J g", positive=True)))
    raise KeyError(family)


def check_twin_expr(numeric, symbolic, subs: dict, point: dict, what: str, extra=None, rel=1e-10) -> None:
    got = at_state(numeric, point, extra=extra)
    want = at_state(sp.sympify(symbolic).xreplace(subs), point, extra=extra)
    close(got, want, f"{what}: numbers against symbols then values", rel=rel, abs_=1e-12 * max(1.0, abs(want)))


def hoop(m, R, J, g) -> lg.Model:
    """A bead of mass m on a hoop of radius R and inertia J turning freely about its vertical diameter:
    L = ½ (J + m R² sin²θ) φ̇² + ½ m R² θ̇² + m g R cos θ (θ from the bottom)."""
    model = lg.Model("bead on a free hoop", dim=3)
    model.add("body", "hoop", "hoop", m=1.0, inertia=(J, J, J))
    model.add("revolute", "spin", ("ground", "hoop"), axis=(0, 0, 1))
    model.add("link", "arm", "arm", points={"bead": (0, 0, -R)})
    model.add("revolute", "slide", ("hoop", "arm"), axis=(1, 0, 0))
    model.add("mass", "bead", "arm.bead", m=m)
    model.add("gravity", "gravity", g=g)
    return model


# -- reduce ---------------------------------------------------------------------------------------


def spherical_momentum(v):
    """C from a dimensionless draw c: C = c · m l² √(g/l)."""
    return v["c"] * v["m"] * v["length"] ** 2 * math.sqrt(v["g"] / v["length"])


def reduce_spherical(v):
    """V_eff = C²/(2 m l² sin²θ) − m g l cos θ; φ̇ = C/(m l² sin²θ)."""
    m, length, g, theta = v["m"], v["length"], v["g"], v["theta"]
    C = spherical_momentum(v)
    red = routh.reduce(models.spherical_pendulum(m, length, g))
    same(red.ignored, ["theta_turn"], "ignored coordinates")
    C_sym = momentum_symbols(red)["C_theta_turn"]
    want = C**2 / (2 * m * length**2 * math.sin(theta) ** 2) - m * g * length * math.cos(theta)
    got = at_state(red.effective_potential, {"theta_tilt": theta}, extra={"C_theta_turn": C})
    close(got, want, "V_eff", rel=1e-10)
    rate = at_state(red.rates["theta_turn"], {"theta_tilt": theta}, extra={"C_theta_turn": C})
    close(rate, C / (m * length**2 * math.sin(theta) ** 2), "φ̇ = ∂R/∂C", rel=1e-10)
    sym = twin("spherical")
    same(sym.ignored, red.ignored, "ignored coordinates of the symbolic twin")
    same(sym.effective_potential is None, False, "the twin has an effective potential")
    subs = values_of(sym, SPHERICAL, v)
    check_twin_expr(red.effective_potential, sym.effective_potential, subs, {"theta_tilt": theta}, "V_eff",
                    extra={C_sym.name: C})


def top_values(v):
    """m, l, I1, I3, g with I3 = r · 2 I1 (a body's principal moments obey I1 + I2 ≥ I3), as three-digit decimals."""
    return v["m"], v["l"], v["I1"], float(f"{2 * v['I1'] * v['r']:.3g}"), v["g"]


def top_momenta(v):
    scale = math.sqrt(v["m"] * v["g"] * v["l"] * (v["I1"] + v["m"] * v["l"] ** 2))
    return v["cphi"] * scale, v["cpsi"] * scale


def reduce_top(v):
    """V_eff = (C_φ − C_ψ cos θ)²/(2 A sin²θ) + C_ψ²/(2 I₃) + m g l cos θ, A = I₁ + m l²."""
    m, l, I1, I3, g = top_values(v)
    theta = v["theta"]
    Cphi, Cpsi = top_momenta(v)
    red = routh.reduce(models.heavy_top(m, l, I1, I3, g))
    same(sorted(red.ignored), ["theta_precession", "theta_spin"], "ignored coordinates")
    A = I1 + m * l**2
    want = (Cphi - Cpsi * math.cos(theta)) ** 2 / (2 * A * math.sin(theta) ** 2) + Cpsi**2 / (2 * I3) \
        + m * g * l * math.cos(theta)
    C = {"C_theta_precession": Cphi, "C_theta_spin": Cpsi}
    got = at_state(red.effective_potential, {"theta_nutation": theta}, extra=C)
    # the terms may cancel to far below their size: the tolerance is relative to the largest term
    scale = max(abs(want), (Cphi**2 + Cpsi**2) / (A * math.sin(theta) ** 2), Cpsi**2 / I3, m * g * l)
    close(got, want, "V_eff", rel=0, abs_=1e-10 * scale)
    sym = twin("top")
    same(sorted(sym.ignored), sorted(red.ignored), "ignored coordinates of the symbolic twin")
    subs = values_of(sym, TOP, dict(zip(TOP, (m, l, I1, I3, g))))
    twin_value = at_state(sym.effective_potential.xreplace(subs), {"theta_nutation": theta}, extra=C)
    close(twin_value, got, "V_eff: numbers against symbols then values", rel=0, abs_=1e-10 * scale)


def central_r0(v):
    """Circular orbit of k/rⁿ: C²/(m r₀³) = k/r₀ⁿ, r₀ = (C²/(m k))^(1/(3−n)); C from a drawn r₀."""
    return v["r0"]


def reduce_central(v):
    """V_eff = C²/(2 m r²) + V(r), V = −k/((n−1) r^(n−1))."""
    m, k, n, r = v["m"], v["k"], v["n"], v["r"]
    C = v["c"] * math.sqrt(m * k * r ** (3 - n))
    red = routh.reduce(central(m, k, n))
    same(red.ignored, ["theta_orbit"], "ignored coordinates")
    want = C**2 / (2 * m * r**2) - k / ((n - 1) * r ** (n - 1))
    got = at_state(red.effective_potential, {"s_radius": r}, extra={"C_theta_orbit": C})
    scale = max(C**2 / (2 * m * r**2), abs(k / ((n - 1) * r ** (n - 1))))
    close(got, want, "V_eff", rel=0, abs_=1e-10 * scale)


# -- steady motions and their stability -----------------------------------------------------------


def spherical_steady(v, symbolic: bool):
    m, length, g, theta0 = v["m"], v["length"], v["g"], v["theta0"]
    Omega = math.sqrt(g / (length * math.cos(theta0)))
    C = m * length**2 * math.sin(theta0) ** 2 * Omega
    if symbolic:
        red = twin("spherical")
        motions = red.steady_motions(params={k: v[k] for k in SPHERICAL}, momenta={"theta_turn": C},
                                     search={"theta_tilt": (0.01, 3.13)})
    else:
        red = routh.reduce(models.spherical_pendulum(m, length, g))
        motions = red.steady_motions(momenta={"theta_turn": C}, search={"theta_tilt": (0.01, 3.13)})
    return motions, Omega


def steady_spherical(v):
    """Steady precession at θ₀ (below the horizontal): Ω² = g/(l cos θ₀), the only one for C ≠ 0."""
    for symbolic in (False, True):
        motions, Omega = spherical_steady(v, symbolic)
        who = "symbolic twin" if symbolic else "numbers"
        same(len(motions), 1, f"steady motions found ({who})")
        close(float(motions[0].coordinates["theta_tilt"]), v["theta0"], f"θ₀ ({who})", rel=1e-9)
        close(float(motions[0].rates["theta_turn"]), Omega, f"precession rate ({who})", rel=1e-9)


def steady_central(v):
    """Circular orbits of k/rⁿ: r₀ = (C²/(m k))^(1/(3−n)), θ̇ = C/(m r₀²): one for each C ≠ 0."""
    m, k, n, r0 = v["m"], v["k"], v["n"], v["r0"]
    C = math.sqrt(m * k * r0 ** (3 - n))
    red = routh.reduce(central(m, k, n))
    motions = red.steady_motions(momenta={"theta_orbit": C}, search={"s_radius": (r0 / 30, 30 * r0)})
    same(len(motions), 1, "circular orbits found")
    close(float(motions[0].coordinates["s_radius"]), r0, "r₀", rel=1e-9)
    close(float(motions[0].rates["theta_orbit"]), C / (m * r0**2), "orbital rate", rel=1e-9)


def hoop_spin(v):
    """Ω relative to the critical √(g/R), and the momentum of spinning at Ω with the bead at θ."""
    return v["w"] * math.sqrt(v["g"] / v["R"])


def steady_hoop(v):
    """At the bottom for every Ω; off it at cos θ₀ = g/(R Ω²) when Ω² > g/R, with C = (J + m R² sin²θ₀) Ω."""
    m, R, J, g = v["m"], v["R"], v["J"] * v["m"] * v["R"] ** 2, v["g"]
    Omega = hoop_spin(v)
    tilted = Omega**2 > g / R
    theta0 = math.acos(g / (R * Omega**2)) if tilted else 0.0
    C = (J + m * R**2 * math.sin(theta0) ** 2) * Omega
    found = {}
    for who, red, params in (("numbers", routh.reduce(hoop(m, R, J, g)), None),
                             ("symbolic twin", twin("hoop"), {"m": m, "R": R, "J": J, "g": g})):
        motions = red.steady_motions(params=params, momenta={"theta_spin": C}, search={"theta_slide": (-3.1, 3.1)})
        angles = sorted(float(s.coordinates["theta_slide"]) for s in motions)
        found[who] = angles
        if tilted:
            # the same C holds the bead at ±θ₀, and at the bottom spinning at C/J
            same(len(angles), 3, f"steady motions at this momentum ({who})")
            close(angles[0], -theta0, f"−θ₀ ({who})", rel=1e-9)
            close(angles[2], theta0, f"θ₀ ({who})", rel=1e-9)
        if not any(abs(a) < 1e-9 for a in angles):
            raise Mismatch(f"the bead at the bottom is a steady motion ({who}); found {angles}")
    for a, b in zip(*found.values()):
        close(a, b, "numbers against the symbolic twin", rel=1e-9, abs_=1e-12)


def stability_spherical(v):
    """Small oscillations about steady precession: ω² = (g/l)(3 cos θ₀ + sec θ₀), stable (V_eff has a minimum)."""
    verdicts = []
    for symbolic in (False, True):
        motions, _ = spherical_steady(v, symbolic)
        s = motions[0].stability()
        want = math.sqrt(v["g"] / v["length"] * (3 * math.cos(v["theta0"]) + 1 / math.cos(v["theta0"])))
        same(s.verdict, "stable", "verdict")
        close(s.frequencies[0], want, "small-oscillation frequency", rel=1e-7)
        verdicts.append(s)
    close(verdicts[0].frequencies[0], verdicts[1].frequencies[0], "numbers against the symbolic twin", rel=1e-10)
    close(verdicts[0].curvature[0], verdicts[1].curvature[0], "V_eff curvature, numbers against symbols", rel=1e-9)


def stability_hoop(v):
    """The bead at the bottom: ω² = g/R − Ω² (C = J Ω: the bead adds no inertia there); stable below the
    critical spin, unstable above it — never 'marginal' (there is no gyroscopic term)."""
    m, R, J, g = v["m"], v["R"], v["J"] * v["m"] * v["R"] ** 2, v["g"]
    Omega = hoop_spin(v)
    C = J * Omega
    verdicts = []
    for who, red, params in (("numbers", routh.reduce(hoop(m, R, J, g)), None),
                             ("symbolic twin", twin("hoop"), {"m": m, "R": R, "J": J, "g": g})):
        bottom = [s for s in red.steady_motions(params=params, momenta={"theta_spin": C}, search={"theta_slide": (-0.5, 0.5)})
                  if abs(float(s.coordinates["theta_slide"])) < 1e-9]
        same(len(bottom), 1, f"the steady motion at the bottom ({who})")
        s = bottom[0].stability()
        w2 = g / R - Omega**2
        same(s.verdict, "stable" if w2 > 0 else "unstable", f"verdict ({who})")
        lam = np.sort(s.eigenvalues.real if w2 < 0 else s.eigenvalues.imag)
        close(lam[-1], math.sqrt(abs(w2)), f"{'growth rate' if w2 < 0 else 'frequency'} ({who})", rel=1e-7)
        verdicts.append((s.verdict, lam[-1]))
    same(verdicts[0][0], verdicts[1][0], "verdict, numbers against the symbolic twin")
    close(verdicts[0][1], verdicts[1][1], "eigenvalue, numbers against the symbolic twin", rel=1e-9)


def stability_top(v):
    """Steady precession of the heavy top at θ₀ found from V_eff' = 0 (checked on the closed form), with
    small oscillations ω² = V_eff''(θ₀)/A: stable when V_eff'' > 0 — the same verdict from numbers and symbols."""
    m, l, I1, I3, g = top_values(v)
    Cphi, Cpsi = top_momenta(v)
    A = I1 + m * l**2
    th = sp.Symbol("theta")
    Veff = (Cphi - Cpsi * sp.cos(th)) ** 2 / (2 * A * sp.sin(th) ** 2) + m * g * l * sp.cos(th)
    d1, d2 = sp.lambdify(th, Veff.diff(th)), sp.lambdify(th, Veff.diff(th, 2))
    momenta = {"theta_precession": Cphi, "theta_spin": Cpsi}
    search = {"theta_nutation": (0.02, 3.12)}
    results = []
    for who, red, params in (("numbers", routh.reduce(models.heavy_top(m, l, I1, I3, g)), None),
                             ("symbolic twin", twin("top"), dict(zip(TOP, (m, l, I1, I3, g))))):
        motions = red.steady_motions(params=params, momenta=momenta, search=search)
        if not motions:
            raise Mismatch(f"no steady precession found ({who})")
        for s in motions:
            theta0 = float(s.coordinates["theta_nutation"])
            curv = d2(theta0)
            scale = abs(d2(theta0)) + m * g * l + abs(Cphi * Cpsi) / A
            if abs(d1(theta0)) > 1e-8 * scale:
                raise Mismatch(f"θ₀ = {theta0} is not where V_eff' = 0 ({who}): V_eff' = {d1(theta0)}")
            stab = s.stability()
            if abs(curv) < 1e-6 * scale:
                continue  # a fold of the steady motions: the linearization cannot decide
            same(stab.verdict, "stable" if curv > 0 else "unstable", f"verdict at θ₀ = {theta0:.6g} ({who})")
            if curv > 0:
                close(stab.frequencies[0], math.sqrt(curv / A), f"frequency at θ₀ = {theta0:.6g} ({who})", rel=1e-6)
            results.append((round(theta0, 6), stab.verdict))
    half = len(results) // 2
    same(sorted(results[:half]), sorted(results[half:]), "steady motions and verdicts, numbers against symbols")


def top_admissible(v):
    Cphi, Cpsi = top_momenta(v)
    return abs(abs(Cphi) - abs(Cpsi)) > 1e-2 * (abs(Cphi) + abs(Cpsi))  # off the sleeping top θ₀ → 0 or π


# -- the Jacobi integral --------------------------------------------------------------------------


def jacobi_spherical(v):
    """Scleronomic and natural: h = T + V = ½ m l² (θ̇² + φ̇² sin²θ) − m g l cos θ, conserved."""
    m, length, g = v["m"], v["length"], v["g"]
    h = routh.jacobi_integral(models.spherical_pendulum(m, length, g))
    same((h.conserved, h.energy_conserved), (True, True), "conserved, and equal to T + V")
    q = {"theta_turn": v["phi"], "theta_tilt": v["theta"]}
    rates = {"theta_turn": v["dphi"], "theta_tilt": v["dtheta"]}
    want = 0.5 * m * length**2 * (v["dtheta"] ** 2 + v["dphi"] ** 2 * math.sin(v["theta"]) ** 2) \
        - m * g * length * math.cos(v["theta"])
    scale = 0.5 * m * length**2 * (v["dtheta"] ** 2 + v["dphi"] ** 2) + m * g * length
    close(at_state(h.expr, q, rates), want, "h", rel=0, abs_=1e-12 * scale)
    sym = routh.jacobi_integral(twin("spherical").full)
    same(sym.conserved, h.conserved, "verdict of the symbolic twin")
    value = at_state(sym.expr.xreplace(values_of(twin("spherical"), SPHERICAL, v)), q, rates)
    close(value, want, "h of the symbolic twin", rel=0, abs_=1e-12 * scale)


def supports(m, A, w, k, k2, both: bool) -> lg.Model:
    """A mass between supports at ±c(t), c = A (cos ωt, sin ωt), on zero-length springs k and k2."""
    model = lg.Model("mass between supports on a circle", dim=2)
    model.add("mass", "m", "p", m=m)
    c = sp.Matrix([A * sp.cos(w * lg.t), A * sp.sin(w * lg.t)])
    model.add("prescribed_motion", "s1", "s1", position=c)
    model.add("spring", "k1", ("s1", "p"), k=k)
    if both:
        model.add("prescribed_motion", "s2", "s2", position=-c)
        model.add("spring", "k2", ("s2", "p"), k=k2)
    return model


def jacobi_supports(v):
    """With equal springs L = ½ m |ṗ|² − k |p|² − k A²: time cancels, h = ½ m |ṗ|² + k |p|² + k A², conserved.
    With one support, or unequal springs, L keeps a p·c(t) term: not conserved, and the reason says time."""
    m, A, w, k = v["m"], v["A"], v["w"], v["k"]
    state = {"x_p": v["x"], "y_p": v["y"]}
    rates = {"x_p": v["vx"], "y_p": v["vy"]}
    h = routh.jacobi_integral(supports(m, A, w, k, k, both=True))
    same(h.conserved, True, "h conserved when the time dependence cancels")
    want = 0.5 * m * (v["vx"] ** 2 + v["vy"] ** 2) + k * (v["x"] ** 2 + v["y"] ** 2) + k * A**2
    close(at_state(h.expr, state, rates, extra={}), want, "h", rel=1e-10)
    for model in (supports(m, A, w, k, k, both=False), supports(m, A, w, k, k * (1 + v["dk"]), both=True)):
        other = routh.jacobi_integral(model)
        same(other.conserved, False, f"h of {model.name!r} with time left in L")
        if "time" not in " ".join(other.reasons):
            raise Mismatch(f"the reason does not name the time dependence: {other.reasons}")
    same(supports_twin().conserved, True, "verdict of the symbolic twin")


@lru_cache(maxsize=None)
def supports_twin():
    symbols = sp.symbols("m A w k", positive=True)
    return routh.jacobi_integral(supports(*symbols, symbols[3], both=True))


CASES = [
    Case("reduce", "spherical pendulum", {"m": decades(1e-2, 1e2), "length": decades(1e-2, 1e2), "g": decades(0.1, 100),
                                           "theta": uniform(0.05, 3.09), "c": decades(1e-3, 1e2)}, reduce_spherical),
    Case("reduce", "heavy top", {"m": decades(1e-2, 1e2), "l": decades(1e-2, 1e1), "I1": decades(1e-4, 1e2),
                                 "r": uniform(0.05, 0.99), "g": decades(0.1, 100), "theta": uniform(0.05, 3.09),
                                 "cphi": uniform(-3, 3), "cpsi": uniform(-3, 3)}, reduce_top),
    Case("reduce", "central force", {"m": decades(1e-2, 1e2), "k": decades(1e-2, 1e3), "n": uniform(1.2, 2.9),
                                     "r": decades(1e-2, 1e2), "c": decades(1e-2, 1e2)}, reduce_central),
    Case("steady_motions", "spherical pendulum", {"m": decades(1e-2, 1e2), "length": decades(1e-2, 1e2),
                                                  "g": decades(0.1, 100), "theta0": uniform(0.1, 1.45)}, steady_spherical),
    Case("steady_motions", "central force", {"m": decades(1e-2, 1e2), "k": decades(1e-2, 1e3), "n": uniform(1.2, 2.9),
                                             "r0": decades(1e-2, 1e2)}, steady_central),
    Case("steady_motions", "bead on a free hoop", {"m": decades(1e-2, 1e2), "R": decades(1e-2, 1e1),
                                                   "J": decades(1e-2, 1e2), "g": decades(0.1, 100),
                                                   "w": decades(0.1, 10)}, steady_hoop,
         admissible=lambda v: abs(v["w"] - 1) > 0.02),
    Case("stability", "spherical pendulum", {"m": decades(1e-2, 1e2), "length": decades(1e-2, 1e2),
                                             "g": decades(0.1, 100), "theta0": uniform(0.1, 1.45)}, stability_spherical),
    Case("stability", "bead on a free hoop", {"m": decades(1e-2, 1e2), "R": decades(1e-2, 1e1),
                                              "J": decades(1e-2, 1e2), "g": decades(0.1, 100),
                                              "w": decades(0.1, 10)}, stability_hoop,
         admissible=lambda v: abs(v["w"] - 1) > 0.02),
    Case("stability", "heavy top", {"m": decades(1e-2, 1e2), "l": decades(1e-2, 1e1), "I1": decades(1e-4, 1e2),
                                    "r": uniform(0.05, 0.99), "g": decades(0.1, 100),
                                    "cphi": uniform(-3, 3), "cpsi": uniform(-3, 3)}, stability_top,
         admissible=top_admissible),
    Case("jacobi_integral", "spherical pendulum", {"m": decades(1e-2, 1e2), "length": decades(1e-2, 1e2),
                                                   "g": decades(0.1, 100), "theta": uniform(-3, 3), "phi": uniform(-3, 3),
                                                   "dtheta": uniform(-10, 10), "dphi": uniform(-10, 10)}, jacobi_spherical),
    Case("jacobi_integral", "supports on a circle", {"m": decades(1e-2, 1e2), "A": decades(1e-3, 1e1),
                                                     "w": decades(1e-2, 1e2), "k": decades(1e-2, 1e4),
                                                     "dk": decades(1e-3, 1), "x": uniform(-1, 1), "y": uniform(-1, 1),
                                                     "vx": uniform(-5, 5), "vy": uniform(-5, 5)}, jacobi_supports),
]
