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

__all__ = [
    "PREDICTION_STEP",
    "DamperParams",
    "coupled_axial_reference",
    "damper_arrays",
    "damper_step",
]


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
    k_c : float
        Depth-of-cut coupling of the axial reference (0: off): the axial reference becomes
        ``r_a (1 + k_c (omega / r_w - 1))`` with the measured bit angular velocity ``omega``
        (:func:`coupled_axial_reference`); at k_c = 1 the loop asks for a constant depth of cut
        2 pi r_a / r_w per revolution instead of a constant rate of penetration.
    angle_doc : bool
        The axial prediction's depth of cut from the measured bit *angle* (the surface the
        blade ahead left when the bit was at theta - 2 pi/n, Eq. 2.10, with the angle advanced
        at the current rotary speed over the horizon) instead of the time delay 2 pi/(n omega)
        at the current speed. The time delay errs by d/omega per rad/s of speed deviation
        (dWOB/domega = -k_w d/omega, 1.9e4 N per rad/s at 5 rad/s, 14 mm/s with Table 3.1),
        which is what the depth-of-cut coupling feeds back.
    filter_a : float
        Bandwidth (rad/s) of a first-order low-pass filter on the axial damping command (0:
        none). At high gain (k_d = 4) the discretized prediction loop oscillates near the
        Nyquist frequency without one.
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
    k_c: float = 0.0
    angle_doc: bool = False
    filter_a: float = 0.0


@njit(cache=True)
def _predict(dh, n, cap, dp, bp, omega, xbuf, ntn):
    """Predicted bit axial velocity at t_n + tau_steps dt from the histories ``dh`` (ring
    buffers of ``cap`` samples, index k % cap, rows :data:`_V`, :data:`_DV`, :data:`_W`,
    :data:`_X`, :data:`_U`, :data:`_TH`), by Euler steps of ``stride`` samples (a divisor of
    ``tau_steps``), implicit in the velocity terms (the wear-flat force's velocity dependence is
    stiff near v = 0); ``xbuf`` holds the predicted X at those steps. The depth of cut at step i
    is n (X - X_b) with X_b the bit position when the blade ahead passed the same point:

    * ``dp.angle_doc``: by angle, the bit angle at step i being theta_n + omega i h; X_b from the
      measured angle history (:func:`_surface_at`) or, for angles reached within the horizon,
      from ``xbuf``;
    * otherwise by the time delay ``ntn`` steps (2 pi/(n omega) at the current speed)."""
    nt = dp.tau_steps
    nh = dp.h_steps
    stride = dp.stride
    nbl = dp.n_blades
    a0, a1, g1, b, m_b = dp.a0, dp.a1, dp.g1, dp.b, dp.bit_mass
    by_angle = dp.angle_doc
    vh, dvh, wh, xh, uh, thh = dh[_V], dh[_DV], dh[_W], dh[_X], dh[_U], dh[_TH]
    pitch = 2.0 * math.pi / nbl
    k0 = n % cap
    v = vh[k0]
    x = xh[k0]
    th_n = thh[k0]
    nsub = nt // stride
    h = dp.dt * stride
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
        target = 0.0
        kb = 0
        if by_angle:
            target = th_n + omega * i * h - pitch
            inside = target > th_n
            q = (target - th_n) / (omega * h)
        else:
            kb = k - ntn
            inside = kb >= n
            q = (kb - n) / stride
        if inside:
            i0 = int(q)
            f = q - i0
            xb = xbuf[i0] if i0 + 1 > i else (1.0 - f) * xbuf[i0] + f * xbuf[i0 + 1]
        elif by_angle:
            xb = _surface_at(thh, xh, n, cap, target)
        elif kb >= 0:
            xb = xh[kb % cap]
        else:
            xb = 0.0
        d = nbl * (x - xb)
        d = max(d, 0.0)
        sl = bit_forces_and_slopes(d, v, omega, bp)
        dv = a0 * v + a1 * vd + g1 * dvd + b * ud - (sl[0] - g1 * wd) / m_b
        x += h * v
        # the velocity dependence of the wear-flat force is stiff near v = 0: implicit in v
        v += h * dv / (1.0 + h * (max(sl[3], 0.0) / m_b - a0))
    return v


@njit(cache=True)
def coupled_axial_reference(k_c, r_a, r_w, w):
    """The axial reference with the depth-of-cut coupling ``k_c`` (:class:`DamperParams`):
    ``r_a (1 + k_c (w / r_w - 1))`` clipped to [0, 2 r_a]; ``r_a`` itself when ``k_c`` is 0,
    ``r_a`` or ``r_w`` is not positive. At a given rate of penetration the torque on bit grows as
    1/omega (the depth of cut is 2 pi rop/omega): a slowing bit cuts deeper and is slowed further,
    a negative damping -T/omega that at low rotary speed and high rate of penetration exceeds the
    string's (docs/neutral-eid.md, "Envelope"). With the reference scaled by the measured rotary
    speed the depth of cut, and with it the torque on bit, no longer grows when the bit slows;
    at the set point (w = r_w) the reference is unchanged."""
    if k_c == 0.0 or r_a <= 0.0 or r_w <= 0.0:
        return r_a
    f = 1.0 + k_c * (w / r_w - 1.0)
    if f < 0.0:
        f = 0.0
    elif f > 2.0:
        f = 2.0
    return r_a * f


#: Target step of the prediction's Euler integration, s (the largest whole number of control
#: steps up to it that divides the prediction horizon).
PREDICTION_STEP = 1e-3


@njit(cache=True)
def damper_step(dp, dh, ds, xbuf, bp, v, w, r_a, u_eid):
    """One step of the predictive damper at t_n (n = ds[1]) with measured bit velocities ``v``,
    ``w``, axial reference ``r_a`` and the EID's axial command ``u_eid`` (relative to the hanging
    equilibrium). Stores the histories ``dh`` (rows :data:`_V` .. :data:`_TH`: v, v', W, X, u,
    theta) and returns ``du``."""
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
    om = max(om, 0.5)
    ntn = int(round(2.0 * math.pi / (nbl * om) / dt))
    ntn = max(ntn, 1)
    du = 0.0
    known = True
    if dp.angle_doc:
        th = ds[2]
        dh[_TH, k] = th
        ds[2] = th + dt * w
        xb = _surface_at(dh[_TH], dh[_X], n, cap, th - 2.0 * math.pi / nbl)
    elif ntn < cap:
        xb = dh[3, (n - ntn) % cap] if n - ntn >= 0 else 0.0
    else:
        known = False
        xb = 0.0
    if known:
        d = nbl * (x - xb)
        d = max(d, 0.0)
        wob, _ = bit_forces(d, v, om, bp)
        dh[2, k] = wob
        if dp.k_d > 0.0:
            du = -dp.k_d * (_predict(dh, n, cap, dp, bp, om, xbuf, ntn) - r_a)
            if dp.filter_a > 0.0:
                du = ds[3] + (1.0 - math.exp(-dp.filter_a * dt)) * (du - ds[3])
                ds[3] = du
    else:
        dh[2, k] = 0.0
    dh[4, k] = u_eid + du
    ds[0] = x + dt * v
    ds[1] = n + 1
    return du


#: Rows of the damper's history array ``dh``: bit axial velocity v, v', WOB, bit position X,
#: axial command u, bit angle theta.
_V, _DV, _W, _X, _U, _TH = range(6)


@njit(cache=True)
def _surface_at(th_row, x_row, n, cap, target):
    """Bit position X at the past time when the measured bit angle was ``target`` (the surface
    the blade ahead left, Eq. 2.10), by bisection on the stored angles (monotone while the bit
    turns forward) and linear interpolation; 0 before the start; the oldest stored X if the
    angle is older than the history."""
    lo = n - cap + 1
    lo = max(lo, 0)
    if th_row[lo % cap] > target:
        return 0.0 if lo == 0 else x_row[lo % cap]
    hi = n
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if th_row[mid % cap] <= target:
            lo = mid
        else:
            hi = mid
    t0 = th_row[lo % cap]
    t1 = th_row[hi % cap]
    if t1 > t0:
        f = (target - t0) / (t1 - t0)
        f = min(f, 1.0)
        return (1.0 - f) * x_row[lo % cap] + f * x_row[hi % cap]
    return x_row[lo % cap]


def _stride(nt: int, target: float) -> int:
    """Largest divisor of ``nt`` not above ``target`` (the prediction's Euler steps then end
    exactly at t + tau)."""
    return max(k for k in range(1, max(1, int(round(target))) + 1) if nt % k == 0)


def damper_arrays(dp: DamperParams):
    """Fresh ``(dh, ds, xbuf)`` (histories, state [X, n, theta, filtered du], prediction buffer)
    for parameters ``dp``."""
    cap = dp.tau_steps + dp.h_steps + 8
    return np.zeros((6, cap)), np.zeros(4), np.zeros(dp.tau_steps // dp.stride + 2)
