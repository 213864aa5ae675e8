"""What a scene plans and returns: the parts of its minimal model, the plan with its report, the result.

:class:`Part` is one independently simulated part of a scene's minimal model,
:class:`Offer` an approximate simplification offered (never applied),
:class:`ScenePlan` what the scene keeps, drops and eliminates with its report,
and :class:`SceneResult` the outputs on the requested times, each computed on
first access by the :class:`~lagrangian.scene.Scene` that made it.  The
measures the planner uses are here too: what coordinates are reachable
(:func:`_closure`), whether equations may be linear time-invariant
(:func:`_maybe_linear`), and what they cost to evaluate (:func:`_ops`).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field

import numpy as np

from ..base.component import t
from ..derivation.equations import Equations
from ..errors import ModelError, UnknownNameError
from ..model import Model
from ..base import display
from ..numerics.simulation import Result
from ..numerics.tape import size
from ..base import deferred as _deferred

sp = _deferred.module("sympy", globals())


@dataclass
class _Output:
    label: str
    expr: sp.Expr  # in the plain symbols of the full model
    depends: set[int]  # coordinate indices (positions or rates)
    meaning: str = ""  # what a branch output is, in words ("charge through C1 [C] ...")


@dataclass
class Part:
    """One independently simulated part of a scene's minimal model."""

    coordinates: list[str]  # full-model coordinates this part carries (integrated or not)
    integrated: list[str]  # coordinates actually integrated
    eliminated: list[str]  # ignorable coordinates eliminated through the Routhian
    reconstructed: list[str]  # eliminated ones recovered by quadrature (their values are requested)
    method: str  # "exact", "uniform", or the integrator's name
    why: str  # why this solver path
    model: Model = field(repr=False)
    operations: int = 0


@dataclass
class Offer:
    """An approximate simplification, offered, not applied."""

    component: str
    would_drop: list[str]
    estimated_error: float
    note: str


class Sizes(Mapping):
    """A model's sizes (``coordinates``, ``equations``, ``operations``), computed when first read: those of a whole
    model the scene pruned by its graph need its derivation, which the scene itself never needs."""

    def __init__(self, compute: Callable[[], dict[str, int]]):
        self._compute, self._sizes = compute, None

    def _get(self) -> dict[str, int]:
        if self._sizes is None:
            self._sizes = self._compute()
        return self._sizes

    def __getitem__(self, key: str) -> int:
        return self._get()[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self._get())

    def __len__(self) -> int:
        return len(self._get())

    def __repr__(self) -> str:
        return repr(self._get())


@dataclass
class ScenePlan:
    """What the scene keeps, drops, eliminates, and how it solves each part."""

    model: str
    outputs: list[str]
    parts: list[Part]
    kept: list[str]
    dropped: dict[str, str]
    held: dict[str, str]
    before: Mapping[str, int]  # the whole model's (a :class:`Sizes`: computed when read)
    after: dict[str, int]
    offers: list[Offer] = field(default_factory=list)
    unused: dict[str, str] = field(default_factory=dict)  # given initial values (``x``), velocities (``x'``), params: why not needed

    def report(self) -> str:
        """The plan as text: kept, dropped and why, eliminated coordinates, solver paths, sizes."""
        lines = [f"scene on model {self.model!r}: outputs {', '.join(self.outputs)}"]
        lines.append(f"  before: {self.before['coordinates']} coordinates, {self.before['equations']} equations, "
                     f"{self.before['operations']} operations")
        lines.append(f"  after:  {self.after['coordinates']} coordinates solved for, {self.after['equations']} equations, "
                     f"{self.after['operations']} operations, in {len(self.parts)} part(s)")
        for k, part in enumerate(self.parts, 1):
            lines.append(f"  part {k}: {', '.join(part.coordinates)} — {part.method} ({part.why})")
            if part.eliminated:
                lines.append(f"    eliminated through the Routhian: {', '.join(part.eliminated)}"
                             + (f"; reconstructed by quadrature: {', '.join(part.reconstructed)}" if part.reconstructed else ""))
        lines.append(f"  kept components: {', '.join(self.kept) if self.kept else '(none)'}")
        dropped: dict[str, list[str]] = {}  # one line per reason: a graph's pruning drops dozens alike
        for name, why in self.dropped.items():
            dropped.setdefault(why, []).append(name)
        for why, names in dropped.items():
            lines.append(f"  dropped {', '.join(map(repr, names))}: {why}")
        for name, why in self.held.items():
            lines.append(f"  held {name!r}: {why}")
        reasons: dict[str, list[str]] = {}
        for name, why in self.unused.items():
            reasons.setdefault(why, []).append(name)
        for why, given in reasons.items():
            lines.append(f"  given, not needed: {', '.join(given)} ({why})")
        for offer in self.offers:
            lines.append(f"  offered, not applied: drop {offer.component!r} (would remove {', '.join(offer.would_drop)}): "
                         f"{offer.note}; estimated change of the outputs {offer.estimated_error:.2e}")
        return "\n".join(lines)


class SceneResult:
    """The scene's outputs on the requested times, each computed on first access.

    ``res[label]`` is an output by the label it was requested with;
    ``res.parts`` are the parts' :class:`~lagrangian.Result` objects;
    ``res.t`` the time grid; ``res.computed`` the outputs computed so far.
    """

    # ``scene`` is the Scene of scene.py, which imports this module: the annotation stays a string
    def __init__(self, scene: "Scene", t: np.ndarray, parts: list[tuple[Part, Result]]):  # noqa: F821
        self.scene = scene
        self.t = t
        self.parts = parts
        self.computed: dict[str, np.ndarray] = {}

    def __getitem__(self, label: str) -> np.ndarray:
        if label not in self.computed:
            outputs = {o.label: o for o in self.scene._outputs}
            if label not in outputs:
                raise UnknownNameError("scene output", label, outputs)
            self.computed[label] = self.scene._evaluate(outputs[label].expr, self)
        return self.computed[label]

    @property
    def outputs(self) -> list[str]:
        return [o.label for o in self.scene._outputs]

    @property
    def meanings(self) -> dict[str, str]:
        """What each branch output is, by label (``"[C1]": "charge through C1 [C] (its voltage: v(C1))"``)."""
        return {o.label: o.meaning for o in self.scene._outputs if o.meaning}

    def as_dict(self) -> dict[str, np.ndarray]:
        """Every output (computing those not yet computed)."""
        return {label: self[label] for label in self.outputs}

    def __repr__(self) -> str:
        span = f"[{self.t[0]:g}, {self.t[-1]:g}]" if len(self.t) else "[]"
        return (f"<SceneResult of {self.scene.model.name!r}: outputs {display.short(self.outputs)}, {len(self.t)} "
                f"times over {span}, {len(self.parts)} part(s) run>")

    def _repr_html_(self) -> str:
        """The scene's report and a chart of its outputs (Jupyter)."""
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(7, 3.4), constrained_layout=True)
        for label in self.outputs[:8]:
            ax.plot(self.t, self[label], label=label)
        ax.set_xlabel("t")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
        return display.block(f"scene of {self.scene.model.name}", f"<pre>{display.escape(self.scene.report())}</pre>",
                             display.image(display.png(fig), alt="scene outputs"))


def _closure(start, neighbours) -> set[int]:
    """Everything reachable from ``start`` through ``neighbours(i)``."""
    seen, stack = set(), list(start)
    while stack:
        i = stack.pop()
        if i not in seen:
            seen.add(i)
            stack.extend(neighbours(i) - seen)
    return seen


def _maybe_linear(eq: Equations) -> bool:
    """False when the equations are plainly not linear time-invariant (state or time in ``A``, ``b`` not
    polynomial in the state); True means "ask :func:`lagrangian.linear.state_space`".  Read on the generic
    equations (the structure, as the compiled run takes it: putting the values in walks every entry)."""
    g = eq.generic()
    state = set(eq.sym.q) | set(eq.sym.v)
    if any(e.free_symbols & (state | {t}) for e in g["A"]):
        return False
    return all(e.is_polynomial(*state) for e in g["b"])


def _rows(eq: Equations) -> int:
    """The equations of the solve ``A u = b``: counted on the generic ``A`` where it is made (the one with the
    values in is put together only when read, a matrix of large sums for a spatial chain)."""
    g = eq.generic()
    return g["A"].shape[0] if "A" in g else eq.A.shape[0]


def _ops(eq: Equations) -> int:
    """Operations to evaluate ``A`` and ``b`` once, every common subexpression once (the size of their tape), counted
    on the generic equations: a model given numbers weighs as its symbolic twin does (counted once per
    equations: a plan weighs a part, then reports it)."""
    made = eq.__dict__.get("_tape_size")
    if made is None:
        g = eq.generic()
        made = eq.__dict__["_tape_size"] = size(list(g["A"]) + list(g["b"]))
    return made


def _with_values(eq: Equations, params: dict, expr: sp.Expr) -> sp.Expr:
    """``expr`` with the values of its symbolic parameters from ``params`` (those of other parts not needed)."""
    inner = set(eq.sym.q) | set(eq.sym.v) | {t}
    free = sorted(expr.free_symbols - inner, key=str)
    missing = sorted({s.name for s in free if s.name not in params})
    if missing:
        raise ModelError(f"the outputs need values of the symbolic parameters {', '.join(missing)}: pass them, "
                         f"e.g. Scene(..., params={{{', '.join(f'{k!r}: ...' for k in missing)}}}).")
    return expr.xreplace({s: sp.Float(float(params[s.name])) for s in free})
