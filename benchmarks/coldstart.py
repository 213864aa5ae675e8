"""Cold starts: what a fresh process pays before it does anything, and a netlist run from the command line.

Each case runs in fresh processes (the least CPU time, user + system, of ``--repeat`` processes, 5 by default);
the compiled-code cache is empty for every one (``LAGRANGIAN_CACHE_DIR`` a new directory).

- ``import lagrangian`` against ``import numpy``: the CPU time of the import statement alone, in its process.
- ``lagrangian --help``: the whole process.
- ``ladder200``: an RLC ladder of 200 sections (random values over a decade, a 1 V sine source at 0.2 Hz, 30 s,
  3,001 points) written as a netlist.  ``lagrangian simulate ladder200.cir --output v(n0) --out v.csv`` writes the
  first section's node voltage; a fresh process builds the same circuit in PySpice and runs ngspice's transient at
  its default settings (step 0.01 s); the ``ngspice -b`` binary runs the deck for information, where it is
  installed.  The whole process of each.  The errors of both against the exact solution of the ladder's state
  equations, written out here and solved by eigenvectors (an independent reference), relative to the peak.
- whether the command line's netlist run imported SymPy.

The package is byte-compiled first, as an installed one is.  Prints a table and, as its last line, a JSON object
with the fields of the issue that asks for light starts.  Run: ``.venv/bin/python benchmarks/coldstart.py``.
"""

from __future__ import annotations

import argparse
import compileall
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve()
ROOT = HERE.parent.parent
PYTHON = sys.executable
CLI = str(Path(PYTHON).parent / "lagrangian")
SECTIONS, FREQUENCY, T_END, STEP = 200, 0.2, 30.0, 0.01


def ladder_values(sections: int) -> list[tuple[float, float, float]]:
    """R (Ω), L (H), C (F) of each section: three significant digits, drawn over about a decade."""
    rng = np.random.default_rng(1)
    return [(float(f"{rng.uniform(0.2, 2.0):.3g}"), float(f"{rng.uniform(0.05, 0.5):.3g}"),
             float(f"{rng.uniform(0.1, 1.0):.3g}")) for _ in range(sections)]


def netlist(sections: int) -> str:
    lines = [f"{sections}-section RLC ladder, sine source", f"V1 in 0 SIN(0 1 {FREQUENCY})"]
    prev = "in"
    for k, (R, L, C) in enumerate(ladder_values(sections)):
        lines += [f"R{k} {prev} m{k} {R}", f"L{k} m{k} n{k} {L}", f"C{k} n{k} 0 {C}"]
        prev = f"n{k}"
    return "\n".join([*lines, f".tran {STEP} {T_END}", ".end", ""])


def exact(sections: int, t: np.ndarray) -> np.ndarray:
    """v(n0) of the ladder from rest, from its state equations (inductor currents i_k, capacitor voltages v_k):
    L_k i_k' = v_(k−1) − R_k i_k − v_k (v_(−1) the source), C_k v_k' = i_k − i_(k+1); the sine's steady response
    plus the free response that starts the state at zero, by the eigenvectors of the state matrix."""
    values = ladder_values(sections)
    n = len(values)
    A = np.zeros((2 * n, 2 * n))
    b = np.zeros(2 * n)
    for k, (R, L, C) in enumerate(values):
        A[k, k] = -R / L
        A[k, n + k] = -1 / L
        if k:
            A[k, n + k - 1] = 1 / L
        A[n + k, k] = 1 / C
        if k + 1 < n:
            A[n + k, k + 1] = -1 / C
    b[0] = 1 / values[0][1]
    w = 2 * np.pi * FREQUENCY
    z = np.linalg.solve(1j * w * np.eye(2 * n) - A, b)  # the response to sin(w t) is Im(z e^{iwt})
    lam, V = np.linalg.eig(A)
    c = np.linalg.solve(V, -np.imag(z))
    row = n  # v_0
    free = np.real((V[row] * c) @ np.exp(lam[:, None] * t[None, :]))
    return np.imag(z[row] * np.exp(1j * w * t)) + free


CHILD_NGSPICE = f"""
import sys
import numpy as np
from PySpice.Spice.Netlist import Circuit
from PySpice.Unit import u_s
sys.path.insert(0, {str(HERE.parent)!r})
from coldstart import ladder_values, FREQUENCY, STEP, T_END
circuit = Circuit("ladder")
circuit.SinusoidalVoltageSource("1", "in", circuit.gnd, amplitude=1, frequency=FREQUENCY)
prev = "in"
for k, (R, L, C) in enumerate(ladder_values({SECTIONS})):
    circuit.R(f"{{k}}", prev, f"m{{k}}", R)
    circuit.L(f"{{k}}", f"m{{k}}", f"n{{k}}", L)
    circuit.C(f"{{k}}", f"n{{k}}", circuit.gnd, C)
    prev = f"n{{k}}"
analysis = circuit.simulator().transient(step_time=STEP @ u_s, end_time=T_END @ u_s, use_initial_condition=True)
np.save(sys.argv[1], np.vstack([np.array(analysis.time), np.array(analysis["n0"])]))
"""


def cpu_of(command: list[str], env: dict | None = None, cwd: str | None = None) -> tuple[float, str]:
    """The CPU time (user + system) of one fresh process running ``command``, and its standard output."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    out = subprocess.run(command, capture_output=True, text=True, env=env, cwd=cwd)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if out.returncode:
        raise SystemExit(f"{' '.join(command)} failed:\n{out.stderr[-3000:]}")
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime), out.stdout


def import_cpu(module: str) -> float:
    """The CPU time of ``import module`` alone, measured inside a fresh process."""
    code = f"import time\nt0 = time.process_time()\nimport {module}\nprint(time.process_time() - t0)"
    return float(cpu_of([PYTHON, "-c", code])[1].strip().splitlines()[-1])


def best(repeat: int, measure) -> float:
    return min(measure() for _ in range(repeat))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5, help="fresh processes per case (the least CPU is kept)")
    args = parser.parse_args()
    for folder in ("core", "plugins"):
        compileall.compile_dir(str(ROOT / folder), quiet=1)
    work = Path(tempfile.mkdtemp(prefix="lagrangian-coldstart-"))
    deck = work / "ladder200.cir"
    deck.write_text(netlist(SECTIONS))
    rows = []
    numpy_s = best(args.repeat, lambda: import_cpu("numpy"))
    ours_s = best(args.repeat, lambda: import_cpu("lagrangian"))
    rows.append(("import numpy (the statement)", numpy_s, ""))
    rows.append(("import lagrangian (the statement)", ours_s, f"{ours_s / numpy_s:.2f} × numpy's"))
    help_s = best(args.repeat, lambda: cpu_of([CLI, "--help"])[0])
    rows.append(("lagrangian --help (the process)", help_s, ""))

    def ours() -> float:
        env = {**os.environ, "LAGRANGIAN_CACHE_DIR": tempfile.mkdtemp(dir=work)}
        return cpu_of([CLI, "simulate", str(deck), "--points", str(int(round(T_END / STEP)) + 1), "--output", "v(n0)",
                       "--out", str(work / "v.csv")], env=env)[0]

    ours_run = best(args.repeat, ours)
    table = np.loadtxt(work / "v.csv", delimiter=",", skiprows=1)
    t, v = table[:, 0], table[:, 1]
    reference = exact(SECTIONS, t)
    peak = float(np.abs(reference).max())
    our_error = float(np.abs(v - reference).max() / peak)
    rows.append(("ladder 200, lagrangian simulate (process)", ours_run, f"error {our_error:.2g} of peak"))
    script = work / "ngspice_child.py"
    script.write_text(CHILD_NGSPICE)
    ng_run = best(args.repeat, lambda: cpu_of([PYTHON, str(script), str(work / "ng.npy")])[0])
    t_ng, v_ng = np.load(work / "ng.npy")
    ng_error = float(np.abs(v_ng - exact(SECTIONS, t_ng)).max() / peak)
    rows.append(("ladder 200, ngspice through PySpice (process)", ng_run, f"error {ng_error:.2g} of peak"))
    binary = shutil.which("ngspice")
    binary_run = None
    if binary:
        batch = work / "batch.cir"
        batch.write_text(netlist(SECTIONS).replace(".end\n", ".print tran v(n0)\n.end\n"))
        binary_run = best(args.repeat, lambda: cpu_of([binary, "-b", str(batch)], cwd=str(work))[0])
        rows.append(("ladder 200, ngspice -b (process, for information)", binary_run, ""))
    probe = ("import sys\nfrom lagrangian.cli import main\n"
             f"main(['simulate', {str(deck)!r}, '--points', '301', '--output', 'v(n0)', '--out', {str(work / 'p.csv')!r}])\n"
             "print('sympy' in sys.modules)")
    env = {**os.environ, "LAGRANGIAN_CACHE_DIR": tempfile.mkdtemp(dir=work)}
    imports_sympy = cpu_of([PYTHON, "-c", probe], env=env)[1].strip().splitlines()[-1] == "True"
    rows.append(("netlist path imports SymPy", float("nan"), str(imports_sympy)))
    print(f"{'case':50s} {'CPU s':>8s}  notes")
    for name, cpu, note in rows:
        print(f"{name:50s} {cpu:8.3f}  {note}")
    shutil.rmtree(work, ignore_errors=True)
    print(json.dumps({
        "import_s": round(ours_s, 4), "numpy_import_s": round(numpy_s, 4),
        "import_vs_numpy": round(ours_s / numpy_s, 3),
        "cli_help_s": round(help_s, 3),
        "ladder200_cli_s": round(ours_run, 3), "ladder200_ngspice_pyspice_s": round(ng_run, 3),
        "ladder200_cli_vs_ngspice": round(ng_run / ours_run, 3),
        "ladder200_cli_vs_ngspice_binary": None if binary_run is None else round(binary_run / ours_run, 3),
        "ladder200_error": our_error, "ladder200_ngspice_error": ng_error,
        "netlist_path_imports_sympy": imports_sympy,
        "time": time.strftime("%Y-%m-%d"),
    }))


if __name__ == "__main__":
    main()
