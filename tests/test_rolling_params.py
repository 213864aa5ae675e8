"""A rolling contact's parameters given anew in ``params=``, and given twice.

The constraint checks use the run's values: a ball built with one radius and run with another starts, rolls and is
checked on the other (its centre at height r, rolling at v = ω r).  A turntable given as an integer is the turntable
given as a float: in space a parameter that ``params=`` turns (a ball released on it circles at 2Ω/7), in the plane
zero or refused.  A disc's rolling contact takes the disc's radius: one radius, which ``params=`` moves for the
inertia and the rim together (a wheel pushed at its centre accelerates at 2F/3m and turns at ẍ/r); two radii given
that differ are refused by name.
"""

import functools
import math
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import lagrangian as lg
from lagrangian.plugins.multibody import consistent_initial, constraint_residual, independent_coordinates

G = 9.81
TIGHT = {"rtol": 1e-12, "atol": 1e-14}
ROLLING = ["x_j", "y_j", "alpha_j", "beta_j", "gamma_j"]  # a ball's free coordinates: its height follows


def decade(lo, hi):
    return st.floats(math.log10(lo), math.log10(hi)).map(lambda e: float(f"{10 ** e:.3g}"))


def ball(r=0.1, m=0.3, **rolling):
    """A uniform ball (I = 2/5 m r², a ``body``: no radius of its own) rolling on z = 0 on x-y-z angles."""
    model = lg.Model("ball", dim=3)
    inertia = 2 * m * r**2 / 5
    model.add("body", "b", "b", m=m, inertia=(inertia, inertia, inertia))
    model.add("free", "j", ("ground", "b"))
    model.add("rolling", "roll", "b", radius=r, shape="sphere", **rolling)
    model.add("gravity", "g", g=G)
    return model


@functools.lru_cache(maxsize=None)
def built_ball():
    return ball()


def start(z, **rates):
    names = built_ball().coordinate_names
    return {**dict.fromkeys(names, 0.0), "z_j": z}, {**dict.fromkeys(names, 0.0), **rates}


# -- defect: the constraint checks took the built values, not the run's -------------------------------------------


@pytest.mark.slow
def test_a_start_consistent_with_the_radius_given_in_params_is_accepted_and_keeps_rolling_at_v_equal_omega_r():
    """Built with r = 0.1, run with r = 0.2: at height 0.2, rolling along x at u = β̇ r (x-y-z angles at zero turn
    the ball about the body's y axis by β: the contact's slip v + ω × (−r ẑ) is (ẋ − r β̇, ẏ + r α̇)), it rolls on at
    u, with nothing pushing it."""
    model = built_ball()
    u, r = 0.3, 0.2
    initial, velocity = start(r, x_j=u, beta_j=u / r)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no energy drift: the start is the one the run's constraints hold
        res = model.simulate(1.0, initial=initial, velocity=velocity, params={"radius_roll": r}, points=11, **TIGHT)
    assert np.max(np.abs(res["z_j"] - r)) < 1e-12
    assert np.max(np.abs(res["x_j"] - u * res.t)) < 1e-10
    assert np.max(np.abs(res.v["beta_j"] - u / r)) < 1e-10
    assert constraint_residual(model, res) < 1e-12  # measured on the run's radius, not the built one


def test_a_start_that_breaks_the_constraint_of_the_radius_given_in_params_is_refused_by_name():
    model = built_ball()
    initial, velocity = start(0.1)  # the built radius: 0.1 below the run's
    with pytest.raises(lg.ModelError, match=r"does not satisfy the constraints of 'roll' \(\|Φ\| = 0\.1,.*"
                                            r"consistent_initial\(model, initial, velocity, params=params\)"):
        model.simulate(0.5, initial=initial, velocity=velocity, params={"radius_roll": 0.2}, points=3)
    initial, velocity = start(0.2, x_j=0.3, beta_j=0.3 / 0.1)  # rolling on the built radius: it slides on the run's
    with pytest.raises(lg.ModelError, match=r"initial rates of model 'ball' violate the constraints on velocities of "
                                            r"'roll' \(\|c\| = 0\.3\)"):
        model.simulate(0.5, initial=initial, velocity=velocity, params={"radius_roll": 0.2}, points=3)


@settings(max_examples=10, deadline=None)
@given(decade(1e-3, 1e2), st.floats(-30, 30), st.floats(-30, 30))
@pytest.mark.slow
def test_consistent_initial_solves_height_and_velocity_with_the_radius_given_in_params(r, wx, wy):
    """z = r, and (ẋ, ẏ) = (r β̇, −r α̇) from the turning rates, over radii across five decades."""
    model = built_ball()
    initial, _ = start(0.0)
    begun = consistent_initial(model, initial, {"alpha_j": wx, "beta_j": wy}, independent=ROLLING,
                               params={"radius_roll": r})
    assert begun.initial["z_j"] == pytest.approx(r, rel=1e-12)
    assert begun.velocity["x_j"] == pytest.approx(r * wy, rel=1e-12, abs=1e-14 * r)
    assert begun.velocity["y_j"] == pytest.approx(-r * wx, rel=1e-12, abs=1e-14 * r)
    assert independent_coordinates(model, begun.initial, params={"radius_roll": r}).residual < 1e-12 * r


# -- defect: a turntable given as the integer 0 was a parameter that params= took and ignored ---------------------


@pytest.mark.parametrize("built", [0, 0.0, 2, 2.0])
@pytest.mark.slow
def test_a_turntable_given_as_an_int_is_one_given_as_a_float_and_params_turns_it(built):
    """A uniform ball on a table turning at Ω circles at k = 2Ω/7: released at (a, 0) with velocity (0, u), rolling
    on the table, x = a + (u/k)(cos kt − 1), y = (u/k) sin kt — with Ω given in params=, whatever was built."""
    m, r, Omega, a, u = 0.05, 0.02, 3.3, 0.4, 0.15
    model = ball(r, m, turntable=built)
    assert model.parameter_values["turntable_roll"] == float(built)
    names = model.coordinate_names
    res = model.simulate(3.0, initial={**dict.fromkeys(names, 0.0), "x_j": a, "z_j": r},
                         velocity={**dict.fromkeys(names, 0.0), "y_j": u, "alpha_j": (Omega * a - u) / r},
                         params={"turntable_roll": Omega}, points=31, **TIGHT)
    k = 2 * Omega / 7
    assert np.max(np.abs(res["x_j"] - (a + u / k * (np.cos(k * res.t) - 1)))) < 1e-9
    assert np.max(np.abs(res["y_j"] - u / k * np.sin(k * res.t))) < 1e-9


def wheel(**rolling):
    """A uniform disc rolling on the line y = 0 (the plane), pushed at its centre by 0.2 N along x."""
    model = lg.Model("wheel", dim=2)
    model.add("disc", "d", "d", m=0.4, radius=0.1)
    model.add("free", "j", ("ground", "d"))
    model.add("rolling", "roll", "d", **rolling)
    model.add("gravity", "g", g=G)
    model.add("force", "push", "d", F=[0.2, 0])
    return model


@pytest.mark.parametrize("zero", [0, 0.0])
def test_a_turntable_given_as_zero_in_the_plane_is_none_and_no_parameter(zero):
    model = wheel(radius=0.1, turntable=zero)
    assert "turntable_roll" not in model.parameter_values
    assert len(model.eq.velocity_constraints) == 1
    with pytest.raises(lg.UnknownNameError, match="unknown parameter 'turntable_roll'"):
        model.simulate(0.1, initial={"y_j": 0.1}, params={"turntable_roll": 2.0})


@pytest.mark.parametrize("spin", [1, 0.5])
def test_a_turntable_in_the_plane_is_refused_as_an_int_as_a_float(spin):
    with pytest.raises(lg.ModelError, match=r"rolling 'roll': a turntable turns the ground of a model in space"):
        wheel(radius=0.1, turntable=spin).eq  # noqa: B018


# -- defect: a disc's radius and its contact's were two parameters nothing tied ------------------------------------


def pushed(model, r, params=None):
    """The wheel pushed from rest at height r: x = a t²/2 with a = F/(m + I/r²) = 2F/3m, and θ = −x/r (rolling)."""
    res = model.simulate(1.0, initial={"x_j": 0.0, "y_j": r, "theta_j": 0.0},
                         velocity={"x_j": 0.0, "y_j": 0.0, "theta_j": 0.0}, params=params, points=11, **TIGHT)
    a = 2 * 0.2 / (3 * 0.4)
    assert np.max(np.abs(res["x_j"] - a * res.t**2 / 2)) < 1e-10
    assert np.max(np.abs(res["theta_j"] + res["x_j"] / r)) < 1e-9
    assert np.max(np.abs(res["y_j"] - r)) < 1e-12


@pytest.mark.parametrize("rolling", [{}, {"radius": 0.1}])
def test_a_disc_rolls_on_its_own_radius_which_params_moves_with_its_inertia(rolling):
    model = wheel(**rolling)
    assert [k for k in model.parameter_values if k.startswith("radius")] == ["radius_d"]
    pushed(model, 0.1)
    pushed(model, 0.25, params={"radius_d": 0.25})  # the rim and the inertia together: a and θ = −x/r hold


def test_the_contact_radius_alone_in_params_is_refused_naming_the_discs():
    model = wheel(radius=0.1)
    with pytest.raises(lg.UnknownNameError, match=r"unknown parameter 'radius_roll'\. Did you mean 'radius_d'\?"):
        model.simulate(0.1, initial={"y_j": 0.1}, params={"radius_roll": 0.25})


@settings(max_examples=10, deadline=None)
@given(decade(1e-3, 1e2))
@pytest.mark.slow
def test_the_default_contact_radius_follows_the_disc_over_decades(r):
    """ẍ = 2F/3m whatever the radius, and θ̈ = −ẍ/r with the disc's radius given in params=."""
    model = built_wheel()
    acc = model.numeric({"radius_d": r}).rhs(0.0, np.array([0.0, r, 0.0, 0.0, 0.0, 0.0]))[3:]
    a = 2 * 0.2 / (3 * 0.4)
    assert acc[0] == pytest.approx(a, rel=1e-12)
    assert acc[2] == pytest.approx(-a / r, rel=1e-12)
    # held on the ground: zero to the round-off of the solve that balances gravity, whose conditioning grows with
    # the inertia m r²/2 against the mass
    assert abs(acc[1]) < 1e-13 * G * max(1.0, r * r)


@functools.lru_cache(maxsize=None)
def built_wheel():
    return wheel()


@pytest.mark.parametrize(("disc", "contact", "shown"), [(0.1, 0.07, ("0.07", "0.1")), (0.1, "r", ("r", "0.1"))])
def test_a_contact_radius_other_than_the_discs_is_refused_naming_both(disc, contact, shown):
    import sympy as sp

    model = wheel(radius=sp.Symbol(contact, positive=True) if isinstance(contact, str) else contact)
    with pytest.raises(lg.ParameterError, match=rf"component 'roll', parameter 'radius': rolling 'roll' has radius "
                                                rf"{shown[0]} but rolls on disc 'd', whose radius is {shown[1]}.*Leave "
                                                rf"radius= out of rolling 'roll'"):
        model.eq  # noqa: B018


def test_a_body_without_a_radius_needs_the_contacts():
    model = lg.Model("ball", dim=3)
    model.add("body", "b", "b", m=0.3, inertia=(1.2e-3, 1.2e-3, 1.2e-3))
    model.add("free", "j", ("ground", "b"))
    model.add("rolling", "roll", "b", shape="sphere")
    with pytest.raises(lg.ParameterError, match=r"component 'roll', parameter 'radius': required: .*body 'b', which "
                                                r"has no radius of its own"):
        model.eq  # noqa: B018
