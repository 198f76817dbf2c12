"""Drill-string description: pipe, collar and BHA segments from surface to bit, stabilizers, mud.

A :class:`DrillString` is an immutable list of uniform :class:`StringSegment` s ordered from the
surface down to the bit, optional :class:`Stabilizer` s (contact points whose torque arm is the
blade radius) and the mud density that sets buoyancy (buoyed weight per length
w = g A (rho_steel - rho_mud), open-ended pipe with mud inside and out).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from downhole.errors import DownholeInputError
from downhole.params.strings import PipeSection
from downhole.units import si_or_number

__all__ = ["DrillString", "Stabilizer", "StringSegment", "pipe_section"]

_KINDS = ("pipe", "heavyweight", "collar", "bha")


@dataclass(frozen=True)
class StringSegment:
    """A uniform tubular of ``length`` m.

    Parameters
    ----------
    length : float
        Segment length, m (> 0).
    section : PipeSection
        Geometry and material (outer/inner diameter, E, G, density).
    kind : {"pipe", "heavyweight", "collar", "bha"}
        What it is (informational; collars and BHA are where stabilizers usually sit).
    """

    length: float
    section: PipeSection
    kind: str = "pipe"

    def __post_init__(self):
        object.__setattr__(self, "length", si_or_number(self.length, "length", "segment length"))
        if not (isinstance(self.length, (int, float)) and self.length > 0):
            raise DownholeInputError(f"segment length must be > 0 m, got {self.length!r}")
        if self.kind not in _KINDS:
            raise DownholeInputError(f"segment kind must be one of {_KINDS}, got {self.kind!r}")


@dataclass(frozen=True)
class Stabilizer:
    """A stabilizer at ``distance_from_bit`` m with blade ``outer_diameter`` m (torque arm = OD/2).

    Parameters
    ----------
    distance_from_bit : float
        Distance from the bit along the string, m (>= 0).
    outer_diameter : float
        Blade outer diameter, m (> 0).

    Raises
    ------
    DownholeInputError
        A value that does not convert, or out of range.
    """

    distance_from_bit: float
    outer_diameter: float

    def __post_init__(self):
        for name in ("distance_from_bit", "outer_diameter"):
            object.__setattr__(self, name, _number(getattr(self, name), "length",
                                                   f"stabilizer {name}"))
        if not self.distance_from_bit >= 0:
            raise DownholeInputError(
                f"stabilizer distance_from_bit must be >= 0 m, got {self.distance_from_bit!r}")
        if not self.outer_diameter > 0:
            raise DownholeInputError(
                f"stabilizer outer_diameter must be > 0 m, got {self.outer_diameter!r}")


#: Dimensions of the material keywords of :func:`pipe_section`.
_MATERIAL = {"young_modulus": "pressure", "shear_modulus": "pressure", "density": "density"}


def _number(value, dimension: str, what: str) -> float:
    """A number in SI from a number, a quantity string or a pint Quantity (one-line errors)."""
    value = si_or_number(value, dimension, what)
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise DownholeInputError(f"{what}: expected a number or a quantity such as '5 in', got "
                                 f"{value!r}")
    return float(value)


def pipe_section(outer_diameter: float, inner_diameter: float, **material) -> PipeSection:
    """A :class:`PipeSection` with precise errors for negative or inverted diameters.

    Every value is a number in SI or a quantity (``"5 in"``, ``"30e6 psi"``, a pint Quantity).

    Parameters
    ----------
    outer_diameter : float, str or pint.Quantity
        Outer diameter, m (> 0).
    inner_diameter : float, str or pint.Quantity
        Inner diameter, m (>= 0, smaller than the outer diameter).
    **material
        Optional ``young_modulus`` (Pa), ``shear_modulus`` (Pa) and ``density`` (kg/m^3);
        defaults: those of :class:`PipeSection` (steel).

    Returns
    -------
    PipeSection

    Raises
    ------
    DownholeInputError
        An unknown keyword, a value that does not convert, or diameters out of order.

    Examples
    --------
    >>> round(pipe_section("5 in", "4.276 in").outer_diameter, 4)
    0.127
    """
    outer_diameter = _number(outer_diameter, "length", "outer_diameter")
    inner_diameter = _number(inner_diameter, "length", "inner_diameter")
    unknown = sorted(set(material) - set(_MATERIAL))
    if unknown:
        raise DownholeInputError(f"pipe_section: unknown keyword(s) {unknown}; expected "
                                 f"{sorted(_MATERIAL)}")
    material = {k: _number(v, _MATERIAL[k], k) for k, v in material.items()}
    if not outer_diameter > 0:
        raise DownholeInputError(f"outer_diameter must be > 0 m, got {outer_diameter!r}")
    if not inner_diameter >= 0:
        raise DownholeInputError(f"inner_diameter must be >= 0 m, got {inner_diameter!r}")
    if inner_diameter >= outer_diameter:
        raise DownholeInputError(
            f"inner_diameter ({inner_diameter} m) must be smaller than outer_diameter "
            f"({outer_diameter} m)")
    return PipeSection(outer_diameter=outer_diameter, inner_diameter=inner_diameter, **material)


@dataclass(frozen=True)
class DrillString:
    """Segments from surface (index 0) to bit, stabilizers and mud density.

    Parameters
    ----------
    segments : tuple of StringSegment
        Surface first.
    stabilizers : tuple of Stabilizer
        Optional.
    mud_density : float
        kg/m^3 (0 = in air).
    g : float
        Gravity, m/s^2.

    Examples
    --------
    >>> ds = DrillString.uniform(5000.0, pipe_section(0.12, 0.06))
    >>> round(ds.length)
    5000
    """

    segments: tuple
    stabilizers: tuple = field(default_factory=tuple)
    mud_density: float = 0.0
    g: float = 9.81

    def __post_init__(self):
        object.__setattr__(self, "mud_density", _number(self.mud_density, "density",
                                                         "mud_density"))
        object.__setattr__(self, "g", _number(self.g, "acceleration", "g"))
        if not self.segments:
            raise DownholeInputError("a drill string needs at least one segment")
        for k, s in enumerate(self.segments):
            if not isinstance(s, StringSegment):
                raise DownholeInputError(f"segments[{k}] must be a StringSegment, got {type(s).__name__}")
        if not self.mud_density >= 0:
            raise DownholeInputError(f"mud_density must be >= 0 kg/m^3, got {self.mud_density!r}")
        for k, s in enumerate(self.segments):
            if self.mud_density >= s.section.density:
                raise DownholeInputError(
                    f"mud_density ({self.mud_density} kg/m^3) >= steel density of segment {k} "
                    f"({s.section.density} kg/m^3): the string would float")
        for st in self.stabilizers:
            if st.distance_from_bit > self.length:
                raise DownholeInputError(
                    f"stabilizer at {st.distance_from_bit} m from the bit lies above the top of a "
                    f"{self.length:g} m string")

    @classmethod
    def uniform(cls, length: float, section: PipeSection, mud_density: float = 0.0,
                g: float = 9.81) -> DrillString:
        """One uniform pipe of ``length`` m (or a quantity such as ``"15000 ft"``).

        Parameters
        ----------
        length : float, str or pint.Quantity
            String length, m.
        section : PipeSection
            The pipe's cross-section and material.
        mud_density : float, optional
            Mud density, kg/m^3 (default 0: in air).
        g : float, optional
            Gravity, m/s^2 (default 9.81).

        Returns
        -------
        DrillString

        Raises
        ------
        DownholeInputError
            A value that does not convert, or a mud density at or above the steel's.
        """
        return cls((StringSegment(_number(length, "length", "length"), section),),
                   mud_density=mud_density, g=g)

    @property
    def length(self) -> float:
        """Total length, m."""
        return float(sum(s.length for s in self.segments))

    @property
    def boundaries(self) -> np.ndarray:
        """Measured depths (from the top of the string) of the segment joints, incl. 0 and length."""
        return np.concatenate([[0.0], np.cumsum([s.length for s in self.segments])])

    def segment_at(self, s) -> np.ndarray:
        """Index of the segment containing distance ``s`` (m from the top).

        Parameters
        ----------
        s : float or array_like
            Distance from the top of the string (measured depth along the string), m.

        Returns
        -------
        ndarray of int
            Segment index (0 = surface), shaped like ``s``; distances beyond the ends are clipped
            to the first or last segment.
        """
        b = self.boundaries
        return np.clip(np.searchsorted(b, np.asarray(s, float), side="right") - 1, 0,
                       len(self.segments) - 1)

    def property_at(self, s, name: str) -> np.ndarray:
        """A :class:`PipeSection` attribute (``area``, ``polar_moment``, ...) at ``s``.

        Parameters
        ----------
        s
            As :meth:`segment_at`.
        name : str
            Attribute name of :class:`PipeSection`.

        Returns
        -------
        ndarray
            The attribute's value (in its SI unit) of the segment at each ``s``.

        Raises
        ------
        AttributeError
            If ``name`` is not an attribute of :class:`PipeSection`.
        """
        idx = self.segment_at(s)
        vals = np.array([float(getattr(seg.section, name)) for seg in self.segments])
        return vals[idx]

    def buoyed_weight_per_length(self, s) -> np.ndarray:
        """w = g A (rho_steel - rho_mud) at ``s``, N/m.

        Parameters
        ----------
        s
            As :meth:`segment_at`.

        Returns
        -------
        ndarray
            Buoyed weight per unit length, N/m, shaped like ``s``.
        """
        idx = self.segment_at(s)
        vals = np.array([self.g * seg.section.weight_factor * seg.section.area
                         * (seg.section.density - self.mud_density)
                         for seg in self.segments])
        return vals[idx]

    @property
    def buoyancy_factor(self) -> float:
        """1 - rho_mud/rho_steel of the first segment."""
        return 1.0 - self.mud_density / self.segments[0].section.density

    def __repr__(self) -> str:
        kinds = ", ".join(f"{s.kind} {s.length:g} m OD {s.section.outer_diameter:g}"
                          for s in self.segments)
        return f"DrillString({kinds}; mud {self.mud_density:g} kg/m^3)"


