"""Unit-aware parsing of user-typed quantities ("10 rad/s", "120 rpm", "30 m/h", "25 klbf").

Everything inside downhole is SI. Values typed by users (scenario files, CLI options) may carry
units, including the oilfield units drilling engineers think in; this module converts them to SI
with pint and raises a precise :class:`UnitError` otherwise.

A quantity string is *a number and a unit, nothing else* (see :data:`QUANTITY_GRAMMAR`): it is
checked against a strict grammar before pint sees it, so arithmetic such as ``"1 s * 10**10**8"``
is refused instead of evaluated. Every converted value must be finite and inside the admissible
range of its physical dimension (:data:`RANGES`); the same ranges apply to bare numbers.
"""

from __future__ import annotations

import math
import re
from functools import lru_cache

import pint

__all__ = ["UnitError", "to_si", "SI_UNITS", "RANGES", "MAX_QUANTITY_LENGTH",
           "QUANTITY_GRAMMAR", "check_range", "parse_quantity_string"]

#: The SI unit downhole stores for each physical dimension name used in parameter schemas.
SI_UNITS: dict[str, str] = {
    "length": "m",
    "velocity": "m/s",
    "angular_velocity": "rad/s",
    "angle": "rad",
    "force": "N",
    "torque": "N*m",
    "mass": "kg",
    "inertia": "kg*m**2",
    "stiffness": "N/m",
    "torsional_stiffness": "N*m/rad",
    "damping": "N*s/m",
    "torsional_damping": "N*m*s/rad",
    "pressure": "Pa",
    "time": "s",
    "density": "kg/m**3",
    "area": "m**2",
    "second_moment": "m**4",
    "dimensionless": "",
    "acceleration": "m/s**2",
}

#: Admissible range ``(low, high)`` of every dimension, in the SI unit of :data:`SI_UNITS`
#: (inclusive; fields may narrow it, e.g. a length that must be positive). Sensible engineering
#: bounds with a wide margin: a well is at most a few tens of km deep, a hook load a few MN, a
#: Young's modulus a few hundred GPa. Anything outside is a typo or hostile input.
RANGES: dict[str, tuple[float, float]] = {
    "length": (0.0, 1e5),                     # m: wells, strings, diameters, depths of cut
    "velocity": (-1e3, 1e3),                  # m/s
    "angular_velocity": (-1e4, 1e4),          # rad/s (about 95 000 rpm)
    "angle": (-4 * math.pi, 4 * math.pi),     # rad
    "force": (-1e9, 1e9),                     # N
    "torque": (-1e8, 1e8),                    # N m
    "mass": (0.0, 1e9),                       # kg
    "inertia": (0.0, 1e8),                    # kg m^2
    "stiffness": (0.0, 1e13),                 # N/m
    "torsional_stiffness": (0.0, 1e12),       # N m/rad
    "damping": (0.0, 1e12),                   # N s/m
    "torsional_damping": (0.0, 1e12),         # N m s/rad
    "pressure": (0.0, 1e13),                  # Pa
    "time": (0.0, 1e6),                       # s (about 11.6 days)
    "density": (0.0, 1e5),                    # kg/m^3
    "area": (0.0, 1e3),                       # m^2
    "second_moment": (0.0, 1e2),              # m^4
    "dimensionless": (-1e15, 1e15),
    "acceleration": (-1e3, 1e3),              # m/s^2
}

#: Longest accepted quantity string (characters).
MAX_QUANTITY_LENGTH = 64

#: The accepted quantity grammar (documented in ``docs/scenarios.md``).
QUANTITY_GRAMMAR = (
    "NUMBER [UNIT]: NUMBER is a decimal number with an optional exponent (e.g. 2.5e-3); UNIT is "
    "unit names joined by '*', '/' or spaces, each optionally raised to a small integer power "
    "with '^' or '**' (|power| <= 4), parentheses allowed, e.g. 'kg/m^3', 'N*m/rad', "
    "'kg*m**2', '1/(N*s)'"
)

_NUMBER = re.compile(r"\s*([+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d{1,3})?)")
_TOKEN = re.compile(r"\s*(?:(?P<name>[A-Za-z_\u00b5\u03bc\u00b0\u03a9][A-Za-z0-9_]*)"
                    r"|(?P<pow>\*\*|\^)\s*(?P<exp>[+-]?\d{1,2})"
                    r"|(?P<op>[*/])|(?P<open>\()|(?P<close>\))|(?P<one>1))")
_MAX_POWER = 4
_MAX_DEPTH = 3


class UnitError(ValueError):
    """A quantity could not be parsed or has the wrong dimension."""


@lru_cache(maxsize=1)
def _registry() -> pint.UnitRegistry:
    ureg = pint.UnitRegistry()
    # Drilling shorthand not in pint's default set.
    ureg.define("klbf = 1000 * lbf")
    ureg.define("kft_lbf = 1000 * foot * lbf")
    ureg.define("ft_lbf = foot * lbf")
    return ureg


def _check_unit_expression(text: str, original: str) -> None:
    """Raise :class:`UnitError` unless ``text`` is a unit expression of the accepted grammar."""
    pos, depth, expect_operand = 0, 0, True
    bad = (f"cannot parse quantity {original!r}: expected a number and a unit, nothing else "
           "(e.g. '10 rad/s', '25 klbf', 'kg/m^3'; see docs/scenarios.md)")
    while pos < len(text):
        m = _TOKEN.match(text, pos)
        if m is None or m.end() == pos:
            raise UnitError(bad)
        pos = m.end()
        if m.group("name"):
            expect_operand = False
        elif m.group("one"):
            # only as the numerator of a reciprocal, '1/s', '1/(N*s)'
            rest = text[pos:].lstrip()
            if not expect_operand or not rest.startswith("/"):
                raise UnitError(bad)
            expect_operand = False
        elif m.group("pow"):
            if expect_operand:
                raise UnitError(bad)
            if abs(int(m.group("exp"))) > _MAX_POWER:
                raise UnitError(f"cannot parse quantity {original!r}: unit powers are small "
                                f"integers (|power| <= {_MAX_POWER})")
            nxt = _TOKEN.match(text, pos)
            if nxt is not None and nxt.group("pow"):
                raise UnitError(bad)  # a power of a power: 'm**2**3'
        elif m.group("op"):
            if expect_operand:
                raise UnitError(bad)
            expect_operand = True
        elif m.group("open"):
            depth += 1
            if depth > _MAX_DEPTH:
                raise UnitError(bad)
            expect_operand = True
        else:  # close
            if expect_operand or depth == 0:
                raise UnitError(bad)
            depth -= 1
    if depth or (expect_operand and text.strip()):
        raise UnitError(bad)


def parse_quantity_string(value: str) -> tuple[float, str]:
    """Split a quantity string into ``(number, unit expression)`` after checking the grammar.

    Parameters
    ----------
    value : str
        E.g. ``"120 rpm"``, ``"1e7 N/m"``, ``"1200 kg/m^3"``.

    Returns
    -------
    (float, str)
        The finite number and the unit expression (empty for a bare number).

    Raises
    ------
    UnitError
        If the string is too long, contains anything but a number and a unit of the grammar in
        :data:`QUANTITY_GRAMMAR`, or the number is not finite.
    """
    if len(value) > MAX_QUANTITY_LENGTH:
        raise UnitError(f"quantity string of {len(value)} characters; at most "
                        f"{MAX_QUANTITY_LENGTH} are accepted (a number and a unit)")
    m = _NUMBER.match(value)
    if m is None:
        raise UnitError(f"cannot parse quantity {value!r}: expected a number and a unit, e.g. "
                        "'10 rad/s' (see docs/scenarios.md)")
    number = float(m.group(1))
    if not math.isfinite(number):
        raise UnitError(f"quantity {value!r} is not a finite number")
    unit = value[m.end():].strip()
    if unit and m.end() < len(value) and not value[m.end()].isspace() \
            and value[m.end()] not in "*/":
        # '10rad/s' is fine for pint, but '1e5e5' or '1.2.3 m' is not a number
        if not (value[m.end()].isalpha() or value[m.end()] in "\u00b5\u03bc\u00b0\u03a9"):
            raise UnitError(f"cannot parse quantity {value!r}: expected a number and a unit")
    _check_unit_expression(unit, value)
    return number, unit


def check_range(value: float, dimension: str) -> float:
    """Return ``value`` if it is finite and inside :data:`RANGES` of ``dimension``.

    Raises
    ------
    UnitError
        Naming the admissible range in SI units.
    """
    if not math.isfinite(value):
        raise UnitError(f"expected a finite number, got {value!r}")
    lo, hi = RANGES[dimension]
    if not lo <= value <= hi:
        unit = SI_UNITS[dimension]
        u = f" {unit}" if unit else ""
        raise UnitError(f"{value:g}{u} is outside the admissible range of a "
                        f"{dimension.replace('_', ' ')}, {lo:g} to {hi:g}{u}")
    return value


def to_si(value: float | int | str, dimension: str) -> float:
    """Convert ``value`` to the SI unit of ``dimension``.

    Parameters
    ----------
    value : float, int or str
        A bare number (taken as already SI) or a string with a unit, e.g. ``"120 rpm"``
        (grammar: :data:`QUANTITY_GRAMMAR`).
    dimension : str
        A key of :data:`SI_UNITS`, e.g. ``"angular_velocity"``.

    Returns
    -------
    float
        The value in SI units, finite and inside :data:`RANGES` of ``dimension``.

    Raises
    ------
    UnitError
        If the string cannot be parsed, its unit has the wrong dimension, or the value is not
        finite or outside the admissible range.

    Examples
    --------
    >>> round(to_si("60 rpm", "angular_velocity"), 6)
    6.283185
    >>> to_si("36 m/h", "velocity")
    0.01
    """
    if dimension not in SI_UNITS:
        raise UnitError(f"unknown dimension {dimension!r}; expected one of {sorted(SI_UNITS)}")
    if isinstance(value, bool):
        raise UnitError(f"expected a number or a quantity string, got boolean {value}")
    if isinstance(value, int):
        if abs(value) > 1e300:
            raise UnitError(f"integer with {len(str(abs(value)))} digits is outside the "
                            f"admissible range of a {dimension.replace('_', ' ')}")
        return check_range(float(value), dimension)
    if isinstance(value, float):
        return check_range(value, dimension)
    if not isinstance(value, str):
        raise UnitError(f"expected a number or a quantity string, got {type(value).__name__}")
    number, unit = parse_quantity_string(value)
    ureg = _registry()
    target = SI_UNITS[dimension]
    try:
        q = ureg.Quantity(number, unit) if unit else ureg.Quantity(number)
    except Exception as exc:  # pint raises several error types  # noqa: BLE001
        raise UnitError(f"cannot parse quantity {value!r}: {exc}") from None
    try:
        if target == "":
            si = q.to("dimensionless").magnitude
        else:
            # rad is dimensionless in pint, so rpm -> rad/s works, and "N*m" torque is accepted.
            si = q.to(target).magnitude
    except pint.DimensionalityError:
        raise UnitError(
            f"quantity {value!r} has unit '{q.units}', which cannot be converted to "
            f"{target or 'a plain number'}"
        ) from None
    except Exception as exc:  # offset units (degC) and other pint refusals  # noqa: BLE001
        raise UnitError(f"cannot convert quantity {value!r} to {target or 'a number'}: "
                        f"{exc}") from None
    try:
        si = float(si)
    except (OverflowError, TypeError, ValueError):
        raise UnitError(f"quantity {value!r} does not convert to a finite number") from None
    return check_range(si, dimension)
