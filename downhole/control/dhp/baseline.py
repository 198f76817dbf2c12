"""Plain-NumPy form of the Riccati DHP trainer: the benchmark baseline of Table 4.2.

The same algorithm as ``method="riccati"`` of :func:`downhole.control.dhp.train_dhp`, written with
NumPy calls (see :func:`riccati_numpy`); ``downhole bench --group ch4`` times the compiled
trainer against it in the same run, and a test checks that both give the same gains.
"""

from __future__ import annotations

import numpy as np

from downhole.control.dhp.riccati import _forces, _prepare, draw_offsets
from downhole.control.dhp.trainer import DHPSettings

__all__ = ["riccati_numpy"]


def riccati_numpy(problem, settings=None):
    """Plain-NumPy version of the same trainer (benchmark baseline, same samples and result).

    The same algorithm as ``method="riccati"`` - fresh samples from the same SFC64 streams
    (``numpy.random.Generator``), the force fit, the modal Riccati pass - written with NumPy
    calls: the fits of a chunk of steps batched (``matmul`` / ``solve`` on stacks), the
    backward pass a Python loop over steps. Returns ``(kc, kd, mu)``."""
    settings = settings or DHPSettings()
    model = problem.model
    n, m = model.n_states, model.n_inputs
    ns = settings.n_samples if settings.n_samples is not None else max(2 * (n + 1), 20)
    radius = np.broadcast_to(np.asarray(settings.sample_radius, dtype=float), (n,)).copy()
    pre = _prepare(problem, radius)
    mf, q = pre["mf"], pre["q"]
    gp, Gp, Qp, Sp, Vr, base = (pre[k] for k in ("gp", "Gp", "Qp", "Sp", "Vr", "base"))
    R = problem.R
    Rinv = np.linalg.inv(R)
    ref = problem.reference
    n_steps = problem.n_steps
    kc = np.zeros((n_steps, m))
    kd = np.zeros((n_steps, m, n))
    mu = np.zeros(n_steps)
    M = Sp.copy()
    cn = np.zeros(n)
    K0 = max(4, min(256, 262144 // (ns * n)))
    T, Vinv = mf.T, mf.Vinv
    k_hi = n_steps - 1
    while k_hi >= 0:
        K = min(K0, k_hi + 1)
        ks = np.arange(k_hi, k_hi - K, -1)
        W = draw_offsets(settings.seed, (n_steps - 1 - ks) // settings.resample_every, ns, n)
        Z = ref[ks][:, None, :] + radius * W
        if q:
            F = _forces(model, Z.reshape(K * ns, n), q).reshape(K, ns, q)
            Phi = np.concatenate([np.ones((K, ns, 1)), W], axis=2)
            PhiT = Phi.transpose(0, 2, 1)
            sol = np.linalg.solve(PhiT @ Phi, PhiT @ F)          # (K, p, q)
            c0 = sol[:, 0, :]
            Yk = sol[:, 1:, :].transpose(0, 2, 1) @ Vr            # (K, q, n)
        for j, k in enumerate(ks):
            last = k == n_steps - 1
            Mk = Sp if last else M
            a = np.zeros(n) if last else T.T @ cn
            Mg = Mk @ gp
            mu[k] = float(np.max(np.abs(np.linalg.eigvals(gp.T @ Mg @ Rinv))))
            Sginv = np.linalg.inv(R + gp.T @ Mg)
            NM = Mk - Mg @ (Sginv @ (gp.T @ Mk))
            e = base[k] + (Gp @ c0[j] if q else 0.0)
            v = Mk @ e + a
            cn = v - Mg @ (Sginv @ (gp.T @ v))
            D = NM @ T
            if q:
                D = D + (NM @ Gp) @ Yk[j]
            kd[k] = Rinv @ (gp.T @ D) @ Vinv
            kc[k] = Rinv @ (gp.T @ cn)
            M = Qp + T.T @ D
        k_hi -= K
    return kc, kd, mu
