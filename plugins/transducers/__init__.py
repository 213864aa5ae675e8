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

The plugin's modules: :mod:`.components` (the four transducers),
:mod:`.two_ports` (their circuit analogues), :mod:`.electrostatic` (the
electrostatic actuator's helpers), :mod:`.errors` and :mod:`.hooks` (the hook
implementations); this package re-exports their public names.

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

# the public names of the modules, all importable from here as before the split
from .components import DCMotor, MovingCoil, Solenoid, VariableCapacitor
from .electrostatic import ElectrostaticEquilibria, Equilibrium, electrostatic_equilibria, simulate_checked
from .errors import GapClosedError, PullInError
from .hooks import register_analogues, register_component_types  # noqa: F401 - pluggy registers this module
from .two_ports import CapacitiveTwoPort, InductiveTwoPort

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

# doctest.testmod(lagrangian.plugins.transducers) finds the examples of what a module defines; those of the names
# re-exported here run with this module's through __test__.
__test__ = {name: globals()[name] for name in __all__}
