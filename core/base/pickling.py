"""Pickling what a model holds: whether pickle's own pickling is under way, and refusing the callables it cannot
carry, by name."""

from __future__ import annotations

import pickle
import sys
from typing import Any

from ..errors import ModelError

__all__ = ["pickling_by_name", "refuse_unpicklable"]


def pickling_by_name() -> bool:
    """Whether what is under way is pickle's own pickling, which carries a function, class or module by an
    importable name only: not cloudpickle's (which carries one built at run time by value), nor a
    :func:`copy.deepcopy` (which keeps functions as they are)."""
    cloudpickle = sys.modules.get("cloudpickle")
    pickler = getattr(cloudpickle, "Pickler", None)
    frame = sys._getframe(1)
    while frame is not None:
        if frame.f_globals.get("__name__") == "copy" or (
                pickler is not None and isinstance(frame.f_locals.get("self"), pickler)):
            return False
        frame = frame.f_back
    return True


def refuse_unpicklable(func: Any, what: str) -> None:
    """A :class:`ModelError` naming ``what`` when ``func`` (a Python callable a model holds) is one pickle cannot
    carry — a lambda, a local function — and the pickling under way is pickle's; cloudpickle carries it by value."""
    if not pickling_by_name():
        return
    try:
        pickle.dumps(func)
    except Exception as exc:
        raise ModelError(f"{what} is the Python callable {func!r:.60}, which pickle cannot carry "
                         f"({exc.__class__.__name__}: {exc}): pickle the model with cloudpickle (which carries it "
                         f"by value), define the function in an importable module, or give a SymPy expression of "
                         f"t.") from None
