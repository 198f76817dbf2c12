"""Standard DP baseline: grid the states and the inputs, project forward, interpolate J_{k+1}.

The inputs are gridded as string force and torque levels within the bounds (u1 = x1 + F/K_a,
u2 = x3 + T/K_t, held over each DP step as in Eq. 2.12). Each projection integrates the 4th-order
model over the step with small substeps (the forward model cannot take the DP step in one go,
seed Sec. 2.3.2); J_{k+1} is interpolated bilinearly over the (x2, x4) grid (x1 and x3 do not
change the cost, so gridding them would only multiply the work). The optimal inputs are then
extracted by rolling the policy forward from rest on the same model, and the reported cost is
the cost of that rollout (the interpolated estimate is kept in ``info["cost_estimate"]``).
"""

from __future__ import annotations

import time

import numpy as np

from downhole.control.dp._progress import chunks, progress_bar
from downhole.control.dp.customized import stage_vector
from downhole.control.dp.kernels import project_table, standard_backward, standard_choose
from downhole.control.dp.problem import DPProblem
from downhole.control.dp.solution import DPSolution, trajectory_cost
from downhole.errors import DownholeInputError

__all__ = ["input_levels", "solve_standard"]


def input_levels(problem: DPProblem) -> tuple[np.ndarray, np.ndarray]:
    """The input grid: string force levels (N) and torque levels (N m) spanning the bounds."""
    s, b = problem.standard, problem.bounds
    return (np.linspace(b.force[0], b.force[1], s.force_levels),
            np.linspace(b.torque[0], b.torque[1], s.torque_levels))


def solve_standard(problem: DPProblem, *, progress: bool = False) -> DPSolution:
    """Solve the problem with the standard (forward-projection, interpolating) DP.

    Parameters
    ----------
    problem : DPProblem
        The validated problem (``problem.standard`` sets the input grid and substep).
    progress : bool
        Show a rich progress bar.

    Returns
    -------
    DPSolution
        Off-grid path (``path_i2 = -1``) of the policy rolled out from rest; ``cost`` is the
        rollout's Eq. 2.13 cost.
    """
    t0 = time.perf_counter()
    g2, g4 = problem.grid2(), problem.grid4()
    a = problem.arrays()
    lumped, p = a.lumped(), a.bit
    fl, tl = input_levels(problem)
    dt, n_steps = problem.step, problem.steps
    nsub = int(np.ceil(dt / problem.standard.substep - 1e-9))
    bounds = np.array([*problem.bounds.force, *problem.bounds.torque], dtype=float)
    x2p, x4p, adm = project_table(g2, g4, fl, tl, lumped, p, dt, nsub, bounds)
    stage, term = stage_vector(problem)
    J = np.empty((n_steps + 1, stage.size))
    J[n_steps] = term
    with progress_bar(n_steps, "standard DP", progress) as advance:
        for hi, lo in chunks(n_steps):
            standard_backward(x2p, x4p, adm, stage, J, g2, g4, hi, lo)
            advance(hi - lo)
    idx = problem.target_indices()
    start = idx["x2_0"] * g4.size + idx["x4_0"]
    estimate = float(J[0, start])
    if not np.isfinite(estimate):
        raise DownholeInputError("standard DP: no admissible input sequence from rest stays on "
                                 "the grid within the bounds; widen the grid or the bounds")
    # roll the policy forward from rest on the same (substepped) model
    x1 = np.zeros(n_steps + 1)
    x2 = np.zeros(n_steps + 1)
    x3 = np.zeros(n_steps + 1)
    x4 = np.zeros(n_steps + 1)
    force = np.empty(n_steps)
    torque = np.empty(n_steps)
    for k in range(n_steps):
        q, v, w, d1, d3 = standard_choose(x2[k], x4[k], J[k + 1], fl, tl, g2, g4, lumped, p, dt,
                                          nsub, bounds)
        if q < 0:
            raise DownholeInputError(f"standard DP rollout left the grid at step {k} "
                                     f"(x2={x2[k]:.4g} m/s, x4={x4[k]:.4g} rad/s)")
        force[k], torque[k] = fl[q // tl.size], tl[q % tl.size]
        x2[k + 1], x4[k + 1] = v, w
        x1[k + 1], x3[k + 1] = x1[k] + d1, x3[k] + d3
    cost = trajectory_cost(problem, x2, x4)
    info = {"seconds": time.perf_counter() - t0, "cost_estimate": estimate,
            "projections": int(adm.size), "admissible_projections": int(adm.sum()),
            "substeps": nsub, "grid": [problem.x2.points, problem.x4.points],
            "input_grid": [fl.size, tl.size], "step": dt, "horizon": problem.horizon}
    minus = -np.ones(n_steps + 1, dtype=np.int64)
    return DPSolution(method="standard", problem=problem, times=problem.times, x1=x1, x2=x2,
                      x3=x3, x4=x4, u1=x1[:-1] + force / a.ka, u2=x3[:-1] + torque / a.kt,
                      force=force, torque=torque, cost=cost, grid2=g2, grid4=g4, path_i2=minus,
                      path_i4=minus.copy(), info=info)
