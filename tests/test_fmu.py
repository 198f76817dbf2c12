"""FMU export: FMPy runs the exported plant with the same results as downhole's simulation."""

import zipfile

import numpy as np
import pytest

from downhole.cli import main


def test_exported_fmu_matches_simulate(tmp_path):
    from downhole.control.topdrive import Hook, TopDrive
    from downhole.sil.fmu import simulate_fmu
    from downhole.sim import simulate
    from downhole.string.hybrid import hybrid_model

    fmu = tmp_path / "plant.fmu"
    assert main(["export-fmu", "examples/sil_pi_hybrid68.toml", "--out", str(fmu)]) == 0
    with zipfile.ZipFile(fmu) as z:
        xml = z.read("modelDescription.xml").decode()
    assert 'fmiVersion="2.0"' in xml and "<CoSimulation" in xml
    assert 'name="command_hook_load"' in xml and 'causality="input"' in xml
    assert 'name="bit_angular_velocity"' in xml
    hm = hybrid_model("hybrid68")
    res = simulate_fmu(fmu, 3.0, 0.01, {"command_top_drive_angular_velocity": 12.0,
                                       "command_hook_load": hm.buoyed_weight - 150e3})
    ref = simulate(hm, {"hook_load": lambda t: hm.buoyed_weight - 150e3 if t > 0 else 0},
                   duration=3.0, dt=1e-3, top_drive=TopDrive(speed=12.0),
                   hook=Hook(wob=120e3), record_dt=0.01)
    assert res.time.size == ref.time.size
    for ch in ("bit_axial_velocity", "bit_angular_velocity"):
        a, b = res[ch], ref[ch]
        err = np.max(np.abs(a - b)) / np.max(np.abs(b))
        print(f"\n{ch}: max relative difference FMPy vs simulate {err:.1e}")
        assert err < 1e-6
    # the input really acts: 12 rad/s set-point reached at the surface
    assert res["top_drive_angular_velocity"][-1] == pytest.approx(12.0, rel=0.2)


def test_export_fmu_rejects_a_bad_scenario(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[model]\nfidelity = 'hybrid'\npreset = 'hybrid99'\n")
    assert main(["export-fmu", str(bad), "--out", str(tmp_path / "x.fmu")]) == 2


# ------------------------------------------------------------------ the FMU carries data only
class _Hold:
    """A controller that sets nothing: the FMU's inputs keep their start values."""

    needs = ()
    commands = ()

    def reset(self):
        pass

    def command(self, t, observation, reference=None):
        return {}


def _export(tmp_path, scenario, name="plant.fmu", **kw):
    from downhole.sil.fmu import export_fmu

    return export_fmu(scenario, tmp_path / name, **kw)


def _rewrite(fmu, out, member, edit):
    """A copy of ``fmu`` with ``edit(bytes) -> bytes`` applied to ``resources/<member>``."""
    with zipfile.ZipFile(fmu) as zin, zipfile.ZipFile(out, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item.filename)
            if item.filename == f"resources/{member}":
                new = edit(data)
                assert new != data
                data = new
            zout.writestr(item, data)
    return out


def test_an_exported_fmu_carries_the_scenario_text_and_no_pickle(tmp_path):
    import json
    from pathlib import Path

    import downhole

    fmu = _export(tmp_path, "examples/nominal_table_2_1.toml")
    with zipfile.ZipFile(fmu) as z:
        names = z.namelist()
        assert not [n for n in names if n.lower().endswith((".pkl", ".pickle"))]
        # no member is a pickle stream either (protocol 2+ starts with b"\x80" and the protocol)
        assert not [n for n in names if z.read(n)[:1] == b"\x80" and z.read(n)[1:2] in
                    (b"\x02", b"\x03", b"\x04", b"\x05")]
        assert z.read("resources/scenario.toml").decode() == \
            Path("examples/nominal_table_2_1.toml").read_text()
        meta = json.loads(z.read("resources/fmu.json"))
    assert meta == {"format": 1, "fidelity": "lumped4", "options": {},
                    "downhole_version": downhole.__version__,
                    "source": "nominal_table_2_1.toml"}
    # the only Python in it: the package's slave and pythonfmu's own runtime
    py = [n for n in names if n.endswith(".py")]
    assert "resources/DownholePlant.py" in py
    assert all(n == "resources/DownholePlant.py" or n.startswith("resources/pythonfmu/")
               for n in py)
    assert not any("pickle" in n for n in names)


@pytest.mark.parametrize("scenario, duration", [
    ("examples/nominal_table_2_1.toml", 2.0),   # lumped4, explicit Euler at 0.5 ms
    ("examples/neutral_open_loop.toml", 1.0),   # neutral preset, 0.1 ms (was refused before)
])
def test_fmu_of_a_simulate_scenario_matches_simulate(tmp_path, scenario, duration):
    """FMPy steps the FMU of a ``downhole simulate`` scenario open loop (inputs at their start
    values, the scenario's set-points) and gets ``downhole.sim.simulate``'s run of the same
    scenario. Both step the same kernel configuration with the same held commands from the same
    start, so they agree to rounding (the kernel's per-step call vs its loop): 1e-9 of the
    channel's range is far below any modelling difference (a command off by the neutral model's
    hanging offset M_S g / alpha_A moves the bit speed by whole percent). Observed: identical."""
    from downhole.scenario import load_scenario
    from downhole.sil.fmu import simulate_fmu
    from downhole.sim import simulate

    data, source, _ = load_scenario(scenario)
    if data["model"]["fidelity"] == "neutral":
        from downhole.scenario.neutral import validate_neutral_scenario

        sc, model = validate_neutral_scenario(data, source)
        sim = sc.simulation
        inputs = (sc.operation.axial_command, sc.operation.surface_speed)
        kw = {}
    else:
        from downhole.scenario import validate_lumped
        from downhole.sim import SurfaceInputs

        sc, model = validate_lumped(data, source)
        sim = sc.simulation
        inputs = SurfaceInputs.velocity(sc.operation.rop, sc.operation.surface_speed)
        kw = {"integrator": sim.integrator}
    ref = simulate(model, inputs, duration=duration, dt=sim.dt, depth_of_cut=sim.depth_of_cut,
                   record_dt=0.01, start=sim.start, **kw)
    fmu = _export(tmp_path, scenario)
    res = simulate_fmu(fmu, duration, 0.01)
    assert res.time.size == ref.time.size
    np.testing.assert_allclose(res.time, ref.time, atol=1e-9)
    for ch in ("bit_angular_velocity", "bit_axial_velocity", "wob"):
        a, b = res[ch], ref[ch]
        span = np.max(np.abs(b))
        err = np.max(np.abs(a - b)) / span
        print(f"\n{scenario} {ch}: max difference FMU vs simulate {err:.1e} of {span:.4g}")
        assert err < 1e-9, ch
    assert np.ptp(ref["bit_angular_velocity"]) > 1.0  # the run is not trivially at rest


_HUGE_STEPS = r"""
import json, math, sys
from ctypes import byref
import fmpy
from fmpy.fmi2 import (FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                       fmi2CallbackFunctions, fmi2CallbackLoggerTYPE)
from fmpy.logging import addLoggerProxy
from downhole.sil.fmu import _Log

fmu = sys.argv[1]
md = fmpy.read_model_description(fmu)
unzip = fmpy.extract(fmu)
log = _Log()
callbacks = fmi2CallbackFunctions()
callbacks.logger = fmi2CallbackLoggerTYPE(log)
callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(fmpy.calloc)
callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(fmpy.free)
addLoggerProxy(byref(callbacks))
slave = FMU2Slave(guid=md.guid, unzipDirectory=unzip,
                  modelIdentifier=md.coSimulation.modelIdentifier, instanceName="huge")
slave.instantiate(callbacks=callbacks, loggingOn=True)
slave.setupExperiment(startTime=0.0)
slave.enterInitializationMode()
slave.exitInitializationMode()
out = {}
for step in (3600.0, 1e6, -1.0, math.nan, math.inf):
    try:
        slave.doStep(currentCommunicationPoint=0.0, communicationStepSize=step)
        out[repr(step)] = "accepted"
    except Exception as exc:
        out[repr(step)] = [str(exc), log.last_line()]
slave.freeInstance()
print(json.dumps(out))
"""


def test_a_huge_or_bad_step_is_refused_with_an_fmi_error_at_once(tmp_path):
    """doStep of 1 h or 1e6 s (millions of plant steps), negative or non-finite: an FMI error
    naming the reason, before any plant step. The run is a subprocess with a generous timeout:
    the guard against the hang this replaces (hours), not a timing assertion."""
    import json
    import subprocess
    import sys

    from downhole.sil.fmu import MAX_STEP_SECONDS

    fmu = _export(tmp_path, "examples/neutral_open_loop.toml")
    done = subprocess.run([sys.executable, "-c", _HUGE_STEPS, str(fmu)], capture_output=True,
                          text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    out = json.loads(done.stdout.strip().splitlines()[-1])
    limit = min(MAX_STEP_SECONDS, 100_000 * 1e-4)  # neutral_open_loop: dt = 0.1 ms
    for step in ("3600.0", "1000000.0"):
        status, said = out[step]
        assert "fmi2DoStep" in status or "error" in status.lower(), status
        assert f"exceeds the limit of {limit:g} s per doStep" in said
    for step in ("-1.0", "nan", "inf"):
        assert "not a positive finite number" in out[step][1], out[step]


def test_a_tampered_scenario_is_refused_on_instantiation(tmp_path):
    """The FMU's scenario is validated when an instance is created, as any file: an edited
    step, an unknown key or a tampered fmu.json fail the instantiation with the one-line
    validation message (through FMPy's log)."""
    from downhole.errors import DownholeInputError
    from downhole.sil.fmu import run_fmu_closed_loop

    fmu = _export(tmp_path, "examples/neutral_open_loop.toml")
    bad_dt = _rewrite(fmu, tmp_path / "dt.fmu", "scenario.toml",
                      lambda b: b.replace(b'dt = "0.1 ms"', b'dt = "-1 ms"'))
    with pytest.raises(DownholeInputError, match=r"dt.fmu failed to instantiate: .*scenario.toml: "
                                                 r"simulation.dt: .*admissible range"):
        run_fmu_closed_loop(bad_dt, _Hold(), 0.01)
    unknown = _rewrite(fmu, tmp_path / "key.fmu", "scenario.toml",
                       lambda b: b.replace(b"[operation]", b"[operation]\nexec = 'import os'"))
    with pytest.raises(DownholeInputError, match=r"failed to instantiate: .*operation.exec: "
                                                 r"unknown key"):
        run_fmu_closed_loop(unknown, _Hold(), 0.01)
    meta = _rewrite(fmu, tmp_path / "meta.fmu", "fmu.json",
                    lambda b: b.replace(b'"neutral"', b'"lumped7"'))
    with pytest.raises(DownholeInputError, match=r"failed to instantiate: .*fmu.json: fidelity "
                                                 r"'lumped7' is not one of"):
        run_fmu_closed_loop(meta, _Hold(), 0.01)
    newer = _rewrite(fmu, tmp_path / "newer.fmu", "fmu.json",
                     lambda b: b.replace(b'"downhole_version": "', b'"downhole_version": "99.'))
    with pytest.raises(DownholeInputError, match=r"exported by downhole 99\..*install downhole"):
        run_fmu_closed_loop(newer, _Hold(), 0.01)


def _examples():
    import glob

    return sorted(glob.glob("examples/*.toml"))


@pytest.mark.parametrize("scenario", _examples())
def test_every_example_exports_or_says_why_in_one_line(scenario):
    """Every example that ``downhole simulate`` or ``downhole sil`` runs gives the FMU's plant
    at its own fidelity, or one line naming the file and what the FMU plant does not support."""
    from downhole.errors import ScenarioError
    from downhole.sil.fmu import scenario_plant

    try:
        plant, settings = scenario_plant(scenario)
    except ScenarioError as exc:
        msg = str(exc)
        assert msg.startswith(scenario + ": ") and "\n" not in msg, msg
        return
    assert plant.dt > 0 and settings["stop_time"] > 0
    assert set(settings["command_start"]) <= set(plant.command_names)


@pytest.mark.parametrize("scenario, why", [
    ("examples/directional_hybrid68_stickslip.toml", "operation.surface_speed: a time profile"),
    ("examples/eid_tracking.toml", "simulation.noise"),
    ("examples/dhp_step_fem24.toml", "a DHP design scenario trains a controller"),
    ("examples/sil_hil.toml", "link.mode: 'hil' is not supported"),
])
def test_what_an_fmu_plant_does_not_support_is_one_line(tmp_path, capsys, scenario, why):
    out = tmp_path / "x.fmu"
    assert main(["export-fmu", scenario, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert scenario in err and why in err and len(err.splitlines()) == 1, err
    assert not out.exists()


def test_a_survey_scenario_carries_its_survey(tmp_path):
    """A described well from a survey CSV: the FMU carries the CSV beside the scenario, and the
    instance rebuilds the same plant from them."""
    from downhole.sil.fmu import fmu_signals, run_fmu_closed_loop

    fmu = _export(tmp_path, "examples/directional_survey.toml", fidelity="lumped4")
    with zipfile.ZipFile(fmu) as z:
        assert "resources/directional_survey_well.csv" in z.namelist()
    assert fmu_signals(fmu)["step_size"] == 5e-4
    res = run_fmu_closed_loop(fmu, _Hold(), 0.01)
    assert np.all(np.isfinite(res["bit_angular_velocity"]))
