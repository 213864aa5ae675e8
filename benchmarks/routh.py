"""Reduced (Routhian) model against the full model: work–precision for the spherical pendulum and Kepler.

For each example and each tolerance (DOP853, rtol = atol/100 from 1e-4 to
1e-12) three runs are timed — the full model, the reduced model alone (the
non-ignorable coordinates) and the reduced model with the ignorable
coordinates reconstructed by quadrature — and their largest error on every
coordinate they return is measured against a tight reference (the full
model, DOP853 at rtol 1e-13).  Wall times are medians of repeated runs with
the derivation and code generation already done (they are reported once,
separately).  One PNG per example; a table; the last line is a JSON object.

Run: .venv/bin/python benchmarks/routh.py [--repeat 5] [--out-dir benchmarks]
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "examples"))

from kepler import central  # noqa: E402
from spherical_steady import spherical  # noqa: E402

from lagrangian import routh  # noqa: E402

TOLERANCES = [1e-4, 1e-6, 1e-8, 1e-10, 1e-12]
CASES = {
    "spherical pendulum": dict(
        build=spherical, span=20.0,
        initial={"theta_turn": 0.2, "theta_tilt": 0.9}, velocity={"theta_turn": 1.7, "theta_tilt": -0.4},
    ),
    "kepler": dict(
        build=central, span=40.0,
        initial={"theta_orbit": 0.0, "s_radius": 1.0}, velocity={"theta_orbit": 0.75, "s_radius": 0.3},
    ),
}


def timed(fn, repeat: int):
    times, out = [], None
    for _ in range(repeat):
        start = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times), out


def error(res, ref, names) -> float:
    return max(float(np.max(np.abs(res[n] - ref[n]))) for n in names)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5, help="runs per timing (median)")
    parser.add_argument("--out-dir", default=str(Path(__file__).resolve().parent), help="where to write the PNGs")
    args = parser.parse_args()
    rows, summary = [], {}
    for label, case in CASES.items():
        start = time.perf_counter()
        model = case["build"]()
        model.eq
        t_full = time.perf_counter() - start
        start = time.perf_counter()
        red = routh.reduce(model)
        red.eq
        red.reconstructing(True).eq
        t_red = time.perf_counter() - start
        common = dict(initial=case["initial"], velocity=case["velocity"], points=2001)
        ref = model.simulate(case["span"], rtol=1e-13, atol=1e-15, **common)
        kept = red.coordinate_names
        print(f"{label}: derivation full {t_full:.3f} s, reduction {t_red:.3f} s; span {case['span']} s; "
              f"remaining {kept}, ignorable {red.ignored}", flush=True)
        series = {"full": [], "reduced": [], "reduced + reconstructed": []}
        for tol in TOLERANCES:
            opts = dict(rtol=tol, atol=tol / 100, **common)
            runs = {
                "full": (lambda: model.simulate(case["span"], **opts), model.coordinate_names),
                "reduced": (lambda: red.simulate(case["span"], **opts), kept),
                "reduced + reconstructed": (lambda: red.simulate(case["span"], reconstruct=True, **opts), model.coordinate_names),
            }
            for name, (fn, names) in runs.items():
                fn()  # numeric functions built, caches warm
                wall, res = timed(fn, args.repeat)
                err = error(res, ref, names)
                series[name].append((wall, err))
                rows.append((label, name, tol, wall, err))
        # chart
        fig, ax = plt.subplots(figsize=(6.5, 4.8), constrained_layout=True)
        for name, pts in series.items():
            w, e = zip(*pts)
            ax.loglog(e, np.array(w) * 1e3, "o-", label=name)
        ax.set_xlabel("max error vs reference")
        ax.set_ylabel("wall time [ms]")
        ax.set_title(f"{label}: reduced vs full (DOP853, rtol 1e-4 … 1e-12)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
        path = Path(args.out_dir) / f"routh-{label.replace(' ', '-')}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        full_t = np.array([w for w, _ in series["full"]])
        red_t = np.array([w for w, _ in series["reduced"]])
        rec_t = np.array([w for w, _ in series["reduced + reconstructed"]])
        summary[label] = {
            "speedup_reduced": float(np.median(full_t / red_t)),
            "speedup_reconstructed": float(np.median(full_t / rec_t)),
            "error_full_at_1e-8": series["full"][2][1],
            "error_reduced_at_1e-8": series["reduced"][2][1],
        }
        print(f"  chart: {path}", flush=True)

    print()
    print("| example | model | rtol | wall ms | max error |")
    print("|---|---|---|---|---|")
    for label, name, tol, wall, err in rows:
        print(f"| {label} | {name} | {tol:.0e} | {wall * 1e3:.2f} | {err:.2e} |")
    print()
    for label, s in summary.items():
        print(f"{label}: reduced is {s['speedup_reduced']:.2f}× faster than full (median over tolerances), "
              f"{s['speedup_reconstructed']:.2f}× with reconstruction; at rtol 1e-8 error full {s['error_full_at_1e-8']:.2e}, "
              f"reduced {s['error_reduced_at_1e-8']:.2e}")
    print(json.dumps({label.replace(" ", "_"): {k: round(v, 4) if "speedup" in k else v for k, v in s.items()}
                      for label, s in summary.items()}))


if __name__ == "__main__":
    main()
