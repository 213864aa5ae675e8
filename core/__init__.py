"""lagrangian: energy-based modelling of mechanisms and circuits.

A component graph — masses, springs, dampers, inductors, capacitors,
resistors, sources, and whatever plugins add — is assembled into one
Lagrangian, from which equations of motion are derived and simulated.

>>> import lagrangian as lg
>>> m = lg.Model("rlc")
>>> _ = m.add("inductor", "L1", ("n1", "0"), L=1)
>>> _ = m.add("capacitor", "C1", ("n1", "0"), C=1)
>>> m.coordinate_names
['q_L1']
"""

from .component import GROUND, Component, Contribution, Example, Load, Parameter, dot, t
from .domain import Context, Coordinate, Domain, DomainView, Network, Option
from .errors import *  # noqa: F403 - the hierarchy is part of the public API
from .errors import __all__ as _errors
from .hookspecs import hookimpl
from .integrate import EnergyDriftWarning, StiffnessWarning
from .model import Model
from .registry import Registry, default_registry
from .simulation import InitialConditionWarning, Result

__version__ = "0.1.0"

__all__ = [
    "Model",
    "Result",
    "Component",
    "Contribution",
    "Load",
    "Parameter",
    "Example",
    "Domain",
    "DomainView",
    "Network",
    "Option",
    "Context",
    "Coordinate",
    "Registry",
    "default_registry",
    "hookimpl",
    "t",
    "GROUND",
    "dot",
    "InitialConditionWarning",
    "EnergyDriftWarning",
    "StiffnessWarning",
    *_errors,
]
