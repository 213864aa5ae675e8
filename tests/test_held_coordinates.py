"""Coordinates without inertia of their own whose motion a loop constraint fixes (a massless slider).

The reference is the one-degree-of-freedom Lagrangian of the same
slider–crank written by hand (the slider and rod angle eliminated through
the loop in closed form), integrated with SciPy.
"""

import numpy as np
import pytest
import sympy as sp
from scipy.integrate import solve_ivp

import lagrangian as lg
from lagrangian.plugins.multibody import consistent_initial, constraint_residual

R, L, M_CRANK, M_ROD, G = 0.1, 0.3, 0.7, 0.2, 9.81


def slider_crank() -> lg.Model:
    m = lg.Model("slider-crank", dim=2)
    m.add("disc", "crank", "crank", m=M_CRANK, radius=R, points={"pin": (R, 0)})
    m.add("rod", "rod", "rod", m=M_ROD, length=L)
    m.add("link", "slider", "slider")  # massless
    m.add("revolute", "O", ("ground", "crank"), absolute=True)
    m.add("revolute", "A", ("crank", "rod"), parent_point=(R, 0), absolute=True)
    m.add("prismatic", "P", ("ground", "slider"))
    m.add("revolute", "B", ("rod", "slider"), parent_point=(L, 0))
    m.add("gravity", "g", g=G)
    return m


def reference_rhs():
    """θ̈(θ, θ̇) of the crank from L(θ, θ̇), the rod angle φ = −asin(R sin θ / L) eliminated by hand."""
    th, w = sp.symbols("theta omega", real=True)
    phi = -sp.asin(R * sp.sin(th) / L)
    dphi = sp.diff(phi, th) * w
    pin = sp.Matrix([R * sp.cos(th), R * sp.sin(th)])
    com = pin + L / 2 * sp.Matrix([sp.cos(phi), sp.sin(phi)])
    vcom = com.diff(th) * w
    T = sp.Rational(1, 2) * (M_CRANK * R**2 / 2) * w**2 + sp.Rational(1, 2) * M_ROD * (vcom.T * vcom)[0] \
        + sp.Rational(1, 2) * (M_ROD * L**2 / 12) * dphi**2
    V = M_ROD * G * com[1]
    Lag = T - V
    p = sp.diff(Lag, w)
    acc = (sp.diff(Lag, th) - sp.diff(p, th) * w) / sp.diff(p, w)
    return sp.lambdify((th, w), acc)


def test_massless_slider_closed_by_a_loop_moves_as_the_one_degree_of_freedom_mechanism():
    model = slider_crank()
    assert model.first_order == []
    q0, v0 = consistent_initial(model, {"theta_O": 0.3, "s_P": 0.39, "theta_A": -0.1}, {"theta_O": 5.0},
                                independent=["theta_O"])
    res = model.simulate(1.5, initial=q0, velocity=v0, points=301, rtol=1e-11, atol=1e-13)
    acc = reference_rhs()
    ref = solve_ivp(lambda t, y: [y[1], acc(y[0], y[1])], (0, 1.5), [q0["theta_O"], v0["theta_O"]],
                    t_eval=res.t, rtol=1e-12, atol=1e-13, method="DOP853")
    assert np.max(np.abs(res["theta_O"] - ref.y[0])) < 1e-7
    # the slider follows the crank as the loop says, and nothing is lost
    x = R * np.cos(res["theta_O"]) + np.sqrt(L**2 - (R * np.sin(res["theta_O"])) ** 2)
    assert np.max(np.abs(res["s_P"] - x)) < 1e-8
    assert constraint_residual(model, res) < 1e-8
    assert res.energy_drift() < 1e-8


def test_a_massless_coordinate_outside_every_loop_is_still_refused():
    m = lg.Model("bare slider", dim=2)
    m.add("link", "slider", "slider")
    m.add("prismatic", "P", ("ground", "slider"))
    m.add("mass", "bob", "bob", m=0.3)
    m.add("spring", "k", ("ground", "bob"), k=7.0)
    with pytest.raises(lg.ModelError, match="s_P"):
        m.equations
