"""The main demo: a driven mass–spring–damper and its series RLC analogue.
=======================================================================

Both are assembled from plugins into one Lagrangian each; the demo prints
both Lagrangians and equations of motion, simulates both, prints how far
apart the responses are and how far each is from the closed form, and
writes a PNG chart of both.  Then it checks both against ngspice: the
circuit as built, and the mechanism through the circuit analogue the
framework derives for it (force–voltage, through the dual graph), with a
report and a chart of each comparison.

Force–voltage analogy: mass m ↔ inductance L, stiffness k ↔ 1/C, damping c
↔ resistance R, force F(t) ↔ source voltage E(t), displacement x ↔ loop
charge q.

Run:  make demo     (or: .venv/bin/python examples/demo.py [--out FILE])
"""

from __future__ import annotations

import argparse
import time
import warnings
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import sympy as sp

import lagrangian as lg
from lagrangian.analogy import map_model
from lagrangian.compare import compare_with_ngspice

M, K, C = 1.0, 4.0, 0.4  # kg, N/m, N s/m
FORCE = sp.sin(sp.Rational(3, 2) * lg.t)  # N
X0 = 0.1  # m


def mechanism() -> lg.Model:
    m = lg.Model("mass-spring-damper")
    m.add("mass", "m", "cart", m=M)
    m.add("spring", "k", ("ground", "cart"), k=K)
    m.add("damper", "c", ("ground", "cart"), c=C)
    m.add("force", "F", "cart", F=FORCE)
    return m


def circuit() -> lg.Model:
    c = lg.Model("series-RLC", formulation="charge")
    c.add("voltage_source", "E", ("n1", "0"), E=FORCE)
    c.add("resistor", "R", ("n1", "n2"), R=C)
    c.add("inductor", "L", ("n2", "n3"), L=M)
    c.add("capacitor", "C", ("n3", "0"), C=1 / K)
    return c


def closed_form(t: np.ndarray) -> np.ndarray:
    """x(t) of m x'' + c x' + k x = sin(w t), x(0) = X0, x'(0) = 0, derived by hand."""
    w = 1.5
    det = (K - M * w**2) ** 2 + (C * w) ** 2
    a, b = (K - M * w**2) / det, -C * w / det  # particular solution a sin(wt) + b cos(wt)
    gamma = C / (2 * M)
    wd = np.sqrt(K / M - gamma**2)
    c1 = X0 - b
    c2 = (gamma * c1 - a * w) / wd
    return a * np.sin(w * t) + b * np.cos(w * t) + np.exp(-gamma * t) * (c1 * np.cos(wd * t) + c2 * np.sin(wd * t))


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").partition("\n")[0])
    parser.add_argument("--out", default="demo.png", help="where to write the chart (PNG)")
    parser.add_argument("--t-end", type=float, default=20.0)
    args = parser.parse_args()

    registry = lg.default_registry()
    print("plugins:")
    for line in registry.describe().splitlines():
        print("  " + line)

    mech, circ = mechanism(), circuit()
    for model in (mech, circ):
        print()
        print(model.describe())

    results = {}
    for model, coord in ((mech, "x_cart"), (circ, "q_L")):
        start = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", lg.InitialConditionWarning)
            res = model.simulate(args.t_end, initial={coord: X0}, velocity={coord: 0.0}, points=2001)
        results[model.name] = (res, coord, time.perf_counter() - start)

    (rm, xm, tm), (rc, xc, tc) = results.values()
    x, q = rm[xm], rc[xc]
    diff = np.abs(x - q)
    vdiff = np.abs(rm.velocity(xm) - rc.velocity(xc))
    print()
    print(f"simulated 0–{args.t_end:g} s on {x.size} points (DOP853, rtol 1e-9, atol 1e-12):")
    print(f"  mechanism: {tm * 1e3:.0f} ms (incl. code generation), {rm.nfev} RHS evaluations")
    print(f"  circuit:   {tc * 1e3:.0f} ms (incl. code generation), {rc.nfev} RHS evaluations")
    print(f"  max |x(t) − q(t)|   = {diff.max():.3e}  (peak |x| = {np.abs(x).max():.3f})")
    print(f"  max |x'(t) − q'(t)| = {vdiff.max():.3e}")
    exact = closed_form(rm.t)
    print(f"  against the closed-form solution: max |x − exact| = {np.abs(x - exact).max():.3e}, "
          f"max |q − exact| = {np.abs(q - exact).max():.3e}")
    print(f"  energy dissipated by the damper / the resistor: "
          f"{np.trapezoid(2 * rm.D, rm.t):.6f} J / {np.trapezoid(2 * rc.D, rc.t):.6f} J")

    fig, (top, bottom) = plt.subplots(2, 1, figsize=(9, 6), sharex=True, constrained_layout=True)
    top.plot(rm.t, x, lw=2.5, label=r"mass–spring–damper: $x(t)$ [m]")
    top.plot(rc.t, q, "--", lw=1.5, label=r"series RLC analogue: $q(t)$ [C]")
    top.plot(rm.t, exact, ":", color="k", lw=1, label="closed form")
    top.set_ylabel(r"$x$ [m], $q$ [C]")
    top.set_title(f"Driven mass–spring–damper and its series RLC analogue ($F = E = {sp.latex(FORCE)}$)")
    top.grid(True, alpha=0.3)
    top.legend(loc="upper right")
    bottom.semilogy(rm.t, np.maximum(np.abs(x - exact), 1e-18), color="C0", label=r"$|x - x_{\mathrm{exact}}|$")
    bottom.semilogy(rc.t, np.maximum(np.abs(q - exact), 1e-18), "--", color="C1", label=r"$|q - q_{\mathrm{exact}}|$")
    bottom.semilogy(rm.t, np.maximum(diff, 1e-18), color="C3", lw=0.8, label=r"$|x - q|$ (zero where identical)")
    bottom.set_ylabel("absolute difference")
    bottom.legend(loc="lower right", fontsize=8)
    bottom.set_xlabel(r"$t$ [s]")
    bottom.grid(True, which="both", alpha=0.3)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=120)
    print(f"\nchart written to {out}")

    print("\nngspice (through PySpice), step cap 2.5e-4 s:")
    derived = map_model(mech, "force-voltage")
    print(f"  the mechanism's force–voltage analogue, derived through the dual graph: "
          f"{', '.join(f'{name} ({c.kind}, from {derived.origin[name]})' for name, c in derived.model.components.items())}")
    for model, coord, analogy, suffix in ((circ, "q_L", None, "circuit"), (mech, "x_cart", "force-voltage", "mechanism")):
        cmp = compare_with_ngspice(model, args.t_end, analogy=analogy, initial={coord: X0}, velocity={coord: 0.0},
                                   step=0.01, max_step=2.5e-4)
        for line in cmp.table().splitlines():
            print("  " + line)
        if any(r.meaning.lstrip().startswith("-") for r in cmp.rows):
            print("  sign: v(C_k) = −k·x_cart is the spring's force on the mass, which the analogue's capacitor "
                  "voltage stands for: it has the opposite sign of the displacement, and both sides compare it")
        chart = cmp.chart(out.with_name(f"{out.stem}-ngspice-{suffix}{out.suffix}"))
        print(f"  chart written to {chart}")


if __name__ == "__main__":
    main()
