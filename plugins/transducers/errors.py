"""Errors of the transducers plugin's electrostatic actuators: :class:`PullInError` (no stable equilibrium) and
:class:`GapClosedError` (a plate reached its electrode during a simulation).  Both keep the public name
``lagrangian.plugins.transducers.<name>``, under which they are raised and printed."""

from __future__ import annotations

from lagrangian import ModelError, NumericalError


class PullInError(ModelError):
    """An electrostatic actuator has no stable equilibrium at the voltage asked for (it is past pull-in)."""

    __module__ = "lagrangian.plugins.transducers"  # its public name, which tracebacks print


class GapClosedError(NumericalError):
    """A simulation reached a configuration where a variable capacitor's gap closes (C → ∞).

    ``component`` names the capacitor, ``time`` is when its plate reached the electrode.
    """

    __module__ = "lagrangian.plugins.transducers"  # its public name, which tracebacks print

    def __init__(self, component: str, time: float, message: str):
        self.component = component
        self.time = time
        super().__init__(message)
