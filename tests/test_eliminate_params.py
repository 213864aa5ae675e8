"""A symbolic parameter that cancels from the energies once a constraint eliminates a coordinate (``eliminate=``)
still belongs to the model: the eliminated coordinate's solution holds it.

A disc of mass m and inertia J = m R²/2 rolls with x = R θ, θ eliminated: T = ½ (m + J/R²) ẋ² = ¾ m ẋ², in which R
cancels, yet θ = x / R.  Pushed by F from rest: ẍ = F / (m + J/R²) = 2F / 3m, so x = F t² / 3m and θ = x / R; on a
spring k, the force to θ is 1 / (R ((m + J/R²) s² + k)).  Every expected value is that closed form.
"""

import math

import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

import lagrangian as lg
from lagrangian import frequency
from lagrangian.identity import equal

R = sp.Symbol("R", positive=True)


def decade(lo, hi):
    return st.floats(math.log10(lo), math.log10(hi)).map(lambda e: float(f"{10 ** e:.3g}"))


def rolling_disc(m, F, k=None):
    """A disc (J = m R²/2, R a symbol) rolling with x = R θ, θ eliminated; pushed by F, held by a spring k if given."""
    model = lg.Model("rolling disc")
    model.add("mass", "m", "p", m=m)
    model.add("inertia", "J", "w", J=m * R**2 / 2)
    model.add("constraint", "roll", f=lg.coordinate("x_p") - R * lg.coordinate("theta_w"), eliminate="theta_w")
    model.add("force", "F", "p", F=F)
    if k is not None:
        model.add("spring", "k", ("ground", "p"), k=k)
    return model


def test_the_cancelled_radius_is_a_parameter_of_the_model():
    """Regression: R cancels from T, and was dropped from the parameters (params={"R": ...} refused, res["theta_w"]
    unreadable).  It is a parameter before anything is derived, and a run without it is refused naming it."""
    model = rolling_disc(0.3, 0.2)
    assert model.coordinate_names == ["x_p"]
    assert [s.name for s in model.parameters] == ["R"]
    with pytest.raises(lg.ModelError, match=r"without values: R\. .*params=\{'R': \.\.\.\}"):
        model.simulate(1.0, initial={"x_p": 0.0}, velocity={"x_p": 0.0})


def test_the_eliminated_angle_is_read_back_with_the_radius_given():
    """The same model run with two radii: the centre moves alike (R cancels), θ = x / R with each."""
    m, F = 0.3, 0.2
    model = rolling_disc(m, F)
    runs = {r: model.simulate(1.0, initial={"x_p": 0.0}, velocity={"x_p": 0.0}, params={"R": r}, points=11)
            for r in (0.05, 0.12)}
    for r, res in runs.items():
        x = F * res.t**2 / (3 * m)
        assert np.max(np.abs(res["x_p"] - x)) < 1e-12 + 1e-10 * x[-1]
        assert np.max(np.abs(res["theta_w"] - x / r)) < 1e-10 * x[-1] / r
        assert np.max(np.abs(res.velocity("theta_w") - 2 * F * res.t / (3 * m * r))) < 1e-10 * F / (m * r)
        assert list(res.to_pandas().columns[:2]) == ["x_p", "theta_w"]


@settings(max_examples=10)
@given(m=decade(1e-2, 1e2), r=decade(1e-3, 1.0), F=decade(1e-2, 1e2), time=st.floats(0.1, 2.0))
def test_rolling_from_rest_over_decades_gives_theta_x_over_r(m, r, F, time):
    """ẍ = F / (m + J/R²) with J = m R²/2, θ = x / R, for masses, radii and forces over decades."""
    res = rolling_disc(m, F).simulate(time, initial={"x_p": 0.0}, velocity={"x_p": 0.0}, params={"R": r}, points=5)
    x = F * res.t**2 / (m + m / 2)
    assert res["x_p"] == pytest.approx(x / 2, rel=1e-9, abs=1e-12 * x[-1])
    assert res["theta_w"] == pytest.approx(x / (2 * r), rel=1e-9, abs=1e-12 * x[-1] / r)


@settings(max_examples=8)
@given(m=decade(1e-2, 1e2), r=decade(1e-3, 1.0), k=decade(1.0, 1e4), w=decade(0.1, 1e3))
def test_the_force_to_the_eliminated_angle_takes_the_radius_given(m, r, k, w):
    """F to θ = x / R on a spring k: 1 / (R ((m + J/R²) s² + k)) at s = jω, numerically with params={"R": ...}, and
    symbolically 1/R times the response of x."""
    model = rolling_disc(m, 0.0, k=k)
    s = 1j * w
    expected = 1 / (r * ((m + m / 2) * s**2 + k))
    tf = frequency.transfer_function(model, "F", "theta_w", params={"R": r})
    assert complex(tf(s)) == pytest.approx(expected, rel=1e-9)
    lin = frequency.linearize(model, inputs=["F"], outputs=["theta_w", "x_p"], symbolic=True)
    assert lin.parameters == [R]
    assert equal(lin.Cq[0][0, 0], 1 / R) and equal(lin.Cq[0][1, 0], 1)
