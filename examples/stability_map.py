"""A stability map: where a steady motion stays stable, over a plane of two parameters, swept on Dask.
===================================================================================================

A pendulum hangs from a turntable (a disc of 2 kg and 0.25 m turning freely
about the vertical; a bob of 0.3 kg on an arm of length l pinned to it by a
horizontal hinge).  The turntable's angle is ignorable: its momentum C is
conserved, and the Routhian reduces the model to the tilt θ alone
(``lagrangian.routh``).  Hanging straight down (θ = 0) is a steady motion
for every C; the turntable then spins at Ω = C / I.  Is it stable?

The script sweeps Ω and l over a grid with ``lagrangian.sweep.sweep(...,
analysis=verdict)``: for each sample, the steady motions at that momentum
and their stability verdict (from the eigenvalues of the perturbation
equations and the effective potential's curvature), run on the local Dask
cluster.  The effective potential V = C²/2(I + m l² sin²θ) − m g l cos θ has
V''(0) = m l (g − Ω² l), so hanging down is stable exactly where Ω² l < g:
the script counts the samples whose verdict agrees with that boundary, and
charts the map with the boundary drawn over it.  Beyond it the bob settles
on one of two conical steady motions at θ = ±arccos(g (I + m l²) ... ) — the
map's second panel shows their tilt.

Run: .venv/bin/python examples/stability_map.py [--points 16] [--out stability_map.png] [--serial]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import sympy as sp

import lagrangian as lg
from lagrangian import routh
from lagrangian.sweep import describe, plot, sweep

G, TABLE_MASS, TABLE_RADIUS, BOB = 9.81, 2.0, 0.25, 0.3
INERTIA = 0.5 * TABLE_MASS * TABLE_RADIUS**2  # the turntable's, about its axis (the bob adds m l² sin²θ)


def turntable_pendulum() -> lg.Model:
    """The turntable and its pendulum, the arm's length a symbol ``l`` (given per sample)."""
    length = sp.Symbol("l", positive=True)
    m = lg.Model("turntable pendulum", dim=3)
    m.add("disc", "table", "table", m=TABLE_MASS, radius=TABLE_RADIUS)
    m.add("revolute", "turn", ("ground", "table"), axis=(0, 0, 1))
    m.add("link", "arm", "arm", points={"bob": (0, 0, -length)})
    m.add("revolute", "tilt", ("table", "arm"), axis=(1, 0, 0))
    m.add("mass", "bob", "arm.bob", m=BOB)
    m.add("gravity", "g", g=G)
    return m


def verdict(model: lg.Model, values: dict[str, float]) -> dict[str, object]:
    """The steady motions at the turntable's momentum C = I Ω, with l given: hanging down's verdict, and the
    tilt of the conical ones (0 when there are none).  Runs on a worker: the reduction is done once per worker
    (it is cached on the model) and each sample solves numerically."""
    reduced = routh.reduce(model)
    motions = reduced.steady_motions(params={"l": values["l"]}, momenta={"theta_turn": INERTIA * values["Omega"]})
    down = next(s for s in motions if abs(float(s.coordinates["theta_tilt"])) < 1e-9)
    tilts = [abs(float(s.coordinates["theta_tilt"])) for s in motions if s is not down]
    stability = down.stability()
    return {"hanging": stability.verdict, "cone_tilt": max(tilts, default=0.0),
            "growth": float(max(np.real(stability.eigenvalues), default=0.0))}


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").partition("\n")[0])
    parser.add_argument("--points", type=int, default=16, help="values of Ω and of l (a points × points grid)")
    parser.add_argument("--out", default="stability_map.png", help="where to write the chart (PNG)")
    parser.add_argument("--serial", action="store_true", help="run in this process instead of on Dask")
    args = parser.parse_args()
    omega = np.linspace(1.0, 8.0, args.points)
    length = np.geomspace(0.1, 2.0, args.points)
    ds = sweep(turntable_pendulum(), {"Omega": omega, "l": length}, analysis=verdict,
               units={"Omega": "rad/s", "l": "m"}, client="serial" if args.serial else None)
    print(describe(ds))
    done = ds.status == 0
    stable = ds.hanging == "stable"
    boundary = ds.Omega**2 * ds.l < G
    near = abs(ds.Omega**2 * ds.l / G - 1) < 1e-6  # on the boundary itself the verdict is undecided
    agree = int(((stable == boundary) | near).where(done, False).sum())
    print(f"hanging down: stable where Ω² l < g in {agree} of {int(done.sum())} samples "
          f"(closed form V''(0) = m l (g − Ω² l))")
    fig, (left, right) = plt.subplots(1, 2, figsize=(13, 5), constrained_layout=True)
    plot(ds, "hanging", x="Omega", y="l", ax=left)
    plot(ds, "cone_tilt", x="Omega", y="l", ax=right)
    curve = np.linspace(omega[0], omega[-1], 200)
    for ax in (left, right):
        ax.plot(curve, G / curve**2, "w--", lw=1.5, label="Ω² l = g")
        ax.set_ylim(length[0], length[-1])
        ax.legend(loc="upper right", fontsize=8)
    left.set_title("hanging down, turntable at Ω: verdict")
    right.set_title("tilt of the conical steady motions [rad]")
    fig.savefig(args.out, dpi=120)
    print(f"written: {args.out}")


if __name__ == "__main__":
    main()
