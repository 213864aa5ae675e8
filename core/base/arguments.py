"""Checks of the arguments users pass to runs: one place, one kind of error, the argument named with its fix.

``Model.simulate`` and the exact solution (:mod:`lagrangian.linear`) take the
same arguments; these functions check them before any work is done, so a
wrong type or value is a :class:`~lagrangian.errors.ModelError` naming the
argument — never a NumPy, SciPy or SymPy error from deep inside a run.

>>> check_span("10")
Traceback (most recent call last):
...
lagrangian.errors.ModelError: t_end must be a number of seconds or a pair (t0, t1), got '10' of type str: write t_end=10.
>>> check_grid((0.0, 1.0), 3, None)
array([0. , 0.5, 1. ])
"""

from __future__ import annotations

import functools
import math
import numbers
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import ModelError
from .units import coordinate_unit, is_quantity, split, to_si

#: a run's outputs may take at most this share of the machine's memory
MEMORY_SHARE = 0.5
#: initial values beyond this are refused (squares of states must stay far from overflow)
STATE_LARGEST = 1e100
#: a run that would take more steps than this is refused before it starts (it would not end)
MAX_STEPS = 100_000_000


def _number(value: Any) -> bool:
    """A real number given as one (not a string, not a bool)."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def _kind(value: Any) -> str:
    return type(value).__name__


def check_span(t_end: Any) -> tuple[float, float]:
    """``t_end`` (a number) or ``(t0, t1)`` as a pair of finite floats with ``t1 > t0``."""
    if _number(t_end):
        pair: Sequence[Any] = (0.0, t_end)
    elif isinstance(t_end, (tuple, list, np.ndarray)) and len(t_end) == 2 and all(_number(x) for x in t_end):
        pair = t_end
    else:
        fix = f"write t_end={t_end.strip()}" if isinstance(t_end, str) and _parses(t_end) else "give seconds as a number"
        raise ModelError(f"t_end must be a number of seconds or a pair (t0, t1), got {t_end!r} of type {_kind(t_end)}: {fix}.")
    out = (float(pair[0]), float(pair[1]))
    if not all(math.isfinite(x) for x in out) or not out[1] > out[0]:
        raise ModelError(f"the time span must end after it starts, with finite times; got {out}.")
    return out


def _parses(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def check_grid(bounds: tuple[float, float], points: Any, t_eval: Any, states: int = 1) -> np.ndarray:
    """The output times: ``points`` evenly spaced over ``bounds``, or ``t_eval`` (sorted, finite, within ``bounds``).

    ``states`` values are kept per time; a grid whose outputs would not fit in
    :data:`MEMORY_SHARE` of the machine's memory is refused.
    """
    if t_eval is None:
        if not isinstance(points, numbers.Integral) or isinstance(points, bool) or points < 1:
            raise ModelError(f"points must be a positive whole number of output times, got {points!r}: e.g. points=1001.")
        _fits(int(points), states, "points")
        if points <= _EVEN_KEPT:
            return _even(float(bounds[0]), float(bounds[1]), int(points)).copy()
        return np.linspace(*bounds, int(points))
    if isinstance(t_eval, (str, bytes, Mapping)) or callable(t_eval):
        raise ModelError(f"t_eval must be a sequence of times, got one of type {_kind(t_eval)}.")
    try:
        times = np.asarray(t_eval, dtype=float)
    except (TypeError, ValueError):
        raise ModelError("t_eval must be a sequence of times (numbers).") from None
    if times.ndim != 1 or times.size == 0:
        raise ModelError(f"t_eval must be a non-empty one-dimensional sequence of times, got shape {times.shape}.")
    _fits(times.size, states, "t_eval")
    if not np.all(np.isfinite(times)):
        raise ModelError("t_eval must hold finite times (it holds nan or inf).")
    if np.any(np.diff(times) < 0):
        at = int(np.argmax(np.diff(times) < 0))
        raise ModelError(f"t_eval must be sorted in increasing order ({times[at]:g} comes before {times[at + 1]:g}): "
                         f"pass np.sort(t_eval).")
    width = bounds[1] - bounds[0]
    slack = 1e-12 * max(width, abs(bounds[0]), abs(bounds[1]))
    if times[0] < bounds[0] - slack or times[-1] > bounds[1] + slack:
        raise ModelError(f"t_eval must lie within the time span [{bounds[0]:g}, {bounds[1]:g}], "
                         f"got [{times[0]:g}, {times[-1]:g}]: widen t_end or trim t_eval.")
    return np.clip(times, *bounds)


#: Evenly spaced grids of at most this many times are kept (:func:`_even`) for runs repeated over one span.
_EVEN_KEPT = 10_000


@functools.lru_cache(maxsize=8)
def _even(t0: float, t1: float, points: int) -> np.ndarray:
    """``np.linspace(t0, t1, points)``, kept read-only for the next run over the same span (callers copy it)."""
    grid = np.linspace(t0, t1, points)
    grid.setflags(write=False)
    return grid


@functools.lru_cache(maxsize=1)
def _memory() -> float:
    """Bytes of physical memory (inf where the platform does not say; read once)."""
    try:
        return float(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):  # pragma: no cover - not POSIX
        return math.inf


def _fits(times: int, states: int, what: str) -> None:
    """Refuse output that would take more than :data:`MEMORY_SHARE` of memory (a result holds about three copies
    of ``(2 states + 4)`` values per time: the solver's, the result's and the energies')."""
    need = 3.0 * 8.0 * times * (2 * max(states, 1) + 4)
    have = MEMORY_SHARE * _memory()
    if need > have:
        raise ModelError(
            f"{what} asks for {times:,} output times of {states} state value(s): about {need / 2**30:.1f} GiB, more than "
            f"{MEMORY_SHARE:.0%} of this machine's memory ({have / MEMORY_SHARE / 2**30:.1f} GiB): ask for fewer times "
            f"(the run's accuracy does not depend on them), or run the span in pieces."
        )


def check_positive(name: str, value: Any, *, infinite: bool = False) -> float | None:
    """``value`` as a float > 0 (``None`` stays ``None``); ``infinite`` allows ``inf``."""
    if value is None:
        return None
    if not _number(value):
        raise ModelError(f"{name} must be a positive number, got {value!r} of type {_kind(value)}.")
    try:
        out = float(value)
    except OverflowError:
        out = math.inf
    if not out > 0 or math.isnan(out) or (math.isinf(out) and not infinite):
        raise ModelError(f"{name} must be a positive number{'' if infinite else ' (finite)'}, got {value!r}.")
    return out


def check_atol(value: Any, states: int) -> Any:
    """``atol``: a positive number, or one per state value (``states`` of them)."""
    if value is None or _number(value):
        return check_positive("atol", value)
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ModelError(f"atol must be a positive number or one per state value, got {value!r}.") from None
    if arr.shape != (states,):
        raise ModelError(f"atol given per state must have {states} entries (coordinates, then the velocities of "
                         f"those with inertia), got shape {arr.shape}.")
    if not np.all(np.isfinite(arr) & (arr > 0)):
        raise ModelError("atol given per state must be positive and finite in every entry.")
    return arr


def check_energy_tol(value: Any) -> float | bool | None:
    """``energy_tol``: ``None`` (the default), ``False`` (no check), ``True``, or a relative drift ≥ 0."""
    if value is None or isinstance(value, bool):
        return value
    if not _number(value) or not float(value) >= 0 or math.isinf(float(value)):
        raise ModelError(f"energy_tol must be a relative drift ≥ 0 (e.g. 1e-6), False to skip the check, or None; "
                         f"got {value!r}.")
    return float(value)


def check_mapping(name: str, value: Any, names: Sequence[str]) -> dict[str, Any]:
    """``initial`` / ``velocity`` / ``params``: a mapping by name (``None`` is empty)."""
    if value is None:
        return {}
    if isinstance(value, Mapping):
        return dict(value)
    example = f"{name}={{{names[0]!r}: 0.1}}" if names else f"{name}={{}}"
    hint = f", e.g. dict(zip({list(names)!r}, values))" if isinstance(value, (np.ndarray, list, tuple)) and names else ""
    raise ModelError(f"{name} must map names to numbers ({example}), got one of type {_kind(value)}{hint}. "
                     f"Names: {', '.join(names) or '(none)'}.")


def check_state(name: str, given: Mapping[str, Any]) -> Mapping[str, Any]:
    """Initial values (``initial`` / ``velocity``): numbers within ±:data:`STATE_LARGEST`; values with units
    (``"1 cm"``, a pint quantity) in SI, as the coordinate's name implies (``x_`` metres, ``theta_`` radians).

    Energies square the state and methods' error norms square it again: from 1e149 on, LSODA never returns on
    an oscillator (measured: 1e140 takes 0.06 s).  Text, lists and the like are refused here too.
    """
    what = "initial value" if name == "initial" else "initial velocity"
    converted = {}
    for key, value in given.items():
        if is_quantity(value) or split(value) is not None:  # "1 cm", 5 * ureg.deg: in SI, as the coordinate's
            unit = coordinate_unit(key)
            value = to_si(value, unit + ("/s" if unit and name != "initial" else ""), f"{what} of {key!r}")
        converted[key] = value
        if not _number(value):
            raise ModelError(f"{what} of {key!r} must be a number, got {value!r:.60} of type {_kind(value)}.")
        try:
            x = float(value)
        except OverflowError:
            x = math.inf
        if not math.isfinite(x) or abs(x) > STATE_LARGEST:
            raise ModelError(f"{what} of {key!r} must be finite and within ±{STATE_LARGEST:g}, got {value!r:.30}: give "
                             f"the state in units that keep it finite.")
    return converted


def check_max_step(max_step: float | None, bounds: tuple[float, float]) -> float | None:
    """``max_step``: positive, and not so small that the run would take more than :data:`MAX_STEPS` steps."""
    max_step = check_positive("max_step", max_step, infinite=True)
    if max_step is not None and (bounds[1] - bounds[0]) / max_step > MAX_STEPS:
        raise ModelError(f"max_step={max_step:g} over a span of {bounds[1] - bounds[0]:g} caps the run at more than "
                         f"{MAX_STEPS:,} steps, which would not end: give a larger max_step, or none.")
    return max_step


@dataclass(frozen=True)
class RunOptions:
    """What one run is asked, checked once by the functions of this module and passed down whole.

    ``span`` is ``(t0, t1)``; ``initial``, ``velocity`` and ``params`` map names to values; the output grid is
    ``t_eval`` when given, else ``points`` evenly spaced times; ``method`` names an integrator (or is one),
    ``"auto"`` or ``"exact"``; ``rtol``, ``atol``, ``max_step`` (adaptive) and ``step`` (fixed-step) are ``None``
    when not given; ``options`` are the method's own keyword options; ``notes`` go to ``Result.notes`` first.
    """

    span: tuple[float, float]
    initial: Mapping[str, Any]
    velocity: Mapping[str, Any]
    params: Mapping[str, Any]
    points: int = 1001
    t_eval: Any = None
    method: Any = "DOP853"
    rtol: float | None = None
    atol: Any = None
    max_step: float | None = None
    step: float | None = None
    energy_tol: float | bool | None = None
    progress: bool | Callable[[float, float], None] = False
    compiled: bool | str = "auto"
    events: tuple = ()
    options: Mapping[str, Any] = field(default_factory=dict)
    max_evaluations: float | None = None
    notes: tuple[str, ...] = ()


def check_progress(value: Any) -> bool | Callable[[float, float], None]:
    """``progress``: a bool or a callable ``progress(t, t_end)``."""
    if isinstance(value, bool) or callable(value):
        return value
    raise ModelError(f"progress must be True, False or a callable progress(t, t_end), got {value!r}.")
