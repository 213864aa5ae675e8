"""Work–precision of simulation: error against wall time over methods and tolerances.

Model: the demo's driven mass–spring–damper (m=1, k=4, c=0.4, F=sin 1.5t,
x(0)=0.1), whose closed-form solution gives the exact error. Prints a table
(method, rtol, RHS evaluations, wall time, max error) and writes
``benchmarks/simulation.png``. Run: ``make benchmark``.
"""

from __future__ import annotations

import sys
import time
import warnings
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "examples"))
import demo  # noqa: E402

import lagrangian as lg  # noqa: E402

METHODS = ("RK45", "DOP853", "Radau", "LSODA")
RTOLS = (1e-4, 1e-6, 1e-8, 1e-10, 1e-12)


def main() -> None:
    model = demo.mechanism()
    start = time.perf_counter()
    model.numeric()
    print(f"derivation + code generation: {(time.perf_counter() - start) * 1e3:.1f} ms")
    t_eval = np.linspace(0, 20, 401)
    exact = demo.closed_form(t_eval)
    rows = []
    print(f"{'method':8} {'rtol':>8} {'nfev':>7} {'wall ms':>9} {'max error':>10}")
    for method in METHODS:
        for rtol in RTOLS:
            times = []
            for _ in range(3):
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", lg.InitialConditionWarning)
                    t0 = time.perf_counter()
                    res = model.simulate(20, initial={"x_cart": demo.X0}, t_eval=t_eval, method=method, rtol=rtol, atol=rtol * 1e-3)
                    times.append(time.perf_counter() - t0)
            err = float(np.max(np.abs(res["x_cart"] - exact)))
            wall = min(times)
            rows.append((method, rtol, res.nfev, wall, err))
            print(f"{method:8} {rtol:8.0e} {res.nfev:7d} {wall * 1e3:9.2f} {err:10.2e}")

    fig, ax = plt.subplots(figsize=(7, 5), constrained_layout=True)
    for method in METHODS:
        pts = [(w, e) for m, _, _, w, e in rows if m == method]
        ax.loglog([p[0] * 1e3 for p in pts], [p[1] for p in pts], "o-", label=method)
    ax.set_xlabel("wall time per simulation [ms]")
    ax.set_ylabel("max |x − closed form| over 0–20 s")
    ax.set_title("Work–precision: driven mass–spring–damper")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    out = Path(__file__).with_suffix(".png")
    fig.savefig(out, dpi=110)
    print(f"chart written to {out}")


if __name__ == "__main__":
    main()
