"""Replay of DP solutions: on the DP's discrete model, on the continuous 4th-order model (also
with perturbed epsilon), and on the 4th/12th-order simulation models of :mod:`downhole.sim`.

On-grid solutions are replayed by path inversion (docs/seed-errata.md): the top displacements are
rebuilt at every simulation step from the linear (x2, x4) path (Eq. 2.15 in continuous form), which
makes the 4th-order model follow the path closely; interpolating the DP's u(k) instead leaves 5-12 %
errors.
"""

from __future__ import annotations

import numpy as np

from downhole.control.dp.kernels import discrete_replay, path_replay
from downhole.control.dp.solution import DPSolution, trajectory_cost
from downhole.errors import DownholeInputError

__all__ = [
    "ensemble_costs",
    "replay_discrete",
    "replay_epsilon",
    "replay_lumped",
    "replay_path",
]


def replay_discrete(sol: DPSolution, epsilon_scale: float = 1.0) -> np.ndarray:
    """States x1..x4 of Eq. 2.12 driven by the solution's u1(k), u2(k).

    Parameters
    ----------
    sol : DPSolution
        The solution (its inputs u1 (m) and u2 (rad) per DP step).
    epsilon_scale : float, optional
        Factor on the rock's intrinsic specific energy of the replayed model (default 1).

    Returns
    -------
    ndarray, shape (N+1, 4)
        Bit displacement (m), axial velocity (m/s), angle (rad) and angular velocity (rad/s)
        at k = 0..N.
    """
    a = sol.problem.arrays(epsilon_scale)
    return discrete_replay(np.asarray(sol.u1, float), np.asarray(sol.u2, float),
                           sol.problem.step, a.lumped(), a.bit)


def replay_path(sol: DPSolution, epsilon_scale: float = 1.0, dt: float = 1e-3,
                every: int | None = None):
    """Continuous replay on the 4th-order approximated-depth model (own compiled integrator).

    Parameters
    ----------
    sol : DPSolution
        An on-grid solution (customized or robust DP).
    epsilon_scale : float
        Factor on epsilon of the replayed model (the inputs stay the nominal path's).
    dt : float
        Integration step, s; must divide the DP step.
    every : int, optional
        Output decimation in integration steps; default: one sample per DP step.

    Returns
    -------
    dict
        ``time`` (s), ``x2``, ``x4`` (bit velocities, m/s and rad/s) and ``e1``, ``e3`` (path
        minus model position, m and rad).

    Raises
    ------
    DownholeInputError
        An off-grid (standard DP) solution, or a ``dt`` that does not divide the DP step.
    """
    if not sol.on_grid:
        raise DownholeInputError("replay_path needs an on-grid (customized or robust) solution")
    step = sol.problem.step
    nsub = int(round(step / dt))
    if nsub < 1 or abs(nsub * dt - step) > 1e-9 * step:
        raise DownholeInputError(f"dt = {dt} s must divide the DP step {step} s")
    nominal = sol.problem.arrays()
    model = sol.problem.arrays(epsilon_scale)
    t, v, w, e1, e3 = path_replay(np.asarray(sol.x2, float), np.asarray(sol.x4, float), step,
                                  nsub, nominal.lumped(), nominal.bit, model.bit,
                                  every or nsub)
    return {"time": t, "x2": v, "x4": w, "e1": e1, "e3": e3}


def ensemble_costs(sol: DPSolution, scales) -> list[float]:
    """Eq. 2.13 cost of the solution's inputs on each model of an epsilon ensemble.

    Same integrator and substep as the robust DP (:func:`replay_path`); the nominal model
    (factor 1) follows the path exactly.

    Parameters
    ----------
    sol : DPSolution
        An on-grid solution.
    scales : iterable of float
        Factors on epsilon, one per ensemble model.

    Returns
    -------
    list of float
        The cost of each model, in the order of ``scales``.

    Raises
    ------
    DownholeInputError
        If the solution is off grid (from :func:`replay_path`).
    """
    out = []
    step = sol.problem.step
    nsub = int(np.ceil(step / sol.problem.robust.substep - 1e-9))
    for s in scales:
        if abs(s - 1.0) < 1e-12:
            out.append(trajectory_cost(sol.problem, sol.x2, sol.x4))
            continue
        r = replay_path(sol, s, dt=step / nsub)
        out.append(trajectory_cost(sol.problem, r["x2"], r["x4"]))
    return out


def replay_lumped(sol: DPSolution, order: int = 4, *, epsilon_scale: float = 1.0,
                  duration: float | None = None, dt: float = 5e-4,
                  depth_of_cut: str = "approximate", integrator: str = "euler",
                  record_dt: float | None = 0.01):
    """Replay the solution open loop on the lumped simulation model of ``order`` (4 or 12).

    The top displacements come from :meth:`DPSolution.input_signals` (path inversion) and drive
    :func:`downhole.sim.simulate` through ``SurfaceInputs.displacement``.

    Parameters
    ----------
    sol : DPSolution
        The solution.
    order : {4, 12}, optional
        Order of the lumped model (default 4).
    epsilon_scale : float, optional
        Factor on the rock's intrinsic specific energy (default 1).
    duration : float, optional
        Simulated time, s (default: the DP horizon).
    dt : float, optional
        Integration step, s (default 5e-4).
    depth_of_cut : {"approximate", "delayed"}, optional
        Depth-of-cut model (default ``"approximate"``).
    integrator : {"euler", "newmark"}, optional
        Integrator (default ``"euler"``).
    record_dt : float or None, optional
        Recording interval, s (default 0.01).

    Returns
    -------
    downhole.sim.result.Result

    Raises
    ------
    DownholeInputError
        If ``order`` is not 4 or 12, or an argument :func:`downhole.sim.simulate` refuses.
    """
    from downhole.sim import SurfaceInputs, simulate
    from downhole.sim.lumped_model import lumped_model

    if order not in (4, 12):
        raise DownholeInputError(f"order must be 4 or 12, got {order!r}")
    string, bit = sol.problem.params()
    if epsilon_scale != 1.0:
        bit = bit.model_copy(update={"epsilon": bit.epsilon * float(epsilon_scale)})
    model = lumped_model(string, bit, order=order)
    t, u1, u2 = sol.input_signals(dt, duration)
    inputs = SurfaceInputs.displacement(time=t, axial=u1, angular=u2)
    return simulate(model, inputs, duration=float(t[-1]), dt=dt, depth_of_cut=depth_of_cut,
                    integrator=integrator, record_dt=record_dt)


def replay_epsilon(sol: DPSolution, scales, *, dt: float = 1e-3, every: int | None = None,
                   duration: float | None = None, use_sim: bool = False, **sim_kwargs):
    """Bit velocities of the solution's inputs over a set of epsilon factors.

    With ``use_sim`` the 4th-order simulation model of :mod:`downhole.sim` is used (kwargs go to
    :func:`replay_lumped`); otherwise the compiled approximated-depth replay of
    :func:`replay_path`.

    Parameters
    ----------
    sol : DPSolution
        The solution (on grid unless ``use_sim``).
    scales : iterable of float
        Factors on epsilon.
    dt : float, optional
        Integration step of :func:`replay_path`, s (default 1e-3).
    every : int, optional
        Output decimation of :func:`replay_path`.
    duration : float, optional
        Simulated time with ``use_sim``, s (default: the DP horizon).
    use_sim : bool, optional
        Replay on the simulation model (default False).
    **sim_kwargs
        Passed to :func:`replay_lumped` with ``use_sim``.

    Returns
    -------
    dict
        ``time`` (s), ``scales`` and ``x2`` (m/s) / ``x4`` (rad/s) arrays of shape
        (len(scales), samples).
    """
    rows2, rows4, t = [], [], None
    for s in scales:
        if use_sim:
            res = replay_lumped(sol, 4, epsilon_scale=s, duration=duration, **sim_kwargs)
            t = res.time
            rows2.append(res["bit_axial_velocity"])
            rows4.append(res["bit_angular_velocity"])
        else:
            r = replay_path(sol, s, dt=dt, every=every)
            t = r["time"]
            rows2.append(r["x2"])
            rows4.append(r["x4"])
    return {"time": t, "scales": np.asarray(scales, float), "x2": np.array(rows2),
            "x4": np.array(rows4)}
