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
        print(f"\n{ch}: max relative difference FMPy vs simulate_directional {err:.1e}")
        assert err < 1e-6
    # the input really acts: 12 rad/s set-point reached at the surface
    assert res["top_drive_angular_velocity"][-1] == pytest.approx(12.0, rel=0.2)


def test_export_fmu_rejects_a_bad_scenario(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[model]\nfidelity = 'hybrid'\npreset = 'hybrid99'\n")
    assert main(["export-fmu", str(bad), "--out", str(tmp_path / "x.fmu")]) == 2
