"""lagrangian.fit: estimates against the true values of synthetic measurements, exact Jacobians against the
derivatives of closed forms, identifiability against the known symmetry of a loudspeaker's impedance."""

import math

import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

import lagrangian as lg
from lagrangian import models
from lagrangian.fitting import _Frequency

TRUTH = dict(R_Re=6.0, L_Le=0.5e-3, Bl_coil=7.0, m_m=0.02, k_k=2000.0, c_c=1.5)
OFF = dict(Re=5.0, Le=0.8e-3, Bl=5.0, m=0.03, k=1500.0, c=1.0)  # a start some 30 % off
F = np.geomspace(5, 5000, 200)


def impedance(f, p=TRUTH, added=0.0):
    """The closed form: Z = Re + jωLe + Bl² / (Rms + jω(Mms + added) + k/(jω))."""
    w = 2 * np.pi * f
    return p["R_Re"] + 1j * w * p["L_Le"] + p["Bl_coil"] ** 2 / (p["c_c"] + 1j * w * (p["m_m"] + added) + p["k_k"] / (1j * w))


def noisy(z, rng, level=0.005):
    return z * (1 + level * (rng.normal(size=z.size) + 1j * rng.normal(size=z.size)) / np.sqrt(2))


def speaker(added=0.0):
    model = models.loudspeaker(**OFF)
    if added:
        model.add("mass", "added", "cone", m=added)
    return model


def curve(z, **kwargs):
    return lg.FrequencyData(F, z, input="E", output="i(Le)", impedance=True, **kwargs)


def test_thiele_small_parameters_from_free_air_and_added_mass_curves():
    rng = np.random.default_rng(3)
    result = lg.fit(speaker(), [curve(noisy(impedance(F), rng), name="free air"),
                                curve(noisy(impedance(F, added=0.01), rng), model=speaker(0.01), name="+10 g")],
                    list(TRUTH))
    bounds = result.interval(3.0)
    for name, true in TRUTH.items():
        assert abs(result.values[name] / true - 1) < 1e-2, (name, result.values[name])
        assert bounds[name][0] <= true <= bounds[name][1], (name, bounds[name], true)
    assert result.undetermined == [] and result.failed_steps == [] and result.structural == []
    assert np.allclose(np.diag(result.correlation), 1.0)
    table = result.to_pandas()
    assert list(table.index) == list(TRUTH) and (table["stderr"] > 0).all()


def test_free_air_impedance_alone_leaves_bl_mms_cms_rms_undetermined_and_says_which_combinations_it_fixes():
    rng = np.random.default_rng(4)
    result = lg.fit(speaker(), curve(noisy(impedance(F), rng)), list(TRUTH))
    assert result.undetermined == ["the data do not determine Bl_coil, m_m, k_k, c_c separately: scaling Bl_coil by "
                                   "λ, m_m by λ^2, k_k by λ^2, c_c by λ^2 leaves every prediction unchanged."]
    assert result.determined == ["m_m/Bl_coil^2", "k_k/Bl_coil^2", "c_c/Bl_coil^2"]
    # and no data could: the transfer function's coefficients (symbolic) have the same symmetry
    assert result.structural == ["no data of these experiments can determine Bl_coil, m_m, k_k, c_c separately: "
                                 "scaling Bl_coil by λ, m_m by λ^2, k_k by λ^2, c_c by λ^2 leaves every prediction "
                                 "unchanged."]
    for name in ("Bl_coil", "m_m", "k_k", "c_c"):
        assert math.isinf(result.stderr[name])
    v, t = result.values, TRUTH
    for name in ("m_m", "k_k", "c_c"):  # what it does determine, it determines well
        assert abs((v[name] / v["Bl_coil"] ** 2) / (t[name] / t["Bl_coil"] ** 2) - 1) < 1e-2
    for name in ("R_Re", "L_Le"):
        assert abs(v[name] / t[name] - 1) < 1e-2 and math.isfinite(result.stderr[name])
    assert "not determined" in str(result) and "λ^2" in result._repr_html_()


def test_the_jacobian_is_the_derivative_of_the_closed_form():
    """∂Z/∂θ from the symbolic linearization against sympy's derivative of the closed-form impedance."""
    names = list(TRUTH)
    part = _Frequency(curve(impedance(F)), speaker(), names)
    theta = np.array([TRUTH[n] for n in names])
    Z, J = part.predict(theta, True)
    assert np.allclose(Z, impedance(F), rtol=1e-12)
    s = {n: sp.Symbol(n, positive=True) for n in names}
    w = sp.Symbol("w", positive=True)
    closed = s["R_Re"] + sp.I * w * s["L_Le"] + s["Bl_coil"] ** 2 / (s["c_c"] + sp.I * w * s["m_m"] + s["k_k"] / (sp.I * w))
    for j, n in enumerate(names):
        slope = sp.lambdify([w, *s.values()], sp.diff(closed, s[n]), "numpy")(2 * np.pi * F, *theta)
        assert np.allclose(J[:, j], slope, rtol=1e-10, atol=1e-12 * np.max(np.abs(slope))), n


@settings(max_examples=20, deadline=None)
@given(st.floats(1.0, 6.0), st.floats(-9.0, -4.0), st.floats(-5.0, -1.0), st.floats(0.5, 2.0))
def test_a_series_rlc_over_decades_is_recovered_exactly_from_exact_data(logR, logC, logL, factor):
    """R, L and C drawn over decades; the start off by ``factor`` in each; noise-free data: the fit lands on the
    truth (the frequency grid spans the resonance)."""
    R, C, L = 10 ** logR, 10 ** logC, 10 ** logL
    w0 = 1 / math.sqrt(L * C)
    f = np.geomspace(w0 / 2 / math.pi / 30, w0 / 2 / math.pi * 30, 60)
    w = 2 * np.pi * f
    Z = R + 1j * w * L + 1 / (1j * w * C)
    m = lg.Model("rlc")
    m.add("voltage_source", "V1", ("a", "0"), E=0)
    m.add("resistor", "R1", ("a", "b"), R=R * factor)
    m.add("inductor", "L1", ("b", "c"), L=L / factor)
    m.add("capacitor", "C1", ("c", "0"), C=C * factor)
    result = lg.fit(m, lg.FrequencyData(f, Z, input="V1", output="i(L1)", impedance=True), ["R_R1", "L_L1", "C_C1"],
                    max_nfev=400)
    for name, true in (("R_R1", R), ("L_L1", L), ("C_C1", C)):
        assert result.values[name] == pytest.approx(true, rel=1e-6)
    assert result.structural == []  # Z = R + sL + 1/(sC) fixes all three


@pytest.mark.parametrize("make, words", [
    (lambda: curve(np.where(F > 100, np.nan, impedance(F))), r"holds \(?nan.* at index 87: remove the point"),
    (lambda: lg.FrequencyData(F[:-1], impedance(F), input="E", output="i(Le)"), "199 frequencies but 200 values"),
    (lambda: lg.FrequencyData(np.r_[0.0, F[1:]], impedance(F), input="E", output="i(Le)"), "must be positive"),
    (lambda: curve(impedance(F), weight=-1.0), "weight must be a positive number"),
    (lambda: lg.TimeSeries([0, 1, 1], {"x_cone": [0, 1, 2]}), "must increase strictly"),
    (lambda: lg.TimeSeries([0, 1, 2], {"x_cone": [0, 1]}), "2 values for 3 times"),
])
def test_bad_data_is_refused_by_name(make, words):
    with pytest.raises(lg.ModelError, match=words):
        make()


def test_bad_requests_are_refused_by_name():
    data = curve(impedance(F))
    with pytest.raises(lg.UnknownNameError, match="Bl"):
        lg.fit(speaker(), data, ["Bl"])
    with pytest.raises(lg.ModelError, match="each fitted parameter once"):
        lg.fit(speaker(), data, ["R_Re", "R_Re"])
    with pytest.raises(lg.ModelError, match=r"'R_Re': its start 5 must lie within its bounds \(6, 7\)"):
        lg.fit(speaker(), data, ["R_Re"], bounds={"R_Re": (6.0, 7.0)})
    with pytest.raises(lg.ModelError, match="FrequencyData, TimeSeries"):
        lg.fit(speaker(), [1, 2], ["R_Re"])
    with pytest.raises(lg.NumericalError, match="did not converge.*stopped at"):
        lg.fit(speaker(), data, list(TRUTH)[:2] + ["m_m"], max_nfev=1)


def oscillator(m=0.3, k=40.0, c=0.5):
    model = lg.Model("oscillator")
    model.add("mass", "m", "p", m=m)
    model.add("spring", "k", ("ground", "p"), k=k)
    model.add("damper", "c", ("ground", "p"), c=c)
    return model


def decay(t, m=0.3, k=40.0, c=0.5, x0=0.01):
    """The closed form of the damped oscillator released from x0 at rest."""
    wn, zeta = math.sqrt(k / m), c / (2 * math.sqrt(k * m))
    wd = wn * math.sqrt(1 - zeta**2)
    return x0 * np.exp(-zeta * wn * t) * (np.cos(wd * t) + zeta * wn / wd * np.sin(wd * t))


def test_a_damped_oscillator_from_a_noisy_record_of_its_decay():
    """The record is the closed form plus 0.5 % noise; the fit from 25 % off finds k and c within their intervals,
    and the start x(0) too when asked."""
    rng = np.random.default_rng(8)
    t = np.linspace(0, 3, 301)
    x = decay(t) + 0.005 * 0.01 * rng.normal(size=t.size)
    data = lg.TimeSeries(t, {"x_p": x}, initial={"x_p": 0.0125}, velocity={"x_p": 0.0})
    result = lg.fit(oscillator(k=50.0, c=0.4), data, ["k_k", "c_c", "x_p"])
    bounds = result.interval(3.0)
    for name, true in (("k_k", 40.0), ("c_c", 0.5), ("x_p", 0.01)):
        assert abs(result.values[name] / true - 1) < 1e-2, (name, result.values[name])
        assert bounds[name][0] <= true <= bounds[name][1], (name, bounds[name])
    assert result.undetermined == []


def test_a_dataframe_of_measurements_fits_as_a_time_series():
    pd = pytest.importorskip("pandas")
    t = np.linspace(0, 2, 201)
    frame = pd.DataFrame({"x_p": decay(t)}, index=t)
    data = lg.TimeSeries.from_table(frame, initial={"x_p": 0.01}, velocity={"x_p": 0.0})
    result = lg.fit(oscillator(k=44.0), data, ["k_k"])
    assert result.values["k_k"] == pytest.approx(40.0, rel=1e-6)


def test_mass_spring_and_damper_alone_are_not_determined_by_a_free_decay_only_their_ratios():
    """A free decay fixes k/m and c/m only: scaling m, k and c together changes nothing, and the fit says so."""
    t = np.linspace(0, 2, 201)
    data = lg.TimeSeries(t, {"x_p": decay(t)}, initial={"x_p": 0.01}, velocity={"x_p": 0.0})
    result = lg.fit(oscillator(m=0.35), data, ["m_m", "k_k", "c_c"])
    assert result.undetermined == ["the data do not determine m_m, k_k, c_c separately: scaling m_m by λ, k_k by λ, "
                                   "c_c by λ leaves every prediction unchanged."]
    assert result.determined == ["k_k/m_m", "c_c/m_m"]
    v = result.values
    assert v["k_k"] / v["m_m"] == pytest.approx(40 / 0.3, rel=1e-6)


def test_an_unknown_output_is_refused_by_name():
    data = lg.TimeSeries([0, 1, 2], {"y_q": [0, 1, 2]})
    with pytest.raises(lg.UnknownNameError, match="y_q"):
        lg.fit(oscillator(), data, ["k_k"])
