"""Parameters given as numbers are values of symbols: compiled code takes them at run time.

A model built with numbers can be run with other values (``params=`` by
the names in ``Model.parameter_values``) without deriving or recording
anything again; the answers are checked against the closed form of the
oscillator, and against the same model built with the new value.
"""

import math

import numpy as np
import sympy as sp
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import lagrangian as lg
from lagrangian.codegen import programs


def decades(lo, hi):
    return st.floats(math.log10(lo), math.log10(hi)).map(lambda e: float(f"{10 ** e:.3g}"))


def oscillator(m=0.3, k=40.0):
    model = lg.Model("oscillator")
    model.add("mass", "m1", "p", m=m)
    model.add("spring", "k1", ("ground", "p"), k=k)
    return model


def test_parameter_values_are_named_for_params():
    assert oscillator().parameter_values == {"m_m1": 0.3, "k_k1": 40.0}
    assert oscillator().parameters == []


@settings(max_examples=12)
@given(m=decades(1e-3, 1e2), k=decades(1e-2, 1e5))
def test_other_values_at_run_time_follow_the_closed_form(m, k):
    model = oscillator()
    w = math.sqrt(k / m)
    t_end = 3 * 2 * math.pi / w
    for method in ("DOP853", "exact"):
        res = model.simulate(t_end, initial={"x_p": 0.01}, velocity={"x_p": 0.0}, params={"m_m1": m, "k_k1": k},
                             method=method, points=201)
        assert np.max(np.abs(res["x_p"] - 0.01 * np.cos(w * res.t))) < 1e-9


def test_the_tape_is_recorded_once_for_every_set_of_values():
    model = oscillator()
    first, second = programs(model.numeric({"k_k1": 40.0})), programs(model.numeric({"k_k1": 12.5}))
    assert first[0].code is second[0].code  # the same instructions: nothing recorded again
    assert sorted(first[0].constants) != sorted(second[0].constants)
    direct = oscillator(k=12.5).simulate(2, initial={"x_p": 0.1}, velocity={"x_p": 0.3}, compiled="tape")
    given_ = model.simulate(2, initial={"x_p": 0.1}, velocity={"x_p": 0.3}, params={"k_k1": 12.5}, compiled="tape")
    np.testing.assert_allclose(given_["x_p"], direct["x_p"], rtol=0, atol=1e-12)


def test_another_value_obeys_the_parameter_rule():
    with pytest.raises(lg.ParameterError, match=r"component 'k1', parameter 'k': must be positive"):
        oscillator().simulate(1, initial={"x_p": 0.1}, params={"k_k1": -3.0})


def test_analyses_that_use_the_built_value_refuse_another_rather_than_ignore_it():
    from lagrangian.spice import netlist

    with pytest.raises(lg.ModelError, match=r"'k_k1' .* was given as a number \(40\)"):
        netlist(oscillator(), params={"k_k1": 3.0}, t_end=1)


@settings(max_examples=30)
@given(k=decades(1e-4, 1e4), m=decades(1e-4, 1e4), x=st.floats(-3, 3), y=st.floats(-3, 3))
def test_what_depends_on_parameters_alone_is_computed_once_per_set_of_values(k, m, x, y):
    import sympy as sp
    from lagrangian.tape import record

    K, Mm, X, Y = sp.symbols("K M X Y", real=True)
    exprs = [K * Mm * sp.sin(X) + sp.sqrt(K / Mm) * Y, (K + Mm) ** 2 * X, K * Mm]
    program = record(exprs, [X, Y], parameters=[K, Mm])
    folded = program.with_values({K: k, Mm: m})
    assert len(folded.code) < len(program.code)
    expected = [float(e.evalf(30, subs={K: k, Mm: m, X: x, Y: y})) for e in exprs]
    np.testing.assert_allclose(folded.evaluate([x, y]), expected, rtol=1e-13, atol=1e-300)


def test_geometry_given_as_numbers_is_symbols_in_the_derivation():
    """The heavy top from numbers derives the very Lagrangian of the top from symbols (the values go in after):
    its centre of mass and principal moments are symbols too, the two equal moments one symbol."""
    from lagrangian import models

    num = models.heavy_top(0.3, 0.4, 0.3, 0.5, 9.81)
    sym = models.heavy_top(*sp.symbols("m l I1 I3 g", positive=True))
    names = {"m_top": "m", "inertia_top_0": "I1", "inertia_top_2": "I3", "com_top_2": "l", "g_g": "g"}
    assert num.parameter_values == {"m_top": 0.3, "inertia_top_0": 0.3, "inertia_top_2": 0.5, "com_top_2": 0.4, "g_g": 9.81}
    rename = {s: sp.Symbol(names[s.name], positive=True) for s in num.eq.values}
    assert sp.expand(num.eq.generic()["L"].xreplace(rename) - sym.eq.L) == 0
    # another centre of mass at run time is the model rebuilt with it
    start = dict(initial={"theta_precession": 0.0, "theta_nutation": 0.5, "theta_spin": 0.0},
                 velocity={"theta_precession": 1.0, "theta_nutation": 0.0, "theta_spin": 30.0})
    got = num.simulate(0.5, params={"com_top_2": 0.25}, rtol=1e-11, atol=1e-12, **start)
    want = models.heavy_top(0.3, 0.25, 0.3, 0.5, 9.81).simulate(0.5, rtol=1e-11, atol=1e-12, **start)
    np.testing.assert_allclose(got["theta_nutation"], want["theta_nutation"], atol=1e-10)


@pytest.mark.parametrize("kind, nodes, name, value", [
    ("revolute", ("ground", "b"), "angle", []),
    ("revolute", ("ground", "b"), "angle", [0.3 * lg.t, 0.2]),
    ("prismatic", ("ground", "b"), "displacement", (0.01, 0.02)),
    ("prescribed_rotation", "a", "angle", [lg.t]),
    ("torque", "a", "tau", [0.7]),
])
def test_a_scalar_signal_given_a_sequence_is_refused_by_name(kind, nodes, name, value):
    """A driven joint's angle or displacement, a rotational node's angle or torque: one signal, not a list (an empty
    list reached the kinematics as a matrix: a TypeError adding it to an angle)."""
    model = lg.Model("driven", dim=2)
    with pytest.raises(lg.ParameterError, match=rf"component 'j', parameter '{name}': is one signal .*not a sequence"):
        model.add(kind, "j", nodes, **{name: value})


@settings(max_examples=15, deadline=None)
@given(st.floats(-3, 1).map(lambda e: float(f"{10 ** e:.3g}")), st.floats(-3, 1).map(lambda e: float(f"{10 ** e:.3g}")))
def test_outputs_of_a_linearization_take_the_values_given_in_params(C_built, C_given):
    """A ladder built with one capacitance and linearized with another in ``params=``: its outputs (an element's
    voltage, a node's) are those of the ladder built with the second, as its stiffness is; they kept the first."""
    from lagrangian.frequency import linearize

    def ladder(C1):
        m = lg.Model("ladder", formulation="charge")
        m.add("voltage_source", "V1", ("in", "0"), E=0.0)
        m.add("resistor", "R0", ("in", "m0"), R=0.37)
        m.add("inductor", "L0", ("m0", "n0"), L=7e-3)
        m.add("capacitor", "C0", ("n0", "0"), C=0.47)
        m.add("resistor", "R1", ("n0", "m1"), R=1.3)
        m.add("inductor", "L1", ("m1", "n1"), L=0.12)
        m.add("capacitor", "C1", ("n1", "0"), C=C1)
        return m

    outputs = ["v(C1)", "v(n1)", "i(L1)"]
    got = linearize(ladder(C_built), params={"C_C1": C_given}, inputs=["V1"], outputs=outputs)
    want = linearize(ladder(C_given), inputs=["V1"], outputs=outputs)
    for name in ("K", "M", "C"):
        assert np.allclose(getattr(got, name), getattr(want, name), rtol=1e-12, atol=0), name
    for a, b in zip(got.Cq, want.Cq):
        assert np.allclose(np.asarray(a, dtype=float), np.asarray(b, dtype=float), rtol=1e-12, atol=0)
