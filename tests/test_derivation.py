"""The derivation of ``M q̈ = f``: the structured path against the general formulas and against
sympy.physics.mechanics (an independent engine), numerically at random states and, where cheap,
symbolically.  No timing assertions: ``benchmarks/derivation.py`` measures speed."""

from __future__ import annotations

import random

import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st
import sympy.physics.mechanics as me

import lagrangian as lg
from lagrangian.derive import Calculus, Derivation, float_value, general, time_derivative
from lagrangian.equations import Equations, _is_zero

t = lg.t
RTOL = 1e-12


# -- helpers ----------------------------------------------------------------------------------------


def chain(n: int, shared: bool = False):
    """Our planar n-link pendulum: links with a point ``end``, absolute revolute joints, point masses, gravity."""
    m = [sp.Symbol("m")] * n if shared else list(sp.symbols(f"m:{n}"))
    l = [sp.Symbol("l")] * n if shared else list(sp.symbols(f"l:{n}"))
    g = sp.Symbol("g")
    model = lg.Model(f"{n}-link", dim=2)
    parent = "ground"
    for k in range(n):
        model.add("link", f"L{k}", f"L{k}", points={"end": (l[k], 0)})
        model.add("revolute", f"j{k}", (parent, f"L{k}"), absolute=True, **({"parent_point": (l[k - 1], 0)} if k else {}))
        model.add("mass", f"m{k}", f"L{k}.end", m=m[k])
        parent = f"L{k}"
    model.add("gravity", "g", g=g)
    return model, (m, l, g)


def kane_chain(n: int, params):
    """The same pendulum by KanesMethod: ``(mass_matrix, forcing, q, u)``."""
    m, l, g = params
    q, u = me.dynamicsymbols(f"q:{n}"), me.dynamicsymbols(f"u:{n}")
    N, O = me.ReferenceFrame("N"), me.Point("O")
    O.set_vel(N, 0)
    particles, loads, kd, P = [], [], [], O
    for k in range(n):
        A = N.orientnew(f"A{k}", "Axis", [q[k], N.z])
        A.set_ang_vel(N, u[k] * N.z)
        Pk = P.locatenew(f"P{k}", l[k] * A.x)
        Pk.v2pt_theory(P, N, A)
        particles.append(me.Particle(f"pa{k}", Pk, m[k]))
        loads.append((Pk, -m[k] * g * N.y))
        kd.append(q[k].diff() - u[k])
        P = Pk
    km = me.KanesMethod(N, q_ind=q, u_ind=u, kd_eqs=kd)
    km.kanes_equations(particles, loads)
    return km.mass_matrix, km.forcing, q, u


def values(exprs, subs) -> np.ndarray:
    """Entries at a state, with 30-digit arithmetic (the comparison is then of the expressions, not of rounding)."""
    return np.array([float(sp.sympify(e).xreplace(subs).evalf(30)) for e in exprs])


def close(a, b, rtol=RTOL) -> bool:
    scale = max(1.0, float(np.max(np.abs(b)))) if len(b) else 1.0
    return bool(np.all(np.abs(a - b) <= rtol * scale))


def random_subs(symbols, rng, lo=-2.0, hi=2.0) -> dict:
    return {s: sp.Float(rng.uniform(lo, hi), 30) for s in sorted(symbols, key=str)}


def reference(eq: Equations):
    """``M`` and ``f`` by the textbook formulas on the whole Lagrangian (SymPy's diff, no structure)."""
    return general(eq.T, eq.V, eq.G, eq.D, list(eq.Q), eq.sym.q, eq.sym.v, t)


def check_against_reference(eq: Equations, rng, states: int = 3, symbolic: bool = False) -> None:
    M0, f0 = reference(eq)
    free = (eq.M.free_symbols | eq.f.free_symbols | M0.free_symbols | f0.free_symbols) - {t}
    for _ in range(states):
        subs = random_subs(free, rng, 0.3, 2.0)
        subs[t] = sp.Float(rng.uniform(0, 3), 30)
        assert close(values(eq.M, subs), values(M0, subs)), "M differs from the general formulas"
        assert close(values(eq.f, subs), values(f0, subs)), "f differs from the general formulas"
    if symbolic:
        assert all(vanishes(e) for e in eq.M - M0)
        assert all(vanishes(e) for e in eq.f - f0)


def vanishes(expr) -> bool:
    """Whether ``expr`` is zero, as a polynomial in sines and cosines reduced by sin² = 1 − cos²."""
    def reduce(p):
        k = int(p.exp)
        return sp.sin(p.base.args[0]) ** (k % 2) * (1 - sp.cos(p.base.args[0]) ** 2) ** (k // 2)

    e = sp.expand(expr)
    e = e.replace(lambda p: p.is_Pow and p.exp.is_Integer and p.exp > 1 and isinstance(p.base, sp.sin), reduce)
    return sp.expand(e) == 0


# -- the n-link pendulum ----------------------------------------------------------------------------


@pytest.mark.parametrize("n", [2, 3, 5])
@pytest.mark.slow
def test_pendulum_structured_equals_general_path(n):
    model, _ = chain(n)
    check_against_reference(model.eq, random.Random(n), symbolic=n <= 3)


@pytest.mark.parametrize("n", [2, 3, 5])
@pytest.mark.slow
def test_pendulum_equals_kanes_method(n):
    model, params = chain(n)
    eq = model.eq
    Mk, Fk, q, u = kane_chain(n, params)
    assert eq.names == [f"theta_j{k}" for k in range(n)]
    to_ours = {**dict(zip(q, eq.sym.q)), **dict(zip(u, eq.sym.v))}
    Mk, Fk = Mk.xreplace(to_ours), Fk.xreplace(to_ours)
    rng = random.Random(10 + n)
    free = set(eq.sym.q) | set(eq.sym.v) | {*params[0], *params[1], params[2]}
    for _ in range(4):
        subs = random_subs(free, rng, -3.0, 3.0)
        assert close(values(eq.M, subs), values(Mk, subs))
        assert close(values(eq.f, subs), values(Fk, subs))
    if n == 2:  # symbolically: the difference vanishes once the trigonometric sums are expanded
        for ours, kane in ((eq.M, Mk), (eq.f, Fk)):
            assert all(vanishes(sp.expand_trig(e)) for e in ours - kane)


def test_pendulum_with_shared_parameters_and_compact_mass_matrix():
    model, (m, l, g) = chain(3, shared=True)
    eq = model.eq
    m, l = m[0], l[0]
    assert eq.M[0, 0] == 3 * m * l**2  # Σ m (sin² + cos²) l² collapsed
    assert eq.M[2, 2] == m * l**2
    check_against_reference(eq, random.Random(3), symbolic=True)


@pytest.mark.slow
def test_count_ops_stay_below_kanes_for_the_pendulum():
    n = 5
    model, params = chain(n)
    Mk, Fk, _, _ = kane_chain(n, params)
    ours = sp.count_ops(model.eq.M) + sp.count_ops(model.eq.f)
    assert ours <= sp.count_ops(Mk) + sp.count_ops(Fk)


# -- every built-in kind, and Lagrangians of other shapes ---------------------------------------------


def example_models():
    """A model of every installed kind, from its own ``example()`` (as the conformance suite builds them)."""
    registry = lg.default_registry()
    for kind in sorted(registry.kinds):
        ex = registry.component_type(kind).example()
        model = lg.Model(f"example-{kind}", **dict(ex.options))
        model.add(kind, kind, ex.nodes, **dict(ex.params))
        for other_kind, name, nodes, params in ex.context:
            model.add(other_kind, name, nodes, **dict(params))
        yield kind, model


@pytest.mark.slow
def test_every_example_model_matches_the_general_path():
    rng = random.Random(2)
    for kind, model in example_models():
        eq = model.eq
        if eq.M.atoms(sp.core.function.AppliedUndef) or eq.f.atoms(sp.core.function.AppliedUndef):
            continue  # callable signals: no numeric value here
        try:
            check_against_reference(eq, rng, states=2)
        except AssertionError as exc:  # pragma: no cover - the message names the kind
            raise AssertionError(f"{kind}: {exc}") from None


x, y, z = sp.symbols("q_x q_y q_z", real=True)
vx, vy, vz = sp.symbols("v_x v_y v_z", real=True)
a, b, c, k = sp.symbols("a b c k", positive=True)

LAGRANGIANS = {
    # T, V, G, D, Q
    "coupled squares": (a * (vx + vy) ** 2 / 2 + b * vx * vy, k * x * y, 0, 0, [0, 0]),
    "position-dependent inertia": ((a + b * sp.sin(x) ** 2) * vx**2 / 2 + x**2 * vy**2, k * x**2, 0, c * vx**2 / 2, [0, sp.cos(t)]),
    "rheonomic (a moving support)": (a * ((vx + c * sp.cos(t)) ** 2 + (y * vx + vy) ** 2) / 2, k * (x**2 + y**2), 0, 0, [0, 0]),
    "not a gradient (curl terms)": (a * (y * vx + vy) ** 2 / 2 + b * (vx - x * vy + t) ** 2, 0, 0, 0, [vx * y, 0]),
    "time-dependent coefficient": ((1 + t**2) * a * vx**2 / 2 + sp.exp(t) * vx * vy * sp.cos(y) + vy**2, k * sp.cos(x), 0, 0, [0, 0]),
    "gyroscopic and non-quadratic": (a * vx**2 / 2 + b * vy**2 / 2 + vx**4 / 12 + x * vx * vy**2, k * x * y, c * (x * vy - y * vx), c * vy**2, [t, 0]),
    "three coordinates, single-term velocities": (
        a * (sp.sin(x) * vx) ** 2 / 2 + b * (sp.cos(y) * vy - sp.sin(x) * vz) ** 2 / 2 + c * (z * vx) ** 2,
        a * sp.cos(x) + b * sp.sin(y) * z,
        0,
        k * (vx - vz) ** 2 / 2,
        [0, 0, sp.sin(t)],
    ),
}


@pytest.mark.parametrize("name", list(LAGRANGIANS))
def test_lagrangians_of_other_shapes(name):
    T, V, G, D = (sp.sympify(e) for e in LAGRANGIANS[name][:4])
    Q = [sp.sympify(e) for e in LAGRANGIANS[name][4]]
    q, v = ([x, y, z], [vx, vy, vz]) if len(Q) == 3 else ([x, y], [vx, vy])
    M, f = Derivation(q, v, t).equations(T, V, G, D, Q)
    M0, f0 = general(T, V, G, D, Q, q, v, t)
    assert (sp.Matrix(M) - M0).applyfunc(sp.expand) == sp.zeros(*M0.shape)
    assert (sp.Matrix(f) - f0).applyfunc(sp.expand) == sp.zeros(*f0.shape)


def test_momenta_are_dL_dv():
    T, V, G = LAGRANGIANS["gyroscopic and non-quadratic"][:3]
    d = Derivation([x, y], [vx, vy], t)
    d.equations(T, V, G, 0, [0, 0])
    p = d.momenta()
    for pi, vi in zip(p, [vx, vy]):
        assert sp.expand(pi - sp.diff(T - V + G, vi)) == 0


def test_model_momenta_and_lagrangian_are_kept():
    model, _ = chain(2)
    eq = model.eq
    assert (eq.p - sp.Matrix([sp.diff(eq.L, v) for v in eq.sym.v])).applyfunc(sp.expand) == sp.zeros(2, 1)
    assert sp.expand(eq.L - (eq.T - eq.V + eq.G)) == 0


# -- the solve A u = b, built block by block ----------------------------------------------------------


def reference_split(eq: Equations):
    """``A`` and ``b`` as the Jacobian of the residual in the unknowns (the original construction)."""
    n = len(eq.names)
    M, f = eq.M, eq.f
    unknowns = [eq.sym.a[i] for i in eq.inertial] + [eq.sym.v[i] for i in eq.first_order]
    residual = sp.Matrix([sum((M[i, j] * eq.sym.a[j] for j in eq.inertial), sp.Integer(0)) - f[i] for i in range(n)])
    if len(eq.constraints):
        q, v, acc = eq.sym.q, eq.sym.v, eq.sym.a
        Jq = eq.constraints.jacobian(q)
        Phi_dot = Jq * sp.Matrix(v) + eq.constraints.diff(t)
        w = sp.Float(eq.constraint_rate)
        rows = Jq * sp.Matrix(acc) + Phi_dot.jacobian(q) * sp.Matrix(v) + Phi_dot.diff(t) + 2 * w * Phi_dot + w**2 * eq.constraints
        residual = (residual - Jq.T * sp.Matrix(eq.multipliers)).col_join(rows)
        unknowns += eq.multipliers
    A = residual.jacobian(unknowns)
    return A, -residual.xreplace({u: 0 for u in unknowns})


def rc_ladder():
    model = lg.Model("rc")
    model.add("voltage_source", "V1", ("in", "0"), E=sp.sin(t))
    model.add("resistor", "R1", ("in", "a"), R=2)
    model.add("capacitor", "C1", ("a", "0"), C=sp.Rational(1, 3))
    model.add("resistor", "R2", ("a", "b"), R=1)
    model.add("inductor", "L2", ("b", "0"), L=sp.Rational(1, 2))
    return model


def four_bar():
    model = lg.Model("four-bar", dim=2)
    for name, length in (("crank", 1), ("coupler", 3), ("rocker", 2)):
        model.add("rod", name, name, m=1, length=length)
    model.add("revolute", "A", ("ground", "crank"), absolute=True)
    model.add("revolute", "B", ("crank", "coupler"), parent_point=(1, 0), absolute=True)
    model.add("revolute", "D", ("ground", "rocker"), parent_point=(3, 0), absolute=True)
    model.add("revolute", "C", ("coupler", "rocker"), parent_point=(3, 0), child_point=(2, 0))
    model.add("gravity", "g")
    return model


@pytest.mark.parametrize("build", [rc_ladder, four_bar], ids=["first-order", "constrained"])
def test_blockwise_solve_matches_the_jacobian_of_the_residual(build):
    eq = build().eq
    assert eq.first_order or len(eq.constraints)
    A0, b0 = reference_split(eq)
    assert eq.A.shape == A0.shape and eq.b.shape == b0.shape
    rng = random.Random(5)
    free = (A0.free_symbols | b0.free_symbols | eq.A.free_symbols | eq.b.free_symbols) - {t}
    for _ in range(3):
        subs = random_subs(free, rng)
        subs[t] = sp.Float(rng.uniform(0, 3), 30)
        assert close(values(eq.A, subs), values(A0, subs))
        assert close(values(eq.b, subs), values(b0, subs))


# -- the building blocks ----------------------------------------------------------------------------


def test_time_derivative_and_partial_derivatives_agree_with_sympy():
    q1, q2 = sp.Function("q1", real=True)(t), sp.Function("q2", real=True)(t)
    exprs = [
        3 * sp.sin(q1) * sp.cos(q2) ** 2 + q1.diff(t) * t**2,
        sp.sqrt(1 + q1**2) / (2 + sp.cos(q2 - q1)),
        sp.exp(q1 * t) * sp.tan(q2) + q2.diff(t, 2),
    ]
    for e in exprs:
        assert sp.simplify(time_derivative(e, t) - e.diff(t)) == 0
    s1, s2 = sp.symbols("s1 s2", real=True)
    calc = Calculus([s1, s2, t])
    for e in [sp.sin(s1) ** 3 * s2 + t * sp.cos(s1 * s2), s1 ** sp.Rational(1, 2) * sp.exp(s2 * t), sp.Abs(s1) + sp.atan(s2)]:
        for s in (s1, s2, t):
            assert sp.simplify(calc.diff(e, s) - sp.diff(e, s)) == 0


@st.composite
def _expressions(draw, atoms, depth=3):
    """Random expressions of ``atoms``: sums, products, powers, sin, cos, sqrt and exp, sharing sub-expressions."""
    if depth == 0:
        return draw(st.sampled_from(atoms)) * draw(st.sampled_from([1, 2, sp.Rational(3, 10), sp.Float(0.7)]))
    a, b = draw(_expressions(atoms, depth - 1)), draw(_expressions(atoms, depth - 1))
    return draw(st.sampled_from([a + b, a * b, a**2 * b, sp.sin(a) * b, sp.cos(a + b), sp.sqrt(1 + a**2) + b,
                                 sp.exp(a / 3) * a, a * sp.sin(a)]))


@settings(max_examples=40, deadline=None)
@given(st.data())
def test_the_derivative_along_a_direction_is_the_chain_rule_of_sympys_derivatives(data):
    """Calculus.along (one forward pass) against Σ ∂e/∂s · rate_s by SymPy's own diff, at random points."""
    s1, s2, v1, v2 = sp.symbols("s1 s2 v1 v2", real=True)
    e = data.draw(_expressions([s1, s2, t]))
    rates = {s1: v1, s2: v2 * s1, t: sp.S.One}
    got = Calculus([s1, s2, t]).along(e, rates, {})
    want = sum(sp.diff(e, s) * r for s, r in rates.items())
    rng = np.random.default_rng(0)
    for _ in range(3):
        point = dict(zip((s1, s2, v1, v2, t), rng.uniform(-1.5, 1.5, 5)))
        a, b = complex(got.evalf(subs=point)), complex(want.evalf(subs=point))
        assert abs(a - b) <= 1e-9 * (1 + abs(b))


def test_zero_tests_are_exact_about_identical_zeros():
    s1, s2 = sp.symbols("s1 s2", real=True)
    assert _is_zero(sp.Integer(0))
    assert _is_zero((s1 + s2) ** 2 - s1**2 - 2 * s1 * s2 - s2**2)  # zero, though not structurally
    assert not _is_zero(sp.sin(s1) ** 2 + sp.cos(s1) ** 2 - 1 + s2 * 1e-3)
    assert float_value(sp.sin(s1) * s2 + 1, {s1: 0.5, s2: 2.0})[0] == pytest.approx(2 * np.sin(0.5) + 1)
    assert float_value(sp.Abs(s1), {s1: 1.0}) is None  # outside the quick probe: the caller falls back to expand


def test_zero_test_settles_large_nested_expressions_without_expanding():
    xs, ys = sp.symbols("x:30", real=True), sp.symbols("y:30", real=True)
    A = sp.Mul(*[x + y for x, y in zip(xs, ys)])  # 2**30 terms once expanded
    e = A * (xs[0] + ys[0]) - A * xs[0] - A * ys[0] + sp.Rational(1, 2)  # = 1/2; rounding hides it in floats
    assert not _is_zero(e)  # settled by the 60-digit probe, never by expand


def test_a_massless_coordinate_with_only_springs_is_still_refused():
    model = lg.Model("bare")
    model.add("mass", "m", "a", m=1)
    model.add("spring", "k1", ("a", "b"), k=1)
    model.add("spring", "k2", ("b", "ground"), k=1)
    with pytest.raises(lg.ModelError, match="neither inertia nor dissipation"):
        model.eq  # noqa: B018
