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

import importlib as _importlib
import importlib.abc as _importlib_abc
import importlib.util as _importlib_util
import sys as _sys

import lazy_loader as _lazy_loader

from .base.limits import limits
from .errors import *  # noqa: F403 - the hierarchy is part of the public API
from .errors import __all__ as _errors
from .base import deferred as _deferred

__version__ = "0.1.0"

#: The public names and the modules they live in, imported when first asked for (SPEC 1, :mod:`lazy_loader`):
#: ``import lagrangian`` loads neither SymPy, SciPy, NumPy nor networkx until a feature needs them
#: (``EAGER_IMPORT=1`` loads every one of them at once, as a check).
_NAMES = {
    "model": ["Model", "NodeNameWarning"],
    "base.component": ["GROUND", "Component", "Contribution", "Example", "Load", "MovingFrame", "Parameter", "dot", "t"],
    "base.domain": ["Context", "Coordinate", "Domain", "DomainView", "Incidence", "Network", "Option", "Recursion",
                    "RecursiveDynamics", "Shape", "coordinate", "rate"],
    "base.linear": ["Linear", "LinearContext", "Potential", "Quantity"],
    "plugin.hookspecs": ["hookimpl"],
    "plugin.registry": ["Registry", "default_registry"],
    "numerics.events": ["Event", "Occurrence"],
    "numerics.integrate": ["EnergyDriftWarning", "StiffnessWarning"],
    "numerics.problem": ["SlowRunWarning"],
    "numerics.simulation": ["InitialConditionWarning", "Result"],
    "analysis.fitting": ["fit", "Fit", "FrequencyData", "TimeSeries"],
}
#: Every module keeps the name it had before the package was layered (``lagrangian.integrate``,
#: ``lagrangian.routh``, ...): ``import lagrangian.routh`` gives the same module object as
#: ``lagrangian.analysis.routh``, imported when first asked for.
MODULES = {
    "base": ("component", "domain", "graph", "network", "text", "identity", "arguments", "switching", "budget",
             "display", "units", "latex", "modelfile"),
    "plugin": ("contracts", "hookspecs", "registry"),
    "derivation": ("assembly", "derive", "equations"),
    "numerics": ("tape", "codegen", "simulation", "events", "integrate", "compiled_loops", "linear", "bench", "ensemble",
                 "result"),
    "analysis": ("routh", "impulse", "scene", "derived", "frequency", "linearize", "operating", "sweep", "stick_slip",
                 "fitting"),
    "circuits": ("analogy", "spice", "netlist", "compare", "ac"),
}
_WHERE = {name: f"{__name__}.{layer}.{name}" for layer, names in MODULES.items() for name in names}


class _Alias(_importlib_abc.MetaPathFinder, _importlib_abc.Loader):
    """``lagrangian.<module>`` → the module in its layer (the same object, under both names)."""

    def find_spec(self, fullname, path=None, target=None):
        package, _, name = fullname.rpartition(".")
        if package != __name__ or name not in _WHERE:
            return None
        return _importlib_util.spec_from_loader(fullname, self)

    def create_module(self, spec):
        module = _importlib.import_module(_WHERE[spec.name.rpartition(".")[2]])
        self._specs[module.__name__] = module.__spec__
        return module

    def exec_module(self, module):
        module.__spec__ = self._specs[module.__name__]  # its own spec again, not the alias's


_Alias._specs = {}


_sys.meta_path.append(_Alias())

_attribute, _, _ = _lazy_loader.attach(__name__, submod_attrs=_NAMES)


def __getattr__(name: str):
    if name in _WHERE:
        return _importlib.import_module(f"{__name__}.{name}")
    if name == "t":  # the symbol itself, not the stand-in the package's modules hold until SymPy is used
        return _deferred.time_symbol()
    if name == "load":  # ``lagrangian.load("m.json")``: the model a model file describes (:meth:`Model.load`)
        return _attribute("Model").load
    try:
        return _attribute(name)
    except AttributeError:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}") from None


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__, *_WHERE})


__all__ = [
    "Model",
    "load",
    "limits",
    "fit",
    "Fit",
    "FrequencyData",
    "TimeSeries",
    "Result",
    "Component",
    "Contribution",
    "Load",
    "MovingFrame",
    "Parameter",
    "Example",
    "Domain",
    "DomainView",
    "Shape",
    "Recursion",
    "RecursiveDynamics",
    "Network",
    "Option",
    "Context",
    "Incidence",
    "Linear",
    "LinearContext",
    "Potential",
    "Quantity",
    "Coordinate",
    "coordinate",
    "rate",
    "Registry",
    "default_registry",
    "hookimpl",
    "t",
    "GROUND",
    "dot",
    "InitialConditionWarning",
    "NodeNameWarning",
    "EnergyDriftWarning",
    "StiffnessWarning",
    "SlowRunWarning",
    "Event",
    "Occurrence",
    *_errors,
]
