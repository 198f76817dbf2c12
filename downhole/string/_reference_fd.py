"""Independent reference for the neutral-type model: a finite-difference (lumped mass-spring)
discretization of the wave equations 3.1-3.2 with the boundary conditions 3.3-3.6, N elements per
field, integrated by symplectic Euler (the top damper and the stiff bit friction implicit).

It shares only the bit law and the rock-surface memory with :mod:`downhole.string.neutral`; the
string is resolved in space instead of by d'Alembert's formula, so agreement (and convergence as
N grows) tests the delays, impedances and boundary handling of the wave model.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from downhole.bit.law import approx_depth_of_cut, bit_force_slopes, bit_forces
from downhole.bit.rock_surface import RockSurfaceSpec, rock_advance, rock_depth, rock_init

__all__ = ["simulate_fd"]


@njit(cache=True)
def _run_fd(n, ea_dz, gj_dz, m_node, i_node, m_b, i_b, alpha_a, alpha_t, f_top, n0, grav,
            bitp, approx, ua, ut, surf, istate, rp, nsteps, dt, every, out):
    ua_ = np.zeros(n + 1)  # axial displacement from the initial state
    va = np.zeros(n + 1)
    ta = np.zeros(n + 1)  # twist angle
    wa = np.zeros(n + 1)
    rec = 0
    for k in range(nsteps + 1):
        xb = ua_[n]
        vb = va[n]
        thb = ta[n]
        wb = wa[n]
        if approx:
            d = approx_depth_of_cut(vb, wb, bitp)
        else:
            d = rock_depth(surf, istate, rp, xb, thb)
        wob, tob = bit_forces(d, vb, wb, bitp)
        if k % every == 0:
            out[rec, 0] = k * dt
            out[rec, 1] = vb
            out[rec, 2] = wb
            out[rec, 3] = wob
            out[rec, 4] = tob
            rec += 1
        if k == nsteps:
            break
        ca, ct = bit_force_slopes(d, vb, wb, bitp, approx)
        # velocities (forces from current displacements), top damper and bit implicit
        for i in range(n + 1):
            fa = 0.0
            ft = 0.0
            if i < n:
                fa += n0 + ea_dz * (ua_[i + 1] - ua_[i])
                ft += gj_dz * (ta[i + 1] - ta[i])
            if i > 0:
                fa -= n0 + ea_dz * (ua_[i] - ua_[i - 1])
                ft -= gj_dz * (ta[i] - ta[i - 1])
            if i == 0:
                # N(0) = alpha (v0 - U) + F_top acts upward on the top node
                va[0] = (m_node[0] * va[0] + dt * (fa - f_top + alpha_a * ua[k + 1])) / (
                    m_node[0] + dt * alpha_a)
                wa[0] = (i_node[0] * wa[0] + dt * (ft + alpha_t * ut[k + 1])) / (
                    i_node[0] + dt * alpha_t)
            elif i == n:
                m = m_node[n] + m_b
                ii = i_node[n] + i_b
                va[n] = (m * va[n] + dt * (fa + grav - wob + ca * va[n])) / (m + dt * ca)
                wa[n] = (ii * wa[n] + dt * (ft - tob + ct * wa[n])) / (ii + dt * ct)
            else:
                va[i] += dt * fa / m_node[i]
                wa[i] += dt * ft / i_node[i]
        for i in range(n + 1):
            ua_[i] += dt * va[i]
            ta[i] += dt * wa[i]
        if not approx:
            rock_advance(surf, istate, rp, thb, xb, ta[n], ua_[n])
    return rec


def simulate_fd(model, n_elements: int, duration: float, u_axial: float, u_angular: float,
                depth_of_cut: str = "delayed", cfl: float = 0.5, record_dt: float = 1e-3):
    """Finite-difference solution of Eqs. 3.1-3.6 under constant commands (U_A, U_T) from the
    hanging state at rest (U_A = M_S g/alpha_A, U_T = 0 before t = 0).

    Parameters
    ----------
    model : NeutralModel
    n_elements : int
        Elements per field (>= 2).
    duration : float
        Simulated time, s.
    u_axial, u_angular : float
        Constant commands from t = 0 (m/s, rad/s; seed convention).
    depth_of_cut : {"delayed", "approximate"}
    cfl : float
        Courant number c dt / dz of the faster (axial) field, < 1.
    record_dt : float
        Output interval, s (rounded to a multiple of the step).

    Returns
    -------
    dict with ``time``, ``bit_axial_velocity``, ``bit_angular_velocity``, ``wob``, ``tob``.
    """
    p = model.params
    pipe = p.pipe
    n = int(n_elements)
    if n < 2:
        raise ValueError(f"n_elements must be >= 2, got {n_elements}")
    dz = p.length / n
    c = pipe.axial_wave_speed
    dt0 = cfl * dz / c
    every = max(1, int(math.ceil(record_dt / dt0)))
    dt = record_dt / every
    nsteps = int(round(duration / dt))
    rho = pipe.density
    m_el = rho * pipe.area * dz
    i_el = rho * pipe.polar_moment * dz
    m_node = np.full(n + 1, m_el)
    m_node[0] = m_node[-1] = 0.5 * m_el
    i_node = np.full(n + 1, i_el)
    i_node[0] = i_node[-1] = 0.5 * i_el
    ua = np.full(nsteps + 2, float(u_axial))
    ut = np.full(nsteps + 2, float(u_angular))
    spec = RockSurfaceSpec(model.bit.n_blades, 512, True)
    surf, istate, rp = rock_init(spec, 0.0, 0.0)
    out = np.empty((nsteps // every + 2, 5))
    g = p.g
    rec = _run_fd(n, pipe.young_modulus * pipe.area / dz, pipe.shear_modulus * pipe.polar_moment
                  / dz, m_node, i_node, p.bit_mass, p.bit_inertia, p.alpha_axial,
                  p.alpha_torsional, (p.string_mass + p.bit_mass) * g, p.bit_mass * g,
                  p.bit_mass * g, model.bit.kernel_params(), depth_of_cut == "approximate", ua, ut,
                  surf, istate, rp, nsteps, dt, every, out)
    out = out[:rec]
    return {"time": out[:, 0], "bit_axial_velocity": out[:, 1], "bit_angular_velocity": out[:, 2],
            "wob": out[:, 3], "tob": out[:, 4]}
