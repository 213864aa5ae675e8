"""Symbolic work under a time budget: a solve that can blow up fails with advice instead of hanging.

SymPy's ``solve``, ``simplify`` and friends have no way to stop part way.
:func:`within` runs such a call in a forked child process and waits at most
``seconds``; past that the child is killed and :class:`BudgetExceeded` is
raised, which callers turn into an error saying what to give instead
(numeric values, a search interval).  The result comes back by pickling,
which SymPy expressions support.  Where ``fork`` is not available (Windows)
the call runs in this process without a budget.

:func:`interruptible` is the cheap form for many small calls whose result
is optional (a cosmetic simplification): in the main thread a timer signal
interrupts the call in this process, elsewhere it runs in a child as
:func:`within` does.

>>> within(sum, [1, 2, 3], seconds=10)
6
>>> import time
>>> within(time.sleep, 5, seconds=0.2)
Traceback (most recent call last):
...
lagrangian.base.budget.BudgetExceeded: the call did not finish within its budget of 0.2 s
"""

from __future__ import annotations

import contextlib
import os
import pickle
import select
import signal
import threading
import time
from collections.abc import Callable
from typing import Any

from ..errors import _unpickled_error

__all__ = ["within", "interruptible", "BudgetExceeded", "DEFAULT_SECONDS"]

#: The default budget of a symbolic solve, in seconds of wall time.
DEFAULT_SECONDS = 20.0


class BudgetExceeded(Exception):
    """A bounded call did not finish within its budget (internal: callers raise their own error with advice).

    It pickles with its message and ``seconds`` (its ``__init__`` takes the seconds, not the message it builds:
    unpickling restores both without calling it again), so it crosses a process boundary as itself — a process
    pool's worker returns it, rather than breaking the pool.

    >>> import pickle
    >>> back = pickle.loads(pickle.dumps(BudgetExceeded(0.5)))
    >>> back.seconds, str(back)
    (0.5, 'the call did not finish within its budget of 0.5 s')
    """

    def __init__(self, seconds: float):
        super().__init__(f"the call did not finish within its budget of {seconds:g} s")
        self.seconds = seconds

    def __reduce__(self):
        return _unpickled_error, (type(self), self.args, self.__dict__)


def _child(fd: int, fn, args, kwargs) -> None:  # pragma: no cover - runs in the forked child
    try:
        payload = ("ok", fn(*args, **kwargs))
    except BaseException as exc:  # noqa: BLE001 - every failure goes back to the parent
        payload = ("error", exc)
    try:
        data = pickle.dumps(payload)
    except Exception as exc:  # noqa: BLE001
        data = pickle.dumps(("error", RuntimeError(f"the result could not be sent back: {exc}")))
    try:
        with os.fdopen(fd, "wb") as out:
            out.write(data)
    finally:
        os._exit(0)


def within(fn: Callable[..., Any], *args: Any, seconds: float = DEFAULT_SECONDS, **kwargs: Any) -> Any:
    """``fn(*args, **kwargs)``, or :class:`BudgetExceeded` after ``seconds`` of wall time.

    Exceptions raised by ``fn`` are raised here.  ``seconds=None`` (or
    ``inf``) runs the call directly, without a budget.  The child is forked
    with :func:`os.fork` itself rather than through :mod:`multiprocessing`,
    so that it works in daemonic processes too (the worker processes of a
    Dask cluster, a process pool's workers), which ``multiprocessing``
    forbids to have children.
    """
    if seconds is None or seconds == float("inf") or not hasattr(os, "fork"):
        return fn(*args, **kwargs)
    read, write = os.pipe()
    pid = os.fork()
    if pid == 0:  # pragma: no cover - the child
        os.close(read)
        _child(write, fn, args, kwargs)
    os.close(write)
    deadline = time.monotonic() + float(seconds)
    chunks: list[bytes] = []
    finished = False
    try:
        while True:  # read as the child writes (a large result fills the pipe), until it closes its end
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([read], [], [], left)[0]:
                raise BudgetExceeded(float(seconds))
            chunk = os.read(read, 1 << 20)
            if not chunk:
                break
            chunks.append(chunk)
        finished = True
    finally:
        if not finished:
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
        _, code = os.waitpid(pid, 0)
        os.close(read)
    if not chunks:  # the child died without an answer (out of memory, a signal)
        raise RuntimeError(f"the bounded call ended without a result (wait status {code})")
    status, value = pickle.loads(b"".join(chunks))
    if status == "error":
        raise value
    return value


#: After the budget, the timer fires again every RETRY seconds until the call stops: an exception raised where
#: Python swallows it (a garbage-collector callback, a ``__del__``; it then prints "Exception ignored in") or caught
#: by the code under the budget would otherwise let the call run on unbounded.
RETRY = 0.05


def _expire(signum, frame):  # pragma: no cover - runs when the timer fires
    signal.setitimer(signal.ITIMER_REAL, RETRY)  # disarmed by interruptible once the exception reaches it
    raise BudgetExceeded(_expire.seconds)


def interruptible(fn: Callable[..., Any], *args: Any, seconds: float, **kwargs: Any) -> Any:
    """``fn(*args, **kwargs)``, interrupted with :class:`BudgetExceeded` after ``seconds``.

    In the main thread (and where ``SIGALRM`` exists) the call runs in this
    process under a timer: no fork, so it costs nothing for the many quick
    calls.  Elsewhere (another thread, a timer already set by the caller)
    it runs as :func:`within` does.

    >>> interruptible(sorted, [3, 1, 2], seconds=1)
    [1, 2, 3]
    >>> import time
    >>> interruptible(time.sleep, 5, seconds=0.2)
    Traceback (most recent call last):
    ...
    lagrangian.base.budget.BudgetExceeded: the call did not finish within its budget of 0.2 s
    """
    if (threading.current_thread() is not threading.main_thread() or not hasattr(signal, "setitimer")
            or signal.getitimer(signal.ITIMER_REAL)[0] > 0):
        return within(fn, *args, seconds=seconds, **kwargs)
    _expire.seconds = float(seconds)
    previous = signal.signal(signal.SIGALRM, _expire)
    signal.setitimer(signal.ITIMER_REAL, float(seconds))
    try:
        return fn(*args, **kwargs)
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
