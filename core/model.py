"""The model: a component graph and everything derived from it.

>>> import lagrangian as lg
>>> m = lg.Model("oscillator")
>>> _ = m.add("mass", "m1", "cart", m=2)
>>> _ = m.add("spring", "k1", ("ground", "cart"), k=8)
>>> m.lagrangian
-4*x_cart(t)**2 + Derivative(x_cart(t), t)**2
>>> m.equations
[Eq(2*Derivative(x_cart(t), (t, 2)), -8*x_cart(t))]
"""

from __future__ import annotations

import logging
import re
from dataclasses import replace
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from .base.arguments import RunOptions, check_atol, check_max_step, check_state, check_energy_tol, check_grid, check_mapping, check_positive, check_progress, check_span
from .derivation.assembly import Assembly, assemble
from .base.component import GROUND, Component, check_value, t
from .base.domain import Coordinate, check_name
from .derivation.calculus import symbols_of
from .derivation.equations import Equations
from .base import deferred as _deferred, display, modelfile, sliders
from .base.overrides import Rules
from .base.latex import to_latex
from .errors import LagrangianError, ModelError, ParameterError, UnknownNameError, closest, warn
from .base.graph import ComponentGraph, unchanged_while_running as _unchanged_while_running
from .base.units import is_quantity, split, to_si
from .plugin.registry import Registry, default_registry
from .numerics.simulation import NumericModel, Result, check_start, initial_state
from .numerics.integrate import choose, integrate, Problem, resolve
from .numerics.events import Event, check as check_events
from .numerics.linear import prepared, simulate_exact, stamped, state_space
from .numerics.fmu import export as export_fmu
from .numerics import assembled as _assembled, sensitivity as _sensitivity
sp = _deferred.module("sympy", globals())  # SymPy imported when first used (lagrangian.base.deferred)

__all__ = ["Model"]

_log = logging.getLogger("lagrangian")

class NodeNameWarning(UserWarning):
    """A node only one component touches has a name a slip away from another node's (see ``Model``)."""


def _shown(value: Any) -> str:
    """A parameter's value, short: a number as given, an expression or array in at most 40 characters."""
    text = f"{float(value):g}" if isinstance(value, (float, sp.Float, sp.Integer)) else str(value)
    return text if len(text) <= 40 else text[:37] + "..."


class Model:
    """A component graph assembled into one Lagrangian.

    ``Model(name, **options)``: options belong to the installed domains, for
    example ``dim`` (1, 2 or 3: spatial dimension of mechanical nodes) and
    ``formulation`` (``"charge"``: loop charges, or ``"flux"``: node flux
    linkages, for circuits).  ``registry`` selects the plugins (the installed
    ones by default).

    Everything derived — coordinates, Lagrangian, equations — is computed on
    first request and cached until the model changes.
    """

    def __init__(self, name: str = "model", *, registry: Registry | None = None, **options: Any):
        self.name = name
        self._registry = registry
        self._graph = ComponentGraph()
        self._options = dict(options)
        self._cache: dict[str, Any] = {}
        self._numeric: dict[Any, NumericModel] = {}
        known = self.registry.options()
        for key, value in options.items():
            if key not in known:
                raise UnknownNameError("model option", key, known)
            domain, opt = known[key]
            if opt.choices and not any(value == c and type(value) is type(c) for c in opt.choices):
                raise ModelError(
                    f"model option {key!r} ({opt.doc}, from the {domain} domain) must be one of "
                    f"{', '.join(map(repr, opt.choices))}, not {value!r}."
                )

    #: The derived results a pickle keeps (SymPy, NumPy): a double pendulum unpickled and simulated in a fresh
    #: process takes 0.13 s with them or derived again (simulating 0.010 s against 0.026 s): kept, as larger
    #: models derive longer.
    _PICKLED = ("assembly", "equations", "unvalued", "numeric", "numeric_branches")

    def __getstate__(self) -> dict[str, Any]:
        """Graph, options, registry (by name: :meth:`Registry.__reduce__`), derivation; no compiled code (rebuilt on
        first use).  Unpickled or not, one model is for one thread's runs at a time: give each thread its own copy."""
        return {**self.__dict__, "_numeric": {}, "_cache": {k: v for k, v in self._cache.items() if k in self._PICKLED}}

    @property
    def registry(self) -> Registry:
        if self._registry is None:
            self._registry = default_registry()
        return self._registry

    @property
    def options(self) -> dict[str, Any]:
        """Every domain option with its value in this model (defaults included)."""
        return {k: self._options.get(k, opt.default) for k, (_, opt) in self.registry.options().items()}

    # -- building --------------------------------------------------------------
    def add(self, kind: str, name: str | None = None, nodes: str | Sequence[str] = (), **params: Any) -> Component:
        """Add a component of a registered ``kind``; return it.

        ``nodes`` is a node name for one-terminal components or a sequence ``(a, b)``; ``ground`` (also ``"0"``,
        ``"gnd"``) is the reference.  ``params`` are the kind's parameters: numbers, SymPy expressions, or (for
        signals) Python callables of time.
        """
        cls = self.registry.component_type(kind)
        if name is None:
            i = 1
            while f"{kind}{i}" in self._graph.components:
                i += 1
            name = f"{kind}{i}"
        if not isinstance(name, str) or not name:
            raise ModelError(f"component names must be non-empty strings, got {name!r}.")
        check_name(name, "component name")
        if isinstance(nodes, (str, int)) and not isinstance(nodes, bool):
            node_list = (nodes,)
        elif isinstance(nodes, Sequence) and not isinstance(nodes, (str, bytes, bytearray)):
            node_list = tuple(nodes)
        else:
            want = (f"a {kind} takes {', '.join(cls.terminals)}" if cls.terminals
                    else f"a {kind} takes none: leave nodes out")
            raise ModelError(
                f"{kind} {name!r}: nodes are a node name or a tuple of node names ({want}), got {nodes!r:.80}."
            )
        for n in node_list:
            if isinstance(n, str):
                check_name(n, f"{kind} {name!r}: node name")
        if len(node_list) != len(cls.terminals):
            want = ", ".join(cls.terminals) or "no nodes"
            raise ModelError(
                f"{kind} {name!r} takes {len(cls.terminals)} node(s) ({want}), got {len(node_list)}: {node_list!r}."
            )
        normalized = tuple(self._graph.normalize_node(n) for n in node_list)
        component = cls(name, normalized, params)
        self._graph.add(component)
        self._changed()
        return component

    def node(self, name: str) -> str:
        """Declare a node before attaching anything to it (a node left bare is an error at assembly)."""
        out = self._graph.declare(name)
        self._changed()
        return out

    def _changed(self) -> None:
        self._cache.clear()
        self._numeric.clear()

    @property
    def components(self) -> dict[str, Component]:
        """Components by name, in insertion order."""
        return dict(self._graph.components)

    def component(self, name: str) -> Component:
        try:
            return self._graph.components[name]
        except KeyError:
            raise UnknownNameError("component", name, self._graph.components) from None

    @property
    def nodes(self) -> list[str]:
        """Nodes in order of first use, ``ground`` first."""
        return self._graph.nodes()

    def check_node(self, node: str) -> str:
        """The canonical name of ``node``; :class:`UnknownNodeError` with a suggestion if the model has none such."""
        return self._graph.check_node(node)

    def graph(self):
        """The component graph as a networkx ``MultiGraph`` (edges keyed by component name)."""
        return self._graph.graph()

    # -- derived ---------------------------------------------------------------
    def _get(self, key: str, build):
        if key not in self._cache:
            self._cache[key] = build()
        return self._cache[key]

    @property
    def assembly(self) -> Assembly:
        return self._get("assembly", self._assemble)

    def _assemble(self) -> Assembly:
        self._check_node_names()
        return assemble(self._graph, self.registry, self._options)

    def _check_node_names(self) -> None:
        """Warn (:class:`NodeNameWarning`) of a node only one component touches whose name is a slip away from
        another node's (``crat`` beside ``cart``): most often a typo that left a part unconnected.  Names of one
        numbered family (``ball1``, ``ball2``) are not slips."""
        count: dict[str, int] = {}
        for comp in self._graph.components.values():
            for node in set(comp.nodes):
                count[node] = count.get(node, 0) + 1
        names = [n for n in count if n not in (GROUND, "0") and "." not in n]  # (a body's points are checked by it)
        family = {n: re.sub(r"\d+", "#", n) for n in names}
        for node in names:
            if count[node] != 1:
                continue
            others = [n for n in names if family[n] != family[node]]
            hint = closest(node, others)
            if hint and len(node) >= 3:
                user = next(c.name for c in self._graph.components.values() if node in c.nodes)
                warn(f"model {self.name!r}: node {node!r} is touched by one component only ({user!r}), and its name "
                     f"is close to another node's.{hint} If it is a slip, the part it holds is not connected.",
                     NodeNameWarning)

    @property
    def eq(self) -> Equations:
        return self._get("equations", lambda: Equations(self.assembly))

    @property
    def coordinates(self) -> list[Coordinate]:
        """The generalized coordinates, each a named function of ``t`` with a description."""
        return list(self.assembly.coordinates)

    @property
    def coordinate_names(self) -> list[str]:
        return [c.name for c in self.assembly.coordinates]

    @property
    def first_order(self) -> list[str]:
        """Coordinates with no inertia whose velocities follow from dissipation (first-order dynamics)."""
        return [self.eq.names[i] for i in self.eq.first_order]

    @property
    def kinetic_energy(self) -> sp.Expr:
        return self.eq.display(self.eq.T)

    @property
    def potential_energy(self) -> sp.Expr:
        return self.eq.display(self.eq.V)

    @property
    def lagrangian(self) -> sp.Expr:
        """``L = T - V`` in terms of the coordinates ``q(t)`` and their derivatives."""
        return self.eq.display(self.eq.L)

    @property
    def rayleigh(self) -> sp.Expr:
        """The Rayleigh dissipation function ``D``."""
        return self.eq.display(self.eq.D)

    @property
    def generalized_forces(self) -> sp.Matrix:
        """Generalized forces ``Q`` from the components' loads."""
        return self.eq.Q.applyfunc(self.eq.display)

    def load_power(self, *components: str) -> sp.Expr:
        """The power ``Σ Q_i q̇_i`` the loads of ``components`` (every load by default) deliver, in ``q(t)``,
        ``q̇(t)`` and ``t``: ``result.cumulative(model.load_power("pd"))`` is the work they have done, which the
        energy balance ``E(t) − E(0) = W(t) − (energy dissipated)`` holds (see :meth:`Result.cumulative`)."""
        shares = dict(self.eq.load_shares)
        for name in components:
            if name not in shares:
                raise UnknownNameError("component with a load", name, list(shares))
        v = self.eq.sym.v
        return self.eq.display(sp.Add(*[e * v[i] for name, share in self.eq.load_shares
                                        if not components or name in components for i, e in enumerate(share)]))

    @property
    def mass_matrix(self) -> sp.Matrix:
        """``M(q, t)`` of ``M q̈ = f``."""
        return self.eq.mass_matrix

    @property
    def forcing(self) -> sp.Matrix:
        """``f(q, q̇, t)`` of ``M q̈ = f``."""
        return self.eq.forcing

    @property
    def equations(self) -> list[sp.Eq]:
        """The equations of motion, one ``Eq(Σ M_ij q̈_j, f_i)`` per coordinate."""
        return self.eq.as_equalities()

    @property
    def parameters(self) -> list[sp.Symbol]:
        """Symbols that need numeric values before simulating, sorted by name."""
        if "equations" not in self._cache and not self._get("unvalued", self._unvalued):
            return []  # every symbol of the contributions has a value: nothing to derive to know that
        return sorted(self.eq.parameter_symbols(), key=lambda s: (s.name, str(s.assumptions0)))

    def _unvalued(self) -> bool:
        """Whether a symbol of the contributions (or the domains' constraints, eliminated solutions) has no value."""
        a = self.assembly
        known = set(a.values) | {t}
        parts = [e for c in a.generic.values()
                 for e in [c.T, c.V, c.D, c.G, *(x for load in c.loads for x in (load.force, load.velocity)),
                           *c.constraints, *c.velocity_constraints] if isinstance(e, (sp.Basic, sp.MatrixBase))]
        # each shared sub-expression visited once (SymPy's free_symbols walks a body's nested pose once per
        # occurrence: exponential in the depth of a spatial chain)
        if not symbols_of(parts) <= known:
            return True
        return any(not sp.Matrix(view.constraints).free_symbols <= known
                   for view in a.generic_views.values() if len(getattr(view, "constraints", ()))) \
            or any(not e.solution.free_symbols <= known for e in a.eliminated.values())  # θ = x / R, R cancelled

    def latex(self, dots: bool = False) -> str:
        """The Lagrangian, Rayleigh function and equations of motion as LaTeX: SymPy's notation (``x(t)``,
        ``d/dt x(t)``), or with ``dots=True`` the mechanics notation (``x``, ``ẋ``) the notebook display uses.

        >>> import lagrangian as lg
        >>> m = lg.Model("osc")
        >>> _ = m.add("mass", "m1", "p", m=2)
        >>> _ = m.add("spring", "k1", ("ground", "p"), k=8)
        >>> m.latex(dots=True).splitlines()[0]
        'L = - 4 x_{p}^{2} + \\\\dot{x}_{p}^{2}'
        """
        latex = lambda e: to_latex(e, dots)  # noqa: E731
        lines = [rf"L = {latex(self.lagrangian)}"]
        if self.eq.D != 0:
            lines.append(rf"D = {latex(self.rayleigh)}")
        lines.append(
            rf"{latex(self.mass_matrix)} \ddot{{q}} = {latex(self.forcing)},\quad "
            rf"q = {latex(sp.Matrix([c.function for c in self.coordinates]))}"
        )
        return "\n".join(lines)

    def __repr__(self) -> str:
        comps = self._graph.components
        derived = "assembly" in self._cache
        coords = f", coordinates {display.short(self.coordinate_names)}" if derived else ""
        return f"<Model {self.name!r}: {len(comps)} components ({display.short(comps)}){coords}>"

    #: Up to this many coordinates the notebook display shows the equations; beyond, their count.
    DISPLAY_EQUATIONS = 12

    def _repr_html_(self) -> str:
        """Components, coordinates, and the Lagrangian and equations in LaTeX (Jupyter)."""
        rows = []
        for c in self._graph.components.values():
            values = ", ".join(f"{k}={_shown(v)}" for k, v in c.params.items() if v is not None)
            rows.append([c.name, c.kind, " – ".join(c.nodes), values])
        parts = [display.table(["component", "kind", "nodes", "parameters"], rows)]
        note = None
        try:
            coords = self.coordinates
            parts.append(display.table(["coordinate", "meaning"], [[c.name, c.description] for c in coords]))
            if len(coords) <= self.DISPLAY_EQUATIONS:
                parts += [display.math(line) for line in self.latex(dots=True).splitlines()]
            else:
                note = f"{len(coords)} coordinates: model.latex() gives the equations."
        except LagrangianError as exc:  # a model that cannot be derived still shows its parts, and why
            note = f"not derived: {exc}"
        return display.block(f"model {self.name}", *parts, note=note)

    def draw(self, ax=None, path: str | None = None):
        """A picture of the component graph: nodes as points (ground hatched), two-terminal components as edges,
        others as boxes joined to their terminals, each labelled with its name and kind and coloured by domain;
        ``path`` saves it as PNG.  Returns the matplotlib Axes.

        >>> import lagrangian as lg
        >>> m = lg.Model("osc")
        >>> _ = m.add("mass", "m1", "p", m=0.3)
        >>> _ = m.add("spring", "k1", ("ground", "p"), k=40)
        >>> sorted(t.get_text() for t in m.draw().texts if t.get_text())
        ['ground', 'k1\\nspring', 'p\\nm1 (mass)']
        """
        ax = display.draw_components(list(self._graph.components.values()), f"model {self.name}", ax=ax)
        if path:
            ax.figure.savefig(path, dpi=120)
        return ax

    def schematic(self, path: str | None = None):
        """A circuit schematic of the model (:mod:`schemdraw`): its two-terminal elements with their symbols
        (resistors, capacitors, inductors, sources; a box with the kind for others), labelled with their names,
        the nodes on a row above ground; a two-port (a gyrator) as its numbered ports tied by a dashed line, and
        coupled inductors likewise.  For circuits, netlists and the circuit analogues of mechanisms (``map_model(
        model, ...).model.schematic()``); ``path`` saves it (PNG, SVG or PDF).  Returns the ``schemdraw.Drawing``.
        Any other component (a transducer between domains) is refused: ``draw()`` draws any model.

        >>> import lagrangian as lg
        >>> c = lg.Model("rc")
        >>> _ = c.add("voltage_source", "V1", ("in", "0"), E=1)
        >>> _ = c.add("resistor", "R1", ("in", "out"), R=1e3)
        >>> _ = c.add("capacitor", "C1", ("out", "0"), C=1e-6)
        >>> import schemdraw.elements as elm
        >>> drawn = c.schematic().elements
        >>> [sum(isinstance(e, kind) for e in drawn) for kind in (elm.Resistor, elm.Capacitor, elm.SourceV)]
        [1, 1, 1]
        """
        try:
            drawing = display.schematic(list(self._graph.components.values()), f"{self.name}")
        except ValueError as exc:
            raise ModelError(f"model {self.name!r}: {exc}.") from None
        if path:
            drawing.save(str(path))
        return drawing

    def describe(self) -> str:
        """A plain-text summary: components, coordinates, Lagrangian, equations."""
        out = [f"model {self.name!r}"]
        out.append("  components: " + ", ".join(f"{c.name} ({c.kind})" for c in self._graph.components.values()))
        out.append("  coordinates: " + ", ".join(f"{c.name} — {c.description}" for c in self.coordinates))
        if self.first_order:
            out.append("  first-order (no inertia): " + ", ".join(self.first_order))
        out += [f"  eliminated by {e.owner!r}: {n} = {sp.sstr(e.solution.xreplace(self.assembly.values))}"
                for n, e in self.assembly.eliminated.items()]
        out.append(f"  L = {sp.sstr(self.lagrangian)}")
        if self.eq.D != 0:
            out.append(f"  D = {sp.sstr(self.rayleigh)}")
        for e in self.equations:
            out.append(f"  {sp.sstr(e.lhs)} = {sp.sstr(e.rhs)}")
        return "\n".join(out)

    # -- simulation ------------------------------------------------------------
    @property
    def parameter_values(self) -> dict[str, float]:
        """The parameters given as numbers, by the name that gives them another value in ``params=``
        (``<parameter>_<component>``): ``simulate(..., params={"k_k1": 5.0})`` runs the model with that value
        without deriving anything again (compiled code takes parameter values at run time).  A nonzero entry of a
        vector is named by its index (``com_b_2``, ``points_arm_tip_0``; equal entries of one parameter share a
        name) and keeps its sign.

        >>> import lagrangian as lg
        >>> m = lg.Model("oscillator")
        >>> _ = m.add("mass", "m1", "p", m=0.3)
        >>> _ = m.add("spring", "k1", ("ground", "p"), k=40)
        >>> m.parameter_values
        {'m_m1': 0.3, 'k_k1': 40.0}
        """
        return {s.name: float(v) for s, v in self.assembly.values.items()}

    def _values(self, params: Mapping[str, float], *, overrides: bool = False) -> dict[sp.Symbol, float]:
        """Every parameter's value: those given as numbers, and ``params`` by name for the symbolic ones.
        ``overrides``: whether ``params`` may give another value to a parameter given as a number (the paths that
        evaluate the generic equations: simulation, exact solution); elsewhere that is refused, never ignored."""
        needed: dict[str, list[sp.Symbol]] = {}
        for s in self.parameters:  # symbols of one name but different assumptions share the value
            needed.setdefault(s.name, []).append(s)
        valued: dict[str, list[sp.Symbol]] = {}
        for s in self.assembly.values:  # parameters given as numbers: another value may be given by name
            valued.setdefault(s.name, []).append(s)
        unknown = [k for k in params if k not in needed and k not in valued]
        if unknown:
            raise UnknownNameError("parameter", unknown[0], {**needed, **valued})
        fixed = [k for k in params if k in valued and k not in needed]
        if fixed and not overrides:
            k = fixed[0]
            raise ModelError(
                f"parameter {k!r} of model {self.name!r} was given as a number ({float(self.assembly.values[valued[k][0]]):g}) "
                f"and this analysis uses that value: to vary it here, build the model with a symbol for it "
                f"(sympy.Symbol) and give its value in params=; simulate(params={{{k!r}: ...}}) does take another value."
            )
        missing = [k for k in needed if k not in params]
        if missing:
            raise ModelError(
                f"model {self.name!r} has symbolic parameters without values: {', '.join(missing)}. "
                f"Pass them, e.g. simulate(..., params={{{', '.join(f'{k!r}: ...' for k in missing)}}})."
            )
        values = {s: float(v) for s, v in self.assembly.values.items()}
        for k in params:
            given = params[k]
            if is_quantity(given) or split(given) is not None:  # "5 N/m": in the parameter's declared unit
                owner, pname, unit = self._declared_unit(k)
                try:
                    given = to_si(given, unit, "the value")
                except ModelError as exc:
                    raise ParameterError(owner, pname, f"{str(exc).removeprefix('the value: ')} (params={{{k!r}: ...}})") from None
            try:
                value = float(given)
            except (TypeError, ValueError):
                raise ModelError(f"parameter {k!r} must be a number, got {params[k]!r:.80}.") from None
            except OverflowError:  # an integer (or fraction) beyond a float
                raise ModelError(f"parameter {k!r} must be a finite number within the range of a float (±1.8e308), "
                                 f"got {params[k]!r:.40}: give it in units that keep it finite.") from None
            values.update(dict.fromkeys(needed.get(k, []) + valued.get(k, []), value))
        self._check_overrides({s: values[s] for k in params for s in valued.get(k, [])})
        subs = None  # (built when a parameter is an expression of others: most models have none)
        for comp in self._graph.components.values():
            for pname, spec in comp.parameters.items():
                value = comp.params.get(pname)
                if isinstance(value, sp.Expr) and value.free_symbols - {t}:
                    subs = subs or {s: sp.Float(v) for s, v in values.items()}
                    check_value(value.xreplace(subs), spec.check, comp.name, pname)
        return values

    def _declared_unit(self, name: str) -> tuple[str, str, str]:
        """``(component, parameter, unit)`` of the parameter named ``name`` (the model and ``""`` when no
        component declares one)."""
        for comp in self._graph.components.values():
            for pname, spec in comp.parameters.items():
                symbol, value = getattr(comp, "_symbols", {}).get(pname), comp.params.get(pname)
                if any(isinstance(s, sp.Symbol) and s.name == name for s in (symbol, value)):
                    return comp.name, pname, spec.unit
        return self.name, name, ""

    def _check_overrides(self, given: Mapping[sp.Symbol, float]) -> None:
        """Another value for a parameter given as a number obeys that parameter's rule (positive, ...)."""
        if given:
            self._get("override_rules", lambda: Rules(self._graph.components.values())).check(given)

    def numeric(self, params: Mapping[str, float] | None = None) -> NumericModel:
        """The model's numeric functions for the given parameter values (cached)."""
        values = self._values(params or {}, overrides=True)
        key = tuple(sorted((s.name, v) for s, v in values.items()))
        if key not in self._numeric:
            self._numeric[key] = NumericModel(self.eq, values, self.assembly.signals)
        return self._numeric[key]

    @_unchanged_while_running
    def simulate(
        self,
        t_end: float | tuple[float, float] = 10.0,
        *,
        initial: Mapping[str, float] | None = None, velocity: Mapping[str, float] | None = None,
        params: Mapping[str, float] | None = None, points: int = 1001, t_eval: Sequence[float] | None = None,
        method: Any = "DOP853", rtol: float | None = None, atol: float | None = None, max_step: float | None = None,
        step: float | None = None,
        energy_tol: float | bool | None = None,
        progress: bool | Callable[[float, float], None] = False,
        compiled: bool | str = "auto",
        events: Sequence[Event] = (),
        max_evaluations: float | None = None,
        sensitivities: Sequence[str] = (),
        **options: Any,
    ) -> Result:
        """Integrate the equations of motion with a registered method, or solve them exactly.

        ``initial`` and ``velocity`` give coordinates and velocities by name;
        any not given start at zero and are listed in ``Result.defaulted``
        (with an :class:`InitialConditionWarning`); a coordinate a constraint
        eliminates (``eliminate=``) is refused there, and in ``res`` from the others.  ``params`` gives values
        to symbolic parameters by name, and other values to parameters given
        as numbers (by the names of :attr:`parameter_values`), with nothing
        derived or recorded again.  Output is on ``points`` evenly spaced
        times, or on ``t_eval``.  ``progress=True`` reports progress on
        standard error every 5 % of the time span; a callable
        ``progress(t, t_end)`` is called instead.

        ``method`` names a registered integrator (``lagrangian integrators``
        lists them; see :mod:`lagrangian.integrate`) or is an integrator
        object.  Adaptive ones (``RK45``, ``DOP853`` — the default, stepped
        in C where the model has compiled code —, ``Radau``, ``BDF``,
        ``LSODA``, ...) take ``rtol`` (default 1e-9), ``atol`` (1e-12) and
        ``max_step``; fixed-step ones (``rk4``, ``verlet``,
        ``implicit_midpoint``, ``gauss_legendre``, ``variational``) take
        ``step``.  Further keyword ``options`` go to the method (e.g.
        ``stages=3``, ``rule="trapezoidal"``, ``newton_tol=1e-13``).  A
        method that cannot integrate the model (first-order coordinates, a
        Lagrangian that is not separable, ...) refuses it with a
        :class:`ModelError` saying why and what to use.  For a conservative
        model the energy (Jacobi integral) is checked after the run: a drift
        beyond ``energy_tol`` warns (:class:`~lagrangian.integrate.EnergyDriftWarning`).

        A model of at least ``lagrangian.numerics.assembled.ASSEMBLED_MIN`` coordinates whose components all say their
        energies in numbers (masses, springs, cubic ones too, dampers, forces: a chain of 10⁴) runs with the default
        method from its numeric assembly, nothing derived symbolically (:mod:`lagrangian.numerics.assembled`;
        ``Result.notes`` says so); ``params``, events, sensitivities, ``step`` or ``compiled`` take the symbolic path.

        ``method="exact"`` solves a linear time-invariant model exactly by
        matrix exponentials (:func:`lagrangian.linear.simulate_exact`; no
        tolerances apply).  A model that is not linear time-invariant, or an
        input that is not a sum of products of polynomials, exponentials,
        sines and cosines of ``t`` (piecewise ones included), is refused with
        a :class:`ModelError` naming the term.

        ``max_evaluations`` is the run's budget of evaluations (default 1e9):
        a run that at its pace would need more stops with an
        :class:`IntegrationError` saying where it got to — lower it to bound
        the work of models from untrusted input.  A run within it that, a few
        seconds in, would take more than a minute in all says so once
        (:class:`~lagrangian.SlowRunWarning`, with the time it projects),
        unless it reports its ``progress``.

        ``events`` are :class:`~lagrangian.Event` objects: zero-crossings of a
        function of time and state, located to 1e-14 relative, that end the
        run (``terminal``) or change its state (``action``) — a ball that
        stops at the floor, a velocity reversed at a wall; they are listed
        in ``Result.events`` (see :mod:`lagrangian.numerics.events`).  Every
        adaptive and fixed-step method takes them; ``method="exact"`` does
        not.

        ``sensitivities`` names parameters (of :attr:`parameter_values`, or symbolic ones) and initial values (``"x_p"``,
        ``"x_p'"``) whose forward sensitivities are integrated with the state: ``res.sensitivity("x_p", "k_k1")`` is
        ``∂x_p(t)/∂k_k1`` (adaptive methods; no events; with constraints, what they do not hold:
        :mod:`lagrangian.numerics.sensitivity`).

        ``method="auto"`` picks one from the model's properties — exact for
        a linear time-invariant model, an implicit method for a stiff one
        (eigenvalues of the linearization at the start), a symplectic one for
        a long conservative run at a loose tolerance, DOP853 or RK45
        otherwise — and says what and why in ``Result.method`` and
        ``Result.notes`` (see :func:`lagrangian.integrate.choose`).

        ``compiled`` chooses how the right-hand side, the energies and the
        outputs are evaluated (:mod:`lagrangian.codegen`): ``"auto"``
        (default) — this model's native library when it has been built
        before (in this process or in the disk cache), else its tapes run by
        the tape interpreter, which is compiled once per machine and shared by
        every model, so nothing is compiled for the model and it runs the
        moment its equations are derived; ``"tape"`` — always the tape;
        ``True`` (or ``"native"``) — native code: the model's tapes printed as
        C and compiled once (0.1–0.5 s; cached on disk, so later runs of the
        same model load it at once), about twice as fast per evaluation as the
        tape, which pays for runs beyond 10⁵–10⁶ evaluations; ``False`` —
        NumPy.  Without a C compiler, or for a model with Python-callable
        signals, compiled code falls back to NumPy (with a note in
        ``Result.notes`` when it was asked for).  Measured on the n-link
        pendulum (n = 3–10): 1.2–2.2 µs per evaluation from Python on the
        tape, 1.1–1.5 native, 11–44 with NumPy; in the stepping loops of
        ``dopri5_c``, ``rk4_c`` and ``verlet_c``, 0.2–1.2 µs on the tape and
        0.1–0.5 native.

        >>> import lagrangian as lg
        >>> m = lg.Model("free fall")
        >>> _ = m.add("mass", "m", "p", m=1)
        >>> _ = m.add("gravity", "g", g=10)
        >>> res = m.simulate(1, initial={"x_p": 0}, velocity={"x_p": 0}, points=3)
        >>> [round(float(x), 9) for x in res["x_p"]]  # x = -g t²/2
        [0.0, -1.25, -5.0]
        >>> m.simulate(1, initial={"x_p": 0}, velocity={"x_p": 0}, method="auto").method
        'exact'
        """

        # a large linear model with every parameter valued is solved from its stamps, never derived symbolically
        # (nor assembled symbolically, when its components say their contributions in numbers)
        # so is a large one of many lumped components under the default method, nonlinear ones included
        local = _assembled.stamps_for_run(self) if _assembled.wanted(method, params, events, sensitivities, compiled,
                                                                     step) else None
        st, names, params, numeric = (local, list(local.names), {}, True) if local is not None else \
            prepared(self, params, method in ("auto", "exact") and not events, initial, velocity)
        dim = len(names) + len(st.inertial if st is not None else self.eq.inertial)
        span = check_span(t_end)
        run = RunOptions(
            span=span,
            initial=check_state("initial", check_mapping("initial", initial, names)),
            velocity=check_state("velocity", check_mapping("velocity", velocity, names)),
            params=params,
            points=points,
            t_eval=t_eval,
            method=method,
            rtol=check_positive("rtol", rtol),
            atol=check_atol(atol, dim),
            max_step=check_max_step(max_step, span),
            step=check_positive("step", step),
            energy_tol=check_energy_tol(energy_tol),
            progress=check_progress(progress),
            compiled=compiled,
            events=check_events(events),
            options=dict(options),
            max_evaluations=check_positive("max_evaluations", max_evaluations, infinite=True),
        )
        check_grid(run.span, points, t_eval, dim)
        res = self._solve(run, local, st, numeric, sensitivities)
        res.source = self  # what it animates
        return res

    def _solve(self, run: RunOptions, local, st, numeric: bool, sensitivities: Sequence[str]) -> Result:
        """The run of :meth:`simulate`, checked: by the method it names, or the one ``"auto"`` picks."""
        if run.events and run.method == "exact":
            raise ModelError("method='exact' solves the whole span at once and takes no events: use an adaptive "
                             "method (DOP853, RK45, Radau) or method='auto'.")
        if local is not None:
            return _assembled.simulate_assembled(self, run, local, self.registry.integrators)
        if _sensitivity.asked(sensitivities):
            return _sensitivity.simulate(self, run, sensitivities)
        not_exact = None
        if run.method == "auto" and st is not None:
            try:
                res = simulate_exact(self, run.span, initial=run.initial, velocity=run.velocity, params=run.params,
                                     points=run.points, t_eval=run.t_eval, progress=run.progress)
                res.notes.insert(0, "auto: exact, the model is linear time-invariant (assembled from its components' "
                                    + ("numbers)" if numeric else "stamps)"))
                return res
            except ModelError as exc:  # an input the exact solution does not take: integrate (not tried again)
                _log.info("%s: auto: not solved exactly: %s", self.name, exc)
                not_exact = exc
        if run.method == "auto":
            return self._auto(run, not_exact)
        if run.method == "exact":
            if run.options or run.step is not None:
                raise ModelError(f"method='exact' takes no step or method options (got {', '.join([*run.options, *(['step'] if run.step is not None else [])])}).")
            return simulate_exact(self, run.span, initial=run.initial, velocity=run.velocity, params=run.params,
                                  points=run.points, t_eval=run.t_eval, progress=run.progress)
        resolve(run.method, self.registry.integrators)  # an unknown name fails before any derivation
        return self._integrate(run)

    def _auto(self, run: RunOptions, not_exact: ModelError | None = None) -> Result:
        """``method="auto"``: the method :func:`~lagrangian.integrate.choose` picks, with its notes (``not_exact``:
        why the exact solution, tried already from the stamps, does not apply)."""
        numeric = self.numeric(run.params)
        y0, _ = initial_state(self.eq, run.initial, run.velocity, warn=False)
        problem = self._get(("problem", id(numeric)), lambda: Problem(numeric, self.name))
        rtol = 1e-9 if run.rtol is None else run.rtol
        lti = not run.events and not_exact is None and self._linear(run.params)
        choice = choose(problem, run.span, y0, rtol=rtol, linear_exact=lti, integrators=self.registry.integrators)
        if not_exact is not None:
            choice.notes.insert(0, f"auto: not solved exactly: {not_exact}")
        if choice.method == "exact":
            try:
                res = simulate_exact(self, run.span, initial=run.initial, velocity=run.velocity, params=run.params,
                                     points=run.points, t_eval=run.t_eval, progress=run.progress)
                res.notes[:0] = choice.notes
                return res
            except ModelError as exc:
                choice = choose(problem, run.span, y0, rtol=rtol, integrators=self.registry.integrators)
                choice.notes.insert(0, f"auto: not solved exactly: {exc}")
        for note in choice.notes:
            _log.info("%s: %s", self.name, note)
        picked = self.registry.integrators[choice.method]
        extra = {k: v for k, v in choice.options.items() if k != "step"} | dict(run.options)
        if picked.kind == "adaptive":  # the tolerances were asked of auto; a step was not
            return self._integrate(replace(run, method=picked, step=None, options=extra, notes=tuple(choice.notes)))
        return self._integrate(replace(run, method=picked, rtol=None, atol=None, max_step=None,
                                       step=choice.options["step"], options=extra, notes=tuple(choice.notes)))

    _span = staticmethod(check_span)
    interact = sliders.interact  # sliders over parameters, each move a run and a chart again

    def _linear(self, params) -> bool:
        """Whether the model is linear time-invariant (so ``method="exact"`` may apply): in numbers where it is
        assembled so (no symbolic derivation), else from its state-space form."""
        try:
            if not params and "assembly" not in self._cache and stamped(self) is not None:
                return True
            state_space(self, params)
        except ModelError:
            return False
        return True

    def _no_state_callables(self, analysis: str) -> None:
        """Refuse, for ``analysis`` (which differentiates the forces), loads given as Python callables of the state."""
        held = self.assembly.state_callables
        if held:
            raise ModelError(f"model {self.name!r}: {analysis} differentiates the forces, and the loads given as Python "
                             f"callables of the state ({', '.join(held)}) have no derivatives to take. Write them as "
                             f"expressions of lagrangian.coordinate(...) and lagrangian.rate(...).")

    def to_fmu(self, path: str, kind: str = "model-exchange", *, model_identifier: str | None = None, **start: Any):
        """Write the model as an FMI 2.0 FMU to ``path`` (its path back); ``initial=``, ``velocity=``, ``params=`` give
        start values as in :meth:`simulate`.  What it holds and refuses: :mod:`lagrangian.numerics.fmu`."""
        return export_fmu(self, path, kind, identifier=model_identifier, **start)

    def _holonomic_only(self, analysis: str, error: type = ModelError) -> None:
        """Refuse, for ``analysis``, a model with constraints on velocities (nonholonomic), naming them."""
        owners = sorted({name for name, _ in self.assembly.velocity_constraint_list(generic=True)})
        if owners:
            raise error(f"model {self.name!r} has constraints on velocities (nonholonomic: {', '.join(map(repr, owners))}), "
                        f"which {analysis} does not cover: the Lagrange–d'Alembert equations hold them in a "
                        f"simulation (Model.simulate), an impact and a linearization (lagrangian.frequency.linearize "
                        f"about rest or a steady motion, velocity=; speed_sweep).")

    def _integrate(self, run: RunOptions) -> Result:
        integrator = resolve(run.method, self.registry.integrators)
        numeric = self.numeric(run.params)
        notes = list(run.notes)
        note = numeric.use_compiled(run.compiled)
        if note and not getattr(integrator, "needs_compiled", False):  # asked for, not usable (a compiled loop says so)
            notes.append(note)
        y0, defaulted = initial_state(self.eq, run.initial, run.velocity)
        check_start(numeric, self.name, run.span[0], y0, params=run.params)
        grid = check_grid(run.span, run.points, run.t_eval, len(y0))
        problem = self._get(("problem", id(numeric)), lambda: Problem(numeric, self.name))
        given = {"rtol": run.rtol, "atol": run.atol, "max_step": run.max_step, "step": run.step}
        wanted = {"rtol": 1e-9, "atol": 1e-12, "max_step": np.inf} if integrator.kind == "adaptive" else {"step": None}
        for key, value in given.items():
            if value is not None and key not in wanted:
                other = "step=" if integrator.kind == "adaptive" else "rtol=, atol= or max_step="
                raise ModelError(
                    f"method {integrator.name!r} is {integrator.kind}: {key}= does not apply to it "
                    f"({'give rtol/atol, or max_step to cap its steps' if integrator.kind == 'adaptive' else 'give step='}; "
                    f"{other} belongs to {'fixed-step' if integrator.kind == 'adaptive' else 'adaptive'} methods)."
                )
        run_options = {k: (given[k] if given[k] is not None else default) for k, default in wanted.items()}
        if integrator.kind == "fixed-step" and run_options["step"] is None:
            run_options.pop("step")
        return integrate(
            problem, integrator, run.span, y0,
            t_eval=grid, options={**run_options, **run.options}, model=self.name, defaulted=defaulted,
            integrators=self.registry.integrators, notes=notes, energy_tol=run.energy_tol, progress=run.progress,
            events=run.events, max_evaluations=run.max_evaluations,
        )

    def save(self, path: Any) -> None:
        """Write this model to ``path`` as a versioned JSON model file, read back by :meth:`load` (the schema, and
        what a file cannot hold: :mod:`lagrangian.base.modelfile`); :class:`ModelFileError` naming what cannot."""
        modelfile.save(path, self.name, self._options, self._graph.declared, self._graph.components.values(),
                       self.registry)

    @classmethod
    def load(cls, path: Any, registry: Registry | None = None, *, max_bytes: int = modelfile.MAX_BYTES) -> "Model":
        """The model a file written by :meth:`save` describes, validated and never executed; kinds from
        ``registry`` (the installed plugins by default).  :class:`ModelFileError` at the JSON pointer of the fault."""
        return modelfile.load(path, cls, registry, max_bytes=max_bytes)
