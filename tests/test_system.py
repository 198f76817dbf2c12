"""One drilling-system description built at every fidelity: first natural frequencies, static
stiffness and hanging hook load agree across fidelities and with hand calculations."""

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from downhole.errors import DownholeInputError
from downhole.string.drillstring import DrillString, StringSegment, pipe_section
from downhole.system import FIDELITIES, DrillingSystem, _chain_frequencies


def _bar_with_end_mass(wave_speed, length, line_mass, end_mass):
    """First natural frequency (Hz) of a uniform bar, top clamped, end mass at the bottom:
    beta L tan(beta L) = line mass / end mass."""
    x = brentq(lambda b: b * math.tan(b) - line_mass / end_mass, 1e-12, math.pi / 2 - 1e-12)
    return x * wave_speed / length / (2 * math.pi)


@pytest.fixture(scope="module")
def table51():
    return DrillingSystem.table_5_1(friction=0.0)


@pytest.fixture(scope="module")
def bha_string():
    pipe = pipe_section(0.127, 0.1086)
    collar = pipe_section(0.2032, 0.0714)
    ds = DrillString((StringSegment(2800.0, pipe), StringSegment(200.0, collar, "collar")),
                     mud_density=1200.0)
    return DrillingSystem.vertical(ds, friction=0.0)


def test_table_5_1_first_frequencies_agree_at_every_fidelity(table51):
    p = table51.string.segments[0].section
    length = table51.string.length
    # uniform fixed-free bar: quarter wave
    f_axial = p.axial_wave_speed / (4 * length)
    f_tors = p.torsional_wave_speed / (4 * length)
    fem = table51.build("fem")
    assert fem.natural_frequencies("axial", 1, top="fixed")[0] == pytest.approx(f_axial, rel=2e-3)
    assert fem.natural_frequencies("torsional", 1, top="fixed")[0] == pytest.approx(f_tors,
                                                                                    rel=2e-3)
    for fid in ("lumped4", "lumped12"):
        m = table51.build(fid)
        fa, ft = (_chain_frequencies(f)[0] / (2 * math.pi) for f in (m.axial, m.torsional))
        assert fa == pytest.approx(f_axial, rel=2e-3), fid
        assert ft == pytest.approx(f_tors, rel=2e-3), fid
    n = table51.build("neutral")
    q = n.params
    fa = _bar_with_end_mass(n.axial.wave_speed, q.length, q.pipe.density * q.pipe.area * q.length,
                            q.bit_mass)
    ft = _bar_with_end_mass(n.torsional.wave_speed, q.length,
                            q.pipe.density * q.pipe.polar_moment * q.length, q.bit_inertia)
    assert fa == pytest.approx(f_axial, rel=5e-3)
    assert ft == pytest.approx(f_tors, rel=5e-3)


def test_string_with_bha_frequencies_agree_across_fidelities(bha_string):
    der = bha_string.lumped_derivation()
    fem = bha_string.build("fem", n_elements=300)
    ref = (fem.natural_frequencies("axial", 1, top="fixed")[0],
           fem.natural_frequencies("torsional", 1, top="fixed")[0])
    # the derivation's reference FEM is converged against a finer mesh
    assert der.first_frequency == pytest.approx(ref, rel=1e-3)
    n = bha_string.build("neutral")
    q = n.params
    # the neutral model lumps the collars into the bit: mass and inertia of 200 m of collar
    collar = bha_string.string.segments[1].section
    assert q.bit_mass == pytest.approx(collar.density * collar.area * 200.0)
    fa = _bar_with_end_mass(n.axial.wave_speed, q.length, q.pipe.density * q.pipe.area * q.length,
                            q.bit_mass)
    ft = _bar_with_end_mass(n.torsional.wave_speed, q.length,
                            q.pipe.density * q.pipe.polar_moment * q.length, q.bit_inertia)
    assert fa == pytest.approx(ref[0], rel=0.01)  # rigid-collar approximation: within 1 %
    assert ft == pytest.approx(ref[1], rel=0.01)
    for fid in ("lumped4", "lumped12"):
        m = bha_string.build(fid)
        got = tuple(_chain_frequencies(f)[0] / (2 * math.pi) for f in (m.axial, m.torsional))
        assert got == pytest.approx(ref, rel=2e-3), fid


def test_static_stiffness_is_the_series_compliance_of_the_sections(bha_string):
    segs = bha_string.string.segments
    k_hand = 1.0 / sum(s.length / (s.section.young_modulus * s.section.area) for s in segs)
    fem = bha_string.build("fem", n_elements=120)
    # FEM: top clamped, unit force at the bit
    K = np.diag(fem.Ka[0]) + np.diag(fem.Ka[1][:-1], 1) + np.diag(fem.Ka[1][:-1], -1) \
        if isinstance(fem.Ka, tuple) else _dense(fem.Ka)
    f = np.zeros(K.shape[0])
    f[-1] = 1.0
    u = np.linalg.solve(K[1:, 1:], f[1:])
    assert 1.0 / u[-1] == pytest.approx(k_hand, rel=1e-9)
    for fid in ("lumped4", "lumped12"):
        m = bha_string.build(fid)
        Kc = m.axial.stiffness_matrix()
        e = np.zeros(m.n)
        e[-1] = 1.0
        assert 1.0 / np.linalg.solve(Kc, e)[-1] == pytest.approx(k_hand, rel=1e-9), fid


def _dense(T):
    from downhole.string.fem import _tri_dense

    return _tri_dense(T)


def test_hanging_hook_load_is_the_buoyed_weight_at_every_fidelity(table51, bha_string):
    sec = table51.string.segments[0].section
    tvd = 3000.0 + 4000.0 * math.sin(math.radians(30.0))
    hand = table51.string.g * sec.area * sec.density * tvd
    assert table51.hanging_weight() == pytest.approx(hand, rel=1e-6)
    for system in (table51, bha_string):
        w = system.hanging_weight()
        assert system.build("fem").buoyed_weight == pytest.approx(w, rel=1e-6)
        assert system.build("hybrid").buoyed_weight == pytest.approx(w, rel=1e-6)
        for fid in ("lumped4", "lumped12"):
            assert system.build(fid).weight == pytest.approx(w, rel=1e-12)
        q = system.build("neutral").params
        assert (q.string_mass + q.bit_mass) * q.g == pytest.approx(w, rel=1e-12)
    ds = bha_string.string
    hand_bha = ds.g * sum(s.section.area * (s.section.density - ds.mud_density) * s.length
                          for s in ds.segments)
    assert bha_string.hanging_weight() == pytest.approx(hand_bha, rel=1e-12)


def test_unrepresentable_features_give_precise_errors():
    s = DrillingSystem.table_5_1()
    for fid in ("lumped4", "lumped12", "neutral"):
        with pytest.raises(DownholeInputError, match="cannot represent wall contact"):
            s.build(fid)
    assert s.build("fem", n_elements=107).n_states == 432
    assert s.build("hybrid", preset="hybrid68").n_states == 68
    with pytest.raises(DownholeInputError, match="fidelity must be one of"):
        s.build("lumped6")
    pipe, hw = pipe_section(0.127, 0.1086), pipe_section(0.127, 0.0762)
    two = DrillString((StringSegment(2000.0, pipe), StringSegment(300.0, hw, "heavyweight")))
    with pytest.raises(DownholeInputError, match="one uniform pipe"):
        DrillingSystem.vertical(two, friction=0.0).build("neutral")
    with pytest.raises(DownholeInputError, match="exceeds the well"):
        DrillingSystem(s.well, DrillString.uniform(9000.0, pipe), s.bit)
    with pytest.raises(DownholeInputError, match="friction"):
        DrillingSystem.table_5_1(friction=float("nan"))
    assert set(FIDELITIES) == {"lumped4", "lumped12", "neutral", "fem", "hybrid"}
