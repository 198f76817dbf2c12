"""The one compiled mechanics kernel: lumped chains, the directional FEM and the hybrid model.

One kernel, :func:`run_kernel`, advances every chain model: nodes form one or two chains
(lumped masses on springs and dampers, or 2-node axial-torsional bar elements (tridiagonal mass, stiffness and Rayleigh damping per field; a zero
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

Explicit Euler (the seed's Chapter 2 scheme, ``KernelParams.explicit_euler``) is the other
integrator: it needs a diagonal mass and a stiffness matrix whose rows sum to zero (the string's
supports are the hook and top-drive laws at node 0), and applies the bit force of the state at
the start of the step; it takes neither the dense (modal) damping nor the wave joint (only the
lumped chains select it). The lumped models of Chapter 2 drive node 0 towards a given, massless top
(``KernelParams.given_reference``): per step boundary the top positions and velocities (or the
hook load and surface torque) come from the ``top_ref`` array instead of being integrated from
``cmd`` in the kernel.

The kernel takes its constant settings as one :class:`KernelParams` (a ``NamedTuple``, passed
by value), the bit law's as one :class:`~downhole.params.bit.BitKernelParams`, its clocks and
references as one :data:`RUN_STATE_DTYPE` record (updated in place) and the rest as plain arrays;
:mod:`downhole.string.fem`, :mod:`downhole.string.hybrid` and
:mod:`downhole.sim.lumped_model` build them.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from downhole.bit.law import (
    approx_depth_of_cut,
    approx_depth_rate,
    bit_forces,
    bit_wob,
    solve_bit_node,
)
from downhole.bit.rock_surface import rock_advance_to, rock_depth_at
from downhole.contact.softstring import (
    contact_elements_into,
    element_normal_half,
    friction_damper,
)
from downhole.sim.wave import wave_read_at, wave_read_plan, wave_source_forces, wave_step_at

__all__ = [
    "CHANNELS",
    "RUN_STATE_DTYPE",
    "KernelModel",
    "KernelParams",
    "KernelState",
    "kernel_state",
    "new_kernel_work",
    "new_run_state",
    "run_kernel",
    "thomas_solve",
]

#: Recorded channels, in order.
CHANNELS = (
    "bit_axial_position", "bit_axial_velocity", "bit_angle", "bit_angular_velocity",
    "depth_of_cut", "wob", "tob", "hook_load", "surface_torque", "top_drive_axial_velocity",
    "top_drive_angular_velocity", "force_b", "torque_b", "force_c", "torque_c",
    "top_drive_angle", "reference_angular_velocity",
)


class KernelParams(NamedTuple):
    """The constant settings of :func:`run_kernel` (SI units), built by name in
    :class:`downhole.string.fem._Packed` (directional models) and
    :class:`downhole.sim.lumped_model.ChainPack` (lumped chains).

    Attributes
    ----------
    velocity_hook : bool
        True: velocity-servo hook (the block follows ``cmd[:, 0]`` in m/s through the spring
        ``hook_k`` and damper ``hook_c``); False: ``cmd[:, 0]`` is the hook load, N.
    hook_k, hook_c : float
        Hook servo stiffness (N/m) and damping (N s/m).
    hook_load0 : float
        Hook load of the static state (buoyed weight - WOB), N.
    torque_mode : bool
        True: ``cmd[:, 1]`` is the top-drive torque (N m); False: a speed set-point for the PI.
    kp, ki : float
        Top-drive PI gains, N m s/rad and N m/rad.
    soft_gain, soft_tau : float
        Soft-torque gain (rad/s per N m; 0 switches it off) and low-pass time constant (s).
    mu, v_eps : float
        Wellbore friction coefficient and its velocity regularization (m/s).
    approx_doc : bool
        Approximated depth of cut (True) or the delayed one from the rock-surface memory.
    node_b, node_c : int
        Nodes B and C (the ends of the wave segment, or the reporting nodes of the FEM).
    hybrid : bool
        A wave segment joins B and C.
    dense : bool
        Dense L per field (modal damping) instead of the tridiagonal one.
    n_lags_a, n_lags_t : int
        Lag-cascade stages on the incoming waves (axial, torsional).
    lag_tau_a, lag_tau_t : float
        Time constant of each lag stage, s.
    fb0, fc0 : float
        Static preload forces of the wave segment on B and C, N.
    prebalanced_weight : float
        Weight pre-balanced out of the nodal forces (lumped models, N): the force-driven top
        applies it minus the hook load, and the recorded hook load of a given reference adds
        it.
    explicit_euler : bool
        Explicit Euler steps (diagonal mass, zero-row-sum stiffness, a given reference;
        Chapter 2) instead of Newmark's average acceleration.
    given_reference : bool
        The top is a given, massless reference: the ``top_ref`` rows (axial position, angle,
        axial velocity, angular velocity; force mode: hook load, surface torque) at the step
        boundaries replace ``cmd`` and the in-kernel integration of the references; the
        recorded top-drive velocities are the reference's and the surface torque is the
        top coupling's.
    bit_iterations : int
        Newton iterations of the implicit bit force per step and field (default 60: the
        exact implicit force, to round-off; 1: linearly implicit, the law linearized at the
        velocity of the start of the step, one law evaluation per field).
    bit_disturbance : bool
        ``cmd`` has two more columns: a force (N) and a torque (N m) added to the bit's WOB
        and TOB over the step (noise); not with a given reference.
    rig_node, bit_node : int
        The node the top drive and the hook act on, and the node the bit law acts on (-1: the
        last node). Every pack names them (the chains and the FEM: 0 and the last node); the
        kernel hard-wires neither.
    """

    velocity_hook: bool
    hook_k: float
    hook_c: float
    hook_load0: float
    torque_mode: bool
    kp: float
    ki: float
    soft_gain: float
    soft_tau: float
    mu: float
    v_eps: float
    approx_doc: bool
    node_b: int
    node_c: int
    hybrid: bool
    dense: bool
    n_lags_a: int
    lag_tau_a: float
    n_lags_t: int
    lag_tau_t: float
    fb0: float
    fc0: float
    prebalanced_weight: float = 0.0
    explicit_euler: bool = False
    given_reference: bool = False
    bit_iterations: int = 60
    bit_disturbance: bool = False
    rig_node: int = 0
    bit_node: int = -1


#: The clocks and references :func:`run_kernel` carries from call to call, one record of
#: shape (1,): simulated time (s), hook servo reference position (m), top-drive angle reference
#: (rad), soft-torque low-pass state (N m), bit axial position of the start (m, subtracted from
#: the recorded position) and the number of steps taken.
RUN_STATE_DTYPE = np.dtype([("time", np.float64), ("x_ref", np.float64),
                            ("theta_ref", np.float64), ("soft_lowpass", np.float64),
                            ("ubit0", np.float64), ("step", np.float64)])


def new_run_state(**values) -> np.ndarray:
    """A fresh (1,) record of :data:`RUN_STATE_DTYPE`, fields zero unless given by name."""
    rs = np.zeros(1, dtype=RUN_STATE_DTYPE)
    for name, value in values.items():
        if name not in RUN_STATE_DTYPE.names:
            raise KeyError(f"unknown run-state field {name!r}: expected one of "
                           f"{RUN_STATE_DTYPE.names}")
        rs[name] = value
    return rs


#: Rows of the float scratch buffer of :func:`run_kernel` (each row has one value per node).
_WORK_ROWS = 27


class KernelModel(NamedTuple):
    """What a model is for the kernel (constant over runs): the field matrices ``mats`` (18,
    n), the dense L per field ``Ldense`` (2, n, n) (modal damping, else unused), the elements
    ``elem`` (n, 8), the nodal gravity and torque arm ``node`` (n, 2), the settings ``top``
    (:class:`KernelParams`) and the bit law ``bit``
    (:class:`~downhole.params.bit.BitKernelParams`). See :func:`run_kernel`."""

    mats: np.ndarray
    Ldense: np.ndarray
    elem: np.ndarray
    node: np.ndarray
    top: object
    bit: object


class KernelState(NamedTuple):
    """One run's state for the kernel (updated in place): nodal ``state`` (6, n), clocks and
    references ``run`` (:data:`RUN_STATE_DTYPE`), the rock surface (``surf``, ``istate`` and
    its parameters ``rock``), the wave segment of each field (ring buffer, clock and
    :class:`~downhole.sim.wave.WaveParams`), the lag cascades ``lag`` (4, m) and the scratch
    ``work`` (:func:`new_kernel_work`). See :func:`run_kernel`."""

    state: np.ndarray
    run: np.ndarray
    surf: np.ndarray
    istate: np.ndarray
    rock: object
    wave_a_hist: np.ndarray
    wave_a_pos: np.ndarray
    wave_a: object
    wave_t_hist: np.ndarray
    wave_t_pos: np.ndarray
    wave_t: object
    lag: np.ndarray
    work: tuple


def kernel_state(st: dict) -> KernelState:
    """The :class:`KernelState` of a pack's run state ``st`` (a dict with ``state``, ``run``,
    ``surf``, ``istate``, ``rp``, ``wa`` and ``wt`` (hist, pos, params), ``lag``, ``work``): the
    same arrays, not copies.

    Parameters
    ----------
    st : dict
        The run state a pack's ``begin``/``start`` returned.

    Returns
    -------
    KernelState
    """
    wa, wt = st["wa"], st["wt"]
    return KernelState(st["state"], st["run"], st["surf"], st["istate"], st["rp"], wa[0], wa[1],
                       wa[2], wt[0], wt[1], wt[2], st["lag"], st["work"])


def new_kernel_work(n: int, dense: bool = False):
    """Scratch buffers for :func:`run_kernel` on ``n`` nodes (reused from call to call).

    Parameters
    ----------
    n : int
        Number of nodes.
    dense : bool, optional
        The model has dense (modal) damping: an (n, n) solve buffer is needed.

    Returns
    -------
    tuple
        ``(float (27, n), int64 (3, n), float (n, n) or (1, 1))``.
    """
    return (np.zeros((_WORK_ROWS, n)), np.zeros((3, n), np.int64),
            np.empty((n, n)) if dense else np.empty((1, 1)))


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
def _lag_cascade(lag, row, n_lags, al, x):
    """Cascade of first-order lags (exact discretization, factor ``al``); the last output."""
    inp = x
    for j in range(n_lags):
        lag[row, j] += al * (inp - lag[row, j])
        inp = lag[row, j]
    return inp


@njit(cache=True)
def _spd_solve2(A, b1, b2, x1, x2, n):
    """Solve A x1 = b1 and A x2 = b2 for a symmetric positive definite A (Gaussian elimination
    without pivoting, in place: A, b1 and b2 are overwritten)."""
    for k in range(n):
        inv = 1.0 / A[k, k]
        for i in range(k + 1, n):
            m = A[i, k] * inv
            if m != 0.0:
                for j in range(k + 1, n):
                    A[i, j] -= m * A[k, j]
                b1[i] -= m * b1[k]
                b2[i] -= m * b2[k]
    for i in range(n - 1, -1, -1):
        s1 = b1[i]
        s2 = b2[i]
        for j in range(i + 1, n):
            s1 -= A[i, j] * x1[j]
            s2 -= A[i, j] * x2[j]
        x1[i] = s1 / A[i, i]
        x2[i] = s2 / A[i, i]


@njit(cache=True)
def _tension(Ko, u, e):
    """Elastic tension in element e (positive in tension): EA/L (u_{e+1} - u_e)."""
    return -Ko[e] * (u[e + 1] - u[e])


@njit(cache=True)
def _torque(Ko, th, e):
    """Elastic torque in element e: GJ/L (theta_e - theta_{e+1})."""
    return Ko[e] * (th[e + 1] - th[e])


@njit(cache=True)
def _mid_tension(Ko, u, i):
    """Tension at node i: mean of its two elements (an end node: its one element)."""
    n = u.size
    if 0 < i < n - 1:
        return 0.5 * (_tension(Ko, u, i - 1) + _tension(Ko, u, i))
    return _tension(Ko, u, min(max(i, 0), n - 2))


@njit(cache=True)
def _mid_torque(Ko, th, i):
    """Torque at node i: mean of its two elements (an end node: its one element)."""
    n = th.size
    if 0 < i < n - 1:
        return 0.5 * (_torque(Ko, th, i - 1) + _torque(Ko, th, i))
    return _torque(Ko, th, min(max(i, 0), n - 2))


@njit(cache=True)
def run_kernel(model, ks, cmd, top_ref, n_steps, dt, rec, rec_every, rec_start):
    """Advance ``n_steps`` steps of ``dt``; record every ``rec_every`` steps into ``rec``.

    Parameters
    ----------
    model : KernelModel
        The model: ``mats`` (18, n), rows M_a diag/off, K_a diag/off, L_a diag/off (L = M +
        dt/2 C + dt^2/4 K), then the same for the torsional field, then C_a diag/off and C_t
        diag/off (for reporting); ``Ldense`` (2, n, n), the dense L per field when
        ``top.dense`` (modal damping); ``elem`` (n, 8), per element e (0..n-2): length, dt/ds
        (3), w g_perp (3), contact flag; ``node`` (n, 2), nodal gravity force (N, downward) and
        torque arm (m); ``top`` (:class:`KernelParams`), hook, top drive, friction,
        depth-of-cut and wave-segment settings; ``bit``, the bit law's parameters.
    ks : KernelState
        The run, updated in place: ``state`` (6, n), u_a, v_a, a_a, theta, omega, alpha;
        ``run``, clocks and references; ``surf``, ``istate``, ``rock``, the rock-surface memory
        (:class:`~downhole.bit.rock_surface.RockSurfaceParams`); ``wave_a_*``, ``wave_t_*``,
        the wave segments (axial, torsional: ring buffers, clocks and
        :class:`~downhole.sim.wave.WaveParams`; ignored unless hybrid); ``lag`` (4, m),
        lag-cascade states (rows: axial b_in, axial a_in, torsional b_in, a_in); ``work``,
        scratch buffers from :func:`new_kernel_work` (overwritten; the kernel allocates nothing,
        so a caller that steps one step per call, a compiled closed loop, pays no allocation).
    cmd : (n_steps, 2) or (n_steps, 4)
        Per step: axial command (hook load N, or top axial velocity m/s) and torsional command
        (speed set-point rad/s, or top-drive torque N m); with ``top.bit_disturbance`` also the
        WOB and TOB disturbances. Ignored with ``top.given_reference``.
    top_ref : (n_steps + 1, 4)
        With ``top.given_reference``: the top at the step boundaries t_k (rows k = 0..n_steps):
        axial position, angle, axial velocity, angular velocity (velocity hook), or hook load,
        surface torque (force hook, columns 0 and 1). Else ignored (any shape).
    rec : (n_rec, len(CHANNELS)) output; ``rec_start`` is the first row written.

    Returns
    -------
    status : int
        0 ok, 1 non-finite or runaway state (bit beyond 1e9 m or m/s, 1e12 rad or rad/s).
    rows : int
        Number of rows written.

    Notes
    -----
    Written for a small fixed cost per step (the hybrid models have only 6-27 nodes): one
    function body; scalar bit-law helpers with analytic slopes; everything constant over the
    call found once (contact elements, static forces and dampers, the Thomas factors of the
    nodes above the first contact node, wave read offsets, lag factors); the rock-surface and
    wave ring buffers read and written inline; clocks in locals.
    """
    mats, Ldense, elem, node, top, bt = model
    state, run, surf, istate, rp = ks.state, ks.run, ks.surf, ks.istate, ks.rock
    wa_hist, wa_pos, wa_wp = ks.wave_a_hist, ks.wave_a_pos, ks.wave_a
    wt_hist, wt_pos, wt_wp = ks.wave_t_hist, ks.wave_t_pos, ks.wave_t
    lag, work = ks.lag, ks.work
    n = state.shape[1]
    it = top.rig_node
    ib = top.bit_node if top.bit_node >= 0 else n - 1
    iB = top.node_b
    iC = top.node_c
    hybrid = top.hybrid
    dense = top.dense
    approx = top.approx_doc
    vel_hook = top.velocity_hook
    torque_mode = top.torque_mode
    given = top.given_reference
    euler = top.explicit_euler
    n_newton = top.bit_iterations
    dist = top.bit_disturbance and not given
    dwob = 0.0
    dtob = 0.0
    soft = (not torque_mode) and (not given) and top.soft_gain > 0.0
    w_pre = top.prebalanced_weight
    hk, hc, h0 = top.hook_k, top.hook_c, top.hook_load0
    kp, ki, sg, stau = top.kp, top.ki, top.soft_gain, top.soft_tau
    mu = top.mu
    v_eps = top.v_eps
    fb0, fc0 = top.fb0, top.fc0
    h = 0.5 * dt
    ih = 1.0 / h
    # rock surface (downhole.bit.rock_surface layout), unpacked
    r_ref, r_h, r_nb, r_cap, r_nbl = rp.theta_ref, rp.h, rp.nb, rp.cap, rp.n_blades
    r_mem = rp.memory
    j_next = istate[0]
    drate_rock = rp.n_blades * h  # delayed depth of cut: d(v1) = dax0 + n h v1
    # ---- contact elements / nodes (skip elements whose normal force is identically zero:
    # straight and vertical, no curvature and no lateral weight)
    wk, wki, Aw = work
    wk[:] = 0.0
    n_ce = contact_elements_into(elem, wki[0]) if mu > 0.0 else 0
    ce = wki[0]
    incontact = wki[2]
    incontact[:] = 0
    for j in range(n_ce):
        incontact[ce[j]] = 1
        incontact[ce[j] + 1] = 1
    cn = wki[1]
    n_cn = 0
    for i in range(n):
        if incontact[i] != 0:
            cn[n_cn] = i
            n_cn += 1
    # first node whose diagonal changes from step to step (contact), capped at the bit node
    p_var = ib
    if n_cn > 0 and cn[0] < ib:
        p_var = cn[0]
    # ---- static forces, dampers and springs; the diagonal and Thomas factors they give
    # (every work row is a view of the caller's buffer: nothing is allocated per call)
    Fst = wk[0:2]
    Cst = wk[2:4]
    Kx = wk[4:6]
    for i in range(n):
        Fst[0, i] = node[i, 0]
    if vel_hook:
        Fst[0, it] += -h0
        Cst[0, it] += hc
        Kx[0, it] = hk
    if not torque_mode:
        Cst[1, it] += kp
        Kx[1, it] = ki
    if hybrid:
        za0 = wa_wp.impedance
        zt0 = wt_wp.impedance
        Fst[0, iB] += fb0
        Fst[0, iC] += fc0
        Cst[0, iB] += za0
        Cst[0, iC] += za0
        Cst[1, iB] += zt0
        Cst[1, iC] += zt0
    Dst = wk[6:8]
    cwc = wk[8:10]
    invc = wk[10:12]
    for f in range(2):
        for i in range(n):
            Dst[f, i] = mats[6 * f + 4, i] + h * (Cst[f, i] + Kx[f, i] * h)
        for i in range(p_var):
            den = Dst[f, i]
            if i > 0:
                den -= mats[6 * f + 5, i - 1] * cwc[f, i - 1]
            invc[f, i] = 1.0 / den
            cwc[f, i] = mats[6 * f + 5, i] * invc[f, i]
    # explicit Euler: ground damping per node (row sums of C), element springs and dampers
    Cg = wk[12:14]
    if euler:
        for f in range(2):
            rc = 12 + 2 * f
            for i in range(n):
                cg = mats[rc, i]
                if i > 0:
                    cg += mats[rc + 1, i - 1]
                if i < n - 1:
                    cg += mats[rc + 1, i]
                Cg[f, i] = cg
    F = wk[14:16]
    F[:, :] = Fst
    cfr = wk[16:18]
    rhs = wk[18]
    rhs_t = wk[19]
    dd = wk[20]
    y = wk[21]
    y_t = wk[22]
    cw = wk[23]
    cw_t = wk[24]
    nrm = wk[25]
    fe = wk[26]
    # ---- wave segments (downhole.sim.wave): clocks, capacities and read plans in locals
    za = wa_wp.impedance
    zt = wt_wp.impedance
    pos_a = wa_pos[0]
    pos_t = wt_pos[0]
    cap_a = wa_wp.cap
    cap_t = wt_wp.cap
    off_a, fr_a = wave_read_plan(wa_wp.delay_steps)
    off_t, fr_t = wave_read_plan(wt_wp.delay_steps)
    nla = top.n_lags_a
    nlt = top.n_lags_t
    al_a = 1.0 - math.exp(-dt / top.lag_tau_a) if nla > 0 else 0.0
    al_t = 1.0 - math.exp(-dt / top.lag_tau_t) if nlt > 0 else 0.0
    # ---- clocks and references in locals
    rs = run[0]
    t_now = rs.time
    x_ref = rs.x_ref
    th_ref = rs.theta_ref
    lowp = rs.soft_lowpass
    ubit0 = rs.ubit0
    n_done = rs.step
    fb_line = 0.0
    tb_line = 0.0
    fc_line = 0.0
    tc_line = 0.0
    row = rec_start
    countdown = rec_every
    bit_known = False
    wob_k = 0.0
    tob_k = 0.0
    status = 0
    for k in range(n_steps):
        # runaway guard: a diverging run stops before the grid-indexed rock memory sees bit
        # positions or angles it cannot index
        if not (abs(state[0, ib]) < 1e9 and abs(state[1, ib]) < 1e9
                and abs(state[3, ib]) < 1e12 and abs(state[4, ib]) < 1e12):
            status = 1
            break
        if given:
            # the top at t_{n+1} from the given reference
            if vel_hook:
                x_ref = top_ref[k + 1, 0]
                cax = top_ref[k + 1, 2]
            else:
                cax = top_ref[k + 1, 0]
            if torque_mode:
                ctq = top_ref[k + 1, 1]
            else:
                th_ref = top_ref[k + 1, 1]
                ctq = top_ref[k + 1, 3]
            omega_ref = ctq
        else:
            cax = cmd[k, 0]
            ctq = cmd[k, 1]
            # ---- references at t_{n+1}
            omega_ref = ctq
            if soft:
                tq0 = mats[9, it] * (state[3, it + 1] - state[3, it]) if n > 1 else 0.0
                if stau > 0:
                    lowp += (dt / stau) * (tq0 - lowp)
                omega_ref = ctq - sg * (tq0 - lowp)
            th_ref += dt * omega_ref
            if vel_hook:
                x_ref += dt * cax
        # ---- top drive and hook (node 0; the Newmark end-of-step forces)
        if not euler:
            if vel_hook:
                F[0, it] = Fst[0, it] + hk * (x_ref - state[0, it]) + hc * cax
            else:
                F[0, it] = Fst[0, it] + (w_pre - cax)
            if torque_mode:
                F[1, it] = ctq
            else:
                F[1, it] = kp * omega_ref + ki * (th_ref - state[3, it])
        # ---- wellbore contact (soft string, frozen-coefficient friction)
        if n_ce > 0:
            for j in range(n_cn):
                nrm[cn[j]] = 0.0
            for j in range(n_ce):
                e = ce[j]
                tension = -mats[3, e] * (state[0, e + 1] - state[0, e])
                half = element_normal_half(elem, e, tension)
                nrm[e] += half
                nrm[e + 1] += half
            for j in range(n_cn):
                i = cn[j]
                if nrm[i] > 0.0:
                    r = node[i, 1]
                    c = friction_damper(nrm[i], mu, state[1, i], r * state[4, i], v_eps)
                    cfr[0, i] = c
                    cfr[1, i] = c * r * r
                else:
                    cfr[0, i] = 0.0
                    cfr[1, i] = 0.0
        ua_b0 = state[0, ib]
        th_b0 = state[3, ib]
        if euler:
            # ---- explicit Euler (seed Eq. 2.12): forces of the state and the top at t_n
            # (the top at t_n: Euler runs with a given reference, the lumped chains')
            xr0 = top_ref[k, 0]
            tr0 = top_ref[k, 1]
            vr0 = top_ref[k, 2] if vel_hook else 0.0
            wr0 = top_ref[k, 3] if not torque_mode else 0.0
            vb0 = state[1, ib]
            wb0 = state[4, ib]
            if bit_known:
                # the record of the previous step evaluated the law at this state
                wob_e, tob_e = wob_k, tob_k
            else:
                if approx:
                    d_e = approx_depth_of_cut(vb0, wb0, bt)
                else:
                    d_e = rock_depth_at(surf, j_next, r_ref, r_h, r_nb, r_cap, r_nbl, ua_b0,
                                        th_b0)
                wob_e, tob_e = bit_forces(d_e, vb0, wb0, bt)
            bit_known = False
            for f in range(2):
                ru = 3 * f
                rc = 12 + 2 * f
                for i in range(n):
                    cg = Cg[f, i] + cfr[f, i] if n_ce > 0 else Cg[f, i]
                    fe[i] = Fst[f, i] - cg * state[ru + 1, i]
                for i in range(n - 1):
                    fl = (-mats[6 * f + 3, i]) * (state[ru, i + 1] - state[ru, i]) \
                        + (-mats[rc + 1, i]) * (state[ru + 1, i + 1] - state[ru + 1, i])
                    fe[i] += fl
                    fe[i + 1] -= fl
                if f == 0:
                    if vel_hook:
                        fe[it] += hk * (xr0 - state[0, it]) + hc * (vr0 - state[1, it])
                    else:
                        fe[it] += w_pre - xr0
                    fe[ib] -= wob_e
                else:
                    if torque_mode:
                        fe[it] += tr0
                    else:
                        fe[it] += ki * (tr0 - state[3, it]) + kp * (wr0 - state[4, it])
                    fe[ib] -= tob_e
                for i in range(n):
                    state[ru, i] += dt * state[ru + 1, i]
                    state[ru + 1, i] += dt * fe[i] / mats[6 * f, i]
                    state[ru + 2, i] = fe[i] / mats[6 * f, i]
        # ---- bit: depth of cut from the old state (axial: d(v1) = dax0 + drate v1)
        if euler:
            dax0 = 0.0
            drate = 0.0
        elif approx:
            dax0 = 0.0
            drate = approx_depth_rate(state[4, ib], bt)
        else:
            # d(t + dt) = n (x1 - s(theta1)): linear in x1 = x0 + h (v0 + v1); the surface
            # under the blades read at the angle the bit reaches at its present speed (exact at
            # steady rotation, so a steady state has the depth of cut 2 pi v / omega)
            dax0 = rock_depth_at(surf, j_next, r_ref, r_h, r_nb, r_cap, r_nbl,
                                 ua_b0 + h * state[1, ib], th_b0 + dt * state[4, ib])
            drate = drate_rock
        # ---- wave segment between B and C
        a_in = 0.0
        b_in = 0.0
        ta_in = 0.0
        tb_in = 0.0
        if hybrid:
            a_in, b_in = wave_read_at(wa_hist, pos_a, off_a, fr_a, cap_a, wa_wp.a_init,
                                      wa_wp.b_init)
            ta_in, tb_in = wave_read_at(wt_hist, pos_t, off_t, fr_t, cap_t, wt_wp.a_init,
                                        wt_wp.b_init)
            if nla > 0:
                b_in = _lag_cascade(lag, 0, nla, al_a, b_in)
                a_in = _lag_cascade(lag, 1, nla, al_a, a_in)
            if nlt > 0:
                tb_in = _lag_cascade(lag, 2, nlt, al_t, tb_in)
                ta_in = _lag_cascade(lag, 3, nlt, al_t, ta_in)
            sb, sc = wave_source_forces(za, a_in, b_in)
            tsb, tsc = wave_source_forces(zt, ta_in, tb_in)
            if iB == it:
                # the line starts at the top node (the neutral model): its forces add to the
                # hook and top-drive forces set above
                F[0, it] += sb
                F[1, it] += tsb
            else:
                F[0, iB] = Fst[0, iB] + sb
                F[1, iB] = tsb
            F[0, iC] = Fst[0, iC] + sc
            F[1, iC] = tsc
        if dist:
            # a force disturbance on the bit (noise on WOB and TOB), the command's columns 2, 3
            base = hybrid and iC == ib
            dwob = cmd[k, 2]
            dtob = cmd[k, 3]
            F[0, ib] = (F[0, ib] if base else Fst[0, ib]) - dwob
            F[1, ib] = (F[1, ib] if base else Fst[1, ib]) - dtob
        # ---- solve both fields: (M + h C + h^2 K + h C_x + h^2 K_x) v1 = rhs
        if euler:
            pass
        elif dense:
            for f in range(2):
                ru = 3 * f
                rm = 6 * f
                for i in range(n):
                    mv = mats[rm, i] * (state[ru + 1, i] + h * state[ru + 2, i])
                    ku = mats[rm + 2, i] * (state[ru, i] + h * state[ru + 1, i])
                    if i > 0:
                        mv += mats[rm + 1, i - 1] * (state[ru + 1, i - 1]
                                                     + h * state[ru + 2, i - 1])
                        ku += mats[rm + 3, i - 1] * (state[ru, i - 1] + h * state[ru + 1, i - 1])
                    if i < n - 1:
                        mv += mats[rm + 1, i] * (state[ru + 1, i + 1] + h * state[ru + 2, i + 1])
                        ku += mats[rm + 3, i] * (state[ru, i + 1] + h * state[ru + 1, i + 1])
                    rhs[i] = mv - h * ku + h * (F[f, i] - Kx[f, i] * h * state[ru + 1, i])
                if f == 0:
                    c0 = dax0
                    c1 = drate
                else:
                    va_new = state[1, ib]
                    if approx:
                        d1 = approx_depth_of_cut(va_new, state[4, ib], bt)
                    else:
                        d1 = dax0 + drate * va_new
                    c0 = d1
                    c1 = va_new
                for i in range(n):
                    for j in range(n):
                        Aw[i, j] = Ldense[f, i, j]
                    Aw[i, i] = Dst[f, i] + h * cfr[f, i] + (Ldense[f, i, i] - mats[rm + 4, i])
                # exact implicit bit force through the Schur complement on the bit node:
                # v = y1 - h F(x) y2 with A y1 = rhs, A y2 = e_bit, x = v_bit
                for i in range(n):
                    cw[i] = 0.0
                cw[ib] = 1.0
                _spd_solve2(Aw, rhs, cw, y, dd, n)
                den = 1.0 / dd[ib]
                x = solve_bit_node(f, den, den * y[ib], h, state[ru + 1, ib], c0, c1, bt,
                                   n_newton)
                if f == 0:
                    fb, _, _ = bit_wob(c0 + c1 * x, x, bt)
                else:
                    _, fb = bit_forces(c0, c1, x, bt)
                for i in range(n):
                    y[i] -= h * fb * dd[i]
                y[ib] = x
                # Newmark update: a1 = (v1 - v0)/h - a0, u1 = u0 + h (v0 + v1)
                for i in range(n):
                    vo = state[ru + 1, i]
                    vn = y[i]
                    state[ru + 2, i] = (vn - vo) * ih - state[ru + 2, i]
                    state[ru, i] += h * (vo + vn)
                    state[ru + 1, i] = vn
        else:
            # both fields at once (two independent dependency chains): rhs, forward sweeps
            # (factors precomputed above the first contact node), the exact implicit bit forces
            # on the last node (axial first: the torsional law needs the new bit axial speed),
            # back sweeps and the Newmark update
            for i in range(n):
                mva = mats[0, i] * (state[1, i] + h * state[2, i])
                kua = mats[2, i] * (state[0, i] + h * state[1, i])
                mvt = mats[6, i] * (state[4, i] + h * state[5, i])
                kut = mats[8, i] * (state[3, i] + h * state[4, i])
                if i > 0:
                    mva += mats[1, i - 1] * (state[1, i - 1] + h * state[2, i - 1])
                    kua += mats[3, i - 1] * (state[0, i - 1] + h * state[1, i - 1])
                    mvt += mats[7, i - 1] * (state[4, i - 1] + h * state[5, i - 1])
                    kut += mats[9, i - 1] * (state[3, i - 1] + h * state[4, i - 1])
                if i < n - 1:
                    mva += mats[1, i] * (state[1, i + 1] + h * state[2, i + 1])
                    kua += mats[3, i] * (state[0, i + 1] + h * state[1, i + 1])
                    mvt += mats[7, i] * (state[4, i + 1] + h * state[5, i + 1])
                    kut += mats[9, i] * (state[3, i + 1] + h * state[4, i + 1])
                rhs[i] = mva - h * kua + h * (F[0, i] - Kx[0, i] * h * state[1, i])
                rhs_t[i] = mvt - h * kut + h * (F[1, i] - Kx[1, i] * h * state[4, i])
            for i in range(p_var):
                ra = rhs[i]
                rt = rhs_t[i]
                if i > 0:
                    ra -= mats[5, i - 1] * y[i - 1]
                    rt -= mats[11, i - 1] * y_t[i - 1]
                y[i] = ra * invc[0, i]
                y_t[i] = rt * invc[1, i]
                cw[i] = cwc[0, i]
                cw_t[i] = cwc[1, i]
            dena = 1.0
            dent = 1.0
            ra = 0.0
            rt = 0.0
            for i in range(p_var, n):
                dena = Dst[0, i] + h * cfr[0, i]
                dent = Dst[1, i] + h * cfr[1, i]
                ra = rhs[i]
                rt = rhs_t[i]
                if i > 0:
                    dena -= mats[5, i - 1] * cw[i - 1]
                    ra -= mats[5, i - 1] * y[i - 1]
                    dent -= mats[11, i - 1] * cw_t[i - 1]
                    rt -= mats[11, i - 1] * y_t[i - 1]
                if i < ib:
                    inva = 1.0 / dena
                    invt = 1.0 / dent
                    cw[i] = mats[5, i] * inva
                    y[i] = ra * inva
                    cw_t[i] = mats[11, i] * invt
                    y_t[i] = rt * invt
            va_new = solve_bit_node(0, dena, ra, h, state[1, ib], dax0, drate, bt, n_newton)
            if approx:
                d1 = approx_depth_of_cut(va_new, state[4, ib], bt)
            else:
                d1 = dax0 + drate * va_new
            y[ib] = va_new
            y_t[ib] = solve_bit_node(1, dent, rt, h, state[4, ib], d1, va_new, bt, n_newton)
            for i in range(n - 2, -1, -1):
                y[i] -= cw[i] * y[i + 1]
                y_t[i] -= cw_t[i] * y_t[i + 1]
            for i in range(n):
                vo = state[1, i]
                vn = y[i]
                state[2, i] = (vn - vo) * ih - state[2, i]
                state[0, i] += h * (vo + vn)
                state[1, i] = vn
                vo = state[4, i]
                vn = y_t[i]
                state[5, i] = (vn - vo) * ih - state[5, i]
                state[3, i] += h * (vo + vn)
                state[4, i] = vn
        if not approx:
            j_next = rock_advance_to(surf, j_next, r_ref, r_h, r_nb, r_cap, r_mem, th_b0,
                                       ua_b0, state[3, ib], state[0, ib])
        if hybrid:
            f_b, f_c = wave_step_at(wa_hist, pos_a, cap_a, za, state[1, iB], state[1, iC], a_in,
                                    b_in)
            pos_a += 1
            fb_line = fb0 + f_b
            fc_line = -fc0 - f_c
            # reported torque GJ (theta_up - theta_down)/L is minus the line's N
            f_b, f_c = wave_step_at(wt_hist, pos_t, cap_t, zt, state[4, iB], state[4, iC], ta_in,
                                    tb_in)
            pos_t += 1
            tb_line = -f_b
            tc_line = f_c
        t_now += dt
        n_done += 1.0
        # ---- record
        countdown -= 1
        if countdown == 0:
            countdown = rec_every
            vab = state[1, ib]
            vtb = state[4, ib]
            if not (math.isfinite(vab) and math.isfinite(vtb) and math.isfinite(state[0, it])):
                status = 1
                break
            if approx:
                dn = approx_depth_of_cut(vab, vtb, bt)
            else:
                dn = rock_depth_at(surf, j_next, r_ref, r_h, r_nb, r_cap, r_nbl, state[0, ib],
                                     state[3, ib])
            wn, tn = bit_forces(dn, vab, vtb, bt)
            if euler:
                bit_known = True
                wob_k = wn
                tob_k = tn
            rec[row, 0] = state[0, ib] - ubit0
            rec[row, 1] = vab
            rec[row, 2] = state[3, ib]
            rec[row, 3] = vtb
            rec[row, 4] = dn
            rec[row, 5] = wn + dwob
            rec[row, 6] = tn + dtob
            if given and vel_hook:
                rec[row, 7] = (h0 + w_pre) - (hk * (x_ref - state[0, it])
                                              + hc * (cax - state[1, it]))
                rec[row, 9] = cax
            elif vel_hook:
                rec[row, 7] = (h0 + w_pre) - hk * (x_ref - state[0, it]) \
                    - hc * (cax - state[1, it])
                rec[row, 9] = state[1, it]
            else:
                rec[row, 7] = cax
                rec[row, 9] = state[1, it]
            if given and not torque_mode:
                rec[row, 8] = ki * (th_ref - state[3, it]) + kp * (ctq - state[4, it])
                rec[row, 10] = ctq
            elif given:
                rec[row, 8] = ctq
                rec[row, 10] = state[4, it]
            else:
                if hybrid and iB == it:
                    rec[row, 8] = tb_line  # the line's torque at the top node
                else:
                    rec[row, 8] = (mats[9, it] * (state[3, it + 1] - state[3, it]) if n > 1
                                   else 0.0)
                rec[row, 10] = state[4, it]
            if hybrid:
                rec[row, 11] = fb_line
                rec[row, 12] = tb_line
                rec[row, 13] = fc_line
                rec[row, 14] = tc_line
            else:
                rec[row, 11] = _mid_tension(mats[3], state[0], iB)
                rec[row, 12] = _mid_torque(mats[9], state[3], iB)
                rec[row, 13] = _mid_tension(mats[3], state[0], iC)
                rec[row, 14] = _mid_torque(mats[9], state[3], iC)
            rec[row, 15] = state[3, it]
            rec[row, 16] = omega_ref
            row += 1
    rs.time = t_now
    rs.x_ref = x_ref
    rs.theta_ref = th_ref
    rs.soft_lowpass = lowp
    rs.step = n_done
    istate[0] = j_next
    wa_pos[0] = pos_a
    wt_pos[0] = pos_t
    return status, row - rec_start
