"""A SIL run longer than the ring it keeps in memory streams to disk and --out holds the whole
run (issue 24, item 3: recordings have a memory budget and stream to disk)."""

from pathlib import Path

import numpy as np

from downhole.cli import main
from downhole.sim.result import load_result

ROOT = Path(__file__).resolve().parents[1]


def _scenario(tmp_path, ring="1 s"):
    text = (ROOT / "examples" / "sil_open_loop.toml").read_text()
    text = text.replace('duration = "30 s"', 'duration = "3 s"\nrecord_dt = "10 ms"')
    text += f'\n[realtime]\npaced = false\nring_seconds = "{ring}"\n'
    p = tmp_path / "s.toml"
    p.write_text(text)
    return p


def test_a_run_longer_than_the_ring_is_whole_in_out(tmp_path, capsys):
    out = tmp_path / "run.nc"
    assert main(["sil", str(_scenario(tmp_path)), "--out", str(out), "--no-progress"]) == 0
    err = capsys.readouterr().err
    assert "keeps the last 1 s in memory" in err and "streams to" in err
    res = load_result(out)
    # 3 s at 10 ms: every sample from t = 0, not only the last second the ring kept
    assert res.time[0] == 0.0 and res.time[-1] >= 2.98
    assert res.time.size >= 299
    assert np.all(np.diff(res.time) > 0)
    # the chunk folder was this run's own: once --out holds the run it is gone
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.nc", "s.toml"]


def test_a_run_the_ring_holds_writes_no_chunks(tmp_path, capsys):
    out = tmp_path / "run.nc"
    assert main(["sil", str(_scenario(tmp_path, ring="10 s")), "--out", str(out),
                 "--no-progress"]) == 0
    assert "streams to" not in capsys.readouterr().err
    assert load_result(out).time[0] == 0.0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.nc", "s.toml"]
