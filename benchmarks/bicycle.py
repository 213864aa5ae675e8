"""The Whipple bicycle linearized about straight running: ours against sympy.physics.mechanics' KanesMethod.

Model: the benchmark bicycle of Meijaard, Papadopoulos, Ruina and Schwab (2007), ``lagrangian.models.
whipple_bicycle()``; the peer is the same bicycle written for ``KanesMethod`` (``tests/test_bicycle.py``'s
``kane_method``: yaw, roll, pitch and steer, pitch dependent through the front contact's height, three independent
speeds, the front contact's three velocity constraints).

- ``derive``: ours, the equations from the model (``model.eq``); Kane's, ``kanes_equations``.
- ``linearize``: ours, ``linearize(model, at=, velocity=)`` and ``state_space()`` at 5 m/s; Kane's,
  ``KanesMethod.linearize(op_point=..., A_and_B=True)`` (symbolic, the straight-running point substituted), then
  its state matrix evaluated at 5 m/s.  Kane's is stopped after ``--budget`` seconds.
- ``sweep``: ours, ``speed_sweep`` over 101 speeds from 0 to 10 m/s with the weave and capsize speeds found;
  against linearizing at each speed apart (the time of one, times 101).
- ``error``: the largest difference of our lean–steer state matrix at 5 m/s from the one the benchmark's published
  matrices give, relative; the weave and capsize speeds against the published ones.

Run: ``.venv/bin/python benchmarks/bicycle.py [--budget 300]``.
"""

from __future__ import annotations

import argparse
import json
import math
import multiprocessing
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))


def ours() -> dict:
    from lagrangian import models
    from lagrangian.frequency import linearize, speed_sweep
    from test_bicycle import BENCH, WEAVE_SPEED, CAPSIZE_SPEED, FLIP, LATERAL, published, unit_speed

    out = {}
    began = time.perf_counter()
    bike = models.whipple_bicycle()
    bike.eq
    out["derive_s"] = time.perf_counter() - began
    at = {"z_frame": BENCH["rR"], "theta_pitch": -BENCH["lam"]}
    began = time.perf_counter()
    A, _, _, _, states = linearize(bike, at=at, velocity={k: 5 * x for k, x in unit_speed().items()},
                                   inputs=[]).state_space()
    out["linearize_s"] = time.perf_counter() - began
    lateral = [states.index(n) for n in LATERAL]
    mine = FLIP @ A[np.ix_(lateral, lateral)] @ FLIP
    out["error_vs_published"] = float(np.max(np.abs(mine - published(5.0))) / np.max(np.abs(published(5.0))))
    began = time.perf_counter()
    sweep = speed_sweep(bike, np.linspace(0, 10, 101), at=at, velocity=unit_speed())
    weave, capsize = sweep.crossings()
    out["sweep_101_s"] = time.perf_counter() - began
    out["each_speed_apart_101_s"] = 101 * out["linearize_s"]
    out["weave_speed"], out["capsize_speed"] = weave.speed, capsize.speed
    out["weave_error"], out["capsize_error"] = abs(weave.speed - WEAVE_SPEED), abs(capsize.speed - CAPSIZE_SPEED)
    return out


def _kane(queue) -> None:
    import sympy as sp
    from test_bicycle import BENCH, kane_method

    began = time.perf_counter()
    km, q, u, height, slip, _ = kane_method()
    derive = time.perf_counter() - began
    began = time.perf_counter()
    yaw, roll, pitch, steer = q
    v = sp.Symbol("v")
    point = {**{x: 0 for x in (yaw, roll, steer)}, pitch: 0, **{x.diff(): 0 for x in q},
             u[0]: 0, u[1]: -v / BENCH["rR"], u[2]: 0, u[3]: 0, u[4]: 0, u[5]: -v / BENCH["rF"]}
    point.update({x.diff(): 0 for x in u})
    A, *_ = km.linearize(op_point=point, A_and_B=True)
    A5 = np.array(A.subs(v, 5.0).evalf(), dtype=float)
    queue.put({"derive_s": derive, "linearize_s": time.perf_counter() - began, "shape": list(A5.shape)})


def kane(budget: float) -> dict:
    queue: multiprocessing.Queue = multiprocessing.Queue()
    proc = multiprocessing.Process(target=_kane, args=(queue,))
    proc.start()
    proc.join(budget)
    if proc.is_alive():
        proc.terminate()
        return {"stopped_after_s": budget}
    return queue.get() if not queue.empty() else {"failed": proc.exitcode}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--budget", type=float, default=300.0, help="seconds given to KanesMethod.linearize")
    args = parser.parse_args()
    result = {"ours": ours(), "kane": kane(args.budget)}
    print(json.dumps(result, indent=2))
    o, k = result["ours"], result["kane"]
    print(f"linearize at 5 m/s: ours {o['derive_s']:.2f} s derive + {o['linearize_s']:.2f} s; "
          f"KanesMethod {k.get('derive_s', math.nan):.2f} s derive + "
          f"{k.get('linearize_s', k.get('stopped_after_s', math.nan)):.2f} s"
          f"{' (stopped)' if 'stopped_after_s' in k else ''}")
    print(f"101 speeds: {o['sweep_101_s']:.2f} s (each apart: {o['each_speed_apart_101_s']:.1f} s); weave "
          f"{o['weave_speed']:.15g} (off {o['weave_error']:.1e}), capsize {o['capsize_speed']:.15g} "
          f"(off {o['capsize_error']:.1e}); state matrix against the published one: {o['error_vs_published']:.1e}")


if __name__ == "__main__":
    main()
