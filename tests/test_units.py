"""Values with units (pint): parameters, initial values and params= in SI, dimensions checked, text never run."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import lagrangian as lg
from lagrangian.base import units

pint = pytest.importorskip("pint")
ureg = pint.get_application_registry()


def oscillator(m, k, c):
    model = lg.Model("oscillator")
    model.add("mass", "m1", "p", m=m)
    model.add("spring", "k1", ("ground", "p"), k=k)
    model.add("damper", "c1", ("ground", "p"), c=c)
    return model


@settings(max_examples=30)
@given(st.floats(1e-3, 1e3), st.floats(1e-2, 1e4), st.floats(1e-4, 1e1),
       st.sampled_from([("g", 1e-3), ("kg", 1.0), ("mg", 1e-6), ("lb", 0.45359237)]))
def test_parameters_with_units_are_their_si_values(m, k, c, mass_unit):
    """A mass in g, mg, lb or kg, a stiffness in kN/m, a damping as a pint quantity: the SI model, exactly."""
    unit, factor = mass_unit
    given = oscillator(f"{m / factor!r} {unit}", f"{k / 1e3!r} kN/m", c * ureg.N * ureg.s / ureg.m)
    si = oscillator(m, k, c)
    for name, value in si.parameter_values.items():
        assert given.parameter_values[name] == pytest.approx(value, rel=1e-12)


def test_circuit_values_take_prefixes_and_the_ohm_sign():
    c = lg.Model("rlc")
    c.add("inductor", "L1", ("a", "0"), L="7 mH")
    c.add("capacitor", "C1", ("a", "0"), C="2.2 uF")
    c.add("resistor", "R1", ("a", "0"), R="4.7 kΩ")
    c.add("current_source", "I1", ("0", "a"), I="3 mA")
    assert c.parameter_values == pytest.approx({"L_L1": 7e-3, "C_C1": 2.2e-6, "R_R1": 4.7e3, "I_I1": 3e-3})


@pytest.mark.parametrize("kind, nodes, name, value, words", [
    ("mass", "p", "m", "4 N/m", r"\[mass\] / \[time\] \*\* 2, not of \[mass\] \(kg\)"),
    ("spring", ("ground", "p"), "k", "3 m", r"\[length\], not of \[mass\] / \[time\] \*\* 2 \(N/m\)"),
    ("capacitor", ("a", "0"), "C", "1 H", r"not of .* \(F\)"),
    ("mass", "p", "m", "3 furlongs", r"\[length\]"),
    ("mass", "p", "m", "3 xyzzy", "not a unit pint knows"),
])
def test_a_unit_of_another_dimension_is_refused_naming_the_one_expected(kind, nodes, name, value, words):
    with pytest.raises(lg.ParameterError, match=words):
        lg.Model("x").add(kind, "c1", nodes, **{name: value})


def test_initial_values_and_params_take_units_too():
    m = oscillator("300 g", "40 N/m", "0 N*s/m")
    res = m.simulate(1, initial={"x_p": "1 cm"}, velocity={"x_p": 0 * ureg.m / ureg.s},
                     params={"k_k1": "0.04 kN/m"}, points=3)
    w = math.sqrt(40 / 0.3)
    assert np.allclose(res["x_p"], 0.01 * np.cos(w * res.t), atol=1e-10)
    pendulum = lg.Model("pendulum", dim=2)
    pendulum.add("rod", "r", "r", m="300 g", length="70 cm")
    pendulum.add("revolute", "j", ("ground", "r"))
    pendulum.add("gravity", "g")
    start = pendulum.simulate(0.01, initial={"theta_j": "5 deg"}, velocity={"theta_j": "0 rad/s"}, points=2)
    assert start["theta_j"][0] == pytest.approx(math.radians(5), rel=1e-15)
    with pytest.raises(lg.ModelError, match=r"initial value of 'x_p': 1 kg is a quantity of \[mass\]"):
        m.simulate(1, initial={"x_p": "1 kg"})
    with pytest.raises(lg.ParameterError, match=r"component 'k1', parameter 'k'.*\(N/m\)"):
        m.simulate(1, params={"k_k1": "3 kg"})


def test_results_carry_units():
    res = oscillator("300 g", "40 N/m", "0.05 N*s/m").simulate(0.1, initial={"x_p": "1 cm"}, velocity={"x_p": 0},
                                                                points=3)
    ds = res.to_xarray()
    assert ds.x_p.attrs["units"] == "m" and ds["x_p'"].attrs["units"] == "m/s" and ds.E.attrs["units"] == "J"


def test_unit_text_is_data_never_run_and_pint_is_optional(monkeypatch):
    for text in ("3 __import__('os')", "3 kg; import os", "3 kg\nimport os", "3 " + "m*" * 40):
        assert units.split(text) is None  # not a number and a unit: the whitelisting parser refuses it after
        with pytest.raises(lg.ParameterError):
            lg.Model("x").add("mass", "m1", "p", m=text)
    monkeypatch.setitem(units._REGISTRY, "ureg", None)
    with pytest.raises(lg.ParameterError, match=r"units need pint: pip install 'lagrangian\[units\]'"):
        lg.Model("x").add("mass", "m1", "p", m="300 g")
    assert lg.Model("x").add("mass", "m1", "p", m=0.3).m == 0.3  # plain numbers as always
