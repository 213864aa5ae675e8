"""Other values for parameters given as numbers (``simulate(params=...)``, every trial point of a fit): the quick
check by :class:`lagrangian.base.overrides.Rules` refuses exactly what the rule of each parameter refuses."""

import pytest
import sympy as sp
from hypothesis import given, strategies as st

import lagrangian as lg
from lagrangian import models
from lagrangian.base.component import check_value
from lagrangian.base.overrides import Rules

VALUES = st.one_of(st.floats(allow_nan=True, allow_infinity=True),
                   st.builds(lambda s, e: s * 10.0**e, st.sampled_from([-1.0, 1.0]), st.integers(-320, 308)))


def _refused_by_rule(value, check):
    try:
        check_value(sp.Float(value), check, "c", "p")
    except lg.ParameterError:
        return True
    return False


@given(value=VALUES)
def test_a_scalar_override_is_refused_exactly_when_its_rule_refuses_it(value):
    model = models.double_pendulum(0.3, 0.2)
    rules = Rules(model.components.values())
    for symbol, owners in rules.scalar.items():
        for check, component, pname in owners:
            expected = _refused_by_rule(value, check)
            if expected:
                with pytest.raises(lg.ParameterError, match=f"component '{component}', parameter '{pname}'"):
                    rules.check({symbol: value})
            else:
                rules.check({symbol: value})


def test_an_entry_keeps_its_sign_and_the_error_names_it():
    top = models.heavy_top()
    with pytest.raises(lg.ParameterError, match="parameter 'com': entry 'com_top_2' was given as a positive number"):
        top.simulate(0.01, params={"com_top_2": -0.4}, points=2)
    with pytest.raises(lg.ParameterError, match="parameter 'inertia': entry 'inertia_top_0'"):
        top.simulate(0.01, params={"inertia_top_0": -0.1}, points=2)
    with pytest.raises(lg.ParameterError, match="parameter 'm': must be positive"):
        top.simulate(0.01, params={"m_top": -0.3}, points=2)


def test_the_rules_follow_a_model_that_changes():
    model = lg.Model("osc")
    model.add("mass", "m", "p", m=0.3)
    model.add("spring", "k", ("ground", "p"), k=40.0)
    model.simulate(0.01, initial={"x_p": 0.1}, velocity={"x_p": 0.0}, params={"k_k": 50.0}, points=2)
    model.add("damper", "c", ("ground", "p"), c=0.7)
    with pytest.raises(lg.ParameterError, match="component 'c', parameter 'c'"):
        model.simulate(0.01, initial={"x_p": 0.1}, velocity={"x_p": 0.0}, params={"c_c": -0.7}, points=2)
