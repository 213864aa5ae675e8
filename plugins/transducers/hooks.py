"""The transducers plugin's hook implementations: its component types, and the circuit analogues of the
transducers (gyrators and two-ports) for coupled models mapped to one circuit."""

from __future__ import annotations

from lagrangian import hookimpl

from .components import DCMotor, MovingCoil, Solenoid, VariableCapacitor
from .two_ports import CapacitiveTwoPort, InductiveTwoPort


@hookimpl
def register_component_types(register):
    for cls in (MovingCoil, DCMotor, VariableCapacitor, Solenoid, CapacitiveTwoPort, InductiveTwoPort):
        register(cls)


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
