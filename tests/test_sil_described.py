"""The SIL runtime and the Gymnasium environment run a described system (issue 23, item 3: every
command reads the description): the system's model at its fidelity under the rig, with the same
surface commands at every fidelity, checked against the hand balance of steady drilling."""

import math
from pathlib import Path

import numpy as np
import pytest

from downhole.cli import main
from downhole.errors import ScenarioError
from downhole.sil.scenario import build_from_scenario, load_sil_scenario
from downhole.sim.result import load_result

ROOT = Path(__file__).resolve().parents[1]
FIRST_RUN = ROOT / "examples" / "first_run.toml"


def _copy(tmp_path, fidelity, extra=""):
    text = FIRST_RUN.read_text().replace('fidelity = "lumped4"', f'fidelity = "{fidelity}"')
    p = tmp_path / f"{fidelity}.toml"
    p.write_text(text.replace('duration = "30 s"', 'duration = "1 s"') + extra)
    return p


@pytest.mark.parametrize("fidelity", ["lumped4", "neutral", "fem"])
def test_the_plant_is_the_described_system_under_the_rig(tmp_path, fidelity):
    sc = load_sil_scenario(_copy(tmp_path, fidelity))
    plant, ctrl = build_from_scenario(sc, with_controller=False)
    assert plant.command_names == ("hook_load", "top_drive_angular_velocity")
    # open loop: the hook holds the hanging weight less 100 kN, the PI turns at 120 rpm
    from downhole.scenario.schema import read_scenario
    from downhole.scenario.system import build_system, parse_system

    data, source, _ = read_scenario(FIRST_RUN)
    weight = build_system(parse_system(data, source), source, "fem").hanging_weight()
    cmd = plant.default_command()
    assert cmd["hook_load"] == pytest.approx(weight - 100e3, rel=1e-9)
    assert cmd["top_drive_angular_velocity"] == pytest.approx(120 * math.pi / 30)


def test_sil_runs_the_described_steady_state(tmp_path, capsys):
    """``downhole sil`` on the first run's file: from the steady start the bit holds 120 rpm
    and the hook load is the hanging weight less 100 kN, open loop (type "none")."""
    p = _copy(tmp_path, "fem", '\n[controller]\ntype = "none"\n[realtime]\npaced = false\n')
    out = tmp_path / "run.nc"
    assert main(["sil", str(p), "--out", str(out), "--no-progress"]) == 0
    res = load_result(out)
    w = np.asarray(res["bit_angular_velocity"])
    assert np.allclose(w, 120 * math.pi / 30, rtol=1e-2)
    assert res.time[-1] == pytest.approx(1.0, abs=0.011)


def test_what_a_described_system_cannot_do_in_the_sil_is_one_line(tmp_path):
    for extra, field in (('\n[controller]\ntype = "dhp"\n', "controller.type"),
                         ('\n[link]\nmode = "hil"\n', "link.mode")):
        with pytest.raises(ScenarioError, match=field):
            load_sil_scenario(_copy(tmp_path, "fem", extra))
    p = tmp_path / "i.toml"
    p.write_text(FIRST_RUN.read_text().replace('friction = 0.0', 'friction = 0.0\n'
                                               'interface = "state"'))
    with pytest.raises(ScenarioError, match="model.interface"):
        load_sil_scenario(p)


def test_the_environment_steps_a_described_system_at_every_fidelity(tmp_path):
    from downhole.gym import DrillingEnv

    for fid in ("lumped4", "lumped12", "neutral", "fem", "hybrid"):
        env = DrillingEnv.from_scenario(_copy(tmp_path, fid))
        obs, _ = env.reset(seed=0)
        for _ in range(3):
            obs, *_ = env.step(np.zeros(env.action_space.shape, np.float32))
        assert np.all(np.isfinite(obs)), fid
