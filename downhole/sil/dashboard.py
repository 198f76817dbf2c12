"""Live dashboard of a real-time run: FastAPI + WebSocket, one self-contained HTML page.

``GET /`` serves the page; ``WS /ws`` pushes the newest recorded row (bit and surface signals,
references, commands), the runtime counters (deadline misses, overruns, late commands), the
state (running, controller on, safe action) and the last events, ``publish_hz`` times a
second. Controls (``POST``, JSON bodies only): ``/api/start``, ``/api/stop``,
``/api/controller`` ``{"on": bool}``, ``/api/reference`` ``{"axial": m/s, "angular": rad/s}``.

Security (every HTTP request and every WebSocket handshake, before any route, the API docs
``/docs``, ``/redoc``, ``/openapi.json`` included):

- **Host**: the ``Host`` header must name the address the server was bound to (on loopback:
  ``127.0.0.1``, ``localhost`` or ``[::1]``; on a wildcard address: this machine's names) or one
  of ``allowed_hosts``, with the server's port: a DNS-rebinding page is refused (400).
- **Origin**: a request that carries ``Origin`` must come from the dashboard's own origin or
  one of ``allowed_origins``; a browser request without ``Origin`` but marked cross-site by
  ``Sec-Fetch-Site`` is refused too, except a top-level navigation (403; WebSocket: closed
  with 1008 before the handshake completes).
- **JSON only**: ``POST`` (and any other method with a body) needs ``Content-Type:
  application/json`` (415 otherwise), so no form or ``text/plain`` post reaches a control.
- **Token** (when set; required to bind beyond loopback, at least 16 characters there): the
  header ``Authorization: Bearer TOKEN`` or ``X-Downhole-Token: TOKEN``, or the cookie
  ``downhole_token``, on every route and on the WebSocket (403 / close 1008 otherwise).
  ``GET /?token=TOKEN`` is the one place a query token is read: it sets the cookie (HttpOnly,
  SameSite=Strict) and redirects to ``/``. The token is never printed in full.
- **Set-points**: ``/api/reference`` takes finite numbers within the declared range
  (``reference_limits``; 422 and a message otherwise); ``/api/controller`` takes a boolean.
- **No NaN on the wire**: ``/api/state`` and ``/ws`` replace non-finite numbers by ``null``
  and record a ``dashboard_non_finite`` event naming the fields.

Refusals are counted in :attr:`DashboardSession.refused` (shown in the state as ``refused``).
"""


import asyncio
import hmac
import ipaddress
import json
import math
import socket
import threading
from http.cookies import CookieError, SimpleCookie
from numbers import Integral, Real
from urllib.parse import parse_qs

from downhole.errors import DownholeInputError

__all__ = ["DashboardSession", "make_app", "serve_dashboard", "is_loopback", "TOKEN_COOKIE",
           "DEFAULT_REFERENCE_LIMITS", "MIN_REMOTE_TOKEN", "check_dashboard_settings"]

SIGNALS = ("bit_axial_velocity", "bit_angular_velocity", "wob", "tob", "hook_load",
           "surface_torque", "top_drive_angular_velocity", "top_drive_axial_velocity",
           "reference_axial_velocity", "reference_angular_velocity")

#: Name of the cookie that carries the token.
TOKEN_COOKIE = "downhole_token"
#: Admissible set-points when none are declared: axial m/s, angular rad/s (``[reference]``).
DEFAULT_REFERENCE_LIMITS = {"axial": (0.0, 0.05), "angular": (0.0, 40.0)}
#: Shortest token accepted when the dashboard binds beyond loopback.
MIN_REMOTE_TOKEN = 16
_UNITS = {"axial": "m/s", "angular": "rad/s"}
_WILDCARDS = ("0.0.0.0", "::", "")
_SECURITY_HEADERS = [(b"x-frame-options", b"DENY"),
                     (b"content-security-policy", b"frame-ancestors 'none'"),
                     (b"x-content-type-options", b"nosniff"),
                     (b"referrer-policy", b"no-referrer"),
                     (b"cache-control", b"no-store")]


def is_loopback(host: str) -> bool:
    """True for 127.0.0.0/8, ::1 and ``localhost``."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def _norm_host(name: str) -> str:
    return name.strip().lower().strip("[]").rstrip(".")


def _split_host(value: str) -> tuple[str, int | None] | None:
    """``"[::1]:8765"`` -> ``("::1", 8765)``; ``"localhost"`` -> ``("localhost", None)``;
    None when malformed."""
    value = value.strip()
    if not value or any(c.isspace() or c in "/@?#\\" for c in value):
        return None
    if value.startswith("["):
        end = value.find("]")
        if end < 0:
            return None
        name, rest = value[1:end], value[end + 1:]
        if rest and not rest.startswith(":"):
            return None
        port = rest[1:] if rest else None
    else:
        if value.count(":") > 1:
            return None
        name, _, port = value.partition(":")
        port = port if ":" in value else None
    if port is not None:
        if not port.isdigit() or not 0 < int(port) < 65536:
            return None
        port = int(port)
    return _norm_host(name), port


def default_allowed_hosts(host: str) -> set[str]:
    """Host names a browser may use to reach a server bound to ``host`` (see module doc)."""
    names = {"localhost", "127.0.0.1", "::1"} if is_loopback(host) else {_norm_host(host)}
    if host in _WILDCARDS:
        names = {"localhost", "127.0.0.1", "::1"}
        for n in (socket.gethostname(), socket.getfqdn()):
            if n:
                names.add(_norm_host(n))
    return names


def _finite_tree(obj, path: str, bad: list):
    """Copy of ``obj`` with every non-finite number replaced by None (paths into ``bad``)."""
    if isinstance(obj, dict):
        return {k: _finite_tree(v, f"{path}.{k}" if path else str(k), bad)
                for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite_tree(v, f"{path}[{i}]", bad) for i, v in enumerate(obj)]
    if isinstance(obj, bool) or obj is None or isinstance(obj, str):
        return obj
    if isinstance(obj, Integral):
        return int(obj)
    if isinstance(obj, Real):
        v = float(obj)
        if math.isfinite(v):
            return v
        bad.append(path)
        return None
    return str(obj)


class DashboardSession:
    """Runs a :class:`~downhole.sil.runtime.RealTimeRunner` in a background thread for the
    dashboard: ``start()`` (fresh the first time, then resumes), ``stop()``, ``snapshot()``.

    Parameters
    ----------
    runner : RealTimeRunner
    duration : float, optional
        Simulated seconds of the whole run (None: until stopped).

    Attributes
    ----------
    refused : dict
        Requests refused by the dashboard's checks, by reason (``host``, ``origin``,
        ``content_type``, ``token``).
    """

    def __init__(self, runner, duration: float | None = None):
        self.runner = runner
        self.duration = duration
        self._thread: threading.Thread | None = None
        self._started_once = False
        self.error: str | None = None
        self.finished = threading.Event()
        self.refused = {"host": 0, "origin": 0, "content_type": 0, "token": 0}
        self._non_finite_reported: set[str] = set()
        self._lock = threading.Lock()

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def start(self) -> bool:
        """Start (or resume) the run in a background thread; False when already running or
        the duration is used up."""
        with self._lock:
            if self.running:
                return False
            fresh = not self._started_once
            remaining = self.duration
            if remaining is not None and not fresh:
                remaining = self.duration - self.runner._k * self.runner.dt
                if remaining <= 1e-12:
                    return False
            self._started_once = True

            def work():
                try:
                    self.runner.run(remaining, reset=fresh)
                except Exception as exc:  # noqa: BLE001 - shown on the page
                    self.error = f"{type(exc).__name__}: {exc}"
                finally:
                    if self.duration is not None and \
                            self.runner._k * self.runner.dt >= self.duration - 1e-9:
                        self.finished.set()

            self._thread = threading.Thread(target=work, name="downhole-sil-runtime",
                                            daemon=True)
            self._thread.start()
            return True

    def stop(self) -> None:
        """Ask the run to stop and wait for it (up to 5 s)."""
        self.runner.stop()
        if self._thread is not None:
            self._thread.join(timeout=5.0)

    def snapshot(self) -> dict:
        """The state sent to the page: JSON-safe, every non-finite number replaced by None
        (a ``dashboard_non_finite`` event names new offenders once)."""
        r = self.runner
        row = r.recorder.latest()
        sig = {k: row.get(k) for k in (*SIGNALS, "time")}
        for c in r.plant.command_names:
            sig[f"command_{c}"] = row.get(f"command_{c}")
        ev = list(r.events)[-5:]
        events = []
        for e in ev:
            t = e.get("time")
            ts = f"{t:.3f} s" if isinstance(t, Real) and math.isfinite(t) else "? s"
            events.append(f"{ts} {e.get('kind')} {e.get('detail')}")
        raw = {"signals": sig, "stats": dict(r.stats), "running": self.running,
               "controller_enabled": bool(r.controller_enabled),
               "safe_action": r._safe_since is not None, "reference": dict(r.reference),
               "events": events, "error": self.error, "model": r.plant.name,
               "scheduler": r.scheduler, "refused": dict(self.refused)}
        bad: list[str] = []
        out = _finite_tree(raw, "", bad)
        new = sorted(set(bad) - self._non_finite_reported)
        if new:
            self._non_finite_reported.update(new)
            r._event("dashboard_non_finite", "null sent for " + ", ".join(new))
        return out


def _check_token(given: str | None, token: str) -> bool:
    if given is None:
        return False
    return hmac.compare_digest(given.encode("utf-8", "surrogatepass"), token.encode("utf-8"))


class _Guard:
    """ASGI middleware: Host, Origin, content type and token checks (module docstring)."""

    def __init__(self, app, *, session, token, allowed_hosts, allowed_origins, port):
        self.app = app
        self.session = session
        self.token = token
        self.hosts = allowed_hosts
        self.origins = allowed_origins
        self.port = port

    def _refuse_reason(self, scope, headers: dict) -> tuple[str, int, str] | None:
        hosts = headers.get("host", [])
        if len(hosts) != 1:
            return "host", 400, "exactly one Host header is required"
        parsed = _split_host(hosts[0])
        if parsed is None or parsed[0] not in self.hosts:
            return "host", 400, f"Host {hosts[0]!r} is not this dashboard's address"
        if self.port is not None and (parsed[1] if parsed[1] is not None else 80) != self.port:
            return "host", 400, f"Host {hosts[0]!r} does not name port {self.port}"
        origins = headers.get("origin", [])
        if len(origins) > 1:
            return "origin", 403, "more than one Origin header"
        if origins:
            o = origins[0].strip().rstrip("/").lower()
            same = {f"http://{hosts[0].strip().lower()}", f"https://{hosts[0].strip().lower()}"}
            if o not in same and o not in self.origins:
                return "origin", 403, f"cross-origin request from {origins[0]!r} refused"
        else:
            site = (headers.get("sec-fetch-site") or [""])[0].lower()
            mode = (headers.get("sec-fetch-mode") or [""])[0].lower()
            nav = scope["type"] == "http" and scope.get("method") in ("GET", "HEAD") \
                and mode == "navigate"
            if site in ("cross-site", "same-site") and not nav:
                return "origin", 403, "cross-site request refused"
        if scope["type"] == "http" and scope.get("method") not in ("GET", "HEAD", "OPTIONS"):
            ctype = (headers.get("content-type") or [""])[0].split(";")[0].strip().lower()
            if ctype != "application/json":
                return ("content_type", 415,
                        "send JSON (Content-Type: application/json); got "
                        f"{ctype or 'no content type'}")
        return None

    def _given_token(self, headers: dict) -> str | None:
        auth = (headers.get("authorization") or [""])[0].strip()
        if auth[:7].lower() == "bearer ":
            return auth[7:].strip()
        if headers.get("x-downhole-token"):
            return headers["x-downhole-token"][0].strip()
        for raw in headers.get("cookie", []):
            try:
                c = SimpleCookie()
                c.load(raw)
            except CookieError:
                continue
            if TOKEN_COOKIE in c:
                return c[TOKEN_COOKIE].value
        return None

    async def __call__(self, scope, receive, send):
        if scope["type"] not in ("http", "websocket"):
            return await self.app(scope, receive, send)
        headers: dict[str, list[str]] = {}
        for k, v in scope.get("headers", []):
            headers.setdefault(k.decode("latin-1").lower(), []).append(v.decode("latin-1"))
        why = self._refuse_reason(scope, headers)
        login = None
        if why is None and self.token is not None:
            if not _check_token(self._given_token(headers), self.token):
                query = parse_qs(scope.get("query_string", b"").decode("latin-1"))
                q = query.get("token")
                if (scope["type"] == "http" and scope.get("method") == "GET"
                        and scope.get("path") == "/" and q and _check_token(q[0], self.token)):
                    login = q[0]
                else:
                    why = ("token", 403, "missing or wrong token (Authorization: Bearer, "
                           f"X-Downhole-Token or the {TOKEN_COOKIE} cookie)")
        if why is not None:
            self.session.refused[why[0]] += 1
            if scope["type"] == "websocket":
                await send({"type": "websocket.close", "code": 1008, "reason": why[2][:120]})
                return
            return await self._respond(send, why[1], json.dumps({"detail": why[2]}).encode(),
                                       [(b"content-type", b"application/json")])
        if login is not None:
            cookie = (f"{TOKEN_COOKIE}={login}; HttpOnly; SameSite=Strict; Path=/").encode()
            return await self._respond(send, 303, b"", [(b"location", b"/"),
                                                        (b"set-cookie", cookie)])
        if scope["type"] == "websocket":
            return await self.app(scope, receive, send)

        async def send_secure(message):
            if message["type"] == "http.response.start":
                message = dict(message)
                message["headers"] = list(message.get("headers", [])) + _SECURITY_HEADERS
            await send(message)

        return await self.app(scope, receive, send_secure)

    @staticmethod
    async def _respond(send, status: int, body: bytes, headers: list):
        await send({"type": "http.response.start", "status": status,
                    "headers": headers + _SECURITY_HEADERS
                    + [(b"content-length", str(len(body)).encode())]})
        await send({"type": "http.response.body", "body": body})


def _setpoint(body: dict, name: str, limits: dict):
    from fastapi import HTTPException

    v = body.get(name)
    if v is None:
        return None
    unit = _UNITS[name]
    if isinstance(v, bool) or not isinstance(v, Real):
        raise HTTPException(status_code=422, detail=f"{name} must be a number ({unit}), got "
                                                    f"{json.dumps(v)[:40]}")
    try:
        v = float(v)
    except OverflowError:
        v = math.inf
    if not math.isfinite(v):
        raise HTTPException(status_code=422, detail=f"{name} must be finite ({unit}), got {v}")
    lo, hi = limits[name]
    if not lo <= v <= hi:
        raise HTTPException(status_code=422, detail=f"{name} = {v:g} {unit} is outside the "
                                                    f"admissible range [{lo:g}, {hi:g}] {unit}")
    return v


def make_app(session: DashboardSession, token: str | None = None, publish_hz: float = 20.0, *,
             host: str = "127.0.0.1", port: int | None = None, allowed_hosts=(),
             allowed_origins=(), reference_limits: dict | None = None):
    """The FastAPI application for ``session`` (see the module docstring).

    Parameters
    ----------
    session : DashboardSession
    token : str, optional
        Required on every request when set.
    publish_hz : float
        WebSocket updates per second.
    host : str
        The address the server binds (decides the default allowed Host names).
    port : int, optional
        The server's port: a ``Host`` header must name it (None or 0: any port).
    allowed_hosts : iterable of str
        Extra Host names (e.g. the name of a rig PC the dashboard is browsed by).
    allowed_origins : iterable of str
        Extra origins (``scheme://host[:port]``) allowed to call the API.
    reference_limits : dict, optional
        ``{"axial": (lo, hi), "angular": (lo, hi)}`` in m/s and rad/s
        (default :data:`DEFAULT_REFERENCE_LIMITS`).
    """
    from fastapi import FastAPI, HTTPException, Request, WebSocket, WebSocketDisconnect
    from fastapi.responses import HTMLResponse, JSONResponse

    check_dashboard_settings("127.0.0.1", token)
    limits = dict(DEFAULT_REFERENCE_LIMITS)
    limits.update(reference_limits or {})
    for name, (lo, hi) in limits.items():
        if name not in _UNITS or not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            raise DownholeInputError(f"reference_limits[{name!r}] must be finite (lo, hi) with "
                                     f"lo < hi, got {(lo, hi)!r}")
    hosts = default_allowed_hosts(host) | {_norm_host(h) for h in allowed_hosts}
    origins = {o.strip().rstrip("/").lower() for o in allowed_origins}

    app = FastAPI(title="downhole SIL dashboard")
    app.add_middleware(_Guard, session=session, token=token, allowed_hosts=hosts,
                       allowed_origins=origins, port=port or None)

    async def json_object(request: Request) -> dict:
        raw = await request.body()
        if not raw.strip():
            return {}
        try:
            body = json.loads(raw)
        except (ValueError, UnicodeDecodeError):
            raise HTTPException(status_code=400, detail="the body is not valid JSON") from None
        if not isinstance(body, dict):
            raise HTTPException(status_code=422, detail="the body must be a JSON object")
        return body

    @app.get("/", response_class=HTMLResponse)
    def index():
        return _PAGE

    @app.get("/api/state")
    def state():
        return JSONResponse(session.snapshot())

    @app.post("/api/start")
    def start():
        return {"started": session.start()}

    @app.post("/api/stop")
    def stop():
        session.stop()
        return {"running": session.running}

    @app.post("/api/controller")
    async def controller(request: Request):
        body = await json_object(request)
        if set(body) - {"on"} or not isinstance(body.get("on"), bool):
            raise HTTPException(status_code=422, detail='send {"on": true} or {"on": false}')
        session.runner.set_controller_enabled(body["on"])
        return {"controller_enabled": session.runner.controller_enabled}

    @app.post("/api/reference")
    async def reference(request: Request):
        body = await json_object(request)
        extra = set(body) - {"axial", "angular"}
        if extra:
            raise HTTPException(status_code=422, detail=f"unknown field(s) {sorted(extra)}; "
                                                        "expected axial (m/s), angular (rad/s)")
        ax = _setpoint(body, "axial", limits)
        an = _setpoint(body, "angular", limits)
        if ax is None and an is None:
            raise HTTPException(status_code=422, detail="give axial (m/s) and/or angular (rad/s)")
        session.runner.set_reference(ax, an)
        return {"reference": session.runner.reference}

    @app.websocket("/ws")
    async def ws(websocket: WebSocket):
        await websocket.accept()
        try:
            while True:
                await websocket.send_text(json.dumps(session.snapshot(), allow_nan=False))
                await asyncio.sleep(1.0 / publish_hz)
        except (WebSocketDisconnect, RuntimeError):
            return

    return app


def check_dashboard_settings(host: str, token: str | None) -> None:
    """Refuse settings the dashboard will not serve with (called before a run starts).

    Raises
    ------
    DownholeInputError
        A non-loopback ``host`` without a token, or with one shorter than
        :data:`MIN_REMOTE_TOKEN`; a token with spaces, quotes, commas, semicolons or
        backslashes (it must fit in a cookie).
    """
    if token is not None and (not isinstance(token, str) or not token
                              or any(c.isspace() or c in ";,\"\\" for c in token)):
        raise DownholeInputError("the dashboard token must be a non-empty string without "
                                 "spaces, quotes, commas, semicolons or backslashes")
    if not is_loopback(host):
        if not token:
            raise DownholeInputError(f"the dashboard binds {host!r}, which is not loopback: set "
                                     "[dashboard] token or token_file (every request must then "
                                     "carry it)")
        if len(token) < MIN_REMOTE_TOKEN:
            raise DownholeInputError(
                f"the dashboard binds {host!r}, which is not loopback: the token must have at "
                f"least {MIN_REMOTE_TOKEN} characters, e.g. python -c 'import secrets; "
                "print(secrets.token_urlsafe(24))'")


def _describe_token(token: str, source: str | None) -> str:
    hint = f"{token[:4]}... ({len(token)} characters)" if len(token) >= MIN_REMOTE_TOKEN \
        else f"{len(token)} characters"
    return f"token {hint}" + (f" from {source}" if source else "")


def serve_dashboard(runner, host: str = "127.0.0.1", port: int = 8765,
                    token: str | None = None, duration: float | None = None,
                    publish_hz: float = 20.0, autostart: bool = True, *, allowed_hosts=(),
                    allowed_origins=(), token_source: str | None = None,
                    reference_limits: dict | None = None) -> None:
    """Serve the dashboard (blocking) until Ctrl-C or, with ``duration``, the run's end.

    Parameters are those of :func:`make_app`; ``token_source`` (a file path or a scenario
    field) is printed instead of the token, of which at most a 4-character prefix is shown.

    Raises
    ------
    DownholeInputError
        ``host`` is not a loopback address and no ``token`` (of at least
        :data:`MIN_REMOTE_TOKEN` characters) is given.
    """
    import uvicorn

    check_dashboard_settings(host, token)
    session = DashboardSession(runner, duration)
    app = make_app(session, token, publish_hz, host=host, port=port,
                   allowed_hosts=allowed_hosts, allowed_origins=allowed_origins,
                   reference_limits=reference_limits)
    server = uvicorn.Server(uvicorn.Config(app, host=host, port=port, log_level="warning"))
    if autostart:
        session.start()

    def watch():
        session.finished.wait()
        server.should_exit = True

    threading.Thread(target=watch, daemon=True).start()
    shown = f"[{host}]" if ":" in host else host
    print(f"dashboard: http://{shown}:{port}/", flush=True)
    if token:
        print(f"  {_describe_token(token, token_source)} required: open "
              f"http://{shown}:{port}/?token=<token> once (sets a cookie), or send "
              "'Authorization: Bearer <token>'", flush=True)
    try:
        server.run()
    finally:
        session.stop()


_PAGE = r"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>downhole SIL dashboard</title>
<style>
body{font-family:system-ui,sans-serif;margin:16px;background:#f7f7f9;color:#222}
h1{font-size:20px;margin:0 0 8px}
.row{display:flex;gap:16px;flex-wrap:wrap}
.card{background:#fff;border:1px solid #ddd;border-radius:6px;padding:10px 14px}
table{border-collapse:collapse}td{padding:2px 8px;font-variant-numeric:tabular-nums}
td.v{text-align:right;min-width:110px}
button{margin:2px 4px 2px 0;padding:5px 12px}
#status span{font-weight:600}.bad{color:#b00}.good{color:#080}
canvas{background:#fff;border:1px solid #ddd}
</style></head><body>
<h1>downhole real-time SIL &mdash; <span id="model"></span></h1>
<div class="row">
 <div class="card" id="status">
  run: <span id="running">?</span> &nbsp; controller: <span id="controller">?</span>
  &nbsp; safe action: <span id="safe">?</span><br>
  t = <span id="time">0</span> s &nbsp; deadline misses: <span id="misses">0</span>
  (<span id="missfrac">0</span> %) &nbsp; overruns: <span id="overruns">0</span>
  &nbsp; late commands: <span id="late">0</span> &nbsp; scheduler: <span id="sched"></span>
  <div>
   <button id="start">Start</button><button id="stop">Stop</button>
   <button id="ctrl_on">Controller on</button><button id="ctrl_off">Controller off</button>
  </div>
  <div>reference: axial <input id="ref_axial" size="7"> m/s, angular
   <input id="ref_angular" size="7"> rad/s <button id="apply_ref">Apply</button></div>
  <div id="error" class="bad"></div><div id="refused" class="bad"></div>
 </div>
 <div class="card"><table id="signals"></table></div>
</div>
<div class="row" style="margin-top:12px">
 <canvas id="plot_w" width="640" height="220"></canvas>
 <canvas id="plot_v" width="640" height="220"></canvas>
</div>
<div class="card" style="margin-top:12px"><b>events</b><pre id="events"></pre></div>
<script>
// the token (when one is set) travels in the HttpOnly cookie set by GET /?token=...
const UNITS = {bit_axial_velocity:"m/s", bit_angular_velocity:"rad/s", wob:"N", tob:"N m",
  hook_load:"N", surface_torque:"N m", top_drive_angular_velocity:"rad/s",
  top_drive_axial_velocity:"m/s", reference_axial_velocity:"m/s",
  reference_angular_velocity:"rad/s", time:"s"};
const hist = {t:[], w:[], wr:[], v:[], vr:[]};
let refFilled = false;
function post(path, body){
  return fetch(path, {method:"POST", headers:{"Content-Type":"application/json"},
    body: JSON.stringify(body || {})}).then(r => r.ok ? null : r.json().then(j => {
      document.getElementById("refused").textContent = path + ": " + j.detail; }));
}
document.getElementById("start").onclick = () => post("/api/start");
document.getElementById("stop").onclick = () => post("/api/stop");
document.getElementById("ctrl_on").onclick = () => post("/api/controller", {on:true});
document.getElementById("ctrl_off").onclick = () => post("/api/controller", {on:false});
document.getElementById("apply_ref").onclick = () => post("/api/reference", {
  axial: parseFloat(document.getElementById("ref_axial").value),
  angular: parseFloat(document.getElementById("ref_angular").value)});
function fmt(x){ if (x === null || x === undefined) return "-";
  const a = Math.abs(x); return (a !== 0 && (a < 1e-3 || a >= 1e5)) ? x.toExponential(4) : x.toFixed(4); }
function draw(id, t, a, b, label){
  const c = document.getElementById(id), g = c.getContext("2d");
  g.clearRect(0, 0, c.width, c.height);
  if (t.length < 2) return;
  const all = a.concat(b).filter(x => x !== null);
  let lo = Math.min(...all), hi = Math.max(...all); if (hi - lo < 1e-9) { hi += 1; lo -= 1; }
  const X = i => 40 + (c.width - 50) * (t[i] - t[0]) / Math.max(t[t.length-1] - t[0], 1e-9);
  const Y = y => c.height - 20 - (c.height - 40) * (y - lo) / (hi - lo);
  for (const [s, col] of [[b, "#999"], [a, "#1565c0"]]) {
    g.strokeStyle = col; g.beginPath();
    s.forEach((y, i) => { if (y === null) return; i ? g.lineTo(X(i), Y(y)) : g.moveTo(X(i), Y(y)); });
    g.stroke(); }
  g.fillStyle = "#222"; g.fillText(label + "  [" + fmt(lo) + ", " + fmt(hi) + "]", 44, 14);
}
function update(s){
  document.getElementById("model").textContent = s.model;
  const r = document.getElementById("running"); r.textContent = s.running ? "running" : "stopped";
  r.className = s.running ? "good" : "bad";
  const c = document.getElementById("controller");
  c.textContent = s.controller_enabled ? "on" : "off"; c.className = s.controller_enabled ? "good" : "bad";
  document.getElementById("safe").textContent = s.safe_action ? "ACTIVE" : "no";
  document.getElementById("time").textContent = fmt(s.signals.time);
  document.getElementById("misses").textContent = s.stats.deadline_misses;
  document.getElementById("missfrac").textContent =
    (100 * s.stats.deadline_misses / Math.max(s.stats.steps, 1)).toFixed(2);
  document.getElementById("overruns").textContent = s.stats.overruns;
  document.getElementById("late").textContent = s.stats.late_commands;
  document.getElementById("sched").textContent = s.scheduler;
  document.getElementById("error").textContent = s.error || "";
  if (!refFilled) { document.getElementById("ref_axial").value = s.reference.axial;
    document.getElementById("ref_angular").value = s.reference.angular; refFilled = true; }
  const tb = document.getElementById("signals"); let html = "";
  for (const [k, v] of Object.entries(s.signals))
    html += "<tr><td>" + k + "</td><td class='v' id='sig_" + k + "'>" + fmt(v) + "</td><td>" +
            (UNITS[k] || "") + "</td></tr>";
  tb.innerHTML = html;
  document.getElementById("events").textContent = s.events.join("\n");
  const t = s.signals.time;
  if (t !== null && (hist.t.length === 0 || t !== hist.t[hist.t.length-1])) {
    if (hist.t.length && t < hist.t[hist.t.length-1]) for (const k in hist) hist[k] = [];
    hist.t.push(t); hist.w.push(s.signals.bit_angular_velocity);
    hist.wr.push(s.signals.reference_angular_velocity);
    hist.v.push(s.signals.bit_axial_velocity); hist.vr.push(s.signals.reference_axial_velocity);
    if (hist.t.length > 600) for (const k in hist) hist[k].shift();
  }
  draw("plot_w", hist.t, hist.w, hist.wr, "bit angular velocity (rad/s) vs reference");
  draw("plot_v", hist.t, hist.v, hist.vr, "bit axial velocity (m/s) vs reference");
}
function connect(){
  const ws = new WebSocket((location.protocol === "https:" ? "wss://" : "ws://") + location.host + "/ws");
  ws.onmessage = ev => update(JSON.parse(ev.data));
  ws.onclose = () => setTimeout(connect, 1000);
}
connect();
</script></body></html>
"""
