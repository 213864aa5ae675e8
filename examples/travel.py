"""A model that travels: pickled, saved to a file, exported as an FMU and handed to python-control.
=================================================================================================

The double pendulum of ``lagrangian.models`` goes four ways out of this
process, and each way is checked against the model itself:

1. pickled and unpickled: the unpickled model simulates bit for bit as the
   original;
2. saved as a model file (versioned JSON) and loaded back: the same;
3. exported as an FMI 2.0 FMU and run by FMPy (when installed: ``pip
   install 'lagrangian[fmi]'``): the largest difference from our run,
   relative to the peak;
4. linearized about its rest, hanging, and handed to python-control (when installed:
   ``pip install 'lagrangian[control]'``): its Bode response against ours.

Run: .venv/bin/python examples/travel.py [--out travel.png] [--dir DIR]
"""

from __future__ import annotations

import argparse
import importlib.util
import pickle
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

import lagrangian as lg
from lagrangian import models
from lagrangian.frequency import decades, frequency_response, linearize

START = {"initial": {"theta_j1": 0.6, "theta_j2": -0.3}, "velocity": {"theta_j1": 0.0, "theta_j2": 0.0}}


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").partition("\n")[0])
    parser.add_argument("--out", default="travel.png", help="the chart (PNG)")
    parser.add_argument("--dir", help="where the model file and the FMU go (default: a temporary directory)")
    args = parser.parse_args()
    where = Path(args.dir) if args.dir else Path(tempfile.mkdtemp())
    where.mkdir(parents=True, exist_ok=True)

    model = models.double_pendulum(m1=0.3, m2=0.2, l1=0.5, l2=0.4)
    res = model.simulate(5.0, points=501, method="DOP853", rtol=1e-12, atol=1e-14, **START)

    again = pickle.loads(pickle.dumps(model))
    same = again.simulate(5.0, points=501, method="DOP853", rtol=1e-12, atol=1e-14, **START)
    print(f"pickled: {len(pickle.dumps(model))} bytes; bit for bit the same run: "
          f"{all(np.array_equal(res[n], same[n]) for n in res.names)}")

    path = where / "double_pendulum.json"
    model.save(path)
    loaded = lg.load(path)
    same = loaded.simulate(5.0, points=501, method="DOP853", rtol=1e-12, atol=1e-14, **START)
    print(f"model file {path.name}: {path.stat().st_size} bytes; bit for bit the same run: "
          f"{all(np.array_equal(res[n], same[n]) for n in res.names)}")

    fmu_run = None
    if importlib.util.find_spec("fmpy") is not None:
        from fmpy import simulate_fmu

        fmu = model.to_fmu(where / "double_pendulum.fmu", **START)
        fmu_run = simulate_fmu(str(fmu), stop_time=5.0, output_interval=0.01, relative_tolerance=1e-12,
                               output=["theta_j1", "theta_j2"])
        worst = max(float(np.max(np.abs(np.interp(res.t, fmu_run["time"], fmu_run[n]) - res[n])) /
                          np.max(np.abs(res[n]))) for n in ("theta_j1", "theta_j2"))
        print(f"FMU {Path(fmu).name}: FMPy's run against ours: {worst:.1e} of the peak")
    else:
        print("FMU: FMPy is not installed (pip install 'lagrangian[fmi]'): not run")

    bode = None
    if importlib.util.find_spec("control") is not None:
        driven = models.double_pendulum(m1=0.3, m2=0.2, l1=0.5, l2=0.4)
        driven.add("generalized_force", "T", coordinate="theta_j1", Q=0)  # a torque on the upper joint
        down = -np.pi / 2  # hanging: the angles are from the x axis
        lin = linearize(driven, at={"theta_j1": down, "theta_j2": down}, inputs=["T"], outputs=["theta_j1"])
        f = decades(0.05, 5.0, 40)
        ours = frequency_response(lin, f).H[0, 0]
        theirs = np.array([complex(lin.to_control()(2j * np.pi * fk)) for fk in f])
        bode = (f, ours, theirs)
        print(f"python-control: its Bode response against ours: {np.max(np.abs(theirs - ours) / np.abs(ours)):.1e}")
    else:
        print("python-control is not installed (pip install 'lagrangian[control]'): not compared")

    fig, (a, b) = plt.subplots(1, 2, figsize=(12, 4.5))
    for n in ("theta_j1", "theta_j2"):
        a.plot(res.t, res[n], label=f"{n} (ours)")
        if fmu_run is not None:
            a.plot(fmu_run["time"][::20], fmu_run[n][::20], "o", ms=3, label=f"{n} (FMU in FMPy)")
    a.set(xlabel="t (s)", ylabel="angle (rad)", title="the double pendulum, here and as an FMU")
    a.legend(fontsize=8)
    if bode is not None:
        f, ours, theirs = bode
        b.loglog(f, np.abs(ours), label="ours")
        b.loglog(f, np.abs(theirs), "o", ms=3, label="python-control")
        b.set(xlabel="f (Hz)", ylabel="|θ₁ / T| (rad/N m)", title="torque on the upper arm to its angle")
        b.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(args.out, dpi=110)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
