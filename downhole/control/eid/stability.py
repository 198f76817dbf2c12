"""Closed-loop stability of the EID loop on the neutral plant *with its input delay*: characteristic
roots, spectral abscissa and the difference-operator condition, plus a plot.

Per channel the loop (plant x, observer xhat, predictor model z, internal model x_R, filter x_F)
is a linear neutral system ``xi' - G xi'(t-2tau) = A0 xi + A1 xi(t-tau) + A2 xi(t-2tau)`` (the
bit/rock forces enter as an optional linear damper ``bit_damping`` dW/dv). Its roots solve
``det(s (I - G q^2) - A0 - A1 q - A2 q^2) = 0`` with ``q = exp(-s tau)``. They are found from a
Chebyshev collocation of the infinitesimal generator on [-2 tau, 0] and refined by Newton's method
on the determinant. The difference operator ``xi - G xi(t - 2tau)`` is stable iff its spectral
radius |g1| < 1; its root chains then lie at Re s = ln|g1| / (2 tau) < 0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["channel_loop_matrices", "characteristic_roots", "StabilityReport",
           "closed_loop_stability", "plot_roots"]

_X, _XH, _Z, _XR, _XF = range(5)


def _e(state, delay=0, coef=1.0):
    m = np.zeros((3, 5))
    m[delay, state] = coef
    return m


def _shift(m):
    out = np.zeros_like(m)
    out[1:] = m[:-1]
    if np.any(m[-1] != 0):
        raise ValueError("delay beyond 2 tau")
    return out


def channel_loop_matrices(ch: dict, g, *, predictor=True, delayed_input_observer=True,
                          bit_damping: float = 0.0, bit_mass: float = 1.0):
    """(A0, A1, A2, G, tau) of the true closed loop of one channel (state [x, xhat, z, x_R, x_F])."""
    a0, a1, g1, b, tau = ch["a0"], ch["a1"], ch["g1"], ch["b"], ch["tau"]
    xp = _e(_Z) + _e(_XH) - _e(_Z, 1) if predictor else _e(_XH)
    uf = g.kp * xp + g.kr * _e(_XR)
    u = uf - _e(_XF)
    rows = np.zeros((5, 3, 5))
    Gm = np.zeros((5, 5))
    kappa = bit_damping / (bit_mass * b)
    # plant: x' = a0 x + a1 x(t-2tau) + g1 x'(t-2tau) + b u(t-tau) + b d_e
    rows[_X] = a0 * _e(_X) + a1 * _e(_X, 2) + b * _shift(u) + b * kappa * (-_e(_X)
                                                                          + g1 * _e(_X, 2))
    Gm[_X, _X] = g1
    uf_o = _shift(uf) if delayed_input_observer else uf
    dt_o = _shift(uf - u) if delayed_input_observer else (uf - u)
    rows[_XH] = a0 * _e(_XH) + a1 * _e(_XH, 2) + b * uf_o + g.l * (_e(_X) - _e(_XH))
    Gm[_XH, _XH] = g1
    rows[_Z] = a0 * _e(_Z) + a1 * _e(_Z, 2) + b * uf
    Gm[_Z, _Z] = g1
    rows[_XR] = -g.br * xp
    rows[_XF] = -g.bf * _e(_XF) + g.bf * (g.l / b * (_e(_X) - _e(_XH)) + dt_o)
    A = [rows[:, k, :] for k in range(3)]
    return A[0], A[1], A[2], Gm, tau


def _det(s, A0, A1, A2, G, tau):
    q = np.exp(-s * tau)
    n = A0.shape[0]
    return np.linalg.det(s * (np.eye(n) - G * q * q) - A0 - A1 * q - A2 * q * q)


def _cheb(N, a, b):
    x = np.cos(np.pi * np.arange(N + 1) / N)  # 1 .. -1
    c = np.hstack([2.0, np.ones(N - 1), 2.0]) * (-1.0) ** np.arange(N + 1)
    X = np.tile(x, (N + 1, 1)).T
    dX = X - X.T
    D = np.outer(c, 1.0 / c) / (dX + np.eye(N + 1))
    D -= np.diag(D.sum(axis=1))
    theta = (a + b) / 2 + (b - a) / 2 * x  # theta[0] = b (= 0), theta[N] = a (= -2 tau)
    return theta, D * 2.0 / (b - a)


def _interp_row(theta, t):
    """Barycentric Lagrange weights to evaluate at t from values at Chebyshev nodes theta."""
    N = len(theta) - 1
    w = (-1.0) ** np.arange(N + 1)
    w[0] *= 0.5
    w[-1] *= 0.5
    d = t - theta
    if np.any(np.abs(d) < 1e-14):
        r = np.zeros(N + 1)
        r[np.argmin(np.abs(d))] = 1.0
        return r
    r = w / d
    return r / r.sum()


def characteristic_roots(A0, A1, A2, G, tau, n_nodes: int = 40, max_imag: float = 200.0):
    """Characteristic roots with |Im s| <= max_imag (generator collocation + Newton)."""
    n = A0.shape[0]
    theta, D = _cheb(n_nodes, -2 * tau, 0.0)
    N1 = n_nodes + 1
    big = np.kron(D, np.eye(n))  # rows for theta_i < 0: phi' = D phi
    e_tau = _interp_row(theta, -tau)
    row0 = np.zeros((n, n * N1))
    row0[:, 0:n] += A0
    for j in range(N1):
        row0[:, j * n:(j + 1) * n] += A1 * e_tau[j]
    row0[:, n_nodes * n:] += A2
    # neutral term: G phi'(-2 tau) = G (D phi)(theta_N)
    for j in range(N1):
        row0[:, j * n:(j + 1) * n] += G * D[n_nodes, j]
    big[0:n, :] = row0
    lam = np.linalg.eigvals(big)
    lam = lam[np.abs(lam.imag) <= max_imag]
    roots = []
    lam = lam[np.isfinite(lam) & (lam.real > -1e3)]
    old = np.seterr(all="ignore")
    for s in lam:
        s = complex(s)
        ok = False
        for _ in range(40):
            f = _det(s, A0, A1, A2, G, tau)
            h = 1e-6 * (1 + abs(s))
            df = (_det(s + h, A0, A1, A2, G, tau) - _det(s - h, A0, A1, A2, G, tau)) / (2 * h)
            if df == 0 or not np.isfinite(df) or not np.isfinite(f):
                break
            step = f / df
            s -= step
            if abs(step) < 1e-10 * (1 + abs(s)):
                ok = True
                break
        if ok and abs(s.imag) <= max_imag and not any(abs(s - r) < 1e-6 * (1 + abs(s))
                                                      for r in roots):
            roots.append(s)
    np.seterr(**old)
    return np.array(sorted(roots, key=lambda z: -z.real))


@dataclass
class StabilityReport:
    """Roots and margins of the closed loop, per channel."""

    roots: dict
    spectral_abscissa: dict
    difference_operator_radius: dict
    chain_abscissa: dict

    @property
    def stable(self) -> bool:
        return all(v < 0 for v in self.spectral_abscissa.values()) and all(
            r < 1 for r in self.difference_operator_radius.values())

    def to_dict(self) -> dict:
        return {"spectral_abscissa": self.spectral_abscissa,
                "difference_operator_radius": self.difference_operator_radius,
                "chain_abscissa": self.chain_abscissa, "stable": self.stable}


def closed_loop_stability(controller, model=None, *, bit_damping=(0.0, 0.0),
                          n_nodes: int = 40, max_imag: float = 200.0,
                          predictor=None, delayed_input_observer=None) -> StabilityReport:
    """Spectral abscissa of the true closed loop (input delay included) per channel.

    Parameters
    ----------
    controller : EIDController
    model : NeutralModel, optional
        For the bit mass/inertia when ``bit_damping`` is non-zero.
    bit_damping : (float, float)
        Linearized bit forces dW/dv (N s/m) and dT/domega (N m s/rad).
    predictor, delayed_input_observer : bool, optional
        Override the controller's structure (False, False = the printed design).

    Returns
    -------
    StabilityReport
        The spectral abscissa is the larger of the rightmost root found and the neutral chain
        abscissa ln|g1|/(2 tau).
    """
    pr = controller.predictor if predictor is None else predictor
    di = controller.delayed_input_observer if delayed_input_observer is None else \
        delayed_input_observer
    roots, sa, rad, chain = {}, {}, {}, {}
    masses = (1.0, 1.0)
    if model is not None:
        masses = (model.params.bit_mass, model.params.bit_inertia)
    for i, name in enumerate(("axial", "torsional")):
        ch = controller.model_coeffs[i]
        A0, A1, A2, G, tau = channel_loop_matrices(ch, controller.gains[i], predictor=pr,
                                                   delayed_input_observer=di,
                                                   bit_damping=bit_damping[i],
                                                   bit_mass=masses[i])
        r = characteristic_roots(A0, A1, A2, G, tau, n_nodes, max_imag)
        g1 = abs(ch["g1"])
        rad[name] = g1
        chain[name] = math.log(g1) / (2 * tau) if g1 > 0 else -math.inf
        roots[name] = r
        sa[name] = float(max(r.real.max() if r.size else -math.inf, chain[name]))
    return StabilityReport(roots, sa, rad, chain)


def plot_roots(report: StabilityReport, path=None, title: str = "EID closed-loop roots"):
    """Scatter of the characteristic roots per channel with the chain abscissae."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for ax, name in zip(axes, ("axial", "torsional")):
        r = report.roots[name]
        ax.plot(r.real, r.imag, "x")
        ax.axvline(0, color="k", lw=0.8)
        ax.axvline(report.chain_abscissa[name], color="r", ls="--", lw=0.8,
                   label="neutral chain ln|g1|/2tau")
        ax.set_title(f"{name}: spectral abscissa {report.spectral_abscissa[name]:.3g} 1/s")
        ax.set_xlabel("Re s, 1/s")
        ax.set_ylabel("Im s, rad/s")
        ax.set_xlim(min(-20, r.real.min() - 1) if r.size else -20, 2)
        ax.legend(fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    if path is not None:
        fig.savefig(path, dpi=110)
        plt.close(fig)
    return fig
