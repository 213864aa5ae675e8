"""A singular mass matrix says which case it is and what to do.

The case built here from its physics: the spherical pendulum at its pole
in azimuth–tilt angles, where the azimuth has no inertia.
"""

import pytest

import lagrangian as lg
from lagrangian import models


def test_a_pole_of_the_angles_is_called_a_gimbal_lock_naming_the_angle():
    model = models.spherical_pendulum(0.3, 0.7)
    with pytest.raises(lg.SingularMassMatrixError, match=r"theta_turn is not determined.*gimbal lock.*other angles"):
        model.simulate(0.1, initial={"theta_tilt": 0.0, "theta_turn": 0.4}, velocity={"theta_tilt": 0.2, "theta_turn": 0.0})

