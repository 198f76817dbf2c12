"""Z-torque: a top-drive speed command that matches the drill pipe's torsional impedance.

A torsional wave travelling up the pipe carries torque and speed in the ratio of the pipe's
characteristic impedance Z = J sqrt(rho G) (N m s/rad). A stiff speed-controlled top drive
reflects it back down (reflection coefficient close to -1), which is what sustains stick-slip; a
top drive whose speed yields to torque as omega = omega_sp - (T - T_mean) / Z looks to the wave
like more pipe and absorbs it (reflection 0). This is the idea of Z-torque (Dwars, Kamphorst and
Blanken, SPE-173045, 2015); Simulator4nDOF's ``TopdriveController`` is a public formulation of
the same law. Here the mean torque ``T_mean`` follows the measured surface torque through a
first-order low-pass (time constant ``tau``), so the mean speed still equals the set-point, and
the measured torque is the torque the top drive delivers to the string (``surface_torque``: no
inertia compensation needed).

The controller sets only the rotary command ``top_drive_angular_velocity`` (the drive's speed
command at every fidelity); the axial command keeps the plant's default or another controller's.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from downhole.control.base import Controller
from downhole.errors import DownholeInputError

__all__ = ["ZTorque", "torsional_impedance"]


def torsional_impedance(section) -> float:
    """Characteristic torsional impedance J sqrt(rho G) of a pipe section, N m s/rad.

    Parameters
    ----------
    section : PipeSection
        The pipe's cross-section and material.

    Returns
    -------
    float
        The impedance, N m s/rad.
    """
    return float(section.torsional_impedance)


class ZTorque(Controller):
    """Impedance-matching top-drive speed command.

    Parameters
    ----------
    impedance : float
        The top pipe's torsional impedance Z, N m s/rad (:func:`torsional_impedance`).
    speed : float, optional
        Speed set-point, rad/s; default: the reference ``reference_angular_velocity``.
    tau : float
        Time constant of the mean-torque low-pass, s (several stick-slip periods; 10 s).
    gain : float
        Fraction of the impedance-matching term applied (1 = matched).
    dt : float
        Controller step, s (the plant's).

    Examples
    --------
    >>> from downhole.params.strings import PipeSection
    >>> z = torsional_impedance(PipeSection(outer_diameter=0.127, inner_diameter=0.1086))
    >>> c = ZTorque(z, speed=10.0, dt=1e-3)
    >>> c.reset()
    >>> c.command(0.0, {"surface_torque": 5000.0})["top_drive_angular_velocity"]
    10.0
    """

    needs = ("surface_torque",)
    commands = ("top_drive_angular_velocity",)

    def __init__(self, impedance: float, *, speed: float | None = None, tau: float = 10.0,
                 gain: float = 1.0, dt: float = 1e-3):
        for name, value, strict in (("impedance", impedance, True), ("tau", tau, True),
                                    ("gain", gain, False), ("dt", dt, True)):
            if not (isinstance(value, (int, float)) and math.isfinite(value)
                    and (value > 0 if strict else value >= 0)):
                kind = "positive" if strict else "non-negative"
                raise DownholeInputError(f"ZTorque {name} must be a {kind} number, got "
                                         f"{value!r}")
        if speed is not None and not math.isfinite(float(speed)):
            raise DownholeInputError(f"ZTorque speed must be finite, got {speed!r}")
        self.impedance, self.tau, self.gain, self.dt = (float(impedance), float(tau),
                                                        float(gain), float(dt))
        self.speed = None if speed is None else float(speed)
        self.reset()

    def reset(self) -> None:
        self._mean = None

    def command(self, t: float, observation: Mapping[str, float],
                reference: Mapping[str, float] | None = None) -> dict:
        """One controller step: the impedance-matching top-drive speed command.

        ``w = w_sp - gain (T - T_mean) / Z`` with T_mean a first-order low-pass (time constant
        ``tau``) of the surface torque, clipped to [0, 2 |w_sp|].

        Parameters
        ----------
        t : float
            Time, s (unused).
        observation : mapping
            Must hold ``surface_torque``, N m.
        reference : mapping, optional
            ``reference_angular_velocity`` (rad/s), the set-point when ``speed`` was not given.

        Returns
        -------
        dict
            ``{"top_drive_angular_velocity": rad/s}``.

        Raises
        ------
        DownholeInputError
            If no set-point is available.
        """
        torque = float(observation["surface_torque"])
        if self.speed is not None:
            sp = self.speed
        else:
            try:
                sp = float(reference["reference_angular_velocity"])
            except (TypeError, KeyError):
                raise DownholeInputError("ZTorque without a speed needs the reference "
                                         "'reference_angular_velocity'") from None
        if self._mean is None:
            self._mean = torque
        else:
            self._mean += (torque - self._mean) * min(1.0, self.dt / self.tau)
        w = sp - self.gain * (torque - self._mean) / self.impedance
        # the drive never reverses the string, nor runs above twice the set-point
        return {"top_drive_angular_velocity": min(max(w, 0.0), 2.0 * abs(sp))}
