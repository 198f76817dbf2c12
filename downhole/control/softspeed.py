"""SoftSpeed-style tuned soft-torque top-drive speed control, and the stiff PI it is compared to.

A top drive under a PI speed controller (gains P, N m s/rad, and I, N m/rad) with rotor inertia
J looks to a torsional wave arriving from the drill pipe like the mechanical impedance

    Z_td(i w) = P + i (w J - I / w)          (torque per unit speed, N m s/rad).

The pipe carries waves with its characteristic impedance Z = J_p sqrt(rho G) (N m s/rad,
:func:`downhole.control.ztorque.torsional_impedance`), so the top reflects a speed wave with the
coefficient

    r(w) = (Z - Z_td(i w)) / (Z + Z_td(i w)),

close to -1 for a stiff drive (P >> Z: the stick-slip wave comes back intact and the cycle
sustains itself). Kyllingstad and Nessjoen (SPE-119660, 2009, "A new stick-slip prevention
system") tune the drive's own speed controller so that it absorbs the wave at the stick-slip
frequency w_s:

* **I = J w_s^2**: the integral term's spring cancels the rotor's inertia at w_s (the
  controller's resonance sits at the stick-slip frequency), so that Z_td(i w_s) = P is a pure
  damper;
* **P = a Z**: a fraction ``a`` of the pipe's characteristic impedance, giving
  r(w_s) = (1 - a) / (1 + a); a = 1 absorbs the wave completely, smaller fractions trade
  absorption for a stiffer mean-speed hold.

Here w_s is the string's first torsional natural frequency with the top clamped
(:meth:`downhole.system.DrillingSystem.lumped_derivation`, from a fine FEM of the description),
Z is the top pipe section's and J the rig's top-drive inertia.

Every fidelity's top drive follows its speed command (``top_drive_angular_velocity``:
kinematically in the lumped and neutral models, through the rig's stiff PI servo in the FEM and
hybrid models), so the controller computes the drive's response in software: it integrates

    J d(omega)/dt = P (omega_sp - omega) + I theta_e - T_s,    d(theta_e)/dt = omega_sp - omega,

with the measured surface torque T_s (``surface_torque``), and commands omega. The string then
sees Z_td above, whatever the drive's own servo is (as long as it is stiff in the stick-slip band).
:class:`TopDriveSpeedPI` is the same law with given gains: with a rig's stiff gains it is the
stiff PI baseline.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from downhole.control.base import Controller
from downhole.errors import DownholeInputError

__all__ = [
    "SoftSpeed",
    "TopDriveSpeedPI",
    "reflection_coefficient",
    "softspeed_tuning",
    "stick_slip_frequency",
    "top_drive_impedance",
]


def _number(owner, name, value, *, strict=True, allow_none=False):
    if value is None and allow_none:
        return None
    ok = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
    if not ok or (value <= 0 if strict else value < 0):
        kind = "positive" if strict else "non-negative"
        raise DownholeInputError(f"{owner} {name} must be a finite {kind} number, got {value!r}")
    return float(value)


def softspeed_tuning(impedance: float, frequency: float, inertia: float,
                     fraction: float = 1.0) -> tuple[float, float]:
    """The SoftSpeed gains: ``(P, I) = (fraction Z, J w_s^2)``.

    Parameters
    ----------
    impedance : float
        Characteristic torsional impedance Z of the top pipe, N m s/rad.
    frequency : float
        Stick-slip (first torsional) angular frequency w_s, rad/s.
    inertia : float
        Top-drive inertia J, kg m^2.
    fraction : float
        a = P / Z (0 < a; 1 absorbs the wave at w_s completely).

    Returns
    -------
    (float, float)
        Proportional gain P (N m s/rad) and integral gain I (N m/rad).

    Examples
    --------
    >>> softspeed_tuning(480.0, 1.0, 500.0, 0.5)
    (240.0, 500.0)
    """
    z = _number("softspeed_tuning", "impedance", impedance)
    w = _number("softspeed_tuning", "frequency", frequency)
    j = _number("softspeed_tuning", "inertia", inertia)
    a = _number("softspeed_tuning", "fraction", fraction)
    return a * z, j * w * w


def top_drive_impedance(kp: float, ki: float, inertia: float, omega: float) -> complex:
    """Z_td(i w) = P + i (w J - I / w) of a PI speed-controlled top drive, N m s/rad.

    Parameters
    ----------
    kp : float
        Proportional gain P, N m s/rad.
    ki : float
        Integral gain I, N m/rad.
    inertia : float
        Top-drive inertia J, kg m^2.
    omega : float
        Angular frequency w, rad/s (positive).

    Returns
    -------
    complex
        The drive's impedance, N m s/rad.

    Raises
    ------
    DownholeInputError
        If ``omega`` is not a positive finite number.
    """
    w = _number("top_drive_impedance", "omega", omega)
    return complex(kp, w * inertia - ki / w)


def reflection_coefficient(impedance: float, kp: float, ki: float, inertia: float,
                           omega: float) -> complex:
    """Speed-wave reflection coefficient (Z - Z_td) / (Z + Z_td) of the top drive at ``omega``.

    -1: a clamped (stiff) top, 0: a matched (absorbing) top, +1: a free top.

    Parameters
    ----------
    impedance : float
        Characteristic torsional impedance Z of the top pipe, N m s/rad.
    kp, ki, inertia
        As :func:`top_drive_impedance`.
    omega : float
        Angular frequency, rad/s (positive).

    Returns
    -------
    complex
        The reflection coefficient (dimensionless).

    Raises
    ------
    DownholeInputError
        If ``omega`` is not a positive finite number.
    """
    ztd = top_drive_impedance(kp, ki, inertia, omega)
    return (impedance - ztd) / (impedance + ztd)


def stick_slip_frequency(system, mode: int = 1, reference_elements: int = 400) -> float:
    """A torsional natural frequency of the described string, top clamped, rad/s: the frequency
    SoftSpeed is tuned to.

    Parameters
    ----------
    system : DrillingSystem
        The described system (well, string, bit and Rayleigh damping).
    mode : int
        1 (default): the first torsional mode, the classic stick-slip mode (the frequency the
        lumped chains are matched to, :meth:`DrillingSystem.lumped_derivation`). A string that
        stick-slips in a higher mode (a long bare pipe with a light bit: the observed period is
        that mode's) is tuned to that mode.
    reference_elements : int
        Elements of the fine FEM the frequency is computed on.

    Returns
    -------
    float
        The torsional natural frequency, rad/s.

    Raises
    ------
    DownholeInputError
        If ``mode`` is not an integer from 1 to 20.
    """
    if not (isinstance(mode, int) and not isinstance(mode, bool) and 1 <= mode <= 20):
        raise DownholeInputError(f"stick-slip mode must be an integer 1-20, got {mode!r}")
    if mode == 1:
        return 2.0 * math.pi * float(system.lumped_derivation(reference_elements)
                                     .first_frequency[1])
    from downhole.string.fem import fem_model

    ref = fem_model(system.well, system.string, system.bit, n_elements=reference_elements,
                    friction=0.0, rayleigh_alpha=system.rayleigh_alpha,
                    rayleigh_beta=system.rayleigh_beta)
    return 2.0 * math.pi * float(ref.natural_frequencies("torsional", mode, top="fixed")[-1])


class TopDriveSpeedPI(Controller):
    """A top drive's PI speed controller and inertia, computed in software (see the module
    docstring): the command is the speed of a rotor of inertia ``inertia`` driven by
    P (omega_sp - omega) + I theta_e against the measured surface torque.

    Parameters
    ----------
    kp : float
        Proportional gain P, N m s/rad.
    ki : float
        Integral gain I, N m/rad (0: P only).
    inertia : float
        Rotor inertia J, kg m^2.
    speed : float, optional
        Speed set-point, rad/s; default: the reference ``reference_angular_velocity``.
    max_speed : float, optional
        Largest command, rad/s (default: twice the set-point); the drive never reverses.
    dt : float
        Controller step, s (a runner sets it to its control step).
    """

    needs = ("surface_torque",)
    commands = ("top_drive_angular_velocity",)

    def __init__(self, kp: float, ki: float, inertia: float, *, speed: float | None = None,
                 max_speed: float | None = None, dt: float = 1e-3):
        name = type(self).__name__
        self.kp = _number(name, "kp", kp, strict=False)
        self.ki = _number(name, "ki", ki, strict=False)
        self.inertia = _number(name, "inertia", inertia)
        self.dt = _number(name, "dt", dt)
        if speed is not None and not (isinstance(speed, (int, float)) and math.isfinite(speed)
                                      and speed >= 0):
            raise DownholeInputError(f"{name} speed must be a finite non-negative number of "
                                     f"rad/s, got {speed!r}")
        self.speed = None if speed is None else float(speed)
        self.max_speed = _number(name, "max_speed", max_speed, allow_none=True)
        self.reset()

    def reset(self) -> None:
        self._omega = None
        self._theta = 0.0

    def impedance(self, omega: float) -> complex:
        """The drive's impedance Z_td(i omega) seen by the string, N m s/rad.

        Parameters
        ----------
        omega : float
            Angular frequency, rad/s (positive).

        Returns
        -------
        complex
            :func:`top_drive_impedance` of this drive's gains and inertia.
        """
        return top_drive_impedance(self.kp, self.ki, self.inertia, omega)

    def _set_point(self, reference):
        if self.speed is not None:
            return self.speed
        try:
            sp = float(reference["reference_angular_velocity"])
        except (TypeError, KeyError, ValueError):
            raise DownholeInputError(f"{type(self).__name__} without a speed needs the "
                                     "reference 'reference_angular_velocity'") from None
        if not math.isfinite(sp):
            raise DownholeInputError(f"{type(self).__name__}: reference_angular_velocity "
                                     f"{sp!r} is not finite")
        return sp

    def command(self, t: float, observation: Mapping[str, float],
                reference: Mapping[str, float] | None = None) -> dict:
        """One controller step: the top-drive speed command.

        The rotor is advanced by one ``dt`` under P (omega_sp - omega) + I theta_e minus the
        measured surface torque; the first call starts bumplessly from the observed drive speed.
        The command is clipped to [0, max_speed] with anti-windup.

        Parameters
        ----------
        t : float
            Time, s (unused).
        observation : mapping
            Must hold ``surface_torque`` (N m); ``top_drive_angular_velocity`` (rad/s) is used at
            the first call when present.
        reference : mapping, optional
            ``reference_angular_velocity`` (rad/s), the set-point when ``speed`` was not given.

        Returns
        -------
        dict
            ``{"top_drive_angular_velocity": rad/s}``.

        Raises
        ------
        DownholeInputError
            A non-finite surface torque, or no usable set-point.
        """
        sp = self._set_point(reference)
        torque = float(observation["surface_torque"])
        if not math.isfinite(torque):
            raise DownholeInputError(f"{type(self).__name__}: observation surface_torque = "
                                     f"{torque!r} is not finite")
        if self._omega is None:
            # bumpless start: from the drive's speed, the motor torque balancing the string's
            self._omega = float(observation.get("top_drive_angular_velocity", sp))
            err = sp - self._omega
            self._theta = (torque - self.kp * err) / self.ki if self.ki > 0 else 0.0
        err = sp - self._omega
        motor = self.kp * err + self.ki * self._theta
        omega = self._omega + self.dt * (motor - torque) / self.inertia
        top = self.max_speed if self.max_speed is not None else 2.0 * abs(sp)
        clipped = min(max(omega, 0.0), top)
        # anti-windup: the integral stops while the command sits on a limit pushing outward
        if clipped == omega or (omega > top and err < 0) or (omega < 0 and err > 0):
            self._theta += self.dt * err
        self._omega = clipped
        return {"top_drive_angular_velocity": clipped}


class SoftSpeed(TopDriveSpeedPI):
    """SoftSpeed-tuned soft-torque top-drive speed controller (Kyllingstad and Nessjoen,
    SPE-119660, 2009): P = ``fraction`` Z, I = J w_s^2 (see the module docstring).

    Parameters
    ----------
    system : DrillingSystem, optional
        The described system: Z from the top pipe section, w_s from
        :func:`stick_slip_frequency` (torsional mode ``mode``), J from the rig's top drive.
        Explicit ``impedance``, ``frequency`` and ``inertia`` override it (and are required
        without it).
    speed : float, optional
        Speed set-point, rad/s (default: the reference ``reference_angular_velocity``).
    fraction : float
        a = P / Z (default 1: the wave is absorbed at w_s, r(w_s) = 0; 0.5 gives r = 1/3,
        89 % of the wave's energy absorbed).
    mode : int
        Torsional mode whose frequency (top clamped) is w_s when it comes from ``system``
        (default 1, the first).
    impedance, frequency, inertia : float, optional
        Z (N m s/rad), w_s (rad/s), J (kg m^2).
    max_speed, dt
        As :class:`TopDriveSpeedPI`.

    Examples
    --------
    >>> c = SoftSpeed(impedance=480.0, frequency=1.0, inertia=500.0, speed=5.0, fraction=0.5,
    ...               dt=1e-3)
    >>> c.kp, c.ki
    (240.0, 500.0)
    >>> round(abs(c.reflection(1.0)), 6)  # (1 - a) / (1 + a)
    0.333333
    """

    def __init__(self, system=None, *, speed: float | None = None, fraction: float = 1.0,
                 mode: int = 1, impedance: float | None = None, frequency: float | None = None,
                 inertia: float | None = None, max_speed: float | None = None,
                 dt: float = 1e-3):
        if system is not None:
            from downhole.system import DrillingSystem

            if not isinstance(system, DrillingSystem):
                raise DownholeInputError(f"SoftSpeed system must be a DrillingSystem, got "
                                         f"{type(system).__name__}")
            if impedance is None:
                impedance = float(system.string.segments[0].section.torsional_impedance)
            if inertia is None:
                inertia = float(system.rig.top_drive.inertia)
            if frequency is None:
                frequency = stick_slip_frequency(system, mode)
        missing = [n for n, v in (("impedance", impedance), ("frequency", frequency),
                                  ("inertia", inertia)) if v is None]
        if missing:
            raise DownholeInputError(f"SoftSpeed needs a DrillingSystem or explicit {missing}")
        kp, ki = softspeed_tuning(impedance, frequency, inertia, fraction)
        self.pipe_impedance = float(impedance)
        self.frequency = float(frequency)
        self.fraction = float(fraction)
        super().__init__(kp, ki, inertia, speed=speed, max_speed=max_speed, dt=dt)

    def reflection(self, omega: float | None = None) -> complex:
        """Reflection coefficient of the tuned drive at ``omega`` (default: w_s).

        Parameters
        ----------
        omega : float, optional
            Angular frequency, rad/s (default: the tuned stick-slip frequency w_s).

        Returns
        -------
        complex
            :func:`reflection_coefficient` against the top pipe's impedance.
        """
        return reflection_coefficient(self.pipe_impedance, self.kp, self.ki, self.inertia,
                                      self.frequency if omega is None else omega)

