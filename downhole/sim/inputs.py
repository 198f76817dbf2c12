"""Surface inputs: how the top of the string is driven (velocity, displacement or force)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from downhole.errors import DownholeInputError
from downhole.units import _is_quantity, as_si, as_si_array

__all__ = ["Signal", "SurfaceInputs", "sample_signal"]

#: A signal: a constant, a callable f(t) (vectorized over arrays), or (times, values) samples
#: interpolated linearly (held constant outside).
Signal = float | Callable | tuple


def sample_signal(sig: Signal, t: np.ndarray, name: str) -> np.ndarray:
    """Evaluate ``sig`` at times ``t``.

    Parameters
    ----------
    sig : float, tuple or callable
        A constant, a callable f(t) (vectorized over arrays; a scalar result is broadcast), or
        ``(times, values)`` samples (1-D, equal length, times in s non-decreasing) interpolated
        linearly and held constant outside.
    t : ndarray
        Sample times, s.
    name : str
        Name of the signal, used in error messages.

    Returns
    -------
    ndarray
        The values at ``t`` (the signal's own unit), shaped like ``t``.

    Raises
    ------
    DownholeInputError
        A malformed signal, a result of the wrong shape, or non-finite values.
    """
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


#: Dimensions of the (axial, angular) inputs of each mode.
_DIMENSIONS = {"velocity": ("velocity", "angular_velocity"),
               "displacement": ("length", "angle"), "force": ("force", "torque")}


def _si_signal(sig, dimension: str, name: str):
    """A signal with its quantities in SI: a quantity string or pint Quantity becomes a float,
    ``(times, values)`` arrays of quantities become float arrays; callables are taken as SI."""
    if callable(sig) and not _is_quantity(sig):
        return sig
    if isinstance(sig, tuple):
        if len(sig) != 2:
            raise DownholeInputError(f"{name}: expected (times, values), got a tuple of "
                                     f"{len(sig)}")
        return (as_si_array(sig[0], "time", f"{name} times"),
                as_si_array(sig[1], dimension, f"{name} values"))
    if isinstance(sig, bool):
        raise DownholeInputError(f"{name}: expected a number, a quantity, (times, values) or "
                                 f"f(t), got {sig!r}")
    if isinstance(sig, str) or _is_quantity(sig):
        return as_si(sig, dimension, name)
    try:
        value = float(sig)
    except (TypeError, ValueError):
        raise DownholeInputError(f"{name}: expected a number, a quantity such as '30 ft/h', "
                                 f"(times, values) or f(t), got {sig!r}") from None
    if not np.isfinite(value):
        raise DownholeInputError(f"{name}: {value} is not a finite number")
    return value


@dataclass(frozen=True)
class SurfaceInputs:
    """Top-drive inputs.

    Use the constructors: :meth:`velocity` (top-drive axial velocity, m/s, and rotary speed,
    rad/s), :meth:`displacement` (top-drive axial displacement, m, and angle, rad, relative to the
    hanging equilibrium), or :meth:`force` (hook load, N, and surface torque, N m).

    Parameters
    ----------
    mode : {"velocity", "displacement", "force"}
        The kind of inputs.
    axial, angular : float, str, tuple or callable
        The axial and angular signals in the units of ``mode`` (see above): constants,
        quantity strings, ``(times, values)`` samples or callables f(t) in SI; quantities are
        converted to SI here.

    Raises
    ------
    DownholeInputError
        An unknown mode, or a signal that does not convert.
    """

    mode: str
    axial: Signal
    angular: Signal

    def __post_init__(self):
        if self.mode not in _DIMENSIONS:
            raise DownholeInputError(f"input mode must be one of {tuple(_DIMENSIONS)}, got "
                                     f"{self.mode!r}")
        for attr, dim in zip(("axial", "angular"), _DIMENSIONS[self.mode]):
            object.__setattr__(self, attr, _si_signal(getattr(self, attr), dim,
                                                      f"{self.mode} input {attr}"))

    @classmethod
    def velocity(cls, axial: Signal = 0.01, angular: Signal = 10.0) -> SurfaceInputs:
        """Velocity-driven top: top-drive axial velocity and rotary speed.

        Parameters
        ----------
        axial : float, str, tuple or callable, optional
            Top-drive axial velocity, m/s (default 0.01), or a quantity such as ``"30 ft/h"``; a
            constant, ``(times, values)`` samples (times in s) or a callable f(t) in SI.
        angular : float, str, tuple or callable, optional
            Top-drive rotary speed, rad/s (default 10), or ``"120 rpm"``; same forms.

        Returns
        -------
        SurfaceInputs

        Raises
        ------
        DownholeInputError
            A value that is not a number, a quantity of the right dimension or a valid signal.
        """
        return cls("velocity", axial, angular)

    @classmethod
    def displacement(cls, time, axial, angular) -> SurfaceInputs:
        """Displacement-driven top: axial displacement and angle at ``time``.

        Relative to the hanging equilibrium; arrays of numbers in SI, of quantity strings or pint
        Quantity arrays.

        Parameters
        ----------
        time : array_like
            Sample times, s.
        axial : array_like
            Top-drive axial displacement at ``time``, m.
        angular : array_like
            Top-drive angle at ``time``, rad.

        Returns
        -------
        SurfaceInputs

        Raises
        ------
        DownholeInputError
            Values that do not convert to finite SI numbers, or arrays of unequal length.
        """
        t = as_si_array(time, "time", "displacement input time")
        return cls("displacement", (t, as_si_array(axial, "length", "displacement input axial")),
                   (t, as_si_array(angular, "angle", "displacement input angular")))

    @classmethod
    def force(cls, hook_load: Signal, torque: Signal) -> SurfaceInputs:
        """Force-driven top: hook load and surface torque.

        Parameters
        ----------
        hook_load : float, str, tuple or callable
            Hook load, N (or ``"250 klbf"``); a constant, ``(times, values)`` samples (times
            in s) or a callable f(t) in SI.
        torque : float, str, tuple or callable
            Surface torque, N m (or ``"10 kft*lbf"``); same forms.

        Returns
        -------
        SurfaceInputs
            Raising :class:`DownholeInputError` as :meth:`velocity` does.
        """
        return cls("force", hook_load, torque)

    def sample(self, t: np.ndarray):
        """Sample the inputs at ``t``; rows = (axial, torsional).

        Velocity mode: positions are the trapezoidal integral of the velocities (from 0);
        displacement mode: velocities are ``np.gradient`` of the displacements. Both assume a
        uniform step ``t[1] - t[0]``.

        Parameters
        ----------
        t : ndarray, shape (n,)
            Uniformly spaced times, s.

        Returns
        -------
        pos : ndarray, shape (2, n)
            Velocity/displacement modes: top axial position (m) and angle (rad). Force mode: hook
            load (N) and surface torque (N m).
        vel : ndarray, shape (2, n)
            Top axial velocity (m/s) and angular velocity (rad/s); zeros in force mode.

        Raises
        ------
        DownholeInputError
            If a signal cannot be evaluated at ``t``.
        """
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
