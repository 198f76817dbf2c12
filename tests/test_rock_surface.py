"""The one depth-of-cut memory (downhole.bit.rock_surface) against an independent reference.

The reference keeps the bit's whole path (theta_k, x_k) and evaluates the printed Eq. 2.9
(depth against the bit's own position one blade pitch back, found by interpolating the path in
angle, i.e. solving Eq. 2.10) or the hole-bottom surface hb(phi) = max(path(phi), hb(phi - pitch))
recursively, with no grid. The grid memory must agree to its interpolation error.
"""

import math

import numpy as np
import pytest

from downhole.bit.rock_surface import (
    RockSurfaceSpec,
    rock_advance,
    rock_advance_to,
    rock_depth,
    rock_depth_at,
    rock_init,
)

N_BLADES = 5
PITCH = 2 * math.pi / N_BLADES


def _path(n_steps=4000, dth=0.01, v=2e-4, amp=6e-4, k=3.0):
    """Forward rotation, axial position v theta + amp sin(k theta): with amp k > v the bit lifts
    off (x decreases) part of every cycle, so the hole-bottom memory matters."""
    th = np.arange(n_steps + 1) * dth
    return th, v * th + amp * np.sin(k * th)


def _reference_depth(th_hist, x_hist, x, theta, memory):
    def path(phi):
        if phi <= th_hist[0]:
            return x_hist[0]
        return float(np.interp(phi, th_hist, x_hist))

    def bottom(phi):
        if phi <= th_hist[0]:
            return x_hist[0]
        return max(path(phi), bottom(phi - PITCH)) if memory else path(phi)

    return N_BLADES * (x - bottom(theta - PITCH))


@pytest.mark.parametrize("memory", [True, False])
def test_grid_memory_matches_the_path_reference(memory):
    th, x = _path()
    spec = RockSurfaceSpec(N_BLADES, 512, memory)
    surf, istate, rp = rock_init(spec, x[0], th[0])
    errs = []
    depths = []
    for k in range(1, th.size):
        d = rock_depth(surf, istate, rp, x[k], th[k])
        if k % 37 == 0:
            ref = _reference_depth(th[:k], x[:k], x[k], th[k], memory)
            errs.append(abs(d - ref))
            depths.append(ref)
        rock_advance(surf, istate, rp, th[k - 1], x[k - 1], th[k], x[k])
    depths = np.array(depths)
    h = PITCH / 512
    # interpolation error of the grid: n h^2 max|x''| / 8 ~ 3e-8 m where the surface is smooth;
    # where the hole bottom switches between cuts (a kink, slope jump <= 2 (v + amp k)) at most
    # n h |jump| / 4
    assert np.median(errs) < 2e-7
    kink = N_BLADES * h * 2 * (2e-4 + 6e-4 * 3.0) / 4 if memory else 2e-7
    assert max(errs) < kink
    if memory:
        # the memory changes the answer: after lift-off the blade meets rock, not its own path
        th_, x_ = th[:2000], x[:2000]
        printed = [_reference_depth(th_, x_, x[2000 + j], th[2000 + j], False) for j in range(60)]
        bottom = [_reference_depth(th_, x_, x[2000 + j], th[2000 + j], True) for j in range(60)]
        assert min(np.array(bottom) - np.array(printed)) < -1e-4
    assert depths.max() > 1e-3


def test_packed_and_unpacked_forms_are_the_same_function():
    th, x = _path(800)
    spec = RockSurfaceSpec(N_BLADES, 64, True)
    s1, i1, rp = rock_init(spec, 0.0, 0.0)
    s2, i2, _ = rock_init(spec, 0.0, 0.0)
    j2 = int(i2[0])
    for k in range(1, th.size):
        d1 = rock_depth(s1, i1, rp, x[k], th[k])
        d2 = rock_depth_at(s2, j2, rp.theta_ref, rp.h, rp.nb, rp.cap, rp.n_blades, x[k],
                           th[k])
        assert d1 == d2
        rock_advance(s1, i1, rp, th[k - 1], x[k - 1], th[k], x[k])
        j2 = rock_advance_to(s2, j2, rp.theta_ref, rp.h, rp.nb, rp.cap, True, th[k - 1],
                             x[k - 1], th[k], x[k])
    assert j2 == i1[0]
    assert np.array_equal(s1, s2)


def test_backward_rotation_cuts_nothing_and_meets_its_own_surface():
    spec = RockSurfaceSpec(N_BLADES, 256, True)
    surf, istate, rp = rock_init(spec, 0.0, 0.0)
    # drill forward two pitches at a steady 1 mm per revolution-blade ...
    th = np.linspace(0.0, 2 * PITCH, 400)
    x = 1e-3 * th / PITCH
    for k in range(1, th.size):
        rock_advance(surf, istate, rp, th[k - 1], x[k - 1], th[k], x[k])
    j_front = int(istate[0])
    before = surf.copy()
    # ... turn back half a pitch at constant x: nothing is recorded
    rock_advance(surf, istate, rp, th[-1], x[-1], th[-1] - 0.5 * PITCH, x[-1])
    assert np.array_equal(surf, before) and istate[0] == j_front
    # re-traversing angles already cut, the blade meets its own surface: at the angle it left
    # 0.2 mm ago it now stands 0.2 mm deeper -> d = n * 0.2 mm
    phi = th[-1] - 0.5 * PITCH
    x_cut = 1e-3 * phi / PITCH
    d = rock_depth(surf, istate, rp, x_cut + 2e-4, phi)
    assert d == pytest.approx(N_BLADES * 2e-4, rel=1e-6)
    # a non-finite state (a diverging run) records nothing either
    rock_advance(surf, istate, rp, th[-1], x[-1], th[-1] + 1.0, float("nan"))
    assert np.array_equal(surf, before)


def test_spec_rejects_bad_layouts():
    with pytest.raises(ValueError, match="n_blades"):
        RockSurfaceSpec(0)
    with pytest.raises(ValueError, match="points_per_pitch"):
        RockSurfaceSpec(5, 2)
