"""Fitting models to measurements: accuracy, identifiability and speed of ``lagrangian.fit``.

- Thiele–Small parameters (Re, Le, Bl, Mms, Cms = 1/k, Rms) of a loudspeaker from two synthetic impedance
  curves (free air, and with 10 g added to the cone) with 0.5 % complex noise: the worst relative error against
  the true values, and whether each true value lies in its reported 3σ interval.
- The free-air curve alone: whether the fit reports that Bl, Mms, Cms and Rms are not determined separately.
- A damped double pendulum (point masses 0.3 and 0.2 kg, joint dampers): the second mass and both dampers from
  a 10 s record of both angles (from 0.4 and −0.3 rad) with 0.5 % noise, from a start 20–25 % off; the worst relative error and the 3σ
  check.
- Speed: the same pendulum fit with ``scipy.optimize.least_squares`` and its default finite differences over
  ``Model.simulate`` (same residuals, start, tolerances and windows of the record), against ``lagrangian.fit``
  with its exact Jacobian from the forward sensitivities: wall time, both warm, interleaved, best of 3 (the first
  fit, which also builds the model's sensitivity tape, is reported as ``pendulum_fit_cold_s``).
- ``simulate_overhead_ms``: the median wall time of a warm double pendulum's ``simulate(1e-6, points=2)``.

Prints a table and, as its last line, a JSON object.

Run: .venv/bin/python benchmarks/fit.py
"""

from __future__ import annotations

import json
import time
import warnings

import numpy as np

import lagrangian as lg
from lagrangian import models

TRUTH = dict(R_Re=6.0, L_Le=0.5e-3, Bl_coil=7.0, m_m=0.02, k_k=2000.0, c_c=1.5)
F = np.geomspace(5, 5000, 200)


def impedance(f, added=0.0, p=TRUTH):
    w = 2 * np.pi * f
    return p["R_Re"] + 1j * w * p["L_Le"] + p["Bl_coil"] ** 2 / (p["c_c"] + 1j * w * (p["m_m"] + added) + p["k_k"] / (1j * w))


def noisy(z, rng):
    return z * (1 + 0.005 * (rng.normal(size=z.size) + 1j * rng.normal(size=z.size)) / np.sqrt(2))


def speaker(added=0.0):
    model = models.loudspeaker(Re=5.0, Le=0.8e-3, Bl=5.0, m=0.03, k=1500.0, c=1.0)
    if added:
        model.add("mass", "added", "cone", m=added)
    return model


def thiele_small() -> dict:
    rng = np.random.default_rng(11)
    curves = [lg.FrequencyData(F, noisy(impedance(F), rng), input="E", output="i(Le)", impedance=True, name="free air"),
              lg.FrequencyData(F, noisy(impedance(F, 0.01), rng), input="E", output="i(Le)", impedance=True,
                               model=speaker(0.01), name="+10 g")]
    began = time.perf_counter()
    both = lg.fit(speaker(), curves, list(TRUTH))
    seconds = time.perf_counter() - began
    bounds = both.interval(3.0)
    alone = lg.fit(speaker(), curves[0], list(TRUTH))
    flagged = any({"Bl_coil", "m_m", "k_k", "c_c"} <= {w.strip(",") for w in s.split()} for s in alone.undetermined)
    return {"ts_from_impedance_rel_error": max(abs(both.values[n] / t - 1) for n, t in TRUTH.items()),
            "ts_within_3_sigma": all(bounds[n][0] <= t <= bounds[n][1] for n, t in TRUTH.items()),
            "ts_fit_s": seconds, "ts_identifiability_flagged": flagged,
            "ts_undetermined": alone.undetermined}


PENDULUM = {"m_m2": 0.2, "c_d1": 0.02, "c_d2": 0.01}
START = {"theta_j1": 0.4, "theta_j2": -0.3}
STILL = {"theta_j1": 0.0, "theta_j2": 0.0}


def pendulum(m2=0.2, c1=0.02, c2=0.01) -> lg.Model:
    model = models.double_pendulum(0.3, m2)
    model.add("rotational_damper", "d1", ("ground", "l1"), c=c1)
    model.add("rotational_damper", "d2", ("l1", "l2"), c=c2)
    return model


def record(rng) -> lg.TimeSeries:
    t = np.linspace(0.0, 10.0, 501)
    run = pendulum().simulate((0.0, 10.0), t_eval=t, initial=START, velocity=STILL, rtol=1e-12, atol=1e-14)
    outputs = {n: run[n] + 0.005 * np.max(np.abs(run[n])) * rng.normal(size=t.size) for n in ("theta_j1", "theta_j2")}
    return lg.TimeSeries(t, outputs, initial=START, velocity=STILL)


def pendulum_fit() -> dict:
    data = record(np.random.default_rng(5))
    start = pendulum(0.24, 0.025, 0.008)  # 20 %, 25 %, −20 % off
    names = list(PENDULUM)
    began = time.perf_counter()
    ours = lg.fit(start, data, names, rtol=1e-9, atol=1e-11)
    cold_s = time.perf_counter() - began  # (with building the sensitivity tape, once per model)
    bounds = ours.interval(3.0)

    from scipy.optimize import least_squares

    from lagrangian.analysis.fitting import WINDOW_FTOL

    scale = {n: 1 / np.max(np.abs(v)) for n, v in data.outputs.items()}

    def residuals(z, keep):
        t = data.t[:keep]
        run = start.simulate((0.0, float(t[-1])), t_eval=t, initial=START, velocity=STILL, rtol=1e-9, atol=1e-11,
                             params=dict(zip(names, np.exp(z))))
        return np.concatenate([(run[n] - v[:keep]) * scale[n] for n, v in data.outputs.items()])

    def finite_differences():
        # lg.fit's own scheme with SciPy's default Jacobian: the same windows (1/8, 1/4, 1/2, all of the record,
        # without which neither finds the answer) and tolerances (WINDOW_FTOL over the shorter windows)
        z = np.log([start.parameter_values[n] for n in names])
        for share in (0.125, 0.25, 0.5, 1.0):
            keep = int(np.searchsorted(data.t, share * data.t[-1], side="right"))
            z = least_squares(residuals, z, args=(keep,), x_scale="jac", ftol=1e-12 if share == 1.0 else WINDOW_FTOL,
                              xtol=1e-12, gtol=1e-12, max_nfev=200).x
        return z

    ours_s, theirs_s = [], []
    for _ in range(3):  # warm, interleaved, best of 3
        began = time.perf_counter()
        lg.fit(start, data, names, rtol=1e-9, atol=1e-11)
        ours_s.append(time.perf_counter() - began)
        began = time.perf_counter()
        z = finite_differences()
        theirs_s.append(time.perf_counter() - began)
    return {"pendulum_fit_rel_error": max(abs(ours.values[n] / t - 1) for n, t in PENDULUM.items()),
            "pendulum_within_3_sigma": all(bounds[n][0] <= t <= bounds[n][1] for n, t in PENDULUM.items()),
            "pendulum_fit_s": min(ours_s), "pendulum_fit_cold_s": cold_s, "pendulum_fit_nfev": ours.nfev,
            "finite_differences_s": min(theirs_s),
            "finite_differences_rel_error": max(abs(np.exp(z[i]) / PENDULUM[n] - 1) for i, n in enumerate(names)),
            "fit_speedup_vs_finite_differences": min(theirs_s) / min(ours_s)}


def overhead() -> dict:
    model = models.double_pendulum()
    run = dict(initial={"theta_j1": 0.3, "theta_j2": -0.2}, velocity=STILL, points=2)
    model.simulate(1e-6, **run)
    times = []
    for _ in range(500):
        began = time.perf_counter()
        model.simulate(1e-6, **run)
        times.append(time.perf_counter() - began)
    return {"simulate_overhead_ms": 1e3 * float(np.median(times)), "simulate_overhead_min_ms": 1e3 * min(times)}


def main() -> None:
    warnings.simplefilter("ignore", lg.InitialConditionWarning)
    figures = {**thiele_small(), **pendulum_fit(), **overhead()}
    print(f"{'figure':36} value")
    for key, value in figures.items():
        print(f"{key:36} {value}")
    print(json.dumps(figures, default=float))


if __name__ == "__main__":
    main()
