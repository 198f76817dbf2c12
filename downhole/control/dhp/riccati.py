"""The fast exact DHP trainer: the Riccati form with fresh samples, in the modal basis.

This is ``method="riccati"`` of :func:`downhole.control.dhp.trainer.train_dhp`: the same weights
as Algorithm 1 (seed Sec. 4.3.3) at its fixed point, with N_S fresh random samples at every
step, computed as

1. *samples* (fresh at every step): ``w = 2 u - 1``, ``u`` uniform from an SFC64 stream of its
   own per step (sample set), seeded from (seed, set) by SplitMix64; the compiled draw is
   bit-identical to ``numpy.random.Generator`` over ``numpy.random.SFC64`` with that state
   (:func:`draw_offsets`), so the plain-NumPy baseline and the reference methods draw the very
   same samples, independent of chunking and threads; ``z = r_k + radius * w``;
2. *the fit* of the nonlinear forces only (``h(z) = forces(z) @ force_map.T``): least squares
   of the q force columns on ``phi = [1, w]`` over the N_S samples (normal equations, Cholesky);
   steps are independent, so this runs chunk by chunk and, with ``threads > 1``, in parallel;
3. *the backward pass* (sequential) in the real modal basis of the linear part,
   ``A = V T V^-1`` with T block diagonal (1x1 and 2x2 blocks): with M' = V^T M V,
   g' = V^-1 g, Gam' = V^-1 force_map and the fitted slopes ``C`` (n, q),

       N M' = M' - M'g' (R + g'^T M' g')^-1 g'^T M'
       D'   = N M' T + (N M' Gam') (C^T V)            (D' = V^T D_k^T V)
       c'   = N [M' e'_k + T^T c'_{k+1}]
                  (e'_k = V^-1 (f_fit(r_k) + g u_ff - r_{k+1}))
       M'_{k-1} = Q' + T^T D'
       kd_k = R^-1 g'^T D' V^-1,  kc_k = R^-1 g'^T c'

   which is the Riccati form of :mod:`~downhole.control.dhp.trainer` written in other
   coordinates (a similarity transform; no approximation). The per-step cost is O(n^2 q) instead
   of the O(n^3) of the two dense products D = N M (A + H), M = Q + A^T D; T being block
   diagonal, N M' T and T^T D' are O(n^2). When the eigenvector matrix is ill-conditioned
   (cond > 1e7, e.g. a defective A) the pass runs with V = I and T = A (dense).

What is fresh: the N_S x n sample offsets of every step (``resample_every = 1``, as the seed's
Algorithm 1). What is constant and computed once: V, T, g', Gam', Q', S' and the linear part of
the residual along the reference. With ``resample_every = K`` the offsets (not the samples: they
stay centred on each step's reference) are re-used for K steps and the Cholesky factor of the
sample design matrix with them.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg
from numba import int64, njit, uint64

from downhole._blas import chol_solve_right, potrf_upper, syrk_gram

__all__ = ["ModalForm", "draw_offsets", "train_riccati"]


# ----------------------------------------------------------------------------------- samples
_M64 = (1 << 64) - 1


@njit(cache=True, nogil=True)
def _splitmix(x):
    x = x + uint64(0x9E3779B97F4A7C15)
    z = x
    z = (z ^ (z >> uint64(30))) * uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> uint64(27))) * uint64(0x94D049BB133111EB)
    return x, z ^ (z >> uint64(31))


@njit(cache=True, nogil=True)
def _sfc64_next(st):
    a, b, c, w = st[0], st[1], st[2], st[3]
    tmp = a + b + w
    st[3] = w + uint64(1)
    st[0] = b ^ (b >> uint64(11))
    st[1] = c + (c << uint64(3))
    st[2] = ((c << uint64(24)) | (c >> uint64(40))) + tmp
    return tmp


@njit(cache=True, nogil=True)
def _step_state(seed, k, st):
    """SFC64 state of sample set ``k``: a, b, c from SplitMix64 of (seed, k), counter 1, then 12
    discarded outputs (as NumPy seeds SFC64)."""
    x = uint64(seed) * uint64(0xD1B54A32D192ED03) + uint64(k)
    x, st[0] = _splitmix(x)
    x, st[1] = _splitmix(x)
    x, st[2] = _splitmix(x)
    st[3] = uint64(1)
    for _ in range(12):
        _sfc64_next(st)


def _step_state_py(seed: int, k: int) -> list[int]:
    """Pure-Python twin of :func:`_step_state` (for the NumPy generator)."""
    def mix(x):
        x = (x + 0x9E3779B97F4A7C15) & _M64
        z = x
        z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & _M64
        z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & _M64
        return x, z ^ (z >> 31)

    x = (seed * 0xD1B54A32D192ED03 + k) & _M64
    x, a = mix(x)
    x, b = mix(x)
    x, c = mix(x)
    w = 1
    for _ in range(12):
        tmp = (a + b + w) & _M64
        w += 1
        a = b ^ (b >> 11)
        b = (c + (c << 3)) & _M64
        c = ((((c << 24) | (c >> 40)) & _M64) + tmp) & _M64
    return [a, b, c, w]


@njit(cache=True, nogil=True)
def _draw_one(seed, set_id, PhiT):
    """Fresh samples of one step: PhiT (n+1, N) = [1, w]^T with w = 2u - 1, u the SFC64 stream
    of sample set ``set_id`` (sample by sample). The design matrix is stored transposed (one
    row per basis function) for the Gram product; the samples are z = r_k + radius * w."""
    p, N = PhiT.shape
    n = p - 1
    st = np.empty(4, dtype=np.uint64)
    scale = 2.0 / 9007199254740992.0          # 2u - 1 = k 2^-52 - 1, exact as in NumPy
    _step_state(seed, set_id, st)
    a, b, c, w = st[0], st[1], st[2], st[3]
    for s in range(N):
        PhiT[0, s] = 1.0
    for s in range(N):
        for i in range(n):
            tmp = a + b + w
            w += uint64(1)
            a = b ^ (b >> uint64(11))
            b = c + (c << uint64(3))
            c = ((c << uint64(24)) | (c >> uint64(40))) + tmp
            # the top 53 bits fit an int64: the signed conversion is exact and faster
            PhiT[i + 1, s] = int64(tmp >> uint64(11)) * scale - 1.0


@njit(cache=True, nogil=True)
def _draw(seed, set_ids, ref, radius, Phi, Z):
    """:func:`_draw_one` for every step j of a chunk (Phi (K, n+1, N)) and the samples
    Z[j] = r_j + radius * w (K, N, n)."""
    K, p, N = Phi.shape
    for j in range(K):
        _draw_one(seed, set_ids[j], Phi[j])
        refj = ref[j]
        for s in range(N):
            for i in range(p - 1):
                Z[j, s, i] = refj[i] + radius[i] * Phi[j, i + 1, s]


def draw_offsets(seed: int, set_ids, ns: int, n: int) -> np.ndarray:
    """Offsets w in [-1, 1) (len(set_ids), ns, n) in plain NumPy: ``Generator(SFC64)`` with the
    state of each set (the same numbers as the compiled trainer draws)."""
    bg = np.random.SFC64(0)
    gen = np.random.Generator(bg)
    st = bg.state
    out = np.empty((len(set_ids), ns, n))
    for j, k in enumerate(set_ids):
        st["state"]["state"] = np.array(_step_state_py(int(seed), int(k)), dtype=np.uint64)
        st["has_uint32"] = 0
        bg.state = st
        out[j] = gen.random((ns, n))
    out *= 2.0
    out -= 1.0
    return out


# ----------------------------------------------------------------------------------- modal form
class ModalForm:
    """Real block-diagonal (modal) coordinates of a DHP problem's linear part.

    Attributes
    ----------
    V, Vinv : ndarray (n, n)
        A = V T V^-1 (identity when ``banded`` is False).
    T : ndarray (n, n)
        Block-diagonal (``banded``) or A itself.
    td, tu, tl : ndarray (n,)
        Diagonal, super-diagonal T[i, i+1] and sub-diagonal T[i+1, i] of the blocks.
    banded : bool
    cond : float
        Condition number of V.
    """

    def __init__(self, A: np.ndarray, max_cond: float = 1e7):
        n = A.shape[0]
        self.banded = False
        self.cond = 1.0
        V = np.eye(n)
        T = A.copy()
        try:
            w, Vc = np.linalg.eig(A)
            # conjugate pairs adjacent, real eigenvalues as they come
            wr, Vr = scipy.linalg.cdf2rdf(w, Vc)
            Vr = Vr / np.linalg.norm(Vr, axis=0)
            cond = float(np.linalg.cond(Vr))
            if np.isfinite(cond) and cond < max_cond:
                Vinv = np.linalg.inv(Vr)
                Tm = Vinv @ A @ Vr
                off = Tm.copy()
                for i in range(n):
                    for j in range(max(0, i - 1), min(n, i + 2)):
                        off[i, j] = 0.0
                if np.abs(off).max() <= 1e-9 * max(1.0, np.abs(A).max()):
                    V, T, self.banded, self.cond = Vr, Tm, True, cond
        except (np.linalg.LinAlgError, ValueError):
            pass
        if self.banded:
            T = T.copy()
            for i in range(n):
                for j in range(n):
                    if abs(i - j) > 1:
                        T[i, j] = 0.0
            # 1x1 blocks next to each other carry no coupling
            self.Vinv = np.linalg.inv(V)
        else:
            self.Vinv = np.eye(n)
        self.V, self.T = V, T
        self.td = np.ascontiguousarray(np.diag(T))
        self.tu = np.zeros(n)
        self.tl = np.zeros(n)
        if self.banded:
            self.tu[:-1] = np.diag(T, 1)
            self.tl[:-1] = np.diag(T, -1)


# ----------------------------------------------------------------------------------- kernels
@njit(cache=True, nogil=True)
def _fit_one(PhiT, F, Vr, c0, Y, U, B, refactor):
    """Least-squares fit of one step: F (N, q) ~ c0 + w C_w on the samples PhiT = [1, w]^T;
    Y = C_w^T Vr = C^T V (q, n). U (p, p) holds the Cholesky factor of the Gram matrix
    (computed when ``refactor``), B (p, q) is scratch. False when it is singular."""
    q = F.shape[1]
    if refactor:
        syrk_gram(PhiT, U)                   # upper triangle of the Gram (BLAS dsyrk)
        if potrf_upper(U) != 0:              # its Cholesky factor in place (LAPACK dpotrf)
            return False
    np.dot(PhiT, F, B)
    chol_solve_right(U, B)                   # two BLAS dtrsm
    for c in range(q):
        c0[c] = B[0, c]
    np.dot(B[1:].T, Vr, Y)
    return True


@njit(cache=True, nogil=True)
def _fit(Phi, F, set_ids, Vr, c0, Y):
    """:func:`_fit_one` for every step j of a chunk (the factor re-used while the sample set
    repeats). Returns the first step whose design matrix is singular, or -1."""
    K, p, N = Phi.shape
    q = F.shape[2]
    if q == 0:
        return -1
    U = np.empty((p, p))
    B = np.empty((p, q))
    for j in range(K):
        if not _fit_one(Phi[j], F[j], Vr, c0[j], Y[j], U, B,
                        j == 0 or set_ids[j] != set_ids[j - 1]):
            return j
    return -1


@njit(cache=True, nogil=True)
def _mu2(X):
    """Spectral radius of a small real matrix (closed form for m <= 2; for larger m the limit
    of ||X^(2^j)||^(2^-j) over 30 squarings, normalized; no LAPACK, cheap to compile)."""
    m = X.shape[0]
    if m == 1:
        return abs(X[0, 0])
    if m == 2:
        tr = 0.5 * (X[0, 0] + X[1, 1])
        det = X[0, 0] * X[1, 1] - X[0, 1] * X[1, 0]
        disc = tr * tr - det
        if disc >= 0.0:
            sq = np.sqrt(disc)
            return max(abs(tr + sq), abs(tr - sq))
        return np.sqrt(abs(det))
    Y = X.copy()
    logr = 0.0
    w = 1.0
    for _ in range(30):
        nrm = np.sqrt(np.sum(Y * Y))
        if nrm == 0.0:
            return 0.0
        Y = Y / nrm
        logr += w * np.log(nrm)
        Y = Y @ Y
        w *= 0.5
    nrm = np.sqrt(np.sum(Y * Y))
    if nrm > 0.0:
        logr += w * np.log(nrm)
    return np.exp(logr)


@njit(cache=True, nogil=True)
def _small_inv(A, out):
    """Inverse of a small matrix into ``out`` (closed form for 1x1 and 2x2)."""
    m = A.shape[0]
    if m == 1:
        out[0, 0] = 1.0 / A[0, 0]
    elif m == 2:
        det = A[0, 0] * A[1, 1] - A[0, 1] * A[1, 0]
        out[0, 0] = A[1, 1] / det
        out[1, 1] = A[0, 0] / det
        out[0, 1] = -A[0, 1] / det
        out[1, 0] = -A[1, 0] / det
    else:                                   # Gauss-Jordan with partial pivoting
        W = A.copy()
        out[:, :] = 0.0
        for i in range(m):
            out[i, i] = 1.0
        for c in range(m):
            piv = c
            for r in range(c + 1, m):
                if abs(W[r, c]) > abs(W[piv, c]):
                    piv = r
            for j in range(m):
                W[c, j], W[piv, j] = W[piv, j], W[c, j]
                out[c, j], out[piv, j] = out[piv, j], out[c, j]
            f = 1.0 / W[c, c]
            for j in range(m):
                W[c, j] *= f
                out[c, j] *= f
            for r in range(m):
                if r != c:
                    f = W[r, c]
                    for j in range(m):
                        W[r, j] -= f * W[c, j]
                        out[r, j] -= f * out[c, j]


@njit(cache=True, nogil=True, fastmath={"reassoc", "contract"})
def _combine_rows(coef, X, out):
    """out (m, c) = coef (m, r) @ X (r, c) as combinations of the rows of X (m small)."""
    m, nr = coef.shape
    nc = X.shape[1]
    for l in range(m):
        o = out[l]
        for c in range(nc):
            o[c] = 0.0
        for r in range(nr):
            f = coef[l, r]
            Xr = X[r]
            for c in range(nc):
                o[c] += f * Xr[c]


@njit(cache=True, nogil=True, fastmath={"reassoc", "contract"})
def _mg_rows(M, gpT, Mg, gM, r0, r1, clear):
    """Rows r0..r1-1 of M'g' (n, m) into Mg and their share of g'^T M' (m, n) added to gM
    (cleared first when ``clear``)."""
    m, n = gpT.shape
    for l in range(m):
        gl = gpT[l]
        gMl = gM[l]
        if clear:
            for c in range(n):
                gMl[c] = 0.0
        for r in range(r0, r1):
            Mr = M[r]
            s = 0.0
            f = gl[r]
            for c in range(n):
                s += Mr[c] * gl[c]
                gMl[c] += f * Mr[c]
            Mg[r, l] = s


@njit(cache=True, nogil=True, error_model="numpy", fastmath={"reassoc", "contract"})
def _backward(k_hi, n_total, base, c0, Y, T, td, tu, tl, banded, gp, Gp, Qp, Sp, R, Rinv, Vinv,
              M, cn, kc, kd, mu_out, mu_max_ok, max_weight, keep_every, w_steps, w_Dp, w_cp,
              w_count):
    """Sequential backward pass over the K steps k_hi, k_hi - 1, ... of a chunk (modal form).

    base (K, n): V^-1 (A r_k + g u_ff,k - r_{k+1}); c0 (K, q) fitted forces at the reference;
    Y (K, q, n) = C^T V of the fitted slopes. M (n, n) and cn (n,) carry M'_k and c'_{k+1}
    between chunks. Returns (status, step): 0 ok, 1 mu >= mu_max_ok, 2 non-finite/too large."""
    K = base.shape[0]
    n = M.shape[0]
    m = gp.shape[1]
    q = Gp.shape[1]
    gpT = np.ascontiguousarray(gp.T)
    Mg = np.empty((n, m))
    gM = np.empty((m, n))
    NM = np.empty((n, n))
    D = np.empty((n, n))
    X = np.empty((n, q))
    XY = np.zeros((n, n))
    e = np.empty(n)
    v = np.empty(n)
    a = np.empty(n)
    W1 = np.empty((m, n))
    RW = np.empty((m, n))
    gMg = np.empty((m, m))
    X2 = np.empty((m, m))
    Sginv = np.empty((m, m))
    MgS = np.empty((n, m))
    gv = np.empty(m)
    t = np.empty(m)
    tdn = np.zeros(n + 1)
    tun = np.zeros(n + 1)      # tun[c] = T[c-1, c]
    tln = np.zeros(n + 1)      # tln[c] = T[c+1, c]
    for c in range(n):
        tdn[c] = td[c]
        if c > 0:
            tun[c] = tu[c - 1]
        tln[c] = tl[c]
    fresh_mg = False                           # Mg, gM hold M'g', g'^T M' of the current M
    for j in range(K):
        k = k_hi - j
        if k == n_total - 1:
            M[:, :] = Sp
            fresh_mg = False
            a[:] = 0.0
        elif banded:
            for i in range(n):
                s = td[i] * cn[i]
                if i > 0:
                    s += tu[i - 1] * cn[i - 1]
                if i < n - 1:
                    s += tl[i] * cn[i + 1]
                a[i] = s
        else:
            for i in range(n):
                acc = 0.0
                for r in range(n):
                    acc += T[r, i] * cn[r]
                a[i] = acc
        if not fresh_mg:                       # M'g', g'^T M' (m is small: loops, no BLAS)
            _mg_rows(M, gpT, Mg, gM, 0, n, True)
        for l1 in range(m):                    # g'^T M' g' (m x m, m small)
            for l2 in range(m):
                acc = 0.0
                for r in range(n):
                    acc += gpT[l1, r] * Mg[r, l2]
                gMg[l1, l2] = acc
        for l1 in range(m):
            for l2 in range(m):
                acc = 0.0
                for i in range(m):
                    acc += gMg[l1, i] * Rinv[i, l2]
                X2[l1, l2] = acc
        mu = _mu2(X2)
        mu_out[k] = mu
        if mu >= mu_max_ok:
            return 1, k
        _small_inv(R + gMg, Sginv)
        for r in range(n):                     # M'g' Sg^-1 (n, m)
            for l2 in range(m):
                acc = 0.0
                for i in range(m):
                    acc += Mg[r, i] * Sginv[i, l2]
                MgS[r, l2] = acc
        for r in range(n):                     # N M' = M' - M'g' Sg^-1 g'^T M'
            Mr = M[r]
            NMr = NM[r]
            for c in range(n):
                NMr[c] = Mr[c]
            for l in range(m):
                f = MgS[r, l]
                gl = gM[l]
                for c in range(n):
                    NMr[c] -= f * gl[c]
        for i in range(n):                     # e' = base + Gam' c0
            s = base[j, i]
            for l in range(q):
                s += Gp[i, l] * c0[j, l]
            e[i] = s
        for i in range(n):
            Mi = M[i]
            acc = a[i]
            for c in range(n):
                acc += Mi[c] * e[c]
            v[i] = acc
        for l in range(m):
            acc = 0.0
            for r in range(n):
                acc += gpT[l, r] * v[r]
            gv[l] = acc
        for l in range(m):
            acc = 0.0
            for i in range(m):
                acc += Sginv[l, i] * gv[i]
            t[l] = acc
        for i in range(n):                     # c' = N v
            s = v[i]
            for l in range(m):
                s -= Mg[i, l] * t[l]
            cn[i] = s
        if q > 0:                              # (N M' Gam') Y
            np.dot(NM, Gp, X)
            np.dot(X, Y[j], XY)
        if banded:                             # D' = N M' T + (N M' Gam') Y, and
            for l in range(m):                 # W1 = g'^T D' in the same pass
                W1[l, :] = 0.0
            for r in range(n):
                NMr = NM[r]
                Dr = D[r]
                XYr = XY[r]
                Dr[0] = NMr[0] * tdn[0] + XYr[0]
                for c in range(1, n):
                    Dr[c] = NMr[c] * tdn[c] + NMr[c - 1] * tun[c] + XYr[c]
                for c in range(n - 1):
                    Dr[c] += NMr[c + 1] * tln[c]
                for l in range(m):
                    f = gpT[l, r]
                    W1l = W1[l]
                    for c in range(n):
                        W1l[c] += f * Dr[c]
        else:
            for r in range(n):
                for c in range(n):
                    acc = XY[r, c]
                    for i in range(n):
                        acc += NM[r, i] * T[i, c]
                    D[r, c] = acc
            _combine_rows(gpT, D, W1)           # W1 = g'^T D'
        for l in range(m):                     # gains: kd = R^-1 g'^T D' V^-1
            for c in range(n):
                s = 0.0
                for i in range(m):
                    s += Rinv[l, i] * W1[i, c]
                RW[l, c] = s
        _combine_rows(RW, Vinv, kd[k])
        for l in range(m):
            acc = 0.0
            for r in range(n):
                acc += gpT[l, r] * cn[r]
            gv[l] = acc
        for l in range(m):
            acc = 0.0
            for i in range(m):
                acc += Rinv[l, i] * gv[i]
            kc[k, l] = acc
        for i in range(n):
            if not abs(cn[i]) < max_weight:
                return 2, k
        for r in range(m):
            for c in range(n):
                if not abs(kd[k, r, c]) < max_weight:
                    return 2, k
        if keep_every > 0 and k % keep_every == 0:
            w_steps[w_count[0]] = k
            w_Dp[w_count[0]] = D
            w_cp[w_count[0]] = cn
            w_count[0] += 1
        if banded:                             # M'_{k-1} = Q' + T^T D', and the next
            for l in range(m):                 # step's M'g', g'^T M' in the same pass
                gM[l, :] = 0.0
            for r in range(n):
                Mr = M[r]
                Qr = Qp[r]
                Dr = D[r]
                f = td[r]
                for c in range(n):
                    Mr[c] = Qr[c] + f * Dr[c]
                if r > 0:
                    f = tu[r - 1]
                    Dp = D[r - 1]
                    for c in range(n):
                        Mr[c] += f * Dp[c]
                if r < n - 1:
                    f = tl[r]
                    Dn = D[r + 1]
                    for c in range(n):
                        Mr[c] += f * Dn[c]
                _mg_rows(M, gpT, Mg, gM, r, r + 1, False)
            fresh_mg = True
        else:
            for r in range(n):
                for c in range(n):
                    acc = Qp[r, c]
                    for i in range(n):
                        acc += T[i, r] * D[i, c]
                    M[r, c] = acc
    return 0, -1


# ----------------------------------------------------------------------------------- driver
def _prepare(problem, radius):
    """Constant pieces of the modal Riccati form."""
    model = problem.model
    A = np.ascontiguousarray(model.linear)
    g = np.ascontiguousarray(model.g)
    n = A.shape[0]
    mf = ModalForm(A)
    if model.is_linear:
        Gam = np.zeros((n, 0))
    elif model.force_map is not None:
        Gam = np.ascontiguousarray(model.force_map)
    else:
        rows = model.nonlinear_rows
        Gam = np.zeros((n, rows.size))
        Gam[rows, np.arange(rows.size)] = 1.0
    Vinv, V = mf.Vinv, mf.V
    ref, uff = problem.reference, problem.u_ff
    lin = ref[:-1] @ A.T + uff @ g.T - ref[1:]
    base = np.ascontiguousarray(lin @ Vinv.T)
    return dict(mf=mf, gp=np.ascontiguousarray(Vinv @ g), Gp=np.ascontiguousarray(Vinv @ Gam),
                Qp=np.ascontiguousarray(V.T @ problem.Q @ V),
                Sp=np.ascontiguousarray(V.T @ problem.S @ V),
                Vr=np.ascontiguousarray(V / radius[:, None]), base=base, Gam=Gam,
                q=Gam.shape[1])


def _forces(model, Zflat, q):
    if q == 0:
        return np.zeros((Zflat.shape[0], 0))
    if model.force_map is not None:
        return np.ascontiguousarray(model.forces(Zflat), dtype=float)
    return np.ascontiguousarray(model.nonlinear(Zflat)[:, model.nonlinear_rows])


class _Chunk:
    """Fit results of one chunk of steps."""

    def __init__(self, K, ns, n, q):
        self.ns = ns
        self.c0 = np.zeros((K, q))
        self.Y = np.zeros((K, q, n))


def _produce(model, seed, q, ref, radius, buf, ks, sid, a, b):
    """Samples, forces and fits of the steps ks[a:b] into buf[a:b] (GIL released in kernels).

    A model with a compiled ``sample_fit`` (e.g. the directional design model) does all three
    per step in one kernel (the step's samples stay in cache); otherwise the samples of the
    chunk are drawn, ``model.forces`` evaluated on them and the fits computed."""
    if b <= a:
        return -1
    n = ref.shape[1]
    ns = buf.ns
    if q == 0:
        return -1
    fused = getattr(model, "sample_fit", None)
    if fused is not None:
        j = fused(seed, sid[a:b], ref[ks[a:b]], radius, ns, buf.Vr, buf.c0[a:b], buf.Y[a:b])
        return -1 if j < 0 else a + j
    Phi = np.empty((b - a, n + 1, ns))
    Z = np.empty((b - a, ns, n))
    _draw(seed, sid[a:b], ref[ks[a:b]], radius, Phi, Z)
    F = _forces(model, Z.reshape((b - a) * ns, n), q).reshape(b - a, ns, q)
    j = _fit(Phi, F, sid[a:b], buf.Vr, buf.c0[a:b], buf.Y[a:b])
    return -1 if j < 0 else a + j


class _Feeder:
    """Fits of the chunks, shared by ``workers`` threads and the main thread.

    A chunk's steps are cut into blocks of :attr:`block` steps queued in chunk order. The
    workers take blocks as they come; :meth:`wait` (the main thread, before the backward pass
    of chunk i) takes the remaining blocks of chunk i itself and then waits for the ones in
    flight. So with two threads in all the main thread computes fits whenever it is not in the
    backward pass, and no more threads than cores run (kernels release the GIL)."""

    block = 16

    def __init__(self, produce, workers: int):
        import collections
        import threading

        self._produce = produce
        self._cv = threading.Condition()
        self._queue = collections.deque()
        self._left: dict[int, int] = {}
        self._bad: dict[int, list[int]] = {}
        self._error: BaseException | None = None
        self._closed = False
        self._threads = [threading.Thread(target=self._work, daemon=True,
                                          name=f"dhp-fit-{w}") for w in range(workers)]
        for t in self._threads:
            t.start()

    def add(self, i: int, K: int) -> None:
        cuts = list(range(0, K, self.block)) + [K]
        with self._cv:
            self._left[i] = len(cuts) - 1
            self._bad[i] = []
            self._queue.extend((i, cuts[j], cuts[j + 1]) for j in range(len(cuts) - 1))
            self._cv.notify_all()

    def _run(self, item) -> None:
        i, a, b = item
        try:
            r = self._produce(i, a, b)
            err = None
        except BaseException as exc:
            r, err = -1, exc
        with self._cv:
            if err is not None and self._error is None:
                self._error = err
            if r >= 0:
                self._bad[i].append(r)
            self._left[i] -= 1
            self._cv.notify_all()

    def _work(self) -> None:
        while True:
            with self._cv:
                while not self._queue and not self._closed:
                    self._cv.wait()
                if self._closed:
                    return
                item = self._queue.popleft()
            self._run(item)

    def wait(self, i: int) -> list[int]:
        """Finish the fits of chunk i (helping); the steps (chunk positions) that failed."""
        while True:
            with self._cv:
                if self._error is not None:
                    raise self._error
                if self._left[i] == 0:
                    return self._bad.pop(i)
                item = None
                if self._queue and self._queue[0][0] == i:
                    item = self._queue.popleft()
                else:
                    self._cv.wait()
            if item is not None:
                self._run(item)

    def close(self) -> None:
        with self._cv:
            self._closed = True
            self._queue.clear()
            self._cv.notify_all()
        for t in self._threads:
            t.join()


def train_riccati(problem, settings, ns, radius, out, mu_ok, bar=None):
    """Run the modal Riccati trainer; fills ``out`` (kc, kd, mu, w_steps, w_store, w_count).

    Returns ``(status, step)``: 0 ok, 1 mu >= 1, 2 weights non-finite/too large, 3 singular
    sample design matrix."""
    model = problem.model
    n = model.n_states
    pre = _prepare(problem, radius)
    mf, q = pre["mf"], pre["q"]
    n_steps = problem.n_steps
    kc, kd, mu = out["kc"], out["kd"], out["mu"]
    stride = out["stride"]
    n_keep = out["w_store"].shape[0]
    w_steps, w_count = out["w_steps"], out["w_count"]
    w_Dp = np.zeros((n_keep, n, n))
    w_cp = np.zeros((n_keep, n))
    Rinv = np.linalg.inv(problem.R)
    M = np.zeros((n, n))
    cn = np.zeros(n)
    ref = problem.reference
    re = settings.resample_every
    seed = int(settings.seed)
    threads = settings.threads
    # chunk: ~2 MB of samples per thread when they are stored, at most settings.chunk steps
    fused = getattr(model, "sample_fit", None) is not None
    K0 = settings.chunk if fused else max(1, min(settings.chunk,
                                                 threads * max(4, 262144 // (ns * n))))
    bufs = [_Chunk(K0, ns, n, q) for _ in range(2 if threads > 1 else 1)]
    for bf in bufs:
        bf.Vr = pre["Vr"]
    chunks = []
    k_hi = n_steps - 1
    while k_hi >= 0:
        K = min(K0, k_hi + 1)
        ks = np.arange(k_hi, k_hi - K, -1)
        chunks.append((k_hi, ks, ((n_steps - 1 - ks) // re).astype(np.int64)))
        k_hi -= K

    def produce(i, a, b):
        k_hi, ks, sid = chunks[i]
        return _produce(model, seed, q, ref, radius, bufs[i % len(bufs)], ks, sid, a, b)

    status, kf = 0, -1
    feeder = _Feeder(produce, threads - 1)
    try:
        for i in range(min(len(bufs), len(chunks))):
            feeder.add(i, chunks[i][1].size)
        for i, (k_hi, ks, sid) in enumerate(chunks):
            bad = feeder.wait(i)       # the main thread helps with the fits of chunk i
            if bad:
                return 3, int(ks[min(bad)])
            buf = bufs[i % len(bufs)]
            K = ks.size
            status, kf = _backward(k_hi, n_steps, pre["base"][ks], buf.c0[:K], buf.Y[:K], mf.T,
                                   mf.td, mf.tu, mf.tl, mf.banded, pre["gp"], pre["Gp"],
                                   pre["Qp"], pre["Sp"], problem.R, Rinv, mf.Vinv, M, cn, kc,
                                   kd, mu, mu_ok, settings.max_weight, stride, w_steps, w_Dp,
                                   w_cp, w_count)
            if status:
                break
            if i + len(bufs) < len(chunks):     # buffer i % len(bufs) is free again
                feeder.add(i + len(bufs), chunks[i + len(bufs)][1].size)
            if bar:
                bar[0].update(bar[1], advance=K)
    finally:
        feeder.close()
    # full weights W_k = [c - D r_k; D^T] of the snapshots, back in the original coordinates
    for i in range(int(w_count[0])):
        k = w_steps[i]
        Dt = mf.Vinv.T @ w_Dp[i] @ mf.Vinv
        c = mf.Vinv.T @ w_cp[i]
        out["w_store"][i, 0] = c - Dt @ ref[k]
        out["w_store"][i, 1:] = Dt.T
    return status, kf
