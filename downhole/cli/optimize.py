"""``downhole optimize dp SCENARIO.toml --method customized|standard|robust --out DIR``.

Solves the Ch. 2 drilling optimal control problem described by a DP problem file (``[model]``,
``[bit]`` and the problem in ``[optimize]``; TOML schema in docs/dp.md, examples in
``examples/dp_*.toml``), writes the solution (``solution.npz`` + ``solution.json``), a plot of
the bit velocities and inputs, and prints a one-screen summary. ``--method`` overrides the file's
``optimize.method`` (default ``customized``).
"""

from __future__ import annotations

from pathlib import Path

import typer

from downhole._atomic import OutputFolder, atomic_path, check_output_path
from downhole.cli import app

__all__ = ["optimize_app"]

#: The files ``optimize dp`` writes into its folder (removed before a new run into it).
SOLUTION_FILES = ("solution.npz", "solution.json", "solution.png")

optimize_app = typer.Typer(no_args_is_help=True,
                           help="Optimize drilling inputs (dynamic programming).")
app.add_typer(optimize_app, name="optimize")


@optimize_app.command("dp")
def dp(
    scenario: Path = typer.Argument(..., help="DP problem TOML file (see docs/dp.md)"),
    method: str = typer.Option(None, "--method",
                               help="customized | standard | robust (default: the file's "
                                    "optimize.method, else customized)"),
    out: Path = typer.Option(Path("out/dp"), "--out", help="output folder"),
    regions: bool = typer.Option(None, "--regions/--no-regions",
                                 help="customized: use the seed's x1/x3 index regions "
                                      "(default: when the file defines them)"),
    replay: bool = typer.Option(True, "--replay/--no-replay",
                                help="replay the inputs on the continuous 4th-order model"),
    progress: bool = typer.Option(True, "--progress/--no-progress", help="progress bar"),
):
    """Solve a DP problem file and write the solution to OUT."""
    from rich.console import Console
    from rich.table import Table

    from downhole.control.dp import METHODS, replay_path, solve, trajectory_cost
    from downhole.control.dp.problem import load_dp_scenario
    from downhole.errors import DownholeInputError

    if method is not None and method not in METHODS:
        # raised (not fail()): main() maps it to exit code 2
        raise DownholeInputError(f"--method must be one of {', '.join(METHODS)}, got {method!r}")
    check_output_path(out, kind="folder")
    problem, file_method = load_dp_scenario(scenario)
    method = method or file_method or "customized"
    kwargs = {"regions": regions} if method == "customized" and regions is not None else {}
    with OutputFolder(out, SOLUTION_FILES, "optimize dp") as folder:
        sol = solve(problem, method, progress=progress, **kwargs)
        sol.info["scenario"] = str(scenario)
        if replay and sol.on_grid:
            r = replay_path(sol, dt=problem.step / max(1, round(problem.step / 2.5e-3)))
            sol.info["replayed_cost"] = trajectory_cost(problem, r["x2"], r["x4"])
        folder.writing()
        sol.save(out)
        _plot(sol, out / "solution.png")
    console = Console()
    table = Table("quantity", "value")
    table.add_row("method", method)
    table.add_row("cost (Eq. 2.13)", f"{sol.cost:.6g}")
    if "replayed_cost" in sol.info:
        table.add_row("cost replayed (continuous model)", f"{sol.info['replayed_cost']:.6g}")
    table.add_row("final bit velocity", f"{sol.x2[-1] * 1e3:.3f} mm/s, {sol.x4[-1]:.3f} rad/s")
    table.add_row("search time", f"{sol.info['seconds']:.3f} s")
    console.print(table)
    console.print(f"solution in {out}/ (solution.npz, solution.json, solution.png)")


def _plot(sol, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(2, 2, figsize=(10, 6), sharex=True)
    t = sol.times
    ax[0, 0].plot(t, sol.x2 * 1e3, ".-")
    ax[0, 0].set_ylabel("bit axial velocity (mm/s)")
    ax[0, 1].plot(t, sol.x4, ".-")
    ax[0, 1].set_ylabel("bit angular velocity (rad/s)")
    ax[1, 0].step(t[:-1], sol.force / 1e3, where="post")
    ax[1, 0].set_ylabel("string force (kN)")
    ax[1, 1].step(t[:-1], sol.torque / 1e3, where="post")
    ax[1, 1].set_ylabel("string torque (kN m)")
    for a in ax[1]:
        a.set_xlabel("time (s)")
    fig.suptitle(f"{sol.method} DP, cost {sol.cost:.4g}")
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=90)
    plt.close(fig)
