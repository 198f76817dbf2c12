"""LMI synthesis of the EID controller gains (seed Theorem 1 with the corrections of
docs/seed-errata.md) with cvxpy + Clarabel.

The design model (Eq. 3.13) is diagonal, so each channel (axial, torsional) is designed on its own
scalar neutral system ``x' = a0 x + a1 x(t-h) + g1 x'(t-h) + b (u(t - tau) + d_e)``. The closed
loop analysed by the Lyapunov-Krasovskii functional of Theorem 1 is, with the corrections (internal
model x_R' = B_R (r - y), observer driven by u_f, B+ = (B^T B)^-1 B^T, F(s) = bf/(s + bf)) and with
the input delay handled by a predictor and a delayed-input observer (see
:mod:`downhole.control.eid.controller`), ``xi = [z, x_R, dx, x_F]``::

    xi' = Abar0 xi + Abar_h xi(t-h) + Gbar_h xi'(t-h) + Abar_tau xi(t - tau)
    Abar0 = [[a0 + b kp, b kr, 0, 0], [-br, 0, 0, 0], [0, 0, a0 - l, 0], [0, 0, bf l / b, -bf]]
    Abar_h = diag(a1, 0, a1, 0), Gbar_h = diag(g1, 0, g1, 0)
    Abar_tau: the delayed disturbance compensation, -b x_F(t-tau) in dx', +bf x_F(t-tau) in x_F'

The LMI is Theorem 1's (Schur complements, congruence with diag(X, Y, M, I, ...)) written for any
set of delayed terms, with X = diag(X1, x2, x3), W1 = [kp kr] X1, w2 = l x2 (Lemma 2 with C = I).
The functional is delay-independent: feasibility proves stability for all h and tau.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from downhole.errors import DownholeInputError

__all__ = [
    "ChannelGains",
    "LMIInfeasible",
    "LMIReport",
    "channel_closed_loop_design",
    "lmi_blocks",
    "synthesize_channel",
]


class LMIInfeasible(DownholeInputError):
    """The LMI has no solution; ``family`` names the constraint family that failed."""

    def __init__(self, channel: str, family: str, detail: str):
        self.channel, self.family = channel, family
        super().__init__(f"EID LMI infeasible on the {channel} channel: constraint family "
                         f"'{family}' cannot be satisfied ({detail})")


@dataclass(frozen=True)
class ChannelGains:
    """Gains of one channel: state feedback kp, internal-model gain kr, observer gain l, internal
    model input br and filter bandwidth bf (F(s) = bf/(s + bf))."""

    kp: float
    kr: float
    l: float
    br: float
    bf: float


@dataclass
class LMIReport:
    """Outcome of one channel's LMI: solver status, time and eigenvalue margins."""

    channel: str
    status: str
    solve_seconds: float
    lmi_max_eigenvalue: float
    min_eigenvalues: dict = field(default_factory=dict)
    size: int = 0

    def to_dict(self) -> dict:
        return {"channel": self.channel, "status": self.status,
                "solve_seconds": self.solve_seconds,
                "lmi_max_eigenvalue": self.lmi_max_eigenvalue,
                "min_eigenvalues": self.min_eigenvalues, "size": self.size}


def channel_closed_loop_design(ch: dict, g: ChannelGains, delayed_input: bool = False):
    """Matrices (A0bar, [(A_k, delay_k)], [(G_k, delay_k)]) of the design closed loop of one
    channel (state [z, x_R, dx, x_F])."""
    a0, a1, g1, b, h, tau = ch["a0"], ch["a1"], ch["g1"], ch["b"], ch["h"], ch["tau"]
    A0 = np.array([[a0 + b * g.kp, b * g.kr, 0, 0], [-g.br, 0, 0, 0], [0, 0, a0 - g.l, 0],
                   [0, 0, g.bf * g.l / b, -g.bf]], float)
    Ah = np.diag([a1, 0.0, a1, 0.0])
    Gh = np.diag([g1, 0.0, g1, 0.0])
    if not delayed_input:
        # delay-free design model (the seed's): x_F' = bf l/b dx, dx' = ... - b x_F
        A0[2, 3] = -b
        A0[3, 3] = 0.0
        return A0, [(Ah, h)], [(Gh, h)]
    At = np.zeros((4, 4))
    At[2, 3] = -b
    At[3, 3] = g.bf
    return A0, [(Ah, h), (At, tau)], [(Gh, h)]


def lmi_blocks(Abar0X, XAbar0T, X, delayed_A, delayed_G, Y, M):
    """Assemble Theorem 1's block LMI (a cvxpy expression or numbers).

    ``delayed_A``: list of constant matrices A_k, with Y[k] = R_k^-1; ``delayed_G``: list of G_k
    with M[k] = N_k^-1. Block order: [xi, xi(t-h_k) ..., xi'(t-h_k) ..., Schur columns of the N_k
    (one per G_k), Schur columns of the R_k (one per A_k)]."""
    import cvxpy as cp

    n = X.shape[0]
    Z = np.zeros((n, n))
    na, ng = len(delayed_A), len(delayed_G)
    nb = 1 + na + ng + ng + na
    B = [[None] * nb for _ in range(nb)]
    B[0][0] = Abar0X + XAbar0T
    for k, A in enumerate(delayed_A):
        B[0][1 + k] = A @ Y[k]
        B[1 + k][1 + k] = -Y[k]
    for k, G in enumerate(delayed_G):
        B[0][1 + na + k] = G @ M[k]
        B[1 + na + k][1 + na + k] = -M[k]
    for j in range(ng):  # Schur columns Pi^T for N_j
        c = 1 + na + ng + j
        B[0][c] = XAbar0T
        for k, A in enumerate(delayed_A):
            B[1 + k][c] = Y[k] @ A.T
        for k, G in enumerate(delayed_G):
            B[1 + na + k][c] = M[k] @ G.T
        B[c][c] = -M[j]
    for k in range(na):  # Schur columns I for R_k
        c = 1 + na + 2 * ng + k
        B[0][c] = X
        B[c][c] = -Y[k]
    for i in range(nb):
        for j in range(nb):
            if B[i][j] is None:
                B[i][j] = B[j][i].T if (j < i and B[j][i] is not None) else Z
    return cp.bmat(B)


def synthesize_channel(ch: dict, name: str, *, br: float, bf: float, eps: float = 1e-6,
                       observer_gain: float, gain_bound: float = 5.0, delayed_input: bool = True,
                       solver: str = "CLARABEL"):
    """Solve the corrected Theorem 1 LMI of one channel for (kp, kr, l).

    Parameters
    ----------
    ch : dict
        Scalar design model from :meth:`NDDEMatrices.channel` (a0, a1, g1, b, h, tau).
    name : str
        Channel name for messages.
    br : float
        Internal-model input gain B_R (seed Eq. 3.32: 1 axial, 0.05 torsional).
    bf : float
        Filter bandwidth, rad/s (F(s) = bf/(s + bf); seed 200 and 100).
    eps : float
        Strictness margin: LMI <= -eps I and every positive-definite variable >= eps I.
    gain_bound, observer_bound : float
        Bounds on |[kp kr]| and |l| (X1 >= I, x2 >= 1 and Schur bounds on W1, w2).

    Returns
    -------
    (ChannelGains, LMIReport)

    Raises
    ------
    LMIInfeasible
        Names the constraint family that failed (found by re-solving with each family relaxed).
    """
    import cvxpy as cp

    for nm, val in (("br", br), ("bf", bf)):
        if not np.isfinite(val) or val <= 0:
            raise DownholeInputError(f"{name} channel: {nm} must be positive, got {val}")
    a0, g1, b = ch["a0"], ch["g1"], ch["b"]
    if not abs(g1) < 1.0:
        raise DownholeInputError(f"{name} channel: |G| = {abs(g1):.6g} >= 1, the difference "
                                 "operator is unstable; no LMI can stabilize it")
    t0 = time.perf_counter()
    X1 = cp.Variable((2, 2), symmetric=True)
    Xe = cp.Variable((2, 2), symmetric=True)  # [dx, x_F] block, full (see module docstring)
    W1 = cp.Variable((1, 2))
    Mh = cp.Variable((4, 4), symmetric=True)
    z22 = np.zeros((2, 2))
    X = cp.bmat([[X1, z22], [z22, Xe]])
    Aaug = np.array([[a0, 0.0], [-br, 0.0]])
    Baug = np.array([[b], [0.0]])
    g_fixed = ChannelGains(0.0, 0.0, observer_gain, br, bf)
    A0bar, dA, dG = channel_closed_loop_design(ch, g_fixed, delayed_input)
    Ae = A0bar[2:, 2:]
    AX = cp.bmat([[Aaug @ X1 + Baug @ W1, z22], [z22, Ae @ Xe]])
    big_vars = [cp.Variable((4, 4), symmetric=True) for _ in dA]
    big = lmi_blocks(AX, AX.T, X, [A for A, _ in dA], [G for G, _ in dG], big_vars, [Mh])
    nbig = big.shape[0]
    big_sym = 0.5 * (big + big.T)
    families = {
        "Theorem 1 LMI (Eq. 3.27) < 0": [big_sym << -eps * np.eye(nbig)],
        "Lyapunov matrix X = diag(X1, X_err) > 0 (normalised X1 >= I)":
            [X1 >> np.eye(2), Xe >> eps * np.eye(2)],
        "delay functionals Y, M > 0": [Y >> eps * np.eye(4) for Y in big_vars] +
                                      [Mh >> eps * np.eye(4)],
        "gain bound |[kp kr]| <= gain_bound": [
            cp.bmat([[gain_bound**2 * np.eye(1), W1], [W1.T, np.eye(2)]]) >> 0],
    }
    cons = [c for fam in families.values() for c in fam]
    prob = cp.Problem(cp.Minimize(0), cons)
    try:
        prob.solve(solver=solver)
    except cp.error.SolverError:
        prob.solve(solver="SCS", eps=1e-9, max_iters=200000)
    seconds = time.perf_counter() - t0
    if prob.status not in ("optimal", "optimal_inaccurate"):
        family = _blame(prob, families)
        raise LMIInfeasible(name, family, f"solver status {prob.status}")
    X1v = X1.value
    K = W1.value @ np.linalg.inv(X1v)
    gains = ChannelGains(kp=float(K[0, 0]), kr=float(K[0, 1]), l=observer_gain, br=br, bf=bf)
    lmi_val = 0.5 * (big.value + big.value.T)
    report = LMIReport(
        channel=name, status=prob.status, solve_seconds=seconds,
        lmi_max_eigenvalue=float(np.linalg.eigvalsh(lmi_val).max()),
        min_eigenvalues={"X1": float(np.linalg.eigvalsh(X1v).min()),
                         "X_err": float(np.linalg.eigvalsh(Xe.value).min()),
                         "Y": float(min(np.linalg.eigvalsh(Y.value).min() for Y in big_vars)),
                         "M_h": float(np.linalg.eigvalsh(Mh.value).min())},
        size=int(nbig))
    return gains, report


def _blame(prob, families) -> str:
    """Which family makes the problem infeasible: drop one family at a time."""
    import cvxpy as cp

    for fam in families:
        rest = [c for f, cs in families.items() if f != fam for c in cs]
        try:
            p = cp.Problem(cp.Minimize(0), rest)
            p.solve(solver="CLARABEL")
        except cp.error.SolverError:
            continue
        if p.status in ("optimal", "optimal_inaccurate"):
            return fam
    return "Theorem 1 LMI (Eq. 3.27) < 0"
