"""Work–precision: error against wall time over methods and tolerances (or step sizes).

A :class:`Benchmark` is a scene — a model, an initial state, a time span —
with the truth to measure against: an exact solution, or a reference run
(a method with tight tolerances, or ``"exact"`` for linear models).  Plugins
register benchmarks (hook ``register_benchmarks``); the built-in set is
``oscillator``, ``kepler``, ``duffing``, ``rlc_ladder`` and ``energy``
(``lagrangian bench --list``).

:func:`work_precision` runs methods over tolerances (adaptive methods) or
step sizes (fixed-step ones) and measures, per run, the wall time, the
number of model evaluations and the largest error; the
:class:`WorkPrecision` it returns prints as a table and writes CSV and a
log–log chart.  :func:`stability_limit` finds by bisection the largest
step with which a fixed-step method stays bounded.  The command line is
``lagrangian bench NAME... --methods RK45,DOP853,verlet --out DIR``.

>>> from lagrangian.bench import benchmarks, work_precision
>>> wp = work_precision(benchmarks()["oscillator"], ["DOP853", "verlet"], tolerances=[1e-8], steps=[0.01])
>>> [(r.method, r.setting, r.status) for r in wp.rows]
[('DOP853', 'rtol=1e-08', 'ok'), ('verlet', 'step=0.01', 'ok')]
>>> wp.rows[1].error < 1e-3      # Verlet's error after 10 periods at h = 0.01: about h²·t/24 ≈ 2.6e-4
True
"""

from __future__ import annotations

import csv
import math
import sys
import time
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..base import charts
from ..base import display
from ..plugin.contracts import DEFAULT_TOLERANCES, Benchmark
from ..errors import LagrangianError, ModelError, UnknownNameError
from .integrate import EnergyDriftWarning
from ..plugin.registry import default_registry
from .simulation import InitialConditionWarning

__all__ = ["Benchmark", "DEFAULT_TOLERANCES", "Row", "WorkPrecision", "benchmarks", "work_precision", "run", "stability_limit", "ProgressBar"]

@dataclass
class Row:
    """One run: ``method`` at ``setting`` (``"rtol=1e-06"`` or ``"step=0.01"``) and what it cost and achieved."""

    benchmark: str
    method: str
    kind: str
    setting: str
    value: float
    nfev: int
    wall: float
    error: float
    status: str
    message: str = ""


@dataclass
class WorkPrecision:
    """The rows of a work–precision run on one benchmark; a table, a CSV file, a chart."""

    benchmark: str
    description: str
    rows: list[Row]
    measure: str = "state"

    def table(self) -> str:
        """A plain-text table, one line per run."""
        lines = [f"{self.benchmark}: {self.description}",
                 f"{'method':18} {'setting':16} {'nfev':>9} {'wall s':>10} {'error':>10}  status"]
        for r in self.rows:
            err = f"{r.error:10.2e}" if math.isfinite(r.error) else f"{'-':>10}"
            wall = f"{r.wall:10.4f}" if math.isfinite(r.wall) else f"{'-':>10}"
            status = (f"ok ({r.message})" if r.message else "ok") if r.status == "ok" else f"{r.status}: {r.message[:90]}"
            lines.append(f"{r.method:18} {r.setting:16} {r.nfev:9d} {wall} {err}  {status}")
        return "\n".join(lines)

    def write_csv(self, path: str | Path) -> Path:
        """Write the rows as CSV; return the path."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        with path.open("w", newline="") as fh:
            writer = csv.writer(fh)
            writer.writerow(["benchmark", "method", "kind", "setting", "value", "nfev", "wall_s", "error", "status", "message"])
            for r in self.rows:
                writer.writerow([r.benchmark, r.method, r.kind, r.setting.split("=")[0], repr(r.value), r.nfev,
                                 f"{r.wall:.6g}", f"{r.error:.6g}", r.status, r.message])
        return path

    @charts.plain
    def plot(self, ax) -> None:
        """Draw error against wall time on the matplotlib ``ax`` (log–log), one line per method."""
        import matplotlib

        methods = list(dict.fromkeys(r.method for r in self.rows))
        colors = matplotlib.colormaps["tab20"]
        for i, method in enumerate(methods):
            pts = [(r.wall, r.error) for r in self.rows
                   if r.method == method and r.status == "ok" and r.error > 0 and math.isfinite(r.error)]
            if not pts:
                continue
            kind = next(r.kind for r in self.rows if r.method == method)
            style = "o-" if kind == "adaptive" else "s--"
            ax.loglog([p[0] for p in pts], [p[1] for p in pts], style, color=colors(i % 20), label=f"{method} ({kind})")
        ax.set_xlabel("wall time per run [s]")
        ax.set_ylabel("largest relative energy error" if self.measure == "energy" else "largest error (relative)")
        ax.set_title(f"Work–precision: {self.benchmark}")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)

    def chart(self, path: str | Path) -> Path:
        """Write :meth:`plot` as a PNG file; return the path."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        fig = display.figure(figsize=(7.5, 5.5), layout="constrained")
        self.plot(fig.subplots())
        fig.savefig(path, dpi=110)
        return path


def benchmarks(registry=None) -> dict[str, Benchmark]:
    """The registered benchmarks by name (of the installed plugins by default)."""

    return dict((registry or default_registry()).benchmarks)


class ProgressBar:
    """A one-line progress bar on standard error: ``[#####-----] 12/40 label``."""

    def __init__(self, total: int, stream=None, width: int = 30):
        self.total, self.done, self.width, self._shown = max(total, 1), 0, width, 0
        self.stream = stream if stream is not None else sys.stderr

    def _show(self, text: str, end: str = "") -> None:
        self.stream.write("\r" + text.ljust(self._shown) + end)
        self.stream.flush()
        self._shown = len(text)

    def update(self, label: str) -> None:
        """Show that the next item, ``label``, is under way."""
        filled = int(self.width * self.done / self.total)
        self._show(f"[{'#' * filled}{'-' * (self.width - filled)}] {self.done + 1}/{self.total} {label}"[:120])
        self.done += 1

    def close(self) -> None:
        """Finish the line."""
        self._show(f"[{'#' * self.width}] {self.total}/{self.total} done", "\n")


class _Auto:
    """``method="auto"`` in a work–precision run: given tolerances like an adaptive method."""

    kind = "adaptive"


_AUTO = _Auto()


def _quiet(fn, *args, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", InitialConditionWarning)
        warnings.simplefilter("ignore", EnergyDriftWarning)
        return fn(*args, **kwargs)


def _error(benchmark: Benchmark, res, truth: Mapping[str, np.ndarray] | None) -> float:
    if benchmark.measure == "energy":
        E = res.E
        return float(np.max(np.abs(E - E[0])) / max(abs(E[0]), np.finfo(float).tiny))
    scale = max(float(np.max(np.abs(v))) for v in truth.values()) or 1.0
    return max(float(np.max(np.abs(res[name] - truth[name]))) for name in truth) / scale


def work_precision(
    benchmark: Benchmark | str,
    methods: Sequence[str] | None = None,
    *,
    tolerances: Sequence[float] | None = None,
    steps: Sequence[float] | None = None,
    repeat: int = 1,
    registry=None,
    progress: bool | ProgressBar = False,
) -> WorkPrecision:
    """Run ``methods`` on ``benchmark`` over tolerances and step sizes; measure error, evaluations and wall time.

    Adaptive methods run at each ``rtol`` of ``tolerances`` (with
    ``atol = rtol · benchmark.atol_factor``), fixed-step ones at each of
    ``steps`` (the benchmark's by default).  Wall time is the best of
    ``repeat`` runs of ``Model.simulate``, after an untimed short run that
    builds the model's numeric code.  Fixed-step methods step one by one
    (``fast_linear=False``) unless the benchmark's options say otherwise.
    ``"auto"`` runs at each tolerance like an adaptive method; its row's
    message says what it picked (and the step, for a fixed-step pick).
    A method that refuses the model, or fails, gives a row with status
    ``"refused"`` or ``"failed"`` and its message; the others go on.
    ``progress=True`` shows a progress bar on standard error.
    """

    registry = registry or default_registry()
    if isinstance(benchmark, str):
        known = registry.benchmarks
        if benchmark not in known:
            raise UnknownNameError("benchmark", benchmark, known)
        benchmark = known[benchmark]
    why = benchmark.unavailable(registry)
    if why:
        raise ModelError(f"benchmark {benchmark.name!r} cannot run: it {why}.")
    methods = list(methods or benchmark.methods or registry.integrators)
    integrators = {m: _AUTO if m == "auto" else registry.integrator(m) for m in methods}
    tolerances = list(benchmark.tolerances if tolerances is None else tolerances)
    steps = list(benchmark.steps if steps is None else steps)
    model = benchmark.build()
    t_eval = np.linspace(0.0, benchmark.t_end, benchmark.points)
    base = {"initial": dict(benchmark.initial), "velocity": dict(benchmark.velocity), "params": dict(benchmark.params)}
    truth = None
    if benchmark.measure != "energy":
        if benchmark.exact is not None:
            truth = {k: np.asarray(v, dtype=float) for k, v in benchmark.exact(t_eval).items()}
        else:
            ref = _quiet(model.simulate, benchmark.t_end, t_eval=t_eval, energy_tol=False, **base, **dict(benchmark.reference))
            truth = {name: ref[name] for name in ref.names}
    plan = [(m, v) for m in methods for v in (tolerances if integrators[m].kind == "adaptive" else steps)]
    bar = progress if isinstance(progress, ProgressBar) else (ProgressBar(len(plan)) if progress else None)
    rows: list[Row] = []
    warmed: set[str] = set()
    for method, value in plan:
        integrator = integrators[method]
        adaptive = integrator.kind == "adaptive"
        setting = f"rtol={value:.0e}" if adaptive else f"step={value:.3g}"
        if bar is not None:
            bar.update(f"{benchmark.name}  {method} {setting}")
        options = dict(benchmark.options.get(method, {}))
        if adaptive:
            options.update(rtol=value, atol=value * benchmark.atol_factor)
        else:
            options.setdefault("fast_linear", False)
            options["step"] = value
        kwargs = {**base, "t_eval": t_eval, "method": method, **options}
        try:
            if method not in warmed:
                short = min(benchmark.t_end, benchmark.t_end / 100 if adaptive else 3 * value)
                _quiet(model.simulate, short, **{**kwargs, "t_eval": np.linspace(0.0, short, 2)})
                warmed.add(method)
            best = math.inf
            for _ in range(max(1, repeat)):
                start = time.perf_counter()
                res = _quiet(model.simulate, benchmark.t_end, **kwargs)
                best = min(best, time.perf_counter() - start)
            used = float(value) if adaptive or res.step is None else float(res.step)
            picked = ""
            if method == "auto":
                picked = f"picked {res.method}" + (f", step {res.step:.3g}" if res.step is not None else "")
            rows.append(Row(benchmark.name, method, integrator.kind, setting, used, res.nfev, best,
                            _error(benchmark, res, truth), "ok", picked))
        except LagrangianError as exc:
            status = "refused" if isinstance(exc, ModelError) else "failed"
            rows.append(Row(benchmark.name, method, integrator.kind, setting, float(value), 0, math.nan, math.nan, status,
                            str(exc)))
    if bar is not None and not isinstance(progress, ProgressBar):
        bar.close()
    return WorkPrecision(benchmark.name, benchmark.description, rows, benchmark.measure)


def run(
    names: Sequence[str],
    methods: Sequence[str] | None = None,
    *,
    out: str | Path = ".",
    tolerances: Sequence[float] | None = None,
    steps: Sequence[float] | None = None,
    repeat: int = 1,
    registry=None,
    progress: bool = True,
    chart: bool = True,
) -> list[tuple[WorkPrecision, list[Path]]]:
    """Run benchmarks by name (``"all"``: every available one); write ``<out>/<name>.csv`` and ``.png``."""

    registry = registry or default_registry()
    known = registry.benchmarks
    if list(names) == ["all"]:
        names = [n for n, b in known.items() if not b.unavailable(registry)]
    for name in names:
        if name not in known:
            raise UnknownNameError("benchmark", name, known)
    selected = [known[n] for n in names]
    total = 0
    for b in selected:
        ms = list(methods or b.methods or registry.integrators)
        total += sum(len(b.tolerances if tolerances is None else tolerances) if m == "auto" or registry.integrator(m).kind == "adaptive"
                     else len(b.steps if steps is None else steps) for m in ms)
    bar = ProgressBar(total) if progress else None
    out = Path(out)
    results = []
    for b in selected:
        wp = work_precision(b, methods, tolerances=tolerances, steps=steps, repeat=repeat, registry=registry,
                            progress=bar or False)
        files = [wp.write_csv(out / f"{b.name}.csv")]
        if chart:
            files.append(wp.chart(out / f"{b.name}.png"))
        results.append((wp, files))
    if bar is not None:
        bar.close()
    return results


def stability_limit(
    model,
    method: str,
    *,
    initial: Mapping[str, float],
    velocity: Mapping[str, float] | None = None,
    params: Mapping[str, float] | None = None,
    lo: float,
    hi: float,
    n_steps: int = 2000,
    growth: float = 1e3,
    rel: float = 1e-4,
    **options: Any,
) -> float:
    """The largest step with which ``method`` keeps ``model`` bounded, by bisection between ``lo`` and ``hi``.

    A step is unstable when the largest ``|q|`` over ``n_steps`` steps exceeds
    ``growth`` times the initial one (or the run fails); ``lo`` must be
    stable and ``hi`` unstable.  Bisection stops at relative width ``rel``.
    """

    def unstable(h: float) -> bool:
        span = n_steps * h
        try:
            res = _quiet(model.simulate, span, initial=initial, velocity=velocity or {}, params=params or {},
                         method=method, step=h, t_eval=np.linspace(0.0, span, n_steps + 1), energy_tol=False, **options)
        except LagrangianError:
            return True
        size = np.max(np.abs(np.array([res[n] for n in res.names])), axis=0)
        return bool(np.max(size) > growth * max(size[0], np.finfo(float).tiny))

    if unstable(lo):
        raise ModelError(f"stability_limit: {method} is already unstable at the lower bound step={lo:g}.")
    if not unstable(hi):
        raise ModelError(f"stability_limit: {method} is still stable at the upper bound step={hi:g}.")
    while hi - lo > rel * lo:
        mid = 0.5 * (lo + hi)
        if unstable(mid):
            hi = mid
        else:
            lo = mid
    return lo
