"""Chapter 4/5 directional experiments in quick mode: figures written, claims checked."""

import pytest

from downhole.experiments import run_experiment


@pytest.mark.parametrize("eid", ["fig4.4", "fig5.4", "fig5.5", "fig5.6", "fig5.7", "fig5.8",
                                 "fig5.9"])
def test_directional_experiment_quick(eid, tmp_path):
    claim = run_experiment(eid, tmp_path, quick=True)
    assert (tmp_path / eid / f"{eid}.png").exists()
    assert claim["passed"], claim["measured"]


def test_table_5_2_runs_quick(tmp_path):
    # speed is reported, not asserted (shared machines); the table must be written
    claim = run_experiment("table5.2", tmp_path, quick=True)
    assert (tmp_path / "table5.2" / "table5.2.md").exists()
    assert len(claim["measured"]["rows"]) == 6
