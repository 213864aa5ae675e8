"""The exception hierarchy of lagrangian.

Every error the library raises on purpose derives from :class:`LagrangianError`,
names the component, node, parameter or plugin at fault, and says what would
fix it.

>>> issubclass(UnknownKindError, ModelError) and issubclass(ModelError, LagrangianError)
True
"""

from __future__ import annotations

import difflib
import sys
import warnings
from collections.abc import Iterable

__all__ = [
    "LagrangianError",
    "PluginError",
    "ModelError",
    "UnknownKindError",
    "ParameterError",
    "UnknownNodeError",
    "UnknownNameError",
    "DuplicateNameError",
    "DanglingNodeError",
    "DomainError",
    "TopologyError",
    "FloatingNetworkError",
    "ReductionError",
    "ExpressionError",
    "ModelFileError",
    "NumericalError",
    "SingularMassMatrixError",
    "IntegrationError",
    "closest",
]


def closest(word: str, choices: Iterable[str]) -> str:
    """A ``" Did you mean 'x'?"`` suffix naming the closest choice, or ``""``.

    A choice that differs only in case comes first (``rk45`` → ``RK45``),
    then the closest by spelling.

    >>> closest("sprng", ["spring", "mass"])
    " Did you mean 'spring'?"
    >>> closest("rk45", ["rk4", "RK45"])
    " Did you mean 'RK45'?"
    """
    choices = [str(c) for c in choices]
    same = [c for c in choices if c.casefold() == str(word).casefold()]
    match = same or difflib.get_close_matches(str(word), choices, n=1, cutoff=0.6)
    return f" Did you mean {match[0]!r}?" if match else ""


#: The packages whose frames a warning passes over on its way to the user's line.
_PASSED_OVER = ("lagrangian", "scipy", "numpy")


def warn(message: str, category: type[Warning]) -> None:
    """``warnings.warn`` attributed to the caller's own line: the first frame outside this package (its
    plugins included) and the numerical libraries that call back into it (SciPy's integrators stepping a
    right-hand side), however deep the warning arises, so that the warning names the user's
    ``simulate(...)``, not a line of lagrangian or SciPy."""
    frame, level = sys._getframe(1), 2  # stacklevel 1 is this line; 2 the caller
    while frame is not None and str(frame.f_globals.get("__name__", "")).split(".")[0] in _PASSED_OVER:
        frame, level = frame.f_back, level + 1
    warnings.warn(message, category, stacklevel=level)


class LagrangianError(Exception):
    """Base class of every error raised by lagrangian.

    Every one pickles (with its message, ``args`` and attributes, whatever its ``__init__`` takes): unpickling
    restores them without calling ``__init__`` again.
    """

    def __reduce__(self):
        return _unpickled_error, (type(self), self.args, self.__dict__)


def _unpickled_error(cls: type, args: tuple, state: dict) -> BaseException:
    """An error of class ``cls`` with ``args`` and attributes ``state``, its ``__init__`` not called (it may take
    other arguments than the message it built)."""
    error = cls.__new__(cls, *args)
    error.args = args
    error.__dict__.update(state)
    return error


class PluginError(LagrangianError):
    """A plugin failed to load, or registered something invalid.

    ``plugin`` names the plugin at fault.
    """

    def __init__(self, plugin: str, message: str):
        self.plugin = plugin
        super().__init__(f"plugin {plugin!r}: {message}")


class ModelError(LagrangianError, ValueError):
    """The model as described cannot be assembled."""


class UnknownKindError(ModelError):
    """No registered plugin provides the requested component kind."""

    def __init__(self, kind: str, known: Iterable[str]):
        known = sorted(known)
        self.kind = kind
        super().__init__(
            f"unknown component kind {kind!r}.{closest(kind, known)} "
            f"Known kinds: {', '.join(known)}. A third-party kind needs its plugin installed "
            f"(see `lagrangian plugins`)."
        )


class ParameterError(ModelError):
    """A parameter is missing, unknown, or has an invalid value."""

    def __init__(self, component: str, parameter: str, message: str):
        self.component = component
        self.parameter = parameter
        super().__init__(f"component {component!r}, parameter {parameter!r}: {message}")


class UnknownNodeError(ModelError):
    """A node was referred to that the model does not have."""

    def __init__(self, node: str, known: Iterable[str]):
        known = sorted(map(str, known))
        self.node = node
        super().__init__(
            f"unknown node {node!r}.{closest(node, known)} Nodes of this model: {', '.join(known)}."
        )


class UnknownNameError(ModelError):
    """A coordinate, parameter or component name that the model does not have."""

    def __init__(self, what: str, name: str, known: Iterable[str]):
        known = sorted(map(str, known))
        self.name = name
        shown = ", ".join(known[:_SHOWN]) + (f", … ({len(known) - _SHOWN} more)" if len(known) > _SHOWN else "")
        super().__init__(f"unknown {what} {name!r}.{closest(name, known)} Known: {shown or '(none)'}.")


#: Names listed after an unknown one: a model of 10⁴ coordinates would otherwise fill the screen.
_SHOWN = 40


class DuplicateNameError(ModelError):
    """Two components were given the same name."""


class DanglingNodeError(ModelError):
    """A declared node has nothing attached to it."""


class DomainError(ModelError):
    """Components of different physical domains meet at one node, or a domain is missing."""


class TopologyError(ModelError):
    """The network cannot be solved as drawn: a loop of ideal across-sources
    (voltage sources, prescribed motions), a cut-set of ideal through-sources
    (current sources), or a component whose branch joins a node to itself."""


class FloatingNetworkError(TopologyError):
    """Part of the network has no path to the reference node ``ground``."""


class ReductionError(ModelError):
    """A Routhian reduction cannot be carried out as asked: a coordinate that is not
    ignorable, momentum equations that cannot be solved for the ignorable
    velocities, or a state on the singular set of the reduced model."""


class ExpressionError(ModelError):
    """Text given as an expression holds something an expression may not (a call, an attribute), or cannot be
    read; nothing in it is ever run (:mod:`lagrangian.text`)."""


class ModelFileError(ModelError):
    """A model file cannot be written or read (:mod:`lagrangian.base.modelfile`): a value a file cannot hold, or a
    file that is not valid, too large, of an unknown version or naming a kind no installed plugin provides.

    ``pointer`` is the JSON pointer of the place at fault (``"/components/3/params/k"``; ``""`` the whole file) and
    ``path`` the file, where known.
    """

    def __init__(self, message: str, *, pointer: str | None = None, path: str | None = None):
        self.pointer, self.path = pointer, path
        where = f"model file {path!r}" if path is not None else "model file"
        if pointer:
            where += f", at {pointer}"
        super().__init__(f"{where}: {message}")


class NumericalError(LagrangianError, ArithmeticError):
    """Numerical trouble detected while evaluating or integrating a model."""


class SingularMassMatrixError(NumericalError):
    """The mass matrix (with first-order rows) cannot be solved for the accelerations.

    The message says which case it is and what to do: dependent loop-closure constraints (an over-constrained
    loop, or a loop at a singular position), a coordinate or a direction of the coordinates without inertia at
    any configuration (a massless coordinate), or a direction lost at this configuration only (a gimbal lock of
    a joint's angle sequence, a pole of the angles).
    """


class IntegrationError(NumericalError):
    """The integrator failed or produced non-finite values."""
