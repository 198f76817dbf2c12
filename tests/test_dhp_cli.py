"""`downhole design dhp`: scenario parsing, outputs and one-line errors."""

import json

import numpy as np
import pytest

from downhole.cli import main
from downhole.control.dhp import load_controller

SCEN = """
[model]
kind = "fem24"
[reference]
type = "step"
axial = "10 mm/s"
angular = 20.0
[training]
horizon = 8.0
n_samples = 50
[simulation]
duration = 8.0
plant = "design"
"""


def test_design_dhp_writes_controller_report_and_result(tmp_path, capsys):
    sc = tmp_path / "s.toml"
    sc.write_text(SCEN)
    rc = main(["design", "dhp", str(sc), "--out", str(tmp_path / "o"), "--no-progress"])
    assert rc == 0
    rep = json.loads((tmp_path / "o" / "report.json").read_text())
    assert rep["n_states"] == 24 and rep["max_mu"] < 1
    s = rep["simulation"]["summary"]
    assert s["stuck_fraction"] == 0.0
    assert abs(s["mean_rop"] - 0.01) < 0.05 * 0.01
    ctrl = load_controller(tmp_path / "o" / "dhp_controller")
    assert ctrl.kd.shape == (8000, 2, 24)
    assert (tmp_path / "o" / "closed_loop.nc").exists()
    assert np.isfinite(ctrl.kc).all()


@pytest.mark.parametrize("text, msg", [
    ('[model]\nkind = "fem25"\n', "model.kind: expected 'fem24', 'fem' or 'lumped'"),
    ('[training]\nhorizon = "0.1 ms"\n', "shorter than one step"),
    ('[training]\nn_samples = 10\nhorizon = 0.01\n', "n_samples = 10 is fewer than"),
    ('[reference]\ntype = "square"\n', "reference.type"),
    ('[weights]\nq_bit = [1, 1]\n', "unknown penalty weight keys"),
    ('[simulation]\nplant = "rig"\n', "simulation.plant"),
    ('[nonsense]\n', "unknown table"),
    ('[model]\nkind = "lumped"\npreset = "table_3_1"\n', "needs a lumped one"),
    ('[plan]\nknots = 3\n', "plan.knots: unknown key"),
    ('[plan]\nn_knots = 30\n', "plan: PlanSettings: the knots end at 12 s"),
    ('[model]\nkind = "lumped"\n[plan]\n', "plan: a planned start-up needs a FEM design"),
])
def test_bad_scenarios_exit_2_with_one_line(tmp_path, capsys, text, msg):
    sc = tmp_path / "bad.toml"
    sc.write_text(text)
    rc = main(["design", "dhp", str(sc), "--out", str(tmp_path / "o"), "--no-progress"])
    assert rc == 2
    err = capsys.readouterr().err
    assert msg in err and err.count("\n") == 1


def test_downhole_simulate_runs_a_dhp_scenario_with_a_saved_controller(tmp_path):
    sc = tmp_path / "s.toml"
    sc.write_text(SCEN)
    assert main(["design", "dhp", str(sc), "--out", str(tmp_path / "o"), "--no-progress"]) == 0
    run = tmp_path / "run.toml"
    run.write_text('title = "saved DHP"\n[controller]\nfile = "o/dhp_controller"\n'
                   + SCEN.replace("[model]\n", '[model]\ntype = "dhp"\n'))
    assert main(["simulate", str(run), "--out", str(tmp_path / "r")]) == 0
    summary = json.loads((tmp_path / "r" / "summary.json").read_text())
    flat = json.dumps(summary)
    assert "mean_rop" in flat
    bad = tmp_path / "bad.toml"
    bad.write_text('[controller]\nfile = "nowhere"\n[model]\ntype = "dhp"\n')
    assert main(["simulate", str(bad), "--out", str(tmp_path / "b")]) == 2


def test_design_dhp_with_a_plan_table_plans_the_start_up(tmp_path, capsys):
    """A [plan] table: the start-up is planned on the design FEM; on the design FEM itself the
    closed loop follows the plan (the bit at rest until the planned torque wave arrives, the
    commands the planned knots), and the report records the plan."""
    sc = tmp_path / "p.toml"
    sc.write_text(SCEN.replace('plant = "design"', 'plant = "fem24"') + """
[plan]
duration = 3.0
knot_spacing = 0.5
n_knots = 5
settle_from = 2.0
late_from = 2.5
steady_from = 2.5
max_evaluations = 2
""")
    rc = main(["design", "dhp", str(sc), "--out", str(tmp_path / "o"), "--no-progress"])
    assert rc == 0
    assert "start-up planned on the design FEM" in capsys.readouterr().out
    rep = json.loads((tmp_path / "o" / "report.json").read_text())
    knots = np.array(rep["plan"]["knots"])
    assert knots.shape == (5, 2)
    ctrl = load_controller(tmp_path / "o" / "dhp_controller")
    assert "reference_shift" in ctrl.arrays
    # the saved feed-forward is the planned piecewise-linear input: the knot at 1.0 s
    assert np.allclose(ctrl.u_ff[1000] * ctrl.input_scale, knots[1])
