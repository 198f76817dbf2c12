"""Dynamic-programming optimizers of the Ch. 2 drilling problem: standard, customized, robust.

Define a :class:`DPProblem` (Eqs. 2.12-2.14; or load one from TOML with :func:`load_problem`),
solve it with :func:`solve_customized` (partial inversion, Eqs. 2.15-2.24), :func:`solve_standard`
(forward projection with interpolation, the baseline) or :func:`solve_robust` (ensemble of
perturbed-epsilon models, Eq. 2.25), save/load the :class:`DPSolution` (npz + JSON) and replay it
on the discrete, continuous, 4th- and 12th-order models (:mod:`downhole.control.dp.replay`).
"""

from downhole.control.dp.baseline import best_constant_velocities, constant_velocity_cost
from downhole.control.dp.customized import solve_customized
from downhole.control.dp.problem import (
    BoundSpec,
    DPProblem,
    GridSpec,
    RobustSpec,
    StandardSpec,
    TargetSpec,
    WeightSpec,
    load_problem,
    problem_from_dict,
)
from downhole.control.dp.replay import (
    ensemble_costs,
    replay_discrete,
    replay_epsilon,
    replay_lumped,
    replay_path,
)
from downhole.control.dp.robust import solve_robust
from downhole.control.dp.solution import DPSolution, load_solution, trajectory_cost
from downhole.control.dp.standard import solve_standard

__all__ = [
    "METHODS",
    "BoundSpec",
    "DPProblem",
    "DPSolution",
    "GridSpec",
    "RobustSpec",
    "StandardSpec",
    "TargetSpec",
    "WeightSpec",
    "best_constant_velocities",
    "constant_velocity_cost",
    "ensemble_costs",
    "load_problem",
    "load_solution",
    "problem_from_dict",
    "replay_discrete",
    "replay_epsilon",
    "replay_lumped",
    "replay_path",
    "solve",
    "solve_customized",
    "solve_robust",
    "solve_standard",
    "trajectory_cost",
]

METHODS = ("customized", "standard", "robust")


def solve(problem: DPProblem, method: str = "customized", *, progress: bool = False,
          **kwargs) -> DPSolution:
    """Solve ``problem`` with ``method`` in :data:`METHODS` (keyword args go to the solver)."""
    from downhole.errors import DownholeInputError

    if method == "customized":
        return solve_customized(problem, progress=progress, **kwargs)
    if method == "standard":
        return solve_standard(problem, progress=progress, **kwargs)
    if method == "robust":
        return solve_robust(problem, progress=progress, **kwargs)
    raise DownholeInputError(f"method must be one of {', '.join(METHODS)}, got {method!r}")
