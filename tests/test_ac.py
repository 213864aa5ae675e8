"""Frequency responses against ngspice's AC analysis, through PySpice (real ngspice, no mock).

Both sides are exact linear algebra, so they must agree to rounding: 1e-9 relative on every output.
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import lagrangian as lg
from lagrangian.ac import compare_ac_with_ngspice
from lagrangian.netlist import read_netlist


def decade(lo, hi):
    return st.floats(np.log10(lo), np.log10(hi)).map(lambda e: float(f"{10 ** e:.4g}"))


def series_rlc(formulation):
    m = lg.Model("series rlc", formulation=formulation)
    m.add("voltage_source", "V1", ("in", "0"), E=0)
    m.add("resistor", "R1", ("in", "a"), R=10.0)
    m.add("inductor", "L1", ("a", "b"), L=7e-3)
    m.add("capacitor", "C1", ("b", "0"), C=2.2e-6)
    return m


@pytest.mark.parametrize("formulation", ["charge", "flux"])
def test_series_rlc_agrees_with_ngspice_on_every_output(formulation, tmp_path):
    outputs = ["v(C1)", "v(R1)", "v(L1)", "i(L1)"] + (["i(V1)"] if formulation == "charge" else [])
    cmp = compare_ac_with_ngspice(series_rlc(formulation), input="V1", outputs=outputs, start=10, stop=1e6, points=20)
    assert [r.label for r in cmp.rows] == outputs
    assert len(cmp.frequencies) == 101 and cmp.frequencies[0] == pytest.approx(10) and cmp.frequencies[-1] == pytest.approx(1e6)
    assert cmp.worst_rel < 1e-9, cmp.table()
    # the resonance is where the closed form puts it, on both sides
    f0 = 1 / (2 * np.pi * np.sqrt(7e-3 * 2.2e-6))
    peak = cmp.frequencies[np.argmax(np.abs(cmp.spice["i(L1)"]))]
    assert abs(np.log10(peak / f0)) <= 0.5 / 20
    assert "max rel diff" in cmp.table()
    assert cmp.chart(tmp_path / "ac.png").stat().st_size > 10_000


def test_coupled_tanks_driven_by_a_current_source_agree_with_ngspice():
    m = lg.Model("coupled tanks", formulation="flux")
    m.add("current_source", "I1", ("0", "n1"), I=0)
    for i, (L, C, R) in enumerate([(7e-3, 2.2e-6, 150.0), (4.7e-3, 3.3e-6, 220.0)], start=1):
        m.add("inductor", f"L{i}", (f"n{i}", "0"), L=L)
        m.add("capacitor", f"C{i}", (f"n{i}", "0"), C=C)
        m.add("resistor", f"R{i}", (f"n{i}", "0"), R=R)
    m.add("coupling", "K1", inductor1="L1", inductor2="L2", k=0.4)
    cmp = compare_ac_with_ngspice(m, input="I1", outputs=["v(C1)", "v(C2)", "i(L1)", "i(L2)"], start=50, stop=5e4, points=40)
    assert cmp.worst_rel < 1e-9, cmp.table()


@settings(max_examples=8)
@given(st.integers(2, 6), st.lists(st.tuples(decade(1.0, 1e3), decade(1e-6, 1e-1), decade(1e-9, 1e-4)), min_size=6, max_size=6))
def test_random_rlc_ladders_agree_with_ngspice(sections, values):
    m = lg.Model("ladder")
    m.add("voltage_source", "V1", ("in", "0"), E=0)
    prev = "in"
    for k, (R, L, C) in enumerate(values[:sections]):
        m.add("resistor", f"R{k}", (prev, f"m{k}"), R=R)
        m.add("inductor", f"L{k}", (f"m{k}", f"n{k}"), L=L)
        m.add("capacitor", f"C{k}", (f"n{k}", "0"), C=C)
        prev = f"n{k}"
    w = [1 / np.sqrt(L * C) / (2 * np.pi) for _, L, C in values[:sections]]
    cmp = compare_ac_with_ngspice(m, input="V1", start=min(w) / 100, stop=max(w) * 100, points=10)
    # relative to each output's own size, where ngspice's rounding is not larger than the response itself
    for r in cmp.rows:
        ours, theirs = cmp.ours[r.label], cmp.spice[r.label]
        scale = np.maximum(np.abs(theirs), 1e-9 * np.abs(theirs).max())
        assert np.max(np.abs(ours - theirs) / scale) < 1e-9, cmp.table()


def test_an_imported_netlist_agrees_with_ngspice():
    net = read_netlist("""band-pass
V1 in 0 DC 0
R1 in a 1k
C1 a b 100n
L1 b out 10m
R2 out 0 470
C2 out 0 22n
.end""")
    cmp = compare_ac_with_ngspice(net.model, input="V1", outputs=["v(R2)", "v(C1)", "i(L1)"], start=100, stop=1e6, points=25)
    assert cmp.worst_rel < 1e-9, cmp.table()


def test_bad_requests_get_clear_errors():
    m = series_rlc("charge")
    with pytest.raises(lg.ModelError, match="voltage or current source"):
        compare_ac_with_ngspice(m, input="R1")
    with pytest.raises(lg.UnknownNameError, match="V9"):
        compare_ac_with_ngspice(m, input="V9")
    with pytest.raises(lg.ModelError, match="start < stop"):
        compare_ac_with_ngspice(m, input="V1", start=1e3, stop=10)
    with pytest.raises(lg.ModelError, match="positive frequency"):
        compare_ac_with_ngspice(m, input="V1", start=float("nan"))
    with pytest.raises(lg.ModelError, match="v\\(R1\\)"):
        compare_ac_with_ngspice(m, input="V1", outputs=["i(R1)"])
    with pytest.raises(lg.ModelError, match="'v\\(X\\)'"):
        compare_ac_with_ngspice(m, input="V1", outputs=["x_p"])


def test_a_long_ladder_solved_banded_agrees_with_ngspice_and_with_the_dense_solve(monkeypatch):
    import lagrangian.analysis.frequency as frequency
    import lagrangian.analysis.laplace as laplace

    rng = np.random.default_rng(7)
    m = lg.Model("ladder60")
    m.add("voltage_source", "V1", ("in", "0"), E=0)
    prev = "in"
    for k in range(60):
        m.add("resistor", f"R{k}", (prev, f"m{k}"), R=float(f"{rng.uniform(0.2, 1):.3g}"))
        m.add("inductor", f"L{k}", (f"m{k}", f"n{k}"), L=float(f"{rng.uniform(0.5, 2):.3g}"))
        m.add("capacitor", f"C{k}", (f"n{k}", "0"), C=float(f"{rng.uniform(0.2, 1):.3g}"))
        prev = f"n{k}"
    lin = frequency.linearize(m, inputs=["V1"], outputs=["i(L0)", "v(C59)", "v(n30)"])
    assert lin.size >= laplace.BANDED_MIN and laplace._band(lin) is not None
    cmp = compare_ac_with_ngspice(m, input="V1", outputs=["i(L0)", "v(C59)", "v(n30)"], start=1e-3, stop=1.0, points=100)
    assert cmp.worst_rel < 1e-9, cmp.table()
    banded = frequency.frequency_response(lin, cmp.frequencies).H
    monkeypatch.setattr(laplace, "BANDED_MIN", 10**9)
    dense = frequency.frequency_response(lin, cmp.frequencies).H
    floor = 1e-12 * np.abs(dense).max(axis=-1, keepdims=True)
    assert np.max(np.abs(banded - dense) / np.maximum(np.abs(dense), floor)) < 1e-10


@pytest.mark.parametrize("analogy", ["force-voltage", "force-current"])
def test_a_mechanisms_analogue_in_ngspice_agrees_with_the_mechanism(analogy):
    """Driven by a force, every state quantity of the analogue; driven by a base motion, the mass's velocity."""
    m = lg.Model("oscillator")
    m.add("mass", "m", "p", m=0.3)
    m.add("spring", "k", ("ground", "p"), k=40.0)
    m.add("damper", "c", ("ground", "p"), c=0.5)
    m.add("force", "F", "p", F=0)
    cmp = compare_ac_with_ngspice(m, input="F", analogy=analogy, start=0.1, stop=100, points=20)
    assert len(cmp.rows) == 2 and cmp.worst_rel < 1e-9, cmp.table()
    velocity = "i(L_m)" if analogy == "force-voltage" else "v(C_m)"
    f = cmp.frequencies
    mobility = 1 / (0.5 + 2j * np.pi * f * 0.3 + 40.0 / (2j * np.pi * f))  # v / F, by hand
    assert np.max(np.abs(cmp.spice[velocity] / mobility - 1)) < 1e-9
    base = lg.Model("isolator")
    base.add("prescribed_motion", "base", "b", position=0)
    base.add("mass", "m", "p", m=0.3)
    base.add("spring", "k", ("b", "p"), k=40.0)
    base.add("damper", "c", ("b", "p"), c=0.5)
    cmp = compare_ac_with_ngspice(base, input="base", analogy=analogy, start=0.1, stop=100, points=20)
    assert [r.label for r in cmp.rows] == [velocity] and cmp.worst_rel < 1e-9, cmp.table()
    spring = "v(C_k)" if analogy == "force-voltage" else "i(L_k)"
    with pytest.raises(lg.ModelError, match="velocities"):
        compare_ac_with_ngspice(base, input="base", analogy=analogy, outputs=[spring], start=0.1, stop=100, points=20)
