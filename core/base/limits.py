"""Bounds on every size that comes from input: one place, named, and raisable.

A netlist, a model file, a unit string or an argument can ask for any amount of work; each size it can set is
checked against a field of :data:`limits` before the work starts, and a request beyond it is refused with a
:class:`~lagrangian.ModelError` that names the size, the bound and how to raise it (:func:`refuse`).  The
defaults let every ordinary model through (a 200-section ladder, 10⁴ coordinates, a decade sweep at 10⁴ points
per decade) and stop what would exhaust a machine's memory or time.

Raise a bound for the whole process, or for a block of code:

>>> import lagrangian as lg
>>> lg.limits.grid_points
10000000
>>> with lg.limits(grid_points=20_000_000):
...     lg.limits.grid_points
20000000
>>> lg.limits.grid_points
10000000

Bounds are process-wide settings (like NumPy's print options): set them before starting threads that read them.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator
from dataclasses import dataclass, fields, replace

from ..errors import ModelError

__all__ = ["Limits", "limits", "refuse"]


@dataclass
class Limits:
    """The bounds (see the module's text).  Each is a positive whole number."""

    #: points of a frequency or parameter grid (``decades``, ``.ac`` lines, ``--points``, scene grids)
    grid_points: int = 10_000_000
    #: bytes of a netlist or model file read from disk or given as text
    file_bytes: int = 64 * 2**20
    #: elements of one netlist (lines that add a component)
    netlist_elements: int = 200_000
    #: the largest exponent a unit string or parameter text may raise to (``9^9^9`` is refused)
    exponent: int = 1024
    #: bytes of compiled libraries kept in the cache directory (``lagrangian cache``): beyond it, the least
    #: recently used are deleted after each build (never one this process uses); they are rebuilt when needed
    cache_bytes: int = 2 * 2**30
    #: frames of one animation (each an image in its player: ``Result.animate(frames=...)``)
    frames: int = 2000

    def __call__(self, **changes: int) -> contextlib.AbstractContextManager[Limits]:
        """A context manager that sets ``changes`` for the block and restores the bounds after it."""
        return _scoped(self, changes)

    def __setattr__(self, name: str, value: int) -> None:
        known = [f.name for f in fields(self)]
        if name not in known:
            raise ModelError(f"lagrangian.limits has no bound {name!r}; the bounds are {', '.join(known)}.")
        if not isinstance(value, int) or isinstance(value, bool) or value < 1:
            raise ModelError(f"lagrangian.limits.{name} must be a positive whole number, got {value!r:.60}.")
        object.__setattr__(self, name, value)


@contextlib.contextmanager
def _scoped(bounds: Limits, changes: dict[str, int]) -> Iterator[Limits]:
    before = replace(bounds)
    try:
        for name, value in changes.items():
            setattr(bounds, name, value)
        yield bounds
    finally:
        for f in fields(bounds):
            object.__setattr__(bounds, f.name, getattr(before, f.name))


#: The bounds in force (``lagrangian.limits``).
limits = Limits()


def refuse(what: str, size: float, bound: str) -> None:
    """Raise :class:`~lagrangian.ModelError` when ``size`` (the request ``what`` makes) exceeds the bound named
    ``bound``; the message says how to raise it.

    >>> refuse("frequency grid", 5, "grid_points")
    >>> refuse("frequency grid", 6e8, "grid_points")
    Traceback (most recent call last):
    ...
    lagrangian.errors.ModelError: frequency grid asks for 6e+08 points, beyond lagrangian.limits.grid_points = 10000000; raise it with lagrangian.limits.grid_points = ... (or `with lagrangian.limits(grid_points=...):`) if this is intended.
    """
    most = getattr(limits, bound)
    if not size <= most:  # also refuses nan
        unit = {"grid_points": "points", "file_bytes": "bytes", "netlist_elements": "elements",
                "exponent": "as exponent", "cache_bytes": "bytes", "frames": "frames"}[bound]
        try:
            shown = f"{size:.6g}"
        except OverflowError:  # an int beyond a float (10**400 points): shown by its number of digits
            shown = f"about 1e{int(abs(size).bit_length() * math.log10(2))}"
        raise ModelError(f"{what} asks for {shown} {unit}, beyond lagrangian.limits.{bound} = {most}; raise it "
                         f"with lagrangian.limits.{bound} = ... (or `with lagrangian.limits({bound}=...):`) if this "
                         f"is intended.")
