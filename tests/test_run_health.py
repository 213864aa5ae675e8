"""Runs that cannot give a right answer, or only at great cost, say so.

Expected values come from the physics: the damped oscillator's rates
(k/c and c/m) decide whether it is stiff; a mass let go at rest above a
central force k/r² falls into the centre in the finite time
π/2·√(m r₀³/(2k)), which a fixed step passes through.
"""

import math
import signal
import warnings

import numpy as np

import pytest

import lagrangian as lg
from lagrangian import integrate


@pytest.fixture
def ctrl_c():
    """Ctrl-C raises ``KeyboardInterrupt``, as in any Python process started from a terminal.  A pytest-xdist worker
    starts with SIGINT ignored (the controller handles it), where ``_thread.interrupt_main`` does nothing: the tests
    that simulate Ctrl-C install Python's own handler for their duration."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)


def damped(c):
    model = lg.Model("damped")
    model.add("mass", "m", "p", m=0.3)
    model.add("spring", "k", ("ground", "p"), k=40)
    model.add("damper", "c", ("ground", "p"), c=c)
    return model


@pytest.mark.slow
def test_an_explicit_method_on_a_stiff_model_warns_before_it_crawls(monkeypatch):
    # rates k/c = 4e-3 and c/m = 3.3e4 1/s: a 1 s run needs some 3e4 explicit steps (warned from 1e5 on; a
    # lower threshold here keeps the test short)
    monkeypatch.setattr(integrate, "STIFFNESS_CHECK_STEPS", 1e4)
    with pytest.warns(lg.StiffnessWarning, match=r"'damped' is stiff.*method='auto'.*'Radau'"):
        res = damped(1e4).simulate(1.0, initial={"x_p": 0.01}, velocity={"x_p": 0.0})
    assert any(note.startswith("WARNING: model 'damped' is stiff") for note in res.notes)
    with warnings.catch_warnings():
        warnings.simplefilter("error", lg.StiffnessWarning)
        damped(1e4).simulate(1.0, initial={"x_p": 0.01}, velocity={"x_p": 0.0}, method="auto")
        damped(1e4).simulate(1.0, initial={"x_p": 0.01}, velocity={"x_p": 0.0}, method="Radau")
        damped(0.7).simulate(1.0, initial={"x_p": 0.01}, velocity={"x_p": 0.0})
        monkeypatch.setattr(integrate, "STIFFNESS_CHECK_STEPS", 1e5)
        damped(1e4).simulate(1.0, initial={"x_p": 0.01}, velocity={"x_p": 0.0})  # stiff, but 3e4 steps are quick


def test_a_fixed_step_through_a_singularity_is_an_error_not_a_state():
    m, k, r0 = 0.3, 2.0, 1.0
    fall = math.pi / 2 * math.sqrt(m * r0**3 / (2 * k))  # 0.43 s to the centre
    model = lg.Model("fall", dim=2)
    model.add("mass", "planet", "p", m=m)
    model.add("central_force", "sun", ("ground", "p"), k=k)
    start = dict(initial={"x_p": r0, "y_p": 0.0}, velocity={"x_p": 0.0, "y_p": 0.0})
    for method in ("verlet", "rk4"):
        with pytest.raises(lg.IntegrationError, match=rf"exploded under {method}.*t=0\.4"):
            model.simulate(3 * fall, method=method, step=0.01, energy_tol=False, **start)
    # before the fall, the same steps are a fine solution
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        model.simulate(0.8 * fall, method="verlet", step=1e-4, **start)


def test_a_run_that_would_not_end_is_refused_and_the_way_out_works():
    # c/m = 3.3e9 1/s: an explicit method would need 3e10 steps over 10 s
    with pytest.raises(lg.IntegrationError, match=r"3\.3\de\+10 steps.*would not end.*method='auto'"):
        damped(1e9).simulate(10, initial={"x_p": 0.01}, velocity={"x_p": 0.0})
    res = damped(1e9).simulate(10, initial={"x_p": 0.01}, velocity={"x_p": 0.0}, method="auto")
    # the slow mode creeps at k/c = 4e-8 1/s: x(10) = 0.01 exp(−4e-7) to first order
    assert res["x_p"][-1] == pytest.approx(0.01 * math.exp(-40 / 1e9 * 10), rel=1e-6)


def test_a_stiff_run_that_would_crawl_for_minutes_is_refused_at_once_and_auto_solves_it():
    # c/m = 3.3e7 1/s decays: DOP853 would need some 3.3e8 steps over 10 s (it took 48 s at c = 1e5, 100 times
    # fewer); the slow mode creeps at k/c = 4e-6 1/s — below the rounding of the linearization next to 3.3e7,
    # so the refusal rests on the fast decay alone — and Radau steps over the decay
    with pytest.raises(lg.IntegrationError, match=r"'damped' is stiff.*decays at 3\.33e\+07 1/s.*3\.3\de\+08 steps.*method='auto'.*'Radau'"):
        damped(1e7).simulate(10, initial={"x_p": 0.01}, velocity={"x_p": 0.0})
    res = damped(1e7).simulate(10, initial={"x_p": 0.01}, velocity={"x_p": 0.0}, method="auto")
    assert res["x_p"][-1] == pytest.approx(0.01 * math.exp(-40 / 1e7 * 10), rel=1e-6)
    # an oscillation as fast is not stiff: every method must step through it, and it is not refused below 1e10
    fast = lg.Model("fast")
    fast.add("mass", "m", "p", m=0.3)
    fast.add("spring", "k", ("ground", "p"), k=3e6)
    fast.add("spring", "k2", ("p", "q"), k=1.0)
    fast.add("mass", "m2", "q", m=3.0)
    assert fast.simulate(0.05, initial={"x_p": 0.01}, points=5).t[-1] == pytest.approx(0.05)


@pytest.mark.parametrize("method", ["auto", "DOP853", "RK45"])
@pytest.mark.slow
def test_a_run_whose_pace_would_never_finish_is_refused_on_the_way(method):
    """A rod 4.91e-96 m long let go horizontal: at the start θ'' = −(3g/2L) cos θ ≈ −3e96 but the linearization is
    zero (sin θ = 0), so nothing warns before the run; then it swings at ~5e47 rad/s. The run is judged on its pace
    after 131,072 evaluations and refused (it had reached t ≈ 1e-45 of 0.0324 s), not left to step for ever; DOP853's
    loop in C refuses it sooner, when the rate passes 1e30 times the state's initial size."""
    model = lg.Model("speck", dim=2)
    model.add("rod", "r", "r", m=1, length=4.91e-96)
    model.add("revolute", "j", ("ground", "r"))
    model.add("gravity", "g")
    with pytest.raises(lg.IntegrationError, match=r"'speck' (has come to t=.* in \d+ evaluations: at this pace .* would "
                                                  r"not end.*Check the parameter values|at t=0: the state diverged .* by "
                                                  r"t=1\.\d+e-49)"):
        model.simulate(0.0324, points=3, method=method, initial={"theta_j": 0.0}, velocity={"theta_j": 0.0})


def test_values_beyond_floating_point_products_are_refused_when_given():
    with pytest.raises(lg.ParameterError, match=r"component 'c', parameter 'c': 1e\+308 is beyond 1e\+150"):
        damped(1e308)


@pytest.mark.parametrize("method", ["auto", "DOP853", "RK45"])
def test_a_pendulum_too_short_to_integrate_is_refused_at_once(method):
    """A rod of 4.91e-96 m: ω = √(g/L) ≈ 1.4e48 rad/s. The exact 1 of q' = v must not be taken for rounding next to
    g/L (it was, the pair ±iω was lost, and the run went on for ~1e47 steps)."""
    m = lg.Model("tiny pendulum", dim=2)
    m.add("link", "arm", "arm", points={"bob": (4.91e-96, 0)})
    m.add("revolute", "pin", ("ground", "arm"), absolute=True)
    m.add("mass", "bob", "arm.bob", m=0.3)
    m.add("gravity", "g", g=9.81)
    with pytest.raises(lg.IntegrationError, match="oscillates at 1.3e\\+48 rad/s"):
        m.simulate(0.5, initial={"theta_pin": -1.0}, velocity={"theta_pin": 0.0}, method=method)


@pytest.mark.parametrize("method", ["DOP853", "dopri5_c", "RK45"])  # loops in C, and SciPy's in Python
@pytest.mark.slow
def test_a_run_beyond_its_evaluation_budget_is_refused_and_one_within_it_runs(method):
    """A 1e-12 kg mass on a 137 N/m spring for 0.7 s: ω = 1.17e7 rad/s, some 1.3e6 periods and ~3e8 evaluations
    of DOP853 — a legitimate run of minutes, which a service running models it did not write bounds with
    ``max_evaluations``."""
    m = lg.Model("speck on a spring")
    m.add("mass", "m", "p", m=1e-12)
    m.add("spring", "k", ("ground", "p"), k=137.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lg.StiffnessWarning)
        with pytest.raises(lg.IntegrationError, match=r"would need some .* allow more than max_evaluations=1e\+06"):
            m.simulate(0.7, initial={"x_p": 1e-3}, velocity={"x_p": 0.0}, max_evaluations=1e6, method=method)
        res = m.simulate(2e-6, initial={"x_p": 1e-3}, velocity={"x_p": 0.0}, max_evaluations=1e6, points=3,
                         method=method)
    omega = math.sqrt(137.0 / 1e-12)
    assert res["x_p"] == pytest.approx(1e-3 * np.cos(omega * res.t), rel=0, abs=1e-3 * 1e-7)
    for bad in (0, -5, "1e6", float("nan")):
        with pytest.raises(lg.ModelError, match="max_evaluations must be a positive number"):
            m.simulate(1e-6, initial={"x_p": 1e-3}, velocity={"x_p": 0.0}, max_evaluations=bad)


@pytest.mark.parametrize("method", ["DOP853", "dopri5_c"])
@pytest.mark.slow
def test_a_long_run_in_c_reports_its_progress_and_stops_on_an_interrupt(method, ctrl_c):
    """A loop in C (DOP853's, dopri5_c's) runs on a thread of its own: the caller's reports progress on the way and, on Ctrl-C
    (simulated by ``_thread.interrupt_main``), stops the loop and raises ``KeyboardInterrupt``, as a run stepped in
    Python would.  The run: a 1e-12 kg mass on a 137 N/m spring for 0.7 s, some 3e8 evaluations."""
    import _thread
    import threading

    m = lg.Model("speck on a spring")
    m.add("mass", "m", "p", m=1e-12)
    m.add("spring", "k", ("ground", "p"), k=137.0)
    seen = []
    timer = threading.Timer(0.5, _thread.interrupt_main)
    timer.start()
    try:
        with warnings.catch_warnings(), pytest.raises(KeyboardInterrupt):
            warnings.simplefilter("ignore", lg.StiffnessWarning)
            m.simulate(0.7, initial={"x_p": 1e-3}, velocity={"x_p": 0.0}, max_evaluations=1e12, method=method,
                       progress=lambda t, end: seen.append(t))
    finally:
        timer.cancel()
    assert seen and 0 < max(seen) < 0.7
    assert seen == sorted(seen)


@pytest.mark.parametrize("method", ["rk4_c", "verlet_c"])
@pytest.mark.slow
def test_the_fixed_step_loops_in_c_are_watched_and_budgeted(method, ctrl_c):
    """rk4_c and verlet_c run on a thread of their own like the adaptive loops (progress on the way, Ctrl-C stops
    them); their evaluations are known before they start, so a run beyond max_evaluations is refused at once."""
    import _thread
    import threading

    m = lg.Model("oscillator")
    m.add("mass", "m", "p", m=0.3)
    m.add("spring", "k", ("ground", "p"), k=47.0)
    start = dict(initial={"x_p": 1e-3}, velocity={"x_p": 0.0}, method=method, energy_tol=False)
    with pytest.raises(lg.IntegrationError, match=r"1000000 steps .* need \d+ evaluations, more than the run's budget "
                                                  r"\(max_evaluations=1e\+05\)"):
        m.simulate(1.0, step=1e-6, max_evaluations=1e5, **start)
    seen = []
    timer = threading.Timer(0.5, _thread.interrupt_main)
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            m.simulate(50.0, step=1e-6, points=3, progress=lambda t, end: seen.append(t), **start)  # 5e7 steps
    finally:
        timer.cancel()
    assert seen and 0 < max(seen) < 50.0


@pytest.mark.parametrize("kind, nodes, params, dim", [
    ("central_force", ("ground", "ground"), {"k": -0.5}, 2),
    ("central_force", ("p", "p"), {"k": -0.5}, 2),
    ("spring", ("ground", "0"), {"k": 4.7}, 1),  # ground under two of its names
    ("spring", ("p", "p"), {"k": 4.7, "rest_length": 0.2}, 2),
    ("damper", ("p", "p"), {"c": 0.03}, 2),  # its rate would be 0/0
    ("coulomb_friction", ("p", "p"), {"F_c": 0.2}, 1),
    ("torsion_spring", ("p", "p"), {"k": 3.0}, 1),
    ("revolute", ("L0", "L0"), {}, 2),
])
def test_an_element_joining_a_node_to_itself_is_refused_by_name(kind, nodes, params, dim):
    """A spring, damper, central force, friction or joint between a node and itself acts on nothing (or is singular:
    a central force's k/r, a damper's rate in the plane): refused when added, naming the component, the node and the
    fix, not accepted silently nor a KeyError from SymPy's printer when the run is compiled."""
    model = lg.Model("self-joined", dim=dim)
    with pytest.raises(lg.ModelError, match=rf"{kind} 'K'.*all node '(ground|p|L0)'.*act on nothing.*Join different"):
        model.add(kind, "K", nodes, **params)
    assert "K" not in model.components


def test_equations_holding_an_undefined_constant_are_refused_before_they_run():
    """A division by zero SymPy writes as ``zoo`` in equations (whatever their source) is a ModelError before any
    evaluation, not a KeyError from the printer or NaNs."""
    import sympy as sp

    from lagrangian.simulation import _lambdify

    x = sp.Symbol("x")
    with pytest.raises(lg.ModelError, match="undefined constant"):
        _lambdify([x], sp.Matrix([x, sp.zoo * x]), {})


def test_a_run_that_will_take_long_says_how_long_once_and_runs_on(monkeypatch):
    """A run stepped in Python, judged often here (every 256 evaluations, from 0.02 s on), that would take longer in
    all than a (lowered) limit says so once with its projected time, and still ends with the answer; with progress
    reported it says nothing, since its progress shows."""
    import lagrangian.numerics.problem as problem

    monkeypatch.setattr(problem, "PACE_EVERY", 0xFF)
    monkeypatch.setattr(problem, "LONG_RUN_AFTER", 0.02)
    monkeypatch.setattr(problem, "LONG_RUN", 0.1)
    m = lg.Model("fast spring")
    m.add("mass", "m", "p", m=0.3)
    m.add("spring", "k", ("ground", "p"), k=3e4)
    with pytest.warns(lg.SlowRunWarning, match=r"'fast spring' has come to t=.* at this pace it will take some .* s in "
                                               r"all\. It is not stuck\. progress=True") as seen:
        res = m.simulate(0.5, initial={"x_p": 1e-3}, velocity={"x_p": 0.0}, points=5, method="RK45", rtol=1e-10,
                         compiled=False)
    slow = [w for w in seen if issubclass(w.category, lg.SlowRunWarning)]
    assert len(slow) == 1 and slow[0].filename == __file__  # the caller's line, not the library's
    omega = math.sqrt(3e4 / 0.3)
    assert res["x_p"] == pytest.approx(1e-3 * np.cos(omega * res.t), rel=0, abs=1e-3 * 1e-4)
    with warnings.catch_warnings():
        warnings.simplefilter("error", lg.SlowRunWarning)
        m.simulate(0.2, initial={"x_p": 1e-3}, velocity={"x_p": 0.0}, points=5, method="RK45", rtol=1e-10,
                   compiled=False, progress=lambda t, end: None)
