"""``downhole sweep``: grid or Monte Carlo sweeps of a scenario, locally or on a Dask cluster."""

from __future__ import annotations

import json
from pathlib import Path

import typer
from rich.console import Console

from downhole._atomic import OutputFolder, check_output_path, write_json_atomic
from downhole.cli import app, fail
from downhole.cli._units import UNIT_OPTION, UNITS_OPTION, resolve_units

#: What ``sweep`` writes into its folder (the previous run's are removed when a new one starts).
SWEEP_FILES = ("sweep.nc", "failed.json", "stability_map.png", "sweep_*.png")

console = Console()


@app.command()
def sweep(
    scenario: Path = typer.Argument(..., help="scenario TOML (an optional [sweep] table gives "
                                              "defaults for the options below)"),
    param: list[str] | None = typer.Option(
        None, "--param", help="NAME=START:STOP:COUNT (grid), NAME=START:STOP (with --random) or "
                              "NAME=V1,V2,...; NAME is a dotted scenario path such as "
                              "operation.surface_speed or bit.epsilon; units allowed "
                              "(2:20:10 mm/s). Repeat for more dimensions."),
    metric: list[str] | None = typer.Option(None, "--metric", help="metric to record "
                                               "(repeat); e.g. stick_slip_severity"),
    random: int | None = typer.Option(None, "--random", help="Monte Carlo: N cases drawn "
                                         "uniformly in the ranges instead of a grid"),
    seed: int | None = typer.Option(None, "--seed", help="random seed for --random"),
    window: str | None = typer.Option(None, "--window", help="metric window START:END in "
                                         "seconds (default: second half of each run)"),
    out: Path = typer.Option(Path("out/sweep"), "--out", help="output folder"),
    scheduler: str | None = typer.Option(None, "--scheduler", help="Dask scheduler address "
                                            "tcp://HOST:PORT"),
    local_cluster: bool = typer.Option(False, "--local-cluster", help="run on a dask.distributed "
                                       "LocalCluster (workers = --processes or the cores)"),
    processes: int | None = typer.Option(None, "--processes", help="worker processes "
                                            "(default: number of cores; 1 = in this process)"),
    batch_size: int | None = typer.Option(None, "--batch-size", help="cases per task"),
    severity_threshold: float = typer.Option(0.5, "--severity-threshold",
                                             help="stick-slip above this severity (map)"),
    bounce_threshold: float = typer.Option(0.01, "--bounce-threshold",
                                           help="bit bounce above this fraction (map)"),
    no_plots: bool = typer.Option(False, "--no-plots", help="write only the NetCDF dataset"),
    units: str = UNITS_OPTION,
    unit: list[str] | None = UNIT_OPTION,
):
    """Sweep scenario parameters; write OUT/sweep.nc, plots and the drilling stability map."""
    from downhole.sweep import load_sweep_file

    if scheduler and local_cluster:
        fail("give either --scheduler ADDRESS or --local-cluster, not both")
    display = resolve_units(units, unit)
    check_output_path(out, kind="folder")
    base, source, settings = load_sweep_file(scenario)
    base["sweep"] = settings
    sched = scheduler or ("local-cluster" if local_cluster else None)
    folder = OutputFolder(out, SWEEP_FILES, "sweep")
    # the folder is marked and cleared just before the first case runs (run_sweep validates all
    # its input first, so a rejected sweep leaves the previous results alone)
    try:
        _run_and_write(folder, folder.begin, base, source, param, metric, random, seed, window,
                       sched, processes, batch_size, severity_threshold, bounce_threshold,
                       no_plots, display)
    except BaseException as exc:
        folder.fail(f"{type(exc).__name__}: {exc}")
        raise
    folder.commit()


def _run_and_write(folder, begin, base, source, param, metric, random, seed, window, sched,
                   processes, batch_size, severity_threshold, bounce_threshold, no_plots,
                   display=None):
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TimeElapsedColumn

    from downhole.sweep import failed_cases, plot_sweep, run_sweep, save_sweep, stability_map

    out = folder.path
    with Progress("[progress.description]{task.description}", BarColumn(), MofNCompleteColumn(),
                  TimeElapsedColumn(), console=console, transient=True) as progress:
        task = progress.add_task("sweep", total=None)

        def _progress(done, total):
            progress.update(task, completed=done, total=total)

        ds = run_sweep(base, param or None, metric or None, random=random, seed=seed,
                       window=window, scheduler=sched, processes=processes,
                       batch_size=batch_size, progress=_progress, source=source,
                       on_start=begin)
    folder.writing()
    files = []
    if not no_plots:
        metrics = json.loads(ds.attrs["metrics"])
        grid_2d = ds.attrs["sweep_mode"] == "grid" and len(ds["error"].dims) == 2
        if grid_2d and {"stick_slip_severity", "bit_bounce_fraction"} <= set(metrics):
            regimes = stability_map(ds, out / "stability_map.png",
                                    severity_threshold=severity_threshold,
                                    bounce_threshold=bounce_threshold,
                                    title=f"drilling stability map: {base.get('title', source)}",
                                    units=display)
            ds["regime"] = regimes.transpose(*ds["error"].dims)
            files.append(out / "stability_map.png")
        files += plot_sweep(ds, out, units=display)
    save_sweep(ds, out / "sweep.nc")
    failed = failed_cases(ds)
    write_json_atomic(out / "failed.json", failed)
    console.print(f"{ds.attrs['n_cases']} cases on {ds.attrs['executor']} in "
                  f"{ds.attrs['wall_seconds']:.1f} s; {len(failed)} failed")
    for f in failed[:10]:
        console.print(f"  [red]failed[/] {f['params']}: {f['error']}")
    if len(failed) > 10:
        console.print(f"  ... {len(failed) - 10} more in {out}/failed.json")
    console.print(f"written {out}/sweep.nc" + (f" and {len(files)} plots" if files else ""))
