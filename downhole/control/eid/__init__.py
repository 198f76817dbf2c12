"""Equivalent-input-disturbance (EID) control of the neutral-type drill string (seed Ch. 3):
LMI synthesis, the controller (observer, estimator, filter, internal model, predictor),
references and closed-loop stability analysis."""

from downhole.control.eid.controller import EIDController, design_eid, load_eid
from downhole.control.eid.design import ChannelGains, LMIInfeasible, LMIReport
from downhole.control.eid.references import (Reference, constant_reference,
                                             seed_tracking_reference, user_reference)

__all__ = ["EIDController", "design_eid", "load_eid", "ChannelGains", "LMIInfeasible",
           "LMIReport", "Reference", "constant_reference", "seed_tracking_reference",
           "user_reference"]
