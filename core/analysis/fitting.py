"""Fitting models to measurements: estimates, their uncertainty, and what the data cannot determine.

:func:`fit` adjusts parameters of a model (by their :attr:`~lagrangian.Model.parameter_values` names) so that it
matches one or more experiments:

- :class:`FrequencyData` — a measured complex frequency response of one input to one output (a transfer function
  ``output/input``, or with ``impedance=True`` its inverse ``input/output``: a loudspeaker's electrical impedance
  ``E / i``).  The model's response and its exact derivatives by the parameters come from a linearization in which
  the fitted parameters are symbols, differentiated symbolically once
  (:class:`~lagrangian.analysis.parametric.ParametricResponse`);
- :class:`TimeSeries` — measured outputs over time (coordinates ``"x_p"`` and rates ``"x_p'"``).  The model's run
  and its exact Jacobian come from one :meth:`~lagrangian.Model.simulate` with ``sensitivities=`` (the forward
  sensitivity equations integrated with the states).

Experiments share the fitted parameters; each may bring its own model (the same speaker with an added mass), which
must name them alike.  The least-squares problem is solved by :func:`scipy.optimize.least_squares` with that
Jacobian, in log-parameters where a parameter's bounds are positive (the default for a positive value).  Residuals
are relative: a frequency point's error divided by the measured magnitude (real and imaginary parts), a time
series' error divided by the output's largest measured magnitude, each times the experiment's ``weight``.

The :class:`Fit` holds the estimates, standard errors and confidence intervals from the Jacobian at the optimum
(``cov = s² (JᵀJ)⁻¹``, ``s²`` the residual variance), the correlation matrix, the residuals, and the parameter
combinations the data do not determine: directions of the Jacobian's null space (its singular values below
``1e-7`` of the largest), said in words — "scaling Bl_coil by λ, m_m by λ², ... leaves every prediction unchanged"
— with the monomials that *are* determined.  For frequency data the same question is answered for any data
(``Fit.structural``): exact data at every frequency fix the transfer functions' coefficients and no more, so the
null directions of their Jacobian, from their symbolic expressions, are what no measurement of these experiments
can determine.  Such a direction is left out of the search (the parameters keep
their start along it, where it would otherwise drift without bound), and the standard errors of its parameters
are infinite rather than a number.

>>> import numpy as np, lagrangian as lg
>>> m = lg.Model("rc")
>>> _ = m.add("voltage_source", "V1", ("a", "0"), E=0)
>>> _ = m.add("resistor", "R1", ("a", "b"), R=1e3)
>>> _ = m.add("capacitor", "C1", ("b", "0"), C=1e-6)
>>> f = np.geomspace(10, 1e4, 30)
>>> Z = 2.2e3 + 1 / (2j * np.pi * f * 4.7e-7)  # what a meter would read: 2.2 kΩ in series with 470 nF
>>> result = lg.fit(m, lg.FrequencyData(f, Z, input="V1", output="i(R1)", impedance=True), ["R_R1", "C_C1"])
>>> [float(f"{v:.4g}") for v in result.values.values()]
[2200.0, 4.7e-07]
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from fractions import Fraction
from typing import Any

import numpy as np

from ..base import charts
from ..errors import ModelError, NumericalError, UnknownNameError
from ..model import Model
from .parametric import ParametricResponse
from ..base import deferred as _deferred

sp = _deferred.module("sympy", globals())

__all__ = ["fit", "Fit", "FrequencyData", "TimeSeries"]

#: Singular values of the scaled Jacobian below this share of the largest are directions the data cannot see.
NULL_SHARE = 1e-7
#: The ``ftol`` of the fits over a time series' shorter windows, which only bring the start near the answer; the
#: fit over the whole record keeps the caller's.
WINDOW_FTOL = 1e-6




# -- the data ---------------------------------------------------------------------------------------------------------

def _array(values: Any, what: str, kind: type = float) -> np.ndarray:
    try:
        out = np.asarray(values, dtype=complex if kind is complex else float)
    except (TypeError, ValueError):
        raise ModelError(f"{what} must be an array of numbers, got {type(values).__name__}.") from None
    if out.ndim != 1 or out.size == 0:
        raise ModelError(f"{what} must be a non-empty 1-D array of numbers, got shape {out.shape}.")
    if not np.all(np.isfinite(out)):
        bad = int(np.flatnonzero(~np.isfinite(out))[0])
        raise ModelError(f"{what} holds {out[bad]} at index {bad}: remove the point or give a finite value.")
    return out


@dataclass
class FrequencyData:
    """A measured frequency response: ``values`` (complex) at ``frequencies`` (Hz) of ``output`` to ``input`` (a
    component with a signal: a source or a force); ``impedance=True`` when ``values`` are ``input/output`` (an
    impedance ``E/i``).  ``model``: this experiment's model (default: the one :func:`fit` is given); ``weight``
    multiplies its residuals."""

    frequencies: Any
    values: Any
    input: str
    output: str
    impedance: bool = False
    model: Model | None = None
    weight: float = 1.0
    name: str = "frequency response"

    def __post_init__(self) -> None:
        self.frequencies = _array(self.frequencies, f"{self.name}: frequencies")
        self.values = _array(self.values, f"{self.name}: values", complex)
        if self.frequencies.size != self.values.size:
            raise ModelError(f"{self.name}: {self.frequencies.size} frequencies but {self.values.size} values; give one "
                             f"value per frequency.")
        if np.any(self.frequencies <= 0):
            raise ModelError(f"{self.name}: frequencies must be positive (Hz).")
        if np.any(self.values == 0):
            raise ModelError(f"{self.name}: a measured value is 0, which a relative residual cannot weigh; drop it.")
        _weight(self.weight, self.name)


@dataclass
class TimeSeries:
    """Measured ``outputs`` (name → values: coordinates ``"x_p"``, rates ``"x_p'"``) at times ``t``, of a run from
    ``initial`` and ``velocity`` (as :meth:`~lagrangian.Model.simulate` takes them; fitted too when named in
    :func:`fit`'s ``params`` as ``"x_p"`` or ``"x_p'"``).  ``model``, ``weight`` as for :class:`FrequencyData`."""

    t: Any
    outputs: Mapping[str, Any]
    initial: Mapping[str, float] = field(default_factory=dict)
    velocity: Mapping[str, float] = field(default_factory=dict)
    model: Model | None = None
    weight: float = 1.0
    name: str = "time series"

    def __post_init__(self) -> None:
        self.t = _array(self.t, f"{self.name}: t")
        if np.any(np.diff(self.t) <= 0):
            raise ModelError(f"{self.name}: times must increase strictly.")
        if not isinstance(self.outputs, Mapping) or not self.outputs:
            raise ModelError(f"{self.name}: outputs must be a mapping of output names to measured values.")
        self.outputs = {str(k): _array(v, f"{self.name}: output {k!r}") for k, v in self.outputs.items()}
        for k, v in self.outputs.items():
            if v.size != self.t.size:
                raise ModelError(f"{self.name}: output {k!r} has {v.size} values for {self.t.size} times.")
        _weight(self.weight, self.name)

    @classmethod
    def from_table(cls, table: Any, **kwargs: Any) -> TimeSeries:
        """From a pandas DataFrame (its index the times, its columns the outputs) or an xarray Dataset (its one
        dimension the times, its variables the outputs)."""
        if hasattr(table, "data_vars"):
            dims = list(table.dims)
            if len(dims) != 1:
                raise ModelError(f"a Dataset of measurements has one dimension (time), not {dims}.")
            return cls(table[dims[0]].values, {str(k): table[k].values for k in table.data_vars}, **kwargs)
        if hasattr(table, "columns") and hasattr(table, "index"):
            return cls(np.asarray(table.index, dtype=float), {str(c): table[c].to_numpy() for c in table.columns},
                       **kwargs)
        raise ModelError(f"measurements must be a pandas DataFrame or an xarray Dataset, got {type(table).__name__}.")


def _weight(weight: Any, name: str) -> None:
    if not (isinstance(weight, (int, float)) and not isinstance(weight, bool) and math.isfinite(weight) and weight > 0):
        raise ModelError(f"{name}: weight must be a positive number, got {weight!r:.40}.")


# -- each experiment's predictions and their derivatives ----------------------------------------------------------------

class _Frequency:
    """A :class:`FrequencyData`'s model response ``H(jω; θ)`` and ``∂H/∂θ``
    (:class:`~lagrangian.analysis.parametric.ParametricResponse`), as relative residuals."""

    def __init__(self, data: FrequencyData, model: Model, names: list[str]):
        self.data = data
        self.response = ParametricResponse(model, [data.input], [data.output], names)

    def predict(self, theta: np.ndarray, jacobian: bool) -> tuple[np.ndarray, np.ndarray | None]:
        """The model's values at the data's frequencies and, with ``jacobian``, their derivatives by ``θ``
        (frequencies × parameters)."""
        H, dH = self.response.evaluate(theta, self.data.frequencies, jacobian)
        H, J = H[0, 0], (dH[:, 0, 0].T if dH is not None else None)
        if self.data.impedance:  # the data are input/output = 1/H
            if J is not None:
                J = -J / H[:, None] ** 2
            H = 1 / H
        return H, J

    def residuals(self, theta: np.ndarray, jacobian: bool) -> tuple[np.ndarray, np.ndarray | None]:
        H, J = self.predict(theta, jacobian)
        scale = self.data.weight / np.abs(self.data.values)
        r = (H - self.data.values) * scale
        if J is not None:
            J = J * scale[:, None]
            J = np.concatenate([J.real, J.imag])
        return np.concatenate([r.real, r.imag]), J


class _Time:
    """A :class:`TimeSeries`'s model run and its sensitivities (one :meth:`Model.simulate` per evaluation)."""

    def __init__(self, data: TimeSeries, model: Model, names: list[str], options: Mapping[str, Any]):
        self.data, self.model, self.names, self.options = data, model, names, dict(options)
        coordinates = set(model.coordinate_names)
        for out in data.outputs:
            if out.rstrip("'") not in coordinates or out.count("'") > 1:
                raise UnknownNameError("output", out, [*coordinates, *(f"{c}'" for c in coordinates)])
        self.starts = [n for n in names if n.rstrip("'") in coordinates]
        self.scale = {k: data.weight / max(float(np.max(np.abs(v))), 1e-300) for k, v in data.outputs.items()}

    def residuals(self, theta: np.ndarray, jacobian: bool) -> tuple[np.ndarray, np.ndarray | None]:
        values = dict(zip(self.names, map(float, theta)))
        initial, velocity = dict(self.data.initial), dict(self.data.velocity)
        for n in self.starts:
            (velocity if n.endswith("'") else initial)[n.rstrip("'")] = values.pop(n)
        t = self.data.t
        res = self.model.simulate((float(t[0]), float(t[-1])), t_eval=t, initial=initial, velocity=velocity,
                                  params=values, sensitivities=self.names if jacobian else None, **self.options)
        rows, jac = [], []
        for out, measured in self.data.outputs.items():
            mine = res.velocity(out[:-1]) if out.endswith("'") else res[out]
            rows.append((mine - measured) * self.scale[out])
            if jacobian:
                jac.append(np.column_stack([res.sensitivity(out, n) for n in self.names]) * self.scale[out])
        return np.concatenate(rows), (np.vstack(jac) if jacobian else None)


# -- the result -------------------------------------------------------------------------------------------------------

@dataclass
class Fit:
    """What :func:`fit` found (see the module's text): ``values`` (estimates by name), ``stderr``, ``correlation``
    (a matrix in the order of ``names``), ``residuals`` (the relative residuals at the optimum), ``cost`` (half
    their sum of squares), ``undetermined`` (one sentence per direction the data cannot see), ``determined`` (the
    monomials they do determine, when some are not), ``nfev``, ``njev`` and ``failed_steps`` (trial points where
    the model could not be evaluated, with the reason)."""

    names: list[str]
    values: dict[str, float]
    stderr: dict[str, float]
    correlation: np.ndarray
    residuals: np.ndarray
    cost: float
    undetermined: list[str]
    determined: list[str]
    nfev: int
    njev: int
    failed_steps: list[str]
    experiments: list[Any]
    #: for frequency data, what the model's structure leaves undetermined whatever the data (exact data at every
    #: frequency fix a transfer function's coefficients and no more: the rank of their Jacobian, from their symbolic
    #: expressions); ``None`` when not worked out (time series, or systems beyond ``parametric.COEFFICIENTS_MAX``)
    structural: list[str] | None = None

    def interval(self, sigmas: float = 3.0) -> dict[str, tuple[float, float]]:
        """``value ± sigmas·stderr`` by name (in log-parameters for a positive one: ``value·exp(±sigmas·σ/value)``,
        which keeps the interval positive)."""
        out = {}
        for n in self.names:
            v, e = self.values[n], self.stderr[n]
            if v > 0 and math.isfinite(e):
                spread = min(sigmas * e / v, 700.0)  # (beyond: the interval is every positive value a float holds)
                out[n] = (v * math.exp(-spread), v * math.exp(spread))
            else:
                out[n] = (v - sigmas * e, v + sigmas * e)
        return out

    def to_pandas(self):
        """A DataFrame: one row per parameter, with its value, standard error, relative error and 3σ interval."""
        import pandas as pd

        bounds = self.interval()
        return pd.DataFrame({"value": self.values, "stderr": self.stderr,
                             "relative": {n: self.stderr[n] / abs(self.values[n]) if self.values[n] else math.inf
                                          for n in self.names},
                             "low (3σ)": {n: b[0] for n, b in bounds.items()},
                             "high (3σ)": {n: b[1] for n, b in bounds.items()}})

    def __str__(self) -> str:
        lines = [f"fit of {len(self.names)} parameters: cost {self.cost:.4g}, {self.nfev} evaluations"]
        for n in self.names:
            e = self.stderr[n]
            lines.append(f"  {n:>14} = {self.values[n]:.6g} ± {e:.2g}" if math.isfinite(e) else
                         f"  {n:>14} = {self.values[n]:.6g} (not determined)")
        lines += [f"  {s}" for s in self.undetermined]
        lines += [f"  structurally: {s}" for s in self.structural or () if s.split(":")[0].replace(
            "no data of these experiments can", "the data do not") not in {u.split(":")[0] for u in self.undetermined}]
        if self.determined:
            lines.append(f"  determined: {', '.join(self.determined)}")
        lines += [f"  failed step: {s}" for s in self.failed_steps]
        return "\n".join(lines)

    def _repr_html_(self) -> str:
        from html import escape

        rows = "".join(f"<tr><td>{escape(n)}</td><td>{self.values[n]:.6g}</td><td>{self.stderr[n]:.3g}</td></tr>"
                       for n in self.names)
        notes = "".join(f"<p>{escape(s)}</p>" for s in self.undetermined)
        return (f"<table><tr><th>parameter</th><th>value</th><th>standard error</th></tr>{rows}</table>{notes}"
                f"<p>cost {self.cost:.4g}; {self.nfev} evaluations</p>")

    @charts.plain
    def plot(self, ax=None):
        """Each experiment's data against the fitted model: magnitudes over frequency, or outputs over time."""
        import matplotlib.pyplot as plt

        if ax is None:
            _, ax = plt.subplots(figsize=(7, 4.5), constrained_layout=True)
        theta = np.array([self.values[n] for n in self.names])
        for e in self.experiments:
            if isinstance(e, _Frequency):
                H, _ = e.predict(theta, False)
                ax.loglog(e.data.frequencies, np.abs(e.data.values), ".", label=f"{e.data.name} (data)")
                ax.loglog(e.data.frequencies, np.abs(H), "-", label=f"{e.data.name} (fit)")
                ax.set_xlabel("frequency (Hz)")
            else:
                r, _ = e.residuals(theta, False)
                for k, (out, measured) in enumerate(e.data.outputs.items()):
                    ax.plot(e.data.t, measured, ".", ms=2, label=f"{out} (data)")
                    ax.plot(e.data.t, measured + r[k * e.data.t.size:(k + 1) * e.data.t.size] / e.scale[out], "-",
                            label=f"{out} (fit)")
                ax.set_xlabel("t (s)")
        ax.legend()
        return ax


# -- fitting ----------------------------------------------------------------------------------------------------------

def _window(data: TimeSeries, share: float) -> TimeSeries:
    """``data`` over the first ``share`` of its span (at least 10 points)."""
    keep = max(int(np.searchsorted(data.t, data.t[0] + share * (data.t[-1] - data.t[0]), side="right")), 10)
    return TimeSeries(data.t[:keep], {k: v[:keep] for k, v in data.outputs.items()}, initial=data.initial,
                      velocity=data.velocity, model=data.model, weight=data.weight, name=data.name)


def _null_directions(J: np.ndarray, names: list[str], share: float = NULL_SHARE) -> tuple[list[str], list[str]]:
    """The directions (in log-parameters) the data cannot see, in words, and the monomials the data determine."""
    if J.size == 0:
        return [], []
    norms = np.linalg.norm(J, axis=0)
    norms[norms == 0] = 1.0
    _, s, vt = np.linalg.svd(J / norms, full_matrices=J.shape[0] < J.shape[1])
    s = np.concatenate([s, np.zeros(len(names) - s.size)])
    words, determined = [], []
    for k in np.flatnonzero(s < share * s[0]):
        v = vt[k] / norms
        big = np.abs(v) > 1e-6 * np.max(np.abs(v))
        v = np.where(big, v, 0.0) / v[big][np.argmin(np.abs(v[big]))]  # the smallest power 1
        exps = [Fraction(float(x)).limit_denominator(6) for x in v]
        involved = [(n, e) for n, e in zip(names, exps) if e != 0]
        if len(involved) == 1:
            words.append(f"the data do not determine {involved[0][0]}: it changes no prediction.")
            continue
        scaling = ", ".join(f"{n} by λ{'' if e == 1 else '^' + str(e)}" for n, e in involved)
        words.append(f"the data do not determine {', '.join(n for n, _ in involved)} separately: scaling {scaling} "
                     f"leaves every prediction unchanged.")
        (first, a), rest = involved[0], involved[1:]
        for n, e in rest:  # n · first^(-e/a) is unchanged by the scaling
            power = -e / a
            shown = first if abs(power) == 1 else f"{first}^{abs(power)}"
            determined.append(f"{n}·{shown}" if power > 0 else f"{n}/{shown}")
    return words, determined


def fit(model: Model, data: Any, params: Sequence[str], *, start: Mapping[str, float] | None = None,
        bounds: Mapping[str, tuple[float, float]] | None = None, rtol: float = 1e-10, atol: float = 1e-13,
        max_nfev: int = 200, ftol: float = 1e-12, windows: int = 4, **simulate: Any) -> Fit:
    """Fit ``params`` of ``model`` to ``data`` (see the module's text): a :class:`FrequencyData`, a
    :class:`TimeSeries`, a pandas DataFrame or xarray Dataset of outputs over time, or a list of them (experiments
    sharing the parameters).  ``start``: starting values (default the model's values); ``bounds``: ``(low, high)``
    by name (positive bounds, and by default a positive value's, fit ``log θ``); ``rtol``/``atol``: the runs'
    tolerances; ``max_nfev``, ``ftol``: SciPy's; other keywords go to each run of a time series.  ``windows``: a
    time series is fitted first over the first ``1/2^(windows-1)`` of its span, then over twice as much, and so on
    to the whole, each fit starting where the last ended — an oscillation's phase over a long record makes its
    least-squares surface rugged far from the answer, and a short record's is smooth (frequency data are fitted
    at once).

    Raises :class:`~lagrangian.NumericalError` when the optimizer does not converge (it never returns the start as
    an answer), naming its reason and where it stopped."""
    from scipy.optimize import least_squares

    if not isinstance(model, Model):
        raise ModelError(f"fit takes a lagrangian.Model, got {type(model).__name__}.")
    experiments = list(data) if isinstance(data, (list, tuple)) else [data]
    experiments = [TimeSeries.from_table(e) if hasattr(e, "columns") or hasattr(e, "data_vars") else e
                   for e in experiments]
    if not experiments or not all(isinstance(e, (FrequencyData, TimeSeries)) for e in experiments):
        raise ModelError("data must be FrequencyData, TimeSeries, a DataFrame or Dataset, or a list of them.")
    names = [str(n) for n in params]
    if not names or len(set(names)) != len(names):
        raise ModelError(f"params must name each fitted parameter once, got {list(params)!r:.80}.")
    known = dict(model.parameter_values)
    coordinates = set(model.coordinate_names)
    for n in names:
        if n not in known and n.rstrip("'") not in coordinates:
            raise UnknownNameError("parameter", n, known)
    start = dict(start or {})
    x0 = np.array([float(start.get(n, known.get(n, 0.0))) for n in names])
    given = dict(bounds or {})
    low = np.array([float(given.get(n, (0.0 if known.get(n, 0) > 0 else -np.inf, np.inf))[0]) for n in names])
    high = np.array([float(given.get(n, (0.0, np.inf))[1]) for n in names])
    log = (low >= 0) & (x0 > 0)
    for n, lo, hi, x in zip(names, low, high, x0):
        if not lo < hi or not lo <= x <= hi:
            raise ModelError(f"parameter {n!r}: its start {x:g} must lie within its bounds ({lo:g}, {hi:g}).")
    if not isinstance(windows, int) or isinstance(windows, bool) or not 1 <= windows <= 16:
        raise ModelError(f"windows must be a whole number from 1 to 16, got {windows!r:.40}.")
    if windows > 1 and any(isinstance(e, TimeSeries) and e.t.size >= 40 for e in experiments):
        for k in range(windows - 1, 0, -1):
            part = [_window(e, 2.0**-k) if isinstance(e, TimeSeries) else e for e in experiments]
            try:
                start = fit(model, part, names, start=start, bounds=bounds, rtol=rtol, atol=atol, max_nfev=max_nfev,
                            ftol=max(ftol, WINDOW_FTOL), windows=1, **simulate).values
            except NumericalError:  # (a window it cannot settle: the next, longer one starts from where it was)
                continue
        x0 = np.array([float(start.get(n, known.get(n, 0.0))) for n in names])
    parts = [(_Frequency(e, e.model or model, names) if isinstance(e, FrequencyData) else
              _Time(e, e.model or model, names, dict(rtol=rtol, atol=atol, **simulate))) for e in experiments]
    failed: list[str] = []
    last: dict[str, Any] = {}

    def theta_of(z):
        return np.where(log, np.exp(np.where(log, z, 0.0)), z)

    def evaluate(z, jacobian):
        theta = theta_of(z)
        try:
            pieces = [p.residuals(theta, jacobian) for p in parts]
        except (NumericalError, ModelError) as exc:
            failed.append(f"at {dict(zip(names, map(float, theta)))}: {exc}")
            if not last:
                raise
            return last["r"] * 10.0, last["J"]  # a step the optimizer rejects
        r = np.concatenate([p[0] for p in pieces])
        J = np.vstack([p[1] for p in pieces]) * np.where(log, theta, 1.0) if jacobian else None
        if not np.all(np.isfinite(r)) or (J is not None and not np.all(np.isfinite(J))):
            failed.append(f"at {dict(zip(names, map(float, theta)))}: the model's predictions are not finite")
            return (last["r"] * 10.0, last["J"]) if last else (r, J)
        last.update(r=r, J=J if J is not None else last.get("J"), z=z)
        return r, J

    cache: dict[bytes, tuple] = {}

    def both(z):
        key = z.tobytes()
        if key not in cache:
            cache.clear()
            cache[key] = evaluate(z, True)
        return cache[key]

    z0 = np.where(log, np.log(np.where(log, x0, 1.0)), x0)
    zlow = np.where(log, np.log(np.maximum(low, 1e-300)), low)
    zlow = np.where(log & (low == 0), -np.inf, zlow)
    zhigh = np.where(log, np.log(np.where(np.isfinite(high) & log, high, 1.0)), high)
    zhigh = np.where(log & ~np.isfinite(high), np.inf, zhigh)
    # Directions the data cannot see at the start (a scaling symmetry: they are the same everywhere) are left out
    # of the search, which would otherwise drift along them without bound: z = z0 + basis·w.
    J0 = both(z0)[1]
    norms = np.linalg.norm(J0, axis=0)
    norms[norms == 0] = 1.0
    _, sv, vt = np.linalg.svd(J0 / norms, full_matrices=J0.shape[0] < J0.shape[1])
    sv = np.concatenate([sv, np.zeros(len(names) - sv.size)])
    seen = sv > NULL_SHARE * max(sv[0], 1e-300)
    if not seen.all() and np.isinf(zlow).all() and np.isinf(zhigh).all():
        basis = vt[seen].T / norms[:, None]
        solution = least_squares(lambda w: both(z0 + basis @ w)[0], np.zeros(int(seen.sum())),
                                 jac=lambda w: both(z0 + basis @ w)[1] @ basis, x_scale="jac", ftol=ftol, xtol=1e-12,
                                 gtol=1e-12, max_nfev=max_nfev, method="trf")
        solution.x = z0 + basis @ solution.x
    else:
        solution = least_squares(lambda z: both(z)[0], z0, jac=lambda z: both(z)[1], bounds=(zlow, zhigh),
                                 x_scale="jac", ftol=ftol, xtol=1e-12, gtol=1e-12, max_nfev=max_nfev, method="trf")
    theta = theta_of(solution.x)
    if solution.status <= 0:
        raise NumericalError(f"fit did not converge ({solution.message}); it stopped at "
                             f"{dict(zip(names, map(float, theta)))} after {solution.nfev} evaluations: give a start "
                             f"nearer the data, more max_nfev, or fewer parameters.")
    r, J = both(solution.x)
    Jp = J / np.where(log, theta, 1.0)  # by the parameters themselves
    dof = max(r.size - len(names), 1)
    s2 = float(r @ r) / dof
    undetermined, determined = _null_directions(Jp * np.where(theta != 0, theta, 1.0), names)  # (by log θ)
    norms = np.linalg.norm(Jp, axis=0)
    norms[norms == 0] = 1.0
    u, s, vt = np.linalg.svd(Jp / norms, full_matrices=False)
    keep = s > NULL_SHARE * s[0]
    inverse = (vt[keep].T / s[keep] ** 2) @ vt[keep]
    cov = s2 * inverse / np.outer(norms, norms)
    blind = np.abs(vt[~keep]).max(axis=0) > 1e-6 if (~keep).any() else np.zeros(len(names), bool)
    stderr = np.sqrt(np.maximum(np.diag(cov), 0.0))
    stderr[blind] = np.inf
    with np.errstate(invalid="ignore", divide="ignore"):
        correlation = cov / np.outer(stderr, stderr)
    return Fit(names=names, values=dict(zip(names, map(float, theta))), stderr=dict(zip(names, map(float, stderr))),
               correlation=correlation, residuals=r, cost=0.5 * float(r @ r), undetermined=undetermined,
               determined=determined, nfev=int(solution.nfev), njev=int(solution.njev or 0), failed_steps=failed,
               experiments=parts, structural=_structural(parts, names, theta))


def _structural(parts: list, names: list[str], theta: np.ndarray) -> list[str] | None:
    """The directions no data of these frequency experiments can determine: null directions of the Jacobian of
    their transfer functions' coefficients (``∂ log c / ∂ log θ``), differentiated symbolically."""
    if not parts or not all(isinstance(p, _Frequency) for p in parts):
        return None
    rows = []
    for p in parts:
        found = p.response.coefficients()
        if found is None:
            return None
        coefficients, symbols = found
        values = dict(zip(symbols, map(float, theta)))
        for c in coefficients:  # ∂ log c / ∂ log θ: each coefficient relative to itself, whatever its size
            size = float(c.subs(values))
            if size != 0:
                rows.append([float(sp.diff(c, x).subs(values)) * values[x] / size for x in symbols])
    words, _ = _null_directions(np.array(rows), names, share=1e-9)
    return [w.replace("the data do not", "no data of these experiments can") for w in words]
