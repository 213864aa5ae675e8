"""Small-signal analysis of SPICE decks: .ac lines, AC sources, node voltages and the ``lagrangian ac`` command.

References: a doubly terminated Butterworth ladder's closed form |H| = ½ / √(1 + (f/fc)^10), and ngspice's own
.ac analysis of the same deck text (real ngspice through PySpice).
"""

import csv
import math

import numpy as np
import pytest

import lagrangian as lg
from lagrangian.cli import main
from lagrangian.frequency import sweep
from lagrangian.netlist import ACSweep, read_netlist
from lagrangian.spice import run_ac

FC, R0 = 1000.0, 50.0
G = [2 * math.sin((2 * k - 1) * math.pi / 10) for k in range(1, 6)]  # Butterworth prototype values, order 5
WC = 2 * math.pi * FC


def butterworth(sweep: str = "dec 50 10 100k", source: str = "DC 0 AC 1") -> str:
    C1, L2, C3, L4, C5 = (g / (R0 * WC) if k % 2 == 0 else g * R0 / WC for k, g in enumerate(G))
    return f"""5th-order Butterworth low-pass
V1 in 0 {source}
Rs in n1 {R0!r}
C1 n1 0 {C1!r}
L2 n1 n2 {L2!r}
C3 n2 0 {C3!r}
L4 n2 n3 {L4!r}
C5 n3 0 {C5!r}
RL n3 0 {R0!r}
.ac {sweep}
.end
"""


def test_a_butterworth_deck_has_its_closed_form_response_at_every_node_voltage_asked():
    net = read_netlist(butterworth())
    assert net.ac == ACSweep("dec", 50, 10.0, 1e5) and net.ac_sources == {"V1": (1.0, 0.0)}
    resp = net.frequency_response()
    assert resp.outputs == ["v(in)", "v(n1)", "v(n2)", "v(n3)"]
    f = resp.frequencies
    assert len(f) == 201 and f[0] == pytest.approx(10) and f[-1] == pytest.approx(1e5)
    closed = 0.5 / np.sqrt(1 + (f / FC) ** 10)
    assert np.max(np.abs(np.abs(resp["v(n3)"]) / closed - 1)) < 1e-9
    assert np.allclose(resp["v(in)"], 1.0, rtol=1e-14)
    # the node voltage equals the voltage across the load, by another path of elements
    same = net.frequency_response(outputs=["v(RL)", "v(C5)"])
    assert np.allclose(same["v(RL)"], resp["v(n3)"], rtol=1e-12) and np.allclose(same["v(C5)"], resp["v(n3)"], rtol=1e-12)


@pytest.mark.parametrize("sweep", ["dec 7 3 20k", "oct 5 10 5k", "lin 13 100 2.5k"])
def test_sweeps_give_ngspices_frequencies_and_its_response(sweep):
    text = butterworth(sweep)
    net = read_netlist(text)
    run = run_ac(text, {"v(n3)": ("v", "n3"), "v(n1)": ("v", "n1")})
    assert np.allclose(net.ac.frequencies, run.time, rtol=1e-12, atol=0)
    resp = net.frequency_response(outputs=["v(n3)", "v(n1)"])
    for label in ("v(n3)", "v(n1)"):
        assert np.max(np.abs(resp[label] - run.quantities[label]) / np.abs(run.quantities[label])) < 1e-9


def test_several_ac_sources_add_with_their_magnitudes_and_phases_as_in_ngspice():
    text = """two sources
V1 a 0 DC 0 AC 2 30
I1 0 b AC 0.5 -45
R1 a b 220
C1 b 0 1u
L1 b c 10m
R2 c 0 47
.ac dec 10 10 100k
.end
"""
    net = read_netlist(text)
    assert net.ac_sources == {"V1": (2.0, 30.0), "I1": (0.5, -45.0)}
    resp = net.frequency_response(outputs=["v(b)", "v(c)", "i(L1)"])
    assert resp.inputs == ["V1 + I1"]
    run = run_ac(text, {"v(b)": ("v", "b"), "v(c)": ("v", "c"), "i(L1)": ("i", "l1")})
    for label in resp.outputs:
        assert np.max(np.abs(resp[label] - run.quantities[label]) / np.abs(run.quantities[label])) < 1e-9
    # an AC-only source is 0 in a transient
    assert float(net.model.component("I1").I) == 0.0


def test_bad_ac_requests_on_decks_are_refused():
    plain = read_netlist("no ac\nV1 a 0 1\nR1 a b 1k\nC1 b 0 1u\n.end\n")
    with pytest.raises(lg.ModelError, match="no AC source"):
        plain.frequency_response()
    net = read_netlist(butterworth().replace(".ac dec 50 10 100k\n", ""))
    with pytest.raises(lg.ModelError, match="no .ac line"):
        net.frequency_response()
    with pytest.raises(lg.ModelError, match="no path"):
        read_netlist("float\nV1 a 0 AC 1\nR1 a 0 1k\nC1 x y 1u\nR2 y x 1k\n.ac dec 1 1 10\n.end\n").frequency_response(
            outputs=["v(x)"])


# -- the command --------------------------------------------------------------------------------------------


def test_the_ac_command_prints_writes_and_checks_against_ngspice(tmp_path, capsys):
    deck = tmp_path / "bw.cir"
    deck.write_text(butterworth("dec 20 10 100k"))
    table, chart = tmp_path / "bw.csv", tmp_path / "bw.png"
    assert main(["ac", str(deck), "-o", "v(n3)", "-o", "i(L2)", "--csv", str(table), "--chart", str(chart),
                 "--ngspice"]) == 0
    out = capsys.readouterr().out
    assert "response to V1, 81 frequencies 10–100000 Hz (dec)" in out
    assert "max rel diff" in out
    worst = max(float(line.split()[1]) for line in out.splitlines() if line.strip().startswith(("v(n3)", "i(L2)"))
                and "e" in line.split()[1])
    assert worst < 1e-9
    rows = list(csv.reader(table.open()))
    assert rows[0] == ["frequency_hz", "v(n3) dB", "v(n3) deg", "i(L2) dB", "i(L2) deg"] and len(rows) == 82
    f, db = float(rows[1 + 20 * 2][0]), float(rows[1 + 20 * 2][1])  # 1 kHz: the cutoff, −3 dB below the ½ of DC
    assert f == pytest.approx(FC) and db == pytest.approx(20 * math.log10(0.5 / math.sqrt(2)), abs=1e-9)
    assert chart.read_bytes().startswith(b"\x89PNG")


def test_the_ac_command_on_a_model_file(tmp_path, capsys):
    source = tmp_path / "isolator.py"
    source.write_text(
        "import lagrangian as lg\n"
        "def build():\n"
        "    m = lg.Model('isolator')\n"
        "    m.add('prescribed_motion', 'base', 'b', position=0)\n"
        "    m.add('mass', 'm', 'p', m=0.3)\n"
        "    m.add('spring', 'k', ('b', 'p'), k=40.0)\n"
        "    m.add('damper', 'c', ('b', 'p'), c=0.5)\n"
        "    return m\n")
    assert main(["ac", f"{source}:build", "--input", "base", "-o", "x_p", "--start", "0.1", "--stop", "10",
                 "--points", "40"]) == 0
    out = capsys.readouterr().out
    line = next(line for line in out.splitlines() if line.strip().startswith("x_p"))
    start, peak, at, stop = map(float, line.split()[1:])
    wn = math.sqrt(40 / 0.3)
    zeta = 0.5 / (2 * math.sqrt(40 * 0.3))

    def closed(f):
        r = 2 * math.pi * f / wn
        return math.sqrt(1 + (2 * zeta * r) ** 2) / math.sqrt((1 - r**2) ** 2 + (2 * zeta * r) ** 2)

    assert start == pytest.approx(closed(0.1), rel=1e-5) and stop == pytest.approx(closed(10), rel=1e-5)  # printed to 6
    grid = sweep("dec", 40, 0.1, 10)
    best = grid[int(np.argmax([closed(f) for f in grid]))]
    assert at == pytest.approx(best, rel=1e-5) and peak == pytest.approx(closed(best), rel=1e-5)


@pytest.mark.parametrize("args, fragment", [
    (["--start", "1e5", "--stop", "10"], "must be below"),
    (["-o", "v(nowhere)"], "nowhere"),
    (["--input", "RL"], "signal"),
])
def test_the_ac_command_reports_bad_requests_in_one_line(tmp_path, capsys, args, fragment):
    deck = tmp_path / "bw.cir"
    deck.write_text(butterworth())
    assert main(["ac", str(deck), *args]) == 1
    err = capsys.readouterr().err
    assert err.startswith("lagrangian: error: ") and fragment in err and "Traceback" not in err


def test_a_dc_bias_and_a_dc_current_do_not_stop_the_small_signal_analysis_of_a_linear_circuit():
    """SPICE linearizes about its DC operating point; a linear circuit's response is the same about any point."""
    text = "bias\nV1 in 0 DC 5 AC 1\nR1 in out 2.2k\nC1 out 0 47n\nL1 out x 10m\nR2 x 0 100\n.ac dec 10 10 100k\n.end\n"
    net = read_netlist(text)
    resp = net.frequency_response(outputs=["v(out)", "i(L1)"])
    run = run_ac(text, {"v(out)": ("v", "out"), "i(L1)": ("i", "l1")})
    for label in resp.outputs:
        assert np.max(np.abs(resp[label] - run.quantities[label]) / np.abs(run.quantities[label])) < 1e-9
    # a nonlinear model is still held to rest: a pendulum away from its equilibria
    m = lg.Model("pendulum", dim=2)
    m.add("rod", "r", "r", m=0.3, length=0.7)
    m.add("revolute", "j", ("ground", "r"), absolute=True)
    m.add("gravity", "g")
    with pytest.raises(lg.ModelError, match="not at rest"):
        lg.frequency.linearize(m, at={"theta_j": 0.3})
