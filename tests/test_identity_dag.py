"""The zero test on expressions whose sub-expressions are shared (a spatial chain's: each body's velocity inside
every body's beyond it): each distinct sub-expression visited once, and the same unknowns as SymPy finds."""

import pytest
import sympy as sp
from hypothesis import given, settings, strategies as st
from sympy.core.function import AppliedUndef

from lagrangian.base import identity
from lagrangian.derivation.calculus import Calculus

x, y = sp.symbols("x y", real=True)
f = sp.Function("f")
t = sp.Symbol("t")


def nested(depth: int) -> sp.Expr:
    """e_{k+1} = sin(e_k)·cos(e_k) + e_k·y: a tree of 2^depth leaves, a graph of 3·depth nodes."""
    e = x
    for _ in range(depth):
        e = sp.sin(e) * sp.cos(e) + e * y
    return e


@pytest.mark.timeout(60)
def test_a_deeply_shared_expression_is_decided_without_visiting_every_occurrence():
    e = nested(60)  # 2^60 leaves as a tree
    assert len(identity.nodes([e])) < 400
    assert identity.is_zero(e) is False
    assert identity.is_zero(e - e) is True  # (SymPy cancels it: zero without any point)
    assert [s.name for s in identity._opaque(e)] == ["x", "y"]


@pytest.mark.timeout(60)
def test_dependence_and_equality_of_deeply_shared_expressions_visit_each_part_once():
    e = nested(60)
    z = sp.Symbol("z", real=True)
    diff = Calculus([x, y, z]).diff  # (memoized on shared parts: SymPy's diff walks every occurrence)
    assert identity.depends_on(e * z + x, z, diff=diff) is True and identity.depends_on(e, z) is False
    assert identity.symbols_of([e]) == {x, y} == nested(6).free_symbols
    assert identity.equal(e, e + 0 * z) is True
    assert identity.equal(e, e + sp.Mul(2, z, evaluate=False)) is False


ATOMS = st.sampled_from([x, y, f(t), sp.Derivative(f(t), t), sp.Integer(2), sp.Float(0.5)])


@st.composite
def expressions(draw, depth=3):
    if depth == 0:
        return draw(ATOMS)
    op = draw(st.sampled_from(["add", "mul", "sin", "atom"]))
    if op == "atom":
        return draw(ATOMS)
    a, b = draw(expressions(depth - 1)), draw(expressions(depth - 1))
    return {"add": a + b, "mul": a * b, "sin": sp.sin(a)}[op]


@settings(max_examples=100, deadline=None)
@given(expressions())
def test_the_unknowns_and_floats_found_once_per_node_are_sympys(e):
    reference = sorted(set(e.free_symbols) | e.atoms(AppliedUndef, sp.Derivative), key=sp.default_sort_key)
    assert identity._opaque(e) == reference
    assert identity._has_float(e, {}) == bool(e.atoms(sp.Float))


@settings(max_examples=100, deadline=None)
@given(expressions())
def test_a_contributions_functions_are_found_once_per_node_as_sympy_finds_them(e):
    from lagrangian.derivation.assembly import _every

    integral = sp.Integral(e * f(x), (x, 0, 1))  # (inside a node that binds a symbol, too)
    for expr in (e, integral):
        assert _every(expr, AppliedUndef) == expr.atoms(AppliedUndef)
        assert _every(expr, sp.Derivative) == expr.atoms(sp.Derivative)


@pytest.mark.timeout(60)
def test_values_go_into_deeply_shared_contributions_and_cached_parts_visiting_each_part_once():
    """The values of parameters put into a contribution (the model's valued assembly) and into a cached reduction's
    parts (lagrangian.routh): a memoized xreplace, where SymPy's walked the 2^60 leaves."""
    import lagrangian as lg
    from lagrangian.analysis.routh.cache import _put
    from lagrangian.derivation.assembly import _with_values

    e, k = nested(60), sp.Symbol("k", positive=True)
    valued = _with_values(lg.Contribution(T=k * e, V=e + k), {k: 2})
    assert valued.T == 2 * e and valued.V == e + 2
    assert _put([k * e, (e, k)], {k: sp.Integer(3)}) == [3 * e, (e, 3)]
