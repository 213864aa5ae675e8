"""The variable capacitor and the solenoid in ngspice, through their circuit analogues.

Each transducer maps (``lagrangian.analogy.map_model``) to a two-port of
behavioural sources — ``capacitive_two_port``, ``inductive_two_port`` — with
the mechanical part as its force–voltage or force–current network, so the
electromechanical system is one ngspice deck.  Everything here runs the real
ngspice shared library through PySpice: no mocks.  The references are
lagrangian's own simulation of the original model (same time points) and
closed forms of the static equilibrium, solved with ``scipy.optimize.brentq``.

Tolerances stated per test are relative to the peak of the compared signal.
The behavioural laws (``lagrangian.spice.Behaviour``) these decks are made of
are tested here too.
"""

from __future__ import annotations

import functools
import math
import re
import sys
import warnings

import numpy as np
import pytest
import sympy as sp
from hypothesis import Phase, given, settings
from hypothesis import strategies as st
from scipy.optimize import brentq

import lagrangian as lg
from lagrangian.analogy import map_model
from lagrangian.compare import compare_with_ngspice
from lagrangian.plugins.transducers import electrostatic_equilibria
from lagrangian.spice import Behaviour, SpiceElement, netlist, run_transient, spice_expression

ANALOGIES = ["force-voltage", "force-current"]
FORMULATION = {"force-voltage": "charge", "force-current": "flux"}
# the electrostatic actuator's charges (1e-9 C), currents (1e-7 A) and forces (1e-4 N) sit near ngspice's default
# absolute tolerances (chgtol 1e-14 C, abstol 1e-12 A, vntol 1e-6 V); these tighter ones take its error from ~1e-5
# to ~1e-6 of the peak (far tighter ones stall ngspice near rest, "timestep too small")
OPTIONS = {"reltol": 1e-6, "abstol": 1e-15, "vntol": 1e-12, "chgtol": 1e-20}


# ---------------------------------------------------------------------------
# the two systems


def actuator(formulation: str, *, V: float, R: float, eps_A: float, gap: float, m: float, k: float, c: float) -> lg.Model:
    """Electrostatic actuator: a plate (mass m, spring k, damper c) facing an electrode, charged through R."""
    model = lg.Model("electrostatic actuator", formulation=formulation)
    model.add("voltage_source", "V", ("n1", "0"), E=V)
    model.add("resistor", "R", ("n1", "n2"), R=R)
    model.add("variable_capacitor", "Cx", ("n2", "0", "plate"), eps_A=eps_A, gap=gap)
    model.add("mass", "m", "plate", m=m)
    model.add("spring", "k", ("ground", "plate"), k=k)
    model.add("damper", "c", ("ground", "plate"), c=c)
    return model


def plunger(formulation: str, *, V: float, R: float, L0: float, x0: float, m: float, k: float, c: float) -> lg.Model:
    """Solenoid plunger: series R, L(x) = L0/(1 + x/x0), plunger mass m on a spring k with a damper c, a voltage step."""
    model = lg.Model("solenoid plunger", formulation=formulation)
    model.add("voltage_source", "V", ("n1", "0"), E=V)
    model.add("resistor", "R", ("n1", "n2"), R=R)
    model.add("solenoid", "S", ("n2", "0", "plunger"), L0=L0, x0=x0)
    model.add("mass", "m", "plunger", m=m)
    model.add("spring", "k", ("ground", "plunger"), k=k)
    model.add("damper", "c", ("ground", "plunger"), c=c)
    return model


# ordinary values: 1 cm² plates 100 µm apart in air (C0 = 8.85 pF), a 10 mg plate on 100 N/m (503 Hz), ζ = 0.5;
# 4.7 MΩ makes the charging time R C0 = 42 µs, about a fiftieth of the period; 100 V is 0.55 of pull-in (183 V)
ACTUATOR = dict(V=100.0, R=4.7e6, eps_A=8.85e-12 * 1e-4, gap=1e-4, m=1e-5, k=100.0, c=0.5 * 2 * math.sqrt(100.0 * 1e-5))
# a 50 mH coil whose inductance halves over 2 mm of travel, 50 Ω (L/R = 1 ms), a 10 g plunger on 1000 N/m (50 Hz), ζ = 0.5,
# a 5 V step: 0.1 A pulls with 0.125 N, 6 % of k·x0 (the solenoid's own pull-in is at 4/27 of it)
PLUNGER = dict(V=5.0, R=50.0, L0=0.05, x0=2e-3, m=0.01, k=1000.0, c=0.5 * 2 * math.sqrt(1000.0 * 0.01))


def electrostatic_rest(V: float, eps_A: float, gap: float, k: float, **_) -> float:
    """The stable root of k x = eps_A V² / (2 (gap − x)²), between 0 and the pull-in displacement gap/3."""
    return brentq(lambda x: k * x - eps_A * V**2 / (2 * (gap - x) ** 2), 0.0, gap / 3, xtol=1e-16 * gap, rtol=1e-15)


def solenoid_rest(V: float, R: float, L0: float, x0: float, k: float, **_) -> float:
    """The stable root of k x = ½ i² L'(x) = −L0 i² / (2 x0 (1 + x/x0)²), i = V/R, between −x0/3 (pull-in) and 0."""
    i = V / R
    return brentq(lambda x: k * x + L0 * i**2 / (2 * x0 * (1 + x / x0) ** 2), -x0 / 3, 0.0, xtol=1e-16 * x0, rtol=1e-15)


def settling_time(A: np.ndarray, decades: float = 9.5) -> float:
    """Time for the slowest mode of the linearization ẏ = A y about rest to decay by 10^-decades."""
    return decades * math.log(10) / min(-np.linalg.eigvals(A).real)


def actuator_settling(V, R, eps_A, gap, m, k, c, **_) -> float:
    """Settling time of the actuator: R q̇ + q (gap − x)/eps_A = V, m ẍ + c ẋ + k x = q²/(2 eps_A), linearized at rest."""
    x = electrostatic_rest(V=V, eps_A=eps_A, gap=gap, k=k)
    q = eps_A * V / (gap - x)
    return settling_time(np.array([[-(gap - x) / (eps_A * R), q / (eps_A * R), 0], [0, 0, 1], [q / (eps_A * m), -k / m, -c / m]]))


def plunger_settling(V, R, L0, x0, m, k, c, **_) -> float:
    """Settling time of the plunger: d(L(x) i)/dt + R i = V, m ẍ + c ẋ + k x = ½ L'(x) i², linearized at rest."""
    x, i = solenoid_rest(V=V, R=R, L0=L0, x0=x0, k=k), V / R
    L, dL, d2L = L0 / (1 + x / x0), -L0 / (x0 * (1 + x / x0) ** 2), 2 * L0 / (x0**2 * (1 + x / x0) ** 3)
    return settling_time(np.array([[-R / L, 0, -dL * i / L], [0, 0, 1], [dL * i / m, (-k + d2L * i**2 / 2) / m, -c / m]]))


# ---------------------------------------------------------------------------
# running both


def current_expr(model: lg.Model) -> sp.Expr:
    """The current through the resistor (the transducer's current), in the model's coordinates."""
    branch = model.assembly.views["electrical"].branch_value("R").diff(lg.t)
    return branch if model.options["formulation"] == "charge" else branch / model.component("R").R


@functools.cache
def trajectories(kind: str, analogy: str, t_end: float, max_step: float, values: tuple, options: tuple = tuple(OPTIONS.items())):
    """ngspice on the analogue and lagrangian on the model, from rest; displacement and current on ngspice's points.

    Returns ``(time, x_spice, x_ours, i_spice, i_ours, deck)``.  Our integration's absolute tolerance is 1e-14 of
    the plate's speed scale ``x_eq·ω``: far below every state's size, and above the rounding noise of the speed at rest.
    """
    values = dict(values)
    build, scale, transducer = (actuator, "gap", "Cx") if kind == "capacitor" else (plunger, "x0", "S")
    x_eq = electrostatic_rest(**values) if kind == "capacitor" else solenoid_rest(**values)
    atol = 1e-14 * abs(x_eq) * math.sqrt(values["k"] / values["m"])
    model = build(FORMULATION[analogy], **values)
    mapped = map_model(model, analogy)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lg.InitialConditionWarning)  # from rest, uncharged
        q0, v0 = mapped.initial({}, {})
        net = netlist(mapped.model, initial=q0, velocity=v0, t_end=t_end, step=max_step * 10, max_step=max_step,
                      options=dict(options))
        source = next(name for name, comp in net.elements.items() if comp == "V")
        run = run_transient(net, {**net.probes, "i_source": ("i", source)})
        res = model.simulate((0.0, max(t_end, run.time[-1])), t_eval=run.time, method="LSODA", rtol=1e-12, atol=atol)
    x_spice = run.quantities[f"v(T_{transducer}.x)"] * values[scale]
    i_spice = -run.quantities["i_source"]  # ngspice's source current runs from + through the source to −
    return run.time, x_spice, res[f"x_{'plate' if kind == 'capacitor' else 'plunger'}"], i_spice, res.quantity(current_expr(model)), net.text


def rel_err(ours: np.ndarray, theirs: np.ndarray) -> float:
    return float(np.max(np.abs(ours - theirs)) / np.max(np.abs(theirs)))


# ---------------------------------------------------------------------------
# the decks


def test_the_actuator_maps_to_one_deck_of_behavioural_sources():
    """Force–voltage: the plate's mesh carries a B voltage source −F, the plates are a charge held by a B source."""
    model = actuator("charge", **ACTUATOR)
    mapped = map_model(model, "force-voltage")
    kinds = {name: c.kind for name, c in mapped.model.components.items()}
    assert kinds["T_Cx"] == "capacitive_two_port" and kinds["L_m"] == "inductor" and kinds["C_k"] == "capacitor"
    assert mapped.origin["T_Cx"] == "Cx"
    deck = netlist(mapped.model, t_end=1e-3).text
    lines = {line.split()[0]: line for line in deck.splitlines()[1:]}
    assert lines["b_t_cx_hold_q"] == "b_t_cx_hold_q t_cx_u 0 V=v(n2,0)/(1 - v(t_cx_x))"
    assert lines["c_t_cx_q"] == "c_t_cx_q t_cx_uc 0 8.85e-12 ic=0"  # C0 = eps_A/gap, charged to q/C0
    assert lines["f_t_cx_port"] == "f_t_cx_port n2 0 v_t_cx_sense_q 1"  # dq/dt into the port
    # the force q²/(2 eps_A) = eps_A u²/(2 gap²) against the mesh current, x/gap integrated from it
    assert lines["b_t_cx_force"] == "b_t_cx_force t_cx_m 0 V=-4.425e-08*pow(v(t_cx_uc),2)"
    assert lines["b_t_cx_integrate_x"] == "b_t_cx_integrate_x 0 t_cx_x I=10000.0*i(v_t_cx_sense_x)"


def test_the_plunger_maps_to_one_deck_of_behavioural_sources():
    """Force–current: the plunger's node takes a B current source −F; the coil is a flux-controlled B current source."""
    model = plunger("flux", **PLUNGER)
    mapped = map_model(model, "force-current")
    assert {c.kind for c in mapped.model.components.values()} == {
        "voltage_source", "resistor", "inductive_two_port", "capacitor", "inductor"}
    deck = netlist(mapped.model, t_end=1e-3).text
    lines = {line.split()[0]: line for line in deck.splitlines()[1:]}
    assert lines["b_t_s_integrate_lam"] == "b_t_s_integrate_lam 0 t_s_lam I=20.0*v(n2,0)"  # λ/L0 on a 1 F node
    assert lines["b_t_s_port"] == "b_t_s_port n2 0 I=v(t_s_lam)*(v(t_s_x) + 1)"  # i = λ (1 + x/x0)/L0
    assert lines["b_t_s_force"] == "b_t_s_force plunger 0 I=12.5*pow(v(t_s_lam),2)"  # −F = λ²/(2 L0 x0)
    assert lines["b_t_s_integrate_x"] == "b_t_s_integrate_x 0 t_s_x I=500.0*v(plunger,0)"


def test_names_in_the_deck_are_escaped_and_parameters_take_their_values():
    """User names reach the deck only through the netlist's escaping; symbolic parameters only as numbers."""
    eps_A, gap = sp.symbols("eps_A gap", positive=True)
    model = lg.Model("weird names")
    model.add("voltage_source", "V", ("in", "0"), E=10)
    model.add("resistor", "R", ("in", "Top Plate"), R=1e6)
    model.add("variable_capacitor", "C x;.end", ("Top Plate", "0", "plate-1"), eps_A=eps_A, gap=gap)
    model.add("mass", "m", "plate-1", m=1e-5)
    model.add("spring", "k", ("ground", "plate-1"), k=100)
    mapped = map_model(model, "force-voltage")
    with pytest.raises(lg.ModelError, match="symbol"):
        netlist(mapped.model, t_end=1e-3)
    deck = netlist(mapped.model, t_end=1e-3, params={"eps_A": 8.85e-16, "gap": 1e-4}).text
    for line in deck.splitlines()[1:-1]:
        assert re.fullmatch(r"[.A-Za-z0-9_ =(),*/+\-]+", line) and not line.startswith(".end"), line
    assert "V=v(top_plate,0)/(1 - v(t_c_x__end_x))" in deck and "eps_A" not in deck and "gap" not in deck


def test_behavioural_laws_are_checked_and_keep_the_sign_of_odd_powers():
    # ngspice's pow(x, n) is |x|^n: an odd power keeps its sign through a factor of its base
    assert spice_expression(sp.sin(lg.t) ** 3) == "(sin(time))*pow(sin(time),2)"
    assert spice_expression(1 / sp.sin(lg.t)) == "1/((sin(time)))"
    with pytest.raises(lg.ModelError, match="sets V or I"):
        Behaviour("Q", lg.t)

    u = sp.Dummy("u")
    model = lg.Model("b")
    model.add("capacitor", "C", ("a", "0"), C=1)
    model.add("inductor", "L", ("a", "0"), L=1)
    model.components["C"].spice = lambda ctx: [SpiceElement("B", ("a", "0"), Behaviour("V", u, ((u, ("i", "nowhere")),)))]
    with pytest.raises(lg.ModelError, match="refers to \\('i', 'nowhere'\\)"):
        netlist(model, t_end=1)


def test_a_behavioural_source_reads_node_voltages_and_odd_powers_keep_their_sign():
    """B V=(v(in))^3 across a resistor in ngspice: −8 V from −2 V (ngspice's own pow(x, 3) would give +8)."""
    v = sp.Dummy("v")
    m = lg.Model("cube")
    m.add("voltage_source", "V1", ("in", "0"), E=-2)
    m.add("resistor", "R1", ("out", "0"), R=1)
    m.add("capacitor", "C1", ("out", "0"), C=1e-3)
    m.add("resistor", "R2", ("in", "0"), R=1)
    m.components["R1"].spice = lambda ctx: [SpiceElement("B", ("out", lg.GROUND), Behaviour("V", v**3, ((v, ("v", "in")),)))]
    net = netlist(m, t_end=1e-3, options={"reltol": 1e-6})
    assert "b_r1 out 0 V=(v(in))*pow(v(in),2)" in net.text and ".options reltol=1e-06" in net.text
    run = run_transient(net, {"out": ("v", "out")})
    assert np.allclose(run.quantities["out"], -8.0)
    with pytest.raises(lg.ModelError, match="option names"):
        netlist(m, t_end=1e-3, options={"reltol=1 .end": 1})


@pytest.mark.parametrize("kind", ["capacitor", "solenoid"])
@pytest.mark.parametrize("analogy", ANALOGIES)
def test_the_analogue_has_the_transducers_equations(kind, analogy):
    """Substituting the coordinate map into the analogue's equations gives back the model's, symbolically."""
    m_, k_, c_, R_, V_, a_, b_ = sp.symbols("m k c R V a b", positive=True)
    if kind == "capacitor":
        model = actuator(FORMULATION[analogy], V=V_, R=R_, eps_A=a_, gap=b_, m=m_, k=k_, c=c_)
    else:
        model = plunger(FORMULATION[analogy], V=V_, R=R_, L0=a_, x0=b_, m=m_, k=k_, c=c_)
    mapped = map_model(model, analogy)
    funcs = [c.function for c in mapped.model.coordinates]
    theirs = mapped.model.mass_matrix * sp.Matrix([f.diff(lg.t, 2) for f in funcs]) - mapped.model.forcing
    theirs = [sp.expand(mapped.to_source(r)) for r in theirs]
    funcs = [c.function for c in model.coordinates]
    ours = [sp.expand(r) for r in model.mass_matrix * sp.Matrix([f.diff(lg.t, 2) for f in funcs]) - model.forcing]
    for r in theirs:
        assert any(sp.simplify(r - s) == 0 or sp.simplify(r + s) == 0 for s in ours), r


# ---------------------------------------------------------------------------
# trajectories and equilibria against ngspice


ACTUATOR_RUN = dict(t_end=0.015, max_step=1e-6)  # 7.5 periods, e^{-ζωt} = 5e-11: at rest
PLUNGER_RUN = dict(t_end=0.15, max_step=1e-5)  # 7.5 periods, 30 L/R: at rest


@pytest.mark.parametrize("analogy", ANALOGIES)
def test_electrostatic_actuator_trajectory_agrees_with_ngspice(analogy):
    """Displacement within 5e-6 and current within 5e-5 of their peaks, along a 15 ms step response (measured 1.0e-6, 1.0e-5)."""
    time, xs, xo, i_s, i_o, _ = trajectories("capacitor", analogy, values=tuple(ACTUATOR.items()), **ACTUATOR_RUN)
    assert np.max(xs) > 1.1 * xs[-1] > 0  # it overshoots its rest position: a dynamic test, not a static one
    assert rel_err(xo, xs) < 5e-6
    assert rel_err(i_o, i_s) < 5e-5
    assert i_s[0] == pytest.approx(100.0 / 4.7e6, rel=0.05)  # the step charges the plates through R


@pytest.mark.parametrize("analogy", ANALOGIES)
def test_electrostatic_actuator_rests_where_the_closed_form_says(analogy):
    """k x = eps_A V² / (2 (gap − x)²): ngspice's and lagrangian's last x within 1e-9 of the root (measured 4.4e-11)."""
    x_eq = electrostatic_rest(**ACTUATOR)
    time, xs, xo, *_ = trajectories("capacitor", analogy, values=tuple(ACTUATOR.items()), **ACTUATOR_RUN)
    assert 0.04 < x_eq / ACTUATOR["gap"] < 0.06
    assert xs[-1] == pytest.approx(x_eq, rel=1e-9) and xo[-1] == pytest.approx(x_eq, rel=1e-9)
    model = actuator("charge", **ACTUATOR)
    assert electrostatic_equilibria(model, "Cx", ACTUATOR["V"]).position == pytest.approx(x_eq, rel=1e-12)


@pytest.mark.parametrize("analogy", ANALOGIES)
def test_solenoid_plunger_trajectory_agrees_with_ngspice(analogy):
    """Displacement within 5e-6 and current within 1e-5 of their peaks, along a 150 ms step response (measured 8.4e-7, 2.3e-6)."""
    time, xs, xo, i_s, i_o, _ = trajectories("solenoid", analogy, values=tuple(PLUNGER.items()), **PLUNGER_RUN)
    assert np.min(xs) < 1.05 * xs[-1] < 0  # pulled towards smaller x, past its rest position
    assert rel_err(xo, xs) < 5e-6
    assert rel_err(i_o, i_s) < 1e-5
    assert i_s[-1] == pytest.approx(PLUNGER["V"] / PLUNGER["R"], rel=1e-9)


@pytest.mark.parametrize("analogy", ANALOGIES)
def test_solenoid_plunger_rests_where_the_closed_form_says(analogy):
    """k x (1 + x/x0)² = −L0 (V/R)² / (2 x0): ngspice's and lagrangian's last x within 1e-9 of the root (measured 1.2e-11)."""
    x_eq = solenoid_rest(**PLUNGER)
    time, xs, xo, *_ = trajectories("solenoid", analogy, values=tuple(PLUNGER.items()), **PLUNGER_RUN)
    assert -0.08 < x_eq / PLUNGER["x0"] < -0.06
    assert xs[-1] == pytest.approx(x_eq, rel=1e-9) and xo[-1] == pytest.approx(x_eq, rel=1e-9)


@pytest.mark.parametrize("kind", ["capacitor", "solenoid"])
@pytest.mark.parametrize("analogy", ANALOGIES)
def test_compare_with_ngspice_takes_models_with_the_transducers(kind, analogy):
    """The public comparison, with ngspice's default tolerances: every state quantity within 1e-4 of its peak."""
    if kind == "capacitor":
        model, run = actuator(FORMULATION[analogy], **ACTUATOR), dict(t_end=0.005, max_step=1e-6)
        names = {"v(T_Cx.q)", "v(T_Cx.x)"}
    else:
        model, run = plunger(FORMULATION[analogy], **PLUNGER), dict(t_end=0.05, max_step=1e-5)
        names = {"v(T_S.lam)", "v(T_S.x)"}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lg.InitialConditionWarning)
        cmp = compare_with_ngspice(model, run["t_end"], analogy=analogy, step=10 * run["max_step"], max_step=run["max_step"],
                                   method="LSODA", rtol=1e-12, atol=1e-20)
    assert names <= {r.label for r in cmp.rows} and len(cmp.rows) == 4
    assert all(r.peak > 0 for r in cmp.rows)
    assert cmp.worst_rel < 1e-4, cmp.table()


# ---------------------------------------------------------------------------
# over decades


# log-uniform bounds, then uniform ones, of what the property tests draw (and `python tests/test_transducer_spice.py`)
ACTUATOR_DECADES = dict(gap=(1e-4, 1e-3), area=(1e-6, 1e-4), k=(10, 1e3), m=(1e-6, 1e-4), ratio=(0.02, 0.2))
ACTUATOR_LINEAR = dict(zeta=(0.3, 1.0), fraction=(0.1, 0.8))
PLUNGER_DECADES = dict(L0=(1e-3, 1e-1), x0=(1e-4, 1e-2), k=(10, 1e4), m=(1e-3, 1e-1), ratio=(0.05, 2.0))
PLUNGER_LINEAR = dict(zeta=(0.3, 1.0), fraction=(0.01, 0.12))


def three_digits(x: float) -> float:
    return float(f"{x:.3g}")


def log_uniform(lo: float, hi: float):
    return st.floats(math.log10(lo), math.log10(hi)).map(lambda e: three_digits(10**e))


def actuator_case(gap, area, k, m, zeta, ratio, fraction) -> tuple[float, float, float]:
    """Errors (displacement, current: of their peaks; rest position: of the closed form) of one drawn actuator.

    R sets the charging time to ``ratio`` of the mechanical period, V is ``fraction`` of the pull-in voltage; the
    run lasts until the slowest mode of the coupled system linearized at rest has decayed by 10^-9.5 (the pull
    softens the spring, so the closer to pull-in the slower).  It runs in the flux
    formulation through the force-current analogy: in the charge formulation R (up to 1e11 Ω) and the plate's mass
    (down to 1e-6 kg) share the matrix of the solve, whose spread passes the compiled solver's pivot threshold
    (n·eps·max), and it calls the matrix singular.
    """
    eps_A = 8.85e-12 * area
    omega = math.sqrt(k / m)
    period = 2 * math.pi / omega
    v_pi = math.sqrt(8 * k * gap**3 / (27 * eps_A))
    values = dict(V=float(f"{fraction * v_pi:.4g}"), R=three_digits(ratio * period * gap / eps_A), eps_A=eps_A, gap=gap,
                  m=m, k=k, c=2 * zeta * math.sqrt(k * m))
    x_eq = electrostatic_rest(**values)
    t_end = actuator_settling(**values)
    _, xs, xo, i_s, i_o, _ = trajectories("capacitor", "force-current", t_end, period / 2000, tuple(values.items()))
    return rel_err(xo, xs), rel_err(i_o, i_s), max(abs(xs[-1] / x_eq - 1), abs(xo[-1] / x_eq - 1))


def plunger_case(L0, x0, k, m, zeta, ratio, fraction) -> tuple[float, float, float]:
    """Errors (as :func:`actuator_case`) of one drawn plunger: L0/R is ``ratio`` of the mechanical period, V makes the
    pull ``fraction``·k·x0 at x = 0; force-voltage analogy."""
    omega = math.sqrt(k / m)
    period = 2 * math.pi / omega
    R = three_digits(L0 / (ratio * period))
    current = math.sqrt(2 * x0 * fraction * k * x0 / L0)  # L0 i² / (2 x0) = fraction · k x0
    values = dict(V=float(f"{current * R:.4g}"), R=R, L0=L0, x0=x0, m=m, k=k, c=2 * zeta * math.sqrt(k * m))
    max_step = min(period / 2000, L0 / R / 100)
    x_eq = solenoid_rest(**values)
    t_end = plunger_settling(**values)
    _, xs, xo, i_s, i_o, _ = trajectories("solenoid", "force-voltage", t_end, max_step, tuple(values.items()))
    return rel_err(xo, xs), rel_err(i_o, i_s), max(abs(xs[-1] / x_eq - 1), abs(xo[-1] / x_eq - 1))


@settings(max_examples=6, phases=[Phase.explicit, Phase.reuse, Phase.generate])  # no shrinking: ~0.5 s a case
@given(**{k: log_uniform(*b) for k, b in ACTUATOR_DECADES.items()}, **{k: st.floats(*b) for k, b in ACTUATOR_LINEAR.items()})
def test_electrostatic_actuators_over_decades_agree_with_ngspice_and_the_closed_form(gap, area, k, m, zeta, ratio, fraction):
    """Plates of 1 mm² … 1 cm², gaps of 0.1 … 1 mm, springs of 10 … 1000 N/m, 1 … 100 mg, up to 0.8 of pull-in.

    Over 60 cases (``python tests/test_transducer_spice.py 60``): displacement within 1.3e-6 and current within
    1.1e-5 of their peaks, rest position within 7.5e-9 of the closed form; asserted: 1e-5, 1e-4, 1e-7.
    """
    x, i, rest = actuator_case(gap, area, k, m, zeta, ratio, fraction)
    assert x < 1e-5 and i < 1e-4 and rest < 1e-7, (x, i, rest)


@settings(max_examples=6, phases=[Phase.explicit, Phase.reuse, Phase.generate])  # no shrinking: ~0.5 s a case
@given(**{k: log_uniform(*b) for k, b in PLUNGER_DECADES.items()}, **{k: st.floats(*b) for k, b in PLUNGER_LINEAR.items()})
def test_solenoid_plungers_over_decades_agree_with_ngspice_and_the_closed_form(L0, x0, k, m, zeta, ratio, fraction):
    """Coils of 1 … 100 mH, travel scales of 0.1 … 10 mm, 10 … 10⁴ N/m, 1 … 100 g, pulled up to 0.12 k·x0 (pull-in: 4/27).

    Over 60 cases (``python tests/test_transducer_spice.py 60``): displacement within 5.2e-7 and current within
    2.1e-6 of their peaks, rest position within 1.7e-9 of the closed form; asserted: 5e-6, 1e-5, 1e-7.
    """
    x, i, rest = plunger_case(L0, x0, k, m, zeta, ratio, fraction)
    assert x < 5e-6 and i < 1e-5 and rest < 1e-7, (x, i, rest)


# ---------------------------------------------------------------------------
# every transducer example cross-checks itself in ngspice




def run_example(example, script: str, *args: str) -> str:
    out, where = example(script, "--out", "{dir}/chart.png", *args)
    assert "cross-check skipped" not in out
    return out


@pytest.mark.parametrize(("script", "args", "runs", "tol"), [
    ("electrostatic_pullin.py", (), 1, 1e-5),
    ("loudspeaker.py", ("--points", "3"), 1, 1e-5),
    ("dc_motor.py", (), 1, 1e-5),
    ("solenoid.py", (), 2, 1e-4),
])
def test_transducer_examples_agree_with_ngspice(example, script, args, runs, tol):
    out = run_example(example, script, *args)
    worst = [float(w) for w in re.findall(r"ngspice vs simulation.*: worst (\S+) of peak", out)]
    assert len(worst) == runs and max(worst) < tol, out
    if script == "electrostatic_pullin.py":
        rest, exact = map(float, re.search(r"in ngspice the plate rests at x = (\S+) \(stable equilibrium (\S+)\)", out).groups())
        assert rest == pytest.approx(exact, abs=2e-9)
    if script == "solenoid.py":
        diffs = [float(d) for d in re.findall(r"relative difference(?: to the closed form)? (\S+?)\)", out)]
        assert len(diffs) == 3 and max(diffs) < 1e-9, out


# ---------------------------------------------------------------------------
# the figures quoted above: python tests/test_transducer_spice.py [cases drawn per family, default 60]


def main(draws: int = 60) -> None:
    print(f"{'case':58} {'x err':>9} {'i err':>9} {'rest err':>9}")
    for kind, values, run, rest in (("capacitor", ACTUATOR, ACTUATOR_RUN, electrostatic_rest),
                                    ("solenoid", PLUNGER, PLUNGER_RUN, solenoid_rest)):
        x_eq = rest(**values)
        for analogy in ANALOGIES:
            for label, options in (("default tolerances", ()), ("OPTIONS", tuple(OPTIONS.items()))):
                _, xs, xo, i_s, i_o, _ = trajectories(kind, analogy, values=tuple(values.items()), options=options, **run)
                err = max(abs(xs[-1] / x_eq - 1), abs(xo[-1] / x_eq - 1))
                print(f"{kind + ', ' + analogy + ', ' + label:58} {rel_err(xo, xs):9.2e} {rel_err(i_o, i_s):9.2e} {err:9.2e}")
    rng = np.random.default_rng(0)
    for name, case, decades, linear in (("actuators", actuator_case, ACTUATOR_DECADES, ACTUATOR_LINEAR),
                                        ("plungers", plunger_case, PLUNGER_DECADES, PLUNGER_LINEAR)):
        worst = np.zeros(3)
        for _ in range(draws):
            drawn = {k: three_digits(10 ** rng.uniform(math.log10(lo), math.log10(hi))) for k, (lo, hi) in decades.items()}
            drawn.update({k: rng.uniform(lo, hi) for k, (lo, hi) in linear.items()})
            worst = np.maximum(worst, case(**drawn))
        print(f"{f'{draws} {name} drawn over decades, worst':58} {worst[0]:9.2e} {worst[1]:9.2e} {worst[2]:9.2e}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 60)
