"""Untrusted input never runs, and bad input gets the project's own errors: the CI profile of benchmarks/fuzz.py.

The property tests draw cases from the benchmark's own generators (models
built through the public API with hostile names and values, mutated SPICE
decks, expression text), with hypothesis driving the generators' random
choices, and run them through the benchmark's checker: a case must end in
success or a ``LagrangianError`` (warnings allowed), and the marker file
every payload tries to create must never appear.  Native compilation and
ngspice runs are left to the benchmark (``heavy=False``).

Inputs the fuzzer found are pinned below one by one.  One the library
still answers with a foreign exception, or lets run, is a strict xfail
naming the bug; a fix turns its test into an XPASS failure, and its marker
is then removed (so every test below passes once its bug is fixed).
"""

import itertools
import json
import os
import signal
import subprocess
import sys
import warnings
from pathlib import Path

import pytest
import sympy as sp
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import lagrangian as lg

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks"))

import fuzz  # noqa: E402

codegen = fuzz.lib("codegen")

PROPERTY = settings(max_examples=60, deadline=None, derandomize=True,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
LIMIT = 20.0
_counter = itertools.count()


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    """Markers go here; compiled code goes to a cache of its own (restored afterwards)."""
    path = tmp_path_factory.mktemp("fuzz")
    saved = dict(codegen._settings)
    codegen.set_cache_dir(path / "cache")
    fuzz.examples()
    yield path
    codegen._settings.clear()
    codegen._settings.update(saved)


def _marker(workdir: Path) -> str:
    return str(workdir / f"EXECUTED-{next(_counter)}")


def _judge(case: dict) -> None:
    outcome, _ = fuzz.check(case, LIMIT)
    assert outcome is None, (
        f"{outcome['kind']}: {outcome['type']}: {outcome['message']} (last frame {outcome['last']}, library frame "
        f"{outcome['library']}); case: {json.dumps(case)[:3000]}"
    )


# ---------------------------------------------------------------------------------------------------
# Properties over the benchmark's generators
# ---------------------------------------------------------------------------------------------------


@PROPERTY
@given(rng=st.randoms(use_true_random=False))
def test_models_built_from_untrusted_input_end_in_success_or_a_project_error(rng, workdir):
    _judge(fuzz.draw_model(rng, _marker(workdir), heavy=False))


@PROPERTY
@given(rng=st.randoms(use_true_random=False))
def test_no_payload_in_a_model_ever_runs(rng, workdir):
    """The same model cases, judged only on the marker: whatever the exception, nothing was run."""
    outcome, _ = fuzz.check(fuzz.draw_model(rng, _marker(workdir), heavy=False), LIMIT)
    assert outcome is None or outcome["kind"] != "executed", outcome


@PROPERTY
@given(rng=st.randoms(use_true_random=False))
def test_mutated_netlists_end_in_success_or_a_project_error(rng, workdir):
    _judge(fuzz.draw_netlist(rng, _marker(workdir), heavy=False))


@PROPERTY
@given(rng=st.randoms(use_true_random=False))
def test_expression_text_ends_in_success_or_a_project_error(rng, workdir):
    _judge(fuzz.draw_signal(rng, _marker(workdir), heavy=False))


@PROPERTY
@given(rng=st.randoms(use_true_random=False))
def test_any_name_of_a_node_or_component_stays_out_of_c_and_spice(rng, workdir):
    """A hostile name on every node and component of a circuit: its C source and SPICE deck keep it inert.

    This property is about the text written, so its names have no NUL: a NUL in a node name stops the derivation
    with a foreign exception (pinned by test_a_nul_in_a_node_name_is_a_model_error; the model properties above
    draw NULs too).
    """
    netlist = fuzz.lib("spice").netlist
    marker = _marker(workdir)
    name = fuzz.name_text(rng, marker).replace("\x00", "")
    model = lg.Model(name)
    try:
        model.add("voltage_source", f"V{name}", (f"a{name}", "0"), E=1.0)
        model.add("resistor", f"R{name}", (f"a{name}", f"b{name}"), R=2.0)
        model.add("capacitor", f"C{name}", (f"b{name}", "0"), C=0.5)
        model.add("inductor", f"L{name}", (f"b{name}", "0"), L=0.25)
        source = codegen.generate_source(model.numeric())
        deck = netlist(model, t_end=0.1).text
    except lg.LagrangianError:
        return
    comment, rest = source.split("\n", 1)
    assert comment.startswith("/* ") and comment.endswith(" */") and comment.count("*/") == 1
    assert "system" not in rest and marker not in rest
    assert len(deck.splitlines()) == 7 and not any(line.lower().startswith((".control", "shell", ".include"))
                                                   for line in deck.splitlines())
    assert not os.path.exists(marker)


# ---------------------------------------------------------------------------------------------------
# The benchmark itself
# ---------------------------------------------------------------------------------------------------


def test_the_benchmark_prints_its_summary_and_nothing_ran():
    proc = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "fuzz.py"), "--cases", "50", "--jobs", "1"],
                          capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr[-3000:]
    summary = json.loads(proc.stdout.strip().splitlines()[-1])
    assert list(summary)[:4] == ["cases", "unexpected_exceptions", "hangs", "executed"]
    assert summary["cases"] == 50 and summary["executed"] == 0


def test_the_checker_tells_a_foreign_exception_from_a_project_error(workdir, monkeypatch):
    """The harness itself: a KeyError is unexpected, a ModelError is not, a payload that runs is caught."""
    case = {"family": "signal", "marker": _marker(workdir), "text": "1", "where": "parse", "method": "auto",
            "compiled": False, "t_end": 0.1, "netlist": False}
    assert fuzz.check(case, LIMIT)[0] is None

    def raises(exc):
        def run(case, stats):
            raise exc
        return run

    monkeypatch.setitem(fuzz.RUN, "signal", raises(KeyError("x")))
    assert fuzz.check(case, LIMIT)[0]["kind"] == "unexpected"
    monkeypatch.setitem(fuzz.RUN, "signal", raises(lg.ModelError("refused")))
    assert fuzz.check(case, LIMIT)[0] is None
    monkeypatch.setitem(fuzz.RUN, "signal", lambda case, stats: Path(case["marker"]).touch())
    assert fuzz.check(case, LIMIT)[0]["kind"] == "executed"
    Path(case["marker"]).unlink()
    monkeypatch.setitem(fuzz.RUN, "signal", lambda case, stats: signal.pause())
    assert fuzz.check(case, 0.2)[0]["kind"] == "hang"


# ---------------------------------------------------------------------------------------------------
# Known failing inputs (found by the fuzzer, shrunk by hand), one test each
# ---------------------------------------------------------------------------------------------------


def correct(run) -> None:
    """``run()`` succeeds or raises a LagrangianError; any other exception fails the test."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            run()
        except lg.LagrangianError:
            pass


def oscillator(node="p"):
    model = lg.Model("oscillator")
    model.add("mass", "m", node, m=1.0)
    model.add("spring", "k", ("ground", node), k=4.0)
    return model


def rc():
    model = lg.Model("rc")
    model.add("voltage_source", "V1", ("in", "0"), E=1)
    model.add("resistor", "R1", ("in", "out"), R=1)
    model.add("capacitor", "C1", ("out", "0"), C=1)
    return model


def code(marker) -> str:
    return f"__import__('os').system('touch {marker}')"


# -- text that runs ---------------------------------------------------------------------------------


def test_netlist_options_given_as_text_never_run(tmp_path):
    marker = tmp_path / "ran"
    correct(lambda: fuzz.lib("spice").netlist(rc(), options={"abstol": f"{code(marker)} or 1e-12"}))
    assert not marker.exists()


def test_text_given_to_an_analogue_never_runs(tmp_path):
    marker = tmp_path / "ran"
    mapped = fuzz.lib("analogy").map_model(oscillator(), "force-current")
    correct(lambda: mapped.to_source(code(marker)))
    assert not marker.exists()


@pytest.mark.parametrize("shape", ["dict", "tuple"])
def test_text_inside_a_container_given_for_a_parameter_never_runs(tmp_path, shape):
    marker = tmp_path / "ran"
    value = {code(marker): 1} if shape == "dict" else (code(marker),)
    correct(lambda: lg.Model().add("mass", "m", "p", m=value))
    assert not marker.exists()


@pytest.mark.parametrize("shape", ["dict", "tuple"])
def test_text_inside_a_container_given_for_a_quantity_never_runs(tmp_path, shape):
    marker = tmp_path / "ran"
    res = oscillator().simulate(0.1, points=3, initial={"x_p": 0.1}, velocity={"x_p": 0.0})
    correct(lambda: res.quantity({code(marker): 1} if shape == "dict" else (code(marker),)))
    assert not marker.exists()


# -- foreign exceptions -----------------------------------------------------------------------------


@pytest.mark.parametrize("nodes", [None, 1.5])
def test_nodes_that_are_not_names_are_a_model_error(nodes):
    correct(lambda: lg.Model().add("gravity", "g", nodes))


def test_a_nul_in_a_node_name_is_a_model_error():
    correct(lambda: oscillator("\x00").equations)


def test_a_percent_in_a_node_name_prints_as_latex():
    correct(lambda: oscillator("%").latex())


def test_an_initial_value_beyond_a_float_is_a_model_error():
    correct(lambda: oscillator().simulate(0.1, points=3, initial={"x_p": 10**400}))


def test_a_parameter_value_beyond_a_float_is_a_model_error():
    correct(lambda: oscillator().simulate(0.1, points=3, params={"k_k": 10**400}))


@pytest.mark.parametrize("text", [pytest.param("1/0", id="zoo"), pytest.param("sqrt(-1)", id="complex"),
                                  pytest.param("1" * 400, id="huge-integer"), pytest.param("erfc(-t)", id="erfc")])
def test_a_quantity_is_evaluated_or_is_a_project_error(text):
    res = oscillator().simulate(0.1, points=3, initial={"x_p": 0.1}, velocity={"x_p": 0.0})
    correct(lambda: res.quantity(text))


def test_mapping_a_lone_inductor_is_a_model_error():
    model = lg.Model("lone")
    model.add("inductor", "L", ("a", "0"), L=1.0)
    correct(lambda: fuzz.lib("analogy").map_model(model, "force-voltage"))


@pytest.mark.parametrize("given", [pytest.param("abc", id="text"), pytest.param([1.0], id="list"),
                                   pytest.param(sp.Heaviside(lg.t), id="expression")])
def test_a_bad_initial_value_of_an_analogue_is_a_model_error(given):
    mapped = fuzz.lib("analogy").map_model(oscillator(), "force-current")
    correct(lambda: mapped.initial({"x_p": given}, {}))


def test_a_huge_integer_inside_a_signal_runs_on_numpy():
    model = oscillator()
    model.add("force", "F", "p", F="cot(10**30)")
    correct(lambda: model.simulate(0.1, points=3, compiled=False))


def test_netlist_options_that_are_not_numbers_are_a_model_error():
    correct(lambda: fuzz.lib("spice").netlist(rc(), options={"abstol": "1e"}))


@pytest.mark.parametrize("option", ["t_end", "step"])
def test_netlist_times_given_as_text_are_a_model_error(option):
    correct(lambda: fuzz.lib("spice").netlist(rc(), **{option: "1"}))


def test_auto_on_a_nearly_massless_transducer_is_a_project_error():
    model = lg.Model("solenoid")
    model.add("capacitor", "C", ("n1", "0"), C=32.3)
    model.add("mass", "m", "p", m=1e-300)
    model.add("spring", "k", ("ground", "p"), k=2)
    model.add("solenoid", "S", ("n1", "0", "p"), L0=1, x0=4)
    correct(lambda: model.simulate(0.03, method="auto"))


def test_a_singular_signal_on_numpy_is_a_numerical_error():
    model = oscillator()
    model.add("force", "F", "p", F="1/t")
    correct(lambda: model.simulate(0.5, points=3, compiled=False))


def test_bdf_on_numpy_with_a_singular_mass_matrix_is_a_numerical_error():
    model = lg.Model("solenoid")
    model.add("capacitor", "C", ("a", "0"), C=1)
    model.add("mass", "m", "p", m=0.417)
    model.add("solenoid", "S", ("a", "0", "p"), L0=4.53e-141, x0=4)
    correct(lambda: model.simulate(0.0697, method="BDF", compiled=False, initial={"q_S": 552.0}))


def test_a_signal_whose_callable_raises_is_a_model_error_naming_it():
    """Seed 103, case 6110: a voltage source's callable that raises reached the SPICE deck's initial state as the
    callable's own RuntimeError (so did a run); now every path tells it as a ModelError naming the signal and the
    time, the user's exception chained."""
    def broken(t):
        raise RuntimeError("a user's signal failed")

    m = lg.Model("rlc")
    m.add("voltage_source", "Z", ("n1", "0"), E=broken)
    m.add("resistor", "R", ("n1", "n2"), R=1)
    m.add("inductor", "L", ("n2", "n3"), L=1)
    m.add("capacitor", "C", ("n3", "0"), C=1)
    spice = fuzz.lib("spice")
    for run in (lambda: m.simulate(0.5, points=3), lambda: m.simulate(0.5, points=3, compiled=False),
                lambda: spice.netlist(m, t_end=0.01)):
        with pytest.raises(lg.ModelError, match=r"signal E_Z\(t\).*raised RuntimeError: a user's signal failed") as info:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                run()
        assert isinstance(info.value.__cause__, RuntimeError)


def test_a_long_node_name_does_not_crash_ngspice():
    script = (
        "import sys; sys.path.insert(0, 'benchmarks'); import fuzz, lagrangian as lg\n"
        "node = 'n' * 520\n"
        "m = lg.Model('o')\n"
        "m.add('capacitor', 'C', (node, '0'), C=1)\n"
        "m.add('inductive_two_port', 'T', (node, '0', 'n2', '0'), L0=1, x0=4)\n"
        "m.add('inductor', 'Lm', ('n2', 'n3'), L=1)\n"
        "m.add('capacitor', 'Ck', ('n3', '0'), C=0.5)\n"
        "spice = fuzz.lib('spice')\n"
        "try:\n"
        "    spice.run_transient(spice.netlist(m, t_end=0.1))\n"
        "except lg.LagrangianError as exc:\n"
        "    sys.exit(3 if type(exc).__name__ == 'NgspiceMissingError' else 0)\n"
    )
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120, cwd=ROOT)
    if proc.returncode == 3:
        pytest.skip("ngspice's shared library is not installed")
    assert proc.returncode == 0, proc.stderr[-500:]


# -- hangs ------------------------------------------------------------------------------------------


class _Late(BaseException):
    pass


def within(seconds, run):
    """``correct(run)`` under a timer: past ``seconds`` it is stopped with _Late."""

    def late(signum, frame):
        raise _Late

    previous = signal.signal(signal.SIGALRM, late)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        correct(run)
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def test_lsoda_from_a_huge_initial_value_returns():
    within(3.0, lambda: oscillator().simulate(0.03, points=5, method="LSODA", initial={"x_p": -1e150}))


def test_an_adaptive_step_cap_that_takes_forever_is_refused():
    within(3.0, lambda: oscillator().simulate(1e-3, points=3, method="RK45", max_step=1e-20))


def test_auto_with_a_deeply_nested_signal_returns():
    model = oscillator()
    model.add("force", "F", "p", F="sin(" * 10 + "t" + ")" * 10)
    within(3.0, lambda: model.simulate(1e-3, points=3, method="auto"))
