"""Circuits assembled in numbers (``lagrangian.derivation.numeric``) against the symbolic derivation and ngspice.

The reference for every linearization here is the model's symbolic derivation (its Lagrangian differentiated, the
path every model can take); the numeric assembly must give the same coordinates, matrices, output rows and operating
values, on circuits drawn at random with values over decades.  The banded solver of frequency responses is checked
against dense LAPACK solves (``lagrangian.analysis.laplace``).
"""

from __future__ import annotations

from contextlib import contextmanager
from unittest import mock

import numpy as np
import pytest
from hypothesis import example, given, settings, strategies as st

import lagrangian as lg
from lagrangian import models
import lagrangian.analysis.laplace as laplace
import lagrangian.analysis.linearize as linearize_module
from lagrangian.analysis.lti import numeric
from lagrangian.derivation.numeric import assemble_numeric
from lagrangian.derivation.stamps import NotStampable
from lagrangian.frequency import frequency_response, linearize


@contextmanager
def derived_only():
    """Linearizations derived symbolically: neither the numeric assembly nor the stamps."""
    with mock.patch.object(linearize_module, "numeric", lambda *a, **k: None), \
            mock.patch.object(linearize_module, "stamped", lambda *a, **k: None):
        yield


def _close(a, b, what):
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    assert a.shape == b.shape, what
    scale = max(np.abs(b).max(initial=0.0), 1e-300)
    assert np.abs(a - b).max(initial=0.0) <= 1e-11 * scale, f"{what}:\n{a}\n{b}"


def _padded(rows, count):
    rows = [np.asarray(r, dtype=float) for r in rows]
    return rows + [np.zeros_like(rows[0])] * (count - len(rows))


def same_linearization(fast, slow):
    assert fast.coordinates == slow.coordinates
    assert fast.inputs == slow.inputs and fast.outputs == slow.outputs
    for name in ("M", "C", "K", "Bi", "Di"):
        _close(getattr(fast, name), getattr(slow, name), name)
    for name in ("B", "Cq", "D"):
        a, b = getattr(fast, name), getattr(slow, name)
        count = max(len(a), len(b))
        for k, (x, y) in enumerate(zip(_padded(a, count), _padded(b, count))):
            _close(x, y, f"{name}[{k}]")
    assert fast.first_order == slow.first_order
    for label in slow.y0:
        assert fast.y0[label] == pytest.approx(float(slow.y0[label]), rel=1e-9, abs=1e-12)
    for name in slow.at:
        assert float(fast.at[name]) == pytest.approx(float(slow.at[name]), rel=1e-9, abs=1e-12)


values = st.floats(-4, 4).map(lambda e: float(f"{10 ** e:.3g}"))  # values as users type them, over decades


@st.composite
def circuits(draw):
    """A random RLC network: every node has a capacitor to ground (so every coordinate has inertia or
    dissipation), a tree of resistors and inductors joins the nodes, a few more join random pairs; a voltage
    source behind a resistor (loop charges) or a current source (node fluxes) drives node n1."""
    formulation = draw(st.sampled_from(["charge", "flux"]))
    nodes = draw(st.integers(1, 5))
    m = lg.Model("random", formulation=formulation)
    names = [f"n{i}" for i in range(1, nodes + 1)]
    scale = {"resistor": ("R", 1e2), "inductor": ("L", 1e-3), "capacitor": ("C", 1e-6)}

    def element(kind, a, b):
        pname, unit = scale[kind]
        m.add(kind, f"{pname}{len(m.components)}", (a, b), **{pname: draw(values) * unit})

    for i, node in enumerate(names):
        element("capacitor", node, "0")
        if i:
            element(draw(st.sampled_from(["resistor", "inductor"])), names[draw(st.integers(0, i - 1))], node)
    for _ in range(draw(st.integers(0, 3))):
        a = draw(st.sampled_from(names))
        b = draw(st.sampled_from([n for n in names + ["0"] if n != a]))
        element(draw(st.sampled_from(["resistor", "inductor"])), a, b)
    if formulation == "charge":
        m.add("voltage_source", "V1", ("in", "0"), E=draw(st.sampled_from([0.0, 1.5])))
        element("resistor", "in", "n1")
    else:
        m.add("current_source", "I1", ("0", "n1"), I=draw(st.sampled_from([0.0, 2e-3])))
    elements = [c.name for c in m.components.values() if c.kind != "coupling"]
    outputs = draw(st.lists(st.sampled_from(
        [f"v({e})" for e in elements] + [f"i({e})" for e in elements] + [f"v({n})" for n in names]
        + [c + p for c in m.coordinate_names for p in ("", "'", "''")]), min_size=1, max_size=4, unique=True))
    return m, outputs


@settings(max_examples=40, deadline=None)
@given(circuits())
def test_a_random_circuit_in_numbers_is_its_derivation(case):
    m, outputs = case
    source = "V1" if "V1" in m.components else "I1"
    assert numeric(m, [source], outputs, 0.0) is not None  # the numeric path applies: what is compared is it
    fast = linearize(m, inputs=[source], outputs=outputs)
    with derived_only():
        slow = linearize(m, inputs=[source], outputs=outputs)
    same_linearization(fast, slow)


@pytest.mark.parametrize("formulation", ["charge", "flux"])
def test_coupled_inductors_in_numbers_are_their_derivation_and_ngspice(formulation):
    from lagrangian.ac import compare_ac_with_ngspice

    m = lg.Model("transformer", formulation=formulation)
    if formulation == "charge":
        m.add("voltage_source", "V1", ("in", "0"), E=0)
        m.add("resistor", "R1", ("in", "a"), R=47.0)
        source = "V1"
    else:
        m.add("current_source", "V1", ("0", "a"), I=0)
        m.add("resistor", "R1", ("a", "0"), R=470.0)
        source = "V1"
    m.add("inductor", "L1", ("a", "0"), L=7e-3)
    m.add("inductor", "L2", ("b", "0"), L=2.2e-3)
    m.add("capacitor", "C1", ("a", "0"), C=3.3e-6)
    m.add("capacitor", "C2", ("b", "0"), C=1e-6)
    m.add("resistor", "R2", ("b", "0"), R=220.0)
    m.add("coupling", "K1", inductor1="L1", inductor2="L2", k=0.6)
    outputs = ["v(L1)", "i(L1)", "v(L2)", "i(L2)", "v(b)"]
    assert numeric(m, [source], outputs, 0.0) is not None
    fast = linearize(m, inputs=[source], outputs=outputs)
    with derived_only():
        slow = linearize(m, inputs=[source], outputs=outputs)
    same_linearization(fast, slow)
    cmp = compare_ac_with_ngspice(m, input=source, outputs=outputs, start=10.0, stop=1e5, points=20)
    assert cmp.worst_rel < 1e-9, cmp.table()


def test_a_gyrator_in_numbers_is_its_derivation():
    m = lg.Model("gyrated")
    m.add("voltage_source", "V1", ("n0", "0"), E=0.5)
    m.add("resistor", "R", ("n0", "n1"), R=6.0)
    m.add("inductor", "L1", ("n1", "n4"), L=0.5e-3)
    m.add("gyrator", "G", ("n4", "0", "n2", "0"), r=7.0)
    m.add("inductor", "L2", ("n2", "n3"), L=0.02)
    m.add("capacitor", "C2", ("n3", "0"), C=5e-4)
    m.add("resistor", "R2", ("n2", "n3"), R=1 / 1.5)
    outputs = ["i(V1)", "v(C2)", "i(G)", "q_L1'"]
    assert numeric(m, ["V1"], outputs, 0.0) is not None
    fast = linearize(m, inputs=["V1"], outputs=outputs)
    with derived_only():
        slow = linearize(m, inputs=["V1"], outputs=outputs)
    same_linearization(fast, slow)


def test_a_source_at_its_operating_value_sets_the_rest_point_and_the_outputs_there():
    """A DC source: the capacitor charges to E·C, its voltage is E, and the current is 0 (the numeric path's rest
    point and output values, against the circuit's DC solution)."""
    m = lg.Model("dc")
    m.add("voltage_source", "V1", ("in", "0"), E=1.5)
    m.add("resistor", "R1", ("in", "a"), R=330.0)
    m.add("inductor", "L1", ("a", "b"), L=7e-3)
    m.add("capacitor", "C1", ("b", "0"), C=2.2e-6)
    lin = linearize(m, inputs=["V1"], outputs=["v(C1)", "i(L1)", "v(V1)", "v(a)"])
    assert float(lin.at["q_L1"]) == pytest.approx(1.5 * 2.2e-6, rel=1e-12)
    assert lin.y0 == pytest.approx({"v(C1)": 1.5, "i(L1)": 0.0, "v(V1)": 1.5, "v(a)": 1.5}, rel=1e-12, abs=1e-15)
    assert lin.u0 == {"V1": 1.5}


@pytest.mark.parametrize("build", [
    # a current source fixes its loop's charge: a branch not in numbers alone
    lambda: [("current_source", "I1", ("0", "n1"), {"I": 0}), ("resistor", "R", ("n1", "0"), {"R": 1.0}),
             ("capacitor", "C", ("n1", "0"), {"C": 1e-6})],
    # a parameter without a value
    lambda: [("voltage_source", "V1", ("n1", "0"), {"E": 0}), ("resistor", "R", ("n1", "n2"), {"R": lg.t * 0 + 5}),
             ("capacitor", "C", ("n2", "0"), {"C": __import__("sympy").Symbol("C", positive=True)})],
])
def test_what_is_not_in_numbers_takes_the_symbolic_path(build):
    m = lg.Model("fallback")
    for kind, name, nodes, params in build():
        m.add(kind, name, nodes, **params)
    source = next(c.name for c in m.components.values() if "source" in c.kind)
    with pytest.raises(NotStampable):
        assemble_numeric(m)
    assert numeric(m, [source], None, 0.0) is None
    lin = linearize(m, inputs=[source])  # the symbolic path answers
    assert lin.coordinates == m.coordinate_names


def test_an_expression_output_takes_the_symbolic_path_and_agrees():
    m = lg.Model("rc")
    m.add("voltage_source", "V1", ("in", "0"), E=0)
    m.add("resistor", "R1", ("in", "out"), R=1e3)
    m.add("capacitor", "C1", ("out", "0"), C=2.2e-6)
    q = lg.coordinate("q_R1")
    assert numeric(m, ["V1"], [3 * q], 0.0) is None
    lin = linearize(m, inputs=["V1"], outputs=[3 * q, "q_R1"])
    assert np.allclose(lin.Cq[0], [[3.0], [1.0]])


def test_bad_inputs_are_refused_on_the_numeric_path_as_on_the_symbolic_one():
    m = lg.Model("rc")
    m.add("voltage_source", "V1", ("in", "0"), E=0)
    m.add("resistor", "R1", ("in", "out"), R=1e3)
    m.add("capacitor", "C1", ("out", "0"), C=2.2e-6)
    with pytest.raises(lg.UnknownNameError, match="V2"):
        linearize(m, inputs=["V2"])
    with pytest.raises(lg.ModelError, match="no signal parameter"):
        linearize(m, inputs=["R1"])


# ---------------------------------------------------------------------------
# the banded solve without pivoting, checked by its residual
# ---------------------------------------------------------------------------


def _dense(A, lower):
    """The matrices of a band stack ``A[i, d, f]`` as a dense stack ``out[f]``."""
    N, W, F = A.shape
    out = np.zeros((F, N, N), dtype=complex)
    for i in range(N):
        for d in range(W):
            j = i + d - lower
            if 0 <= j < N:
                out[:, i, j] = A[i, d]
    return out


@settings(max_examples=30, deadline=None)
@given(st.integers(2, 30), st.integers(0, 3), st.integers(0, 3), st.integers(0, 2**32 - 1))
def test_the_banded_solve_is_a_dense_solve_where_its_residual_says_so(N, lower, upper, seed):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(N, lower + upper + 1, 5)) + 1j * rng.normal(size=(N, lower + upper + 1, 5))
    A *= 10.0 ** rng.uniform(-3, 3, size=5)
    b = rng.normal(size=(N, 2, 5)) + 0j
    y = laplace._band_solve(A, b, lower, upper)
    ok = laplace._residual(A, y, b, lower)[0] <= laplace.BACKWARD
    dense = np.linalg.solve(_dense(A, lower), np.moveaxis(b, -1, 0))
    for f in range(5):
        expected = dense[f]
        got = y[:, :, f] if ok[f] else laplace._gbsv(A[:, :, f], b[:, :, f], lower, upper)
        assert np.allclose(got, expected, rtol=1e-6, atol=1e-9 * np.abs(expected).max())


def test_a_zero_pivot_is_caught_by_the_residual_and_solved_with_pivoting():
    A = np.zeros((3, 3, 1), dtype=complex)  # tridiagonal [[0, 1, 0], [1, 2, 1], [0, 1, 3]]
    A[:, 1, 0] = [0, 2, 3]
    A[:-1, 2, 0] = 1
    A[1:, 0, 0] = 1
    b = np.array([[1.0], [2.0], [3.0]], dtype=complex)[:, :, None]
    y = laplace._band_solve(A, b, 1, 1)
    assert not laplace._residual(A, y, b, 1)[0][0] <= laplace.BACKWARD
    fixed = laplace._gbsv(A[:, :, 0], b[:, :, 0], 1, 1)
    assert np.allclose(_dense(A, 1)[0] @ fixed, b[:, :, 0], rtol=1e-14, atol=1e-14)


@settings(max_examples=40, deadline=None)
@given(st.integers(1, laplace.SMALL_MAX), st.floats(0.2, 1.0), st.booleans(), st.booleans(), st.integers(0, 2**32 - 1))
def test_the_small_solve_is_a_dense_solve_where_its_residual_says_so(N, density, by_entries, dominant, seed):
    """Random complex systems with a random symmetric pattern of nonzeros (the diagonal kept), solved by blocks or
    entry by entry along the pattern: where the backward error passes, LAPACK's answer; and it passes everywhere
    for a diagonally dominant system (no pivoting needed)."""
    rng = np.random.default_rng(seed)
    pattern = rng.random((N, N)) < density
    pattern |= pattern.T | np.eye(N, dtype=bool)
    A = (rng.normal(size=(N, N, 5)) + 1j * rng.normal(size=(N, N, 5))) * pattern[:, :, None]
    if dominant:
        A += 4 * N * np.eye(N)[:, :, None]
    A *= 10.0 ** rng.uniform(-3, 3, size=5)
    b = rng.normal(size=(N, 2, 5)) + 0j
    plan = laplace._elimination_plan(pattern) if by_entries else None
    y = laplace._eliminate_small(A.copy(), b.copy(), plan)
    ok = laplace._small_residual(A, np.abs(A), y, b)[0] <= laplace.BACKWARD
    assert ok.all() or not dominant
    dense = np.linalg.solve(np.moveaxis(A, -1, 0), np.moveaxis(b, -1, 0))
    for f in np.flatnonzero(ok):
        assert np.allclose(y[:, :, f], dense[f], rtol=1e-6, atol=1e-9 * np.abs(dense[f]).max())


@settings(max_examples=40, deadline=None)
@given(st.integers(1, laplace.SMALL_MAX), st.floats(0.2, 1.0), st.booleans(), st.integers(0, 2**32 - 1))
def test_the_small_solves_screen_bounds_the_inverse_from_above(N, density, by_entries, seed):
    """``⟨U⟩⁻¹ ⟨L⟩⁻¹ z`` from the factors the elimination leaves is at least ``|P⁻¹| z`` (LAPACK's inverse) at every
    frequency whose backward error passed: the screen of the error bound never vouches for less than it is."""
    rng = np.random.default_rng(seed)
    pattern = rng.random((N, N)) < density
    pattern |= pattern.T | np.eye(N, dtype=bool)
    A = (rng.normal(size=(N, N, 5)) + 1j * rng.normal(size=(N, N, 5))) * pattern[:, :, None]
    A *= 10.0 ** rng.uniform(-3, 3, size=(N, 1, 5))  # rows scaled over decades
    b = rng.normal(size=(N, 2, 5)) + 0j
    z = np.abs(rng.normal(size=(N, 2, 5)))
    plan = laplace._elimination_plan(pattern) if by_entries else None
    LU = A.copy()
    y = laplace._eliminate_small(LU, b.copy(), plan)
    ok = laplace._small_residual(A, np.abs(A), y, b)[0] <= laplace.BACKWARD
    screen = laplace._small_comparison_solve(LU, z, plan)
    inverse = np.abs(np.linalg.inv(np.moveaxis(A, -1, 0)))
    for f in np.flatnonzero(ok):
        assert np.all(screen[:, :, f] >= (1 - 1e-9) * (inverse[f] @ z[:, :, f]))


@settings(max_examples=30, deadline=None)
@given(st.integers(2, 30), st.integers(1, 3), st.integers(1, 3), st.integers(0, 2**32 - 1))
def test_the_banded_solves_screen_bounds_the_inverse_from_above(N, lower, upper, seed):
    """As for the small solve: from a tridiagonal system's pivots, or a wider band's factors."""
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(N, lower + upper + 1, 5)) + 1j * rng.normal(size=(N, lower + upper + 1, 5))
    A *= 10.0 ** rng.uniform(-3, 3, size=(N, 1, 5))
    A[:, lower] += 3 * (lower + upper)  # mostly no small pivot
    b = rng.normal(size=(N, 1, 5)) + 0j
    z = np.abs(rng.normal(size=(N, 2, 5)))
    y, factors = laplace._band_factor_solve(A, b, lower, upper)
    ok = laplace._residual(A, y, b, lower)[0] <= laplace.BACKWARD
    assert ok.any()
    screen = laplace._band_comparison_solve(A, factors, z, lower, upper)
    inverse = np.abs(np.linalg.inv(_dense(A, lower)))
    for f in np.flatnonzero(ok):
        assert np.all(screen[:, :, f] >= (1 - 1e-9) * (inverse[f] @ z[:, :, f]))


def _tank_at_a_millihertz():
    """1 mH across 10 nF, fed through 10 Ω: in loop charges ``P = [[L s² + 1/C, −1/C], [−1/C, R s + 1/C]]``, whose
    ``L s²`` (4e-8 at 1 mHz) is lost beside ``1/C`` (1e8) in doubles: returned as it came, ``v(C0)`` was wrong in its
    first digit at 1 mHz and 3.5 mHz, and right to three digits at 12 mHz."""
    m = lg.Model("tank", formulation="charge")
    m.add("capacitor", "C0", ("n1", "0"), C=1e-8)
    m.add("inductor", "L1", ("n1", "0"), L=1e-3)
    m.add("voltage_source", "V1", ("in", "0"), E=0.0)
    m.add("resistor", "R3", ("in", "n1"), R=10.0)
    return m


def _parallel_coils_at_a_millihertz():
    """Two 1 mH coils in parallel between 1 µF and 1 nF, fed through 100 Ω: at 1 mHz their loop's ``L s²`` (4e-8)
    is lost beside ``1/C`` (1e9) in doubles, where ``P`` is singular though the exact matrices are not."""
    m = lg.Model("parallel coils", formulation="charge")
    m.add("capacitor", "C0", ("n1", "0"), C=1e-6)
    m.add("capacitor", "C1", ("n2", "0"), C=1e-9)
    m.add("resistor", "R2", ("n1", "n2"), R=100.0)
    m.add("inductor", "L3", ("n1", "n2"), L=1e-3)
    m.add("inductor", "L4", ("n1", "n2"), L=1e-3)
    m.add("voltage_source", "V1", ("in", "0"), E=0.0)
    m.add("resistor", "R6", ("in", "n1"), R=100.0)
    return m


def _error_bound(mpmath, P, lin, s, b_abs, P_abs, C_abs):
    """``(x, bound, singular)``: the solution of ``P x = b`` at 40 digits; per output, the first-order bound of the
    error of a componentwise backward-stable solve of it, ``16 ε Σ|s|ᵏ|Cq_k| (|P⁻¹| (|P| |x| + |b|) + |x|)``, with
    ``|P| = |M| |s|² + |C| |s| + |K|``; and whether ``P`` is singular within a thousand roundings of its entries
    (``ε ‖ |P⁻¹| |P| ‖∞ ≥ 1e-3``: no first-order bound holds, nor can one be computed in doubles).  ``(None, inf,
    True)`` when ``P`` is singular even at 40 digits."""
    N = len(P)
    ms = mpmath.mpc(0, s.imag)
    rhs = mpmath.matrix([sum(mpmath.mpf(B[a, 0]) * ms**j for j, B in enumerate(lin.B)) for a in range(N)])
    try:
        inverse = mpmath.inverse(P)
    except (ZeroDivisionError, TypeError):  # singular (mpmath's LU stumbles on a zero column with a TypeError)
        return None, np.full(len(lin.outputs), np.inf), True
    x = inverse * rhs
    x = np.array([complex(v) for v in x])
    inv_abs = np.array([[abs(complex(v)) for v in row] for row in inverse.tolist()])
    spread = inv_abs @ (P_abs @ np.abs(x) + b_abs) + np.abs(x)
    eps = np.finfo(float).eps
    return x, 16 * eps * (C_abs @ spread) + 1e-300, eps * (inv_abs @ P_abs).sum(axis=1).max() >= 1e-3


@settings(max_examples=25, deadline=None)
@given(circuits(), st.floats(0, 5))
@example((_parallel_coils_at_a_millihertz(), ["v(C0)"]), 0.0)
@example((_tank_at_a_millihertz(), ["v(C0)", "i(L1)"]), 0.0)
def test_a_small_circuits_response_is_within_the_error_bound_of_its_exact_response(case, decade):
    """Random circuits (values over eight decades: often ill-conditioned), twelve frequencies over six decades
    around a point drawn over five, each output against the exact response of the same floating-point matrices
    (mpmath, 40 digits).

    A value returned is within the first-order error bound of a componentwise backward-stable solve
    (:func:`_error_bound`) of the exact ``P = M s² + C s + K`` plus that of ``P`` as formed in doubles, which
    may be singular, or nearly, where the exact one is not (``L s²`` of 4e-8 lost beside ``1/C`` of 1e9).  (LAPACK
    with partial pivoting stays within 1× of the bound on such circuits; the solve without pivoting, within 1.4×.)
    A value refused must be one that the doubles' bound leaves without a certain digit, and the response must say
    why."""
    mpmath = pytest.importorskip("mpmath")
    m, outputs = case
    source = "V1" if "V1" in m.components else "I1"
    lin = linearize(m, inputs=[source], outputs=outputs)
    N = lin.size
    assert N <= laplace.SMALL_MAX and N == len(lin.coordinates)
    f = np.geomspace(10.0 ** (decade - 3), 10.0 ** (decade + 3), 12)
    resp = frequency_response(lin, f)
    got = resp.H
    exact = np.zeros((len(outputs), len(f)), dtype=complex)
    with mpmath.workdps(40):
        for k, fk in enumerate(f):
            s = 2j * np.pi * fk
            ms = mpmath.mpc(0, s.imag)
            exact_P = mpmath.matrix([[(mpmath.mpf(lin.M[a, b]) * ms + mpmath.mpf(lin.C[a, b])) * ms
                                      + mpmath.mpf(lin.K[a, b]) for b in range(N)] for a in range(N)])
            doubles = (lin.M * s + lin.C) * s + lin.K  # as a double-precision solver forms it
            doubles_P = mpmath.matrix([[mpmath.mpc(v.real, v.imag) for v in row] for row in doubles])
            P_abs = np.abs(lin.M) * abs(s) ** 2 + np.abs(lin.C) * abs(s) + np.abs(lin.K)
            b_abs = sum(np.abs(B[:, 0]) * abs(s) ** j for j, B in enumerate(lin.B))
            C_abs = sum(np.abs(c) * abs(s) ** j for j, c in enumerate(lin.Cq))
            x, bound, _ = _error_bound(mpmath, exact_P, lin, s, b_abs, P_abs, C_abs)
            x_doubles, bound_doubles, singular = _error_bound(mpmath, doubles_P, lin, s, b_abs, P_abs, C_abs)

            def output(x, o):
                return sum((c[o] @ x) * s**j for j, c in enumerate(lin.Cq)) + sum(d[o, 0] * s**j for j, d in enumerate(lin.D))

            for o in range(len(outputs)):
                exact[o, k] = output(x, o)
                if np.isfinite(got[o, 0, k]):
                    assert abs(got[o, 0, k] - exact[o, k]) <= bound[o] + bound_doubles[o], (outputs[o], fk)
                    continue
                # refused, and said so: only where the doubles leave no digit of it certain, or are singular
                # within rounding
                assert any("not finite" in n or "no certain digit" in n for n in resp.notes), (outputs[o], fk)
                assert singular or 4 * bound_doubles[o] >= abs(output(x_doubles, o)), (outputs[o], fk)
    # and no value returned is wrong in its first digit, unless below 1e-12 of its output's peak (a notch's depth)
    error = np.abs(got[:, 0, :] - exact)
    floor = 1e-12 * np.abs(exact).max(axis=1, keepdims=True)
    assert np.all(~np.isfinite(got[:, 0, :]) | (error <= np.maximum(0.5 * np.abs(exact), floor))), error


def _coiled_ladder(values, coil_at, formulation):
    """An RLC ladder (series ``R`` and ``L``, shunt ``C`` to ground), one shunt also holding a 1 mH coil: in loop
    charges, the coil's loop and its neighbour's share the capacitor's ``1/C``, beside which ``L s²`` is lost at
    low frequencies."""
    m = lg.Model("coiled ladder", formulation=formulation)
    m.add("voltage_source", "V1", ("n0", "0"), E=0.0)
    for k, (R, L, C) in enumerate(values):
        m.add("resistor", f"R{k}", (f"n{k}", f"m{k}"), R=R)
        m.add("inductor", f"L{k}", (f"m{k}", f"n{k + 1}"), L=L)
        m.add("capacitor", f"C{k}", (f"n{k + 1}", "0"), C=C)
        if k == coil_at:
            m.add("inductor", "Lp", (f"n{k + 1}", "0"), L=1e-3)
    return m


def _coiled_ladder_response(mpmath, values, coil_at, f):
    """The last capacitor's voltage per volt of the source, at 40 digits, by the ladder's impedances from its far end
    (``W_k = R_k + s L_k + 1/(Y_k + 1/W_{k+1})``) and the voltage divided down it: no matrix at all."""
    out = []
    with mpmath.workdps(40):
        for fk in f:
            s = mpmath.mpc(0, 2 * mpmath.pi * mpmath.mpf(fk))
            W, inv = [], mpmath.mpf(0)
            for k in reversed(range(len(values))):
                R, L, C = (mpmath.mpf(v) for v in values[k])
                Y = s * C + (1 / (s * mpmath.mpf(1e-3)) if k == coil_at else 0)
                W.append(R + s * L + 1 / (Y + inv))
                inv = 1 / W[-1]
            v = mpmath.mpf(1)
            for (R, L, _), w in zip(values, reversed(W)):
                v -= v / w * (mpmath.mpf(R) + s * mpmath.mpf(L))
            out.append(complex(v))
    return np.array(out)


@settings(max_examples=6, deadline=None)
@given(st.sampled_from([12, 45]), st.integers(0, 2**32 - 1), st.data())
def test_a_ladders_response_is_within_its_error_bound_on_the_dense_and_banded_paths(sections, seed, data):
    """A ladder of 12 sections (dense path) or 45 (banded), values over a decade, a coil across one capacitor, from
    a millihertz to 100 kHz, against its impedances at 40 digits: every value returned is within its error bound;
    values without a certain digit in loop charges are refused, and said so; in node fluxes, where nothing is
    lost, the same ladder is exact to 1e-9 of its peak at every frequency."""
    mpmath = pytest.importorskip("mpmath")
    rng = np.random.default_rng(seed)
    values = [(10 * 10 ** rng.uniform(0, 1), 1e-3 * 10 ** rng.uniform(0, 1), 1e-8 * 10 ** rng.uniform(0, 1))
              for _ in range(sections)]
    coil_at = data.draw(st.integers(0, sections - 1))
    f = np.geomspace(1e-3, 1e5, 17)
    exact = _coiled_ladder_response(mpmath, values, coil_at, f)
    peak = np.abs(exact).max()
    for formulation in ("charge", "flux"):
        lin = linearize(_coiled_ladder(values, coil_at, formulation), inputs=["V1"], outputs=[f"v(C{sections - 1})"])
        banded = lin.size >= laplace.BANDED_MIN and laplace._band(lin) is not None
        assert banded == (sections == 45) and lin.size > laplace.SMALL_MAX
        resp = frequency_response(lin, f)
        got, error = resp.H[0, 0], resp.error[0, 0]
        finite = np.isfinite(got)
        # the bound covers the solve's rounding, not that of the values themselves into doubles: 1e-15 of the peak
        assert np.all(np.abs(got - exact)[finite] <= 1.5 * error[finite] + 1e-15 * peak), formulation
        if formulation == "flux":
            assert finite.all() and np.abs(got - exact).max() <= 1e-9 * peak
        elif not finite.all():
            assert any("no certain digit" in n for n in resp.notes)
            assert np.all(error[~finite] >= 0.5 * np.abs(exact[~finite]))


def test_a_zero_pivot_of_a_small_system_is_solved_with_pivoting():
    """Two loops sharing a capacitor: at the first loop's own resonance its diagonal entry L s² + 1/C vanishes
    while the system does not (the shared capacitor couples the loops), and the current is the closed form's."""
    L1, C, L2, R = 7e-3, 2.2e-6, 4.7e-3, 33.0
    m = lg.Model("shared capacitor")
    m.add("voltage_source", "V1", ("in", "0"), E=0)
    m.add("inductor", "L1", ("in", "a"), L=L1)
    m.add("capacitor", "C", ("a", "0"), C=C)
    m.add("inductor", "L2", ("a", "b"), L=L2)
    m.add("resistor", "R", ("b", "0"), R=R)
    lin = linearize(m, inputs=["V1"], outputs=["i(L1)"])
    f0 = 1 / (2 * np.pi * np.sqrt(L1 * C))
    f = np.array([0.5 * f0, f0, 2 * f0])
    s = 2j * np.pi * f
    expected = 1 / (L1 * s + 1 / (C * s + 1 / (L2 * s + R)))  # the source's current: 1 / Z
    got = frequency_response(lin, f).H[0, 0]
    P = (lin.M[:, :, None] * s + lin.C[:, :, None]) * s + lin.K[:, :, None]
    assert np.min(np.abs(P[0, 0]) / np.abs(P).max(axis=(0, 1))) < 1e-12  # the first pivot is nothing at f0
    assert np.allclose(np.abs(got), np.abs(expected), rtol=1e-9)


def test_a_ladder_response_in_numbers_is_the_dense_response_of_its_derivation():
    m = models.rlc_ladder(50, seed=3)
    f = np.geomspace(1e-3, 1.0, 200)
    outputs = ["i(L0)", "v(C49)", "v(n25)"]
    fast = frequency_response(m, f, inputs=["V1"], outputs=outputs).H
    with derived_only():
        lin = linearize(m, inputs=["V1"], outputs=outputs)
    with mock.patch.object(laplace, "BANDED_MIN", 10**9):
        dense = frequency_response(lin, f).H
    floor = 1e-12 * np.abs(dense).max(axis=-1, keepdims=True)
    assert np.max(np.abs(fast - dense) / np.maximum(np.abs(dense), floor)) < 1e-10


@settings(max_examples=25, deadline=None)
@given(st.integers(1, 4), st.sampled_from(["translational", "rotational"]), st.data())
def test_a_chain_of_masses_or_rotors_in_numbers_is_its_derivation(n, kind, data):
    """Masses, springs, dampers and a force on one axis, or rotors, shafts, drag cups and a torque, springs with or
    without a rest length (angle), masses with or without gravity along the axis: the numeric linearization (its
    rest point moved by the constant loads) is the derived one."""
    mass, spring, damper, load, coordinate = (("mass", "spring", "damper", "force", "x") if kind == "translational"
                                              else ("inertia", "torsion_spring", "rotary_damper", "torque", "theta"))
    pname = {"mass": "m", "inertia": "J", "force": "F", "torque": "tau"}
    m = lg.Model("chain")
    prev = "ground"
    for i in range(n):
        m.add(mass, f"m{i}", f"p{i}", **{pname[mass]: data.draw(values) * 0.1})
        rest = {("rest_length" if kind == "translational" else "rest_angle"): data.draw(st.sampled_from([0.3, 1.7]))}
        m.add(spring, f"k{i}", (prev, f"p{i}"), k=data.draw(values) * 100, **(rest if data.draw(st.booleans()) else {}))
        if data.draw(st.booleans()):
            m.add(damper, f"c{i}", (prev, f"p{i}"), c=data.draw(values))
        prev = f"p{i}"
    if kind == "translational" and data.draw(st.booleans()):
        direction = data.draw(st.sampled_from([{}, {"direction": (1.0,)}, {"direction": (-2.0,)}]))
        m.add("gravity", "g", g=data.draw(st.sampled_from([9.81, 1.62])), **direction)
    m.add(load, "F", f"p{n - 1}", **{pname[load]: data.draw(st.sampled_from([0.0, 2.5]))})
    outputs = [f"{coordinate}_p{n - 1}", f"{coordinate}_p0'", f"{coordinate}_p0''"]
    assert numeric(m, ["F"], outputs, 0.0) is not None
    fast = linearize(m, inputs=["F"], outputs=outputs)
    with derived_only():
        slow = linearize(m, inputs=["F"], outputs=outputs)
    same_linearization(fast, slow)


def test_a_moving_coil_loudspeaker_in_numbers_is_its_derivation_and_so_is_its_analogue():
    from lagrangian.analogy import map_model

    m = models.loudspeaker()
    outputs = ["i(E)", "x_cone'", "v(Re)"]
    assert numeric(m, ["E"], outputs, 0.0) is not None
    fast = linearize(m, inputs=["E"], outputs=outputs)
    with derived_only():
        slow = linearize(m, inputs=["E"], outputs=outputs)
    same_linearization(fast, slow)
    analogue = map_model(m, "force-voltage")
    f = np.geomspace(5.0, 5e3, 50)
    mapped = frequency_response(analogue.model, f, inputs=["E"], outputs=["i(E)"]).H
    direct = frequency_response(m, f, inputs=["E"], outputs=["i(E)"]).H
    assert np.allclose(mapped, direct, rtol=1e-12, atol=0)
    # the coordinate map, solved when first asked for: the cone's position is the analogue's mass-loop charge
    assert {str(k.func): v for k, v in analogue.coordinates.items()} == {"q_L_m": lg.coordinate("x_cone"),
                                                                           "q_Le": lg.coordinate("q_Le")}


def test_a_base_excited_mass_is_not_in_numbers_and_takes_the_symbolic_path():
    m = lg.Model("isolator")
    m.add("prescribed_motion", "base", "b", position=0)
    m.add("mass", "m", "p", m=0.3)
    m.add("spring", "k", ("b", "p"), k=40.0)
    m.add("damper", "c", ("b", "p"), c=0.5)
    with pytest.raises(NotStampable, match="fix the branches"):
        assemble_numeric(m)
    lin = linearize(m, inputs=["base"], outputs=["x_p"])
    assert lin.coordinates == ["x_p"]


@settings(max_examples=200, deadline=None)
@given(st.integers(1, 6), st.lists(st.tuples(st.integers(0, 6), st.integers(0, 6), st.sampled_from([None, "across",
                                                                                                     "through"])),
                                   min_size=1, max_size=12))
def test_the_quick_topology_check_passes_exactly_the_networks_the_searches_pass(nodes, edges):
    """``_sound`` (union–find) lets a network through exactly when networkx's searches find nothing wrong."""
    import networkx as nx

    from lagrangian.base.network import _sound, check_topology
    from lagrangian.errors import TopologyError

    g = nx.MultiGraph()
    g.add_node("ground")
    names = ["ground"] + [f"n{i}" for i in range(nodes)]
    roles = {}
    for i, (a, b, role) in enumerate(edges):
        u, v = names[a % len(names)], names[b % len(names)]
        if u == v:
            continue
        g.add_edge(u, v, key=f"e{i}", a=u, b=v)
        roles[f"e{i}"] = role
    with mock.patch("lagrangian.base.network._sound", lambda *a: False):
        try:
            check_topology(g, "ground", roles.get)
            fine = True
        except TopologyError:
            fine = False
    assert _sound(g, "ground", roles.get) == fine


def test_a_plugins_component_in_numbers_is_assembled_in_numbers_and_agrees_with_its_energy():
    """A third-party component type, registered in-process, that says its contribution in numbers (``linear``) is
    assembled without symbolic work, and its linearization is that of its energy."""
    import types

    class GroundedCapacitor(lg.Component):
        """A capacitor to ground in loop charges (its own kind): V = q²/2C."""

        kind, domain, terminals = "grounded_capacitor", "electrical", ("a",)
        parameters = {"C": lg.Parameter("capacitance", unit="F")}

        def contribute(self, ctx):
            return lg.Contribution(V=ctx.view.charge(self) ** 2 / (2 * self.C))

        def linear(self, ctx):
            C = ctx.number(self, "C")
            return None if C is None else lg.Linear(V={(0, 0): 1 / C},
                                                    quantities={"v": lg.Quantity(((0, 0, 1 / C),))})

        quantities = {"v": "voltage to ground"}

        def quantity(self, ctx, name):
            return ctx.view.charge(self) / self.C

        @classmethod
        def example(cls):
            return lg.Example(("n1",), {"C": 1e-6}, context=[("inductor", "L", ("n1", "0"), {"L": 1e-3})])

    plugin = types.ModuleType("grounded_capacitor_plugin")
    plugin.register_component_types = lg.hookimpl(lambda register: register(GroundedCapacitor))
    registry = lg.Registry(plugins={"grounded_capacitor_plugin": plugin})
    m = lg.Model("rlc", registry=registry)
    m.add("voltage_source", "V1", ("in", "0"), E=0)
    m.add("resistor", "R1", ("in", "a"), R=33.0)
    m.add("inductor", "L1", ("a", "b"), L=4.7e-3)
    m.add("grounded_capacitor", "C1", "b", C=2.2e-7)
    outputs = ["v(C1)", "i(L1)"]
    assert numeric(m, ["V1"], outputs, 0.0) is not None
    fast = linearize(m, inputs=["V1"], outputs=outputs)
    with derived_only():
        slow = linearize(m, inputs=["V1"], outputs=outputs)
    same_linearization(fast, slow)


@settings(max_examples=200, deadline=None)
@given(st.integers(1, 8), st.data())
def test_fundamental_loops_follow_the_trees_paths_as_networkx_finds_them(n, data):
    """Each chord's loop is the chord and the tree's path from its ``b`` to its ``a``, as networkx's
    ``shortest_path`` on the tree finds it, with the signs of the edges walked."""
    import networkx as nx

    from lagrangian.base.network import fundamental_loops, normal_tree

    nodes = ["ground"] + [f"n{i}" for i in range(n)]
    g = nx.MultiGraph()
    g.add_nodes_from(nodes)
    for i in range(1, len(nodes)):  # connected
        a, b = nodes[i], nodes[data.draw(st.integers(0, i - 1))]
        a, b = (b, a) if data.draw(st.booleans()) else (a, b)
        g.add_edge(a, b, key=f"t{i}", a=a, b=b)
    for j in range(data.draw(st.integers(0, 8))):
        a, b = data.draw(st.lists(st.sampled_from(nodes), min_size=2, max_size=2, unique=True))
        g.add_edge(a, b, key=f"x{j}", a=a, b=b)
    priority = {k: data.draw(st.floats(0, 1)) for _, _, k in g.edges(keys=True)}
    tree = normal_tree(g, "ground", priority.get)
    tg = nx.Graph()
    tg.add_nodes_from(nodes)
    tg.add_edges_from((u, v, {"key": k, "a": d["a"], "b": d["b"]}) for u, v, k, d in g.edges(keys=True, data=True)
                      if k in tree)
    for chord, loop in fundamental_loops(g, tree).items():
        d = next(d for _, _, k, d in g.edges(keys=True, data=True) if k == chord)
        path = nx.shortest_path(tg, d["b"], d["a"])
        expected = [(chord, 1)] + [(tg.edges[p, q]["key"], 1 if (tg.edges[p, q]["a"], tg.edges[p, q]["b"]) == (p, q)
                                    else -1) for p, q in zip(path, path[1:])]
        assert loop == expected


@settings(max_examples=25, deadline=None)
@given(circuits(), st.sampled_from([None, "sin", "sum"]))
def test_a_circuits_stamps_in_numbers_are_its_stamps_from_its_energies(case, signal):
    """What the exact time-domain solution reads (``numeric_stamps``) equals the stamps differentiated from the
    components' symbolic energies: ``M``, ``C``, ``K``, the forcing ``B s(t)`` at several instants, the energies'
    quadratic forms, and which coordinates have inertia."""
    import sympy as sp

    from lagrangian.derivation.numeric import numeric_stamps
    from lagrangian.derivation.stamps import stamps

    m, _ = case
    source = m.components["V1" if "V1" in m.components else "I1"]
    pname = "E" if source.kind == "voltage_source" else "I"
    value = {None: 1.5, "sin": 2 * sp.sin(3 * lg.t), "sum": 0.5 + sp.cos(7 * lg.t) / 4}[signal]
    twin = lg.Model("twin", formulation=m.options["formulation"])
    for comp in m.components.values():
        params = {k: v for k, v in comp.params.items() if v is not None}
        if comp is source:
            params[pname] = value
        twin.add(comp.kind, comp.name, comp.nodes, **params)
    fast = numeric_stamps(twin)
    slow = stamps(twin.assembly, twin.assembly.values)
    assert fast.names == slow.names
    for name in ("M", "C", "K"):
        _close(getattr(fast, name).toarray(), getattr(slow, name).toarray(), name)
    for time in (0.0, 0.37, 1.9):
        def forcing(stmp):
            s = np.array([float(sp.sympify(e).subs(lg.t, time)) for e in stmp.inputs])
            return stmp.B.toarray() @ s if len(s) else np.zeros(stmp.n)
        _close(forcing(fast), forcing(slow), f"B s({time})")
    for part in "TVD":
        _close(fast.energies[part].H.toarray(), slow.energies[part].H.toarray(), part)
    assert fast.inertial == slow.inertial and fast.first_order == slow.first_order


def test_a_parameters_number_is_the_value_given_and_no_number_in_its_symbolic_view():
    """A component keeps the plain numbers it was given for the numeric assembly; its symbolic view and its input
    twin, whose parameters are symbols or expressions, have none of them."""
    from lagrangian.base.linear import LinearContext

    m = lg.Model("rc")
    source = m.add("voltage_source", "V1", ("in", "0"), E=1.5)
    resistor = m.add("resistor", "R1", ("in", "a"), R=4.7e3)
    m.add("capacitor", "C1", ("a", "0"), C=2.2e-6)
    ctx = LinearContext(m.options, m.components)
    assert ctx.number(resistor, "R") == 4.7e3 and ctx.number(source, "E") == 1.5
    assert ctx.number(resistor.symbolic_view(), "R") is None
    twin, _ = source.with_input("E", "w_V1")
    assert ctx.number(twin, "E") is None
