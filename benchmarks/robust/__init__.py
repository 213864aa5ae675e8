"""Generated cases for the robustness benchmark and its property tests.

A :class:`Case` is one analysis on one family of models: the space its
parameters and states are drawn from, and a ``check`` that runs the analysis
through the public API on one draw and compares the result with a reference
that does not come from the code under test (a closed form, the full model,
sympy.physics.mechanics, ngspice) and with the same model built from symbols
and then given the values (the *symbolic twin*: same verdicts, values within
1e-10).  ``check`` raises :class:`Mismatch` when they disagree; any other
exception is a failure too.

``benchmarks/robustness.py`` draws with NumPy from a seed; ``tests/test_robustness.py``
draws from the same spaces with hypothesis, so a failure shrinks.

Values are drawn log-uniformly over decades for parameters and uniformly for
states, then rounded to three significant digits: ordinary decimals (0.347,
7.12e-3) that binary floating point does not represent exactly.
"""

from __future__ import annotations

import importlib
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np

MODULES = ("robust.routh_cases", "robust.impact_cases", "robust.circuit_cases", "robust.scene_cases")


class Mismatch(AssertionError):
    """An analysis disagrees with its reference or with its symbolic twin."""


@dataclass(frozen=True)
class Draw:
    """A range to draw one value from: ``log`` (log-uniform over decades) or ``uniform``."""

    kind: str
    lo: float
    hi: float
    digits: int = 3

    def __post_init__(self):
        if self.kind not in ("log", "uniform") or not self.lo < self.hi or (self.kind == "log" and self.lo <= 0):
            raise ValueError(f"bad range {self}")

    def from_unit(self, u: float) -> float:
        """The value at ``u`` in [0, 1], rounded to ``digits`` significant digits and kept inside the range."""
        if self.kind == "log":
            x = math.exp(math.log(self.lo) + u * (math.log(self.hi) - math.log(self.lo)))
        else:
            x = self.lo + u * (self.hi - self.lo)
        x = float(f"{x:.{self.digits}g}")
        return min(max(x, self.lo), self.hi)


def decades(lo: float, hi: float, digits: int = 3) -> Draw:
    return Draw("log", lo, hi, digits)


def uniform(lo: float, hi: float, digits: int = 3) -> Draw:
    return Draw("uniform", lo, hi, digits)


@dataclass(frozen=True)
class Case:
    """One analysis on one model family; ``check(values)`` raises when the analysis is wrong."""

    analysis: str
    name: str
    space: Mapping[str, Draw]
    check: Callable[[dict[str, float]], None] = field(repr=False)
    admissible: Callable[[dict[str, float]], bool] | None = field(default=None, repr=False)

    def draw(self, rng: np.random.Generator, tries: int = 1000) -> dict[str, float]:
        """Values from ``rng``, redrawn until ``admissible`` accepts them."""
        for _ in range(tries):
            values = {k: d.from_unit(float(rng.random())) for k, d in self.space.items()}
            if self.admissible is None or self.admissible(values):
                return values
        raise RuntimeError(f"{self.analysis}/{self.name}: no admissible draw in {tries} tries")


def cases() -> list[Case]:
    """Every case of every module in :data:`MODULES`."""
    out: list[Case] = []
    for name in MODULES:
        out.extend(importlib.import_module(name).CASES)
    return out


def close(got: float, want: float, what: str, rel: float = 1e-10, abs_: float = 0.0) -> None:
    """Raise :class:`Mismatch` unless ``got`` is within ``rel`` (relative) or ``abs_`` of ``want``."""
    got, want = float(got), float(want)
    if not (math.isfinite(got) and abs(got - want) <= max(rel * abs(want), abs_)):
        raise Mismatch(f"{what}: got {got!r}, expected {want!r} (rel {rel:g})")


def same(got, want, what: str) -> None:
    """Raise :class:`Mismatch` unless ``got == want`` (verdicts, names, structure)."""
    if got != want:
        raise Mismatch(f"{what}: got {got!r}, expected {want!r}")
