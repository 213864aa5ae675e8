"""The compiled-code cache under faults and hostile contents: failed builds leave nothing behind, a cache that
cannot be written gives way to a private directory (for sweeps as for Model.simulate), a symbolic link or a
library whose digest is not the one recorded is never loaded, keys that are not hex digests name no file, and
the cache stays within ``lagrangian.limits.cache_bytes`` (``lagrangian cache`` shows it, ``--clear`` empties it).

Expected values: the closed form x = cos(√k t) of a unit mass on a spring released from rest at x = 1, and a
marker file that a hostile library's constructor would write if it were ever loaded.
"""

from __future__ import annotations

import dataclasses
import errno
import hashlib
import json
import logging
import os
import shutil
import subprocess
import sys
import tempfile
import time
import types

import numpy as np
import pytest

import lagrangian as lg
from lagrangian import codegen, models
from lagrangian.cli import main
from lagrangian.numerics import c_build, c_units, ensemble, tape
from lagrangian.numerics.ensemble import Library
from lagrangian.simulation import NumericModel
from lagrangian.sweep import design, sweep

pytestmark = pytest.mark.skipif(codegen.compiler() is None, reason="no C compiler on this machine")

START = {"initial": {"x_p": 1.0}, "velocity": {"x_p": 0.0}}


def oscillator(k: float) -> lg.Model:
    model = lg.Model("oscillator")
    model.add("mass", "m", "p", m=1.0)
    model.add("spring", "k", ("ground", "p"), k=k)
    return model


def assert_closed_form(t, x, k, atol=1e-7):
    np.testing.assert_allclose(x, np.cos(np.sqrt(k) * np.asarray(t)), atol=atol)


@pytest.fixture(scope="module")
def runtime_entry(tmp_path_factory):
    """The runtime library's cache entry (.so, .c, .json), built once for the module (about a second)."""
    where = tmp_path_factory.mktemp("runtime")
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(c_build, "_settings", {"cache_dir": str(where), "compiler": None, "private": None})
        path = codegen.runtime()
    return [path.with_suffix(suffix) for suffix in (".so", ".c", ".json")]


@pytest.fixture
def private(tmp_path):
    path = tmp_path / "private"
    path.mkdir(mode=0o700)
    return path


@pytest.fixture(autouse=True)
def cache(tmp_path, private, runtime_entry, monkeypatch):
    """A cache of this test's own, holding the runtime library, and a private directory of its own."""
    path = tmp_path / "cache"
    path.mkdir(mode=0o700)
    for f in runtime_entry:
        shutil.copy2(f, path / f.name)
    monkeypatch.setattr(c_build, "_settings", {"cache_dir": str(path), "compiler": None, "private": str(private)})
    return path


def leftovers(*directories):
    return [p.name for d in directories if d.exists() for p in d.iterdir()
            if p.name.startswith(".build-") or p.name.endswith(".tmp")]


def model_key(model: lg.Model) -> str:
    return codegen._key(codegen.generate_source(model.numeric()), codegen.compiler())


def hostile_library(where, marker) -> bytes:
    """A valid library whose constructor writes ``marker`` when it is loaded (it has ``lg_dims``, so a loader that
    reached it would get as far as calling it)."""
    src = where / "hostile.c"
    src.write_text('#include <stdio.h>\n'
                   f'__attribute__((constructor)) static void mark(void) {{ FILE *f = fopen("{marker}", "w"); '
                   'if (f) fclose(f); }\n'
                   'void lg_dims(int *d) { d[0] = d[1] = d[2] = d[3] = d[4] = -1; }\n')
    out = where / "hostile.so"
    subprocess.run([codegen.compiler(), "-shared", "-fPIC", "-o", str(out), str(src)], check=True)
    return out.read_bytes()


def sweep_plan(k_values=(1.0, 4.0)):
    from lagrangian.analysis.sweep.plan import plan

    return plan(oscillator(1.0), design({"k_k": list(k_values)}), outputs=["x_p"], t_end=1.0, points=5, **START)


# -- 1. a failed build leaves no build directory ----------------------------------------------------------------


def no_space(*args, **kwargs):
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


@pytest.mark.parametrize("stage", ["_write_file", "_write_atomic"])
def test_a_full_disk_leaves_no_build_directory(cache, private, monkeypatch, stage):
    """The source cannot be written (``_write_file``), or the library cannot be stored (``_write_atomic``): in the
    cache and in the private directory tried next; nothing is left in either, and simulate runs on NumPy."""
    monkeypatch.setattr(c_build, stage, no_space)
    model = oscillator(3.0)
    compiled, note = codegen.compile_model(model.numeric())
    assert compiled is None and "No space left on device" in note and "NumPy path" in note
    assert leftovers(cache, private) == []
    assert not list(cache.glob(f"{model_key(model)}.*")) and not list(private.iterdir())
    res = model.simulate(1.0, points=5, compiled=True, **START)
    assert_closed_form(res.t, res["x_p"], 3.0)
    assert leftovers(cache, private) == []


def in_units(monkeypatch) -> lg.Model:
    """A model whose native library is printed in parts of 30 instructions, so built as several units."""
    monkeypatch.setattr(tape, "C_PART", 30)
    model = models.pendulum_chain(3, m=0.3, length=0.7)
    assert len(c_units.split(codegen.generate_source(model.numeric()))) > 2
    return model


@pytest.mark.parametrize("stage", ["_write_file", "_write_atomic"])
def test_a_full_disk_leaves_no_build_directory_of_a_library_in_units(cache, private, monkeypatch, stage):
    model = in_units(monkeypatch)
    monkeypatch.setattr(c_build, stage, no_space)
    compiled, note = codegen.compile_model(model.numeric())
    assert compiled is None and "No space left on device" in note
    assert leftovers(cache, private) == [] and not list(private.iterdir())


def test_a_unit_that_fails_to_compile_stops_the_others_and_is_reported(cache, monkeypatch):
    """The compiler's message is the note, the other compilers are stopped and nothing is left behind; the same
    model builds once its units compile."""
    model = in_units(monkeypatch)
    real = c_build.split
    monkeypatch.setattr(c_build, "split", lambda source: real(source)[:-1] + ["#error a broken unit\n"])
    compiled, note = codegen.compile_model(model.numeric(), "native")
    assert compiled is None and "failed" in note and "a broken unit" in note
    assert leftovers(cache) == []
    monkeypatch.setattr(c_build, "split", real)
    compiled, note = codegen.compile_model(model.numeric(), "native")
    assert compiled.kind == "native" and leftovers(cache) == []


@pytest.mark.slow
@pytest.mark.parametrize("units", [False, True], ids=["one unit", "units"])
def test_an_interrupted_build_stops_and_removes_every_compilation(cache, monkeypatch, units):
    """Two libraries compiled at once (a sweep's model and a runtime not yet cached); an interrupt while the first
    is finished: the second compiler is stopped and both build directories are removed; a library built in units
    stops every compiler of its own."""
    model = in_units(monkeypatch) if units else oscillator(3.5)
    for f in cache.glob("runtime-*"):
        f.unlink()
    started, real_start, real_finish = [], c_build._start, c_build._finish

    def start(*args):
        job = real_start(*args)
        started.append(job)
        return job

    def interrupted(directory, job, cc):  # Ctrl-C while waiting for the first compiler
        proc, wait = job[0], job[0].communicate

        def once(*args, **kwargs):
            proc.communicate = wait
            raise KeyboardInterrupt

        proc.communicate = once
        return real_finish(directory, job, cc)

    monkeypatch.setattr(c_build, "_start", start)
    monkeypatch.setattr(c_build, "_finish", interrupted)
    with pytest.raises(KeyboardInterrupt):
        codegen.compile_model(model.numeric())
    assert len(started) == 2 and all(job[0].poll() is not None for job in started)
    assert isinstance(started[-1][0], c_units.Compilation) == units
    assert leftovers(cache) == [] and not any(job[1].exists() for job in started)


# -- 2. a read-only or full cache: the private directory, for sweeps too ---------------------------------------


def unwritable(cache, code):
    """A stand-in for ``tempfile`` in c_build that fails with ``code`` for files in ``cache`` (as a read-only or
    full file system does) and works elsewhere."""
    inside = lambda where: where is not None and os.path.abspath(where).startswith(str(cache))  # noqa: E731

    def guard(real):
        def call(*args, **kwargs):
            if inside(kwargs.get("dir")):
                raise OSError(code, os.strerror(code), str(kwargs["dir"]))
            return real(*args, **kwargs)
        return call

    return types.SimpleNamespace(mkdtemp=guard(tempfile.mkdtemp), mkstemp=guard(tempfile.mkstemp))


@pytest.fixture(params=["read-only", "full"])
def cannot_write(request, cache, monkeypatch):
    """The cache made read-only (chmod 500, or where that does not bind — running as root — the failures such a
    cache gives), or full."""
    if request.param == "read-only":
        os.chmod(cache, 0o500)
        if os.access(cache, os.W_OK):  # root writes anyway: fail as a read-only directory would
            monkeypatch.setattr(c_build, "tempfile", unwritable(cache, errno.EACCES))
    else:
        monkeypatch.setattr(c_build, "tempfile", unwritable(cache, errno.ENOSPC))
    yield request.param
    os.chmod(cache, 0o700)


@pytest.mark.slow
def test_a_sweep_on_a_cache_that_cannot_be_written_builds_in_the_private_directory(cache, private, cannot_write,
                                                                                   caplog):
    before = sorted(p.name for p in cache.iterdir())
    with caplog.at_level(logging.WARNING, logger="lagrangian"):
        ds = sweep(oscillator(1.0), {"k_k": [1.0, 4.0, 9.0]}, t_end=1.0, points=5, client="serial", **START)
    assert (ds["status"].values == 0).all()
    for i, k in enumerate((1.0, 4.0, 9.0)):
        assert_closed_form(ds["time"].values, ds["x_p"].values[i], k)
    assert sorted(p.name for p in cache.iterdir()) == before  # nothing written in the cache
    assert len(list(private.glob("*.so"))) == 1 and leftovers(cache, private) == []  # the model's (runtime cached)
    assert "cannot be written" in caplog.text and "private directory" in caplog.text
    # Model.simulate: the same fallback (native code, built in the private directory), with the same note
    res = oscillator(2.0).simulate(1.0, points=5, compiled=True, **START)
    assert_closed_form(res.t, res["x_p"], 2.0)
    assert any("native code" in n for n in res.notes) and not any("NumPy" in n for n in res.notes)
    compiled, note = codegen.compile_model(oscillator(2.5).numeric())
    assert compiled.path.parent == private and "cannot be written" in note and "private directory" in note
    assert sorted(p.name for p in cache.iterdir()) == before


def test_a_worker_whose_cache_cannot_be_written_installs_shipped_libraries_privately(tmp_path, cache, private,
                                                                                      monkeypatch):
    p = sweep_plan()
    worker_cache, worker_private = tmp_path / "worker-cache", tmp_path / "worker-private"
    worker_cache.mkdir(mode=0o700)
    worker_private.mkdir(mode=0o700)
    monkeypatch.setattr(c_build, "_settings", {"cache_dir": str(worker_cache), "compiler": None,
                                               "private": str(worker_private)})
    monkeypatch.setattr(c_build, "tempfile", unwritable(worker_cache, errno.EROFS))
    chunk = ensemble.run_chunk(dataclasses.replace(p.form, token="worker"), p.P, p.Y0, p.spec)
    assert (chunk.status == 0).all()
    assert_closed_form(p.spec.t_eval, chunk.data[1, 0], 4.0)
    assert not list(worker_cache.iterdir())
    assert {f.name for f in worker_private.glob("*.so")} == {f"{p.form.model.key}.so", f"{p.form.runtime.key}.so"}


# -- 3. a symbolic link is not followed -------------------------------------------------------------------------


def test_a_symlink_planted_as_a_library_is_not_loaded(tmp_path, cache, caplog):
    """``KEY.so`` a link to a hostile library, with a manifest whose digest is the target's (so a digest check
    through the link would pass): refused, rebuilt in its place, the hostile constructor never run."""
    marker = tmp_path / "hostile-ran"
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    data = hostile_library(elsewhere, marker)
    model = oscillator(5.0)
    key = model_key(model)
    (cache / f"{key}.so").symlink_to(elsewhere / "hostile.so")
    (cache / f"{key}.json").write_text(json.dumps({"sha256": hashlib.sha256(data).hexdigest()}))
    with caplog.at_level(logging.WARNING, logger="lagrangian"):
        compiled, note = codegen.compile_model(model.numeric())
    assert compiled is not None and note is None and not compiled.from_cache
    assert "symbolic link" in caplog.text
    assert not marker.exists()
    assert not (cache / f"{key}.so").is_symlink() and (elsewhere / "hostile.so").read_bytes() == data
    np.testing.assert_allclose(compiled.rhs(0.0, np.array([1.0, 0.0])), [0.0, -5.0])


def test_a_symlink_in_a_workers_cache_is_not_loaded(tmp_path, cache, monkeypatch):
    p = sweep_plan()
    marker = tmp_path / "hostile-ran"
    data = hostile_library(tmp_path, marker)
    worker = tmp_path / "worker-cache"
    worker.mkdir(mode=0o700)
    key = p.form.model.key
    (worker / f"{key}.so").symlink_to(tmp_path / "hostile.so")
    (worker / f"{key}.json").write_text(json.dumps({"sha256": hashlib.sha256(data).hexdigest()}))
    monkeypatch.setattr(c_build, "_settings", {"cache_dir": str(worker), "compiler": None,
                                               "private": str(tmp_path / "private")})
    chunk = ensemble.run_chunk(dataclasses.replace(p.form, token="linked"), p.P, p.Y0, p.spec)
    assert (chunk.status == 0).all() and not marker.exists()
    assert_closed_form(p.spec.t_eval, chunk.data[0, 0], 1.0)
    assert (worker / f"{key}.so").read_bytes() == p.form.model.data and not (worker / f"{key}.so").is_symlink()


def test_libraries_loaded_through_a_reused_descriptor_number_are_each_their_own(tmp_path):
    """Loading from the descriptor checked (``/proc/self/fd/N`` on Linux): descriptor numbers are reused, and the
    dynamic loader hands back the library it loaded before under the same name — each load must get its own file."""
    cc = codegen.compiler()
    for i in range(4):
        (tmp_path / f"v{i}.c").write_text(f"int which(void) {{ return {i}; }}\n")
        subprocess.run([cc, "-shared", "-fPIC", "-o", str(tmp_path / f"v{i}.so"), str(tmp_path / f"v{i}.c")], check=True)
    got = []
    for i in range(4):
        path = tmp_path / f"v{i}.so"
        lib, data = c_build._open_library(path, hashlib.sha256(path.read_bytes()).hexdigest())
        got.append(lib.which())
        assert data == path.read_bytes()
    assert got == [0, 1, 2, 3]
    with pytest.raises(ValueError, match="digest does not match"):
        c_build._open_library(tmp_path / "v0.so", "0" * 64)


def test_a_build_under_a_permissive_umask_is_loaded_and_stored_private(cache):
    """The compiler's output is world-writable under umask 0; it is loaded from the build's own directory all the
    same, and stored readable by this user only."""
    old = os.umask(0)
    try:
        compiled, note = codegen.compile_model(oscillator(9.5).numeric())
    finally:
        os.umask(old)
    assert compiled is not None and note is None and not compiled.from_cache
    assert (compiled.path.stat().st_mode & 0o777) == 0o600


# -- 4. a library whose digest is not the one recorded is rebuilt, not loaded ------------------------------------


def test_a_corrupt_cached_library_is_rebuilt_and_the_run_is_right(tmp_path, cache):
    model = oscillator(6.0)
    first = model.simulate(1.0, points=5, compiled=True, **START)
    key = model_key(model)
    library = cache / f"{key}.so"
    good = library.read_bytes()
    marker = tmp_path / "hostile-ran"
    library.unlink()  # (never overwrite a loaded library in place: its pages are mapped)
    library.write_bytes(hostile_library(tmp_path, marker))  # loadable, but not the bytes recorded
    again = oscillator(6.0)
    res = again.simulate(1.0, points=5, compiled=True, **START)
    assert not marker.exists()
    assert any("built for this model" in n for n in res.notes)
    np.testing.assert_array_equal(res["x_p"], first["x_p"])
    assert_closed_form(res.t, res["x_p"], 6.0)
    library.unlink()
    library.write_bytes(good[: len(good) // 2])  # truncated
    third = oscillator(6.0).simulate(1.0, points=5, compiled=True, **START)
    np.testing.assert_array_equal(third["x_p"], first["x_p"])
    assert library.read_bytes()[:4] == b"\x7fELF" and len(library.read_bytes()) > len(good) // 2


def test_a_worker_checks_the_digest_of_a_library_already_in_its_cache(tmp_path, cache, monkeypatch):
    """A worker used to load ``KEY.so`` unchecked whenever it existed: a hostile library there, without a manifest
    or with another library's, is now replaced by the bytes shipped."""
    p = sweep_plan()
    marker = tmp_path / "hostile-ran"
    hostile = hostile_library(tmp_path, marker)
    worker = tmp_path / "worker-cache"
    worker.mkdir(mode=0o700)
    (worker / f"{p.form.model.key}.so").write_bytes(hostile)
    (worker / f"{p.form.runtime.key}.so").write_bytes(hostile)
    (worker / f"{p.form.runtime.key}.json").write_text(json.dumps({"sha256": "0" * 64}))
    monkeypatch.setattr(c_build, "_settings", {"cache_dir": str(worker), "compiler": None,
                                               "private": str(tmp_path / "private")})
    chunk = ensemble.run_chunk(dataclasses.replace(p.form, token="checked"), p.P, p.Y0, p.spec)
    assert (chunk.status == 0).all() and not marker.exists()
    assert_closed_form(p.spec.t_eval, chunk.data[1, 0], 4.0)
    assert (worker / f"{p.form.model.key}.so").read_bytes() == p.form.model.data
    assert (worker / f"{p.form.runtime.key}.so").read_bytes() == p.form.runtime.data


# -- 5. keys are hex digests before they name files ---------------------------------------------------------------


BAD_KEYS = ["../evil", "a/b", "", "x" * 2**20, "runtime-../../evil", "0" * 31, "A" * 32, "0" * 32 + "/x",
            "fmu-" + "0" * 31 + "\n", None, 42]


@pytest.mark.parametrize("key", BAD_KEYS, ids=lambda k: repr(k)[:20])
def test_a_key_that_is_not_a_hex_digest_names_no_file(tmp_path, cache, key):
    before = sorted(p.name for p in tmp_path.rglob("*"))
    with pytest.raises(lg.ModelError, match="is not a key of the compiled-code cache") as error:
        ensemble._load(Library(key, "int x;", b"not a library"))
    assert len(str(error.value)) < 600  # a megabyte of key is not echoed
    with pytest.raises(lg.ModelError, match="is not a key of the compiled-code cache"):
        c_build._libraries(cache, {"x": (key, "int x;")}, codegen.compiler())
    assert sorted(p.name for p in tmp_path.rglob("*")) == before  # nothing written anywhere
    assert not (tmp_path / "evil.so").exists() and not (tmp_path / "evil.c").exists()


def test_a_form_carrying_a_bad_key_is_refused_by_the_worker(tmp_path, cache):
    p = sweep_plan()
    form = dataclasses.replace(p.form, model=Library("../evil", p.form.model.source, p.form.model.data), token="evil")
    with pytest.raises(lg.ModelError, match="'../evil' is not a key of the compiled-code cache"):
        ensemble.run_chunk(form, p.P, p.Y0, p.spec)
    assert not (tmp_path / "evil.so").exists()


def test_the_keys_the_cache_makes_are_accepted():
    cc = codegen.compiler()
    for key in (c_build._key("int x;", cc), "runtime-" + c_build._key("y", cc), "fmu-" + c_build._key("z", cc)):
        assert c_build.check_key(key) == key


# -- 6. a size bound, least recently used out -----------------------------------------------------------------


def plant(cache, key, size, age):
    """A cache entry of ``size`` bytes in all, last used ``age`` seconds ago (not loaded by this process)."""
    then = time.time() - age
    for suffix, part in ((".so", size - 200), (".c", 100), (".json", 100)):
        path = cache / f"{key}{suffix}"
        path.write_bytes(b"\0" * part)
        os.utime(path, (then, then))


def entry_size(cache, key):
    return sum(p.stat().st_size for p in cache.glob(f"{key}.*"))


def test_the_least_recently_used_entries_go_first(cache):
    old, older, oldest = "c" * 32, "b" * 32, "a" * 32
    plant(cache, oldest, 50_000, 3000)
    plant(cache, older, 50_000, 2000)
    plant(cache, old, 50_000, 1000)
    total = sum(p.stat().st_size for p in cache.iterdir())
    with lg.limits(cache_bytes=total - 1):
        c_build._evict(cache)
    assert not list(cache.glob(f"{oldest}.*")) and entry_size(cache, older) == entry_size(cache, old) == 50_000
    with lg.limits(cache_bytes=total - 100_000):
        c_build._evict(cache)
    assert not list(cache.glob(f"{older}.*")) and entry_size(cache, old) == 50_000
    with lg.limits(cache_bytes=total):  # within the bound: nothing goes
        c_build._evict(cache)
    assert entry_size(cache, old) == 50_000


def test_a_build_beyond_the_bound_evicts_all_but_what_this_process_uses(cache):
    """A tiny bound: after the build, every entry goes but the one just built and those this process loaded (the
    runtime); stale leftovers of crashed builds go too, a build running now stays."""
    plant(cache, "d" * 32, 10_000, 100)
    plant(cache, "fmu-" + "e" * 32, 10_000, 50)
    stale, running = cache / ".build-crashed", cache / ".build-running"
    stale.mkdir()
    running.mkdir()
    os.utime(stale, (time.time() - 7200, time.time() - 7200))
    model = oscillator(7.0)
    with lg.limits(cache_bytes=1):
        res = model.simulate(1.0, points=5, compiled=True, **START)
        assert_closed_form(res.t, res["x_p"], 7.0)
        key = model_key(model)
        assert sorted(p.name for p in cache.iterdir() if not p.name.startswith(".")) == sorted(
            [f"{key}{s}" for s in (".so", ".c", ".json")] + [f.name for f in cache.glob("runtime-*")])
        assert not stale.exists() and running.exists()
        again = oscillator(7.0).simulate(1.0, points=5, compiled=True, **START)  # from the cache still
        assert any("from the cache" in n for n in again.notes)
        np.testing.assert_array_equal(again["x_p"], res["x_p"])


def test_a_library_loaded_is_touched(cache):
    model = oscillator(8.0)
    codegen.compile_model(model.numeric())
    library = cache / f"{model_key(model)}.so"
    then = time.time() - 10_000
    os.utime(library, (then, then))
    compiled, _ = codegen.compile_model(NumericModel(model.eq, model.numeric().values, {}))
    assert compiled.from_cache and library.stat().st_mtime > then + 5000


# -- the command ---------------------------------------------------------------------------------------------------


def test_the_cache_command_shows_and_clears_the_cache(tmp_path, cache, monkeypatch, capsys):
    monkeypatch.setattr(c_build, "_settings", {"cache_dir": None, "compiler": None, "private": None})
    monkeypatch.setenv("LAGRANGIAN_CACHE_DIR", str(cache))
    plant(cache, "f" * 32, 3_000, 10)
    (cache / "notes.txt").write_text("not the cache's")
    files = sorted(cache.iterdir())
    size = sum(p.stat().st_size for p in files)
    assert main(["cache"]) == 0
    out = capsys.readouterr().out
    assert f"directory: {cache}\n" in out and f"files: {len(files)} (2 libraries)" in out
    assert f"size: {size / 2**20:.1f} MiB" in out and "lagrangian.limits.cache_bytes" in out
    assert main(["cache", "--clear"]) == 0
    out = capsys.readouterr().out
    assert f"removed {len(files) - 1} files" in out and "1 files left" in out
    assert [p.name for p in cache.iterdir()] == ["notes.txt"]
    monkeypatch.setenv("LAGRANGIAN_CACHE_DIR", str(tmp_path / "never-made"))
    assert main(["cache"]) == 0 and "(not made yet)" in capsys.readouterr().out
    assert main(["cache", "--clear"]) == 0 and "nothing to clear" in capsys.readouterr().out
    assert not (tmp_path / "never-made").exists()


@pytest.mark.slow
def test_python_dash_m_lagrangian_cache(cache):
    run = subprocess.run([sys.executable, "-m", "lagrangian", "cache"], capture_output=True, text=True, timeout=120,
                         env={**os.environ, "LAGRANGIAN_CACHE_DIR": str(cache)})
    assert run.returncode == 0, run.stderr
    assert f"directory: {cache}" in run.stdout and "files: 3 (1 libraries)" in run.stdout
