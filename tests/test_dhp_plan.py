"""Planned start-up (two-degree-of-freedom DHP, downhole/control/dhp/plan.py)."""

import numpy as np
import pytest

from downhole.control.dhp import (
    BitReference,
    DHPSettings,
    DirectionalStatePlant,
    PenaltyWeights,
    design_dhp,
    load_controller,
    run_on_plant,
)
from downhole.control.dhp.plan import (
    PlannedTrajectory,
    PlanSettings,
    plan_trajectory,
    planned_controller,
)
from downhole.errors import DownholeInputError

SHORT = PlanSettings(duration=3.0, knot_spacing=0.5, n_knots=5, settle_from=2.0, late_from=2.5,
                     steady_from=2.5, max_evaluations=2)


@pytest.fixture(scope="module")
def setup():
    from downhole.control.dhp.directional import directional_affine_model, table_5_1_models

    fem24, hyb68 = table_5_1_models()
    design = directional_affine_model(fem24)
    plan = plan_trajectory(fem24, design, BitReference.step(), SHORT)
    gains = design_dhp(design, BitReference.step(), horizon=4.0,
                       weights=PenaltyWeights(bit_velocity=(0.2, 70), bit_position=(0.4, 0.02),
                                              integral=(60, 60)),
                       settings=DHPSettings(n_samples=50))
    return fem24, design, plan, gains


def test_planned_controller_reproduces_the_plan_on_the_design_fem(setup):
    """The plan's states (recorded node velocities of a compiled FEM run, positions by the
    trapezoidal rule) are the states the step-by-step plant reports (node fields, integrated
    by the plant) under the planned inputs: the feedback sees zero error, so the closed loop
    is the plan - to round-off, not to a tolerance of the controller."""
    fem24, design, plan, gains = setup
    ctrl = planned_controller(gains, plan)
    res = run_on_plant(ctrl, DirectionalStatePlant(fem24, design, design.dt,
                                                   depth_of_cut="approximate"), 3.0)
    v, w = plan.bit_velocities(design)
    n = plan.inputs.shape[0]
    assert np.max(np.abs(res["bit_angular_velocity"][:n] - w[:n])) < 1e-6
    assert np.max(np.abs(res["bit_axial_velocity"][:n] - v[:n])) < 1e-9
    # and the commands are the planned inputs (zero feedback)
    assert np.max(np.abs(res["surface_torque"][:n] - plan.inputs[:, 1])) < 1e-3
    assert np.max(np.abs(res["slack_off_force"][:n] - plan.inputs[:, 0])) < 1e-2


def test_plan_inputs_are_the_piecewise_linear_knots(setup):
    _, design, plan, _ = setup
    t = plan.time[:-1]
    for j, tk in enumerate(0.5 * np.arange(1, 6)):
        k = int(round(tk / design.dt))
        assert np.allclose(plan.inputs[k], plan.knots[j], rtol=1e-12, atol=1e-6)
    assert np.allclose(plan.inputs[0], 0.0)
    assert np.allclose(plan.inputs[t >= 2.5], plan.knots[-1])


def test_planned_reference_joins_the_trained_one_and_survives_save_load(setup, tmp_path):
    """After the plan the reference is the trained one shifted rigidly (positions only), also
    past the trained horizon; saving and loading keeps it."""
    _, design, plan, gains = setup
    ctrl = planned_controller(gains, plan)
    n = plan.inputs.shape[0]
    P = ctrl.state_scale
    d = (ctrl.reference_nd[n + 1:, :24] - gains.reference_nd[n + 1:, :24]) * P[:24]
    kinds = np.array(ctrl.state_kinds[:24])
    assert np.allclose(d[:, kinds == "axial_velocity"], 0.0)
    assert np.allclose(d[:, kinds == "angular_velocity"], 0.0)
    assert np.ptp(d[:, kinds == "angular_position"]) < 1e-9      # one rigid shift
    shift = d[0, kinds == "angular_position"][0]
    assert shift < -5.0               # the bit lags the step's integral after the start-up
    # the integrators' shift: their Euler sums along the plan (within a step's motion of it)
    assert abs((ctrl.reference_nd[n + 1, 25] - gains.reference_nd[n + 1, 25]) * P[25]
               - shift) < 20.0 * design.dt
    # past the horizon: the same shift (no jump back to the step's integral)
    r_past = ctrl.step_terms(ctrl.n_steps + 5)[0] * P
    r_last = ctrl.reference_nd[-1] * P
    ia = design.index("angular_position", design.bit_node)
    # reference_nd[-1] is step n_steps, step_terms(n_steps + 5) is 6 steps on
    assert abs(r_past[ia] - r_last[ia] - 20.0 * 6 * design.dt) < 1e-6
    ctrl.save(tmp_path / "c")
    back = load_controller(tmp_path / "c")
    back.attach_model(ctrl._model)
    z = ctrl.reference_nd[100] * P
    assert np.allclose(back.control(100, z[:24]), ctrl.control(100, z[:24]))
    assert np.allclose(back.step_terms(ctrl.n_steps + 5)[0], ctrl.step_terms(ctrl.n_steps + 5)[0])


def test_integral_controller_takes_named_observations_of_the_model_states(setup):
    """With integral action the controller keeps its integrators: a plant that reports the
    24 model states by name (the SIL runtime) gets the same command as with ``state``."""
    _, design, plan, gains = setup
    ctrl = planned_controller(gains, plan)
    z = ctrl.reference_nd[500, :24] * ctrl.state_scale[:24] + 0.01
    named = {n: float(v) for n, v in zip(design.state_names, z)}
    ctrl.reset()
    a = ctrl.command(0.5, named)
    ctrl.reset()
    b = ctrl.command(0.5, {"state": z})
    assert a == b
    with pytest.raises(DownholeInputError, match="observation lacks state 'v_6'"):
        ctrl.command(0.5, {k: v for k, v in named.items() if k != "v_6"})


def test_plan_settings_and_inputs_are_checked(setup):
    fem24, design, plan, gains = setup
    with pytest.raises(DownholeInputError, match="knot_spacing must be a positive"):
        PlanSettings(knot_spacing=0.0)
    with pytest.raises(DownholeInputError, match="knots end at 8 s, past duration = 7 s"):
        PlanSettings(n_knots=20)
    with pytest.raises(DownholeInputError, match="n_knots must be an integer >= 1"):
        PlanSettings(n_knots=0)
    with pytest.raises(DownholeInputError, match="steady_from = 8 s must be before duration"):
        PlanSettings(steady_from=8.0)
    with pytest.raises(DownholeInputError, match="planning model must be a DirectionalModel"):
        plan_trajectory(design, design)
    with pytest.raises(DownholeInputError, match="must be shorter than the trained horizon"):
        short = design_dhp(design, BitReference.step(), horizon=2.0,
                           settings=DHPSettings(n_samples=50))
        planned_controller(short, plan)
    with pytest.raises(DownholeInputError, match="plan must be a PlannedTrajectory"):
        planned_controller(gains, "plan")
    assert isinstance(plan, PlannedTrajectory)


@pytest.mark.slow
def test_default_plan_takes_the_design_fem_into_the_5_percent_band_by_3_5_s(setup):
    """The default plan (the one dhp.hybrid68 uses) on its own FEM, open loop: both bit
    velocities within 5% of 10 mm/s and 20 rad/s from 3.5 s to the end of the plan."""
    fem24, design, _, _ = setup
    plan = plan_trajectory(fem24, design)
    v, w = plan.bit_velocities(design)
    late = plan.time >= 3.5
    assert np.max(np.abs(v[late] - 0.01)) < 5e-4
    assert np.max(np.abs(w[late] - 20.0)) < 1.0
    assert np.max(np.abs(plan.inputs[:, 1])) < 60e3          # inside the torque limit


@pytest.mark.slow
def test_sil_ch6_scenario_with_planned_weights_settles_the_hybrid_by_5_s(tmp_path):
    """examples/sil_dhp_hybrid68.toml (weights = "planned"): the runtime, unpaced, drives the
    68-state hybrid (delayed depth of cut) into the 5% band of the step by 5 s."""
    from downhole.cli import main
    from downhole.sim.result import load_result

    out = tmp_path / "run.nc"
    assert main(["sil", "examples/sil_dhp_hybrid68.toml", "--duration", "7", "--unpaced",
                 "--out", str(out)]) == 0
    res = load_result(out)
    late = res.time >= 5.0
    assert np.max(np.abs(res["bit_axial_velocity"][late] - 0.01)) < 5e-4
    assert np.max(np.abs(res["bit_angular_velocity"][late] - 20.0)) < 1.0
