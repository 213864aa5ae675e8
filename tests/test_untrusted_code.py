"""Generated C and its cache hold nothing a user's text or another user can turn into code; shared models
stay correct under threads; large models do not overflow the stack.

Expected values: a serial run of the same model (threads), the closed form
x = x0 cos(ωt) of an oscillator (fallbacks), and the C source itself (names).
"""

import hashlib
import json
import os
import shutil
import subprocess
import threading
import warnings

import numpy as np
import pytest

import lagrangian as lg
from lagrangian import codegen
from lagrangian.numerics import c_build
from lagrangian.simulation import NumericModel

pytestmark = pytest.mark.skipif(codegen.compiler() is None, reason="no C compiler on this machine")


@pytest.fixture(autouse=True)
def private_cache(tmp_path, monkeypatch):
    monkeypatch.setattr(c_build, "_settings", {"cache_dir": str(tmp_path / "cache"), "compiler": None})
    yield tmp_path / "cache"


def oscillator(node="p", k=4.0):
    model = lg.Model("oscillator")
    model.add("mass", "m", node, m=1.0)
    model.add("spring", "k", ("ground", node), k=k)
    return model


def test_names_reach_c_only_inside_one_comment(tmp_path):
    marker = tmp_path / "ran"
    name = f"p */ __attribute__((constructor)) static void x(void) {{ system(\"touch {marker}\"); }} /* \\\n#define q"
    model = oscillator(node=name)
    source = codegen.generate_source(model.numeric())
    first, rest = source.split("\n", 1)
    assert first.startswith("/* ") and first.endswith(" */") and first.count("*/") == 1
    assert "system" not in rest and "\\" not in first
    res = model.simulate(1.0, initial={model.coordinate_names[0]: 1.0}, points=5, compiled=True)
    assert not any("not used" in n for n in res.notes)
    np.testing.assert_allclose(res[model.coordinate_names[0]], np.cos(2 * res.t), atol=1e-6)
    assert not marker.exists()


def test_a_new_cache_directory_is_private(private_cache):
    oscillator().simulate(0.5, initial={"x_p": 1.0}, points=3, compiled=True)
    assert (private_cache.stat().st_mode & 0o777) == 0o700


@pytest.mark.parametrize("mode", [0o777, 0o775, 0o722])
def test_a_cache_others_can_write_is_not_loaded_from(private_cache, mode, caplog):
    private_cache.mkdir(mode=0o700)
    os.chmod(private_cache, mode)
    model = oscillator(k=9.0)
    with caplog.at_level("WARNING", logger="lagrangian"):
        compiled, note = codegen.compile_model(model.numeric())
    assert compiled is not None and "writable by others" in note and "private directory" in note
    assert private_cache not in compiled.path.parents and not list(private_cache.iterdir())
    assert (compiled.path.parent.stat().st_mode & 0o777) == 0o700
    np.testing.assert_allclose(compiled.rhs(0.0, np.array([1.0, 0.0])), [0.0, -9.0])


def test_a_library_without_our_functions_falls_back_with_a_note(private_cache):
    """A valid library with a matching manifest, in the model's place in the cache, that is not the model's."""
    model = oscillator(k=7.3)
    numeric = model.numeric()
    cc = codegen.compiler()
    key = codegen._key(codegen.generate_source(numeric), cc)
    private_cache.mkdir(mode=0o700)
    src = private_cache.parent / "other.c"
    src.write_text("int unrelated(void) { return 0; }\n")
    subprocess.run([cc, "-shared", "-fPIC", "-o", str(private_cache / f"{key}.so"), str(src)], check=True)
    digest = hashlib.sha256((private_cache / f"{key}.so").read_bytes()).hexdigest()
    (private_cache / f"{key}.json").write_text(json.dumps({"sha256": digest}))
    compiled, note = codegen.compile_model(numeric)
    assert compiled is None and "lacks" in note and "NumPy path" in note
    res = model.simulate(1.0, initial={"x_p": 1.0}, velocity={"x_p": 0.0}, points=5, compiled=True)
    np.testing.assert_allclose(res["x_p"], np.cos(np.sqrt(7.3) * res.t), atol=1e-6)


def test_one_model_shared_by_threads_gives_the_serial_results():
    """8 threads × 50 runs of one model (its compiled functions shared): each bitwise equal to the serial run."""
    model = lg.Model("double pendulum", dim=2)
    model.add("rod", "r1", "r1", m=0.3, length=0.7)
    model.add("rod", "r2", "r2", m=0.2, length=0.5)
    model.add("revolute", "j1", ("ground", "r1"))
    model.add("revolute", "j2", ("r1", "r2"), parent_point=(0.7, 0))
    model.add("gravity", "g", g=9.81)
    starts = [0.1 + 0.02 * i for i in range(8)]

    def run(a):
        return model.simulate(2.0, initial={"theta_j1": a, "theta_j2": -a}, velocity={"theta_j1": 0, "theta_j2": 0},
                              points=51, compiled=True)["theta_j2"]

    serial = {a: run(a) for a in starts}
    mismatches, errors = [], []

    def worker(a):
        try:
            for _ in range(50):
                got = run(a)
                if not np.array_equal(got, serial[a]):
                    mismatches.append((a, float(np.max(np.abs(got - serial[a])))))
        except Exception as exc:  # pragma: no cover - reported below
            errors.append(exc)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        threads = [threading.Thread(target=worker, args=(a,)) for a in starts]
        for th in threads:
            th.start()
        for th in threads:
            th.join()
    assert not errors and not mismatches


def test_scratch_beyond_the_stack_size_runs(private_cache):
    """A solve larger than the scratch kept on the stack (2,048 numbers: 45 coordinates' matrix) runs on the heap,
    on the tape interpreter and in native code, and agrees with NumPy."""
    model = lg.Model("chain")
    n = 50
    for i in range(n):
        model.add("mass", f"m{i}", f"p{i}", m=0.3 + 0.01 * i)
        model.add("spring", f"k{i}", ("ground" if i == 0 else f"p{i - 1}", f"p{i}"), k=40.0 + i)
    start = {"x_p0": 0.01}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ref = model.simulate(0.2, initial=start, points=5, compiled=False, rtol=1e-10, atol=1e-12)
        for kind in ("tape", True):
            got = model.simulate(0.2, initial=start, points=5, compiled=kind, rtol=1e-10, atol=1e-12)
            np.testing.assert_allclose(got[f"x_p{n - 1}"], ref[f"x_p{n - 1}"], atol=1e-9)


def test_a_model_name_is_one_title_line_in_the_deck(tmp_path):
    """The model name goes into the deck's title: a newline there must not add an element or a .control block."""
    from lagrangian.spice import netlist, run_transient

    marker = tmp_path / "deck-ran"
    model = lg.Model(f"rc\nR99 in 0 1e-9\n.control\nshell touch {marker}\n.endc\n* ")
    model.add("voltage_source", "V1", ("in", "0"), E=1)
    model.add("resistor", "R1", ("in", "out"), R=1)
    model.add("capacitor", "C1", ("out", "0"), C=1)
    net = netlist(model)
    title, *rest = net.text.splitlines()
    assert title.startswith(".title rc") and "\n" not in title
    assert not any(line.lower().startswith(("r99", ".control", "shell", ".endc")) for line in rest)
    # the deck runs as the circuit it describes: v(C1) = 1 − e^(−t/RC) at t = 1 s (no 1 nΩ short across the source)
    assert run_transient(net).quantities["v(C1)"][-1] == pytest.approx(1 - np.exp(-1), abs=1e-4)
    assert not marker.exists()
