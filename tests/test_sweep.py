"""Parameter sweeps: designs, compiled runs against closed forms and Model.simulate, failures, outputs, datasets.

Expected values come from the physics (the matrix exponential of a damped oscillator, x = x₀ cos ωt, energy
conservation) and from an independent path (a loop of Model.simulate).  These run in this process
(client="serial"); tests/test_sweep_dask.py runs the same sweeps on real Dask clusters.
"""

import math

import numpy as np
import pytest
import scipy.linalg
import sympy as sp
from hypothesis import example, given, settings
from hypothesis import strategies as st

import lagrangian as lg
from lagrangian import models
from lagrangian.cli import main
from lagrangian.sweep import (DONE, FAILED, NOT_RUN, LogUniform, Normal, Uniform, describe, design, parse_axis, plot,
                              sweep)

SERIAL = "serial"


def decade(lo, hi):
    return st.floats(np.log10(lo), np.log10(hi)).map(lambda e: float(f"{10 ** e:.4g}"))


def oscillator(m=0.3, k=40.0, c=0.0):
    model = lg.Model("oscillator")
    model.add("mass", "m1", "p", m=m)
    model.add("spring", "k1", ("ground", "p"), k=k)
    if c is not None:
        model.add("damper", "c1", ("ground", "p"), c=c)
    return model


def double_pendulum():
    return models.double_pendulum()


START = {"initial": {"theta_j1": -1.0, "theta_j2": -0.5}, "velocity": {"theta_j1": 0.0, "theta_j2": 0.0}}


# -- designs --------------------------------------------------------------------------------------------------


def test_grid_zip_and_random_designs_have_the_shapes_and_values_asked_for():
    g = design({"a": [1, 2, 3], "b": [10, 20]})
    assert g.dims == ("a", "b") and g.shape == (3, 2) and g.count == 6
    assert sorted(zip(g.table["a"], g.table["b"])) == sorted((a, b) for a in (1, 2, 3) for b in (10, 20))
    z = design({"a": [1, 2, 3], "b": [4, 5, 6]}, kind="zip")
    assert z.dims == ("sample",) and z.table["b"].tolist() == [4, 5, 6]
    r1 = design({"a": Uniform(1, 2), "b": LogUniform(1e-3, 1e3), "c": 7}, samples=500, seed=11)
    r2 = design({"a": Uniform(1, 2), "b": LogUniform(1e-3, 1e3), "c": 7}, samples=500, seed=11)
    assert np.array_equal(r1.table["b"], r2.table["b"]) and r1.fixed == {"c": 7.0} and r1.seed == 11
    assert 1 <= r1.table["a"].min() and r1.table["a"].max() <= 2
    # log-uniform: about as many draws in each of the six decades
    counts = np.histogram(np.log10(r1.table["b"]), bins=6, range=(-3, 3))[0]
    assert counts.min() > 50
    unseeded = design({"a": Uniform(0, 1)}, samples=3)
    assert isinstance(unseeded.seed, int)  # drawn, and recorded so that the draws can be repeated
    assert np.array_equal(design({"a": Uniform(0, 1)}, samples=3, seed=unseeded.seed).table["a"], unseeded.table["a"])


@pytest.mark.parametrize("kind", ["lhs", "sobol"])
@pytest.mark.slow
def test_quasi_random_designs_cover_the_unit_interval_in_strata(kind):
    s = design({"a": Uniform(0, 1), "b": Normal(5, 2)}, kind=kind, samples=64, seed=3)
    if kind == "lhs":  # one draw in each of the 64 strata
        assert sorted(np.floor(s.table["a"] * 64).astype(int).tolist()) == list(range(64))
    assert abs(np.mean(s.table["b"]) - 5) < 0.5


@pytest.mark.parametrize("params, kwargs, words", [
    ({"a": Uniform(0, 1)}, {"kind": "grid"}, "distribution"),
    ({"a": [1, 2], "b": [1, 2, 3]}, {"kind": "zip"}, "one length"),
    ({"a": Uniform(0, 1)}, {}, "samples="),
    ({"a": [1, 2]}, {"samples": 5}, "samples="),
    ({"a": [1, np.nan]}, {}, "finite"),
    ({"a": "fast"}, {}, "numbers"),
    ({"a": [[1, 2]]}, {}, "shape"),
    ({"a": Uniform(0, 1), "b": [1, 2]}, {"samples": 4}, "list"),
    ({}, {}, "mapping"),
])
def test_bad_designs_are_refused_with_what_to_do(params, kwargs, words):
    with pytest.raises(lg.ModelError, match=words):
        design(params, **kwargs)


@pytest.mark.parametrize("args, words", [((2, 1), "low < high"), ((0, 1), "0 < low")])
def test_distributions_check_their_bounds(args, words):
    with pytest.raises(lg.ModelError, match=words):
        (Uniform if "high" in words else LogUniform)(*args)
    with pytest.raises(lg.ModelError, match="std > 0"):
        Normal(1, 0)


def test_axis_text_is_read_as_numbers_never_evaluated():
    assert parse_axis("1:10:4").tolist() == [1, 4, 7, 10]
    assert np.allclose(parse_axis("log:1e-3:1:4"), [1e-3, 1e-2, 1e-1, 1])
    assert parse_axis("1,2,5").tolist() == [1, 2, 5]
    assert parse_axis("normal:4.7e3:80") == Normal(4700.0, 80.0)
    for text in ("__import__('os').system('true')", "1:2", "log:-1:1:3", "1:2:0", "inf", "uniform:1"):
        with pytest.raises(lg.ModelError):
            parse_axis(text)


# -- compiled runs against the physics and against Model.simulate ---------------------------------------------


@settings(max_examples=15)
@given(decade(1e-2, 1e2), st.lists(st.tuples(decade(1e-1, 1e4), decade(1e-4, 1e1)), min_size=1, max_size=4),
       st.floats(-1e-2, 1e-2), st.floats(-1.0, 1.0))
@example(1.0, [(1.0, 1.0), (1e4, 0.1)], 0.0078125, 0.0)  # output times 7.5 periods apart: v sampled near its zeros
@pytest.mark.slow
def test_damped_oscillator_sweeps_match_the_matrix_exponential(m, rows, x0, v0):
    """Mass, stiffnesses and damping drawn over decades: every sample is the exact solution exp(A t) y0, to the
    tolerance times the size of its state, ``√(x² + (v/ω)²)`` (the output times may fall near the zeros of x or v:
    every 7.5 periods of a stiff sample, v is sampled where it vanishes)."""
    k = [r[0] for r in rows]
    c = [r[1] for r in rows]
    model = oscillator(m=m)
    w = math.sqrt(max(k) / m)
    t_end = 3 * 2 * math.pi / math.sqrt(min(k) / m)
    if t_end * w > 2000:  # keep each run to a few thousand steps
        t_end = 2000 / w
    ds = sweep(model, {"k_k1": k, "c_c1": c}, design="zip", initial={"x_p": x0}, velocity={"x_p": v0},
               outputs=["x_p", "x_p'"], t_end=t_end, points=41, rtol=1e-11, atol=1e-15, method="dopri5",
               client=SERIAL)  # (DOP853's estimator, here as in SciPy's, lets heavily damped runs err to 3e-7)
    assert (ds.status == DONE).all()
    for j in range(len(k)):
        A = np.array([[0.0, 1.0], [-k[j] / m, -c[j] / m]])
        exact = np.array([scipy.linalg.expm(A * t) @ [x0, v0] for t in ds.time.values])
        wj = math.sqrt(k[j] / m)
        scale = max(np.max(np.hypot(exact[:, 0], exact[:, 1] / wj)), 1e-12)  # the state's size, in metres
        assert np.max(np.abs(ds.x_p.values[j] - exact[:, 0])) <= 1e-7 * scale + 1e-13  # rtol |x| + atol, widened
        assert np.max(np.abs(ds["x_p'"].values[j] - exact[:, 1])) <= 1e-7 * wj * scale + 1e-13 * w


def test_a_sweep_is_a_loop_of_simulate_to_the_last_bit():
    model = double_pendulum()
    ds = sweep(model, {"m_m1": Uniform(0.5, 2.0), "m_m2": LogUniform(0.1, 10.0)}, samples=6, seed=5,
               outputs=["theta_j1", "theta_j2'", "E"], t_end=5, points=51, client=SERIAL, **START)
    assert ds.attrs["method"] == "DOP853" and ds.attrs["seed"] == 5
    for i in range(6):
        values = {"m_m1": float(ds.m_m1[i]), "m_m2": float(ds.m_m2[i])}
        res = model.simulate(5, params=values, points=51, **START)
        assert np.array_equal(ds.theta_j1.values[i], res["theta_j1"])
        assert np.array_equal(ds["theta_j2'"].values[i], res.velocity("theta_j2"))
        assert np.allclose(ds.E.values[i], res.E, rtol=0, atol=1e-12 * np.max(np.abs(res.E)))
        assert ds.nfev.values[i] == res.nfev
    assert float(ds.energy_drift.max()) < 1e-7  # conservative: the Jacobi integral is kept


def test_initial_values_and_rates_can_be_swept():
    model = oscillator(m=0.3, k=40.0, c=None)
    ds = sweep(model, {"x_p(0)": [0.01, -0.02], "x_p'(0)": [0.0, 0.5]}, design="zip", t_end=0.4, points=21,
               outputs=["x_p", "E"], client=SERIAL)
    w = math.sqrt(40 / 0.3)
    t = ds.time.values
    for j, (x0, v0) in enumerate([(0.01, 0.0), (-0.02, 0.5)]):
        assert np.allclose(ds.x_p.values[j], x0 * np.cos(w * t) + v0 / w * np.sin(w * t), atol=1e-10)
        assert np.allclose(ds.E.values[j], 0.5 * 0.3 * v0**2 + 0.5 * 40 * x0**2, rtol=1e-8)


def test_symbolic_parameters_are_swept_by_their_names():
    k = sp.Symbol("k", positive=True)
    model = oscillator(m=2.0, k=k, c=None)
    ds = sweep(model, {"k": [2.0, 8.0]}, initial={"x_p": 1.0}, velocity={"x_p": 0.0}, t_end=1.0, points=5,
               client=SERIAL)
    for j, kv in enumerate([2.0, 8.0]):
        assert np.allclose(ds.x_p.values[j], np.cos(math.sqrt(kv / 2.0) * ds.time.values), atol=1e-9)
    with pytest.raises(lg.ModelError, match="without values: k"):
        sweep(model, {"m_m1": [1.0, 2.0]}, t_end=1.0, client=SERIAL)


def test_circuit_outputs_are_branch_quantities():
    """Parallel RLC in node fluxes, C charged to V0: v(C1) = λ̇ with C λ̈ + λ̇/R + λ/L = 0 (matrix exponential)."""
    R, L, C, V0 = 4.7e3, 7e-3, 2.2e-9, 3.3
    model = lg.Model("tank", formulation="flux")
    model.add("resistor", "R1", ("a", "0"), R=R)
    model.add("inductor", "L1", ("a", "0"), L=L)
    model.add("capacitor", "C1", ("a", "0"), C=C)
    (flux,) = model.coordinate_names
    period = 2 * np.pi * np.sqrt(L * C)
    ds = sweep(model, {"R_R1": [R, 10 * R]}, outputs=["v(C1)", "i(L1)", "E"], initial={flux: 0.0},
               velocity={flux: V0}, t_end=3 * period, points=31, client=SERIAL)
    assert ds["v(C1)"].attrs["units"] == "V" and ds["i(L1)"].attrs["units"] == "A"
    for j, r in enumerate([R, 10 * R]):
        A = np.array([[0.0, 1.0], [-1 / (L * C), -1 / (r * C)]])
        exact = np.array([scipy.linalg.expm(A * t) @ [0.0, V0] for t in ds.time.values])
        assert np.allclose(ds["v(C1)"].values[j], exact[:, 1], rtol=0, atol=1e-7 * V0)
        assert np.allclose(abs(ds["i(L1)"].values[j]), abs(exact[:, 0] / L), rtol=0, atol=1e-7 * V0 * np.sqrt(C / L))
        assert np.allclose(ds.E.values[j], 0.5 * C * exact[:, 1] ** 2 + 0.5 * exact[:, 0] ** 2 / L, rtol=1e-6)


# -- bad samples and bad requests ---------------------------------------------------------------------------------


def test_a_failing_sample_is_recorded_and_does_not_sink_the_sweep():
    model = oscillator(m=0.3, k=40.0, c=0.1)
    ds = sweep(model, {"k_k1": [40.0, -5.0, 90.0]}, initial={"x_p": 0.01}, velocity={"x_p": 0}, t_end=0.3,
               points=11, client=SERIAL)
    assert ds.status.values.tolist() == [DONE, FAILED, DONE]
    assert "k1" in str(ds.error.values[1]) and "positive" in str(ds.error.values[1])
    assert np.isnan(ds.x_p.values[1]).all() and np.isfinite(ds.x_p.values[[0, 2]]).all()
    budget = sweep(model, {"k_k1": [40.0, 4e6]}, initial={"x_p": 0.01}, velocity={"x_p": 0}, t_end=10, points=11,
                   max_evaluations=20_000, client=SERIAL)
    assert budget.status.values.tolist() == [DONE, FAILED] and "budget" in str(budget.error.values[1])
    assert "1 failed" in describe(budget)


def test_a_sample_whose_geometry_opens_a_loop_is_refused_with_the_reason():
    """A four-bar linkage (crank 1, coupler 3, rocker 2, ground 3) started closed: a longer rocker opens the loop."""
    from lagrangian.plugins.multibody import consistent_initial

    m = lg.Model("four-bar", dim=2)
    for name, length, mass in (("crank", 1.0, 1.0), ("coupler", 3.0, 2.0), ("rocker", 2.0, 1.5)):
        m.add("rod", name, name, m=mass, length=length)
    m.add("revolute", "A", ("ground", "crank"), absolute=True)
    m.add("revolute", "B", ("crank", "coupler"), parent_point=(1.0, 0), absolute=True)
    m.add("revolute", "D", ("ground", "rocker"), parent_point=(3.0, 0), absolute=True)
    m.add("revolute", "C", ("coupler", "rocker"), parent_point=(3.0, 0), child_point=(2.0, 0))
    m.add("gravity", "g")
    q0, v0 = consistent_initial(m, {"theta_A": 0.5, "theta_D": 1.5, "theta_B": 0.3}, {"theta_A": 6.0},
                                independent=["theta_A"])
    ds = sweep(m, {"m_coupler": [2.0, 3.0, 2.0], "child_point_C_0": [2.0, 2.0, 2.5]}, design="zip", initial=q0,
               velocity=v0, t_end=0.5, points=5, client=SERIAL)
    assert ds.status.values.tolist() == [DONE, DONE, FAILED]
    assert "close the kinematic loops" in str(ds.error.values[2])
    res = m.simulate(0.5, initial=q0, velocity=v0, params={"m_coupler": 3.0}, points=5)
    assert np.array_equal(ds.theta_D.values[1], res["theta_D"])


@pytest.mark.parametrize("kwargs, words", [
    ({"params": {"k_nope": [1, 2]}}, "k_nope"),
    ({"params": {"k_k1": [1, 2]}, "method": "Radau"}, "analysis"),
    ({"params": {"k_k1": [1, 2]}, "outputs": ["x_p''"]}, "accelerations"),
    ({"params": {"k_k1": [1, 2]}, "outputs": ["x_p + __import__('os')"]}, "x_p"),
    ({"params": {"k_k1": [1, 2]}, "outputs": ["zeta"]}, "zeta"),
    ({"params": {"k_k1": [1, 2]}, "atol": [1e-9, 1e-9]}, "atol"),
    ({"params": {"k_k1": [1, 2]}, "client": 42}, "client"),
    ({"params": {"k_k1": [1, 2]}, "address": "localhost"}, "address"),
    ({"params": {"k_k1": [1, 2]}, "chunk": 0}, "chunk"),
    ({"params": {"k_k1": [-1, -2]}}, "no sample"),
])
def test_bad_requests_are_refused_before_anything_runs(kwargs, words):
    kwargs.setdefault("client", SERIAL)
    with pytest.raises(lg.ModelError, match=words):
        sweep(oscillator(), initial={"x_p": 0.1}, velocity={"x_p": 0}, t_end=1, **kwargs)


# -- analyses ------------------------------------------------------------------------------------------------------


def resonance(model, values):
    """The peak of the oscillator's mobility |x'/F| over frequency: at ω₀ = √(k/m) for light damping."""
    from lagrangian.frequency import frequency_response

    f = np.linspace(0.5, 3.0, 2001)
    resp = frequency_response(model, f, inputs=["F1"], outputs=["x_p'"], params=values)
    return {"peak_hz": float(f[np.argmax(np.abs(resp["x_p'"]))]), "verdict": "ok"}


def test_any_analysis_can_be_swept_and_its_failures_are_recorded():
    k = sp.Symbol("k", positive=True)
    model = oscillator(m=0.3, k=k, c=0.01)
    model.add("force", "F1", "p", F=0)
    ds = sweep(model, {"k": [10.0, 40.0, -1.0]}, analysis=resonance, client=SERIAL)
    expected = np.sqrt(np.array([10.0, 40.0]) / 0.3) / (2 * np.pi)
    assert np.allclose(ds.peak_hz.values[:2], expected, atol=2e-3)
    assert ds.status.values.tolist() == [DONE, DONE, FAILED] and ds.verdict.values[0] == "ok"
    assert "k" in str(ds.error.values[2])
    assert ds.attrs["analysis"] == "resonance"


# -- datasets, files, charts, interrupts ---------------------------------------------------------------------------


def test_datasets_save_to_netcdf_and_results_export(tmp_path):
    xr = pytest.importorskip("xarray")
    model = oscillator()
    ds = sweep(model, {"k_k1": Uniform(10, 40), "c_c1": LogUniform(1e-3, 1)}, samples=4, seed=2,
               initial={"x_p": 0.01}, velocity={"x_p": 0}, outputs=["x_p", "E"], t_end=1, points=11, client=SERIAL)
    path = tmp_path / "sweep.nc"
    ds.to_netcdf(path)
    back = xr.load_dataset(path)
    assert np.array_equal(back.x_p.values, ds.x_p.values) and back.attrs["seed"] == 2
    assert back.error.values.tolist() == [""] * 4 and back.x_p.attrs["units"] == "m"
    res = model.simulate(1, initial={"x_p": 0.01}, velocity={"x_p": 0}, params={"k_k1": 20.0}, points=11)
    frame, data = res.to_pandas(), res.to_xarray()
    assert np.array_equal(frame["x_p"].values, res["x_p"]) and np.array_equal(data["x_p'"].values, res.velocity("x_p"))
    assert np.array_equal(data.E.values, res.E) and data.attrs["method"] == res.method


def test_charts_of_one_and_two_parameters(tmp_path):
    model = oscillator()
    ds = sweep(model, {"k_k1": [10.0, 20.0, 40.0], "c_c1": [0.01, 0.1]}, initial={"x_p": 0.01},
               velocity={"x_p": 0}, t_end=1, points=11, client=SERIAL)
    ax = plot(ds, "x_p", at="amplitude", path=str(tmp_path / "map.png"))
    assert ax.get_xlabel().startswith("k_k1") and (tmp_path / "map.png").stat().st_size > 1000
    line = sweep(model, {"k_k1": [10.0, 20.0, 40.0]}, initial={"x_p": 0.01}, velocity={"x_p": 0}, t_end=1,
                 points=11, client=SERIAL)
    assert len(plot(line, "x_p", at="max").lines) == 1
    with pytest.raises(lg.ModelError, match="at="):
        plot(line, "x_p", at="median")


def test_interrupting_keeps_what_finished():
    model = oscillator()

    def stop(done, total):
        if done >= 4:
            raise KeyboardInterrupt

    ds = sweep(model, {"k_k1": np.linspace(10, 40, 12)}, initial={"x_p": 0.01}, velocity={"x_p": 0}, t_end=0.5,
               points=11, chunk=2, progress=stop, client=SERIAL)
    assert ds.attrs["interrupted"] == 1
    done = ds.status.values == DONE
    # two tasks of two samples ran; tasks are dealt samples in turn (of six tasks, the first holds 0 and 6)
    assert np.flatnonzero(done).tolist() == [0, 1, 6, 7] and (ds.status.values[~done] == NOT_RUN).all()
    assert np.isfinite(ds.x_p.values[done]).all() and np.isnan(ds.x_p.values[~done]).all()


def test_command_line_sweep_writes_a_dataset_and_a_chart(tmp_path, capsys):
    xr = pytest.importorskip("xarray")
    source = tmp_path / "machine.py"
    source.write_text("import lagrangian as lg\n\ndef build():\n    m = lg.Model('cart')\n"
                      "    m.add('mass', 'cart', 'x', m=0.3)\n    m.add('spring', 'k', ('ground', 'x'), k=4.0)\n"
                      "    m.add('damper', 'c', ('ground', 'x'), c=0.1)\n    return m\n")
    out, chart = tmp_path / "sweep.nc", tmp_path / "sweep.png"
    code = main(["sweep", f"{source}:build", "--param", "k_k=1:10:3", "--param", "c_c=log:1e-3:1:2", "-o", "x_x",
                 "--initial", "x_x=0.1", "--velocity", "x_x=0", "--out", str(out), "--chart", str(chart), "--serial",
                 "--quiet", "--t-end", "2"])
    printed = capsys.readouterr()
    assert code == 0, printed.err
    assert "6 done" in printed.out
    ds = xr.load_dataset(out)
    assert ds.x_x.dims == ("k_k", "c_c", "time") and chart.stat().st_size > 1000
    assert main(["sweep", f"{source}:build", "--param", "k_k=fast", "--serial"]) == 1
    assert "k_k" in capsys.readouterr().err


def bounce(model, values):
    """A ball striking the ground at (0.5, −v) m/s with restitution e."""
    from lagrangian import impulse

    jump = impulse.impact(model, [impulse.ground("ball", e=values["e"])], at={"x_ball": 0.0, "y_ball": 0.0},
                          velocity={"x_ball": 0.5, "y_ball": -values["v"]})
    return {"vy": float(jump.after["y_ball"]), "vx": float(jump.after["x_ball"]), "lost": float(jump.energy_lost)}


def test_impacts_can_be_swept():
    model = lg.Model("ball", dim=2)
    model.add("mass", "ball", "ball", m=0.3)
    model.add("gravity", "g")
    ds = sweep(model, {"e": [0.3, 0.8, 1.0], "v": [0.7, 3.1]}, analysis=bounce, client=SERIAL)
    e, v = np.meshgrid([0.3, 0.8, 1.0], [0.7, 3.1], indexing="ij")
    assert np.allclose(ds.vy.values, e * v, rtol=1e-12) and np.allclose(ds.vx.values, 0.5, rtol=1e-12)
    assert np.allclose(ds.lost.values, 0.5 * 0.3 * v**2 * (1 - e**2), rtol=1e-9, atol=1e-15)


@settings(max_examples=5)
@given(decade(1.0, 1e3), decade(1e-4, 1e-1), decade(1e-9, 1e-5))
def test_frequency_responses_can_be_swept(R, L, C):
    """Series RLC driven by V1: v(C1)/V1 = 1 / (1 − ω²LC + jωRC) on every sample."""
    from lagrangian.sweep import response

    r = sp.Symbol("r", positive=True)
    model = lg.Model("series rlc")
    model.add("voltage_source", "V1", ("in", "0"), E=0)
    model.add("resistor", "R1", ("in", "a"), R=r)
    model.add("inductor", "L1", ("a", "b"), L=L)
    model.add("capacitor", "C1", ("b", "0"), C=C)
    f0 = 1 / (2 * np.pi * np.sqrt(L * C))
    f = np.geomspace(f0 / 10, f0 * 10, 9)
    ds = sweep(model, {"r": [R, 3 * R]}, analysis=response(f, inputs=["V1"], outputs=["v(C1)"]), client=SERIAL)
    assert ds["mag(v(C1))"].dims == ("r", "frequency") and ds["mag(v(C1))"].attrs["units"] == "V/V"
    w = 2 * np.pi * f
    for j, rj in enumerate([R, 3 * R]):
        H = 1 / (1 - w**2 * L * C + 1j * w * rj * C)
        assert np.allclose(ds["mag(v(C1))"].values[j], np.abs(H), rtol=1e-9)
        assert np.allclose(ds["phase(v(C1))"].values[j], np.degrees(np.angle(H)), atol=1e-7)


def test_a_shipped_library_that_does_not_load_here_is_built_from_its_source(tmp_path):
    """As on a worker of another platform: the bytes shipped are not a library here, so the C source shipped
    with them is compiled on the spot, and the samples are the same."""
    import dataclasses

    from lagrangian import codegen
    from lagrangian.analysis.sweep.plan import plan
    from lagrangian.numerics.ensemble import Library, run_chunk

    model = double_pendulum()
    samples = design({"m_m2": [0.5, 2.0]})
    p = plan(model, samples, outputs=["theta_j1"], t_end=2, points=5, **START)
    reference = run_chunk(p.form, p.P, p.Y0, p.spec)
    broken = dataclasses.replace(p.form, model=Library(p.form.model.key, p.form.model.source, b"not a library"),
                                 token="another")
    codegen.set_cache_dir(tmp_path)
    try:
        again = run_chunk(broken, p.P, p.Y0, p.spec)
    finally:
        codegen.set_cache_dir(None)
    assert (again.status == 0).all() and np.array_equal(again.data, reference.data)
    assert any(f.suffix == ".so" and f.stat().st_size > 1000 for f in tmp_path.iterdir())


@settings(max_examples=60)
@given(st.integers(1, 5000), st.integers(1, 64), st.integers(1, 3000))
def test_tasks_deal_every_sample_once_in_turn_within_their_size(count, tasks, cap):
    """Cutting a sweep into tasks: every sample in exactly one task, none larger than the cap, about the number of
    tasks asked for when the cap allows, and samples dealt in turn (neighbours of a grid, which often cost alike,
    go to different tasks)."""
    from lagrangian.analysis.sweep import _blocks, _chunk_size

    indices = np.arange(count) * 3 + 7  # the samples not refused: any increasing indices
    size = _chunk_size(count, tasks, None, cap)
    blocks = _blocks(indices, size)
    assert sorted(np.concatenate(blocks).tolist()) == indices.tolist()
    assert all(1 <= len(b) <= size <= cap for b in blocks)
    assert len(blocks) == math.ceil(count / size)
    if count >= tasks and math.ceil(count / tasks) <= cap:
        assert len(blocks) <= tasks
    if len(blocks) > 1:
        assert blocks[1][0] == indices[1]
    if len(blocks[0]) > 1:
        assert blocks[0][1] == indices[len(blocks)]
