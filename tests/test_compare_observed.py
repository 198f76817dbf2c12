"""DHP and EID on the benchmark's rig (:mod:`downhole.compare.observed`).

The actuator adapters are checked against independent physics: a torque step through
:class:`RigActuators` drives the top drive as a torque source on the pipe's torsional
impedance (the semi-infinite line answer, before the first reflection returns), and
:class:`VelocityServo` on a force-driven hook reproduces the plant's own block-velocity servo.
DHP (built-in, and trained, saved and loaded from a file) runs from the surface observer and
holds a smooth point; the n/a cells left say why.
"""

import dataclasses
import math

import numpy as np
import pytest

from downhole.compare import BUILTIN, SUITES, NotApplicable, compare_controllers
from downhole.compare.observed import (
    BUILTIN_DHP_HORIZON,
    BUILTIN_DHP_SAMPLES,
    RigActuators,
    VelocityServo,
    design_fem,
)
from downhole.compare.runner import case_plant
from downhole.control.base import run_closed_loop

STANDARD = {c.id: c for c in SUITES["standard"]}


class _Const:
    """Sets fixed values (or ``f(t)``) of the named commands."""

    def __init__(self, values):
        self.values = values
        self.commands = tuple(values)
        self.needs = ()

    def reset(self):
        pass

    def command(self, t, observation, reference=None):
        return {k: float(v(t) if callable(v) else v) for k, v in self.values.items()}


def _steady(case_id, **change):
    case = dataclasses.replace(STANDARD[case_id], **change)
    system = case.drilling_system()
    return case, system, case_plant(case, system)


def test_rig_actuators_apply_the_torque_asked_for():
    """From the steady state at 15 rad/s, a surface-torque step of dT through the rig's speed
    PI: the top drive on the pipe (impedance Z) answers omega = dT / Z (1 - exp(-Z t / J))
    until the first reflection returns from the collars (2 L / c = 1.6 s); the slack-off force
    is the hook load's complement exactly."""
    case, system, plant = _steady("ch2-smooth-steady")
    weight = system.build("fem", n_elements=case.n_elements).buoyed_weight
    t0 = plant.reset(start="steady", set_point={"top_drive_angular_velocity": case.speed})
    torque0 = t0["surface_torque"]
    dT, t_step = 1000.0, 0.1
    inner = _Const({"slack_off_force": case.wob,
                    "surface_torque": lambda t: torque0 + (dT if t >= t_step else 0.0)})
    td = system.rig.top_drive
    ctrl = RigActuators(inner, weight=weight, kp=td.kp, ki=td.ki, speed=case.speed,
                        dt=case.dt)
    out = run_closed_loop(plant, ctrl, 1.0, start="steady",
                          set_point={"top_drive_angular_velocity": case.speed})
    assert np.allclose(out["command:hook_load"], weight - case.wob, rtol=0, atol=1e-6)
    t = out["time"]
    w = out["top_drive_angular_velocity"]
    assert abs(w[t < t_step] - case.speed).max() < 1e-6       # the steady state is held
    z = float(system.string.segments[0].section.torsional_impedance)
    j = td.inertia
    for tau in (0.3, 0.6, 0.9):
        k = int(round((t_step + tau) / case.dt))
        expected = dT / z * (1.0 - math.exp(-z * tau / j))
        assert w[k] - case.speed == pytest.approx(expected, rel=0.05), tau


def test_velocity_servo_reproduces_the_rigs_block_velocity_servo():
    """EID's block velocity through a force-driven hook: the software servo gives the WOB and
    the block and bit velocities of the plant's own velocity hook (same gains) within 1 %
    (RMS over a block-velocity step of +50 %)."""
    base = dataclasses.replace(SUITES["smoke"][0], noise=False, delay=0.0, start="steady",
                               pre_time=0.0, duration=2.0)
    v0 = base.reference_rop()

    def block(t):
        return v0 * (1.5 if t >= 0.2 else 1.0)

    runs = {}
    for hook in ("force", "velocity"):
        case = dataclasses.replace(base, hook=hook, rop=v0 if hook == "velocity" else None)
        system = case.drilling_system()
        plant = case_plant(case, system)
        inner = _Const({"top_drive_axial_velocity": block,
                        "top_drive_angular_velocity": case.speed})
        if hook == "force":
            hk = system.rig.hook
            weight = system.build("fem", n_elements=case.n_elements).buoyed_weight
            ctrl = VelocityServo(inner, hook_load0=weight - case.wob,
                                 stiffness=hk.servo_stiffness, damping=hk.servo_damping,
                                 dt=case.dt)
        else:
            ctrl = inner
        sp = {"top_drive_angular_velocity": case.speed}
        if hook == "velocity":
            sp["top_drive_axial_velocity"] = v0
        runs[hook] = run_closed_loop(plant, ctrl, case.duration, start="steady", set_point=sp)
    f, v = runs["force"], runs["velocity"]
    assert f["wob"][-1] > 1.05 * f["wob"][0]                  # the faster block loads the bit
    for name in ("wob", "top_drive_axial_velocity", "bit_axial_velocity"):
        scale = np.abs(v[name]).max()
        err = f[name] - v[name]
        # RMS within 1 %; the software servo lags the rig's by one step at the block's step
        assert np.sqrt(np.mean(err ** 2)) < 0.01 * scale, name
    assert np.abs(f["wob"] - v["wob"]).max() < 0.01 * np.abs(v["wob"]).max()


def test_the_na_reason_given_before_any_design():
    """EID's block-velocity servo cannot run through an actuator delay."""
    noisy = STANDARD["ch2-ss-cycle-noisy"]
    with pytest.raises(NotApplicable, match="actuator delay"):
        BUILTIN["eid"].factory(noisy.drilling_system(), noisy)


def test_dhp_built_in_and_from_a_file_score_and_hold_a_smooth_point(tmp_path):
    """The built-in DHP and the same DHP trained by a user, saved and loaded from its file,
    score on a smooth point of the Ch. 2 string from the surface observer: the same scores
    (the same controller), and the point stays smooth: severity below 0.1 and the ROP of the
    stiff PI within 2 %. A DHP trained on another string is n/a with the reason."""
    from downhole.compare import load_controller_spec
    from downhole.control.dhp import BitReference, DHPSettings, design_dhp
    from downhole.control.dhp.directional import directional_affine_model

    case = STANDARD["ch2-smooth-steady"]
    system = case.drilling_system()
    design = directional_affine_model(design_fem(system), case.dt)
    dhp = design_dhp(design, BitReference.step(case.reference_rop(), case.speed),
                     horizon=BUILTIN_DHP_HORIZON,
                     settings=DHPSettings(n_samples=BUILTIN_DHP_SAMPLES))
    dhp.save(tmp_path / "mine")
    mine = load_controller_spec(tmp_path / "mine.json")
    s = compare_controllers({"stiff-pi": "stiff-pi", "dhp": "dhp", "mine": mine},
                            suite="standard", cases=[case.id], traces=False)
    row = s["cells"][case.id]
    assert row["dhp"]["status"] == "ok" and row["mine"] == row["dhp"]
    dhp_s, pi = row["dhp"]["scores"], row["stiff-pi"]["scores"]
    assert dhp_s["stick_slip_severity"] < 0.1
    assert dhp_s["stuck_fraction"] == 0.0
    assert dhp_s["mean_rop"] == pytest.approx(pi["mean_rop"], rel=0.02)
    # DHP moves its commands (the feedback acts) where the stiff PI holds them
    assert dhp_s["effort"]["top_drive_angular_velocity"] > 0.0
    ch3 = STANDARD["ch3-wob-ss-cycle"]
    with pytest.raises(NotApplicable, match="^mine was trained on another string or mesh"):
        mine(ch3.drilling_system(), ch3)


def test_a_dhp_trained_on_the_ch4_fem24_is_rebuilt_on_the_table_5_1_cases(tmp_path):
    """A DHP trained on the Ch. 4 24-state FEM (the hybrid24 design FEM, as
    examples/dhp_step_fem24.toml trains it) runs on the Table 5.1 cases of the suite: its
    observer is rebuilt on that FEM of the case's system (the same nodes), the pair fits the
    case's plant; on another string it is n/a."""
    from downhole.compare import load_controller_spec
    from downhole.control.base import check_pair
    from downhole.control.dhp import BitReference, DHPSettings, design_dhp
    from downhole.control.dhp.directional import directional_affine_model, table_5_1_models

    fem24, _ = table_5_1_models()
    dhp = design_dhp(directional_affine_model(fem24), BitReference.step(0.01, 20.0),
                     horizon=1.0, settings=DHPSettings(method="riccati", n_samples=50))
    dhp.save(tmp_path / "fem24")
    spec = load_controller_spec(tmp_path / "fem24.json")
    case = STANDARD["t51-ss-rest"]
    system = case.drilling_system()
    ctrl = spec(system, case)
    assert list(ctrl.inner.estimator.est.kf.A.shape) == [26, 26]      # 24 states + 2 forces
    assert check_pair(ctrl, case_plant(case, system).inner) is None
    hz = STANDARD["hz-smooth-steady"]
    with pytest.raises(NotApplicable, match="^fem24 was trained on another string or mesh"):
        spec(hz.drilling_system(), hz)


@pytest.mark.slow
def test_eid_through_the_software_servo_tracks_the_rop_better_than_the_stiff_pi():
    """On the Ch. 3 WOB cycle (force hook, no delay) EID runs through VelocityServo: its axial
    tracking error is half the stiff PI's, whose hook load is held (open loop on the axial
    axis); docs/compare-controllers.md: RMS 39 against 88 mm/s."""
    s = compare_controllers(["stiff-pi", "eid"], suite="standard", cases=["ch3-wob-ss-cycle"],
                            traces=False)
    row = s["cells"]["ch3-wob-ss-cycle"]
    eid, pi = row["eid"]["scores"], row["stiff-pi"]["scores"]
    assert eid["tracking_rms_axial"] < 0.6 * pi["tracking_rms_axial"]
    assert eid["mean_rop"] > 0.5 * STANDARD["ch3-wob-ss-cycle"].reference_rop()


def test_rig_actuators_set_the_hook_load_through_a_block_velocity_servo():
    """On a velocity-driven hook the adapter sets the block velocity at which the rig's servo
    applies the hook load W - S: before a slack-off step of 20 kN the measured hook load is
    W - S within 1 % of the step; from 20 ms after it within 10 % (the adapter's damper term
    uses the top's velocity of the step before: an error c dv that rings out over a few ms),
    and within 2 % over the last half second."""
    base = dataclasses.replace(STANDARD["ch3-rop-smooth-steady-noisy"], noise=False, delay=0.0)
    system = base.drilling_system()
    plant = case_plant(base, system)
    weight = system.build("fem", n_elements=base.n_elements).buoyed_weight
    sp = {"top_drive_angular_velocity": base.speed, "top_drive_axial_velocity": base.rop}
    obs0 = plant.reset(start="steady", set_point=sp)
    s0 = weight - obs0["hook_load"]

    def slack(t):
        return s0 + (20e3 if t >= 0.1 else 0.0)

    inner = _Const({"slack_off_force": slack, "surface_torque": obs0["surface_torque"]})
    td, hk = system.rig.top_drive, system.rig.hook
    ctrl = RigActuators(inner, weight=weight, kp=td.kp, ki=td.ki, speed=base.speed, dt=base.dt,
                        hook_servo=(weight - base.wob, hk.servo_stiffness, hk.servo_damping))
    assert ctrl.commands == ("top_drive_axial_velocity", "top_drive_angular_velocity")
    out = run_closed_loop(plant, ctrl, 1.0, start="steady", set_point=sp)
    t, h = out["time"], out["hook_load"]
    want = weight - np.array([slack(x) for x in t])
    err = np.abs(h - want)[t >= 0.12]
    assert err.max() < 0.1 * 20e3
    assert err[-500:].max() < 0.02 * 20e3
    assert np.abs(h - want)[t < 0.1].max() < 0.01 * 20e3
