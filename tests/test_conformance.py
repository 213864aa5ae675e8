"""Conformance suite: every installed component kind, built from its own ``example()``.

Parametrized over ``lg.default_registry().kinds`` — built-ins and third-party
plugins alike — so a new plugin is checked without writing a test for it:
its contribution is made of SymPy scalars in the model's coordinates (and
signals), its kinetic energy is a nonnegative quadratic form in velocities,
its Rayleigh function is nonnegative, the example model derives square
equations and simulates for one time unit with finite results, and the kind
is documented.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from sympy.core.function import AppliedUndef

import lagrangian as lg

KINDS = sorted(lg.default_registry().kinds)
N_STATES = 4


def test_the_suite_covers_builtins_and_the_third_party_plugin():
    assert {"mass", "spring", "damper", "gravity", "force", "prescribed_motion"} <= set(KINDS)
    assert {"inductor", "capacitor", "resistor", "voltage_source", "current_source"} <= set(KINDS)
    assert "cubic_spring" in KINDS


def build(kind: str, registry: lg.Registry | None = None) -> tuple[lg.Model, lg.Example]:
    ex = (registry or lg.default_registry()).example(kind)  # the plugin's example, checked (a PluginError if not)
    assert isinstance(ex, lg.Example)
    m = lg.Model(f"example-{kind}", registry=registry, **dict(ex.options))
    m.add(kind, kind, ex.nodes, **dict(ex.params))
    for other_kind, name, nodes, params in ex.context:
        m.add(other_kind, name, nodes, **dict(params))
    return m, ex


@pytest.fixture(scope="module", params=KINDS, ids=KINDS)
def example(request):
    """(kind, model built from the kind's example) — built once per kind."""
    kind = request.param
    m, ex = build(kind)
    m.eq  # noqa: B018 - derive once; failures show up in every test of this kind
    return kind, m


def random_states(m: lg.Model, rng: np.random.Generator, n: int = N_STATES) -> list[dict]:
    eq = m.eq
    states = []
    for _ in range(n):
        subs = {s: sp.Float(rng.uniform(-2, 2)) for s in [*eq.sym.q, *eq.sym.v]}
        subs[lg.t] = sp.Float(rng.uniform(0, 3))
        states.append(subs)
    return states


def _numeric(expr) -> float:
    value = complex(sp.N(expr))
    assert abs(value.imag) < 1e-12, expr
    return value.real


# --- the contribution --------------------------------------------------------


def test_every_component_contributes_sympy_scalars_in_coordinates(example):
    check_contribution(*example)


def check_contribution(kind, m):
    allowed = {c.function.func for c in m.coordinates} | set(m.assembly.signals)
    assert set(m.assembly.contributions) == set(m.components)
    for name, c in m.assembly.contributions.items():
        assert isinstance(c, lg.Contribution), name
        for label in ("T", "V", "D", "G"):
            expr = sp.sympify(getattr(c, label))
            assert isinstance(expr, sp.Expr), (name, label, expr)
            assert not isinstance(expr, sp.MatrixBase)
            undefined = {f.func for f in expr.atoms(AppliedUndef)}
            assert undefined <= allowed, (name, label, undefined - allowed)
            # no accelerations, and nothing but t and the (numeric) example parameters
            assert not any(d.derivative_count > 1 for d in expr.atoms(sp.Derivative)), (name, label)
            assert expr.free_symbols <= {lg.t}, (name, label, expr.free_symbols)
        for load in c.loads:
            assert isinstance(load, lg.Load)
        for e in c.constraints:  # holonomic: scalars in coordinates and t, no rates
            expr = sp.sympify(e)
            assert isinstance(expr, sp.Expr) and not expr.atoms(sp.Derivative), (name, expr)
            assert {f.func for f in expr.atoms(AppliedUndef)} <= allowed and expr.free_symbols <= {lg.t}, (name, expr)
    # the kind under test is not a no-op: it adds energy, dissipation, a load, a constraint or fixes coordinates
    own = m.assembly.contributions[kind]
    cls = type(m.component(kind))
    assert (own.T != 0 or own.V != 0 or own.D != 0 or own.G != 0 or own.loads or own.constraints
            or own.velocity_constraints or cls.role in ("across", "through") or cls.structural)


def test_kinetic_energy_is_a_nonnegative_quadratic_form_in_velocities(example):
    check_kinetic(*example)


def check_kinetic(kind, m):
    eq = m.eq
    v = eq.sym.v
    rng = np.random.default_rng(sum(map(ord, kind)))
    states = random_states(m, rng)
    # each component's own T (a cross term such as a mutual inductance is checked only in the total)
    comps = m.components
    contributions = [eq.symbolic(c.T) for n, c in m.assembly.contributions.items() if not comps[n].cross_energy] + [eq.T]
    for T in contributions:
        H = sp.hessian(T, v) if v else sp.Matrix()
        # quadratic at most: the Hessian does not depend on the velocities
        assert not (H.free_symbols & set(v)), T
        for state in states:
            assert _numeric(T.xreplace(state)) >= -1e-12, (T, state)
            if H.shape[0]:
                Hn = np.array(H.xreplace(state).evalf(), dtype=float)
                assert np.allclose(Hn, Hn.T)
                assert np.linalg.eigvalsh(Hn).min() >= -1e-10, (T, Hn)
    # gyroscopic terms G are linear in the velocities: they add nothing to the mass matrix
    for c in m.assembly.contributions.values():
        G = eq.symbolic(c.G)
        assert all(sp.expand(sp.diff(G, a, b)) == 0 for a in v for b in v), G
    # and the model's mass matrix is the Hessian of the total T
    assert sp.simplify(eq.M - sp.hessian(eq.T, v)) == sp.zeros(len(v), len(v))


def test_rayleigh_function_is_nonnegative(example):
    check_rayleigh(*example)


def check_rayleigh(kind, m):
    eq = m.eq
    rng = np.random.default_rng(1 + sum(map(ord, kind)))
    for state in random_states(m, rng):
        for c in [*m.assembly.contributions.values()]:
            assert _numeric(eq.symbolic(c.D).xreplace(state)) >= -1e-12, (c.D, state)
        assert _numeric(eq.D.xreplace(state)) >= -1e-12


# --- the example model -------------------------------------------------------


def test_example_model_derives_square_equations(example):
    check_equations(*example)


def check_equations(kind, m):
    n = len(m.coordinates)
    assert n >= 1
    assert len(m.coordinate_names) == len(set(m.coordinate_names)) == n
    assert m.mass_matrix.shape == (n, n)
    assert m.forcing.shape == (n, 1)
    assert len(m.equations) == n
    assert m.eq.A.shape == (n + len(m.eq.multipliers),) * 2  # a multiplier per constraint
    assert m.parameters == []  # examples are fully numeric
    # every first-order coordinate is also a coordinate
    assert set(m.first_order) <= set(m.coordinate_names)


def test_example_model_simulates_with_finite_results(example):
    check_simulation(*example)


def check_simulation(kind, m):
    eq = m.eq
    initial = {name: 0.1 * (i + 1) for i, name in enumerate(eq.names)}
    velocity = {eq.names[i]: -0.05 * (i + 1) for i in eq.inertial}
    if len(eq.constraints):  # the dependent coordinates solved from the independent ones
        from lagrangian.plugins.multibody import consistent_initial, independent_coordinates

        free = independent_coordinates(m, initial).independent
        # rates a constraint on velocities involves are moved onto it below, not held here (held, they may conflict)
        tied = {n for n, s in zip(eq.names, eq.sym.v) if any(c.has(s) for c in eq.velocity_constraints)}
        initial, held = consistent_initial(m, {k: initial[k] for k in free},
                                           {k: velocity[k] for k in free if k not in tied})
        velocity = {**held, **{k: velocity[k] for k in tied if k in velocity}}
    if len(eq.velocity_constraints):  # the rates moved (least change) onto A(q)·q̇ + b(q) = 0
        at = {**{s: sp.Float(x) for s, x in eq.values.items()}, **{q: initial[n] for q, n in zip(eq.sym.q, eq.names)},
              lg.t: 0}
        c = eq.velocity_constraints.xreplace(at)
        A = np.array(c.jacobian(eq.sym.v).tolist(), dtype=float)
        b = np.array(c.xreplace({x: 0 for x in eq.sym.v}).tolist(), dtype=float)[:, 0]
        v0 = np.array([velocity.get(n, 0.0) for n in eq.names])
        v0 = v0 - np.linalg.pinv(A) @ (A @ v0 + b)
        velocity = dict(zip(eq.names, map(float, v0)))
    res = m.simulate(1.0, initial=initial, velocity=velocity, points=21, rtol=1e-7, atol=1e-9)
    assert res.defaulted == []
    assert res.t[0] == 0.0 and res.t[-1] == pytest.approx(1.0)
    assert set(res.q) == set(res.v) == set(eq.names)
    for name in eq.names:
        assert res.q[name].shape == res.t.shape
        assert np.all(np.isfinite(res.q[name])), name
        assert np.all(np.isfinite(res.v[name])), name
        assert res.q[name][0] == pytest.approx(initial[name])
    for series in (res.T, res.V, res.D):
        assert series.shape == res.t.shape and np.all(np.isfinite(series))
    assert np.all(res.T >= -1e-12) and np.all(res.D >= -1e-12)
    # something actually moved
    assert any(not np.allclose(res.q[name], res.q[name][0]) for name in eq.names)


# --- the kind itself ---------------------------------------------------------


@pytest.mark.parametrize("kind", KINDS)
def test_kind_is_documented_and_consistent(kind):
    cls = lg.default_registry().component_type(kind)
    assert issubclass(cls, lg.Component)
    assert cls.kind == kind
    doc = cls.__dict__.get("__doc__")
    assert isinstance(doc, str) and doc.strip(), f"{kind}: class needs a docstring"
    assert cls.domain in lg.default_registry().domains
    assert cls.parameters, f"{kind}: declares no parameters"
    for pname, p in cls.parameters.items():
        assert isinstance(p, lg.Parameter), (kind, pname)
        assert pname.isidentifier()
        assert isinstance(p.doc, str) and p.doc.strip(), f"{kind}.{pname}: parameter needs a doc"
    ex = cls.example()
    nodes = (ex.nodes,) if isinstance(ex.nodes, str) else tuple(ex.nodes)
    assert len(nodes) == len(cls.terminals)
    assert set(ex.params) <= set(cls.parameters)
    assert {p for p, spec in cls.parameters.items() if spec.required} <= set(ex.params)
    for item in ex.context:
        assert len(item) == 4 and item[0] in lg.default_registry().kinds


@pytest.mark.parametrize("kind", KINDS)
def test_example_is_reproducible(kind):
    """``example()`` builds the same model twice (no hidden state), with the same Lagrangian."""
    a, _ = build(kind)
    b, _ = build(kind)
    assert a.coordinate_names == b.coordinate_names
    assert sp.simplify(a.lagrangian - b.lagrangian) == 0
    assert f"{kind} ({kind})" in a.describe()


# --- the suite itself rejects what it should -----------------------------------


def _kind(kind: str, contribute, doc: str = "A deliberately broken kind."):
    def example(cls):
        return lg.Example("p", {"a": 1}, context=[("mass", "m", "p", {"m": 1}), ("spring", "k", ("ground", "p"), {"k": 1})])

    return type(
        kind,
        (lg.Component,),
        {
            "__doc__": doc,
            "kind": kind,
            "domain": "mechanical",
            "terminals": ("node",),
            "parameters": {"a": lg.Parameter("coefficient")},
            "contribute": contribute,
            "example": classmethod(example),
        },
    )


def _v(self, ctx):
    return ctx.view.velocity(self.nodes[0])[0]


BROKEN = {
    # negative kinetic energy (an "anti-mass" that still leaves the total mass positive)
    "anti_mass": (_kind("anti_mass", lambda self, ctx: lg.Contribution(T=-self.a * _v(self, ctx) ** 2 / 4)), check_kinetic),
    # quartic in velocity: not a quadratic form
    "quartic_mass": (_kind("quartic_mass", lambda self, ctx: lg.Contribution(T=_v(self, ctx) ** 4)), check_kinetic),
    # negative dissipation
    "anti_damper": (_kind("anti_damper", lambda self, ctx: lg.Contribution(D=-self.a * _v(self, ctx) ** 2)), check_rayleigh),
    # an energy in a function that is neither coordinate nor signal
    "stray_function": (
        _kind("stray_function", lambda self, ctx: lg.Contribution(V=sp.Function("stray")(lg.t) ** 2)),
        None,  # assembly itself refuses it
    ),
    # a free symbol the example never gives a value
    "stray_symbol": (_kind("stray_symbol", lambda self, ctx: lg.Contribution(V=sp.Symbol("s") * _v(self, ctx))), check_contribution),
    # blows up within the time unit: V = -a x^4 pushes x to infinity
    "runaway": (
        _kind("runaway", lambda self, ctx: lg.Contribution(V=-1e4 * self.a * ctx.view.position(self.nodes[0])[0] ** 4)),
        check_simulation,
    ),
}


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
@pytest.mark.parametrize("name", sorted(BROKEN))
def test_suite_rejects_a_broken_kind(name):
    cls, check = BROKEN[name]
    reg = lg.Registry(plugins={"broken": _plugin(cls)})
    if check is None:
        with pytest.raises(lg.ModelError, match=name):
            build(name, reg)[0].eq  # noqa: B018
        return
    m, _ = build(name, reg)
    with pytest.raises((AssertionError, lg.LagrangianError)):
        check(name, m)


def _plugin(cls):
    import types

    plugin = types.ModuleType("broken")

    @lg.hookimpl
    def register_component_types(register):
        register(cls)

    plugin.register_component_types = register_component_types
    return plugin


LINEAR_KINDS = [k for k in KINDS if lg.default_registry().component_type(k).linear is not lg.Component.linear]


@pytest.mark.parametrize("kind", LINEAR_KINDS, ids=LINEAR_KINDS)
def test_a_kind_said_in_numbers_linearizes_as_its_energy_does(kind):
    """A kind that says its contribution in numbers (``linear``) gives, on its example, the linearization its
    symbolic energy gives: coordinates, matrices, inputs and every coordinate as output.  An example that the
    numeric assembly does not take (a spring's rest length, a constant force) is linearized by the symbolic path,
    the numeric one declining."""
    from unittest import mock

    import lagrangian.analysis.linearize as linearize_module
    from lagrangian.analysis.lti import numeric
    from lagrangian.derivation.numeric import assemble_numeric
    from lagrangian.derivation.stamps import NotStampable
    from lagrangian.frequency import linearize

    m, _ = build(kind)
    try:
        assemble_numeric(m)
    except NotStampable:
        assert numeric(m, None, None, 0.0) is None
        assert linearize(m).coordinates == m.coordinate_names
        return
    assert numeric(m, None, None, 0.0) is not None
    fast = linearize(m)
    with mock.patch.object(linearize_module, "numeric", lambda *a, **k: None), \
            mock.patch.object(linearize_module, "stamped", lambda *a, **k: None):
        slow = linearize(m)
    assert fast.coordinates == slow.coordinates and fast.inputs == slow.inputs
    for name in ("M", "C", "K", "Bi"):
        a, b = np.asarray(getattr(fast, name), float), np.asarray(getattr(slow, name), float)
        assert np.allclose(a, b, rtol=1e-12, atol=1e-12 * max(np.abs(b).max(initial=0), 1e-300)), name
    for name in ("B", "Cq"):
        a, b = getattr(fast, name), getattr(slow, name)
        for k in range(max(len(a), len(b))):
            x = np.asarray(a[k], float) if k < len(a) else 0 * np.asarray(b[k], float)
            y = np.asarray(b[k], float) if k < len(b) else 0 * x
            assert np.allclose(x, y, rtol=1e-12, atol=1e-12 * max(np.abs(y).max(initial=0), 1e-300)), (name, k)
