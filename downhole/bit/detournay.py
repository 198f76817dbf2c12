"""Compiled PDC bit/rock law (Detournay cutting + wear-flat friction), seed Eqs. 2.2-2.8.

Corrections from SPEC.md applied here (see docs/seed-errata.md): cutting torque vanishes for
omega <= 0 (smooth ramp of width ``omega_reg``); wear-flat force saturates continuously at d*
(default); the Stribeck law acts on |omega|.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from downhole.params.bit import BitParams

__all__ = ["bit_forces", "bit_forces_py", "approx_depth_of_cut", "bit_force_slopes"]

# indices into the packed parameter array (BIT_ARRAY_LAYOUT)
_EPS, _SIG, _ZETA, _A, _N, _L, _DSTAR, _KC = 0, 1, 2, 3, 4, 5, 6, 7
_MUC, _MUS, _GAM, _GAMB, _VF, _MUGAM, _A1, _B1, _A2, _B2 = 8, 9, 10, 11, 12, 13, 14, 15, 16, 17
_CONT, _STRIB, _OMREG, _OMFLOOR = 18, 19, 20, 21


@njit(cache=True, inline="always")
def bit_forces(d, v, omega, p):
    """Weight and torque on bit for total depth of cut ``d`` (m), axial velocity ``v`` (m/s,
    positive into the rock) and angular velocity ``omega`` (rad/s). Returns ``(wob, tob)``."""
    if d <= 0.0:
        return 0.0, 0.0
    eps = p[_EPS]
    a = p[_A]
    wob_c = p[_ZETA] * eps * a * d
    # cutting torque only while the bit turns forward (ramp over [0, omega_reg])
    s = omega / p[_OMREG]
    if s < 0.0:
        s = 0.0
    elif s > 1.0:
        s = 1.0
    tob_c = 0.5 * eps * a * a * d * s
    # wear-flat contact force
    arg = p[_A1] * v + p[_B1]
    if arg > 50.0:
        fv = 0.0
    else:
        fv = 1.0 / (1.0 + math.exp(arg))
    full = p[_SIG] * p[_L] * a
    if p[_CONT] > 0.5:
        r = d / p[_DSTAR]
        if r > 1.0:
            r = 1.0
        wob_f = full * r * fv
    else:
        if d > p[_DSTAR]:
            wob_f = full * fv
        else:
            wob_f = p[_KC] * d
    # wear-flat friction torque
    if p[_STRIB] > 0.5:
        mu = p[_MUC] + (p[_MUS] - p[_MUC]) * math.exp(-p[_GAMB] / p[_VF] * abs(omega))
        mugam = mu * p[_GAM]
    else:
        mugam = p[_MUGAM]
    g = math.tanh(p[_A2] * omega + p[_B2])
    tob_f = 0.5 * mugam * a * g * wob_f
    return wob_c + wob_f, tob_c + tob_f


@njit(cache=True, inline="always")
def approx_depth_of_cut(v, omega, p):
    """Approximated total depth of cut d = 2 pi v / max(omega, omega*) (Eqs. 2.11, 4.16), m."""
    w = omega
    if w < p[_OMFLOOR]:
        w = p[_OMFLOOR]
    return 2.0 * math.pi * v / w


@njit(cache=True)
def bit_force_slopes(d, v, omega, p, approx):
    """Non-negative effective dampers -dWOB/dv and -dTOB/domega (finite differences).

    Used by the implicit integrators to apply the stiff regularised friction laws implicitly
    (frozen coefficients). With ``approx`` true the depth of cut follows v and omega."""
    hv = 1e-7 + 1e-4 * abs(v)
    hw = 1e-6 + 1e-4 * abs(omega)
    if approx:
        w1, _ = bit_forces(approx_depth_of_cut(v + hv, omega, p), v + hv, omega, p)
        w0, _ = bit_forces(approx_depth_of_cut(v - hv, omega, p), v - hv, omega, p)
        _, t1 = bit_forces(approx_depth_of_cut(v, omega + hw, p), v, omega + hw, p)
        _, t0 = bit_forces(approx_depth_of_cut(v, omega - hw, p), v, omega - hw, p)
    else:
        w1, _ = bit_forces(d, v + hv, omega, p)
        w0, _ = bit_forces(d, v - hv, omega, p)
        _, t1 = bit_forces(d, v, omega + hw, p)
        _, t0 = bit_forces(d, v, omega - hw, p)
    ca = (w1 - w0) / (2.0 * hv)
    ct = (t1 - t0) / (2.0 * hw)
    return max(ca, 0.0), max(ct, 0.0)


def bit_forces_py(d, v, omega, bit: BitParams) -> tuple[float, float]:
    """Convenience wrapper: ``(wob, tob)`` in N and N m for a :class:`BitParams`."""
    return bit_forces(float(d), float(v), float(omega), bit.to_array())


def bit_forces_vec(d, v, omega, bit: BitParams):
    """Vectorised wrapper over NumPy arrays (for plots and analysis)."""
    p = bit.to_array()
    d, v, omega = np.broadcast_arrays(np.asarray(d, float), np.asarray(v, float),
                                      np.asarray(omega, float))
    wob = np.empty(d.shape)
    tob = np.empty(d.shape)
    for i in np.ndindex(d.shape):
        wob[i], tob[i] = bit_forces(d[i], v[i], omega[i], p)
    return wob, tob
