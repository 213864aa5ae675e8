"""SPICE's source waveforms in numbers (:mod:`lagrangian.base.waveforms`): a netlist's ``SIN`` and ``PULSE`` sources
held as numbers, solved exactly without SymPy, and the same as the SymPy expressions they stand for.

References: each waveform's SymPy expression (``Piecewise`` of ``Mod`` for a pulse, as ngspice defines it) evaluated
by SymPy itself; closed forms of an RC circuit; the exact solution of the same model given the expression (the
exosystem SymPy expands) against the one given the waveform (the exosystem built from its terms).
"""

from __future__ import annotations

import pickle
import subprocess
import sys

import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

import lagrangian as lg
from lagrangian.base.waveforms import Pulse, Sine
from lagrangian.linear import simulate_exact
from lagrangian.netlist import read_netlist


def _decades(low, high):
    return st.floats(low, high).map(lambda x: float(f"{10 ** x:.3g}"))


sines = st.builds(Sine, offset=st.floats(-2, 2).map(lambda x: round(x, 2)), amplitude=_decades(-2, 1),
                  frequency=_decades(-1, 1), delay=st.sampled_from([0.0, 0.13, 0.5]),
                  damping=st.sampled_from([0.0, 0.7, 3.0]), phase=st.sampled_from([0.0, 30.0, -90.0]))
pulses = st.builds(Pulse, low=st.floats(-1, 1).map(lambda x: round(x, 2)), high=_decades(-1, 1),
                   delay=st.sampled_from([0.0, 0.05, 0.3]), rise=_decades(-3, -1), fall=_decades(-3, -1),
                   width=_decades(-2, -0.5), period=st.just(1.0), count=st.sampled_from([0.0, 2.0, 1.5]))


def _by_sympy(wave, times):
    fn = sp.lambdify(lg.t, wave.expr(), modules=["numpy"])
    return np.broadcast_to(np.asarray(fn(times), dtype=float), times.shape)


@settings(max_examples=40, deadline=None)
@given(wave=st.one_of(sines, pulses), seed=st.integers(0, 2**16))
def test_a_waveforms_values_are_its_expressions(wave, seed):
    times = np.sort(np.random.default_rng(seed).uniform(0, 3.0, 200))
    scale = 1 + abs(getattr(wave, "offset", 0.0)) + abs(getattr(wave, "amplitude", 0.0)) + abs(getattr(wave, "low", 0)) \
        + abs(getattr(wave, "high", 0))
    assert np.max(np.abs(wave(times) - _by_sympy(wave, times))) <= 1e-12 * scale


@settings(max_examples=40, deadline=None)
@given(wave=st.one_of(sines, pulses), seed=st.integers(0, 2**16))
def test_on_each_piece_the_terms_are_the_waveform(wave, seed):
    # Σ c τ^k e^{λτ} on every piece between switching times, against the values
    edges = [0.0, *wave.cuts(0.0, 3.0), 3.0]
    rng = np.random.default_rng(seed)
    for a, b in zip(edges[:-1], edges[1:]):
        times = np.sort(rng.uniform(a, b, 5))
        tau = times - a
        got = sum(c * tau**k * np.exp(lam * tau) for (k, lam), c in wave.terms(a, b).items())
        assert np.max(np.abs(got.imag)) <= 1e-12 * (1 + np.max(np.abs(got.real)))
        assert np.max(np.abs(got.real - wave(times))) <= 1e-11 * (1 + np.max(np.abs(wave(times))))


def test_a_pulses_switching_times_are_its_corners():
    p = Pulse(0.0, 5.0, 1e-3, 1e-4, 2e-4, 4e-4, 1e-3, count=2)
    assert p.cuts(0.0, 1.0) == pytest.approx([1e-3, 1.1e-3, 1.5e-3, 1.7e-3, 2e-3, 2.1e-3, 2.5e-3, 2.7e-3, 3e-3])


def test_a_waveform_is_read_by_sympy_as_its_expression_and_pickles_without_it():
    w = Sine(0.5, 2.0, 50.0, delay=0.01)
    assert sp.sympify(w) == w.expr() and (sp.Integer(3) * w).has(lg.t)
    back = pickle.loads(pickle.dumps(w))
    assert back == w and hash(back) == hash(w) and "_expr" not in back.__dict__


def _rc_netlist(source: str) -> str:
    return f"rc\nV1 in 0 {source}\nR1 in a 2.2k\nC1 a 0 4.7u\n.tran 0.1m 40m\n.end\n"


@pytest.mark.parametrize("source", ["SIN(0.3 1.7 60 2m 0 30)", "PULSE(0 5 1m 0.2m 0.3m 4m 10m)"])
def test_a_netlists_source_solved_in_numbers_is_its_expression_solved_by_sympy(source):
    # the netlist's model holds the waveform; a twin holds its SymPy expression: the exact solution of each (the
    # exosystem from the waveform's terms, and from SymPy's expansion of the expression) agree to rounding
    net = read_netlist(_rc_netlist(source))
    wave = net.model.component("V1").params.raw("E")
    assert isinstance(wave, (Sine, Pulse))
    twin = lg.Model("rc twin")
    twin.add("voltage_source", "V1", ("in", "0"), E=wave.expr())
    twin.add("resistor", "R1", ("in", "a"), R=2.2e3)
    twin.add("capacitor", "C1", ("a", "0"), C=4.7e-6)
    a = simulate_exact(net.model, 0.04, initial={"q_R1": 0.0}, points=401)
    b = simulate_exact(twin, 0.04, initial={"q_R1": 0.0}, points=401)
    scale = float(np.max(np.abs(b["q_R1"])))
    assert np.max(np.abs(a["q_R1"] - b["q_R1"])) <= 1e-10 * scale


def _fresh_cli(args: list[str], absent: tuple[str, ...]) -> None:
    """``lagrangian ARGS`` in a fresh process, which must succeed with none of the libraries ``absent`` loaded."""
    code = ("import sys\nfrom lagrangian.cli import main\n"
            f"status = main({args!r})\n"
            f"print(status, sorted(m for m in {absent!r} if m in sys.modules))\n")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert run.stdout.strip().splitlines()[-1] == "0 []", run.stdout + run.stderr


@pytest.mark.slow
def test_a_netlist_run_in_numbers_imports_neither_sympy_nor_scipy_and_is_the_closed_form(tmp_path):
    # a fresh process: the RC low-pass under VA sin(ωt) from rest, v(t) = VA/(1+(ωτ)²) (sin ωt − ωτ cos ωt + ωτ e^(−t/τ))
    deck, out = tmp_path / "rc.cir", tmp_path / "v.csv"
    deck.write_text("rc\nV1 in 0 SIN(0 1.7 60)\nR1 in a 2.2k\nC1 a 0 4.7u\n.tran 0.1m 40m\n.end\n")
    _fresh_cli(["simulate", str(deck), "--output", "v(a)", "--out", str(out)], ("sympy", "mpmath", "matplotlib", "scipy"))
    table = np.loadtxt(out, delimiter=",", skiprows=1)
    t, v = table[:, 0], table[:, 1]
    w, tau = 2 * np.pi * 60, 2.2e3 * 4.7e-6
    exact = 1.7 / (1 + (w * tau) ** 2) * (np.sin(w * t) - w * tau * np.cos(w * t) + w * tau * np.exp(-t / tau))
    assert np.max(np.abs(v - exact)) <= 1e-9 * 1.7


@pytest.mark.slow
def test_a_netlists_ac_response_in_numbers_imports_neither_sympy_nor_scipy_and_is_the_closed_form(tmp_path):
    # a fresh process: `lagrangian ac` of an RC low-pass whose source also has a SIN for transients writes
    # H(jω) = 1 / (1 + jωτ) in dB and degrees, with no SymPy, mpmath or SciPy loaded
    deck, out = tmp_path / "rc.cir", tmp_path / "h.csv"
    deck.write_text("rc\nV1 in 0 AC 1 SIN(0 1.7 60)\nR1 in a 2.2k\nC1 a 0 4.7u\n.ac dec 10 1 100k\n.end\n")
    _fresh_cli(["ac", str(deck), "--output", "v(a)", "--csv", str(out)], ("sympy", "mpmath", "scipy"))
    f, db, deg = np.loadtxt(out, delimiter=",", skiprows=1).T
    h = 1 / (1 + 2j * np.pi * f * 2.2e3 * 4.7e-6)
    assert f.size == 51
    np.testing.assert_allclose(db, 20 * np.log10(np.abs(h)), rtol=0, atol=1e-9)
    np.testing.assert_allclose(deg, np.degrees(np.angle(h)), rtol=0, atol=1e-9)
