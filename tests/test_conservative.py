"""Whether a run's energy is conserved (``Problem._conservative``, which the energy check reads): the verdicts of
physics, reached from the energy tape's evidence or from the symbolic test where the evidence is silent."""

import sympy as sp

import lagrangian as lg
from lagrangian import models
from lagrangian.numerics.problem import Problem


def oscillator(**extra):
    m = lg.Model("oscillator")
    m.add("mass", "m", "p", m=0.3)
    m.add("spring", "k", ("ground", "p"), k=40.0)
    for kind, name, nodes, params in extra.get("add", []):
        m.add(kind, name, nodes, **params)
    return m


def verdict(model, params=None):
    return Problem(model.numeric(params or {}))._conservative


def test_a_spring_and_mass_keep_their_energy_and_a_damper_spends_it():
    assert verdict(oscillator()) == (True, "")
    damped = oscillator(add=[("damper", "c", ("ground", "p"), {"c": 0.02})])
    kept, why = verdict(damped)
    assert not kept and "dissipates energy" in why


def test_a_damper_whose_value_is_zero_spends_nothing():
    """D is a term of the equations (its coefficient a symbol), but the run's value makes it zero."""
    c = sp.Symbol("c", nonnegative=True)
    model = oscillator(add=[("damper", "d", ("ground", "p"), {"c": c})])
    assert verdict(model, {"c": 0.0}) == (True, "")
    assert not verdict(model, {"c": 0.5})[0]


def test_a_prescribed_motion_puts_time_into_the_lagrangian():
    model = lg.Model("driven")
    model.add("prescribed_motion", "base", "b", position=0.01 * sp.sin(3 * lg.t))
    model.add("mass", "m", "p", m=0.3)
    model.add("spring", "k", ("b", "p"), k=40.0)
    kept, why = verdict(model)
    assert not kept and "depends on time" in why
    still = lg.Model("still base")
    still.add("prescribed_motion", "base", "b", position=0)
    still.add("mass", "m", "p", m=0.3)
    still.add("spring", "k", ("b", "p"), k=40.0)
    assert verdict(still) == (True, "")


def test_a_long_chain_gets_the_verdicts_of_a_short_one():
    for n in (3, 300):
        chain = models.spring_chain(n, m=0.3, k=40.0, beta=1e3)
        assert verdict(chain) == (True, ""), n
        chain.add("damper", "c", ("ground", "p0"), c=0.1)
        assert "dissipates energy" in verdict(chain)[1], n
