"""Bad arguments to a run get the project's errors, naming the argument and the fix — never a NumPy/SciPy/SymPy one."""

import math

import numpy as np
import pytest

import lagrangian as lg
from lagrangian import arguments, impulse


@pytest.fixture(scope="module")
def osc():
    m = lg.Model("osc")
    m.add("mass", "m", "p", m=0.3)
    m.add("spring", "k", ("ground", "p"), k=7.0)
    m.numeric()
    return m


BAD = [
    ({"initial": np.array([0.1])}, "initial must map names", "dict(zip"),
    ({"initial": [("x_p", 0.1)]}, "initial must map names", "x_p"),
    ({"initial": 0.1}, "initial must map names", "x_p"),
    ({"velocity": 0.1}, "velocity must map names", "x_p"),
    ({"params": [1, 2]}, "params must map names", "k_k"),
    ({"points": 2.5}, "points must be a positive whole number", "points=1001"),
    ({"points": 0}, "points must be a positive whole number", "points=1001"),
    ({"points": -3}, "points must be a positive whole number", "points=1001"),
    ({"points": "100"}, "points must be a positive whole number", "points=1001"),
    ({"points": 10**12}, "more than 50% of this machine's memory", "fewer times"),
    ({"t_eval": [0, 0.7, 0.3]}, "t_eval must be sorted", "np.sort"),
    ({"t_eval": [0, 20]}, "t_eval must lie within the time span", "widen t_end"),
    ({"t_eval": [0, math.nan]}, "t_eval must hold finite times", "nan"),
    ({"t_eval": [[0, 1]]}, "one-dimensional", "shape (1, 2)"),
    ({"t_eval": "0 1"}, "t_eval must be a sequence of times", "str"),
    ({"t_eval": []}, "non-empty", "shape (0,)"),
    ({"rtol": 0}, "rtol must be a positive", "got 0"),
    ({"rtol": -1e-6}, "rtol must be a positive", "-1e-06"),
    ({"rtol": "1e-6"}, "rtol must be a positive number", "str"),
    ({"rtol": math.nan}, "rtol must be a positive", "nan"),
    ({"atol": -1}, "atol must be a positive", "-1"),
    ({"atol": [1e-9, 1e-9, 1e-9]}, "atol given per state must have 2 entries", "(3,)"),
    ({"atol": [1e-9, 0.0]}, "positive and finite in every entry", "atol"),
    ({"max_step": 0}, "max_step must be a positive", "got 0"),
    ({"max_step": -1.0}, "max_step must be a positive", "-1"),
    ({"energy_tol": -1e-6}, "energy_tol must be a relative drift", "-1e-06"),
    ({"energy_tol": "1e-6"}, "energy_tol must be a relative drift", "'1e-6'"),
    ({"progress": "yes"}, "progress must be True, False or a callable", "'yes'"),
    ({"method": "rk4", "step": 0}, "step must be a positive", "got 0"),
    ({"method": "rk4", "step": math.inf}, "step must be a positive number (finite)", "inf"),
    ({"method": "rk4", "step": 10**400}, "step must be a positive number (finite)", "1000"),
    ({"rtol": 10**400}, "rtol must be a positive number (finite)", "1000"),
]


@pytest.mark.parametrize("method", ["DOP853", "exact", "auto"])
@pytest.mark.parametrize("given,message,fix", BAD, ids=[f"{list(k)[-1]}={v!r}"[:40] for k, v, _ in
                                                         [(b[0], list(b[0].values())[-1], None) for b in BAD]])
def test_a_bad_argument_is_a_model_error_naming_it(osc, given, message, fix, method):
    kwargs = {"initial": {"x_p": 0.1}, "method": method, **given}  # checked before any method runs
    with pytest.raises(lg.ModelError) as info:
        osc.simulate(1.0, **kwargs)
    assert message in str(info.value)
    assert fix in str(info.value)


@pytest.mark.parametrize("t_end,fix", [("10", "write t_end=10"), ("ten", "give seconds as a number"),
                                       ([0, "1"], "give seconds"), (None, "give seconds")])
def test_t_end_given_as_text_is_refused(osc, t_end, fix):
    with pytest.raises(lg.ModelError, match="t_end must be a number of seconds") as info:
        osc.simulate(t_end, initial={"x_p": 0.1})
    assert fix in str(info.value)


@pytest.mark.parametrize("t_end", [math.nan, math.inf, -1.0, 0.0, (1.0, 1.0), (2.0, 1.0)])
def test_a_span_that_does_not_end_after_it_starts_is_refused(osc, t_end):
    with pytest.raises(lg.ModelError, match="the time span must end after it starts"):
        osc.simulate(t_end, initial={"x_p": 0.1})


def test_numbers_of_every_numpy_kind_are_accepted(osc):
    """The checks refuse wrong kinds, not NumPy's numbers: np.float32 spans, np.int64 points, an array t_eval."""
    res = osc.simulate(np.float32(1.0), initial={"x_p": np.float64(0.1)}, points=np.int64(5), rtol=np.float64(1e-9))
    assert res.t.size == 5
    res = osc.simulate((np.int64(0), 1), initial={"x_p": 0.1}, t_eval=np.linspace(0, 1, 4), atol=np.full(2, 1e-12))
    # a mass 0.3 on a spring 7: x = 0.1 cos(ω t), ω = √(7/0.3)
    assert np.allclose(res["x_p"], 0.1 * np.cos(math.sqrt(7 / 0.3) * res.t), rtol=0, atol=1e-8)


@pytest.mark.parametrize("value,message", [(lambda t: np.array([1.0, 2.0]), "array of shape (2,)"),
                                           (lambda t: "a", "it must return a number"),
                                           (lambda t: None, "it must return a number")])
def test_a_force_callable_that_does_not_return_one_number_is_named(value, message):
    m = lg.Model("pushed")
    m.add("mass", "m", "p", m=0.3)
    m.add("force", "F", "p", F=value)
    with pytest.raises(lg.ModelError, match="the signal F") as info:
        m.simulate(1.0, initial={"x_p": 0}, velocity={"x_p": 0})
    assert message in str(info.value)


def test_a_force_callable_returning_numbers_still_runs():
    m = lg.Model("pushed")
    m.add("mass", "m", "p", m=0.3)
    m.add("force", "F", "p", F=lambda t: 0.6)
    res = m.simulate(1.0, initial={"x_p": 0}, velocity={"x_p": 0}, points=3)
    assert np.allclose(res["x_p"], 0.5 * (0.6 / 0.3) * res.t**2, rtol=1e-9, atol=1e-12)  # x = F t² / 2m


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf, np.float64("nan")])
def test_a_non_finite_impulse_is_refused(bad):
    m = lg.Model("cart")
    m.add("mass", "m", "cart", m=0.3)
    with pytest.raises(lg.LagrangianError, match="finite") as info:
        impulse.velocity_jump(m, [impulse.Impulse("cart", bad)], at={}, velocity={"x_cart": 0.1})
    assert "impulse at 'cart'" in str(info.value)


def test_the_memory_estimate_follows_the_state_size():
    """A grid that fits for a 1-DOF model is refused for one with 1000× the states."""
    share = arguments.MEMORY_SHARE * arguments._memory()
    times = int(share / (3 * 8 * (2 * 2 + 4)) / 2)  # half the budget for 2 state values
    arguments._fits(times, 2, "points")
    with pytest.raises(lg.ModelError, match="more than 50%"):
        arguments._fits(times, 2000, "points")


@pytest.mark.parametrize("given,message", [
    ({"initial": {"x_p": -1e150}}, r"within ±1e\+100"),
    ({"velocity": {"x_p": 1e183}}, r"within ±1e\+100"),
    ({"initial": {"x_p": 10**400}}, r"within ±1e\+100"),
    ({"initial": {"x_p": math.inf}}, "initial value of 'x_p' must be finite"),
    ({"initial": {"x_p": "0.1"}}, "must be a number, got '0.1'"),
    ({"velocity": {"x_p": [0.1]}}, "initial velocity of 'x_p' must be a number"),
])
def test_an_initial_state_that_is_no_physical_state_is_refused(osc, given, message):
    """From 1e149 on, LSODA never returns on an oscillator: states are bounded before any run."""
    with pytest.raises(lg.ModelError, match=message):
        osc.simulate(0.03, points=5, method="LSODA", **{"initial": {"x_p": 0.1}, **given})


def test_an_initial_state_of_ordinary_size_in_large_units_still_runs(osc):
    res = osc.simulate(0.03, points=5, method="LSODA", initial={"x_p": -1e100}, velocity={"x_p": 0.0})
    assert np.allclose(res["x_p"], -1e100 * np.cos(math.sqrt(7 / 0.3) * res.t), rtol=1e-6)


@pytest.mark.parametrize("method", ["RK45", "DOP853", "dopri5_c", "Radau"])
def test_a_step_cap_that_would_never_end_is_refused(osc, method):
    with pytest.raises(lg.ModelError, match="caps the run at more than 100,000,000 steps"):
        osc.simulate(1e-3, points=3, method=method, max_step=1e-20, initial={"x_p": 0.1})
