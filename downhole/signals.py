"""The one registry of named signals and metrics, with their SI units and meanings.

Every name a plant observes or is commanded with, every channel a :class:`~downhole.sim.Result`
records and every metric a summary or sweep reports is declared here once: its SI unit (a pint
string), the physical dimension (a key of :data:`downhole.units.SI_UNITS`), a description and, for
signals that can be commanded, the admissible range a command must lie in. Results, the SIL
layout, LAS export, sweeps and plants read units from here instead of keeping tables of their own.

A model or controller that records a signal of its own registers it with :func:`register_signal`
(idempotent for an identical declaration; a conflicting one raises).

Examples
--------
>>> from downhole.signals import signal, unit_of
>>> signal("wob").unit
'N'
>>> unit_of("surface_torque")
'N*m'
>>> unit_of("not_a_signal", default="")
''
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = [
    "METRICS",
    "SIGNALS",
    "STANDARD_CHANNELS",
    "Metric",
    "Signal",
    "check_command_value",
    "metric_unit",
    "range_reason",
    "register_signal",
    "signal",
    "unit_of",
]


@dataclass(frozen=True)
class Signal:
    """A named scalar signal.

    Attributes
    ----------
    name : str
        Snake-case name used everywhere (Result channel, SIL layout, observation key).
    unit : str
        SI unit as a pint string (``""`` for dimensionless).
    dimension : str
        Physical dimension, a key of :data:`downhole.units.SI_UNITS`.
    description : str
        One line, with the sign convention where it matters.
    low, high : float
        Admissible range of the signal as a *command* (values outside are refused, never
        applied); infinite for signals that are never commanded. The bounds are finite and
        physically sane for a drilling rig (they catch a wrong unit, a corrupted or hostile
        packet, an absurd set-point), not the rig's operating envelope. The bit velocities
        have ranges because a hardware-in-the-loop rig sends them as commands.
    """

    name: str
    unit: str
    dimension: str
    description: str
    low: float = -math.inf
    high: float = math.inf

    def admits(self, value: float) -> bool:
        """True when ``value`` is finite and inside ``[low, high]``.

        Parameters
        ----------
        value : float
            Candidate command value, in the signal's SI unit (:attr:`unit`).

        Returns
        -------
        bool
        """
        return math.isfinite(value) and self.low <= value <= self.high


@dataclass(frozen=True)
class Metric:
    """A scalar summary of a run (see :func:`downhole.analysis.metrics.summarize`).

    Attributes
    ----------
    name : str
        Snake-case metric name.
    unit : str
        SI unit as a pint string (``"-"`` for ratios).
    description : str
        One line.
    """

    name: str
    unit: str
    description: str


SIGNALS: dict[str, Signal] = {}
METRICS: dict[str, Metric] = {}


def register_signal(name: str, unit: str, dimension: str, description: str, *,
                    low: float = -math.inf, high: float = math.inf) -> Signal:
    """Declare a signal; returns it. Re-declaring the same signal identically is a no-op.

    Parameters
    ----------
    name : str
        Snake-case signal name.
    unit : str
        SI unit as a pint string (``""`` for dimensionless).
    dimension : str
        Physical dimension, a key of :data:`downhole.units.SI_UNITS`.
    description : str
        One line, with the sign convention where it matters.
    low, high : float, optional
        Admissible range as a command, in ``unit`` (default unbounded).

    Returns
    -------
    Signal
        The declared signal (also stored in :data:`SIGNALS`).

    Raises
    ------
    ValueError
        When ``name`` is already declared differently, or ``low > high``.
    """
    if not low <= high:
        raise ValueError(f"signal {name!r}: admissible range low={low} > high={high}")
    sig = Signal(name, unit, dimension, description, float(low), float(high))
    old = SIGNALS.get(name)
    if old is not None and old != sig:
        raise ValueError(f"signal {name!r} is already declared as {old}; not redeclaring it "
                         f"as {sig}")
    SIGNALS[name] = sig
    return sig


def signal(name: str) -> Signal:
    """The declared signal ``name``.

    Parameters
    ----------
    name : str
        Signal name.

    Returns
    -------
    Signal

    Raises
    ------
    KeyError
        With the known names, when ``name`` is not declared.
    """
    try:
        return SIGNALS[name]
    except KeyError:
        raise KeyError(f"unknown signal {name!r}; declared signals: "
                       f"{', '.join(sorted(SIGNALS))}") from None


def unit_of(name: str, default: str | None = None) -> str:
    """SI unit of signal ``name``; ``default`` when undeclared.

    Parameters
    ----------
    name : str
        Signal name.
    default : str, optional
        Unit returned for an undeclared name; None (default) makes an undeclared name an error.

    Returns
    -------
    str
        Pint unit string (``""`` for dimensionless).

    Raises
    ------
    KeyError
        If ``name`` is not declared and ``default`` is None.
    """
    sig = SIGNALS.get(name)
    if sig is None:
        if default is None:
            signal(name)
        return default
    return sig.unit


def metric_unit(name: str, default: str = "") -> str:
    """SI unit of metric ``name`` (``"-"`` for ratios), ``default`` when undeclared.

    Parameters
    ----------
    name : str
        Metric name (:data:`METRICS`).
    default : str, optional
        Unit returned for an undeclared name (default ``""``).

    Returns
    -------
    str
    """
    m = METRICS.get(name)
    return m.unit if m is not None else default


def range_reason(name: str, value, low: float, high: float, unit: str = "") -> str | None:
    """Why ``value`` is not a finite number in ``[low, high]`` (None when it is).

    The one check behind every command and set-point range in plants, the SIL runtime and the
    UDP link.

    Parameters
    ----------
    name : str
        Name of the value, used in the message.
    value : object
        The value to check (anything ``float()`` accepts).
    low, high : float
        Admissible range, inclusive, in ``unit``.
    unit : str, optional
        Unit printed in the message (default none).

    Returns
    -------
    str or None
        A one-line reason, or None when the value is admissible.
    """
    try:
        v = float(value)
    except (TypeError, ValueError):
        return f"{name}: expected a number, got {value!r}"
    if not math.isfinite(v):
        return f"{name}: {v} is not a finite number"
    if not low <= v <= high:
        u = f" {unit}" if unit else ""
        return f"{name}: {v:g}{u} is outside the admissible range [{low:g}, {high:g}]{u}"
    return None


def check_command_value(name: str, value: float) -> str | None:
    """Why ``value`` may not be applied as command ``name`` (None when it may).

    Non-finite values are never admissible; declared signals must lie in their range.

    Parameters
    ----------
    name : str
        Command (signal) name.
    value : float
        Command value, in the signal's SI unit.

    Returns
    -------
    str or None
        A one-line reason, or None when the value may be applied.
    """
    sig = SIGNALS.get(name)
    if sig is None:
        return range_reason(name, value, -math.inf, math.inf)
    return range_reason(name, value, sig.low, sig.high, sig.unit)


def _declare_standard() -> None:
    s = register_signal
    # --- bit ---
    s("time", "s", "time", "simulated time")
    s("bit_axial_position", "m", "length", "bit axial displacement from the start, positive "
      "downward")
    s("bit_axial_velocity", "m/s", "velocity", "bit axial velocity, positive into the rock",
      low=-1.0, high=1.0)
    s("bit_angle", "rad", "angle", "bit rotation angle")
    s("bit_angular_velocity", "rad/s", "angular_velocity", "bit angular velocity",
      low=-100.0, high=100.0)
    s("depth_of_cut", "m", "length", "total depth of cut per revolution (all blades)")
    s("wob", "N", "force", "weight on bit")
    s("tob", "N*m", "torque", "torque on bit")
    # --- surface (rig) ---
    s("hook_load", "N", "force", "hook load (string weight minus slack-off)", low=0.0,
      high=1.0e7)
    s("surface_torque", "N*m", "torque", "torque delivered by the top drive to the string",
      low=-2.0e5, high=2.0e5)
    s("top_drive_axial_velocity", "m/s", "velocity", "top drive axial velocity, positive "
      "downward", low=-1.0, high=1.0)
    s("top_drive_angular_velocity", "rad/s", "angular_velocity", "top drive angular velocity",
      low=-100.0, high=100.0)
    s("top_drive_angle", "rad", "angle", "top drive rotation angle")
    s("top_drive_set_point", "rad/s", "angular_velocity", "top drive speed set-point of its "
      "drive controller", low=-100.0, high=100.0)
    s("slack_off_force", "N", "force", "hook force taken off the string (slack-off), "
      "positive lowers the string", low=-1.0e7, high=1.0e7)
    # --- references ---
    s("reference_axial_velocity", "m/s", "velocity", "reference bit axial velocity (ROP)",
      low=-1.0, high=1.0)
    s("reference_angular_velocity", "rad/s", "angular_velocity",
      "reference bit angular velocity", low=-100.0, high=100.0)
    s("reference_wob", "N", "force", "weight-on-bit set-point (auto-driller)", low=0.0,
      high=2.0e6)
    # --- velocity commands of the velocity-driven (lumped, neutral) models ---
    s("command_axial", "m/s", "velocity", "commanded top axial velocity", low=-5.0, high=5.0)
    s("command_angular", "rad/s", "angular_velocity", "commanded top angular velocity",
      low=-100.0, high=100.0)
    # --- measurements and observers ---
    s("measured_axial_velocity", "m/s", "velocity", "measured bit axial velocity (with noise)")
    s("measured_angular_velocity", "rad/s", "angular_velocity",
      "measured bit angular velocity (with noise)")
    s("eid_disturbance_axial", "m/s", "velocity", "EID estimate of the equivalent axial "
      "input disturbance")
    s("eid_disturbance_angular", "rad/s", "angular_velocity", "EID estimate of the equivalent "
      "angular input disturbance")
    s("eid_prediction_axial", "m/s", "velocity", "EID predictor output, axial")
    s("eid_prediction_angular", "rad/s", "angular_velocity", "EID predictor output, angular")
    # --- directional models: the wave segment's ends and the last FEM node ---
    s("force_b", "N", "force", "axial force at node B (top of the wave segment)")
    s("torque_b", "N*m", "torque", "torque at node B (top of the wave segment)")
    s("force_c", "N", "force", "axial force at node C (bottom of the wave segment)")
    s("torque_c", "N*m", "torque", "torque at node C (bottom of the wave segment)")
    s("last_node_axial_velocity", "m/s", "velocity", "axial velocity of the last string node")
    s("last_node_angular_velocity", "rad/s", "angular_velocity",
      "angular velocity of the last string node")
    s("node_axial_velocity", "m/s", "velocity", "axial velocity of every string node")
    s("node_angular_velocity", "rad/s", "angular_velocity",
      "angular velocity of every string node")

    m = lambda name, unit, desc: METRICS.__setitem__(name, Metric(name, unit, desc))
    m("stick_slip_severity", "-", "(max - min) / (2 mean) of the bit angular velocity")
    m("stuck_fraction", "-", "fraction of samples with |bit angular velocity| < 0.1 rad/s")
    m("bit_bounce_fraction", "-", "fraction of samples with WOB <= 0 or depth of cut <= 0")
    m("mean_rop", "m/s", "mean bit axial velocity (rate of penetration)")
    m("mean_bit_angular_velocity", "rad/s", "mean bit angular velocity")
    m("mse", "Pa", "mechanical specific energy at the bit (Teale)")
    m("tracking_rms_axial", "m/s", "RMS error of bit axial velocity to the reference")
    m("tracking_rms_angular", "rad/s", "RMS error of bit angular velocity to the reference")
    m("mean_wob", "N", "mean weight on bit")
    m("max_wob", "N", "maximum weight on bit")
    m("mean_tob", "N*m", "mean torque on bit")
    m("max_tob", "N*m", "maximum torque on bit")
    m("mean_hook_load", "N", "mean hook load")
    m("mean_surface_torque", "N*m", "mean surface torque")
    m("max_surface_torque", "N*m", "maximum surface torque")
    m("min_bit_angular_velocity", "rad/s", "minimum bit angular velocity")
    m("max_bit_angular_velocity", "rad/s", "maximum bit angular velocity")


_declare_standard()

#: The channels every simulation Result carries (the rest depend on the model).
STANDARD_CHANNELS = (
    "bit_axial_position", "bit_axial_velocity", "bit_angle", "bit_angular_velocity",
    "depth_of_cut", "wob", "tob", "hook_load", "surface_torque", "top_drive_axial_velocity",
    "top_drive_angular_velocity",
)
