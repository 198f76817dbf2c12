"""Neutral-type model (wave segment + bit + top damper) against independent references."""

import math

import numpy as np
import pytest

from downhole.errors import DownholeInputError
from downhole.params import NeutralStringParams, PipeSection
from downhole.sim import simulate
from downhole.string._reference_fd import simulate_fd
from downhole.string.neutral import NOMINAL_U_A, NOMINAL_U_T, neutral_model


def _rel_rms(ref, val):
    return float(np.sqrt(np.mean((val - ref) ** 2)) / np.max(np.abs(ref)))


@pytest.fixture(scope="module")
def model():
    return neutral_model("table_3_1")


@pytest.fixture(scope="module")
def wave_run(model):
    return simulate(model, duration=10.0, dt=1e-4, record_dt=1e-3)


def test_agrees_with_fine_finite_differences_and_converges(model, wave_run):
    # Done-means: within 1 % (RMS over peak) of a >= 1000-element discretization of Eqs. 3.1-3.6
    # over 10 s, nominal open loop, and the error falls as the discretization is refined.
    errs = {}
    for n in (250, 1000):
        fd = simulate_fd(model, n, 10.0, NOMINAL_U_A, NOMINAL_U_T, depth_of_cut="delayed")
        k = min(len(fd["time"]), len(wave_run.time))
        assert np.allclose(fd["time"][:k], wave_run.time[:k])
        errs[n] = [_rel_rms(wave_run[c][:k], fd[c][:k])
                   for c in ("bit_axial_velocity", "bit_angular_velocity")]
    assert max(errs[1000]) < 0.01
    assert errs[1000][0] < 0.6 * errs[250][0] and errs[1000][1] < 0.6 * errs[250][1]


def test_open_loop_steady_state_formula(model, wave_run):
    # v = U_A - (W + M_S g)/alpha_A and Omega = U_T - T/alpha_T (Eq. 3.9 at rest)
    p = model.params
    late = wave_run.time > 8.0
    v = wave_run["bit_axial_velocity"][late].mean()
    w = wave_run["bit_angular_velocity"][late].mean()
    wob = wave_run["wob"][late].mean()
    tob = wave_run["tob"][late].mean()
    assert v == pytest.approx(NOMINAL_U_A - (wob + p.string_mass * p.g) / p.alpha_axial, abs=1e-6)
    assert w == pytest.approx(NOMINAL_U_T - tob / p.alpha_torsional, rel=1e-5)
    # docs/seed-errata.md: the nominal commands give 10 mm/s and 20 rad/s
    assert v == pytest.approx(0.010, rel=1e-3)
    assert w == pytest.approx(20.0, rel=1e-3)
    # hook load = total weight minus WOB, surface torque = TOB at steady state
    assert wave_run["hook_load"][-1] == pytest.approx((p.string_mass + p.bit_mass) * p.g - wob,
                                                      rel=1e-6)
    assert wave_run["surface_torque"][-1] == pytest.approx(tob, rel=1e-5)


def test_gamma_upsilon_match_spec_with_table_3_1_printed_a_and_j():
    # The reference values were computed with Table 3.1's printed A = 8.5e-3 m^2 and J = 1.9e-5 m^4
    # and the corrected delays; Gamma2 (1 + Gamma1) = Gamma3 exactly.
    m = neutral_model(NeutralStringParams(), None)
    p = m.params
    za = 8.5e-3 * math.sqrt(p.pipe.density * p.pipe.young_modulus)
    zt = 1.9e-5 * math.sqrt(p.pipe.density * p.pipe.shear_modulus)
    g = ((p.alpha_axial - za) / (p.alpha_axial + za), za / p.bit_mass,
         2 * p.alpha_axial * za / (p.bit_mass * (p.alpha_axial + za)))
    u = ((p.alpha_torsional - zt) / (p.alpha_torsional + zt), zt / p.bit_inertia,
         2 * p.alpha_torsional * zt / (p.bit_inertia * (p.alpha_torsional + zt)))
    assert g == pytest.approx((0.268586, 11.5312, 14.6283), rel=2e-5)
    assert u == pytest.approx((0.255837, 7.02298, 8.81971), rel=2e-5)
    # the model's own coefficients (A and J from the diameters) follow the same formulas
    g1, g2, g3 = m.gammas
    assert g3 == pytest.approx(g2 * (1 + g1), rel=1e-12)
    assert g1 == pytest.approx(0.268586, rel=5e-3) and m.upsilons[0] == pytest.approx(0.255837,
                                                                                       rel=1e-2)
    assert m.tau1 == pytest.approx(0.19288, abs=1e-5) and m.tau2 == pytest.approx(0.31463,
                                                                                  abs=1e-5)


def test_ndde_matrices_steady_gain(model):
    # DC gain of Eq. 3.13 from u to x is 1 in both channels: -(A0 + A1) = B
    nd = model.ndde()
    assert np.allclose(-(nd.A0 + nd.A1 + nd.A2), nd.B)
    assert nd.h1 == pytest.approx(2 * model.tau1)
    assert nd.u_offset[0] == pytest.approx(model.params.string_mass * 9.81 / 6e5)


def test_hanging_at_rest_stays_at_rest(model):
    r = simulate(model, duration=1.0, dt=1e-4, inputs=(model.hang_command, 0.0))
    assert np.max(np.abs(r["bit_axial_velocity"])) < 1e-12
    assert np.max(np.abs(r["wob"])) == 0.0


def test_bad_inputs_are_named():
    with pytest.raises(DownholeInputError, match="dt"):
        simulate(neutral_model("table_3_1"), duration=1.0, dt=0.5)
    with pytest.raises(DownholeInputError, match="depth_of_cut"):
        simulate(neutral_model("table_3_1"), duration=1.0, depth_of_cut="exact")
    with pytest.raises(DownholeInputError, match="neutral"):
        neutral_model("table_2_1")
    with pytest.raises(DownholeInputError, match="noise"):
        simulate(neutral_model("table_3_1"), duration=0.01, noise={"rop": 1.0})
    with pytest.raises(ValueError):
        NeutralStringParams(length=-5.0)
    with pytest.raises(ValueError):
        NeutralStringParams(pipe=PipeSection(outer_diameter=0.1, inner_diameter=0.2))


def test_plant_steps_like_the_compiled_run(model):
    # the plant (reset/step over named signals) is the same kernel stepped from Python
    from downhole.string.fem import DirectionalPlant

    ref = simulate(model, duration=0.5, dt=2e-4, record_dt=2e-4)
    plant = DirectionalPlant(model, dt=2e-4)
    obs = plant.reset()
    assert obs["wob"] == 0.0 and obs["time"] == 0.0
    vs = [obs["bit_axial_velocity"]]
    for _ in range(2500):
        obs = plant.step({"top_drive_axial_velocity": NOMINAL_U_A - model.hang_command,
                          "top_drive_angular_velocity": NOMINAL_U_T})
        vs.append(obs["bit_axial_velocity"])
    assert obs["time"] == pytest.approx(0.5)
    # the relative command (U_A - M_S g / alpha_A) is added back in floating point
    assert np.allclose(np.array(vs), ref["bit_axial_velocity"], rtol=1e-9, atol=1e-12)
    with pytest.raises(DownholeInputError, match="top_drive_angular_velocity"):
        plant.step({"top_drive_axial_velocity": 0.01})


class _PI:
    """A plain PI controller on the bit velocities (not an EID): integral action must remove the
    steady-state error, whatever the plant's static gain."""

    def __init__(self, model):
        self.m = model

    def reset(self):
        self.i = np.zeros(2)
        self.t = None

    def command(self, t, obs, reference):
        r = np.array([reference["reference_axial_velocity"],
                      reference["reference_angular_velocity"]])
        e = r - np.array([obs["bit_axial_velocity"], obs["bit_angular_velocity"]])
        dt = 0.0 if self.t is None else t - self.t
        self.t = t
        self.i += e * dt
        u = np.array([0.1, 0.1]) * e + np.array([1.0, 0.5]) * self.i
        return {"top_drive_axial_velocity": u[0], "top_drive_angular_velocity": u[1]}


def test_python_loop_runs_any_controller(model):
    res = simulate(model, duration=40.0, dt=2e-4, controller=_PI(model),
                           reference=(0.01, 20.0), control_dt=1e-3, depth_of_cut="approximate")
    t = res.time
    assert res.attrs["controller"] == "_PI" and res.attrs["control_dt"] == pytest.approx(1e-3)
    assert np.abs(res["bit_axial_velocity"][t > 35] - 0.01).max() < 1e-4
    assert np.abs(res["bit_angular_velocity"][t > 35] - 20.0).max() < 0.02
    # the command the controller returned is what drove the plant (open-loop check)
    ol = simulate(model, duration=40.0, dt=2e-4, depth_of_cut="approximate",
                          inputs=((t, res["command_axial"]), (t, res["command_angular"])),
                          record_dt=float(t[1] - t[0]))
    assert np.abs(ol["bit_angular_velocity"] - res["bit_angular_velocity"]).max() < 0.05
