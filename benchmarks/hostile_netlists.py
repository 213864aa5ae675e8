"""Hostile netlists: what reading (and running) a large or malformed deck costs, each case in a fresh process.

- ``caps N``: ``N`` capacitors in parallel across a voltage source and a resistor (node fluxes, where they share
  one node), read and simulated over its ``.tran``;
- ``klines N``: ``N`` pairs of coupled inductors (``2N`` inductors, ``N`` distinct ``K`` lines, each pair in its own
  loop with a resistor), read (its DC operating point included);
- ``kdup N``: ``N`` inductors with ``N/2`` distinct ``K`` lines and, last, one that repeats the first pair: the time
  until the refusal;
- ``resistors N``: ``N`` resistors in parallel across a source (``N`` beyond ``lagrangian.limits.netlist_elements``
  is refused while parsing), read (``limits`` left as they are);
- ``devzero``: ``read_netlist_file("/dev/zero")``, refused past ``lagrangian.limits.file_bytes``.

Each prints one line: the case, what happened (``read``, or the error's first words), seconds and the process's
peak resident memory (``resource.getrusage``, import included).  Run:
``.venv/bin/python benchmarks/hostile_netlists.py caps 10000 klines 3000``.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve()


def deck(case: str, n: int) -> tuple[str, str]:
    """The netlist text of ``case`` at size ``n`` and the formulation to read it in."""
    if case == "caps":
        return "\n".join(["parallel capacitors", "V1 in 0 DC 1", "R1 in a 1k", *(f"C{i} a 0 1n" for i in range(n)),
                          ".tran 1u 10u", ".end"]), "flux"
    if case == "resistors":
        return "\n".join(["parallel resistors", "V1 a 0 DC 1", *(f"R{i} a 0 1meg" for i in range(n)), ".end"]), "charge"
    if case in ("klines", "kdup"):
        pairs = n if case == "klines" else n // 2
        lines = ["coupled pairs", "V1 in 0 DC 1"]
        for i in range(pairs):
            lines += [f"R{i} in a{i} 1k", f"La{i} a{i} 0 1m", f"Lb{i} b{i} 0 1m", f"Rb{i} b{i} 0 50", f"K{i} La{i} Lb{i} 0.5"]
        if case == "kdup":
            lines.append("Kdup Lb0 La0 0.3")
        return "\n".join([*lines, ".tran 1u 10u", ".end"]), "charge"
    raise SystemExit(f"unknown case {case!r}")


def child(case: str, n: int) -> dict:
    import resource
    import time

    import lagrangian as lg
    from lagrangian.circuits.netlist import read_netlist, read_netlist_file

    start = time.perf_counter()
    outcome = "read"
    try:
        if case == "devzero":
            read_netlist_file("/dev/zero")
        else:
            text, formulation = deck(case, n)
            net = read_netlist(text, formulation=formulation)
            if case == "caps":
                net.simulate()
                outcome = "read and simulated"
    except lg.LagrangianError as exc:
        outcome = f"refused: {str(exc)[:110]}"
    seconds = time.perf_counter() - start
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # KiB on Linux
    return {"case": case, "n": n, "outcome": outcome, "seconds": round(seconds, 2), "peak_rss_mib": round(peak)}


def main(argv: list[str]) -> None:
    if argv[:1] == ["--child"]:
        print(json.dumps(child(argv[1], int(argv[2]))))
        return
    cases = []
    words = list(argv) or ["caps", "10000", "klines", "1000", "devzero"]
    while words:
        case = words.pop(0)
        n = int(words.pop(0)) if case != "devzero" else 0
        cases.append((case, n))
    for case, n in cases:
        run = subprocess.run([sys.executable, str(HERE), "--child", case, str(n)], capture_output=True, text=True)
        if run.returncode:
            print(f"{case} {n}: exit status {run.returncode}: {run.stderr.strip()[-300:]}")
            continue
        got = json.loads(run.stdout.strip().splitlines()[-1])
        print(f"{case:10} {n:>8}  {got['seconds']:8.2f} s  {got['peak_rss_mib']:6} MiB  {got['outcome']}")


if __name__ == "__main__":
    main(sys.argv[1:])
