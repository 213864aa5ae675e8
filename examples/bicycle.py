"""The Whipple bicycle: self-stability against speed, and a ride between the weave and capsize speeds.
=====================================================================================================

The benchmark bicycle of Meijaard, Papadopoulos, Ruina and Schwab (Proc. R.
Soc. A 463, 2007), ``lagrangian.models.whipple_bicycle()``: a rear frame on
a free joint, a fork on the steer axis, two wheels rolling without slipping.
The script

1. linearizes straight running about every speed from 0 to 10 m/s
   (``frequency.speed_sweep``: Kane's independent coordinates and speeds,
   the state matrix quadratic in the speed), prints the eigenvalues at
   5 m/s beside the paper's Table 2, and the weave and capsize speeds beside
   the paper's;
2. rides it at 5 m/s, inside the self-stable range, after a sideways nudge
   (a lean rate of 0.2 rad/s): the lean dies away, the energy stays;
3. charts the eigenvalues against speed, the self-stable range shaded, and
   the ride's lean and steer.

Run: .venv/bin/python examples/bicycle.py [--out bicycle.png]
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from lagrangian import models
from lagrangian.frequency import speed_sweep
from lagrangian.plugins.multibody import consistent_initial

#: Meijaard et al. (2007), Table 2: the eigenvalues at 5 m/s, the weave and capsize speeds
PAPER_AT_5 = [-14.07838969279822, -0.77534188219585 + 4.46486771378823j, -0.32286642900409]
PAPER_WEAVE, PAPER_CAPSIZE = 4.29238253634111, 6.02426201538837
R_REAR, R_FRONT, TILT = 0.3, 0.35, math.pi / 10


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").partition("\n")[0])
    parser.add_argument("--out", default="bicycle.png", help="the chart (PNG)")
    args = parser.parse_args()

    bike = models.whipple_bicycle()
    upright = {"z_frame": R_REAR, "theta_pitch": -TILT}
    unit = {"x_frame": 1.0, "theta_rear": 1 / R_REAR, "theta_front": 1 / R_FRONT}   # rates at 1 m/s
    sweep = speed_sweep(bike, np.linspace(0.0, 10.0, 201), at=upright, velocity=unit)
    print(sweep)
    lam = np.linalg.eigvals(sweep.state_matrix(5.0))
    ours = sorted((z for z in lam if abs(z) > 1e-6 and z.imag >= 0), key=lambda z: z.real)
    print("eigenvalues at 5 m/s (1/s):")
    for z, paper in zip(ours, sorted(PAPER_AT_5, key=lambda z: z.real)):
        print(f"  {complex(z):.14g}   paper {complex(paper):.14g}   off {abs(z - paper):.1e}")
    weave, capsize = sweep.crossings()
    print(f"weave speed   {weave.speed:.15g} m/s, paper {PAPER_WEAVE}: off {abs(weave.speed - PAPER_WEAVE):.1e}")
    print(f"capsize speed {capsize.speed:.15g} m/s, paper {PAPER_CAPSIZE}: off {abs(capsize.speed - PAPER_CAPSIZE):.1e}")

    # a ride at 5 m/s after a sideways nudge: the rates the constraints allow, the lean's rate given
    v = 5.0
    start = consistent_initial(bike, {**dict.fromkeys(bike.coordinate_names, 0.0), **upright},
                               {"theta_roll": 0.2, "theta_rear": v / R_REAR},
                               independent=["x_frame", "y_frame", "theta_yaw", "theta_roll", "theta_rear",
                                            "theta_steer", "theta_front"])
    res = bike.simulate(6.0, initial=start.initial, velocity=start.velocity, points=601, rtol=1e-10, atol=1e-12)
    lean = res["theta_roll"]
    drift = float(np.max(np.abs(res.E - res.E[0])) / abs(res.E[0]))
    print(f"ride at {v} m/s: lean peaks at {np.max(np.abs(lean)):.4f} rad, {abs(lean[-1]):.2e} rad after "
          f"{res.t[-1]:.0f} s; energy kept to {drift:.1e}")

    fig, (a, b) = plt.subplots(1, 2, figsize=(12, 4.5))
    sweep.plot(ax=a, ylim=(-10, 10))
    a.set_xlabel("speed (m/s)")
    b.plot(res.t, lean, label="lean (rad)")
    b.plot(res.t, res["theta_steer"], label="steer (rad)")
    b.set(xlabel="t (s)", title=f"a nudge at {v} m/s dies away")
    b.legend()
    fig.tight_layout()
    fig.savefig(args.out, dpi=110)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
