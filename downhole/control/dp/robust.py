"""Robust DP (seed Eq. 2.25): minimize the cost averaged over models with perturbed epsilon.

The nominal model's path over the (x2, x4) grid defines the top inputs (path inversion); every
ensemble model is driven by those same inputs from the same rest start, so the search must run
forward: each node keeps the ensemble states of the best path reaching it and the perturbed
models are integrated accurately (linearly implicit Euler substeps) along every candidate step.
With a single nominal model the forward search is exact and equals the customized DP's optimum.
"""

from __future__ import annotations

import time

import numpy as np

from downhole.control.dp._progress import progress_bar
from downhole.control.dp.customized import check_reachable, path_solution, transitions
from downhole.control.dp.kernels import (
    path_load_table,
    robust_forward_step,
    robust_forward_step_parallel,
)
from downhole.control.dp.problem import DPProblem
from downhole.control.dp.solution import DPSolution
from downhole.errors import DownholeInputError

__all__ = ["solve_robust"]

#: Largest precomputed table of nominal path loads (transitions x substeps x 2 floats), bytes.
_TABLE_BYTES = 256 * 2**20


def solve_robust(problem: DPProblem, *, epsilon_scales=None, progress: bool = False,
                 parallel: bool = False) -> DPSolution:
    """Solve the robust DP over the epsilon ensemble ``problem.robust.epsilon_scales``.

    Parameters
    ----------
    problem : DPProblem
        The validated problem; ``problem.robust`` sets the ensemble and the substep.
    epsilon_scales : sequence of float, optional
        Override of the ensemble (factors multiplying epsilon; 1.0 is the nominal model).
    progress : bool
        Show a rich progress bar.
    parallel : bool
        Spread the nodes of each step over threads (numba ``prange``); same result.

    Returns
    -------
    DPSolution
        ``cost`` is the ensemble-mean cost of Eq. 2.25 of the chosen path;
        ``info["ensemble_costs"]`` the cost of each model.
    """
    scales = tuple(problem.robust.epsilon_scales if epsilon_scales is None else epsilon_scales)
    if len(scales) == 0 or any(not s > 0 for s in scales):
        raise DownholeInputError(f"epsilon_scales must be positive factors, got {list(scales)}")
    t0 = time.perf_counter()
    succ_ptr, succ, pred_ptr, pred = transitions(problem)
    check_reachable(problem, succ_ptr, succ)
    g2, g4 = problem.grid2(), problem.grid4()
    a = problem.arrays()
    lumped = a.lumped()
    p_ens = tuple(problem.arrays(s).bit for s in scales)  # one BitKernelParams per member
    nominal = np.array([abs(s - 1.0) < 1e-12 for s in scales])
    weights = np.full(len(scales), 1.0 / len(scales))
    w, t = problem.weights, problem.targets
    lam = np.array([w.lambda1, w.lambda2, w.lambda3, w.lambda4])
    targets = np.array([t.v_m, t.w_m, t.v_d, t.w_d])
    dt, n_steps = problem.step, problem.steps
    nsub = int(np.ceil(dt / problem.robust.substep - 1e-9))
    nn = g2.size * g4.size
    idx = problem.target_indices()
    start = idx["x2_0"] * g4.size + idx["x4_0"]
    cost = np.full(nn, np.inf)
    alive = np.zeros(nn, bool)
    states = np.zeros((nn, len(scales), 4))
    cost[start] = (w.lambda1 * t.v_m ** 2 + w.lambda2 * t.w_m ** 2) * dt  # rest state, all models
    alive[start] = True
    states[start, :, :] = 0.0
    parents = []
    kernel = robust_forward_step_parallel if parallel else robust_forward_step
    if pred.size * nsub * 16 <= _TABLE_BYTES:
        table = path_load_table(pred_ptr, pred, g2, g4, dt, nsub, lumped, a.bit)
    else:
        table = np.empty((0, 1, 2))
    with progress_bar(n_steps, "robust DP", progress) as advance:
        for k in range(n_steps):
            cost, states, alive, parent = kernel(
                pred_ptr, pred, g2, g4, dt, nsub, lumped, a.bit, p_ens, nominal, weights, lam,
                targets, k == n_steps - 1, cost, states, alive, table)
            parents.append(parent)
            advance()
    end = int(np.argmin(cost))
    if not np.isfinite(cost[end]):
        raise DownholeInputError("robust DP: no admissible path from rest within the bounds")
    path = np.empty(n_steps + 1, dtype=np.int64)
    path[n_steps] = end
    for k in range(n_steps - 1, -1, -1):
        path[k] = parents[k][path[k + 1]]
    info = {"seconds": time.perf_counter() - t0, "epsilon_scales": list(scales),
            "substeps": nsub, "transitions": int(succ.size),
            "grid": [problem.x2.points, problem.x4.points], "step": dt,
            "horizon": problem.horizon}
    sol = path_solution(problem, path, "robust", float(cost[end]), info)
    from downhole.control.dp.replay import ensemble_costs

    sol.info["ensemble_costs"] = ensemble_costs(sol, scales)
    return sol
