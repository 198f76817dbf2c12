"""Compiled implicit Newmark kernels for the directional FEM and hybrid FEM + wave-segment models.

One kernel, :func:`run_directional`, advances both models: nodes form one or two chains of 2-node
axial-torsional bar elements (tridiagonal mass, stiffness and Rayleigh damping per field; a zero
off-diagonal separates the top chain AB from the bottom chain CD of the hybrid model), optionally
joined by a lossless wave segment between node B (last of AB) and node C (first of CD).

Time stepping is Newmark's average-acceleration scheme in velocity form::

    (M + dt/2 C + dt^2/4 K) v1 = M (v0 + dt/2 a0) - dt/2 K (u0 + dt/2 v0) + dt/2 F1

solved per field with the Thomas algorithm (or a dense solve with modal damping). The
nonlinear forces enter F1 as frozen-coefficient implicit terms ``f0 - c v1 - k (u1 - u0)``:
wellbore friction (c = mu N / sqrt(v^2 + (r omega)^2 + v_eps^2)), the bit law (c = -dWOB/dv,
k = dWOB/dx from the depth of cut), the top-drive PI (c = Kp, k = Ki), the hook servo and the
wave segment's end impedances (c = Z). All of these are dissipative or linear, so the step is
stable at dt = 1e-3 with any regularization width.

Everything here takes plain arrays; :mod:`downhole.string.fem` and :mod:`downhole.string.hybrid`
build them.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from downhole.bit.detournay import approx_depth_of_cut, bit_forces
from downhole.bit.rock_surface import rock_advance, rock_depth
from downhole.contact.softstring import normal_force_per_length
from downhole.string.wave import wave_incoming, wave_push

__all__ = ["CHANNELS", "TOP_LAYOUT", "MISC_LAYOUT", "run_directional", "thomas_solve"]

#: Recorded channels, in order.
CHANNELS = (
    "bit_axial_position", "bit_axial_velocity", "bit_angle", "bit_angular_velocity",
    "depth_of_cut", "wob", "tob", "hook_load", "surface_torque", "top_drive_axial_velocity",
    "top_drive_angular_velocity", "force_b", "torque_b", "force_c", "torque_c",
    "top_drive_angle", "reference_angular_velocity",
)

#: Layout of the ``top`` parameter array.
TOP_LAYOUT = ("axial_mode", "hook_k", "hook_c", "hook_load0", "torsional_mode", "kp", "ki",
              "soft_gain", "soft_tau", "mu", "v_eps", "approx_doc", "bit_node", "node_b",
              "node_c", "hybrid", "dense", "n_lags_a", "lag_tau_a", "n_lags_t", "lag_tau_t",
              "fb0", "fc0", "max_torque")
_AXM, _HK, _HC, _H0, _TQM, _KP, _KI, _SG, _ST, _MU, _VEPS, _APPROX, _IBIT, _IB, _IC, _HYB, \
    _DENSE, _NLA, _LTA, _NLT, _LTT, _FB0, _FC0, _TMAX = range(24)

#: Layout of the ``misc`` state array.
MISC_LAYOUT = ("time", "x_ref", "theta_ref", "soft_lowpass", "ubit0", "step")


@njit(cache=True)
def thomas_solve(d, o, rhs, out, work):
    """Solve the symmetric tridiagonal system (diag ``d``, off-diagonal ``o``) into ``out``."""
    n = d.size
    c = work
    b0 = d[0]
    c[0] = o[0] / b0 if n > 1 else 0.0
    out[0] = rhs[0] / b0
    for i in range(1, n):
        den = d[i] - o[i - 1] * c[i - 1]
        if i < n - 1:
            c[i] = o[i] / den
        out[i] = (rhs[i] - o[i - 1] * out[i - 1]) / den
    for i in range(n - 2, -1, -1):
        out[i] -= c[i] * out[i + 1]


@njit(cache=True)
def _tri_mv(d, o, x, i):
    """(T x)_i for a symmetric tridiagonal T."""
    s = d[i] * x[i]
    if i > 0:
        s += o[i - 1] * x[i - 1]
    if i < x.size - 1:
        s += o[i] * x[i + 1]
    return s


@njit(cache=True)
def _bit_g(field, v, d0, x_rate, vother, bitp, approx, omega_frozen):
    """Bit force on the bit node as a function of its new velocity ``v`` (field 0: axial,
    returns -WOB; field 1: torsional, returns -TOB). ``d0 + x_rate * v`` is the depth of cut."""
    if field == 0:
        if approx:
            d = approx_depth_of_cut(v, omega_frozen, bitp)
        else:
            d = d0 + x_rate * v
        w, _ = bit_forces(d, v, omega_frozen, bitp)
        return -w
    _, t = bit_forces(d0, vother, v, bitp)
    return -t


@njit(cache=True)
def _field_step(Md, Mo, Kd, Ko, Ld, Lo, Ldense, dense, u, v, a, f0, cx, kx, dt, rhs, d, vnew,
                work, bit_field, bd0, brate, bother, bitp, approx, bomega):
    """Advance one field: solve for v1 with extra diagonal damper cx and stiffness kx.

    With ``bit_field`` >= 0 the bit force on the last node is applied exactly implicitly
    (a scalar monotone equation solved after the forward sweep), not linearized."""
    n = u.size
    h = 0.5 * dt
    for i in range(n):
        mv = Md[i] * (v[i] + h * a[i])
        if i > 0:
            mv += Mo[i - 1] * (v[i - 1] + h * a[i - 1])
        if i < n - 1:
            mv += Mo[i] * (v[i + 1] + h * a[i + 1])
        ku = Kd[i] * (u[i] + h * v[i])
        if i > 0:
            ku += Ko[i - 1] * (u[i - 1] + h * v[i - 1])
        if i < n - 1:
            ku += Ko[i] * (u[i + 1] + h * v[i + 1])
        rhs[i] = mv - h * ku + h * (f0[i] - kx[i] * h * v[i])
        d[i] = Ld[i] + h * (cx[i] + kx[i] * h)
    if dense:
        A = Ldense.copy()
        for i in range(n):
            A[i, i] = Ldense[i, i] + (d[i] - Ld[i])
        if bit_field >= 0:
            # linearize the bit force about the old velocity (dense path only)
            g0 = _bit_g(bit_field, v[n - 1], bd0, brate, bother, bitp, approx, bomega)
            hv = 1e-7 + 1e-6 * abs(v[n - 1])
            g1 = _bit_g(bit_field, v[n - 1] + hv, bd0, brate, bother, bitp, approx, bomega)
            slope = (g1 - g0) / hv
            if slope > 0.0:
                slope = 0.0
            rhs[n - 1] += h * (g0 - slope * v[n - 1])
            A[n - 1, n - 1] -= h * slope
        sol = np.linalg.solve(A, rhs)
        for i in range(n):
            vnew[i] = sol[i]
    else:
        # Thomas forward sweep
        c = work
        o = Lo
        den = d[0]
        r = rhs[0]
        for i in range(n):
            if i > 0:
                den = d[i] - o[i - 1] * c[i - 1]
                r = rhs[i] - o[i - 1] * vnew[i - 1]
            if i < n - 1:
                c[i] = o[i] / den
                vnew[i] = r / den
            else:
                if bit_field < 0:
                    vnew[i] = r / den
                else:
                    # den * x - h * g(x) = r, g decreasing in x: monotone, safeguarded Newton
                    x = v[i]
                    xprev = x
                    fprev = 0.0
                    fp = den
                    lo = -1e300
                    hi = 1e300
                    for it in range(60):
                        gx = _bit_g(bit_field, x, bd0, brate, bother, bitp, approx, bomega)
                        fx = den * x - h * gx - r
                        if fx > 0.0:
                            hi = x
                        else:
                            lo = x
                        if it == 0:
                            eps = 1e-9 * (1.0 + abs(x))
                            fp = den - h * (_bit_g(bit_field, x + eps, bd0, brate, bother,
                                                   bitp, approx, bomega) - gx) / eps
                        elif x != xprev:
                            fp = (fx - fprev) / (x - xprev)  # secant: one evaluation per step
                        xprev = x
                        fprev = fx
                        xn = x - fx / fp if fp > 0.0 else x - fx / den
                        if not (lo < xn < hi):
                            if lo > -1e299 and hi < 1e299:
                                xn = 0.5 * (lo + hi)
                            elif xn <= lo:
                                xn = lo + 1.0 + abs(lo)
                            else:
                                xn = hi - 1.0 - abs(hi)
                        if abs(xn - x) < 1e-13 * (1.0 + abs(x)):
                            x = xn
                            break
                        x = xn
                    vnew[i] = x
        for i in range(n - 2, -1, -1):
            vnew[i] -= c[i] * vnew[i + 1]
    for i in range(n):
        an = (vnew[i] - v[i]) / h - a[i]
        u[i] += h * (v[i] + vnew[i])
        v[i] = vnew[i]
        a[i] = an


@njit(cache=True)
def _lag_update(lag, row, n_lags, tau, dt, x):
    """Cascade of first-order lags (exact discretization); returns the last output."""
    if n_lags <= 0:
        return x
    al = 1.0 - math.exp(-dt / tau)
    inp = x
    for j in range(n_lags):
        lag[row, j] += al * (inp - lag[row, j])
        inp = lag[row, j]
    return inp


@njit(cache=True)
def _tension(Ko, u, e):
    """Elastic tension in element e (positive in tension): EA/L (u_{e+1} - u_e)."""
    return -Ko[e] * (u[e + 1] - u[e])


@njit(cache=True)
def _torque(Ko, th, e):
    """Elastic torque in element e: GJ/L (theta_e - theta_{e+1})."""
    return Ko[e] * (th[e + 1] - th[e])


@njit(cache=True)
def run_directional(mats, Ldense, elem, node, top, bitp, state, misc, surf, istate, rp,
                    wa_hist, wa_pos, wa_wp, wt_hist, wt_pos, wt_wp, lag, cmd, n_steps, dt,
                    rec, rec_every, rec_start):
    """Advance ``n_steps`` steps of ``dt``; record every ``rec_every`` steps into ``rec``.

    Parameters (all plain arrays)
    ----------
    mats : (18, n)
        Rows: M_a diag/off, K_a diag/off, L_a diag/off (L = M + dt/2 C + dt^2/4 K), then the
        same for the torsional field, then C_a diag/off and C_t diag/off (for reporting).
    Ldense : (2, n, n)
        Dense L per field when ``top[dense]`` is 1 (modal damping), else ignored.
    elem : (n, 8)
        Per element e (0..n-2): length, dt/ds (3), w g_perp (3), contact flag.
    node : (n, 2)
        Nodal gravity force (N, downward) and torque arm (m).
    top : see :data:`TOP_LAYOUT`.
    bitp : bit parameter array.
    state : (6, n)
        u_a, v_a, a_a, theta, omega, alpha. Updated in place.
    misc : see :data:`MISC_LAYOUT`. Updated in place.
    surf, istate, rp : rock-surface memory.
    wa_*, wt_* : wave-segment states (axial, torsional); ignored unless hybrid.
    lag : (4, m) lag-cascade states (rows: axial b_in, axial a_in, torsional b_in, a_in).
    cmd : (n_steps, 2)
        Per step: axial command (hook load N, or top axial velocity m/s) and torsional command
        (speed set-point rad/s, or top-drive torque N m).
    rec : (n_rec, len(CHANNELS)) output; ``rec_start`` is the first row written.

    Returns
    -------
    status : int
        0 ok, 1 non-finite state.
    rows : int
        Number of rows written.
    """
    n = state.shape[1]
    MAd, MAo, KAd, KAo, LAd, LAo = mats[0], mats[1], mats[2], mats[3], mats[4], mats[5]
    MTd, MTo, KTd, KTo, LTd, LTo = mats[6], mats[7], mats[8], mats[9], mats[10], mats[11]
    ua, va, aa, ut, vt, at = state[0], state[1], state[2], state[3], state[4], state[5]
    ib = int(top[_IBIT])
    iB = int(top[_IB])
    iC = int(top[_IC])
    hybrid = top[_HYB] > 0.5
    dense = top[_DENSE] > 0.5
    approx = top[_APPROX] > 0.5
    mu = top[_MU]
    veps = top[_VEPS]
    h = 0.5 * dt
    fa = np.zeros(n)
    ft = np.zeros(n)
    ca = np.zeros(n)
    ct = np.zeros(n)
    kxa = np.zeros(n)
    kxt = np.zeros(n)
    rhs = np.empty(n)
    dd = np.empty(n)
    vnew = np.empty(n)
    work = np.empty(n)
    nrm = np.zeros(n)
    row = rec_start
    za = wa_wp[0]
    zt = wt_wp[0]
    fb_line = 0.0
    tb_line = 0.0
    fc_line = 0.0
    tc_line = 0.0
    for k in range(n_steps):
        cax = cmd[k, 0]
        ctq = cmd[k, 1]
        # ---- references at t_{n+1}
        surf_torque0 = _torque(KTo, ut, 0) if n > 1 else 0.0
        omega_ref = ctq
        if top[_TQM] < 0.5 and top[_SG] > 0.0:
            misc[3] += (dt / top[_ST]) * (surf_torque0 - misc[3]) if top[_ST] > 0 else 0.0
            omega_ref = ctq - top[_SG] * (surf_torque0 - misc[3])
        misc[2] += dt * omega_ref
        if top[_AXM] > 0.5:
            misc[1] += dt * cax
        for i in range(n):
            fa[i] = node[i, 0]
            ft[i] = 0.0
            ca[i] = 0.0
            ct[i] = 0.0
            kxa[i] = 0.0
            kxt[i] = 0.0
            nrm[i] = 0.0
        # ---- top drive and hook
        if top[_AXM] < 0.5:
            fa[0] -= cax
        else:
            fa[0] += -top[_H0] + top[_HK] * (misc[1] - ua[0]) + top[_HC] * cax
            ca[0] += top[_HC]
            kxa[0] += top[_HK]
        if top[_TQM] < 0.5:
            ft[0] += top[_KP] * omega_ref + top[_KI] * (misc[2] - ut[0])
            ct[0] += top[_KP]
            kxt[0] += top[_KI]
        else:
            ft[0] += ctq
        # ---- wellbore contact (soft string, frozen-coefficient friction)
        if mu > 0.0:
            for e in range(n - 1):
                if elem[e, 7] > 0.5:
                    T = _tension(KAo, ua, e)
                    Nl = normal_force_per_length(T, elem[e, 1], elem[e, 2], elem[e, 3],
                                                 elem[e, 4], elem[e, 5], elem[e, 6])
                    half = 0.5 * elem[e, 0] * Nl
                    nrm[e] += half
                    nrm[e + 1] += half
            for i in range(n):
                if nrm[i] > 0.0:
                    r = node[i, 1]
                    c = mu * nrm[i] / math.sqrt(va[i] * va[i] + r * r * vt[i] * vt[i]
                                                 + veps * veps)
                    ca[i] += c
                    ct[i] += c * r * r
        # ---- bit: depth of cut from the old state; forces applied exactly implicitly
        if approx:
            d0 = approx_depth_of_cut(va[ib], vt[ib], bitp)
        else:
            d0 = rock_depth(surf, istate, rp, ua[ib], ut[ib])
        # axial: d(v1) = d0 + n h (v0 + v1) = (d0 + n h v0) + n h v1
        dax0 = d0 + rp[4] * h * va[ib] if not approx else 0.0
        drate = rp[4] * h if not approx else 0.0
        # ---- wave segment between B and C
        if hybrid:
            a_in, b_in = wave_incoming(wa_hist, wa_pos, wa_wp)
            b_in = _lag_update(lag, 0, int(top[_NLA]), top[_LTA], dt, b_in)
            a_in = _lag_update(lag, 1, int(top[_NLA]), top[_LTA], dt, a_in)
            ta_in, tb_in = wave_incoming(wt_hist, wt_pos, wt_wp)
            tb_in = _lag_update(lag, 2, int(top[_NLT]), top[_LTT], dt, tb_in)
            ta_in = _lag_update(lag, 3, int(top[_NLT]), top[_LTT], dt, ta_in)
            fa[iB] += top[_FB0] + 2.0 * za * b_in
            ca[iB] += za
            fa[iC] += top[_FC0] + 2.0 * za * a_in
            ca[iC] += za
            ft[iB] += 2.0 * zt * tb_in
            ct[iB] += zt
            ft[iC] += 2.0 * zt * ta_in
            ct[iC] += zt
        # ---- solve both fields
        thb0 = ut[ib]
        xb0 = ua[ib]
        thb_w = vt[ib]
        _field_step(MAd, MAo, KAd, KAo, LAd, LAo, Ldense[0], dense, ua, va, aa, fa, ca, kxa, dt,
                    rhs, dd, vnew, work, 0 if ib == n - 1 else -1, dax0, drate, 0.0, bitp,
                    approx, vt[ib])
        if approx:
            d1 = approx_depth_of_cut(va[ib], thb_w, bitp)
        else:
            d1 = dax0 + drate * va[ib]
        _field_step(MTd, MTo, KTd, KTo, LTd, LTo, Ldense[1], dense, ut, vt, at, ft, ct, kxt, dt,
                    rhs, dd, vnew, work, 1 if ib == n - 1 else -1, d1, 0.0, va[ib], bitp,
                    approx, 0.0)
        if not approx:
            rock_advance(surf, istate, rp, thb0, xb0, ut[ib], ua[ib])
        if hybrid:
            wave_push(wa_hist, wa_pos, wa_wp, va[iB] - b_in, va[iC] - a_in)
            wave_push(wt_hist, wt_pos, wt_wp, vt[iB] - tb_in, vt[iC] - ta_in)
            fb_line = top[_FB0] + za * (2.0 * b_in - va[iB])
            fc_line = -top[_FC0] - za * (2.0 * a_in - va[iC])
            # reported torque GJ (theta_up - theta_down)/L is minus the line's N
            tb_line = -zt * (2.0 * tb_in - vt[iB])
            tc_line = zt * (2.0 * ta_in - vt[iC])
        misc[0] += dt
        misc[5] += 1.0
        # ---- record
        if (k + 1) % rec_every == 0:
            if not (math.isfinite(va[ib]) and math.isfinite(vt[ib]) and math.isfinite(ua[0])):
                return 1, row - rec_start
            if approx:
                dn = approx_depth_of_cut(va[ib], vt[ib], bitp)
            else:
                dn = rock_depth(surf, istate, rp, ua[ib], ut[ib])
            wn, tn = bit_forces(dn, va[ib], vt[ib], bitp)
            rec[row, 0] = ua[ib] - misc[4]
            rec[row, 1] = va[ib]
            rec[row, 2] = ut[ib]
            rec[row, 3] = vt[ib]
            rec[row, 4] = dn
            rec[row, 5] = wn
            rec[row, 6] = tn
            if top[_AXM] < 0.5:
                rec[row, 7] = cax
            else:
                rec[row, 7] = top[_H0] - top[_HK] * (misc[1] - ua[0]) - top[_HC] * (cax - va[0])
            rec[row, 8] = _torque(KTo, ut, 0) if n > 1 else 0.0
            rec[row, 9] = va[0]
            rec[row, 10] = vt[0]
            if hybrid:
                rec[row, 11] = fb_line
                rec[row, 12] = tb_line
                rec[row, 13] = fc_line
                rec[row, 14] = tc_line
            else:
                rec[row, 11] = 0.5 * (_tension(KAo, ua, iB - 1) + _tension(KAo, ua, iB)) \
                    if 0 < iB < n - 1 else _tension(KAo, ua, min(max(iB, 0), n - 2))
                rec[row, 12] = 0.5 * (_torque(KTo, ut, iB - 1) + _torque(KTo, ut, iB)) \
                    if 0 < iB < n - 1 else _torque(KTo, ut, min(max(iB, 0), n - 2))
                rec[row, 13] = 0.5 * (_tension(KAo, ua, iC - 1) + _tension(KAo, ua, iC)) \
                    if 0 < iC < n - 1 else _tension(KAo, ua, min(max(iC, 0), n - 2))
                rec[row, 14] = 0.5 * (_torque(KTo, ut, iC - 1) + _torque(KTo, ut, iC)) \
                    if 0 < iC < n - 1 else _torque(KTo, ut, min(max(iC, 0), n - 2))
            rec[row, 15] = ut[0]
            rec[row, 16] = omega_ref
            row += 1
    return 0, row - rec_start
