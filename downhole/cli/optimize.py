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
from downhole.cli._units import UNIT_OPTION, UNITS_OPTION, resolve_units

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
    units: str = UNITS_OPTION,
    unit: list[str] | None = UNIT_OPTION,
):
    """Solve a DP problem file and write the solution to OUT (solution.npz and .json in SI;
    the table and solution.png in the display units of --units/--unit)."""
    from rich.console import Console
    from rich.table import Table

    from downhole.control.dp import METHODS, replay_path, solve, trajectory_cost
    from downhole.errors import DownholeInputError
    from downhole.scenario.system import load_dp_problem
    from downhole.units import unit_label

    if method is not None and method not in METHODS:
        # raised (not fail()): main() maps it to exit code 2
        raise DownholeInputError(f"--method must be one of {', '.join(METHODS)}, got {method!r}")
    display = resolve_units(units, unit)
    check_output_path(out, kind="folder")
    # a preset's 4th-order model, or the one derived from a described well and string
    problem, file_method = load_dp_problem(scenario)
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
        _plot(sol, out / "solution.png", display)
    console = Console()
    table = Table("quantity", "value")
    table.add_row("method", method)
    table.add_row("cost (Eq. 2.13)", f"{sol.cost:.6g}")
    if "replayed_cost" in sol.info:
        table.add_row("cost replayed (continuous model)", f"{sol.info['replayed_cost']:.6g}")
    fig_units = display.for_figures()
    v, vu = fig_units.convert("bit_axial_velocity", float(sol.x2[-1]))
    w, wu = fig_units.convert("bit_angular_velocity", float(sol.x4[-1]))
    table.add_row("final bit velocity", f"{v:.4g} {unit_label(vu)}, {w:.4g} {unit_label(wu)}")
    table.add_row("search time", f"{sol.info['seconds']:.3f} s")
    console.print(table)
    console.print(f"solution in {out}/ (solution.npz, solution.json, solution.png)")


def _plot(sol, path: Path, units=None) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from downhole.units import display_units

    u = display_units(units or "si").for_figures()
    fig, ax = plt.subplots(2, 2, figsize=(10, 6), sharex=True)
    t = sol.times
    ax[0, 0].plot(t, u.convert("bit_axial_velocity", sol.x2)[0], ".-")
    ax[0, 0].set_ylabel(f"bit axial velocity ({u.label('bit_axial_velocity')})")
    ax[0, 1].plot(t, u.convert("bit_angular_velocity", sol.x4)[0], ".-")
    ax[0, 1].set_ylabel(f"bit angular velocity ({u.label('bit_angular_velocity')})")
    ax[1, 0].step(t[:-1], u.convert("hook_load", sol.force)[0], where="post")
    ax[1, 0].set_ylabel(f"string force ({u.label('hook_load')})")
    ax[1, 1].step(t[:-1], u.convert("surface_torque", sol.torque)[0], where="post")
    ax[1, 1].set_ylabel(f"string torque ({u.label('surface_torque')})")
    for a in ax[1]:
        a.set_xlabel("time (s)")
    fig.suptitle(f"{sol.method} DP, cost {sol.cost:.4g}")
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=90)
    plt.close(fig)
