"""The DHP methods and the contraction check (issue 17, item 2).

Algorithm 1 iterates to the fixed point of the co-state target and contracts only when
mu = rho(g^T M g R^-1) < 1; the ``riccati`` method solves the same fixed point directly and must
train every well-posed problem (R > 0, Q, S >= 0), whatever mu is. The problem below (a double
integrator with a cheap input and a heavy final weight) has mu = 10 at the last step: the
non-iterative method must return the finite-horizon LQR gains, computed here by an
independent backward Riccati recursion, and Algorithm 1 must refuse, naming itself.
"""

import numpy as np
import pytest

from downhole.control.affine import ControlAffineModel
from downhole.control.dhp import DHPProblem, DHPSettings, TrainingDiverged, train_dhp
from downhole.control.dhp.trainer import ITERATIVE_METHODS, METHODS

A = np.array([[1.0, 0.01], [0.0, 1.0]])
B = np.array([[0.0], [0.01]])
Q = 0.01 * np.eye(2)
R = np.array([[1e-4]])
S = 10.0 * np.eye(2)
N_STEPS = 50


def _problem(reference=None):
    model = ControlAffineModel(A, B, state_scale=1.0, input_scale=1.0, dt=0.01,
                               state_names=["x", "v"], input_names=["u"], strict_inputs=False)
    ref = np.zeros((N_STEPS + 1, 2)) if reference is None else reference
    return DHPProblem(model, Q, R, S, ref)


def _lqr_reference(n_steps):
    """Finite-horizon LQR by the backward Riccati recursion in its 'P - P B (R + B'PB)^-1 B'P'
    form (written here, independent of the trainer): gains K_k (u_k = -K_k x_k) and P_0."""
    P = S.copy()
    gains = []
    for _ in range(n_steps):
        BtP = B.T @ P
        H = R + BtP @ B
        gains.append(np.linalg.inv(H) @ BtP @ A)
        P = Q + A.T @ (P - P @ B @ np.linalg.inv(H) @ BtP) @ A
    return np.array(gains[::-1]), P


def test_problem_violates_contraction():
    """The test case is the one of the issue: mu = g^T S g / R = 1e-4 * 10 / 1e-4 = 10 at the last
    step, so Algorithm 1 cannot contract there (recorded by the non-iterative trainers)."""
    tr = train_dhp(_problem(), DHPSettings(method="riccati"))
    assert tr.mu[-1] == pytest.approx(10.0, rel=1e-12)
    assert np.nanmax(tr.mu) >= 10.0


def test_non_iterative_method_trains_and_matches_lqr():
    tr = train_dhp(_problem(), DHPSettings(method="riccati"))
    K, P0 = _lqr_reference(N_STEPS)
    assert tr.kd.shape == (N_STEPS, 1, 2)
    scale = np.max(np.abs(K))
    assert scale > 1.0  # non-trivial gains (heavy final weight, cheap input)
    np.testing.assert_allclose(tr.kd, K, rtol=1e-10, atol=1e-10 * scale)
    np.testing.assert_allclose(tr.kc, 0.0, atol=1e-10 * scale)
    # the closed loop's cost from x0 equals the LQR value 1/2 x0^T P0 x0
    x = x0 = np.array([0.3, -0.2])
    cost = 0.0
    for k in range(N_STEPS):
        u = -tr.kd[k] @ x - tr.kc[k]
        cost += 0.5 * (x @ Q @ x + u @ R @ u)
        x = A @ x + B @ u
    cost += 0.5 * x @ S @ x
    assert cost == pytest.approx(0.5 * x0 @ P0 @ x0, rel=1e-9)


def test_non_iterative_method_tracks_a_reference():
    """With a constant non-zero reference r the error e = z - r obeys e+ = A e + B u + (A - I) r;
    for this A, (A - I) r = 0 when r = (x_r, 0), so the gains and offsets are the regulator's."""
    ref = np.tile([0.5, 0.0], (N_STEPS + 1, 1))
    tr = train_dhp(_problem(ref), DHPSettings(method="riccati"))
    K, _ = _lqr_reference(N_STEPS)
    scale = np.max(np.abs(K))
    np.testing.assert_allclose(tr.kd, K, rtol=1e-10, atol=1e-10 * scale)
    np.testing.assert_allclose(tr.kc, 0.0, atol=1e-9 * scale)


@pytest.mark.parametrize("method", ITERATIVE_METHODS)
def test_algorithm1_refuses_naming_itself(method):
    with pytest.raises(TrainingDiverged, match=rf"step k = {N_STEPS - 1} .*Algorithm 1 iteration "
                                               rf"\(method '{method}'\) cannot converge: "
                                               r"mu = rho\(g\^T M g R\^-1\) = 10 >= 1") as info:
        train_dhp(_problem(), DHPSettings(method=method))
    assert info.value.step == N_STEPS - 1
    assert "riccati" in str(info.value)  # the message points at the method that works


def test_require_contraction_false_lets_algorithm1_try():
    """Without the check Algorithm 1 runs into the non-contracting iteration and diverges
    (non-finite co-state), rather than being refused up front: the check is Algorithm 1's."""
    with pytest.raises(TrainingDiverged, match=r"method 'algorithm1'") as info:
        train_dhp(_problem(), DHPSettings(method="algorithm1", require_contraction=True))
    assert "cannot converge" in str(info.value)
    with pytest.raises(TrainingDiverged) as info:
        train_dhp(_problem(), DHPSettings(method="algorithm1", require_contraction=False,
                                          n_iterations=2000, max_weight=1e8))
    assert "cannot converge" not in str(info.value)


def test_every_method_is_classified():
    assert set(ITERATIVE_METHODS) < set(METHODS)
    assert set(METHODS) - set(ITERATIVE_METHODS) == {"riccati"}
