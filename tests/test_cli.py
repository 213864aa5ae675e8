"""The ``lagrangian`` command as a tool: exit status, one-line errors and warnings, broken pipes, ``--version``.

Every case runs the real command on real inputs: a SPICE netlist written
here, the double pendulum of ``examples/pendulums.py``, the shipped
``oscillator`` benchmark.  The tables of bad option values and of failures
run through ``lagrangian.cli.main([...])`` in this process; some of their
cases, the successful runs, the warnings, ``--version``, the missing command
and the broken pipes run as processes (``python -m lagrangian ...``), so the
exit status is the one a shell sees.  Those processes are started together
(each spends most of its second importing the package) and their results
shared by the tests.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import warnings
from concurrent.futures import ThreadPoolExecutor
from importlib import metadata
from pathlib import Path

import pytest

from lagrangian.cli import main

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
PENDULUMS = f"{EXAMPLES / 'pendulums.py'}:double_pendulum"

# A series RLC circuit; ic= values with a .tran without 'uic' make the reader warn (NetlistWarning).
RLC = """series RLC
V1 in 0 DC 1
R1 in a 10
L1 a b 1m ic=0
C1 b 0 1u ic=0.5
.tran 1u 1m
.end
"""
NETLIST_WARNING = (
    "lagrangian: warning: netlist 'series RLC': .tran has no 'uic', so the elements' ic= values are ignored, as SPICE "
    "ignores them, and the run starts from the DC operating point. Add 'uic' to the .tran line to start from them.\n"
)
SCENE = ["scene", "{tmp}/rlc.cir", "-o", "q_L1"]
BENCH = ["bench", "oscillator", "--methods", "DOP853", "--tolerances", "1e-4", "--no-chart", "--quiet"]

# name: (arguments, option named in the message, a fragment of the message)
USAGE_ERRORS = {
    "points-negative": (SCENE + ["--points", "-3"], "--points", "at least 2"),
    "points-zero": (SCENE + ["--points", "0"], "--points", "got '0'"),
    "points-not-a-number": (SCENE + ["--points", "many"], "--points", "whole number"),
    "tol-zero": (SCENE + ["--tol", "0"], "--tol", "between 0 and 1"),
    "tol-negative": (SCENE + ["--tol=-1e-8"], "--tol", "between 0 and 1"),
    "tol-nan": (SCENE + ["--tol", "nan"], "--tol", "got 'nan'"),
    "t-end-zero": (SCENE + ["--t-end", "0"], "--t-end", "> 0"),
    "t-end-negative": (SCENE + ["--t-end", "-1"], "--t-end", "> 0"),
    "t-end-inf": (SCENE + ["--t-end", "inf"], "--t-end", "finite"),
    "t-end-nan": (SCENE + ["--t-end", "nan"], "--t-end", "got 'nan'"),
    "scene-method": (SCENE + ["--method", "RK54"], "--method", "unknown integration method 'RK54'. Did you mean 'RK45'?"),
    "initial-no-value": (SCENE + ["--initial", "q_L1"], "--initial", "name=value"),
    "param-not-a-number": (SCENE + ["--param", "R=ten"], "--param", "finite number"),
    "steps-zero": (BENCH + ["--steps", "0"], "--steps", "'0' is not a valid step size"),
    "steps-negative": (BENCH + ["--steps=0.1,-0.1"], "--steps", "'-0.1' is not a valid step size"),
    "repeat-zero": (BENCH + ["--repeat", "0"], "--repeat", "at least 1"),
    "repeat-negative": (BENCH + ["--repeat", "-2"], "--repeat", "at least 1"),
    "tolerances-zero": (BENCH + ["--tolerances", "0"], "--tolerances", "'0' is not a valid relative tolerance"),
    "tolerances-negative": (BENCH + ["--tolerances=-1e-6"], "--tolerances", "'-1e-6' is not a valid relative tolerance"),
    "tolerances-text": (BENCH + ["--tolerances", "1e-6,tight"], "--tolerances", "'tight' is not a valid"),
    "tolerances-nan": (BENCH + ["--tolerances", "nan"], "--tolerances", "'nan' is not a valid"),
    "tolerances-empty": (BENCH + ["--tolerances", ","], "--tolerances", "comma-separated"),
    "negative-without-equals": (BENCH + ["--tolerances", "-1e-6"], "--tolerances", "--option=VALUE"),
    "bench-methods": (BENCH + ["--methods", "DOP853,RK54"], "--methods", "Did you mean 'RK45'?"),
    "unknown-option": (["kinds", "--verbose"], "--verbose", "unrecognized arguments"),
    "unknown-command": (["frobnicate"], "command", "invalid choice: 'frobnicate'"),
    "missing-output": (["scene", "{tmp}/rlc.cir"], "--output", "required"),
}

# name: (arguments, what the message must say)
FAILURES = {
    "csv-is-a-directory": (SCENE + ["--csv", "{tmp}"], "--csv '{tmp}' is a directory: give a file name"),
    "csv-under-a-file": (SCENE + ["--csv", "{tmp}/plain/out.csv"], "'{tmp}/plain' is a file, not a directory"),
    "csv-directory-missing": (SCENE + ["--csv", "{tmp}/missing/out.csv"], "directory '{tmp}/missing' does not exist"),
    "out-is-a-file": (BENCH + ["--out", "{tmp}/plain"], "--out '{tmp}/plain' is a file, not a directory"),
    "out-under-a-file": (BENCH + ["--out", "{tmp}/plain/wp"], "'{tmp}/plain' is a file, not a directory"),
    # passes the checks made before running, fails when the benchmark's CSV file is written
    "out-file-is-a-directory": (BENCH + ["--out", "{tmp}/busy"], "cannot write '{tmp}/busy/oscillator.csv': Is a directory"),
    "unknown-benchmark": (["bench", "keplr", "--quiet"], "unknown benchmark 'keplr'. Did you mean 'kepler'?"),
    "missing-source": (["scene", "{tmp}/none.py", "-o", "x"], "does not exist"),
    "source-is-a-directory": (["scene", "{tmp}", "-o", "x"], "is a directory"),
    "source-syntax-error": (["scene", "{tmp}/broken.py", "-o", "x"], "line 1"),
    "unknown-output": (SCENE[:-1] + ["x_b"], "unknown scene output 'x_b'"),
}

SUCCESSES = {
    "bench-run": BENCH + ["--out", "{tmp}/wp"],
    "scene-csv": SCENE + ["--csv", "{tmp}/out.csv", "--points", "11"],
    "pendulum": ["scene", PENDULUMS, "-o", "E", "--t-end", "0.5", "--points", "11"],
}
# Cases of the tables that also run as processes: the exit status as a shell sees it, for each kind of error (a
# bad option value of each command, a failure found before running and one met while running).
IN_A_PROCESS = ["points-negative", "repeat-zero", "csv-is-a-directory", "out-file-is-a-directory"]


def _args(args: list[str], tmp: Path) -> list[str]:
    return [a.replace("{tmp}", str(tmp)) for a in args]


def _command(args: list[str], tmp: Path) -> list[str]:
    return [sys.executable, "-m", "lagrangian", *_args(args, tmp)]


@pytest.fixture(scope="module")
def tmp(tmp_path_factory) -> Path:
    tmp = tmp_path_factory.mktemp("cli")
    (tmp / "rlc.cir").write_text(RLC)
    (tmp / "plain").write_text("a file, not a directory\n")
    (tmp / "busy" / "oscillator.csv").mkdir(parents=True)
    (tmp / "broken.py").write_text("def build(:\n")
    return tmp


@pytest.fixture(scope="module")
def ran(tmp) -> dict[str, subprocess.CompletedProcess]:
    """The cases run as processes (``python -m lagrangian ...``), started together."""
    table = {**{k: v[0] for k, v in USAGE_ERRORS.items()}, **{k: v[0] for k, v in FAILURES.items()}}
    cases = {name: (table[name], {}) for name in IN_A_PROCESS}
    cases.update({name: (args, {}) for name, args in SUCCESSES.items()})
    cases.update({"version": (["--version"], {}), "no-command": ([], {}),
                  "warning-as-error": (SCENE, {"PYTHONWARNINGS": "error"})})
    base = {k: v for k, v in os.environ.items() if k != "PYTHONWARNINGS"}

    def run(args, env):
        return subprocess.run(_command(args, tmp), capture_output=True, text=True, timeout=300, cwd=tmp,
                              env={**base, **env})

    with ThreadPoolExecutor(max_workers=4) as pool:
        futures = {name: pool.submit(run, *case) for name, case in cases.items()}
    return {name: f.result() for name, f in futures.items()}


def _one_error_line(stderr: str) -> str:
    """The error line of ``stderr``: no traceback, exactly one error line (warning lines aside)."""
    assert "Traceback" not in stderr, stderr
    lines = [line for line in stderr.splitlines() if not line.startswith("lagrangian: warning: ")]
    assert len(lines) == 1, stderr
    assert lines[0].startswith("lagrangian: error: "), stderr
    return lines[0]


@pytest.mark.parametrize("name", USAGE_ERRORS)
def test_bad_option_values_are_usage_errors(tmp, capsys, name):
    args, option, fragment = USAGE_ERRORS[name]
    assert main(_args(args, tmp)) == 2
    out, err = capsys.readouterr()
    line = _one_error_line(err)
    assert option in line and fragment in line, line
    assert out == ""


@pytest.mark.parametrize("name", FAILURES)
def test_failures_while_running_exit_1_with_one_line(tmp, capsys, name):
    args, message = FAILURES[name]
    assert main(_args(args, tmp)) == 1
    assert message.replace("{tmp}", str(tmp)) in _one_error_line(capsys.readouterr().err)


@pytest.mark.parametrize("name", IN_A_PROCESS)
@pytest.mark.slow
def test_exit_status_of_the_process(ran, tmp, name):
    proc = ran[name]
    if name in USAGE_ERRORS:
        _, option, fragment = USAGE_ERRORS[name]
        assert proc.returncode == 2, proc.stderr
        line = _one_error_line(proc.stderr)
        assert option in line and fragment in line, line
    else:
        assert proc.returncode == 1, proc.stderr
        assert FAILURES[name][1].replace("{tmp}", str(tmp)) in _one_error_line(proc.stderr)


def test_successful_runs_exit_0(ran, tmp):
    for name in SUCCESSES:
        assert ran[name].returncode == 0, (name, ran[name].stderr)
    assert "DOP853             rtol=1e-04" in ran["bench-run"].stdout and (tmp / "wp" / "oscillator.csv").exists()
    assert ran["scene-csv"].stdout.endswith(f"written: {tmp}/out.csv\n")
    assert (tmp / "out.csv").read_text().splitlines()[0] == "t,q_L1"
    assert len((tmp / "out.csv").read_text().splitlines()) == 12


def test_warnings_are_one_line_each(ran):
    assert ran["scene-csv"].stderr == NETLIST_WARNING
    pendulum = ran["pendulum"]
    assert pendulum.stderr == (
        "lagrangian: warning: initial conditions not given, set to zero: "
        "theta_shoulder, theta_elbow, theta_shoulder', theta_elbow'\n"
    )
    assert "E: at t = 0.5:" in pendulum.stdout


def test_a_warning_made_an_error_is_a_failure(ran):
    proc = ran["warning-as-error"]
    assert proc.returncode == 1
    assert _one_error_line(proc.stderr).startswith("lagrangian: error: NetlistWarning: netlist 'series RLC'")


def test_version(ran):
    proc = ran["version"]
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout == f"lagrangian {metadata.version('lagrangian')}\n"


def test_no_command_prints_usage_and_exits_2(ran):
    proc = ran["no-command"]
    assert proc.returncode == 2
    assert proc.stdout == ""
    assert proc.stderr.startswith("usage: lagrangian ")
    assert "{plugins,kinds,integrators,bench,scene,ac,simulate,convert,equations,sweep,cache}" in " ".join(
        proc.stderr.split())
    assert proc.stderr.splitlines()[-1].startswith("lagrangian: error: no command given")


@pytest.mark.slow
def test_stdout_closed_before_anything_is_written():
    read, write = os.pipe()
    os.close(read)
    try:
        proc = subprocess.run(_command(["kinds"], Path(".")), stdout=write, stderr=subprocess.PIPE, text=True, timeout=120)
    finally:
        os.close(write)
    assert proc.returncode == 141
    assert proc.stderr == ""  # no traceback, no "Exception ignored ... BrokenPipeError"


@pytest.mark.slow
def test_reader_that_stops_after_one_line():
    # `lagrangian kinds | head -1`: the reader may close before or after everything was written
    proc = subprocess.Popen(_command(["kinds"], Path(".")), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    first = proc.stdout.readline()
    proc.stdout.close()
    stderr = proc.stderr.read()
    proc.stderr.close()
    assert proc.wait(timeout=120) in (0, 141)
    assert first.startswith("body  [mechanical")
    assert stderr == ""


def test_main_in_process_returns_the_status(capsys):
    assert main(["--version"]) == 0
    assert capsys.readouterr().out == f"lagrangian {metadata.version('lagrangian')}\n"
    assert main([]) == 2
    assert "usage: lagrangian" in capsys.readouterr().err
    assert main(["bench", "--repeat", "0"]) == 2
    assert capsys.readouterr().err.startswith("lagrangian: error: argument --repeat: ")
    assert main(["bench", "keplr", "--quiet"]) == 1
    assert capsys.readouterr().err.startswith("lagrangian: error: unknown benchmark 'keplr'")


def test_warning_display_is_restored_after_an_in_process_run(capsys):
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        before = warnings.showwarning
        assert main(["scene", PENDULUMS, "-o", "E", "--t-end", "0.5", "--points", "11"]) == 0
        assert warnings.showwarning is before
        assert warnings.filters[0][0] == "always"
    err = capsys.readouterr().err
    assert err.startswith("lagrangian: warning: initial conditions not given, set to zero: theta_shoulder")
    assert len(err.splitlines()) == 1


@pytest.mark.slow
def test_the_readme_command_lines_run_as_written(tmp_path, monkeypatch, capsys):
    """Every ``lagrangian scene``, ``ac`` and ``sweep`` line of the README, on the files it names under examples/
    (``bench`` lines are the benchmarks' own tests)."""
    import shlex

    root = Path(__file__).resolve().parents[1]
    lines = [line.split("  #")[0].strip() for line in (root / "README.md").read_text().splitlines()
             if re.match(r"lagrangian (scene|ac|sweep) ", line)]
    assert len(lines) >= 4
    (tmp_path / "examples").symlink_to(root / "examples")
    monkeypatch.chdir(tmp_path)
    for line in lines:
        args = shlex.split(line)[1:]
        if args[0] == "sweep":
            args.append("--quiet")
        code = main(args)
        assert code == 0, (line, capsys.readouterr().err)
    written = {p.name for p in tmp_path.iterdir()}
    assert {"out.csv", "sweep.nc", "bode.png"} <= written


def test_help_is_plain_text_with_examples_and_the_version_is_single_sourced(capsys):
    import lagrangian

    assert main(["--help"]) == 0
    text = capsys.readouterr().out
    assert "``" not in text and ":func:" not in text and "examples:" in text and "lagrangian sweep " in text
    assert main(["--version"]) == 0
    assert capsys.readouterr().out.strip() == f"lagrangian {lagrangian.__version__}" == f"lagrangian {metadata.version('lagrangian')}"
    root = Path(__file__).resolve().parents[1]
    assert (root / "LICENSE").read_text().startswith("MIT License") and (root / "core" / "py.typed").exists()
    assert "License :: OSI Approved :: MIT License" in metadata.metadata("lagrangian").get_all("Classifier")


@pytest.mark.parametrize("given, numpy_first, expected", [(None, False, "4"), ("12", False, "12"), (None, True, None)])
def test_the_command_lets_idle_blas_threads_sleep_unless_told_otherwise(given, numpy_first, expected):
    """A fresh command sets ``OPENBLAS_THREAD_TIMEOUT`` before NumPy loads OpenBLAS; a value in the environment wins,
    and a process that imported NumPy first (where OpenBLAS has read its settings) is left as it is."""
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_THREAD_TIMEOUT"}
    if given:
        env["OPENBLAS_THREAD_TIMEOUT"] = given
    code = ("import os, sys\n" + ("import numpy\n" if numpy_first else "") +
            "from lagrangian.cli import main\nmain(['--version'])\n"
            "print(os.environ.get('OPENBLAS_THREAD_TIMEOUT'))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, env=env)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().splitlines()[-1] == str(expected)
