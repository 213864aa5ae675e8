"""Electromechanical models driven by their own circuit's source, against ngspice's AC analysis (real ngspice, no mock).

Under an analogy the circuit of a coupled model is kept as it is, so its voltage source drives the analogue as it
drives the model: every state quantity of the analogue compares, to rounding (1e-9 relative), and each agrees with
the closed form of the transducer's electrical impedance and mechanical mobility.
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import lagrangian as lg
from lagrangian import models
from lagrangian.ac import compare_ac_with_ngspice
from lagrangian.analogy import map_model


def decade(lo, hi):
    return st.floats(np.log10(lo), np.log10(hi)).map(lambda e: float(f"{10 ** e:.4g}"))


def coil_responses(f, R, L, K, m, c, k=0.0):
    """Coil current, velocity and spring force per volt, by hand: the coil sees ``R + jωL + K²/Z_m`` with the
    mechanical impedance ``Z_m = c + jωm + k/(jω)``; the velocity is ``K i / Z_m``, the spring force ``k v / (jω)``."""
    s = 2j * np.pi * f
    Zm = c + s * m + k / s
    i = 1 / (R + s * L + K**2 / Zm)
    v = K * i / Zm
    return i, v, k * v / s


def same_up_to_sign(a, b, tol=1e-9):
    """``a = ±b`` at every frequency, the same sign throughout."""
    r = a / b
    return np.max(np.abs(r - np.sign(r[0].real))) < tol


EPS = np.finfo(float).eps
SPEAKER = dict(Re=6.0, Le=0.5e-3, Bl=7.0, m=0.02, k=2000.0, c=1.5)


def test_a_loudspeaker_driven_by_its_voltage_source_agrees_with_ngspice_on_every_output():
    """The voltage source E is the coil circuit's own: not a prescribed motion, and v(C_k) (the suspension's force)
    compares with the rest."""
    cmp = compare_ac_with_ngspice(models.loudspeaker(**SPEAKER), input="E", analogy="force-voltage",
                                  start=10, stop=2e4, points=20)
    assert [r.label for r in cmp.rows] == ["i(Le)", "i(L_m)", "v(C_k)"] and cmp.input == "E"
    assert cmp.worst_rel < 1e-9, cmp.table()
    i, v, spring = coil_responses(cmp.frequencies, SPEAKER["Re"], SPEAKER["Le"], SPEAKER["Bl"], SPEAKER["m"],
                                  SPEAKER["c"], SPEAKER["k"])
    assert np.max(np.abs(cmp.spice["i(Le)"] / i - 1)) < 1e-9  # a current, not a charge
    assert np.max(np.abs(cmp.ours["i(Le)"] / i - 1)) < 1e-9
    assert same_up_to_sign(cmp.spice["i(L_m)"], v) and same_up_to_sign(cmp.ours["i(L_m)"], v)  # a velocity
    assert same_up_to_sign(cmp.spice["v(C_k)"], spring) and same_up_to_sign(cmp.ours["v(C_k)"], spring)
    analogue = compare_ac_with_ngspice(map_model(models.loudspeaker(**SPEAKER), "force-voltage").model, input="E",
                                       start=10, stop=2e4, points=20)  # mapped first: the same deck, the same outputs
    for label in ("i(Le)", "i(L_m)", "v(C_k)"):
        assert np.max(np.abs(cmp.spice[label] / analogue.spice[label] - 1)) < 1e-12
        assert np.max(np.abs(cmp.ours[label] / analogue.ours[label] - 1)) < 1e-9
    only = compare_ac_with_ngspice(models.loudspeaker(**SPEAKER), input="E", analogy="force-voltage",
                                   outputs=["v(C_k)"], start=10, stop=2e4, points=5)
    assert [r.label for r in only.rows] == ["v(C_k)"] and only.worst_rel < 1e-9, only.table()


@pytest.mark.slow
@settings(max_examples=5)
@given(decade(2.0, 16.0), decade(5e-5, 2e-3), decade(2.0, 20.0), decade(2e-3, 0.1), decade(200.0, 2e4), decade(0.3, 5.0))
def test_loudspeakers_over_decades_agree_with_ngspice(Re, Le, Bl, m, k, c):
    """The currents to 1e-9.  ngspice reads v(C_k) as the difference of two node voltages of the cone's loop, which
    carry its larger inertial and damping forces (far above resonance ωm/(k/ω) reaches 1e8): its rounding is relative
    to those, a few ε of ``|v|(ωm + c + k/ω)``."""
    model = models.loudspeaker(Re=Re, Le=Le, Bl=Bl, m=m, k=k, c=c)
    cmp = compare_ac_with_ngspice(model, input="E", analogy="force-voltage", start=1, stop=1e5, points=10)
    assert [r.label for r in cmp.rows] == ["i(Le)", "i(L_m)", "v(C_k)"]
    rel = {r.label: r.max_rel for r in cmp.rows}
    assert rel["i(Le)"] < 1e-9 and rel["i(L_m)"] < 1e-9, cmp.table()
    f = cmp.frequencies
    i, v, spring = coil_responses(f, Re, Le, Bl, m, c, k)
    w = 2 * np.pi * f
    loop = np.abs(v) * (w * m + c + k / w)
    assert np.all(np.abs(cmp.ours["v(C_k)"] - cmp.spice["v(C_k)"]) <= 1e-9 * np.abs(spring) + 100 * EPS * loop), cmp.table()
    assert np.max(np.abs(cmp.spice["i(Le)"] / i - 1)) < 1e-9
    assert same_up_to_sign(cmp.ours["i(L_m)"], v) and same_up_to_sign(cmp.ours["v(C_k)"], spring)


def test_a_dc_motor_driven_by_its_voltage_source_agrees_with_ngspice():
    """Torque–voltage: the armature current and the shaft's angular velocity per volt."""
    R, L, K, J, b = 1.2, 3e-3, 0.05, 2e-5, 1e-5
    m = lg.Model("dc motor")
    m.add("voltage_source", "E", ("n1", "0"), E=0)
    m.add("resistor", "Ra", ("n1", "n2"), R=R)
    m.add("inductor", "La", ("n2", "n3"), L=L)
    m.add("dc_motor", "M", ("n3", "0", "shaft"), K=K)
    m.add("inertia", "J", "shaft", J=J)
    m.add("rotary_damper", "b", ("ground", "shaft"), c=b)
    cmp = compare_ac_with_ngspice(m, input="E", analogy="torque-voltage", start=0.1, stop=1e4, points=10)
    assert [r.label for r in cmp.rows] == ["i(La)", "i(L_J)"] and cmp.worst_rel < 1e-9, cmp.table()
    i, w, _ = coil_responses(cmp.frequencies, R, L, K, J, b)
    assert np.max(np.abs(cmp.spice["i(La)"] / i - 1)) < 1e-9
    assert same_up_to_sign(cmp.spice["i(L_J)"], w) and same_up_to_sign(cmp.ours["i(L_J)"], w)


def test_inputs_that_do_not_drive_an_analogue_get_clear_errors():
    with pytest.raises(lg.ModelError, match="mass 'm' maps to inductor 'L_m'"):
        compare_ac_with_ngspice(models.loudspeaker(), input="m", analogy="force-voltage")
    rc = lg.Model("rc")
    rc.add("voltage_source", "V1", ("in", "0"), E=0)
    rc.add("resistor", "R1", ("in", "out"), R=2.2e3)
    rc.add("capacitor", "C1", ("out", "0"), C=47e-9)
    with pytest.raises(lg.ModelError, match="circuit already.*without analogy="):
        compare_ac_with_ngspice(rc, input="V1", analogy="force-voltage")
