"""Gymnasium environment: the environment checker, and the documented reward recomputed from
the plant stepped by hand."""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import downhole.gym  # noqa: F401  (registers downhole/Drilling-v0)
from downhole.gym import DrillingEnv
from downhole.sil import build_plant


def test_env_passes_gymnasium_checker():
    env = gym.make("downhole/Drilling-v0", model="lumped", episode_seconds=1.0)
    check_env(env.unwrapped, skip_render_check=True)
    obs, info = env.reset(seed=3)
    assert env.observation_space.contains(obs)
    total, steps, done = 0.0, 0, False
    while not done:
        obs, r, term, trunc, info = env.step(env.action_space.sample())
        total += r
        steps += 1
        done = term or trunc
    assert steps == 20 and np.isfinite(total)


def test_reward_is_the_documented_formula():
    env = DrillingEnv(model="lumped", reference=(0.01, 20.0), control_dt=0.02)
    env.reset(seed=0)
    action = np.array([0.2, -0.1], dtype=np.float32)
    # by hand: the same plant, the documented action map and reward
    plant = build_plant("lumped")
    plant.reset()
    cmd = {"top_drive_axial_velocity": 0.6 * 0.03, "top_drive_angular_velocity": 0.45 * 40.0}
    for k in range(3):
        _, r, *_ = env.step(action)
        terms = []
        for _ in range(20):
            o = plant.step(cmd)
            terms.append(((o["bit_axial_velocity"] - 0.01) / 0.01) ** 2
                         + ((o["bit_angular_velocity"] - 20.0) / 20.0) ** 2
                         + (abs(o["bit_angular_velocity"]) < 0.1) + (o["wob"] <= 0))
        assert r == pytest.approx(-np.mean(terms), rel=1e-9)


@pytest.mark.parametrize("model", ["neutral", "hybrid24"])
def test_env_starts_in_the_steady_drilling_state(model):
    # the environment resets through the Plant contract: from the steady state at the held
    # commands the bit does not move off its velocities, from rest it starts still
    env = DrillingEnv(model=model, reference=(0.01, 20.0), control_dt=0.01)
    hold = env.plant.default_command()
    obs, _ = env.reset(seed=0, options={"start": "steady", "set_point": hold})
    w0 = env.plant.last_observation["bit_angular_velocity"]
    assert w0 > 5.0 and obs[1] == pytest.approx(w0 / 20.0, rel=1e-6)
    for _ in range(20):  # 0.2 s holding the same commands, stepped by hand
        o = env.plant.step(hold)
    assert o["bit_angular_velocity"] == pytest.approx(w0, rel=0.01)
    env.reset(seed=0)
    assert env.plant.last_observation["bit_angular_velocity"] == 0.0


def test_env_from_a_scenario_file_uses_the_one_schema(tmp_path):
    """The environment reads the scenario schema every command reads: its plant, bit, step,
    episode length and reference come from the file; a bad file is one ScenarioError line."""
    from downhole.errors import DownholeInputError, ScenarioError

    sc = tmp_path / "env.toml"
    sc.write_text('[model]\nfidelity = "lumped4"\n[bit]\nepsilon = "90 MPa"\n'
                  '[simulation]\ndt = "1 ms"\nduration = "0.5 s"\n'
                  '[reference]\naxial_velocity = "12 mm/s"\nangular_velocity = "15 rad/s"\n')
    env = DrillingEnv.from_scenario(sc, control_dt=0.05)
    assert env.plant.plant.model.bit.epsilon == pytest.approx(90e6)
    assert env.max_steps == 10 and env.fixed_reference == (pytest.approx(0.012), 15.0)
    obs, info = env.reset(seed=0)
    assert info["reference"] == (pytest.approx(0.012), 15.0)
    n, done = 0, False
    while not done:
        _, _, term, trunc, _ = env.step(np.zeros(2))
        n, done = n + 1, term or trunc
    assert n == 10
    sc.write_text('[plant]\nmodel = "lumped"\n')
    with pytest.raises(ScenarioError, match="plant.model: renamed: use model.fidelity"):
        DrillingEnv.from_scenario(sc)
    sc.write_text('[model]\nfidelity = "hybrid"\ninterface = "state"\n')
    with pytest.raises(DownholeInputError, match="interface"):
        DrillingEnv.from_scenario(sc)
