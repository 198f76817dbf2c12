"""Starting a run from rest, off bottom or the steady drilling state (the Plant contract's
``start``), checked against hand-computed equilibria of the seed's bit law."""

import math

import numpy as np
import pytest

from downhole.errors import DownholeInputError
from downhole.params import get_preset
from downhole.sim import SurfaceInputs, simulate
from downhole.sim.lumped_model import lumped_model
from downhole.sim.plant import START_MODES, Plant
from downhole.string.fem import DirectionalPlant

V0, W0 = 0.01, 20.0  # 10 mm/s, 20 rad/s: outside the stick-slip region of Table 2.1


def _hand_bit_forces(d, v, omega):
    """Eqs. 2.2-2.8 (corrected) written out for d >= d*, v > 0, omega > 0."""
    b = get_preset("table_2_1").bit
    a = b.radius
    wf = b.sigma * b.wear_length * a / (1.0 + math.exp(b.a1 * v + b.b1))
    mu = b.mu_c + (b.mu_s - b.mu_c) * math.exp(-b.gamma_b / b.v_f * omega)
    wob = b.zeta * b.epsilon * a * d + wf
    tob = 0.5 * b.epsilon * a * a * d + 0.5 * mu * b.gamma * a * math.tanh(b.a2 * omega + b.b2) * wf
    return wob, tob


@pytest.mark.parametrize("order", [4, 12])
@pytest.mark.parametrize("doc", ["delayed", "approximate"])
def test_steady_start_stays_in_equilibrium_for_a_second(order, doc):
    m = lumped_model("table_2_1", order=order)
    dt = 5e-4 if order == 4 else 1e-4
    r = simulate(m, SurfaceInputs.velocity(V0, W0), duration=1.0, dt=dt, depth_of_cut=doc,
                 start="steady")
    assert np.max(np.abs(r["bit_axial_velocity"] / V0 - 1)) < 0.01
    assert np.max(np.abs(r["bit_angular_velocity"] / W0 - 1)) < 0.01
    d0 = 2 * math.pi * V0 / W0
    wob, tob = _hand_bit_forces(d0, V0, W0)
    assert r["depth_of_cut"][0] == pytest.approx(d0, rel=1e-9)
    assert r["wob"][0] == pytest.approx(wob, rel=1e-9)
    assert r["tob"][0] == pytest.approx(tob, rel=1e-9)
    # from rest the same run is far from the set-points at first
    r0 = simulate(m, SurfaceInputs.velocity(V0, W0), duration=1.0, dt=dt, depth_of_cut=doc)
    assert np.max(np.abs(r0["bit_angular_velocity"] / W0 - 1)) > 0.5


def test_steady_deflection_of_the_4th_order_model_is_the_hand_value():
    m = lumped_model("table_2_1", order=4)
    p = get_preset("table_2_1").string
    plant = DirectionalPlant(m)
    plant.reset(start="steady", set_point={"top_drive_axial_velocity": V0,
                                           "top_drive_angular_velocity": W0})
    wob, tob = _hand_bit_forces(2 * math.pi * V0 / W0, V0, W0)
    # spring to the top drive (at 0) carries the bit force and the absolute damping
    assert plant.node_fields()["axial_position"][0] == pytest.approx(-(wob + p.axial_damping * V0) / p.axial_stiffness,
                                           rel=1e-12)
    assert plant.node_fields()["angle"][0] == pytest.approx(-(tob + p.torsional_damping * W0)
                                           / p.torsional_stiffness, rel=1e-12)
    # the plant keeps it, step after step, under the same command
    for _ in range(2000):
        obs = plant.step({"top_drive_axial_velocity": V0, "top_drive_angular_velocity": W0})
    assert obs["bit_angular_velocity"] == pytest.approx(W0, rel=1e-6)
    assert obs["wob"] == pytest.approx(wob, rel=1e-6)


def test_off_bottom_start_rotates_freely_until_the_bit_tags_bottom():
    m = lumped_model("table_2_1", order=4)
    clearance = 0.005  # 0.5 s at 10 mm/s
    r = simulate(m, SurfaceInputs.velocity(V0, W0), duration=1.0, dt=5e-4, start="off_bottom",
                 clearance=clearance)
    t = r.time
    before = t < 0.9 * clearance / V0
    assert np.all(r["wob"][before] == 0.0) and np.all(r["tob"][before] == 0.0)
    assert np.max(np.abs(r["bit_angular_velocity"][before] / W0 - 1)) < 1e-9
    assert np.max(r["wob"][t > 1.1 * clearance / V0]) > 1e3  # it cuts once on bottom


def test_start_errors_are_precise():
    m = lumped_model("table_2_1", order=4)
    with pytest.raises(DownholeInputError, match="start must be one of"):
        simulate(m, duration=1.0, start="flying")
    with pytest.raises(DownholeInputError, match="positive angular set-point"):
        simulate(m, SurfaceInputs.velocity(0.01, 0.0), duration=1.0, start="steady")
    with pytest.raises(DownholeInputError, match="velocity-driven"):
        DirectionalPlant(m, mode="force").reset(start="steady")
    plant = DirectionalPlant(m)
    with pytest.raises(DownholeInputError, match="not commands"):
        plant.reset(start="steady", set_point={"wob": 1.0})
    with pytest.raises(DownholeInputError, match="clearance"):
        plant.reset(start="off_bottom", clearance=-1.0)


def test_plant_refuses_bad_commands_without_applying_them():
    plant = DirectionalPlant(lumped_model("table_2_1", order=4))
    plant.reset(start="steady", set_point={"top_drive_axial_velocity": V0,
                                           "top_drive_angular_velocity": W0})
    before = plant.node_fields()
    for bad in (math.nan, math.inf, 1e300):
        with pytest.raises(DownholeInputError, match="command refused"):
            plant.step({"top_drive_axial_velocity": V0, "top_drive_angular_velocity": bad})
    with pytest.raises(DownholeInputError, match="lacks"):
        plant.step({"top_drive_axial_velocity": V0})
    after = plant.node_fields()
    assert all(np.array_equal(after[k], before[k]) for k in before)
    assert isinstance(plant, Plant) and START_MODES == ("rest", "off_bottom", "steady")
