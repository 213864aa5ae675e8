"""Impulses and impacts against impulse–momentum balances written out here.

Families: a free rod struck anywhere along it (linear and angular impulse–
momentum: Δv_G = P/m, I Δω = d × P), a double pendulum struck at its lower
bob (M(q) Δq̇ = Jᵀ P with M and J by hand), a rod falling onto the ground
at an angle (Newton's law of restitution with the effective mass
1/m_eff = 1/m + (d × n)²/I), and two masses colliding on a line (the 1-D
collision formulas).  Each also from symbols given the values (``params=``):
the same velocities after.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
import sympy as sp

import lagrangian as lg
from lagrangian.impulse import Impulse, between, ground, impact, velocity_jump

from . import Case, Mismatch, close, decades, same, uniform


def free_rod(m, length, offset) -> lg.Model:
    """A rod flying in the plane; coordinates: its centre (x_fly, y_fly) and angle theta_fly; point P at
    ``offset`` from the centre along the rod."""
    rod = lg.Model("free rod", dim=2)
    rod.add("rod", "rod", "rod", m=m, length=length, points={"P": (length / 2 + offset, 0)})
    rod.add("free", "fly", ("ground", "rod"), child_point=(length / 2, 0))
    return rod


@lru_cache(maxsize=None)
def rod_twin():
    m, L, f = sp.symbols("m L f", positive=True)
    return free_rod(m, L, (f - sp.Rational(1, 2)) * L)  # P at a fraction f of the rod from its start


def rod_state(v):
    vel = {"x_fly": v["vx"], "y_fly": v["vy"], "theta_fly": v["w"] / v["L"]}
    return {"theta_fly": v["phi"], "x_fly": 0.0, "y_fly": 0.0}, vel


def by_hand_rod(v):
    m, L, phi, s = v["m"], v["L"], v["phi"], (v["f"] - 0.5) * v["L"]
    return m, L, phi, s, m * L**2 / 12, np.array([s * math.cos(phi), s * math.sin(phi)])


def jump_rod(v):
    """Δv_G = P/m and (m L²/12) Δω = d × P, d from the centre to the struck point."""
    m, L, phi, s, I, d = by_hand_rod(v)
    P = np.array([v["Px"], v["Py"]])
    at, vel = rod_state(v)
    want = {"x_fly": vel["x_fly"] + P[0] / m, "y_fly": vel["y_fly"] + P[1] / m,
            "theta_fly": vel["theta_fly"] + (d[0] * P[1] - d[1] * P[0]) / I}
    scale = max(abs(x) for x in want.values()) + np.abs(P).max() / m + np.abs(P).max() * L / I
    results = []
    for who, model, params in (("numbers", free_rod(m, L, s), None),
                               ("symbolic twin", rod_twin(), {"m": m, "L": L, "f": v["f"]})):
        jump = velocity_jump(model, [Impulse("rod.P", (v["Px"], v["Py"]))], at=at, velocity=vel, params=params)
        for name, value in want.items():
            close(jump.after[name], value, f"{name}' after ({who})", rel=0, abs_=1e-11 * scale)
        T = 0.5 * m * (want["x_fly"] ** 2 + want["y_fly"] ** 2) + 0.5 * I * want["theta_fly"] ** 2
        close(jump.T_after, T, f"T after ({who})", rel=1e-10, abs_=1e-12 * (m * scale**2))
        results.append([float(jump.after[n]) for n in want])
    for a, b in zip(*results):
        close(a, b, "numbers against the symbolic twin", rel=0, abs_=1e-10 * scale)


def double_pendulum(m1, m2, l1, l2) -> lg.Model:
    model = lg.Model("double pendulum", dim=2)
    model.add("link", "a1", "a1", points={"bob": (l1, 0)})
    model.add("link", "a2", "a2", points={"bob": (l2, 0)})
    model.add("revolute", "j1", ("ground", "a1"), absolute=True)
    model.add("revolute", "j2", ("a1", "a2"), parent_point=(l1, 0), absolute=True)
    model.add("mass", "m1", "a1.bob", m=m1)
    model.add("mass", "m2", "a2.bob", m=m2)
    return model


@lru_cache(maxsize=None)
def pendulum_twin():
    return double_pendulum(*sp.symbols("m1 m2 l1 l2", positive=True))


def jump_pendulum(v):
    """Absolute angles, r₁ = l₁(cos θ₁, sin θ₁), r₂ = r₁ + l₂(cos θ₂, sin θ₂): M Δθ̇ = Jᵀ P with
    M = [[(m₁+m₂) l₁², m₂ l₁ l₂ cos(θ₁−θ₂)], [·, m₂ l₂²]] and J = ∂r₂/∂θ."""
    m1, m2, l1, l2, a, b = (v[k] for k in ("m1", "m2", "l1", "l2", "t1", "t2"))
    c = math.cos(a - b)
    M = np.array([[(m1 + m2) * l1**2, m2 * l1 * l2 * c], [m2 * l1 * l2 * c, m2 * l2**2]])
    J = np.array([[-l1 * math.sin(a), -l2 * math.sin(b)], [l1 * math.cos(a), l2 * math.cos(b)]])
    P = np.array([v["Px"], v["Py"]])
    before = np.array([v["w1"], v["w2"]])
    after = before + np.linalg.solve(M, J.T @ P)
    scale = float(np.abs(after).max() + np.abs(before).max())
    at = {"theta_j1": a, "theta_j2": b}
    vel = {"theta_j1": v["w1"], "theta_j2": v["w2"]}
    results = []
    for who, model, params in (("numbers", double_pendulum(m1, m2, l1, l2), None),
                               ("symbolic twin", pendulum_twin(), {"m1": m1, "m2": m2, "l1": l1, "l2": l2})):
        jump = velocity_jump(model, [Impulse("a2.bob", (v["Px"], v["Py"]))], at=at, velocity=vel, params=params)
        got = np.array([float(jump.after["theta_j1"]), float(jump.after["theta_j2"])])
        # M is ill-conditioned when the arms are nearly aligned: compare at the accuracy the solve allows
        tol = 1e-11 * np.linalg.cond(M) * scale
        for k in range(2):
            close(got[k], after[k], f"θ{k + 1}' after ({who})", rel=0, abs_=tol)
        results.append(got)
    if not np.allclose(results[0], results[1], rtol=0, atol=1e-10 * np.linalg.cond(M) * scale):
        raise Mismatch(f"numbers against the symbolic twin: {results[0]} vs {results[1]}")


def impact_rod(v):
    """The end at d from the centre hits the ground (n = (0, 1)) approaching at ġ < 0: Λ = −(1+e) m_eff ġ with
    1/m_eff = 1/m + d_x²/I, then Δv = Λ n/m, I Δω = d_x Λ; the normal velocity after is −e ġ."""
    m, L, phi, s, I, d = by_hand_rod(v)
    e = v["e"]
    at, vel = rod_state(v)
    gdot = vel["y_fly"] + d[0] * vel["theta_fly"]
    meff = 1 / (1 / m + d[0] ** 2 / I)
    lam = -(1 + e) * meff * gdot
    want = {"x_fly": vel["x_fly"], "y_fly": vel["y_fly"] + lam / m, "theta_fly": vel["theta_fly"] + d[0] * lam / I}
    scale = abs(gdot) + max(abs(x) for x in want.values()) * (1 + L)
    results = []
    for who, model, params in (("numbers", free_rod(m, L, s), None),
                               ("symbolic twin", rod_twin(), {"m": m, "L": L, "f": v["f"]})):
        hit = impact(model, [ground("rod.P", e=e)], at=at, velocity=vel, params=params)
        close(hit.impulses["ground(rod.P)"], lam, f"the impulse ({who})", rel=1e-9, abs_=1e-12 * meff * scale)
        close(hit.normal_after["ground(rod.P)"], -e * gdot, f"ġ after ({who})", rel=0, abs_=1e-10 * scale)
        for name, value in want.items():
            close(hit.after[name], value, f"{name}' after ({who})", rel=0, abs_=1e-10 * scale)
        results.append([float(hit.after[n]) for n in want])
    for a, b in zip(*results):
        close(a, b, "numbers against the symbolic twin", rel=0, abs_=1e-10 * scale)


def rod_approaches(v):
    m, L, phi, s, I, d = by_hand_rod(v)
    at, vel = rod_state(v)
    gdot = vel["y_fly"] + d[0] * vel["theta_fly"]
    return gdot < -1e-3 * (abs(vel["y_fly"]) + abs(d[0] * vel["theta_fly"]) + 1e-300)


def two_masses(m1, m2) -> lg.Model:
    model = lg.Model("two masses")
    model.add("mass", "m1", "a", m=m1)
    model.add("mass", "m2", "b", m=m2)
    return model


@lru_cache(maxsize=None)
def masses_twin():
    return two_masses(*sp.symbols("m1 m2", positive=True))


def impact_masses(v):
    """1-D: v₁' = (m₁v₁ + m₂v₂ − m₂e(v₁−v₂))/(m₁+m₂), v₂' = (m₁v₁ + m₂v₂ + m₁e(v₁−v₂))/(m₁+m₂)."""
    m1, m2, e, v1, v2, d = v["m1"], v["m2"], v["e"], v["v1"], v["v2"], v["d"]
    p = m1 * v1 + m2 * v2
    want = {"x_a": (p - m2 * e * (v1 - v2)) / (m1 + m2), "x_b": (p + m1 * e * (v1 - v2)) / (m1 + m2)}
    lost = 0.5 * m1 * m2 / (m1 + m2) * (1 - e**2) * (v1 - v2) ** 2
    scale = abs(v1) + abs(v2)
    at = {"x_a": 0.0, "x_b": d}
    for who, model, params in (("numbers", two_masses(m1, m2), None),
                               ("symbolic twin", masses_twin(), {"m1": m1, "m2": m2})):
        hit = impact(model, [between("a", "b", distance=d, e=e)], at=at, velocity={"x_a": v1, "x_b": v2}, params=params)
        for name, value in want.items():
            close(hit.after[name], value, f"{name}' after ({who})", rel=0, abs_=1e-12 * scale)
        close(hit.T_before - hit.T_after, lost, f"energy lost ({who})", rel=1e-9,
              abs_=1e-12 * (m1 + m2) * scale**2)
        same(sorted(hit.impulses), ["between(a, b)"], f"contacts ({who})")


ROD = {"m": decades(1e-2, 1e2), "L": decades(1e-2, 1e1), "f": uniform(0.0, 1.0), "phi": uniform(-1.5, 1.5),
       "vx": uniform(-3, 3), "vy": uniform(-3, 3), "w": uniform(-3, 3)}

CASES = [
    Case("velocity_jump", "free rod struck anywhere", {**ROD, "Px": uniform(-5, 5), "Py": uniform(-5, 5)}, jump_rod),
    Case("velocity_jump", "double pendulum struck at its bob",
         {"m1": decades(1e-2, 1e2), "m2": decades(1e-2, 1e2), "l1": decades(1e-2, 1e1), "l2": decades(1e-2, 1e1),
          "t1": uniform(-3, 3), "t2": uniform(-3, 3), "w1": uniform(-3, 3), "w2": uniform(-3, 3),
          "Px": uniform(-5, 5), "Py": uniform(-5, 5)}, jump_pendulum,
         admissible=lambda v: abs(math.sin(v["t1"] - v["t2"])) > 0.05),
    Case("impact", "rod onto the ground", {**ROD, "e": uniform(0.0, 1.0)}, impact_rod, admissible=rod_approaches),
    Case("impact", "two masses on a line", {"m1": decades(1e-3, 1e3), "m2": decades(1e-3, 1e3), "e": uniform(0.0, 1.0),
                                            "v1": uniform(-5, 5), "v2": uniform(-5, 5), "d": decades(1e-3, 1)},
         impact_masses, admissible=lambda v: v["v1"] - v["v2"] > 1e-2 * (abs(v["v1"]) + abs(v["v2"]))),
]
