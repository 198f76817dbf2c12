"""Wellbore contact: soft-string normal force against Johancsik's form; regularized friction."""

import math

import numpy as np
import pytest

from downhole.contact import friction_forces, soft_string_normal_force
from downhole.errors import DownholeInputError
from downhole.string.drillstring import DrillString, StringSegment, pipe_section
from downhole.well import Arc, Tangent, Vertical, WellPath


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


# ---------------------------------------------------------------- the compiled contact
def _build_arc_element(theta, build_rate, w, length):
    """elem row of one element on a planar build arc at inclination theta (from vertical)."""
    t = np.array([math.sin(theta), 0.0, math.cos(theta)])           # tangent (N, E, down)
    k = build_rate * np.array([math.cos(theta), 0.0, -math.sin(theta)])  # dt/ds
    g = np.array([0.0, 0.0, 1.0]) - t[2] * t                         # down, normal part
    elem = np.zeros((2, 8))
    elem[0, 0] = length
    elem[0, 1:4] = k
    elem[0, 4:7] = w * g
    elem[0, 7] = 1.0
    return elem


@pytest.mark.parametrize("tension", [2.0e5, 5.0e4, -1.0e5])
def test_compiled_normal_force_on_a_build_arc_by_hand(tension):
    from downhole.contact import element_normal_half

    # 30 deg inclination, 3 deg / 30 m build, 300 N/m buoyed weight, 10 m element:
    # planar Johancsik N = |T theta' - w sin(theta)|, each end node takes L N / 2
    theta, rate, w, L = math.radians(30.0), math.radians(3.0) / 30.0, 300.0, 10.0
    elem = _build_arc_element(theta, rate, w, L)
    by_hand = abs(tension * rate - w * 0.5) * L / 2
    assert element_normal_half(elem, 0, tension) == pytest.approx(by_hand, rel=1e-12)


def test_compiled_normal_force_at_the_tension_that_lifts_the_string_off_the_low_side():
    from downhole.contact import element_normal_half

    # T theta' = w sin(theta): the string touches neither side
    theta, rate, w = math.radians(60.0), math.radians(4.0) / 30.0, 450.0
    elem = _build_arc_element(theta, rate, w, 9.0)
    assert element_normal_half(elem, 0, w * math.sin(theta) / rate) == pytest.approx(0.0,
                                                                                      abs=1e-9)


def test_compiled_friction_by_hand():
    from downhole.contact import friction_damper

    N, mu, r, v, om, ve = 2500.0, 0.3, 0.0635, 0.02, 12.0, 1e-3
    s = math.sqrt(v**2 + (r * om) ** 2 + ve**2)            # sliding speed, regularized
    fa, tq = friction_forces(N, mu, v, om, r, ve)
    assert fa == pytest.approx(-mu * N * v / s, rel=1e-13)
    assert tq == pytest.approx(-mu * N * r * (r * om) / s, rel=1e-13)
    assert friction_damper(N, mu, v, r * om, ve) == pytest.approx(mu * N / s, rel=1e-13)
    # at rest the regularized friction vanishes (no force without sliding)
    assert friction_forces(N, mu, 0.0, 0.0, r, ve) == (0.0, 0.0)


def test_contact_elements_skip_straight_vertical_and_unflagged():
    from downhole.contact import contact_elements

    elem = np.zeros((5, 8))
    elem[:4, 0] = 10.0
    elem[:4, 7] = 1.0
    elem[1, 6] = 50.0                    # inclined: normal weight
    elem[2, 1] = 1e-3                    # curved
    elem[3, 6] = 50.0
    elem[3, 7] = 0.0                     # no contact (e.g. the wave segment of a hybrid)
    elem[4, 6] = 50.0                    # the last row is no element
    assert contact_elements(elem).tolist() == [1, 2]
    assert contact_elements(np.zeros((1, 8))).size == 0


def test_fem_elements_reproduce_johancsik_and_numpy_form_matches_compiled():
    from downhole.contact import (
        element_normal_half,
        friction_damper,
        nodal_friction_forces,
        normal_force_per_length,
    )
    from downhole.string.fem import fem_model

    well = WellPath.from_sections([Vertical(300), Arc(600, 0.8, azimuth=0.2),
                                   Arc(500, 1.1, toolface=0.7)])
    pipe = pipe_section(0.127, 0.1086)
    ds = DrillString.uniform(well.total_depth, pipe, mud_density=1200.0)
    m = fem_model(well, ds, n_elements=40, md_b=400.0, md_c=900.0, friction=0.3)
    n = m.n_nodes
    mid = 0.5 * (m.node_md[1:] + m.node_md[:-1])
    h = 1e-3
    inc = well.inclination(mid)
    th1 = (well.inclination(mid + h) - well.inclination(mid - h)) / (2 * h)
    ph1 = (well.azimuth(mid + h) - well.azimuth(mid - h)) / (2 * h)
    rng = np.random.default_rng(3)
    T = rng.uniform(-1e5, 6e5, n - 1)
    wb = ds.buoyed_weight_per_length(mid)
    johancsik = np.sqrt((T * th1 - wb * np.sin(inc)) ** 2 + (T * np.sin(inc) * ph1) ** 2)
    elem = m.elem
    got = np.array([element_normal_half(elem, e, T[e]) for e in range(n - 1)])
    assert np.allclose(got, 0.5 * elem[:-1, 0] * johancsik, rtol=1e-5, atol=1e-3)
    # the NumPy batch form (design exports) is the same law: nodal sums of the element halves
    va = rng.normal(0.0, 0.05, (3, n))
    vt = rng.normal(0.0, 10.0, (3, n))
    Tb = T[None, :] * rng.uniform(0.5, 1.5, (3, 1))
    fa, ft = nodal_friction_forces(Tb, elem, m.radius, m.mu, va, vt, m.v_eps)
    for s in range(3):
        Nn = np.zeros(n)
        for e in range(n - 1):
            half = 0.5 * elem[e, 0] * normal_force_per_length(Tb[s, e], *elem[e, 1:7])
            assert half == pytest.approx(element_normal_half(elem, e, Tb[s, e]), rel=1e-15)
            Nn[e] += half
            Nn[e + 1] += half
        for i in range(n):
            c = friction_damper(Nn[i], m.mu, va[s, i], m.radius[i] * vt[s, i], m.v_eps)
            assert fa[s, i] == pytest.approx(-c * va[s, i], rel=1e-12, abs=1e-12)
            assert ft[s, i] == pytest.approx(-c * m.radius[i] ** 2 * vt[s, i], rel=1e-12,
                                             abs=1e-12)


@pytest.mark.parametrize("kw, match", [
    (dict(tension=np.zeros(3)), r"velocities \(\.\.\., 4\)"),
    (dict(elem=np.zeros((5, 7))), r"elem \(n, 8\) expected"),
    (dict(tension=np.zeros(6)), r"elem \(n, 8\) expected"),
    (dict(tension=5.0), r"tension \(\.\.\., n - 1\)"),
    (dict(radius=np.zeros(4)), r"radius \(5,\)"),
    (dict(v_eps=0.0), "v_eps must be > 0"),
    (dict(v_eps=float("nan")), "v_eps must be > 0"),
])
def test_numpy_friction_rejects_mismatched_input(kw, match):
    from downhole.contact import nodal_friction_forces

    args = dict(tension=np.zeros(4), elem=np.zeros((5, 8)), radius=np.full(5, 0.06), mu=0.3,
                v_axial=np.zeros(5), v_angular=np.zeros(5), v_eps=1e-3)
    args.update(kw)
    with pytest.raises(DownholeInputError, match=match):
        nodal_friction_forces(**args)


def test_kernel_torque_loss_of_a_rotating_string_equals_the_soft_string_integral():
    # torque and drag by hand: a string hanging at zero WOB and rotating steadily at 10 rad/s in
    # a build-and-hold well does not slide axially, so the tension is the buoyed weight below
    # (T(s) = w (TVD(L) - TVD(s))) and the surface torque is int mu r N(s) ds with Johancsik's
    # N; mass-proportional damping off, so the wall friction is the only torque on the string
    from scipy.integrate import quad

    from downhole.control.topdrive import Hook, TopDrive
    from downhole.sim import simulate
    from downhole.string.fem import fem_model

    well = WellPath.from_sections([Vertical(500.0), Arc(600.0, math.pi / 3), Tangent(300.0)])
    pipe = pipe_section(0.127, 0.1086)
    ds = DrillString.uniform(well.total_depth, pipe, mud_density=1200.0)
    mu = 0.25
    m = fem_model(well, ds, n_elements=80, friction=mu, rayleigh_alpha=0.0,
                  rayleigh_beta=0.02, md_b=200.0, md_c=400.0)
    r = simulate(m, duration=30.0, dt=1e-3, top_drive=TopDrive(speed=10.0, ramp_time=3.0),
                             hook=Hook(mode="force", wob=0.0), depth_of_cut="approximate",
                             record_dt=0.01)
    steady = r.time > 25.0
    torque = np.asarray(r["surface_torque"])[steady]
    assert np.max(np.abs(np.asarray(r["bit_angular_velocity"])[steady] - 10.0)) < 0.05
    assert np.max(np.abs(np.asarray(r["wob"])[steady])) < 1.0

    L = well.total_depth
    w = float(ds.buoyed_weight_per_length(0.5 * L))
    tvd_bit = float(well.tvd(L))
    h = 1e-3

    def normal(s):
        T = w * (tvd_bit - float(well.tvd(s)))
        inc = float(well.inclination(s))
        th1 = (float(well.inclination(s + h)) - float(well.inclination(s - h))) / (2 * h)
        ph1 = (float(well.azimuth(s + h)) - float(well.azimuth(s - h))) / (2 * h)
        return math.hypot(T * th1 - w * math.sin(inc), T * math.sin(inc) * ph1)

    radius = pipe.outer_diameter / 2
    arc_end = 500.0 + 600.0 * math.pi / 3
    by_hand = sum(quad(lambda s: mu * radius * normal(s), a, b, limit=200)[0]
                  for a, b in ((h, 500.0), (500.0, arc_end), (arc_end, L - h)))
    assert by_hand > 1000.0  # a real torque loss, not a vanishing one
    assert float(np.mean(torque)) == pytest.approx(by_hand, rel=5e-3)
    assert np.ptp(torque) < 0.02 * by_hand
