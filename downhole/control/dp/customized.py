"""Customized DP by partial inversion of the 4th-order model (seed Eqs. 2.15-2.24).

Candidate states are grid pairs (x2, x4); the inverted discrete model (Eq. 2.15) gives the
inputs that connect a node at step k with a node at step k+1, so no interpolation and no
forward integration is needed. Two variants give the same optimum (x1 and x3 enter the model
only as x - u, docs/seed-errata.md):

* ``regions=False`` (default): the DP over (x2, x4) nodes, O(N (L2 L4)^2).
* ``regions=True``: the seed's algorithm, with x1/x3 binned into ``x1_regions`` / ``x3_regions``
  regions (Eqs. 2.19-2.20 with L1, L3 as region widths) as extra node coordinates; this is how
  the sizes of the seed's Table 2.2 are defined.

The candidate's cost includes the cost-to-go J_{k+1} of the connected node (Eq. 2.21 as printed
omits it, which would make the DP ignore the future).
"""

from __future__ import annotations

import time

import numpy as np

from downhole.control.dp._progress import chunks, progress_bar
from downhole.control.dp.kernels import (
    backward_plain,
    node_bit_loads,
    regions_step,
    transition_lists,
)
from downhole.control.dp.problem import DPProblem
from downhole.control.dp.solution import DPSolution
from downhole.errors import DownholeInputError

__all__ = ["check_reachable", "path_solution", "solve_customized", "stage_vector", "transitions"]


def stage_vector(problem: DPProblem) -> tuple[np.ndarray, np.ndarray]:
    """Stage cost (Eq. 2.13 terms for k < N) and terminal cost at every (x2, x4) node.

    Parameters
    ----------
    problem : DPProblem
        The problem (grids, weights, targets, step).

    Returns
    -------
    stage : ndarray, shape (n2 * n4,)
        ``(lambda1 (x2 - v_m)^2 + lambda2 (x4 - w_m)^2) Delta t`` per node, node index
        ``i2 * n4 + i4``.
    term : ndarray, shape (n2 * n4,)
        ``lambda3 (x2 - v_d)^2 + lambda4 (x4 - w_d)^2`` per node.
    """
    g2, g4 = problem.grid2(), problem.grid4()
    w, t, dt = problem.weights, problem.targets, problem.step
    x2, x4 = np.meshgrid(g2, g4, indexing="ij")
    stage = (w.lambda1 * (x2 - t.v_m) ** 2 + w.lambda2 * (x4 - t.w_m) ** 2).ravel() * dt
    term = (w.lambda3 * (x2 - t.v_d) ** 2 + w.lambda4 * (x4 - t.w_d) ** 2).ravel()
    return stage, term


def _bounds_array(problem: DPProblem) -> tuple[np.ndarray, bool]:
    b = problem.bounds
    rates = b.top_speed is not None or b.rotary_speed is not None
    ts = b.top_speed or (-np.inf, np.inf)
    rs = b.rotary_speed or (-np.inf, np.inf)
    return np.array([*b.force, *b.torque, *ts, *rs], dtype=float), rates


def transitions(problem: DPProblem, epsilon_scale: float = 1.0):
    """CSR lists ``(succ_ptr, succ, pred_ptr, pred)`` of the admissible node pairs.

    A pair of (x2, x4) nodes is admissible when the string force and torque needed to move
    between them in one step (and the top speeds, if bounded) lie within ``problem.bounds``.

    Parameters
    ----------
    problem : DPProblem
        The problem.
    epsilon_scale : float, optional
        Factor on the rock's intrinsic specific energy (default 1).

    Returns
    -------
    succ_ptr, succ, pred_ptr, pred : ndarray of int
        Successors and predecessors of every node (node index ``i2 * n4 + i4``) in compressed
        sparse row form.
    """
    a = problem.arrays(epsilon_scale)
    bounds, rates = _bounds_array(problem)
    return transition_lists(problem.grid2(), problem.grid4(), a.lumped(), a.bit, problem.step,
                            bounds, rates)


def check_reachable(problem: DPProblem, succ_ptr, succ) -> None:
    """Reject the problem before the search if no admissible path reaches (v_d, w_d) in N steps.

    Parameters
    ----------
    problem : DPProblem
        The problem.
    succ_ptr, succ : ndarray of int
        Successor lists from :func:`transitions`.

    Raises
    ------
    DownholeInputError
        Naming the bounds and the force and torque one grid step in one DP step needs, when
        the final target cannot be reached from rest.
    """
    idx = problem.target_indices()
    n4 = problem.x4.points
    nn = problem.x2.points * n4
    start = idx["x2_0"] * n4 + idx["x4_0"]
    goal = idx["v_d"] * n4 + idx["w_d"]
    reach = np.zeros(nn, bool)
    reach[start] = True
    for k in range(problem.steps):
        nxt = np.zeros(nn, bool)
        for n in np.flatnonzero(reach):
            nxt[succ[succ_ptr[n]:succ_ptr[n + 1]]] = True
        reach = nxt
        if reach[goal]:
            return
    b = problem.bounds
    g2, g4 = problem.grid2(), problem.grid4()
    a = problem.arrays()
    rates = ""
    if b.top_speed is not None or b.rotary_speed is not None:
        rates = f", bounds.top_speed={b.top_speed} m/s, bounds.rotary_speed={b.rotary_speed} rad/s"
    raise DownholeInputError(
        f"infeasible problem: the final target (v_d={problem.targets.v_d} m/s, "
        f"w_d={problem.targets.w_d} rad/s) cannot be reached from rest in {problem.steps} steps "
        f"of {problem.step} s within bounds.force={list(b.force)} N, "
        f"bounds.torque={list(b.torque)} N m{rates}. One grid step in one DP step needs "
        f"{a.mass * (g2[1] - g2[0]) / problem.step:.4g} N (x2) and "
        f"{a.inertia * (g4[1] - g4[0]) / problem.step:.4g} N m (x4) of inertial load on top of "
        "the bit load; use a longer step, finer grids or wider bounds")


def path_solution(problem: DPProblem, path: np.ndarray, method: str, cost: float,
                  info: dict) -> DPSolution:
    """Build a :class:`DPSolution` from a node path (k = 0..N) by the inversion of Eq. 2.15.

    Parameters
    ----------
    problem : DPProblem
        The problem.
    path : ndarray of int, shape (N+1,)
        Node indices ``i2 * n4 + i4`` of the path.
    method : str
        Name of the solver (``customized``, ``robust``, ...).
    cost : float
        The cost reported by the search.
    info : dict
        Timings and other settings stored with the solution.

    Returns
    -------
    DPSolution
        States x1..x4 (m, m/s, rad, rad/s), string force (N) and torque (N m), top inputs
        u1 (m) and u2 (rad).
    """
    g2, g4 = problem.grid2(), problem.grid4()
    n4 = g4.size
    i2, i4 = path // n4, path % n4
    x2, x4 = g2[i2], g4[i4]
    dt = problem.step
    a = problem.arrays()
    x1 = np.concatenate([[0.0], np.cumsum(x2[:-1] * dt)])
    x3 = np.concatenate([[0.0], np.cumsum(x4[:-1] * dt)])
    wob, tob = node_bit_loads(g2, g4, a.bit)
    force = wob[path[:-1]] + a.ca * x2[:-1] + a.mass * np.diff(x2) / dt
    torque = tob[path[:-1]] + a.ct * x4[:-1] + a.inertia * np.diff(x4) / dt
    return DPSolution(method=method, problem=problem, times=problem.times, x1=x1, x2=x2, x3=x3,
                      x4=x4, u1=x1[:-1] + force / a.ka, u2=x3[:-1] + torque / a.kt, force=force,
                      torque=torque, cost=float(cost), grid2=g2, grid4=g4,
                      path_i2=i2.astype(np.int64), path_i4=i4.astype(np.int64), info=info)


def solve_customized(problem: DPProblem, *, regions: bool | None = None,
                     progress: bool = False) -> DPSolution:
    """Solve the problem with the customized (partially inverted) DP.

    Parameters
    ----------
    problem : DPProblem
        The validated problem.
    regions : bool, optional
        Use the seed's x1/x3 index regions (needs ``problem.x1_regions``/``x3_regions``).
        Default: True when the problem defines regions, else False. The optimum is the same.
    progress : bool
        Show a rich progress bar.

    Returns
    -------
    DPSolution
        ``cost`` is the DP's optimal cost J_0 at the rest state; ``info["seconds"]`` the search
        time, ``info["nodes"]`` the number of candidate nodes created.

    Raises
    ------
    DownholeInputError
        If the targets cannot be reached within the bounds (checked before the search).

    Examples
    --------
    >>> from downhole.control.dp import DPProblem, solve_customized
    >>> sol = solve_customized(DPProblem(horizon=5.0, step=0.25))
    >>> round(float(sol.x2[-1]), 4), round(float(sol.x4[-1]), 1)
    (0.01, 10.0)
    """
    if regions is None:
        regions = problem.x1_regions is not None
    if regions and problem.x1_regions is None:
        raise DownholeInputError("regions=True needs x1_regions and x3_regions in the problem")
    t0 = time.perf_counter()
    succ_ptr, succ, pred_ptr, pred = transitions(problem)
    check_reachable(problem, succ_ptr, succ)
    stage, term = stage_vector(problem)
    n_steps = problem.steps
    idx = problem.target_indices()
    n4 = problem.x4.points
    start = idx["x2_0"] * n4 + idx["x4_0"]
    info = {"transitions": int(succ.size), "grid": [problem.x2.points, problem.x4.points],
            "step": problem.step, "horizon": problem.horizon, "regions": bool(regions)}
    if not regions:
        nn = stage.size
        J = np.empty((n_steps + 1, nn))
        J[n_steps] = term
        policy = np.empty((n_steps, nn), dtype=np.int32)
        with progress_bar(n_steps, "customized DP", progress) as advance:
            for hi, lo in chunks(n_steps):
                backward_plain(succ_ptr, succ, stage, J, policy, hi, lo)
                advance(hi - lo)
        cost = J[0, start]
        path = np.empty(n_steps + 1, dtype=np.int64)
        path[0] = start
        for k in range(n_steps):
            path[k + 1] = policy[k, path[k]]
        info["nodes"] = int(nn * (n_steps + 1))
    else:
        cost, path, nodes = _regions_search(problem, pred_ptr, pred, stage, term, start, progress)
        info["nodes"] = nodes
        info["x1_regions"], info["x3_regions"] = problem.x1_regions, problem.x3_regions
    info["seconds"] = time.perf_counter() - t0
    if not np.isfinite(cost):
        raise DownholeInputError("no admissible path from rest within the bounds")
    return path_solution(problem, path, "customized", cost, info)


def _region_layout(lo_v: float, hi_v: float, horizon: float, count: int):
    """Region width and index range for x = -(sum of velocities * dt), x in [-hi T, -lo T]."""
    span = (max(hi_v, 0.0) - min(lo_v, 0.0)) * horizon
    width = span / count if span > 0 else 1.0
    r_lo = int(np.floor(-max(hi_v, 0.0) * horizon / width + 0.5)) - 1
    r_hi = int(np.floor(-min(lo_v, 0.0) * horizon / width + 0.5)) + 1
    return width, r_lo, r_hi - r_lo + 1


def _regions_search(problem, pred_ptr, pred, stage, term, start, progress):
    g2, g4 = problem.grid2(), problem.grid4()
    dt, n_steps = problem.step, problem.steps
    w1, r1_lo, n_r1 = _region_layout(g2[0], g2[-1], problem.horizon, problem.x1_regions)
    w3, r3_lo, n_r3 = _region_layout(g4[0], g4[-1], problem.horizon, problem.x3_regions)
    nn = stage.size
    # nodes at step N: every grid node, x1 = x3 = 0 (x1/x3 are measured from the final state)
    node_n = np.arange(nn, dtype=np.int32)
    node_x1 = np.zeros(nn)
    node_x3 = np.zeros(nn)
    node_j = term.copy()
    keep = np.isfinite(node_j)
    node_n, node_x1, node_x3, node_j = node_n[keep], node_x1[keep], node_x3[keep], node_j[keep]
    layers = [(node_n, None)]
    total = node_n.size
    with progress_bar(n_steps, "customized DP (regions)", progress) as advance:
        for k in range(n_steps - 1, -1, -1):
            node_n, node_x1, node_x3, node_j, parent = regions_step(
                pred_ptr, pred, stage, g2, g4, dt, w1, w3, r1_lo, n_r1, r3_lo, n_r3,
                node_n, node_x1, node_x3, node_j)
            layers.append((node_n, parent))
            total += node_n.size
            advance()
    layers.reverse()  # layers[k] = (grid nodes at step k, successor index into layer k+1)
    n0, par0 = layers[0]
    cand = np.flatnonzero(n0 == start)
    if cand.size == 0:
        return np.inf, None, total
    q = cand[np.argmin(node_j[cand])]
    cost = node_j[q]
    path = np.empty(n_steps + 1, dtype=np.int64)
    for k in range(n_steps):
        nodes_k, par_k = layers[k]
        path[k] = nodes_k[q]
        q = par_k[q]
    path[n_steps] = layers[n_steps][0][q]
    return float(cost), path, int(total)
