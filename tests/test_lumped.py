"""4th- and 12th-order lumped models: analytic steady states, depth-of-cut models, convergence,
an independent NumPy stepping, and error reporting."""

import math

import numpy as np
import pytest

from downhole.bit import bit_forces_py
from downhole.errors import DownholeInputError, SimulationDiverged
from downhole.sim import SurfaceInputs, simulate
from downhole.sim.lumped_model import lumped_model
from downhole.sim.reference_numpy import simulate_lumped4_numpy
from downhole.string.fem import DirectionalPlant

M4 = lumped_model("table_2_1", order=4)
P = M4.params


def test_natural_frequencies_are_analytic():
    f = M4.natural_frequencies()
    assert f["axial"][0] == pytest.approx(math.sqrt(P.axial_stiffness / P.mass))
    assert f["torsional"][0] == pytest.approx(math.sqrt(P.torsional_stiffness / P.inertia))
    # the 12th-order chain keeps the static compliance 1/Ka: its first mode is close
    f12 = lumped_model("table_2_1", order=12).natural_frequencies()
    assert f12["axial"][0] == pytest.approx(f["axial"][0], rel=0.06)


def test_nominal_steady_state_is_analytic():
    """10 mm/s, 10 rad/s: bit velocities equal the inputs, WOB/TOB follow the law at
    d = 2 pi V/Omega, and the surface loads balance them through the string dampers."""
    v0, w0 = 0.01, 10.0
    res = simulate(M4, SurfaceInputs.velocity(v0, w0), duration=400.0, dt=1e-3,
                   integrator="newmark", record_dt=0.1)
    assert res["bit_axial_velocity"][-1] == pytest.approx(v0, rel=2e-3)
    assert res["bit_angular_velocity"][-1] == pytest.approx(w0, rel=2e-3)
    d = 2 * math.pi * v0 / w0
    assert res["depth_of_cut"][-1] == pytest.approx(d, rel=5e-3)
    wob, tob = bit_forces_py(d, v0, w0, M4.bit)
    assert res["wob"][-1] == pytest.approx(wob, rel=5e-3)
    assert res["tob"][-1] == pytest.approx(tob, rel=5e-3)
    # hook load = weight - (WOB + C_a v); surface torque = TOB + C_t omega
    assert res["hook_load"][-1] == pytest.approx(P.mass * 9.81 - wob - P.axial_damping * v0, rel=1e-4)
    assert res["surface_torque"][-1] == pytest.approx(tob + P.torsional_damping * w0, rel=5e-3)


def test_force_driven_top_reaches_force_balance():
    slack, torque = 60e3, 7e3
    inputs = SurfaceInputs.force(hook_load=M4.weight - slack, torque=torque)
    # (this operating point, ~4.6 rad/s, is below the delayed model's stability limit, so the
    # force balance is checked on the approximated depth of cut, whose equilibrium is stable)
    res = simulate(M4, inputs, duration=300.0, dt=1e-3, integrator="newmark", record_dt=0.1,
                   depth_of_cut="approximate")
    assert res["hook_load"][-1] == pytest.approx(M4.weight - slack)
    v, w = res["bit_axial_velocity"][-1], res["bit_angular_velocity"][-1]
    assert res["wob"][-1] + P.axial_damping * v == pytest.approx(slack, rel=1e-3)
    assert res["tob"][-1] + P.torsional_damping * w == pytest.approx(torque, rel=1e-3)
    assert v > 0 and w > 0


def test_delayed_and_approximated_agree_at_10_rad_s():
    inputs = SurfaceInputs.velocity(0.01, 10.0)
    a = simulate(M4, inputs, duration=40.0, dt=5e-4, record_dt=0.01)
    b = simulate(M4, inputs, duration=40.0, dt=5e-4, record_dt=0.01, depth_of_cut="approximate")
    sel = a.time >= 20.0
    for ch in ("bit_axial_velocity", "bit_angular_velocity", "depth_of_cut"):
        rel = np.max(np.abs(a[ch][sel] - b[ch][sel])) / np.mean(np.abs(a[ch][sel]))
        assert rel < 0.02, ch


def test_stick_slip_only_with_the_delay_at_2_rad_s():
    inputs = SurfaceInputs.velocity(0.01, 2.0)
    a = simulate(M4, inputs, duration=80.0, dt=5e-4, record_dt=0.01).summary()
    b = simulate(M4, inputs, duration=80.0, dt=5e-4, record_dt=0.01,
                 depth_of_cut="approximate").summary()
    assert a["stuck_fraction"] > 0.1
    assert a["stick_slip_severity"] > 0.5
    assert b["stuck_fraction"] == 0.0
    assert b["stick_slip_severity"] < 0.2


def test_twelfth_order_follows_fourth_order():
    inputs = SurfaceInputs.velocity(0.01, 10.0)
    r4 = simulate(M4, inputs, duration=40.0, dt=5e-4, record_dt=0.01)
    r12 = simulate(lumped_model("table_2_1", order=12), inputs, duration=40.0, dt=5e-4,
                   record_dt=0.01)
    sel = r4.time >= 20.0
    for ch in ("bit_axial_velocity", "bit_angular_velocity"):
        x, y = r4[ch][sel], r12[ch][sel]
        assert np.sqrt(np.mean((x - y) ** 2)) / np.mean(np.abs(x)) < 0.05


@pytest.mark.parametrize("integrator", ["euler", "newmark"])
def test_converges_as_dt_shrinks(integrator):
    inputs = SurfaceInputs.velocity(0.01, 10.0)
    kw = dict(duration=8.0, record_dt=0.01, integrator=integrator)
    ref = simulate(M4, inputs, dt=6.25e-5, **kw)["bit_angular_velocity"]
    errs = [np.max(np.abs(simulate(M4, inputs, dt=dt, **kw)["bit_angular_velocity"] - ref))
            for dt in (1e-3, 5e-4, 2.5e-4)]
    assert errs[0] > errs[1] > errs[2]
    assert errs[2] < 0.01 * np.max(np.abs(ref))


def test_matches_independent_numpy_stepping():
    """The compiled kernel (rock-surface grid) vs plain NumPy (history search for Eq. 2.10)."""
    res = simulate(M4, SurfaceInputs.velocity(0.01, 10.0), duration=10.0, dt=5e-4,
                   record_dt=5e-4, rock_memory=False)
    ref = simulate_lumped4_numpy(M4, 0.01, 10.0, 10.0, 5e-4)
    for ch in ("bit_axial_velocity", "bit_angular_velocity", "depth_of_cut"):
        scale = np.max(np.abs(ref[ch]))
        assert np.max(np.abs(res[ch] - ref[ch])) < 2e-3 * scale, ch


def test_plant_steps_like_simulate():
    plant = DirectionalPlant(M4, dt=5e-4)
    obs = plant.reset()
    assert obs["bit_angular_velocity"] == 0.0
    for _ in range(2000):
        obs = plant.step({"top_drive_axial_velocity": 0.01, "top_drive_angular_velocity": 10.0})
    res = simulate(M4, SurfaceInputs.velocity(0.01, 10.0), duration=1.0, dt=5e-4, record_dt=5e-4)
    assert obs["time"] == pytest.approx(1.0)
    assert obs["bit_angular_velocity"] == pytest.approx(res["bit_angular_velocity"][-1], rel=1e-9)
    with pytest.raises(DownholeInputError, match="top_drive_angular_velocity"):
        plant.step({"top_drive_axial_velocity": 0.01})


def test_divergence_names_time_and_channel():
    with pytest.raises(SimulationDiverged, match=r"t = .* in channel"):
        simulate(lumped_model("table_2_1", order=12), SurfaceInputs.velocity(0.01, 10.0),
                 duration=50.0, dt=0.05)


@pytest.mark.parametrize("kwargs,match", [
    (dict(duration=-1.0), "duration"), (dict(dt=0.0), "dt"),
    (dict(depth_of_cut="exact"), "depth_of_cut"), (dict(integrator="rk45"), "integrator"),
    (dict(duration=1.0, dt=0.3), "divide"),
])
def test_bad_arguments(kwargs, match):
    with pytest.raises(DownholeInputError, match=match):
        simulate(M4, **kwargs)


def test_unbalanced_printed_model_sags_by_weight_over_stiffness():
    """Without the pre-balance (printed Eq. 2.1) the string's weight is unbalanced: hanging off
    bottom it would settle M g / K_a = 21.9 m lower (docs/seed-errata.md)."""
    from downhole.params import LumpedParams

    p = P.model_copy(update={"gravity_prebalance": False})
    assert isinstance(p, LumpedParams)
    m = lumped_model(p, order=4)
    assert m.axial.gravity[0] == pytest.approx(P.mass * 9.81)
    assert m.axial.gravity[0] / m.axial.k_top == pytest.approx(21.88, rel=1e-3)
