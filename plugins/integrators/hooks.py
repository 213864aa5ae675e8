"""The integrators plugin's registered integrators (:data:`INTEGRATORS`: the methods of this package, and the
stepping loops compiled to C) and its hook implementations, which register them and the benchmarks."""

from __future__ import annotations

from lagrangian import hookimpl
from lagrangian.compiled_loops import CompiledDormandPrince, CompiledFixedStep
from lagrangian.integrate import Integrator

from .adaptive import ScipyMethod
from .benchmarks import BENCHMARKS
from .explicit import RK4, StormerVerlet
from .implicit import GaussLegendre, Variational


_RK45 = ScipyMethod("RK45", 5, "scipy: explicit Runge–Kutta 5(4) (Dormand–Prince)")
_DOP853 = ScipyMethod("DOP853_scipy", 8, "scipy: explicit Runge–Kutta of order 8 (Dormand–Prince), stepped in Python",
                      method="DOP853")
_VERLET = StormerVerlet()
_VERLET_SEPARABLE = StormerVerlet(strict=True)  # what the loop in C runs

INTEGRATORS: tuple[Integrator, ...] = (
    ScipyMethod("RK23", 3, "scipy: explicit Runge–Kutta 3(2) (Bogacki–Shampine)"),
    _RK45,
    _DOP853,
    ScipyMethod("Radau", 5, "scipy: implicit Runge–Kutta Radau IIA of order 5, for stiff models", implicit=True, stiff=True),
    ScipyMethod("BDF", 5, "scipy: implicit backward differentiation formulas of order 1–5, for stiff models", implicit=True, stiff=True),
    ScipyMethod("LSODA", 12, "scipy: Adams/BDF switching on detected stiffness (ODEPACK)", implicit=True, stiff=True),
    RK4,
    _VERLET,
    GaussLegendre("implicit_midpoint", 1, "implicit midpoint rule (1-stage Gauss–Legendre), symplectic, A-stable, order 2", fixed=True),
    GaussLegendre("gauss_legendre", 2, "Gauss–Legendre collocation (stages=1, 2, 3; default 2), symplectic, A-stable, order 2·stages"),
    Variational(),
    # the stepping loop in C (lagrangian.codegen); the Python sibling runs when there is no C compiler
    CompiledDormandPrince(_RK45),
    # DOP853 runs its stepping loop in C where the model has compiled code (SciPy's steps, SciPy's accuracy, no
    # Python per step), as SciPy's DOP853 otherwise or while reporting progress; dop853_c says when it cannot
    CompiledDormandPrince(_DOP853, "DOP853", variant="dop853", quiet=True),
    CompiledDormandPrince(_DOP853, "dop853_c", variant="dop853"),
    CompiledFixedStep("rk4", RK4),
    CompiledFixedStep("verlet", _VERLET_SEPARABLE),
)


@hookimpl
def register_integrators(register):
    for integrator in INTEGRATORS:
        register(integrator)


@hookimpl
def register_benchmarks(register):
    for benchmark in BENCHMARKS:
        register(benchmark)
