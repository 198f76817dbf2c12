"""Unit-aware parsing of user-typed quantities ("10 rad/s", "120 rpm", "30 m/h", "25 klbf").

Everything inside downhole is SI. Values typed by users (scenario files, CLI options) may carry
units, including the oilfield units drilling engineers think in; this module converts them to SI
with pint and raises a precise :class:`UnitError` otherwise.
"""

from __future__ import annotations

from functools import lru_cache

import pint

__all__ = ["UnitError", "to_si", "SI_UNITS"]

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


def to_si(value: float | int | str, dimension: str) -> float:
    """Convert ``value`` to the SI unit of ``dimension``.

    Parameters
    ----------
    value : float, int or str
        A bare number (taken as already SI) or a string with a unit, e.g. ``"120 rpm"``.
    dimension : str
        A key of :data:`SI_UNITS`, e.g. ``"angular_velocity"``.

    Returns
    -------
    float
        The value in SI units.

    Raises
    ------
    UnitError
        If the string cannot be parsed or its unit has the wrong dimension.

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
    if isinstance(value, (int, float)):
        return float(value)
    if not isinstance(value, str):
        raise UnitError(f"expected a number or a quantity string, got {type(value).__name__}")
    ureg = _registry()
    try:
        q = ureg.Quantity(value.strip())
    except Exception as exc:  # pint raises several error types
        raise UnitError(f"cannot parse quantity {value!r}: {exc}") from None
    target = SI_UNITS[dimension]
    if not isinstance(q, ureg.Quantity):
        q = ureg.Quantity(float(q), "")
    try:
        if target == "":
            return float(q.to("dimensionless").magnitude)
        # rad is dimensionless in pint, so rpm -> rad/s works, and "N*m" torque is accepted as-is.
        return float(q.to(target).magnitude)
    except pint.DimensionalityError:
        raise UnitError(
            f"quantity {value!r} has unit '{q.units}', which cannot be converted to {target}"
        ) from None
