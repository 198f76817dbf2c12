"""Compiled EID controller step (observer, disturbance estimator, filter F(s), internal model,
state feedback, Smith-type predictor) on plain arrays, shared by the fast neutral-model kernel and
the Python :class:`~downhole.control.eid.controller.EIDController`.

Per channel ``i`` (0 axial, 1 torsional) the design model is the scalar NDDE of seed Eq. 3.13,
``x' = a0 x + a1 x(t-h) + g1 x'(t-h) + b (u(t - tau) + d_e)`` with h = 2 tau. Arrays:

* ``cp``: parameters, a pair ``(axial, torsional)`` of :class:`EIDChannelParams` (built by name
  in :meth:`EIDController.compiled_params
  <downhole.control.eid.controller.EIDController.compiled_params>`);
* ``cs`` (2, 4): states ``[xhat, z, x_R, x_F]``;
* ``ch`` (2, 6, cap): histories at the step dt of ``[xhat, xhat', z, z', u_f, d_tilde]``;
* ``cpos`` (1,) int64: number of stored samples (the current time is ``t_n``, n = cpos[0]).

One step at ``t_n`` with measurement ``y`` and reference ``r``::

    x_p   = z + xhat - z(t - tau)          (predictor on; else x_p = xhat)
    u_f   = kp x_p + kr x_R                 (internal model x_R' = br (r - x_p))
    u     = u_f - d_tilde,  d_tilde = x_F   (C_F = 1)
    xhat' = a0 xhat + a1 xhat(t-h) + g1 xhat'(t-h) + b u_f(t - tau_o) + l (y - xhat)
    d_hat = l/b (y - xhat) + u_f(t - tau_o) - u(t - tau_o)     (B+ = (B^T B)^-1 B^T = 1/b)
    x_F'  = af x_F + bf d_hat               (F(s) = bf/(s - af), af = -bf for unit DC gain)
    z'    = a0 z + a1 z(t-h) + g1 z'(t-h) + b u_f

where ``tau_o = tau`` for the delayed-input observer (default) and 0 for the printed structure.
The command sent to the plant is ``u + offset`` (offset = M_S g / alpha_A on the axial channel,
Eq. 3.15 corrected). States advance by explicit Euler.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit


class EIDChannelParams(NamedTuple):
    """The compiled EID step's parameters of one channel (symbols of the module docstring).

    Attributes
    ----------
    a0, a1, g1, b : float
        Design-model coefficients (seed Eq. 3.13).
    l : float
        Observer gain.
    kp, kr, br : float
        State-feedback gain, internal-model gain and internal-model input gain.
    af, bf : float
        Filter F(s) = bf / (s - af).
    h_steps, tau_steps : float
        Delays h and tau in steps of dt.
    offset : float
        Added to the command sent to the plant (plant units).
    predictor : bool
        Smith-type predictor on.
    observer_delay : bool
        Delayed-input observer (``tau_o = tau``) rather than the printed structure.
    u_min, u_max : float
        Command limits (plant units).
    """

    a0: float
    a1: float
    g1: float
    b: float
    l: float
    kp: float
    kr: float
    br: float
    af: float
    bf: float
    h_steps: float
    tau_steps: float
    offset: float
    predictor: bool
    observer_delay: bool
    u_min: float
    u_max: float

NSIG = 4  # recorded per channel: u (plant units, incl. offset), d_tilde, x_p, x_R


@njit(cache=True)
def _hist(ch, i, row, n, lag, cap):
    q = n - lag
    k0 = int(math.floor(q))
    f = q - k0
    v0 = 0.0 if k0 < 0 else ch[i, row, k0 % cap]
    v1 = 0.0 if k0 + 1 < 0 else ch[i, row, (k0 + 1) % cap]
    return (1.0 - f) * v0 + f * v1


@njit(cache=True)
def eid_step(cp, cs, ch, cpos, y, r, dt, uout, sig):
    """Advance the EID controller one step; writes the plant commands into ``uout[0:2]`` and
    ``[u, d_tilde, x_p, x_R]`` per channel into ``sig`` (2, 4)."""
    cap = ch.shape[2]
    n = cpos[0]
    for i in range(2):
        c = cp[i]
        a0 = c.a0
        a1 = c.a1
        g1 = c.g1
        b = c.b
        l = c.l
        kp = c.kp
        kr = c.kr
        br = c.br
        af = c.af
        bf = c.bf
        dh = c.h_steps
        dtau = c.tau_steps
        xhat = cs[i, 0]
        z = cs[i, 1]
        xr = cs[i, 2]
        xf = cs[i, 3]
        if c.predictor:
            xp = z + xhat - _hist(ch, i, 2, n, dtau, cap)
        else:
            xp = xhat
        uf = kp * xp + kr * xr
        dtil = xf
        u = uf - dtil
        # saturation of the command (plant units) feeds back into the estimator via u
        ucmd = u + c.offset
        if ucmd < c.u_min:
            ucmd = c.u_min
        elif ucmd > c.u_max:
            ucmd = c.u_max
        u = ucmd - c.offset
        dtil = uf - u
        if c.observer_delay:
            uf_o = _hist(ch, i, 4, n, dtau, cap)
            dtil_o = _hist(ch, i, 5, n, dtau, cap)
        else:
            uf_o = uf
            dtil_o = dtil
        e = y[i] - xhat
        dxhat = (a0 * xhat + a1 * _hist(ch, i, 0, n, dh, cap) + g1 * _hist(ch, i, 1, n, dh, cap)
                 + b * uf_o + l * e)
        dhat = l / b * e + dtil_o
        dxf = af * xf + bf * dhat
        dz = a0 * z + a1 * _hist(ch, i, 2, n, dh, cap) + g1 * _hist(ch, i, 3, n, dh, cap) + b * uf
        dxr = br * (r[i] - xp)
        k = n % cap
        ch[i, 0, k] = xhat
        ch[i, 1, k] = dxhat
        ch[i, 2, k] = z
        ch[i, 3, k] = dz
        ch[i, 4, k] = uf
        ch[i, 5, k] = dtil
        cs[i, 0] = xhat + dt * dxhat
        cs[i, 1] = z + dt * dz
        cs[i, 2] = xr + dt * dxr
        cs[i, 3] = xf + dt * dxf
        uout[i] = ucmd
        sig[i, 0] = ucmd
        sig[i, 1] = dtil
        sig[i, 2] = xp
        sig[i, 3] = xr
    cpos[0] = n + 1


def eid_arrays(cp):
    """Fresh ``(cs, ch, cpos)`` for parameters ``cp`` (all states and histories zero)."""
    cap = int(math.ceil(max(cp[0].h_steps, cp[1].h_steps, cp[0].tau_steps,
                            cp[1].tau_steps))) + 3
    return np.zeros((2, 4)), np.zeros((2, 6, cap)), np.zeros(1, dtype=np.int64)
