"""The transducers plugin's components: the :class:`MovingCoil`, the :class:`DCMotor`, the
:class:`VariableCapacitor` and the :class:`Solenoid`, each an electrical branch coupled to a moving node."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from lagrangian import GROUND, Component, Contribution, Example, Linear, ModelError, Parameter
from lagrangian.base import deferred as _deferred

sp = _deferred.module("sympy", globals())


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

    def linear(self, ctx):
        """``G = Bl·x·q̇`` in numbers (charge formulation, one axis): ``x`` is branch 1, ``q`` branch 0."""
        Bl = ctx.number(self, "Bl")
        if Bl is None or ctx.options.get("formulation") != "charge" or ctx.options.get("dim", 1) != 1:
            return None
        return Linear(G={(1, 0): Bl})

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

    def linear(self, ctx):
        """``G = K·θ·q̇`` in numbers (charge formulation): ``θ`` is branch 1, ``q`` branch 0."""
        K = ctx.number(self, "K")
        if K is None or ctx.options.get("formulation") != "charge":
            return None
        return Linear(G={(1, 0): K})

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
    [('v(T_Cx.q)', '112994350282.486*q_R'), ('v(T_Cx.x)', '10000.0*x_plate')]
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
