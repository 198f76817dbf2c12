"""The operator's dashboard (issue 18): driller set-points in display units (checked against
hand conversions), the stick-slip severity trend (against downhole.analysis's metric on each
window), switching controllers through the runtime, the run waiting for Start and the server
staying up after it (the real `downhole sil` command), and a real browser (Debian's chromium)
whose chart canvases are checked pixel by pixel: series colours in the plot area, tick labels
beside it, a set-point line that moves when the surface rpm set-point changes."""

import io
import json
import math
import os
import shutil
import signal
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest

from downhole.analysis.metrics import stick_slip_severity
from downhole.control.base import Controller
from downhole.errors import DownholeInputError
from downhole.sil import RealTimeRunner, build_plant, pi_controller_for
from downhole.sil.controllers import (
    ManualFill,
    plant_stick_slip_frequency,
    plant_torsional_impedance,
)
from downhole.sil.dashboard import (
    UNIT_SYSTEMS,
    DashboardSession,
    display_units,
    make_app,
    rolling_severity,
)
from downhole.sil.testing import ServerThread, free_port

CHROMIUM = "/usr/bin/chromium"
ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
        "--disable-component-update", "--disable-sync", "--no-first-run"]
ROOT = Path(__file__).resolve().parents[1]
# hand conversions (exact definitions: 1 ft = 0.3048 m, 1 lbf = 4.4482216152605 N)
LBF = 4.4482216152605
RPM = 2 * math.pi / 60  # rad/s per rpm


def _runner(paced=True):
    plant = build_plant("lumped")
    return RealTimeRunner(plant, pi_controller_for(plant), record_every=10, paced=paced)


def _client(session, **kw):
    from fastapi.testclient import TestClient

    return TestClient(make_app(session, port=8765, **kw), base_url="http://127.0.0.1:8765")


# ------------------------------------------------------------------ units and severity
def test_display_units_are_the_hand_conversions_and_bad_systems_are_refused():
    m, f = display_units("metric"), display_units("field")
    assert m["rotary_speed"]["factor"] == pytest.approx(1 / RPM, rel=1e-12)
    assert m["torque"]["factor"] == pytest.approx(1e-3) and m["force"]["factor"] == 1e-3
    assert m["rop"]["factor"] == pytest.approx(3600.0) and m["depth"]["factor"] == 1.0
    assert f["force"]["factor"] == pytest.approx(1 / (1000 * LBF), rel=1e-12)
    assert f["torque"]["factor"] == pytest.approx(1 / (1000 * LBF * 0.3048), rel=1e-12)
    assert f["rop"]["factor"] == pytest.approx(3600 / 0.3048, rel=1e-12)
    assert f["depth"]["factor"] == pytest.approx(1 / 0.3048, rel=1e-12)
    assert m["torque"]["unit"] == "kN\u00b7m" and f["force"]["unit"] == "klbf"
    with pytest.raises(DownholeInputError, match="unknown unit system"):
        display_units("imperial-ish")
    with pytest.raises(DownholeInputError, match="rotary_speed"):
        display_units({**UNIT_SYSTEMS["metric"], "rotary_speed": "kN"})
    with pytest.raises(DownholeInputError, match="lacks"):
        display_units({"force": "kN"})
    with pytest.raises(DownholeInputError, match="not a unit"):
        display_units({**UNIT_SYSTEMS["metric"], "depth": "furlongs_of_doom"})


def test_the_command_lines_unit_system_drives_the_dashboard():
    """``downhole sil --dashboard --units oilfield`` hands the dashboard a
    :class:`downhole.units.UnitSystem`: the same factors as the field system (hand values), and
    a per-quantity override (``--unit torque=kN*m``) reaches the torque trend."""
    from downhole.units import display_units as system

    f = display_units(system("oilfield"))
    assert f["rotary_speed"]["factor"] == pytest.approx(1 / RPM, rel=1e-12)
    assert f["force"]["factor"] == pytest.approx(1 / (1000 * LBF), rel=1e-12)
    assert f["torque"]["factor"] == pytest.approx(1 / (1000 * LBF * 0.3048), rel=1e-12)
    assert f["rop"]["factor"] == pytest.approx(3600 / 0.3048, rel=1e-12)
    assert f["depth"]["factor"] == pytest.approx(1 / 0.3048, rel=1e-12)
    o = display_units(system("oilfield", ["torque=kN*m"]))
    assert o["torque"]["factor"] == pytest.approx(1e-3) and o["torque"]["unit"] == "kN\u00b7m"
    m = display_units(system("metric"))
    assert m["rop"]["factor"] == pytest.approx(3600.0) and m["force"]["factor"] == 1e-3


@pytest.mark.parametrize("n", [1, 2, 7, 50])
def test_rolling_severity_is_the_metric_over_each_trailing_window(n):
    rng = np.random.default_rng(n)
    w = 10 + 8 * np.sin(np.linspace(0, 12, 400)) + rng.normal(0, 1, 400)
    sev = rolling_severity(w, n)
    # the metric says inf where the mean is not positive; the trend has no value (NaN) there
    ref = [stick_slip_severity(w[max(0, i - n + 1):i + 1]) for i in range(w.size)]
    ref = np.where(np.isinf(ref), np.nan, ref)
    np.testing.assert_allclose(sev, ref, rtol=1e-12)
    # with history rows as context, only the rows after it, the same values
    np.testing.assert_allclose(rolling_severity(w, n, context=100), ref[100:], rtol=1e-12)
    # a window whose mean is not positive has no severity (the metric says inf)
    z = np.array([1.0, -3.0, 1.0, 5.0])
    out = rolling_severity(z, 2)
    assert out[0] == 0.0 and math.isnan(out[1]) and math.isnan(out[2]) and out[3] == pytest.approx(
        stick_slip_severity(z[2:4]))


# ------------------------------------------------------------------ set-points and controllers
def test_driller_setpoints_in_metric_and_field_units_reach_reference_and_open_loop():
    session = DashboardSession(_runner())
    c = _client(session)
    r = session.runner
    resp = c.post("/api/setpoints", json={"surface_rpm": 120, "rop": 18})
    assert resp.status_code == 200, resp.text
    assert r.reference["angular"] == pytest.approx(120 * RPM, rel=1e-12)
    assert r.reference["axial"] == pytest.approx(18 / 3600, rel=1e-12)
    # the open-loop command of the velocity-driven top follows the same set-points
    assert r.manual_command["top_drive_angular_velocity"] == pytest.approx(120 * RPM)
    assert r.manual_command["top_drive_axial_velocity"] == pytest.approx(18 / 3600)
    state = c.get("/api/state").json()
    assert state["setpoints"]["surface_speed"] == pytest.approx(120 * RPM)
    assert state["units"]["rotary_speed"]["unit"] == "rpm" and state["phase"] == "waiting"
    # WOB is no set-point of a velocity-fed top; refusals change nothing
    before = (dict(r.reference), dict(r.manual_command))
    for body, word in (({"wob": 50}, "feed"), ({"surface_rpm": 500}, "admissible range"),
                       ({"rop": -1}, "admissible range"), ({"surface_rpm": "fast"}, "number"),
                       ({"rop": True}, "number"), ({"surface_rpm": 1e400}, "finite"),
                       ({"torque": 3}, "unknown"), ({}, "give")):
        resp = c.post("/api/setpoints", content=json.dumps(body),
                      headers={"content-type": "application/json"})
        assert resp.status_code == 422, body
        assert word in resp.json()["detail"], (body, resp.json())
    # the limit is said in the operator's unit: 40 rad/s = 381.97 rpm
    detail = c.post("/api/setpoints", json={"surface_rpm": 500}).json()["detail"]
    assert "rpm" in detail and "381.972" in detail
    assert c.post("/api/setpoints", content='{"rop": NaN}',
                  headers={"content-type": "application/json"}).status_code == 422
    assert (dict(r.reference), dict(r.manual_command)) == before
    # field units: ROP in ft/h
    cf = _client(DashboardSession(_runner()), units="field")
    resp = cf.post("/api/setpoints", json={"rop": 60})
    assert resp.status_code == 200
    assert resp.json()["reference"]["axial"] == pytest.approx(60 * 0.3048 / 3600, rel=1e-12)
    # the security layer guards the new routes too
    assert c.post("/api/setpoints", content='{"rop": 10}',
                  headers={"content-type": "text/plain"}).status_code == 415
    assert c.post("/api/setpoints", json={"rop": 10},
                  headers={"origin": "http://evil.example"}).status_code == 403


def test_wob_setpoint_of_a_force_driven_hook_is_buoyed_weight_minus_wob():
    plant = build_plant("hybrid24", interface="surface")
    runner = RealTimeRunner(plant, pi_controller_for(plant), record_every=10)
    session = DashboardSession(runner)
    weight = plant.safe_command()["hook_load"]
    assert session.setpoints["wob"] == pytest.approx(120e3)  # build_plant's default WOB
    c = _client(session, units="field")
    resp = c.post("/api/setpoints", json={"wob": 20})  # klbf
    assert resp.status_code == 200, resp.text
    assert runner.manual_command["hook_load"] == pytest.approx(weight - 20e3 * LBF, rel=1e-12)
    assert c.post("/api/setpoints", json={"wob": -5}).status_code == 422


def test_controller_choice_switches_through_the_runtime():
    runner = _runner(paced=False)
    session = DashboardSession(runner)
    assert set(session.controllers) == {"pi", "ztorque", "softspeed"}
    assert session.controller_name == "pi"
    # Z-torque's impedance of the lumped top: sqrt(k J) of Table 2.1 (685.2 N m/rad, 2863 kg m^2)
    assert plant_torsional_impedance(runner.plant) == pytest.approx(math.sqrt(685.2 * 2863))
    # SoftSpeed's w_s: the one torsional mode of the 4-DOF chain, sqrt(k / J)
    assert plant_stick_slip_frequency(runner.plant) == pytest.approx(math.sqrt(685.2 / 2863))
    soft = session.controllers["softspeed"][1]()
    assert soft.kp == pytest.approx(math.sqrt(685.2 * 2863))  # P = Z
    assert soft.ki == pytest.approx(500.0 * 685.2 / 2863)  # I = J w_s^2
    c = _client(session)
    for bad in ({"name": "dhp"}, {"name": 3}, {}, {"name": "pi", "x": 1}):
        assert c.post("/api/controller/select", json=bad).status_code == 422, bad
    assert c.post("/api/setpoints", json={"rop": 18}).status_code == 200
    assert c.post("/api/controller/select", json={"name": "ztorque"}).status_code == 200
    assert isinstance(runner.controller, ManualFill)
    assert type(runner.controller.inner).__name__ == "ZTorque"
    res = runner.run(0.5)
    # Z-torque sets the rotary command; the axial one is the driller's ROP (18 m/h)
    np.testing.assert_allclose(res["command_top_drive_axial_velocity"][1:], 18 / 3600)
    kinds = [e["kind"] for e in runner.events]
    assert "controller_switch" in kinds
    state = c.get("/api/state").json()
    assert state["controller"] == "ztorque" and state["controller_enabled"]
    assert c.post("/api/controller/select", json={"name": "off"}).status_code == 200
    assert runner.controller_enabled is False
    assert c.get("/api/state").json()["controller"] == "off"
    # while running, the switch is made by the loop at its next step
    session.select_controller("pi")
    session.duration = None
    session.start()
    try:
        end = time.monotonic() + 30
        while runner.stats["steps"] < 100 and time.monotonic() < end:
            time.sleep(0.01)
        session.select_controller("ztorque")
        while runner._pending_controller is not None and time.monotonic() < end:
            time.sleep(0.01)
        assert type(runner.controller.inner).__name__ == "ZTorque" and session.error is None
    finally:
        session.stop()


@pytest.mark.slow
def test_switching_to_an_impedance_matched_top_drive_ends_the_stick_slip():
    """The lumped string under the bit-speed PI sticks and slips; switched (through the
    dashboard session) to Z-torque or SoftSpeed, whose tops absorb the torsional wave, it
    rotates steadily: severity over the last 20 s of 60 s."""
    sev = {}
    for name in ("pi", "ztorque", "softspeed"):
        runner = _runner(paced=False)
        session = DashboardSession(runner)
        session.select_controller(name)
        res = runner.run(60.0)
        w = res["bit_angular_velocity"][res.time > 40.0]
        sev[name] = stick_slip_severity(w)
    assert sev["pi"] > 0.8, sev
    assert sev["ztorque"] < 0.1 and sev["softspeed"] < 0.1, sev


def test_switch_controller_refuses_what_cannot_drive_the_plant():
    class Blind(Controller):
        needs = ("no_such_signal",)
        commands = ("top_drive_angular_velocity",)

        def command(self, t, observation, reference=None):
            return {}

    runner = _runner(paced=False)
    with pytest.raises(DownholeInputError, match="no_such_signal"):
        runner.switch_controller(Blind())
    with pytest.raises(DownholeInputError, match="reset"):
        runner.switch_controller(object())
    remote = RealTimeRunner(build_plant("lumped"), link=("127.0.0.1", free_port()))
    try:
        with pytest.raises(DownholeInputError, match="remote"):
            remote.switch_controller(pi_controller_for(remote.plant))
        assert DashboardSession(remote).controllers == {}
    finally:
        remote.close()


def test_trend_sends_the_whole_recording_thinned_with_its_severity():
    runner = _runner(paced=False)
    session = DashboardSession(runner, duration=3.0, severity_window=1.0)
    session.start()
    session._thread.join(60)
    assert session.phase == "finished"
    full = runner.result()
    trend, cursor = session.trend(0, max_points=50)
    assert cursor == runner.recorder.count and len(trend["time"]) == 50
    assert trend["time"][0] == 0.0 and trend["time"][-1] == pytest.approx(full.time[-1])
    # severity at the last row: the metric over the last second of bit speed
    w = full["bit_angular_velocity"]
    n = int(round(1.0 / (runner.dt * runner.record_every)))
    assert trend["stick_slip_severity"][-1] == pytest.approx(stick_slip_severity(w[-n:]))
    # nothing new: nothing sent; new rows only from the cursor on
    assert session.trend(cursor)[0] == {}
    part, _ = session.trend(cursor - 3)
    assert part["time"] == pytest.approx(full.time[-3:].tolist())
    assert part["stick_slip_severity"][-1] == pytest.approx(stick_slip_severity(w[-n:]))


def test_the_page_and_its_chart_library_are_served_by_the_app_behind_the_guard():
    from fastapi.testclient import TestClient

    session = DashboardSession(_runner())
    c = _client(session)
    page = c.get("/").text
    assert "/static/vendor/uplot/uPlot.iife.min.js" in page
    assert "http://" not in page and "https://" not in page  # no CDN, nothing from elsewhere
    lib = c.get("/static/vendor/uplot/uPlot.iife.min.js")
    assert lib.status_code == 200 and lib.headers["content-type"].startswith("text/javascript")
    assert lib.headers["x-content-type-options"] == "nosniff"
    assert "MIT" in c.get("/static/vendor/uplot/LICENSE").text
    for path in ("/static/../dashboard.py", "/static/%2e%2e/dashboard.py",
                 "/static/vendor/uplot/../../dashboard.js/../../dashboard.py",
                 "/static/vendor/uplot/package.json", "/static/"):
        assert c.get(path).status_code == 404, path
    guarded = TestClient(make_app(session, token="k3y-for-tests-0123456789abcdef", port=8765),
                         base_url="http://127.0.0.1:8765")
    assert guarded.get("/static/dashboard.js").status_code == 403
    assert guarded.get("/static/dashboard.js", headers={
        "x-downhole-token": "k3y-for-tests-0123456789abcdef"}).status_code == 200
    assert c.get("/static/dashboard.js", headers={"host": "evil.example:8765"}).status_code == 400


# ------------------------------------------------------------------ the command
def _get(url, timeout=5):
    with urllib.request.urlopen(url, timeout=timeout) as r:
        return r.status, r.read()


def _post(url, body):
    req = urllib.request.Request(url, data=json.dumps(body).encode(), method="POST",
                                 headers={"Content-Type": "application/json"})
    with urllib.request.urlopen(req, timeout=5) as r:
        return r.status, json.loads(r.read())


def _wait_state(base, pred, what, timeout=120):
    end = time.monotonic() + timeout
    last = None
    while time.monotonic() < end:
        try:
            last = json.loads(_get(base + "/api/state")[1])
            if pred(last):
                return last
        except OSError:
            pass
        time.sleep(0.1)
    raise AssertionError(f"timed out waiting for {what}; last state {last}")


def test_sil_command_waits_for_start_and_stays_up_after_the_run(tmp_path):
    sc = tmp_path / "s.toml"
    port, udp = free_port(), free_port()
    sc.write_text(f'[model]\nfidelity = "lumped4"\n[simulation]\nduration = "1 s"\n'
                  f'[link]\nport = {udp}\n[dashboard]\nport = 1\n')
    out = tmp_path / "run.nc"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    cmd = [sys.executable, "-c", "import sys; from downhole.cli import main; sys.exit(main())",
           "sil", str(sc), "--dashboard", "--http-port", str(port), "--no-progress",
           "--out", str(out)]
    proc = subprocess.Popen(cmd, cwd=tmp_path, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    base = f"http://127.0.0.1:{port}"
    try:
        state = _wait_state(base, lambda s: True, "the dashboard")
        assert state["phase"] == "waiting" and state["stats"]["steps"] == 0
        time.sleep(0.5)
        state = _wait_state(base, lambda s: True, "the dashboard")
        assert state["phase"] == "waiting" and state["stats"]["steps"] == 0  # no Start, no run
        assert _post(base + "/api/start", {})[1] == {"started": True}
        state = _wait_state(base, lambda s: s["phase"] == "finished", "the end of the run")
        assert state["signals"]["time"] == pytest.approx(1.0)
        # the run is over and the server still serves it: the page, its library, the state
        assert _get(base + "/")[0] == 200
        status, lib = _get(base + "/static/vendor/uplot/uPlot.iife.min.js")
        assert status == 200 and b"uPlot" in lib
        assert _post(base + "/api/start", {})[1] == {"started": False}  # duration used up
        assert proc.poll() is None
        proc.send_signal(signal.SIGINT)
        stdout, stderr = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 0, stderr
    assert f"http://127.0.0.1:{port}/" in stdout and "press Start" in stdout
    assert "results stay on" in stdout
    from downhole.sim.result import load_result

    res = load_result(out)
    assert res.time[-1] == pytest.approx(1.0) and "stopped_by" not in res.dataset.attrs


def test_sil_command_closed_before_start_records_and_writes_nothing(tmp_path):
    sc = tmp_path / "s.toml"
    port = free_port()
    sc.write_text('[model]\nfidelity = "lumped4"\n[simulation]\nduration = "1 s"\n')
    out = tmp_path / "run.nc"
    out.write_text("the previous result")
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    cmd = [sys.executable, "-c", "import sys; from downhole.cli import main; sys.exit(main())",
           "sil", str(sc), "--dashboard", "--http-port", str(port), "--no-progress",
           "--out", str(out)]
    proc = subprocess.Popen(cmd, cwd=tmp_path, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        _wait_state(f"http://127.0.0.1:{port}", lambda s: s["phase"] == "waiting",
                    "the dashboard")
        proc.send_signal(signal.SIGINT)
        _, stderr = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 130
    assert "before the run was started" in stderr and "nothing recorded or written" in stderr
    assert out.read_text() == "the previous result"  # untouched, and no marker beside it
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.nc", "s.toml"]


def test_dashboard_options_need_the_dashboard(capsys):
    from downhole.cli import main

    for opt in (["--http-port", "8000"], ["--autostart"], ["--exit-after-run"]):
        assert main(["sil", "no-such.toml", *opt]) == 2
        assert "add --dashboard" in capsys.readouterr().err


# ------------------------------------------------------------------ the browser
_Server = ServerThread  # uvicorn in a thread (downhole.sil.testing)


def _hex(color):
    return tuple(int(color[i:i + 2], 16) for i in (1, 3, 5))


def _canvas(page, cid):
    """The chart's canvas as an RGB array, and its plot area (x0, y0, x1, y1) in pixels."""
    from PIL import Image

    png = page.locator(f"#chart_{cid} canvas").screenshot()
    img = np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(int)
    bb = page.evaluate(f"(() => {{ const b = window.dashboard.charts['{cid}'].bbox; "
                       "return [b.left, b.top, b.left + b.width, b.top + b.height]; })()")
    return img, [int(round(v)) for v in bb]


def _near(img, color, tol=40):
    return np.all(np.abs(img - np.array(color)) <= tol, axis=-1)


def _check_drawn(page):
    """Every chart: each series' colour in its plot area, tick labels left of and below it."""
    for chart in page.evaluate("window.dashboard.CHARTS.map(c => [c.id, c.series])"):
        cid, series = chart
        img, (x0, y0, x1, y1) = _canvas(page, cid)
        plot = img[y0:y1, x0:x1]
        for label, _key, color, _dash in series:
            assert _near(plot, _hex(color)).sum() > 20, (cid, label)
        dark = np.all(img < 120, axis=-1)  # axis text is #333 (antialiased)
        assert dark[y0:y1, :max(x0 - 4, 1)].sum() > 40, (cid, "y tick labels")
        assert dark[y1 + 2:, x0:x1].sum() > 40, (cid, "x tick labels")


@pytest.mark.realtime
@pytest.mark.skipif(shutil.which(CHROMIUM) is None, reason="Debian chromium not installed "
                    "(make test installs it)")
def test_browser_operator_view_draws_trends_setpoints_and_controller(tmp_path):
    from playwright.sync_api import sync_playwright

    runner = _runner()
    session = DashboardSession(runner, duration=8.0, severity_window=2.0)
    port = free_port()
    try:
        with _Server(make_app(session, port=port), port), sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=CHROMIUM, args=ARGS, headless=True)
            page = browser.new_page(viewport={"width": 1280, "height": 1000},
                                    device_scale_factor=1)
            page.set_default_timeout(30000)
            page.goto(f"http://127.0.0.1:{port}/")
            page.wait_for_function("document.getElementById('running').textContent "
                                   "=== 'waiting'")
            page.wait_for_function("Object.keys(window.dashboard.charts).length === 7")
            # nothing runs and nothing is drawn before the operator's Start
            img, (x0, y0, x1, y1) = _canvas(page, "rpm")
            assert _near(img[y0:y1, x0:x1], _hex("#1f77b4")).sum() == 0
            assert runner.stats["steps"] == 0
            legend = page.inner_text("#chart_rpm .u-legend")
            assert "surface (rpm)" in legend and "bit (rpm)" in legend
            assert "bit reference (rpm)" in legend
            # the surface speed set-point is the top drive's 10 rad/s; the bit reference the
            # PI tracks is the runner's 20 rad/s, shown beside it in the same unit
            assert page.input_value("#sp_rpm") == "95.493"
            assert page.input_value("#ref_angular") == "190.99"
            assert page.is_disabled("#sp_wob")  # a velocity-fed top takes no WOB set-point
            page.click("#start")
            page.wait_for_function("(() => { const t = window.dashboard.store.t; "
                                   "return t.length && t[t.length - 1] > 2.0; })()")
            page.wait_for_timeout(400)  # one more redraw
            _check_drawn(page)
            # the surface rpm set-point: 190.99 -> 120 rpm, the dashed line moves down
            page.fill("#sp_rpm", "120")
            page.click("#apply_sp")
            page.wait_for_function("(() => { const c = window.dashboard.store.cols"
                                   ".reference_angular_velocity; return c.length && "
                                   "Math.abs(c[c.length - 1] * 60 / (2 * Math.PI) - 120) "
                                   "< 1e-9; })()")
            # until the right eighth of the time axis lies after the change
            page.wait_for_function("(() => { const s = window.dashboard.store, t = s.t, "
                                   "c = s.cols.reference_angular_velocity; "
                                   "const i = c.findIndex(v => Math.abs(v * 60 / (2 * Math.PI)"
                                   " - 120) < 1e-9); "
                                   "return t[t.length - 1] > (t[i] + 0.1) * 8 / 7; })()")
            page.wait_for_timeout(400)
            assert runner.reference["angular"] == pytest.approx(120 * RPM)
            img, (x0, y0, x1, y1) = _canvas(page, "rpm")
            ypos = page.evaluate("[190.99, 120].map(v => window.dashboard.charts.rpm"
                                 ".valToPos(v, 'y', true))")
            green = _near(img, _hex("#2ca02c"))
            w = x1 - x0
            old_row = green[int(round(ypos[0])) - 2:int(round(ypos[0])) + 3, x0:x0 + w // 4]
            new_row = green[int(round(ypos[1])) - 2:int(round(ypos[1])) + 3, x1 - w // 8:x1]
            assert old_row.sum() > 10 and new_row.sum() > 5
            assert green[int(round(ypos[0])) - 2:int(round(ypos[0])) + 3,
                         x1 - w // 8:x1].sum() == 0  # the old level is gone at the right
            # controller: switch to Z-torque, then off
            page.select_option("#ctrl_select", "ztorque")
            page.click("#ctrl_apply")
            page.wait_for_function("document.getElementById('ctrl_name').textContent"
                                   ".includes('Z-torque')")
            assert type(runner.controller.inner).__name__ == "ZTorque"
            page.select_option("#ctrl_select", "off")
            page.click("#ctrl_apply")
            page.wait_for_function("document.getElementById('controller').textContent "
                                   "=== 'off'")
            # the run ends; the server stays up and a page opened now shows all of it
            page.wait_for_function("document.getElementById('running').textContent "
                                   "=== 'finished'")
            page.reload()
            page.wait_for_function("(() => { const t = window.dashboard.store.t; "
                                   "return t.length > 100 && t[t.length - 1] > 7.9; })()")
            page.wait_for_timeout(400)
            _check_drawn(page)
            shot = Path(tmp_path) / "operator.png"
            page.screenshot(path=str(shot), full_page=True)
            out = Path("out")
            if out.is_dir():
                shutil.copy(shot, out / "dashboard_operator.png")
            browser.close()
        kinds = [e["kind"] for e in runner.events]
        assert {"controller_switch", "controller_off", "reference_change"} <= set(kinds)
        assert session.error is None
    finally:
        session.stop()
