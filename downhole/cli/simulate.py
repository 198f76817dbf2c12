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


#: The demo's drilling system, described once (the one-description scenario format,
#: docs/scenarios.md): a 3000 m vertical well, 2820 m of 5" drill pipe (OD 127 mm, ID 108.6 mm)
#: over 180 m of 6 3/4" collars, an 8 1/2" PDC bit (Table 2.1's cutter and wear-flat constants,
#: radius 4.25 in), 1200 kg/m^3 mud; the 4th-order lumped chain matched to that string.
#: ``examples/first_run.toml`` and ``examples/first_run_stickslip.toml`` are the same two cases
#: as files (tests/test_first_run.py checks that they agree).
DEMO_SYSTEM = {
    "model": {"fidelity": "lumped4", "friction": 0.0},
    "well": {"sections": [{"type": "vertical", "length": "3000 m"}]},
    "string": {"mud_density": "1200 kg/m^3",
               "segments": [{"kind": "pipe", "length": "2820 m", "outer_diameter": "127 mm",
                             "inner_diameter": "108.6 mm"},
                            {"kind": "collar", "outer_diameter": "6.75 in",
                             "inner_diameter": "2.8125 in"}]},
    "bit": {"preset": "table_2_1", "radius": "4.25 in"},
}

#: The demo's two operating points: the same WOB, nominal and low rotary speed.
DEMO_CASES = {
    "nominal": {"label": "nominal", "surface_speed": "120 rpm", "wob": "100 kN"},
    "stickslip": {"label": "stick-slip (low rotary speed)", "surface_speed": "50 rpm",
                  "wob": "100 kN"},
}

DEMO_WELL = "3000 m vertical well, 5 in pipe over 180 m of 6 3/4 in collars, 8 1/2 in PDC bit"


def demo_scenario(name: str) -> dict:
    """The scenario dict of demo case ``name`` (``nominal`` or ``stickslip``)."""
    import copy

    case = DEMO_CASES[name]
    data = copy.deepcopy(DEMO_SYSTEM)
    data["title"] = f"{DEMO_WELL}: {case['label']}"
    data["operation"] = {"surface_speed": case["surface_speed"], "wob": case["wob"]}
    data["simulation"] = {"duration": "30 s", "dt": "0.5 ms", "record_dt": "10 ms",
                          "depth_of_cut": "delayed", "start": "steady"}
    return data


def operating_point(data: dict, units) -> str:
    """``"120 rpm, WOB 100 kN"``: a scenario's set-points in the display ``units``."""
    from downhole.units import to_si

    units = units.for_figures()
    op = data["operation"]
    parts = []
    if "surface_speed" in op:
        v, u = units.convert("top_drive_angular_velocity",
                             to_si(op["surface_speed"], "angular_velocity"))
        parts.append(f"{float(v):.4g} {u}")
    if "wob" in op:
        v, u = units.convert("wob", to_si(op["wob"], "force"))
        parts.append(f"WOB {float(v):.4g} {u}")
    if "rop" in op:
        v, u = units.convert("bit_axial_velocity", to_si(op["rop"], "velocity"))
        parts.append(f"ROP {float(v):.4g} {u}")
    return ", ".join(parts)


#: The channels of the demo's second table (mean and range over the second half of each run).
DEMO_CHANNELS = ("hook_load", "wob", "tob", "surface_torque", "top_drive_angular_velocity",
                 "bit_angular_velocity", "bit_axial_velocity")


def channel_table(results: dict, units) -> Table:
    """Mean and range (min to max) of :data:`DEMO_CHANNELS` over the second half of each run,
    in the display ``units``."""
    table = Table("channel: mean [min, max], 2nd half", "unit", *results)
    for ch in DEMO_CHANNELS:
        cells = []
        for res in results.values():
            t = res.time
            x, _ = units.convert(ch, res[ch][t >= t[0] + (t[-1] - t[0]) / 2])
            cells.append(f"{x.mean():.3g} [{x.min():.3g}, {x.max():.3g}]")
        table.add_row(ch, units.label(ch), *cells)
    return table


@app.command()
def demo(out: Path = typer.Option(Path("out"), "--out", help="output folder"),
         units: str = typer.Option(
             "metric", "--units", help="display units of the tables and figures: metric "
             "(default here: m/h, rpm, kN, kN*m, MPa), si or oilfield; see docs/units.md"),
         unit: list[str] | None = UNIT_OPTION):
    """The main demo: a 3000 m vertical well with 5" pipe, collars and an 8 1/2" PDC bit, drilled
    at 120 rpm (nominal) and at 50 rpm (stick-slip), both at 100 kN WOB."""
    from downhole.scenario import run_scenario

    display = resolve_units(units, unit)
    check_output_path(out, kind="folder")
    for name in DEMO_CASES:
        check_output_path(out / name, kind="folder")
    rows, results = {}, {}
    with console.status("running the demo"):
        for name in DEMO_CASES:
            data = demo_scenario(name)
            title = f"{data['title']}\nset-points {operating_point(data, display)}"
            with OutputFolder(out / name, RUN_FILES, "demo") as folder:
                res = run_scenario(data, source=f"<demo {name}>")
                folder.writing()
                rows[name] = write_run(res, out / name, title=title, units=display)
                results[name] = res
    console.print(DEMO_WELL + "; " + "; ".join(
        f"{k}: {operating_point(demo_scenario(k), display)}" for k in DEMO_CASES))
    console.print(summary_table(rows, display))
    console.print(channel_table(results, display))
    console.print(f"figures: {out}/nominal/overview.png, {out}/stickslip/overview.png")
