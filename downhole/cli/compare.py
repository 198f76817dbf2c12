"""CLI of the controller benchmark: ``downhole compare-controllers``."""

from __future__ import annotations

from pathlib import Path

import typer
from rich.console import Console
from rich.table import Table

from downhole._atomic import check_output_path
from downhole.cli import app, fail
from downhole.cli._units import UNIT_OPTION, UNITS_OPTION, resolve_units

__all__ = ["compare_controllers_cmd"]

console = Console()


@app.command("compare-controllers")
def compare_controllers_cmd(
    out: Path = typer.Option(..., "--out", help="output folder (index.html, scores.json)"),
    suite: str = typer.Option("standard", "--suite", help="standard (full) or smoke (seconds)"),
    controller: list[Path] | None = typer.Option(
        None, "--controller", help="a controller file to score as well: a saved DHP "
        "(.json/.npz) or, with --allow-code, a Python file (make_controller(plant) or "
        "controller); repeatable"),
    builtin: list[str] | None = typer.Option(
        None, "--builtin", help="score only these built-in controllers (default: all); "
        "repeatable"),
    no_builtin: bool = typer.Option(False, "--no-builtin", help="score only the --controller "
                                    "files"),
    allow_code: bool = typer.Option(False, "--allow-code", help="allow running Python "
                                    "controller files (they are code)"),
    case: list[str] | None = typer.Option(None, "--case", help="only these case ids"),
    jobs: int = typer.Option(1, "--jobs", "-j", help="worker processes for the cells"),
    units: str = UNITS_OPTION,
    unit: list[str] | None = UNIT_OPTION,
):
    """Score controllers on a fixed, versioned suite of cases (true FEM plant, delayed depth of
    cut); write OUT/index.html (tables and plots) and OUT/scores.json."""
    from downhole.compare import BUILTIN, SUITES, compare_controllers, load_controller_spec
    from downhole.compare.suite import get_suite

    display = resolve_units(units, unit)
    check_output_path(out, kind="folder")
    if suite not in SUITES:
        fail(f"--suite must be one of {sorted(SUITES)}, got {suite!r}")
    if jobs < 1:
        fail(f"--jobs must be at least 1, got {jobs}")
    if case:
        known = {c.id for c in get_suite(suite)}
        unknown = [c for c in case if c not in known]
        if unknown:
            fail(f"unknown --case {unknown} in suite {suite!r}; known: {sorted(known)}")
    if no_builtin and builtin:
        fail("--builtin and --no-builtin exclude each other")
    names = [] if no_builtin else list(builtin or BUILTIN)
    unknown = [n for n in names if n not in BUILTIN]
    if unknown:
        fail(f"unknown --builtin {unknown}; known: {sorted(BUILTIN)}")
    specs = {n: n for n in names}
    for path in controller or []:
        ctrl = load_controller_spec(path, allow_code=allow_code)  # one-line error, exit 2
        label = str(getattr(ctrl, "label", path.stem))
        k = 2
        while label in specs:
            label = f"{path.stem}#{k}"
            k += 1
        specs[label] = ctrl
    if not specs:
        fail("nothing to score: give --controller files or leave out --no-builtin")

    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    with Progress(TextColumn("[progress.description]{task.description}"), BarColumn(),
                  MofNCompleteColumn(), TimeElapsedColumn(), console=console) as progress:
        n_cases = len(case) if case else len(get_suite(suite))
        task = progress.add_task(f"suite {suite}", total=n_cases * len(specs))

        def _progress(done, total, case_id, label, status):
            progress.update(task, completed=done, description=f"{case_id} / {label}: {status}")

        scores = compare_controllers(specs, suite=suite, out=out, jobs=jobs, progress=_progress,
                                     cases=case, units=display)
    table = Table("controller", "ok", "n/a", "failed", "suppressed", "mean severity (stick-slip)",
                  "mean stuck (stick-slip)")
    for label, row in scores["summary"].items():
        sev = row["mean_severity_stick_slip_cases"]
        stuck = row["mean_stuck_fraction_stick_slip_cases"]
        table.add_row(label, str(row["ok"]), str(row["n/a"]), str(row["failed"]),
                      f"{row['suppressed']}/{row['stick_slip_cases']}",
                      "-" if sev is None else f"{sev:.2f}",
                      "-" if stuck is None else f"{stuck:.2f}")
    console.print(table)
    console.print(f"suite {suite} v{scores['suite']['version']}: {scores['wall_seconds']:g} s "
                  f"on {jobs} job(s); report: {out}/index.html, scores: {out}/scores.json")
