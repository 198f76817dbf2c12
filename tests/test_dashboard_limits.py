"""The dashboard's resource limits (issue 27, item 1), tried on 127.0.0.1 servers.

Half-open connections and slow headers (slowloris), bodies too large (a declared 100 MB JSON
refused with 413 before it is read, a chunked one once the limit is read), token guessing
(locked out after N wrong tokens: 429, per client address), short tokens beyond loopback, and
Stop answering the operator while another address does all of this. Attackers connect from
127.0.0.2 (the whole of 127.0.0.0/8 is loopback), the operator from 127.0.0.1.

The checks are statuses, counters and what the server did; times are only hang guards.
"""

import http.client
import json
import re
import select
import socket
import time

import pytest
from fastapi.testclient import TestClient
from starlette.websockets import WebSocketDisconnect

from downhole.errors import DownholeInputError
from downhole.sil import RealTimeRunner, build_plant, pi_controller_for
from downhole.sil.dashboard import (
    DashboardLimits,
    DashboardSession,
    check_dashboard_settings,
    make_app,
    serve_dashboard,
)
from downhole.sil.testing import ServerThread, free_port

TOKEN = "k3y-for-tests-0123456789abcdef"
ATTACKER = "127.0.0.2"
GUARD = 15.0  # hang guard of every wait, s (never an expected duration)


def _runner():
    plant = build_plant("lumped")
    return RealTimeRunner(plant, pi_controller_for(plant), record_every=10)


def _until(cond, timeout: float = GUARD) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if cond():
            return True
        time.sleep(0.02)
    return cond()


def _raw(port: int, source: str = "127.0.0.1") -> socket.socket:
    s = socket.create_connection(("127.0.0.1", port), timeout=GUARD, source_address=(source, 0))
    return s


def _request(port, method, path, body=None, token=TOKEN, source="127.0.0.1", headers=None):
    """One HTTP request (its own connection): ``(status, headers, body)``."""
    c = http.client.HTTPConnection("127.0.0.1", port, timeout=GUARD, source_address=(source, 0))
    h = {"Content-Type": "application/json", **(headers or {})}
    if token is not None:
        h["Authorization"] = f"Bearer {token}"
    try:
        c.request(method, path, body=None if body is None else json.dumps(body), headers=h)
        r = c.getresponse()
        return r.status, dict(r.getheaders()), r.read()
    finally:
        c.close()


def _closed_by_server(s: socket.socket, timeout: float = GUARD) -> bool:
    """True when the server closed ``s`` (EOF or reset) before ``timeout``; what it sent
    before is ignored."""
    s.settimeout(timeout)
    try:
        while True:
            if not s.recv(65536):
                return True
    except (ConnectionResetError, BrokenPipeError):
        return True
    except TimeoutError:
        return False


def _server(limits=None, token=TOKEN, duration=600.0):
    session = DashboardSession(_runner(), duration=duration)
    port = free_port()
    app = make_app(session, token, port=port, limits=limits)
    return session, port, ServerThread(app, port)


# ------------------------------------------------------------------------------- settings
def test_limits_and_remote_tokens_are_checked():
    for bad in ({"max_connections": 0}, {"max_body_bytes": -1}, {"token_failures": 1.5},
                {"request_timeout": 0}, {"lockout": float("nan")}, {"request_timeout": True}):
        with pytest.raises(DownholeInputError, match=next(iter(bad))):
            DashboardLimits(**bad)
    d = DashboardLimits()
    assert (d.max_connections, d.max_connections_per_client, d.request_timeout,
            d.max_body_bytes, d.token_failures, d.lockout) == (64, 16, 10.0, 65536, 10, 60.0)
    # beyond loopback: a token, and one of 16 characters at least
    for token in (None, "short", "x" * 15):
        with pytest.raises(DownholeInputError, match="not loopback"):
            check_dashboard_settings("0.0.0.0", token)
        with pytest.raises(DownholeInputError, match="not loopback"):
            serve_dashboard(_runner(), host="192.0.2.1", token=token)
    check_dashboard_settings("0.0.0.0", "x" * 16)
    check_dashboard_settings("127.0.0.1", "short")  # loopback: any token
    with pytest.raises(DownholeInputError, match="DashboardLimits"):
        make_app(DashboardSession(_runner()), limits={"max_connections": 4})


# ------------------------------------------------------------------------------- slowloris
def test_half_open_connections_are_capped_per_client_and_closed_after_the_request_timeout():
    limits = DashboardLimits(max_connections=16, max_connections_per_client=4,
                             request_timeout=1.0)
    session, port, server = _server(limits)
    with server:
        head = f"GET /api/state HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n".encode()
        socks = []
        for i in range(10):  # half of them send half a request head, the others nothing
            s = _raw(port, ATTACKER)
            if i % 2:
                s.sendall(head)
            socks.append(s)
        # 4 kept (for now), 6 closed as soon as they are accepted
        assert _until(lambda: session.refused["connections"] == 6)
        # the operator, from another address, is served meanwhile
        status, _, body = _request(port, "GET", "/api/state")
        assert status == 200 and "phase" in json.loads(body)
        # the 4 kept ones never complete their head: closed at the deadline, none answered
        assert _until(lambda: session.refused["timeout"] == 4)
        assert all(_closed_by_server(s) for s in socks)
        for s in socks:
            s.close()
        # capacity is back: the attacker's address is served again (it never got a lockout)
        assert _request(port, "GET", "/api/state", source=ATTACKER)[0] == 200
    assert session.refused["connections"] == 6 and session.refused["timeout"] == 4


def test_slow_headers_are_cut_off_and_never_answered():
    """A head sent a byte at a time, without end: the connection is closed (it would hold a
    slot for ever with uvicorn's defaults)."""
    session, port, server = _server(DashboardLimits(request_timeout=1.0))
    with server:
        s = _raw(port, ATTACKER)
        s.settimeout(0.1)
        trickle = f"GET /api/state HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nX-Slow: ".encode()
        sent, closed, answer = 0, False, b""
        end = time.monotonic() + GUARD
        while time.monotonic() < end and not closed:
            try:
                s.send(trickle[sent % len(trickle):][:1] if sent < len(trickle) else b"a")
                sent += 1
                if select.select([s], [], [], 0.1)[0]:
                    chunk = s.recv(4096)
                    answer += chunk
                    closed = not chunk
            except (ConnectionResetError, BrokenPipeError):
                closed = True
        s.close()
        assert closed and not answer.startswith(b"HTTP/1.1 200")
        assert session.refused["timeout"] == 1
        # a slow body: the head is complete, the body never is
        s = _raw(port, ATTACKER)
        s.sendall(f"POST /api/reference HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n"
                  f"Authorization: Bearer {TOKEN}\r\nContent-Type: application/json\r\n"
                  "Content-Length: 100\r\n\r\n{".encode())
        assert _closed_by_server(s)
        s.close()
        assert session.refused["timeout"] == 2
        assert session.runner.reference["axial"] != 0.03  # nothing applied


def test_the_total_connection_cap_holds_across_addresses():
    limits = DashboardLimits(max_connections=6, max_connections_per_client=4,
                             request_timeout=1.0)
    session, port, server = _server(limits)
    with server:
        socks = [_raw(port, src) for src in ("127.0.0.2",) * 4 + ("127.0.0.3",) * 4]
        assert _until(lambda: session.refused["connections"] == 2)
        assert len(server.server.server_state.connections) <= 6
        assert _until(lambda: session.refused["timeout"] == 6)
        for s in socks:
            s.close()


# ------------------------------------------------------------------------------- bodies
def _post_streaming(port, head: bytes, chunk: bytes, total: int) -> tuple[bytes, int]:
    """Send ``head``, then ``chunk`` repeatedly up to ``total`` bytes, until the server
    answers or stops reading; returns ``(answer, body bytes sent)``."""
    s = _raw(port, ATTACKER)
    s.sendall(head)
    s.settimeout(2.0)
    sent = 0
    try:
        while sent < total:
            if select.select([s], [], [], 0)[0]:
                break  # answered (before the body is all there)
            sent += s.send(chunk)
    except (TimeoutError, ConnectionResetError, BrokenPipeError):
        pass  # the server stopped reading, or closed
    s.settimeout(GUARD)
    answer = b""
    try:
        while True:
            data = s.recv(65536)
            if not data:
                break
            answer += data
            if b"\r\n\r\n" in answer and answer.startswith(b"HTTP/1.1 413"):
                head, _, body = answer.partition(b"\r\n\r\n")
                m = re.search(rb"content-length: *(\d+)", head, re.IGNORECASE)
                if m is None or len(body) >= int(m.group(1)):
                    break  # the whole answer, body included (it may come in two segments)
    except (TimeoutError, ConnectionResetError):
        pass
    s.close()
    return answer, sent


def test_a_100_mb_json_body_is_refused_with_413_before_it_is_read():
    session, port, server = _server()
    total = 100 * 2**20
    with server:
        head = (f"POST /api/reference HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n"
                f"Authorization: Bearer {TOKEN}\r\nContent-Type: application/json\r\n"
                f"Content-Length: {total}\r\n\r\n").encode()
        answer, sent = _post_streaming(port, head, b" " * 65536, total)
        assert answer.startswith(b"HTTP/1.1 413"), answer[:200]
        assert b"at most 65536 bytes" in answer
        assert sent < total // 4  # refused early: most of it never left this process
        # chunked (no Content-Length): refused once the limit is read
        head = (f"POST /api/reference HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n"
                f"Authorization: Bearer {TOKEN}\r\nContent-Type: application/json\r\n"
                "Transfer-Encoding: chunked\r\n\r\n").encode()
        chunk = b"%x\r\n%s\r\n" % (16384, b" " * 16384)
        answer, sent = _post_streaming(port, head, chunk, total)
        assert answer.startswith(b"HTTP/1.1 413"), answer[:200]
        assert sent < total // 4
        # the operator is served meanwhile
        assert _request(port, "POST", "/api/reference", {"axial": 0.02})[0] == 200
    assert session.refused["too_large"] == 2
    assert session.runner.reference["axial"] == 0.02


def test_body_limit_at_the_byte():
    session = DashboardSession(_runner(), duration=600.0)
    app = make_app(session, TOKEN, port=8765, limits=DashboardLimits(max_body_bytes=100))
    c = TestClient(app, base_url="http://127.0.0.1:8765",
                   headers={"authorization": f"Bearer {TOKEN}"})
    body = json.dumps({"axial": 0.02}).encode()
    ok = body + b" " * (100 - len(body))
    assert c.post("/api/reference", content=ok,
                  headers={"content-type": "application/json"}).status_code == 200
    r = c.post("/api/reference", content=ok + b" ", headers={"content-type": "application/json"})
    assert r.status_code == 413 and "at most 100 bytes" in r.json()["detail"]
    for length in ("-1", "1e9", "abc"):  # a Content-Length that is not a small count
        r = c.post("/api/reference", content=b"{}",
                   headers={"content-type": "application/json", "content-length": length})
        assert r.status_code in (400, 413), length

    def chunks():  # no Content-Length: counted as it is read
        yield body
        yield b" " * 200

    r = c.post("/api/reference", content=chunks(), headers={"content-type": "application/json"})
    assert r.status_code == 413
    assert session.refused["too_large"] >= 2


# ------------------------------------------------------------------------------- tokens
def test_token_guessing_locks_the_address_out():
    limits = DashboardLimits(token_failures=5, lockout=1.0)
    session, port, server = _server(limits)
    with server:
        for i in range(5):
            st, _, _ = _request(port, "POST", "/api/stop", {}, token=f"guess-{i}",
                                source=ATTACKER)
            assert st == 403, i
        # locked out: every request refused with 429, the right token included
        st, headers, body = _request(port, "POST", "/api/stop", {}, source=ATTACKER)
        assert st == 429 and int(headers["retry-after"]) >= 1
        assert "too many wrong tokens" in json.loads(body)["detail"]
        assert _request(port, "GET", "/?token=" + TOKEN, token=None, source=ATTACKER)[0] == 429
        # other addresses are not: the operator is served
        assert _request(port, "GET", "/api/state")[0] == 200
        # a missing token is refused but is no guess: never locked out for that
        for _ in range(8):
            assert _request(port, "GET", "/api/state", token=None)[0] == 403
        assert _request(port, "GET", "/api/state")[0] == 200
        # once the lockout is over the right token works again (polled: 429 meanwhile)
        assert _until(lambda: _request(port, "GET", "/api/state", source=ATTACKER)[0] == 200)
    assert session.refused["token"] == 5 + 8
    assert session.refused["lockout"] >= 2


def test_a_right_token_resets_the_count_and_the_websocket_is_locked_out_too():
    session = DashboardSession(_runner(), duration=600.0)
    app = make_app(session, TOKEN, port=8765, limits=DashboardLimits(token_failures=3))
    c = TestClient(app, base_url="http://127.0.0.1:8765")
    good = {"authorization": f"Bearer {TOKEN}"}
    for _ in range(4):  # 2 wrong, then the right one: the count restarts
        assert c.get("/api/state", headers={"authorization": "Bearer nope"}).status_code == 403
        assert c.get("/api/state", headers={"x-downhole-token": "nope"}).status_code == 403
        assert c.get("/api/state", headers=good).status_code == 200
    for _ in range(3):
        assert c.get("/api/state", headers={"authorization": "Bearer nope"}).status_code == 403
    assert c.get("/api/state", headers=good).status_code == 429
    with pytest.raises(WebSocketDisconnect) as exc, \
            c.websocket_connect("ws://127.0.0.1:8765/ws", headers=good) as ws:
        ws.receive_text()
    assert exc.value.code == 1008
    assert session.refused["lockout"] == 2


# ------------------------------------------------------------------------------- Stop
def test_stop_answers_while_another_address_attacks():
    limits = DashboardLimits(max_connections=32, max_connections_per_client=8,
                             request_timeout=5.0, token_failures=3, lockout=60.0)
    session, port, server = _server(limits, duration=600.0)
    with server:
        assert _request(port, "POST", "/api/start", {})[0] == 200
        assert _until(lambda: session.running)
        # the attacker: its connections all held half-open, locked out for guessing, a big
        # body refused
        held = [_raw(port, ATTACKER) for _ in range(12)]
        assert _until(lambda: session.refused["connections"] >= 4)
        for s in held:
            s.close()
        assert _until(lambda: len(server.server.server_state.connections) == 0)
        for i in range(4):
            _request(port, "POST", "/api/stop", {}, token=f"guess-{i}", source=ATTACKER)
        assert _request(port, "POST", "/api/stop", {}, source=ATTACKER)[0] == 429
        held = [_raw(port, ATTACKER) for _ in range(8)]
        for s in held:
            s.sendall(f"POST /api/stop HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n".encode())
        assert session.running
        # the operator's Stop answers, and stops the run
        st, _, body = _request(port, "POST", "/api/stop", {})
        assert st == 200 and json.loads(body) == {"running": False}
        assert not session.running and session.phase == "stopped"
        for s in held:
            s.close()



# ------------------------------------------------------------------------------- --out
def test_a_dashboard_run_is_written_to_out_when_it_ends(tmp_path):
    """``downhole sil --dashboard --out``: the ended run is in ``--out`` while the dashboard
    still shows it, and the command's end (Ctrl-C) does not write it again."""
    import os
    import signal
    import subprocess
    import sys
    from pathlib import Path

    from downhole.sim.result import load_result

    sc = tmp_path / "s.toml"
    port, udp = free_port(), free_port()
    sc.write_text(f'[model]\nfidelity = "lumped4"\n[simulation]\nduration = "0.5 s"\n'
                  f'[link]\nport = {udp}\n[dashboard]\nport = 1\n')
    out = tmp_path / "run.nc"
    out.write_text("the previous result")
    root = Path(__file__).resolve().parents[1]
    env = dict(os.environ, PYTHONPATH=str(root))
    cmd = [sys.executable, "-c", "import sys; from downhole.cli import main; sys.exit(main())",
           "sil", str(sc), "--dashboard", "--autostart", "--http-port", str(port),
           "--no-progress", "--out", str(out)]
    proc = subprocess.Popen(cmd, cwd=tmp_path, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    marker = tmp_path / "run.nc.INCOMPLETE"
    try:
        def written():
            return out.is_file() and out.read_bytes()[:4] != b"the " and not marker.exists()

        assert _until(written, timeout=600), "the ended run was not written"  # liveness only
        assert proc.poll() is None  # the dashboard is still up, showing the run
        first = out.stat()
        res = load_result(out)
        assert res.time[-1] == pytest.approx(0.5) and "stopped_by" not in res.dataset.attrs
        assert _request(port, "GET", "/api/state", token=None)[0] == 200
        proc.send_signal(signal.SIGINT)
        _, stderr = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 0, stderr
    assert "(the run has ended)" in stderr and stderr.count(f"wrote {out}") == 1
    after = out.stat()
    assert (after.st_ino, after.st_mtime_ns) == (first.st_ino, first.st_mtime_ns)
    assert not marker.exists()
