"""Controllers and optimizers: PI top drive, dynamic programming, EID + LMI, DHP (SNAC), and the
industry's baselines written against the controller contract (:mod:`downhole.control.base`):
Z-torque, SoftSpeed-tuned soft torque, the stiff top-drive PI and an auto-driller.

:data:`BASELINES` maps the registry names of the contract baselines (``ztorque``, ``softspeed``,
``stiff_pi``, ``autodriller``) to their classes; each takes the
:class:`~downhole.system.DrillingSystem` (or explicit parameters) and keyword set-points, see
``docs/controllers.md``.
"""

from downhole.control.autodriller import AutoDriller, autodriller_gains
from downhole.control.base import Controller, check_pair, run_closed_loop
from downhole.control.softspeed import (
    SoftSpeed,
    TopDriveSpeedPI,
    reflection_coefficient,
    softspeed_tuning,
    stick_slip_frequency,
    top_drive_impedance,
)
from downhole.control.ztorque import ZTorque, torsional_impedance

#: Registry names of the contract baselines -> classes (for ``[controller] type`` names).
BASELINES = {"ztorque": ZTorque, "softspeed": SoftSpeed, "stiff_pi": TopDriveSpeedPI,
             "autodriller": AutoDriller}

__all__ = [
    "BASELINES",
    "AutoDriller",
    "Controller",
    "SoftSpeed",
    "TopDriveSpeedPI",
    "ZTorque",
    "autodriller_gains",
    "check_pair",
    "reflection_coefficient",
    "run_closed_loop",
    "softspeed_tuning",
    "stick_slip_frequency",
    "top_drive_impedance",
    "torsional_impedance",
]
