"""A run survives what ends it (issue 27): signals, a second run on its folder, a full disk and
planted links.

- SIGTERM, SIGHUP (a closed terminal, a dropped SSH session) and SIGINT sent to ``downhole
  simulate``, ``sweep --processes 2``, ``compare-controllers -j 2`` and ``sil`` once they run
  (the output folder is marked ``INCOMPLETE`` and, with workers, the workers are up): the command
  ends with one line and exit code 128 + the signal, no process of its process group is left
  (``os.killpg(pgid, 0)`` raises ``ProcessLookupError``, polled within a bound), the folder keeps
  its marker with the reason, and ``sil`` writes the rows it recorded;
- a second run on an ``--out`` that a running command owns is refused with one line, and the
  first run's folder is untouched;
- a full disk (``ENOSPC`` raised in-process by the writers) is one line, exit code 1, and what
  was recorded before it stays readable;
- a link planted under a temporary's name, a staging folder's name or given as ``--out`` is not
  followed.

Each subprocess starts in its own session (``start_new_session``), so that its process group is
exactly the command and its workers. The waits are bounds for events on a loaded machine, not
timing claims.
"""

from __future__ import annotations

import errno
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import downhole
from downhole._atomic import LOCK_NAME, MARKER, OutputFolder, is_incomplete
from downhole.cli import main
from downhole.sim.result import Result, load_result

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"),
                                reason="process groups and /proc")

ROOT = Path(downhole.__file__).resolve().parents[1]
BOUND = 120.0  # s: upper bound of any wait on a loaded 2-core machine; normally seconds
LONG = "5000 s"  # simulated: tens of seconds of work (and ~0.6 GB) per run; signalled long before

SIM = """
title = "survival"
[model]
fidelity = "lumped4"
preset = "table_2_1"
[operation]
rop = "10 mm/s"
surface_speed = "10 rad/s"
[simulation]
duration = "{duration}"
dt = "0.5 ms"
record_dt = "{record_dt}"
"""

SIL = """
title = "survival, lumped plant"
[model]
fidelity = "lumped4"
[simulation]
dt = "1 ms"
duration = "{duration}"
record_dt = "2 ms"
[realtime]
ring_seconds = "600 s"
chunk_dir = "chunks"
[controller]
type = "pi"
"""


# ------------------------------------------------------------------------------- helpers
class Command:
    """``downhole ARGS`` in a subprocess of its own session; stderr collected line by line."""

    def __init__(self, args, cwd: Path, env: dict | None = None):
        env = dict(os.environ, MPLBACKEND="Agg", PYTHONUNBUFFERED="1", **(env or {}))
        env["PYTHONPATH"] = os.pathsep.join(
            [str(ROOT), str(cwd)] + [p for p in env.get("PYTHONPATH", "").split(os.pathsep)
                                     if p])
        self.p = subprocess.Popen(
            # SIGINT as in a terminal's foreground job (a test runner started in the background
            # may pass it on ignored)
            [sys.executable, "-c", "import signal, sys; from downhole.cli import main; "
             "signal.signal(signal.SIGINT, signal.default_int_handler); "
             "sys.exit(main(sys.argv[1:]))", *map(str, args)],
            cwd=cwd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
            start_new_session=True)
        self.pgid = self.p.pid  # the session leader leads its process group
        self.lines: list[str] = []
        self._t = threading.Thread(target=self._read, daemon=True)
        self._t.start()

    def _read(self):
        for line in self.p.stderr:
            self.lines.append(line)

    def wait_for(self, what: str, pred) -> None:
        end = time.monotonic() + BOUND
        while time.monotonic() < end:
            if pred():
                return
            if self.p.poll() is not None:
                self._t.join(5)
                pytest.fail(f"the command ended (rc {self.p.returncode}) before {what}:\n"
                            + "".join(self.lines))
            time.sleep(0.05)
        pytest.fail(f"timed out waiting for {what}:\n" + "".join(self.lines))

    def workers(self) -> list[int]:
        """Spawned worker processes of the command (its process group, ``spawn_main``) that
        are ready: their initializer left SIGINT and SIGHUP to the parent (``SigIgn``)."""
        found = []
        want = (1 << (signal.SIGINT - 1)) | (1 << (signal.SIGHUP - 1))
        for pid in _group(self.pgid):
            try:
                with open(f"/proc/{pid}/cmdline", "rb") as fh:
                    if b"spawn_main" not in fh.read():
                        continue
                with open(f"/proc/{pid}/status") as fh:
                    ign = next(int(ln.split()[1], 16) for ln in fh if ln.startswith("SigIgn:"))
            except (OSError, StopIteration, ValueError):
                continue
            if ign & want == want:
                found.append(pid)
        return found

    def stop(self, sig, group: bool = False) -> int:
        """Send ``sig`` to the command (``group``: to its whole process group, as a terminal
        does: Ctrl-C, a closed terminal); wait for it to end."""
        if group:
            os.killpg(self.pgid, sig)
        else:
            os.kill(self.p.pid, sig)
        try:
            rc = self.p.wait(BOUND)
        except subprocess.TimeoutExpired:
            pytest.fail(f"the command did not end after {sig.name}:\n" + "".join(self.lines))
        self._t.join(5)
        return rc

    def error_lines(self) -> list[str]:
        return [ln.rstrip("\n") for ln in self.lines if ln.strip()]

    def cleanup(self) -> None:
        with _suppress():
            os.killpg(self.pgid, signal.SIGKILL)
        if self.p.poll() is None:
            self.p.wait(10)


class _suppress:
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return exc[0] is not None and issubclass(exc[0], OSError)


def _group(pgid: int) -> list[int]:
    """Live (not zombie) processes of process group ``pgid``."""
    pids = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat") as fh:
                fields = fh.read().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[2]) == pgid and fields[0] != "Z":
            pids.append(int(entry))
    return pids


def assert_group_gone(cmd: Command) -> None:
    """No process of the command's group is left (polled up to the bound)."""
    end = time.monotonic() + BOUND
    while True:
        try:
            os.killpg(cmd.pgid, 0)
        except ProcessLookupError:
            return
        if time.monotonic() > end:
            pytest.fail(f"processes left in the group of the command: {_group(cmd.pgid)}")
        time.sleep(0.05)


@pytest.fixture
def commands():
    started: list[Command] = []

    def start(args, cwd, env=None):
        c = Command(args, cwd, env)
        started.append(c)
        return c

    yield start
    for c in started:
        c.cleanup()


def stopped_line(sig) -> str:
    return ("error: interrupted (SIGINT)" if sig == signal.SIGINT
            else f"error: stopped by {sig.name}")


def check_stopped(cmd: Command, sig, out: Path, rc: int) -> None:
    """One line, exit code 128 + sig, nothing left running, the folder marked with why."""
    assert rc == 128 + sig, "".join(cmd.lines)
    lines = cmd.error_lines()
    assert len(lines) == 1 and lines[0].startswith(stopped_line(sig)), "\n".join(lines)
    assert "Traceback" not in "".join(cmd.lines)
    assert_group_gone(cmd)
    assert is_incomplete(out)
    why = "KeyboardInterrupt" if sig == signal.SIGINT else f"stopped by {sig.name}"
    assert "failed: " in (out / MARKER).read_text() and why in (out / MARKER).read_text()
    assert not (out / LOCK_NAME).exists()


# ------------------------------------------------------------------------------- signals
@pytest.mark.parametrize("sig", [signal.SIGHUP, signal.SIGTERM, signal.SIGINT])
def test_simulate_stopped_by_a_signal_is_one_line_and_leaves_the_folder_marked(
        sig, tmp_path, commands):
    out = tmp_path / "run"
    scen = tmp_path / "long.toml"
    scen.write_text(SIM.format(duration=LONG, record_dt="1 s"))
    cmd = commands(["simulate", scen, "--out", out], tmp_path)
    cmd.wait_for("the run to start", lambda: is_incomplete(out))
    check_stopped(cmd, sig, out, cmd.stop(sig))
    assert sorted(p.name for p in out.iterdir()) == [MARKER]  # no temporary, no lock


@pytest.mark.parametrize("sig", [signal.SIGHUP, signal.SIGINT])
def test_compare_controllers_j2_stopped_kills_its_workers_and_leaves_no_old_scores(
        sig, tmp_path, commands):
    out = tmp_path / "bench"
    out.mkdir()
    (out / "scores.json").write_text('{"the previous run": true}')
    (out / "index.html").write_text("previous report")
    argv = ["compare-controllers", "--suite", "smoke", "--builtin", "stiff-pi", "--builtin",
            "soft-torque", "--builtin", "softspeed", "-j", "2", "--out", out]
    cmd = commands(argv, tmp_path)
    # marked when it starts (not only when it writes): the previous scores are gone at once
    cmd.wait_for("the folder to be marked", lambda: is_incomplete(out)
                 and not (out / "scores.json").exists())
    cmd.wait_for("two workers", lambda: len(cmd.workers()) >= 2)
    # to the whole group, as a terminal does: the workers leave it to the parent (no traceback)
    check_stopped(cmd, sig, out, cmd.stop(sig, group=True))
    assert sorted(p.name for p in out.iterdir()) == [MARKER]


def test_a_second_run_on_a_folder_in_use_is_refused_with_one_line(tmp_path, commands, capsys):
    out = tmp_path / "bench"
    argv = ["compare-controllers", "--suite", "smoke", "--builtin", "stiff-pi", "--builtin",
            "soft-torque", "-j", "2", "--out", out]
    first = commands(argv, tmp_path)
    first.wait_for("the first run to start", lambda: is_incomplete(out))
    marker = (out / MARKER).read_text()
    assert main([str(a) for a in argv]) == 2  # the second run, in this process
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"error: output folder {out}: another downhole "
                                               f"run (pid {first.p.pid}) is writing it"), err
    assert (out / MARKER).read_text() == marker  # the first run's folder is untouched
    check_stopped(first, signal.SIGTERM, out, first.stop(signal.SIGTERM))
    # the lock ended with its run: the folder can be taken again
    folder = OutputFolder(out, ("scores.json",), "test").begin()
    folder.commit()
    assert not is_incomplete(out)


def test_sweep_on_two_processes_stopped_by_sigterm_kills_its_workers(tmp_path, commands):
    out = tmp_path / "sweep"
    scen = tmp_path / "s.toml"
    scen.write_text(SIM.format(duration=LONG, record_dt="1 s"))
    cmd = commands(["sweep", scen, "--param", "operation.surface_speed=5:10:4", "--metric",
                    "mean_wob", "--processes", "2", "--no-plots", "--out", out], tmp_path)
    cmd.wait_for("the folder to be marked", lambda: is_incomplete(out))
    cmd.wait_for("two workers", lambda: len(cmd.workers()) >= 2)
    check_stopped(cmd, signal.SIGTERM, out, cmd.stop(signal.SIGTERM))


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGHUP])
def test_sil_stopped_writes_the_rows_so_far_and_leaves_nothing_running(sig, tmp_path, commands):
    from downhole.sil import load_chunks

    out = tmp_path / "run.nc"
    scen = tmp_path / "sil.toml"
    scen.write_text(SIL.format(duration="600 s"))
    cmd = commands(["sil", scen, "--unpaced", "--out", out], tmp_path)
    cmd.wait_for("the first chunk", lambda: (tmp_path / "chunks" / "chunk_000001.npz").exists())
    rc = cmd.stop(sig)
    assert rc == 128 + sig, "".join(cmd.lines)
    assert_group_gone(cmd)
    res = load_result(out)  # the partial recording, readable
    # at least the first chunk (20 s: its last row is one record step before 20 s)
    assert res.attrs["stopped_by"] == sig.name and 19.99 <= res.time[-1] < 600.0
    np.testing.assert_array_equal(load_chunks(tmp_path / "chunks").time, res.time)


PLUGIN = """
import time
from downhole.experiments import experiment, _REGISTRY

for _i in (1, 2):
    if f"survival.slow{_i}" not in _REGISTRY:
        @experiment(f"survival.slow{_i}", title="writes its data, then works", chapter=2,
                    claim="it never finishes here")
        def _slow(out_dir, quick):
            (out_dir / "data.csv").write_text("1\\n")
            time.sleep(600)
            return {"measured": {}, "passed": True}
"""


@pytest.mark.parametrize("jobs, sig", [(1, signal.SIGHUP), (2, signal.SIGTERM)])
def test_reproduce_stopped_leaves_its_experiments_marked_and_no_worker(jobs, sig, tmp_path,
                                                                      commands):
    (tmp_path / "survival_plugin.py").write_text(PLUGIN)
    out = tmp_path / "repro"
    ids = ["survival.slow1", "survival.slow2"]
    cmd = commands(["reproduce", *ids, "--jobs", jobs, "--out", out], tmp_path,
                   {"DOWNHOLE_EXPERIMENT_PLUGINS": "survival_plugin"})
    running = lambda: list(out.glob(".survival.slow*.staging-*/survival.slow*/data.csv"))  # noqa: E731
    cmd.wait_for("an experiment to run", lambda: len(running()) >= jobs)
    if jobs > 1:
        cmd.wait_for("two workers", lambda: len(cmd.workers()) >= 2)
    check_stopped(cmd, sig, out, cmd.stop(sig))
    for eid in ids:  # stopped: marked, no claim
        assert sorted(p.name for p in (out / eid).iterdir()) == [MARKER]
    if jobs == 1:  # the stopped experiment's staging folder went with it
        assert not [p for p in out.iterdir() if ".staging-" in p.name]


# ------------------------------------------------------------------------------- full disk
def _enospc(path) -> OSError:
    return OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))


def test_a_full_disk_during_a_sil_run_is_one_line_and_the_chunks_so_far_load(
        tmp_path, capsys, monkeypatch):
    """The third chunk finds the disk full: exit 1 with one line; chunks 1 and 2 load, the
    chunk folder and --out say why in their markers, no temporary is left."""
    from downhole.sil import load_chunks
    from downhole.sil import recorder as rec_mod

    real = np.savez
    calls = []

    def savez(file, *args, **kwargs):
        calls.append(file)
        if len(calls) >= 3:
            raise _enospc(file)
        return real(file, *args, **kwargs)

    monkeypatch.setattr(rec_mod.np, "savez", savez)
    scen = tmp_path / "sil.toml"
    scen.write_text(SIL.format(duration="100 s"))
    out = tmp_path / "run.nc"
    rc = main(["sil", str(scen), "--unpaced", "--no-progress", "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    chunks = tmp_path / "chunks"
    assert rc == 1, err
    assert err == [f"error: No space left on device: {chunks / 'chunk_000003.npz'} (free some "
                   "space or choose another --out)"], err
    part = load_chunks(chunks)
    assert part.attrs["incomplete"] == 1 and part.time.size == 20_000
    assert "failed: OSError" in (chunks / MARKER).read_text()
    assert "chunks 1 to 2 are complete" in (chunks / MARKER).read_text()
    assert not out.exists() and "failed: OSError" in (tmp_path / "run.nc.INCOMPLETE").read_text()
    assert sorted(p.name for p in chunks.iterdir()) == [MARKER, "channels.json",
                                                        "chunk_000001.npz", "chunk_000002.npz"]


def test_a_full_disk_while_simulate_writes_is_one_line_and_the_folder_marked(
        tmp_path, capsys, monkeypatch):
    """``result.nc`` is written, then ``summary.json`` finds the disk full."""
    real = os.fdopen

    class Full:
        def __init__(self, f, name):
            self.f, self.name = f, name

        def write(self, data):
            raise _enospc(self.name)

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            self.f.close()

    def fdopen(fd, *args, **kwargs):
        f = real(fd, *args, **kwargs)
        name = os.readlink(f"/proc/self/fd/{fd}")
        return Full(f, name) if ".summary.part-" in name else f

    monkeypatch.setattr(os, "fdopen", fdopen)
    scen = tmp_path / "s.toml"
    scen.write_text(SIM.format(duration="1 s", record_dt="10 ms"))
    out = tmp_path / "run"
    assert main(["simulate", str(scen), "--out", str(out)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"error: No space left on device: {out / 'summary.json'} (free some space or "
                   "choose another --out)"], err
    assert is_incomplete(out) and "failed: OSError" in (out / MARKER).read_text()
    assert sorted(p.name for p in out.iterdir()) == [MARKER, "result.nc"]  # no temporary
    assert load_result(out / "result.nc").time[-1] == pytest.approx(1.0)  # what was written


# ------------------------------------------------------------------------------- links
def test_a_link_planted_at_the_old_las_temporary_is_not_followed(tmp_path):
    from downhole.io import write_las

    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    out = tmp_path / "run.las"
    (tmp_path / "run.las.part").symlink_to(victim)  # the fixed name the LAS writer used
    write_las(Result(np.arange(3.0), {"bit_angular_velocity": np.ones(3)}), out)
    assert victim.read_text() == "precious"
    assert out.is_file() and not out.is_symlink() and "~A" in out.read_text()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.las", "run.las.part",
                                                          "victim.txt"]


def test_a_link_planted_at_a_staging_folder_name_is_not_followed(tmp_path, monkeypatch):
    """reproduce's staging folder has a random name made by an exclusive mkdir."""
    from downhole.experiments import _REGISTRY, experiment
    from downhole.report.reproduce import run_one

    @experiment("survival.tiny", title="writes one file", chapter=2, claim="it writes")
    def _tiny(out_dir, quick):
        (out_dir / "data.csv").write_text("1\n")
        return {"measured": {"n": 1}, "passed": True}

    monkeypatch.setitem(_REGISTRY, "survival.tiny", _REGISTRY.pop("survival.tiny"))  # undone
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    out = tmp_path / "out"
    out.mkdir()
    (out / f".survival.tiny.staging-{os.getpid()}").symlink_to(elsewhere)  # the old name
    claim = run_one("survival.tiny", out, quick=True)
    assert claim["passed"]
    assert list(elsewhere.iterdir()) == []
    assert (out / "survival.tiny" / "data.csv").read_text() == "1\n"
    assert not is_incomplete(out / "survival.tiny")


@pytest.mark.parametrize("command", ["compare-controllers", "sweep"])
def test_a_symlinked_out_is_refused_with_one_line(command, tmp_path, capsys):
    real = tmp_path / "real"
    real.mkdir()
    link = tmp_path / "link"
    link.symlink_to(real)
    scen = tmp_path / "s.toml"
    scen.write_text(SIM.format(duration="1 s", record_dt="10 ms"))
    argv = {"compare-controllers": ["compare-controllers", "--suite", "smoke", "--out", link],
            "sweep": ["sweep", scen, "--param", "operation.surface_speed=5:10:2", "--metric",
                      "mean_wob", "--processes", "1", "--out", link]}[command]
    assert main([str(a) for a in argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"error: --out {link}: is a symbolic link"), err
    assert list(real.iterdir()) == []


def test_bench_marks_its_report_when_it_starts_and_a_stop_leaves_no_old_report(
        tmp_path, capsys, monkeypatch):
    """``bench`` removes the previous report and marks ``FILE.INCOMPLETE`` before the first
    case; a stop (SIGTERM, here raised where a case runs) is one line and keeps the marker."""
    import downhole.bench as bench_mod
    from downhole._workers import StopRequested

    out = tmp_path / "bench.json"
    out.write_text('{"the previous run": true}')
    seen = {}

    def run_bench(**kwargs):
        seen["marked"] = (tmp_path / "bench.json.INCOMPLETE").exists()
        seen["old report gone"] = not out.exists()
        raise StopRequested(signal.SIGTERM)

    monkeypatch.setattr(bench_mod, "run_bench", run_bench)
    name = bench_mod.all_cases()[0].name
    assert main(["bench", "--case", name, "--out", str(out)]) == 128 + signal.SIGTERM
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: stopped by SIGTERM"), err
    assert seen == {"marked": True, "old report gone": True}
    assert "stopped by SIGTERM" in (tmp_path / "bench.json.INCOMPLETE").read_text()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bench.json.INCOMPLETE"]
