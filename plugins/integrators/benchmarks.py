"""The benchmark problems of ``lagrangian bench`` (:data:`BENCHMARKS`): a harmonic oscillator, a Kepler orbit (with
its :class:`InverseSquare` attraction and the exact :func:`kepler_orbit`), a Duffing oscillator, a stiff RLC ladder
and the long-time energy of an oscillator."""

from __future__ import annotations

import functools
import math
import types

import numpy as np

from lagrangian import Component, Contribution, Example, Parameter, dot, hookimpl
from lagrangian.bench import Benchmark
from lagrangian.base import deferred as _deferred

sp = _deferred.module("sympy", globals())


class InverseSquare(Component):
    """Inverse-square attraction between two nodes: V = −k / |r_b − r_a| (a fixed sun's gravity, Coulomb).

    Registered only in the registry of the ``kepler`` benchmark.
    """

    kind = "inverse_square"
    domain = "mechanical"
    parameters = {"k": Parameter("strength (G m₁ m₂)", unit="N m²")}

    def contribute(self, ctx) -> Contribution:
        d = ctx.view.position(self.nodes[1]) - ctx.view.position(self.nodes[0])
        return Contribution(V=-self.k / sp.sqrt(dot(d, d)))

    @classmethod
    def example(cls) -> Example:
        return Example(("ground", "p"), {"k": 1}, context=[("mass", "m", "p", {"m": 1})], options={"dim": 2})


@functools.cache
def _kepler_registry():
    import lagrangian as lg

    plugin = types.ModuleType("lagrangian_kepler_benchmark")
    plugin.register_component_types = hookimpl(lambda register: register(InverseSquare))
    return lg.Registry(plugins={"kepler_benchmark": plugin})


def _oscillator():
    import lagrangian as lg

    m = lg.Model("harmonic oscillator")
    m.add("mass", "m", "p", m=1)
    m.add("spring", "k", ("ground", "p"), k=1)
    return m


def _kepler():
    import lagrangian as lg

    m = lg.Model("Kepler orbit", dim=2, registry=_kepler_registry())
    m.add("mass", "m", "planet", m=1)
    m.add("inverse_square", "sun", ("ground", "planet"), k=1)
    return m


KEPLER_E = 0.5


def kepler_orbit(times: np.ndarray, e: float = KEPLER_E) -> dict[str, np.ndarray]:
    """The exact orbit ``x, y`` for ``μ = a = 1`` from pericenter ``(1 − e, 0)`` at ``t = 0`` (Kepler's equation by Newton).

    >>> xy = kepler_orbit(np.array([0.0, 2 * np.pi]))
    >>> np.allclose(xy["x_planet"], 0.5) and np.allclose(xy["y_planet"], 0.0)
    True
    """
    M = np.asarray(times, dtype=float)  # mean anomaly, n = 1
    E = M + e * np.sin(M)
    for _ in range(50):
        dE = (E - e * np.sin(E) - M) / (1 - e * np.cos(E))
        E = E - dE
        if np.max(np.abs(dE)) < 1e-15:
            break
    return {"x_planet": np.cos(E) - e, "y_planet": math.sqrt(1 - e * e) * np.sin(E)}


def _duffing():
    import lagrangian as lg

    m = lg.Model("Duffing oscillator")
    m.add("mass", "m", "p", m=1)
    m.add("cubic_spring", "s", ("ground", "p"), k=1, k3=1)
    return m


def _rlc_ladder():
    """Three RLC sections driven by a sine; the middle inductance is tiny, so one mode decays ~10⁴ times faster."""
    import lagrangian as lg

    m = lg.Model("stiff RLC ladder", formulation="charge")
    m.add("voltage_source", "V1", ("n1", "0"), E=sp.sin(2 * lg.t))
    m.add("resistor", "R1", ("n1", "n2"), R=1.0)
    m.add("inductor", "L1", ("n2", "n3"), L=1.0)
    m.add("capacitor", "C1", ("n3", "0"), C=1.0)
    m.add("resistor", "R2", ("n3", "n4"), R=1.0)
    m.add("inductor", "L2", ("n4", "n5"), L=1e-4)
    m.add("capacitor", "C2", ("n5", "0"), C=1.0)
    m.add("resistor", "R3", ("n5", "n6"), R=0.5)
    m.add("inductor", "L3", ("n6", "n7"), L=2.0)
    m.add("capacitor", "C3", ("n7", "0"), C=0.5)
    return m


TWO_PI = 2 * math.pi
_FIXED = ("rk4", "verlet", "implicit_midpoint", "gauss_legendre", "variational")
_METHODS = ("RK45", "DOP853", "Radau", "BDF", "LSODA", *_FIXED)

BENCHMARKS = (
    Benchmark(
        "oscillator",
        "harmonic oscillator m = k = 1 over 10 periods, x(0) = 1; exact x = cos t",
        _oscillator, t_end=10 * TWO_PI, initial={"x_p": 1.0}, velocity={"x_p": 0.0}, points=81,
        exact=lambda times: {"x_p": np.cos(times)},
        steps=tuple(TWO_PI / k for k in (8, 16, 32, 64, 128, 256, 512)), methods=_METHODS,
    ),
    Benchmark(
        "kepler",
        f"Kepler orbit, e = {KEPLER_E}, μ = a = 1, 5 revolutions from pericenter; exact from Kepler's equation",
        _kepler, t_end=5 * TWO_PI, initial={"x_planet": 1 - KEPLER_E, "y_planet": 0.0},
        velocity={"x_planet": 0.0, "y_planet": math.sqrt((1 + KEPLER_E) / (1 - KEPLER_E))}, points=321,
        exact=kepler_orbit,
        steps=tuple(TWO_PI / k for k in (64, 128, 256, 512, 1024, 2048)), methods=_METHODS,
    ),
    Benchmark(
        "duffing",
        "Duffing oscillator x'' = −x − x³ from x = 1 over 20 time units; reference DOP853 at rtol 1e-13",
        _duffing, t_end=20.0, initial={"x_p": 1.0}, velocity={"x_p": 0.0}, points=81,
        steps=tuple(1 / k for k in (4, 8, 16, 32, 64, 128, 256)), requires=("cubic_spring",), methods=_METHODS,
    ),
    Benchmark(
        "rlc_ladder",
        "stiff RLC ladder (three sections, one with L = 1e-4: a decay rate 1e4 beside modes of order 1), sine "
        "drive, 10 time units; reference: the exact solution",
        _rlc_ladder, t_end=10.0, initial={}, points=51,
        reference={"method": "exact"},
        tolerances=(1e-3, 1e-5, 1e-7, 1e-9),
        steps=tuple(10 / k for k in (50, 100, 200, 400, 1000, 2000, 4000, 40000)),
        methods=("RK45", "DOP853", "Radau", "BDF", "LSODA", "rk4", "implicit_midpoint", "gauss_legendre", "variational"),
    ),
    Benchmark(
        "energy",
        "long-time energy: harmonic oscillator over 1000 periods, error = largest relative energy error; fixed-step "
        "methods advance by powers of their one-step map (fast_linear)",
        _oscillator, t_end=1000 * TWO_PI, initial={"x_p": 1.0}, velocity={"x_p": 0.0}, points=2001,
        measure="energy", tolerances=(1e-4, 1e-6, 1e-8),
        steps=tuple(TWO_PI / k for k in (8, 16, 32, 64, 128)),
        options={name: {"fast_linear": True} for name in _FIXED},
        methods=("RK45", "DOP853", *_FIXED),
    ),
)
