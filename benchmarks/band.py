"""Banded against dense solves: one evaluation of the right-hand side on the tape interpreter, per size.

Two systems: a chain of masses, springs and dampers on absolute coordinates (a diagonal mass matrix) and a ladder of
capacitors in node fluxes (a tridiagonal capacitance matrix), each evaluated with the banded solve
(:mod:`lagrangian.numerics.band`) and with the dense LU, called from Python at a fixed state (median of many calls,
microseconds).  The sizes where the band starts to pay decide ``band.BAND_FROM``.

Prints a table and, as its last line, a JSON object.  Run: ``.venv/bin/python benchmarks/band.py``.
"""

from __future__ import annotations

import json
import time
import warnings

import numpy as np
import sympy as sp

import lagrangian as lg
from lagrangian.numerics import band
from lagrangian.numerics.codegen import compile_model
from scale import chain_model

SIZES = (8, 16, 32, 64, 128, 256)


def chain(n: int) -> lg.Model:
    """``benchmarks/scale.py``'s chain of masses, springs and dampers."""
    return chain_model(n)[0]


def ladder(n: int) -> lg.Model:
    m = lg.Model("capacitor ladder", formulation="flux")
    m.add("voltage_source", "V1", ("n0", "ground"), E=sp.sin(2 * lg.t))
    m.add("resistor", "R0", ("n0", "a0"), R=1.0)
    for i in range(n):
        a, b = f"a{i}", f"a{i + 1}"
        m.add("capacitor", f"Cs{i}", (a, b), C=0.5)
        m.add("capacitor", f"Cg{i}", (b, "ground"), C=1.0)
        m.add("inductor", f"L{i}", (b, "ground"), L=2.0)
        m.add("resistor", f"R{i + 1}", (b, "ground"), R=10.0)
    m.add("capacitor", "Cin", ("a0", "ground"), C=1.0)
    return m


def per_evaluation_us(model: lg.Model) -> tuple[float, bool]:
    compiled, _ = compile_model(model.numeric(), "tape")
    y = np.random.default_rng(0).normal(size=compiled.dim) * 0.01
    compiled.rhs(0.0, y)
    calls = max(200, int(2e5 / compiled.dim))
    times = []
    for _ in range(5):
        began = time.perf_counter()
        for _ in range(calls):
            compiled.rhs(0.0, y)
        times.append((time.perf_counter() - began) / calls * 1e6)
    return float(np.median(times)), compiled.band is not None


def main() -> None:
    warnings.simplefilter("ignore", lg.InitialConditionWarning)
    chosen = band.BAND_FROM
    figures: dict = {"band_from": chosen}
    print(f"{'system':10} {'unknowns':>8} {'banded µs':>10} {'dense µs':>10}")
    try:
        for build in (chain, ladder):
            for n in SIZES:
                band.BAND_FROM = 1
                banded, used = per_evaluation_us(build(n))
                band.BAND_FROM = 10**9
                dense, _ = per_evaluation_us(build(n))
                shown = f"{banded:10.2f}" if used else f"{'(dense)':>10}"
                print(f"{build.__name__:10} {n:8d} {shown} {dense:10.2f}")
                figures[f"{build.__name__}{n}_banded_us"] = banded if used else None
                figures[f"{build.__name__}{n}_dense_us"] = dense
    finally:
        band.BAND_FROM = chosen
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
