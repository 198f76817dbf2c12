"""DHP on the directional FEM / hybrid models (seed Ch. 4 design, Ch. 6 validation).

- :func:`directional_affine_model`: the non-dimensional control-affine design model of a
  :class:`~downhole.string.fem.DirectionalModel` (same physics as its export by
  :func:`downhole.control.affine.from_directional`:
  ZOH linear part, bit law with the approximated depth of cut and its floor, soft-string
  friction with the hanging tension) in the structured form ``h = forces(z) @ force_map.T``
  with the forces compiled (numba) and vectorized over the batch of samples. The DHP trainer
  evaluates the forces on N_S samples at each of 40 000 steps; the export's per-sample Python
  loop would dominate the training time.
- :class:`DirectionalStatePlant`: a :class:`~downhole.string.fem.DirectionalPlant` (force-driven
  hook with zero initial WOB, torque-driven top drive) whose observations also carry the full
  design-model state ``"state"`` (deviations from the hanging equilibrium, interpolated along
  measured depth from the plant's nodes to the design model's nodes: for a 68-state hybrid
  plant and a 24-state design model this is the Ch. 6 set-up). Commands are the controller's
  ``slack_off_force`` and ``surface_torque``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from downhole.bit.law import approx_depth_of_cut, bit_forces
from downhole.contact.softstring import contact_elements, element_normal_half, friction_damper
from downhole.control.affine import ControlAffineModel, directional_state_layout
from downhole.control.dhp.riccati import _draw_one, _fit_one
from downhole.errors import DownholeInputError
from downhole.params.rig import DEFAULT_TOP_DRIVE_INERTIA
from downhole.sim.plant import Plant
from downhole.units import si_or_number

__all__ = ["DirectionalStatePlant", "directional_affine_model", "table_5_1_models"]


@njit(cache=True, nogil=True, error_model="numpy")
def _directional_forces(WT, P0, P1, bitp, tension, koff, elem, radius, mu, v_eps, contact,
                        nodes, out):
    """Active nodal forces (N, q) of the bit and the wellbore friction.

    The samples come transposed, one row per state: WT (n, N), and state i of sample s is
    ``P0[i] + P1[i] * WT[i, s]`` in physical units (a non-dimensional batch zb: WT = zb^T,
    P0 = 0, P1 = P; the trainer's samples z = r + radius * w: WT = w^T, P0 = P r,
    P1 = P radius), so the loops over samples read contiguous rows.
    ``nodes`` (q/2,): the nodes whose force pair [axial, torque] is a column pair of ``out``
    (the bit node and the nodes of contact elements, in increasing order); ``contact`` (E,):
    the contact elements. The other nodes carry no nonlinear force (their columns would be
    identically zero), so the design model leaves them out. Samples are processed in blocks
    with the sample index innermost (vectorized square roots)."""
    N = WT.shape[1]
    n = radius.shape[0]
    ib = n - 1
    q2 = nodes.shape[0]
    slot = np.full(n, -1)
    for j in range(q2):
        slot[nodes[j]] = j
    BS = 64
    normal = np.empty((q2, BS))
    vax = np.empty(BS)
    vtr = np.empty(BS)
    iva = 2 * n + 2 * ib
    jb = slot[ib]
    for s0 in range(0, N, BS):
        nb = min(BS, N - s0)
        for t in range(nb):
            s = s0 + t
            for j in range(2 * q2):
                out[s, j] = 0.0
            va = P0[iva] + P1[iva] * WT[iva, s]
            vt = P0[iva + 1] + P1[iva + 1] * WT[iva + 1, s]
            d = approx_depth_of_cut(va, vt, bitp)
            w, tq = bit_forces(d, va, vt, bitp)
            out[s, 2 * jb] = -w
            out[s, 2 * jb + 1] = -tq
        if not (mu > 0.0 and contact.shape[0] > 0):
            continue
        normal[:, :nb] = 0.0
        for e in contact:
            i0 = 2 * e
            i1 = 2 * (e + 1)
            w0 = WT[i0]
            w1 = WT[i1]
            d0 = P0[i1] - P0[i0]
            p0 = P1[i0]
            p1 = P1[i1]
            te = tension[e]
            ke = koff[e]
            sa = slot[e]
            sb = slot[e + 1]
            for t in range(nb):
                dx = d0 + w1[s0 + t] * p1 - w0[s0 + t] * p0
                half = element_normal_half(elem, e, te - ke * dx)
                normal[sa, t] += half
                normal[sb, t] += half
        for j in range(q2):
            i = nodes[j]
            ia = 2 * n + 2 * i
            wa = WT[ia]
            wt = WT[ia + 1]
            oa, sa_ = P0[ia], P1[ia]
            ot, st_ = P0[ia + 1], P1[ia + 1]
            r = radius[i]
            for t in range(nb):
                vax[t] = oa + sa_ * wa[s0 + t]
                vtr[t] = ot + st_ * wt[s0 + t]
            for t in range(nb):
                c = friction_damper(normal[j, t], mu, vax[t], r * vtr[t], v_eps)
                vax[t] = c * vax[t]
                vtr[t] = c * r * r * vtr[t]
            for t in range(nb):
                out[s0 + t, 2 * j] -= vax[t]
                out[s0 + t, 2 * j + 1] -= vtr[t]


@njit(cache=True, nogil=True)
def _directional_sample_fit(seed, set_ids, ref, radius, ns, Vr, c0, Y, P, bitp, tension, koff,
                            elem, rnode, mu, v_eps, contact, nodes):
    """Fused DHP sample step for the directional model: for every step j, draw the step's fresh
    samples, evaluate the forces on them (read from the design matrix: z = r_k + radius w) and
    fit them (see :mod:`downhole.control.dhp.riccati`); the samples of one step stay in cache.
    Returns the first singular step or -1."""
    K = set_ids.shape[0]
    n = ref.shape[1]
    p = n + 1
    q = 2 * nodes.shape[0]
    Phi = np.empty((p, ns))
    F = np.empty((ns, q))
    U = np.empty((p, p))
    B = np.empty((p, q))
    P0 = np.empty(n)
    P1 = np.empty(n)
    for i in range(n):
        P1[i] = P[i] * radius[i]
    for j in range(K):
        refj = ref[j]
        for i in range(n):
            P0[i] = P[i] * refj[i]
        _draw_one(seed, set_ids[j], Phi)
        _directional_forces(Phi[1:], P0, P1, bitp, tension, koff, elem, rnode, mu, v_eps,
                            contact, nodes, F)
        if not _fit_one(Phi, F, Vr, c0[j], Y[j], U, B, j == 0 or set_ids[j] != set_ids[j - 1]):
            return j
    return -1


def directional_affine_model(dmodel, dt: float = 1e-3, *, state_scale=None,
                             input_scale=(1e5, 1e4),
                             top_drive_inertia: float = DEFAULT_TOP_DRIVE_INERTIA,
                             friction: bool = True, v_eps_design: float = 0.05,
                             input_limits=((-5e4, 3e5), (-6e4, 6e4))) -> ControlAffineModel:
    """Compiled, structured control-affine design model of a directional FEM / hybrid model.

    Same model as ``from_directional(dmodel, dt, ...)`` (a test checks that both give the same
    f), with the nonlinear forces as ``forces`` (N, q) and their ZOH map as ``force_map``
    (n, q): only the force pairs that can be non-zero (the bit node and the nodes of the
    contact elements; ``metadata["force_nodes"]``), so that the DHP trainer fits no
    identically-zero force column.

    Parameters
    ----------
    dmodel : DirectionalModel
        A FEM (used as is) or a hybrid (its ``design_model()``: the FEM on the same nodes).
    dt : float
        Step, s.
    state_scale : array_like, optional
        P of Eq. 4.17; default 0.05 m, 30 rad, 0.02 m/s, 20 rad/s per kind (as the export).
    input_scale : (float, float)
        Input scale (N, N m).
    top_drive_inertia : float
        kg m^2 on the top node's angular DOF.
    friction : bool
        Include the wellbore friction.
    v_eps_design : float
        Friction regularization of the design model, m/s.
    input_limits : ((float, float), (float, float)) or None
        Slack-off force (N) and surface torque (N m) bounds applied online (docs/seed-errata.md:
        -50..300 kN, +/-60 kN m).

    Returns
    -------
    ControlAffineModel
    """
    from downhole.string.fem import hanging_tension

    m = dmodel.design_model()
    n = m.n_nodes
    A_d, B_d = dmodel.linear_model(dt, top_drive_inertia)
    A, _, names, _ = dmodel.continuous_linear_model(top_drive_inertia)
    ns = A.shape[0]
    Gam = dmodel.nodal_force_map(dt, top_drive_inertia)
    kinds, nodes, state_scale = directional_state_layout(n, state_scale)
    P = np.ascontiguousarray(np.broadcast_to(np.asarray(state_scale, float), (ns,)))
    bitp = m.bit.kernel_params()
    tension = np.ascontiguousarray(hanging_tension(m), dtype=float)
    koff = np.ascontiguousarray(m.Ka[1, :n - 1], dtype=float)
    elem = np.ascontiguousarray(m.elem, dtype=float)
    radius = np.ascontiguousarray(m.radius, dtype=float)
    mu = float(m.mu) if friction else 0.0
    # contact elements whose normal force can be non-zero (the kernel's selection)
    contact = contact_elements(elem) if mu > 0.0 else np.zeros(0, dtype=np.int64)
    act = np.unique(np.concatenate([[n - 1], contact, contact + 1])).astype(np.int64)
    cols = np.ravel(np.column_stack([2 * act, 2 * act + 1]))
    Gam = np.ascontiguousarray(Gam[:, cols])

    zero = np.zeros(ns)

    def forces(zb):
        zb = np.asarray(zb, dtype=float)
        out = np.empty((zb.shape[0], 2 * act.size))
        _directional_forces(np.ascontiguousarray(zb.T), zero, P, bitp, tension, koff, elem,
                            radius, mu, float(v_eps_design), contact, act, out)
        return out

    def sample_fit(seed, set_ids, ref, radius_s, ns, Vr, c0, Y):
        return _directional_sample_fit(int(seed), np.ascontiguousarray(set_ids, dtype=np.int64),
                                       np.ascontiguousarray(ref), radius_s, int(ns), Vr, c0, Y,
                                       P, bitp, tension, koff, elem, radius, mu,
                                       float(v_eps_design), contact, act)

    model = ControlAffineModel.from_physical(
        A_d, B_d, state_scale=P, input_scale=input_scale, dt=dt, force_map=Gam, forces=forces,
        state_names=names, state_kinds=kinds, state_nodes=nodes,
        input_names=["slack_off_force", "surface_torque"], bit=m.bit,
        hanging_hook_load=m.buoyed_weight, node_depths=m.node_md, input_limits=input_limits,
        name=f"{dmodel.name} design ({m.n_states} states)",
        metadata={"family": "directional", "model": dmodel.name, "kind": dmodel.kind,
                  "n_nodes": n, "force_nodes": act.tolist()})
    # compiled samples + forces + fit of the DHP trainer (same numbers as the generic path)
    model.sample_fit = sample_fit
    return model


def table_5_1_models():
    """The Table 5.1 well as the 24-state FEM (design model and plant) and the 68-state hybrid.

    The 24-state FEM is the hybrid24 preset's design FEM: 6 nodes at 0, 2000 (B), 3000 (C) m and
    three more along the arc CD to the bit (5094 m)."""
    from downhole.string.hybrid import hybrid_model

    fem24 = hybrid_model("hybrid24").design_model()
    hyb68 = hybrid_model("hybrid68")
    return fem24, hyb68


class DirectionalStatePlant(Plant):
    """A directional plant that reports the design model's full state and takes DHP commands
    (the :class:`~downhole.sim.plant.Plant` contract: commands ``slack_off_force`` (N, the
    hook load is the buoyed weight minus it) and ``surface_torque`` (N m); observations the
    inner :class:`~downhole.string.fem.DirectionalPlant`'s plus ``state``).

    Parameters
    ----------
    dmodel : DirectionalModel
        The plant (FEM or hybrid, any node count).
    design : ControlAffineModel
        The controller's design model (its ``node_depths`` and state layout).
    dt : float
        Step, s.
    depth_of_cut : {"delayed", "approximate"}
        ``delayed`` is the true plant; ``approximate`` the design model's bit law.
    top_drive_inertia : float
        kg m^2 (must match the design model's).
    """

    def __init__(self, dmodel, design: ControlAffineModel, dt: float = 1e-3, *,
                 depth_of_cut: str = "delayed",
                 top_drive_inertia: float = DEFAULT_TOP_DRIVE_INERTIA):
        dt = si_or_number(dt, "time", "dt")  # "0.5 ms" or a pint quantity
        from downhole.control.topdrive import Hook, TopDrive
        from downhole.string.fem import DirectionalPlant

        if design.node_depths is None:
            raise DownholeInputError("the design model has no node_depths; it must come from "
                                     "directional_affine_model or control.affine.from_directional")
        self.plant = DirectionalPlant(dmodel, dt, top_drive=TopDrive(mode="torque",
                                                                     inertia=top_drive_inertia),
                                      hook=Hook(mode="force", wob=0.0),
                                      depth_of_cut=depth_of_cut)
        self.dmodel, self.design, self.dt = dmodel, design, float(dt)
        self.weight = float(dmodel.buoyed_weight)
        self._md = np.asarray(dmodel.node_md, float)
        self._dmd = np.asarray(design.node_depths, float)
        if self._dmd.max() > self._md.max() + 1e-6 or self._dmd.min() < self._md.min() - 1e-6:
            raise DownholeInputError("design node depths lie outside the plant's nodes")
        self._ref = None

    def _state(self) -> np.ndarray:
        f = self.plant.node_fields()
        if self._ref is None:
            self._ref = f["axial_position"]
        n = self._dmd.size
        z = np.empty(4 * n)
        z[0:2 * n:2] = np.interp(self._dmd, self._md, f["axial_position"] - self._ref)
        z[1:2 * n:2] = np.interp(self._dmd, self._md, f["angle"])
        z[2 * n::2] = np.interp(self._dmd, self._md, f["axial_velocity"])
        z[2 * n + 1::2] = np.interp(self._dmd, self._md, f["angular_velocity"])
        return z

    command_names = ("slack_off_force", "surface_torque")

    @property
    def observation_names(self) -> tuple:
        return (*self.plant.observation_names, "state")

    def _reset(self, start: str, set_point: dict, **options) -> dict:
        obs = self.plant.reset(start=start, set_point={
            "hook_load": self.weight - set_point["slack_off_force"],
            "surface_torque": set_point["surface_torque"]}, **options)
        self._ref = None
        obs["state"] = self._state()
        return obs

    def _step(self, command: np.ndarray) -> dict:
        obs = self.plant.step({"hook_load": self.weight - command[0],
                               "surface_torque": command[1]})
        obs["state"] = self._state()
        return obs
