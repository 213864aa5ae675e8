"""Built-in plugin: lumped circuits.

The ``electrical`` domain picks coordinates from a *normal tree* of the
network (voltage sources, then capacitors, resistors, inductors; current
sources never), chosen with the model option ``formulation``:

- ``"charge"`` (loop charges; the force–voltage analogy): one coordinate per
  chord of the tree, named ``q_<chord>``, the charge that has passed through
  that component; the fundamental loop of each chord carries it.  Inductors
  give ``T = ½ L q̇²``, capacitors ``V = q²/2C``, resistors ``D = ½ R q̇²``;
  voltage sources are generalized forces, current sources fix their loop's
  charge.
- ``"flux"`` (node flux linkages; the force–current analogy): one coordinate
  per tree branch, named ``lambda_<node>`` for a branch from a node to
  ground (the node's flux linkage, whose rate is the node voltage) and
  ``lambda_<component>`` otherwise (the flux linkage across that
  component).  Capacitors give ``T = ½ C λ̇²``, inductors ``V = λ²/2L``,
  resistors ``D = λ̇²/2R``; current sources are generalized forces, voltage
  sources fix their branch's flux.

Branches follow SPICE's orientation: a component on nodes ``(a, b)``
carries current from ``a`` to ``b`` through itself, and its voltage is
``v_a − v_b``; a voltage source makes ``v_a − v_b = E``; a current source
drives ``I`` from ``a`` through itself to ``b``.

>>> import lagrangian as lg
>>> m = lg.Model("parallel", formulation="flux")
>>> for kind, name, value in [("capacitor", "C1", {"C": 1}), ("inductor", "L1", {"L": 1})]:
...     _ = m.add(kind, name, ("n1", "0"), **value)
>>> m.coordinate_names
['lambda_n1']
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from lagrangian import (
    GROUND,
    Component,
    Contribution,
    Coordinate,
    Domain,
    DomainView,
    Example,
    Incidence,
    Linear,
    LinearContext,
    Load,
    ModelError,
    Network,
    Option,
    Parameter,
    Quantity,
    hookimpl,
)
from lagrangian.base.component import t
from lagrangian.derive import time_derivative, time_integral
from lagrangian.network import fundamental_loops, normal_tree, tree_potentials
from lagrangian.spice import SpiceElement, spice_expression, spice_waveform
from lagrangian.base import deferred as _deferred

sp = _deferred.module("sympy", globals())


@dataclass
class ElectricalView(DomainView):
    """Branch quantities of the circuit, in the model's formulation."""

    formulation: str = "charge"
    branch: dict[str, sp.Expr] = field(default_factory=dict)

    def branch_value(self, key: str) -> sp.Expr:
        """The branch charge (charge formulation) or flux linkage (flux formulation) of edge ``key``."""
        return self.branch[key]

    def branch_meaning(self, key: str, rate: bool = False) -> str:
        """``"charge through C1 [C]"`` (its rate: the current) or ``"flux linkage of C1 [Wb]"`` (its rate: the
        voltage), as the formulation has it; the voltage of a charge-formulation branch is ``v(C1)``."""
        if self.formulation == "charge":
            return f"current through {key} [A]" if rate else f"charge through {key} [C] (its voltage: v({key}))"
        return f"voltage across {key} [V]" if rate else f"flux linkage of {key} [Wb] (its current: i({key}))"

    def _get(self, component: Component, wanted: str, branch: int) -> sp.Expr:
        if self.formulation != wanted:
            raise ModelError(
                f"{component.kind} {component.name!r} asked for the branch {wanted} in the {self.formulation} formulation."
            )
        return self.branch[component.name if branch == 0 else f"{component.name}#{branch}"]

    def charge(self, component: Component, branch: int = 0) -> sp.Expr:
        """Charge that has passed through ``component`` (its ``branch``) from ``a`` to ``b`` (charge formulation)."""
        return self._get(component, "charge", branch)

    def current(self, component: Component, branch: int = 0) -> sp.Expr:
        """Current through ``component`` from ``a`` to ``b`` (charge formulation)."""
        return time_derivative(self.charge(component, branch), t)  # memoized: SymPy's diff is a third of assembly

    def flux(self, component: Component, branch: int = 0) -> sp.Expr:
        """Flux linkage ``λ_a − λ_b`` across ``component`` (flux formulation)."""
        return self._get(component, "flux", branch)

    def voltage(self, component: Component, branch: int = 0) -> sp.Expr:
        """Voltage ``v_a − v_b`` across ``component`` (flux formulation)."""
        return time_derivative(self.flux(component, branch), t)


def _integral(component: Component, value: Any, what: str) -> sp.Expr:
    """∫₀ᵗ value dt, symbolically, or a clear error."""
    if component.signals() or not isinstance(value, sp.Expr):
        raise ModelError(
            f"{component.kind} {component.name!r}: in this formulation its {what} fixes a coordinate and must be "
            f"integrated symbolically; give it as a SymPy expression of t, not a Python callable, "
            f"or choose the other formulation."
        )
    result = _antiderivative(value)
    if result.has(sp.Integral):
        raise ModelError(
            f"{component.kind} {component.name!r}: SymPy cannot integrate its {what} {value} in closed form; "
            f"choose the other formulation."
        )
    return result


@functools.lru_cache(maxsize=256)
def _antiderivative(value: sp.Expr) -> sp.Expr:
    """``∫₀ᵗ value dt``, remembered per expression (the domain builds its view more than once per model, in symbols
    and in numbers): in closed form for the waveforms of sources (``time_integral``: milliseconds where SymPy took
    2.4 s for a damped, delayed SIN), else by SymPy."""
    closed = time_integral(value, t)
    if closed is not None:
        return closed
    tau = sp.Dummy("tau", real=True)
    return sp.integrate(value.subs(t, tau), (tau, 0, t))


class ElectricalDomain(Domain):
    """Lumped circuits, in loop charges or node flux linkages."""

    name = "electrical"
    light_incidence = True  # its incidence reads nodes and edges only: no networkx for a circuit in numbers
    options = {
        "formulation": Option(
            "charge", "circuit coordinates: loop charges or node flux linkages", choices=("charge", "flux")
        )
    }

    @staticmethod
    def _tree(network: Network) -> tuple[dict[str, Component], set[str]]:
        """The components by edge key, and the normal tree: voltage sources, capacitors, resistors, inductors."""
        by_key = {k: d["component"] for _, _, k, d in network.graph.edges(keys=True, data=True)}

        def priority(key: str) -> float:
            comp = by_key[key]
            if comp.role == "across":
                return 0
            if comp.role == "through":
                return float("inf")
            return getattr(comp, "tree_priority", 2)

        return by_key, normal_tree(network.graph, GROUND, priority)

    def incidence(self, network: Network, options: dict[str, Any]) -> Incidence:
        """The coordinates of :meth:`build` and each branch's charge (flux linkage) over them, in numbers."""
        by_key, tree = self._tree(network)
        names: list[str] = []
        branch: dict[str, dict[int, float]] = {key: {} for key in by_key}
        prescribed: set[str] = set()
        if options["formulation"] == "charge":
            for chord, loop in fundamental_loops(network.graph, tree).items():
                if by_key[chord].role == "through":
                    prescribed.update(key for key, _ in loop)
                    continue
                names.append(f"q_{chord}")
                for key, sign in loop:
                    row = branch[key]
                    row[len(names) - 1] = row.get(len(names) - 1, 0.0) + sign
            return Incidence(names, branch, prescribed)
        drops: dict[str, dict[int, float] | None] = {}
        for u, v, key, data in network.graph.edges(keys=True, data=True):
            if key not in tree:
                continue
            if by_key[key].role == "across":
                drops[key] = None
                continue
            node = v if u == GROUND else u
            names.append(f"lambda_{node}" if GROUND in (u, v) else f"lambda_{key}")
            drops[key] = {len(names) - 1: -1.0 if GROUND in (u, v) and data["a"] != node else 1.0}
        node_flux: dict[str, dict[int, float] | None] = {}
        for node, path in tree_potentials(network.graph, tree, GROUND).items():
            total: dict[int, float] | None = {}
            for key, sign in path:
                if drops[key] is None:
                    total = None
                    break
                for i, c in drops[key].items():
                    total[i] = total.get(i, 0.0) + sign * c
            node_flux[node] = total
        for _, _, key, data in network.graph.edges(keys=True, data=True):
            a, b = node_flux[data["a"]], node_flux[data["b"]]
            if a is None or b is None:
                prescribed.add(key)
                continue
            row = dict(a)
            for i, c in b.items():
                row[i] = row.get(i, 0.0) - c
            branch[key] = row
        return Incidence(names, branch, prescribed)

    def build(self, network: Network, options: dict[str, Any]) -> ElectricalView:
        formulation = options["formulation"]
        by_key, tree = self._tree(network)
        view = ElectricalView(formulation=formulation)
        if formulation == "charge":
            chords: dict[str, sp.Expr] = {}
            loops = fundamental_loops(network.graph, tree)
            for chord, loop in loops.items():
                comp = by_key[chord]
                if comp.role == "through":
                    chords[chord] = _integral(comp, comp.I, "current")
                    continue
                path = " → ".join(k for k, _ in loop)
                coord = Coordinate.named(f"q_{chord}", f"charge through {comp.kind} {chord} (loop {path})")
                view.coordinates.append(coord)
                chords[chord] = coord.function
            terms: dict[str, list[sp.Expr]] = {key: [] for key in by_key}
            for chord, loop in loops.items():
                for key, sign in loop:
                    terms[key].append(sign * chords[chord])
            for key in by_key:  # one sum each: adding term by term made a branch in n loops cost n² (a source feeding
                view.branch[key] = sp.Add(*terms[key])  # 10⁴ elements in parallel: minutes)
        else:
            drops: dict[str, sp.Expr] = {}
            for u, v, key, data in network.graph.edges(keys=True, data=True):
                if key not in tree:
                    continue
                comp = by_key[key]
                if comp.role == "across":
                    drops[key] = _integral(comp, comp.E, "voltage")
                elif GROUND in (u, v):
                    node = v if u == GROUND else u
                    coord = Coordinate.named(f"lambda_{node}", f"flux linkage of node {node!r} (rate: node voltage)")
                    view.coordinates.append(coord)
                    drops[key] = coord.function if data["a"] == node else -coord.function
                else:
                    coord = Coordinate.named(f"lambda_{key}", f"flux linkage across {comp.kind} {key} (rate: its voltage)")
                    view.coordinates.append(coord)
                    drops[key] = coord.function
            potentials = tree_potentials(network.graph, tree, GROUND)
            node_flux = {n: sp.Add(*(s * drops[k] for k, s in path)) for n, path in potentials.items()}
            for u, v, key, data in network.graph.edges(keys=True, data=True):
                view.branch[key] = node_flux[data["a"]] - node_flux[data["b"]]
        return view


class _Element(Component):
    domain = "electrical"
    quantities = {"v": "voltage v_a − v_b", "i": "current from a through it to b"}

    def quantity(self, ctx, name: str) -> sp.Expr:
        """``"v"`` or ``"i"``: the branch's own rate in its formulation (current of a loop charge, voltage of a flux
        linkage); the other from the element's law (:meth:`law`)."""
        if name not in self.quantities:
            return super().quantity(ctx, name)
        own = "i" if ctx.view.formulation == "charge" else "v"
        if name == own and self.role is None:
            return ctx.view.current(self) if own == "i" else ctx.view.voltage(self)
        return self.law(ctx, name)

    def law(self, ctx, name: str) -> sp.Expr:
        """The quantity ``name`` that the formulation does not give directly, from the element's law."""
        other = "flux" if ctx.view.formulation == "charge" else "charge"
        raise ModelError(f"{self.kind} {self.name!r}: its {'voltage' if name == 'v' else 'current'} is not a function "
                         f"of the coordinates in the {ctx.view.formulation} formulation; use formulation={other!r}.")


def _rate(order: int = 1, c: float = 1.0) -> Quantity:
    """A quantity ``c · dᵒx/dtᵒ`` of the element's own branch quantity ``x``."""
    return Quantity(((0, order, c),))


def _coupled(component: Component, ctx) -> tuple[Any, ...] | None:
    """For an inductor: ``()`` when no coupling names it, ``(other inductor, row of the pair's inductance matrix,
    its own index)`` when one coupling does and gives its matrix in numbers, ``None`` otherwise."""
    couplings = [c for c in ctx.naming(component.name) if hasattr(c, "current_correction")]
    if not couplings:
        return ()
    got = couplings[0].numeric_inductance(ctx) if len(couplings) == 1 else None
    if got is None:
        return None
    names, inductance = got
    k = names.index(component.name)
    return names[1 - k], inductance, k


def _source(component: Component, letter: str, value: Any, ctx) -> SpiceElement:
    if isinstance(value, (sp.Basic, sp.MatrixBase)):
        value = value.xreplace(ctx.values)  # symbols of the waveform (an amplitude E, a frequency) as given values
    wave = spice_waveform(value)
    if wave is not None:
        return SpiceElement(letter, component.nodes, wave)
    return SpiceElement("B", component.nodes, f"{letter}={spice_expression(value)}")


class Inductor(_Element):
    """Inductor: magnetic co-energy ½ L i² (charge), or potential λ²/2L (flux)."""

    kind = "inductor"
    symbol = "Inductor2"
    tree_priority = 3
    parameters = {"L": Parameter("inductance", unit="H")}

    def contribute(self, ctx) -> Contribution:
        if ctx.view.formulation == "charge":
            return Contribution(T=self.L * ctx.view.current(self) ** 2 / 2)
        return Contribution(V=ctx.view.flux(self) ** 2 / (2 * self.L))

    def linear(self, ctx: LinearContext) -> Linear | None:
        L = ctx.number(self, "L")
        if L is None:
            return None
        coupled = _coupled(self, ctx)
        charge = ctx.options["formulation"] == "charge"
        own = Linear(T={(0, 0): L}, quantities={"i": _rate()}) if charge else Linear(V={(0, 0): 1 / L}, quantities={"v": _rate()})
        if coupled is None:  # its law holds couplings not given in numbers: no "v" (charge), "i" (flux) here
            return own
        if not coupled:
            own.quantities["v" if charge else "i"] = _rate(2, L) if charge else _rate(0, 1 / L)
            return own
        other, inductance, k = coupled  # v = L di/dt + M di₂/dt; i = (Γ λ)_k
        row = inductance[k] if charge else np.linalg.inv(inductance)[k]
        law = Quantity(((0, 2 if charge else 0, float(row[k])), (1, 2 if charge else 0, float(row[1 - k]))))
        return Linear(branches=((self.name, 0), (other, 0)), T=own.T, V=own.V,
                      quantities={**own.quantities, ("v" if charge else "i"): law})

    def spice(self, ctx) -> list[SpiceElement]:
        return [SpiceElement("L", self.nodes, self.L, state=("i", self._current(ctx)))]

    def _current(self, ctx) -> sp.Expr:
        if ctx.view.formulation == "charge":
            return ctx.view.current(self)
        # λ/L, plus what mutual couplings add
        return ctx.view.flux(self) / self.L + sum(
            (c.current_correction(ctx, self) for c in ctx.components if hasattr(c, "current_correction")), sp.Integer(0)
        )

    def law(self, ctx, name: str) -> sp.Expr:
        if name == "i":
            return self._current(ctx)
        # v = L di/dt + Σ M di_other/dt over the couplings that name it (its own in the charge formulation: here)
        total = self.L * time_derivative(ctx.view.current(self), t)
        for c in ctx.components:
            if hasattr(c, "current_correction") and self.name in c.params.values():
                other = next(x for x in c.inductors(ctx) if x.name != self.name)
                total += c.mutual(ctx) * time_derivative(ctx.view.current(other), t)
        return total

    @classmethod
    def example(cls) -> Example:
        return Example(("n1", "0"), {"L": 2}, context=[("capacitor", "C", ("n1", "0"), {"C": 0.5})])


class Capacitor(_Element):
    """Capacitor: potential q²/2C (charge), or electric co-energy ½ C v² (flux)."""

    kind = "capacitor"
    symbol = "Capacitor"
    tree_priority = 1
    parameters = {"C": Parameter("capacitance", unit="F")}

    def contribute(self, ctx) -> Contribution:
        if ctx.view.formulation == "charge":
            return Contribution(V=ctx.view.charge(self) ** 2 / (2 * self.C))
        return Contribution(T=self.C * ctx.view.voltage(self) ** 2 / 2)

    def linear(self, ctx: LinearContext) -> Linear | None:
        C = ctx.number(self, "C")
        if C is None:
            return None
        if ctx.options["formulation"] == "charge":
            return Linear(V={(0, 0): 1 / C}, quantities={"i": _rate(), "v": _rate(0, 1 / C)})
        return Linear(T={(0, 0): C}, quantities={"v": _rate(), "i": _rate(2, C)})

    def spice(self, ctx) -> list[SpiceElement]:
        v = ctx.view.charge(self) / self.C if ctx.view.formulation == "charge" else ctx.view.voltage(self)
        return [SpiceElement("C", self.nodes, self.C, state=("v", v))]

    def law(self, ctx, name: str) -> sp.Expr:
        if name == "v":
            return ctx.view.charge(self) / self.C
        return self.C * time_derivative(ctx.view.voltage(self), t)

    @classmethod
    def example(cls) -> Example:
        return Example(("n1", "0"), {"C": 0.5}, context=[("inductor", "L", ("n1", "0"), {"L": 2})])


class Resistor(_Element):
    """Resistor: Rayleigh dissipation ½ R i² (charge) or v²/2R (flux)."""

    kind = "resistor"
    symbol = "Resistor"
    tree_priority = 2
    parameters = {"R": Parameter("resistance", unit="Ω")}

    def contribute(self, ctx) -> Contribution:
        if ctx.view.formulation == "charge":
            return Contribution(D=self.R * ctx.view.current(self) ** 2 / 2)
        return Contribution(D=ctx.view.voltage(self) ** 2 / (2 * self.R))

    def linear(self, ctx: LinearContext) -> Linear | None:
        R = ctx.number(self, "R")
        if R is None:
            return None
        if ctx.options["formulation"] == "charge":
            return Linear(D={(0, 0): R}, quantities={"i": _rate(), "v": _rate(1, R)})
        return Linear(D={(0, 0): 1 / R}, quantities={"v": _rate(), "i": _rate(1, 1 / R)})

    def spice(self, ctx) -> list[SpiceElement]:
        return [SpiceElement("R", self.nodes, self.R)]

    def law(self, ctx, name: str) -> sp.Expr:
        return self.R * ctx.view.current(self) if name == "v" else ctx.view.voltage(self) / self.R

    @classmethod
    def example(cls) -> Example:
        return Example(
            ("n1", "n2"),
            {"R": 3},
            context=[("inductor", "L", ("n2", "0"), {"L": 1}), ("capacitor", "C", ("n1", "0"), {"C": 1})],
        )


class VoltageSource(_Element):
    """Ideal voltage source: v_a − v_b = E(t)."""

    kind = "voltage_source"
    symbol = "SourceV"
    role = "across"
    parameters = {"E": Parameter("source voltage", check="real", shape="signal", unit="V", vector=False)}

    def contribute(self, ctx) -> Contribution:
        if ctx.view.formulation == "charge":
            # power delivered to the rest of the circuit: −E · i_ab
            return Contribution(loads=[Load(-self.E, ctx.view.current(self))])
        return Contribution()

    def linear(self, ctx: LinearContext) -> Linear | None:
        if ctx.options["formulation"] != "charge":
            return None  # it fixes a branch's flux: the incidence says so
        return Linear(force={0: -1.0}, quantities={"v": Quantity(signal=1.0), "i": _rate()})

    def spice(self, ctx) -> list[SpiceElement]:
        return [_source(self, "V", self.E, ctx)]

    def law(self, ctx, name: str) -> sp.Expr:
        if name == "v":
            return self.E
        if ctx.view.formulation == "charge":
            return ctx.view.current(self)
        return super().law(ctx, name)

    @classmethod
    def example(cls) -> Example:
        return Example(
            ("n1", "0"),
            {"E": sp.cos(t)},
            context=[
                ("resistor", "R", ("n1", "n2"), {"R": 1}),
                ("inductor", "L", ("n2", "n3"), {"L": 1}),
                ("capacitor", "C", ("n3", "0"), {"C": 1}),
            ],
        )


class CurrentSource(_Element):
    """Ideal current source driving I(t) from a, through itself, to b."""

    kind = "current_source"
    symbol = "SourceI"
    role = "through"
    parameters = {"I": Parameter("source current", check="real", shape="signal", unit="A", vector=False)}

    def contribute(self, ctx) -> Contribution:
        if ctx.view.formulation == "flux":
            # power delivered to the rest of the circuit: −v_ab · I
            return Contribution(loads=[Load(-self.I, ctx.view.voltage(self))])
        return Contribution()

    def linear(self, ctx: LinearContext) -> Linear | None:
        if ctx.options["formulation"] != "flux":
            return None  # it fixes a loop's charge: the incidence says so
        return Linear(force={0: -1.0}, quantities={"i": Quantity(signal=1.0), "v": _rate()})

    def spice(self, ctx) -> list[SpiceElement]:
        return [_source(self, "I", self.I, ctx)]

    def law(self, ctx, name: str) -> sp.Expr:
        if name == "i":
            return self.I
        if ctx.view.formulation == "flux":
            return ctx.view.voltage(self)
        return super().law(ctx, name)

    @classmethod
    def example(cls) -> Example:
        return Example(
            ("0", "n1"),
            {"I": sp.sin(t)},
            context=[
                ("resistor", "R", ("n1", "0"), {"R": 2}),
                ("inductor", "L", ("n1", "0"), {"L": 1}),
                ("capacitor", "C", ("n1", "0"), {"C": 1}),
            ],
            options={"formulation": "flux"},
        )


class Gyrator(_Element):
    """Ideal gyrator two-port: ``v_ab = r·i_cd`` and ``v_cd = −r·i_ab`` (charge formulation).

    Lagrangian term ``G = r·q_cd·q̇_ab`` (it stores no energy).  It is the
    circuit analogue of a moving coil or a DC motor under the force–voltage
    analogy; in SPICE it is two current-controlled voltage sources.
    """

    kind = "gyrator"
    terminals = ("a", "b", "c", "d")
    tree_priority = 3
    parameters = {"r": Parameter("gyration resistance", check="real", unit="Ω")}

    def branches(self) -> list[tuple[str, str]]:
        a, b, c, d = self.nodes
        return [(a, b), (c, d)]

    def contribute(self, ctx) -> Contribution:
        if ctx.view.formulation != "charge":
            raise ModelError(f"gyrator {self.name!r} is defined in the charge formulation only: use formulation='charge'.")
        return Contribution(G=self.r * ctx.view.charge(self, 1) * ctx.view.current(self, 0))

    def linear(self, ctx: LinearContext) -> Linear | None:
        r = ctx.number(self, "r")
        if r is None or ctx.options["formulation"] != "charge":
            return None
        return Linear(G={(1, 0): r}, quantities={"i": _rate()})

    def spice(self, ctx) -> list[SpiceElement]:
        if not self.r.is_number:
            raise ModelError(f"gyrator {self.name!r}: its SPICE equivalent needs a numeric r, not {self.r}.")
        a, b, c, d = self.nodes
        r = float(self.r)
        return [
            SpiceElement("V", (a, "~p1"), "DC 0", tag="sense1"),
            SpiceElement("H", ("~p1", b), f"{{sense2}} {r!r}", tag="port1"),
            SpiceElement("V", (c, "~p2"), "DC 0", tag="sense2"),
            SpiceElement("H", ("~p2", d), f"{{sense1}} {-r!r}", tag="port2"),
        ]

    @classmethod
    def example(cls) -> Example:
        return Example(
            ("n1", "0", "n2", "0"),
            {"r": 2},
            context=[
                ("voltage_source", "V", ("n0", "0"), {"E": sp.sin(t)}),
                ("resistor", "R", ("n0", "n1"), {"R": 1}),
                ("inductor", "L1", ("n1", "0"), {"L": 1}),
                ("inductor", "L2", ("n2", "n3"), {"L": 1}),
                ("capacitor", "C2", ("n3", "0"), {"C": 1}),
            ],
        )


@hookimpl
def register_domains(register):
    register(ElectricalDomain())


@hookimpl
def register_component_types(register):
    for cls in (Inductor, Capacitor, Resistor, VoltageSource, CurrentSource, Gyrator):
        register(cls)


# -- analogies: circuit → mechanism (the inverse direction; mechanics declares the forward one) ---------

from lagrangian.analogy import AnalogyError, Element  # noqa: E402


def _anchored(build):
    """Mark a builder whose element must attach to the reference in a dual mapping."""
    build.anchored = True
    return build


def _grounded(component, a: str, b: str, what: str) -> tuple[str, int]:
    """The non-ground node of (a, b) and the sign of its position relative to the branch quantity."""
    if b == GROUND:
        return a, 1
    if a == GROUND:
        return b, -1
    raise AnalogyError(
        f"{component.kind} {component.name!r} between {a!r} and {b!r} would be {what} between two moving points; "
        f"a {what} is referred to the fixed frame. Use the other analogy."
    )


def _mass(c, p, value):
    node, sign = _grounded(c, *p.branch(), "a mass")
    return [Element("mass", f"m_{c.name}", node, {"m": value}, sign=sign)]


def _forces(c, p, F):
    a, b = p.branch()
    return [
        Element("force", f"F_{c.name}_{n}", n, {"F": s * F}, branch=None) for n, s in ((a, 1), (b, -1)) if n != GROUND
    ]


def _motion(c, p, value, what):
    node, sign = _grounded(c, *p.branch(), "a prescribed motion")
    return [Element("prescribed_motion", f"X_{c.name}", node, {"position": sign * _integral(c, value, what)}, branch=None)]


INVERSE_FORCE_CURRENT = {
    "capacitor": lambda c, p: _mass(c, p, c.C),
    "inductor": lambda c, p: [Element("spring", f"k_{c.name}", p.branch(), {"k": 1 / c.L})],
    "resistor": lambda c, p: [Element("damper", f"c_{c.name}", p.branch(), {"c": 1 / c.R})],
    "current_source": lambda c, p: _forces(c, p, -c.I),  # drives I into b: a force +I on b
    "voltage_source": lambda c, p: _motion(c, p, c.E, "voltage"),
}

INVERSE_FORCE_VOLTAGE = {
    "inductor": _anchored(lambda c, p: _mass(c, p, c.L)),
    "capacitor": lambda c, p: [Element("spring", f"k_{c.name}", p.branch(), {"k": 1 / c.C})],
    "resistor": lambda c, p: [Element("damper", f"c_{c.name}", p.branch(), {"c": c.R})],
    "voltage_source": lambda c, p: _forces(c, p, -c.E),  # delivers −E·i_ab = −E (v_a − v_b)
    "current_source": _anchored(lambda c, p: _motion(c, p, c.I, "current")),
}


@hookimpl
def register_analogues(register):
    for analogy, table in (("force-voltage", INVERSE_FORCE_VOLTAGE), ("force-current", INVERSE_FORCE_CURRENT)):
        for kind, build in table.items():
            register(kind, analogy, build)
