"""Integrators as plugins: the contract, the built-in methods, ``method="auto"``, and where methods fail.

Expected values come from physics and numerical analysis written out here:
closed forms of the oscillator and of each method's one-step map on it,
orders of convergence measured from two step sizes against a reference
computed by SciPy on an ODE written by hand, stability bounds from the
eigenvalues of hand-written mass and stiffness matrices, and conservation
laws.  Nothing expected is taken from the code under test.
"""

from __future__ import annotations

import math
import re
import types
import warnings
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

import lagrangian as lg
from lagrangian import models
from lagrangian.bench import stability_limit
from lagrangian.integrate import EnergyDriftWarning, FixedStepIntegrator, Integrator, Problem, Solution, Stepper, choose

FIXED = ["rk4", "verlet", "implicit_midpoint", "gauss_legendre", "variational"]
ADAPTIVE = ["RK23", "RK45", "DOP853", "DOP853_scipy", "Radau", "BDF", "LSODA"]  # DOP853: in C where it can
COMPILED = ["dopri5_c", "dop853_c", "rk4_c", "verlet_c"]  # stepping loops in C (see tests/test_codegen.py)


def decades(lo, hi):
    """Values drawn log-uniformly from ``lo`` to ``hi``, rounded to three digits (ordinary decimals)."""
    return st.floats(math.log10(lo), math.log10(hi)).map(lambda e: float(f"{10 ** e:.3g}"))


@pytest.fixture(autouse=True)
def _no_initial_condition_warnings():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lg.InitialConditionWarning)
        yield


# ---------------------------------------------------------------------------
# builders


def oscillator(m=1.0, k=1.0, c=None, F=None) -> lg.Model:
    model = lg.Model("oscillator")
    model.add("mass", "m1", "p", m=m)
    model.add("spring", "k1", ("ground", "p"), k=k)
    if c is not None:
        model.add("damper", "c1", ("ground", "p"), c=c)
    if F is not None:
        model.add("force", "f1", "p", F=F)
    return model


def duffing() -> lg.Model:
    """x'' = −x − x³ (m = k = k3 = 1), the example plugin's cubic spring."""
    model = lg.Model("duffing")
    model.add("mass", "m1", "p", m=1)
    model.add("cubic_spring", "s", ("ground", "p"), k=1, k3=1)
    return model


def stiff_chain(K=1e4) -> lg.Model:
    """ground —1— a —K— b, unit masses: M = I, K = [[1+K, −K], [−K, K]]."""
    model = lg.Model("stiff chain")
    model.add("mass", "m1", "a", m=1)
    model.add("mass", "m2", "b", m=1)
    model.add("spring", "k1", ("ground", "a"), k=1)
    model.add("spring", "k2", ("a", "b"), k=K)
    return model


def rc(R=1.0, C=1e-3, E=0.0) -> lg.Model:
    """Source, resistor, capacitor in series: R q' + q/C = E, a first-order coordinate with λ = −1/(RC)."""
    model = lg.Model("rc", formulation="charge")
    model.add("voltage_source", "V", ("n1", "0"), E=E)
    model.add("resistor", "R", ("n1", "n2"), R=R)
    model.add("capacitor", "C", ("n2", "0"), C=C)
    return model


def solenoid() -> lg.Model:
    """A coil whose inductance L(x) = 1/(1 + x/4) depends on the armature position: M = diag(L(x), 1), conservative."""
    model = lg.Model("solenoid")
    model.add("solenoid", "S", ("n1", "0", "p"), L0=1, x0=4)
    model.add("capacitor", "C", ("n1", "0"), C=1)
    model.add("mass", "m", "p", m=1)
    model.add("spring", "k", ("ground", "p"), k=2)
    return model


SOLENOID_START = {"initial": {"x_p": 0.5, "q_S": 1.0}, "velocity": {"x_p": 0.0, "q_S": 0.0}}


# ---------------------------------------------------------------------------
# 1. The hook and the registry


def test_builtin_integrators_are_registered_by_the_integrators_plugin():
    reg = lg.default_registry()
    info = {p.name: p for p in reg.plugins()}
    assert info["integrators"].distribution == "lagrangian"
    assert set(info["integrators"].integrators) == set(FIXED) | set(ADAPTIVE) | set(COMPILED)
    assert {n for n, m in reg.integrators.items() if m.kind == "fixed-step"} == set(FIXED) | {"rk4_c", "verlet_c"}
    assert {n for n, m in reg.integrators.items() if m.symplectic} == {"verlet", "verlet_c", "implicit_midpoint", "gauss_legendre", "variational"}
    assert {n for n, m in reg.integrators.items() if not m.implicit} == {"RK23", "RK45", "DOP853", "DOP853_scipy", "rk4",
                                                                          "verlet", *COMPILED}
    assert {n for n, m in reg.integrators.items() if not m.first_order} == {"verlet", "verlet_c", "variational"}
    assert {m.order for n, m in reg.integrators.items() if n in FIXED} == {2, 4}


class Euler(FixedStepIntegrator):
    """Explicit Euler: a third-party fixed-step method in a dozen lines."""

    name = "euler"
    order = 1
    description = "explicit Euler"

    def stepper(self, problem, h):
        return Stepper(lambda t, y: y + h * problem.rhs(t, y))


def integrator_plugin(*things, name="extra"):
    plugin = types.ModuleType(name)
    plugin.register_integrators = lg.hookimpl(lambda register: [register(x) for x in things])
    return plugin


def test_a_third_party_fixed_step_method_runs_and_is_first_order():
    reg = lg.Registry(plugins={"euler_plugin": integrator_plugin(Euler)})  # a class is instantiated
    assert isinstance(reg.integrators["euler"], Euler)
    assert {p.name: p for p in reg.plugins()}["euler_plugin"].integrators == ["euler"]
    m = oscillator()
    m._registry = reg
    errors = []
    for h in (0.01, 0.005):
        res = m.simulate(1.0, initial={"x_p": 1}, velocity={"x_p": 0}, method="euler", step=h, points=11, energy_tol=False)
        errors.append(np.max(np.abs(res["x_p"] - np.cos(res.t))))
    assert math.log2(errors[0] / errors[1]) == pytest.approx(1.0, abs=0.05)


def test_an_integrator_object_may_be_passed_without_registering_it():
    res = oscillator().simulate(1.0, initial={"x_p": 1}, velocity={"x_p": 0}, method=Euler(), step=1e-3, points=3)
    assert res.method == "euler" and res.step == pytest.approx(1e-3)
    with pytest.raises(lg.ModelError, match="neither a registered method name nor a valid integrator"):
        oscillator().simulate(1.0, method=object())


def test_duplicate_integrator_names_both_plugins():
    class MyRK45(Euler):
        name = "RK45"

    with pytest.raises(lg.PluginError, match="integrator 'RK45' is already provided by plugin 'integrators'") as info:
        lg.Registry(plugins={"copycat": integrator_plugin(MyRK45())})
    assert info.value.plugin == "copycat"


class _Broken(Integrator):
    name, kind = "broken", "adaptive"

    def solve(self, problem, t_span, y0, t_eval, **options):
        return Solution(t_eval, np.zeros((problem.dim, t_eval.size)))


INVALID = [
    ("no-name", type("N", (_Broken,), {"name": None})(), r"its name None"),
    ("bad-name", type("N", (_Broken,), {"name": "my method"})(), r"its name 'my method'"),
    ("reserved", type("N", (_Broken,), {"name": "auto"})(), r"'auto' is reserved"),
    ("reserved-exact", type("N", (_Broken,), {"name": "exact"})(), r"'exact' is reserved"),
    ("bad-kind", type("N", (_Broken,), {"kind": "variable"})(), r"kind 'variable' is not one of"),
    ("flag", type("N", (_Broken,), {"symplectic": "yes"})(), r"flag 'symplectic' must be True or False"),
    ("order", type("N", (_Broken,), {"order": 0})(), r"order must be a positive int"),
    ("no-solve", type("N", (), {"name": "x", "kind": "adaptive", "symplectic": False, "implicit": False,
                                "stiff": False, "first_order": True})(), r"no solve"),
    ("options", type("N", (_Broken,), {"options": {"y0": "clash"}})(), r"may not be named y0"),
    ("class-needs-arguments", type("N", (_Broken,), {"__init__": lambda self, x: None}), r"cannot be instantiated"),
]


@pytest.mark.parametrize(("obj", "pattern"), [c[1:] for c in INVALID], ids=[c[0] for c in INVALID])
def test_invalid_integrators_are_plugin_errors_naming_the_plugin(obj, pattern):
    with pytest.raises(lg.PluginError, match=pattern) as info:
        lg.Registry(plugins={"bad": integrator_plugin(obj)})
    assert info.value.plugin == "bad"


def test_unknown_method_lists_the_registered_ones_with_a_suggestion():
    with pytest.raises(lg.UnknownNameError, match=r"unknown integration method 'RK54'\. Did you mean 'RK45'\?") as info:
        oscillator().simulate(1.0, method="RK54")
    for name in [*ADAPTIVE, *FIXED, "auto", "exact"]:
        assert name in str(info.value)
    with pytest.raises(lg.UnknownNameError, match="Did you mean 'verlet'"):
        oscillator().simulate(1.0, method="verlett", step=0.1)


def test_options_are_checked_against_the_method():
    m = oscillator()
    with pytest.raises(lg.ModelError, match=r"does not take the option 'stage'\. Did you mean 'stages'\?"):
        m.simulate(1.0, method="gauss_legendre", step=0.1, stage=3)
    with pytest.raises(lg.ModelError, match=r"'verlet' is fixed-step: rtol= does not apply"):
        m.simulate(1.0, method="verlet", step=0.1, rtol=1e-3)
    with pytest.raises(lg.ModelError, match=r"'RK45' is adaptive: step= does not apply"):
        m.simulate(1.0, method="RK45", step=0.1)
    with pytest.raises(lg.ModelError, match="method='exact' takes no step"):
        m.simulate(1.0, method="exact", step=0.1)


def test_fixed_step_methods_need_a_step_and_suggest_one_from_the_linearization():
    # ω = √(k/m) = 2: shortest period π, suggested step π/50 ≈ 0.0628
    with pytest.raises(lg.ModelError, match=r"verlet is a fixed-step method: give its step size.*step=0\.0628") as info:
        oscillator(k=4).simulate(1.0, method="verlet")
    assert "3.14" in str(info.value)
    with pytest.raises(lg.ModelError, match="step must be a positive number"):
        oscillator().simulate(1.0, method="rk4", step=-0.1)


# ---------------------------------------------------------------------------
# 2. Accuracy: closed forms and orders of convergence


def test_verlet_iterates_are_the_closed_form_of_its_one_step_map():
    # Velocity Verlet on x'' = −ω²x is the linear map whose iterates are x_k = cos(kθ) from x = 1, v = 0,
    # with cos θ = 1 − (hω)²/2 (its characteristic roots e^{±iθ}).
    w, h = 2.0, 0.05
    res = oscillator(k=w**2).simulate(10.0, initial={"x_p": 1}, velocity={"x_p": 0}, method="verlet", step=h,
                                      points=201, fast_linear=False)
    k = np.rint(res.t / h)
    theta = math.acos(1 - (h * w) ** 2 / 2)
    assert np.max(np.abs(res["x_p"] - np.cos(k * theta))) < 1e-12


def test_rk4_one_step_map_is_the_taylor_polynomial_of_the_exponential():
    # On y' = F y, one RK4 step is R(hF) = I + hF + (hF)²/2 + (hF)³/6 + (hF)⁴/24.
    w, h = 1.0, 0.3
    res = oscillator().simulate(3.0, initial={"x_p": 1}, velocity={"x_p": 0}, method="rk4", step=h, points=11,
                                fast_linear=False)
    F = np.array([[0.0, 1.0], [-(w**2), 0.0]])
    hF = h * F
    R = np.eye(2) + hF + hF @ hF / 2 + hF @ hF @ hF / 6 + hF @ hF @ hF @ hF / 24
    y, expected = np.array([1.0, 0.0]), []
    for _ in range(11):
        expected.append(y[0])
        y = R @ y
    assert np.max(np.abs(res["x_p"] - expected)) < 1e-13


def duffing_reference(t_eval):
    sol = solve_ivp(lambda t, y: [y[1], -y[0] - y[0] ** 3], (0, t_eval[-1]), [1.0, 0.0], method="DOP853",
                    rtol=1e-13, atol=1e-15, t_eval=t_eval)
    return sol.y[0]


ORDERS = [
    ("rk4", {}, 0.1, 4),
    ("verlet", {}, 0.05, 2),
    ("implicit_midpoint", {}, 0.05, 2),
    ("gauss_legendre", {}, 0.1, 4),
    ("gauss_legendre", {"stages": 3}, 0.2, 6),
    ("variational", {}, 0.05, 2),
    ("variational", {"rule": "trapezoidal"}, 0.05, 2),
]


@pytest.mark.parametrize(("method", "options", "h", "order"), ORDERS,
                         ids=[f"{m}{'-' + '-'.join(map(str, o.values())) if o else ''}" for m, o, _, _ in ORDERS])
@pytest.mark.slow
def test_order_of_convergence_from_two_step_sizes(method, options, h, order):
    # Global error ∝ h^p: p = log2(e(h) / e(h/2)), on the nonlinear Duffing oscillator against SciPy.
    t_eval = np.linspace(0, 4, 5)
    exact = duffing_reference(t_eval)
    errors = []
    for step in (h, h / 2):
        res = duffing().simulate(4.0, initial={"x_p": 1}, velocity={"x_p": 0}, method=method, step=step, t_eval=t_eval, **options)
        errors.append(np.max(np.abs(res["x_p"] - exact)))
    assert errors[1] > 1e-11  # well above rounding, so the ratio measures the method
    assert math.log2(errors[0] / errors[1]) == pytest.approx(order, abs=0.1)


def test_methods_with_dissipation_and_forcing_converge_to_the_closed_form():
    # m x'' + c x' + k x = F0 cos Ωt; with m = 1, k = 4, c = 0.4, F0 = 1, Ω = 1.5 and x(0) = x'(0) = 0.
    # Steady state X cos(Ωt − φ), X = F0/√((k − mΩ²)² + (cΩ)²), tan φ = cΩ/(k − mΩ²); transient from the
    # homogeneous solution e^{−ζω t}(A cos ω_d t + B sin ω_d t) fitted to the initial conditions.
    import sympy as sp

    m, k, c, F0, W = 1.0, 4.0, 0.4, 1.0, 1.5
    X = F0 / math.hypot(k - m * W**2, c * W)
    phi = math.atan2(c * W, k - m * W**2)
    sigma, wd = c / (2 * m), math.sqrt(k / m - (c / (2 * m)) ** 2)
    A = -X * math.cos(phi)
    B = (-X * W * math.sin(phi) + sigma * A) / wd

    def exact(t):
        return X * np.cos(W * t - phi) + np.exp(-sigma * t) * (A * np.cos(wd * t) + B * np.sin(wd * t))

    model = oscillator(m=m, k=k, c=c, F=F0 * sp.cos(W * lg.t))
    t_eval = np.linspace(0, 5, 11)
    for method, order in (("variational", 2), ("implicit_midpoint", 2), ("gauss_legendre", 4), ("rk4", 4)):
        errors = []
        for h in (0.05, 0.025):
            res = model.simulate(5.0, initial={"x_p": 0}, velocity={"x_p": 0}, method=method, step=h, t_eval=t_eval)
            errors.append(np.max(np.abs(res["x_p"] - exact(t_eval))))
        assert math.log2(errors[0] / errors[1]) == pytest.approx(order, abs=0.15), method
        assert errors[1] < {2: 1e-3, 4: 1e-6}[order], method


def test_variational_rules_reproduce_verlet_and_implicit_midpoint_on_separable_lagrangians():
    # Trapezoidal L_d of ½ẋ² − V(x) gives x_{k+1} − 2x_k + x_{k−1} = −h² V'(x_k): Störmer–Verlet.
    # Midpoint L_d with constant M gives the implicit midpoint rule on (q, p).
    t_eval = np.linspace(0, 5, 51)
    run = lambda method, **o: duffing().simulate(5.0, initial={"x_p": 1}, velocity={"x_p": 0.3}, method=method,
                                                 step=0.05, t_eval=t_eval, **o)
    trap, verlet = run("variational", rule="trapezoidal"), run("verlet")
    mid, imp = run("variational"), run("implicit_midpoint")
    assert np.max(np.abs(trap["x_p"] - verlet["x_p"])) < 1e-11
    assert np.max(np.abs(trap.velocity("x_p") - verlet.velocity("x_p"))) < 1e-11
    assert np.max(np.abs(mid["x_p"] - imp["x_p"])) < 1e-10


def test_outputs_between_steps_are_interpolated_and_noted():
    res = oscillator().simulate(2.0, initial={"x_p": 1}, velocity={"x_p": 0}, method="gauss_legendre", step=0.1,
                                t_eval=[0.0, 0.37, 1.0, 1.93, 2.0], fast_linear=False)
    assert np.max(np.abs(res["x_p"] - np.cos(res.t))) < 1e-5  # Hermite O(h⁴) ≈ 1e-4·h⁴·… with GL4 below it
    assert any("Hermite" in n for n in res.notes)
    shortened = oscillator().simulate(1.0, initial={"x_p": 1}, velocity={"x_p": 0}, method="verlet", step=0.3, points=3,
                                      energy_tol=False)
    assert shortened.step == pytest.approx(0.25)  # ⌈0.5 / 0.3⌉ = 2 steps per output interval
    assert any("shortened to 0.25" in n for n in shortened.notes)


def test_first_order_coordinates_with_fixed_step_methods():
    # R q' + q/C = E with E = 1 V, q(0) = 0: q = C E (1 − e^{−t/RC}); RC = 0.5.
    model = rc(R=1.0, C=0.5, E=1.0)
    assert model.first_order == ["q_R"]
    for method, h, tol in (("rk4", 0.01, 1e-9), ("implicit_midpoint", 0.01, 1e-5), ("gauss_legendre", 0.02, 1e-9)):
        res = model.simulate(2.0, initial={"q_R": 0}, method=method, step=h, points=21)
        assert np.max(np.abs(res["q_R"] - 0.5 * (1 - np.exp(-res.t / 0.5)))) < tol, method
    for method in ("verlet", "variational"):
        with pytest.raises(lg.ModelError, match=r"q_R have no inertia \(first-order\).*Methods that handle first-order") as info:
            model.simulate(2.0, initial={"q_R": 0}, method=method, step=0.01)
        assert "gauss_legendre" in str(info.value) and "Radau" in str(info.value)


@pytest.mark.slow
def test_verlet_refuses_a_configuration_dependent_mass_matrix_and_says_what_to_use():
    with pytest.raises(lg.ModelError, match=r"verlet .*constant mass matrix.*mass matrix depends on x_p\..*"
                                            r"'variational' with rule='trapezoidal'"):
        solenoid().simulate(1.0, method="verlet", step=0.01, **SOLENOID_START)
    # the loop in C runs the classical method only: dissipation is refused there, naming the Python verlet
    with pytest.raises(lg.ModelError, match=r"verlet_c \(Störmer–Verlet\) needs a separable.*dissipation.*"
                                            r"Use 'variational' or 'gauss_legendre'.*or 'verlet'"):
        oscillator(c=0.1).simulate(1.0, method="verlet_c", step=0.01)
    # what verlet names instead runs, and keeps the energy of this conservative model
    res = solenoid().simulate(20.0, method="variational", rule="trapezoidal", step=0.01, points=201, **SOLENOID_START)
    assert np.max(np.abs(res.E - res.E[0])) < 1e-3 * abs(res.E[0])


def forced_damped_exact(m, k, c, F0, w, x0, v0):
    """x(t) of m x'' + c x' + k x = F0 sin(w t) (underdamped), written out: the steady sine plus the free decay."""
    det = (k - m * w**2) ** 2 + (c * w) ** 2
    A, B = F0 * (k - m * w**2) / det, -F0 * c * w / det  # x_p = A sin wt + B cos wt
    g, wd = c / (2 * m), math.sqrt(k / m - (c / (2 * m)) ** 2)
    a = x0 - B  # free part e^{−gt}(a cos wd t + b sin wd t), from x(0) and x'(0)
    b = (v0 - A * w + g * a) / wd
    return lambda t: A * np.sin(w * t) + B * np.cos(w * t) + np.exp(-g * t) * (a * np.cos(wd * t) + b * np.sin(wd * t))


def test_verlet_damped_and_forced_is_second_order_against_the_closed_form():
    # 0.3 kg, 0.7 N/m, 0.05 N s/m, 0.2 sin(1.3 t) N: the kick with the damping is a linear solve (M + h/2 C)
    m, k, c, F0, w = 0.3, 0.7, 0.05, 0.2, 1.3
    exact = forced_damped_exact(m, k, c, F0, w, 0.1, -0.4)
    model = oscillator(m=m, k=k, c=c, F=F0 * sp.sin(w * lg.t))
    errors = []
    for h in (0.02, 0.01):
        res = model.simulate(10.0, initial={"x_p": 0.1}, velocity={"x_p": -0.4}, method="verlet", step=h, points=101)
        errors.append(np.max(np.abs(res["x_p"] - exact(res.t))))
    assert errors[1] < 2e-4
    assert math.log2(errors[0] / errors[1]) == pytest.approx(2.0, abs=0.15)


@given(m=decades(1e-2, 1e2), k=decades(1e-2, 1e2), zeta=decades(1e-3, 0.5))
@settings(max_examples=8)
def test_verlet_damped_oscillator_follows_the_closed_form_over_decades(m, k, zeta):
    # unforced, damping ratio ζ; h·ω = 0.02: Störmer–Verlet's phase error is about (hω)²/24 per radian
    w0 = math.sqrt(k / m)
    c = 2 * zeta * math.sqrt(k * m)
    exact = forced_damped_exact(m, k, c, 0.0, 1.0, 0.3, 0.0)
    model = oscillator(m=m, k=k, c=c)
    res = model.simulate(20 / w0, initial={"x_p": 0.3}, velocity={"x_p": 0.0}, method="verlet", step=0.02 / w0,
                         points=41)
    assert np.max(np.abs(res["x_p"] - exact(res.t))) < 0.3 * 1e-3


@pytest.mark.slow
def test_structure_preserving_methods_with_a_configuration_dependent_mass_matrix():
    # M = diag(L(x), 1) with L(x) = 1/(1 + x/4): Gauss–Legendre runs on (q, p), the variational integrator on L_d;
    # both keep the energy (no dissipation, no sources) and follow a tight DOP853 run.
    model = solenoid()
    ref = model.simulate(20.0, points=201, rtol=1e-12, atol=1e-14, **SOLENOID_START)
    for method, h, tol, drift in (("gauss_legendre", 0.05, 1e-5, 1e-7), ("variational", 0.01, 1e-3, 1e-5)):
        res = model.simulate(20.0, points=201, method=method, step=h, **SOLENOID_START)
        assert max(np.max(np.abs(res[n] - ref[n])) for n in res.names) < tol, method
        assert res.energy_drift() < drift, method


def test_singular_mass_matrix_raises_for_every_kind_of_method():
    # Two massless nodes joined only by a damper: the first-order block c·[[1, −1], [−1, 1]] is singular.
    model = lg.Model("singular")
    model.add("spring", "k1", ("ground", "p"), k=1)
    model.add("spring", "k2", ("ground", "q"), k=2)
    model.add("damper", "c", ("p", "q"), c=1)
    for method, options in (("rk4", {"step": 0.1}), ("gauss_legendre", {"step": 0.1}), ("Radau", {}), ("auto", {})):
        with pytest.raises(lg.SingularMassMatrixError, match="singular"):
            model.simulate(1.0, initial={"x_p": 0.1, "x_q": 0.2}, method=method, **options)


def test_newton_failure_is_a_numerical_error_saying_what_to_change():
    with pytest.raises(lg.IntegrationError, match=r"gauss_legendre: the Newton iteration .* did not converge.*Reduce step=") as info:
        duffing().simulate(2.0, initial={"x_p": 1}, velocity={"x_p": 0}, method="gauss_legendre", step=0.5,
                           newton_maxiter=2, newton_tol=1e-14)
    assert isinstance(info.value, lg.NumericalError)


def test_progress_is_reported_by_fixed_step_runs():
    seen = []
    oscillator().simulate(10.0, initial={"x_p": 1}, velocity={"x_p": 0}, method="verlet", step=1e-3,
                          fast_linear=False, progress=lambda t, t_end: seen.append((t, t_end)))
    assert len(seen) >= 10 and seen[-1] == (10.0, 10.0)
    assert all(b == 10.0 for _, b in seen) and [a for a, _ in seen] == sorted(a for a, _ in seen)


# ---------------------------------------------------------------------------
# 3. Stability where explicit methods fail


def chain_omega_max(K=1e4) -> float:
    Kmat = np.array([[1 + K, -K], [-K, K]])
    return float(np.sqrt(np.linalg.eigvalsh(Kmat)).max())  # M = I


def rk4_stability_boundary(direction: complex) -> float:
    """|z| where |R(z)| = 1 along the ray z = r·direction, R the RK4 polynomial (found by bisection)."""
    R = lambda z: abs(1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24)
    lo, hi = 0.1, 4.0
    for _ in range(100):
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if R(mid * direction) <= 1 else (lo, mid)
    return lo


@pytest.mark.slow
def test_explicit_methods_go_unstable_at_the_theoretical_step_on_a_stiff_chain():
    # Eigenvalues of the stiff chain are ±iω; leapfrog is stable for hω_max < 2, RK4 for hω_max < 2√2
    # (its stability region meets the imaginary axis at 2√2 ≈ 2.828).
    w = chain_omega_max()
    assert rk4_stability_boundary(1j) == pytest.approx(2 * math.sqrt(2), rel=1e-9)
    start = {"initial": {"x_a": 1.0, "x_b": -1.0}}
    for method, bound in (("verlet", 2 / w), ("rk4", 2 * math.sqrt(2) / w)):
        h = stability_limit(stiff_chain(), method, lo=0.5 * bound, hi=1.5 * bound, **start)
        assert h / bound == pytest.approx(1.0, abs=2e-3), method
        # and stepping one by one (no linear fast path) agrees either side of the bound
        for factor, bounded in ((0.98, True), (1.02, False)):
            try:
                res = stiff_chain().simulate(2000 * factor * bound, method=method, step=factor * bound, fast_linear=False,
                                             t_eval=np.linspace(0, 2000 * factor * bound, 2001), energy_tol=False, **start)
                grew = np.max(np.abs(res["x_b"])) / abs(res["x_b"][0])
            except lg.IntegrationError as exc:  # diverged past 1e30: reported, not returned
                assert "diverged" in str(exc) and "Reduce step=" in str(exc)
                grew = math.inf
            assert (grew < 10) == bounded, (method, factor, grew)


def test_rk4_goes_unstable_at_the_theoretical_step_on_a_stiff_rc_circuit():
    # λ = −1/(RC) = −1000 (a first-order coordinate): RK4 is stable for h|λ| below the root of
    # 1 + z/2 + z²/6 + z³/24 = 0 on the negative real axis, ≈ 2.7853.
    roots = np.roots([1 / 24, 1 / 6, 1 / 2, 1])
    real_root = float(roots[np.abs(roots.imag) < 1e-12].real[0])
    assert rk4_stability_boundary(-1) == pytest.approx(-real_root, rel=1e-9)
    bound = -real_root / 1000
    h = stability_limit(rc(R=1.0, C=1e-3), "rk4", initial={"q_R": 1.0}, lo=0.5 * bound, hi=1.5 * bound)
    assert h / bound == pytest.approx(1.0, abs=2e-3)
    # a diverging run is reported with the step, |λ|max and what to do
    with pytest.raises(lg.IntegrationError, match=r"rk4 failed.*diverged.*h·\|λ\|max = 3.*unstable.*Reduce step="):
        rc(R=1.0, C=1e-3).simulate(2.0, initial={"q_R": 1.0}, method="rk4", step=3e-3, fast_linear=False)


def test_implicit_methods_are_stable_far_beyond_the_explicit_bound():
    # A-stable: implicit midpoint and Gauss–Legendre stay bounded at h = 100× the RK4 bound on the RC circuit.
    for method in ("implicit_midpoint", "gauss_legendre"):
        res = rc(R=1.0, C=1e-3).simulate(2.0, initial={"q_R": 1.0}, method=method, step=0.25, points=9)
        assert np.all(np.abs(res["q_R"]) <= 1.0 + 1e-12), method


def test_auto_never_picks_an_explicit_method_for_a_stiff_model():
    reg = lg.default_registry()
    linear = stiff_chain().simulate(1.0, method="auto", initial={"x_a": 1.0})
    assert linear.method == "exact"  # linear time-invariant: solved exactly
    # a stiffer chain made nonlinear (a cubic spring) and overdamped across the stiff spring: the relative
    # mode's eigenvalues −c/2μ ± √((c/2μ)² − K/μ) (μ = ½) are ≈ −1.0e3 and −2.0e5, beside |λ| ≈ 1.4
    model = stiff_chain(K=1e8)
    model.add("cubic_spring", "s3", ("ground", "a"), k=1, k3=1)
    model.add("damper", "c", ("a", "b"), c=1e5)
    for rtol in (1e-9, 1e-3):
        res = model.simulate(0.5, method="auto", rtol=rtol, initial={"x_a": 1.0})
        picked = reg.integrators[res.method]
        assert picked.implicit and picked.stiff, res.method
        assert res.method == "LSODA"
        assert "stiff" in res.notes[0] and "auto: picked" in res.notes[0]


@pytest.mark.slow
def test_auto_on_non_stiff_models():
    # Duffing: not linear, not stiff; DOP853 for tight tolerances, RK45 for loose ones
    assert duffing().simulate(1.0, method="auto", initial={"x_p": 1}).method == "DOP853"
    assert duffing().simulate(1.0, method="auto", rtol=1e-4, initial={"x_p": 1}).method == "RK45"
    # a long conservative run at a loose tolerance: a symplectic method, Verlet when separable
    res = duffing().simulate(4000.0, method="auto", rtol=1e-3, initial={"x_p": 1}, points=11)  # ≈ 1270 periods of ω = 2
    assert res.method == "verlet" and res.step > 0
    assert "symplectic" in res.notes[0] and "long conservative run" in res.notes[0]
    # ... Gauss–Legendre when the mass matrix depends on the configuration (asked of choose, without running)
    model = solenoid()
    problem = Problem(model.numeric(), model.name)
    choice = choose(problem, (0.0, 5000.0), np.array([1.0, 0.5, 0.0, 0.0]), rtol=1e-4)
    assert choice.method == "gauss_legendre" and choice.options["step"] > 0 and not choice.stiff
    # ... and never for a damped one
    assert oscillator(c=0.1).simulate(1.0, method="auto", rtol=1e-4, initial={"x_p": 1}).method == "exact"


def spherical_pendulum(m=0.3, length=0.7, g=9.81) -> lg.Model:
    """The README's spherical pendulum: φ = theta_turn about the vertical (ignorable), θ = theta_tilt from below."""
    return models.spherical_pendulum(m, length, g)


@given(m=decades(1e-2, 1e2), length=decades(1e-2, 1e2), g=decades(0.1, 100), theta=st.floats(0.2, 1.4),
       rate=decades(0.1, 10), span=decades(10, 1e5))
@settings(max_examples=6)
@pytest.mark.slow
def test_auto_measures_stiffness_on_the_non_zero_spectrum(m, length, g, theta, rate, span):
    # Spherical pendulum at θ, θ' = 0, φ' = Ω.  From θ'' = sin θ cos θ φ'² − (g/l) sin θ and φ'' = −2 cot θ θ' φ',
    # the linearization in (φ, θ, φ', θ') has the characteristic polynomial λ² (λ² + ω²) with
    # ω² = (1 + 2 cos² θ) Ω² + (g/l) cos θ: a zero pair (φ is ignorable) and ±iω.  Not stiff, whatever the span.
    model = spherical_pendulum(m, length, g)
    problem = Problem(model.numeric(), model.name)
    y0 = np.array([0.0, theta, rate, 0.0])  # (theta_turn, theta_tilt, their rates)
    spectrum = problem.spectrum(0.0, y0)
    omega = math.sqrt((1 + 2 * math.cos(theta) ** 2) * rate**2 + g / length * math.cos(theta))
    assert int(spectrum.zero.sum()) == 2
    assert np.sort(np.abs(spectrum.nonzero)) == pytest.approx([omega, omega], rel=1e-6)
    choice = choose(problem, (0.0, span), y0, rtol=1e-9, integrators=lg.default_registry().integrators)
    assert not choice.stiff and choice.method == "DOP853", choice.notes
    assert "2 zero" in choice.notes[0]


@pytest.mark.slow
def test_auto_on_the_readme_spherical_pendulum_over_a_long_run_is_not_stiff_but_symplectic():
    # 0.3 kg at 0.7 m, 1000 s at rtol 1e-4: ω ≈ 3.72 rad/s, ≈ 590 periods — a long conservative run, so a
    # symplectic method (the mass matrix depends on θ: Gauss–Legendre), not LSODA
    model = spherical_pendulum()
    problem = Problem(model.numeric(), model.name)
    reg = lg.default_registry()
    choice = choose(problem, (0.0, 1000.0), np.array([0.0, 0.9, 1.7, 0.0]), rtol=1e-4, integrators=reg.integrators)
    assert not choice.stiff and reg.integrators[choice.method].symplectic, choice.notes


def double_pendulum(m=0.3, length=0.7) -> lg.Model:
    """The README's double pendulum (absolute angles from +x, gravity along −y) with ordinary values."""
    model = lg.Model("double pendulum", dim=2)
    for i in (1, 2):
        model.add("link", f"l{i}", f"l{i}", points={"end": (length, 0)})
        model.add("mass", f"m{i}", f"l{i}.end", m=m)
    model.add("revolute", "j1", ("ground", "l1"), absolute=True)
    model.add("revolute", "j2", ("l1", "l2"), parent_point=(length, 0), absolute=True)
    model.add("gravity", "g")
    return model


@pytest.mark.slow
def test_auto_keeps_the_energy_of_a_long_conservative_run_started_at_rest_away_from_equilibrium():
    # Let go from the horizontal, the double pendulum's linearization at the start has no frequency in it
    # (∂(torque)/∂θ ∝ sin θ = 0 there, and the velocities are zero).  auto must still see a long conservative run
    # (its probe run finds the rates of the motion) and keep the energy T + V bounded: the Jacobi integral
    # of a conservative system is constant, so its spread is the integration error.
    model = double_pendulum()
    res = model.simulate(120.0, method="auto", rtol=1e-3, initial={"theta_j1": 0.0, "theta_j2": 0.0}, points=2001)
    assert lg.default_registry().integrators[res.method].symplectic, res.notes
    scale = np.max(np.abs(res.V)) + np.max(np.abs(res.T))
    assert np.max(np.abs(res.E - res.E[0])) / scale < 1e-2
    # a pendulum of 0.3 kg on 0.7 m, let go from the horizontal over 300 s (≈ 1400 periods of its fastest
    # linearized rate along the swing): separable (M = m l²), so Störmer–Verlet, bounded energy
    pendulum = lg.Model("pendulum", dim=2)
    pendulum.add("link", "arm", "arm", points={"bob": (0.7, 0)})
    pendulum.add("revolute", "pin", ("ground", "arm"))
    pendulum.add("mass", "bob", "arm.bob", m=0.3)
    pendulum.add("gravity", "g")
    res = pendulum.simulate(300.0, method="auto", rtol=1e-4, initial={"theta_pin": 0.0}, points=3001)
    assert res.method == "verlet", res.notes
    assert np.max(np.abs(res.E - res.E[0])) / (0.3 * 9.81 * 0.7) < 1e-3


README = Path(__file__).resolve().parents[1] / "README.md"


def readme_models() -> dict[str, lg.Model]:
    """Every model the README's Python blocks build: each block's leading imports, ``lg.Model(...)`` and ``.add`` lines."""
    keep = re.compile(r"^(import |from |\w+ = lg\.Model\(|\w+\.add\(|for |\s+\S|\s*$)")
    models = {}
    for block in re.findall(r"```python\n(.*?)```", README.read_text(), re.S):
        if "lg.Model(" not in block or "lg.Registry(plugins=" in block:  # (that one needs its plugin: test_plugins)
            continue
        lines = []
        for line in block.splitlines():
            if not keep.match(line):
                break
            lines.append(line)
        namespace = {"lg": lg, "sp": sp}
        exec("\n".join(lines), namespace)
        models.update({v.name: v for v in namespace.values() if isinstance(v, lg.Model)})
    return models


@pytest.mark.slow
def test_readme_integrator_examples_run_as_written():
    block = next(b for b in re.findall(r"```python\n(.*?)```", README.read_text(), re.S) if 'method="verlet"' in b)
    statements = [line for line in block.splitlines() if line.startswith("res = m.simulate(")]
    assert [s.split("method=")[1][:8] for s in statements] == ['"verlet"', '"auto", ']
    models = readme_models()
    assert set(models) >= {"mass-spring-damper", "series-RLC", "double pendulum", "spherical pendulum"}
    # the quickstart's m ẍ + c ẋ + k x = sin 1.5t (1 kg, 4 N/m, 0.4 N s/m) and its analogue, L q̈ + R q̇ + q/C = sin 1.5t
    # (1 H, 0.4 Ω, 0.25 F), both from rest: the closed form of the forced damped oscillator
    exact = forced_damped_exact(1.0, 4.0, 0.4, 1.0, 1.5, 0.0, 0.0)
    for name, coordinate in (("mass-spring-damper", "x_cart"), ("series-RLC", "q_L")):
        namespace = {"m": models[name]}
        for statement, tol in zip(statements, (1e-4, 1e-9)):  # verlet: O((hω)²) with hω = 0.02; auto: exact
            exec(statement, namespace)
            res = namespace["res"]
            assert np.max(np.abs(res[coordinate] - exact(res.t))) < tol * 0.6, (name, statement)  # amplitude ≈ 0.6
    # the pendulums: a configuration-dependent mass matrix, refused with what to use instead ...
    for name, start in (("double pendulum", {"theta_j1": -1.0, "theta_j2": -0.5}),
                        ("spherical pendulum", {"theta_tilt": 0.9, "theta_turn": 0.0})):
        with pytest.raises(lg.ModelError, match=r"mass matrix depends on theta.*'variational' with rule='trapezoidal'"):
            exec(statements[0], {"m": models[name]})
        # ... and what it names runs, keeping the energy of these conservative models
        res = models[name].simulate(10, method="variational", rule="trapezoidal", step=0.01, initial=start, points=101)
        assert np.max(np.abs(res.E - res.E[0])) < 1e-3 * (np.max(np.abs(res.T)) + np.max(np.abs(res.V)))


# ---------------------------------------------------------------------------
# 4. Long-time energy


def long_run_grid(h, periods, every=321):
    """Output every ``every`` steps (not a multiple of the 32 steps per period, so every phase is sampled)."""
    n_out = periods * 32 // every
    return np.arange(n_out + 1) * every * h


@pytest.mark.slow
def test_energy_over_1e5_periods_bounded_for_symplectic_methods_drifting_for_rk4():
    # Oscillator m = k = 1 (ω = 1), h = T/32 (y = hω = 2π/32), 3.2·10⁶ steps.  On this linear model every
    # fixed-step method is one constant matrix per step, applied here by its powers (fast_linear).
    # Verlet conserves ½v² + ½x²(1 − y²/4)... its energy E = ½(v² + x²) stays within a relative
    #   (y/2)² / (1 − (y/2)²) of that invariant's level: bounded, no drift.
    # Implicit midpoint, Gauss–Legendre and the midpoint variational integrator conserve E exactly (a quadratic
    #   invariant) up to rounding.
    # RK4 is R(iy) times a rotation per step: E_N / E_0 = |R(iy)|^{2N}, |R(iy)|² = 1 − y⁶/72 + y⁸/576 — drift.
    y = 2 * math.pi / 32
    t_eval = long_run_grid(y, 100_000)
    N = int(round(t_eval[-1] / y))
    assert N > 3_000_000
    model = oscillator()
    runs = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", EnergyDriftWarning)
        for method in ("verlet", "implicit_midpoint", "gauss_legendre", "variational", "rk4"):
            runs[method] = model.simulate(t_eval[-1], initial={"x_p": 1}, velocity={"x_p": 0}, method=method, step=y, t_eval=t_eval)
    rel = {m: np.abs(r.E - r.E[0]) / r.E[0] for m, r in runs.items()}
    bound = (y / 2) ** 2 / (1 - (y / 2) ** 2)
    verlet = rel["verlet"]
    tenth = len(verlet) // 10
    assert verlet.max() <= bound * (1 + 1e-9)
    assert verlet.max() > 0.9 * bound  # the bound is reached: every phase is sampled
    assert verlet[-tenth:].max() == pytest.approx(verlet[:tenth].max(), rel=0.02)  # no drift over 10⁵ periods
    for method in ("implicit_midpoint", "gauss_legendre", "variational"):
        assert rel[method].max() < 1e-8, method
    expected = (1 - y**6 / 72 + y**8 / 576) ** N
    assert expected < 0.1
    assert runs["rk4"].E[-1] / runs["rk4"].E[0] == pytest.approx(expected, rel=1e-6)


@pytest.mark.slow
def test_linear_fast_path_gives_the_same_iterates_as_stepping():
    t_eval = long_run_grid(2 * math.pi / 32, 100)
    model = oscillator()
    for method in ("verlet", "rk4", "gauss_legendre", "variational"):
        a, b = (model.simulate(t_eval[-1], initial={"x_p": 1}, velocity={"x_p": 0}, method=method, step=2 * math.pi / 32,
                               t_eval=t_eval, fast_linear=fast) for fast in (True, False))
        assert np.max(np.abs(a["x_p"] - b["x_p"])) < 1e-10, method
        assert any("powers" in n for n in a.notes) and not any("powers" in n for n in b.notes)


@pytest.mark.slow
def test_energy_of_a_nonlinear_oscillator_bounded_for_symplectic_methods_drifting_otherwise():
    # Duffing, E = ½ẋ² + ½x² + ¼x⁴ = 3/4 from x = 1.  Stepped one by one (it is not linear).
    model = duffing()
    start = {"initial": {"x_p": 1}, "velocity": {"x_p": 0}}

    def envelope(res):
        rel = np.abs(res.E - res.E[0]) / res.E[0]
        tenth = len(rel) // 10
        return rel[:tenth].max(), rel[-tenth:].max()

    verlet = model.simulate(4000.0, method="verlet", step=0.05, points=4001, **start)  # ≈ 750 periods, 80 000 steps
    first, last = envelope(verlet)
    assert last < 2e-3 and last < 1.5 * first  # bounded
    for method in ("variational", "gauss_legendre"):
        res = model.simulate(400.0, method=method, step=0.1, points=401, **start)
        first, last = envelope(res)
        assert last < 1.5 * first and last < 2e-3, method
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", EnergyDriftWarning)
        rk4 = model.simulate(2000.0, method="rk4", step=0.2, points=2001, **start)
        rk45 = model.simulate(200.0, method="RK45", rtol=1e-5, atol=1e-8, points=201, **start)
    for res in (rk4, rk45):
        first, last = envelope(res)
        assert last > 5 * first, res.method  # grows with time


def test_energy_drift_of_a_conservative_model_warns_and_is_noted():
    with pytest.warns(EnergyDriftWarning, match=r"conservative, but its energy .* drifted by .* under rk4.*symplectic") as record:
        res = oscillator().simulate(20_000.0, initial={"x_p": 1}, velocity={"x_p": 0}, method="rk4", step=0.3, points=101)
    assert record[0].filename == __file__  # the warning points at the caller
    assert res.notes[-1].startswith("WARNING: ")
    with pytest.warns(EnergyDriftWarning, match="under DOP853 .*tighten rtol"):
        oscillator().simulate(100.0, initial={"x_p": 1}, velocity={"x_p": 0}, energy_tol=1e-13)
    with warnings.catch_warnings():
        warnings.simplefilter("error", EnergyDriftWarning)
        ok = oscillator().simulate(100.0, initial={"x_p": 1}, velocity={"x_p": 0})  # DOP853 at 1e-9: fine
        assert "energy (Jacobi integral) kept to" in ok.notes[-1]
        oscillator().simulate(20_000.0, initial={"x_p": 1}, velocity={"x_p": 0}, method="rk4", step=0.3, points=101,
                              energy_tol=False)
        damped = oscillator(c=0.5).simulate(10.0, initial={"x_p": 1}, velocity={"x_p": 0})
        assert not any("energy" in n for n in damped.notes)  # not conservative: nothing to check
    with pytest.raises(EnergyDriftWarning):
        with warnings.catch_warnings():
            warnings.simplefilter("error", EnergyDriftWarning)  # how a caller makes drift an error
            oscillator().simulate(100.0, initial={"x_p": 1}, velocity={"x_p": 0}, energy_tol=1e-13)


def test_dop853_runs_in_c_with_scipys_steps_and_accuracy():
    """The loop in C against SciPy's DOP853 (an independent implementation of the same method): the same steps (the
    evaluations differ by the three of one dense output SciPy also prepares for the start), solutions within a
    hundredth of the tolerance, and against the closed form of a damped oscillator within the tolerance."""
    m = lg.Model("damped oscillator")
    m.add("mass", "m", "p", m=0.3)
    m.add("spring", "k", ("ground", "p"), k=47.0)
    m.add("damper", "c", ("ground", "p"), c=0.09)
    start = dict(initial={"x_p": 0.02}, velocity={"x_p": 0.0}, points=301)
    w0, zeta = math.sqrt(47.0 / 0.3), 0.09 / (2 * math.sqrt(47.0 * 0.3))
    wd = w0 * math.sqrt(1 - zeta**2)
    for rtol in (1e-5, 1e-8, 1e-11):
        ours = m.simulate(6.0, rtol=rtol, atol=rtol * 1e-3, **start)
        ref = m.simulate(6.0, method="DOP853_scipy", rtol=rtol, atol=rtol * 1e-3, **start)
        assert ours.method == "DOP853" and any("steps in compiled code" in n for n in ours.notes)
        assert abs(ours.nfev - ref.nfev) <= 3
        assert np.abs(ours["x_p"] - ref["x_p"]).max() <= max(0.01 * rtol, 1e-11) * 0.02  # rounding below 1e-11
        t = ours.t
        exact = 0.02 * np.exp(-zeta * w0 * t) * (np.cos(wd * t) + zeta * w0 / wd * np.sin(wd * t))
        assert np.abs(ours["x_p"] - exact).max() <= 50 * rtol * 0.02
    # where it cannot run in C (NumPy evaluation asked for, or progress reported) it is SciPy's, without a note
    numpy = m.simulate(6.0, compiled=False, rtol=1e-8, **start)
    assert numpy.method == "DOP853" and not any("compiled" in n for n in numpy.notes)
    assert np.abs(numpy["x_p"] - m.simulate(6.0, rtol=1e-8, **start)["x_p"]).max() <= 1e-12


def test_the_dop853_tables_in_c_are_scipys():
    """The coefficients written out in lagrangian.numerics.c_dop853 are scipy.integrate.DOP853's, exactly."""
    import re

    from scipy.integrate import DOP853

    from lagrangian.numerics.c_dop853 import dop853_source

    source = dop853_source()

    def table(name):
        body = re.search(rf"static const double {name}\[[^=]*= \{{(.*?)\}};", source, re.S).group(1)
        return np.array([float(x) for x in re.findall(r"-?\d+\.\d+(?:e-?\d+)?|-?\d+e-?\d+", body)])

    A = table("D8_A").reshape(16, 16)
    assert np.array_equal(A[:12, :12], DOP853.A) and np.array_equal(A[12, :12], DOP853.B)
    assert np.array_equal(A[13:16], DOP853.A_EXTRA)
    C = table("D8_C")
    assert np.array_equal(C[:12], DOP853.C) and C[12] == 1.0 and np.array_equal(C[13:], DOP853.C_EXTRA)
    assert np.array_equal(table("D8_E5"), DOP853.E5) and np.array_equal(table("D8_E3"), DOP853.E3)
    assert np.array_equal(table("D8_D").reshape(4, 16), DOP853.D)

    # the stages as the loop computes them, written out with the nonzero coefficients: SciPy's rows, term by term
    def terms(text):
        return [(float(c), int(j)) for c, j in re.findall(r"(-?\d[\d.e+-]*) \* k(\d+)\[i\]", text)]

    def nonzero(row):
        return [(float(c), j) for j, c in enumerate(row) if c != 0.0]

    rows = [*DOP853.A[1:], DOP853.B, *DOP853.A_EXTRA]
    for s, row in enumerate(rows, start=1):
        case = re.search(rf"case {s}: \{{.*?\n(.*?); return; \}}", source, re.S).group(1)
        assert terms(case) == nonzero(row), s
    errors = re.search(r"e5\[i\] = (.*?);\s+e3\[i\] = (.*?);", source, re.S)
    assert terms(errors.group(1)) == nonzero(DOP853.E5) and terms(errors.group(2)) == nonzero(DOP853.E3)
    for r in range(4):
        assert terms(re.search(rf"F{3 + r}\[i\] = hs \* \((.*?)\);", source).group(1)) == nonzero(DOP853.D[r]), r


@settings(max_examples=30)
@given(st.sampled_from([1, 2, 3]), st.lists(st.floats(-1e3, 1e3), min_size=4, max_size=4), st.floats(1e-4, 10.0))
def test_gauss_legendre_starts_each_step_on_the_last_steps_collocation_polynomial(stages, coefficients, h):
    """The starting stages continue the collocation polynomial: exact for a motion that is a polynomial of degree
    up to the number of stages (what collocation reproduces), checked against the polynomial itself."""
    from lagrangian.plugins.integrators.implicit import _extrapolation, gauss_legendre_tableau

    _, _, c = gauss_legendre_tableau(stages)
    poly = np.polynomial.Polynomial(coefficients[:stages + 1])
    t0 = 0.37

    def u(theta):  # the motion over the last step, in units of the step
        return poly(t0 + theta * h)

    Z = np.array([[u(ci) - u(0.0)] for ci in c])
    expected = np.array([u(1.0 + ci) - u(1.0) for ci in c])
    scale = max(1.0, float(np.max(np.abs([u(x) for x in (0.0, 1.0, 2.0)]))))
    assert np.allclose((_extrapolation(c) @ Z).ravel(), expected, rtol=0, atol=1e-9 * scale)


@settings(max_examples=60)
@given(st.integers(1, 12), st.integers(0, 2**32 - 1), st.floats(0.0, 0.6))
def test_balancing_is_lapacks_to_the_bit(n, seed, sparsity):
    """The stiffness check's balancing against SciPy's (LAPACK's DGEBAL, scaling only), on matrices whose entries
    span 16 decades, some of them zero."""
    import scipy.linalg

    from lagrangian.numerics.problem import balance

    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n)) * 10.0 ** rng.uniform(-8, 8, (n, n))
    A[rng.random((n, n)) < sparsity] = 0.0
    B, d = balance(A)
    ref, T = scipy.linalg.matrix_balance(A, permute=False)
    assert np.array_equal(B, ref) and np.array_equal(d, np.diag(T))
