"""A sweep's results as an :class:`xarray.Dataset`, and its charts.

Dimensions: the swept parameters for a grid (one axis each), else
``sample``; then ``time`` for simulations, or the dimensions an analysis
returns.  The swept values are coordinates (along ``sample`` when not a
grid).  Every sample has a ``status`` (0: done, 1: failed, 2: not run —
the sweep was interrupted first) and an ``error`` (its message, else
``""``); simulations add ``nfev`` and, for conservative models,
``energy_drift``.  Attributes say what ran (model, analysis, method,
tolerances, design, seed, workers, notes); a failed or unrun sample's
outputs are NaN.  ``ds.to_netcdf("sweep.nc")`` saves it (SciPy's netCDF-3
writer serves when netCDF4 is not installed).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    import xarray as xr

from ...base import charts
from ...errors import ModelError, UnknownNameError
from .designs import Samples

__all__ = ["DONE", "FAILED", "NOT_RUN", "dataset", "describe", "plot"]

DONE, FAILED, NOT_RUN = 0, 1, 2


def _coords(samples: Samples, units: Mapping[str, str]) -> dict[str, Any]:
    import xarray as xr  # imported when used (0.26 s), as pandas is

    coords: dict[str, Any] = {}
    if samples.design == "grid":
        for name, axis in samples.axes.items():
            coords[name] = xr.Variable((name,), axis, {"units": units.get(name, "")} if units.get(name) else {})
    else:
        coords["sample"] = np.arange(samples.count)
        for name, column in samples.table.items():
            coords[name] = xr.Variable(("sample",), column, {"units": units.get(name, "")} if units.get(name) else {})
    return coords


def dataset(samples: Samples, status: np.ndarray, errors: Sequence[str], variables: Mapping[str, tuple],
            attrs: Mapping[str, Any], units: Mapping[str, str] | None = None, extra_coords: Mapping[str, Any] | None = None
            ) -> xr.Dataset:
    """The dataset of a sweep: ``variables`` maps a name to ``(dims after the samples', values shaped
    (count, ...), attrs)``; ``status`` and ``errors`` are per sample (flat)."""
    import xarray as xr

    units = dict(units or {})
    shape, dims = samples.shape, samples.dims
    data = {
        "status": (dims, np.asarray(status, dtype=np.int8).reshape(shape),
                   {"meaning": "0 done, 1 failed (see error), 2 not run (the sweep was interrupted)"}),
        "error": (dims, np.asarray([str(e) for e in errors], dtype=object).reshape(shape)),
    }
    for name, (inner, values, var_attrs) in variables.items():
        values = np.asarray(values)
        data[name] = (dims + tuple(inner), values.reshape(shape + values.shape[1:]), dict(var_attrs))
    coords = _coords(samples, units) | dict(extra_coords or {})
    clean = {k: v for k, v in attrs.items() if v is not None}
    return xr.Dataset(data, coords=coords, attrs=clean)


def describe(ds: xr.Dataset) -> str:
    """A few lines on a sweep: what ran, how fast, what failed, and each output's range.

    The range of a simulated output is over its final values (time series are summarized by their last point).
    """
    status = ds["status"].values
    count = status.size
    done, failed, unrun = int((status == DONE).sum()), int((status == FAILED).sum()), int((status == NOT_RUN).sum())
    seconds = float(ds.attrs.get("wall_seconds", 0.0))
    swept = ", ".join(f"{c} ({ds[c].size if c in ds.dims else 'sample'})" for c in ds.coords
                      if c not in ("time", "sample") and set(ds[c].dims) <= set(ds["status"].dims))
    lines = [f"{ds.attrs.get('model', 'model')}: {ds.attrs.get('analysis', '')} over {count:,} samples "
             f"({ds.attrs.get('design', '')}{', seed ' + str(ds.attrs['seed']) if 'seed' in ds.attrs else ''}) of {swept}",
             f"  {done:,} done, {failed:,} failed, {unrun:,} not run; {ds.attrs.get('workers', 1)} worker(s), "
             f"{seconds:.3g} s ({count / seconds if seconds > 0 else float('nan'):,.0f} samples/s)"]
    for name, var in ds.data_vars.items():
        if name in ("status", "error") or var.dtype == object:
            continue
        values = var.isel(time=-1) if "time" in var.dims else var
        values = values.where(ds["status"] == DONE).values
        if np.isfinite(values).any():
            unit = var.attrs.get("units", "")
            lines.append(f"  {name:16} {np.nanmin(values):12.6g} … {np.nanmax(values):<12.6g} {unit}".rstrip())
    errors = [e for e in np.ravel(ds["error"].values) if e]
    if errors:
        first = max(set(errors), key=errors.count)
        lines.append(f"  most common error ({errors.count(first)} samples): {first}")
    for note in str(ds.attrs.get("notes", "") or "").splitlines():
        lines.append(f"  note: {note}")
    return "\n".join(lines)


def _pick(ds: xr.Dataset, output: str) -> xr.DataArray:
    if output not in ds.data_vars:
        raise UnknownNameError("output of the sweep", output, [v for v in ds.data_vars if v not in ("status", "error")])
    return ds[output]


@charts.plain
def plot(ds: xr.Dataset, output: str, *, x: str | None = None, y: str | None = None, at: Any = "final",
         ax=None, path: str | None = None):
    """Chart ``output`` of a sweep against one swept parameter (a line) or two (a heat map); return the Axes.

    ``at`` reduces the time dimension of a simulation first: ``"final"``
    (default: the value at the last time), ``"max"``, ``"min"``, ``"amplitude"``
    (max − min), ``"rms"``, or a time (the nearest output time).  Outputs that
    are text (a stability verdict) are drawn as a map of categories.  A
    random design draws a scatter coloured by the output.  ``path`` saves a
    PNG.  Failed samples are left blank.
    """
    import matplotlib.colors
    import matplotlib.pyplot as plt

    da = _pick(ds, output)
    if "time" in da.dims:
        da = _reduce(da, at)
    swept = [d for d in ds.status.dims]
    grid = "sample" not in ds.status.dims
    names = [str(n) for n in (swept if grid else [c for c in ds.coords if ds[c].dims == ("sample",) and c != "sample"])]
    x = x or (names[0] if names else None)
    if x not in names:
        raise UnknownNameError("swept parameter", x, names)
    if y is not None and y not in names:
        raise UnknownNameError("swept parameter", y, names)
    if y is None and len(names) > 1 and grid:
        y = next(n for n in names if n != x)
    if ax is None:
        _, ax = plt.subplots(figsize=(7, 4.8), constrained_layout=True)
    label = output + (f" ({at})" if "time" in ds[output].dims else "")
    unit = ds[output].attrs.get("units", "")
    text = da.dtype == object
    if text:
        categories = sorted({str(v) for v in np.ravel(da.values) if str(v)})
        codes = np.vectorize(lambda v: categories.index(str(v)) if str(v) in categories else np.nan, otypes=[float])(da.values)
        da = da.copy(data=codes)
    else:
        da = da.where(ds.status == DONE)
    xs = ds[x].values
    log = {n: bool(np.all(ds[n].values > 0) and ds[n].values.max() / ds[n].values.min() > 50) for n in filter(None, (x, y))}
    if y is None:
        if grid:
            other = [d for d in da.dims if d != x]
            series = da.transpose(x, *other).values.reshape(len(xs), -1)
            ax.plot(xs, series, marker="." if len(xs) < 40 else None)
        else:
            ax.scatter(xs, da.values, s=8)
        ax.set_ylabel(f"{label} [{unit}]" if unit else label)
    else:
        ys = ds[y].values
        cmap, norm = plt.get_cmap("viridis"), None
        if text:  # one colour per category
            cmap = matplotlib.colors.ListedColormap(plt.get_cmap("tab10").colors[: max(len(categories), 1)])
            norm = matplotlib.colors.BoundaryNorm(np.arange(len(categories) + 1) - 0.5, cmap.N)
        if grid:
            z = da.transpose(y, x).values
            mesh = ax.pcolormesh(_edges(xs, log.get(x)), _edges(ys, log.get(y)), z, cmap=cmap, norm=norm)
        else:
            mesh = ax.scatter(xs, ys, c=da.values, s=10, cmap=cmap, norm=norm)
        bar = plt.colorbar(mesh, ax=ax, ticks=range(len(categories)) if text else None)
        if text:
            bar.set_ticklabels(categories)
        bar.set_label(f"{label} [{unit}]" if unit else label)
        ax.set_ylabel(_axis_label(ds, y))
        if log.get(y):
            ax.set_yscale("log")
    ax.set_xlabel(_axis_label(ds, x))
    if log.get(x):
        ax.set_xscale("log")
    failed = int((ds.status != DONE).sum())
    title = f"{ds.attrs.get('model', '')}: {label}"
    ax.set_title(title + (f" ({failed} of {ds.status.size} samples failed or not run)" if failed else ""), fontsize=10)
    ax.grid(True, alpha=0.3)
    if path:
        ax.figure.savefig(path, dpi=120)
    return ax


def _edges(values: np.ndarray, log: bool | None) -> np.ndarray:
    """Cell edges around sorted grid values: midway between neighbours (geometrically on a log axis)."""
    v = np.log(values) if log else np.asarray(values, dtype=float)
    if v.size == 1:
        mids = np.array([v[0] - 0.5, v[0] + 0.5])
    else:
        inner = (v[1:] + v[:-1]) / 2
        mids = np.concatenate([[2 * v[0] - inner[0]], inner, [2 * v[-1] - inner[-1]]])
    return np.exp(mids) if log else mids


def _axis_label(ds: xr.Dataset, name: str) -> str:
    unit = ds[name].attrs.get("units", "")
    return f"{name} [{unit}]" if unit else name


def _reduce(da: xr.DataArray, at: Any) -> xr.DataArray:
    reductions = {"final": lambda a: a.isel(time=-1), "max": lambda a: a.max("time"), "min": lambda a: a.min("time"),
                  "amplitude": lambda a: a.max("time") - a.min("time"),
                  "rms": lambda a: np.sqrt((a ** 2).mean("time"))}
    if isinstance(at, str):
        if at not in reductions:
            raise ModelError(f"plot: at= is one of {', '.join(map(repr, reductions))} or a time, not {at!r}.")
        return reductions[at](da)
    try:
        return da.sel(time=float(at), method="nearest")
    except (TypeError, ValueError):
        raise ModelError(f"plot: at= is one of {', '.join(map(repr, reductions))} or a time, not {at!r:.40}.") from None
