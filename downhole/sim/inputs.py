"""Surface inputs: how the top of the string is driven (velocity, displacement or force)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Union

import numpy as np

from downhole.errors import DownholeInputError

__all__ = ["SurfaceInputs", "Signal", "sample_signal"]

#: A signal: a constant, a callable f(t) (vectorized over arrays), or (times, values) samples
#: interpolated linearly (held constant outside).
Signal = Union[float, Callable, tuple]


def sample_signal(sig: Signal, t: np.ndarray, name: str) -> np.ndarray:
    """Evaluate ``sig`` at times ``t``."""
    if callable(sig):
        out = np.asarray(sig(t), dtype=float)
        if out.shape == ():
            out = np.full(t.shape, float(out))
    elif isinstance(sig, tuple):
        if len(sig) != 2:
            raise DownholeInputError(f"{name}: expected (times, values), got a tuple of {len(sig)}")
        ts, vs = (np.asarray(a, dtype=float) for a in sig)
        if ts.ndim != 1 or ts.shape != vs.shape or ts.size < 1:
            raise DownholeInputError(f"{name}: times and values must be 1-D arrays of equal length")
        if np.any(np.diff(ts) < 0):
            raise DownholeInputError(f"{name}: sample times must be non-decreasing")
        out = np.interp(t, ts, vs)
    else:
        try:
            out = np.full(t.shape, float(sig))
        except (TypeError, ValueError):
            raise DownholeInputError(f"{name}: expected a number, (t, values) or f(t), "
                                     f"got {sig!r}") from None
    if out.shape != t.shape:
        raise DownholeInputError(f"{name}: signal returned shape {out.shape}, expected {t.shape}")
    if not np.all(np.isfinite(out)):
        raise DownholeInputError(f"{name}: signal has non-finite values")
    return out


@dataclass(frozen=True)
class SurfaceInputs:
    """Top-drive inputs.

    Use the constructors: :meth:`velocity` (top-drive axial velocity, m/s, and rotary speed,
    rad/s), :meth:`displacement` (top-drive axial displacement, m, and angle, rad, relative to the
    hanging equilibrium), or :meth:`force` (hook load, N, and surface torque, N m).
    """

    mode: str
    axial: Signal
    angular: Signal

    @classmethod
    def velocity(cls, axial: Signal = 0.01, angular: Signal = 10.0) -> "SurfaceInputs":
        return cls("velocity", axial, angular)

    @classmethod
    def displacement(cls, time, axial, angular) -> "SurfaceInputs":
        t = np.asarray(time, float)
        return cls("displacement", (t, np.asarray(axial, float)), (t, np.asarray(angular, float)))

    @classmethod
    def force(cls, hook_load: Signal, torque: Signal) -> "SurfaceInputs":
        return cls("force", hook_load, torque)

    def sample(self, t: np.ndarray):
        """Arrays (2, len(t)) of (position, velocity) for velocity/displacement modes, or
        (force, 0) for force mode, rows = (axial, torsional)."""
        dt = t[1] - t[0] if t.size > 1 else 1.0
        pos = np.zeros((2, t.size))
        vel = np.zeros((2, t.size))
        for i, (sig, name) in enumerate(((self.axial, "axial"), (self.angular, "angular"))):
            vals = sample_signal(sig, t, f"{self.mode} input {name}")
            if self.mode == "velocity":
                vel[i] = vals
                pos[i, 1:] = np.cumsum(0.5 * (vals[1:] + vals[:-1]) * dt)
            elif self.mode == "displacement":
                pos[i] = vals
                vel[i] = np.gradient(vals, dt) if t.size > 1 else 0.0
            elif self.mode == "force":
                pos[i] = vals
            else:
                raise DownholeInputError(f"unknown input mode {self.mode!r}")
        return pos, vel
