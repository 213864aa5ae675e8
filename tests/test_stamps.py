"""Linear models assembled numerically from their components' stamps, and solved on sparse matrices.

References, none of them the code under test:

- the symbolic equations of the same model (:class:`lagrangian.derivation.equations.Equations`, a different
  derivation of the same contributions): ``M``, ``∂f/∂q̇``, ``∂f/∂q`` and the state-free part of ``f``;
- the closed-form normal modes of a uniform chain (a fixed–free chain of ``N`` equal masses ``m`` and springs
  ``k``: ``ω_j = 2 √(k/m) sin((2j − 1) π / (2(2N + 1)))``, mode shape ``sin(i θ_j)``, ``θ_j = (2j − 1) π/(2N + 1)``);
- the dense exact solution of the symbolic state space (the path the stamps bypass), on the same model.

Thresholds: the three exact solutions differ by rounding alone (a few ulps per step, amplified by the
condition of the eigenvectors); 1e-12 of the solution's scale, as in ``test_linear.py``.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

import lagrangian as lg
import lagrangian.numerics.linear as linear
from lagrangian.derivation.stamps import NotStampable, stamps

TOL = 1e-12


def _decades(lo: float, hi: float):
    return st.floats(math.log10(lo), math.log10(hi)).map(lambda e: float(f"{10 ** e:.3g}"))


@st.composite
def linear_models(draw):
    """A random linear mechanism or circuit: a chain with side branches, every value drawn over decades."""
    if draw(st.booleans()):
        m = lg.Model("mech")
        n = draw(st.integers(2, 5))
        nodes = [f"p{i}" for i in range(n)]
        for i, node in enumerate(nodes):
            if i == 0 or draw(st.integers(0, 4)):  # some nodes without mass: first-order where damped
                m.add("mass", f"m{i}", node, m=draw(_decades(1e-3, 1e2)))
            prev = "ground" if i == 0 else nodes[draw(st.integers(0, i - 1))]
            m.add("spring", f"k{i}", (prev, node), k=draw(_decades(1e-1, 1e4)))
            m.add("damper", f"c{i}", (prev, node), c=draw(_decades(1e-3, 1e1)))
        m.add("force", "F", nodes[-1], F=draw(_decades(0.1, 10)) * sp.sin(draw(_decades(0.1, 30)) * lg.t))
        if draw(st.booleans()):
            m.add("gravity", "g", g=9.81)
        return m
    formulation = draw(st.sampled_from(["charge", "flux"]))
    c = lg.Model("rlc", formulation=formulation)
    c.add("voltage_source", "V1", ("in", "0"), E=draw(_decades(0.1, 10)) * sp.cos(draw(_decades(1, 1e3)) * lg.t))
    prev = "in"
    for k in range(draw(st.integers(1, 3))):
        c.add("resistor", f"R{k}", (prev, f"m{k}"), R=draw(_decades(1, 1e3)))
        c.add("inductor", f"L{k}", (f"m{k}", f"n{k}"), L=draw(_decades(1e-4, 1e-1)))
        c.add("capacitor", f"C{k}", (f"n{k}", "0"), C=draw(_decades(1e-7, 1e-3)))
        prev = f"n{k}"
    return c


def _symbolic_reference(model):
    """``M``, ``C = −∂f/∂q̇``, ``K = −∂f/∂q`` and ``f`` at rest from the symbolic equations ``M q̈ = f``."""
    eq = model.eq
    q, v = eq.sym.q, eq.sym.v
    f = eq.f
    M = np.array(eq.M.tolist(), dtype=float)
    C = -np.array(f.jacobian(v).tolist(), dtype=float)
    K = -np.array(f.jacobian(q).tolist(), dtype=float)
    rest = f.xreplace({s: 0 for s in [*q, *v]})
    return M, C, K, rest


@settings(max_examples=40, deadline=None)
@given(linear_models())
@pytest.mark.slow
def test_stamps_agree_with_the_symbolic_equations(model):
    st_ = stamps(model.assembly, model.assembly.values)
    M, C, K, rest = _symbolic_reference(model)
    for name, ours, ref in (("M", st_.M, M), ("C", st_.C, C), ("K", st_.K, K)):
        scale = max(np.abs(ref).max(), 1e-300)
        assert np.abs(ours.toarray() - ref).max() <= 1e-13 * scale, name
    for time in (0.0, 0.37, 2.9):
        s = np.array([float(e.subs(lg.t, time)) for e in st_.inputs])
        ours = st_.B @ s if len(s) else np.zeros(st_.n)
        ref = np.array([float(e.subs(lg.t, time)) for e in rest])
        assert np.abs(ours - ref).max() <= 1e-13 * max(np.abs(ref).max(), 1.0)


def _chain(n, *, massless_every=0, force=True, gravity=False, pulse=False):
    m = lg.Model("chain")
    prev = "ground"
    for i in range(n):
        node = f"p{i}"
        if not massless_every or i % massless_every:
            m.add("mass", f"m{i}", node, m=0.3 + 0.01 * (i % 7))
        m.add("spring", f"k{i}", (prev, node), k=40.0 + i % 5)
        m.add("damper", f"c{i}", (prev, node), c=0.02 + 0.5 * (massless_every and not i % massless_every))
        prev = node
    if force:
        F = sp.Piecewise((1.5, lg.t < 0.4), (0, True)) if pulse else 0.7 * sp.sin(3 * lg.t)
        m.add("force", "F", prev, F=F)
    if gravity:
        m.add("gravity", "g")
    return m


def _not_in_numbers(model):
    raise NotStampable("the symbolic path, for comparison")


def _three_ways(build, monkeypatch, **run):
    """The dense stamped, the sparse stamped and the symbolic exact solution of the same model."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        dense = build().simulate(method="exact", **run)
        monkeypatch.setattr(linear, "DENSE_MAX", 4)
        sparse = build().simulate(method="exact", **run)
        monkeypatch.setattr(linear, "STAMPS_MIN", 10**9)
        monkeypatch.setattr(linear, "numeric_stamps", _not_in_numbers)
        symbolic = build().simulate(method="exact", **run)
    assert "dense" in dense.notes[0] and "sparse" in sparse.notes[0] and not symbolic.notes
    return dense, sparse, symbolic


@pytest.mark.parametrize("kind", ["masses, a harmonic force and gravity", "massless damped nodes (first-order)",
                                  "a pulse, on an uneven grid"])
@pytest.mark.slow
def test_dense_sparse_and_symbolic_exact_solutions_agree(kind, monkeypatch):
    run = dict(t_end=1.5, initial={"x_p0": 0.01, "x_p3": -0.02}, points=61)
    if kind.startswith("masses"):
        def build():
            return _chain(42, gravity=True)
    elif kind.startswith("massless"):
        def build():
            return _chain(42, massless_every=3)
    else:
        def build():
            return _chain(42, pulse=True)
        run = dict(run, points=None, t_eval=np.sort(np.random.default_rng(3).uniform(0, 1.5, 40)))
        run.pop("points")
    results = _three_ways(build, monkeypatch, **run)
    ref = results[2]
    scale = max(np.abs(x).max() for x in ref.q.values())
    for res in results[:2]:
        assert max(np.abs(res.q[k] - ref.q[k]).max() for k in ref.q) <= TOL * scale * 100
        assert max(np.abs(res.v[k] - ref.v[k]).max() for k in ref.v) <= 1e-10 * max(np.abs(x).max() for x in ref.v.values())
        for part in ("T", "V", "D"):
            a, b = getattr(res, part), getattr(ref, part)
            assert np.abs(a - b).max() <= 1e-10 * max(np.abs(b).max(), 1e-300), part


@pytest.mark.slow
def test_a_uniform_chain_of_700_masses_swings_in_its_closed_form_normal_mode():
    """Sparse path (1,400 states): x_i(t) = sin(i θ_j) cos(ω_j t), ω_j = 2√(k/m) sin(θ_j/2)."""
    N, mass, k, j = 700, 0.3, 40.0, 3
    m = lg.Model("uniform chain")
    prev = "ground"
    for i in range(N):
        m.add("mass", f"m{i}", f"p{i}", m=mass)
        m.add("spring", f"k{i}", (prev, f"p{i}"), k=k)
        prev = f"p{i}"
    theta = (2 * j - 1) * math.pi / (2 * N + 1)
    omega = 2 * math.sqrt(k / mass) * math.sin(theta / 2)
    shape = np.sin(np.arange(1, N + 1) * theta)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = m.simulate(3.0, initial={f"x_p{i}": 1e-2 * shape[i] for i in range(N)}, method="auto", points=31)
    assert res.method == "exact" and "sparse" in res.notes[1]
    expected = 1e-2 * np.outer(shape, np.cos(omega * res.t))
    got = np.array([res.q[f"x_p{i}"] for i in range(N)])
    assert np.abs(got - expected).max() <= 1e-11
    E0 = 0.5 * k * 1e-4 * (shape[0] ** 2 + np.sum(np.diff(shape) ** 2))  # released at rest: all potential
    assert np.abs(res.E - E0).max() <= 1e-11 * E0
    assert "equations" not in m._cache  # nothing was derived symbolically
    with pytest.raises(lg.UnknownNameError, match="Did you mean 'x_p9'") as err:
        res["p9"]
    assert "(660 more)" in str(err.value) and len(str(err.value)) < 1000  # 700 names, not all listed
    with pytest.warns(lg.InitialConditionWarning, match=r"x_p0', x_p1', .*\(660 more\)"):
        m.simulate(0.1, initial={f"x_p{i}": 0.0 for i in range(N)}, method="exact", points=2)


@pytest.mark.slow
def test_symbolic_parameters_given_values_are_stamped_like_numbers():
    k = sp.Symbol("k", positive=True)
    a = _chain(45)
    b2 = lg.Model("chain")  # the same chain with one spring's stiffness a symbol
    for comp in a.components.values():
        params = dict(comp.params)
        if comp.name == "k7":
            params["k"] = k
        b2.add(comp.kind, comp.name, comp.nodes, **params)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ra = a.simulate(1.0, initial={"x_p0": 0.01}, method="auto", points=11)
        rb = b2.simulate(1.0, initial={"x_p0": 0.01}, method="auto", points=11, params={"k": 47.0})
    assert "stamps" in rb.notes[0] and b2.parameters == [k]
    assert max(np.abs(ra.q[n] - rb.q[n]).max() for n in ra.q) > 1e-6  # another stiffness moved it
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rc = a.simulate(1.0, initial={"x_p0": 0.01}, method="auto", points=11, params={"k_k7": 47.0})
    assert max(np.abs(rc.q[n] - rb.q[n]).max() for n in ra.q) <= TOL * 0.01


@pytest.mark.slow
def test_models_the_stamps_do_not_take_go_the_symbolic_way_with_its_messages():
    m = _chain(41, force=False)
    m.add("force", "F", "p40", F=lambda time: 0.1)
    with pytest.raises(NotStampable, match="callable"):
        stamps(m.assembly, m.assembly.values)
    assert linear.stamped(m) is None
    with pytest.raises(lg.ModelError, match="Python callable"), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m.simulate(1.0, method="exact")
    planar = lg.Model("planar", dim=2)
    prev = "ground"
    for i in range(20):
        planar.add("mass", f"m{i}", f"p{i}", m=0.2)
        planar.add("spring", f"k{i}", (prev, f"p{i}"), k=30.0, rest_length=0.1)
        prev = f"p{i}"
    with pytest.raises(NotStampable, match="depends on the state"):
        stamps(planar.assembly, planar.assembly.values)
