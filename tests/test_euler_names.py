"""The names of a spherical or free joint's angles follow its ``sequence``: a Tait–Bryan angle is named after the axis
it turns about (alpha about x, beta about y, gamma about z; ``"xyz"``, the default, keeps alpha, beta, gamma), a proper
Euler sequence's are precession, nutation and spin (phi, theta, psi).  Checked against sympy.physics.vector's
``orient_body_fixed`` (which angle turns about which axis), against the physics (a body on a ball joint under gravity
along −z keeps only its turn about z ignorable), and in the gimbal lock's error."""

import math
import warnings

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me

import lagrangian as lg
from lagrangian.plugins.multibody import PROPER_EULER, TAIT_BRYAN

AXIS = {"alpha": "x", "beta": "y", "gamma": "z"}

#: the convention, written out: each sequence's coordinate names in its order
NAMES = {
    "xyz": ["alpha", "beta", "gamma"], "xzy": ["alpha", "gamma", "beta"], "yxz": ["beta", "alpha", "gamma"],
    "yzx": ["beta", "gamma", "alpha"], "zxy": ["gamma", "alpha", "beta"], "zyx": ["gamma", "beta", "alpha"],
    **{s: ["phi", "theta", "psi"] for s in PROPER_EULER},
}


def on_a_ball(sequence, kind="spherical"):
    model = lg.Model("body", dim=3)
    model.add("body", "b", "b", m=0.3, inertia=(0.011, 0.017, 0.023), com=(0.02, -0.03, 0.1))
    model.add(kind, "j", ("ground", "b"), sequence=sequence)
    model.add("gravity", "g", g=9.81, direction=(0, 0, -1))
    return model


@pytest.mark.parametrize("sequence", TAIT_BRYAN + PROPER_EULER)
def test_each_sequence_names_its_angles_by_the_convention(sequence):
    assert on_a_ball(sequence).coordinate_names == [f"{n}_j" for n in NAMES[sequence]]
    free = on_a_ball(sequence, kind="free")
    assert free.coordinate_names == ["x_j", "y_j", "z_j", *(f"{n}_j" for n in NAMES[sequence])]


@pytest.mark.parametrize("sequence", TAIT_BRYAN)
def test_the_angle_named_after_an_axis_turns_about_it_as_sympy_vector_says(sequence):
    """Our rotation with each angle given by name equals sympy.physics.vector's body-fixed rotation with the angle
    about axis x, y, z given alpha's, beta's, gamma's value."""
    by_name = {"alpha": 0.37, "beta": -0.81, "gamma": 1.93}
    model = on_a_ball(sequence)
    R = model.assembly.views["mechanical"].poses["b"].R
    ours = np.array(R.xreplace({c.function: by_name[c.name.split("_")[0]] for c in model.coordinates}), dtype=float)
    N, B = me.ReferenceFrame("N"), me.ReferenceFrame("B")
    names = {axis: name for name, axis in AXIS.items()}
    B.orient_body_fixed(N, [by_name[names[axis]] for axis in sequence], sequence)
    theirs = np.array(N.dcm(B), dtype=float)
    assert np.max(np.abs(ours - theirs)) < 1e-14
    descriptions = {c.name: c.description for c in model.coordinates}
    for k, axis in enumerate(sequence):
        name = f"{names[axis]}_j"
        assert descriptions[name].startswith(f"{('first', 'second', 'third')[k]} angle (about the body's {axis} axis)")


@pytest.mark.parametrize("sequence", ["zyx", "zxy"])
def test_the_angle_about_the_vertical_is_the_ignorable_one_under_gravity_along_z(sequence):
    """A turn about the vertical (first in these sequences) leaves the Lagrangian of a body on a ball joint under
    gravity along −z unchanged: that angle, named gamma (about z), is ignorable, and no other."""
    from lagrangian import routh

    assert routh.ignorable(on_a_ball(sequence)) == ["gamma_j"]


@pytest.mark.slow
def test_a_gimbal_lock_error_names_the_middle_angle_by_its_axis():
    """"xzy" locks where its second angle, about z (gamma), is ±π/2 (the body's y axis along the parent's x)."""
    model = on_a_ball("xzy")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lg.InitialConditionWarning)
        with pytest.raises(lg.SingularMassMatrixError) as info:
            model.simulate(0.1, initial={"alpha_j": 0.1, "gamma_j": math.pi / 2, "beta_j": 0.2},
                           velocity={"beta_j": 0.7})
    text = str(info.value)
    assert "the motion of alpha_j, beta_j is not determined there" in text
    assert "alpha_j: first angle (about the body's x axis)" in text and "beta_j: third angle (about the body's y axis)" in text
    assert 'sequence "xzy" is in gimbal lock where gamma_j = ±π/2' in text
    # sympy.physics.vector: the angular velocity loses rank where the angle about z (second) is π/2
    q = me.dynamicsymbols("q1:4")
    N, B = me.ReferenceFrame("N"), me.ReferenceFrame("B")
    B.orient_body_fixed(N, q, "xzy")
    w = B.ang_vel_in(N).to_matrix(N).jacobian([x.diff(me.dynamicsymbols._t) for x in q])
    assert np.linalg.matrix_rank(np.array(w.subs({q[0]: 0.1, q[1]: sp.pi / 2, q[2]: 0.2}), dtype=float), tol=1e-12) == 2


def test_a_bad_sequence_says_how_the_angles_are_named():
    with pytest.raises(lg.ParameterError, match=r"each angle named after its axis: alpha about x, beta about y, gamma "
                                                r"about z.*the default is 'xyz'"):
        lg.Model("m", dim=3).add("spherical", "j", ("ground", "b"), sequence="zyy")
