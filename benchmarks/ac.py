"""Frequency responses against ngspice's AC analysis: agreement and time, from cold.

Cases (each on 1,000 log-spaced frequencies):

* ``series_rlc``: a series RLC driven by a voltage source, its four element voltages and its current;
* ``butterworth``: ``examples/butterworth.cir`` read as a netlist, its three node voltages;
* ``loudspeaker``: the force–voltage analogue of a moving-coil loudspeaker (the coil a gyrator), its input current;
* ``coupled_tanks``: two inductively coupled LC tanks with losses, driven by a current, in node fluxes;
* ``ladder100``: an RLC ladder of 100 sections, its first current and last capacitor voltage.

Timing, per case, best of ``--repeat`` runs: ngspice's cold run is the deck loaded into ngspice's shared
library, its ``.ac`` run and its output vectors read into arrays, through PySpice (``lagrangian.spice.run_ac``:
what a PySpice user waits for before having the response; the table shows the read apart); ours is from cold as
well: the model
built from its components (the deck read, for the netlist; the mechanism mapped, for the loudspeaker), linearized
and solved at every frequency (``lagrangian.frequency.frequency_response``), in one process after the imports.
Every case here is linear with numeric values, so it is assembled in numbers
(``lagrangian.derivation.numeric``): nothing is derived symbolically, and nothing is kept between repeats but
what a process keeps (imported modules, compiled code).  The best of ``--repeat`` runs is kept.  Agreement is the
largest relative difference of the complex responses (relative to the response, floored at 1e-12 of its peak:
``lagrangian.ac.FLOOR``).  Prints a table; its last line is
``{"cases": N, "worst_rel_error": …, "speedup_vs_ngspice": …, "speedup_without_read": …}``, the speed-up being
ngspice's time over ours for the case where ours is slowest against it (the minimum), with and without ngspice's
read of its vectors.

Run: .venv/bin/python benchmarks/ac.py [--repeat 9]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

import lagrangian as lg
from lagrangian import models
from lagrangian.ac import FLOOR, compare_ac_with_ngspice
from lagrangian.frequency import frequency_response, sweep
from lagrangian.netlist import read_netlist

HERE = Path(__file__).resolve().parent


def series_rlc() -> lg.Model:
    m = lg.Model("series rlc")
    m.add("voltage_source", "V1", ("in", "0"), E=0)
    m.add("resistor", "R1", ("in", "a"), R=10.0)
    m.add("inductor", "L1", ("a", "b"), L=7e-3)
    m.add("capacitor", "C1", ("b", "0"), C=2.2e-6)
    return m


def loudspeaker() -> lg.Model:
    from lagrangian.analogy import map_model

    return map_model(models.loudspeaker(), "force-voltage").model


def coupled_tanks() -> lg.Model:
    m = lg.Model("coupled tanks", formulation="flux")
    m.add("current_source", "I1", ("0", "n1"), I=0)
    for i, (L, C, R) in enumerate([(7e-3, 2.2e-6, 2e3), (4.7e-3, 3.3e-6, 1.5e3)], start=1):
        m.add("inductor", f"L{i}", (f"n{i}", "0"), L=L)
        m.add("capacitor", f"C{i}", (f"n{i}", "0"), C=C)
        m.add("resistor", f"R{i}", (f"n{i}", "0"), R=R)
    m.add("coupling", "K1", inductor1="L1", inductor2="L2", k=0.3)
    return m


def ladder(n: int = 100) -> lg.Model:
    return models.rlc_ladder(n, seed=1)


def butterworth():
    return read_netlist((HERE.parent / "examples" / "butterworth.cir").read_text())


#: name → (build, input, outputs, start Hz, stop Hz)
CASES = {
    "series_rlc": (series_rlc, "V1", ["v(R1)", "v(L1)", "v(C1)", "i(L1)"], 10.0, 1e6),
    "butterworth": (butterworth, "V1", ["v(n1)", "v(n2)", "v(n3)"], 10.0, 1e5),
    "loudspeaker": (loudspeaker, "E", ["i(E)"], 5.0, 5e3),
    "coupled_tanks": (coupled_tanks, "I1", ["v(C1)", "v(C2)", "i(L2)"], 100.0, 1e4),
    "ladder100": (ladder, "V1", ["i(L0)", "v(C99)"], 1e-3, 1.0),
}


def run_case(name: str, repeat: int) -> dict:
    build, source, outputs, start, stop = CASES[name]
    points = int(round(999 / np.log10(stop / start)))  # ngspice's dec grid of about 1,000 frequencies
    ours_s, ngspice_s, bare_s = [], [], []
    cmp = None
    for _ in range(repeat):
        began = time.perf_counter()
        built = build()
        model = built.model if hasattr(built, "model") else built
        resp = frequency_response(model, sweep("dec", points, start, stop), inputs=[source], outputs=outputs)
        ours_s.append(time.perf_counter() - began)
        began = time.perf_counter()
        cmp = compare_ac_with_ngspice(model, input=source, outputs=outputs, start=start, stop=stop, points=points)
        bare_s.append(cmp.ngspice_load_s + cmp.ngspice_s)
        ngspice_s.append(bare_s[-1] + cmp.ngspice_read_s)
        assert np.allclose(resp.frequencies, cmp.frequencies, rtol=1e-12)
    errors = []
    for label in outputs:
        theirs = cmp.spice[label]
        floor = FLOOR * np.abs(theirs).max()
        errors.append(float(np.max(np.abs(resp[label] - theirs) / np.maximum(np.abs(theirs), floor))))
    return {"name": name, "frequencies": len(cmp.frequencies), "ours_s": min(ours_s), "ngspice_s": min(ngspice_s),
            "bare_s": min(bare_s), "worst_rel": max(errors), "unknowns": len(model.coordinate_names)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=9, help="runs per case; the best time is kept (default 9)")
    args = parser.parse_args()
    rows = [run_case(name, args.repeat) for name in CASES]
    print(f"{'case':15} {'coords':>6} {'freqs':>6} {'ngspice cold ms':>16} {'(read ms)':>10} {'ours cold ms':>13} "
          f"{'speed-up':>9} {'(no read)':>10} {'worst rel':>10}")
    for r in rows:
        print(f"{r['name']:15} {r['unknowns']:6d} {r['frequencies']:6d} {r['ngspice_s'] * 1e3:16.2f} "
              f"{(r['ngspice_s'] - r['bare_s']) * 1e3:10.2f} {r['ours_s'] * 1e3:13.2f} {r['ngspice_s'] / r['ours_s']:9.3f} "
              f"{r['bare_s'] / r['ours_s']:10.3f} {r['worst_rel']:10.2e}")
    print(json.dumps({"cases": len(rows), "worst_rel_error": max(r["worst_rel"] for r in rows),
                      "speedup_vs_ngspice": round(min(r["ngspice_s"] / r["ours_s"] for r in rows), 4),
                      "speedup_without_read": round(min(r["bare_s"] / r["ours_s"] for r in rows), 4)}))


if __name__ == "__main__":
    main()
