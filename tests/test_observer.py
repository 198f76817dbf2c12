"""Surface observers (downhole.control.observer): the Kalman filter against a closed form, error
convergence on the linear design models (eigenvalues and simulation), recovery of constant bit
forces, the controller wrapper's contract and its refusals, and (slow) EID and DHP fed from the
surface only."""

from __future__ import annotations

import math

import numpy as np
import pytest

from downhole.control.observer import (
    DEFAULT_SURFACE_NOISE,
    FEM_MEASUREMENTS,
    NEUTRAL_MEASUREMENTS,
    KalmanObserver,
    MeasurementNoise,
    NeutralSurfaceObserver,
    SurfaceFeedback,
    bit_law_jacobian,
    eid_from_surface,
    fem_surface_observer,
    steady_state_gain,
)
from downhole.errors import DownholeInputError
from downhole.signals import SIGNALS


@pytest.fixture(scope="module")
def fem24():
    from downhole.string.hybrid import hybrid_model

    return hybrid_model("hybrid24").design_model()


@pytest.fixture(scope="module")
def neutral():
    from downhole.string.neutral import neutral_model

    return neutral_model("table_3_1")


# ------------------------------------------------------------------------ the filter itself
def test_scalar_gain_matches_the_closed_form_riccati_solution():
    # x+ = a x + w, y = x + v: P = a^2 P r / (P + r) + q, i.e. P^2 + P (r - a^2 r - q) - q r = 0
    a, q, r = 0.95, 0.3, 2.0
    K, P = steady_state_gain([[a]], [[1.0]], [[q]], [[r]])
    b = r - a * a * r - q
    p_exact = 0.5 * (-b + math.sqrt(b * b + 4 * q * r))
    assert P[0, 0] == pytest.approx(p_exact, rel=1e-10)
    assert K[0, 0] == pytest.approx(p_exact / (p_exact + r), rel=1e-10)


def test_refusals_of_the_gain():
    with pytest.raises(DownholeInputError, match="positive definite"):
        steady_state_gain([[0.9]], [[1.0]], [[1.0]], [[0.0]])
    with pytest.raises(DownholeInputError, match="shape"):
        steady_state_gain(np.eye(2), np.ones((1, 3)), np.eye(2), [[1.0]])
    with pytest.raises(DownholeInputError, match="non-finite"):
        steady_state_gain([[np.nan]], [[1.0]], [[1.0]], [[1.0]])
    # an unstable mode the measurement does not see: no stabilizing filter exists
    with pytest.raises(DownholeInputError, match="detectable"):
        steady_state_gain(np.diag([1.2, 0.5]), [[0.0, 1.0]], np.eye(2), [[1.0]])


def test_fem_observer_error_converges_on_its_linear_model(fem24):
    kf = fem_surface_observer(fem24, 1e-3)
    n = kf.n_states
    assert n == fem24.n_states + 2
    # analytic: every eigenvalue of the error dynamics (I - K C) A inside the unit circle
    rho = kf.spectral_radius()
    assert rho < 1.0
    # simulate: the model itself with an input, a constant bit force ("rest" part) and a wrong
    # initial estimate; noise-free, the error must decay at least as fast as rho^k allows
    rng = np.random.default_rng(0)
    x = np.zeros(n)
    x[-2:] = [3.0e4, 2.0e3]              # constant WOB and TOB (the random-walk states)
    kf.reset()
    e0 = np.linalg.norm(kf.x - x)
    steps = 20000
    for _ in range(steps):
        u = np.array([1e5, 1e4]) * (1.0 + 0.1 * rng.standard_normal(2))
        x = kf.A @ x + kf.B @ u
        kf.update(kf.C @ x, u)
    err = np.abs(kf.x - x)
    assert np.linalg.norm(kf.x - x) < 1e-3 * e0
    # the disturbance estimates recover the constant bit forces
    assert err[-2] < 1e-3 * 3.0e4 and err[-1] < 1e-3 * 2.0e3


def test_fem_observer_names_and_bit_damper(fem24):
    kf = fem_surface_observer(fem24, 1e-3)
    assert kf.output_names == ("block_position", "top_drive_angle", "top_drive_axial_velocity",
                               "top_drive_angular_velocity")
    assert kf.state_names[-2:] == ("wob_rest", "tob_rest")
    # the axial damper is the bit law's slope at 10 mm/s, 20 rad/s (positive, ~2e6 N s/m)
    J = bit_law_jacobian(fem24.bit, 0.01, 20.0)
    assert kf.bit_jacobian[0, 0] == J[0, 0] > 1e6
    plain = fem_surface_observer(fem24, 1e-3, operating_point=None)
    assert np.all(plain.bit_jacobian == 0.0)
    with pytest.raises(DownholeInputError, match="unknown noise key"):
        fem_surface_observer(fem24, 1e-3, noise={"hookload": 1.0})
    with pytest.raises(DownholeInputError, match="positive"):
        fem_surface_observer(fem24, 1e-3, wob_rate=-1.0)


def test_fem_observer_friction_term_is_the_design_models_friction(fem24):
    """With the DHP design model the prediction adds its wellbore friction: the design model's
    forces less those of the same model without friction (its bit law), through the ZOH map."""
    from downhole.control.dhp.directional import directional_affine_model

    design = directional_affine_model(fem24)
    bare = directional_affine_model(fem24, friction=False)
    kf = fem_surface_observer(fem24, 1e-3, design=design)
    assert kf.nonlinear is not None
    assert fem_surface_observer(fem24, 1e-3).nonlinear is None
    n = fem24.n_nodes
    x = np.zeros(kf.n_states)
    assert np.allclose(kf.nonlinear(x), 0.0)          # at rest: no friction
    x[2 * n:4 * n:2] = 0.01                           # the whole string drilling at 10 mm/s,
    x[2 * n + 1:4 * n:2] = 20.0                       # 20 rad/s
    P = np.asarray(design.state_scale)
    z = (x[:4 * n] / P)[None, :]
    act = design.metadata["force_nodes"]
    assert act[-1] == n - 1 and bare.metadata["force_nodes"] == [n - 1]
    friction = np.asarray(design.forces(z), float)[0]
    friction[-2:] -= np.asarray(bare.forces(z), float)[0]     # less the bit law
    f_nodal = np.zeros(2 * n)
    for j, a in enumerate(act):
        f_nodal[2 * a:2 * a + 2] = friction[2 * j:2 * j + 2]
    h = kf.nonlinear(x)[:4 * n]
    assert np.any(f_nodal != 0.0)
    # over one short step a held force changes the velocities by dt M^-1 f (first order)
    _, _, _, Minv = fem24.continuous_linear_model()
    expected = 1e-3 * Minv @ f_nodal
    assert np.allclose(h[2 * n:], expected, rtol=0.05, atol=0.05 * np.abs(expected).max())
    # friction opposes the motion: it slows the rotation and the axial motion of the string
    assert h[2 * n + 1::2].sum() < 0 and h[2 * n::2].sum() < 0
    with pytest.raises(DownholeInputError, match="does not belong"):
        fem_surface_observer(hybrid_design_mismatch(), 1e-3, design=design)


def hybrid_design_mismatch():
    from downhole.string.hybrid import hybrid_model

    return hybrid_model("hybrid68").design_model(n_bc=4)


def test_bit_law_jacobian_against_the_law_and_refusals(neutral):
    from downhole.bit.law import approx_depth_of_cut, bit_forces

    p = neutral.bit.kernel_params()
    J = bit_law_jacobian(neutral.bit, 0.01, 20.0)
    # the approximated law is homogeneous of degree 0 in (v, omega) along the depth of cut:
    # WOB(v, w) depends on v/w only in the cutting part, so v dW/dv + w dW/dw = W - W_contact;
    # check instead against a one-sided difference of the law itself
    h = 1e-6
    w1 = bit_forces(approx_depth_of_cut(0.01 + h, 20.0, p), 0.01 + h, 20.0, p)[0]
    w0 = bit_forces(approx_depth_of_cut(0.01, 20.0, p), 0.01, 20.0, p)[0]
    assert J[0, 0] == pytest.approx((w1 - w0) / h, rel=1e-3)
    with pytest.raises(DownholeInputError, match="operating point"):
        bit_law_jacobian(neutral.bit, 0.0, 20.0)
    with pytest.raises(DownholeInputError, match="operating point"):
        bit_law_jacobian(neutral.bit, 0.01, float("nan"))


# ------------------------------------------------------------------------------ neutral
class _Recorder:
    """Inner controller of SurfaceFeedback for the tests: constant commands, records what it
    was given."""

    commands = ("top_drive_axial_velocity", "top_drive_angular_velocity")
    dt = 1e-3

    def __init__(self, u):
        self.u = dict(zip(self.commands, u, strict=True))
        self.seen = []

    def reset(self):
        self.seen = []

    def command(self, t, observation, reference=None):
        self.seen.append([observation[k] for k in ("bit_axial_velocity",
                                                   "bit_angular_velocity", "wob", "tob")])
        return dict(self.u)


def test_neutral_observer_filters_are_stable_and_sizes(neutral):
    obs = NeutralSurfaceObserver(neutral, 1e-3)
    assert obs.spectral_radius() < 1.0
    ax, to = obs.channels
    # the line read off the EID design model (Eq. 3.13) is the plant's line
    assert ax.Z == pytest.approx(neutral.axial.impedance, rel=1e-12)
    assert to.Z == pytest.approx(neutral.torsional.impedance, rel=1e-12)
    assert ax.alpha == pytest.approx(neutral.params.alpha_axial, rel=1e-12)
    assert to.alpha == pytest.approx(neutral.params.alpha_torsional, rel=1e-12)
    assert ax.D == pytest.approx(neutral.tau1 / 1e-3)
    with pytest.raises(DownholeInputError, match="exceeds the axial"):
        NeutralSurfaceObserver(neutral, 0.5)
    with pytest.raises(DownholeInputError, match="unknown noise key"):
        NeutralSurfaceObserver(neutral, 1e-3, noise={"wob": 1.0})


def test_neutral_observer_recovers_bit_velocities_and_forces_in_open_loop(neutral):
    """Constant commands on the true plant (delayed depth of cut): from rest the bit settles
    at 10 mm/s, 20 rad/s; the observer, seeing the surface only, converges to the bit's
    velocities and its (constant) WOB and TOB."""
    from downhole.sim import simulate
    from downhole.string.neutral import NOMINAL_U_A, NOMINAL_U_T

    inner = _Recorder((NOMINAL_U_A - neutral.hang_command, NOMINAL_U_T))
    fb = SurfaceFeedback(inner, NeutralSurfaceObserver(neutral, 1e-3), NEUTRAL_MEASUREMENTS)
    res = simulate(neutral, duration=14.0, dt=2e-4, controller=fb, control_dt=1e-3,
                           record_dt=1e-3)
    est = np.array(inner.seen)
    t = res.time
    n = min(len(t), len(est))
    late = t[:n] >= 12.0
    true = np.column_stack([res[k][:n] for k in ("bit_axial_velocity", "bit_angular_velocity",
                                                 "wob", "tob")])
    assert abs(true[late, 0].mean() - 0.01) < 2e-4 and abs(true[late, 1].mean() - 20.0) < 0.1
    rel = np.abs(est[:n][late] - true[late]) / np.abs(true[late]).mean(axis=0)
    assert rel.max(axis=0).tolist() == pytest.approx([0, 0, 0, 0], abs=0.01)


# ------------------------------------------------------------------------------ wrapper
def test_wrapper_declares_surface_signals_only(neutral):
    from downhole.control.base import check_pair
    from downhole.string.fem import DirectionalPlant

    inner = _Recorder((0.0, 0.0))        # stands in for the EID (same contract)
    fb = eid_from_surface(inner, neutral, 1e-3)
    downhole_signals = {"bit_axial_velocity", "bit_angular_velocity", "wob", "tob",
                        "depth_of_cut", "bit_axial_position", "bit_angle"}
    assert not set(fb.needs) & downhole_signals
    assert all(name in SIGNALS for name in fb.needs)
    assert all(name in SIGNALS for name in FEM_MEASUREMENTS)
    assert check_pair(fb, DirectionalPlant(neutral, dt=1e-4)) is None
    assert fb.commands == ("top_drive_axial_velocity", "top_drive_angular_velocity")


def test_wrapper_refuses_missing_or_non_finite_signals_and_a_wrong_rate(neutral):
    fb = SurfaceFeedback(_Recorder((0.0, 0.0)), NeutralSurfaceObserver(neutral, 1e-3),
                         NEUTRAL_MEASUREMENTS)
    fb.reset()
    ok = {"top_drive_axial_velocity": 0.0, "top_drive_angular_velocity": 0.0,
          "hook_load": 9.5e5, "surface_torque": 0.0}
    fb.command(0.0, ok)
    with pytest.raises(DownholeInputError, match="lacks 'hook_load'"):
        fb.command(0.001, {k: v for k, v in ok.items() if k != "hook_load"})
    with pytest.raises(DownholeInputError, match="not a finite number"):
        fb.command(0.001, dict(ok, surface_torque=float("inf")))
    with pytest.raises(DownholeInputError, match="not a finite number"):
        fb.command(0.001, dict(ok, hook_load="heavy"))
    fb.dt = 2e-3                          # a runner stepping it at another rate
    with pytest.raises(DownholeInputError, match="sample time"):
        fb.reset()
    with pytest.raises(DownholeInputError, match="inner must be a controller"):
        SurfaceFeedback(object(), NeutralSurfaceObserver(neutral, 1e-3), NEUTRAL_MEASUREMENTS)


def test_measurement_noise_is_seeded_and_refuses_bad_sigmas():
    class Echo:
        needs = ("hook_load",)
        commands = ("slack_off_force",)

        def reset(self):
            pass

        def command(self, t, obs, ref=None):
            return {"slack_off_force": obs["hook_load"]}

    def run(seed):
        mn = MeasurementNoise(Echo(), {"hook_load": 10.0, "not_observed": 1.0}, seed=seed)
        mn.reset()
        return np.array([mn.command(0.0, {"hook_load": 100.0})["slack_off_force"]
                         for _ in range(4000)])

    a, b = run(3), run(3)
    assert np.array_equal(a, b) and not np.array_equal(a, run(4))
    assert abs(a.mean() - 100.0) < 1.0 and a.std() == pytest.approx(10.0, rel=0.05)
    with pytest.raises(DownholeInputError, match=">= 0"):
        MeasurementNoise(Echo(), {"hook_load": -1.0})
    with pytest.raises(DownholeInputError, match="number"):
        MeasurementNoise(Echo(), {"hook_load": "loud"})
    assert set(DEFAULT_SURFACE_NOISE) >= set(NEUTRAL_MEASUREMENTS) | set(FEM_MEASUREMENTS)


def test_kalman_observer_refuses_mismatched_names():
    with pytest.raises(DownholeInputError, match="names"):
        KalmanObserver([[0.9]], [[1.0]], [[1.0]], [[1.0]], [[1.0]], state_names=("a", "b"))


# ------------------------------------------------------------------- closed loops (slow)
@pytest.mark.slow
def test_eid_regulates_from_the_surface_within_the_stated_bound():
    from downhole.experiments.ch3_eid import _errors
    from downhole.experiments.ch7_observer import EID_OMEGA_BOUND, EID_ROP_BOUND, run_eid_surface

    e_rop, e_w = _errors(run_eid_surface(quick=True))
    assert e_rop < EID_ROP_BOUND and e_w < EID_OMEGA_BOUND


@pytest.mark.slow
def test_dhp_step_from_the_surface_within_the_stated_bound():
    from downhole.experiments.ch7_observer import (
        DHP_ANGULAR_BOUND,
        DHP_AXIAL_BOUND,
        _dhp_measure,
        run_dhp_surface,
    )

    m = _dhp_measure(run_dhp_surface(quick=False))
    assert m["stuck_fraction"] == 0.0
    assert m["max_abs_axial_error_mm_s"] <= DHP_AXIAL_BOUND
    assert m["max_abs_angular_error_rad_s"] <= DHP_ANGULAR_BOUND
