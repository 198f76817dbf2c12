"""Reproduction runner and report: parallel runs with failures isolated, index.html rendered by
Chromium (images load, pass/fail shown), the benchmark report."""

from __future__ import annotations

import json
import shutil
import sys
import textwrap
from pathlib import Path

import pytest

from downhole.report import bench_markdown, build_index, reproduce

PLUGIN = textwrap.dedent('''
    """Test experiments registered through $DOWNHOLE_EXPERIMENT_PLUGINS."""
    import numpy as np
    from downhole.experiments import experiment, _REGISTRY

    if "test.ok" not in _REGISTRY:
        @experiment("test.ok", title="a working experiment", chapter=2, claim="sum is 3",
                    caption="Figure T.1: a line.")
        def _ok(out_dir, quick):
            import matplotlib
            matplotlib.use("Agg")
            import matplotlib.pyplot as plt
            fig, ax = plt.subplots(figsize=(4, 3))
            ax.plot([0, 1, 2], [0, 1, 4])
            fig.savefig(out_dir / "line.png")
            plt.close(fig)
            np.savetxt(out_dir / "data.csv", [1.0, 2.0])
            return {"measured": {"sum": 1 + 2, "nested": {"a": 0.5}}, "passed": True}

        @experiment("test.fail", title="an experiment that raises", chapter=2,
                    claim="never reached")
        def _fail(out_dir, quick):
            print("about to fail")
            raise RuntimeError("boom in the experiment")

        @experiment("test.claimfalse", title="a claim that does not hold", chapter=3,
                    claim="1 > 2")
        def _false(out_dir, quick):
            return {"measured": {"lhs": 1, "rhs": 2}, "passed": False}

        @experiment("test.slow", title="a timing claim that does not hold", chapter=3,
                    claim="100x faster than the seed")
        def _slow(out_dir, quick):
            return {"measured": {"speed-up": 30}, "passed": False}
''')

IDS = ["test.ok", "test.fail", "test.claimfalse"]
ALL_IDS = [*IDS, "test.slow"]


@pytest.fixture(scope="module")
def plugin(tmp_path_factory):
    mod_dir = tmp_path_factory.mktemp("plugins")
    (mod_dir / "dh_test_experiments.py").write_text(PLUGIN)
    with pytest.MonkeyPatch.context() as mp:
        mp.syspath_prepend(str(mod_dir))
        mp.setenv("PYTHONPATH", str(mod_dir) + ":" + ":".join(sys.path))
        mp.setenv("DOWNHOLE_EXPERIMENT_PLUGINS", "dh_test_experiments")
        yield "dh_test_experiments"
    from downhole.experiments import _REGISTRY

    for eid in ALL_IDS:
        _REGISTRY.pop(eid, None)
    sys.modules.pop("dh_test_experiments", None)


@pytest.fixture(scope="module")
def report_dir(tmp_path_factory, plugin):
    out = tmp_path_factory.mktemp("report") / "out"
    summary = reproduce(IDS, out, quick=True, jobs=2)
    return out, summary


def test_failing_experiment_is_recorded_and_others_run(report_dir):
    out, summary = report_dir
    assert summary["passed"] == ["test.ok"]
    assert summary["failed"] == ["test.claimfalse", "test.fail"]
    bad = json.loads((out / "test.fail" / "claim.json").read_text())
    assert bad["passed"] is False and bad["error"] == "RuntimeError: boom in the experiment"
    assert bad["claim"] == "never reached"
    tb = (out / "test.fail" / "error.log").read_text()
    assert "Traceback" in tb and "boom in the experiment" in tb
    assert "about to fail" in (out / "test.fail" / "run.log").read_text()
    ok = json.loads((out / "test.ok" / "claim.json").read_text())
    assert ok["passed"] is True and ok["measured"]["sum"] == 3 and ok["quick"] is True
    assert (out / "test.ok" / "line.png").exists()
    assert "error" not in json.loads((out / "test.claimfalse" / "claim.json").read_text())
    index = (out / "index.html").read_text()
    assert "Figure T.1: a line." in index and "RuntimeError: boom in the experiment" in index
    assert 'href="test.fail/error.log"' in index and 'href="test.ok/data.csv"' in index
    assert json.loads((out / "reproduce.json").read_text())["jobs"] == 2


def test_cli_reproduce_in_process(tmp_path, plugin, capsys):
    from downhole.cli import main

    out = tmp_path / "cli"
    rc = main(["reproduce", "test.ok", "test.fail", "--out", str(out), "--jobs", "1"])
    assert rc == 1  # a failed claim is a failed command
    text = capsys.readouterr().out
    assert "1 passed, 1 failed" in " ".join(text.split())  # rich may wrap lines
    assert "index.html" in text.replace("\n", "")
    assert "failed claims: test.fail" in " ".join(text.split())
    assert main(["reproduce", "test.ok", "--out", str(out), "--jobs", "1"]) == 0
    capsys.readouterr()
    # a timing claim alone: its own exit code, so that a script can tell load from physics
    assert main(["reproduce", "test.ok", "test.slow", "--out", str(out), "--jobs", "1"]) == 3
    assert "only timing claims failed: test.slow" in " ".join(capsys.readouterr().out.split())
    assert main(["reproduce", "no.such.exp", "--out", str(out)]) == 2
    assert "unknown experiment 'no.such.exp'" in capsys.readouterr().err


CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"


@pytest.mark.skipif(not Path(CHROMIUM).exists(), reason="chromium not installed "
                    "(apt-get install chromium)")
def test_index_renders_in_chromium(report_dir, tmp_path):
    playwright = pytest.importorskip("playwright.sync_api")
    out, _ = report_dir
    shot = tmp_path / "index.png"
    with playwright.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=["--no-sandbox",
                                                                    "--disable-gpu"])
        page = browser.new_page(viewport={"width": 1300, "height": 1600})
        page.goto((out / "index.html").as_uri())
        page.wait_for_load_state("load")
        for img in page.query_selector_all("img"):
            img.scroll_into_view_if_needed()
        page.wait_for_function("Array.from(document.images).every(i => i.complete)")
        widths = page.eval_on_selector_all("img", "els => els.map(e => e.naturalWidth)")
        assert widths and all(w > 0 for w in widths)  # every figure loaded
        assert page.locator("section#test\\.ok .badge.pass").count() == 1
        assert page.locator("section#test\\.fail .badge.fail").count() == 1
        assert "boom in the experiment" in page.inner_text("section#test\\.fail .error")
        assert page.locator("h2", has_text="Chapter 3").count() == 1
        page.screenshot(path=str(shot), full_page=False)
        browser.close()
    assert shot.stat().st_size > 20_000


@pytest.mark.skipif(not Path(CHROMIUM).exists(), reason="chromium not installed")
def test_index_screenshot_with_headless_chromium_cli(report_dir, tmp_path):
    import subprocess

    import matplotlib.image as mpimg

    out, _ = report_dir
    shot = tmp_path / "cli.png"
    subprocess.run([CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu",
                    "--disable-background-networking", "--hide-scrollbars",
                    "--window-size=1200,900", f"--screenshot={shot}",
                    (out / "index.html").as_uri()], check=True, timeout=120,
                   capture_output=True)
    img = mpimg.imread(shot)
    assert img.shape[0] == 900 and img.shape[1] == 1200
    assert img[..., :3].std() > 0.05  # not a blank page
    # the header band is the report's dark blue (#1f3a4d)
    r, g, b = img[10, 600, :3]
    assert b > r and abs(r - 0x1F / 255) < 0.05


def test_index_lists_experiments_not_run(tmp_path):
    out = build_index(tmp_path)
    text = out.read_text()
    assert "not run" in text and "Chapter 2" in text


def test_bench_markdown_ratios_and_machine():
    report = {"machine": {"cpu": "Test CPU", "cores": 2, "memory_gib": 24.0,
                          "platform": "Linux", "python": "3.11.7", "numba": "0.60"},
              "run": {"quick": True, "date": "2026-01-01", "downhole_version": "0.1.0",
                      "command": "downhole bench --out b.json --quick"},
              "cases": [{"name": "case A", "group": "ch2", "seconds": 0.5, "baseline": "numpy",
                         "baseline_seconds": 5.0, "ratio": 10.0, "seed_seconds": 100.0,
                         "ratio_to_seed": 200.0},
                        {"name": "case B", "group": "ch3", "seconds": None, "baseline": None,
                         "baseline_seconds": None, "ratio": None, "seed_seconds": None,
                         "ratio_to_seed": None, "error": "RuntimeError: broke"}]}
    md = bench_markdown(report, "b.json")
    assert "| case A | 100 | 0.5 | 200x | numpy | 5 | 10x |" in md
    assert "| case B | - | failed: RuntimeError: broke |" in md
    assert "Test CPU, 2 cores" in md and "downhole bench --out b.json --quick" in md
    assert "## ch2" in md and "## ch3" in md


def test_cli_bench_isolates_a_failing_case_and_reports(tmp_path, monkeypatch):
    from downhole.bench import _CASES, BenchOutcome, bench_case
    from downhole.cli import main

    @bench_case("test sum ok", seed_seconds=2.0, group="test")
    def _ok(quick):
        return BenchOutcome(0.5, "slow sum", 1.5)

    @bench_case("test broken", group="test")
    def _broken(quick):
        raise ValueError("bench broke")

    try:
        out = tmp_path / "b.json"
        rc = main(["bench", "--out", str(out), "--case", "test sum ok", "--case", "test broken"])
        assert rc == 0
        data = json.loads(out.read_text())
        rows = {r["name"]: r for r in data["cases"]}
        assert rows["test sum ok"]["ratio"] == pytest.approx(3.0)
        assert rows["test sum ok"]["ratio_to_seed"] == pytest.approx(4.0)
        assert rows["test broken"]["error"] == "ValueError: bench broke"
        assert data["machine"]["cores"] >= 1 and data["run"]["quick"] is False
        md = tmp_path / "perf.md"
        assert main(["bench-report", str(out), "--out", str(md)]) == 0
        text = md.read_text()
        assert "| test sum ok | 2 | 0.5 | 4x | slow sum | 1.5 | 3x |" in text
        assert main(["bench-report", str(tmp_path / "missing.json"), "--out", str(md)]) == 2
    finally:
        _CASES.pop("test sum ok", None)
        _CASES.pop("test broken", None)


def test_speed_and_deadline_claims_run_alone():
    """Claims about speed, and the paced run's deadline claim, are measured alone after the
    pool (beside another experiment on 2 cores fig6.8 missed 6.4 % of its deadlines); the
    physics claims of the real-time runtime run in the pool."""
    from downhole.experiments import get_experiment
    from downhole.report.reproduce import is_timing

    for eid in ("fig4.13", "table5.2", "fig6.8"):
        assert is_timing(get_experiment(eid)), eid
    for eid in ("fig6.5", "fig6.11", "fig3.6"):
        assert not is_timing(get_experiment(eid)), eid
