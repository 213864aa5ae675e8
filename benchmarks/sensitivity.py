"""Forward sensitivities against central differences: the double pendulum for 10 s.

Model: ``lagrangian.models.double_pendulum(0.3, 0.2)`` from ``θ1 = −1``, ``θ2 = −0.3``, ``θ̇2 = 0.4``, output on
1001 times, ``rtol`` 1e-9 (the default) and 1e-11.  Timed, in this process after a warm-up of 30 runs (the
derivation, the tapes, the compiled code, all cached from then on, and the first runs' extra time gone), median
of ``--repeat`` rounds, the variants interleaved, each run at parameter values of its own (as a fit's iterations
are: nothing of a previous run's values is reused):

- **sensitivities**: one ``simulate(..., sensitivities=["m_m1", "m_m2", "g_g"])`` — the state and three
  sensitivities (16 variables) by DOP853's loop in C on the augmented right-hand side in C;
- **plain ×1, ×4, ×6**: that many plain ``simulate`` runs (DOP853 in C) — four is a run and one per parameter
  (forward differences), six what central differences of three parameters need (two runs each);
- **seen values**: a sensitivity run and a plain run at the model's own values, run before: what is left when
  nothing is rebuilt for new values (per new set of values a run builds the model's numeric functions again and
  loads its compiled code, some milliseconds that dominate runs this short);
- for information, **sensitivities, NumPy**: the same with ``compiled=False`` (SciPy's DOP853 stepping the augmented
  system in NumPy, the fallback without a C compiler).

Also printed: the largest difference between the sensitivities and the central differences of six plain runs
(steps of 1e-5 relative), relative to the largest sensitivity.  Nothing is asserted.

Run: ``.venv/bin/python benchmarks/sensitivity.py [--repeat 5]``.  The last line is a JSON object.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

import numpy as np

import lagrangian as lg  # noqa: F401 - plugins registered
from lagrangian import models

NAMES = ["m_m1", "m_m2", "g_g"]
START = dict(initial={"theta_j1": -1.0, "theta_j2": -0.3}, velocity={"theta_j1": 0.0, "theta_j2": 0.4}, points=1001)
T_END = 10.0


def timed(call) -> float:
    start = time.perf_counter()
    call()
    return time.perf_counter() - start


def measure(model, rtol: float, repeat: int) -> dict:
    base = model.parameter_values
    values = lambda k: {n: base[n] * (1 + 1e-7 * (k + 1)) for n in NAMES}  # noqa: E731 - fresh values per run
    # warm-up: the derivation, tapes and libraries, then runs at fresh values until a plain run's time has settled
    # (the first dozen in a process take 3-4 times longer: caches of SymPy and the allocator filling)
    k = 1000
    for k in range(1000, 1030):
        model.simulate(T_END, **START, rtol=rtol, params=values(k), sensitivities=NAMES if k % 3 == 0 else ())
    rows: dict[str, list[float]] = {"sensitivities": [], "plain x1": [], "plain x4": [], "plain x6": [],
                                    "sensitivities, seen values": [], "plain x1, seen values": []}
    for _ in range(repeat):
        k += 1
        rows["sensitivities"].append(timed(lambda: model.simulate(T_END, **START, rtol=rtol, params=values(k),
                                                                  sensitivities=NAMES)))
        for count in (1, 4, 6):
            def plain(count=count):
                nonlocal k
                for _ in range(count):
                    k += 1
                    model.simulate(T_END, **START, rtol=rtol, params=values(k))
            rows[f"plain x{count}"].append(timed(plain))
        rows["sensitivities, seen values"].append(timed(lambda: model.simulate(T_END, **START, rtol=rtol,
                                                                               sensitivities=NAMES)))
        rows["plain x1, seen values"].append(timed(lambda: model.simulate(T_END, **START, rtol=rtol)))
    k += 1
    rows["sensitivities, NumPy"] = [timed(lambda: model.simulate(T_END, **START, rtol=rtol, params=values(k),
                                                                sensitivities=NAMES, compiled=False))]
    res = model.simulate(T_END, **START, rtol=rtol, sensitivities=NAMES)
    worst = 0.0
    for name in NAMES:
        h = 1e-5 * base[name]
        up = model.simulate(T_END, **START, rtol=rtol, params={name: base[name] + h})
        down = model.simulate(T_END, **START, rtol=rtol, params={name: base[name] - h})
        for c in model.coordinate_names:
            s = res.sensitivity(c, name)
            worst = max(worst, float(np.max(np.abs(s - (up[c] - down[c]) / (2 * h))) / np.max(np.abs(s))))
    return {"seconds": {key: statistics.median(v) for key, v in rows.items()}, "nfev": res.nfev,
            "central_vs_sensitivity": worst, "notes": res.notes}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    model = models.double_pendulum(0.3, 0.2)
    out = {}
    for rtol in (1e-9, 1e-11):
        out[rtol] = measure(model, rtol, args.repeat)
    print(f"double pendulum, {T_END:g} s, {START['points']} outputs, sensitivities to {', '.join(NAMES)}; median of "
          f"{args.repeat} runs (ms)")
    keys = list(out[1e-9]["seconds"])
    print(f"{'':24s}" + "".join(f"{f'rtol {r:g}':>14s}" for r in out))
    for key in keys:
        print(f"{key:24s}" + "".join(f"{1e3 * out[r]['seconds'][key]:14.2f}" for r in out))
    print(f"{'sens / plain x4':24s}" + "".join(
        f"{out[r]['seconds']['sensitivities'] / out[r]['seconds']['plain x4']:14.2f}" for r in out))
    print(f"{'evaluations (sens)':24s}" + "".join(f"{out[r]['nfev']:14d}" for r in out))
    print(f"{'|sens − central| / max':24s}" + "".join(f"{out[r]['central_vs_sensitivity']:14.1e}" for r in out))
    print(f"notes: {out[1e-9]['notes'][-1]}")
    r = out[1e-9]["seconds"]
    print(json.dumps({"sens_s": round(r["sensitivities"], 5), "plain_s": round(r["plain x1"], 5),
                      "plain4_s": round(r["plain x4"], 5), "plain6_s": round(r["plain x6"], 5),
                      "sens_numpy_s": round(r["sensitivities, NumPy"], 4),
                      "sens_over_plain4": round(r["sensitivities"] / r["plain x4"], 3),
                      "sens_seen_s": round(r["sensitivities, seen values"], 5),
                      "plain_seen_s": round(r["plain x1, seen values"], 5),
                      "sens_s_rtol1e-11": round(out[1e-11]["seconds"]["sensitivities"], 5),
                      "plain4_s_rtol1e-11": round(out[1e-11]["seconds"]["plain x4"], 5),
                      "central_vs_sensitivity": float(f"{out[1e-9]['central_vs_sensitivity']:.2e}")}))


if __name__ == "__main__":
    main()
