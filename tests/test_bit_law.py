"""The bit/rock law against hand-computed values of seed Eqs. 2.2-2.8 (with the corrections of
docs/seed-errata.md)."""

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
    p = BIT.kernel_params()
    assert approx_depth_of_cut(0.01, 10.0, p) == pytest.approx(2 * math.pi * 0.001)
    floor = BIT.omega_floor
    assert approx_depth_of_cut(0.01, 0.0, p) == pytest.approx(2 * math.pi * 0.01 / floor)


def test_bit_params_validation():
    with pytest.raises(ValueError, match="n_blades"):
        BitParams(n_blades=0)
    with pytest.raises(ValueError, match="epsilon"):
        BitParams(epsilon=-1.0)
    assert BitParams(epsilon="45 MPa").epsilon == 45e6


# ---- the interface: analytic slopes, the Aarsnes & van de Wouw law, law selection -----------

import itertools

from downhole.bit import LAWS, bit_forces_and_slopes_py, law_id

AARSNES = BIT.model_copy(update={"law": "aarsnes"})  # F_c = sigma l a = 24.3 kN, d_c = 10 um


def hand_slopes(d, v, w):
    """Partial slopes of hand() written out (d < d* or d > d*, v where f(v) = 1, w > omega_reg)."""
    eps, sig, zeta, a, lw, dstar = 77e6, 45e6, 0.64, 0.15, 3.6e-3, 1.2e-3
    full = sig * lw * a
    dwf_dd = full / dstar if d < dstar else 0.0
    wf = full * min(d / dstar, 1.0)
    mu = 0.5 + 0.3 * math.exp(-0.9 * w)
    dmu = -0.3 * 0.9 * math.exp(-0.9 * w)
    g = math.tanh(70e3 * w + 2.0)
    dwob_dd = zeta * eps * a + dwf_dd
    dtob_dd = 0.5 * eps * a**2 + 0.5 * mu * a * g * dwf_dd
    dtob_dw = 0.5 * a * wf * dmu * g  # tanh saturated, cutting ramp flat above omega_reg
    return dwob_dd, 0.0, dtob_dd, 0.0, dtob_dw


@pytest.mark.parametrize("d,v,w", [(6e-4, 0.002, 3.0), (6.283e-3, 0.01, 10.0), (2e-3, 0.01, 1.0)])
def test_analytic_slopes_match_hand_values(d, v, w):
    r = bit_forces_and_slopes_py(d, v, w, BIT)
    assert r[:2] == pytest.approx(hand(d, v, w), rel=1e-12)
    assert r[2:] == pytest.approx(hand_slopes(d, v, w), rel=1e-12, abs=1e-9)
    # below d*: 7.392 MN/m of cutting + 20.25 MN/m of wear-flat contact (Table 2.1)
    if d < 1.2e-3:
        assert r[2] == pytest.approx(7.392e6 + 20.25e6, rel=1e-12)


def _fd_slopes(bit, d, v, w):
    def f(dd, vv, ww):
        return bit_forces_and_slopes_py(dd, vv, ww, bit)[:2]
    hd, hv, hw = 1e-6 * d, 1e-9, 1e-6 * max(abs(w), 1e-3)
    wd = [(f(d + hd, v, w)[i] - f(d - hd, v, w)[i]) / (2 * hd) for i in (0, 1)]
    wv = [(f(d, v + hv, w)[i] - f(d, v - hv, w)[i]) / (2 * hv) for i in (0, 1)]
    ww = (f(d, v, w + hw)[1] - f(d, v, w - hw)[1]) / (2 * hw)
    return wd[0], wv[0], wd[1], wv[1], ww


# points in the smooth regions of each law (away from d*, d_c, omega = 0, omega_reg and the
# kinks of the regularisations), including the lift-off region of f(v) and the tanh region of g
SMOOTH_POINTS = [(6e-4, 0.002, 3.0), (3e-3, 0.01, 10.0), (2e-3, -5e-6, 4.0),
                 (8e-4, 1e-5, 0.7), (2.5e-3, 0.003, 0.005), (4e-3, 0.004, 1e-4),
                 (3e-3, 0.002, -0.5)]


@pytest.mark.parametrize("bit", [BIT, AARSNES,
                                 BIT.model_copy(update={"friction_law": "constant"}),
                                 BIT.model_copy(update={"wear_flat_law": "printed"})],
                         ids=["detournay", "aarsnes", "constant-mu", "printed"])
@pytest.mark.parametrize("d,v,w", SMOOTH_POINTS)
def test_analytic_slopes_match_finite_differences(bit, d, v, w):
    if bit.law == "aarsnes" and d < 2 * bit.contact_depth:
        pytest.skip("inside the contact onset ramp")
    r = bit_forces_and_slopes_py(d, v, w, bit)
    fd = _fd_slopes(bit, d, v, w)
    scale_w = max(abs(r[0]) / d, abs(r[2]), 1.0)  # N/m
    for got, want, scale in zip(r[2:], fd, (scale_w, max(abs(r[3]), 1.0), scale_w,
                                            max(abs(r[5]), 1.0), max(abs(r[6]), 1.0))):
        assert got == pytest.approx(want, rel=2e-5, abs=2e-6 * scale)


def hand_aarsnes(d, v, w, fc=45e6 * 3.6e-3 * 0.15, dc=1e-5):
    """Aarsnes & van de Wouw (2019) with Table 2.1's bit: W = zeta eps a d + W_f,
    T = 1/2 eps a^2 d s(w) + gamma mu a W_f g(w), W_f = F_c min(d/d_c, 1) f(v)."""
    if d <= 0:
        return 0.0, 0.0
    eps, zeta, a = 77e6, 0.64, 0.15
    arg = -20e4 * v - 1.5
    f = 0.0 if arg > 700 else 1.0 / (1.0 + math.exp(arg))
    wf = fc * min(d / dc, 1.0) * f
    ramp = min(max(w / 0.01, 0.0), 1.0)
    mu = 0.5 + 0.3 * math.exp(-0.9 * abs(w))
    g = math.tanh(70e3 * w + 2.0)
    return zeta * eps * a * d + wf, 0.5 * eps * a**2 * d * ramp + 1.0 * mu * a * wf * g


@pytest.mark.parametrize("d,v,w", [(6.283e-3, 0.01, 10.0), (6e-4, 0.002, 3.0), (5e-6, 0.01, 2.0),
                                   (3e-3, -0.01, 5.0), (2e-3, 0.0, 0.0), (2e-3, 0.01, -1.0),
                                   (-1e-3, 0.01, 10.0)])
def test_aarsnes_law_matches_hand_values(d, v, w):
    wob, tob = bit_forces_and_slopes_py(d, v, w, AARSNES)[:2]
    ew, et = hand_aarsnes(d, v, w)
    assert wob == pytest.approx(ew, rel=1e-12)
    assert tob == pytest.approx(et, rel=1e-12, abs=1e-9)


def test_aarsnes_nominal_numbers_by_hand():
    # 10 mm/s at 10 rad/s, d = 6.2832 mm: W_c = 0.64 * 77e6 * 0.15 * d = 46.445 kN,
    # W_f = 24.3 kN; T_c = 0.5 * 77e6 * 0.0225 * d = 5443 N m,
    # T_f = mu(10) a W_f = (0.5 + 0.3 e^-9) * 0.15 * 24300 = 1822.5 N m
    wob, tob = bit_forces_and_slopes_py(2 * math.pi * 1e-3, 0.01, 10.0, AARSNES)[:2]
    assert wob == pytest.approx(46445.3 + 24300.0, rel=1e-5)
    assert tob == pytest.approx(5442.9 + 1822.5, rel=1e-4)


def test_aarsnes_contact_force_does_not_grow_with_depth_of_cut():
    # above the onset ramp the wear-flat force is F_c whatever d: WOB - W_c is constant ...
    for d in (2e-5, 1e-4, 1.2e-3, 5e-3, 2e-2):
        wob, _ = bit_forces_and_slopes_py(d, 0.01, 10.0, AARSNES)[:2]
        assert wob - 0.64 * 77e6 * 0.15 * d == pytest.approx(24300.0, rel=1e-9)
    # ... while Detournay's grows linearly up to d*
    w1 = bit_forces_py(3e-4, 0.01, 10.0, BIT)[0] - 0.64 * 77e6 * 0.15 * 3e-4
    assert w1 == pytest.approx(24300.0 * 0.25, rel=1e-9)
    fc = AARSNES.model_copy(update={"contact_force": 10e3})
    assert bit_forces_py(1e-3, 0.01, 10.0, fc)[0] == pytest.approx(7392.0 + 10e3, rel=1e-9)


def test_aarsnes_torque_to_weight_ratio_tends_to_the_cutting_ratio():
    # T/W = (1/2 eps a^2 d + gamma mu a F_c) / (zeta eps a d + F_c) -> a / (2 zeta) as d grows,
    # the remainder falling like 1/d (the contact terms stop mattering)
    cut = 0.15 / (2 * 0.64)
    errs = []
    for d in (1e-3, 1e-2, 1e-1, 1.0):
        wob, tob = bit_forces_py(d, 0.01, 10.0, AARSNES)
        errs.append(abs(tob / wob - cut))
    assert errs[-1] < 2e-3 * cut
    for e0, e1 in itertools.pairwise(errs):
        assert e1 < e0
    assert errs[2] / errs[3] == pytest.approx(10.0, rel=0.05)


def test_law_registry_and_selection():
    assert set(LAWS) == {"detournay", "aarsnes"}
    assert law_id("detournay") == 0 and law_id("aarsnes") == 1
    with pytest.raises(ValueError, match="unknown bit law 'maurer'"):
        law_id("maurer")
    with pytest.raises(ValueError, match="law"):
        BitParams(law="maurer")
    with pytest.raises(ValueError, match="contact_force"):
        BitParams(law="aarsnes", contact_force=-1.0)
    with pytest.raises(ValueError, match="contact_depth"):
        BitParams(law="aarsnes", contact_depth=0.0)
    assert BitParams(law="aarsnes", contact_force="20 kN").contact_force == 20e3
    # every parameter a law reads exists in BitParams
    for law in LAWS.values():
        assert set(law.parameters) <= set(BitParams.model_fields)
    p = BitParams(law="aarsnes").kernel_params()
    assert p[-3] == 1.0 and p[-2] == pytest.approx(45e6 * 3.6e-3 * 0.15)


@pytest.mark.parametrize("bit", [BIT, AARSNES], ids=["detournay", "aarsnes"])
def test_torque_at_a_fixed_contact_force_is_the_law(bit):
    # the split the FEM's torsional solve uses: W_f(d, v) once, then TOB(d, W_f, omega)
    from downhole.bit.law import bit_contact_force, bit_torque_at_contact

    p = bit.kernel_params()
    for d, v, w in SMOOTH_POINTS + [(-1e-3, 0.01, 3.0)]:
        r = bit_forces_and_slopes_py(d, v, w, bit)
        wf, dwf_dd, dwf_dv = bit_contact_force(d, v, p)
        tob, dtob_dw = bit_torque_at_contact(d, wf, w, p)
        assert tob == pytest.approx(r[1], rel=1e-14, abs=1e-12)
        assert dtob_dw == pytest.approx(r[6], rel=1e-14, abs=1e-12)
        cut = 0.64 * 77e6 * 0.15 * d if d > 0 else 0.0
        assert wf == pytest.approx(r[0] - cut, rel=1e-12, abs=1e-9)
        assert r[2] == pytest.approx((0.64 * 77e6 * 0.15 if d > 0 else 0.0) + dwf_dd, rel=1e-12)
        assert r[3] == pytest.approx(dwf_dv, rel=1e-12)
