"""Compiled kernels of the dynamic-programming optimizers (plain arrays in, no Python objects).

The 4th-order model is Eq. 2.1 written in deviations from the hanging equilibrium, with the
approximated depth of cut d = 2 pi x2 / max(x4, omega*) (Eq. 2.11 with the floor of Eq. 4.16);
the bit law is :func:`downhole.bit.bit_forces`. ``lumped`` arrays are ``[M, I, Ka, Ca, Kt, Ct]``.
Grid node ``n`` stands for (x2[i], x4[j]) with ``n = i * L4 + j``.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from downhole.bit import approx_depth_of_cut, approx_depth_rate, bit_forces, bit_forces_and_slopes


class LumpedKernelParams(NamedTuple):
    """The 4th-order lumped model's constants the DP kernels take (seed Eq. 2.1).

    Attributes
    ----------
    mass, inertia : float
        Bit/BHA mass (kg) and moment of inertia (kg m^2).
    ka, ca : float
        Axial string stiffness (N/m) and damping (N s/m).
    kt, ct : float
        Torsional string stiffness (N m/rad) and damping (N m s/rad).
    """

    mass: float
    inertia: float
    ka: float
    ca: float
    kt: float
    ct: float


__all__ = [
    "LumpedKernelParams",
    "advance",
    "backward_plain",
    "discrete_replay",
    "node_bit_loads",
    "path_inputs",
    "path_load_table",
    "path_replay",
    "project_table",
    "regions_step",
    "robust_forward_step",
    "robust_forward_step_parallel",
    "standard_backward",
    "standard_choose",
    "steady_loads",
    "transition_lists",
]

_INF = np.inf


@njit(cache=True)
def steady_loads(v, w, ca, ct, p):
    """String force and torque (N, N m) that hold the bit at constant (v, w)."""
    d = approx_depth_of_cut(v, w, p)
    wob, tob = bit_forces(d, v, w, p)
    return wob + ca * v, tob + ct * w


@njit(cache=True)
def node_bit_loads(g2, g4, p):
    """WOB and TOB at every grid node, flattened to length L2 * L4."""
    n2, n4 = g2.size, g4.size
    wob = np.empty(n2 * n4)
    tob = np.empty(n2 * n4)
    for i in range(n2):
        for j in range(n4):
            d = approx_depth_of_cut(g2[i], g4[j], p)
            wob[i * n4 + j], tob[i * n4 + j] = bit_forces(d, g2[i], g4[j], p)
    return wob, tob


@njit(cache=True)
def transition_lists(g2, g4, lumped, p, dt, bounds, use_rates):
    """Admissible node pairs of the partially inverted model (Eq. 2.15), as CSR lists.

    For a pair (n at step k, m at step k+1) the inversion gives the string force
    F = WOB(n) + Ca x2(n) + M (x2(m) - x2(n)) / dt at the start of the step and
    WOB(m) + Ca x2(m) + M (...) / dt at its end along the linear path (likewise the torque);
    both ends must lie in ``bounds[0:2]`` (force) and ``bounds[2:4]`` (torque). With
    ``use_rates`` the mean top-drive speeds over the step must lie in ``bounds[4:6]`` and
    ``bounds[6:8]``. Returns ``(succ_ptr, succ, pred_ptr, pred)``.
    """
    mass, inertia, ka, ca, kt, ct = (lumped.mass, lumped.inertia, lumped.ka, lumped.ca,
                                     lumped.kt, lumped.ct)
    n2, n4 = g2.size, g4.size
    nn = n2 * n4
    wob, tob = node_bit_loads(g2, g4, p)
    ok = np.zeros((nn, nn), dtype=np.bool_)
    count_s = np.zeros(nn + 1, dtype=np.int64)
    count_p = np.zeros(nn + 1, dtype=np.int64)
    for n in range(nn):
        i, j = n // n4, n % n4
        for m in range(nn):
            i2, j2 = m // n4, m % n4
            a = (g2[i2] - g2[i]) / dt
            b = (g4[j2] - g4[j]) / dt
            f0 = wob[n] + ca * g2[i] + mass * a
            f1 = wob[m] + ca * g2[i2] + mass * a
            if f0 < bounds[0] or f0 > bounds[1] or f1 < bounds[0] or f1 > bounds[1]:
                continue
            t0 = tob[n] + ct * g4[j] + inertia * b
            t1 = tob[m] + ct * g4[j2] + inertia * b
            if t0 < bounds[2] or t0 > bounds[3] or t1 < bounds[2] or t1 > bounds[3]:
                continue
            if use_rates:
                vt = 0.5 * (g2[i] + g2[i2]) + (wob[m] - wob[n] + ca * (g2[i2] - g2[i])) / (ka * dt)
                wt = 0.5 * (g4[j] + g4[j2]) + (tob[m] - tob[n] + ct * (g4[j2] - g4[j])) / (kt * dt)
                if vt < bounds[4] or vt > bounds[5] or wt < bounds[6] or wt > bounds[7]:
                    continue
            ok[n, m] = True
            count_s[n + 1] += 1
            count_p[m + 1] += 1
    for n in range(nn):
        count_s[n + 1] += count_s[n]
        count_p[n + 1] += count_p[n]
    succ = np.empty(count_s[nn], dtype=np.int32)
    pred = np.empty(count_p[nn], dtype=np.int32)
    fill_p = count_p[:-1].copy()
    q = 0
    for n in range(nn):
        for m in range(nn):
            if ok[n, m]:
                succ[q] = m
                q += 1
                pred[fill_p[m]] = n
                fill_p[m] += 1
    return count_s, succ, count_p, pred


@njit(cache=True)
def backward_plain(succ_ptr, succ, stage, J, policy, k_hi, k_lo):
    """Backward recursion over (x2, x4) nodes for steps k = k_hi-1 down to k_lo.

    J_k(n) = stage(n) + min over admissible successors m of J_{k+1}(m) (Eq. 2.21 with the
    cost-to-go of the connected node). ``J`` is (N+1, nn) with row N filled; ``policy`` (N, nn).
    """
    nn = stage.size
    for k in range(k_hi - 1, k_lo - 1, -1):
        for n in range(nn):
            best = _INF
            arg = -1
            for q in range(succ_ptr[n], succ_ptr[n + 1]):
                c = J[k + 1, succ[q]]
                if c < best:
                    best = c
                    arg = succ[q]
            J[k, n] = stage[n] + best if arg >= 0 else _INF
            policy[k, n] = arg


@njit(cache=True)
def regions_step(pred_ptr, pred, stage, g2, g4, dt, w1, w3, r1_lo, n_r1, r3_lo, n_r3,
                 node_n, node_x1, node_x3, node_j):
    """One backward step of the seed's customized DP with x1/x3 index regions (Eqs. 2.17-2.24).

    Nodes at step k+1 carry (grid node, x1, x3, cost-to-go). Every admissible predecessor grid
    node gives x1(k) = x1(k+1) - x2 dt, x3(k) = x3(k+1) - x4 dt (Eq. 2.15), binned into regions of
    widths ``w1``, ``w3`` (Eqs. 2.19-2.20); per (region1, x2, region3, x4) the lowest cost
    stage + J_{k+1} is kept. Returns the step-k node lists and each node's successor index.
    """
    nn = stage.size
    size = n_r1 * n_r3 * nn
    best = np.full(size, _INF)
    parent = np.full(size, -1, dtype=np.int32)
    bx1 = np.empty(size)
    bx3 = np.empty(size)
    n4 = g4.size
    # per predecessor node: x1/x3 shift in region units, plus the offset that turns floor()
    # into a truncation of a positive number (regions are indexed from r_lo)
    s1 = np.empty(nn)
    s3 = np.empty(nn)
    for n in range(nn):
        s1[n] = g2[n // n4] * dt / w1 - 0.5 + r1_lo
        s3[n] = g4[n % n4] * dt / w3 - 0.5 + r3_lo
    top1 = n_r1 - 1
    top3 = n_r3 - 1
    for q in range(node_n.size):
        m = node_n[q]
        jm = node_j[q]
        y1 = node_x1[q] / w1
        y3 = node_x3[q] / w3
        for t in range(pred_ptr[m], pred_ptr[m + 1]):
            n = pred[t]
            z1 = y1 - s1[n]
            z3 = y3 - s3[n]
            r1 = int(z1) if z1 >= 0.0 else 0
            r3 = int(z3) if z3 >= 0.0 else 0
            r1 = min(r1, top1)
            r3 = min(r3, top3)
            key = (r1 * n_r3 + r3) * nn + n
            c = stage[n] + jm
            if c < best[key]:
                best[key] = c
                parent[key] = q
                bx1[key] = node_x1[q] - g2[n // n4] * dt
                bx3[key] = node_x3[q] - g4[n % n4] * dt
    count = 0
    for key in range(size):
        if parent[key] >= 0:
            count += 1
    out_n = np.empty(count, dtype=np.int32)
    out_x1 = np.empty(count)
    out_x3 = np.empty(count)
    out_j = np.empty(count)
    out_p = np.empty(count, dtype=np.int32)
    c = 0
    for key in range(size):
        if parent[key] >= 0:
            out_n[c] = key % nn
            out_x1[c] = bx1[key]
            out_x3[c] = bx3[key]
            out_j[c] = best[key]
            out_p[c] = parent[key]
            c += 1
    return out_n, out_x1, out_x3, out_j, out_p


@njit(cache=True)
def _slopes(v, w, p):
    """Non-negative dampers dWOB/dv and dTOB/dw of the bit law along the approximated depth of
    cut (analytic slopes of :func:`downhole.bit.bit_forces_and_slopes`; the torque's depth
    coupling is left explicit), used to apply the stiff part of the bit law implicitly
    (linearly implicit Euler)."""
    if v <= 0.0:
        return 0.0, 0.0
    rate = approx_depth_rate(w, p)
    d = approx_depth_of_cut(v, w, p)
    r = bit_forces_and_slopes(d, v, w, p)
    cv = r[2] * rate + r[3]
    cw = r[6]
    return (max(0.0, cv)), (max(0.0, cw))


@njit(cache=True)
def advance(v, w, fs, ts, mass, inertia, ca, ct, p, h):
    """One linearly implicit Euler step of the bit velocities under string load (fs, ts).

    M v' = fs - Ca v - WOB(v, w), I w' = ts - Ct w - TOB(v, w); the bit law's stiff dampers are
    taken implicitly so that steps of a few ms stay stable at any rotary speed."""
    d = approx_depth_of_cut(v, w, p)
    wob, tob = bit_forces(d, v, w, p)
    cv, cw = _slopes(v, w, p)
    v_new = v + h * (fs - ca * v - wob) / (mass + h * (cv + ca))
    w_new = w + h * (ts - ct * w - tob) / (inertia + h * (cw + ct))
    return v_new, w_new


@njit(cache=True)
def project_table(g2, g4, fl, tl, lumped, p, dt, nsub, bounds):
    """Forward projections of the standard DP: every node under every (force, torque) input.

    The top displacement is held over the step (Eq. 2.12's zero-order hold), so the string force
    relaxes by Ka * (x1 advance). Returns (x2', x4', admissible) arrays of shape (nn, nF*nT)."""
    mass, inertia, ka, ca, kt, ct = (lumped.mass, lumped.inertia, lumped.ka, lumped.ca,
                                     lumped.kt, lumped.ct)
    n4 = g4.size
    nn = g2.size * n4
    nq = fl.size * tl.size
    x2p = np.empty((nn, nq))
    x4p = np.empty((nn, nq))
    adm = np.zeros((nn, nq), dtype=np.bool_)
    h = dt / nsub
    for n in range(nn):
        for q in range(nq):
            f = fl[q // tl.size]
            t = tl[q % tl.size]
            v = g2[n // n4]
            w = g4[n % n4]
            y1 = 0.0
            y3 = 0.0
            for s in range(nsub):
                v, w = advance(v, w, f - ka * y1, t - kt * y3, mass, inertia, ca, ct, p, h)
                y1 += v * h
                y3 += w * h
            x2p[n, q] = v
            x4p[n, q] = w
            fe = f - ka * y1
            te = t - kt * y3
            adm[n, q] = (bounds[0] <= fe <= bounds[1] and bounds[2] <= te <= bounds[3]
                         and math.isfinite(v) and math.isfinite(w))
    return x2p, x4p, adm


@njit(cache=True)
def _interp(jrow, g2min, h2, n2, g4min, h4, n4, v, w):
    """Bilinear interpolation of a cost row over the (x2, x4) grid; inf outside or next to inf."""
    fx = (v - g2min) / h2
    fy = (w - g4min) / h4
    if fx < -1e-9 or fy < -1e-9 or fx > n2 - 1 + 1e-9 or fy > n4 - 1 + 1e-9:
        return _INF
    i = int(fx)
    j = int(fy)
    if i >= n2 - 1:
        i = n2 - 2
    if j >= n4 - 1:
        j = n4 - 2
    i = max(i, 0)
    j = max(j, 0)
    tx = min(max(fx - i, 0.0), 1.0)
    ty = min(max(fy - j, 0.0), 1.0)
    out = 0.0
    for di in range(2):
        wx = tx if di == 1 else 1.0 - tx
        if wx == 0.0:
            continue
        for dj in range(2):
            wy = ty if dj == 1 else 1.0 - ty
            if wy == 0.0:
                continue
            c = jrow[(i + di) * n4 + j + dj]
            if c == _INF:
                return _INF
            out += wx * wy * c
    return out


@njit(cache=True)
def standard_backward(x2p, x4p, adm, stage, J, g2, g4, k_hi, k_lo):
    """Backward recursion of the standard DP with bilinear interpolation of J_{k+1}."""
    nn, nq = x2p.shape
    n2, n4 = g2.size, g4.size
    h2 = g2[1] - g2[0]
    h4 = g4[1] - g4[0]
    for k in range(k_hi - 1, k_lo - 1, -1):
        for n in range(nn):
            best = _INF
            for q in range(nq):
                if not adm[n, q]:
                    continue
                c = _interp(J[k + 1], g2[0], h2, n2, g4[0], h4, n4, x2p[n, q], x4p[n, q])
                best = min(best, c)
            J[k, n] = stage[n] + best


@njit(cache=True)
def standard_choose(v, w, jnext, fl, tl, g2, g4, lumped, p, dt, nsub, bounds):
    """Standard-DP policy at an off-grid state: the input minimizing interpolated J_{k+1}.

    Returns (q, x2', x4', dx1, dx3) of the best admissible input (q = -1 if none)."""
    mass, inertia, ka, ca, kt, ct = (lumped.mass, lumped.inertia, lumped.ka, lumped.ca,
                                     lumped.kt, lumped.ct)
    h = dt / nsub
    h2 = g2[1] - g2[0]
    h4 = g4[1] - g4[0]
    best = _INF
    out = (-1, v, w, 0.0, 0.0)
    for q in range(fl.size * tl.size):
        f = fl[q // tl.size]
        t = tl[q % tl.size]
        vv, ww, y1, y3 = v, w, 0.0, 0.0
        for s in range(nsub):
            vv, ww = advance(vv, ww, f - ka * y1, t - kt * y3, mass, inertia, ca, ct, p, h)
            y1 += vv * h
            y3 += ww * h
        fe = f - ka * y1
        te = t - kt * y3
        if not (bounds[0] <= fe <= bounds[1] and bounds[2] <= te <= bounds[3]):
            continue
        c = _interp(jnext, g2[0], h2, g2.size, g4[0], h4, g4.size, vv, ww)
        if c < best:
            best = c
            out = (q, vv, ww, y1, y3)
    return out


@njit(cache=True)
def _path_loads(x2a, x4a, a, b, tau, lumped, p):
    """Nominal string force/torque of the path inversion (Eq. 2.15 in continuous form) at
    time ``tau`` into a step whose linear path starts at (x2a, x4a) with slopes (a, b)."""
    v = x2a + a * tau
    w = x4a + b * tau
    d = approx_depth_of_cut(v, w, p)
    wob, tob = bit_forces(d, v, w, p)
    return wob + lumped.ca * v + lumped.mass * a, tob + lumped.ct * w + lumped.inertia * b


def _robust_forward_step(pred_ptr, pred, g2, g4, dt, nsub, lumped, p_nom, p_ens, nominal_mask,
                         weights_ens, lam, targets, last, cost, states, alive, load_table):
    """One forward step of the robust DP (Eq. 2.25) over (x2, x4) nodes.

    Each alive node n carries its accumulated ensemble cost and, for every ensemble model e, the
    state (e1, v, e3, w) with e1 = x1_nom - x1_e, e3 = x3_nom - x3_e. Along the linear nominal
    path n -> m the same top inputs (path inversion) drive every model; non-nominal models are
    integrated with ``nsub`` linearly implicit Euler substeps. The candidate cost adds the
    ensemble-mean stage cost at k+1 (or the terminal cost when ``last``); each node m keeps its
    best predecessor. Returns the new (cost, states, alive, parent) arrays.
    """
    nn = cost.size
    ne = len(p_ens)
    mass, inertia, ka, ca, kt, ct = (lumped.mass, lumped.inertia, lumped.ka, lumped.ca,
                                     lumped.kt, lumped.ct)
    n4 = g4.size
    h = dt / nsub
    new_cost = np.full(nn, _INF)
    new_states = np.zeros((nn, ne, 4))
    new_alive = np.zeros(nn, dtype=np.bool_)
    parent = np.full(nn, -1, dtype=np.int32)
    l1, l2, l3, l4 = lam[0], lam[1], lam[2], lam[3]
    vm, wm, vd, wd = targets[0], targets[1], targets[2], targets[3]
    use_table = load_table.shape[0] == pred.size
    for m in prange(nn):
        tmp = np.empty((ne, 4))
        best = np.empty((ne, 4))
        best_c = _INF
        best_n = -1
        x2m = g2[m // n4]
        x4m = g4[m % n4]
        for qq in range(pred_ptr[m], pred_ptr[m + 1]):
            n = pred[qq]
            if not alive[n]:
                continue
            x2a = g2[n // n4]
            x4a = g4[n % n4]
            a = (x2m - x2a) / dt
            b = (x4m - x4a) / dt
            for e in range(ne):
                for c in range(4):
                    tmp[e, c] = states[n, e, c]
            for s in range(nsub):
                tau = s * h
                if use_table:
                    fn = load_table[qq, s, 0]
                    tn = load_table[qq, s, 1]
                else:
                    fn, tn = _path_loads(x2a, x4a, a, b, tau, lumped, p_nom)
                vn_mid = x2a + a * (tau + 0.5 * h)
                wn_mid = x4a + b * (tau + 0.5 * h)
                for e in range(ne):
                    if nominal_mask[e]:
                        continue
                    v_new, w_new = advance(tmp[e, 1], tmp[e, 3], fn + ka * tmp[e, 0],
                                           tn + kt * tmp[e, 2], mass, inertia, ca, ct, p_ens[e], h)
                    tmp[e, 1] = v_new
                    tmp[e, 3] = w_new
                    tmp[e, 0] += (vn_mid - v_new) * h
                    tmp[e, 2] += (wn_mid - w_new) * h
            add = 0.0
            for e in range(ne):
                if nominal_mask[e]:
                    tmp[e, 0] = 0.0
                    tmp[e, 1] = x2m
                    tmp[e, 2] = 0.0
                    tmp[e, 3] = x4m
                if last:
                    add += weights_ens[e] * (l3 * (tmp[e, 1] - vd) ** 2
                                             + l4 * (tmp[e, 3] - wd) ** 2)
                else:
                    add += weights_ens[e] * (l1 * (tmp[e, 1] - vm) ** 2
                                             + l2 * (tmp[e, 3] - wm) ** 2) * dt
            c = cost[n] + add
            if c < best_c:
                best_c = c
                best_n = n
                for e in range(ne):
                    for cc in range(4):
                        best[e, cc] = tmp[e, cc]
        if best_n >= 0:
            new_cost[m] = best_c
            parent[m] = best_n
            new_alive[m] = True
            for e in range(ne):
                for cc in range(4):
                    new_states[m, e, cc] = best[e, cc]
    return new_cost, new_states, new_alive, parent


@njit(cache=True)
def path_load_table(pred_ptr, pred, g2, g4, dt, nsub, lumped, p_nom):
    """Nominal string force/torque of the path inversion for every transition (in ``pred``
    order) at the start of every substep: shape (transitions, nsub, 2). Time-invariant."""
    n4 = g4.size
    out = np.empty((pred.size, nsub, 2))
    h = dt / nsub
    for m in range(pred_ptr.size - 1):
        for qq in range(pred_ptr[m], pred_ptr[m + 1]):
            n = pred[qq]
            x2a = g2[n // n4]
            x4a = g4[n % n4]
            a = (g2[m // n4] - x2a) / dt
            b = (g4[m % n4] - x4a) / dt
            for s in range(nsub):
                out[qq, s, 0], out[qq, s, 1] = _path_loads(x2a, x4a, a, b, s * h, lumped, p_nom)
    return out


robust_forward_step = njit(cache=True)(_robust_forward_step)
robust_forward_step_parallel = njit(cache=True, parallel=True)(_robust_forward_step)


@njit(cache=True)
def path_replay(x2k, x4k, dt, nsub, lumped, p_nom, p_model, out_every):
    """Continuous replay of a DP path on the 4th-order approximated-depth model.

    The top inputs are rebuilt by path inversion (Eq. 2.15 in continuous form) along the linear
    (x2, x4) path and applied open loop to the model with bit parameters ``p_model`` (e.g. a
    perturbed epsilon). Returns time, x2, x4, e1 (= x1_path - x1), e3 sampled every
    ``out_every`` substeps."""
    mass, inertia, ka, ca, kt, ct = (lumped.mass, lumped.inertia, lumped.ka, lumped.ca,
                                     lumped.kt, lumped.ct)
    nsteps = x2k.size - 1
    h = dt / nsub
    total = nsteps * nsub
    nout = total // out_every + 1
    t_out = np.empty(nout)
    v_out = np.empty(nout)
    w_out = np.empty(nout)
    e1_out = np.empty(nout)
    e3_out = np.empty(nout)
    v, w, e1, e3 = x2k[0], x4k[0], 0.0, 0.0
    t_out[0], v_out[0], w_out[0], e1_out[0], e3_out[0] = 0.0, v, w, 0.0, 0.0
    o = 1
    for k in range(nsteps):
        a = (x2k[k + 1] - x2k[k]) / dt
        b = (x4k[k + 1] - x4k[k]) / dt
        for s in range(nsub):
            tau = s * h
            fn, tn = _path_loads(x2k[k], x4k[k], a, b, tau, lumped, p_nom)
            v, w = advance(v, w, fn + ka * e1, tn + kt * e3, mass, inertia, ca, ct, p_model, h)
            e1 += (x2k[k] + a * (tau + 0.5 * h) - v) * h
            e3 += (x4k[k] + b * (tau + 0.5 * h) - w) * h
            idx = k * nsub + s + 1
            if idx % out_every == 0:
                t_out[o] = idx * h
                v_out[o], w_out[o], e1_out[o], e3_out[o] = v, w, e1, e3
                o += 1
    return t_out[:o], v_out[:o], w_out[:o], e1_out[:o], e3_out[:o]


@njit(cache=True)
def path_inputs(x2k, x4k, dt, times, lumped, p_nom):
    """Top displacements u1(t), u2(t) (m, rad from the hanging start) that make the 4th-order
    model follow the linear (x2, x4) path: u = x_path(t) + (bit load + C x' + M x'') / K."""
    ka, kt = lumped.ka, lumped.kt
    nsteps = x2k.size - 1
    x1s = np.zeros(nsteps + 1)
    x3s = np.zeros(nsteps + 1)
    for k in range(nsteps):
        x1s[k + 1] = x1s[k] + 0.5 * (x2k[k] + x2k[k + 1]) * dt
        x3s[k + 1] = x3s[k] + 0.5 * (x4k[k] + x4k[k + 1]) * dt
    u1 = np.empty(times.size)
    u2 = np.empty(times.size)
    for r in range(times.size):
        t = times[r]
        k = int(math.floor(t / dt + 1e-9))
        if k >= nsteps:
            k = nsteps - 1
        k = max(k, 0)
        tau = t - k * dt
        a = (x2k[k + 1] - x2k[k]) / dt
        b = (x4k[k + 1] - x4k[k]) / dt
        fn, tn = _path_loads(x2k[k], x4k[k], a, b, tau, lumped, p_nom)
        x1 = x1s[k] + x2k[k] * tau + 0.5 * a * tau * tau
        x3 = x3s[k] + x4k[k] * tau + 0.5 * b * tau * tau
        u1[r] = x1 + fn / ka
        u2[r] = x3 + tn / kt
    return u1, u2


@njit(cache=True)
def discrete_replay(u1, u2, dt, lumped, p):
    """Eq. 2.12 (explicit Euler at the DP step, depth of cut approximated) driven by u1(k), u2(k)
    from the rest state; returns x1..x4 at k = 0..N."""
    mass, inertia, ka, ca, kt, ct = (lumped.mass, lumped.inertia, lumped.ka, lumped.ca,
                                     lumped.kt, lumped.ct)
    n = u1.size
    x = np.zeros((n + 1, 4))
    for k in range(n):
        x1, x2, x3, x4 = x[k, 0], x[k, 1], x[k, 2], x[k, 3]
        d = approx_depth_of_cut(x2, x4, p)
        wob, tob = bit_forces(d, x2, x4, p)
        x[k + 1, 0] = x1 + x2 * dt
        x[k + 1, 1] = x2 + (-ca * x2 - ka * (x1 - u1[k]) - wob) / mass * dt
        x[k + 1, 2] = x3 + x4 * dt
        x[k + 1, 3] = x4 + (-ct * x4 - kt * (x3 - u2[k]) - tob) / inertia * dt
    return x
