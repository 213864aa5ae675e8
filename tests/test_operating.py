"""Operating points: equilibria, every branch, with stability verdicts; linearization about steady motions.

References: the pendulum's two equilibria, the electrostatic actuator's cubic k x (g − x)² = εA V²/2 and its pull-in
voltage √(8 k g³ / 27 εA) (also the transducer plugin's own root finder), a spring under a constant force, and the
spherical pendulum's small oscillations about its steady motion, ω² = (g/l)(3 cos θ₀ + sec θ₀), from the Routhian.
"""

import math

import numpy as np
import pytest
import sympy as sp
from hypothesis import example, given, settings
from hypothesis import strategies as st

import lagrangian as lg
from lagrangian import frequency, routh
from lagrangian.operating import equilibria
from lagrangian.plugins.transducers import electrostatic_equilibria

G = 9.81


def decade(lo, hi):
    return st.floats(np.log10(lo), np.log10(hi)).map(lambda e: float(f"{10 ** e:.4g}"))


def pendulum(torsion=None):
    m = lg.Model("pendulum", dim=2)
    m.add("rod", "r", "r", m=0.3, length=0.7)
    m.add("revolute", "j", ("ground", "r"), absolute=True)
    m.add("gravity", "g", g=G)
    return m


def test_a_pendulum_hangs_stably_and_balances_unstably():
    found = equilibria(pendulum())
    assert [round(e.point["theta_j"], 12) for e in found] == [round(-math.pi / 2, 12), round(math.pi / 2, 12)]
    hanging, inverted = found
    assert hanging.stability.verdict == "stable" and inverted.stability.verdict == "unstable"
    w = math.sqrt(3 * G / (2 * 0.7))  # a rod: ω² = 3g / 2l
    assert hanging.modes.omega[0] == pytest.approx(w, rel=1e-12)
    assert inverted.stability.eigenvalues.real.max() == pytest.approx(w, rel=1e-12)


@settings(max_examples=15)
@given(decade(0.01, 100.0), decade(1.0, 1e4), decade(1e-3, 10.0), decade(1e-2, 10.0))
@pytest.mark.slow
def test_a_damped_spring_under_a_constant_force_settles_where_the_forces_balance(mass, k, c, force):
    m = lg.Model("hanging")
    m.add("mass", "m", "p", m=mass)
    m.add("spring", "k", ("ground", "p"), k=k)
    m.add("damper", "c", ("ground", "p"), c=c)
    m.add("force", "F", "p", F=-force)
    (only,) = equilibria(m)
    assert only.point["x_p"] == pytest.approx(-force / k, rel=1e-12)
    assert only.stability.verdict == "asymptotically stable"
    roots = np.roots([mass, c, k])
    assert np.allclose(np.sort(np.abs(only.stability.eigenvalues)), np.sort(np.abs(roots))[: len(only.stability.eigenvalues)],
                       rtol=1e-9)


def actuator(V, eps_A=1.0, gap=1.0, k=1.0, mass=1.0, c=1.0, R=0.1):
    m = lg.Model("actuator")
    m.add("voltage_source", "V", ("n1", "0"), E=V)
    m.add("resistor", "R", ("n1", "n2"), R=R)
    m.add("variable_capacitor", "Cx", ("n2", "0", "plate"), eps_A=eps_A, gap=gap)
    m.add("mass", "m", "plate", m=mass)
    m.add("spring", "k", ("ground", "plate"), k=k)
    m.add("damper", "c", ("ground", "plate"), c=c)
    return m


@settings(max_examples=12)
@given(decade(1e-3, 1e3), decade(1e-6, 1e-2), decade(1e-12, 1e-6), st.floats(0.05, 0.97))
@example(k=100.0, gap=1e-6, eps_A=1e-6, fraction=0.5)  # an RC of 1e3 s beside a resonance at 1e4 rad/s: stiff
@pytest.mark.slow
def test_electrostatic_equilibria_are_the_cubics_roots_and_stable_below_pull_in(k, gap, eps_A, fraction):
    v_pi = math.sqrt(8 * k * gap**3 / (27 * eps_A))
    V = fraction * v_pi
    model = actuator(V, eps_A=eps_A, gap=gap, k=k, mass=1e-6, c=1e-3, R=1e3)
    found = [e for e in equilibria(model) if e.point["x_plate"] < gap]  # beyond the electrode is no place to rest
    cubic = np.roots([k, -2 * k * gap, k * gap**2, -eps_A * V**2 / 2])
    inside = np.sort([r.real for r in cubic if abs(r.imag) < 1e-9 * gap and r.real < gap])
    assert len(found) == 2 == len(inside)
    assert [e.point["x_plate"] for e in found] == pytest.approx(list(inside), rel=1e-9, abs=1e-12 * gap)
    stable, unstable = found
    assert stable.point["x_plate"] < gap / 3 < unstable.point["x_plate"]
    assert stable.stability.verdict == "asymptotically stable" and unstable.stability.verdict == "unstable"
    assert stable.point["x_plate"] == pytest.approx(electrostatic_equilibria(model, "Cx", V).position, rel=1e-7)
    # the verdict's eigenvalues are those of the state-space matrix (q first-order, x second-order)
    for e in found:
        A = frequency.linearize(model, at=e.point, inputs=[]).state_space()[0]
        every = np.linalg.eigvals(A)
        assert all(np.min(np.abs(every - lam)) <= 1e-7 * np.abs(every).max() for lam in e.stability.eigenvalues)
    # the charge is the capacitor's, C(x) V
    assert stable.point["q_R"] == pytest.approx(eps_A / (gap - stable.point["x_plate"]) * V, rel=1e-9)


@pytest.mark.slow
def test_past_pull_in_no_equilibrium_is_left_in_the_gap():
    v_pi = math.sqrt(8 / 27)
    assert not [e for e in equilibria(actuator(1.05 * v_pi)) if e.point["x_plate"] < 1.0]
    at = [e for e in equilibria(actuator(0.999 * v_pi)) if e.point["x_plate"] < 1.0]
    assert len(at) == 2 and all(abs(e.point["x_plate"] - 1 / 3) < 0.05 for e in at)  # the branches meet at g/3


@pytest.mark.slow
def test_small_oscillations_about_a_steady_motion_are_the_routhian_ones():
    m = lg.Model("spherical pendulum", dim=3)
    m.add("link", "yoke", "yoke")
    m.add("revolute", "turn", ("ground", "yoke"), axis=(0, 0, 1))
    m.add("link", "arm", "arm", points={"bob": (0, 0, -0.7)})
    m.add("revolute", "tilt", ("yoke", "arm"), axis=(1, 0, 0))
    m.add("mass", "bob", "arm.bob", m=0.3)
    m.add("gravity", "g", g=G)
    red = routh.reduce(m)
    for C in (0.05, 0.4, 2.0):
        steady = red.steady_motions(momenta={"theta_turn": C})
        assert len(steady) == 2
        for sm in steady:
            th0 = float(sm.coordinates["theta_tilt"])
            found = frequency.modes(red, at={"theta_tilt": th0}, params={"C_theta_turn": C})
            closed = G / 0.7 * (3 * math.cos(th0) + 1 / math.cos(th0))
            assert found.omega[0] ** 2 == pytest.approx(closed, rel=1e-10)
            assert found.omega[0] ** 2 == pytest.approx(float(sm.perturbation().frequency_squared), rel=1e-10)
            # and the steady motion is an equilibrium of the reduced model, stable (Newton from near it)
            (at_rest,) = equilibria(red, params={"C_theta_turn": C}, near={"theta_tilt": 0.9 * th0})
            assert at_rest.point["theta_tilt"] == pytest.approx(th0, rel=1e-10)
            assert at_rest.stability.verdict == "stable" == sm.stability().verdict


@pytest.mark.slow
def test_transcendental_equilibria_need_a_guess_and_newton_finds_them():
    m = lg.Model("pendulum on a torsion spring", dim=2)
    m.add("rod", "r", "r", m=0.3, length=0.7)
    m.add("revolute", "j", ("ground", "r"), absolute=True)
    m.add("rotational_spring", "s", ("ground", "r"), k=0.8)
    m.add("gravity", "g", g=G)
    with pytest.raises(lg.ModelError, match="near="):
        equilibria(m, budget=2)
    (found,) = equilibria(m, near={"theta_j": -0.5})
    th = found.point["theta_j"]
    assert 0.8 * th + 0.3 * G * 0.35 * math.cos(th) == pytest.approx(0.0, abs=1e-12)  # k θ = −m g (l/2) cos θ
    assert found.stability.verdict == "stable"
    with pytest.raises(lg.UnknownNameError, match="theta_x"):
        equilibria(m, near={"theta_x": 0.1})


def test_symbolic_parameters_need_values():
    m = lg.Model("hanging")
    m.add("mass", "m", "p", m=sp.Symbol("m", positive=True))
    m.add("spring", "k", ("ground", "p"), k=sp.Symbol("k", positive=True))
    m.add("force", "F", "p", F=-1.0)
    with pytest.raises(lg.ModelError, match="k"):
        equilibria(m)
    (only,) = equilibria(m, params={"m": 0.3, "k": 40.0})
    assert only.point["x_p"] == pytest.approx(-1 / 40.0, rel=1e-12) and only.stability.verdict == "stable"


def test_with_no_point_the_linearization_finds_the_operating_point_as_spice_does():
    """The actuator biased at 0.5 V: Newton from rest settles on the stable branch, and the small-signal gain there
    is the closed form's dx/dV = εA V / (k ((g − x)² − 2 x (g − x)))."""
    lin = frequency.linearize(actuator(0.5), inputs=["V"], outputs=["x_plate"])
    x = lin.at["x_plate"]
    stable = electrostatic_equilibria(actuator(0.5), "Cx", 0.5).position
    assert float(x) == pytest.approx(stable, rel=1e-10)
    gain = frequency.transfer_function(lin, "V", "x_plate").dc_gain
    assert gain == pytest.approx(0.5 / ((1 - stable) ** 2 - 2 * stable * (1 - stable)), rel=1e-9)


def test_a_continuum_of_equilibria_is_refused_by_name_in_polynomial_and_other_equations():
    """Two masses joined by a spring and nothing else rest wherever they are together (a free translation): no
    finite list of equilibria; said so, naming the free coordinate.  The same with a pendulum's angle free."""
    m = lg.Model("free pair")
    m.add("mass", "ma", "a", m=0.3)
    m.add("mass", "mb", "b", m=0.7)
    m.add("spring", "k", ("a", "b"), k=40.0)
    with pytest.raises(lg.ModelError, match="continuum of equilibria.*can take any value"):
        equilibria(m)
    p = lg.Model("pendulum without gravity", dim=2)
    p.add("rod", "arm", "arm", m=0.3, length=0.4)
    p.add("revolute", "pin", ("ground", "arm"), absolute=True)
    with pytest.raises(lg.ModelError, match="continuum of equilibria.*theta_pin can take any value"):
        equilibria(p)
    pushed = lg.Model("pushed mass")
    pushed.add("mass", "m1", "p", m=0.3)
    pushed.add("force", "F", "p", F=2.5)  # nothing balances it
    assert equilibria(pushed) == []
