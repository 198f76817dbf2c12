"""The bit/rock law against hand-computed values of seed Eqs. 2.2-2.8 (with SPEC corrections)."""

import math

import pytest

from downhole.bit import approx_depth_of_cut, bit_forces_py
from downhole.params import BitParams, get_preset

BIT = get_preset("table_2_1").bit  # eps 77 MPa, sigma 45 MPa, zeta .64, a .15, l 3.6 mm, d* 1.2 mm


def hand(d, v, w, continuous=True):
    """Eqs. 2.3-2.8 written out by hand for Table 2.1."""
    if d <= 0:
        return 0.0, 0.0
    eps, sig, zeta, a, l, dstar = 77e6, 45e6, 0.64, 0.15, 3.6e-3, 1.2e-3
    wob_c = zeta * eps * a * d
    ramp = min(max(w / 0.01, 0.0), 1.0)
    tob_c = 0.5 * eps * a**2 * d * ramp
    arg = -20e4 * v - 1.5
    f = 0.0 if arg > 700 else 1.0 / (1.0 + math.exp(arg))
    if continuous:
        wob_f = sig * l * a * min(d / dstar, 1.0) * f
    else:
        wob_f = sig * l * a * f if d > dstar else 37.5e6 * d
    mu = 0.5 + (0.8 - 0.5) * math.exp(-0.9 / 1.0 * abs(w))
    g = math.tanh(70e3 * w + 2.0)
    tob_f = 0.5 * mu * 1.0 * a * g * wob_f
    return wob_c + wob_f, tob_c + tob_f


@pytest.mark.parametrize("d,v,w", [
    (2 * math.pi * 0.01 / 10.0, 0.01, 10.0),   # nominal drilling, d > d*
    (6e-4, 0.002, 3.0),                         # 0 < d < d*: wear flat not saturated
    (3e-3, -0.01, 5.0),                         # bit moving up: axial friction vanishes
    (2e-3, 0.0, 0.0),                           # stuck bit: no cutting torque
    (2e-3, 0.01, -1.0),                         # backward rotation: friction torque reverses
    (2e-3, 0.01, 0.005),                        # inside the cutting-torque ramp
])
def test_bit_law_matches_hand_values(d, v, w):
    wob, tob = bit_forces_py(d, v, w, BIT)
    ew, et = hand(d, v, w)
    assert wob == pytest.approx(ew, rel=1e-12)
    assert tob == pytest.approx(et, rel=1e-12, abs=1e-9)


def test_nominal_numbers():
    # 10 mm/s at 10 rad/s: d = 6.283 mm -> WOB = 46.4 kN cutting + 24.3 kN friction
    wob, tob = bit_forces_py(2 * math.pi * 0.01 / 10, 0.01, 10.0, BIT)
    assert wob == pytest.approx(0.64 * 77e6 * 0.15 * 6.2832e-3 + 24300, rel=1e-4)
    assert 6300 < tob < 6400


@pytest.mark.parametrize("d", [0.0, -1e-3, -0.1])
def test_no_contact_no_force(d):
    assert bit_forces_py(d, 0.01, 10.0, BIT) == (0.0, 0.0)


def test_backward_rotation_has_no_cutting_torque():
    # omega <= 0: only the (reversed) friction torque remains
    _, tob = bit_forces_py(5e-3, 0.01, -0.5, BIT)
    assert tob < 0
    wob_f = 45e6 * 3.6e-3 * 0.15
    assert tob == pytest.approx(-0.5 * (0.5 + 0.3 * math.exp(-0.45)) * 0.15 * wob_f, rel=1e-4)


def test_printed_piecewise_law_jumps_at_dstar():
    printed = BIT.model_copy(update={"wear_flat_law": "printed"})
    below, _ = bit_forces_py(1.2e-3 - 1e-9, 0.01, 10.0, printed)
    above, _ = bit_forces_py(1.2e-3 + 1e-9, 0.01, 10.0, printed)
    assert below - above == pytest.approx(45e3 - 24.3e3, rel=1e-3)  # K_c d* vs sigma l a
    wob, _ = bit_forces_py(1e-3, 0.01, 10.0, printed)
    assert wob == pytest.approx(hand(1e-3, 0.01, 10.0, continuous=False)[0], rel=1e-12)
    # the default continuous law has no jump
    b, _ = bit_forces_py(1.2e-3 - 1e-9, 0.01, 10.0, BIT)
    a, _ = bit_forces_py(1.2e-3 + 1e-9, 0.01, 10.0, BIT)
    assert abs(a - b) < 1.0


def test_constant_friction_law():
    bit = BitParams(friction_law="constant", mu_gamma=0.7)
    _, tob = bit_forces_py(3e-3, 0.01, 10.0, bit)
    wob_c = 0.64 * 77e6 * 0.15 * 3e-3
    expected = 0.5 * 77e6 * 0.0225 * 3e-3 + 0.5 * 0.7 * 0.15 * 24300
    assert tob == pytest.approx(expected, rel=1e-6)
    assert wob_c > 0


def test_approximated_depth_of_cut_floor():
    p = BIT.to_array()
    assert approx_depth_of_cut(0.01, 10.0, p) == pytest.approx(2 * math.pi * 0.001)
    floor = BIT.omega_floor
    assert approx_depth_of_cut(0.01, 0.0, p) == pytest.approx(2 * math.pi * 0.01 / floor)


def test_bit_params_validation():
    with pytest.raises(ValueError, match="n_blades"):
        BitParams(n_blades=0)
    with pytest.raises(ValueError, match="epsilon"):
        BitParams(epsilon=-1.0)
    assert BitParams(epsilon="45 MPa").epsilon == 45e6
