"""The cache of reductions by structure: work done once for the same components given other numbers.

:func:`_by_structure` keys a computation on the expressions it is computed from,
with the symbols standing for numbers renamed to canonical ones, and keeps at
most :data:`CACHE_SIZE` results (least recently used dropped first); :func:`_put`
puts the values of parameters given as numbers into the parts of a result.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Mapping
from typing import Any

from ...derivation.calculus import Rewriter
from ...base import deferred as _deferred

sp = _deferred.module("sympy", globals())

#: Reductions kept by structure (least recently used dropped first).
CACHE_SIZE = 128
_CACHE: "OrderedDict[tuple, dict]" = OrderedDict()
_CACHE_LOCK = threading.Lock()


def _by_structure(key: tuple, values: Mapping[sp.Symbol, sp.Expr], compute) -> dict:
    """``compute()`` (a dict of parts in the symbols of ``values``), once per structure.

    ``key`` holds the expressions the parts are computed from; the symbols
    standing for numbers (the keys of ``values``, unique to one model) are
    renamed to canonical symbols in the key and in the stored parts, and back
    on the way out, so the same components given other numbers reuse the work.
    """
    canon = {s: sp.Symbol(s.name, **s.assumptions0) for s in values}
    to_canon = Rewriter(dict(canon))
    key = tuple(_put(k, canon, to_canon) for k in key)
    with _CACHE_LOCK:
        cached = _CACHE.get(key)
        if cached is not None:
            _CACHE.move_to_end(key)
    if cached is None:
        parts = compute()
        with _CACHE_LOCK:
            _CACHE[key] = {k: _put(part, canon, to_canon) for k, part in parts.items()}
            while len(_CACHE) > CACHE_SIZE:
                _CACHE.popitem(last=False)
        return parts
    back = {c: s for s, c in canon.items()}
    from_canon = Rewriter(dict(back))
    return {k: _put(part, back, from_canon) for k, part in cached.items()}


def _put(part: Any, values: Mapping[sp.Symbol, sp.Expr], rewrite: Rewriter | None = None) -> Any:
    """A part of the reduction with the values of parameters given as numbers put in (lists part by part), by a
    memoized ``xreplace`` (:class:`~lagrangian.derivation.calculus.Rewriter`: SymPy's walks a shared sub-expression
    once per occurrence, minutes for the Jacobi integral of eight bodies on spherical joints)."""
    if not values or isinstance(part, (bool, int)):
        return part
    rewrite = rewrite if rewrite is not None else Rewriter(dict(values))
    if isinstance(part, list):
        return [_put(e, values, rewrite) for e in part]
    if isinstance(part, tuple):
        return tuple(_put(e, values, rewrite) for e in part)
    return rewrite(part) if isinstance(part, sp.Basic) else part
