"""The EID controller's compiled closed loop on the neutral-type string: the fast path that
:func:`downhole.string.neutral.simulate_neutral` asks a controller for through
``controller.neutral_runner(dt)``.

The loop couples :func:`~downhole.control.eid._kernel.eid_step` with the mechanics core's
compiled per-step functions (:func:`~downhole.string.neutral.neutral_top_and_bit`,
:func:`~downhole.string.neutral.neutral_record`, :func:`~downhole.string.neutral.neutral_advance`),
the same ones the open-loop runner uses, so no plant physics is written here. At each step t_k the
controller sees the bit velocities plus the measurement noise and the reference at t_k, and its
command acts on the top nodes at t_k (as in the Python loop with ``control_dt = dt``).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from downhole.control.eid._kernel import eid_arrays, eid_step
from downhole.control.eid.damper import (
    DamperParams,
    coupled_axial_reference,
    damper_arrays,
    damper_step,
)
from downhole.string.neutral import (
    neutral_advance,
    neutral_record,
    neutral_top_and_bit,
    neutral_wave_start,
)

__all__ = ["EID_CHANNELS", "make_neutral_runner", "run_neutral_eid"]

#: Channels the EID runner adds to the record (besides the reference, which the core adds).
EID_CHANNELS = ("measured_axial_velocity", "measured_angular_velocity",
                "eid_disturbance_axial", "eid_disturbance_angular",
                "eid_prediction_axial", "eid_prediction_angular")


@njit(cache=True)
def run_neutral_eid(za, zt, m_b, i_b, alpha_a, alpha_t, f_top, m_s_g, grav, bitp, approx,
                    ha, pa, wpa, ht, pt, wpt, surf, istate, rp,
                    cp, cs, ch, cpos, dp, dh, ds, xbuf, bpc, ref, noise, fnoise, nsteps, dt,
                    every, out, sigout):
    """Closed loop from the state held in the wave buffers (``pa``, ``pt``) with the bit at rest
    at t = 0: ``nsteps`` steps of ``dt`` with the EID controller (parameters ``cp``, states
    ``cs``, ``ch``, ``cpos`` from :func:`~downhole.control.eid._kernel.eid_arrays`) and, when
    ``dp.k_d > 0``, the predictive bit damper added to its axial command
    (:func:`~downhole.control.eid.damper.damper_step`: parameters ``dp``, states ``dh``,
    ``ds``, ``xbuf``, the controller's bit law ``bpc``). Records every ``every`` steps and the
    last into ``out`` (:data:`~downhole.string.neutral.NEUTRAL_CHANNELS`) and ``sigout``
    (:data:`EID_CHANNELS`); returns (status, step, channel)."""
    x = 0.0
    v = 0.0
    th = 0.0
    w = 0.0
    na, nt, plan, a_in, b_in, a_in_t, b_in_t = neutral_wave_start(ha, pa, wpa, ht, pt, wpt)
    uvec = np.zeros(2)
    y = np.zeros(2)
    r = np.zeros(2)
    sig = np.zeros((2, 4))
    rec = 0
    off = cp[0].offset
    for k in range(nsteps + 1):
        y[0] = v + noise[0, k]
        y[1] = w + noise[1, k]
        r[1] = ref[1, k]
        r[0] = coupled_axial_reference(dp.k_c, ref[0, k], r[1], y[1])
        eid_step(cp, cs, ch, cpos, y, r, dt, uvec, sig)
        ua = uvec[0]
        ut = uvec[1]
        if dp.k_d > 0.0:
            ua += damper_step(dp, dh, ds, xbuf, bpc, y[0], y[1], r[0], uvec[0] - off)
        top_bit = neutral_top_and_bit(
            za, zt, alpha_a, alpha_t, f_top, bitp, approx, surf, istate, rp,
            x, v, th, w, a_in, b_in, a_in_t, b_in_t, ua, ut, fnoise[0, k], fnoise[1, k])
        vtop, wtop, d, wob, tob = top_bit
        if k % every == 0 or k == nsteps:
            sigout[rec, 0] = y[0]
            sigout[rec, 1] = y[1]
            sigout[rec, 2] = sig[0, 1]
            sigout[rec, 3] = sig[1, 1]
            sigout[rec, 4] = sig[0, 2]
            sigout[rec, 5] = sig[1, 2]
            c = neutral_record(out, rec, k * dt, x, v, th, w, d, wob, tob, vtop, wtop,
                               ua, ut, alpha_a, alpha_t, f_top, m_s_g)
            if c != 0:
                pa[0] = na
                pt[0] = nt
                return 1, k, c
            rec += 1
        if k == nsteps:
            break
        na, nt, x, v, th, w, a_in, b_in, a_in_t, b_in_t = neutral_advance(
            za, zt, m_b, i_b, grav, bitp, approx, ha, wpa, ht, wpt, surf, istate, rp, plan,
            na, nt, x, v, th, w, a_in, b_in, a_in_t, b_in_t, top_bit, dt)
    pa[0] = na
    pt[0] = nt
    return 0, nsteps, 0


#: The damper switched off (the plain EID loop).
NO_DAMPER = DamperParams(k_d=0.0, tau_steps=1, h_steps=1, a0=0.0, a1=0.0, g1=0.0, b=0.0,
                         bit_mass=1.0, n_blades=1.0, dt=1.0, stride=1)


def make_neutral_runner(cp, damper=None):
    """A runner for ``simulate_neutral``'s compiled fast path with EID parameters ``cp`` (from
    :meth:`EIDController.compiled_params <downhole.control.eid.controller.EIDController.
    compiled_params>`) and optionally the predictive damper ``damper = (dp, bpc)``
    (:class:`~downhole.control.eid.predictor.PredictiveEID`); fresh states per call."""
    def runner(plant_args, ref, mnoise, fnoise, nsteps, dt, every, out):
        cs, ch, cpos = eid_arrays(cp)
        if damper is None:
            dp, bpc = NO_DAMPER, plant_args[9]  # plant_args[9]: the plant's bit law
        else:
            dp, bpc = damper
        dh, ds, xbuf = damper_arrays(dp)
        sigout = np.zeros((out.shape[0], len(EID_CHANNELS)))
        status, kfail, cfail = run_neutral_eid(*plant_args, cp, cs, ch, cpos, dp, dh, ds, xbuf,
                                               bpc, ref, mnoise, fnoise, nsteps, dt, every,
                                               out, sigout)
        return status, kfail, cfail, {name: sigout[:, j] for j, name in enumerate(EID_CHANNELS)}

    return runner
