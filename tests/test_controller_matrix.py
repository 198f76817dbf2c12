"""Controller x fidelity x runner: every controller runs unchanged on every plant of one
description whose signals it needs, and the runners agree.

- controllers: the surface PI (``SurfacePI``), Z-torque (``ZTorque``) and EID;
- fidelities: ``lumped4``, ``lumped12``, ``neutral``, ``fem``, ``hybrid`` of one
  :class:`~downhole.system.DrillingSystem` (Table 5.1, no friction), all velocity-driven (top-drive
  axial and angular velocity commands);
- runners: ``offline`` (:func:`~downhole.control.base.run_closed_loop`), ``sil`` (the real-time
  SIL loop in process, unpaced), ``udp`` (the SIL loop with the controller behind the UDP link)
  and ``fmu`` (the plant exported with :func:`~downhole.sil.fmu.export_fmu` from
  ``examples/table_5_1.toml`` at each fidelity, once per module, driven through FMPy's
  low-level API by :func:`~downhole.sil.fmu.run_fmu_closed_loop`); every runner steps the plant
  that scenario describes (:func:`~downhole.sil.fmu.scenario_plant`), holding the scenario's
  set-points until the controller sets a command.

Each cell checks the pair, runs every runner and requires the bit speed of ``sil``, ``udp`` and
``fmu`` to equal the offline one (``rtol = atol = 1e-6``; they are the same loop, bit for bit in
practice). All 15 controller x fidelity cells work in all four runners; the cells that cannot
work (DHP and the DP replay off their own plants) say why in ``REASONS``."""

import dataclasses
import threading

import numpy as np
import pytest

from downhole.control.base import check_pair, run_closed_loop
from downhole.control.ztorque import ZTorque, torsional_impedance
from downhole.sil import RealTimeRunner
from downhole.sil.controllers import SurfacePI
from downhole.sil.link import ControllerClient
from downhole.sil.plants import SilPlant
from downhole.sil.testing import free_port
from downhole.string.fem import DirectionalPlant
from downhole.system import FIDELITIES, DrillingSystem

DURATION = 0.3  # s simulated per cell
RUNNERS = ("offline", "sil", "udp", "fmu")
CONTROLLERS = ("pi", "ztorque", "softspeed", "eid")

#: Cells that cannot work, and why (the test checks that check_pair or the plant says so too,
#: where the reason is a missing signal).
REASONS = {
    "dhp": "DHP is trained on the 24-state FEM's own states: it needs the 'state' observation of "
           "a DirectionalStatePlant (torque-driven top drive, slack-off hook); it runs there in "
           "the SIL loop, in process and over UDP (tests/test_sil_runtime.py, test_dhp_plan.py)",
    "dp": "the DP solution is an open-loop schedule of top velocities optimized on the "
          "4th-order model's states; its replay runs on the lumped plant it was optimized for "
          "(tests/test_dp.py), not as feedback on other fidelities",
    "dhp_fmu": "the DHP needs the 24-state design model's states, which only the FMU of the "
               "SIL scenario's interface = 'state' plant outputs (x_1, ...; inputs slack-off "
               "force and surface torque): tests/test_fmu_closed_loop.py drives that FMU with "
               "the trained DHP and matches the in-process SIL loop (slow: the DHP design)",
    "dp_fmu": "the DP replay is open loop: the top motion (path inversion of the optimal path, "
              "SurfaceInputs.displacement) for the 4th-order model it was optimized on; against "
              "an FMU it is an input table for the importing tool, not a feedback loop for "
              "run_fmu_closed_loop",
}


@pytest.fixture(scope="module")
def system():
    return DrillingSystem.table_5_1(friction=0.0)


@pytest.fixture(scope="module")
def scenarios(tmp_path_factory):
    """The scenario of each fidelity: ``examples/table_5_1.toml`` (Table 5.1, no friction), the
    neutral model at 1 ms."""
    from pathlib import Path

    folder = tmp_path_factory.mktemp("scenarios")
    text = Path("examples/table_5_1.toml").read_text()
    out = {}
    for fid in FIDELITIES:
        path = folder / f"{fid}.toml"
        path.write_text(text.replace('record_dt = "10 ms"', 'record_dt = "10 ms"\ndt = "1 ms"')
                        if fid == "neutral" else text)
        out[fid] = path
    return out


@pytest.fixture(scope="module")
def fmus(tmp_path_factory, scenarios):
    """``fmu_for(fidelity)``: the FMU of each fidelity, exported once per module."""
    from downhole.sil.fmu import export_fmu

    folder = tmp_path_factory.mktemp("fmus")
    built = {}

    def fmu_for(fidelity):
        if fidelity not in built:
            built[fidelity] = export_fmu(scenarios[fidelity], folder / f"{fidelity}.fmu",
                                         fidelity=fidelity)
        return built[fidelity]

    return fmu_for


@pytest.fixture(scope="module")
def eid_design(system):
    from downhole.control.eid import design_eid

    return design_eid(system.build("neutral"))


def _plant(scenarios, fidelity):
    """The plant the FMU of ``fidelity`` runs, holding the FMU inputs' start values (the
    scenario's set-points) as its default command, as the FMU does."""
    from downhole.sil.fmu import scenario_plant

    plant, settings = scenario_plant(scenarios[fidelity], fidelity)
    start = dict(settings["command_start"])
    plant.default_command = lambda: dict(start)
    return plant


def _controller(name, plant, system, eid_design):
    if name == "pi":
        return SurfacePI(plant.command_names, dt=plant.dt)
    if name == "ztorque":
        return ZTorque(torsional_impedance(system.string.segments[0].section), speed=10.0,
                       dt=plant.dt)
    if name == "softspeed":  # the soft-torque drive, tuned (SPE-119660) from the description
        from downhole.control import SoftSpeed

        return SoftSpeed(system, speed=10.0, dt=plant.dt)
    # the drive's limits: a block velocity within +/- 0.5 m/s of the hanging command, 0-40 rad/s
    off = eid_design.model_coeffs[0]["offset"]
    ctrl = dataclasses.replace(eid_design, u_limits=((off - 0.5, off + 0.5), (0.0, 40.0)))
    ctrl.dt = plant.dt
    return ctrl


REF = {"reference_axial_velocity": 0.005, "reference_angular_velocity": 10.0}


def _run(runner, plant, ctrl, fmu=None):
    if runner == "offline":
        r = run_closed_loop(plant, ctrl, DURATION, reference=REF)
        return r["bit_angular_velocity"], r["command:top_drive_angular_velocity"]
    if runner == "fmu":
        from downhole.sil.fmu import run_fmu_closed_loop

        r = run_fmu_closed_loop(fmu, ctrl, DURATION, reference=REF)
        assert r.attrs["dt"] == plant.dt  # the FMU's default step is the plant's
        return r["bit_angular_velocity"], r["command_top_drive_angular_velocity"]
    sil = SilPlant(plant, plant.command_names, plant.default_command(),
                   {n: 0.0 for n in plant.command_names})
    ref = {"axial": REF["reference_axial_velocity"], "angular": REF["reference_angular_velocity"]}
    if runner == "sil":
        rt = RealTimeRunner(sil, ctrl, reference=ref, paced=False, record_every=1)
        res = rt.run(DURATION)
        rt.close()
    else:
        port = free_port()
        rt = RealTimeRunner(sil, link=("127.0.0.1", port), reference=ref, paced=False,
                            record_every=1, command_timeout=5.0)
        client = ControllerClient("127.0.0.1", port)
        th = threading.Thread(target=lambda: (client.connect(10.0),
                                              client.serve(ctrl, idle_timeout=3.0,
                                                           hold=plant.default_command())),
                              daemon=True)
        th.start()
        assert rt.wait_for_controller(20.0)
        res = rt.run(DURATION)
        rt.close()
        th.join(10)
        client.sock.close()
        assert rt.stats["safe_actions"] == 0
    return res["bit_angular_velocity"], res["command_top_drive_angular_velocity"]


@pytest.mark.parametrize("fidelity", FIDELITIES)
@pytest.mark.parametrize("controller", CONTROLLERS)
def test_controller_runs_at_every_fidelity_in_every_runner(system, eid_design, scenarios, fmus,
                                                           controller, fidelity):
    out = {}
    for runner in RUNNERS:
        plant = _plant(scenarios, fidelity)
        ctrl = _controller(controller, plant, system, eid_design)
        assert check_pair(ctrl, plant) is None
        w, cmd = _run(runner, plant, ctrl, fmus(fidelity) if runner == "fmu" else None)
        assert np.all(np.isfinite(w)) and np.all(np.isfinite(cmd))
        assert np.all(np.abs(cmd) <= 100.0)
        out[runner] = (np.asarray(w), np.asarray(cmd))
    # the runners are the same loop: same plant, same controller, same commands
    n = min(len(v[0]) for v in out.values())
    for runner in ("sil", "udp", "fmu"):
        assert np.allclose(out[runner][0][:n], out["offline"][0][:n], rtol=1e-6, atol=1e-6), \
            runner


def test_cells_that_cannot_work_say_why(system):
    plant = DirectionalPlant(system.build("lumped4"), mode="force")
    why = check_pair(ZTorque(480.0), plant)
    assert "takes" in why  # a force-driven top: no speed command to set
    for key in ("dhp", "dp", "dhp_fmu", "dp_fmu"):
        assert len(REASONS[key]) > 40
