"""Text given where an expression is expected is read, never run.

A payload that would create a marker file if Python evaluated it goes to
every entry point that takes text (parameters, forces, impulses, momenta,
quantities, contacts); each must answer with the project's error and the
marker must never appear.  Ordinary text still reads as the expression it
writes.
"""

import math
import warnings

import numpy as np
import pytest
import sympy as sp
from hypothesis import example, given, settings
from hypothesis import strategies as st

import lagrangian as lg
from lagrangian import models, routh
from lagrangian.impulse import Impulse, ground, velocity_jump
from lagrangian.text import MAX_LENGTH, parse_expression


@pytest.fixture
def marker(tmp_path):
    path = tmp_path / "executed"
    yield path
    assert not path.exists(), "a payload ran"


def payloads(path):
    p = str(path)
    return [
        f"__import__('os').system('touch {p}')",
        f"open('{p}', 'w')",
        f"(lambda: open('{p}', 'w'))()",
        f"sin.__globals__['__builtins__']['open']('{p}', 'w')",
        f"[c for c in ().__class__.__base__.__subclasses__()]",
        f"Symbol('x').__class__",
        f"exec('open(\"{p}\", \"w\")')",
    ]


def oscillator(**params):
    model = lg.Model("oscillator")
    model.add("mass", "m", "p", m=params.get("m", 0.3))
    model.add("spring", "k", ("ground", "p"), k=params.get("k", 40))
    return model


def test_parameters_and_forces(marker):
    for text in payloads(marker):
        with pytest.raises(lg.ParameterError, match="component 'm', parameter 'm'"):
            oscillator(m=text)
        model = oscillator()
        with pytest.raises(lg.ParameterError, match="component 'F', parameter 'F'"):
            model.add("force", "F", "p", F=text)


def test_impulses_contacts_and_momenta(marker):
    pendulum = lg.Model("pendulum", dim=2)
    pendulum.add("link", "arm", "arm", points={"bob": (0.7, 0)})
    pendulum.add("revolute", "pin", ("ground", "arm"), absolute=True)
    pendulum.add("mass", "m", "arm.bob", m=0.3)
    spherical = models.spherical_pendulum(0.3, 0.7)
    for text in payloads(marker):
        with pytest.raises(lg.ModelError):
            velocity_jump(pendulum, [Impulse("arm.bob", (text, 0))], at={"theta_pin": 0.2})
        with pytest.raises(lg.ModelError):
            velocity_jump(pendulum, [{"theta_pin": text}], at={"theta_pin": 0.2})
        with pytest.raises(lg.ModelError):
            velocity_jump(pendulum, [{"theta_pin": 1.0}], at={"theta_pin": text})
        with pytest.raises(lg.ModelError):
            ground("arm.bob", level=text)
        with pytest.raises(lg.ModelError):
            routh.reduce(spherical, momenta={"theta_turn": text})


def test_quantities(marker):
    model = oscillator()
    res = model.simulate(0.5, initial={"x_p": 0.01}, velocity={"x_p": 0.0}, points=11)
    for text in payloads(marker):
        with pytest.raises(lg.ModelError):
            res.quantity(text)
    # ordinary text: coordinate names stand for the coordinates, parameters for their values
    np.testing.assert_allclose(res.quantity("k_k * x_p**2 / 2"), 40 * res["x_p"] ** 2 / 2, rtol=1e-12)


def test_ordinary_text_reads_as_written():
    t = lg.t
    k, x = sp.symbols("k x")
    assert parse_expression("k*x**2/2", "e") == k * x**2 / 2
    assert parse_expression("1e-3*sin(2*pi*50*t)", "e") == sp.Float(1e-3) * sp.sin(100 * sp.pi * t)
    assert parse_expression("3/4", "e") == sp.Rational(3, 4)
    assert parse_expression("-2**-1", "e") == -sp.Rational(1, 2)
    assert parse_expression("Abs(x) + ln(k) + max(x, k)", "e") == sp.Abs(x) + sp.log(k) + sp.Max(x, k)
    force = oscillator().add("force", "F", "p", F="0.5*cos(3*t)")
    assert force.F == sp.Float(0.5) * sp.cos(3 * t)
    pulse = sp.Piecewise((0, t <= 1e-3), (2.5, (sp.Mod(t, 0.02) < 0.01) & ~(t > 1)), (x, True))
    assert parse_expression("Piecewise((0, t <= 1e-3), (2.5, (Mod(t, 0.02) < 0.01) & ~(t > 1)), (x, True))",
                            "e") == pulse
    assert parse_expression("Piecewise((1, (t >= 2) | (t < 1)), (0, True))", "e") == \
        sp.Piecewise((1, (t >= 2) | (t < 1)), (0, True))


@pytest.mark.parametrize("text, why", [
    ("9**9**9", "not a finite number"),
    ("erfc(1e308)", r"erfc\(1\.0+e\+308\) is not a finite number"),  # SymPy evaluates it at once: mpmath overflows
    ("cot(-cosh(1e308) + 7)", r"cosh\(1\.0+e\+308\) is beyond a float's range"),  # mpmath: 10**(4e307), then recursion
    ("sec(exp(10**30)) - 0.5", r"exp\(10+\) is beyond a float's range"),  # sec of it: mpmath reduces 4e29 digits
    ("exp(710)", r"exp\(710\) is beyond a float's range"),
    ("cot(max())", r"max\(\) takes one argument or more"),  # Max() is -oo, and cot(-oo) an interval
    ("(" * 300 + "1" + ")" * 300, "nest|cannot read"),
    ("x" + "%s" * 2000, "nested too deeply to show.* is not allowed"),  # ast.parse reads it; ast.unparse recursed
    ("1" * (MAX_LENGTH + 1), "longer than"),
    ("x if x else 1", "not allowed"),
    ("sin", "is a function"),
    ("sin(x, key=1)", "plain arguments"),
    ("'text'", "not a number"),
    ("", "empty"),
    ("1 +", "cannot read"),
    ("Piecewise(1, 2)", "takes pairs"),
    ("Piecewise((1, t == 2))", "'t == 2' is not a condition"),
    ("Piecewise((1, 0 < t < 3))", "is not a condition"),
    ("Piecewise((1, t < 2 and t > 1))", "is not a condition"),
    ("Piecewise((1, __import__('os')))", "is not a condition"),
    ("Piecewise((open('x'), True))", "'open' is not a function"),
    ("Piecewise((1, t > 1), (2, t < 3), key=0)", "takes pairs"),
])
def test_what_an_expression_may_not_hold_is_named(text, why):
    with pytest.raises(lg.ExpressionError, match=why):
        parse_expression(text, "a force")


@settings(max_examples=60)
@given(st.integers(-10**6, 10**6).filter(lambda p: p not in (-1, 0, 1)), st.integers(1, 10**6),
       st.integers(65, 10**40), st.sampled_from([1, -1]))
@example(-7, 7, 10**31 + 1, 1)  # -1 to an odd power: -1, where the float of the exponent is even
def test_a_power_of_numbers_with_a_large_exponent_is_the_float_it_fits_not_computed_exactly(p, q, e, sign):
    """``(p/q)**(±e)`` with |e| beyond 64: the float ``math.pow`` gives (0.0 where it underflows), or refused where it
    overflows; never SymPy's exact rational, whose numerator or denominator would have some e digits (3**-(10**31):
    a hang)."""
    if abs(p) == q:  # ±1: exactly, by the exponent's parity
        assert parse_expression(f"({p}/{q})**({sign}*{e})", "a force") == (-1 if p < 0 and e % 2 else 1)
        return
    text = f"({p}/{q})**({sign}*{e})"
    try:
        expected = math.pow(p / q, sign * e)
    except (OverflowError, ValueError):
        expected = math.inf
    if not math.isfinite(expected):
        with pytest.raises(lg.ExpressionError, match="not a finite number"):
            parse_expression(text, "a force")
        return
    value = parse_expression(text, "a force")
    assert value.is_Float and float(value) == pytest.approx(expected, rel=1e-12, abs=0.0)


def test_a_function_of_a_large_number_that_evalf_cannot_settle_is_read_not_refused():
    """floor(1e308/pi) is within a float's range, though evalf cannot give it to 17 digits (PrecisionExhausted): the
    reader keeps it rather than raising SymPy's error."""
    value = parse_expression("floor((1e308 / --pi))", "a force")
    assert value.func == sp.floor and math.isclose(float(value.args[0]), 1e308 / math.pi, rel_tol=1e-15)


def test_a_symbols_power_beyond_64_under_functions_is_accepted_undecided_not_queried_for_ever():
    """Whether cosh(sec(x**(10**30))) is real is a question SymPy's assumptions take minutes or more on (seconds at
    x**100): the parameter's rule leaves such an expression undecided, as it does any it cannot settle."""
    model = lg.Model("cart")
    model.add("mass", "m", "p", m=0.3)
    force = model.add("force", "F", "p", F="cosh(sec(-(I ** 10**30)))")
    assert force.F.has(sp.Symbol("I"))


ALPHABET = st.sampled_from(list("()[]{}.,:;'\"\\`$|&!?_=+-*/%<>^~@# \n\t0123456789abcxyzEIO") +
                           ["__", "import", "os", "system", "lambda", "exec", "eval", "open", "class", "sin", "pi",
                            "t", "**", "globals", "subclasses", "builtins", "__import__('os')"])


@settings(max_examples=300)
@given(st.lists(ALPHABET, max_size=40).map("".join))
def test_any_text_is_an_expression_or_an_expression_error(text):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        try:
            expr = parse_expression(text, "fuzz")
        except lg.ExpressionError:
            return
    assert isinstance(expr, sp.Expr)


def test_vectors_and_matrices_read_each_entry_as_text(marker):
    for text in payloads(marker):
        for inertia in ((text, 1, 1), [[1, 0, 0], [0, text, 0], [0, 0, 1]]):
            with pytest.raises(lg.ParameterError, match="component 'b', parameter 'inertia'"):
                lg.Model("body", dim=3).add("body", "b", "b", m=1, inertia=inertia)
        with pytest.raises(lg.ParameterError, match="parameter 'com'"):
            lg.Model("body", dim=3).add("body", "b", "b", m=1, inertia=(1, 1, 1), com=(0, text, 0))
    body = lg.Model("body", dim=3).add("body", "b", "b", m=1, inertia=[["0.3", 0, 0], [0, "0.3", 0], [0, 0, "1/2"]])
    assert body.params["inertia"] == sp.diag(sp.Float(0.3), sp.Float(0.3), sp.Rational(1, 2))


def test_the_time_derivative_plugins_call_refuses_text(marker):
    from lagrangian.derivation.calculus import time_derivative, time_integral

    for text in payloads(marker):
        with pytest.raises(lg.ModelError, match="time_derivative takes a SymPy expression, not text"):
            time_derivative(text, lg.t)
        with pytest.raises(lg.ModelError, match="time_integral takes a SymPy expression, not text"):
            time_integral(text, lg.t)
    assert not marker.exists()
