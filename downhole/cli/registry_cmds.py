"""CLI commands over the registries: presets, experiments, reproduce, bench."""

from __future__ import annotations

import json
from pathlib import Path
from typing import List, Optional

import typer
from rich.console import Console
from rich.table import Table

from downhole.cli import app, fail

console = Console()


@app.command()
def presets():
    """List the named parameter presets."""
    from downhole.params import PRESETS

    table = Table("name", "kind", "description")
    for p in PRESETS.values():
        table.add_row(p.name, p.kind, p.description)
    console.print(table)


@app.command()
def experiments():
    """List the experiment ids (dissertation figures/tables) with their claims."""
    from downhole.experiments import all_experiments

    table = Table("id", "chapter", "title", "claim")
    for e in all_experiments():
        table.add_row(e.id, str(e.chapter), e.title, e.claim)
    console.print(table)


@app.command()
def reproduce(
    ids: Optional[List[str]] = typer.Argument(None, help="experiment ids, e.g. fig2.3 table2.2"),
    out: Path = typer.Option(Path("out/reproduce"), "--out", help="output folder"),
    all_: bool = typer.Option(False, "--all", help="run every experiment"),
    quick: bool = typer.Option(False, "--quick", help="reduced sizes for a fast check"),
):
    """Run experiments; each writes OUT/ID/ with figures, data and claim.json."""
    from rich.progress import Progress

    from downhole.experiments import all_experiments, get_experiment, run_experiment

    if all_:
        ids = [e.id for e in all_experiments()]
    if not ids:
        fail("name experiment ids or pass --all (see `downhole experiments`)")
    for eid in ids:
        get_experiment(eid)  # validate all ids before running anything
    out.mkdir(parents=True, exist_ok=True)
    results = []
    with Progress(console=console, transient=True) as progress:
        task = progress.add_task("experiments", total=len(ids))
        for eid in ids:
            progress.update(task, description=f"running {eid}")
            results.append(run_experiment(eid, out, quick=quick))
            progress.advance(task)
    table = Table("id", "passed", "claim")
    for r in results:
        table.add_row(r["id"], "[green]yes[/]" if r["passed"] else "[red]no[/]", r["claim"])
    console.print(table)
    console.print(f"results in {out}/")


@app.command()
def bench(
    out: Path = typer.Option(Path("out/bench.json"), "--out", help="JSON report file"),
    quick: bool = typer.Option(False, "--quick", help="only the quick cases"),
    case: Optional[List[str]] = typer.Option(None, "--case", help="run only these cases"),
):
    """Run benchmarks (ratios against in-run baselines and the seed's published times)."""
    from downhole.bench import run_bench

    with console.status("benchmarking") as status:
        report = run_bench(quick=quick, names=case or None,
                           progress=lambda n: status.update(f"benchmarking {n}"))
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".part")
    tmp.write_text(json.dumps(report, indent=2))
    tmp.replace(out)
    table = Table("case", "seconds", "baseline", "x baseline", "seed s", "x seed")
    for r in report["cases"]:
        table.add_row(r["name"], f"{r['seconds']:.4g}", r["baseline"] or "-",
                      f"{r['ratio']:.1f}" if r["ratio"] else "-",
                      f"{r['seed_seconds']:.4g}" if r["seed_seconds"] else "-",
                      f"{r['ratio_to_seed']:.0f}" if r.get("ratio_to_seed") else "-")
    console.print(table)
    console.print(f"written {out}")
