"""A small catalogue of drill pipe, heavyweight pipe and drill collars as drillers specify them:
nominal size and weight with tool joints, not only outer and inner diameter.

A drill-pipe joint is a plain tube (the body: OD, ID, plain-end weight) with upsets and a tool
joint (a box and a pin of larger OD) at its ends. What hangs on the hook is the *adjusted*
weight per length, the joint's whole weight over its length: for 5" 19.50 lb/ft S-135 pipe with
NC50 joints 23.52 lb/ft against a plain-end 17.93 lb/ft, 31 % more. A string given by OD/ID
alone therefore weighs 10-25 % light. :func:`catalogue_section` returns the body's
:class:`~downhole.params.strings.PipeSection` with ``weight_factor`` = adjusted / plain-end
weight: mass, weight and displaced volume per length use the adjusted weight (hook load, torque
and drag, the models' masses), stiffness the body's.

Entries (the manufacturer's or API's published adjusted weights; ``source`` names them):

=================================  ==========================================================
``5in 19.50 S135 NC50``           drill pipe, 5" x 4.276", NC50 6-5/8" x 3-1/4" tool joint,
                                  tong lengths 9"/12", range 2 (31.7 ft), 23.52 lb/ft
``5-1/2in 21.90 S135 HT55``       drill pipe, 5-1/2" x 4.778", HT55 7-1/8" x 3-7/8",
                                  tong lengths 10"/15", range 2 (32.0 ft), 26.51 lb/ft
``5in HWDP 49.3``                 heavyweight, 5" x 3" tube, NC50 6-1/2" x 3-1/16", 49.3 lb/ft
``3-1/2in HWDP 25.3``             heavyweight, 3-1/2" x 2-1/16" tube, NC38 4-3/4" x 2-3/16",
                                  25.3 lb/ft
``6-1/2in DC 2-13/16``, ...       drill collars (plain bars: adjusted = plain weight),
                                  6-1/2", 6-3/4", 8", 9-1/2" OD
=================================  ==========================================================

Drill-collar weights follow from their diameters (steel 7850 kg/m^3, 3.40 lb/ft per in^2:
8" x 2-13/16" gives 149.9 lb/ft, the API table's 150); they are checked in the tests.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from downhole.errors import DownholeInputError
from downhole.params.strings import PipeSection

__all__ = ["CATALOGUE", "CatalogueEntry", "catalogue_names", "catalogue_section"]

_IN = 0.0254
_FT = 0.3048
_LBFT = 0.45359237 / 0.3048  # 1 lb/ft in kg/m


@dataclass(frozen=True)
class CatalogueEntry:
    """One catalogue tubular (dimensions in inches and feet, weights in lb/ft, as published).

    Parameters
    ----------
    kind : {"pipe", "heavyweight", "collar"}
        What it is.
    outer_diameter, inner_diameter : float
        Body (tube) OD and ID, in.
    adjusted_weight : float or None
        Published adjusted weight (joint weight over joint length), lb/ft; None for a plain bar
        (collars), whose weight follows from its diameters.
    tool_joint_od, tool_joint_id : float or None
        Tool joint OD and ID, in.
    tool_joint_length : float or None
        Pin plus box tong length, in.
    joint_length : float or None
        Joint length (range 2), ft.
    source : str
        Where the adjusted weight comes from.
    """

    kind: str
    outer_diameter: float
    inner_diameter: float
    adjusted_weight: float | None = None
    tool_joint_od: float | None = None
    tool_joint_id: float | None = None
    tool_joint_length: float | None = None
    joint_length: float | None = None
    source: str = ""

    def plain_weight(self, density: float = 7850.0) -> float:
        """Plain-end (body) weight, lb/ft.

        Parameters
        ----------
        density : float
            Steel density, kg/m^3.

        Returns
        -------
        float
            The body's weight per length, lb/ft.
        """
        area = math.pi / 4 * ((self.outer_diameter * _IN) ** 2 - (self.inner_diameter * _IN) ** 2)
        return area * density / _LBFT


_DS = "Grant Prideco drill-pipe performance sheet (Workstrings International 2011)"
_HW = ("heavyweight drill pipe tables of the manufacturers (nominal weight, tool joints and "
       "centre upset included)")

#: The catalogue, by name (see the module docstring).
CATALOGUE: dict[str, CatalogueEntry] = {
    "5in 19.50 S135 NC50": CatalogueEntry("pipe", 5.0, 4.276, 23.52, 6.625, 3.25, 21.0, 31.7,
                                          _DS),
    "5-1/2in 21.90 S135 HT55": CatalogueEntry("pipe", 5.5, 4.778, 26.51, 7.125, 3.875, 25.0,
                                              32.0, _DS),
    "5in HWDP 49.3": CatalogueEntry("heavyweight", 5.0, 3.0, 49.3, 6.5, 3.0625, None, 30.0, _HW),
    "3-1/2in HWDP 25.3": CatalogueEntry("heavyweight", 3.5, 2.0625, 25.3, 4.75, 2.1875, None,
                                        30.0, _HW),
    "6-1/2in DC 2-13/16": CatalogueEntry("collar", 6.5, 2.8125),
    "6-3/4in DC 2-13/16": CatalogueEntry("collar", 6.75, 2.8125),
    "8in DC 2-13/16": CatalogueEntry("collar", 8.0, 2.8125),
    "9-1/2in DC 3": CatalogueEntry("collar", 9.5, 3.0),
}


def catalogue_names() -> list[str]:
    """The catalogue's names, sorted.

    Returns
    -------
    list of str
        Names :func:`catalogue_section` takes.
    """
    return sorted(CATALOGUE)


def _key(name: str) -> str:
    return " ".join(name.lower().replace('"', "in").split())


def catalogue_section(name: str, **material) -> PipeSection:
    """The :class:`PipeSection` of a catalogue tubular: body OD/ID and the adjusted weight.

    Parameters
    ----------
    name : str
        A catalogue name (case and spacing free, ``"`` for ``in``), e.g. ``"5in 19.50 S135
        NC50"``; :func:`catalogue_names` lists them.
    **material
        ``young_modulus``, ``shear_modulus``, ``density`` of the body (SI numbers), as
        :class:`PipeSection` takes them.

    Returns
    -------
    PipeSection
        With ``weight_factor`` = adjusted weight / plain-end weight (1 for collars).

    Raises
    ------
    DownholeInputError
        An unknown name (the known ones are listed, the closest first).
    """
    wanted = _key(str(name))
    entry = next((e for n, e in CATALOGUE.items() if _key(n) == wanted), None)
    if entry is None:
        import difflib

        close = difflib.get_close_matches(wanted, [_key(n) for n in CATALOGUE], n=1)
        hint = f"; did you mean {next(n for n in CATALOGUE if _key(n) == close[0])!r}?" \
            if close else ""
        raise DownholeInputError(f"no tubular {name!r} in the catalogue{hint} (known: "
                                 f"{', '.join(catalogue_names())})")
    density = float(material.get("density", 7850.0))
    factor = 1.0 if entry.adjusted_weight is None else \
        entry.adjusted_weight / entry.plain_weight(density)
    return PipeSection(outer_diameter=entry.outer_diameter * _IN,
                       inner_diameter=entry.inner_diameter * _IN,
                       weight_factor=max(1.0, factor), **material)
