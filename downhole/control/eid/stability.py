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

from downhole.bit import bit_forces_and_slopes_py

__all__ = [
    "StabilityReport",
    "bit_rock_open_loop_roots",
    "channel_loop_matrices",
    "characteristic_roots",
    "closed_loop_stability",
    "plot_roots",
    "regenerative_closed_loop",
]

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


# ----------------------------------------------------------------------------------------------
# bit/rock regeneration: the delayed depth of cut in the linearized loop
# ----------------------------------------------------------------------------------------------
def _newton_roots(f, re_range=(-6.0, 6.0), im_max=200.0, n_re=5, d_im=1.5, iters=60):
    """Roots of an analytic ``f(s)`` (vectorized) in the upper half plane, from a grid of
    starting points refined by Newton's method (all starts at once)."""
    re = np.linspace(re_range[0], re_range[1], n_re)
    im = np.arange(0.25, im_max, d_im)
    s = (re[:, None] + 1j * im[None, :]).ravel()
    ok = np.zeros(s.shape, bool)
    old = np.seterr(all="ignore")
    for _ in range(iters):
        h = 1e-6 * (1 + np.abs(s))
        fs = f(s)
        df = (f(s + h) - f(s - h)) / (2 * h)
        step = fs / df
        step[~np.isfinite(step)] = 0.0
        s = s - step
        ok = np.abs(step) < 1e-10 * (1 + np.abs(s))
    fin = ok & np.isfinite(s) & (np.abs(f(s)) < 1e-6 * (1 + np.abs(f(s + 1e-3))))
    np.seterr(**old)
    roots = []
    for z in s[fin]:
        if z.imag >= -1e-9 and z.imag <= im_max and z.real > re_range[0] - 2 and not any(
                abs(z - r) < 1e-6 * (1 + abs(z)) for r in roots):
            roots.append(complex(z))
    return np.array(sorted(roots, key=lambda z: -z.real))


def _bit_rock_gains(model, rop, omega):
    """Linearized bit/rock law with the delayed depth of cut around (rop, omega):
    returns (k_w, k_t, c, t_n) with W = k_w (1 - e^{-s t_n}) (X - c Theta) and the same for T
    with k_t (per-blade depth d_n = x(t) - x(t - t_n), total d = n d_n; the state-dependent
    delay contributes c = rop/omega). Wear flats saturated (d > d*) and the velocity-weakening
    factors flat at the operating point, as for Table 3.1 at 10 mm/s, 20 rad/s. The gains are
    the depth-of-cut slopes dWOB/dd, dTOB/dd of the model's bit law (:mod:`downhole.bit.law`) at
    the steady depth of cut 2 pi rop / omega, times n."""
    b = model.bit
    n = b.n_blades
    slopes = bit_forces_and_slopes_py(2 * math.pi * rop / omega, rop, omega, b)
    kw = slopes[2] * n
    kt = slopes[4] * n
    return kw, kt, rop / omega, 2 * math.pi / (n * omega)


def bit_rock_open_loop_roots(model, rop: float = 0.01, omega: float = 20.0, *,
                             top: str = "damper", im_max: float = 200.0):
    """Roots of the open-loop neutral plant linearized around steady drilling with the
    *delayed* depth of cut (regenerative bit/rock interaction), axial and torsional coupled.

    The bit sees the line through the top boundary: ``Z_L(s) = Z (1 + G q^2)/(1 - G q^2)`` with
    ``q = exp(-s tau)`` and G = Gamma1 / Upsilon1 (``top="damper"``, the model's alpha_A,
    alpha_T), or ``Z_L = Z`` (``top="absorbing"``: a perfectly matched top that reflects nothing,
    the best broadband passive termination). Characteristic equation:
    ``det [[M s^2 + Z_La s + k_w (1-E), -k_w c (1-E)], [k_t (1-E), I s^2 + Z_Lt s - k_t c (1-E)]]
    = 0`` with ``E = exp(-s t_n)``, t_n = 2 pi/(n omega).

    Returns
    -------
    ndarray of complex
        Roots with 0 <= Im s <= im_max, rightmost first (s = 0 is the drift of the bit
        position, harmless for velocities).
    """
    if top not in ("damper", "absorbing"):
        raise ValueError(f"top must be 'damper' or 'absorbing', got {top!r}")
    p = model.params
    kw, kt, c, tn = _bit_rock_gains(model, rop, omega)
    za, zt = model.axial.impedance, model.torsional.impedance
    g1, u1 = model.gammas[0], model.upsilons[0]
    ta, tt = model.tau1, model.tau2

    def f(s):
        e = np.exp(-s * tn)
        if top == "damper":
            qa, qt = np.exp(-2 * s * ta), np.exp(-2 * s * tt)
            zla, zlt = za * (1 + g1 * qa) / (1 - g1 * qa), zt * (1 + u1 * qt) / (1 - u1 * qt)
        else:
            zla, zlt = za, zt
        a11 = p.bit_mass * s * s + zla * s + kw * (1 - e)
        a22 = p.bit_inertia * s * s + zlt * s - kt * c * (1 - e)
        return (a11 * a22 + kw * c * (1 - e) * kt * (1 - e)) / (p.bit_mass * p.bit_inertia)

    return _newton_roots(f, im_max=im_max)


def _regenerative_roots(char, im_max, g1, u1, model) -> dict:
    """Roots of the regenerative characteristic ``char`` and their summary (spectral abscissa
    with the neutral chain's bound log|g1| / 2 tau1, log|u1| / 2 tau2; dominant and rightmost
    oscillatory roots; the six rightmost roots; stability)."""
    roots = _newton_roots(char, im_max=im_max, n_re=3, d_im=3.0, iters=40)
    chain = max(math.log(abs(g1)) / (2 * model.tau1), math.log(abs(u1)) / (2 * model.tau2))
    sa = float(max(roots.real.max() if roots.size else -math.inf, chain))
    dom = roots[0] if roots.size else complex(chain, 0)
    osc = [r for r in roots if r.imag > 10.0]
    osc = osc[0] if osc else complex(-math.inf, 0.0)
    return {"spectral_abscissa": sa, "dominant_root": [float(dom.real), float(dom.imag)],
            "rightmost_oscillatory_root": [float(osc.real), float(osc.imag)],
            "roots": [[float(r.real), float(r.imag)] for r in roots[:6]], "stable": sa < 0}


def regenerative_closed_loop(controller, model, rop: float = 0.01, omega: float = 20.0, *,
                             im_max: float = 200.0) -> dict:
    """Spectral abscissa of the EID closed loop on the true plant (input delay included) with
    the linearized *delayed* depth of cut, both channels coupled through the bit.

    Builds the 10x10 characteristic matrix of the two channel loops of
    :func:`channel_loop_matrices` and adds the regenerative bit/rock forces to the plant rows:
    ``(1/M) (1 - G q^2) k (1 - e^{-s t_n}) (X - c Theta)`` (see :func:`bit_rock_open_loop_roots`).

    Returns
    -------
    dict
        ``spectral_abscissa`` (1/s), ``dominant_root`` (complex, as [re, im]),
        ``rightmost_oscillatory_root`` (Im > 10 rad/s: the regenerative mode), ``roots``
        (rightmost few), ``stable``.
    """
    mats = []
    for i in range(2):
        mats.append(channel_loop_matrices(controller.model_coeffs[i], controller.gains[i],
                                          predictor=controller.predictor,
                                          delayed_input_observer=controller.delayed_input_observer))
    kw, kt, c, tn = _bit_rock_gains(model, rop, omega)
    p = model.params
    g1, u1 = model.gammas[0], model.upsilons[0]
    n = 5

    def char(s):
        s = np.atleast_1d(s).astype(complex)
        M = np.zeros((s.size, 2 * n, 2 * n), complex)
        eye = np.eye(n)
        for i, (A0, A1, A2, G, tau) in enumerate(mats):
            q = np.exp(-s * tau)[:, None, None]
            M[:, i * n:(i + 1) * n, i * n:(i + 1) * n] = (s[:, None, None] * (eye - G * q * q)
                                                          - A0 - A1 * q - A2 * q * q)
        small = np.abs(s) < 1e-12
        e = np.where(small, tn, (1 - np.exp(-s * tn)) / np.where(small, 1.0, s))
        qa, qt = np.exp(-2 * s * model.tau1), np.exp(-2 * s * model.tau2)
        fa = (1 - g1 * qa) / p.bit_mass * e
        ft = (1 - u1 * qt) / p.bit_inertia * e
        M[:, 0, 0] += fa * kw
        M[:, 0, n] += -fa * kw * c
        M[:, n, 0] += ft * kt
        M[:, n, n] += -ft * kt * c
        return np.linalg.det(M)

    return _regenerative_roots(char, im_max, g1, u1, model)
