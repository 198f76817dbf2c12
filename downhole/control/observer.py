"""Output feedback: state observers from surface measurements, and the controller wrapper that
lets a full-state controller (EID, DHP) run on them.

A rig measures the surface at a high rate - top-drive speed and torque, hook load, block position
and velocity - and the downhole only at a low rate, late, if at all. EID needs the bit velocities
and DHP the whole 24-state FEM state. This module estimates them from the surface signals with
Kalman filters designed on the controllers' own linear design models, with the bit forces (WOB,
TOB) as random-walk disturbance states:

:class:`KalmanObserver`
    The steady-state (stationary-gain) discrete Kalman filter of ``x+ = A x + B u + w``,
    ``y = C x + v``, predictor-corrector form; the gain from the discrete algebraic Riccati
    equation. The estimation error obeys ``e+ = (I - K C) A e`` (noise aside):
    :meth:`KalmanObserver.error_matrix` and :meth:`KalmanObserver.spectral_radius`.
:func:`fem_surface_observer`
    That filter on the ZOH-discretized directional FEM (the DHP design model,
    :meth:`~downhole.string.fem.DirectionalModel.linear_model` and
    :meth:`~downhole.string.fem.DirectionalModel.nodal_force_map`, both through
    :func:`downhole.string.zoh.zoh`) augmented with WOB and TOB, measuring the block position,
    the top-drive angle and the two top-drive velocities.
:class:`NeutralSurfaceObserver`
    The neutral-type string of seed Ch. 3 (the EID design model, Eq. 3.13) is a lossless
    delay line between the massless top and the bit: the surface sees the bit a one-way delay
    ``tau`` late. Inverting the top boundary gives the upward wave arriving at the top, hence
    the bit velocity at ``t - tau`` (d'Alembert); a 2-state Kalman filter (bit velocity, bit
    force as a random walk) runs on that delayed time axis and the bit model, driven by the
    downward waves already on their way (known from the past surface signals), predicts the
    estimate forward to ``t``. For a linear model with a measurement delay this delayed filter
    plus open-loop prediction is the optimal (Kalman) estimate: no measurement says anything
    about the process noise of the last ``tau``.
:class:`SurfaceFeedback`
    A :class:`~downhole.control.base.Controller` that declares only surface signals in
    ``needs``, runs an observer on them and feeds the estimates to an inner full-state
    controller (:func:`eid_from_surface`, :func:`dhp_from_surface`).
:class:`MeasurementNoise`
    Adds seeded white noise to named observation signals before a controller sees them (the
    sensors of the experiments).

The EID/DHP claims measured with these observers are in docs/observer.md
(``downhole reproduce observer-surface``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
from numba import njit

from downhole.control.base import Controller
from downhole.errors import DownholeInputError
from downhole.string.zoh import zoh

__all__ = [
    "DEFAULT_SURFACE_NOISE",
    "FEM_MEASUREMENTS",
    "NEUTRAL_MEASUREMENTS",
    "KalmanObserver",
    "MeasurementNoise",
    "NeutralSurfaceObserver",
    "SurfaceFeedback",
    "bit_law_jacobian",
    "dhp_from_surface",
    "eid_from_surface",
    "fem_surface_observer",
    "steady_state_gain",
]

#: Surface signals the FEM observer reads (the block position is integrated from the block
#: velocity inside :class:`SurfaceFeedback` when the plant does not report it).
FEM_MEASUREMENTS = ("top_drive_axial_velocity", "top_drive_angular_velocity", "top_drive_angle")
#: Surface signals the neutral-string observer reads.
NEUTRAL_MEASUREMENTS = ("top_drive_axial_velocity", "top_drive_angular_velocity", "hook_load",
                        "surface_torque")

#: White sensor noise (standard deviation per 1 kHz sample) used by the experiments: block
#: velocity 1 mm/s, top-drive speed 0.1 rad/s (~1 rpm), hook load 10 kN (~1 % of the string
#: weight), surface torque 200 N m, top-drive angle 1 mrad (encoder).
DEFAULT_SURFACE_NOISE = {"top_drive_axial_velocity": 1e-3, "top_drive_angular_velocity": 0.1,
                         "hook_load": 1e4, "surface_torque": 200.0, "top_drive_angle": 1e-3}


def _matrix(name, value, shape=None):
    a = np.asarray(value, dtype=float)
    if a.ndim == 1 and shape is not None and len(shape) == 2 and shape[1] == 1:
        a = a[:, None]
    if shape is not None and (a.ndim != len(shape) or any(
            s is not None and s != d for s, d in zip(shape, a.shape, strict=False))):
        raise DownholeInputError(f"observer: {name} must have shape "
                                 f"{tuple('n' if s is None else s for s in shape)}, got "
                                 f"{a.shape}")
    if not np.all(np.isfinite(a)):
        raise DownholeInputError(f"observer: {name} has non-finite entries")
    return a


def _positive(name, value) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise DownholeInputError(f"observer: {name} must be a number, got {value!r}") from None
    if not (math.isfinite(x) and x > 0):
        raise DownholeInputError(f"observer: {name} must be a positive finite number, got "
                                 f"{value!r}")
    return x


def _surface_noise(who: str, noise) -> dict:
    """:data:`DEFAULT_SURFACE_NOISE` with the entries of ``noise`` (validated, positive) put in;
    an unknown key is a :class:`DownholeInputError` naming ``who``."""
    sig = dict(DEFAULT_SURFACE_NOISE)
    for k, v in dict(noise or {}).items():
        if k not in sig:
            raise DownholeInputError(f"{who}: unknown noise key {k!r}; expected {sorted(sig)}")
        sig[k] = _positive(f"noise.{k}", v)
    return sig


def bit_law_jacobian(bit, v: float, omega: float) -> np.ndarray:
    """Jacobian ``[[dWOB/dv, dWOB/domega], [dTOB/dv, dTOB/domega]]`` of the bit law with the
    approximated depth of cut (d = 2 pi v / omega) at ``(v, omega)`` (central differences).

    The surface observers put it into their models as a linear damper at the bit: the bit
    forces react within milliseconds to the bit velocities (``dWOB/dv`` is ~5 times the
    axial line impedance), which a random walk cannot follow; the random-walk states then
    carry only the rest (``WOB - J v``)."""
    from downhole.bit.law import approx_depth_of_cut, bit_forces

    v, omega = float(v), float(omega)
    if not (math.isfinite(v) and math.isfinite(omega) and v > 0 and omega > 0):
        raise DownholeInputError(f"observer: the operating point must have a positive bit "
                                 f"velocity and angular velocity, got v = {v!r} m/s, omega = "
                                 f"{omega!r} rad/s")
    p = bit.kernel_params()

    def f(vv, ww):
        return np.array(bit_forces(approx_depth_of_cut(vv, ww, p), vv, ww, p))

    hv, hw = 1e-4 * v, 1e-4 * omega
    return np.column_stack([(f(v + hv, omega) - f(v - hv, omega)) / (2 * hv),
                            (f(v, omega + hw) - f(v, omega - hw)) / (2 * hw)])


def steady_state_gain(A, C, Q, R):
    """Stationary Kalman filter gain of ``x+ = A x + w``, ``y = C x + v``.

    Parameters
    ----------
    A : array_like (n, n)
    C : array_like (p, n)
    Q : array_like (n, n)
        Process noise covariance (symmetric, >= 0).
    R : array_like (p, p)
        Measurement noise covariance (symmetric, > 0).

    Returns
    -------
    K : ndarray (n, p)
        Measurement-update gain: ``x = x^- + K (y - C x^-)``.
    P : ndarray (n, n)
        Stationary a-priori error covariance (the DARE solution).

    Raises
    ------
    DownholeInputError
        Shapes that do not match, non-finite entries, R not positive definite, or no stabilizing
        solution ((A, C) not detectable: a mode the measurements cannot see).
    """
    from scipy.linalg import solve_discrete_are

    A = _matrix("A", A)
    n = A.shape[0]
    if A.ndim != 2 or A.shape != (n, n):
        raise DownholeInputError(f"observer: A must be square, got {A.shape}")
    C = _matrix("C", C, (None, n))
    p = C.shape[0]
    Q = _matrix("Q", Q, (n, n))
    R = _matrix("R", R, (p, p))
    if np.linalg.eigvalsh(0.5 * (R + R.T)).min() <= 0:
        raise DownholeInputError("observer: the measurement noise covariance R must be positive "
                                 "definite (every measurement needs a noise level > 0)")
    try:
        P = solve_discrete_are(A.T, C.T, Q, R)
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise DownholeInputError(f"observer: no stationary Kalman filter ({exc}); is every mode "
                                 "of the model seen by the measurements (detectable)?") from None
    S = C @ P @ C.T + R
    K = np.linalg.solve(S.T, (P @ C.T).T).T
    return K, P


class KalmanObserver:
    """Stationary-gain discrete Kalman filter ``x+ = A x + B u + w``, ``y = C x + v``.

    Each :meth:`update` takes the input held over the last step and the measurement now:
    ``x^- = A x + B u`` (predict), then ``x = x^- + K (y - C x^-)`` (correct).

    Parameters
    ----------
    A, B, C : array_like
        (n, n), (n, m), (p, n).
    Q, R : array_like
        Process (n, n) and measurement (p, p) noise covariances.
    state_names, output_names : sequence of str, optional
        Labels (for the wrapper and messages).

    Raises
    ------
    DownholeInputError
        See :func:`steady_state_gain`.
    """

    def __init__(self, A, B, C, Q, R, state_names=None, output_names=None):
        self.A = _matrix("A", A)
        n = self.A.shape[0]
        self.B = _matrix("B", B, (n, None))
        self.C = _matrix("C", C, (None, n))
        self.K, self.P = steady_state_gain(self.A, self.C, Q, R)
        self.Q = np.asarray(Q, float)
        self.R = np.asarray(R, float)
        self.state_names = tuple(state_names or (f"x{i}" for i in range(n)))
        self.output_names = tuple(output_names or (f"y{i}" for i in range(self.C.shape[0])))
        if len(self.state_names) != n or len(self.output_names) != self.C.shape[0]:
            raise DownholeInputError("observer: state_names / output_names do not match the "
                                     "model's sizes")
        # one matrix per update: x = (I - K C) (A x + B u) + K y
        IKC = np.eye(n) - self.K @ self.C
        self._IKC = IKC
        self._F = IKC @ self.A
        self._G = IKC @ self.B
        self._M = np.hstack([self._F, self._G, self.K])   # one product per update
        self._xuy = np.zeros(self._M.shape[1])
        #: optional known nonlinear increment h(x) added to the prediction (see :meth:`update`)
        self.nonlinear = None
        self.reset()

    @property
    def n_states(self) -> int:
        return self.A.shape[0]

    def error_matrix(self) -> np.ndarray:
        """``(I - K C) A``: the estimation error's transition matrix (noise-free)."""
        return self._F.copy()

    def spectral_radius(self) -> float:
        """Largest |eigenvalue| of :meth:`error_matrix` (< 1: the error converges)."""
        return float(np.max(np.abs(np.linalg.eigvals(self._F))))

    def reset(self, x0=None) -> None:
        """Start from ``x0`` (default zeros)."""
        self.x = (np.zeros(self.n_states) if x0 is None
                  else _matrix("x0", x0, (self.n_states,)).copy())

    def update(self, y, u) -> np.ndarray:
        """Predict with the input ``u`` held over the last step, correct with ``y``; returns the
        estimate (a view, do not modify). With :attr:`nonlinear` set, the prediction is
        ``A x + B u + nonlinear(x)`` (the gain stays the linear model's)."""
        n, m = self.n_states, self.B.shape[1]
        v = self._xuy
        v[:n] = self.x
        v[n:n + m] = u
        v[n + m:] = y
        x = self._M @ v
        if self.nonlinear is not None:
            x += self._IKC @ self.nonlinear(self.x)
        self.x = x
        return self.x

    def predict(self, u) -> np.ndarray:
        """Predict only (no measurement this step)."""
        x = self.A @ self.x + self.B @ u
        if self.nonlinear is not None:
            x += self.nonlinear(self.x)
        self.x = x
        return self.x


# ------------------------------------------------------------------------------------- FEM
def fem_surface_observer(dmodel, dt: float, *, noise: Mapping[str, float] | None = None,
                         wob_rate: float = 2e4, tob_rate: float = 2e3,
                         state_noise: float = 0.1, top_drive_inertia: float | None = None,
                         block_position_noise: float = 1e-3,
                         operating_point=(0.01, 20.0), design=None) -> KalmanObserver:
    """Kalman filter on the DHP design FEM with the bit forces as random-walk states.

    State: the FEM's (``x_i, alpha_i`` then ``v_i, omega_i``, deviations from the hanging
    equilibrium, :meth:`~downhole.string.fem.DirectionalModel.continuous_linear_model`) plus
    the bit forces' random-walk parts ``wob - J v_bit`` (N) and ``tob - J omega_bit`` (N m),
    which act on the bit node through the ZOH nodal force map, where ``J`` is
    :func:`bit_law_jacobian` at ``operating_point`` (its axial slope only: a damper at the bit
    in the model). Inputs: ``slack_off_force`` (N), ``surface_torque`` (N m). Outputs: the top
    node's axial position (block position), angle (top-drive angle), axial velocity and
    angular velocity. With ``design`` (the DHP design model of ``dmodel``), the prediction also
    adds the wellbore friction forces of that model at the estimated state (its soft-string
    friction with the design regularization); without it the filter lumps the friction into
    the bit forces, which puts the string's twist in the wrong place (docs/observer.md).

    Parameters
    ----------
    dmodel : DirectionalModel
        The FEM (a hybrid: its ``design_model()``).
    dt : float
        Step, s.
    noise : mapping, optional
        Measurement noise standard deviations per sample: keys of
        :data:`DEFAULT_SURFACE_NOISE` (``top_drive_axial_velocity``,
        ``top_drive_angular_velocity``, ``top_drive_angle``); defaults from there.
    wob_rate, tob_rate : float
        Random-walk intensities of WOB (N/sqrt(s)) and TOB (N m/sqrt(s)): how fast the filter
        lets the bit forces move.
    state_noise : float
        Process noise on the velocities (m/s or rad/s per sqrt(s)), unmodelled forces.
    top_drive_inertia : float, optional
        kg m^2 (default the rig default, as the DHP design model).
    block_position_noise : float
        Noise of the block position, m.
    operating_point : (float, float) or None
        Bit velocities (m/s, rad/s) where the bit law is linearized; None: no bit damper (the
        random walks carry the whole bit forces).
    design : ControlAffineModel, optional
        From :func:`~downhole.control.dhp.directional.directional_affine_model` of ``dmodel``:
        its ``forces`` give the friction term of the prediction.

    Returns
    -------
    KalmanObserver
        ``state_names`` = the FEM's + ``("wob_rest", "tob_rest")``; the attribute
        ``bit_jacobian`` (2, 2) gives the bit forces back, ``[wob, tob] = rest + J [v,
        omega]``; ``output_names`` = ``("block_position", "top_drive_angle",
        "top_drive_axial_velocity", "top_drive_angular_velocity")``.
    """
    from downhole.params.rig import DEFAULT_TOP_DRIVE_INERTIA

    dt = _positive("dt", dt)
    J = DEFAULT_TOP_DRIVE_INERTIA if top_drive_inertia is None else top_drive_inertia
    m = dmodel.design_model()
    n = m.n_nodes
    Ac, Bc, names, Minv = dmodel.continuous_linear_model(J)
    ns = Ac.shape[0]
    ib = n - 1
    jb = [2 * ib, 2 * ib + 1]
    Jb = np.zeros((2, 2))
    if operating_point is not None:
        # the axial damper only: the torsional slope of the approximated law is negative
        # (-TOB/omega) and the cross terms couple the fields through a velocity-weakening
        # bit; in the model they turn the error dynamics of the stick phase unstable
        Jb[0, 0] = bit_law_jacobian(m.bit, *operating_point)[0, 0]
    Ac = Ac.copy()
    # bit forces -(rest + Jb [v_b, w_b]) on the bit DOFs: the damper part into A
    Ac[2 * n:, [2 * n + j for j in jb]] -= Minv[:, jb] @ Jb
    act = np.zeros(0, dtype=int)
    if design is not None and getattr(design, "forces", None) is not None:
        act = np.asarray(design.metadata.get("force_nodes", []), dtype=int)
        if design.n_states != ns or ib not in act:
            raise DownholeInputError(f"fem_surface_observer: design model {design.name!r} does "
                                     f"not belong to this FEM ({design.n_states} states, "
                                     f"expected {ns} with force nodes including the bit)")
    cols = np.ravel(np.column_stack([2 * act, 2 * act + 1])).astype(int)
    Mf = np.vstack([np.zeros((2 * n, 2 + cols.size)), Minv[:, jb + cols.tolist()]])
    A_d, BG = zoh(Ac, np.hstack([Bc, Mf]), dt)
    B_d, Gbit, Gact = BG[:, :2], -BG[:, 2:4], BG[:, 4:]
    A = np.block([[A_d, Gbit], [np.zeros((2, ns)), np.eye(2)]])
    B = np.vstack([B_d, np.zeros((2, 2))])
    C = np.zeros((4, ns + 2))
    C[0, 0] = 1.0                 # x_1: block position
    C[1, 1] = 1.0                 # alpha_1: top-drive angle
    C[2, 2 * n] = 1.0             # v_1
    C[3, 2 * n + 1] = 1.0         # omega_1
    sig = _surface_noise("fem_surface_observer", noise)
    R = np.diag([_positive("block_position_noise", block_position_noise),
                 sig["top_drive_angle"], sig["top_drive_axial_velocity"],
                 sig["top_drive_angular_velocity"]]) ** 2
    q = np.zeros(ns + 2)
    q[2 * n:ns] = _positive("state_noise", state_noise) ** 2 * dt
    q[ns] = _positive("wob_rate", wob_rate) ** 2 * dt
    q[ns + 1] = _positive("tob_rate", tob_rate) ** 2 * dt
    kf = KalmanObserver(A, B, C, np.diag(q), R, state_names=(*names, "wob_rest", "tob_rest"),
                        output_names=("block_position", "top_drive_angle",
                                      "top_drive_axial_velocity", "top_drive_angular_velocity"))
    kf.bit_jacobian = Jb
    kf.bit_indices = (2 * n + jb[0], 2 * n + jb[1])
    if act.size:
        kf.nonlinear = _friction_term(design, Gact, int(np.nonzero(act == ib)[0][0]), ns)
    return kf


def _friction_term(design, Gact, slot, ns):
    """``h(x)``: the ZOH increment of the design model's wellbore friction at the state ``x``
    (its forces less its bit law, which the filter replaces by the bit-force states)."""
    from downhole.bit.law import approx_depth_of_cut, bit_forces

    P = np.asarray(design.state_scale, float)
    bitp = design.bit.kernel_params()
    iv, iw = 2 * (ns // 4) + 2 * (ns // 4 - 1), 2 * (ns // 4) + 2 * (ns // 4 - 1) + 1
    out = np.zeros(ns + 2)

    def h(x):
        z = x[:ns]
        f = np.asarray(design.forces((z / P)[None, :]), float)[0]
        va, vt = z[iv], z[iw]
        wob, tob = bit_forces(approx_depth_of_cut(va, vt, bitp), va, vt, bitp)
        f[2 * slot] += wob           # the kernel's bit column is -wob - friction: keep friction
        f[2 * slot + 1] += tob
        out[:ns] = Gact @ f
        return out

    return h


# --------------------------------------------------------------------------------- neutral
def _line(a0, bd, g1):
    """Line impedance Z (Gamma2 = Z/m = -a0, 1/m = bd) and top damper alpha (Gamma1 = g1 =
    (alpha - Z)/(alpha + Z)) of one field of the design model."""
    Z = -a0 / bd
    return Z, Z * (1.0 + g1) / (1.0 - g1)


class _Channel:
    """One field of the neutral observer (see :class:`NeutralSurfaceObserver`)."""

    def __init__(self, a0, bd, g1, tau, dt, c_top, r_meas, q_v, q_f, slope):
        self.Z, self.alpha = _line(a0, bd, g1)
        self.g1 = g1
        self.c_top = c_top
        self.dt = dt
        self.slope = slope
        # bit: v' = a0 (v - 2 a_in) - bd c v + bd F, F random walk (F = gravity - (WOB - c v),
        # or -(TOB - c omega)), c the bit law's slope at the operating point
        Ac = np.array([[a0 - bd * slope, bd], [0.0, 0.0]])
        Bc = np.array([[-2.0 * a0], [0.0]])
        self.Phi, self.Gam = zoh(Ac, Bc, dt)
        D = tau / dt
        self.n1 = math.floor(D)
        self.f1 = D - self.n1
        self.Phi_f, self.Gam_f = zoh(Ac, Bc, self.f1 * dt) if self.f1 > 1e-12 else (
            np.eye(2), np.zeros((2, 1)))
        # prediction over tau: s(t) = P s(t - tau) + W @ a_seq (+ fractional step)
        N = self.n1
        W = np.empty((2, N))
        M = self.Gam[:, 0].copy()
        Pn = np.eye(2)
        for j in range(N - 1, -1, -1):      # a_seq[j] enters with Phi^(N-1-j)
            W[:, j] = M
            M = self.Phi @ M
        for _ in range(N):
            Pn = self.Phi @ Pn
        self.PN, self.W = Pn, W
        Q = np.diag([q_v * dt, q_f * dt])
        self.kf = KalmanObserver(self.Phi, self.Gam, np.array([[1.0, 0.0]]), Q,
                                 np.array([[r_meas]]), state_names=("v", "F"),
                                 output_names=("v_delayed",))
        # ring buffer of the downward waves leaving the top
        self.cap = math.ceil(2 * D) + 8
        self.D = D

    def reset(self, a_top0, v0, f0):
        self.buf = np.full(self.cap, a_top0)
        self.k = 0
        self.kf.reset([v0, f0])

    def step(self, v_top, u_rel):
        """One sample: the top velocity (fused measurement) and the command that produced it.
        Returns (v_bit(t), F(t))."""
        self.k += 1
        return _channel_step(self.buf, self.k, self.kf.x, self.kf._F, self.kf._G[:, 0],
                             self.kf.K[:, 0], self.PN, self.W, self.Phi_f, self.Gam_f[:, 0],
                             self.Z, self.alpha, self.c_top, self.D, self.f1, v_top, u_rel)


@njit(cache=True)
def _wave_at(buf, k, lag):
    """The sample ``lag`` steps (fractional: linear interpolation) before sample ``k``."""
    cap = buf.shape[0]
    i = int(math.floor(lag))
    fr = lag - i
    j = (k - i) % cap
    return (1.0 - fr) * buf[j] + fr * buf[(j - 1) % cap]


@njit(cache=True)
def _channel_step(buf, k, x, F, G, K, PN, W, Phi_f, Gam_f, Z, alpha, c_top, D, f1, v_top,
                  u_rel):
    """One sample of one field of :class:`NeutralSurfaceObserver` (sample ``k``): store the
    downward wave leaving the top, update the delayed filter state ``x`` (in place) and return
    the prediction ``(v, F)`` at the current time."""
    cap = buf.shape[0]
    b_in = ((Z + alpha) * v_top - alpha * u_rel + c_top) / (2.0 * Z)
    # delayed filter at t - tau: input a_in_bit over the last step (trapezoid), measurement
    # v(t - tau) = b_in(t) + a_in_bit(t - tau) = b_in(t) + a_top(t - 2 tau)
    a_now = _wave_at(buf, k, 2.0 * D)
    a_prev = _wave_at(buf, k, 2.0 * D + 1.0)
    u = 0.5 * (a_now + a_prev)
    y = b_in + a_now
    x0 = F[0, 0] * x[0] + F[0, 1] * x[1] + G[0] * u + K[0] * y
    x1 = F[1, 0] * x[0] + F[1, 1] * x[1] + G[1] * u + K[1] * y
    x[0] = x0
    x[1] = x1
    # the downward wave leaving the top now, from the filtered upward wave b = v(t - tau) -
    # a_in_bit(t - tau) and the known command through the top boundary (not the raw
    # measurement: its noise would enter every prediction of the next 2 tau)
    b_f = x0 - a_now
    buf[k % cap] = (2.0 * Z * b_f + alpha * u_rel - c_top) / (Z + alpha) - b_f
    # prediction over [t - tau, t]: a_in_bit there = a_top over [t - 2 tau, t - tau]
    n1 = W.shape[1]
    p0 = PN[0, 0] * x0 + PN[0, 1] * x1
    p1 = PN[1, 0] * x0 + PN[1, 1] * x1
    prev = a_now
    for j in range(n1):
        cur = _wave_at(buf, k, 2.0 * D - j - 1.0)
        a = 0.5 * (prev + cur)
        p0 += W[0, j] * a
        p1 += W[1, j] * a
        prev = cur
    if f1 > 1e-12:
        q0 = Phi_f[0, 0] * p0 + Phi_f[0, 1] * p1 + Gam_f[0] * prev
        q1 = Phi_f[1, 0] * p0 + Phi_f[1, 1] * p1 + Gam_f[1] * prev
        p0, p1 = q0, q1
    return p0, p1


class NeutralSurfaceObserver:
    """Bit velocities and forces of the neutral-type string from the surface signals.

    Built from the EID design model (:meth:`~downhole.string.neutral.NeutralModel.ndde`,
    Eq. 3.13): per field, ``a0 = -Z/m``, ``g1 = (alpha - Z)/(alpha + Z)`` and ``bd = 1/m`` give
    the line impedance ``Z``, the top damper ``alpha`` and the bit mass; the surface-force
    offsets (string and bit weight) come from the model's parameters. Per sample, each field:

    1. fuse the two surface measurements of the top node's velocity (the top-drive velocity,
       and the one implied by the hook load or the surface torque through the top damper,
       weighted by their noise variances);
    2. invert the top boundary for the upward wave arriving at the top, ``b_in(t)``, and the
       downward wave leaving it, ``a_top(t)`` (:mod:`downhole.sim.wave` conventions);
    3. a 2-state Kalman filter (bit velocity; bit force ``F`` = bit weight - WOB, or -TOB, a
       random walk) at time ``t - tau`` measures ``v(t - tau) = b_in(t) + a_top(t - 2 tau)``
       with the line's downward wave ``a_top(t - 2 tau)`` as its input;
    4. predict to ``t`` with the bit model driven by ``a_top`` over ``[t - 2 tau, t - tau]``
       (the waves on their way down, already measured).

    Parameters
    ----------
    model : NeutralModel
    dt : float
        Sample time, s (<= the axial delay).
    noise : mapping, optional
        Sensor standard deviations per sample (keys of :data:`DEFAULT_SURFACE_NOISE`).
    force_rate : (float, float)
        Random-walk intensities of the bit forces (N/sqrt(s), N m/sqrt(s)).
    velocity_rate : (float, float)
        Process noise on the bit velocities (m/s, rad/s per sqrt(s)).
    operating_point : (float, float) or None
        Bit velocities where the bit law's slopes ``dWOB/dv``, ``dTOB/domega``
        (:func:`bit_law_jacobian`) are taken into the bit model as dampers (None: none).
    """

    signals = ("bit_axial_velocity", "bit_angular_velocity", "wob", "tob")

    def __init__(self, model, dt: float, *, noise: Mapping[str, float] | None = None,
                 force_rate=(2e5, 2e3), velocity_rate=(1e-3, 0.1),
                 operating_point=(0.01, 20.0)):
        self.model = model
        self.dt = _positive("dt", dt)
        if self.dt > model.tau1:
            raise DownholeInputError(f"NeutralSurfaceObserver: dt = {dt} s exceeds the axial "
                                     f"wave delay {model.tau1:.6g} s")
        sig = _surface_noise("NeutralSurfaceObserver", noise)
        self.noise = sig
        nd = model.ndde()
        p = model.params
        self.weights = []
        self.channels = []
        alphas = (p.alpha_axial, p.alpha_torsional)
        vel_keys = ("top_drive_axial_velocity", "top_drive_angular_velocity")
        force_keys = ("hook_load", "surface_torque")
        c_tops = (p.bit_mass * p.g, 0.0)
        Jb = (np.zeros((2, 2)) if operating_point is None
              else bit_law_jacobian(model.bit, *operating_point))
        for i in range(2):
            ch = nd.channel(i)
            bd = float(nd.Bd[i, i])
            # fused top-velocity measurement: inverse-variance weights
            var_v = sig[vel_keys[i]] ** 2
            var_f = (sig[force_keys[i]] / alphas[i]) ** 2
            wv = var_f / (var_v + var_f)
            var = var_v * var_f / (var_v + var_f)
            self.weights.append(wv)
            # noise of the delayed bit-velocity measurement b_in(t) + a_top(t - 2 tau)
            Z, alpha = _line(ch["a0"], bd, ch["g1"])
            gain = (Z + alpha) / (2.0 * Z)
            r = var * gain ** 2 * (1.0 + ch["g1"] ** 2)
            c = _Channel(ch["a0"], bd, ch["g1"], ch["tau"], self.dt, c_tops[i], r,
                         _positive("velocity_rate", velocity_rate[i]) ** 2,
                         _positive("force_rate", force_rate[i]) ** 2, float(Jb[i, i]))
            self.channels.append(c)
        self._p = p
        self.reset()

    def reset(self) -> None:
        """Start from the hanging rest of the neutral plant (``start="rest"``): bit
        at rest touching the rock (zero WOB), the line carrying the bit weight (v_top = 0,
        b_in = M_B g / (2 Z), a_top = -b_in)."""
        p = self._p
        for i, c in enumerate(self.channels):
            c.reset(-c.c_top / (2.0 * c.Z), 0.0, p.bit_mass * p.g if i == 0 else 0.0)

    def update(self, observation: Mapping[str, float], command) -> dict:
        """Estimates at the time of ``observation`` (which holds :data:`NEUTRAL_MEASUREMENTS`),
        ``command`` = the plant command held over the last step, ``(top_drive_axial_velocity
        (relative to the hanging equilibrium), top_drive_angular_velocity)``."""
        p = self._p
        u_a, u_t = float(command[0]), float(command[1])
        va = observation["top_drive_axial_velocity"]
        wa = observation["top_drive_angular_velocity"]
        # hook load = alpha_A (v_top - u_rel) + (M_S + M_B) g; torque = alpha_T (U_T - w_top)
        va_f = u_a + (observation["hook_load"] - (p.string_mass + p.bit_mass) * p.g) \
            / p.alpha_axial
        wa_f = u_t - observation["surface_torque"] / p.alpha_torsional
        w0, w1 = self.weights
        v, fa = self.channels[0].step(w0 * va + (1.0 - w0) * va_f, u_a)
        w, ft = self.channels[1].step(w1 * wa + (1.0 - w1) * wa_f, u_t)
        ca, ct = self.channels[0].slope, self.channels[1].slope
        return {"bit_axial_velocity": v, "bit_angular_velocity": w,
                "wob": p.bit_mass * p.g - fa + ca * v, "tob": -ft + ct * w}

    def spectral_radius(self) -> float:
        """Largest |eigenvalue| of the delayed filters' error matrices."""
        return max(c.kf.spectral_radius() for c in self.channels)


# ---------------------------------------------------------------------------------- wrapper
class _FEMEstimator:
    """The FEM Kalman filter as an estimator of :class:`SurfaceFeedback`."""

    def __init__(self, kf: KalmanObserver, n_states: int, dt: float):
        self.kf, self.n, self.dt = kf, n_states, dt

    def reset(self):
        self.kf.reset()
        self._pos = 0.0
        self._v_prev = None

    def update(self, observation, command):
        v = float(observation["top_drive_axial_velocity"])
        if self._v_prev is not None:
            self._pos += 0.5 * self.dt * (v + self._v_prev)
        self._v_prev = v
        y = np.array([self._pos, observation["top_drive_angle"], v,
                      observation["top_drive_angular_velocity"]], float)
        x = self.kf.update(y, np.asarray(command, float))
        f = x[self.n:self.n + 2] + self.kf.bit_jacobian @ x[list(self.kf.bit_indices)]
        return {"state": x[:self.n], "wob": float(f[0]), "tob": float(f[1])}


class SurfaceFeedback(Controller):
    """A full-state controller run on the estimates of a surface observer.

    ``needs`` lists surface signals only; :meth:`command` reads them, updates the estimator
    with the command it gave the step before, and asks ``inner`` for the command on the
    estimated observation (the estimator's signals, e.g. the bit velocities or ``"state"``).

    Parameters
    ----------
    inner : Controller
        Full-state controller (``reset()``, ``command(t, obs, ref)``, ``commands``).
    estimator : object
        ``reset()`` and ``update(observation, last_command) -> dict`` (e.g.
        :class:`NeutralSurfaceObserver`).
    needs : tuple of str
        The surface signals the estimator reads.
    commands : tuple of str, optional
        Default ``inner.commands``.
    initial_command : sequence of float, optional
        The command held before t = 0 (default zeros: the hanging rest of the plants here).
    """

    label = "surface-feedback"

    def __init__(self, inner, estimator, needs, commands=None, initial_command=None):
        if not (hasattr(inner, "command") and hasattr(inner, "reset")):
            raise DownholeInputError(f"SurfaceFeedback: inner must be a controller with reset() "
                                     f"and command(); got {type(inner).__name__}")
        self.inner = inner
        self.estimator = estimator
        self.needs = tuple(needs)
        self.commands = tuple(commands if commands is not None else inner.commands)
        if not self.commands:
            raise DownholeInputError("SurfaceFeedback: the inner controller declares no "
                                     "commands; pass commands=")
        self._u0 = np.zeros(len(self.commands)) if initial_command is None else \
            _matrix("initial_command", initial_command, (len(self.commands),))
        self.label = f"{getattr(inner, 'label', type(inner).__name__)}+observer"
        self.dt = getattr(inner, "dt", None)
        self.estimate: dict = {}

    def reset(self) -> None:
        """Reset the estimator and the inner controller (which gets this wrapper's ``dt``)."""
        if self.dt is not None and hasattr(self.inner, "dt"):
            self.inner.dt = self.dt
        est_dt = getattr(self.estimator, "dt", None)
        if est_dt is not None and self.dt is not None and abs(est_dt - self.dt) > 1e-12:
            raise DownholeInputError(f"SurfaceFeedback: the observer was designed for a "
                                     f"sample time of {est_dt} s but runs every {self.dt} s")
        self.estimator.reset()
        self.inner.reset()
        self._u = self._u0.copy()
        self.estimate = {}

    def command(self, t: float, observation: Mapping[str, float], reference=None) -> dict:
        """The inner controller's command on the estimate from ``observation`` (surface
        signals)."""
        if not hasattr(self, "_u"):
            self.reset()
        for name in self.needs:
            if name not in observation:
                raise DownholeInputError(f"SurfaceFeedback: observation lacks {name!r}; it needs "
                                         f"{self.needs}")
            try:
                value = float(observation[name])
            except (TypeError, ValueError):
                value = math.nan
            if not math.isfinite(value):
                raise DownholeInputError(f"SurfaceFeedback: observation {name!r} is not a finite "
                                         f"number ({observation[name]!r})")
        est = self.estimator.update(observation, self._u)
        self.estimate = est
        cmd = self.inner.command(t, est, reference)
        self._u = np.array([float(cmd[c]) for c in self.commands])
        return {c: float(cmd[c]) for c in self.commands}


class MeasurementNoise(Controller):
    """Adds seeded white noise (standard deviation per call) to named observation signals
    before ``inner`` sees them; everything else passes through.

    Parameters
    ----------
    inner : Controller
    sigmas : mapping of str to float
        Signal name -> standard deviation (its SI unit), >= 0.
    seed : int
    """

    def __init__(self, inner, sigmas: Mapping[str, float], seed: int = 0):
        self.inner = inner
        self.sigmas = {}
        for k, v in dict(sigmas).items():
            try:
                s = float(v)
            except (TypeError, ValueError):
                raise DownholeInputError(f"MeasurementNoise: sigma of {k!r} must be a number, "
                                         f"got {v!r}") from None
            if not (math.isfinite(s) and s >= 0):
                raise DownholeInputError(f"MeasurementNoise: sigma of {k!r} must be >= 0 and "
                                         f"finite, got {v!r}")
            self.sigmas[k] = s
        self.seed = int(seed)
        self.needs = tuple(getattr(inner, "needs", ()))
        self.commands = tuple(getattr(inner, "commands", ()))
        self.label = getattr(inner, "label", type(inner).__name__)
        self.dt = getattr(inner, "dt", None)

    def reset(self) -> None:
        if self.dt is not None and hasattr(self.inner, "dt"):
            self.inner.dt = self.dt
        self._rng = np.random.default_rng(self.seed)
        self._names = list(self.sigmas)
        self._s = np.array([self.sigmas[n] for n in self._names])
        self.inner.reset()

    def command(self, t, observation, reference=None) -> dict:
        if not hasattr(self, "_rng"):
            self.reset()
        obs = dict(observation)
        e = self._rng.standard_normal(len(self._names)) * self._s
        for name, x in zip(self._names, e, strict=True):
            if name in obs:
                obs[name] = float(obs[name]) + float(x)
        return self.inner.command(t, obs, reference)


# --------------------------------------------------------------------------- constructors
def eid_from_surface(eid, model, dt: float = 1e-3, **observer_options) -> SurfaceFeedback:
    """The EID controller on the neutral string, from surface measurements only.

    Parameters
    ----------
    eid : EIDController
    model : NeutralModel
        The plant's design model (the one ``eid`` was designed on).
    dt : float
        Sample time of observer and EID, s.
    **observer_options
        Passed to :class:`NeutralSurfaceObserver` (``noise``, ``force_rate``, ...).
    """
    import copy

    inner = copy.copy(eid)          # the caller's controller keeps its own sample time
    inner.dt = float(dt)
    obs = NeutralSurfaceObserver(model, dt, **observer_options)
    return SurfaceFeedback(inner, obs, NEUTRAL_MEASUREMENTS,
                           commands=("top_drive_axial_velocity", "top_drive_angular_velocity"))


class _DHPState:
    """Adapter: a DHP controller's ``commands`` and reference for :class:`SurfaceFeedback`."""

    def __init__(self, dhp):
        self.dhp = dhp
        self.commands = tuple(dhp.input_names)
        self.dt = dhp.dt
        self.label = "dhp"

    def reset(self):
        self.dhp.reset()

    def command(self, t, observation, reference=None):
        return self.dhp.command(t, {"state": observation["state"]}, reference)


def dhp_from_surface(dhp, dmodel, design=None, **observer_options) -> SurfaceFeedback:
    """A DHP controller on the directional FEM, from surface measurements only.

    Parameters
    ----------
    dhp : DHPController
        Trained on the design model of ``dmodel`` (24-state FEM of Ch. 4).
    dmodel : DirectionalModel
        The design FEM (its linear model is the observer's).
    design : ControlAffineModel, optional
        The DHP design model of ``dmodel``: its wellbore friction enters the observer's
        prediction (see :func:`fem_surface_observer`).
    **observer_options
        Passed to :func:`fem_surface_observer`.
    """
    kf = fem_surface_observer(dmodel, dhp.dt, design=design, **observer_options)
    n = dmodel.design_model().n_states
    if n != int((dhp._integral or {}).get("n_base", dhp.n_states)):
        raise DownholeInputError(f"dhp_from_surface: the controller has {dhp.n_states} states, "
                                 f"the FEM {n}")
    est = _FEMEstimator(kf, n, dhp.dt)
    est.dt = dhp.dt
    return SurfaceFeedback(_DHPState(dhp), est, FEM_MEASUREMENTS)
