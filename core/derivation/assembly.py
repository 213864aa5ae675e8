"""Assembly: from the component graph to coordinates and summed energy terms.

Each domain present in the model builds its coordinates; each component
then contributes ``T``, ``V``, ``D`` and loads through a :class:`Context`.
The sums are the model's kinetic energy, potential energy and Rayleigh
function; ``L = T - V``.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any

from ..base.component import GROUND, Component, Contribution, Load, MovingFrame, StateCall, t
from ..base.domain import Context, Coordinate, DomainView, Network
from ..errors import DomainError, LagrangianError, ModelError, UnknownNameError, closest
from ..base.graph import ComponentGraph
from ..base.identity import is_zero, nodes
from .calculus import Rewriter
from ..base.network import check_topology
from ..plugin.registry import Registry
from ..base import deferred as _deferred

sp = _deferred.module("sympy", globals())

__all__ = ["Assembly", "Elimination", "Signals", "assemble", "driven", "refuse_eliminated"]


class Signals(dict):
    """The Python callables standing behind signal parameters, by their undefined functions (what the equations
    hold), and ``owners``: each function's name → ``(component, parameter)``, so that what a callable does wrong is
    told as a :class:`ParameterError` naming them.

    >>> s = Signals({}, owners={"F_F": ("F", "F")})
    >>> s.owners["F_F"], dict(s)
    (('F', 'F'), {})
    """

    def __init__(self, *args: Any, owners: Mapping[str, tuple[str, str]] | None = None, **kwargs: Any):
        super().__init__(*args, **kwargs)
        self.owners = dict(owners or getattr(args[0] if args else None, "owners", None) or {})


@dataclass
class Assembly:
    """The coordinates of a model and the energy terms of its components (SymPy, functions of ``t``).

    ``generic`` holds the contributions with every parameter given as a
    number still a symbol (the equations are derived from them), ``values``
    those symbols' values, and ``contributions`` the contributions with the
    values in (what the components add, as users gave them).  Likewise
    ``generic_views`` are the domains' views built from the components'
    symbolic views (kinematics in symbols: what the derivation uses), and
    ``views`` the same built from the components as given (positions and
    branch quantities in numbers; built on first use).  ``eliminated`` maps
    each coordinate a holonomic constraint eliminates (``eliminate=``) to
    its :class:`Elimination`: it is no coordinate of the model, and every
    contribution holds its solution in its place.
    """

    coordinates: list[Coordinate]
    generic_views: dict[str, DomainView]
    contributions: Mapping[str, Contribution]
    signals: dict[sp.Function, Any] = field(default_factory=dict)
    generic: dict[str, Contribution] = field(default_factory=dict)
    values: dict[sp.Symbol, sp.Expr] = field(default_factory=dict)
    build_views: Any = field(default=None, repr=False)  # () -> the views with the values in
    eliminated: dict[str, "Elimination"] = field(default_factory=dict)

    @property
    def state_callables(self) -> list[str]:
        """Names of the loads' Python callables of ``(t, q, v)`` (their derivatives are unknown: what needs them —
        linearization, equilibria, the exact solution — refuses the model)."""
        return sorted(f.__name__ for f, fn in self.signals.items() if isinstance(fn, StateCall))

    @property
    def views(self) -> dict[str, DomainView]:
        """The domains' views with the values of parameters given as numbers in (built on first use)."""
        if "_views" not in self.__dict__:
            self.__dict__["_views"] = self.generic_views if self.build_views is None else self.build_views()
        return self.__dict__["_views"]

    def energy(self, part: str, generic: bool = False) -> sp.Expr:
        """The sum of every component's ``part`` (``"T"``, ``"V"``, ``"D"`` or ``"G"``)."""
        source = self.generic if generic else self.contributions
        return sp.Add(*(sp.sympify(getattr(c, part)) for c in source.values()))

    def frame_list(self, generic: bool = False) -> list[MovingFrame]:
        """Every component's :class:`~lagrangian.MovingFrame` declarations."""
        source = self.generic if generic else self.contributions
        return [frame for c in source.values() for frame in c.frames]

    def constraint_list(self, generic: bool = False) -> list[tuple[str, sp.Expr]]:
        """``(component, Φ)`` pairs: the holonomic constraints components impose (beyond the domains' loop
        closures, ``view.constraints``)."""
        source = self.generic if generic else self.contributions
        return [(name, sp.sympify(e, strict=True)) for name, c in source.items() for e in c.constraints]

    def velocity_constraint_list(self, generic: bool = False) -> list[tuple[str, sp.Expr]]:
        """``(component, c)`` pairs: the constraints on velocities ``c(q, q̇, t) = 0`` components impose."""
        source = self.generic if generic else self.contributions
        return [(name, sp.sympify(e, strict=True)) for name, c in source.items() for e in c.velocity_constraints]

    def load_list(self, generic: bool = False) -> list[tuple[str, Load]]:
        """``(component, load)`` pairs."""
        source = self.generic if generic else self.contributions
        return [(name, load) for name, c in source.items() for load in c.loads]

    @property
    def T(self) -> sp.Expr:
        return self.energy("T")

    @property
    def V(self) -> sp.Expr:
        return self.energy("V")

    @property
    def D(self) -> sp.Expr:
        return self.energy("D")

    @property
    def G(self) -> sp.Expr:
        return self.energy("G")

    @property
    def loads(self) -> list[tuple[str, Load]]:
        return self.load_list()


def assemble(graph: ComponentGraph, registry: Registry, options: Mapping[str, Any]) -> Assembly:
    """Choose coordinates domain by domain, then collect every component's contribution."""
    components = list(graph.components.values())
    if not components:
        raise ModelError("the model has no components: add some with Model.add(kind, name, nodes, **params).")
    graph.node_domains()
    whole = graph.graph()
    roles = {k: d["component"].role for _, _, k, d in whole.edges(keys=True, data=True)}
    check_topology(whole, GROUND, roles.get)

    # Domains build their views (kinematics, networks) from the components' symbolic views: geometry given as
    # numbers is symbols there too, and the values go in with the rest after the derivation.
    symbolic = [comp.symbolic_view() for comp in components]
    standing = {c.name: view for c, view in zip(components, symbolic)}

    views = _views(graph, registry, options, components, standing)

    coordinates: list[Coordinate] = []
    seen: dict[str, str] = {}
    for dname, view in views.items():
        for c in view.coordinates:
            if c.name in seen:
                raise ModelError(f"coordinate {c.name!r} is introduced by both the {seen[c.name]} and the {dname} domain.")
            seen[c.name] = dname
            coordinates.append(c)

    allowed = {c.function.func for c in coordinates} | {u for comp in components for u in comp.inputs()}
    signals = Signals()  # (and whose each one is: errors name the component and parameter)
    for comp in components:
        signals.update(comp.signals())
        signals.owners.update(comp.signal_owners())
    # a load's callable of (t, q, v): its function applied to t, every coordinate and every rate
    names = [c.name for c in coordinates]
    state_args = (t, *[c.function for c in coordinates], *[sp.Derivative(c.function, t) for c in coordinates])
    applied = {}
    for comp in components:
        for f in comp.state_callables():
            applied[f(t)] = f(*state_args)
            signals[f] = StateCall(signals[f], names)
    generic, values = {}, {}
    for comp in components:
        values.update(comp.values)
    allowed = allowed | set(signals)
    checked: set = set()  # sub-expressions whose functions the checks of contributions have found allowed
    for comp, view in zip(components, symbolic):
        ctx = Context(views[comp.domain], views, dict(options), symbolic, values=values)
        try:
            contribution = view.contribute(ctx)
        except LagrangianError:
            raise
        except Exception as exc:
            raise ModelError(
                f"{comp.kind} {comp.name!r} failed to contribute its energy: {exc.__class__.__name__}: {exc}"
            ) from exc
        if applied and isinstance(contribution, Contribution) and contribution.loads:  # a copy: never the plugin's own
            contribution = replace(contribution, loads=[Load(_applied(load.force, applied), load.velocity)
                                                        for load in contribution.loads])
        _check_contribution(comp, contribution, allowed, names, checked)  # (one list of names, one set of nodes)
        generic[comp.name] = contribution
    eliminated = _eliminations(components, generic, coordinates)
    if eliminated:
        generic = _substituted(generic, eliminated)
        coordinates = [c for c in coordinates if c.name not in eliminated]
    contributions = _Valued(generic, values)
    valued = None if all(view is comp for comp, view in zip(components, symbolic)) else \
        functools.partial(_views, graph, registry, options, components, None)  # (a partial, not a closure: it pickles)
    return Assembly(coordinates, views, contributions, signals, generic, values, valued, eliminated)


def driven(model: Any, chosen: Mapping[str, tuple[str, int | None]]) -> tuple[Any, dict[str, Any]]:
    """A copy of ``model`` (a :class:`lagrangian.Model`: the copy is built by its own type) whose components named
    in ``chosen`` carry an input on a signal parameter, ``{name: (parameter, index or None, ...)}``
    (:meth:`lagrangian.Component.with_input`); returns the copy and each name's input function ``w``."""
    functions: dict[str, Any] = {}
    components = []
    for comp in model.components.values():
        if comp.name in chosen:
            pname, index = chosen[comp.name][:2]
            comp, functions[comp.name] = comp.with_input(pname, f"w_{comp.name}", index)
        components.append(comp)
    return twin(model, components), functions


def twin(model: Any, components: Any = None, **options: Any) -> Any:
    """A model of ``model``'s type, name, registry and declared nodes holding ``components`` (default: ``model``'s
    own), with ``options`` over ``model``'s."""
    out = type(model)(model.name, registry=model.registry, **{**model._options, **options})
    out._graph.declared = list(model._graph.declared)
    for comp in model.components.values() if components is None else components:
        out._graph.add(comp)
    return out


def _views(graph: ComponentGraph, registry: Registry, options: Mapping[str, Any], components: list[Component],
           stand: Mapping[str, Component] | None) -> dict[str, DomainView]:
    """The domains' views of ``components``: built from the components ``stand`` has in their place (their symbolic
    views), or from the components as given (``None``)."""
    out: dict[str, DomainView] = {}
    for dname in dict.fromkeys(d for c in components for d in c.domains):
        domain = registry.domains.get(dname)
        if domain is None:
            raise DomainError(f"no installed plugin provides the domain {dname!r}.")
        members = [c for c in components if dname in c.domains]
        opts = {name: options.get(name, opt.default) for name, opt in domain.options.items()}
        network = graph.graph(members, domain=dname)
        if stand is not None:
            for _, _, data in network.edges(data=True):
                if "component" in data:
                    data["component"] = stand[data["component"].name]
            members = [stand[c.name] for c in members]
        out[dname] = domain.build(Network(network, members), opts)
    return out


def _applied(force: Any, applied: Mapping) -> Any:
    """``force`` with the functions of the load's state callables applied to the state."""
    return force.xreplace(applied) if isinstance(force, (sp.Basic, sp.MatrixBase)) else force


class _Valued(Mapping):
    """The contributions with the values given as numbers in, each built on first use (the derivation and the
    stamps read the generic ones: a large model need not pay for both)."""

    def __init__(self, generic: Mapping[str, Contribution], values: Mapping):
        self._generic, self._values, self._done = generic, values, {}
        self._put = Rewriter(dict(values))  # (one memo for all: the bodies of a chain share their poses)

    def __getitem__(self, name: str) -> Contribution:
        out = self._done.get(name)
        if out is None:
            out = self._done[name] = _with_values(self._generic[name], self._values, self._put)
        return out

    def __iter__(self):
        return iter(self._generic)

    def __len__(self) -> int:
        return len(self._generic)


def _with_values(c: Contribution, values: Mapping, rewriter: Rewriter | None = None) -> Contribution:
    """``c`` with its parameter symbols replaced by their values (by ``rewriter``, a memoized ``xreplace`` of them:
    SymPy's walks a shared sub-expression once per occurrence, exponential in the depth of a spatial chain)."""
    if not values:
        return c
    rewrite = rewriter if rewriter is not None else Rewriter(dict(values))

    def put(expr):
        if isinstance(expr, sp.MatrixBase):
            return expr.applyfunc(rewrite)
        return rewrite(sp.sympify(expr)) if isinstance(expr, sp.Basic) else expr

    return Contribution(put(c.T), put(c.V), put(c.D), put(c.G),
                        [Load(put(load.force), put(load.velocity)) for load in c.loads],
                        [MovingFrame(put(f.omega), tuple(put(v) for v in f.velocities)) for f in c.frames],
                        [put(e) for e in c.constraints], [put(e) for e in c.velocity_constraints])


def _every(expr, kind=None, seen: set | None = None) -> set:
    """The sub-expressions of ``expr`` of ``kind``, each distinct one visited once (:func:`~lagrangian.identity.nodes`:
    ``atoms`` visits a shared one once per occurrence, 32 million visits for seven bodies on spherical joints), and
    those inside nodes that bind a symbol (an integral); ``seen``: nodes an earlier walk visited, skipped.  ``kind``
    by default: every SymPy object."""
    kind = sp.Basic if kind is None else kind
    found = nodes([expr], seen)
    out = {e for e in found if isinstance(e, kind)}
    for e in found:
        if e.args and getattr(e, "bound_symbols", None):
            out |= e.atoms(kind)
    return out


def _check_contribution(comp: Component, c: Any, allowed: set, names: list[str] = (), seen: set | None = None) -> None:
    """Refuse a contribution that is not one, or whose expressions hold a function that is neither a coordinate nor a
    signal (``seen``: sub-expressions earlier contributions' checks found sound, not walked again: the bodies of a
    chain share their poses, and walking each body's anew was quadratic in their number)."""
    where = f"{comp.kind} {comp.name!r}"
    if not isinstance(c, Contribution):
        raise ModelError(f"{where}: contribute() returned {type(c).__name__}, not a lagrangian.Contribution.")
    parts = [("T", c.T), ("V", c.V), ("D", c.D), ("G", c.G)]
    for i, load in enumerate(c.loads):
        if not isinstance(load, Load):
            raise ModelError(f"{where}: loads[{i}] is not a lagrangian.Load.")
        parts += [(f"loads[{i}].force", load.force), (f"loads[{i}].velocity", load.velocity)]
    if not isinstance(c.constraints, (list, tuple)):
        raise ModelError(f"{where}: constraints must be a list of expressions Φ(q, t) (each Φ = 0), not "
                         f"{type(c.constraints).__name__}.")
    for i, e in enumerate(c.constraints):
        parts.append((f"constraints[{i}]", e))
        if isinstance(e, sp.Basic) and any(isinstance(d, sp.Derivative) for d in _every(e)):
            raise ModelError(f"{where}: constraints[{i}] holds a rate ({e}): a holonomic constraint is Φ(q, t) = 0, "
                             f"in coordinates and t alone.")
    if not isinstance(c.velocity_constraints, (list, tuple)):
        raise ModelError(f"{where}: velocity_constraints must be a list of expressions A(q, t)·q̇ + b(q, t) (each = 0), "
                         f"not {type(c.velocity_constraints).__name__}.")
    for i, e in enumerate(c.velocity_constraints):
        parts.append((f"velocity_constraints[{i}]", e))
    for i, frame in enumerate(c.frames):
        if not isinstance(frame, MovingFrame):
            raise ModelError(f"{where}: frames[{i}] is not a lagrangian.MovingFrame.")
        if not isinstance(frame.velocities, (tuple, list)):
            raise ModelError(f"{where}: frames[{i}].velocities must be a tuple of 3 × 1 SymPy Matrices, not "
                             f"{type(frame.velocities).__name__}.")
        for k, vec in enumerate((frame.omega, *frame.velocities)):
            label = f"frames[{i}]." + ("omega" if k == 0 else f"velocities[{k - 1}]")
            if not (isinstance(vec, sp.MatrixBase) and vec.shape == (3, 1)):
                raise ModelError(f"{where}: {label} must be a 3 × 1 SymPy Matrix (components in the frame's axes).")
            parts.append((label, vec))
    for label, expr in parts:
        if isinstance(expr, (str, bytes)):  # text is never read as code, even from a plugin
            raise ModelError(f"{where}: {label} is text, not a SymPy expression: {expr!r:.60}.")
        try:
            expr = sp.sympify(expr, strict=True)
        except sp.SympifyError:
            raise ModelError(f"{where}: {label} is not a SymPy expression: {expr!r}.") from None
        if label in ("T", "V", "D", "G") and not isinstance(expr, sp.Expr):
            raise ModelError(f"{where}: {label} must be a scalar expression.")
        for f in _every(expr, sp.core.function.AppliedUndef, seen):
            if f.func not in allowed:
                if f.args == (t,) and names:  # a load written in lagrangian.coordinate(...)
                    raise ModelError(f"{where}: {label} depends on {f}, which is not a coordinate of the model."
                                     f"{closest(f.func.__name__, names)} Its coordinates: {', '.join(names)}.")
                raise ModelError(f"{where}: {label} depends on {f}, which is neither a coordinate nor a signal.")


@dataclass(frozen=True)
class Elimination:
    """A coordinate a holonomic constraint eliminates (``eliminate=`` on ``constraint``, ``gear``,
    ``rack_and_pinion``): ``function`` (``x(t)``) equals ``solution``, a function of the remaining coordinates and
    ``t``, and its rate equals ``rate``, the solution's time derivative (chain rule, explicit time dependence
    included).  ``kind`` and ``owner`` name the component whose constraint it is.

    >>> import lagrangian as lg
    >>> m = lg.Model("rack")
    >>> _ = m.add("mass", "rack", "p", m=0.5)
    >>> _ = m.add("inertia", "J", "s", J=1e-3)
    >>> _ = m.add("rack_and_pinion", "mesh", rack="x_p", pinion="theta_s", radius=0.02, eliminate="theta_s")
    >>> e = m.assembly.eliminated["theta_s"]
    >>> e.solution, e.rate
    (50.0*x_p(t), 50.0*Derivative(x_p(t), t))
    """

    name: str
    kind: str
    owner: str
    function: sp.Expr
    solution: sp.Expr
    rate: sp.Expr
    given_by: tuple[str, ...] = ()  # the coordinates the solution holds

    @property
    def follows(self) -> str:
        """``"x follows from it"`` (or ``them``): how the coordinate relates to those its solution holds."""
        return f"{self.name} follows from {'them' if len(self.given_by) > 1 else 'it'}"

    def refusal(self, arg: str, why: str, shown: sp.Expr | None = None) -> ModelError:
        """The error for ``arg=`` naming this coordinate: the constraint that eliminates it, its solution
        (``shown``, else :attr:`solution`), the coordinates to give instead (``why`` in parentheses after them), or
        the multiplier."""
        given = " and ".join(map(repr, self.given_by)) or "the coordinates it follows from"
        return ModelError(f"{arg}= gives {self.name!r}, which {self.kind} {self.owner!r} eliminates ({self.name} = "
                          f"{self.solution if shown is None else shown}): give {given} instead ({why}), or keep the "
                          f"constraint with a multiplier (leave eliminate= out).")

    @property
    def mapping(self) -> dict[sp.Expr, sp.Expr]:
        """``{ẋ(t): rate, x(t): solution}``: what an ``xreplace`` puts in (the rate first: it holds ``x(t)``)."""
        return {sp.Derivative(self.function, t): self.rate, self.function: self.solution}


def refuse_eliminated(eliminated: Mapping[str, Elimination], values: Mapping | None = None, **given: Any) -> None:
    """Refuse a mapping (``initial=``, ``velocity=``) naming a coordinate in ``eliminated`` (an assembly's or
    equations' ``eliminated``): it follows from the others.  ``values`` put numbers in the solution shown.

    >>> import lagrangian as lg
    >>> m = lg.Model("rack")
    >>> _ = m.add("mass", "rack", "p", m=0.5)
    >>> _ = m.add("inertia", "J", "s", J=1e-3)
    >>> _ = m.add("rack_and_pinion", "mesh", rack="x_p", pinion="theta_s", radius=0.02, eliminate="theta_s")
    >>> refuse_eliminated(m.assembly.eliminated, initial={"theta_s": 0.1})
    Traceback (most recent call last):
    ...
    lagrangian.errors.ModelError: initial= gives 'theta_s', which rack_and_pinion 'mesh' eliminates ...
    """
    for what, mapping in given.items():
        if not isinstance(mapping, Mapping) or not eliminated:
            continue
        for name in mapping:
            e = eliminated.get(name) if isinstance(name, str) else None
            if e is None:
                continue
            shown = e.solution.xreplace(values) if values else e.solution
            raise e.refusal(what, f"{e.follows} and is in the result as res[{name!r}]", shown)


def _eliminations(components: list[Component], generic: Mapping[str, Contribution],
                  coordinates: list[Coordinate]) -> dict[str, Elimination]:
    """The coordinates the components' ``eliminate=`` name, each solved from its constraint, a chain of them
    (``x`` in terms of ``y``, ``y`` in terms of ``z``) resolved in order."""
    functions = {c.name: c.function for c in coordinates}
    out: dict[str, Elimination] = {}
    for comp in components:
        name = getattr(comp, "eliminate", None)
        if name is None:
            continue
        where = f"{comp.kind} {comp.name!r}"
        if name not in functions:
            raise UnknownNameError(f"coordinate (eliminate= of {where})", name, functions)
        rows = list(generic[comp.name].constraints)
        if len(rows) != 1:
            raise ModelError(f"{where}: eliminate= solves one constraint for one coordinate, and it imposes "
                             f"{len(rows)}: give each its own {comp.kind} (each with its own eliminate=), or keep "
                             f"them with multipliers (leave eliminate= out).")
        if name in out:
            first = out[name]
            raise ModelError(f"{first.kind} {first.owner!r} and {where} both eliminate {name!r}: a coordinate is "
                             f"solved from one constraint. Keep the other with a multiplier (leave its eliminate= "
                             f"out), or let it eliminate another of its coordinates.")
        out[name] = _solved(comp, where, sp.sympify(rows[0], strict=True), name, functions)
    if not out:
        return out
    names = {g: n for n, g in functions.items()}
    return {n: replace(e, given_by=tuple(sorted({names[g] for g in e.solution.atoms(sp.core.function.AppliedUndef) if g in names})))
            for n, e in _resolved(out).items()}


def _solved(comp: Component, where: str, f: sp.Expr, name: str, functions: Mapping[str, sp.Expr]) -> Elimination:
    """``f = a·x + g = 0`` solved for ``x = −g / a``, with ``a`` free of every coordinate and not zero."""
    x = functions[name]
    coords = {g: n for n, g in functions.items()}
    held = sorted({coords[g] for g in f.atoms(sp.core.function.AppliedUndef) if g in coords})
    fix = (f"keep it with a multiplier (leave eliminate= out), or write the constraint solved, {name} − g(q, t), "
           f"and eliminate {name!r} from that")
    X = sp.Dummy(name, real=True)
    fx = f.xreplace({x: X})
    a = sp.diff(fx, X)
    absent = ModelError(f"{where}: its constraint {f} = 0 does not hold {name!r}, so it cannot eliminate it: "
                        f"eliminate one of the coordinates it holds ({', '.join(held)}).")
    if not f.has(x):
        raise absent
    if a.has(X):
        raise ModelError(f"{where}: cannot eliminate {name!r}: the constraint {f} = 0 is not linear in it (solving "
                         f"it would choose a branch): {fix}.")
    varying = sorted({coords[g] for g in a.atoms(sp.core.function.AppliedUndef) if g in coords})
    if varying:
        raise ModelError(f"{where}: cannot eliminate {name!r}: its coefficient in the constraint {f} = 0, {a}, "
                         f"depends on {', '.join(varying)} (where it vanishes the solution is singular): {fix}.")
    if is_zero(a):
        raise absent
    solution = -fx.xreplace({X: 0}) / a
    return Elimination(name, comp.kind, comp.name, x, solution, sp.diff(solution, t))


def _resolved(out: dict[str, Elimination]) -> dict[str, Elimination]:
    """Each solution in the coordinates that remain: the solutions of the eliminated coordinates it holds put in,
    in order; a cycle (``x`` in terms of ``y``, ``y`` in terms of ``x``) refused by name."""
    deps = {n: [m for m in out if m != n and e.solution.has(out[m].function)] for n, e in out.items()}
    done: dict[str, Elimination] = {}

    def visit(n: str, path: list[str]) -> None:
        if n in done:
            return
        if n in path:
            cycle = path[path.index(n):] + [n]
            steps = ", ".join(f"{out[a].kind} {out[a].owner!r} gives {a} in terms of {b}" for a, b in zip(cycle, cycle[1:]))
            raise ModelError(f"the eliminations form a cycle ({steps}): no coordinate of it is left to solve them "
                             f"in. Keep one of these constraints with a multiplier (leave its eliminate= out).")
        for m in deps[n]:
            visit(m, path + [n])
        e = out[n]
        solution = e.solution.xreplace({done[m].function: done[m].solution for m in deps[n]}) if deps[n] else e.solution
        done[n] = replace(e, solution=solution, rate=sp.diff(solution, t))

    for n in out:
        visit(n, [])
    return {n: done[n] for n in out}


def _substituted(generic: Mapping[str, Contribution], eliminated: Mapping[str, Elimination]) -> dict[str, Contribution]:
    """Every contribution with the eliminated coordinates and their rates replaced by their solutions; the rows
    that eliminated them dropped."""
    sub: dict[sp.Expr, sp.Expr] = {}
    for e in eliminated.values():
        sub.update(e.mapping)
    owners = {e.owner for e in eliminated.values()}

    def put(expr):
        return expr.xreplace(sub) if isinstance(expr, (sp.Basic, sp.MatrixBase)) else expr

    return {name: Contribution(put(c.T), put(c.V), put(c.D), put(c.G),
                               [Load(put(load.force), put(load.velocity)) for load in c.loads],
                               [MovingFrame(put(f.omega), tuple(put(v) for v in f.velocities)) for f in c.frames],
                               [] if name in owners else [put(sp.sympify(e, strict=True)) for e in c.constraints],
                               [put(sp.sympify(e, strict=True)) for e in c.velocity_constraints])
            for name, c in generic.items()}
