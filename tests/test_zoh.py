"""The one zero-order-hold helper against independent references (RK45, scipy.signal)."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.signal import cont2discrete

from downhole.errors import DownholeInputError
from downhole.string.zoh import zoh


def _oscillator():
    # damped two-mass chain (stiff enough that a Taylor series would need many terms)
    k, c, m1, m2 = 4.0e4, 30.0, 2.0, 5.0
    A = np.array([[0.0, 0.0, 1.0, 0.0],
                  [0.0, 0.0, 0.0, 1.0],
                  [-k / m1, k / m1, -c / m1, c / m1],
                  [k / m2, -k / m2, c / m2, -c / m2]])
    B = np.array([[0.0, 0.0], [0.0, 0.0], [1.0 / m1, 0.0], [0.0, 1.0 / m2]])
    return A, B


@pytest.mark.parametrize("dt", [1e-3, 0.02, 0.3])
def test_matches_scipy_cont2discrete(dt):
    A, B = _oscillator()
    Ad, Bd = zoh(A, B, dt)
    Ar, Br, *_ = cont2discrete((A, B, np.eye(4), np.zeros((4, 2))), dt, method="zoh")
    assert np.allclose(Ad, Ar, rtol=1e-12, atol=1e-12)
    assert np.allclose(Bd, Br, rtol=1e-12, atol=1e-14)


def test_matches_fine_rk45_with_held_input():
    A, B = _oscillator()
    dt = 0.05
    x0 = np.array([1e-3, -2e-3, 0.1, -0.05])
    u = np.array([3.0, -7.0])
    sol = solve_ivp(lambda t, x: A @ x + B @ u, (0.0, dt), x0, method="RK45", rtol=1e-11,
                    atol=1e-14)
    Ad, Bd = zoh(A, B, dt)
    assert np.allclose(Ad @ x0 + Bd @ u, sol.y[:, -1], rtol=1e-7, atol=1e-11)


def test_gamma_is_the_input_integral():
    A, B = _oscillator()
    dt = 0.01
    Ad, Bd, G = zoh(A, B, dt, gamma=True)
    Ad2, Bd2 = zoh(A, B, dt)
    assert np.allclose(Ad, Ad2, rtol=1e-12, atol=1e-13)
    assert np.allclose(Bd, Bd2, rtol=1e-10, atol=1e-15)
    assert np.allclose(G @ B, Bd, rtol=1e-10, atol=1e-15)
    # Gamma of a held unit term on every state: A Gamma = A_d - I
    assert np.allclose(A @ G, Ad - np.eye(4), rtol=1e-9, atol=1e-10)


def test_scalar_first_order_lag_closed_form():
    a, b, dt = -3.0, 2.0, 0.2
    Ad, Bd = zoh([[a]], [[b]], dt)
    assert Ad[0, 0] == pytest.approx(np.exp(a * dt), rel=1e-14)
    assert Bd[0, 0] == pytest.approx(b * (np.exp(a * dt) - 1.0) / a, rel=1e-13)


def test_directional_model_maps_are_the_helper():
    from downhole.string.fem import fem_model

    m = fem_model(n_elements=6)
    A, B, _, Minv = m.continuous_linear_model(500.0)
    Ad, Bd = m.linear_model(1e-3)
    Ad2, Bd2 = zoh(A, B, 1e-3)
    assert np.array_equal(Ad, Ad2) and np.array_equal(Bd, Bd2)
    G = m.nodal_force_map(1e-3)
    n2 = Minv.shape[0]
    # the top node's axial and torsional force columns are the input columns
    assert np.allclose(G[:, [0, 1]], Bd, rtol=1e-10, atol=1e-18)
    assert G.shape == (2 * n2, n2)


def test_lumped_dhp_reexport_is_the_core_helper():
    from downhole.control.dhp import drilling

    assert drilling.zoh is zoh


@pytest.mark.parametrize("args, match", [
    (([[0.0, 1.0]], [[1.0]], 0.1), "square"),
    (([[0.0]], [[1.0], [2.0]], 0.1), r"B must have shape \(1, m\)"),
    (([[np.nan]], [[1.0]], 0.1), "finite"),
    (([[0.0]], [[1.0]], 0.0), "dt must be > 0"),
    (([[0.0]], [[1.0]], -1.0), "dt must be > 0"),
    (([[0.0]], [[1.0]], np.inf), "dt must be > 0"),
    (([[0.0]], [[1.0]], "fast"), "dt must be a number"),
])
def test_bad_input_is_rejected(args, match):
    with pytest.raises(DownholeInputError, match=match):
        zoh(*args)
