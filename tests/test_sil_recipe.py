"""The UDP recipe of docs/sil.md and code only on request (issue 16, items 7 and 10).

- ``downhole sil SCENARIO --remote`` + ``downhole sil-controller --scenario SCENARIO`` works in
  either start order: the controller builds (designs) before it sends anything, the plant waits
  with a countdown for ``[link] connect_timeout`` / ``--wait``; both give up with a clear
  error; a controller that got nothing to answer exits 1. The full DHP recipe is a slow test.
- A Python controller file runs only with ``--allow-code`` (``allow_code=True`` from Python):
  the test's file would create a marker file if it were executed.
- The countdown and the run progress line, with a fake clock and a fake runner.
"""

import io
import json
import os
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from downhole.cli import main
from downhole.errors import DownholeInputError
from downhole.sil.console import RunProgress, ServeProgress, format_seconds, wait_with_countdown
from downhole.sil.testing import free_port

EXAMPLE = Path(__file__).resolve().parent.parent / "examples" / "sil_dhp_hybrid68.toml"
CLI = [sys.executable, "-c", "import sys; from downhole.cli import main; "
       "sys.exit(main(sys.argv[1:]))"]


def _start(*args, cwd=None):
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    return subprocess.Popen([*CLI, *map(str, args)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, cwd=cwd, env=env)


def _finish(proc, timeout=120):
    try:
        out, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        out, err = proc.communicate()
        raise AssertionError(f"timed out:\n{err[-3000:]}") from None
    return proc.returncode, out, err


def _pi_scenario(tmp_path, port, duration="1 s", extra=""):
    sc = tmp_path / "pi.toml"
    sc.write_text(f'[model]\nfidelity = "hybrid"\npreset = "hybrid68"\n[simulation]\n'
                  f'duration = "{duration}"\n[controller]\ntype = "pi"\n[link]\nport = {port}\n'
                  f'{extra}')
    return sc


# ------------------------------------------------------------------ countdown and progress
class _Clock:
    def __init__(self):
        self.t = 100.0

    def __call__(self):
        return self.t


def test_countdown_shows_the_time_left_and_stops_when_ready():
    clock, out, calls = _Clock(), io.StringIO(), []

    def attempt(s):
        calls.append(s)
        clock.t += s
        return len(calls) == 7

    assert wait_with_countdown(attempt, 60, what="the controller", out=out, slice_s=2.0,
                               every=5.0, clock=clock, interactive=False)
    lines = out.getvalue().splitlines()
    assert calls == [2.0] * 7
    # a line at once, then every 5 s (of the fake clock), then the outcome
    assert lines[0] == "waiting for the controller: 1:00 left (Ctrl-C to stop)"
    assert lines[1] == "waiting for the controller: 0:54 left (Ctrl-C to stop)"
    assert lines[2] == "waiting for the controller: 0:48 left (Ctrl-C to stop)"
    assert lines[-1] == "waiting for the controller: ready after 14.0 s"
    assert len(lines) == 4


def test_countdown_gives_up_exactly_at_the_timeout():
    clock, out, calls = _Clock(), io.StringIO(), []

    def attempt(s):
        calls.append(s)
        clock.t += s
        return False

    assert not wait_with_countdown(attempt, 2.5, what="the plant", out=out, slice_s=1.0,
                                   clock=clock, interactive=True)
    assert calls == [1.0, 1.0, 0.5]  # never past the deadline
    text = out.getvalue()
    assert text.count("\r") == 4  # redrawn in place on a terminal
    assert "0:03 left" in text and "0:02 left" in text and "0:01 left" in text
    assert text.endswith("\r\x1b[Kwaiting for the plant: gave up after 2.5 s\n")
    for bad in (0, -1, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="timeout"):
            wait_with_countdown(attempt, bad, what="x", out=out)


def test_format_seconds():
    assert [format_seconds(s) for s in (0, 0.2, 59.5, 245, 3723)] == \
        ["0:00", "0:01", "1:00", "4:05", "1:02:03"]
    assert format_seconds(float("nan")) == "--"


class _FakeRunner:
    dt = 1e-3

    def __init__(self):
        self.stats = {"steps": 0, "deadline_misses": 0, "late_commands": 0}


def test_run_progress_line_and_plain_output():
    r, out = _FakeRunner(), io.StringIO()
    with RunProgress(r, 2.0, out=out, interval=0.05, every=0.1, interactive=False) as p:
        r.stats.update(steps=500, deadline_misses=5, late_commands=2)
        line = p.line()
        time.sleep(0.3)
        r.stats.update(steps=2000, deadline_misses=6, real_time_factor=1.25)
    assert "running [#####...............]    0.50 / 2 s  500 steps  misses 5 (1.00 %)" in line
    assert "late 2" in line
    lines = out.getvalue().splitlines()
    assert lines[0] == "running 2 s of simulated time"
    assert len(lines) >= 3  # periodic lines while running
    assert lines[-1].startswith("running [####################]    2.00 / 2 s  2000 steps")
    assert lines[-1].endswith("x1.25 real time")


def test_serve_progress_shows_the_link_counters_on_a_terminal():
    class _Client:
        counters = {"rx": 0, "tx": 0, "stale": 0, "malformed": 0, "foreign": 0}

    cl, out = _Client(), io.StringIO()
    with ServeProgress(cl, out=out, interval=0.05, interactive=True):
        time.sleep(0.2)
        cl.counters.update(rx=1001, tx=1000, stale=3)
        time.sleep(0.2)
    text = out.getvalue()
    assert text.count("\r\x1b[K") >= 3 and text.endswith("\n")
    last = text.split("\r\x1b[K")[-1]
    assert "1001 received  1000 sent  stale 3  malformed 0  foreign 0" in last
    assert "0 received" in text.split("\r\x1b[K")[1]


# ------------------------------------------------------------------ the recipe, cheap controller
def test_recipe_plant_first_then_a_late_controller(tmp_path):
    port = free_port()
    sc = _pi_scenario(tmp_path, port)
    plant = _start("sil", sc, "--remote", "--out", tmp_path / "run.nc")
    time.sleep(2.5)  # the controller comes late (as a DHP design would make it)
    ctrl = _start("sil-controller", "--scenario", sc, "--idle-timeout", "3")
    rc_c, out_c, err_c = _finish(ctrl)
    rc_p, out_p, err_p = _finish(plant)
    assert rc_p == 0, err_p
    assert rc_c == 0, err_c
    assert f"plant listening on udp://127.0.0.1:{port}" in err_p
    assert "waiting for the controller on udp://127.0.0.1" in err_p and "left" in err_p
    assert "ready after" in err_p and "running [####################]" in err_p
    assert "serving the plant" in err_c and "sent" in err_c.splitlines()[-1]
    stats = json.loads(out_p)["stats"]
    assert stats["steps"] == 1000 and stats["safe_actions"] == 0
    # every step was served (no safe action); how many commands the controller sent depends on
    # how busy the machine is (it answers each observation it receives, and UDP may drop a few
    # under load), so only a bound that load cannot break is asserted here
    assert 500 <= json.loads(out_c.splitlines()[-1])["commands_sent"] <= 1000
    assert (tmp_path / "run.nc").exists()


def test_recipe_controller_first_waits_for_the_plant(tmp_path):
    port = free_port()
    sc = _pi_scenario(tmp_path, port)
    ctrl = _start("sil-controller", "--scenario", sc, "--idle-timeout", "3")
    time.sleep(2.5)
    plant = _start("sil", sc, "--remote", "--no-progress")
    rc_p, out_p, err_p = _finish(plant)
    rc_c, out_c, err_c = _finish(ctrl)
    assert rc_c == 0 and rc_p == 0, err_c + err_p
    assert f"waiting for the plant on udp://127.0.0.1:{port}" in err_c
    assert "waiting for" not in err_p  # --no-progress
    assert json.loads(out_p)["stats"]["steps"] == 1000


def test_controller_builds_before_it_sends_anything(tmp_path):
    """The controller's first datagram reaches the plant's port only after its (slow) build."""
    port = free_port()
    marker = tmp_path / "built_at"
    slow = tmp_path / "slow.py"
    slow.write_text("import time\nfrom pathlib import Path\n"
                    "from downhole.sil import SurfacePI\n"
                    "def make_controller(plant):\n"
                    "    time.sleep(2.0)  # a long design\n"
                    f"    Path({str(marker)!r}).write_text(repr(time.time()))\n"
                    "    return SurfacePI(('hook_load', 'top_drive_angular_velocity'))\n")
    listener = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    listener.bind(("127.0.0.1", port))
    listener.settimeout(20)
    try:
        ctrl = _start("sil-controller", "--port", port, "--controller", slow, "--allow-code",
                      "--wait", "5", "--no-progress")
        listener.recvfrom(2048)
        first = time.time()
    finally:
        listener.close()
    rc, _, err = _finish(ctrl)
    assert marker.exists()
    assert first >= float(marker.read_text())
    assert rc == 2 and "no plant answered" in err  # the fake plant never answers


def test_both_ends_give_up_after_their_wait_with_a_clear_error(tmp_path):
    port = free_port()
    sc = _pi_scenario(tmp_path, port)
    t = time.monotonic()
    rc, _, err = _finish(_start("sil", sc, "--remote", "--wait", "1.5"))
    assert rc == 2
    assert f"error: no controller answered on udp://127.0.0.1:{port} within 1.5 s" in err
    assert "gave up after 1.5 s" in err
    assert 1.4 <= time.monotonic() - t
    rc, _, err = _finish(_start("sil-controller", "--scenario", sc, "--wait", "1"))
    assert rc == 2 and f"no plant answered on udp://127.0.0.1:{port} within 1 s" in err
    # the scenario setting, and the default that fits the documented DHP recipe (~60 s design)
    sc2 = _pi_scenario(tmp_path, port, extra='connect_timeout = "1 s"\n')
    rc, _, err = _finish(_start("sil", sc2, "--remote"))
    assert rc == 2 and "within 1 s" in err
    from downhole.sil.scenario import load_sil_scenario

    assert load_sil_scenario(EXAMPLE).link.connect_timeout >= 240
    assert main(["sil", str(sc), "--remote", "--wait", "0"]) == 2


def test_ctrl_c_while_waiting_is_a_clean_error(tmp_path):
    import signal

    sc = _pi_scenario(tmp_path, free_port())
    env = dict(os.environ, OMP_NUM_THREADS="1")
    plant = subprocess.Popen([*CLI, "sil", str(sc), "--remote"], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True, env=env,
                             preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    seen = []
    while not any("waiting for the controller" in line for line in seen):
        line = plant.stderr.readline()
        assert line, "".join(seen)
        seen.append(line)
    plant.send_signal(signal.SIGINT)
    rc, _, err = _finish(plant, timeout=30)
    assert rc == 130
    assert err.strip().splitlines()[-1] == ("error: interrupted (SIGINT) while waiting for the "
                                            "controller; nothing recorded or written")
    assert "Traceback" not in err


def test_controller_that_got_nothing_to_answer_exits_1(tmp_path):
    from downhole.sil.link import PlantLink
    from downhole.sil.protocol import Layout

    link = PlantLink(Layout(1e-3, "sil", ("bit_angular_velocity",),
                            ("hook_load", "top_drive_angular_velocity"), {}), "127.0.0.1", 0)
    done = threading.Event()

    def answer_hellos():  # a plant that says LAYOUT, then never sends an observation
        while not done.is_set():
            link.poll()
            time.sleep(0.01)

    th = threading.Thread(target=answer_hellos, daemon=True)
    th.start()
    try:
        sc = _pi_scenario(tmp_path, link.address[1])
        rc, out, err = _finish(_start("sil-controller", "--scenario", sc, "--idle-timeout",
                                      "1", "--no-progress"))
    finally:
        done.set()
        th.join(5)
        link.close()
    assert rc == 1
    assert json.loads(out.splitlines()[-1])["commands_sent"] == 0
    assert "the plant sent no observation within --idle-timeout 1 s" in err


# ------------------------------------------------------------------ code only on request
def _code_file(tmp_path):
    marker = tmp_path / "EXECUTED"
    f = tmp_path / "evil.py"
    f.write_text(f"from pathlib import Path\nPath({str(marker)!r}).write_text('ran')\n"
                 "from downhole.sil import build_plant, pi_controller_for\n"
                 "def make_controller(plant):\n    return pi_controller_for(plant)\n")
    return f, marker


def test_scenario_with_a_python_controller_never_runs_it_without_the_opt_in(tmp_path, capsys):
    f, marker = _code_file(tmp_path)
    sc = tmp_path / "s.toml"
    sc.write_text(f'[model]\nfidelity = "lumped4"\n[controller]\ntype = "file"\n'
                  f'file = "{f.name}"\n')
    port = str(free_port())
    for argv in (["sil", str(sc), "--duration", "0.05", "--unpaced"],
                 ["sil", str(tmp_path / "plain.toml"), "--controller", str(f)],
                 ["sil-controller", "--scenario", str(sc), "--port", port, "--wait", "1"],
                 ["sil-controller", "--controller", str(f), "--port", port, "--wait", "1"]):
        (tmp_path / "plain.toml").write_text('[model]\nfidelity = "lumped4"\n')
        assert main(argv) == 2, argv
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1, err  # one line
        assert "--allow-code" in err and "evil.py" in err and "Python code" in err
        assert not marker.exists(), argv
    # the same from Python: the opt-in is the keyword allow_code=True, nothing else
    from downhole.sil import load_controller_file
    from downhole.sil.scenario import build_from_scenario, load_sil_scenario

    for kw in ({}, {"allow_code": False}, {"allow_code": 1}, {"allow_code": "yes"}):
        with pytest.raises(DownholeInputError, match="allow-code"):
            load_controller_file(f, **kw)
        with pytest.raises(DownholeInputError, match="allow-code"):
            build_from_scenario(load_sil_scenario(sc), **kw)
    assert not marker.exists()
    # the plant of a remote run builds no controller: the scenario is fine there
    plant, ctrl = build_from_scenario(load_sil_scenario(sc), with_controller=False)
    assert ctrl is None and not marker.exists()
    # with the opt-in it runs
    assert main(["sil", str(sc), "--duration", "0.05", "--unpaced", "--allow-code",
                 "--no-progress"]) == 0
    assert marker.read_text() == "ran"


def test_data_controller_files_need_no_opt_in(tmp_path, capsys):
    """A saved DHP controller (.json/.npz) is data: no --allow-code needed; other suffixes are
    refused whatever the flag."""
    from downhole.sil import load_controller_file

    with pytest.raises(DownholeInputError, match="expected .py, .json or .npz"):
        load_controller_file(tmp_path / "x.sh", allow_code=True)
    with pytest.raises(Exception) as exc:  # a missing .json fails as a missing file, not as code
        load_controller_file(tmp_path / "missing.json")
    assert "allow-code" not in str(exc.value)


# ------------------------------------------------------------------ the documented DHP recipe
@pytest.mark.slow
def test_documented_dhp_recipe_over_udp(tmp_path):
    """docs/sil.md: ``downhole sil examples/sil_dhp_hybrid68.toml --remote`` in one shell,
    ``downhole sil-controller --scenario examples/sil_dhp_hybrid68.toml`` in another (the
    example's port moved to a free one, the run cut to 3 s)."""
    port = free_port()
    sc = tmp_path / "sil_dhp_hybrid68.toml"
    sc.write_text(EXAMPLE.read_text().replace("port = 47600", f"port = {port}"))
    plant = _start("sil", sc, "--remote", "--duration", "3")
    ctrl = _start("sil-controller", "--scenario", sc)
    rc_c, out_c, err_c = _finish(ctrl, timeout=600)
    rc_p, out_p, err_p = _finish(plant, timeout=60)
    assert rc_p == 0, err_p
    assert rc_c == 0, err_c
    assert "designing the DHP controller" in err_c
    assert err_c.index("designing the DHP") < err_c.index("waiting for the plant")
    assert "waiting for the controller" in err_p and "ready after" in err_p
    stats = json.loads(out_p)["stats"]
    assert stats["steps"] == 3000 and stats["safe_actions"] == 0
    assert stats["late_commands"] < 150
    assert json.loads(out_c.splitlines()[-1])["commands_sent"] >= 2900
