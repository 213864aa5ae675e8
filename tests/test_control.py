"""python-control systems of linearizations, transfer functions and frequency responses (``to_control()``).

python-control evaluates what it is given with its own engine (a dense solve of ``(jω I − A) x = B`` per frequency
for a state space, the polynomials for a transfer function); its response is compared with ours (the Laplace form
solved with the loop constraints and multipliers, :func:`frequency_response`, ``TransferFunction.__call__``) and both
with closed forms.  A dense solve keeps a response rolled off by decades only to ``κ ε`` relative (1e-10 on a series
RLC three decades above its resonance), so state spaces are compared over the band of their dynamics, and the matrices
handed to python-control are also evaluated in 40-digit arithmetic (mpmath) over the whole band.
"""

import functools
import sys

import mpmath
import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

import lagrangian as lg
from lagrangian.frequency import decades, frequency_response, impedance, linearize, transfer_function
from lagrangian.models import loudspeaker, rlc_ladder

ct = pytest.importorskip("control")

G = 9.81
TOL = 1e-12


def decade(lo, hi):
    """A value drawn log-uniformly between ``lo`` and ``hi``."""
    return st.floats(np.log10(lo), np.log10(hi)).map(lambda e: float(f"{10 ** e:.4g}"))


def relative(a, b):
    """Largest relative difference of ``a`` from ``b``; where ``b`` is exactly zero (an input that does not reach an
    output), ``a`` must be zero too."""
    a, b = np.asarray(a, dtype=complex), np.asarray(b, dtype=complex)
    zero = b == 0
    assert np.all(a[zero] == 0), a[zero]
    return float(np.max(np.abs(a[~zero] - b[~zero]) / np.abs(b[~zero]), initial=0.0))


def matched(found, expected, scale):
    """Largest distance from each expected root to a distinct found one, relative to ``max(|root|, scale)``."""
    found = list(np.asarray(found, dtype=complex))
    worst = 0.0
    for r in sorted(np.asarray(expected, dtype=complex), key=abs):
        i = int(np.argmin([abs(f - r) for f in found]))
        worst = max(worst, abs(found.pop(i) - r) / max(abs(r), scale))
    return worst


def control_response(system, f):
    """python-control's frequency response of ``system`` at ``f`` (Hz): outputs × inputs × frequencies."""
    out = ct.frequency_response(system, 2 * np.pi * np.asarray(f)).complex
    return np.asarray(out).reshape(system.noutputs, system.ninputs, len(f))


def exact_response(system, f, digits=40):
    """``C (jω I − A)⁻¹ B + D`` of python-control's matrices in ``digits``-digit arithmetic."""
    with mpmath.workdps(digits):
        A, B, C, D = (mpmath.matrix(np.asarray(X).tolist()) for X in (system.A, system.B, system.C, system.D))
        eye = mpmath.eye(system.nstates)
        out = np.empty((system.noutputs, system.ninputs, len(f)), dtype=complex)
        for k, fk in enumerate(f):
            P = mpmath.mpc(0, 2 * mpmath.pi * fk) * eye - A
            for j in range(system.ninputs):  # mpmath solves one right-hand side at a time
                y = C * mpmath.lu_solve(P, B.column(j)) + D.column(j)
                out[:, j, k] = [complex(y[i]) for i in range(system.noutputs)]
    return out


# ---------------------------------------------------------------------------
# The models
# ---------------------------------------------------------------------------


def msd(m, k, c):
    model = lg.Model("msd")
    model.add("mass", "m", "p", m=m)
    model.add("spring", "k", ("ground", "p"), k=k)
    model.add("damper", "c", ("ground", "p"), c=c)
    model.add("force", "F", "p", F=0)
    return model


def series_rlc(R=10.0, L=7e-3, C=2.2e-6, formulation="charge"):
    model = lg.Model("series rlc", formulation=formulation)
    model.add("voltage_source", "V1", ("in", "0"), E=0)
    model.add("resistor", "R1", ("in", "a"), R=R)
    model.add("inductor", "L1", ("a", "b"), L=L)
    model.add("capacitor", "C1", ("b", "0"), C=C)
    return model


PARALLELOGRAM = dict(mc=0.35, mp=0.8, L=0.6, d=1.1)
HANGING = {"theta_A": -np.pi / 2, "theta_B": 0.0, "theta_D": -np.pi / 2}
SLEIGH = dict(m=0.3, inertia=2e-3, a=0.05, u=0.4)


@functools.lru_cache(maxsize=None)
def parallelogram():
    """Two equal cranks and a translating coupler (four revolutes: one loop constraint pair), hanging, pushed
    sideways on the coupler (tests/test_frequency.py)."""
    mc, mp, L, d = (PARALLELOGRAM[k] for k in ("mc", "mp", "L", "d"))
    m = lg.Model("parallelogram", dim=2)
    m.add("rod", "crank", "crank", m=mc, length=L)
    m.add("rod", "coupler", "coupler", m=mp, length=d)
    m.add("rod", "rocker", "rocker", m=mc, length=L)
    m.add("revolute", "A", ("ground", "crank"), absolute=True)
    m.add("revolute", "B", ("crank", "coupler"), parent_point=(L, 0), absolute=True)
    m.add("revolute", "D", ("ground", "rocker"), parent_point=(d, 0), absolute=True)
    m.add("revolute", "C", ("coupler", "rocker"), parent_point=(d, 0), child_point=(L, 0))
    m.add("gravity", "g", g=G)
    m.add("force", "F", "coupler", F=(0, 0))
    return linearize(m, HANGING, inputs=["F[0]"], outputs=["theta_A", "theta_D'"])


@functools.lru_cache(maxsize=None)
def sleigh():
    """Chaplygin's sleigh gliding along +x (a knife edge a behind its centre of mass: one constraint on velocities),
    pushed along its path (F[0]) and across it at its centre of mass (P[1]) (tests/test_linearize_motion.py)."""
    m, inertia, a, u = (SLEIGH[k] for k in ("m", "inertia", "a", "u"))
    model = lg.Model("Chaplygin sleigh", dim=2)
    model.add("body", "b", "b", m=m, inertia=inertia, points={"edge": (-a, 0.0)})
    model.add("free", "j", ("ground", "b"))
    model.add("knife_edge", "k", "b.edge")
    model.add("force", "F", "b", F=(0.0, 0.0))
    model.add("force", "P", "b", F=(0.0, 0.0))
    return linearize(model, velocity={"x_j": u}, inputs=["F[0]", "P[1]"],
                     outputs=["x_j'", "theta_j", "y_j", "theta_j'"])


@functools.lru_cache(maxsize=None)
def cases():
    """name → (linearization, the band of its dynamics (Hz), the whole band looked at (Hz))."""
    return {
        "msd": (linearize(msd(0.3, 40.0, 0.5), inputs=["F"], outputs=["x_p", "x_p'"]), (0.01, 100.0), (0.01, 100.0)),
        "series rlc": (linearize(series_rlc(), inputs=["V1"], outputs=["i(L1)", "v(C1)"]), (1.0, 3e4), (1.0, 1e6)),
        "loudspeaker": (linearize(loudspeaker(), inputs=["E"], outputs=["x_cone", "i(Le)", "x_cone'"]),
                        (1.0, 2e3), (1.0, 2e4)),  # the cone's resonance at 50 Hz, the coil's corner Re/Le at 1.9 kHz
        "ladder": (linearize(rlc_ladder(20), inputs=["V1"], outputs=["v(C19)", "i(L0)", "v(C5)"]),
                   (1e-3, 10.0), (1e-3, 10.0)),
        "parallelogram": (parallelogram(), (0.01, 100.0), (0.01, 100.0)),
        "sleigh": (sleigh(), (0.01, 100.0), (0.01, 100.0)),
    }


NAMES = ["msd", "series rlc", "loudspeaker", "ladder", "parallelogram", "sleigh"]


# ---------------------------------------------------------------------------
# State space: LinearModel.to_control()
# ---------------------------------------------------------------------------


@pytest.mark.slow
@settings(max_examples=30, deadline=None)
@given(m=decade(1e-3, 1e3), k=decade(1e-1, 1e6), zeta=decade(1e-3, 3.0))
def test_mass_spring_damper_state_space_has_our_bode_response_poles_and_dc_gain(m, k, zeta):
    c = 2 * zeta * np.sqrt(k * m)
    lin = linearize(msd(m, k, c), inputs=["F"], outputs=["x_p", "x_p'"])
    system = lin.to_control()
    assert isinstance(system, ct.StateSpace)
    assert (system.input_labels, system.output_labels, system.state_labels) == (["F"], ["x_p", "x_p'"],
                                                                                ["x_p", "x_p'"])
    w0 = np.sqrt(k / m)
    f = w0 / (2 * np.pi) * np.logspace(-2, 2, 41)  # two decades either side of the resonance
    ours = frequency_response(lin, f).H
    s = 2j * np.pi * f
    closed = np.array([1 / (m * s**2 + c * s + k), s / (m * s**2 + c * s + k)])[:, None, :]
    assert relative(ours, closed) <= TOL
    assert relative(ours, exact_response(system, f, digits=30)) <= TOL
    band = f <= w0 / (2 * np.pi) * 10**1.5  # python-control's dense solve: 1e-12 at 100 ω₀, (ω/ω₀)² ε
    assert relative(control_response(system, f[band]), ours[..., band]) <= TOL
    # the poles as the coefficients of their monic polynomial, s² + c/m s + k/m: a double root at critical damping
    # is only known to √ε, its polynomial to ε
    ours_poles = transfer_function(lin, "F", "x_p").poles()
    expected = np.array([1.0, c / m, k / m])
    for poles in (ours_poles, system.poles()):
        assert len(poles) == 2
        assert np.max(np.abs(np.real(np.poly(poles)) - expected) / w0 ** np.arange(3)) <= 1e-9
    assert np.asarray(ct.dcgain(system)).ravel() == pytest.approx([1 / k, 0.0], rel=TOL, abs=TOL / k)


@pytest.mark.parametrize("name", NAMES)
def test_state_space_bode_response_equals_ours_over_the_band_of_its_dynamics(name):
    lin, (lo, hi), _ = cases()[name]
    system = lin.to_control()
    _, _, _, _, states = lin.state_space()
    assert system.input_labels == lin.inputs and system.output_labels == lin.outputs
    assert system.state_labels == states and system.name == lin.model
    f = decades(lo, hi, 25)
    assert relative(control_response(system, f), frequency_response(lin, f).H) <= TOL


@pytest.mark.parametrize("name", [n if n != "ladder" else pytest.param(n, marks=pytest.mark.slow) for n in NAMES])
def test_state_space_handed_to_python_control_is_ours_exactly_over_the_whole_band(name):
    """The matrices python-control holds, evaluated in 40 digits, against our Laplace-form solve: the conversion
    loses nothing, where python-control's dense solve keeps κ ε."""
    lin, _, (lo, hi) = cases()[name]
    f = decades(lo, hi, 8)
    assert relative(frequency_response(lin, f).H, exact_response(lin.to_control(), f)) <= TOL


@pytest.mark.parametrize("name", NAMES)
def test_state_space_poles_hold_our_transfer_functions_poles(name):
    """Each entry's poles (the modes its input reaches and its output sees) are poles of the state space; where the
    state is minimal for an entry (every state both reached and seen) they are all of them."""
    lin, _, _ = cases()[name]
    system = lin.to_control()
    found = system.poles()
    scale = max(np.abs(found).max(), 1e-300)
    for o in lin.outputs:
        for i in lin.inputs:
            assert matched(found, transfer_function(lin, i, o).poles(), scale) <= 1e-9, (o, i)
    minimal = {"series rlc": ("i(L1)", "V1"), "ladder": ("v(C19)", "V1"), "parallelogram": ("theta_A", "F[0]")}
    if name in minimal:
        ours = transfer_function(lin, minimal[name][1], minimal[name][0]).poles()
        assert len(ours) == system.nstates and matched(ours, found, scale) <= 1e-9


def test_dc_gains_of_the_state_spaces_are_the_closed_forms():
    rlc, ladder, par = (cases()[k][0].to_control() for k in ("series rlc", "ladder", "parallelogram"))
    assert np.asarray(ct.dcgain(rlc)).ravel() == pytest.approx([0.0, 1.0], abs=TOL)  # i(L1), v(C1): C blocks DC
    assert np.asarray(ct.dcgain(ladder)).ravel() == pytest.approx([1.0, 0.0, 1.0], abs=TOL)
    mc, mp = PARALLELOGRAM["mc"], PARALLELOGRAM["mp"]
    # a sideways push F on the coupler: F L δθ = (mc + mp) g L θ δθ (the cranks' centres rise half as much)
    assert np.asarray(ct.dcgain(par)).ravel() == pytest.approx([1 / (G * (mc + mp)), 0.0], rel=TOL, abs=TOL)


def test_the_gliding_sleigh_state_space_is_kanes_with_the_closed_form_turning():
    lin = sleigh()
    system = lin.to_control()
    assert system.state_labels == ["x_j", "y_j", "theta_j", "x_j'", "theta_j'"]  # 3 coordinates, 2 speeds
    m, inertia, a, u = (SLEIGH[k] for k in ("m", "inertia", "a", "u"))
    rate = -m * a * u / (inertia + m * a**2)  # (I + m a²) ω̇ = −m a u ω + a P
    assert matched(system.poles(), [rate, 0, 0, 0, 0], abs(rate)) <= 1e-12
    f = decades(0.01, 100.0, 10)
    s = 2j * np.pi * f
    theirs = control_response(system, f)
    assert relative(theirs[0, 0], 1 / (m * s)) <= TOL  # a push along the edge: 1/(m s)
    assert relative(theirs[3, 1], a / ((inertia + m * a**2) * s + m * a * u)) <= TOL
    assert np.all(theirs[1:, 0] == 0) and np.all(theirs[0, 1] == 0)
    turning = transfer_function(lin, "P[1]", "theta_j'").to_control()  # the state space's A is singular
    assert float(ct.dcgain(turning)) == pytest.approx(1 / (m * u), rel=TOL)


# ---------------------------------------------------------------------------
# Transfer functions: TransferFunction.to_control()
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["msd", "series rlc", "loudspeaker", "parallelogram", "sleigh"])
def test_transfer_function_bode_response_and_poles_equal_ours_over_the_whole_band(name):
    lin, _, (lo, hi) = cases()[name]
    f = decades(lo, hi, 25)
    s = 2j * np.pi * f
    for o in lin.outputs:
        for i in lin.inputs:
            H = transfer_function(lin, i, o)
            system = H.to_control()
            assert isinstance(system, ct.TransferFunction)
            assert (system.input_labels, system.output_labels) == ([i], [o])
            assert relative(np.asarray(system(s)).ravel(), H(s)) <= TOL
            assert relative(np.asarray(ct.frequency_response(system, 2 * np.pi * f).complex).ravel(), H(s)) <= TOL
            ours = H.poles()
            assert len(system.poles()) == len(ours)
            assert matched(system.poles(), ours, max(np.abs(ours).max(initial=0.0), 1.0)) <= 1e-9


def test_loudspeaker_transfer_functions_have_the_closed_form_response_and_dc_gains():
    Re, Le, Bl, m, k, c = 6.0, 0.5e-3, 7.0, 0.02, 2000.0, 1.5
    lin = cases()["loudspeaker"][0]
    cone, current = (transfer_function(lin, "E", o).to_control() for o in ("x_cone", "i(Le)"))
    f = decades(1.0, 2e4, 20)
    s = 2j * np.pi * f
    mech = m * s**2 + c * s + k
    assert relative(np.asarray(cone(s)).ravel(), Bl / ((Re + Le * s) * mech + Bl**2 * s)) <= TOL
    assert relative(np.asarray(current(s)).ravel(), mech / ((Re + Le * s) * mech + Bl**2 * s)) <= TOL
    assert float(cone.dcgain()) == pytest.approx(Bl / (Re * k), rel=TOL)  # Bl i = k x, i = E / Re
    assert float(current.dcgain()) == pytest.approx(1 / Re, rel=TOL)


def test_an_impedance_becomes_a_system_from_the_current_to_the_voltage():
    R, L, C = 10.0, 7e-3, 2.2e-6
    Z = impedance(series_rlc(R, L, C), "V1")
    system = Z.to_control()
    assert (system.input_labels, system.output_labels) == (["i(V1)"], ["V1"])
    s = 2j * np.pi * decades(10.0, 1e5, 10)
    assert relative(np.asarray(system(s)).ravel(), R + L * s + 1 / (C * s)) <= TOL


def test_the_ladder_transfer_function_is_a_real_polynomial_ratio_of_degree_40():
    """Twenty sections: the expression comes from the poles and zeros, its coefficients real to rounding.  A ratio
    of degree-40 polynomials holds the response only to about 1e-7 (measured 3e-7 against ours); the state space
    holds it to 1e-12 (the tests above)."""
    lin = cases()["ladder"][0]
    H = transfer_function(lin, "V1", "v(C19)")
    system = H.to_control()
    assert np.isrealobj(system.num[0][0]) and np.isrealobj(system.den[0][0])
    assert len(system.poles()) == 40 and len(system.zeros()) == 0
    s = 2j * np.pi * decades(1e-3, 10.0, 10)
    assert relative(np.asarray(system(s)).ravel(), H(s)) <= 1e-5
    assert float(system.dcgain()) == pytest.approx(1.0, rel=1e-9)  # no current at DC: no drop along the ladder


def test_inputs_through_their_derivatives_have_a_transfer_function_but_no_state_space():
    m, k, c = 0.3, 40.0, 0.5
    model = lg.Model("isolator")
    model.add("prescribed_motion", "base", "b", position=0)
    model.add("mass", "m", "p", m=m)
    model.add("spring", "k", ("b", "p"), k=k)
    model.add("damper", "c", ("b", "p"), c=c)
    lin = linearize(model, inputs=["base"], outputs=["x_p"])
    with pytest.raises(lg.ModelError, match=r"time derivatives.*transfer_function\(lin, 'base', 'x_p'\)\.to_control"):
        lin.to_control()
    system = transfer_function(lin, "base", "x_p").to_control()
    s = 2j * np.pi * decades(0.1, 100.0, 10)
    assert relative(np.asarray(system(s)).ravel(), (c * s + k) / (m * s**2 + c * s + k)) <= TOL
    nodal = linearize(series_rlc(formulation="flux"), inputs=["V1"], outputs=["v(C1)"])
    with pytest.raises(lg.ModelError, match=r"integral.*to_control\(\) gives a control\.TransferFunction"):
        nodal.to_control()


# ---------------------------------------------------------------------------
# Frequency responses, refusals
# ---------------------------------------------------------------------------


def test_frequency_response_data_holds_our_values_at_omega():
    lin = cases()["loudspeaker"][0]
    f = decades(1.0, 2e4, 10)
    resp = frequency_response(lin, f)
    data = resp.to_control()
    assert isinstance(data, ct.FrequencyResponseData)
    assert data.input_labels == ["E"] and data.output_labels == lin.outputs
    assert np.array_equal(data.omega, 2 * np.pi * f)
    assert np.array_equal(np.asarray(data.frdata), resp.H)


def test_symbolic_systems_are_refused_naming_their_symbols():
    R, L, C = sp.symbols("R L C", positive=True)
    model = series_rlc(R, L, C)
    with pytest.raises(lg.ModelError, match=r"symbolically \(C, L, R without values\).*params="):
        linearize(model, inputs=["V1"], outputs=["i(L1)"]).to_control()
    with pytest.raises(lg.ModelError, match=r"symbolically \(C, L, R without values\).*params="):
        transfer_function(model, "V1", "i(L1)").to_control()
    partly = transfer_function(model, "V1", "i(L1)", params={"R": 10.0, "C": 2.2e-6})
    with pytest.raises(lg.ModelError, match=r"\(L without values\)"):
        partly.to_control()


def test_without_python_control_the_error_says_how_to_install_it(monkeypatch):
    lin = cases()["series rlc"][0]
    H = transfer_function(lin, "V1", "i(L1)")
    resp = frequency_response(lin, [10.0])
    monkeypatch.setitem(sys.modules, "control", None)  # import control raises ImportError
    for convert in (lin.to_control, H.to_control, resp.to_control):
        with pytest.raises(lg.ModelError, match=r"needs python-control.*pip install 'lagrangian\[control\]'"):
            convert()
