"""Behavioural sources in SPICE decks: laws written from SymPy, names filled in by the netlist.

Everything here runs the real ngspice shared library through PySpice: no mocks.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

import lagrangian as lg
from lagrangian.spice import Behaviour, SpiceElement, netlist, run_transient, spice_expression


def test_behavioural_laws_are_checked_and_keep_the_sign_of_odd_powers():
    # ngspice's pow(x, n) is |x|^n: an odd power keeps its sign through a factor of its base
    assert spice_expression(sp.sin(lg.t) ** 3) == "(sin(time))*pow(sin(time),2)"
    assert spice_expression(1 / sp.sin(lg.t)) == "1/((sin(time)))"
    with pytest.raises(lg.ModelError, match="sets V or I"):
        Behaviour("Q", lg.t)

    u = sp.Dummy("u")
    model = lg.Model("b")
    model.add("capacitor", "C", ("a", "0"), C=1)
    model.add("inductor", "L", ("a", "0"), L=1)
    model.components["C"].spice = lambda ctx: [SpiceElement("B", ("a", "0"), Behaviour("V", u, ((u, ("i", "nowhere")),)))]
    with pytest.raises(lg.ModelError, match="refers to \\('i', 'nowhere'\\)"):
        netlist(model, t_end=1)


def test_a_behavioural_source_reads_node_voltages_and_odd_powers_keep_their_sign():
    """B V=(v(in))^3 across a resistor in ngspice: −8 V from −2 V (ngspice's own pow(x, 3) would give +8)."""
    v = sp.Dummy("v")
    m = lg.Model("cube")
    m.add("voltage_source", "V1", ("in", "0"), E=-2)
    m.add("resistor", "R1", ("out", "0"), R=1)
    m.add("capacitor", "C1", ("out", "0"), C=1e-3)
    m.add("resistor", "R2", ("in", "0"), R=1)
    m.components["R1"].spice = lambda ctx: [SpiceElement("B", ("out", lg.GROUND), Behaviour("V", v**3, ((v, ("v", "in")),)))]
    net = netlist(m, t_end=1e-3, options={"reltol": 1e-6})
    assert "b_r1 out 0 V=(v(in))*pow(v(in),2)" in net.text and ".options reltol=1e-06" in net.text
    run = run_transient(net, {"out": ("v", "out")})
    assert np.allclose(run.quantities["out"], -8.0)
    with pytest.raises(lg.ModelError, match="option names"):
        netlist(m, t_end=1e-3, options={"reltol=1 .end": 1})
