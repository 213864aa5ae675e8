"""Runs of large lumped models assembled in numbers (``lagrangian.numerics.assembled``) against the symbolic path.

The reference is the model's symbolic derivation (its Lagrangian differentiated, run on the tape interpreter): the
assembled right-hand side, energies and runs must agree with it on networks of masses, springs (cubic ones, with
rest lengths), dampers and forces drawn at random, with values over decades.  The path is taken only where it
applies, and each potential expression is derived once for every component that has it.
"""

from __future__ import annotations

import pickle
import subprocess
import sys
import warnings

import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings, strategies as st

import lagrangian as lg
from lagrangian import Linear, Potential, models
from lagrangian.derivation.numeric import assemble_local, assemble_numeric, local_stamps
from lagrangian.derivation.stamps import NotStampable
from lagrangian.numerics import assembled
from lagrangian.numerics.assembled import AssembledModel


def _decades(lo: float, hi: float):
    return st.floats(np.log10(lo), np.log10(hi)).map(lambda e: float(f"{10 ** e:.3g}"))


@st.composite
def networks(draw):
    """A random 1-D network: ``n`` masses, each tied to ground or an earlier node by a spring (cubic or linear,
    with or without a rest length), some with dampers, extra springs between random pairs, a harmonic force,
    gravity along the axis or not."""
    n = draw(st.integers(2, 7))
    m = lg.Model("net")
    for i in range(n):
        m.add("mass", f"m{i}", f"p{i}", m=draw(_decades(0.05, 20.0)))
    springs = [(("ground" if i == 0 else f"p{draw(st.integers(0, i - 1))}"), f"p{i}") for i in range(n)]
    springs += [tuple(f"p{j}" for j in draw(st.lists(st.integers(0, n - 1), min_size=2, max_size=2, unique=True)))
                for _ in range(draw(st.integers(0, 3)))]
    for k, nodes in enumerate(springs):
        extra = {}
        if draw(st.booleans()):
            extra["beta"] = draw(_decades(1.0, 1e5)) * draw(st.sampled_from([1.0, -1.0]))
        if draw(st.booleans()):
            extra["rest_length"] = draw(_decades(0.01, 2.0))
        m.add("spring", f"k{k}", nodes, k=draw(_decades(0.5, 5e3)), **extra)
        if draw(st.booleans()):
            m.add("damper", f"c{k}", nodes, c=draw(_decades(1e-3, 10.0)))
    if draw(st.booleans()):
        m.add("force", "F", f"p{n - 1}", F=draw(_decades(0.1, 10.0)) * sp.sin(draw(_decades(0.3, 30.0)) * lg.t))
    if draw(st.booleans()):
        m.add("gravity", "g", g=draw(_decades(1.0, 20.0)), **draw(st.sampled_from([{}, {"direction": (1.0,)}])))
    return m


@settings(max_examples=40, deadline=None)
@given(networks(), st.integers(0, 2**32 - 1))
def test_rhs_and_energies_equal_the_symbolic_derivation(m, seed):
    st_ = local_stamps(m)
    ours = AssembledModel(m, st_)
    reference = m.numeric()
    assert list(st_.names) == m.coordinate_names
    rng = np.random.default_rng(seed)
    n = st_.n
    for _ in range(3):
        y = np.concatenate([rng.uniform(-0.3, 0.3, n), rng.uniform(-2.0, 2.0, n)])
        time = float(rng.uniform(0.0, 5.0))
        a, b = ours.rhs(time, y), reference.rhs(time, y)
        assert np.allclose(a, b, rtol=1e-9, atol=1e-9 * np.abs(b).max()), (a, b)
        q, v = y[:n, None], y[n:, None]
        for x, ref in zip(ours.energies(np.array([time]), q, v), reference.energies(np.array([time]), q, v)):
            assert np.allclose(x, ref, rtol=1e-9, atol=1e-12 * (1 + np.abs(ref).max()))


def test_each_potential_expression_is_derived_once_for_all_its_components():
    m = models.spring_chain(40, m=[0.3 + 0.01 * i for i in range(40)], k=[40.0 + i for i in range(40)], beta=2e4)
    m.add("spring", "tail", ("p39", "ground"), k=7.0, rest_length=0.25, beta=0.0)  # a beta given: the same expression
    ours = AssembledModel(m, local_stamps(m))
    assert len(ours.kernels) == 1 and len(ours.kernels[0].names) == 41
    assert {k.energy for k in ours.kernels} == {assemble_local(m).potentials["k0"].energy}


def fput(n: int):
    m = models.spring_chain(n, m=1.0, k=100.0, beta=1e6)
    m.add("spring", f"k{n}", (f"p{n - 1}", "ground"), k=100.0, beta=1e6)
    start = {f"x_p{i}": 0.05 * np.sin(np.pi * (n // 10) * (i + 1) / (n + 1)) for i in range(n)}
    return m, start


def test_a_large_cubic_chain_runs_assembled_and_agrees_with_the_symbolic_path():
    n = assembled.ASSEMBLED_MIN + 10
    m, start = fput(n)
    still = {name: 0.0 for name in start}
    res = m.simulate(0.2, initial=start, velocity=still, points=21)
    assert res.method == "DOP853"
    assert "assembled in numbers" in res.notes[0] and f"{n + 1} nonlinear potentials" in res.notes[0]
    assert "assembly" not in m._cache and "equations" not in m._cache  # nothing symbolic was built
    energy = res.T + res.V
    assert np.max(np.abs(energy - energy[0])) <= 1e-8 * energy[0]  # conservative: the Jacobi integral T + V
    assert "energy (Jacobi integral) kept" in res.notes[-1]
    ref = m.simulate(0.2, initial=start, velocity=still, points=21, compiled="tape")  # the symbolic path
    assert not any("assembled" in note for note in ref.notes)
    scale = max(abs(x) for x in start.values())
    for name in m.coordinate_names:
        assert np.max(np.abs(res[name] - ref[name])) <= 1e-8 * scale
    assert np.allclose(res.V, ref.V, rtol=1e-9)
    # quantities come from the symbolic model, derived on that request
    x = m.coordinates[-1].function
    assert np.allclose(res.quantity(3 * x), 3 * res[f"x_p{n - 1}"], rtol=1e-14, atol=0)


def test_a_damped_driven_chain_runs_assembled_and_agrees():
    n = assembled.ASSEMBLED_MIN
    m = models.spring_chain(n, m=[0.3 + 0.01 * (i % 7) for i in range(n)], k=[40.0 + i % 5 for i in range(n)], c=0.02,
                            force=0.5 * sp.sin(3 * lg.t))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # (coordinates left at zero)
        res = m.simulate(0.5, initial={"x_p0": 0.01}, points=11)
        ref = m.simulate(0.5, initial={"x_p0": 0.01}, points=11, compiled="tape")
    assert "assembled in numbers" in res.notes[0] and "nonlinear" not in res.notes[0]
    assert not any("energy" in note for note in res.notes)  # it dissipates, and is driven: nothing to check
    for name in ("x_p0", f"x_p{n - 1}"):
        assert np.allclose(res[name], ref[name], rtol=0, atol=1e-9 * 0.01)
    assert np.allclose(res.D, ref.D, rtol=1e-8, atol=1e-16)
    assert res.defaulted == ref.defaulted


@pytest.mark.parametrize("ask", [
    {"params": {"k_k0": 50.0}}, {"compiled": True}, {"method": "RK45"}, {"method": "auto"},
    {"events": [lg.Event(lambda t, q, v: q["x_p0"] - 1.0)]},
])
def test_the_symbolic_path_serves_what_the_assembled_one_does_not(ask):
    assert assembled.wanted("DOP853", None, (), (), "auto")
    assert not assembled.wanted(ask.get("method", "DOP853"), ask.get("params"), ask.get("events", ()), (),
                                ask.get("compiled", "auto"))


def test_small_or_symbolic_models_keep_the_symbolic_path():
    m, start = fput(assembled.ASSEMBLED_MIN - 1)
    assert assembled.stamps_for_run(m) is None
    m, start = fput(assembled.ASSEMBLED_MIN)
    assert assembled.stamps_for_run(m) is not None
    m.add("spring", "soft", ("p0", "p3"), k=sp.Symbol("k_s"))  # a stiffness without a value
    assert assembled.stamps_for_run(m) is None
    m, start = fput(assembled.ASSEMBLED_MIN)
    m.add("damper", "lone", ("p2", "p_free"), c=0.3)  # a node with a damper and no mass: first-order
    assert assembled.stamps_for_run(m) is None


def test_linear_analyses_refuse_a_potential_by_name_and_take_the_symbolic_path():
    m, start = fput(assembled.ASSEMBLED_MIN)
    with pytest.raises(NotStampable, match=r"spring 'k0' is nonlinear"):
        assemble_numeric(m)
    m2 = lg.Model("duffing")
    m2.add("mass", "m", "p", m=0.3)
    m2.add("spring", "k", ("ground", "p"), k=40.0, beta=2e4)
    res = m2.simulate(0.5, initial={"x_p": 0.1}, velocity={"x_p": 0.0}, method="auto", points=3)
    assert res.method != "exact"


class _Odd(lg.Component):
    """A spring whose potential holds a symbol that is no placeholder."""

    kind = "odd_spring"
    domain = "mechanical"
    terminals = ("a", "b")
    parameters = {"k": lg.Parameter("stiffness")}

    def contribute(self, ctx):
        d = ctx.view.position(self.nodes[1])[0] - ctx.view.position(self.nodes[0])[0]
        return lg.Contribution(V=self.k * d**2 / 2)

    def linear(self, ctx):
        (x,), (p,) = Potential.placeholders(1, 1)
        return Linear(potential=Potential(p * x**2 / 2 + sp.Symbol("stray") * x, (float(ctx.number(self, "k")),)))

    @classmethod
    def example(cls):
        return lg.Example(("ground", "p"), {"k": 2.0}, context=[("mass", "m", "p", {"m": 1.0})])


def test_a_potential_with_a_stray_symbol_is_refused_by_name(registry_with):
    m = lg.Model("odd", registry=registry_with(_Odd))
    for i in range(3):
        m.add("mass", f"m{i}", f"p{i}", m=0.3)
        m.add("spring", f"k{i}", ("ground", f"p{i}"), k=40.0, beta=2e4)
    m.add("odd_spring", "bad", ("p0", "p1"), k=3.0)
    with pytest.raises(NotStampable, match=r"odd_spring 'bad'.*stray.*no placeholder"):
        assemble_local(m)
    assert assembled.stamps_for_run(m) is None


def test_a_pickled_model_runs_assembled_in_a_fresh_process():
    m, start = fput(assembled.ASSEMBLED_MIN)
    still = {name: 0.0 for name in start}
    res = m.simulate(0.05, initial=start, velocity=still, points=3)
    blob = pickle.dumps((m, start, still))
    code = ("import pickle, sys, numpy as np; m, s, v = pickle.loads(sys.stdin.buffer.read()); "
            "r = m.simulate(0.05, initial=s, velocity=v, points=3); "
            "print(r.notes[0][:30]); print(repr(float(r['x_p3'][-1])))")
    out = subprocess.run([sys.executable, "-c", code], input=blob, capture_output=True, check=True).stdout.decode()
    note, last = out.strip().splitlines()
    assert note == res.notes[0][:30]
    assert abs(float(last) - float(res["x_p3"][-1])) <= 1e-12 * 0.05


def test_a_result_of_the_assembled_path_pickles_and_still_evaluates_quantities():
    m, start = fput(assembled.ASSEMBLED_MIN)
    res = m.simulate(0.05, initial=start, velocity={name: 0.0 for name in start}, points=3)
    back = pickle.loads(pickle.dumps(res))
    x = m.coordinates[0].function
    assert np.array_equal(back.quantity(2 * x), 2 * res["x_p0"])


def test_step_with_the_default_method_is_refused_as_on_the_symbolic_path():
    m, start = fput(assembled.ASSEMBLED_MIN)
    with pytest.raises(lg.ModelError, match=r"adaptive: step= does not apply"):
        m.simulate(0.05, initial=start, velocity={name: 0.0 for name in start}, step=1e-3)
