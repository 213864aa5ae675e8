"""The Python overhead of one warm ``Model.simulate``: what a fit that calls it thousands of times pays per call.

Model: ``lagrangian.models.double_pendulum()``; the call is
``m.simulate(1e-6, initial={"theta_j1": 0.3, "theta_j2": -0.2}, velocity={"theta_j1": 0, "theta_j2": 0},
points=2)`` with the defaults (``method="DOP853"``, ``compiled="auto"``): a run of a few steps that takes
microseconds in C, so its wall time is the overhead of the Python around it.  One warm-up call (derivation,
compiled code loaded, caches filled), then ``--calls`` timed calls (default 500), each timed alone with
``time.perf_counter``.  Prints the median and the minimum (and quartiles) in milliseconds; the last line is a JSON
object ``{"simulate_overhead_ms": <median>, "simulate_overhead_min_ms": <minimum>, ...}``.

Run: ``.venv/bin/python benchmarks/overhead.py [--calls 500]``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
import warnings


def measure(calls: int) -> dict:
    from lagrangian import models

    m = models.double_pendulum()
    kwargs = dict(initial={"theta_j1": 0.3, "theta_j2": -0.2}, velocity={"theta_j1": 0, "theta_j2": 0}, points=2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m.simulate(1e-6, **kwargs)  # warm-up: derivation, compiled code, caches
        times = []
        for _ in range(calls):
            start = time.perf_counter()
            m.simulate(1e-6, **kwargs)
            times.append(time.perf_counter() - start)
    ms = sorted(1e3 * x for x in times)
    q1, _, q3 = statistics.quantiles(ms, n=4)
    return {"simulate_overhead_ms": round(statistics.median(ms), 4), "simulate_overhead_min_ms": round(ms[0], 4),
            "simulate_overhead_q1_ms": round(q1, 4), "simulate_overhead_q3_ms": round(q3, 4), "calls": calls}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--calls", type=int, default=500)
    args = parser.parse_args()
    out = measure(args.calls)
    print(f"warm Model.simulate on double_pendulum (t_end=1e-6, points=2, DOP853, compiled='auto'), {out['calls']} calls")
    print(f"{'':10s} {'ms':>9s}")
    for label, key in (("min", "simulate_overhead_min_ms"), ("q1", "simulate_overhead_q1_ms"),
                       ("median", "simulate_overhead_ms"), ("q3", "simulate_overhead_q3_ms")):
        print(f"{label:10s} {out[key]:9.4f}")
    print(json.dumps({"simulate_overhead_ms": out["simulate_overhead_ms"],
                      "simulate_overhead_min_ms": out["simulate_overhead_min_ms"]}))


if __name__ == "__main__":
    main()
