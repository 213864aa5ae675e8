"""Built-in plugin: electromechanical transducers, coupling circuits and motion in one Lagrangian.

Each transducer has two electrical terminals ``a``, ``b`` (its electrical
branch, branch 0, oriented ``a → b`` like every circuit element: current
``i`` flows from ``a`` through it to ``b``, its voltage is ``v_a − v_b``) and
one moving terminal: a node of the 1-D ``mechanical`` domain (position
``x`` against the fixed frame ``ground``, which holds the magnet or the
electrode; gaps are stated for ``x = 0``) or of the ``rotational`` domain
(angle ``θ`` against the grounded stator).  Power is conserved: the
electrical power absorbed, ``(v_a − v_b)·i``, is the mechanical power
delivered plus the rate of change of the energy the transducer stores.

===================  =======================================  ==========================================
kind                 charge formulation (q, i = q̇)            flux formulation (λ, v = λ̇)
===================  =======================================  ==========================================
moving_coil          L ∋ Bl·x·i  (as G = Bl·x·i)               not supported (ModelError)
dc_motor             L ∋ K·θ·i   (as G = K·θ·i)               not supported (ModelError)
variable_capacitor   V = q²/2C(x),  C(x) = εA/(gap − x)        T = ½ C(x) v²
solenoid             T = ½ L(x) i², L(x) = L0/(1 + x/x0)       V = λ²/2L(x)
===================  =======================================  ==========================================

Why the moving coil has no flux form: an ideal gyrator ties the coil's
flux linkage to the motion (``λ_ab = Bl·x``), a holonomic constraint between
two domains' coordinates that the domains cannot impose yet; its charge
form is an ordinary Lagrangian term.

Every transducer has a circuit analogue, so a model holding one runs in
ngspice as one deck (``lagrangian.compare.compare_with_ngspice(model, t_end,
analogy=...)``): its mechanical (rotational) part becomes the analogue
network and the transducer a two-port between its electrical branch and the
branch standing for its motion.

===================  ===============================  =====================================================
kind                 analogies                        two-port, and in SPICE
===================  ===============================  =====================================================
moving_coil          force-voltage                    ``gyrator``: two current-controlled voltage sources
dc_motor             torque-voltage                   ``gyrator``: two current-controlled voltage sources
variable_capacitor   force-voltage, force-current     ``capacitive_two_port``: q = C(x)·v held on an
                                                      internal capacitor by a B source; force q²/2εA
solenoid             force-voltage, force-current     ``inductive_two_port``: λ = ∫v on an internal node,
                                                      i = λ/L(x) a B source; force −λ²/(2 L0 x0)
===================  ===============================  =====================================================

The force–voltage analogy keeps the model's charge formulation (the default),
the force–current analogy needs ``formulation='flux'``.

The electrostatic actuator also gets two helpers: :func:`electrostatic_equilibria`
(equilibria of the plate at a DC voltage, their stability, the pull-in
voltage and displacement) and :func:`simulate_checked` (a simulation that
stops with :class:`GapClosedError` when a plate reaches its electrode).

>>> import lagrangian as lg
>>> m = lg.Model("shaker")
>>> _ = m.add("voltage_source", "E", ("n1", "0"), E=1)
>>> _ = m.add("inductor", "Le", ("n1", "n2"), L=1)
>>> _ = m.add("moving_coil", "coil", ("n2", "0", "cone"), Bl=2)
>>> _ = m.add("mass", "m", "cone", m=1)
>>> m.coordinate_names
['q_Le', 'x_cone']
>>> m.equations
[Eq(Derivative(q_Le(t), (t, 2)), 1 - 2*Derivative(x_cone(t), t)), Eq(Derivative(x_cone(t), (t, 2)), 2*Derivative(q_Le(t), t))]
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import sympy as sp

import lagrangian as lg
from lagrangian import GROUND, Component, Contribution, Example, ModelError, NumericalError, Parameter, hookimpl, t

__all__ = [
    "MovingCoil",
    "DCMotor",
    "VariableCapacitor",
    "Solenoid",
    "CapacitiveTwoPort",
    "InductiveTwoPort",
    "Equilibrium",
    "ElectrostaticEquilibria",
    "PullInError",
    "GapClosedError",
    "electrostatic_equilibria",
    "simulate_checked",
]


class PullInError(ModelError):
    """An electrostatic actuator has no stable equilibrium at the voltage asked for (it is past pull-in)."""


class GapClosedError(NumericalError):
    """A simulation reached a configuration where a variable capacitor's gap closes (C → ∞).

    ``component`` names the capacitor, ``time`` is when its plate reached the electrode.
    """

    def __init__(self, component: str, time: float, message: str):
        self.component = component
        self.time = time
        super().__init__(message)


# ---------------------------------------------------------------------------
# the components


class _Transducer(Component):
    """Two electrical terminals and one moving terminal; the electrical branch is branch 0."""

    domain = "electrical"
    #: domain of the moving terminal
    moving_domain = "mechanical"

    def __init__(self, name: str, nodes: tuple[str, ...], params: Mapping[str, Any]):
        super().__init__(name, nodes, params)
        if nodes and nodes[-1] == GROUND:
            raise ModelError(
                f"{self.kind} {name!r}: its moving terminal {self.terminals[-1]!r} is ground, so nothing can move; "
                f"connect it to a {self.moving_domain} node (a {'mass' if self.moving_domain == 'mechanical' else 'inertia'})."
            )

    def branches(self) -> list[tuple[str, str]]:
        """Branch 0: the coil ``a → b`` (electrical); branch 1: the moving node against the frame."""
        return [(self.nodes[0], self.nodes[1]), (self.nodes[2], GROUND)]

    def displacement(self, ctx) -> sp.Expr:
        """Position x (mechanical) or angle θ (rotational) of the moving terminal."""
        view = ctx.views[self.moving_domain]
        node = self.nodes[-1]
        if self.moving_domain == "rotational":
            return view.angle(node)
        if view.dim != 1:
            raise ModelError(
                f"{self.kind} {self.name!r} acts along one axis; the model's mechanical dimension is {view.dim}. "
                f"Use a 1-D model (dim=1)."
            )
        return view.position(node)[0]

    def _charge_only(self, ctx, law: str) -> None:
        if ctx.view.formulation != "charge":
            raise ModelError(
                f"{self.kind} {self.name!r} cannot be modelled in the {ctx.view.formulation} formulation: "
                f"as an ideal gyrator it ties the flux linkage across its coil to the motion ({law}), a constraint "
                f"between domains that this version cannot impose. Use Model(..., formulation='charge')."
            )


class MovingCoil(_Transducer):
    """Moving-coil (voice-coil) transducer: a coil on node ``p`` in a radial magnetic field fixed to ground.

    Conventions: a current ``i`` from ``a`` through the coil to ``b`` pushes
    ``p`` in +x with the force ``F = Bl·i``; a velocity ``ẋ`` induces the
    back-emf ``v_a − v_b = Bl·ẋ`` (a voltage drop along ``i``).  The coil
    absorbs the electrical power ``Bl·ẋ·i`` and delivers the same mechanical
    power ``F·ẋ``: it stores no energy (an ideal gyrator; model the coil's
    resistance and inductance with a resistor and an inductor in series).

    Lagrangian term (charge formulation): ``L ∋ Bl·x·q̇``.  The momentum of
    the charge ``∂L/∂q̇ ∋ Bl·x`` is the magnet's flux linked by the coil; the
    Euler–Lagrange equation of ``q`` gains ``d/dt(Bl·x) = Bl·ẋ`` (the
    back-emf) and that of ``x`` gains ``−∂L/∂x = −Bl·q̇`` (the force ``Bl·i``
    moved to the right-hand side).  ``−Bl·ẋ·q`` differs from it by the total
    derivative ``d/dt(Bl·x·q)`` and gives the same equations.  The term is
    linear in the velocities and stores no energy (a gyrator), so it is
    returned as the gyroscopic part ``G = Bl·x·q̇`` of ``L = T − V + G``;
    ``Result.E = T + V`` stays the stored energy.  Only the charge
    formulation is supported.
    """

    kind = "moving_coil"
    terminals = ("a", "b", "p")
    terminal_domains = ("electrical", "electrical", "mechanical")
    tree_priority = 3  # like an inductor: preferably a chord, whose charge is a coordinate
    parameters = {
        "Bl": Parameter(
            "force factor: flux density × coil wire length (negative reverses polarity)", check="real", unit="T m = N/A = V s/m"
        )
    }

    def contribute(self, ctx) -> Contribution:
        self._charge_only(ctx, "λ_ab = Bl·x")
        return Contribution(G=self.Bl * self.displacement(ctx) * ctx.view.current(self))

    @classmethod
    def example(cls) -> Example:
        return Example(
            ("n1", "0", "p"),
            {"Bl": 2},
            context=[
                ("inductor", "L", ("n1", "0"), {"L": 1}),
                ("mass", "m", "p", {"m": 1}),
                ("spring", "k", ("ground", "p"), {"k": 3}),
            ],
        )


class DCMotor(_Transducer):
    """Permanent-magnet DC motor (or generator): the rotational moving coil, shaft node against the grounded stator.

    Conventions: a current ``i`` from ``a`` through the armature to ``b``
    drives the shaft with the torque ``τ = K·i`` in +θ; a speed ``θ̇``
    induces the back-emf ``v_a − v_b = K·θ̇``.  In SI units the torque
    constant (N m/A) equals the back-emf constant (V s/rad), both ``K``.
    Lagrangian term (charge formulation): ``L ∋ K·θ·q̇``, returned as
    ``G = K·θ·q̇`` (see :class:`MovingCoil`); armature resistance and
    inductance are separate components.  Only the charge formulation is
    supported.
    """

    kind = "dc_motor"
    terminals = ("a", "b", "shaft")
    terminal_domains = ("electrical", "electrical", "rotational")
    moving_domain = "rotational"
    tree_priority = 3
    parameters = {
        "K": Parameter(
            "motor constant: torque per ampere = back-emf per rad/s (negative reverses polarity)",
            check="real",
            unit="N m/A = V s/rad",
        )
    }

    def contribute(self, ctx) -> Contribution:
        self._charge_only(ctx, "λ_ab = K·θ")
        return Contribution(G=self.K * self.displacement(ctx) * ctx.view.current(self))

    @classmethod
    def example(cls) -> Example:
        return Example(
            ("n1", "0", "shaft"),
            {"K": 0.5},
            context=[
                ("inductor", "La", ("n1", "0"), {"L": 1}),
                ("inertia", "J", "shaft", {"J": 1}),
                ("torsion_spring", "k", ("ground", "shaft"), {"k": 2}),
            ],
        )


class VariableCapacitor(_Transducer):
    """Parallel-plate electrostatic actuator: a plate on node ``p`` facing an electrode fixed to ground.

    ``x`` is the plate's displacement towards the electrode, so the gap is
    ``gap − x`` and ``C(x) = eps_A / (gap − x)``; the model holds for
    ``x < gap`` (:func:`simulate_checked` stops a simulation at contact).
    Charge formulation: ``V = q² (gap − x) / (2 eps_A)`` (the field energy
    q²/2C); flux formulation: ``T = ½ C(x) λ̇²`` (the electric co-energy).
    Either way the plate is attracted towards the electrode (+x) by
    ``F = q²/(2 eps_A) = ½ C'(x) v²``, which does not depend on the
    formulation.  With a spring ``k`` and a DC voltage the plate snaps onto
    the electrode above the pull-in voltage ``sqrt(8 k gap³ / (27 eps_A))``,
    reached at ``x = gap/3`` (see :func:`electrostatic_equilibria`).

    In ngspice it is a :class:`CapacitiveTwoPort` (behavioural sources), its
    plate's mass, spring and damper the analogue network: an actuator of
    1 cm² plates 100 µm apart on a 100 N/m spring, charged to 100 V through
    4.7 MΩ, agrees with ngspice to 1e-4 of each quantity's peak (step cap
    1 µs):

    >>> import lagrangian as lg
    >>> from lagrangian.compare import compare_with_ngspice
    >>> m = lg.Model("actuator")
    >>> _ = m.add("voltage_source", "V", ("n1", "0"), E=100)
    >>> _ = m.add("resistor", "R", ("n1", "n2"), R=4.7e6)
    >>> _ = m.add("variable_capacitor", "Cx", ("n2", "0", "plate"), eps_A=8.85e-16, gap=1e-4)
    >>> _ = m.add("mass", "m", "plate", m=1e-5)
    >>> _ = m.add("spring", "k", ("ground", "plate"), k=100)
    >>> _ = m.add("damper", "c", ("ground", "plate"), c=0.03)
    >>> cmp = compare_with_ngspice(m, 5e-3, analogy="force-voltage", max_step=1e-6)
    >>> [(r.label, r.meaning) for r in cmp.rows if r.label.startswith("v(T_Cx")]  # q/C0 and x/gap
    [('v(T_Cx.q)', '112994350282.486*q_R(t)'), ('v(T_Cx.x)', '10000.0*x_plate(t)')]
    >>> cmp.worst_rel < 1e-4
    True
    """

    kind = "variable_capacitor"
    terminals = ("a", "b", "p")
    terminal_domains = ("electrical", "electrical", "mechanical")
    tree_priority = 1  # like a capacitor
    parameters = {
        "eps_A": Parameter("permittivity × plate area, ε·A", unit="F m"),
        "gap": Parameter("gap between plate and electrode at x = 0", unit="m"),
    }

    def capacitance(self, x: Any) -> Any:
        """C(x) = eps_A / (gap − x)."""
        return self.eps_A / (self.gap - x)

    def contribute(self, ctx) -> Contribution:
        x = self.displacement(ctx)
        if ctx.view.formulation == "charge":
            return Contribution(V=ctx.view.charge(self) ** 2 * (self.gap - x) / (2 * self.eps_A))
        return Contribution(T=self.capacitance(x) * ctx.view.voltage(self) ** 2 / 2)

    @classmethod
    def example(cls) -> Example:
        return Example(
            ("n1", "0", "p"),
            {"eps_A": 1, "gap": 3},
            context=[
                ("inductor", "L", ("n1", "0"), {"L": 1}),
                ("mass", "m", "p", {"m": 1}),
                ("spring", "k", ("ground", "p"), {"k": 2}),
            ],
        )


class Solenoid(_Transducer):
    """Variable-inductance actuator (solenoid, reluctance actuator): a coil whose iron path has an air gap set by node ``p``.

    ``L(x) = L0 / (1 + x/x0)``: the reluctance of the magnetic circuit is
    that of the closed circuit (inductance ``L0`` at ``x = 0``) plus an air gap
    growing linearly with ``x``; ``x0`` is the gap opening that doubles the
    reluctance.  Charge formulation: ``T = ½ L(x) q̇²`` (magnetic co-energy);
    flux formulation: ``V = λ² / (2 L(x))`` (magnetic energy).  Either way the
    force on ``p`` is ``F = ½ i² L'(x) = −L0 i² / (2 x0 (1 + x/x0)²)``: the
    armature is pulled towards smaller x, closing the gap.  Valid for
    ``x > −x0``.

    In ngspice it is an :class:`InductiveTwoPort` (behavioural sources), the
    plunger's mass, spring and damper the analogue network: a 50 mH coil
    behind 50 Ω pulling a 10 g plunger on a 1000 N/m spring after a 5 V
    step agrees with ngspice to 1e-4 of each quantity's peak (step cap
    10 µs), and the plunger comes to rest at the root of
    ``k x = ½ (V/R)² L'(x)``:

    >>> import lagrangian as lg
    >>> from lagrangian.compare import compare_with_ngspice
    >>> m = lg.Model("plunger", formulation="flux")
    >>> _ = m.add("voltage_source", "V", ("n1", "0"), E=5)
    >>> _ = m.add("resistor", "R", ("n1", "n2"), R=50)
    >>> _ = m.add("solenoid", "S", ("n2", "0", "plunger"), L0=0.05, x0=2e-3)
    >>> _ = m.add("mass", "m", "plunger", m=0.01)
    >>> _ = m.add("spring", "k", ("ground", "plunger"), k=1000)
    >>> _ = m.add("damper", "c", ("ground", "plunger"), c=3)
    >>> cmp = compare_with_ngspice(m, 0.2, analogy="force-current", max_step=1e-5)
    >>> cmp.worst_rel < 1e-4
    True
    >>> x = float(2e-3 * cmp.spice["v(T_S.x)"][-1])  # v(T_S.x) is x/x0
    >>> round(x * 1e6, 3), round(1000 * x * (1 + x / 2e-3) ** 2 / (-0.05 * 0.1**2 / (2 * 2e-3)), 9)
    (-145.362, 1.0)
    """

    kind = "solenoid"
    terminals = ("a", "b", "p")
    terminal_domains = ("electrical", "electrical", "mechanical")
    tree_priority = 3  # like an inductor
    parameters = {
        "L0": Parameter("inductance at x = 0", unit="H"),
        "x0": Parameter("air-gap opening that halves the inductance", unit="m"),
    }

    def inductance(self, x: Any) -> Any:
        """L(x) = L0 / (1 + x/x0)."""
        return self.L0 / (1 + x / self.x0)

    def contribute(self, ctx) -> Contribution:
        x = self.displacement(ctx)
        if ctx.view.formulation == "charge":
            return Contribution(T=self.inductance(x) * ctx.view.current(self) ** 2 / 2)
        return Contribution(V=ctx.view.flux(self) ** 2 * (1 + x / self.x0) / (2 * self.L0))

    @classmethod
    def example(cls) -> Example:
        return Example(
            ("n1", "0", "p"),
            {"L0": 1, "x0": 4},
            context=[
                ("capacitor", "C", ("n1", "0"), {"C": 1}),
                ("mass", "m", "p", {"m": 1}),
                ("spring", "k", ("ground", "p"), {"k": 2}),
            ],
        )


# ---------------------------------------------------------------------------
# circuit analogues: a variable capacitor or a solenoid as an electrical two-port


class _TwoPort(Component):
    """Electrical two-port standing for a transducer: port ``a → b`` its coil or plates, port ``c → d`` its motion.

    Under an analogy the transducer's moving terminal becomes a circuit
    branch whose branch quantity is the displacement: the charge of
    ``c → d`` in the charge formulation (force–voltage: velocity ↔ current,
    force ↔ voltage), its flux linkage in the flux formulation (force–current:
    velocity ↔ voltage, force ↔ current).  The two-port keeps the
    transducer's Lagrangian term with ``x`` read from that branch.
    """

    domain = "electrical"
    terminals = ("a", "b", "c", "d")

    def branches(self) -> list[tuple[str, str]]:
        a, b, c, d = self.nodes
        return [(a, b), (c, d)]

    def displacement(self, ctx) -> sp.Expr:
        """The branch quantity of port ``c → d``: the displacement x of the transducer it stands for."""
        if ctx.view.formulation == "charge":
            return ctx.view.charge(self, 1)
        return ctx.view.flux(self, 1)

    def _motion_port(self, ctx, force: sp.Expr, controls: tuple, scale: sp.Expr) -> list:
        """SPICE elements of port ``c → d``: the force as a source, and x integrated on an internal node.

        Charge formulation: a 0 V sense source measures ``ẋ`` (the port
        current) and a behavioural voltage source ``v_cd = −F`` in series
        with it drives the mesh; flux formulation: a behavioural current
        source ``i_cd = −F`` injects ``F`` into node ``c`` and ``ẋ = v_cd``.
        Either way ``ẋ / scale`` charges a 1 F capacitor on the internal node
        ``x``, whose voltage is then ``x / scale`` (of order one).
        """
        from lagrangian.spice import Behaviour, SpiceElement

        c, d = self.nodes[2:]
        rate = sp.Dummy("rate")
        if ctx.view.formulation == "charge":
            out = [
                SpiceElement("V", (c, "~m"), "DC 0", tag="sense_x"),
                SpiceElement("B", ("~m", d), Behaviour("V", -force, controls), tag="force"),
                SpiceElement("B", (GROUND, "~x"), Behaviour("I", rate / scale, ((rate, ("i", "sense_x")),)), tag="integrate_x"),
            ]
        else:
            out = [
                SpiceElement("B", (c, d), Behaviour("I", -force, controls), tag="force"),
                SpiceElement("B", (GROUND, "~x"), Behaviour("I", rate / scale, ((rate, ("v", c, d)),)), tag="integrate_x"),
            ]
        out.append(SpiceElement("C", ("~x", GROUND), 1, state=("v", self.displacement(ctx) / scale), tag="x"))
        return out


class CapacitiveTwoPort(_TwoPort):
    """Circuit analogue of a variable capacitor: ``C(x) = eps_A/(gap − x)`` across ``a → b``, x the branch quantity of ``c → d``.

    Lagrangian term as the variable capacitor's (``V = q_ab² (gap − x)/(2 eps_A)``
    in the charge formulation, ``T = ½ C(x) v_ab²`` in the flux formulation).
    In SPICE (behavioural sources; internal nodes ``u``, ``uc``, ``x``):

    - port ``a → b``: the charge ``q = C(x)·v_ab`` sits on an internal
      capacitor ``C0 = eps_A/gap`` held at ``u = q/C0 = v_ab/(1 − x/gap)`` by
      ``B V=v(a,b)/(1 - v(x))``; a current-controlled current source
      ``F`` copies its current ``dq/dt`` into the port;
    - port ``c → d``: the force ``F = ½ v² C'(x) = q²/(2 eps_A) = eps_A u²/(2 gap²)``
      (towards +x) as a source, and ``x/gap`` integrated on the 1 F node ``x``
      (see ``_motion_port``).

    The state quantities read back are ``v(<name>.q) = q/C0`` and ``v(<name>.x) = x/gap``.
    """

    kind = "capacitive_two_port"
    tree_priority = 1
    parameters = VariableCapacitor.parameters
    capacitance = VariableCapacitor.capacitance
    contribute = VariableCapacitor.contribute

    def spice(self, ctx) -> list:
        from lagrangian.spice import Behaviour, SpiceElement

        a, b = self.nodes[:2]
        v, u, xs = sp.Dummy("v"), sp.Dummy("u"), sp.Dummy("x")
        C0 = self.eps_A / self.gap
        x = self.displacement(ctx)
        q = ctx.view.charge(self) if ctx.view.formulation == "charge" else self.capacitance(x) * ctx.view.voltage(self)
        return [
            SpiceElement("B", ("~u", GROUND), Behaviour("V", v / (1 - xs), ((v, ("v", a, b)), (xs, ("v", "~x")))), tag="hold_q"),
            SpiceElement("V", ("~u", "~uc"), "DC 0", tag="sense_q"),
            SpiceElement("C", ("~uc", GROUND), C0, state=("v", q / C0), tag="q"),
            SpiceElement("F", (a, b), "{sense_q} 1", tag="port"),
            *self._motion_port(ctx, self.eps_A * u**2 / (2 * self.gap**2), ((u, ("v", "~uc")),), self.gap),
        ]

    @classmethod
    def example(cls) -> Example:
        return Example(
            ("n1", "0", "n2", "0"),
            {"eps_A": 1, "gap": 3},
            context=[
                ("inductor", "L", ("n1", "0"), {"L": 1}),
                ("inductor", "Lm", ("n2", "n3"), {"L": 1}),
                ("capacitor", "Ck", ("n3", "0"), {"C": 0.5}),
            ],
        )


class InductiveTwoPort(_TwoPort):
    """Circuit analogue of a solenoid: ``L(x) = L0/(1 + x/x0)`` across ``a → b``, x the branch quantity of ``c → d``.

    Lagrangian term as the solenoid's (``T = ½ L(x) i_ab²`` in the charge
    formulation, ``V = λ_ab²/(2 L(x))`` in the flux formulation).  In SPICE
    (behavioural sources; internal nodes ``lam``, ``x``):

    - port ``a → b``: the flux linkage ``λ = ∫ v_ab dt`` is integrated on the
      1 F node ``lam`` as ``λ/L0`` (``B I=v(a,b)/L0`` into it), and the port
      draws ``i = λ/L(x) = v(lam)·(1 + v(x))``, a behavioural current source;
    - port ``c → d``: the force ``F = ½ i² L'(x) = −λ²/(2 L0 x0) = −L0 v(lam)²/(2 x0)``
      (towards −x, closing the gap) as a source, and ``x/x0`` integrated on
      the 1 F node ``x`` (see ``_motion_port``).

    The state quantities read back are ``v(<name>.lam) = λ/L0`` and ``v(<name>.x) = x/x0``.
    """

    kind = "inductive_two_port"
    tree_priority = 3
    parameters = Solenoid.parameters
    inductance = Solenoid.inductance
    contribute = Solenoid.contribute

    def spice(self, ctx) -> list:
        from lagrangian.spice import Behaviour, SpiceElement

        a, b = self.nodes[:2]
        v, lam, xs = sp.Dummy("v"), sp.Dummy("lam"), sp.Dummy("x")
        x = self.displacement(ctx)
        flux = self.inductance(x) * ctx.view.current(self) if ctx.view.formulation == "charge" else ctx.view.flux(self)
        return [
            SpiceElement("B", (GROUND, "~lam"), Behaviour("I", v / self.L0, ((v, ("v", a, b)),)), tag="integrate_lam"),
            SpiceElement("C", ("~lam", GROUND), 1, state=("v", flux / self.L0), tag="lam"),
            SpiceElement("B", (a, b), Behaviour("I", lam * (1 + xs), ((lam, ("v", "~lam")), (xs, ("v", "~x")))), tag="port"),
            *self._motion_port(ctx, -self.L0 * lam**2 / (2 * self.x0), ((lam, ("v", "~lam")),), self.x0),
        ]

    @classmethod
    def example(cls) -> Example:
        return Example(
            ("n1", "0", "n2", "0"),
            {"L0": 1, "x0": 4},
            context=[
                ("capacitor", "C", ("n1", "0"), {"C": 1}),
                ("inductor", "Lm", ("n2", "n3"), {"L": 1}),
                ("capacitor", "Ck", ("n3", "0"), {"C": 0.5}),
            ],
        )


@hookimpl
def register_component_types(register):
    for cls in (MovingCoil, DCMotor, VariableCapacitor, Solenoid, CapacitiveTwoPort, InductiveTwoPort):
        register(cls)


# ---------------------------------------------------------------------------
# electrostatic actuators: equilibria, pull-in, contact


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


def _two_port(kind: str, names: tuple[str, ...]):
    """Analogue builder: the transducer as a ``kind`` two-port between its electrical branch and its node's port."""
    from lagrangian.analogy import Element

    def build(c, ports):
        params = {name: getattr(c, name) for name in names}
        return [Element(kind, f"T_{c.name}", (*ports.branch(0), *ports.branch(1)), params, branch=((0, 0), (1, 1)))]

    return build


@hookimpl
def register_analogues(register):
    """Analogues of the transducers, for coupled models mapped to one circuit.

    Under the force– (torque–) voltage analogy a moving coil (DC motor)
    becomes a gyrator between its coil and its node's mesh.  A variable
    capacitor becomes a ``capacitive_two_port``, a solenoid an
    ``inductive_two_port``, under both the force–voltage analogy (the model in
    the charge formulation; x is the charge of the plate's mesh) and the
    force–current analogy (the flux formulation; x is the flux linkage of the
    plate's node).
    """
    from lagrangian.analogy import Element

    for analogy in ("force-voltage", "force-current"):
        register("variable_capacitor", analogy, _two_port("capacitive_two_port", ("eps_A", "gap")))
        register("solenoid", analogy, _two_port("inductive_two_port", ("L0", "x0")))

    register(
        "moving_coil",
        "force-voltage",
        lambda c, ports: [
            Element("gyrator", f"G_{c.name}", (*ports.branch(0), *ports.branch(1)), {"r": c.Bl}, branch=((0, 0), (1, 1)))
        ],
    )
    register(
        "dc_motor",
        "torque-voltage",
        lambda c, ports: [
            Element("gyrator", f"G_{c.name}", (*ports.branch(0), *ports.branch(1)), {"r": c.K}, branch=((0, 0), (1, 1)))
        ],
    )
