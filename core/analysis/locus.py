"""Root loci and pole–zero maps: where a model's poles go as one of its parameters changes, and where a transfer
function's poles and zeros lie.

:func:`root_locus` linearizes the model at each value of the parameter and takes its eigenvalues
(:func:`~lagrangian.analysis.modes.modes`, each complex pair with both of its members); :meth:`RootLocus.plot`
draws them in the complex plane coloured by the value, and :func:`pole_zero_map` a transfer function's poles (×)
and zeros (○).

>>> import lagrangian as lg
>>> import numpy as np
>>> m = lg.Model("oscillator")
>>> _ = m.add("mass", "m", "p", m=0.3)
>>> _ = m.add("spring", "k", ("ground", "p"), k=40.0)
>>> _ = m.add("damper", "c", ("ground", "p"), c=0.5)
>>> locus = root_locus(m, "c_c", [0.0, 2 * (40.0 * 0.3) ** 0.5])      # undamped, then critically damped
>>> np.abs(locus.poles.imag).round(6).tolist()
[[11.547005, 11.547005], [0.0, 0.0]]
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..base import charts
from ..base.limits import refuse
from ..errors import UnknownNameError
from ..model import Model
from .linearize import linearize
from .modes import modes

__all__ = ["RootLocus", "pole_zero_map", "root_locus"]


@dataclass
class RootLocus:
    """The poles (rad/s) of ``model`` at each value of ``parameter``: ``poles[i]`` at ``values[i]`` (every complex
    pair with both members; rows padded with ``nan`` where a value has fewer poles)."""

    model: str
    parameter: str
    values: np.ndarray
    poles: np.ndarray

    def __repr__(self) -> str:
        return (f"<RootLocus of {self.model!r}: {self.poles.shape[1]} poles over {len(self.values)} values of "
                f"{self.parameter}>")

    @charts.plain
    def plot(self, path: str | None = None):
        """The poles in the complex plane, coloured by the parameter's value (on a log scale when the values are
        positive and span more than a decade), the first value's marked ×, the last's ○; returns the Figure."""
        import matplotlib.colors as mcolors

        fig, ax = charts.subplots(figsize=(6.5, 5), constrained_layout=True)
        values = np.repeat(self.values, self.poles.shape[1])
        flat = self.poles.ravel()
        positive = np.all(self.values > 0)
        norm = (mcolors.LogNorm() if positive and self.values.max() > 10 * self.values.min() else mcolors.Normalize())
        points = ax.scatter(flat.real, flat.imag, c=values, s=8, cmap="viridis", norm=norm)
        ax.plot(self.poles[0].real, self.poles[0].imag, "kx", ms=8, label=f"{self.parameter} = {self.values[0]:g}")
        ax.plot(self.poles[-1].real, self.poles[-1].imag, "ko", mfc="none", ms=8,
                label=f"{self.parameter} = {self.values[-1]:g}")
        fig.colorbar(points, ax=ax, label=self.parameter)
        ax.axvline(0, color="k", lw=0.5)
        ax.axhline(0, color="k", lw=0.5)
        ax.set_xlabel("Re s (1/s)")
        ax.set_ylabel("Im s (rad/s)")
        ax.set_title(f"{self.model}: root locus against {self.parameter}")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
        if path is not None:
            fig.savefig(path, dpi=110)
        return fig


def root_locus(model: Model, parameter: str, values: Sequence[float], **kwargs: Any) -> RootLocus:
    """The poles of ``model`` linearized (``kwargs`` as for :func:`~lagrangian.frequency.linearize`: ``at``,
    ``velocity``, ``params``) at each of ``values`` of ``parameter`` (a name of ``model.parameter_values``)."""
    if parameter not in model.parameter_values:
        raise UnknownNameError("parameter", parameter, model.parameter_values)
    values = np.asarray(values, dtype=float).ravel()
    refuse("root locus", len(values), "grid_points")
    params = dict(kwargs.pop("params", None) or {})
    rows = []
    for value in values:
        lam = modes(linearize(model, params={**params, parameter: float(value)}, **kwargs)).eigenvalues
        pairs = lam[np.abs(lam.imag) > 1e-12 * np.maximum(np.abs(lam), 1e-300)]
        rows.append(np.concatenate([lam, pairs.conj()]))
    width = max((len(r) for r in rows), default=0)
    poles = np.full((len(rows), width), np.nan, dtype=complex)
    for i, row in enumerate(rows):
        poles[i, :len(row)] = np.sort_complex(row)
    return RootLocus(model.name, parameter, values, poles)


@charts.plain
def pole_zero_map(poles: Sequence[complex], zeros: Sequence[complex], title: str = "", path: str | None = None):
    """Poles (×) and zeros (○) in the complex plane (rad/s); returns the Figure (a transfer function's:
    ``pole_zero_map(H.poles(), H.zeros(), repr(H))``)."""
    fig, ax = charts.subplots(figsize=(5.5, 5), constrained_layout=True)
    p, z = np.asarray(poles, dtype=complex), np.asarray(zeros, dtype=complex)
    ax.plot(p.real, p.imag, "x", ms=9, mew=2, label=f"poles ({len(p)})")
    ax.plot(z.real, z.imag, "o", ms=9, mfc="none", mew=1.5, label=f"zeros ({len(z)})")
    ax.axvline(0, color="k", lw=0.5)
    ax.axhline(0, color="k", lw=0.5)
    ax.set_xlabel("Re s (1/s)")
    ax.set_ylabel("Im s (rad/s)")
    if title:
        ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    if path is not None:
        fig.savefig(path, dpi=110)
    return fig
