"""Banded solves (:mod:`lagrangian.numerics.band`): large sparse systems solved in linear time, against the exact
solution of the same linear models (``method="exact"``, an independent engine) and against the dense solve."""

import math

import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings, strategies as st

import lagrangian as lg
from lagrangian import models
from lagrangian.numerics import band
from lagrangian.numerics.c_source import band_of

pytestmark = pytest.mark.filterwarnings("ignore::lagrangian.InitialConditionWarning")  # (starts at rest, on purpose)


def chain(n: int) -> lg.Model:
    """Masses on absolute coordinates, each tied to the last by a spring and a damper: a diagonal mass matrix."""
    return models.spring_chain(n, m=[0.3 + 0.01 * (i % 7) for i in range(n)], k=[40.0 + i % 5 for i in range(n)],
                               c=0.02, force=0.5 * sp.sin(3 * lg.t))


def ladder(n: int) -> lg.Model:
    """Capacitors in series along a line and to ground, inductors and resistors to ground, in node fluxes: a
    tridiagonal capacitance matrix."""
    m = lg.Model("capacitor ladder", formulation="flux")
    m.add("voltage_source", "V1", ("n0", "ground"), E=sp.sin(2 * lg.t))
    m.add("resistor", "R0", ("n0", "a0"), R=1.0)
    for i in range(n):
        a, b = f"a{i}", f"a{i + 1}"
        m.add("capacitor", f"Cs{i}", (a, b), C=0.5 + 0.01 * (i % 5))
        m.add("capacitor", f"Cg{i}", (b, "ground"), C=1.0)
        m.add("inductor", f"L{i}", (b, "ground"), L=2.0 + 0.1 * (i % 3))
        m.add("resistor", f"R{i + 1}", (b, "ground"), R=10.0)
    m.add("capacitor", "Cin", ("a0", "ground"), C=1.0)
    return m


def test_the_plan_finds_the_band_after_renumbering():
    x = sp.symbols("x0:60")
    n = 60
    order = np.random.default_rng(3).permutation(n)  # a tridiagonal system with its unknowns shuffled
    entries = {(int(order[i]), int(order[i])): 2 + x[i] ** 2 for i in range(n)}
    entries |= {(int(order[i]), int(order[i + 1])): -x[i] for i in range(n - 1)}
    entries |= {(int(order[i + 1]), int(order[i])): -x[i] for i in range(n - 1)}
    found = band.plan(sp.SparseMatrix(n, n, entries), constraints=0)
    assert (found.kl, found.ku, len(found.pattern)) == (1, 1, 3 * n - 2)
    assert band.plan(sp.SparseMatrix(n, n, entries), constraints=2) is None  # (multipliers: the dense solve)
    full = sp.SparseMatrix(n, n, {(i, j): x[i] + x[j] for i in range(n) for j in range(n)})
    assert band.plan(full, constraints=0) is None  # as wide as it is large


def test_large_models_take_the_banded_solve_and_small_ones_the_dense_one():
    assert band_of(chain(band.BAND_FROM).eq) is not None
    assert band_of(chain(band.BAND_FROM // 2).eq) is None
    wheel = chain(band.BAND_FROM)
    wheel.add("inertia", "J", "w", J=2e-3)
    wheel.add("constraint", "roll", f=lg.coordinate("x_p0") - 0.1 * lg.coordinate("theta_w"))
    assert band_of(wheel.eq) is None  # constraints: the dense solve, which balances their rows


def decades(low, high):
    return st.floats(math.log10(low), math.log10(high)).map(lambda e: 10.0**e)


LADDER = ladder(40)


@settings(max_examples=6, deadline=None)
@given(C=decades(1e-9, 1e-3), L=decades(1e-6, 1e-1), rho=decades(0.3, 30.0), ratio=decades(0.1, 10.0))
def test_a_banded_run_matches_the_exact_solution_over_decades(C, L, rho, ratio):
    """Capacitances and inductances over six decades; the resistances (ρ√(L/C)) and series capacitances (a ratio of
    the shunt ones) keep the time scales together, so that the explicit default method is the right one."""
    R = rho * math.sqrt(L / C)
    params = {}
    for i in range(40):
        params |= {f"C_Cs{i}": ratio * C * (1 + 0.1 * (i % 5)), f"C_Cg{i}": C, f"L_L{i}": L * (1 + 0.1 * (i % 3)),
                   f"R_R{i + 1}": R}
    params |= {"C_Cin": C, "R_R0": R}
    span = 10 * math.sqrt(L * C)
    kw = dict(params=params, points=21)
    exact = LADDER.simulate(span, method="exact", **kw)
    scale = max(float(np.max(np.abs(exact[name]))) for name in LADDER.coordinate_names)
    run = LADDER.simulate(span, rtol=1e-10, atol=1e-12 * scale, **kw)
    assert any("the solve banded: 41 unknowns within 1 + 1 diagonals" in n for n in run.notes)
    for name in ("lambda_a1", "lambda_a20", "lambda_a40"):
        np.testing.assert_allclose(run[name], exact[name], rtol=0, atol=1e-7 * scale, err_msg=name)


def test_native_and_tape_run_the_band_alike_and_a_dense_solve_agrees():
    model = ladder(40)
    kw = dict(points=11, rtol=1e-10)
    tape = model.simulate(2.0, compiled="tape", **kw)
    native = model.simulate(2.0, compiled="native", **kw)
    assert "the solve banded" in tape.notes[0] and "the solve banded" in native.notes[0]
    for name in model.coordinate_names:
        np.testing.assert_array_equal(native[name], tape[name])
    old = band.BAND_FROM
    try:
        band.BAND_FROM = 10**9
        dense = ladder(40).simulate(2.0, compiled="tape", **kw)
    finally:
        band.BAND_FROM = old
    assert "the solve banded" not in dense.notes[0]
    for name in model.coordinate_names:
        scale = float(np.max(np.abs(dense[name])))
        np.testing.assert_allclose(tape[name], dense[name], rtol=0, atol=1e-9 * scale)


def test_a_chain_of_two_hundred_masses_runs_by_default_and_matches_the_exact_solution():
    model = chain(200)
    kw = dict(initial={"x_p0": 0.01}, points=11)
    run = model.simulate(1.0, **kw)
    assert run.method == "DOP853" and any("the solve banded: 200 unknowns within 0 + 0" in n for n in run.notes)
    exact = model.simulate(1.0, method="exact", **kw)
    for name in ("x_p0", "x_p1", "x_p199"):
        scale = float(np.max(np.abs(exact[name])))
        np.testing.assert_allclose(run[name], exact[name], rtol=0, atol=1e-6 * scale, err_msg=name)
