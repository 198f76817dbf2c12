"""The closed loop through the FMU (downhole.sil.fmu.run_fmu_closed_loop): any controller of the
Controller contract drives an exported plant through FMPy's low-level API and gets the offline
loop's trajectory; every fidelity of a system scenario can be exported; bad input is named."""

import zipfile

import numpy as np
import pytest

from downhole.cli import main
from downhole.control.base import run_closed_loop
from downhole.errors import DownholeInputError
from downhole.sil.controllers import SurfacePI
from downhole.sil.fmu import export_fmu, fmu_signals, run_fmu_closed_loop
from downhole.string.fem import DirectionalPlant
from downhole.string.lumped import lumped_model

REF = {"reference_axial_velocity": 0.005, "reference_angular_velocity": 10.0}


#: The plant of _lumped() as a scenario (an FMU carries a scenario, not a plant object): the
#: Table 2.1 4th-order chain, Newmark at 0.5 ms, inputs starting at rest.
LUMPED = """
[model]
fidelity = "lumped4"
preset = "table_2_1"

[operation]
rop = "0 m/s"
surface_speed = "0 rad/s"

[simulation]
duration = "10 s"
dt = "0.5 ms"
integrator = "newmark"
"""


def _lumped():
    return DirectionalPlant(lumped_model("table_2_1", order=4), dt=5e-4, integrator="newmark")


def _scenario(folder, text=LUMPED, name="lumped.toml", **replace):
    for old, new in replace.items():
        assert old in text
        text = text.replace(old, new)
    path = folder / name
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def lumped_fmu(tmp_path_factory):
    folder = tmp_path_factory.mktemp("fmu")
    return export_fmu(_scenario(folder), folder / "lumped.fmu")


class Echo:
    """Sets the top-drive speed to the angular reference and records what it saw."""

    needs = ("bit_angular_velocity",)
    commands = ("top_drive_angular_velocity",)
    dt = None

    def __init__(self):
        self.seen = []
        self.resets = 0

    def reset(self):
        self.resets += 1
        self.seen.clear()

    def command(self, t, observation, reference=None):
        self.seen.append((t, observation["time"]))
        return {"top_drive_angular_velocity": reference["reference_angular_velocity"]}


class Needs:
    def __init__(self, needs=(), commands=(), out=None):
        self.needs, self.commands, self.out = needs, commands, out or {}

    def reset(self):
        pass

    def command(self, t, observation, reference=None):
        return dict(self.out)


def test_fmu_declares_the_plant_signals(lumped_fmu):
    plant = _lumped()
    sig = fmu_signals(lumped_fmu)
    assert sig["commands"] == plant.default_command()
    # the plant's "time" is the FMU output "sim_time" (no FMU variable is named time)
    assert sig["observations"] == ["sim_time" if n == "time" else n
                                   for n in plant.observation_names]
    assert sig["step_size"] == plant.dt
    with zipfile.ZipFile(lumped_fmu) as z:
        xml = z.read("modelDescription.xml").decode()
    assert 'name="command_top_drive_angular_velocity"' in xml and 'causality="input"' in xml
    assert 'name="bit_angular_velocity"' in xml and "<CoSimulation" in xml


def test_pi_through_the_fmu_is_the_offline_loop(lumped_fmu):
    """Same controller class, same plant: the FMU loop reproduces run_closed_loop exactly."""
    plant = _lumped()
    off = run_closed_loop(plant, SurfacePI(plant.command_names, dt=plant.dt), 0.5, reference=REF)
    res = run_fmu_closed_loop(lumped_fmu, SurfacePI(plant.command_names, dt=1.0), 0.5,
                              reference=REF)
    assert res.attrs["runner"] == "fmu" and res.attrs["dt"] == plant.dt
    assert res.time.size == off["time"].size == 1001
    np.testing.assert_allclose(res.time, off["time"], rtol=0, atol=1e-12)
    for ch in ("bit_angular_velocity", "bit_axial_velocity", "tob", "surface_torque"):
        np.testing.assert_allclose(res[ch], off[ch], rtol=1e-12, atol=1e-12, err_msg=ch)
    for c in plant.command_names:
        np.testing.assert_allclose(res[f"command_{c}"], off[f"command:{c}"], rtol=1e-12,
                                   atol=1e-12)
    # the runner set the PI's step to the communication step (dt=1.0 given above): its first
    # command is w_ref + kp e + ki dt e with e = 10 rad/s (bit at rest)
    assert res["command_top_drive_angular_velocity"][0] == pytest.approx(
        10.0 + 0.3 * 10.0 + 0.2 * plant.dt * 10.0, rel=1e-12)
    assert res["bit_angular_velocity"][-1] > 0.1  # the loop acts: the bit starts turning


def test_reference_time_and_the_untouched_command(lumped_fmu):
    """A callable reference reaches the controller at the communication points; the command the
    controller does not set keeps the FMU's start value; reset is called once per run."""
    ctrl = Echo()
    res = run_fmu_closed_loop(lumped_fmu, ctrl, 0.01, dt=1e-3,
                              reference=lambda t: {"reference_angular_velocity": 1000.0 * t})
    assert ctrl.resets == 1
    t = np.array([s[0] for s in ctrl.seen])
    np.testing.assert_allclose(t, np.arange(11) * 1e-3, atol=1e-15)
    # the plant's own clock (an FMU output): two plant steps of 0.5 ms per communication step
    np.testing.assert_allclose([s[1] for s in ctrl.seen], t, atol=1e-12)
    np.testing.assert_allclose(res["command_top_drive_angular_velocity"], 1000.0 * t)
    assert np.all(res["command_top_drive_axial_velocity"] == 0.0)
    # the top of a velocity-driven chain follows the held command one step later
    np.testing.assert_allclose(res["top_drive_angular_velocity"][1:], 1000.0 * t[:-1],
                               atol=1e-9)


def test_record_every_keeps_the_last_step(lumped_fmu):
    plant = _lumped()
    full = run_fmu_closed_loop(lumped_fmu, SurfacePI(plant.command_names, dt=plant.dt), 0.05,
                               reference=REF)
    some = run_fmu_closed_loop(lumped_fmu, SurfacePI(plant.command_names, dt=plant.dt), 0.05,
                               reference=REF, record_every=30)
    assert list(np.round(some.time / plant.dt)) == [0, 30, 60, 90, 100]
    np.testing.assert_allclose(some["bit_angular_velocity"],
                               full["bit_angular_velocity"][[0, 30, 60, 90, 100]])


def test_missing_signals_are_named(lumped_fmu):
    with pytest.raises(DownholeInputError, match=r"needs \['x_1'\].*does not output"):
        run_fmu_closed_loop(lumped_fmu, Needs(needs=("bit_angular_velocity", "x_1")), 0.01)
    with pytest.raises(DownholeInputError, match=r"sets \['surface_torque'\].*takes"):
        run_fmu_closed_loop(lumped_fmu, Needs(commands=("surface_torque",)), 0.01)
    # a controller that declares nothing is caught at its first command
    with pytest.raises(DownholeInputError, match=r"at t = 0 s sets \['surface_torque'\]"):
        run_fmu_closed_loop(lumped_fmu, Needs(out={"surface_torque": 1.0}), 0.01)


def test_bad_commands_are_named_and_never_applied(lumped_fmu):
    for value, why in ((float("nan"), "not a finite number"), (1e6, "outside the admissible")):
        ctrl = Needs(out={"top_drive_angular_velocity": value})
        with pytest.raises(DownholeInputError, match=f"top_drive_angular_velocity.*{why}"):
            run_fmu_closed_loop(lumped_fmu, ctrl, 0.01)


def test_a_step_the_fmu_rejects_says_why(lumped_fmu):
    """A communication step that is not a multiple of the plant's dt: the FMU's own log line
    comes back in the error."""
    with pytest.raises(DownholeInputError, match="rejected the step at t = 0 s.*whole multiple"):
        run_fmu_closed_loop(lumped_fmu, Needs(), 0.01, dt=7e-4)


@pytest.mark.parametrize("kw, match", [
    ({"duration": 0.0}, "duration must be a positive"),
    ({"duration": float("nan")}, "duration must be a positive"),
    ({"duration": 0.01, "dt": -1e-3}, "dt must be a positive"),
    ({"duration": 1e-4}, "exceeds the duration"),
    ({"duration": 0.01, "record_every": 0}, "record_every"),
])
def test_bad_run_settings(lumped_fmu, kw, match):
    with pytest.raises(DownholeInputError, match=match):
        run_fmu_closed_loop(lumped_fmu, Needs(), **kw)


def test_not_an_fmu(tmp_path):
    with pytest.raises(DownholeInputError, match="no such FMU file"):
        run_fmu_closed_loop(tmp_path / "none.fmu", Needs(), 0.1)
    text = tmp_path / "text.fmu"
    text.write_text("not a zip")
    with pytest.raises(DownholeInputError, match="not a readable FMU"):
        run_fmu_closed_loop(text, Needs(), 0.1)
    empty = tmp_path / "empty.fmu"
    with zipfile.ZipFile(empty, "w") as z:
        z.writestr("readme.txt", "no model description")
    with pytest.raises(DownholeInputError, match="not a readable FMU"):
        run_fmu_closed_loop(empty, Needs(), 0.1)


def test_export_fmu_rejects_bad_input(tmp_path):
    from downhole.errors import ScenarioError

    good = _scenario(tmp_path)
    with pytest.raises(DownholeInputError, match="must end in .fmu"):
        export_fmu(good, tmp_path / "x.zip")
    with pytest.raises(ScenarioError, match="simulation.start"):
        export_fmu(_scenario(tmp_path, name="f.toml", **{'integrator = "newmark"':
                                                         'start = "flying"'}),
                   tmp_path / "x.fmu")
    profile = _scenario(tmp_path, name="p.toml", **{'rop = "0 m/s"': 'rop = [[0, 0], [1, 0.01]]'})
    with pytest.raises(ScenarioError, match=r"p.toml: operation.rop: a time profile cannot be "
                                            r"exported"):
        export_fmu(profile, tmp_path / "x.fmu")
    with pytest.raises(ScenarioError, match="admissible range"):
        export_fmu(_scenario(tmp_path, name="s.toml", **{'"0 rad/s"': '"1e6 rad/s"'}),
                   tmp_path / "x.fmu")
    assert not (tmp_path / "x.fmu").exists()


def test_steady_start_and_command_start(tmp_path):
    """start = 'steady' at the set-point: the first observation is the steady drilling state
    (bit at the set-point speed), the inputs start at the set-point."""
    sp = {"top_drive_axial_velocity": 0.01, "top_drive_angular_velocity": 12.0}
    fmu = export_fmu(_scenario(tmp_path, **{'"0 m/s"': '"10 mm/s"', '"0 rad/s"': '"12 rad/s"',
                                            'integrator = "newmark"':
                                            'integrator = "newmark"\nstart = "steady"'}),
                     tmp_path / "steady.fmu")
    assert fmu_signals(fmu)["commands"] == sp
    res = run_fmu_closed_loop(fmu, Needs(), 0.1)
    w = res["bit_angular_velocity"]
    assert w[0] == pytest.approx(12.0, rel=1e-6)
    assert np.max(np.abs(w - 12.0)) < 0.05 * 12.0  # it stays there with the held set-point
    plant = _lumped()
    first = plant.reset(start="steady", set_point=sp)
    assert res["wob"][0] == pytest.approx(first["wob"], rel=1e-9)


@pytest.mark.parametrize("fid", [
    "neutral", "fem",
    # the lumped chains derive from a 400-element reference FEM; the hybrid compiles its kernel
    pytest.param("lumped4", marks=pytest.mark.slow),
    pytest.param("lumped12", marks=pytest.mark.slow),
    pytest.param("hybrid", marks=pytest.mark.slow)])
def test_export_fmu_cli_system_scenario_fidelity(tmp_path, fid):
    """``downhole export-fmu SYSTEM.toml --fidelity NAME``: the same inputs at every fidelity,
    the scenario's set-points as start values, the fidelity's default step."""
    from downhole.scenario.system import DEFAULT_DT

    out = tmp_path / f"{fid}.fmu"
    assert main(["export-fmu", "examples/table_5_1.toml", "--fidelity", fid,
                 "--out", str(out)]) == 0
    sig = fmu_signals(out)
    assert set(sig["commands"]) == {"top_drive_axial_velocity",
                                    "top_drive_angular_velocity"}
    # the same rig and commands at every fidelity (the neutral line runs under the rig's node):
    # the PI's set-point and the block velocity of the steady state
    assert sig["commands"]["top_drive_angular_velocity"] == 10.0
    assert 0 < sig["commands"]["top_drive_axial_velocity"] < 0.1  # the ROP at 120 kN
    assert sig["step_size"] == DEFAULT_DT[fid]
    assert {"bit_angular_velocity", "wob", "tob", "surface_torque"} <= set(
        sig["observations"])
    res = run_fmu_closed_loop(out, Needs(), 20 * sig["step_size"])  # open loop: start values
    assert res.time.size == 21 and np.all(np.isfinite(res["bit_axial_position"]))
    assert np.all(res["command_top_drive_angular_velocity"]
                  == sig["commands"]["top_drive_angular_velocity"])


def test_export_fmu_cli_refuses(tmp_path, capsys):
    out = tmp_path / "x.fmu"
    assert main(["export-fmu", "examples/sil_pi_hybrid68.toml", "--fidelity", "fem",
                 "--out", str(out)]) == 2
    assert "--fidelity applies to a scenario that describes the system" in \
        capsys.readouterr().err
    assert main(["export-fmu", "examples/table_5_1.toml", "--fidelity", "lumped7",
                 "--out", str(out)]) == 2
    assert "--fidelity" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.slow
def test_dhp_drives_the_fmu_of_the_state_plant(tmp_path):
    """The trained DHP (24-state design model, ch. 6 set-up) drives the FMU of the SIL scenario's
    68-state hybrid with the DHP interface (states x_1, ... as outputs; slack-off force and
    surface torque as inputs) and gets the in-process SIL loop's trajectory."""
    from downhole.sil import RealTimeRunner
    from downhole.sil.plants import build_plant
    from downhole.sil.testing import ch6_dhp

    design, ctrl = ch6_dhp("step", horizon=2.0, samples=50)
    plant = build_plant("hybrid68", interface="state", design_model=design)
    fmu = export_fmu("examples/sil_dhp_hybrid68.toml", tmp_path / "dhp_plant.fmu")
    sig = fmu_signals(fmu)
    assert set(sig["commands"]) == {"slack_off_force", "surface_torque"}
    assert set(design.state_names) <= set(sig["observations"])
    assert sig["step_size"] == 1e-3
    res = run_fmu_closed_loop(fmu, ctrl, 2.0, record_every=10)
    ref = RealTimeRunner(plant, ctrl, paced=False, record_every=10).run(2.0)
    assert res.time.size == ref.time.size
    for ch in ("bit_axial_velocity", "bit_angular_velocity", "wob"):
        np.testing.assert_allclose(res[ch], ref[ch], rtol=1e-9, atol=1e-9, err_msg=ch)
    assert res["bit_angular_velocity"][-1] > 5.0  # the step reference is being tracked


def test_a_huge_step_is_refused_at_once_not_run_for_hours(lumped_fmu):
    """A 1 h communication step (7.2e6 plant steps of 0.5 ms) is an FMI error naming the limit,
    returned before any plant step is taken (the run would otherwise take hours)."""
    from downhole.sil.fmu import MAX_STEPS_PER_DO_STEP

    limit = min(60.0, MAX_STEPS_PER_DO_STEP * 5e-4)
    with pytest.raises(DownholeInputError,
                       match=rf"rejected the step at t = 0 s.*doStep refused: a communication "
                             rf"step of 3600 s exceeds the limit of {limit:g} s per doStep"):
        run_fmu_closed_loop(lumped_fmu, Needs(), 7200.0, dt=3600.0)
