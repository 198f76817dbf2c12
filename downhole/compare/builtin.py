"""The benchmark's registry of built-in controllers: name -> ``factory(system, case)``.

Each :class:`Entry` builds the controller for one case from the case's
:class:`~downhole.system.DrillingSystem` and :class:`~downhole.compare.suite.Case`. An entry may
declare up front the signals its controller reads (``needs``) and the commands it sets
(``commands``): the benchmark then checks the pair with
:func:`~downhole.control.base.check_pair` before building anything, so a cell whose plant cannot
provide a signal is marked ``n/a`` with check_pair's reason without paying for a design. A
factory that finds the controller cannot be built for a system raises :class:`NotApplicable`.

Adding a controller is one line::

    register("softspeed", lambda system, case: SoftSpeed(...), "SoftSpeed-tuned soft torque")

The industrial baselines of :mod:`downhole.control` (``SoftSpeed``, ``AutoDriller``) are
registered here like the others.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from downhole.compare.runner import SetPoint
from downhole.control.ztorque import ZTorque

__all__ = ["BUILTIN", "Entry", "NotApplicable", "declared_stand_in", "register"]


class NotApplicable(Exception):
    """A controller cannot be built for a case; the message says why (the cell is ``n/a``)."""


@dataclass(frozen=True)
class Entry:
    """A built-in controller.

    Attributes
    ----------
    name : str
    factory : callable
        ``factory(system, case) -> controller`` (the Controller contract).
    description : str
        One line for the report (what it is, what it reads).
    needs, commands : tuple of str, optional
        Declared before building (see the module docstring).
    class_name : str
        Named in check_pair's reasons for the declared check.
    cache_key : callable, optional
        ``cache_key(case)``: cases with the same key share one built controller (an expensive
        design that depends only on the system, e.g. EID's LMIs).
    """

    name: str
    factory: Callable
    description: str = ""
    needs: tuple | None = None
    commands: tuple | None = None
    class_name: str = ""
    cache_key: Callable | None = None


#: Name -> Entry, in registration order.
BUILTIN: dict[str, Entry] = {}


def register(name: str, factory: Callable, description: str = "", *, needs=None,
             commands=None, class_name: str = "", cache_key=None) -> Entry:
    """Add (or replace) the built-in controller ``name``; returns its :class:`Entry`."""
    entry = Entry(name, factory, description, None if needs is None else tuple(needs),
                  None if commands is None else tuple(commands), class_name or name,
                  cache_key)
    BUILTIN[name] = entry
    return entry


def declared_stand_in(entry: Entry):
    """An object declaring ``entry``'s needs and commands, named like its controller, for
    :func:`~downhole.control.base.check_pair` (None when the entry declares nothing)."""
    if entry.needs is None and entry.commands is None:
        return None
    cls = type(entry.class_name, (), {"needs": entry.needs or (), "commands": entry.commands or ()})
    return cls()


# ---------------------------------------------------------------------------------- factories
def _top_impedance(system) -> float:
    return float(system.string.segments[0].section.torsional_impedance)


def _stiff_pi(system, case):
    cmds = ("top_drive_angular_velocity",) + (("top_drive_axial_velocity",)
                                              if case.hook == "velocity" else ())
    return SetPoint(cmds)


def _soft_torque(system, case):
    td = system.rig.top_drive
    # the rig's soft-torque law through the contract: the speed command yields to the
    # high-passed surface torque, w = w_sp - soft_gain (T - lowpass_tau(T)): Z-torque's law
    # with Z = 1 / soft_gain and tau = soft_tau
    return ZTorque(1.0 / td.soft_gain, tau=td.soft_tau, dt=case.dt)


def _z_torque(system, case):
    return ZTorque(_top_impedance(system), dt=case.dt)


def _eid(system, case):
    from downhole.control.eid import LMIInfeasible, design_eid
    from downhole.errors import DownholeInputError

    try:
        model = system.build("neutral")
    except DownholeInputError as exc:
        raise NotApplicable(f"EID is designed on the neutral-type model, which this system "
                            f"does not have: {exc}") from None
    try:
        ctrl = design_eid(model)
    except LMIInfeasible as exc:
        raise NotApplicable(f"EID design: {exc}") from None
    ctrl.dt = case.dt
    return ctrl


def _dhp(system, case):
    raise NotApplicable("the built-in DHP has no trained controller for this system: train one "
                        "(downhole design dhp) and score it with --controller FILE.json")


register("stiff-pi", _stiff_pi, "the rig's stiff top-drive PI (Kp 1e4 N m s/rad, Ki 2e3 N m/rad) "
         "with the set-points held; reads nothing", needs=(),
         commands=("top_drive_angular_velocity",), class_name="SetPoint")
register("soft-torque", _soft_torque, "the rig's soft-torque law (speed set-point lowered by "
         "5e-4 rad/s per N m of surface torque high-passed at 2 s); reads surface torque",
         needs=("surface_torque",), commands=("top_drive_angular_velocity",),
         class_name="ZTorque")
register("z-torque", _z_torque, "Z-torque: speed yields to surface torque by the top pipe's "
         "torsional impedance, mean torque low-passed at 10 s; reads surface torque",
         needs=("surface_torque",), commands=("top_drive_angular_velocity",),
         class_name="ZTorque")
register("eid", _eid, "EID (Ch. 3) designed on the system's neutral-type model; reads the bit "
         "velocities, sets block velocity and speed",
         needs=("bit_axial_velocity", "bit_angular_velocity"),
         commands=("top_drive_axial_velocity", "top_drive_angular_velocity"),
         class_name="EIDController", cache_key=lambda case: (case.system, case.epsilon_scale))
register("dhp", _dhp, "DHP (Ch. 4): full design-model state feedback, sets slack-off force and "
         "surface torque", needs=("state",), commands=("slack_off_force", "surface_torque"),
         class_name="DHPController")


# ------------------------------------------------------------------ industrial baselines
def _softspeed(system, case):
    from downhole.control import SoftSpeed

    return SoftSpeed(system, speed=case.speed, dt=case.dt)


def _autodriller(system, case):
    from downhole.control import AutoDriller

    if case.wob is None:
        raise NotApplicable("the auto-driller holds a WOB set-point; this case gives none")
    return AutoDriller(system, wob=case.wob, dt=case.dt)


register("softspeed", _softspeed, "SoftSpeed-tuned soft torque (Kyllingstad & Nessjoen, "
         "SPE-119660): PI speed control with P = the top pipe's torsional impedance and I "
         "placing the drive's resonance at the first torsional frequency",
         class_name="SoftSpeed")
register("autodriller", _autodriller, "auto-driller: holds the case's WOB by the block "
         "velocity from the hook load (rotation at the top drive's set-point)",
         class_name="AutoDriller")
