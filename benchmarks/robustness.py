"""Robustness: generated cases of every public analysis against independent references.

Each case (``benchmarks/robust/``) draws ordinary values — parameters
log-uniformly over four or more decades, states uniformly, every value a
three-digit decimal — runs one analysis through the public API, and checks
it against a reference that is not the code under test (closed forms, the
full model, sympy.physics.mechanics, ngspice) and against the same model
built from symbols and then given the values.

``--cases N`` is the number of cases in all, split evenly over the analyses
and, within an analysis, over its model families.  A case that raises, hangs
past ``--limit`` seconds or disagrees is a failure; the first failures are
printed with their values, so they can be replayed with ``--replay``.

Prints a table by analysis and, as its last line, a JSON object
``{"cases": …, "failures": …, "by_analysis": {analysis: {"cases", "failures"}}}``.

Run: .venv/bin/python benchmarks/robustness.py --cases 10000 [--jobs 2] [--seed 0]
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import sys
import time
import traceback
import warnings
from collections import defaultdict
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from robust import Mismatch, cases  # noqa: E402


class _Hang(Exception):
    pass


def _alarm(signum, frame):
    raise _Hang


def _run_one(case, values: dict, limit: float) -> str | None:
    """None when the case passes, else a one-line reason."""
    signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, limit)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            case.check(dict(values))
        return None
    except _Hang:
        return f"no answer within {limit:g} s"
    except Mismatch as exc:
        return f"wrong: {exc}"
    except Exception as exc:  # noqa: BLE001 - every other exception is a failure, reported with its type
        where = traceback.extract_tb(exc.__traceback__)[-1]
        return f"error: {type(exc).__name__}: {exc} ({Path(where.filename).name}:{where.lineno})"
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)


def _chunk(index: int, count: int, seed: int, limit: float) -> list[tuple[int, dict, str | None, float]]:
    """Run ``count`` draws of case ``index`` in this worker; one child seed per case keeps runs reproducible."""
    case = cases()[index]
    rng = np.random.default_rng([seed, index])
    out = []
    for _ in range(count):
        values = case.draw(rng)
        start = time.perf_counter()
        reason = _run_one(case, values, limit)
        out.append((index, values, reason, time.perf_counter() - start))
    return out


def _plan(all_cases, total: int, only: set[str] | None) -> list[tuple[int, int]]:
    """(case index, count) with ``total`` split evenly over analyses, then over each analysis' cases."""
    by: dict[str, list[int]] = defaultdict(list)
    for i, c in enumerate(all_cases):
        if only is None or c.analysis in only:
            by[c.analysis].append(i)
    plan = []
    analyses = sorted(by)
    for a_i, analysis in enumerate(analyses):
        share = total // len(analyses) + (a_i < total % len(analyses))
        members = by[analysis]
        for m_i, index in enumerate(members):
            count = share // len(members) + (m_i < share % len(members))
            if count:
                plan.append((index, count))
    return plan


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=200, help="cases in all, split evenly over the analyses")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--chunk", type=int, default=25, help="draws of one case per task (a warm worker reuses its symbolic twin)")
    parser.add_argument("--limit", type=float, default=120.0, help="seconds before one draw counts as a hang")
    parser.add_argument("--analysis", action="append", help="run only this analysis (repeatable)")
    parser.add_argument("--show", type=int, default=10, help="failures to print in full")
    parser.add_argument("--replay", nargs=2, metavar=("ANALYSIS/FAMILY", "VALUES_JSON"),
                        help="run one printed failure again, with its traceback")
    args = parser.parse_args(argv)

    all_cases = cases()
    if args.replay:
        key, values = args.replay
        found = [c for c in all_cases if f"{c.analysis}/{c.name}" == key]
        if not found:
            parser.error(f"no case {key!r}; cases: {', '.join(sorted(f'{c.analysis}/{c.name}' for c in all_cases))}")
        found[0].check(json.loads(values))
        print(f"{key}: passes")
        return {"cases": 1, "failures": 0, "by_analysis": {found[0].analysis: {"cases": 1, "failures": 0}}}
    plan = _plan(all_cases, args.cases, set(args.analysis) if args.analysis else None)
    tasks = []
    for index, count in plan:
        for j, start in enumerate(range(0, count, args.chunk)):
            tasks.append((index, min(args.chunk, count - start), args.seed * 1_000_003 + j))
    total = sum(count for _, count in plan)
    results: list[tuple[int, dict, str | None, float]] = []
    began = time.perf_counter()
    done = 0

    def report(rows):
        nonlocal done
        results.extend(rows)
        done += len(rows)
        failed = sum(r[2] is not None for r in results)
        rate = done / max(time.perf_counter() - began, 1e-9)
        sys.stderr.write(f"\r{done}/{total} cases, {failed} failures, {rate:.1f} cases/s   ")
        sys.stderr.flush()

    if args.jobs <= 1:
        for task in tasks:
            report(_chunk(*task, args.limit))
    else:
        with ProcessPoolExecutor(args.jobs) as pool:
            futures = [pool.submit(_chunk, *task, args.limit) for task in tasks]
            for f in as_completed(futures):
                report(f.result())
    sys.stderr.write("\n")
    wall = time.perf_counter() - began

    by_analysis: dict[str, dict] = {}
    rows = defaultdict(lambda: [0, 0, 0.0, set()])
    for index, values, reason, seconds in results:
        c = all_cases[index]
        r = rows[c.analysis]
        r[0] += 1
        r[1] += reason is not None
        r[2] += seconds
        r[3].add(c.name)
    print(f"{'analysis':<22}{'cases':>8}{'failures':>10}{'ms/case':>10}  model families")
    for analysis in sorted(rows):
        n, f, s, names = rows[analysis]
        print(f"{analysis:<22}{n:>8}{f:>10}{1000 * s / n:>10.1f}  {', '.join(sorted(names))}")
        by_analysis[analysis] = {"cases": n, "failures": f}
    failures = [(all_cases[i], v, r) for i, v, r, _ in results if r is not None]
    print(f"{'total':<22}{len(results):>8}{len(failures):>10}   wall {wall:.1f} s on {args.jobs} process(es), seed {args.seed}")
    for c, values, reason in failures[: args.show]:
        print(f"FAIL {c.analysis}/{c.name} {json.dumps(values)}: {reason}")
    summary = {"cases": len(results), "failures": len(failures), "by_analysis": by_analysis}
    print(json.dumps(summary))
    return summary


if __name__ == "__main__":
    main()
