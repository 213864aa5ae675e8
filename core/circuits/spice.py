"""SPICE netlists from circuit models, and transient runs in ngspice through PySpice.

A component that has a SPICE equivalent implements ``spice(ctx)`` returning
a list of :class:`SpiceElement`; this module numbers the nodes, writes the
netlist text (and the PySpice ``Circuit`` holding it), sets element initial
conditions from the model's initial state (SPICE ``uic``), runs ngspice's
shared library through PySpice, and reads back the *state quantities* —
capacitor voltages and inductor currents — that the elements declared, so
they can be compared with the model quantity by quantity.

ngspice facts this relies on (see the project's notes): accuracy comes from
the step cap, not the tolerances; with ``uic`` there is no row at t = 0;
branch currents are positive from n+ to n− through the element; the shared
library is one instance per process and not thread-safe, so runs are
serialized with a lock, and every run removes its circuit and plots.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import logging
import math
import numbers
import re
import threading
import time as _time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..base.component import GROUND, t
from ..base.domain import Context
from ..base.text import as_expr
from ..errors import LagrangianError, ModelError, NumericalError
from ..model import Model
from ..numerics.simulation import initial_state
from ..base import deferred as _deferred

sp = _deferred.module("sympy", globals())

__all__ = [
    "SpiceElement",
    "Behaviour",
    "Netlist",
    "SpiceRun",
    "NgspiceError",
    "NgspiceMissingError",
    "netlist",
    "run_transient",
    "spice_expression",
    "spice_waveform",
]

_LOCK = threading.Lock()


class NgspiceMissingError(LagrangianError):
    """ngspice's shared library (or PySpice) cannot be loaded."""


class NgspiceError(NumericalError):
    """ngspice rejected the netlist or failed to converge; the message carries ngspice's own words."""


@dataclass(frozen=True)
class SpiceElement:
    """One SPICE element contributed by a component.

    ``prefix`` is the SPICE letter (``R``, ``L``, ``C``, ``V``, ``I``, ``B``,
    ``H``, ``K``); ``nodes`` are model node names, or internal nodes of the
    component written ``"~name"``; ``value`` is the rest of the line
    (``"0.25"``, ``"SIN(0 1 0.5)"``, ``"V=sin(2*time)"``), in which
    ``{tag}`` stands for the SPICE name of the component's element tagged
    ``tag`` (a controlled source names its controlling element so) and
    ``{ref0}``, ``{ref1}``, ... for the SPICE names of the elements of the
    components named in ``refs`` (a ``K`` line names its inductors); ``state``, for
    energy-storing elements, is ``("v", voltage)`` or ``("i", current)``: the
    quantity (a SymPy expression in the model's coordinates) that becomes the
    element's ``ic=`` and is read back from ngspice, labelled ``v(<component>)``
    / ``i(<component>)``, or ``v(<component>.<tag>)`` when the component has
    several state elements.  ``value`` may also be a :class:`Behaviour`: the
    law of a ``B`` source written from SymPy, its node and element names
    filled in here.
    """

    prefix: str
    nodes: tuple[str, ...]
    value: str
    state: tuple[str, sp.Expr] | None = None
    tag: str = ""
    refs: tuple[str, ...] = ()


@dataclass(frozen=True)
class Behaviour:
    """The law of a behavioural (``B``) source: ``V=expr`` or ``I=expr``, written as SymPy.

    ``expr`` is an expression of :data:`t`, of the component's parameters
    (their values put in like every element value, ``params=...``) and of the
    symbols keyed in ``controls``, each standing for what ngspice measures:
    ``("v", node)`` a node voltage, ``("v", node_a, node_b)`` a voltage
    difference (model nodes or the component's internal ``"~name"`` nodes),
    ``("i", tag)`` the current through the component's own voltage source
    tagged ``tag``.  :func:`netlist` prints it with the SPICE names of those
    nodes and elements, through the same printer as every behavioural source.
    """

    quantity: str
    expr: Any
    controls: tuple[tuple[sp.Symbol, tuple[str, ...]], ...] = ()

    def __post_init__(self):
        if self.quantity not in ("V", "I"):
            raise ModelError(f"a behavioural source sets V or I, not {self.quantity!r}.")


@dataclass
class Netlist:
    """A SPICE netlist generated from a model, with the record of where everything came from.

    ``text`` is the netlist; ``elements`` maps SPICE element name to component
    name; ``nodes`` maps model node to SPICE node; ``probes`` maps each state
    quantity label (``"v(C1)"``, ``"i(L1)"``) to ``(kind, spice names...)``;
    ``quantities`` maps the same labels to SymPy expressions in the model's
    coordinates.
    """

    text: str
    elements: dict[str, str]
    nodes: dict[str, str]
    probes: dict[str, tuple[str, ...]]
    quantities: dict[str, sp.Expr]
    initial: dict[str, float] = field(default_factory=dict)

    def pyspice_circuit(self):
        """The same netlist as a PySpice ``Circuit`` (elements as raw SPICE lines)."""
        from PySpice.Spice.Netlist import Circuit

        lines = self.text.splitlines()
        circuit = Circuit(lines[0].removeprefix(".title ").strip())
        circuit.raw_spice = "\n".join(
            line for line in lines[1:] if line.strip() and not line.lower().startswith((".end", ".tran"))
        )
        return circuit


@dataclass
class SpiceRun:
    """Output of one ngspice analysis: time points (frequencies, for ``.ac``) and the quantities probed on them."""

    time: np.ndarray
    quantities: dict[str, np.ndarray]
    wall: float
    messages: list[str] = field(default_factory=list)
    #: seconds ngspice took to load (parse and set up) the netlist, before ``wall``
    load: float = 0.0
    #: seconds reading ngspice's output vectors into arrays, after ``wall``
    read: float = 0.0


# -- expressions and waveforms -------------------------------------------------------------------


@functools.cache
def _spice_printer() -> type:
    """:class:`_SpicePrinter`, made on first use (a subclass of SymPy's, which is imported then)."""
    from sympy.printing.str import StrPrinter

    class _SpicePrinter(StrPrinter):
        def __init__(self, names: Mapping[sp.Symbol, str] | None = None):
            super().__init__()
            self.names = dict(names or {})

        def _print_Symbol(self, expr):
            if expr == t:
                return "time"
            if expr in self.names:
                return self.names[expr]
            raise ModelError(f"the expression still has the symbol {expr}: give it a value (params=...).")

        _print_Dummy = _print_Symbol

        def _print_Pow(self, expr, rational=False):
            base, exp = expr.as_base_exp()
            if exp == sp.Rational(1, 2):
                return f"sqrt({self._print(base)})"
            if exp.is_Integer and int(exp) % 2:  # ngspice's pow(x, n) is |x|^n: odd powers keep the sign by a factor x
                n = abs(int(exp))
                odd = f"({self._print(base)})" if n == 1 else f"({self._print(base)})*pow({self._print(base)},{n - 1})"
                return f"1/({odd})" if exp < 0 else odd
            return f"pow({self._print(base)},{self._print(exp)})"

        def _print_Float(self, expr):
            return repr(float(expr))

        def _print_Rational(self, expr):
            return repr(float(expr))

        def _print_Integer(self, expr):
            return str(int(expr))

        def _print_Piecewise(self, expr):
            out = self._print(expr.args[-1].expr) if expr.args[-1].cond == True else "0"  # noqa: E712
            for piece in reversed(expr.args[:-1] if expr.args[-1].cond == True else expr.args):  # noqa: E712
                out = f"(({self._print(piece.cond)}) ? ({self._print(piece.expr)}) : ({out}))"
            return out

        def _print_Mod(self, expr):  # a periodic pulse's phase: ngspice has floor, not mod
            a, b = (self._print(x) for x in expr.args)
            return f"(({a}) - ({b}) * floor(({a}) / ({b})))"

        def _print_floor(self, expr):
            return f"floor({self._print(expr.args[0])})"

        def _print_ceiling(self, expr):
            return f"ceil({self._print(expr.args[0])})"

        def _print_Heaviside(self, expr):
            return f"u({self._print(expr.args[0])})"

        def _print_log(self, expr):
            return f"ln({self._print(expr.args[0])})"

        def _print_And(self, expr):
            return " && ".join(f"({self._print(a)})" for a in expr.args)

        def _print_Or(self, expr):
            return " || ".join(f"({self._print(a)})" for a in expr.args)

        def _print_BooleanTrue(self, expr):
            return "1"

        def _print_Function(self, expr):
            name = expr.func.__name__
            if name not in {"sin", "cos", "tan", "exp", "sqrt", "abs", "sinh", "cosh", "tanh", "atan", "asin", "acos"}:
                raise ModelError(f"ngspice has no function {name!r} (in {expr}); give the signal as an elementary expression of t.")
            return f"{name}({', '.join(self._print(a) for a in expr.args)})"

        _print_Abs = lambda self, expr: f"abs({self._print(expr.args[0])})"  # noqa: E731

    return _SpicePrinter


def _fmt(x: Any) -> str:
    return f"{float(x):.15g}"


def spice_expression(expr: Any, names: Mapping[sp.Symbol, str] | None = None) -> str:
    """An expression of :data:`t` as ngspice behavioural-source text (``time`` for t).

    ``names`` writes other symbols as the given text (what :func:`netlist`
    does for a :class:`Behaviour`'s node voltages and currents).  Odd integer
    powers are written with a factor of their base, since ngspice's
    ``pow(x, n)`` is ``|x|^n``.

    >>> spice_expression(3 * sp.sin(2 * t) + t**2)
    'pow(time,2) + 3*sin(2*time)'
    >>> spice_expression(sp.sin(t) ** 3)
    '(sin(time))*pow(sin(time),2)'
    """
    return _spice_printer()(names).doprint(sp.sympify(expr))


def spice_waveform(expr: Any) -> str | None:
    """A standard SPICE source waveform for ``expr`` (``DC``, ``SIN``), or ``None`` if there is none.

    >>> spice_waveform(2)
    'DC 2'
    >>> spice_waveform(0.5 + 2 * sp.cos(3 * t))
    'SIN(0.5 2 0.477464829275686 0 0 90)'
    """
    expr = sp.sympify(expr)
    if not expr.has(t):
        return f"DC {_fmt(expr)}"
    c, a, w, p = (sp.Wild(n, exclude=[t]) for n in "cawp")
    for trig, shift in ((sp.sin, 0.0), (sp.cos, 90.0)):
        m = expr.match(c + a * trig(w * t + p))
        if m and m[w] != 0 and all(m[x].is_number for x in (c, a, w, p)):
            amp, omega, phase = float(m[a]), float(m[w]), float(m[p]) * 180 / np.pi + shift
            if omega < 0:  # sin(-wt + p) = -sin(wt - p); cos(-wt + p) = cos(wt - p)
                omega, phase = -omega, -phase + (2 * shift if shift else 180.0)
            return f"SIN({_fmt(m[c])} {_fmt(amp)} {_fmt(omega / (2 * np.pi))} 0 0 {_fmt(phase)})"
    return None


# -- netlist ---------------------------------------------------------------------------------------


class _NodeNames(dict):
    """SPICE node names, made safe (lower case, no ``time``) and unique as nodes are met."""

    def __init__(self, nodes: Sequence[str]):
        super().__init__({GROUND: "0"})
        self.used = {"0"}
        for node in nodes:
            self[node]  # noqa: B018 - name the model's nodes first, in order

    def __missing__(self, node: str) -> str:
        base = _bounded(re.sub(r"[^a-z0-9_]", "_", str(node).lower().lstrip("~")) or "n", str(node))
        if base in {"time", "0", "gnd"} or not base[0].isalpha():
            base = f"n_{base}"
        name, i = base, 1
        while name in self.used:
            i += 1
            name = f"{base}_{i}"
        self[node] = name
        self.used.add(name)
        return name


def spice_title(text: str) -> str:
    """A model's name as a deck's title line: letters, digits, spaces and the signs ``_-.,()`` kept, anything else
    (a newline that would start a ``.control`` block or an element, a ``*``, a ``;``) made ``_``, at most 80
    characters — user text enters a deck only through this, :class:`_NodeNames` and ``_element_name``.

    >>> spice_title("rlc" + chr(10) + ".control" + chr(10) + "shell touch x")
    'rlc_.control_shell touch x'
    """
    safe = re.sub(r"[^A-Za-z0-9 _\-.,()]", "_", str(text))[:80].strip()
    return safe or "model"


#: the longest name written into a deck: ngspice copies names into fixed buffers (a 520-character node name in a
#: behavioural source overflows one and aborts the process)
MAX_NAME = 48


def _bounded(name: str, original: str) -> str:
    """``name`` cut to :data:`MAX_NAME` characters, with a digest of ``original`` so that cut names stay distinct.

    >>> len(_bounded("n" * 500, "n" * 500)) <= MAX_NAME
    True
    """
    if len(name) <= MAX_NAME:
        return name
    digest = hashlib.blake2s(original.encode("utf-8", "surrogatepass"), digest_size=5).hexdigest()
    return f"{name[:MAX_NAME - 11]}_{digest}"


def _element_name(prefix: str, component: str, used: set[str]) -> str:
    base = _bounded(re.sub(r"[^a-z0-9_]", "_", component.lower()), component)
    name = base if base.startswith(prefix.lower()) else f"{prefix.lower()}_{base}"
    out, i = name, 1
    while out in used:
        i += 1
        out = f"{name}_{i}"
    used.add(out)
    return out


def _number(value: Any, subs: Mapping, what: str) -> str:
    """``value`` (its parameters' values in) as a SPICE number; ``what`` names whose value it is in messages."""
    value = as_expr(value, f"{what}: its SPICE value").xreplace(subs)
    if not value.is_number:
        raise ModelError(f"{what}: its SPICE value {value} is not a number; give parameter values (params=...).")
    try:
        x = float(value)  # a complex number (sqrt(-2), I) raises: it has no float
    except (TypeError, ValueError, OverflowError):
        raise ModelError(f"{what}: its SPICE value {value} is not a real number; SPICE takes real values.") from None
    if not math.isfinite(x):
        raise ModelError(f"{what}: its SPICE value {value} is not finite ({x}); SPICE takes finite values.")
    return _fmt(x)


def netlist(
    model: Model,
    *,
    initial: Mapping[str, float] | None = None,
    velocity: Mapping[str, float] | None = None,
    params: Mapping[str, float] | None = None,
    t_end: float = 1.0,
    step: float | None = None,
    max_step: float | None = None,
    options: Mapping[str, float] | None = None,
) -> Netlist:
    """The SPICE netlist of a circuit model, with element initial conditions from its initial state.

    Every component must implement ``spice(ctx)``; the ``.tran`` line uses
    ``step`` (default ``t_end/1000``) and the step cap ``max_step`` (default
    ``step/10``) with ``uic``.  ``options`` adds an ``.options`` line of
    numeric simulator options (``{"reltol": 1e-7, "abstol": 1e-16}``): a
    circuit whose charges, currents or voltages are far below ngspice's
    absolute tolerances (``abstol`` 1e-12 A, ``vntol`` 1e-6 V, ``chgtol``
    1e-14 C) needs smaller ones.

    >>> import lagrangian as lg
    >>> m = lg.Model("rc")
    >>> _ = m.add("voltage_source", "V1", ("in", "0"), E=1)
    >>> _ = m.add("resistor", "R1", ("in", "out"), R=1e3)
    >>> _ = m.add("capacitor", "C1", ("out", "0"), C=1e-6)
    >>> print(netlist(m, t_end=5e-3).text)
    .title rc
    v1 in 0 DC 1
    r1 in out 1000
    c1 out 0 1e-06 ic=0
    .tran 5e-06 0.005 0 5e-07 uic
    .end
    """

    t_end = _seconds("t_end", t_end)
    step = None if step is None else _seconds("step", step)
    max_step = None if max_step is None else _seconds("max_step", max_step)
    values = model._values(params or {})
    subs = {s: sp.Float(v) for s, v in values.items()}
    eq = model.eq
    y0, _ = initial_state(eq, initial or {}, velocity or {}, warn=False)
    numeric = model.numeric(params)
    v_all, _ = numeric.velocities(0.0, y0)
    point = {**dict(zip(eq.sym.q, y0[: numeric.n])), **dict(zip(eq.sym.v, v_all)), t: 0.0}

    asm = model.assembly
    nodes = _NodeNames(model.nodes)
    lines = [f".title {spice_title(model.name)}"]
    elements: dict[str, str] = {}
    probes: dict[str, tuple[str, ...]] = {}
    quantities: dict[str, sp.Expr] = {}
    used: set[str] = set()
    ics: dict[str, float] = {}
    pending: list[tuple[Any, list[SpiceElement], list[str]]] = []
    for comp in model.components.values():
        spice = getattr(comp, "spice", None)
        if spice is None:
            raise ModelError(
                f"{comp.kind} {comp.name!r} has no SPICE equivalent (its kind does not implement spice(ctx)); "
                f"map a mechanism to its circuit analogue first (lagrangian.analogy)."
            )
        ctx = Context(asm.views[comp.domain], asm.views, model.options, list(model.components.values()), values=subs)
        parts = spice(ctx)
        names = [_element_name(el.prefix, comp.name if len(parts) == 1 else f"{comp.name}_{el.tag or i}", used)
                 for i, el in enumerate(parts)]
        for name in names:
            elements[name] = comp.name
        pending.append((comp, parts, names))
    element_of = {}
    for name, comp_name in elements.items():
        element_of.setdefault(comp_name, name)
    for comp, parts, names in pending:
        tags = {el.tag: name for el, name in zip(parts, names) if el.tag}
        several = sum(el.state is not None for el in parts) > 1
        for index, (el, name) in enumerate(zip(parts, names)):
            inner = [f"~{comp.name}.{n[1:]}" if n.startswith("~") else n for n in el.nodes]
            if isinstance(el.value, Behaviour):
                text = _behaviour(el.value, subs, nodes, tags, comp)
            elif isinstance(el.value, (sp.Basic, int, float)):
                text = _number(el.value, subs, f"component {comp.name!r}")
            else:
                text = el.value
            if (tags or el.refs) and not isinstance(el.value, Behaviour):
                try:
                    text = text.format(**tags, **{f"ref{i}": element_of[r] for i, r in enumerate(el.refs)})
                except KeyError as exc:
                    raise ModelError(f"{comp.kind} {comp.name!r}: its SPICE line refers to {exc.args[0]!r}, which has no element.") from None
            line = f"{name} {' '.join(nodes[n] for n in inner)} {text}".rstrip()
            if el.state is not None:
                kind, expr = el.state
                expr = sp.sympify(expr).xreplace(subs)
                label = f"{kind}({comp.name}.{el.tag or index})" if several else f"{kind}({comp.name})"
                value = float(eq.symbolic(expr).xreplace(point))
                ics[label] = value
                line += f" ic={_fmt(value)}"
                quantities[label] = expr
                probes[label] = ("i", name) if kind == "i" else ("v", *(nodes[n] for n in inner[:2]))
            lines.append(line)
    if options:
        bad = [k for k in options if not re.fullmatch(r"[a-z][a-z0-9_]*", str(k))]
        if bad:
            raise ModelError(f"SPICE option names are lower-case words; got {', '.join(map(repr, bad))}.")
        lines.append(".options " + " ".join(f"{k}={_number(v, subs, f'SPICE option {k}')}" for k, v in options.items()))
    step = step or t_end / 1000
    max_step = max_step or step / 10
    lines.append(f".tran {_fmt(step)} {_fmt(t_end)} 0 {_fmt(max_step)} uic")
    lines.append(".end")
    return Netlist("\n".join(lines), elements, nodes, probes, quantities, ics)


def _seconds(name: str, value: Any) -> float:
    """A time of the ``.tran`` line (``t_end``, ``step``, ``max_step``): a finite positive number of seconds."""
    if not isinstance(value, numbers.Real) or isinstance(value, bool):
        hint = " (write it as a number, not text)" if isinstance(value, str) else ""
        raise ModelError(f"netlist: {name} must be a positive number of seconds, got {value!r:.60} of type "
                         f"{type(value).__name__}{hint}.")
    try:
        out = float(value)
    except OverflowError:
        out = math.inf
    if not (math.isfinite(out) and out > 0):
        raise ModelError(f"netlist: {name} must be a finite positive number of seconds, got {value!r:.40}.")
    return out


def _behaviour(law: Behaviour, subs: Mapping, nodes: Mapping[str, str], tags: Mapping[str, str], comp) -> str:
    """``V=...`` / ``I=...`` text of a behavioural law, its controls named as in the netlist."""
    names = {}
    for symbol, control in law.controls:
        kind, *args = control
        if kind == "v" and len(args) in (1, 2):
            inner = [f"~{comp.name}.{n[1:]}" if n.startswith("~") else n for n in args]
            names[symbol] = f"v({','.join(nodes[n] for n in inner)})"
        elif kind == "i" and len(args) == 1 and args[0] in tags:
            names[symbol] = f"i({tags[args[0]]})"
        else:
            raise ModelError(f"{comp.kind} {comp.name!r}: its behavioural source refers to {control!r}, which is not "
                             f"('v', node), ('v', node_a, node_b) or ('i', tag of its own voltage source).")
    expr = sp.sympify(law.expr).xreplace(subs)
    try:
        return f"{law.quantity}={_spice_printer()(names).doprint(expr)}"
    except ModelError as exc:
        raise ModelError(f"{comp.kind} {comp.name!r}: {exc}") from None


# -- running ngspice -----------------------------------------------------------------------------


@contextlib.contextmanager
def _quiet_pyspice():
    logger = logging.getLogger("PySpice")
    level = logger.level
    logger.setLevel(logging.CRITICAL)
    try:
        yield
    finally:
        logger.setLevel(level)


def _shared():
    try:
        from PySpice.Spice.NgSpice.Shared import NgSpiceShared
    except ImportError as exc:  # pragma: no cover - PySpice is a dependency
        raise NgspiceMissingError(f"PySpice is not importable ({exc}); install it with `pip install PySpice`.") from exc
    try:
        return NgSpiceShared.new_instance()
    except OSError as exc:
        raise NgspiceMissingError(
            f"ngspice's shared library cannot be loaded ({exc}). Install it from the system's package manager: "
            f"Debian/Ubuntu `apt-get install libngspice0-dev` (or run `make setup`), Fedora `dnf install libngspice-devel`, "
            f"macOS `brew install libngspice`; or point NGSPICE_LIBRARY_PATH at libngspice.so."
        ) from exc


def _errors(lines: Sequence[str]) -> list[str]:
    return [ln for ln in lines if re.match(r"\s*(error|doanalyses|run simulation|.*timestep too small)", ln, re.I)]


def run_ac(text: str, probes: Mapping[str, tuple[str, ...]]) -> SpiceRun:
    """Run a netlist's ``.ac`` analysis in ngspice; return its frequencies (as ``time``) and the probed quantities
    (complex).  Probes and errors as for :func:`run_transient`."""
    return _run(text, probes, complex, "frequency")


def run_transient(net: Netlist | str, probes: Mapping[str, tuple[str, ...]] | None = None) -> SpiceRun:
    """Run the netlist's ``.tran`` in ngspice; return its time points and the probed quantities.

    ``probes`` defaults to the netlist's own (its state quantities); a probe
    is ``("v", node)``, ``("v", node_a, node_b)`` or ``("i", element)``.
    Raises :class:`NgspiceError` with ngspice's messages when it rejects the
    netlist or fails to converge, and :class:`NgspiceMissingError` when the
    library is missing.
    """
    text = net.text if isinstance(net, Netlist) else net
    probes = dict(net.probes if probes is None and isinstance(net, Netlist) else probes or {})
    return _run(text, probes, float, "time")


def _run(text: str, probes: Mapping[str, tuple[str, ...]], dtype, axis: str) -> SpiceRun:
    """Load ``text`` into ngspice, run its analysis, read the ``axis`` vector and the probes as ``dtype``."""
    with _LOCK, _quiet_pyspice():
        ng = _shared()
        ng.clear_output()
        try:
            loading = _time.perf_counter()
            ng.load_circuit(text)
            load = _time.perf_counter() - loading
            bad = _errors(ng._stderr) + _errors(ng._stdout)
            if bad:
                raise NgspiceError("ngspice rejected the netlist: " + " | ".join(bad))
            start = _time.perf_counter()
            try:
                ng.run()
            except Exception as exc:
                msgs = _errors(ng._stderr) + _errors(ng._stdout)
                notes = all(line.strip().lower().startswith("note:") for line in ng._stderr)
                if msgs or not notes:  # PySpice fails a run on any line on stderr, ngspice's notes included
                    raise NgspiceError("ngspice failed: " + (" | ".join(msgs) or str(exc))) from None
            wall = _time.perf_counter() - start
            msgs = _errors(ng._stderr)
            if msgs:
                raise NgspiceError("ngspice failed: " + " | ".join(msgs))
            reading = _time.perf_counter()
            vectors = {name.lower(): np.asarray(vec._data, dtype=dtype) for name, vec in ng.plot(None, ng.last_plot).items()}
            took_to_read = _time.perf_counter() - reading
        except Exception as exc:
            if isinstance(exc, LagrangianError):
                raise
            raise NgspiceError(f"ngspice failed: {exc.__class__.__name__}: {exc}") from exc
        finally:
            with contextlib.suppress(Exception):
                ng.remove_circuit()
            with contextlib.suppress(Exception):
                ng.destroy()
    time = np.real(vectors.pop(axis))

    def read(probe: tuple[str, ...]) -> np.ndarray:
        kind, *names = probe
        if kind == "i":
            return vectors[f"{names[0]}#branch"]
        # ngspice names a node's vector after the node, and a numbered node's "v(<number>)"
        v = [np.zeros_like(time) if n == "0" else vectors[n] if n in vectors else vectors[f"v({n})"] for n in names]
        return v[0] - v[1] if len(v) == 2 else v[0]

    try:
        out = {label: read(probe) for label, probe in probes.items()}
    except KeyError as exc:
        raise NgspiceError(f"ngspice's output has no vector {exc.args[0]!r} (it has {', '.join(sorted(vectors))}).") from None
    return SpiceRun(time, out, wall, load=load, read=took_to_read)
