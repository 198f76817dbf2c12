"""One cell of the benchmark: one controller on one case, through the Plant and Controller
contracts.

The case's plant is the directional FEM of its system with the delayed depth of cut
(:class:`~downhole.string.fem.DirectionalPlant`), wrapped in :class:`MeasuredPlant`, which adds
the case's measurement noise to what the controller sees and delays every command by the case's
actuator delay; the scores are computed from the true signals, which the wrapper logs. A start
from a developed stick-slip cycle runs the stiff PI (the set-point held) for ``pre_time`` s and
then hands over to the controller (:class:`HandOver`); the controller's clock starts at the
hand-over.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from downhole.analysis.metrics import summarize
from downhole.control.base import Controller, check_pair, run_closed_loop
from downhole.errors import DownholeError, DownholeInputError
from downhole.sim.plant import Plant
from downhole.sim.result import Result

__all__ = [
    "SUPPRESS_BAND",
    "SUPPRESS_HOLD",
    "TRUE_CHANNELS",
    "HandOver",
    "MeasuredPlant",
    "NotApplicable",
    "SetPoint",
    "case_plant",
    "run_cell",
    "score_run",
]

#: True plant signals logged for the scores (and the plots).
TRUE_CHANNELS = ("bit_axial_velocity", "bit_angular_velocity", "wob", "tob", "depth_of_cut",
                 "surface_torque", "hook_load", "top_drive_angular_velocity")

#: Stick-slip counts as suppressed once the bit speed stays within this fraction of the
#: speed set-point (a stuck bit is outside).
SUPPRESS_BAND = 0.5
#: ... and it must stay there for at least this long before the end of the run, s.
SUPPRESS_HOLD = 5.0

#: Trace decimation for the report's plots (one sample in this many plant steps).
TRACE_EVERY = 50


class NotApplicable(Exception):
    """A controller cannot be built for a case; the message says why (the cell is ``n/a``)."""


class MeasuredPlant(Plant):
    """A plant seen through noisy sensors and a delayed actuator (the Plant contract over
    another plant's).

    Parameters
    ----------
    inner : Plant
    noise : mapping of str to float
        Standard deviation (signal units) of the white Gaussian noise added to each named
        observation the controller receives.
    delay_steps : int
        Every command reaches ``inner`` this many steps after the controller issued it (the
        set-point of the start fills the pipeline).
    seed : int
        Seed of the noise (the same sequence for every controller on a case).

    Attributes
    ----------
    log : dict of str to ndarray
        After a run: the true observations of :data:`TRUE_CHANNELS` and ``time``, and the
        applied commands ``applied:<name>``, one row per step including t = 0.
    """

    def __init__(self, inner: Plant, *, noise=None, delay_steps: int = 0, seed: int = 0):
        self.inner = inner
        self.dt = inner.dt
        self.command_names = tuple(inner.command_names)
        self.observation_names = tuple(inner.observation_names)
        self.noise = {k: float(v) for k, v in (noise or {}).items()}
        unknown = sorted(set(self.noise) - set(self.observation_names))
        if unknown:
            raise DownholeInputError(f"noise names {unknown} are not observations of "
                                     f"{type(inner).__name__}")
        if not (isinstance(delay_steps, int) and delay_steps >= 0):
            raise DownholeInputError(f"delay_steps must be an integer >= 0, got "
                                     f"{delay_steps!r}")
        self.delay_steps = delay_steps
        self.seed = int(seed)
        self._rows: list = []

    def default_command(self) -> dict:
        return self.inner.default_command()

    def _measure(self, obs: dict) -> dict:
        self._rows.append([obs[c] for c in TRUE_CHANNELS] + [obs.get("time", 0.0)])
        if not self.noise:
            return obs
        seen = dict(obs)
        draws = self._rng.standard_normal(len(self.noise))
        for (name, std), z in zip(self.noise.items(), draws):
            seen[name] = obs[name] + std * z
        return seen

    def _reset(self, start: str, set_point: dict, **options) -> dict:
        obs = self.inner.reset(start=start, set_point=set_point, **options)
        self._rng = np.random.default_rng(self.seed)
        first = np.array([set_point[n] for n in self.command_names], float)
        self._fifo = deque(first.copy() for _ in range(self.delay_steps))
        self._rows = []
        self._applied = [first]
        return self._measure(obs)

    def _step(self, command: np.ndarray) -> dict:
        self._fifo.append(np.array(command, float))
        applied = self._fifo.popleft()
        self._applied.append(applied)
        obs = self.inner.step(dict(zip(self.command_names, applied.tolist())))
        return self._measure(obs)

    @property
    def log(self) -> dict:
        rows = np.asarray(self._rows, float)
        out = {c: rows[:, i] for i, c in enumerate(TRUE_CHANNELS)}
        out["time"] = rows[:, -1]
        applied = np.asarray(self._applied, float)
        out.update({f"applied:{c}": applied[:, i] for i, c in enumerate(self.command_names)})
        return out


class SetPoint(Controller):
    """The stiff PI: the rig's own top-drive PI (and hook) with the set-points held, i.e. the
    speed command is the reference speed and, on a velocity-driven hook, the block feeds at
    the reference ROP.

    Parameters
    ----------
    commands : tuple of str
        The plant's commands (those this controller sets).
    """

    needs = ()

    def __init__(self, commands=("top_drive_angular_velocity",)):
        self.commands = tuple(commands)

    def command(self, t, observation, reference=None) -> dict:
        ref = reference or {}
        out = {}
        for c in self.commands:
            if c == "top_drive_angular_velocity":
                out[c] = float(ref["reference_angular_velocity"])
            elif c == "top_drive_axial_velocity":
                out[c] = float(ref["reference_axial_velocity"])
        return out


class HandOver(Controller):
    """``first`` until ``t_switch`` s, then ``then`` with its clock restarted at the hand-over.

    Commands ``then`` does not set keep their last value (:func:`run_closed_loop` holds them).
    """

    needs = None
    commands = None

    def __init__(self, first, then, t_switch: float):
        self.first, self.then, self.t_switch = first, then, float(t_switch)
        self._dt = None

    @property
    def dt(self):
        return self._dt

    @dt.setter
    def dt(self, value):
        self._dt = value
        for c in (self.first, self.then):
            if getattr(c, "dt", None) is not None:
                c.dt = value

    def reset(self) -> None:
        self.first.reset()
        self.then.reset()

    def command(self, t, observation, reference=None) -> dict:
        if t < self.t_switch - 1e-9:
            return self.first.command(t, observation, reference)
        return self.then.command(t - self.t_switch, observation, reference)


def case_plant(case, system=None):
    """The case's true plant: the FEM of its system (delayed depth of cut, the rig's PI top
    drive, the case's hook) behind the case's sensors and actuator delay."""
    from downhole.params.rig import Hook
    from downhole.string.fem import DirectionalPlant

    system = system if system is not None else case.drilling_system()
    model = system.build("fem", n_elements=case.n_elements)
    td = system.rig.top_drive.__class__(inertia=system.rig.top_drive.inertia,
                                        kp=system.rig.top_drive.kp, ki=system.rig.top_drive.ki,
                                        speed=case.speed)
    hk = system.rig.hook
    if case.hook == "force":
        hook = Hook(mode="force", wob=case.wob, servo_stiffness=hk.servo_stiffness,
                    servo_damping=hk.servo_damping, block_mass=hk.block_mass)
    else:
        hook = Hook(mode="velocity", wob=case.wob, velocity=case.rop,
                    servo_stiffness=hk.servo_stiffness, servo_damping=hk.servo_damping,
                    block_mass=hk.block_mass)
    inner = DirectionalPlant(model, case.dt, top_drive=td, hook=hook, depth_of_cut="delayed")
    return MeasuredPlant(inner, noise=case.noise_levels(), delay_steps=case.delay_steps,
                         seed=case.seed)


def _windowed(result_time, lo, hi):
    return (result_time >= lo - 1e-12) & (result_time <= hi + 1e-12)


def score_run(log: dict, commands: dict, case, bit_radius: float,
              set_points: dict | None = None) -> dict:
    """The scores of one run from its true log and the controller's issued commands.

    See :data:`downhole.compare.SCORES` for the definitions.
    """
    t = log["time"]
    t0, t_end = case.handover_time, case.handover_time + case.duration
    ref_v, ref_w = case.reference_rop(), case.speed
    channels = {c: log[c] for c in TRUE_CHANNELS}
    channels["reference_axial_velocity"] = np.full(t.size, ref_v)
    channels["reference_angular_velocity"] = np.full(t.size, ref_w)
    res = Result(t, channels, attrs={"bit_radius": bit_radius})
    window = (t0 + 0.5 * (t_end - t0), t_end)
    s = summarize(res, window=window)
    ctrl = _windowed(t, t0, t_end)
    omega = log["bit_angular_velocity"][ctrl]
    tc = t[ctrl]
    outside = np.nonzero(np.abs(omega - ref_w) > SUPPRESS_BAND * abs(ref_w))[0]
    if outside.size == 0:
        t_sup = 0.0
    else:
        last = float(tc[outside[-1]])
        t_sup = None if last > t_end - SUPPRESS_HOLD else last - t0
    effort, rate = {}, {}
    for name, u in commands.items():
        u = np.asarray(u, float)[ctrl]
        sp = (set_points or {}).get(name, float(u[0]))
        effort[name] = float(np.sqrt(np.mean((u - sp) ** 2)))
        rate[name] = float(np.mean(np.abs(np.diff(u))) / case.dt) if u.size > 1 else 0.0
    return {
        "stick_slip_severity": _finite(s["stick_slip_severity"]),
        "time_to_suppress": t_sup,
        "stuck_fraction": s["stuck_fraction"],
        "bit_bounce_fraction": s["bit_bounce_fraction"],
        "mean_rop": s["mean_rop"],
        "mse": _finite(s["mse"]),
        "tracking_rms_angular": s["tracking_rms_angular"],
        "tracking_rms_axial": s["tracking_rms_axial"],
        "peak_surface_torque": float(np.max(np.abs(log["surface_torque"][ctrl]))),
        "effort": effort,
        "command_rate": rate,
    }


def _finite(x):
    return float(x) if x is not None and math.isfinite(x) else None


def run_cell(case, controller, *, system=None, trace: bool = True) -> dict:
    """Run ``controller`` on ``case``; returns ``{"status": "ok", "scores": ..., "trace": ...}``,
    ``{"status": "n/a", "reason": ...}`` (the pair does not fit, :func:`check_pair`) or
    ``{"status": "failed", "reason": ...}`` (the run diverged or a command was refused).
    """
    system = system if system is not None else case.drilling_system()
    plant = case_plant(case, system)
    why = check_pair(controller, plant.inner)
    if why:
        return {"status": "n/a", "reason": why}
    if case.start == "stick_slip":
        loop = HandOver(SetPoint(_rotary_and_feed(plant)), controller, case.handover_time)
        start = "rest"
    else:
        loop = controller
        start = case.start
    ref = {"reference_axial_velocity": case.reference_rop(),
           "reference_angular_velocity": case.speed}
    set_point = {"top_drive_angular_velocity": case.speed}
    if "top_drive_axial_velocity" in plant.command_names:
        set_point["top_drive_axial_velocity"] = case.rop
    try:
        out = run_closed_loop(plant, loop, case.handover_time + case.duration, reference=ref,
                              start=start, set_point=set_point)
    except DownholeError as exc:  # diverged, a refused command, a controller input error
        t_fail = len(plant._rows) * plant.dt
        return {"status": "failed", "reason": f"{type(exc).__name__} at t = {t_fail:.3g} s: "
                                              f"{exc}"}
    log = plant.log
    commands = {c: out[f"command:{c}"] for c in plant.command_names}
    sp = dict(plant.default_command(), **set_point)
    scores = score_run(log, commands, case, system.bit.radius, sp)
    cell = {"status": "ok", "scores": scores}
    if trace:
        k = slice(0, None, TRACE_EVERY)
        cell["trace"] = {"time": log["time"][k].round(4).tolist(),
                         "bit_angular_velocity": log["bit_angular_velocity"][k].round(4).tolist(),
                         "bit_axial_velocity": log["bit_axial_velocity"][k].round(7).tolist(),
                         "surface_torque": log["surface_torque"][k].round(1).tolist(),
                         "speed_command": out["command:top_drive_angular_velocity"][k]
                         .round(4).tolist()
                         if "command:top_drive_angular_velocity" in out else None}
    return cell


def _rotary_and_feed(plant) -> tuple:
    return tuple(c for c in plant.command_names
                 if c in ("top_drive_angular_velocity", "top_drive_axial_velocity"))
