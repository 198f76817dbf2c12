"""Equivalent-input-disturbance (EID) control of the neutral-type drill string (seed Ch. 3):
LMI synthesis, the controller (observer, estimator, filter, internal model, predictor),
references and closed-loop stability analysis; over the drilling envelope, the schedule of
designs by the regenerative bit/rock margin and the predictive bit damper
(:mod:`downhole.control.eid.envelope`, :mod:`downhole.control.eid.predictor`)."""

from downhole.control.eid.controller import EIDController, design_eid, load_eid
from downhole.control.eid.design import ChannelGains, LMIInfeasible, LMIReport
from downhole.control.eid.envelope import EIDSchedule, operating_point, settle_metrics
from downhole.control.eid.predictor import PredictiveEID
from downhole.control.eid.references import (
                                             Reference,
                                             constant_reference,
                                             envelope_tracking_reference,
                                             rotate_then_drill,
                                             seed_tracking_reference,
                                             startup_reference,
                                             user_reference,
)

__all__ = [
                                             "ChannelGains",
                                             "EIDController",
                                             "EIDSchedule",
                                             "LMIInfeasible",
                                             "LMIReport",
                                             "PredictiveEID",
                                             "Reference",
                                             "constant_reference",
                                             "design_eid",
                                             "envelope_tracking_reference",
                                             "load_eid",
                                             "operating_point",
                                             "rotate_then_drill",
                                             "seed_tracking_reference",
                                             "settle_metrics",
                                             "startup_reference",
                                             "user_reference",
]
