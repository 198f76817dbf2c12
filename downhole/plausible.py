"""Plausibility, not only validity: the admissible range of every physical input on a real rig.

:data:`downhole.units.RANGES` refuses values no physics admits (a length of 1e6 m, a non-finite
speed). This module refuses values that are *valid but not plausible* for a drilling rig: a
rotary speed of 120 rad/s (1,146 rpm; a driller's bare "120" means rpm), a WOB of 25 N (25
klbf meant), a 5 m pipe (5 in meant), a mud of 10 kg/m^3 (10 lb/gal meant). There is one table,
:data:`PLAUSIBLE`, of the quantity kinds; :data:`FIELDS` says which scenario key is of which
kind, and :func:`check_scenario` applies both to a parsed scenario file before any schema sees
it (every loader calls it through :func:`downhole._schema.check_dialect`), together with the
geometry as a whole (:func:`check_geometry`: the bit inside the hole, every string OD below the
hole and the bit). Survey curvature (dogleg severity) and depth are checked where the stations
are read (:func:`check_dogleg`, :data:`MAX_DEPTH`).

A refusal names the field (1-based positions: ``string.segments[2]`` is the second segment),
the value as written and in the unit the range is quoted in, the range, and the likely fix::

    operation.surface_speed: 120 (a bare number is rad/s) = 1,146 rpm is above 400 rpm, the
    fastest top drives; did you mean "120 rpm"?

This module imports only :mod:`downhole.units` and :mod:`downhole.errors` (and, for the bit
of a preset, :mod:`downhole.params`, lazily): the well reader uses it. The ranges are documented in ``docs/scenarios.md``,
"Plausible ranges".
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from downhole.errors import ScenarioError
from downhole.units import MAX_ROTARY_SPEED, UnitError, parse_quantity_string, to_si

__all__ = [
    "FIELDS",
    "MAX_DEPTH",
    "MAX_DOGLEG",
    "MAX_HOOK_LOAD",
    "PLAUSIBLE",
    "Plausible",
    "check_dogleg",
    "check_geometry",
    "check_scenario",
    "check_value",
    "format_value",
]

_IN = 0.0254
_KN = 1e3
_MH = 1.0 / 3600.0
#: Deepest well (measured depth) on record is about 15 km (Sakhalin, 15.0 km; Kola, 12.3 km), m.
MAX_DEPTH = 15_000.0
#: The heaviest hook load a rig holds, N (1,000 t; the largest rigs are rated 1,000-1,400 short
#: tons).
MAX_HOOK_LOAD = 1.0e7
#: The sharpest curve (dogleg severity) of a well a rotating string passes: 30 deg/30 m
#: (1 deg/m, 30.5 deg/100 ft, the tight end of medium-radius wells), rad/m.
MAX_DOGLEG = math.radians(30.0) / 30.0


@dataclass(frozen=True)
class Plausible:
    """The plausible range of one kind of input.

    Attributes
    ----------
    name : str
        What it is, as messages say it (``"rotary speed"``).
    dimension : str
        Its dimension (a key of :data:`downhole.units.SI_UNITS`).
    low, high : float
        The range, SI, inclusive.
    unit : str
        The unit the range is quoted in (``"rpm"``).
    why_low, why_high : str
        Why a value below / above the range is not plausible (``"the fastest top drives"``).
    zero : bool
        Exactly 0 is accepted below ``low`` (no mud; a profile ramping from rest).
    fixes : tuple of str
        Units a number out of range most likely meant, tried in order: the first that brings
        it into the range is the suggested fix (``did you mean "120 rpm"?``).
    """

    name: str
    dimension: str
    low: float
    high: float
    unit: str
    why_low: str
    why_high: str
    zero: bool = False
    fixes: tuple[str, ...] = ()

    def contains(self, value: float) -> bool:
        """True when ``value`` (SI) is plausible.

        Parameters
        ----------
        value : float
            The value in the SI unit of :attr:`dimension`.

        Returns
        -------
        bool
        """
        return (self.zero and value == 0.0) or self.low <= value <= self.high


#: The plausible range of every kind of physical input on a real rig (SI; ``unit`` is how the
#: range is quoted). Documented in ``docs/scenarios.md``, "Plausible ranges".
PLAUSIBLE: dict[str, Plausible] = {
    "rotary_speed": Plausible(
        "rotary speed", "angular_velocity", 0.0, MAX_ROTARY_SPEED, "rpm",
        "a string does not turn backwards", "the fastest top drives", fixes=("rpm",)),
    "wob": Plausible(
        "weight on bit", "force", 1.0 * _KN, 700.0 * _KN, "kN",
        "a bit needs at least 1 kN to cut", "the heaviest loads of the largest bits",
        zero=True, fixes=("kN", "klbf")),
    "rop": Plausible(
        "rate of penetration", "velocity", 0.0, 250.0 * _MH, "m/h",
        "a bit does not drill backwards", "the fastest drilling in soft rock",
        fixes=("m/h", "ft/h", "mm/s")),
    "torque": Plausible(
        "torque", "torque", 100.0, 150.0 * _KN, "kN*m",
        "a bit or top drive turning a string needs at least 0.1 kN*m",
        "the strongest top drives and drill pipe connections",
        zero=True, fixes=("kN*m", "kft*lbf")),
    "hook_load": Plausible(
        "hook load", "force", 0.0, MAX_HOOK_LOAD, "kN",
        "a hook load is not negative", "the largest rigs' hook capacity",
        fixes=("kN", "klbf")),
    "pipe_od": Plausible(
        "string outer diameter", "length", 1.0 * _IN, 14.0 * _IN, "in",
        "the smallest tubulars (1 in coiled tubing)", "the largest drill collars",
        fixes=("in", "mm")),
    "pipe_id": Plausible(
        "string inner diameter", "length", 0.0, 12.0 * _IN, "in",
        "a bore is not negative", "the largest drill-pipe bores", fixes=("in", "mm")),
    "stabilizer_od": Plausible(
        "stabilizer outer diameter", "length", 2.0 * _IN, 36.0 * _IN, "in",
        "the smallest stabilizers", "the largest bits", fixes=("in", "mm")),
    "bit_radius": Plausible(
        "bit radius", "length", 1.75 * _IN, 18.0 * _IN, "in",
        "a 3.5 in bit, the smallest", "a 36 in bit, the largest", fixes=("in", "mm")),
    "hole_diameter": Plausible(
        "hole diameter", "length", 3.5 * _IN, 48.0 * _IN, "in",
        "the smallest bits (3.5 in)", "the largest holes drilled (36 in bits, underreamed)",
        fixes=("in", "mm")),
    "mud_density": Plausible(
        "mud density", "density", 500.0, 2600.0, "kg/m^3",
        "the lightest (foamed) muds; 0 means no mud",
        "the heaviest muds (21.7 lb/gal, specific gravity 2.6)",
        zero=True, fixes=("lb/gal", "g/cm^3")),
    "depth": Plausible(
        "length along the well", "length", 0.0, MAX_DEPTH, "m",
        "a length is not negative", "the deepest wells drilled (15 km)", fixes=("ft",)),
    "dogleg": Plausible(
        "dogleg severity", "curvature", 0.0, MAX_DOGLEG, "deg_per_30m",
        "a curvature is not negative",
        "the sharpest curve a rotating string passes (medium-radius wells)",
        fixes=("deg_per_30m", "deg_per_100ft")),
}

#: The kind (a key of :data:`PLAUSIBLE`) of every checked scenario key; ``[]`` stands for any
#: entry of a list of tables (``string.segments[]``). A value may be a number, a quantity
#: string or a profile ``[[t, value], ...]`` (each value checked).
FIELDS: dict[str, str] = {
    "operation.surface_speed": "rotary_speed",
    "operation.wob": "wob",
    "operation.rop": "rop",
    "operation.surface_torque": "torque",
    "operation.hook_load": "hook_load",
    "torque_drag.wob": "wob",
    "torque_drag.tob": "torque",
    "string.mud_density": "mud_density",
    "string.segments[].length": "depth",
    "string.segments[].outer_diameter": "pipe_od",
    "string.segments[].inner_diameter": "pipe_id",
    "string.stabilizers[].outer_diameter": "stabilizer_od",
    "string.stabilizers[].distance_from_bit": "depth",
    "well.hole_diameter": "hole_diameter",
    "well.sections[].length": "depth",
    "bit.radius": "bit_radius",
}

#: Display labels of the units ranges are quoted in.
_LABELS = {"deg_per_30m": "deg/30m", "deg_per_100ft": "deg/100ft"}


def _label(unit: str) -> str:
    return _LABELS.get(unit, unit)


def _number_text(x: float) -> str:
    """A number as a user writes it: ``120``, ``4.276``, ``1e+06``."""
    if float(x).is_integer() and abs(x) < 1e15:
        return str(int(x))
    return format(float(x), ".10g")


def _figure(x: float) -> str:
    """A converted value for a message: ``1,146``, ``12.25``, ``0.0025`` (4 digits)."""
    if abs(x) >= 100.0:
        return f"{x:,.0f}"
    return f"{x:.4g}"


def format_value(value: float, unit: str, dimension: str) -> str:
    """``value`` (SI) in ``unit``, as messages print it (``"1,146 rpm"``, ``"8.5 in"``).

    Parameters
    ----------
    value : float
        The value in the SI unit of ``dimension``.
    unit : str
        A unit of ``dimension`` (``"rpm"``, ``"in"``, ``"deg_per_30m"``).
    dimension : str
        A key of :data:`downhole.units.SI_UNITS`.

    Returns
    -------
    str
    """
    from downhole.units import SI_UNITS, convert

    shown = convert(value, SI_UNITS[dimension], unit)
    return f"{_figure(float(shown))} {_label(unit)}"


def _written(raw) -> tuple[str, float | None, str]:
    """(the value as written, its number, its unit ('' for a bare number))."""
    if isinstance(raw, str):
        try:
            number, unit = parse_quantity_string(raw)
        except UnitError:
            return raw, None, ""
        return raw, number, unit
    return _number_text(raw), float(raw), ""


def _fix(rng: Plausible, number: float, written_unit: str, prefer: tuple[str, ...]) -> str:
    """``; did you mean "N UNIT"?`` for the first unit of the fixes that makes ``number``
    plausible ('' when none does)."""
    order = [u for u in prefer if u in rng.fixes] + [u for u in rng.fixes if u not in prefer]
    for unit in order:
        if unit.replace(" ", "") == written_unit.replace(" ", ""):
            continue
        try:
            value = to_si(f"{_number_text(number)} {unit}", rng.dimension)
        except UnitError:
            continue
        if number != 0 and rng.contains(value):
            return f'; did you mean "{_number_text(number)} {unit}"?'
    return ""


def check_value(kind: str, raw, prefer: tuple[str, ...] = ()) -> float | None:
    """Refuse a value that is valid but not plausible for a real rig.

    Parameters
    ----------
    kind : str
        A key of :data:`PLAUSIBLE` (``"rotary_speed"``, ``"wob"``, ``"pipe_od"``, ...).
    raw : float or str
        The value as written: a bare number (SI) or a quantity string (``"120 rpm"``).
    prefer : tuple of str
        Units to try first for the fix (the file's unit system, e.g. ``("klbf", "ft/h")`` in an
        oilfield file).

    Returns
    -------
    float or None
        The value in SI when it is plausible; None when it is not a number of the kind's
        dimension at all (the schema then says what is wrong).

    Raises
    ------
    ValueError
        Outside the kind's range: the value as written, in the range's unit, the range and,
        when another unit makes the number plausible, the fix (``did you mean "120 rpm"?``).

    Examples
    --------
    >>> round(check_value("rotary_speed", "120 rpm"), 4)
    12.5664
    >>> check_value("wob", 25)
    Traceback (most recent call last):
    ...
    ValueError: 25 (a bare number is N) = 0.025 kN is below 1 kN, a bit needs at least 1 kN to cut; did you mean "25 kN"?
    """
    rng = PLAUSIBLE[kind]
    if isinstance(raw, bool) or not isinstance(raw, (int, float, str)):
        return None
    try:
        value = to_si(raw, rng.dimension)
    except UnitError:
        return None
    if rng.contains(value):
        return value
    text, number, unit = _written(raw)
    if not unit:
        from downhole.units import SI_UNITS

        si = SI_UNITS[rng.dimension].replace("**", "^") or "dimensionless"
        text = f"{text} (a bare number is {si})"
    shown = format_value(value, rng.unit, rng.dimension)
    if value > rng.high:
        bound, why = f"is above {format_value(rng.high, rng.unit, rng.dimension)}", rng.why_high
    else:
        bound, why = f"is below {format_value(rng.low, rng.unit, rng.dimension)}", rng.why_low
    fix = _fix(rng, number, unit, prefer) if number is not None else ""
    raise ValueError(f"{text} = {shown} {bound}, {why}{fix}")


# ------------------------------------------------------------------------------ scenario files
def _entries(data, dotted: str):
    """``(field as messages name it, raw value)`` of every value at ``dotted`` in ``data``
    (``[]``: each entry of a list, named 1-based)."""
    nodes = [("", data)]
    for part in dotted.split("."):
        listed = part.endswith("[]")
        key = part[:-2] if listed else part
        nxt = []
        for name, node in nodes:
            if not isinstance(node, dict) or key not in node:
                continue
            here = f"{name}.{key}" if name else key
            if listed:
                if isinstance(node[key], list):
                    nxt += [(f"{here}[{i}]", v) for i, v in enumerate(node[key], start=1)]
            else:
                nxt.append((here, node[key]))
        nodes = nxt
    return nodes


def _values(field: str, raw):
    """``(field, value)`` of a scalar or of each value of a profile ``[[t, value], ...]``
    (``operation.rop[2]``: the second breakpoint)."""
    if isinstance(raw, list):
        for i, pair in enumerate(raw, start=1):
            if isinstance(pair, list) and len(pair) == 2:
                yield f"{field}[{i}]", pair[1]
        return
    yield field, raw


def _oilfield(data: dict) -> bool:
    well = data.get("well")
    return isinstance(well, dict) and well.get("units") == "oilfield"


def check_scenario(data: dict, source: str) -> None:
    """Refuse implausible values of a scenario file: every key of :data:`FIELDS` in its range
    of :data:`PLAUSIBLE`, then the geometry as a whole (:func:`check_geometry`).

    Values that are not numbers of the right dimension are left to the schema, which names
    what is wrong with them.

    Parameters
    ----------
    data : dict
        The parsed file (before any schema).
    source : str
        The file, for messages.

    Raises
    ------
    ScenarioError
        Naming the file, the field (1-based positions) and, as :func:`check_value` does, the
        value, the range and the fix.
    """
    if not isinstance(data, dict):
        return
    prefer = ("klbf", "ft/h", "kft*lbf", "lb/gal", "ft", "in", "deg_per_100ft") \
        if _oilfield(data) else ()
    for dotted, kind in FIELDS.items():
        for field, raw in _entries(data, dotted):
            for name, value in _values(field, raw):
                try:
                    check_value(kind, value, prefer)
                except ValueError as exc:
                    raise ScenarioError(source, name, str(exc)) from None
    check_geometry(data, source)


def _bit_radius(data: dict):
    """``(bit radius SI, how the file gives it)`` or None when unknown."""
    bit = data.get("bit") if isinstance(data.get("bit"), dict) else {}
    if "radius" in bit:
        try:
            return to_si(bit["radius"], "length"), f"2 x bit.radius ({_written(bit['radius'])[0]})"
        except UnitError:
            return None
    model = data.get("model") if isinstance(data.get("model"), dict) else {}
    name = bit.get("preset", model.get("preset", "table_5_1"))
    try:
        from downhole.params import get_preset

        radius = float(get_preset(name).bit.radius)
    except Exception:  # an unknown preset: the schema says so
        return None
    return radius, f"2 x the radius of preset {name!r}'s bit"


def _segment_od(seg: dict, catalogue):
    """A segment's outer diameter (SI) and its unit as written, or None."""
    if "outer_diameter" in seg:
        try:
            return to_si(seg["outer_diameter"], "length"), _written(seg["outer_diameter"])[2]
        except UnitError:
            return None
    if isinstance(seg.get("catalogue"), str) and catalogue is not None:
        try:
            return float(catalogue(seg["catalogue"])), "in"
        except Exception:  # an unknown name: the schema says so
            return None
    return None


def check_geometry(data: dict, source: str, catalogue=None) -> None:
    """The geometry of a described well and string as a whole: the bit fits the hole, and
    every string segment is thinner than the hole and the bit, every stabilizer no wider than
    the hole.

    The hole diameter is ``[well] hole_diameter`` (default: the bit's diameter, twice
    ``[bit] radius`` or the radius of the preset's bit).

    Parameters
    ----------
    data : dict
        The parsed scenario file.
    source : str
        The file, for messages.
    catalogue : callable, optional
        Catalogue name -> outer diameter, m, for segments given by ``catalogue`` (skipped
        without it).

    Raises
    ------
    ScenarioError
        Naming the field (``string.segments[2].outer_diameter``), both diameters in the unit
        the field is written in and where the hole's and bit's diameters come from.
    """
    string = data.get("string")
    well = data.get("well") if isinstance(data.get("well"), dict) else {}
    bit = _bit_radius(data)
    if bit is None:
        return
    bit_d, bit_from = 2.0 * bit[0], bit[1]
    hole_d, hole_from = bit_d, f"the bit's diameter, {bit_from}; [well] hole_diameter unset"
    if "hole_diameter" in well:
        try:
            hole_d = to_si(well["hole_diameter"], "length")
        except UnitError:
            return
        hole_from = "well.hole_diameter"
        unit = _written(well["hole_diameter"])[2] or "m"
        if hole_d < bit_d:
            raise ScenarioError(source, "well.hole_diameter", (
                f"{format_value(hole_d, unit, 'length')} is below the bit's diameter, "
                f"{format_value(bit_d, unit, 'length')} ({bit_from}): a bit drills a hole at "
                "least its own size; check hole_diameter and the bit's radius (a radius, not a "
                "diameter?)"))
    if not isinstance(string, dict):
        return
    segments = string.get("segments")
    for k, seg in enumerate(segments if isinstance(segments, list) else [], start=1):
        got = _segment_od(seg, catalogue) if isinstance(seg, dict) else None
        if got is None:
            continue
        od, unit = got[0], got[1] or "m"
        for limit, what in ((bit_d, f"the bit's diameter, {{}} ({bit_from})"),
                            (hole_d, f"the hole's diameter, {{}} ({hole_from})")):
            if od >= limit:
                raise ScenarioError(source, f"string.segments[{k}].outer_diameter", (
                    f"{format_value(od, unit, 'length')} is not below "
                    + what.format(format_value(limit, unit, 'length'))
                    + ": the string must pass through the hole the bit drills; check the "
                    "segment's outer_diameter and the bit's radius (a radius, not a diameter?)"))
    stabs = string.get("stabilizers")
    for k, stab in enumerate(stabs if isinstance(stabs, list) else [], start=1):
        if not isinstance(stab, dict) or "outer_diameter" not in stab:
            continue
        try:
            od = to_si(stab["outer_diameter"], "length")
        except UnitError:
            continue
        unit = _written(stab["outer_diameter"])[2] or "m"
        if od > hole_d * (1.0 + 1e-9):
            raise ScenarioError(source, f"string.stabilizers[{k}].outer_diameter", (
                f"{format_value(od, unit, 'length')} is wider than the hole's diameter, "
                f"{format_value(hole_d, unit, 'length')} ({hole_from}): a stabilizer is at most "
                "full gauge; check its outer_diameter, the bit's radius or [well] "
                "hole_diameter"))


def check_dogleg(md, inclination, azimuth, *, length_unit: str = "m", degrees: bool = True):
    """The first survey interval whose dogleg severity is implausible, or None.

    Parameters
    ----------
    md : array_like
        Measured depths of the stations, in ``length_unit``.
    inclination, azimuth : array_like
        Station angles, deg (rad with ``degrees=False``).
    length_unit : {"m", "ft"}
        Unit of ``md``; the severity is quoted per 30 m, or per 100 ft for a survey in feet.
    degrees : bool
        Angles in degrees.

    Returns
    -------
    (int, str) or None
        The 0-based index of the station that ends the interval and the message (``dogleg
        severity of 45 deg/30m between MD 1000 and 1010 m is above 30 deg/30m, ...``).
    """
    import numpy as np

    md = np.asarray(md, float)
    inc, azi = np.asarray(inclination, float), np.asarray(azimuth, float)
    if degrees:
        inc, azi = np.radians(inc), np.radians(azi)
    scale = 0.3048 if length_unit == "ft" else 1.0
    t = np.stack([np.sin(inc) * np.cos(azi), np.sin(inc) * np.sin(azi), np.cos(inc)], axis=-1)
    rng = PLAUSIBLE["dogleg"]
    unit = "deg_per_100ft" if length_unit == "ft" else "deg_per_30m"
    for i in range(1, len(md)):
        ds = (md[i] - md[i - 1]) * scale
        if not ds > 0:
            continue
        beta = math.acos(float(np.clip(np.dot(t[i - 1], t[i]), -1.0, 1.0)))
        if beta / ds > rng.high:
            return i, (f"dogleg severity {format_value(beta / ds, unit, 'curvature')} "
                       f"({math.degrees(beta):.3g} deg over {_figure(md[i] - md[i - 1])} "
                       f"{length_unit}, MD {_figure(md[i - 1])} to {_figure(md[i])} "
                       f"{length_unit}) is above "
                       f"{format_value(rng.high, unit, 'curvature')}, {rng.why_high}; check "
                       "the stations' units (inclination and azimuth in degrees, MD in "
                       f"{'feet' if length_unit == 'ft' else 'metres'})")
    return None
