"""Bad input gets the project's own errors, never a bare TypeError, ValueError, OverflowError, KeyError or
ZeroDivisionError from NumPy, SciPy or SymPy underneath; and input that is fine simply works.

Each test is one of the failures tests/test_fuzz.py pins (found by benchmarks/fuzz.py), with ordinary values and
the message checked: it names the argument, component, node or quantity at fault.
"""

import math
import time
import warnings

import numpy as np
import pytest
import sympy as sp

import lagrangian as lg
from lagrangian.base.domain import Coordinate
from lagrangian.circuits.analogy import AnalogyError, map_model
from lagrangian.circuits.spice import netlist
from lagrangian.numerics import exosystem, linear
from lagrangian.numerics.problem import Problem
from lagrangian.numerics.simulation import initial_state


@pytest.fixture(autouse=True)
def quiet():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        yield


def oscillator(node="p", **force):
    model = lg.Model("oscillator")
    model.add("mass", "m", node, m=1.0)
    model.add("spring", "k", ("ground", node), k=4.0)
    if force:
        model.add("force", "F", node, **force)
    return model


def rc():
    model = lg.Model("rc")
    model.add("voltage_source", "V1", ("in", "0"), E=1)
    model.add("resistor", "R1", ("in", "out"), R=1)
    model.add("capacitor", "C1", ("out", "0"), C=1)
    return model


# -- names ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("nodes", [None, 1.5, b"p", {"p": 1}])
def test_nodes_that_are_neither_a_name_nor_a_tuple_of_names_are_a_model_error(nodes):
    with pytest.raises(lg.ModelError, match=r"spring 'k': nodes are a node name or a tuple of node names \(a spring "
                                            r"takes a, b\)"):
        lg.Model().add("spring", "k", nodes, k=1.0)


def test_nodes_as_a_name_a_tuple_or_a_list_still_work():
    model = lg.Model()
    model.add("mass", "m", "p", m=1.0)
    model.add("spring", "k", ["ground", "p"], k=1.0)
    model.add("damper", "c", ("p", "ground"), c=0.1)
    assert model.coordinate_names == ["x_p"]
    with pytest.raises(lg.ModelError, match="a gravity takes none: leave nodes out"):
        model.add("gravity", "g", None)


@pytest.mark.parametrize("where", ["node", "component"])
@pytest.mark.parametrize("char", ["\x00", "\x1b", "\x7f"])
def test_a_control_character_in_a_name_is_a_model_error_naming_it(where, char):
    name = f"a{char}b"
    with pytest.raises(lg.ModelError, match=r"contains the control character") as info:
        if where == "node":
            lg.Model().add("mass", "m", name, m=1.0)
        else:
            lg.Model().add("mass", name, "p", m=1.0)
    assert repr(name) in str(info.value)


def test_a_coordinate_named_with_a_nul_is_a_model_error():
    with pytest.raises(lg.ModelError, match=r"coordinate name 'x_\\x00'"):
        Coordinate.named("x_\x00")


def test_tabs_and_line_breaks_in_names_are_left_to_the_writers():
    model = oscillator("p\nq\tr")
    assert model.coordinate_names == ["x_p\nq\tr"]


@pytest.mark.parametrize("node, shown", [("%", r"\%"), ("#", r"\#"), ("a{b", r"a\{b"), ("a}b", r"a\}b"),
                                         ("$&", r"\$\&"), ("\\", r"\backslash{}"), ("~", r"\sim{}")])
def test_latex_special_characters_in_names_are_escaped(node, shown):
    model = oscillator(node)
    model.add("force", f"F{node}", node, F=sp.Symbol(f"f{node}"))
    text = model.latex()
    assert f"x_{{{shown}}}" in text and f"f{shown}" in text


@pytest.mark.parametrize("node, shown", [("%", r"\%"), ("a{b", r"a\{b"), ("$&", r"\$\&"), ("a_b", r"a\_b")])
def test_a_transfer_functions_latex_escapes_the_names_it_shows(node, shown):
    from lagrangian.frequency import transfer_function

    model = oscillator(node)
    model.add("force", "F1", node, F=0)
    text = transfer_function(model, "F1", f"x_{node}")._repr_latex_()
    assert text.startswith(f"$$\\frac{{\\text{{x\\_{shown}}}}}{{\\text{{F1}}}}(s) = ") and text.endswith("$$")


def test_latex_of_ordinary_names_is_sympys():
    model = oscillator("cart")
    model.add("damper", "c_1", ("cart", "ground"), c=sp.Symbol("c"))
    text = model.latex()
    assert sp.latex(model.lagrangian) in text and sp.latex(model.forcing) in text and sp.latex(model.rayleigh) in text


# -- numbers beyond a float ---------------------------------------------------------------------------


def test_an_initial_value_beyond_a_float_is_a_model_error():
    model = oscillator()
    with pytest.raises(lg.ModelError, match="x_p"):
        model.simulate(0.1, points=3, initial={"x_p": 10**400})
    with pytest.raises(lg.ModelError, match=r"initial value of 'x_p' must be finite"):
        initial_state(model.eq, {"x_p": 10**400}, {})
    with pytest.raises(lg.ModelError, match=r"initial velocity of 'x_p' must be finite"):
        initial_state(model.eq, {}, {"x_p": -(10**400)})


def test_a_parameter_value_beyond_a_float_is_a_model_error_naming_it():
    with pytest.raises(lg.ModelError, match=r"parameter 'k_k' must be a finite number"):
        oscillator().simulate(0.1, points=3, params={"k_k": 10**400})


# -- quantities ---------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def result():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return oscillator().simulate(0.5, points=5, initial={"x_p": 0.1}, velocity={"x_p": 0.0})


@pytest.mark.parametrize("text, why", [("1/0", "is not finite"), ("log(0)", "is not finite"),
                                       ("sqrt(-1)", "takes complex values"), ("1" * 400, "beyond a float"),
                                       ("2*x_p + sqrt(-1)", "takes complex values")])
def test_a_quantity_that_is_not_a_finite_real_is_an_expression_error(result, text, why):
    with pytest.raises(lg.ExpressionError, match=why) as info:
        result.quantity(text)
    assert repr(text if len(text) <= 80 else text[:77] + "...") in str(info.value)


def test_a_quantity_holding_an_acceleration_is_refused_as_such(result):
    """Said as what it is (it once said "an energy term depends on an acceleration"), named with primes."""
    x = lg.coordinate("x_p")
    with pytest.raises(lg.ModelError, match=r"holds an acceleration \(x_p''\).*coordinates and rates only"):
        result.quantity(0.3 * sp.diff(x, lg.t, 2) + 40.0 * x)


@pytest.mark.parametrize("text, fn", [("erfc(-t)", lambda t: math.erfc(-t)), ("erf(2*t)", lambda t: math.erf(2 * t)),
                                      ("erf(t) + erfc(t)", lambda t: 1.0)])
def test_erf_and_erfc_in_a_quantity_are_evaluated(result, text, fn):
    np.testing.assert_allclose(result.quantity(text), [fn(x) for x in result.t], rtol=1e-14)


def test_a_matrix_quantity_is_evaluated_entry_by_entry(result):
    x = oscillator().coordinates[0].function
    out = result.quantity(sp.Matrix([[x, 2], [3 * x, lg.t]]))
    assert out.shape == (2, 2, result.t.size)
    np.testing.assert_allclose(out[1, 0], 3 * result["x_p"])
    np.testing.assert_allclose(out[1, 1], result.t)


# -- analogies ----------------------------------------------------------------------------------------


def test_mapping_a_model_without_coordinates_is_an_analogy_error():
    model = lg.Model("lone")
    model.add("inductor", "L", ("a", "0"), L=1.0)
    with pytest.raises(AnalogyError, match=r"analogue of model 'lone' has no generalized coordinates .*lone inductor"):
        map_model(model, "force-voltage")


@pytest.mark.parametrize("given", ["abc", "1.5", [1.0], sp.Heaviside(lg.t), 10**400, math.nan, math.inf, None, True])
def test_a_bad_initial_value_of_an_analogue_is_a_model_error_naming_the_coordinate(given):
    mapped = map_model(oscillator(), "force-current")
    with pytest.raises(lg.ModelError, match=r"initial value of 'x_p' must be a (finite )?number"):
        mapped.initial({"x_p": given}, {})
    with pytest.raises(lg.ModelError, match=r"initial velocity of 'x_p' must be a (finite )?number"):
        mapped.initial({}, {"x_p": given})


def test_initial_values_of_an_analogue_by_unknown_names_or_not_by_name_are_refused():
    mapped = map_model(oscillator(), "force-current")
    with pytest.raises(lg.UnknownNameError, match="'y'"):
        mapped.initial({"y": 1.0}, {})
    with pytest.raises(lg.ModelError, match="initial must map names to numbers"):
        mapped.initial([1.0], {})
    assert mapped.initial({"x_p": sp.Float(0.25)}, {"x_p": np.float64(0.5)}) == ({"lambda_p": 0.25},
                                                                                {"lambda_p": 0.5})


# -- signals on NumPy and in the exact solution -------------------------------------------------------


@pytest.mark.parametrize("text", ["cot(10**30)", "acosh(10**30)", "10**30/7 * 1e-30 * t"])
@pytest.mark.parametrize("method", ["DOP853", "exact"])
def test_huge_integers_inside_a_signal_run_on_numpy_as_on_the_tape(text, method):
    model = oscillator(F=text)
    kwargs = {} if method == "exact" else {"compiled": False}
    numpy = model.simulate(0.5, points=5, method=method, initial={"x_p": 0.1}, **kwargs)
    tape = model.simulate(0.5, points=5, initial={"x_p": 0.1}, compiled="tape")
    np.testing.assert_allclose(numpy["x_p"], tape["x_p"], rtol=1e-7, atol=1e-9)


def test_a_signal_singular_at_the_start_on_numpy_is_a_numerical_error_naming_the_time():
    model = oscillator(F="1/t")
    for compiled in (False, "tape"):
        with pytest.raises(lg.NumericalError, match=r"at t=0 "):
            model.simulate(0.5, points=3, compiled=compiled, initial={"x_p": 0.1})


def test_a_signal_with_erf_runs_on_numpy():
    model = oscillator(F="erf(t)")
    numpy = model.simulate(0.5, points=5, compiled=False, initial={"x_p": 0.1})
    tape = model.simulate(0.5, points=5, compiled="tape", initial={"x_p": 0.1})
    np.testing.assert_allclose(numpy["x_p"], tape["x_p"], rtol=1e-7, atol=1e-9)


# -- a singular mass matrix, the spectrum -------------------------------------------------------------


def solenoid(m=0.417, L0=4.53e-141):
    model = lg.Model("solenoid")
    model.add("capacitor", "C", ("a", "0"), C=1)
    model.add("mass", "m", "p", m=m)
    model.add("solenoid", "S", ("a", "0", "p"), L0=L0, x0=4)
    return model


@pytest.mark.parametrize("compiled", [False, "tape"])
@pytest.mark.parametrize("method", ["BDF", "Radau", "RK45"])
def test_a_nearly_singular_mass_matrix_is_singular_on_numpy_as_on_the_tape(compiled, method):
    with pytest.raises(lg.SingularMassMatrixError, match=r"singular at t=0 .*the motion of q_S"):
        solenoid().simulate(0.0697, method=method, compiled=compiled, initial={"q_S": 552.0})


def test_an_ordinary_solenoid_still_runs_on_numpy_as_on_the_tape():
    model = solenoid(L0=1.0)
    model.add("spring", "k", ("ground", "p"), k=2.0)
    numpy = model.simulate(0.05, points=5, method="BDF", compiled=False, initial={"q_S": 0.5})
    tape = model.simulate(0.05, points=5, method="BDF", compiled="tape", initial={"q_S": 0.5})
    np.testing.assert_allclose(numpy["q_S"], tape["q_S"], rtol=1e-6)


class _Overflowing:
    """A problem whose rate overflows: SciPy's implicit methods then meet a Jacobian of infinities."""

    name = "overflowing"

    def rhs(self, t, y):
        with np.errstate(all="ignore"):
            return np.array([1e308 * y[0] * 1e10])


def test_scipys_non_finite_jacobian_is_an_integration_error():
    bdf = lg.Model().registry.integrators["BDF"]
    with np.errstate(all="ignore"):
        with pytest.raises(lg.IntegrationError, match=r"BDF failed on model 'overflowing': its Jacobian or state is "
                                                      r"not finite"):
            bdf.solve(_Overflowing(), (0.0, 1.0), np.array([1.0]), None)
        solver = bdf.start(_Overflowing(), 0.0, np.array([1.0]), 1.0)
        with pytest.raises(lg.IntegrationError, match="not finite"):
            solver.step()


def test_a_stepped_scipy_solver_still_steps():
    class Decay:
        name = "decay"

        def rhs(self, t, y):
            return -y

    solver = lg.Model().registry.integrators["BDF"].start(Decay(), 0.0, np.array([1.0]), 1.0)
    while solver.status == "running":
        solver.step()
    assert solver.status == "finished" and abs(solver.y[0] - math.exp(-1)) < 1e-3


def test_the_spectrum_of_a_linearization_past_a_float_does_not_overflow():
    model = lg.Model("two")
    model.add("mass", "m1", "a", m=1.0)
    model.add("mass", "m2", "b", m=1.0)
    problem = Problem(model.numeric(), "two")
    J = np.zeros((4, 4))
    J[0, 2] = J[1, 3] = 1.0
    J[2, 0], J[3, 1] = -3.096e-2, -2e300  # a mass of 1e-300 on a spring
    problem._central_jacobian = lambda t, y, widen=1.0: J
    spectrum = problem.spectrum(0.0, np.zeros(4))
    assert spectrum.eigenvalues.shape == (4,) and np.isfinite(spectrum.scale)


def test_auto_on_a_nearly_massless_transducer_says_the_mass_matrix_is_singular():
    model = lg.Model("solenoid")
    model.add("capacitor", "C", ("n1", "0"), C=32.3)
    model.add("mass", "m", "p", m=1e-300)
    model.add("spring", "k", ("ground", "p"), k=2)
    model.add("solenoid", "S", ("n1", "0", "p"), L0=1, x0=4)
    with pytest.raises(lg.SingularMassMatrixError, match="x_p"):
        model.simulate(0.03, method="auto")


# -- SPICE netlists -----------------------------------------------------------------------------------


@pytest.mark.parametrize("option", ["t_end", "step", "max_step"])
@pytest.mark.parametrize("value", ["1", math.nan, math.inf, -1.0, 0.0, 10**400, None, [1.0]])
def test_netlist_times_that_are_not_positive_finite_numbers_are_a_model_error(option, value):
    if value is None and option != "t_end":
        assert ".tran" in netlist(rc(), **{option: value}).text  # None: the default
        return
    with pytest.raises(lg.ModelError, match=rf"netlist: {option} must be a (finite )?positive number of seconds"):
        netlist(rc(), **{option: value})


def test_netlist_times_that_are_numbers_are_written():
    assert ".tran 0.001 2 0 0.0001 uic" in netlist(rc(), t_end=np.float64(2.0), step=1e-3).text


@pytest.mark.parametrize("value, why", [(sp.sqrt(-2), "not a real number"), (sp.I * 1e-12, "not a real number"),
                                        (sp.Float("1e400"), "finite"), (sp.exp(1000.0), "finite")])
def test_netlist_values_that_are_complex_or_beyond_a_float_are_a_model_error_naming_them(value, why):
    """A SPICE option or element value that evaluates to a complex number or beyond a float is refused by name, not a
    TypeError from SymPy's float() nor 'nan'/'inf' written into the deck."""
    with pytest.raises(lg.ModelError, match=rf"SPICE option reltol: .*{why}"):
        netlist(rc(), t_end=1e-3, options={"reltol": value})
    model = lg.Model("rc")
    model.add("voltage_source", "V1", ("n1", "0"), E=sp.sin(lg.t))
    model.add("resistor", "R1", ("n1", "n2"), R=sp.Symbol("R"))
    model.add("capacitor", "C1", ("n2", "0"), C=4.7e-6)
    with pytest.raises(lg.ModelError, match="parameter 'R'"):  # an element's value: refused as a parameter's
        netlist(model, t_end=1e-3, params={"R": value})


# -- the exact solution's budget ----------------------------------------------------------------------

NESTED = "sin(" * 10 + "t" + ")" * 10


@pytest.mark.slow
def test_an_input_that_does_not_expand_in_time_is_refused_by_the_exact_solution():
    start = time.monotonic()
    with pytest.raises(lg.ModelError, match=rf"did not expand into exponentials within {linear.EXPAND_SECONDS:g} s"):
        oscillator(F=NESTED).simulate(1e-3, points=3, method="exact")
    assert time.monotonic() - start < linear.EXPAND_SECONDS + 5


@pytest.mark.slow
def test_auto_integrates_an_input_that_does_not_expand_in_time_with_a_note():
    res = oscillator(F=NESTED).simulate(1e-3, points=3, method="auto", initial={"x_p": 0.1})
    assert res.method != "exact" and any("did not expand into exponentials" in n for n in res.notes)


def test_flat_inputs_expand_without_a_budget(monkeypatch):
    def no_budget(*args, **kwargs):
        raise AssertionError("a flat input went through the budget")

    monkeypatch.setattr(exosystem, "interruptible", no_budget)
    res = oscillator(F="sin(2*t)**2 + exp(-t)*cos(3*t + 1) + t**3").simulate(
        1.0, points=5, method="exact", initial={"x_p": 0.1})
    assert res.method == "exact"
