"""Holonomic constraints that eliminate a coordinate (``eliminate=`` on ``constraint``, ``gear``,
``rack_and_pinion``): the same motion as the constraint kept with a multiplier, checked against closed forms and
against sympy.physics.mechanics built independently (the constraint put in by hand); the eliminated coordinate in
results; the refusals."""

import doctest
import math

import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

import lagrangian as lg
import lagrangian.plugins.mechanics as mechanics
from lagrangian import frequency
from lagrangian.derivation.stamps import stamps
from lagrangian.numerics.linear import simulate_exact
from lagrangian.numerics.simulation import initial_state


def decade(lo, hi):
    return st.floats(math.log10(lo), math.log10(hi)).map(lambda e: float(f"{10 ** e:.3g}"))


def gone(name):
    """``eliminate=name`` as a keyword, or nothing (the constraint kept with a multiplier)."""
    return {} if name is None else {"eliminate": name}


def rack(m, k, J, r, eliminate=None, c=0.0, F=0.0):
    model = lg.Model("rack and pinion")
    model.add("mass", "rack", "p", m=m)
    model.add("spring", "k", ("ground", "p"), k=k)
    if c:
        model.add("damper", "c", ("ground", "p"), c=c)
    if F:
        model.add("force", "F", "p", F=F)
    model.add("inertia", "J", "s", J=J)
    model.add("rack_and_pinion", "mesh", rack="x_p", pinion="theta_s", radius=r, **gone(eliminate))
    return model


def accelerations(model, time, state):
    """``q̈`` by coordinate name at ``state`` (coordinate name → (q, q̇))."""
    names = model.coordinate_names
    y = np.array([state[n][0] for n in names] + [state[n][1] for n in names])
    return dict(zip(names, model.numeric().rhs(time, y)[len(names):]))


# --- rack and pinion: closed forms ---------------------------------------------------------------------------------

@settings(max_examples=12)
@given(decade(0.05, 20), decade(1.0, 1e4), decade(1e-5, 1e-1), decade(5e-3, 0.2), st.floats(-2, 2), st.floats(-20, 20),
       st.sampled_from(["theta_s", "x_p"]))
@pytest.mark.slow
def test_rack_and_pinion_eliminated_moves_with_the_effective_mass_over_decades(m, k, J, r, theta, omega, which):
    """Either coordinate eliminated: one coordinate left, ẍ = −k x / (m + J / r²), the same as with the multiplier."""
    model = rack(m, k, J, r, eliminate=which)
    kept = "x_p" if which == "theta_s" else "theta_s"
    assert model.coordinate_names == [kept] and len(model.eq.constraints) == 0
    x, v = r * theta, r * omega
    closed = -k * x / (m + J / r**2)  # ẍ
    scale = 1e-12 * k * abs(x) / (m + J / r**2) + 1e-300
    ours = accelerations(model, 0.0, {"x_p": (x, v), "theta_s": (theta, omega)})[kept]
    assert ours * (1 if kept == "x_p" else r) == pytest.approx(closed, rel=1e-10, abs=scale)
    kept_model = rack(m, k, J, r)
    both = accelerations(kept_model, 0.0, {"x_p": (x, v), "theta_s": (theta, omega)})
    # the multiplier's solve leaves round-off of the order of the forces, and of the constraint's stabilization
    # (rate 10/s on the round-off of ẋ − r θ̇), even at x = 0
    tol = 1e-12 * (k * (abs(x) + r) / (m + J / r**2) + 100 * abs(v)) / (1 if kept == "x_p" else r)
    assert ours == pytest.approx(both[kept], rel=1e-9, abs=tol)


def test_rack_and_pinion_eliminated_oscillates_at_the_closed_form_frequency_and_keeps_its_energy():
    m, k, J, r = 0.5, 20.0, 1e-3, 0.02
    model = rack(m, k, J, r, eliminate="theta_s")
    w = math.sqrt(k / (m + J / r**2))
    res = model.simulate(3.0, initial={"x_p": 0.01}, velocity={"x_p": 0.0}, points=301, rtol=1e-11, atol=1e-14)
    assert res.names == ["x_p"]
    assert "eliminated by 'mesh': theta_s = 50.0*x_p(t)" in model.describe()
    assert np.max(np.abs(res["x_p"] - 0.01 * np.cos(w * res.t))) < 1e-10
    # the eliminated angle is in the result, from x = r θ
    assert np.max(np.abs(res["theta_s"] - 0.01 * np.cos(w * res.t) / r)) < 1e-8
    assert np.max(np.abs(res.velocity("theta_s") + 0.01 * w * np.sin(w * res.t) / r)) < 1e-7
    # energy: ½ (m + J / r²) ẋ² + ½ k x², kept
    E = 0.5 * (m + J / r**2) * res.velocity("x_p") ** 2 + 0.5 * k * res["x_p"] ** 2
    assert np.max(np.abs(res.E - E)) < 1e-12 and np.ptp(res.E) < 1e-9 * res.E[0]
    assert res.E[0] == pytest.approx(0.5 * k * 0.01**2, rel=1e-12)
    modes = frequency.modes(frequency.linearize(model, inputs=[]))
    assert modes.omega[0] == pytest.approx(w, rel=1e-10)


def test_exact_solution_of_a_linear_model_with_an_eliminating_gear():
    """Two inertias on torsion springs geared together, the second angle eliminated: ω² = (k1 + k2 n²) / (J1 + J2 n²)
    with n = N1 / N2; method='exact' and DOP853 agree with the closed form."""
    J1, J2, k1, k2, N1, N2 = 0.01, 0.04, 3.0, 7.0, 12, 36
    model = lg.Model("geared springs")
    model.add("inertia", "J1", "s1", J=J1)
    model.add("inertia", "J2", "s2", J=J2)
    model.add("torsion_spring", "k1", ("ground", "s1"), k=k1)
    model.add("torsion_spring", "k2", ("ground", "s2"), k=k2)
    model.add("gear", "mesh", a="theta_s1", b="theta_s2", teeth_a=N1, teeth_b=N2, eliminate="theta_s2")
    n = N1 / N2
    w = math.sqrt((k1 + k2 * n**2) / (J1 + J2 * n**2))
    kw = dict(initial={"theta_s1": 0.2}, velocity={"theta_s1": 0.0}, points=51)
    exact = model.simulate(2.0, method="exact", **kw)
    assert exact.method == "exact"
    assert np.max(np.abs(exact["theta_s1"] - 0.2 * np.cos(w * exact.t))) < 1e-12
    assert np.max(np.abs(exact["theta_s2"] + n * 0.2 * np.cos(w * exact.t))) < 1e-12  # external mesh: θ2 = −n θ1
    numeric = model.simulate(2.0, rtol=1e-11, atol=1e-14, **kw)
    assert np.max(np.abs(numeric["theta_s2"] - exact["theta_s2"])) < 1e-9
    assert model.simulate(2.0, method="auto", **kw).method == "exact"


@pytest.mark.slow
def test_stamps_of_a_large_linear_model_hold_the_eliminated_inertia():
    """A chain of 40 masses whose last drives a pinion whose angle is eliminated: the models past STAMPS_MIN are
    solved from the stamps, which must carry J / r² on the last mass (and no constraint)."""
    n, m, k, J, r = 40, 0.3, 50.0, 2e-3, 0.05
    model = lg.Model("chain")
    for i in range(n):
        model.add("mass", f"m{i}", f"n{i}", m=m)
        model.add("spring", f"k{i}", ("ground" if i == 0 else f"n{i - 1}", f"n{i}"), k=k)
    model.add("inertia", "J", "s", J=J)
    model.add("rack_and_pinion", "mesh", rack=f"x_n{n - 1}", pinion="theta_s", radius=r, eliminate="theta_s")
    assert len(model.coordinate_names) == n
    st_ = stamps(model.assembly, model.assembly.values)
    M = st_.M.toarray()
    assert np.allclose(np.diag(M), [m] * (n - 1) + [m + J / r**2], rtol=1e-14, atol=0)
    assert np.count_nonzero(M - np.diag(np.diag(M))) == 0
    start = {name: 0.0 for name in model.coordinate_names} | {f"x_n{n - 1}": 0.01}
    rest = dict.fromkeys(model.coordinate_names, 0.0)
    res = model.simulate(0.5, initial=start, velocity=rest, method="exact", points=6)
    assert "stamps" in res.notes[0]
    ref = model.simulate(0.5, initial=start, velocity=rest, points=6, rtol=1e-11, atol=1e-14)
    assert np.max(np.abs(res["theta_s"] - ref["theta_s"])) < 1e-8 * 0.01 / r


# --- rolling down an incline: closed form ----------------------------------------------------------------------------

@settings(max_examples=10)
@given(decade(0.05, 50), decade(0.01, 1), st.floats(0.05, 1.4), st.sampled_from([0.5, 0.4, 1.0]),
       st.sampled_from(["theta_w", "x_p"]))
@pytest.mark.slow
def test_rolling_down_an_incline_eliminated_accelerates_at_the_closed_form(m, R, alpha, shape, which):
    """A disc, a sphere or a hoop (I = shape · m R²) rolling down an incline, s = R θ with either coordinate
    eliminated: s̈ = g sin α / (1 + I / (m R²))."""
    g = 9.81
    model = lg.Model("rolling")
    model.add("mass", "body", "p", m=m)
    model.add("force", "weight", "p", F=m * g * math.sin(alpha))
    model.add("inertia", "I", "w", J=shape * m * R**2)
    model.add("constraint", "roll", f=lg.coordinate("x_p") - R * lg.coordinate("theta_w"), eliminate=which)
    kept = "x_p" if which == "theta_w" else "theta_w"
    res = model.simulate(2.0, initial={kept: 0.0}, velocity={kept: 0.0}, points=21, rtol=1e-12, atol=1e-14)
    a = g * math.sin(alpha) / (1 + shape)
    assert res.names == [kept]
    assert np.max(np.abs(res["x_p"] - 0.5 * a * res.t**2)) <= 1e-9 * 0.5 * a * 4
    assert np.max(np.abs(res["theta_w"] * R - 0.5 * a * res.t**2)) <= 1e-9 * 0.5 * a * 4
    assert np.max(np.abs(res.velocity("x_p") - a * res.t)) <= 1e-9 * a * 2


# --- a gear train against sympy.physics.mechanics ----------------------------------------------------------------------

def gear_train(J1, J2, J3, N1, N2a, N2b, N3, k, internal=False, eliminate=(None, None)):
    """Shaft 1 driven by a torque sin t; gear 1 meshes gear 2a, gear 2b (on shaft 2) meshes gear 3; a torsion
    spring holds shaft 3."""
    model = lg.Model("gear train")
    for name, J in (("s1", J1), ("s2", J2), ("s3", J3)):
        model.add("inertia", f"J{name}", name, J=J)
    model.add("torque", "drive", "s1", tau=sp.sin(lg.t))
    model.add("torsion_spring", "k3", ("ground", "s3"), k=k)
    model.add("gear", "g12", a="theta_s1", b="theta_s2", teeth_a=N1, teeth_b=N2a, **gone(eliminate[0]))
    model.add("gear", "g23", a="theta_s2", b="theta_s3", teeth_a=N2b, teeth_b=N3, internal=internal,
              **gone(eliminate[1]))
    return model


@settings(max_examples=8)
@given(decade(1e-4, 1), decade(1e-4, 1), decade(1e-4, 1), st.integers(8, 80), st.integers(8, 80), st.integers(8, 80),
       st.integers(8, 80), decade(0.1, 100), st.booleans(), st.floats(-3, 3), st.floats(-5, 5), st.floats(0, 6),
       st.sampled_from([("theta_s2", "theta_s3"), ("theta_s2", None), ("theta_s1", "theta_s2")]))
@pytest.mark.slow
def test_an_eliminating_gear_train_matches_kane_over_decades(kane_gear_train, J1, J2, J3, N1, N2a, N2b, N3, k, internal, theta,
                                                              omega, time, eliminate):
    """θ2 and θ3 eliminated (θ1 left); θ2 eliminated and g23 kept with a multiplier in θ1, θ3; or the chain θ1 in
    terms of θ2, θ2 in terms of θ3 (θ3 left)."""
    n2 = -N1 / N2a  # θ2 = −(N1/N2a) θ1; θ3 = ∓(N2b/N3) θ2 (external: opposite senses; internal: the same)
    n3 = n2 * (N2b / N3) * (1 if internal else -1)
    model = gear_train(J1, J2, J3, N1, N2a, N2b, N3, k, internal, eliminate)
    ratio = {"theta_s1": 1.0, "theta_s2": n2, "theta_s3": n3}
    left = [n for n in ratio if n not in eliminate]
    assert model.coordinate_names == left
    assert len(model.eq.constraints) == sum(e is None for e in eliminate)
    ours = accelerations(model, time, {n: (r * theta, r * omega) for n, r in ratio.items()})[left[-1]]
    reference = kane_gear_train(J1, J2, J3, n2, n3, k, theta, omega, time) * ratio[left[-1]]
    scale = (1 + k * abs(n3 * theta)) * max(1.0, abs(ratio[left[-1]])) / min(J1, J2, J3)
    assert ours == pytest.approx(reference, rel=1e-10, abs=1e-10 * scale)


# --- rheonomic: x_a = x_b + A sin ωt ----------------------------------------------------------------------------------

def shaker(ma, mb, ka, kb, A, w, eliminate="x_a"):
    model = lg.Model("shaker")
    model.add("mass", "ma", "a", m=ma)
    model.add("mass", "mb", "b", m=mb)
    model.add("spring", "ka", ("ground", "a"), k=ka)
    model.add("spring", "kb", ("ground", "b"), k=kb)
    model.add("constraint", "drive", f=lg.coordinate("x_a") - lg.coordinate("x_b") - A * sp.sin(w * lg.t),
              **gone(eliminate))
    return model


@settings(max_examples=10)
@given(decade(0.01, 10), decade(0.01, 10), decade(0.1, 1e3), decade(0.1, 1e3), decade(1e-3, 0.1), decade(0.1, 100),
       st.floats(-1, 1), st.floats(-5, 5), st.floats(0, 3))
@pytest.mark.slow
def test_a_rheonomic_elimination_matches_the_closed_form_and_the_multiplier(ma, mb, ka, kb, A, w, x, v, time):
    """x_a = x_b + A sin ωt: (ma + mb) ẍ_b = −ka (x_b + A sin ωt) − kb x_b + ma A ω² sin ωt."""
    model = shaker(ma, mb, ka, kb, A, w)
    assert model.coordinate_names == ["x_b"]
    s = math.sin(w * time)
    closed = (-ka * (x + A * s) - kb * x + ma * A * w**2 * s) / (ma + mb)
    scale = (ka * (abs(x) + A) + kb * abs(x) + ma * A * w**2) / (ma + mb)
    state = {"x_b": (x, v), "x_a": (x + A * s, v + A * w * math.cos(w * time))}
    ours = accelerations(model, time, state)["x_b"]
    assert ours == pytest.approx(closed, rel=1e-10, abs=1e-12 * scale)
    kept = accelerations(shaker(ma, mb, ka, kb, A, w, eliminate=None), time, state)
    assert ours == pytest.approx(kept["x_b"], rel=1e-8, abs=1e-10 * scale)


def test_the_rheonomic_eliminated_coordinate_is_in_the_result():
    A, w = 0.02, 7.0
    model = shaker(0.3, 0.5, 40.0, 20.0, A, w)
    res = model.simulate(1.0, initial={"x_b": 0.01}, velocity={"x_b": 0.0}, points=11)
    assert np.max(np.abs(res["x_a"] - res["x_b"] - A * np.sin(w * res.t))) < 1e-14
    assert np.max(np.abs(res.velocity("x_a") - res.velocity("x_b") - A * w * np.cos(w * res.t))) < 1e-13
    assert np.allclose(res.quantity(lg.coordinate("x_a") - lg.coordinate("x_b")), A * np.sin(w * res.t), atol=1e-14)


# --- loads on the eliminated coordinate -------------------------------------------------------------------------------

@settings(max_examples=10)
@given(decade(0.05, 20), decade(1.0, 1e4), decade(1e-5, 1e-1), decade(5e-3, 0.2), decade(1e-3, 10), decade(0.01, 100),
       st.floats(-2, 2), st.floats(-20, 20))
@pytest.mark.slow
def test_a_damper_and_a_force_on_the_eliminated_rack_act_through_the_pinion(kane_rack, m, k, J, r, c, F, theta, omega):
    """The rack's coordinate eliminated (x = r θ): the spring, damper and force on it give the generalized force
    Q_θ = r (F − k r θ − c r θ̇), so θ̈ = r (F − k r θ − c r θ̇) / (J + m r²); and sympy.physics.mechanics agrees."""
    model = rack(m, k, J, r, eliminate="x_p", c=c, F=F)
    assert model.coordinate_names == ["theta_s"]
    Q = r * (F - k * r * theta - c * r * omega)
    scale = r * (F + k * r * abs(theta) + c * r * abs(omega)) / (J + m * r**2)
    ours = accelerations(model, 0.0, {"theta_s": (theta, omega)})["theta_s"]
    assert ours == pytest.approx(Q / (J + m * r**2), rel=1e-10, abs=1e-12 * scale)
    kane = float(kane_rack(m, k, J, r, c, F)(theta, omega))
    assert ours == pytest.approx(kane, rel=1e-10, abs=1e-12 * scale)


@pytest.mark.slow
def test_the_generalized_forces_of_loads_on_the_eliminated_coordinate():
    """A damper c and a constant force F on the rack, a generalized force Q on x_p, x_p eliminated: the model's
    generalized force on θ is r (F + Q) − c r² θ̇ (the damper in D, so only the loads in Q)."""
    m, k, J, r, c, F, Qx = 0.5, 20.0, 1e-3, 0.02, 0.7, 3.0, -1.5
    model = rack(m, k, J, r, eliminate="x_p", c=c, F=F)
    model.add("generalized_force", "push", coordinate="x_p", Q=Qx)
    th = lg.coordinate("theta_s")
    w = lg.rate("theta_s")
    assert float(model.generalized_forces[0]) == pytest.approx(r * (F + Qx), rel=1e-14)
    assert float(sp.diff(model.rayleigh, w, 2)) == pytest.approx(c * r**2, rel=1e-14)
    assert float(sp.diff(model.potential_energy, th, 2)) == pytest.approx(k * r**2, rel=1e-14)
    res = model.simulate(1.0, initial={"theta_s": 0.0}, velocity={"theta_s": 0.0}, points=101, rtol=1e-11, atol=1e-14)
    # work of the force and energy dissipated by the damper balance the stored energy
    work = res.cumulative(model.load_power("F", "push"))
    dissipated = res.cumulative(2 * res.D)
    assert np.max(np.abs(work - dissipated - (res.E - res.E[0]))) < 1e-8 * np.max(np.abs(work))
    assert np.max(np.abs(work - (F + Qx) * res["x_p"])) < 1e-7 * np.max(np.abs(work))  # Simpson on 101 times


# --- refusals ----------------------------------------------------------------------------------------------------------

def two_masses(**constraints):
    model = lg.Model("two")
    model.add("mass", "ma", "a", m=1.0)
    model.add("mass", "mb", "b", m=2.0)
    model.add("mass", "mc", "c", m=3.0)
    for name, (f, which) in constraints.items():
        model.add("constraint", name, f=f, **gone(which))
    return model


def test_refusals_name_the_constraint_the_coordinate_and_the_fix():
    xa, xb, xc = (lg.coordinate(n) for n in ("x_a", "x_b", "x_c"))
    bad = two_masses(circle=(xa**2 + xb**2 - 1, "x_a"))
    with pytest.raises(lg.ModelError, match=r"constraint 'circle': cannot eliminate 'x_a'.*not linear.*keep it with a "
                                            r"multiplier.*x_a − g\(q, t\)"):
        bad.equations
    bad = two_masses(lever=(sp.cos(xb) * xa - xc, "x_a"))
    with pytest.raises(lg.ModelError, match=r"'lever': cannot eliminate 'x_a'.*coefficient.*depends on x_b"):
        bad.equations
    bad = two_masses(tie=(xa - 2 * xb, "x_ab"))
    with pytest.raises(lg.UnknownNameError, match=r"eliminate= of constraint 'tie'.*'x_ab'.*Did you mean"):
        bad.coordinate_names
    bad = two_masses(tie=(xa - 2 * xb, "x_c"))
    with pytest.raises(lg.ModelError, match=r"'tie'.*does not hold 'x_c'.*x_a, x_b"):
        bad.equations
    bad = two_masses(one=(xa - 2 * xb, "x_b"), two=(xb - 3 * xa, "x_a"))
    with pytest.raises(lg.ModelError, match=r"cycle.*constraint '(one|two)'.*constraint '(one|two)'.*multiplier"):
        bad.equations
    bad = two_masses(one=(xa - 2 * xb, "x_a"), two=(xa - 3 * xc, "x_a"))
    with pytest.raises(lg.ModelError, match=r"'one' and constraint 'two' both eliminate 'x_a'"):
        bad.equations
    bad = two_masses(both=(sp.Matrix([xa - xb, xb - xc]), "x_a"))
    with pytest.raises(lg.ModelError, match=r"'both': eliminate= solves one constraint.*imposes 2"):
        bad.equations
    model = rack(0.5, 20.0, 1e-3, 0.02, eliminate="theta_s")
    for kw in ({"initial": {"theta_s": 0.1}}, {"velocity": {"theta_s": 0.1}}):
        with pytest.raises(lg.ModelError, match=r"gives 'theta_s', which rack_and_pinion 'mesh' eliminates.*give 'x_p' "
                                                r"instead"):
            model.simulate(1.0, **kw)
    with pytest.raises(lg.ModelError, match=r"velocity= gives 'theta_s', which rack_and_pinion 'mesh' eliminates"):
        simulate_exact(model, 1.0, velocity={"theta_s": 0.1})
    with pytest.raises(lg.ModelError, match=r"initial= gives 'theta_s'.*\(theta_s = 50\.0\*x_p\(t\)\)"):
        initial_state(model.eq, {"theta_s": 0.1}, {})
    with pytest.raises(lg.UnknownNameError, match="x_p, theta_s|theta_s, x_p"):
        model.simulate(1.0, points=3, initial={"x_p": 0.0}, velocity={"x_p": 0.0})["theta"]
    gears = gear_train(0.01, 0.02, 0.03, 12, 24, 12, 36, 1.0, eliminate=("theta_s3", None))
    with pytest.raises(lg.ModelError, match=r"gear 'g12': its constraint .* does not hold 'theta_s3'.*theta_s1, theta_s2"):
        gears.equations


def test_a_chain_of_eliminations_is_solved_in_order():
    """x_a = 2 x_b (eliminating x_a), x_b = 3 x_c (eliminating x_b): x_a = 6 x_c, whichever is added first."""
    xa, xb, xc = (lg.coordinate(n) for n in ("x_a", "x_b", "x_c"))
    for order in ((("one", xa - 2 * xb, "x_a"), ("two", xb - 3 * xc, "x_b")),
                  (("two", xb - 3 * xc, "x_b"), ("one", xa - 2 * xb, "x_a"))):
        model = two_masses(**{name: (f, gone) for name, f, gone in order})
        assert model.coordinate_names == ["x_c"]
        assert float(model.mass_matrix[0]) == pytest.approx(1.0 * 36 + 2.0 * 9 + 3.0, rel=1e-14)
        assert sp.simplify(model.assembly.eliminated["x_a"].solution - 6 * xc) == 0


def test_other_constraints_and_velocity_constraints_hold_the_solution():
    xa, xb, xc = (lg.coordinate(n) for n in ("x_a", "x_b", "x_c"))
    model = two_masses(one=(xa - 2 * xb, "x_a"), kept=(xa + xc, None))
    model.add("velocity_constraint", "slow", c=lg.rate("x_a") - lg.rate("x_c"))
    q_b, q_c, v_b, v_c = sp.symbols("q_x_b q_x_c v_x_b v_x_c", real=True)
    assert sp.expand(model.eq.constraints[0] - (2 * q_b + q_c)) == 0
    assert sp.expand(model.eq.velocity_constraints[0] - (2 * v_b - v_c)) == 0


def test_the_docstring_examples_of_the_constraint_kinds_run():
    finder = doctest.DocTestFinder()
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    for cls in (mechanics.Constraint, mechanics.Gear, mechanics.RackAndPinion):
        for test in finder.find(cls, cls.__name__, globs={}):
            runner.run(test)
    assert runner.failures == 0 and runner.tries >= 15


@pytest.mark.slow
def test_an_angle_eliminated_in_a_multibody_chain_moves_as_with_the_multiplier():
    """A double pendulum of rods whose second joint follows θ2 = θ1 / 2 + 0.1 t: the bodies' frames hold the
    solution (rheonomic), and θ̈1 is the one the multiplier gives on the constraint."""
    def build(**kw):
        m = lg.Model("driven double pendulum", dim=2)
        m.add("rod", "a1", "a1", m=0.3, length=0.7)
        m.add("rod", "a2", "a2", m=0.2, length=0.5)
        m.add("revolute", "j1", ("ground", "a1"))
        m.add("revolute", "j2", ("a1", "a2"), parent_point=(0.7, 0))
        m.add("gravity", "g", g=9.81, direction=(0, -1))
        m.add("constraint", "c", f=lg.coordinate("theta_j2") - 0.5 * lg.coordinate("theta_j1") - 0.1 * lg.t, **kw)
        return m

    th, w, time = 0.3, 0.7, 0.4
    ours = accelerations(build(eliminate="theta_j2"), time, {"theta_j1": (th, w)})["theta_j1"]
    kept = accelerations(build(), time, {"theta_j1": (th, w), "theta_j2": (0.5 * th + 0.1 * time, 0.5 * w + 0.1)})
    assert ours == pytest.approx(kept["theta_j1"], rel=1e-12)


@pytest.mark.slow
def test_the_eliminated_coordinate_is_a_column_of_the_exports():
    model = rack(0.5, 20.0, 1e-3, 0.02, eliminate="theta_s")
    res = model.simulate(0.5, initial={"x_p": 0.01}, velocity={"x_p": 0.0}, points=11)
    df = res.to_pandas()
    assert list(df.columns) == ["x_p", "theta_s", "x_p'", "theta_s'", "T", "V", "D", "E"]
    assert np.allclose(df["theta_s"].to_numpy(), res["x_p"] / 0.02, rtol=1e-14, atol=0)
    assert res.to_xarray()["theta_s"].attrs["units"] == "rad"


def test_eliminate_none_keeps_the_multiplier():
    model = lg.Model("rack")
    model.add("mass", "rack", "p", m=0.5)
    model.add("inertia", "J", "s", J=1e-3)
    model.add("rack_and_pinion", "mesh", rack="x_p", pinion="theta_s", radius=0.02, eliminate=None)
    assert model.coordinate_names == ["x_p", "theta_s"] and len(model.eq.constraints) == 1
    with pytest.raises(lg.ParameterError, match="'mesh2', parameter 'eliminate'"):
        model.add("gear", "mesh2", a="x_p", b="theta_s", teeth_a=1, teeth_b=2, eliminate=3)
