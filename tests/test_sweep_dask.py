"""Sweeps on real Dask clusters: a scheduler and two worker processes started from the command line, and the
local default; one worker is killed mid-sweep, and every sample must still be there, equal to a serial run."""

import json
import os
import signal
import subprocess
import sys
import time

import dask
import numpy as np
import pytest

import lagrangian as lg
from lagrangian import models
from lagrangian.sweep import DONE, Uniform, local_client, sweep

distributed = pytest.importorskip("distributed")


def double_pendulum():
    return models.double_pendulum()


# Long enough runs (about 10 ms each, two samples per task) that a worker is busy when it is killed.
RUN = dict(params={"m_m1": Uniform(0.5, 2.0), "m_m2": Uniform(0.5, 2.0)}, samples=60, seed=7,
           initial={"theta_j1": -1.0, "theta_j2": -0.5}, velocity={"theta_j1": 0.0, "theta_j2": 0.0},
           outputs=["theta_j1", "E"], t_end=200.0, points=101, chunk=2, progress=False)


@pytest.fixture(scope="module")
def serial():
    return sweep(double_pendulum(), client="serial", **RUN)


def killer(pids):
    """A progress callable that kills the worker process ``pids[1]`` when the first task has come back."""
    state = {"killed": False}

    def progress(done, total):
        if not state["killed"]:
            os.kill(pids[1], signal.SIGKILL)
            state["killed"] = True

    return progress, state


def same(ds, reference):
    assert (ds.status == DONE).all(), ds.error.values
    assert np.array_equal(ds.m_m1.values, reference.m_m1.values)
    assert np.array_equal(ds.theta_j1.values, reference.theta_j1.values)
    assert np.array_equal(ds.E.values, reference.E.values)


def test_a_cluster_by_address_loses_no_sample_when_a_worker_dies(tmp_path, serial):
    info = tmp_path / "scheduler.json"
    python = [sys.executable, "-m", "dask"]
    quiet = {"stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL}
    procs = [subprocess.Popen([*python, "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                               "--scheduler-file", str(info)], **quiet)]
    try:
        deadline = time.time() + 60
        while not info.exists() and time.time() < deadline:
            time.sleep(0.1)
        address = json.loads(info.read_text())["address"]
        caches = [tmp_path / f"cache{k}" for k in range(2)]  # empty: as on other machines, nothing built yet
        for k, cache in enumerate(caches):
            cache.mkdir(mode=0o700)
            procs.append(subprocess.Popen([*python, "worker", address, "--nthreads", "1", "--no-nanny",
                                           "--no-dashboard", "--name", f"w{k}"], **quiet,
                                          env={**os.environ, "LAGRANGIAN_CACHE_DIR": str(cache)}))
        with distributed.Client(address, timeout="30s") as client:
            client.wait_for_workers(2, timeout=60)
            pids = sorted(client.run(os.getpid).values())
        progress, state = killer(pids)
        ds = sweep(double_pendulum(), address=address, client=None, **{**RUN, "progress": progress})
        assert state["killed"]
        deadline = time.time() + 10
        while time.time() < deadline and all(p.poll() is None for p in procs[1:]):
            time.sleep(0.1)
        assert any(p.poll() is not None for p in procs[1:])  # the worker is gone: the other one did its work
        assert ds.attrs["workers"] == 2
        same(ds, serial)
        # the workers loaded the libraries shipped with the compiled form (the one killed may not have got to it),
        # and none compiled one
        manifests = [json.loads(p.read_text()) for cache in caches for p in cache.glob("*.json")]
        assert manifests and all(m.get("shipped") for m in manifests)
        assert max(len(list(cache.glob("*.so"))) for cache in caches) == 2
    finally:
        for p in procs:
            p.kill()
            p.wait()


def test_the_local_default_loses_no_sample_when_a_worker_dies(serial):
    client = local_client()
    client.wait_for_workers(1, timeout=60)
    # its workers run without Dask's statistical profiler, which would take CPU from the samples
    assert set(client.run(lambda: dask.config.get("distributed.worker.profile.enabled")).values()) == {False}
    pids = sorted(client.run(os.getpid).values())
    if len(pids) < 2:
        pytest.skip("one core: the local cluster has one worker")
    progress, state = killer(pids)
    ds = sweep(double_pendulum(), **{**RUN, "progress": progress})
    assert state["killed"]
    same(ds, serial)
    again = sweep(double_pendulum(), **RUN)  # the nanny restarted the worker: the cluster is whole again
    same(again, serial)


def test_the_readme_sweep_runs_as_written(tmp_path, monkeypatch):
    """The README's sweep block, on the local default cluster: a 50 × 20 grid and 10,000 random samples."""
    import re
    from pathlib import Path

    readme = (Path(__file__).resolve().parents[1] / "README.md").read_text()
    block = next(b for b in re.findall(r"```python\n(.*?)```", readme, re.S) if "from lagrangian.sweep" in b)
    monkeypatch.chdir(tmp_path)
    namespace = {"__name__": "__main__"}
    exec(block, namespace)
    ds = namespace["ds"]
    assert ds.sizes["sample"] == 10_000 and (ds.status == DONE).all()
    # x = x₀ e^(−ζωt)(cos ω_d t + ζ/√(1−ζ²) sin ω_d t): the closed form of every sample, at the end
    k, c, x0 = ds.k_k1.values, ds.c_c1.values, ds["x_p(0)"].values
    w, z = np.sqrt(k / 0.3), c / (2 * np.sqrt(k * 0.3))
    wd, t = w * np.sqrt(1 - z**2), ds.time.values[-1]
    exact = x0 * np.exp(-z * w * t) * (np.cos(wd * t) + z / np.sqrt(1 - z**2) * np.sin(wd * t))
    assert np.max(np.abs(ds.x_p.values[:, -1] - exact)) < 1e-8 * 0.02
    assert (tmp_path / "map.png").stat().st_size > 1000 and (tmp_path / "sweep.nc").exists()


def against_ngspice(model, values):
    from lagrangian.circuits.compare import compare_with_ngspice

    cmp = compare_with_ngspice(model, 2e-3, params=values, initial={"q_L1": 2.2e-6 * 3.3}, velocity={"q_L1": 0.0})
    return {"worst_rel": cmp.worst_rel}


def test_ngspice_comparisons_run_on_the_workers():
    """A series RLC discharging its 2.2 µF capacitor from 3.3 V, for three resistances: ngspice (in each worker
    process) agrees with the exact solution to its own accuracy."""
    import sympy as sp

    R = sp.Symbol("R", positive=True)
    model = lg.Model("rlc")
    model.add("resistor", "R1", ("a", "b"), R=R)
    model.add("inductor", "L1", ("b", "0"), L=7e-3)
    model.add("capacitor", "C1", ("a", "0"), C=2.2e-6)
    ds = sweep(model, {"R": [10.0, 47.0, 220.0]}, analysis=against_ngspice, chunk=1)
    assert (ds.status == DONE).all(), ds.error.values
    assert float(ds.worst_rel.max()) < 1e-4


def test_interrupting_a_distributed_sweep_keeps_what_finished(serial):
    from lagrangian.sweep import NOT_RUN

    def stop(done, total):
        if done >= 10:
            raise KeyboardInterrupt

    ds = sweep(double_pendulum(), **{**RUN, "progress": stop})
    assert ds.attrs["interrupted"] == 1
    finished = ds.status.values == DONE
    assert 10 <= finished.sum() < 60 and set(ds.status.values[~finished]) == {NOT_RUN}
    assert np.array_equal(ds.theta_j1.values[finished], serial.theta_j1.values[finished])
    assert np.isnan(ds.theta_j1.values[~finished]).all()
    again = sweep(double_pendulum(), **RUN)  # the cluster is free again: nothing of the cancelled tasks is left
    same(again, serial)


def test_a_script_without_the_main_guard_is_told_what_to_do(tmp_path):
    script = tmp_path / "noguard.py"
    script.write_text("import lagrangian as lg\nfrom lagrangian.sweep import sweep\nm = lg.Model('osc')\n"
                      "m.add('mass', 'm1', 'p', m=0.3)\nm.add('spring', 'k1', ('ground', 'p'), k=40)\n"
                      "sweep(m, {'k_k1': [1.0, 2.0]}, initial={'x_p': 0.1}, velocity={'x_p': 0})\n")
    proc = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert proc.returncode == 1
    last = proc.stderr.strip().splitlines()[-1]
    assert last.startswith("lagrangian.errors.ModelError") and 'if __name__ == "__main__":' in last


def final_angle(model, values):
    res = model.simulate(1.0, params=values, initial={"theta_j1": 0.4, "theta_j2": 0.0},
                         velocity={"theta_j1": 0.0, "theta_j2": 0.0}, rtol=1e-10, atol=1e-12, points=2)
    return {"theta_end": float(res["theta_j1"][-1])}


def test_a_model_simulated_here_is_swept_with_an_analysis_on_the_cluster():
    """Once simulated, a model holds compiled code (ctypes pointers); it still travels to the workers (rebuilt there
    from the cache, never pickled as machine code), and their analysis equals this process's."""
    model = models.double_pendulum(0.3, 0.2)
    model.simulate(0.1, initial={"theta_j1": 0.4}, velocity={"theta_j1": 0.0})  # now it holds compiled code
    values = {"m_m1": [0.3, 0.7, 1.9]}
    ds = sweep(model, values, analysis=final_angle, chunk=1, progress=False)
    assert (ds.status == DONE).all(), ds.error.values
    here = [final_angle(model, {"m_m1": m})["theta_end"] for m in values["m_m1"]]
    assert np.allclose(ds.theta_end.values, here, rtol=1e-12, atol=1e-14)
