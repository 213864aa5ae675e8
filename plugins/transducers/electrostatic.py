"""Electrostatic actuators (a variable capacitor's plate on a spring): :func:`electrostatic_equilibria` (the
equilibria at a DC voltage, their stability, the pull-in point) and :func:`simulate_checked` (a simulation that
stops with :class:`GapClosedError` when a plate reaches its electrode)."""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

import lagrangian as lg
from lagrangian import ModelError
from lagrangian.base.component import t

from .components import VariableCapacitor
from .errors import GapClosedError, PullInError
from lagrangian.base import deferred as _deferred

sp = _deferred.module("sympy", globals())


@dataclass(frozen=True)
class Equilibrium:
    """One equilibrium of a plate: its displacement ``x``, whether it is stable, and the net stiffness U''(x)."""

    x: float
    stable: bool
    stiffness: float


@dataclass
class ElectrostaticEquilibria:
    """Equilibria of a variable capacitor's plate at a DC voltage (from :func:`electrostatic_equilibria`).

    ``equilibria`` lists every equilibrium with ``x < gap``, sorted by x;
    ``pull_in_voltage`` and ``pull_in_displacement`` are where the stable
    branch ends.  ``position`` is the stable equilibrium, or a
    :class:`PullInError` when there is none; ``str()`` says which.
    """

    component: str
    coordinate: str
    voltage: float
    gap: float
    pull_in_voltage: float
    pull_in_displacement: float
    equilibria: list[Equilibrium] = field(default_factory=list)

    @property
    def stable(self) -> list[Equilibrium]:
        """The stable equilibria (U'' > 0)."""
        return [e for e in self.equilibria if e.stable]

    @property
    def position(self) -> float:
        """The stable equilibrium displacement; :class:`PullInError` past pull-in."""
        if not self.stable:
            raise PullInError(self._no_equilibrium())
        return min(self.stable, key=lambda e: abs(e.x - self.pull_in_displacement)).x

    def _no_equilibrium(self) -> str:
        return (
            f"variable_capacitor {self.component!r}: no stable equilibrium at V = {self.voltage:.6g} V "
            f"(|V| > V_pull-in = {self.pull_in_voltage:.6g} V): the electrostatic force beats the restoring force "
            f"everywhere past x = {self.pull_in_displacement:.6g} m and the plate snaps onto the electrode "
            f"(gap {self.gap:.6g} m). Keep |V| below the pull-in voltage."
        )

    def __str__(self) -> str:
        if not self.stable:
            return self._no_equilibrium()
        listed = ", ".join(f"x = {e.x:.6g} m ({'stable' if e.stable else 'unstable'})" for e in self.equilibria)
        return (
            f"variable_capacitor {self.component!r} at V = {self.voltage:.6g} V: {listed}; "
            f"pull-in at V = {self.pull_in_voltage:.6g} V, x = {self.pull_in_displacement:.6g} m"
        )


def electrostatic_equilibria(
    model: lg.Model, capacitor: str, voltage: float, *, params: Mapping[str, float] | None = None
) -> ElectrostaticEquilibria:
    """Equilibria of the plate of ``capacitor`` held at the DC ``voltage``, their stability, and the pull-in point.

    At rest the plate feels the restoring force of the model's mechanical
    potential ``V_m(x)`` (springs, gravity, any single-domain mechanical
    component) and the electrostatic pull ``½ V² C'(x)``; its equilibria are
    the stationary points of ``U(x) = V_m(x) − ½ V² C(x)`` with ``x < gap``
    (stable where ``U'' > 0``).  The voltage that holds the plate at ``x`` is
    ``V(x)² = 2 V_m'(x) / C'(x)``; going from the rest position towards the
    electrode it rises to a maximum, the pull-in point, past which no stable
    equilibrium exists.  All of this is numerical (root finding on a fine grid,
    refined by Brent's method); the mechanical part must have one
    coordinate, the plate's.  ``params`` gives values to symbolic parameters.

    >>> import lagrangian as lg
    >>> m = lg.Model("actuator")
    >>> _ = m.add("voltage_source", "E", ("n1", "0"), E=0.5)
    >>> _ = m.add("resistor", "R", ("n1", "n2"), R=1)
    >>> _ = m.add("variable_capacitor", "C", ("n2", "0", "plate"), eps_A=1, gap=1)
    >>> _ = m.add("mass", "m", "plate", m=1)
    >>> _ = m.add("spring", "k", ("ground", "plate"), k=1)
    >>> eq = electrostatic_equilibria(m, "C", 0.5)
    >>> round(eq.pull_in_voltage, 6), round((8 / 27) ** 0.5, 6), round(eq.pull_in_displacement, 6)
    (0.544331, 0.544331, 0.333333)
    >>> electrostatic_equilibria(m, "C", 0.6).position
    Traceback (most recent call last):
    ...
    lagrangian.plugins.transducers.PullInError: variable_capacitor 'C': no stable equilibrium at V = 0.6 V (|V| > V_pull-in = 0.544331 V): ...
    """
    from scipy.optimize import brentq, minimize_scalar

    comp = model.component(capacitor)
    if comp.kind != VariableCapacitor.kind:
        raise ModelError(f"component {capacitor!r} is a {comp.kind}, not a variable_capacitor.")
    try:
        voltage = abs(float(voltage))
    except (TypeError, ValueError):
        raise ModelError(f"the voltage must be a number, got {voltage!r}.") from None
    eq = model.eq
    mech = [c.name for c in model.assembly.views["mechanical"].coordinates]
    x_name = f"x_{comp.nodes[-1]}"
    if mech != [x_name]:
        raise ModelError(
            f"electrostatic_equilibria needs a model whose mechanical part has one coordinate, the plate's "
            f"({x_name}); this model's mechanical coordinates are {', '.join(mech) or 'none'}."
        )
    xs = eq.sym.q[eq.names.index(x_name)]
    Vm = sp.Add(
        *(eq.symbolic(c.V) for name, c in model.assembly.contributions.items() if model.component(name).domains == ("mechanical",))
    )
    values = _parameter_values(model, [Vm, comp.eps_A, comp.gap], {xs}, params or {})
    Vm, eps_A, gap = (sp.sympify(e).xreplace(values) for e in (Vm, comp.eps_A, comp.gap))
    if t in Vm.free_symbols:
        raise ModelError("electrostatic_equilibria needs a time-independent mechanical potential (no prescribed motion).")
    eps_A, gap = float(eps_A), float(gap)
    dV = sp.lambdify(xs, sp.diff(Vm, xs), "numpy")
    d2V = sp.lambdify(xs, sp.diff(Vm, xs, 2), "numpy")

    def dU(x, V):  # U'(x) = V_m'(x) − ½ V² C'(x), C'(x) = eps_A / (gap − x)²
        return dV(x) + 0 * x - V**2 * eps_A / (2 * (gap - x) ** 2)

    def d2U(x, V):
        return d2V(x) + 0 * x - V**2 * eps_A / (gap - x) ** 3

    s = np.geomspace(1e-9 * gap, 1e3 * gap, 20001)[::-1]  # distance to the electrode, large to small
    grid = gap - s  # ascending, all below gap

    def equilibria(V: float) -> list[Equilibrium]:
        values = dU(grid, V)
        out = []
        for i in np.flatnonzero(np.sign(values[:-1]) * np.sign(values[1:]) < 0):
            x = brentq(dU, grid[i], grid[i + 1], args=(V,), xtol=1e-14 * gap, rtol=1e-14)
            k = float(d2U(x, V))
            out.append(Equilibrium(float(x), k > 0, k))
        for i in np.flatnonzero(values == 0):
            out.append(Equilibrium(float(grid[i]), float(d2U(grid[i], V)) > 0, float(d2U(grid[i], V))))
        return sorted(out, key=lambda e: e.x)

    rest = [e for e in equilibria(0.0) if e.stable]
    if not rest:
        raise ModelError(
            f"variable_capacitor {capacitor!r}: the plate has no stable rest position even at zero voltage "
            f"(within {1e3 * gap:g} m of the electrode); hold it with a spring."
        )
    x_rest = rest[-1].x  # the rest position nearest the electrode

    def held(x):  # V(x)² that holds the plate at x
        return 2 * dV(x) * (gap - x) ** 2 / eps_A

    branch = grid[grid > x_rest]
    v2 = held(branch) + 0 * branch
    falling = np.flatnonzero(np.diff(v2) < 0)
    i = int(falling[0]) if falling.size else len(branch) - 1
    lo, hi = branch[max(i - 1, 0)], branch[min(i + 1, len(branch) - 1)]
    def slope(x):  # d/dx of V(x)² · eps_A / 2 = V_m''(x) (gap − x)² − 2 V_m'(x) (gap − x), divided by (gap − x)
        return d2V(x) * (gap - x) - 2 * dV(x)

    if slope(lo) > 0 > slope(hi):
        x_pi = float(brentq(slope, lo, hi, xtol=1e-15 * gap, rtol=1e-15))
    else:  # a maximum on the grid's edge, or a flat one: maximize directly
        x_pi = float(minimize_scalar(lambda x: -held(x), bounds=(lo, hi), method="bounded", options={"xatol": 1e-13 * gap}).x)
    v_pi = math.sqrt(max(float(held(x_pi)), 0.0))
    return ElectrostaticEquilibria(capacitor, x_name, voltage, gap, v_pi, x_pi, equilibria(voltage))


def _parameter_values(model: lg.Model, exprs, inner: set, params: Mapping[str, float]) -> dict:
    """Numeric values for the symbolic parameters of ``exprs`` (by name, from ``params``)."""
    free = set().union(*(sp.sympify(e).free_symbols for e in exprs)) - inner - {t}
    missing = sorted({s.name for s in free if s.name not in params})
    if missing:
        raise ModelError(
            f"model {model.name!r} has symbolic parameters without values: {', '.join(missing)}; pass params={{...}}."
        )
    return {s: sp.Float(float(params[s.name])) for s in free}


def simulate_checked(model: lg.Model, t_end: float = 10.0, **kwargs: Any) -> lg.Result:
    """``model.simulate(t_end, **kwargs)``, stopped with :class:`GapClosedError` if a plate reaches its electrode.

    A variable capacitor's model holds only while ``x < gap``; past contact
    (pull-in, or an overshoot) the charge formulation would integrate on
    through a negative gap and the flux formulation meets a singular mass
    matrix.  This runs the simulation, and if any plate reaches its
    electrode (or the integrator fails), integrates again with a terminal
    event at ``x = gap`` to report exactly when: a :class:`GapClosedError`
    (a :class:`lagrangian.NumericalError`) naming the capacitor.  Otherwise
    it returns the :class:`lagrangian.Result` unchanged.
    """
    guards = _gap_guards(model, kwargs.get("params") or {})
    initial = kwargs.get("initial") or {}
    for comp, name, gap in guards:
        if float(initial.get(name, 0.0)) >= gap:
            raise GapClosedError(
                comp.name,
                0.0,
                f"variable_capacitor {comp.name!r}: the plate starts at {name} = {initial[name]} ≥ gap = {gap:g}; "
                f"start it in front of the electrode.",
            )
    try:
        res = model.simulate(t_end, **kwargs)
    except lg.IntegrationError as exc:
        _locate_contact(model, guards, t_end, kwargs, exc)
        raise
    if any(np.any(res[name] >= gap) for _, name, gap in guards):
        _locate_contact(model, guards, t_end, kwargs, None)
    return res


def _gap_guards(model: lg.Model, params: Mapping[str, float]) -> list[tuple[VariableCapacitor, str, float]]:
    guards = []
    for comp in model.components.values():
        if comp.kind == VariableCapacitor.kind:
            name = f"x_{comp.nodes[-1]}"
            if name not in model.coordinate_names:
                continue  # a plate on a prescribed motion: nothing to guard
            gap = sp.sympify(comp.gap).xreplace(_parameter_values(model, [comp.gap], set(), params))
            guards.append((comp, name, float(gap)))
    return guards


def _locate_contact(model, guards, t_end, kwargs, cause) -> None:
    """Integrate with a terminal event at each plate's contact; raise GapClosedError at the first one."""
    from scipy.integrate import solve_ivp

    from lagrangian.simulation import initial_state

    if not guards:
        return
    numeric = model.numeric(kwargs.get("params"))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lg.InitialConditionWarning)
        y0, _ = initial_state(model.eq, kwargs.get("initial") or {}, kwargs.get("velocity") or {})
    names = model.eq.names
    events = []
    for _, name, gap in guards:
        idx = names.index(name)

        def event(time, y, idx=idx, gap=gap):
            return gap - y[idx]

        event.terminal, event.direction = True, -1
        events.append(event)
    span = (0.0, float(t_end)) if np.isscalar(t_end) else tuple(map(float, t_end))

    def rhs(time, y):
        with np.errstate(all="ignore"):
            return numeric.rhs(time, y)

    try:
        sol = solve_ivp(
            rhs, span, y0, method=kwargs.get("method", "DOP853"), events=events,
            rtol=kwargs.get("rtol", 1e-9), atol=kwargs.get("atol", 1e-12), max_step=kwargs.get("max_step", np.inf),
        )
    except (lg.LagrangianError, ArithmeticError, ValueError):
        return
    hits = [(te[0], g) for te, g in zip(sol.t_events or [], guards) if len(te)]
    if not hits:
        return
    time, (comp, name, gap) = min(hits, key=lambda h: h[0])
    raise GapClosedError(
        comp.name,
        float(time),
        f"variable_capacitor {comp.name!r}: the plate reached the fixed electrode at t = {time:.6g} "
        f"({name} = gap = {gap:g}): the gap closed and C → ∞, so the model does not hold past this instant. "
        f"The voltage exceeds the pull-in voltage, or the plate overshot; lower the voltage, or add damping or a stop.",
    ) from cause
