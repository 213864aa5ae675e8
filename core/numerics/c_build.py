"""Building compiled code: the C compiler, the on-disk cache (``0700``, refused when others can write to it) and
the libraries built from :mod:`lagrangian.numerics.c_source`, each compiled once per source and compiler.

Every library is stored with a manifest (``KEY.json``) recording its SHA-256, and is loaded only from a regular
file (never through a symbolic link) whose digest, computed from the very descriptor it is then loaded from
(``/proc/self/fd`` on Linux), is the one recorded; anything else is built again.  Keys are checked
(:func:`check_key`) before a path is made from them; builds leave nothing behind when they fail; a cache that
cannot be written (read-only, full) gives way to a private directory of the process; and the cache is held
within ``lagrangian.limits.cache_bytes``, least recently used libraries out first (:func:`_evict`).
"""

from __future__ import annotations

import atexit
import contextlib
import ctypes
import errno
import functools
import hashlib
import itertools
import json
import logging
import os
import re
import shutil
import stat
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterable
from pathlib import Path
from typing import Any, NamedTuple

from ..base.limits import limits
from ..errors import ModelError
from .c_source import CODEGEN_VERSION, _runtime_source, _Unavailable
from .c_units import Compilation, split

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
    private = _private()
    note = f"{why}; compiled code is built in a private directory of this process instead (set LAGRANGIAN_CACHE_DIR " \
           f"to a directory of your own, mode 700)"
    _log.warning(note)
    return private, note


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


# ---------------------------------------------------------------------------
# Keys: the only names of files in the cache
# ---------------------------------------------------------------------------

#: A cache key as :func:`_key` makes it (32 hexadecimal digits), after ``runtime-`` for the runtime library or
#: ``fmu-`` for an FMU's binary.  No path is made from a key that does not match: a worker receives its keys with
#: each compiled form, and ``../x`` or ``a/b`` would name files outside the cache.
_KEY_FORMAT = re.compile(r"(?:runtime-|fmu-)?[0-9a-f]{32}")
_KEY_LONGEST = len("runtime-") + 32
#: The files of one cache entry: ``KEY.so`` (the library), ``KEY.c`` (its source), ``KEY.json`` (its manifest).
_ENTRY_FILE = re.compile(r"((?:runtime-|fmu-)?[0-9a-f]{32})\.(so|c|json)")


def check_key(key: object) -> str:
    """``key`` when it is a key of the compiled-code cache (the format :func:`_key` makes), else
    :class:`~lagrangian.ModelError`, raised before any path is made from it.

    >>> check_key("runtime-" + "0" * 32) == "runtime-" + "0" * 32
    True
    >>> check_key("../evil")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    lagrangian.errors.ModelError: the library key '../evil' is not a key of the compiled-code cache (32 hexadecimal ...
    """
    if isinstance(key, str) and len(key) <= _KEY_LONGEST and _KEY_FORMAT.fullmatch(key):
        return key
    shown = repr(key[:40] if isinstance(key, (str, bytes)) else key)
    if len(shown) > 60:
        shown = shown[:57] + "..."
    if isinstance(key, (str, bytes)) and len(key) > 40:
        shown += f"… ({len(key)} characters)"
    raise ModelError(f"the library key {shown} is not a key of the compiled-code cache (32 hexadecimal digits, "
                     f"optionally after 'runtime-' or 'fmu-'), so no file is named after it: the compiled form "
                     f"carrying it was not made by this version of lagrangian, or was altered on its way here; make it "
                     f"again (lagrangian.sweep does) with the version the workers run.")


# ---------------------------------------------------------------------------
# Loading: the file checked is the file loaded
# ---------------------------------------------------------------------------


class _Refused(ValueError):
    """A file of the cache that is not loaded: a symbolic link, not a regular file, another user's, or writable by
    others."""


class Built(NamedTuple):
    """A library of the cache, loaded: ``from_cache`` (else just built or installed), ``path`` (its place in the
    cache), ``data`` (the bytes checked and loaded) and ``note`` (why it is in a private directory, else ``None``)."""

    lib: ctypes.CDLL
    from_cache: bool
    path: Path
    data: bytes
    note: str | None = None


_OPEN_FLAGS = os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_CLOEXEC", 0) | getattr(os, "O_NONBLOCK", 0)
_ALIASES = itertools.count()
#: ``(directory, key)`` of every library this process loaded: never evicted by it.
_IN_USE: set[tuple[str, str]] = set()
#: How old (seconds) a ``.build-*`` directory or ``.*.tmp`` file is when eviction takes it for a crashed build's.
_STALE_SECONDS = 3600.0


@functools.lru_cache(maxsize=1)
def _proc_fd() -> bool:
    """Whether a library can be loaded from an open descriptor, as ``/proc/self/fd/N`` (Linux)."""
    return sys.platform.startswith("linux") and os.path.isdir("/proc/self/fd")


def _open_checked(path: Path, *, strict: bool = True) -> tuple[int, os.stat_result]:
    """A descriptor open on ``path`` and its status, where ``path`` is a regular file — with ``strict``, of this
    user, and not writable by everyone (the group cannot reach it: the cache directory is refused when others can
    use it, see :func:`_trusted`).  A symbolic link is not followed (``O_NOFOLLOW``) but refused, and the checks
    are made on the file opened, so that what is checked is what is read and loaded."""
    try:
        fd = os.open(path, _OPEN_FLAGS)
    except OSError as exc:
        if exc.errno in (errno.ELOOP, errno.EMLINK) and path.is_symlink():
            raise _Refused(f"{path.name} is a symbolic link (the cache loads regular files only)") from None
        raise
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise _Refused(f"{path.name} is not a regular file")
        if strict and hasattr(os, "getuid") and info.st_uid != os.getuid():
            raise _Refused(f"{path.name} belongs to another user (uid {info.st_uid})")
        if strict and info.st_mode & stat.S_IWOTH:
            raise _Refused(f"{path.name} is writable by everyone (mode {stat.S_IMODE(info.st_mode):o})")
        return fd, info
    except BaseException:
        os.close(fd)
        raise


def _read_fd(fd: int, limit: int | None = None) -> bytes:
    chunks, size = [], 0
    while chunk := os.read(fd, 1 << 20):
        chunks.append(chunk)
        size += len(chunk)
        if limit is not None and size > limit:
            raise ValueError(f"larger than {limit} bytes")
    return b"".join(chunks)


def _dlopen(fd: int, path: Path, info: os.stat_result) -> ctypes.CDLL:
    """Load the library open as ``fd`` (checked, as ``path``): from the descriptor on Linux, so that the file loaded
    is the file checked whatever happens to ``path`` meanwhile; elsewhere by ``path``, refused afterwards when that
    no longer names the file checked."""
    if _proc_fd():
        # The dynamic loader returns the library it loaded before under the same name, and descriptor numbers are
        # reused: each load gets a name of its own, the same file through '.' and empty components
        # (/proc/self/fd//7, /proc/self/fd/./7, /proc/self/fd/.//7, ...: a counter in binary).
        hops = "".join("./" if bit == "1" else "/" for bit in format(next(_ALIASES), "b"))
        return ctypes.CDLL(f"/proc/self/fd/{hops}{fd}")
    lib = ctypes.CDLL(str(path))
    now = os.stat(path, follow_symlinks=False)
    if (now.st_dev, now.st_ino) != (info.st_dev, info.st_ino):
        raise _Refused(f"{path.name} was replaced while it was loaded")
    return lib


def _open_library(path: Path, sha256: str) -> tuple[ctypes.CDLL, bytes]:
    """The library at ``path`` loaded, and its bytes, when their SHA-256 is ``sha256`` (else ``ValueError``);
    opened once (see :func:`_open_checked`), its digest computed from the descriptor it is loaded from."""
    fd, info = _open_checked(path)
    try:
        data = _read_fd(fd)
        if hashlib.sha256(data).hexdigest() != sha256:
            raise ValueError("its digest does not match the one recorded when it was stored")
        lib = _dlopen(fd, path, info)
        if os.utime in os.supports_fd:  # used now: the last to be evicted
            with contextlib.suppress(OSError):
                os.utime(fd)
    finally:
        os.close(fd)
    return lib, data


def _recorded(directory: Path, key: str) -> str:
    """The SHA-256 of ``key``'s library, as its manifest ``KEY.json`` recorded it when the library was stored."""
    fd, _ = _open_checked(directory / f"{key}.json")
    try:
        digest = json.loads(_read_fd(fd, limit=1 << 16))["sha256"]
    finally:
        os.close(fd)
    if not isinstance(digest, str):
        raise TypeError("its manifest's sha256 is not text")
    return digest


def _load_cached(directory: Path, key: str) -> Built | None:
    """``key``'s library from ``directory`` when it is there and sound (its digest the one recorded), else ``None``."""
    try:
        lib, data = _open_library(directory / f"{key}.so", _recorded(directory, key))
    except FileNotFoundError:
        return None
    except _Refused as exc:
        _log.warning("compiled-code cache entry %s in %s not loaded: %s; it is built again", key, directory, exc)
        return None
    except (OSError, ValueError, KeyError, TypeError) as exc:  # corrupt or half-deleted: rebuild
        _log.info("compiled model cache entry %s is unusable (%s); rebuilding", key, exc)
        return None
    _IN_USE.add((os.path.abspath(directory), key))
    return Built(lib, True, directory / f"{key}.so", data)


def _private() -> Path:
    """This process's own cache directory (made once, ``0700``, removed at exit)."""
    if _settings.get("private") is None:
        made = tempfile.mkdtemp(prefix="lagrangian-cache-")
        _settings["private"] = made
        owner = os.getpid()
        atexit.register(lambda: os.getpid() == owner and shutil.rmtree(made, ignore_errors=True))
    return Path(_settings["private"])


def _places(directory: Path) -> list[Path]:
    """Where a library may be found: ``directory``, then the private directory when one was made."""
    private = _settings.get("private")
    return [directory] + ([Path(private)] if private and Path(private) != directory else [])


def _find(directory: Path, key: str) -> Built | None:
    for place in _places(directory):
        found = _load_cached(place, key)
        if found is not None:
            return found
    return None


def _present(directory: Path, key: str) -> bool:
    """Whether ``key``'s library is in the cache (or the private directory), not checked: see :func:`_find`."""
    return any((place / f"{key}.so").exists() for place in _places(directory))


# ---------------------------------------------------------------------------
# Storing and building
# ---------------------------------------------------------------------------

#: What writing in the cache fails with when the cache is read-only or full: the private directory then stands in.
_UNWRITABLE = frozenset(code for code in (errno.EACCES, errno.EPERM, errno.EROFS, errno.ENOSPC,
                                          getattr(errno, "EDQUOT", None)) if code is not None)


def _write_atomic(directory: Path, name: str, data: bytes) -> None:
    fd, tmp = tempfile.mkstemp(dir=directory, prefix=f".{name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.replace(tmp, directory / name)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _write_file(path: Path, data: bytes) -> None:
    """Write a new file (a source to compile, in a build's own directory)."""
    with open(path, "xb") as fh:
        fh.write(data)


def _store(directory: Path, key: str, source: str, data: bytes, manifest: dict) -> None:
    """Store a library in the cache: its source, its bytes, then its manifest (each written atomically)."""
    _write_atomic(directory, f"{key}.c", source.encode())
    _write_atomic(directory, f"{key}.so", data)
    _write_atomic(directory, f"{key}.json", json.dumps(manifest).encode())


def _start(directory: Path, key: str, source: str, cc: str) -> tuple:
    """Start compiling ``source`` in the background (in a private temporary directory); see :func:`_finish`."""
    work = Path(tempfile.mkdtemp(dir=directory, prefix=".build-"))
    try:
        src, out = work / f"{key}.c", work / f"{key}.so"
        units = split(source)  # (a long tape's functions: units of bounded size, side by side on the machine's cores)
        job = Compilation(cc, FLAGS, units, work, out, write=_write_file) if len(units) > 1 else None
        if job is None:
            _write_file(src, source.encode())
        try:
            proc = job.start() if job is not None else subprocess.Popen(
                [cc, *FLAGS, "-o", str(out), str(src), "-lm"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        except OSError as exc:
            raise _Unavailable(f"the C compiler {cc} could not be run ({exc})") from None
    except BaseException:  # a full disk, an interrupt...: no build directory is left behind
        shutil.rmtree(work, ignore_errors=True)
        raise
    return proc, work, key, source


def _abandon(job: tuple) -> None:
    """Stop a compilation that will not be finished and remove its directory."""
    proc, work = job[0], job[1]
    try:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    finally:
        shutil.rmtree(work, ignore_errors=True)


def _full(path: Path) -> bool:
    """Whether the file system of ``path`` is (all but) full: what a compiler's failure then means."""
    try:
        return shutil.disk_usage(path).free < 2**20
    except OSError:
        return False


def _finish(directory: Path, job: tuple, cc: str) -> Built:
    """Wait for a compilation; load the library from the build directory (the bytes loaded are the bytes stored);
    store it in the cache (atomically: temporary file, then rename)."""
    proc, work, key, source = job
    try:
        try:
            _, err = proc.communicate(timeout=600)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.communicate()
            raise _Unavailable(f"the C compiler {cc} took more than 600 s") from None
        if proc.returncode:
            if _full(work):
                raise OSError(errno.ENOSPC, f"no space left on the device of {directory} for the compiler's output")
            first = "; ".join(err.strip().splitlines()[:3])
            raise _Unavailable(f"the C compiler {cc} failed (exit {proc.returncode}): {first}")
        out = work / f"{key}.so"
        try:  # (the compiler's output, in this build's own directory: its mode is the umask's)
            fd, info = _open_checked(out, strict=False)
        except _Refused as exc:
            raise _Unavailable(f"the C compiler {cc} did not write a library ({exc})") from None
        try:
            data = _read_fd(fd)
            lib = _dlopen(fd, out, info)
        finally:
            os.close(fd)
        manifest = {"sha256": hashlib.sha256(data).hexdigest(), "compiler": _compiler_identity(cc),
                    "flags": list(FLAGS), "codegen": CODEGEN_VERSION, "created": time.time()}
        _store(directory, key, source, data, manifest)
    except BaseException:
        _abandon(job)
        raise
    finally:
        shutil.rmtree(work, ignore_errors=True)
    _IN_USE.add((os.path.abspath(directory), key))
    return Built(lib, False, directory / f"{key}.so", data)


def _build(directory: Path, wanted: dict[str, tuple[str, str]], cc: str) -> dict[str, Built]:
    """Compile ``wanted`` ``{name: (key, source)}`` into ``directory``, all at once, in parallel; every compilation
    started is finished (or stopped) and its build directory removed, whatever fails."""
    directory.mkdir(mode=0o700, parents=True, exist_ok=True)
    jobs: dict[str, tuple] = {}
    built: dict[str, Built] = {}
    failure: BaseException | None = None
    try:
        for name, (key, source) in wanted.items():
            try:
                jobs[name] = _start(directory, key, source, cc)
            except (_Unavailable, OSError) as exc:
                failure = failure or exc
        while jobs:  # finish every job started, even after a failure
            name, job = next(iter(jobs.items()))
            del jobs[name]  # _finish cleans up after itself
            try:
                built[name] = _finish(directory, job, cc)
            except (_Unavailable, OSError) as exc:
                failure = failure or exc
    finally:
        for job in jobs.values():  # left by an interrupt
            _abandon(job)
    if failure is not None:
        raise failure
    return built


def _fallback_note(directory: Path, exc: OSError) -> str:
    return (f"the cache directory {directory} cannot be written ({exc.strerror or exc}); compiled code is built in a "
            f"private directory of this process instead (free space or grant write access there, or set "
            f"LAGRANGIAN_CACHE_DIR to a writable directory of your own, mode 700)")


def _libraries(directory: Path, wanted: dict[str, tuple[str, str]], cc: str) -> dict[str, Built]:
    """``{name: Built}`` for ``wanted`` ``{name: (key, source)}``: each from the cache, or compiled (all the missing
    ones at once, in parallel) and stored there — in this process's private directory when the cache cannot be
    written (read-only, full), as for a cache others can write (see :func:`_cache`).  Then the cache is held
    within ``lagrangian.limits.cache_bytes`` (see :func:`_evict`)."""
    for key, _ in wanted.values():
        check_key(key)
    found = {name: _find(directory, key) for name, (key, _) in wanted.items()}
    missing = {name: wanted[name] for name, lib in found.items() if lib is None}
    if missing:
        place = directory
        try:
            built = _build(directory, missing, cc)
        except OSError as exc:
            if exc.errno not in _UNWRITABLE or _private() == directory:
                raise
            note = _fallback_note(directory, exc)
            _log.warning(note)
            place = _private()
            built = {name: lib._replace(note=note) for name, lib in _build(place, missing, cc).items()}
        found.update(built)
        _evict(place, keep={wanted[name][0] for name in built})
    return found  # type: ignore[return-value]


def _shipped(key: str, source: str, data: bytes | None) -> ctypes.CDLL:
    """A library built elsewhere and shipped here (``data``, compiled from ``source``; a sweep's worker receives its
    libraries so): this machine's cached copy when it has a sound one, else ``data`` stored in the cache (in the
    private directory when the cache cannot be written) and loaded.  ``key`` is checked first (see
    :func:`check_key`).  Raises ``OSError`` (or ``ValueError``) when it does not load here: another platform's."""
    check_key(key)
    directory, _ = _cache()
    found = _find(directory, key)
    if found is not None:
        return found.lib
    if data is None:
        raise FileNotFoundError(f"{key}.so is not in the cache and no library was shipped")
    digest = hashlib.sha256(data).hexdigest()
    place = directory
    try:
        directory.mkdir(mode=0o700, parents=True, exist_ok=True)
        _store(directory, key, source, data, {"sha256": digest, "shipped": True})
    except OSError as exc:
        if exc.errno not in _UNWRITABLE or _private() == directory:
            raise
        _log.warning(_fallback_note(directory, exc))
        place = _private()
        _store(place, key, source, data, {"sha256": digest, "shipped": True})
    lib, _ = _open_library(place / f"{key}.so", digest)
    _IN_USE.add((os.path.abspath(place), key))
    _evict(place, keep={key})
    return lib


# ---------------------------------------------------------------------------
# Size: least recently used libraries out beyond lagrangian.limits.cache_bytes
# ---------------------------------------------------------------------------


_Files = list[tuple[Path, os.stat_result]]


def _scan(directory: Path) -> tuple[dict[str, _Files], _Files, int]:
    """The cache's entries ``{key: [(file, status), ...]}``, its leftovers (``.build-*`` directories, ``.*.tmp``
    files) and the number of other files in it."""
    entries: dict[str, _Files] = {}
    leftovers, others = [], 0
    with os.scandir(directory) as listing:
        for item in listing:
            try:
                info = item.stat(follow_symlinks=False)
            except OSError:
                continue
            match = _ENTRY_FILE.fullmatch(item.name)
            if match:
                entries.setdefault(match.group(1), []).append((Path(item.path), info))
            elif item.name.startswith(".build-") or (item.name.startswith(".") and item.name.endswith(".tmp")):
                leftovers.append((Path(item.path), info))
            else:
                others += 1
    return entries, leftovers, others


def _remove(path: Path, info: os.stat_result) -> bool:
    try:
        if stat.S_ISDIR(info.st_mode):
            shutil.rmtree(path)
        else:
            path.unlink(missing_ok=True)
        return True
    except OSError:
        return False


def _last_used(files: _Files) -> float:
    """When an entry was last used: its library's modification time (touched at each load), else its newest file's."""
    libraries = [info.st_mtime for path, info in files if path.suffix == ".so"]
    return max(libraries or [info.st_mtime for _, info in files])


def _evict(directory: Path, keep: Iterable[str] = ()) -> None:
    """Hold ``directory`` within ``lagrangian.limits.cache_bytes``: delete the least recently used entries (library,
    source, manifest) until it is under the bound — never those in ``keep`` (just built) nor those this process
    loaded — and the leftovers of builds that crashed more than an hour ago."""
    try:
        entries, leftovers, _ = _scan(directory)
    except OSError:
        return
    now = time.time()
    for path, info in leftovers:
        if now - info.st_mtime > _STALE_SECONDS:
            _remove(path, info)
    bound = limits.cache_bytes
    sizes = {key: sum(info.st_size for _, info in files) for key, files in entries.items()}
    total = sum(sizes.values())
    if total <= bound:
        return
    here = os.path.abspath(directory)
    protected = set(keep) | {key for place, key in _IN_USE if place == here}
    for key in sorted(entries, key=lambda k: _last_used(entries[k])):
        if total <= bound:
            break
        if key in protected:
            continue
        if all([_remove(path, info) for path, info in entries[key]]):
            total -= sizes[key]
            _log.info("compiled-code cache: %s evicted (least recently used; lagrangian.limits.cache_bytes = %d)",
                      key, bound)
    if total > bound:
        _log.info("compiled-code cache %s holds %d bytes, beyond lagrangian.limits.cache_bytes = %d: the rest is in "
                  "use by this process", directory, total, bound)


def cache_usage(directory: str | os.PathLike | None = None) -> dict[str, Any]:
    """What the cache holds (``directory``, default :func:`cache_dir`): ``{"directory", "exists", "libraries",
    "files", "bytes", "bound", "problem"}`` — ``problem`` says why this process would not use it (``None``: it
    would); nothing is created."""
    where = Path(directory) if directory is not None else cache_dir()
    usage = {"directory": where, "exists": where.is_dir(), "libraries": 0, "files": 0, "bytes": 0,
             "bound": limits.cache_bytes, "problem": None}
    if not usage["exists"]:
        return usage
    usage["problem"] = _trusted(where)
    for root, _, names in os.walk(where):
        for name in names:
            with contextlib.suppress(OSError):
                usage["bytes"] += os.lstat(os.path.join(root, name)).st_size
                usage["files"] += 1
    entries = _scan(where)[0]
    usage["libraries"] = sum(any(path.suffix == ".so" for path, _ in files) for files in entries.values())
    return usage


def clear_cache(directory: str | os.PathLike | None = None) -> dict[str, Any]:
    """Delete the cache's entries (``directory``, default :func:`cache_dir`) and the leftovers of crashed builds:
    ``{"directory", "files", "bytes", "left"}`` — files removed, their size, and files left (another process's
    build in progress, or not the cache's).  Libraries loaded by running processes stay loaded there."""
    where = Path(directory) if directory is not None else cache_dir()
    done = {"directory": where, "files": 0, "bytes": 0, "left": 0}
    if not where.is_dir():
        return done
    entries, leftovers, others = _scan(where)
    now = time.time()
    for path, info in [item for files in entries.values() for item in files] + leftovers:
        size, count = info.st_size, 1
        if stat.S_ISDIR(info.st_mode):
            if now - info.st_mtime <= _STALE_SECONDS:  # a build running now
                done["left"] += 1
                continue
            inside = [p for p in path.rglob("*") if p.is_file()]
            size, count = sum(p.lstat().st_size for p in inside), len(inside)
        if _remove(path, info):
            done["files"] += count
            done["bytes"] += size
        else:
            done["left"] += count
    done["left"] += others
    return done


def _runtime_library() -> Built:
    """The runtime library (tape interpreter and stepping loops), loaded: from the cache, else built now."""
    cc = compiler()
    if cc is None:
        raise ModelError("no C compiler found (none of cc, gcc, clang on the PATH, or LAGRANGIAN_CC); install one.")
    (directory, _), source = _cache(), _runtime_source()
    key = "runtime-" + _key(source, cc)
    try:
        return _libraries(directory, {"runtime": (key, source)}, cc)["runtime"]
    except (_Unavailable, OSError) as exc:
        raise ModelError(f"the runtime library could not be built in {directory}: {exc}") from None


def runtime() -> Path:
    """Build the runtime library (tape interpreter and stepping loops) now if it is not in the cache, and return
    its path — what an installation step or a container image would run once, so that no model ever waits for
    the C compiler unless it asks for native code.

    Raises :class:`~lagrangian.ModelError` with the reason when there is no
    usable C compiler or cache directory.
    """
    return _runtime_library().path


#: What ``compile_model`` can build: native code, the tape interpreter, or whichever is ready at once.
