"""Equivalent-input-disturbance (EID) control of the neutral-type drill string (seed Ch. 3):
LMI synthesis, the controller (observer, estimator, filter, internal model, predictor),
references and closed-loop stability analysis; over the drilling envelope, a schedule of designs
by the regenerative bit/rock margin (:class:`EIDSchedule`, which takes its candidate tunings as an
argument) and the EID with the predictive bit damper (:class:`PredictiveEID`: options
``angle_doc``, ``axial_filter``, ``depth_of_cut_gain``); :mod:`downhole.control.eid.schedule`,
:mod:`downhole.control.eid.predictor`."""

from downhole.control.eid.controller import EIDController, design_eid, load_eid
from downhole.control.eid.design import ChannelGains, LMIInfeasible, LMIReport
from downhole.control.eid.predictor import PredictiveEID, predictive_closed_loop
from downhole.control.eid.references import (
    Reference,
    constant_reference,
    envelope_tracking_reference,
    rotate_then_drill,
    seed_tracking_reference,
    startup_reference,
    user_reference,
)
from downhole.control.eid.schedule import EIDSchedule, closed_loop_margin, operating_point

__all__ = [
    "ChannelGains",
    "EIDController",
    "EIDSchedule",
    "LMIInfeasible",
    "LMIReport",
    "PredictiveEID",
    "Reference",
    "closed_loop_margin",
    "constant_reference",
    "design_eid",
    "envelope_tracking_reference",
    "load_eid",
    "operating_point",
    "predictive_closed_loop",
    "rotate_then_drill",
    "seed_tracking_reference",
    "startup_reference",
    "user_reference",
]
