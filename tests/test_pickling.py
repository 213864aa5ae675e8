"""A model, its results and its errors leave the process: they pickle with ``pickle`` and ``cloudpickle``, and an
unpickled model (here, in a fresh process, on Dask workers) simulates exactly as the original does.

The reference of every check is the original object: the unpickled one must give the same arrays, bit for bit,
from the same method on the same points.  Compiled code never travels in a pickle: it is rebuilt from the disk
cache (or compiled again) on first use.
"""

from __future__ import annotations

import importlib
import inspect
import os
import pickle
import subprocess
import sys
import textwrap
import types
import warnings

import cloudpickle
import numpy as np
import pandas as pd
import pytest
import sympy as sp

import lagrangian as lg
import lagrangian.errors as errors
from lagrangian import frequency, models, routh
from lagrangian.registry import PluginInfo, default_registry
from lagrangian.sweep import sweep

PICKLERS = {"pickle": pickle, "cloudpickle": cloudpickle}

# the modules that define errors of their own: the core's hierarchy, and the plugins'
ERROR_MODULES = ("lagrangian.errors", "lagrangian.circuits.spice", "lagrangian.circuits.analogy",
                 "lagrangian.plugins.transducers")


def roundtrip(obj, how: str):
    return pickle.loads(PICKLERS[how].dumps(obj))


@pytest.fixture(params=sorted(PICKLERS))
def how(request) -> str:
    return request.param


# ---------------------------------------------------------------------------------------------------------------
# the models and the runs compared

PENDULUM_RUN = dict(t_end=3.0, initial={"theta_j1": -1.0, "theta_j2": -0.3},
                    velocity={"theta_j1": 0.0, "theta_j2": 0.4}, points=61)
LADDER_RUN = dict(t_end=4.0, initial={f"q_L{k}": 0.1 * (-1) ** k for k in range(5)},
                  velocity={f"q_L{k}": 0.05 * k for k in range(5)}, points=41)


def run(model, spec, **extra):
    spec = {**spec, **extra}
    return model.simulate(spec.pop("t_end"), **spec)


def assert_same_run(a, b):
    assert a.names == b.names and a.method == b.method and a.nfev == b.nfev
    assert np.array_equal(a.t, b.t)
    for name in a.names:
        assert np.array_equal(a.q[name], b.q[name]) and np.array_equal(a.v[name], b.v[name])
    for part in ("T", "V", "D"):
        assert np.array_equal(getattr(a, part), getattr(b, part))


def oscillator(k=None) -> lg.Model:
    m = lg.Model("osc")
    m.add("mass", "m1", "p", m=0.3)
    m.add("spring", "k1", ("ground", "p"), k=sp.Symbol("k", positive=True) if k is None else k)
    m.add("damper", "c1", ("ground", "p"), c=0.05)
    return m


@pytest.fixture(scope="module")
def pendulum():
    m = models.double_pendulum()
    return m, run(m, PENDULUM_RUN, compiled="tape")


# ---------------------------------------------------------------------------------------------------------------
# models


@pytest.mark.parametrize("derived", [False, True], ids=["as built", "derived and simulated"])
def test_a_double_pendulum_round_trips_and_simulates_as_the_original(how, derived):
    m = models.double_pendulum()
    if derived:
        run(m, PENDULUM_RUN, compiled="tape")
    back = roundtrip(m, how)
    assert back is not m and back.name == m.name and list(back.components) == list(m.components)
    assert back.registry is default_registry()  # the installed plugins, loaded by name
    assert back._numeric == {}  # no numeric functions, no compiled code: rebuilt on first use
    assert all(isinstance(k, str) for k in back._cache)  # nothing keyed by an id of this process
    assert sp.simplify(back.lagrangian - m.lagrangian) == 0
    assert_same_run(run(back, PENDULUM_RUN, compiled="tape"), run(m, PENDULUM_RUN, compiled="tape"))


def test_a_circuit_round_trips_and_simulates_as_the_original(how):
    m = models.rlc_ladder(5)
    first = run(m, LADDER_RUN)
    back = roundtrip(m, how)
    assert [c.kind for c in back.components.values()] == [c.kind for c in m.components.values()]
    assert_same_run(run(back, LADDER_RUN), first)
    assert_same_run(run(back, LADDER_RUN, method="exact"), run(m, LADDER_RUN, method="exact"))


def test_a_model_with_a_symbolic_parameter_keeps_it(how):
    m = oscillator()
    spec = dict(t_end=2.0, params={"k": 40.0}, initial={"x_p": 0.01}, velocity={"x_p": 0.0}, points=21)
    first = run(m, spec)
    back = roundtrip(m, how)
    assert [s.name for s in back.parameters] == ["k"] and back.parameters[0].is_positive
    assert_same_run(run(back, spec), first)
    with pytest.raises(lg.ModelError, match="k"):  # its value is still asked for
        back.simulate(1.0, initial={"x_p": 0.01}, velocity={"x_p": 0.0})


def test_a_reduced_model_round_trips(how):
    m = models.spherical_pendulum()
    red = routh.reduce(m)
    spec = dict(t_end=2.0, initial={"theta_tilt": 0.9, "theta_turn": 0.0},
                velocity={"theta_turn": 1.7, "theta_tilt": 0.0}, reconstruct=True, points=21)
    first = run(red, spec)
    back = roundtrip(red, how)
    assert back.ignored == red.ignored and sp.simplify(back.routhian - red.routhian) == 0
    again = run(back, spec)
    assert_same_run(again, first)
    assert np.array_equal(again["theta_turn"], first["theta_turn"])  # reconstructed by quadrature


def test_a_callable_signal_is_refused_by_pickle_by_name_and_carried_by_cloudpickle():
    m = lg.Model("pushed")
    m.add("mass", "m1", "p", m=2.0)
    m.add("force", "F", "p", F=lambda time: np.sin(3.0 * time))
    spec = dict(t_end=1.0, initial={"x_p": 0.0}, velocity={"x_p": 0.0}, points=11)
    res = run(m, spec)
    with pytest.raises(lg.ModelError, match="component 'F': parameter 'F' is the Python callable .*cloudpickle"):
        pickle.dumps(m)
    with pytest.raises(lg.ModelError, match="signal F_F .*cloudpickle"):
        pickle.dumps(res)  # its evaluator holds the model's functions, the callable among them
    assert_same_run(run(roundtrip(m, "cloudpickle"), spec), res)
    assert_same_run(roundtrip(res, "cloudpickle"), res)


def test_numeric_functions_travel_without_compiled_code_and_rebuild_it_on_first_use(how, pendulum):
    m, _ = pendulum
    numeric = m.numeric()
    numeric.use_compiled("tape")
    y = np.array([-1.0, -0.3, 0.2, 0.4])
    back = roundtrip(numeric, how)
    assert back._builds == {}  # nothing compiled came with it
    assert np.array_equal(back.rhs(0.5, y), numeric.rhs(0.5, y))  # the tape, built again here on first use
    assert back._fast is back._builds["tape"] and back._fast is not numeric._fast
    T, V, D = back.energies(np.array([0.5]), y[:2, None], y[2:, None])
    assert np.array_equal(T + V, sum(numeric.energies(np.array([0.5]), y[:2, None], y[2:, None])[:2]))


# ---------------------------------------------------------------------------------------------------------------
# results


def test_a_result_round_trips_with_its_methods(how, pendulum):
    m, res = pendulum
    back = roundtrip(res, how)
    assert_same_run(back, res)
    assert back.names == res.names == ["theta_j1", "theta_j2"]
    assert back.notes == res.notes and back.defaulted == res.defaulted and back.model == res.model
    assert np.array_equal(back["theta_j2"], res["theta_j2"])
    assert np.array_equal(back.velocity("theta_j1"), res.velocity("theta_j1"))
    assert np.array_equal(back.E, res.E)
    pd.testing.assert_frame_equal(back.to_pandas(), res.to_pandas(), check_exact=True)
    # a quantity evaluated along the result: its model's functions are rebuilt, not unpickled
    theta = m.coordinates[0].function
    assert np.array_equal(back.quantity(sp.cos(theta)), res.quantity(sp.cos(theta)))
    assert back.evaluator.__self__._builds == {}


def test_an_exact_solution_round_trips(how):
    m = oscillator(k=40.0)
    res = m.simulate(2.0, initial={"x_p": 0.01}, velocity={"x_p": 0.0}, points=11, method="exact")
    back = roundtrip(res, how)
    assert_same_run(back, res)
    x = m.coordinates[0].function
    assert np.array_equal(back.quantity(40.0 * x), res.quantity(40.0 * x))


def test_an_exact_solution_of_a_large_network_from_its_stamps_round_trips(how):
    """Solved from its stamps (nothing symbolic derived), its quantities derived on request: that too travels."""
    m = models.rlc_ladder(40, seed=2)
    res = m.simulate(0.01, points=11, method="exact")
    assert "stamps" in res.notes[0]
    back = roundtrip(res, how)
    assert_same_run(back, res)
    q = m.coordinates[0].function
    assert np.array_equal(back.quantity(3.0 * q), res.quantity(3.0 * q))


@pytest.mark.slow  # the sweep compiles the model's library (0.6 s with an empty disk cache)
def test_a_sweep_dataset_round_trips():
    m = oscillator()
    ds = sweep(m, {"k": [10.0, 40.0]}, initial={"x_p": 0.01}, velocity={"x_p": 0.0}, outputs=["x_p", "E"],
               t_end=1.0, points=11, client="serial", progress=False)
    for how in PICKLERS:
        back = roundtrip(ds, how)
        assert back.identical(ds) and np.array_equal(back.x_p.values, ds.x_p.values)


def test_frequency_responses_transfer_functions_and_linear_models_round_trip(how):
    m = lg.Model("isolator")
    m.add("prescribed_motion", "base", "b", position=0)
    m.add("mass", "m", "p", m=0.3)
    m.add("spring", "k", ("b", "p"), k=40.0)
    m.add("damper", "c", ("b", "p"), c=0.5)
    f = frequency.decades(0.1, 100, 20)
    resp = frequency.frequency_response(m, f, outputs=["x_p"])
    back = roundtrip(resp, how)
    assert np.array_equal(back.H, resp.H) and np.array_equal(back.frequencies, resp.frequencies)
    assert (back.inputs, back.outputs, back.units) == (resp.inputs, resp.outputs, resp.units)
    assert np.array_equal(back["x_p"], resp["x_p"])
    H = frequency.transfer_function(m, "base", "x_p")
    H2 = roundtrip(H, how)
    s = 2j * np.pi * f
    assert np.array_equal(H2(s), H(s)) and sp.simplify(H2.expr - H.expr) == 0
    assert np.array_equal(np.sort_complex(H2.poles()), np.sort_complex(H.poles())) and H2.dc_gain == H.dc_gain
    lin = frequency.linearize(m, inputs=["base"], outputs=["x_p"])
    lin2 = roundtrip(lin, how)
    for name in ("M", "C", "K"):
        assert np.array_equal(getattr(lin2, name), getattr(lin, name))
    assert all(np.array_equal(a, b) for a, b in zip(lin2.B, lin.B))
    assert (lin2.coordinates, lin2.inputs, lin2.outputs) == (lin.coordinates, lin.inputs, lin.outputs)


# ---------------------------------------------------------------------------------------------------------------
# errors


def error_classes() -> list[type]:
    """Every error class of lagrangian (the plugins' included), found by walking the hierarchy."""
    for name in ERROR_MODULES:
        importlib.import_module(name)
    found, todo = [], [errors.LagrangianError]
    while todo:
        cls = todo.pop()
        if cls.__module__.startswith("lagrangian") and "<locals>" not in cls.__qualname__:
            found.append(cls)
        todo += cls.__subclasses__()
    return sorted(set(found), key=lambda c: (c.__module__, c.__qualname__))


def sample_arguments(cls: type) -> tuple:
    """Arguments for ``cls(...)`` from its signature: text for names and messages, a list for ``known``."""
    values = {"known": ["spring", "mass", "damper"], "time": 0.125}
    out = []
    for p in list(inspect.signature(cls.__init__).parameters.values())[1:]:
        if p.kind in (p.VAR_POSITIONAL,):
            out.append(f"{cls.__name__} went wrong: the message")
        elif p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD) and p.default is p.empty:
            out.append(values.get(p.name, f"{p.name}-given"))
    return tuple(out)


def test_every_error_class_is_found():
    classes = {c.__name__ for c in error_classes()}
    public = {n for n in errors.__all__ if isinstance(getattr(errors, n), type)}
    assert public <= classes
    assert {"PullInError", "GapClosedError", "NgspiceError", "AnalogyError"} <= classes


@pytest.mark.parametrize("cls", error_classes(), ids=lambda c: c.__name__)
def test_every_error_round_trips_with_its_message_and_attributes(cls, how):
    error = cls(*sample_arguments(cls))
    error.add_note("a note added on the way")
    back = roundtrip(error, how)
    assert type(back) is cls
    assert str(back) == str(error) and back.args == error.args
    assert vars(back) == vars(error)  # the attributes its __init__ set (plugin, kind, component, ...), notes
    with pytest.raises(cls, match="went wrong|given|spring"):
        raise back


def test_an_error_with_its_own_signature_keeps_its_attributes():
    error = lg.ParameterError("k1", "k", "must be positive, got -1.")
    back = pickle.loads(pickle.dumps(error))
    assert (back.component, back.parameter) == ("k1", "k")
    assert str(back) == "component 'k1', parameter 'k': must be positive, got -1."
    unknown = pickle.loads(pickle.dumps(lg.UnknownKindError("sprng", ["spring", "mass"])))
    assert unknown.kind == "sprng" and "Did you mean 'spring'?" in str(unknown)


# ---------------------------------------------------------------------------------------------------------------
# plugins passed in at run time


FLYWHEEL = '''
import lagrangian as lg

class Flywheel(lg.Component):
    """T = a x'^2 / 2 at one node."""
    kind = "flywheel"
    domain = "mechanical"
    terminals = ("node",)
    parameters = {"a": lg.Parameter("inertia-like coefficient", unit="kg")}

    def contribute(self, ctx):
        v = ctx.view.velocity(self.nodes[0])
        return lg.Contribution(T=self.a * lg.dot(v, v) / 2)

    @classmethod
    def example(cls):
        return lg.Example("p", {"a": 1}, context=[("spring", "k", ("ground", "p"), {"k": 1})])

@lg.hookimpl
def register_component_types(register):
    register(Flywheel)
'''

FLY_RUN = dict(t_end=1.0, initial={"x_p": 0.1}, velocity={"x_p": 0.0}, points=11)


def flywheel_model(plugin) -> lg.Model:
    m = lg.Model("fly", registry=lg.Registry(plugins={"scratch": plugin}))
    m.add("flywheel", "f", "p", a=2.0)
    m.add("spring", "k1", ("ground", "p"), k=8.0)
    return m


def test_an_importable_plugin_module_is_pickled_by_its_name(how):
    import lagrangian.plugins.integrators as integrators
    import lagrangian.plugins.mechanics as mechanics

    plugins = {"mech": mechanics, "steppers": integrators}
    m = lg.Model("osc", registry=lg.Registry(plugins=plugins, entry_points=False))
    m.add("mass", "m1", "p", m=0.3)
    m.add("spring", "k1", ("ground", "p"), k=40.0)
    back = roundtrip(m, how)
    assert back.registry is not m.registry and back.registry.pm.get_plugin("mech") is mechanics
    assert [p.name for p in back.registry.plugins()] == ["mech", "steppers"]  # no entry point loaded, as built
    spec = dict(t_end=1.0, initial={"x_p": 0.01}, velocity={"x_p": 0.0}, points=11)
    assert_same_run(run(back, spec), run(m, spec))


def test_a_plugin_module_built_at_run_time_is_refused_by_pickle_and_carried_by_cloudpickle():
    plugin = types.ModuleType("scratch_plugin")
    exec(FLYWHEEL, plugin.__dict__)
    m = flywheel_model(plugin)
    first = run(m, FLY_RUN)
    with pytest.raises(lg.ModelError, match="plugin 'scratch'.*'scratch_plugin'.*cloudpickle"):
        pickle.dumps(m)
    back = pickle.loads(cloudpickle.dumps(m))  # by value: the module and the class it defines
    assert back.registry.pm.get_plugin("scratch") is not plugin
    assert type(back.component("f")) is back.registry.kinds["flywheel"]
    assert_same_run(run(back, FLY_RUN), first)


def test_a_model_needing_a_plugin_not_installed_where_it_is_unpickled_says_which():
    registry = lg.Registry()
    registry.info["phantom"] = PluginInfo("phantom", "lagrangian-phantom", "1.0")  # as if installed here, not there
    m = lg.Model("osc", registry=registry)
    m.add("mass", "m1", "p", m=0.3)
    data = pickle.dumps(m)
    with pytest.raises(lg.PluginError, match="plugin 'phantom'.*not installed"):
        pickle.loads(data)


# ---------------------------------------------------------------------------------------------------------------
# a fresh process, and Dask workers

FRESH = """
import pickle, sys, warnings
warnings.simplefilter("ignore")
runs = pickle.load(open(sys.argv[1], "rb"))
out = []
for model, spec, extra in runs:
    spec = dict(spec)
    out.append(model.simulate(spec.pop("t_end"), **spec, **extra))
pickle.dump(out, open(sys.argv[2], "wb"))
"""


BUILT = """
import pickle, sys, warnings
warnings.simplefilter("ignore")
from lagrangian import models
pendulum, ladder = models.double_pendulum(), models.rlc_ladder(5)
out = []
for i, (spec, extra) in enumerate(pickle.load(open(sys.argv[1], "rb"))):
    spec = dict(spec)
    out.append((pendulum if i < 3 else ladder).simulate(spec.pop("t_end"), **spec, **extra))
pickle.dump(out, open(sys.argv[2], "wb"))
"""


@pytest.mark.slow
def test_a_model_unpickled_in_a_fresh_process_simulates_bit_for_bit_as_the_original(tmp_path):
    pendulum, ladder = models.double_pendulum(), models.rlc_ladder(5)
    runs = [(pendulum, PENDULUM_RUN, {"compiled": "tape"}), (pendulum, PENDULUM_RUN, {"compiled": True}),
            (pendulum, PENDULUM_RUN, {"method": "rk4", "step": 0.01, "compiled": "tape"}),
            (ladder, LADDER_RUN, {"compiled": "tape"}), (ladder, LADDER_RUN, {"compiled": True}),
            (ladder, LADDER_RUN, {"method": "Radau", "compiled": "tape"}), (ladder, LADDER_RUN, {"method": "exact"})]
    # the evaluator pinned: with compiled="auto" a cold cache runs the tape while the model compiles, a warm one the
    # compiled code, whose sums round in another order.  The originals run in a fresh process too, built there: a
    # process that has run other work (the test suite's) may round a Radau run otherwise (noted as its own issue).
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for model, spec, extra in runs:  # run here first: the models pickled hold compiled code
            run(model, spec, **extra)
    (tmp_path / "fresh.py").write_text(FRESH)
    (tmp_path / "models.pkl").write_bytes(pickle.dumps(runs))
    (tmp_path / "built.py").write_text(BUILT)
    (tmp_path / "specs.pkl").write_bytes(pickle.dumps([(spec, extra) for _, spec, extra in runs]))
    out = []
    for script, given, result in (("fresh.py", "models.pkl", "results.pkl"), ("built.py", "specs.pkl", "here.pkl")):
        proc = subprocess.run([sys.executable, str(tmp_path / script), str(tmp_path / given), str(tmp_path / result)],
                              capture_output=True, text=True, timeout=300)
        assert proc.returncode == 0, proc.stderr
        out.append(pickle.loads((tmp_path / result).read_bytes()))
    there, here = out
    assert len(there) == len(here) == len(runs)
    for a, b in zip(there, here):
        assert_same_run(a, b)


@pytest.mark.slow
def test_dask_workers_simulate_a_scattered_model_as_this_process_does():
    distributed = pytest.importorskip("distributed")
    from lagrangian.sweep import local_cluster

    def final_values(params, model):  # a user's function: by value to the workers (cloudpickle)
        res = model.simulate(5.0, params=params, initial={"theta_j1": -1.0, "theta_j2": -0.5},
                             velocity={"theta_j1": 0.0, "theta_j2": 0.0}, points=11, compiled="tape")
        return np.array([res["theta_j1"][-1], res["theta_j2"][-1], res.E[-1]])

    model = models.double_pendulum()
    samples = [{"m_m2": m2, "g_g": g} for m2 in (0.5, 1.0, 2.0) for g in (9.81, 1.62)]
    with local_cluster(2) as cluster, distributed.Client(cluster, set_as_default=False) as client:
        sent = client.scatter(model, broadcast=True)  # once, to every worker
        there = client.gather(client.map(final_values, samples, model=sent, pure=False))
        pids = set(client.run(os.getpid).values())
    here = [final_values(p, model) for p in samples]
    assert len(pids) == 2 and os.getpid() not in pids
    for a, b in zip(there, here):
        assert np.array_equal(a, b)
    assert len({tuple(a) for a in here}) == len(samples)  # the parameters did reach the runs
