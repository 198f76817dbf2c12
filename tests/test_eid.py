"""EID controller: LMI certificate, closed-loop roots (input delay included), true-plant runs."""

import warnings

import numpy as np
import pytest

from downhole.control.eid import ChannelGains, LMIInfeasible, design_eid, load_eid
from downhole.control.eid.design import synthesize_channel
from downhole.control.eid.stability import closed_loop_stability
from downhole.sim import simulate
from downhole.string.neutral import neutral_model

warnings.filterwarnings("ignore", category=UserWarning)


@pytest.fixture(scope="module")
def model():
    return neutral_model("table_3_1")


@pytest.fixture(scope="module")
def ctrl(model):
    return design_eid(model)


def test_lmi_strictly_negative_with_margins(ctrl):
    for rep in ctrl.reports:
        assert rep.status == "optimal"
        assert rep.lmi_max_eigenvalue < -1e-4
        assert all(v > 0 for v in rep.min_eigenvalues.values())


def test_closed_loop_with_input_delay_is_stable_and_printed_design_is_not(model, ctrl):
    rep = closed_loop_stability(ctrl, model)
    assert rep.stable and max(rep.spectral_abscissa.values()) < 0
    assert rep.difference_operator_radius["axial"] < 1
    # the printed structure (observer driven by u(t), no predictor) with the seed's gains on the
    # plant with its input delay has roots in the right half plane (docs/seed-errata.md, Ch. 3)
    from dataclasses import replace

    seed = replace(ctrl, gains=(ChannelGains(0.4735, 0.0, 199.3022, 1.0, 200.0),
                                ChannelGains(0.7008, 0.0, 357.6114, 0.05, 100.0)),
                   predictor=False, delayed_input_observer=False)
    bad = closed_loop_stability(seed, model)
    assert max(bad.spectral_abscissa.values()) > 1.0


def test_root_finder_against_a_known_scalar_dde():
    # x' = -x(t - 1): rightmost roots solve s = -exp(-s), s = -0.3181 +/- 1.3372 i (Lambert W)
    from downhole.control.eid.stability import characteristic_roots

    z = np.zeros((1, 1))
    r = characteristic_roots(z, -np.eye(1), z, z, 1.0, n_nodes=30, max_imag=20)
    assert r[0].real == pytest.approx(-0.318132, abs=1e-5)
    assert abs(r[0].imag) == pytest.approx(1.337236, abs=1e-5)


def test_true_plant_regulation_and_saved_gains(model, ctrl, tmp_path):
    ctrl.save(tmp_path)
    c2 = load_eid(tmp_path)
    assert c2.gains == ctrl.gains
    res = simulate(model, duration=60.0, dt=2e-4, controller=c2)
    t = res.time
    v, w = res["bit_axial_velocity"], res["bit_angular_velocity"]
    assert np.max(np.abs(v[t >= 10] - 0.01)) < 0.01 * 0.01
    assert np.max(np.abs(w[t >= 40] - 20.0)) < 0.02 * 20.0
    g = np.load(tmp_path / "eid_gains.npz")
    assert np.allclose(g["A_F"], -g["B_F"])  # F(s) = bf/(s + bf): unit DC gain


def test_python_command_matches_compiled_loop(model, ctrl):
    ctrl.dt = 1e-3
    ctrl.reset()
    u = ctrl.command(0.0, {"bit_axial_velocity": 0.0, "bit_angular_velocity": 0.0})
    # the Plant contract's axial command is relative to the hanging equilibrium: 0 at rest
    assert u["top_drive_axial_velocity"] == pytest.approx(0.0, abs=1e-12)
    u = ctrl.command(1e-3, {"bit_axial_velocity": 0.0, "bit_angular_velocity": 0.0},
                     {"reference_axial_velocity": 0.01, "reference_angular_velocity": 20.0})
    assert u["top_drive_axial_velocity"] > 0.0  # integrator pushes towards 10 mm/s


def test_infeasible_lmi_names_the_family(model):
    ch = model.ndde().channel(0)
    with pytest.raises(LMIInfeasible, match="constraint family"):
        synthesize_channel(ch, "axial", br=1.0, bf=2.0, observer_gain=4.0, gain_bound=1e-9)
    bad = dict(ch, g1=1.2)
    with pytest.raises(Exception, match=r"\|G\| = 1.2"):
        synthesize_channel(bad, "axial", br=1.0, bf=2.0, observer_gain=4.0)


def test_python_loop_eid_equals_compiled(model, ctrl):
    # the controller stepped from Python over the neutral plant gives the compiled loop's numbers
    kw = dict(duration=2.0, dt=2e-4, controller=ctrl, noise={"axial": 1e-3, "angular": 1.0})
    a = simulate(model, **kw)
    b = simulate(model, python_loop=True, **kw)
    for ch in ("bit_axial_velocity", "bit_angular_velocity", "command_axial", "hook_load"):
        # equal up to the rounding of U_A - M_S g/alpha_A + M_S g/alpha_A in the Python path
        assert np.allclose(a[ch], b[ch], rtol=1e-9, atol=1e-9 * np.abs(a[ch]).max()), ch


def test_eid_runs_through_the_controller_contract_on_the_neutral_plant(model, ctrl):
    # the generic runner (controller.dt set to the plant step, mapping references, the Plant
    # contract's relative axial command) reproduces the compiled closed loop
    from downhole.control.base import check_pair, run_closed_loop
    from downhole.string.fem import DirectionalPlant

    a = simulate(model, duration=1.0, dt=2e-4, controller=ctrl, record_dt=2e-4)
    plant = DirectionalPlant(model, 2e-4)
    assert check_pair(ctrl, plant) is None
    r = run_closed_loop(plant, ctrl, 1.0, reference={"reference_axial_velocity": 0.01,
                                                     "reference_angular_velocity": 20.0})
    assert ctrl.dt == pytest.approx(2e-4)
    for ch in ("bit_axial_velocity", "bit_angular_velocity"):
        assert np.allclose(r[ch], a[ch], rtol=1e-9, atol=1e-9 * np.abs(a[ch]).max()), ch
    assert np.abs(r["bit_angular_velocity"]).max() > 5.0  # it did spin the string up


def test_compiled_loop_in_pieces_gives_the_same_numbers(model, ctrl, monkeypatch):
    """The compiled closed loop runs in pieces (Python runs between them, so Ctrl-C acts): a
    piece length that is not a multiple of the record step changes no number."""
    from downhole.control.eid import neutral_runner

    whole = simulate(model, controller=ctrl, duration=0.5, dt=1e-4, record_dt=1e-3,
                     noise={"axial": 1e-4, "angular": 0.05})
    monkeypatch.setattr(neutral_runner, "PIECE", 777)
    pieces = simulate(model, controller=ctrl, duration=0.5, dt=1e-4, record_dt=1e-3,
                      noise={"axial": 1e-4, "angular": 0.05})
    for name in whole.channels:
        np.testing.assert_array_equal(pieces[name], whole[name], err_msg=name)
