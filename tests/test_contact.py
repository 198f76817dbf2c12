"""Wellbore contact: soft-string normal force against Johancsik's form; regularized friction."""

import math

import numpy as np
import pytest

from downhole.contact import friction_forces, soft_string_normal_force
from downhole.errors import DownholeInputError
from downhole.string.drillstring import DrillString, StringSegment, pipe_section
from downhole.well import Arc, Vertical, WellPath


def test_normal_force_equals_johancsik_inclination_azimuth_form():
    # 3-D arc: N = sqrt((T theta' - w sin theta)^2 + (T sin theta phi')^2) (Johancsik 1984)
    w = WellPath.from_sections([Vertical(100), Arc(300, 0.5, azimuth=0.3),
                                Arc(400, 0.6, toolface=1.0)])
    s = np.array([160.0, 200.0, 240.0, 300.0, 350.0, 420.0, 470.0])
    h = 1e-3
    inc = w.inclination(s)
    th1 = (w.inclination(s + h) - w.inclination(s - h)) / (2 * h)
    ph1 = (w.azimuth(s + h) - w.azimuth(s - h)) / (2 * h)
    T = np.linspace(-2e5, 8e5, s.size)
    wt = 600.0
    ref = np.sqrt((T * th1 - wt * np.sin(inc)) ** 2 + (T * np.sin(inc) * ph1) ** 2)
    got = soft_string_normal_force(T, w.curvature_vector(s), np.full(s.size, wt), w.tangent(s))
    assert np.allclose(got, ref, rtol=1e-5, atol=1e-3)


def test_friction_is_bounded_by_mu_n_and_regularized():
    N, mu, r = 1000.0, 0.4, 0.06
    for v, om in [(1.0, 0.0), (0.0, 50.0), (0.3, 10.0)]:
        fa, tq = friction_forces(N, mu, v, om, r, 1e-4)
        # large speeds: the full Coulomb force, along the sliding direction
        assert math.hypot(fa, tq / r) == pytest.approx(mu * N, rel=1e-6)
        assert fa * v <= 0 and tq * om <= 0
    fa, tq = friction_forces(N, mu, 1e-6, 0.0, r, 1e-4)
    assert abs(fa) == pytest.approx(mu * N * 1e-6 / math.hypot(1e-6, 1e-4), rel=1e-9)


def test_drill_string_validation_messages():
    with pytest.raises(DownholeInputError, match="inner_diameter .* must be smaller"):
        pipe_section(0.1, 0.12)
    with pytest.raises(DownholeInputError, match="outer_diameter must be > 0"):
        pipe_section(-0.1, 0.05)
    with pytest.raises(DownholeInputError, match="length must be > 0"):
        StringSegment(-3.0, pipe_section(0.12, 0.06))
    ds = DrillString.uniform(1000.0, pipe_section(0.12, 0.06), mud_density=1200.0)
    sec = ds.segments[0].section
    assert ds.buoyed_weight_per_length(10.0) == pytest.approx(
        9.81 * sec.area * sec.density * (1 - 1200.0 / sec.density))
