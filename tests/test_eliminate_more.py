"""Coordinates eliminated by a holonomic constraint (``eliminate=``) where users meet them beyond ``Model.simulate``:
as outputs of a linearization (transfer functions, frequency responses), in the results of impacts and of stick–slip
runs, and the refusals of ``linearize(at=)``, ``consistent_initial`` and ``independent_coordinates`` naming one.
Every expected value is a closed form derived here (the rack carries the effective mass m + J / r²)."""

import math

import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

import lagrangian as lg
from lagrangian import frequency
from lagrangian.impulse import ground, simulate_with_impacts
from lagrangian.plugins.multibody import consistent_initial, independent_coordinates
from lagrangian.stick_slip import simulate as stick_slip


def decade(lo, hi):
    return st.floats(math.log10(lo), math.log10(hi)).map(lambda e: float(f"{10 ** e:.3g}"))


def rack(m, k, J, r, c, eliminate, F=0.0):
    """A rack (mass m on a spring k and a damper c, driven by a force F) meshing a pinion of inertia J and radius r."""
    model = lg.Model("rack and pinion")
    model.add("mass", "rack", "p", m=m)
    model.add("spring", "k", ("ground", "p"), k=k)
    model.add("damper", "c", ("ground", "p"), c=c)
    model.add("force", "F", "p", F=F)
    model.add("inertia", "J", "s", J=J)
    model.add("rack_and_pinion", "mesh", rack="x_p", pinion="theta_s", radius=r, eliminate=eliminate)
    return model


# --- outputs of a linearization -----------------------------------------------------------------------------------

@settings(max_examples=8, deadline=None)
@given(decade(0.05, 20), decade(1.0, 1e4), decade(1e-5, 1e-1), decade(5e-3, 0.2), decade(1e-3, 10),
       st.sampled_from(["theta_s", "x_p"]), decade(0.1, 1e3))
@pytest.mark.slow
def test_the_eliminated_coordinate_is_an_output_of_the_transfer_function(m, k, J, r, c, which, w):
    """F on the rack to θ = x / r: 1 / (r ((m + J/r²) s² + c s + k)); to x: r times that; rates and the SymPy
    coordinate multiply by s — whichever of x, θ the constraint eliminated."""
    model = rack(m, k, J, r, c, which)
    s = 1j * w
    H_x = 1 / ((m + J / r**2) * s**2 + c * s + k)
    expected = {"theta_s": H_x / r, "theta_s'": s * H_x / r, "theta_s''": s**2 * H_x / r, "x_p": H_x,
                "x_p'": s * H_x}
    lin = frequency.linearize(model, inputs=["F"], outputs=list(expected) + [lg.coordinate(which)])
    assert lin.coordinates == (["x_p"] if which == "theta_s" else ["theta_s"])
    H = frequency.frequency_response(lin, [w / (2 * math.pi)]).H[:, 0, 0]
    for label, value in zip(lin.outputs, H):
        ref = expected[label if label in expected else which]
        assert value == pytest.approx(ref, rel=1e-9), label
    tf = frequency.transfer_function(model, "F", which)
    assert complex(tf(s)) == pytest.approx(expected[which], rel=1e-9)


def test_the_eliminated_angle_is_an_output_at_an_operating_point_and_of_a_rheonomic_constraint():
    """The pinion's θ = x / r at a displaced operating point x₀ (a force F₀ = k x₀ holds it): y₀ = x₀ / r; and
    x_a = x_b + A sin ωt linearized at t₀: y₀ = A sin ωt₀ with x_b at 0, and the output's row that of x_b."""
    m, k, J, r, c, x0 = 0.3, 40.0, 2e-3, 0.025, 0.5, 7e-3
    model = rack(m, k, J, r, c, "theta_s", F=k * x0)
    lin = frequency.linearize(model, at={"x_p": x0}, inputs=[], outputs=["theta_s", "theta_s'"])
    assert float(lin.y0["theta_s"]) == pytest.approx(x0 / r, rel=1e-12)
    assert float(lin.y0["theta_s'"]) == 0.0
    assert float(lin.Cq[0][0, 0]) == pytest.approx(1 / r, rel=1e-12)
    assert float(lin.Cq[1][1, 0]) == pytest.approx(1 / r, rel=1e-12)
    A, w, t0 = 0.02, 7.0, 0.3
    shaker = lg.Model("shaker")
    shaker.add("mass", "ma", "a", m=0.3)
    shaker.add("mass", "mb", "b", m=0.5)
    shaker.add("spring", "kb", ("ground", "b"), k=20.0)
    shaker.add("constraint", "drive", f=lg.coordinate("x_a") - lg.coordinate("x_b") - A * sp.sin(w * lg.t),
               eliminate="x_a")
    lin = frequency.linearize(shaker, inputs=[], outputs=["x_a"], time=t0, at={"x_b": 0.0})
    assert float(lin.y0["x_a"]) == pytest.approx(A * math.sin(w * t0), rel=1e-12)
    assert float(lin.Cq[0][0, 0]) == pytest.approx(1.0, rel=1e-14)


def test_an_unknown_output_lists_the_eliminated_coordinates_too():
    model = rack(0.3, 40.0, 2e-3, 0.025, 0.5, "theta_s")
    with pytest.raises(lg.UnknownNameError, match=r"'theta_z'.*theta_s"):
        frequency.linearize(model, inputs=["F"], outputs=["theta_z"])


# --- results of impacts and of stick–slip -------------------------------------------------------------------------

def test_a_rack_dropped_on_the_ground_turns_its_pinion_by_the_closed_form():
    """A rack of mass m falls under gravity driving a pinion (J, r; θ = x / r eliminated): it falls at
    a = m g / (m + J/r²), reaches the ground at t₁ = √(2h/a) and rebounds at e √(2 a h); res["theta_s"] = x / r."""
    m, J, r, g, h, e = 0.3, 2e-4, 0.02, 9.81, 0.5, 0.6
    model = lg.Model("geared drop")
    model.add("mass", "rack", "p", m=m)
    model.add("gravity", "g", g=g)
    model.add("inertia", "J", "s", J=J)
    model.add("rack_and_pinion", "mesh", rack="x_p", pinion="theta_s", radius=r, eliminate="theta_s")
    res = simulate_with_impacts(model, 0.6, [ground("p", e=e)], initial={"x_p": h}, velocity={"x_p": 0.0},
                                points=61)
    a = m * g / (m + J / r**2)
    t1, v1 = math.sqrt(2 * h / a), math.sqrt(2 * a * h)
    assert res.impacts[0].time == pytest.approx(t1, rel=1e-9)
    assert res.impacts[0].after["x_p"] == pytest.approx(e * v1, rel=1e-9)
    closed = np.where(res.t <= t1, h - 0.5 * a * res.t**2, e * v1 * (res.t - t1) - 0.5 * a * (res.t - t1) ** 2)
    assert res.t[-1] < t1 + 2 * e * v1 / a  # one impact in the span
    assert np.max(np.abs(res["theta_s"] - closed / r)) < 1e-8 * h / r
    after = res.t > t1 + 1e-9
    assert np.max(np.abs(res.velocity("theta_s")[after] - (e * v1 - a * (res.t[after] - t1)) / r)) < 1e-8 * v1 / r
    with pytest.raises(lg.ModelError, match=r"initial= gives 'theta_s', which rack_and_pinion 'mesh' eliminates"):
        simulate_with_impacts(model, 0.1, [ground("p", e=e)], initial={"theta_s": 1.0}, velocity={"x_p": 0.0})


@settings(max_examples=6, deadline=None)
@given(decade(0.05, 5), decade(1e-6, 1e-2), decade(1e-6, 1e-2), decade(5e-3, 0.1), st.integers(8, 60),
       st.integers(8, 60), decade(0.05, 2), st.floats(0.1, 0.9))
@pytest.mark.slow
def test_a_rack_dropped_through_a_gear_train_over_decades(m, J1, J2, r, N1, N2, h, e):
    """The rack drives pinion 1 (θ1 = x / r eliminated), which meshes gear 2 (θ2 = −(N1/N2) θ1 eliminated: a chain):
    it falls at a = m g / (m + J1/r² + J2 (N1/N2)²/r²) and rebounds at e √(2 a h); θ2 = −(N1/N2) x / r throughout."""
    g = 9.81
    model = lg.Model("geared drop")
    model.add("mass", "rack", "p", m=m)
    model.add("gravity", "g", g=g)
    model.add("inertia", "J1", "s1", J=J1)
    model.add("inertia", "J2", "s2", J=J2)
    model.add("rack_and_pinion", "mesh", rack="x_p", pinion="theta_s1", radius=r, eliminate="theta_s1")
    model.add("gear", "pair", a="theta_s1", b="theta_s2", teeth_a=N1, teeth_b=N2, eliminate="theta_s2")
    a = m * g / (m + J1 / r**2 + J2 * (N1 / N2) ** 2 / r**2)
    t1, v1 = math.sqrt(2 * h / a), math.sqrt(2 * a * h)
    span = t1 + 1.5 * e * v1 / a  # one impact, the rebound's top past
    res = simulate_with_impacts(model, span, [ground("p", e=e)], initial={"x_p": h}, velocity={"x_p": 0.0},
                                points=41)
    assert res.names == ["x_p"] and len(res.impacts) == 1
    assert res.impacts[0].time == pytest.approx(t1, rel=1e-8)
    closed = np.where(res.t <= t1, h - 0.5 * a * res.t**2, e * v1 * (res.t - t1) - 0.5 * a * (res.t - t1) ** 2)
    ratio = -(N1 / N2) / r
    assert np.max(np.abs(res["theta_s2"] - ratio * closed)) < 1e-8 * h * abs(ratio)
    rate = np.where(res.t <= t1, -a * res.t, e * v1 - a * (res.t - t1))
    away = np.abs(res.t - t1) > 1e-9 * t1  # the impact time holds both velocities
    assert np.max(np.abs(res.velocity("theta_s2")[away] - ratio * rate[away])) < 1e-8 * v1 * abs(ratio)


def test_a_pushed_rack_with_dry_friction_turns_its_pinion_by_the_closed_form():
    """A rack on a rough floor (F_c) with a pinion (J, r; θ eliminated), pushed by F for 1 s: it slides at
    a = (F − F_c) / M, M = m + J/r², sticks at 1 + M v₁ / F_c having slid ½ a + M v₁² / 2F_c; θ = x / r."""
    m, J, r, F, Fc = 0.5, 1e-4, 0.02, 2.0, 1.0
    model = lg.Model("pushed rack")
    model.add("mass", "rack", "p", m=m)
    model.add("force", "push", "p", F=sp.Piecewise((F, lg.t < 1), (0.0, True)))
    model.add("coulomb_friction", "f", ("ground", "p"), F_c=Fc, stick_slip=True)
    model.add("inertia", "J", "s", J=J)
    model.add("rack_and_pinion", "mesh", rack="x_p", pinion="theta_s", radius=r, eliminate="theta_s")
    M = m + J / r**2
    a = (F - Fc) / M
    v1 = a
    stop = 1 + M * v1 / Fc
    res = stick_slip(model, 3.0, initial={"x_p": 0.0}, velocity={"x_p": 0.0}, points=31)
    assert [s.after for s in res.switches] == ["slip+", "stick"]
    assert res.switches[-1].t == pytest.approx(stop, rel=1e-9)
    end = 0.5 * a + M * v1**2 / (2 * Fc)
    assert res["theta_s"][-1] == pytest.approx(end / r, rel=1e-9)
    early = res.t <= 1.0
    assert np.max(np.abs(res["theta_s"][early] - 0.5 * a * res.t[early] ** 2 / r)) < 1e-9 * end / r
    assert np.max(np.abs(res.velocity("theta_s")[early] - a * res.t[early] / r)) < 1e-9 * v1 / r
    with pytest.raises(lg.ModelError, match=r"velocity= gives 'theta_s', which rack_and_pinion 'mesh' eliminates.*"
                                            r"give 'x_p' instead"):
        stick_slip(model, 1.0, initial={"x_p": 0.0}, velocity={"theta_s": 0.0})


# --- refusals -------------------------------------------------------------------------------------------------------

def test_linearize_and_consistent_initial_refuse_an_eliminated_coordinate_by_its_constraint():
    model = rack(0.3, 40.0, 2e-3, 0.025, 0.5, "theta_s")
    solution = r"\(theta_s = 40\.0\*x_p\(t\)\)"
    with pytest.raises(lg.ModelError, match=r"at= gives 'theta_s', which rack_and_pinion 'mesh' eliminates "
                                            + solution + r": give 'x_p' instead.*multiplier"):
        frequency.linearize(model, at={"theta_s": 0.1}, inputs=["F"])
    with pytest.raises(lg.ModelError, match=r"at= gives 'theta_s', which rack_and_pinion 'mesh'"):
        frequency.transfer_function(model, "F", "x_p", at={"theta_s": 0.1})
    with pytest.raises(lg.ModelError, match=r"^at= gives 'theta_s', which rack_and_pinion 'mesh' eliminates "
                                            + solution + r": give 'x_p' instead"):
        independent_coordinates(model, {"theta_s": 0.1})
    for kw, what in (({"initial": {"theta_s": 0.1}}, "initial"), ({"initial": {"x_p": 0.0}, "velocity": {"theta_s": 1}},
                                                                  "velocity"),
                     ({"initial": {"x_p": 0.0}, "independent": ["theta_s"]}, "independent")):
        with pytest.raises(lg.ModelError, match=rf"^{what}= gives 'theta_s', which rack_and_pinion 'mesh' eliminates "
                                                + solution + r": give 'x_p' instead \(theta_s follows from it\), or keep"):
            consistent_initial(model, **kw)
    with pytest.raises(lg.UnknownNameError, match="theta_z"):  # a name that is no coordinate at all: as before
        frequency.linearize(model, at={"theta_z": 0.1}, inputs=["F"])
