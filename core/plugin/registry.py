"""The plugin manager and the typed registry of what plugins provide.

The registry is built on first use (:func:`default_registry`), never at
import: the pluggy manager gets the hook specifications, then every plugin of
the entry-point group ``lagrangian`` (built-ins included), then any plugins
passed in explicitly.  Each plugin's hooks are called one plugin at a time,
so anything it registers is recorded with its name, and a duplicate kind, an
invalid registration or an exception inside a hook becomes a
:class:`~lagrangian.errors.PluginError` naming the plugin.
"""

from __future__ import annotations

import functools
import importlib
import importlib.metadata as metadata
import keyword
import pickle
import sys
import types
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import pluggy

from . import hookspecs
from ..base.component import Component, Example, Parameter, pickling_by_name
from .contracts import Analogy, Benchmark, integrator_problem, resolve
from ..base.domain import Domain, Option
from ..errors import ModelError, PluginError, UnknownKindError, closest

__all__ = ["Registry", "PluginInfo", "default_registry", "ENTRY_POINT_GROUP"]

ENTRY_POINT_GROUP = "lagrangian"


@dataclass
class PluginInfo:
    """One loaded plugin: its name, the distribution that installed it, and what it provides.

    A plugin of the entry-point group names its distribution (``dist``): its name and version are read from the
    distribution's metadata when first asked for (parsing a distribution's metadata, its long description
    included, took half the time of building the registry).
    """

    name: str
    distribution: str | None = None
    version: str | None = None
    kinds: list[str] = field(default_factory=list)
    domains: list[str] = field(default_factory=list)
    integrators: list[str] = field(default_factory=list)
    benchmarks: list[str] = field(default_factory=list)
    dist: Any = field(default=None, repr=False, compare=False)

    def __getattribute__(self, attr: str) -> Any:
        if attr in ("distribution", "version"):
            value = object.__getattribute__(self, attr)
            dist = object.__getattribute__(self, "dist")
            if value is None and dist is not None:
                value = _dist_fields(dist)[0 if attr == "distribution" else 1]
                object.__setattr__(self, attr, value)
            return value
        return object.__getattribute__(self, attr)

    @property
    def installed(self) -> bool:
        """Whether a distribution installed the plugin (it came from the entry-point group)."""
        return self.dist is not None or object.__getattribute__(self, "distribution") is not None


def _dist_fields(dist: Any) -> tuple[str, str]:
    """A distribution's name and version, from its metadata."""
    meta = dist.metadata
    return meta["Name"], meta["Version"]


class Registry:
    """Component kinds, domains, integrators and benchmarks provided by plugins, keyed by name.

    ``Registry()`` loads the entry-point group ``lagrangian``; ``plugins``
    adds more at run time (``{"name": module_or_object}``), as tests do.

    >>> reg = Registry()
    >>> "mass" in reg.kinds and "capacitor" in reg.kinds
    True
    >>> reg.component_type("capacitr")
    Traceback (most recent call last):
    ...
    lagrangian.errors.UnknownKindError: unknown component kind 'capacitr'. Did you mean 'capacitor'? ...
    """

    def __init__(self, plugins: Mapping[str, Any] | None = None, *, entry_points: bool = True):
        self.pm = pluggy.PluginManager(hookspecs.PROJECT)
        self.pm.add_hookspecs(hookspecs)
        self.kinds: dict[str, type[Component]] = {}
        self.domains: dict[str, Domain] = {}
        self.analogies: dict[str, Any] = {}
        self.analogues: dict[tuple[str, str], Any] = {}
        self.integrators: dict[str, Any] = {}
        self.benchmarks: dict[str, Any] = {}
        self.info: dict[str, PluginInfo] = {}
        self._given = dict(plugins or {})  # the plugins passed in, as given (what pickling refers to)
        self._entry_points = entry_points
        if entry_points:
            for ep in sorted(metadata.entry_points(group=ENTRY_POINT_GROUP), key=lambda e: e.name):
                dist = getattr(ep, "dist", None)
                info = PluginInfo(ep.name, dist=dist)
                try:
                    module = ep.load()
                except Exception as exc:  # any import failure is the plugin's
                    raise PluginError(
                        ep.name,
                        f"failed to import {ep.value!r} (distribution {info.distribution}): "
                        f"{exc.__class__.__name__}: {exc}. Reinstall or uninstall that distribution.",
                    ) from exc
                self._register_plugin(ep.name, module, info)
        for name, plugin in (plugins or {}).items():
            self._register_plugin(name, plugin, PluginInfo(name))
        self.pm.check_pending()
        self._collect()

    def __reduce__(self):
        """Pickled by reference, never by content (a plugin manager holds modules and hook callers): the
        plugins of the entry-point group are loaded again by name where it is unpickled (the registry of
        installed plugins, :func:`default_registry`, when no others were given), and any plugin that was passed
        in is pickled by its module's import name when it is an importable module, as itself when it pickles,
        and by value under cloudpickle; else pickling refuses with a :class:`~lagrangian.errors.ModelError`
        naming it.  Unpickling checks that every plugin of the entry-point group it was built with is installed
        (a :class:`~lagrangian.errors.PluginError` naming the one that is not)."""
        loaded = sorted(n for n, info in self.info.items() if info.installed and n not in self._given)
        given = {name: _plugin_reference(name, plugin) for name, plugin in self._given.items()}
        return _unpickled_registry, (given, self._entry_points, loaded)

    def _register_plugin(self, name: str, plugin: Any, info: PluginInfo) -> None:
        if name in self.info:
            raise PluginError(name, f"a plugin of this name is already registered (from {self.info[name].distribution}).")
        try:
            self.pm.register(plugin, name=name)
        except Exception as exc:
            raise PluginError(name, f"cannot be registered: {exc}") from exc
        for caller in self.pm.get_hookcallers(plugin) or []:
            if not caller.has_spec():
                self.pm.unregister(plugin)
                known = ", ".join(n for n in dir(hookspecs) if n.startswith("register_"))
                raise PluginError(name, f"implements unknown hook {caller.name!r}.{closest(caller.name, known.split(', '))} Known hooks: {known}.")
        self.info[name] = info

    def _collect(self) -> None:
        hooks = (
            ("register_domains", self._add_domain),
            ("register_component_types", self._add_kind),
            ("register_analogies", self._add_analogy),
            ("register_analogues", self._add_analogue),
            ("register_integrators", self._add_integrator),
            ("register_benchmarks", self._add_benchmark),
        )
        for hook, accept in hooks:
            caller = getattr(self.pm.hook, hook)
            for impl in caller.get_hookimpls():  # registration order
                plugin = impl.plugin_name
                args = {"register": functools.partial(accept, plugin)}
                try:
                    impl.function(**{a: args[a] for a in impl.argnames})
                except PluginError:
                    raise
                except Exception as exc:
                    raise PluginError(plugin, f"hook {hook} raised {exc.__class__.__name__}: {exc}") from exc
        for kind, cls in self.kinds.items():
            missing = [d for d in (cls.domain, *(cls.terminal_domains or ())) if d not in self.domains]
            if missing:
                raise PluginError(
                    self._owner(kind),
                    f"component kind {kind!r} belongs to domain {missing[0]!r}, which no plugin registers "
                    f"(registered domains: {', '.join(sorted(self.domains)) or 'none'}).",
                )

    def _owner(self, kind: str) -> str:
        return next(p for p, info in self.info.items() if kind in info.kinds)

    def _add_kind(self, plugin: str, cls: Any) -> None:
        problem = _component_type_problem(cls)
        if problem:
            raise PluginError(plugin, f"registered an invalid component type {cls!r}: {problem}")
        if cls.kind in self.kinds:
            raise PluginError(
                plugin,
                f"component kind {cls.kind!r} is already provided by plugin {self._owner(cls.kind)!r}; "
                f"kinds must be unique: rename one or uninstall a plugin.",
            )
        self.kinds[cls.kind] = cls
        self.info[plugin].kinds.append(cls.kind)

    def _add_domain(self, plugin: str, domain: Any) -> None:
        if not isinstance(domain, Domain) or not isinstance(getattr(domain, "name", None), str):
            raise PluginError(plugin, f"registered {domain!r}, which is not an instance of lagrangian.Domain with a name.")
        if domain.name in self.domains:
            owner = next(p for p, info in self.info.items() if domain.name in info.domains)
            raise PluginError(plugin, f"domain {domain.name!r} is already provided by plugin {owner!r}.")
        for opt in domain.options.values():
            if not isinstance(opt, Option):
                raise PluginError(plugin, f"domain {domain.name!r}: options must be lagrangian.Option instances.")
        self.domains[domain.name] = domain
        self.info[plugin].domains.append(domain.name)

    def _add_analogy(self, plugin: str, analogy: Any) -> None:
        if not isinstance(analogy, Analogy):
            raise PluginError(plugin, f"registered {analogy!r}, which is not a lagrangian.analogy.Analogy.")
        if analogy.name in self.analogies:
            raise PluginError(plugin, f"analogy {analogy.name!r} is already registered.")
        self.analogies[analogy.name] = analogy

    def _add_analogue(self, plugin: str, kind: Any, analogy: Any = None, build: Any = None) -> None:
        if not isinstance(kind, str) or not isinstance(analogy, str) or not callable(build):
            raise PluginError(plugin, "register_analogues: call register(kind, analogy_name, build) with a callable build.")
        if (kind, analogy) in self.analogues:
            raise PluginError(plugin, f"the {analogy} analogue of {kind!r} is already declared by plugin {self.analogues[kind, analogy][0]!r}.")
        self.analogues[kind, analogy] = (plugin, build)

    def _add_integrator(self, plugin: str, integrator: Any) -> None:
        if isinstance(integrator, type):
            try:
                integrator = integrator()
            except Exception as exc:
                raise PluginError(plugin, f"registered the integrator class {integrator!r}, which cannot be instantiated "
                                          f"without arguments ({exc.__class__.__name__}: {exc}); register an instance.") from exc
        problem = integrator_problem(integrator)
        if problem:
            raise PluginError(plugin, f"registered an invalid integrator {integrator!r}: {problem}.")
        name = integrator.name
        if name in self.integrators:
            owner = next(p for p, info in self.info.items() if name in info.integrators)
            raise PluginError(
                plugin,
                f"integrator {name!r} is already provided by plugin {owner!r}; method names must be unique: "
                f"rename one or uninstall a plugin.",
            )
        self.integrators[name] = integrator
        self.info[plugin].integrators.append(name)

    def _add_benchmark(self, plugin: str, benchmark: Any) -> None:
        if not isinstance(benchmark, Benchmark) or not isinstance(benchmark.name, str) or not benchmark.name:
            raise PluginError(plugin, f"registered {benchmark!r}, which is not a lagrangian.bench.Benchmark with a name.")
        if benchmark.name in self.benchmarks:
            owner = next(p for p, info in self.info.items() if benchmark.name in info.benchmarks)
            raise PluginError(plugin, f"benchmark {benchmark.name!r} is already provided by plugin {owner!r}.")
        self.benchmarks[benchmark.name] = benchmark
        self.info[plugin].benchmarks.append(benchmark.name)

    def integrator(self, name: str) -> Any:
        """The integrator registered as ``name``; :class:`UnknownNameError` with a suggestion otherwise.

        >>> Registry().integrator("RK54")
        Traceback (most recent call last):
        ...
        lagrangian.errors.UnknownNameError: unknown integration method 'RK54'. Did you mean 'RK45'? ...
        """
        return resolve(name, self.integrators)

    def component_type(self, kind: str) -> type[Component]:
        """The class registered for ``kind``; :class:`UnknownKindError` with suggestions otherwise."""
        try:
            return self.kinds[kind]
        except KeyError:
            raise UnknownKindError(kind, self.kinds) from None

    def example(self, kind: str) -> Example:
        """Kind ``kind``'s :class:`~lagrangian.Example`: a small model using it, what the conformance suite builds
        (called when asked for, not at registration: an example may build SymPy expressions of time, which a
        numeric model never needs).  A :class:`~lagrangian.errors.PluginError` naming the plugin when ``example()``
        raises or gives something else.

        >>> Registry().example("capacitor").params
        {'C': 0.5}
        """
        cls = self.component_type(kind)
        example, problem = _example_problem(cls)
        if problem:
            raise PluginError(self._owner(kind), f"component kind {kind!r}: {problem}")
        return example

    def options(self) -> dict[str, tuple[str, Option]]:
        """Every model option any domain accepts, as ``{option: (domain, Option)}``."""
        return {name: (d.name, opt) for d in self.domains.values() for name, opt in d.options.items()}

    def plugins(self) -> list[PluginInfo]:
        """The loaded plugins, in load order."""
        return list(self.info.values())

    def describe(self) -> str:
        """A table of plugins and what each provides (what ``lagrangian plugins`` prints)."""
        lines = []
        for info in self.plugins():
            origin = f"{info.distribution} {info.version}" if info.distribution else "registered at run time"
            lines.append(f"{info.name}  ({origin})")
            if info.domains:
                lines.append(f"    domains: {', '.join(info.domains)}")
            if info.kinds or not (info.integrators or info.benchmarks):
                lines.append(f"    kinds:   {', '.join(info.kinds) or '(none)'}")
            if info.integrators:
                lines.append(f"    integrators: {', '.join(info.integrators)}")
            if info.benchmarks:
                lines.append(f"    benchmarks:  {', '.join(info.benchmarks)}")
        return "\n".join(lines)


def _component_type_problem(cls: Any) -> str | None:
    if not isinstance(cls, type) or not issubclass(cls, Component):
        return "it is not a subclass of lagrangian.Component"
    kind = getattr(cls, "kind", None)
    if not isinstance(kind, str) or not kind.isidentifier() or keyword.iskeyword(kind):
        return f"its kind {kind!r} is not a valid identifier"
    if not isinstance(getattr(cls, "domain", None), str):
        return "it declares no domain"
    if not isinstance(cls.terminals, tuple) or not all(isinstance(x, str) for x in cls.terminals):
        return "terminals must be a tuple of names"
    if not all(isinstance(p, Parameter) for p in cls.parameters.values()):
        return "every entry of parameters must be a lagrangian.Parameter"
    hidden = sorted(p for p in cls.parameters if hasattr(Component, p) or p.startswith("_"))
    if hidden:  # self.<name> would give Component's attribute (a method such as state or given), not the value
        return (f"its parameter {hidden[0]!r} is hidden by lagrangian.Component.{hidden[0]}, which every component "
                f"has: rename the parameter")
    if cls.terminal_domains is not None and (
        not isinstance(cls.terminal_domains, tuple) or len(cls.terminal_domains) != len(cls.terminals)
    ):
        return "terminal_domains must be a tuple with one domain per terminal"
    if cls.role not in (None, "across", "through"):
        return f"role must be None, 'across' or 'through', not {cls.role!r}"
    if cls.contribute is Component.contribute:
        return "it does not implement contribute(ctx)"
    if getattr(cls.example, "__func__", None) is Component.example.__func__:
        return "it does not implement example()"
    return None


def _example_problem(cls: type[Component]) -> tuple[Any, str | None]:
    """``(example, problem)`` of a registered kind: what its ``example()`` gives, or why it is not an example."""
    try:
        example = cls.example()
    except Exception as exc:
        return None, f"example() raised {exc.__class__.__name__}: {exc}"
    if not isinstance(example, Example):
        return None, "example() must return a lagrangian.Example"
    return example, None


class _ImportedPlugin:
    """A plugin module, pickled by its import name and imported again where it is unpickled."""

    def __init__(self, module: str):
        self.module = module


def _importable(module: types.ModuleType) -> bool:
    """Whether ``module`` is the one its name imports (not built at run time, nor replaced in ``sys.modules``)."""
    name = getattr(module, "__name__", None)
    return (isinstance(name, str) and sys.modules.get(name) is module and getattr(module, "__spec__", None) is not None
            and name != "__main__")


def _plugin_reference(name: str, plugin: Any) -> Any:
    """What a registry's pickle holds for the plugin passed in as ``name`` (see :meth:`Registry.__reduce__`)."""
    if isinstance(plugin, types.ModuleType) and _importable(plugin):
        return _ImportedPlugin(plugin.__name__)
    if not pickling_by_name():
        return plugin
    if not isinstance(plugin, types.ModuleType):
        try:
            pickle.dumps(plugin)
        except Exception as exc:
            raise ModelError(f"plugin {name!r}, passed in to Registry(plugins=...), does not pickle "
                             f"({exc.__class__.__name__}: {exc}): define it in an importable module, or pickle "
                             f"with cloudpickle, which pickles it by value.") from None
        return plugin
    raise ModelError(
        f"plugin {name!r}, passed in to Registry(plugins=...), is the module {plugin.__name__!r}, which cannot be "
        f"imported by that name (it was built at run time): a model or registry holding it pickles with "
        f"cloudpickle (by value), not with pickle. Put the plugin in an importable module, or install it under "
        f"the entry-point group {ENTRY_POINT_GROUP!r}."
    )


def _unpickled_registry(given: Mapping[str, Any], entry_points: bool, loaded: Iterable[str]) -> Registry:
    """A registry rebuilt where it is unpickled (see :meth:`Registry.__reduce__`)."""
    plugins = {}
    for name, plugin in given.items():
        if isinstance(plugin, _ImportedPlugin):
            try:
                plugin = importlib.import_module(plugin.module)
            except Exception as exc:
                raise PluginError(name, f"its module {plugin.module!r} cannot be imported here "
                                        f"({exc.__class__.__name__}: {exc}); make it importable where the model "
                                        f"is unpickled.") from None
        plugins[name] = plugin
    registry = default_registry() if entry_points and not plugins else Registry(plugins, entry_points=entry_points)
    missing = [n for n in loaded if n not in registry.info]
    if missing:
        raise PluginError(missing[0], f"the pickled model was built with this plugin of the entry-point group "
                                      f"{ENTRY_POINT_GROUP!r}, which is not installed here: install it.")
    return registry


@functools.cache
def default_registry() -> Registry:
    """The registry of installed plugins, built on first call and reused."""
    return Registry()
