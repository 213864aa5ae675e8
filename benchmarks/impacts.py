"""Impacts: error of the impact time and of the post-impact state against the event-location tolerance.

Two scenes with exact answers:

1. A ball dropped from 1 m (e = 0.8): impact k at t_k = t₁ + 2v₁(e + … + e^{k−1})/g,
   leaving at e^k v₁.  Free flight under gravity is a polynomial, so DOP853
   integrates it exactly and the error is the event location's alone.
2. A pendulum (ℓ = 1, released 1.2 rad from the vertical) against a wall
   through its pivot (e = 0.8): impact j at √(ℓ/g)·[K(k₀²) + 2 Σ K(k_i²)],
   k_i = e^i sin(α/2); here the integration error adds (rtol 1e-12).

For each ``event_tol`` (the time tolerance of Brent's method on the dense
output) the table gives the largest error over the first five impacts of the
impact time, of the post-impact velocity, and of the post-impact position
(the gap at the located time: 0 exactly at the true impact), with the number
of right-hand-side evaluations.  Writes ``benchmarks/impacts.png``; the last
line printed is a JSON summary.

Run: ``.venv/bin/python benchmarks/impacts.py``
"""

from __future__ import annotations

import json
import math
import warnings
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from scipy.special import ellipk  # noqa: E402

import lagrangian as lg  # noqa: E402
from lagrangian.impulse import ground, simulate_with_impacts, wall  # noqa: E402

warnings.simplefilter("ignore", lg.InitialConditionWarning)
G, E, IMPACTS = 9.81, 0.8, 5
TOLS = [10.0**-k for k in range(1, 15)]


def ball_scene():
    model = lg.Model("ball")
    model.add("mass", "m", "ball", m=1.0)
    model.add("gravity", "g", g=G)
    v1, t1 = math.sqrt(2 * G), math.sqrt(2 / G)
    times = np.array([t1 + 2 * v1 * sum(E**i for i in range(1, k + 1)) / G for k in range(IMPACTS)])
    speeds = v1 * E ** np.arange(1, IMPACTS + 1)  # leaving speeds

    def run(tol):
        res = simulate_with_impacts(model, times[-1] + 0.05, [ground("ball", e=E)], initial={"x_ball": 1.0},
                                    velocity={"x_ball": 0.0}, event_tol=tol, points=3)
        r = res.impacts[:IMPACTS]
        return (np.array([x.time for x in r]), np.array([x.after["x_ball"] for x in r]),
                np.array([res.q["x_ball"][np.searchsorted(res.t, x.time)] for x in r]), res.nfev)

    return "bouncing ball", times, speeds, run


def pendulum_scene(alpha=1.2):
    model = lg.Model("pendulum", dim=2)
    model.add("link", "arm", "arm", points={"bob": (1.0, 0)})
    model.add("revolute", "pin", ("ground", "arm"), absolute=True)
    model.add("mass", "m", "arm.bob", m=1.0)
    model.add("gravity", "g", g=G)
    k = [math.sin(alpha / 2) * E**j for j in range(IMPACTS)]
    tau = 1 / math.sqrt(G)
    times = tau * (ellipk(k[0] ** 2) + 2 * np.concatenate([[0], np.cumsum([ellipk(x**2) for x in k[1:]])]))
    # leaving angular speed: e times the arrival speed 2 sin(α_j/2)·√(g/ℓ)
    speeds = np.array([2 * x * math.sqrt(G) * E * (-1) ** j for j, x in enumerate(k)])

    def run(tol):
        res = simulate_with_impacts(model, times[-1] + 0.05, [wall("arm.bob", 0.0, side=+1, e=E)],
                                    initial={"theta_pin": -math.pi / 2 + alpha}, velocity={"theta_pin": 0.0},
                                    event_tol=tol, rtol=1e-12, atol=1e-14, points=3)
        r = res.impacts[:IMPACTS]
        return (np.array([x.time for x in r]), np.array([x.after["theta_pin"] for x in r]),
                np.array([math.cos(res.q["theta_pin"][np.searchsorted(res.t, x.time)]) for x in r]), res.nfev)

    return "pendulum on a wall", times, speeds, run


def main() -> None:
    summary = {}
    fig, axes = plt.subplots(1, 2, figsize=(13, 4.8), constrained_layout=True)
    for ax, (name, times, speeds, run) in zip(axes, (ball_scene(), pendulum_scene())):
        print(f"\n{name}: first {IMPACTS} impacts, e = {E}")
        print(f"{'event_tol':>10} {'|Δt_impact|':>12} {'|Δ velocity after|':>19} {'|gap at impact|':>16} {'nfev':>6}")
        rows = []
        for tol in TOLS:
            t_sim, v_sim, gap, nfev = run(tol)
            row = (tol, float(np.max(np.abs(t_sim - times))), float(np.max(np.abs(np.abs(v_sim) - np.abs(speeds)))),
                   float(np.max(np.abs(gap))), int(nfev))
            rows.append(row)
            print(f"{row[0]:10.0e} {row[1]:12.3e} {row[2]:19.3e} {row[3]:16.3e} {row[4]:6d}")
        rows = np.array(rows)
        floor = np.finfo(float).eps
        for col, label, style in ((1, "impact time error [s]", "o-"), (2, "post-impact velocity error", "s-"),
                                  (3, "gap at the located impact", "^-")):
            ax.loglog(rows[:, 0], np.maximum(rows[:, col], floor), style, label=label)
        ax.loglog(rows[:, 0], rows[:, 0], "k:", label="event_tol")
        ax.set_xlabel("event-location tolerance event_tol [s]")
        ax.set_ylabel("largest error over the first five impacts")
        ax.set_title(name)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
        summary[name] = {
            "time_error_at_1e-3": rows[TOLS.index(1e-3), 1], "time_error_at_1e-12": rows[TOLS.index(1e-12), 1],
            "velocity_error_at_1e-12": rows[TOLS.index(1e-12), 2], "nfev_at_1e-12": int(rows[TOLS.index(1e-12), 4]),
        }
    out = Path(__file__).with_suffix(".png")
    fig.savefig(out, dpi=110)
    print(f"\nchart written to {out}")
    print(json.dumps({"benchmark": "impacts", "impacts": IMPACTS, "e": E, **summary}))


if __name__ == "__main__":
    main()
