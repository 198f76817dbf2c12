"""``downhole torque-drag``: soft-string torque and drag of a described system."""

from __future__ import annotations

from pathlib import Path

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from downhole._atomic import OutputFolder, atomic_path, check_output_path, write_json_atomic
from downhole.cli import app
from downhole.cli._units import UNIT_OPTION, UNITS_OPTION, resolve_units

console = Console()

#: The files ``torque-drag`` writes into its folder.
TORQUE_DRAG_FILES = ("torque_drag.csv", "summary.json", "broomstick.png", "profiles.png",
                     "survey.png")


def _parse_friction(text: str) -> tuple:
    from downhole.errors import DownholeInputError

    parts = [p.strip() for p in text.split(",")]
    vals = []
    for p in parts:
        try:
            x = float(p)
        except ValueError:
            raise DownholeInputError(f"--friction: expected comma-separated numbers such as "
                                     f"0.1,0.2,0.3, got {text!r}") from None
        if not (0.0 <= x <= 10.0):
            raise DownholeInputError(f"--friction: friction factors must be between 0 and 10, "
                                     f"got {p}")
        vals.append(x)
    if not 1 <= len(vals) <= 20:
        raise DownholeInputError(f"--friction: give 1 to 20 friction factors, got {len(vals)}")
    return tuple(vals)


@app.command("torque-drag")
def torque_drag(
    scenario: Path = typer.Argument(..., help="system scenario TOML file ([well], [string])"),
    out: Path = typer.Option(Path("out/torque_drag"), "--out", help="output folder"),
    friction: str | None = typer.Option(
        None, "--friction", help="friction factors, comma-separated (e.g. 0.1,0.2,0.3); "
        "overrides the file's torque_drag.friction_factors"),
    units: str = UNITS_OPTION, unit: list[str] | None = UNIT_OPTION,
):
    """Soft-string torque and drag: tension, torque and side force along the string, hook load
    and surface torque against bit depth (trip out, trip in, rotating off bottom, drilling) at
    several friction factors, and the survey (DLS, build, turn, vertical section). Writes
    OUT/torque_drag.csv, summary.json, broomstick.png, profiles.png and survey.png."""
    from downhole.analysis import torque_drag as tdplot
    from downhole.scenario import load_scenario
    from downhole.scenario.torque_drag import run_torque_drag, torque_drag_case
    from downhole.units import unit_label

    check_output_path(out, kind="folder")
    display = resolve_units(units, unit)
    fig_units = display.for_figures()
    factors = _parse_friction(friction) if friction is not None else None
    data, source, _ = load_scenario(scenario)
    case = torque_drag_case(data, source, factors)  # every check before the folder is touched
    well = case.system.well
    with OutputFolder(out, TORQUE_DRAG_FILES, "torque-drag") as folder:
        with console.status(f"torque and drag of {scenario}"):
            result = run_torque_drag(case, source)
        folder.writing()
        cols = tdplot.display_table(tdplot.torque_drag_table(result, well, case.azimuth),
                                    display)
        with atomic_path(out / "torque_drag.csv") as tmp:
            tdplot.write_csv(tmp, cols)
        summ = tdplot.summary(result, well, case.azimuth)
        summ["title"] = case.title
        summ["units"] = display.to_dict()  # the CSV's headers name each column's unit
        write_json_atomic(out / "summary.json", summ)
        for name, plot in (
                ("broomstick.png", lambda p: tdplot.plot_broomstick(result, p, units=fig_units)),
                ("profiles.png", lambda p: tdplot.plot_profiles(result, p, units=fig_units)),
                ("survey.png", lambda p: tdplot.plot_survey(well, p, case.azimuth,
                                                            units=fig_units))):
            with atomic_path(out / name) as tmp:
                plot(tmp)
    F = lambda v: fig_units.convert("hook_load", v, "N")
    T = lambda v: fig_units.convert("surface_torque", v, "N*m")
    fu, tu = (unit_label(F(1.0)[1]), unit_label(T(1.0)[1]))
    depth, du = fig_units.convert("md", well.total_depth, "m")
    table = Table("case", *[f"mu = {f:g}" for f in result.friction],
                  title=escape(f"hook load [{fu}] / surface torque [{tu}], bit at "
                               f"{depth:.0f} {unit_label(du)} MD"))
    for c in ("trip_out", "trip_in", "rotating", "drilling"):
        cells = []
        for k in range(len(result.friction)):
            hl = F(result.tension[c][k, 0])[0]
            tq = T(result.torque[c][k, 0])[0]
            cells.append(f"{hl:.1f}" + (f" / {tq:.2f}" if c in ("rotating", "drilling") else ""))
        table.add_row(c, *cells)
    console.print(table)
    console.print(f"WOB {F(result.wob)[0]:.1f} {fu}, TOB {T(result.tob)[0]:.2f} {tu} (drilling)")
    console.print(f"written {out}/torque_drag.csv, summary.json, broomstick.png, profiles.png, "
                  "survey.png")
