"""A third-party lagrangian plugin: the cubic hardening (Duffing) spring.

Installed as its own distribution, it registers the kind ``cubic_spring``
through the entry-point group ``lagrangian``; nothing in lagrangian knows of
it.  Its force is ``k e + k3 e³`` for an extension ``e``, so its potential
energy is ``V = ½ k e² + ¼ k3 e⁴``.

It also takes part in the force–voltage analogy: it registers the
electrical kind ``cubic_capacitor`` (``V = q²/2C + ¼ k3 q⁴``, charge
formulation) and declares each kind the analogue of the other.

>>> import lagrangian as lg
>>> m = lg.Model("duffing")
>>> _ = m.add("mass", "m1", "p", m=1)
>>> _ = m.add("cubic_spring", "s", ("ground", "p"), k=1, k3=0.5)
>>> m.potential_energy
0.125*x_p(t)**4 + x_p(t)**2/2
"""

from lagrangian import Component, Contribution, Example, ModelError, Parameter, dot, hookimpl
from lagrangian.analogy import Element

__all__ = ["CubicSpring", "CubicCapacitor"]


class CubicSpring(Component):
    """Hardening spring: V = ½ k e² + ¼ k3 e⁴ (e: extension along the line between its nodes)."""

    kind = "cubic_spring"
    domain = "mechanical"
    parameters = {
        "k": Parameter("linear stiffness", unit="N/m"),
        "k3": Parameter("cubic stiffness", check="nonnegative", unit="N/m³"),
    }

    def contribute(self, ctx) -> Contribution:
        d = ctx.view.position(self.nodes[1]) - ctx.view.position(self.nodes[0])
        e2 = d[0] ** 2 if ctx.view.dim == 1 else dot(d, d)
        return Contribution(V=self.k * e2 / 2 + self.k3 * e2**2 / 4)

    @classmethod
    def example(cls) -> Example:
        return Example(("ground", "p"), {"k": 1, "k3": 0.5}, context=[("mass", "m", "p", {"m": 1})])


class CubicCapacitor(Component):
    """Hardening capacitor: V = q²/2C + ¼ k3 q⁴ (charge formulation only)."""

    kind = "cubic_capacitor"
    domain = "electrical"
    tree_priority = 1
    parameters = {
        "C": Parameter("small-signal capacitance", unit="F"),
        "k3": Parameter("cubic elastance coefficient", check="nonnegative", unit="V/C³"),
    }

    def contribute(self, ctx) -> Contribution:
        if ctx.view.formulation != "charge":
            raise ModelError(f"cubic_capacitor {self.name!r} is defined in the charge formulation only: use formulation='charge'.")
        q = ctx.view.charge(self)
        return Contribution(V=q**2 / (2 * self.C) + self.k3 * q**4 / 4)

    @classmethod
    def example(cls) -> Example:
        return Example(("n1", "0"), {"C": 1, "k3": 0.5}, context=[("inductor", "L", ("n1", "0"), {"L": 1})])


@hookimpl
def register_component_types(register):
    register(CubicSpring)
    register(CubicCapacitor)


@hookimpl
def register_analogues(register):
    register("cubic_spring", "force-voltage", lambda c, ports: [
        Element("cubic_capacitor", f"C_{c.name}", ports.branch(), {"C": 1 / c.k, "k3": c.k3})
    ])
    register("cubic_capacitor", "force-voltage", lambda c, ports: [
        Element("cubic_spring", f"k_{c.name}", ports.branch(), {"k": 1 / c.C, "k3": c.k3})
    ])
