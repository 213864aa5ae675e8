"""Compare a model's frequency response with ngspice's AC analysis.

The circuit is written as a SPICE netlist (:func:`lagrangian.spice.netlist`),
its input source given ``AC 1`` and its operating value as ``DC``, and run
with ``.ac dec`` in ngspice through PySpice.  Ours is the exact Laplace-domain
response of the model linearized about the same point
(:func:`lagrangian.frequency.frequency_response`), evaluated at ngspice's own
frequencies.  Both are exact linear algebra, so they agree to rounding: the
report gives per output the largest relative difference of the complex
responses (relative to the response, or to :data:`FLOOR` of its peak in a
stop band deeper than that), and of magnitude (dB) and phase (degrees)
where the response is above that floor, and both wall times;
:meth:`ACComparison.chart` draws both responses with their difference
underneath.

>>> import lagrangian as lg
>>> m = lg.Model("rc")
>>> _ = m.add("voltage_source", "V1", ("in", "0"), E=0)
>>> _ = m.add("resistor", "R1", ("in", "out"), R=2.2e3)
>>> _ = m.add("capacitor", "C1", ("out", "0"), C=47e-9)
>>> cmp = compare_ac_with_ngspice(m, input="V1", start=10, stop=1e6, points=10)   # doctest: +SKIP
>>> cmp.worst_rel < 1e-9                                                          # doctest: +SKIP
True
"""

from __future__ import annotations

import time as _time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..base import charts
from ..analysis.frequency import frequency_response, sweep_size
from ..base import display
from ..base.component import t
from ..errors import ModelError
from ..model import Model
from .analogy import Mapped, map_model
from .netlist import ImportedNetlist
from .spice import _fmt, netlist, run_ac
from ..base import deferred as _deferred

sp = _deferred.module("sympy", globals())

__all__ = ["ACComparison", "OutputError", "compare_ac_with_ngspice"]

#: Differences are relative to the response, or to this fraction of its peak where the response is smaller.
FLOOR = 1e-12


@dataclass
class OutputError:
    """Agreement on one output: the largest relative difference of the complex responses, of their magnitudes
    (dB) and of their phases (degrees)."""

    label: str
    max_rel: float
    max_db: float
    max_deg: float


@dataclass
class ACComparison:
    """The outcome of :func:`compare_ac_with_ngspice`; ``print(cmp.table())`` for the report."""

    model: str
    input: str
    netlist: str
    frequencies: np.ndarray
    ours: dict[str, np.ndarray]
    spice: dict[str, np.ndarray]
    rows: list[OutputError]
    ours_s: float
    ngspice_s: float
    notes: list[str] = field(default_factory=list)
    #: seconds ngspice took to load the deck, before its analysis (``ngspice_s``)
    ngspice_load_s: float = 0.0
    #: seconds reading ngspice's output vectors into arrays, after its analysis
    ngspice_read_s: float = 0.0

    @property
    def worst_rel(self) -> float:
        """The largest relative difference over all outputs."""
        return max(r.max_rel for r in self.rows)

    def table(self) -> str:
        f = self.frequencies
        lines = [f"{self.model}: response to {self.input}, {f.size} frequencies {f[0]:g}–{f[-1]:g} Hz",
                 f"  {'output':16} {'max rel diff':>13} {'max |dB| diff':>14} {'max phase diff (°)':>19}"]
        for r in self.rows:
            lines.append(f"  {r.label:16} {r.max_rel:13.3e} {r.max_db:14.3e} {r.max_deg:19.3e}")
        lines.append(f"  wall time: ngspice {self.ngspice_s * 1e3:.1f} ms (+{self.ngspice_load_s * 1e3:.1f} ms loading "
                     f"the deck, +{self.ngspice_read_s * 1e3:.1f} ms reading its vectors); ours "
                     f"{self.ours_s * 1e3:.1f} ms (derived, linearized and solved)")
        return "\n".join(lines)

    @charts.plain
    def chart(self, path: str | Path) -> Path:
        """Write a PNG: each output's two magnitude responses overlaid, their relative difference underneath."""
        n = len(self.rows)
        fig = display.figure(figsize=(4.2 * n + 1, 6), layout="constrained")
        axes = fig.subplots(2, n, squeeze=False, sharex=True)
        for k, r in enumerate(self.rows):
            top, bottom = axes[0][k], axes[1][k]
            with np.errstate(divide="ignore"):
                top.semilogx(self.frequencies, 20 * np.log10(np.abs(self.ours[r.label])), lw=2.2, label="lagrangian")
                top.semilogx(self.frequencies, 20 * np.log10(np.abs(self.spice[r.label])), "--", lw=1.2, label="ngspice")
            top.set_title(f"{r.label} / {self.input}", fontsize=9)
            top.set_ylabel("|H| (dB)")
            top.grid(True, which="both", alpha=0.3)
            diff = np.abs(self.ours[r.label] - self.spice[r.label]) / np.maximum(np.abs(self.spice[r.label]), 1e-300)
            bottom.loglog(self.frequencies, np.maximum(diff, 1e-18), color="C3")
            bottom.set_title(f"relative difference, max {r.max_rel:.1e}", fontsize=9)
            bottom.set_xlabel("frequency (Hz)")
            bottom.grid(True, which="both", alpha=0.3)
        axes[0][0].legend(fontsize=8)
        fig.suptitle(self.table().splitlines()[0])
        out = Path(path)
        out.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(out, dpi=110)
        return out


def compare_ac_with_ngspice(system: Model | ImportedNetlist, *, input: str | None = None,
                            outputs: Sequence[str] | None = None, start: float | None = None,
                            stop: float | None = None, points: int | None = None, sweep: str | None = None,
                            params: Mapping[str, float] | None = None,
                            at: Mapping[str, float] | None = None, analogy: str | None = None) -> ACComparison:
    """Run ngspice's ``.ac sweep points start stop`` on a model or an imported netlist driven at ``input``;
    compare with ours.

    ``sweep`` is ``"dec"`` (default), ``"oct"`` or ``"lin"``; ``start`` and
    ``stop`` in Hz (default 1 Hz to 1 MHz), ``points`` per decade or octave,
    or in all (default 20).  An imported netlist gives its own: its ``.ac``
    line and its one AC source.  ``outputs`` are ``"v(X)"`` (any
    two-terminal element), ``"v(node)"`` (a node's voltage) and ``"i(X)"``
    (inductors and voltage sources, whose currents ngspice reports); every
    capacitor voltage and inductor current by default.  ``params`` gives
    symbolic parameters their values; ``at`` the operating point (coordinate
    values) for a model that is not linear.  ``analogy`` (``"force-voltage"``
    or ``"force-current"``) runs a mechanism's circuit analogue in ngspice,
    driven by the element its ``input`` (a force, a prescribed motion) maps
    to, and compares each of the analogue's state quantities with what it
    means in the mechanism (a current with a velocity, for force–voltage),
    from the mechanism's own linearization.  The circuit of an
    electromechanical model (a loudspeaker's voice coil) is kept as it is in
    the analogue, so a source of it drives both sides alike.  A prescribed
    motion becomes a source of its rate, so ``AC 1`` there is a motion of
    ``1/(jω)``, and only the quantities that stand for rates (the
    velocities) compare: the others depend on the motion itself.
    """
    model = system.model if isinstance(system, ImportedNetlist) else system
    mapped = None
    if analogy is not None:  # the mechanism's analogue runs in ngspice; ours is the mechanism's own response
        if isinstance(system, ImportedNetlist):
            raise ModelError("an imported netlist is a circuit already: compare it without analogy=.")
        mapped = map_model(model, analogy)
        if mapped.direction == "inverse":
            raise ModelError(f"model {model.name!r} is a circuit already (its {analogy} analogue is a "
                             f"{mapped.analogy.source} model, which ngspice does not run): compare it without analogy=.")
    if isinstance(system, ImportedNetlist):
        if input is None:
            if len(system.ac_sources) != 1:
                raise ModelError(f"netlist {system.title!r} has {len(system.ac_sources)} AC sources "
                                 f"({', '.join(system.ac_sources) or 'none'}): name the input, input='V1'.")
            input = next(iter(system.ac_sources))
        if system.ac is not None:
            sweep = sweep or system.ac.kind
            start = system.ac.start if start is None else start
            stop = system.ac.stop if stop is None else stop
            points = system.ac.points if points is None else points
    if input is None:
        raise ModelError("name the input source of the AC comparison: input='V1'.")
    sweep = sweep or "dec"
    start = 1.0 if start is None else start
    stop = 1e6 if stop is None else stop
    points = 20 if points is None else points
    if sweep not in ("dec", "oct", "lin"):
        raise ModelError(f"sweep is 'dec', 'oct' or 'lin', not {sweep!r}.")
    source = input
    if mapped is not None:
        model.component(input)
        analogues = [name for name, origin in mapped.origin.items() if origin == input]
        if len(analogues) != 1:
            raise ModelError(f"{input!r} has {len(analogues)} elements in the {analogy} analogue; drive one source.")
        circuit, input = mapped.model, analogues[0]
    else:
        circuit = model
    moved = mapped is not None and _prescribed_motion(mapped, model.component(source))
    comp = circuit.component(input)
    if comp.kind not in ("voltage_source", "current_source"):
        what = (f"{source!r} is a {comp.kind}" if input == source else
                f"{model.component(source).kind} {source!r} maps to {comp.kind} {input!r}")
        raise ModelError(f"the input of an AC comparison is a voltage or current source (or, with analogy=, a force or "
                         f"prescribed motion that maps to one); {what}.")
    for name, value in (("start", start), ("stop", stop)):
        if not isinstance(value, (int, float)) or not np.isfinite(value) or value <= 0:
            raise ModelError(f"{name} must be a positive frequency in Hz, got {value!r}.")
    if not start < stop or not isinstance(points, int) or isinstance(points, bool) or points < 1:
        raise ModelError(f"need start < stop and a whole number of points ≥ 1, got {start!r}, {stop!r}, {points!r}.")
    sweep_size(sweep, points, start, stop)  # ngspice would make the grid too: refused here when beyond the bound
    net = netlist(circuit, params=params, t_end=1.0)
    element = next(name for name, owner in net.elements.items() if owner == input)
    subs = {sym: sp.Float(v) for sym, v in circuit._values(params or {}).items()}
    signal = comp.params["E" if comp.kind == "voltage_source" else "I"]
    try:
        dc = float(sp.sympify(signal, strict=True).xreplace({t: 0}).xreplace(subs))
    except (TypeError, sp.SympifyError):
        raise ModelError(f"source {input!r}: its value at t = 0 is not a number; give it as a number or an "
                         f"expression of t.") from None
    lines = []
    for line in net.text.splitlines():
        head = line.split()
        if head and head[0] == element:
            line = f"{head[0]} {head[1]} {head[2]} DC {_fmt(dc)} AC 1"
        elif line.startswith(".tran"):
            line = f".ac {sweep} {points} {_fmt(float(start))} {_fmt(float(stop))}"
        lines.append(line)
    labels = list(outputs) if outputs is not None else [k for k in net.probes if "." not in k]
    probes = {label: _probe(circuit, net, label) for label in labels}
    run = run_ac("\n".join(lines), probes)
    if mapped is not None:  # each analogue quantity means an expression of the mechanism's coordinates
        unknown = [label for label in labels if label not in net.quantities]
        if unknown:
            raise ModelError(f"with analogy=, compare the analogue's state quantities ({', '.join(net.quantities)}); "
                             f"{unknown[0]!r} is not one.")
        meaning = [mapped.to_source(net.quantities[label]) for label in labels]
        if moved:
            # the analogue was built with the motion at its value; what a spring's force owes to the motion itself
            # is not in its meaning, so only rates (velocities) compare
            coordinates = {c.function for c in model.coordinates}
            rates = [not any(f in coordinates for f in e.xreplace({d: sp.Dummy() for d in e.atoms(sp.Derivative)})
                             .atoms(sp.core.function.AppliedUndef)) for e in meaning]
            if outputs is None:
                labels = [label for label, ok in zip(labels, rates) if ok]
                meaning = [e for e, ok in zip(meaning, rates) if ok]
            elif not all(rates):
                bad = [label for label, ok in zip(labels, rates) if not ok]
                raise ModelError(f"driven by the prescribed motion {source!r}, the analogue's {', '.join(bad)} stand for "
                                 f"forces or displacements that depend on the motion itself; compare its velocities "
                                 f"(the inductor currents or capacitor voltages of masses).")
            run.quantities = {label: run.quantities[label] for label in labels}
    began = _time.perf_counter()
    resp = frequency_response(model, run.time, inputs=[source], outputs=meaning if mapped else labels, params=params,
                              at=at)
    ours_s = _time.perf_counter() - began
    ours = {label: resp[out] for label, out in zip(labels, resp.outputs)}
    if moved:
        # a prescribed motion becomes a source of its rate (velocity ↔ current or voltage): AC 1 there is a motion 1/s
        ours = {label: h / (2j * np.pi * run.time) for label, h in ours.items()}
    rows = []
    for label in labels:
        a, b = ours[label], run.quantities[label]
        # relative to the response's own size, but not below FLOOR of its peak: where the response is that far
        # down (a deep stop band), both sides' rounding is relative to the peak
        floor = FLOOR * np.max(np.abs(b), initial=0.0)
        seen = np.abs(b) > floor
        with np.errstate(divide="ignore", invalid="ignore"):
            rel = np.abs(a - b) / np.maximum(np.abs(b), floor)
            db = np.abs(20 * np.log10(np.abs(a[seen]) / np.abs(b[seen])))
            deg = np.abs(np.degrees(np.angle(a[seen] / b[seen])))
        rows.append(OutputError(label, float(np.nanmax(rel, initial=0.0)), float(np.nanmax(db, initial=0.0)),
                                float(np.nanmax(deg, initial=0.0))))
    return ACComparison(model.name, source, "\n".join(lines), run.time, ours, run.quantities, rows, ours_s, run.wall,
                        list(resp.notes), run.load, run.read)


def _prescribed_motion(mapped: Mapped, comp) -> bool:
    """Whether source ``comp`` of the mapped model is a prescribed motion: an across source mapped through the analogy
    (its analogue a source of the motion's rate), not a source of the domain the analogy maps to, which the analogue
    keeps as it is (the voltage source of a loudspeaker's coil under the force–voltage analogy)."""
    return comp.role == "across" and set(comp.domains) != {mapped.analogy.target}


def _probe(model: Model, net, label: str) -> tuple[str, ...]:
    """The ngspice vector(s) of an output ``v(X)`` or ``i(X)``."""
    label = str(label).strip()
    if len(label) < 4 or label[1] != "(" or label[-1] != ")" or label[0] not in "vi":
        raise ModelError(f"an AC comparison's outputs are 'v(X)' or 'i(X)' of a component X, or 'v(node)'; "
                         f"got {label!r}.")
    name = label[2:-1]
    if label[0] == "v" and name not in model.components and name in net.nodes:
        return ("v", net.nodes[name])
    comp = model.component(name)
    if len(comp.nodes) != 2:
        raise ModelError(f"{comp.kind} {comp.name!r} has {len(comp.nodes)} terminals; compare a two-terminal element.")
    if label[0] == "v":
        return ("v", *(net.nodes[n] for n in comp.nodes))
    element = [name for name, owner in net.elements.items() if owner == comp.name]
    if comp.kind not in ("inductor", "voltage_source") or len(element) != 1:
        raise ModelError(f"ngspice reports the currents of inductors and voltage sources; {comp.name!r} is a "
                         f"{comp.kind}: compare its voltage, v({comp.name}).")
    return ("i", element[0])
