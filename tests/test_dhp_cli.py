"""`downhole design dhp`: scenario parsing, outputs and one-line errors."""

import json

import numpy as np
import pytest

from downhole.cli import main
from downhole.control.dhp import load_controller

SCEN = """
[model]
fidelity = "fem"
preset = "design"
[controller]
type = "dhp"
[controller.dhp]
design = "fem24"
[controller.dhp.training]
horizon = "8 s"
n_samples = 50
[reference]
type = "step"
axial_velocity = "10 mm/s"
angular_velocity = 20.0
[simulation]
duration = 8.0
depth_of_cut = "approximate"
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
    assert rep["simulation"]["units"]["mean_rop"] == "m/s"
    # --units oilfield: the same run's summary in ft/h and rpm (independent pint registry)
    import pint

    ureg = pint.UnitRegistry()
    capsys.readouterr()
    assert main(["design", "dhp", str(sc), "--out", str(tmp_path / "f"), "--no-progress",
                 "--units", "oilfield"]) == 0
    printed = capsys.readouterr().out
    f = json.loads((tmp_path / "f" / "report.json").read_text())["simulation"]
    assert f["units"]["mean_rop"] == "ft/h" and f["units"]["mean_bit_angular_velocity"] == "rpm"
    assert f["summary"]["mean_rop"] == pytest.approx(
        ureg.Quantity(s["mean_rop"], "m/s").to("ft/hour").magnitude, rel=1e-9)
    assert f["summary"]["mean_bit_angular_velocity"] == pytest.approx(
        ureg.Quantity(s["mean_bit_angular_velocity"], "rad/s").to("rpm").magnitude, rel=1e-9)
    assert "ft/h" in printed and "rpm" in printed


@pytest.mark.parametrize("text, msg", [
    ('[controller.dhp]\ndesign = "fem25"\n', "controller.dhp.design: Input should be 'fem24'"),
    ('[controller.dhp.training]\nhorizon = "0.1 ms"\n', "shorter than one step"),
    ('[controller.dhp.training]\nn_samples = 10\nhorizon = 0.01\n', "n_samples = 10 is fewer than"),
    ('[reference]\ntype = "square"\n', "reference.type"),
    ('[controller.dhp.weights]\nq_bit = [1, 1]\n', "unknown penalty weight keys"),
    ('[controller.dhp]\nweights = "heavy"\n', "controller.dhp.weights: "),
    ('[model]\nfidelity = "rig"\n', "model.fidelity"),
    ('[model]\nfidelity = "lumped4"\n', "model.fidelity: a 'fem24' design has the FEM's states"),
    ('[model]\nfidelity = "hybrid"\npreset = "hybrid24"\n', "model.preset: the hybrid plant"),
    ('[nonsense]\n', "unknown table"),
    ('[controller.dhp]\ndesign = "lumped"\npreset = "table_3_1"\n', "needs a lumped one"),
    ('[controller.dhp]\nelements = 7\n', "controller.dhp.elements: used by design = 'fem'"),
    ('[controller.dhp]\nfriction = true\n', "controller.dhp.friction: expected a friction"),
    ('[controller.dhp]\ninput_limits = [["300 kN", "-50 kN"], [-6e4, 6e4]]\n',
     "controller.dhp.input_limits: force limits"),
    ('[controller.dhp]\ninput_limits = [[1, 2, 3], [-6e4, 6e4]]\n',
     "controller.dhp.input_limits[1]"),
    ('[controller.dhp.plan]\nknots = 3\n', "controller.dhp.plan.knots: unknown key"),
    ('[controller.dhp.plan]\nn_knots = 30\n',
     "controller.dhp.plan: PlanSettings: the knots end at 12 s"),
    ('[controller.dhp]\ndesign = "lumped"\n[controller.dhp.plan]\n',
     "controller.dhp.plan: a planned start-up needs a FEM design"),
    ('[controller]\ntype = "pi"\n', "controller.type"),
    ('[bit]\nepsilon = "-3 MPa"\n', "bit.epsilon"),
    ('[reference]\nt_final = "10 s"\n', "reference.t_final: used by type = 'ramp' only"),
    ('[controller.dhp.training]\nhorizon = "1e5 s"\n',
     "controller.dhp.training.horizon: horizon / dt = 1e+08 training steps"),
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
    run.write_text('title = "saved DHP"\n'
                   + SCEN.replace('type = "dhp"\n', 'type = "dhp"\nfile = "o/dhp_controller"\n'))
    assert main(["simulate", str(run), "--out", str(tmp_path / "r")]) == 0
    summary = json.loads((tmp_path / "r" / "summary.json").read_text())
    flat = json.dumps(summary)
    assert "mean_rop" in flat
    bad = tmp_path / "bad.toml"
    bad.write_text('[controller]\ntype = "dhp"\nfile = "nowhere"\n[controller.dhp]\n')
    assert main(["simulate", str(bad), "--out", str(tmp_path / "b")]) == 2


def test_design_dhp_with_a_plan_table_plans_the_start_up(tmp_path, capsys):
    """A [plan] table: the start-up is planned on the design FEM; on the design FEM itself the
    closed loop follows the plan (the bit at rest until the planned torque wave arrives, the
    commands the planned knots), and the report records the plan."""
    sc = tmp_path / "p.toml"
    sc.write_text(SCEN.replace('preset = "design"', 'preset = "fem24"') + """
[controller.dhp.plan]
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
