"""Bit-velocity references for the DHP tracker: step, ramp (Eqs. 4.48-4.49), sine (Eq. 4.47), user.

A :class:`BitReference` gives the desired bit axial velocity v_d (m/s) and angular velocity
omega_d (rad/s) at any time t >= 0, and their integrals x_d, alpha_d (the position references of
the deviation states). It is a plain description (kind + numbers) that saves to JSON.

Behaviour past the end: the ramp of Eqs. 4.48-4.49 is defined on [0, t_f) of its own ``t_f``
and holds its end value (the starting level) afterwards; the step holds; the sine continues;
the user reference holds its last sample.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from downhole.errors import DownholeInputError

__all__ = ["REFERENCE_KINDS", "BitReference"]

REFERENCE_KINDS = ("step", "ramp", "sine", "user")


@dataclass(frozen=True)
class BitReference:
    """Desired bit velocities.

    Attributes
    ----------
    kind : {"step", "ramp", "sine", "user"}
    axial : float
        Step: v_d (m/s). Ramp: the low level (10 mm/s in Eq. 4.48; high = 2 x low).
        Sine: the mean (20 mm/s in Eq. 4.47; amplitude = axial / 2).
    angular : float
        The same for omega_d (rad/s): 20 (step), 20 (ramp low), 40 (sine mean).
    t_final : float
        Ramp: the t_f of Eqs. 4.48-4.49, s.
    frequency : float
        Sine: angular frequency, rad/s (0.1 pi in Eq. 4.47).
    time, axial_values, angular_values : tuple of float
        User reference samples (s, m/s, rad/s), linearly interpolated, held after the last.
    """

    kind: str = "step"
    axial: float = 0.01
    angular: float = 20.0
    t_final: float = 40.0
    frequency: float = 0.1 * math.pi
    time: tuple = ()
    axial_values: tuple = ()
    angular_values: tuple = ()

    def __post_init__(self):
        if self.kind not in REFERENCE_KINDS:
            raise DownholeInputError(f"reference kind must be one of {REFERENCE_KINDS}, got "
                                     f"{self.kind!r}")
        for name in ("axial", "angular", "t_final", "frequency"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v)):
                raise DownholeInputError(f"reference {name} must be a finite number, got {v!r}")
        if self.kind == "ramp" and self.t_final <= 0:
            raise DownholeInputError(f"ramp reference t_final must be > 0, got {self.t_final}")
        if self.kind == "user":
            t = np.asarray(self.time, float)
            if t.ndim != 1 or t.size < 1 or len(self.axial_values) != t.size \
                    or len(self.angular_values) != t.size:
                raise DownholeInputError("user reference needs time, axial_values and "
                                         "angular_values of the same length >= 1")
            if t[0] != 0.0 or np.any(np.diff(t) <= 0):
                raise DownholeInputError("user reference time must start at 0 and increase")

    # -------------------------------------------------------------------- constructors
    @classmethod
    def step(cls, axial=0.01, angular=20.0) -> BitReference:
        """Constant v_d, omega_d from t = 0 (Fig. 4.7: 10 mm/s, 20 rad/s)."""
        return cls("step", float(axial), float(angular))

    @classmethod
    def ramp(cls, t_final=40.0, axial=0.01, angular=20.0) -> BitReference:
        """Eqs. 4.48-4.49: low, ramp to 2 x low over the second quarter, hold, ramp back."""
        return cls("ramp", float(axial), float(angular), t_final=float(t_final))

    @classmethod
    def sine(cls, axial=0.02, angular=40.0, frequency=0.1 * math.pi) -> BitReference:
        """Eq. 4.47: v_d = 20 + 10 sin(0.1 pi t) mm/s, omega_d = 40 + 20 sin(0.1 pi t) rad/s."""
        return cls("sine", float(axial), float(angular), frequency=float(frequency))

    @classmethod
    def user(cls, time, axial, angular) -> BitReference:
        return cls("user", 0.0, 0.0, time=tuple(map(float, time)),
                   axial_values=tuple(map(float, axial)),
                   angular_values=tuple(map(float, angular)))

    # -------------------------------------------------------------------- evaluation
    def velocities(self, t) -> tuple[np.ndarray, np.ndarray]:
        """(v_d, omega_d) at times ``t`` (s)."""
        t = np.asarray(t, dtype=float)
        if self.kind == "step":
            return np.full(t.shape, self.axial), np.full(t.shape, self.angular)
        if self.kind == "sine":
            s = np.sin(self.frequency * t)
            return self.axial + 0.5 * self.axial * s, self.angular + 0.5 * self.angular * s
        if self.kind == "ramp":
            tf = self.t_final
            x = np.clip(t / tf, 0.0, 1.0)
            shape = np.where(x < 0.25, 0.0, np.where(x < 0.5, (x - 0.25) / 0.25,
                                                     np.where(x < 0.75, 1.0,
                                                              1.0 - (x - 0.75) / 0.25)))
            shape = np.where(t >= tf, 0.0, shape)
            return self.axial * (1 + shape), self.angular * (1 + shape)
        tt = np.asarray(self.time)
        return (np.interp(t, tt, self.axial_values), np.interp(t, tt, self.angular_values))

    def sample(self, n_steps: int, dt: float):
        """v_d, omega_d, x_d, alpha_d on the grid k dt, k = 0..n_steps (integrals exact for the
        step and sine, trapezoidal otherwise)."""
        t = np.arange(n_steps + 1) * dt
        v, w = self.velocities(t)
        if self.kind == "step":
            x, a = self.axial * t, self.angular * t
        elif self.kind == "sine":
            c = (1.0 - np.cos(self.frequency * t)) / self.frequency
            x = self.axial * t + 0.5 * self.axial * c
            a = self.angular * t + 0.5 * self.angular * c
        else:
            x = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * dt)])
            a = np.concatenate([[0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * dt)])
        return v, w, x, a

    def to_dict(self) -> dict:
        return {"kind": self.kind, "axial": self.axial, "angular": self.angular,
                "t_final": self.t_final, "frequency": self.frequency, "time": list(self.time),
                "axial_values": list(self.axial_values),
                "angular_values": list(self.angular_values)}

    @classmethod
    def from_dict(cls, d: dict) -> BitReference:
        d = dict(d)
        for k in ("time", "axial_values", "angular_values"):
            if k in d:
                d[k] = tuple(d[k])
        known = set(cls.__dataclass_fields__)
        bad = set(d) - known
        if bad:
            raise DownholeInputError(f"unknown reference keys {sorted(bad)}; known {sorted(known)}")
        return cls(**d)
