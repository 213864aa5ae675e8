"""Running blocks of samples on Dask: a local process pool by default, or any ``distributed`` cluster.

Without ``client=`` or ``address=``, a sweep runs on a local cluster of one
single-threaded worker process per core (:func:`local_client`), started on
first use (about a second) and kept for the rest of the process, so later
sweeps start at once.  ``client=`` takes a :class:`distributed.Client`;
``address="tcp://host:8786"`` connects to a running scheduler (``dask
scheduler`` and ``dask worker`` on the cluster's machines); ``client="serial"``
runs every block here, in order, without Dask (for debugging, and as the
reference a distributed run is checked against).

What every block needs (the compiled form, or the model) is sent to every
worker once (:meth:`distributed.Client.scatter` with ``broadcast=True``);
each block is then one task.  Dask reschedules the tasks of a worker that
is lost, so no sample is lost with it; a task that keeps killing its
workers is recorded as failed with Dask's message.  Ctrl-C cancels what has
not finished and keeps what has.

Like every program that starts worker processes, a script that runs a sweep
on the local default must start it under ``if __name__ == "__main__":``
(the worker processes import the script's module again); without the guard
the cluster cannot start, and the sweep stops with an error that says why.
"""

from __future__ import annotations

import atexit
import contextlib
import logging
import math
import os
import sys
import threading
import time
import uuid
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from concurrent.futures import CancelledError
from typing import Any

from ...errors import ModelError

__all__ = ["SERIAL", "Outcome", "check_address", "connected", "execute", "local_client", "local_cluster", "shutdown", "workers"]

#: ``client=SERIAL`` runs every block in this process, in order, without Dask.
SERIAL = "serial"

_LOCAL: dict[str, Any] = {}
#: Dask's settings for the local cluster: no statistical profiler (a thread in each worker that samples every
#: thread's stack 100 times a second, for the dashboard's profile page), the system monitor every 2 s (not 0.5 s),
#: the event loops' health check every 200 ms (not 20 ms) and the memory limits' every 0.5 s (not 0.1 s).  What they
#: take runs beside the samples on the same cores: idle, the cluster of two workers took 6.7 % of a core with the
#: first two settings alone and 1.5 % with all four; a double pendulum's 10,000 samples ran 3 %, then 4 % faster.
_QUIET = {"distributed.worker.profile.enabled": False, "distributed.admin.system-monitor.interval": "2s",
          "distributed.admin.tick.interval": "200ms", "distributed.worker.memory.monitor-interval": "500ms"}
_LOCAL_LOCK = threading.Lock()


def _cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not on Linux
        return os.cpu_count() or 1


def local_cluster(workers: int | None = None):
    """A new local Dask cluster of ``workers`` single-threaded worker processes (default: one per core), with the
    settings of :data:`_QUIET`; the caller closes it.  What :func:`local_client` starts, and what a user starts to
    run the same sweeps on fewer cores."""
    import dask  # imported when used: 0.3 s that other commands need not pay
    from distributed import LocalCluster

    try:
        with dask.config.set(_QUIET):  # the workers take the configuration they start with
            return LocalCluster(n_workers=workers or _cores(), threads_per_worker=1, processes=True,
                                dashboard_address=":0", silence_logs=logging.ERROR)
    except (RuntimeError, OSError) as exc:  # distributed's own words are "Nanny failed to start."
        raise ModelError(
            f"sweep: the local Dask cluster could not start its worker processes ({exc}). The usual cause: the "
            f"script runs the sweep when it is imported, and worker processes import it again; put the sweep "
            f"under `if __name__ == \"__main__\":`, as every program that starts worker processes must (or "
            f"run it here with client=\"serial\").") from None


def local_client():
    """The client of this process's local Dask cluster (:func:`local_cluster`: one single-threaded worker process
    per core), started on first use and closed when the process exits (or by :func:`shutdown`)."""
    from distributed import Client

    with _LOCAL_LOCK:
        client = _LOCAL.get("client")
        if client is not None and client.status == "running":
            return client
        cluster = local_cluster()
        _LOCAL.update(cluster=cluster, client=Client(cluster, set_as_default=False))
        return _LOCAL["client"]


def shutdown() -> None:
    """Close the local cluster of :func:`local_client`, if one was started (the next sweep starts another)."""
    with _LOCAL_LOCK:
        client, cluster = _LOCAL.pop("client", None), _LOCAL.pop("cluster", None)
        if client is not None:
            client.close()
        if cluster is not None:
            cluster.close()


atexit.register(shutdown)


def workers(client) -> int:
    """How many workers ``client``'s cluster has now (1 for :data:`SERIAL`)."""
    if client == SERIAL:
        return 1
    return len(client.scheduler_info().get("workers", {}))


@dataclass
class Outcome:
    """What came back: ``results`` by block index, ``failures`` (block index → message) for blocks whose task
    failed as a whole, whether the run was ``interrupted``, how many ``workers`` ran it and the wall time."""

    results: dict[int, Any] = field(default_factory=dict)
    failures: dict[int, str] = field(default_factory=dict)
    interrupted: bool = False
    workers: int = 1
    seconds: float = 0.0


class _Progress:
    """``sweep: 3,400/10,000 samples (34 %) · 1,230/s · 5 s left`` on standard error, or a callable's calls."""

    def __init__(self, progress: Any, total: int, label: str):
        if progress is None:
            progress = sys.stderr.isatty()
        self.call = progress if callable(progress) else None
        self.show = bool(progress) and self.call is None
        self.total, self.done, self.label, self.start, self.last = total, 0, label, time.perf_counter(), 0.0

    def add(self, count: int) -> None:
        self.done += count
        if self.call is not None:
            self.call(self.done, self.total)
            return
        now = time.perf_counter()
        if self.show and (now - self.last > 0.2 or self.done == self.total):
            self.last = now
            rate = self.done / max(now - self.start, 1e-9)
            left = (self.total - self.done) / rate if rate > 0 else math.inf
            sys.stderr.write(f"\r{self.label}: {self.done:,}/{self.total:,} samples ({100 * self.done / max(self.total, 1):.0f} %) "
                             f"· {rate:,.0f}/s · {left:.0f} s left   ")
            sys.stderr.flush()

    def end(self) -> None:
        if self.show:
            sys.stderr.write("\n")
            sys.stderr.flush()


#: The schemes of the communication backends ``distributed`` ships (``distributed.comm.registry``): TCP, TLS, UCX,
#: WebSockets, and a scheduler in this process (``inproc``); a backend another package registers is taken too.
SCHEMES = ("tcp", "tls", "ucx", "ws", "wss", "inproc")
#: The forms of a scheduler's address, as a refusal lists them.
ADDRESS_FORMS = ("'tcp://host:port' (also tls://, ucx://, ws://, wss://), 'inproc://...' (a scheduler in this "
                 "process) or 'host:port' (TCP)")


def check_address(address: Any) -> str:
    """``address``, a Dask scheduler's address in a form ``distributed`` connects to — ``scheme://host:port`` with a
    scheme of its communication backends, ``inproc://...``, or ``host:port`` (TCP) — or a :class:`ModelError`
    naming it and the accepted forms (``distributed`` itself would raise its own ``ValueError``, or try to resolve
    the text as a host name).

    >>> check_address("tcp://10.0.0.5:8786"), check_address("localhost:8786"), check_address("tcp://[::1]:8786")
    ('tcp://10.0.0.5:8786', 'localhost:8786', 'tcp://[::1]:8786')
    >>> check_address("file:///x")
    Traceback (most recent call last):
    ...
    lagrangian.errors.ModelError: sweep: address='file:///x' is not a Dask scheduler's address (its scheme 'file' is none of distributed's: inproc, tcp, ...); give 'tcp://host:port' (also tls://, ...) or 'host:port' (TCP), such as 'tcp://10.0.0.5:8786'.
    """
    def refuse(why: str) -> ModelError:
        return ModelError(f"sweep: address={address!r:.80} is not a Dask scheduler's address ({why}); give "
                          f"{ADDRESS_FORMS}, such as 'tcp://10.0.0.5:8786'.")

    if not isinstance(address, str):
        raise refuse(f"not text but a value of type {type(address).__name__}")
    if not address or any(ch.isspace() or not ch.isprintable() for ch in address):
        raise refuse("empty, or holding spaces or control characters")
    scheme, sep, where = address.partition("://")
    if not sep:
        scheme, where = "tcp", address
    known = set(SCHEMES)
    try:  # the backends registered where this runs (a package may add one)
        from distributed.comm.registry import backends

        known |= set(backends)
    except Exception:  # noqa: BLE001 - distributed missing or changed: its own schemes stand
        pass
    if scheme not in known:
        raise refuse(f"its scheme {scheme!r} is none of distributed's: {', '.join(sorted(known))}")
    if scheme == "inproc":
        if not where:
            raise refuse("nothing after 'inproc://'")
        return address
    if where.startswith("["):  # an IPv6 address: [::1]:8786
        host, close, rest = where[1:].partition("]")
        port = rest[1:] if close and rest.startswith(":") else ""
        ok_host = bool(host) and all(ch in "0123456789abcdefABCDEF:." for ch in host)
    else:
        host, colon, port = where.rpartition(":")
        if not colon:
            host, port = where, ""
        ok_host = bool(host) and all(ch.isalnum() or ch in ".-_" for ch in host)
    if not ok_host:
        raise refuse(f"no host name or IP address before the port in {where!r}" if not host else
                     f"{host!r} is not a host name or IP address")
    if not port:
        raise refuse(f"no port after the host {host!r}: write host:port, such as {host}:8786")
    if not port.isdigit() or not 0 < int(port) < 65536:
        raise refuse(f"the port {port!r} is not a number from 1 to 65535")
    return address


def _connect(client: Any, address: str | None):
    """``(client, close)``: the client to run on and whether this call opened it (and must close it)."""
    if client is not None and address is not None:
        raise ModelError("sweep: give client= or address=, not both.")
    if client == SERIAL:
        return SERIAL, False
    if address is not None:
        check_address(address)
        from distributed import Client

        try:
            return Client(address, timeout="20s", set_as_default=False), True
        except OSError as exc:
            raise ModelError(f"sweep: no Dask scheduler answers at {address} ({exc}); start one with `dask scheduler` "
                             f"and workers with `dask worker {address}`.") from None
        except (ValueError, TypeError) as exc:  # what distributed refuses that check_address let through
            raise ModelError(f"sweep: address={address!r:.80} is refused by distributed ({type(exc).__name__}: "
                             f"{str(exc)[:200]}); give {ADDRESS_FORMS}, such as 'tcp://10.0.0.5:8786'.") from None
    if client is None:
        return local_client(), False
    if not hasattr(client, "submit") or not hasattr(client, "scatter"):
        raise ModelError(f"sweep: client= takes a distributed.Client (or 'serial'), not {type(client).__name__}.")
    return client, False


@contextlib.contextmanager
def connected(client: Any = None, address: str | None = None):
    """The client a sweep runs on, as :func:`execute` chooses it from ``client`` and ``address`` (the local
    cluster's, by default), connected for the ``with`` block; one this opened (``address=``) is closed after it."""
    client, close = _connect(client, address)
    try:
        yield client
    finally:
        if close:
            client.close()


def execute(fn: Callable, shared: Any, blocks: Sequence[tuple], sizes: Sequence[int], *, client: Any = None,
            address: str | None = None, progress: Any = None, label: str = "sweep") -> Outcome:
    """``fn(shared, *block)`` for every block, on Dask (or here, for :data:`SERIAL`); see the module's text."""
    client, close = _connect(client, address)
    reporter = _Progress(progress, int(sum(sizes)), label)
    outcome = Outcome(workers=workers(client))
    start = time.perf_counter()
    try:
        if client == SERIAL:
            try:
                for i, block in enumerate(blocks):
                    outcome.results[i] = fn(shared, *block)
                    reporter.add(sizes[i])
            except KeyboardInterrupt:
                outcome.interrupted = True
        else:
            _distributed(client, fn, shared, blocks, sizes, outcome, reporter)
    finally:
        reporter.end()
        outcome.seconds = time.perf_counter() - start
        if close:
            client.close()
    return outcome


def _distributed(client, fn, shared, blocks, sizes, outcome: Outcome, reporter: _Progress) -> None:
    from distributed import as_completed

    token = uuid.uuid4().hex[:12]
    pending = set(range(len(blocks)))
    rounds = 0
    try:
        while pending and rounds < 3:  # a round again only when the shared data itself was lost with workers
            rounds += 1
            data = client.scatter(shared, broadcast=True, hash=False)
            futures = {client.submit(fn, data, *blocks[i], key=f"lagrangian-{token}-{rounds}-{i}", pure=False): i
                       for i in sorted(pending)}
            try:
                for future in as_completed(futures, loop=client.loop):
                    i = futures[future]
                    try:
                        outcome.results[i] = future.result()
                    except CancelledError:
                        continue  # its inputs were lost: run again in the next round
                    except Exception as exc:  # the task failed as a whole (KilledWorker, ...): recorded
                        outcome.failures[i] = f"{type(exc).__name__}: {exc}"
                    pending.discard(i)
                    reporter.add(sizes[i])
            finally:
                client.cancel([*futures, data], force=True)  # the shared data too: nothing left on the workers
                del futures, data
    except KeyboardInterrupt:
        outcome.interrupted = True
    for i in pending:
        if not outcome.interrupted:
            outcome.failures[i] = "the data the task needed was lost with the workers that held it, three times"

