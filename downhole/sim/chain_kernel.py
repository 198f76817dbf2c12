"""Compiled fixed-step kernel for lumped chain models with the bit law at the last DOF.

Two integrators: explicit Euler (the seed's scheme) and the trapezoidal rule (Newmark average
acceleration) with a tridiagonal solve per field, the stiff regularised bit friction applied as a
frozen-coefficient implicit damper. Depth of cut: delayed (rock-surface memory) or approximated.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from downhole.bit.law import approx_depth_of_cut, bit_force_slopes, bit_forces
from downhole.bit.rock_surface import rock_advance, rock_depth

__all__ = ["CHANNELS", "run_chain"]

CHANNELS = ("time", "bit_axial_position", "bit_axial_velocity", "bit_angle",
            "bit_angular_velocity", "depth_of_cut", "wob", "tob", "hook_load", "surface_torque",
            "top_drive_axial_velocity", "top_drive_angular_velocity")
NCH = len(CHANNELS)


@njit(cache=True, inline="always")
def _forces(mass, k_link, c_link, c_abs, k_top, c_top, gravity, q, v, f, n, in_pos, in_vel,
            force_mode, out):
    """Linear + top forces on field f: out = gravity - K q - C v + top terms."""
    for i in range(n):
        out[i] = gravity[f, i] - c_abs[f, i] * v[f, i]
    for i in range(n - 1):
        fl = k_link[f, i] * (q[f, i + 1] - q[f, i]) + c_link[f, i] * (v[f, i + 1] - v[f, i])
        out[i] += fl
        out[i + 1] -= fl
    if force_mode:
        out[0] += in_pos
    else:
        out[0] += k_top[f] * (in_pos - q[f, 0]) + c_top[f] * (in_vel - v[f, 0])


@njit(cache=True)
def _thomas(a, b, c, d, n, x):
    """Solve the tridiagonal system (sub a[1:], diag b, super c[:-1]) in place into x."""
    cp = np.empty(n)
    dp = np.empty(n)
    cp[0] = c[0] / b[0]
    dp[0] = d[0] / b[0]
    for i in range(1, n):
        m = b[i] - a[i] * cp[i - 1]
        cp[i] = c[i] / m if i < n - 1 else 0.0
        dp[i] = (d[i] - a[i] * dp[i - 1]) / m
    x[n - 1] = dp[n - 1]
    for i in range(n - 2, -1, -1):
        x[i] = dp[i] - cp[i] * x[i + 1]


@njit(cache=True)
def run_chain(mass, k_link, c_link, c_abs, k_top, c_top, gravity, bitp, q, v, force_mode,
              in_pos, in_vel, weight, k0, nsteps, dt, integrator, approx, surf, istate, rp,
              record_every, out, rec0):
    """Advance ``nsteps`` steps from step index ``k0``; state ``q, v`` (2, n) updated in place.

    ``in_pos``/``in_vel`` (2, nsteps + 1) hold the top inputs at each step (positions and
    velocities, or forces in ``in_pos`` when ``force_mode``). Rows ``rec0, rec0+1, ...`` of
    ``out`` receive the channels of :data:`CHANNELS` at every ``record_every``-th step (state at
    the start of the step, plus the final state). Returns ``(status, step, channel)``: status 0
    ok, 1 non-finite value (the step and channel index where it appeared). ``out`` rows written:
    the caller counts them as ``nsteps // record_every + 1``.
    """
    n = q.shape[1]
    nb = n - 1
    fbuf = np.empty(n)
    fbuf1 = np.empty(n)
    lo = np.empty(n)
    di = np.empty(n)
    up = np.empty(n)
    rhs = np.empty(n)
    vnew = np.empty(n)
    rec = rec0
    for k in range(nsteps + 1):
        xb = q[0, nb]
        vb = v[0, nb]
        thb = q[1, nb]
        wb = v[1, nb]
        # runaway guard: a diverging run stops here, before the grid-indexed rock memory sees
        # angles it cannot index (reported like a non-finite value)
        if not (abs(xb) < 1e9 and abs(vb) < 1e9):
            return 1, k0 + k, 1 if abs(xb) >= 1e9 or not math.isfinite(xb) else 2
        if not (abs(thb) < 1e12 and abs(wb) < 1e12):
            return 1, k0 + k, 3 if abs(thb) >= 1e12 or not math.isfinite(thb) else 4
        if approx:
            d = approx_depth_of_cut(vb, wb, bitp)
        else:
            d = rock_depth(surf, istate, rp, xb, thb)
        wob, tob = bit_forces(d, vb, wb, bitp)
        if k % record_every == 0 or k == nsteps:
            if force_mode:
                hook = weight - in_pos[0, k]
                torque = in_pos[1, k]
                tdv = v[0, 0]
                tdw = v[1, 0]
            else:
                hook = weight - (k_top[0] * (in_pos[0, k] - q[0, 0])
                                 + c_top[0] * (in_vel[0, k] - v[0, 0]))
                torque = k_top[1] * (in_pos[1, k] - q[1, 0]) + c_top[1] * (in_vel[1, k] - v[1, 0])
                tdv = in_vel[0, k]
                tdw = in_vel[1, k]
            out[rec, 0] = (k0 + k) * dt
            out[rec, 1] = xb
            out[rec, 2] = vb
            out[rec, 3] = thb
            out[rec, 4] = wb
            out[rec, 5] = d
            out[rec, 6] = wob
            out[rec, 7] = tob
            out[rec, 8] = hook
            out[rec, 9] = torque
            out[rec, 10] = tdv
            out[rec, 11] = tdw
            for c in range(1, NCH):
                if not math.isfinite(out[rec, c]):
                    return 1, k0 + k, c
            rec += 1
        if k == nsteps:
            break
        xprev = xb
        thprev = thb
        if integrator == 0:
            # explicit Euler (seed Eq. 2.12)
            for f in range(2):
                _forces(mass, k_link, c_link, c_abs, k_top, c_top, gravity, q, v, f, n,
                        in_pos[f, k], in_vel[f, k], force_mode, fbuf)
                fbuf[nb] -= wob if f == 0 else tob
                for i in range(n):
                    q[f, i] += dt * v[f, i]
                    v[f, i] += dt * fbuf[i] / mass[f, i]
        else:
            ca, ct = bit_force_slopes(d, vb, wb, bitp, approx)
            for f in range(2):
                cnl = ca if f == 0 else ct
                # forces at n (linear + top) and the top terms at n+1 (known inputs)
                _forces(mass, k_link, c_link, c_abs, k_top, c_top, gravity, q, v, f, n,
                        in_pos[f, k], in_vel[f, k], force_mode, fbuf)
                # tridiagonal S = M/dt + C/2 + dt/4 K (+ implicit bit damper)
                for i in range(n):
                    di[i] = mass[f, i] / dt + 0.5 * c_abs[f, i]
                    lo[i] = 0.0
                    up[i] = 0.0
                for i in range(n - 1):
                    s = 0.5 * c_link[f, i] + 0.25 * dt * k_link[f, i]
                    di[i] += s
                    di[i + 1] += s
                    up[i] = -s
                    lo[i + 1] = -s
                if not force_mode:
                    di[0] += 0.5 * c_top[f] + 0.25 * dt * k_top[f]
                di[nb] += cnl
                # rhs = M v/dt + (F_n + F_{n+1})/2 expressed with K q_{n+1} = K(q + dt/2 (v + v1))
                for i in range(n):
                    rhs[i] = mass[f, i] * v[f, i] / dt + 0.5 * fbuf[i]
                # second half: F_{n+1} = gravity + top(n+1) - K(q + dt/2 v) - (dt/2 K + C) v1
                # -> known part gravity + top_known(n+1) - K(q + dt/2 v)
                for i in range(n):
                    fbuf1[i] = gravity[f, i]
                for i in range(n - 1):
                    dq = (q[f, i + 1] + 0.5 * dt * v[f, i + 1]) - (q[f, i] + 0.5 * dt * v[f, i])
                    fl = k_link[f, i] * dq
                    fbuf1[i] += fl
                    fbuf1[i + 1] -= fl
                if force_mode:
                    fbuf1[0] += in_pos[f, k + 1]
                else:
                    fbuf1[0] += k_top[f] * (in_pos[f, k + 1] - (q[f, 0] + 0.5 * dt * v[f, 0])) \
                        + c_top[f] * in_vel[f, k + 1]
                for i in range(n):
                    rhs[i] += 0.5 * fbuf1[i]
                rhs[nb] += -(wob if f == 0 else tob) + cnl * v[f, nb]
                _thomas(lo, di, up, rhs, n, vnew)
                for i in range(n):
                    q[f, i] += 0.5 * dt * (v[f, i] + vnew[i])
                    v[f, i] = vnew[i]
        if not approx:
            rock_advance(surf, istate, rp, thprev, xprev, q[1, nb], q[0, nb])
    return 0, k0 + nsteps, 0
