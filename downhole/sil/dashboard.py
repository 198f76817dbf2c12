"""Live dashboard of a real-time run: FastAPI + WebSocket, one self-contained HTML page.

``GET /`` serves the page; ``WS /ws`` pushes the newest recorded row (bit and surface signals,
references, commands), the runtime counters (deadline misses, overruns, late commands), the
state (running, controller on, safe action) and the last events, ``publish_hz`` times a
second. Controls (``POST``, JSON): ``/api/start``, ``/api/stop``, ``/api/controller``
``{"on": bool}``, ``/api/reference`` ``{"axial": m/s, "angular": rad/s}``.

Security: the server binds 127.0.0.1 by default. Binding any other address requires a token
(:class:`~downhole.errors.DownholeInputError` otherwise); when a token is set every request
must carry it (``?token=...`` or header ``X-Downhole-Token``), else 403 / WebSocket close 1008.
"""


import asyncio
import hmac
import ipaddress
import json
import math
import threading

from downhole.errors import DownholeInputError

__all__ = ["DashboardSession", "make_app", "serve_dashboard", "is_loopback"]

SIGNALS = ("bit_axial_velocity", "bit_angular_velocity", "wob", "tob", "hook_load",
           "surface_torque", "top_drive_angular_velocity", "top_drive_axial_velocity",
           "reference_axial_velocity", "reference_angular_velocity")


def is_loopback(host: str) -> bool:
    """True for 127.0.0.0/8, ::1 and ``localhost``."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


class DashboardSession:
    """Runs a :class:`~downhole.sil.runtime.RealTimeRunner` in a background thread for the
    dashboard: ``start()`` (fresh the first time, then resumes), ``stop()``, ``snapshot()``."""

    def __init__(self, runner, duration: float | None = None):
        self.runner = runner
        self.duration = duration
        self._thread: threading.Thread | None = None
        self._started_once = False
        self.error: str | None = None
        self.finished = threading.Event()

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def start(self) -> bool:
        if self.running:
            return False
        fresh = not self._started_once
        self._started_once = True
        remaining = self.duration
        if remaining is not None and not fresh:
            remaining = self.duration - self.runner._k * self.runner.dt
            if remaining <= 0:
                return False

        def work():
            try:
                self.runner.run(remaining, reset=fresh)
            except Exception as exc:  # noqa: BLE001 - shown on the page
                self.error = f"{type(exc).__name__}: {exc}"
            finally:
                if self.duration is not None and \
                        self.runner._k * self.runner.dt >= self.duration - 1e-9:
                    self.finished.set()

        self._thread = threading.Thread(target=work, name="downhole-sil-runtime", daemon=True)
        self._thread.start()
        return True

    def stop(self) -> None:
        self.runner.stop()
        if self._thread is not None:
            self._thread.join(timeout=5.0)

    def snapshot(self) -> dict:
        r = self.runner
        row = r.recorder.latest()
        sig = {k: _num(row.get(k)) for k in (*SIGNALS, "time")}
        for c in r.plant.command_names:
            sig[f"command_{c}"] = _num(row.get(f"command_{c}"))
        ev = list(r.events)[-5:]
        return {"signals": sig, "stats": {k: _num(v) for k, v in r.stats.items()},
                "running": self.running, "controller_enabled": r.controller_enabled,
                "safe_action": r._safe_since is not None, "reference": r.reference,
                "events": [f"{e['time']:.3f} s {e['kind']} {e['detail']}" for e in ev],
                "error": self.error, "model": r.plant.name, "scheduler": r.scheduler}


def _num(v):
    if v is None:
        return None
    v = float(v)
    return v if math.isfinite(v) else None


def make_app(session: DashboardSession, token: str | None = None, publish_hz: float = 20.0):
    """The FastAPI application for ``session`` (see the module docstring)."""
    from fastapi import FastAPI, HTTPException, Request, WebSocket, WebSocketDisconnect
    from fastapi.responses import HTMLResponse

    app = FastAPI(title="downhole SIL dashboard")

    def _ok(given: str | None) -> bool:
        if token is None:
            return True
        return given is not None and hmac.compare_digest(str(given), token)

    def check(request: Request):
        given = request.query_params.get("token") or request.headers.get("x-downhole-token")
        if not _ok(given):
            raise HTTPException(status_code=403, detail="missing or wrong token")

    @app.get("/", response_class=HTMLResponse)
    def index(request: Request):
        check(request)
        return _PAGE

    @app.get("/api/state")
    def state(request: Request):
        check(request)
        return session.snapshot()

    @app.post("/api/start")
    def start(request: Request):
        check(request)
        return {"started": session.start()}

    @app.post("/api/stop")
    def stop(request: Request):
        check(request)
        session.stop()
        return {"running": session.running}

    @app.post("/api/controller")
    async def controller(request: Request):
        check(request)
        body = await request.json()
        session.runner.set_controller_enabled(bool(body.get("on", True)))
        return {"controller_enabled": session.runner.controller_enabled}

    @app.post("/api/reference")
    async def reference(request: Request):
        check(request)
        body = await request.json()
        try:
            ax = None if body.get("axial") is None else float(body["axial"])
            an = None if body.get("angular") is None else float(body["angular"])
        except (TypeError, ValueError):
            raise HTTPException(status_code=422,
                                detail="axial and angular must be numbers") from None
        session.runner.set_reference(ax, an)
        return {"reference": session.runner.reference}

    @app.websocket("/ws")
    async def ws(websocket: WebSocket):
        if not _ok(websocket.query_params.get("token")):
            await websocket.close(code=1008)
            return
        await websocket.accept()
        try:
            while True:
                await websocket.send_text(json.dumps(session.snapshot()))
                await asyncio.sleep(1.0 / publish_hz)
        except (WebSocketDisconnect, RuntimeError):
            return

    return app


def serve_dashboard(runner, host: str = "127.0.0.1", port: int = 8765,
                    token: str | None = None, duration: float | None = None,
                    publish_hz: float = 20.0, autostart: bool = True) -> None:
    """Serve the dashboard (blocking) until Ctrl-C or, with ``duration``, the run's end.

    Raises
    ------
    DownholeInputError
        ``host`` is not a loopback address and no ``token`` is given.
    """
    import uvicorn

    if not is_loopback(host) and not token:
        raise DownholeInputError(f"the dashboard binds {host!r}, which is not loopback: set "
                                 "[dashboard] token (every request must then carry it)")
    session = DashboardSession(runner, duration)
    app = make_app(session, token, publish_hz)
    server = uvicorn.Server(uvicorn.Config(app, host=host, port=port, log_level="warning"))
    if autostart:
        session.start()

    def watch():
        session.finished.wait()
        server.should_exit = True

    threading.Thread(target=watch, daemon=True).start()
    q = f"?token={token}" if token else ""
    print(f"dashboard: http://{host}:{port}/{q}", flush=True)
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
  <div id="error" class="bad"></div>
 </div>
 <div class="card"><table id="signals"></table></div>
</div>
<div class="row" style="margin-top:12px">
 <canvas id="plot_w" width="640" height="220"></canvas>
 <canvas id="plot_v" width="640" height="220"></canvas>
</div>
<div class="card" style="margin-top:12px"><b>events</b><pre id="events"></pre></div>
<script>
const token = new URLSearchParams(location.search).get("token");
const q = token ? ("?token=" + encodeURIComponent(token)) : "";
const UNITS = {bit_axial_velocity:"m/s", bit_angular_velocity:"rad/s", wob:"N", tob:"N m",
  hook_load:"N", surface_torque:"N m", top_drive_angular_velocity:"rad/s",
  top_drive_axial_velocity:"m/s", reference_axial_velocity:"m/s",
  reference_angular_velocity:"rad/s", time:"s"};
const hist = {t:[], w:[], wr:[], v:[], vr:[]};
let refFilled = false;
function post(path, body){
  return fetch(path + q, {method:"POST", headers:{"Content-Type":"application/json"},
    body: JSON.stringify(body || {})});
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
  const ws = new WebSocket((location.protocol === "https:" ? "wss://" : "ws://") + location.host + "/ws" + q);
  ws.onmessage = ev => update(JSON.parse(ev.data));
  ws.onclose = () => setTimeout(connect, 1000);
}
connect();
</script></body></html>
"""
