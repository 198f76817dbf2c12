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

from downhole.compare.observed import DHP_SIGNALS
from downhole.compare.runner import NotApplicable, SetPoint
from downhole.control.ztorque import ZTorque

__all__ = ["BUILTIN", "Entry", "NotApplicable", "declared_stand_in", "register"]


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


_EID_DESIGNS: dict = {}


def _eid_design_model(system):
    """The neutral-type model (Eq. 3.13) EID is designed on, and a note when it leaves out the
    wall friction (the neutral model cannot represent wall contact: the design takes the
    string without it; the plant keeps it)."""
    from dataclasses import replace

    from downhole.errors import DownholeInputError

    try:
        return system.build("neutral"), ""
    except DownholeInputError as exc:
        if "wall contact" not in str(exc):
            raise NotApplicable(f"EID is designed on the neutral-type model, which this "
                                f"system does not have: {exc}") from None
    try:
        return replace(system, friction=0.0).build("neutral"), "designed without wall friction"
    except DownholeInputError as exc:
        raise NotApplicable(f"EID is designed on the neutral-type model, which this system "
                            f"does not have: {exc}") from None


def _eid(system, case):
    import copy

    from downhole.control.eid import LMIInfeasible, design_eid

    if case.hook == "force" and case.delay > 0:
        raise NotApplicable(EID_DELAYED_SERVO)
    key = (case.system, case.epsilon_scale)
    if key not in _EID_DESIGNS:
        model, _ = _eid_design_model(system)
        try:
            _EID_DESIGNS[key] = design_eid(model)
        except LMIInfeasible as exc:
            raise NotApplicable(f"EID design: {exc}") from None
    ctrl = copy.deepcopy(_EID_DESIGNS[key])
    ctrl.dt = case.dt
    if case.hook == "velocity":
        return ctrl
    from downhole.compare.observed import VelocityServo

    hk = system.rig.hook
    weight = system.build("fem", n_elements=case.n_elements).buoyed_weight
    return VelocityServo(ctrl, hook_load0=weight - case.wob, stiffness=hk.servo_stiffness,
                         damping=hk.servo_damping, dt=case.dt)


#: Why EID is n/a on a force-hook case with an actuator delay.
EID_DELAYED_SERVO = ("EID sets the block velocity and this case's hook takes a hook load: the "
                     "block-velocity servo EID is designed for (damping 1e6 N s/m on the top "
                     "node) would run through the case's actuator delay, which makes it "
                     "unstable (smoke case: the hook load leaves its range 0.2 s after the "
                     "hand-over)")


def _dhp(system, case):
    from downhole.compare.observed import builtin_dhp

    return builtin_dhp(system, case)


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
register("eid", _eid, "EID (Ch. 3) designed on the system's neutral-type model (without the "
         "wall friction where the well has contact); reads the bit velocities, sets block "
         "velocity (on a force hook through the rig's block-velocity servo in software) and "
         "speed", needs=("bit_axial_velocity", "bit_angular_velocity"),
         class_name="EIDController")
register("dhp", _dhp, "DHP (Ch. 4) trained on the coarse FEM of the case's string for a step "
         "to the case's reference, its state estimated from the surface (top-drive velocities "
         "and angle, block velocity); its slack-off force and surface torque set through the "
         "rig's hook and speed PI", needs=DHP_SIGNALS, class_name="DHPController")


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
