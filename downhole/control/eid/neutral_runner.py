"""The EID controller's compiled closed loop on the neutral-type string: the fast path that
:func:`downhole.string.neutral.simulate_neutral` asks a controller for through
``controller.neutral_runner(dt)``.

The mechanics core's one compiled loop, :func:`downhole.string.neutral.neutral_loop`, takes the
surface commands of each step from a compiled command function; this module supplies the EID's,
:func:`eid_commands` (:func:`~downhole.control.eid._kernel.eid_step` on the measured bit
velocities and the reference), so no plant physics is written here. At each step t_k the
controller sees the bit velocities plus the measurement noise and the reference at t_k, and its
command acts on the top nodes at t_k (as in the Python loop with ``control_dt = dt``).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from downhole.control.eid._kernel import eid_arrays, eid_step
from downhole.string.neutral import neutral_loop

__all__ = ["EID_CHANNELS", "eid_commands", "make_neutral_runner"]

#: Channels the EID runner adds to the record (besides the reference, which the core adds).
EID_CHANNELS = ("measured_axial_velocity", "measured_angular_velocity",
                "eid_disturbance_axial", "eid_disturbance_angular",
                "eid_prediction_axial", "eid_prediction_angular")


@njit(cache=True)
def eid_commands(ctl, k, v, w, dt, rec):
    """Command function of :func:`~downhole.string.neutral.neutral_loop` for the EID:
    ``ctl = (cp, cs, ch, cpos, ref, noise, y, r, uvec, sig, sigout)``; one EID step on the bit
    velocities plus the measurement noise ``noise[:, k]`` and the reference ``ref[:, k]``; on a
    record step (``rec >= 0``) writes :data:`EID_CHANNELS` into ``sigout[rec]``."""
    cp, cs, ch, cpos, ref, noise, y, r, uvec, sig, sigout = ctl
    y[0] = v + noise[0, k]
    y[1] = w + noise[1, k]
    r[0] = ref[0, k]
    r[1] = ref[1, k]
    eid_step(cp, cs, ch, cpos, y, r, dt, uvec, sig)
    if rec >= 0:
        sigout[rec, 0] = y[0]
        sigout[rec, 1] = y[1]
        sigout[rec, 2] = sig[0, 1]
        sigout[rec, 3] = sig[1, 1]
        sigout[rec, 4] = sig[0, 2]
        sigout[rec, 5] = sig[1, 2]
    return uvec[0], uvec[1]


def make_neutral_runner(cp: np.ndarray):
    """A runner for ``simulate_neutral``'s compiled fast path with EID parameters ``cp`` (from
    :meth:`EIDController.compiled_params <downhole.control.eid.controller.EIDController.
    compiled_params>`); fresh controller states per call, the bit at rest at t = 0."""

    def runner(plant_args, ref, mnoise, fnoise, nsteps, dt, every, out):
        cs, ch, cpos = eid_arrays(cp)
        sigout = np.zeros((out.shape[0], len(EID_CHANNELS)))
        ctl = (cp, cs, ch, cpos, ref, mnoise, np.zeros(2), np.zeros(2), np.zeros(2),
               np.zeros((2, 4)), sigout)
        status, kfail, cfail = neutral_loop(eid_commands, ctl, *plant_args, fnoise, nsteps, dt,
                                            every, out, np.zeros(4), 0.0)
        return status, kfail, cfail, {name: sigout[:, j] for j, name in enumerate(EID_CHANNELS)}

    return runner
