"""``downhole design dhp SCENARIO.toml --out DIR``: train a DHP (SNAC) tracking controller.

Writes ``DIR/dhp_controller.npz`` + ``DIR/dhp_controller.json``, ``DIR/report.json`` and, with a
``[simulation]`` table, ``DIR/closed_loop.nc`` and ``DIR/closed_loop.png`` (the closed loop on
the ``[model]`` plant). The scenario schema (``[controller.dhp]`` the design, ``[model]`` the
plant, ``[bit]``, ``[reference]``, ``[simulation]``; docs/dhp.md) and the runner behind
``downhole simulate`` live in :mod:`downhole.scenario.dhp`.
"""

from __future__ import annotations

import json
from pathlib import Path

import typer

from downhole.cli._units import UNIT_OPTION, UNITS_OPTION, resolve_units
from downhole.cli.design import design_app
from downhole.scenario.dhp import (  # noqa: F401
    design_from_scenario,
    load_dhp_scenario,
    parse_dhp_scenario,
    run_dhp_scenario,
    run_scenario_simulation,
)

__all__ = ["design_dhp_cmd"]


@design_app.command("dhp")
def design_dhp_cmd(scenario: Path = typer.Argument(..., help="DHP design scenario (TOML)"),
                   out: Path = typer.Option(Path("out/dhp"), "--out", help="output directory"),
                   progress: bool = typer.Option(True, "--progress/--no-progress",
                                                 help="progress bar while training"),
                   units: str = UNITS_OPTION, unit: list[str] | None = UNIT_OPTION):
    """Train a DHP (single-network adaptive critic) controller; optionally simulate it."""
    from downhole._atomic import OutputFolder, check_output_path

    check_output_path(out, kind="folder")
    display = resolve_units(units, unit)
    sc = load_dhp_scenario(scenario)
    folder = OutputFolder(out, ("dhp_controller.npz", "dhp_controller.json", "closed_loop.nc",
                                "closed_loop.png", "report.json"), "design dhp").begin()
    try:
        _design_and_write(folder, scenario, sc, progress, display)
    except BaseException as exc:
        folder.fail(f"{type(exc).__name__}: {exc}")
        raise
    folder.commit()


def _design_and_write(folder, scenario, sc, progress, display) -> None:
    from downhole._atomic import write_text_atomic

    out = folder.path
    ctrl = design_from_scenario(sc, progress=progress)
    folder.writing()
    npz, js = ctrl.save(out / "dhp_controller")
    tr = ctrl.training
    report = {"scenario": str(scenario), "model": sc["model"].name,
              "n_states": sc["model"].n_states, "horizon_s": ctrl.horizon,
              "method": tr.method, "training_seconds": tr.seconds,
              "max_iterations": int(tr.iterations.max()),
              "median_iterations": float(sorted(tr.iterations)[len(tr.iterations) // 2]),
              "max_mu": ctrl.meta["max_mu"], "controller": [str(npz), str(js)]}
    if "plan" in ctrl.meta:
        report["plan"] = ctrl.meta["plan"]
    if sc["simulation"] is not None:
        res = run_scenario_simulation(sc, ctrl)
        res.save(out / "closed_loop.nc")
        plant = sc["plant"]
        label = plant["fidelity"] if plant["preset"] is None else \
            f"{plant['fidelity']} {plant['preset']}"
        res.plot(out / "closed_loop.png", title=f"DHP closed loop ({label}, "
                                                f"{sc['simulation']['depth_of_cut']})",
                 units=display.for_figures())
        window = (min(5.0, 0.5 * sc["simulation"]["duration"]), sc["simulation"]["duration"])
        summary, summary_units = display.convert_summary(res.summary(window))
        report["simulation"] = {**sc["simulation"], "window": list(window),
                                "summary": summary, "units": summary_units}
    write_text_atomic(out / "report.json", json.dumps(report, indent=2, default=float))
    typer.echo(f"trained {sc['model'].name} over {ctrl.horizon:g} s in {tr.seconds:.2f} s "
               f"({tr.method}); controller: {npz}")
    if "plan" in report:
        typer.echo(f"start-up planned on the design FEM ({ctrl.plan.evaluations} FEM runs, "
                   f"{ctrl.plan.seconds:.1f} s)")
    if "simulation" in report:
        s, u = report["simulation"]["summary"], report["simulation"]["units"]
        if display.name == "si" and not display.overrides:  # the familiar mm/s
            rop, rop_unit = s["mean_rop"] * 1e3, "mm/s"
        else:
            rop, rop_unit = s["mean_rop"], u["mean_rop"]
        typer.echo(f"closed loop: mean ROP {rop:.2f} {rop_unit}, mean bit speed "
                   f"{s['mean_bit_angular_velocity']:.2f} {u['mean_bit_angular_velocity']}, "
                   f"stuck fraction {s['stuck_fraction']:.3f}")
