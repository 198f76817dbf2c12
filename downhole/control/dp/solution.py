"""The result of a DP search: inputs, state path, cost, grids and settings; saved without pickle.

A :class:`DPSolution` is written as ``solution.npz`` (plain float/int arrays, loaded with
``allow_pickle=False``) next to ``solution.json`` (method, cost, timings and the problem as a
plain dict that re-validates on load). The pair is written atomically and carries one
``run_id``, so that arrays and metadata of two different saves are never loaded together.
"""

from __future__ import annotations

import json
import os
import uuid
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from downhole._atomic import new_temp, replace_atomic
from downhole.errors import DownholeInputError

__all__ = ["DPSolution", "load_solution", "stage_costs", "trajectory_cost"]

_ARRAYS = ("times", "x1", "x2", "x3", "x4", "u1", "u2", "force", "torque", "grid2", "grid4",
           "path_i2", "path_i4")
_FORMAT = "downhole.dp.solution/1"


def stage_costs(problem, x2, x4) -> np.ndarray:
    """Per-sample costs of Eq. 2.13: stage terms for k < N, the terminal term at k = N.

    Parameters
    ----------
    problem : DPProblem
        The problem (weights lambda1..4, targets v_m, w_m, v_d, w_d and step Delta t, s).
    x2 : array_like, shape (N+1,)
        Bit axial velocity at k = 0..N, m/s.
    x4 : array_like, shape (N+1,)
        Bit angular velocity at k = 0..N, rad/s.

    Returns
    -------
    ndarray, shape (N+1,)
        ``(lambda1 (x2 - v_m)^2 + lambda2 (x4 - w_m)^2) Delta t`` for k < N and
        ``lambda3 (x2 - v_d)^2 + lambda4 (x4 - w_d)^2`` at k = N (units of the weights times
        squared velocities; dimensionless with the seed's weights).
    """
    w, t, dt = problem.weights, problem.targets, problem.step
    x2 = np.asarray(x2, float)
    x4 = np.asarray(x4, float)
    c = (w.lambda1 * (x2 - t.v_m) ** 2 + w.lambda2 * (x4 - t.w_m) ** 2) * dt
    c[-1] = w.lambda3 * (x2[-1] - t.v_d) ** 2 + w.lambda4 * (x4[-1] - t.w_d) ** 2
    return c


def trajectory_cost(problem, x2, x4) -> float:
    """Cost g(x) of Eq. 2.13 of a trajectory sampled at k = 0..N.

    Parameters
    ----------
    problem, x2, x4
        As :func:`stage_costs`.

    Returns
    -------
    float
        The sum of :func:`stage_costs`.
    """
    return float(np.sum(stage_costs(problem, x2, x4)))


@dataclass
class DPSolution:
    """An optimal input sequence and the path it produces on the DP's model.

    Attributes
    ----------
    method : str
        ``customized``, ``standard`` or ``robust``.
    problem : DPProblem
        The problem solved.
    times : ndarray, shape (N+1,)
        Sample times k Delta t, s.
    x1, x2, x3, x4 : ndarray, shape (N+1,)
        Bit displacement (m), axial velocity (m/s), angle (rad) and angular velocity (rad/s) on the
        DP's model (Eq. 2.12 for customized/robust, the projection model for standard).
    u1, u2 : ndarray, shape (N,)
        Top-drive displacement (m) and angle (rad) from the hanging start, held over each step
        (the discrete model's inputs).
    force, torque : ndarray, shape (N,)
        String force K_a (u1 - x1) (N) and torque K_t (u2 - x3) (N m) at the start of each step.
    cost : float
        The optimal cost reported by the search (Eq. 2.13; for robust, the ensemble mean).
    grid2, grid4 : ndarray
        The search grids (m/s, rad/s).
    path_i2, path_i4 : ndarray of int, shape (N+1,)
        Grid indices of the path (-1 where the state is off grid, as in the standard DP).
    info : dict
        Timings (``seconds``), node/transition counts, ensemble costs and other settings.
    """

    method: str
    problem: object
    times: np.ndarray
    x1: np.ndarray
    x2: np.ndarray
    x3: np.ndarray
    x4: np.ndarray
    u1: np.ndarray
    u2: np.ndarray
    force: np.ndarray
    torque: np.ndarray
    cost: float
    grid2: np.ndarray
    grid4: np.ndarray
    path_i2: np.ndarray
    path_i4: np.ndarray
    info: dict = field(default_factory=dict)

    @property
    def on_grid(self) -> bool:
        """True when the state path lies on the (x2, x4) grid (customized and robust DP)."""
        return bool(np.all(self.path_i2 >= 0))

    def input_signals(self, dt: float, duration: float | None = None):
        """Top displacements sampled every ``dt`` for replay on a simulation model.

        On-grid paths are replayed by path inversion: the linear (x2, x4) path is inverted in
        continuous form at every sample (do not interpolate u(k), docs/seed-errata.md). Off-grid
        solutions (standard DP) hold u(k) over each step.

        Parameters
        ----------
        dt : float
            Sample step, s (> 0).
        duration : float, optional
            Length of the signals, s (default: the horizon). Beyond the horizon an on-grid
            solution holds the final velocities (steady drilling); an off-grid one holds the last
            input.

        Returns
        -------
        t, u1, u2 : ndarray
            Times (s), top axial displacement (m) and top angle (rad) from the hanging start.

        Raises
        ------
        DownholeInputError
            If ``dt`` is not positive.
        """
        from downhole.control.dp.kernels import path_inputs

        if not dt > 0:
            raise DownholeInputError(f"dt must be > 0 s, got {dt!r}")
        horizon = float(self.times[-1]) if duration is None else float(duration)
        t = np.arange(int(round(horizon / dt)) + 1) * dt
        a = self.problem.arrays()
        if self.on_grid:
            tt = np.minimum(t, self.times[-1])
            u1, u2 = path_inputs(self.x2, self.x4, self.problem.step, tt, a.lumped(), a.bit)
            if duration is not None and duration > self.times[-1]:
                # hold the final velocities beyond the horizon (steady drilling)
                late = t > self.times[-1]
                u1[late] += self.x2[-1] * (t[late] - self.times[-1])
                u2[late] += self.x4[-1] * (t[late] - self.times[-1])
            return t, u1, u2
        k = np.minimum((t / self.problem.step + 1e-9).astype(int), self.u1.size - 1)
        return t, self.u1[k], self.u2[k]

    def summary(self) -> dict:
        """Cost, final velocities and timing, as plain numbers."""
        return {"method": self.method, "cost": float(self.cost),
                "final_x2": float(self.x2[-1]), "final_x4": float(self.x4[-1]),
                "steps": int(self.times.size - 1), **{k: v for k, v in self.info.items()
                                                      if isinstance(v, (int, float, str))}}

    # ------------------------------------------------------------------ persistence
    def save(self, directory: str | os.PathLike) -> Path:
        """Write ``solution.npz`` and ``solution.json`` into ``directory``; returns it.

        The pair is written so that it is never left mixed from two saves: both files are
        written under temporary names first (and fsynced), the old ``solution.json`` is removed,
        then ``solution.npz`` and last ``solution.json`` are renamed into place. Both carry the
        same ``run_id``, which :func:`load_solution` checks. A save killed at any point leaves
        either the previous pair, or no ``solution.json`` (and :func:`load_solution` says so).

        Parameters
        ----------
        directory : str or os.PathLike
            Output folder (created if needed).

        Returns
        -------
        pathlib.Path
            ``directory``.
        """
        d = Path(directory)
        d.mkdir(parents=True, exist_ok=True)
        run_id = uuid.uuid4().hex
        npz, js = d / "solution.npz", d / "solution.json"
        meta = {"format": _FORMAT, "run_id": run_id, "method": self.method,
                "cost": float(self.cost), "problem": self.problem.model_dump(mode="json"),
                "info": _jsonable(self.info)}
        tmp_npz, tmp_js = new_temp(npz), new_temp(js)
        try:
            np.savez(tmp_npz, run_id=np.array(run_id),
                     **{k: np.asarray(getattr(self, k)) for k in _ARRAYS})
            tmp_js.write_text(json.dumps(meta, indent=2))
            # until the json is renamed the folder holds no solution.json, so a kill cannot
            # leave the new arrays beside the previous run's metadata
            js.unlink(missing_ok=True)
            replace_atomic(tmp_npz, npz)
            replace_atomic(tmp_js, js)
        finally:
            tmp_npz.unlink(missing_ok=True)
            tmp_js.unlink(missing_ok=True)
        return d


def load_solution(directory: str | os.PathLike) -> DPSolution:
    """Load a solution written by :meth:`DPSolution.save` (no pickle).

    Parameters
    ----------
    directory : str or os.PathLike
        Folder holding ``solution.json`` and ``solution.npz``.

    Returns
    -------
    DPSolution

    Raises
    ------
    DownholeInputError
        If a file is missing, of another format, from another save, or the arrays are
        inconsistent.
    ScenarioError
        If the stored problem fails validation.
    """
    from downhole.control.dp.problem import problem_from_dict

    d = Path(directory)
    meta_path, arr_path = d / "solution.json", d / "solution.npz"
    for pth in (meta_path, arr_path):
        if not pth.is_file():
            raise DownholeInputError(f"DP solution file {pth} not found")
    meta = json.loads(meta_path.read_text())
    if meta.get("format") != _FORMAT:
        raise DownholeInputError(f"{meta_path}: format {meta.get('format')!r}, "
                                 f"expected {_FORMAT!r}")
    with np.load(arr_path, allow_pickle=False) as z:
        missing = [k for k in _ARRAYS if k not in z.files]
        if missing:
            raise DownholeInputError(f"{arr_path}: missing arrays {missing}")
        arrays = {k: np.array(z[k]) for k in _ARRAYS}
        npz_id = str(z["run_id"]) if "run_id" in z.files else None
    json_id = meta.get("run_id")
    if npz_id is not None and json_id is not None and npz_id != json_id:
        raise DownholeInputError(f"{arr_path} and {meta_path} come from two different saves "
                                 f"(run_id {npz_id} vs {json_id}); rerun the optimization")
    problem = problem_from_dict(meta["problem"], source=str(meta_path))
    n = problem.steps
    if arrays["x2"].size != n + 1 or arrays["u1"].size != n:
        raise DownholeInputError(f"{arr_path}: arrays do not match the problem's {n} steps")
    return DPSolution(method=meta["method"], problem=problem, cost=float(meta["cost"]),
                      info=meta.get("info", {}), **arrays)


def _jsonable(obj):
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, (np.floating, np.integer)):
        return obj.item()
    if isinstance(obj, np.bool_):
        return bool(obj)
    return obj
