"""An auto-driller: holds a weight-on-bit (or rate-of-penetration) set-point through the hook.

A rig's auto-driller lowers the travelling block (the drawworks) so that the weight on bit,
estimated at the surface from the hook load, stays at its set-point:

    WOB_est = W_hang - hook_load,

with W_hang the hook load of the string hanging off bottom (buoyed weight,
:meth:`downhole.system.DrillingSystem.hanging_weight`). The block velocity command
``top_drive_axial_velocity`` (positive downward) is a PI on the WOB error,

    v = k_p e + k_i int(e) dt,    e = WOB_sp - WOB_est,

limited to ``[-max_velocity, max_velocity]`` and in rate (``max_acceleration``), with the
integral held while the command sits on a limit (anti-windup). The gains come from the string's
static axial stiffness k_a (N/m, :meth:`DrillingSystem.lumped_derivation`): feeding the block
faster than the bit drills compresses the string, dWOB/dt ~ k_a (v - v_bit), so

    k_p = 1 / (k_a tau),    k_i = k_p / (2 tau)

place the WOB loop's poles about the integrator at s^2 + s / tau + 1 / (2 tau^2) = 0 (damping
ratio 1/sqrt(2), natural frequency 1 / (sqrt(2) tau)); the bit's own WOB-to-ROP response
(ROP grows with WOB) only adds damping. At steady state the block velocity equals the ROP
the bit drills at that WOB.

In ROP mode (``rop`` set) the block feeds at the ROP set-point and the WOB channel acts only as a
limit: above ``wob_max`` the command drops by k_p (WOB_est - wob_max).

Set-points: the keyword arguments, or the references ``reference_wob`` (N) and
``reference_axial_velocity`` (m/s, the ROP) of :mod:`downhole.signals`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from downhole.control.base import Controller
from downhole.errors import DownholeInputError

__all__ = ["AutoDriller", "autodriller_gains"]


def _num(name, value, *, strict=True, allow_none=False):
    if value is None and allow_none:
        return None
    ok = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
    if not ok or (value <= 0 if strict else value < 0):
        kind = "positive" if strict else "non-negative"
        raise DownholeInputError(f"AutoDriller {name} must be a finite {kind} number, got "
                                 f"{value!r}")
    return float(value)


def autodriller_gains(axial_stiffness: float, tau: float) -> tuple[float, float]:
    """PI gains ``(k_p, k_i) = (1 / (k_a tau), k_p / (2 tau))`` of the WOB loop.

    Parameters
    ----------
    axial_stiffness : float
        Static axial stiffness of the string, N/m.
    tau : float
        Closed-loop time constant, s.

    Returns
    -------
    (float, float)
        k_p in (m/s)/N and k_i in (m/s)/(N s).

    Examples
    --------
    >>> autodriller_gains(2e5, 5.0)
    (1e-06, 1e-07)
    """
    k = _num("axial_stiffness", axial_stiffness)
    t = _num("tau", tau)
    kp = 1.0 / (k * t)
    return kp, kp / (2.0 * t)


class AutoDriller(Controller):
    """Auto-driller: WOB (or ROP) set-point through the block velocity, from the hook load.

    Parameters
    ----------
    system : DrillingSystem, optional
        Gives the hanging weight and the axial stiffness (explicit values override it; without
        it both are required).
    wob : float, optional
        WOB set-point, N (default: the reference ``reference_wob``).
    rop : float, optional
        ROP set-point, m/s: ROP mode (the block feeds at ``rop``; ``wob_max`` limits).
    hanging_weight : float, optional
        Hook load off bottom, N.
    axial_stiffness : float, optional
        Static axial stiffness of the string, N/m.
    tau : float
        WOB loop time constant, s (default 5).
    max_velocity : float
        Largest block speed, m/s (default 0.05, 180 m/h).
    max_acceleration : float
        Largest rate of change of the block velocity, m/s^2 (default 0.01).
    wob_max : float, optional
        ROP mode: WOB limit, N (default: no limit).
    dt : float
        Controller step, s (a runner sets it to its control step).

    Examples
    --------
    >>> c = AutoDriller(wob=100e3, hanging_weight=1.0e6, axial_stiffness=2e5, dt=1e-3)
    >>> c.reset()
    >>> c.command(0.0, {"hook_load": 1.0e6})["top_drive_axial_velocity"]  # rate-limited start
    1e-05
    """

    needs = ("hook_load",)
    commands = ("top_drive_axial_velocity",)

    def __init__(self, system=None, *, wob: float | None = None, rop: float | None = None,
                 hanging_weight: float | None = None, axial_stiffness: float | None = None,
                 tau: float = 5.0, max_velocity: float = 0.05, max_acceleration: float = 0.01,
                 wob_max: float | None = None, dt: float = 1e-3):
        if system is not None:
            from downhole.system import DrillingSystem

            if not isinstance(system, DrillingSystem):
                raise DownholeInputError(f"AutoDriller system must be a DrillingSystem, got "
                                         f"{type(system).__name__}")
            if hanging_weight is None:
                hanging_weight = system.hanging_weight()
            if axial_stiffness is None:
                axial_stiffness = _static_axial_stiffness(system)
        missing = [n for n, v in (("hanging_weight", hanging_weight),
                                  ("axial_stiffness", axial_stiffness)) if v is None]
        if missing:
            raise DownholeInputError(f"AutoDriller needs a DrillingSystem or explicit {missing}")
        if wob is not None and rop is not None:
            raise DownholeInputError("AutoDriller holds one set-point: give wob or rop, not both")
        self.wob = _num("wob", wob, strict=False, allow_none=True)
        if rop is not None and not (isinstance(rop, (int, float)) and math.isfinite(rop)
                                    and abs(rop) <= 0.1):
            raise DownholeInputError(f"AutoDriller rop must be a finite number of m/s within "
                                     f"+/-0.1, got {rop!r}")
        self.rop = None if rop is None else float(rop)
        self.hanging_weight = _num("hanging_weight", hanging_weight)
        self.axial_stiffness = _num("axial_stiffness", axial_stiffness)
        self.tau = _num("tau", tau)
        self.max_velocity = _num("max_velocity", max_velocity)
        self.max_acceleration = _num("max_acceleration", max_acceleration)
        self.wob_max = _num("wob_max", wob_max, allow_none=True)
        self.dt = _num("dt", dt)
        self.kp, self.ki = autodriller_gains(self.axial_stiffness, self.tau)
        self.reset()

    def reset(self) -> None:
        self._integral = 0.0
        self._v = None

    def wob_estimate(self, observation: Mapping[str, float]) -> float:
        """Surface WOB estimate W_hang - hook load, N.

        Parameters
        ----------
        observation : mapping
            Must hold ``hook_load``, N.

        Returns
        -------
        float
            Estimated weight on bit, N.

        Raises
        ------
        DownholeInputError
            If the hook load is not finite.
        """
        hook = float(observation["hook_load"])
        if not math.isfinite(hook):
            raise DownholeInputError(f"AutoDriller: observation hook_load = {hook!r} is not "
                                     "finite")
        return self.hanging_weight - hook

    def _set_points(self, reference):
        ref = reference or {}
        if self.rop is not None:
            return None, self.rop
        if self.wob is not None:
            return self.wob, None
        for name in ("reference_wob", "reference_axial_velocity"):
            if name in ref:
                try:
                    value = float(ref[name])
                except (TypeError, ValueError):
                    value = math.nan
                if not math.isfinite(value):
                    raise DownholeInputError(f"AutoDriller: {name} {ref[name]!r} is not finite")
                return (value, None) if name == "reference_wob" else (None, value)
        raise DownholeInputError("AutoDriller without a wob or rop set-point needs the reference "
                                 "'reference_wob' (N) or 'reference_axial_velocity' (m/s)")

    def command(self, t: float, observation: Mapping[str, float],
                reference: Mapping[str, float] | None = None) -> dict:
        """One controller step: the block (top-drive axial) velocity command.

        WOB mode: a PI on the WOB estimate; ROP mode: the ROP set-point, reduced when the WOB
        exceeds ``wob_max``. The command is rate- and magnitude-limited, with anti-windup.

        Parameters
        ----------
        t : float
            Time, s (unused).
        observation : mapping
            Must hold ``hook_load`` (N); ``top_drive_axial_velocity`` (m/s) is the starting
            velocity at the first call when present.
        reference : mapping, optional
            ``reference_wob`` (N) or ``reference_axial_velocity`` (m/s), used when neither ``wob``
            nor ``rop`` was given.

        Returns
        -------
        dict
            ``{"top_drive_axial_velocity": m/s}``, positive downward.

        Raises
        ------
        DownholeInputError
            A non-finite hook load or set-point, or no set-point at all.
        """
        wob_sp, rop_sp = self._set_points(reference)
        wob = self.wob_estimate(observation)
        if self._v is None:
            self._v = float(observation.get("top_drive_axial_velocity", 0.0))
        if wob_sp is not None:
            e = wob_sp - wob
            raw = self.kp * e + self.ki * (self._integral + self.dt * e)
        else:
            e = 0.0
            raw = rop_sp
            if self.wob_max is not None and wob > self.wob_max:
                raw -= self.kp * (wob - self.wob_max)
        step = self.max_acceleration * self.dt
        v = min(max(raw, self._v - step, -self.max_velocity), self._v + step, self.max_velocity)
        # anti-windup: integrate only while the command follows the PI (or moves it back)
        if v == raw or (v < raw and e < 0) or (v > raw and e > 0):
            self._integral += self.dt * e
        self._v = v
        return {"top_drive_axial_velocity": v}


def _static_axial_stiffness(system) -> float:
    """1 / sum L_i / (E_i A_i): the string's static axial stiffness, top clamped, N/m."""
    return 1.0 / sum(s.length / (s.section.young_modulus * s.section.area)
                     for s in system.string.segments)
