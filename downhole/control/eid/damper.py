"""The predictive bit damper's compiled step (:class:`~downhole.control.eid.predictor.
PredictiveEID`, whose module docstring derives it): the bit-velocity prediction over one axial
wave delay and the damping command. Its own module so that the one compiled EID loop
(:mod:`downhole.control.eid.neutral_runner`) and the controller both use it without an import
cycle."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from downhole.bit.law import bit_forces, bit_forces_and_slopes

__all__ = ["DamperParams", "damper_step", "damper_arrays", "PREDICTION_STEP"]


@njit(cache=True)
def _predict(vh, dvh, wh, xh, uh, n, cap, dt, nt, nh, ntn, a0, a1, g1, b, m_b, nbl, omega, bp,
             xbuf, stride):
    """Predicted bit axial velocity at t_n + nt dt from the histories (ring buffers of ``cap``
    samples, index k % cap) of v, v', W, X and u, by Euler steps of ``stride`` samples (a
    divisor of ``nt``) (implicit in
    the velocity terms: the wear-flat force's velocity dependence is stiff near v = 0);
    ``xbuf`` holds the predicted X at those steps."""
    v = vh[n % cap]
    x = xh[n % cap]
    nsub = nt // stride
    h = dt * stride
    for i in range(nsub + 1):
        xbuf[i] = x
        if i == nsub:
            break
        k = n + i * stride
        kh = k - nh
        vd = vh[kh % cap] if kh >= 0 else 0.0
        dvd = dvh[kh % cap] if kh >= 0 else 0.0
        wd = wh[kh % cap] if kh >= 0 else 0.0
        ku = k - nt
        ud = uh[ku % cap] if ku >= 0 else 0.0
        kb = k - ntn
        if kb >= n:
            q = (kb - n) / stride
            i0 = int(q)
            f = q - i0
            xb = xbuf[i0] if i0 + 1 > i else (1.0 - f) * xbuf[i0] + f * xbuf[i0 + 1]
        elif kb >= 0:
            xb = xh[kb % cap]
        else:
            xb = 0.0
        d = nbl * (x - xb)
        if d < 0.0:
            d = 0.0
        sl = bit_forces_and_slopes(d, v, omega, bp)
        dv = a0 * v + a1 * vd + g1 * dvd + b * ud - (sl[0] - g1 * wd) / m_b
        x += h * v
        # the velocity dependence of the wear-flat force is stiff near v = 0: implicit in v
        v += h * dv / (1.0 + h * (max(sl[3], 0.0) / m_b - a0))
    return v


class DamperParams(NamedTuple):
    """The compiled damper's parameters (built by :meth:`PredictiveEID.damper_params`).

    Attributes
    ----------
    k_d : float
        Damping gain on the predicted bit-velocity error, N s/m (0: off).
    tau_steps, h_steps : int
        The axial channel's delays tau and h in steps of ``dt``.
    a0, a1, g1, b : float
        The axial design-model coefficients (seed Eq. 3.13).
    bit_mass : float
        Bit (BHA) mass, kg.
    n_blades : float
        Blades of the bit (depth of cut per revolution).
    dt : float
        Control step, s.
    stride : int
        Control steps per Euler step of the prediction.
    """

    k_d: float
    tau_steps: int
    h_steps: int
    a0: float
    a1: float
    g1: float
    b: float
    bit_mass: float
    n_blades: float
    dt: float
    stride: int

#: Target step of the prediction's Euler integration, s (the largest whole number of control
#: steps up to it that divides the prediction horizon).
PREDICTION_STEP = 1e-3


@njit(cache=True)
def damper_step(dp, dh, ds, xbuf, bp, v, w, r_a, u_eid):
    """One step of the predictive damper at t_n (n = ds[1]) with measured bit velocities ``v``,
    ``w``, axial reference ``r_a`` and the EID's axial command ``u_eid`` (relative to the hanging
    equilibrium). Stores the histories ``dh`` (5, cap: v, v', W, X, u) and returns ``du``."""
    cap = dh.shape[1]
    n = int(ds[1])
    dt = dp.dt
    nbl = dp.n_blades
    x = ds[0]
    k = n % cap
    dh[0, k] = v
    dh[3, k] = x
    if n > 0:
        dh[1, (n - 1) % cap] = (v - dh[0, (n - 1) % cap]) / dt
    om = abs(w)
    if om < 0.5:
        om = 0.5
    ntn = int(round(2.0 * math.pi / (nbl * om) / dt))
    if ntn < 1:
        ntn = 1
    du = 0.0
    if ntn < cap:
        xb = dh[3, (n - ntn) % cap] if n - ntn >= 0 else 0.0
        d = nbl * (x - xb)
        if d < 0.0:
            d = 0.0
        wob, _ = bit_forces(d, v, om, bp)
        dh[2, k] = wob
        if dp.k_d > 0.0:
            vp = _predict(dh[0], dh[1], dh[2], dh[3], dh[4], n, cap, dt, dp.tau_steps,
                          dp.h_steps, ntn, dp.a0, dp.a1, dp.g1, dp.b, dp.bit_mass, nbl, om, bp,
                          xbuf, dp.stride)
            du = -dp.k_d * (vp - r_a)
    else:
        dh[2, k] = 0.0
    dh[4, k] = u_eid + du
    ds[0] = x + dt * v
    ds[1] = n + 1
    return du


def _stride(nt: int, target: float) -> int:
    """Largest divisor of ``nt`` not above ``target`` (the prediction's Euler steps then end
    exactly at t + tau)."""
    return max(k for k in range(1, max(1, int(round(target))) + 1) if nt % k == 0)



def damper_arrays(dp: DamperParams):
    """Fresh ``(dh, ds, xbuf)`` (histories, state, prediction buffer) for parameters ``dp``."""
    cap = dp.tau_steps + dp.h_steps + 8
    return np.zeros((5, cap)), np.zeros(2), np.zeros(dp.tau_steps // dp.stride + 2)
