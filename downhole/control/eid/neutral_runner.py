"""The EID controller's compiled closed loop on the neutral-type string: the fast path that
:func:`downhole.sim.simulate` asks a controller for through
``controller.kernel_runner(pack)``.

The loop couples :func:`~downhole.control.eid._kernel.eid_step` with the one mechanics kernel
(:func:`~downhole.sim.kernel.run_kernel`, configured by
:class:`~downhole.string.neutral.NeutralPack`), called one step at a time, so no plant physics
is written here. At each step t_k the controller sees the bit velocities of t_k plus the
measurement noise and the reference at t_k, and its command is held over the step from t_k to
t_{k+1}: the same timing as the Python loop with ``control_dt = dt``, so the two give the same
numbers (``tests/test_eid.py``).
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
from downhole.sim.kernel import kernel_state, run_kernel

__all__ = ["EID_CHANNELS", "PIECE", "make_neutral_runner", "run_neutral_eid"]

#: Channels the EID runner adds to the record (besides the reference, which the core adds).
EID_CHANNELS = ("command_axial", "command_angular",
                "measured_axial_velocity", "measured_angular_velocity",
                "eid_disturbance_axial", "eid_disturbance_angular",
                "eid_prediction_axial", "eid_prediction_angular")


#: Steps per compiled call: between calls Python runs, so Ctrl-C (KeyboardInterrupt) and the
#: CLI's stop signals end a long closed loop within one piece (about 0.1 s of work).
PIECE = 200_000


@njit(cache=True)
def run_neutral_eid(model, ks, cmd, no_ref, hang, cp, cs, ch, cpos, dp, dh, ds, xbuf, bpc, ref,
                    noise, fnoise, k0, k1, nsteps, dt, every, rec, sigout, last_io, uvec_io,
                    sig_io):
    """Closed loop from the kernel's model and run state (``model`` a
    :class:`~downhole.sim.kernel.KernelModel`, ``ks`` a :class:`~downhole.sim.kernel.KernelState`,
    ``cmd`` a (1, 2) or (1, 4) command row, ``no_ref`` the unused top reference): the steps
    ``k0`` to ``k1 - 1`` of ``nsteps`` steps of ``dt`` (each: the controller at t_k, the record,
    the kernel step; with ``k1 == nsteps`` also the controller and record of t_nsteps) with the
    EID controller (parameters ``cp``, states ``cs``, ``ch``, ``cpos`` from
    :func:`~downhole.control.eid._kernel.eid_arrays`) and, when ``dp.k_d > 0``, the predictive
    bit damper added to its axial command (:func:`~downhole.control.eid.damper.damper_step`:
    parameters ``dp``, states ``dh``, ``ds``, ``xbuf``, the controller's bit law ``bpc``). The
    command U_A is given to the kernel relative to the hanging equilibrium (``U_A - hang``).
    ``last_io`` (1, channels) holds the record of t_k0 (row 0 of ``rec`` at k0 = 0) and is carried
    to the next call, as are ``uvec_io`` (2,) and ``sig_io`` (2, 4), the EID step's outputs; rows
    every ``every`` steps and the last are written into ``rec`` and ``sigout``
    (:data:`EID_CHANNELS`). Returns (status, step reached)."""
    y = np.zeros(2)
    r = np.zeros(2)
    # locals for the carried arrays (the compiler keeps them apart from the others), written
    # back at the end of the piece
    last = last_io.copy()
    uvec = uvec_io.copy()
    sig = sig_io.copy()
    nrec = rec.shape[0]
    off = cp[0].offset
    noisy = cmd.shape[1] > 2
    state = ks.state
    kend = k1 + 1 if k1 == nsteps else k1
    for k in range(k0, kend):
        y[0] = state[1, 1] + noise[0, k]
        y[1] = state[4, 1] + noise[1, k]
        r[1] = ref[1, k]
        r[0] = coupled_axial_reference(dp.k_c, ref[0, k], r[1], y[1])
        eid_step(cp, cs, ch, cpos, y, r, dt, uvec, sig)
        ua = uvec[0]
        if dp.k_d > 0.0:
            ua += damper_step(dp, dh, ds, xbuf, bpc, y[0], y[1], r[0], uvec[0] - off)
        row = k // every if k % every == 0 else (nrec - 1 if k == nsteps else -1)
        if row >= 0:
            rec[row, :] = last[0, :]
            sigout[row, 0] = ua
            sigout[row, 1] = uvec[1]
            sigout[row, 2] = y[0]
            sigout[row, 3] = y[1]
            sigout[row, 4] = sig[0, 1]
            sigout[row, 5] = sig[1, 1]
            sigout[row, 6] = sig[0, 2]
            sigout[row, 7] = sig[1, 2]
        if k == nsteps:
            break
        cmd[0, 0] = ua - hang
        cmd[0, 1] = uvec[1]
        if noisy:
            cmd[0, 2] = fnoise[k, 0]
            cmd[0, 3] = fnoise[k, 1]
        status, _ = run_kernel(model, ks, cmd, no_ref, 1, dt, last, 1, 0)
        if status != 0:
            return 1, k
    last_io[:, :] = last
    uvec_io[:] = uvec
    sig_io[:, :] = sig
    return 0, k1


#: The damper switched off (the plain EID loop).
NO_DAMPER = DamperParams(k_d=0.0, tau_steps=1, h_steps=1, a0=0.0, a1=0.0, g1=0.0, b=0.0,
                         bit_mass=1.0, n_blades=1.0, dt=1.0, stride=1)


def make_neutral_runner(cp, damper=None):
    """A runner for ``simulate``'s compiled fast path with EID parameters ``cp`` (from
    :meth:`EIDController.compiled_params <downhole.control.eid.controller.EIDController.
    compiled_params>`) and optionally the predictive damper ``damper = (dp, bpc)``
    (:class:`~downhole.control.eid.predictor.PredictiveEID`); fresh states per call."""
    def runner(pack, st, ref, mnoise, fnoise, nsteps, every, rec):
        cs, ch, cpos = eid_arrays(cp)
        if damper is None:
            dp, bpc = NO_DAMPER, pack.bitp
        else:
            dp, bpc = damper
        dh, ds, xbuf = damper_arrays(dp)
        sigout = np.zeros((rec.shape[0], len(EID_CHANNELS)))
        fn = np.ascontiguousarray(fnoise) if fnoise.shape[1] else np.zeros((1, 2))
        model, ks = pack.kernel_model(), kernel_state(st)
        last = rec[:1].copy()
        uvec, sig = np.zeros(2), np.zeros((2, 4))
        k0 = 0
        while True:  # in pieces: Python runs between them (Ctrl-C, stop signals)
            k1 = min(k0 + PIECE, nsteps)
            status, kfail = run_neutral_eid(model, ks, st["cmd"], np.zeros((1, 4)),
                                            pack.model.hang_command, cp, cs, ch, cpos, dp, dh,
                                            ds, xbuf, bpc, ref, mnoise, fn, k0, k1, nsteps,
                                            pack.dt, every, rec, sigout, last, uvec, sig)
            if status != 0 or k1 == nsteps:
                break
            k0 = k1
        return status, kfail, {name: sigout[:, j] for j, name in enumerate(EID_CHANNELS)}

    return runner
