"""Reading SPICE netlists into models.

:func:`read_netlist` turns the text of a SPICE deck of linear circuits into a
:class:`~lagrangian.Model` and returns it in an :class:`ImportedNetlist`, together
with the initial state that the deck's ``ic=`` values and ``.ic`` line give
and its ``.tran`` settings.

What is read
------------

- The first non-blank line is the title (as in SPICE, it is never parsed).
  ``*`` starts a comment line; ``;`` (and `` $ ``) start an end-of-line
  comment; a line starting with ``+`` continues the previous one.  Element
  letters, keywords, dot commands, unit suffixes and node names are
  case-insensitive (node names are lower-cased, as ngspice does); element
  names are kept as written (``R1``, ``Lload``) and become component names.
- ``R``, ``L``, ``C`` (linear; ``ic=`` on ``L`` and ``C``), ``K`` (coupled
  inductors, ``0 < k ≤ 1``: kind ``coupling``, in either formulation; see
  ``lagrangian.plugins.coupled_inductors``), independent ``V`` and ``I`` sources with a
  DC value (``5``, ``DC 5``), ``SIN(vo va freq td theta phase)`` or
  ``PULSE(v1 v2 td tr tf pw per np)``.  An ``AC`` specification next to a
  transient one is ignored (it belongs to AC analysis); when a source has
  both a DC value and a waveform, the waveform is used, as SPICE does in a
  transient analysis.
- ``.tran tstep tstop [tstart [tmax]] [uic]``, ``.ic v(node)=value ...``,
  ``.options ...`` (stored, not used), ``.title``, ``.end`` (nothing after it
  is read) and the output directives ``.print``, ``.plot``, ``.save``,
  ``.probe`` (ignored).
- Numbers take SPICE's scale suffixes ``f p n u m k meg g t`` and ``mil``
  (25.4 µm); letters after a number or a suffix are units and are ignored,
  so ``10uF`` is 10 µF, ``1F`` is 1 fF and ``1M`` is 1 mΩ, as in SPICE.
- Node ``0`` (and ``gnd``) is the ground.

Anything else (semiconductors, subcircuits, controlled and behavioural
sources, switches, transmission lines, PWL/EXP/SFFM/AM waveforms, AC-only
sources, ``.param`` expressions, analyses other than ``.tran``) is refused
with a :class:`~lagrangian.errors.ModelError` naming the line and the
element, and listing what is supported.

Conventions (those of ``lagrangian.plugins.circuits``, which follow SPICE):
``V n+ n- E`` makes ``v(n+) − v(n−) = E``; ``I n+ n- I`` drives ``I`` from
``n+`` through the source to ``n−``; an element's current flows from its
first node through it to its second, and ``K`` dots the first node of each
inductor.

Waveforms (ngspice 39 semantics, checked against it in the tests)
-----------------------------------------------------------------

- ``SIN``: ``vo + va·sin(φ)`` for ``t ≤ td``, then
  ``vo + va·e^(−θ(t−td))·sin(2π f (t−td) + φ)`` with ``φ = phase·π/180``;
  ``freq`` defaults to ``1/tstop``.
- ``PULSE``: ``v1`` until ``td``, then a trapezoid repeating with period
  ``per``: a linear rise over ``tr``, ``v2`` for ``pw``, a linear fall over
  ``tf``, ``v1`` for the rest of the period; after ``np`` periods (if given
  and positive) ``v1`` again.  A zero or missing ``tr``/``tf`` is ``tstep``
  and a zero or missing ``pw``/``per`` is ``tstop``.  It is a SymPy
  ``Piecewise`` of ``Mod(t − td, per)``: exact for every ``t``, evaluated
  quickly, but not integrable in closed form, so a PULSE voltage source in
  the flux formulation (or current source in the charge formulation), where
  the source fixes a coordinate to the integral of its value, is refused.

Initial state
-------------

The state at ``t = 0`` is SPICE's ``uic`` state: each capacitor starts at
its ``ic=`` voltage, or else at the difference of its nodes' ``.ic``
voltages (nodes not listed are at 0 V); each inductor starts at its ``ic=``
current, or 0.  :attr:`ImportedNetlist.initial` and
:attr:`ImportedNetlist.velocity` give every coordinate and every inertial
velocity a value, found by solving the linear relations between them and
the capacitor charges and inductor currents (charge formulation) or the
inductor flux linkages and capacitor voltages (flux formulation).
Directions those relations leave free change no capacitor or inductor
state; they are set to zero (the least-norm solution).  States a
formulation cannot take raise a ModelError naming the elements: in loop
charges, capacitor charges that would not balance at a node where only
capacitors meet, and inductor currents that break Kirchhoff's current law;
in node fluxes, inductor flux linkages that would not add up around a loop
of inductors, and capacitor voltages that break Kirchhoff's voltage law.
A ``.tran`` without ``uic`` makes SPICE start from the DC operating point
instead; this reader still uses the ``uic`` state, and warns
(:class:`NetlistWarning`) when the two could differ.

>>> net = read_netlist('''series RLC, capacitor charged to 1 V
... V1 in 0 SIN(0 1 1k)
... R1 in a 10
... L1 a b 1m ic=0
... C1 b 0 1u ic=1
... .tran 10u 2m uic
... .end''')
>>> net.model.coordinate_names
['q_L1']
>>> net.initial, net.velocity    # the loop charge is the capacitor's, C v = 1 µC; its rate is the inductor current
({'q_L1': 1e-06}, {'q_L1': 0.0})
>>> net.tran
Transient(step=1e-05, stop=0.002, start=0.0, max_step=None, uic=True)
"""

from __future__ import annotations

import re
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field
from decimal import Decimal, InvalidOperation
from pathlib import Path
from typing import Any

import numpy as np
import sympy as sp

from ..base.component import t
from ..base.domain import Context
from ..errors import LagrangianError, ModelError, ParameterError
from ..model import Model
from ..plugin.registry import Registry
from ..numerics.simulation import Result

__all__ = ["ImportedNetlist", "Transient", "NetlistWarning", "read_netlist", "read_netlist_file", "parse_number", "SUPPORTED"]

#: What the reader understands, quoted in its error messages.
SUPPORTED = (
    "R, L, C (linear; ic= on L and C), K (coupled inductors), independent V and I sources "
    "(a DC value, DC x, SIN(...), PULSE(...)); dot commands .tran, .ic, .options, .title, .end "
    "(.print, .plot, .save and .probe are ignored)"
)

_UNSUPPORTED_ELEMENTS = {
    "a": "an XSPICE code model",
    "b": "a behavioural source",
    "d": "a diode",
    "e": "a voltage-controlled voltage source",
    "f": "a current-controlled current source",
    "g": "a voltage-controlled current source",
    "h": "a current-controlled voltage source",
    "j": "a JFET",
    "m": "a MOSFET",
    "n": "a numerical device",
    "o": "a lossy transmission line",
    "p": "a coupled transmission line",
    "q": "a bipolar transistor",
    "s": "a voltage-controlled switch",
    "t": "a transmission line",
    "u": "an RC line",
    "w": "a current-controlled switch",
    "x": "a subcircuit instance",
    "y": "a transmission line",
    "z": "a MESFET",
}
_IGNORED_COMMANDS = {".print", ".plot", ".save", ".probe"}
_ANALYSES = {".ac", ".dc", ".op", ".noise", ".tf", ".sens", ".pz", ".disto", ".four", ".sp", ".pss", ".meas", ".measure"}
_WAVEFORMS = {"sin": (2, 6), "pulse": (2, 8)}
_OTHER_WAVEFORMS = {"exp", "pwl", "sffm", "am", "trnoise", "trrandom", "distof1", "distof2", "port"}

_NUMBER = re.compile(r"([+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)([A-Za-z]*)\Z")
_SCALES = (("meg", "1e6"), ("mil", "25.4e-6"), ("t", "1e12"), ("g", "1e9"), ("k", "1e3"),
           ("m", "1e-3"), ("u", "1e-6"), ("n", "1e-9"), ("p", "1e-12"), ("f", "1e-15"))  # fmt: skip
_TOKEN = re.compile(r"[^\s(),=]+|[()=]")


class NetlistWarning(UserWarning):
    """The netlist asks for something this reader does differently from SPICE (the reason is in the message)."""


def parse_number(text: str) -> float:
    """A SPICE number: a decimal with an optional scale suffix, then ignored unit letters.

    >>> parse_number("4.7k"), parse_number("10uF"), parse_number("2MEG"), parse_number("1mil")
    (4700.0, 1e-05, 2000000.0, 2.54e-05)
    >>> parse_number("1M")    # milli: SPICE is case-insensitive
    0.001
    """
    match = _NUMBER.match(text.strip())
    if not match:
        raise ValueError(f"{text!r} is not a SPICE number")
    mantissa, letters = match.groups()
    letters = letters.lower()
    scale = next((factor for suffix, factor in _SCALES if letters.startswith(suffix)), "1")
    try:
        return float(Decimal(mantissa) * Decimal(scale))
    except InvalidOperation:  # pragma: no cover - the pattern admits only decimals
        raise ValueError(f"{text!r} is not a SPICE number") from None


@dataclass(frozen=True)
class Transient:
    """The ``.tran`` line: output step, stop time, output start, step cap, and whether ``uic`` was given."""

    step: float
    stop: float
    start: float = 0.0
    max_step: float | None = None
    uic: bool = False

    @property
    def times(self) -> np.ndarray:
        """SPICE's output grid: ``start, start + step, ...`` up to ``stop`` (included).

        >>> Transient(0.25, 1.0).times
        array([0.  , 0.25, 0.5 , 0.75, 1.  ])
        """
        n = int(np.floor((self.stop - self.start) / self.step * (1 + 1e-12)))
        grid = self.start + self.step * np.arange(n + 1)
        if abs(self.stop - grid[-1]) <= 1e-9 * self.step:
            grid[-1] = self.stop  # 1e-5 · 3000 is 0.030000000000000002: the last point is the stop, not past it
        elif self.stop - grid[-1] > 0:
            grid = np.append(grid, self.stop)
        return np.minimum(grid, self.stop)


@dataclass
class ImportedNetlist:
    """A netlist read into a model, with its initial state and analysis settings.

    ``model``: the :class:`~lagrangian.Model`; ``initial`` and ``velocity``:
    coordinate values and (inertial) velocities at ``t = 0`` to pass to
    ``model.simulate`` (see the module docstring); ``ic``: the initial
    voltage of every capacitor and current of every inductor, by element
    name; ``tran``: the ``.tran`` settings or ``None``; ``title``; ``options``
    from ``.options`` lines; ``lines``: the line number of each element.
    """

    model: Model
    initial: dict[str, float]
    velocity: dict[str, float]
    ic: dict[str, float] = field(default_factory=dict)
    tran: Transient | None = None
    title: str = ""
    options: dict[str, Any] = field(default_factory=dict)
    lines: dict[str, int] = field(default_factory=dict)

    def simulate(self, t_end: float | tuple[float, float] | None = None, **kwargs: Any) -> Result:
        """``model.simulate`` from the netlist's initial state; by default over the ``.tran`` span, on its output grid.

        ``initial`` and ``velocity`` given here override the netlist's values
        coordinate by coordinate; every other keyword goes to
        :meth:`lagrangian.Model.simulate`.
        """
        if t_end is None:
            if self.tran is None:
                raise ModelError(f"netlist {self.title!r} has no .tran line: give simulate() the time span t_end.")
            t_end = self.tran.stop
            if "t_eval" not in kwargs and "points" not in kwargs:
                kwargs["t_eval"] = self.tran.times
        initial = {**self.initial, **(kwargs.pop("initial", None) or {})}
        velocity = {**self.velocity, **(kwargs.pop("velocity", None) or {})}
        return self.model.simulate(t_end, initial=initial, velocity=velocity, **kwargs)

    def capacitor_voltage(self, result: Result, name: str) -> np.ndarray:
        """The voltage ``v(n+) − v(n−)`` of capacitor ``name`` over a :class:`~lagrangian.Result` of this model."""
        comp = self._element(name, "capacitor")
        branch = self._branch(name)
        expr = branch / comp.C if self._formulation == "charge" else branch.diff(t)
        return result.quantity(expr)

    def inductor_current(self, result: Result, name: str) -> np.ndarray:
        """The current of inductor ``name`` (from ``n+`` through it to ``n−``) over a :class:`~lagrangian.Result`."""
        comp = self._element(name, "inductor")
        if self._formulation == "charge":
            expr = self._branch(name).diff(t)
        else:  # λ/L, plus what couplings add (the inverse inductance matrix of coupled coils)
            asm = self.model.assembly
            components = list(self.model.components.values())
            ctx = Context(asm.views["electrical"], asm.views, self.model.options, components)
            expr = self._branch(name) / comp.L
            for other in components:
                correction = getattr(other, "current_correction", None)
                if correction is not None:
                    expr += correction(ctx, comp)
        return result.quantity(expr)

    @property
    def _formulation(self) -> str:
        return self.model.assembly.views["electrical"].formulation

    def _branch(self, name: str) -> sp.Expr:
        return self.model.assembly.views["electrical"].branch[name]

    def _element(self, name: str, kind: str):
        comp = self.model.component(name)
        if comp.kind != kind:
            raise ModelError(f"{name!r} is a {comp.kind}, not a {kind}.")
        return comp


# --- reading ---------------------------------------------------------------------------


def read_netlist_file(path: str | Path, **kwargs: Any) -> ImportedNetlist:
    """:func:`read_netlist` of the text of the file at ``path`` (keywords as for :func:`read_netlist`)."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise ModelError(f"cannot read the netlist file {str(path)!r}: {exc.strerror or exc}.") from None
    kwargs.setdefault("name", path.stem)
    return read_netlist(text, **kwargs)


def read_netlist(
    text: str, *, name: str | None = None, formulation: str = "charge", registry: Registry | None = None
) -> ImportedNetlist:
    """Read the SPICE netlist ``text`` into a :class:`ImportedNetlist` (see the module docstring for what is read).

    ``name`` names the model (the title by default); ``formulation`` is the
    circuit formulation (``"charge"`` or ``"flux"``); ``registry`` selects
    the plugins.  Errors in the text raise :class:`~lagrangian.errors.ModelError`
    naming the line.
    """
    if not isinstance(text, str):
        raise ModelError(f"read_netlist expects the netlist text as a string, got {type(text).__name__}.")
    deck = _parse(text)
    model = Model(name or deck.title or "netlist", registry=registry, formulation=formulation)
    for element in deck.elements:
        _add(model, deck, element, formulation)
    ic = _initial_values(deck)
    if deck.tran is not None and not deck.tran.uic and (deck.node_ic or deck.element_ic or _sources_start_nonzero(model)):
        warnings.warn(
            f"netlist {deck.title!r}: .tran has no 'uic', so SPICE would start from the DC operating point; this "
            f"reader starts from the uic state (ic= values, .ic node voltages, zero otherwise). Add 'uic' to the "
            f".tran line to make the netlist say what is simulated.",
            NetlistWarning,
            stacklevel=2,
        )
    initial, velocity = _initial_state(model, ic)
    return ImportedNetlist(
        model=model,
        initial=initial,
        velocity=velocity,
        ic=ic,
        tran=deck.tran,
        title=deck.title,
        options=deck.options,
        lines={e.name: e.line for e in deck.elements},
    )


@dataclass
class _Element:
    letter: str
    name: str
    line: int
    nodes: tuple[str, ...] = ()
    value: Any = None  # a number, or (waveform, [args]) for sources
    ic: float | None = None
    refs: tuple[str, ...] = ()  # inductor names of a K element

    def where(self) -> str:
        return f"netlist line {self.line} ({self.name})"


@dataclass
class _Parsed:
    title: str = ""
    elements: list[_Element] = field(default_factory=list)
    tran: Transient | None = None
    node_ic: dict[str, float] = field(default_factory=dict)
    options: dict[str, Any] = field(default_factory=dict)

    @property
    def element_ic(self) -> bool:
        return any(e.ic is not None for e in self.elements)


def _logical_lines(text: str) -> tuple[str, list[tuple[int, str]]]:
    """The title and the (line number, text) of each logical line: comments removed, continuations joined."""
    physical = text.splitlines()
    first = next((i for i, line in enumerate(physical) if line.strip()), len(physical))
    title = physical[first].strip() if first < len(physical) else ""
    lines: list[list] = []
    for number, raw in enumerate(physical[first + 1 :], start=first + 2):
        line = raw.strip()
        if not line or line.startswith("*"):
            continue
        line = re.split(r";|\s\$\s|\s\$$", line, maxsplit=1)[0].strip()
        if line.startswith("+"):
            if not lines:
                raise ModelError(f"netlist line {number}: a continuation line ('+') with no line before it to continue.")
            lines[-1][1] += " " + line[1:].strip()
            continue
        if line:
            lines.append([number, line])
    return title, [(n, s) for n, s in lines]


def _parse(text: str) -> _Parsed:
    title, lines = _logical_lines(text)
    deck = _Parsed(title=title)
    seen: dict[str, _Element] = {}
    for number, line in lines:
        tokens = _TOKEN.findall(line)
        if not tokens:  # only separators (commas)
            continue
        head = tokens[0].lower()
        if head.startswith("."):
            if head == ".end":
                break
            _directive(deck, number, head, tokens[1:])
            continue
        element = _element(number, tokens)
        other = seen.get(element.name.lower())
        if other is not None:
            raise ModelError(
                f"netlist line {number}: element {element.name!r} has the same name as {other.name!r} on line "
                f"{other.line} (SPICE names are case-insensitive): rename one."
            )
        seen[element.name.lower()] = element
        deck.elements.append(element)
    inductors = {e.name.lower(): e.name for e in deck.elements if e.letter == "l"}
    for element in deck.elements:
        if element.letter != "k":
            continue
        resolved = []
        for ref in element.refs:
            if ref.lower() not in inductors:
                raise ModelError(
                    f"{element.where()}: couples {ref!r}, which is not an inductor of this netlist "
                    f"(inductors: {', '.join(inductors.values()) or 'none'})."
                )
            resolved.append(inductors[ref.lower()])
        element.refs = tuple(resolved)
    return deck


def _number(token: str, where: str, what: str) -> float:
    try:
        return parse_number(token)
    except ValueError:
        raise ModelError(f"{where}: expected a number for {what}, got {token!r}.") from None


def _node(token: str, where: str) -> str:
    if token in "()=" or token.startswith("{"):
        raise ModelError(f"{where}: expected a node name, got {token!r}.")
    node = token.lower()
    if node == "ground":
        raise ModelError(
            f"{where}: 'ground' is an ordinary node name in SPICE but the reference node in lagrangian; "
            f"rename the node (SPICE's reference is 0)."
        )
    return node


def _element(number: int, tokens: list[str]) -> _Element:
    name = tokens[0]
    letter = name[0].lower()
    where = f"netlist line {number} ({name})"
    if letter in _UNSUPPORTED_ELEMENTS:
        raise ModelError(
            f"{where}: {name!r} is {_UNSUPPORTED_ELEMENTS[letter]}, which the netlist reader does not support. "
            f"Supported: {SUPPORTED}."
        )
    if letter not in "rlckvi":
        raise ModelError(f"{where}: {name!r} is not a SPICE element the reader knows. Supported: {SUPPORTED}.")
    if any(tok.startswith(("{", "'")) for tok in tokens):
        raise ModelError(f"{where}: parameter expressions ({{...}}, '...') are not supported; write numbers. Supported: {SUPPORTED}.")
    element = _Element(letter, name, number)
    if letter == "k":
        if len(tokens) != 4:
            raise ModelError(f"{where}: expected 'K<name> <inductor1> <inductor2> <k>', got {' '.join(tokens)!r}.")
        element.refs = (tokens[1], tokens[2])
        element.value = _number(tokens[3], where, "the coupling coefficient")
        return element
    if len(tokens) < 3 or any(tok in "()=" for tok in tokens[1:3]):
        raise ModelError(f"{where}: expected '{name} <node+> <node-> ...', got {' '.join(tokens)!r}.")
    element.nodes = (_node(tokens[1], where), _node(tokens[2], where))
    rest = tokens[3:]
    if letter in "rlc":
        quantity = {"r": "resistance", "l": "inductance", "c": "capacitance"}[letter]
        if not rest:
            raise ModelError(f"{where}: expected a {quantity} after the nodes.")
        element.value = _number(rest[0], where, f"the {quantity}")
        extra = rest[1:]
        if letter in "lc" and len(extra) == 3 and extra[0].lower() == "ic" and extra[1] == "=":
            element.ic = _number(extra[2], where, "ic")
        elif extra:
            allowed = " (only ic=... is supported)" if letter in "lc" else ""
            raise ModelError(f"{where}: unsupported {quantity} parameters {' '.join(extra)!r}{allowed}. Supported: {SUPPORTED}.")
        return element
    element.value = _source(rest, where)
    return element


def _source(tokens: list[str], where: str) -> tuple[str, list[float]]:
    """``("dc", [value])`` or ``(waveform, [arguments])`` from the tokens after a source's nodes."""
    dc: float | None = None
    wave: tuple[str, list[float]] | None = None
    ac = False
    i = 0
    while i < len(tokens):
        word = tokens[i].lower()
        if word == "dc":
            if i + 1 >= len(tokens):
                raise ModelError(f"{where}: 'DC' needs a value.")
            dc = _number(tokens[i + 1], where, "the DC value")
            i += 2
        elif word == "ac":
            ac = True
            i += 1
            for _ in range(2):  # magnitude and phase, both optional
                if i < len(tokens) and _NUMBER.match(tokens[i]):
                    i += 1
        elif word in _WAVEFORMS:
            i, args = _arguments(tokens, i + 1, where, word)
            low, high = _WAVEFORMS[word]
            if not low <= len(args) <= high:
                raise ModelError(f"{where}: {word.upper()} takes {low} to {high} values, got {len(args)}.")
            wave = (word, args)
        elif word in _OTHER_WAVEFORMS:
            raise ModelError(f"{where}: {word.upper()} sources are not supported. Supported: {SUPPORTED}.")
        elif i == 0 and _NUMBER.match(tokens[i]):
            dc = _number(tokens[i], where, "the DC value")
            i += 1
        else:
            raise ModelError(f"{where}: unexpected {tokens[i]!r} in the source specification. Supported: {SUPPORTED}.")
    if wave is not None:
        return wave
    if dc is None and ac:
        raise ModelError(
            f"{where}: an AC-only source (small-signal analysis) has no transient value; give it a DC value or a "
            f"SIN/PULSE waveform. Supported: {SUPPORTED}."
        )
    return ("dc", [dc or 0.0])


def _arguments(tokens: list[str], i: int, where: str, word: str) -> tuple[int, list[float]]:
    args: list[float] = []
    parenthesized = i < len(tokens) and tokens[i] == "("
    if parenthesized:
        i += 1
    while i < len(tokens) and tokens[i] != ")":
        if not _NUMBER.match(tokens[i]):
            if parenthesized:
                raise ModelError(f"{where}: expected a number in {word.upper()}(...), got {tokens[i]!r}.")
            break
        args.append(_number(tokens[i], where, f"a {word.upper()} value"))
        i += 1
    if parenthesized:
        if i >= len(tokens):
            raise ModelError(f"{where}: {word.upper()}( is not closed by ')'.")
        i += 1
    return i, args


def _directive(deck: _Parsed, number: int, head: str, tokens: list[str]) -> None:
    where = f"netlist line {number} ({head})"
    if head == ".tran":
        uic = bool(tokens) and tokens[-1].lower() == "uic"
        values = [_number(tok, where, ".tran values") for tok in (tokens[:-1] if uic else tokens)]
        if not 2 <= len(values) <= 4:
            raise ModelError(f"{where}: expected '.tran tstep tstop [tstart [tmax]] [uic]', got {len(values)} values.")
        step, stop, start, max_step = (*values, None, None)[:4]
        start = start or 0.0
        if not (step > 0 and stop > start >= 0) or (max_step is not None and max_step <= 0):
            raise ModelError(f"{where}: need tstep > 0, tstop > tstart ≥ 0 and tmax > 0, got {' '.join(tokens)!r}.")
        deck.tran = Transient(step, stop, start, max_step, uic)
    elif head == ".ic":
        i = 0
        while i < len(tokens):
            chunk = tokens[i : i + 6]
            if len(chunk) < 6 or chunk[0].lower() != "v" or chunk[1] != "(" or chunk[3] != ")" or chunk[4] != "=":
                raise ModelError(f"{where}: expected 'v(node)=value' entries, got {' '.join(tokens[i:])!r}.")
            node = _node(chunk[2], where)
            value = _number(chunk[5], where, f"v({node})")
            if node in ("0", "gnd"):
                if value != 0:
                    raise ModelError(f"{where}: the ground node 0 is at 0 V, not {value:g}.")
            else:
                deck.node_ic[node] = value
            i += 6
    elif head in (".options", ".option", ".opt"):
        i = 0
        while i < len(tokens):
            key = tokens[i].lower()
            if i + 2 < len(tokens) and tokens[i + 1] == "=":
                raw = tokens[i + 2]
                try:
                    deck.options[key] = parse_number(raw)
                except ValueError:
                    deck.options[key] = raw.lower()
                i += 3
            else:
                deck.options[key] = True
                i += 1
    elif head == ".title":
        deck.title = " ".join(tokens)
    elif head in _IGNORED_COMMANDS:
        pass
    elif head in _ANALYSES:
        raise ModelError(f"{where}: only transient analysis (.tran) is supported. Supported: {SUPPORTED}.")
    else:
        raise ModelError(f"{where}: the dot command {head!r} is not supported. Supported: {SUPPORTED}.")


# --- building the model ------------------------------------------------------------------

_KINDS = {
    "r": ("resistor", "R"),
    "l": ("inductor", "L"),
    "c": ("capacitor", "C"),
    "v": ("voltage_source", "E"),
    "i": ("current_source", "I"),
}


def _add(model: Model, deck: _Parsed, element: _Element, formulation: str) -> None:
    where = element.where()
    if element.letter == "k":
        kind, params, nodes = "coupling", {
            "inductor1": element.refs[0],
            "inductor2": element.refs[1],
            "k": element.value,
        }, ()
    else:
        kind, pname = _KINDS[element.letter]
        value = element.value
        if element.letter in "vi":
            wave, args = value
            if wave == "pulse" and (element.letter, formulation) in (("v", "flux"), ("i", "charge")):
                fixes = "a flux linkage" if element.letter == "v" else "a loop charge"
                raise ModelError(
                    f"{where}: in the {formulation} formulation this source fixes {fixes} to the integral of its "
                    f"PULSE waveform, which SymPy cannot integrate in closed form; use formulation="
                    f"{'charge' if formulation == 'flux' else 'flux'!r}."
                )
            value = _waveform(wave, args, deck.tran, where)
        params, nodes = {pname: value}, element.nodes
    try:
        model.add(kind, element.name, nodes, **params)
    except ParameterError as exc:
        raise ParameterError(exc.component, exc.parameter, f"{str(exc).split(': ', 1)[1]} ({where})") from None
    except LagrangianError as exc:
        raise ModelError(f"{where}: {exc}") from None


def _waveform(wave: str, args: list[float], tran: Transient | None, where: str) -> sp.Expr:
    """The SymPy expression of ``t`` for a source specification (ngspice 39 semantics)."""
    if wave == "dc":
        return sp.Float(args[0])

    def default(value: float, fallback: str) -> float:
        if value:
            return value
        if tran is None:
            raise ModelError(
                f"{where}: a {wave.upper()} value left out (or 0) defaults to the .tran {fallback}, but there is no .tran line."
            )
        return tran.step if fallback == "tstep" else tran.stop

    if wave == "sin":
        vo, va, freq, td, theta, phase = (*args, *[0.0] * (6 - len(args)))
        freq = freq or 1 / default(0.0, "tstop")
        phi = sp.Float(phase) * sp.pi / 180
        x = t - sp.Float(td)
        damping = sp.exp(-sp.Float(theta) * x) if theta else 1
        body = sp.Float(vo) + sp.Float(va) * sp.sin(2 * sp.pi * sp.Float(freq) * x + phi) * damping
        if td > 0:
            return sp.Piecewise((sp.Float(vo) + sp.Float(va) * sp.sin(phi), t <= sp.Float(td)), (body, True))
        return body
    v1, v2, td, tr, tf, pw, per, count = (*args, *[0.0] * (8 - len(args)))
    tr, tf = default(tr, "tstep"), default(tf, "tstep")
    pw, per = default(pw, "tstop"), default(per, "tstop")
    v1, v2, td, tr, tf, pw, per = map(sp.Float, (v1, v2, td, tr, tf, pw, per))
    s = sp.Mod(t - td, per)
    pieces = [(v1, t <= td)]
    if count > 0:
        pieces.append((v1, t >= td + sp.Float(count) * per))
    pieces += [
        (v1 + (v2 - v1) * s / tr, s < tr),
        (v2, s <= tr + pw),
        (v2 + (v1 - v2) * (s - tr - pw) / tf, s < tr + pw + tf),
        (v1, True),
    ]
    return sp.Piecewise(*pieces)


def _sources_start_nonzero(model: Model) -> bool:
    for comp in model.components.values():
        value = {"voltage_source": "E", "current_source": "I"}.get(comp.kind)
        if value is not None and sp.sympify(getattr(comp, value)).subs(t, 0) != 0:
            return True
    return False


# --- the initial state ---------------------------------------------------------------------


def _initial_values(deck: _Parsed) -> dict[str, float]:
    """The initial voltage of every capacitor and current of every inductor (SPICE's uic rule)."""
    out = {}
    for e in deck.elements:
        if e.letter == "c":
            a, b = (deck.node_ic.get(n, 0.0) for n in e.nodes)
            out[e.name] = e.ic if e.ic is not None else a - b
        elif e.letter == "l":
            out[e.name] = e.ic if e.ic is not None else 0.0
    return out


def _initial_state(model: Model, ic: Mapping[str, float]) -> tuple[dict[str, float], dict[str, float]]:
    """Coordinates and inertial velocities at ``t = 0`` that put every capacitor and inductor at ``ic``."""
    view = model.assembly.views["electrical"]
    eq = model.eq
    coords = model.coordinates
    q = [sp.Dummy(f"q{i}") for i in range(len(coords))]
    v = [sp.Dummy(f"v{i}") for i in range(len(coords))]
    to_symbols = {}
    for c, qi, vi in zip(coords, q, v):
        to_symbols[c.function.diff(t)] = vi
        to_symbols[c.function] = qi

    def at_zero(expr: sp.Expr) -> sp.Expr:
        return sp.sympify(expr).xreplace(to_symbols).subs(t, 0)

    components = model.components
    capacitors = [n for n in ic if components[n].kind == "capacitor"]
    inductors = [n for n in ic if components[n].kind == "inductor"]
    if view.formulation == "charge":
        positions = [(n, at_zero(view.branch[n]), float(components[n].C) * ic[n]) for n in capacitors]
        rates = [(n, at_zero(view.branch[n].diff(t)), ic[n]) for n in inductors]
    else:
        positions = []
        for n in inductors:
            flux = sum((float(m) * ic[other] for other, m in _mutuals(model, n)), float(components[n].L) * ic[n])
            positions.append((n, at_zero(view.branch[n]), flux))
        rates = [(n, at_zero(view.branch[n].diff(t)), ic[n]) for n in capacitors]
    q0 = _solve(positions, q, model, view.formulation, "position")
    v0 = _solve(rates, v, model, view.formulation, "rate")
    initial = {c.name: float(x) + 0.0 for c, x in zip(coords, q0)}
    velocity = {eq.names[i]: float(v0[i]) + 0.0 for i in eq.inertial}
    return initial, velocity


def _mutuals(model: Model, inductor: str) -> list[tuple[str, sp.Expr]]:
    """``(other inductor, M)`` for every coupling of ``inductor``."""
    out = []
    components = model.components
    for comp in components.values():
        if comp.kind == "coupling" and inductor in comp.inductor_names:
            a, b = comp.inductor_names
            other = b if a == inductor else a
            out.append((other, comp.k * sp.sqrt(components[a].L * components[b].L)))
    return out


_TROUBLE = {
    ("charge", "position"): (
        "capacitors {names} cannot start at these voltages in the charge formulation: their charges would not "
        "balance at a node where only capacitors (and current sources) meet, and charge is conserved there. "
        "Check their ic= values and the .ic line, or use formulation='flux'."
    ),
    ("charge", "rate"): (
        "inductors {names} cannot start at these currents: they break Kirchhoff's current law (inductors in series, "
        "or in series with a current source, carry one current). Check their ic= values."
    ),
    ("flux", "position"): (
        "inductors {names} cannot start at these currents in the flux formulation: their flux linkages would not "
        "add up to zero around a loop of inductors and voltage sources. Check their ic= values, or use "
        "formulation='charge'."
    ),
    ("flux", "rate"): (
        "capacitors {names} cannot start at these voltages: they break Kirchhoff's voltage law around a loop of "
        "capacitors and voltage sources (a capacitor across a source starts at the source's value). Check their "
        "ic= values and the .ic line."
    ),
}


def _solve(
    rows: list[tuple[str, sp.Expr, float]], unknowns: list[sp.Symbol], model: Model, formulation: str, level: str
) -> np.ndarray:
    """Least-norm solution of the linear conditions ``expr = value``; a ModelError naming the elements if there is none."""
    n = len(unknowns)
    if not rows or not n:
        bad = [name for name, expr, value in rows if abs(value - float(expr)) > 0] if rows else []
        if bad:
            raise ModelError(f"model {model.name!r}: " + _TROUBLE[formulation, level].format(names=", ".join(bad)))
        return np.zeros(n)
    A = np.zeros((len(rows), n))
    b = np.zeros(len(rows))
    for r, (name, expr, value) in enumerate(rows):
        expr = sp.expand(expr)
        for j, u in enumerate(unknowns):
            A[r, j] = float(expr.coeff(u))
        b[r] = value - float(expr.xreplace({u: 0 for u in unknowns}))
    x = np.linalg.lstsq(A, b, rcond=None)[0]
    residual = np.abs(A @ x - b)
    scale = np.abs(b).max() + np.abs(A).max() * np.abs(x).max()
    bad = [rows[r][0] for r in np.flatnonzero(residual > 1e-9 * scale)]
    if bad:
        raise ModelError(f"model {model.name!r}: " + _TROUBLE[formulation, level].format(names=", ".join(bad)))
    return x
