"""compare_with_ngspice on a model with symbolic parameters gives their values to the circuit analogue too.

The reference is ngspice running the analogue, and the same comparison of
the model built with the numbers themselves.
"""

import numpy as np
import sympy as sp

import lagrangian as lg
from lagrangian.compare import compare_with_ngspice


def oscillator(m, k, c):
    model = lg.Model("msd")
    model.add("mass", "m", "cart", m=m)
    model.add("spring", "k", ("ground", "cart"), k=k)
    model.add("damper", "c", ("ground", "cart"), c=c)
    model.add("force", "F", "cart", F=sp.sin(1.5 * lg.t))
    return model


def test_symbolic_parameters_reach_the_analogue_and_agree_with_the_numeric_model():
    values = {"m": 0.3, "k": 40.0, "c": 0.05}
    symbols = {name: sp.Symbol(name, positive=True) for name in values}
    state = {"initial": {"x_cart": 0.01}, "velocity": {"x_cart": 0.0}}
    both = [compare_with_ngspice(model, 2, analogy="force-voltage", max_step=1e-4, params=params, **state)
            for model, params in ((oscillator(**symbols), values), (oscillator(**values), None))]
    for cmp in both:
        assert cmp.worst_rel < 1e-4, cmp.table()
    for a, b in zip(both[0].rows, both[1].rows):
        np.testing.assert_allclose(both[0].spice[a.label], both[1].spice[b.label], rtol=1e-9, atol=1e-12)


def test_a_source_waveform_with_symbols_takes_their_values_in_the_deck():
    """V = E sin(ω t) with E and ω symbols: the deck's SIN source gets the values, and ngspice agrees with the model
    and with the model given the numbers (RC: τ = 1 ms, ω = 2π·200 rad/s)."""
    E, w = sp.symbols("E omega", positive=True)

    def rc(amplitude, rate):
        model = lg.Model("rc")
        model.add("voltage_source", "V1", ("in", "0"), E=amplitude * sp.sin(rate * lg.t))
        model.add("resistor", "R1", ("in", "out"), R=1e3)
        model.add("capacitor", "C1", ("out", "0"), C=1e-6)
        return model

    values = {"E": 2.5, "omega": 2 * np.pi * 200}
    state = {"initial": {"q_R1": 0.0}}
    symbolic = compare_with_ngspice(rc(E, w), 0.01, params=values, max_step=1e-6, **state)
    numeric = compare_with_ngspice(rc(2.5, 2 * np.pi * 200), 0.01, max_step=1e-6, **state)
    assert symbolic.worst_rel < 1e-3 and numeric.worst_rel < 1e-3, symbolic.table()
    assert symbolic.worst_rel == numeric.worst_rel
