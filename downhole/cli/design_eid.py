"""``downhole design eid SCENARIO.toml --out DIR``: synthesize the EID controller (LMI), check the
closed loop with the input delay, write the gains (npz + JSON), a short report and a root plot.

Scenario schema (all tables optional)::

    [model]
    preset = "table_3_1"            # a 'neutral' preset
    epsilon = "45 MPa"              # optional bit override (any BitParams field)

    [eid]
    internal_model_gain = [10.0, 1.0]   # B_R (axial, torsional)
    filter_bandwidth = [10.0, 2.0]      # rad/s, F(s) = bf/(s + bf)
    observer_gain = [20.0, 7.0]         # L
    gain_bound = 5.0                    # |[Kp K_R]| per channel
    predictor = true
    delayed_input_observer = true

    [reference]
    type = "constant"                   # or "seed_tracking" (Eqs. 3.34/3.35)
    axial = 0.01                        # m/s (constant)
    angular = 20.0                      # rad/s (constant)
"""

from __future__ import annotations

import json
import tomllib
import warnings
from pathlib import Path

import typer

from downhole.cli.design import design_app
from downhole.errors import ScenarioError

_EID_KEYS = {"internal_model_gain", "filter_bandwidth", "observer_gain", "gain_bound",
             "predictor", "delayed_input_observer"}


def _pair(src, key, val):
    if not (isinstance(val, list) and len(val) == 2 and all(isinstance(x, (int, float))
                                                            for x in val)):
        raise ScenarioError(src, f"eid.{key}", f"expected two numbers [axial, torsional], got "
                                               f"{val!r}")
    return tuple(float(x) for x in val)


def load_eid_scenario(path: Path):
    """Parse and validate an EID design scenario; returns (model, design kwargs, reference)."""
    from downhole.control.eid.references import constant_reference, seed_tracking_reference
    from downhole.params import get_preset
    from downhole.string.neutral import neutral_model

    src = str(path)
    try:
        data = tomllib.loads(Path(path).read_text())
    except FileNotFoundError:
        raise ScenarioError(src, "", "file not found") from None
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(src, "", f"invalid TOML: {exc}") from None
    unknown = set(data) - {"model", "eid", "reference"}
    if unknown:
        raise ScenarioError(src, sorted(unknown)[0], "unknown table; expected model, eid, "
                                                     "reference")
    mt = dict(data.get("model", {}))
    preset = mt.pop("preset", "table_3_1")
    try:
        pre = get_preset(preset)
    except KeyError as exc:
        raise ScenarioError(src, "model.preset", str(exc.args[0])) from None
    if pre.kind != "neutral":
        raise ScenarioError(src, "model.preset", f"{preset!r} is a {pre.kind} preset; need a "
                                                 "neutral one (table_3_1)")
    try:
        bit = pre.bit.model_copy(update={}) if not mt else type(pre.bit)(
            **{**pre.bit.model_dump(), **mt})
    except ValueError as exc:
        raise ScenarioError(src, "model", str(exc).splitlines()[0] + ": " + str(exc)) from None
    model = neutral_model(pre.string, bit)
    et = data.get("eid", {})
    bad = set(et) - _EID_KEYS
    if bad:
        raise ScenarioError(src, f"eid.{sorted(bad)[0]}", f"unknown key; expected one of "
                                                          f"{sorted(_EID_KEYS)}")
    kw = {}
    for k, v in et.items():
        if k in ("internal_model_gain", "filter_bandwidth", "observer_gain"):
            kw[k] = _pair(src, k, v)
        elif k == "gain_bound":
            if not isinstance(v, (int, float)) or v <= 0:
                raise ScenarioError(src, "eid.gain_bound", f"expected a positive number, got {v!r}")
            kw[k] = float(v)
        else:
            if not isinstance(v, bool):
                raise ScenarioError(src, f"eid.{k}", f"expected true/false, got {v!r}")
            kw[k] = v
    rt = data.get("reference", {})
    typ = rt.get("type", "constant")
    if typ == "constant":
        ref = constant_reference(float(rt.get("axial", 0.01)), float(rt.get("angular", 20.0)))
    elif typ == "seed_tracking":
        ref = seed_tracking_reference()
    else:
        raise ScenarioError(src, "reference.type", f"expected 'constant' or 'seed_tracking', got "
                                                   f"{typ!r}")
    return model, kw, ref


@design_app.command("eid")
def design_eid_cmd(scenario: Path = typer.Argument(..., help="EID design scenario (TOML)"),
                   out: Path = typer.Option(Path("out/eid"), "--out", help="output directory")):
    """Synthesize EID gains by LMI and check the closed loop with the input delay."""
    from downhole.control.eid import design_eid
    from downhole.control.eid.stability import closed_loop_stability, plot_roots

    model, kw, ref = load_eid_scenario(scenario)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ctrl = design_eid(model, reference=ref, **kw)
    out.mkdir(parents=True, exist_ok=True)
    ctrl.save(out)
    stab = closed_loop_stability(ctrl, model)
    plot_roots(stab, out / "roots.png")
    lines = ["# EID design report", "", f"scenario: {scenario}", ""]
    for g, r in zip(ctrl.gains, ctrl.reports):
        lines.append(f"- {r.channel}: Kp = {g.kp:.6g}, K_R = {g.kr:.6g}, L = {g.l:.6g}, "
                     f"B_R = {g.br:.6g}, F(s) = {g.bf:.6g}/(s + {g.bf:.6g}); LMI max eigenvalue "
                     f"{r.lmi_max_eigenvalue:.3e} (size {r.size}, {r.solve_seconds:.3f} s)")
    lines += ["", f"closed loop with input delay: {json.dumps(stab.to_dict())}", ""]
    (out / "report.md").write_text("\n".join(lines))
    typer.echo("\n".join(lines))
    if not stab.stable:
        typer.echo("warning: the closed loop with the input delay is NOT stable", err=True)
