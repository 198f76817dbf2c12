"""CLI commands over the registries: presets, experiments, reproduce, bench, bench-report."""

from __future__ import annotations

import json
from pathlib import Path

import typer
from rich.console import Console
from rich.table import Table

from downhole._atomic import OutputFile, check_output_path, write_text_atomic
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
    from downhole.report.reproduce import load_plugins

    load_plugins()

    table = Table("id", "chapter", "title", "claim")
    for e in all_experiments():
        table.add_row(e.id, str(e.chapter), e.title, e.claim)
    console.print(table)


@app.command()
def reproduce(
    ids: list[str] | None = typer.Argument(None, help="experiment ids, e.g. fig2.3 table2.2"),
    out: Path = typer.Option(Path("out/reproduce"), "--out", help="output folder"),
    all_: bool = typer.Option(False, "--all", help="run every experiment"),
    quick: bool = typer.Option(False, "--quick", help="reduced sizes for a fast check"),
    jobs: int | None = typer.Option(None, "--jobs", "-j", help="parallel worker processes "
                                       "(default: number of cores; 1 = in this process)"),
    chapter: list[int] | None = typer.Option(None, "--chapter", help="only these chapters"),
):
    """Run experiments in parallel; each writes OUT/ID/ (figures, data, claim.json, run.log),
    a failure is recorded and does not stop the others; OUT/index.html shows them all."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    from downhole.experiments import all_experiments, get_experiment
    from downhole.report import reproduce as run_all
    from downhole.report.reproduce import load_plugins

    load_plugins()

    if all_ or chapter:
        ids = [e.id for e in all_experiments() if not chapter or e.chapter in chapter]
    if not ids:
        fail("name experiment ids or pass --all (see `downhole experiments`)")
    if jobs is not None and jobs < 1:
        fail(f"--jobs must be at least 1, got {jobs}")
    for eid in ids:
        get_experiment(eid)  # validate all ids before running anything
    check_output_path(out, kind="folder")
    with Progress(TextColumn("[progress.description]{task.description}"), BarColumn(),
                  MofNCompleteColumn(), TimeElapsedColumn(), console=console) as progress:
        task = progress.add_task("experiments", total=len(ids))

        def _progress(eid, claim):
            mark = "[green]pass[/]" if claim.get("passed") else "[red]FAIL[/]"
            extra = f" ({claim['error'][:100]})" if claim.get("error") else ""
            progress.console.print(f"{mark} {eid} {claim.get('seconds', 0):.1f} s{extra}")
            progress.update(task, description=f"done {eid}")
            progress.advance(task)

        summary = run_all(ids, out, quick=quick, jobs=jobs, progress=_progress)
    table = Table("id", "passed", "seconds", "claim")
    claims = {}
    for eid in ids:
        try:
            claims[eid] = json.loads((out / eid / "claim.json").read_text())
        except (OSError, ValueError):
            claims[eid] = {"passed": False, "claim": "(no claim.json)"}
    for eid in ids:
        r = claims[eid]
        table.add_row(eid, "[green]yes[/]" if r.get("passed") else "[red]no[/]",
                      f"{r.get('seconds', 0):.1f}", r.get("error") or r.get("claim", ""))
    console.print(table)
    console.print(f"{len(summary['passed'])} passed, {len(summary['failed'])} failed in "
                  f"{summary['wall_seconds']:.1f} s on {summary['jobs']} jobs; "
                  f"report: {out}/index.html")
    failed = [eid for eid in ids if not claims[eid].get("passed")]
    if failed:
        from downhole.report.reproduce import is_timing

        physics = [eid for eid in failed if not is_timing(get_experiment(eid))]
        if physics:
            console.print(f"[red]failed claims: {', '.join(physics)}[/] (exit code 1)")
            raise typer.Exit(1)
        console.print(f"[yellow]only timing claims failed: {', '.join(failed)}[/] (speed "
                      "depends on the machine's load; exit code 3)")
        raise typer.Exit(3)


def _git_commit() -> str | None:
    import subprocess

    try:
        return subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                              text=True, timeout=5, cwd=Path(__file__).resolve().parents[2]
                              ).stdout.strip() or None
    except (OSError, subprocess.SubprocessError):
        return None


@app.command()
def bench(
    out: Path = typer.Option(Path("out/bench.json"), "--out", help="JSON report file"),
    quick: bool = typer.Option(False, "--quick", help="only the quick cases"),
    case: list[str] | None = typer.Option(None, "--case", help="run only these cases"),
    group: list[str] | None = typer.Option(None, "--group", help="only these groups (ch2...)"),
):
    """Run benchmarks (ratios against in-run baselines and the seed's published times); a
    failing case is recorded with its error and the others go on."""
    import time
    import traceback

    from downhole import __version__
    from downhole.bench import all_cases, run_bench
    from downhole.report import machine_description

    check_output_path(out, kind="file", parents=True)
    cases = all_cases()
    known = {c.name for c in cases}
    unknown = [c for c in (case or []) if c not in known]
    if unknown:
        fail(f"unknown bench cases {unknown}; known: {sorted(known)}")
    selected = [c for c in cases if (not case or c.name in case) and (not quick or c.quick)
                and (not group or c.group in group)]
    if not selected:
        fail("no bench case selected")
    out.parent.mkdir(parents=True, exist_ok=True)
    # marked (and locked) now: an interrupted run leaves no previous report looking fresh
    out_file = OutputFile(out, "bench").begin()
    try:
        rows, report = [], None
        t_start = time.perf_counter()
        with console.status("benchmarking") as status:
            for c in selected:
                status.update(f"benchmarking {c.name}")
                try:
                    report = run_bench(quick=quick, names=[c.name])
                    rows += report["cases"]
                except Exception as exc:
                    rows.append({"name": c.name, "group": c.group, "seconds": None,
                                 "baseline": None, "baseline_seconds": None, "ratio": None,
                                 "seed_seconds": c.seed_seconds, "ratio_to_seed": None,
                                 "error": f"{type(exc).__name__}: {exc}",
                                 "traceback": traceback.format_exc()})
        machine = dict((report or {}).get("machine", {}))
        machine.update(machine_description())
        argv = ["downhole bench", f"--out {out}"] + (["--quick"] if quick else []) + \
            [f"--case '{c}'" for c in case or []] + [f"--group {g}" for g in group or []]
        full = {"machine": machine, "cases": rows,
                "run": {"quick": quick, "date": time.strftime("%Y-%m-%d %H:%M %Z"),
                        "downhole_version": __version__, "git_commit": _git_commit(),
                        "command": " ".join(argv),
                        "wall_seconds": round(time.perf_counter() - t_start, 1)}}
        write_text_atomic(out, json.dumps(full, indent=2))
    except BaseException as exc:
        out_file.fail(f"{type(exc).__name__}: {exc}")
        raise
    out_file.commit()
    table = Table("case", "seconds", "baseline", "x baseline", "seed s", "x seed")
    for r in rows:
        if r.get("error"):
            table.add_row(r["name"], "[red]failed[/]", r["error"][:60], "-", "-", "-")
            continue
        table.add_row(r["name"], f"{r['seconds']:.4g}", r["baseline"] or "-",
                      f"{r['ratio']:.1f}" if r["ratio"] else "-",
                      f"{r['seed_seconds']:.4g}" if r["seed_seconds"] else "-",
                      f"{r['ratio_to_seed']:.0f}" if r.get("ratio_to_seed") else "-")
    console.print(table)
    console.print(f"written {out}")


@app.command("bench-report")
def bench_report(
    report: Path = typer.Argument(..., help="JSON written by `downhole bench`"),
    out: Path = typer.Option(Path("docs/performance.md"), "--out", help="Markdown file"),
):
    """Turn a bench JSON into a Markdown table (case, seed s, downhole s, ratios, machine)."""
    from downhole.errors import DownholeInputError
    from downhole.report import bench_markdown

    check_output_path(out, kind="file", parents=True)
    try:
        data = json.loads(report.read_text())
    except OSError as exc:
        raise DownholeInputError(f"{report}: cannot read ({exc.strerror})") from None
    except ValueError as exc:
        raise DownholeInputError(f"{report}: not a JSON bench report ({exc})") from None
    if not isinstance(data, dict) or not isinstance(data.get("cases"), list):
        raise DownholeInputError(f"{report}: expected a `downhole bench` report with a 'cases' "
                                 "list")
    out.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomic(out, bench_markdown(data, source=str(report)))
    console.print(f"written {out} ({len(data['cases'])} cases)")
