"""What a new operator sees on the dashboard (issue 24, item 7): the speed set-point is the
scenario's surface speed (it showed the bit reference: 190.99 rpm for a scenario at 95.5 rpm), the
bit-reference row follows set-point changes and is in the display units, refused set-points are
counted in the stats the page shows, and the severity axis has a real label (it was a lone
``-``, drawn rotated like a stray ``'``). The example scenario is a real-size string."""

import math
import shutil
from pathlib import Path

import pytest

from downhole.sil.dashboard import DashboardSession, make_app
from downhole.sil.runtime import RealTimeRunner
from downhole.sil.scenario import build_from_scenario, load_sil_scenario, parse_sil_scenario
from downhole.sil.testing import ServerThread, free_port

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "sil_dashboard_lumped.toml"
CHROMIUM = "/usr/bin/chromium"
ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
        "--disable-component-update", "--disable-sync", "--no-first-run"]
RPM = 2 * math.pi / 60  # rad/s per rpm


def _session(sc):
    """The runner and session ``downhole sil SCENARIO --dashboard`` builds (not started)."""
    plant, ctrl = build_from_scenario(sc)
    every = max(1, int(round(sc.simulation.record_dt / sc.simulation.dt)))
    runner = RealTimeRunner(plant, ctrl, reference={"axial": sc.reference.axial_velocity,
                                                    "angular": sc.reference.angular_velocity},
                            paced=False, record_every=every,
                            controller_enabled=sc.controller.type != "none")
    limits = {"axial": (sc.reference.axial_velocity_min, sc.reference.axial_velocity_max),
              "angular": (sc.reference.angular_velocity_min, sc.reference.angular_velocity_max)}
    return DashboardSession(runner, duration=sc.simulation.duration), limits


def _client(session, limits):
    from fastapi.testclient import TestClient

    return TestClient(make_app(session, port=8765, reference_limits=limits, units="metric"),
                      base_url="http://127.0.0.1:8765")


def test_speed_setpoint_is_the_scenarios_surface_speed_not_the_bit_reference():
    # the former example: the top drive at 10 rad/s (95.5 rpm), the bit reference 20 rad/s
    sc = parse_sil_scenario({"model": {"fidelity": "lumped4", "preset": "table_2_1"},
                             "operation": {"surface_speed": "10 rad/s", "rop": "10 mm/s"},
                             "controller": {"type": "pi"},
                             "reference": {"axial_velocity": "12 mm/s",
                                           "angular_velocity": "20 rad/s"}})
    session, limits = _session(sc)
    state = _client(session, limits).get("/api/state").json()
    assert state["setpoints"]["surface_speed"] == pytest.approx(10.0)
    assert state["setpoints"]["surface_speed"] / RPM == pytest.approx(95.49, abs=0.01)
    assert state["setpoints"]["rop"] == pytest.approx(0.01)  # the top's feed, lumped plant
    assert state["reference"] == {"axial": pytest.approx(0.012), "angular": pytest.approx(20.0)}


def test_the_example_is_a_real_size_string_whose_setpoint_and_reference_agree():
    sc = load_sil_scenario(EXAMPLE)
    session, limits = _session(sc)
    state = _client(session, limits).get("/api/state").json()
    assert state["setpoints"]["surface_speed"] / RPM == pytest.approx(100.0)
    assert state["reference"]["angular"] / RPM == pytest.approx(100.0)
    assert state["setpoints"]["rop"] * 3600 == pytest.approx(20.0)
    # the hanging string weighs ~50 t (2500 m of 5" pipe over 200 m of collars), not 787 t
    weight = session.runner.plant.safe_command().get("hook_load")
    obs = session.runner.plant.reset()
    hook = weight if weight is not None else obs.get("hook_load")
    assert hook is None or 300e3 < hook < 700e3


def test_refused_setpoints_are_counted_in_the_stats_the_page_shows():
    sc = load_sil_scenario(EXAMPLE)
    session, limits = _session(sc)
    c = _client(session, limits)
    assert c.get("/api/state").json()["stats"]["rejected_setpoints"] == 0
    assert c.post("/api/setpoints", json={"surface_rpm": 900}).status_code == 422
    assert c.post("/api/reference", json={"angular": 1e3}).status_code == 422
    assert c.post("/api/setpoints", json={"wob": 50}).status_code == 422  # velocity-fed top
    state = c.get("/api/state").json()
    assert state["stats"]["rejected_setpoints"] == 3 and state["refused"]["setpoint"] == 3
    assert sum(e["kind"] == "setpoint_rejected" for e in session.runner.events) == 3
    # an accepted one is not counted; the counts survive the Start (which resets the runtime's)
    assert c.post("/api/setpoints", json={"surface_rpm": 110}).status_code == 200
    assert c.get("/api/state").json()["stats"]["rejected_setpoints"] == 3


def test_setpoints_move_the_reference_the_state_reports():
    sc = load_sil_scenario(EXAMPLE)
    session, limits = _session(sc)
    c = _client(session, limits)
    assert c.post("/api/setpoints", json={"surface_rpm": 80, "rop": 15}).status_code == 200
    state = c.get("/api/state").json()
    assert state["reference"]["angular"] / RPM == pytest.approx(80.0)
    assert state["reference"]["axial"] * 3600 == pytest.approx(15.0)
    assert state["setpoints"]["surface_speed"] / RPM == pytest.approx(80.0)


@pytest.mark.skipif(shutil.which(CHROMIUM) is None, reason="Debian chromium not installed "
                    "(make test installs it)")
def test_browser_fields_follow_the_setpoints_count_refusals_and_label_severity(tmp_path):
    from playwright.sync_api import sync_playwright

    sc = load_sil_scenario(EXAMPLE)
    session, limits = _session(sc)
    port = free_port()
    app = make_app(session, port=port, reference_limits=limits, units="metric")
    with ServerThread(app, port), sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=CHROMIUM, args=ARGS, headless=True)
        try:
            page = browser.new_page(viewport={"width": 1400, "height": 900})
            page.set_default_timeout(20000)
            page.goto(f"http://127.0.0.1:{port}/")
            page.wait_for_function("document.getElementById('sp_rpm').value !== ''")
            # the scenario's 100 rpm, in the speed field and in the bit-reference row (rpm)
            assert float(page.input_value("#sp_rpm")) == pytest.approx(100.0)
            assert float(page.input_value("#ref_angular")) == pytest.approx(100.0)
            assert float(page.input_value("#ref_axial")) == pytest.approx(20.0)  # m/h
            # a set-point change moves the reference row
            page.fill("#sp_rpm", "120")
            page.fill("#sp_rop", "25")
            page.click("#apply_sp")
            page.wait_for_function("parseFloat(document.getElementById('ref_angular').value)"
                                   " === 120")
            assert float(page.input_value("#ref_axial")) == pytest.approx(25.0)
            assert session.runner.reference["angular"] == pytest.approx(120 * RPM)
            # the reference row takes display units too
            page.fill("#ref_angular", "90")
            page.click("#apply_ref")
            for _ in range(400):  # the POST's answer (no clock: up to 400 polls)
                if session.runner.reference["angular"] == pytest.approx(90 * RPM):
                    break
                page.wait_for_timeout(50)
            assert session.runner.reference["angular"] == pytest.approx(90 * RPM)
            assert session.runner.reference["axial"] == pytest.approx(25 / 3600)
            # a refusal is counted on the page
            assert page.inner_text("#rejected") == "0"
            page.fill("#sp_rpm", "900")
            page.click("#apply_sp")
            page.wait_for_function("document.getElementById('refused').textContent"
                                   ".includes('admissible range')")
            page.wait_for_function("document.getElementById('rejected').textContent === '1'")
            # the refused value does not stay in the field: it shows the set-point again
            page.wait_for_function("document.getElementById('sp_rpm').value === '120'")
            # every axis has a label; the severity axis says what it is
            labels = page.evaluate("Object.fromEntries(Object.entries(window.dashboard.charts)"
                                   ".map(([k, c]) => [k, c.axes[1].label]))")
            assert labels["severity"] == "severity (-)"
            assert labels["rpm"] == "rpm" and labels["torque"] == "kN\u00b7m"
            assert all(isinstance(v, str) and v.strip() not in ("", "-", "'")
                       for v in labels.values()), labels
        finally:
            browser.close()
