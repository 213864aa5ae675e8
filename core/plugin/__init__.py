"""The plugin layer: the contracts hooks name (:mod:`.contracts`), the hook specifications and the registry
that loads plugins through entry points.  Depends only on :mod:`lagrangian.base`.
"""
