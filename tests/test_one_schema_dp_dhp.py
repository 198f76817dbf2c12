"""The DP problem file and the DHP design scenario are read through the one scenario schema
(downhole._schema.parse): both give the same Scenario type, and the problem read from
examples/dp_customized.toml is the one its keys say (hand values from the file)."""

from pathlib import Path

import pytest

from downhole._reader import read_toml
from downhole._schema import DHPOptions, Scenario, parse
from downhole.control.dp import DPProblem, TargetSpec, WeightSpec
from downhole.control.dp.problem import BoundSpec, dp_problem_of, load_dp_scenario
from downhole.errors import ScenarioError

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def test_a_dp_file_and_a_dhp_file_parse_to_the_one_scenario():
    dp, src_dp, _ = read_toml(EXAMPLES / "dp_customized.toml")
    dhp, src_dhp, _ = read_toml(EXAMPLES / "dhp_step_fem24.toml")
    a, b = parse(dp, src_dp), parse(dhp, src_dhp)
    assert type(a) is type(b) is Scenario
    assert a.optimize is not None and a.model.fidelity == "lumped4" and a.simulation is None
    assert b.optimize is None and isinstance(b.controller.options, DHPOptions)
    assert b.controller.options.dhp.design == "fem24"
    assert b.controller.options.dhp.training.horizon == 20.0
    assert b.simulation.depth_of_cut == "approximate"


def test_the_dp_example_is_the_problem_its_keys_say():
    """examples/dp_customized.toml by hand: table_2_1, 20 s in 0.25 s steps, 21 x 21 grid up to
    0.02 m/s and 20 rad/s, targets 0.01 m/s / 10 rad/s, the Eq. 2.13 weights, 200 kN / 30 kN m."""
    problem, method = load_dp_scenario(EXAMPLES / "dp_customized.toml")
    hand = DPProblem(
        horizon=20.0, step=0.25,
        x2={"min": 0.0, "max": 0.02, "points": 21}, x4={"min": 0.0, "max": 20.0, "points": 21},
        targets=TargetSpec(v_m=0.01, w_m=10.0, v_d=0.01, w_d=10.0),
        weights=WeightSpec(lambda1=1.0e4, lambda2=1.0e-2, lambda3=1.0e5, lambda4=1.0e-1),
        bounds=BoundSpec(force=(0.0, 200.0e3), torque=(0.0, 30.0e3)),
        model={"preset": "table_2_1"})
    assert method == "customized"
    assert problem == hand
    assert problem.model_dump() == hand.model_dump()
    assert problem.steps == 80 and problem.model.epsilon is None


def test_a_dp_file_without_model_or_optimize_is_the_default_problem():
    problem, method = dp_problem_of({}, "<t>")
    assert problem == DPProblem() and method is None
    problem, _ = dp_problem_of({"model": {"preset": "table_2_1"}, "bit": {"epsilon": "77 MPa"}})
    assert problem.model.epsilon == pytest.approx(77e6)


@pytest.mark.parametrize("data, field", [
    ({"controller": {"type": "pi"}}, "controller"),
    ({"model": {"interface": "state"}}, "model.interface"),
    ({"model": {"fidelity": "neutral"}}, "model.fidelity"),
])
def test_the_one_schemas_other_tables_are_not_a_dp_problems(data, field):
    with pytest.raises(ScenarioError) as info:
        dp_problem_of(data, "<t>")
    assert info.value.field == field, str(info.value)
