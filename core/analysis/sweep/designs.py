"""What a sweep runs: full grids, zipped lists, or random samples of distributions with a seed.

A parameter is swept over a list of values (a grid's axis, or one column of
zipped lists) or drawn from a distribution (:class:`Uniform`,
:class:`LogUniform`, :class:`Normal`); a single number holds it fixed.
Random designs draw independent samples (``"random"``), a Latin hypercube
(``"lhs"``) or a scrambled Sobol' sequence (``"sobol"``) through
:mod:`scipy.stats.qmc`, mapped through each distribution's quantile function:
the same seed gives the same samples on every machine.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

from ...errors import ModelError

__all__ = ["Distribution", "Uniform", "LogUniform", "Normal", "Samples", "design", "parse_axis"]

DESIGNS = ("grid", "zip", "random", "lhs", "sobol")


class Distribution:
    """A distribution to draw a parameter from: :meth:`ppf` maps uniform numbers in (0, 1) to its values."""

    def ppf(self, u: np.ndarray) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError

    @staticmethod
    def _finite(**given: Any) -> dict[str, float]:
        out = {}
        for name, value in given.items():
            try:
                out[name] = float(value)
            except (TypeError, ValueError):
                raise ModelError(f"{name} must be a number, got {value!r:.60}.") from None
            if not math.isfinite(out[name]):
                raise ModelError(f"{name} must be finite, got {value!r}.")
        return out


@dataclass(frozen=True)
class Uniform(Distribution):
    """Uniform on ``[low, high]``.

    >>> Uniform(1, 3).ppf(np.array([0.0, 0.5, 1.0])).tolist()
    [1.0, 2.0, 3.0]
    """

    low: float
    high: float

    def __post_init__(self):
        v = self._finite(low=self.low, high=self.high)
        if not v["low"] < v["high"]:
            raise ModelError(f"Uniform(low, high) needs low < high, got {self.low!r}, {self.high!r}.")

    def ppf(self, u):
        return self.low + (self.high - self.low) * np.asarray(u, dtype=float)


@dataclass(frozen=True)
class LogUniform(Distribution):
    """Uniform in ``log`` between ``low > 0`` and ``high``: as many values in each decade (a parameter known to
    within orders of magnitude).

    >>> LogUniform(1e-3, 1e1).ppf(np.array([0.0, 0.25, 1.0])).round(12).tolist()
    [0.001, 0.01, 10.0]
    """

    low: float
    high: float

    def __post_init__(self):
        v = self._finite(low=self.low, high=self.high)
        if not 0 < v["low"] < v["high"]:
            raise ModelError(f"LogUniform(low, high) needs 0 < low < high, got {self.low!r}, {self.high!r}.")

    def ppf(self, u):
        lo, hi = math.log(self.low), math.log(self.high)
        return np.exp(lo + (hi - lo) * np.asarray(u, dtype=float))


@dataclass(frozen=True)
class Normal(Distribution):
    """Normal with ``mean`` and standard deviation ``std`` (a manufacturing tolerance: ``Normal(4.7e3, 0.05 *
    4.7e3 / 3)`` for a 5 % resistor at three sigma).

    >>> round(float(Normal(10, 2).ppf(np.array([0.5]))[0]), 12)
    10.0
    """

    mean: float
    std: float

    def __post_init__(self):
        v = self._finite(mean=self.mean, std=self.std)
        if not v["std"] > 0:
            raise ModelError(f"Normal(mean, std) needs std > 0, got {self.std!r}.")

    def ppf(self, u):
        import scipy.special

        return self.mean + self.std * scipy.special.ndtri(np.asarray(u, dtype=float))


@dataclass
class Samples:
    """The samples of a sweep: ``table`` maps each swept name to its value in every sample (flat, in C order of
    ``shape``); ``dims`` names the dataset's dimensions over samples (the swept names for a grid, ``("sample",)``
    otherwise), ``shape`` their lengths, ``axes`` each grid axis's values; ``fixed`` the names held at one value."""

    table: dict[str, np.ndarray]
    dims: tuple[str, ...]
    shape: tuple[int, ...]
    design: str
    axes: dict[str, np.ndarray] = field(default_factory=dict)
    fixed: dict[str, float] = field(default_factory=dict)
    seed: int | None = None

    @property
    def count(self) -> int:
        return int(np.prod(self.shape, dtype=np.int64))


def _values(name: str, given: Any) -> np.ndarray:
    try:
        values = np.asarray(given, dtype=float)
    except (TypeError, ValueError):
        raise ModelError(f"sweep: the values of {name!r} must be numbers or a distribution (lg.sweep.Uniform, "
                         f"LogUniform, Normal), got {given!r:.80}.") from None
    if values.ndim != 1 or values.size == 0:
        raise ModelError(f"sweep: the values of {name!r} must be one number or a non-empty list of them, got an array "
                         f"of shape {values.shape}.")
    if not np.all(np.isfinite(values)):
        raise ModelError(f"sweep: the values of {name!r} must be finite numbers (entry {int(np.argmin(np.isfinite(values)))} "
                         f"is {values[~np.isfinite(values)][0]}).")
    return values


def design(params: Mapping[str, Any], *, kind: str | None = None, samples: int | None = None,
           seed: int | None = None, limit: int = 10**7) -> Samples:
    """The samples of ``params`` (name → list of values, distribution or one number).

    ``kind``: ``"grid"`` (every combination; the default for lists),
    ``"zip"`` (lists of equal length, taken together), ``"random"``,
    ``"lhs"`` or ``"sobol"`` (``samples`` draws of the distributions; the
    default ``"random"`` when any parameter is a distribution).  ``seed``
    makes draws repeatable; without one a seed is drawn and recorded.

    >>> s = design({"k": [1, 2, 3], "c": [0.1, 0.2]})
    >>> s.dims, s.shape, s.table["c"].tolist()
    (('k', 'c'), (3, 2), [0.1, 0.2, 0.1, 0.2, 0.1, 0.2])
    >>> s = design({"k": LogUniform(1, 100), "m": 0.3}, samples=4, seed=1)
    >>> s.dims, s.fixed, s.table["k"].shape
    (('sample',), {'m': 0.3}, (4,))
    """
    if not isinstance(params, Mapping) or not params:
        raise ModelError("sweep: params= must be a mapping of parameter names to values, lists or distributions, "
                         "e.g. params={'k_k1': np.linspace(1, 10, 50)}.")
    fixed: dict[str, float] = {}
    lists: dict[str, np.ndarray] = {}
    drawn: dict[str, Distribution] = {}
    for name, given in params.items():
        if not isinstance(name, str):
            raise ModelError(f"sweep: parameter names must be text, got {name!r:.60}.")
        if isinstance(given, Distribution):
            drawn[name] = given
        elif np.ndim(given) == 0 and not isinstance(given, (str, bytes)):
            fixed[name] = float(_values(name, [given])[0])
        else:
            lists[name] = _values(name, given)
    if kind is None:
        kind = "random" if drawn else "grid"
    if kind not in DESIGNS:
        raise ModelError(f"sweep: design must be one of {', '.join(map(repr, DESIGNS))}, not {kind!r}.")
    if kind in ("grid", "zip"):
        if drawn:
            raise ModelError(f"sweep: {', '.join(map(repr, drawn))} {'is a distribution' if len(drawn) == 1 else 'are distributions'}, "
                             f"which a {kind} design does not draw from: give lists of values, or design='random' "
                             f"(or 'lhs', 'sobol') with samples=.")
        if samples is not None:
            raise ModelError(f"sweep: samples= is the number of random draws; a {kind} design runs each of its "
                             f"{'combinations' if kind == 'grid' else 'rows'} once (leave samples= out).")
        if not lists:
            lists = {name: np.array([value]) for name, value in fixed.items()}
            fixed = {}
        if kind == "grid":
            shape = tuple(v.size for v in lists.values())
            count = int(np.prod(shape, dtype=np.int64))
            if count > limit:
                raise ModelError(f"sweep: the grid has {count:,} combinations ({' × '.join(map(str, shape))}), more "
                                 f"than the limit of {limit:,}: use fewer values, or a random design with samples=.")
            mesh = np.meshgrid(*lists.values(), indexing="ij")
            table = {name: m.ravel() for name, m in zip(lists, mesh)}
            return Samples(table, tuple(lists), shape, kind, axes=dict(lists), fixed=fixed)
        sizes = {name: v.size for name, v in lists.items()}
        if len(set(sizes.values())) > 1:
            raise ModelError(f"sweep: a zip design takes lists of one length; got {', '.join(f'{k}: {n}' for k, n in sizes.items())}.")
        return Samples(dict(lists), ("sample",), (next(iter(sizes.values())),), kind, fixed=fixed)
    if lists:
        raise ModelError(f"sweep: a {kind} design draws every swept parameter from a distribution; "
                         f"{', '.join(map(repr, lists))} {'is a list' if len(lists) == 1 else 'are lists'} (give "
                         f"lg.sweep.Uniform(low, high) or another distribution, or one number to hold it fixed).")
    if not drawn:
        raise ModelError(f"sweep: a {kind} design needs at least one parameter given as a distribution.")
    if samples is None or isinstance(samples, bool) or not isinstance(samples, (int, np.integer)) or samples < 1:
        raise ModelError(f"sweep: a {kind} design needs samples= (a positive whole number of draws), got {samples!r}.")
    if samples > limit:
        raise ModelError(f"sweep: {samples:,} samples are more than the limit of {limit:,}.")
    if seed is None:
        seed = int(np.random.SeedSequence().entropy % (2**63))
    rng = np.random.default_rng(seed)
    d = len(drawn)
    if kind == "random":
        u = rng.random((int(samples), d))
    elif kind == "lhs":
        import scipy.stats.qmc as qmc  # imported when used: scipy.stats takes 0.2 s

        u = qmc.LatinHypercube(d=d, seed=rng).random(int(samples))
    else:
        import scipy.stats.qmc as qmc

        with warnings.catch_warnings():  # Sobol' points are balanced at powers of 2; other counts are still fine
            warnings.simplefilter("ignore", UserWarning)
            u = qmc.Sobol(d=d, scramble=True, seed=rng).random(int(samples))
    u = np.clip(u, np.finfo(float).tiny, 1 - np.finfo(float).epsneg)  # inside (0, 1): finite quantiles
    table = {name: np.asarray(dist.ppf(u[:, j]), dtype=float) for j, (name, dist) in enumerate(drawn.items())}
    return Samples(table, ("sample",), (int(samples),), kind, fixed=fixed, seed=int(seed))


def _number(text: str, what: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise ModelError(f"{what}: {text!r} is not a number.") from None
    if not math.isfinite(value):
        raise ModelError(f"{what}: {text!r} is not a finite number.")
    return value


def _count(text: str, what: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise ModelError(f"{what}: {text!r} is not a whole number of values.") from None
    if not 1 <= value <= 10**7:
        raise ModelError(f"{what}: the number of values must be between 1 and 10,000,000, got {value}.")
    return value


def parse_axis(text: str, what: str = "sweep") -> Any:
    """The values or distribution written in ``text`` (the command line's ``--param name=TEXT``), read as numbers
    only, never evaluated: ``"1:10:50"`` (50 values from 1 to 10), ``"log:1e-3:1:20"`` (20 values evenly
    spaced in log), ``"0.1,0.2,0.5"`` (a list), ``"0.3"`` (one value), ``"uniform:1:3"``,
    ``"loguniform:1e-3:1"``, ``"normal:4.7e3:80"`` (distributions).

    >>> parse_axis("1:2:3").tolist(), parse_axis("log:1:100:3").tolist(), parse_axis("0.3")
    ([1.0, 1.5, 2.0], [1.0, 10.0, 100.0], 0.3)
    >>> parse_axis("loguniform:1e-3:1")
    LogUniform(low=0.001, high=1.0)
    """
    if not isinstance(text, str) or not text.strip():
        raise ModelError(f"{what}: expected values such as 1:10:50, log:1e-3:1:20, 0.1,0.2 or uniform:1:3, got "
                         f"{text!r:.60}.")
    parts = [p.strip() for p in text.strip().split(":")]
    head = parts[0].lower()
    distributions = {"uniform": Uniform, "loguniform": LogUniform, "normal": Normal}
    if head in distributions:
        if len(parts) != 3:
            raise ModelError(f"{what}: {head} takes two numbers, as in {head}:1:3, got {text!r:.60}.")
        return distributions[head](_number(parts[1], what), _number(parts[2], what))
    if head in ("log", "lin"):
        if len(parts) != 4:
            raise ModelError(f"{what}: {head}:START:STOP:COUNT, as in {head}:1e-3:1:20, got {text!r:.60}.")
        lo, hi, n = _number(parts[1], what), _number(parts[2], what), _count(parts[3], what)
        if head == "log":
            if not (lo > 0 and hi > 0):
                raise ModelError(f"{what}: log spacing needs positive ends, got {parts[1]} and {parts[2]}.")
            return np.geomspace(lo, hi, n)
        return np.linspace(lo, hi, n)
    if len(parts) == 3:
        return np.linspace(_number(parts[0], what), _number(parts[1], what), _count(parts[2], what))
    if len(parts) != 1:
        raise ModelError(f"{what}: expected START:STOP:COUNT, log:START:STOP:COUNT, a list or a distribution, got "
                         f"{text!r:.60}.")
    values = [_number(v.strip(), what) for v in parts[0].split(",")]
    return values[0] if len(values) == 1 else np.array(values)
