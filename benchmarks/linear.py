"""Exact solution (matrix exponential) against numerical integration, on linear models.

Two models, each solved on 2,001 output points:

- the demo's driven mass–spring–damper (m=1, k=4, c=0.4, F=sin 1.5t, x(0)=0.1),
  0–20 s, against its closed form (``examples/demo.py``);
- a 5-section RLC ladder driven by E = sin 1.3t from rest, 0–30 s, against
  a reference written here without the library: Kirchhoff's laws for the
  loop charges by hand, solved by eigendecomposition plus the phasor
  particular solution.

For each: ``simulate_exact`` and ``Model.simulate`` (DOP853 at rtol 1e-6,
1e-9, 1e-12, atol = rtol·1e-3), wall time per call (best of 5, after a first
call that derives and compiles; the exact solver's matrix exponentials are
recomputed on every call) and max error.  The last line is a JSON object.
Run: ``.venv/bin/python benchmarks/linear.py``.
"""

from __future__ import annotations

import json
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import sympy as sp

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "examples"))
import demo  # noqa: E402

import lagrangian as lg  # noqa: E402
from lagrangian.linear import simulate_exact, state_space  # noqa: E402

RTOLS = (1e-6, 1e-9, 1e-12)
POINTS = 2001
REPEATS = 5
LADDER_W = 1.3


def ladder_values(sections: int = 5):
    rng = np.random.default_rng(2024)
    return [(float(rng.uniform(0.2, 1.0)), float(rng.uniform(0.5, 2.0)), float(rng.uniform(0.2, 1.0))) for _ in range(sections)]


def ladder() -> lg.Model:
    """E(in, 0) — [R_k (…, m_k) — L_k (m_k, n_k) — C_k (n_k, 0)] × 5."""
    model = lg.Model("rlc-ladder", formulation="charge")
    model.add("voltage_source", "V1", ("in", "0"), E=sp.sin(sp.Float(LADDER_W) * lg.t))
    prev = "in"
    for k, (R, L, C) in enumerate(ladder_values(), start=1):
        model.add("resistor", f"R{k}", (prev, f"m{k}"), R=R)
        model.add("inductor", f"L{k}", (f"m{k}", f"n{k}"), L=L)
        model.add("capacitor", f"C{k}", (f"n{k}", "0"), C=C)
        prev = f"n{k}"
    return model


def ladder_reference(T: np.ndarray) -> np.ndarray:
    """Loop charges q_k (through L_k) of the ladder from rest, by hand.

    KVL round loop k, with capacitor voltages v_k = (q_k − q_{k+1}) / C_k (q_6 = 0) and v_0 = E:
        L_k q̈_k + R_k q̇_k + v_k − v_{k−1} = 0.
    As M q̈ + B q̇ + K q = e_1 E(t); first-order form ẏ = P y + b E, y = (q, q̇).  For E = Im e^{iωt}:
    y = Im(Y e^{iωt}) + V e^{Λt} V⁻¹ (y(0) − Im Y), with (iω − P) Y = b.
    """
    vals = ladder_values()
    n = len(vals)
    R = np.array([v[0] for v in vals])
    L = np.array([v[1] for v in vals])
    C = np.array([v[2] for v in vals])
    K = np.zeros((n, n))
    for k in range(n):  # v_k − v_{k−1} in terms of charges
        K[k, k] += 1 / C[k]
        if k + 1 < n:
            K[k, k + 1] -= 1 / C[k]
        if k > 0:
            K[k, k] += 1 / C[k - 1]
            K[k, k - 1] -= 1 / C[k - 1]
    P = np.block([[np.zeros((n, n)), np.eye(n)], [-K / L[:, None], -np.diag(R / L)]])
    b = np.zeros(2 * n)
    b[n] = 1 / L[0]
    Y = np.linalg.solve(1j * LADDER_W * np.eye(2 * n) - P, b)
    lam, V = np.linalg.eig(P)
    c = np.linalg.solve(V, -Y.imag)
    y = (Y[:, None] * np.exp(1j * LADDER_W * T)).imag + (V @ (c[:, None] * np.exp(lam[:, None] * T))).real
    return y[:n]


def timed(fn):
    best, out = np.inf, None
    for _ in range(REPEATS):
        start = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - start)
    return best, out


def measure(name, model, coords, initial, velocity, t_end, reference):
    rows = []
    start = time.perf_counter()
    state_space(model)
    derive = time.perf_counter() - start
    start = time.perf_counter()
    model.numeric()
    compile_ = time.perf_counter() - start
    ss = state_space(model)

    def exact():
        ss._propagators.clear()  # count the matrix exponentials in every call
        return simulate_exact(model, t_end, initial=initial, velocity=velocity, points=POINTS)

    exact()
    wall, res = timed(exact)
    err = max(float(np.max(np.abs(res[c] - r))) for c, r in zip(coords, reference(res.t)))
    rows.append((name, "exact (expm)", "-", wall, err))
    for rtol in RTOLS:
        run = lambda rtol=rtol: model.simulate(  # noqa: E731
            t_end, initial=initial, velocity=velocity, points=POINTS, method="DOP853", rtol=rtol, atol=rtol * 1e-3
        )
        run()
        wall, res = timed(run)
        err = max(float(np.max(np.abs(res[c] - r))) for c, r in zip(coords, reference(res.t)))
        rows.append((name, "DOP853", f"{rtol:.0e}", wall, err))
    return rows, {"derive_s": derive, "numeric_s": compile_}


def main() -> None:
    warnings.simplefilter("ignore", lg.InitialConditionWarning)
    rows, setup = [], {}
    mech = demo.mechanism()
    r, s = measure("mass-spring-damper", mech, ["x_cart"], {"x_cart": demo.X0}, {"x_cart": 0.0}, 20.0,
                   lambda T: [demo.closed_form(T)])
    rows += r
    setup["mass-spring-damper"] = s
    lad = ladder()
    names = lad.coordinate_names
    assert names == [f"q_L{k}" for k in range(1, 6)], names
    zero = dict.fromkeys(names, 0.0)
    r, s = measure("rlc-ladder-5", lad, names, zero, zero, 30.0, ladder_reference)
    rows += r
    setup["rlc-ladder-5"] = s

    print(f"{POINTS} output points; wall time per call, best of {REPEATS}; error = max |result − reference|")
    print(f"{'model':20} {'method':14} {'rtol':>6} {'wall ms':>9} {'max error':>10}")
    for name, method, rtol, wall, err in rows:
        print(f"{name:20} {method:14} {rtol:>6} {wall * 1e3:9.2f} {err:10.2e}")
    for name, s in setup.items():
        print(f"{name}: state-space derivation {s['derive_s'] * 1e3:.0f} ms, numeric code {s['numeric_s'] * 1e3:.0f} ms (once per model)")
    summary = {
        name: {
            (m if m != "DOP853" else f"DOP853@{rt}"): {"wall_ms": round(w * 1e3, 3), "max_error": float(f"{e:.3e}")}
            for n, m, rt, w, e in rows
            if n == name
        }
        for name in setup
    }
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
