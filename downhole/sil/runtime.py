"""The real-time runtime: steps a plant at a fixed step paced to ``time.monotonic()``.

:class:`RealTimeRunner` advances a :class:`~downhole.sil.plants.SilPlant` one ``dt`` per
period with the command of an in-process controller, of a remote controller over the UDP link
(:class:`~downhole.sil.link.PlantLink`), or the open-loop (manual) command when the controller
is off. Step ``k`` is scheduled to start at ``t0 + k dt`` and must finish by its deadline
``t0 + (k + 1) dt``.

Timing counters (``stats``):

- ``deadline_misses``: steps that finished after their deadline;
- ``overruns``: steps whose own execution took longer than ``dt`` (the cause of a miss, as
  opposed to a miss inherited from a late start);
- ``late_commands``: remote commands that did not arrive within the wait budget
  (``wait_fraction * dt`` after the observation was sent); the last command is held;
- ``resyncs``: times the runner fell more than ``max_lag`` behind and re-anchored its clock;
- ``max_rx_s``, ``mean_rx_s``: CPU time per step spent reading and validating link datagrams
  (bounded by :meth:`~downhole.sil.link.PlantLink.poll`; also recorded as ``rx_time``);
  ``max_rx_listen_s``, ``mean_rx_listen_s``: its part spent on datagrams from anybody but
  the owner (what a flood costs; recorded as ``rx_listen_time``);
- ``rx_dropped``: datagrams of the link's owner read and dropped unparsed because the step's
  read bound was reached (at most ``rx_max_commands`` handled per step, see
  :class:`~downhole.sil.link.PlantLink`): an owner sending more than one command per step
  costs each step a bounded amount of work;
- ``rejected_commands``: commands of an in-process controller that were not finite or outside
  the plant's admissible ranges (:attr:`~downhole.sil.plants.SilPlant.command_ranges`); the
  last admissible command is held instead (remote ones are counted by the link:
  ``non_finite``, ``out_of_range``); ``rejected_setpoints``: refused
  :meth:`RealTimeRunner.set_reference` / :meth:`RealTimeRunner.set_manual_command` calls.

Simulated time is always ``k dt``: steps are never skipped or stretched. When the runner is
behind by less than ``max_lag`` it runs the next steps back to back (catch up); beyond it, it
re-anchors ``t0`` (wall clock and simulated time keep a new constant offset) and records a
``resync`` event. The recorded ``wall_lag`` channel shows how late each step finished.

Safety (:class:`SafetyPolicy`): when a remote controller goes silent (no valid command for
``timeout`` s, counted from the start of the run, so a controller that dies before its first
command is caught as well) the runner records ``controller_timeout`` and applies the safe
action: hold the last command for ``hold`` s, then ramp every command linearly over ``ramp`` s
to the plant's safe state (:meth:`~downhole.sil.plants.SilPlant.safe_command`: no weight on
bit, top drive stopped), records ``safe_state_reached`` and keeps running. With
``resume="manual"`` (default) a returning controller is ignored until
:meth:`RealTimeRunner.arm` (the dashboard's "controller on"); with ``"auto"`` the next valid
command ends the safe action. An in-process controller whose commands are rejected for
``timeout`` s of simulated time also gets the safe action (re-armed by :meth:`arm`). Handing
the link to another controller (:meth:`RealTimeRunner.replace_controller`) starts the safe
action as well.

Memory: the recording is a preallocated ring (:class:`~downhole.sil.recorder.RingRecorder`,
optionally chunked to disk), events are a bounded deque: a run of hours does not grow.
"""

from __future__ import annotations

import gc
import math
import threading
import time
from collections import deque
from dataclasses import asdict, dataclass

import numpy as np

from downhole.errors import DownholeInputError
from downhole.sil.link import PlantLink
from downhole.sil.plants import COMMAND_RANGES, REFERENCE_RANGES, SilPlant, check_range
from downhole.sil.protocol import Layout
from downhole.sil.recorder import RingRecorder
from downhole.sil.scheduling import elevate_priority, sleep_until
from downhole.sim.result import Result

__all__ = ["STATS_KEYS", "RealTimeRunner", "SafetyPolicy", "elevate_priority"]

STATS_KEYS = ("steps", "deadline_misses", "overruns", "late_commands", "resyncs",
              "max_lag_s", "max_exec_s", "mean_exec_s", "wall_s", "sim_s", "real_time_factor",
              "deadline_miss_fraction", "safe_actions", "rejected_commands",
              "rejected_setpoints", "max_rx_s", "mean_rx_s", "max_rx_listen_s",
              "mean_rx_listen_s", "rx_dropped")

REFERENCE_NAMES = ("reference_axial_velocity", "reference_angular_velocity")
HIL_NAMES = ("bit_axial_velocity", "bit_angular_velocity")


@dataclass(frozen=True)
class SafetyPolicy:
    """Controller-timeout action (see the module docstring).

    Parameters
    ----------
    timeout : float
        Seconds (wall clock) without a valid command before the safe action, s.
    hold : float
        Seconds (simulated) holding the last command, s.
    ramp : float
        Seconds (simulated) of the linear ramp to the safe state, s.
    resume : {"manual", "auto"}
        What a returning controller does (see the module docstring).
    """

    timeout: float = 0.1
    hold: float = 0.2
    ramp: float = 2.0
    resume: str = "manual"

    def __post_init__(self):
        for name in ("timeout", "hold", "ramp"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise DownholeInputError(f"safety {name} must be a number >= 0 s, got {v!r}")
        if self.resume not in ("manual", "auto"):
            raise DownholeInputError(f"safety resume must be 'manual' or 'auto', got "
                                     f"{self.resume!r}")


class RealTimeRunner:
    """Run a plant in real time with a controller in-process, over UDP, or none.

    Parameters
    ----------
    plant : SilPlant
        The plant (its command layout, ranges and safe command).
    controller : object, optional
        In-process controller: ``reset()`` and ``command(t, observation, reference) -> dict``
        naming the plant's commands. In HIL mode it gives the surface commands.
    link : PlantLink or (host, port), optional
        Remote controller (SIL) or rig (HIL) over UDP. Mutually exclusive with ``controller``
        in SIL mode.
    hil : bool
        Hardware-in-the-loop: the link's peer receives the observations (among them
        ``last_node_axial_velocity``, ``last_node_angular_velocity``) and returns the bit
        velocities ``bit_axial_velocity``, ``bit_angular_velocity``, which the plant (a
        :class:`~downhole.sil.hil.HILStringPlant`) takes as its bit motion.
    reference : dict, optional
        ``{"axial": m/s, "angular": rad/s}`` (default 0.01, 20); the controller receives it as
        the named signals ``reference_axial_velocity`` and ``reference_angular_velocity``.
    paced : bool
        Pace to the wall clock (False: as fast as possible, for benchmarks).
    record_every : int
        Record every n-th step.
    ring_rows : int
        Rows kept in memory (the last ``ring_rows`` recorded).
    chunk_dir : path, optional
        Also write every recorded row to chunk files there.
    ring_bytes : int, optional
        Memory budget of the ring, bytes: ``ring_rows`` is lowered to what fits (8 bytes per
        channel and row); :attr:`ring_capped` then says how many rows were asked for.
    max_lag : float
        Re-anchor the clock when more than this far behind, s.
    wait_fraction : float
        Fraction of ``dt`` to wait for a remote command after sending the observation.
    safety : SafetyPolicy, optional
        Controller-timeout action (default ``SafetyPolicy()``).
    controller_enabled : bool
        Start with the controller on (False: open-loop command).
    spin : float
        Busy-wait this long before each period start for accuracy, s.
    command_timeout : float, optional
        Wait budget for a remote command in seconds, overriding ``wait_fraction * dt``
        (unpaced lock-step runs over the link, e.g. tests and the UDP benchmark).
    realtime : bool
        When paced, try to run the loop thread under SCHED_FIFO (:func:`elevate_priority`);
        the policy obtained is in ``stats["scheduler"]``.
    link_key, link_key_file : bytes or str, path, optional
        Shared key of the UDP link (:class:`~downhole.sil.link.PlantLink`; required to bind
        beyond loopback; default: the environment variable ``DOWNHOLE_LINK_KEY``).
    rx_fraction : float
        Share of the step the link may spend per step reading its listening socket (the bound
        that keeps a flood from stalling the plant).
    rx_max_commands : int
        Per step, the most datagrams of the link's owner handled (default 4; the excess is
        dropped and counted as ``stats["rx_dropped"]``, see
        :class:`~downhole.sil.link.PlantLink`).

    Raises
    ------
    DownholeInputError
        Bad arguments, a reference outside :data:`~downhole.sil.plants.REFERENCE_RANGES`, or
        a link that cannot be set up (see :class:`~downhole.sil.link.PlantLink`).
    """

    def __init__(self, plant: SilPlant, controller=None, *, link=None, hil: bool = False,
                 reference: dict | None = None, paced: bool = True, record_every: int = 10,
                 ring_rows: int = 200_000, chunk_dir=None, ring_bytes: int | None = None,
                 max_lag: float = 0.05,
                 wait_fraction: float = 0.7, safety: SafetyPolicy | None = None,
                 controller_enabled: bool = True, spin: float = 2e-4, realtime: bool = True,
                 command_timeout: float | None = None, link_key=None, link_key_file=None,
                 rx_fraction: float = 0.02, rx_max_commands: int = 4):
        if not isinstance(plant, SilPlant):
            raise DownholeInputError(f"plant must be a SilPlant (downhole.sil.build_plant), got "
                                     f"{type(plant).__name__}")
        if controller is not None and not (hasattr(controller, "command")
                                           and hasattr(controller, "reset")):
            raise DownholeInputError("controller must have reset() and command(t, observation, "
                                     "reference)")
        if link is not None and controller is not None and not hil:
            raise DownholeInputError("give either an in-process controller or a link, not both")
        if not 0 < wait_fraction < 1:
            raise DownholeInputError(f"wait_fraction must be in (0, 1), got {wait_fraction}")
        if record_every < 1:
            raise DownholeInputError(f"record_every must be >= 1, got {record_every}")
        if not 0 < rx_fraction < 1:
            raise DownholeInputError(f"rx_fraction must be in (0, 1), got {rx_fraction}")
        self.plant = plant
        self.dt = plant.dt
        self.controller = controller
        self.hil = bool(hil)
        self.paced = bool(paced)
        self.record_every = int(record_every)
        self.max_lag = float(max_lag)
        self.wait_fraction = float(wait_fraction)
        self.safety = safety or SafetyPolicy()
        self.spin = float(spin)
        self.realtime = bool(realtime)
        self.command_timeout = command_timeout
        self.scheduler = "normal"
        ref = reference or {}
        self.reference = {"axial": float(ref.get("axial", 0.01)),
                          "angular": float(ref.get("angular", 20.0))}
        for k, v in self.reference.items():
            why = check_range(k, v, REFERENCE_RANGES)
            if why is not None:
                raise DownholeInputError(f"reference: {why}")
        self.controller_enabled = bool(controller_enabled)
        self.manual_command = plant.default_command()
        obs_names = tuple(n for n in plant.observation_names if n not in REFERENCE_NAMES)
        self.obs_names = obs_names + REFERENCE_NAMES
        self.link = None
        if link is not None:
            if isinstance(link, PlantLink):
                self.link = link
            else:
                host, port = link
                cmds = HIL_NAMES if self.hil else plant.command_names
                ranges = ({c: COMMAND_RANGES[c] for c in HIL_NAMES} if self.hil
                          else plant.command_ranges)
                units = dict(plant.units)
                units.update({"reference_axial_velocity": "m/s",
                              "reference_angular_velocity": "rad/s"})
                self.link = PlantLink(Layout(self.dt, "hil" if self.hil else "sil",
                                             self.obs_names, cmds, units), host, port,
                                      key=link_key, key_file=link_key_file,
                                      command_ranges=ranges, rx_budget=rx_fraction * self.dt,
                                      rx_max_commands=rx_max_commands)
        elif self.hil:
            raise DownholeInputError("HIL mode needs a link to the rig")
        cmd_cols = tuple(f"command_{c}" for c in plant.command_names)
        self.channels = (("time",) + tuple(n for n in obs_names if n != "time")
                         + REFERENCE_NAMES + cmd_cols
                         + ("wall_lag", "exec_time", "controller_on", "safe_action",
                            "rx_time", "rx_listen_time"))
        self.ring_capped = None
        if ring_bytes is not None:
            fits = max(1, int(ring_bytes) // (8 * len(self.channels)))
            if ring_rows > fits:
                self.ring_capped = int(ring_rows)
                ring_rows = fits
        self.recorder = RingRecorder(self.channels, ring_rows, chunk_dir)
        self._row = np.zeros(len(self.channels))
        self.events: deque = deque(maxlen=1000)
        self.event_count = 0
        self._stop = threading.Event()
        self._switch_lock = threading.Lock()
        self._pending_controller = None
        self.running = False
        self._reset_state()

    # ---------------------------------------------------------------- controls (thread-safe)
    def stop(self) -> None:
        """Ask the loop to end after the current step."""
        self._stop.set()

    def _refuse(self, why: str):
        self.stats["rejected_setpoints"] += 1
        self._event("setpoint_rejected", why)
        raise DownholeInputError(why)

    def set_reference(self, axial: float | None = None, angular: float | None = None) -> None:
        """Change the bit-velocity reference seen by the controller.

        Parameters
        ----------
        axial : float, optional
            Reference bit axial velocity, m/s (None: unchanged).
        angular : float, optional
            Reference bit angular velocity, rad/s (None: unchanged).

        Raises
        ------
        DownholeInputError
            A value that is not finite or outside
            :data:`~downhole.sil.plants.REFERENCE_RANGES` (counted as ``rejected_setpoints``;
            the reference is unchanged).
        """
        new = dict(self.reference)
        for k, v in (("axial", axial), ("angular", angular)):
            if v is None:
                continue
            why = check_range(k, v, REFERENCE_RANGES)
            if why is not None:
                self._refuse(f"reference refused: {why}")
            new[k] = float(v)
        self.reference = new
        self._event("reference_change", f"axial={new['axial']:g} angular={new['angular']:g}")

    def set_controller_enabled(self, on: bool) -> None:
        """Controller on (and re-armed after a safe action) or off (open-loop command).

        Parameters
        ----------
        on : bool
            True: the controller drives the plant (and :meth:`arm` is called); False: the manual
            (open-loop) command does.
        """
        self.controller_enabled = bool(on)
        if on:
            self.arm()
        self._event("controller_on" if on else "controller_off", "")

    def arm(self) -> None:
        """End a safe action so that a returning controller takes over again."""
        if self._safe_since is not None:
            self._event("safe_action_cleared", "")
        self._safe_since = None
        self._safe_reached = False
        self._last_valid = time.monotonic()

    def set_manual_command(self, **values) -> None:
        """Change the open-loop command (used while the controller is off).

        Parameters
        ----------
        **values
            Command name -> value in its SI unit (a subset of the plant's commands).

        Raises
        ------
        DownholeInputError
            An unknown name, or a value that is not finite or outside the plant's
            :attr:`~downhole.sil.plants.SilPlant.command_ranges` (counted as
            ``rejected_setpoints``; nothing is changed).
        """
        new = dict(self.manual_command)
        for k, v in values.items():
            if k not in self.manual_command:
                raise DownholeInputError(f"unknown command {k!r}; expected "
                                         f"{tuple(self.manual_command)}")
            why = check_range(k, v, self.plant.command_ranges)
            if why is not None:
                self._refuse(f"manual command refused: {why}")
            new[k] = float(v)
        self.manual_command = new

    def replace_controller(self) -> None:
        """Operator action: hand the UDP link to another controller.

        The current owner is sent BYE and its session ends (a new session id is drawn); while
        the plant runs, the safe action starts first (``controller_timeout`` with the reason
        "operator replaced the controller"), so that nothing is applied until the new owner -
        the next client to say HELLO - is accepted under the ``resume`` policy (``manual``:
        after :meth:`arm`; ``auto``: with its first valid command). Thread-safe: while running,
        the loop does it at the start of its next step."""
        if self.link is None:
            raise DownholeInputError("replace_controller needs a runner with a UDP link")
        if self.running:
            self._replace_requested = True
        else:
            self.link.release_owner()
            self._drain_link_events()

    def switch_controller(self, controller, name: str | None = None) -> None:
        """Operator action: drive the plant with another in-process controller.

        The new controller is checked against the plant (``reset()``/``command()``, and
        :func:`~downhole.control.base.check_pair` for one that declares ``needs`` and
        ``commands``), then takes over at the start of the next step: it is reset there, a
        ``controller_switch`` event names it, and its first command goes through the same
        admissibility check as every other. A safe action in progress stays in force until
        :meth:`arm` (the dashboard's "controller on"). Thread-safe; while stopped the switch is
        made at once.

        Parameters
        ----------
        controller : Controller
            An object with ``reset()`` and ``command(t, observation, reference)``.
        name : str, optional
            Label of the controller in events and the dashboard (default: its class name).

        Raises
        ------
        DownholeInputError
            A runner whose controller is remote (SIL over the UDP link; HIL is fine), or a
            controller that cannot drive this plant.
        """
        from downhole.control.base import check_pair

        if self.link is not None and not self.hil:
            raise DownholeInputError("the controller is remote (UDP link): switch it with "
                                     "replace_controller() on the controller's side")
        if not (hasattr(controller, "command") and hasattr(controller, "reset")):
            raise DownholeInputError("controller must have reset() and command(t, observation, "
                                     "reference)")
        why = check_pair(controller, self.plant)
        if why is not None:
            raise DownholeInputError(f"cannot switch to this controller: {why}")
        label = name or type(controller).__name__
        with self._switch_lock:
            if self.running:
                self._pending_controller = (controller, label)
                return
            self._pending_controller = None
        controller.reset()
        self.controller = controller
        self._bad_since = None
        self._event("controller_switch", label)

    def _take_pending_controller(self) -> None:
        with self._switch_lock:
            pending, self._pending_controller = self._pending_controller, None
        if pending is None:
            return
        controller, label = pending
        controller.reset()
        self.controller = controller
        self._bad_since = None
        self._event("controller_switch", label)

    # ---------------------------------------------------------------- state
    def _reset_state(self):
        self.stats = {k: 0 for k in STATS_KEYS}
        self.stats.update(max_lag_s=0.0, max_exec_s=0.0, mean_exec_s=0.0)
        self._k = 0
        self._safe_since = None
        self._safe_reached = False
        self._held = None
        self._last_cmd = self.plant.default_command()
        self._hil_vals = None
        self._last_valid = time.monotonic()
        self._got_first = False
        self._bad_since = None
        self._replace_requested = False
        self._exec_sum = 0.0
        self._rx_sum = self._listen_sum = 0.0
        self._rx_step = self._listen_step = 0.0
        self._dropped0 = self.link.counters["rx_dropped"] if self.link is not None else 0

    def _event(self, kind: str, detail: str) -> None:
        self.events.append({"time": self._k * self.dt, "wall": time.monotonic(), "kind": kind,
                            "detail": detail})
        self.event_count += 1

    def latest(self) -> dict:
        """Newest recorded row plus the counters (for the dashboard)."""
        out = self.recorder.latest()
        out.update({f"stat_{k}": v for k, v in self.stats.items()})
        return out

    def _controller_reference(self) -> dict:
        """The reference handed to the controller: named signals of :mod:`downhole.signals`."""
        return {"reference_axial_velocity": self.reference["axial"],
                "reference_angular_velocity": self.reference["angular"]}

    def _controller_obs(self, obs: dict) -> dict:
        o = dict(obs)
        o["reference_axial_velocity"] = self.reference["axial"]
        o["reference_angular_velocity"] = self.reference["angular"]
        return o

    # ---------------------------------------------------------------- safety
    def _safe_command(self, t: float) -> dict:
        s = self.safety
        tau = t - self._safe_since
        safe = self.plant.safe_command()
        if tau <= s.hold:
            return dict(self._held)
        if s.ramp > 0 and tau < s.hold + s.ramp:
            a = (tau - s.hold) / s.ramp
            return {k: (1 - a) * self._held[k] + a * safe[k] for k in safe}
        if not self._safe_reached:
            self._safe_reached = True
            self._event("safe_state_reached", ", ".join(f"{k}={v:g}" for k, v in safe.items()))
        return safe

    def _enter_safe(self, t: float, why: str) -> None:
        self._safe_since = t
        self._safe_reached = False
        self._held = dict(self._last_cmd)
        self.stats["safe_actions"] += 1
        self._event("controller_timeout", why)

    def _drain_link_events(self) -> list:
        kinds = []
        for kind, detail in self.link.events:
            self._event(kind, detail)
            kinds.append(kind)
        self.link.events.clear()
        return kinds

    # ---------------------------------------------------------------- one step
    def _command(self, t: float, obs: dict, start: float) -> dict:
        """The command for the step starting now (also talks to the link)."""
        link = self.link
        remote = None
        self._rx_step = self._listen_step = 0.0
        if link is not None:
            link.begin_step()
            if self._replace_requested:
                self._replace_requested = False
                if self._safe_since is None:
                    self._enter_safe(t, "operator replaced the controller")
                link.release_owner()
            kinds = self._drain_link_events()
            if "controller_bye" in kinds and self._safe_since is None:
                self._enter_safe(t, "controller said bye")
            if link.connected:
                o = self._controller_obs(obs)
                vec = np.array([o[n] for n in self.obs_names])
                seq = link.send_obs(t, vec)
                budget = (self.wait_fraction * self.dt if self.command_timeout is None
                          else self.command_timeout)
                remote = link.wait_command(seq, start + budget)
            else:
                link.poll()
            self._rx_step = link.step_rx_s
            self._listen_step = link.step_listen_s
            self.stats["rx_dropped"] = link.counters["rx_dropped"] - self._dropped0
            if remote is None:
                self.stats["late_commands"] += link.connected
            else:
                if not self._got_first:
                    self._got_first = True
                    self._event("controller_first_command", "")
                self._last_valid = time.monotonic()
                if self._safe_since is not None and self.safety.resume == "auto":
                    self._event("controller_resumed", "")
                    self._safe_since = None
            # the timer runs from the start of the run: no command at all is a timeout too
            if (self._safe_since is None and (self.controller_enabled or self.hil)
                    and time.monotonic() - self._last_valid > self.safety.timeout):
                self._enter_safe(t, f"no valid command for {self.safety.timeout:g} s" +
                                 ("" if self._got_first else " (none since the start)"))
        if self.hil:
            if remote is not None:
                self._hil_vals = remote
            cmd = self._surface_command(t, obs, None)
            hv = self._hil_vals if self._hil_vals is not None else (
                obs["last_node_axial_velocity"], obs["last_node_angular_velocity"])
            cmd = dict(cmd)
            cmd["bit_axial_velocity"], cmd["bit_angular_velocity"] = float(hv[0]), float(hv[1])
            return cmd
        return self._surface_command(t, obs, remote)

    def _surface_command(self, t, obs, remote):
        if self._pending_controller is not None:
            self._take_pending_controller()
        if not self.controller_enabled:
            cmd = dict(self.manual_command)
        elif self._safe_since is not None:
            cmd = self._safe_command(t)
        elif self.controller is not None:
            raw = self.controller.command(t, self._controller_obs(obs), self._controller_reference())
            declared = getattr(self.controller, "commands", None)
            if declared and isinstance(raw, dict):
                # commands a controller does not declare keep their last value (the contract)
                raw = {**{k: v for k, v in self._last_cmd.items() if k not in declared}, **raw}
            why = self.plant.check_command(raw)
            if why is None:
                cmd = {k: float(raw[k]) for k in self.plant.command_names}
                self._bad_since = None
            else:  # never applied: hold the last admissible command
                self.stats["rejected_commands"] += 1
                if self._bad_since is None:
                    self._bad_since = t
                    self._event("command_rejected", why)
                cmd = dict(self._last_cmd)
                if t - self._bad_since >= self.safety.timeout:
                    self._enter_safe(t, f"controller commands rejected for "
                                        f"{self.safety.timeout:g} s: {why}")
                    cmd = self._safe_command(t)
        elif self.link is not None and not self.hil:
            if remote is not None:  # validated by the link (finite, within range)
                cmd = dict(zip(self.plant.command_names, remote.tolist()))
            elif not self._got_first:
                cmd = dict(self.manual_command)  # no controller yet: open loop
            else:
                cmd = dict(self._last_cmd)  # late: hold
        else:
            cmd = dict(self.manual_command)
        self._last_cmd = cmd
        return cmd

    def _record(self, obs, cmd, lag, exec_time):
        r = self._row
        ch = self.channels
        i = 0
        r[0] = self._k * self.dt
        for i, n in enumerate(ch[1:], start=1):
            if n in obs:
                r[i] = obs[n]
            elif n.startswith("command_"):
                r[i] = cmd.get(n[8:], np.nan)
            elif n == "reference_axial_velocity":
                r[i] = self.reference["axial"]
            elif n == "reference_angular_velocity":
                r[i] = self.reference["angular"]
            elif n == "wall_lag":
                r[i] = lag
            elif n == "exec_time":
                r[i] = exec_time
            elif n == "controller_on":
                r[i] = float(self.controller_enabled and self._safe_since is None)
            elif n == "safe_action":
                r[i] = float(self._safe_since is not None)
            elif n == "rx_time":
                r[i] = self._rx_step
            elif n == "rx_listen_time":
                r[i] = self._listen_step
            else:
                r[i] = np.nan
        self.recorder.append(r)

    # ---------------------------------------------------------------- the loop
    def wait_for_controller(self, timeout: float) -> bool:
        """Block until a remote peer has connected and answered a readiness probe.

        The probe is an observation of the initial state with sim_time = -1. The clock starts only
        after this, so a slow-starting controller does not make the first steps run open loop.

        Parameters
        ----------
        timeout : float
            Longest wait, s (wall-clock).

        Returns
        -------
        bool
            True when the controller answered (or there is no UDP link), False on timeout.
        """
        if self.link is None:
            return True
        obs = self._controller_obs(self.plant.reset())
        vec = np.array([obs[n] for n in self.obs_names])
        ok = self.link.probe(vec, timeout)
        self._drain_link_events()
        if ok:
            self._event("controller_ready", "")
        return ok

    def _warm_up(self) -> None:
        """One throw-away step of plant and controller before the clock starts (compiles the
        kernels, fills caches) so that step 0 does not miss its deadline."""
        obs = self.plant.reset()
        cmd = self.plant.default_command()
        if self.controller is not None:
            c = self.controller.command(0.0, self._controller_obs(obs), self._controller_reference())
            cmd = {k: float(c.get(k, cmd[k])) for k in cmd}
        self.plant.step(cmd)

    def run(self, duration: float | None = None, *, reset: bool = True) -> Result:
        """Run for ``duration`` s of simulated time (None: until :meth:`stop`).

        Parameters
        ----------
        duration : float, optional
            Simulated time to run, s (positive; None: until :meth:`stop`).
        reset : bool, optional
            Warm up, reset the plant, the runner's state and the controller first (default True);
            False continues from the last observation.

        Returns
        -------
        Result
            Recorded channels (the plant's, the commands as ``command_<name>``, the references,
            ``wall_lag``, ``exec_time``, ``controller_on``, ``safe_action``); attrs ``stats``,
            ``events`` (JSON) and ``link_counters``.

        Raises
        ------
        DownholeInputError
            If ``duration`` is not a positive finite number.
        """
        if duration is not None and not (isinstance(duration, (int, float))
                                         and math.isfinite(duration) and duration > 0):
            raise DownholeInputError(f"duration must be a positive number of seconds, got "
                                     f"{duration!r}")
        n_steps = None if duration is None else int(round(duration / self.dt))
        if reset:
            self._warm_up()
            obs = self.plant.reset()
            self._reset_state()
            if self.controller is not None:
                self.controller.reset()
            self._record(obs, self._last_cmd, 0.0, 0.0)
        else:
            obs = dict(self.plant.last_observation)
        self._stop.clear()
        self.running = True
        self._event("start", f"dt={self.dt:g} paced={self.paced}")
        self._last_valid = time.monotonic()  # the controller timeout runs from the start
        dt = self.dt
        k0 = self._k
        t0 = time.monotonic() - k0 * dt if self.paced else time.monotonic()
        wall0 = time.monotonic()
        restore = lambda: None
        if self.paced and self.realtime:
            restore, self.scheduler = elevate_priority()
        gc_was = gc.isenabled()
        gc.disable()  # no collector pauses inside the loop (per-step objects hold no cycles)
        try:
            while not self._stop.is_set() and (n_steps is None or self._k - k0 < n_steps):
                k = self._k
                if self.paced:
                    sleep_until(t0 + k * dt, self.spin)
                start = time.monotonic()
                t = k * dt
                cmd = self._command(t, obs, start)
                obs = self.plant.step(cmd)
                self._k = k + 1
                end = time.monotonic()
                ex = end - start
                st = self.stats
                st["steps"] += 1
                self._exec_sum += ex
                rx = self._rx_step
                self._rx_sum += rx
                st["max_rx_s"] = max(st["max_rx_s"], rx)
                self._listen_sum += self._listen_step
                st["max_rx_listen_s"] = max(st["max_rx_listen_s"], self._listen_step)
                if ex > dt:
                    st["overruns"] += 1
                st["max_exec_s"] = max(st["max_exec_s"], ex)
                lag = end - (t0 + (k + 1) * dt) if self.paced else 0.0
                if lag > 0:
                    st["deadline_misses"] += 1
                    st["max_lag_s"] = max(st["max_lag_s"], lag)
                    if lag > self.max_lag:
                        t0 += lag
                        st["resyncs"] += 1
                        self._event("resync", f"{lag * 1e3:.1f} ms behind")
                if self._k % self.record_every == 0:
                    self._record(obs, cmd, lag, ex)
        finally:
            if gc_was:
                gc.enable()
            restore()
            self.running = False
            wall = time.monotonic() - wall0
            st = self.stats
            st["wall_s"] = wall
            st["sim_s"] = (self._k - k0) * dt
            st["real_time_factor"] = st["sim_s"] / wall if wall > 0 else float("inf")
            st["mean_exec_s"] = self._exec_sum / max(st["steps"], 1)
            st["mean_rx_s"] = self._rx_sum / max(st["steps"], 1)
            st["mean_rx_listen_s"] = self._listen_sum / max(st["steps"], 1)
            st["deadline_miss_fraction"] = st["deadline_misses"] / max(st["steps"], 1)
            self._event("stop", f"{st['steps']} steps")
            self.recorder.flush()
        return self.result()

    def result(self) -> Result:
        """The recording as a Result: the rows in memory, or the whole run from the chunk files
        when the ring has dropped its oldest rows."""
        import json

        units = {f"command_{c}": self.plant.units.get(c, "") for c in self.plant.command_names}
        units.update({n: u for n, u in self.plant.units.items() if n in self.channels})
        units.update(wall_lag="s", exec_time="s", rx_time="s", rx_listen_time="s")
        attrs = {"model": self.plant.name, "dt": self.dt, "scheduler": self.scheduler,
                 "runtime": "real-time" if self.paced else "unpaced",
                 "stats": json.dumps(self.stats),
                 "events": json.dumps(list(self.events)),
                 "safety": json.dumps(asdict(self.safety)), "hil": int(self.hil),
                 "controller": type(self.controller).__name__ if self.controller is not None
                 else ("remote" if self.link is not None else "none")}
        if self.link is not None:
            attrs["link_counters"] = json.dumps(self.link.counters)
        attrs.update({k: v for k, v in self.plant.info.items() if isinstance(v, (str, int,
                                                                                  float))})
        rec = self.recorder
        if rec.chunk_dir is not None and rec.count > rec.capacity and rec.disk_error is None:
            # the ring has dropped the oldest rows: the whole run is in the chunk files
            from downhole.sil.recorder import load_chunks

            rec.flush()
            res = load_chunks(rec.chunk_dir, units, attrs)
            res.dataset.attrs.pop("incomplete", None)  # a live read: the run owns the folder
            return res
        return rec.to_result(units, attrs)

    def stream_to(self, chunk_dir) -> None:
        """Record to chunk files in ``chunk_dir`` as well (before the run starts): the run is
        longer than the ring keeps, so the whole run goes to disk and :meth:`result` reads it
        back from there."""
        self.recorder = RingRecorder(self.channels, self.recorder.capacity, chunk_dir)

    def close(self) -> None:
        """Close the link (sends BYE to the peer)."""
        if self.link is not None:
            self.link.close()
