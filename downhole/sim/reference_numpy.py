"""A plain NumPy/Python stepping of the 4th-order model (Eq. 2.1) with the delayed depth of cut.

Independent of the compiled kernel: the delay of Eq. 2.10 is solved by searching the bit-angle
history (``np.searchsorted`` + linear interpolation) instead of the rock-surface grid. Used as the
speed baseline of ``downhole bench`` and as a second method in the tests. No rock-surface memory
(the printed Eq. 2.9), so compare with ``rock_memory=False`` or in runs without bit bounce.

This is the benchmark's independent baseline (``downhole bench``, group ch2): its stepping and
its depth-of-cut search are written separately on purpose and must stay so. The bit/rock law is
not: it is the package's one law (:func:`downhole.bit.law.bit_forces`, called from Python).
"""

from __future__ import annotations

import math

import numpy as np

from downhole.bit.law import bit_forces
from downhole.sim.lumped_model import ChainModel

__all__ = ["simulate_lumped4_numpy"]


def simulate_lumped4_numpy(model: ChainModel, v0: float, w0: float, duration: float,
                           dt: float) -> dict:
    """Explicit Euler of the 4th-order model at constant top-drive velocities ``v0`` (m/s),
    ``w0`` (rad/s). Returns arrays ``time, bit_axial_velocity, bit_angular_velocity,
    depth_of_cut`` at every step."""
    if model.n != 1:
        raise ValueError("the NumPy reference covers the 4th-order model only")
    law = bit_forces.py_func  # the one law (its outer function interpreted)
    p = model.bit.kernel_params()
    n_bl = model.bit.n_blades
    pitch = 2 * math.pi / n_bl
    m, inertia = model.axial.mass[0], model.torsional.mass[0]
    ka, kt = model.axial.k_top, model.torsional.k_top
    ca, ct = model.axial.c_abs[0], model.torsional.c_abs[0]
    nsteps = int(round(duration / dt))
    # state z = [x1, x2, x3, x4] of Eq. 2.1; z' = A z + B u + F(bit)
    a_mat = np.array([[0.0, 1.0, 0.0, 0.0],
                      [-ka / m, -ca / m, 0.0, 0.0],
                      [0.0, 0.0, 0.0, 1.0],
                      [0.0, 0.0, -kt / inertia, -ct / inertia]])
    b_mat = np.array([[0.0, 0.0], [ka / m, 0.0], [0.0, 0.0], [0.0, kt / inertia]])
    f_map = np.array([[0.0, 0.0], [-1.0 / m, 0.0], [0.0, 0.0], [0.0, -1.0 / inertia]])
    x_hist = np.zeros(nsteps + 1)
    th_hist = np.zeros(nsteps + 1)  # running max of the bit angle (monotone for searchsorted)
    out = np.zeros((4, nsteps + 1))
    z = np.zeros(4)
    for k in range(nsteps + 1):
        t = k * dt
        target = z[2] - pitch
        if target <= 0.0:
            x_prev = 0.0  # flat bottom before the start
        else:
            j = int(np.searchsorted(th_hist[: k + 1], target))
            j = min(max(j, 1), k)
            t0, t1 = th_hist[j - 1], th_hist[j]
            f = 0.0 if t1 <= t0 else (target - t0) / (t1 - t0)
            x_prev = x_hist[j - 1] + f * (x_hist[j] - x_hist[j - 1])
        d = n_bl * (z[0] - x_prev)
        wob, tob = law(d, z[1], z[3], p)
        out[:, k] = (t, z[1], z[3], d)
        if k == nsteps:
            break
        u = np.array([v0 * t, w0 * t])
        z = z + dt * (a_mat @ z + b_mat @ u + f_map @ np.array([wob, tob]))
        x_hist[k + 1] = z[0]
        th_hist[k + 1] = max(z[2], th_hist[k])
    return {"time": out[0], "bit_axial_velocity": out[1], "bit_angular_velocity": out[2],
            "depth_of_cut": out[3]}
