"""Pendulums from rigid bodies and revolute joints: simple, double and n-link.
===========================================================================

1. Simple pendulum: a point mass on a massless link, released from rest at
   amplitude A from the downward vertical.  Its period is exactly
   T = 4 √(L/g) K(sin²(A/2)) (K the complete elliptic integral of the first
   kind, parameter m = k²); the script measures the simulated period from
   the downward crossings of the vertical and prints both.
2. Double pendulum: two uniform rods (absolute angles).  Energy is conserved:
   the relative drift of T + V at tight tolerances is printed.
3. n-link pendulum: a chain of n uniform rods (relative angles); the energy
   drift again.

Angles of absolute revolute joints are measured from the x axis, so hanging
straight down is θ = −π/2.  Writes a chart with the three motions.

Run: .venv/bin/python examples/pendulums.py [--t-end 20] [--links 5] [--out pendulums.png]
"""

from __future__ import annotations

import argparse
import math
import warnings
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from scipy.special import ellipk

import lagrangian as lg

G = 9.81
TIGHT = {"rtol": 1e-12, "atol": 1e-14}


def simple_pendulum(L: float, m: float = 1.0) -> lg.Model:
    model = lg.Model("simple pendulum", dim=2)
    model.add("link", "arm", "arm", points={"bob": (L, 0)})
    model.add("revolute", "pin", ("ground", "arm"), absolute=True)
    model.add("mass", "bob", "arm.bob", m=m)
    model.add("gravity", "g", g=G)
    return model


def double_pendulum() -> lg.Model:
    model = lg.Model("double pendulum", dim=2)
    model.add("rod", "upper", "upper", m=1.0, length=1.0)
    model.add("rod", "lower", "lower", m=1.0, length=1.0)
    model.add("revolute", "shoulder", ("ground", "upper"), absolute=True)
    model.add("revolute", "elbow", ("upper", "lower"), parent_point=(1.0, 0), absolute=True)
    model.add("gravity", "g", g=G)
    return model


def chain(n: int) -> lg.Model:
    model = lg.Model(f"{n}-link pendulum", dim=2)
    parent = "ground"
    for i in range(n):
        model.add("rod", f"r{i}", f"r{i}", m=1.0, length=0.5)
        model.add("revolute", f"j{i}", (parent, f"r{i}"), parent_point=(0, 0) if i == 0 else (0.5, 0))
        parent = f"r{i}"
    model.add("gravity", "g", g=G)
    return model


def downward_crossings(t: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Times where x crosses zero going down, linearly interpolated (x is an inflection there: accurate)."""
    i = np.flatnonzero((x[:-1] > 0) & (x[1:] <= 0))
    return t[i] - x[i] * (t[i + 1] - t[i]) / (x[i + 1] - x[i])


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").partition("\n")[0])
    parser.add_argument("--t-end", type=float, default=20.0, help="simulated time span [s]")
    parser.add_argument("--links", type=int, default=5, help="links of the n-link pendulum")
    parser.add_argument("--out", default="pendulums.png", help="where to write the chart (PNG)")
    args = parser.parse_args()
    warnings.simplefilter("ignore", lg.InitialConditionWarning)
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.8), constrained_layout=True)

    # 1. simple pendulum: period against the elliptic integral
    L, A = 0.8, 2.0
    model = simple_pendulum(L)
    res = model.simulate(args.t_end, initial={"theta_pin": -math.pi / 2 + A}, velocity={"theta_pin": 0.0},
                         points=int(400 * args.t_end) + 1, **TIGHT)
    swing = res["theta_pin"] + math.pi / 2
    crossings = downward_crossings(res.t, swing)
    exact = 4 * math.sqrt(L / G) * ellipk(math.sin(A / 2) ** 2)
    print(f"simple pendulum (L = {L} m, amplitude {A} rad = {math.degrees(A):.1f}°):")
    if len(crossings) >= 2:
        period = float(np.mean(np.diff(crossings)))
        print(f"  period simulated {period:.10f} s, exact 4√(L/g) K(sin²(A/2)) = {exact:.10f} s "
              f"(small-amplitude 2π√(L/g) = {2 * math.pi * math.sqrt(L / G):.4f} s)")
    else:
        print(f"  fewer than two swings in {args.t_end} s; exact period {exact:.10f} s")
    print(f"  relative energy drift {res.energy_drift():.2e}")
    axes[0].plot(res.t, swing, label="θ + π/2 (from the downward vertical)")
    axes[0].set_title(f"simple pendulum, amplitude {A} rad: T = {exact:.4f} s")
    axes[0].set_xlabel("t [s]")
    axes[0].set_ylabel("angle [rad]")

    # 2. double pendulum: energy
    model = double_pendulum()
    res = model.simulate(args.t_end, initial={"theta_shoulder": 0.0, "theta_elbow": 0.5},
                         velocity={"theta_shoulder": 0.0, "theta_elbow": 0.0}, points=int(200 * args.t_end) + 1, **TIGHT)
    print(f"double pendulum (released horizontal, {args.t_end:g} s): relative energy drift {res.energy_drift():.2e}")
    tip = model.assembly.views["mechanical"].position("lower.end")
    x, y = res.quantity(tip[0]), res.quantity(tip[1])
    axes[1].plot(x, y, lw=0.6)
    axes[1].set_title("double pendulum: path of the tip")
    axes[1].set_aspect("equal")

    # 3. n-link pendulum: energy
    n = args.links
    model = chain(n)
    init = {f"theta_j{i}": (-math.pi / 2 + 1.0 if i == 0 else 0.3 * (-1) ** i) for i in range(n)}
    res = model.simulate(args.t_end, initial=init, velocity={}, points=int(100 * args.t_end) + 1, **TIGHT)
    print(f"{n}-link pendulum ({n} coordinates, {args.t_end:g} s): relative energy drift {res.energy_drift():.2e}")
    tip = model.assembly.views["mechanical"].position(f"r{n - 1}.end")
    axes[2].plot(res.quantity(tip[0]), res.quantity(tip[1]), lw=0.6)
    axes[2].set_title(f"{n}-link pendulum: path of the last tip")
    axes[2].set_aspect("equal")
    for ax in axes:
        ax.grid(True, alpha=0.3)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    print(f"chart written to {out}")


if __name__ == "__main__":
    main()
