"""Tests of the control-affine model interface (downhole.control.affine)."""

import numpy as np
import pytest

from downhole.control.affine import ControlAffineModel, scale_from_trajectory
from downhole.errors import DownholeInputError


def _model(nonlinear=None, **kw):
    A = np.array([[1.0, 0.1], [-0.2, 0.95]])
    B = np.array([[0.0], [0.1]])
    return ControlAffineModel.from_physical(
        A, B, state_scale=[2.0, 0.5], input_scale=[10.0], dt=0.1,
        nonlinear_physical=nonlinear, state_names=["x", "v"],
        state_kinds=["axial_position", "axial_velocity"], state_nodes=[0, 0],
        input_names=["slack_off_force"], **kw)


def test_scaling_matches_physical_step():
    h = lambda z: np.stack([np.zeros(len(z)), -0.01 * z[:, 1] ** 3], axis=1)
    m = _model(h)
    z = np.array([0.3, -0.4])
    u = np.array([7.0])
    phys = m.A_d @ z + m.B_d @ u + h(z[None])[0]
    nd = m.step(m.to_nondim_state(z), m.to_nondim_input(u))
    np.testing.assert_allclose(m.to_physical_state(nd), phys, rtol=1e-12)
    # batch evaluation agrees with single
    Z = np.random.default_rng(0).normal(size=(5, 2))
    np.testing.assert_allclose(m.f(Z)[3], m.f(Z[3]), rtol=1e-12)


def test_exact_jacobian_is_analytic():
    h = lambda z: np.stack([np.zeros(len(z)), -0.01 * z[:, 1] ** 3], axis=1)
    m = _model(h)
    zb = np.array([0.2, 0.7])
    J = m.jacobian(zb, kind="exact")
    v = zb[1] * 0.5  # physical velocity
    # d hbar_1 / d zbar_1 = P1^-1 * (-0.03 v^2) * P1
    expect = m.linear.copy()
    expect[1, 1] += -0.03 * v**2
    np.testing.assert_allclose(J, expect, rtol=1e-6)
    assert m.jacobian(kind="seed") is m.linear


def test_indices_and_bookkeeping():
    m = _model()
    assert m.index("axial_velocity", "bit") == 1
    assert m.is_linear and m.n_states == 2 and m.n_inputs == 1
    assert m.describe()["state_scale"] == [2.0, 0.5]


@pytest.mark.parametrize("kw, msg", [
    (dict(state_scale=[1.0, -1.0]), "state_scale must be positive"),
    (dict(state_names=["x"]), "state_names has 1 names"),
    (dict(input_names=["hook"]), "input name 'hook'"),
    (dict(state_kinds=["axial_position", "speed"]), "state_kinds\\[1\\]"),
    (dict(input_limits=[[1.0, 0.0]]), "input_limits"),
])
def test_validation_messages(kw, msg):
    args = dict(state_scale=[1.0, 1.0], input_scale=[1.0], dt=0.1, state_names=["x", "v"],
                input_names=["slack_off_force"])
    args.update(kw)
    with pytest.raises(DownholeInputError, match=msg):
        ControlAffineModel(np.eye(2), np.ones((2, 1)), **args)


def test_shape_mismatch_rejected():
    with pytest.raises(DownholeInputError, match="g must have shape"):
        ControlAffineModel(np.eye(3), np.ones((2, 1)), state_scale=1.0, input_scale=1.0,
                           dt=0.1, state_names="abc", input_names=["surface_torque"])


def test_scale_from_trajectory():
    z = np.array([[1.0, -3.0, 0.0], [-2.0, 1.0, 0.0]])
    np.testing.assert_allclose(scale_from_trajectory(z, floor=0.5), [2.0, 3.0, 0.5])
    with pytest.raises(DownholeInputError):
        scale_from_trajectory(z)


def test_structured_force_form_equals_nonlinear_form():
    A = np.array([[1.0, 0.1], [-0.2, 0.95]])
    B = np.array([[0.0], [0.1]])
    fmap = np.array([[0.001], [0.02]])  # physical increment per N
    kw = dict(state_scale=[2.0, 0.5], input_scale=[10.0], dt=0.1, state_names=["x", "v"],
              input_names=["slack_off_force"])
    s = ControlAffineModel.from_physical(A, B, force_map=fmap,
                                         forces=lambda zb: -3.0 * np.tanh(zb[:, 1:2]), **kw)
    h = lambda z: -3.0 * np.tanh(z[:, 1:2] / 0.5) @ fmap.T
    u = ControlAffineModel.from_physical(A, B, nonlinear_physical=h, **kw)
    Z = np.random.default_rng(1).normal(size=(4, 2))
    np.testing.assert_allclose(s.f(Z), u.f(Z), rtol=1e-12)
    assert s.nonlinear_rows.tolist() == [0, 1]
