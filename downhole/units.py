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
import numbers
import re
from dataclasses import dataclass, field
from functools import lru_cache

import pint

__all__ = [
    "MAX_QUANTITY_LENGTH",
    "MAX_ROTARY_SPEED",
    "QUANTITY_GRAMMAR",
    "RANGES",
    "SI_UNITS",
    "SYSTEMS",
    "UNIT_TYPOS",
    "UnitError",
    "UnitSystem",
    "as_si",
    "as_si_array",
    "check_range",
    "check_rotary_speed",
    "convert",
    "display_units",
    "parse_quantity_string",
    "parse_unit_override",
    "registry",
    "si_or_number",
    "to_si",
    "unit_label",
]

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
    "curvature": "rad/m",
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
    "curvature": (0.0, 10.0),                 # rad/m (dogleg severity; 10 rad/m = 1.7 deg/ft)
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
    # dogleg severity, the way directional drillers quote it
    ureg.define("deg_per_100ft = degree / (100 * foot)")
    ureg.define("deg_per_30m = degree / (30 * meter)")
    return ureg


def registry() -> pint.UnitRegistry:
    """The pint registry downhole converts with (pint's defaults plus ``klbf``, ``kft_lbf``,
    ``ft_lbf``, ``deg_per_100ft`` and ``deg_per_30m``)."""
    return _registry()


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
    # '10rad/s' is fine for pint, but '1e5e5' or '1.2.3 m' is not a number
    if unit and m.end() < len(value) and not value[m.end()].isspace() \
            and value[m.end()] not in "*/" \
            and not (value[m.end()].isalpha() or value[m.end()] in "\u00b5\u03bc\u00b0\u03a9"):
        raise UnitError(f"cannot parse quantity {value!r}: expected a number and a unit")
    _check_unit_expression(unit, value)
    return number, unit


#: The fastest rotary speed of a real top drive (400 rpm), rad/s: a rotary-speed set-point above it
#: is a slip of the pen (most often rpm written as a bare number, which is rad/s).
MAX_ROTARY_SPEED = 400.0 * 2.0 * math.pi / 60.0


def check_rotary_speed(raw):
    """Refuse a rotary-speed set-point no rig turns, naming the value in the user's units and
    the likely fix; used by the scenario schemas as a pydantic ``mode="before"`` validator.

    Parameters
    ----------
    raw : float, str or pint Quantity
        The value as written: a bare number (SI, rad/s) or a quantity (``"120 rpm"``).

    Returns
    -------
    object
        ``raw``, unchanged, when it is plausible (or not a number: the field's own validation
        then says what is wrong).

    Raises
    ------
    ValueError
        Above :data:`MAX_ROTARY_SPEED` (400 rpm); for a bare number the message suggests the
        same number in rpm.
    """
    if isinstance(raw, bool):
        return raw
    if isinstance(raw, (int, float)):
        if math.isfinite(raw) and raw > MAX_ROTARY_SPEED:
            rpm = raw * 60.0 / (2.0 * math.pi)
            raise ValueError(f"{raw:g} (a bare number is rad/s) = {rpm:,.0f} rpm is above 400 "
                             f"rpm, the fastest top drives; did you mean \"{raw:g} rpm\"?")
        return raw
    try:
        value = si_or_number(raw, "angular_velocity", "rotary speed")
    except Exception:
        return raw
    if isinstance(value, (int, float)) and math.isfinite(value) and value > MAX_ROTARY_SPEED:
        rpm = value * 60.0 / (2.0 * math.pi)
        raise ValueError(f"{raw} = {rpm:,.0f} rpm is above 400 rpm, the fastest top drives")
    return raw


def check_range(value: float, dimension: str) -> float:
    """Return ``value`` if it is finite and inside :data:`RANGES` of ``dimension``.

    Parameters
    ----------
    value : float
        The value, in the SI unit of ``dimension`` (:data:`SI_UNITS`).
    dimension : str
        A key of :data:`SI_UNITS`, e.g. ``"length"`` or ``"angular_velocity"``.

    Returns
    -------
    float
        ``value`` unchanged.

    Raises
    ------
    UnitError
        If ``value`` is not finite or lies outside the admissible range (the message names the
        range in SI units).
    KeyError
        If ``dimension`` is not a key of :data:`RANGES`.
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


def to_si(value: float | str, dimension: str) -> float:
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
    ureg = _registry()
    target = SI_UNITS[dimension]
    if _is_quantity(value):
        q = _own_quantity(value)
        if q.magnitude.__class__ is not float and not isinstance(q.magnitude, numbers.Real):
            raise UnitError(f"expected a scalar quantity, got {value!r}")
    elif isinstance(value, numbers.Real):  # numpy scalars
        return check_range(float(value), dimension)
    elif not isinstance(value, str):
        raise UnitError(f"expected a number or a quantity string, got {type(value).__name__}")
    else:
        try:
            number, unit = parse_quantity_string(value)
        except UnitError as exc:
            raise UnitError(f"{exc}{_did_you_mean(value, dimension)}") from None
        try:
            q = ureg.Quantity(number, unit) if unit else ureg.Quantity(number)
        except Exception as exc:  # pint raises several error types
            raise UnitError(f"cannot parse quantity {value!r}: {exc}"
                            f"{_did_you_mean(value, dimension)}") from None
    try:
        if target == "":
            si = q.to("dimensionless").magnitude
        else:
            # rad is dimensionless in pint, so rpm -> rad/s works, and "N*m" torque is accepted.
            si = q.to(target).magnitude
    except pint.DimensionalityError:
        raise UnitError(
            f"quantity {value!r} has unit '{q.units}', which cannot be converted to "
            f"{target or 'a plain number'}{_did_you_mean(value, dimension)}"
        ) from None
    except Exception as exc:  # offset units (degC) and other pint refusals
        raise UnitError(f"cannot convert quantity {value!r} to {target or 'a number'}: "
                        f"{exc}") from None
    try:
        si = float(si)
    except (OverflowError, TypeError, ValueError):
        raise UnitError(f"quantity {value!r} does not convert to a finite number") from None
    return check_range(si, dimension)


#: Units drillers write that pint reads otherwise or not at all -> the unit meant.
UNIT_TYPOS: dict[str, str] = {
    "klb": "klbf", "klbs": "klbf", "kip": "klbf", "kips": "klbf", "lb": "lbf", "lbs": "lbf",
    "klbsf": "klbf",
    "knm": "kN*m", "kn.m": "kN*m", "nm": "N*m", "ftlb": "ft*lbf", "ftlbf": "ft*lbf",
    "ft-lb": "ft*lbf", "ft.lb": "ft*lbf", "kftlb": "kft*lbf", "kftlbf": "kft*lbf",
    "kft-lb": "kft*lbf", "kft.lb": "kft*lbf", "ppg": "lb/gal", "sg": "g/cm^3", "kg/l": "kg/L",
    "fph": "ft/h", "ft/hr": "ft/h", "m/hr": "m/h", "mph": "m/h", "revs": "rpm",
    "deg/100ft": "deg_per_100ft", "°/100ft": "deg_per_100ft", "deg/30m": "deg_per_30m",
    "°/30m": "deg_per_30m", "inch": "in", "inches": "in", '"': "in",
}

#: The units of each dimension a "did you mean" may suggest (close spellings of these).
_SUGGEST: dict[str, tuple[str, ...]] = {
    "length": ("m", "mm", "cm", "km", "ft", "in"),
    "velocity": ("m/s", "mm/s", "m/h", "ft/h", "ft/s"),
    "angular_velocity": ("rpm", "rad/s"),
    "angle": ("deg", "rad"),
    "force": ("N", "kN", "MN", "lbf", "klbf"),
    "torque": ("N*m", "kN*m", "ft*lbf", "kft*lbf"),
    "mass": ("kg", "t", "lb"),
    "pressure": ("Pa", "kPa", "MPa", "GPa", "psi", "bar"),
    "time": ("s", "ms", "min", "h"),
    "density": ("kg/m^3", "g/cm^3", "lb/gal"),
    "curvature": ("deg_per_30m", "deg_per_100ft", "rad/m"),
}


def _did_you_mean(value: str, dimension: str) -> str:
    """``'; did you mean "30 klbf"?'`` for a quantity string whose unit is a known slip
    (:data:`UNIT_TYPOS`) or a close spelling of a unit of ``dimension``; ``''`` otherwise."""
    import difflib

    m = _NUMBER.match(value) if isinstance(value, str) else None
    if m is None:
        return ""
    number, unit = m.group(1), value[m.end():].strip()
    if not unit:
        return ""
    candidates = []
    typo = UNIT_TYPOS.get(unit.lower()) or UNIT_TYPOS.get(unit.replace(" ", "").lower())
    if typo:
        candidates.append(typo)
    pool = _SUGGEST.get(dimension, ())
    lower = {u.lower(): u for u in pool}
    candidates += [lower[u] for u in difflib.get_close_matches(unit.lower(), list(lower), 3, 0.5)]
    for cand in candidates:
        if cand != unit and _converts(cand, SI_UNITS[dimension] or "dimensionless"):
            return f'; did you mean "{number} {cand}"?'
    return ""


def _converts(unit: str, target: str) -> bool:
    """True when pint converts ``unit`` to ``target``."""
    try:
        _registry().Quantity(1.0, unit).to(target)
    except Exception:  # unknown unit or other dimension
        return False
    return True


# ----------------------------------------------------------------------- quantities from Python
def _is_quantity(value) -> bool:
    """True for a pint Quantity (of any registry)."""
    return isinstance(value, pint.Quantity) or (
        hasattr(value, "magnitude") and hasattr(value, "units")
        and hasattr(value, "dimensionality"))


def _own_quantity(value):
    """``value`` (a pint Quantity, possibly of another registry) in downhole's registry."""
    ureg = _registry()
    if getattr(value, "_REGISTRY", None) is ureg:
        return value
    try:
        return ureg.Quantity(value.magnitude, str(value.units))
    except Exception as exc:
        raise UnitError(f"cannot use quantity {value!r}: {exc}") from None


def as_si(value, dimension: str, what: str) -> float:
    """``value`` as a float in the SI unit of ``dimension``.

    The API boundary of the public Python constructors: :func:`to_si` with its
    :class:`UnitError` turned into a :class:`~downhole.errors.DownholeInputError`.

    Parameters
    ----------
    value : float, int, str or pint.Quantity
        A number (taken as already SI), a quantity string such as ``"5 in"`` (grammar:
        :data:`QUANTITY_GRAMMAR`) or a pint Quantity.
    dimension : str
        A key of :data:`SI_UNITS`, e.g. ``"length"`` or ``"angular_velocity"``.
    what : str
        Name of the value (e.g. the parameter name), prefixed to the error message.

    Returns
    -------
    float
        The value in the SI unit of ``dimension``.

    Raises
    ------
    DownholeInputError
        ``what: <reason>``, when the value cannot be parsed, has the wrong dimension or lies
        outside the admissible range of ``dimension`` (:data:`RANGES`).

    Examples
    --------
    >>> as_si("5 in", "length", "outer_diameter")
    0.127
    >>> round(as_si("120 rpm", "angular_velocity", "speed"), 4)
    12.5664
    """
    from downhole.errors import DownholeInputError

    try:
        return to_si(value, dimension)
    except UnitError as exc:
        raise DownholeInputError(f"{what}: {exc}") from None


def si_or_number(value, dimension: str, what: str):
    """``value`` converted by :func:`as_si` when it is a quantity string or a pint Quantity.

    Anything else is returned unchanged (numbers are SI and keep their own checks).

    Parameters
    ----------
    value : object
        A quantity string, a pint Quantity, or anything else (returned as is).
    dimension, what
        As :func:`as_si`.

    Returns
    -------
    float or object
        The SI float for a string or Quantity, otherwise ``value`` itself.

    Raises
    ------
    DownholeInputError
        As :func:`as_si`, for a string or Quantity that does not convert.
    """
    if isinstance(value, str) or _is_quantity(value):
        return as_si(value, dimension, what)
    return value


def as_si_array(values, dimension: str, what: str):
    """Like :func:`as_si` for an array.

    Parameters
    ----------
    values : array_like, str or pint.Quantity
        A pint Quantity array, a sequence (or nested sequence) of numbers (taken as SI) or of
        quantity strings / Quantities, or a single quantity string.
    dimension, what
        As :func:`as_si`.

    Returns
    -------
    ndarray of float
        The values in the SI unit of ``dimension``, with the shape of ``values``.

    Raises
    ------
    DownholeInputError
        ``what: <reason>``, when an element cannot be parsed or converted, has the wrong dimension
        or lies outside :data:`RANGES` (elements given as strings or Quantities), or a value is not
        finite.
    KeyError
        If ``dimension`` is not a key of :data:`SI_UNITS`.
    """
    import numpy as np

    from downhole.errors import DownholeInputError

    target = SI_UNITS[dimension]
    try:
        if _is_quantity(values):
            q = _own_quantity(values)
            try:
                arr = np.asarray(q.to(target).magnitude if target else
                                 q.to("dimensionless").magnitude, dtype=float)
            except pint.DimensionalityError:
                raise UnitError(f"quantity has unit '{q.units}', which cannot be converted to "
                                f"{target or 'a plain number'}") from None
        elif isinstance(values, str):
            arr = np.asarray(to_si(values, dimension), dtype=float)
        else:
            try:
                arr = np.asarray(values, dtype=float)
            except (TypeError, ValueError):  # quantity strings or pint quantities inside
                obj = np.asarray(values, dtype=object)
                arr = np.array([to_si(v, dimension) if isinstance(v, str) or _is_quantity(v)
                                else float(v) for v in obj.ravel()],
                               dtype=float).reshape(obj.shape)
    except UnitError as exc:
        raise DownholeInputError(f"{what}: {exc}") from None
    except (TypeError, ValueError) as exc:
        raise DownholeInputError(f"{what}: expected numbers or quantities, got {values!r} "
                                 f"({exc})") from None
    if not np.all(np.isfinite(arr)):
        raise DownholeInputError(f"{what}: values must be finite")
    return arr


def convert(values, from_unit: str, to_unit: str):
    """``values`` converted from ``from_unit`` to ``to_unit`` with pint (downhole's registry).

    Parameters
    ----------
    values : float or array_like
        The values in ``from_unit``.
    from_unit : str
        Pint unit string of ``values``; ``""`` or ``"-"`` for dimensionless.
    to_unit : str
        Pint unit string wanted; ``""`` or ``"-"`` for dimensionless.

    Returns
    -------
    float or ndarray
        The converted values; a scalar comes back as float. ``values`` is returned unchanged when
        both units are dimensionless.

    Raises
    ------
    pint.DimensionalityError
        If the two units are of different dimensions (other pint errors for unknown units).
    """
    import numpy as np

    if (from_unit or "") in ("", "-") and (to_unit or "") in ("", "-"):
        return values
    ureg = _registry()
    q = ureg.Quantity(np.asarray(values, dtype=float), from_unit or "")
    out = q.to(to_unit or "dimensionless").magnitude
    return float(out) if np.ndim(out) == 0 else out


# ------------------------------------------------------------------------- display unit systems
#: Display kinds beyond the dimensions of :data:`SI_UNITS`: name -> dimension.
EXTRA_KINDS = {"diameter": "length"}

#: Short names accepted for kinds in per-quantity overrides (``--unit speed=rad/s``).
KIND_ALIASES = {"speed": "angular_velocity", "rotary_speed": "angular_velocity",
                "rop": "velocity", "weight": "force", "load": "force", "depth": "length",
                "mud_density": "density", "dls": "curvature", "dogleg_severity": "curvature",
                "stress": "pressure"}

#: Signals shown in a kind finer than their dimension: the depth of cut is a small length,
#: read in inches (oilfield) or millimetres (metric) like a diameter.
NAME_KINDS = {"depth_of_cut": "diameter"}

_SI_DISPLAY = dict(SI_UNITS, diameter="m")

_OILFIELD = {
    "length": "ft", "diameter": "in", "velocity": "ft/h", "angular_velocity": "rpm",
    "angle": "deg", "force": "klbf", "torque": "kft*lbf", "mass": "lb", "inertia": "lb*ft**2",
    "stiffness": "lbf/ft", "torsional_stiffness": "ft*lbf/rad", "damping": "lbf*s/ft",
    "torsional_damping": "ft*lbf*s/rad", "pressure": "psi", "time": "s", "density": "lb/gal",
    "area": "in**2", "second_moment": "in**4", "dimensionless": "", "acceleration": "ft/s**2",
    "curvature": "deg_per_100ft",
}

_METRIC = {
    "length": "m", "diameter": "mm", "velocity": "m/h", "angular_velocity": "rpm",
    "angle": "deg", "force": "kN", "torque": "kN*m", "mass": "kg", "inertia": "kg*m**2",
    "stiffness": "kN/m", "torsional_stiffness": "kN*m/rad", "damping": "kN*s/m",
    "torsional_damping": "N*m*s/rad", "pressure": "MPa", "time": "s", "density": "kg/m**3",
    "area": "mm**2", "second_moment": "cm**4", "dimensionless": "", "acceleration": "m/s**2",
    "curvature": "deg_per_30m",
}

#: Figures of the ``si`` system: SI with prefixes a plot reader expects, rotary speed in rpm.
_SI_FIGURES = dict(_SI_DISPLAY, velocity="mm/s", angular_velocity="rpm", angle="deg",
                   force="kN", torque="kN*m", pressure="MPa", curvature="deg_per_30m")

#: The named display systems: name -> (kind -> pint unit string).
SYSTEMS: dict[str, dict[str, str]] = {"si": _SI_DISPLAY, "metric": _METRIC,
                                      "oilfield": _OILFIELD}

_PRETTY = (("deg_per_100ft", "deg/100ft"), ("deg_per_30m", "deg/30m"), ("kft_lbf", "kft*lbf"),
           ("ft_lbf", "ft*lbf"), ("**2", "²"), ("**3", "³"), ("**4", "⁴"), ("^2", "²"),
           ("^3", "³"), ("^4", "⁴"), ("*", "·"))


def unit_label(unit: str) -> str:
    """A unit string as printed in tables and axis labels.

    ``"kft*lbf"`` -> ``"kft·lbf"``, ``"kg/m**3"`` -> ``"kg/m³"``, dimensionless -> ``"-"``.

    Parameters
    ----------
    unit : str or None
        Pint unit string; ``""``, ``"-"`` or None for dimensionless.

    Returns
    -------
    str
        The printable label.
    """
    if unit in ("", "-", None):
        return "-"
    for a, b in _PRETTY:
        unit = unit.replace(a, b)
    return unit


def _dimension_of_unit(unit: str | None) -> str | None:
    if unit is None:
        return None
    u = unit.replace(" ", "")
    if u in ("", "-", "1", "dimensionless"):
        return "dimensionless"
    for dim, si in SI_UNITS.items():
        if si == u:
            return dim
    return None


def _kind_dimension(kind: str) -> str:
    return EXTRA_KINDS.get(kind, kind)


def _declared(name: str):
    """(dimension, SI unit) of a declared signal or metric, or None."""
    from downhole.signals import METRICS, SIGNALS

    sig = SIGNALS.get(name)
    if sig is not None:
        return sig.dimension, sig.unit
    m = METRICS.get(name)
    if m is not None:
        return _dimension_of_unit(m.unit), m.unit
    return None


def parse_unit_override(text: str) -> tuple[str, str]:
    """``"torque=kN*m"`` -> ``("torque", "kN*m")``, checked (see :func:`display_units`).

    The key is a kind (a dimension of :data:`SI_UNITS`, ``diameter``, or an alias of
    :data:`KIND_ALIASES`) or the name of a declared signal or metric (``wob``, ``mean_rop``).

    Parameters
    ----------
    text : str
        The override, ``KEY=UNIT``.

    Returns
    -------
    (key, unit) : tuple of str
        The key and the pint unit string, stripped.

    Raises
    ------
    UnitError
        Not ``KEY=UNIT``, an unknown key, a unit pint does not know or of the wrong dimension.
    """
    if not isinstance(text, str) or "=" not in text:
        raise UnitError(f"unit override {text!r}: expected KIND=UNIT, e.g. torque=kN*m or "
                        "wob=kN")
    key, unit = (p.strip() for p in text.split("=", 1))
    _check_override(key, unit)
    return key, unit


def _check_override(key: str, unit: str) -> tuple[str, str]:
    """(dimension, SI unit) of override ``key``; raises :class:`UnitError` when ``unit`` does
    not fit."""
    kind = KIND_ALIASES.get(key, key)
    if kind in SI_UNITS or kind in EXTRA_KINDS:
        dim = _kind_dimension(kind)
        si = SI_UNITS[dim]
    else:
        decl = _declared(key)
        if decl is None or decl[0] is None:
            kinds = sorted(set(SI_UNITS) | set(EXTRA_KINDS) | set(KIND_ALIASES))
            raise UnitError(f"unit override {key}={unit}: unknown quantity {key!r}; expected a "
                            f"kind ({', '.join(kinds)}) or a signal or metric name")
        dim, si = decl
    if not isinstance(unit, str) or len(unit) > MAX_QUANTITY_LENGTH:
        raise UnitError(f"unit override {key}: expected a unit string of at most "
                        f"{MAX_QUANTITY_LENGTH} characters")
    if unit in ("", "-"):
        if dim in ("dimensionless", "angle"):
            return dim, si
        raise UnitError(f"unit override {key}=: a {dim.replace('_', ' ')} needs a unit "
                        f"(SI: {si})")
    try:
        _check_unit_expression(unit, unit)
    except UnitError:
        raise UnitError(f"unit override {key}={unit}: expected a unit expression such as "
                        "kN*m, ft/h or lb/gal (names joined by '*' and '/', small powers)"
                        ) from None
    ureg = _registry()
    try:
        ureg.Quantity(1.0, unit).to(si.replace("-", "") or "dimensionless")
    except pint.DimensionalityError:
        raise UnitError(f"unit override {key}={unit}: {unit} is not a unit of "
                        f"{dim.replace('_', ' ')} (SI: {si or '-'})") from None
    except Exception as exc:
        raise UnitError(f"unit override {key}={unit}: {exc}") from None
    return dim, si


@dataclass(frozen=True)
class UnitSystem:
    """A display unit system: the unit every result is shown in, by kind and by name.

    Internally everything stays SI; a UnitSystem converts at the edge (tables, ``summary.json``,
    plots, LAS, CSV, dashboards), always through pint. Build one with :func:`display_units`.

    Attributes
    ----------
    name : str
        ``si``, ``metric`` or ``oilfield`` (:data:`SYSTEMS`).
    overrides : dict
        Per-quantity units: kind (``torque``), alias (``speed``) or signal/metric name
        (``wob``, ``mean_rop``) -> pint unit string. A name beats its kind.
    figures : bool
        The figure variant of ``si`` (kN, kN·m, mm/s, rpm, MPa; :meth:`for_figures`).

    Examples
    --------
    >>> u = display_units("oilfield")
    >>> u.unit_of("wob"), u.unit_of("surface_torque"), u.unit_of("mean_rop")
    ('klbf', 'kft*lbf', 'ft/h')
    >>> v, unit = u.convert("bit_angular_velocity", 10.0)
    >>> round(v, 3), unit
    (95.493, 'rpm')
    >>> display_units("oilfield", {"torque": "kN*m"}).unit_of("tob")
    'kN*m'
    """

    name: str = "si"
    overrides: dict = field(default_factory=dict)
    figures: bool = False

    @property
    def kinds(self) -> dict[str, str]:
        """kind -> display unit, overrides of kinds applied."""
        base = dict(_SI_FIGURES if (self.figures and self.name == "si") else SYSTEMS[self.name])
        for key, unit in self.overrides.items():
            kind = KIND_ALIASES.get(key, key)
            if kind in base:
                base[kind] = unit
        return base

    def kind_unit(self, kind: str) -> str:
        """Display unit of a kind (``"torque"``, ``"diameter"``, ``"speed"``...).

        Parameters
        ----------
        kind : str
            A kind of :attr:`kinds` or an alias of :data:`KIND_ALIASES`.

        Returns
        -------
        str
            Pint unit string of that kind in this system (overrides applied).

        Raises
        ------
        KeyError
            If ``kind`` is unknown (the message lists the kinds).
        """
        kind = KIND_ALIASES.get(kind, kind)
        try:
            return self.kinds[kind]
        except KeyError:
            raise KeyError(f"unknown kind {kind!r}; kinds: {', '.join(sorted(self.kinds))}"
                           ) from None

    def _resolve(self, name: str, si_unit: str | None) -> tuple[str, str]:
        """(SI unit, display unit) of a signal/metric ``name`` (or of ``si_unit``)."""
        decl = _declared(name)
        if si_unit is None:
            si_unit = decl[1] if decl else ""
        dim = decl[0] if decl and si_unit.replace(" ", "") == decl[1] else \
            _dimension_of_unit(si_unit)
        if name in self.overrides:
            return si_unit, self.overrides[name]
        if dim is None:
            return si_unit, si_unit  # a unit of no known kind: shown as stored
        if dim == "dimensionless":
            return si_unit, si_unit
        kind = NAME_KINDS.get(name, dim)
        if _kind_dimension(kind) != dim:
            kind = dim
        return si_unit, self.kinds.get(kind, si_unit)

    def unit_of(self, name: str, si_unit: str | None = None) -> str:
        """Display unit of signal or metric ``name``.

        Parameters
        ----------
        name : str
            Signal or metric name (:mod:`downhole.signals`).
        si_unit : str, optional
            Stored (SI) unit of ``name``, for names not declared in :mod:`downhole.signals`
            (default: the declared unit).

        Returns
        -------
        str
            Pint unit string (``""``/``"-"`` dimensionless); a name override beats its kind.
        """
        return self._resolve(name, si_unit)[1]

    def label(self, name: str, si_unit: str | None = None) -> str:
        """Printed display unit of ``name`` (``"kft·lbf"``, ``"-"``).

        Parameters
        ----------
        name : str
            Signal or metric name.
        si_unit : str, optional
            Stored (SI) unit of ``name``, for names not declared in :mod:`downhole.signals`
            (default: the declared unit).

        Returns
        -------
        str
            :func:`unit_label` of :meth:`unit_of`.
        """
        return unit_label(self.unit_of(name, si_unit))

    def convert(self, name: str, values, si_unit: str | None = None):
        """``(values in the display unit, display unit)`` of SI ``values`` of ``name``.

        Parameters
        ----------
        name : str
            Signal or metric name.
        values : float or array_like
            Values in the stored SI unit; a number comes back as float.
        si_unit : str, optional
            Stored (SI) unit of ``name``, for names not declared in :mod:`downhole.signals`
            (default: the declared unit).

        Returns
        -------
        (values, unit) : tuple
            The converted values (unchanged when no conversion is needed) and the display unit
            string.
        """
        src, dst = self._resolve(name, si_unit)
        if dst == src or dst.replace(" ", "") == src.replace(" ", ""):
            return values, dst
        return convert(values, src, dst), dst

    def convert_summary(self, summary: dict, si_units: dict | None = None
                        ) -> tuple[dict, dict]:
        """``(values, units)`` of a summary dict of metrics in this system.

        Parameters
        ----------
        summary : dict
            Metric name -> value in SI; None and non-numbers are kept as is.
        si_units : dict, optional
            Metric name -> stored SI unit, for metrics not declared in :mod:`downhole.signals`.

        Returns
        -------
        values : dict
            Metric name -> value in the display unit.
        units : dict
            Metric name -> display unit string (``"-"`` for ratios).
        """
        values, units = {}, {}
        for k, v in summary.items():
            si = (si_units or {}).get(k)
            unit = self.unit_of(k, si)
            if isinstance(v, (int, float)) and not isinstance(v, bool) and v is not None:
                v = self.convert(k, float(v), si)[0]
            values[k] = v
            units[k] = unit if unit not in ("",) else "-"
        return values, units

    def for_figures(self) -> UnitSystem:
        """The units of figures: this system, except that ``si`` shows forces in kN, torques in
        kN·m, velocities in mm/s, rotary speeds in rpm and pressures in MPa."""
        return UnitSystem(self.name, dict(self.overrides), True)

    def to_dict(self) -> dict:
        """JSON-ready description: ``{"system": name, "kinds": {...}, "overrides": {...}}``."""
        return {"system": self.name, "kinds": self.kinds, "overrides": dict(self.overrides)}


def display_units(system="si", overrides=None, **units) -> UnitSystem:
    """A display :class:`UnitSystem` by name, with per-quantity overrides.

    Parameters
    ----------
    system : str or UnitSystem
        ``"si"`` (default: the stored SI units), ``"metric"`` (m/h, rpm, kN, kN·m, MPa) or
        ``"oilfield"`` (ft, ft/h, rpm, klbf, kft·lbf, psi, lb/gal, in, deg/100ft).
    overrides : dict or list of str, optional
        ``{"torque": "kN*m", "wob": "kN"}`` or ``["torque=kN*m", "wob=kN"]``.
    **units
        The same as keywords, welleng-style: ``display_units("oilfield", torque="kN*m")``.

    Returns
    -------
    UnitSystem

    Raises
    ------
    DownholeInputError
        An unknown system, a malformed override, an unknown quantity or a unit of the wrong
        dimension (one line naming it).
    """
    from downhole.errors import DownholeInputError

    if isinstance(system, UnitSystem):
        base, merged = system.name, dict(system.overrides)
    else:
        if not isinstance(system, str) or system.strip().lower() not in SYSTEMS:
            raise DownholeInputError(f"units: expected one of {', '.join(SYSTEMS)}, got "
                                     f"{system!r}")
        base, merged = system.strip().lower(), {}
    items = list(overrides.items() if isinstance(overrides, dict) else (overrides or []))
    items += list(units.items())
    try:
        for item in items:
            key, unit = (item if isinstance(item, tuple) else parse_unit_override(item))
            _check_override(key, unit)
            merged[key] = unit
    except UnitError as exc:
        raise DownholeInputError(str(exc)) from None
    return UnitSystem(base, merged)
