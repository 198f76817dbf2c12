"""Hybrid FEM + wave segment against a dense FEM; the line's delay and impedance; presets."""

import numpy as np
import pytest

from downhole.control.topdrive import Hook, TopDrive
from downhole.errors import DownholeInputError
from downhole.sim import simulate
from downhole.string.fem import fem_model
from downhole.string.hybrid import hybrid_model
from downhole.well import Arc, Vertical, WellPath


@pytest.fixture(scope="module")
def runs():
    # 20 s of stick-slip (PI top drive at 10 rad/s, 120 kN WOB, Table 5.1 damping)
    dense = simulate(fem_model(n_elements=1000), duration=20.0, dt=1e-3)
    h68 = simulate(hybrid_model("hybrid68"), duration=20.0, dt=1e-3)
    return dense, h68


def _rms_over_peak(a, b, t):
    sel = t >= 0.1
    a, b = a[sel], b[sel]
    return np.sqrt(np.mean((a - b) ** 2)) / (b.max() - b.min())


def test_presets_have_the_seed_state_counts():
    assert [hybrid_model(p).n_states for p in ("hybrid24", "hybrid68", "hybrid108")] == [24, 68, 108]


def test_forces_at_b_and_c_match_dense_fem(runs):
    dense, h68 = runs
    for ch in ("force_b", "torque_b", "force_c", "torque_c"):
        assert _rms_over_peak(h68[ch], dense[ch], dense.time) < 0.03, ch


def test_68_state_bit_speed_within_5_percent_of_dense_fem(runs):
    dense, h68 = runs
    w, wf = h68["bit_angular_velocity"], dense["bit_angular_velocity"]
    assert np.sqrt(np.mean((w - wf) ** 2)) / np.sqrt(np.mean(wf**2)) < 0.05
    s = dense.summary(window=(5, 20))
    assert s["stuck_fraction"] > 0.2  # it is a stick-slip run


def test_wave_segment_delays_a_torque_step_by_tau_with_impedance_z():
    m = hybrid_model(None, n_ab=30, n_cd=30, rayleigh_alpha=0.0, rayleigh_beta=0.0,
                     friction=0.0)
    tau_t = m.wave["tau"][1]
    Z = m.wave["impedance"][1]
    r = simulate(m, duration=1.2, dt=1e-4, top_drive=TopDrive(mode="torque", speed=5000.0),
                             hook=Hook(wob=0.0), record_dt=1e-4)
    t = r.time
    tb, tc = r["torque_b"], r["torque_c"]
    arr_b = t[np.argmax(np.abs(tb) > 0.05 * np.abs(tb).max())]
    arr_c = t[np.argmax(np.abs(tc) > 0.05 * np.abs(tb).max())]
    assert arr_c - arr_b == pytest.approx(tau_t, abs=3e-3)
    # the incoming front at B sees the line as a dashpot: torque = Z * omega_B
    i = np.searchsorted(t, arr_b + 0.3 * tau_t)
    from downhole.sim.kernel import CHANNELS  # noqa: F401
    pl = hybrid_model(None, n_ab=30, n_cd=30, rayleigh_alpha=0.0, rayleigh_beta=0.0, friction=0.0)
    from downhole.string.fem import DirectionalPlant
    plant = DirectionalPlant(pl, 1e-4, top_drive=TopDrive(mode="torque", speed=5000.0),
                             hook=Hook(wob=0.0))
    hold = plant.default_command()
    for _ in range(i):
        plant.step(hold)
    fields = plant.node_fields()
    omega_b = fields["angular_velocity"][pl.node_b]
    assert plant._obs["torque_b"] == pytest.approx(Z * omega_b, rel=0.02)
    obs = plant.step(hold)
    fields = plant.node_fields()
    assert fields["angular_velocity"][-1] == obs["last_node_angular_velocity"]
    assert fields["axial_velocity"][-1] == obs["last_node_axial_velocity"]
    assert fields["angle"].shape == (len(pl.node_md),)


def test_hybrid_bad_input():
    with pytest.raises(DownholeInputError, match="unknown hybrid preset"):
        hybrid_model("hybrid99")
    with pytest.raises(DownholeInputError, match="n_cd .* must be >= 2"):
        hybrid_model(None, n_ab=3, n_cd=1)
    well = WellPath.from_sections([Vertical(1000), Arc(2000, 0.5)])
    with pytest.raises(DownholeInputError, match="curved"):
        hybrid_model(None, n_ab=3, n_cd=3, well=well, md_b=1200, md_c=1600)


def test_soft_torque_top_drive_reduces_stick_slip_on_the_fig_5_7_case():
    m = hybrid_model("hybrid68")
    win = (15.0, 40.0)
    pi = simulate(m, duration=40.0, dt=1e-3, top_drive=TopDrive(mode="pi")).summary(win)
    soft = simulate(m, duration=40.0, dt=1e-3,
                                top_drive=TopDrive(mode="soft_torque")).summary(win)
    assert pi["stuck_fraction"] > 0.2                        # the PI case stick-slips
    assert soft["stuck_fraction"] < 0.5 * pi["stuck_fraction"]
    assert soft["stick_slip_severity"] < 0.8 * pi["stick_slip_severity"]
    # same mean speed: the soft drive only yields to the torque oscillation
    assert soft["mean_bit_angular_velocity"] == pytest.approx(10.0, rel=0.05)
