"""``[simulation] start`` in the files of a preset (lumped, neutral, FEM / hybrid) and of the SIL
testbed: from the steady drilling state the bit stays at its set-points over the first second
(the Plant contract's start, tests/test_start.py and test_start_fidelity.py, reached from a
file)."""

from pathlib import Path

import numpy as np
import pytest

from downhole.scenario import run_scenario

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _first_second(res, name):
    t = res.time
    return np.asarray(res[name])[(t > 0.0) & (t <= 1.0)]


@pytest.mark.parametrize("start", ["rest", "steady"])
def test_lumped_preset_file_starts_where_asked(tmp_path, start):
    text = (EXAMPLES / "fig2.4.toml").read_text().replace('duration = "60 s"',
                                                           'duration = "1 s"')
    text = text.replace("[simulation]", f'[simulation]\nstart = "{start}"')
    f = tmp_path / "s.toml"
    f.write_text(text)
    res = run_scenario(f)
    w = _first_second(res, "bit_angular_velocity")
    v = _first_second(res, "bit_axial_velocity")
    if start == "steady":  # 20 mm/s, 20 rad/s: a stable point of Table 2.1 (Fig. 2.4)
        assert np.max(np.abs(w / 20.0 - 1.0)) < 0.01
        assert np.max(np.abs(v / 0.02 - 1.0)) < 0.01
    else:  # from rest the bit is still far from its set-points early in the first second
        assert abs(w[0]) < 1.0


def test_neutral_preset_file_steady_start(tmp_path):
    text = (EXAMPLES / "neutral_open_loop.toml").read_text()
    text = text.replace('duration = "20 s"', 'duration = "1 s"')
    text = text.replace("[simulation]", '[simulation]\nstart = "steady"')
    f = tmp_path / "s.toml"
    f.write_text(text)
    res = run_scenario(f)
    w = _first_second(res, "bit_angular_velocity")
    v = _first_second(res, "bit_axial_velocity")
    # the seed's nominal open-loop commands (U_A = 1.147224 m/s, U_T = 22.5196 rad/s) hold the
    # bit at 10 mm/s and 20 rad/s (Table 3.1 nominal point, Fig. 3.2)
    assert np.max(np.abs(w / 20.0 - 1.0)) < 0.01
    assert np.max(np.abs(v / 0.01 - 1.0)) < 0.01


def test_sil_file_steady_start_reaches_the_plant(tmp_path):
    from downhole.sil.scenario import build_from_scenario, load_sil_scenario

    f = tmp_path / "s.toml"
    f.write_text('[model]\nfidelity = "lumped4"\n[operation]\nrop = "20 mm/s"\n'
                 'surface_speed = "20 rad/s"\n[simulation]\nstart = "steady"\n'
                 '[controller]\ntype = "none"\n')
    plant, _ = build_from_scenario(load_sil_scenario(f))
    obs = plant.reset()  # what the runtime calls
    assert obs["bit_angular_velocity"] == pytest.approx(20.0, rel=1e-3)
    assert obs["bit_axial_velocity"] == pytest.approx(0.02, rel=1e-3)
    for _ in range(1000):  # 1 s at 1 ms
        obs = plant.step({"top_drive_axial_velocity": 0.02, "top_drive_angular_velocity": 20.0})
    assert obs["bit_angular_velocity"] == pytest.approx(20.0, rel=0.01)
