"""Quantities with units: ``"0.3 kg"``, ``"7 mH"``, ``300 * ureg.g`` become numbers in SI units.

Values given with a unit are converted, with :mod:`pint`, to the unit each
parameter declares (``Parameter.unit``: ``"kg"``, ``"N/m"``, ``"H"``, ...),
and a unit of another dimension is refused, naming the dimension expected.
A unit given as text is read as data: a number, then a unit spelled with
letters, digits, spaces, ``* / ^ ( ) . -`` and the signs ``µ Ω ° ² ³``
(at most 60 characters), which pint's own parser reads (it never evaluates
Python).  pint is an optional extra (``pip install 'lagrangian[units]'``);
without it plain numbers work as always, and a value with a unit is refused
with that advice.

>>> to_si("300 g", "kg", "mass")
0.3
>>> to_si("7 mH", "H", "inductance")
0.007
>>> to_si("4 N/m", "kg", "mass")
Traceback (most recent call last):
...
lagrangian.errors.ModelError: mass: 4 N/m is a quantity of [mass] / [time] ** 2, not of [mass] (kg): give it in kg or a unit of the same dimension.
"""

from __future__ import annotations

import math
import re
from typing import Any

from ..errors import ModelError

__all__ = ["registry", "is_quantity", "split", "to_si", "coordinate_unit", "UNIT_CHARS", "COORDINATE_UNITS"]

#: Units of coordinates by the prefix of their names (``q_`` a charge, ``lambda_`` a flux linkage, ``x_`` a
#: position, ``theta_`` an angle...): for initial values given with units, and the labels of charts.
COORDINATE_UNITS = {"q": "C", "lambda": "Wb", "x": "m", "y": "m", "z": "m", "s": "m", "theta": "rad", "phi": "rad",
                    "psi": "rad", "alpha": "rad", "beta": "rad", "gamma": "rad"}


def coordinate_unit(name: str) -> str:
    """The unit of a coordinate by its name's prefix, or ``""`` when unknown.

    >>> coordinate_unit("x_cart"), coordinate_unit("theta_j1"), coordinate_unit("q_L1"), coordinate_unit("u")
    ('m', 'rad', 'C', '')
    """
    return COORDINATE_UNITS.get(str(name).partition("_")[0], "")

#: The characters a unit given as text may hold.
UNIT_CHARS = re.compile(r"^[A-Za-zµμΩ°²³][A-Za-z0-9µμΩ°²³ */^().\-]{0,59}$")
_NUMBER_UNIT = re.compile(r"^\s*([-+]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][-+]?\d+)?)\s*([A-Za-zµμΩ°].*?)\s*$")
_SUPERSCRIPTS = {"²": "**2", "³": "**3"}

_REGISTRY: dict[str, Any] = {}


def registry():
    """pint's application registry (the one ``pint.get_application_registry()`` gives users), or ``None``
    when pint is not installed."""
    if "ureg" not in _REGISTRY:
        try:
            import pint  # optional: imported when a unit is first met
        except ImportError:
            _REGISTRY["ureg"] = None
        else:
            _REGISTRY["ureg"] = pint.get_application_registry()
    return _REGISTRY["ureg"]


def is_quantity(value: Any) -> bool:
    """Whether ``value`` is a pint quantity (by its interface: a magnitude, units and ``to``)."""
    return all(hasattr(value, a) for a in ("magnitude", "units", "to", "dimensionality")) and not isinstance(value, type)


def split(text: Any) -> tuple[float, str] | None:
    """``(number, unit)`` when ``text`` is a number followed by a unit (``"0.3 kg"``), else ``None``.

    >>> split("3e-3 H"), split("0.3"), split("2*pi")
    ((0.003, 'H'), None, None)
    """
    if not isinstance(text, str):
        return None
    match = _NUMBER_UNIT.match(text)
    if not match or not UNIT_CHARS.match(match.group(2)):
        return None
    return float(match.group(1)), match.group(2)


def _spelled(unit: str) -> str:
    for sign, power in _SUPERSCRIPTS.items():
        unit = unit.replace(sign, power)
    return unit.replace("μ", "µ")


def _declared(unit: str, ureg):
    """The unit a parameter declares, as pint reads it, or ``None`` when it declares none pint can read."""
    unit = unit.split("=")[0].strip()
    if not unit:
        return None
    try:
        return ureg.Unit(_spelled(unit))
    except Exception:  # noqa: BLE001 - a declared unit pint cannot read ("N m^n"): SI base units then
        return None


def to_si(value: Any, unit: str, what: str) -> float:
    """``value`` (a pint quantity, or text ``"number unit"``) as a number in ``unit`` (a parameter's declared
    unit; ``""``: SI base units).  :class:`~lagrangian.ModelError` naming ``what`` when pint is missing, the
    unit unknown or of another dimension, or the number not finite."""
    ureg = registry()
    if ureg is None:
        raise ModelError(f"{what}: {value} has a unit, and units need pint: pip install 'lagrangian[units]' (or pint), "
                         f"or give the number in SI units{f' ({unit})' if unit else ''}.")
    if is_quantity(value):
        quantity = value
    else:
        parts = split(value)
        if parts is None:
            raise ModelError(f"{what}: {value!r:.80} is not a number followed by a unit, such as '0.3 kg'.")
        number, text = parts
        try:
            quantity = ureg.Quantity(number, _spelled(text))
        except Exception as exc:  # noqa: BLE001 - pint's errors: an unknown or malformed unit
            raise ModelError(f"{what}: {text!r} is not a unit pint knows ({type(exc).__name__}): write it as "
                             f"'kg', 'mH', 'N/m', 'N*s/m', 'uF'...") from None
    target = _declared(unit, ureg)
    try:
        converted = quantity.to(target) if target is not None else quantity.to_base_units()
    except Exception:  # noqa: BLE001 - pint's DimensionalityError
        shown = value.strip() if isinstance(value, str) else f"{quantity:~P}"
        raise ModelError(f"{what}: {shown} is a quantity of {quantity.dimensionality}, not of "
                         f"{target.dimensionality} ({unit.split('=')[0].strip()}): give it in "
                         f"{unit.split('=')[0].strip()} or a unit of the same dimension.") from None
    try:
        number = float(converted.magnitude)
    except (TypeError, ValueError):
        raise ModelError(f"{what}: {value} must be one number with a unit.") from None
    if not math.isfinite(number):
        raise ModelError(f"{what}: {value} is not finite.")
    return number
