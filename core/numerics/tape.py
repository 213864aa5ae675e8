"""Straight-line programs ("tapes") from SymPy expressions: the one intermediate form of compiled models.

:func:`record` turns a list of SymPy expressions of some input symbols into
a :class:`Program`: a flat list of instructions ``(op, dst, x, y, z)`` over
a register file holding the inputs, the constants and the temporaries, in
which every distinct subexpression is computed once (SymPy's expressions
are hash-consed, so a dictionary from expression to register *is* common
subexpression elimination).  Recording is a single pass over the
expression graph — milliseconds where :func:`sympy.cse` takes tenths of a
second — and the program is then either

- **interpreted** by a small C loop over the instructions, compiled once
  per machine and shared by every model (:mod:`lagrangian.codegen`,
  ``compiled="tape"``): no compilation per model, so a model runs the
  moment its equations are derived; or
- **printed** as straight-line C (:meth:`Program.c_lines`), compiled per
  model into native code (``compiled=True``): the fastest per evaluation,
  after a C compilation of a tenth of a second or more (then cached).

Both run the same operations in the same order (compiled without fused
multiply–adds), so they agree to the last bit.
Integer powers become products (by squaring), half-integer powers square
roots, quotients one division per term.  The operations are those of
:data:`OPS`; an expression with anything else (an unevaluated integral, a
Python-callable time signal, ``zoo``) raises :class:`TapeError` naming it,
which compiled models turn into a note and the NumPy path.

>>> import sympy as sp
>>> x, y = sp.symbols("x y")
>>> prog = record([sp.sin(x) ** 2 + y / sp.sin(x), sp.sqrt(x * y)], [x, y])
>>> len(prog.code), prog.n_inputs, prog.n_outputs    # sin(x) computed once
(6, 2, 2)
>>> prog.evaluate([0.5, 2.0])                       # a reference interpreter in Python
[4.4015081..., 1.0]
>>> print("\\n".join(prog.c_lines({0: "x", 1: "y"}, ["out[0]", "out[1]"])))
const double w0 = sin(x);
const double w1 = w0 * w0;
...
out[1] = w5;
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np

from .c_units import BEGIN, END, PART, PREAMBLE, UNIT_PARTS
from ..base import deferred as _deferred

sp = _deferred.module("sympy", globals())

__all__ = ["C_PART", "OPS", "Program", "TapeError", "c_body", "record", "size"]


class TapeError(Exception):
    """An expression the tape cannot hold; the message names what (turned into a note by compiled models)."""


#: The operations: name → (number of operands, C expression of the operands ``x``, ``y``, ``z``).
#: Their order is the opcode; the interpreter's ``switch`` and the printed C come from this one table.
OPS: dict[str, tuple[int, str]] = {
    "add": (2, "x + y"), "sub": (2, "x - y"), "mul": (2, "x * y"), "div": (2, "x / y"), "neg": (1, "-x"),
    "pow": (2, "pow(x, y)"), "sqrt": (1, "sqrt(x)"), "exp": (1, "exp(x)"), "log": (1, "log(x)"),
    "sin": (1, "sin(x)"), "cos": (1, "cos(x)"), "tan": (1, "tan(x)"), "asin": (1, "asin(x)"),
    "acos": (1, "acos(x)"), "atan": (1, "atan(x)"), "atan2": (2, "atan2(x, y)"), "sinh": (1, "sinh(x)"),
    "cosh": (1, "cosh(x)"), "tanh": (1, "tanh(x)"), "asinh": (1, "asinh(x)"), "acosh": (1, "acosh(x)"),
    "atanh": (1, "atanh(x)"), "abs": (1, "fabs(x)"), "sign": (1, "(double)((x > 0) - (x < 0))"),
    "heaviside": (2, "(x > 0 ? 1.0 : (x < 0 ? 0.0 : y))"), "floor": (1, "floor(x)"), "ceil": (1, "ceil(x)"),
    "min": (2, "fmin(x, y)"), "max": (2, "fmax(x, y)"), "mod": (2, "x - y * floor(x / y)"),
    "lt": (2, "(double)(x < y)"), "le": (2, "(double)(x <= y)"), "gt": (2, "(double)(x > y)"),
    "ge": (2, "(double)(x >= y)"), "eq": (2, "(double)(x == y)"), "ne": (2, "(double)(x != y)"),
    "and": (2, "(double)(x != 0 && y != 0)"), "or": (2, "(double)(x != 0 || y != 0)"),
    "not": (1, "(double)(x == 0)"), "select": (3, "(x != 0 ? y : z)"), "erf": (1, "erf(x)"),
    "erfc": (1, "erfc(x)"), "gamma": (1, "tgamma(x)"), "loggamma": (1, "lgamma(x)"),
}
CODE = {name: k for k, name in enumerate(OPS)}
_PY = {  # the same operations in Python, for Program.evaluate (a reference, not a fast path)
    "add": lambda x, y, z: x + y, "sub": lambda x, y, z: x - y, "mul": lambda x, y, z: x * y,
    "div": lambda x, y, z: x / y if y else math.copysign(math.inf, x) * math.copysign(1.0, y) if x else math.nan,
    "neg": lambda x, y, z: -x, "pow": lambda x, y, z: x ** y, "sqrt": lambda x, y, z: math.sqrt(x),
    "atan2": lambda x, y, z: math.atan2(x, y), "abs": lambda x, y, z: abs(x),
    "sign": lambda x, y, z: float((x > 0) - (x < 0)), "heaviside": lambda x, y, z: 1.0 if x > 0 else 0.0 if x < 0 else y,
    "ceil": lambda x, y, z: float(math.ceil(x)), "floor": lambda x, y, z: float(math.floor(x)),
    "min": lambda x, y, z: min(x, y), "max": lambda x, y, z: max(x, y), "mod": lambda x, y, z: x - y * math.floor(x / y),
    "lt": lambda x, y, z: float(x < y), "le": lambda x, y, z: float(x <= y), "gt": lambda x, y, z: float(x > y),
    "ge": lambda x, y, z: float(x >= y), "eq": lambda x, y, z: float(x == y), "ne": lambda x, y, z: float(x != y),
    "and": lambda x, y, z: float(x != 0 and y != 0), "or": lambda x, y, z: float(x != 0 or y != 0),
    "not": lambda x, y, z: float(x == 0), "select": lambda x, y, z: y if x != 0 else z,
    "gamma": lambda x, y, z: math.gamma(x), "loggamma": lambda x, y, z: math.lgamma(x),
}
for _name in OPS:
    if _name not in _PY:  # one-argument functions of the math module: sin, exp, erf, ...
        _PY[_name] = (lambda f: lambda x, y, z: f(x))(getattr(math, _name))


def _elementwise(f):
    return lambda x, y, z: np.frompyfunc(f, 3, 1)(x, y, z).astype(float)


_NP = {  # the same operations on arrays, for Program.evaluate_many (IEEE arithmetic, as C does)
    "add": lambda x, y, z: x + y, "sub": lambda x, y, z: x - y, "mul": lambda x, y, z: x * y,
    "div": lambda x, y, z: x / y, "neg": lambda x, y, z: -x, "pow": lambda x, y, z: np.power(x, y),
    "atan2": lambda x, y, z: np.arctan2(x, y), "abs": lambda x, y, z: np.fabs(x), "sign": lambda x, y, z: np.sign(x),
    "heaviside": lambda x, y, z: np.where(x > 0, 1.0, np.where(x < 0, 0.0, y)), "min": lambda x, y, z: np.fmin(x, y),
    "max": lambda x, y, z: np.fmax(x, y), "mod": lambda x, y, z: x - y * np.floor(x / y),
    "lt": lambda x, y, z: np.less(x, y) * 1.0, "le": lambda x, y, z: np.less_equal(x, y) * 1.0,
    "gt": lambda x, y, z: np.greater(x, y) * 1.0, "ge": lambda x, y, z: np.greater_equal(x, y) * 1.0,
    "eq": lambda x, y, z: np.equal(x, y) * 1.0, "ne": lambda x, y, z: np.not_equal(x, y) * 1.0,
    "and": lambda x, y, z: np.logical_and(x != 0, y != 0) * 1.0, "or": lambda x, y, z: np.logical_or(x != 0, y != 0) * 1.0,
    "not": lambda x, y, z: np.equal(x, 0) * 1.0, "select": lambda x, y, z: np.where(x != 0, y, z),
    **{name: (lambda f: lambda x, y, z: f(x))(getattr(np, alias)) for name, alias in (
        ("sqrt", "sqrt"), ("exp", "exp"), ("log", "log"), ("sin", "sin"), ("cos", "cos"), ("tan", "tan"),
        ("asin", "arcsin"), ("acos", "arccos"), ("atan", "arctan"), ("sinh", "sinh"), ("cosh", "cosh"),
        ("tanh", "tanh"), ("asinh", "arcsinh"), ("acosh", "arccosh"), ("atanh", "arctanh"), ("floor", "floor"),
        ("ceil", "ceil"))},
    **{name: _elementwise(_PY[name]) for name in ("erf", "erfc", "gamma", "loggamma")},
}


@functools.cache
def _functions():
    return {
        sp.sin: "sin", sp.cos: "cos", sp.tan: "tan", sp.asin: "asin", sp.acos: "acos", sp.atan: "atan",
        sp.sinh: "sinh", sp.cosh: "cosh", sp.tanh: "tanh", sp.asinh: "asinh", sp.acosh: "acosh", sp.atanh: "atanh",
        sp.exp: "exp", sp.Abs: "abs", sp.sign: "sign", sp.floor: "floor", sp.ceiling: "ceil", sp.erf: "erf",
        sp.erfc: "erfc", sp.gamma: "gamma", sp.loggamma: "loggamma",
    }


@functools.cache
def _binary():
    return {sp.atan2: "atan2", sp.Mod: "mod"}


@functools.cache
def _relations():
    return {sp.StrictLessThan: "lt", sp.LessThan: "le", sp.StrictGreaterThan: "gt", sp.GreaterThan: "ge",
                  sp.Equality: "eq", sp.Unequality: "ne"}


@functools.cache
def _folds():
    return {sp.Min: "min", sp.Max: "max", sp.And: "and", sp.Or: "or"}


@dataclass
class Program:
    """A straight-line program.

    Registers ``0 … n_inputs−1`` hold the inputs (in the order given to
    :func:`record`), the next ``len(constants)`` the constants, the rest the
    temporaries; ``code`` is an ``int32`` array of rows ``(op, dst, x, y, z)``
    (``op`` indexes :data:`OPS`; unused operands are 0), executed in order;
    ``outputs`` are the registers holding the results.
    """

    n_inputs: int
    constants: np.ndarray
    code: np.ndarray
    outputs: np.ndarray
    #: parameters recorded as constants whose values come later: symbol → index into ``constants``
    parameters: dict = field(default_factory=dict)

    def with_values(self, values: Mapping) -> "Program":
        """The same program with its parameters' values (symbol → number) in their constant registers: no
        recording again, so a parameter's value is a run-time input.

        >>> k, x = sp.symbols("k x")
        >>> prog = record([k * sp.sin(x)], [x], parameters=[k])
        >>> prog.with_values({k: 2.0}).evaluate([0.5]), prog.with_values({k: 3.0}).evaluate([0.5])
        ([0.958851077208406], [1.438276615812609])
        """
        missing = [str(s) for s in self.parameters if s not in values]
        if missing:
            raise TapeError(f"no value for the parameter(s) {', '.join(missing)}")
        constants = self.constants.copy()
        for symbol, index in self.parameters.items():
            constants[index] = float(values[symbol])
        return _fold(Program(self.n_inputs, constants, self.code, self.outputs, dict(self.parameters)))


    @property
    def n_registers(self) -> int:
        return self.n_inputs + len(self.constants) + len(self.code)

    @property
    def n_outputs(self) -> int:
        return len(self.outputs)

    def evaluate_many(self, inputs: np.ndarray) -> np.ndarray:
        """Run the program on NumPy arrays: ``inputs`` one row per input, a column per point; the outputs the
        same way.  Each instruction is one array operation for all the points, so a long program (a tree of 30
        bodies, its 30,000 steps) costs its length in NumPy calls, whatever the number of points: the NumPy path
        of a model the tape holds, where a compiled library is not at hand."""
        inputs = np.asarray(inputs, dtype=float)
        width = inputs.shape[1:]
        r: list = [*inputs, *(np.full(width, c) for c in self.constants.tolist())]
        r += [None] * len(self.code)
        ops = [_NP[name] for name in OPS]
        with np.errstate(all="ignore"):
            for op, dst, x, y, z in self.code.tolist():
                r[dst] = ops[op](r[x], r[y], r[z])
        return np.array([np.broadcast_to(r[k], width) for k in self.outputs.tolist()], dtype=float)

    def evaluate(self, inputs: Sequence[float]) -> list[float]:
        """Run the program in Python (slowly; the reference the C interpreter is tested against)."""
        r = [*map(float, inputs), *map(float, self.constants), *([0.0] * len(self.code))]
        names = list(OPS)
        for op, dst, x, y, z in self.code.tolist():
            try:
                value = _PY[names[op]](r[x], r[y], r[z])
            except (ValueError, ZeroDivisionError):  # outside the domain: C gives NaN (every branch is computed)
                value = math.nan
            except OverflowError:
                value = math.inf
            r[dst] = value if isinstance(value, float) else math.nan  # a complex power of a negative base: NaN in C
        return [r[k] for k in self.outputs.tolist()]

    def c_lines(self, inputs: dict[int, str], targets: Sequence[str], indent: str = "", *,
                zeroed: bool = False) -> list[str]:
        """Straight-line C: one ``const double wK = …;`` per instruction, then ``target = …;`` per output.
        ``inputs`` spells each input register (``{0: "t", 1: "q[0]", …}``), and may spell constant registers too
        (a parameter read at run time, ``"P[3]"``); other constants are written as numbers.  ``zeroed``: the
        targets hold +0.0 already (the caller cleared them with ``memset``), so an output that is the constant
        +0.0 writes nothing: a mass matrix of 50 masses on a chain is 2,450 zeros of 2,500 entries, whose stores
        took GCC 3.5 s at ``-O3`` (SLP vectorization and alias walking), against 0.2 s for the rest."""
        first = self.n_inputs + len(self.constants)
        names = dict(inputs)
        for k, c in enumerate(self.constants.tolist()):  # a constant spelled in ``inputs`` (a parameter) keeps it
            names.setdefault(self.n_inputs + k, "NAN" if c != c else f"({c!r})" if c < 0 else repr(c))
        op_names = list(OPS)
        lines = []
        for op, dst, x, y, z in self.code.tolist():
            arity, template = OPS[op_names[op]]
            spelled = {"x": names[x], "y": names[y], "z": names[z]}
            text = "".join(spelled.get(ch, ch) if ch in "xyz" and _alone(template, i) else ch for i, ch in enumerate(template))
            names[dst] = f"w{dst - first}"
            lines.append(f"{indent}const double {names[dst]} = {text};")
        skip = set(self.zero_outputs(inputs)) if zeroed else set()
        lines += [f"{indent}{target} = {names[k]};" for i, (target, k) in enumerate(zip(targets, self.outputs.tolist()))
                  if i not in skip]
        return lines

    def c_parts(self, inputs: dict[int, str], targets: Sequence[str], size: int, *, zeroed: bool = False,
                store: str = "W") -> tuple[list[list[str]], int, list[str]]:
        """:meth:`c_lines` cut into parts of at most ``size`` instructions, for functions of their own: a C
        compiler's time on one straight-line function grows faster than its length (GCC took 50 s on the 31,591
        instructions of 30 bodies on spherical joints), on parts of bounded size linearly.  A result a later part
        or an output reads is kept in ``store[k]`` (an array of the caller's), the others in locals.  Returns the
        parts' lines, the length of ``store`` needed and the lines that write the targets from it.

        >>> x = sp.Symbol("x")
        >>> parts, n, last = record([sp.sin(x) + 1, sp.sin(x) * 2], [x]).c_parts({0: "x"}, ["o[0]", "o[1]"], 2)
        >>> parts, n, last
        ([['W[0] = sin(x);', 'W[1] = 1.0 + W[0];'], ['const double w2 = 2.0 * W[0];', 'o[1] = w2;']], 2, ['o[0] = W[1];'])
        """
        first = self.n_inputs + len(self.constants)
        names = dict(inputs)
        for k, c in enumerate(self.constants.tolist()):
            names.setdefault(self.n_inputs + k, "NAN" if c != c else f"({c!r})" if c < 0 else repr(c))
        op_names = list(OPS)
        rows = self.code.tolist()
        part = {row[1]: i // size for i, row in enumerate(rows)}
        kept = set()
        for i, (op, dst, x, y, z) in enumerate(rows):
            for r in (x, y, z)[:OPS[op_names[op]][0]]:
                if r in part and part[r] != i // size:
                    kept.add(r)
        outputs = self.outputs.tolist()
        skip = set(self.zero_outputs(inputs)) if zeroed else set()
        last_part = (len(rows) - 1) // size
        kept |= {r for i, r in enumerate(outputs) if r in part and i not in skip and part[r] != last_part}
        slot = {r: k for k, r in enumerate(sorted(kept))}
        parts: list[list[str]] = [[] for _ in range(last_part + 1)] if rows else []
        for i, (op, dst, x, y, z) in enumerate(rows):
            template = OPS[op_names[op]][1]
            spelled = {"x": names[x], "y": names[y], "z": names[z]}
            text = "".join(spelled.get(ch, ch) if ch in "xyz" and _alone(template, j) else ch for j, ch in enumerate(template))
            if dst in slot:
                names[dst] = f"{store}[{slot[dst]}]"
                parts[i // size].append(f"{names[dst]} = {text};")
            else:
                names[dst] = f"w{dst - first}"
                parts[i // size].append(f"const double {names[dst]} = {text};")
        written = [(target, k) for i, (target, k) in enumerate(zip(targets, outputs)) if i not in skip]

        def in_last(k):  # an output the last part computes: written there, from its locals
            return bool(parts) and k in part and part[k] == last_part

        if parts:
            parts[-1] += [f"{target} = {names[k]};" for target, k in written if in_last(k)]
        final = [f"{target} = {names[k]};" for target, k in written if not in_last(k)]
        return parts, len(slot), final

    def zero_outputs(self, inputs: Mapping[int, str] | None = None) -> list[int]:
        """The positions of the outputs that are the constant +0.0 (not a constant ``inputs`` spells: a parameter
        read at run time)."""
        zero = {self.n_inputs + k for k, c in enumerate(self.constants.tolist())
                if c == 0.0 and math.copysign(1.0, c) > 0 and self.n_inputs + k not in (inputs or {})}
        return [i for i, k in enumerate(self.outputs.tolist()) if k in zero]


#: The most instructions printed in one C function: a longer tape is cut into parts of this size, each a function of
#: its own (:meth:`Program.c_parts`).  GCC's time on one straight-line function grows faster than its
#: length.  Measured on the native library of 30 bodies on spherical joints (31,591 instructions for A and b, 2.7 MB
#: of C), GCC -O3: 50 s as one function each, 9.3 s in parts of 4,000 instructions, 7.7 s of 2,000, 6.9 s of 1,000
#: and of 500.
C_PART = 1000


def c_body(program: Program, inputs: dict, targets: list[str], name: str, params: str, args: str, fail: list[str],
           zeroed: bool = False) -> tuple[list[str], list[str]]:
    """The C of ``program`` writing ``targets``: ``([], lines)`` in one function's body up to :data:`C_PART`
    instructions; beyond, the functions of its parts (``name_k(params, W)``) and the body that calls them in turn,
    their shared results in a scratch array ``W`` (``fail``: what the body does when no memory is left for it).
    The parts are grouped :data:`~lagrangian.numerics.c_units.UNIT_PARTS` to a translation unit, compiled in
    parallel (:mod:`lagrangian.numerics.c_units`); their prototypes stay with the body."""
    if len(program.code) <= C_PART:
        return [], program.c_lines(inputs, targets, "    ", zeroed=zeroed)
    parts, size, final = program.c_parts(inputs, targets, C_PART, zeroed=zeroed)
    functions = [PREAMBLE, *(f"{PART} void {name}_{k}({params}, double *W);" for k in range(len(parts)))]
    for k, lines in enumerate(parts):
        if k % UNIT_PARTS == 0:
            functions += [BEGIN, PREAMBLE]
        functions += [f"{PART} void {name}_{k}({params}, double *W) {{",
                      "    (void)P; (void)t; (void)q; (void)W;", *(f"    {line}" for line in lines), "}"]
        if k % UNIT_PARTS == UNIT_PARTS - 1 or k == len(parts) - 1:
            functions += [END, ""]
    body = [f"    SCRATCH(W, {max(size, 1)});", "    if (!W) {", *(f"        {line}" for line in fail), "    }",
            *(f"    {name}_{k}({args}, W);" for k in range(len(parts))), *(f"    {line}" for line in final),
            "    RELEASE(W);"]
    return functions, body


def _fold(program: Program) -> Program:
    """``program`` with every instruction whose operands are all constants computed once, here, and held as a
    constant: what depends on the parameters alone costs nothing per evaluation (as when the values were in the
    expressions).  The same operations as the C code (IEEE arithmetic, the C library's functions), so the
    results are the same to the last bit."""
    n_in, n_c = program.n_inputs, len(program.constants)
    value: dict[int, float] = {n_in + k: float(c) for k, c in enumerate(program.constants)}
    names = list(OPS)
    static, moving = [], []
    for row in program.code.tolist():
        op, dst, x, y, z = row
        arity = OPS[names[op]][0]
        operands = (x, y, z)[:arity]
        if all(r in value for r in operands):
            try:
                result = _PY[names[op]](*(value[r] for r in operands), *([0.0] * (3 - arity)))
            except (ValueError, ZeroDivisionError):
                result = math.nan
            except OverflowError:
                result = math.inf
            value[dst] = result if isinstance(result, float) else math.nan
            static.append(dst)
        else:
            moving.append(row)
    if not static:
        return program
    n_c2 = n_c + len(static)
    where = {r: r for r in range(n_in)}
    where.update({n_in + k: n_in + k for k in range(n_c)})
    where.update({dst: n_in + n_c + j for j, dst in enumerate(static)})
    where.update({row[1]: n_in + n_c2 + i for i, row in enumerate(moving)})
    code = np.array([[op, where[dst], where[x], where[y], where[z]] for op, dst, x, y, z in moving],
                    dtype=np.int32).reshape(-1, 5)
    constants = np.concatenate([program.constants, np.array([value[d] for d in static], dtype=float)])
    outputs = np.array([where[r] for r in program.outputs.tolist()], dtype=np.int32)
    return Program(n_in, constants, code, outputs, dict(program.parameters))


def _alone(template: str, i: int) -> bool:
    """Whether ``template[i]`` is an operand name rather than a letter of a word (``exp``, ``fmax``)."""
    return not (i > 0 and template[i - 1].isalnum()) and not (i + 1 < len(template) and template[i + 1].isalnum())


class _Recorder:
    def __init__(self, inputs: Sequence[sp.Symbol], opaque: bool = False, parameters: Sequence[sp.Symbol] = ()):
        self.opaque = opaque  # unknown symbols and functions become leaves (size(): counting, not running)
        self.parameters = frozenset(parameters)  # symbols held in constant registers, their values given later
        self.n_inputs = len(inputs)
        self.memo: dict = {s: k for k, s in enumerate(inputs)}
        if len(self.memo) != len(inputs):
            raise TapeError("the inputs of a tape must be distinct symbols")
        self.constants: dict = {}  # value (or "nan", or size()'s leaves) → −1 − index (relocated at the end)
        self.code: list[tuple[int, int, int, int, int]] = []

    # registers ---------------------------------------------------------------
    def const(self, value: float, nan: bool = False) -> int:
        """The register of a constant; NaN only when ``nan`` (a Piecewise with no branch for some inputs)."""
        if not math.isfinite(value) and not (nan and math.isnan(value)):
            raise TapeError(f"the equations contain a non-finite constant ({value})")
        key = float(value)
        if key == 0.0:
            key = 0.0  # one register for 0.0 and -0.0
        elif key != key:
            key = "nan"  # NaN is not equal to itself: a key that is
        reg = self.constants.get(key)
        if reg is None:
            reg = self.constants[key] = -1 - len(self.constants)
        return reg

    def emit(self, op: str, x: int, y: int = 0, z: int = 0, key=None) -> int:
        key = (op, x, y, z) if key is None else key
        reg = self.memo.get(key)
        if reg is None:
            reg = self.n_inputs + len(self.code)
            self.code.append((CODE[op], reg, x, y, z))
            self.memo[key] = reg
        return reg

    # expressions -------------------------------------------------------------
    def reg(self, e) -> int:
        found = self.memo.get(e)
        if found is not None:
            return found
        out = self._expr(e)
        self.memo[e] = out
        return out

    def _expr(self, e) -> int:
        if e.is_Number or e.is_NumberSymbol:
            return self.const(float(e))
        if self.opaque and (e.is_Symbol or isinstance(e, (sp.core.function.AppliedUndef, sp.Derivative))):
            return self.constants.setdefault(("leaf", e), -1 - len(self.constants))  # a leaf of its own, no instruction
        if e.is_Symbol and e in self.parameters:
            return self.constants.setdefault(("param", e), -1 - len(self.constants))
        if e.is_Symbol:
            raise TapeError(f"the symbol {e} has no value (not an input, not a parameter with a value)")
        if e.is_Add:
            return self._add(e.args)
        if e.is_Mul:
            return self._mul(e.args)
        if e.is_Pow:
            base, exp = e.args
            if base is sp.E:
                return self.emit("exp", self.reg(exp))
            return self._pow(base, exp)
        func = e.func
        if func in _functions():
            return self.emit(_functions()[func], self.reg(e.args[0]))
        if func is sp.log:
            if len(e.args) == 2:
                return self.emit("div", self.emit("log", self.reg(e.args[0])), self.emit("log", self.reg(e.args[1])))
            return self.emit("log", self.reg(e.args[0]))
        if func in _binary():
            return self.emit(_binary()[func], self.reg(e.args[0]), self.reg(e.args[1]))
        if func in _relations():
            return self.emit(_relations()[func], self.reg(e.args[0]), self.reg(e.args[1]))
        if func in _folds():
            regs = [self.reg(a) for a in e.args]
            out = regs[0]
            for r in regs[1:]:
                out = self.emit(_folds()[func], out, r)
            return out
        if func is sp.Not:
            return self.emit("not", self.reg(e.args[0]))
        if e is sp.true or e is sp.false:
            return self.const(1.0 if e is sp.true else 0.0)
        if func is sp.Heaviside:
            h0 = self.reg(e.args[1]) if len(e.args) > 1 else self.const(0.5)
            return self.emit("heaviside", self.reg(e.args[0]), h0)
        if func is sp.Piecewise:
            pieces = list(e.args)
            out = self.const(math.nan, nan=True) if pieces[-1].cond is not sp.true else self.reg(pieces.pop().expr)
            for piece in reversed(pieces):
                out = self.emit("select", self.reg(piece.cond), self.reg(piece.expr), out)
            return out
        if isinstance(e, (sp.core.function.AppliedUndef, sp.Derivative)):
            raise TapeError(f"{e} is a time signal given as a Python callable, which compiled code cannot call; "
                            f"give it as a SymPy expression of t")
        if e.is_number:  # a constant the cases above do not name (sin(1), Catalan, ...)
            try:
                return self.const(float(e))
            except (TypeError, ValueError):
                pass
        if self.opaque:  # an operation the tape does not know: one instruction on its arguments
            args = [self.reg(a) for a in e.args if isinstance(a, sp.Basic)] or [self.const(0.0)]
            return self.emit("add", args[0], args[-1], key=("opaque", e))
        raise TapeError(f"the equations use {type(e).__name__}, which compiled code does not evaluate")

    def _add(self, terms) -> int:
        plus, minus = [], []
        for term in terms:
            coeff, rest = term.as_coeff_Mul()
            if rest is sp.S.One:
                (plus if coeff >= 0 else minus).append(self.const(abs(float(coeff))))
                continue
            r = self.reg(rest)
            c = float(coeff)
            if abs(c) != 1.0:
                r = self.emit("mul", self.const(abs(c)), r)
            (plus if c > 0 else minus).append(r)
        if plus:
            out = plus[0]
            for r in plus[1:]:
                out = self.emit("add", out, r)
        else:
            out = self.emit("neg", minus.pop(0))
        for r in minus:
            out = self.emit("sub", out, r)
        return out

    def _mul(self, factors) -> int:
        coeff, num, den = 1.0, [], []
        for f in factors:
            if f.is_Number:
                coeff *= float(f)
            elif f.is_Pow and f.exp.is_Number and f.exp < 0 and f.base is not sp.E:
                den.append(self._pow(f.base, -f.exp))
            else:
                num.append(self.reg(f))
        out = None
        for r in num:
            out = r if out is None else self.emit("mul", out, r)
        if den:
            d = den[0]
            for r in den[1:]:
                d = self.emit("mul", d, r)
            if out is None:
                return self.emit("div", self.const(coeff), d)
            out = self.emit("div", out, d)
        if out is None:
            return self.const(coeff)
        if coeff == -1.0:
            return self.emit("neg", out)
        return out if coeff == 1.0 else self.emit("mul", self.const(coeff), out)

    def _pow(self, base, exp) -> int:
        if exp.is_Integer:
            k = int(exp)
            if k < 0:
                return self.emit("div", self.const(1.0), self._power(self.reg(base), -k))
            return self._power(self.reg(base), k)
        if exp.is_Rational and exp.q == 2:  # x^(p/2) = sqrt(x)^p
            root = self.emit("sqrt", self.reg(base))
            k = int(exp.p)
            return self._power(root, k) if k > 0 else self.emit("div", self.const(1.0), self._power(root, -k))
        return self.emit("pow", self.reg(base), self.reg(exp))

    def _power(self, r: int, k: int) -> int:
        """``r ** k`` for an integer ``k ≥ 0`` by squaring (``x*x``, ``(x*x)*(x*x)``, …; each power kept for reuse)."""
        if k == 0:
            return self.const(1.0)
        if k == 1:
            return r
        key = ("power", r, k)
        found = self.memo.get(key)
        if found is not None:
            return found
        half = self._power(r, k // 2)
        out = self.emit("mul", half, half)
        if k % 2:
            out = self.emit("mul", out, r)
        self.memo[key] = out
        return out

    def program(self, outputs: list[int]) -> Program:
        keys = sorted(self.constants, key=lambda v: -self.constants[v])
        constants = np.array([math.nan if isinstance(v, (str, tuple)) else v for v in keys], dtype=float)
        parameters = {key[1]: k for k, key in enumerate(keys) if isinstance(key, tuple) and key[0] == "param"}
        n_in, n_const = self.n_inputs, len(constants)

        def place(reg):
            return n_in - 1 - reg if reg < 0 else reg + n_const if reg >= n_in else reg

        code = np.array(self.code, dtype=np.int64).reshape(-1, 5)
        if code.size:
            operands = code[:, 1:]
            code[:, 1:] = np.where(operands < 0, n_in - 1 - operands, np.where(operands >= n_in, operands + n_const, operands))
            # operands a unary/binary op does not use are 0 (an input register): harmless, never read
            for k, (name, (arity, _)) in enumerate(OPS.items()):
                rows = code[:, 0] == k
                code[rows, 2 + arity:] = 0
        return Program(n_in, constants, code.astype(np.int32), np.array([place(r) for r in outputs], dtype=np.int32),
                       parameters)


def size(exprs: Sequence) -> int:
    """The number of instructions the tape of ``exprs`` would have — the operations evaluating them costs once
    every common subexpression is computed once.  Any expression can be counted: symbols and unknown
    functions count as leaves and single operations.

    >>> x, y = sp.symbols("x y")
    >>> size([sp.sin(x) ** 2 + y / sp.sin(x)]), sp.count_ops(sp.sin(x) ** 2 + y / sp.sin(x))
    (4, 5)
    """
    rec = _Recorder([], opaque=True)
    try:
        for e in exprs:
            rec.reg(sp.sympify(e))
    except RecursionError:
        raise TapeError("an expression is nested too deeply for the tape (more than ~900 levels)") from None
    return len(rec.code)


def record(exprs: Sequence, inputs: Sequence[sp.Symbol], parameters: Sequence[sp.Symbol] = (),
           definitions: Sequence[tuple[sp.Symbol, sp.Expr]] = ()) -> Program:
    """The :class:`Program` computing ``exprs`` from ``inputs`` (symbols), subexpressions computed once.

    ``parameters`` are symbols held in constant registers whose values are
    given later (:meth:`Program.with_values`): the program is recorded once
    for every set of values.  ``definitions`` are ``(symbol, expression)``
    pairs in order, each expression in the inputs, the parameters and the
    symbols defined before it: a program written as a sequence of small
    steps (a recursion over a tree of bodies) stays as long as its steps,
    where the same program as one expression would repeat them.  Raises
    :class:`TapeError` for an expression the tape cannot hold (an unknown
    function, a symbol that is neither an input, a parameter nor defined,
    a non-finite constant).

    >>> x, w = sp.symbols("x w")
    >>> record([w * w], [x], definitions=[(w, sp.sin(x) + 1)]).evaluate([0.0])
    [1.0]
    """
    rec = _Recorder(list(inputs), parameters=parameters)
    try:
        for symbol, e in definitions:
            if symbol in rec.memo:
                raise TapeError(f"the symbol {symbol} is defined twice, or is an input")
            rec.memo[symbol] = rec.reg(sp.sympify(e))
        outputs = [rec.reg(sp.sympify(e)) for e in exprs]
    except RecursionError:
        raise TapeError("an expression is nested too deeply for the tape (more than ~900 levels)") from None
    return rec.program(outputs)
