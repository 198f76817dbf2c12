"""``downhole simulate`` and ``downhole demo``."""

from __future__ import annotations

import json
import math
from pathlib import Path

import typer
from rich.console import Console
from rich.table import Table

from downhole.cli import app

console = Console()


def write_run(result, out: Path, title: str = "") -> dict:
    """Write ``result.nc``, ``summary.json`` and ``overview.png`` into ``out`` (atomically per
    file, the folder created only now that the run succeeded). Returns the summary."""
    summary = result.summary()
    out.mkdir(parents=True, exist_ok=True)
    result.save(out / "result.nc")
    tmp = out / "summary.json.part"
    tmp.write_text(json.dumps({k: (None if isinstance(v, float) and not math.isfinite(v) else v)
                               for k, v in summary.items()}, indent=2))
    tmp.replace(out / "summary.json")
    png = out / "overview.part.png"
    result.plot(png, title=title or None)
    png.replace(out / "overview.png")
    return summary


def summary_table(rows: dict[str, dict]) -> Table:
    keys = []
    for s in rows.values():
        keys += [k for k in s if k not in keys]
    table = Table("metric", *rows.keys())
    for k in keys:
        cells = []
        for s in rows.values():
            v = s.get(k)
            cells.append("-" if v is None else f"{v:.4g}")
        table.add_row(k, *cells)
    return table


@app.command()
def simulate(
    scenario: Path = typer.Argument(..., help="scenario TOML file"),
    out: Path = typer.Option(Path("out/simulate"), "--out", help="output folder"),
):
    """Run a scenario; write OUT/result.nc, OUT/summary.json and OUT/overview.png."""
    from downhole.scenario import load_scenario, run_scenario

    data, source, _ = load_scenario(scenario)
    with console.status(f"simulating {scenario}"):
        result = run_scenario(scenario)
    summary = write_run(result, out, title=data.get("title", ""))
    console.print(summary_table({scenario.stem: summary}))
    console.print(f"written {out}/result.nc, summary.json, overview.png")


@app.command()
def demo(out: Path = typer.Option(Path("out"), "--out", help="output folder")):
    """The main demo on built-in defaults: nominal Table 2.1 drilling and the stick-slip case."""
    from downhole.scenario import run_scenario

    cases = {
        "nominal": {"title": "Nominal Table 2.1: 10 mm/s, 10 rad/s, delayed depth of cut",
                    "model": {"type": "lumped4", "preset": "table_2_1"},
                    "surface": {"axial_velocity": "10 mm/s", "angular_velocity": "10 rad/s"},
                    "reference": {"axial_velocity": "10 mm/s", "angular_velocity": "10 rad/s"},
                    "simulation": {"duration": "60 s", "dt": "0.5 ms", "record_dt": "10 ms"}},
        "stickslip": {"title": "Stick-slip: Table 2.1 at 2 rad/s, delayed depth of cut",
                      "model": {"type": "lumped4", "preset": "table_2_1"},
                      "surface": {"axial_velocity": "10 mm/s", "angular_velocity": "2 rad/s"},
                      "simulation": {"duration": "100 s", "dt": "0.5 ms", "record_dt": "10 ms"}},
    }
    rows = {}
    with console.status("running the demo"):
        for name, data in cases.items():
            res = run_scenario(data, source=f"<demo {name}>")
            rows[name] = write_run(res, out / name, title=data["title"])
    console.print(summary_table(rows))
    console.print(f"figures: {out}/nominal/overview.png, {out}/stickslip/overview.png")
