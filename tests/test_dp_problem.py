"""DP problem definition: validation before any search, TOML files, the CLI command."""

import json

import pytest

from downhole.control.dp import DPProblem, load_problem, problem_from_dict, solve_customized
from downhole.errors import DownholeInputError, ScenarioError


@pytest.mark.parametrize("changes, match", [
    ({"x2": {"min": 0.0, "max": 0.02, "points": 1}}, "x2 needs at least 2 points"),
    ({"x4": {"min": 20.0, "max": 0.0, "points": 11}}, "x4 is empty or inverted"),
    ({"x4": {"min": 0.0, "max": 0.0, "points": 11}}, "x4 is empty or inverted"),
    ({"targets": {"v_d": 0.05}}, r"v_d = 0.05 m/s is outside the x2 grid"),
    ({"targets": {"w_m": 9.5}}, "w_m = 9.5 rad/s is not on the x4 grid"),
    ({"x2": {"min": 0.001, "max": 0.02, "points": 20}}, "x2 initial state"),
    ({"step": 0.3}, r"step 0.3 s does not divide horizon 20.0 s"),
    ({"horizon": -1.0}, "horizon: .* admissible range of a time"),
    ({"bounds": {"force": (1e5, 0.0)}}, r"bounds.force .* is empty"),
    ({"bounds": {"force": (0.0, 5e4)}}, r"infeasible bounds: .*string force of 7.1\d*e\+04 N"),
    ({"bounds": {"torque": (0.0, 8e3)}}, r"infeasible bounds: .*string torque of 1.05\d*e\+04"),
    ({"x1_regions": 5}, "must be given together"),
    ({"x1_regions": 0, "x3_regions": 0}, "positive number of regions"),
    ({"model": {"preset": "table_3_1"}}, "neutral preset"),
    ({"model": {"preset": "nope"}}, "unknown preset"),
    ({"robust": {"epsilon_scales": (1.0, -0.5)}}, "positive factors"),
    ({"standard": {"substep": 1.0}}, "exceeds the DP step"),
])
def test_bad_problem_definitions_are_rejected_with_precise_messages(changes, match):
    with pytest.raises(DownholeInputError, match=match):
        DPProblem(**changes)


def test_unreachable_target_is_rejected_before_the_search():
    # 0.05 s step with a 2 rad/s x4 grid needs ~115 kN m for one grid step: infeasible
    p = DPProblem(step=0.05, x4={"min": 0, "max": 20, "points": 11})
    with pytest.raises(DownholeInputError, match=r"cannot be reached from rest in 400 steps"):
        solve_customized(p)


def test_units_are_accepted():
    p = DPProblem(targets={"v_m": "36 m/h", "v_d": "36 m/h"}, horizon="20 s")
    assert p.targets.v_m == pytest.approx(0.01)


def test_toml_examples_load_and_errors_name_the_field(tmp_path):
    from pathlib import Path

    root = Path(__file__).resolve().parents[1] / "examples"
    files = sorted(root.glob("dp_*.toml"))
    assert len(files) >= 3
    for f in files:
        if f.name == "dp_described.toml":  # its model comes from the description
            continue                        # (tests/test_dp_described.py)
        load_problem(f)
    bad = tmp_path / "bad.toml"
    bad.write_text("[optimize]\nhorizon = 20.0\n[optimize.x2]\nmin = 0.0\nmax = 0.02\n"
                   "points = 'many'\n")
    with pytest.raises(ScenarioError, match=r"bad.toml: optimize.x2.points: .*integer"):
        load_problem(bad)
    bad.write_text("[optimize]\nhorizon = 20.0\nstepp = 0.25\n")
    with pytest.raises(ScenarioError, match="optimize.stepp: unknown key"):
        load_problem(bad)
    bad.write_text("horizon = [\n")
    with pytest.raises(ScenarioError, match="not valid TOML"):
        load_problem(bad)
    with pytest.raises(ScenarioError, match="step 0.3 s does not divide"):
        problem_from_dict({"step": 0.3})


def test_cli_optimize_dp(tmp_path, capsys):
    from downhole.cli import main

    scen = tmp_path / "p.toml"
    scen.write_text("[optimize]\nhorizon = 3.0\nstep = 0.25\n")
    assert main(["optimize", "dp", str(scen), "--method", "customized", "--out",
                 str(tmp_path / "o"), "--no-progress"]) == 0
    meta = json.loads((tmp_path / "o" / "solution.json").read_text())
    assert meta["method"] == "customized" and meta["cost"] > 0
    assert (tmp_path / "o" / "solution.png").is_file()
    assert main(["optimize", "dp", str(scen), "--method", "magic", "--out",
                 str(tmp_path / "o2")]) == 2
    capsys.readouterr()
    scen.write_text("[optimize]\nhorizon = 3.0\nstep = 0.4\n")
    assert main(["optimize", "dp", str(scen), "--out", str(tmp_path / "o3")]) == 2
    err = capsys.readouterr().err
    assert "optimize.step: step 0.4 s does not divide" in err and err.count("\n") == 1
    assert not (tmp_path / "o3").exists()


def test_cli_uses_the_files_method_unless_overridden(tmp_path):
    from downhole.cli import main

    scen = tmp_path / "p.toml"
    scen.write_text('[optimize]\nmethod = "standard"\nhorizon = 2.0\nstep = 0.25\n'
                    "[optimize.standard]\nforce_levels = 5\ntorque_levels = 5\n")
    assert main(["optimize", "dp", str(scen), "--out", str(tmp_path / "a"),
                 "--no-progress", "--no-replay"]) == 0
    assert json.loads((tmp_path / "a" / "solution.json").read_text())["method"] == "standard"
    assert main(["optimize", "dp", str(scen), "--method", "customized", "--out",
                 str(tmp_path / "b"), "--no-progress", "--no-replay"]) == 0
    assert json.loads((tmp_path / "b" / "solution.json").read_text())["method"] == "customized"


# ------------------------------------------------------------------ the unified file schema
OLD_DP = """horizon = 20.0
step = 0.25
[model]
preset = "table_2_1"
epsilon = "77 MPa"
[x2]
min = 0.0
max = 0.02
points = 21
"""


@pytest.mark.parametrize("text, field, hint", [
    ("horizon = 20.0\n", "horizon", "optimize.horizon"),
    ("step = 0.25\n", "step", "optimize.step"),
    ("x1_regions = 5\nx3_regions = 5\n", "x1_regions", "optimize.x1_regions"),
    ("[x2]\nmin = 0\nmax = 0.02\npoints = 21\n", "x2", "[optimize.x2]"),
    ("[x4]\nmin = 0\nmax = 20\npoints = 21\n", "x4", "[optimize.x4]"),
    ("[targets]\nv_m = 0.01\n", "targets", "[optimize.targets]"),
    ("[weights]\nlambda1 = 1.0\n", "weights", "[optimize.weights] (DP files)"),
    ("[bounds]\nforce = [0, 1e5]\n", "bounds", "[optimize.bounds]"),
    ("[robust]\nsubstep = 0.005\n", "robust", "[optimize.robust]"),
    ("[standard]\nsubstep = 0.005\n", "standard", "[optimize.standard]"),
    ("[dp]\nhorizon = 20.0\n", "dp", "[optimize]"),
    ('[model]\npreset = "table_2_1"\nepsilon = "77 MPa"\n', "model.epsilon", "bit.epsilon"),
])
def test_every_older_dp_key_gets_a_one_line_hint(tmp_path, capsys, text, field, hint):
    from downhole.cli import main

    f = tmp_path / "old.toml"
    f.write_text(text)
    with pytest.raises(ScenarioError) as info:
        load_problem(f)
    assert info.value.field == field
    assert info.value.message.startswith("renamed: use ") and hint in info.value.message
    assert main(["optimize", "dp", str(f), "--out", str(tmp_path / "o"), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{field}: renamed: use " in err and hint in err
    assert not (tmp_path / "o").exists()


def test_a_whole_older_file_names_a_key_to_rename(tmp_path):
    f = tmp_path / "old.toml"
    f.write_text(OLD_DP)
    with pytest.raises(ScenarioError, match="renamed: use"):
        load_problem(f)


def test_unit_strings_are_accepted_on_every_physical_value(tmp_path):
    """Each physical value of a problem file in units equals the SI one; bare numbers are SI."""
    from downhole.control.dp.problem import load_dp_scenario

    si = """
[model]
fidelity = "lumped4"
[bit]
epsilon = 60e6
zeta = 0.6
[optimize]
horizon = 20.0
step = 0.25
[optimize.x2]
min = 0.0
max = 0.02
points = 21
[optimize.x4]
min = 0.0
max = 20.0
points = 21
[optimize.targets]
v_m = 0.01
w_m = 10.0
v_d = 0.01
w_d = 10.0
[optimize.bounds]
force = [0.0, 200e3]
torque = [0.0, 30e3]
top_speed = [-0.2, 0.2]
rotary_speed = [0.0, 40.0]
[optimize.robust]
substep = 0.005
[optimize.standard]
substep = 0.005
"""
    units = (si.replace("epsilon = 60e6", 'epsilon = "60 MPa"')
             .replace("horizon = 20.0", 'horizon = "20 s"')
             .replace("step = 0.25", 'step = "250 ms"')
             .replace("max = 0.02", 'max = "72 m/h"').replace("max = 20.0", 'max = "20 rad/s"')
             .replace("v_m = 0.01", 'v_m = "10 mm/s"').replace("w_m = 10.0", 'w_m = "10 rad/s"')
             .replace("v_d = 0.01", 'v_d = "36 m/h"').replace("w_d = 10.0", 'w_d = "10 rad/s"')
             .replace("force = [0.0, 200e3]", 'force = ["0 kN", "200 kN"]')
             .replace("torque = [0.0, 30e3]", 'torque = ["0 kN*m", "30 kN*m"]')
             .replace("top_speed = [-0.2, 0.2]", 'top_speed = ["-200 mm/s", "0.2 m/s"]')
             .replace("rotary_speed = [0.0, 40.0]", 'rotary_speed = ["0 rpm", "40 rad/s"]')
             .replace("substep = 0.005", 'substep = "5 ms"'))
    assert units.count('"') >= 40
    (tmp_path / "si.toml").write_text(si)
    (tmp_path / "units.toml").write_text(units)
    a, _ = load_dp_scenario(tmp_path / "si.toml")
    b, _ = load_dp_scenario(tmp_path / "units.toml")
    da, db = a.model_dump(), b.model_dump()
    assert da.keys() == db.keys()
    for key in da:
        assert da[key] == pytest.approx(db[key]) if not isinstance(da[key], dict) else True, key
    assert a.targets == b.targets and a.bounds.top_speed == pytest.approx(b.bounds.top_speed)
    assert a.x2.max == pytest.approx(b.x2.max) == 0.02 and a.step == pytest.approx(b.step)
    assert a.robust.substep == pytest.approx(b.robust.substep) == 0.005
    assert a.bounds.force == pytest.approx(b.bounds.force) == (0.0, 2e5)
    # the [bit] overrides reach the model: epsilon (the robust ensemble's base) and zeta
    _, bit = b.params()
    assert bit.epsilon == pytest.approx(60e6) and bit.zeta == pytest.approx(0.6)
    assert b.arrays().bit[0] == pytest.approx(60e6)


@pytest.mark.parametrize("text, field, msg", [
    ('[model]\nfidelity = "fem"\n', "model.fidelity", "expected 'lumped4'"),
    ('[model]\npreset = "table_3_1"\n', "model.preset", "neutral preset"),
    ("[bit]\nepsilon = \"nan\"\n", "bit.epsilon", "finite number"),
    ("[bit]\nblades = 3\n", "bit.blades", "unknown bit parameter"),
    ('[bit]\npreset = "table_2_1"\n', "bit.preset", "brings its bit"),
    ('[optimize]\nmethod = "magic"\n', "optimize.method", "customized"),
    ("[optimize.x2]\nmin = 0\nmax = \"1e300 m/s\"\npoints = 21\n", "optimize.x2.max",
     "admissible range"),
    ("[optimize.x4]\nmin = 0\nmax = 20\npoints = [1, 2]\n", "optimize.x4.points", "integer"),
    ("[optimize.targets]\nw_d = 9.5\n", "optimize.targets.w_d", "not on the x4 grid"),
    ("[optimize.bounds]\nforce = [0, 1, 2]\n", "optimize.bounds.force", "at most 2"),
    ("[optimize.bounds]\ntorque = [0.0, 8e3]\n", "optimize.bounds.torque", "infeasible"),
    ("[optimize.robust]\nsubstep = \"1 s\"\n", "optimize.robust.substep", "exceeds the DP step"),
    ("[optimize]\nx1_regions = 4\n", "optimize.x3_regions", "given together"),
    ("[simulation]\nduration = 1.0\n", "simulation", "unknown key"),
])
def test_bad_problem_files_name_the_file_field(tmp_path, text, field, msg):
    f = tmp_path / "bad.toml"
    f.write_text(text)
    with pytest.raises(ScenarioError) as info:
        load_problem(f)
    assert info.value.field == field, str(info.value)
    assert msg in info.value.message and "bad.toml" in str(info.value)
