"""Dashboard security, tried as a hostile web page would (issue 16, item 5), on 127.0.0.1 only.

Cross-origin requests and WebSockets, DNS rebinding (a foreign Host), text/plain and form
posts, NaN / inf / out-of-range set-points (refused with 4xx while the run goes on), the token
on every route (the API docs included), in a header or a cookie on HTTP and on the WebSocket,
never printed in full; and a real browser on a foreign origin that cannot drive the run.
"""

import json
import math
import shutil
import time

import pytest
from fastapi.testclient import TestClient
from starlette.websockets import WebSocketDisconnect

from downhole.cli import main
from downhole.errors import DownholeInputError
from downhole.sil import RealTimeRunner, build_plant, pi_controller_for
from downhole.sil.dashboard import TOKEN_COOKIE, DashboardSession, make_app
from downhole.sil.testing import ServerThread, free_port

PORT = 8765
BASE = f"http://127.0.0.1:{PORT}"
EVIL = "http://evil.example"
TOKEN = "k3y-for-tests-0123456789abcdef"
CHROMIUM = "/usr/bin/chromium"
ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
        "--disable-component-update", "--disable-sync", "--no-first-run"]
POSTS = {"/api/start": {}, "/api/stop": {}, "/api/controller": {"on": False},
         "/api/reference": {"axial": 0.02, "angular": 30.0}}


def _runner():
    plant = build_plant("lumped")
    return RealTimeRunner(plant, pi_controller_for(plant), record_every=10)


def _client(token=None, **kw):
    session = DashboardSession(_runner(), duration=600.0)
    app = make_app(session, token, port=PORT, **kw)
    return session, TestClient(app, base_url=BASE)


def _strict_json(text: str):
    """json.loads that fails on NaN / Infinity (what a browser's JSON.parse does)."""
    def bad(name):
        raise ValueError(f"non-JSON constant {name}")

    return json.loads(text, parse_constant=bad)


def _unchanged(session, ref0):
    r = session.runner
    assert r.reference == ref0
    assert r.controller_enabled is True
    assert not any(e["kind"] in ("reference_change", "controller_off") for e in r.events)


def test_cross_origin_requests_are_refused_and_change_nothing():
    session, c = _client()
    ref0 = dict(session.runner.reference)
    for path, body in POSTS.items():
        for ctype in ("text/plain", "application/json"):
            r = c.post(path, content=json.dumps(body),
                       headers={"origin": EVIL, "content-type": ctype})
            assert r.status_code == 403, (path, ctype)
            assert "cross-origin" in r.json()["detail"]
    assert c.get("/api/state", headers={"origin": EVIL}).status_code == 403
    assert c.options("/api/reference", headers={
        "origin": EVIL, "access-control-request-method": "POST"}).status_code == 403
    # "null" (sandboxed frames, file://) and a look-alike of the own origin are foreign too
    for o in ("null", "http://127.0.0.1:8766", "https://127.0.0.1.evil.example:8765"):
        assert c.post("/api/stop", json={}, headers={"origin": o}).status_code == 403, o
    # a browser request without Origin but marked cross-site (e.g. <img src>, no-cors GET)
    assert c.get("/api/state", headers={"sec-fetch-site": "cross-site",
                                        "sec-fetch-mode": "no-cors"}).status_code == 403
    assert c.post("/api/stop", json={}, headers={"sec-fetch-site": "same-site"}).status_code \
        == 403
    _unchanged(session, ref0)
    assert not session.running
    # the dashboard's own origin, a plain navigation to the page, a non-browser client: served
    assert c.post("/api/reference", json={"axial": 0.02},
                  headers={"origin": BASE}).status_code == 200
    assert c.get("/", headers={"sec-fetch-site": "cross-site",
                               "sec-fetch-mode": "navigate"}).status_code == 200
    assert c.get("/api/state").status_code == 200
    assert session.refused["origin"] >= 12
    assert c.get("/api/state").json()["refused"]["origin"] == session.refused["origin"]


def test_allowed_origins_list_admits_exactly_those_origins():
    session, c = _client(allowed_origins=["http://hmi.example:8080"])
    assert c.post("/api/controller", json={"on": False},
                  headers={"origin": "http://hmi.example:8080"}).status_code == 200
    assert session.runner.controller_enabled is False
    for o in ("http://hmi.example", "http://hmi.example:8081", EVIL):
        assert c.post("/api/controller", json={"on": True},
                      headers={"origin": o}).status_code == 403
    assert session.runner.controller_enabled is False


def test_foreign_host_dns_rebinding_is_refused():
    session, c = _client()
    for host in ("evil.example:8765", "evil.example", "127.0.0.1:9999", "127.0.0.1",
                 "127.0.0.1:8765@evil.example", "", "localhost:8765:1"):
        r = c.get("/api/state", headers={"host": host})
        assert r.status_code == 400, host
        r = c.post("/api/stop", json={}, headers={"host": host})
        assert r.status_code == 400, host
    # the loopback names with the right port are this dashboard
    for host in ("127.0.0.1:8765", "localhost:8765", "LOCALHOST:8765", "[::1]:8765"):
        assert c.get("/api/state", headers={"host": host}).status_code == 200, host
    with pytest.raises(WebSocketDisconnect) as exc:
        with c.websocket_connect(f"ws://127.0.0.1:{PORT}/ws",
                                 headers={"host": "evil.example:8765"}) as ws:
            ws.receive_text()
    assert exc.value.code == 1008
    assert session.refused["host"] == 15
    # an operator can name an extra host (the rig PC's name)
    _, c2 = _client(allowed_hosts=["rig-pc.local"])
    assert c2.get("/api/state", headers={"host": "rig-pc.local:8765"}).status_code == 200
    assert c2.get("/api/state", headers={"host": "evil.example:8765"}).status_code == 400


def test_only_json_bodies_reach_the_controls():
    session, c = _client()
    ref0 = dict(session.runner.reference)
    body = json.dumps({"axial": 0.02, "angular": 30})
    for ctype in ("text/plain", "text/plain;charset=UTF-8", "application/x-www-form-urlencoded",
                  "multipart/form-data; boundary=x", None):
        headers = {} if ctype is None else {"content-type": ctype}
        for path in POSTS:
            r = c.post(path, content=body, headers=headers)
            assert r.status_code == 415, (path, ctype)
            assert "application/json" in r.json()["detail"]
    _unchanged(session, ref0)
    assert not session.running
    # malformed JSON and non-objects: 4xx with a message, nothing applied
    for raw, code in (("{axial: 1}", 400), ("[0.02, 30]", 422), ('"x"', 422)):
        r = c.post("/api/reference", content=raw, headers={"content-type": "application/json"})
        assert r.status_code == code and r.json()["detail"], raw
    _unchanged(session, ref0)


@pytest.mark.parametrize("raw, word", [
    ('{"axial": NaN, "angular": 20}', "finite"),
    ('{"axial": 0.01, "angular": Infinity}', "finite"),
    ('{"angular": -Infinity}', "finite"),
    ('{"axial": 1e400}', "finite"),
    ('{"angular": 1e300}', "admissible range"),
    ('{"axial": -0.01}', "admissible range"),
    ('{"angular": 40.5}', "admissible range"),
    ('{"axial": "fast"}', "number"),
    ('{"angular": true}', "number"),
    ('{"axial": [0.01]}', "number"),
    ('{"wob": 1e6}', "unknown"),
    ('{}', "give axial"),
])
def test_bad_set_points_are_refused_with_4xx(raw, word):
    session, c = _client()
    ref0 = dict(session.runner.reference)
    r = c.post("/api/reference", content=raw, headers={"content-type": "application/json"})
    assert r.status_code == 422
    assert word in r.json()["detail"]
    assert session.runner.reference == ref0


def test_nan_set_point_does_not_kill_a_running_run_and_bounds_are_inclusive():
    session, c = _client(reference_limits={"angular": (5.0, 30.0)})
    session.start()
    try:
        end = time.monotonic() + 20
        while session.runner.stats["steps"] < 50 and time.monotonic() < end:
            time.sleep(0.02)
        for raw in ('{"axial": NaN, "angular": 20}', '{"angular": 31}', '{"angular": 4.9}'):
            assert c.post("/api/reference", content=raw,
                          headers={"content-type": "application/json"}).status_code == 422
        for bad in ({"on": "false"}, {"on": 0}, {}, {"on": True, "x": 1}):
            assert c.post("/api/controller", json=bad).status_code == 422
        assert session.runner.controller_enabled is True
        steps = session.runner.stats["steps"]
        time.sleep(0.3)
        assert session.running and session.error is None
        assert session.runner.stats["steps"] > steps  # still stepping
        ok = c.post("/api/reference", json={"angular": 30.0})
        assert ok.status_code == 200 and ok.json()["reference"]["angular"] == 30.0
        state = _strict_json(c.get("/api/state").text)
        assert state["running"] and state["error"] is None
    finally:
        session.stop()


def test_state_and_websocket_never_emit_nan():
    session, c = _client()
    r = session.runner
    # the Python API refuses a non-finite reference (counted, reference unchanged)
    with pytest.raises(DownholeInputError, match="reference refused"):
        r.set_reference(float("nan"), float("inf"))
    assert r.stats["rejected_setpoints"] >= 1 and math.isfinite(r.reference["axial"])
    # defence in depth: a non-finite value that got in anyway is served as null, reported once
    r.reference = {"axial": float("nan"), "angular": float("inf")}
    for _ in range(2):
        resp = c.get("/api/state")
        assert resp.status_code == 200
        state = _strict_json(resp.text)
        assert state["reference"] == {"axial": None, "angular": None}
    notes = [e for e in r.events if e["kind"] == "dashboard_non_finite"]
    assert len(notes) == 1  # reported once, not at every publish
    assert "reference.axial" in notes[0]["detail"] and "reference.angular" in notes[0]["detail"]
    with c.websocket_connect(f"ws://127.0.0.1:{PORT}/ws") as ws:
        msg = _strict_json(ws.receive_text())
    assert msg["reference"]["axial"] is None
    # a run with that reference: the non-finite commands it produces are refused, never
    # applied, and the state still serves without NaN
    session.start()
    end = time.monotonic() + 20
    while session.running and r.stats.get("rejected_commands", 0) < 5 \
            and time.monotonic() < end:
        time.sleep(0.05)
    session.stop()
    assert r.stats.get("rejected_commands", 0) >= 5 or session.error is not None
    resp = c.get("/api/state")
    assert resp.status_code == 200
    state = _strict_json(resp.text)
    assert all(v is None or math.isfinite(v) for v in state["signals"].values())
    assert all(math.isfinite(v) for v in r.latest().values() if isinstance(v, float))


def test_token_guards_every_route_including_the_api_docs():
    session, c = _client(TOKEN)
    for path in ("/", "/api/state", "/docs", "/redoc", "/openapi.json", "/docs/oauth2-redirect",
                 "/no-such-page"):
        r = c.get(path)
        assert r.status_code == 403, path
        assert "token" in r.json()["detail"]
        assert "openapi" not in r.text.lower() or path == "/openapi.json"
    for path, body in POSTS.items():
        assert c.post(path, json=body).status_code == 403
    assert not session.running and session.runner.controller_enabled
    for path in ("/docs", "/openapi.json"):
        assert c.get(path, headers={"authorization": f"Bearer {TOKEN}"}).status_code == 200
    assert "/api/reference" in c.get("/openapi.json",
                                      headers={"x-downhole-token": TOKEN}).json()["paths"]
    # wrong, empty, prefixed and non-ASCII tokens
    for bad in ("", TOKEN[:-1], TOKEN + "x", "Bearer " + TOKEN, "k\u00e9y".encode("latin-1")):
        assert c.get("/api/state", headers={"x-downhole-token": bad}).status_code == 403
    assert session.refused["token"] >= 16


def test_token_in_a_header_or_a_cookie_works_on_http_and_on_the_websocket():
    session, c = _client(TOKEN)
    ws_url = f"ws://127.0.0.1:{PORT}/ws"
    ways = [{"authorization": f"Bearer {TOKEN}"}, {"Authorization": f"bearer {TOKEN}"},
            {"x-downhole-token": TOKEN}, {"cookie": f"other=1; {TOKEN_COOKIE}={TOKEN}"}]
    for h in ways:
        assert c.get("/api/state", headers=h).status_code == 200, h
        assert c.post("/api/reference", json={"angular": 21.0}, headers=h).status_code == 200
        with c.websocket_connect(ws_url, headers=h) as ws:
            assert "signals" in _strict_json(ws.receive_text())
    for h in ({}, {"x-downhole-token": "nope"}, {"cookie": f"{TOKEN_COOKIE}=nope"}):
        with pytest.raises(WebSocketDisconnect) as exc:
            with c.websocket_connect(ws_url, headers=h) as ws:
                ws.receive_text()
        assert exc.value.code == 1008
    # the query token is a login for the page only, not for the WebSocket
    with pytest.raises(WebSocketDisconnect):
        with c.websocket_connect(f"{ws_url}?token={TOKEN}") as ws:
            ws.receive_text()
    # the token does not replace the Origin check
    with pytest.raises(WebSocketDisconnect) as exc:
        with c.websocket_connect(ws_url, headers={"x-downhole-token": TOKEN,
                                                  "origin": EVIL}) as ws:
            ws.receive_text()
    assert exc.value.code == 1008


def test_token_is_not_printed(tmp_path, capfd):
    token_file = tmp_path / "dashboard.token"
    token_file.write_text(TOKEN + "\n")
    sc = tmp_path / "s.toml"
    sc.write_text(f'[model]\nfidelity = "lumped4"\n[simulation]\nduration = "0.3 s"\n'
                  f'[dashboard]\nport = {free_port()}\ntoken_file = "dashboard.token"\n')
    assert main(["sil", str(sc), "--dashboard", "--autostart", "--exit-after-run",
                 "--no-progress"]) == 0
    out, err = capfd.readouterr()
    assert TOKEN not in out and TOKEN not in err
    assert TOKEN[:8] not in out + err
    assert str(token_file) in out and "required" in out
    sc.write_text(sc.read_text().replace('token_file = "dashboard.token"', f'token = "{TOKEN}"'))
    assert main(["sil", str(sc), "--dashboard", "--autostart", "--exit-after-run",
                 "--no-progress"]) == 0
    out, err = capfd.readouterr()
    assert TOKEN not in out + err and f"{TOKEN[:4]}..." in out


def test_token_file_errors_name_the_file(tmp_path, capsys):
    sc = tmp_path / "s.toml"
    sc.write_text('[model]\nfidelity = "lumped4"\n[dashboard]\ntoken_file = "missing.token"\n')
    assert main(["sil", str(sc), "--dashboard", "--duration", "0.1"]) == 2
    assert "missing.token" in capsys.readouterr().err
    (tmp_path / "blank.token").write_text("\n \n")
    sc.write_text(sc.read_text().replace("missing", "blank"))
    assert main(["sil", str(sc), "--dashboard", "--duration", "0.1"]) == 2
    assert "blank.token" in capsys.readouterr().err
    sc.write_text('[dashboard]\ntoken = "a"\ntoken_file = "x"\n')
    assert main(["sil", str(sc), "--dashboard"]) == 2
    assert "dashboard.token_file" in capsys.readouterr().err
    # refused before the plant waits for its controller (300 s here), not after
    for db, word in (('host = "0.0.0.0"', "not loopback"),
                     ('host = "0.0.0.0"\ntoken = "short"', "16 characters"),
                     ('token = "semi;colon"', "semicolons")):
        sc.write_text(f'[model]\nfidelity = "lumped4"\n[link]\nport = {free_port()}\n'
                      f'[dashboard]\n{db}\n')
        t = time.monotonic()
        assert main(["sil", str(sc), "--dashboard", "--remote", "--wait", "300"]) == 2
        assert time.monotonic() - t < 250  # it did not wait for the plant's 300 s
        assert word in capsys.readouterr().err


_Server = ServerThread  # uvicorn in a thread (downhole.sil.testing)


def test_real_server_refuses_a_cross_origin_websocket():
    from websockets.exceptions import InvalidStatus
    from websockets.sync.client import connect

    port = free_port()
    session = DashboardSession(_runner(), duration=600.0)
    with _Server(make_app(session, port=port), port):
        url = f"ws://127.0.0.1:{port}/ws"
        with pytest.raises(InvalidStatus) as exc:
            connect(url, origin=EVIL, open_timeout=10)
        assert exc.value.response.status_code == 403
        with connect(url, origin=f"http://127.0.0.1:{port}", open_timeout=10) as ws:
            assert "signals" in _strict_json(ws.recv(timeout=10))
    assert session.refused["origin"] == 1


@pytest.mark.skipif(shutil.which(CHROMIUM) is None, reason="Debian chromium not installed "
                    "(make test installs it)")
def test_browser_on_a_foreign_origin_cannot_drive_the_run():
    """A page on another origin posts text/plain (no preflight) and JSON to every control and
    opens the WebSocket; a DNS-rebinding name for 127.0.0.1 gets 400. The run goes on."""
    from playwright.sync_api import sync_playwright

    runner = _runner()
    session = DashboardSession(runner, duration=600.0)
    port, evil_port = free_port(), free_port()
    evil_page = f"""<!doctype html><html><body><pre id="log"></pre><script>
const T = "http://127.0.0.1:{port}", log = [];
async function attack() {{
  for (const p of ["/api/stop", "/api/controller", "/api/reference"]) {{
    try {{ await fetch(T + p, {{method: "POST", mode: "no-cors",
      headers: {{"Content-Type": "text/plain"}}, body: '{{"on": false, "angular": 35}}'}}); }}
    catch (e) {{}}
    try {{ const r = await fetch(T + p, {{method: "POST",
      headers: {{"Content-Type": "application/json"}}, body: '{{"on": false}}'}});
      log.push("json " + r.status); }} catch (e) {{ log.push("json blocked"); }}
  }}
  await new Promise(done => {{
    const ws = new WebSocket("ws://127.0.0.1:{port}/ws");
    ws.onmessage = () => {{ log.push("ws message"); ws.close(); }};
    ws.onerror = () => log.push("ws error");
    ws.onclose = () => done();
  }});
  document.getElementById("log").textContent = log.join("\\n");
  document.title = "done";
}}
attack();
</script></body></html>"""

    from fastapi import FastAPI
    from fastapi.responses import HTMLResponse

    evil = FastAPI()
    evil.get("/", response_class=HTMLResponse)(lambda: evil_page)
    session.start()
    try:
        with _Server(make_app(session, port=port), port), _Server(evil, evil_port), \
                sync_playwright() as pw:
            browser = pw.chromium.launch(
                executable_path=CHROMIUM, headless=True,
                args=ARGS + ["--host-resolver-rules=MAP evil.example 127.0.0.1"])
            page = browser.new_page()
            page.set_default_timeout(20000)
            page.goto(f"http://localhost:{evil_port}/")
            page.wait_for_function("document.title === 'done'")
            log = page.inner_text("#log")
            assert "ws message" not in log and "json 200" not in log
            # DNS rebinding: evil.example resolves to 127.0.0.1, the Host header gives it away
            resp = page.goto(f"http://evil.example:{port}/api/state")
            assert resp.status == 400
            # the dashboard itself still works from its own origin
            page.goto(f"http://127.0.0.1:{port}/")
            page.wait_for_function("document.getElementById('running').textContent "
                                   "=== 'running'")
            browser.close()
        assert session.running and runner.controller_enabled
        assert runner.reference["angular"] == 20.0
        assert session.refused["origin"] >= 4 and session.refused["host"] >= 1
    finally:
        session.stop()


@pytest.mark.parametrize("toml, field", [
    ('[reference]\naxial_velocity = "60 mm/s"\n', "reference.axial_velocity"),
    ('[reference]\nangular_velocity_min = "30 rad/s"\nangular_velocity_max = "10 rad/s"\n',
     "reference.angular_velocity_min"),
    ('[reference]\naxial_velocity_max = "nan m/s"\n', "reference.axial_velocity"),
    ('[dashboard]\ntoken = "two words"\n', "dashboard.token"),
    ('[dashboard]\ntoken = ""\n', "dashboard.token"),
    ('[dashboard]\nallowed_origins = ["evil.example"]\n', "dashboard.allowed_origins"),
    ('[dashboard]\nallowed_origins = ["http://hmi.example/"]\n', "dashboard.allowed_origins"),
    ('[dashboard]\nallowed_hosts = "rig-pc"\n', "dashboard.allowed_hosts"),
])
def test_scenario_dashboard_and_range_fields_are_validated(tmp_path, toml, field):
    from downhole.errors import ScenarioError
    from downhole.sil.scenario import load_sil_scenario

    sc = tmp_path / "s.toml"
    sc.write_text(toml)
    with pytest.raises(ScenarioError) as exc:
        load_sil_scenario(sc)
    assert field in str(exc.value) and str(sc) in str(exc.value)


def test_declared_ranges_reach_the_dashboard(tmp_path):
    """The scenario's [reference] ranges are what /api/reference enforces."""
    from downhole.cli.sil import _reference_limits
    from downhole.sil.scenario import load_sil_scenario

    sc = tmp_path / "s.toml"
    sc.write_text('[reference]\nangular_velocity_max = "30 rad/s"\n'
                  'axial_velocity_max = "20 mm/s"\n')
    limits = _reference_limits(load_sil_scenario(sc))
    assert limits == {"axial": (0.0, pytest.approx(0.02)), "angular": (0.0, 30.0)}
    session, c = _client(reference_limits=limits)
    assert c.post("/api/reference", json={"angular": 35.0}).status_code == 422
    assert c.post("/api/reference", json={"axial": 0.019, "angular": 30.0}).status_code == 200
    with pytest.raises(Exception, match="reference_limits"):
        make_app(session, reference_limits={"axial": (1.0, 0.0)})


@pytest.mark.skipif(shutil.which(CHROMIUM) is None, reason="Debian chromium not installed "
                    "(make test installs it)")
def test_browser_logs_in_once_and_the_cookie_carries_http_and_websocket():
    """With a token: /?token=... sets the cookie and leaves the address bar clean; the page's
    WebSocket and its controls then work with the cookie alone; without it, nothing does."""
    from playwright.sync_api import sync_playwright

    runner = _runner()
    session = DashboardSession(runner, duration=600.0)
    port = free_port()
    session.start()
    try:
        with _Server(make_app(session, TOKEN, port=port), port), sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=CHROMIUM, args=ARGS, headless=True)
            anon = browser.new_page()
            assert anon.goto(f"http://127.0.0.1:{port}/").status == 403
            page = browser.new_context().new_page()
            page.set_default_timeout(20000)
            page.goto(f"http://127.0.0.1:{port}/?token={TOKEN}")
            assert page.url == f"http://127.0.0.1:{port}/"  # the token left the address bar
            cookie = page.context.cookies()[0]
            assert cookie["name"] == TOKEN_COOKIE and cookie["httpOnly"]
            assert cookie["sameSite"] == "Strict"
            assert TOKEN not in page.content()
            page.wait_for_selector("#sig_time")
            t1 = float(page.inner_text("#sig_time"))
            page.wait_for_function(f"parseFloat(document.getElementById('sig_time')"
                                   f".textContent) > {t1 + 0.2}")  # the WebSocket streams
            page.click("#ctrl_off")
            page.wait_for_function("document.getElementById('controller').textContent === 'off'")
            # a refused set-point is shown on the page; the run goes on
            page.fill("#ref_angular", "400")
            page.click("#apply_ref")
            page.wait_for_function("document.getElementById('refused').textContent"
                                   ".includes('admissible range')")
            browser.close()
        assert runner.controller_enabled is False and runner.reference["angular"] == 20.0
        assert session.running
    finally:
        session.stop()
