"""Model files (lagrangian.base.modelfile): a model saved and loaded is the same model, and a hostile file is refused.

A round trip is checked against the original model itself: the loaded model's mass matrix and forcing minus the
original's are identically zero (lagrangian.identity.is_zero), and a simulation of each, same method and points,
gives the very same arrays.  Hostile files (truncated, unknown keys, huge numbers, code in expressions, deep
nesting, a huge string) are each a ModelFileError naming the place, and nothing in them runs.
"""

from __future__ import annotations

import importlib.metadata as metadata
import importlib.util
import json
import math
import pathlib
import re
import tempfile
import warnings

import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

import lagrangian as lg
from lagrangian import models
from lagrangian.base import modelfile
from lagrangian.identity import is_zero

EXAMPLES = pathlib.Path(__file__).resolve().parent.parent / "examples"


def round_trip(model: lg.Model, path: pathlib.Path) -> lg.Model:
    model.save(path)
    return lg.load(path)


def same_equations(a: lg.Model, b: lg.Model) -> None:
    assert b.name == a.name and b.options == a.options
    assert b.coordinate_names == a.coordinate_names
    assert b.parameter_values == a.parameter_values
    for got, want in ((b.mass_matrix, a.mass_matrix), (b.forcing, a.forcing)):
        assert got.shape == want.shape
        assert all(is_zero(e) for e in got - want)


def same_runs(a: lg.Model, b: lg.Model, t_end: float = 0.5, **kwargs) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lg.InitialConditionWarning)
        ra, rb = (m.simulate(t_end, points=21, **kwargs) for m in (a, b))
    assert np.array_equal(ra.t, rb.t)
    for name in a.coordinate_names:
        assert np.array_equal(ra[name], rb[name]), name
        assert np.array_equal(ra.velocity(name), rb.velocity(name)), name


def example(name: str):
    spec = importlib.util.spec_from_file_location(f"example_{name}", EXAMPLES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


# --- round trips ------------------------------------------------------------------------------------------------


@pytest.mark.slow
@pytest.mark.parametrize("build, initial", [
    (models.spherical_pendulum, {"theta_tilt": 0.4}),
    (models.double_pendulum, {"theta_j1": -1.0, "theta_j2": -0.5}),
    (models.heavy_top, {"theta_nutation": 0.3}),
    (lambda: models.loudspeaker(E=sp.sin(200 * lg.t)), {}),
    (lambda: models.rlc_ladder(10, E=1), {}),
], ids=["spherical_pendulum", "double_pendulum", "heavy_top", "loudspeaker", "rlc_ladder10"])
def test_canonical_models_round_trip(tmp_path, build, initial):
    original = build()
    loaded = round_trip(original, tmp_path / "m.json")
    same_equations(original, loaded)
    same_runs(original, loaded, initial=initial, method="RK45")


@pytest.mark.slow
def test_whipple_bicycle_round_trips(tmp_path):
    """The bicycle's equations are large: the loaded model's components equal the original's, and its numeric
    right-hand side equals the original's at a random state."""
    original = models.whipple_bicycle()
    loaded = round_trip(original, tmp_path / "bicycle.json")
    assert loaded.coordinate_names == original.coordinate_names
    for name, c in original.components.items():
        assert loaded.components[name].params == c.params, name
    na, nb = original.numeric(), loaded.numeric()
    y = np.random.default_rng(7).normal(size=2 * na.n) * 0.1
    assert np.array_equal(na.rhs(0.3, y), nb.rhs(0.3, y))


def test_small_model_round_trips_exactly(tmp_path):
    m = lg.Model("mass-spring-damper")
    m.add("mass", "m", "cart", m=1.0)
    m.add("spring", "k", ("ground", "cart"), k=4.0)
    m.add("damper", "c", ("ground", "cart"), c=0.4)
    m.add("force", "F", "cart", F=sp.sin(1.5 * lg.t))
    loaded = round_trip(m, tmp_path / "msd.json")
    same_equations(m, loaded)
    same_runs(m, loaded, initial={"x_cart": 0.1}, method="RK45", compiled=False)


@pytest.mark.parametrize("name, builder", [
    ("demo", "mechanism"), ("demo", "circuit"), ("dc_motor", "motor"), ("isolator_transmissibility", "isolator"),
    ("coupled_tanks_modes", "tanks"), ("kepler", "central"), ("four_bar", "four_bar"),
])
def test_example_models_round_trip(tmp_path, name, builder):
    module = example(name)
    args = {"isolator": (0.3,), "tanks": ("flux",)}.get(builder, ())
    original = getattr(module, builder)(*args)
    loaded = round_trip(original, tmp_path / f"{builder}.json")
    assert [(c.kind, c.name, c.nodes) for c in loaded.components.values()] == \
           [(c.kind, c.name, c.nodes) for c in original.components.values()]
    for cname, c in original.components.items():
        assert loaded.components[cname].params == c.params, cname


@pytest.mark.parametrize("deck", ["filter.cir", "ladder.cir"])
def test_netlist_pulses_round_trip_and_run_alike(tmp_path, deck):
    """A PULSE or damped SIN source is a Piecewise expression of t (with Mod for the period): written as text,
    read back as the same expression, and the loaded model runs bit for bit as the original."""
    from lagrangian.circuits.netlist import read_netlist_file

    original = read_netlist_file(EXAMPLES / deck).model
    assert original.components["V1"].params["E"].has(sp.Piecewise)
    loaded = round_trip(original, tmp_path / "deck.json")
    assert loaded.components["V1"].params["E"] == original.components["V1"].params["E"]
    same_equations(original, loaded)
    a, b = original.simulate(2e-3, points=41), loaded.simulate(2e-3, points=41)
    assert all(np.array_equal(a[n], b[n]) for n in a.names)


@pytest.mark.slow
@pytest.mark.parametrize("name, builder", [("demo", "mechanism"), ("demo", "circuit"), ("dc_motor", "motor")])
def test_example_models_simulate_alike(tmp_path, name, builder):
    original = getattr(example(name), builder)()
    loaded = round_trip(original, tmp_path / "m.json")
    same_equations(original, loaded)
    same_runs(original, loaded, method="RK45")


def test_symbols_expressions_of_time_and_state(tmp_path):
    k = sp.Symbol("k", positive=True)
    w = sp.Symbol("omega")
    m = lg.Model("symbolic")
    m.add("mass", "m", "p", m=sp.Rational(3, 10))
    m.add("spring", "k", ("ground", "p"), k=k)
    m.add("force", "F", "p", F=0.30000000000000004 * sp.cos(w * lg.t) * sp.exp(-lg.t / 7)
          - 0.2 * lg.rate("x_p") * sp.Abs(lg.rate("x_p")) - sp.E * lg.coordinate("x_p") ** 3 + sp.pi / 3)
    path = tmp_path / "symbolic.json"
    loaded = round_trip(m, path)
    doc = json.loads(path.read_text())
    assert doc["symbols"] == {"k": {"positive": True}, "omega": {}}
    assert doc["state"] == {"coordinate__x_p": {"coordinate": "x_p"}, "rate__x_p": {"rate": "x_p"}}
    assert doc["components"][0]["params"] == {"m": "3/10"}
    assert loaded.components["F"].F == m.components["F"].F  # structurally the same SymPy expression
    assert loaded.components["k"].k == k
    same_equations(m, loaded)
    assert loaded.parameters == m.parameters == [k, w]
    same_runs(m, loaded, initial={"x_p": 0.1}, params={"k": 4.0, "omega": 1.5}, method="RK45", compiled=False)


@pytest.mark.slow  # (pint's first import)
def test_units_are_written_in_si_and_read_from_text(tmp_path):
    m = lg.Model("units")
    m.add("mass", "m", "p", m="300 g")
    m.add("spring", "k", ("ground", "p"), k="0.04 kN/m")
    path = tmp_path / "units.json"
    loaded = round_trip(m, path)
    params = [c["params"] for c in json.loads(path.read_text())["components"]]
    assert params == [{"m": float(m.components["m"].m)}, {"k": float(m.components["k"].k)}]
    same_equations(m, loaded)
    # a file written by hand may give units: converted on loading, as Model.add converts them
    doc = json.loads(path.read_text())
    doc["components"][0]["params"]["m"] = "300 g"
    path.write_text(json.dumps(doc))
    assert lg.load(path).components["m"].m == m.components["m"].m


def test_cubic_spring_plugin_round_trips(tmp_path):
    m = lg.Model("duffing")
    m.add("mass", "m1", "p", m=1)
    m.add("cubic_spring", "s", ("ground", "p"), k=1, k3=0.5)
    path = tmp_path / "duffing.json"
    loaded = round_trip(m, path)
    plugins = {p["name"]: p for p in json.loads(path.read_text())["plugins"]}
    assert plugins["cubic_spring"]["distribution"] == "lagrangian-cubic-spring"
    assert plugins["cubic_spring"]["kinds"] == ["cubic_spring"]
    same_equations(m, loaded)
    same_runs(m, loaded, initial={"x_p": 0.5}, method="RK45", compiled=False)
    # without the plugin the kind is refused by name, with the plugin the file names for it
    with pytest.raises(lg.ModelFileError, match=r"/components/1/kind: unknown component kind 'cubic_spring'.*"
                                                r"pip install lagrangian-cubic-spring") as info:
        lg.Model.load(path, registry=_registry_without("cubic_spring"))
    assert info.value.pointer == "/components/1/kind"


def _registry_without(plugin: str) -> lg.Registry:
    eps = {ep.name: ep.load() for ep in metadata.entry_points(group="lagrangian") if ep.name != plugin}
    return lg.Registry(eps, entry_points=False)


def test_declared_nodes_keep_their_order(tmp_path):
    m = lg.Model("order")
    m.node("b")
    m.add("mass", "ma", "a", m=1)
    m.add("mass", "mb", "b", m=2)
    m.add("spring", "k", ("a", "b"), k=3)
    loaded = round_trip(m, tmp_path / "order.json")
    assert loaded.nodes == m.nodes and loaded.coordinate_names == m.coordinate_names


def test_vectors_tensors_mappings_flags_and_names(tmp_path):
    m = lg.Model("spinning", dim=3)
    m.add("body", "b", "b", m=2, inertia=[[3, 0, 1], [0, 4, 0], [1, 0, 5]], com=(0, 0, sp.Rational(1, 4)),
          points={"tip": (0.1, 0.2, -0.3)})
    m.add("spherical", "j", ("ground", "b"), sequence="zxz")
    m.add("gravity", "g")
    loaded = round_trip(m, tmp_path / "spinning.json")
    for name, c in m.components.items():
        assert loaded.components[name].params == c.params


@settings(max_examples=25, deadline=None)
@given(st.lists(st.floats(min_value=-12, max_value=12), min_size=3, max_size=3),
       st.lists(st.integers(min_value=1, max_value=10**12), min_size=1, max_size=1))
def test_values_over_decades_round_trip_bit_for_bit(exponents, integers):
    m = lg.Model("decades")
    mass, stiffness, damping = (10.0**e * (1 + 1e-3 * i) for i, e in enumerate(exponents))
    m.add("mass", "m", "p", m=mass)
    m.add("spring", "k", ("ground", "p"), k=stiffness)
    m.add("damper", "c", ("ground", "p"), c=damping)
    m.add("force", "F", "p", F=integers[0] * sp.sin(stiffness * lg.t) + mass)
    with tempfile.TemporaryDirectory() as d:
        loaded = round_trip(m, pathlib.Path(d) / "m.json")
    for name, c in m.components.items():
        assert loaded.components[name].params == c.params
    assert [float(v) for v in loaded.parameter_values.values()] == [float(v) for v in m.parameter_values.values()]


# --- what a file cannot hold ------------------------------------------------------------------------------------


def test_a_callable_signal_is_refused_by_name(tmp_path):
    m = lg.Model("callable")
    m.add("mass", "m", "p", m=1)
    m.add("force", "push", "p", F=math.sin)
    path = tmp_path / "c.json"
    with pytest.raises(lg.ModelFileError, match=r"component 'push' \(force\), parameter 'F': is a Python callable"
                                                r".*expression of lagrangian.t"):
        m.save(path)
    assert not path.exists()


@pytest.mark.parametrize("value, words", [
    (sp.Dummy("k", positive=True), "Dummy"),
    (sp.Float("0.1", 30), "bits of precision"),
    (sp.gamma(sp.Symbol("x", positive=True)) + 1, r"gamma\(\) is not a function"),
    (sp.Piecewise((1, sp.Eq(sp.Symbol("x"), 0)), (2, True)), "is not a condition"),
    (sp.Symbol("lambda", positive=True), "cannot be written as a name"),
    (sp.Float(2.0**-1074) * 3 / 7 + 1 / sp.Symbol("x", positive=True), "beyond a double's range"),
])
def test_values_a_file_cannot_hold_are_refused(tmp_path, value, words):
    m = lg.Model("x")
    m.add("spring", "k", ("ground", "p"), k=value)
    with pytest.raises(lg.ModelFileError, match=rf"component 'k' \(spring\), parameter 'k': .*{words}"):
        m.save(tmp_path / "x.json")


def test_an_expression_sympy_reads_back_arranged_otherwise_is_refused_with_the_fix(tmp_path):
    x = sp.Symbol("x", positive=True)
    m = lg.Model("arranged")
    m.add("mass", "m", "p", m=1)
    m.add("force", "F", "p", F=sp.Mul(2, x + 1, evaluate=False))  # SymPy reads 2*(x + 1) as 2*x + 2
    with pytest.raises(lg.ModelFileError, match=r"parameter 'F': 2\*\(x \+ 1\) reads back arranged otherwise, as "
                                                r"2\*x \+ 2: give the parameter as that expression"):
        m.save(tmp_path / "arranged.json")
    for value in (2 * x + 2, (x + 1.0) ** -1 / 2):  # (the second is written as a plain product of powers)
        m = lg.Model("arranged")
        m.add("mass", "m", "p", m=1)
        m.add("force", "F", "p", F=value)
        assert round_trip(m, tmp_path / "arranged.json").components["F"].F == m.components["F"].F


# --- hostile files ----------------------------------------------------------------------------------------------


def valid() -> dict:
    return {"lagrangian_model": 1, "name": "osc", "options": {},
            "components": [{"kind": "mass", "name": "m", "nodes": ["p"], "params": {"m": 1.0}},
                           {"kind": "spring", "name": "k", "nodes": ["ground", "p"], "params": {"k": 4.0}}]}


def refused(tmp_path, text: str | bytes, pointer: str, words: str, **kwargs) -> lg.ModelFileError:
    path = tmp_path / "hostile.json"
    (path.write_bytes if isinstance(text, bytes) else path.write_text)(text)
    with pytest.raises(lg.ModelFileError, match=words) as info:
        lg.load(path, **kwargs)
    assert info.value.pointer == pointer, str(info.value)
    assert str(path) in str(info.value)
    return info.value


def with_(change) -> str:
    doc = valid()
    change(doc)
    return json.dumps(doc)


def test_the_valid_neighbour_loads(tmp_path):
    path = tmp_path / "ok.json"
    path.write_text(json.dumps(valid()))
    assert lg.load(path).coordinate_names == ["x_p"]


def test_truncated_json(tmp_path):
    text = json.dumps(valid())
    refused(tmp_path, text[: len(text) // 2], "", r"not valid JSON: .*line 1, column")


@pytest.mark.parametrize("change, pointer, words", [
    (lambda d: d.update(extra=1), "/extra", "unknown key"),
    (lambda d: d["components"][1].update(colour="red"), "/components/1/colour", "unknown key"),
    (lambda d: d["components"][1]["params"].update(kk=1), "/components/1/params/kk", "no such parameter. Did you mean 'k'"),
    (lambda d: d.update(lagrangian_model=2), "/lagrangian_model", "version 2 .* upgrade lagrangian"),
    (lambda d: d.update(lagrangian_model="1"), "/lagrangian_model", "expected the schema version, an integer, got text"),
    (lambda d: d.pop("lagrangian_model"), "", "not a lagrangian model file"),
    (lambda d: d.pop("components"), "", "'components' is missing"),
    (lambda d: d["components"][0].update(nodes="p"), "/components/0/nodes", "expected an array"),
    (lambda d: d["components"][1]["params"].update(k=True), "/components/1/params/k", "got true/false"),
    (lambda d: d["components"][1]["params"].update(k=-4), "/components/1/params/k", "must be positive"),
    (lambda d: d["components"][1].update(kind="sprng"), "/components/1/kind", "Did you mean 'spring'"),
    (lambda d: d["components"][1].update(name="m"), "/components/1", "already used"),
    (lambda d: d["options"].update(dim=7), "/options/dim", "must be one of"),
    (lambda d: d["options"].update(dimm=2), "/options/dimm", "unknown model option"),
    (lambda d: d.update(symbols={"k": {"positive": True, "negative": True}}), "/symbols/k", "contradict"),
    (lambda d: d.update(symbols={"os.system": {}}), "/symbols/os.system", "not a name"),
    (lambda d: d.update(state={"v": {"rate": "x_p(t)"}}), "/state/v/rate", "not a coordinate name"),
    (lambda d: d["components"][1]["params"].update(k="1e400"), "/components/1/params/k", "not finite"),
    (lambda d: d["options"].update(registry="os"), "/options/registry", "multiple values"),
    (lambda d: d["components"][0]["params"].update(m=[1, 2]), "/components/0/params/m", "expected a number"),
    (lambda d: d["components"][0]["params"].update(m={"__class__": 1}), "/components/0/params/m", "got an object"),
    (lambda d: d.update(plugins=[{"name": 1}]), "/plugins/0/name", "expected the plugin's entry-point name"),
], ids=lambda x: x if isinstance(x, str) else "")
def test_structure_is_validated_at_its_pointer(tmp_path, change, pointer, words):
    refused(tmp_path, with_(change), pointer, words)


def test_duplicate_keys(tmp_path):
    text = json.dumps(valid()).replace('"params": {"k": 4.0}', '"params": {"k": 4.0, "k": 5.0}')
    refused(tmp_path, text, "/components/1/params/k", "given twice")


@pytest.mark.parametrize("literal, words", [
    ("1e400", "not a finite number"), ("-1e400", "not a finite number"), ("NaN", "not a finite number"),
    ("Infinity", "not a finite number"), ("1" + "0" * 100_000, "100001 digits"),
])
def test_huge_numbers(tmp_path, literal, words):
    text = json.dumps(valid()).replace('"k": 4.0', f'"k": {literal}')
    refused(tmp_path, text, "/components/1/params/k", words)


@pytest.mark.parametrize("text, words", [
    ("10**100000", "power 10\\*\\*100000 is not a finite number"),
    ("9**9**9", "not a finite number"),
    ("exp(10**30)", "beyond a float's range|not a finite number"),
])
def test_huge_numbers_as_text(tmp_path, text, words):
    refused(tmp_path, with_(lambda d: d["components"][1]["params"].update(k=text)), "/components/1/params/k", words)


@pytest.mark.parametrize("code", [
    "__import__('os').system('touch pwned')", "open('pwned', 'w')", "(lambda: 1)()", "k.__class__",
    "[x for x in ()]", "exec('1')",
])
def test_code_in_expressions_is_never_run(tmp_path, monkeypatch, code):
    monkeypatch.chdir(tmp_path)
    error = refused(tmp_path, with_(lambda d: d["components"][1]["params"].update(k=code)), "/components/1/params/k",
                    "write numbers, names|cannot read|not allowed")
    assert not (tmp_path / "pwned").exists()
    assert "Traceback" not in str(error)


def test_code_in_names_is_data(tmp_path, monkeypatch):
    """A component, node or model name with code in it is a name: kept as text, never run."""
    monkeypatch.chdir(tmp_path)
    code = "__import__('os').system('touch pwned')"
    doc = valid()
    doc["name"] = code
    doc["components"][1].update(name=code, nodes=["ground", code])
    doc["components"][0]["nodes"] = [code]
    path = tmp_path / "names.json"
    path.write_text(json.dumps(doc))
    loaded = lg.load(path)
    assert loaded.name == code and code in loaded.components and code in loaded.nodes
    assert not (tmp_path / "pwned").exists()
    refused(tmp_path, with_(lambda d: d["components"][1].update(name="a\x00b")), "/components/1", "control character")


def test_deep_nesting(tmp_path):
    text = json.dumps(valid()).replace('"params": {"k": 4.0}', '"params": {"k": ' + "[" * 1000 + "]" * 1000 + "}")
    refused(tmp_path, text, "", r"nest deeper than 32 levels \(line 1, column")
    # brackets inside strings are not nesting
    text = json.dumps(valid()).replace('"name": "osc"', '"name": "' + "[" * 1000 + '"')
    path = tmp_path / "brackets.json"
    path.write_text(text)
    assert lg.load(path).name == "[" * 1000


def test_a_huge_string_is_refused_by_the_size_bound_before_parsing(tmp_path, monkeypatch):
    path = tmp_path / "huge.json"
    text = json.dumps(valid())
    path.write_text(text.replace('"name": "osc"', '"name": "' + "x" * 50_000_000 + '"'))

    def no_parsing(*args, **kwargs):
        raise AssertionError("the file was parsed")

    monkeypatch.setattr(modelfile, "parse", no_parsing)
    with pytest.raises(lg.ModelFileError, match=r"bytes, more than 10,000,000 \(load\(\.\.\., max_bytes=\)") as info:
        lg.load(path)
    assert info.value.pointer == ""


def test_a_long_string_within_the_file_bound(tmp_path):
    refused(tmp_path, with_(lambda d: d.update(name="x" * 20_000)), "/name", "20000 characters is longer than 10000")
    refused(tmp_path, with_(lambda d: d["components"][1]["params"].update(k="k" + "+k" * 6000)),
            "/components/1/params/k", "longer than 10000")


def test_many_entries(tmp_path, monkeypatch):
    refused(tmp_path, with_(lambda d: d.update(nodes=["n"] * 10_001)), "/nodes", "10001 entries are more than 10000")
    monkeypatch.setattr(modelfile, "MAX_COMPONENTS", 1)
    refused(tmp_path, json.dumps(valid()), "/components", "2 entries are more than 1")


def test_not_utf8_and_not_an_object(tmp_path):
    refused(tmp_path, b'{"name": "\xff"}', "", "not UTF-8")
    refused(tmp_path, "[1, 2]", "", "expected a JSON object")


def test_missing_file(tmp_path):
    with pytest.raises(lg.ModelFileError, match="cannot read it"):
        lg.load(tmp_path / "absent.json")


def test_errors_are_model_errors_with_a_pointer():
    assert issubclass(lg.ModelFileError, lg.ModelError)
    error = lg.ModelFileError("bad", pointer="/components/3/params/k", path="m.json")
    assert str(error) == "model file 'm.json', at /components/3/params/k: bad"
    assert error.pointer == "/components/3/params/k" and error.path == "m.json"


def test_loading_never_evaluates_text(tmp_path, monkeypatch):
    """No text of a file reaches eval, exec or sympify: every expression is read by lagrangian.text."""
    import builtins

    marker = "omega_marker"
    seen = []
    for module, name in ((builtins, "eval"), (builtins, "exec"), (sp, "sympify")):
        original = getattr(module, name)

        def watch(source, *args, _original=original, **kwargs):
            if isinstance(source, (str, bytes)) and marker in str(source):  # text, not SymPy objects
                seen.append(source)
            return _original(source, *args, **kwargs)

        monkeypatch.setattr(module, name, watch)
    m = lg.Model("watched")
    m.add("mass", "m", "p", m=1)
    m.add("force", "F", "p", F=sp.sin(sp.Symbol(marker) * lg.t) - lg.rate("x_p"))
    loaded = round_trip(m, tmp_path / "watched.json")
    assert loaded.components["F"].F == m.components["F"].F
    assert seen == []


_X, _Y = sp.Symbol("x", positive=True), sp.Symbol("y", real=True)
_LEAVES = st.one_of(
    st.floats(min_value=1e-12, max_value=1e12).map(sp.Float), st.floats(min_value=-1e6, max_value=-1e-6).map(sp.Float),
    st.integers(-10**6, 10**6).map(sp.Integer), st.fractions(max_denominator=1000).map(sp.Rational),
    st.sampled_from([_X, _Y, lg.t, sp.pi, sp.E, lg.coordinate("x_p"), lg.rate("x_p")]))
_EXPRESSIONS = st.recursive(_LEAVES, lambda inner: st.one_of(
    st.tuples(inner, inner).map(lambda ab: ab[0] + ab[1]), st.tuples(inner, inner).map(lambda ab: ab[0] * ab[1]),
    st.tuples(inner, st.integers(-3, 3)).map(lambda ab: ab[0] ** ab[1] if ab[0] != 0 or ab[1] > 0 else ab[0]),
    st.tuples(st.sampled_from([sp.sin, sp.exp, sp.Abs, sp.tanh, lambda a: sp.sqrt(a**2 + 1), sp.Heaviside]), inner)
      .map(lambda fa: fa[0](fa[1])),
    st.tuples(inner, inner).map(lambda ab: sp.atan2(ab[0], ab[1]) if ab != (0, 0) else ab[0]),
    st.tuples(inner, inner, st.floats(1e-6, 1e3), st.floats(1e-3, 1e4)).map(  # a pulse, as netlists give them
        lambda p: sp.Piecewise((p[0], lg.t <= p[2]), (p[1], sp.Mod(lg.t, p[3]) < p[2]), (0, True)))), max_leaves=8)


@settings(max_examples=40, deadline=None)
@given(_EXPRESSIONS)
def test_random_expressions_are_written_exactly(expr):
    """A force written as any expression of numbers over decades, symbols, t and the state reads back as the very
    same SymPy expression (or the model refuses the value when it is added, before any file)."""
    m = lg.Model("random")
    m.add("mass", "m", "p", m=1)
    try:
        m.add("force", "F", "p", F=expr)
    except lg.ModelError:
        return  # (not finite, complex, ...: not a value of a force)
    with tempfile.TemporaryDirectory() as d:
        path = pathlib.Path(d) / "m.json"
        try:
            m.save(path)
        except lg.ModelFileError as exc:  # refused, never changed
            assert re.search("beyond a double's range|reads back arranged otherwise|beyond a float's range", str(exc))
            return
        loaded = lg.load(path)
    assert loaded.components["F"].F == m.components["F"].F
