"""Real sizes: large chains and ladders, each run in a fresh process, against ngspice where it has a peer.

- ``chain10k``: a chain of 10,000 masses, springs and dampers (30,001 components) driven by a harmonic force
  at its end, built, assembled and solved over 1 s (101 points) with ``method="auto"``: CPU time and peak
  memory of the whole process, import included; ``chain10k_default``: the same run with the default method.
- ``fput10k``: a Fermi–Pasta–Ulam–Tsingou β chain of 10,000 unit masses between two fixed walls (springs of force
  100·d + 10⁶·d³, nonlinear: no exact solution to fall back on) from the shape of its linear mode n/10, where
  the cubic force is about twice the linear one, default settings, 1 s: CPU, peak memory and the drift of its energy.
- ``spatial``: three rigid bodies on spherical joints (``benchmarks/spatial.py``): the size of our equations against
  KanesMethod's, and a warm 5 s run against PyDy's Cython code (``null`` without the ``bench`` extra).
- ``ladder2000``: an RLC ladder of 2,000 sections (sine source, 30 s, 3,001 points), likewise.
- ``second run``: a 6-link pendulum run for 10 s in a second process (its compiled code in the cache), against a
  process that imports ``numpy`` and ``scipy.integrate``: the least CPU time of three processes each.
- ``ladder200`` against ngspice: the same ladder at 200 sections (the first capacitor's voltage compared), our process against one running the same
  circuit through PySpice at ngspice's default settings (no lagrangian imported).  ngspice's error is
  measured against ours (exact up to rounding: its agreement with the symbolic path and with closed forms is
  tested in ``tests/test_stamps.py``).

The package is byte-compiled first, as an installed one is (:func:`bytecode`).  Prints a table and, as its last
line, a JSON object with the fields of the real-sizes issue that this run
measures (``null`` for those it does not).  Run: ``.venv/bin/python benchmarks/scale.py`` (``--large``: the two
default-method chains alone).
"""

from __future__ import annotations

import json
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve()


def ladder_values(sections: int):
    rng = np.random.default_rng(1)
    return [(float(f"{rng.uniform(0.2, 1.0):.3g}"), float(f"{rng.uniform(0.5, 2.0):.3g}"),
             float(f"{rng.uniform(0.2, 1.0):.3g}")) for _ in range(sections)]


def chain_model(n: int):
    """A chain of ``n`` masses, springs and dampers driven by a harmonic force at its end, and its last node
    (lagrangian is imported here: a child process's import is part of what it measures)."""
    import sympy as sp

    import lagrangian as lg
    from lagrangian import models

    m = models.spring_chain(n, m=[0.3 + 0.01 * (i % 7) for i in range(n)], k=[40.0 + i % 5 for i in range(n)], c=0.02,
                            force=0.5 * sp.sin(3 * lg.t))
    return m, f"p{n - 1}"


def child_chain(n: int, method: str | None = "auto") -> dict:
    import warnings

    m, last = chain_model(n)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = m.simulate(1.0, initial={"x_p0": 0.01}, points=101, **({"method": method} if method else {}))
    return {"method": res.method, "notes": res.notes[:2], "x_end": float(res[f"x_{last}"][-1])}


def child_chain_default(n: int) -> dict:
    """The chain of :func:`child_chain`, run with every option at its default (no ``method``)."""
    return child_chain(n, method=None)


def child_fput(n: int) -> dict:
    """A Fermi–Pasta–Ulam–Tsingou β chain: ``n`` masses between two walls joined by springs of force k·d + β·d³,
    from the shape of its linear mode ``n/10`` (where the cubic force of a stretched spring is about twice the
    linear one: strongly nonlinear), default settings, 1 s; the drift of its energy (it has no damping)."""
    import warnings

    from lagrangian import models

    m = models.spring_chain(n, m=1.0, k=100.0, beta=1e6)
    m.add("spring", f"k{n}", (f"p{n - 1}", "ground"), k=100.0, beta=1e6)  # the far wall: fixed, as the near one
    mode = max(n // 10, 1)
    start = {f"x_p{i}": 0.05 * np.sin(np.pi * mode * (i + 1) / (n + 1)) for i in range(n)}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = m.simulate(1.0, initial=start, velocity={f"x_p{i}": 0.0 for i in range(n)}, points=101)
    E = res.T + res.V
    return {"method": res.method, "notes": res.notes[:2], "energy_drift": float(np.max(np.abs(E - E[0])) / abs(E[0]))}


def child_ladder(n: int) -> dict:
    import warnings

    import sympy as sp

    import lagrangian as lg

    c = lg.Model("ladder", formulation="charge")
    c.add("voltage_source", "V1", ("in", "0"), E=sp.sin(sp.Float(1.3) * lg.t))
    prev = "in"
    for k, (R, L, C) in enumerate(ladder_values(n)):
        c.add("resistor", f"R{k}", (prev, f"m{k}"), R=R)
        c.add("inductor", f"L{k}", (f"m{k}", f"n{k}"), L=L)
        c.add("capacitor", f"C{k}", (f"n{k}", "0"), C=C)
        prev = f"n{k}"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = c.simulate(30.0, method="auto", points=3001)
    # the first capacitor's voltage: its charge is the difference of the loop charges on either side
    v_out = (res["q_L0"] - res["q_L1"]) / ladder_values(n)[0][2]
    np.save(f"/tmp/lagrangian-scale-ours-{n}.npy", np.vstack([res.t, v_out]))
    return {"method": res.method, "notes": res.notes[:2]}


def child_ngspice(n: int) -> dict:
    from PySpice.Spice.Netlist import Circuit
    from PySpice.Unit import u_s

    circuit = Circuit("ladder")
    circuit.SinusoidalVoltageSource("1", "in", circuit.gnd, amplitude=1, frequency=1.3 / (2 * np.pi))
    prev = "in"
    for k, (R, L, C) in enumerate(ladder_values(n)):
        circuit.R(f"{k}", prev, f"m{k}", R)
        circuit.L(f"{k}", f"m{k}", f"n{k}", L)
        circuit.C(f"{k}", f"n{k}", circuit.gnd, C)
        prev = f"n{k}"
    sim = circuit.simulator()
    analysis = sim.transient(step_time=0.01 @ u_s, end_time=30 @ u_s, use_initial_condition=True)
    np.save(f"/tmp/lagrangian-scale-ngspice-{n}.npy", np.vstack([np.array(analysis.time), np.array(analysis["n0"])]))
    return {"points": len(analysis.time)}


def child_pendulum(n: int) -> dict:
    """A 6-link pendulum run for 10 s (default method, compiled code from the cache when there), as a second process
    of a user would."""
    import lagrangian as lg

    sys.path.insert(0, str(HERE.parent))
    from rhs import ours_model

    res = ours_model(n).simulate(10.0, initial={f"theta_j{k}": -1.2 + 0.4 * (-1) ** k for k in range(n)},
                                 velocity={f"theta_j{k}": 0.0 for k in range(n)}, points=101, energy_tol=False)
    return {"method": res.method, "notes": res.notes[:1], "nfev": res.nfev, "lagrangian": lg.__name__}


def child_numpy(n: int) -> dict:
    import numpy  # noqa: F401
    import scipy.integrate  # noqa: F401

    return {}


def child_spatial(n: int) -> dict:
    """``n`` bodies on spherical joints against KanesMethod and PyDy (benchmarks/spatial.py)."""
    sys.path.insert(0, str(HERE.parent))
    import spatial

    out = spatial.ops(n)
    try:
        out.update(spatial.speed(n))
    except ImportError as exc:  # PyDy and Cython are the bench extra: pip install -e ".[bench]"
        out.update(speed_ratio=None, reason=str(exc))
    return out


def bytecode() -> None:
    """Byte-compile the package (``core/``, ``plugins/``) as pip does when it installs one, so that each fresh
    process reads it compiled, as a user's second process does.  (Without it, where ``PYTHONDONTWRITEBYTECODE`` is
    set, every process would compile the package's sources again: some 0.4 s of CPU.)"""
    import compileall

    for folder in ("core", "plugins"):
        compileall.compile_dir(str(HERE.parent.parent / folder), quiet=1)


def run_child(kind: str, n: int) -> dict:
    """Run one case in a fresh process: its CPU time (user + system, children included) and peak memory."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    wall = time.perf_counter()
    out = subprocess.run([sys.executable, str(HERE), "--child", kind, str(n)], capture_output=True, text=True)
    wall = time.perf_counter() - wall
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if out.returncode:
        raise SystemExit(f"{kind} {n} failed:\n{out.stderr[-3000:]}")
    info = json.loads(out.stdout.strip().splitlines()[-1])
    info["cpu_s"] = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    info["wall_s"] = wall
    return info


def main() -> None:
    if len(sys.argv) > 1 and sys.argv[1] == "--child":
        kind, n = sys.argv[2], int(sys.argv[3])
        info = {"chain": child_chain, "chain_default": child_chain_default, "fput": child_fput, "ladder": child_ladder,
                "ngspice": child_ngspice, "pendulum": child_pendulum, "numpy": child_numpy,
                "spatial": child_spatial}[kind](n)
        info["rss_gb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6
        print(json.dumps(info))
        return
    bytecode()
    rows = []
    large = {}
    for kind, label in (("chain_default", "chain of 10,000 masses, default method"),
                        ("fput", "FPUT β chain of 10,000 masses, default")):
        large[kind] = run_child(kind, 10000)
        rows.append((label, large[kind]["cpu_s"], large[kind]["rss_gb"], large[kind]["notes"][0]))
    if "--large" in sys.argv:  # (the O(n) cases alone)
        return _report(rows, {
            "chain10k_default_cpu_s": round(large["chain_default"]["cpu_s"], 2),
            "chain10k_default_rss_gb": round(large["chain_default"]["rss_gb"], 3),
            "fput10k_cpu_s": round(large["fput"]["cpu_s"], 2), "fput10k_rss_gb": round(large["fput"]["rss_gb"], 3),
            "fput10k_energy_drift": large["fput"]["energy_drift"]})
    spatial = run_child("spatial", 3)
    rows.append(("3 bodies on spherical joints, derivation", spatial["ours_derive_s"], spatial["rss_gb"],
                 f"{spatial['ours_ops']} operations against KanesMethod's {spatial['kane_ops']} (derived in "
                 f"{spatial['kane_derive_s']:.2f} s)"))
    if spatial.get("speed_ratio") is not None:
        rows.append(("3 bodies, warm 5 s run, ours (native)", spatial["ours_s"], spatial["rss_gb"],
                     f"PyDy cython {spatial['pydy_cython_s']:.4f} s; ours on the tape {spatial['ours_tape_s']:.4f} s; "
                     f"runs differ by {spatial['max_difference']:.1e}"))
    run_child("pendulum", 6)  # compiles and caches what the second process finds
    # the same statistic for both, the least CPU of three fresh processes each (this machine's timings vary by ±20 %)
    second = min((run_child("pendulum", 6) for _ in range(3)), key=lambda info: info["cpu_s"])
    numpy_import = min(run_child("numpy", 0)["cpu_s"] for _ in range(3))
    rows.append(("6-link pendulum, 10 s, second process", second["cpu_s"], second["rss_gb"], second["notes"][0]))
    rows.append(("import numpy, scipy.integrate", numpy_import, 0.0, ""))
    ngspice200 = run_child("ngspice", 200)
    ours200 = run_child("ladder", 200)
    t_ng, v_ng = np.load("/tmp/lagrangian-scale-ngspice-200.npy")
    t_us, v_us = np.load("/tmp/lagrangian-scale-ours-200.npy")
    peak = np.abs(v_us).max()
    ng_error = float(np.abs(np.interp(t_us, t_ng, v_ng) - v_us).max() / peak)
    rows.append(("ladder 200 sections, ngspice (PySpice)", ngspice200["cpu_s"], ngspice200["rss_gb"], f"error {ng_error:.2g} of peak"))
    rows.append(("ladder 200 sections, ours", ours200["cpu_s"], ours200["rss_gb"], ours200["notes"][-1]))
    ladder2000 = run_child("ladder", 2000)
    rows.append(("ladder 2,000 sections, ours", ladder2000["cpu_s"], ladder2000["rss_gb"], ladder2000["notes"][-1]))
    chain = run_child("chain", 10000)
    rows.append(("chain of 10,000 masses, ours", chain["cpu_s"], chain["rss_gb"], chain["notes"][-1]))
    _report(rows, {
        "spatial_ops_vs_kane": round(spatial["ops_ratio"], 3),
        "spatial_speed_vs_pydy_cython": None if spatial.get("speed_ratio") is None else round(spatial["speed_ratio"], 3),
        "ladder200_speed_vs_ngspice": round(ngspice200["cpu_s"] / ours200["cpu_s"], 3),
        "ladder200_ngspice_error": ng_error,
        "ladder2000_s": round(ladder2000["cpu_s"], 2),
        "chain10k_cpu_s": round(chain["cpu_s"], 2),
        "chain10k_rss_gb": round(chain["rss_gb"], 3),
        "second_run_vs_numpy_scipy_import": round(second["cpu_s"] / numpy_import, 3),
        "chain10k_default_cpu_s": round(large["chain_default"]["cpu_s"], 2),
        "chain10k_default_rss_gb": round(large["chain_default"]["rss_gb"], 3),
        "fput10k_cpu_s": round(large["fput"]["cpu_s"], 2), "fput10k_rss_gb": round(large["fput"]["rss_gb"], 3),
        "fput10k_energy_drift": large["fput"]["energy_drift"],
    })


def _report(rows, figures: dict) -> None:
    print(f"{'case':42s} {'CPU s':>8s} {'peak GB':>8s}  notes")
    for name, cpu, rss, note in rows:
        print(f"{name:42s} {cpu:8.3g} {rss:8.3f}  {note}")
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
