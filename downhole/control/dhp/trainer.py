"""The DHP (single-network adaptive critic) trainer of seed Sec. 4.3.3: Algorithm 1 and its fast
exact form.

The co-state is approximated by one network, lambda_{k+1} = W_k^T phi(z_k) (Eq. 4.35), trained
backward from the final condition lambda_n = S (z_n - r_n) (Eqs. 4.36-4.42) on N_S random samples
per step, and applied as u_k = u_ff,k - R^-1 g^T lambda_{k+1} (Eq. 4.34; u_ff = 0 in the seed,
see :mod:`downhole.control.dhp` for the feed-forward). Two methods compute the same weights:

``"algorithm1"``
    The seed's Algorithm 1, in plain NumPy (the reference): at each step, iterate W^{i+1} =
    LS-fit of the target co-state computed with W^i until the change of the co-state on the
    samples (Eq. 4.43) falls below ``threshold`` (relative to the target's size), at most
    ``n_iterations`` times. Any basis, the seed's or the exact Jacobian.
``"riccati"``
    g is constant, so the per-sample target is affine in the network output and the iteration's
    fixed point has a closed form, y* = (I + M G)^-1 [M (f(z) + g u_ff - r_{k+1}) + a],
    G = g R^-1 g^T, whose least-squares fit is Algorithm 1's converged weight exactly (the
    sample projection acts on the left, M G on the right, so they commute). Written as matrices:
    fit only the nonlinear forces to the samples (h(z) ~ c0 + H (z - r_k)), then
    D_k^T = N M (A + H), c_k = N [M(f_r + g u_ff - r_{k+1}) + a] with
    N = (I + M G)^-1 = I - M g (R + g^T M g)^-1 g^T. For a linear plant this is the
    finite-horizon LQR Riccati recursion. Computed in the modal basis of A with compiled
    kernels (:mod:`downhole.control.dhp.riccati`); ``downhole.control.dhp.baseline.riccati_numpy``
    is the same trainer in plain NumPy (benchmark baseline, same samples). Linear basis and the
    seed's Jacobian.

Both methods draw the samples from one SFC64 stream (``settings.seed``), so for the same
settings they see the very same samples.

Algorithm 1's fixed-point iteration contracts only if mu = rho(g^T M g R^-1) < 1, where M is
the target's derivative with respect to z_{k+1} (S at the last step, Q + A^T W_{z,k+1}^T
before). Both methods compute mu at every step (``DHPTraining.mu``); with
``require_contraction`` (default) Algorithm 1 stops with :class:`TrainingDiverged` naming the
method and the step when mu >= 1. The Riccati form solves the fixed point directly - (I + M G)
is invertible for any M, G >= 0 - so it trains every well-posed problem (R > 0, Q, S >= 0)
whatever mu is.

The network is fitted in centred form lambda_{k+1} = c_k + D_k^T (z_k - r_k) (identical to
W_k = [c_k - D_k^T r_k; D_k] for phi = [1, z], better conditioned).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from downhole.control.affine import ControlAffineModel
from downhole.control.dhp.riccati import draw_offsets, train_riccati
from downhole.errors import DownholeError, DownholeInputError

__all__ = [
    "ITERATIVE_METHODS",
    "METHODS",
    "DHPProblem",
    "DHPSettings",
    "DHPTraining",
    "LinearBasis",
    "QuadraticBasis",
    "TrainingDiverged",
    "train_dhp",
]

METHODS = ("riccati", "algorithm1")
#: The methods that iterate Algorithm 1 to its fixed point (they need mu < 1).
ITERATIVE_METHODS = ("algorithm1",)


class TrainingDiverged(DownholeError, FloatingPointError):
    """DHP training stopped: names the step (and time), the iteration and why."""

    def __init__(self, step: int, dt: float, reason: str, iteration: int | None = None):
        self.step, self.time, self.reason, self.iteration = step, step * dt, reason, iteration
        it = f", iteration {iteration}" if iteration is not None else ""
        super().__init__(f"DHP training diverged at step k = {step} (t = {step * dt:.6g} s{it}): "
                         f"{reason}")


# ---------------------------------------------------------------------------------------- bases
class LinearBasis:
    """phi(z) = [1, z_1, ..., z_n] (Eq. 4.46), p = n + 1. Enables the Riccati form."""

    is_linear = True
    name = "linear"

    def size(self, n: int) -> int:
        return n + 1

    def __call__(self, Z: np.ndarray) -> np.ndarray:
        return np.concatenate([np.ones((Z.shape[0], 1)), Z], axis=1)


class QuadraticBasis:
    """phi(z) = [1, z, z_i^2] (linear plus squares), p = 2n + 1 (Algorithm 1 only)."""

    is_linear = False
    name = "quadratic"

    def size(self, n: int) -> int:
        return 2 * n + 1

    def __call__(self, Z: np.ndarray) -> np.ndarray:
        return np.concatenate([np.ones((Z.shape[0], 1)), Z, Z * Z], axis=1)


_BASES = {"linear": LinearBasis, "quadratic": QuadraticBasis}


def _basis(spec):
    """A basis from its name or a user object (``size(n)``, ``__call__(Z) -> (N, p)``,
    ``is_linear``)."""
    if isinstance(spec, str):
        return _BASES[spec]()
    return spec


# ---------------------------------------------------------------------------------------- settings
@dataclass(frozen=True)
class DHPSettings:
    """Hyper-parameters of the trainer (Table 4.1 and Algorithm 1).

    Attributes
    ----------
    n_samples : int or None
        N_S, random samples per step; default ``max(2 (n + 1), 20)``. Fewer than the basis size
        is rejected (the fit is singular); fewer than 2 (n + 1) is noisy.
    n_iterations : int
        N_I, maximum Algorithm 1 iterations per step (20 in Table 4.1).
    threshold : float
        Algorithm 1 stops at a step when max |lambda^{i+1} - lambda^i| over the samples is below
        ``threshold`` times max |lambda^{i+1}| (Eq. 4.43, relative).
    sample_radius : float or array of float
        Samples z = r_k + U(-a, a) in non-dimensional units (local to the reference,
        docs/seed-errata.md).
    method : str
        One of :data:`METHODS`.
    jacobian : {"seed", "exact"}
        A_k in the co-state recursion: the seed's constant P^-1 A_d P, or with the derivative
        of the nonlinear forces (``algorithm1`` only).
    basis : {"linear", "quadratic"} or object
        phi; non-linear bases need ``algorithm1``. Any object with ``size(n) -> p``,
        ``__call__(Z (N, n)) -> (N, p)`` (the first column constant) and ``is_linear = False``
        plugs in (see :class:`QuadraticBasis`); its ``name`` (default: the class name) is what
        a saved controller records.
    warm_start : bool
        Start Algorithm 1 at step k from W_{k+1} (True) or from zero (False, the seed's "initial
        guess").
    require_contraction : bool
        For Algorithm 1 (``"algorithm1"``): stop with :class:`TrainingDiverged` when
        mu = rho(g^T M g R^-1) >= 1 at some step (the iteration cannot contract there). Ignored
        by the non-iterative ``"riccati"``, which needs no contraction.
    seed : int
        Random generator seed of the samples.
    record_steps : tuple of int
        Steps (negative counts from the end, -1 = n - 1) whose Algorithm 1 weight iterates are
        recorded (Fig. 4.5).
    weight_stride : int or None
        Keep the full weights W_k every ``weight_stride`` steps (None: about 400 snapshots).
    chunk : int
        Steps per chunk of the Riccati form's sample/force/fit work (memory vs. overhead).
    resample_every : int
        Draw a fresh set of N_S sample offsets every ``resample_every`` steps (1: every step,
        the seed's Algorithm 1). The samples are always centred on the step's own reference;
        re-using the offsets lets the Riccati form factor the least-squares fit once per set.
    max_weight : float
        Weights larger than this (or non-finite) count as divergence (for ``"riccati"``: the
        co-state offsets c_k and the gains R^-1 g^T W_k).
    threads : int
        Threads for the per-step force fits of ``"riccati"`` (independent across steps; the
        backward pass stays sequential). 1 (default) is single-threaded; BLAS is always pinned
        to one thread inside the trainer.
    """

    n_samples: int | None = None
    n_iterations: int = 20
    threshold: float = 1e-6
    sample_radius: float | tuple = 0.02
    method: str = "riccati"
    jacobian: str = "seed"
    basis: object = "linear"
    warm_start: bool = True
    require_contraction: bool = True
    seed: int = 0
    record_steps: tuple = (-1,)
    weight_stride: int | None = None
    chunk: int = 256
    max_weight: float = 1e12
    resample_every: int = 1
    threads: int = 1

    def __post_init__(self):
        if self.method not in METHODS:
            raise DownholeInputError(f"method must be one of {METHODS}, got {self.method!r}")
        if self.jacobian not in ("seed", "exact"):
            raise DownholeInputError(f"jacobian must be 'seed' or 'exact', got {self.jacobian!r}")
        if isinstance(self.basis, str):
            if self.basis not in _BASES:
                raise DownholeInputError(f"basis must be one of {tuple(_BASES)} or a basis "
                                         f"object, got {self.basis!r}")
        elif not (callable(self.basis) and callable(getattr(self.basis, "size", None))
                  and hasattr(self.basis, "is_linear")):
            raise DownholeInputError(f"basis object {self.basis!r} needs size(n), "
                                     "__call__(Z) and is_linear")
        linear = self.basis == "linear" or (not isinstance(self.basis, str)
                                             and isinstance(self.basis, LinearBasis))
        if self.method != "algorithm1" and (self.jacobian != "seed" or not linear):
            raise DownholeInputError(
                f"method {self.method!r} needs basis='linear' and jacobian='seed'; use "
                "method='algorithm1' for other bases or the exact Jacobian")
        if not (isinstance(self.n_iterations, int) and self.n_iterations >= 1):
            raise DownholeInputError(f"n_iterations must be an integer >= 1, got "
                                     f"{self.n_iterations!r}")
        if not (self.threshold > 0 and math.isfinite(self.threshold)):
            raise DownholeInputError(f"threshold must be positive, got {self.threshold!r}")
        if self.n_samples is not None and not (isinstance(self.n_samples, int)
                                               and self.n_samples >= 2):
            raise DownholeInputError(f"n_samples must be an integer >= 2, got {self.n_samples!r}")
        r = np.asarray(self.sample_radius, dtype=float)
        if not np.all(np.isfinite(r)) or np.any(r <= 0):
            raise DownholeInputError(f"sample_radius must be positive, got {self.sample_radius!r}")
        if self.chunk < 1:
            raise DownholeInputError(f"chunk must be >= 1, got {self.chunk!r}")
        if not (isinstance(self.threads, int) and self.threads >= 1):
            raise DownholeInputError(f"threads must be an integer >= 1, got {self.threads!r}")
        if not (isinstance(self.resample_every, int) and self.resample_every >= 1):
            raise DownholeInputError(f"resample_every must be an integer >= 1, got "
                                     f"{self.resample_every!r}")


def _psd(name, M, n, definite=False):
    M = np.asarray(M, dtype=float)
    if M.ndim == 1:
        M = np.diag(M)
    if M.shape != (n, n):
        raise DownholeInputError(f"{name} must be ({n}, {n}) (or a diagonal of length {n}), "
                                 f"got shape {M.shape}")
    if not np.all(np.isfinite(M)):
        raise DownholeInputError(f"{name} must be finite")
    if not np.allclose(M, M.T, rtol=1e-10, atol=1e-14 * max(1.0, np.abs(M).max())):
        raise DownholeInputError(f"{name} must be symmetric")
    ev = np.linalg.eigvalsh(0.5 * (M + M.T))
    tol = 1e-12 * max(1.0, float(np.abs(ev).max()))
    if definite and ev.min() <= 0:
        raise DownholeInputError(f"{name} must be positive definite; its smallest eigenvalue is "
                                 f"{ev.min():.6g}")
    if not definite and ev.min() < -tol:
        raise DownholeInputError(f"{name} must be positive semi-definite; its smallest "
                                 f"eigenvalue is {ev.min():.6g}")
    return M


@dataclass
class DHPProblem:
    """A finite-horizon tracking problem on a :class:`ControlAffineModel` (Eq. 4.26).

    J = 1/2 sum_{k<n} [(z_k - r_k)^T Q (z_k - r_k) + (u_k - u_ff,k)^T R (u_k - u_ff,k)]
        + 1/2 (z_n - r_n)^T S (z_n - r_n), all in non-dimensional units (Q, R, S are the
    discrete weights, i.e. the seed's Qbar dt etc.).

    Parameters
    ----------
    model : ControlAffineModel
    Q, S : array_like (n, n) or (n,)
        Positive semi-definite state and final-state weights.
    R : array_like (m, m) or (m,)
        Positive definite input weight.
    reference : array_like (n_steps + 1, n)
        Non-dimensional state reference r_0..r_n (Eqs. 4.21-4.23).
    u_ff : array_like (n_steps, m), optional
        Non-dimensional feed-forward inputs (default zero, the seed's formulation).
    """

    model: ControlAffineModel
    Q: np.ndarray
    R: np.ndarray
    S: np.ndarray
    reference: np.ndarray
    u_ff: np.ndarray | None = None

    def __post_init__(self):
        if not isinstance(self.model, ControlAffineModel):
            raise DownholeInputError(f"model must be a ControlAffineModel, got "
                                     f"{type(self.model).__name__}")
        n, m = self.model.n_states, self.model.n_inputs
        self.Q = _psd("Q", self.Q, n)
        self.S = _psd("S", self.S, n)
        self.R = _psd("R", self.R, m, definite=True)
        ref = np.asarray(self.reference, dtype=float)
        if ref.ndim != 2 or ref.shape[1] != n:
            raise DownholeInputError(f"reference must have shape (n_steps + 1, {n}), got "
                                     f"{ref.shape}")
        if ref.shape[0] < 2:
            raise DownholeInputError(
                f"the horizon must be at least one step: reference has {ref.shape[0]} row(s), "
                "expected n_steps + 1 >= 2")
        if not np.all(np.isfinite(ref)):
            raise DownholeInputError("reference must be finite")
        self.reference = ref
        ns = ref.shape[0] - 1
        if self.u_ff is None:
            self.u_ff = np.zeros((ns, m))
        else:
            uff = np.asarray(self.u_ff, dtype=float)
            if uff.shape != (ns, m):
                raise DownholeInputError(f"u_ff must have shape (n_steps, m) = ({ns}, {m}), got "
                                         f"{uff.shape}")
            self.u_ff = uff

    @property
    def n_steps(self) -> int:
        return self.reference.shape[0] - 1


@dataclass
class DHPTraining:
    """What training returns: the time-varying affine policy and diagnostics.

    The online law is u_k = u_ff,k - kc_k - kd_k (z_k - r_k) (non-dimensional), which equals
    u_ff,k - R^-1 g^T W_k^T phi(z_k) with W_k = [c_k - D_k^T r_k; D_k].

    Attributes
    ----------
    kc : ndarray (n_steps, m)
        R^-1 g^T c_k.
    kd : ndarray (n_steps, m, n)
        R^-1 g^T D_k^T.
    weight_steps : ndarray of int
        Steps k whose full weights W_k (p, n) are kept in ``weights``.
    weights : ndarray (len(weight_steps), p, n)
    iterations : ndarray of int (n_steps,)
        Algorithm 1 iterations used at each step (0 for the Riccati form).
    errors : ndarray (n_steps,)
        Final relative training error of each step (Eq. 4.44 on the samples; 0 for the Riccati
        form).
    mu : ndarray (n_steps,)
        Contraction factor rho(g^T M g R^-1) of each step.
    iteration_history : dict of int to ndarray (iters + 1, p, n)
        Weight iterates at the recorded steps (Fig. 4.5).
    seconds : float
        Wall time of the training.
    """

    kc: np.ndarray
    kd: np.ndarray
    weight_steps: np.ndarray
    weights: np.ndarray
    iterations: np.ndarray
    errors: np.ndarray
    mu: np.ndarray
    iteration_history: dict = field(default_factory=dict)
    seconds: float = 0.0
    method: str = ""

    def controls(self, z_nd: np.ndarray, k: int, reference: np.ndarray, u_ff: np.ndarray):
        """u_k (non-dimensional) for state ``z_nd`` at step ``k``."""
        return u_ff[k] - self.kc[k] - self.kd[k] @ (z_nd - reference[k])


# ---------------------------------------------------------------------------------------- driver
def _progress(total, enabled, label):
    if not enabled:
        return None
    from rich.progress import (
        BarColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    prog = Progress(TextColumn(label), BarColumn(),
                    TextColumn("{task.completed}/{task.total} steps"),
                    TimeElapsedColumn(), TimeRemainingColumn(), transient=True)
    prog.start()
    task = prog.add_task(label, total=total)
    return prog, task


def train_dhp(problem: DHPProblem, settings: DHPSettings | None = None, *,
              progress: bool = False) -> DHPTraining:
    """Train the DHP critic backward over the horizon and return the policy.

    Parameters
    ----------
    problem : DHPProblem
        Model, weights, reference and feed-forward (non-dimensional).
    settings : DHPSettings, optional
        Hyper-parameters; default ``DHPSettings()`` (Riccati form).
    progress : bool
        Show a progress bar (rich) over the steps.

    Returns
    -------
    DHPTraining

    Raises
    ------
    DownholeInputError
        Settings that do not fit the problem (too few samples for the basis, ...).
    TrainingDiverged
        mu >= 1 at some step of Algorithm 1 (with ``require_contraction``), non-finite or
        exploding weights, or Algorithm 1's error growing instead of shrinking; the message names
        the method (for mu), the step and the time.

    Examples
    --------
    >>> import numpy as np
    >>> from downhole.control.affine import ControlAffineModel
    >>> m = ControlAffineModel(np.array([[1.0, 0.1], [0.0, 1.0]]), np.array([[0.0], [0.1]]),
    ...                        state_scale=1.0, input_scale=1.0, dt=0.1, state_names="xv",
    ...                        input_names=["u"], strict_inputs=False)
    >>> pb = DHPProblem(m, Q=[1.0, 0.1], R=[0.1], S=[1.0, 1.0], reference=np.zeros((51, 2)))
    >>> tr = train_dhp(pb)
    >>> tr.kd.shape
    (50, 1, 2)
    """
    settings = settings or DHPSettings()
    if not isinstance(problem, DHPProblem):
        raise DownholeInputError(f"problem must be a DHPProblem, got {type(problem).__name__}")
    model = problem.model
    n, m = model.n_states, model.n_inputs
    basis = _basis(settings.basis)
    p = basis.size(n)
    ns = settings.n_samples if settings.n_samples is not None else max(2 * (n + 1), 20)
    if ns < p:
        raise DownholeInputError(
            f"n_samples = {ns} is fewer than the {p} basis functions of a {n}-state model: the "
            f"least-squares fit is singular; use n_samples >= 2 (n + 1) = {2 * (n + 1)}")
    radius = np.broadcast_to(np.asarray(settings.sample_radius, dtype=float), (n,)).copy()
    n_steps = problem.n_steps
    rng = settings.seed
    Rinv = np.linalg.inv(problem.R)
    stride = settings.weight_stride or max(1, n_steps // 400)
    n_keep = n_steps // stride + 2
    w_steps = np.full(n_keep, -1, dtype=np.int64)
    w_store = np.zeros((n_keep, p, n))
    w_count = np.zeros(1, dtype=np.int64)
    kc = np.zeros((n_steps, m))
    kd = np.zeros((n_steps, m, n))
    mu = np.full(n_steps, np.nan)
    err = np.zeros(n_steps)
    iters = np.zeros(n_steps, dtype=np.int64)
    rec_steps = sorted({(s if s >= 0 else n_steps + s) for s in settings.record_steps
                        if -n_steps <= s < n_steps})
    history: dict[int, np.ndarray] = {}
    method = settings.method
    # only Algorithm 1 iterates to the fixed point; the other methods solve it directly
    mu_ok = 1.0 if settings.require_contraction and method in ITERATIVE_METHODS else np.inf
    t0 = time.perf_counter()
    bar = _progress(n_steps, progress, f"DHP {method}")
    from threadpoolctl import threadpool_limits

    # the kernels multiply many small matrices: threaded BLAS only adds overhead (10-30x slower
    # on a shared 2-core machine)
    limiter = threadpool_limits(limits=1, user_api="blas")
    try:
        if method == "algorithm1":
            _train_numpy(problem, settings, basis, ns, radius, rng, Rinv, kc, kd, mu, err, iters,
                         stride, w_steps, w_store, w_count, rec_steps, history, mu_ok, bar)
        else:
            out = dict(kc=kc, kd=kd, mu=mu, stride=stride, w_steps=w_steps, w_store=w_store,
                       w_count=w_count)
            status, kf = train_riccati(problem, settings, ns, radius, out, mu_ok, bar)
            if status == 1:
                raise TrainingDiverged(int(kf), model.dt, _mu_reason(mu[kf], method))
            if status == 2:
                raise TrainingDiverged(int(kf), model.dt,
                                       f"weights became non-finite or exceeded max_weight = "
                                       f"{settings.max_weight:g}")
            if status == 3:
                raise TrainingDiverged(int(kf), model.dt, "the least-squares fit of the forces "
                                       "is singular (sample design matrix not positive definite)")
    finally:
        limiter.restore_original_limits()
        if bar:
            bar[0].stop()
    order = np.argsort(w_steps[:w_count[0]])
    return DHPTraining(kc=kc, kd=kd, weight_steps=w_steps[:w_count[0]][order],
                       weights=w_store[:w_count[0]][order], iterations=iters, errors=err, mu=mu,
                       iteration_history=history, seconds=time.perf_counter() - t0,
                       method=method)


def _mu_reason(mu, method):
    return (f"the Algorithm 1 iteration (method {method!r}) cannot converge: mu = "
            f"rho(g^T M g R^-1) = {mu:.4g} >= 1 (M = S at the last step, Q + A^T W_z^T before). "
            "Use method='riccati' (no iteration, no contraction needed), or "
            "increase R, decrease Q/S, or scale the inputs (input_scale) so that g^T M g is "
            "small against R")


def _train_numpy(problem, settings, basis, ns, radius, rng, Rinv, kc, kd, mu, err, iters, stride,
                 w_steps, w_store, w_count, rec_steps, history, mu_ok, bar):
    """Algorithm 1 in plain NumPy (the reference): any basis, seed or exact Jacobian."""
    model = problem.model
    n = model.n_states
    A, g = model.linear, model.g
    G = g @ Rinv @ g.T
    Q, S, ref, uff = problem.Q, problem.S, problem.reference, problem.u_ff
    n_steps = problem.n_steps
    W_next = None
    for k in range(n_steps - 1, -1, -1):
        delta = draw_offsets(rng, [(n_steps - 1 - k) // settings.resample_every], ns,
                             n)[0] * radius
        Z = ref[k] + delta
        Phi = basis(Z)
        base = model.f(Z) + g @ uff[k]
        last = k == n_steps - 1
        if basis.is_linear and settings.jacobian == "seed":
            Mk = S if last else Q + A.T @ W_next[1:].T
            mu[k] = float(np.max(np.abs(np.linalg.eigvals(g.T @ Mk @ g @ Rinv))))
            if mu[k] >= mu_ok:
                raise TrainingDiverged(k, model.dt, _mu_reason(mu[k], settings.method))
        if settings.warm_start and W_next is not None:
            W = W_next.copy()
        else:
            W = np.zeros((Phi.shape[1], n))
        Y = Phi @ W
        rec = [W.copy()] if k in rec_steps else None
        e = np.inf
        it = 0
        first_err = None
        for it in range(1, settings.n_iterations + 1):
            Z1 = base - Y @ G
            if last:
                T = (Z1 - ref[k + 1]) @ S.T
            else:
                lam2 = basis(Z1) @ W_next
                if settings.jacobian == "seed":
                    T = (Z1 - ref[k + 1]) @ Q.T + lam2 @ A
                else:
                    J = model.jacobian(Z1, kind="exact")
                    T = (Z1 - ref[k + 1]) @ Q.T + np.einsum("sij,si->sj", J, lam2)
            W = np.linalg.lstsq(Phi, T, rcond=None)[0]
            Ynew = Phi @ W
            big = float(np.max(np.abs(Ynew)))
            e = float(np.max(np.abs(Ynew - Y))) / max(big, 1e-300)
            Y = Ynew
            if rec is not None:
                rec.append(W.copy())
            if not (np.isfinite(e) and big < settings.max_weight):
                raise TrainingDiverged(k, model.dt, f"co-state became non-finite or exceeded "
                                       f"max_weight = {settings.max_weight:g}", iteration=it)
            first_err = e if first_err is None else first_err
            if e <= settings.threshold:
                break
        else:
            if e > 10.0 * first_err and e > 1.0:
                raise TrainingDiverged(k, model.dt, f"training error grew from {first_err:.3g} "
                                       f"to {e:.3g} over {settings.n_iterations} iterations",
                                       iteration=it)
        iters[k] = it
        err[k] = e
        if rec is not None:
            history[k] = np.array(rec)
        if basis.is_linear:
            # centred gains: lambda = W0 + Wz^T z = (W0 + Wz^T r_k) + Wz^T (z - r_k)
            c = W[0] + W[1:].T @ ref[k]
            Dt = W[1:].T
            kc[k] = Rinv @ g.T @ c
            kd[k] = Rinv @ g.T @ Dt
        else:
            # the online law is the policy linearized at the reference (storing W_k of a
            # non-linear basis for every step would take p n 8 bytes per step)
            eps = 1e-6
            lam0 = basis(ref[k][None])[0] @ W
            J = np.empty((n, n))
            for i in range(n):
                zp = ref[k].copy()
                zp[i] += eps
                J[:, i] = (basis(zp[None])[0] @ W - lam0) / eps
            kc[k] = Rinv @ g.T @ lam0
            kd[k] = Rinv @ g.T @ J
        if k % stride == 0:
            w_steps[w_count[0]] = k
            if W.shape[0] == w_store.shape[1]:
                w_store[w_count[0]] = W
            w_count[0] += 1
        W_next = W
        if bar:
            bar[0].update(bar[1], advance=1)
