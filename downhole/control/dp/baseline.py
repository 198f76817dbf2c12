"""The conventional baseline the DP must beat: constant top-drive speeds (u1 = V0 t, u2 = W0 t).

The cost of Eq. 2.13 is evaluated on the continuous 4th-order approximated-depth model (the same
compiled integrator as the DP replays), and the best (V0, W0) is found by a grid scan refined
with Nelder-Mead.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from scipy.optimize import minimize

from downhole.control.dp.kernels import advance
from downhole.control.dp.problem import DPProblem
from downhole.control.dp.solution import trajectory_cost

__all__ = ["best_constant_velocities", "constant_velocity_cost", "constant_velocity_run"]


@njit(cache=True)
def constant_velocity_run(v0, w0, n_steps, dt, nsub, lumped, p):
    """Bit velocities at k dt (k = 0..n_steps) for constant top speeds v0, w0 from rest.

    The 4th-order lumped model (Eq. 2.1, approximated depth of cut) driven by top positions
    v0 t and w0 t, integrated with ``nsub`` substeps per step.

    Parameters
    ----------
    v0 : float
        Top axial speed, m/s.
    w0 : float
        Top angular speed, rad/s.
    n_steps : int
        Number of DP steps N.
    dt : float
        DP step, s.
    nsub : int
        Integration substeps per DP step.
    lumped : LumpedKernelParams
        Mass (kg), inertia (kg m^2), stiffnesses and dampings of the lumped model.
    p : BitKernelParams
        Compiled bit parameters.

    Returns
    -------
    x2 : ndarray, shape (n_steps + 1,)
        Bit axial velocity, m/s.
    x4 : ndarray, shape (n_steps + 1,)
        Bit angular velocity, rad/s.
    """
    mass, inertia, ka, ca, kt, ct = (lumped.mass, lumped.inertia, lumped.ka, lumped.ca,
                                     lumped.kt, lumped.ct)
    h = dt / nsub
    x2 = np.zeros(n_steps + 1)
    x4 = np.zeros(n_steps + 1)
    x1, v, x3, w = 0.0, 0.0, 0.0, 0.0
    t = 0.0
    for k in range(n_steps):
        for s in range(nsub):
            v, w = advance(v, w, ka * (v0 * t - x1), kt * (w0 * t - x3), mass, inertia, ca, ct,
                           p, h)
            x1 += v * h
            x3 += w * h
            t += h
        x2[k + 1] = v
        x4[k + 1] = w
    return x2, x4


def constant_velocity_cost(problem: DPProblem, v0: float, w0: float,
                           substep: float = 2.5e-3, epsilon_scale: float = 1.0) -> float:
    """Eq. 2.13 cost of constant top speeds ``v0`` (m/s) and ``w0`` (rad/s).

    Parameters
    ----------
    problem : DPProblem
        The problem (model, horizon, step, weights and targets).
    v0 : float
        Top axial speed, m/s.
    w0 : float
        Top angular speed, rad/s.
    substep : float, optional
        Largest integration substep, s (default 2.5e-3).
    epsilon_scale : float, optional
        Factor on the rock's intrinsic specific energy (default 1).

    Returns
    -------
    float
        The cost (:func:`~downhole.control.dp.solution.trajectory_cost`); inf if the run
        diverges.
    """
    a = problem.arrays(epsilon_scale)
    nsub = int(np.ceil(problem.step / substep - 1e-9))
    x2, x4 = constant_velocity_run(float(v0), float(w0), problem.steps, problem.step, nsub,
                                   a.lumped(), a.bit)
    if not (np.all(np.isfinite(x2)) and np.all(np.isfinite(x4))):
        return float("inf")
    return trajectory_cost(problem, x2, x4)


def best_constant_velocities(problem: DPProblem, scan: int = 11,
                             substep: float = 2.5e-3) -> tuple[float, float, float]:
    """Best constant top speeds for the problem's cost: ``(cost, v0, w0)``.

    A ``scan`` x ``scan`` grid from 0.25 to 2 times the largest target velocities, refined by
    Nelder-Mead from the best grid point.

    Parameters
    ----------
    problem : DPProblem
        The problem.
    scan : int, optional
        Grid points per speed (default 11).
    substep : float, optional
        Largest integration substep, s (default 2.5e-3).

    Returns
    -------
    (cost, v0, w0) : tuple of float
        The lowest cost found, the top axial speed (m/s) and angular speed (rad/s).
    """
    t = problem.targets
    vs = np.linspace(0.25, 2.0, scan) * max(t.v_m, t.v_d)
    ws = np.linspace(0.25, 2.0, scan) * max(t.w_m, t.w_d)
    best = (np.inf, vs[0], ws[0])
    for v in vs:
        for w in ws:
            c = constant_velocity_cost(problem, v, w, substep)
            if c < best[0]:
                best = (c, v, w)
    scale = np.array([vs[1] - vs[0], ws[1] - ws[0]])
    res = minimize(lambda z: constant_velocity_cost(problem, *(z * scale), substep),
                   np.array([best[1], best[2]]) / scale, method="Nelder-Mead",
                   options={"xatol": 1e-3, "fatol": 1e-9 * max(best[0], 1e-12), "maxiter": 200})
    if res.fun < best[0]:
        v, w = res.x * scale
        best = (float(res.fun), float(v), float(w))
    return float(best[0]), float(best[1]), float(best[2])
