"""∂H/∂p of frequency responses (frequency_response(..., sensitivities=)) against sympy's derivatives of closed
forms, over parameter values drawn across decades."""

import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

import lagrangian as lg
from lagrangian import models
from lagrangian.frequency import decades, frequency_response, linearize

NAMES = {"Re": "R_Re", "Le": "L_Le", "Bl": "Bl_coil", "m": "m_m", "k": "k_k", "c": "c_c"}


@settings(max_examples=15, deadline=None)
@given(st.floats(0.5, 50), st.floats(-5, -2), st.floats(0.5, 30), st.floats(-3, 0), st.floats(2, 5), st.floats(-1, 1))
def test_a_loudspeakers_admittance_sensitivities_are_the_closed_forms_derivatives(Re, logLe, Bl, logm, logk, logc):
    values = {"Re": Re, "Le": 10**logLe, "Bl": Bl, "m": 10**logm, "k": 10**logk, "c": 10**logc}
    model = models.loudspeaker(**values)
    f = decades(1, 1e4, 4)
    resp = frequency_response(model, f, inputs=["E"], outputs=["i(Le)"], sensitivities=list(NAMES.values()))
    sym = {k: sp.Symbol(k, positive=True) for k in values}
    w = sp.Symbol("w", positive=True)
    Z = sym["Re"] + sp.I * w * sym["Le"] + sym["Bl"] ** 2 / (sym["c"] + sp.I * w * sym["m"] + sym["k"] / (sp.I * w))
    for key, name in NAMES.items():
        slope = sp.lambdify([w, *sym.values()], sp.diff(1 / Z, sym[key]), "numpy")(2 * np.pi * f, *values.values())
        ours = resp.sensitivity(name)
        assert np.allclose(ours, slope, rtol=1e-8, atol=1e-10 * np.max(np.abs(slope))), name


def test_a_constrained_mechanism_and_several_outputs():
    """Two masses tied by a constraint x_a = x_b (one body of m_a + m_b on k): X/F = 1/(k − ω²(m_a + m_b)), for
    both outputs; its derivatives by m_a and k."""
    m = lg.Model("tied")
    m.add("mass", "ma", "a", m=0.3)
    m.add("mass", "mb", "b", m=0.2)
    m.add("spring", "k", ("ground", "a"), k=40.0)
    m.add("constraint", "tie", f=lg.coordinate("x_a") - lg.coordinate("x_b"))
    m.add("force", "F", "b", F=0)
    f = np.array([0.5, 1.3, 7.0])
    resp = frequency_response(m, f, inputs=["F"], outputs=["x_a", "x_b"], sensitivities=["m_ma", "k_k"])
    w2 = (2 * np.pi * f) ** 2
    H = 1 / (40.0 - w2 * 0.5)
    for out in ("x_a", "x_b"):
        assert np.allclose(resp[out], H, rtol=1e-10)
        assert np.allclose(resp.sensitivity("m_ma", out), w2 * H**2, rtol=1e-9)
        assert np.allclose(resp.sensitivity("k_k", out), -(H**2), rtol=1e-9)


def test_what_sensitivities_cannot_take_is_refused_by_name():
    model = models.loudspeaker()
    with pytest.raises(lg.UnknownNameError, match="Bl"):
        frequency_response(model, [10.0], sensitivities=["Bl"])
    with pytest.raises(lg.ModelError, match="takes a Model"):
        frequency_response(linearize(model), [10.0], sensitivities=["Bl_coil"])
    with pytest.raises(lg.ModelError, match="positive frequencies"):
        frequency_response(model, [0.0, 10.0], sensitivities=["Bl_coil"])
    resp = frequency_response(model, [10.0], inputs=["E"], outputs=["i(Le)"], sensitivities=["Bl_coil"])
    with pytest.raises(lg.UnknownNameError, match="k_k"):
        resp.sensitivity("k_k")
