"""``downhole design eid SCENARIO.toml --out DIR``: synthesize the EID controller (LMI), check the
closed loop with the input delay, write the gains (npz + JSON), a short report and a root plot.

The scenario is the neutral-model scenario of ``downhole simulate`` (schema in
:mod:`downhole.scenario.neutral`): ``[model]`` (fidelity "neutral", preset, ``[model.string]``,
``[bit]`` overrides) or a described system (``[well]``, ``[string]``: the design model is its
neutral-type model, :func:`downhole.scenario.system.neutral_design_model`), ``[controller] type = "eid"`` with the design options
(``internal_model_gain``, ``filter_bandwidth``, ``observer_gain``, ``gain_bound``, ``predictor``,
``delayed_input_observer``; all optional) and an optional ``[reference]``. ``[operation]`` and
``[simulation]`` are ignored here, so the same file both designs and runs the loop.
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import typer

from downhole._atomic import OutputFolder, atomic_path, check_output_path, write_text_atomic
from downhole.cli.design import design_app
from downhole.errors import ScenarioError


def load_eid_scenario(path: Path):
    """Parse and validate an EID design scenario; returns (model, design kwargs, reference)."""
    from downhole.scenario import load_scenario
    from downhole.scenario.neutral import build_neutral, build_reference, load_neutral_scenario

    data, source, _ = load_scenario(path)
    if "well" in data or "string" in data:  # the design model from the description
        from downhole.scenario.system import neutral_design_model

        return neutral_design_model(data, source)
    model_t = data.get("model")
    if isinstance(model_t, dict) and "fidelity" not in model_t:
        raise ScenarioError(source, "model.fidelity", 'required field is missing (use '
                            '"neutral")')
    sc = load_neutral_scenario(data, source)
    if sc.controller.type is None:
        raise ScenarioError(source, "controller", 'required table is missing ([controller] '
                            'type = "eid" with the design options)')
    if sc.controller.file is not None:
        raise ScenarioError(source, "controller.file", "design eid synthesizes a controller; "
                            "remove 'file' (it names an existing design)")
    model = build_neutral(sc, source)
    return model, sc.controller.options.design_options(), build_reference(sc)


@design_app.command("eid")
def design_eid_cmd(scenario: Path = typer.Argument(..., help="EID design scenario (TOML)"),
                   out: Path = typer.Option(Path("out/eid"), "--out", help="output directory")):
    """Synthesize EID gains by LMI and check the closed loop with the input delay."""
    check_output_path(out, kind="folder")
    model, kw, ref = load_eid_scenario(scenario)
    folder = OutputFolder(out, EID_FILES, "design eid").begin()
    try:
        _design_and_write(folder, scenario, model, kw, ref)
    except BaseException as exc:
        folder.fail(f"{type(exc).__name__}: {exc}")
        raise
    folder.commit()


#: What ``design eid`` writes into its folder (the previous run's are removed first).
EID_FILES = ("eid_gains.npz", "eid_controller.json", "roots.png", "report.md")


def _design_and_write(folder, scenario, model, kw, ref):
    from downhole.control.eid import design_eid
    from downhole.control.eid.stability import closed_loop_stability, plot_roots

    out = folder.path
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ctrl = design_eid(model, reference=ref, **kw)
    folder.writing()
    ctrl.save(out)
    stab = closed_loop_stability(ctrl, model)
    with atomic_path(out / "roots.png") as tmp:
        plot_roots(stab, tmp)
    lines = ["# EID design report", "", f"scenario: {scenario}", ""]
    for g, r in zip(ctrl.gains, ctrl.reports):
        lines.append(f"- {r.channel}: Kp = {g.kp:.6g}, K_R = {g.kr:.6g}, L = {g.l:.6g}, "
                     f"B_R = {g.br:.6g}, F(s) = {g.bf:.6g}/(s + {g.bf:.6g}); LMI max eigenvalue "
                     f"{r.lmi_max_eigenvalue:.3e} (size {r.size}, {r.solve_seconds:.3f} s)")
    lines += ["", f"closed loop with input delay: {json.dumps(stab.to_dict())}", ""]
    write_text_atomic(out / "report.md", "\n".join(lines))
    typer.echo("\n".join(lines))
    if not stab.stable:
        typer.echo("warning: the closed loop with the input delay is NOT stable", err=True)
