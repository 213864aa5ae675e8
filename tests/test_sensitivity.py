"""Forward sensitivities (``Model.simulate(..., sensitivities=[...])``, lagrangian.numerics.sensitivity) against
independent derivatives: the closed form of a damped oscillator differentiated by SymPy, and central differences
of plain runs at a tight tolerance for nonlinear mechanisms, circuits and first-order coordinates."""

import math
import pickle
import warnings

import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

import lagrangian as lg
from lagrangian import models


def decade(lo, hi):
    return st.floats(math.log10(lo), math.log10(hi)).map(lambda e: float(f"{10 ** e:.3g}"))


def oscillator(m=0.3, k=40.0, c=0.5):
    model = lg.Model("damped oscillator")
    model.add("mass", "m", "p", m=m)
    model.add("spring", "k", ("ground", "p"), k=k)
    model.add("damper", "c", ("ground", "p"), c=c)
    return model


def closed_form():
    """The underdamped oscillator m ẍ + c ẋ + k x = 0 from (x0, v0), written out here — independent of the library —
    with its derivatives by m, c, k, x0 and v0 as NumPy functions of (t, m, c, k, x0, v0): position and rate."""
    t, m, c, k, x0, v0 = sp.symbols("t m c k x0 v0", positive=True)
    alpha = c / (2 * m)
    wd = sp.sqrt(k / m - alpha**2)
    x = sp.exp(-alpha * t) * (x0 * sp.cos(wd * t) + (v0 + alpha * x0) / wd * sp.sin(wd * t))
    args = (t, m, c, k, x0, v0)
    out = {}
    for name, p in (("m_m", m), ("c_c", c), ("k_k", k), ("x_p", x0), ("x_p'", v0)):
        dx = sp.diff(x, p)
        out[name] = (sp.lambdify(args, dx, "numpy"), sp.lambdify(args, sp.diff(dx, t), "numpy"))
    out["x"] = (sp.lambdify(args, x, "numpy"), sp.lambdify(args, sp.diff(x, t), "numpy"))
    return out


CLOSED = closed_form()
NAMES = ["m_m", "c_c", "k_k", "x_p", "x_p'"]


def test_damped_oscillator_sensitivities_match_the_closed_form_differentiated():
    m, k, c, x0 = 0.3, 40.0, 0.5, 0.01
    res = oscillator(m, k, c).simulate(3.0, initial={"x_p": x0}, velocity={"x_p": 0.0}, points=301, rtol=1e-11,
                                       atol=1e-15, sensitivities=NAMES)
    assert res.sensitivity_names == NAMES
    t = res.t
    np.testing.assert_allclose(res["x_p"], CLOSED["x"][0](t, m, c, k, x0, 0.0), rtol=0, atol=1e-12)
    for name in NAMES:
        for series, f in (("x_p", CLOSED[name][0]), ("x_p'", CLOSED[name][1])):
            exact = np.broadcast_to(f(t, m, c, k, x0, 0.0), t.shape)
            got = res.sensitivity(series, name)
            scale = np.max(np.abs(exact))
            assert np.max(np.abs(got - exact)) <= 1e-8 * scale, (series, name)


def test_numpy_and_c_paths_and_scipy_methods_give_the_same_sensitivities():
    """The augmented system in C (DOP853's loop), in NumPy (compiled=False) and under SciPy's RK45 and Radau."""
    kw = dict(initial={"x_p": 0.01}, velocity={"x_p": 0.2}, points=21, sensitivities=["k_k", "c_c", "x_p'"])
    model = oscillator()
    c_run = model.simulate(2.0, rtol=1e-11, **kw)
    numpy_run = model.simulate(2.0, rtol=1e-11, compiled=False, **kw)
    assert "compiled code" in c_run.notes[-1] and "NumPy" in numpy_run.notes[-1]
    for name in kw["sensitivities"]:
        np.testing.assert_allclose(numpy_run.sensitivity("x_p", name), c_run.sensitivity("x_p", name), rtol=1e-9,
                                   atol=1e-12 * np.max(np.abs(c_run.sensitivity("x_p", name))))
    # (the implicit one at a looser tolerance: its Jacobian of the augmented system is SciPy's finite differences)
    for method, rtol, tol in (("RK45", 1e-10, 1e-6), ("dopri5_c", 1e-10, 1e-6), ("Radau", 1e-7, 1e-6)):
        other = model.simulate(2.0, rtol=rtol, method=method, **kw)
        assert other.method == method
        for name in kw["sensitivities"]:
            exact = CLOSED[name][0](other.t, 0.3, 0.5, 40.0, 0.01, 0.2)
            assert np.max(np.abs(other.sensitivity("x_p", name) - exact)) <= tol * np.max(np.abs(exact))


@settings(max_examples=25)
@given(decade(1e-3, 1e2), decade(1e-1, 1e5), st.floats(0.01, 0.6), decade(1e-3, 10.0))
def test_oscillator_over_decades_matches_the_closed_form(m, k, zeta, x0):
    """Masses 1e-3..1e2 kg, stiffnesses 1e-1..1e5 N/m, damping ratios 0.01..0.6: three periods at rtol=1e-10,
    every sensitivity within 1e-6 of its largest value over the run (the integration's error, amplified over the
    periods, and its scale)."""
    c = float(f"{2 * zeta * math.sqrt(k * m):.6g}")
    w = math.sqrt(k / m)
    span = 3 * 2 * math.pi / w
    res = oscillator(m, k, c).simulate(span, initial={"x_p": x0}, velocity={"x_p": 0.3 * w * x0}, points=61,
                                       rtol=1e-10, atol=1e-14 * x0, sensitivities=NAMES)
    for name in NAMES:
        for series, f in (("x_p", CLOSED[name][0]), ("x_p'", CLOSED[name][1])):
            exact = np.broadcast_to(f(res.t, m, c, k, x0, 0.3 * w * x0), res.t.shape)
            err = np.max(np.abs(res.sensitivity(series, name) - exact))
            assert err <= 1e-6 * np.max(np.abs(exact)), (series, name, err)


def central(model, span, name, value, kw, step):
    """The central difference of plain runs (rtol=1e-13) by ``name``: a parameter, or an initial value or rate."""
    runs = []
    for sign in (1.0, -1.0):
        given = {"initial": dict(kw["initial"]), "velocity": dict(kw["velocity"]), "params": {}}
        if name in model.parameter_values:
            given["params"][name] = value + sign * step
        elif name.endswith("'"):
            given["velocity"][name[:-1]] = value + sign * step
        else:
            given["initial"][name] = value + sign * step
        runs.append(model.simulate(span, **given, points=kw["points"], rtol=1e-13, atol=1e-16))
    return {series: (getter(runs[0], c) - getter(runs[1], c)) / (2 * step)
            for c in model.coordinate_names
            for series, getter in ((c, lambda r, c: r[c]), (f"{c}'", lambda r, c: r.velocity(c)))}


def check_against_central(model, span, kw, names, tol, rel=1e-4):
    res = model.simulate(span, **kw, rtol=1e-12, atol=1e-15, sensitivities=names)
    values = {**model.parameter_values, **kw["initial"], **{f"{k}'": v for k, v in kw["velocity"].items()}}
    for name in names:
        value = values[name]
        step = rel * abs(value) if value else rel
        differences = central(model, span, name, value, kw, step)
        for series, cd in differences.items():
            got = res.sensitivity(series, name)
            scale = max(np.max(np.abs(cd)), 1e-300)
            assert np.max(np.abs(got - cd)) <= tol * scale, (name, series, np.max(np.abs(got - cd)) / scale)
    return res


def test_double_pendulum_sensitivities_match_central_differences():
    model = models.double_pendulum(0.3, 0.2)
    kw = dict(initial={"theta_j1": -1.0, "theta_j2": -0.3}, velocity={"theta_j1": 0.0, "theta_j2": 0.4}, points=31)
    names = ["m_m1", "m_m2", "points_l1_end_0", "points_l2_end_0", "g_g", "theta_j2", "theta_j1'"]
    check_against_central(model, 3.0, kw, names, 1e-5)


def test_loudspeaker_sensitivities_match_central_differences():
    """A circuit driven by a step of 2 V into a moving coil: force factor and resistance, current and cone."""
    model = models.loudspeaker(E=2.0)
    kw = dict(initial={"q_Le": 0.0, "x_cone": 0.0}, velocity={"q_Le": 0.0, "x_cone": 0.0}, points=41)
    # (steps of 1e-3: the current's fast start (L/R = 83 µs) leaves plain runs errors of 1e-10 A, which smaller steps
    # of the central difference magnify past its truncation error)
    check_against_central(model, 0.02, kw, ["Bl_coil", "R_Re", "L_Le", "k_k"], 1e-5, rel=1e-3)


def test_first_order_coordinate_sensitivities_match_central_differences():
    """A Maxwell element (spring into a damper, no mass between them: x_a is first-order) on a mass: the rate of the
    first-order coordinate is no state, its sensitivity comes from the equations."""
    model = lg.Model("maxwell")
    model.add("mass", "m", "p", m=0.3)
    model.add("spring", "k1", ("ground", "p"), k=40.0)
    model.add("spring", "k2", ("p", "a"), k=25.0)
    model.add("damper", "c", ("a", "ground"), c=0.8)
    assert model.first_order == ["x_a"]
    kw = dict(initial={"x_p": 0.01, "x_a": 0.002}, velocity={"x_p": 0.1}, points=31)
    res = check_against_central(model, 2.0, kw, ["k_k2", "c_c", "m_m", "x_a", "x_p'"], 1e-6)
    np.testing.assert_allclose(res.sensitivity("x_a", "x_a")[0], 1.0)


@pytest.mark.parametrize("compiled", ["auto", False])
def test_symbolic_parameter_given_in_params_and_a_time_input(compiled):
    """A symbolic mass valued in params=, and a force that is a pulse of t (the run restarts at its corners): the
    sensitivities to the mass and the stiffness against central differences, in C and in NumPy."""
    model = lg.Model("pushed")
    model.add("mass", "m", "p", m=sp.Symbol("M", positive=True))
    model.add("spring", "k", ("ground", "p"), k=20.0)
    model.add("force", "F", "p", F=sp.Piecewise((1.5, (lg.t > 0.2) & (lg.t < 0.7)), (0.0, True)))
    kw = dict(initial={"x_p": 0.0}, velocity={"x_p": 0.0}, points=26)
    res = model.simulate(1.5, **kw, params={"M": 0.4}, rtol=1e-12, atol=1e-15, sensitivities=["M", "k_k"],
                         compiled=compiled)
    assert any("restarted" in n for n in res.notes)
    for name, value in (("M", 0.4), ("k_k", 20.0)):
        h = 1e-4 * value
        up = model.simulate(1.5, **kw, params={"M": 0.4, name: value + h} if name != "M" else {"M": value + h},
                            rtol=1e-12, atol=1e-15)
        down = model.simulate(1.5, **kw, params={"M": 0.4, name: value - h} if name != "M" else {"M": value - h},
                              rtol=1e-12, atol=1e-15)
        cd = (up["x_p"] - down["x_p"]) / (2 * h)
        assert np.max(np.abs(res.sensitivity("x_p", name) - cd)) <= 1e-6 * np.max(np.abs(cd))


def test_without_the_loop_in_c_scipy_integrates_and_says_so(monkeypatch):
    """No C compiler for the augmented right-hand side, or atol given per state: SciPy's DOP853, with a note."""
    from lagrangian.numerics import sensitivity, sensitivity_c

    kw = dict(initial={"x_p": 0.01}, velocity={"x_p": 0.0}, points=11, rtol=1e-11, sensitivities=["k_k"])
    reference = oscillator().simulate(1.0, **kw)
    per_state = oscillator().simulate(1.0, **kw, atol=[1e-14, 1e-13])
    assert any("atol given per state" in n for n in per_state.notes)
    monkeypatch.setattr(sensitivity_c, "compiler", lambda: None)
    monkeypatch.setattr(sensitivity, "_BUILT", type(sensitivity._BUILT)())
    monkeypatch.setattr(sensitivity_c, "_LAST", {})  # (the library this process loaded before)
    without = oscillator().simulate(1.0, **kw)
    assert any("not usable here" in n and "SciPy's DOP853" in n for n in without.notes)
    for res in (per_state, without):
        np.testing.assert_allclose(res.sensitivity("x_p", "k_k"), reference.sensitivity("x_p", "k_k"), rtol=1e-8,
                                   atol=1e-12 * np.max(np.abs(reference.sensitivity("x_p", "k_k"))))


def test_unknown_names_are_refused_naming_them_and_listing_the_known():
    model = oscillator()
    kw = dict(initial={"x_p": 0.01}, velocity={"x_p": 0.0}, points=3)
    with pytest.raises(lg.UnknownNameError, match=r"'k_k1'.*Did you mean 'k_k'.*Known: c_c, k_k, m_m, x_p, x_p'"):
        model.simulate(1.0, **kw, sensitivities=["k_k1"])
    with pytest.raises(lg.ModelError, match="list of names"):
        model.simulate(1.0, **kw, sensitivities="k_k")
    res = model.simulate(1.0, **kw, sensitivities=["k_k"])
    with pytest.raises(lg.UnknownNameError, match=r"'c_c'.*Known: k_k"):
        res.sensitivity("x_p", "c_c")
    with pytest.raises(lg.UnknownNameError, match=r"'x_q'.*Known: x_p, x_p'"):
        res.sensitivity("x_q", "k_k")


def test_first_order_rate_is_no_initial_condition():
    model = lg.Model("rc-like")
    model.add("mass", "m", "p", m=0.3)
    model.add("spring", "k2", ("p", "a"), k=25.0)
    model.add("damper", "c", ("a", "ground"), c=0.8)
    with pytest.raises(lg.ModelError, match="'x_a' of model 'rc-like' is first-order"):
        model.simulate(1.0, initial={"x_p": 0.01, "x_a": 0.0}, velocity={"x_p": 0.0}, sensitivities=["x_a'"])


def test_what_constraints_hold_events_or_callables_are_refused_by_name():
    model = lg.Model("rolling")
    model.add("mass", "body", "p", m=0.5)
    model.add("inertia", "I", "w", J=1e-3)
    model.add("force", "F", "p", F=1.0)
    model.add("constraint", "roll", f=lg.coordinate("x_p") - 0.05 * lg.coordinate("theta_w"))
    kw = dict(initial={"x_p": 0.0, "theta_w": 0.0}, velocity={"x_p": 0.0, "theta_w": 0.0}, points=3)
    with pytest.raises(lg.ModelError, match=r"'theta_w' is an initial value held by the constraints of model 'rolling' "
                                            r"\('roll'\)"):
        model.simulate(1.0, **kw, sensitivities=["m_body", "theta_w"])
    osc = oscillator()
    wall = lg.Event(lambda t, y: y[0] + 0.005, name="wall", terminal=True)
    with pytest.raises(lg.ModelError, match="has events \\('wall'\\)"):
        osc.simulate(1.0, initial={"x_p": 0.01}, velocity={"x_p": 0.0}, events=[wall], sensitivities=["k_k"])
    driven = oscillator()
    driven.add("force", "drive", "p", F=lambda t: np.sin(3 * t))
    with pytest.raises(lg.ModelError, match=r"Python callables \(.*\)"):
        driven.simulate(1.0, initial={"x_p": 0.01}, velocity={"x_p": 0.0}, sensitivities=["k_k"])
    for method in ("rk4", "exact", "auto"):
        with pytest.raises(lg.ModelError, match="not taken by a sensitivity run"):
            osc.simulate(1.0, initial={"x_p": 0.01}, velocity={"x_p": 0.0}, method=method,
                         step=0.01 if method == "rk4" else None, sensitivities=["k_k"])


def test_switches_of_the_state_or_of_an_asked_parameter_are_refused_by_name():
    """Coulomb friction (the sign of the rate) and a pulse whose end is the parameter asked make the sensitivities
    jump; a pulse of fixed times with another parameter asked, and Abs of the state (a bend, no jump), are taken."""
    kw = dict(initial={"x_p": 0.01}, velocity={"x_p": 0.0}, points=5)
    friction = oscillator()
    friction.add("force", "dry", "p", F=-0.05 * sp.sign(lg.rate("x_p")))
    with pytest.raises(lg.ModelError, match=r"switch on .*sign.*x_p"):
        friction.simulate(1.0, **kw, sensitivities=["k_k"])
    T = sp.Symbol("T", positive=True)
    pulsed = oscillator()
    pulsed.add("force", "push", "p", F=sp.Piecewise((1.0, lg.t < T), (0.0, True)))
    with pytest.raises(lg.ModelError, match=r"switch on .*where T crosses"):
        pulsed.simulate(1.0, **kw, params={"T": 0.3}, sensitivities=["T"])
    assert pulsed.simulate(1.0, **kw, params={"T": 0.3}, sensitivities=["k_k"]).sensitivity_names == ["k_k"]
    bent = oscillator()
    bent.add("force", "bend", "p", F=-2.0 * abs(lg.coordinate("x_p")))
    assert bent.simulate(1.0, **kw, sensitivities=["m_m"]).sensitivity_names == ["m_m"]


def test_no_sensitivities_is_a_plain_run():
    model = oscillator()
    kw = dict(initial={"x_p": 0.01}, velocity={"x_p": 0.0}, points=11)
    plain = model.simulate(1.0, **kw)
    for empty in ([], (), None):
        res = model.simulate(1.0, **kw, sensitivities=empty)
        np.testing.assert_array_equal(res["x_p"], plain["x_p"])
        assert res.notes == plain.notes and res.sensitivity_names == []
    with pytest.raises(lg.ModelError, match="computed no sensitivities"):
        plain.sensitivity("x_p", "k_k")


def test_results_and_models_with_sensitivities_pickle():
    """A result keeps its sensitivities through a pickle; a model that ran with them (its derivatives cached on its
    equations) pickles and runs again to the same numbers, bit for bit."""
    model = oscillator()
    kw = dict(initial={"x_p": 0.01}, velocity={"x_p": 0.0}, points=11, sensitivities=["k_k", "x_p"])
    res = model.simulate(1.0, **kw)
    back = pickle.loads(pickle.dumps(res))
    assert back.sensitivity_names == ["k_k", "x_p"]
    np.testing.assert_array_equal(back.sensitivity("x_p'", "k_k"), res.sensitivity("x_p'", "k_k"))
    again = pickle.loads(pickle.dumps(model)).simulate(1.0, **kw)
    for name in kw["sensitivities"]:
        np.testing.assert_array_equal(again.sensitivity("x_p", name), res.sensitivity("x_p", name))


def test_unset_initial_conditions_warn_as_in_a_plain_run():
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        oscillator().simulate(1.0, initial={"x_p": 0.01}, points=3, sensitivities=["k_k"])
    assert any(issubclass(w.category, lg.InitialConditionWarning) for w in seen)
