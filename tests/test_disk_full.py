"""A full disk gives one line and exit code 1, never a traceback or a crash, and leaves the output
folder marked incomplete with the reason (issue "survival").

The disk is a 300 kB tmpfs mounted for the test (needs root, as CI runs; skipped where mounting is
not allowed). The run is a subprocess: before the fix, HDF5 writing onto the full disk left a
broken file object that crashed the interpreter at exit (SIGSEGV, exit -11).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from downhole._atomic import MARKER, write_bytes_atomic

SCENARIO = """
[model]
fidelity = "lumped4"
preset = "table_2_1"
[operation]
rop = "10 mm/s"
surface_speed = "10 rad/s"
[simulation]
duration = "20 s"
dt = "0.5 ms"
record_dt = "1 ms"
"""


@pytest.fixture()
def small_disk(tmp_path):
    mnt = tmp_path / "small"
    mnt.mkdir()
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=300k", "tmpfs", str(mnt)],
                       capture_output=True, text=True)
    if r.returncode != 0:
        pytest.skip(f"cannot mount a small tmpfs here ({r.stderr.strip()[:80]})")
    try:
        yield mnt
    finally:
        subprocess.run(["umount", "-l", str(mnt)], capture_output=True)


def test_a_full_disk_is_one_line_and_exit_1_with_the_folder_marked(small_disk, tmp_path):
    scen = tmp_path / "s.toml"
    scen.write_text(SCENARIO)
    out = small_disk / "run"
    r = subprocess.run([sys.executable, "-c", "import sys; from downhole.cli import main; "
                        "sys.exit(main(sys.argv[1:]))", "simulate", str(scen), "--out", str(out)],
                       capture_output=True, text=True, timeout=600,
                       env=dict(os.environ, PYTHONFAULTHANDLER="1"))
    assert r.returncode == 1, (r.returncode, r.stderr[-2000:])  # not -11 (SIGSEGV)
    err = r.stderr.strip().splitlines()
    assert err == [f"error: No space left on device: {out / 'result.nc'} (free some space or "
                   "choose another --out)"], r.stderr[-2000:]
    assert "Traceback" not in r.stderr
    names = sorted(p.name for p in out.iterdir())
    assert names == [MARKER]  # no temporary, no half file, no lock left behind
    assert "failed: OSError" in (out / MARKER).read_text()


def test_write_bytes_atomic_on_a_full_disk_leaves_the_old_file(small_disk):
    final = small_disk / "a.bin"
    write_bytes_atomic(final, b"old")
    with pytest.raises(OSError) as info:
        write_bytes_atomic(final, b"x" * 1_000_000)
    assert info.value.filename == str(final)
    assert final.read_bytes() == b"old"
    assert sorted(p.name for p in Path(small_disk).iterdir()) == ["a.bin"]
