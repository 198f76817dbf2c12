"""``downhole simulate`` and ``downhole demo``."""

from __future__ import annotations

import math
from pathlib import Path

import typer
from rich.console import Console
from rich.table import Table

from downhole._atomic import OutputFolder, check_output_path, write_json_atomic
from downhole.cli import app
from downhole.cli._units import UNIT_OPTION, UNITS_OPTION, resolve_units

console = Console()


#: The files ``simulate`` (and each ``demo`` case) writes into its folder.
RUN_FILES = ("result.nc", "summary.json", "overview.png")


def write_run(result, out: Path, title: str = "", units=None) -> dict:
    """Write ``result.nc``, ``summary.json`` and ``overview.png`` into ``out``; returns the
    summary in SI.

    ``units`` (a :class:`~downhole.units.UnitSystem`, default SI) sets the units of
    ``summary.json`` (its values, and its ``"units"`` object naming each metric's unit) and of
    the figure; ``result.nc`` is always SI with the unit of every channel in its attributes.

    Each file is written atomically. The three belong together: call this inside an
    :class:`~downhole._atomic.OutputFolder` of ``out`` (as ``simulate`` and ``demo`` do), which
    removed the previous run's three before the run and keeps the folder marked ``INCOMPLETE``
    until the last one is written.
    """
    from downhole._atomic import atomic_path
    from downhole.analysis.plots import plot_overview
    from downhole.units import display_units

    units = display_units(units or "si")
    summary = result.summary()
    out.mkdir(parents=True, exist_ok=True)
    result.save(out / "result.nc")
    write_json_atomic(out / "summary.json", summary_json(summary, units))
    with atomic_path(out / "overview.png") as tmp:
        plot_overview(result, tmp, title=title or None, units=units)
    return summary


def summary_json(summary: dict, units) -> dict:
    """The content of ``summary.json``: each metric in the display ``units`` (NaN/inf as null)
    and a top-level ``"units"`` object naming the unit of every metric (``"-"`` for ratios)."""
    values, names = units.convert_summary(summary)
    doc = {k: (None if isinstance(v, float) and not math.isfinite(v) else v)
           for k, v in values.items()}
    doc["units"] = names
    return doc


def summary_table(rows: dict[str, dict], units=None) -> Table:
    """A table of metrics, one column per run, with the ``unit`` of each metric (values in the
    display ``units``, default SI)."""
    from downhole.units import display_units

    units = display_units(units or "si")
    keys = []
    for s in rows.values():
        keys += [k for k in s if k not in keys]
    table = Table("metric", "unit", *rows.keys())
    for k in keys:
        cells = []
        for s in rows.values():
            v = s.get(k)
            if v is not None:
                v = units.convert(k, v)[0]
            cells.append("-" if v is None else f"{v:.4g}")
        table.add_row(k, units.label(k), *cells)
    return table


@app.command()
def simulate(
    scenario: Path = typer.Argument(..., help="scenario TOML file"),
    out: Path = typer.Option(Path("out/simulate"), "--out", help="output folder"),
    fidelity: str | None = typer.Option(
        None, "--fidelity", help="model fidelity of a system scenario ([model] fidelity): "
        "lumped4, lumped12, neutral, fem or hybrid; overrides the file's"),
    units: str = UNITS_OPTION,
    unit: list[str] | None = UNIT_OPTION,
):
    """Run a scenario; write OUT/result.nc, OUT/summary.json and OUT/overview.png."""
    from downhole.scenario import load_scenario, run_scenario, validate_data
    from downhole.scenario.system import check_fidelity

    display = resolve_units(units, unit)
    check_output_path(out, kind="folder")
    data, source, _ = load_scenario(scenario)
    if fidelity is not None:
        check_fidelity(fidelity, source, "--fidelity")
    validate_data(data, source, fidelity)  # every check before the output folder is touched
    with OutputFolder(out, RUN_FILES, "simulate") as folder:
        with console.status(f"simulating {scenario}"):
            result = run_scenario(scenario, fidelity=fidelity)
        folder.writing()
        summary = write_run(result, out, title=data.get("title", ""), units=display)
    console.print(summary_table({scenario.stem: summary}, display))
    console.print(f"written {out}/result.nc, summary.json, overview.png")


@app.command()
def demo(out: Path = typer.Option(Path("out"), "--out", help="output folder"),
         units: str = UNITS_OPTION, unit: list[str] | None = UNIT_OPTION):
    """The main demo on built-in defaults: nominal Table 2.1 drilling and the stick-slip case."""
    from downhole.scenario import run_scenario

    cases = {
        "nominal": {"title": "Nominal Table 2.1: 10 mm/s, 10 rad/s, delayed depth of cut",
                    "model": {"fidelity": "lumped4", "preset": "table_2_1"},
                    "operation": {"rop": "10 mm/s", "surface_speed": "10 rad/s"},
                    "reference": {"axial_velocity": "10 mm/s", "angular_velocity": "10 rad/s"},
                    "simulation": {"duration": "60 s", "dt": "0.5 ms", "record_dt": "10 ms"}},
        "stickslip": {"title": "Stick-slip: Table 2.1 at 2 rad/s, delayed depth of cut",
                      "model": {"fidelity": "lumped4", "preset": "table_2_1"},
                      "operation": {"rop": "10 mm/s", "surface_speed": "2 rad/s"},
                      "simulation": {"duration": "100 s", "dt": "0.5 ms", "record_dt": "10 ms"}},
    }
    display = resolve_units(units, unit)
    check_output_path(out, kind="folder")
    for name in cases:
        check_output_path(out / name, kind="folder")
    rows = {}
    with console.status("running the demo"):
        for name, data in cases.items():
            with OutputFolder(out / name, RUN_FILES, "demo") as folder:
                res = run_scenario(data, source=f"<demo {name}>")
                folder.writing()
                rows[name] = write_run(res, out / name, title=data["title"], units=display)
    console.print(summary_table(rows, display))
    console.print(f"figures: {out}/nominal/overview.png, {out}/stickslip/overview.png")
