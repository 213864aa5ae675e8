"""The command line's arguments: numbers, name=value pairs and method names checked as argparse reads them, and
output paths checked before anything runs (:mod:`lagrangian.cli`)."""

from __future__ import annotations

import argparse
import math
import os
import warnings
from pathlib import Path

import lazy_loader

from .base.limits import refuse
from .errors import ModelError, UnknownNameError

with warnings.catch_warnings():
    warnings.simplefilter("ignore", RuntimeWarning)  # (lazy_loader warns that the parent package loads at once)
    _registry = lazy_loader.load("lagrangian.plugin.registry")

__all__ = ["methods", "number", "numbers", "out_problem", "output_problem", "pairs", "positive", "tolerance", "whole",
           "write_failure"]


def whole(minimum: int, what: str, bound: str | None = None):
    """A whole number of at least ``minimum``, written ``1000`` or ``1e3``; with ``bound`` (a field of
    :data:`lagrangian.limits`), at most that bound."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            found = number(text, -math.inf)  # 1e3; 2.5, nan, inf and 1e400 are no whole numbers
            value = int(found) if found is not None and found == int(found) else None
        if value is None or value < minimum:
            raise argparse.ArgumentTypeError(f"expected a whole number of at least {minimum} ({what}), got {text!r}")
        if bound is not None:
            try:
                refuse(f"{text.strip()} ({what})", value, bound)
            except ModelError as exc:
                raise argparse.ArgumentTypeError(str(exc)) from None
        return value

    return parse


def number(text: str, lo: float = 0.0, hi: float = math.inf) -> float | None:
    """``text`` as a float with ``lo < value < hi`` (finite), else None."""
    try:
        value = float(text)
    except ValueError:
        return None
    return value if math.isfinite(value) and lo < value < hi else None


def positive(what: str, example: str):
    """A finite number above 0 (``what``, such as ``example``)."""
    def parse(text: str) -> float:
        value = number(text)
        if value is None:
            raise argparse.ArgumentTypeError(f"expected {what}: a finite number > 0 such as {example}, got {text!r}")
        return value

    return parse


def tolerance(text: str) -> float:
    """A relative tolerance between 0 and 1."""
    value = number(text, 0.0, 1.0)
    if value is None:
        raise argparse.ArgumentTypeError(f"expected a relative tolerance between 0 and 1 such as 1e-8, got {text!r}")
    return value


def numbers(what: str, example: str, hi: float = math.inf):
    """Comma-separated numbers, each finite with ``0 < value < hi`` (``--tolerances``, ``--frequencies``)."""
    def parse(text: str) -> list[float]:
        items = [item.strip() for item in text.split(",") if item.strip()]
        if not items:
            raise argparse.ArgumentTypeError(f"expected comma-separated {what}s such as {example}, got {text!r}")
        values = []
        for item in items:
            value = number(item, 0.0, hi)
            if value is None:
                bound = f"a number between 0 and {hi:g}" if math.isfinite(hi) else "a finite number > 0"
                raise argparse.ArgumentTypeError(
                    f"{item!r} is not a valid {what} ({bound}): give comma-separated values such as {example}")
            values.append(value)
        return values

    return parse


def pairs(text: str) -> dict[str, float]:
    """``name=value[,name=value]`` as a dict (``--initial``, ``--velocity``, ``--param``)."""
    out = {}
    for pair in text.split(","):
        if not pair.strip():
            continue
        key, sep, value = pair.partition("=")
        key = key.strip()
        if not sep or not key:
            raise argparse.ArgumentTypeError(f"expected name=value pairs such as x=1,y=0, got {pair.strip()!r}")
        try:
            given = float(value)
        except ValueError:
            given = math.nan
        if not math.isfinite(given):
            raise argparse.ArgumentTypeError(f"the value of {key!r} must be a finite number, got {value.strip()!r}")
        out[key] = given
    return out


def methods(extra: tuple[str, ...], single: bool):
    """Integration method names, checked against the registered integrators (and ``extra``)."""

    def parse(text: str) -> str | list[str]:
        names = [text.strip()] if single else [m.strip() for m in text.split(",") if m.strip()]
        if not names or not names[0]:
            raise argparse.ArgumentTypeError(f"expected {'a method name' if single else 'comma-separated method names'} "
                                             f"(see 'lagrangian integrators'), got {text!r}")
        known = [*_registry.default_registry().integrators, *extra]
        for name in names:
            if name not in known:
                raise argparse.ArgumentTypeError(
                    f"{UnknownNameError('integration method', name, known)} See 'lagrangian integrators'.")
        return names[0] if single else names

    return parse


# ---------------------------------------------------------------------------
# Output paths
# ---------------------------------------------------------------------------


def output_problem(option: str, path: str, *, directory: bool) -> str | None:
    """Why ``path`` cannot take the output of ``option`` (a file, or a directory made if missing), or None."""
    target = Path(path).absolute()
    if directory and target.exists() and not target.is_dir():
        return f"{option} {path!r} is a file, not a directory: give a directory (it is created if missing)."
    if not directory and target.is_dir():
        return f"{option} {path!r} is a directory: give a file name, such as {os.path.join(path, 'out.csv')!r}."
    folder = target if directory else target.parent
    existing = folder
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir():
        return f"{option} {path!r}: {str(existing)!r} is a file, not a directory: give a path inside a directory."
    if not directory and existing != folder:
        return f"{option} {path!r}: directory {str(folder)!r} does not exist: create it or give another path."
    if not os.access(existing, os.W_OK | os.X_OK) or (target.exists() and not os.access(target, os.W_OK)):
        return f"{option} {path!r}: permission denied: give a path you can write to."
    return None


def write_failure(option: str, path: str, exc: OSError) -> str:
    """The message of an output ``path`` that could not be written (``exc``), naming the file and the fix."""
    file = f" {str(exc.filename)!r}" if exc.filename and str(exc.filename) != str(path) else ""
    return f"{option} {path!r}: cannot write{file}: {exc.strerror or exc}. Give a path you can write to."


def out_problem(path: str, suffixes, advice: str) -> str | None:
    """What is wrong with ``--out path`` before anything runs: a file that cannot be written, or a kind of file the
    command does not write (its suffix not one of ``suffixes``: ``advice`` says which)."""
    problem = output_problem("--out", path, directory=False)
    if not problem and Path(path).suffix.lower() not in suffixes:
        problem = f"--out {path!r}: {advice}."
    return problem
