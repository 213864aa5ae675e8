"""Model files: a model's components as versioned JSON, written and read as data.

``model.save("m.json")`` writes a model; ``lagrangian.load("m.json")`` (or
``Model.load``) builds it again, with the plugins installed here.  A file
holds what the model was built from — its options and its components with
the parameters given to them — never derived equations, and never code:
loading validates it and builds the model through ``Model.add``, reading
every expression with :mod:`lagrangian.text` (never evaluated).

The schema, version 1 (``"lagrangian_model": 1``)::

    {
      "lagrangian_model": 1,                    required: the schema version, an integer
      "name": "oscillator",                     the model's name (default "model")
      "options": {"dim": 2, "formulation": "charge"},   the model options given (Model(name, **options))
      "nodes": ["cart"],                        nodes declared with Model.node before use (optional)
      "symbols": {"k": {"positive": true}},     SymPy symbols of the expressions, with their assumptions
      "state": {"coordinate__x_p": {"coordinate": "x_p"},
                "rate__x_p": {"rate": "x_p"}},  names in expressions standing for lagrangian.coordinate("x_p")
                                                and lagrangian.rate("x_p") (a load of the state)
      "plugins": [{"name": "cubic_spring", "distribution": "lagrangian-cubic-spring",
                   "version": "0.1.0", "kinds": ["cubic_spring"]}],   the plugins whose kinds it uses
      "components": [                           required, in the order they were added
        {"kind": "mass", "name": "m", "nodes": ["cart"], "params": {"m": 0.3}},
        {"kind": "force", "name": "F", "nodes": ["cart"], "params": {"F": "0.5*sin(1.5*t)"}}
      ]
    }

Parameters are written by the shape their kind declares (:class:`~lagrangian.Parameter`):

* a number as a JSON number: an integer as an integer, a float by its shortest ``repr`` (read back to the
  same bits);
* any other scalar (a symbol, an exact fraction, an expression, a signal of ``t`` or of the state) as text
  in the notation :mod:`lagrangian.text` reads — numbers, names, ``+ - * / **`` and its functions —, each
  float in it by ``repr``; :func:`save` reads every text back and refuses an expression that does not read
  back to the very same expression;
* a vector as an array, a matrix as an array of rows, a mapping (a body's points) as an object of arrays,
  a flag as ``true``/``false``, a name as a string, an absent value as ``null``.

Units: a model holds its values in SI (the unit each parameter declares), and a file holds them so: a value
given as ``"300 g"`` is written ``0.3``.  A file written by hand may give ``"300 g"``, converted on loading
as ``Model.add`` converts it (with pint).  A symbol's assumptions are kept (``"symbols"``); a name in a text
that ``"symbols"`` does not list is a plain symbol, as :mod:`lagrangian.text` reads it.

What a file cannot hold is refused by :func:`save`, naming the component and parameter, with the fix: a
Python callable (a signal given as a function: write it as an expression of ``lagrangian.t``, or pickle the
model), a SymPy ``Dummy``, a float of other than double precision, a function :mod:`lagrangian.text` does
not read (``Piecewise``: write it with ``Heaviside``).

Loading is bounded and strict: the file is at most :data:`MAX_BYTES` (checked before it is read), nested at
most :data:`MAX_DEPTH` deep (checked before it is parsed), its strings at most :data:`MAX_STRING`
characters, integers at most :data:`MAX_DIGITS` digits, arrays and objects at most :data:`MAX_ITEMS`
entries, components at most :data:`MAX_COMPONENTS`; numbers are finite, keys known, types right, the
version one this reader reads.  Anything else is a :class:`~lagrangian.ModelFileError` naming the place
with a JSON pointer (``/components/3/params/k``), as is a kind no installed plugin provides (with the
plugin the file names for it) and every error ``Model.add`` raises for a component.

>>> import sympy as sp, lagrangian as lg
>>> m = lg.Model("osc")
>>> _ = m.add("mass", "m", "p", m=sp.Symbol("m", positive=True))
>>> _ = m.add("force", "F", "p", F=0.1 * sp.sin(3 * lg.t) - 0.2 * lg.rate("x_p"))
>>> doc = document(m.name, {}, [], m.components.values(), m.registry)
>>> doc["symbols"], doc["state"]
({'m': {'positive': True}}, {'rate__x_p': {'rate': 'x_p'}})
>>> doc["components"][1]["params"]
{'F': '0.1*sin(3*t) - 0.2*rate__x_p'}
"""

from __future__ import annotations

import ast
import functools
import json
import keyword
import math
import os
import re
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any

import numpy as np

from ..errors import LagrangianError, ModelFileError, UnknownKindError, closest
from .component import Parameter, _CallableSignal, t
from .text import FUNCTIONS, MAX_LENGTH, parse_expression
from .units import split
from . import deferred as _deferred

sp = _deferred.module("sympy", globals())

__all__ = ["VERSION", "MAX_BYTES", "MAX_DEPTH", "MAX_STRING", "MAX_DIGITS", "MAX_ITEMS", "MAX_COMPONENTS",
           "document", "dumps", "save", "load", "parse"]

#: The schema version this module writes and reads.
VERSION = 1
#: Largest model file read (bytes), unless ``max_bytes`` says otherwise.
MAX_BYTES = 10_000_000
#: Deepest nesting of arrays and objects (a model file needs six).
MAX_DEPTH = 32
#: Longest string (names, expressions), in characters.
MAX_STRING = min(10_000, MAX_LENGTH)
#: Most digits of an integer.
MAX_DIGITS = 400
#: Most entries of one array or object (the components and the symbols apart).
MAX_ITEMS = 10_000
#: Most components (and most entries of "symbols" and "state").
MAX_COMPONENTS = 100_000

_TOP = {"lagrangian_model", "name", "options", "nodes", "symbols", "state", "plugins", "components"}
_COMPONENT = {"kind", "name", "nodes", "params"}
_PLUGIN = {"name", "distribution", "version", "kinds"}
_IDENTIFIER = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
#: Assumptions a symbol may carry in a file.
_ASSUMPTIONS = frozenset({
    "real", "extended_real", "complex", "imaginary", "positive", "negative", "nonnegative", "nonpositive", "nonzero",
    "zero", "extended_positive", "extended_negative", "extended_nonnegative", "extended_nonpositive",
    "extended_nonzero", "integer", "rational", "irrational", "finite", "infinite", "even", "odd", "prime",
    "composite", "algebraic", "transcendental", "commutative", "hermitian", "antihermitian", "noninteger"})


# -- writing ------------------------------------------------------------------------------------------------------

class _Unwritable(Exception):
    """A value a model file cannot hold (the message says why and what to do)."""


def _double(x: sp.Float) -> float:
    """The double ``x`` is, exactly; refused when it is none (more precision, or beyond a double's range)."""
    if x._prec != 53:
        raise _Unwritable(f"the number {x!s} has {x._prec} bits of precision; a file holds doubles: give it as a "
                          f"Python float, or exactly as a fraction (sympy.Rational)")
    value = float(x)
    if not math.isfinite(value) or sp.Float(value) != x:
        raise _Unwritable(f"the number {x!s} is beyond a double's range (below about 2.2e-308 it loses digits)")
    return value


@functools.cache
def _printers() -> tuple[type, type]:
    """The printers, made on first use (subclasses of SymPy's, which is imported then)."""
    from sympy.printing.precedence import PRECEDENCE
    from sympy.printing.str import StrPrinter

    class _Printer(StrPrinter):
        """SymPy's text, restricted to what :mod:`lagrangian.text` reads: floats by ``repr``, ``E`` as ``exp(1)``,
        coordinates and rates by the names of the ``state`` table; anything else it would not read is refused."""

        def __init__(self, writer: "_Writer"):
            super().__init__()
            self.writer = writer

        def _print_Float(self, expr):
            return repr(_double(expr))

        def _print_Symbol(self, expr):
            return self.writer.symbol(expr)

        def _print_Dummy(self, expr):
            raise _Unwritable(f"{expr} is a sympy.Dummy, which is unique to this process: use a sympy.Symbol")

        def _print_Exp1(self, expr):
            return "exp(1)"

        def _print_AppliedUndef(self, expr):
            return self.writer.state(expr)

        def _print_Derivative(self, expr):
            return self.writer.state(expr)

        def _print_Piecewise(self, expr):
            return "Piecewise(" + ", ".join(f"({self._print(e)}, {self._print(c)})" for e, c in expr.args) + ")"

        def _print_Function(self, expr):
            name = type(expr).__name__
            if FUNCTIONS.get(name) is not type(expr):
                raise _Unwritable(f"{name}() is not a function lagrangian.text reads (it reads "
                                  f"{', '.join(sorted(FUNCTIONS, key=str.lower))})")
            return super()._print_Function(expr)


    class _PlainPrinter(_Printer):
        """Products and powers as they stand, numbers last (``(x + 1.0)**(-1)*(1/2)``), for an expression SymPy would
        read back arranged otherwise as :class:`_Printer` writes it (``1/(2*(x + 1.0))``, where ``2*(x + 1.0)`` reads
        as ``2*x + 2.0``)."""

        def _print_Mul(self, expr):
            args = sorted(expr.args, key=lambda a: a.is_Number)  # (stable: the others keep their order)
            return "*".join(self.parenthesize(a, PRECEDENCE["Mul"], strict=a.is_Number) for a in args)

        def _print_Pow(self, expr, rational=False):
            return f"{self.parenthesize(expr.base, PRECEDENCE['Pow'], strict=True)}**" \
                   f"{self.parenthesize(expr.exp, PRECEDENCE['Pow'], strict=True)}"

    return _Printer, _PlainPrinter


class _Writer:
    """Encodes one model's parameters, collecting the symbols and state names its expressions use."""

    def __init__(self):
        self.symbols: dict[str, dict] = {}
        self.names: dict[str, sp.Basic] = {}  # every name a text uses → what it reads back as
        self.state_table: dict[str, dict] = {}
        self.printers = tuple(printer(self) for printer in _printers())

    def symbol(self, s: sp.Symbol) -> str:
        if s == t:
            return "t"
        name = s.name
        if not _IDENTIFIER.match(name) or keyword.iskeyword(name) or name in FUNCTIONS or name in ("pi", "t"):
            raise _Unwritable(f"the symbol name {name!r} cannot be written as a name in an expression: name symbols "
                              f"as Python identifiers (letters, digits, _), other than pi, t and function names")
        assumptions = getattr(s, "_assumptions_orig", None)
        assumptions = {k: bool(v) for k, v in (s.assumptions0 if assumptions is None else assumptions).items()
                       if v is not None}
        self._claim(name, s)
        self.symbols[name] = assumptions
        return name

    def state(self, expr: sp.Expr) -> str:
        if isinstance(expr, sp.Derivative):
            f, what = expr.expr, "rate"
            if expr.variables != (t,) or not isinstance(f, sp.core.function.AppliedUndef):
                raise _Unwritable(f"{expr} is not the rate of a coordinate (lagrangian.rate)")
        else:
            f, what = expr, "coordinate"
        name = type(f).__name__
        if f != sp.Function(name, real=True)(t):
            raise _Unwritable(f"{f} is not a coordinate as lagrangian.coordinate({name!r}) gives it: build loads of the "
                              f"state with lagrangian.coordinate and lagrangian.rate")
        key = f"{what}__{name}"
        self._claim(key, expr)
        self.state_table[key] = {what: name}
        return key

    def _claim(self, name: str, value: sp.Basic) -> None:
        if self.names.setdefault(name, value) != value:
            raise _Unwritable(f"the name {name!r} stands for two different things ({self.names[name]} and {value}); "
                              f"give different symbols different names")

    def scalar(self, value: Any) -> Any:
        if isinstance(value, sp.Integer):
            return int(value)
        if isinstance(value, sp.Float):
            return _double(value)
        if not isinstance(value, sp.Expr):
            raise _Unwritable(f"{value!r:.80} is not a number or an expression")
        for printer in self.printers:
            text = printer.doprint(value)
            if len(text) > MAX_STRING:
                raise _Unwritable(f"the expression is {len(text)} characters long as text, beyond {MAX_STRING}")
            try:
                back = parse_expression(text, "the text", names=self.names)
            except LagrangianError as exc:
                back = exc
            if back == value:
                return text
        if isinstance(back, LagrangianError):
            raise _Unwritable(f"{text!r:.80} cannot be read back ({str(back).removeprefix('the text: ')})")
        # SymPy arranges some terms otherwise when it reads them (2*(x + 1.0) is 2*x + 2.0)
        raise _Unwritable(f"{_short(value)} reads back arranged otherwise, as {_short(back)}: give the parameter as "
                          f"that expression to save it exactly")

    def value(self, value: Any) -> Any:
        if value is None or isinstance(value, (bool, str)):
            return value
        if isinstance(value, _CallableSignal):
            raise _Unwritable("is a Python callable, which a model file cannot hold (it would be code): give the "
                              "signal as an expression of lagrangian.t (such as '0.5*sin(3*t)'), or pickle the model")
        if isinstance(value, Mapping):
            return {str(k): self.value(v) for k, v in value.items()}
        if isinstance(value, sp.MatrixBase):
            if value.cols == 1:
                return [self.scalar(e) for e in value]
            return [[self.scalar(e) for e in value.row(i)] for i in range(value.rows)]
        return self.scalar(value)


def _short(value: Any, width: int = 80) -> str:
    text = str(value)
    return text if len(text) <= width else text[: width - 3] + "..."


def _plugins(kinds: Iterable[str], registry: Any) -> list[dict]:
    """The plugins providing ``kinds`` in ``registry``, each once, with their distribution and version."""
    out = []
    info = getattr(registry, "info", {}) or {}
    for name, plugin in info.items():
        used = [k for k in plugin.kinds if k in kinds]
        if used:
            out.append({"name": name, "distribution": plugin.distribution, "version": plugin.version, "kinds": used})
    return out


def document(name: str, options: Mapping[str, Any], nodes: Sequence[str], components: Iterable[Any],
             registry: Any) -> dict:
    """The model file of a model (its ``name``, the ``options`` given, the ``nodes`` declared before use, its
    ``components`` in order, the ``registry`` that provides their kinds) as a JSON object; a
    :class:`~lagrangian.ModelFileError` naming the component and parameter that cannot be written."""
    writer = _Writer()
    out_components = []
    for c in components:
        params = {}
        for pname in c.parameters:
            if pname not in c._given:
                continue
            try:
                params[pname] = writer.value(c.params[pname])
            except _Unwritable as exc:
                raise ModelFileError(f"component {c.name!r} ({c.kind}), parameter {pname!r}: {exc}.") from None
        out_components.append({"kind": c.kind, "name": c.name, "nodes": list(c.nodes), "params": params})
    for key, value in options.items():
        if not (value is None or isinstance(value, (bool, int, str)) or isinstance(value, float) and math.isfinite(value)):
            raise ModelFileError(f"model option {key!r}: {value!r:.80} is not a number, text, true/false or null.")
    doc: dict[str, Any] = {"lagrangian_model": VERSION, "name": str(name), "options": dict(options)}
    if nodes:
        doc["nodes"] = list(nodes)
    if writer.symbols:
        doc["symbols"] = dict(sorted(writer.symbols.items()))
    if writer.state_table:
        doc["state"] = dict(sorted(writer.state_table.items()))
    doc["plugins"] = _plugins({c["kind"] for c in out_components}, registry)
    doc["components"] = out_components

    def fail(pointer: str, message: str):  # what loading would refuse is not written
        raise ModelFileError(f"cannot be written: at {pointer}, {message}.")

    _bounded(doc, [], fail)
    return doc


def dumps(name: str, options: Mapping[str, Any], nodes: Sequence[str], components: Iterable[Any], registry: Any) -> str:
    """:func:`document` as JSON text (one component a line)."""
    doc = document(name, options, nodes, components, registry)
    body = {k: v for k, v in doc.items() if k != "components"}
    head = json.dumps(body, ensure_ascii=False, allow_nan=False)[:-1]
    lines = [json.dumps(c, ensure_ascii=False, allow_nan=False) for c in doc["components"]]
    return head + ', "components": [\n' + ",\n".join(lines) + "\n]}\n"


def save(path: str | os.PathLike, name: str, options: Mapping[str, Any], nodes: Sequence[str],
         components: Iterable[Any], registry: Any) -> None:
    """Write the model file of a model to ``path`` (see :func:`document`); nothing is written when it fails."""
    text = dumps(name, options, nodes, components, registry)
    with open(path, "w", encoding="utf-8") as f:
        f.write(text)


# -- reading: bounds and syntax -----------------------------------------------------------------------------------

class _Big:
    """An integer of more than :data:`MAX_DIGITS` digits, kept as its length (refused where it stands)."""

    def __init__(self, digits: int):
        self.digits = digits


class _Object(dict):
    """A JSON object; ``duplicate`` names a key given twice."""

    duplicate: str | None = None


def _pairs(pairs: list) -> _Object:
    out = _Object()
    for key, value in pairs:
        if key in out and out.duplicate is None:
            out.duplicate = key
        out[key] = value
    return out


_STRING = re.compile(rb'"(?:[^"\\]++|\\.)*+"', re.S)
_BRACKETS = bytes(range(256)).translate(None, b"[]{}")


def _pointer(parts: Sequence[Any]) -> str:
    return "".join("/" + str(p).replace("~", "~0").replace("/", "~1") for p in parts)


def _check_depth(data: bytes, fail: Callable[[str, str], None]) -> None:
    """Refuse nesting deeper than :data:`MAX_DEPTH` before the text is parsed (brackets inside strings aside)."""
    brackets = _STRING.sub(b'""', data).translate(None, _BRACKETS)
    if not brackets:
        return
    step = np.frombuffer(brackets, dtype=np.uint8)
    depth = np.cumsum(np.where((step == ord("[")) | (step == ord("{")), 1, -1), dtype=np.int64)
    if depth.max() <= MAX_DEPTH:
        return
    kept = _STRING.sub(lambda m: b'"' + b" " * (len(m.group()) - 2) + b'"', data)  # the offsets kept, to say where
    at = np.flatnonzero(np.isin(np.frombuffer(kept, dtype=np.uint8), np.frombuffer(b"[]{}", dtype=np.uint8)))
    first = int(at[int(np.argmax(depth > MAX_DEPTH))])
    line = kept.count(b"\n", 0, first) + 1
    column = first - kept.rfind(b"\n", 0, first)
    fail("", f"arrays and objects nest deeper than {MAX_DEPTH} levels (line {line}, column {column}); a model file "
             f"needs six")


def parse(data: bytes, fail: Callable[[str, str], None]) -> Any:
    """The JSON value of ``data`` (bytes, UTF-8), its nesting bounded before parsing; ``fail(pointer, message)``
    raises.  Integers beyond :data:`MAX_DIGITS` digits are kept as their length, to be refused where they
    stand; non-finite numbers are read as such, to be refused likewise."""
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        fail("", f"the file is not UTF-8 text (byte {exc.start})")
    _check_depth(data, fail)
    try:
        return json.loads(text, object_pairs_hook=_pairs, parse_constant=float,
                          parse_int=lambda s: int(s) if len(s) <= MAX_DIGITS else _Big(len(s)))
    except json.JSONDecodeError as exc:
        fail("", f"not valid JSON: {exc.msg} (line {exc.lineno}, column {exc.colno})")
    except (ValueError, RecursionError, MemoryError) as exc:  # (bounds above keep these out; a last guard)
        fail("", f"not valid JSON ({type(exc).__name__})")


def _bounded(value: Any, at: list, fail: Callable[[str, str], None]) -> None:
    """Check every size in ``value``: strings, integers, arrays and objects, numbers finite."""
    if isinstance(value, _Big):
        fail(_pointer(at), f"an integer of {value.digits} digits is beyond {MAX_DIGITS}")
    elif isinstance(value, float) and not math.isfinite(value):
        fail(_pointer(at), f"{value} is not a finite number (a number in a file is at most about 1.8e308)")
    elif isinstance(value, str) and len(value) > MAX_STRING:
        fail(_pointer(at), f"a string of {len(value)} characters is longer than {MAX_STRING}")
    elif isinstance(value, (list, dict)):
        limit = MAX_COMPONENTS if at in (["components"], ["symbols"], ["state"]) else MAX_ITEMS
        if len(value) > limit:
            fail(_pointer(at), f"{len(value)} entries are more than {limit}")
        if isinstance(value, _Object) and value.duplicate is not None:
            fail(_pointer([*at, value.duplicate]), "the key is given twice")
        for key, item in value.items() if isinstance(value, dict) else enumerate(value):
            if isinstance(key, str) and len(key) > MAX_STRING:
                fail(_pointer(at), f"a key of {len(key)} characters is longer than {MAX_STRING}")
            if isinstance(item, (list, dict, str, float, _Big)):  # (the others are within bounds)
                _bounded(item, [*at, key], fail)


# -- reading: the schema --------------------------------------------------------------------------------------------

def _kind_of(value: Any) -> str:
    return {bool: "true/false", int: "a number", float: "a number", str: "text", list: "an array",
            _Object: "an object", dict: "an object", type(None): "null"}.get(type(value), type(value).__name__)


class _Reader:
    """Builds a model from a parsed model file, each error a :class:`ModelFileError` at its JSON pointer."""

    def __init__(self, doc: Any, fail: Callable[[str, str], None]):
        self.doc, self.fail = doc, fail
        self.names: dict[str, sp.Basic] = {}

    def expect(self, value: Any, types: tuple, at: Sequence[Any], what: str) -> Any:
        if not isinstance(value, types) or isinstance(value, bool) and bool not in types:
            self.fail(_pointer(at), f"expected {what}, got {_kind_of(value)}")
        return value

    def keys(self, obj: Mapping, allowed: set, required: set, at: Sequence[Any]) -> None:
        for key in obj:
            if key not in allowed:
                self.fail(_pointer([*at, key]), f"unknown key.{closest(key, allowed)} Known keys here: "
                                                f"{', '.join(sorted(allowed))}")
        for key in sorted(required - set(obj)):
            self.fail(_pointer(at), f"the key {key!r} is missing")

    def header(self) -> tuple[str, dict, list]:
        doc = self.expect(self.doc, (dict,), [], "a JSON object (a lagrangian model file)")
        if "lagrangian_model" not in doc:
            self.fail("", "not a lagrangian model file: the key 'lagrangian_model' (the schema version) is missing")
        version = self.expect(doc["lagrangian_model"], (int,), ["lagrangian_model"], "the schema version, an integer")
        if version != VERSION:
            newer = "a newer lagrangian: upgrade lagrangian to read it" if version > VERSION else "no lagrangian"
            self.fail("/lagrangian_model", f"schema version {version} is one this lagrangian does not read (it reads "
                                           f"version {VERSION}); the file was written by {newer}")
        self.keys(doc, _TOP, {"components"}, [])
        name = self.expect(doc.get("name", "model"), (str,), ["name"], "the model's name, text")
        options = self.expect(doc.get("options", {}), (dict,), ["options"], "an object of model options")
        for key, value in options.items():
            self.expect(value, (bool, int, float, str, type(None)), ["options", key], "a number, text, true/false or null")
        nodes = self.expect(doc.get("nodes", []), (list,), ["nodes"], "an array of node names")
        for i, node in enumerate(nodes):
            self.expect(node, (str,), ["nodes", i], "a node name, text")
        self.read_symbols(doc.get("symbols", {}))
        self.read_state(doc.get("state", {}))
        self.read_plugins(doc.get("plugins", []))
        self.expect(doc["components"], (list,), ["components"], "an array of components")
        return name, options, nodes

    def identifier(self, name: str, at: list) -> None:
        if not _IDENTIFIER.match(name) or keyword.iskeyword(name) or name in FUNCTIONS or name in ("pi", "t"):
            self.fail(_pointer(at), f"{name!r:.60} is not a name an expression may hold (a Python identifier other "
                                    f"than pi, t and function names)")
        if name in self.names:
            self.fail(_pointer(at), f"the name {name!r} is given twice (in 'symbols' and 'state')")

    def read_symbols(self, table: Any) -> None:
        table = self.expect(table, (dict,), ["symbols"], "an object of symbol names to assumptions")
        for name, assumptions in table.items():
            at = ["symbols", name]
            self.identifier(name, at)
            self.expect(assumptions, (dict,), at, "an object of assumptions, such as {\"positive\": true}")
            for key, flag in assumptions.items():
                if key not in _ASSUMPTIONS:
                    self.fail(_pointer([*at, key]), f"not an assumption SymPy knows.{closest(key, _ASSUMPTIONS)}")
                self.expect(flag, (bool,), [*at, key], "true or false")
            try:
                self.names[name] = sp.Symbol(name, **assumptions)
            except (ValueError, TypeError) as exc:  # InconsistentAssumptions
                self.fail(_pointer(at), f"the assumptions contradict one another ({exc})")

    def read_state(self, table: Any) -> None:
        table = self.expect(table, (dict,), ["state"], "an object of names to coordinates and rates")
        for name, entry in table.items():
            at = ["state", name]
            self.identifier(name, at)
            self.expect(entry, (dict,), at, "{\"coordinate\": name} or {\"rate\": name}")
            if len(entry) != 1 or next(iter(entry)) not in ("coordinate", "rate"):
                self.fail(_pointer(at), "expected {\"coordinate\": name} or {\"rate\": name}")
            what, coordinate = next(iter(entry.items()))
            self.expect(coordinate, (str,), [*at, what], "a coordinate's name, text")
            if not _IDENTIFIER.match(coordinate) or keyword.iskeyword(coordinate):
                self.fail(_pointer([*at, what]), f"{coordinate!r:.60} is not a coordinate name (letters, digits, _)")
            f = sp.Function(coordinate, real=True)(t)
            self.names[name] = sp.Derivative(f, t) if what == "rate" else f

    def read_plugins(self, plugins: Any) -> None:
        self.plugins: dict[str, dict] = {}
        self.expect(plugins, (list,), ["plugins"], "an array of plugins")
        for i, plugin in enumerate(plugins):
            at = ["plugins", i]
            self.expect(plugin, (dict,), at, "an object {\"name\", \"distribution\", \"version\", \"kinds\"}")
            self.keys(plugin, _PLUGIN, {"name"}, at)
            self.expect(plugin["name"], (str,), [*at, "name"], "the plugin's entry-point name, text")
            for key in ("distribution", "version"):
                self.expect(plugin.get(key), (str, type(None)), [*at, key], "text or null")
            kinds = self.expect(plugin.get("kinds", []), (list,), [*at, "kinds"], "an array of kinds")
            for j, kind in enumerate(kinds):
                self.plugins[self.expect(kind, (str,), [*at, "kinds", j], "a kind, text")] = plugin

    def component(self, model: Any, i: int, entry: Any) -> None:
        at = ["components", i]
        self.expect(entry, (dict,), at, "a component {\"kind\", \"name\", \"nodes\", \"params\"}")
        self.keys(entry, _COMPONENT, {"kind", "name"}, at)
        kind = self.expect(entry["kind"], (str,), [*at, "kind"], "a component kind, text")
        name = self.expect(entry["name"], (str,), [*at, "name"], "a component name, text")
        nodes = self.expect(entry.get("nodes", []), (list,), [*at, "nodes"], "an array of node names")
        for j, node in enumerate(nodes):
            self.expect(node, (str,), [*at, "nodes", j], "a node name, text")
        params = self.expect(entry.get("params", {}), (dict,), [*at, "params"], "an object of parameters")
        try:
            cls = model.registry.component_type(kind)
        except UnknownKindError as exc:
            plugin = self.plugins.get(kind)
            hint = ""
            if plugin is not None:
                dist = plugin.get("distribution")
                hint = (f" The file says the plugin {plugin['name']!r} provides it"
                        + (f", from the distribution {dist!r}: pip install {dist}" if dist else "") + ".")
            self.fail(_pointer([*at, "kind"]), f"{exc}{hint}")
        values = {}
        for pname, raw in params.items():
            spec = cls.parameters.get(pname)
            if spec is None:
                self.fail(_pointer([*at, "params", pname]),
                          f"{kind!r} has no such parameter.{closest(pname, cls.parameters)} Its parameters: "
                          f"{', '.join(cls.parameters) or '(none)'}")
            values[pname] = self.value(raw, spec, [*at, "params", pname])
        try:
            model.add(kind, name, tuple(nodes), **values)
        except LagrangianError as exc:
            pname = str(getattr(exc, "parameter", "")).split("[")[0]
            where = [*at, "params", pname] if pname in params else at
            self.fail(_pointer(where), str(exc))
        except Exception as exc:  # noqa: BLE001 - a kind's own check of the values given, whatever it raises
            self.fail(_pointer(at), f"{kind} {name!r} refuses these values ({type(exc).__name__}: {exc})")

    def value(self, raw: Any, spec: Parameter, at: list) -> Any:
        if raw is None:
            return None
        shape = spec.shape
        if shape == "flag":
            return self.expect(raw, (bool,), at, "true or false")
        if shape == "name":
            return self.expect(raw, (str,), at, "a name, text")
        if shape == "mapping":
            self.expect(raw, (dict,), at, "an object of names to vectors")
            return {k: self.vector(v, [*at, k]) for k, v in raw.items()}
        if shape == "vector" or (shape == "signal" and isinstance(raw, list)):
            return self.vector(raw, at)
        if shape == "tensor" and isinstance(raw, list):
            if raw and all(isinstance(r, list) for r in raw):
                return [self.vector(r, [*at, j]) for j, r in enumerate(raw)]
            return self.vector(raw, at)
        return self.scalar(raw, at)

    def vector(self, raw: Any, at: list) -> list:
        self.expect(raw, (list,), at, "an array of numbers or expressions")
        return [self.scalar(v, [*at, j]) for j, v in enumerate(raw)]

    def scalar(self, raw: Any, at: list) -> Any:
        self.expect(raw, (int, float, str), at, "a number or an expression (text)")
        if not isinstance(raw, str):
            return raw
        if split(raw) is not None and not _syntax(raw):
            return raw  # a number with a unit ("300 g"), which is no expression: converted by Model.add
        where = _pointer(at)
        try:
            return parse_expression(raw, where, names=self.names)
        except LagrangianError as exc:
            self.fail(where, str(exc).removeprefix(f"{where}: "))


def _syntax(text: str) -> bool:
    """Whether ``text`` is written as an expression ("1e400" is, "300 g" is not); parsed, never run."""
    try:
        ast.parse(text.strip(), mode="eval")
    except (SyntaxError, ValueError, RecursionError, MemoryError):
        return False
    return True


def load(path: str | os.PathLike, factory: Callable[..., Any], registry: Any = None, *,
         max_bytes: int = MAX_BYTES) -> Any:
    """The model the file at ``path`` describes, built by ``factory(name, registry=registry, **options)`` (the
    ``Model`` class) and its ``add``; a :class:`~lagrangian.ModelFileError` at the JSON pointer of anything
    wrong.  A file over ``max_bytes`` is refused before it is read."""
    where = os.fspath(path)

    def fail(pointer: str, message: str):
        error = ModelFileError(message if message.endswith(".") else message + ".", pointer=pointer, path=where)
        error.__suppress_context__ = True  # the message says what the error met was
        raise error

    try:
        with open(path, "rb") as f:
            size = os.fstat(f.fileno()).st_size
            if size > max_bytes:
                fail("", f"the file is {size:,} bytes, more than {max_bytes:,} (load(..., max_bytes=) reads more)")
            data = f.read(max_bytes + 1)
    except OSError as exc:
        raise ModelFileError(f"cannot read it ({exc.strerror or exc})", path=where) from None
    if len(data) > max_bytes:
        fail("", f"the file is more than {max_bytes:,} bytes (load(..., max_bytes=) reads more)")
    doc = parse(data, fail)
    _bounded(doc, [], fail)
    reader = _Reader(doc, fail)
    name, options, nodes = reader.header()
    try:
        model = factory(name, registry=registry, **options)
    except (LagrangianError, TypeError) as exc:  # (TypeError: an option named "name" or "registry")
        key = next((k for k in options if k == getattr(exc, "name", None) or f"model option {k!r}" in str(exc)
                    or f"argument {k!r}" in str(exc)), None)
        fail(_pointer(["options"] if key is None else ["options", key]), str(exc))
    for i, node in enumerate(nodes):
        try:
            model.node(node)
        except LagrangianError as exc:
            fail(_pointer(["nodes", i]), str(exc))
    for i, entry in enumerate(doc["components"]):
        reader.component(model, i, entry)
    return model
