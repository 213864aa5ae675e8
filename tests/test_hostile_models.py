"""Findings of a security and load review, each held by the project's own errors.

1. A constraint's scale decides nothing: ``f = c·(x_a − x_b)`` is the same constraint for every factor ``c``, so the
   solve (and the singularity test on it) and the start's check judge it as they judge ``c = 1``; a model that is
   singular whatever the scale still says so, naming its coordinates.
2. Python callables given for signals and loads: text returned where a number is wanted, a model changed by one
   while a run calls it, and an expression that is never real are refused, naming the component and parameter.
3. Errors and warnings cross process boundaries: pickled, returned by a process pool's workers.
4. A sweep's ``address=`` is checked before distributed sees it.
"""

from __future__ import annotations

import concurrent.futures
import importlib
import multiprocessing
import pickle
import re
from pathlib import Path

import cloudpickle
import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

import lagrangian as lg
from lagrangian.base.budget import BudgetExceeded
from lagrangian.sweep import sweep
from lagrangian.analysis.sweep.execute import check_address

ROOT = Path(__file__).resolve().parents[1]
PICKLERS = {"pickle": pickle, "cloudpickle": cloudpickle}

# ---------------------------------------------------------------------------------------------------------------
# 1. a constraint's scale

START = dict(initial={"x_a": 0.01, "x_b": 0.01}, velocity={"x_a": 0.0, "x_b": 0.0})


def two_masses(factor: float) -> lg.Model:
    """Two masses on springs, their positions kept equal by a constraint written with ``factor``."""
    m = lg.Model("two masses", dim=1)
    m.add("mass", "ma", "a", m=0.3)
    m.add("mass", "mb", "b", m=0.5)
    m.add("spring", "k1", ("ground", "a"), k=40.0)
    m.add("spring", "k2", ("a", "b"), k=25.0)
    m.add("spring", "k3", ("ground", "b"), k=10.0)
    m.add("constraint", "c", f=factor * (lg.coordinate("x_a") - lg.coordinate("x_b")))
    return m


def motion(model: lg.Model, compiled="auto") -> np.ndarray:
    res = model.simulate(0.5, **START, points=11, compiled=compiled)
    return np.array([res["x_a"], res["x_b"], res.velocity("x_a")])


REFERENCE: dict = {}


def reference(compiled="auto") -> np.ndarray:
    if compiled not in REFERENCE:
        REFERENCE[compiled] = motion(two_masses(1.0), compiled)
    return REFERENCE[compiled]


def assert_same_motion(got: np.ndarray, want: np.ndarray) -> None:
    assert np.max(np.abs(got - want)) <= 1e-9 * np.max(np.abs(want))


@settings(max_examples=20)
@given(exponent=st.floats(-12.0, 15.0), sign=st.sampled_from([1.0, -1.0]))
def test_a_constraint_gives_the_same_motion_whatever_its_factor(exponent, sign):
    assert_same_motion(motion(two_masses(sign * 10.0**exponent)), reference())


@pytest.mark.parametrize("compiled", ["auto", False, "tape"])
@pytest.mark.parametrize("factor", [1e-12, 1e-9, 1e15, 1e30])
def test_a_constraint_refused_before_for_its_scale_runs_on_every_evaluator(factor, compiled):
    assert_same_motion(motion(two_masses(factor), compiled), reference(compiled))


@pytest.mark.parametrize("factor", [1e-9, 1.0, 1e15])
def test_an_inconsistent_start_is_refused_whatever_the_factor(factor):
    with pytest.raises(lg.ModelError, match=r"does not satisfy the constraints of 'c'"):
        two_masses(factor).simulate(0.5, initial={"x_a": 0.01, "x_b": 0.02}, velocity={"x_a": 0.0, "x_b": 0.0},
                                    points=3)


def massless_pair(factor: float) -> lg.Model:
    """x_b and x_d have no inertia, and the constraint between them fixes only their difference: singular for every
    factor."""
    m = lg.Model("massless pair", dim=1)
    m.add("mass", "ma", "a", m=0.3)
    m.add("spring", "k1", ("ground", "a"), k=40.0)
    m.add("spring", "k2", ("a", "b"), k=40.0)
    m.add("spring", "k3", ("ground", "d"), k=40.0)
    m.add("constraint", "c", f=factor * (lg.coordinate("x_b") - lg.coordinate("x_d")))
    return m


@pytest.mark.parametrize("compiled", ["auto", False])
@pytest.mark.parametrize("factor", [1e-9, 1.0, 1e15])
def test_a_constraint_on_massless_coordinates_is_singular_whatever_its_factor(factor, compiled):
    with pytest.raises(lg.SingularMassMatrixError, match=r"the motion of x_b, x_d is not determined") as info:
        massless_pair(factor).simulate(0.5, initial={"x_a": 0.01, "x_b": 0.0, "x_d": 0.0},
                                       velocity={"x_a": 0.0, "x_b": 0.0, "x_d": 0.0}, points=3, compiled=compiled)
    assert not re.search(r"the motion of\s+(is|\()", str(info.value))


@pytest.mark.parametrize("compiled", ["auto", False])
def test_a_coordinate_without_inertia_and_no_constraint_is_singular_naming_it(compiled):
    m = lg.Model("no inertia", dim=1)
    m.add("mass", "ma", "a", m=0.3)
    m.add("mass", "mb", "b", m=1e-300)  # no inertia to speak of beside 0.3 kg
    m.add("spring", "k1", ("ground", "a"), k=40.0)
    m.add("spring", "k2", ("a", "b"), k=40.0)
    with pytest.raises(lg.SingularMassMatrixError, match=r"the motion of x_b \(x_b: x position of node 'b'\) is not "
                                                         r"determined"):
        m.simulate(0.5, initial={"x_a": 0.01, "x_b": 0.0}, velocity={"x_a": 0.0, "x_b": 0.0}, points=3,
                   compiled=compiled)


def test_the_singular_message_names_a_coordinate_when_only_multipliers_are_at_fault():
    numeric = two_masses(1.0).numeric()
    # the multiplier's column lost (as a factor of 1e-12 left it, unscaled): the null direction is the multiplier's
    A = np.array([[0.3, 0.0, 0.0], [0.0, 0.5, 0.0], [1.0, -1.0, 0.0]])
    message = numeric._singular_message(0.0, A, np.array([0.01, 0.01]))
    assert re.search(r"the motion of x_a, x_b\b", message) and "the motion of  " not in message


# ---------------------------------------------------------------------------------------------------------------
# 2. user callables


def pushed(F) -> lg.Model:
    m = lg.Model("pushed", dim=1)
    m.add("mass", "m1", "p", m=0.3)
    m.add("spring", "k1", ("ground", "p"), k=40.0)
    m.add("force", "F", "p", F=F)
    return m


def simulate_pushed(model: lg.Model, **extra):
    return model.simulate(0.2, initial={"x_p": 0.01}, velocity={"x_p": 0.0}, points=5, **extra)


@pytest.mark.parametrize("compiled", ["auto", False])
@pytest.mark.parametrize("returned, kind", [("1", "str"), (b"1", "bytes"), (["1"], "array of <U1")],
                         ids=["str", "bytes", "list of str"])
def test_a_signal_returning_text_is_a_parameter_error_naming_it(returned, kind, compiled):
    with pytest.raises(lg.ParameterError, match=rf"the signal F_F\(t\), a Python callable, returned .*\(an? {kind}\)"
                                                rf".*not text") as info:
        simulate_pushed(pushed(lambda t: returned), compiled=compiled)
    assert (info.value.component, info.value.parameter) == ("F", "F")
    assert str(info.value).startswith("component 'F', parameter 'F': ")


def test_a_load_of_the_state_returning_text_is_a_parameter_error_naming_it():
    with pytest.raises(lg.ParameterError, match=r"the load F_F\(t, q, v\), a Python callable, returned '1' \(a str\)"
                                                r".*not text") as info:
        simulate_pushed(pushed(lambda t, q, v: "1"))
    assert (info.value.component, info.value.parameter) == ("F", "F")


def test_callables_returning_numbers_still_run():
    spring_only = simulate_pushed(pushed(0.0))
    for F in (lambda t: 0.0, lambda t: np.zeros_like(t), lambda t, q, v: np.float64(0.0), lambda t, q, v: 0):
        np.testing.assert_allclose(simulate_pushed(pushed(F))["x_p"], spring_only["x_p"], rtol=1e-9, atol=1e-15)


def test_a_callable_raising_is_a_parameter_error_naming_it():
    def broken(t):
        raise RuntimeError("the sensor is gone")

    with pytest.raises(lg.ParameterError, match=r"component 'F', parameter 'F': the signal F_F\(t\), a Python "
                                                r"callable, raised RuntimeError: the sensor is gone"):
        simulate_pushed(pushed(broken))


def test_a_callable_adding_a_component_during_a_run_is_refused_naming_it():
    model = pushed(0.0)

    def meddling(t):
        if "k2" not in model.components:
            model.add("spring", "k2", ("ground", "p"), k=10.0)
        return 0.0

    model.add("force", "F2", "p", F=meddling)
    with pytest.raises(lg.ModelError, match=r"model 'pushed' was changed during simulate: component 'k2' \(a "
                                            r"spring\) added while it ran"):
        simulate_pushed(model)
    assert "k2" in model.components  # the change stays, and the next run is of the model as it now is
    res = simulate_pushed(model)
    reference = pushed(0.0)
    reference.add("spring", "k2", ("ground", "p"), k=10.0)
    np.testing.assert_allclose(res["x_p"], simulate_pushed(reference)["x_p"], rtol=1e-9, atol=1e-15)


def test_a_callable_declaring_a_node_during_a_run_is_refused_naming_it():
    model = pushed(0.0)
    model.add("force", "F2", "p", F=lambda t: (model.node("stray"), 0.0)[1])
    with pytest.raises(lg.ModelError, match=r"changed during simulate: node 'stray' added"):
        simulate_pushed(model, compiled=False)


def test_a_run_that_changes_nothing_is_not_refused():
    calls = []
    model = pushed(lambda t: (calls.append(t), 0.0)[1])
    simulate_pushed(model)
    assert calls


@pytest.mark.parametrize("F", [sp.sqrt(-1 - lg.coordinate("x_p") ** 2), sp.log(-1 - lg.t**2)],
                         ids=["sqrt of a negative state", "log of a negative time"])
def test_an_expression_that_is_never_real_is_refused_clearly(F):
    with pytest.raises(lg.ParameterError, match=r"^component 'F', parameter 'F': .* is never a real number "
                                                r"\(a root or logarithm of a quantity always negative") as info:
        pushed(F)
    assert ": , but" not in str(info.value) and "declared otherwise" not in str(info.value)


def test_a_rule_the_assumptions_break_still_says_so():
    k = sp.Symbol("k", negative=True)
    with pytest.raises(lg.ParameterError, match=r"component 'k1', parameter 'k': must be positive, but k is declared "
                                                r"otherwise"):
        lg.Model("m").add("spring", "k1", ("ground", "p"), k=k)


# ---------------------------------------------------------------------------------------------------------------
# 3. errors and warnings across process boundaries


def roundtrip(obj, how: str):
    return pickle.loads(PICKLERS[how].dumps(obj))


@pytest.mark.parametrize("how", sorted(PICKLERS))
def test_budget_exceeded_round_trips_with_its_seconds(how):
    error = BudgetExceeded(0.25)
    error.add_note("while solving")
    back = roundtrip(error, how)
    assert type(back) is BudgetExceeded and back.seconds == 0.25
    assert str(back) == str(error) == "the call did not finish within its budget of 0.25 s"
    assert back.args == error.args and vars(back) == vars(error)


#: The modules of the package (its plugins included) that define warning classes, found in the source.
def _declared_warnings() -> dict[str, set[str]]:
    found: dict[str, set[str]] = {}
    for top, package in ((ROOT / "core", "lagrangian"), (ROOT / "plugins", "lagrangian.plugins")):
        for path in top.rglob("*.py"):
            names = set(re.findall(r"^class (\w+)\([\w., ]*Warning\b[\w., ]*\):", path.read_text(), re.M))
            if names:
                parts = path.relative_to(top).with_suffix("").parts
                module = ".".join((package, *parts[:-1])) if parts[-1] == "__init__" else ".".join((package, *parts))
                found[module] = names
    return found


def warning_classes() -> list[type]:
    """Every warning class of lagrangian, found by walking ``Warning``'s subclasses once the modules that the source
    says define one are imported."""
    for module in _declared_warnings():
        importlib.import_module(module)
    found, todo = set(), [Warning]
    while todo:
        cls = todo.pop()
        if cls.__module__.startswith("lagrangian") and "<locals>" not in cls.__qualname__:
            found.add(cls)
        todo += cls.__subclasses__()
    return sorted(found, key=lambda c: (c.__module__, c.__qualname__))


def test_every_warning_class_of_the_source_is_found_by_the_walk():
    declared = {name for names in _declared_warnings().values() for name in names}
    walked = {cls.__name__ for cls in warning_classes()}
    assert declared == walked
    assert {"InitialConditionWarning", "EnergyDriftWarning", "StiffnessWarning", "SlowRunWarning", "NodeNameWarning",
            "NetlistWarning"} <= walked


@pytest.mark.parametrize("how", sorted(PICKLERS))
@pytest.mark.parametrize("cls", warning_classes(), ids=lambda c: c.__name__)
def test_every_warning_round_trips_with_its_message_and_attributes(cls, how):
    warning = cls(f"{cls.__name__}: what happened, and what to do")
    warning.component, warning.value = "k1", 0.3  # attributes a caller may set on it
    warning.add_note("a note added on the way")
    back = roundtrip(warning, how)
    assert type(back) is cls and str(back) == str(warning) and back.args == warning.args
    assert vars(back) == vars(warning)
    with pytest.warns(cls, match="what happened"):
        import warnings

        warnings.warn(back, stacklevel=1)


def refused_parameter(k: float) -> float:
    """A worker's task (top level: a process pool pickles it by name)."""
    raise lg.ParameterError("k1", "k", f"must be positive (got {k}).")


def over_budget(seconds: float) -> float:
    raise BudgetExceeded(seconds)


def test_a_pool_returns_a_parameter_error_to_the_parent():
    with multiprocessing.get_context("fork").Pool(2) as pool:
        with pytest.raises(lg.ParameterError, match=r"component 'k1', parameter 'k': must be positive \(got -") as info:
            pool.map(refused_parameter, [-1.0, -2.0])
    assert (info.value.component, info.value.parameter) == ("k1", "k")


@pytest.mark.parametrize("task, error, attribute", [(refused_parameter, lg.ParameterError, ("component", "k1")),
                                                     (over_budget, BudgetExceeded, ("seconds", -1.0))],
                         ids=["ParameterError", "BudgetExceeded"])
def test_a_process_pool_executor_reports_the_error_not_a_broken_pool(task, error, attribute):
    with concurrent.futures.ProcessPoolExecutor(2, mp_context=multiprocessing.get_context("fork")) as pool:
        futures = [pool.submit(task, x) for x in (-1.0, -2.0)]
        with pytest.raises(error) as info:
            futures[0].result(timeout=120)
        assert getattr(info.value, attribute[0]) == attribute[1]
        assert isinstance(futures[1].exception(timeout=120), error)  # the pool still works: not broken


# ---------------------------------------------------------------------------------------------------------------
# 4. a sweep's address


def oscillator() -> lg.Model:
    m = lg.Model("osc", dim=1)
    m.add("mass", "m1", "p", m=0.3)
    m.add("spring", "k1", ("ground", "p"), k=40.0)
    return m


@pytest.mark.parametrize("address, why", [
    ("file:///x", r"its scheme 'file' is none of distributed's"),
    ("http://10.0.0.5:8786", r"its scheme 'http'"),
    ("tcp://10.0.0.5", r"no port after the host '10.0.0.5'"),
    ("localhost", r"no port after the host 'localhost'"),
    ("tcp://:8786", r"no host name or IP address"),
    ("tcp://10.0.0.5:99999", r"the port '99999' is not a number from 1 to 65535"),
    ("tcp://10.0.0.5:8786\n", r"spaces or control characters"),
    (8786, r"not text but a value of type int"),
])
def test_a_sweep_refuses_an_address_distributed_cannot_use_naming_it_and_the_forms(address, why):
    with pytest.raises(lg.ModelError) as info:
        sweep(oscillator(), {"k_k1": [10.0, 40.0]}, initial={"x_p": 0.01}, velocity={"x_p": 0.0}, t_end=0.1,
              points=3, address=address, progress=False)
    message = str(info.value)
    assert type(info.value) is lg.ModelError and re.search(why, message)
    assert f"address={address!r}" in message
    assert "'tcp://host:port'" in message and "'host:port'" in message and "inproc://" in message


@pytest.mark.parametrize("address", ["tcp://10.0.0.5:8786", "tls://scheduler.example.org:8786", "ucx://10.0.0.5:13337",
                                     "inproc://10.0.0.5/1234/1", "localhost:8786", "tcp://[::1]:8786"])
def test_the_forms_distributed_accepts_pass_the_check(address):
    assert check_address(address) == address


def test_what_distributed_still_refuses_is_a_model_error(monkeypatch):
    import distributed

    def refusing(address, **_):
        raise ValueError(f"unknown address {address!r}")

    monkeypatch.setattr(distributed, "Client", refusing)
    with pytest.raises(lg.ModelError, match=r"address='tcp://10.0.0.5:8786' is refused by distributed \(ValueError: "
                                            r"unknown address.*'tcp://host:port'"):
        sweep(oscillator(), {"k_k1": [10.0, 40.0]}, analysis=lambda model, values: {"k": values["k_k1"]},
              address="tcp://10.0.0.5:8786", progress=False)
