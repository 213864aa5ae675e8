"""Circuit analogues of the transducers plugin's variable capacitor and solenoid: the electrical two-ports
:class:`CapacitiveTwoPort` and :class:`InductiveTwoPort`, with their SPICE elements (behavioural sources)."""

from __future__ import annotations

from lagrangian import GROUND, Component, Example

from .components import Solenoid, VariableCapacitor
from lagrangian.base import deferred as _deferred

sp = _deferred.module("sympy", globals())


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
