"""Rotations and poses of the multibody plugin: a body's :class:`Pose`, planar and spatial rotation matrices,
:func:`transform` of body-frame points, and the twelve body-fixed angle sequences (checked, named, described and
turned into a rotation with its angular velocity)."""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any

from lagrangian.base.component import t
from lagrangian.derive import trig
from lagrangian.base import deferred as _deferred

sp = _deferred.module("sympy", globals())


@dataclass
class Pose:
    """Rotation ``R`` (dim × dim), origin ``p`` and angular velocity ``omega`` (planar: scalar; spatial: 3-vector in
    the fixed frame) of a body, as expressions of the coordinates and time; spatial poses also carry
    ``omega_body``, the angular velocity in the body's own frame (``Rᵀ ω``), built joint by joint."""

    R: sp.Matrix
    p: sp.Matrix
    omega: Any
    angle: Any = None  # planar only
    omega_body: Any = None  # spatial only
    v_body: Any = None  # spatial only: the origin's velocity in the body frame


def _rot2(phi) -> sp.Matrix:
    c, s = trig(sp.cos, phi), trig(sp.sin, phi)
    return sp.Matrix([[c, -s], [s, c]])


def _rot3(axis: sp.Matrix, angle) -> sp.Matrix:
    """Rotation by ``angle`` about the unit vector ``axis`` (Rodrigues); exact for the coordinate axes."""
    ax = [sp.nsimplify(a) if a.is_number else a for a in axis]
    if ax == [1, 0, 0]:
        return sp.Matrix([[1, 0, 0], [0, sp.cos(angle), -sp.sin(angle)], [0, sp.sin(angle), sp.cos(angle)]])
    if ax == [0, 1, 0]:
        return sp.Matrix([[sp.cos(angle), 0, sp.sin(angle)], [0, 1, 0], [-sp.sin(angle), 0, sp.cos(angle)]])
    if ax == [0, 0, 1]:
        return sp.Matrix([[sp.cos(angle), -sp.sin(angle), 0], [sp.sin(angle), sp.cos(angle), 0], [0, 0, 1]])
    k = sp.Matrix([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return sp.eye(3) + sp.sin(angle) * k + (1 - sp.cos(angle)) * k * k


@functools.cache
def unit_vectors() -> tuple:
    """The unit vectors of the axes x, y, z, as SymPy column matrices (``E3``)."""
    return sp.Matrix([1, 0, 0]), sp.Matrix([0, 1, 0]), sp.Matrix([0, 0, 1])


def __getattr__(name: str):
    if name == "E3":  # the unit vectors, made when first asked for (SymPy imported then)
        return list(unit_vectors())
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def product(A: sp.Matrix, B: sp.Matrix) -> sp.Matrix:
    """``A B`` without forming products by exact zeros: SymPy's ``0 · x`` asks whether ``x`` may be infinite, a walk
    of all of ``x`` (the nested rotations of a chain of 30 bodies spent 4.9 s of 14 in it)."""
    rows, inner, cols = A.rows, A.cols, B.cols
    return sp.Matrix(rows, cols, [sp.Add(*[A[i, k] * B[k, j] for k in range(inner) if A[i, k] != 0 and B[k, j] != 0])
                                  for i in range(rows) for j in range(cols)])


def transform(p: sp.Matrix, R: sp.Matrix, x: sp.Matrix) -> sp.Matrix:
    """``p + R x`` (a point given in a body frame, in the fixed frame), without products by zero entries of ``x``."""
    x = list(x)
    cols = [k for k, e in enumerate(x) if e != 0]
    if not cols:
        return sp.Matrix(p)
    return sp.Matrix([sp.Add(p[i], *[R[i, k] * x[k] for k in cols]) for i in range(R.rows)])


#: The twelve body-fixed angle sequences: proper Euler (first and last axis the same) and Tait–Bryan (three axes).
PROPER_EULER = ("zxz", "zyz", "xyx", "xzx", "yxy", "yzy")
TAIT_BRYAN = ("xyz", "xzy", "yxz", "yzx", "zxy", "zyx")
SEQUENCES = TAIT_BRYAN + PROPER_EULER


def _check_sequence(kind: str, name: str, value) -> str:
    """The angle sequence of a spherical or free joint, checked against the twelve (never evaluated)."""
    if isinstance(value, str) and value in SEQUENCES:
        return value
    hint = ""
    if isinstance(value, str) and value.strip().lower() in SEQUENCES:
        hint = f" Write it in lowercase without spaces: {value.strip().lower()!r} (the rotations are body-fixed)."
    from lagrangian import ParameterError

    raise ParameterError(
        name, "sequence",
        f"{kind} joint {name!r}: {value!r} is not an angle sequence.{hint} Give one of the 12 body-fixed sequences: "
        f"proper Euler {', '.join(map(repr, PROPER_EULER))} (angles phi, theta, psi) or Tait–Bryan "
        f"{', '.join(map(repr, TAIT_BRYAN))} (each angle named after its axis: alpha about x, beta about y, gamma "
        f"about z); the default is 'xyz'.",
    )


#: The name of a Tait–Bryan angle, after the axis it turns about (``"xyz"``: alpha, beta, gamma in turn).
AXIS_ANGLES = {"x": "alpha", "y": "beta", "z": "gamma"}


def _angle_names(sequence: str) -> tuple[str, str, str]:
    """The names of a sequence's three angles, in its order: a proper Euler sequence's precession, nutation and spin
    ``phi``, ``theta``, ``psi``; a Tait–Bryan sequence's named after their axes, ``alpha`` about x, ``beta`` about y,
    ``gamma`` about z (``"zyx"``: gamma, beta, alpha)."""
    if sequence in PROPER_EULER:
        return ("phi", "theta", "psi")
    a, b, c = (AXIS_ANGLES[axis] for axis in sequence)
    return a, b, c


def _lock(sequence: str) -> str:
    """Where the middle angle of a sequence puts the first and last rotation axes in line."""
    return "0 or ±π" if sequence in PROPER_EULER else "±π/2"


def _elsewhere(sequence: str) -> tuple[str, str]:
    """A sequence whose gimbal lock is a quarter turn away from that of ``sequence``, and where it locks.

    ``"aba"`` locks with the body's a axis along the parent's a axis; ``"cba"`` (Tait–Bryan, c the axis after a in
    x → y → z → x) with the body's a axis along the parent's c axis.  ``"abc"`` locks with the body's c axis along
    the parent's a axis; ``"cbc"`` with it along the parent's c axis."""
    a, b, c = sequence
    if a == c:
        c = "xyz"[("xyz".index(a) + 1) % 3]
        other = c + ({"x", "y", "z"} - {a, c}).pop() + a
        return other, f"the body's {a} axis along the parent's {c} axis"
    return c + b + c, f"the body's {c} axis along the parent's {c} axis"


def _angle_descriptions(kind: str, name: str, sequence: str, names: list[str]) -> list[str]:
    """Coordinate descriptions of a joint's three angles: which rotation each is, then (after a semicolon) the
    sequence's gimbal lock and a sequence that locks elsewhere."""
    a, c = sequence[0], sequence[2]
    other, where = _elsewhere(sequence)
    # sequences in double quotes: a quoted 'name' in a description is the component that owns the coordinate
    lock = (f'sequence "{sequence}" is in gimbal lock where {names[1]} = {_lock(sequence)} (the body\'s {c} axis along '
            f'the parent\'s {a} axis: {names[0]} and {names[2]} then turn about one axis); sequence="{other}" locks '
            f'elsewhere ({where})')
    order = ("first", "second", "third")
    return [f"{order[k]} angle (about the body's {sequence[k]} axis) of {kind} joint {name!r}; {lock}" for k in range(3)]


def _euler(sequence: str, a, b, c):
    """Rotation ``R = R_1(a) R_2(b) R_3(c)`` (body-fixed rotations about the axes named by ``sequence``) and the
    angular velocity in the parent frame, ``e_1 ȧ + R_1 e_2 ḃ + R_1 R_2 e_3 ċ``."""
    e1, e2, e3 = (unit_vectors()["xyz".index(axis)] for axis in sequence)
    R1, R2, R3 = _rot3(e1, a), _rot3(e2, b), _rot3(e3, c)
    omega = e1 * a.diff(t) + R1 * e2 * b.diff(t) + R1 * R2 * e3 * c.diff(t)
    return R1 * R2 * R3, omega


def _euler_body(sequence: str, a, b, c) -> sp.Matrix:
    """The angular velocity of :func:`_euler`'s rotation in the rotated (body) frame,
    ``Rᵀ ω = R_3ᵀ R_2ᵀ e_1 ȧ + R_3ᵀ e_2 ḃ + e_3 ċ``: each rate turned back only through the later rotations."""
    e1, e2, e3 = (unit_vectors()["xyz".index(axis)] for axis in sequence)
    R2, R3 = _rot3(e2, b), _rot3(e3, c)
    return R3.T * (R2.T * e1 * a.diff(t) + e2 * b.diff(t)) + e3 * c.diff(t)
