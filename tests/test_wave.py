"""Wave segment (lossless delay line): analytical checks of the contract in downhole.sim.wave."""

import math

import numpy as np
import pytest

from downhole.errors import DownholeInputError
from downhole.params import NeutralStringParams, get_preset
from downhole.sim.wave import (
    WaveSegment,
    segments_from_pipe,
    static_end_forces,
    wave_end_forces,
    wave_incoming,
    wave_outgoing,
    wave_push,
    wave_source_forces,
    wave_state,
    wave_step,
)


def _run_line(seg, dt, n, v_b_fn, c_end):
    """B driven with prescribed velocity, C massless with a damper c_end to ground.

    Massless C: Z (2 a_in - v_C) - c v_C = 0. Returns t, F_B, v_C."""
    hist, pos, wp = wave_state(seg, dt)
    z = seg.impedance
    t = np.arange(n) * dt
    fb = np.empty(n)
    vc = np.empty(n)
    vb = np.empty(n)
    for i in range(n):
        a_in, b_in = wave_incoming(hist, pos, wp)
        v_b = v_b_fn(t[i])
        v_c = 2.0 * z * a_in / (z + c_end)
        fb[i], _ = wave_end_forces(z, v_b, v_c, a_in, b_in)
        a_out, b_out = wave_outgoing(v_b, v_c, a_in, b_in)
        wave_push(hist, pos, wp, a_out, b_out)
        vc[i] = v_c
        vb[i] = v_b
    return t, fb, vc, vb


@pytest.mark.parametrize("c_ratio", [0.0, 1.0, 3.0])
def test_step_reflection_matches_dalembert(c_ratio):
    # Velocity step V at B: a wave of force -Z V travels down, arrives after tau, reflects with
    # coefficient (Z - c)/(Z + c) and returns to B after 2 tau (classical transmission-line result).
    seg = WaveSegment(1000.0, 5000.0, 2.0e5)  # tau = 0.2 s
    dt = 1e-3
    z = seg.impedance
    c = c_ratio * z
    V = 0.3
    t, fb, vc, _ = _run_line(seg, dt, 700, lambda s: V, c)
    refl = (z - c) / (z + c)
    # before the wave reaches C
    assert np.all(np.abs(vc[t < 0.2 - 1e-9]) < 1e-12)
    # transmitted velocity at C
    sel = (t > 0.2 + 1e-9) & (t < 0.6 - 1e-9)
    assert np.allclose(vc[sel], 2 * z * V / (z + c), rtol=1e-12)
    # force at B: -Z V until the reflection returns, then Z (2 V refl - V)
    assert np.allclose(fb[t < 0.4 - 1e-9], -z * V)
    sel = (t > 0.4 + 1e-9) & (t < 0.6 - 1e-9)
    assert np.allclose(fb[sel], z * (2 * V * refl - V), rtol=1e-12)


def test_force_recursion_of_spec_eq_5_15_corrected():
    # seed-errata Ch. 5: P(t) = P(t - 2 tau) + Z v_B(t) + Z v_B(t - 2 tau) - 2 Z v_C(t - tau), where
    # P = -F_B is the force the node applies to the line (the printed v_C(t - 2 tau) diverges).
    seg = WaveSegment(600.0, 3000.0, 1.5e4)  # tau = 0.2 s, dt below divides it exactly
    dt = 1e-3
    rng = np.random.default_rng(1)
    vb_samples = rng.normal(size=2000)
    t, fb, vc, vb = _run_line(seg, dt, 2000, lambda s: vb_samples[int(round(s / dt))], 0.7e4)
    k = 200
    z = seg.impedance
    i = np.arange(2 * k, 2000)
    p = -fb
    rhs = p[i - 2 * k] + z * vb[i] + z * vb[i - 2 * k] - 2 * z * vc[i - k]
    assert np.max(np.abs(p[i] - rhs)) < 1e-9 * z
    # the printed form (v_C at t - 2 tau) does not hold
    printed = p[i - 2 * k] + z * vb[i] + z * vb[i - 2 * k] - 2 * z * vc[i - 2 * k]
    assert np.max(np.abs(p[i] - printed)) > 0.1 * z


def _quarter_wave_run(seg, dt, n):
    """B fixed, C free (massless): pulse at B, then the line rings at c / (4 L)."""
    hist, pos, wp = wave_state(seg, dt)
    vc = np.empty(n)
    for i in range(n):
        a_in, b_in = wave_incoming(hist, pos, wp)
        v_b = 1.0 if i * dt < 0.05 else 0.0
        v_c = 2.0 * a_in  # free end: F_C = 0
        a_out, b_out = wave_outgoing(v_b, v_c, a_in, b_in)
        wave_push(hist, pos, wp, a_out, b_out)
        vc[i] = v_c
    return vc


def test_quarter_wave_period_and_energy():
    seg = WaveSegment(1000.0, 5000.0, 1.0)
    dt = 1e-3
    vc = _quarter_wave_run(seg, dt, 4000)
    period = int(round(4 * seg.delay / dt))  # fixed-free bar: f = c / (4 L)
    half = period // 2
    # undamped, exact for integer delay/dt: odd-periodic with half period 2 tau
    assert np.allclose(vc[half + 200:3000], -vc[200:3000 - half], atol=1e-12)
    assert np.allclose(vc[period + 200:3000], vc[200:3000 - period], atol=1e-12)
    assert np.max(np.abs(vc)) == pytest.approx(2.0)


def test_non_integer_delay_interpolates():
    # delay/dt = 200.5: interpolation delays the pulse by the right amount (centroid) and
    # keeps its area (linear interpolation conserves the mean of a pulse).
    seg = WaveSegment(1002.5, 5000.0, 1.0)
    dt = 1e-3
    vc = _quarter_wave_run(seg, dt, 600)
    t = np.arange(600) * dt
    first = (t > 0.1) & (t < 0.35)
    area = np.sum(vc[first]) * dt
    centroid = np.sum(vc[first] * t[first]) * dt / area
    assert area == pytest.approx(2 * 0.05, rel=1e-9)
    # the pulse occupies samples 0..49 (centre 24.5 dt); arrival after tau = 0.2005 s
    assert centroid == pytest.approx(24.5 * dt + seg.delay, abs=1e-9)


def test_uniform_initial_state_is_steady():
    seg = WaveSegment(500.0, 3200.0, 480.0)
    hist, pos, wp = wave_state(seg, 1e-3, velocity=2.0, tension=1000.0)
    for _ in range(500):
        a_in, b_in = wave_incoming(hist, pos, wp)
        fb, fc = wave_end_forces(seg.impedance, 2.0, 2.0, a_in, b_in)
        assert fb == pytest.approx(1000.0) and fc == pytest.approx(-1000.0)
        wave_push(hist, pos, wp, *wave_outgoing(2.0, 2.0, a_in, b_in))


def test_pipe_impedances_and_delays_table_3_1():
    p = NeutralStringParams()
    ax, to = segments_from_pipe(p.pipe, p.length)
    area = math.pi / 4 * (0.12**2 - 0.06**2)
    jp = math.pi / 32 * (0.12**4 - 0.06**4)
    assert jp == pytest.approx(1.9085e-5, rel=1e-4)
    assert ax.impedance == pytest.approx(area * math.sqrt(7850 * 2.11e11))
    assert to.impedance == pytest.approx(jp * math.sqrt(7850 * 7.93e10))
    # docs/seed-errata.md: tau = L sqrt(rho/E) = 0.19288 s, L sqrt(rho/G) = 0.31463 s (Eq. 3.10 is
    # inverted)
    assert ax.delay == pytest.approx(0.19288, abs=1e-5)
    assert to.delay == pytest.approx(0.31463, abs=1e-5)
    # Table 5.1 impedances of seed-errata Ch. 5 (3.44e5 N s/m, 481 N m s/rad)
    w = get_preset("table_5_1").string
    ax5, to5 = segments_from_pipe(w.pipe, w.length_bc)
    assert ax5.impedance == pytest.approx(3.44e5, rel=5e-3)
    assert to5.impedance == pytest.approx(481.0, rel=5e-3)


def test_static_end_forces_carry_the_weight():
    seg = WaveSegment(1000.0, 5000.0, 1e5)
    fb, fc = static_end_forces(seg, bottom_tension=2e4, weight_per_length=650.0)
    assert fb + fc == pytest.approx(650.0 * 1000.0)  # net pull = segment weight
    assert fc == -2e4


@pytest.mark.parametrize("kw", [dict(length=0.0), dict(wave_speed=-1.0), dict(impedance=0.0),
                                dict(length=float("nan"))])
def test_bad_segment_is_rejected(kw):
    args = dict(length=100.0, wave_speed=5000.0, impedance=1.0)
    args.update(kw)
    name = next(iter(kw))
    with pytest.raises(DownholeInputError, match=f"WaveSegment.{name}"):
        WaveSegment(**args)


def test_delay_shorter_than_step_is_rejected():
    seg = WaveSegment(1.0, 5000.0, 1.0)
    with pytest.raises(DownholeInputError, match="shorter than the step"):
        wave_state(seg, 1e-3)


def test_pulse_arrives_after_length_over_speed_and_returns_inverted():
    # d'Alembert: a velocity pulse imposed at B travels down at c; at a fixed end C (v_C = 0)
    # the force is F_C(t) = 2 Z v_B(t - L/c), and the reflected wave (velocity inverted) is back
    # at B after 2 L/c: F_B(t) = -Z v_B(t) - 2 Z v_B(t - 2 L/c). Non-integer delay/dt = 173.37.
    seg = WaveSegment(866.85, 5000.0, 3.0e5)
    dt = 1e-3
    tau, z = seg.delay, seg.impedance
    t0, width, amp = 0.05, 0.008, 0.2

    def v_b(t):
        return amp * math.exp(-0.5 * ((t - t0) / width) ** 2)

    hist, pos, wp = wave_state(seg, dt)
    n = 450
    t = np.arange(n) * dt
    fb = np.empty(n)
    fc = np.empty(n)
    for i in range(n):
        a_in, b_in = wave_incoming(hist, pos, wp)
        ref = wave_end_forces(z, v_b(t[i]), 0.0, a_in, b_in)
        fb[i], fc[i] = wave_step(hist, pos, wp, v_b(t[i]), 0.0, a_in, b_in)
        assert (fb[i], fc[i]) == ref
        # the known part of the end forces, the rest is the end damper Z v
        sb, sc = wave_source_forces(z, a_in, b_in)
        assert sb - z * v_b(t[i]) == pytest.approx(fb[i], rel=1e-12, abs=1e-9)
        assert sc == pytest.approx(fc[i], rel=1e-12, abs=1e-9)
    assert pos[0] == n
    exact_c = np.array([2 * z * v_b(s - tau) for s in t])
    exact_b = np.array([-z * v_b(s) - 2 * z * v_b(s - 2 * tau) for s in t])
    # linear interpolation at weight f of a pulse 8 samples wide: peak error about
    # f (1 - f) / 2 (dt / width)^2 = 1.8e-3 of the amplitude per pass; the reflection passes twice
    assert np.max(np.abs(fc - exact_c)) < 2.5e-3 * 2 * z * amp
    assert np.max(np.abs(fb - exact_b)) < 5e-3 * 2 * z * amp
    # nothing reaches C before t0 + L/c - 5 widths
    assert np.all(np.abs(fc[t < t0 + tau - 5 * width]) < 1e-4 * z * amp)
    # the arrival (centroid of F_C) lies at t0 + L/c
    sel = t < t0 + 1.5 * tau
    centroid = np.sum(fc[sel] * t[sel]) / np.sum(fc[sel])
    assert centroid == pytest.approx(t0 + tau, abs=1e-6)


def test_read_weight_stays_exact_after_many_steps():
    # the read position t_n - delay uses an exact integer offset and weight: after 10^9 steps
    # the interpolation is as exact as at the start (n - delay in floating point is not)
    from fractions import Fraction

    seg = WaveSegment(1000.0, 5184.5, 1.0)
    dt = 1.3e-3
    hist, pos, wp = wave_state(seg, dt)
    cap = wp.cap
    for n in (1001, 10**6 + 7, 10**9 + 3):
        pos[0] = n
        for k in range(n - cap + 1, n):
            hist[0, k % cap] = k % 2      # parity of the absolute sample index
            hist[1, k % cap] = 1 - k % 2
        a, b = wave_incoming(hist, pos, wp)
        q = Fraction(n) - Fraction(wp.delay_steps)
        k0 = math.floor(q)
        f = float(q - k0)
        exact = (1 - f) * (k0 % 2) + f * ((k0 + 1) % 2)
        assert a == pytest.approx(exact, abs=1e-15)
        assert a + b == pytest.approx(1.0, abs=1e-15)


def test_line_preload_is_the_static_end_forces_of_the_line_weight():
    from downhole.sim.wave import line_preload

    seg = WaveSegment(800.0, 5100.0, 3.0e5)
    assert line_preload(2.0e4, 350.0 * 800.0) == static_end_forces(seg, 2.0e4, 350.0)
    # the hybrid's preload: B carries the line's weight on top of the tension at C
    from downhole.string.fem import _line_preload
    from downhole.string.hybrid import hybrid_model

    m = hybrid_model("hybrid24")
    fb0, fc0, _ = _line_preload(m, 1.0e5)
    n_c = float(m.gravity[m.node_c:].sum()) - 1.0e5
    assert (fb0, fc0) == (n_c + m.wave["line_weight"], -n_c)
