"""Compare a model with ngspice, quantity by quantity.

A circuit model is written as a netlist and run in ngspice as it is; a
mechanism is first mapped to its circuit analogue (force–voltage or
force–current) and the analogue is run, its quantities mapped back to the
mechanism's coordinates.  Both run on ngspice's own time points; the report
gives, per state quantity (capacitor voltages, inductor currents), the
maximum absolute error and the error relative to the signal's peak, both
wall times, and a chart of both responses and their difference.
"""

from __future__ import annotations

import time as _time
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..base import charts
from ..base import display
from ..errors import ModelError
from .analogy import map_model
from ..model import Model
from .spice import netlist, run_transient
from ..base import deferred as _deferred

sp = _deferred.module("sympy", globals())

__all__ = ["QuantityError", "Comparison", "compare_with_ngspice"]


@dataclass
class QuantityError:
    """Agreement on one quantity: ``label`` in the circuit, ``meaning`` in the model compared."""

    label: str
    meaning: str
    max_abs: float
    peak: float

    @property
    def max_rel(self) -> float:
        """Maximum absolute error relative to the peak of ngspice's signal."""
        return self.max_abs / self.peak if self.peak > 0 else float(self.max_abs > 0) * np.inf


@dataclass(repr=False)
class Comparison:
    """The outcome of :func:`compare_with_ngspice`; ``print(cmp.table())`` for the report."""

    model: str
    circuit: str
    netlist: str
    time: np.ndarray
    ours: dict[str, np.ndarray]
    spice: dict[str, np.ndarray]
    rows: list[QuantityError]
    ours_s: float
    codegen_s: float
    ngspice_s: float
    analogy: str | None = None
    meta: dict[str, Any] = field(default_factory=dict)
    #: how our solution was found: ``"exact"``, or the integration method
    method: str = ""

    @property
    def worst_rel(self) -> float:
        """The largest relative error over all quantities."""
        return max(r.max_rel for r in self.rows)

    def table(self) -> str:
        head = f"{self.model}" + (f" via its {self.analogy} analogue" if self.analogy else "") + f": {self.time.size} ngspice points"
        lines = [head, f"  {'quantity':24} {'meaning':28} {'max abs err':>12} {'rel to peak':>12}"]
        for r in self.rows:
            lines.append(f"  {r.label:24} {r.meaning[:28]:28} {r.max_abs:12.3e} {r.max_rel:12.3e}")
        setup = (f"+{self.codegen_s * 1e3:.0f} ms set-up: derivation, code generation, imports" if self.codegen_s >= 5e-4
                 else "no set-up: the derivation and code were already made in this process")
        lines.append(
            f"  wall time: ngspice {self.ngspice_s * 1e3:.1f} ms; ours"
            f"{f' ({self.method})' if self.method else ''} {self.ours_s * 1e3:.1f} ms ({setup})"
        )
        return "\n".join(lines)

    def __repr__(self) -> str:
        return (f"<Comparison of {self.model!r} with ngspice: {len(self.rows)} quantities, worst "
                f"{self.worst_rel:.2e} of peak over {self.time.size} points>")

    def _repr_html_(self) -> str:
        """The table and the chart (Jupyter)."""
        rows = [[r.label, r.meaning, f"{r.max_abs:.3e}", f"{r.max_rel:.3e}"] for r in self.rows]
        return display.block(self.table().splitlines()[0],
                             display.table(["quantity", "meaning", "max abs err", "rel to peak"], rows),
                             display.image(display.png(self._figure()), alt="ours against ngspice"),
                             note=self.table().splitlines()[-1].strip())

    def chart(self, path: str | Path) -> Path:
        """Write a PNG: each quantity's two responses overlaid, and their difference."""
        fig = self._figure()
        out = Path(path)
        out.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(out, dpi=110)
        return out

    @charts.plain
    def _figure(self):
        n = len(self.rows)
        fig = display.figure(figsize=(11, 2.4 * n + 0.8), layout="constrained")
        axes = fig.subplots(n, 2, squeeze=False)
        for (left, right), r in zip(axes, self.rows):
            left.plot(self.time, self.ours[r.label], lw=2.2, label="lagrangian")
            left.plot(self.time, self.spice[r.label], "--", lw=1.2, label="ngspice")
            left.set_ylabel(r.label)
            left.set_title(r.meaning, fontsize=9)
            left.grid(True, alpha=0.3)
            right.semilogy(self.time, np.maximum(np.abs(self.ours[r.label] - self.spice[r.label]), 1e-18), color="C3")
            right.set_title(f"|difference|, max {r.max_abs:.2e} ({r.max_rel:.1e} of peak)", fontsize=9)
            right.grid(True, which="both", alpha=0.3)
        axes[0][0].legend(loc="upper right", fontsize=8)
        axes[-1][0].set_xlabel("t")
        axes[-1][1].set_xlabel("t")
        fig.suptitle(self.table().splitlines()[0])
        return fig


def _plain(expr) -> str:
    """An expression of the coordinates in the notation of outputs: ``x_cart`` for ``x_cart(t)``, ``x_cart'`` for
    its rate.

    >>> x = sp.Function("x_cart")(sp.Symbol("t"))
    >>> _plain(-4.0 * x), _plain(x.diff(sp.Symbol("t")))
    ('-4.0*x_cart', "x_cart'")
    """
    expr = sp.sympify(expr)
    names = {}
    for d in expr.atoms(sp.Derivative):
        if isinstance(d.expr, sp.core.function.AppliedUndef) and len(d.variables) <= 2 and len(set(d.variables)) == 1:
            names[d] = sp.Symbol(d.expr.func.__name__ + "'" * len(d.variables))
    expr = expr.xreplace(names)
    return sp.sstr(expr.xreplace({f: sp.Symbol(f.func.__name__) for f in expr.atoms(sp.core.function.AppliedUndef)}))


def _state_scale(model: Model, res) -> np.ndarray:
    """Each state's peak over ``res`` (coordinates, then velocities of the inertial ones), as a scale for ``atol``.

    A state that stays at zero takes 1e-12 of the largest peak of its kind, so it does not ask for steps of round-off.
    """
    eq = model.eq
    q = np.array([np.max(np.abs(res.q[n])) for n in eq.names])
    v = np.array([np.max(np.abs(res.v[eq.names[i]])) for i in eq.inertial])
    floor = lambda x: np.maximum(x, 1e-12 * (np.max(x) if x.size and np.max(x) > 0 else 1.0))  # noqa: E731
    return np.concatenate([floor(q), floor(v)])


def _scaled_atol(model: Model, span, initial, velocity, params, t_eval, method) -> np.ndarray:
    """Each state's scale, from runs at ``rtol=1e-6``: the first with ``atol=1e-12``, again while a state's peak
    proves far smaller than the absolute tolerance it ran with (at most three runs)."""
    atol: Any = 1e-12
    for _ in range(3):
        res = model.simulate(span, initial=initial, velocity=velocity, params=params, t_eval=t_eval,
                             method=method, rtol=1e-6, atol=atol)
        scale = _state_scale(model, res)
        if np.all(1e-6 * scale >= 0.1 * np.asarray(atol)):
            break
        atol = 1e-6 * scale
    return scale


def compare_with_ngspice(
    model: Model,
    t_end: float,
    *,
    analogy: str | None = None,
    initial: Mapping[str, float] | None = None,
    velocity: Mapping[str, float] | None = None,
    params: Mapping[str, float] | None = None,
    step: float | None = None,
    max_step: float | None = None,
    method: str = "auto",
    rtol: float = 1e-11,
    atol: float | None = None,
) -> Comparison:
    """Simulate ``model`` and run it (or its ``analogy`` analogue) in ngspice; compare every state quantity.

    ``step`` is the output step of ngspice (default ``t_end/1000``) and
    ``max_step`` its step cap (default ``step/10``): ngspice's error follows
    the cap (about 0.3·h² for the trapezoidal rule), so choose it for the
    accuracy wanted.  Our solution: with ``method="auto"`` (default) a
    linear time-invariant model is solved exactly (matrix exponentials, at
    ngspice's uneven time points all at once: rounding error, where DOP853
    at ``rtol=1e-11`` drifts to 3e-7 of the peak over ngspice's 3e4 points),
    and anything else is integrated by the method ``Model.simulate`` picks;
    any other ``method`` integrates with ``rtol`` and ``atol``.
    ``atol=None`` (default) scales the absolute tolerance to each state: a
    first run at ``rtol=1e-6`` finds each state's peak, and the run compared
    takes ``atol = rtol × peak`` per state.  A fixed absolute tolerance is
    wrong for circuits, whose charges are often 1e-8 C or less: 1e-13 would
    be a relative error of 1e-5 there.
    """

    initial, velocity = dict(initial or {}), dict(velocity or {})
    domains = {d for c in model.components.values() for d in c.domains}
    spice_ready = all(hasattr(c, "spice") for c in model.components.values())
    if analogy is None and not spice_ready:
        raise ModelError(
            f"model {model.name!r} has components without a SPICE equivalent (domains: {', '.join(sorted(domains))}): "
            f"pass analogy='force-current' or analogy='force-voltage' to compare its circuit analogue."
        )
    mapped = map_model(model, analogy) if analogy is not None else None
    circuit = mapped.model if mapped else model
    if mapped:
        c_initial, c_velocity = mapped.initial(initial, velocity, params)
        # the analogue's elements carry the mechanism's symbols (L = m, C = 1/k, ...): the same values
        wanted = {s.name for s in circuit.parameters}
        c_params = {name: value for name, value in (params or {}).items() if name in wanted} or None
    else:
        c_initial, c_velocity, c_params = initial, velocity, params
    net = netlist(circuit, initial=c_initial, velocity=c_velocity, params=c_params, t_end=t_end, step=step, max_step=max_step)
    run = run_transient(net)

    start = _time.perf_counter()
    model.numeric(params)
    import scipy.integrate  # noqa: F401  (its first import is set-up, not integration)

    codegen = _time.perf_counter() - start
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        start = _time.perf_counter()
        # ngspice's last time point may pass t_end by a rounding: the span covers every point it returned
        end = max(float(t_end), float(run.time[-1])) if len(run.time) else float(t_end)
        res = None
        if method == "auto":
            try:
                res = model.simulate((0.0, end), initial=initial, velocity=velocity, params=params, t_eval=run.time,
                                     method="exact")
            except ModelError:  # not linear time-invariant, or inputs without an exact solution: integrated
                pass
        if res is None:
            if atol is None:
                atol = _scaled_atol(model, (0.0, end), initial, velocity, params, run.time, method) * rtol
            res = model.simulate((0.0, end), initial=initial, velocity=velocity, params=params,
                                 t_eval=run.time, method=method, rtol=rtol, atol=atol)
        ours_s = _time.perf_counter() - start
    ours, rows = {}, []
    for label, expr in net.quantities.items():
        target = mapped.to_source(expr) if mapped else expr
        ours[label] = res.quantity(target)
        spice = run.quantities[label]
        meaning = _plain(target) if mapped else label
        rows.append(QuantityError(label, meaning, float(np.max(np.abs(ours[label] - spice))), float(np.max(np.abs(spice)))))
    return Comparison(
        model=model.name,
        circuit=circuit.name,
        netlist=net.text,
        time=run.time,
        ours=ours,
        spice=run.quantities,
        rows=rows,
        ours_s=ours_s,
        codegen_s=codegen,
        ngspice_s=run.wall,
        analogy=analogy,
        method=res.method,
    )
