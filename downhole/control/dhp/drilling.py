"""Drilling specifics of the DHP design (seed Sec. 4.3.1-4.3.2, 4.4): models, references, weights.

- :func:`lumped_affine_model`: the 4th-order lumped string (Eq. 2.1, deviations from the hanging
  equilibrium) as a :class:`ControlAffineModel` with the approximated depth of cut and its floor
  (Eq. 4.16), zero-order-hold discretization and the non-dimensionalization of Eqs. 4.17-4.19.
- :func:`reference_states`: the reference transform of Eqs. 4.21-4.23 (all positions follow
  x_d = int v_d, alpha_d = int omega_d; all velocities follow v_d, omega_d; non-dimensional).
  The "rotation" R_i of Eq. 4.22 is the identity: downhole models both fields along the measured
  depth (docs/seed-errata.md: the cos-rotation of Eqs. 4.3-4.5 is not a valid transformation).
- :func:`feed_forward`: the steady-state inputs u_ff that keep the model on the reference.
- :class:`PenaltyWeights` / :func:`penalty_matrices`: the diagonal layout of Eq. 4.45 and
  Table 4.1 (weights on the top, selected nodes and the bit), and :func:`table_4_1_weights`
  (the seed's numbers, for comparison: with physical inputs they violate the contraction
  condition, see :mod:`downhole.control.dhp.trainer`).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from numba import njit

from downhole.bit.law import approx_depth_of_cut, bit_forces
from downhole.control.affine import ControlAffineModel
from downhole.errors import DownholeInputError
from downhole.params.bit import BitKernelParams, BitParams
from downhole.params.lumped import LumpedParams
from downhole.string.zoh import zoh

__all__ = [
    "INTEGRAL_STATE_NAMES",
    "PenaltyWeights",
    "feed_forward",
    "integral_augmented_model",
    "lumped_affine_model",
    "penalty_matrices",
    "reference_states",
    "table_4_1_weights",
    "zoh",
]


@njit(cache=True)
def _bit_batch(v, w, p, out):
    for i in range(v.shape[0]):
        d = approx_depth_of_cut(v[i], w[i], p)
        wob, tob = bit_forces(d, v[i], w[i], p)
        out[i, 0] = wob
        out[i, 1] = tob
        out[i, 2] = d


def bit_forces_batch(v, omega, bit: BitParams | BitKernelParams) -> np.ndarray:
    """WOB, TOB (N, N m) and approximated depth of cut (m) for arrays of bit velocities.

    Returns an array (N, 3). The depth of cut is d = 2 pi v / max(omega, omega*) (Eq. 4.16)."""
    p = bit.kernel_params() if isinstance(bit, BitParams) else bit
    v = np.ascontiguousarray(np.asarray(v, float).ravel())
    w = np.ascontiguousarray(np.asarray(omega, float).ravel())
    out = np.empty((v.size, 3))
    _bit_batch(v, w, p, out)
    return out


def lumped_affine_model(string: str | LumpedParams = "table_2_1", bit: BitParams | None = None,
                        *, dt: float = 1e-3, state_scale=None, input_scale=None,
                        name: str | None = None) -> ControlAffineModel:
    """4th-order lumped drill string (Eq. 2.1) as a non-dimensional control-affine model.

    States (physical, deviations from the hanging equilibrium): bit axial position x (m, down),
    bit axial velocity v (m/s), bit angle theta (rad), bit angular velocity omega (rad/s).
    Inputs: top-drive axial displacement u1 (m) and angle u2 (rad) from the hanging position:

        M dv/dt = K_a (u1 - x) - C_a v - WOB(v, omega)
        I domega/dt = K_t (u2 - theta) - C_t omega - TOB(v, omega)

    with WOB, TOB from :func:`downhole.bit.bit_forces` at the approximated depth of cut
    2 pi v / max(omega, omega*) (Eq. 4.16). The linear part is discretized exactly (ZOH); the bit
    forces are held over the step (their ZOH map is ``force_map``).

    Parameters
    ----------
    string : str or LumpedParams
        Preset name (``"table_2_1"``, ``"plausible_lumped"``) or parameters.
    bit : BitParams, optional
        Default: the preset's bit.
    dt : float
        Time step, s.
    state_scale : array_like (4,), optional
        P of Eq. 4.17; default [1 m, 0.02 m/s, 1000 rad, 40 rad/s] (typical maxima over a 40 s
        horizon at the seed's references).
    input_scale : array_like (2,), optional
        Default [0.1 m, 10 rad].

    Returns
    -------
    ControlAffineModel
    """
    if isinstance(string, str):
        from downhole.params import get_preset

        pre = get_preset(string)
        if pre.kind != "lumped":
            raise DownholeInputError(f"preset {string!r} is a {pre.kind} preset; "
                                     "lumped_affine_model needs a lumped one")
        params, bit = pre.string, bit or pre.bit
        label = string
    else:
        if not isinstance(string, LumpedParams):
            raise DownholeInputError(f"string must be a preset name or LumpedParams, got "
                                     f"{type(string).__name__}")
        if bit is None:
            raise DownholeInputError("bit parameters are required with explicit LumpedParams")
        params, label = string, "custom"
    M, inertia = params.mass, params.inertia
    ka, ca, kt, ct = (params.axial_stiffness, params.axial_damping, params.torsional_stiffness,
                      params.torsional_damping)
    Ac = np.array([[0, 1, 0, 0], [-ka / M, -ca / M, 0, 0], [0, 0, 0, 1],
                   [0, 0, -kt / inertia, -ct / inertia]], dtype=float)
    Bc = np.array([[0, 0, 0, 0], [ka / M, 0, -1.0 / M, 0], [0, 0, 0, 0],
                   [0, kt / inertia, 0, -1.0 / inertia]], dtype=float)
    Ad, Bd_all = zoh(Ac, Bc, dt)
    Bd, Fd = Bd_all[:, :2], Bd_all[:, 2:]
    P = np.array([1.0, 0.02, 1000.0, 40.0]) if state_scale is None else state_scale
    U = np.array([0.1, 10.0]) if input_scale is None else input_scale
    P = np.asarray(P, dtype=float)
    bitp = bit.kernel_params()
    Pv, Pw = float(P[1]), float(P[3])

    def forces(zb, _p=bitp, _Pv=Pv, _Pw=Pw):
        out = bit_forces_batch(zb[:, 1] * _Pv, zb[:, 3] * _Pw, _p)
        return out[:, :2]

    weight = params.mass * params.g

    def outputs(z, u, _p=bitp, _ka=ka, _kt=kt, _w=weight, _dt=dt):
        f = bit_forces_batch(z[:, 1], z[:, 3], _p)
        du = np.diff(u, axis=0, prepend=u[:1] * 0.0) / _dt
        return {"wob": f[:, 0], "tob": f[:, 1], "depth_of_cut": f[:, 2],
                "hook_load": _w - _ka * (u[:, 0] - z[:, 0]),
                "surface_torque": _kt * (u[:, 1] - z[:, 2]),
                "top_drive_axial_velocity": du[:, 0], "top_drive_angular_velocity": du[:, 1]}

    return ControlAffineModel.from_physical(
        Ad, Bd, state_scale=P, input_scale=U, dt=dt, force_map=Fd, forces=forces,
        state_names=["bit_axial_position", "bit_axial_velocity", "bit_angle",
                     "bit_angular_velocity"],
        state_kinds=["axial_position", "axial_velocity", "angular_position", "angular_velocity"],
        state_nodes=[1, 1, 1, 1], bit_node=1,
        input_names=["top_drive_axial_displacement", "top_drive_angle"], bit=bit,
        hanging_hook_load=weight, outputs=outputs,
        name=name or f"lumped {label} (4 states)",
        metadata={"family": "lumped", "preset": label, "axial_stiffness": ka,
                  "torsional_stiffness": kt})


# ------------------------------------------------------------------------------ references
def reference_states(model: ControlAffineModel, v_d, omega_d, x_d, alpha_d) -> np.ndarray:
    """Non-dimensional state reference (Eqs. 4.21-4.23) over time samples.

    Parameters
    ----------
    model : ControlAffineModel
    v_d, omega_d : array_like (T,)
        Desired bit axial (m/s) and angular (rad/s) velocities.
    x_d, alpha_d : array_like (T,)
        Their integrals (m, rad): the desired positions of every node (deviation states).

    Returns
    -------
    ndarray (T, n)
        r-bar: positions of all nodes at x_d / alpha_d, velocities at v_d / omega_d, "other"
        states at 0, each divided by its scale P_i.
    """
    cols = {"axial_position": x_d, "angular_position": alpha_d, "axial_velocity": v_d,
            "angular_velocity": omega_d}
    arrs = {k: np.asarray(v, dtype=float) for k, v in cols.items()}
    T = arrs["axial_velocity"].shape[0]
    for k, a in arrs.items():
        if a.shape != (T,):
            raise DownholeInputError(f"reference arrays must all have shape ({T},); "
                                     f"{k} has {a.shape}")
    r = np.zeros((T, model.n_states))
    for i, kind in enumerate(model.state_kinds):
        if kind in arrs:
            r[:, i] = arrs[kind]
    return r / model.state_scale


def feed_forward(model: ControlAffineModel, reference: np.ndarray,
                 regularization: float = 1e-3, *, return_reference: bool = False,
                 iterations: int = 3):
    """Steady-state feed-forward u_ff,k (non-dimensional) along a non-dimensional reference.

    Solves, for every step, f(r_k + E d_k) + g u_k = r_{k+1} + E d_k for the input u_k and the
    position offsets d_k (E selects the position states: the string's static deflection - twist
    and stretch - under the bit and contact forces). The positions of a free string are
    determined up to a rigid shift per field; the shift is fixed by asking for zero offset at
    the bit (a tie-break weighted by ``regularization``, exact when the shift is free), so that
    the bit positions keep following x_d = int v_d, alpha_d = int omega_d. The forces'
    dependence on d (e.g. the contact tension) is included by ``iterations`` fixed-point passes.

    Parameters
    ----------
    model : ControlAffineModel
    reference : ndarray (n_steps + 1, n)
        Non-dimensional reference (Eqs. 4.21-4.23).
    regularization : float
        Weight of the bit-offset tie-break relative to the size of the equations.
    return_reference : bool
        Also return the consistent reference r_k + E d_k (the steady deflected trajectory on
        which the feed-forward is an exact equilibrium).

    Returns
    -------
    ndarray (n_steps, m), or (u_ff, reference) with ``return_reference``.
    """
    ref = np.asarray(reference, dtype=float)
    n = model.n_states
    pos = [i for i, k in enumerate(model.state_kinds) if k in ("axial_position",
                                                               "angular_position")]
    npos = len(pos)
    E = np.zeros((n, npos))
    E[pos, np.arange(npos)] = 1.0
    Mat = np.hstack([(model.linear - np.eye(n)) @ E, model.g])
    scale = max(1e-300, float(np.linalg.norm(Mat, 2)))
    bit = [j for j, i in enumerate(pos) if model.state_nodes[i] == model.bit_node]
    tie = np.zeros((len(bit), Mat.shape[1]))
    tie[np.arange(len(bit)), bit] = regularization * scale
    big = np.vstack([Mat, tie])
    pinv = np.linalg.pinv(big, rcond=1e-12)
    T = ref.shape[0] - 1
    d = np.zeros((T + 1, npos))
    sol = np.zeros((T, Mat.shape[1]))
    AE = model.linear @ E
    for _ in range(max(1, int(iterations))):
        # G(d, u) = (A - I) E d + g u + [f(r + E d) - A E d - r_{k+1}] = 0: fixed point on the
        # force part (the forces depend weakly on the deflection)
        Ed = d[:-1] @ E.T
        rhs = ref[1:] + d[:-1] @ AE.T - model.f(ref[:-1] + Ed)
        sol = np.hstack([rhs, np.zeros((T, len(bit)))]) @ pinv.T
        d[:-1] = sol[:, :npos]
        d[-1] = d[-2]
    uff = np.ascontiguousarray(sol[:, npos:])
    if return_reference:
        return uff, ref + d @ E.T
    return uff


# ------------------------------------------------------------------------------ weights
@dataclass(frozen=True)
class PenaltyWeights:
    """Diagonal weights of Eq. 4.45 (non-dimensional units), axial then torsional in each pair.

    Attributes
    ----------
    top_position : (float, float)
        q_1, q_2: top node (node 0) axial and angular position.
    node_position : (float, float)
        q_{N1+1}, q_{N1+2}: positions at the nodes listed in ``nodes`` (e.g. the end of the
        vertical section).
    nodes : tuple of int
        Intermediate nodes weighted by ``node_position``.
    bit_position : (float, float)
        Bit axial and angular position.
    bit_velocity : (float, float)
        Bit axial and angular velocity.
    final_scale : float
        S = final_scale * Q (Table 4.1 uses separate s values; give ``final`` to set them).
    final : dict or None
        Optional explicit final weights with the same keys as above.
    r : (float, float)
        R diagonal.
    string_velocity : (float, float)
        Axial and angular velocity of every node other than the bit (deviations from the
        velocity reference v_d, omega_d): damping injection for the string's own modes
        (beyond the seed, whose Table 4.1 weights only positions away from the bit).
    integral : (float, float)
        Weights of the integrator states (sums of the bit axial / angular velocity errors;
        integral action, beyond the seed). Non-zero values make :func:`design_dhp` augment the
        design model with :func:`integral_augmented_model`.
    """

    top_position: tuple = (0.0, 0.0)
    node_position: tuple = (0.0, 0.0)
    nodes: tuple = ()
    bit_position: tuple = (0.1, 0.1)
    bit_velocity: tuple = (100.0, 100.0)
    final_scale: float = 1.0
    final: dict | None = None
    r: tuple = (1.0, 1.0)
    integral: tuple = (0.0, 0.0)
    string_velocity: tuple = (0.0, 0.0)

    def to_dict(self) -> dict:
        d = asdict(self)
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in d.items()}

    @classmethod
    def from_dict(cls, d: dict) -> PenaltyWeights:
        known = {f for f in cls.__dataclass_fields__}
        bad = set(d) - known
        if bad:
            raise DownholeInputError(f"unknown penalty weight keys {sorted(bad)}; known: "
                                     f"{sorted(known)}")
        return cls(**{k: (tuple(v) if isinstance(v, list) else v) for k, v in d.items()})


def _layout(model: ControlAffineModel, top, node, nodes, bitpos, bitvel,
            strvel=(0.0, 0.0)) -> np.ndarray:
    q = np.zeros(model.n_states)

    def put(kind, nd, w):
        for i in model.indices(kind, nd):
            q[i] = w

    if 0 in model.nodes and model.bit_node != 0:
        put("axial_position", 0, top[0])
        put("angular_position", 0, top[1])
    for nd in nodes:
        if nd not in model.nodes:
            raise DownholeInputError(f"penalty node {nd} is not a node of model {model.name!r} "
                                     f"(nodes {model.nodes})")
        put("axial_position", nd, node[0])
        put("angular_position", nd, node[1])
    for nd in model.nodes:
        if nd != model.bit_node and nd >= 0:
            put("axial_velocity", nd, strvel[0])
            put("angular_velocity", nd, strvel[1])
    put("axial_position", model.bit_node, bitpos[0])
    put("angular_position", model.bit_node, bitpos[1])
    put("axial_velocity", model.bit_node, bitvel[0])
    put("angular_velocity", model.bit_node, bitvel[1])
    return q


def _integral_layout(model: ControlAffineModel, q: np.ndarray, w) -> np.ndarray:
    integ = model.metadata.get("integral")
    if integ is None:
        if any(float(x) != 0.0 for x in w):
            raise DownholeInputError("integral weights need a model with integrator states "
                                     "(integral_augmented_model; design_dhp does it)")
        return q
    nb = int(integ["n_base"])
    q[nb], q[nb + 1] = float(w[0]), float(w[1])
    return q


def penalty_matrices(model: ControlAffineModel, w: PenaltyWeights):
    """Q, R, S (diagonal matrices) of Eq. 4.45 for ``model``'s state layout."""
    q = _layout(model, w.top_position, w.node_position, w.nodes, w.bit_position, w.bit_velocity,
                w.string_velocity)
    q = _integral_layout(model, q, w.integral)
    if w.final is None:
        s = w.final_scale * q
    else:
        f = dict(top_position=w.top_position, node_position=w.node_position,
                 bit_position=w.bit_position, bit_velocity=w.bit_velocity,
                 string_velocity=w.string_velocity)
        f.update(w.final)
        s = _layout(model, f["top_position"], f["node_position"], w.nodes, f["bit_position"],
                    f["bit_velocity"], f["string_velocity"])
        s = _integral_layout(model, s, f.get("integral", w.integral))
    r = np.asarray(w.r, dtype=float)
    if r.shape != (model.n_inputs,):
        raise DownholeInputError(f"penalty r must have {model.n_inputs} entries, got {w.r}")
    return np.diag(q), np.diag(r), np.diag(s)


def table_4_1_weights(nodes: tuple = ()) -> PenaltyWeights:
    """Table 4.1 taken literally (R = 1e-11, q = 10 / 1e10 / 1e8, s = 1e9 / 1e7).

    The table lists s_1 twice (1 and 1e9); the bit entries 1e9 / 1e7 are used for the final
    weights of the bit states and 1 for the others."""
    return PenaltyWeights(top_position=(10.0, 10.0), node_position=(10.0, 10.0), nodes=nodes,
                          bit_position=(1e10, 1e8), bit_velocity=(1e10, 1e8),
                          final={"top_position": (1.0, 1.0), "node_position": (1.0, 1.0),
                                 "bit_position": (1e9, 1e7), "bit_velocity": (1e9, 1e7)},
                          r=(1e-11, 1e-11))


# ------------------------------------------------------------------------------ integral action
INTEGRAL_STATE_NAMES = ("bit_axial_velocity_integral", "bit_angular_velocity_integral")


def integral_augmented_model(model: ControlAffineModel) -> ControlAffineModel:
    """The design model with two integrator states (integral action; beyond the seed).

    xi_ax,k+1 = xi_ax,k + dt v_bit,k and xi_ang,k+1 = xi_ang,k + dt omega_bit,k (physical m
    and rad, Euler sums of the bit velocities, scaled like the bit positions). Their reference
    is the integral of the velocity reference (they are of kind ``axial_position`` /
    ``angular_position`` with node -1, so :func:`reference_states` gives them x_d and
    alpha_d), hence xi - r_xi is the running sum of the bit-velocity errors. The controller
    keeps xi itself (:class:`~downhole.control.dhp.controller.DHPController`, with
    anti-windup: the error sum is frozen while an input saturates). The nonlinear forces act
    on the original states only.

    Returns
    -------
    ControlAffineModel
        n + 2 states; ``metadata["integral"]`` describes the augmentation.
    """
    n, m = model.n_states, model.n_inputs
    bn = model.bit_node
    iv = model.index("axial_velocity", bn)
    iw = model.index("angular_velocity", bn)
    ix = model.index("axial_position", bn)
    ia = model.index("angular_position", bn)
    P = model.state_scale
    Pxi = np.array([P[ix], P[ia]])
    A = np.zeros((n + 2, n + 2))
    A[:n, :n] = model.linear
    A[n, n] = A[n + 1, n + 1] = 1.0
    A[n, iv] = model.dt * P[iv] / Pxi[0]
    A[n + 1, iw] = model.dt * P[iw] / Pxi[1]
    g = np.vstack([model.g, np.zeros((2, m))])
    kw = {}
    if model.force_map is not None:
        fm = np.vstack([model.force_map, np.zeros((2, model.force_map.shape[1]))])

        def forces(zb, _f=model.forces, _n=n):
            return _f(np.ascontiguousarray(np.asarray(zb)[:, :_n]))

        kw = dict(force_map=fm, forces=forces)
    elif not model.is_linear:
        def nonlinear(zb, _h=model.nonlinear, _n=n):
            zb = np.asarray(zb)
            return np.hstack([_h(zb[:, :_n]), np.zeros((zb.shape[0], 2))])

        kw = dict(nonlinear=nonlinear, nonlinear_rows=model.nonlinear_rows)
    meta = dict(model.metadata)
    meta["integral"] = {"n_base": n, "source": [int(iv), int(iw)], "scale": Pxi.tolist()}
    return ControlAffineModel(
        A, g, state_scale=np.concatenate([P, Pxi]), input_scale=model.input_scale,
        dt=model.dt, state_names=list(model.state_names) + list(INTEGRAL_STATE_NAMES),
        input_names=model.input_names,
        state_kinds=list(model.state_kinds) + ["axial_position", "angular_position"],
        state_nodes=list(model.state_nodes) + [-1, -1], bit_node=bn,
        input_limits=model.input_limits, bit=model.bit,
        hanging_hook_load=model.hanging_hook_load, node_depths=model.node_depths,
        name=f"{model.name} + integral action", metadata=meta, outputs=None,
        strict_inputs=False, **kw)
