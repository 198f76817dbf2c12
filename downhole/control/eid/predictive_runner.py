"""Compiled closed loop of :class:`~downhole.control.eid.predictor.PredictiveEID` on the
neutral-type string: :mod:`downhole.control.eid.neutral_runner`'s loop with the predictive
damper's :func:`~downhole.control.eid.predictor.damper_step` added to the axial command after the
EID step (the same per-step plant functions of :mod:`downhole.string.neutral`)."""

from __future__ import annotations

import numpy as np
from numba import njit

from downhole.control.eid._kernel import eid_arrays, eid_step
from downhole.control.eid.neutral_runner import EID_CHANNELS
from downhole.control.eid.predictor import PredictiveEID, damper_step
from downhole.string.neutral import (neutral_advance, neutral_record, neutral_top_and_bit,
                                     neutral_wave_start)

__all__ = ["run_neutral_predictive", "make_predictive_runner"]


@njit(cache=True)
def run_neutral_predictive(za, zt, m_b, i_b, alpha_a, alpha_t, f_top, m_s_g, grav, bitp, approx,
                           ha, pa, wpa, ht, pt, wpt, surf, istate, rp,
                           cp, cs, ch, cpos, dp, dh, ds, xbuf, bpc, ref, noise, fnoise, nsteps,
                           dt, every, out, sigout):
    """As :func:`~downhole.control.eid.neutral_runner.run_neutral_eid`, with the damper
    (parameters ``dp``, state ``dh``, ``ds``, ``xbuf``, controller-side bit law ``bpc``)."""
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
        r[0] = ref[0, k]
        r[1] = ref[1, k]
        eid_step(cp, cs, ch, cpos, y, r, dt, uvec, sig)
        du = damper_step(dp, dh, ds, xbuf, bpc, y[0], y[1], r[0], uvec[0] - off)
        ua = uvec[0] + du
        ut = uvec[1]
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


def make_predictive_runner(cp, dp, bpc):
    """A runner for ``simulate_neutral``'s compiled fast path (fresh states per call)."""

    def runner(plant_args, ref, mnoise, fnoise, nsteps, dt, every, out):
        cs, ch, cpos = eid_arrays(cp)
        dh, ds, xbuf = PredictiveEID.damper_arrays(dp)
        sigout = np.zeros((out.shape[0], len(EID_CHANNELS)))
        status, kfail, cfail = run_neutral_predictive(*plant_args, cp, cs, ch, cpos, dp, dh, ds,
                                                      xbuf, bpc, ref, mnoise, fnoise, nsteps, dt,
                                                      every, out, sigout)
        return status, kfail, cfail, {name: sigout[:, j] for j, name in enumerate(EID_CHANNELS)}

    return runner
