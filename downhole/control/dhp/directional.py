"""DHP on the directional FEM / hybrid models (seed Ch. 4 design, Ch. 6 validation).

- :func:`directional_affine_model`: the non-dimensional control-affine design model of a
  :class:`~downhole.string.fem.DirectionalModel` (same physics as its ``control_affine`` export:
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

import math

import numpy as np
from numba import njit
from scipy.linalg import expm

from downhole.bit.detournay import approx_depth_of_cut, bit_forces
from downhole.control.affine import ControlAffineModel
from downhole.errors import DownholeInputError

__all__ = ["directional_affine_model", "DirectionalStatePlant", "table_5_1_models"]


@njit(cache=True)
def _directional_forces(zb, P, bitp, tension, koff, elem, radius, mu, v_eps, out):
    """Nodal forces (N, 2n) [axial_1, torque_1, ...] of the bit and wellbore friction."""
    N = zb.shape[0]
    n = radius.shape[0]
    ib = n - 1
    for s in range(N):
        for j in range(2 * n):
            out[s, j] = 0.0
        va = zb[s, 2 * n + 2 * ib] * P[2 * n + 2 * ib]
        vt = zb[s, 2 * n + 2 * ib + 1] * P[2 * n + 2 * ib + 1]
        d = approx_depth_of_cut(va, vt, bitp)
        w, t = bit_forces(d, va, vt, bitp)
        out[s, 2 * ib] -= w
        out[s, 2 * ib + 1] -= t
        if mu > 0.0:
            for e in range(n - 1):
                if elem[e, 7] < 0.5:
                    continue
                dx = zb[s, 2 * (e + 1)] * P[2 * (e + 1)] - zb[s, 2 * e] * P[2 * e]
                T = tension[e] - koff[e] * dx
                a0 = T * elem[e, 1] + elem[e, 4]
                a1 = T * elem[e, 2] + elem[e, 5]
                a2 = T * elem[e, 3] + elem[e, 6]
                half = 0.5 * elem[e, 0] * math.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
                for i in (e, e + 1):
                    vax = zb[s, 2 * n + 2 * i] * P[2 * n + 2 * i]
                    vtr = zb[s, 2 * n + 2 * i + 1] * P[2 * n + 2 * i + 1]
                    r = radius[i]
                    den = math.sqrt(vax * vax + (r * vtr) ** 2 + v_eps * v_eps)
                    c = mu * half / den
                    out[s, 2 * i] -= c * vax
                    out[s, 2 * i + 1] -= c * r * r * vtr


def directional_affine_model(dmodel, dt: float = 1e-3, *, state_scale=None,
                             input_scale=(1e5, 1e4), top_drive_inertia: float = 500.0,
                             friction: bool = True, v_eps_design: float = 0.05,
                             input_limits=((-5e4, 3e5), (-6e4, 6e4))) -> ControlAffineModel:
    """Compiled, structured control-affine design model of a directional FEM / hybrid model.

    Same model as ``dmodel.control_affine(dt, ...)`` (a test checks that both give the same
    f), with the nonlinear forces as ``forces`` (N, 2n) and their ZOH map as ``force_map``.

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
        Slack-off force (N) and surface torque (N m) bounds applied online (SPEC.md: -50..300 kN,
        +/-60 kN m).

    Returns
    -------
    ControlAffineModel
    """
    from downhole.string.fem import _hanging_tension

    m = dmodel.design_model()
    n = m.n_nodes
    A_d, B_d = dmodel.linear_model(dt, top_drive_inertia)
    A, _, names, Minv = dmodel.continuous_linear_model(top_drive_inertia)
    ns = A.shape[0]
    Bf = np.vstack([np.zeros((2 * n, 2 * n)), Minv])
    aug = np.zeros((ns + 2 * n, ns + 2 * n))
    aug[:ns, :ns] = A
    aug[:ns, ns:] = Bf
    Gam = expm(aug * dt)[:ns, ns:]
    kinds, nodes = [], []
    for blk in ("position", "velocity"):
        for i in range(n):
            kinds += [f"axial_{blk}", f"angular_{blk}"]
            nodes += [i, i]
    if state_scale is None:
        base = {"axial_position": 0.05, "angular_position": 30.0, "axial_velocity": 0.02,
                "angular_velocity": 20.0}
        state_scale = np.array([base[k] for k in kinds])
    P = np.ascontiguousarray(np.broadcast_to(np.asarray(state_scale, float), (ns,)))
    bitp = m.bit.to_array()
    tension = np.ascontiguousarray(_hanging_tension(m), dtype=float)
    koff = np.ascontiguousarray(m.Ka[1, :n - 1], dtype=float)
    elem = np.ascontiguousarray(m.elem, dtype=float)
    radius = np.ascontiguousarray(m.radius, dtype=float)
    mu = float(m.mu) if friction else 0.0

    def forces(zb):
        zb = np.ascontiguousarray(zb, dtype=float)
        out = np.empty((zb.shape[0], 2 * n))
        _directional_forces(zb, P, bitp, tension, koff, elem, radius, mu, float(v_eps_design),
                            out)
        return out

    return ControlAffineModel.from_physical(
        A_d, B_d, state_scale=P, input_scale=input_scale, dt=dt, force_map=Gam, forces=forces,
        state_names=names, state_kinds=kinds, state_nodes=nodes,
        input_names=["slack_off_force", "surface_torque"], bit=m.bit,
        hanging_hook_load=m.buoyed_weight, node_depths=m.node_md, input_limits=input_limits,
        name=f"{dmodel.name} design ({m.n_states} states)",
        metadata={"family": "directional", "model": dmodel.name, "kind": dmodel.kind,
                  "n_nodes": n})


def table_5_1_models():
    """The Table 5.1 well as the 24-state FEM (design model and plant) and the 68-state hybrid.

    The 24-state FEM is the hybrid24 preset's design FEM: 6 nodes at 0, 2000 (B), 3000 (C) m and
    three more along the arc CD to the bit (5094 m)."""
    from downhole.string.hybrid import hybrid_model

    fem24 = hybrid_model("hybrid24").design_model()
    hyb68 = hybrid_model("hybrid68")
    return fem24, hyb68


class DirectionalStatePlant:
    """A directional plant that reports the design model's full state and takes DHP commands.

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
                 depth_of_cut: str = "delayed", top_drive_inertia: float = 500.0):
        from downhole.control.topdrive import Hook, TopDrive
        from downhole.string.fem import DirectionalPlant

        if design.node_depths is None:
            raise DownholeInputError("the design model has no node_depths; it must come from "
                                     "directional_affine_model or DirectionalModel.control_affine")
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
        s = self.plant._st["state"]  # rows: ua, va, aa, ut, vt, at (DirectionalPlant internals)
        if self._ref is None:
            self._ref = s[0].copy()
        n = self._dmd.size
        z = np.empty(4 * n)
        z[0:2 * n:2] = np.interp(self._dmd, self._md, s[0] - self._ref)
        z[1:2 * n:2] = np.interp(self._dmd, self._md, s[3])
        z[2 * n::2] = np.interp(self._dmd, self._md, s[1])
        z[2 * n + 1::2] = np.interp(self._dmd, self._md, s[4])
        return z

    def reset(self) -> dict:
        obs = self.plant.reset()
        self._ref = None
        obs["state"] = self._state()
        return obs

    def step(self, command: dict) -> dict:
        try:
            slack = float(command["slack_off_force"])
            torque = float(command["surface_torque"])
        except KeyError as exc:
            raise DownholeInputError(f"command lacks {exc.args[0]!r}; expected "
                                     "slack_off_force and surface_torque") from None
        obs = self.plant.step({"hook_load": self.weight - slack, "surface_torque": torque})
        obs["state"] = self._state()
        return obs
