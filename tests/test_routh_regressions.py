"""Routhian reduction on models that reduce nothing: a bead on a hoop spun at a prescribed rate.

The hoop turns about its vertical diameter at ω, given as a function of time (no coordinate); the bead's angle θ
from the bottom is the one coordinate, and nothing is ignorable. By hand (mass m, radius R):

    L = ½ m R² (θ̇² + ω² sin² θ) + m g R cos θ,    m R² θ̈ = m R² ω² sin θ cos θ − m g R sin θ,

so the bead rests relative to the hoop at θ = 0, at θ = π, and at cos θ = g/(R ω²) when R ω² > g.  Linearized,
θ = θ₀ + s gives s̈ + κ s = 0 with κ = g cos θ₀ / R − ω² cos 2θ₀: the bottom is stable below ω² = g/R and
unstable above, the top always unstable, and the off-axis rests stable wherever they exist (κ = ω² sin² θ₀).
"""

from __future__ import annotations

import math

import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

import lagrangian as lg
from lagrangian import routh
from lagrangian.identity import equal

G = 9.81
m_, R_, g_, w_ = sp.symbols("m R g omega", positive=True)


def decades(lo, hi):
    """Floats drawn log-uniformly between lo and hi, rounded to 3 significant digits as users type them."""
    return st.floats(math.log10(lo), math.log10(hi)).map(lambda e: float(f"{10 ** e:.3g}"))


def spun_hoop(m, R, omega, g=G) -> lg.Model:
    """A bead of mass m on a massless hoop of radius R driven round its vertical diameter at omega;
    theta_slide is the bead's angle from the bottom."""
    model = lg.Model("bead on a spun hoop", dim=3)
    model.add("link", "hoop", "hoop")
    model.add("revolute", "spin", ("ground", "hoop"), axis=(0, 0, 1), angle=omega * lg.t)
    model.add("link", "arm", "arm", points={"bead": (0, 0, -R)})
    model.add("revolute", "slide", ("hoop", "arm"), axis=(1, 0, 0))
    model.add("mass", "bead", "arm.bead", m=m)
    model.add("gravity", "g", g=g)
    return model


def closed_form(R, omega, g=G) -> dict[float, str]:
    """{θ₀ of every rest relative to the hoop in (−π, π]: its verdict}, from κ = g cos θ₀ / R − ω² cos 2θ₀."""
    rests = {0.0: "stable" if omega**2 < g / R else "unstable", math.pi: "unstable"}
    if R * omega**2 > g:
        off = math.acos(g / (R * omega**2))
        rests |= {off: "stable", -off: "stable"}
    return rests


@pytest.fixture(scope="module")
def symbolic():
    return routh.reduce(spun_hoop(m_, R_, w_, g_), ignorable=[])


@pytest.fixture(scope="module")
def symbolic_rests(symbolic):
    """The symbolic twin's steady motions, solved once (SymPy takes most of a second)."""
    return symbolic.steady_motions()


def test_reducing_nothing_keeps_the_model_with_its_routhian_minus_l(symbolic):
    """Regression: ``ignorable=[]`` on a one-coordinate rheonomic model raised a bare IndexError from SymPy."""
    red = symbolic
    assert red.ignored == [] and red.momenta == {} and red.rates == {}
    assert red.coordinate_names == ["theta_slide"]
    th = lg.coordinate("theta_slide")
    L = m_ * R_**2 * (th.diff(lg.t) ** 2 + w_**2 * sp.sin(th) ** 2) / 2 + m_ * g_ * R_ * sp.cos(th)
    assert equal(red.routhian, -L)
    assert equal(red.effective_potential, -m_ * R_**2 * w_**2 * sp.sin(th) ** 2 / 2 - m_ * g_ * R_ * sp.cos(th))


def test_the_prescribed_spin_is_no_coordinate_to_reduce():
    """The hoop's angle is a function of time, not a coordinate: naming it is refused by name."""
    with pytest.raises(lg.UnknownNameError, match="theta_spin"):
        routh.reduce(spun_hoop(0.3, 0.2, 8.0), ignorable=["theta_spin"])


@pytest.mark.slow
def test_symbolic_rests_are_the_closed_forms_top_included(symbolic_rests):
    """Solved symbolically: θ = 0, θ = π (which SymPy's half-angle substitution alone misses) and the pair
    cos θ = g/(R ω²)."""
    found = [sm.coordinates["theta_slide"] for sm in symbolic_rests]
    assert len(found) == 4
    assert any(equal(x, 0) for x in found) and any(equal(x, sp.pi) for x in found)
    off = [x for x in found if not (equal(x, 0) or equal(x, sp.pi))]
    assert all(equal(sp.cos(x), g_ / (R_ * w_**2)) for x in off)
    assert equal(off[0], -off[1])


def verdicts(red) -> dict[float, str]:
    """{θ₀: verdict} of the numeric model's steady motions found on the default search range (the whole turn)."""
    return {float(sm.coordinates["theta_slide"]): sm.stability().verdict for sm in red.steady_motions()}


def assert_closed_form(found: dict[float, str], R, omega):
    expected = closed_form(R, omega)
    assert sorted(found) == pytest.approx(sorted(expected), abs=1e-9)
    for theta, verdict in found.items():
        assert verdict == expected[min(expected, key=lambda x: abs(x - theta))]


@pytest.mark.parametrize("omega", [4.0, 9.0])  # R ω² below and above g
def test_rests_of_a_bead_on_a_spun_hoop_with_their_stability(omega):
    """Regression: the equilibria of the reduced model (nothing eliminated) with their verdicts, the top at π
    found on the default search range."""
    R = 0.2
    red = routh.reduce(spun_hoop(0.3, R, omega), ignorable=[])
    assert_closed_form(verdicts(red), R, omega)


@pytest.mark.slow
@settings(max_examples=8)
@given(m=decades(1e-2, 1e2), R=decades(1e-2, 1e1), ratio=st.one_of(decades(0.1, 0.8), decades(1.25, 10.0)))
def test_rests_and_verdicts_of_numbers_and_symbols_match_the_closed_form(symbolic, symbolic_rests, m, R, ratio):
    """R ω² = ratio · g, away from the bifurcation at ratio 1: the rests found numerically (default search, the
    whole turn) and the symbolic ones at the same values are the closed form's, with its verdicts."""
    omega = math.sqrt(ratio * G / R)
    assert_closed_form(verdicts(routh.reduce(spun_hoop(m, R, omega), ignorable=[])), R, omega)
    values = {"m": m, "R": R, "omega": omega, "g": G}
    subs = {m_: m, R_: R, w_: omega, g_: G}
    found = {}
    for sm in symbolic_rests:
        theta = sp.sympify(sm.coordinates["theta_slide"]).xreplace(subs)
        if theta.is_real:  # the off-axis pair exists only above ratio 1
            found[float(theta)] = sm.stability(values).verdict
    assert_closed_form(found, R, omega)
