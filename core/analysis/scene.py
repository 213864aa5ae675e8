"""Scenes: a model with the question asked of it, answered by the smallest exact model.

A :class:`Scene` takes a model, the outputs wanted (coordinates, rates,
energies, a component's energy or branch quantity, any expression), the time
span and the tolerance.  Planning it builds the minimal model — every step
exact, none an approximation:

1. **pruning**: a coordinate is kept only if a requested output depends on
   it, or the equations of a kept coordinate do (its position, rate or
   acceleration appear there, or a loop constraint ties them); the rest —
   disconnected parts, parts cut off by a prescribed motion, parts only
   driven by the kept ones — is dropped.  Kept coordinates that do not
   influence each other form separate *parts*, simulated separately.  A
   model of point masses or of rotors on one axis whose outputs are
   coordinates is pruned by its component graph first, before anything is
   derived
   (:mod:`~lagrangian.analysis.scene_graph`): ``scene.model`` is then the
   part the outputs reach, ``scene.full_model`` the one given, and the
   report's sizes of the whole model are derived only when read.
2. **reduction**: in each part, ignorable coordinates (see
   :mod:`lagrangian.routh`) are eliminated through the Routhian and never
   integrated, their momenta taken from the initial state; those whose
   values are requested are reconstructed by quadrature, those whose rates
   are requested are evaluated from ``∂R/∂C``; a part whose coordinates are
   all ignorable moves uniformly and is solved in closed form.
3. **constants and trivial parts**: coordinates held by prescribed motions or
   driven joints are functions of time already (the report lists them);
   components that contribute nothing (a zero parameter) are dropped with a
   note.
4. **linear parts**: a part that is linear time-invariant is solved exactly
   by the matrix exponential; the others by a general integrator.
5. **lazy outputs**: each output is computed from the parts' solutions only
   when asked for, and only on the requested times.

Where a simplification would be approximate — a weak coupling that could be
cut — it is *offered* in the report with its estimated effect, never applied.

>>> import sympy as sp, lagrangian as lg
>>> m = lg.Model("two oscillators on one shaker")
>>> _ = m.add("prescribed_motion", "shaker", "s", position=sp.sin(3 * lg.t) / 100)
>>> for i in (1, 2):
...     _ = m.add("mass", f"m{i}", f"p{i}", m=1)
...     _ = m.add("spring", f"k{i}", ("s", f"p{i}"), k=4 * i)
>>> start = dict(initial={"x_p1": 0.01, "x_p2": 0}, velocity={"x_p1": 0, "x_p2": 0})
>>> scene = Scene(m, ["x_p1"], t_end=2, **start)
>>> [part.coordinates for part in scene.plan.parts]
[['x_p1']]
>>> scene.plan.dropped["m2"]  # found in the graph: the shaker's node passes nothing from p2's spring to p1's
"joins only nodes the outputs' nodes do not reach (ground and nodes whose motion is prescribed pass nothing on)"
>>> scene.plan.unused  # the full state was given: what the minimal model did not need
{'x_p2': 'coordinates the outputs do not depend on', "x_p2'": 'coordinates the outputs do not depend on'}
>>> res = scene.run()
>>> abs(float(res["x_p1"][-1]) - float(m.simulate(2, rtol=1e-12, atol=1e-14, **start)["x_p1"][-1])) < 1e-10
True
"""

from __future__ import annotations

import dataclasses
import math
import numbers
import re
import warnings
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ..base import display
from ..base.identity import is_zero
from ..base.arguments import check_grid
from ..base.limits import refuse
from ..base.component import t
from .derived import DerivedModel
from ..derivation.equations import Equations, _is_zero
from ..errors import ModelError, ReductionError, UnknownNameError, warn
from .impulse import simulate_with_impacts
from ..model import Model
from .channels import _BRANCH, _output_expr
from .routh import _depends, _drop, ignorable, reduce
from .scene_cost import reduction_skipped
from .scene_graph import prune
from .scene_plan import Offer, Part, ScenePlan, SceneResult, Sizes, _closure, _maybe_linear, _ops, _Output, _rows, _with_values
from ..numerics.simulation import InitialConditionWarning, Result, _lambdify
from ..base import deferred as _deferred

sp = _deferred.module("sympy", globals())

__all__ = ["Scene", "ScenePlan", "Part", "SceneResult", "Offer"]

_ENERGIES = ("T", "V", "D", "E", "L")


class Scene:
    """A model, the outputs asked of it, the time span and tolerance; solved by the smallest exact model.

    ``outputs`` are strings: a coordinate name (``"x_p"``), its rate
    (``"x_p'"``), a whole-model energy (``"T"``, ``"V"``, ``"D"``, ``"E"``,
    ``"L"``), a component's share (``"T[m1]"``, ``"V[k1]"``, ``"D[c1]"``),
    a branch's integral quantity or its rate (``"[C1]"``, ``"[L1]'"``:
    charge/current, displacement/velocity, flux/voltage as the domain
    defines them, said in words by ``SceneResult.meanings``), an element's
    voltage or current or a node's voltage (``"v(C1)"``, ``"i(L1)"``,
    ``"v(n2)"``, as SPICE names them); or SymPy expressions of the coordinates ``q(t)``, their
    derivatives and ``t`` (labelled by their text).  ``initial``,
    ``velocity`` and ``params`` are named as for
    :meth:`lagrangian.Model.simulate` and may give the whole model's state
    and parameters: each part takes what it needs (an eliminated
    coordinate's momentum from its velocity and the rest of its part's
    state), and ``plan.unused`` and the report list what was given but not
    needed (coordinates the outputs do not depend on, eliminated ones whose
    values are not asked for, parameters only of dropped components).  A
    name the model does not have is an :class:`~lagrangian.UnknownNameError`.
    Another value for a parameter given as a number (a name of
    :attr:`~lagrangian.Model.parameter_values`) is refused where the
    minimal model keeps its component, as the parts are built with the
    model's value (give that parameter as a symbol to vary it), and listed
    as not needed elsewhere.  ``tol`` is the relative tolerance asked
    (``atol = tol·1e-3``); ``method`` the integrator for nonlinear parts;
    ``offer=False`` skips estimating approximate simplifications;
    ``progress`` reports each part's progress as ``Model.simulate`` does;
    ``events`` are contacts (:mod:`lagrangian.impulse`: ``ground``, ``wall``,
    ...): a part they act on is simulated with impacts
    (:func:`~lagrangian.impulse.simulate_with_impacts`: no reduction, no
    exact solve, as impulses change every momentum), an event on pruned
    coordinates is dropped with a note.  ``reduce``: eliminate ignorable
    coordinates through the Routhian when it pays (``"auto"``: the part is
    run as it is within the evaluations its reduction would cost, and a
    run that ends within them is the scene's, returned by :meth:`run`; the
    report gives both costs: :mod:`lagrangian.analysis.scene_cost`), always
    (``True``) or never (``False``).
    """

    def __init__(self, model: Model, outputs: Sequence[Any], t_end: float | tuple[float, float] = 10.0, *,
                 tol: float = 1e-8, initial: Mapping[str, float] | None = None, velocity: Mapping[str, float] | None = None,
                 params: Mapping[str, float] | None = None, points: int = 1001, t_eval: Sequence[float] | None = None,
                 method: str = "DOP853", offer: bool = True, progress: bool | Any = False,
                 events: Sequence[Any] = (), reduce: bool | str = "auto"):
        if isinstance(outputs, (str, sp.Basic)):
            outputs = [outputs]
        if not outputs:
            raise ModelError("a scene needs at least one output (a coordinate name, 'E', 'T[m1]', an expression...).")
        if not (isinstance(tol, (int, float)) and 0 < tol < 1):
            raise ModelError(f"tol must be a number between 0 and 1, got {tol!r}.")
        if t_eval is None and isinstance(points, numbers.Real) and not isinstance(points, (bool, np.bool_)) and (
                isinstance(points, numbers.Integral) or math.isfinite(points)):
            refuse("a scene's output times (points=)", points, "grid_points")  # before any work; the rest: check_grid
        # a model of point masses or rotors is pruned by its graph first: what the outputs cannot reach is never derived
        self.pruned = prune(model, outputs, events)
        self.full_model = model
        if self.pruned is not None:
            model = self.pruned.model
        model._holonomic_only("a scene")
        self.model = model
        self.requested = list(outputs)
        self.span = Model._span(t_end)
        self.tol = float(tol)
        self.initial = dict(initial or {})
        self.velocity = dict(velocity or {})
        self.params = dict(params or {})
        self.grid = check_grid(self.span, points, None) if t_eval is None else np.asarray(t_eval, dtype=float)
        if not any(reduce is v for v in (True, False)) and reduce != "auto":
            raise ModelError(f"reduce must be 'auto', True or False, not {reduce!r}.")
        self.reduce = reduce
        self.method = method
        self.offer = offer
        self.progress = progress
        self.events = list(events)
        if self.events and t_eval is not None:
            raise ModelError("a scene with events gives its outputs on evenly spaced times: use points=, not t_eval=.")
        eq = model.eq
        every = self.pruned.coordinates if self.pruned is not None else eq.names
        for given in (self.initial, self.velocity):
            for name in given:
                if name not in eq.names and name not in every:
                    raise UnknownNameError("coordinate", name, every)
        for name in self.velocity:
            if name in eq.names and eq.names.index(name) in eq.first_order:
                raise ModelError(f"coordinate {name!r} is first-order (it has no inertia): its velocity follows from "
                                 f"the equations and cannot be given as an initial condition.")
        known = {s.name for s in model.parameters} | set(model.parameter_values)
        if self.pruned is not None:
            known |= self.pruned.parameters
        for name in self.params:
            if name not in known:
                raise UnknownNameError("parameter", name, known)
        self._outputs = [self._parse(o) for o in self.requested]
        self._plan: ScenePlan | None = None
        self._kept: dict[tuple[str, ...], tuple[Result, list]] = {}  # runs made while planning (_keep)

    # -- outputs -----------------------------------------------------------------------
    def _parse(self, spec: Any) -> _Output:
        model, eq = self.model, self.model.eq
        names = eq.names
        if isinstance(spec, sp.Basic):
            expr, label = eq.symbolic(spec), sp.sstr(spec)
        elif not isinstance(spec, str):
            raise ModelError(f"scene outputs are names or SymPy expressions, got {spec!r}.")
        else:
            label = spec.strip()
            m = re.fullmatch(r"(T|V|D|E|L)?\[([^\]]+)\](')?", label)
            meaning = ""
            if label not in names and _BRANCH.match(label):  # v(C1), i(L1), a node's voltage v(n2)
                # (in the model's own values, as its contributions are: a scene's parts are built with them)
                expr = eq.symbolic(sp.sympify(_output_expr(model, eq, label)[1]).xreplace(model.assembly.values))
            elif label in names:
                expr = eq.sym.q[names.index(label)]
            elif label.endswith("'") and label[:-1] in names:
                expr = eq.sym.v[names.index(label[:-1])]
            elif label in _ENERGIES:
                expr = {"T": eq.T, "V": eq.V, "D": eq.D, "E": eq.T + eq.V, "L": eq.L}[label]
            elif m:
                part, comp, rate = m.groups()
                contributions = model.assembly.contributions
                if comp not in contributions:
                    raise UnknownNameError("component", comp, contributions)
                if part:
                    c = contributions[comp]
                    if rate:
                        raise ModelError(f"scene output {label!r}: a rate applies to branch quantities ('[{comp}]'') only.")
                    expr = eq.symbolic({"T": c.T, "V": c.V, "D": c.D, "E": sp.sympify(c.T) + sp.sympify(c.V),
                                        "L": sp.sympify(c.T) - sp.sympify(c.V) + sp.sympify(c.G)}[part])
                else:
                    domain = model.component(comp).domain
                    try:
                        value = model.assembly.views[domain].branch_value(comp)
                    except (NotImplementedError, KeyError):
                        raise ModelError(f"scene output {label!r}: component {comp!r} has no branch quantity in the "
                                         f"{domain} domain; ask for a coordinate or an energy instead.") from None
                    expr = eq.symbolic(value.diff(t) if rate else value)
                    meaning = model.assembly.views[domain].branch_meaning(comp, bool(rate))
            else:
                choices = names + [f"{n}'" for n in names] + list(_ENERGIES) + ["T[<component>]", "[<component>]"]
                raise UnknownNameError("scene output", label, choices)

        expr = sp.sympify(expr)
        q, v = eq.sym.q, eq.sym.v
        absent = [s for s in (*q, *v) if s in expr.free_symbols and not _depends(eq, expr, s)]
        expr = _drop(expr, absent)  # e.g. an angle that cancels out of an energy
        free = expr.free_symbols
        depends = {i for i in range(len(names)) if q[i] in free or v[i] in free}
        return _Output(label, expr, depends, meaning if isinstance(spec, str) else "")

    # -- planning ---------------------------------------------------------------------
    @property
    def plan(self) -> ScenePlan:
        """The minimal model and the report (built once)."""
        if self._plan is None:
            self._plan = self._make_plan()
        return self._plan

    def report(self) -> str:
        return self.plan.report()

    def __repr__(self) -> str:
        return f"<Scene of {self.model.name!r}: outputs {display.short([o.label for o in self._outputs])}>"

    def _repr_html_(self) -> str:
        """The plan's report: the parts, how each is solved, what was dropped and why (Jupyter)."""
        return display.block(f"scene of {self.model.name}", f"<pre>{display.escape(self.report())}</pre>")

    def _dependencies(self) -> list[set[int]]:
        """``deps[i]``: coordinates whose position, rate or acceleration appear in the equation of ``i``."""
        eq = self.model.eq
        n = len(eq.names)
        q, v = eq.sym.q, eq.sym.v
        index = {s: i for i, s in enumerate(q)} | {s: i for i, s in enumerate(v)}
        deps = [set() for _ in range(n)]
        # read off the generic M and f (the parameters as symbols, as the compiled run takes them), with only the
        # values that are zero put in (a spring of k = 0 couples nothing): putting every value in walks each entry
        values = eq.values
        zeros = {s: 0 for s, v in values.items() if v == 0}
        M, f = eq._generic["M"], eq._generic["f"]
        if zeros:
            M, f = M.xreplace(zeros), f.xreplace(zeros)
        for i in range(n):
            free = f[i].free_symbols | eq.Q[i].free_symbols
            for j in range(n):
                free |= M[i, j].free_symbols
            deps[i] |= {index[s] for s in free if s in index}
            # an acceleration the equation holds: asked of the entries whose coordinate is not there already (the
            # check differentiates and evaluates; most entries of a coupled mechanism need not be asked)
            deps[i] |= {j for j in range(n) if j not in deps[i] and not is_zero(M[i, j], values)}
        for c in eq.constraints:  # a loop ties its coordinates through the multiplier
            tied = {index[s] for s in c.free_symbols if s in index}
            for i in tied:
                deps[i] |= tied
        return deps

    def _make_plan(self) -> ScenePlan:
        model, eq = self.model, self.model.eq
        names = eq.names
        n = len(names)
        deps = self._dependencies()
        events = {}
        for contact in self.events:  # an impact acts on every coordinate of its gap at once
            gap = eq.symbolic(contact.gap(model))
            events[contact] = touched = {i for i in range(n) if eq.sym.q[i] in gap.free_symbols}
            for i in touched:
                deps[i] |= touched
        wanted = set().union(*(o.depends for o in self._outputs))
        needed = _closure(wanted, lambda i: deps[i])
        # parts: connected groups of the needed coordinates
        groups: list[set[int]] = []
        for i in sorted(needed):
            touching = [g for g in groups if g & (deps[i] | {j for j in needed if i in deps[j]})]
            merged = {i}.union(*touching) if touching else {i}
            groups = [g for g in groups if g not in touching] + [merged]
        groups.sort(key=min)
        if not needed:  # outputs that depend on no coordinate (a function of time only)
            groups = []
        kept, dropped, held = self._components(needed)
        if self.pruned is not None:
            dropped = {**self.pruned.dropped, **dropped}
        for contact, touched in events.items():
            if not touched & needed:
                dropped[f"event {contact.name}"] = "acts only on coordinates the outputs do not depend on"
        self._events = {c: touched for c, touched in events.items() if touched & needed}
        self.plan_dropped = dropped
        self._check_overrides(kept, dropped, held)
        parts = [self._part(sorted(g)) for g in groups]
        whole = self.full_model
        before = Sizes(lambda: {"coordinates": len(whole.eq.names), "equations": _rows(whole.eq),
                                "operations": _ops(whole.eq)})
        after = {
            "coordinates": sum(len(p.integrated) for p in parts),
            "equations": sum(_rows(p.model.eq) if p.integrated else 0 for p in parts),
            "operations": sum(p.operations for p in parts),
        }
        plan = ScenePlan(model.name, [o.label for o in self._outputs], parts, kept, dropped, held, before, after,
                         unused=self._unused(parts))
        if self.offer:
            plan.offers = self._offers(needed, deps)
        return plan

    def _components(self, needed: set[int]):
        model, eq = self.model, self.model.eq
        q, v = eq.sym.q, eq.sym.v
        names = eq.names
        kept, dropped, held = [], {}, {}
        self._touch: dict[str, set[int]] = {}
        shares = dict((name, share) for name, share in eq.load_shares)
        # every coordinate needed and no offers to weigh: a component is kept unless it contributes nothing or only
        # imposes a function of time, so only those are read (reading each contribution walks its energies)
        everything = len(needed) == len(names) and not self.offer
        contributions = model.assembly.contributions  # each read fills in the model's values (see below)
        for name in contributions:
            comp = model.component(name)
            zeros = [p for p, value in comp.params.items() if isinstance(value, (int, float, sp.Number)) and value == 0
                     and comp.parameters.get(p) is not None and comp.parameters[p].default != value]
            if getattr(comp, "role", None) == "across" and any(isinstance(x, (sp.Expr, sp.MatrixBase)) and x.has(t) for x in comp.params.values()):
                held[name] = "imposes its across quantity (a position, a voltage) as a given function of time: no coordinate to solve for"
            if everything and not zeros and name not in held:
                kept.append(name)
                continue
            # the generic contribution (parameters as symbols) touches the coordinates the valued one does, or more
            # where values would cancel (kept then): its values are filled in only to ask whether it vanishes
            c = contributions[name] if zeros else model.assembly.generic[name]
            exprs = [eq.symbolic(sp.sympify(getattr(c, p))) for p in ("T", "V", "D", "G")] + list(shares.get(name, []))
            # whether a contribution vanishes is asked (a check at random points) only of a component given a zero;
            # of the others, what is not literally zero counts, and at worst keeps a component the outputs need not
            exprs = [e for e in exprs if not _is_zero(e)] if zeros else [e for e in exprs if e != 0]
            if not exprs and zeros:
                held.pop(name, None)
                dropped[name] = f"contributes nothing ({', '.join(f'{p} = 0' for p in zeros)})"
                continue
            owned = {i for i, c_ in enumerate(eq.coordinates) if f"'{name}'" in c_.description}
            if not exprs and not owned:
                if name not in held:
                    kept.append(name)
                continue
            touched = owned | {i for i in range(len(names)) for e in exprs if q[i] in e.free_symbols or v[i] in e.free_symbols}
            self._touch[name] = touched
            if touched & needed or not touched:
                kept.append(name)
            else:
                dropped[name] = (f"acts only on {', '.join(names[i] for i in sorted(touched))}, "
                                 f"which the outputs do not depend on")
        return kept, dropped, held

    def _check_overrides(self, kept: list[str], dropped: Mapping[str, str], held: Mapping[str, str]) -> None:
        """Refuse another value for a parameter given as a number when a component the minimal model keeps has it:
        the parts are built (pruned, reduced) with the value the model was built with.  Values for parameters of
        dropped components are not needed and only reported."""
        model = self.model
        symbolic = {s.name for s in model.parameters}
        for name, value in self.params.items():
            if name in symbolic:
                continue
            owners = [c.name for c in model.components.values() if name in {s.name for s in getattr(c, "values", {})}]
            live = [o for o in owners if o not in dropped or dropped[o].startswith("contributes nothing")]
            if live:
                raise ModelError(
                    f"parameter {name!r} of model {model.name!r} was given as a number "
                    f"({model.parameter_values[name]:g}), and the scene builds its minimal model (pruned, reduced) "
                    f"with that value ({', '.join(repr(o) for o in live)} {'is' if len(live) == 1 else 'are'} part of "
                    f"it): to vary it in a scene, build the model with a symbol for it (sympy.Symbol) and give its "
                    f"value in params=; Model.simulate(params={{{name!r}: ...}}) runs the full model with another value."
                )

    def _needs(self, part: Part) -> tuple[list[str], list[str]]:
        """The initial values and the velocities (by coordinate name) the part starts from."""
        inertial = self._inertial()
        skip = [] if part.method in ("uniform", "hybrid") else [n for n in part.eliminated if n not in part.reconstructed]
        values = [n for n in part.coordinates if n not in skip]
        rates = [n for n in part.coordinates if n in inertial]  # an eliminated coordinate's velocity gives its momentum
        return values, rates

    def _start(self, part: Part) -> tuple[dict[str, float], dict[str, float]]:
        """The given initial values and velocities of the part's coordinates (the rest of the state is not its)."""
        mine = set(part.coordinates)
        return ({k: v for k, v in self.initial.items() if k in mine}, {k: v for k, v in self.velocity.items() if k in mine})

    def _params_for(self, model: Model) -> dict[str, float]:
        """The given parameter values a part's model takes (a reduced model: those of the part it reduces, too)."""
        names = {s.name for s in model.parameters}
        full = getattr(model, "full", None)
        if full is not None:
            names |= {s.name for s in full.parameters}
        return {k: v for k, v in self.params.items() if k in names}

    def _unused(self, parts: list[Part]) -> dict[str, str]:
        """What of the given state and parameters no part needs, and why."""
        values, rates, owned = set(), set(), set()
        for part in parts:
            v, r = self._needs(part)
            values |= set(v)
            rates |= set(r)
            owned |= set(part.coordinates)
        out = {}
        for name in self.initial:
            if name not in values:
                out[name] = ("eliminated through the Routhian, values not asked for" if name in owned
                             else "coordinates the outputs do not depend on")
        for name in self.velocity:
            if name not in rates:
                out[f"{name}'"] = "coordinates the outputs do not depend on"
        used = set()
        for part in parts:
            used |= set(self._params_for(part.model))
        for o in self._outputs:
            used |= {s.name for s in o.expr.free_symbols}
        for name in self.params:
            if name not in used:
                out[name] = "parameters only of dropped components"
        return out

    def _part(self, idx: list[int]) -> Part:
        full, eq = self.model, self.model.eq
        names = [eq.names[i] for i in idx]
        sub = self._submodel(idx) if len(idx) < len(eq.names) else full
        requested_q = {eq.names[i] for o in self._outputs for i in o.depends if eq.sym.q[i] in o.expr.free_symbols}
        contacts = [c for c, touched in self._events.items() if touched & set(idx)]
        if contacts:
            return Part(names, names, [], [], "hybrid", f"impacts at {', '.join(c.name for c in contacts)}: integrated "
                        f"at rtol {self.tol:g} between impacts located in time to {self.tol * 1e-3:g}", sub, _ops(sub.eq))
        try:
            cyclic = ignorable(sub) if not len(sub.eq.constraints) else []
        except ModelError:  # pragma: no cover - defensive: a model the analysis cannot read
            cyclic = []
        if cyclic and len(cyclic) == len(names) and not _is_zero(sub.eq.L) and not sub.eq.L.has(t):
            return Part(names, [], cyclic, [], "uniform", "every coordinate is ignorable and L does not depend on t: "
                        "constant velocities, q = q₀ + q̇₀ (t − t₀)", sub, 0)
        if not (cyclic and len(cyclic) < len(names)):
            return self._solved_by(names, sub)
        as_is = None if self.reduce is True else self._solved_by(names, sub)
        skipped = reduction_skipped(self, as_is, cyclic)
        if skipped:
            return dataclasses.replace(as_is, why=f"{as_is.why}; {skipped}")
        try:
            red = reduce(sub, cyclic)
        except ReductionError:
            return as_is or self._solved_by(names, sub)
        reconstructed = [c for c in cyclic if c in requested_q]
        return self._solved_by(names, red.reconstructing(reconstructed) if reconstructed else red, cyclic, reconstructed)

    def _solved_by(self, names: list[str], model: Model, eliminated: Sequence[str] = (),
                   reconstructed: Sequence[str] = ()) -> Part:
        """The part on the coordinates ``names`` solved by ``model`` (the part as it is, or reduced with
        ``eliminated`` ignorable coordinates, ``reconstructed`` of them by quadrature): exactly where it is linear
        time-invariant, else integrated."""
        integrated = [nm for nm in model.coordinate_names if nm not in reconstructed]
        values = self._part_params(model, list(eliminated), names)
        exact = False
        if _maybe_linear(model.eq):  # a cheap screen first: the full check differentiates every entry
            try:
                exact = model._linear(values)
            except ModelError:
                exact = False
        if exact:
            method, why = "exact", "linear time-invariant: matrix exponential, no integration error"
        else:
            method, why = self.method, f"nonlinear or time-varying: integrated at rtol {self.tol:g}"
        return Part(names, integrated, list(eliminated), list(reconstructed), method, why, model, _ops(model.eq))

    def _submodel(self, idx: list[int], minus: Mapping[str, sp.Expr] | None = None, share=None) -> DerivedModel:
        full = self.model
        eq = full.eq
        keep = set(idx)
        out_q = [eq.sym.q[i] for i in range(len(eq.names)) if i not in keep]
        out_v = [eq.sym.v[i] for i in range(len(eq.names)) if i not in keep]
        rows = sorted(idx)

        def build() -> Equations:
            dropped = out_q + out_v
            less = minus or {}
            T, V, G, D = (_drop(e - less.get(p, 0), dropped) for p, e in (("T", eq.T), ("V", eq.V), ("G", eq.G), ("D", eq.D)))
            Q = [_drop(eq.Q[i] - (share[i] if share is not None else 0), dropped) for i in rows]
            constraints = [c for c in eq.constraints if c.free_symbols & {eq.sym.q[i] for i in rows}]
            return Equations.from_energies([eq.coordinates[i] for i in rows], T, V, G, D, Q, constraints, eq.constraint_rate)

        label = ", ".join(eq.names[i] for i in rows)
        return DerivedModel(full, f"{full.name} [{label}]", build)

    def _part_params(self, model: Model, eliminated: list[str], coordinates: Sequence[str]) -> dict[str, float]:
        """The part's parameter values, with the eliminated coordinates' momenta ``C_<name>`` from its own state."""
        names = {s.name for s in model.parameters}
        out = {k: v for k, v in self.params.items() if k in names}
        if eliminated and hasattr(model, "momenta_from"):
            mine = set(coordinates)
            initial = {k: v for k, v in self.initial.items() if k in mine}
            velocity = {k: v for k, v in self.velocity.items() if k in mine}
            for n, value in model.momenta_from(initial, velocity, self._params_for(model)).items():
                out[f"C_{n}"] = value
        return out

    def _offers(self, needed: set[int], deps: list[set[int]]) -> list[Offer]:
        """Weak couplings whose removal would shrink the model, with their effect estimated (never applied).

        A coupling is *weak* when its first numeric parameter is at most 1e-3 of the median of the same
        parameter over the other components of its kind; its effect is estimated by solving the kept part
        with and without it and comparing the requested coordinates.
        """
        model, eq = self.model, self.model.eq
        touch = self._touch
        wanted = set().union(*(o.depends for o in self._outputs))
        offers = []
        for name, touched in touch.items():
            if len(touched) < 2 or not touched <= needed or name in self.plan_dropped:
                continue
            comp = model.component(name)
            numeric = [(p, abs(float(v))) for p, v in comp.params.items()
                       if isinstance(v, (int, float, sp.Number)) and not isinstance(v, bool) and v != 0]
            if not numeric:
                continue
            pname, value = numeric[0]
            peers = [abs(float(other.params[pname])) for other in model.components.values()
                     if other.kind == comp.kind and other.name != name and isinstance(other.params.get(pname), (int, float, sp.Number))
                     and other.params.get(pname) != 0]
            if not peers or value > 1e-3 * float(np.median(peers)):
                continue
            reach = _closure(wanted, lambda i: set().union(*(t_ for other, t_ in touch.items() if other != name and i in t_)))
            if reach >= needed:
                continue
            error = self._estimate_without(name, sorted(needed), sorted(reach), wanted)
            offers.append(Offer(name, [eq.names[i] for i in sorted(needed - reach)], error,
                                f"weak: {pname} = {value:g} is {value / float(np.median(peers)):.1e} of the other "
                                f"{comp.kind}s' (median {float(np.median(peers)):g})"))
            if len(offers) >= 3:
                break
        return offers

    def _estimate_without(self, name: str, needed: list[int], reach: list[int], wanted: set[int]) -> float:
        eq = self.model.eq
        c = self.model.assembly.contributions[name]
        share = dict(eq.load_shares).get(name, [0] * len(eq.names))
        minus = {p: eq.symbolic(sp.sympify(getattr(c, p))) for p in ("T", "V", "D", "G")}
        with_it = self._submodel(needed) if len(needed) < len(eq.names) else self.model
        without = self._submodel(reach, minus=minus, share=share)
        rtol = min(self.tol, 1e-8)

        def run(model, idx):
            initial = {eq.names[i]: self.initial.get(eq.names[i], 0.0) for i in idx}
            velocity = {eq.names[i]: self.velocity.get(eq.names[i], 0.0) for i in idx if i in eq.inertial}
            params = {k: v for k, v in self.params.items() if k in {s.name for s in model.parameters}}
            return model.simulate(self.span, initial=initial, velocity=velocity, params=params, t_eval=self.grid,
                                  rtol=rtol, atol=rtol * 1e-3)

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            a, b = run(with_it, needed), run(without, reach)
        return max(float(np.max(np.abs(a[eq.names[i]] - b[eq.names[i]]))) for i in wanted)

    # -- running ---------------------------------------------------------------------------
    def run(self) -> SceneResult:
        """Solve every part on the requested times; outputs are computed when read."""
        plan = self.plan
        results = []
        for part in plan.parts:
            results.append((part, self._solve(part)))
        return SceneResult(self, self.grid, results)

    def _keep(self, part: Part, res: Result, caught: list) -> None:
        """Keep ``res``, the run of ``part`` made while planning (:func:`~lagrangian.analysis.scene_cost.reduction_skipped`),
        and the warnings it gave, for :meth:`run` to return once."""
        self._kept[tuple(part.coordinates)] = (res, caught)

    def _solve(self, part: Part, max_evaluations: float | None = None) -> Result:
        kept = self._kept.pop(tuple(part.coordinates), None)
        if kept is not None:  # the part ran while planning (reduction_skipped): its run, and what it warned
            res, caught = kept
            for w in caught:
                warnings.warn(w.message, stacklevel=3)
            return res
        initial, velocity = self._start(part)
        values, rates = self._needs(part)
        missing = [n for n in values if n not in initial] + [f"{n}'" for n in rates if n not in velocity]
        if missing:
            warn(f"initial conditions not given, set to zero: {', '.join(missing)}", InitialConditionWarning)
            initial = {n: initial.get(n, 0.0) for n in part.coordinates}
            velocity = {n: velocity.get(n, 0.0) for n in part.coordinates if n in self._inertial()}
        if part.method == "hybrid":
            idx = {self.model.eq.names.index(n) for n in part.coordinates}
            contacts = [c for c, touched in self._events.items() if touched & idx]
            params = self._params_for(part.model)
            res = simulate_with_impacts(part.model, self.span, contacts, initial=initial, velocity=velocity, params=params,
                                        points=len(self.grid), method=self.method, rtol=self.tol, atol=self.tol * 1e-3,
                                        event_tol=self.tol * 1e-3)
            keep = np.isin(res.t, self.grid)
            keep[:-1] &= res.t[:-1] != res.t[1:]  # an impact exactly on an output time: the state after it
            if keep.sum() != len(self.grid):  # pragma: no cover - the hybrid run outputs the grid itself
                raise ModelError("the hybrid run did not return the requested output times.")
            res.t = res.t[keep]
            res.q = {k: v[keep] for k, v in res.q.items()}
            res.v = {k: v[keep] for k, v in res.v.items()}
            res.T, res.V, res.D = res.T[keep], res.V[keep], res.D[keep]
            return res
        if part.method == "uniform":
            tt = self.grid
            q = {n: np.full_like(tt, initial.get(n, 0.0)) + velocity.get(n, 0.0) * (tt - self.span[0]) for n in part.coordinates}
            v = {n: np.full_like(tt, velocity.get(n, 0.0)) for n in part.coordinates}
            zero = np.zeros_like(tt)
            return Result(tt, q, v, zero, zero, zero, model=part.model.name, method="uniform")
        model = part.model
        params = self._params_for(model)
        common = dict(t_eval=self.grid, params=params, progress=self.progress)
        if hasattr(model, "momenta_from"):  # a reduced model: momenta from the full state
            return model.simulate(self.span, initial=initial, velocity=velocity,
                                  method=part.method if part.method == "exact" else self.method,
                                  **({} if part.method == "exact" else {"rtol": self.tol, "atol": self.tol * 1e-3}), **common)
        if part.method == "exact":
            return model.simulate(self.span, initial=initial, velocity=velocity, method="exact", **common)
        return model.simulate(self.span, initial=initial, velocity=velocity, method=self.method,
                              rtol=self.tol, atol=self.tol * 1e-3, max_evaluations=max_evaluations, **common)

    def _inertial(self) -> set[str]:
        eq = self.model.eq
        return {eq.names[i] for i in eq.inertial}

    def _evaluate(self, expr: sp.Expr, res: SceneResult) -> np.ndarray:
        eq = self.model.eq
        q, v = eq.sym.q, eq.sym.v
        columns: dict[sp.Symbol, np.ndarray] = {}
        for part, result in res.parts:
            rates = {}
            if part.eliminated and part.method != "uniform":
                red = part.model
                rates = {n: red.full.eq.symbolic(r) for n, r in red.rates.items()}
            for n in part.coordinates:
                i = eq.names.index(n)
                if n in result.q:
                    columns[q[i]] = result.q[n]
                    columns[v[i]] = result.v[n] if n in result.v else None
                if n in rates:
                    columns[v[i]] = ("rate", rates[n], part, result)
        expr = _with_values(self.model.eq, self.params, expr)
        args, data = [], []
        for s in sorted(expr.free_symbols - {t}, key=str):
            col = columns.get(s)
            if col is None:
                raise ModelError(f"output needs {s}, which the scene did not compute (ask for it explicitly).")
            if isinstance(col, tuple):
                _, rate, part, result = col
                col = part.model.numeric(self._part_params(part.model, part.eliminated, part.coordinates)).evaluate(
                    eq.display(rate), result)
            args.append(s)
            data.append(col)
        if len(args) == 1 and expr == args[0]:  # a coordinate or rate as computed (lambdify's NumPy namespace: 0.1 s)
            return np.broadcast_to(np.asarray(data[0], dtype=float), res.t.shape).copy()
        fn = _lambdify([t, args], expr, self.model.assembly.signals)
        return np.broadcast_to(np.asarray(fn(res.t, data), dtype=float), res.t.shape).copy()
