"""DHP trainer tests: LQR equivalence, Algorithm 1 convergence on the drilling model, errors.

The reference oracles (the textbook finite-horizon LQR recursion, the per-sample closed form of
Algorithm 1's fixed point in the original coordinates) are written here, independent of the
trainer."""

import numpy as np
import pytest

from downhole.control.affine import ControlAffineModel
from downhole.control.dhp import (
    METHODS,
    BitReference,
    DHPProblem,
    DHPSettings,
    PenaltyWeights,
    TrainingDiverged,
    build_problem,
    lumped_affine_model,
    table_4_1_weights,
    train_dhp,
)
from downhole.errors import DownholeInputError


def finite_horizon_lqr(A, B, Q, R, S, n_steps):
    """Time-varying LQR gains of the textbook backward Riccati recursion (independent check).

    Minimizes 1/2 sum_{k<n} (x^T Q x + u^T R u) + 1/2 x_n^T S x_n for x+ = A x + B u; returns
    gains K (n_steps, m, n) with u_k = -K_k x_k.
    """
    P = np.asarray(S, float)
    K = np.zeros((n_steps, B.shape[1], A.shape[0]))
    for k in range(n_steps - 1, -1, -1):
        K[k] = np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A)
        P = Q + A.T @ P @ (A - B @ K[k])
        P = 0.5 * (P + P.T)
    return K


def closed_form_gains(pb, settings):
    """Algorithm 1's fixed point per sample in the original coordinates (reference oracle): g is
    constant, so the target co-state is affine in the network output and the fixed point is
    y* = (I + M G)^-1 [M (f(z) + g u_ff - r_{k+1}) + a], G = g R^-1 g^T, fitted by least squares
    on [1, z - r_k] over the same samples as the trainer (its SFC64 streams). Returns kd."""
    from downhole.control.dhp.riccati import draw_offsets

    model, n, g = pb.model, pb.model.n_states, pb.model.g
    ns = settings.n_samples
    radius = np.broadcast_to(np.asarray(settings.sample_radius, float), (n,))
    Rinv = np.linalg.inv(pb.R)
    ref, uff, A = pb.reference, pb.u_ff, model.linear
    kd = np.zeros((pb.n_steps, model.n_inputs, n))
    M, c_next = pb.S, np.zeros(n)
    for k in range(pb.n_steps - 1, -1, -1):
        delta = draw_offsets(settings.seed, [(pb.n_steps - 1 - k) // settings.resample_every],
                             ns, n)[0] * radius
        base = model.f(ref[k] + delta) + g @ uff[k] - ref[k + 1]
        a = np.zeros(n) if k == pb.n_steps - 1 else A.T @ c_next
        Mg = M @ g
        V = base @ M.T + a
        Y = V - (V @ g) @ np.linalg.inv(pb.R + g.T @ Mg).T @ Mg.T
        sol = np.linalg.lstsq(np.hstack([np.ones((ns, 1)), delta]), Y, rcond=None)[0]
        c, Dt = sol[0], sol[1:].T
        kd[k] = Rinv @ g.T @ Dt
        M, c_next = pb.Q + A.T @ Dt, c
    return kd


def _linear_plant(n=6, m=2, seed=3):
    rng = np.random.default_rng(seed)
    A = np.eye(n) + 0.05 * rng.normal(size=(n, n))
    B = 0.1 * rng.normal(size=(n, m))
    model = ControlAffineModel(A, B, state_scale=1.0, input_scale=1.0, dt=0.01,
                               state_names=[f"s{i}" for i in range(n)],
                               input_names=[f"u{i}" for i in range(m)], strict_inputs=False)
    Q = np.diag(rng.uniform(0.1, 1.0, n))
    R = np.diag([1.0, 2.0])
    S = np.eye(n) * 2.0
    return model, A, B, Q, R, S


@pytest.mark.parametrize("method", METHODS)
def test_linear_plant_controls_equal_finite_horizon_lqr(method):
    """Done-means: the trainer's controls equal the Riccati controls within 1% of their scale
    at every step (regulator, closed loop from a random initial state)."""
    model, A, B, Q, R, S = _linear_plant()
    n_steps = 150
    pb = DHPProblem(model, Q, R, S, np.zeros((n_steps + 1, 6)))
    tr = train_dhp(pb, DHPSettings(method=method, threshold=1e-9, n_iterations=200))
    K = finite_horizon_lqr(A, B, Q, R, S, n_steps)
    x_lqr = x_dhp = np.random.default_rng(7).normal(size=6)
    u_l, u_d = [], []
    for k in range(n_steps):
        ul = -K[k] @ x_lqr
        ud = tr.controls(x_dhp, k, pb.reference, pb.u_ff)
        u_l.append(ul)
        u_d.append(ud)
        x_lqr = A @ x_lqr + B @ ul
        x_dhp = A @ x_dhp + B @ ud
    u_l, u_d = np.array(u_l), np.array(u_d)
    scale = np.max(np.abs(u_l), axis=0)
    assert np.all(np.abs(u_d - u_l) <= 0.01 * scale)
    assert np.max(np.abs(tr.kd - K)) <= 1e-6 * np.max(np.abs(K))


def test_linear_tracking_with_feed_forward_is_lqr_on_the_error():
    """With a consistent reference and feed-forward, the affine term vanishes and the gain is
    the LQR gain: u - u_ff = -K (z - r)."""
    model, A, B, Q, R, S = _linear_plant()
    n_steps = 100
    rng = np.random.default_rng(1)
    uff = rng.normal(size=(n_steps, 2)) * 0.1
    ref = np.zeros((n_steps + 1, 6))
    ref[0] = rng.normal(size=6)
    for k in range(n_steps):
        ref[k + 1] = A @ ref[k] + B @ uff[k]
    pb = DHPProblem(model, Q, R, S, ref, uff)
    K = finite_horizon_lqr(A, B, Q, R, S, n_steps)
    tr = train_dhp(pb, DHPSettings(method="riccati"))
    np.testing.assert_allclose(tr.kd, K, rtol=1e-8, atol=1e-10)
    assert np.max(np.abs(tr.kc)) < 1e-9


def test_drilling_algorithm1_converges_within_10_iterations():
    """Done-means: on the drilling model the training error falls below the threshold within 10
    iterations per step (cold start, as the seed's Algorithm 1), and all methods agree."""
    model = lumped_affine_model("table_2_1", dt=1e-3)
    pb = build_problem(model, BitReference.step(0.01, 20.0), 0.2, PenaltyWeights())
    thr = 1e-6
    a1 = train_dhp(pb, DHPSettings(method="algorithm1", warm_start=False, threshold=thr,
                                   n_iterations=20, seed=4))
    assert a1.iterations.max() <= 10
    assert np.all(a1.errors <= thr)
    ric = train_dhp(pb, DHPSettings(method="riccati", seed=4))
    scale = np.abs(ric.kd).max(axis=(0, 2), keepdims=True)  # per input
    assert np.all(np.abs(a1.kd - ric.kd) <= 1e-4 * scale)
    # the seed reports about 4 iterations per step
    assert 2 <= np.median(a1.iterations) <= 6


def test_table_4_1_literal_violates_contraction_with_clear_error():
    model = lumped_affine_model("table_2_1", dt=1e-3, input_scale=[1.0, 1.0])
    pb = build_problem(model, BitReference.step(), 0.1, table_4_1_weights())
    with pytest.raises(TrainingDiverged, match=r"step k = 99 .*method 'algorithm1'.*mu = rho"):
        train_dhp(pb, DHPSettings(method="algorithm1"))
    # the non-iterative Riccati form needs no contraction: it trains (mu recorded, > 1)
    tr = train_dhp(pb, DHPSettings(method="riccati"))
    assert tr.mu[-1] > 1.0 and np.all(np.isfinite(tr.kd))


def test_diverging_iteration_names_step_and_reason():
    model, A, B, Q, R, S = _linear_plant()
    pb = DHPProblem(model, Q * 1e4, R * 1e-3, S * 1e4, np.zeros((11, 6)))
    with pytest.raises(TrainingDiverged, match=r"step k = 9 \(t = 0.09 s, iteration \d+\): "
                                               r"co-state became non-finite"):
        train_dhp(pb, DHPSettings(method="algorithm1", require_contraction=False,
                                  n_iterations=2000, max_weight=1e8))
    with pytest.raises(TrainingDiverged, match=r"step k = \d+ .*weights became non-finite"):
        train_dhp(pb, DHPSettings(method="riccati", require_contraction=False,
                                  max_weight=1e-6))


@pytest.mark.parametrize("change, msg", [
    (dict(R=np.diag([1.0, -1.0])), "R must be positive definite"),
    (dict(R=np.zeros((2, 2))), "R must be positive definite"),
    (dict(Q=np.eye(5)), r"Q must be \(6, 6\)"),
    (dict(S=-np.eye(6)), "S must be positive semi-definite"),
    (dict(reference=np.zeros((1, 6))), "horizon must be at least one step"),
    (dict(reference=np.zeros((11, 5))), r"reference must have shape \(n_steps \+ 1, 6\)"),
    (dict(u_ff=np.zeros((10, 3))), r"u_ff must have shape"),
])
def test_bad_problem_rejected(change, msg):
    model, A, B, Q, R, S = _linear_plant()
    args = dict(model=model, Q=Q, R=R, S=S, reference=np.zeros((11, 6)))
    args.update(change)
    with pytest.raises(DownholeInputError, match=msg):
        DHPProblem(**args)


def test_bad_settings_rejected():
    with pytest.raises(DownholeInputError, match="method must be one of"):
        DHPSettings(method="newton")
    with pytest.raises(DownholeInputError, match="needs basis='linear'"):
        DHPSettings(method="riccati", basis="quadratic")
    model, A, B, Q, R, S = _linear_plant()
    pb = DHPProblem(model, Q, R, S, np.zeros((11, 6)))
    with pytest.raises(DownholeInputError, match="n_samples = 5 is fewer than the 7 basis"):
        train_dhp(pb, DHPSettings(n_samples=5))
    with pytest.raises(DownholeInputError, match="shorter than one step"):
        build_problem(lumped_affine_model(), BitReference.step(), 1e-4, PenaltyWeights())


def test_quadratic_basis_reference_path_runs_and_matches_linear_plant():
    model, A, B, Q, R, S = _linear_plant()
    pb = DHPProblem(model, Q, R, S, np.zeros((21, 6)))
    tr = train_dhp(pb, DHPSettings(method="algorithm1", basis="quadratic", n_samples=40,
                                   threshold=1e-10, n_iterations=200))
    K = finite_horizon_lqr(A, B, Q, R, S, 20)
    np.testing.assert_allclose(tr.kd, K, rtol=1e-5, atol=1e-8)


def test_user_basis_object_plugs_in_and_matches_lqr_on_linear_plant():
    """A user basis (here [1, z, z^3]) trains through Algorithm 1; on a linear plant the
    co-state is linear, so the controls are the LQR ones."""

    class CubicBasis:
        is_linear = False
        name = "cubic"

        def size(self, n):
            return 2 * n + 1

        def __call__(self, Z):
            return np.concatenate([np.ones((Z.shape[0], 1)), Z, Z ** 3], axis=1)

    model, A, B, Q, R, S = _linear_plant()
    pb = DHPProblem(model, Q, R, S, np.zeros((21, 6)))
    tr = train_dhp(pb, DHPSettings(method="algorithm1", basis=CubicBasis(), n_samples=40,
                                   threshold=1e-10, n_iterations=200))
    K = finite_horizon_lqr(A, B, Q, R, S, 20)
    np.testing.assert_allclose(tr.kd, K, rtol=1e-5, atol=1e-8)
    with pytest.raises(DownholeInputError, match="needs size"):
        DHPSettings(method="algorithm1", basis=object())
    with pytest.raises(DownholeInputError, match="needs basis='linear'"):
        DHPSettings(basis=CubicBasis())


def test_directional_design_model_matches_fem_export():
    """The compiled structured design model equals the export of control.affine.from_directional."""
    from downhole.control.affine import from_directional
    from downhole.control.dhp.directional import directional_affine_model, table_5_1_models

    fem24, _ = table_5_1_models()
    fast = directional_affine_model(fem24)
    ref = from_directional(fem24, 1e-3)
    Z = np.random.default_rng(0).uniform(-1.0, 1.0, (40, 24))
    np.testing.assert_allclose(fast.f(Z), ref.f(Z), rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(fast.g, ref.g)
    assert fast.n_states == 24


def test_resampling_every_k_steps_matches_fresh_samples_on_linear_plant():
    model, A, B, Q, R, S = _linear_plant()
    pb = DHPProblem(model, Q, R, S, np.zeros((60, 6)))
    a = train_dhp(pb, DHPSettings(resample_every=1))
    b = train_dhp(pb, DHPSettings(resample_every=25, chunk=16))
    np.testing.assert_allclose(a.kd, b.kd, rtol=1e-9, atol=1e-12)


def test_compiled_sample_stream_equals_numpy_generator():
    """The trainer's compiled sample draws are NumPy's Generator(SFC64) numbers, bit for bit."""
    from downhole.control.dhp.riccati import _draw, _step_state_py, draw_offsets

    w = draw_offsets(7, [0, 3, 3, 11], 9, 5)
    compiled = np.empty((4, 9, 5))  # the compiled kernel's samples r + radius w, here r = 0
    _draw(7, np.array([0, 3, 3, 11], dtype=np.int64), np.zeros((4, 5)), np.ones(5),
          np.empty((4, 6, 9)), compiled)
    np.testing.assert_array_equal(compiled, w)
    np.testing.assert_array_equal(w[1], w[2])          # same set id, same samples
    assert not np.allclose(w[0], w[1])                  # fresh otherwise
    bg = np.random.SFC64()
    st = bg.state
    st["state"]["state"] = np.array(_step_state_py(7, 11), dtype=np.uint64)
    bg.state = st
    np.testing.assert_array_equal(w[3], 2.0 * np.random.Generator(bg).random((9, 5)) - 1.0)
    assert -1.0 <= w.min() and w.max() < 1.0


def test_modal_riccati_matches_algorithm1_numpy_and_threads_on_fem():
    """The fast trainer (modal Riccati form, fused compiled samples/forces/fit, 1 or 2 threads)
    gives Algorithm 1's fixed point: Algorithm 1 iterated to 1e-12 on the same samples, and the
    plain-NumPy version of the same trainer."""
    from downhole.control.dhp.baseline import riccati_numpy
    from downhole.control.dhp.directional import directional_affine_model, table_5_1_models

    design = directional_affine_model(table_5_1_models()[0])
    pb = build_problem(design, BitReference.step(), 0.12, PenaltyWeights())
    st = DHPSettings(n_samples=60, seed=5)
    ric = train_dhp(pb, st)
    scale = np.abs(ric.kd).max()
    a1 = train_dhp(pb, DHPSettings(n_samples=60, seed=5, method="algorithm1",
                                   threshold=1e-12, n_iterations=60))
    assert np.abs(a1.kd - ric.kd).max() <= 1e-7 * scale
    assert np.abs(a1.kc - ric.kc).max() <= 1e-7 * np.abs(ric.kc).max()
    kc, kd, mu = riccati_numpy(pb, st)
    assert np.abs(kd - ric.kd).max() <= 1e-10 * scale
    np.testing.assert_allclose(mu, ric.mu, rtol=1e-10)
    two = train_dhp(pb, DHPSettings(n_samples=60, seed=5, threads=2, chunk=16))
    np.testing.assert_array_equal(two.kd, ric.kd)
    generic = design.sample_fit
    try:  # the generic path (draw, model.forces, fit) gives the same numbers as the fused one
        design.sample_fit = None
        gen = train_dhp(pb, st)
    finally:
        design.sample_fit = generic
    # the fused kernel evaluates a state as P r + (P radius) w, the generic one as
    # P (r + radius w): equal up to rounding, which the fits carry to ~1e-12 of the gains
    assert np.abs(gen.kd - ric.kd).max() <= 1e-10 * scale
    assert not np.array_equal(gen.kd, 0.0 * gen.kd)
    # the weight snapshots map back to the original coordinates: W = [c - D r; D^T]
    k = int(ric.weight_steps[-1])
    W = ric.weights[-1]
    Rinv = np.linalg.inv(pb.R)
    np.testing.assert_allclose(Rinv @ design.g.T @ W[1:].T, ric.kd[k], rtol=1e-9,
                               atol=1e-12 * scale)


def test_defective_linear_part_falls_back_to_dense_and_equals_lqr():
    """A Jordan block (double integrator) has no modal basis: the trainer uses T = A."""
    from downhole.control.dhp.riccati import ModalForm

    A = np.array([[1.0, 0.1, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 0.9]])
    B = np.array([[0.0], [0.1], [0.2]])
    assert not ModalForm(A).banded
    model = ControlAffineModel(A, B, state_scale=1.0, input_scale=1.0, dt=0.1,
                               state_names=["x", "v", "y"], input_names=["u"],
                               strict_inputs=False)
    Q, R, S = np.diag([1.0, 0.1, 0.5]), np.array([[0.3]]), np.eye(3)
    tr = train_dhp(DHPProblem(model, Q, R, S, np.zeros((41, 3))),
                   DHPSettings(require_contraction=False))
    np.testing.assert_allclose(tr.kd, finite_horizon_lqr(A, B, Q, R, S, 40), rtol=1e-9,
                               atol=1e-12)


@pytest.mark.slow
def test_closed_form_matches_riccati_on_drilling_models():
    """The per-sample closed form (original coordinates) equals the modal Riccati form."""
    from downhole.control.dhp.directional import directional_affine_model, table_5_1_models

    for model, T in ((lumped_affine_model("table_2_1", dt=1e-3), 0.5),
                     (directional_affine_model(table_5_1_models()[0]), 0.12)):
        pb = build_problem(model, BitReference.step(), T, PenaltyWeights())
        ric = train_dhp(pb, DHPSettings(n_samples=60, seed=4))
        cf = closed_form_gains(pb, DHPSettings(n_samples=60, seed=4))
        scale = np.abs(ric.kd).max(axis=(0, 2), keepdims=True)
        assert np.all(np.abs(cf - ric.kd) <= 1e-8 * scale)


def test_feed_forward_is_an_exact_steady_state_of_the_design_model():
    """u_ff and the consistent (deflected) reference satisfy f(r_k) + g u_k = r_{k+1}; the bit
    positions keep following the integral of the velocity reference."""
    from downhole.control.dhp import feed_forward, reference_states
    from downhole.control.dhp.directional import directional_affine_model, table_5_1_models

    model = directional_affine_model(table_5_1_models()[0])
    v, w, x, a = BitReference.step(0.01, 20.0).sample(300, model.dt)
    ref = reference_states(model, v, w, x, a)
    uff, rc = feed_forward(model, ref, return_reference=True)
    res = model.f(rc[:-1]) + uff @ model.g.T - rc[1:]
    assert np.abs(res).max() < 1e-8
    for kind in ("axial_position", "angular_position"):
        i = model.index(kind, "bit")
        np.testing.assert_allclose(rc[:, i], ref[:, i], atol=1e-9)
    # the string is twisted and stretched under the steady bit and contact loads
    top = model.index("angular_position", 0)
    assert (rc[-1, top] - ref[-1, top]) * model.state_scale[top] > 10.0     # rad
    # the steady torque balances bit torque + contact torque + damping (> forces alone)
    F = model.forces(rc[-2:-1])[0]
    assert uff[-1, 1] * model.input_scale[1] > -F[1::2].sum()
