"""The cases of ``tests/test_kernel_params.py``: one short run per kernel (lumped Euler and
Newmark, neutral open loop, neutral with the compiled EID loop, FEM with a PI top drive, FEM with
soft torque and a velocity hook, hybrid with the Aarsnes law) and the channels compared.

``python tests/_kernel_golden_cases.py OUT.npz`` records them; the file in ``tests/data`` was
written so at commit be13fcb, before the kernels took named parameter structures.
"""

from __future__ import annotations

import dataclasses
import sys

import numpy as np

CHANNELS = ("bit_axial_velocity", "bit_angular_velocity", "depth_of_cut", "wob", "tob",
            "hook_load", "surface_torque")


#: Top-drive set-point stepped down from the steady 10 rad/s (excites the torsional dynamics).
_STEP = ([0.0, 0.1, 0.15, 10.0], [10.0, 10.0, 4.0, 4.0])


def cases():
    """``{name: callable -> Result}``."""
    from downhole.control.eid import design_eid
    from downhole.params import BitParams
    from downhole.params.rig import Hook, TopDrive
    from downhole.sim import simulate
    from downhole.sim.inputs import SurfaceInputs
    from downhole.sim.lumped_model import lumped_model
    from downhole.string.fem import fem_model
    from downhole.string.hybrid import hybrid_model
    from downhole.string.neutral import neutral_model

    def lumped4():
        return simulate(lumped_model("table_2_1"), SurfaceInputs.velocity(0.01, 10.0),
                        duration=3.0, dt=5e-4)

    def lumped12():
        return simulate(lumped_model("table_2_1", order=12), SurfaceInputs.velocity(0.01, 10.0),
                        duration=2.0, dt=5e-4, integrator="newmark",
                        depth_of_cut="approximate")

    def neutral():
        return simulate(neutral_model("table_3_1"), duration=1.0, dt=1e-4)

    def neutral_eid():
        m = neutral_model("table_3_1")
        return simulate(m, duration=1.0, dt=2e-4, controller=design_eid(m))

    def fem():
        return simulate(fem_model(n_elements=60), {"top_drive_angular_velocity": _STEP},
                        duration=3.0, dt=1e-3, start="steady", record_dt=0.01)

    def fem_soft():
        return simulate(fem_model(n_elements=40), duration=3.0, dt=1e-3,
                                    top_drive=TopDrive(mode="soft_torque"),
                                    hook=Hook(mode="velocity", velocity=0.005),
                                    depth_of_cut="approximate", record_dt=0.01)

    def hybrid():
        m = dataclasses.replace(hybrid_model("hybrid24"), bit=BitParams(law="aarsnes", gamma=0.5))
        return simulate(m, {"top_drive_angular_velocity": _STEP}, duration=3.0, dt=1e-3,
                        start="steady", record_dt=0.01)

    return {"lumped4": lumped4, "lumped12": lumped12, "neutral": neutral,
            "neutral_eid": neutral_eid, "fem": fem, "fem_soft": fem_soft, "hybrid": hybrid}


def sample(x):
    """Every 5th recorded sample and the last (what the stored file holds)."""
    x = np.asarray(x, dtype=np.float64)
    return np.concatenate([x[::5], x[-1:]])


def record(path):
    out = {}
    for name, fn in cases().items():
        r = fn()
        for ch in CHANNELS:
            out[f"{name}/{ch}"] = sample(r[ch])
        print(name, {ch: float(np.asarray(r[ch])[-1]) for ch in CHANNELS[:2]})
    np.savez_compressed(path, **out)


if __name__ == "__main__":
    record(sys.argv[1])
