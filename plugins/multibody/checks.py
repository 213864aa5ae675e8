"""Checks shared by the multibody plugin's bodies, joints and loads: vector and unit-vector parameters, the model's
dimension, and the parameter error they raise."""

from __future__ import annotations

from lagrangian import Component, ModelError, dot
from lagrangian.base import deferred as _deferred

sp = _deferred.module("sympy", globals())


def _vec(value, dim: int, comp: Component, pname: str, default=None) -> sp.Matrix:
    if value is None:
        return sp.zeros(dim, 1) if default is None else default
    if not isinstance(value, sp.MatrixBase) or value.shape != (dim, 1):
        raise ModelError(f"{comp.kind} {comp.name!r}: parameter {pname!r} must be a vector of {dim} entries in a {dim}-D model.")
    return sp.Matrix(value)


def _unit(value, comp: Component, pname: str) -> sp.Matrix:
    norm = sp.sqrt(dot(value, value))
    if norm == 0:
        raise ModelError(f"{comp.kind} {comp.name!r}: parameter {pname!r} must not be the zero vector.")
    return value / norm


def _need_dim(comp: Component, view, dims: tuple[int, ...]) -> int:
    if view.dim not in dims:
        raise ModelError(
            f"{comp.kind} {comp.name!r} needs a model of dimension {' or '.join(map(str, dims))} "
            f"(lg.Model(dim=...)); this model has dim={view.dim}."
        )
    return view.dim


def lg_param_error(component, parameter, message):
    from lagrangian import ParameterError

    return ParameterError(component, parameter, message)
