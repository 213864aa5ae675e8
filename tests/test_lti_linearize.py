"""Linear time-invariant models are linearized from their stamps, with nothing derived (lagrangian.analysis.lti).

References: closed forms (the rest point of a biased spring or capacitor, the series RLC's transfer function) and
the symbolic linearization, which derives the model's equations and differentiates them (itself checked against
closed forms, sympy.physics.mechanics' Linearizer and ngspice's .ac in tests/test_frequency.py and test_ac.py).
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import lagrangian as lg
import lagrangian.analysis.linearize as linearize_module
from lagrangian.derivation.equations import Equations
from lagrangian.frequency import frequency_response, linearize


@pytest.fixture
def nothing_derived(monkeypatch):
    """Deriving a model's equations fails the test."""
    def refuse(self, assembly):
        raise AssertionError("the equations were derived")
    monkeypatch.setattr(Equations, "__init__", refuse)


def derived(*args, **kwargs):
    """The symbolic linearization (the stamps' path turned off)."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(linearize_module, "stamped", lambda *a, **k: None)
        return linearize(*args, **kwargs)


def stamped(*args, **kwargs):
    """The linearization, failing if it derives the model's equations."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(Equations, "__init__", lambda self, assembly: pytest.fail("the equations were derived"))
        return linearize(*args, **kwargs)


def same(a, b):
    """Two LinearModels agree: matrices to 1e-12 of their scale, the same point, outputs and labels."""
    assert (a.coordinates, a.inputs, a.outputs, a.first_order) == (b.coordinates, b.inputs, b.outputs, b.first_order)
    for x, y in [(a.M, b.M), (a.C, b.C), (a.K, b.K), (a.Phi, b.Phi), (a.Bi, b.Bi), (a.Di, b.Di),
                 *zip(a.B, b.B), *zip(a.Cq, b.Cq), *zip(a.D, b.D)]:
        assert x.shape == y.shape
        np.testing.assert_allclose(x, y, rtol=1e-12, atol=1e-12 * max(np.abs(y).max(initial=0.0), 1e-300))
    assert (len(a.B), len(a.Cq), len(a.D)) == (len(b.B), len(b.Cq), len(b.D))
    for name in b.at:
        assert float(a.at[name]) == pytest.approx(float(b.at[name]), rel=1e-9, abs=1e-12)
    for label in b.y0:
        assert float(a.y0[label]) == pytest.approx(float(b.y0[label]), rel=1e-9, abs=1e-12)
    assert a.units == b.units and a.u0 == b.u0


decade = st.floats(-2, 2).map(lambda e: float(f"{3.7 * 10 ** e:.3g}"))


def ladder(sections, values, formulation, bias):
    m = lg.Model("ladder", formulation=formulation)
    m.add("voltage_source", "V1", ("in", "0"), E=bias)
    prev = "in"
    for k in range(sections):
        R, L, C = values[3 * k: 3 * k + 3]
        m.add("resistor", f"R{k}", (prev, f"m{k}"), R=R)
        m.add("inductor", f"L{k}", (f"m{k}", f"n{k}"), L=L)
        m.add("capacitor", f"C{k}", (f"n{k}", "0"), C=C)
        prev = f"n{k}"
    return m


@settings(max_examples=15, deadline=None)
@given(sections=st.integers(1, 4), values=st.lists(decade, min_size=12, max_size=12),
       formulation=st.sampled_from(["charge", "flux"]), bias=st.sampled_from([0.0, 2.5]))
def test_ladders_read_off_their_stamps_as_their_equations_give(sections, values, formulation, bias):
    m = ladder(sections, values, formulation, bias)
    outputs = ["i(L0)", f"v(C{sections - 1})", "v(n0)"]
    same(stamped(m, inputs=["V1"], outputs=outputs), derived(m, inputs=["V1"], outputs=outputs))


@settings(max_examples=15, deadline=None)
@given(n=st.integers(1, 4), values=st.lists(decade, min_size=12, max_size=12), g=st.sampled_from([0.0, 9.81]))
def test_chains_under_gravity_rest_where_the_springs_hold_them(n, values, g):
    """A hanging chain of masses and springs, forced at its end: the rest point is the closed form (each spring
    carries the weight below it), and the linearization equals the derived one."""
    m = lg.Model("chain")
    prev = "ground"
    masses, springs = values[:n], values[n:2 * n]
    for i in range(n):
        m.add("mass", f"m{i}", f"p{i}", m=masses[i])
        m.add("spring", f"k{i}", (prev, f"p{i}"), k=springs[i])
        m.add("damper", f"c{i}", (prev, f"p{i}"), c=values[2 * n + i])
        prev = f"p{i}"
    m.add("force", "F", prev, F=0.0)
    if g:
        m.add("gravity", "g", g=g)  # along −x in one dimension
    outputs = [f"x_p{n - 1}", f"x_p{n - 1}'"]
    fast = stamped(m, inputs=["F"], outputs=outputs)
    same(fast, derived(m, inputs=["F"], outputs=outputs))
    # closed form: spring i stretches by the weight it carries, Σ_{j≥i} m_j g / k_i, and the masses sink along −x
    weight_below = np.cumsum(np.array(masses[::-1]) * g)[::-1]
    expected = -np.cumsum(weight_below / np.array(springs))
    got = np.array([float(fast.at[f"x_p{i}"]) for i in range(n)])
    np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-15)


def test_a_point_given_is_kept_and_outputs_are_taken_there(nothing_derived):
    m = lg.Model("msd")
    m.add("mass", "m", "p", m=0.3)
    m.add("spring", "k", ("ground", "p"), k=40.0)
    m.add("damper", "c", ("ground", "p"), c=0.2)
    m.add("force", "F", "p", F=1.5)  # not at rest at x = 0.01: a linear model need not be
    lin = linearize(m, at={"x_p": 0.01}, inputs=["F"], outputs=["x_p", "x_p'"])
    assert float(lin.at["x_p"]) == 0.01 and lin.y0["x_p"] == pytest.approx(0.01)
    np.testing.assert_allclose([lin.M[0, 0], lin.C[0, 0], lin.K[0, 0], lin.B[0][0, 0]], [0.3, 0.2, 40.0, 1.0])
    rest = linearize(m, inputs=["F"], outputs=["x_p"])
    assert float(rest.at["x_p"]) == pytest.approx(1.5 / 40.0, rel=1e-12)  # k x = F


def test_a_series_rlc_transfer_function_is_the_closed_form_with_nothing_derived(nothing_derived):
    R, L, C = 12.0, 7e-3, 2.2e-6
    m = lg.Model("series rlc")
    m.add("voltage_source", "V1", ("in", "0"), E=0)
    m.add("resistor", "R1", ("in", "a"), R=R)
    m.add("inductor", "L1", ("a", "b"), L=L)
    m.add("capacitor", "C1", ("b", "0"), C=C)
    f = np.logspace(1, 6, 61)
    resp = frequency_response(m, f, inputs=["V1"], outputs=["v(C1)", "i(L1)"])
    s = 2j * np.pi * f
    Z = R + s * L + 1 / (s * C)
    np.testing.assert_allclose(resp["i(L1)"], 1 / Z, rtol=1e-12)
    np.testing.assert_allclose(resp["v(C1)"], 1 / (s * C * Z), rtol=1e-12)


def test_models_beyond_the_stamps_are_derived_as_before():
    """A hardening spring (a force cubic in the state) and a symbolic parameter take the derived path."""
    import sympy as sp

    m = lg.Model("duffing")
    m.add("mass", "m", "p", m=0.3)
    m.add("spring", "k", ("ground", "p"), k=40.0)
    m.add("force", "F", "p", F=-50.0 * lg.coordinate("x_p") ** 3 + 40.0 * 0.1 + 50.0 * 0.1 ** 3)  # rests at 0.1
    lin = linearize(m, at={"x_p": 0.1}, inputs=[])
    assert lin.K[0, 0] == pytest.approx(40.0 + 3 * 50.0 * 0.1 ** 2, rel=1e-12)
    k = sp.Symbol("k", positive=True)
    sym = lg.Model("symbolic")
    sym.add("mass", "m", "p", m=0.3)
    sym.add("spring", "k", ("ground", "p"), k=k)
    assert linearize(sym).symbolic
