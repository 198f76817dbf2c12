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
