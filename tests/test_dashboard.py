"""Live dashboard: token rules, and a real browser (Debian's chromium via Playwright) that sees
values update, clicks stop, start, controller off/on and a reference change, and saves a
screenshot."""

import math
import shutil
import time
from pathlib import Path

import pytest

from downhole.errors import DownholeInputError
from downhole.sil import RealTimeRunner, build_plant, pi_controller_for
from downhole.sil.dashboard import DashboardSession, is_loopback, make_app, serve_dashboard
from downhole.sil.testing import ServerThread, free_port

CHROMIUM = "/usr/bin/chromium"
ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
        "--disable-component-update", "--disable-sync", "--no-first-run"]


def _runner():
    plant = build_plant("lumped")
    return RealTimeRunner(plant, pi_controller_for(plant), record_every=10)


def test_binding_off_loopback_needs_a_token_and_requests_must_carry_it():
    from fastapi.testclient import TestClient

    assert is_loopback("127.0.0.1") and is_loopback("localhost") and is_loopback("::1")
    assert not is_loopback("0.0.0.0")
    with pytest.raises(DownholeInputError, match="token"):
        serve_dashboard(_runner(), host="0.0.0.0", token=None)
    with pytest.raises(DownholeInputError, match="16 characters"):
        serve_dashboard(_runner(), host="0.0.0.0", token="short")
    session = DashboardSession(_runner(), duration=0.2)
    client = TestClient(make_app(session, token="s3cret"), base_url="http://127.0.0.1:8765")
    assert client.get("/").status_code == 403
    assert client.get("/?token=wrong").status_code == 403
    assert client.get("/api/state", headers={"X-Downhole-Token": "s3cret"}).status_code == 200
    # a query token is read only by GET /, which turns it into a cookie and redirects
    assert client.get("/api/state?token=s3cret").status_code == 403
    login = client.get("/?token=s3cret", follow_redirects=False)
    assert login.status_code == 303 and login.headers["location"] == "/"
    assert "HttpOnly" in login.headers["set-cookie"] and \
        "SameSite=Strict" in login.headers["set-cookie"]
    assert client.get("/").status_code == 200  # the cookie now
    assert client.post("/api/reference",
                       json={"axial": 0.02, "angular": 25}).json()["reference"] == \
        {"axial": 0.02, "angular": 25.0}


_Server = ServerThread  # uvicorn in a thread (downhole.sil.testing)


@pytest.mark.skipif(shutil.which(CHROMIUM) is None, reason="Debian chromium not installed "
                    "(make test installs it)")
def test_browser_sees_updates_and_drives_the_run(tmp_path):
    from playwright.sync_api import sync_playwright

    runner = _runner()
    session = DashboardSession(runner, duration=120.0)
    port = free_port()
    app = make_app(session, publish_hz=20)
    session.start()
    try:
        with _Server(app, port), sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=CHROMIUM, args=ARGS, headless=True)
            page = browser.new_page(viewport={"width": 1400, "height": 900})
            page.set_default_timeout(15000)
            page.goto(f"http://127.0.0.1:{port}/")
            page.wait_for_selector("#sig_bit_angular_velocity")
            t1 = float(page.inner_text("#sig_time"))
            page.wait_for_function(f"parseFloat(document.getElementById('sig_time')"
                                   f".textContent) > {t1 + 0.3}")
            page.wait_for_function("document.getElementById('running').textContent "
                                   "=== 'running'")
            # stop
            page.click("#stop")
            page.wait_for_function("document.getElementById('running').textContent "
                                   "=== 'stopped'")
            t_stop = float(page.inner_text("#sig_time"))
            time.sleep(0.5)
            assert float(page.inner_text("#sig_time")) == t_stop
            assert not session.running
            # start again: time moves on from where it stopped
            page.click("#start")
            page.wait_for_function(f"parseFloat(document.getElementById('sig_time')"
                                   f".textContent) > {t_stop + 0.2}")
            # controller off / on
            page.click("#ctrl_off")
            page.wait_for_function("document.getElementById('controller').textContent === 'off'")
            assert runner.controller_enabled is False
            page.click("#ctrl_on")
            page.wait_for_function("document.getElementById('controller').textContent === 'on'")
            # reference change, in the page's display units (metric: rpm, m/h)
            page.fill("#ref_angular", "240")
            page.fill("#ref_axial", "54")
            page.click("#apply_ref")
            page.wait_for_function("Math.abs(parseFloat(document.getElementById("
                                   "'sig_reference_angular_velocity').textContent) - 8 * "
                                   "Math.PI) < 1e-3")
            assert runner.reference["angular"] == pytest.approx(8 * math.pi)  # 240 rpm
            assert runner.reference["axial"] == pytest.approx(0.015)  # 54 m/h
            time.sleep(1.0)  # let the plot show the new reference
            shot = Path(tmp_path) / "dashboard.png"
            page.screenshot(path=str(shot), full_page=True)
            assert shot.stat().st_size > 10_000
            out = Path("out")
            if out.is_dir():
                shutil.copy(shot, out / "dashboard.png")
            browser.close()
    finally:
        session.stop()
    kinds = [e["kind"] for e in runner.events]
    assert {"controller_off", "controller_on", "reference_change"} <= set(kinds)
