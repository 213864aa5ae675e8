"""Integrators: work–precision on the shipped benchmarks, where explicit methods go unstable, energy over 10⁵ periods.

1. Work–precision (``lagrangian.bench``) on every shipped benchmark with its
   default methods: a table per benchmark, error against wall time.
2. Stability on a stiff two-mass chain (ω_max ≈ 141) and a stiff RC circuit
   (λ = −1000): the largest stable step of Verlet and RK4, found by running
   them (bisection), against the bounds from the eigenvalues (h·ω < 2 for
   leapfrog; 2√2 on the imaginary and 2.785 on the negative real axis for
   RK4); and the growth per step against h·ω_max, measured and predicted.
3. Long-time energy: the harmonic oscillator over 10⁵ periods at 32 steps per
   period — Verlet stepped one by one (3.2·10⁶ steps in a plain Python loop),
   every fixed-step method through its one-step map's powers, DOP853 and
   RK45 over 10³ periods — the largest relative energy error and wall time.
4. ``method="auto"`` on long conservative runs, as a work–precision run
   (energy measure): the README's double pendulum (1 kg, 1 m) over 1000 s
   from θ₁ = θ₂ = 2 rad above the hanging position, and the README's
   spherical pendulum (0.3 kg, 0.7 m) over 1000 s — auto's pick against
   RK45 and DOP853 at the same tolerances: largest relative energy error,
   evaluations, wall time, and what auto picked.

Writes ``benchmarks/integrators.png`` (all panels); the last line printed
is a JSON summary.  Run: ``make benchmark`` or
``.venv/bin/python benchmarks/integrators.py``.
"""

from __future__ import annotations

import json
import math
import sys
import time
import warnings
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import lagrangian as lg  # noqa: E402
from lagrangian.bench import Benchmark, benchmarks, stability_limit, work_precision  # noqa: E402

warnings.simplefilter("ignore", lg.InitialConditionWarning)
warnings.simplefilter("ignore", lg.EnergyDriftWarning)


def stiff_chain(K=1e4) -> lg.Model:
    m = lg.Model("stiff chain")
    m.add("mass", "m1", "a", m=1)
    m.add("mass", "m2", "b", m=1)
    m.add("spring", "k1", ("ground", "a"), k=1)
    m.add("spring", "k2", ("a", "b"), k=K)
    return m


def rc() -> lg.Model:
    m = lg.Model("stiff rc", formulation="charge")
    m.add("voltage_source", "V", ("n1", "0"), E=0)
    m.add("resistor", "R", ("n1", "n2"), R=1)
    m.add("capacitor", "C", ("n2", "0"), C=1e-3)
    return m


def oscillator() -> lg.Model:
    m = lg.Model("oscillator")
    m.add("mass", "m", "p", m=1)
    m.add("spring", "k", ("ground", "p"), k=1)
    return m


def rk4_factor(z: complex) -> float:
    return abs(1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24)


def leapfrog_factor(y: float) -> float:
    """Largest root modulus of λ² − (2 − y²) λ + 1 = 0 (leapfrog on x'' = −ω²x, y = hω)."""
    return float(np.max(np.abs(np.roots([1, -(2 - y * y), 1]))))


def section_work_precision(axes, summary):
    print("== 1. work–precision (lagrangian.bench) ==")
    out = {}
    for ax, (name, bench) in zip(axes, benchmarks().items()):
        start = time.perf_counter()
        wp = work_precision(bench, progress=True)
        print(wp.table())
        print(f"({time.perf_counter() - start:.1f} s)\n")
        wp.plot(ax)
        best = {}
        for method in dict.fromkeys(r.method for r in wp.rows):
            ok = [r for r in wp.rows if r.method == method and r.status == "ok"]
            if not ok:
                best[method] = {"status": next(r.status for r in wp.rows if r.method == method)}
                continue
            # the cheapest run reaching an error of 1e-6, else the most accurate run
            good = [r for r in ok if r.error <= 1e-6]
            r = min(good, key=lambda r: r.wall) if good else min(ok, key=lambda r: r.error)
            best[method] = {"setting": r.setting, "error": r.error, "wall_s": round(r.wall, 5), "nfev": r.nfev,
                            "reached_1e-6": bool(good)}
        out[name] = best
    summary["work_precision"] = out


def section_stability(ax, summary):
    print("== 2. stability: largest stable step, measured by running, against the eigenvalue bounds ==")
    K = 1e4
    w = float(np.sqrt(np.linalg.eigvalsh(np.array([[1 + K, -K], [-K, K]]))).max())
    roots = np.roots([1 / 24, 1 / 6, 1 / 2, 1])
    real_bound = float(-roots[np.abs(roots.imag) < 1e-12].real[0])
    cases = [
        ("verlet", "stiff chain (±iω, ω_max = %.1f)" % w, stiff_chain, {"x_a": 1.0, "x_b": -1.0}, 2 / w, "h·ω_max < 2"),
        ("rk4", "stiff chain (±iω, ω_max = %.1f)" % w, stiff_chain, {"x_a": 1.0, "x_b": -1.0}, 2 * math.sqrt(2) / w, "h·ω_max < 2√2"),
        ("rk4", "stiff RC (λ = −1000)", rc, {"q_R": 1.0}, real_bound / 1000, "h·|λ| < 2.785"),
    ]
    rows = []
    print(f"{'method':8} {'model':32} {'theory h':>11} {'measured h':>11} {'ratio':>8}  bound")
    for method, label, build, initial, bound, text in cases:
        start = time.perf_counter()
        h = stability_limit(build(), method, initial=initial, lo=0.5 * bound, hi=1.5 * bound, fast_linear=False)
        rows.append({"method": method, "model": label, "theory": bound, "measured": h, "ratio": h / bound,
                     "wall_s": round(time.perf_counter() - start, 3)})
        print(f"{method:8} {label:32} {bound:11.5g} {h:11.5g} {h / bound:8.5f}  {text}")
    summary["stability"] = rows
    # growth per step against h·ω_max on the chain, from the fast mode's eigenvector (so only it is excited):
    # measured over 20 steps taken one by one, predicted from the methods' stability functions
    Kmat = np.array([[1 + K, -K], [-K, K]])
    vals, vecs = np.linalg.eigh(Kmat)
    fast = vecs[:, np.argmax(vals)]
    ys = np.linspace(1.5, 3.2, 35)
    for method, predicted in (("verlet", leapfrog_factor), ("rk4", lambda y: rk4_factor(1j * y))):
        measured = []
        for y in ys:
            h = y / w
            res = stiff_chain().simulate(20 * h, initial={"x_a": fast[0], "x_b": fast[1]}, method=method, step=h,
                                         fast_linear=False, t_eval=np.linspace(0, 20 * h, 21), energy_tol=False)
            # amplitude of the mode: √(x² + (ẋ/ω)²) is constant along an exact solution
            amp = np.hypot(res["x_b"], res.velocity("x_b") / w)
            measured.append((amp[-1] / amp[0]) ** (1 / 20))
        line = ax.plot(ys, measured, "o", ms=4, label=f"{method}: measured")[0]
        ax.plot(ys, [predicted(y) for y in ys], "-", color=line.get_color(), label=f"{method}: predicted")
    ax.axvline(2, color="gray", ls=":")
    ax.axvline(2 * math.sqrt(2), color="gray", ls=":")
    ax.set_xlabel("h·ω_max")
    ax.set_ylabel("amplitude growth per step")
    ax.set_title("Stability on the stiff chain (bounds 2 and 2√2)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    print()


def section_long_energy(ax, summary):
    print("== 3. energy over 10⁵ periods of x'' = −x, h = T/32 ==")
    model = oscillator()
    h = 2 * math.pi / 32
    every = 321  # outputs every 321 steps: not a multiple of 32, so every phase is sampled
    t_eval = np.arange(100_000 * 32 // every + 1) * every * h
    runs = []
    start = {"initial": {"x_p": 1.0}, "velocity": {"x_p": 0.0}}
    for method, label, options, span in [
        ("verlet", "verlet, stepped one by one", {"step": h, "fast_linear": False}, t_eval),
        ("verlet", "verlet, one-step map powers", {"step": h}, t_eval),
        ("rk4", "rk4, one-step map powers", {"step": h}, t_eval),
        ("implicit_midpoint", "implicit_midpoint, map powers", {"step": h}, t_eval),
        ("gauss_legendre", "gauss_legendre, map powers", {"step": h}, t_eval),
        ("variational", "variational, map powers", {"step": h}, t_eval),
        ("DOP853", "DOP853 rtol 1e-6, 10³ periods", {"rtol": 1e-6, "atol": 1e-9}, t_eval[t_eval <= 1000 * 2 * math.pi]),
        ("RK45", "RK45 rtol 1e-6, 10³ periods", {"rtol": 1e-6, "atol": 1e-9}, t_eval[t_eval <= 1000 * 2 * math.pi]),
    ]:
        t0 = time.perf_counter()
        res = model.simulate(span[-1], method=method, t_eval=span, **options, **start)
        wall = time.perf_counter() - t0
        rel = np.abs(res.E - res.E[0]) / res.E[0]
        periods = span[-1] / (2 * math.pi)
        runs.append({"run": label, "periods": round(periods), "max_rel_energy_error": float(rel.max()),
                     "final_rel_energy_error": float(rel[-1]), "wall_s": round(wall, 3), "nfev": res.nfev})
        print(f"{label:34} {periods:9.0f} periods  max |ΔE|/E {rel.max():9.2e}  final {rel[-1]:9.2e}  {wall:7.2f} s  nfev {res.nfev}")
        if "stepped" not in label:
            ax.loglog(res.t[1:] / (2 * math.pi), np.maximum(rel[1:], 1e-17), ".", ms=2, label=label)
    y = h
    print(f"theory: verlet |ΔE|/E ≤ (y/2)²/(1−(y/2)²) = {(y / 2) ** 2 / (1 - (y / 2) ** 2):.3e}; "
          f"rk4 E_N/E_0 = (1 − y⁶/72 + y⁸/576)^N = {(1 - y**6 / 72 + y**8 / 576) ** (32 * 100_000):.4f} after 10⁵ periods")
    ax.set_xlabel("periods")
    ax.set_ylabel("relative energy error")
    ax.set_title("Energy over 10⁵ periods (h = T/32)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, markerscale=4)
    summary["long_energy"] = runs
    print()


def double_pendulum() -> lg.Model:
    """The README's double pendulum: absolute angles from +x, gravity along −y, 1 kg at the end of 1 m links."""
    m = lg.Model("double pendulum", dim=2)
    for i in (1, 2):
        m.add("link", f"l{i}", f"l{i}", points={"end": (1, 0)})
        m.add("mass", f"m{i}", f"l{i}.end", m=1)
    m.add("revolute", "j1", ("ground", "l1"), absolute=True)
    m.add("revolute", "j2", ("l1", "l2"), parent_point=(1, 0), absolute=True)
    m.add("gravity", "g")
    return m


def spherical_pendulum() -> lg.Model:
    """The README's spherical pendulum: 0.3 kg at 0.7 m, φ about the vertical (ignorable), θ from below."""
    m = lg.Model("spherical pendulum", dim=3)
    m.add("link", "yoke", "yoke")
    m.add("revolute", "turn", ("ground", "yoke"), axis=(0, 0, 1))
    m.add("link", "arm", "arm", points={"bob": (0, 0, -0.7)})
    m.add("revolute", "tilt", ("yoke", "arm"), axis=(1, 0, 0))
    m.add("mass", "bob", "arm.bob", m=0.3)
    m.add("gravity", "g")
    return m


def section_auto_long_runs(ax, summary):
    print("== 4. method='auto' on long conservative runs (energy: largest |ΔE| / |E₀|) ==")
    up = 2.0 - math.pi / 2  # 2 rad above hanging straight down (θ = −π/2)
    cases = [
        Benchmark("double_pendulum_1000s", "README double pendulum, 1000 s, θ₁ = θ₂ = 2 rad from hanging, at rest",
                  double_pendulum, t_end=1000.0, initial={"theta_j1": up, "theta_j2": up}, points=4001,
                  measure="energy", tolerances=(1e-3, 1e-4)),
        Benchmark("spherical_pendulum_1000s", "README spherical pendulum, 1000 s, θ = 0.9, φ' = 1.7",
                  spherical_pendulum, t_end=1000.0, initial={"theta_tilt": 0.9, "theta_turn": 0.0},
                  velocity={"theta_turn": 1.7, "theta_tilt": 0.0}, points=4001, measure="energy",
                  tolerances=(1e-3, 1e-4)),
    ]
    out = {}
    for bench in cases:
        start = time.perf_counter()
        wp = work_precision(bench, ["auto", "RK45", "DOP853"])
        print(wp.table())
        print(f"({time.perf_counter() - start:.1f} s)\n")
        wp.plot(ax)
        out[bench.name] = [{"method": r.method, "setting": r.setting, "error": r.error, "nfev": r.nfev,
                            "wall_s": round(r.wall, 3), "note": r.message} for r in wp.rows]
    ax.set_title("auto on long conservative runs (energy error)")
    summary["auto_long_runs"] = out


def main() -> None:
    fig, axes = plt.subplots(2, 4, figsize=(24, 11), constrained_layout=True)
    axes = axes.ravel()
    summary: dict = {}
    section_work_precision(axes[:5], summary)
    section_stability(axes[5], summary)
    section_long_energy(axes[6], summary)
    section_auto_long_runs(axes[7], summary)
    out = Path(__file__).with_suffix(".png")
    fig.savefig(out, dpi=90)
    print(f"chart written to {out}", file=sys.stderr)
    print(json.dumps(summary, default=float))


if __name__ == "__main__":
    if sys.argv[1:] == ["--auto"]:  # section 4 alone
        fig, ax = plt.subplots(figsize=(7, 5), constrained_layout=True)
        summary: dict = {}
        section_auto_long_runs(ax, summary)
        print(json.dumps(summary, default=float))
    else:
        main()
