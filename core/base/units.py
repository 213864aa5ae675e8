"""Quantities with units: ``"0.3 kg"``, ``"7 mH"``, ``300 * ureg.g`` become numbers in SI units.

Values given with a unit are converted, with :mod:`pint`, to the unit each
parameter declares (``Parameter.unit``: ``"kg"``, ``"N/m"``, ``"H"``, ...),
and a unit of another dimension is refused, naming the dimension expected.
A unit given as text is read as data: a number, then a unit spelled with
letters, digits, spaces, ``* / ^ ( ) . -`` and the signs ``µ Ω ° ² ³``
(at most 60 characters), which pint's own parser reads (it never evaluates
Python).  As pint computes the powers of whole numbers exactly, the text is
checked first: a tower of powers (``kg*9^9^9``), an exponent beyond
``lagrangian.limits.exponent`` and a number beyond a float's range are
refused before pint reads it.  pint is an optional extra (``pip install 'lagrangian[units]'``);
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
from .limits import limits, refuse

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
#: A number (taken whole: ``1e5`` is never ``1`` and a unit ``e5``), then a unit.
_NUMBER_UNIT = re.compile(r"^\s*((?>[-+]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][-+]?\d+)?))\s*([A-Za-zµμΩ°].*?)\s*$")
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

    >>> split("3e-3 H"), split("0.3"), split("2*pi"), split("1e5"), split("1e400")
    ((0.003, 'H'), None, None, None, None)

    The number is read whole, as a float: ``"1e400 m"`` gives ``(inf, 'm')``, which :func:`to_si` refuses.
    """
    if not isinstance(text, str):
        return None
    match = _NUMBER_UNIT.match(text)
    if not match or not UNIT_CHARS.match(match.group(2)):
        return None
    return float(match.group(1)), match.group(2)


def _one_line(exc: Exception, width: int = 80) -> str:
    text = " ".join(str(exc).split())
    return text if len(text) <= width else text[: width - 3] + "..."


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
        if not math.isfinite(number):
            written = _NUMBER_UNIT.match(value).group(1)
            raise ModelError(f"{what}: the number {written[:40]!r} in {value.strip()!r:.80} is beyond "
                             f"a float's range (±1.8e308): give the value in a larger unit, or a smaller number.")
        _bounded(_spelled(text), what)  # before pint reads it: pint computes the powers of its numbers exactly
        try:
            quantity = ureg.Quantity(number, _spelled(text))
        except OverflowError:
            raise ModelError(f"{what}: {text!r} is beyond a float's range (±1.8e308).") from None
        except Exception as exc:  # noqa: BLE001 - pint's errors: an unknown or malformed unit
            raise ModelError(f"{what}: {text!r} is not a unit pint knows ({type(exc).__name__}: "
                             f"{_one_line(exc)}): write it as 'kg', 'mH', 'N/m', 'N*s/m', 'uF'...") from None
    target = _declared(unit, ureg)
    shown = value.strip() if isinstance(value, str) else f"{value!r:.80}"
    try:
        converted = quantity.to(target) if target is not None else quantity.to_base_units()
    except OverflowError:  # a conversion factor to a power
        raise ModelError(f"{what}: {shown} in {unit.split('=')[0].strip() or 'SI units'} is beyond a float's range "
                         f"(±1.8e308).") from None
    except Exception:  # noqa: BLE001 - pint's DimensionalityError
        shown = value.strip() if isinstance(value, str) else f"{quantity:~P}"
        raise ModelError(f"{what}: {shown} is a quantity of {quantity.dimensionality}, not of "
                         f"{target.dimensionality} ({unit.split('=')[0].strip()}): give it in "
                         f"{unit.split('=')[0].strip()} or a unit of the same dimension.") from None
    try:
        number = float(converted.magnitude)
    except OverflowError:  # an int beyond a float
        number = math.inf
    except (TypeError, ValueError):
        raise ModelError(f"{what}: {value} must be one number with a unit.") from None
    if not math.isfinite(number):
        raise ModelError(f"{what}: {shown} is not finite in {unit.split('=')[0].strip() or 'SI units'}: it is "
                         f"beyond a float's range (±1.8e308) or not a number.")
    return number


# ---------------------------------------------------------------------------
# A unit's text checked before pint reads it
# ---------------------------------------------------------------------------

_TOKEN = re.compile(r"\s*(?:(?P<number>(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][-+]?\d+)?)|(?P<name>[A-Za-zµμΩ°_][A-Za-z0-9µμΩ°_]*)"
                    r"|(?P<power>\*\*|\^)|(?P<op>[-*/()]))")


def _bounded(text: str, what: str) -> None:
    """Refuse, with a :class:`~lagrangian.ModelError` naming ``what``, a unit's text whose powers would take pint
    long to compute or would not fit a float, before pint reads it.  pint evaluates a unit's text as arithmetic,
    the powers of its whole numbers exactly (``kg*9^9^9`` has 370 million digits; ``10^10^10`` never ends), and
    refuses a number in a unit only after computing it.  Refused here:

    - a power whose exponent is itself a power (``9^9^9``, ``m^(2^3)``: an exponent tower);
    - an exponent that is not a number (``m^x``), or one beyond ``lagrangian.limits.exponent`` in size (also once
      nested powers multiply it: ``((m^100)^100)``);
    - a number, or a product, quotient or power of numbers, beyond a float's range (``1e400``, ``1e300^2``).

    >>> _bounded("kg*m^2/s^2", "mass")
    >>> _bounded("kg*9^9^9", "mass")
    Traceback (most recent call last):
    ...
    lagrangian.errors.ModelError: mass: 'kg*9^9^9' raises to a power whose exponent is itself a power (9^9^9): an exponent tower is refused (pint would compute it exactly, and 9^9^9 has 370 million digits); write one exponent, a number such as m^2 or s^-1.
    """
    _UnitText(text, what).check()


class _UnitText:
    """The tokens of a unit's text and a reading of them as pint reads them (``**`` and ``^`` above unary minus
    above ``*``, ``/`` and juxtaposition, above ``-``), tracking the size of its numbers (as floats) and the
    exponent of each name: enough to bound what pint's reading would cost."""

    def __init__(self, text: str, what: str):
        self.text, self.what = text, what
        self.tokens: list[tuple[str, str, int]] = []  # (kind, token, start)
        at = 0
        while at < len(text):
            if text[at:].isspace():
                break
            match = _TOKEN.match(text, at)
            if not match:
                self.fail(f"{text[at:].strip()[:1]!r} cannot be read")
            kind = match.lastgroup
            self.tokens.append((kind, match.group(kind), match.start(kind)))
            at = match.end()
        self.at = 0

    def fail(self, why: str):
        raise ModelError(f"{self.what}: {self.text!r} is not a unit that can be read ({why}): write it as 'kg', "
                         f"'mH', 'N/m', 'N*s/m', 'kg*m^2', 'uF'...")

    def peek(self) -> tuple[str, str, int] | None:
        return self.tokens[self.at] if self.at < len(self.tokens) else None

    def take(self) -> tuple[str, str, int]:
        token = self.peek()
        if token is None:
            self.fail("it ends early")
        self.at += 1
        return token

    def piece(self, first: int, last: int) -> str:
        """The text of tokens ``first`` to ``last`` (included)."""
        kind, token, start = self.tokens[last]
        return self.text[self.tokens[first][2]: start + len(token)].strip()

    def check(self) -> None:
        self.sum()
        if self.peek() is not None:
            self.fail(f"{self.peek()[1]!r} is not expected there")

    def finite(self, size: float, first: int) -> float:
        if not math.isfinite(size):
            raise ModelError(f"{self.what}: {self.piece(first, self.at - 1)!r} in {self.text!r} is beyond a float's "
                             f"range (±1.8e308): write the unit without it.")
        return size

    # Each reading returns (size, exponents): the size bounds the magnitude of the number it computes (names are
    # 1), the exponents are those of the names in it.
    def sum(self) -> tuple[float, dict[str, float]]:
        first = self.at
        size, powers = self.product()
        while self.peek() is not None and self.peek()[1] == "-":
            self.take()
            other, more = self.product()
            size = self.finite(size + other, first)
            powers = {k: max(abs(powers.get(k, 0)), abs(more.get(k, 0))) for k in {*powers, *more}}
        return size, powers

    def product(self) -> tuple[float, dict[str, float]]:
        first = self.at
        size, powers = self.unary()
        while (token := self.peek()) is not None and (token[1] in ("*", "/", "(") or token[0] in ("name", "number")):
            divide = token[1] == "/"
            if token[1] in ("*", "/"):
                self.take()
            other, more = self.unary()
            if divide:
                if other == 0:
                    self.fail("it divides by zero")
                size = self.finite(size / other, first)
            else:
                size = self.finite(size * other, first)
            sign = -1 if divide else 1
            powers = {k: powers.get(k, 0) + sign * more.get(k, 0) for k in {*powers, *more}}
        return size, powers

    def unary(self) -> tuple[float, dict[str, float]]:
        if self.peek() is not None and self.peek()[1] == "-":
            self.take()
            return self.unary()
        return self.power()

    def power(self) -> tuple[float, dict[str, float]]:
        first = self.at
        size, powers = self.atom()
        if self.peek() is None or self.peek()[0] != "power":
            return size, powers
        self.take()
        exponent = self.exponent(first)
        if self.peek() is not None and self.peek()[0] == "power":
            self.tower(first)
        shown = self.piece(first, self.at - 1)
        if not abs(exponent) <= limits.exponent:
            refuse(f"{self.what}: the power {shown!r} in {self.text!r}", abs(exponent), "exponent")
        for name, value in powers.items():
            if not abs(value * exponent) <= limits.exponent:  # ((m^100)^100) is m^10000
                refuse(f"{self.what}: the power {shown!r} in {self.text!r} (of {name})", abs(value * exponent),
                       "exponent")
        try:
            size = math.pow(size, exponent)
        except OverflowError:
            size = math.inf
        except (ValueError, ZeroDivisionError):  # 0 to a negative power
            self.fail("it divides by zero")
        return self.finite(size, first), {k: v * exponent for k, v in powers.items()}

    def tower(self, first: int) -> None:
        end = self.at
        while end + 1 < len(self.tokens) and (self.tokens[end + 1][0] in ("number", "power") or self.tokens[end + 1][1] == "-"):
            end += 1
        raise ModelError(f"{self.what}: {self.text!r} raises to a power whose exponent is itself a power "
                         f"({self.piece(first, end)}): an exponent tower is refused (pint would compute it exactly, "
                         f"and 9^9^9 has 370 million digits); write one exponent, a number such as m^2 or s^-1.")

    def exponent(self, first: int) -> float:
        """The exponent after ``**`` or ``^``: a number, with signs, or in parentheses, perhaps a fraction
        (``m^-1``, ``m^(1/2)``, ``m^(-2)``)."""
        sign = 1.0
        while self.peek() is not None and self.peek()[1] == "-":
            self.take()
            sign = -sign
        token = self.take()
        if token[0] == "number":
            return sign * float(token[1])
        if token[1] == "(":
            depth, end = 1, self.at
            while end < len(self.tokens) and depth:
                depth += {"(": 1, ")": -1}.get(self.tokens[end][1], 0)
                end += 1
            group = self.tokens[self.at: end - 1]
            if any(kind == "power" for kind, _, _ in group):
                self.at = end - 1
                self.tower(first)
            words = [token for _, token, _ in group]
            numbers = [float(token) for kind, token, _ in group if kind == "number"]
            shapes = (["n"], ["-", "n"], ["n", "/", "n"], ["-", "n", "/", "n"], ["n", "/", "-", "n"])
            shape = ["n" if kind == "number" else token for kind, token, _ in group]
            if depth or shape not in shapes:
                self.fail(f"the exponent ({' '.join(words)}) is not a number or a fraction of two numbers")
            self.at = end
            value = numbers[0] / numbers[1] if len(numbers) == 2 and numbers[1] else (
                numbers[0] if len(numbers) == 1 else math.nan)
            if math.isnan(value):
                self.fail("its exponent divides by zero")
            return sign * value * (-1 if words.count("-") % 2 else 1)
        self.fail(f"the exponent {token[1]!r} is not a number: write a number, such as m^2 or s^-1")

    def atom(self) -> tuple[float, dict[str, float]]:
        first = self.at
        kind, token, _ = self.take()
        if kind == "number":
            return self.finite(float(token), first), {}
        if kind == "name":
            return 1.0, {token: 1.0}
        if token == "(":
            inner = self.sum()
            if self.take()[1] != ")":
                self.fail("a '(' is not closed")
            return inner
        self.fail(f"{token!r} is not expected there")
