"""The rig at the top of the string: top-drive inertia and speed controller (PI, soft torque), hook.

The top drive is an inertia on the top node's angular DOF. Its motor torque is set by

* ``"pi"``: T = Kp (Omega_ref - omega) + Ki (theta_ref - theta), theta_ref = integral of
  Omega_ref, i.e. a PI on the speed error (the integral of the speed error is an angle error, so
  the PI acts as a spring Ki and a damper Kp towards the reference angle; it is applied
  implicitly by the kernels);
* ``"soft_torque"``: the same PI with the set-point lowered by ``soft_gain`` times the
  high-pass-filtered string torque (time constant ``soft_tau``): the drive yields to torque
  oscillations (Tucker and Wang's soft-torque idea, a downhole addition);
* ``"torque"``: the commanded torque is applied directly (for controllers such as DHP).

The hook is either force-driven (``"force"``: a constant or commanded hook load, N) or
velocity-driven (``"velocity"``: a stiff servo makes the block follow a commanded velocity).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from downhole.errors import DownholeInputError

__all__ = ["DEFAULT_TOP_DRIVE_INERTIA", "Hook", "TopDrive"]

#: Top-drive rotor + gearbox inertia on the string's top node, kg m^2. The seed gives none; 500 is
#: the value used throughout (directional FEM, hybrid, DHP design models, SIL plants). Every
#: default of a top-drive inertia in the package refers to this one name.
DEFAULT_TOP_DRIVE_INERTIA = 500.0

_TD_MODES = ("pi", "soft_torque", "torque")
_HOOK_MODES = ("force", "velocity")


def _quantities(obj, what: str, dims: dict) -> None:
    """Quantity strings and pint Quantities of a frozen rig part to SI floats (numbers are SI
    and keep their checks): ``TopDrive(speed="120 rpm")``, ``Hook(wob="25 klbf")``."""
    from downhole.units import si_or_number

    for name, dim in dims.items():
        object.__setattr__(obj, name, si_or_number(getattr(obj, name), dim, f"{what} {name}"))


def _num(name, value, lo=0.0, strict=False):
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise DownholeInputError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(x) or (x <= lo if strict else x < lo):
        raise DownholeInputError(f"{name} must be {'>' if strict else '>='} {lo}, got {value!r}")
    return x


@dataclass(frozen=True)
class TopDrive:
    """Top drive: inertia and speed controller.

    Parameters
    ----------
    inertia : float
        Rotor + gearbox inertia on the string's top node, kg m^2 (default
        :data:`DEFAULT_TOP_DRIVE_INERTIA`).
    mode : {"pi", "soft_torque", "torque"}
    speed : float
        Speed set-point Omega_ref, rad/s (``pi``/``soft_torque``) -- or the constant torque, N m,
        in ``torque`` mode.
    kp : float
        Proportional gain, N m s/rad (1e4).
    ki : float
        Integral gain, N m/rad (2e3).
    soft_gain : float
        Soft-torque gain, rad/s per N m of high-passed string torque.
    soft_tau : float
        Soft-torque high-pass time constant, s.
    ramp_time : float
        Time to ramp the set-point from 0 to ``speed``, s (0 = step).
    """

    inertia: float = DEFAULT_TOP_DRIVE_INERTIA
    mode: str = "pi"
    speed: float = 10.0
    kp: float = 1e4
    ki: float = 2e3
    soft_gain: float = 5e-4
    soft_tau: float = 2.0
    ramp_time: float = 0.0

    def __post_init__(self):
        if self.mode not in _TD_MODES:
            raise DownholeInputError(f"top drive mode must be one of {_TD_MODES}, got {self.mode!r}")
        _quantities(self, "top drive", {
            "inertia": "inertia", "speed": "torque" if self.mode == "torque" else
            "angular_velocity", "kp": "torsional_damping", "ki": "torsional_stiffness",
            "soft_tau": "time", "ramp_time": "time"})
        _num("top drive inertia", self.inertia, strict=True)
        _num("top drive kp", self.kp)
        _num("top drive ki", self.ki)
        _num("top drive soft_gain", self.soft_gain)
        _num("top drive soft_tau", self.soft_tau, strict=True)
        _num("top drive ramp_time", self.ramp_time)
        try:
            s = float(self.speed)
        except (TypeError, ValueError):
            raise DownholeInputError(f"top drive speed must be a number, got {self.speed!r}") from None
        if not math.isfinite(s):
            raise DownholeInputError(f"top drive speed must be finite, got {self.speed!r}")

    def command(self, t):
        """Set-point at times ``t``: ``speed``, ramped up from 0 over ``ramp_time`` if > 0.

        Parameters
        ----------
        t : array_like
            Times, s.

        Returns
        -------
        ndarray
            Set-point shaped like ``t``: rad/s, or N m in torque mode.
        """
        import numpy as np

        t = np.asarray(t, float)
        if self.ramp_time > 0:
            return self.speed * np.clip(t / self.ramp_time, 0.0, 1.0)
        return np.full(t.shape, float(self.speed))


@dataclass(frozen=True)
class Hook:
    """Hook: force-driven (hook load) or velocity-driven (block velocity servo).

    Parameters
    ----------
    mode : {"force", "velocity"}
    wob : float
        ``force`` mode: target static weight on bit, N; the hook load is the buoyed weight minus
        this (constant hook load). Also the initial WOB of the static state.
    velocity : float
        ``velocity`` mode: block velocity, m/s (positive downward).
    block_mass : float
        Travelling block mass added to the top node, kg.
    servo_stiffness, servo_damping : float
        Velocity servo gains, N/m and N s/m.
    """

    mode: str = "force"
    wob: float = 120e3
    velocity: float = 0.0
    block_mass: float = 0.0
    servo_stiffness: float = 1e7
    servo_damping: float = 1e6

    def __post_init__(self):
        if self.mode not in _HOOK_MODES:
            raise DownholeInputError(f"hook mode must be one of {_HOOK_MODES}, got {self.mode!r}")
        _quantities(self, "hook", {"wob": "force", "velocity": "velocity", "block_mass": "mass",
                                   "servo_stiffness": "stiffness",
                                   "servo_damping": "damping"})
        _num("hook wob", self.wob)
        _num("hook block_mass", self.block_mass)
        _num("hook servo_stiffness", self.servo_stiffness, strict=True)
        _num("hook servo_damping", self.servo_damping)
