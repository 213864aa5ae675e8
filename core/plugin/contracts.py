"""The contracts plugins fulfil: the types hooks name, with no feature behind them.

Hook specifications (:mod:`lagrangian.hookspecs`) and the registry name
these types; the features implement them — integrators
(:mod:`lagrangian.integrate`, whose driver runs them on a ``Problem``),
analogies (:mod:`lagrangian.analogy`, which maps models through them) and
work–precision benchmarks (:mod:`lagrangian.bench`, which runs them).  This
module depends on nothing but the component base types and the errors, so
that the plugin layer sits below every feature.

>>> integrator_problem(object())
"its name None is not a string of letters, digits, '_', '-' or '.' starting with a letter"
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..base.component import GROUND, Component
from ..errors import ModelError, UnknownNameError

__all__ = ["Solution", "Integrator", "integrator_problem", "resolve", "KINDS", "RESERVED", "Analogy", "Element",
           "Ports", "Benchmark", "DEFAULT_TOLERANCES"]

#: The two kinds of integrator and the options the driver passes to each.
KINDS = {"adaptive": ("rtol", "atol", "max_step"), "fixed-step": ("step",)}
#: ``method=`` names that are not integrators.
RESERVED = ("auto", "exact")
_FLAGS = ("symplectic", "implicit", "stiff", "first_order")
_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_.-]*$")


# -- integrators ------------------------------------------------------------


@dataclass
class Solution:
    """What :meth:`Integrator.solve` returns.

    ``t``: the output times (normally ``t_eval``); ``y``: the state
    ``(q, q̇_inertial)`` at those times, one column each; ``nfev``: how many
    times the model's functions were evaluated; ``status``: 0 on success,
    negative on failure (then ``message`` says what happened and ``t``/``y``
    hold what was computed); ``notes``: remarks for ``Result.notes``;
    ``step``: the step size used by a fixed-step method.
    """

    t: np.ndarray
    y: np.ndarray
    nfev: int = 0
    status: int = 0
    message: str = ""
    notes: list[str] = field(default_factory=list)
    step: float | None = None


class Integrator:
    """Base class of integrators, and the contract a plugin's integrator fulfils.

    An integrator is registered by a plugin (``register_integrators``) and
    picked with ``Model.simulate(method=name)``.  Subclass this class or
    provide any object with the same attributes:

    1. ``name`` — the ``method=`` name: letters, digits, ``_``, ``-``, ``.``;
       unique across plugins; ``"auto"`` and ``"exact"`` are reserved.
    2. ``kind`` — ``"adaptive"`` (error-controlled: ``solve`` receives
       ``rtol``, ``atol`` and ``max_step``) or ``"fixed-step"`` (``solve``
       receives ``step``, the largest step size; the user must give it).
    3. Flags, all booleans: ``symplectic`` (preserves the symplectic
       structure of conservative models, so the energy error stays bounded
       over long runs), ``implicit`` (solves equations every step),
       ``stiff`` (suited to stiff models: A-stable, or switching to a stiff
       method by itself), ``first_order`` (handles coordinates without
       inertia, ``problem.first_order``).  ``order`` is the order of accuracy
       (an int, or None) and ``description`` one line for listings.
    4. ``options`` — ``{name: description}`` of the further keyword options
       ``solve`` accepts.  ``Model.simulate(..., name=value)`` passes them
       on; the driver refuses an option that is neither one of the kind's
       nor listed here before anything is integrated.
    5. ``check(problem)`` — raise :class:`~lagrangian.ModelError` when the
       method cannot integrate the problem, saying why (from
       ``problem.structure``) and which methods can.  The driver calls it
       before ``solve``; it also refuses problems with first-order
       coordinates by itself when ``first_order`` is False.
    6. ``solve(problem, t_span, y0, t_eval, **options) -> Solution`` —
       integrate ``y' = problem.rhs(t, y)`` from ``y0`` at ``t_span[0]`` to
       ``t_span[1]`` and return the state at the times ``t_eval`` (sorted,
       inside the span).  ``nfev`` counts evaluations of the model
       (``problem.nfev`` counts them for you).  Report failure with a
       negative status and a message, or raise
       :class:`~lagrangian.IntegrationError` (a
       :class:`~lagrangian.NumericalError`) naming the time and what to
       change — a Newton iteration that does not converge, say.  Errors the
       problem's functions raise (a singular mass matrix) propagate.
    7. Use the problem's functions only — ``rhs`` and ``jacobian`` on the
       state; ``pieces`` (``∂L/∂q``, ``∂L/∂q̇``, ``M``, non-conservative
       forces), ``momentum``, ``velocity`` (its inverse), ``mass``,
       ``forces``, ``canonical_rhs`` with ``to_canonical`` and
       ``from_canonical`` on ``(q, p)``, ``acceleration`` for separable
       models — and read ``structure``: they are the model's, with its
       parameter values, and they count evaluations.  Call
       ``problem.report(t)`` now and then so that progress can be shown
       (``rhs`` does it by itself).
    8. Keep no state of a run on the integrator: one instance serves every
       run.
    9. Optional, for events (:mod:`lagrangian.numerics.events`): adaptive
       methods give ``start(problem, t0, y0, t_bound, **options)``, an
       object stepped one step at a time with the interface of SciPy's
       ``OdeSolver`` (``step()``, ``t``, ``y``, ``t_old``, ``status``,
       ``dense_output()``); fixed-step methods give ``stepper(problem, h)``
       (:class:`~lagrangian.integrate.FixedStepIntegrator`).  A method with
       neither refuses events with a clear error.
    """

    name: str = ""
    kind: str = "adaptive"
    order: int | None = None
    symplectic: bool = False
    implicit: bool = False
    stiff: bool = False
    first_order: bool = True
    description: str = ""
    options: Mapping[str, str] = {}

    def check(self, problem: Any) -> None:
        """Raise :class:`~lagrangian.ModelError` if this method cannot integrate ``problem``; the default accepts all."""

    def solve(self, problem: Any, t_span: tuple[float, float], y0: np.ndarray, t_eval: np.ndarray, **options: Any) -> Solution:
        """Integrate ``problem`` over ``t_span`` from ``y0``; the state at ``t_eval`` (see the class's contract)."""
        raise NotImplementedError

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name!r} ({self.kind})>"


def integrator_problem(obj: Any) -> str | None:
    """What is wrong with ``obj`` as an integrator, or None (used by the registry and for ``method=obj``)."""
    name = getattr(obj, "name", None)
    if not isinstance(name, str) or not _NAME.match(name):
        return f"its name {name!r} is not a string of letters, digits, '_', '-' or '.' starting with a letter"
    if name in RESERVED:
        return f"its name {name!r} is reserved (method={name!r} means something else)"
    kind = getattr(obj, "kind", None)
    if kind not in KINDS:
        return f"its kind {kind!r} is not one of {', '.join(map(repr, KINDS))}"
    for flag in _FLAGS:
        if not isinstance(getattr(obj, flag, None), bool):
            return f"its flag {flag!r} must be True or False, not {getattr(obj, flag, None)!r}"
    order = getattr(obj, "order", None)
    if order is not None and (not isinstance(order, int) or order < 1):
        return f"its order must be a positive int or None, not {order!r}"
    if not callable(getattr(obj, "solve", None)):
        return "it has no solve(problem, t_span, y0, t_eval, **options) method"
    options = getattr(obj, "options", {})
    if not isinstance(options, Mapping) or not all(isinstance(k, str) for k in options):
        return "its options must be a mapping of option names to descriptions"
    clash = set(options) & {"t_span", "y0", "t_eval", "problem"}
    if clash:
        return f"its options may not be named {', '.join(sorted(clash))}"
    return None


def resolve(method: Any, integrators: Mapping[str, Any]) -> Any:
    """The integrator that ``method`` names (or ``method`` itself, an integrator object)."""
    if isinstance(method, str):
        try:
            return integrators[method]
        except KeyError:
            raise UnknownNameError("integration method", method, [*integrators, *RESERVED]) from None
    problem = integrator_problem(method)
    if problem:
        raise ModelError(f"method={method!r} is neither a registered method name nor a valid integrator: {problem}.")
    return method


# -- analogies --------------------------------------------------------------


@dataclass(frozen=True)
class Analogy:
    """An analogy between two domains (see the module docstring)."""

    name: str
    source: str
    target: str
    dual: bool
    options: Mapping[str, Any] = field(default_factory=dict)
    inverse_options: Mapping[str, Any] = field(default_factory=dict)
    doc: str = ""


@dataclass(frozen=True)
class Element:
    """One component of the analogue model: ``Model.add(kind, name, nodes, **params)``.

    ``branch`` is the index of the source component's branch this element
    stands for (its branch quantity is identified with ``sign`` times that
    branch's), ``None`` for elements that stand for no branch (sources), or,
    for an element with several branches (a two-port), a sequence of
    ``(element branch, source branch)`` pairs.
    """

    kind: str
    name: str
    nodes: Any
    params: Mapping[str, Any]
    branch: int | None | tuple[tuple[int, int], ...] = 0
    sign: int = 1

    def pairs(self) -> list[tuple[int, int]]:
        """``(element branch, source branch)`` identifications."""
        if self.branch is None:
            return []
        if isinstance(self.branch, int):
            return [(0, self.branch)]
        return [tuple(p) for p in self.branch]


#: what a plugin registers per component kind and analogy: the elements standing for a component, given its ports
AnalogueBuilder = Callable[[Component, "Ports"], list[Element]]


@dataclass
class Ports:
    """Target nodes standing for a component's branches, handed to analogue builders."""

    component: Component
    branches: dict[str, tuple[str, str]]
    ground: str = GROUND
    model: Any = None

    def branch(self, index: int = 0, component: Component | None = None) -> tuple[str, str]:
        """Target ``(a, b)`` for branch ``index`` of ``component`` (this one by default)."""
        comp = component or self.component
        key = comp.name if index == 0 else f"{comp.name}#{index}"
        return self.branches[key]


# -- work–precision benchmarks ----------------------------------------------

#: the rtol values a benchmark runs adaptive methods at, unless it says otherwise
DEFAULT_TOLERANCES = (1e-3, 1e-5, 1e-7, 1e-9, 1e-11)


@dataclass(frozen=True)
class Benchmark:
    """A work–precision problem.

    ``build()`` returns the model; ``initial``, ``velocity``, ``params`` and
    ``t_end`` are the arguments of ``Model.simulate``; errors are measured
    on ``points`` evenly spaced times.  The truth is ``exact(times)``
    (coordinates by name) when given, otherwise a run with ``reference``
    (keyword arguments of ``simulate``: a method and tight tolerances, or
    ``{"method": "exact"}``).  ``measure`` is ``"state"`` (the largest
    error of any coordinate, relative to the largest coordinate value of
    the truth) or ``"energy"`` (the largest relative departure of ``T + V``
    from its initial value — no truth needed).  ``tolerances`` are the
    ``rtol`` of adaptive methods (``atol = rtol · atol_factor``), ``steps``
    the step sizes of fixed-step ones; ``methods`` the default methods
    (empty: every registered one); ``options`` extra options per method;
    ``requires`` the component kinds it needs.
    """

    name: str
    description: str
    build: Callable[[], Any]
    t_end: float
    initial: Mapping[str, float] = field(default_factory=dict)
    velocity: Mapping[str, float] = field(default_factory=dict)
    params: Mapping[str, float] = field(default_factory=dict)
    points: int = 201
    exact: Callable[[np.ndarray], Mapping[str, np.ndarray]] | None = None
    reference: Mapping[str, Any] = field(default_factory=lambda: {"method": "DOP853", "rtol": 1e-13, "atol": 1e-15})
    measure: str = "state"
    tolerances: Sequence[float] = DEFAULT_TOLERANCES
    atol_factor: float = 1e-3
    steps: Sequence[float] = ()
    methods: Sequence[str] = ()
    options: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    requires: Sequence[str] = ()

    def unavailable(self, registry) -> str | None:
        """Why this benchmark cannot run with ``registry``'s plugins, or None."""
        missing = [k for k in self.requires if k not in registry.kinds]
        if missing:
            return f"needs component kind(s) {', '.join(missing)}, which no installed plugin provides"
        return None
