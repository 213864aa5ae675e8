"""Sensitivities of constrained models (Lagrange multipliers, Baumgarte-stabilized rows): a rolling oscillator
against the closed form of the oscillator it is, and a slider-crank against central differences of its runs."""

import re

import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings, strategies as st

import lagrangian as lg


def _closed_form():
    """x(t) of m ẍ + c ẋ + k x = 0 from (x0, 0), underdamped, written out here, and its derivatives by m, c, k."""
    t, m, c, k, x0 = sp.symbols("t m c k x0", positive=True)
    a = c / (2 * m)
    wd = sp.sqrt(k / m - a**2)
    x = sp.exp(-a * t) * x0 * (sp.cos(wd * t) + a / wd * sp.sin(wd * t))
    args = (t, m, c, k, x0)
    return {"x": sp.lambdify(args, x, "numpy"),
            **{name: sp.lambdify(args, sp.diff(x, p), "numpy") for name, p in (("m", m), ("c", c), ("k", k))}}


CLOSED = _closed_form()
R = sp.Symbol("r", positive=True)


def rolling():
    """A body of mass m on a spring and damper, rolling without slip on a wheel of inertia J and radius r:
    x = r·θ makes it the oscillator (m + J/r²) ẍ + c ẋ + k x = 0."""
    model = lg.Model("rolling oscillator")
    model.add("mass", "m", "p", m=0.3)
    model.add("spring", "k", ("ground", "p"), k=40.0)
    model.add("damper", "c", ("ground", "p"), c=0.5)
    model.add("inertia", "J", "w", J=2e-3)
    model.add("constraint", "roll", f=lg.coordinate("x_p") - R * lg.coordinate("theta_w"))
    return model


MODEL = rolling()


def decades(low, high):
    return st.floats(np.log10(low), np.log10(high)).map(lambda e: 10.0**e)


@settings(max_examples=12, deadline=None)
@given(m=decades(0.01, 10.0), J=decades(1e-5, 1e-1), r=decades(0.01, 0.5), k=decades(1.0, 1e4),
       zeta=st.floats(0.01, 0.5), x0=decades(1e-3, 1.0))
def test_a_rolling_oscillator_has_the_sensitivities_of_the_oscillator_it_is(m, J, r, k, zeta, x0):
    me = m + J / r**2
    c = 2 * zeta * np.sqrt(k * me)
    period = 2 * np.pi / np.sqrt(k / me)
    res = MODEL.simulate(2 * period, initial={"x_p": x0, "theta_w": x0 / r}, velocity={"x_p": 0.0, "theta_w": 0.0},
                         params={"m_m": m, "J_J": J, "r": r, "k_k": k, "c_c": c}, points=41, rtol=1e-11, atol=1e-14 * x0,
                         sensitivities=["m_m", "J_J", "k_k", "c_c"])
    t = res.t
    np.testing.assert_allclose(res["x_p"], CLOSED["x"](t, me, c, k, x0), rtol=0, atol=1e-7 * x0)
    dm = CLOSED["m"](t, me, c, k, x0)  # ∂x/∂m_eff
    expected = {"m_m": dm, "J_J": dm / r**2, "k_k": CLOSED["k"](t, me, c, k, x0), "c_c": CLOSED["c"](t, me, c, k, x0)}
    for name, exact in expected.items():
        scale = float(np.max(np.abs(exact)))
        np.testing.assert_allclose(res.sensitivity("x_p", name), exact, rtol=0, atol=1e-6 * scale, err_msg=name)
        # the wheel turns with the body: θ = x / r, and so do its sensitivities
        np.testing.assert_allclose(res.sensitivity("theta_w", name), exact / r, rtol=0, atol=1e-6 * scale / r,
                                   err_msg=name)


def test_what_the_constraints_hold_is_refused_by_name():
    kw = dict(initial={"x_p": 0.01, "theta_w": 0.2}, velocity={"x_p": 0.0, "theta_w": 0.0}, params={"r": 0.05},
              points=3)
    for name in ("r", "x_p", "theta_w'"):
        with pytest.raises(lg.ModelError, match=rf"{re.escape(repr(name))} is .* the constraints of model 'rolling oscillator' "
                                                r"\('roll'\): the start must satisfy them"):
            MODEL.simulate(1.0, **kw, sensitivities=[name])


def slider_crank() -> lg.Model:
    """A flywheel crank driving a slider through a rod under gravity: the joint B closes the loop (two constraint
    rows with multipliers)."""
    m = lg.Model("slider-crank", dim=2)
    m.add("disc", "crank", "crank", m=3.0, radius=1.0, points={"pin": (1.0, 0)})
    m.add("rod", "rod", "rod", m=0.5, length=3.0)
    m.add("body", "slider", "slider", m=1.0, inertia=0.05)
    m.add("revolute", "O", ("ground", "crank"), absolute=True)
    m.add("revolute", "A", ("crank", "rod"), parent_point=(1.0, 0), absolute=True)
    m.add("prismatic", "P", ("ground", "slider"))
    m.add("revolute", "B", ("rod", "slider"), parent_point=(3.0, 0))
    m.add("rotational_damper", "friction", ("ground", "crank"), c=0.07)
    m.add("gravity", "g")
    return m


def test_a_slider_crank_has_the_sensitivities_of_central_differences_of_its_runs():
    from lagrangian.plugins.multibody import consistent_initial

    model = slider_crank()
    q0, v0 = consistent_initial(model, {"theta_O": 0.3, "s_P": 3.9, "theta_A": -0.1}, {"theta_O": 5.0},
                                independent=["theta_O"])
    kw = dict(initial=q0, velocity=v0, points=21, rtol=1e-11, atol=1e-13)
    names = ["m_rod", "m_slider", "m_crank", "c_friction"]
    res = model.simulate(2.0, **kw, sensitivities=names)
    assert "30 variables" in res.notes[-1]  # (six states, four sensitivities)
    h = 1e-5
    for name in names:
        value = model.parameter_values[name]
        up = model.simulate(2.0, **kw, params={name: value * (1 + h)})
        down = model.simulate(2.0, **kw, params={name: value * (1 - h)})
        for c in model.coordinate_names:
            fd = (up[c] - down[c]) / (2 * h * value)
            assert np.max(np.abs(fd)) > 1e-3, (name, c)  # (each moves each coordinate)
            np.testing.assert_allclose(res.sensitivity(c, name), fd, rtol=0, atol=1e-7 * np.max(np.abs(fd)),
                                       err_msg=f"{c} by {name}")
    for name in ("theta_O", "theta_A'", "parent_point_A_0", "parent_point_B_0"):
        with pytest.raises(lg.ModelError, match="the constraints of model 'slider-crank' .its kinematic loops."):
            model.simulate(2.0, **kw, sensitivities=[name])


def test_a_constraint_on_velocities_has_the_sensitivities_of_central_differences():
    """ẋ_a = 2 ẋ_b held as a constraint on velocities: parameters, and the initial position it does not hold."""
    model = lg.Model("geared")
    model.add("mass", "a", "pa", m=0.3)
    model.add("mass", "b", "pb", m=0.7)
    model.add("spring", "k", ("ground", "pa"), k=40.0)
    model.add("damper", "c", ("ground", "pb"), c=0.4)
    model.add("velocity_constraint", "link", c=lg.rate("x_pa") - 2 * lg.rate("x_pb"))
    start = {"x_pa": 0.02, "x_pb": 0.0}
    kw = dict(velocity={"x_pa": 0.0, "x_pb": 0.0}, points=11, rtol=1e-11, atol=1e-14)
    names = ["m_a", "k_k", "c_c", "x_pa"]
    res = model.simulate(1.0, initial=start, **kw, sensitivities=names)
    h = 1e-5
    for name in names:
        value = model.parameter_values.get(name, start.get(name))
        if name in start:
            up = model.simulate(1.0, initial={**start, name: value * (1 + h)}, **kw)
            down = model.simulate(1.0, initial={**start, name: value * (1 - h)}, **kw)
        else:
            up = model.simulate(1.0, initial=start, **kw, params={name: value * (1 + h)})
            down = model.simulate(1.0, initial=start, **kw, params={name: value * (1 - h)})
        for c in model.coordinate_names:
            fd = (up[c] - down[c]) / (2 * h * value)
            np.testing.assert_allclose(res.sensitivity(c, name), fd, rtol=0, atol=1e-7 * np.max(np.abs(fd)),
                                       err_msg=f"{c} by {name}")
    with pytest.raises(lg.ModelError, match=r"\"x_pa'\" is an initial value held by the constraints of model "
                                            r"'geared' \('link'\)"):
        model.simulate(1.0, initial=start, **kw, sensitivities=["x_pa'"])


def test_the_numpy_path_gives_a_constrained_model_the_same_sensitivities():
    kw = dict(initial={"x_p": 0.01, "theta_w": 0.2}, velocity={"x_p": 0.0, "theta_w": 0.0}, params={"r": 0.05},
              points=11, rtol=1e-10, atol=1e-14, sensitivities=["m_m", "J_J", "c_c"])
    in_c = MODEL.simulate(1.0, **kw)
    numpy = MODEL.simulate(1.0, **kw, compiled=False)
    assert "NumPy" in numpy.notes[-1] and "compiled code" in in_c.notes[-1]
    for name in ("m_m", "J_J", "c_c"):
        for c in ("x_p", "theta_w", "x_p'"):
            a, b = in_c.sensitivity(c, name), numpy.sensitivity(c, name)
            np.testing.assert_allclose(b, a, rtol=0, atol=1e-6 * np.max(np.abs(a)), err_msg=f"{c} by {name}")


def test_a_slider_crank_is_fitted_to_a_noisy_record_of_its_crank():
    """The crank's friction and the rod's mass from 2 s of the crank angle with noise, by lg.fit's exact Jacobian:
    the true values within the fit's 3σ intervals."""
    from lagrangian.plugins.multibody import consistent_initial

    truth = slider_crank()
    q0, v0 = consistent_initial(truth, {"theta_O": 0.3, "s_P": 3.9, "theta_A": -0.1}, {"theta_O": 5.0},
                                independent=["theta_O"])
    t = np.linspace(0.0, 2.0, 201)
    run = truth.simulate((0.0, 2.0), t_eval=t, initial=q0, velocity=v0, rtol=1e-11)
    noisy = run["theta_O"] + 0.002 * np.random.default_rng(1).normal(size=t.size)
    data = lg.TimeSeries(t, {"theta_O": noisy}, initial=q0, velocity=v0)
    found = lg.fit(slider_crank(), data, ["c_friction", "m_rod"], start={"c_friction": 0.09, "m_rod": 0.6},
                   rtol=1e-9, atol=1e-11)
    bounds = found.interval(3.0)
    for name, value in (("c_friction", 0.07), ("m_rod", 0.5)):
        assert bounds[name][0] <= value <= bounds[name][1], (name, found.values[name], bounds[name])
        assert abs(found.values[name] / value - 1) < 0.02
