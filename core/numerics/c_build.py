"""Building compiled code: the C compiler, the on-disk cache (``0700``, refused when others can write to it) and
the libraries built from :mod:`lagrangian.numerics.c_source`, each compiled once per source and compiler.
"""

from __future__ import annotations

import ctypes
import functools
import hashlib
import json
import logging
import os
import shutil
import stat
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any


from ..errors import ModelError
from .c_source import CODEGEN_VERSION, _runtime_source, _Unavailable

_log = logging.getLogger("lagrangian")

#: Flags of every compilation (part of the cache key).
FLAGS = ("-O3", "-ffp-contract=off", "-shared", "-fPIC")
_DIVERGED = 1e30
_settings: dict[str, Any] = {"cache_dir": None, "compiler": None}


# ---------------------------------------------------------------------------
# Where: the cache and the compiler
# ---------------------------------------------------------------------------


def cache_dir() -> Path:
    """The directory of compiled artefacts: :func:`set_cache_dir`'s, else ``$LAGRANGIAN_CACHE_DIR``,
    else ``$XDG_CACHE_HOME/lagrangian``, else ``~/.cache/lagrangian``.  Safe to delete.

    >>> set_cache_dir("/tmp/lagrangian-doc-cache"); str(cache_dir())
    '/tmp/lagrangian-doc-cache'
    >>> set_cache_dir(None)
    """
    if _settings["cache_dir"] is not None:
        return Path(_settings["cache_dir"])
    env = os.environ.get("LAGRANGIAN_CACHE_DIR")
    if env:
        return Path(env).expanduser()
    xdg = os.environ.get("XDG_CACHE_HOME")
    base = Path(xdg).expanduser() if xdg else Path.home() / ".cache"
    return base / "lagrangian"


def _trusted(directory: Path) -> str | None:
    """Why ``directory`` may not hold libraries this process loads (``None``: it may).

    Created ``0700`` when missing.  Refused, as ccache and pip refuse theirs,
    when it is not a directory, is owned by another user, or is writable by
    the group or by everyone: whoever can write there could put a library
    that runs code in this process.
    """
    try:
        directory.mkdir(mode=0o700, parents=True, exist_ok=True)
        info = directory.stat()
    except OSError as exc:
        return f"the cache directory {directory} is not usable ({exc})"
    if not stat.S_ISDIR(info.st_mode):
        return f"the cache path {directory} is not a directory"
    if hasattr(os, "getuid") and info.st_uid != os.getuid():
        return f"the cache directory {directory} belongs to another user (uid {info.st_uid})"
    if info.st_mode & (stat.S_IWGRP | stat.S_IWOTH):
        return f"the cache directory {directory} is writable by others (mode {stat.S_IMODE(info.st_mode):o})"
    return None


def _cache() -> tuple[Path, str | None]:
    """The directory to build in and load from: :func:`cache_dir` when it is trusted, else a private directory
    of this process (made once, ``0700``), with a note saying why."""
    directory = cache_dir()
    why = _trusted(directory)
    if why is None:
        return directory, None
    if _settings.get("private") is None:
        _settings["private"] = tempfile.mkdtemp(prefix="lagrangian-cache-")
    note = f"{why}; compiled code is built in a private directory of this process instead (set LAGRANGIAN_CACHE_DIR " \
           f"to a directory of your own, mode 700)"
    _log.warning(note)
    return Path(_settings["private"]), note


def set_cache_dir(path: str | os.PathLike | None) -> None:
    """Use ``path`` for compiled artefacts from now on (``None``: back to the environment and defaults)."""
    _settings["cache_dir"] = None if path is None else os.fspath(path)


def set_compiler(command: str | None) -> None:
    """Compile with ``command`` (a program name or path) from now on; ``None``: back to the default.

    The default is ``$LAGRANGIAN_CC``, else the first of ``cc``, ``gcc``,
    ``clang`` on the ``PATH``.  A program that does not exist means "no
    compiler": models then run on the NumPy path, with a note.
    """
    _settings["compiler"] = command


def wanted_compiler() -> str | None:
    """The compiler asked for (:func:`set_compiler`, else ``LAGRANGIAN_CC``), found or not."""
    return _settings["compiler"] or os.environ.get("LAGRANGIAN_CC")


def compiler() -> str | None:
    """The full path of the C compiler that would be used, or ``None`` if there is none."""
    chosen = _settings["compiler"] or os.environ.get("LAGRANGIAN_CC")
    if chosen:
        return shutil.which(chosen)
    for name in ("cc", "gcc", "clang"):
        found = shutil.which(name)
        if found:
            return found
    return None


@functools.lru_cache(maxsize=8)
def _compiler_identity(path: str) -> str:
    try:
        out = subprocess.run([path, "--version"], capture_output=True, text=True, timeout=30, check=False)
        return (out.stdout or out.stderr).splitlines()[0] if (out.stdout or out.stderr) else path
    except (OSError, subprocess.SubprocessError):
        return path


# ---------------------------------------------------------------------------
# What: the C source
# ---------------------------------------------------------------------------



def _key(source: str, cc: str) -> str:
    text = "\n".join([CODEGEN_VERSION, _compiler_identity(cc), " ".join(FLAGS), sys.platform, source])
    return hashlib.sha256(text.encode()).hexdigest()[:32]


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _load_cached(directory: Path, key: str) -> ctypes.CDLL | None:
    lib, manifest = directory / f"{key}.so", directory / f"{key}.json"
    try:
        recorded = json.loads(manifest.read_text())["sha256"]
        if _digest(lib) != recorded:
            raise ValueError("digest mismatch")
        return ctypes.CDLL(str(lib))
    except FileNotFoundError:
        return None
    except (OSError, ValueError, KeyError, TypeError) as exc:  # corrupt or half-deleted: rebuild
        _log.info("compiled model cache entry %s is unusable (%s); rebuilding", key, exc)
        return None


def _write_atomic(directory: Path, name: str, data: bytes) -> None:
    fd, tmp = tempfile.mkstemp(dir=directory, prefix=f".{name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.replace(tmp, directory / name)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _start(directory: Path, key: str, source: str, cc: str) -> tuple:
    """Start compiling ``source`` in the background (in a private temporary directory); see :func:`_finish`."""
    work = Path(tempfile.mkdtemp(dir=directory, prefix=".build-"))
    src, out = work / f"{key}.c", work / f"{key}.so"
    src.write_text(source)
    try:
        proc = subprocess.Popen([cc, *FLAGS, "-o", str(out), str(src), "-lm"], stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True)
    except OSError as exc:
        shutil.rmtree(work, ignore_errors=True)
        raise _Unavailable(f"the C compiler {cc} could not be run ({exc})") from None
    return proc, work, key, source


def _finish(directory: Path, job: tuple, cc: str) -> ctypes.CDLL:
    """Wait for a compilation; store the library in the cache (atomically: temporary file, then rename); load it."""
    proc, work, key, source = job
    try:
        try:
            _, err = proc.communicate(timeout=600)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.communicate()
            raise _Unavailable(f"the C compiler {cc} took more than 600 s") from None
        if proc.returncode:
            first = "; ".join(err.strip().splitlines()[:3])
            raise _Unavailable(f"the C compiler {cc} failed (exit {proc.returncode}): {first}")
        data = (work / f"{key}.so").read_bytes()
        _write_atomic(directory, f"{key}.c", source.encode())
        _write_atomic(directory, f"{key}.so", data)
        manifest = {"sha256": hashlib.sha256(data).hexdigest(), "compiler": _compiler_identity(cc), "flags": list(FLAGS),
                    "codegen": CODEGEN_VERSION, "created": time.time()}
        _write_atomic(directory, f"{key}.json", json.dumps(manifest).encode())
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return ctypes.CDLL(str(directory / f"{key}.so"))


def _libraries(directory: Path, wanted: dict[str, tuple[str, str]], cc: str) -> dict[str, tuple[ctypes.CDLL, bool]]:
    """``{name: (library, from_cache)}`` for ``wanted`` ``{name: (key, source)}``: each from the cache, or
    compiled (all the missing ones at once, in parallel)."""
    found = {name: _load_cached(directory, key) for name, (key, _) in wanted.items()}
    missing = [name for name, lib in found.items() if lib is None]
    if missing:
        directory.mkdir(parents=True, exist_ok=True)
        jobs, failure = {}, None
        for name in missing:
            try:
                jobs[name] = _start(directory, *wanted[name], cc)
            except _Unavailable as exc:
                failure = failure or exc
        for name, job in jobs.items():  # finish every job started, even after a failure
            try:
                found[name] = _finish(directory, job, cc)
            except _Unavailable as exc:
                failure = failure or exc
        if failure is not None:
            raise failure
    return {name: (lib, name not in missing) for name, lib in found.items()}


def runtime() -> Path:
    """Build the runtime library (tape interpreter and stepping loops) now if it is not in the cache, and return
    its path — what an installation step or a container image would run once, so that no model ever waits for
    the C compiler unless it asks for native code.

    Raises :class:`~lagrangian.ModelError` with the reason when there is no
    usable C compiler or cache directory.
    """
    cc = compiler()
    if cc is None:
        raise ModelError("no C compiler found (none of cc, gcc, clang on the PATH, or LAGRANGIAN_CC); install one.")
    (directory, _), source = _cache(), _runtime_source()
    key = "runtime-" + _key(source, cc)
    try:
        _libraries(directory, {"runtime": (key, source)}, cc)
    except (_Unavailable, OSError) as exc:
        raise ModelError(f"the runtime library could not be built in {directory}: {exc}") from None
    return directory / f"{key}.so"


#: What ``compile_model`` can build: native code, the tape interpreter, or whichever is ready at once.
