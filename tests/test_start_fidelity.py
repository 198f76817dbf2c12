"""``start = "rest" | "off_bottom" | "steady"`` at the distributed fidelities (neutral, FEM,
hybrid), checked against hand values of the bit law and of the string's static balance."""

import math

import numpy as np
import pytest

from downhole.errors import DownholeInputError
from downhole.sim import simulate
from downhole.sim.plant import Plant
from downhole.string.fem import DirectionalPlant
from downhole.string.neutral import NOMINAL_U_A, NOMINAL_U_T, neutral_model


def _hand_bit_forces(bit, d, v, omega):
    """Eqs. 2.2-2.8 (corrected) written out for d >= d*, v > 0, omega > omega_reg."""
    a = bit.radius
    wf = bit.sigma * bit.wear_length * a / (1.0 + math.exp(bit.a1 * v + bit.b1))
    if bit.friction_law == "constant":
        mugam = bit.mu_gamma
    else:
        mugam = bit.gamma * (bit.mu_c + (bit.mu_s - bit.mu_c)
                             * math.exp(-bit.gamma_b / bit.v_f * omega))
    wob = bit.zeta * bit.epsilon * a * d + wf
    tob = 0.5 * bit.epsilon * a * a * d + 0.5 * mugam * a * math.tanh(
        bit.a2 * omega + bit.b2) * wf
    return wob, tob


# ------------------------------------------------------------------------------ neutral
@pytest.fixture(scope="module")
def nmodel():
    return neutral_model("table_3_1")


@pytest.mark.parametrize("doc", ["delayed", "approximate"])
def test_neutral_steady_start_is_an_equilibrium(nmodel, doc):
    m, p = nmodel, nmodel.params
    r = simulate(m, duration=1.0, dt=1e-4, inputs=(NOMINAL_U_A, NOMINAL_U_T),
                         depth_of_cut=doc, start="steady")
    v, w = r["bit_axial_velocity"], r["bit_angular_velocity"]
    # SPEC: the nominal commands give 10 mm/s and 20 rad/s; the bit stays there
    assert v[0] == pytest.approx(0.01, rel=1e-4) and w[0] == pytest.approx(20.0, rel=1e-4)
    assert np.max(np.abs(v / 0.01 - 1)) < 0.01 and np.max(np.abs(w / 20.0 - 1)) < 0.01
    d0 = 2 * math.pi * v[0] / w[0]
    wob, tob = _hand_bit_forces(m.bit, d0, v[0], w[0])
    assert r["depth_of_cut"][0] == pytest.approx(d0, rel=1e-9)
    assert r["wob"][0] == pytest.approx(wob, rel=1e-9)
    assert r["tob"][0] == pytest.approx(tob, rel=1e-9)
    # the steady balance of Eq. 3.9: v = U_A - (W + M_S g)/alpha_A, omega = U_T - T/alpha_T
    assert v[0] == pytest.approx(NOMINAL_U_A - (wob + p.string_mass * p.g) / p.alpha_axial,
                                 rel=1e-9)
    assert w[0] == pytest.approx(NOMINAL_U_T - tob / p.alpha_torsional, rel=1e-9)
    # no wall contact and no damping along the line: surface torque = TOB; hook load =
    # buoyed weight (M_S + M_B) g minus WOB
    assert r["surface_torque"][0] == pytest.approx(tob, rel=1e-9)
    assert r["hook_load"][0] == pytest.approx((p.string_mass + p.bit_mass) * p.g - wob,
                                              rel=1e-9)
    assert np.max(np.abs(r["surface_torque"] / tob - 1)) < 0.01
    # from rest the same commands are far from the steady state at first
    r0 = simulate(m, duration=1.0, dt=1e-4, inputs=(NOMINAL_U_A, NOMINAL_U_T),
                          depth_of_cut=doc)
    assert np.max(np.abs(r0["bit_angular_velocity"] / 20.0 - 1)) > 0.5


def test_neutral_plant_steady_and_off_bottom(nmodel):
    m = nmodel
    sp = {"top_drive_axial_velocity": NOMINAL_U_A - m.hang_command,
          "top_drive_angular_velocity": NOMINAL_U_T}
    plant = DirectionalPlant(m, dt=2e-4)
    assert isinstance(plant, Plant)
    assert plant.default_command() == {"top_drive_axial_velocity": 0.0,
                                       "top_drive_angular_velocity": 0.0}
    obs = plant.reset(start="steady", set_point=sp)
    w0 = obs["bit_angular_velocity"]
    for _ in range(5000):  # 1 s
        obs = plant.step(sp)
        assert abs(obs["bit_angular_velocity"] / w0 - 1) < 0.01
    assert obs["bit_axial_velocity"] == pytest.approx(0.01, rel=0.01)
    # off bottom: the string moves at the commands (no bit force, so v = U_A - M_S g/alpha_A)
    clearance = 0.01
    obs = plant.reset(start="off_bottom", set_point=sp, clearance=clearance)
    v0 = sp["top_drive_axial_velocity"]
    assert obs["bit_axial_velocity"] == pytest.approx(v0, rel=1e-12)
    assert obs["bit_angular_velocity"] == pytest.approx(NOMINAL_U_T, rel=1e-12)
    t_tag = clearance / v0
    tag = None
    for k in range(int(1.5 * t_tag / plant.dt)):
        obs = plant.step(sp)
        if obs["wob"] > 0:
            tag = obs["time"]
            break
        assert obs["tob"] == 0.0 and abs(obs["bit_axial_velocity"] / v0 - 1) < 1e-9
    assert tag == pytest.approx(t_tag, rel=0.01)  # zero bit force until the bit tags bottom
    # rest is the seed's start whatever the set-point
    obs = plant.reset(start="rest", set_point=sp)
    assert obs["bit_axial_velocity"] == 0.0 and obs["wob"] == 0.0


def test_neutral_start_errors_are_precise(nmodel):
    plant = DirectionalPlant(nmodel, dt=2e-4)
    with pytest.raises(DownholeInputError, match="positive angular set-point"):
        plant.reset(start="steady", set_point={"top_drive_axial_velocity": 0.01})
    with pytest.raises(DownholeInputError, match="no steady drilling state"):
        plant.reset(start="steady", set_point={"top_drive_axial_velocity": -0.5,
                                               "top_drive_angular_velocity": 20.0})
    with pytest.raises(DownholeInputError, match="clearance"):
        plant.reset(start="off_bottom", clearance=0.0)
    with pytest.raises(DownholeInputError, match="start must be one of"):
        plant.reset(start="hovering")
    with pytest.raises(DownholeInputError, match="command refused"):
        plant.step({"top_drive_axial_velocity": math.nan, "top_drive_angular_velocity": 1.0})
    from downhole.control.eid.controller import EIDController

    with pytest.raises(DownholeInputError, match="open-loop"):
        simulate(nmodel, duration=0.01, controller=EIDController((), ()),
                         start="steady")


# ------------------------------------------------------------------------------ FEM, hybrid
def _directional(kind):
    from downhole.string.fem import fem_model
    from downhole.string.hybrid import hybrid_model

    return fem_model(n_elements=23) if kind == "fem" else hybrid_model("hybrid24")


def _hand_drags(m, u, v, w):
    """Wall friction (soft string, N from the element tensions) and damping C 1 (v, omega) per
    node, summed by hand: axial drag forces and resisting torques (positive)."""
    from downhole.contact.softstring import element_normal_half

    n = m.n_nodes
    nrm = np.zeros(n)
    for e in range(n - 1):
        if m.elem[e, 7] > 0.5:
            half = element_normal_half(m.elem, e, -m.Ka[1, e] * (u[e + 1] - u[e]))
            nrm[e] += half
            nrm[e + 1] += half
    c = m.mu * nrm / np.sqrt(v ** 2 + (m.radius * w) ** 2 + m.v_eps ** 2)

    def c_ones(T):
        out = T[0].copy()
        out[:-1] += T[1, :-1]
        out[1:] += T[1, :-1]
        return out
    return c * v + c_ones(m.Ca) * v, c * m.radius ** 2 * w + c_ones(m.Ct) * w


@pytest.mark.parametrize("kind", ["fem", "hybrid"])
@pytest.mark.parametrize("doc", ["delayed", "approximate"])
def test_directional_steady_start_stays_for_a_second(kind, doc):
    from downhole.params.rig import Hook, TopDrive
    from downhole.sim import simulate

    m = _directional(kind)
    for hook in (Hook(), Hook(mode="velocity", velocity=0.01)):
        r = simulate(m, duration=1.0, dt=1e-3, top_drive=TopDrive(speed=20.0),
                                 hook=hook, depth_of_cut=doc, start="steady", record_dt=None)
        v, w = r["bit_axial_velocity"], r["bit_angular_velocity"]
        assert w[0] == pytest.approx(20.0, rel=1e-9)
        if hook.mode == "velocity":
            assert v[0] == pytest.approx(0.01, rel=1e-9)
        assert np.max(np.abs(v / v[0] - 1)) < 0.01 and np.max(np.abs(w / 20.0 - 1)) < 0.01
        d0 = 2 * math.pi * v[0] / w[0]
        wob, tob = _hand_bit_forces(m.bit, d0, v[0], w[0])
        assert r["depth_of_cut"][0] == pytest.approx(d0, rel=1e-9)
        assert r["wob"][0] == pytest.approx(wob, rel=1e-9)
        assert r["tob"][0] == pytest.approx(tob, rel=1e-9)
        assert r.attrs["start"] == "steady"


@pytest.mark.parametrize("kind", ["fem", "hybrid"])
@pytest.mark.parametrize("hook_mode", ["force", "velocity"])
def test_directional_steady_balance_by_hand(kind, hook_mode):
    from downhole.params.rig import Hook, TopDrive
    from downhole.string.fem import DirectionalPlant

    m = _directional(kind)
    hook = Hook() if hook_mode == "force" else Hook(mode="velocity", velocity=0.01)
    plant = DirectionalPlant(m, 1e-3, top_drive=TopDrive(speed=20.0), hook=hook,
                             depth_of_cut="approximate")
    sp = dict(plant.default_command(), top_drive_angular_velocity=20.0)
    obs = plant.reset(start="steady", set_point=sp)
    f = plant.node_fields()
    v, w = obs["bit_axial_velocity"], obs["bit_angular_velocity"]
    assert np.allclose(f["axial_velocity"], v) and np.allclose(f["angular_velocity"], w)
    wob, tob = _hand_bit_forces(m.bit, 2 * math.pi * v / w, v, w)
    assert obs["wob"] == pytest.approx(wob, rel=1e-9)
    da, dt_ = _hand_drags(m, f["axial_position"], v, w)
    assert dt_[1:].sum() > 0.05 * tob  # the wall friction matters in this well
    # surface torque (the first element's elastic torque) = TOB + friction and damping torque
    # of every node below the top drive
    assert obs["surface_torque"] == pytest.approx(tob + dt_[1:].sum(), rel=1e-6)
    # hook load = buoyed weight - WOB - axial drag; a force-driven hook sets it and the ROP
    # follows from the bit law at the WOB that is left
    assert obs["hook_load"] == pytest.approx(m.buoyed_weight - wob - da.sum(), rel=1e-9)
    if hook_mode == "force":
        assert obs["hook_load"] == pytest.approx(sp["hook_load"], rel=1e-12)
        assert 0.001 < v < 0.2
    for _ in range(200):
        obs = plant.step(sp)
    assert obs["bit_axial_velocity"] == pytest.approx(v, rel=1e-6)
    assert obs["surface_torque"] == pytest.approx(tob + dt_[1:].sum(), rel=1e-6)


@pytest.mark.parametrize("kind", ["fem", "hybrid"])
def test_directional_off_bottom_until_the_bit_tags(kind):
    from downhole.params.rig import Hook, TopDrive
    from downhole.string.fem import DirectionalPlant

    m = _directional(kind)
    plant = DirectionalPlant(m, 1e-3, top_drive=TopDrive(speed=20.0),
                             hook=Hook(mode="velocity", velocity=0.01))
    sp = plant.default_command()
    clearance = 0.002
    obs = plant.reset(start="off_bottom", set_point=sp, clearance=clearance)
    assert obs["wob"] == 0.0 and obs["bit_angular_velocity"] == pytest.approx(20.0)
    tag = None
    for _ in range(400):
        obs = plant.step(sp)
        if obs["wob"] > 0:
            tag = obs["time"]
            break
        assert obs["tob"] == 0.0
        assert abs(obs["bit_axial_velocity"] / 0.01 - 1) < 1e-6
        assert abs(obs["bit_angular_velocity"] / 20.0 - 1) < 1e-6
    assert tag == pytest.approx(clearance / 0.01, abs=2e-3)


def test_directional_start_errors_are_precise():
    from downhole.params.rig import Hook, TopDrive
    from downhole.string.fem import DirectionalPlant

    m = _directional("fem")
    force = DirectionalPlant(m, 1e-3)
    with pytest.raises(DownholeInputError, match="off bottom nothing but drag"):
        force.reset(start="off_bottom")
    with pytest.raises(DownholeInputError, match="no steady drilling state under hook_load"):
        force.reset(start="steady", set_point={"hook_load": 2 * m.buoyed_weight})
    with pytest.raises(DownholeInputError, match="positive top-drive speed"):
        force.reset(start="steady", set_point={"top_drive_angular_velocity": 0.0})
    p_only = DirectionalPlant(m, 1e-3, top_drive=TopDrive(ki=0.0))
    with pytest.raises(DownholeInputError, match="integral gain"):
        p_only.reset(start="steady")
    vel = DirectionalPlant(m, 1e-3, hook=Hook(mode="velocity", velocity=0.01))
    with pytest.raises(DownholeInputError, match="clearance"):
        vel.reset(start="off_bottom", clearance=-0.1)
    with pytest.raises(DownholeInputError, match="lacks"):
        vel.step({"top_drive_angular_velocity": 10.0})


def test_directional_steady_under_a_torque_driven_top_drive():
    """Torque-driven top drive: omega follows from T_surface = TOB(2 pi v/omega) + drag torque.
    (With a force hook too, TOB hardly depends on omega at a fixed WOB and the balance is
    nearly degenerate: no steady rotation below 100 rad/s for most torques.)"""
    from downhole.params.rig import Hook, TopDrive
    from downhole.string.fem import DirectionalPlant

    m = _directional("hybrid")
    plant = DirectionalPlant(m, 1e-3, top_drive=TopDrive(mode="torque", speed=16e3),
                             hook=Hook(mode="velocity", velocity=0.01),
                             depth_of_cut="approximate")
    obs = plant.reset(start="steady")
    v, w = obs["bit_axial_velocity"], obs["bit_angular_velocity"]
    assert v > 0 and w > 0
    f = plant.node_fields()
    da, dt_ = _hand_drags(m, f["axial_position"], v, w)
    assert v == pytest.approx(0.01, rel=1e-12) and 5.0 < w < 100.0
    assert obs["tob"] + dt_.sum() == pytest.approx(16e3, rel=1e-9)
    assert obs["wob"] + da.sum() == pytest.approx(m.buoyed_weight - obs["hook_load"], rel=1e-9)
    for _ in range(500):
        obs = plant.step(plant.default_command())
    assert obs["bit_angular_velocity"] == pytest.approx(w, rel=1e-6)
    with pytest.raises(DownholeInputError, match="no steady rotation"):
        plant.reset(start="steady", set_point={"surface_torque": 1.0})


@pytest.mark.parametrize("model", ["neutral", "lumped", "hybrid24"])
def test_sil_adapter_starts_every_fidelity_through_the_contract(model):
    from downhole.sil.plants import build_plant

    kw = {"interface": "surface", "top_drive_speed": 20.0} if model != "lumped" else {}
    sp = build_plant(model, dt=1e-3 if model != "lumped" else 1e-4, **kw)
    cmd = sp.default_command()
    if model == "lumped":
        cmd = {"top_drive_axial_velocity": 0.01, "top_drive_angular_velocity": 20.0}
    obs = sp.reset(start="steady", set_point=cmd)
    w0 = obs["bit_angular_velocity"]
    assert w0 > 1.0 and obs["wob"] > 0
    for _ in range(200):
        obs = sp.step(cmd)
    assert obs["bit_angular_velocity"] == pytest.approx(w0, rel=0.01)
    assert sp.reset()["time"] == 0.0  # and back to rest
