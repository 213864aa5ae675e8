"""Scenes against closed forms and against the full model.

Families: two oscillators on one shaker with only one asked for (the other
is pruned; the kept one is a forced oscillator with a closed-form motion),
and a spherical pendulum asked for its tilt and energy from a full-model
state (the turn angle is eliminated through the Routhian; the reference is
the full model simulated at a tight tolerance, and T + V of the start).
Each is also built from symbols and given the values in ``params=``: the
same plan and the same outputs.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
import sympy as sp

import lagrangian as lg
from lagrangian import models
from lagrangian.scene import Scene

from . import Case, Mismatch, decades, same, uniform


def shaker(m1, k1, m2, k2, A, W) -> lg.Model:
    model = lg.Model("two oscillators on one shaker")
    model.add("prescribed_motion", "shaker", "s", position=A * sp.sin(W * lg.t))
    model.add("mass", "m1", "p1", m=m1)
    model.add("spring", "k1", ("s", "p1"), k=k1)
    model.add("mass", "m2", "p2", m=m2)
    model.add("spring", "k2", ("s", "p2"), k=k2)
    return model


@lru_cache(maxsize=None)
def shaker_twin():
    return shaker(*sp.symbols("m1 k1 m2 k2 A W", positive=True))


def scene_shaker(v):
    """m ẍ = −k (x − A sin Ωt): x = x₀ cos ωt + (v₀ − ω² A Ω/(ω² − Ω²))/ω sin ωt + ω² A/(ω² − Ω²) sin Ωt."""
    m1, k1, m2, k2 = v["m1"], v["k1"], v["m2"], v["k2"]
    w = math.sqrt(k1 / m1)
    W = v["r"] * w
    A = v["A"]
    x0, v0 = v["x0"] * A, v["v0"] * A * w
    t_end = 3 * 2 * math.pi / w
    state = dict(initial={"x_p1": x0, "x_p2": 0.3 * A}, velocity={"x_p1": v0, "x_p2": 0.0})
    gain = w**2 * A / (w**2 - W**2)
    scale = abs(x0) + abs(v0) / w + abs(gain) * (1 + W / w)
    results = []
    for who, model, params in (("numbers", shaker(m1, k1, m2, k2, A, W), {}),
                               ("symbolic twin", shaker_twin(), {"m1": m1, "k1": k1, "m2": m2, "k2": k2, "A": A, "W": W})):
        scene = Scene(model, ["x_p1"], t_end, tol=1e-10, params=params, points=201, offer=False, **state)
        same([p.coordinates for p in scene.plan.parts], [["x_p1"]], f"the kept part ({who})")
        if "m2" not in scene.plan.dropped:
            raise Mismatch(f"m2 acts only on x_p2, yet it is not dropped ({who}): {scene.plan.dropped}")
        res = scene.run()
        tt = np.asarray(res.t, dtype=float)
        want = x0 * np.cos(w * tt) + (v0 - gain * W) / w * np.sin(w * tt) + gain * np.sin(W * tt)
        err = float(np.max(np.abs(np.asarray(res["x_p1"], dtype=float) - want)))
        if not err <= 1e-7 * scale:
            raise Mismatch(f"x_p1 against the closed form ({who}): max error {err:.3g}, scale {scale:.3g}")
        results.append(np.asarray(res["x_p1"], dtype=float))
    err = float(np.max(np.abs(results[0] - results[1])))
    if not err <= 1e-9 * scale:
        raise Mismatch(f"numbers against the symbolic twin: max difference {err:.3g}, scale {scale:.3g}")


@lru_cache(maxsize=None)
def spherical_twin():
    return models.spherical_pendulum(*sp.symbols("m length g", positive=True))


def scene_spherical(v):
    """Asked θ and E from a full state: φ is eliminated (its momentum from φ̇), E stays at its start value
    ½ m l² (θ̇₀² + φ̇₀² sin²θ₀) − m g l cos θ₀, and θ(t) is the full model's; left to weigh the reduction
    (``reduce="auto"``), the model given numbers decides as its symbolic twin does."""
    m, length, g = v["m"], v["length"], v["g"]
    rate = math.sqrt(g / length)
    t_end = 4 * 2 * math.pi / rate
    state = dict(initial={"theta_turn": v["phi0"], "theta_tilt": v["theta0"]},
                 velocity={"theta_turn": v["dphi"] * rate, "theta_tilt": v["dtheta"] * rate})
    E0 = 0.5 * m * length**2 * ((v["dtheta"] * rate) ** 2 + (v["dphi"] * rate * math.sin(v["theta0"])) ** 2) \
        - m * g * length * math.cos(v["theta0"])
    scale = m * g * length * (1 + v["dtheta"] ** 2 + v["dphi"] ** 2)
    full = models.spherical_pendulum(m, length, g).simulate(t_end, method="DOP853", rtol=1e-12, atol=1e-14,
                                                            t_eval=np.linspace(0, t_end, 101), **state)
    results, verdicts = [], []
    for who, model, params in (("numbers", models.spherical_pendulum(m, length, g), {}),
                               ("symbolic twin", spherical_twin(), {"m": m, "length": length, "g": g})):
        scene = Scene(model, ["theta_tilt", "E"], t_end, tol=1e-10, params=params, points=101, offer=False,
                      reduce=True, **state)
        same([(p.integrated, p.eliminated) for p in scene.plan.parts], [(["theta_tilt"], ["theta_turn"])],
             f"the integrated and eliminated coordinates ({who})")
        weighed = Scene(model, ["theta_tilt", "E"], t_end, tol=1e-10, params=params, points=101, offer=False, **state)
        verdicts.append([(p.integrated, p.eliminated) for p in weighed.plan.parts])
        res = scene.run()
        theta = np.asarray(res["theta_tilt"], dtype=float)
        err = float(np.max(np.abs(theta - np.asarray(full["theta_tilt"], dtype=float))))
        if not err <= 1e-6:
            raise Mismatch(f"θ against the full model ({who}): max error {err:.3g} rad")
        E = np.asarray(res["E"], dtype=float)
        drift = float(np.max(np.abs(E - E0)))
        if not drift <= 1e-7 * scale:  # a tolerance of 1e-10 per step, over some 10^3 steps
            raise Mismatch(f"E against T + V at the start ({who}): max difference {drift:.3g}, scale {scale:.3g}")
        results.append(theta)
    err = float(np.max(np.abs(results[0] - results[1])))
    if not err <= 1e-8:
        raise Mismatch(f"θ, numbers against the symbolic twin: max difference {err:.3g} rad")
    same(verdicts[0], verdicts[1], "reduce='auto': whether to eliminate φ, numbers against the symbolic twin")


CASES = [
    Case("Scene", "oscillators on a shaker", {"m1": decades(1e-3, 1e2), "k1": decades(1e-1, 1e5), "m2": decades(1e-3, 1e2),
                                              "k2": decades(1e-1, 1e5), "A": decades(1e-4, 1), "r": decades(0.1, 10),
                                              "x0": uniform(-2, 2), "v0": uniform(-2, 2)}, scene_shaker,
         admissible=lambda v: abs(v["r"] - 1) > 0.05),
    Case("Scene", "spherical pendulum", {"m": decades(1e-2, 1e2), "length": decades(1e-2, 1e2), "g": decades(0.1, 100),
                                         "phi0": uniform(-3, 3), "theta0": uniform(0.2, 2.9), "dphi": uniform(0.1, 2),
                                         "dtheta": uniform(-1, 1)}, scene_spherical),
]
