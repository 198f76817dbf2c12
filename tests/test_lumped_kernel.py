"""The lumped models run on the one kernel (:mod:`downhole.sim.kernel`): agreement with the former
chain kernel, and analytic checks.

``tests/data/lumped_kernel_bb4dbcc.npz`` holds 16 samples of four channels of ten runs made with
the separate chain kernel (``downhole/sim/chain_kernel.py``, ``run_chain``) at commit bb4dbcc,
before it was deleted. The same runs on the one kernel:

* explicit Euler (seed Eq. 2.12, Chapter 2): bit-identical in all runs measured (velocity and
  force driven top, delayed and approximated depth of cut, 4th and 12th order, rest, off-bottom
  and steady starts, thinned recording);
* Newmark: the same average-acceleration scheme, but the one kernel solves the bit force exactly
  implicitly at the end of the step and carries the acceleration, where the chain kernel
  linearized the bit force about the start of the step (a frozen-coefficient damper) and
  recomputed the start forces. Measured differences (max over the channels, relative to each
  channel's range): 8.5e-5 and 1.8e-4 with the approximated depth of cut, 4.8e-3 and 9.4e-3 with
  the delayed one (WOB in the stick-slip transient after a speed step; halving dt halves it),
  1.3e-12 off bottom (no bit force). The tolerances below are about twice these.
"""

import math
from pathlib import Path

import numpy as np
import pytest

from downhole.sim import SurfaceInputs, simulate
from downhole.sim.lumped_model import lumped_model
from downhole.string.fem import DirectionalPlant

GOLDEN = Path(__file__).parent / "data" / "lumped_kernel_bb4dbcc.npz"
CHANNELS = ("bit_axial_velocity", "bit_angular_velocity", "wob", "hook_load")
#: Top-drive speed stepped down from 10 to 3 rad/s at 0.5-0.6 s (stick-slip transient).
STEP = ([0.0, 0.5, 0.6, 10.0], [10.0, 10.0, 3.0, 3.0])

M4 = lumped_model("table_2_1")
M12 = lumped_model("table_2_1", order=12)


def _cases():
    vel = SurfaceInputs.velocity(0.01, STEP)
    frc = SurfaceInputs.force(M4.weight - 60e3, 7e3)
    kw = dict(duration=3.0, dt=5e-4)
    return {
        "l4_euler_delayed_vel": lambda: simulate(M4, vel, **kw),
        "l4_euler_approximate_force": lambda: simulate(M4, frc, depth_of_cut="approximate", **kw),
        "l12_euler_delayed_vel": lambda: simulate(M12, vel, **kw),
        "l12_euler_offbottom_rec": lambda: simulate(M12, vel, duration=2.0, dt=5e-4,
                                                    start="off_bottom", record_dt=0.0015),
        "l4_euler_steady": lambda: simulate(M4, vel, start="steady", **kw),
        "l4_newmark_delayed_vel": lambda: simulate(M4, vel, integrator="newmark", **kw),
        "l4_newmark_approximate_vel": lambda: simulate(M4, vel, integrator="newmark",
                                                       depth_of_cut="approximate", **kw),
        "l4_newmark_delayed_force": lambda: simulate(M4, frc, integrator="newmark", **kw),
        "l12_newmark_approximate_vel": lambda: simulate(M12, vel, integrator="newmark",
                                                        depth_of_cut="approximate", **kw),
        "l12_newmark_offbottom_rec": lambda: simulate(M12, vel, duration=2.0, dt=5e-4,
                                                      start="off_bottom", record_dt=0.0015,
                                                      integrator="newmark"),
    }


#: Relative tolerance per case (Euler: the same arithmetic; Newmark: see the module docstring).
TOLERANCE = {"l4_newmark_delayed_vel": 1e-2, "l4_newmark_approximate_vel": 2e-4,
             "l4_newmark_delayed_force": 2e-2, "l12_newmark_approximate_vel": 4e-4,
             "l12_newmark_offbottom_rec": 1e-10}


@pytest.fixture(scope="module")
def golden():
    with np.load(GOLDEN) as z:
        return dict(z)


@pytest.mark.parametrize("name", list(_cases()))
def test_lumped_runs_agree_with_the_former_chain_kernel(golden, name):
    r = _cases()[name]()
    idx = golden[f"{name}/index"]
    tol = TOLERANCE.get(name, 1e-12)
    for ch in CHANNELS:
        ref = golden[f"{name}/{ch}"]
        got = np.asarray(r[ch])[idx]
        scale = max(np.max(np.abs(ref)), 1e-300)
        assert np.max(np.abs(got - ref)) <= tol * scale, (name, ch)


def test_the_golden_runs_move(golden):
    for name in _cases():
        w = golden[f"{name}/bit_angular_velocity"]
        assert np.ptp(w) > 0.05 * np.max(np.abs(w)), name


@pytest.mark.parametrize("integrator", ["euler", "newmark"])
def test_free_axial_oscillation_of_lumped4_is_the_analytic_one(integrator):
    """Off bottom, the top moves 10 mm in 1 s and stops: the mass rings at the damped natural
    frequency sqrt(k/m - (c/2m)^2) (k/m = natural_frequencies()[0]^2)."""
    p = M4.params
    v_top = ([0.0, 1.0, 1.0 + 1e-9, 200.0], [0.01, 0.01, 0.0, 0.0])
    r = simulate(M4, SurfaceInputs.velocity(v_top, 0.0), duration=60.0, dt=1e-3,
                 start="off_bottom", clearance=0.2, integrator=integrator, record_dt=1e-3)
    assert np.all(r["wob"] == 0.0)  # the bit never touches the bottom
    t, v = r.time, r["bit_axial_velocity"]
    sel = t > 2.0
    t, v = t[sel], v[sel]
    up = np.nonzero((v[:-1] < 0) & (v[1:] >= 0))[0]
    tc = t[up] - v[up] * (t[up + 1] - t[up]) / (v[up + 1] - v[up])  # interpolated crossings
    omega = 2 * math.pi / np.mean(np.diff(tc))
    wn = M4.natural_frequencies()["axial"][0]
    assert wn == pytest.approx(math.sqrt(p.axial_stiffness / p.mass))
    damped = math.sqrt(wn ** 2 - (p.axial_damping / (2 * p.mass)) ** 2)
    # Newmark's period error is (omega dt)^2 / 12 ~ 4e-8; Euler's is of the same small order
    assert omega == pytest.approx(damped, rel=1e-3)


@pytest.mark.parametrize("model", [M4, M12], ids=["lumped4", "lumped12"])
def test_static_hook_load_is_the_weight(model):
    """At rest off bottom the hook carries the whole (pre-balanced) weight m g."""
    r = simulate(model, SurfaceInputs.velocity(0.0, 0.0), duration=1.0, dt=5e-4,
                 start="off_bottom", integrator="newmark")
    w = model.params.mass * model.params.g
    assert model.weight == pytest.approx(w)
    assert np.allclose(r["hook_load"], w, rtol=1e-12, atol=0.0)


def test_plant_of_a_lumped_model_is_the_directional_plant_class():
    """One plant class: stepping it reproduces simulate() (same kernel, same arrays)."""
    for integrator in ("euler", "newmark"):
        plant = DirectionalPlant(M12, dt=5e-4, integrator=integrator)
        cmd = {"top_drive_axial_velocity": 0.01, "top_drive_angular_velocity": 10.0}
        plant.reset(set_point=cmd)  # Newmark starts from the accelerations under the set-point
        for _ in range(1000):
            obs = plant.step(cmd)
        res = simulate(M12, SurfaceInputs.velocity(0.01, 10.0), duration=0.5, dt=5e-4,
                       record_dt=5e-4, integrator=integrator)
        # simulate's top position is the trapezoidal integral of the velocity samples, the
        # plant's the sum of its held commands: equal for constant commands
        for ch in ("bit_angular_velocity", "wob", "hook_load", "surface_torque"):
            assert obs[ch] == pytest.approx(res[ch][-1], rel=1e-9, abs=1e-12), (integrator, ch)
        assert obs["time"] == pytest.approx(0.5)
