"""Chapter 6 experiments in quick mode: each asserts its figure's claim in numbers."""

import pytest

from downhole.experiments import run_experiment


@pytest.mark.parametrize("eid", ["fig6.5", "fig6.8", "fig6.11",
                                 pytest.param("fig6.12", marks=pytest.mark.slow),
                                 pytest.param("fig6.13", marks=pytest.mark.slow)])
def test_ch6_experiment_quick(eid, tmp_path):
    claim = run_experiment(eid, tmp_path, quick=True)
    print(f"\n{eid}: {claim['measured']}")
    assert (tmp_path / eid / f"{eid}.png").stat().st_size > 10_000
    assert claim["passed"], claim
