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
        load_problem(f)
    bad = tmp_path / "bad.toml"
    bad.write_text("horizon = 20.0\n[x2]\nmin = 0.0\nmax = 0.02\npoints = 'many'\n")
    with pytest.raises(ScenarioError, match=r"bad.toml: x2.points: .*integer"):
        load_problem(bad)
    bad.write_text("horizon = 20.0\nstepp = 0.25\n")
    with pytest.raises(ScenarioError, match="stepp"):
        load_problem(bad)
    bad.write_text("horizon = [\n")
    with pytest.raises(ScenarioError, match="not valid TOML"):
        load_problem(bad)
    with pytest.raises(ScenarioError, match="step 0.3 s does not divide"):
        problem_from_dict({"step": 0.3})


def test_cli_optimize_dp(tmp_path, capsys):
    from downhole.cli import main

    scen = tmp_path / "p.toml"
    scen.write_text("horizon = 3.0\nstep = 0.25\n")
    assert main(["optimize", "dp", str(scen), "--method", "customized", "--out",
                 str(tmp_path / "o"), "--no-progress"]) == 0
    meta = json.loads((tmp_path / "o" / "solution.json").read_text())
    assert meta["method"] == "customized" and meta["cost"] > 0
    assert (tmp_path / "o" / "solution.png").is_file()
    assert main(["optimize", "dp", str(scen), "--method", "magic", "--out",
                 str(tmp_path / "o2")]) == 2
    scen.write_text("horizon = 3.0\nstep = 0.4\n")
    assert main(["optimize", "dp", str(scen), "--out", str(tmp_path / "o3")]) == 2
    assert "does not divide" in capsys.readouterr().err
