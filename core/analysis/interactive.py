"""A Bode chart with sliders over a model's parameters (:func:`interact`, as ``lagrangian.frequency.interact``).

The model is linearized once with the chosen parameters as symbols (:class:`~lagrangian.analysis.parametric.
ParametricResponse`); moving a slider evaluates that response at the new values, nothing derived again, and redraws
the magnitude and phase of every output to every input.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ..base import charts
from ..base.sliders import Sliders
from ..errors import UnknownNameError
from .parametric import ParametricResponse

__all__ = ["interact"]


def interact(model: Any, params: Sequence[str], frequencies: Any, *, inputs: Sequence[str] | None = None,
             outputs: Sequence[Any] | None = None, ranges: Mapping[str, tuple[float, float]] | None = None) -> Sliders:
    """Sliders over ``params`` (names of :attr:`~lagrangian.Model.parameter_values`) and a Bode chart of
    ``outputs`` to ``inputs`` (as :func:`~lagrangian.frequency.frequency_response` takes them) at ``frequencies``
    (Hz) that follows them.  Returns the :class:`~lagrangian.base.sliders.Sliders`; ``response`` on it is the
    latest ``H`` (outputs × inputs × frequencies).

    >>> import numpy as np, lagrangian as lg
    >>> from lagrangian.frequency import decades, interact
    >>> c = lg.Model("rc")
    >>> _ = c.add("voltage_source", "V1", ("in", "0"), E=0)
    >>> _ = c.add("resistor", "R1", ("in", "out"), R=1e3)
    >>> _ = c.add("capacitor", "C1", ("out", "0"), C=2.2e-6)
    >>> bode = interact(c, ["R_R1"], decades(1, 1e5, 50), outputs=["v(C1)"])
    >>> bode.set(R_R1=4.7e3)                             # the corner moves to 1/(2π · 4.7 kΩ · 2.2 µF)
    >>> f = bode.frequencies; H = 1 / (1 + 2j * np.pi * f * 4.7e3 * 2.2e-6)
    >>> bool(np.allclose(bode.response[0, 0], H, rtol=1e-12, atol=0))
    True
    """
    known = model.parameter_values
    for name in params:
        if name not in known:
            raise UnknownNameError("parameter (as parameter_values names it)", name, known)
    f = np.asarray(frequencies, dtype=float)
    parametric = ParametricResponse(model, inputs, outputs, list(params))
    state: dict[str, Any] = {}

    @charts.plain
    def draw(values: dict[str, float]):
        H, _ = parametric.evaluate([values[n] for n in parametric.names], f, jacobian=False)
        state["response"] = H
        figure = state.get("figure")
        if figure is None:
            from matplotlib.figure import Figure

            figure = state["figure"] = Figure(figsize=(7, 5), layout="constrained")
            magnitude, phase = figure.subplots(2, 1, sharex=True)
            for i, out in enumerate(parametric.outputs):
                for j, source in enumerate(parametric.inputs):
                    label = f"{out} / {source}"
                    magnitude.semilogx(f, np.zeros_like(f), label=label)
                    phase.semilogx(f, np.zeros_like(f), label=label)
            magnitude.set_ylabel("|H| (dB)")
            phase.set_ylabel("phase (°)")
            phase.set_xlabel("f (Hz)")
            magnitude.legend(fontsize=8)
        magnitude, phase = figure.axes
        curves = [H[i, j] for i in range(H.shape[0]) for j in range(H.shape[1])]
        for line, h in zip(magnitude.lines, curves):
            line.set_ydata(20 * np.log10(np.abs(h)))
        for line, h in zip(phase.lines, curves):
            line.set_ydata(np.degrees(np.unwrap(np.angle(h))))
        for ax in (magnitude, phase):
            ax.relim()
            ax.autoscale_view()
        magnitude.set_title(", ".join(f"{n} = {v:.4g}" for n, v in values.items()), fontsize=9)
        return figure

    return _BodeSliders(state, f, {n: known[n] for n in params}, draw, ranges, title=f"model {model.name}: Bode")


class _BodeSliders(Sliders):
    """:class:`Sliders` over a Bode chart: ``frequencies`` and the latest ``response``."""

    def __init__(self, state: dict[str, Any], frequencies: np.ndarray, *args: Any, **kwargs: Any):
        self._state, self.frequencies = state, frequencies
        super().__init__(*args, **kwargs)

    @property
    def response(self) -> np.ndarray:
        """``H`` at the sliders' values: outputs × inputs × frequencies."""
        return self._state["response"]
