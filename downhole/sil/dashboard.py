"""The operator's dashboard of a real-time run: FastAPI + WebSocket, a page with trend charts.

``GET /`` serves the page (``downhole/sil/static``; its charts are drawn by uPlot, shipped in
``static/vendor/uplot`` and served by this app: nothing is fetched from elsewhere at run time).
``WS /ws`` pushes, ``publish_hz`` times a second, the newest recorded row (bit and surface
signals, references, commands), the runtime counters (deadline misses, overruns, late
commands), the state (waiting / running / stopped / finished, controller, safe action), the
last events and the *trend*: the recorded rows the connection has not seen yet (the whole
recording in memory, thinned to ``max_points`` rows, on connecting: a page opened after the
run shows all of it), with the stick-slip severity of :func:`rolling_severity`.

The page shows trends of surface and bit rpm, surface torque, hook load, WOB, ROP, stick-slip
severity and bit depth, in the display units of a unit system (:data:`UNIT_SYSTEMS`,
converted with pint), and takes the driller's set-points (surface rpm, WOB, ROP) in those
units.

Controls (``POST``, JSON bodies only): ``/api/start``, ``/api/stop``, ``/api/controller``
``{"on": bool}``, ``/api/controller/select`` ``{"name": "off" | one of the session's
controllers}``, ``/api/setpoints`` ``{"surface_rpm", "wob", "rop"}`` (display units),
``/api/reference`` ``{"axial": m/s, "angular": rad/s}`` (the bit reference, SI).
``GET /api/state`` is the WebSocket's message without the trend.

A driller set-point sets the controller's reference and the open-loop (manual) command used
while the controller is off: surface rpm is the bit-speed reference and the top-drive speed;
ROP is the bit axial-velocity reference and, on a velocity-driven top (lumped plants), the
top's axial velocity; WOB is the open-loop weight on bit of a force-driven hook (hook load =
buoyed string weight - WOB; slack-off force = WOB on the ``state`` interface) and is refused
(422) on a velocity-driven top, where WOB follows from the feed.

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

Limits (:class:`DashboardLimits`; the server is configured by :func:`server_config`):

- **Connections**: at most ``max_connections`` open at once (default 64) and
  ``max_connections_per_client`` from one client address (default 16); a connection beyond
  either is closed as soon as it is accepted (uvicorn's own ``limit_concurrency`` answers 503
  only once a request's head is complete, so it does not bound half-open connections).
- **Request time**: a request's head and body must arrive within ``request_timeout`` seconds
  (default 10) of the connection, or of the previous response on a kept-alive connection;
  the connection is closed otherwise (slow headers, slow bodies, connections that never send
  anything). A request head is at most ``max_header_bytes`` (default 16 KiB, h11's bound; 400
  beyond); a WebSocket message from a page at most 64 KiB (uvicorn's ``ws_max_size``).
- **Body size**: at most ``max_body_bytes`` (default 64 KiB): a larger ``Content-Length`` is
  refused with 413 before the body is read, a chunked body once that many bytes have been read.
- **Token guessing**: after ``token_failures`` wrong tokens (default 10) from one client
  address, that address is locked out for ``lockout`` seconds (default 60): every request and
  WebSocket from it is refused (429, ``Retry-After``), the right token included; a right token
  before then resets the count. A missing token is refused (403) but not counted. Behind a
  reverse proxy every client has the proxy's address: one guesser locks out everybody.

Refusals are counted in :attr:`DashboardSession.refused` (shown in the state as ``refused``).
"""


import asyncio
import hmac
import ipaddress
import json
import math
import socket
import threading
import time
from collections import OrderedDict
from dataclasses import dataclass
from http.cookies import CookieError, SimpleCookie
from numbers import Integral, Real
from urllib.parse import parse_qs

from downhole.errors import DownholeInputError

__all__ = [
    "DEFAULT_REFERENCE_LIMITS",
    "MIN_REMOTE_TOKEN",
    "TOKEN_COOKIE",
    "TREND_CHANNELS",
    "UNIT_SYSTEMS",
    "DashboardLimits",
    "DashboardSession",
    "check_dashboard_settings",
    "display_units",
    "is_loopback",
    "make_app",
    "rolling_severity",
    "serve_dashboard",
    "server_config",
]

SIGNALS = ("bit_axial_velocity", "bit_angular_velocity", "wob", "tob", "hook_load",
           "surface_torque", "top_drive_angular_velocity", "top_drive_axial_velocity",
           "reference_axial_velocity", "reference_angular_velocity")

#: Name of the cookie that carries the token.
TOKEN_COOKIE = "downhole_token"
#: Admissible set-points when none are declared: axial m/s, angular rad/s (``[reference]``).
DEFAULT_REFERENCE_LIMITS = {"axial": (0.0, 0.05), "angular": (0.0, 40.0)}
#: Shortest token accepted when the dashboard binds beyond loopback.
MIN_REMOTE_TOKEN = 16
#: Client addresses whose token failures are remembered at once (the oldest are forgotten).
_MAX_TRACKED_CLIENTS = 4096
#: Largest WebSocket message accepted from a page (the page sends none), bytes.
_WS_MAX_SIZE = 64 * 1024


@dataclass(frozen=True)
class DashboardLimits:
    """Resource limits of the dashboard's server (module docstring, docs/sil.md).

    Parameters
    ----------
    max_connections : int
        Connections open at once (HTTP and WebSocket); one beyond is closed when accepted.
    max_connections_per_client : int
        Connections open at once from one client address.
    request_timeout : float
        Seconds a request's head and body may take to arrive (from the connection, or from
        the previous response on a kept-alive connection); the connection is closed then.
    max_header_bytes : int
        Largest request head, bytes (h11's ``max_incomplete_event_size``; 400 beyond).
    max_body_bytes : int
        Largest request body, bytes (413 beyond; a larger ``Content-Length`` is refused before
        the body is read).
    token_failures : int
        Wrong tokens from one client address before it is locked out.
    lockout : float
        Seconds a client address stays locked out (429 on every request).

    Raises
    ------
    DownholeInputError
        A count below 1 or a time that is not a positive finite number.
    """

    max_connections: int = 64
    max_connections_per_client: int = 16
    request_timeout: float = 10.0
    max_header_bytes: int = 16 * 1024
    max_body_bytes: int = 64 * 1024
    token_failures: int = 10
    lockout: float = 60.0

    def __post_init__(self):
        for name in ("max_connections", "max_connections_per_client", "max_header_bytes",
                     "max_body_bytes", "token_failures"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, Integral) or v < 1:
                raise DownholeInputError(f"dashboard limit {name} must be an integer >= 1, "
                                         f"got {v!r}")
        for name in ("request_timeout", "lockout"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, Real) or not (math.isfinite(v)
                                                                      and v > 0):
                raise DownholeInputError(f"dashboard limit {name} must be a positive number "
                                         f"of seconds, got {v!r}")
_UNITS = {"axial": "m/s", "angular": "rad/s"}

#: Recorded channels sent in the trend (those the plant records), plus ``stick_slip_severity``.
TREND_CHANNELS = ("time", "top_drive_angular_velocity", "bit_angular_velocity",
                  "reference_angular_velocity", "surface_torque", "hook_load", "wob",
                  "bit_axial_velocity", "reference_axial_velocity", "bit_axial_position")

#: SI unit of each displayed quantity (the signals' units, :mod:`downhole.signals`).
_SI_UNITS = {"rotary_speed": "rad/s", "torque": "N*m", "force": "N", "rop": "m/s",
             "depth": "m"}

#: A signal of each displayed quantity, by which a :class:`downhole.units.UnitSystem` names
#: its display unit (depth: the system's unit of length).
_SIGNAL_OF = {"rotary_speed": "top_drive_angular_velocity", "torque": "surface_torque",
              "force": "wob", "rop": "mean_rop", "depth": None}
#: The dashboard's names of the display systems of :mod:`downhole.units` ("field" is oilfield).
_SYSTEM_NAMES = {"metric": "metric", "field": "oilfield", "oilfield": "oilfield", "si": "si"}


def _quantity_units(system) -> dict:
    """quantity -> pint unit of a :class:`downhole.units.UnitSystem`."""
    return {q: (system.unit_of(sig) if sig else system.kind_unit("length")) or _SI_UNITS[q]
            for q, sig in _SIGNAL_OF.items()}


def _named_systems() -> dict:
    from downhole.units import display_units as units_system

    return {name: _quantity_units(units_system(base)) for name, base in _SYSTEM_NAMES.items()}


#: Display units of the dashboard, by unit system: quantity -> pint unit, the views of the
#: display systems of :mod:`downhole.units` (``metric``: rpm, kN*m, kN, m/h, m; ``field`` =
#: ``oilfield``: rpm, kft*lbf, klbf, ft/h, ft). A unit system is just such a mapping:
#: :func:`make_app` takes a name, a mapping of its own or a UnitSystem (``--units``).
UNIT_SYSTEMS = _named_systems()


def display_units(system="metric") -> dict:
    """Display units of the dashboard's quantities in a unit system.

    A value in SI times ``factor`` is the value in the display unit (factors from pint,
    downhole's registry).

    Parameters
    ----------
    system : str, dict or UnitSystem, optional
        A name of :data:`UNIT_SYSTEMS` (default ``"metric"``), a mapping quantity -> pint unit
        (quantities ``rotary_speed``, ``torque``, ``force``, ``rop``, ``depth``), or a
        :class:`downhole.units.UnitSystem`.

    Returns
    -------
    dict
        ``{quantity: {"unit": label, "pint": unit, "factor": f}}``.

    Raises
    ------
    DownholeInputError
        An unknown system name, a missing or unknown quantity, or a unit of the wrong dimension.
    """
    import pint

    from downhole.units import registry, unit_label

    if hasattr(system, "unit_of"):  # a downhole.units.UnitSystem (``--units``, docs/units.md)
        system = _quantity_units(system)
    if isinstance(system, str):
        if system not in UNIT_SYSTEMS:
            raise DownholeInputError(f"unknown unit system {system!r}; expected one of "
                                     f"{sorted(UNIT_SYSTEMS)} or a mapping quantity -> unit")
        system = UNIT_SYSTEMS[system]
    missing = sorted(set(_SI_UNITS) - set(system))
    if missing:
        raise DownholeInputError(f"the unit system lacks {missing}")
    out = {}
    for q, si in _SI_UNITS.items():
        unit = system[q]
        try:
            f = float(registry().Quantity(1.0, si).to(unit).magnitude)
        except (pint.errors.PintError, AttributeError, TypeError, ValueError) as exc:
            raise DownholeInputError(f"unit system: {q} = {unit!r} is not a unit of {si} "
                                     f"({type(exc).__name__})") from None
        out[q] = {"unit": unit_label(unit), "pint": unit, "factor": f}
    return out


def rolling_severity(omega, window_rows: int, context: int = 0):
    """Stick-slip severity (max - min) / (2 mean) of ``omega`` over a trailing window.

    Row ``i`` gets the severity of ``omega[max(0, i - window_rows + 1) : i + 1]`` (the same
    formula as :func:`downhole.analysis.metrics.stick_slip_severity`), NaN where that mean is
    not positive. The first ``context`` rows only serve as history.

    Parameters
    ----------
    omega : array_like, shape (n,)
        Bit angular velocity samples, rad/s.
    window_rows : int
        Window length in samples (at least 1 is used).
    context : int, optional
        Number of leading rows that are history only (default 0).

    Returns
    -------
    ndarray, shape (n - context,)
        Severity (dimensionless) per row.
    """
    import numpy as np
    from scipy.ndimage import maximum_filter1d, minimum_filter1d

    w = np.asarray(omega, float)
    n = max(1, int(window_rows))
    if w.size == 0:
        return w
    # a trailing window [i - n + 1, i]: a centred filter of size n shifted by (n - 1) // 2 ...
    origin = (n - 1) // 2
    hi = maximum_filter1d(w, n, mode="nearest", origin=origin)
    lo = minimum_filter1d(w, n, mode="nearest", origin=origin)
    c = np.concatenate([[0.0], np.cumsum(w)])
    i = np.arange(w.size)
    start = np.maximum(0, i - n + 1)
    mean = (c[i + 1] - c[start]) / (i + 1 - start)
    with np.errstate(divide="ignore", invalid="ignore"):
        sev = np.where(mean > 0, (hi - lo) / (2.0 * mean), np.nan)
    return sev[context:]
_WILDCARDS = ("0.0.0.0", "::", "")
_SECURITY_HEADERS = [(b"x-frame-options", b"DENY"),
                     (b"content-security-policy", b"frame-ancestors 'none'"),
                     (b"x-content-type-options", b"nosniff"),
                     (b"referrer-policy", b"no-referrer"),
                     (b"cache-control", b"no-store")]


def is_loopback(host: str) -> bool:
    """True for 127.0.0.0/8, ::1 and ``localhost``.

    Parameters
    ----------
    host : str
        Host name or IP address (IPv6 optionally in brackets).

    Returns
    -------
    bool
    """
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
    dashboard: ``start()`` (fresh the first time, then resumes), ``stop()``, ``snapshot()``,
    ``trend()``, ``select_controller()``, ``set_setpoints()``.

    Parameters
    ----------
    runner : RealTimeRunner
        The SIL runner to drive.
    duration : float, optional
        Simulated seconds of the whole run (None: until stopped).
    controllers : dict, optional
        ``{name: (label, factory)}`` the operator can switch to (default:
        :func:`~downhole.sil.controllers.controller_choices` of the runner's plant and
        in-process controller; none for a remote controller).
    controller_name : str, optional
        The name of the runner's controller among ``controllers`` (default: ``pi`` for a
        :class:`~downhole.sil.controllers.SurfacePI`, else ``scenario``).
    severity_window : float
        Seconds of the trailing window of the stick-slip severity (default 10 s: about one
        stick-slip period of a few-kilometre string).
    on_start : callable, optional
        Called (without arguments) when the run is started the first time, before it runs
        (the command line removes the previous ``--out`` there); an exception refuses the
        start and is shown as :attr:`error`.

    Attributes
    ----------
    refused : dict
        Requests refused by the dashboard's checks, by reason (``host``, ``origin``,
        ``content_type``, ``token``; the limits: ``too_large`` bodies, ``lockout`` (requests
        of a locked-out address), ``connections`` closed when accepted, ``timeout``
        connections closed for a request that did not arrive in time), and refused set-points
        and references (``setpoint``).
    """

    def __init__(self, runner, duration: float | None = None, *, controllers: dict | None = None,
                 controller_name: str | None = None, severity_window: float = 10.0,
                 on_start=None):
        from downhole.sil.controllers import SurfacePI, controller_choices

        self.runner = runner
        self.duration = duration
        self._thread: threading.Thread | None = None
        self._started_once = False
        self.error: str | None = None
        self.finished = threading.Event()
        self.refused = {"host": 0, "origin": 0, "content_type": 0, "token": 0, "setpoint": 0,
                        "too_large": 0, "lockout": 0, "connections": 0, "timeout": 0}
        self._non_finite_reported: set[str] = set()
        self._lock = threading.Lock()
        if not (isinstance(severity_window, Real) and math.isfinite(severity_window)
                and severity_window > 0):
            raise DownholeInputError(f"severity_window must be a positive number of seconds, "
                                     f"got {severity_window!r}")
        self.severity_window = float(severity_window)
        self.on_start = on_start
        remote = runner.link is not None and not runner.hil
        if controllers is None:
            controllers = {} if remote else controller_choices(runner.plant, runner.controller)
        self.controllers = dict(controllers)
        if controller_name is None and runner.controller is not None:
            controller_name = "pi" if isinstance(runner.controller, SurfacePI) else "scenario"
        self.controller_name = controller_name if controller_name in self.controllers else None
        p = runner.plant
        self._interface = p.info.get("interface", "")
        self._weight = p.safe_command().get("hook_load")
        man = runner.manual_command
        wob = None
        if "hook_load" in man and self._weight is not None:
            wob = self._weight - man["hook_load"]
        elif "slack_off_force" in man:
            wob = man["slack_off_force"]
        #: the driller's set-points, SI: surface speed rad/s, WOB N (None: not a command of
        #: this plant), ROP m/s. The surface speed (and, on a velocity-fed top, the ROP) is the
        #: plant's open-loop command, the scenario's ``[operation]``; without such a command,
        #: the bit reference. (It once showed the bit reference even where the top drive had
        #: its own speed: 190.99 rpm for a scenario at 95.5 rpm with a 20 rad/s reference.)
        speed = man.get("top_drive_angular_velocity", runner.reference["angular"])
        rop = man.get("top_drive_axial_velocity", runner.reference["axial"]) \
            if self._interface == "lumped" else runner.reference["axial"]
        self.setpoints = {"surface_speed": float(speed), "wob": wob, "rop": float(rop)}
        ref = runner.reference["angular"]
        if not math.isclose(ref, speed, rel_tol=1e-9, abs_tol=1e-12):
            # the scenario's [reference] and [operation] disagree: the page shows both
            runner._event("reference_differs", f"bit reference {ref:g} rad/s, surface speed "
                          f"set-point {speed:g} rad/s: the controller tracks the reference; a "
                          "surface speed set-point sets both")

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    @property
    def started(self) -> bool:
        """Whether the run was ever started."""
        return self._started_once

    @property
    def phase(self) -> str:
        """``waiting`` (for the operator's Start), ``running``, ``stopped`` (resumable) or
        ``finished`` (the duration is used up)."""
        if self.running:
            return "running"
        if self.finished.is_set():
            return "finished"
        return "stopped" if self._started_once else "waiting"

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
            if fresh and self.on_start is not None:
                try:
                    self.on_start()
                except Exception as exc:
                    self.error = f"not started: {type(exc).__name__}: {exc}"
                    return False
            self._started_once = True

            def work():
                try:
                    self.runner.run(remaining, reset=fresh)
                except Exception as exc:
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

    # ------------------------------------------------------------------ operator actions
    def select_controller(self, name: str) -> None:
        """Switch the controller the operator chose, or turn it off.

        ``"off"``: controller off (the open-loop driller set-points drive the plant); another name
        of :attr:`controllers`: build it, switch the runner to it
        (:meth:`~downhole.sil.runtime.RealTimeRunner.switch_controller`, at the next step) and
        turn it on. A controller that sets only some commands is completed by the manual
        command (:class:`~downhole.sil.controllers.ManualFill`).

        Parameters
        ----------
        name : str
            ``"off"`` or a key of :attr:`controllers`.

        Raises
        ------
        DownholeInputError
            An unknown name, or a controller that cannot drive the plant.
        """
        from downhole.sil.controllers import ManualFill

        if name == "off":
            self.runner.set_controller_enabled(False)
            return
        if name not in self.controllers:
            raise DownholeInputError(f"unknown controller {name!r}; expected 'off' or one of "
                                     f"{sorted(self.controllers)}")
        label, factory = self.controllers[name]
        ctrl = factory()
        declared = getattr(ctrl, "commands", None)
        if declared and set(declared) != set(self.runner.plant.command_names):
            ctrl = ManualFill(ctrl, self.runner)
        self.runner.switch_controller(ctrl, label)
        self.controller_name = name
        self.runner.set_controller_enabled(True)

    def set_setpoints(self, surface_speed: float | None = None, wob: float | None = None,
                      rop: float | None = None, limits: dict | None = None) -> dict:
        """Apply driller set-points: the reference and the open-loop command (module docstring).

        Everything is checked before anything is applied.

        Parameters
        ----------
        surface_speed : float, optional
            Surface rotary speed, rad/s (None: unchanged).
        wob : float, optional
            Weight on bit, N, >= 0 (None: unchanged).
        rop : float, optional
            Rate of penetration, m/s (None: unchanged).
        limits : dict, optional
            ``{"axial": (lo, hi), "angular": (lo, hi)}`` in m/s and rad/s
            (default :data:`DEFAULT_REFERENCE_LIMITS`).

        Returns
        -------
        dict
            The current set-points ``{"surface_speed", "wob", "rop"}``, SI.

        Raises
        ------
        DownholeInputError
            A value outside ``limits`` (the reference ranges), a WOB on a velocity-driven
            top, or a command outside the plant's admissible range.
        """
        from downhole.sil.plants import REFERENCE_RANGES, check_range

        r = self.runner
        limits = limits or DEFAULT_REFERENCE_LIMITS
        manual = dict(r.manual_command)
        ref = dict(r.reference)
        if surface_speed is not None:
            ref["angular"] = float(surface_speed)
            if "top_drive_angular_velocity" in manual:
                manual["top_drive_angular_velocity"] = float(surface_speed)
        if rop is not None:
            ref["axial"] = float(rop)
            if self._interface == "lumped" and "top_drive_axial_velocity" in manual:
                manual["top_drive_axial_velocity"] = float(rop)
        if wob is not None:
            if "hook_load" in manual and self._weight is not None:
                manual["hook_load"] = self._weight - float(wob)
            elif "slack_off_force" in manual:
                manual["slack_off_force"] = float(wob)
            else:
                raise DownholeInputError(
                    "this plant's top is fed at a velocity (ROP); its WOB follows from the feed "
                    "and is not a set-point")
            if wob < 0:
                raise DownholeInputError(f"WOB must be >= 0 N, got {wob:g} N")
        for k, v in ref.items():
            lo, hi = limits[k]
            why = check_range(k, v, REFERENCE_RANGES)
            if why is None and not lo <= v <= hi:
                why = f"{v:g} {_UNITS[k]} is outside the admissible range [{lo:g}, {hi:g}]"
            if why is not None:
                raise DownholeInputError(f"set-point refused: {why}")
        why = r.plant.check_command(manual)
        if why is not None:
            raise DownholeInputError(f"set-point refused: the open-loop command {why}")
        r.set_reference(ref["axial"], ref["angular"])
        r.set_manual_command(**manual)
        for k, v in (("surface_speed", surface_speed), ("wob", wob), ("rop", rop)):
            if v is not None:
                self.setpoints[k] = float(v)
        return dict(self.setpoints)

    def reject(self, why: str, counted: bool = False) -> None:
        """Count a refused set-point or reference: ``refused["setpoint"]`` (kept over a Start,
        which resets the runtime's counters; the state's ``stats["rejected_setpoints"]`` shows
        the larger of the two) and the runtime's ``stats["rejected_setpoints"]`` with a
        ``setpoint_rejected`` event, unless the runtime refused (and counted) it itself
        (``counted``)."""
        r = self.runner
        self.refused["setpoint"] += 1
        if not counted:
            r.stats["rejected_setpoints"] = r.stats.get("rejected_setpoints", 0) + 1
            r._event("setpoint_rejected", why)

    # ------------------------------------------------------------------ what is sent
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
        stats = dict(r.stats)
        stats["rejected_setpoints"] = max(stats.get("rejected_setpoints", 0),
                                          self.refused["setpoint"])
        raw = {"signals": sig, "stats": stats, "running": self.running,
               "phase": self.phase, "duration": self.duration,
               "controller_enabled": bool(r.controller_enabled),
               "controller": self.controller_name if r.controller_enabled else "off",
               "controllers": [{"name": "off", "label": "off (open loop: set-points)"}] +
               [{"name": k, "label": v[0]} for k, v in self.controllers.items()],
               "safe_action": r._safe_since is not None, "reference": dict(r.reference),
               "setpoints": dict(self.setpoints), "manual_command": dict(r.manual_command),
               "events": events, "error": self.error, "model": r.plant.name,
               "scheduler": r.scheduler, "refused": dict(self.refused)}
        bad: list[str] = []
        out = _finite_tree(raw, "", bad)
        new = sorted(set(bad) - self._non_finite_reported)
        if new:
            self._non_finite_reported.update(new)
            r._event("dashboard_non_finite", "null sent for " + ", ".join(new))
        return out

    def trend(self, since: int, max_points: int = 4000) -> tuple[dict, int]:
        """The recorded rows from row number ``since`` on, for the page's trend plots.

        Rows overwritten in the ring are skipped; the rows are thinned to at most ``max_points``.

        Parameters
        ----------
        since : int
            First row number wanted (the value returned by the previous call; 0 at first).
        max_points : int, optional
            Most rows returned (default 4000).

        Returns
        -------
        data : dict
            ``{channel: [values]}`` (SI; NaN as None) with ``stick_slip_severity``; empty when there
            is nothing new.
        next : int
            The row number to ask from next time.
        """
        import numpy as np

        rec = self.runner.recorder
        count = rec.count
        first = max(since, count - rec.capacity, 0)
        if first >= count:
            return {}, count
        n_w = max(1, int(round(self.severity_window / (self.runner.dt
                                                        * self.runner.record_every))))
        ctx0 = max(first - n_w + 1, count - rec.capacity, 0)
        idx = np.arange(ctx0, count) % rec.capacity
        data = rec.buf[idx]
        ch = rec.channels
        sev = None
        if "bit_angular_velocity" in ch:
            sev = rolling_severity(data[:, ch.index("bit_angular_velocity")], n_w,
                                   context=first - ctx0)
        data = data[first - ctx0:]
        n = data.shape[0]
        keep = np.arange(n)
        if n > max_points:
            keep = np.unique(np.linspace(0, n - 1, max_points).round().astype(int))
        out = {}
        for name in TREND_CHANNELS:
            if name in ch:
                out[name] = _json_floats(data[keep, ch.index(name)])
        if sev is not None:
            out["stick_slip_severity"] = _json_floats(sev[keep])
        return out, count


def _json_floats(a) -> list:
    return [x if math.isfinite(x) else None for x in a.tolist()]


def _check_token(given: str | None, token: str) -> bool:
    if given is None:
        return False
    return hmac.compare_digest(given.encode("utf-8", "surrogatepass"), token.encode("utf-8"))


class _Guard:
    """ASGI middleware: Host, Origin, content type, body size and token checks, and the
    lockout of token guessers (module docstring)."""

    def __init__(self, app, *, session, token, allowed_hosts, allowed_origins, port, limits):
        self.app = app
        self.session = session
        self.token = token
        self.hosts = allowed_hosts
        self.origins = allowed_origins
        self.port = port
        self.limits = limits
        #: client address -> [wrong tokens in a row, locked until (monotonic s) or 0]
        self._failures: OrderedDict[str, list] = OrderedDict()

    def _locked(self, client: str) -> float:
        """Seconds ``client`` stays locked out (0: not locked)."""
        entry = self._failures.get(client)
        if entry is None or not entry[1]:
            return 0.0
        left = entry[1] - time.monotonic()
        if left > 0:
            return left
        del self._failures[client]  # served its time: a fresh count
        return 0.0

    def _failed(self, client: str) -> None:
        """One more wrong token from ``client``; locked out at the limit."""
        entry = self._failures.pop(client, None) or [0, 0.0]
        entry[0] += 1
        if entry[0] >= self.limits.token_failures:
            entry[1] = time.monotonic() + self.limits.lockout
        self._failures[client] = entry  # the newest at the end
        while len(self._failures) > _MAX_TRACKED_CLIENTS:
            self._failures.popitem(last=False)

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
        if scope["type"] == "http":
            for length in headers.get("content-length", []):
                if not length.strip().isdigit() or int(length) > self.limits.max_body_bytes:
                    return ("too_large", 413, f"the body may have at most "
                            f"{self.limits.max_body_bytes} bytes; Content-Length is "
                            f"{length.strip()[:20]!r}")
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
        extra: list = []
        client = str((scope.get("client") or ("",))[0])
        if why is None and self.token is not None:
            left = self._locked(client)
            given = self._given_token(headers)
            if left:
                why = ("lockout", 429, f"too many wrong tokens from {client}: locked out for "
                       f"{math.ceil(left)} s")
                extra = [(b"retry-after", str(math.ceil(left)).encode())]
            elif _check_token(given, self.token):
                self._failures.pop(client, None)
            else:
                query = parse_qs(scope.get("query_string", b"").decode("latin-1"))
                q = query.get("token")
                if (scope["type"] == "http" and scope.get("method") == "GET"
                        and scope.get("path") == "/" and q and _check_token(q[0], self.token)):
                    login = q[0]
                    self._failures.pop(client, None)
                else:
                    why = ("token", 403, "missing or wrong token (Authorization: Bearer, "
                           f"X-Downhole-Token or the {TOKEN_COOKIE} cookie)")
                    if given is not None or q:  # a guess (a missing token is no guess)
                        self._failed(client)
        if why is not None:
            self.session.refused[why[0]] += 1
            if scope["type"] == "websocket":
                await send({"type": "websocket.close", "code": 1008, "reason": why[2][:120]})
                return
            return await self._respond(send, why[1], json.dumps({"detail": why[2]}).encode(),
                                       [(b"content-type", b"application/json"), *extra])
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

        size = 0

        async def receive_bounded():
            """The body, refused (413) once it exceeds the limit (a chunked body has no
            Content-Length to check first)."""
            nonlocal size
            message = await receive()
            if message["type"] == "http.request":
                size += len(message.get("body", b""))
                if size > self.limits.max_body_bytes:
                    from starlette.exceptions import HTTPException

                    self.session.refused["too_large"] += 1
                    raise HTTPException(status_code=413, detail=(
                        f"the body may have at most {self.limits.max_body_bytes} bytes"))
            return message

        return await self.app(scope, receive_bounded, send_secure)

    @staticmethod
    async def _respond(send, status: int, body: bytes, headers: list):
        await send({"type": "http.response.start", "status": status,
                    "headers": headers + _SECURITY_HEADERS
                    + [(b"content-length", str(len(body)).encode())]})
        await send({"type": "http.response.body", "body": body})


def _number(body: dict, name: str, unit: str):
    """``body[name]`` as a finite float (None when absent); 422 otherwise."""
    from fastapi import HTTPException

    v = body.get(name)
    if v is None:
        return None
    if isinstance(v, bool) or not isinstance(v, Real):
        raise HTTPException(status_code=422, detail=f"{name} must be a number ({unit}), got "
                                                    f"{json.dumps(v)[:40]}")
    try:
        v = float(v)
    except OverflowError:
        v = math.inf
    if not math.isfinite(v):
        raise HTTPException(status_code=422, detail=f"{name} must be finite ({unit}), got {v}")
    return v


def _setpoint(body: dict, name: str, limits: dict):
    from fastapi import HTTPException

    unit = _UNITS[name]
    v = _number(body, name, unit)
    if v is None:
        return None
    lo, hi = limits[name]
    if not lo <= v <= hi:
        raise HTTPException(status_code=422, detail=f"{name} = {v:g} {unit} is outside the "
                                                    f"admissible range [{lo:g}, {hi:g}] {unit}")
    return v


def make_app(session: DashboardSession, token: str | None = None, publish_hz: float = 20.0, *,
             host: str = "127.0.0.1", port: int | None = None, allowed_hosts=(),
             allowed_origins=(), reference_limits: dict | None = None, units="metric",
             max_points: int = 4000, limits: DashboardLimits | None = None):
    """The FastAPI application for ``session`` (see the module docstring).

    Parameters
    ----------
    session : DashboardSession
        The session the page controls and watches.
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
        (default :data:`DEFAULT_REFERENCE_LIMITS`); the driller set-points surface rpm and
        ROP are checked against them too.
    units : str or dict
        The display unit system: a name of :data:`UNIT_SYSTEMS` or a mapping quantity ->
        pint unit (:func:`display_units`).
    max_points : int
        Rows of trend sent at most at once (the history sent to a page that connects).
    limits : DashboardLimits, optional
        Body size and token lockout (default :class:`DashboardLimits`); its connection and
        time limits apply when the app is served with :func:`server_config`.

    Returns
    -------
    fastapi.FastAPI
        The application (serve it with uvicorn and :func:`server_config`; :func:`serve_dashboard`
        does).

    Raises
    ------
    DownholeInputError
        A malformed token, reference limits that are not finite ``(lo, hi)`` with lo < hi, an
        unknown unit system, or ``max_points`` < 2.
    """
    from fastapi import FastAPI, HTTPException, Request, WebSocket, WebSocketDisconnect
    from fastapi.responses import HTMLResponse, JSONResponse, Response

    check_dashboard_settings("127.0.0.1", token)
    ref_limits = dict(DEFAULT_REFERENCE_LIMITS)
    ref_limits.update(reference_limits or {})
    for name, (lo, hi) in ref_limits.items():
        if name not in _UNITS or not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            raise DownholeInputError(f"reference_limits[{name!r}] must be finite (lo, hi) with "
                                     f"lo < hi, got {(lo, hi)!r}")
    disp = display_units(units)
    if not (isinstance(max_points, Integral) and max_points >= 2):
        raise DownholeInputError(f"max_points must be an integer >= 2, got {max_points!r}")
    hosts = default_allowed_hosts(host) | {_norm_host(h) for h in allowed_hosts}
    origins = {o.strip().rstrip("/").lower() for o in allowed_origins}

    guard = limits if limits is not None else DashboardLimits()
    if not isinstance(guard, DashboardLimits):
        raise DownholeInputError(f"limits must be a DashboardLimits, got {type(limits).__name__}")
    app = FastAPI(title="downhole SIL dashboard")
    app.state.dashboard_limits = guard
    app.state.dashboard_session = session
    app.add_middleware(_Guard, session=session, token=token, allowed_hosts=hosts,
                       allowed_origins=origins, port=port or None, limits=guard)

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

    static = _static_files()

    @app.get("/", response_class=HTMLResponse)
    def index():
        return static["dashboard.html"][0].decode("utf-8")

    @app.get("/static/{name:path}")
    def static_file(name: str):
        if name not in static:  # a fixed list: no path is ever joined to a request
            raise HTTPException(status_code=404, detail="no such file")
        body, media = static[name]
        return Response(content=body, media_type=media)

    def state_message() -> dict:
        out = session.snapshot()
        out["units"] = disp
        out["limits"] = {k: list(v) for k, v in ref_limits.items()}
        return out

    @app.get("/api/state")
    def state():
        return JSONResponse(state_message())

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

    @app.post("/api/controller/select")
    async def select_controller(request: Request):
        body = await json_object(request)
        names = ["off", *session.controllers]
        if set(body) != {"name"} or not isinstance(body["name"], str) \
                or body["name"] not in names:
            raise HTTPException(status_code=422, detail=f'send {{"name": NAME}} with NAME one '
                                                        f'of {names}')
        try:
            session.select_controller(body["name"])
        except DownholeInputError as exc:
            raise HTTPException(status_code=422, detail=str(exc)) from None
        return {"controller": body["name"],
                "controller_enabled": session.runner.controller_enabled}

    def counting_refusals(handler):
        """Run ``handler``; a 422 (a refused value) is counted by :meth:`DashboardSession.
        reject`, a refusal of the runtime too (and re-raised as 422)."""
        before = session.runner.stats.get("rejected_setpoints", 0)
        try:
            return handler()
        except HTTPException as exc:
            if exc.status_code == 422:
                session.reject(str(exc.detail))
            raise
        except DownholeInputError as exc:
            session.reject(str(exc),
                           counted=session.runner.stats.get("rejected_setpoints", 0) > before)
            raise HTTPException(status_code=422, detail=str(exc)) from None

    @app.post("/api/setpoints")
    async def setpoints(request: Request):
        body = await json_object(request)
        return counting_refusals(lambda: _apply_setpoints(body))

    def _apply_setpoints(body: dict):
        fields = {"surface_rpm": "rotary_speed", "wob": "force", "rop": "rop"}
        extra = set(body) - set(fields)
        if extra:
            raise HTTPException(status_code=422, detail=f"unknown field(s) {sorted(extra)}; "
                                                        f"expected {sorted(fields)}")
        si = {}
        for name, q in fields.items():
            unit, f = disp[q]["unit"], disp[q]["factor"]
            v = _number(body, name, unit)
            si[name] = None if v is None else v / f
        if all(v is None for v in si.values()):
            raise HTTPException(status_code=422, detail="give surface_rpm, wob and/or rop")
        for name, lim, q in (("surface_rpm", "angular", "rotary_speed"), ("rop", "axial", "rop")):
            v = si[name]
            lo, hi = ref_limits[lim]
            if v is not None and not lo <= v <= hi:
                f, unit = disp[q]["factor"], disp[q]["unit"]
                raise HTTPException(status_code=422, detail=(
                    f"{name} = {v * f:g} {unit} is outside the admissible range "
                    f"[{lo * f:g}, {hi * f:g}] {unit}"))
        sp = session.set_setpoints(si["surface_rpm"], si["wob"], si["rop"], limits=ref_limits)
        return {"setpoints": sp, "reference": session.runner.reference}

    @app.post("/api/reference")
    async def reference(request: Request):
        body = await json_object(request)
        return counting_refusals(lambda: _apply_reference(body))

    def _apply_reference(body: dict):
        extra = set(body) - {"axial", "angular"}
        if extra:
            raise HTTPException(status_code=422, detail=f"unknown field(s) {sorted(extra)}; "
                                                        "expected axial (m/s), angular (rad/s)")
        ax = _setpoint(body, "axial", ref_limits)
        an = _setpoint(body, "angular", ref_limits)
        if ax is None and an is None:
            raise HTTPException(status_code=422, detail="give axial (m/s) and/or angular (rad/s)")
        session.runner.set_reference(ax, an)
        return {"reference": session.runner.reference}

    @app.websocket("/ws")
    async def ws(websocket: WebSocket):
        await websocket.accept()
        cursor = 0
        try:
            while True:
                msg = state_message()
                first = cursor == 0
                msg["trend"], cursor = session.trend(cursor, max_points)
                msg["trend_reset"] = first
                await websocket.send_text(json.dumps(msg, allow_nan=False))
                await asyncio.sleep(1.0 / publish_hz)
        except (WebSocketDisconnect, RuntimeError):
            return

    return app


def check_dashboard_settings(host: str, token: str | None) -> None:
    """Refuse settings the dashboard will not serve with (called before a run starts).

    Parameters
    ----------
    host : str
        Address the server binds.
    token : str or None
        Access token required on every request, or None.

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


def _guarded_protocol(limits: DashboardLimits, refused: dict):
    """uvicorn's h11 protocol with the connection limits and the request deadline of
    ``limits`` (uvicorn itself has neither: a connection that never completes a request head
    is kept open for ever, and ``limit_concurrency`` counts it only once its head is in)."""
    import h11
    from uvicorn.protocols.http.h11_impl import H11Protocol

    class GuardedH11Protocol(H11Protocol):
        _deadline = None

        def connection_made(self, transport) -> None:
            super().connection_made(transport)
            peer = self.client[0] if self.client else None
            same = sum(1 for c in self.connections
                       if (getattr(c, "client", None) or (None,))[0] == peer)
            if (len(self.connections) > limits.max_connections
                    or same > limits.max_connections_per_client):
                refused["connections"] += 1
                self.connections.discard(self)
                transport.close()
                return
            self._arm()

        def _arm(self) -> None:
            self._disarm()
            self._deadline = self.loop.call_later(limits.request_timeout, self._expired)

        def _disarm(self) -> None:
            if self._deadline is not None:
                self._deadline.cancel()
                self._deadline = None

        def _expired(self) -> None:
            self._deadline = None
            if self.transport.is_closing():
                return
            # IDLE: the request's head is not complete; SEND_BODY: nor is its body
            if self.conn.their_state in (h11.IDLE, h11.SEND_BODY):
                refused["timeout"] += 1
                if self.cycle is not None and not self.cycle.response_complete:
                    self.cycle.disconnected = True
                self.transport.close()

        def on_response_complete(self) -> None:
            if not self.transport.is_closing():
                self._arm()  # the next request on this connection has as long
            super().on_response_complete()

        def handle_websocket_upgrade(self, event) -> None:
            self._disarm()  # the WebSocket protocol owns the connection from now on
            super().handle_websocket_upgrade(event)

        def connection_lost(self, exc) -> None:
            self._disarm()
            super().connection_lost(exc)

    return GuardedH11Protocol


def server_config(app, host: str = "127.0.0.1", port: int = 8765, **kwargs):
    """The uvicorn configuration that serves a dashboard application with its limits.

    The connection cap and the request deadline of the app's :class:`DashboardLimits` (set by
    :func:`make_app`) are enforced by the HTTP protocol (h11) configured here, the largest
    request head by h11's ``max_incomplete_event_size``, the largest WebSocket message by
    ``ws_max_size``.

    Parameters
    ----------
    app : fastapi.FastAPI
        An application of :func:`make_app`.
    host : str, optional
        Address to bind (default ``"127.0.0.1"``).
    port : int, optional
        TCP port (default 8765).
    **kwargs
        Further :class:`uvicorn.Config` options (default ``log_level="warning"``).

    Returns
    -------
    uvicorn.Config
        The configuration (serve it with :class:`uvicorn.Server`).

    Raises
    ------
    DownholeInputError
        ``app`` is not an application of :func:`make_app`.
    """
    import uvicorn

    limits = getattr(getattr(app, "state", None), "dashboard_limits", None)
    session = getattr(getattr(app, "state", None), "dashboard_session", None)
    if not isinstance(limits, DashboardLimits) or session is None:
        raise DownholeInputError("server_config serves an application of make_app")
    kwargs.setdefault("log_level", "warning")
    return uvicorn.Config(app, host=host, port=port,
                          http=_guarded_protocol(limits, session.refused),
                          h11_max_incomplete_event_size=limits.max_header_bytes,
                          ws_max_size=_WS_MAX_SIZE, **kwargs)


def serve_dashboard(runner, host: str = "127.0.0.1", port: int = 8765,
                    token: str | None = None, duration: float | None = None,
                    publish_hz: float = 20.0, autostart: bool = True, *, allowed_hosts=(),
                    allowed_origins=(), token_source: str | None = None,
                    reference_limits: dict | None = None, exit_after_run: bool = True,
                    units="metric", controllers: dict | None = None,
                    controller_name: str | None = None, on_run_start=None,
                    on_run_end=None, limits: DashboardLimits | None = None) -> DashboardSession:
    """Serve the dashboard (blocking) until Ctrl-C or, with ``exit_after_run``, the run's end.

    ``token_source`` is printed instead of the token, of which at most a 4-character prefix is
    shown.

    Parameters
    ----------
    runner : RealTimeRunner
        The SIL runner to drive.
    host : str, optional
        Address to bind (default ``"127.0.0.1"``).
    port : int, optional
        TCP port (default 8765; 0: any free port).
    token : str, optional
        Access token required on every request.
    duration : float, optional
        Simulated seconds of the whole run, s (None: until stopped).
    publish_hz : float, optional
        WebSocket updates per second, Hz (default 20).
    autostart : bool, optional
        Start the run at once (default); False: it waits for the operator's Start on the page.
    allowed_hosts, allowed_origins : iterable of str, optional
        Extra Host names and origins, as :func:`make_app`.
    token_source : str, optional
        Where the token came from (a file path or a scenario field), printed instead of it.
    reference_limits : dict, optional
        ``{"axial": (lo, hi), "angular": (lo, hi)}`` in m/s and rad/s, as :func:`make_app`.
    exit_after_run : bool, optional
        Stop serving when the run has used up its ``duration`` (default True).
    units : str, dict or UnitSystem, optional
        Display unit system (default ``"metric"``), as :func:`display_units`.
    controllers : dict, optional
        ``{name: (label, factory)}``, as :class:`DashboardSession`.
    controller_name : str, optional
        Name of the runner's controller among ``controllers``.
    on_run_start : callable, optional
        Called without arguments when the run starts the first time
        (:class:`DashboardSession` ``on_start``).
    on_run_end : callable, optional
        Called without arguments (in a thread) when the run has used up its duration (the
        command line writes ``--out`` there); the server exits (``exit_after_run``) once it
        has returned.
    limits : DashboardLimits, optional
        Connections, request time, body size and token lockout (default
        :class:`DashboardLimits`).

    Returns
    -------
    DashboardSession
        The session, after the server has stopped.

    Raises
    ------
    DownholeInputError
        ``host`` is not a loopback address and no ``token`` (of at least
        :data:`MIN_REMOTE_TOKEN` characters) is given, or other settings :func:`make_app`
        refuses.
    """
    import uvicorn

    check_dashboard_settings(host, token)
    session = DashboardSession(runner, duration, controllers=controllers,
                               controller_name=controller_name, on_start=on_run_start)
    sockets = None
    if port == 0:  # any free port: bind it here, so that the Host check and the URL name it
        sock = socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind((host, 0))
        port = sock.getsockname()[1]
        sockets = [sock]
    app = make_app(session, token, publish_hz, host=host, port=port,
                   allowed_hosts=allowed_hosts, allowed_origins=allowed_origins,
                   reference_limits=reference_limits, units=units, limits=limits)
    server = uvicorn.Server(server_config(app, host, port))
    shown = f"[{host}]" if ":" in host else host
    url = f"http://{shown}:{port}/"

    def watch():
        session.finished.wait()
        if on_run_end is not None:
            on_run_end()
        if exit_after_run:
            server.should_exit = True
        else:
            print(f"dashboard: the run has ended; its results stay on {url} until Ctrl-C",
                  flush=True)

    threading.Thread(target=watch, daemon=True).start()
    print(f"dashboard: {url}" + ("" if autostart else "  (press Start on the page to run)"),
          flush=True)
    if token:
        print(f"  {_describe_token(token, token_source)} required: open "
              f"{url}?token=<token> once (sets a cookie), or send "
              "'Authorization: Bearer <token>'", flush=True)
    if autostart:
        session.start()
    try:
        server.run(sockets=sockets)
    finally:
        session.stop()
    return session


_STATIC = {"dashboard.html": "text/html; charset=utf-8",
           "dashboard.js": "text/javascript; charset=utf-8",
           "dashboard.css": "text/css; charset=utf-8",
           "vendor/uplot/uPlot.iife.min.js": "text/javascript; charset=utf-8",
           "vendor/uplot/uPlot.min.css": "text/css; charset=utf-8",
           "vendor/uplot/LICENSE": "text/plain; charset=utf-8"}


def _static_files() -> dict:
    """``{name: (bytes, media type)}`` of the page and its vendored chart library (read from
    the package once per app)."""
    from importlib.resources import files

    root = files("downhole.sil").joinpath("static")
    out = {}
    for name, media in _STATIC.items():
        node = root
        for part in name.split("/"):
            node = node.joinpath(part)
        out[name] = (node.read_bytes(), media)
    return out
