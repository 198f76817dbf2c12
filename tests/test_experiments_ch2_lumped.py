"""The Chapter 2 lumped-model experiments run (quick) and their claims hold."""

import json

import pytest

from downhole.experiments import run_experiment


@pytest.mark.parametrize("eid,png", [("fig2.3", "comparison.png"), ("fig2.4", "comparison.png"),
                                     ("stickslip-lumped", "stickslip.png"),
                                     ("models-4th-vs-12th", "models.png")])
def test_experiment_claim_passes(eid, png, tmp_path):
    claim = run_experiment(eid, tmp_path, quick=True)
    assert claim["passed"], claim
    on_disk = json.loads((tmp_path / eid / "claim.json").read_text())
    assert on_disk == claim
    assert set(on_disk) == {"id", "claim", "measured", "passed"}
    assert (tmp_path / eid / png).stat().st_size > 10_000


def test_examples_hold_each_experiment_scenario():
    """examples/<id>.toml is the scenario each Ch. 2 lumped experiment runs (no drift)."""
    import tomllib
    from pathlib import Path

    from downhole.experiments.ch2_lumped import SCENARIOS
    from downhole.scenario import run_scenario

    root = Path(__file__).resolve().parents[1] / "examples"
    for eid, data in SCENARIOS.items():
        path = root / f"{eid}.toml"
        assert tomllib.loads(path.read_text()) == data, eid
    res = run_scenario(root / "fig2.3.toml")  # and it runs through the scenario machinery
    assert res.time[-1] == 60.0
