"""The ``--units`` and ``--unit`` options, declared once for every command that prints or writes
results (see docs/units.md)."""

from __future__ import annotations

import typer

__all__ = ["UNITS_OPTION", "UNIT_OPTION", "resolve_units"]

#: ``--units si|metric|oilfield``: the display unit system of tables, JSON, plots, LAS and CSV.
UNITS_OPTION = typer.Option(
    "si", "--units", help="display units of printed and written results: si (stored SI "
    "units), metric (m/h, rpm, kN, kN*m, MPa) or oilfield (ft, ft/h, rpm, klbf, kft*lbf, psi, "
    "lb/gal, in); see docs/units.md")

#: ``--unit KIND=UNIT`` (repeatable): per-quantity overrides of the display system.
UNIT_OPTION = typer.Option(
    None, "--unit", help="override one quantity's display unit, KIND=UNIT or NAME=UNIT, e.g. "
    "torque=kN*m, speed=rad/s or wob=kN (repeat)")


def resolve_units(units: str, unit: list[str] | None = None):
    """The :class:`~downhole.units.UnitSystem` of the options (DownholeInputError, exit code 2,
    on a bad name or override)."""
    from downhole.units import display_units

    return display_units(units, list(unit or []))
