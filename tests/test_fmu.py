"""FMI 2.0 export (Model.to_fmu): FMPy, an independent engine, runs the FMU against Model.simulate."""

import ctypes
import json
import math
import shutil
import subprocess
import sys
import venv
import zipfile
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

import lagrangian as lg
from lagrangian import models
from lagrangian.errors import ModelError
from lagrangian.numerics.fmu import _unit_exponents, model_identifier, xml_text

fmpy = pytest.importorskip("fmpy")
from fmpy.fmi2 import FMU2Model  # noqa: E402
from fmpy.validation import validate_fmu  # noqa: E402

needs_cc = pytest.mark.skipif(lg.codegen.compiler() is None, reason="no C compiler")
START = {"theta_j1": 0.3, "theta_j2": -0.2}

# (model, its span, its start, our reference run: DOP853 at tight tolerances, or the exact solution of a linear model)
CASES = {
    "double pendulum": (models.double_pendulum, 5.0, START, dict(rtol=1e-13, atol=1e-15)),
    "loudspeaker": (lambda: models.loudspeaker(E=2.0), 0.05, {"x_cone": 1e-3}, dict(method="exact")),
    "rlc ladder": (lambda: models.rlc_ladder(10, E=1.0), 5.0, {}, dict(method="exact")),
    # the accelerations by the articulated-body algorithm (lagrangian.plugins.multibody.recursive)
    "recursive chain": (lambda: models.pendulum_chain(4, m=[0.3, 0.4, 0.5, 0.6], length=0.6, dynamics="recursive"), 2.0,
                        {"theta_j0": 0.4, "theta_j2": -0.3}, dict(rtol=1e-13, atol=1e-15)),
}


def states(model):
    return [*model.coordinate_names, *(f"{n}'" for n in model.coordinate_names)]


def ours(res, name):
    return res.velocity(name[:-1]) if name.endswith("'") else res[name]


def worst(fmu_result, res, names) -> float:
    """The largest difference over the run, relative to each state's peak."""
    return max(np.max(np.abs(fmu_result[n] - ours(res, n))) / np.max(np.abs(ours(res, n))) for n in names)


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    """Each case's model and its FMU (exported once for the module)."""
    folder = tmp_path_factory.mktemp("fmu")
    out = {}
    for key, (build, _, start, _) in CASES.items():
        model = build()
        out[key] = (model, model.to_fmu(folder / f"{model_identifier(model.name)}.fmu", initial=start))
    return out


def test_identifiers_names_and_units_are_checked():
    assert model_identifier("double pendulum") == "double_pendulum"
    assert model_identifier("3 masses") == "m_3_masses"
    assert model_identifier("é/*x*/") == "x"
    for bad in ("1abc", "a-b", "a b", "x" * 65, ""):
        with pytest.raises(ModelError, match="C identifier"):
            model_identifier("m", bad)
    assert xml_text('a<b>&"c"\x01\'') == "a&lt;b&gt;&amp;&quot;c&quot;?'"
    assert _unit_exponents("N s/m") == ("N s/m", (1, 0, -1, 0, 0, 0, 0, 0))
    assert _unit_exponents("T m = N/A = V s/m") == ("T m", (1, 1, -2, -1, 0, 0, 0, 0))
    assert _unit_exponents("rad/s²") == ("rad/s²", (0, 0, -2, 0, 0, 0, 0, 1))
    assert _unit_exponents("N m^n") is None and _unit_exponents("") is None


def _oscillator(name="osc"):
    model = lg.Model(name)
    model.add("mass", "m1", "p", m=0.5)
    model.add("spring", "k1", ("ground", "p"), k=3.0)
    return model


@pytest.mark.slow
@needs_cc
def test_what_an_fmu_cannot_hold_yet_is_refused_by_name(tmp_path):
    path = tmp_path / "x.fmu"
    with pytest.raises(ModelError, match="kind must be one of"):
        _oscillator().to_fmu(path, kind="me")
    with pytest.raises(ModelError, match="C identifier"):
        _oscillator().to_fmu(path, model_identifier="no way")
    with pytest.raises(ModelError, match="unknown argument 'stop'"):
        _oscillator().to_fmu(path, stop=3)
    with pytest.raises(ModelError, match="is a directory"):
        _oscillator().to_fmu(tmp_path)
    called = _oscillator()
    called.add("force", "push", "p", F=lambda time: math.cos(time))
    with pytest.raises(ModelError, match="Python callables"):
        called.to_fmu(path)
    pulsed = _oscillator()
    pulsed.add("force", "push", "p", F=sp.Piecewise((1.0, lg.t < 1), (0.0, True)))
    with pytest.raises(ModelError, match="switch in time"):
        pulsed.to_fmu(path)
    sticky = _oscillator()
    sticky.add("coulomb_friction", "f", ("ground", "p"), F_c=0.1, stick_slip=True)
    with pytest.raises(ModelError, match="stick_slip=True \\('f'\\)"):
        sticky.to_fmu(path)
    rolled = lg.Model("rolling")
    rolled.add("mass", "body", "p", m=1.0)
    rolled.add("inertia", "I", "w", J=0.5)
    rolled.add("constraint", "roll", f=lg.coordinate("x_p") - 0.2 * lg.coordinate("theta_w"))
    with pytest.raises(ModelError, match="constraints on positions \\('roll'\\)"):
        rolled.to_fmu(path)
    sleigh = lg.Model("sleigh", dim=2)
    sleigh.add("body", "b", "b", m=1.0, inertia=0.2, points={"edge": (-0.3, 0.0)})
    sleigh.add("free", "j", ("ground", "b"))
    sleigh.add("knife_edge", "k", "b.edge")
    with pytest.raises(ModelError, match="constraints on velocities \\(nonholonomic: 'k'\\)"):
        sleigh.to_fmu(path)
    assert not path.exists()
    assert _oscillator().to_fmu(path) == path and validate_fmu(str(path)) == []  # the same model, nothing added


@pytest.mark.slow
@needs_cc
def test_the_fmu_is_valid_and_describes_the_model(exported):
    model, path = exported["double pendulum"]
    assert validate_fmu(str(path)) == []
    with zipfile.ZipFile(path) as archive:
        assert sorted(archive.namelist()) == ["binaries/linux64/double_pendulum.so", "modelDescription.xml",
                                              "sources/double_pendulum.c"]
    md = fmpy.read_model_description(str(path))
    assert md.fmiVersion == "2.0" and md.modelExchange.modelIdentifier == "double_pendulum"
    assert md.coSimulation is None and not md.modelExchange.providesDirectionalDerivative
    variables = {v.name: v for v in md.modelVariables}
    assert [v.name for v in md.modelVariables][:8] == [*states(model), *(f"der({n})" for n in states(model))]
    assert variables["theta_j1"].start == "0.3" and variables["theta_j1'"].start == "0.0"
    assert variables["theta_j1"].unit == "rad" and variables["der(theta_j1')"].unit == "rad/s²"
    assert variables["der(theta_j2')"].derivative is variables["theta_j2'"]
    params = {v.name: float(v.start) for v in md.modelVariables if v.causality == "parameter"}
    assert params == model.parameter_values
    assert all(v.variability == "tunable" for v in md.modelVariables if v.causality == "parameter")
    assert variables["g_g"].unit == "m/s²" and variables["m_m1"].unit == "kg"
    for key in ("loudspeaker", "rlc ladder"):
        assert validate_fmu(str(exported[key][1])) == []
    assert {v.name: v.unit for v in fmpy.read_model_description(str(exported["loudspeaker"][1])).modelVariables
            }["Bl_coil"] == "T m"


def _instance(path, tmp_path):
    md = fmpy.read_model_description(str(path))
    unzipped = fmpy.extract(str(path), str(tmp_path / "unzipped"))
    fmu = FMU2Model(guid=md.guid, unzipDirectory=unzipped, modelIdentifier=md.modelExchange.modelIdentifier,
                    instanceName="check")
    fmu.instantiate()
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    fmu.enterContinuousTimeMode()
    return md, fmu


@pytest.mark.slow
@needs_cc
@pytest.mark.parametrize("key", list(CASES))
def test_the_fmu_derivatives_are_the_models(exported, key, tmp_path):
    """fmi2GetDerivatives at random states, and after a parameter is set, against NumericModel.rhs."""
    model, path = exported[key]
    md, fmu = _instance(path, tmp_path)
    nx = len(md.derivatives)
    rng = np.random.default_rng(7)
    name = sorted(model.parameter_values)[-1]
    vr = {v.name: v.valueReference for v in md.modelVariables}
    try:
        for changed in (False, True):
            if changed:
                fmu.setReal([vr[name]], [1.5 * model.parameter_values[name]])
            numeric = model.numeric({name: 1.5 * model.parameter_values[name]} if changed else None)
            for _ in range(5):
                t, x = float(rng.uniform(0, 2)), rng.normal(size=nx)
                fmu.setTime(t)
                fmu.setContinuousStates((ctypes.c_double * nx)(*x), nx)
                dx = (ctypes.c_double * nx)()
                fmu.getDerivatives(dx, nx)
                expected = numeric.rhs(t, x)
                assert np.allclose(np.array(dx), expected, rtol=1e-12, atol=1e-12 * np.max(np.abs(expected)))
                assert fmu.getReal([nx + i for i in range(nx)]) == list(dx)
        assert fmu.getReal([vr[name]]) == [1.5 * model.parameter_values[name]]
        fmu.terminate()
    finally:
        fmu.freeInstance()


@pytest.mark.slow
@needs_cc
@pytest.mark.parametrize("key", list(CASES))
def test_fmpy_runs_the_fmu_as_simulate_runs_the_model(exported, key):
    model, path = exported[key]
    _, span, start, reference = CASES[key]
    names = states(model)
    out = fmpy.simulate_fmu(str(path), stop_time=span, output_interval=span / 250, relative_tolerance=1e-12,
                            output=names)
    res = model.simulate(span, initial={n: start.get(n, 0.0) for n in model.coordinate_names},
                         velocity={n: 0.0 for n in model.coordinate_names}, t_eval=out["time"], **reference)
    assert worst(out, res, names) < 1e-8


@pytest.mark.slow
@needs_cc
def test_a_tunable_parameter_set_in_fmpy_changes_the_run_as_params_does(exported):
    model, path = exported["double pendulum"]
    names = states(model)
    out = fmpy.simulate_fmu(str(path), stop_time=2.0, output_interval=0.01, relative_tolerance=1e-12, output=names,
                            start_values={"g_g": 3.0, "theta_j2": 0.1})
    run = dict(initial={**START, "theta_j2": 0.1}, velocity={"theta_j1": 0, "theta_j2": 0}, t_eval=out["time"],
               rtol=1e-13, atol=1e-15)
    assert worst(out, model.simulate(2.0, params={"g_g": 3.0}, **run), names) < 1e-8
    assert worst(out, model.simulate(2.0, **run), names) > 1e-2  # the value was not ignored


@pytest.mark.slow
@needs_cc
def test_a_failing_evaluation_is_an_fmi_error_with_its_reason(exported):
    _, path = exported["double pendulum"]
    said = []

    def logger(env, instance, status, category, message):
        said.append(message.decode())

    with pytest.raises(Exception, match="fmi2ExitInitializationMode failed"):
        fmpy.simulate_fmu(str(path), stop_time=1.0, start_values={"m_m1": 0.0, "m_m2": 0.0}, logger=logger)
    assert any("mass matrix is singular" in m for m in said)


@pytest.mark.slow
@needs_cc
def test_the_shipped_source_builds_the_same_fmu(exported, tmp_path):
    """sources/ builds the binary (as another platform would), also with the fmi2 functions prefixed."""
    model, path = exported["double pendulum"]
    cc = lg.codegen.compiler()
    folder = Path(fmpy.extract(str(path), str(tmp_path / "unzipped")))
    source = folder / "sources" / "double_pendulum.c"
    binary = folder / "binaries" / "linux64" / "double_pendulum.so"
    names = states(model)
    before = fmpy.simulate_fmu(str(folder), stop_time=1.0, output_interval=0.05, relative_tolerance=1e-12, output=names)
    subprocess.run([cc, "-O2", "-shared", "-fPIC", "-o", str(binary), str(source), "-lm"], check=True)
    after = fmpy.simulate_fmu(str(folder), stop_time=1.0, output_interval=0.05, relative_tolerance=1e-12, output=names)
    for n in names:
        assert np.allclose(after[n], before[n], rtol=0, atol=1e-12)
    obj = tmp_path / "prefixed.o"
    subprocess.run([cc, "-c", "-DFMI2_FUNCTION_PREFIX=double_pendulum_", "-o", str(obj), str(source)], check=True)
    symbols = subprocess.run(["nm", "-g", "--defined-only", str(obj)], capture_output=True, text=True).stdout
    assert "double_pendulum_fmi2GetDerivatives" in symbols and " fmi2GetDerivatives" not in symbols


@needs_cc
def test_an_fmu_whose_c_is_in_units_runs_and_ships_one_source(tmp_path, monkeypatch):
    """A long tape's functions go to units compiled side by side (lagrangian.numerics.c_units); the FMU's binary is
    built so, its one source compiles alone into the same binary's behaviour, and the part functions stay hidden."""
    from lagrangian.numerics import c_units, tape

    monkeypatch.setattr(tape, "C_PART", 40)
    lg.codegen.set_cache_dir(tmp_path / "cache")
    try:
        model = models.pendulum_chain(4, m=[0.3, 0.4, 0.5, 0.6], length=0.6, dynamics="recursive")
        start = {"theta_j0": 0.4, "theta_j2": -0.3}
        path = model.to_fmu(tmp_path / "chain.fmu", initial=start)
    finally:
        lg.codegen.set_cache_dir(None)
    assert validate_fmu(str(path)) == []
    folder = Path(fmpy.extract(str(path), str(tmp_path / "unzipped")))
    source = next((folder / "sources").glob("*.c"))
    assert len(c_units.split(source.read_text())) > 2
    names = states(model)
    run = dict(stop_time=1.0, output_interval=0.01, relative_tolerance=1e-12, output=names)
    built_in_units = fmpy.simulate_fmu(str(folder), **run)
    res = model.simulate(1.0, initial={n: start.get(n, 0.0) for n in model.coordinate_names},
                         velocity={n: 0.0 for n in model.coordinate_names}, t_eval=built_in_units["time"],
                         rtol=1e-13, atol=1e-15)
    assert worst(built_in_units, res, names) < 1e-8
    binary = next((folder / "binaries").rglob("*.so"))
    symbols = subprocess.run(["nm", "-D", "--defined-only", str(binary)], capture_output=True, text=True).stdout
    assert "fmi2GetDerivatives" in symbols and "_part_" not in symbols
    cc = lg.codegen.compiler()
    subprocess.run([cc, "-O2", "-shared", "-fPIC", "-o", str(binary), str(source), "-lm"], check=True)
    alone = fmpy.simulate_fmu(str(folder), **run)
    for n in names:
        assert np.allclose(alone[n], built_in_units[n], rtol=0, atol=1e-12)


_RUNNER = """
import json, sys
try:
    import lagrangian
except ImportError:
    pass
else:
    sys.exit("lagrangian is importable here")
import fmpy
out = fmpy.simulate_fmu(sys.argv[1], stop_time=2.0, output_interval=0.02, relative_tolerance=1e-12, output=sys.argv[2:])
print(json.dumps({name: out[name].tolist() for name in out.dtype.names}))
"""


def _python_without_lagrangian(folder: Path) -> list[str]:
    """A Python with FMPy and without lagrangian: a fresh venv with FMPy installed by pip; where pip cannot install
    it, this interpreter without its site directories (-S, so the editable install of lagrangian is not on the path)
    and FMPy's own folder (with its dependencies' folder) on PYTHONPATH."""
    env = folder / "venv"
    try:
        venv.create(env, with_pip=True)
        python = env / "bin" / "python"
        subprocess.run([str(python), "-m", "pip", "install", "-q", f"fmpy=={fmpy.__version__}"], check=True,
                       capture_output=True, timeout=600)
        return [str(python)]
    except (subprocess.SubprocessError, OSError):
        shutil.rmtree(env, ignore_errors=True)
        return [sys.executable, "-S"]


@pytest.mark.slow
@needs_cc
def test_the_fmu_runs_where_lagrangian_is_not_installed(exported, tmp_path):
    model, path = exported["double pendulum"]
    python = _python_without_lagrangian(tmp_path)
    env = {"PATH": "/usr/bin:/bin"}
    if python[-1] == "-S":
        env["PYTHONPATH"] = str(Path(fmpy.__file__).parent.parent)
    copy = tmp_path / "elsewhere" / "double_pendulum.fmu"
    copy.parent.mkdir()
    shutil.copy(path, copy)
    (tmp_path / "run.py").write_text(_RUNNER)
    done = subprocess.run([*python, str(tmp_path / "run.py"), str(copy), *states(model)], capture_output=True,
                          text=True, cwd=copy.parent, env=env, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    out = {k: np.array(v) for k, v in json.loads(done.stdout.splitlines()[-1]).items()}
    res = model.simulate(2.0, initial=START, velocity={"theta_j1": 0, "theta_j2": 0}, t_eval=out["time"], rtol=1e-13,
                         atol=1e-15)
    assert worst(out, res, states(model)) < 1e-8


@pytest.mark.slow
@needs_cc
def test_a_co_simulation_fmu_steps_with_the_dop853_loop(tmp_path):
    """Each communication step is a DOP853 run in C: FMPy's steps of 0.01 s land on Model.simulate's run, with the
    parameter FMPy sets."""
    model = models.double_pendulum()
    path = model.to_fmu(tmp_path / "dp.fmu", kind="co-simulation", initial=START)
    assert validate_fmu(str(path)) == []
    md = fmpy.read_model_description(str(path))
    assert md.modelExchange is None and md.coSimulation.modelIdentifier == "double_pendulum"
    names = states(model)
    run = dict(initial=START, velocity={"theta_j1": 0, "theta_j2": 0}, rtol=1e-13, atol=1e-15)
    for params in ({}, {"g_g": 3.0}):
        out = fmpy.simulate_fmu(str(path), stop_time=5.0, output_interval=0.01, relative_tolerance=1e-12, output=names,
                                start_values=params)
        assert worst(out, model.simulate(5.0, t_eval=out["time"], params=params, **run), names) < 1e-8
    with pytest.raises(Exception, match="not supported"):
        fmpy.simulate_fmu(str(path), fmi_type="ModelExchange")


@pytest.mark.slow
@needs_cc
def test_sources_and_loads_are_inputs_that_fmpy_drives(tmp_path):
    """A source given as a number is an FMI input: FMPy switches it between values at given times (time events of
    its input table), and the run equals Model.simulate run piece by piece, each piece with the source's value as a
    parameter and starting where the last one ended."""
    model = models.loudspeaker(E=0.0)
    path = model.to_fmu(tmp_path / "speaker.fmu")
    assert validate_fmu(str(path)) == []
    variables = {v.name: v for v in fmpy.read_model_description(str(path)).modelVariables}
    assert variables["E_E"].causality == "input" and variables["E_E"].variability == "continuous"
    assert variables["E_E"].unit == "V" and variables["R_Re"].causality == "parameter"
    pieces = [(0.0, 0.005, 0.0), (0.005, 0.012, 2.3), (0.012, 0.02, -1.1)]
    table = np.array([(t, value) for a, b, value in pieces for t in (a, b)], dtype=[("time", float), ("E_E", float)])
    names = states(model)
    out = fmpy.simulate_fmu(str(path), stop_time=0.02, output_interval=1e-4, relative_tolerance=1e-12, output=names,
                            input=table)
    start = dict.fromkeys(model.coordinate_names, 0.0)
    at, rate, ran = dict(start), dict(start), []
    for a, b, value in pieces:
        inside = out["time"][(out["time"] > a + 1e-9) & (out["time"] < b - 1e-9)]
        res = model.simulate((a, b), t_eval=[a, *inside, b], params={"E_E": value}, initial=at, velocity=rate,
                             method="exact")
        at = {n: float(res[n][-1]) for n in at}
        rate = {n: float(res.velocity(n)[-1]) for n in rate}
        ran.append((inside, {n: ours(res, n)[1:-1] for n in names}))
    for n in names:
        peak = max(np.max(np.abs(piece[n])) for _, piece in ran)
        for inside, piece in ran:
            theirs = out[n][np.isin(out["time"], inside)]
            assert np.max(np.abs(theirs - piece[n]), initial=0.0) < 1e-8 * peak


@pytest.mark.slow
@needs_cc
def test_a_co_simulation_fmu_holds_an_input_over_each_step(tmp_path):
    """Co-simulation: the force FMPy sets at a communication point holds over the step, as a force given as a
    number holds over a run (a 0.3 kg mass on a 40 N/m spring pushed by 1.7 N)."""
    msd = lg.Model("msd")
    msd.add("mass", "m", "p", m=0.3)
    msd.add("spring", "k", ("ground", "p"), k=40.0)
    msd.add("damper", "c", ("ground", "p"), c=0.5)
    msd.add("force", "F", "p", F=0)
    path = msd.to_fmu(tmp_path / "msd.fmu", kind="co-simulation")
    assert validate_fmu(str(path)) == []
    held = np.array([(0.0, 1.7), (2.0, 1.7)], dtype=[("time", float), ("F_F", float)])
    out = fmpy.simulate_fmu(str(path), stop_time=2.0, output_interval=0.01, relative_tolerance=1e-12,
                            output=["x_p", "x_p'"], input=held)
    pushed = msd.simulate(2.0, t_eval=out["time"], params={"F_F": 1.7}, initial={"x_p": 0}, velocity={"x_p": 0},
                          method="exact")
    assert worst(out, pushed, ["x_p", "x_p'"]) < 1e-8


@pytest.mark.slow
@needs_cc
def test_a_signal_that_fixes_a_coordinate_stays_a_parameter(tmp_path):
    """In node fluxes a voltage source feeding an inductor enters through its node's flux (its integral), and a
    prescribed motion enters with its rates: neither is an input (the FMU holds their values); a force on the same
    model is."""
    flux = lg.Model("flux", formulation="flux")
    flux.add("voltage_source", "V1", ("n1", "0"), E=2.0)
    flux.add("inductor", "L1", ("n1", "n2"), L=7e-3)  # its current is (λ_n1 − λ_n2)/L: the source's integral
    flux.add("capacitor", "C1", ("n2", "0"), C=2.2e-6)
    flux.add("resistor", "R1", ("n2", "0"), R=100.0)
    moved = lg.Model("moved")
    moved.add("mass", "m", "p", m=0.3)
    moved.add("spring", "k", ("p", "b"), k=40.0)
    moved.add("damper", "c", ("p", "b"), c=0.5)
    moved.add("prescribed_motion", "x0", "b", position=0.1)
    moved.add("force", "F", "p", F=0.2)
    for model, inputs in ((flux, []), (moved, ["F_F"])):
        path = model.to_fmu(tmp_path / f"{model.name}.fmu")
        assert validate_fmu(str(path)) == []
        variables = fmpy.read_model_description(str(path)).modelVariables
        assert [v.name for v in variables if v.causality == "input"] == inputs
    assert "E_V1" in {v.name for v in fmpy.read_model_description(str(tmp_path / "flux.fmu")).modelVariables}
