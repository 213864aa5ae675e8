"""SPICE netlists read into models (``lagrangian.netlist``) and magnetic coupling (kind ``coupling``).

Expected values come from ngspice running the very same netlist text
(through PySpice's shared-library interface), from closed forms derived in
the comments, or from numbers worked out by hand — never from the reader.

ngspice's accuracy follows its step cap h (the ``tmax`` of ``.tran``): its
trapezoidal rule is second order, so its error is about c·h² (c ≈ 0.31 for a
unit series RLC; see ngspice-notes.md).  Each comparison runs two caps, h
and h/2: the gap to our solution (integrated at rtol 1e-12, whose own error
is ~1e-10 of the peak) must shrink about fourfold — so the gap *is*
ngspice's discretization error — and stay under a millionth of the peak at
the finer cap.
"""

from __future__ import annotations

import logging
import math
import re
import warnings

import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

import lagrangian as lg
from lagrangian.netlist import ImportedNetlist, NetlistWarning, Transient, parse_number, read_netlist, read_netlist_file

NgSpiceShared = pytest.importorskip("PySpice.Spice.NgSpice.Shared").NgSpiceShared

TIGHT = {"rtol": 1e-12, "atol": 1e-16}


def ngspice(text: str) -> dict[str, np.ndarray]:
    """Run ``text`` in ngspice; every vector of its (transient) plot by lower-case name."""
    logging.getLogger("PySpice").setLevel(logging.ERROR)
    ng = NgSpiceShared.new_instance()
    ng.load_circuit(text)
    try:
        ng.run()
        plot = ng.plot(None, ng.last_plot)
        return {name.lower(): np.asarray(vec.to_waveform(), dtype=float) for name, vec in plot.items()}
    finally:
        ng.destroy()
        ng.remove_circuit()


def relative_gap(ours: np.ndarray, spice: np.ndarray) -> float:
    return float(np.max(np.abs(ours - spice)) / np.max(np.abs(spice)))


#: Compare on every EVERY-th of ngspice's own time points (tens of thousands of them): the gap is smooth in t.
EVERY = 8


# ---------------------------------------------------------------------------
# A fifth-order LC ladder against ngspice
# ---------------------------------------------------------------------------

# Butterworth prototype g = 0.618, 1.618, 2, 1.618, 0.618 scaled to 50 Ω and
# 1 kHz (C = g/(2π f R), L = g R/(2π f)), driven through its source resistance
# by a delayed, damped, phase-shifted sine; two elements start charged.
LADDER = """5th-order Butterworth low-pass, 50 ohm, 1 kHz
* SIN(vo va freq td theta phase): offset, delay, damping and phase all exercised
V1 in 0 SIN(0.1 1 800 0.25m 50 30)
Rs in n1 50
C1 n1 0 1.967u
L2 n1 n2 12.88mH ic=2m
C3 n2 0 6.366uF IC=0.2
L4 n2 n3 12.88m
+ ic=-1m            ; a continuation line
C5 n3 0 1.967u
RL n3 0 50
.options method=trap
.tran 10u 5m 0 {h} uic
.end
"""


def _ladder_gaps(net: ImportedNetlist, text: str) -> dict[str, float]:
    spice = {name: values[::EVERY] for name, values in ngspice(text).items()}
    res = net.simulate(t_eval=spice["time"], **TIGHT)  # uic: ngspice has no t = 0 row; compare on its own times
    assert np.max(np.abs(spice["n3"])) > 0.3  # the output responds: not two flat lines
    gaps = {c: relative_gap(net.capacitor_voltage(res, c), spice[node]) for c, node in [("C1", "n1"), ("C3", "n2"), ("C5", "n3")]}
    gaps.update({name: relative_gap(net.inductor_current(res, name), spice[f"{name.lower()}#branch"]) for name in ("L2", "L4")})
    return gaps


@pytest.mark.parametrize("formulation", ["charge", "flux"])
def test_ladder_filter_matches_ngspice_running_the_same_netlist(formulation):
    texts = [LADDER.format(h=h) for h in (2e-7, 1e-7)]
    net = read_netlist(texts[0], formulation=formulation)
    # tmax steers only ngspice: both texts read into the same model (read once; reading integrates the source in flux)
    assert net.tran.max_step == 2e-7 and read_netlist(texts[1]).tran.max_step == 1e-7
    coarse, fine = (_ladder_gaps(net, text) for text in texts)
    for element in coarse:
        # halving ngspice's cap divides the gap by ~4: the gap is ngspice's O(h²) error, not a modelling difference
        assert 3.0 < coarse[element] / fine[element] < 5.0, (element, coarse[element], fine[element])
        assert fine[element] < 1e-6, (element, fine[element])


@settings(max_examples=15, deadline=None)
@given(st.floats(-2, 2), st.floats(1e-3, 1e3), st.floats(0.05, 40), st.floats(0, 3), st.floats(0, 4), st.floats(-180, 180),
       st.floats(0.01, 8))
def test_flux_of_a_damped_delayed_sin_source_is_its_integral(vo, va, cycles, delay, damping, phase, t_end):
    """In the flux formulation a voltage source fixes its branch's flux linkage to ∫₀ᵗ E dτ: for SPICE's SIN with
    a delay and a damping (amplitudes, frequencies and times over decades), that integral agrees with SciPy's
    adaptive quadrature of the same waveform, and its rate is the waveform."""
    from scipy.integrate import IntegrationWarning, quad

    scale = 10 ** np.floor(np.log10(t_end))  # the deck's time unit: 1e-2 s to 1 s
    freq, td, theta = (float(f"{x:.6g}") for x in (cycles / (t_end * scale), delay * t_end * scale / 3, damping / (t_end * scale)))
    deck = f"src\nV1 a 0 SIN({vo:.6g} {va:.6g} {freq!r} {td!r} {theta!r} {phase:.6g})\nR1 a b 1\nC1 b 0 1u\n.end\n"
    model = read_netlist(deck, formulation="flux").model
    source = model.components["V1"]
    flux = model.assembly.views["electrical"].branch["V1"]  # λ_a − λ_0 = ∫ (v_a − v_0) = ∫ E
    E, F, rate = (sp.lambdify(lg.t, e, "math") for e in (source.E, flux, sp.diff(flux, lg.t)))
    span = t_end * scale
    for x in np.linspace(0.0, span, 7)[1:]:
        # a breakpoint for the delay's kink; one within round-off of 0 (a subnormal delay) only misleads quad, whose
        # subinterval [0, td] then has no width to sample, and the kink there is below its tolerance anyway
        kinks = [td] if 1e-12 * x < td < x else None
        with warnings.catch_warnings():  # (quad's note that rounding limits it: the agreement below is the check)
            warnings.simplefilter("ignore", IntegrationWarning)
            expected = quad(E, 0.0, x, points=kinks, limit=2000, epsabs=0.0, epsrel=1e-12)[0]
            size = quad(lambda s: abs(E(s)), 0.0, x, points=kinks, limit=2000)[0]
        # (plus the round-off of the closed form's terms, of size va/ω: just past the delay the integral is tiny and
        # 1 − cos(ω(x − td)) cancels)
        roundoff = 1e-14 * (abs(va) / (2 * np.pi * freq) + abs(vo) * x) if freq else 0.0
        assert abs(F(x) - expected) <= 1e-9 * max(size, 1e-300) + roundoff, (x, F(x), expected)
        assert rate(x) == pytest.approx(E(x), rel=1e-9, abs=1e-9 * abs(va))


# ---------------------------------------------------------------------------
# Waveforms: ngspice's values, and values worked out by hand
# ---------------------------------------------------------------------------

VOLTAGES = """voltage waveforms across resistors
V1 a 0 SIN(0.5 2 3 0.2 1.5 30)
R1 a 0 1
V2 b 0 PULSE(1 -2 0.1 0.05 0.1 0.2 0.5)
R2 b 0 1
V3 c 0 PULSE(0 1 0.1)
R3 c 0 1
V4 d 0 PULSE(1 -2 0.1 0.05 0.1 0.2 0.3 1.5)
R4 d 0 1
V5 e 0 sin 0 1
R5 e 0 1
V6 f 0 pulse(0, 1, 0, 0, 0, 0.1, 0.25)
R6 f 0 1
V7 g 0 DC -1.5 AC 1
R7 g 0 1
.tran 10m 1 uic
.end
"""
# I n+ n- drives its current from n+ through itself to n-: into h, out of k
CURRENTS = """current waveforms into resistors
I1 0 h PULSE(0 2 0.1 0.05 0.1 0.2 0.5)
R1 h 0 1
I2 k 0 SIN(0 1 2 0.1)
R2 k 0 1
.tran 10m 1 uic
.end
"""


@pytest.mark.parametrize(
    "text, formulation, probes",
    [
        (VOLTAGES, "charge", [(f"V{i}", node, 1) for i, node in enumerate("abcdefg", start=1)]),
        (CURRENTS, "flux", [("I1", "h", 1), ("I2", "k", -1)]),  # PULSE current sources are loads in node fluxes
    ],
    ids=["voltage", "current"],
)
def test_source_waveforms_match_ngspice(text, formulation, probes):
    """Each source drives a lone 1 Ω resistor, so ngspice's node voltage is ±the source's value at its own time points."""
    spice = ngspice(text)
    net = read_netlist(text, formulation=formulation)
    for name, node, sign in probes:
        comp = net.model.component(name)
        value = sp.lambdify(lg.t, comp.E if name[0] == "V" else comp.I, "numpy")
        ours = np.array([float(value(x)) for x in spice["time"]])
        assert np.max(np.abs(sign * ours - spice[node])) < 1e-12, name


TRAN = Transient(step=0.01, stop=4.0)
# (source, time, value worked out by hand)
HAND = [
    # SIN(vo va f td θ φ): before td, vo + va sin φ
    ("SIN(0.5 2 3 0.2 1.5 30)", 0.1, 0.5 + 2 * 0.5),
    # at td + 1/12: phase 2π·3/12 + π/6 = 2π/3, damping e^(−1.5/12)
    ("SIN(0.5 2 3 0.2 1.5 30)", 0.2 + 1 / 12, 0.5 + 2 * (math.sqrt(3) / 2) * math.exp(-0.125)),
    # at td + 1/6: phase π + π/6, sin = −1/2, damping e^(−0.25)
    ("SIN(0.5 2 3 0.2 1.5 30)", 0.2 + 1 / 6, 0.5 - math.exp(-0.25)),
    # frequency left out: 1/tstop = 0.25 Hz; a quarter period in, sin = 1
    ("SIN(0 1)", 1.0, 1.0),
    ("SIN(0 1)", 3.0, -1.0),
    # PULSE(v1 v2 td tr tf pw per): v1 before td
    ("PULSE(1 -2 0.1 0.05 0.1 0.2 0.5)", 0.05, 1.0),
    # half-way up the rise: 1 + (−3)(0.025/0.05)
    ("PULSE(1 -2 0.1 0.05 0.1 0.2 0.5)", 0.125, -0.5),
    ("PULSE(1 -2 0.1 0.05 0.1 0.2 0.5)", 0.3, -2.0),
    # half-way down the fall (0.05 into a 0.1 fall)
    ("PULSE(1 -2 0.1 0.05 0.1 0.2 0.5)", 0.4, -0.5),
    ("PULSE(1 -2 0.1 0.05 0.1 0.2 0.5)", 0.5, 1.0),
    # second period: 0.725 − 0.1 = 0.625 = 0.5 + 0.125, on the plateau
    ("PULSE(1 -2 0.1 0.05 0.1 0.2 0.5)", 0.725, -2.0),
    # tr, tf left out: tstep = 0.01; pw, per: tstop = 4; half-way up at 0.105
    ("PULSE(0 1 0.1)", 0.105, 0.5),
    ("PULSE(0 1 0.1)", 2.0, 1.0),
    # np = 2 pulses: the third (due at 0.1 + 2·0.3) never comes
    ("PULSE(1 -2 0.1 0.05 0.1 0.2 0.3 2)", 0.5, -2.0),
    ("PULSE(1 -2 0.1 0.05 0.1 0.2 0.3 2)", 0.8, 1.0),
    ("PULSE(1 -2 0.1 0.05 0.1 0.2 0.3)", 0.8, -2.0),
    ("DC 2.5", 1.0, 2.5),
    ("2.5", 1.0, 2.5),
]


@pytest.mark.parametrize("spec, time, expected", HAND)
def test_waveform_values_worked_out_by_hand(spec, time, expected):
    net = read_netlist(f"waveform\nV1 a 0 {spec}\nR1 a 0 1\n.tran {TRAN.step} {TRAN.stop} uic\n")
    value = float(net.model.component("V1").E.subs(lg.t, time))
    assert value == pytest.approx(expected, abs=1e-12)


@pytest.mark.parametrize(
    "text, value",
    [
        ("1", 1.0), ("-2e-3", -2e-3), (".5", 0.5), ("1.", 1.0), ("1f", 1e-15), ("1F", 1e-15), ("2p", 2e-12),
        ("3n", 3e-9), ("4.7u", 4.7e-6), ("10uF", 1e-5), ("5m", 5e-3), ("5M", 5e-3), ("1Mohm", 1e-3),
        ("1k", 1e3), ("2.2K", 2200.0), ("1meg", 1e6), ("1MEG", 1e6), ("3.3Meg", 3.3e6), ("3g", 3e9),
        ("1t", 1e12), ("1mil", 25.4e-6), ("2MIL", 50.8e-6), ("10V", 10.0), ("1e3", 1e3), ("1e-3k", 1.0),
        ("2.5e1m", 0.025), ("12.88mH", 0.01288),
    ],
)  # fmt: skip
def test_spice_numbers_and_unit_suffixes(text, value):
    assert parse_number(text) == value


@pytest.mark.parametrize("text", ["abc", "k1", "1.2.3", "", "--1", "1e3.5", "1x2"])
def test_malformed_numbers_are_refused(text):
    with pytest.raises(ValueError):
        parse_number(text)


# ---------------------------------------------------------------------------
# The deck itself: title, comments, continuations, case, dot commands
# ---------------------------------------------------------------------------

DECK = """
My Title Line
* a comment line
v1 IN 0 dc 5 ; an end-of-line comment
R1 in OUT
+ 2.2K
c1 out 0 10uF IC=1.5
R2 Out GND 1meg
.OPTIONS reltol=1e-4 method=gear noopiter
.TRAN 1u 1m 0 10n UIC
.end
Q9 nothing after .end is read
"""


def test_deck_structure_is_read_as_spice_reads_it():
    net = read_netlist(DECK)
    assert isinstance(net, ImportedNetlist)
    assert net.title == "My Title Line" and net.model.name == "My Title Line"
    assert list(net.model.components) == ["v1", "R1", "c1", "R2"]  # names as written
    comps = net.model.components
    assert comps["R1"].nodes == ("in", "out")  # nodes are case-insensitive
    assert comps["c1"].nodes == ("out", "ground") and comps["R2"].nodes == ("out", "ground")
    assert float(comps["R1"].R) == 2200.0 and float(comps["c1"].C) == 1e-5 and float(comps["R2"].R) == 1e6
    assert float(comps["v1"].E) == 5.0
    assert net.ic == {"c1": 1.5}
    assert net.tran == Transient(step=1e-6, stop=1e-3, start=0.0, max_step=1e-8, uic=True)
    assert net.options == {"reltol": 1e-4, "method": "gear", "noopiter": True}
    assert net.lines == {"v1": 4, "R1": 5, "c1": 7, "R2": 8}


def test_read_netlist_file_names_the_model_after_the_file(tmp_path):
    path = tmp_path / "divider.cir"
    path.write_text(DECK)
    net = read_netlist_file(path)
    assert net.model.name == "divider" and list(net.model.components) == ["v1", "R1", "c1", "R2"]
    with pytest.raises(lg.ModelError, match="cannot read"):
        read_netlist_file(tmp_path / "missing.cir")


# ---------------------------------------------------------------------------
# Initial conditions
# ---------------------------------------------------------------------------

# A source-free series loop a -L1-> b -C1-> 0 -R1-> a with the capacitor at 1 V
# and 0.5 A in the inductor.  KVL: L i' + v + R i = 0 and C v' = i give
# v'' + (R/L) v' + v/(LC) = 0 with v(0) = 1, v'(0) = i(0)/C = 2.  So
# v = e^(−αt) (cos ω t + B sin ω t), α = R/2L = 0.2, ω = √(1/LC − α²) = √3.96,
# B = (v'(0) + α)/ω, and i = C v'.
FREE_RLC = """free RLC decay
L1 a b 1 ic=0.5
C1 b 0 0.25 ic=1
R1 a 0 0.4
.tran 0.01 10 uic
.end
"""


@pytest.mark.parametrize("formulation", ["charge", "flux"])
def test_ic_values_start_capacitor_and_inductor_as_a_closed_form_says(formulation):
    net = read_netlist(FREE_RLC, formulation=formulation)
    res = net.simulate(**TIGHT)
    assert np.array_equal(res.t, net.tran.times) and res.defaulted == []
    alpha, omega = 0.2, math.sqrt(3.96)
    B = (2 + alpha) / omega
    tt = res.t
    v = np.exp(-alpha * tt) * (np.cos(omega * tt) + B * np.sin(omega * tt))
    dv = np.exp(-alpha * tt) * ((B * omega - alpha) * np.cos(omega * tt) - (omega + alpha * B) * np.sin(omega * tt))
    v_ours, i_ours = net.capacitor_voltage(res, "C1"), net.inductor_current(res, "L1")
    assert v_ours[0] == pytest.approx(1.0, abs=1e-12) and i_ours[0] == pytest.approx(0.5, abs=1e-12)
    assert np.max(np.abs(v_ours - v)) < 1e-8
    assert np.max(np.abs(i_ours - 0.25 * dv)) < 1e-8


# C1 sits between x and y; .ic gives v(x) = 2 and nothing for y (0 V), so C1
# starts at 2 V; C2's own ic=0.5 overrides v(z) = 3.  Each capacitor then
# discharges through its resistors: τ1 = (1 + 1)·1 = 2 s, τ2 = 1 s.
DOT_IC = """.ic node voltages
R1 x 0 1
C1 x y 1
R2 y 0 1
C2 z 0 1 ic=0.5
R3 z 0 1
.ic v(x)=2 v(z)=3
.tran 0.01 1 uic
.end
"""


@pytest.mark.parametrize("formulation", ["charge", "flux"])
def test_dot_ic_node_voltages_start_capacitors_and_ic_wins(formulation):
    net = read_netlist(DOT_IC, formulation=formulation)
    assert net.ic == {"C1": 2.0, "C2": 0.5}
    res = net.simulate(**TIGHT)
    assert np.max(np.abs(net.capacitor_voltage(res, "C1") - 2 * np.exp(-res.t / 2))) < 1e-9
    assert np.max(np.abs(net.capacitor_voltage(res, "C2") - 0.5 * np.exp(-res.t))) < 1e-9


def test_dot_ic_matches_ngspice():
    spice = ngspice(DOT_IC.replace(".tran 0.01 1 uic", ".tran 0.01 1 0 1e-4 uic"))
    net = read_netlist(DOT_IC)
    res = net.simulate(t_eval=spice["time"], **TIGHT)
    assert relative_gap(net.capacitor_voltage(res, "C1"), spice["x"] - spice["y"]) < 1e-6
    assert relative_gap(net.capacitor_voltage(res, "C2"), spice["z"]) < 1e-6


def test_initial_values_the_coordinates_cannot_take_are_clear_errors():
    # a node where only C1 and C2 meet: charge conservation ties their charges (C1 v1 = C2 v2) in loop charges
    series_caps = "caps\nR1 a 0 1\nC1 a m 1 ic=1\nC2 m 0 1 ic=0\n.tran 0.1 1 uic\n"
    with pytest.raises(lg.ModelError, match=r"capacitors C1, C2 cannot start.*formulation='flux'"):
        read_netlist(series_caps)
    net = read_netlist(series_caps, formulation="flux")  # node voltages can take them
    res = net.simulate(0.1, points=2)
    assert net.capacitor_voltage(res, "C1")[0] == pytest.approx(1.0) and net.capacitor_voltage(res, "C2")[0] == pytest.approx(0.0)
    # two inductors in series carry one current: they start at the one that keeps their flux, L1 i1 + L2 i2
    series_coils = "coils\nL1 a b 1 ic=1\nL2 b c 3 ic=0.5\nC1 c 0 1\nR1 a 0 1\n.tran 0.1 1 uic\n"
    with pytest.warns(NetlistWarning, match=r"L1 starts at 0.625 A, not 1 A, L2 starts at 0.625 A, not 0.5 A"):
        net = read_netlist(series_coils)
    assert net.inductor_current(net.simulate(0.1, points=2), "L2")[0] == pytest.approx(0.625, rel=1e-12)
    # a capacitor across a voltage source: loop charges cannot hold it (neither inertia nor dissipation)
    across = "across\nV1 a 0 DC 1\nC1 a 0 1 ic=0\nR1 a b 1\nC2 b 0 1\n.tran 0.1 1 uic\n"
    with pytest.raises(lg.ModelError, match=r"neither inertia nor dissipation.*formulation='flux'"):
        read_netlist(across).simulate()


#: A capacitor straight across a source, and two in series across it (node m between them reached by a resistor
#: only), all asked to start at 0 V: the source moves charge through them at t = 0.
ACROSS = """capacitors across a source
V1 a 0 DC 5
C1 a 0 1u ic=0
R1 a b 1k
C2 b 0 2u ic=0
C3 a m 1u ic=0
C4 m 0 2u ic=0
R2 m 0 3k
.tran 10u 20m 0 2u uic
.end
"""


#: A current source feeding two inductors in parallel (each through its resistor), both asked to start at 0 A.
FED = """inductors fed by a current source
I1 0 a DC 3m
L1 a b 1m ic=0
R1 b 0 1k
L2 a c 2m ic=0
R2 c 0 1k
.tran 1n 6u 0 2n uic
.end
"""


def test_inductors_fed_by_a_current_source_start_where_it_puts_them_as_in_ngspice():
    """At t = 0 the source's 3 mA splits so that the flux around the loop L1 R1 R2 L2 stays 0: L1 i1 = L2 i2, so
    i1 = 2 mA and i2 = 1 mA; then they relax to the resistive split, 1.5 mA each, with τ = (L1 + L2)/(R1 + R2):
    i1 = 1.5 + 0.5 e^(−t/τ) mA, as ngspice running the same deck has it."""
    with pytest.warns(NetlistWarning, match=r"L1 starts at 0.002 A, not 0 A, L2 starts at 0.001 A, not 0 A"):
        net = read_netlist(FED)
    assert net.ic == pytest.approx({"L1": 2e-3, "L2": 1e-3})
    spice = ngspice(FED)
    keep = spice["time"] > 0
    res = net.simulate(t_eval=spice["time"][keep], **TIGHT)
    tau = 3e-3 / 2e3
    assert np.max(np.abs(net.inductor_current(res, "L1") - (1.5e-3 + 0.5e-3 * np.exp(-res.t / tau)))) < 1e-14
    assert relative_gap(net.inductor_current(res, "L1"), spice["l1#branch"][keep]) < 1e-6  # measured 1.4e-8


def test_capacitors_across_a_source_start_where_the_source_puts_them_as_in_ngspice():
    """C1 starts at the source's 5 V; C3 and C4 in series take the same charge Δq = 5 V / (1/C3 + 1/C4), so
    v(m) jumps to Δq/C4 = 5/3 V and then relaxes through R2 with τ = R2 (C3 + C4) toward 0; C2 (behind R1) starts
    at its 0 V and charges with τ = R1 C2.  Our run agrees with ngspice running the same deck."""
    with pytest.warns(NetlistWarning, match=r"C1 starts at 5 V, not 0 V.*C3 starts at 3.33333 V.*C4 starts at 1.66667 V"):
        net = read_netlist(ACROSS, formulation="flux")
    assert net.ic == pytest.approx({"C1": 5.0, "C2": 0.0, "C3": 10 / 3, "C4": 5 / 3})
    spice = ngspice(ACROSS)
    keep = spice["time"] > 0
    res = net.simulate(t_eval=spice["time"][keep], **TIGHT)
    t = res.t
    assert np.max(np.abs(net.capacitor_voltage(res, "C4") - 5 / 3 * np.exp(-t / (3e3 * 3e-6)))) < 1e-9
    assert np.max(np.abs(net.capacitor_voltage(res, "C2") - 5 * (1 - np.exp(-t / (1e3 * 2e-6))))) < 1e-9
    assert relative_gap(net.capacitor_voltage(res, "C4"), spice["m"][keep]) < 1e-6  # measured 1.4e-9
    assert relative_gap(net.capacitor_voltage(res, "C2"), spice["b"][keep]) < 1e-6  # measured 2.8e-8


DC_START = """dc start
V1 in 0 SIN(5 1 200)
R1 in a 100
L1 a b 10m
C1 b 0 10u
R2 b 0 470
I1 0 b DC 2m
.tran 10u 10m
.end
"""


def test_tran_without_uic_starts_from_the_dc_operating_point_as_ngspice_does():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        net = read_netlist(DC_START)
    # by hand: L1 shorted, C1 open: v(b) = (5/(R1) + I)/(1/R1 + 1/R2) with R1 = 100, R2 = 470, I = 2 mA into b
    vb = (5 / 100 + 2e-3) / (1 / 100 + 1 / 470)
    assert net.ic["C1"] == pytest.approx(vb, rel=1e-12) and net.ic["L1"] == pytest.approx((5 - vb) / 100, rel=1e-12)
    spice = ngspice(DC_START)
    res = net.simulate(t_eval=spice["time"][::EVERY], method="exact")
    assert net.capacitor_voltage(res, "C1")[0] == pytest.approx(spice["b"][0], rel=1e-9)
    assert net.inductor_current(res, "L1")[0] == pytest.approx(spice["l1#branch"][0], rel=1e-9)
    assert relative_gap(net.capacitor_voltage(res, "C1"), spice["b"][::EVERY]) < 1e-4  # ngspice's default steps


def test_without_uic_a_held_node_and_ignored_ic_values_follow_spice():
    held = "held\nV1 a 0 DC 1\nR1 a b 1k\nC1 b 0 1u\nR2 b 0 1k\n.ic v(b)=0.2\n.tran 10u 5m\n.end\n"
    net = read_netlist(held)
    spice = ngspice(held)
    assert net.ic["C1"] == pytest.approx(0.2, rel=1e-12) == pytest.approx(spice["b"][0], rel=1e-9)
    res = net.simulate(t_eval=spice["time"][::EVERY], method="exact")
    assert relative_gap(net.capacitor_voltage(res, "C1"), spice["b"][::EVERY]) < 1e-4
    with pytest.warns(NetlistWarning, match="ic= values are ignored"):
        net = read_netlist(FREE_RLC.replace(" uic", ""))
    assert all(value == 0.0 for value in net.ic.values())  # no source: the operating point is at rest
    with pytest.raises(lg.ModelError, match=r"no DC operating point.*\bm\b"):
        read_netlist("floating\nV1 a 0 DC 1\nC1 a m 1u\nC2 m 0 1u\nR1 a 0 1k\n.tran 1u 1m\n.end\n")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        read_netlist(FREE_RLC)  # uic: its ic= values, quietly


# ---------------------------------------------------------------------------
# Coupled inductors (K)
# ---------------------------------------------------------------------------

# Two equal LC tanks (L = 1 mH, C = 1 µF) coupled by k.  With both currents
# from the dotted first node through the coil, T = ½L i1² + ½L i2² + kL i1 i2:
# the symmetric mode (v1 = v2) has inductance L(1 + k), the antisymmetric one
# L(1 − k), so ω± = 1/√(LC(1 ± k)).  From v1 = 1, v2 = 0 at rest each mode
# carries half: v1 = ½(cos ω+ t + cos ω− t), v2 = ½(cos ω+ t − cos ω− t) —
# the sign of v2 is the dot convention.
TANKS = """coupled tanks
L1 a 0 1m
C1 a 0 1u ic={v1}
L2 b 0 1m
C2 b 0 1u ic={v2}
K1 L1 L2 {k}
.tran 1u 1m uic
.end
"""


@pytest.mark.parametrize("formulation", ["charge", "flux"])
@pytest.mark.parametrize("v1, v2", [(1, 1), (1, -1), (1, 0)], ids=["symmetric", "antisymmetric", "beat"])
def test_coupled_tanks_oscillate_at_the_normal_mode_frequencies(formulation, v1, v2):
    k, L, C = 0.3, 1e-3, 1e-6
    net = read_netlist(TANKS.format(v1=v1, v2=v2, k=k), formulation=formulation)
    res = net.simulate(**TIGHT)
    w_plus, w_minus = 1 / math.sqrt(L * C * (1 + k)), 1 / math.sqrt(L * C * (1 - k))
    s, d = (v1 + v2) / 2, (v1 - v2) / 2  # amplitudes of the symmetric and antisymmetric modes
    expected1 = s * np.cos(w_plus * res.t) + d * np.cos(w_minus * res.t)
    expected2 = s * np.cos(w_plus * res.t) - d * np.cos(w_minus * res.t)
    assert np.max(np.abs(net.capacitor_voltage(res, "C1") - expected1)) < 1e-7
    assert np.max(np.abs(net.capacitor_voltage(res, "C2") - expected2)) < 1e-7


@pytest.mark.parametrize("formulation", ["charge", "flux"])
def test_coupled_coils_start_at_their_ic_currents(formulation):
    """Currents 2 mA and −1 mA, capacitors at 0 V: each mode keeps its share, i1 = s cos ω+t + d cos ω−t, i2 = s cos ω+t − d cos ω−t.

    (In the flux formulation this needs the coils' flux linkages λ = L i + M i_other.)
    """
    k, L, C = 0.3, 1e-3, 1e-6
    text = TANKS.format(v1=0, v2=0, k=k).replace("L1 a 0 1m", "L1 a 0 1m ic=2m").replace("L2 b 0 1m", "L2 b 0 1m ic=-1m")
    net = read_netlist(text, formulation=formulation)
    res = net.simulate(**TIGHT)
    w_plus, w_minus = 1 / math.sqrt(L * C * (1 + k)), 1 / math.sqrt(L * C * (1 - k))
    s, d = 0.5e-3, 1.5e-3
    i1, i2 = net.inductor_current(res, "L1"), net.inductor_current(res, "L2")
    assert i1[0] == pytest.approx(2e-3, abs=1e-15) and i2[0] == pytest.approx(-1e-3, abs=1e-15)
    assert np.max(np.abs(i1 - (s * np.cos(w_plus * res.t) + d * np.cos(w_minus * res.t)))) < 1e-10
    assert np.max(np.abs(i2 - (s * np.cos(w_plus * res.t) - d * np.cos(w_minus * res.t)))) < 1e-10


# The second coil reversed (its dot at ground), unequal tanks, a load, and
# an ideal (k = 1) transformer kept solvable by a leakage inductor Ls in
# series with L1 (node x, between two coils only, has no capacitance: that
# needs loop charges).
LEAKY = "L1 x 0 1m\nLs a x 0.1m"
TRANSFORMER = """coupled coils
{coil}
C1 a 0 1u ic=1
L2 0 b 2m
C2 b 0 0.5u
Rl b 0 1k
K1 L1 L2 {k}
.tran 1u 1m 0 {h} uic
.end
"""


@pytest.mark.parametrize(
    "k, formulation", [(0.3, "charge"), (0.3, "flux"), (1, "charge")], ids=["k0.3-charge", "k0.3-flux", "ideal-charge"]
)
def test_coupled_coils_match_ngspice_dot_convention_included(k, formulation):
    gaps = []
    for h in (2e-8, 1e-8):
        text = TRANSFORMER.format(k=k, h=h, coil=LEAKY if k == 1 else "L1 a 0 1m")
        spice = {name: values[::EVERY] for name, values in ngspice(text).items()}
        net = read_netlist(text, formulation=formulation)
        res = net.simulate(t_eval=spice["time"], **TIGHT)
        gaps.append(
            [relative_gap(net.capacitor_voltage(res, c), spice[n]) for c, n in [("C1", "a"), ("C2", "b")]]
            + [relative_gap(net.inductor_current(res, name), spice[f"{name.lower()}#branch"]) for name in ("L1", "L2")]
        )
    coarse, fine = np.array(gaps)
    assert np.all((3.0 < coarse / fine) & (coarse / fine < 5.0)), (coarse, fine)
    # ngspice's error goes as (ω h)²: the tanks' modes are at ω ≤ 3.8e4 rad/s, but the ideal transformer's
    # leakage mode is at 1.43e5 rad/s (eigenvalues of K = diag(1/C1, 1/C2) over M = [[L1+Ls, √(L1L2)], [√(L1L2), L2]]),
    # (1.43e5/3.8e4)² ≈ 14 times more error at the same cap
    assert np.all(fine < (3e-5 if k == 1 else 1e-6)), fine


def test_coupling_mistakes_are_clear_errors():
    tanks = TANKS.format(v1=1, v2=0, k=1)
    # perfect coupling of two tanks: nothing fixes the split of current between the coils
    with pytest.raises(lg.ModelError, match=r"coupling 'K1': k = 1 .*singular.*leakage"):
        read_netlist(tanks)
    # the flux formulation needs the inverse inductance matrix, which k = 1 does not have
    with pytest.raises(lg.ModelError, match=r"coupling 'K1'.*singular.*formulation='charge'"):
        read_netlist(tanks, formulation="flux")
    with pytest.raises(lg.ParameterError, match=r"'K1', parameter 'k'.*must be in \(0, 1\].*line 6"):
        read_netlist(TANKS.format(v1=1, v2=0, k=1.2))
    with pytest.raises(lg.ModelError, match=r"line 6 \(K1\).*'L9'.*inductors: L1, L2"):
        read_netlist(TANKS.format(v1=1, v2=0, k=0.5).replace("K1 L1 L2", "K1 L1 L9"))
    with pytest.raises(lg.ModelError, match=r"couplings 'K1' and 'K2' both couple L1 and L2"):
        read_netlist(TANKS.format(v1=1, v2=0, k=0.5).replace(".tran", "K2 L2 L1 0.1\n.tran"))
    # through the Python API: an unknown name, a non-inductor, a name that is not a name
    m = lg.Model("tanks")
    m.add("inductor", "L1", ("a", "0"), L=1)
    m.add("capacitor", "C1", ("a", "0"), C=1)
    m.add("coupling", "K1", inductor1="L1", inductor2="Lx", k=0.5)
    with pytest.raises(lg.UnknownNameError, match=r"coupling 'K1', parameter 'inductor2': unknown inductor 'Lx'"):
        m.eq  # noqa: B018
    m2 = lg.Model("tanks")
    m2.add("inductor", "L1", ("a", "0"), L=1)
    m2.add("capacitor", "C1", ("a", "0"), C=1)
    m2.add("coupling", "K1", inductor1="L1", inductor2="C1", k=0.5)
    with pytest.raises(lg.ParameterError, match=r"'C1' is a capacitor, not an inductor"):
        m2.eq  # noqa: B018
    with pytest.raises(lg.ParameterError, match="name of a component"):
        lg.Model().add("coupling", "K2", inductor1=3, inductor2="L1", k=0.5)
    with pytest.raises(lg.ParameterError, match="with itself"):
        lg.Model().add("coupling", "K2", inductor1="L1", inductor2="L1", k=0.5)


def test_three_coils_with_impossible_coupling_coefficients_are_refused():
    m = lg.Model("three coils")
    for i in (1, 2, 3):
        m.add("inductor", f"L{i}", (f"n{i}", "0"), L=1)
        m.add("capacitor", f"C{i}", (f"n{i}", "0"), C=1)
    # k12 = k23 = 0.9 force coils 1 and 3 to be strongly coupled too; k13 = 0.1 is impossible (indefinite L)
    m.add("coupling", "K12", inductor1="L1", inductor2="L2", k=0.9)
    m.add("coupling", "K23", inductor1="L2", inductor2="L3", k=0.9)
    m.add("coupling", "K13", inductor1="L1", inductor2="L3", k=0.1)
    with pytest.raises(lg.ModelError, match="indefinite"):
        m.eq  # noqa: B018


@pytest.mark.parametrize("formulation", ["charge", "flux"])
def test_three_coil_transformer_energy_is_half_i_L_i(formulation):
    """Both formulations give the magnetic energy ½ iᵀ L i of a three-winding transformer (L built by hand)."""
    Lm = np.array([[1.0, 0.5 * math.sqrt(2), 0.2 * math.sqrt(3)], [0.5 * math.sqrt(2), 2.0, 0.0], [0.2 * math.sqrt(3), 0.0, 3.0]])
    m = lg.Model("three coils", formulation=formulation)
    for i, L in enumerate((1, 2, 3), start=1):
        m.add("inductor", f"L{i}", (f"n{i}", "0"), L=L)
        m.add("capacitor", f"C{i}", (f"n{i}", "0"), C=1)
    m.add("coupling", "K12", inductor1="L1", inductor2="L2", k=0.5)
    m.add("coupling", "K13", inductor1="L1", inductor2="L3", k=0.2)
    current = np.array([0.3, -0.7, 1.1])
    names = [f"q_L{i}" for i in (1, 2, 3)] if formulation == "charge" else [f"lambda_n{i}" for i in (1, 2, 3)]
    zero = dict.fromkeys(names, 0.0)
    if formulation == "charge":  # the currents are the coordinates' rates
        res = m.simulate(1e-9, initial=zero, velocity=dict(zip(names, current)), points=2)
        magnetic = res.T[0]
    else:  # the coordinates are the coils' flux linkages λ = L i
        res = m.simulate(1e-9, initial=dict(zip(names, Lm @ current)), velocity=zero, points=2)
        magnetic = res.V[0]
    assert magnetic == pytest.approx(0.5 * current @ Lm @ current, rel=1e-12)


# ---------------------------------------------------------------------------
# What the reader refuses, and where
# ---------------------------------------------------------------------------

BASE = "title\nV1 a 0 1\nR1 a b 1\n{line}\nC1 b 0 1\n.end\n"  # the line under test is line 4


@pytest.mark.parametrize(
    "line, words",
    [
        ("D1 b 0 dmod", "D1.*diode"),
        ("Q1 b a 0 npn", "Q1.*bipolar transistor"),
        ("M1 b a 0 0 nmos", "M1.*MOSFET"),
        ("X1 a b filter", "X1.*subcircuit"),
        ("E1 b 0 a 0 2", "E1.*voltage-controlled voltage source"),
        ("G1 b 0 a 0 1m", "G1.*voltage-controlled current source"),
        ("B1 b 0 V=1", "B1.*behavioural"),
        ("V2 b 0 AC 1 x", "V2.*unexpected 'x'"),
        ("V2 b 0 PWL(0 0 1 1)", "V2.*PWL"),
        ("V2 b 0 EXP(0 1)", "V2.*EXP"),
        ("R2 b 0 {rval}", "R2.*parameter expressions"),
        ("R2 b 0 1k tc1=0.1", "R2.*unsupported resistance parameters"),
        (".subckt filter a b", r"\.subckt"),
        (".param rval=1k", r"\.param"),
        (".include models.lib", r"\.include"),
        (".noise v(b) V1 dec 10 1 1k", "only transient.*small-signal"),
        (".ac dec 10 1k 1", "fstart ≤ fstop"),
        (".ac log 10 1 1k", "dec\\|oct\\|lin"),
    ],
)
def test_unsupported_input_is_refused_naming_the_line_and_what_is_supported(line, words):
    with pytest.raises(lg.ModelError) as info:
        read_netlist(BASE.format(line=line))
    message = str(info.value)
    assert re.search(r"line 4\b", message), message
    assert re.search(words, message), message
    if not line.startswith(("R2", "V2 b 0 AC")):
        assert "Supported:" in message and "PULSE" in message, message


@pytest.mark.parametrize(
    "line, words",
    [
        ("R2 b 0", "expected a resistance"),
        ("R2 b", "expected 'R2 <node\\+> <node->"),
        ("R2 b 0 1x2", "expected a number for the resistance, got '1x2'"),
        ("R2 b 0 1e999", "got '1e999', which is beyond a float's range"),
        ("V2 b 0 PULSE(1 -2 -1e999ohm 0.05 0.1 0.2 0.5)", "got '-1e999ohm', which is beyond a float's range"),
        ("C2 b 0 1u ic", "unsupported capacitance parameters 'ic'"),
        ("L2 b 0 1m ic=x", "expected a number for ic"),
        ("V2 b 0 SIN(0 1", r"SIN\( is not closed"),
        ("V2 b 0 SIN(0)", "SIN takes 2 to 6 values, got 1"),
        ("V2 b 0 SIN(0 1 x)", "expected a number in SIN"),
        ("V2 b 0 PULSE(0 1 0 0 0 1 2 3 4)", "PULSE takes 2 to 8 values, got 9"),
        ("V2 b 0 DC", "'DC' needs a value"),
        ("V2 b 0 1 2", "unexpected '2'"),
        (".tran 1m", "expected '.tran tstep tstop"),
        (".tran 1m 0", "tstop > tstart"),
        (".ic v(b)", "expected 'v\\(node\\)=value'"),
        ("K1 L1 L2 0.5", "'L1', which is not an inductor of this netlist"),
        ("K1 L1", "expected 'K<name> <inductor1> <inductor2> <k>'"),
        ("r1 b 0 2", "same name as 'R1' on line 3"),
        ("R2 b ground 1", "'ground' is an ordinary node name in SPICE"),
        ("R2 b 0 0", "'R2', parameter 'R': must be positive.*line 4"),
    ],
)
def test_malformed_lines_are_refused_naming_the_line(line, words):
    with pytest.raises(lg.ModelError) as info:
        read_netlist(BASE.format(line=line))
    message = str(info.value)
    assert re.search(r"line 4\b", message), message
    assert re.search(words, message), message


def test_a_continuation_with_nothing_to_continue_and_a_pulse_that_cannot_be_integrated():
    with pytest.raises(lg.ModelError, match=r"line 2: a continuation line"):
        read_netlist("title\n+ R1 a 0 1\n")
    pulse = "pulse\nV1 a 0 PULSE(0 1 0 1m 1m 5m 10m)\nR1 a b 1\nC1 b 0 1\n.tran 1m 20m uic\n"
    with pytest.raises(lg.ModelError, match=r"line 2 \(V1\).*PULSE.*formulation='charge'"):
        read_netlist(pulse, formulation="flux")
    with pytest.raises(lg.ModelError, match=r"line 2 \(V1\).*defaults to the .tran"):
        read_netlist(pulse.replace(" 1m 1m 5m 10m", "").replace(".tran 1m 20m uic\n", ""))
    assert read_netlist(pulse).model.coordinate_names == ["q_R1"]  # fine as a load in loop charges


def _kinds_and_values(model):
    """(kind, nodes, {parameter: value at t = 0.7}) of every component, sorted."""
    out = []
    for c in model.components.values():
        values = {k: float(v.subs(lg.t, 0.7)) for k, v in c.params.items() if isinstance(v, sp.Expr)}
        out.append((c.kind, tuple(n.lower() for n in c.nodes), values))
    return sorted(out, key=lambda item: (item[0], item[1]))


@pytest.mark.parametrize("formulation", ["charge", "flux"])
@pytest.mark.slow
def test_export_then_import_gives_the_same_model(formulation):
    """lagrangian.spice.netlist writes the model; read_netlist reads it back: same elements, same response."""
    from lagrangian.spice import netlist as export

    m = lg.Model("round trip", formulation=formulation)
    m.add("voltage_source", "V1", ("in", "0"), E=sp.Rational(1, 2) + 2 * sp.sin(3 * lg.t))
    m.add("resistor", "R1", ("in", "a"), R=1.5)
    m.add("inductor", "L1", ("a", "b"), L=0.25)
    m.add("capacitor", "C1", ("b", "0"), C=0.5)
    m.add("inductor", "L2", ("b", "0"), L=2)
    m.add("coupling", "K1", inductor1="L1", inductor2="L2", k=0.3)
    m.add("current_source", "I1", ("0", "b"), I=0.1)
    names = m.coordinate_names
    initial = {n: 0.01 * (i + 1) for i, n in enumerate(names)}
    velocity = {n: 0.02 for n in names if n not in m.first_order}
    exported = export(m, initial=initial, velocity=velocity, t_end=5, step=0.01)
    back = read_netlist(exported.text, formulation=formulation)

    ours, theirs = _kinds_and_values(m), _kinds_and_values(back.model)
    assert [(k, n) for k, n, _ in theirs] == [(k, n) for k, n, _ in ours]
    for (_, _, a), (_, _, b) in zip(ours, theirs):
        assert b == pytest.approx(a, rel=1e-13)
    # the same response: every capacitor voltage and inductor current, from the exported initial state
    grid = np.linspace(0, 5, 501)
    a = m.simulate(5, initial=initial, velocity=velocity, t_eval=grid, rtol=1e-11, atol=1e-13)
    b = back.simulate(5, t_eval=grid, rtol=1e-11, atol=1e-13)
    assert set(exported.quantities) == {"v(C1)", "i(L1)", "i(L2)"}
    for label, expr in exported.quantities.items():
        ours = a.quantity(expr)
        name = label[2:-1].lower()
        theirs = back.capacitor_voltage(b, name) if label.startswith("v") else back.inductor_current(b, name)
        assert np.ptp(ours) > 0.01
        assert np.allclose(ours, theirs, atol=1e-9)
