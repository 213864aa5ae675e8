"""Holonomic constraints users write between coordinates — ``constraint``, ``gear``, ``rack_and_pinion`` — kept with
multipliers, checked against sympy.physics.mechanics built independently (the constraint eliminated by hand) and
against closed forms."""

import math

import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

import lagrangian as lg
from lagrangian import frequency
from lagrangian.plugins.multibody import consistent_initial, independent_coordinates


def decade(lo, hi):
    return st.floats(math.log10(lo), math.log10(hi)).map(lambda e: float(f"{10 ** e:.3g}"))


def rack(m, k, J, r, c=0.0):
    model = lg.Model("rack and pinion")
    model.add("mass", "rack", "p", m=m)
    model.add("spring", "k", ("ground", "p"), k=k)
    if c:
        model.add("damper", "c", ("ground", "p"), c=c)
    model.add("inertia", "J", "s", J=J)
    model.add("rack_and_pinion", "mesh", rack="x_p", pinion="theta_s", radius=r)
    return model


@settings(max_examples=15)
@given(decade(0.05, 20), decade(1.0, 1e4), decade(1e-5, 1e-1), decade(5e-3, 0.2), decade(1e-3, 10),
       st.floats(-2, 2), st.floats(-20, 20))
@pytest.mark.slow
def test_rack_and_pinion_accelerations_match_kane_over_decades(kane_rack, m, k, J, r, c, theta, omega):
    model = rack(m, k, J, r, c)
    y = np.array([r * theta, theta, r * omega, omega])  # on the constraint: x = r θ
    ours = model.numeric().rhs(0.0, y)[3]
    reference = kane_rack(m, k, J, r, c)(theta, omega)
    assert ours == pytest.approx(reference, rel=1e-9, abs=1e-12 * (k * r * r * abs(theta) + c * r * r * abs(omega)) / J)
    if abs(theta) > 1e-6:  # consistent_initial closes the constraint to its absolute tolerance
        q0, v0 = consistent_initial(model, {"theta_s": theta}, {"theta_s": omega})
        assert q0["x_p"] == pytest.approx(r * theta, rel=1e-10, abs=1e-14)
        assert v0["x_p"] == pytest.approx(r * omega, rel=1e-10, abs=1e-14)


def test_rack_and_pinion_oscillates_at_the_closed_form_frequency_and_keeps_its_energy():
    m, k, J, r = 0.5, 20.0, 1e-3, 0.02
    model = rack(m, k, J, r)
    w = math.sqrt(k / (m + J / r**2))
    res = model.simulate(3.0, initial={"x_p": 0.01, "theta_s": 0.5}, velocity={"x_p": 0.0, "theta_s": 0.0},
                         points=301, rtol=1e-11, atol=1e-14)
    assert np.max(np.abs(res["x_p"] - 0.01 * np.cos(w * res.t))) < 1e-10
    assert np.max(np.abs(res["x_p"] - r * res["theta_s"])) < 1e-12
    assert np.ptp(res.E) < 1e-9 * res.E[0]
    modes = frequency.modes(frequency.linearize(model, inputs=[]))
    assert modes.omega[0] == pytest.approx(w, rel=1e-10)
    part = independent_coordinates(model, {"x_p": 0.01, "theta_s": 0.5})
    assert part.dof == 1 and part.constraints == 1


def gear_train(J1, J2, J3, N1, N2a, N2b, N3, k, internal=False):
    """Shaft 1 driven by a torque sin t; gear 1 meshes gear 2a, gear 2b (on shaft 2) meshes gear 3; a torsion
    spring holds shaft 3."""
    model = lg.Model("gear train")
    for name, J in (("s1", J1), ("s2", J2), ("s3", J3)):
        model.add("inertia", f"J{name}", name, J=J)
    model.add("torque", "drive", "s1", tau=sp.sin(lg.t))
    model.add("torsion_spring", "k3", ("ground", "s3"), k=k)
    model.add("gear", "g12", a="theta_s1", b="theta_s2", teeth_a=N1, teeth_b=N2a)
    model.add("gear", "g23", a="theta_s2", b="theta_s3", teeth_a=N2b, teeth_b=N3, internal=internal)
    return model


@settings(max_examples=10)
@given(decade(1e-4, 1), decade(1e-4, 1), decade(1e-4, 1), st.integers(8, 80), st.integers(8, 80), st.integers(8, 80),
       st.integers(8, 80), decade(0.1, 100), st.booleans(), st.floats(-3, 3), st.floats(-5, 5), st.floats(0, 6))
@pytest.mark.slow
def test_a_gear_train_matches_kane_over_decades(kane_gear_train, J1, J2, J3, N1, N2a, N2b, N3, k, internal, theta, omega,
                                                time):
    model = gear_train(J1, J2, J3, N1, N2a, N2b, N3, k, internal)
    # θ2 = −(N1/N2a) θ1; θ3 = ∓(N2b/N3) θ2 (external: opposite senses; internal: the same)
    n2 = -N1 / N2a
    n3 = n2 * (N2b / N3) * (1 if internal else -1)
    reference = kane_gear_train(J1, J2, J3, n2, n3, k, theta, omega, time)
    ratio = {"theta_s1": 1.0, "theta_s2": n2, "theta_s3": n3}  # the state on the constraints
    y = np.array([ratio[n] * theta for n in model.coordinate_names] + [ratio[n] * omega for n in model.coordinate_names])
    ours = model.numeric().rhs(time, y)[3]
    if abs(theta) > 1e-6:  # consistent_initial closes the constraints to its absolute tolerance
        q0, _ = consistent_initial(model, {"theta_s1": theta}, {"theta_s1": omega})
        assert q0["theta_s3"] == pytest.approx(n3 * theta, rel=1e-10, abs=1e-14)
    assert ours == pytest.approx(reference, rel=1e-9, abs=1e-9 * (1 + k * abs(theta)) / min(J1, J2, J3))


@settings(max_examples=10)
@given(decade(0.05, 50), decade(0.01, 1), st.floats(0.05, 1.4), st.sampled_from([0.5, 0.4, 1.0]))
def test_rolling_without_slipping_down_an_incline_accelerates_at_the_closed_form(m, R, alpha, shape):
    """A disc (I = ½ m R²), a sphere (⅖ m R²) or a hoop (m R²) rolling down an incline: s = R θ, so
    s̈ = g sin α / (1 + I / (m R²))."""
    g = 9.81
    model = lg.Model("rolling")
    model.add("mass", "body", "p", m=m)
    model.add("force", "weight", "p", F=m * g * math.sin(alpha))
    model.add("inertia", "I", "w", J=shape * m * R**2)
    model.add("constraint", "roll", f=lg.coordinate("x_p") - R * lg.coordinate("theta_w"))
    res = model.simulate(2.0, initial={"x_p": 0.0, "theta_w": 0.0}, velocity={"x_p": 0.0, "theta_w": 0.0},
                         points=21, rtol=1e-12, atol=1e-14)
    a = g * math.sin(alpha) / (1 + shape)
    assert np.max(np.abs(res["x_p"] - 0.5 * a * res.t**2)) <= 1e-9 * 0.5 * a * 4
    assert np.max(np.abs(res["theta_w"] * R - res["x_p"])) <= 1e-10 * 0.5 * a * 4


def test_slips_in_constraints_get_errors_that_name_the_fix():
    model = rack(0.5, 20.0, 1e-3, 0.02)
    with pytest.raises(lg.ModelError, match=r"does not satisfy the constraints of 'mesh'.*consistent_initial"):
        model.simulate(1.0, initial={"x_p": 0.01, "theta_s": 0.0}, velocity={"x_p": 0.0, "theta_s": 0.0})
    with pytest.raises(lg.ModelError, match="the constraints of 'mesh'.*covers unconstrained models"):
        model.simulate(1.0, initial={"x_p": 0.01, "theta_s": 0.5}, velocity={"x_p": 0.0, "theta_s": 0.0},
                       method="exact")
    auto = model.simulate(1.0, initial={"x_p": 0.01, "theta_s": 0.5}, velocity={"x_p": 0.0, "theta_s": 0.0},
                          method="auto", points=3)
    assert auto.method == "DOP853"
    bad = lg.Model("bad")
    bad.add("mass", "m1", "p", m=1)
    bad.add("constraint", "c1", f=lg.coordinate("x_q") - 1)
    with pytest.raises(lg.ModelError, match=r"x_q\(t\), which is not a coordinate of the model\. Did you mean 'x_p'\?"):
        bad.equations
    rate = lg.Model("rate")
    rate.add("mass", "m1", "p", m=1)
    rate.add("constraint", "c1", f=lg.rate("x_p") - 1)
    with pytest.raises(lg.ModelError, match="holds a rate.*nonholonomic"):
        rate.equations
    empty = lg.Model("empty")
    empty.add("mass", "m1", "p", m=1)
    empty.add("constraint", "c1", f=sp.sin(lg.t))
    with pytest.raises(lg.ModelError, match="holds no coordinate"):
        empty.equations
