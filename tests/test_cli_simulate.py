"""``lagrangian simulate`` and ``lagrangian equations``: a transient written as CSV, netCDF or a chart and checked
against the closed form of a damped oscillator; a netlist's own ``.tran`` and ``.ic``; the equations printed; output
files refused by their suffix before anything runs."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from lagrangian.cli import main

MSD = """import lagrangian as lg

model = lg.Model("msd")
model.add("mass", "m", "p", m=0.3)
model.add("spring", "k", ("ground", "p"), k=40.0)
model.add("damper", "c", ("ground", "p"), c=0.2)
"""

RC = """charging RC
V1 in 0 DC 2
R1 in a 1k
C1 a 0 1u ic=0
.tran 10u 3m uic
.end
"""


def damped(m, k, c, x0, t):
    """x(t) of m x'' + c x' + k x = 0 from x0 at rest (under-damped)."""
    wn, zeta = math.sqrt(k / m), c / (2 * math.sqrt(k * m))
    wd = wn * math.sqrt(1 - zeta**2)
    return np.exp(-zeta * wn * t) * (x0 * np.cos(wd * t) + zeta * wn * x0 / wd * np.sin(wd * t))


def test_simulate_writes_the_transient_as_csv_with_the_parameters_and_start_given(tmp_path, capsys):
    source = tmp_path / "msd.py"
    source.write_text(MSD)
    out = tmp_path / "run.csv"
    assert main(["simulate", str(source), "--t-end", "2", "--points", "201", "--initial", "x_p=0.1",
                 "--velocity", "x_p=0", "--param", "k_k=9", "--out", str(out)]) == 0
    assert f"written: {out}" in capsys.readouterr().out
    table = pd.read_csv(out)
    t = table["t"].to_numpy()
    assert len(t) == 201 and t[-1] == pytest.approx(2.0)
    assert np.max(np.abs(table["x_p"] - damped(0.3, 9.0, 0.2, 0.1, t))) < 1e-8


def test_simulate_prints_final_values_and_writes_netcdf_and_a_chart(tmp_path, capsys):
    source = tmp_path / "msd.py"
    source.write_text(MSD)
    assert main(["simulate", f"{source}:model", "--t-end", "1.5", "--initial", "x_p=0.1", "--velocity", "x_p=0"]) == 0
    final = float(capsys.readouterr().out.split("x_p = ")[1].split(",")[0])
    assert final == pytest.approx(float(damped(0.3, 40.0, 0.2, 0.1, np.array(1.5))), abs=1e-9)
    xr = pytest.importorskip("xarray")
    assert main(["simulate", str(source), "--t-end", "1", "--initial", "x_p=0.1", "--velocity", "x_p=0",
                 "--out", str(tmp_path / "run.nc")]) == 0
    ds = xr.open_dataset(tmp_path / "run.nc")
    assert float(ds["x_p"][-1]) == pytest.approx(float(damped(0.3, 40.0, 0.2, 0.1, np.array(1.0))), abs=1e-9)
    assert main(["simulate", str(source), "--t-end", "1", "--initial", "x_p=0.1", "--velocity", "x_p=0",
                 "--out", str(tmp_path / "run.png")]) == 0
    assert (tmp_path / "run.png").read_bytes().startswith(b"\x89PNG")


def test_simulate_takes_a_netlists_tran_and_ic(tmp_path):
    source = tmp_path / "rc.cir"
    source.write_text(RC)
    out = tmp_path / "rc.csv"
    assert main(["simulate", str(source), "--out", str(out)]) == 0
    table = pd.read_csv(out)
    t = table["t"].to_numpy()
    assert t[-1] == pytest.approx(3e-3)
    charge = table["q_R1"].to_numpy()
    # the capacitor charges to C V: q = C V (1 − e^{−t/RC})
    assert np.max(np.abs(charge - 1e-6 * 2 * (1 - np.exp(-t / 1e-3)))) < 1e-6 * 2 * 1e-7


LADDER = """two-section RLC ladder, sine source
V1 in 0 SIN(0 1 0.2)
R0 in m0 0.37
L0 m0 n0 7e-3
C0 n0 0 0.47
R1 n0 m1 1.3
L1 m1 n1 0.12
C1 n1 0 0.82
.tran 0.01 6
.end
"""


def ladder_by_hand(t, C1=0.82):
    """Node voltages v(n0), v(n1) and the current of L0 of :data:`LADDER`, from its state equations written out by
    hand (currents of L0, L1 and voltages of C0, C1) and solved exactly: the sine's steady response plus the free
    response that starts the state at zero (eigenvectors of A)."""
    R0, L0, C0, R1, L1 = 0.37, 7e-3, 0.47, 1.3, 0.12
    A = np.array([[-R0 / L0, 0, -1 / L0, 0], [0, -R1 / L1, 1 / L1, -1 / L1],
                  [1 / C0, -1 / C0, 0, 0], [0, 1 / C1, 0, 0]])
    b = np.array([1 / L0, 0, 0, 0])
    w = 2 * np.pi * 0.2
    z = np.linalg.solve(1j * w * np.eye(4) - A, b)  # x_p = Im(z e^{iwt}) for the input sin(w t)
    steady = np.imag(z[:, None] * np.exp(1j * w * t[None, :]))
    lam, V = np.linalg.eig(A)
    c = np.linalg.solve(V, -np.imag(z))
    free = np.real(V @ (c[:, None] * np.exp(lam[:, None] * t[None, :])))
    x = steady + free
    return x[2], x[3], x[0]


def test_simulate_reports_chosen_outputs_node_voltages_and_currents_as_csv(tmp_path, capsys):
    """``--output v(n0),v(C1),i(L0)`` writes those columns alone; checked against the ladder's state equations
    solved by hand (an independent reference), and an output that needs accelerations or names nothing is
    refused by name."""
    source = tmp_path / "ladder.cir"
    source.write_text(LADDER)
    out = tmp_path / "v.csv"
    assert main(["simulate", str(source), "--points", "601", "--output", "v(n0),v(C1)", "--output", "i(L0)",
                 "--out", str(out)]) == 0
    assert "final v(n0) = " in capsys.readouterr().out
    table = pd.read_csv(out)
    assert list(table.columns) == ["t", "v(n0)", "v(C1)", "i(L0)"]
    t = table["t"].to_numpy()
    v0, v1, i0 = ladder_by_hand(t)
    for got, want in ((table["v(n0)"], v0), (table["v(C1)"], v1), (table["i(L0)"], i0)):
        assert np.max(np.abs(got.to_numpy() - want)) <= 1e-9 * np.max(np.abs(want))
    # a value given at the run: the quantities take it too (q / C with the C the run had)
    assert main(["simulate", str(source), "--points", "601", "--output", "v(C1)", "--param", "C_C1=0.5",
                 "--out", str(out)]) == 0
    v1 = ladder_by_hand(t, C1=0.5)[1]
    assert np.max(np.abs(pd.read_csv(out)["v(C1)"].to_numpy() - v1)) <= 1e-9 * np.max(np.abs(v1))
    assert main(["simulate", str(source), "--output", "v(L0)"]) == 1
    assert "depends on an acceleration" in capsys.readouterr().err
    assert main(["simulate", str(source), "--output", "v(n9)"]) == 1
    assert "unknown component or node 'n9'" in capsys.readouterr().err


def test_equations_prints_the_lagrangian_and_the_equation_of_motion(tmp_path, capsys):
    source = tmp_path / "msd.py"
    source.write_text(MSD)
    assert main(["equations", str(source)]) == 0
    text = capsys.readouterr().out
    assert "L = -20.0*x_p(t)**2 + 0.15*Derivative(x_p(t), t)**2" in text
    assert main(["equations", str(source), "--latex"]) == 0
    latex = capsys.readouterr().out
    assert "x_{p}" in latex and "\\frac" in latex


def test_simulate_refuses_an_output_it_cannot_write_before_running(tmp_path, capsys):
    source = tmp_path / "msd.py"
    source.write_text(MSD)
    assert main(["simulate", str(source), "--out", str(tmp_path / "run.txt")]) == 1
    assert "give a .csv, .nc or .png file" in capsys.readouterr().err
    assert main(["simulate", str(tmp_path / "missing.py")]) == 1
    assert "does not exist" in capsys.readouterr().err


def test_convert_writes_a_netlist_as_a_model_file_that_every_command_reads(tmp_path, capsys):
    import lagrangian as lg
    from lagrangian.circuits.netlist import read_netlist_file
    from lagrangian.identity import is_zero

    source = tmp_path / "rc.cir"
    source.write_text(RC)
    out = tmp_path / "rc.json"
    assert main(["convert", str(source), "--out", str(out)]) == 0
    assert f"written: {out}" in capsys.readouterr().out
    original, loaded = read_netlist_file(source).model, lg.load(out)
    assert loaded.coordinate_names == original.coordinate_names
    assert all(is_zero(a - b) for a, b in zip([*original.eq.M, *original.eq.f], [*loaded.eq.M, *loaded.eq.f]))
    table = tmp_path / "rc.csv"
    assert main(["simulate", str(out), "--t-end", "3e-3", "--out", str(table)]) == 0
    t, q = (pd.read_csv(table)[c].to_numpy() for c in ("t", "q_R1"))
    assert np.max(np.abs(q - 1e-6 * 2 * (1 - np.exp(-t / 1e-3)))) < 1e-6 * 2 * 1e-7


def test_convert_refuses_what_a_model_file_cannot_hold_by_name(tmp_path, capsys):
    source = tmp_path / "pulse.cir"
    source.write_text("pulsed RC\nV1 in 0 PULSE(0 1 0 1u 1u 1m 2m)\nR1 in a 1k\nC1 a 0 1u\n.tran 10u 3m\n.end\n")
    assert main(["convert", str(source), "--out", str(tmp_path / "p.json")]) == 1
    assert "component 'V1' (voltage_source), parameter 'E'" in capsys.readouterr().err
    assert main(["convert", str(source), "--out", str(tmp_path / "p.txt")]) == 1
    assert "give a .json file" in capsys.readouterr().err


def test_an_output_of_a_model_without_numbers_comes_from_its_equations(tmp_path):
    """A capacitance given as a symbol (its value at the run): the numeric assembly cannot say ``v(out)``, so the
    symbolic path evaluates it; both paths equal the RC closed form."""
    import sympy as sp

    import lagrangian as lg
    from lagrangian.analysis.channels import output_series

    for C in (1e-6, sp.Symbol("C_1", positive=True)):
        c = lg.Model("rc", formulation="charge")
        c.add("voltage_source", "V1", ("in", "0"), E=2.0)
        c.add("resistor", "R1", ("in", "out"), R=1e3)
        c.add("capacitor", "C1", ("out", "0"), C=C)
        res = c.simulate(3e-3, initial={"q_R1": 0.0}, points=31, rtol=1e-11, atol=1e-15,
                         params=None if isinstance(C, float) else {"C_1": 1e-6})
        want = 2.0 * (1 - np.exp(-res.t / 1e-3))
        for label in ("v(out)", "v(C1)"):
            assert np.max(np.abs(output_series(c, res, label) - want)) <= 1e-8, (C, label)


@pytest.mark.slow
def test_a_netlist_run_written_as_csv_draws_nothing(tmp_path):
    # a fresh process: matplotlib (0.1 s of CPU at start) is imported only for a chart.  The charging RC's
    # capacitor voltage against its closed form, 2 (1 − e^(−t/RC)).
    import subprocess
    import sys

    deck, out = tmp_path / "rc.cir", tmp_path / "v.csv"
    deck.write_text(RC)
    code = ("import sys\nfrom lagrangian.cli import main\n"
            f"status = main(['simulate', {str(deck)!r}, '--output', 'v(a)', '--out', {str(out)!r}])\n"
            "print(status, sorted(m for m in ('matplotlib', 'PIL') if m in sys.modules))\n")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert run.stdout.strip().splitlines()[-1] == "0 []", run.stdout + run.stderr
    table = pd.read_csv(out)
    t = table["t"].to_numpy()
    assert np.max(np.abs(table["v(a)"] - 2 * (1 - np.exp(-t / 1e-3)))) < 1e-9 * 2
