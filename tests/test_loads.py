"""Loads that depend on the state: forces, torques and generalized forces written in the coordinates and their
rates (``lagrangian.coordinate``, ``lagrangian.rate``), checked against closed forms and a SciPy reference."""

import math

import numpy as np
import pytest
import scipy.integrate
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

import lagrangian as lg
from lagrangian import frequency

G = 9.81


def decade(lo, hi):
    return st.floats(math.log10(lo), math.log10(hi)).map(lambda e: float(f"{10 ** e:.3g}"))


def pd_pendulum(m, l, Kp, Kd, g=G):
    """A bob on a massless link of length l, hanging (θ = −π/2 from the x axis), held by a PD controller on its joint:
    m l² θ̈ + m g l cos θ = −Kp (θ + π/2) − Kd θ̇."""
    model = lg.Model("pd pendulum", dim=2)
    model.add("link", "l1", "l1", points={"end": (l, 0)})
    model.add("mass", "bob", "l1.end", m=m)
    model.add("revolute", "j1", ("ground", "l1"))
    model.add("gravity", "g", g=g)
    th = lg.coordinate("theta_j1")
    model.add("generalized_force", "pd", coordinate="theta_j1", Q=-Kp * (th + sp.pi / 2) - Kd * lg.rate("theta_j1"))
    return model


def closed_form_poles(m, l, Kp, Kd, g=G):
    """Roots of m l² s² + Kd s + (m g l + Kp)."""
    return np.roots([m * l**2, Kd, m * g * l + Kp])


def same_roots(found, expected, rel):
    found, expected = np.sort_complex(np.asarray(found, complex)), np.sort_complex(np.asarray(expected, complex))
    scale = np.abs(expected).max()
    return np.max(np.abs(found - expected)) <= rel * scale


@settings(max_examples=25)
@given(decade(0.05, 20.0), decade(0.1, 5.0), decade(1e-3, 1e3), decade(1e-4, 1e2))
@pytest.mark.slow
def test_pd_pendulum_poles_are_the_closed_form_over_decades(m, l, Kp, Kd):
    lin = frequency.linearize(pd_pendulum(m, l, Kp, Kd), at={"theta_j1": -math.pi / 2}, inputs=[])
    A = np.asarray(lin.state_space()[0], dtype=float)
    assert same_roots(np.linalg.eigvals(A), closed_form_poles(m, l, Kp, Kd), 1e-9)


def test_pd_pendulum_with_symbols_has_the_closed_form_characteristic_polynomial_and_the_numbers_verdict():
    m, l, Kp, Kd, g = sp.symbols("m l K_p K_d g", positive=True)
    lin = frequency.linearize(pd_pendulum(m, l, Kp, Kd, g), at={"theta_j1": -sp.pi / 2}, inputs=[])
    A = sp.Matrix(lin.state_space()[0])
    s = sp.Symbol("s")
    assert sp.simplify(A.charpoly(s).as_expr() * m * l**2 - (m * l**2 * s**2 + Kd * s + m * g * l + Kp)) == 0
    values = {m: 0.3, l: 0.7, Kp: 2.5, Kd: 0.04, g: G}
    numeric = frequency.linearize(pd_pendulum(0.3, 0.7, 2.5, 0.04), at={"theta_j1": -math.pi / 2}, inputs=[])
    assert np.allclose(np.asarray(A.subs(values), dtype=float), np.asarray(numeric.state_space()[0], dtype=float),
                       rtol=1e-12, atol=0)


def test_the_controller_brings_the_pendulum_to_rest_at_its_set_point_as_the_linear_solution_says():
    m, l, Kp, Kd = 0.3, 0.7, 2.5, 0.4
    model = pd_pendulum(m, l, Kp, Kd)
    res = model.simulate(3.0, initial={"theta_j1": -math.pi / 2 + 1e-4}, velocity={"theta_j1": 0.0}, points=301,
                         rtol=1e-11, atol=1e-14)
    # a small offset obeys the linear equation: δ(t) = Re(c₁ e^{s₁t} + c₂ e^{s₂t}) with δ(0) = 1e-4, δ'(0) = 0
    s1, s2 = closed_form_poles(m, l, Kp, Kd)
    c1 = 1e-4 * s2 / (s2 - s1)
    exact = (c1 * np.exp(s1 * res.t) + (1e-4 - c1) * np.exp(s2 * res.t)).real
    assert np.max(np.abs(res["theta_j1"] + math.pi / 2 - exact)) < 2e-12 + 1e-6 * 1e-4


def projectile(m, c, dim=2):
    model = lg.Model("projectile with quadratic drag", dim=dim)
    model.add("mass", "ball", "p", m=m)
    model.add("gravity", "g", g=G)
    v = sp.Matrix([lg.rate("x_p"), lg.rate("y_p")])
    speed = sp.sqrt(v[0] ** 2 + v[1] ** 2)
    model.add("force", "drag", "p", F=list(-c * speed * v))
    return model


def scipy_range(m, c, v0, angle):
    """The same flight, hand-written for scipy.integrate.solve_ivp: landing time and distance."""
    def rhs(t, y):
        vx, vy = y[2], y[3]
        speed = math.hypot(vx, vy)
        return [vx, vy, -c / m * speed * vx, -G - c / m * speed * vy]

    def ground(t, y):
        return y[1]

    ground.terminal, ground.direction = True, -1
    sol = scipy.integrate.solve_ivp(rhs, (0, 100), [0, 0, v0 * math.cos(angle), v0 * math.sin(angle)], method="DOP853",
                                    rtol=1e-12, atol=1e-12, events=ground)
    return float(sol.t_events[0][0]), float(sol.y_events[0][0][0])


@settings(max_examples=10)
@given(decade(0.05, 5.0), decade(1e-4, 0.3), st.floats(2.0, 40.0), st.floats(0.2, 1.35))
def test_quadratic_drag_projectile_lands_where_scipy_says(m, c, v0, angle):
    vx, vy = v0 * math.cos(angle), v0 * math.sin(angle)
    land = lg.Event("y_p", direction=-1, terminal=True, name="land")
    res = projectile(m, c).simulate(100.0, initial={"x_p": 0.0, "y_p": 0.0}, velocity={"x_p": vx, "y_p": vy},
                                    events=[land], rtol=1e-12, atol=1e-12, points=201)
    (hit,) = res.events
    t_ref, x_ref = scipy_range(m, c, v0, angle)
    assert hit.t == pytest.approx(t_ref, rel=1e-8)
    assert hit.q["x_p"] == pytest.approx(x_ref, rel=1e-8)
    # the drag only takes energy away: E falls monotonically along the flight
    assert np.all(np.diff(res.E) <= 1e-9 * abs(res.E[0]) + 1e-12)


def test_a_generalized_force_of_the_state_is_a_spring_and_a_damper_in_numbers_and_in_compiled_code():
    k, c = 40.0, 0.25
    loaded = lg.Model("loaded")
    loaded.add("mass", "m1", "p", m=0.3)
    loaded.add("generalized_force", "kc", coordinate="x_p", Q=-k * lg.coordinate("x_p") - c * lg.rate("x_p"))
    plain = lg.Model("plain")
    plain.add("mass", "m1", "p", m=0.3)
    plain.add("spring", "k1", ("ground", "p"), k=k)
    plain.add("damper", "c1", ("ground", "p"), c=c)
    kw = dict(initial={"x_p": 0.01}, velocity={"x_p": 0.0}, points=101, rtol=1e-11, atol=1e-14)
    a = loaded.simulate(2.0, method="DOP853", compiled=False, **kw)["x_p"]
    b = plain.simulate(2.0, method="DOP853", compiled=False, **kw)["x_p"]
    native = loaded.simulate(2.0, method="DOP853", compiled=True, **kw)["x_p"]
    assert np.max(np.abs(a - b)) < 1e-13
    assert np.array_equal(native, loaded.simulate(2.0, method="DOP853", compiled=True, **kw)["x_p"])
    assert np.max(np.abs(native - b)) < 1e-13
    # a linear load is stamped like the spring and the damper it equals: the exact solution agrees with both
    exact = loaded.simulate(2.0, method="exact", initial={"x_p": 0.01}, velocity={"x_p": 0.0}, points=101)["x_p"]
    assert np.max(np.abs(exact - b)) < 1e-10


def test_a_torque_of_the_state_on_a_rotational_node_and_on_a_body_equal_the_generalized_force():
    m, l, Kp, Kd = 0.3, 0.7, 2.5, 0.4
    th = lg.coordinate("theta_j1")
    body = lg.Model("pd body", dim=2)
    body.add("link", "l1", "l1", points={"end": (l, 0)})
    body.add("mass", "bob", "l1.end", m=m)
    body.add("revolute", "j1", ("ground", "l1"))
    body.add("gravity", "g", g=G)
    body.add("body_torque", "pd", "l1", tau=-Kp * (th + sp.pi / 2) - Kd * lg.rate("theta_j1"))
    A = np.asarray(frequency.linearize(body, at={"theta_j1": -math.pi / 2}, inputs=[]).state_space()[0], dtype=float)
    assert same_roots(np.linalg.eigvals(A), closed_form_poles(m, l, Kp, Kd), 1e-9)

    shaft = lg.Model("shaft")
    shaft.add("inertia", "J", "s", J=0.02)
    phi = lg.coordinate("theta_s")
    shaft.add("torque", "pd", "s", tau=-1.5 * phi - 0.03 * lg.rate("theta_s"))
    A = np.asarray(frequency.linearize(shaft, inputs=[]).state_space()[0], dtype=float)
    assert same_roots(np.linalg.eigvals(A), np.roots([0.02, 0.03, 1.5]), 1e-12)


def test_slips_in_loads_get_errors_that_name_the_fix():
    m = lg.Model("slips")
    m.add("mass", "m1", "p", m=0.3)
    m.add("generalized_force", "g1", coordinate="x_p", Q=-2 * lg.coordinate("X_p"))
    with pytest.raises(lg.ModelError, match=r"X_p\(t\), which is not a coordinate of the model\. Did you mean 'x_p'\?"):
        m.equations
    with pytest.raises(lg.ParameterError, match="acceleration"):
        lg.Model("a").add("force", "F", "p", F=lg.coordinate("x_p").diff(lg.t, 2))
    with pytest.raises(lg.ParameterError, match="a signal is a function of time alone.*generalized_force"):
        lg.Model("c").add("voltage_source", "V1", ("n1", "0"), E=lg.coordinate("q_L1"))
    with pytest.raises(lg.ParameterError, match="a signal is a function of time alone"):
        lg.Model("d").add("prescribed_motion", "drive", "p", position=lg.coordinate("x_q"))
    vector = lg.Model("v")
    vector.add("mass", "m1", "p", m=0.3)
    vector.add("generalized_force", "g2", coordinate="x_p", Q=[1, 2])
    with pytest.raises(lg.ModelError, match="acts on one coordinate"):
        vector.equations
    with pytest.raises(lg.ModelError, match="non-empty string"):
        lg.coordinate("")


def test_a_load_of_the_state_makes_its_coordinate_not_ignorable():
    from lagrangian import models, routh

    m = models.spherical_pendulum(0.3, 0.7)
    m.add("generalized_force", "drag", coordinate="theta_turn", Q=-0.01 * lg.rate("theta_turn"))
    with pytest.raises(lg.ReductionError, match="theta_turn: a generalized force acts on it"):
        routh.reduce(m)


def test_the_analogies_map_a_force_given_as_a_callable_and_refuse_one_of_the_state():
    import warnings

    from lagrangian.analogy import AnalogyError, map_model

    def build(F):
        m = lg.Model("driven")
        m.add("mass", "m1", "p", m=0.3)
        m.add("spring", "k1", ("ground", "p"), k=40.0)
        m.add("force", "F", "p", F=F)
        return m

    mech = build(lambda t: math.sin(3 * t))
    analogue = map_model(mech, "force-voltage").model
    kw = dict(points=51, rtol=1e-11, atol=1e-14)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lg.InitialConditionWarning)
        x = mech.simulate(1.0, **kw)["x_p"]
        q = analogue.simulate(1.0, **kw)["q_L_m1"]
    exact = 1 / (0.3 * (40 / 0.3 - 9)) * (np.sin(3 * np.linspace(0, 1, 51))
                                          - 3 / math.sqrt(40 / 0.3) * np.sin(math.sqrt(40 / 0.3) * np.linspace(0, 1, 51)))
    assert np.max(np.abs(x - exact)) < 1e-9 and np.max(np.abs(q - exact)) < 1e-9
    with pytest.raises(AnalogyError, match=r"force 'F' depends on the state \(x_p\(t\)\).*controlled source"):
        map_model(build(-0.2 * lg.rate("x_p") ** 3), "force-current")


def test_a_load_given_as_a_python_callable_of_the_state_runs_as_its_expression_and_is_refused_where_derivatives_are_needed():
    from lagrangian.analogy import AnalogyError, map_model
    from lagrangian.operating import equilibria

    m, l, Kp, Kd = 0.3, 0.7, 2.5, 0.4

    def controller(t, q, v):
        return -Kp * (q["theta_j1"] + math.pi / 2) - Kd * v["theta_j1"]

    written = pd_pendulum(m, l, Kp, Kd)
    called = lg.Model("pd pendulum", dim=2)
    called.add("link", "l1", "l1", points={"end": (l, 0)})
    called.add("mass", "bob", "l1.end", m=m)
    called.add("revolute", "j1", ("ground", "l1"))
    called.add("gravity", "g", g=G)
    called.add("generalized_force", "pd", coordinate="theta_j1", Q=controller)
    kw = dict(initial={"theta_j1": -1.2}, velocity={"theta_j1": 0.3}, points=31, rtol=1e-11, atol=1e-13)
    a = written.simulate(3.0, compiled=False, **kw)["theta_j1"]
    b = called.simulate(3.0, **kw)
    assert np.max(np.abs(a - b["theta_j1"])) < 1e-12
    native = called.simulate(3.0, compiled=True, **kw)
    assert any("Python callables (Q_pd)" in note for note in native.notes)
    assert np.array_equal(native["theta_j1"], b["theta_j1"])
    for call in (lambda: frequency.linearize(called, at={"theta_j1": -math.pi / 2}, inputs=[]),
                 lambda: equilibria(called), lambda: called.simulate(1.0, method="exact", **kw)):
        with pytest.raises(lg.ModelError, match=r"Python callables of the state \(Q_pd\) have no derivatives"):
            call()
    mech = lg.Model("driven")
    mech.add("mass", "m1", "p", m=0.3)
    mech.add("force", "F", "p", F=lambda t, q, v: -0.1 * v["x_p"])
    with pytest.raises(AnalogyError, match="force 'F' depends on the state"):
        map_model(mech, "force-voltage")
    with pytest.raises(lg.ParameterError, match=r"callable of \(t, q, v\): a signal is a function of time alone"):
        lg.Model("s").add("voltage_source", "V1", ("n1", "0"), E=lambda t, q, v: 1.0)
    with pytest.raises(lg.ParameterError, match="callable of 2 required arguments"):
        lg.Model("s").add("force", "F", "p", F=lambda t, q: 1.0)
    bad = lg.Model("bad")
    bad.add("mass", "m1", "p", m=0.3)
    bad.add("force", "F", "p", F=lambda t, q, v: "strong")
    with pytest.raises(lg.ModelError, match=r"the load F_F\(t, q, v\), a Python callable, returned 'strong'"):
        bad.simulate(1.0, initial={"x_p": 0.0}, velocity={"x_p": 0.0})


def test_the_work_of_the_loads_closes_the_energy_balance():
    m, l, Kp, Kd = 0.3, 0.7, 2.5, 0.4
    model = pd_pendulum(m, l, Kp, Kd)
    res = model.simulate(3.0, initial={"theta_j1": -0.4}, velocity={"theta_j1": 1.0}, points=3001, rtol=1e-12,
                         atol=1e-14)
    W = res.cumulative(model.load_power("pd"))
    assert np.max(np.abs(res.E - res.E[0] - W)) < 1e-9 * np.max(np.abs(res.E))
    assert W[-1] < 0  # the controller took energy out on the whole
    # a damper's linear Rayleigh function: the energy it dissipated is ∫ 2D dt, and no load does work
    damped = lg.Model("damped")
    damped.add("mass", "m1", "p", m=0.3)
    damped.add("spring", "k1", ("ground", "p"), k=40.0)
    damped.add("damper", "c1", ("ground", "p"), c=0.25)
    run = damped.simulate(2.0, initial={"x_p": 0.01}, velocity={"x_p": 0.0}, points=2001, rtol=1e-12, atol=1e-15)
    assert damped.load_power() == 0
    assert np.max(np.abs(run.E - run.E[0] + run.cumulative(2 * run.D))) < 1e-9 * run.E[0]
    with pytest.raises(lg.UnknownNameError, match="component with a load"):
        model.load_power("bob")
