"""Hook specifications: the whole interface between lagrangian and its plugins.

A plugin is a module (or any object) with functions marked ``@hookimpl``,
registered through the entry-point group ``lagrangian``::

    # pyproject.toml of a plugin distribution
    [project.entry-points.lagrangian]
    cubic_spring = "lagrangian_cubic_spring"

    # lagrangian_cubic_spring.py
    from lagrangian import hookimpl

    @hookimpl
    def register_component_types(register):
        register(CubicSpring)

Built-in plugins (``lagrangian.plugins.mechanics``, ``lagrangian.plugins.circuits``)
are registered through the same group, by the same code path.  Hooks use the
registry-callback style: each receives a ``register`` function and calls it
once per thing it provides.  An implementation may accept fewer arguments
than its specification, so specifications can grow without breaking plugins.
"""

from __future__ import annotations

from collections.abc import Callable
import pluggy

from ..base.component import Component
from .contracts import AnalogueBuilder, Analogy, Benchmark, Integrator
from ..base.domain import Domain

__all__ = [
    "hookspec",
    "hookimpl",
    "register_component_types",
    "register_domains",
    "register_analogies",
    "register_analogues",
    "register_integrators",
    "register_benchmarks",
]

PROJECT = "lagrangian"
hookspec = pluggy.HookspecMarker(PROJECT)
hookimpl = pluggy.HookimplMarker(PROJECT)


@hookspec
def register_component_types(register: Callable[[type[Component]], None]) -> None:
    """Register component types.

    Call ``register(cls)`` once for each subclass of
    :class:`lagrangian.Component` the plugin provides.  The class's ``kind``
    is the name users pass to :meth:`lagrangian.Model.add`; it must be unique
    across all installed plugins (a duplicate is an error naming both
    plugins).  The class must declare its ``domain`` (a registered domain
    such as ``"mechanical"`` or ``"electrical"``), its ``terminals``, its
    ``parameters`` and an ``example()``; it contributes energy through
    ``contribute(ctx)`` and never writes equations of motion.
    """


@hookspec
def register_domains(register: Callable[[Domain], None]) -> None:
    """Register physical domains.

    Call ``register(domain)`` with an instance of a
    :class:`lagrangian.Domain` subclass.  A domain turns the part of the
    component graph that belongs to it into generalized coordinates (node
    positions, loop charges, node flux linkages, ...) and gives components a
    *view* through which they read those coordinates.  A domain's ``options``
    become keyword options of :class:`lagrangian.Model` (for example
    ``Model(formulation="flux")``).
    """


@hookspec
def register_analogies(register: Callable[[Analogy], None]) -> None:
    """Register analogies between two domains.

    Call ``register(Analogy(name, source, target, dual=..., options=..., inverse_options=...))``.
    An analogy maps a model of its ``source`` domain onto one of its
    ``target`` domain and back: ``dual=False`` keeps the graph (nodes map
    to nodes: the force–current analogy), ``dual=True`` maps through the
    planar dual graph (nodes become meshes: the force–voltage analogy).
    ``options`` are model options of the target model, ``inverse_options``
    those of the source model when mapping back.
    """


@hookspec
def register_analogues(register: Callable[[str, str, AnalogueBuilder], None]) -> None:
    """Declare the analogues of component kinds.

    Call ``register(kind, analogy, build)`` for each component kind and
    analogy name the plugin can map.  ``build(component, ports)`` returns a
    list of :class:`lagrangian.analogy.Element` for the other domain;
    ``ports.branch(i)`` gives the target nodes ``(a, b)`` standing for the
    component's branch ``i`` (for a dual analogy, the two meshes on either
    side of it, oriented so that the target branch's rate equals the source
    branch's rate), ``ports.ground`` the target reference node.  An element
    that stands for branch ``i`` says so (``Element(..., branch=i)``): its
    branch quantity (charge, flux linkage, position difference) is then
    identified with the source branch's, which is how coordinates map.
    """


@hookspec
def register_integrators(register: Callable[[Integrator], None]) -> None:
    """Register integration methods.

    Call ``register(integrator)`` once per method, with an instance (or a
    class, instantiated without arguments) following the contract of
    :class:`lagrangian.integrate.Integrator`: a ``name`` (what users pass
    as ``Model.simulate(method=...)``; unique across plugins, ``"auto"``
    and ``"exact"`` are reserved), a ``kind`` (``"adaptive"``: it receives
    ``rtol``, ``atol``, ``max_step``; ``"fixed-step"``: it receives
    ``step``), the flags ``symplectic``, ``implicit``, ``stiff`` and
    ``first_order``, an ``order``, ``options`` it accepts, an optional
    ``check(problem)`` that refuses models it cannot integrate, and
    ``solve(problem, t_span, y0, t_eval, **options)`` returning a
    :class:`lagrangian.integrate.Solution`.  Fixed-step methods usually
    subclass :class:`lagrangian.integrate.FixedStepIntegrator` and provide
    one step.  A duplicate name is an error naming both plugins.
    """


@hookspec
def register_benchmarks(register: Callable[[Benchmark], None]) -> None:
    """Register benchmark problems for work–precision measurements.

    Call ``register(benchmark)`` with a :class:`lagrangian.bench.Benchmark`:
    a name (what ``lagrangian bench NAME`` takes; unique across plugins), a
    function building the model, the initial state and time span, and the
    truth to measure errors against — an exact solution, or a reference
    run (a method and tight tolerances).  ``requires`` lists component
    kinds it needs; it is listed as unavailable when they are not installed.
    """
