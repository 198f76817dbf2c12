"""DHP controller tests: references, save/load, past-horizon policy, closed loops, integral
action."""

import math

import numpy as np
import pytest

from downhole.control.dhp import (
    BitReference,
    DHPSettings,
    PenaltyWeights,
    design_dhp,
    load_controller,
    lumped_affine_model,
    lumped_true_plant,
    run_design_model,
    run_on_plant,
)
from downhole.errors import DownholeInputError
from downhole.sim.result import REQUIRED_CHANNELS

#: weights that suit the 4-state lumped model (Table 2.1's slow string driven by top displacements)
LUMPED = PenaltyWeights(bit_velocity=(1000.0, 1000.0), bit_position=(1.0, 1.0), r=(1.0, 0.1))


@pytest.fixture(scope="module")
def model():
    return lumped_affine_model("table_2_1", dt=1e-3)


@pytest.fixture(scope="module")
def ctrl(model):
    return design_dhp(model, BitReference.step(0.01, 20.0), horizon=8.0, weights=LUMPED)


def test_ramp_and_sine_references_follow_the_seed_equations():
    r = BitReference.ramp(t_final=40.0)
    v, w = r.velocities(np.array([0.0, 9.9, 15.0, 20.0, 25.0, 35.0, 39.99, 45.0]))
    np.testing.assert_allclose(v * 1e3, [10, 10, 15, 20, 20, 15, 10.01, 10], atol=1e-3)
    np.testing.assert_allclose(w, [20, 20, 30, 40, 40, 30, 20.02, 20], atol=2e-3)
    s = BitReference.sine()
    t = np.array([0.0, 5.0, 15.0])
    v, w = s.velocities(t)
    np.testing.assert_allclose(v * 1e3, 20 + 10 * np.sin(0.1 * math.pi * t))
    np.testing.assert_allclose(w, 40 + 20 * np.sin(0.1 * math.pi * t))
    # exact integral of the sine against the trapezoid rule
    _, _, x, a = s.sample(20000, 1e-3)
    vv, ww = s.velocities(np.arange(20001) * 1e-3)
    np.testing.assert_allclose(x[-1], np.trapezoid(vv, dx=1e-3), rtol=1e-8)
    np.testing.assert_allclose(a[-1], np.trapezoid(ww, dx=1e-3), rtol=1e-8)
    with pytest.raises(DownholeInputError, match="kind must be one of"):
        BitReference(kind="square")


def test_step_reached_on_design_model(model, ctrl):
    res = run_design_model(ctrl, model, 8.0)
    for ch in REQUIRED_CHANNELS + ("reference_axial_velocity", "reference_angular_velocity"):
        assert ch in res
    t = res.time
    late = t >= 5.0
    assert np.all(np.abs(res["bit_axial_velocity"][late] - 0.01) <= 0.05 * 0.01)
    assert np.all(np.abs(res["bit_angular_velocity"][late] - 20.0) <= 0.05 * 20.0)
    assert res.summary((5.0, 8.0))["stuck_fraction"] == 0.0


def test_save_load_round_trip_gives_identical_commands(tmp_path, model, ctrl):
    npz, js = ctrl.save(tmp_path / "ctl")
    assert npz.exists() and js.exists()
    back = load_controller(tmp_path / "ctl.npz")
    z = np.array([0.01, 0.005, 3.0, 12.0])
    for k in (0, 1234, 7999, 9000):
        np.testing.assert_array_equal(back.control(k, z) if k < ctrl.n_steps else
                                      back.control(k, z).shape, ctrl.control(k, z)
                                      if k < ctrl.n_steps else (2,))
    obs = dict(zip(ctrl.state_names, z))
    assert back.command(0.5, obs) == ctrl.command(0.5, obs)
    with pytest.raises(DownholeInputError, match="observation lacks state 'bit_axial_velocity'"):
        ctrl.command(0.0, {"bit_axial_position": 0.0})
    (tmp_path / "bad.json").write_text('{"format": "other"}')
    np.savez(tmp_path / "bad.npz", x=np.zeros(1))
    with pytest.raises(DownholeInputError, match="is not a downhole DHP controller"):
        load_controller(tmp_path / "bad")
    # a missing folder is created (as docs/dhp.md's ctrl.save("out/dhp_step") needs); a file
    # in the way is refused by name
    npz, _ = ctrl.save(tmp_path / "new" / "deeper" / "ctl")
    assert npz == tmp_path / "new" / "deeper" / "ctl.npz" and npz.exists()
    (tmp_path / "afile").write_text("x")
    with pytest.raises(DownholeInputError, match="afile: it is a file, not a folder"):
        ctrl.save(tmp_path / "afile" / "ctl")


def test_past_horizon_policies(model, ctrl):
    # stationary: the loop keeps tracking to twice the trained horizon
    res = run_design_model(ctrl, model, 16.0, record_every=10)
    late = res.time >= 10.0
    assert np.max(np.abs(res["bit_axial_velocity"][late] - 0.01)) < 0.02 * 0.01
    assert np.max(np.abs(res["bit_angular_velocity"][late] - 20.0)) < 0.02 * 20.0
    strict = design_dhp(model, BitReference.step(), horizon=0.2, past_horizon="error")
    with pytest.raises(DownholeInputError, match="past the trained horizon 0.2 s"):
        strict.control(200, np.zeros(4))


@pytest.mark.slow
def test_true_delayed_plant_lumped(ctrl):
    plant, adapter = lumped_true_plant("table_2_1", dt=1e-3, depth_of_cut="delayed")
    res = run_on_plant(ctrl, plant, 8.0, adapter=adapter, record_every=5)
    s = res.summary((5.0, 8.0))
    assert s["stuck_fraction"] == 0.0
    assert abs(s["mean_rop"] - 0.01) < 0.05 * 0.01
    assert abs(s["mean_bit_angular_velocity"] - 20.0) < 0.05 * 20.0


def test_integral_action_removes_most_of_the_rop_offset_when_epsilon_triples():
    """Beyond the seed: integrator states (augmented model, anti-windup in the controller)
    bring the ROP back to the reference when the rock is 3x harder than designed for."""
    import dataclasses

    from downhole.control.dhp.directional import directional_affine_model, table_5_1_models
    from downhole.control.dhp.drilling import INTEGRAL_STATE_NAMES

    fem24, _ = table_5_1_models()
    design = directional_affine_model(fem24)
    hard = directional_affine_model(dataclasses.replace(
        fem24, bit=fem24.bit.model_copy(update={"epsilon": fem24.bit.epsilon * 3})))
    offsets = {}
    for qi in (0.0, 300.0):
        w = PenaltyWeights(bit_velocity=(100.0, 100.0), bit_position=(0.1, 0.1), r=(1.0, 1.0),
                           integral=(qi, qi))
        ctrl = design_dhp(design, BitReference.step(0.01, 20.0), horizon=14.0, weights=w,
                          settings=DHPSettings(n_samples=60))
        assert (ctrl.n_states == design.n_states + 2) == (qi > 0)
        if qi > 0:
            assert ctrl.state_names[-2:] == INTEGRAL_STATE_NAMES
        nominal = run_design_model(ctrl, design, 10.0).summary((7.0, 10.0))
        assert abs(nominal["mean_rop"] - 0.01) < 0.03 * 0.01
        s = run_design_model(ctrl, hard, 10.0).summary((7.0, 10.0))
        assert s["stuck_fraction"] == 0.0
        offsets[qi] = abs(s["mean_rop"] - 0.01)
    assert offsets[0.0] > 0.5 * 0.01                 # no integral action: > 50% off
    assert offsets[300.0] < 0.25 * offsets[0.0]
