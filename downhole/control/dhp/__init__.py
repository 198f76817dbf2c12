"""Dual heuristic programming (single-network adaptive critic) controller of seed Ch. 4.

- :mod:`~downhole.control.dhp.trainer`: the trainer for any
  :class:`~downhole.control.affine.ControlAffineModel` - the seed's Algorithm 1 (plain NumPy,
  the reference) and its exact fast form, the Riccati form (compiled,
  :mod:`~downhole.control.dhp.riccati`).
- :mod:`~downhole.control.dhp.drilling`: the lumped drilling design model, the reference
  transform (Eqs. 4.21-4.23), the steady-state feed-forward and the penalty layout (Eq. 4.45).
- :mod:`~downhole.control.dhp.references`: step, ramp (Eqs. 4.48-4.49), sine (Eq. 4.47), user.
- :mod:`~downhole.control.dhp.design`: :func:`design_dhp` puts them together.
- :mod:`~downhole.control.dhp.controller`: :class:`DHPController` (online law, past-horizon
  policy, save/load as npz + JSON).
- :mod:`~downhole.control.dhp.closed_loop`: closed-loop runs returning Results.
- :mod:`~downhole.control.dhp.directional`: the directional FEM/hybrid design model (compiled
  forces) and a plant adapter that reports the design model's full state.
- :mod:`~downhole.control.dhp.plan`: a start-up planned on the design FEM and the DHP gains
  about it (two degrees of freedom, beyond the seed).

Example
-------
>>> from downhole.control.dhp import lumped_affine_model, design_dhp, BitReference
>>> model = lumped_affine_model("table_2_1", dt=1e-3)
>>> ctrl = design_dhp(model, BitReference.step(0.01, 20.0), horizon=2.0)
>>> ctrl.horizon
2.0
"""

from downhole.control.dhp.closed_loop import (
    DisplacementToVelocity,
    lumped_true_plant,
    run_design_model,
    run_on_plant,
)
from downhole.control.dhp.controller import DHPController, load_controller
from downhole.control.dhp.design import build_problem, design_dhp
from downhole.control.dhp.directional import (
    DirectionalStatePlant,
    directional_affine_model,
    table_5_1_models,
)
from downhole.control.dhp.drilling import (
    PenaltyWeights,
    feed_forward,
    lumped_affine_model,
    penalty_matrices,
    reference_states,
    table_4_1_weights,
)
from downhole.control.dhp.plan import (
    PlannedTrajectory,
    PlanSettings,
    design_dhp_planned,
    plan_trajectory,
    planned_controller,
)
from downhole.control.dhp.references import BitReference
from downhole.control.dhp.trainer import (
    METHODS,
    DHPProblem,
    DHPSettings,
    DHPTraining,
    LinearBasis,
    QuadraticBasis,
    TrainingDiverged,
    train_dhp,
)

__all__ = [
    "METHODS",
    "BitReference",
    "DHPController",
    "DHPProblem",
    "DHPSettings",
    "DHPTraining",
    "DirectionalStatePlant",
    "DisplacementToVelocity",
    "LinearBasis",
    "PenaltyWeights",
    "PlanSettings",
    "PlannedTrajectory",
    "QuadraticBasis",
    "TrainingDiverged",
    "build_problem",
    "design_dhp",
    "design_dhp_planned",
    "directional_affine_model",
    "feed_forward",
    "load_controller",
    "lumped_affine_model",
    "lumped_true_plant",
    "penalty_matrices",
    "plan_trajectory",
    "planned_controller",
    "reference_states",
    "run_design_model",
    "run_on_plant",
    "table_4_1_weights",
    "table_5_1_models",
    "train_dhp",
]
