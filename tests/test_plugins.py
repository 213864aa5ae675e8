"""The plugin machinery: entry points, run-time registration, validation, the CLI.

Plugins are registered through the entry-point group ``lagrangian`` (built-ins
and the separately installed ``lagrangian-cubic-spring`` alike) or passed to
``Registry(plugins={...})``.  Everything a plugin gets wrong is a
:class:`lagrangian.PluginError` naming that plugin.
"""

from __future__ import annotations

import importlib.metadata as metadata
import inspect
import os
import subprocess
import sys
import textwrap
import types
from dataclasses import dataclass, field
from pathlib import Path

import pytest
import sympy as sp

import lagrangian as lg
import lagrangian.hookspecs as hookspecs
from lagrangian.registry import ENTRY_POINT_GROUP

BUILTIN_KINDS = {
    "mechanics": ["mass", "spring", "damper", "coulomb_friction", "gravity", "force", "generalized_force", "constraint",
                  "velocity_constraint", "gear", "rack_and_pinion", "central_force", "prescribed_motion"],
    "circuits": ["inductor", "capacitor", "resistor", "voltage_source", "current_source", "gyrator"],
}


# ---------------------------------------------------------------------------
# helpers: component types and plugin objects built at run time


def make_plugin(name: str = "plugin", *, kinds=(), domains=(), component_hook=None, domain_hook=None):
    """A module-like plugin object whose hooks register ``kinds`` and ``domains``."""
    plugin = types.ModuleType(name)
    if component_hook is None and kinds:

        def component_hook(register):
            for cls in kinds:
                register(cls)

    if domain_hook is None and domains:

        def domain_hook(register):
            for d in domains:
                register(d)

    if component_hook is not None:
        plugin.register_component_types = lg.hookimpl(component_hook)
    if domain_hook is not None:
        plugin.register_domains = lg.hookimpl(domain_hook)
    return plugin


def component_type(kind: str = "widget", *, domain: str = "mechanical", doc: str = "A test component.", **attrs):
    """A valid one-terminal Component subclass (T = ½ a ẋ²), with ``attrs`` overriding anything."""

    def contribute(self, ctx):
        v = ctx.view.velocity(self.nodes[0])
        return lg.Contribution(T=self.a * lg.dot(v, v) / 2)

    def example(cls):
        return lg.Example("p", {"a": 1}, context=[("spring", "k", ("ground", "p"), {"k": 1})])

    namespace = {
        "__doc__": doc,
        "kind": kind,
        "domain": domain,
        "terminals": ("node",),
        "parameters": {"a": lg.Parameter("inertia-like coefficient", unit="kg")},
        "contribute": contribute,
        "example": classmethod(example),
    }
    namespace.update(attrs)
    return type(f"T_{kind}".replace("-", "_") if isinstance(kind, str) else "T_kind", (lg.Component,), namespace)


# ---------------------------------------------------------------------------
# (a) the third-party plugin through its real entry point; built-ins likewise


@pytest.fixture(scope="module")
def registry() -> lg.Registry:
    return lg.Registry()


def test_cubic_spring_is_loaded_from_its_distribution(registry):
    info = {p.name: p for p in registry.plugins()}
    assert "cubic_spring" in info
    assert info["cubic_spring"].distribution == "lagrangian-cubic-spring"
    assert info["cubic_spring"].version == metadata.version("lagrangian-cubic-spring")
    assert info["cubic_spring"].kinds == ["cubic_spring", "cubic_capacitor"]
    assert info["cubic_spring"].domains == []  # it reuses the mechanical domain
    cls = registry.component_type("cubic_spring")
    assert cls.__module__ == "lagrangian_cubic_spring"
    # the module lives in the example distribution, not in lagrangian
    assert Path(inspect.getfile(cls)).parent.name == "cubic-spring"


def test_cubic_spring_entry_point_is_real():
    eps = metadata.entry_points(group=ENTRY_POINT_GROUP, name="cubic_spring")
    assert len(eps) == 1
    (ep,) = eps
    assert ep.value == "lagrangian_cubic_spring"
    assert ep.dist.name == "lagrangian-cubic-spring"


def test_builtins_come_from_the_lagrangian_distribution_via_entry_points(registry):
    eps = {ep.name: ep for ep in metadata.entry_points(group=ENTRY_POINT_GROUP)}
    info = {p.name: p for p in registry.plugins()}
    for name, kinds in BUILTIN_KINDS.items():
        assert eps[name].dist.name == "lagrangian"
        assert eps[name].value == f"lagrangian.plugins.{name}"
        assert info[name].distribution == "lagrangian"
        assert info[name].version == lg.__version__
        assert info[name].kinds == kinds
        assert registry.pm.get_plugin(name) is sys.modules[f"lagrangian.plugins.{name}"]
    assert info["mechanics"].domains == ["mechanical"]
    assert info["circuits"].domains == ["electrical"]
    # the plugins are exactly what the entry points provide, nothing registered behind their back
    assert set(info) == set(eps)
    assert set(registry.kinds) == {k for p in info.values() for k in p.kinds}


def test_without_entry_points_nothing_is_registered():
    reg = lg.Registry(entry_points=False)
    assert reg.kinds == {} and reg.domains == {} and reg.plugins() == []
    with pytest.raises(lg.UnknownKindError, match="'mass'"):
        lg.Model(registry=reg).add("mass", "M", "p", m=1)


def test_a_model_uses_the_cubic_spring():
    m = lg.Model("duffing")
    m.add("mass", "M", "p", m=1)
    m.add("cubic_spring", "s", ("ground", "p"), k=2, k3=sp.Rational(1, 2))
    (x,) = m.eq.sym.q
    assert sp.expand(m.eq.V - (x**2 + x**4 / 8)) == 0
    (eq,) = m.equations
    x_t = m.coordinates[0].function
    assert sp.expand(eq.rhs + 2 * x_t + x_t**3 / 2) == 0
    res = m.simulate(1, initial={"x_p": 1.0}, velocity={"x_p": 0.0}, points=11)
    assert res.energy_drift() < 1e-7
    assert res["x_p"][-1] < 1.0


def test_describe_lists_plugins_and_origins(registry):
    text = registry.describe()
    assert "cubic_spring  (lagrangian-cubic-spring 0.1.0)" in text
    assert "mechanics  (lagrangian 0.1.0)" in text
    assert "circuits  (lagrangian 0.1.0)" in text
    assert ("kinds:   mass, spring, damper, coulomb_friction, gravity, force, generalized_force, constraint, "
            "velocity_constraint, gear, "
            "rack_and_pinion, central_force, prescribed_motion") in text
    assert "domains: electrical" in text


def test_default_registry_is_cached_and_complete():
    assert lg.default_registry() is lg.default_registry()
    assert {"cubic_spring", "mass", "inductor"} <= set(lg.default_registry().kinds)


# ---------------------------------------------------------------------------
# (b) run-time registration


Widget = component_type("widget", doc="Widget: a test inertia, T = ½ a ẋ².")


def test_runtime_plugin_adds_a_kind():
    reg = lg.Registry(plugins={"extra": make_plugin("extra", kinds=[Widget])})
    assert reg.kinds["widget"] is Widget
    info = {p.name: p for p in reg.plugins()}
    assert info["extra"].distribution is None and info["extra"].kinds == ["widget"]
    assert "extra  (registered at run time)" in reg.describe()

    m = lg.Model("w", registry=reg)
    m.add("widget", "W", "p", a=3)
    m.add("spring", "k", ("ground", "p"), k=12)
    assert m.registry is reg
    assert m.mass_matrix == sp.Matrix([[3]])
    res = m.simulate(1, initial={"x_p": 1.0}, velocity={"x_p": 0.0}, points=5)
    assert res["x_p"][-1] == pytest.approx(float(sp.cos(2)), rel=1e-6)

    # the default registry (and so a default model) knows nothing of it
    assert "widget" not in lg.default_registry().kinds
    with pytest.raises(lg.UnknownKindError, match="'widget'"):
        lg.Model().add("widget", "W", "p", a=3)


def test_runtime_plugin_with_only_builtins_selected():
    import lagrangian.plugins.mechanics as mechanics

    reg = lg.Registry(plugins={"mech": mechanics, "extra": make_plugin(kinds=[Widget])}, entry_points=False)
    assert set(reg.kinds) == set(BUILTIN_KINDS["mechanics"]) | {"widget"}
    assert set(reg.options()) == {"dim", "dynamics"}
    m = lg.Model(registry=reg, dim=2)
    m.add("widget", "W", "p", a=1)
    assert m.coordinate_names == ["x_p", "y_p"]
    with pytest.raises(lg.UnknownNameError, match="'formulation'"):
        lg.Model(registry=reg, formulation="flux")
    with pytest.raises(lg.UnknownKindError, match="'inductor'"):
        m.add("inductor", "L", ("n", "ground"), L=1)


@dataclass
class ToyView(lg.DomainView):
    gain: int = 1
    values: dict = field(default_factory=dict)


class ToyDomain(lg.Domain):
    """One coordinate ``u_<node>`` per node."""

    name = "toy"
    options = {"gain": lg.Option(1, "a test option", choices=(1, 2))}

    def build(self, network, options):
        view = ToyView(gain=options["gain"])
        for node in network.nodes:
            c = lg.Coordinate.named(f"u_{node}", f"toy value of {node}")
            view.coordinates.append(c)
            view.values[node] = c.function
        return view


class ToyInertia(lg.Component):
    """Toy inertia: T = ½ gain · m · u̇²."""

    kind = "toy_inertia"
    domain = "toy"
    terminals = ("node",)
    parameters = {"m": lg.Parameter("toy inertia")}

    def contribute(self, ctx):
        u = ctx.view.values[self.nodes[0]]
        return lg.Contribution(T=ctx.view.gain * self.m * u.diff(lg.t) ** 2 / 2, V=u**2 / 2)

    @classmethod
    def example(cls):
        return lg.Example("n", {"m": 1})


def test_runtime_plugin_adds_a_domain_and_its_option():
    plugin = make_plugin("toy", kinds=[ToyInertia], domains=[ToyDomain()])
    reg = lg.Registry(plugins={"toy": plugin})
    assert reg.options()["gain"][0] == "toy"
    assert {p.name: p.domains for p in reg.plugins()}["toy"] == ["toy"]
    m = lg.Model(registry=reg, gain=2)
    m.add("toy_inertia", "T1", "n", m=3)
    assert m.coordinate_names == ["u_n"]
    assert m.mass_matrix == sp.Matrix([[6]])
    assert m.options["gain"] == 2
    with pytest.raises(lg.ModelError, match="'gain'.*must be one of 1, 2"):
        lg.Model(registry=reg, gain=3)
    with pytest.raises(lg.UnknownNameError, match="'gain'"):
        lg.Model(gain=2)  # the installed plugins have no such option


def test_hook_implementation_may_take_fewer_arguments():
    calls = []

    def hook():  # accepts no ``register`` at all
        calls.append(1)

    reg = lg.Registry(plugins={"lazy": make_plugin(component_hook=hook)})
    assert calls == [1]
    assert {p.name: p.kinds for p in reg.plugins()}["lazy"] == []


# ---------------------------------------------------------------------------
# (c) duplicate kinds and domains


def test_duplicate_kind_between_two_runtime_plugins_names_both():
    other = component_type("widget", doc="Another widget.")
    with pytest.raises(lg.PluginError, match="'widget'") as info:
        lg.Registry(plugins={"first": make_plugin(kinds=[Widget]), "second": make_plugin(kinds=[other])})
    message = str(info.value)
    assert "'first'" in message and "'second'" in message
    assert "already provided by plugin" in message and "unique" in message
    assert info.value.plugin in {"first", "second"}


def test_duplicate_of_a_builtin_kind_names_both_plugins():
    fake_spring = component_type("spring", doc="A second spring.")
    with pytest.raises(lg.PluginError, match="'spring'") as info:
        lg.Registry(plugins={"zzz": make_plugin(kinds=[fake_spring])})
    assert "'zzz'" in str(info.value) and "'mechanics'" in str(info.value)


def test_duplicate_of_the_third_party_kind_names_both_plugins():
    fake = component_type("cubic_spring", doc="A second cubic spring.")
    with pytest.raises(lg.PluginError, match="'cubic_spring'") as info:
        lg.Registry(plugins={"copycat": make_plugin(kinds=[fake])})
    assert "'copycat'" in str(info.value)
    assert str(info.value).count("cubic_spring") >= 2  # the kind and the plugin that owns it


class Mechanical2(ToyDomain):
    name = "mechanical"


def test_duplicate_domain_names_both_plugins():
    with pytest.raises(lg.PluginError, match="domain 'mechanical' is already provided by plugin") as info:
        lg.Registry(plugins={"dom": make_plugin(domains=[Mechanical2()])})
    assert "'dom'" in str(info.value) and "'mechanics'" in str(info.value)
    assert info.value.plugin == "dom"


@pytest.mark.parametrize(
    "plugin",
    [make_plugin(kinds=[component_type("mass", doc="A second mass.")]), make_plugin(domains=[Mechanical2()])],
    ids=["kind", "domain"],
)
def test_duplicate_blames_the_newcomer(plugin):
    with pytest.raises(lg.PluginError) as info:
        lg.Registry(plugins={"zzz": plugin})
    assert info.value.plugin == "zzz"
    assert str(info.value).startswith("plugin 'zzz'")


def test_plugin_name_clashing_with_an_installed_one():
    with pytest.raises(lg.PluginError, match="plugin 'mechanics': a plugin of this name is already registered") as info:
        lg.Registry(plugins={"mechanics": make_plugin(kinds=[Widget])})
    assert "lagrangian" in str(info.value)


# ---------------------------------------------------------------------------
# (d) a plugin whose import fails


def write_distribution(root: Path, dist: str, entry_name: str, module: str, source: str) -> None:
    info = root / f"{dist}-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {dist}\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(f"[{ENTRY_POINT_GROUP}]\n{entry_name} = {module}\n")
    (root / f"{module}.py").write_text(textwrap.dedent(source))


BROKEN_SOURCE = """
    raise ImportError("needs the 'unobtainium' package")
"""


@pytest.fixture
def broken_dist(tmp_path, monkeypatch):
    write_distribution(tmp_path, "broken_plugin", "broken", "broken_plugin_mod", BROKEN_SOURCE)
    monkeypatch.syspath_prepend(str(tmp_path))
    yield tmp_path
    sys.modules.pop("broken_plugin_mod", None)


def test_plugin_failing_to_import_is_a_plugin_error(broken_dist):
    with pytest.raises(lg.PluginError, match="plugin 'broken'") as info:
        lg.Registry()
    err = info.value
    assert err.plugin == "broken"
    message = str(err)
    assert "broken_plugin_mod" in message
    assert "broken_plugin" in message  # the distribution
    assert "ImportError" in message and "unobtainium" in message
    assert "Reinstall or uninstall" in message
    assert isinstance(err.__cause__, ImportError)
    # without entry points the broken distribution is never touched
    assert lg.Registry(entry_points=False).plugins() == []


@pytest.mark.slow
def test_cli_reports_a_broken_plugin(broken_dist):
    paths = [str(broken_dist), *filter(None, os.environ.get("PYTHONPATH", "").split(os.pathsep))]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(paths))
    proc = subprocess.run(
        [sys.executable, "-m", "lagrangian", "plugins"], capture_output=True, text=True, env=env, timeout=120
    )
    assert proc.returncode == 1
    assert proc.stderr.startswith("lagrangian: error: plugin 'broken'")
    assert "Traceback" not in proc.stderr
    assert proc.stdout == ""


def test_working_plugin_from_a_fake_distribution(tmp_path, monkeypatch):
    source = """
        import lagrangian as lg

        class Bumper(lg.Component):
            '''Bumper: a soft stop, V = ½ k x².'''
            kind = "bumper"
            domain = "mechanical"
            terminals = ("node",)
            parameters = {"k": lg.Parameter("stiffness")}

            def contribute(self, ctx):
                x = ctx.view.position(self.nodes[0])
                return lg.Contribution(V=self.k * lg.dot(x, x) / 2)

            @classmethod
            def example(cls):
                return lg.Example("p", {"k": 1}, context=[("mass", "m", "p", {"m": 1})])

        @lg.hookimpl
        def register_component_types(register):
            register(Bumper)
    """
    write_distribution(tmp_path, "good_plugin", "good", "good_plugin_mod", source)
    monkeypatch.syspath_prepend(str(tmp_path))
    try:
        reg = lg.Registry()
        info = {p.name: p for p in reg.plugins()}
        assert info["good"].distribution == "good_plugin" and info["good"].version == "0.1"
        assert info["good"].kinds == ["bumper"]
        m = lg.Model(registry=reg)
        m.add("mass", "M", "p", m=1)
        m.add("bumper", "B", "p", k=4)
        assert m.eq.V == 2 * m.eq.sym.q[0] ** 2
    finally:
        sys.modules.pop("good_plugin_mod", None)


# ---------------------------------------------------------------------------
# (e) invalid registrations


def _boom(register):
    raise RuntimeError("boom")


def _registers(*things):
    def hook(register):
        for thing in things:
            register(thing)

    return hook


class NoExample(lg.Component):
    """Has contribute, lacks example()."""

    kind = "no_example"
    domain = "mechanical"

    def contribute(self, ctx):
        return lg.Contribution()


class NoContribute(lg.Component):
    """Has example(), lacks contribute()."""

    kind = "no_contribute"
    domain = "mechanical"

    @classmethod
    def example(cls):
        return lg.Example(("ground", "p"))


INVALID = [
    ("not-a-class", dict(component_hook=_registers(42)), r"not a subclass of lagrangian\.Component"),
    ("not-a-component", dict(component_hook=_registers(dict)), r"not a subclass of lagrangian\.Component"),
    ("instance-not-class", dict(component_hook=_registers(Widget("w", ("p",), {"a": 1}))), r"not a subclass"),
    ("kind-with-dash", dict(kinds=[component_type("my-kind")]), r"kind 'my-kind' is not a valid identifier"),
    ("kind-keyword", dict(kinds=[component_type("class")]), r"kind 'class' is not a valid identifier"),
    ("kind-empty", dict(kinds=[component_type("")]), r"kind '' is not a valid identifier"),
    ("kind-not-str", dict(kinds=[component_type(7)]), r"kind 7 is not a valid identifier"),
    ("no-domain", dict(kinds=[component_type("nodomain", domain=None)]), r"declares no domain"),
    ("terminals-list", dict(kinds=[component_type("tlist", terminals=["a", "b"])]), r"terminals must be a tuple"),
    ("parameter-not-parameter", dict(kinds=[component_type("pbad", parameters={"a": 1.0})]), r"lagrangian\.Parameter"),
    ("bad-role", dict(kinds=[component_type("rbad", role="sideways")]), r"role must be None, 'across' or 'through'"),
    ("parameter-hidden", dict(kinds=[component_type("phid", parameters={"state": lg.Parameter("a state")})]),
     r"parameter 'state' is hidden by lagrangian\.Component\.state.*rename the parameter"),
    ("parameter-private", dict(kinds=[component_type("ppriv", parameters={"_k": lg.Parameter("hidden")})]),
     r"parameter '_k' is hidden"),
    ("no-example", dict(kinds=[NoExample]), r"does not implement example\(\)"),
    ("no-contribute", dict(kinds=[NoContribute]), r"does not implement contribute"),
    ("unknown-domain", dict(kinds=[component_type("heater", domain="thermal")]),
     r"kind 'heater' belongs to domain 'thermal', which no plugin registers.*registered domains: electrical, mechanical"),
    ("hook-raises", dict(component_hook=_boom), r"hook register_component_types raised RuntimeError: boom"),
    ("domain-hook-raises", dict(domain_hook=_boom), r"hook register_domains raised RuntimeError: boom"),
    ("domain-not-domain", dict(domain_hook=_registers("thermal")), r"not an instance of lagrangian\.Domain"),
    ("domain-class-not-instance", dict(domain_hook=_registers(ToyDomain)), r"not an instance of lagrangian\.Domain"),
    ("domain-option-not-option", dict(domain_hook=_registers(type("D", (ToyDomain,), {"name": "d2", "options": {"x": 1}})())),
     r"options must be lagrangian\.Option"),
]


@pytest.mark.parametrize(("spec", "pattern"), [c[1:] for c in INVALID], ids=[c[0] for c in INVALID])
def test_invalid_registration_is_a_plugin_error_naming_the_plugin(spec, pattern):
    with pytest.raises(lg.PluginError, match=pattern) as info:
        lg.Registry(plugins={"bad": make_plugin("bad", **spec)})
    assert info.value.plugin == "bad"
    assert str(info.value).startswith("plugin 'bad': ")


@pytest.mark.parametrize(("example", "pattern"), [
    (classmethod(lambda cls: 1 / 0), r"component kind 'ex': example\(\) raised ZeroDivisionError"),
    (classmethod(lambda cls: {"nodes": "p"}), r"component kind 'ex': example\(\) must return a lagrangian\.Example"),
])
def test_an_example_that_fails_is_a_plugin_error_naming_the_plugin_when_it_is_asked_for(example, pattern):
    # registering reads no example (it may build SymPy expressions a numeric model never needs); asking for it does
    reg = lg.Registry(plugins={"bad": make_plugin("bad", kinds=[component_type("ex", example=example)])})
    assert "ex" in reg.kinds
    with pytest.raises(lg.PluginError, match=pattern) as info:
        reg.example("ex")
    assert info.value.plugin == "bad"


def test_hookimpl_with_an_unknown_argument_is_a_plugin_error():
    def hook(register, extra):
        pass

    with pytest.raises(lg.PluginError, match="plugin 'bad': cannot be registered") as info:
        lg.Registry(plugins={"bad": make_plugin(component_hook=hook)})
    assert info.value.plugin == "bad"
    assert "extra" in str(info.value)


def test_misspelled_hook_is_a_plugin_error():
    plugin = types.ModuleType("typo")
    plugin.register_component_type = lg.hookimpl(lambda register: None)  # missing "s"
    with pytest.raises(lg.PluginError, match="plugin 'typo'.*register_component_type"):
        lg.Registry(plugins={"typo": plugin})


def test_a_valid_neighbour_of_the_invalid_registrations_passes():
    """The helper builds valid types: the failures above come from what each case changes."""
    reg = lg.Registry(plugins={"bad": make_plugin("bad", kinds=[component_type("fine")])})
    assert "fine" in reg.kinds


# ---------------------------------------------------------------------------
# (f) nothing is built at import


def run_python(code: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True)


@pytest.mark.slow
def test_plugin_manager_is_not_built_at_import():
    code = (
        "import sys, lagrangian, lagrangian.registry as r\n"
        "print(r.default_registry.cache_info().currsize)\n"
        "print(sorted(m for m in sys.modules if m.startswith('lagrangian.plugins.') or m == 'lagrangian_cubic_spring'))\n"
        "m = lagrangian.Model('lazy')\n"
        "print(r.default_registry.cache_info().currsize)\n"
        "m.add('mass', 'M', 'p', m=1)\n"
        "print(r.default_registry.cache_info().currsize)\n"
    )
    out = run_python(code).stdout.splitlines()
    assert out == ["0", "[]", "1", "1"]


def test_importing_the_package_and_deriving_a_model_load_no_scipy():
    """SciPy's modules are imported by what uses them: a command that only builds a model, lists plugins or prints
    the version does not pay for them (0.4 s of CPU at every start)."""
    code = (
        "import sys, lagrangian\n"
        "def scipy(): return sorted(m for m in sys.modules if m.split('.')[0] == 'scipy')\n"
        "print(scipy())\n"
        "m = lagrangian.Model('osc')\n"
        "m.add('mass', 'M', 'p', m=0.3)\n"
        "m.add('spring', 'k', ('ground', 'p'), k=40)\n"
        "print(m.eq.names, scipy())\n"
    )
    assert run_python(code).stdout.splitlines() == ["[]", "['x_p'] []"]
    cli = run_python("import sys, lagrangian.cli\nprint(sorted(m for m in sys.modules if m.split('.')[0] == 'scipy'))")
    assert cli.stdout.splitlines() == ["[]"]  # the command line, every command's module imported: none either


def test_a_compiled_run_and_a_scene_of_it_load_neither_scipy_linalg_nor_numpys_namespace():
    """A run in compiled code, and a scene whose outputs are its coordinates, need neither ``scipy.linalg`` nor
    ``scipy.special`` nor the namespace lambdify builds from NumPy (``numpy.ma``, ``numpy.f2py``, ...): 0.3 s of CPU
    in a fresh process, more than the run itself."""
    code = (
        "import sys, lagrangian\n"
        "from lagrangian.scene import Scene\n"
        "def heavy(): return sorted(m for m in ('scipy.linalg', 'scipy.special', 'numpy.ma') if m in sys.modules)\n"
        "m = lagrangian.Model('kepler', dim=2)\n"
        "m.add('mass', 'planet', 'p', m=0.3)\n"
        "m.add('central_force', 'sun', ('ground', 'p'), k=4.7)\n"
        "start = dict(initial={'x_p': 1.0, 'y_p': 0.0}, velocity={'x_p': 0.0, 'y_p': 3.1})\n"
        "print(m.simulate(2.0, **start).method, heavy())\n"
        "print(len(Scene(m, ['x_p'], 2.0, **start).run()['x_p']), heavy())\n"
    )
    assert run_python(code).stdout.splitlines() == ["DOP853 []", "1001 []"]


# ---------------------------------------------------------------------------
# (g) the command line


def run_cli(*args: str, exe: list[str] | None = None) -> subprocess.CompletedProcess:
    cmd = (exe or [sys.executable, "-m", "lagrangian"]) + list(args)
    return subprocess.run(cmd, capture_output=True, text=True, timeout=120)


@pytest.mark.slow
def test_cli_plugins():
    proc = run_cli("plugins")
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    headers = [line for line in lines if not line.startswith(" ")]
    assert {
        "circuits  (lagrangian 0.1.0)",
        "cubic_spring  (lagrangian-cubic-spring 0.1.0)",
        "mechanics  (lagrangian 0.1.0)",
    } <= set(headers)
    assert headers == sorted(headers)  # entry points load in name order
    text = proc.stdout
    for kinds in BUILTIN_KINDS.values():
        assert f"kinds:   {', '.join(kinds)}" in text
    assert "kinds:   cubic_spring" in text


@pytest.mark.slow
def test_cli_kinds_lists_parameters():
    proc = run_cli("kinds")
    assert proc.returncode == 0, proc.stderr
    text = proc.stdout
    for kind in lg.default_registry().kinds:
        assert any(line.startswith(f"{kind}  [") for line in text.splitlines()), kind
    assert "cubic_spring  [mechanical; terminals: a, b]  Hardening spring" in text
    assert "    k3 [N/m³]: cubic stiffness" in text
    assert "    rest_length = 0 [m]: rest length" in text
    assert "    L [H]: inductance" in text
    assert "gravity  [mechanical; terminals: none]" in text
    assert "    g = 9.81 [m/s²]: gravitational acceleration" in text


@pytest.mark.slow
def test_console_script_matches_module():
    script = Path(sys.executable).with_name("lagrangian")
    if not script.exists():
        pytest.skip("console script not installed next to the interpreter")
    proc = run_cli("plugins", exe=[str(script)])
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout == run_cli("plugins").stdout


@pytest.mark.slow
def test_cli_needs_a_command():
    proc = run_cli()
    assert proc.returncode == 2
    assert "plugins" in proc.stderr and "kinds" in proc.stderr


def test_cli_main_in_process(capsys):
    from lagrangian.cli import main

    assert main(["kinds"]) == 0
    out = capsys.readouterr().out
    assert "voltage_source  [electrical; terminals: a, b]" in out
    assert "    E [V]: source voltage" in out


# ---------------------------------------------------------------------------
# (h) meta-test: every hookspec is documented and implemented by a built-in plugin


def hookspec_functions():
    marker = f"{hookspecs.PROJECT}_spec"
    return {name: obj for name, obj in vars(hookspecs).items() if callable(obj) and hasattr(obj, marker)}


def test_hookspecs_are_the_documented_interface():
    specs = hookspec_functions()
    assert set(specs) == {
        "register_component_types", "register_domains", "register_analogies", "register_analogues",
        "register_integrators", "register_benchmarks",
    }
    assert set(specs) <= set(hookspecs.__all__)
    for name, func in specs.items():
        doc = inspect.getdoc(func)
        assert doc and len(doc) > 40, f"hookspec {name} needs a docstring"
        assert "register" in inspect.signature(func).parameters


@pytest.mark.parametrize("hook", sorted(hookspec_functions()))
def test_every_hookspec_is_implemented_by_a_builtin_plugin(registry, hook):
    builtin = {p.name for p in registry.plugins() if p.distribution == "lagrangian"}
    assert set(BUILTIN_KINDS) <= builtin
    implementers = {impl.plugin_name for impl in getattr(registry.pm.hook, hook).get_hookimpls()}
    assert implementers & builtin, f"no built-in plugin implements {hook}"


def test_builtin_plugins_implement_only_known_hooks(registry):
    specs = set(hookspec_functions())
    for name in BUILTIN_KINDS:
        module = registry.pm.get_plugin(name)
        impls = {n for n, obj in vars(module).items() if hasattr(obj, f"{hookspecs.PROJECT}_impl")}
        assert impls and impls <= specs, (name, impls)


def test_the_readme_registers_a_plugin_in_process(tmp_path, monkeypatch):
    """The README's in-process registration of its plugin, whose kind is its own (the installed distribution's
    is ``cubic_spring``)."""
    import re
    import sys
    from pathlib import Path

    readme = (Path(__file__).resolve().parents[1] / "README.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", readme, re.S)
    plugin = next(b for b in blocks if "class CubicSpring" in b)
    (tmp_path / "my_plugin.py").write_text(plugin)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, "my_plugin", raising=False)
    usage = next(b for b in blocks if "lg.Registry(plugins=" in b)
    namespace: dict = {}
    exec(usage, namespace)
    m = namespace["m"]
    assert [c.kind for c in m.components.values()] == ["mass", "hardening_spring"]
    assert str(m.potential_energy.subs(m.coordinates[0].function, 2)) == "4.00000000000000"  # ½·1·2² + ¼·0.5·2⁴
