"""Well paths along measured depth: sections, survey stations and minimum-curvature geometry.

A :class:`WellPath` is an immutable list of survey stations (measured depth, inclination,
azimuth) joined by minimum-curvature arcs, the industry convention (SPE/ISCWSA, ``welleng``).
Sections (:class:`Vertical`, :class:`Tangent`, :class:`Arc`, :class:`BuildTurn`) are turned into
stations; surveys are read from CSV in SI or oilfield units. Queries take measured depths and
return inclination, azimuth, curvature, true vertical depth, position and tangent vectors.

Coordinates: north, east, TVD (down), metres. Angles in radians inside; inclination 0 is
vertical down, azimuth from north towards east.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from downhole.errors import DownholeInputError
from downhole.plausible import MAX_DEPTH
from downhole.units import _is_quantity, as_si_array, si_or_number

__all__ = [
    "Arc",
    "BuildTurn",
    "Tangent",
    "Vertical",
    "WellPath",
    "minimum_curvature",
    "read_survey_csv",
]

_FT = 0.3048


# ----------------------------------------------------------------------------------- sections
def _quantities(obj, dims: dict) -> None:
    """Convert the quantity fields (strings such as ``"3000 ft"``, pint Quantities) of a
    frozen section to SI floats; numbers are SI and keep the checks of the path builder."""
    for name, dim in dims.items():
        value = getattr(obj, name)
        if value is not None:
            object.__setattr__(obj, name, si_or_number(value, dim,
                                                       f"{type(obj).__name__}.{name}"))


@dataclass(frozen=True)
class Vertical:
    """Straight vertical section of ``length`` m (inclination 0).

    Every section takes numbers in SI (m, rad) or quantities: ``Vertical("3000 ft")``,
    ``Arc("1000 ft", "30 deg")``.
    """

    length: float

    def __post_init__(self):
        _quantities(self, {"length": "length"})


@dataclass(frozen=True)
class Tangent:
    """Straight section of ``length`` m keeping the current inclination and azimuth."""

    length: float

    def __post_init__(self):
        _quantities(self, {"length": "length"})


@dataclass(frozen=True)
class Arc:
    """Circular arc of ``radius`` m turning the tangent by ``angle`` rad (dogleg).

    ``toolface`` (rad) sets the plane: 0 builds (inclination grows), pi drops, +pi/2 turns right.
    From a vertical tangent the arc builds towards ``azimuth`` (rad, default 0 = north).
    """

    radius: float
    angle: float
    toolface: float = 0.0
    azimuth: float | None = None

    def __post_init__(self):
        _quantities(self, {"radius": "length", "angle": "angle", "toolface": "angle",
                           "azimuth": "angle"})


@dataclass(frozen=True)
class BuildTurn:
    """Minimum-curvature section of ``length`` m ending at ``inclination`` and ``azimuth`` (rad)."""

    length: float
    inclination: float
    azimuth: float

    def __post_init__(self):
        _quantities(self, {"length": "length", "inclination": "angle", "azimuth": "angle"})


# ------------------------------------------------------------------------------- geometry core
def _tangent(inc, azi):
    inc = np.asarray(inc, float)
    azi = np.asarray(azi, float)
    return np.stack([np.sin(inc) * np.cos(azi), np.sin(inc) * np.sin(azi), np.cos(inc)], axis=-1)


def _inc_azi(t):
    t = np.asarray(t, float)
    t = t / np.linalg.norm(t, axis=-1, keepdims=True)
    inc = np.arccos(np.clip(t[..., 2], -1.0, 1.0))
    azi = np.mod(np.arctan2(t[..., 1], t[..., 0]), 2 * math.pi)
    return inc, azi


def _dogleg(t1, t2) -> float:
    """Angle between unit tangents t1 and t2, rad: arccos of their dot product, and below
    1e-6 rad 2 arcsin(|t2 - t1| / 2) (arccos near 1 loses half the digits: equal tangents
    of a straight interval would turn by ~1e-8 rad)."""
    beta = math.acos(float(np.clip(np.dot(t1, t2), -1.0, 1.0)))
    if beta < 1e-6:
        beta = 2.0 * math.asin(min(1.0, 0.5 * float(np.linalg.norm(t2 - t1))))
    return beta


def minimum_curvature(md, inc, azi, start=(0.0, 0.0, 0.0)):
    """Positions of survey stations by the minimum-curvature method.

    Parameters
    ----------
    md, inc, azi : array_like
        Measured depth (m), inclination and azimuth (rad) of the stations.
    start : sequence of 3 floats
        North, east, TVD of the first station, m.

    Returns
    -------
    ndarray, shape (n, 3)
        North, east, TVD of each station, m.

    Examples
    --------
    >>> import numpy as np
    >>> p = minimum_curvature([0, 100], [0, 0], [0, 0])
    >>> float(p[-1, 2])
    100.0
    """
    md = np.asarray(md, float)
    t = _tangent(inc, azi)
    pos = np.zeros((md.size, 3))
    pos[0] = start
    for i in range(md.size - 1):
        dmd = md[i + 1] - md[i]
        beta = _dogleg(t[i], t[i + 1])
        rf = 1.0 if beta < 1e-9 else 2.0 / beta * math.tan(beta / 2.0)
        pos[i + 1] = pos[i] + dmd / 2.0 * (t[i] + t[i + 1]) * rf
    return pos


def _check_stations(md, inc, azi):
    md = np.asarray(md, float).ravel()
    inc = np.asarray(inc, float).ravel()
    azi = np.asarray(azi, float).ravel()
    if not (md.size == inc.size == azi.size):
        raise DownholeInputError(
            f"survey columns differ in length: md {md.size}, inclination {inc.size}, "
            f"azimuth {azi.size}")
    if md.size < 2:
        raise DownholeInputError(f"a survey needs at least 2 stations, got {md.size}")
    for name, arr in (("measured depth", md), ("inclination", inc), ("azimuth", azi)):
        bad = np.flatnonzero(~np.isfinite(arr))
        if bad.size:
            raise DownholeInputError(f"{name} of station {bad[0]} is not finite ({arr[bad[0]]})")
    dmd = np.diff(md)
    bad = np.flatnonzero(dmd <= 0)
    if bad.size:
        i = bad[0]
        raise DownholeInputError(
            f"measured depth must increase strictly: station {i + 1} has md = {md[i + 1]:g} m "
            f"after md = {md[i]:g} m at station {i}")
    bad = np.flatnonzero((inc < -1e-12) | (inc > math.pi + 1e-12))
    if bad.size:
        i = bad[0]
        raise DownholeInputError(
            f"inclination of station {i} (md = {md[i]:g} m) is {math.degrees(inc[i]):g} deg; "
            "expected 0 to 180 deg")
    return md, np.clip(inc, 0.0, math.pi), np.mod(azi, 2 * math.pi)


# ----------------------------------------------------------------------------------- WellPath
class WellPath:
    """An immutable well trajectory: survey stations joined by minimum-curvature arcs.

    Parameters
    ----------
    md, inclination, azimuth : array_like
        Stations: measured depth (m, strictly increasing), inclination (rad, 0..pi) and
        azimuth (rad). Use :meth:`from_sections` or :meth:`from_survey` for friendlier input.
    start : sequence of 3 floats
        North, east, TVD of the first station, m.

    Raises
    ------
    DownholeInputError
        Non-monotonic measured depth, inclination outside [0, 180] deg, too few stations.

    Examples
    --------
    >>> import math
    >>> w = WellPath.from_sections([Vertical(2000), Arc(4000, math.radians(30))])
    >>> round(float(w.tvd(w.total_depth)), 1)
    4000.0
    """

    def __init__(self, md, inclination, azimuth, start=(0.0, 0.0, 0.0)):
        md, inc, azi = _check_stations(md, inclination, azimuth)
        self._md, self._inc, self._azi = md, inc, azi
        for a in (md, inc, azi):
            a.setflags(write=False)
        self._t = _tangent(inc, azi)
        self._pos = minimum_curvature(md, inc, azi, start)
        n = md.size - 1
        self._beta = np.empty(n)
        for i in range(n):
            self._beta[i] = _dogleg(self._t[i], self._t[i + 1])

    # --- constructors ------------------------------------------------------------------------
    @classmethod
    def from_sections(cls, sections, inclination: float = 0.0, azimuth: float = 0.0,
                      start=(0.0, 0.0, 0.0)) -> WellPath:
        """Build a path from sections, starting at ``inclination``/``azimuth`` (rad).

        Raises
        ------
        DownholeInputError
            A section with a non-positive length, radius or angle, or an unknown section type.
        """
        if not sections:
            raise DownholeInputError("sections is empty: give at least one section")
        inclination = si_or_number(inclination, "angle", "inclination")
        azimuth = si_or_number(azimuth, "angle", "azimuth")
        start = tuple(si_or_number(x, "length", "start") for x in start)
        md, inc, azi = [0.0], [float(inclination)], [float(azimuth)]
        for k, s in enumerate(sections):
            if isinstance(s, (Vertical, Tangent)):
                if not s.length > 0:
                    raise DownholeInputError(
                        f"section {k} ({type(s).__name__}): length must be > 0 m, got {s.length}")
                if isinstance(s, Vertical) and inc[-1] != 0.0:
                    # a vertical section after a deviated one: new station kinks the path
                    raise DownholeInputError(
                        f"section {k} (Vertical) follows a section ending at inclination "
                        f"{math.degrees(inc[-1]):g} deg; use Tangent or an Arc first")
                md.append(md[-1] + s.length)
                inc.append(inc[-1])
                azi.append(azi[-1])
            elif isinstance(s, Arc):
                if not s.radius > 0:
                    raise DownholeInputError(f"section {k} (Arc): radius must be > 0 m, got {s.radius}")
                if not (0 < s.angle < math.pi):
                    raise DownholeInputError(
                        f"section {k} (Arc): angle must be in (0, 180) deg, got "
                        f"{math.degrees(s.angle):g} deg")
                t = _tangent(inc[-1], azi[-1])
                if inc[-1] < 1e-12:
                    az = azi[-1] if s.azimuth is None else s.azimuth
                    high = np.array([math.cos(az), math.sin(az), 0.0])  # build towards az
                    right = np.array([-math.sin(az), math.cos(az), 0.0])
                else:
                    high = np.array([math.cos(inc[-1]) * math.cos(azi[-1]),
                                     math.cos(inc[-1]) * math.sin(azi[-1]), -math.sin(inc[-1])])
                    right = np.array([-math.sin(azi[-1]), math.cos(azi[-1]), 0.0])
                nvec = math.cos(s.toolface) * high + math.sin(s.toolface) * right
                t2 = t * math.cos(s.angle) + nvec * math.sin(s.angle)
                i2, a2 = _inc_azi(t2)
                md.append(md[-1] + s.radius * s.angle)
                inc.append(float(i2))
                azi.append(float(a2) if float(i2) > 1e-12 else azi[-1])
            elif isinstance(s, BuildTurn):
                if not s.length > 0:
                    raise DownholeInputError(f"section {k} (BuildTurn): length must be > 0 m, got {s.length}")
                if not (0 <= s.inclination <= math.pi):
                    raise DownholeInputError(
                        f"section {k} (BuildTurn): inclination {math.degrees(s.inclination):g} "
                        "deg outside 0..180 deg")
                md.append(md[-1] + s.length)
                inc.append(float(s.inclination))
                azi.append(float(s.azimuth))
            else:
                raise DownholeInputError(
                    f"section {k}: unknown section type {type(s).__name__}; expected Vertical, "
                    "Tangent, Arc or BuildTurn")
        return cls(md, inc, azi, start)

    @classmethod
    def from_survey(cls, md, inclination, azimuth, *, degrees: bool = True,
                    length_unit: str = "m", start=(0.0, 0.0, 0.0)) -> WellPath:
        """Path from survey columns; ``degrees`` for the angles, ``length_unit`` "m" or "ft".

        Columns may also be pint Quantity arrays or sequences of quantity strings
        (``["0 ft", "1000 ft"]``); those carry their own units and ignore ``degrees`` and
        ``length_unit``.
        """
        scale = _length_scale(length_unit)
        ang = math.pi / 180.0 if degrees else 1.0
        if _has_units(md):
            md, scale = as_si_array(md, "length", "md"), 1.0
            start = tuple(si_or_number(x, "length", "start") for x in start)
        if _has_units(inclination) or _has_units(azimuth):
            inc = as_si_array(inclination, "angle", "inclination").ravel()
            azi = as_si_array(azimuth, "angle", "azimuth").ravel()
            return cls(np.asarray(md, float) * scale, inc, azi,
                       tuple(float(x) * scale for x in start))
        inc = np.asarray(inclination, float).ravel()
        if degrees:
            bad = np.flatnonzero((inc < 0) | (inc > 180))
            if bad.size:
                raise DownholeInputError(
                    f"inclination of station {bad[0]} is {inc[bad[0]]:g} deg; expected 0 to 180 deg")
        return cls(np.asarray(md, float) * scale, inc * ang, np.asarray(azimuth, float) * ang,
                   tuple(float(x) * scale for x in start))

    @classmethod
    def table_5_1(cls, params=None) -> WellPath:
        """The seed's Table 5.1 well: AB vertical 2000 m, BC vertical 1000 m, CD arc R 4000 m, 30 deg."""
        from downhole.params import DirectionalWellParams

        p = params or DirectionalWellParams()
        return cls.from_sections([Vertical(p.length_ab), Vertical(p.length_bc),
                                  Arc(p.arc_radius_cd, p.arc_angle_cd)])

    # --- stations ----------------------------------------------------------------------------
    @property
    def stations(self) -> dict:
        """Station arrays: ``md``, ``inclination``, ``azimuth`` (rad), ``north``, ``east``, ``tvd``."""
        return {"md": self._md.copy(), "inclination": self._inc.copy(),
                "azimuth": self._azi.copy(), "north": self._pos[:, 0].copy(),
                "east": self._pos[:, 1].copy(), "tvd": self._pos[:, 2].copy()}

    @property
    def total_depth(self) -> float:
        """Measured depth of the last station, m."""
        return float(self._md[-1])

    @property
    def top_depth(self) -> float:
        return float(self._md[0])

    # --- queries -----------------------------------------------------------------------------
    def _locate(self, md):
        # queries take metres, quantity strings ("3000 ft") or pint quantities
        md = as_si_array(md, "length", "measured depth") if _has_units(md) else \
            np.asarray(md, float)
        if np.any(~np.isfinite(md)):
            raise DownholeInputError("measured depth query contains non-finite values")
        lo, hi = self._md[0], self._md[-1]
        tol = 1e-9 * max(1.0, hi)
        if np.any(md < lo - tol) or np.any(md > hi + tol):
            raise DownholeInputError(
                f"measured depth query outside the path: got {md.min():g}..{md.max():g} m, "
                f"path spans {lo:g}..{hi:g} m")
        md = np.clip(md, lo, hi)
        i = np.clip(np.searchsorted(self._md, md, side="right") - 1, 0, self._md.size - 2)
        f = (md - self._md[i]) / (self._md[i + 1] - self._md[i])
        return md, i, f

    def _frame(self, i, f):
        """Tangent and position at fraction f of interval i (vectorised)."""
        t1, t2 = self._t[i], self._t[i + 1]
        beta = self._beta[i]
        L = self._md[i + 1] - self._md[i]
        f = np.asarray(f, float)
        small = beta < 1e-9
        sb = np.where(small, 1.0, np.sin(beta))
        w1 = np.where(small, 1.0 - f, np.sin((1 - f) * beta) / sb)
        w2 = np.where(small, f, np.sin(f * beta) / sb)
        t = w1[..., None] * t1 + w2[..., None] * t2
        t = t / np.linalg.norm(t, axis=-1, keepdims=True)
        # position: p1 + R (sin(f b) t1 + (1 - cos(f b)) n), n = (t2 - t1 cos b)/sin b
        bs = np.where(small, 1.0, beta)
        R = L / bs
        nvec = (t2 - t1 * np.cos(beta)[..., None]) / sb[..., None]
        arc = (R * np.sin(f * beta))[..., None] * t1 + (R * (1 - np.cos(f * beta)))[..., None] * nvec
        straight = (f * L)[..., None] * t1
        pos = self._pos[i] + np.where(small[..., None], straight, arc)
        kappa = np.where(small, 0.0, beta / L)
        # dt/ds = kappa * (unit vector normal to t in the arc plane)
        nrm = nvec - np.sum(nvec * t, axis=-1, keepdims=True) * t
        nn = np.linalg.norm(nrm, axis=-1, keepdims=True)
        dtds = np.where(small[..., None], 0.0, kappa[..., None] * nrm / np.where(nn > 0, nn, 1.0))
        return t, pos, kappa, dtds

    def _frame_at(self, md):
        """:meth:`_frame` (tangent, position, curvature, dt/ds) at measured depth ``md``."""
        _, i, f = self._locate(md)
        return self._frame(i, f)

    def tangent(self, md) -> np.ndarray:
        """Unit tangent (north, east, down) at ``md``, shape (..., 3)."""
        return self._frame_at(md)[0]

    def position(self, md) -> np.ndarray:
        """North, east, TVD at ``md``, m, shape (..., 3)."""
        return self._frame_at(md)[1]

    def tvd(self, md) -> np.ndarray:
        """True vertical depth at ``md``, m."""
        return self.position(md)[..., 2]

    def inclination(self, md) -> np.ndarray:
        """Inclination at ``md``, rad (0 = vertical down)."""
        return _inc_azi(self.tangent(md))[0]

    def azimuth(self, md) -> np.ndarray:
        """Azimuth at ``md``, rad (from north towards east)."""
        return _inc_azi(self.tangent(md))[1]

    def curvature(self, md) -> np.ndarray:
        """Curvature (dogleg severity) at ``md``, rad/m; piecewise constant between stations."""
        return self._frame_at(md)[2]

    def curvature_vector(self, md) -> np.ndarray:
        """dt/ds at ``md``, 1/m, shape (..., 3)."""
        return self._frame_at(md)[3]

    # --- survey quantities -------------------------------------------------------------------
    def _rates(self, md):
        """Rates of inclination and azimuth change d(inc)/ds, d(azi)/ds (rad/m) at ``md``.

        From the minimum-curvature arc: dt/ds projected on the inclination and azimuth unit
        vectors, d(inc)/ds = dt/ds . e_inc and d(azi)/ds = dt/ds . e_azi / sin(inc); the turn
        rate is 0 where the path is vertical (azimuth undefined)."""
        _, i, f = self._locate(md)
        t, _, _, dtds = self._frame(i, f)
        inc, azi = _inc_azi(t)
        e_inc = np.stack([np.cos(inc) * np.cos(azi), np.cos(inc) * np.sin(azi), -np.sin(inc)],
                         axis=-1)
        e_azi = np.stack([-np.sin(azi), np.cos(azi), np.zeros_like(azi)], axis=-1)
        build = np.sum(dtds * e_inc, axis=-1)
        s = np.sin(inc)
        vertical = s < 1e-9
        turn = np.where(vertical, 0.0, np.sum(dtds * e_azi, axis=-1) / np.where(vertical, 1.0, s))
        return build, turn

    def dogleg_severity(self, md, per: float = 30.0) -> np.ndarray:
        """Dogleg severity at ``md`` in degrees per ``per`` metres (30 m; 30.48 m = 100 ft).

        The curvature of the minimum-curvature arc, piecewise constant between stations:
        ``degrees(beta / dMD) * per`` for the interval's dogleg angle ``beta``."""
        return np.degrees(self.curvature(md)) * float(per)

    def build_rate(self, md) -> np.ndarray:
        """Build rate d(inc)/ds at ``md``, rad/m (positive builds, negative drops)."""
        return self._rates(md)[0]

    def turn_rate(self, md) -> np.ndarray:
        """Turn rate d(azi)/ds at ``md``, rad/m (positive turns right, towards east from north);
        0 where the path is vertical."""
        return self._rates(md)[1]

    def closure(self) -> tuple[float, float]:
        """Closure distance (m) and azimuth (rad, 0..2 pi) of the last station from the first
        (horizontal departure and its direction); azimuth 0 without departure."""
        d = self._pos[-1, :2] - self._pos[0, :2]
        dist = float(np.hypot(d[0], d[1]))
        azi = float(np.mod(math.atan2(d[1], d[0]), 2 * math.pi)) if dist > 1e-9 else 0.0
        return dist, azi

    def vertical_section(self, md, azimuth: float | None = None) -> np.ndarray:
        """Vertical section at ``md``, m: the horizontal departure from the first station
        projected on ``azimuth`` (rad; default the closure azimuth, :meth:`closure`),
        ``VS = dN cos(az) + dE sin(az)``."""
        az = self.closure()[1] if azimuth is None else float(azimuth)
        if not math.isfinite(az):
            raise DownholeInputError(f"vertical-section azimuth must be finite, got {azimuth!r}")
        p = self.position(md)
        return ((p[..., 0] - self._pos[0, 0]) * math.cos(az)
                + (p[..., 1] - self._pos[0, 1]) * math.sin(az))

    def __repr__(self) -> str:
        return (f"WellPath({self._md.size} stations, md {self._md[0]:g}..{self._md[-1]:g} m, "
                f"max inclination {math.degrees(self._inc.max()):.1f} deg)")


def _has_units(values) -> bool:
    """True for a pint Quantity or a sequence holding quantity strings or Quantities."""
    if _is_quantity(values) or isinstance(values, str):
        return True
    if isinstance(values, np.ndarray) and values.dtype.kind in "fiub":
        return False
    try:
        return any(isinstance(v, str) or _is_quantity(v) for v in values)
    except TypeError:
        return False


def _length_scale(unit: str) -> float:
    u = unit.strip().lower()
    if u in ("m", "meter", "metre", "si"):
        return 1.0
    if u in ("ft", "foot", "feet", "oilfield"):
        return _FT
    raise DownholeInputError(f"length_unit must be 'm' or 'ft', got {unit!r}")


_MD_NAMES = ("md", "measured_depth", "measured depth", "depth", "md_m", "md_ft", "md (m)", "md (ft)")
_INC_NAMES = ("inc", "inclination", "incl", "inc_deg", "inc (deg)")
_AZI_NAMES = ("azi", "az", "azimuth", "azi_deg", "azi (deg)", "azimuth (deg)")


#: Largest survey file read, bytes (a survey of 100,000 stations is ~3 MB).
MAX_SURVEY_BYTES = 32 * 2**20
#: Deepest measured depth of a plausible survey, m (the longest wells drilled reach ~15 km).
MAX_SURVEY_MD = MAX_DEPTH
_DELIMITERS = ",;\t "


def _survey_header(cells: list[str]) -> tuple[int, int, int] | None:
    """Column indices of MD, INC, AZI when ``cells`` is a survey header, else None."""
    header = [c.strip().lower() for c in cells]
    try:
        return (next(k for k, h in enumerate(header) if h in _MD_NAMES),
                next(k for k, h in enumerate(header) if h in _INC_NAMES),
                next(k for k, h in enumerate(header) if h in _AZI_NAMES))
    except StopIteration:
        return None


def read_survey_csv(path, *, units: str | None = None, angle_unit: str = "deg") -> WellPath:
    """Read a survey CSV with columns MD, INC, AZI (header names case-insensitive).

    Title lines above the header are skipped (the header is the first line that names the three
    columns); the delimiter (comma, semicolon, tab or spaces) is sniffed from the header line;
    ``#`` lines and blank lines are ignored. The file must be a regular file of at most
    :data:`MAX_SURVEY_BYTES`; its contents are never echoed in a message (a path naming some
    other file of the host gets "no survey header", not its first line). Positions in messages
    are the file's 1-based line numbers; values are in the file's units.

    Parameters
    ----------
    path : path-like
        CSV file with a header row naming measured depth (``md``/``measured_depth``),
        inclination (``inc``/``inclination``) and azimuth (``azi``/``azimuth``).
    units : {"si", "oilfield"}, optional
        Measured depth in metres (``si``) or feet (``oilfield``). Default: what the header says
        (``md_ft`` or ``MD (ft)``: feet; ``md_m`` or ``MD (m)``: metres), else metres. Given
        and contradicting the header, the file is refused.
    angle_unit : {"deg", "rad"}
        Unit of inclination and azimuth.

    Returns
    -------
    WellPath

    Raises
    ------
    DownholeInputError
        Missing or special file, no header, a non-numeric cell, a depth that does not increase,
        an inclination outside 0-180 deg or an azimuth outside 0-360 deg (as written, before any
        reduction), an interval whose dogleg severity is above
        :data:`downhole.plausible.MAX_DOGLEG` (30 deg/30 m), ``units`` contradicting the
        header's unit, or a deepest station beyond :data:`MAX_SURVEY_MD` (with the hint to say
        ``units = "oilfield"`` when the depths look like feet); each names the file, its line
        and the column.
    """
    from downhole._reader import read_regular_file

    p = Path(path)
    if units not in (None, "si", "oilfield"):
        raise DownholeInputError(f"units must be 'si' or 'oilfield', got {units!r}")
    if angle_unit not in ("deg", "rad"):
        raise DownholeInputError(f"angle_unit must be 'deg' or 'rad', got {angle_unit!r}")
    raw = read_regular_file(p, MAX_SURVEY_BYTES, "a survey CSV (MD, INC, AZI)")
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise DownholeInputError(f"{p}: not a text file (not UTF-8); expected a survey CSV "
                                 "with columns MD, INC, AZI") from None
    if "\x00" in text:
        raise DownholeInputError(f"{p}: not a text file (NUL bytes); expected a survey CSV")
    lines = text.splitlines()
    found = None
    for n, line in enumerate(lines[:200], start=1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        for delim in _DELIMITERS:
            cells = line.split() if delim == " " else next(csv.reader([line], delimiter=delim))
            cols = _survey_header(cells)
            if cols is not None:
                found = (n, delim, cells, cols)
                break
        if found:
            break
    if found is None:
        raise DownholeInputError(
            f"{p}: no survey header in its first lines: expected a line naming the columns "
            f"measured depth ({'/'.join(_MD_NAMES[:2])}), inclination "
            f"({'/'.join(_INC_NAMES[:2])}) and azimuth ({'/'.join(_AZI_NAMES[:2])}), separated "
            "by commas, semicolons, tabs or spaces")
    hline, delim, cells, (imd, iinc, iazi) = found
    names = [c.strip() for c in cells]
    md_name = names[imd].lower()
    length_unit = "ft" if units == "oilfield" else "m"
    said = "ft" if "ft" in md_name else "m" if (md_name.endswith("_m") or "(m)" in md_name) \
        else None
    if said is not None and units is not None and said != length_unit:
        raise DownholeInputError(
            f"{p}: line {hline}, column {names[imd]!r}: the header says measured depth in "
            f"{'feet' if said == 'ft' else 'metres'}, but units = {units!r} says "
            f"{'feet' if length_unit == 'ft' else 'metres'}; did you mean units = "
            f"\"{'oilfield' if said == 'ft' else 'si'}\"?")
    if said is not None:
        length_unit = said
    ang = "deg" if angle_unit == "deg" else "rad"
    rows, where = [], []
    for n, line in enumerate(lines[hline:], start=hline + 1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        row = line.split() if delim == " " else next(csv.reader([line], delimiter=delim))
        vals = []
        for k in (imd, iinc, iazi):
            cell = row[k].strip() if k < len(row) else ""
            try:
                v = float(cell)
            except ValueError:
                v = math.nan
            if not math.isfinite(v):
                what = "is missing" if not cell else "is not a finite number"
                raise DownholeInputError(f"{p}: line {n}, column {names[k]!r}: {what}")
            vals.append(v)
        rows.append(vals)
        where.append(n)
    if len(rows) < 2:
        raise DownholeInputError(f"{p}: expected at least 2 stations below the header (line "
                                 f"{hline}), got {len(rows)}")
    data = np.array(rows)
    full = 180.0 if ang == "deg" else math.pi
    for r, n in enumerate(where):
        md, inc, azi = data[r]
        if not 0.0 <= inc <= full:
            raise DownholeInputError(f"{p}: line {n}, column {names[iinc]!r}: inclination "
                                     f"{inc:g} {ang} is outside 0 to {full:g} {ang}")
        if not 0.0 <= azi <= 2.0 * full:
            raise DownholeInputError(f"{p}: line {n}, column {names[iazi]!r}: azimuth "
                                     f"{azi:g} {ang} is outside 0 to {2 * full:g} {ang}")
        if md < 0.0:
            raise DownholeInputError(f"{p}: line {n}, column {names[imd]!r}: measured depth "
                                     f"{md:g} {length_unit} is negative")
        if r and not md > data[r - 1, 0]:
            raise DownholeInputError(f"{p}: line {n}, column {names[imd]!r}: measured depth "
                                     f"{md:g} {length_unit} does not increase (line "
                                     f"{where[r - 1]}: {data[r - 1, 0]:g} {length_unit})")
    from downhole.plausible import check_dogleg

    bad = check_dogleg(data[:, 0], data[:, 1], data[:, 2], length_unit=length_unit,
                       degrees=ang == "deg")
    if bad is not None:
        raise DownholeInputError(f"{p}: line {where[bad[0]]}, column {names[iinc]!r}: {bad[1]}")
    deepest = data[-1, 0] * (0.3048 if length_unit == "ft" else 1.0)
    if deepest > MAX_SURVEY_MD:
        hint = ("; if the depths are in feet, say units = \"oilfield\" or name the column "
                "\"MD (ft)\"" if length_unit == "m" and deepest * 0.3048 <= MAX_SURVEY_MD
                else "")
        raise DownholeInputError(
            f"{p}: line {where[-1]}, column {names[imd]!r}: the deepest station, "
            f"{data[-1, 0]:g} {length_unit}, is beyond any well drilled "
            f"({MAX_SURVEY_MD:g} m){hint}")
    return WellPath.from_survey(data[:, 0], data[:, 1], data[:, 2], degrees=angle_unit == "deg",
                                length_unit=length_unit)
