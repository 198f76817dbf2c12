"""Closed-loop references for the EID controller. They are plant-side signals defined in the
mechanics core (:mod:`downhole.sim.references`, which the neutral-model runner samples); this
module re-exports them under the controller's namespace."""

from downhole.sim.references import (Reference, as_reference, constant_reference, eq_3_34,
                                     eq_3_35, seed_tracking_reference, user_reference)

__all__ = ["Reference", "constant_reference", "seed_tracking_reference", "user_reference",
           "as_reference", "eq_3_34", "eq_3_35"]
