"""The robustness cases (benchmarks/robust/) as property tests: hypothesis draws from each case's space.

Every public analysis is covered — the Routhian reduction, steady motions,
their stability, the Jacobi integral, velocity jumps, impacts, circuit
analogues, ngspice comparisons, netlist reading and scenes — each against a
reference that is not the code under test and against its symbolic twin.
``benchmarks/robustness.py --cases 10000`` runs the same checks on many more
draws.
"""

import json
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

BENCHMARKS = Path(__file__).resolve().parent.parent / "benchmarks"
sys.path.insert(0, str(BENCHMARKS))

from robust import Case, Mismatch, cases, decades  # noqa: E402

CASES = cases()
ANALYSES = {"reduce", "steady_motions", "stability", "jacobi_integral", "velocity_jump", "impact", "map_model",
            "compare_with_ngspice", "read_netlist", "Scene"}


def values_of(case: Case):
    """A hypothesis strategy for one draw of ``case``: a unit float per value, mapped through its range."""
    names = sorted(case.space)
    return st.tuples(*[st.floats(0.0, 1.0) for _ in names]).map(
        lambda us: {name: case.space[name].from_unit(u) for name, u in zip(names, us)}
    )


def test_every_public_analysis_has_cases():
    assert {c.analysis for c in CASES} == ANALYSES
    assert len({(c.analysis, c.name) for c in CASES}) == len(CASES)


@pytest.mark.parametrize("case", CASES, ids=[f"{c.analysis}-{c.name}".replace(" ", "_") for c in CASES])
def test_analysis_agrees_with_its_reference_and_its_symbolic_twin(case):
    @settings(max_examples=3, deadline=None, derandomize=True, database=None,
              suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
    @given(values_of(case))
    def check(values):
        assume(case.admissible is None or case.admissible(values))
        case.check(dict(values))

    check()


def test_a_wrong_answer_is_caught():
    """The harness fails a case whose analysis disagrees: a check against a deliberately wrong reference."""
    from robust import close

    wrong = Case("reduce", "wrong on purpose", {"m": decades(0.1, 10)},
                 lambda v: close(v["m"] * (1 + 1e-6), v["m"], "m against itself, off by 1e-6"))
    with pytest.raises(Mismatch, match="off by 1e-6"):
        wrong.check({"m": 0.347})


def test_the_benchmark_prints_its_figures_as_json():
    run = subprocess.run(
        [sys.executable, str(BENCHMARKS / "robustness.py"), "--cases", "10", "--jobs", "1", "--analysis", "impact",
         "--analysis", "map_model"],
        capture_output=True, text=True, timeout=600,
    )
    assert run.returncode == 0, run.stderr
    summary = json.loads(run.stdout.strip().splitlines()[-1])
    assert summary["cases"] == 10
    assert set(summary["by_analysis"]) == {"impact", "map_model"}
    assert sum(a["cases"] for a in summary["by_analysis"].values()) == 10
    assert summary["failures"] == sum(a["failures"] for a in summary["by_analysis"].values())
