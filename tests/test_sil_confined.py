"""A SIL run touches nothing outside its output (issue "safe by default"): the chunk folder is a
name beside ``--out``, never any folder of the host (the recorder removes the previous run's
chunks in it), and the recording ring has a memory budget instead of preallocating whatever
``ring_seconds`` asks for."""

from __future__ import annotations

import numpy as np
import pytest

from downhole.cli import main
from downhole.errors import ScenarioError
from downhole.sil.scenario import load_sil_scenario
from downhole.sim.result import load_result

SIL = """
[model]
fidelity = "lumped4"
[simulation]
dt = "1 ms"
duration = "{duration}"
record_dt = "10 ms"
[realtime]
{realtime}
[controller]
type = "pi"
"""


@pytest.mark.parametrize("bad", ["/etc", "/tmp/x", "../outside", "a/../../b", "~/x", "",
                                 "C:/x"])
def test_a_chunk_dir_outside_the_output_is_refused_naming_the_field(bad, tmp_path):
    sc = tmp_path / "s.toml"
    sc.write_text(SIL.format(duration="0.1 s", realtime=f'chunk_dir = "{bad}"'))
    with pytest.raises(ScenarioError, match=r"realtime\.chunk_dir.*relative to the run's --out"):
        load_sil_scenario(sc)


def test_a_chunk_dir_without_out_is_refused_before_any_work(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    victim = tmp_path / "chunks"
    victim.mkdir()
    (victim / "chunk_000001.npz").write_text("somebody's file")
    sc = tmp_path / "s.toml"
    sc.write_text(SIL.format(duration="0.1 s", realtime='chunk_dir = "chunks"'))
    assert main(["sil", str(sc), "--unpaced"]) == 2
    err = capsys.readouterr().err
    assert "realtime.chunk_dir = 'chunks' needs --out" in err
    assert (victim / "chunk_000001.npz").read_text() == "somebody's file"


def test_chunks_go_beside_out(tmp_path, monkeypatch):
    from downhole.sil import load_chunks

    work = tmp_path / "cwd"
    work.mkdir()
    monkeypatch.chdir(work)  # a relative chunk_dir is not taken relative to the cwd
    runs = tmp_path / "runs"
    runs.mkdir()
    sc = tmp_path / "s.toml"
    sc.write_text(SIL.format(duration="0.5 s", realtime='chunk_dir = "chunks"'))
    assert main(["sil", str(sc), "--unpaced", "--out", str(runs / "run.nc")]) == 0
    assert not list(work.iterdir())
    res = load_result(runs / "run.nc")
    full = load_chunks(runs / "chunks")
    np.testing.assert_array_equal(full.time, res.time)


def test_the_ring_keeps_to_its_memory_budget_and_says_so(tmp_path, capsys):
    sc = tmp_path / "s.toml"
    # 1e5 s at 10 ms would preallocate ~10 M rows; a 0.05 MiB budget holds a few hundred
    sc.write_text(SIL.format(duration="3 s",
                             realtime='ring_seconds = "100000 s"\nring_memory_mib = 0.05'))
    out = tmp_path / "run.nc"
    assert main(["sil", str(sc), "--unpaced", "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert "note: the recording keeps the last" in err and "streams to" in err
    res = load_result(out)
    # the ring holds a few hundred rows; the run streamed to disk, so --out has all of it
    n_ch = len(res.channels) + 1  # the recorder's columns: time and the channels
    rows = int(0.05 * 2**20) // (8 * n_ch)
    assert rows < res.time.size
    assert res.time[0] == 0.0 and res.time[-1] == pytest.approx(3.0)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.nc", "s.toml"]
    np.testing.assert_allclose(np.diff(res.time), 0.01, rtol=1e-6)
