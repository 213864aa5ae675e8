"""A reduced model keeps the parameters given as numbers as symbols with values, like the full model.

Expected values: the closed-form effective potential of the spherical
pendulum, ``V_eff = C²/(2 m l² sin²θ) − m g l cos θ``, and the full model
simulated with the same values.
"""

import math
import warnings

import numpy as np
import pytest
from sympy.core.function import AppliedUndef

import lagrangian as lg
from lagrangian import models, routh


@pytest.fixture(autouse=True)
def _quiet():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        yield


def v_eff(red, theta, C):
    (angle,) = red.effective_potential.atoms(AppliedUndef)
    return float(red.effective_potential.xreplace({angle: theta, red.momenta["theta_turn"]: C}))


def test_models_sharing_a_structure_each_keep_their_own_values():
    # reduced one after another (the second reuses the first's symbolic work): each has its own numbers
    for m, length, g in ((0.3, 0.7, 9.81), (2.9e-3, 41.0, 1.62), (0.3, 0.7, 9.81), (17.0, 0.7, 3.71)):
        red = routh.reduce(models.spherical_pendulum(m, length, g))
        for theta, C in ((0.4, 0.021), (2.2, 1.3)):
            want = C**2 / (2 * m * length**2 * math.sin(theta) ** 2) - m * g * length * math.cos(theta)
            assert v_eff(red, theta, C) == pytest.approx(want, rel=1e-12)


def test_a_reduced_model_takes_other_values_at_run_time():
    red = routh.reduce(models.spherical_pendulum(0.3, 0.7, 9.81))
    # the bob's point on the arm (0, 0, −0.7) is a value too: its nonzero entry
    assert red.parameter_values == {"m_bob": 0.3, "g_g": 9.81, "points_arm_bob_2": -0.7}
    start = {"theta_tilt": 0.4, "theta_turn": 0.0}
    speed = {"theta_tilt": 0.0, "theta_turn": 1.9}
    opts = dict(rtol=1e-11, atol=1e-12)
    other = {"m_bob": 0.45, "g_g": 3.7, "points_arm_bob_2": -1.3}
    got = red.simulate(2, initial=start, velocity=speed, params=other, **opts)
    rebuilt = routh.reduce(models.spherical_pendulum(0.45, 1.3, 3.7))
    want = rebuilt.simulate(2, initial=start, velocity=speed, **opts)
    np.testing.assert_allclose(got["theta_tilt"], want["theta_tilt"], rtol=0, atol=1e-10)
    full = models.spherical_pendulum(0.3, 0.7, 9.81).simulate(2, initial=start, velocity=speed, params=other, **opts)
    np.testing.assert_allclose(np.interp(full.t, got.t, got["theta_tilt"]), full["theta_tilt"], atol=1e-7)


def test_an_entry_of_a_vector_keeps_its_sign():
    model = models.spherical_pendulum(0.3, 0.7, 9.81)
    with pytest.raises(lg.ParameterError, match=r"'points_arm_bob_2' was given as a negative number .* must be negative"):
        model.simulate(1, initial={"theta_tilt": 0.3}, params={"points_arm_bob_2": 0.5})
