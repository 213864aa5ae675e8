"""A singular mass matrix says which case it is, whose coordinates, and what to do.

Each case is built from its physics, with ordinary values:

* an over-constrained loop: a bar pinned to the ground at both ends has one angle and two closure equations
  (its second pin repeats what the first imposes), at every configuration;
* a massless coordinate: a carriage without mass between two sliders along the same axis (only the sum of
  the two displacements carries inertia), and a slender rod on a ball joint (no moment about its own axis);
* a gimbal lock of the chosen angles: a top whose ``"zxz"`` nutation is 0 (precession and spin turn about one
  axis), and a body whose ``"xyz"`` pitch is π/2 — singular there only, each with a sequence whose lock is
  elsewhere, and the same start that the suggested sequence simulates without trouble.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me

import lagrangian as lg
from lagrangian.plugins.multibody import SEQUENCES


@pytest.fixture(autouse=True)
def _quiet():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lg.InitialConditionWarning)
        yield


def top(sequence="zxz", m=0.3, inertia=(0.3, 0.3, 0.5), l=0.4):
    model = lg.Model("top", dim=3)
    model.add("body", "top", "top", m=m, inertia=inertia, com=(0, 0, l))
    model.add("spherical", "ball", ("ground", "top"), sequence=sequence)
    model.add("gravity", "g", g=9.81, direction=(0, 0, -1))
    return model


def test_an_over_constrained_loop_is_named_with_its_coordinates_and_the_fix():
    m = lg.Model("pinned twice", dim=2)
    m.add("rod", "bar", "bar", m=0.3, length=0.7)
    m.add("revolute", "left", ("ground", "bar"))
    m.add("revolute", "right", ("bar", "ground"), parent_point=(0.7, 0), child_point=(0.7, 0))
    with pytest.raises(lg.SingularMassMatrixError) as info:
        m.simulate(0.1, initial={"theta_left": 0.0})
    text = str(info.value)
    assert "loop-closure constraints on theta_left" in text
    assert "dependent at every configuration: an over-constrained loop" in text
    assert "Remove the redundant joint" in text and "independent_coordinates" in text
    assert "gimbal" not in text and "massless" not in text


def test_a_massless_carriage_between_two_sliders_is_a_massless_coordinate():
    """Carriage (no mass) on a slider along x, a 0.3 kg block on a second slider along x on it:
    T = ½ m (ṡ₁ + ṡ₂)², so M = m [[1, 1], [1, 1]] is singular at every position, along ṡ₁ = −ṡ₂."""
    m = lg.Model("carriage", dim=2)
    m.add("link", "carriage", "carriage")
    m.add("body", "block", "block", m=0.3, inertia=0.02)
    m.add("prismatic", "rail", ("ground", "carriage"))
    m.add("prismatic", "slide", ("carriage", "block"))
    m.add("spring", "k", ("ground", "block.origin"), k=7.0)
    with pytest.raises(lg.SingularMassMatrixError) as info:
        m.simulate(0.1, initial={"s_rail": 0.3, "s_slide": 0.7})
    text = str(info.value)
    assert "the motion of s_rail, s_slide" in text
    assert "no inertia along 0.707·s_rail − 0.707·s_slide" in text or "no inertia along 0.707·s_slide − 0.707·s_rail" in text
    assert "at any configuration (a massless coordinate" in text
    assert "Give it inertia" in text and "first-order with a damper" in text
    assert "gimbal" not in text


def test_a_slender_rod_on_a_ball_joint_has_no_inertia_about_its_axis_at_any_angle():
    m = lg.Model("rod on a ball", dim=3)
    m.add("rod", "arm", "arm", m=0.3, length=0.7)
    m.add("spherical", "ball", ("ground", "arm"), sequence="zxz")  # the spin about x mixes all three rates
    m.add("gravity", "g")
    with pytest.raises(lg.SingularMassMatrixError) as info:
        m.simulate(0.1, initial={"phi_ball": 0.3, "theta_ball": 0.6, "psi_ball": 0.1})
    text = str(info.value)
    assert "of spherical joint 'ball'" in text and "at any configuration (a massless coordinate" in text
    assert "spin about its own axis" in text and "gimbal lock" not in text


def test_a_top_at_the_gimbal_lock_of_zxz_names_the_sequence_the_angle_and_another_sequence():
    model = top("zxz")
    with pytest.raises(lg.SingularMassMatrixError) as info:
        model.simulate(0.1, initial={"phi_ball": 0.3, "theta_ball": 0.0, "psi_ball": 0.2}, velocity={"psi_ball": 7.0})
    text = str(info.value)
    assert "the motion of phi_ball, psi_ball is not determined there" in text
    assert "spherical joint 'ball'" in text and "gimbal lock" in text and "this configuration only" in text
    assert 'sequence "zxz" is in gimbal lock where theta_ball = 0 or ±π' in text
    assert 'sequence="xyz" locks elsewhere' in text
    assert "theta_ball = 0" in text.split(":")[0]  # the state is quoted
    # the sequence suggested simulates the same upright start: body z along the parent's z, spinning at 7 rad/s
    res = top("xyz").simulate(0.5, initial={"alpha_ball": 0.0, "beta_ball": 0.0, "gamma_ball": 0.5},
                              velocity={"gamma_ball": 7.0}, rtol=1e-10, atol=1e-12)
    assert np.all(np.isfinite(res["beta_ball"])) and res.energy_drift() < 1e-7


def test_a_body_at_the_gimbal_lock_of_xyz_names_beta_and_suggests_zyz():
    model = top("xyz", inertia=(0.2, 0.3, 0.4))
    with pytest.raises(lg.SingularMassMatrixError) as info:
        model.simulate(0.1, initial={"alpha_ball": 0.1, "beta_ball": math.pi / 2, "gamma_ball": 0.2},
                       velocity={"gamma_ball": 0.7})
    text = str(info.value)
    assert "alpha_ball, gamma_ball" in text
    assert 'sequence "xyz" is in gimbal lock where beta_ball = ±π/2' in text and 'sequence="zyz"' in text


@pytest.mark.parametrize("sequence", SEQUENCES)
@pytest.mark.slow
def test_each_sequence_locks_where_its_description_says(sequence):
    """The lock the description states (middle angle at 0 for proper Euler, π/2 for Tait–Bryan; the body's last
    axis along the parent's first) is where sympy.physics.vector's angular velocity map loses rank, where our mass
    matrix of a body with three distinct moments is singular, and the suggested sequence's lock is where its
    description says too."""
    proper = sequence[0] == sequence[2]
    lock = 0.0 if proper else math.pi / 2
    q = me.dynamicsymbols("q1:4")
    N, B = me.ReferenceFrame("N"), me.ReferenceFrame("B")
    B.orient_body_fixed(N, q, sequence)
    at = {q[0]: 0.4, q[1]: lock, q[2]: -0.3}
    w = B.ang_vel_in(N).to_matrix(N)
    rates = [qi.diff(me.dynamicsymbols._t) for qi in q]
    Jw = np.array(w.jacobian(rates).subs(at), dtype=float)
    assert np.linalg.matrix_rank(Jw, tol=1e-12) == 2
    axis = {"x": B.x, "y": B.y, "z": B.z}[sequence[2]]
    first = {"x": N.x, "y": N.y, "z": N.z}[sequence[0]]
    assert abs(abs(float(axis.dot(first).subs(at))) - 1.0) < 1e-12

    model = top(sequence, inertia=(0.2, 0.3, 0.4))
    desc = model.coordinates[1].description
    assert f'sequence "{sequence}" is in gimbal lock where {model.coordinate_names[1]} = ' in desc
    eq = model.eq
    M = sp.lambdify(eq.sym.q, eq.M)
    s = np.linalg.svd(np.array(M(0.4, lock, -0.3), dtype=float), compute_uv=False)
    assert s[-1] < 1e-12 * s[0]
    s = np.linalg.svd(np.array(M(0.4, lock + 0.3, -0.3), dtype=float), compute_uv=False)
    assert s[-1] > 1e-3 * s[0]
    other = desc.split('sequence="')[1][:3]
    where = desc.split("locks elsewhere (the body's ")[1]
    body_axis, parent_axis = where[0], where.split("parent's ")[1][0]
    B2 = me.ReferenceFrame("B2")
    B2.orient_body_fixed(N, q, other)
    at2 = {q[0]: 0.4, q[1]: 0.0 if other[0] == other[2] else math.pi / 2, q[2]: -0.3}
    b = {"x": B2.x, "y": B2.y, "z": B2.z}[body_axis]
    n = {"x": N.x, "y": N.y, "z": N.z}[parent_axis]
    assert abs(abs(float(b.dot(n).subs(at2))) - 1.0) < 1e-12
    assert (body_axis, parent_axis) != (sequence[2], sequence[0])  # a different lock from the sequence's own
