"""Research record: design variants tried for the strict "within 5% by 5 s" reading on the
68-state hybrid (issue "Chapter 4 controller", docs/dhp.md, "The 68-state hybrid").

Not part of the package and not a test: it re-measures, in about 15 s, the variants that
docs/dhp.md reports as not reaching 5 s, so that the numbers there can be rerun:

    .venv/bin/python examples/research/dhp_hybrid68_variants.py

Each line: settling time into the 5% band (last exit, s; 10 = not settled in the 10 s run), the
maximum axial (mm/s) and angular (rad/s) bit-velocity errors after 5 s and the stuck fraction
after 5 s, on the 24-state FEM (approximate depth of cut), the 68-state hybrid (approximate and
delayed). Training: N_S = 50, horizon 20 s (as the quick experiments). Variants:

- base: the Ch. 4 claim weights (DESIGN_WEIGHTS) and HYBRID_WEIGHTS as in ``dhp.hybrid68``;
- serep: the design model's linear part replaced by a SEREP reduction (O'Callahan 1989) of a
  200-element FEM onto the same 6 nodes (the 6 lowest modes per field kept exactly), so that
  the states keep their meaning but the modes below 1.5 Hz are right;
- ramped deflection: the consistent reference's static twist/stretch ramped in over T_r s
  (smoothstep, its rate added to the node velocity references, u_ff recomputed);
- axial-delayed reference: rotate first, then set down (axial reference from 30% to 100%
  between t1 and t2), evaluated against the same 10 mm/s, 20 rad/s after 5 s;
- torque limit: the online limit lowered from 60 to 30 kN m;
- observer: the controller fed a steady-state Kalman predictor on the design model from the
  top and bit states instead of the node states;
- top damper: a collocated inner loop -Z v_top on the hook and the top drive (the pipe's
  impedances Z_a = 3.44e5 N s/m, Z_t = 481 N m s/rad: a wave-absorbing top), included in the
  design model the DHP is trained on, the total command clipped to the limits;
- truth plants: the same two designs on dense FEMs (100 and 300 elements) and on the hybrid
  with 1 lag per incoming wave for the line's beta0 damping.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import eigh, solve_discrete_are

from downhole.control.dhp import BitReference, DHPSettings, PenaltyWeights, design_dhp, run_on_plant
from downhole.control.dhp.controller import DHPController
from downhole.control.dhp.design import build_problem
from downhole.control.dhp.directional import (DirectionalStatePlant, directional_affine_model,
                                              table_5_1_models)
from downhole.control.dhp.drilling import (integral_augmented_model, penalty_matrices,
                                           reference_states)
from downhole.control.dhp.trainer import DHPProblem, train_dhp
from downhole.experiments.ch4_dhp import (DESIGN_WEIGHTS, HYBRID_WEIGHTS, _settling_time,
                                          _tracking)
from downhole.string.fem import DirectionalModel, _tri_dense, fem_from_nodes, fem_model
from downhole.string.hybrid import hybrid_model

STEP = BitReference.step(0.01, 20.0)
FEM24, HYB68 = table_5_1_models()
DESIGN = directional_affine_model(FEM24)
PLANTS = (("fem24", FEM24, "approximate"), ("hyb68_approx", HYB68, "approximate"),
          ("hyb68_delayed", HYB68, "delayed"))


def measure(ctrl, plants=PLANTS, wrap=None, T=10.0):
    out = {}
    for label, model, doc in plants:
        plant = DirectionalStatePlant(model, DESIGN, ctrl.dt, depth_of_cut=doc)
        if wrap is not None:
            plant = wrap(plant)
        res = run_on_plant(ctrl, plant, T, record_every=10)
        tr = _tracking(res, 5.0)
        out[label] = (round(_settling_time(res), 2), round(tr["max_abs_axial_error_mm_s"], 2),
                      round(tr["max_abs_angular_error_rad_s"], 2), round(tr["stuck_fraction"], 3))
    return out


def train(weights, design=DESIGN, reference=STEP, modify=None, horizon=20.0):
    """design_dhp, optionally with the problem's reference / feed-forward modified."""
    w = PenaltyWeights(**weights)
    if modify is None:
        return design_dhp(design, reference, horizon=horizon, weights=w,
                          settings=DHPSettings(n_samples=50))
    model = integral_augmented_model(design) if any(x != 0 for x in w.integral) else design
    prob = build_problem(model, reference, horizon, w)
    v, om, x, a = reference.sample(prob.n_steps, model.dt)
    ref, uff = modify(model, reference_states(model, v, om, x, a), prob.reference, prob.u_ff)
    Q, R, S = penalty_matrices(model, w)
    prob = DHPProblem(model, Q, R, S, ref, uff)
    tr = train_dhp(prob, DHPSettings(n_samples=50))
    ctrl = DHPController(tr.kc, tr.kd, prob.reference, prob.u_ff, model.state_scale,
                         model.input_scale, model.dt, model.state_names, model.state_kinds,
                         model.input_names, reference, input_limits=model.input_limits,
                         meta={"model": model.describe()})
    return ctrl.attach_model(model)


# ----------------------------------------------------------------------------- SEREP design
class SerepFEM:
    """FEM24 whose linear part is a SEREP reduction of a dense FEM on FEM24's nodes."""

    def __init__(self, base, n_el=200, td=500.0):
        self.base, self.td = base, td
        md0, L = base.node_md, base.node_md[-1] - base.node_md[0]
        md = np.concatenate([md0[:1]] + [
            np.linspace(a, b, max(1, round(n_el * (b - a) / L)) + 1)[1:]
            for a, b in zip(md0[:-1], md0[1:])])
        inf = base.info
        d = fem_from_nodes(base.well, base.string, base.bit, md,
                           rayleigh_alpha=inf["rayleigh_alpha"],
                           rayleigh_beta=inf["rayleigh_beta"], friction=base.mu,
                           v_eps=base.v_eps, mass=inf["mass"], md_b=md0[base.node_b],
                           md_c=md0[base.node_c])
        master = np.array([int(np.argmin(np.abs(md - x))) for x in md0])
        self.red = {}
        for f, mats in (("a", (d.Ma, d.Ka, d.Ca)), ("t", (d.Mt, d.Kt, d.Ct))):
            M, K, C = (_tri_dense(x) for x in mats)
            if f == "t":
                M[0, 0] += td
            _, phi = eigh(K, M)
            T = phi[:, :md0.size] @ np.linalg.inv(phi[master, :md0.size])
            self.red[f] = [0.5 * (X + X.T) for X in (T.T @ M @ T, T.T @ K @ T, T.T @ C @ T)]

    def __getattr__(self, k):
        return getattr(self.base, k)

    def design_model(self, n_bc=1):
        return self

    def continuous_linear_model(self, top_drive_inertia=500.0):
        names = self.base.continuous_linear_model(top_drive_inertia)[2]
        n = self.base.n_nodes
        M, K, C = (np.zeros((2 * n, 2 * n)) for _ in range(3))
        for idx, f in ((np.arange(0, 2 * n, 2), "a"), (np.arange(1, 2 * n, 2), "t")):
            for X, Xr in zip((M, K, C), self.red[f]):
                X[np.ix_(idx, idx)] = Xr
        Minv = np.linalg.inv(M)
        A = np.block([[np.zeros((2 * n, 2 * n)), np.eye(2 * n)], [-Minv @ K, -Minv @ C]])
        Bu = np.zeros((2 * n, 2))
        Bu[0, 0] = Bu[1, 1] = 1.0
        return A, np.vstack([np.zeros((2 * n, 2)), Minv @ Bu]), names, Minv

    linear_model = DirectionalModel.linear_model      # ZOH of continuous_linear_model


# ----------------------------------------------------------------------------- references
def _smooth(t, t0, t1):
    s = np.clip((t - t0) / max(t1 - t0, 1e-12), 0.0, 1.0)
    rate = np.where((t > t0) & (t < t1), 6 * s * (1 - s) / max(t1 - t0, 1e-12), 0.0)
    return s * s * (3 - 2 * s), rate


def ramped_deflection(Tr):
    def modify(model, rigid, consistent, uff):
        t = np.arange(consistent.shape[0]) * model.dt
        sig, dsig = _smooth(t, 0.0, Tr)
        D = consistent - rigid
        ref = rigid + sig[:, None] * D
        P = model.state_scale
        for i, k in enumerate(model.state_kinds):
            if k.endswith("_position") and model.state_nodes[i] >= 0:
                j = model.index(k.replace("position", "velocity"), model.state_nodes[i])
                ref[:, j] += dsig * D[:, i] * P[i] / P[j]
        return ref, (ref[1:] - model.f(ref[:-1])) @ np.linalg.pinv(model.g).T
    return modify


def axial_delayed(a0, t1, t2):
    t = np.linspace(0.0, 30.0, 3001)
    return BitReference.user(t, 0.01 * (a0 + (1 - a0) * _smooth(t, t1, t2)[0]),
                             np.full(t.size, 20.0))


# ----------------------------------------------------------------------------- top damper
class DampedTopFEM:
    """FEM24 with dashpots c_a (N s/m), c_t (N m s/rad) from the top node to ground: the
    collocated inner loop of the controller, trained into the design model."""

    def __init__(self, base, c_a, c_t):
        self.base, self.c = base, (c_a, c_t)

    def __getattr__(self, k):
        return getattr(self.base, k)

    def design_model(self, n_bc=1):
        return self

    def continuous_linear_model(self, top_drive_inertia=500.0):
        A, B, names, Minv = self.base.continuous_linear_model(top_drive_inertia)
        n2 = A.shape[0] // 2
        A = A.copy()
        A[n2:, n2:2 + n2] -= Minv[:, :2] * np.asarray(self.c)
        return A, B, names, Minv

    linear_model = DirectionalModel.linear_model


class DamperPlant:
    """Adds the inner loop -c v_top to the DHP command; the total is clipped to the limits."""

    def __init__(self, plant, c_a, c_t):
        self.p, self.c, self.weight = plant, np.array([c_a, c_t]), plant.weight
        self.iv = [DESIGN.index("axial_velocity", 0), DESIGN.index("angular_velocity", 0)]
        self.lim = np.asarray(DESIGN.input_limits)

    def reset(self):
        self.obs = self.p.reset()
        return self.obs

    def step(self, command):
        u = np.array([command["slack_off_force"], command["surface_torque"]])
        u = np.clip(u - self.c * self.obs["state"][self.iv], self.lim[:, 0], self.lim[:, 1])
        self.obs = self.p.step({"slack_off_force": u[0], "surface_torque": u[1]})
        return self.obs


def with_top_damper(W, c_a=3.44e5, c_t=481.0):
    ctrl = train(W, design=directional_affine_model(DampedTopFEM(FEM24, c_a, c_t)))
    ctrl.input_limits = None             # the limits apply to the total (DamperPlant)
    return measure(ctrl, wrap=lambda p: DamperPlant(p, c_a, c_t))


# ----------------------------------------------------------------------------- observer
class ObserverPlant:
    """Replaces the node states by a Kalman predictor on the design model (top + bit states)."""

    def __init__(self, plant, q=1e-6, r=1e-2):
        d = DESIGN
        self.p, self.d, self.weight = plant, d, plant.weight
        self.idx = np.array([i for i in range(d.n_states) if d.state_nodes[i] in (0, d.bit_node)])
        C = np.eye(d.n_states)[self.idx]
        Pk = solve_discrete_are(d.linear.T, C.T, q * np.eye(d.n_states), r * np.eye(self.idx.size))
        self.L = d.linear @ Pk @ C.T @ np.linalg.inv(C @ Pk @ C.T + r * np.eye(self.idx.size))

    def reset(self):
        obs = self.p.reset()
        self.zh = self.d.to_nondim_state(obs["state"])
        return obs

    def step(self, command):
        lim = np.asarray(self.d.input_limits)
        u = np.clip([command["slack_off_force"], command["surface_torque"]], lim[:, 0], lim[:, 1])
        obs = dict(self.p.step(command))
        y = self.d.to_nondim_state(obs["state"])[self.idx]
        self.zh = self.d.step(self.zh, self.d.to_nondim_input(u)) + self.L @ (y - self.zh[self.idx])
        obs["state"] = self.d.to_physical_state(self.zh)
        return obs


def main():
    serep = directional_affine_model(SerepFEM(FEM24))
    truth = (("fem100", fem_model(n_elements=100), "approximate"),
             ("fem300", fem_model(n_elements=300), "approximate"),
             ("hyb68_lag1", hybrid_model("hybrid68", n_lags=1), "approximate"))
    print("(settling s, max axial error mm/s, max angular error rad/s, stuck fraction) after 5 s")
    for wname, W in (("claim weights", DESIGN_WEIGHTS), ("HYBRID_WEIGHTS", HYBRID_WEIGHTS)):
        base = train(W)
        rows = [("base", measure(base)),
                ("serep design model", measure(train(W, design=serep))),
                ("ramped deflection 2 s", measure(train(W, modify=ramped_deflection(2.0)))),
                ("axial-delayed reference 30% 1-2.5 s",
                 measure(train(W, reference=axial_delayed(0.3, 1.0, 2.5)))),
                ("observer (top + bit states)", measure(base, wrap=ObserverPlant)),
                ("top damper Z_a, Z_t (impedance-matched)", with_top_damper(W)),
                ("truth plants", measure(base, plants=truth))]
        base.input_limits = np.array([[-5e4, 3e5], [-3e4, 3e4]])
        rows.insert(4, ("torque limit 30 kN m", measure(base)))
        for name, r in rows:
            print(f"{wname:15s} {name:38s} {r}", flush=True)


if __name__ == "__main__":
    main()
