"""The text of a SPICE netlist read into a deck: lines, numbers, elements, sources and dot commands.

:func:`_parse` splits the text into logical lines (comments removed,
continuations joined) and tokens, and reads each line into an element
(``R``, ``L``, ``C``, ``K``, ``V``, ``I`` with their values, ``ic=`` and source
specifications) or a dot command (``.tran`` into a :class:`Transient`, ``.ac``
into an :class:`ACSweep`, ``.ic``,
``.options``, ``.title``, ``.end``); :func:`parse_number` reads SPICE's numbers
with their scale suffixes.  Whatever is not supported is refused here with a
:class:`~lagrangian.errors.ModelError` naming the line, listing :data:`SUPPORTED`.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterator
from dataclasses import dataclass, field
from decimal import Decimal, InvalidOperation
from typing import Any

import numpy as np

from ..analysis.frequency import sweep, sweep_size
from ..base.limits import refuse
from ..errors import ModelError

#: What the reader understands, quoted in its error messages.
SUPPORTED = (
    "R, L, C (linear; ic= on L and C), K (coupled inductors), independent V and I sources "
    "(a DC value, DC x, SIN(...), PULSE(...), AC mag [phase]); dot commands .tran, .ac dec|oct|lin, .ic, .options, "
    ".title, .end (.print, .plot, .save and .probe are ignored)"
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
_ANALYSES = {".dc", ".op", ".noise", ".tf", ".sens", ".pz", ".disto", ".four", ".sp", ".pss", ".meas", ".measure"}
_WAVEFORMS = {"sin": (2, 6), "pulse": (2, 8)}
_OTHER_WAVEFORMS = {"exp", "pwl", "sffm", "am", "trnoise", "trrandom", "distof1", "distof2", "port"}

_NUMBER = re.compile(r"([+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)([A-Za-z]*)\Z")
_SCALES = (("meg", "1e6"), ("mil", "25.4e-6"), ("t", "1e12"), ("g", "1e9"), ("k", "1e3"),
           ("m", "1e-3"), ("u", "1e-6"), ("n", "1e-9"), ("p", "1e-12"), ("f", "1e-15"))  # fmt: skip
_TOKEN = re.compile(r"[^\s(),=]+|[()=]")


class _BeyondFloat(ValueError):
    """A SPICE number that a float cannot hold."""


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
    scale = next((factor for suffix, factor in _SCALES if letters.startswith(suffix)), "1") if letters else "1"
    try:
        value = float(mantissa) if scale == "1" else float(Decimal(mantissa) * Decimal(scale))
    except InvalidOperation:  # pragma: no cover - the pattern admits only decimals
        raise ValueError(f"{text!r} is not a SPICE number") from None
    if not math.isfinite(value):  # 1e999: Decimal holds it, a float does not
        raise _BeyondFloat(f"{text!r} is beyond a float's range")
    return value


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
        steps = (self.stop - self.start) / self.step * (1 + 1e-12)
        refuse(f"the output grid of '.tran {self.step:g} {self.stop:g}' (give simulate() points= for fewer times)",
               steps + 1, "grid_points")
        n = int(np.floor(steps))
        grid = self.start + self.step * np.arange(n + 1)
        if abs(self.stop - grid[-1]) <= 1e-9 * self.step:
            grid[-1] = self.stop  # 1e-5 · 3000 is 0.030000000000000002: the last point is the stop, not past it
        elif self.stop - grid[-1] > 0:
            grid = np.append(grid, self.stop)
        return np.minimum(grid, self.stop)


@dataclass(frozen=True)
class ACSweep:
    """The ``.ac`` line: ``kind`` (``"dec"``, ``"oct"`` or ``"lin"``), ``points`` (per decade, per octave, or in
    all), ``start`` and ``stop`` frequencies in Hz."""

    kind: str
    points: int
    start: float
    stop: float

    @property
    def frequencies(self) -> np.ndarray:
        """ngspice's frequencies for this sweep (:func:`lagrangian.frequency.sweep`).

        >>> ACSweep("dec", 2, 1.0, 100.0).frequencies.round(3).tolist()
        [1.0, 3.162, 10.0, 31.623, 100.0]
        >>> ACSweep("lin", 3, 10.0, 30.0).frequencies.tolist()
        [10.0, 20.0, 30.0]
        """
        return sweep(self.kind, self.points, self.start, self.stop)


@dataclass
class _Element:
    letter: str
    name: str
    line: int
    nodes: tuple[str, ...] = ()
    value: Any = None  # a number, or (waveform, [args]) for sources
    ic: float | None = None
    refs: tuple[str, ...] = ()  # inductor names of a K element
    ac: tuple[float, float] | None = None  # a source's AC magnitude and phase (degrees)

    def where(self) -> str:
        return f"netlist line {self.line} ({self.name})"


@dataclass
class _Parsed:
    title: str = ""
    elements: list[_Element] = field(default_factory=list)
    tran: Transient | None = None
    ac: ACSweep | None = None
    node_ic: dict[str, float] = field(default_factory=dict)
    options: dict[str, Any] = field(default_factory=dict)

    @property
    def element_ic(self) -> bool:
        return any(e.ic is not None for e in self.elements)


#: What ``str.splitlines`` splits at: the lines are cut one at a time (:func:`_physical_lines`).
_LINE_BREAK = re.compile(r"\r\n|[\n\r\x0b\x0c\x1c\x1d\x1e\x85\u2028\u2029]")


def _physical_lines(text: str) -> Iterator[str]:
    """The lines of ``text``, as ``text.splitlines()`` gives them, one at a time: a deck of millions of lines is
    refused at its element bound without first becoming a list of millions of strings."""
    start = 0
    for match in _LINE_BREAK.finditer(text):
        yield text[start : match.start()]
        start = match.end()
    if start < len(text):
        yield text[start:]


def _logical_lines(text: str) -> tuple[str, Iterator[tuple[int, str]]]:
    """The title and the (line number, text) of each logical line, read as they are asked for: comments removed,
    continuations joined."""
    physical = enumerate(_physical_lines(text), start=1)
    title = next((raw.strip() for _, raw in physical if raw.strip()), "")
    return title, _joined(physical)


def _joined(physical: Iterator[tuple[int, str]]) -> Iterator[tuple[int, str]]:
    pending: tuple[int, list[str]] | None = None  # a line and its continuations, joined once (not re-copied per '+')
    for number, raw in physical:
        line = raw.strip()
        if not line or line.startswith("*"):
            continue
        line = re.split(r";|\s\$\s|\s\$$", line, maxsplit=1)[0].strip()
        if line.startswith("+"):
            if pending is None:
                raise ModelError(f"netlist line {number}: a continuation line ('+') with no line before it to continue.")
            pending[1].append(line[1:].strip())
            continue
        if line:
            if pending is not None:
                yield pending[0], " ".join(pending[1])
            pending = (number, [line])
    if pending is not None:
        yield pending[0], " ".join(pending[1])


def _parse(text: str) -> _Parsed:
    """The deck of ``text``; a :class:`ModelError` naming the line for what is wrong or unsupported, for more elements
    than ``lagrangian.limits.netlist_elements`` (at the first element beyond it) and for two ``K`` lines coupling
    the same pair of inductors."""
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
        refuse(f"netlist line {number} ({tokens[0]}): the netlist, at this element,", len(deck.elements) + 1,
               "netlist_elements")
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
    couplings: dict[frozenset[str], _Element] = {}  # by the unordered pair of inductors: duplicates found in one pass
    for element in deck.elements:
        if element.letter != "k":
            continue
        resolved = []
        for ref in element.refs:
            if ref.lower() not in inductors:
                raise ModelError(
                    f"{element.where()}: couples {ref!r}, which is not an inductor of this netlist "
                    f"(inductors: {_some(list(inductors.values()))})."
                )
            resolved.append(inductors[ref.lower()])
        element.refs = tuple(resolved)
        pair = frozenset(resolved)
        first = couplings.get(pair)
        if first is not None and len(pair) == 2:  # an inductor coupled with itself: the coupling's own error says so
            raise ModelError(
                f"{element.where()}: couplings {first.name!r} and {element.name!r} both couple "
                f"{' and '.join(sorted(pair))} ({first.name} is on line {first.line}): give one coupling per pair of "
                f"inductors; remove one of the K lines."
            )
        couplings.setdefault(pair, element)
    return deck


def _some(names: list[str], shown: int = 10) -> str:
    """``names`` joined, the first ``shown`` of a long list and how many there are."""
    if not names:
        return "none"
    if len(names) <= shown:
        return ", ".join(names)
    return f"{', '.join(names[:shown])}, ... ({len(names)} in all)"


def _number(token: str, where: str, what: str) -> float:
    try:
        return parse_number(token)
    except _BeyondFloat:
        raise ModelError(f"{where}: expected a number for {what}, got {token!r}, which is beyond a float's range.") from None
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
    element.value, element.ac = _source(rest, where)
    return element


def _source(tokens: list[str], where: str) -> tuple[tuple[str, list[float]], tuple[float, float] | None]:
    """``("dc", [value])`` or ``(waveform, [arguments])`` from the tokens after a source's nodes, and the AC
    magnitude and phase (degrees) when given.  An AC-only source is 0 in a transient, as in SPICE."""
    dc: float | None = None
    wave: tuple[str, list[float]] | None = None
    ac: tuple[float, float] | None = None
    i = 0
    while i < len(tokens):
        word = tokens[i].lower()
        if word == "dc":
            if i + 1 >= len(tokens):
                raise ModelError(f"{where}: 'DC' needs a value.")
            dc = _number(tokens[i + 1], where, "the DC value")
            i += 2
        elif word == "ac":
            i += 1
            values = []
            for _ in range(2):  # magnitude (default 1) and phase in degrees (default 0)
                if i < len(tokens) and _NUMBER.match(tokens[i]):
                    values.append(_number(tokens[i], where, "the AC magnitude or phase"))
                    i += 1
            ac = (values[0] if values else 1.0, values[1] if len(values) > 1 else 0.0)
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
        return wave, ac
    return ("dc", [dc or 0.0]), ac


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
    elif head == ".ac":
        if len(tokens) != 4 or tokens[0].lower() not in ("dec", "oct", "lin"):
            raise ModelError(f"{where}: expected '.ac dec|oct|lin points fstart fstop', got {' '.join(tokens)!r}. "
                             f"Supported: {SUPPORTED}.")
        count = _number(tokens[1], where, "the number of points")
        start, stop = (_number(tok, where, "a frequency") for tok in tokens[2:])
        if count != int(count) or count < 1 or not 0 < start <= stop:
            raise ModelError(f"{where}: need a whole number of points ≥ 1 and 0 < fstart ≤ fstop, got "
                             f"{' '.join(tokens)!r}. Supported: {SUPPORTED}.")
        if tokens[0].lower() != "lin" and start == stop:
            raise ModelError(f"{where}: a dec or oct sweep needs fstart < fstop, got {' '.join(tokens)!r}. "
                             f"Supported: {SUPPORTED}.")
        # the grid's size is checked here, before anything reads the deck further (6e8 frequencies: 24 GB)
        sweep_size(tokens[0].lower(), int(count), start, stop, f"{where}: '.ac {' '.join(tokens)}'")
        deck.ac = ACSweep(tokens[0].lower(), int(count), start, stop)
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
        raise ModelError(f"{where}: only transient (.tran) and small-signal (.ac) analyses are supported. "
                         f"Supported: {SUPPORTED}.")
    else:
        raise ModelError(f"{where}: the dot command {head!r} is not supported. Supported: {SUPPORTED}.")
