"""EID with a predictive bit damper: finite-spectrum-assignment style damping of the regenerative
bit/rock mode through the axial wave delay.

At low rotary speed the bit/rock mode with the delayed depth of cut is unstable in open loop
(:func:`~downhole.control.eid.stability.bit_rock_open_loop_roots`) and no EID tuning stabilizes it:
the top drive acts on the bit only after the axial wave delay tau1 (0.19 s with Table 3.1), which
is 7-8 rad at the mode's 38-45 rad/s. The string delay is, however, a *known* dynamics: over the
next tau1 the bit moves under the waves already travelling down the string (past commands) and the
bit/rock law, so the bit velocity at t + tau1 can be predicted at t. The damper adds to the EID's
axial command

    du(t) = -k_d (vhat(t + tau1 | t) - r_a(t))

which reaches the bit at t + tau1 as the force -M b k_d (v(t + tau1) - r_a): with an exact
prediction a damper of M b k_d N s/m at the bit (b = Gamma3 of Eq. 3.9), i.e. the delay has
gone from the loop (finite spectrum assignment). The prediction integrates the axial neutral
equation of Eq. 3.9 with the bit law,

    v' = a0 v + a1 v(t-h) + g1 v'(t-h) + b u(t - tau1) - (W(t) - g1 W(t-h)) / M_B,
    W(t) = WOB(n (X(t) - X(t - 2 pi/(n omega))), v, omega)

from the measured bit velocity (X its integral) over one tau1, with the stored histories of v, v'
and W and of the commands u (the EID's plus the damper's). The EID itself is unaware of du (its
estimator sees its effect as part of the disturbance and compensates only the part below its
filter bandwidth).

Options (all off by default): ``angle_doc`` looks the depth of cut of the prediction up by the
measured bit angle (Eq. 2.10) instead of the time delay 2 pi/(n omega) at the current speed, which
errs by d/omega per rad/s of speed deviation; ``axial_filter`` low-pass filters du (at k_d = 4 the
discretized prediction loop chatters near the Nyquist frequency without it); ``depth_of_cut_gain``
k_c scales the axial reference with the measured rotary speed, r_a (1 + k_c (omega/r_w - 1)), so
that a slowing bit is not asked to cut deeper (at a given ROP the torque on bit grows as 1/omega,
a negative damping that at 5 rad/s and 17-20 mm/s exceeds the string's).

Linear check: :func:`predictive_closed_loop` is :func:`~downhole.control.eid.stability.
regenerative_closed_loop` for this loop with an exact prediction (the plant row gains b k_d).
The controller runs compiled in :func:`~downhole.sim.simulate` (its
``neutral_runner``) or from Python; both call :func:`damper_step`.
"""

from __future__ import annotations

import math

import numpy as np

from downhole.control.eid.damper import (
    PREDICTION_STEP,
    DamperParams,
    _stride,
    coupled_axial_reference,
    damper_arrays,
    damper_step,
)
from downhole.errors import DownholeInputError

__all__ = [
    "DamperParams",
    "PredictiveEID",
    "damper_step",
    "predictive_closed_loop",
]


class PredictiveEID:
    """An :class:`~downhole.control.eid.controller.EIDController` plus the predictive bit damper
    on the axial channel (module docstring). Same controller contract (``reset``, ``command``,
    ``dt``, ``needs``, ``commands``); runs compiled in ``simulate`` through
    :meth:`kernel_runner` (the EID loop of :mod:`downhole.control.eid.neutral_runner` with
    the damper), or from Python.

    Parameters
    ----------
    eid : EIDController
    model : NeutralModel
        The plant model the prediction uses (string coefficients, bit mass, bit law).
    damping_gain : float
        k_d (the bit sees M_B b k_d N s/m; 2.0 gives about 8.8e5 N s/m = 2.5 Z with Table 3.1).
    depth_of_cut_gain : float
        k_c of the depth-of-cut coupling in [0, 2] (0: off): the axial reference, of the EID
        and of the damper, becomes ``r_a (1 + k_c (omega / r_w - 1))`` with the measured bit
        angular velocity (:func:`~downhole.control.eid.damper.coupled_axial_reference`; 1:
        constant depth of cut while the bit speed deviates). It removes the negative damping
        -T/omega that a rate-of-penetration set point gives the torsional mode at low rotary
        speed; the steady state is unchanged. Use it with ``angle_doc``: with the time-delay
        prediction the coupled loop grows at ~0.4 1/s in simulation although linearly stable.
    angle_doc : bool
        Depth of cut of the prediction from the measured bit angle (see :class:`DamperParams`).
    axial_filter : float
        Bandwidth (rad/s) of a low-pass filter on the axial damping command (0: none).
    """

    needs = ("bit_axial_velocity", "bit_angular_velocity")
    commands = ("top_drive_axial_velocity", "top_drive_angular_velocity")
    label = "eid+predictive-damper"

    def __init__(self, eid, model, damping_gain: float = 2.0, *, depth_of_cut_gain: float = 0.0,
                 angle_doc: bool = False, axial_filter: float = 0.0):
        gains = []
        for name, val in (("damping_gain", damping_gain),
                          ("depth_of_cut_gain", depth_of_cut_gain),
                          ("axial_filter", axial_filter)):
            k = float(val)
            if not (math.isfinite(k) and k >= 0):
                raise DownholeInputError(f"PredictiveEID: {name} must be >= 0 and finite, "
                                         f"got {val!r}")
            gains.append(k)
        self.eid, self.model = eid, model
        if gains[1] > 2.0:
            raise DownholeInputError(f"PredictiveEID: depth_of_cut_gain must be in [0, 2] "
                                     f"(1: constant depth of cut), got {depth_of_cut_gain!r}")
        self.damping_gain, self.depth_of_cut_gain, self.axial_filter = gains
        self.angle_doc = bool(angle_doc)
        self.reference = eid.reference
        self.dt = eid.dt

    def damper_params(self, dt: float) -> DamperParams:
        """The damper's parameters (:class:`DamperParams`) at step ``dt``."""
        ch = self.eid.model_coeffs[0]
        tau = max(1, int(round(ch["tau"] / dt)))
        return DamperParams(k_d=float(self.damping_gain), tau_steps=tau,
                            h_steps=max(1, int(round(ch["h"] / dt))), a0=float(ch["a0"]),
                            a1=float(ch["a1"]), g1=float(ch["g1"]), b=float(ch["b"]),
                            bit_mass=float(self.model.params.bit_mass),
                            n_blades=float(self.model.bit.n_blades), dt=float(dt),
                            stride=int(_stride(tau, PREDICTION_STEP / dt)),
                            k_c=float(self.depth_of_cut_gain), angle_doc=self.angle_doc,
                            filter_a=self.axial_filter)

    @staticmethod
    def damper_arrays(dp: DamperParams):
        """Fresh ``(dh, ds, xbuf)`` for parameters ``dp``."""
        return damper_arrays(dp)

    def kernel_runner(self, pack):
        """Compiled closed loop on the neutral string: the EID loop of
        :mod:`downhole.control.eid.neutral_runner` with this damper (``None`` for other
        models).

        Parameters
        ----------
        pack : object
            The kernel configuration :func:`downhole.sim.simulate` runs.

        Returns
        -------
        callable or None
        """
        if getattr(pack, "kind", None) != "neutral":
            return None
        from downhole.control.eid.neutral_runner import make_neutral_runner

        dt = pack.dt
        return make_neutral_runner(self.eid.compiled_params(dt),
                                   damper=(self.damper_params(dt),
                                           self.model.bit.kernel_params()))

    def reset(self) -> None:
        """Zero the EID and the damper's histories (steps of :attr:`dt`)."""
        self.eid.dt = self.dt
        self.eid.reset()
        self._dp = self.damper_params(float(self.dt))
        self._dh, self._ds, self._xbuf = self.damper_arrays(self._dp)
        self._bp = self.model.bit.kernel_params()

    def command(self, t: float, observation: dict, reference=None) -> dict:
        """One step: the EID's commands with ``du`` added to the axial one (the axial
        reference coupled to the measured bit speed when ``depth_of_cut_gain`` > 0)."""
        if not hasattr(self, "_dh"):
            self.reset()
        if reference is None:
            r = self.reference.sample(np.array([t]))[:, 0]
        elif hasattr(reference, "keys"):
            try:
                r = (reference["reference_axial_velocity"],
                     reference["reference_angular_velocity"])
            except KeyError as exc:
                raise DownholeInputError(f"reference lacks {exc.args[0]!r}") from None
        else:
            r = np.asarray(reference, float).reshape(2)
        v = float(observation["bit_axial_velocity"])
        w = float(observation["bit_angular_velocity"])
        r = np.array([coupled_axial_reference(self._dp.k_c, float(r[0]), float(r[1]), w),
                      float(r[1])])
        out = self.eid.command(t, observation, r)
        u = out["top_drive_axial_velocity"]
        du = damper_step(self._dp, self._dh, self._ds, self._xbuf, self._bp, v, w, float(r[0]),
                         u)
        return {"top_drive_axial_velocity": float(u + du),
                "top_drive_angular_velocity": float(out["top_drive_angular_velocity"])}


def predictive_closed_loop(controller, model, rop: float, omega: float,
                           damping_gain: float = 2.0, im_max: float = 200.0, *,
                           depth_of_cut_gain: float = 0.0, axial_filter: float = 0.0) -> dict:
    """Spectral abscissa of the EID loop with an exact predictive damper (axial plant row
    + b k_d, times af/(s + af) with the axial filter's bandwidth af) and the linearized delayed
    depth of cut:
    :func:`regenerative_closed_loop`'s characteristic matrix with those terms added. With the
    depth-of-cut coupling k_c the axial reference perturbation is k_c (rop/omega) times the bit
    angular velocity: it enters the internal model (x_R' = B_R (r - x_p)) and the damper,
    whose command acts on the bit tau1 later (a factor exp(-s tau1)). Returns the same keys."""
    from downhole.control.eid.stability import (
        _bit_rock_gains,
        _regenerative_roots,
        channel_loop_matrices,
    )

    mats = [channel_loop_matrices(controller.model_coeffs[i], controller.gains[i],
                                  predictor=controller.predictor,
                                  delayed_input_observer=controller.delayed_input_observer)
            for i in range(2)]
    kw, kt, c, tn = _bit_rock_gains(model, rop, omega)
    p = model.params
    g1, u1 = model.gammas[0], model.upsilons[0]
    b = controller.model_coeffs[0]["b"]
    br = controller.gains[0].br
    n = 5

    def char(s):
        s = np.atleast_1d(s).astype(complex)
        M = np.zeros((s.size, 2 * n, 2 * n), complex)
        for i, (A0, A1, A2, G, tau) in enumerate(mats):
            q = np.exp(-s * tau)[:, None, None]
            M[:, i * n:(i + 1) * n, i * n:(i + 1) * n] = (s[:, None, None] * (np.eye(n) - G * q * q)
                                                          - A0 - A1 * q - A2 * q * q)
        small = np.abs(s) < 1e-12
        e = np.where(small, tn, (1 - np.exp(-s * tn)) / np.where(small, 1.0, s))
        fa = (1 - g1 * np.exp(-2 * s * model.tau1)) / p.bit_mass * e
        ft = (1 - u1 * np.exp(-2 * s * model.tau2)) / p.bit_inertia * e
        fil_a = axial_filter / (s + axial_filter) if axial_filter > 0 else 1.0
        M[:, 0, 0] += fa * kw + b * damping_gain * fil_a
        M[:, 0, n] += -fa * kw * c
        M[:, n, 0] += ft * kt
        M[:, n, n] += -ft * kt * c
        if depth_of_cut_gain > 0:
            kap = depth_of_cut_gain * rop / omega
            M[:, 3, n] += -br * kap
            M[:, 0, n] += -b * damping_gain * fil_a * kap * np.exp(-s * model.tau1)
        return np.linalg.det(M)

    return _regenerative_roots(char, im_max, g1, u1, model)
