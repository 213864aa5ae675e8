"""Tapes (lagrangian.tape): recording SymPy expressions as straight-line programs, and running them.

What is tested:

- every operation of ``tape.OPS``, run by the C interpreter (``codegen.run_program``), by the Python
  reference interpreter (``Program.evaluate``) and as printed C (``Program.c_lines`` compiled here),
  at seeded random points inside each function's domain plus the special points (0 for ``sign`` and
  ``Heaviside``, integers for ``floor``, equal operands for ``Eq``, …);
- the shape of the recorded code: common subexpressions computed once, powers by squaring;
- the errors (``TapeError``) for what a tape cannot hold, and the input checks of ``run_program``;
- edge programs: no inputs, outputs that are inputs or constants, many outputs, more registers than
  the interpreter keeps on the stack.

Expected values never come from the code under test: they are SymPy's own numeric evaluation of the
expression (the inputs substituted as exact binary Floats, then ``evalf`` to 30 digits, so the reference
is the correctly rounded value), or plain ``math`` for the large programs.  Nothing asserts on wall time.
"""

from __future__ import annotations

import ctypes
import math
import subprocess
import zlib
from dataclasses import dataclass, field

import numpy as np
import pytest
import sympy as sp

import lagrangian as lg
from lagrangian import codegen, tape
from lagrangian.tape import TapeError, record

needs_cc = pytest.mark.skipif(codegen.compiler() is None, reason="no C compiler on this machine")

X, Y, Z = sp.symbols("x y z")
INPUTS = (X, Y, Z)  # every case is recorded over these three inputs (unused ones are harmless)
RTOL, ATOL = 1e-12, 1e-14


@pytest.fixture(scope="module", autouse=True)
def cache(tmp_path_factory):
    """A private cache directory for the runtime library (compiled once, on first use); restored afterwards."""
    codegen.set_cache_dir(tmp_path_factory.mktemp("cache"))
    yield
    codegen.set_cache_dir(None)


# ---------------------------------------------------------------------------
# The independent reference: SymPy's own evaluation
# ---------------------------------------------------------------------------


def reference(expr, symbols, point, digits: int = 30) -> float:
    """SymPy's value of ``expr`` at ``point``: the inputs as exact Floats, evaluated to ``digits`` digits."""
    subs = {s: sp.Float(float(v), digits) for s, v in zip(symbols, point)}
    value = sp.sympify(expr).xreplace(subs).evalf(digits)
    if value is sp.nan:
        return math.nan
    assert value.is_real, f"SymPy's value of {expr} at {point} is not real: {value}"
    return float(value)


def references(exprs, symbols, points) -> np.ndarray:
    return np.array([[reference(e, symbols, p) for e in exprs] for p in points], dtype=float).reshape(len(points), len(exprs))


def op_rows(prog: tape.Program, name: str) -> np.ndarray:
    """The instructions of ``prog`` performing operation ``name``."""
    return prog.code[prog.code[:, 0] == tape.CODE[name]]


def op_names(prog: tape.Program) -> set[str]:
    names = list(tape.OPS)
    return {names[k] for k in prog.code[:, 0].tolist()}


# ---------------------------------------------------------------------------
# The cases: expressions of x, y, z with the domain the points are drawn from
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class Case:
    id: str
    exprs: tuple
    domain: dict = field(default_factory=dict)  # symbol → (low, high); (-1, 1) when not given
    extra: tuple = ()  # special points (x, y, z), added to the random ones
    n: int = 8

    def points(self) -> np.ndarray:
        rng = np.random.default_rng(zlib.crc32(self.id.encode()))  # seeded per case: independent of the order
        pts = np.column_stack([rng.uniform(*self.domain.get(s, (-1.0, 1.0)), size=self.n) for s in INPUTS])
        return np.vstack([pts, np.array(self.extra, dtype=float).reshape(-1, 3)])


R = sp.Rational
POS = (0.1, 4.0)

CASES = [
    Case("arithmetic", (3 * X**2 - 2 * X * Y + R(5, 7) * Y - 1.25, (X - 2 * Y) / (X**2 + 1) - Z / 3, -X, -(X * Y) / Z,
                        X - Y - Z, -X - Y - 1, 1 / X - 2 / (Y * Z), sp.Float("0.1") * X + R(-3, 4), -2.5 * X * Y * Z + 7),
         {X: (-3, 3), Y: (-3, 3), Z: (0.5, 3)}, extra=((-1.5, 2.0, 0.75),)),
    Case("integer powers", (X**2, X**7, X**-3, (X + Y) ** 5, X**-2 * Y**3, Y / X**4, X**3 - 2 * X**-1),
         {X: (0.3, 2), Y: (-2, 2)}, extra=((-0.7, 1.3, 0), (-1.9, -0.4, 0))),
    Case("half-integer powers", (X ** R(3, 2), X ** R(-1, 2), sp.sqrt(X), X ** R(5, 2) * Y, Y / X ** R(3, 2), sp.sqrt(X * Y + 1)),
         {X: POS, Y: (0, 3)}),
    Case("real powers", (X**0.3, X**Y, X**-1.7, 2**X, X ** R(1, 3), Y * X**-0.3), {X: POS, Y: (-2, 2)}),
    Case("exp and log", (sp.exp(X), sp.exp(-X**2), sp.log(X), sp.log(X, 2), sp.log(X * Y + 1), sp.exp(sp.log(X) / 3)),
         {X: POS, Y: (0, 3)}),
    Case("trigonometric", (sp.sin(X), sp.cos(X), sp.tan(X), sp.atan(3 * X), sp.sin(X) * sp.cos(Y) - sp.tan(X * Y)),
         {X: (-1.3, 1.3), Y: (-1, 1)}),
    Case("inverse trigonometric", (sp.asin(X), sp.acos(X), sp.asin(X) + sp.acos(Y)), {X: (-0.99, 0.99), Y: (-0.99, 0.99)}),
    Case("hyperbolic", (sp.sinh(X), sp.cosh(X), sp.tanh(X), sp.asinh(X)), {X: (-3, 3)}),
    Case("inverse hyperbolic", (sp.atanh(X), sp.acosh(Y)), {X: (-0.99, 0.99), Y: (1.01, 5)}),
    Case("atan2", (sp.atan2(Y, X), sp.atan2(X, Y) + sp.atan2(-Y, X)), {X: (-2, 2), Y: (-2, 2)},
         extra=((-1, 1, 0), (-1, -1, 0), (1, -1, 0))),
    Case("abs and sign", (sp.Abs(X), sp.sign(X), sp.Abs(X - Y) * sp.sign(Y)), {X: (-2, 2), Y: (-2, 2)},
         extra=((0, 0, 0), (0, -1, 0), (-0.5, 0, 0))),
    Case("floor and ceiling", (sp.floor(X), sp.ceiling(X), sp.floor(X / Y) + sp.ceiling(2 * Y)), {X: (-5, 5), Y: (0.5, 3)},
         extra=((-2, 1, 0), (3, 1.5, 0), (-0.5, 2, 0))),
    Case("min and max", (sp.Min(X, Y, Z), sp.Max(X, Y, Z), sp.Min(X, 2), sp.Max(-X, Y), sp.Max(sp.Min(X, Y), Z)),
         {X: (-3, 3), Y: (-3, 3), Z: (-3, 3)}, extra=((1, 1, 1), (2, 2, -5))),
    Case("mod", (sp.Mod(X, Y), sp.Mod(X, 3), sp.Mod(X, -3)), {X: (-10, 10), Y: (0.5, 4)},
         extra=((-7, 3, 0), (7, -3, 0), (-7.5, 3, 0), (6, 3, 0), (-10, -4, 0))),
    Case("error functions", (sp.erf(X), sp.erfc(X), sp.erf(X) * sp.erfc(Y)), {X: (-3, 3), Y: (-3, 3)}),
    Case("gamma", (sp.gamma(X), sp.loggamma(Y)), {X: (0.2, 6), Y: (0.2, 8)},
         extra=((-2.5, 0.5, 0), (-0.5, 10, 0), (5, 3, 0))),
    Case("heaviside", (sp.Heaviside(X), sp.Heaviside(X, 1), sp.Heaviside(X, 0), sp.Heaviside(X - Y) * Y),
         {X: (-2, 2), Y: (-2, 2)}, extra=((0, 0, 0), (0, 1, 0), (1, 1, 0))),
    Case("piecewise", (sp.Piecewise((X**2, X < 0), (sp.sin(X), X <= 1), (1 / X, True)),
                       sp.Piecewise((Y, X > 2), (-Y, True))),
         {X: (-3, 3), Y: (-1, 1)}, extra=((-1, 0.5, 0), (0, 0.5, 0), (1, 0.5, 0), (2, 0.5, 0), (2.5, 0.5, 0))),
    Case("relations", (sp.Piecewise((1, X > Y), (2, X >= 1), (3, sp.Eq(X, Y)), (4, sp.Ne(X, 0)), (5, X <= -1), (6, True)),
                       sp.Piecewise((X, X < Y), (Y, True)), sp.Piecewise((7, sp.Eq(X, 1)), (8, True))),
         {X: (-2, 2), Y: (-2, 2)}, extra=((1, 1, 0), (0, 0, 0), (0, 1, 0), (-1, 3, 0), (1.5, 2, 0), (1, 3, 0))),
    Case("boolean conditions", (sp.Piecewise((X, (X > 0) & (Y > 0)), (Y, (X < -1) | (Y >= 0.5)),
                                             (X * Y, sp.Not((X > -0.5) & (Y > -0.5))), (1, True)),
                                sp.Piecewise((1, (X > 0) & (Y > 0) & (Z > 0)), (2, sp.Not((X > 0) | (Z > 0))), (3, True))),
         {X: (-2, 2), Y: (-2, 2), Z: (-2, 2)}, n=16, extra=((0.5, 0.5, 0.5), (-2, 0, 0), (-0.2, -1, -1), (-0.2, 0.2, 0))),
    Case("constants", (sp.pi * X + sp.E, sp.sin(1) * X, sp.sqrt(2) + X, sp.pi, sp.exp(1) ** 2 - sp.log(3) * Y,
                       sp.EulerGamma + sp.Catalan * X + sp.GoldenRatio, sp.cos(sp.pi / 7) * X**2),
         {X: (-2, 2), Y: (-2, 2)}),
]
CASE_PARAMS = [pytest.param(c, id=c.id) for c in CASES]

# A Piecewise with no True branch: no condition met → NaN (SymPy's value).
NO_TRUE_BRANCH = Case("piecewise without True", (sp.Piecewise((X, X > 0)), sp.Piecewise((X, X > 1), (Y**2, Y < 0))),
                      {X: (-2, 2), Y: (-2, 2)}, extra=((-1, 1, 0), (0.5, 1, 0), (2, 1, 0), (0.5, -1, 0)))
ALL_CASE_PARAMS = [*CASE_PARAMS, pytest.param(NO_TRUE_BRANCH, id=NO_TRUE_BRANCH.id)]


_EXPECTED: dict[str, np.ndarray] = {}


def expected(case: Case) -> np.ndarray:
    """SymPy's values of the case's expressions at its points (computed once per case)."""
    if case.id not in _EXPECTED:
        _EXPECTED[case.id] = references(case.exprs, INPUTS, case.points())
    return _EXPECTED[case.id]


def test_cases_cover_every_operation():
    used = set().union(*(op_names(record(c.exprs, INPUTS)) for c in CASES))
    assert used == set(tape.OPS), f"operations no case exercises: {sorted(set(tape.OPS) - used)}"


@needs_cc
@pytest.mark.parametrize("case", ALL_CASE_PARAMS)
@pytest.mark.slow
def test_interpreter_matches_sympy(case):
    prog = record(case.exprs, INPUTS)
    got = codegen.run_program(prog, case.points())
    np.testing.assert_allclose(got, expected(case), rtol=RTOL, atol=ATOL)


@pytest.mark.parametrize("case", ALL_CASE_PARAMS)
def test_python_reference_matches_sympy(case):
    prog = record(case.exprs, INPUTS)
    got = np.array([prog.evaluate(p) for p in case.points()])
    np.testing.assert_allclose(got, expected(case), rtol=RTOL, atol=ATOL)


@pytest.mark.parametrize("case", ALL_CASE_PARAMS)
def test_numpy_arrays_match_sympy(case):
    """Program.evaluate_many (every operation on arrays of all the points at once) against SymPy's values."""
    prog = record(case.exprs, INPUTS)
    got = prog.evaluate_many(np.array(case.points(), dtype=float).T).T
    np.testing.assert_allclose(got, expected(case), rtol=RTOL, atol=ATOL)


@pytest.mark.parametrize("expr, at, value", [
    pytest.param(sp.Heaviside(X), 0.0, 0.5, id="Heaviside(0)=1/2"), pytest.param(sp.sign(X), 0.0, 0.0, id="sign(0)=0"),
    pytest.param(sp.Mod(X, -3), 7.0, -2.0, id="Mod(7,-3)=-2"), pytest.param(sp.Min(X, 1, -4), 0.0, -4.0, id="Min")])
def test_numpy_arrays_keep_the_special_values(expr, at, value):
    assert record([expr], INPUTS).evaluate_many(np.array([[at], [0.0], [0.0]]))[0, 0] == value


# Values that follow from the definitions (SymPy's conventions): checked in both interpreters.
SPECIAL_VALUES = [
    pytest.param(sp.Heaviside(X), 0.0, 0.5, id="Heaviside(0)=1/2"),
    pytest.param(sp.Heaviside(X, 1), 0.0, 1.0, id="Heaviside(0,1)=1"),
    pytest.param(sp.sign(X), 0.0, 0.0, id="sign(0)=0"),
    pytest.param(sp.sign(X), -3.0, -1.0, id="sign(-3)=-1"),
    pytest.param(sp.Mod(X, 3), -7.0, 2.0, id="Mod(-7,3)=2"),
    pytest.param(sp.Mod(X, -3), 7.0, -2.0, id="Mod(7,-3)=-2"),
    pytest.param(sp.floor(X), -2.5, -3.0, id="floor(-2.5)=-3"),
    pytest.param(sp.ceiling(X), -2.5, -2.0, id="ceiling(-2.5)=-2"),
    pytest.param(sp.Min(X, 1, -4), 0.0, -4.0, id="Min(0,1,-4)=-4"),
]


@pytest.mark.parametrize("expr, at, value", SPECIAL_VALUES)
def test_special_values(expr, at, value):
    assert reference(expr, [X], [at]) == value  # SymPy agrees with the convention
    prog = record([expr], [X])
    assert prog.evaluate([at]) == [value]
    if codegen.compiler() is not None:
        assert codegen.run_program(prog, [[at]]).tolist() == [[value]]


@needs_cc
def test_piecewise_without_true_branch_is_nan_when_no_condition_holds():
    prog = record([sp.Piecewise((X, X > 0))], [X])
    assert math.isnan(codegen.run_program(prog, [[-1.0]])[0, 0])
    assert codegen.run_program(prog, [[2.0]])[0, 0] == 2.0


# A branch not taken may be outside its function's domain: the C interpreter computes it (NaN) and discards it.
UNTAKEN = [sp.Piecewise((sp.sqrt(X), X >= 0), (-X, True)), sp.Piecewise((sp.log(X), X > 0), (0, True)),
           sp.Piecewise((sp.acosh(X), X >= 1), (X, True))]


@needs_cc
def test_interpreter_discards_untaken_branches_outside_their_domain():
    points = np.array([[-4.0], [0.5], [9.0]])
    prog = record(UNTAKEN, [X])
    np.testing.assert_allclose(codegen.run_program(prog, points), references(UNTAKEN, [X], points), rtol=RTOL, atol=ATOL)


def test_python_reference_discards_untaken_branches_outside_their_domain():
    points = np.array([[-4.0], [0.5], [9.0]])
    prog = record(UNTAKEN, [X])
    got = np.array([prog.evaluate(p) for p in points])
    np.testing.assert_allclose(got, references(UNTAKEN, [X], points), rtol=RTOL, atol=ATOL)


# ---------------------------------------------------------------------------
# The shape of the code: subexpressions once, powers by squaring
# ---------------------------------------------------------------------------


def test_common_subexpression_computed_once():
    expr = sp.sin(X) ** 2 + sp.cos(sp.sin(X)) + 3 * sp.sin(X)
    prog = record([expr], [X])
    sin_rows = op_rows(prog, "sin")
    assert len(sin_rows[sin_rows[:, 2] == 0]) == 1  # sin applied to x (input register 0) once
    assert len(sin_rows) == 1
    assert prog.evaluate([0.7])[0] == pytest.approx(reference(expr, [X], [0.7]), rel=1e-14)


def test_common_subexpressions_shared_across_outputs():
    s = sp.sin(X * Y)
    exprs = [s + 1, s**2, sp.exp(s) * Y, sp.cos(X * Y) - s]
    prog = record(exprs, [X, Y])
    muls = op_rows(prog, "mul")
    x_times_y = [r for r in muls.tolist() if sorted(r[2:4]) == [0, 1]]
    assert len(x_times_y) == 1
    assert len(op_rows(prog, "sin")) == 1
    assert len(op_rows(prog, "cos")) == 1
    got = np.array(prog.evaluate([0.4, -1.3]))
    np.testing.assert_allclose(got, references(exprs, [X, Y], [[0.4, -1.3]])[0], rtol=RTOL)


def test_integer_power_by_squaring():
    prog = record([X**8], [X])
    assert len(op_rows(prog, "mul")) == 3 and len(op_rows(prog, "pow")) == 0
    assert len(prog.code) == 3
    assert prog.evaluate([1.7])[0] == pytest.approx(1.7**8, rel=1e-15)


def test_powers_of_one_base_reuse_each_other():
    prog = record([X**2, X**4, X**8], [X])
    assert len(op_rows(prog, "mul")) == 3 and len(prog.code) == 3


def test_negative_integer_power_is_one_division():
    prog = record([X**-3], [X])
    assert len(op_rows(prog, "div")) == 1 and len(op_rows(prog, "mul")) == 2 and len(op_rows(prog, "pow")) == 0
    assert prog.evaluate([1.3])[0] == pytest.approx(1.3**-3, rel=1e-15)


def test_half_integer_power_is_a_square_root():
    prog = record([X ** R(3, 2)], [X])
    assert len(op_rows(prog, "sqrt")) == 1 and len(op_rows(prog, "pow")) == 0
    prog = record([X ** R(-1, 2)], [X])
    assert len(op_rows(prog, "sqrt")) == 1 and len(op_rows(prog, "div")) == 1 and len(op_rows(prog, "pow")) == 0


def test_quotient_of_products_is_one_division():
    prog = record([X * Y / (Z**2 * (X + 1))], [X, Y, Z])
    assert len(op_rows(prog, "div")) == 1


def test_constants_deduplicated():
    prog = record([2.5 * X + 2.5 * Y, 2.5 - X, sp.Float(0.0) * 1 + Y, -0.0 + X * 0.5], [X, Y])
    assert sorted(prog.constants.tolist()) == sorted(set(prog.constants.tolist()))


# ---------------------------------------------------------------------------
# Errors
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("expr, words", [
    pytest.param(sp.besselj(0, X), "besselj", id="unknown function"),
    pytest.param(sp.Integral(X * Y, (Y, 0, 1)), "Integral", id="unevaluated integral"),
    pytest.param(X + sp.Symbol("stiffness"), "stiffness", id="symbol not an input"),
    pytest.param(X + sp.zoo, "ComplexInfinity", id="zoo"),
    pytest.param(X * sp.oo, "non-finite", id="oo"),
    pytest.param(-sp.oo + sp.Integer(0), "non-finite", id="-oo"),
    pytest.param(sp.nan, "non-finite", id="nan"),
    pytest.param(X + sp.I, "ImaginaryUnit", id="imaginary unit"),
    pytest.param(sp.Function("f")(X) + 1, "Python callable", id="applied undefined function"),
    pytest.param(sp.Derivative(sp.Function("g")(X), X), "Python callable", id="derivative of a signal"),
])
def test_what_a_tape_cannot_hold(expr, words):
    with pytest.raises(TapeError, match=words):
        record([sp.sin(X), expr], [X])


def test_duplicated_inputs():
    with pytest.raises(TapeError, match="distinct"):
        record([X + Y], [X, Y, X])


@needs_cc
@pytest.mark.parametrize("rows", [np.zeros((3, 3)), np.zeros((3, 1)), [0.1, 0.2, 0.3], [0.1]])
def test_run_program_checks_the_number_of_inputs(rows):
    prog = record([X + Y], [X, Y])
    with pytest.raises(lg.ModelError, match="2 inputs"):
        codegen.run_program(prog, rows)


# ---------------------------------------------------------------------------
# Edge programs
# ---------------------------------------------------------------------------


@needs_cc
def test_program_without_inputs():
    exprs = [sp.Integer(3), sp.pi, sp.sin(1) + sp.sqrt(2), R(1, 3), sp.exp(sp.Rational(1, 2)) * sp.log(7)]
    prog = record(exprs, [])
    want = [reference(e, [], []) for e in exprs]
    assert prog.n_inputs == 0
    np.testing.assert_allclose(codegen.run_program(prog, np.zeros((4, 0))), [want] * 4, rtol=RTOL)
    np.testing.assert_allclose(prog.evaluate([]), want, rtol=RTOL)


@needs_cc
def test_outputs_that_are_inputs_or_constants():
    exprs = [Y, sp.Float(2.5), X, X, sp.Integer(0), -sp.Integer(4)]
    prog = record(exprs, [X, Y])
    assert len(prog.code) == 0
    points = np.array([[1.5, -2.0], [0.0, 7.25]])
    want = references(exprs, [X, Y], points)
    np.testing.assert_array_equal(codegen.run_program(prog, points), want)
    np.testing.assert_array_equal([prog.evaluate(p) for p in points], want)


@needs_cc
def test_one_row_in_one_row_out():
    exprs = [X * sp.exp(Y), Y - X]
    prog = record(exprs, [X, Y])
    out = codegen.run_program(prog, [0.3, -0.8])
    assert out.shape == (2,)
    np.testing.assert_allclose(out, references(exprs, [X, Y], [[0.3, -0.8]])[0], rtol=RTOL)


@needs_cc
def test_many_outputs():
    exprs = [sp.sin(k * X) + k * Y**2 - R(k, 7) for k in range(300)]
    prog = record(exprs, [X, Y])
    assert prog.n_outputs == 300
    points = np.array([[0.3, 1.1], [-2.0, 0.25]])
    want = np.array([[math.sin(k * x) + k * y**2 - k / 7 for k in range(300)] for x, y in points])
    np.testing.assert_allclose(codegen.run_program(prog, points), want, rtol=RTOL, atol=1e-13)
    np.testing.assert_allclose([prog.evaluate(p) for p in points], want, rtol=RTOL, atol=1e-13)


@needs_cc
@pytest.mark.slow
def test_large_program_beyond_the_stack_registers():
    n = 3000
    exprs = [sp.Add(*(sp.sin(k * X) for k in range(1, n + 1))) + X * Y,
             sp.Add(*(sp.cos(k * Y) * sp.sin(X + k) for k in range(1, 200)))]
    prog = record(exprs, [X, Y])
    assert prog.n_registers > 4096  # the interpreter's registers on the heap, not the stack
    points = np.array([[0.3, 2.0], [-1.7, 0.4], [2.9, -3.1]])

    def by_math(x, y):
        return [math.fsum(math.sin(k * x) for k in range(1, n + 1)) + x * y,
                math.fsum(math.cos(k * y) * math.sin(x + k) for k in range(1, 200))]

    want = np.array([by_math(*p) for p in points])
    # a sum of thousands of terms of size 1: rounding of the order of n·eps in absolute terms
    np.testing.assert_allclose(codegen.run_program(prog, points), want, rtol=0, atol=1e-10)
    np.testing.assert_allclose([prog.evaluate(p) for p in points], want, rtol=0, atol=1e-10)


# ---------------------------------------------------------------------------
# Printed C (Program.c_lines), compiled here
# ---------------------------------------------------------------------------


@pytest.fixture(scope="module")
def printed(tmp_path_factory):
    """One shared library with one function ``void case_K(const double *in, double *out)`` per case, from
    ``c_lines`` (inputs spelled ``in[0]``, ``in[1]``, …; targets ``out[k]``)."""
    parts = ["#include <math.h>"]
    for k, case in enumerate(CASES):
        prog = record(case.exprs, INPUTS)
        lines = prog.c_lines({i: f"in[{i}]" for i in range(prog.n_inputs)},
                             [f"out[{j}]" for j in range(prog.n_outputs)], indent="    ")
        parts += [f"void case_{k}(const double *in, double *out) {{", *lines, "}"]
    work = tmp_path_factory.mktemp("printed")
    src, lib = work / "cases.c", work / "cases.so"
    src.write_text("\n".join(parts) + "\n")
    # -ffp-contract=off: no fused a*b+c, so that the comparison with the interpreter is exact on every machine
    done = subprocess.run([codegen.compiler(), "-O2", "-shared", "-fPIC", "-ffp-contract=off", "-o", str(lib), str(src), "-lm"],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    return ctypes.CDLL(str(lib))


def call_printed(lib, k: int, prog: tape.Program, points: np.ndarray) -> np.ndarray:
    fn = getattr(lib, f"case_{k}")
    fn.argtypes, fn.restype = [ctypes.c_void_p, ctypes.c_void_p], None
    out = np.empty((len(points), prog.n_outputs))
    for i, p in enumerate(points):
        row, res = np.ascontiguousarray(p, dtype=float), np.empty(prog.n_outputs)
        fn(row.ctypes.data, res.ctypes.data)
        out[i] = res
    return out


@needs_cc
@pytest.mark.parametrize("k", range(len(CASES)), ids=[c.id for c in CASES])
def test_printed_c_agrees_with_the_interpreter(printed, k):
    case = CASES[k]
    prog = record(case.exprs, INPUTS)
    points = case.points()
    got = call_printed(printed, k, prog, points)
    np.testing.assert_allclose(got, codegen.run_program(prog, points), rtol=1e-14, atol=1e-300)
    np.testing.assert_allclose(got, expected(case), rtol=RTOL, atol=ATOL)  # and with SymPy, independently


@needs_cc
def test_printed_c_spells_a_nan_constant(tmp_path):
    # The NaN constant a Piecewise without True branch needs (built by hand, to test the printing alone):
    # out = select(x > 0, x, NaN).
    gt, sel = tape.CODE["gt"], tape.CODE["select"]
    prog = tape.Program(1, np.array([0.0, math.nan]), np.array([[gt, 3, 0, 1, 0], [sel, 4, 3, 0, 2]], dtype=np.int32),
                        np.array([4], dtype=np.int32))
    assert prog.evaluate([2.0]) == [2.0] and math.isnan(prog.evaluate([-1.0])[0])
    src, lib = tmp_path / "nan.c", tmp_path / "nan.so"
    src.write_text("\n".join(["#include <math.h>", "void f(const double *in, double *out) {",
                              *prog.c_lines({0: "in[0]"}, ["out[0]"]), "}"]) + "\n")
    done = subprocess.run([codegen.compiler(), "-O2", "-shared", "-fPIC", "-o", str(lib), str(src), "-lm"],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    fn = ctypes.CDLL(str(lib)).f
    fn.argtypes, fn.restype = [ctypes.c_void_p, ctypes.c_void_p], None
    row, out = np.array([-1.0]), np.empty(1)
    fn(row.ctypes.data, out.ctypes.data)
    assert math.isnan(out[0])
