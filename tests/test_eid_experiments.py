"""Chapter 3 experiments in quick mode: each writes its PNG and claim, and its claim holds."""

import json
import warnings

import pytest

from downhole.experiments import run_experiment

warnings.filterwarnings("ignore", category=UserWarning)


@pytest.mark.parametrize("eid", ["fig3.4", "fig3.5", "fig3.6", "fig3.7", "stickslip-neutral"])
def test_ch3_experiment_quick(eid, tmp_path):
    claim = run_experiment(eid, tmp_path, quick=True)
    assert (tmp_path / eid / f"{eid}.png").exists()
    assert json.loads((tmp_path / eid / "claim.json").read_text())["passed"] == claim["passed"]
    assert claim["passed"], claim["measured"]


def test_fig3_8_epsilon_sensitivity(tmp_path):
    claim = run_experiment("fig3.8", tmp_path, quick=True)
    m = claim["measured"]
    for k in ("eps_50pct", "eps_100pct", "eps_150pct"):
        assert m[k]["rop_error_last_10s"] < 0.02 and m[k]["omega_error_last_10s"] < 0.02
    # known gap (docs/neutral-eid.md): at 200 % epsilon the axial loop keeps a limit cycle
    assert claim["passed"] == (m["eps_200pct"]["rop_error_last_10s"] < 0.02)
