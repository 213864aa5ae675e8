"""Sliders over a model's parameters (ipywidgets): moving one runs the model again with its compiled code, nothing
derived again, and redraws the chart.

:class:`Sliders` is the machinery (a slider per parameter, a chart that a ``draw(values)`` call redraws, shown in a
notebook); :func:`interact` is :meth:`lagrangian.Model.interact` (a run's chart, or its animation), and
:func:`lagrangian.frequency.interact` builds a Bode chart on it.  Importing this module imports neither ipywidgets
nor matplotlib.
"""

from __future__ import annotations

import html
import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from ..errors import ModelError, UnknownNameError
from . import charts

__all__ = ["Sliders", "interact", "MAX_SLIDERS"]

#: Most sliders one chart takes.
MAX_SLIDERS = 24
#: A slider spans its parameter's value divided and multiplied by this, on a logarithmic scale (a nonzero value).
SPAN = 10.0


def _widgets():
    try:
        import ipywidgets
    except ImportError:
        raise ModelError("sliders need ipywidgets: pip install ipywidgets (in the notebook's environment).") from None
    return ipywidgets


class Sliders:
    """A slider for each of ``values`` (name → starting value) and an output area that ``draw(values)`` fills.

    ``ranges`` (name → ``(low, high)``) bound a slider; by default a positive value spans a decade each way on a
    logarithmic scale (a negative one likewise, mirrored), and zero spans ``(−1, 1)``.  ``draw`` is called with the
    current values at once and after every change; what it draws (a matplotlib figure it returns) is shown in the
    output area.  :meth:`set` moves sliders from code.  ``widget`` is the ipywidgets box to place elsewhere.
    """

    def __init__(self, values: Mapping[str, float], draw: Callable[[dict[str, float]], Any],
                 ranges: Mapping[str, tuple[float, float]] | None = None, *, title: str = ""):
        widgets = _widgets()
        if not values:
            raise ModelError("no parameters to slide: name some (params=[...]) of the model's parameter_values.")
        if len(values) > MAX_SLIDERS:
            raise ModelError(f"{len(values)} sliders asked for; at most {MAX_SLIDERS}: choose the parameters to vary.")
        ranges = dict(ranges or {})
        unknown = set(ranges) - set(values)
        if unknown:
            raise UnknownNameError("slider", sorted(unknown)[0], values)
        self.values = {name: float(value) for name, value in values.items()}
        self._draw, self.figure = draw, None
        self.sliders = {name: self._slider(widgets, name, value, ranges.get(name)) for name, value in self.values.items()}
        self.output = widgets.Output()
        self.status = widgets.HTML()
        heading = [widgets.HTML(f"<b>{html.escape(title)}</b>")] if title else []  # a model's name: text, escaped
        self.widget = widgets.VBox([*heading, *self.sliders.values(), self.status, self.output])
        for name, slider in self.sliders.items():
            slider.observe(lambda change, name=name: self._moved(name, change["new"]), names="value")
        self.redraw()

    @staticmethod
    def _slider(widgets, name: str, value: float, bounds: tuple[float, float] | None):
        style = {"description_width": "initial"}
        if bounds is not None:
            low, high = (float(b) for b in bounds)
            if not (math.isfinite(low) and math.isfinite(high) and low < high and low <= value <= high):
                raise ModelError(f"slider {name!r}: range ({low:g}, {high:g}) must hold its value {value:g}, low < high.")
            if low > 0:
                return widgets.FloatLogSlider(value=value, min=math.log10(low), max=math.log10(high), step=0.01,
                                              description=name, continuous_update=False, style=style)
            return widgets.FloatSlider(value=value, min=low, max=high, step=(high - low) / 200, description=name,
                                       continuous_update=False, style=style)
        if value > 0:
            return widgets.FloatLogSlider(value=value, min=math.log10(value / SPAN), max=math.log10(value * SPAN),
                                          step=0.01, description=name, continuous_update=False, style=style)
        low, high = (value * SPAN, value / SPAN) if value < 0 else (-1.0, 1.0)
        return widgets.FloatSlider(value=value, min=low, max=high, step=(high - low) / 200, description=name,
                                   continuous_update=False, style=style)

    def _moved(self, name: str, value: float) -> None:
        self.values[name] = float(value)
        self.redraw()

    def set(self, **values: float) -> None:
        """Move sliders to ``values`` (by name) and redraw, as a user dragging them would."""
        for name, value in values.items():
            if name not in self.sliders:
                raise UnknownNameError("slider", name, self.sliders)
            self.sliders[name].value = value  # the observer redraws

    def redraw(self) -> None:
        """Draw again at the sliders' values; a model that cannot run there says why, in the status line."""
        try:
            figure = self._draw(dict(self.values))
        except ModelError as exc:  # a run the values make impossible: said, the last chart kept
            self.status.value = f"<span style='color:#b00'>{html.escape(f'{type(exc).__name__}: {exc}')}</span>"
            return
        self.status.value = ""
        if figure is None:
            return
        self.figure = figure
        from IPython import get_ipython

        if get_ipython() is not None:  # in a notebook: the chart into the output area (outside one, kept only)
            from IPython.display import clear_output, display

            with self.output:
                clear_output(wait=True)
                display(figure)

    def _ipython_display_(self) -> None:
        from IPython.display import display

        display(self.widget)


def interact(model: Any, params: Sequence[str] | None = None, outputs: Sequence[str] | None = None, *,
             t_end: float = 10.0, initial: Mapping[str, float] | None = None,
             velocity: Mapping[str, float] | None = None, points: int = 501, method: str = "auto",
             ranges: Mapping[str, tuple[float, float]] | None = None, view: str = "chart", frames: int = 60) -> Sliders:
    """Sliders over ``params`` (names of :attr:`~lagrangian.Model.parameter_values`; all of them by default) that
    run the model again (``simulate(t_end, ..., params=...)``: its compiled code, nothing derived again) and redraw
    ``outputs`` against time (coordinates, their rates ``x_p'``, energies ``T``, ``V``, ``E``, or any expression
    of them as text: ``"0.5 * x_p"``; the coordinates by default), or, with ``view="animation"``, the mechanism's
    animation (:meth:`lagrangian.Result.animate`, ``frames`` of it).  Returns the :class:`Sliders`; in a notebook it
    shows itself.

    >>> import numpy as np, lagrangian as lg
    >>> m = lg.Model("oscillator")
    >>> _ = m.add("mass", "m1", "p", m=0.3)
    >>> _ = m.add("spring", "k1", ("ground", "p"), k=40)
    >>> s = m.interact(["k_k1"], t_end=1, initial={"x_p": 0.01}, velocity={"x_p": 0})
    >>> s.set(k_k1=120.0)                      # as if dragged: run again with k = 120 N/m
    >>> x = s.figure.axes[0].lines[0].get_ydata()
    >>> bool(abs(x[-1] - 0.01 * np.cos((120 / 0.3) ** 0.5)) < 1e-8)
    True
    """
    import numpy as np

    known = model.parameter_values
    names = list(known) if params is None else list(params)
    for name in names:
        if name not in known:
            raise UnknownNameError("parameter (as parameter_values names it)", name, known)
    if view not in ("chart", "animation"):
        raise ModelError(f"view is 'chart' or 'animation', got {view!r:.40}.")
    state: dict[str, Any] = {}

    @charts.plain
    def run(values: dict[str, float]):
        res = model.simulate(t_end, initial=initial, velocity=velocity, params=values, points=points, method=method)
        state["result"] = res
        if view == "animation":
            from IPython.display import HTML

            return HTML(res.animate(frames=frames).to_jshtml())
        shown = list(outputs) if outputs else list(res.names)
        columns = res._columns()
        series = {name: columns[name] if name in columns else np.broadcast_to(res.quantity(name), res.t.shape)
                  for name in shown}
        figure = state.get("figure")
        if figure is None:
            from matplotlib.figure import Figure

            figure = state["figure"] = Figure(figsize=(7, 3.6), layout="constrained")
            ax = figure.add_subplot()
            for name, values_ in series.items():
                ax.plot(res.t, values_, label=name)
            ax.set_xlabel("t (s)")
            ax.legend(loc="upper right", fontsize=8)
        ax = figure.axes[0]
        for line, values_ in zip(ax.lines, series.values()):
            line.set_data(res.t, values_)
        ax.relim()
        ax.autoscale_view()
        ax.set_title(", ".join(f"{n} = {v:.4g}" for n, v in values.items()), fontsize=9)
        return figure

    return _RunSliders(state, {n: known[n] for n in names}, run, ranges, title=f"model {model.name}")


class _RunSliders(Sliders):
    """:class:`Sliders` over a model's runs: :attr:`result` is the latest run."""

    def __init__(self, state: dict[str, Any], *args: Any, **kwargs: Any):
        self._state = state
        super().__init__(*args, **kwargs)

    @property
    def result(self):
        """The run at the sliders' values (a :class:`~lagrangian.Result`)."""
        return self._state.get("result")
