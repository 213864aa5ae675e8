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
  ``PULSE(v1 v2 td tr tf pw per np)``; when a source has both a DC value
  and a waveform, the waveform is used, as SPICE does in a transient
  analysis.
- ``AC mag [phase]`` on a source marks it as an input of the small-signal
  analysis (:meth:`ImportedNetlist.frequency_response`, ``ac_sources``); an
  AC-only source is 0 in a transient, as in SPICE.
- ``.ac dec|oct|lin points fstart fstop`` (``ac``: its frequencies),
  ``.tran tstep tstop [tstart [tmax]] [uic]``, ``.ic v(node)=value ...``,
  ``.options ...`` (stored, not used), ``.title``, ``.end`` (nothing after it
  is read) and the output directives ``.print``, ``.plot``, ``.save``,
  ``.probe`` (ignored).
- Numbers take SPICE's scale suffixes ``f p n u m k meg g t`` and ``mil``
  (25.4 µm); letters after a number or a suffix are units and are ignored,
  so ``10uF`` is 10 µF, ``1F`` is 1 fF and ``1M`` is 1 mΩ, as in SPICE.
- Node ``0`` (and ``gnd``) is the ground.

Anything else (semiconductors, subcircuits, controlled and behavioural
sources, switches, transmission lines, PWL/EXP/SFFM/AM waveforms,
``.param`` expressions, analyses other than ``.tran`` and ``.ac``) is refused
with a :class:`~lagrangian.errors.ModelError` naming the line and the
element, and listing what is supported.

Sizes are bounded by :data:`lagrangian.limits`: a file (or text) of more
than ``limits.file_bytes`` bytes is refused, a file after reading one byte
past the bound; a deck of more than ``limits.netlist_elements`` elements is
refused while it is parsed, at the first element beyond the bound; each with
a :class:`~lagrangian.errors.ModelError` naming the size, the bound and how
to raise it.  A file that is not UTF-8 text is refused naming the file and
the line, and two ``K`` lines coupling the same pair of inductors naming both.

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

With ``uic``, the state at ``t = 0`` is SPICE's ``uic`` state: each capacitor starts at
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
capacitors meet; in node fluxes, inductor flux linkages that would not add
up around a loop of inductors.  Values the circuit itself cannot hold start,
as the circuit does, where the sources put them, with a
:class:`NetlistWarning` naming the elements moved and
:attr:`ImportedNetlist.ic` the values started from: in node fluxes,
capacitor voltages that break Kirchhoff's voltage law around a loop of
capacitors and voltage sources (a capacitor across a source), the charge
moved at ``t = 0`` conserved at every node the sources do not hold (the
voltages nearest the ones asked in the norm ``Σ C ΔV²``); in loop charges,
inductor currents that break Kirchhoff's current law (an inductor in series
with a current source, or with another inductor), the flux linkage around
every loop the sources do not drive kept (the norm ``ΔIᵀ 𝐋 ΔI``).  (A loop
of capacitors and voltage sources has neither inertia nor dissipation in
loop charges, and is refused.)
A ``.tran`` without ``uic`` starts, as SPICE does, from the DC operating
point at ``t = 0``: the sources at their values there, capacitors open,
inductors shorted, nodes named on a ``.ic`` line held at their voltages;
elements' ``ic=`` values are then ignored, as SPICE ignores them, with a
:class:`NetlistWarning`.  A circuit without an operating point (a node that
only capacitors reach) is refused, naming the nodes.

The text is read into a deck by :mod:`lagrangian.circuits.deck` (lines,
numbers, elements, sources, dot commands), the model is built from the deck
here, and its initial state is found by
:mod:`lagrangian.circuits.initial_state`.

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

import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..analysis.frequency import FrequencyResponse, frequency_response
from ..base.component import GROUND, t
from ..base.domain import Context
from ..base.limits import limits, refuse
from ..base.waveforms import Pulse, Sine, Waveform
from ..errors import LagrangianError, ModelError, ParameterError, warn
from ..model import Model
from ..numerics.simulation import Result
from ..plugin.registry import Registry
from .deck import SUPPORTED, ACSweep, Transient, _Element, _Parsed, _parse, parse_number
from .initial_state import _initial_state, _initial_values, _operating_point
from ..base import deferred as _deferred

sp = _deferred.module("sympy", globals())

__all__ = ["ImportedNetlist", "Transient", "ACSweep", "NetlistWarning", "read_netlist", "read_netlist_file", "parse_number",
           "SUPPORTED"]


class NetlistWarning(UserWarning):
    """The netlist asks for something this reader does differently from SPICE (the reason is in the message)."""


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
    ac: ACSweep | None = None
    ac_sources: dict[str, tuple[float, float]] = field(default_factory=dict)

    def frequency_response(self, outputs: Sequence[str] | None = None, frequencies: Any = None,
                           **kwargs: Any) -> FrequencyResponse:
        """The small-signal response at ``frequencies`` (Hz; by default the ``.ac`` sweep's) to the deck's AC
        sources, each at its ``AC`` magnitude and phase, added as SPICE's ``.ac`` does.

        ``outputs`` are node voltages ``"v(n3)"``, element quantities
        ``"v(C1)"``, ``"i(L1)"`` or coordinates; every node voltage by
        default.  ``kwargs`` go to :func:`lagrangian.frequency.linearize`.
        """
        if not self.ac_sources:
            raise ModelError(f"netlist {self.title!r} has no AC source: give one an 'AC 1' specification.")
        if frequencies is None:
            if self.ac is None:
                raise ModelError(f"netlist {self.title!r} has no .ac line: give frequency_response() the frequencies.")
            frequencies = self.ac.frequencies
        if outputs is None:
            outputs = [f"v({node})" for node in self.model.nodes if node != GROUND]
        names = list(self.ac_sources)
        resp = frequency_response(self.model, frequencies, inputs=names, outputs=outputs, **kwargs)
        weights = np.array([mag * np.exp(1j * np.radians(phase)) for mag, phase in self.ac_sources.values()])
        combined = np.einsum("oif,i->of", resp.H, weights)[:, None, :]
        label = " + ".join(names)
        units = {**resp.units, label: "V" if all(resp.units.get(n) == "V" for n in names) else
                 "A" if all(resp.units.get(n) == "A" for n in names) else ""}
        error = None if resp.error is None else np.einsum("oif,i->of", resp.error, np.abs(weights))[:, None, :]
        return FrequencyResponse(resp.model, resp.frequencies, [label], resp.outputs, combined, resp.notes, units,
                                 error=error)

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
    """:func:`read_netlist` of the text of the file at ``path`` (keywords as for :func:`read_netlist`).

    The file is read as UTF-8 text (an initial byte-order mark is skipped), at most ``lagrangian.limits.file_bytes``
    of it: a larger file (or an endless one, ``/dev/zero``) is refused after reading one byte past the bound, and
    one that is not text (bytes that are not UTF-8, or NUL bytes) is refused naming the file and the offending
    line, both with a :class:`~lagrangian.errors.ModelError`.
    """
    path = Path(path)
    shown = str(path)
    bound, size = limits.file_bytes, 0
    try:
        with path.open("rb") as fh:
            data = fh.read(bound + 1)  # a file that grows, a device or a pipe: never more than one byte past the bound
            if len(data) > bound:
                size = os.fstat(fh.fileno()).st_size  # a regular file's size; 0 for a device or a pipe
    except OSError as exc:
        raise ModelError(f"cannot read the netlist file {shown!r}: {exc.strerror or exc}.") from None
    if len(data) > bound:
        if size > bound:
            refuse(f"netlist file {shown!r}", size, "file_bytes")
        refuse(f"netlist file {shown!r} (not a regular file; it went on past {bound} bytes)", len(data), "file_bytes")
    text = _decoded(data, shown)
    kwargs.setdefault("name", path.stem)
    return read_netlist(text, **kwargs)


def _decoded(data: bytes, shown: str) -> str:
    """The UTF-8 text of the netlist file ``shown``'s bytes ``data``; a :class:`ModelError` naming the file and the
    line for bytes that are not UTF-8 text (the error the ``scene`` command gave, now the reader's own)."""
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        skipped = len(data) - len(exc.object)  # the byte-order mark, if any: offsets are counted in the file
        line = exc.object.count(b"\n", 0, exc.start) + 1
        raise ModelError(
            f"netlist file {shown!r} is not a text file: byte {exc.object[exc.start]:#04x} at offset "
            f"{exc.start + skipped} (line {line}) is not UTF-8 ({exc.reason}); give a SPICE netlist saved as UTF-8 "
            f"(or ASCII) text."
        ) from None
    nul = text.find("\x00")
    if nul >= 0:
        raise ModelError(
            f"netlist file {shown!r} is not a text file: it holds a NUL byte (line {text.count(chr(10), 0, nul) + 1}); "
            f"give a SPICE netlist saved as UTF-8 (or ASCII) text."
        )
    return text


def _text_bytes(text: str) -> int:
    """The size of ``text`` in UTF-8 bytes, counted without encoding it whole (ASCII text: its length)."""
    if text.isascii():
        return len(text)
    step = 1 << 20
    return sum(len(text[i : i + step].encode("utf-8", "surrogatepass")) for i in range(0, len(text), step))


def read_netlist(
    text: str, *, name: str | None = None, formulation: str = "charge", registry: Registry | None = None
) -> ImportedNetlist:
    """Read the SPICE netlist ``text`` into a :class:`ImportedNetlist` (see the module docstring for what is read).

    ``name`` names the model (the title by default); ``formulation`` is the
    circuit formulation (``"charge"`` or ``"flux"``); ``registry`` selects
    the plugins.  Errors in the text raise :class:`~lagrangian.errors.ModelError`
    naming the line; so do text of more than ``lagrangian.limits.file_bytes``
    bytes (in UTF-8) and more than ``lagrangian.limits.netlist_elements``
    elements.
    """
    if not isinstance(text, str):
        raise ModelError(f"read_netlist expects the netlist text as a string, got {type(text).__name__}.")
    refuse(f"netlist text {name!r}" if name else "netlist text", _text_bytes(text), "file_bytes")
    deck = _parse(text)
    model = Model(name or deck.title or "netlist", registry=registry, formulation=formulation)
    for element in deck.elements:
        _add(model, deck, element, formulation)
    if deck.tran is not None and not deck.tran.uic:
        if deck.element_ic:
            warn(
                f"netlist {deck.title!r}: .tran has no 'uic', so the elements' ic= values are ignored, as SPICE "
                f"ignores them, and the run starts from the DC operating point. Add 'uic' to the .tran line to start "
                f"from them.",
                NetlistWarning,
            )
        ic = _operating_point(model, deck)
    else:
        ic = _initial_values(deck)
    initial, velocity, moved = _initial_state(model, ic)
    if moved:
        kinds = {model.components[n].kind for n in moved}
        unit = {n: "V" if model.components[n].kind == "capacitor" else "A" for n in moved}
        why = ("a loop of capacitors and voltage sources fixes their voltages, so the sources move charge through them "
               "at t = 0 (conserved at every node they do not hold)" if kinds == {"capacitor"} else
               "current sources or inductors in series fix their currents, which jump at t = 0 (the flux linkage "
               "around every loop the sources do not drive kept)")
        warn(
            f"netlist {deck.title!r}: "
            + ", ".join(f"{n} starts at {v:.6g} {unit[n]}, not {ic[n]:.6g} {unit[n]}" for n, v in moved.items())
            + f": {why}, as in the circuit itself.",
            NetlistWarning,
        )
        ic = {**ic, **moved}
    return ImportedNetlist(
        model=model,
        initial=initial,
        velocity=velocity,
        ic=ic,
        tran=deck.tran,
        title=deck.title,
        options=deck.options,
        lines={e.name: e.line for e in deck.elements},
        ac=deck.ac,
        ac_sources={e.name: e.ac for e in deck.elements if e.ac is not None},
    )


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


def _waveform(wave: str, args: list[float], tran: Transient | None, where: str) -> Waveform | float:
    """The waveform of a source specification (:mod:`lagrangian.base.waveforms`, ngspice 39 semantics); a DC value
    as its number."""
    if wave == "dc":
        return args[0]  # a plain number, read as every element's value is

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
        return Sine(vo, va, freq or 1 / default(0.0, "tstop"), td, theta, phase)
    v1, v2, td, tr, tf, pw, per, count = (*args, *[0.0] * (8 - len(args)))
    tr, tf = default(tr, "tstep"), default(tf, "tstep")
    pw, per = default(pw, "tstop"), default(per, "tstop")
    return Pulse(v1, v2, td, tr, tf, pw, per, count)
