"""Linearization about a steady motion, with constraints on velocities: the rolling disc's upright motion (stable
above v² = g r / 3, leaning at ω² = 4/5 (3 Ω² − g/r)) and Chaplygin's sleigh gliding straight (its turning decays at
−m a u / (I + m a²)), against their closed forms, given numbers over decades and given symbols; Kane's state space
against the Laplace form's pencil; the refusals a user meets."""

import functools
import math

import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

import lagrangian as lg
from lagrangian.analysis.linearize import s
from lagrangian.frequency import frequency_response, linearize, modes, speed_sweep, transfer_function

G = 9.81


def decade(lo, hi):
    return st.floats(math.log10(lo), math.log10(hi)).map(lambda e: float(f"{10 ** e:.3g}"))


def disc(m, r, g=G):
    """A uniform disc on a free joint (z-x-z angles: yaw φ, lean θ from the vertical, spin ψ) rolling on z = 0."""
    model = lg.Model("rolling disc", dim=3)
    model.add("disc", "d", "d", m=m, radius=r)
    model.add("free", "j", ("ground", "d"), sequence="zxz")
    model.add("rolling", "roll", "d", radius=r)
    model.add("gravity", "g", g=g)
    return model


def upright(r, spin):
    """The upright disc rolling along +x: spinning at −Ω about its axis, its centre moving at Ω r."""
    return {"z_j": r, "theta_j": sp.pi / 2}, {"psi_j": -spin, "x_j": spin * r}


def sleigh(m, inertia, a):
    """Chaplygin's sleigh: a body in the plane whose knife edge, a behind its centre of mass, cannot slide across."""
    model = lg.Model("Chaplygin sleigh", dim=2)
    model.add("body", "b", "b", m=m, inertia=inertia, points={"edge": (-a, 0.0)})
    model.add("free", "j", ("ground", "b"))
    model.add("knife_edge", "k", "b.edge")
    return model


def lean_squared(r, spin, g=G):
    """λ² of the upright disc's lean: 4/5 (g/r − 3 Ω²) (a pair ±λ; imaginary above the critical speed)."""
    return 0.8 * (g / r - 3 * spin**2)


@pytest.mark.slow
def test_the_symbolic_disc_has_the_closed_form_characteristic_polynomial():
    m, r, W, g = sp.symbols("m r W g", positive=True)
    at, velocity = upright(r, W)
    lin = linearize(disc(m, r, g), at=at, velocity=velocity, inputs=[])
    assert lin.symbolic and lin.velocity_rows == 2 and lin.Phi.shape[0] == 3
    P, _ = lin.pencil(s)
    det = sp.factor(sp.simplify(P.det(method="berkowitz")))
    # six zeros (position, heading, spin, their speeds) and the lean: s² = 4/5 (g/r − 3 W²), exactly
    rest = sp.cancel(det / s**6)
    assert sp.degree(rest, s) == 2
    roots = sp.solve(rest, s**2)
    assert len(roots) == 1 and sp.simplify(roots[0] - sp.Rational(4, 5) * (g / r - 3 * W**2)) == 0


@pytest.mark.slow
@settings(max_examples=6, deadline=None)
@given(m=decade(0.01, 30.0), r=decade(0.003, 1.0), ratio=st.one_of(st.floats(0.2, 0.9), st.floats(1.1, 5.0)))
def test_the_upright_disc_is_stable_above_the_critical_speed_over_decades(m, r, ratio):
    # (at the critical speed itself the lean is a double zero, which eigenvalues resolve only to √ε)
    spin = math.sqrt(ratio * G / (3 * r))  # v² = ratio · g r / 3
    at, velocity = upright(r, spin)
    lin = linearize(disc(m, r), at={k: float(v) for k, v in at.items()}, velocity=velocity)
    A, _, _, _, states = lin.state_space()
    assert states[:5] == ["x_j", "y_j", "phi_j", "theta_j", "psi_j"] and len(states) == 8  # 5 coordinates, 3 speeds
    lam = np.linalg.eigvals(A)
    lean = lean_squared(r, spin)
    big = lam[np.argsort(np.abs(lam))][-2:]
    expected = math.sqrt(abs(lean))
    assert np.allclose(np.sort(np.abs(big)), expected, rtol=1e-9)
    if ratio > 1:  # above the critical speed: the lean oscillates
        assert np.all(np.abs(big.real) <= 1e-9 * expected)
    else:  # below: it falls
        assert np.max(big.real) == pytest.approx(expected, rel=1e-9)
    # the pencil of the Laplace form has the same finite eigenvalues
    pencil = modes(lin).eigenvalues
    assert np.min(np.abs(pencil - big[np.argmax(big.imag)])) <= 1e-8 * expected


@pytest.mark.slow
def test_numbers_and_symbols_give_the_same_structure_and_verdict():
    r_, spin_ = 0.07, 12.0
    numeric = linearize(disc(0.3, r_), at={"z_j": r_, "theta_j": math.pi / 2}, velocity={"psi_j": -spin_, "x_j": spin_ * r_})
    m, r, W = sp.symbols("m r W", positive=True)
    at, velocity = upright(r, W)
    symbolic = linearize(disc(m, r), at=at, velocity=velocity)
    assert symbolic.coordinates == numeric.coordinates and symbolic.Phi.shape == numeric.Phi.shape
    assert symbolic.Phi_v.shape == numeric.Phi_v.shape
    put = {m: 0.3, r: r_, W: spin_}
    for name in ("M", "C", "K", "Phi", "Phi_v"):
        value = np.array(sp.Matrix(getattr(symbolic, name)).xreplace(put).evalf(), dtype=float)
        assert np.allclose(value, getattr(numeric, name), rtol=1e-12, atol=1e-12 * np.abs(value).max()), name


@pytest.mark.slow
@settings(max_examples=25, deadline=None)
@given(m=decade(0.05, 50.0), inertia=decade(1e-4, 5.0), a=decade(1e-3, 1.0), u=st.floats(-3.0, 3.0),
       sign=st.sampled_from([1.0, -1.0]))
def test_the_sleigh_gliding_straight_turns_back_at_the_closed_form_rate(m, inertia, a, u, sign):
    lin = _sleigh_lin(m, inertia, sign * a, u)
    A, _, _, _, states = lin.state_space()
    assert len(states) == 5  # x, y, θ and two speeds: one constraint on velocities
    lam = np.linalg.eigvals(A)
    rate = -m * sign * a * u / (inertia + m * a**2)  # ω̇ = −m a u ω / (I + m a²)
    scale = max(abs(rate), 1e-300)
    assert np.min(np.abs(lam - rate)) <= 1e-10 * max(scale, 1.0)
    others = np.delete(lam, np.argmin(np.abs(lam - rate)))
    assert np.all(np.abs(others) <= 1e-10 * max(scale, 1.0))  # position, heading and speed: neutral


@functools.lru_cache(maxsize=None)
def _sleigh_lin(m, inertia, a, u):
    return linearize(sleigh(m, inertia, a), velocity={"x_j": u} if u else None)


def test_the_sleigh_with_symbols_has_the_closed_form_pole():
    m, inertia, a, u = sp.symbols("m I a u", positive=True)
    lin = linearize(sleigh(m, inertia, a), velocity={"x_j": u})
    P, _ = lin.pencil(s)
    det = sp.factor(P.det(method="berkowitz"))
    poles = [p for p in sp.solve(det, s) if p != 0]
    assert len(poles) == 1 and sp.simplify(poles[0] + m * a * u / (inertia + m * a**2)) == 0


def test_a_push_on_the_gliding_sleigh_has_the_transfer_function_of_its_speed():
    m, inertia, a, u = 0.3, 2e-3, 0.05, 0.4
    model = sleigh(m, inertia, a)
    model.add("force", "F", "b", F=(0.0, 0.0))
    lin = linearize(model, velocity={"x_j": u}, inputs=["F[0]"], outputs=["x_j'"])
    H = transfer_function(lin, "F[0]", "x_j'")
    for w in (0.3, 2.0, 17.0):
        assert complex(H(1j * w)) == pytest.approx(1 / (m * 1j * w), rel=1e-12)  # a push along the edge: 1/(m s)


@pytest.mark.slow
def test_rates_that_break_the_constraints_or_move_what_the_equations_depend_on_are_refused():
    model = disc(0.3, 0.07)
    with pytest.raises(lg.ModelError, match=r"violate the constraints on velocities of 'roll'.*consistent_initial"):
        linearize(model, at={"z_j": 0.07, "theta_j": math.pi / 2}, velocity={"psi_j": -10.0, "x_j": 0.3})
    with pytest.raises(lg.ModelError, match=r"'theta_j' move.*not steady"):
        linearize(model, at={"z_j": 0.07, "theta_j": math.pi / 2}, velocity={"theta_j": 1.0})
    with pytest.raises(lg.ModelError, match=r"not in steady motion.*velocity= a steady motion"):
        linearize(model, at={"z_j": 0.07 * math.sin(1.2), "theta_j": 1.2}, velocity={"psi_j": -10.0, "x_j": 0.7})
    with pytest.raises(lg.UnknownNameError, match="psi_d"):
        linearize(model, velocity={"psi_d": 1.0})
    with pytest.raises(lg.ModelError, match=r"velocity\['x_j'\] must be finite"):
        linearize(model, velocity={"x_j": math.inf})
    lin = linearize(sleigh(0.3, 2e-3, 0.05), velocity={"x_j": 0.4})
    with pytest.raises(lg.ModelError, match="no second-order form in independent coordinates"):
        lin.independent()


@pytest.mark.slow
@settings(max_examples=4, deadline=None)
@given(m=decade(0.01, 30.0), r=decade(0.003, 1.0))
def test_the_speed_sweep_finds_the_discs_critical_speed_over_decades(m, r):
    critical = math.sqrt(G * r / 3)  # v² = g r / 3
    sweep = speed_sweep(disc(m, r), np.linspace(0.25, 3.1, 9) * critical, at={"z_j": r, "theta_j": math.pi / 2},
                        velocity={"x_j": 1.0, "psi_j": -1 / r})
    assert sweep.exact
    (crossing,) = sweep.crossings()
    assert crossing.kind == "real" and crossing.becomes == "stable"  # the lean's pair leaves the real axis through 0
    assert crossing.speed == pytest.approx(critical, rel=1e-10)


def test_the_speed_sweep_refuses_what_it_cannot_sweep():
    model = sleigh(0.3, 2e-3, 0.05)
    with pytest.raises(lg.ModelError, match="1 to 10⁶ finite numbers"):
        speed_sweep(model, [0.1, math.nan], velocity={"x_j": 1.0})
    with pytest.raises(lg.ModelError, match="1 to 10⁶ finite numbers"):
        speed_sweep(model, [], velocity={"x_j": 1.0})
    with pytest.raises(lg.ModelError, match="rates of the steady motion at unit speed"):
        speed_sweep(model, [0.1, 0.2], velocity={})
    with pytest.raises(lg.ModelError, match=r"'theta_j' move"):
        speed_sweep(model, [0.1, 0.2], velocity={"theta_j": 1.0})


@pytest.mark.slow
def test_the_laplace_form_and_kanes_state_space_give_the_same_response():
    """A torque on the rolling disc at 12 rad/s: its lean and turning rate over frequency, solved in the Laplace
    form (coordinates and multipliers, the constraints on velocities as rows (∂c/∂q + A s) δq = 0) and from Kane's
    state space (independent speeds, the multipliers projected out) — two formulations, one response."""
    r, spin = 0.07, 12.0
    model = disc(0.3, r)
    model.add("body_torque", "T", "d", tau=(0.0, 0.0, 0.0))
    lin = linearize(model, at={"z_j": r, "theta_j": math.pi / 2}, velocity={"psi_j": -spin, "x_j": spin * r},
                    inputs=["T[0]"], outputs=["theta_j", "phi_j'"])
    assert lin.size > 8  # the dense solve of the Laplace form, not the small one
    A, B, C, D, _ = lin.state_space()
    f = np.array([0.03, 0.3, 1.7, 5.0, 40.0])
    H = frequency_response(lin, f).H[:, 0, :]
    for k, fk in enumerate(f):
        s_ = 2j * np.pi * fk
        want = (C @ np.linalg.solve(s_ * np.eye(len(A)) - A, B) + D)[:, 0]
        assert np.allclose(H[:, k], want, rtol=1e-10, atol=1e-12 * np.abs(want).max())
