"""The result of a simulation: the time grid, coordinates and rates, energies, and how it was obtained; its
exports (:meth:`Result.to_xarray`, :meth:`Result.to_pandas`), chart and notebook display."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..base import charts
from ..base import display
from ..base.animation import Animation
from ..base.limits import refuse
from ..base.units import coordinate_unit
from ..errors import ModelError, UnknownNameError

__all__ = ["Result"]

#: :meth:`Result.plot` without names draws at most this many coordinates (the first ones, and says so in its title),
#: and an axes with more series than this has no legend: 200 entries do not fit a chart, nor do 200 lines read
#: (ten: matplotlib's colours before they repeat).
PLOT_SERIES = 10


def legend(axis) -> None:
    """A legend of the series drawn on ``axis``, up to :data:`PLOT_SERIES` of them; past that, their count in its
    title."""
    count = len(axis.get_lines())
    if count <= PLOT_SERIES:
        axis.legend()
    else:
        axis.set_title(f"{count} series (a legend up to {PLOT_SERIES})", fontsize="small")


@dataclass(repr=False)
class Result:
    """The outcome of :meth:`lagrangian.Model.simulate`.

    ``t`` is the time grid; ``q`` and ``v`` map each coordinate name to its
    values and velocities; ``T``, ``V``, ``D`` are kinetic energy, potential
    energy and Rayleigh function over time, and ``E = T + V``.
    ``defaulted`` lists initial conditions that were not given and set to zero.
    ``method`` is the method that produced the result (the one picked, for
    ``method="auto"``), ``nfev`` how many times it evaluated the model,
    ``step`` the step size of a fixed-step method, and ``notes`` what the
    run wants known: why ``auto`` picked its method, step adjustments, how
    well a conservative model kept its energy.  ``events`` lists the events
    that occurred (:class:`~lagrangian.numerics.events.Occurrence`: name,
    time, state), when the run was given any.
    ``sensitivities`` holds the forward sensitivities a run was asked for (``simulate(..., sensitivities=[...])``,
    :mod:`lagrangian.numerics.sensitivity`): for each name (a parameter, or an initial value), the derivative of each
    coordinate (``"x_p"``) and rate (``"x_p'"``) with respect to it, over ``t`` — read with :meth:`sensitivity`,
    listed by :attr:`sensitivity_names`.
    ``res["x_cart"]`` is the same as ``res.q["x_cart"]``.  ``derived`` maps each
    coordinate a constraint eliminated (``eliminate=``) to its function
    ``x(t)``: no coordinate of the run, ``res["x"]`` and ``res.velocity("x")``
    still give it, from the solution in the others.

    >>> import lagrangian as lg
    >>> m = lg.Model("rack")
    >>> _ = m.add("mass", "rack", "p", m=0.5)
    >>> _ = m.add("inertia", "J", "s", J=1e-3)
    >>> _ = m.add("rack_and_pinion", "mesh", rack="x_p", pinion="theta_s", radius=0.02, eliminate="theta_s")
    >>> res = m.simulate(1, initial={"x_p": 0.0}, velocity={"x_p": 0.1}, points=3)
    >>> res.names, [round(float(a), 9) for a in res["theta_s"]], [float(w) for w in res.velocity("theta_s")]
    (['x_p'], [0.0, 2.5, 5.0], [5.0, 5.0, 5.0])
    """

    t: np.ndarray
    q: dict[str, np.ndarray]
    v: dict[str, np.ndarray]
    T: np.ndarray
    V: np.ndarray
    D: np.ndarray
    model: str = ""
    defaulted: list[str] = field(default_factory=list)
    nfev: int = 0
    method: str = ""
    evaluator: Callable[[Any, "Result"], np.ndarray] | None = field(default=None, repr=False)
    notes: list[str] = field(default_factory=list)
    step: float | None = None
    events: list = field(default_factory=list)
    derived: dict[str, Any] = field(default_factory=dict)
    sensitivities: dict[str, dict[str, np.ndarray]] = field(default_factory=dict, repr=False)

    def __repr__(self) -> str:
        span = f"[{self.t[0]:g}, {self.t[-1]:g}]" if len(self.t) else "[]"
        return (f"<Result of {self.model!r}: {self.method or 'run'}, {len(self.t)} times over {span}, "
                f"coordinates {display.short(self.names)}, {self.nfev} evaluations>")

    def _summary(self) -> list[list[str]]:
        rows = [["method", self.method], ["times", f"{len(self.t)} over [{self.t[0]:g}, {self.t[-1]:g}]"],
                ["evaluations", str(self.nfev)]]
        if self.step is not None:
            rows.append(["step", f"{self.step:g}"])
        for name in self.names[:12]:
            x = self.q[name]
            rows.append([name, f"{x[0]:.6g} → {x[-1]:.6g} (min {np.min(x):.6g}, max {np.max(x):.6g})"])
        if len(self.t) > 1 and np.all(np.isfinite(self.E)):
            rows.append(["energy T + V", f"{self.E[0]:.6g} → {self.E[-1]:.6g}"])
        if self.defaulted:
            rows.append(["started at zero", display.short(self.defaulted)])
        if self.events:
            rows.append(["events", display.short([f"{e.name} at {e.time:.6g}" for e in self.events])])
        if self.sensitivities:
            rows.append(["sensitivities to", display.short(self.sensitivity_names)])
        return rows

    def _repr_html_(self) -> str:
        """A summary table, the notes and a chart of the coordinates (Jupyter)."""
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(7, 3.4), constrained_layout=True)
        self.plot(*self.names[:8], ax=ax)
        chart = display.image(display.png(fig), alt=f"coordinates of {self.model}")
        notes = "".join(f"<li>{display.escape(n)}</li>" for n in self.notes)
        return display.block(f"simulation of {self.model}", display.table(["", ""], self._summary()),
                             f"<ul>{notes}</ul>" if notes else "", chart)

    @property
    def E(self) -> np.ndarray:
        """Total energy ``T + V``."""
        return self.T + self.V

    @property
    def names(self) -> list[str]:
        return list(self.q)

    def __getitem__(self, name: str) -> np.ndarray:
        if name in self.q:
            return self.q[name]
        if name in self.derived:
            return self.quantity(self.derived[name])
        raise UnknownNameError("coordinate", name, [*self.q, *self.derived])

    def velocity(self, name: str) -> np.ndarray:
        """Values of ``q̇`` for the coordinate ``name`` (or one a constraint eliminated, from the solution)."""
        if name in self.v:
            return self.v[name]
        if name in self.derived:
            f = self.derived[name]
            return self.quantity(f.diff(f.args[0]))
        raise UnknownNameError("coordinate", name, [*self.v, *self.derived])

    @property
    def sensitivity_names(self) -> list[str]:
        """What the run computed the sensitivities to (``simulate(..., sensitivities=[...])``), in the order asked:
        parameters by name, coordinates for their initial values, ``"x_p'"`` for an initial rate; ``[]`` for none."""
        return list(self.sensitivities)

    def sensitivity(self, name: str, wrt: str) -> np.ndarray:
        """``∂name(t)/∂wrt`` over :attr:`t`: ``name`` a coordinate (``"x_p"``) or its rate (``"x_p'"``), ``wrt`` one of
        :attr:`sensitivity_names` — a parameter, or a coordinate (``x_p(0)``) or its rate (``x_p'`` for ``ẋ_p(0)``).
        :class:`UnknownNameError` for a name the run did not compute, listing those it did."""
        if not self.sensitivities:
            raise ModelError(f"this run of {self.model!r} computed no sensitivities: ask for them with "
                             f"simulate(..., sensitivities=[...]), naming parameters or initial values.")
        if wrt not in self.sensitivities:
            raise UnknownNameError("sensitivity of this run", wrt, self.sensitivities)
        series = self.sensitivities[wrt]
        if name not in series:
            raise UnknownNameError("coordinate or rate", name, series)
        return series[name]

    def quantity(self, expr: Any) -> np.ndarray:
        """Any expression in the coordinates ``q(t)``, their rates and ``t``, evaluated along the result.

        >>> import lagrangian as lg
        >>> m = lg.Model("osc")
        >>> _ = m.add("mass", "m", "p", m=1)
        >>> _ = m.add("spring", "k", ("ground", "p"), k=4)
        >>> res = m.simulate(1, initial={"x_p": 1}, velocity={"x_p": 0}, points=3)
        >>> x = m.coordinates[0].function
        >>> np.allclose(res.quantity(4 * x), 4 * res["x_p"])  # the spring's force
        True
        """
        if self.evaluator is None:
            raise ModelError("this result is not attached to a model; quantities cannot be evaluated.")
        return self.evaluator(expr, self)

    def cumulative(self, series: Any) -> np.ndarray:
        """``∫₀ᵗ`` of ``series`` (an expression, as :meth:`quantity` takes, or values on ``t``) along the run, by
        Simpson's rule on the output times: the work of a load, ``res.cumulative(model.load_power("F"))``, or the
        energy a linear damper dissipated, ``res.cumulative(2 * res.D)``.  Its error falls as the fourth power of
        the spacing of the output times: ask for more ``points`` for more digits.

        >>> import lagrangian as lg
        >>> m = lg.Model("pushed")
        >>> _ = m.add("mass", "m1", "p", m=2.0)
        >>> _ = m.add("force", "F", "p", F=3.0)
        >>> res = m.simulate(2, initial={"x_p": 0}, velocity={"x_p": 0}, points=101)
        >>> W = res.cumulative(m.load_power("F"))          # F x = F² t² / 2m
        >>> bool(abs(W[-1] - 9.0) < 1e-9 and abs(W[-1] - (res.E[-1] - res.E[0])) < 1e-9)
        True
        """
        from scipy.integrate import cumulative_simpson

        values = series if isinstance(series, np.ndarray) else self.quantity(series)
        values = np.broadcast_to(np.asarray(values, dtype=float), self.t.shape)
        if self.t.size < 2:
            return np.zeros_like(self.t)
        return cumulative_simpson(values, x=self.t, initial=0.0)

    def energy_drift(self) -> float:
        """Largest departure of ``T + V`` from its initial value, relative to the largest of ``|E(0)|``, ``T`` and ``|V|``."""
        E = self.E
        scale = max(abs(E[0]), np.max(np.abs(self.T)), np.max(np.abs(self.V)), np.finfo(float).tiny)
        return float(np.max(np.abs(E - E[0])) / scale)

    def _columns(self) -> dict[str, np.ndarray]:
        """Every series of the run by name: coordinates (those a constraint eliminated after them), their rates
        (``x_p'``), T, V, D and E."""
        q = {**self.q, **{n: self[n] for n in self.derived}}
        rates = {**self.v, **{n: self.velocity(n) for n in self.derived}}
        return {**q, **{f"{n}'": v for n, v in rates.items()}, "T": self.T, "V": self.V, "D": self.D, "E": self.E}

    def to_xarray(self):
        """The run as an :class:`xarray.Dataset` over ``time``: coordinates, their rates (``"x_p'"``), ``T``, ``V``,
        ``D`` and ``E``, with the method, evaluations and notes as attributes (``.to_netcdf(path)`` saves it).

        >>> import lagrangian as lg
        >>> m = lg.Model("osc")
        >>> _ = m.add("mass", "m", "p", m=0.3)
        >>> _ = m.add("spring", "k", ("ground", "p"), k=40)
        >>> ds = m.simulate(1, initial={"x_p": 0.01}, velocity={"x_p": 0}, points=11).to_xarray()
        >>> list(ds.data_vars), ds.sizes["time"]
        (['x_p', "x_p'", 'T', 'V', 'D', 'E'], 11)
        """
        import xarray as xr

        units = {"T": "J", "V": "J", "D": "W", "E": "J"}
        for name in [*self.q, *self.derived]:  # by the coordinate's name: x_ metres, theta_ radians, q_ coulombs...
            if coordinate_unit(name):
                units[name], units[f"{name}'"] = coordinate_unit(name), coordinate_unit(name) + "/s"
        data = {name: xr.Variable(("time",), np.asarray(series), {"units": units[name]} if name in units else {})
                for name, series in self._columns().items()}
        attrs = {"model": self.model, "method": self.method, "nfev": int(self.nfev),
                 "notes": "\n".join(self.notes), "defaulted": ", ".join(self.defaulted)}
        if self.step is not None:
            attrs["step"] = float(self.step)
        return xr.Dataset(data, coords={"time": xr.Variable(("time",), self.t, {"units": "s"})}, attrs=attrs)

    def to_pandas(self):
        """The run as a :class:`pandas.DataFrame` indexed by time, one column per series (see :meth:`to_xarray`).

        >>> import lagrangian as lg
        >>> m = lg.Model("osc")
        >>> _ = m.add("mass", "m", "p", m=0.3)
        >>> _ = m.add("spring", "k", ("ground", "p"), k=40)
        >>> df = m.simulate(1, initial={"x_p": 0.01}, velocity={"x_p": 0}, points=11).to_pandas()
        >>> df.shape, df.index.name
        ((11, 6), 'time')
        """
        import pandas as pd

        return pd.DataFrame(self._columns(), index=pd.Index(self.t, name="time"))

    def to_csv(self, path: Any, columns: Mapping[str, Any] | None = None) -> None:
        """Write the run to the CSV file ``path``: a column ``t``, then one per series (every series of
        :meth:`to_xarray` by default, or ``columns``: names to values over :attr:`t`), each number to 17
        significant digits (it reads back to the same float).  Written by NumPy: a 3,001 × 401 table takes 0.42 s
        of CPU, where pandas' ``to_csv`` took 1.57 s.

        >>> import io, lagrangian as lg
        >>> m = lg.Model("osc")
        >>> _ = m.add("mass", "m", "p", m=0.3)
        >>> _ = m.add("spring", "k", ("ground", "p"), k=40)
        >>> res = m.simulate(1, initial={"x_p": 0.01}, velocity={"x_p": 0}, points=3)
        >>> out = io.StringIO()
        >>> res.to_csv(out, {"x_p": res["x_p"]})
        >>> out.getvalue().splitlines()[:2]
        ['t,x_p', '0,0.01']
        """
        columns = self._columns() if columns is None else dict(columns)
        for name in columns:
            if not isinstance(name, str) or any(c in name for c in ',"\n\r'):
                raise ModelError(f"a CSV column name is text without commas, quotes or line breaks; got {name!r:.80}.")
        table = np.empty((self.t.size, 1 + len(columns)))
        table[:, 0] = self.t
        for k, values in enumerate(columns.values()):
            table[:, k + 1] = np.broadcast_to(np.asarray(values, dtype=float), self.t.shape)
        np.savetxt(path, table, fmt="%.17g", delimiter=",", header=",".join(["t", *columns]), comments="")

    def __getstate__(self) -> dict[str, Any]:
        """Its fields; not the model that made it (:meth:`animate` of a result read back takes ``model=``)."""
        return {k: v for k, v in self.__dict__.items() if k != "source"}

    def animate(self, path: Any = None, *, model: Any = None, frames: int = 100, fps: float = 20,
                size: tuple[float, float] = (6.4, 4.8), dpi: int = 100):
        """The mechanism moving through this run, drawn from its kinematics (:mod:`lagrangian.base.animation`).

        Rigid bodies from their geometry (rods, discs, bodies with points), point masses, springs and dampers,
        joints and the ground, in the plane or in space, at ``frames`` of the output times (evenly spread, each
        one an output time: nothing is interpolated).  In a notebook the returned
        :class:`~lagrangian.base.animation.Animation` shows as a player with a time slider, play and pause,
        offline.  ``path`` also writes it: ``.html`` (a page of its own), ``.gif`` or ``.mp4`` (ffmpeg).
        ``model``: the model that made the run, for a result read back from a pickle (a run of
        :meth:`lagrangian.Model.simulate` knows its model).

        >>> import lagrangian as lg
        >>> m = lg.Model("pendulum", dim=2)
        >>> _ = m.add("rod", "r", "r", m=0.3, length=0.5)
        >>> _ = m.add("revolute", "j", ("ground", "r"))
        >>> _ = m.add("gravity", "g")
        >>> res = m.simulate(2, initial={"theta_j": -1.0}, velocity={"theta_j": 0.0}, points=201)
        >>> anim = res.animate(frames=50)
        >>> len(anim), anim.position("r", 0).round(4).tolist()   # the rod from the pivot to its end, at t = 0
        (50, [[0.0, 0.0, 0.0], [0.2702, -0.4207, 0.0]])
        """
        model = model if model is not None else self.__dict__.get("source")
        if model is None:
            raise ModelError("this result does not know the model that made it (a result read back from a pickle): "
                             "pass it, res.animate(model=m).")
        if isinstance(frames, bool) or not isinstance(frames, (int, np.integer)) or frames < 1:
            raise ModelError(f"frames must be a positive whole number, got {frames!r:.40}.")
        refuse("an animation", frames, "frames")
        shapes = [s for view in model.assembly.generic_views.values() for s in view.shapes()]  # the run's values in
        if not shapes:
            raise ModelError(f"model {model.name!r} has nothing in space to draw: an animation draws mechanical parts "
                             f"(masses, springs, rigid bodies and joints); plot a circuit's run with res.plot().")
        picked = np.unique(np.linspace(0, self.t.size - 1, min(frames, self.t.size)).round().astype(int))
        drawn = []
        for shape in shapes:
            values = np.asarray(self.quantity(shape.points), dtype=float)[..., picked]  # dim × n × frames
            points = np.zeros((picked.size, values.shape[1], 3))
            points[..., : values.shape[0]] = np.moveaxis(values, -1, 0).transpose(0, 2, 1)
            drawn.append((shape.name, shape.kind, points))
        dim = 3 if any(s.points.shape[0] == 3 for s in shapes) else 2
        anim = Animation(f"{model.name}", self.t[picked], drawn, dim=dim, fps=fps, size=size, dpi=dpi)
        if path is not None:
            anim.save(path)
        return anim

    @charts.plain
    def plot(self, *names: str, velocity: bool = False, energy: bool = False, ax=None, label: str | None = None):
        """Plot coordinates (``names``, or all of them up to :data:`PLOT_SERIES`: the first ones, the title says
        how many of how many) against time, one axes per unit (a charge and a displacement are not drawn on one
        scale), each labelled with its unit and with a legend up to :data:`PLOT_SERIES` series; return the matplotlib
        ``Axes``, or an array of them (one per unit, top to bottom, sharing ``t``) when the series have several units
        and no ``ax`` is given.

        ``velocity=True`` plots velocities instead; ``energy=True`` plots T, V and T+V (J).

        >>> import lagrangian as lg
        >>> m = lg.Model("pendulum on a cart", dim=2)
        >>> _ = m.add("link", "arm", "arm")
        >>> _ = m.add("prismatic", "rail", ("ground", "arm"), axis=(1, 0))
        >>> _ = m.add("mass", "cart", "arm", m=1.0)
        >>> res = m.simulate(1, initial={"s_rail": 0.1}, velocity={"s_rail": 0.0}, points=5)
        >>> res.plot().get_ylabel()
        'coordinate (m)'
        >>> import matplotlib.pyplot as plt; plt.close("all")
        """
        import matplotlib.pyplot as plt

        prefix = f"{label}: " if label else ""
        if energy:
            if ax is None:
                _, ax = plt.subplots(figsize=(8, 4.5), constrained_layout=True)
            for lab, series in (("T", self.T), ("V", self.V), ("T+V", self.E)):
                ax.plot(self.t, series, label=prefix + lab)
            ax.set_ylabel("energy (J)")
            ax.set_xlabel("t (s)")
            ax.grid(True, alpha=0.3)
            ax.legend()
            return ax
        chosen = list(names) or self.names[:PLOT_SERIES]
        groups: dict[str, list[str]] = {}
        for name in chosen:
            unit = coordinate_unit(name)
            groups.setdefault(f"{unit}/s" if velocity and unit else unit, []).append(name)
        what = "velocity" if velocity else "coordinate"
        if ax is not None or len(groups) == 1:
            if ax is None:
                _, ax = plt.subplots(figsize=(8, 4.5), constrained_layout=True)
            axes, panels = [ax], [(next(iter(groups)) if len(groups) == 1 else "", sum(groups.values(), []))]
        else:
            _, axes = plt.subplots(len(groups), 1, sharex=True, figsize=(8, 1.2 + 2.4 * len(groups)),
                                   constrained_layout=True)
            panels = list(groups.items())
        for axis, (unit, members) in zip(axes, panels):
            for name in members:
                series = self.velocity(name) if velocity else self[name]
                axis.plot(self.t, series, label=prefix + (f"d{name}/dt" if velocity else name))
            axis.set_ylabel(f"{what} ({unit})" if unit else what)
            axis.grid(True, alpha=0.3)
            legend(axis)
        if len(chosen) < len(self.names) and not names:
            axes[0].set_title(f"the first {len(chosen)} of {len(self.names)} coordinates: name others to draw them",
                              fontsize="small")
        axes[-1].set_xlabel("t (s)")
        return axes[0] if len(axes) == 1 else axes
