"""Parameter sweeps and ensembles: compiled once, run on Dask, results as labelled arrays.

:func:`sweep` runs a model over a grid of parameter values, zipped lists,
or random draws with a seed (:mod:`~lagrangian.sweep.designs`), and returns an
:class:`xarray.Dataset` (:mod:`~lagrangian.sweep.dataset`).

- **Simulations** (the default): the model is derived and compiled once,
  into a native library that reads parameter values at run time
  (:mod:`lagrangian.numerics.ensemble`); workers receive that compiled form
  and parameter vectors, and never derive anything.  Each sample is one run
  of ``Model.simulate``'s DOP853 loop in C, with the same tolerances and the
  same results to the last bit.
- **Any analysis**: ``analysis=fn`` runs ``fn(model, values)`` per sample
  (``values``: the sample's values by name) on the workers, with the model
  sent to each worker once, its derivation included; ``fn`` returns a
  mapping of outputs (numbers, text, arrays or :class:`xarray.DataArray`):
  steady motions and their stability, impacts, frequency responses, ngspice
  comparisons.

Work runs on Dask (:mod:`~lagrangian.sweep.execute`): a local process pool
with no set-up by default, or a cluster through ``client=`` or
``address=``.  A failing sample is recorded with its error, Ctrl-C keeps
what finished, and a lost worker loses no sample.

>>> import numpy as np, lagrangian as lg
>>> from lagrangian.sweep import sweep
>>> m = lg.Model("oscillator")
>>> _ = m.add("mass", "m1", "p", m=0.3)
>>> _ = m.add("spring", "k1", ("ground", "p"), k=40)
>>> ds = sweep(m, {"k_k1": [10.0, 40.0, 90.0]}, initial={"x_p": 0.01}, velocity={"x_p": 0}, t_end=0.5,
...            client="serial")
>>> ds["x_p"].dims, ds.sizes["time"]
(('k_k1', 'time'), 201)
>>> w = np.sqrt(ds.k_k1 / 0.3)                           # x = x₀ cos(ωt), ω = √(k/m)
>>> float(abs(ds.x_p - 0.01 * np.cos(w * ds.time)).max()) < 1e-10
True
"""

from __future__ import annotations

import functools
import importlib.metadata
import math
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    import xarray as xr

from ...errors import ModelError
from ...model import Model
from ...numerics.ensemble import Chunk, run_chunk
from ..frequency import frequency_response
from .dataset import DONE, FAILED, NOT_RUN, dataset, describe, plot
from .designs import Distribution, LogUniform, Normal, Samples, Uniform, design, parse_axis
from .designs import design as make_design
from .execute import SERIAL, check_address, connected, execute, local_client, local_cluster, shutdown, workers
from .plan import plan

__all__ = ["sweep", "response", "Uniform", "LogUniform", "Normal", "Distribution", "design", "parse_axis", "plot", "describe",
           "local_client", "local_cluster", "shutdown",
           "SERIAL", "DONE", "FAILED", "NOT_RUN"]


#: What a task of a simulation sweep holds at most (its runs' states, energies and kept outputs, in bytes): long
#: time series run in tasks a worker's memory holds.
_TASK_BYTES = 32e6


def _blocks(indices: np.ndarray, size: int) -> list[np.ndarray]:
    """``indices`` in blocks of at most ``size``, interleaved: block k of B holds indices k, k + B, k + 2B, ...
    Neighbouring samples of a grid often cost alike (a stiff corner of the plane); spread over every task, the
    costly ones do not leave one worker running alone at the end."""
    count = -(-len(indices) // size)
    return [indices[k::count] for k in range(count)]


def _chunk_size(count: int, tasks: int, chunk: int | None, cap: int) -> int:
    """Samples per task: ``chunk`` when given, else enough for about ``tasks`` tasks, at most ``cap``."""
    if chunk is not None:
        if isinstance(chunk, bool) or not isinstance(chunk, (int, np.integer)) or chunk < 1:
            raise ModelError(f"sweep: chunk= is a positive whole number of samples per task, got {chunk!r}.")
        return int(chunk)
    return max(1, min(cap, math.ceil(count / max(tasks, 1))))


def _tasks(client: Any) -> int:
    """How many tasks a simulation sweep is cut into on ``client``: four per worker (fewer, larger tasks cost the
    cluster less: the double pendulum's 10,000 samples on two workers took 166 µs a sample in tasks of 1,250,
    178 µs in tasks of 500 and 187 µs in tasks of 250; four per worker keep them balanced), or 32 here (each
    block a step of the progress bar)."""
    if client == SERIAL:
        return 32
    try:
        return 4 * max(workers(client), 1)
    except Exception:  # a client without a scheduler answer: as for one worker
        return 4


def _simulate_block(shared, indices: np.ndarray, P: np.ndarray, Y0: np.ndarray) -> tuple[np.ndarray, Chunk]:
    form, spec = shared
    return indices, run_chunk(form, P, Y0, spec)


def _analysis_block(shared, indices: np.ndarray, rows: list[dict[str, float]]) -> tuple[np.ndarray, list]:
    model, fn = shared
    out = []
    for values in rows:
        try:
            result = fn(model, dict(values))
            if not isinstance(result, Mapping):
                raise ModelError(f"the analysis returned {type(result).__name__}; it must return a mapping of output "
                                 f"names to numbers, text, arrays or xarray.DataArray.")
            out.append((DONE, "", dict(result)))
        except Exception as exc:  # recorded, never sinks the sweep
            out.append((FAILED, f"{type(exc).__name__}: {exc}", None))
    return indices, out


def sweep(model: Model, params: Mapping[str, Any], *, design: str | None = None, samples: int | None = None,
          seed: int | None = None, initial: Mapping[str, float] | None = None,
          velocity: Mapping[str, float] | None = None, outputs: Sequence[Any] | None = None, t_end: Any = 10.0,
          points: int = 201, t_eval: Sequence[float] | None = None, method: str = "DOP853",
          rtol: float | None = None, atol: float | None = None, max_step: float | None = None,
          max_evaluations: float | None = None, energy_tol: float = 1e-6,
          analysis: Callable[[Model, dict[str, float]], Mapping[str, Any]] | None = None, client: Any = None,
          address: str | None = None, chunk: int | None = None, progress: Any = None,
          units: Mapping[str, str] | None = None) -> xr.Dataset:
    """Run ``model`` for every sample of ``params``; the results as an :class:`xarray.Dataset`.

    ``params`` maps names to lists of values, distributions
    (:class:`Uniform`, :class:`LogUniform`, :class:`Normal`) or single
    numbers (held fixed).  Names are the model's parameters (as
    ``Model.parameter_values`` names them: ``"k_k1"``), symbolic
    parameters' names, initial values ``"x_p(0)"`` and initial rates
    ``"x_p'(0)"``.  ``design``: ``"grid"`` (every combination; the default
    for lists), ``"zip"`` (lists taken together), ``"random"`` (the default
    with distributions), ``"lhs"`` or ``"sobol"``, with ``samples`` draws and
    a ``seed`` (recorded in the dataset; drawn when not given).

    Simulations take ``initial``, ``velocity``, ``t_end``, ``points`` (201 by
    default: an ensemble keeps every sample's time series), ``t_eval``,
    ``method`` (``"DOP853"`` or ``"dopri5"``), ``rtol`` (1e-9), ``atol``
    (1e-12), ``max_step`` and ``max_evaluations`` (per sample) as
    ``Model.simulate`` does, and keep ``outputs`` (default: every
    coordinate; see :mod:`~lagrangian.sweep.plan` for what may be asked).
    A sample whose values break a parameter's rule, whose run fails, or
    (conservative models) whose energy drifts beyond ``energy_tol`` is
    flagged in ``status`` and ``error`` (drift: in ``energy_drift`` and a
    note), never dropped silently.

    ``analysis=fn`` sweeps ``fn(model, values)`` instead (see the module's
    text); it must be importable or picklable by ``cloudpickle`` (a function
    of a script is).

    ``client`` (a :class:`distributed.Client`, or ``"serial"``) or
    ``address`` (``"tcp://host:8786"``) chooses where it runs; by default a
    local cluster of one process per core.  ``chunk`` is the number of
    samples per task (default: about four tasks per worker, each holding at
    most 32 MB of results; samples are dealt to tasks in turn).
    ``progress``: ``True`` for a progress bar on standard
    error (the default when it is a terminal), ``False`` for none, or a
    callable ``progress(done, total)``.  ``units`` names the units of swept
    names the model does not know (an analysis's own parameters), for the
    dataset's attributes and the charts' labels.
    """
    if not isinstance(model, Model):
        raise ModelError(f"sweep: the first argument is a lagrangian.Model, not {type(model).__name__}.")
    if isinstance(energy_tol, bool) or not isinstance(energy_tol, (int, float)) or not energy_tol > 0:
        raise ModelError(f"sweep: energy_tol is a positive number (a relative drift), got {energy_tol!r:.40}.")
    if address is not None:
        check_address(address)  # before anything is planned or compiled
    samples_ = make_design(params, kind=design, samples=samples, seed=seed)
    count = samples_.count
    if analysis is not None:
        if not callable(analysis):
            raise ModelError(f"sweep: analysis= takes a function fn(model, values), not {type(analysis).__name__}.")
        return _sweep_analysis(model, samples_, analysis, client=client, address=address, chunk=chunk,
                               progress=progress, units=dict(units or {}))
    the_plan = plan(model, samples_, initial=initial, velocity=velocity, outputs=outputs, t_end=t_end, points=points,
                    t_eval=t_eval, method=method, rtol=rtol, atol=atol, max_step=max_step,
                    max_evaluations=max_evaluations)
    run = np.array([k for k in range(count) if k not in the_plan.refused], dtype=np.int64)
    spec = the_plan.spec
    cap = max(1, int(_TASK_BYTES // (8 * spec.t_eval.size * (the_plan.form.dim + 4 + 2 * len(spec.keep)))))
    with connected(client, address) as on:  # (the cluster's size decides the tasks')
        size = _chunk_size(len(run), _tasks(on), chunk, cap)
        blocks = [(idx, the_plan.P[idx], the_plan.Y0[idx]) for idx in _blocks(run, size)]
        outcome = execute(_simulate_block, (the_plan.form, spec), blocks, [len(b[0]) for b in blocks], client=on,
                          progress=progress, label=f"sweep {model.name}")
    N, keep = the_plan.spec.t_eval.size, len(the_plan.spec.keep)
    data = np.full((count, keep, N), np.nan)
    status = np.full(count, NOT_RUN, dtype=np.int8)
    errors = [""] * count
    nfev = np.zeros(count, dtype=np.int64)
    drift = np.full(count, np.nan)
    for k, message in the_plan.refused.items():
        status[k], errors[k] = FAILED, message
    for idx, chunk_ in _finished(blocks, outcome, status, errors):
        data[idx], status[idx], nfev[idx], drift[idx] = chunk_.data, chunk_.status, chunk_.nfev, chunk_.drift
        for k, e in zip(idx, chunk_.errors):
            errors[k] = e
    notes = list(the_plan.notes)
    drifted = int(np.sum(drift > energy_tol))
    if drifted:
        notes.append(f"{drifted} of {count} samples kept their energy (Jacobi integral) only to worse than "
                     f"{energy_tol:g} relative (see energy_drift): tighten rtol for them")
    variables = {name: (("time",), data[:, j], {"units": the_plan.units.get(name, "")})
                 for j, name in enumerate(the_plan.outputs)}
    variables["nfev"] = ((), nfev, {"meaning": "evaluations of the equations by the sample's run"})
    if the_plan.form.conservative:
        variables["energy_drift"] = ((), drift, {"meaning": "largest relative departure of the Jacobi integral"})
    attrs = _attrs(model, samples_, outcome, notes, analysis="simulate", method=the_plan.spec.method,
                   rtol=the_plan.spec.rtol, atol=the_plan.spec.atol, t_end=the_plan.spec.span[1])
    import xarray as xr  # imported when used (0.26 s)

    time = xr.Variable(("time",), the_plan.spec.t_eval, {"units": "s"})
    return dataset(samples_, status, errors, variables, attrs, {**the_plan.parameter_units, **(units or {})},
                   {"time": time})


def response(frequencies: Sequence[float], *, inputs: Sequence[str] | None = None,
             outputs: Sequence[Any] | None = None, **options: Any) -> Callable[[Model, dict[str, float]], dict]:
    """An analysis for :func:`sweep`: the frequency response (:func:`lagrangian.frequency.frequency_response`)
    of each sample on ``frequencies`` (Hz), as ``mag(<output>)`` and ``phase(<output>)`` (degrees) over a
    ``frequency`` dimension; ``options`` go to ``frequency_response`` (``at=``, ...).

    >>> import lagrangian as lg, sympy as sp
    >>> R = sp.Symbol("R", positive=True)
    >>> m = lg.Model("rc")
    >>> _ = m.add("voltage_source", "V1", ("in", "0"), E=0)
    >>> _ = m.add("resistor", "R1", ("in", "out"), R=R)
    >>> _ = m.add("capacitor", "C1", ("out", "0"), C=1e-6)
    >>> ds = sweep(m, {"R": [1e3, 1e4]}, analysis=response([15.915494309189533], outputs=["v(C1)"]), client="serial")
    >>> ds["mag(v(C1))"].values.round(6).tolist()                  # 1/|1 + jωRC| at ω = 100/s
    [[0.995037], [0.707107]]
    """
    f = np.asarray(frequencies, dtype=float)
    if f.ndim != 1 or f.size == 0 or not np.all(np.isfinite(f)) or np.any(f <= 0):
        raise ModelError("response: frequencies are positive finite numbers in Hz, at least one.")
    return functools.partial(_response, f, None if inputs is None else list(inputs),
                             None if outputs is None else list(outputs), dict(options))


def _response(frequencies, inputs, outputs, options, model, values) -> dict:
    import xarray as xr

    resp = frequency_response(model, frequencies, inputs=inputs, outputs=outputs, params=values, **options)
    axis = {"frequency": xr.Variable(("frequency",), frequencies, {"units": "Hz"})}
    out = {}
    for label in resp.outputs:
        h = np.asarray(resp[label])
        unit = resp.unit(label, resp.inputs[0])
        out[f"mag({label})"] = xr.DataArray(np.abs(h), dims=("frequency",), coords=axis,
                                            attrs={"units": unit} if unit else {})
        out[f"phase({label})"] = xr.DataArray(np.degrees(np.angle(h)), dims=("frequency",), coords=axis,
                                              attrs={"units": "deg"})
    return out


def _finished(blocks, outcome, status: np.ndarray, errors: list[str]):
    """``(sample indices, result)`` of every block that came back; the samples of a block whose task failed as a
    whole are marked failed with its message (those of blocks never run stay NOT_RUN)."""
    for i, block in enumerate(blocks):
        idx = block[0]
        if i in outcome.failures:
            status[idx] = FAILED
            for k in idx:
                errors[k] = outcome.failures[i]
        elif i in outcome.results:
            yield idx, outcome.results[i][1]


def _attrs(model: Model, samples: Samples, outcome, notes: list[str], **extra: Any) -> dict[str, Any]:
    return {
        "model": model.name,
        "design": samples.design,
        "samples": samples.count,
        "seed": samples.seed,
        "fixed": ", ".join(f"{k}={v:g}" for k, v in samples.fixed.items()) or None,
        "workers": outcome.workers,
        "wall_seconds": round(outcome.seconds, 6),
        "interrupted": int(outcome.interrupted),
        "notes": "\n".join(notes) or None,
        "lagrangian_version": _version(),
        **extra,
    }


def _version() -> str:
    try:
        return importlib.metadata.version("lagrangian")
    except importlib.metadata.PackageNotFoundError:  # pragma: no cover - run from a source tree
        return "unknown"


def _sweep_analysis(model: Model, samples: Samples, fn, *, client, address, chunk, progress, units) -> xr.Dataset:
    count = samples.count
    rows = [{**{k: float(v[i]) for k, v in samples.table.items()}, **samples.fixed} for i in range(count)]
    _ = model.eq  # derived here, once: the workers receive it with the model
    size = _chunk_size(count, 1, chunk, 1)  # one sample per task unless asked: analyses take long
    indices = np.arange(count)
    blocks = [(idx, [rows[k] for k in idx]) for idx in _blocks(indices, size)]
    outcome = execute(_analysis_block, (model, fn), blocks, [len(b[0]) for b in blocks], client=client,
                      address=address, progress=progress, label=f"sweep {model.name}")
    status = np.full(count, NOT_RUN, dtype=np.int8)
    errors = [""] * count
    results: list[dict | None] = [None] * count
    for idx, out in _finished(blocks, outcome, status, errors):
        for k, (st, err, res) in zip(idx, out):
            status[k], errors[k], results[k] = st, err, res
    variables, coords = _collect(results, status, errors)
    attrs = _attrs(model, samples, outcome, [], analysis=getattr(fn, "__qualname__", repr(fn)))
    return dataset(samples, status, errors, variables, attrs, units, coords)


def _collect(results: list, status: np.ndarray, errors: list[str]):
    """The analysis's outputs as variables: each output's shape (and dims, coords) from its first sample; a
    sample that returns another shape is marked failed."""
    import xarray as xr

    first: dict[str, Any] = {}
    for res in results:
        for key, value in (res or {}).items():
            first.setdefault(key, value)
    variables, coords = {}, {}
    for key, proto in first.items():
        if isinstance(proto, xr.DataArray):
            inner, shape = tuple(proto.dims), proto.shape
            coords.update({c: proto.coords[c] for c in proto.coords if set(proto.coords[c].dims) <= set(inner)})
            attrs = dict(proto.attrs)
        else:
            arr = np.asarray(proto)
            inner, shape, attrs = tuple(f"{key}_dim{i}" for i in range(arr.ndim)), arr.shape, {}
        text = np.asarray(proto).dtype.kind in "OUS"
        dtype = object if text else np.result_type(np.asarray(proto).dtype, float)
        out = np.full((len(results),) + shape, "" if text else np.nan, dtype=dtype)
        for k, res in enumerate(results):
            if res is None or key not in res:
                continue
            value = np.asarray(res[key].values if isinstance(res[key], xr.DataArray) else res[key])
            if value.shape != shape:
                status[k], errors[k] = FAILED, f"output {key!r} has shape {value.shape}, the first sample's {shape}"
                continue
            out[k] = value.astype(object) if text else value
        variables[key] = (inner, out, attrs)
    return variables, coords
