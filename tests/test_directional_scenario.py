"""Directional (FEM / hybrid) scenario files through the CLI: the shipped examples run and write
their outputs; bad input exits with code 2, names the file and the field, and writes nothing."""

import json
import textwrap
from pathlib import Path

import pytest

from downhole.cli import main
from downhole.sim import load_result

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


@pytest.mark.parametrize("name", ["directional_fem_stickslip", "directional_hybrid68_stickslip",
                                  "directional_survey_soft_torque"])
def test_examples_run_through_the_cli(name, tmp_path):
    path = EXAMPLES / f"{name}.toml"
    out = tmp_path / "run"
    assert main(["simulate", str(path), "--out", str(out)]) == 0
    for f in ("result.nc", "summary.json", "overview.png"):
        assert (out / f).stat().st_size > 0, f
    res = load_result(out / "result.nc")
    assert res.attrs["scenario"] == path.read_text()
    summary = json.loads((out / "summary.json").read_text())
    if "stickslip" in name:
        # both Table 5.1 cases stick-slip (fig4.4 / fig5.7 claims)
        assert summary["stuck_fraction"] > 0.2
        w = res["bit_angular_velocity"][res.time >= 10.0]
        assert 1.5 * 10.0 <= w.max() <= 3.0 * 10.0
    else:
        # the survey well: bit ends where the CSV's last station is (2700 m MD, 45 deg hold)
        md = res.attrs["node_md"]
        md = json.loads(md) if isinstance(md, str) else md
        assert md[-1] == pytest.approx(2700.0)
        assert summary["mean_rop"] > 0


BASE = """
title = "bad input"
[model]
fidelity = "{mtype}"
{model}
{extra}
[simulation]
duration = "0.2 s"
dt = "1 ms"
"""


#: A directional preset with a described well or string (not the system runner).
FEM20 = 'preset = "table_5_1"\n[model.fem]\nn_elements = 20'


def _run_bad(tmp_path, capsys, mtype="fem", model=FEM20, extra=""):
    p = tmp_path / "bad.toml"
    p.write_text(textwrap.dedent(BASE.format(mtype=mtype, model=model, extra=extra)))
    out = tmp_path / "out"
    rc = main(["simulate", str(p), "--out", str(out)])
    err = capsys.readouterr().err
    assert rc == 2, err
    assert not out.exists()
    assert str(p) in err
    return err


@pytest.mark.parametrize("extra,field,words", [
    ("[well]\nmd = [0, 500, 400]\ninclination = [0, 0, 10]\nazimuth = [0, 0, 0]",
     "well.md", "increase"),
    ("[well]\nmd = [0, 500, 900]\ninclination = [0, 10, 190]\nazimuth = [0, 0, 0]",
     "well.inclination", "0 to 180"),
    ("[[well.sections]]\ntype = \"vertical\"\nlength = \"-100 m\"",
     "well.sections[1].length", "admissible range of a length, 0 to 100000 m"),
    ("[[well.sections]]\ntype = \"vertical\"\nlength = 500\n[[well.sections]]\ntype = \"arc\"\n"
     "radius = 300", "well.sections[2]", "needs angle"),
    ("[[string.segments]]\nlength = 1000\nouter_diameter = \"5 in\"\ninner_diameter = \"6 in\"",
     "string.segments[1]", "must be smaller than outer_diameter"),
    ("[[string.segments]]\nlength = 1000\nouter_diameter = -0.1\ninner_diameter = 0.05",
     "string.segments[1].outer_diameter", "admissible range of a length, 0 to 100000 m"),
    ("[rig.hook]\nmode = \"force\"\nweight = 3", "rig.hook.weight", "unknown key"),
    ("[operation]\nwob = \"120 kN\"\nweight = 3", "operation.weight", "unknown key"),
    ("[controller]\ntype = \"pi\"\n[operation]\nsurface_speed = \"10 m/s\"",
     "operation.surface_speed", "rad/s"),
])
def test_bad_well_string_and_tables_name_file_and_field(tmp_path, capsys, extra, field, words):
    err = _run_bad(tmp_path, capsys, extra=extra)
    assert f": {field}: " in err and words in err, err


def test_bad_survey_csv_is_reported_with_line(tmp_path, capsys):
    (tmp_path / "s.csv").write_text("MD,INC,AZI\n0,0,0\n800,5,0\n700,10,0\n")
    err = _run_bad(tmp_path, capsys, extra='[well]\nsurvey = "s.csv"')
    assert ": well.survey: " in err and "line 4, column 'MD': measured depth 700 m does not increase (line 3: 800 m)" in err


@pytest.mark.parametrize("mtype,model,field,words", [
    ("fem", "[model.fem]\nn_elements = 1", "model.fem.n_elements", "too few"),
    ("fem", "element = 20", "model.element", "unknown key"),
    ("fem", "[model.fem]\nelement = 20", "model.fem.element", "unknown key"),
    ("hybrid", "[model.hybrid]\nn_ab = 3\nn_cd = 1", "model.hybrid.n_cd",
     "greater than or equal to 2"),
    ("hybrid", "wave_section = [2500, 3500]\n[model.hybrid]\npreset = \"hybrid68\"",
     "model.wave_section", "curved"),
    ("hybrid", "wave_section = [3000, 2000]", "model.wave_section", "0 < B < C"),
    ("hybrid", "wave_section = [0, 2000]", "model.wave_section", "0 < B < C"),
    ("hybrid", "wave_section = [2000]", "model.wave_section", "at least 2"),
    ("fem", "preset = \"table_2_1\"", "model.preset", "directional"),
])
def test_bad_discretization_names_the_field(tmp_path, capsys, mtype, model, field, words):
    err = _run_bad(tmp_path, capsys, mtype=mtype, model=model)
    assert f": {field}: " in err and words in err, err


@pytest.mark.slow  # compiles the DHP trainer's kernels (~40 s with a cold numba cache)
def test_dhp_controller_file_drives_the_directional_plant(tmp_path, capsys):
    from downhole.control.dhp import BitReference, DHPSettings, PenaltyWeights, design_dhp
    from downhole.control.dhp.directional import directional_affine_model, table_5_1_models
    from downhole.scenario import load_scenario, parse_scenario
    from downhole.scenario.directional import (
        DirectionalScenario,
        _dhp_design_depths,
        build_directional,
    )

    fem24, _ = table_5_1_models()
    design = directional_affine_model(fem24, 1e-3)
    ctrl = design_dhp(design, BitReference.step(0.01, 20.0), horizon=2.0,
                      weights=PenaltyWeights(bit_velocity=(100, 100), bit_position=(0.1, 0.1),
                                             r=(1, 1)),
                      settings=DHPSettings(n_samples=50, method="riccati"))
    ctrl.save(tmp_path / "ctrl")
    text = textwrap.dedent("""
        [model]
        fidelity = "hybrid"
        [model.hybrid]
        preset = "hybrid68"
        [controller]
        type = "dhp"
        file = "ctrl"
        [simulation]
        duration = "2 s"
        dt = "{dt}"
        depth_of_cut = "approximate"
        """)
    p = tmp_path / "dhp.toml"
    p.write_text(text.format(dt="1 ms"))
    # the design model's nodes re-meshed on the scenario's well are the DHP module's own
    data, src, _ = load_scenario(p)
    sc = parse_scenario(data, src, DirectionalScenario)
    from downhole.control.dhp import load_controller

    loaded = load_controller(tmp_path / "ctrl")
    depths = _dhp_design_depths(loaded, build_directional(sc, src), loaded.n_states // 4)
    assert depths == pytest.approx(fem24.node_md)
    out = tmp_path / "run"
    assert main(["simulate", str(p), "--out", str(out)]) == 0
    res = load_result(out / "result.nc")
    assert res["surface_torque"].max() > 0           # the controller turned the string
    # a controller trained at 1 ms cannot run at 0.5 ms
    p.write_text(text.format(dt="0.5 ms"))
    assert main(["simulate", str(p), "--out", str(tmp_path / "run2")]) == 2
    assert ": simulation.dt: " in capsys.readouterr().err
    assert not (tmp_path / "run2").exists()


def test_minimal_scenario_uses_the_table_5_1_defaults(tmp_path):
    from downhole.scenario import run_scenario
    from downhole.string.fem import fem_model

    p = tmp_path / "min.toml"
    p.write_text('[model]\nfidelity = "fem"\n[model.fem]\nn_elements = 30\n'
                 '[simulation]\nduration = "1 s"\n')
    res = run_scenario(p)
    assert res["reference_angular_velocity"][-1] == 10.0          # PI at 10 rad/s
    assert res["wob"][0] == pytest.approx(120e3, rel=1e-6)          # static WOB 120 kN
    m = fem_model(n_elements=30)
    assert res["hook_load"][0] == pytest.approx(m.buoyed_weight - 120e3, rel=1e-9)


def test_wave_segment_shorter_than_dt_names_simulation_dt(tmp_path, capsys):
    err = _run_bad(tmp_path, capsys, mtype="hybrid",
                   model='wave_section = [2000, 2005]\n[model.hybrid]\npreset = "hybrid24"')
    assert ": simulation.dt: " in err and "shorter than the step" in err
