"""Sizes that come from input are bounded before any work: frequency grids, output grids, and unit strings.

A five-line netlist, a ``--points`` option or a unit written in a parameter can ask for any amount of memory or
time: ``.ac dec 100000000 1 1e6`` asks for 6e8 frequencies (24 GB), ``"1 kg*9^9^9"`` for a number of 370 million
digits.  Each is refused with a :class:`lagrangian.ModelError` (a :class:`~lagrangian.ParameterError` naming the
component and parameter where a component's value is at fault) that names the size and the bound of
:data:`lagrangian.limits` it exceeds, before anything is allocated or computed; never a raw MemoryError,
TypeError or OverflowError, never a run that does not end.
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

import lagrangian as lg
from lagrangian.cli import main
from lagrangian.frequency import decades, frequency_response, linearize, sweep
from lagrangian.netlist import read_netlist
from lagrangian.scene import Scene
from lagrangian.text import parse_expression
from lagrangian.units import split, to_si

pytest.importorskip("pint")

GRID = r"grid_points = 10000000"


def msd() -> lg.Model:
    m = lg.Model("msd")
    m.add("mass", "m", "p", m=0.3)
    m.add("spring", "k", ("ground", "p"), k=40.0)
    m.add("force", "F", "p", F=0)
    return m


def deck(analysis: str) -> str:
    return f"rc filter\nV1 in 0 DC 0 AC 1\nR1 in out 1k\nC1 out 0 1u\n{analysis}\n.end\n"


# ---------------------------------------------------------------------------
# 1. .ac lines
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("line, size", [
    (".ac dec 100000000 1 1e6", r"6e\+08 points"),
    (".ac lin 100000000 1 1e6", r"1e\+08 points"),
    (".ac oct 100000000 1 1e6", r"1\.99316e\+09 points"),
    (".ac dec 1e300 1 1e6", r"6e\+300 points"),
])
def test_an_ac_line_beyond_the_bound_is_refused_as_the_deck_is_read(line, size):
    with pytest.raises(lg.ModelError, match=rf"netlist line 5 \(\.ac\): .*{size}, beyond lagrangian\.limits\.{GRID}"):
        read_netlist(deck(line))


def test_the_ac_bound_is_lagrangian_limits_and_can_be_raised():
    """``.ac dec 10 1 1e6`` is 61 frequencies: refused under a bound of 60, read under 61."""
    with lg.limits(grid_points=60), pytest.raises(lg.ModelError, match="asks for 61 points"):
        read_netlist(deck(".ac dec 10 1 1e6"))
    with lg.limits(grid_points=61):
        assert read_netlist(deck(".ac dec 10 1 1e6")).ac.frequencies.size == 61


def test_lagrangian_ac_on_a_deck_of_6e8_frequencies_fails_at_once(tmp_path, capsys):
    path = tmp_path / "huge.cir"
    path.write_text(deck(".ac dec 100000000 1 1e6"))
    assert main(["ac", str(path)]) == 1
    err = capsys.readouterr().err
    assert err.startswith("lagrangian: error: netlist line 5 (.ac)") and "6e+08 points" in err and GRID in err


def test_a_tran_output_grid_beyond_the_bound_is_refused():
    net = read_netlist(deck(".tran 1e-15 1"))
    with pytest.raises(lg.ModelError, match=rf"\.tran 1e-15 1.* asks for 1e\+15 points, beyond .*{GRID}"):
        net.simulate()


# ---------------------------------------------------------------------------
# 2. --points, decades, sweep, Scene
# ---------------------------------------------------------------------------


def test_scene_points_1e12_on_the_command_line_is_a_usage_error(tmp_path, capsys):
    path = tmp_path / "rc.cir"
    path.write_text(deck(".tran 1u 1m"))
    assert main(["scene", str(path), "-o", "q_C1", "--points", "1e12"]) == 2
    err = capsys.readouterr().err
    assert "argument --points" in err and "1e+12 points" in err and GRID in err


def test_ac_points_1e12_on_the_command_line_is_refused(tmp_path, capsys):
    path = tmp_path / "rc.cir"
    path.write_text(deck(".ac dec 10 1 1e6"))
    assert main(["ac", str(path), "--points", "1e12"]) == 1
    err = capsys.readouterr().err
    assert "6e+12 points" in err and GRID in err
    assert main(["ac", str(path), "--points", "1e12", "--sweep", "lin"]) == 1
    assert "1e+12 points" in capsys.readouterr().err


def test_points_written_with_an_exponent_are_whole_numbers_on_the_command_line(tmp_path, capsys):
    path = tmp_path / "rc.cir"
    path.write_text(deck(".ac dec 10 1 1e6"))
    assert main(["ac", str(path), "--points", "1e1", "--start", "1", "--stop", "100"]) == 0
    assert "21 frequencies" in capsys.readouterr().out


@pytest.mark.parametrize("command", ["scene", "ac"])
@pytest.mark.parametrize("text", ["2.5", "nan", "inf", "-inf", "-3", "0", "1e400", "many", "true"])
def test_points_that_are_no_whole_number_are_usage_errors(tmp_path, capsys, command, text):
    path = tmp_path / "rc.cir"
    path.write_text(deck(".tran 1u 1m\n.ac dec 10 1 1e6"))
    extra = ["-o", "q_C1"] if command == "scene" else []
    assert main([command, str(path), *extra, f"--points={text}"]) == 2
    err = capsys.readouterr().err
    assert "argument --points" in err and "whole number" in err


def test_decades_and_sweep_refuse_grids_beyond_the_bound():
    with pytest.raises(lg.ModelError, match=rf"asks for 1e\+12 points, beyond lagrangian\.limits\.{GRID}"):
        decades(1, 10, 1e12)
    with pytest.raises(lg.ModelError, match=rf"asks for 1e\+10 points, beyond lagrangian\.limits\.{GRID}"):
        sweep("lin", 1e10, 1, 2)
    with pytest.raises(lg.ModelError, match=rf"asks for about 1e400 points, beyond lagrangian\.limits\.{GRID}"):
        sweep("lin", 10**400, 1, 2)
    with pytest.raises(lg.ModelError, match="grid_points"):
        sweep("oct", 10**7, 1, 1e6)  # 10⁷ per octave, 2e8 in all
    with pytest.raises(lg.ModelError, match="grid_points"):
        decades(1e-300, 1e300, 1e306)  # the count itself overflows a float: inf points


@pytest.mark.parametrize("points", [2.5, -3, 0, math.nan, math.inf, -math.inf, True, False, np.bool_(True), "20",
                                    None, 1 + 0j])
def test_sweep_counts_that_are_no_whole_number_are_refused(points):
    for call in (lambda: decades(1, 10, points), lambda: sweep("lin", points, 1, 2), lambda: sweep("oct", points, 1, 2)):
        with pytest.raises(lg.ModelError, match="must be a whole number ≥ 1"):
            call()


def test_sweep_keeps_accepting_whole_numbers_of_any_type():
    assert decades(1, 100, 2.0).size == decades(1, 100, np.int64(2)).size == 5
    assert sweep("lin", 3.0, 10, 30).tolist() == [10.0, 20.0, 30.0]
    assert sweep("lin", 1, 10, 10).tolist() == [10.0]


@pytest.mark.parametrize("start, stop", [(math.nan, 10), (1, math.inf), (-1, 10), (0, 10), ("1", 10), (1, 10**400),
                                         (True, 10)])
def test_sweep_ends_that_are_no_frequencies_are_refused(start, stop):
    with pytest.raises(lg.ModelError, match="sweep"):
        sweep("dec", 10, start, stop)


def test_a_scene_of_1e12_points_is_refused_before_any_work():
    with pytest.raises(lg.ModelError, match=rf"asks for 1e\+12 points, beyond lagrangian\.limits\.{GRID}"):
        Scene(msd(), "x_p", 1.0, points=1e12)
    with pytest.raises(lg.ModelError, match=rf"asks for 1e\+12 points, beyond lagrangian\.limits\.{GRID}"):
        Scene(msd(), "x_p", 1.0, points=10**12)


@pytest.mark.parametrize("points", [2.5, -1, 0, math.nan, math.inf, True, "11", None])
def test_scene_points_that_are_no_whole_number_are_refused(points):
    with pytest.raises(lg.ModelError, match="points must be a positive whole number"):
        Scene(msd(), "x_p", 1.0, points=points)


def test_a_scene_keeps_its_grid_of_whole_points():
    assert Scene(msd(), "x_p", 1.0, points=np.int64(11)).grid.tolist() == np.linspace(0, 1, 11).tolist()


# ---------------------------------------------------------------------------
# 3. frequencies given to frequency_response
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("frequencies, words", [
    ([1 + 1j], "complex"),
    (np.array([1.0 + 0j]), "complex"),
    ({1.0: 2.0}, "got a dict"),
    ({"f": 1.0}, "got a dict"),
    ({1.0, 2.0}, "got a set"),
    ((f for f in [1.0]), "iterator"),
    ([True, False], "bools"),
    (["1"], "real numbers"),
    ("1k", "got a str"),
    (None, "got nothing"),
    ([object()], "real numbers"),
    ([[1.0, 2.0]], "shape"),
    ([1.0, [2.0, 3.0]], "1-D"),
    ([], "at least one"),
    ([math.nan], "finite"),
    ([1.0, math.inf], "finite"),
    ([-1.0], "≥ 0"),
    ([10**400], "real numbers"),
])
def test_frequencies_that_are_no_real_finite_sequence_are_refused(frequencies, words):
    with pytest.raises(lg.ModelError, match=f"frequencies must .*{words}|{words}"):
        frequency_response(msd(), frequencies)


def test_frequencies_that_are_real_finite_and_not_negative_are_accepted():
    lin = linearize(msd())
    expected = frequency_response(lin, [0.0, 1.0, 2.5]).H
    for given in ([0, 1, 2.5], (0, 1, 2.5), np.array([0, 1, 2.5]), np.array([0, 1, 2.5], dtype=np.float32),
                  [Fraction(0), 1, Fraction(5, 2)], [0, np.int64(1), 2.5]):
        np.testing.assert_allclose(frequency_response(lin, given).H, expected, rtol=1e-6)
    assert frequency_response(lin, 3).frequencies.tolist() == [3.0]  # one number: a grid of one


# ---------------------------------------------------------------------------
# 4. unit strings (and text) that would compute without end
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("value, words", [
    ("1 kg*9^9^9", r"exponent tower"),
    ("1 kg*10^10^10", r"exponent tower"),
    ("1 kg*9**9**9", r"exponent tower"),
    ("1 kg*m^(2^3)", r"exponent tower"),
    ("10^10^10", r"'\^' is not a power"),
    ("1 kg*m^2000", r"asks for 2000 as exponent, beyond lagrangian\.limits\.exponent = 1024"),
    ("1 kg*m^-2000", r"asks for 2000 as exponent, beyond lagrangian\.limits\.exponent = 1024"),
    ("1 kg*((m^100)^100)", r"asks for 10000 as exponent, beyond lagrangian\.limits\.exponent = 1024"),
    ("1 kg*m^1e400", r"asks for inf as exponent"),
    ("1 kg*1e300^2", r"beyond a float's range"),
    ("1 kg*1e400", r"beyond a float's range"),
    ("1e400 kg", r"the number '1e400' in '1e400 kg' is beyond a float's range"),
    ("1e400", r"'1e400' is not finite: it is beyond a float's range"),
    ("1e308 Mg", r"beyond a float's range"),
])
def test_unit_strings_of_a_parameter_are_bounded_before_pint_computes_them(value, words):
    with pytest.raises(lg.ParameterError, match=rf"component 'm', parameter 'm': .*{words}") as info:
        lg.Model("a").add("mass", "m", "p", m=value)
    assert (info.value.component, info.value.parameter) == ("m", "m")


def test_unit_strings_given_to_simulate_are_bounded():
    with pytest.raises(lg.ParameterError, match=r"component 'm', parameter 'm': .*exponent tower"):
        msd().simulate(1, params={"m_m": "1 kg*9^9^9"})
    with pytest.raises(lg.ModelError, match=r"initial value of 'x_p': .*exponent tower"):
        msd().simulate(1, initial={"x_p": "2 m*10^10^10"})
    with pytest.raises(lg.ModelError, match=r"initial value of 'x_p': .*beyond a float's range"):
        msd().simulate(1, initial={"x_p": "1e400 m"})


def test_the_exponent_bound_is_lagrangian_limits_and_can_be_raised():
    with pytest.raises(lg.ModelError, match="exponent"):
        to_si("3 kg*m^2000/m^2000", "kg", "mass")
    with lg.limits(exponent=2000):
        assert to_si("3 kg*m^2000/m^2000", "kg", "mass") == 3.0


def test_ordinary_units_still_read():
    assert to_si("2 g/cm^3", "kg/m^3", "density") == pytest.approx(2000.0)
    assert to_si("1 km^-2", "", "x") == pytest.approx(1e-6)
    assert to_si("4 m^(1/2)", "", "x") == 4.0
    assert to_si("5 kg m²/s²", "J", "energy") == 5.0
    assert to_si("1 m^1024", "", "x") == 1.0
    assert lg.Model("a").add("mass", "m", "p", m="3e5").params["m"] == 3e5  # not 3 of a unit 'e5'


def test_split_reads_the_number_whole():
    assert split("1e400") is None and split("1e5") is None  # numbers, without a unit
    assert split("1e400 m") == (math.inf, "m")  # to_si refuses it
    assert split("2em") == (2.0, "em") and split("1e3m") == (1000.0, "m")
    with pytest.raises(lg.ModelError, match="beyond a float's range"):
        to_si("1e400 m", "m", "length")


@pytest.mark.parametrize("text, words", [
    ("x**9**9**9", r"the power 9\*\*387420489 is not a finite number"),
    ("2^10^10", r"'\^' is not a power in an expression .* write \*\* for a power, as in '2\*\*10\*\*10'"),
    ("x^2", r"'\^' is not a power"),
    ("2*1e400", r"the number '1e400' is not finite"),
])
def test_text_powers_are_refused_clearly(text, words):
    with pytest.raises(lg.ExpressionError, match=words):
        parse_expression(text, "a force")


UNITS = {"kg": 0, "m": 0, "s": 0, "N": 0, "g": -3, "km": 3}  # each unit's SI factor, as a power of ten
NUMBERS = ["9", "10", "2.5", "1e300"]


@st.composite
def unit_strings(draw):
    """``(text, items)``: a number, then units and numbers joined by ``*``, ``/`` or a space, each perhaps raised
    with ``^`` or ``**`` to an exponent (small or beyond the bound, perhaps in parentheses, perhaps a tower)."""
    number = draw(st.floats(1e-3, 1e3))
    items = []
    for i in range(draw(st.integers(1, 4))):
        base = draw(st.sampled_from([*UNITS, *NUMBERS])) if i else draw(st.sampled_from(list(UNITS)))
        exponent = draw(st.one_of(st.none(), st.integers(-4, 4), st.integers(-3000, 3000),
                                  st.tuples(st.integers(-12, 12), st.integers(0, 12))))
        op = draw(st.sampled_from(["^", "**"]))
        join = draw(st.sampled_from(["*", "/", " "])) if i else ""
        if exponent is None:
            written = base
        elif isinstance(exponent, tuple):
            written = f"{base}{op}{exponent[0]}{op}{exponent[1]}"
        elif draw(st.booleans()):
            written = f"{base}{op}({exponent})"
        else:
            written = f"{base}{op}{exponent}"
        items.append((join, base, exponent, written))
    return number, items


@settings(max_examples=200)
@given(unit_strings())
@example((1.0, [("", "kg", None, "kg"), ("*", "9", (9, 9), "9^9^9")]))
@example((2.0, [("", "m", None, "m"), ("*", "10", (10, 10), "10^10^10")]))
@example((1.5, [("", "km", 102, "km^102")]))
def test_unit_strings_give_their_value_or_a_library_error(drawn):
    """Never a hang, never a foreign exception: the finite SI value (equal to one computed here, when its exponents
    are small) or a ModelError."""
    number, items = drawn
    text = f"{number!r} " + "".join(f"{join}{written}" for join, _, _, written in items)
    try:
        value = to_si(text, "", "the value")
    except lg.ModelError:
        value = None
    if value is not None:
        assert math.isfinite(value)
    towers = any(isinstance(e, tuple) for _, _, e, _ in items)
    numbers = any(base in NUMBERS for _, base, _, _ in items)
    large = any(isinstance(e, int) and abs(e) > 1024 for _, _, e, _ in items)
    if towers or large:
        assert value is None, text
        return
    if numbers:  # pint refuses a unit multiplied by a number (unless they cancel): a ModelError, or a value
        return
    decade = sum((-1 if join == "/" else 1) * UNITS[base] * (1 if e is None else e) for join, base, e, _ in items)
    if all(e is None or 1 <= abs(e) <= 4 for _, _, e, _ in items):
        assert value is not None, text  # small exponents: always a value (pint refuses a lone kg^0: KeyError)
    if value is not None and abs(decade) < 290:  # (pint may overflow on the way to a finite value: km^200*g^200)
        assert value == pytest.approx(number * 10.0**decade, rel=1e-9), text
