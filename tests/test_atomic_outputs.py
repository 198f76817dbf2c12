"""Atomic outputs and kill-safety of every command that writes, and ``--out`` checked first.

Each kill test prepares the previous run's result in the output folder, starts a new run into the
same folder as a subprocess, kills it (``kill -9`` or SIGTERM) either mid-run (once the folder is
marked ``INCOMPLETE``) or mid-write (the test-only pause of :mod:`downhole._atomic` between the
fsync of a temporary file and its rename), and checks that

- every file under a final name loads, and comes from one run only;
- nothing of the previous run is left looking fresh (its files are gone, the marker is there);
- a following run cleans up and completes.

The bad ``--out`` cases run in-process: exit code 2, one line naming the option and the path,
nothing printed on standard output (no work started) and nothing created.

The fast suite kills each command once (simulate twice: kill -9 mid-run, SIGTERM mid-write) and
SIGTERMs a SIL run; the other kill cases (every command both ways, reruns after a kill, SIGTERM
of ``sil`` while writing or waiting) are marked slow (``make test-slow``): each subprocess costs
seconds on 2 shared cores.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import downhole
from downhole._atomic import (
    MARKER,
    PAUSE_ENV,
    OutputFile,
    OutputFolder,
    atomic_path,
    check_output_path,
    is_incomplete,
    temp_path,
    write_json_atomic,
    write_text_atomic,
)
from downhole.cli import main
from downhole.errors import DownholeInputError
from downhole.sim.result import Result, load_result

ROOT = Path(downhole.__file__).resolve().parents[1]
WAIT = 180.0  # s: upper bound of any wait (a loaded 2-core machine); normally a few seconds

SIM = """
title = "{title}"
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
LONG = "100000 s"  # hours of simulated time: the kill comes long before the end

DP = """
[model]
fidelity = "lumped4"
preset = "table_2_1"
[optimize]
horizon = 5.0
step = 0.25
[optimize.x2]
min = 0.0
max = 0.02
points = 11
[optimize.x4]
min = 0.0
max = 20.0
points = 11
[optimize.targets]
v_m = 0.01
w_m = 10.0
v_d = 0.01
w_d = 10.0
[optimize.weights]
lambda1 = 1.0e4
lambda2 = 1.0e-2
lambda3 = 1.0e5
lambda4 = 1.0e-1
[optimize.bounds]
force = [0.0, 200.0e3]
torque = [0.0, 30.0e3]
"""

SIL = """
title = "atomic-output test, lumped plant"
[model]
fidelity = "lumped4"
[simulation]
dt = "1 ms"
duration = "{duration}"
record_dt = "10 ms"
{extra}
[controller]
type = "pi"
"""

PLUGIN = textwrap.dedent('''
    """Experiments of the kill tests (registered through $DOWNHOLE_EXPERIMENT_PLUGINS)."""
    import time
    from downhole.experiments import experiment, _REGISTRY

    if "atomic.slow" not in _REGISTRY:
        @experiment("atomic.slow", title="writes its data, then works for a while", chapter=2,
                    claim="the data is 1, 2, 3")
        def _slow(out_dir, quick):
            (out_dir / "data.csv").write_text("1\\n2\\n3\\n")
            time.sleep(float(__import__("os").environ.get("ATOMIC_TEST_SLEEP", "0")))
            return {"measured": {"n": 3}, "passed": True}
''')


# ------------------------------------------------------------------------------- helpers
class Proc:
    """A ``downhole`` command in a subprocess; stderr collected by a thread, line by line."""

    def __init__(self, args, cwd, env=None):
        full_env = dict(os.environ)
        full_env["PYTHONPATH"] = os.pathsep.join(
            [str(ROOT)] + [p for p in full_env.get("PYTHONPATH", "").split(os.pathsep) if p])
        full_env.setdefault("MPLBACKEND", "Agg")
        full_env.update(env or {})
        self.p = subprocess.Popen(
            [sys.executable, "-c", "import sys; from downhole.cli import main; "
             "sys.exit(main(sys.argv[1:]))", *map(str, args)],
            cwd=cwd, env=full_env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        self.lines: list[str] = []
        self._t = threading.Thread(target=self._read, daemon=True)
        self._t.start()

    def _read(self):
        for line in self.p.stderr:
            self.lines.append(line)

    def wait_for(self, what, pred, timeout=WAIT):
        t_end = time.monotonic() + timeout
        while time.monotonic() < t_end:
            if pred():
                return
            if self.p.poll() is not None:
                self._t.join(5)
                pytest.fail(f"the command ended (rc {self.p.returncode}) before {what}:\n"
                            + "".join(self.lines))
            time.sleep(0.02)
        self.kill()
        pytest.fail(f"timed out waiting for {what}:\n" + "".join(self.lines))

    def wait_for_pause(self, name):
        self.wait_for(f"the pause before renaming {name}",
                      lambda: any("downhole-test: paused before rename" in ln and name in ln
                                  for ln in self.lines))

    def signal(self, sig) -> int:
        self.p.send_signal(sig)
        try:
            rc = self.p.wait(WAIT)
        except subprocess.TimeoutExpired:
            self.kill()
            pytest.fail("the command did not end after the signal")
        self._t.join(5)
        return rc

    def finish(self) -> int:
        rc = self.p.wait(WAIT)
        self._t.join(5)
        return rc

    def kill(self):
        if self.p.poll() is None:
            self.p.kill()
            self.p.wait(10)


@pytest.fixture
def procs():
    started: list[Proc] = []
    yield started
    for p in started:
        p.kill()


def start(procs, args, cwd, env=None) -> Proc:
    p = Proc(args, cwd, env)
    procs.append(p)
    return p


def pause(name: str) -> dict:
    return {PAUSE_ENV: f"{name}:{WAIT}"}


def final_files(folder: Path) -> list[str]:
    """Names under which a command publishes results (no hidden temporaries, no marker)."""
    return sorted(p.name for p in folder.iterdir() if not p.name.startswith(".")
                  and p.name != MARKER)


def marked_and_cleared(folder: Path) -> bool:
    """The run has started: the folder is marked INCOMPLETE and its old results are gone (a
    kill between the two leaves the marker beside them, which the kill tests do not cover)."""
    return (folder / MARKER).exists() and not final_files(folder)


def old_result(folder: Path, title="OLD RUN") -> None:
    """The previous run's simulate output, written with the library's own writers."""
    folder.mkdir(parents=True, exist_ok=True)
    t = np.arange(5.0)
    Result(t, {"bit_angular_velocity": np.ones(5)}, attrs={"scenario": title}).save(
        folder / "result.nc")
    write_json_atomic(folder / "summary.json", {"title": title})
    write_text_atomic(folder / "overview.png", "old figure")


# ------------------------------------------------------------------------------- the utility
def test_atomic_path_replaces_only_on_success_and_keeps_the_suffix(tmp_path):
    final = tmp_path / "a.npz"
    final.write_text("previous")
    name = temp_path(final).name
    assert name.startswith(f".a.part-{os.getpid()}-") and name.endswith(".npz")
    assert temp_path(final) != temp_path(final)  # 64 random bits: a fresh name every time
    with pytest.raises(RuntimeError, match="writer broke"), atomic_path(final) as tmp:
        tmp.write_text("half")
        raise RuntimeError("writer broke")
    assert final.read_text() == "previous"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.npz"]  # temporary removed
    with atomic_path(final) as tmp:
        np.savez(tmp, x=np.arange(3))  # savez keeps a name that ends in .npz
    with np.load(final) as z:
        assert z["x"].tolist() == [0, 1, 2]
    with pytest.raises(RuntimeError, match="produced no file"), atomic_path(tmp_path / "b.txt"):
        pass
    assert not (tmp_path / "b.txt").exists()


def test_output_folder_marks_removes_stale_files_and_commits(tmp_path):
    d = tmp_path / "run"
    old_result(d)
    (d / "notes.txt").write_text("the user's own file")
    (d / ".result.part-99999.nc").write_text("left by a killed run")
    f = OutputFolder(d, ("result.nc", "summary.json", "overview.png"), "simulate").begin()
    assert is_incomplete(d)
    assert "simulate: started" in (d / MARKER).read_text()
    assert final_files(d) == ["notes.txt"]  # stale results and temporaries gone, the rest kept
    assert not (d / ".result.part-99999.nc").exists()
    f.fail("SimulationDiverged: boom")
    assert "failed: SimulationDiverged: boom" in (d / MARKER).read_text()
    f.writing()
    f.commit()
    assert not is_incomplete(d)


def test_output_folder_is_marked_when_the_run_starts_and_keeps_why_it_failed(tmp_path):
    d = tmp_path / "new"
    with pytest.raises(ZeroDivisionError), OutputFolder(d, ("x",), "t"):
        assert is_incomplete(d)  # marked at the start, before any file is written
        raise ZeroDivisionError("the run failed")
    assert is_incomplete(d) and "failed: ZeroDivisionError: the run failed" in (
        d / MARKER).read_text()
    assert sorted(p.name for p in d.iterdir()) == [MARKER]  # the lock went with the run


def test_a_second_run_on_a_locked_folder_is_refused_and_the_first_is_untouched(tmp_path):
    d = tmp_path / "run"
    first = OutputFolder(d, ("result.nc",), "simulate").begin()
    write_text_atomic(d / "result.nc", "first run")
    with pytest.raises(DownholeInputError,
                       match=rf"output folder {d}: another downhole run \(pid {os.getpid()}\)"):
        OutputFolder(d, ("result.nc",), "simulate").begin()
    assert (d / "result.nc").read_text() == "first run"  # the refused run removed nothing
    first.commit()
    assert sorted(p.name for p in d.iterdir()) == ["result.nc"]
    with OutputFolder(d, ("result.nc",), "simulate"):  # free again once the first one ended
        pass
    f1 = OutputFile(tmp_path / "one.nc", "sil").begin()
    with pytest.raises(DownholeInputError, match="output file .*one.nc: another downhole run"):
        OutputFile(tmp_path / "one.nc", "sil").begin()
    f1.commit()


def test_a_lock_dies_with_its_process(tmp_path):
    d = tmp_path / "run"
    code = ("import sys, time; from downhole._atomic import OutputFolder; "
            f"OutputFolder({str(d)!r}, ('x',), 't').begin(); print('locked', flush=True); "
            "time.sleep(600)")
    p = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    try:
        assert p.stdout.readline().strip() == "locked"
        with pytest.raises(DownholeInputError, match=f"another downhole run \\(pid {p.pid}\\)"):
            OutputFolder(d, ("x",), "t").begin()
    finally:
        p.kill()
        p.wait()
    OutputFolder(d, ("x",), "t").begin().commit()  # kill -9 released it


def test_planted_links_are_never_followed(tmp_path):
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    d = tmp_path / "shared"
    d.mkdir()
    # links at every name the old, predictable scheme would have used, and at the lock
    for pid in {os.getpid(), os.getppid(), 1}:
        (d / f".summary.part-{pid}.json").symlink_to(victim)
    write_json_atomic(d / "summary.json", {"a": 1})
    assert victim.read_text() == "precious"
    assert json.loads((d / "summary.json").read_text()) == {"a": 1}
    (d / ".downhole.lock").symlink_to(victim)
    with pytest.raises(OSError):  # O_NOFOLLOW: the lock is not taken through a link
        OutputFolder(d, ("summary.json",), "t").begin()
    assert victim.read_text() == "precious"
    # a temporary swapped for a link before its rename is not renamed
    with pytest.raises(RuntimeError, match="not a regular file"), \
            atomic_path(d / "x.txt") as tmp:
        tmp.unlink()
        tmp.symlink_to(victim)
    assert not (d / "x.txt").exists() and victim.read_text() == "precious"


def test_a_symlinked_out_is_refused(tmp_path):
    real = tmp_path / "real"
    real.mkdir()
    link = tmp_path / "link"
    link.symlink_to(real)
    with pytest.raises(DownholeInputError, match=r"--out .*link: is a symbolic link \(to "):
        check_output_path(link)
    with pytest.raises(DownholeInputError, match="is a symbolic link"):
        check_output_path(tmp_path / "dangling", kind="file") if (
            (tmp_path / "dangling").symlink_to(tmp_path / "nowhere") or True) else None


def test_output_file_marker(tmp_path):
    out = tmp_path / "run.nc"
    out.write_text("old")
    f = OutputFile(out, "sil").begin()
    assert not out.exists() and (tmp_path / "run.nc.INCOMPLETE").exists()
    write_text_atomic(out, "new")
    f.commit()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.nc"]


@pytest.mark.parametrize("case", ["file as folder", "under a file", "folder as file",
                                  "missing parent", "empty", "not writable"])
def test_check_output_path_errors(case, tmp_path):
    afile = tmp_path / "afile"
    afile.write_text("x")
    adir = tmp_path / "adir"
    adir.mkdir()
    path, kind, expect = {
        "file as folder": (afile, "folder", "is an existing file, expected a folder"),
        "under a file": (afile / "sub" / "run.nc", "file", f"{afile} is a file, not a folder"),
        "folder as file": (adir, "file", "is an existing folder, expected a file name"),
        "missing parent": (tmp_path / "nodir" / "run.nc", "file", "does not exist"),
        "empty": ("", "folder", "empty path"),
        "not writable": (adir / "x" / "y", "folder", "is not writable"),
    }[case]
    if case == "not writable":
        if os.geteuid() == 0:
            pytest.skip("root can write into a read-only folder")
        adir.chmod(0o500)
    try:
        with pytest.raises(DownholeInputError, match=expect) as info:
            check_output_path(path, option="--out", kind=kind)
    finally:
        adir.chmod(0o700)
    assert str(info.value).startswith(f"--out {path}".rstrip())
    # a missing folder (created with its parents) and an existing file to overwrite are fine
    assert check_output_path(tmp_path / "a" / "b", kind="folder") == tmp_path / "a" / "b"
    assert check_output_path(afile, kind="file") == afile


# ------------------------------------------------------------------------------- bad --out
def _scenarios(tmp_path):
    sim = tmp_path / "sim.toml"
    sim.write_text(SIM.format(title="new", duration="1 s", record_dt="10 ms"))
    dp = tmp_path / "dp.toml"
    dp.write_text(DP)
    sil = tmp_path / "sil.toml"
    sil.write_text(SIL.format(duration="1 s", extra=""))
    return sim, dp, sil


@pytest.mark.parametrize("command", ["simulate", "optimize", "sweep", "reproduce", "sil",
                                     "design eid", "design dhp", "export --csv",
                                     "export --las", "export-fmu", "demo", "bench",
                                     "bench-report"])
@pytest.mark.parametrize("problem", ["existing file", "under a file", "missing parent"])
def test_bad_out_exits_2_before_any_work(command, problem, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    sim, dp, sil = _scenarios(tmp_path)
    afile = tmp_path / "afile"
    afile.write_text("not a folder")
    file_out = command in ("sil", "export --csv", "export --las", "export-fmu", "bench",
                           "bench-report")
    if problem == "existing file":
        if file_out:
            out = tmp_path / "adir"  # a folder where a file is expected
            out.mkdir()
        else:
            out = afile
    elif problem == "under a file":
        out = afile / "run"
    else:
        if not file_out or command.startswith("bench"):
            pytest.skip("created with its missing parent folders")
        out = tmp_path / "nodir" / "run.out"
    res = tmp_path / "r.nc"
    Result(np.arange(3.0), {"bit_angular_velocity": np.ones(3)}).save(res)
    before = sorted(p.name for p in tmp_path.rglob("*"))
    argv = {
        "simulate": ["simulate", sim, "--out", out],
        "optimize": ["optimize", "dp", dp, "--out", out],
        "sweep": ["sweep", sim, "--param", "operation.surface_speed=5:10:2", "--metric",
                  "mean_wob", "--processes", "1", "--out", out],
        "reproduce": ["reproduce", "fig2.3", "--quick", "--jobs", "1", "--out", out],
        "sil": ["sil", sil, "--unpaced", "--out", out],
        "design eid": ["design", "eid", ROOT / "examples" / "eid_nominal.toml", "--out", out],
        "design dhp": ["design", "dhp", ROOT / "examples" / "dhp_lumped.toml", "--out", out],
        "bench": ["bench", "--quick", "--out", out],
        "bench-report": ["bench-report", res, "--out", out],
        "export --csv": ["export", res, "--csv", out],
        "export --las": ["export", res, "--las", out],
        "export-fmu": ["export-fmu", sil, "--out", out],
        "demo": ["demo", "--out", out],
    }[command]
    option = "--csv" if command == "export --csv" else "--las" if command == "export --las" \
        else "--out"
    assert main([str(a) for a in argv]) == 2
    cap = capsys.readouterr()
    assert cap.out == ""  # no progress, no table: nothing ran
    err = cap.err.strip()
    assert len(err.splitlines()) == 1, err
    assert err.startswith(f"error: {option} {out}"), err
    assert sorted(p.name for p in tmp_path.rglob("*")) == before  # nothing written


# ------------------------------------------------------------------------------- simulate
def test_simulate_killed_mid_run_leaves_no_stale_result(tmp_path, procs):
    out = tmp_path / "run"
    old_result(out)
    scen = tmp_path / "long.toml"
    scen.write_text(SIM.format(title="NEW RUN", duration=LONG, record_dt="1 s"))
    p = start(procs, ["simulate", scen, "--out", out], tmp_path)
    p.wait_for("the run to start", lambda: marked_and_cleared(out))
    time.sleep(0.5)  # well into the simulation (it runs for hours)
    p.signal(signal.SIGKILL)
    assert is_incomplete(out)
    assert final_files(out) == []  # the previous run's result, summary and figure are gone


def test_simulate_sigterm_mid_write_leaves_only_loadable_files_of_the_new_run(tmp_path, procs):
    out = tmp_path / "run"
    old_result(out)
    scen = tmp_path / "s.toml"
    scen.write_text(SIM.format(title="NEW RUN", duration="2 s", record_dt="10 ms"))
    p = start(procs, ["simulate", scen, "--out", out], tmp_path, pause("summary.json"))
    p.wait_for_pause("summary.json")
    assert p.signal(signal.SIGTERM) != 0
    assert is_incomplete(out)
    assert final_files(out) == ["result.nc"]  # the new result; its summary and figure never came
    assert "NEW RUN" in load_result(out / "result.nc").attrs["scenario"]


@pytest.mark.slow
def test_simulate_kill9_mid_rename_then_a_rerun_completes(tmp_path, procs):
    out = tmp_path / "run"
    old_result(out)
    scen = tmp_path / "s.toml"
    scen.write_text(SIM.format(title="NEW RUN", duration="2 s", record_dt="10 ms"))
    p = start(procs, ["simulate", scen, "--out", out], tmp_path, pause("result.nc"))
    p.wait_for_pause("result.nc")
    p.signal(signal.SIGKILL)
    assert is_incomplete(out) and final_files(out) == []
    assert any(n.startswith(".result.part-") for n in os.listdir(out))  # hidden temporary
    # the next run cleans up and completes
    assert main(["simulate", str(scen), "--out", str(out)]) == 0
    assert sorted(os.listdir(out)) == ["overview.png", "result.nc", "summary.json"]
    assert "NEW RUN" in load_result(out / "result.nc").attrs["scenario"]


# ------------------------------------------------------------------------------- optimize dp
def _dp(tmp_path):
    scen = tmp_path / "dp.toml"
    scen.write_text(DP)
    out = tmp_path / "dp"
    argv = ["optimize", "dp", scen, "--out", out, "--no-progress", "--no-replay"]
    assert main([str(a) for a in argv]) == 0  # the previous run's solution
    assert not is_incomplete(out)
    return out, argv, json.loads((out / "solution.json").read_text())


def test_optimize_dp_sigterm_between_the_pair_renames(tmp_path, procs):
    from downhole.control.dp import load_solution

    out, argv, old_json = _dp(tmp_path)
    first = load_solution(out)
    # SIGTERM between the npz rename and the json rename: the new npz, no json (old one gone)
    p = start(procs, argv, tmp_path, pause("solution.json"))
    p.wait_for_pause("solution.json")
    p.signal(signal.SIGTERM)
    assert is_incomplete(out)
    assert final_files(out) == ["solution.npz"]
    with np.load(out / "solution.npz", allow_pickle=False) as z:
        assert str(z["run_id"]) != old_json["run_id"]  # the new run's arrays, complete
        np.testing.assert_array_equal(z["x2"], first.x2)
    with pytest.raises(DownholeInputError, match="solution.json not found"):
        load_solution(out)


@pytest.mark.slow
def test_optimize_dp_kill9_mid_run_leaves_no_stale_pair(tmp_path, procs):
    out, argv, _ = _dp(tmp_path)
    big = tmp_path / "big.toml"  # a search of many seconds
    big.write_text(DP.replace("horizon = 5.0", "horizon = 40.0").replace("points = 11",
                                                                          "points = 81"))
    p = start(procs, [a if a != argv[2] else big for a in argv], tmp_path)
    p.wait_for("the run to start", lambda: marked_and_cleared(out))
    time.sleep(0.3)
    p.signal(signal.SIGKILL)
    assert is_incomplete(out) and final_files(out) == []


@pytest.mark.slow
def test_optimize_dp_kill9_mid_write_then_a_rerun_completes(tmp_path, procs):
    from downhole.control.dp import load_solution

    out, argv, old_json = _dp(tmp_path)
    p = start(procs, argv, tmp_path, pause("solution.npz"))
    p.wait_for_pause("solution.npz")
    p.signal(signal.SIGKILL)
    assert is_incomplete(out) and final_files(out) == []
    assert main([str(a) for a in argv]) == 0
    assert sorted(os.listdir(out)) == ["solution.json", "solution.npz", "solution.png"]
    assert load_solution(out).cost == pytest.approx(old_json["cost"])


def test_load_solution_refuses_a_pair_from_two_saves(tmp_path):
    from downhole.control.dp import load_problem, load_solution, solve

    scen = tmp_path / "dp.toml"
    scen.write_text(DP)
    sol = solve(load_problem(scen), "customized", progress=False)
    sol.save(tmp_path / "a")
    sol.save(tmp_path / "b")
    os.replace(tmp_path / "b" / "solution.npz", tmp_path / "a" / "solution.npz")
    with pytest.raises(DownholeInputError, match="two different saves"):
        load_solution(tmp_path / "a")


# ------------------------------------------------------------------------------- sweep
def _sweep(tmp_path, duration="1 s"):
    scen = tmp_path / "s.toml"
    scen.write_text(SIM.format(title="sweep", duration="1 s", record_dt="10 ms"))
    out = tmp_path / "sweep"
    argv = ["sweep", scen, "--param", "operation.surface_speed=5:10:2", "--metric", "mean_wob",
            "--processes", "1", "--no-plots", "--out", out]
    assert main([str(a) for a in argv]) == 0  # the previous run's results
    assert sorted(os.listdir(out)) == ["failed.json", "sweep.nc"]
    scen.write_text(SIM.format(title="sweep", duration=duration,
                               record_dt="1 s" if duration == LONG else "10 ms"))
    return out, argv


@pytest.mark.slow
def test_sweep_sigterm_mid_write_leaves_nothing_stale(tmp_path, procs):
    out, argv = _sweep(tmp_path)
    p = start(procs, argv, tmp_path, pause("sweep.nc"))
    p.wait_for_pause("sweep.nc")
    p.signal(signal.SIGTERM)
    assert is_incomplete(out) and final_files(out) == []


def test_sweep_kill9_mid_run_leaves_nothing_stale(tmp_path, procs):
    out, argv = _sweep(tmp_path, duration=LONG)
    p = start(procs, argv, tmp_path)
    p.wait_for("the run to start", lambda: marked_and_cleared(out))
    time.sleep(0.5)
    p.signal(signal.SIGKILL)
    assert is_incomplete(out) and final_files(out) == []


# ------------------------------------------------------------------------------- reproduce
@pytest.fixture
def plugin_env(tmp_path, monkeypatch):
    (tmp_path / "atomic_test_experiments.py").write_text(PLUGIN)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setenv("DOWNHOLE_EXPERIMENT_PLUGINS", "atomic_test_experiments")
    yield {"DOWNHOLE_EXPERIMENT_PLUGINS": "atomic_test_experiments",
           "PYTHONPATH": str(tmp_path) + os.pathsep + str(ROOT)}
    from downhole.experiments import _REGISTRY

    _REGISTRY.pop("atomic.slow", None)
    sys.modules.pop("atomic_test_experiments", None)


def _reproduce(tmp_path):
    out = tmp_path / "rep"
    argv = ["reproduce", "atomic.slow", "--jobs", "1", "--out", out]
    assert main([str(a) for a in argv]) == 0
    exp = out / "atomic.slow"
    assert json.loads((exp / "claim.json").read_text())["passed"] is True
    assert sorted(os.listdir(exp)) == ["claim.json", "data.csv", "run.log"]
    assert not is_incomplete(out) and (out / "reproduce.json").exists()
    return out, exp, argv


def test_reproduce_kill9_mid_run_leaves_no_old_claim(tmp_path, procs, plugin_env):
    out, exp, argv = _reproduce(tmp_path)
    p = start(procs, argv, tmp_path, {**plugin_env, "ATOMIC_TEST_SLEEP": str(WAIT)})
    p.wait_for("the experiment to start", lambda: any(
        n.startswith(".atomic.slow.staging-") for n in os.listdir(out)))
    p.signal(signal.SIGKILL)
    assert os.listdir(exp) == [MARKER]  # the old claim (passed) and its data are gone
    assert is_incomplete(out) and not (out / "reproduce.json").exists()
    assert not (out / "index.html").exists()


@pytest.mark.slow
def test_reproduce_sigterm_mid_write_then_a_rerun_publishes_one_run(tmp_path, procs,
                                                                      plugin_env):
    out, exp, argv = _reproduce(tmp_path)
    # SIGTERM while claim.json is renamed (in the staging folder): still no claim in OUT/ID
    p = start(procs, argv, tmp_path, {**plugin_env, **pause("claim.json")})
    p.wait_for_pause("claim.json")
    assert p.signal(signal.SIGTERM) == 128 + signal.SIGTERM
    assert os.listdir(exp) == [MARKER]
    # a clean stop removes its staging folder (kill -9 would leave it: see the next run)
    assert not any(".staging-" in n for n in os.listdir(out))
    # the next run removes the leftovers and publishes one consistent folder
    assert main([str(a) for a in argv]) == 0
    assert sorted(os.listdir(exp)) == ["claim.json", "data.csv", "run.log"]
    assert not any(".staging-" in n or ".old-" in n for n in os.listdir(out))
    assert not is_incomplete(out)


def test_run_one_on_its_own_replaces_the_whole_experiment_folder(tmp_path, plugin_env):
    from downhole.report.reproduce import run_one

    exp = tmp_path / "rep" / "atomic.slow"
    exp.mkdir(parents=True)
    (exp / "claim.json").write_text(json.dumps({"id": "atomic.slow", "passed": True, "old": 1}))
    (exp / "stale_figure.png").write_text("from an older version of the experiment")
    claim = run_one("atomic.slow", tmp_path / "rep", quick=True)
    assert claim["passed"] is True and claim["measured"] == {"n": 3}
    assert sorted(os.listdir(exp)) == ["claim.json", "data.csv", "run.log"]
    assert "old" not in json.loads((exp / "claim.json").read_text())
    assert sorted(os.listdir(tmp_path / "rep")) == ["atomic.slow"]  # no staging left


def test_reproduce_refuses_to_clear_a_folder_that_is_not_an_experiments(tmp_path, capsys):
    (tmp_path / "fig2.3").mkdir()
    (tmp_path / "fig2.3" / "thesis.tex").write_text("precious")
    assert main(["reproduce", "fig2.3", "--quick", "--jobs", "1", "--out", str(tmp_path)]) == 2
    assert "is not an experiment folder" in capsys.readouterr().err
    assert (tmp_path / "fig2.3" / "thesis.tex").read_text() == "precious"


# ------------------------------------------------------------------------------- sil
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP])
def test_sil_sigterm_writes_the_rows_recorded_so_far(tmp_path, procs, sig):
    """SIGTERM, and SIGHUP (a closed terminal, a dropped SSH session), stop the run and write
    what it recorded."""
    from downhole.sil import load_chunks

    out = tmp_path / "run.nc"
    Result(np.arange(3.0), {"bit_angular_velocity": np.ones(3)}).save(out)  # previous result
    chunks = tmp_path / "chunks"
    scen = tmp_path / "sil.toml"
    scen.write_text(SIL.format(duration="600 s", extra='record_dt = "2 ms"\n'
                               '[realtime]\nring_seconds = "600 s"\nchunk_dir = "chunks"')
                    .replace('record_dt = "10 ms"\n', ""))
    p = start(procs, ["sil", scen, "--unpaced", "--out", out], tmp_path)
    # the previous result goes when the run starts, after the marker is written
    p.wait_for("the run to start", lambda: (tmp_path / "run.nc.INCOMPLETE").exists()
               and not out.exists())
    # the loop runs: its first chunk of 10 000 rows is on disk
    p.wait_for("the first chunk", lambda: (chunks / "chunk_000001.npz").exists())
    rc = p.signal(sig)
    assert rc == 128 + sig, "".join(p.lines)
    res = load_result(out)
    assert res.attrs["stopped_by"] == sig.name
    n = res.time.size
    # at least the first chunk (the signal may land right after it: then it is all there is)
    assert 10_000 <= n and 19.99 < res.time[-1] < 600
    np.testing.assert_allclose(np.diff(res.time), 0.002, rtol=1e-6)
    assert not (tmp_path / "run.nc.INCOMPLETE").exists()
    # the chunk files hold every row (a partial chunk was flushed) and are marked complete
    full = load_chunks(chunks)
    expected = [f"chunk_{i:06d}.npz" for i in range(1, -(-n // 10_000) + 1)]
    assert sorted(q.name for q in chunks.glob("chunk_*.npz")) == expected
    assert full.time.size == n and "incomplete" not in full.attrs
    np.testing.assert_array_equal(full.time, res.time)


@pytest.mark.slow
def test_sil_sigterm_while_writing_still_writes_the_result(tmp_path, procs):
    out = tmp_path / "run.nc"
    scen = tmp_path / "sil.toml"
    scen.write_text(SIL.format(duration="0.5 s", extra=""))
    p = start(procs, ["sil", scen, "--unpaced", "--out", out], tmp_path,
              {PAUSE_ENV: "run.nc:2"})
    p.wait_for_pause("run.nc")
    assert p.signal(signal.SIGTERM) == 128 + signal.SIGTERM
    res = load_result(out)  # the signal came after the run: the whole run is in the result
    assert res.time[-1] == pytest.approx(0.5) and "stopped_by" not in res.attrs
    assert sorted(os.listdir(tmp_path)) == ["run.nc", "sil.toml"]


@pytest.mark.slow
def test_sil_sigterm_while_waiting_for_the_controller_writes_nothing(tmp_path, procs):
    from downhole.sil.testing import free_port

    out = tmp_path / "run.nc"
    out.write_text("previous result")
    scen = tmp_path / "sil.toml"
    scen.write_text(SIL.format(duration="5 s", extra=""))
    p = start(procs, ["sil", scen, "--remote", "--port", free_port(), "--out", out], tmp_path)
    p.wait_for("the plant to listen", lambda: any("waiting for the" in ln for ln in p.lines))
    assert p.signal(signal.SIGTERM) == 128 + signal.SIGTERM
    assert "(SIGTERM) while waiting for the controller; nothing recorded or written" in "".join(p.lines)
    assert out.read_text() == "previous result"  # no run: the previous result stays as it was
    assert sorted(os.listdir(tmp_path)) == ["run.nc", "sil.toml"]


@pytest.mark.slow
def test_sil_kill9_mid_write_leaves_no_stale_result(tmp_path, procs):
    from downhole.sil import load_chunks

    out = tmp_path / "run.nc"
    out.write_text("previous result")
    chunks = tmp_path / "chunks"
    scen = tmp_path / "sil.toml"
    scen.write_text(SIL.format(duration="0.5 s", extra='[realtime]\nchunk_dir = "chunks"'))
    p = start(procs, ["sil", scen, "--unpaced", "--out", out], tmp_path, pause("run.nc"))
    p.wait_for_pause("run.nc")
    p.signal(signal.SIGKILL)
    assert not out.exists() and (tmp_path / "run.nc.INCOMPLETE").exists()
    assert load_chunks(chunks).time.size == 51  # chunks written atomically before the result


@pytest.mark.slow
def test_sil_kill9_mid_run_leaves_no_stale_result_and_no_stale_chunks(tmp_path, procs):
    out = tmp_path / "run.nc"
    out.write_text("previous result")
    chunks = tmp_path / "chunks"
    chunks.mkdir()
    (chunks / "chunk_000001.npz").write_text("a chunk of the previous run")
    scen = tmp_path / "sil.toml"
    scen.write_text(SIL.format(duration="600 s", extra='[realtime]\nchunk_dir = "chunks"'))
    p = start(procs, ["sil", scen, "--out", out], tmp_path)
    p.wait_for("the run to start", lambda: (tmp_path / "run.nc.INCOMPLETE").exists()
               and not out.exists())
    time.sleep(1.0)
    p.signal(signal.SIGKILL)
    assert not out.exists() and (tmp_path / "run.nc.INCOMPLETE").exists()
    assert (chunks / MARKER).exists()
    assert not list(chunks.glob("chunk_*.npz"))  # the previous run's chunks were removed


def test_a_run_refused_for_its_input_leaves_no_folder_it_created(tmp_path):
    d = tmp_path / "new"
    with pytest.raises(DownholeInputError), OutputFolder(d, ("x",), "t"):
        assert is_incomplete(d)
        raise DownholeInputError("bad field")
    assert not d.exists()
    d.mkdir()  # an existing folder keeps its marker and the reason
    with pytest.raises(DownholeInputError), OutputFolder(d, ("x",), "t"):
        raise DownholeInputError("bad field")
    assert "failed: DownholeInputError: bad field" in (d / MARKER).read_text()
