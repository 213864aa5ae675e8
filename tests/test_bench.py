"""The work–precision harness: benchmarks as plugins, measured errors, CSV and charts, the command line.

Expected errors come from closed forms (Verlet's iterates on the oscillator,
Kepler's orbit and its integrals), never from the harness itself.
"""

from __future__ import annotations

import csv
import io
import math
import types
import warnings

import numpy as np
import pytest

import lagrangian as lg
from lagrangian.bench import Benchmark, ProgressBar, benchmarks, work_precision
from lagrangian.cli import main


@pytest.fixture(autouse=True)
def _quiet():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lg.InitialConditionWarning)
        yield


def test_the_shipped_benchmarks():
    shipped = benchmarks()
    assert {"oscillator", "kepler", "duffing", "rlc_ladder", "energy"} <= set(shipped)
    reg = lg.default_registry()
    assert {p.name: p for p in reg.plugins()}["integrators"].benchmarks == list(shipped)[:5]
    for b in shipped.values():
        assert b.exact is not None or b.reference or b.measure == "energy", b.name
        assert b.unavailable(reg) is None, b.name  # the example plugin provides the Duffing's cubic spring
        assert b.steps and b.tolerances
    assert shipped["rlc_ladder"].reference == {"method": "exact"}
    assert shipped["duffing"].requires == ("cubic_spring",)


def test_the_kepler_benchmark_is_kepler():
    # The exact orbit (Kepler's equation) keeps E = −μ/2a = −½ and h = √(μ a (1 − e²)) = √0.75; and the model —
    # a point mass with the inverse-square component — follows it.
    b = benchmarks()["kepler"]
    t = np.linspace(0, b.t_end, 2001)
    dt = 1e-6
    xy, plus, minus = b.exact(t), b.exact(t + dt), b.exact(t - dt)
    x, y = xy["x_planet"], xy["y_planet"]
    vx = (plus["x_planet"] - minus["x_planet"]) / (2 * dt)
    vy = (plus["y_planet"] - minus["y_planet"]) / (2 * dt)
    assert np.max(np.abs((vx**2 + vy**2) / 2 - 1 / np.hypot(x, y) + 0.5)) < 1e-8
    assert np.max(np.abs(x * vy - y * vx - math.sqrt(0.75))) < 1e-8
    model = b.build()
    res = model.simulate(b.t_end, initial=b.initial, velocity=b.velocity, t_eval=t, rtol=1e-12, atol=1e-14)
    assert max(np.max(np.abs(res[n] - xy[n])) for n in xy) < 1e-8
    assert res.energy_drift() < 1e-9


def test_work_precision_measures_errors_against_the_truth():
    # Verlet on x'' = −x from (1, 0): x_k = cos(kθ), cos θ = 1 − h²/2 (its one-step map), so its error on the
    # benchmark's output grid is known in closed form.
    b = benchmarks()["oscillator"]
    h = 2 * math.pi / 64
    wp = work_precision(b, ["DOP853", "verlet", "rk4"], tolerances=[1e-5, 1e-9], steps=[h])
    rows = {(r.method, r.setting): r for r in wp.rows}
    assert [r.status for r in wp.rows] == ["ok"] * 4
    t = np.linspace(0, b.t_end, b.points)
    theta = math.acos(1 - h * h / 2)
    expected = np.max(np.abs(np.cos(np.rint(t / h) * theta) - np.cos(t)))
    verlet = rows["verlet", f"step={h:.3g}"]
    assert verlet.error == pytest.approx(expected, rel=1e-9)
    assert verlet.value == pytest.approx(h) and verlet.kind == "fixed-step" and verlet.nfev > 640
    assert rows["DOP853", "rtol=1e-09"].error < rows["DOP853", "rtol=1e-05"].error < 1e-3
    assert all(r.wall > 0 for r in wp.rows)
    text = wp.table()
    assert "oscillator" in text and "verlet" in text and "rtol=1e-09" in text


def test_refusals_and_failures_are_rows_not_crashes():
    wp = work_precision("rlc_ladder", ["verlet_c", "rk4", "LSODA"], tolerances=[1e-6], steps=[0.1])
    rows = {r.method: r for r in wp.rows}
    assert rows["verlet_c"].status == "refused" and "separable" in rows["verlet_c"].message
    assert rows["rk4"].status == "failed" and "diverged" in rows["rk4"].message  # h|λ| ≈ 1000 ≫ 2.785
    assert rows["LSODA"].status == "ok" and rows["LSODA"].error < 1e-4
    assert math.isnan(rows["verlet_c"].error)


def test_energy_benchmark_bounds():
    # Oscillator over 1000 periods; Verlet's energy error is at most (y/2)²/(1 − (y/2)²), y = hω; the implicit
    # midpoint rule conserves the quadratic energy exactly.
    y = 2 * math.pi / 16
    wp = work_precision("energy", ["verlet", "implicit_midpoint"], steps=[y])
    rows = {r.method: r for r in wp.rows}
    bound = (y / 2) ** 2 / (1 - (y / 2) ** 2)
    assert 0.8 * bound < rows["verlet"].error <= bound * (1 + 1e-9)
    assert rows["implicit_midpoint"].error < 1e-10


def test_csv_and_chart(tmp_path):
    wp = work_precision("oscillator", ["RK45", "verlet"], tolerances=[1e-4, 1e-6], steps=[0.1, 0.05])
    path = wp.write_csv(tmp_path / "wp.csv")
    with path.open() as fh:
        rows = list(csv.DictReader(fh))
    assert [r["method"] for r in rows] == ["RK45", "RK45", "verlet", "verlet"]
    assert rows[0]["setting"] == "rtol" and rows[2]["setting"] == "step"
    assert float(rows[0]["error"]) > float(rows[1]["error"]) > 0
    png = wp.chart(tmp_path / "wp.png")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_progress_bar_writes_one_line():
    stream = io.StringIO()
    bar = ProgressBar(2, stream=stream)
    bar.update("first")
    bar.update("second")
    bar.close()
    text = stream.getvalue()
    assert "1/2 first" in text and "2/2 second" in text and text.rstrip().endswith("2/2 done")
    assert text.count("\n") == 1


def test_cli_bench(tmp_path, capsys):
    status = main(["bench", "oscillator", "--methods", "DOP853,verlet", "--tolerances", "1e-6", "--steps", "0.1",
                   "--out", str(tmp_path)])
    out, err = capsys.readouterr()
    assert status == 0
    assert "DOP853" in out and "verlet" in out and "oscillator.csv" in out
    assert "[" in err and "2/2" in err and "done" in err  # the progress bar
    assert (tmp_path / "oscillator.csv").exists() and (tmp_path / "oscillator.png").exists()


def test_cli_bench_list_and_errors(capsys):
    assert main(["bench", "--list"]) == 0
    out = capsys.readouterr().out
    assert "kepler:" in out and "rlc_ladder:" in out
    assert main(["bench", "keplr"]) == 1
    assert "unknown benchmark 'keplr'. Did you mean 'kepler'?" in capsys.readouterr().err
    assert main(["bench", "oscillator", "--methods", "RK54", "--quiet"]) == 2  # a usage error
    assert "Did you mean 'RK45'?" in capsys.readouterr().err
    assert main(["integrators"]) == 0
    out = capsys.readouterr().out
    assert "verlet  [fixed-step; order 2; symplectic, no first-order coordinates]" in out
    assert "    stages: 1, 2 or 3 (order 2, 4, 6)" in out


def _free_fall():
    m = lg.Model("free fall")
    m.add("mass", "m", "p", m=1)
    m.add("gravity", "g", g=10)
    return m


FREE_FALL = Benchmark("free_fall", "x = −5 t²", _free_fall, t_end=1.0, initial={"x_p": 0.0}, velocity={"x_p": 0.0},
                      exact=lambda t: {"x_p": -5 * t**2}, steps=(0.1,), tolerances=(1e-6,))


def benchmark_plugin(*things):
    plugin = types.ModuleType("bench_plugin")
    plugin.register_benchmarks = lg.hookimpl(lambda register: [register(x) for x in things])
    return plugin


def test_a_plugin_adds_a_benchmark():
    reg = lg.Registry(plugins={"extra": benchmark_plugin(FREE_FALL)})
    assert "free_fall" in benchmarks(reg)
    wp = work_precision("free_fall", ["verlet", "RK45"], registry=reg)
    assert [r.status for r in wp.rows] == ["ok", "ok"]
    assert {r.method: r for r in wp.rows}["verlet"].error < 1e-14  # Verlet is exact for constant acceleration


def test_benchmark_registration_errors_and_unavailable_benchmarks():
    with pytest.raises(lg.PluginError, match="benchmark 'oscillator' is already provided by plugin 'integrators'"):
        lg.Registry(plugins={"dup": benchmark_plugin(Benchmark("oscillator", "again", _free_fall, 1.0))})
    with pytest.raises(lg.PluginError, match="not a lagrangian.bench.Benchmark"):
        lg.Registry(plugins={"bad": benchmark_plugin({"name": "x"})})
    needs = Benchmark("pendulum", "needs joints", _free_fall, 1.0, requires=("no_such_joint",))
    reg = lg.Registry(plugins={"extra": benchmark_plugin(needs)})
    assert "no_such_joint" in needs.unavailable(reg)
    with pytest.raises(lg.ModelError, match="benchmark 'pendulum' cannot run: it needs component kind"):
        work_precision("pendulum", registry=reg)


def _pendulum():
    m = lg.Model("pendulum", dim=2)
    m.add("link", "arm", "arm", points={"bob": (0.7, 0)})
    m.add("revolute", "pin", ("ground", "arm"))
    m.add("mass", "bob", "arm.bob", m=0.3)
    m.add("gravity", "g")
    return m


@pytest.mark.slow
def test_auto_in_a_work_precision_run_keeps_the_energy_of_a_long_conservative_run():
    # a 0.3 kg bob on 0.7 m let go 0.35 rad below the horizontal (θ = 0 is +x, gravity along −y), 250 s: about 130
    # periods of its swing.  Its energy is conserved (no dissipation, no forces, L independent of t), so the
    # largest relative departure of T + V is the integration error; a long run at rtol 1e-4 must keep it near
    # rtol, where RK45's drift grows with every period.
    bench = Benchmark("long_pendulum", "pendulum over 250 s", _pendulum, t_end=250.0, initial={"theta_pin": -0.35},
                      points=501, measure="energy", tolerances=(1e-4,))
    wp = work_precision(bench, ["auto", "RK45"])
    rows = {r.method: r for r in wp.rows}
    assert rows["auto"].status == "ok" and rows["auto"].message.startswith("picked ")
    assert rows["auto"].error < 1e-3
    assert rows["auto"].error < rows["RK45"].error
    assert "ok (picked" in wp.table()


def test_cli_bench_runs_auto_among_its_methods(tmp_path, capsys):
    from lagrangian.cli import main

    assert main(["bench", "oscillator", "--methods", "auto,RK45", "--tolerances", "1e-4,1e-8", "--quiet", "--no-chart",
                 "--out", str(tmp_path)]) == 0
    rows = (tmp_path / "oscillator.csv").read_text().splitlines()
    methods = [r.split(",")[1] for r in rows[1:]]
    assert methods.count("auto") == 2 and methods.count("RK45") == 2
