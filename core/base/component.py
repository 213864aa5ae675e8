"""Components: the things a model is built from.

A component never writes equations of motion.  It declares its parameters and
terminals and, given a *context* holding the model's coordinates, returns a
:class:`Contribution`: kinetic energy (or co-energy) ``T``, potential energy
``V``, Rayleigh dissipation ``D`` and :class:`Load` s (generalized forces by
virtual power).  The assembly sums contributions into one Lagrangian.
"""

from __future__ import annotations

import math

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar

from ..errors import closest, ExpressionError, ModelError, ParameterError
from .text import as_expr
from .units import is_quantity, split, to_si
from . import deferred as _deferred
from .params import Params
from .pickling import pickling_by_name, refuse_unpicklable  # noqa: F401 - (defined there; named here too)
from .waveforms import Waveform

sp = _deferred.module("sympy", globals())

__all__ = ["t", "GROUND", "Parameter", "Load", "Contribution", "Example", "Component", "dot"]

#: The time symbol every model shares (a stand-in for it until SymPy is first used: :mod:`lagrangian.base.deferred`).
t = _deferred.symbol("t", real=True)

#: Name of the reference node shared by all domains.  ``"0"`` and ``"gnd"`` are accepted aliases.
GROUND = "ground"
GROUND_ALIASES = frozenset({"ground", "gnd", "0"})

_REQUIRED = object()
_CHECKS = {
    "fraction": (lambda v: 0 < v <= 1, "must be in (0, 1]"),
    "positive": (lambda v: v > 0, "must be positive"),
    "nonnegative": (lambda v: v >= 0, "must be zero or positive"),
    "nonzero": (lambda v: v != 0, "must not be zero"),
    "real": (lambda v: True, "must be real"),
}


def dot(a: sp.Matrix, b: sp.Matrix) -> sp.Expr:
    """Scalar product of two column matrices, as a sum of products (``a.T * b`` took half the assembly of 200 bodies).

    >>> dot(sp.Matrix([1, 2]), sp.Matrix([3, 4]))
    11
    """
    return sp.Add(*[x * y for x, y in zip(a, b) if x != 0 and y != 0])


@dataclass(frozen=True)
class Parameter:
    """Declaration of one parameter of a component type.

    ``check`` is one of ``"positive"``, ``"nonnegative"``, ``"nonzero"``,
    ``"fraction"`` (in (0, 1]), ``"real"``.  ``shape`` is ``"scalar"``,
    ``"vector"`` (a sequence or matrix, one entry per spatial axis),
    ``"signal"`` (a number, a SymPy expression of :data:`t`, or a Python
    callable of time; callables become undefined functions in the equations
    and are called numerically; with ``state=True``, the signal of a load,
    also an expression of the coordinates and their rates:
    :func:`lagrangian.coordinate`, :func:`lagrangian.rate`; a sequence of
    them is a vector signal, unless ``vector=False``), ``"name"`` (the name of another
    component, kept as a string), ``"flag"`` (True or False), ``"mapping"``
    (names to vectors) or ``"tensor"`` (a scalar, a vector or a matrix).

    ``symbolic``: a number given for a scalar or signal parameter is a
    *value of a symbol*: the derivation sees a symbol (exact arithmetic,
    the same structure as a model built with SymPy symbols, and faster than
    arithmetic on floats) and the value is substituted once the equations
    are derived (:meth:`Component.symbolic_view`).  So is every nonzero
    number in a vector, matrix or mapping of vectors (a centre of mass,
    principal moments, a body's points): zeros stay zeros, equal numbers
    of one parameter share a symbol (equal principal moments stay a
    symmetric body), and each symbol keeps its value's sign.
    ``symbolic=False`` keeps the number itself, for a value that decides
    the form of the energy (an exponent; a rest length whose zero removes a
    square root; a direction, normalized when the energy is built).

    >>> Parameter("stiffness", unit="N/m").coerce(4, "k1", "k")
    4
    >>> Parameter("mass").coerce(-1, "m1", "m")
    Traceback (most recent call last):
    ...
    lagrangian.errors.ParameterError: component 'm1', parameter 'm': must be positive (got -1).
    """

    doc: str
    default: Any = _REQUIRED
    check: str = "positive"
    shape: str = "scalar"
    unit: str = ""
    symbolic: bool = True
    state: bool = False
    #: A signal may be a sequence (a vector force in 2-D/3-D, a list of constraints); ``False``: one signal only.
    vector: bool = True

    @property
    def required(self) -> bool:
        return self.default is _REQUIRED

    def coerce(self, value: Any, component: str, name: str) -> Any:
        """Turn a user value into a SymPy object, checking it; raise :class:`ParameterError`."""
        if self.shape == "flag":
            if not isinstance(value, bool):
                raise ParameterError(component, name, f"expected True or False, got {value!r}.")
            return value
        if self.shape == "mapping":
            if value is None:
                return None
            if not isinstance(value, Mapping):
                raise ParameterError(component, name, f"expected a mapping of names to vectors, got {value!r}.")
            return {str(k): Parameter(self.doc, shape="vector").coerce(v, component, f"{name}[{k!r}]") for k, v in value.items()}
        if self.shape == "tensor":
            if isinstance(value, (Sequence, sp.MatrixBase)) and not isinstance(value, (str, bytes)):
                rows = list(value.tolist()) if isinstance(value, sp.MatrixBase) else list(value)
                nested = [isinstance(r, (Sequence, sp.MatrixBase)) and not isinstance(r, (str, bytes)) for r in rows]
                if any(nested) and not all(nested):
                    raise ParameterError(component, name, f"expected a scalar, a vector or a square matrix, got {value!r}.")
                # every entry read on its own first (text is parsed, never sympified), then the matrix built
                if all(nested) and rows:
                    rows = [[self._scalar(e, component, name, check="real") for e in r] for r in rows]
                    if len({len(r) for r in rows}) != 1:
                        raise ParameterError(component, name, f"expected a scalar, a vector or a square matrix, got {value!r}.")
                    return sp.Matrix(rows)
                return sp.Matrix([self._scalar(e, component, name, check="real") for e in rows])
            return self._scalar(value, component, name, check=self.check)
        if self.shape == "name":
            if not isinstance(value, str) or not value.strip():
                raise ParameterError(component, name, f"expected the name of a component (a string), got {value!r}.")
            return value.strip()
        if self.shape == "signal" and callable(value) and not isinstance(value, sp.Basic):
            arity = _arity(value)
            if arity == 3 and not self.state:
                raise ParameterError(component, name, "is a callable of (t, q, v): a signal is a function of time "
                                                      "alone, f(t). Loads (force, torque, body_torque, "
                                                      "generalized_force) take callables of the state.")
            if arity not in (1, 3):
                raise ParameterError(component, name, f"is a callable of {arity} required arguments: give f(t)"
                                                      + (", or f(t, q, v) with q and v mappings of coordinate names "
                                                         "to values" if self.state else "") + ".")
            return _CallableSignal(value, f"{name}_{component}", state=arity == 3)
        if self.shape == "signal" and isinstance(value, (Sequence, sp.MatrixBase)) and not isinstance(value, (str, bytes)):
            if not self.vector:
                raise ParameterError(component, name, f"is one signal ({self.doc}: a number, an expression of t or a "
                                                      f"callable of t), not a sequence of them; got {value!r:.80}.")
            return sp.Matrix([self._scalar(v, component, name, check="real") for v in value])
        if self.shape == "vector" and value is not None:
            if isinstance(value, (str, bytes)) or not isinstance(value, (Sequence, sp.MatrixBase)):
                raise ParameterError(component, name, f"expected a vector (a sequence of numbers), got {value!r}.")
            return sp.Matrix([self._scalar(v, component, name, check="real") for v in value])
        if value is None:
            if self.default is None:
                return None
            raise ParameterError(component, name, f"required ({self.doc}), got None.")
        return self._scalar(value, component, name, check=self.check)

    def held(self, value: Any) -> bool:
        """Whether a component holds ``value`` as given until it is read symbolically (:mod:`lagrangian.base.params`):
        a plain number within this parameter's rule, or a waveform for a signal."""
        kind = type(value)
        if kind is float or kind is int:
            return self.shape in ("scalar", "signal", "tensor") and abs(value) <= LARGEST and _CHECKS[self.check][0](value)
        return self.shape == "signal" and isinstance(value, Waveform)

    def _scalar(self, value: Any, component: str, name: str, check: str) -> sp.Expr:
        kind = type(value)
        if (kind is float or kind is int) and abs(value) <= LARGEST and _CHECKS[check][0](value):  # (nan, inf: no)
            # a plain number within the rule, as users mostly give them: what the general path below makes of it,
            # without its tree walks (a third of the cost of adding a component); anything else takes that path
            return sp.Float(value) if kind is float else sp.Integer(value)
        if isinstance(value, (sp.Float, sp.Rational)) and _plain_within(value, check):
            return value  # a SymPy number within the rule (an analogue's values, a copy's): itself, as below
        if isinstance(value, bool):
            raise ParameterError(component, name, f"expected a number or a SymPy expression, got {value!r}.")
        if is_quantity(value) or split(value) is not None:  # "0.3 kg", 300 * ureg.g: converted to SI
            try:
                value = to_si(value, self.unit, "the value")
            except ModelError as exc:
                raise ParameterError(component, name, str(exc).removeprefix("the value: ")) from None
        try:
            expr = as_expr(value, "the value")
        except ExpressionError as exc:
            raise ParameterError(component, name, f"expected a number or a SymPy expression; {exc}") from None
        except (sp.SympifyError, SyntaxError, TypeError, ValueError) as exc:
            raise ParameterError(
                component, name, f"expected a number or a SymPy expression, got {value!r} ({exc.__class__.__name__})."
            ) from None
        if not isinstance(expr, sp.Expr):
            raise ParameterError(component, name, f"expected a scalar expression, got {value!r}.")
        if any(s.name == "t" and s != t for s in expr.free_symbols):
            raise ParameterError(component, name, "uses a symbol named t that is not lagrangian.t: build time expressions from lagrangian.t.")
        if self.shape != "signal" and t in expr.free_symbols:
            raise ParameterError(component, name, "depends on time t; only signal parameters may.")
        if self.shape == "signal":
            self._state_check(expr, component, name)
        check_value(expr, check, component, name)
        return expr


    def _state_check(self, expr: sp.Expr, component: str, name: str) -> None:
        """A signal holds functions of ``t`` alone; a load's (``state=True``) also coordinates ``x(t)`` and their
        first rates, never an acceleration."""
        for d in expr.atoms(sp.Derivative):
            if not self.state:
                break
            if isinstance(d.expr, sp.core.function.AppliedUndef) and set(d.variables) == {t} and d.derivative_count > 1:
                raise ParameterError(component, name, f"holds the acceleration {d}: a load depends on the state "
                                                      f"(coordinates and rates), not on accelerations.")
            if not isinstance(d.expr, sp.core.function.AppliedUndef) or d.variables != (t,):
                raise ParameterError(component, name, f"holds {d}: a load may hold coordinates x(t) and their rates "
                                                      f"dx/dt (lagrangian.coordinate, lagrangian.rate), no other derivative.")
        for f in expr.atoms(sp.core.function.AppliedUndef):
            if not self.state:
                raise ParameterError(component, name, f"depends on {f}: a signal is a function of time alone. Loads "
                                                      f"depend on the state: force, torque, body_torque and "
                                                      f"generalized_force take expressions of lagrangian.coordinate(...) "
                                                      f"and lagrangian.rate(...).")
            if f.args != (t,):
                raise ParameterError(component, name, f"holds {f}: a load may hold coordinates, functions of t "
                                                      f"alone (lagrangian.coordinate).")


#: The largest magnitude a parameter's value may have (a square of it still fits a double).
LARGEST = 1e150


def _plain_within(value: sp.Number, check: str) -> bool:
    """Whether the SymPy number ``value`` is finite, within :data:`LARGEST` and passes the rule ``check``."""
    try:
        x = float(value)
    except (OverflowError, TypeError, ValueError):
        return False
    return abs(x) <= LARGEST and _CHECKS[check][0](x)  # (nan: no)


def check_value(expr: Any, check: str, component: str, name: str) -> None:
    """Check a scalar against a parameter rule; symbolic values are checked by their assumptions."""
    test, rule = _CHECKS[check]
    if isinstance(expr, (sp.MatrixBase, _CallableSignal, str, bool, dict)) or expr is None:
        return
    if expr.is_number:
        try:  # SymPy's own evaluation of a number near a branch point (log of a tiny complex) may divide by zero
            finite = not expr.has(sp.zoo, sp.nan, sp.oo, -sp.oo) and expr.is_real and math.isfinite(float(expr))
        except (ArithmeticError, TypeError, ValueError):
            finite = False
        if not finite:
            raise ParameterError(component, name, f"must be a finite real number (got {expr}).")
        if not test(float(expr)):
            raise ParameterError(component, name, f"{rule} (got {expr}).")
        if abs(float(expr)) > LARGEST:
            raise ParameterError(component, name, f"{float(expr):g} is beyond {LARGEST:g}: the equations multiply "
                                                  f"parameters, and such products overflow floating point. Choose "
                                                  f"units that keep values nearer 1.")
        return
    # symbolic: refuse only what the assumptions prove wrong, where they can say in reasonable time (their queries on
    # a power beyond 64 of a symbol under a trigonometric function, cosh(sec(x**100)), take seconds, and longer
    # beyond: such an expression is left undecided)
    if any(p.exp.is_Number and abs(p.exp) > 64 for p in expr.atoms(sp.Pow)):
        return
    verdict = {  # only the rule asked for is evaluated: assumption queries on sums are slow
        "fraction": lambda: False if expr.is_positive is False or (expr - 1).is_positive else None,
        "positive": lambda: expr.is_positive,
        "nonnegative": lambda: expr.is_nonnegative,
        "nonzero": lambda: expr.is_nonzero,
        "real": lambda: expr.is_real,
    }[check]()
    if verdict is False:
        if check == "real" or expr.is_real is False:  # (queried only here: the rule's own verdict came first)
            raise ParameterError(component, name, f"{expr} is never a real number (a root or logarithm of a quantity "
                                                  f"always negative, as sqrt(-1 - x**2)): give a real expression.")
        raise ParameterError(component, name, f"{rule}, but {expr} is declared otherwise (by the assumptions of "
                                              f"its symbols).")


#: Assumptions of the symbol standing for a number, from the parameter's check.
_ASSUMPTIONS = {
    "fraction": {"positive": True},
    "positive": {"positive": True},
    "nonnegative": {"nonnegative": True},
    "nonzero": {"nonzero": True, "real": True},
    "real": {"real": True},
}


class _Standing:
    """Symbols standing for the nonzero numbers in the entries of one vector, matrix or mapping of vectors.

    Zeros stay zeros (they decide the form of the energy); equal numbers
    share one symbol (equal principal moments make a symmetric body, whose
    spin is then ignorable whether given as numbers or symbols).  Each
    symbol's sign is its value's.
    """

    def __init__(self, prefix: str, values: dict):
        self.prefix, self.values, self.by_value, self.used = prefix, values, {}, False

    def view(self, value: Any, where: str = "") -> Any:
        if isinstance(value, Mapping):
            return {k: self.view(v, f"{where}_{k}") for k, v in value.items()}
        if isinstance(value, sp.MatrixBase):
            cols = value.shape[1]
            return value.__class__(value.rows, cols, [
                self.entry(e, f"{where}_{i}" if cols == 1 else f"{where}_{i}_{j}")
                for i in range(value.rows) for j in range(cols) for e in [value[i, j]]])
        return value

    def entry(self, value: Any, where: str) -> Any:
        if not _plain_number(value) or value == 0:
            return value
        if value not in self.by_value:
            symbol = sp.Dummy(f"{self.prefix}{where}", **({"positive": True} if value > 0 else {"negative": True}))
            self.by_value[value] = symbol
            self.values[symbol] = value
        self.used = True
        return self.by_value[value]


def _plain_number(value: Any) -> bool:
    """A finite real number (a SymPy Number), as opposed to an expression, a matrix or a callable."""
    return isinstance(value, sp.Number) and value.is_finite is not False


class _CallableSignal:
    """A Python callable of time — or, for a load (``state``), of ``(t, q, v)`` with ``q`` and ``v`` mappings of
    coordinate names to values — standing in for a signal parameter.  Its undefined function is applied to ``t``
    alone while the component contributes; the assembly applies a state callable's to every coordinate and rate
    (:func:`lagrangian.derivation.assembly.assemble`)."""

    def __init__(self, func: Callable[..., float], label: str, state: bool = False):
        self.func = func
        self.state = state
        self.function = sp.Function(_identifier(label))
        self.expr = self.function(t)

    def __repr__(self) -> str:
        return f"<callable {self.function}({'t, q, v' if self.state else 't'})>"


class StateCall:
    """A load's Python callable ``f(t, q, v)`` as the equations call it, ``f(t, q₁, …, qₙ, v₁, …, vₙ)``: ``q`` and
    ``v`` handed over as mappings of the coordinate names to values (numbers, or arrays of many states alike)."""

    def __init__(self, func: Callable[..., Any], names: Sequence[str]):
        self.func, self.names = func, list(names)

    def __call__(self, time, *args):
        n = len(self.names)
        return self.func(time, dict(zip(self.names, args[:n])), dict(zip(self.names, args[n:])))


def _arity(func: Callable) -> int | None:
    """How many arguments ``func`` requires (1 for what its signature does not say: a builtin of one number)."""
    import inspect

    try:
        sig = inspect.signature(func)
    except (TypeError, ValueError):
        return 1
    kinds = (inspect.Parameter.POSITIONAL_ONLY, inspect.Parameter.POSITIONAL_OR_KEYWORD)
    required = [p for p in sig.parameters.values() if p.kind in kinds and p.default is p.empty]
    if any(p.kind == inspect.Parameter.VAR_POSITIONAL for p in sig.parameters.values()) and not required:
        return 1
    return len(required)


def _identifier(label: str) -> str:
    out = "".join(ch if ch.isalnum() or ch == "_" else "_" for ch in label)
    return out if out and not out[0].isdigit() else f"f_{out}"


@dataclass(frozen=True)
class Load:
    """A generalized force given by virtual power: ``force · velocity``.

    ``velocity`` is the velocity (a SymPy expression or column matrix, in
    terms of the coordinates' time derivatives) of the point or branch the
    force acts on; the generalized force on coordinate ``q_k`` is
    ``force · ∂velocity/∂q̇_k``.  ``force`` may depend on velocities.
    """

    force: Any
    velocity: Any


@dataclass(frozen=True)
class MovingFrame:
    """Velocities a component's ``T`` is written in, expressed in the axes of a frame that turns.

    ``omega`` is the frame's angular velocity in its own axes (3 components);
    each of ``velocities`` is the velocity of a point, in the same axes.  A
    rigid body's ``T = ½ m v·v + ½ ωᵀ I ω`` is shortest in its own axes, but
    those components are not time derivatives of anything, and Lagrange's
    equations then carry terms from the frame's turning.  Declaring the frame
    lets the derivation write them in closed form, ``Ω_i × ω`` for the
    angular velocity and ``V_i × ω + Ω_i × v`` for a velocity (``Ω_i``,
    ``V_i`` their coefficients of ``q̇_i``), instead of differentiating every
    coefficient by every coordinate.  Optional: the equations are the same
    without it, only larger.
    """

    omega: Any
    velocities: tuple = ()


@dataclass
class Contribution:
    """What one component adds to the model (all SymPy, in terms of the context's coordinates).

    ``T``: kinetic energy or co-energy; ``V``: potential energy;
    ``D``: Rayleigh dissipation function (half the dissipated power for a
    linear damper); ``G``: terms of the Lagrangian linear in the velocities
    that store no energy (gyroscopic and gyrator couplings such as a moving
    coil's ``Bl·x·q̇``), so that ``L = T − V + G``; ``loads``: generalized
    forces by virtual power; ``frames``: the :class:`MovingFrame` objects
    whose velocities ``T`` is written in, if any; ``constraints``: holonomic
    constraints ``Φ(q, t) = 0`` the component imposes between coordinates
    (a gear pair, a rack and pinion, rolling without slipping), each kept
    with a Lagrange multiplier as a closed loop's closure is;
    ``velocity_constraints``: constraints on velocities ``A(q, t)·q̇ + b(q, t)
    = 0`` that no ``Φ(q, t)`` integrates (nonholonomic: a knife edge, a disc
    rolling in space), each entering Lagrange's equations with a multiplier
    (the Lagrange–d'Alembert form).
    """

    T: Any = 0
    V: Any = 0
    D: Any = 0
    G: Any = 0
    loads: list[Load] = field(default_factory=list)
    frames: list[MovingFrame] = field(default_factory=list)
    constraints: list[Any] = field(default_factory=list)
    velocity_constraints: list[Any] = field(default_factory=list)


@dataclass(frozen=True)
class Example:
    """An example instance of a component kind, for documentation and the conformance suite.

    ``nodes`` and ``params`` build the instance itself; ``context`` lists the
    other components (``(kind, name, nodes, params)``) that make a model of
    it well-posed; ``options`` are :class:`Model` options.
    """

    nodes: Any = ()
    params: Mapping[str, Any] = field(default_factory=dict)
    context: Sequence[tuple[str, str, Any, Mapping[str, Any]]] = ()
    options: Mapping[str, Any] = field(default_factory=dict)


class Component:
    """Base class of every component type.

    Subclasses declare, as class attributes:

    1. ``kind``: the unique name users pass to :meth:`Model.add`.
    2. ``domain``: the registered domain whose coordinates it reads.
    3. ``terminals``: names of its connection points.  One terminal means
       the component sits between that node and ``ground`` (a mass is
       referred to the inertial frame as a capacitor is to ground); two
       terminals ``(a, b)`` give a branch oriented from ``a`` to ``b``.
    4. ``parameters``: a mapping of name to :class:`Parameter`.
    5. ``terminal_domains`` (optional): the domain of each terminal, for a
       component that couples domains (a transducer); ``domain`` is then the
       domain whose view ``ctx.view`` is, and ``ctx.views`` has the others.
       Its branches are ``branches()``; each belongs to the domain of its nodes.
    6. ``role``: ``None``, ``"across"`` (an ideal source fixing the across
       quantity of its branch: a prescribed motion, a voltage source) or
       ``"through"`` (fixing its through quantity: a current source).
    7. ``distinct_terminals`` (optional, default ``True``): a component of
       two or more terminals acts between different nodes, so one whose
       branch joins a node to itself (two of its terminals of one domain
       given the same node, ``ground`` under any of its names included) is
       refused when added (:meth:`self_loop`, a
       :class:`~lagrangian.errors.TopologyError`).  ``False`` for a kind
       whose branch from a node to itself means something; no built-in
       kind has one (a spring, damper, joint, resistor, capacitor, inductor
       or source from a node to itself acts on nothing, or holds 0/0).

    and implement ``contribute(ctx)`` and the classmethod ``example()``;
    optionally ``linear(ctx)``, the same contribution in numbers for a
    component linear with constant coefficients (:mod:`lagrangian.base.linear`).
    Parameters are available as attributes (``self.k``).
    """

    kind: ClassVar[str]
    domain: ClassVar[str]
    terminals: ClassVar[tuple[str, ...]] = ("a", "b")
    parameters: ClassVar[Mapping[str, Parameter]] = {}
    role: ClassVar[str | None] = None
    terminal_domains: ClassVar[tuple[str, ...] | None] = None
    #: True for a component whose T is a cross term between others' velocities (a mutual
    #: inductance): not positive semidefinite on its own, only in the model's total.
    cross_energy: ClassVar[bool] = False
    #: True for a component that gives the model coordinates or geometry (a joint, a massless link)
    #: rather than energy: its contribution may be empty.
    structural: ClassVar[bool] = False
    #: True (the default) for a component that acts between different nodes: one whose branch joins a node to
    #: itself is refused when added (:meth:`self_loop`); False for a kind whose self-loop means something.
    distinct_terminals: ClassVar[bool] = True
    #: The schematic symbol of a two-terminal circuit element: the name of a ``schemdraw.elements`` class
    #: (``"Resistor"``, ``"Capacitor"``, ``"Inductor2"``, ``"SourceV"``, ...), for ``Model.schematic``;
    #: ``None``: drawn as a box with the component's kind.
    symbol: ClassVar[str | None] = None

    def __init__(self, name: str, nodes: tuple[str, ...], params: Mapping[str, Any]):
        self.name = name
        self.nodes = nodes
        unknown = set(params) - set(self.parameters)
        if unknown:
            bad = sorted(unknown)[0]
            raise ParameterError(
                name,
                bad,
                f"{self.kind!r} has no such parameter.{closest(bad, self.parameters)} "
                f"Its parameters: {', '.join(self.parameters) or '(none)'}.",
            )
        values = Params()  # plain numbers and waveforms as given, read as SymPy objects (lagrangian.base.params)
        floats = {}  # the parameters given as plain numbers, as floats (what numeric assembly reads)
        for pname, spec in self.parameters.items():
            if pname in params:
                raw = params[pname]
                held = spec.held(raw)
                values[pname] = raw if held else spec.coerce(raw, name, pname)
                if held and type(raw) in (float, int):
                    floats[pname] = float(raw)
            elif spec.required:
                raise ParameterError(name, pname, f"required ({spec.doc}{', ' + spec.unit if spec.unit else ''}).")
            elif spec.default is not None:
                values[pname] = spec.default if spec.held(spec.default) else spec.coerce(spec.default, name, pname)
            else:
                values[pname] = None
        self.params = values
        self._given = frozenset(params)
        self._floats = floats

    def __getstate__(self) -> dict[str, Any]:
        """Its attributes; a parameter given as a Python callable that pickle cannot carry is refused, by name."""
        for pname, value in dict.items(self.params):
            if isinstance(value, _CallableSignal):
                refuse_unpicklable(value.func, f"component {self.name!r}: parameter {pname!r}")
        return self.__dict__

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        if type(self.__dict__.get("params")) is dict:  # pickled before values were held as given
            self.params = Params(self.params)

    def _stand(self) -> None:
        """Make the symbols standing for the parameters given as numbers (:attr:`values`), on first use: a model
        assembled in numbers (:mod:`lagrangian.derivation.numeric`) never needs them, and they are a third of the
        cost of adding a component."""
        if "_values" in self.__dict__:
            return
        standing_values: dict[sp.Symbol, sp.Expr] = {}
        symbols: dict[str, Any] = {}
        for pname, spec in self.parameters.items():
            value = self.params.get(pname)
            if pname not in self._given or not spec.symbolic or value is None:
                continue
            if spec.shape in ("scalar", "signal", "tensor") and _plain_number(value):
                symbol = sp.Dummy(f"{pname}_{self.name}", **_ASSUMPTIONS[spec.check])
                symbols[pname] = symbol
                standing_values[symbol] = value
            elif spec.shape in ("vector", "tensor", "mapping"):
                standing = _Standing(f"{pname}_{self.name}", standing_values)
                view = standing.view(value)
                if standing.used:
                    symbols[pname] = view
        self.__dict__["_values"], self.__dict__["_symbols_"] = standing_values, symbols

    @property
    def values(self) -> dict[sp.Symbol, sp.Expr]:
        """Symbol → value, for the parameters given as numbers (see :meth:`symbolic_view`)."""
        self._stand()
        return self.__dict__["_values"]

    @values.setter
    def values(self, values: dict[sp.Symbol, sp.Expr]) -> None:
        self._stand()
        self.__dict__["_values"] = values

    @property
    def _symbols(self) -> dict[str, Any]:
        self._stand()
        return self.__dict__["_symbols_"]

    @_symbols.setter
    def _symbols(self, symbols: dict[str, Any]) -> None:
        self._stand()
        self.__dict__["_symbols_"] = symbols

    def symbolic_view(self) -> "Component":
        """This component with every parameter given as a number replaced by a symbol standing for it.

        The assembly derives the model's equations from the view's
        contributions and substitutes :attr:`values` afterwards, so a model
        built with numbers and its twin built with symbols share their
        derivation.  A component without such parameters is its own view.

        >>> import lagrangian as lg
        >>> spring = lg.Model().add("spring", "k1", ("ground", "p"), k=0.3)
        >>> spring.k, spring.symbolic_view().k, list(spring.values.values())
        (0.300000000000000, _k_k1, [0.300000000000000])
        """
        if not self._symbols:
            return self
        view = object.__new__(type(self))
        view.__dict__.update(self.__dict__)
        view.params = Params({**self.params, **self._symbols})
        view._floats = {k: v for k, v in getattr(self, "_floats", {}).items() if k not in self._symbols}
        return view

    def with_input(self, pname: str, label: str, index: int | None = None) -> tuple["Component", sp.Function]:
        """A copy of this component whose signal parameter ``pname`` is its value plus an input ``u = ẇ``.

        ``w`` is an undefined function of time named ``label``, returned with
        the copy; the input enters the copy's contribution wherever the
        parameter does, as the rate of ``w`` (its derivatives too, for a
        prescribed motion; ``w`` itself where a source's integral fixes a
        coordinate, as a voltage source does in node fluxes), so the
        derivatives of a model's equations by ``w`` and its rates are its
        response to that input (linearization, transfer functions).  The
        original value stays in as the input's operating value.  ``index``
        picks the entry of a vector parameter to drive.

        >>> import lagrangian as lg
        >>> source = lg.Model().add("voltage_source", "V1", ("n1", "0"), E=5)
        >>> twin, w = source.with_input("E", "w_V1")
        >>> twin.E, twin.values  # the symbol standing for 5, plus ẇ
        (_E_V1 + Derivative(w_V1(t), t), {_E_V1: 5})
        """
        spec = self.parameters.get(pname)
        if spec is None or spec.shape != "signal":
            raise ParameterError(self.name, pname, f"{self.kind!r} has no signal parameter of that name; its signals: "
                                 f"{', '.join(p for p, s in self.parameters.items() if s.shape == 'signal') or '(none)'}.")
        value = self.params[pname]
        if isinstance(value, _CallableSignal):
            raise ParameterError(self.name, pname, "is a Python callable, which has no operating value to perturb; "
                                 "give it as a number or a SymPy expression of t.")
        base = self._symbols.get(pname, value)
        w = sp.Function(_identifier(label), real=True)
        rate = sp.Derivative(w(t), t)
        if isinstance(base, sp.MatrixBase):
            if index is None or not 0 <= index < len(base):
                raise ParameterError(self.name, pname, f"is a vector of {len(base)} components: name the one to drive, "
                                     f"as '{self.name}[0]'.")
            base = base + sp.Matrix([rate if i == index else 0 for i in range(len(base))])
        elif index is not None:
            raise ParameterError(self.name, pname, f"is a scalar: drive it as '{self.name}', without an index.")
        else:
            base = base + rate
        twin = object.__new__(type(self))
        twin.__dict__.update(self.__dict__)
        twin.params = Params({**self.params, pname: base})
        twin._floats = {k: v for k, v in getattr(self, "_floats", {}).items() if k != pname}
        twin._symbols = {k: v for k, v in self._symbols.items() if k != pname}
        twin._inputs = {*self.inputs(), w}
        return twin, w

    def inputs(self) -> set:
        """The input functions ``w`` that :meth:`with_input` put into this component's parameters."""
        return self.__dict__.get("_inputs", set())

    def given(self, pname: str) -> Any:
        """Parameter ``pname`` as a user would give it again: the Python callable of a signal given as one (where
        ``self.<pname>`` is the undefined function standing for it in the equations), else its value.

        >>> import lagrangian as lg
        >>> f = lg.Model().add("force", "F", "p", F=abs)
        >>> f.F, f.given("F") is abs
        (F_F(t), True)
        """
        value = self.params[pname]
        return value.func if isinstance(value, _CallableSignal) else value

    def state(self, pname: str) -> list[sp.Expr]:
        """The coordinates ``x(t)`` that parameter ``pname`` depends on (a load's signal of the state), sorted.

        >>> import lagrangian as lg
        >>> lg.Model().add("force", "F", "p", F=-2 * lg.rate("x_p") - lg.coordinate("y_p")).state("F")
        [x_p(t), y_p(t)]
        """
        value = self.params[pname]
        if not isinstance(value, (sp.Basic, sp.MatrixBase)):
            return []
        return sorted({f for f in value.atoms(sp.core.function.AppliedUndef)
                       if f.args == (t,) and f.func not in self.inputs()}, key=str)

    def __getattr__(self, item: str) -> Any:
        params = self.__dict__.get("params")
        if params is not None and item in params:
            value = params[item]
            return value.expr if isinstance(value, _CallableSignal) else value
        raise AttributeError(f"{type(self).__name__!s} {self.__dict__.get('name', '')!r} has no attribute {item!r}")

    def __repr__(self) -> str:
        return f"<{self.kind} {self.name!r} at {', '.join(self.nodes) or '(global)'}>"

    def node_domain(self, index: int) -> str:
        """The domain of terminal ``index``."""
        return self.terminal_domains[index] if self.terminal_domains else self.domain

    @property
    def domains(self) -> tuple[str, ...]:
        """Every domain this component touches, its own first."""
        return tuple(dict.fromkeys((self.domain, *(self.terminal_domains or ()))))

    def branches(self) -> list[tuple[str, str]]:
        """Edges this component adds to the graph, as ``(a, b)`` node pairs."""
        if len(self.nodes) == 1:
            return [(self.nodes[0], GROUND)]
        if len(self.nodes) == 2:
            return [tuple(self.nodes)]
        if not self.nodes:
            return []
        raise NotImplementedError(f"{self.kind}: components with more than two terminals must define branches()")

    def self_loop(self) -> tuple[str, str, str] | None:
        """``(terminal, terminal, node)``: two terminals of one domain given the same ``node``, joined by one of this
        component's branches from that node to itself; ``None`` when there are none, for a component of fewer than
        two terminals, or for a kind that allows them (``distinct_terminals = False``).

        >>> import lagrangian as lg
        >>> lg.Model().add("spring", "k1", ("ground", "p"), k=5).self_loop() is None
        True
        """
        if len(self.nodes) < 2 or not self.distinct_terminals:
            return None
        try:
            branches = self.branches()
        except NotImplementedError:  # a kind of more than two terminals without its branches: said where they are used
            return None
        names = [*self.terminals, *(str(i) for i in range(len(self.terminals), len(self.nodes)))]
        for a, b in branches:
            if a != b:
                continue
            given = [i for i, n in enumerate(self.nodes) if n == a]
            for i in given:
                for j in given:
                    if i < j and self.node_domain(i) == self.node_domain(j):
                        return names[i], names[j], a
        return None

    def signals(self) -> dict[sp.Function, Callable[[float], float]]:
        """Python callables standing behind the component's signal parameters (of time; a load's of the state too,
        marked by their ``state``)."""
        return {v.function: v.func for v in self.params.values() if isinstance(v, _CallableSignal)}

    def signal_owners(self) -> dict[str, tuple[str, str]]:
        """The names of the undefined functions standing for this component's Python callables → ``(component,
        parameter)``."""
        return {v.function.__name__: (self.name, p) for p, v in self.params.items() if isinstance(v, _CallableSignal)}

    def state_callables(self) -> list[sp.Function]:
        """The undefined functions standing for this component's callables of ``(t, q, v)``."""
        return [v.function for v in self.params.values() if isinstance(v, _CallableSignal) and v.state]

    #: the quantities :meth:`quantity` names, with what each is (for error messages and documentation)
    quantities: ClassVar[Mapping[str, str]] = {}

    def quantity(self, ctx: Any, name: str) -> sp.Expr:
        """A named quantity of this component (``"v"``, ``"i"`` of a circuit element: the voltage ``v_a − v_b``
        and the current from ``a`` to ``b``) as an expression of the coordinates ``q(t)`` and their derivatives,
        for outputs of analyses (transfer functions, impedances).  Types list theirs in :attr:`quantities`."""
        raise ParameterError(self.name, name, f"{self.kind!r} names no such quantity; it names "
                             f"{', '.join(f'{k} ({v})' for k, v in self.quantities.items()) or 'none'}.")

    def linear(self, ctx: Any) -> Any:
        """This component's contribution in numbers, a :class:`lagrangian.base.linear.Linear` (``ctx``: a
        :class:`~lagrangian.base.linear.LinearContext`), or ``None`` (the default) when it is not linear with
        constant coefficients or a parameter it needs has no value: the model is then derived symbolically."""
        return None

    def contribute(self, ctx: Any) -> Contribution:  # pragma: no cover - abstract
        """Return this component's :class:`Contribution` for the model context ``ctx``."""
        raise NotImplementedError

    @classmethod
    def example(cls) -> Example:  # pragma: no cover - abstract
        """An :class:`Example` of this kind, used by documentation and the conformance suite."""
        raise NotImplementedError

