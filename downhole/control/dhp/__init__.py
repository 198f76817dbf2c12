"""Dual heuristic programming (single-network adaptive critic) controller of seed Ch. 4.

- :mod:`~downhole.control.dhp.trainer`: the trainer (Algorithm 1 compiled and in NumPy, the
  closed-form per-sample target and the Riccati form) for any :class:`ControlAffineModel`.
"""

from downhole.control.dhp.trainer import (METHODS, DHPProblem, DHPSettings, DHPTraining,
                                          LinearBasis, QuadraticBasis, TrainingDiverged,
                                          finite_horizon_lqr, train_dhp)

__all__ = ["METHODS", "DHPProblem", "DHPSettings", "DHPTraining", "LinearBasis",
           "QuadraticBasis", "TrainingDiverged", "finite_horizon_lqr", "train_dhp"]
