"""Meshes derived from the description (issue 23, item 5).

Without element or node counts the FEM and the hybrid put a node at every string joint and at
every survey station where the path turns, with elements no longer than 50 m and turning by at
most 2 deg, so that any survey and string run with the defaults; given counts keep the seed's
meshes; a count that is too small is refused with the key to change and a value that works."""

import itertools
import math

import numpy as np
import pytest
from scipy.optimize import brentq

from downhole.errors import DownholeInputError, ScenarioError
from downhole.params import get_preset
from downhole.string.drillstring import DrillString, StringSegment, pipe_section
from downhole.string.fem import fem_model
from downhole.string.hybrid import hybrid_model
from downhole.system import DrillingSystem
from downhole.well.path import Vertical, WellPath

FT = 0.3048
PIPE = pipe_section("5 in", "4.276 in")
HWDP = pipe_section("5 in", "3 in")
COLLAR = pipe_section("6.5 in", "2.8125 in")


def _j_well_ft():
    """A 13,000 ft J-well surveyed every 100 ft: vertical to 5000 ft, build at 3 deg/100 ft to
    45 deg (5000..6500 ft), hold to 13,000 ft; azimuth 30 deg."""
    md = np.arange(0.0, 13000.0 + 1.0, 100.0)
    inc = np.clip((md - 5000.0) * 3.0 / 100.0, 0.0, 45.0)
    return md, inc, np.full_like(md, 30.0)


def _j_well():
    md, inc, azi = _j_well_ft()
    return WellPath.from_survey(md, inc, azi, length_unit="ft")


def _string():
    # joints off the survey stations (11,750 ft and 12,380 ft)
    return DrillString((StringSegment(11750 * FT, PIPE), StringSegment(630 * FT, HWDP,
                                                                       "heavyweight"),
                        StringSegment(620 * FT, COLLAR, "collar")), mud_density=1200.0)


@pytest.fixture(scope="module")
def jwell():
    return DrillingSystem(well=_j_well(), string=_string(), bit=get_preset("table_5_1").bit,
                          friction=0.3)


def _turn_per_element(well, md):
    """Angle between the tangents at the ends of each element, rad."""
    t = well.tangent(md)
    return np.arccos(np.clip(np.sum(t[:-1] * t[1:], axis=1), -1.0, 1.0))


def test_100_ft_survey_builds_at_fem_and_hybrid_with_defaults(jwell):
    joints = jwell.top_md + jwell.string.boundaries[1:-1]
    assert joints / FT == pytest.approx([11750.0, 12380.0])
    fem = jwell.build("fem")
    # vertical 1524 m in 50 m elements (31), build 457.2 m: 15 stations 30.48 m apart at
    # 3 deg / 100 ft, two 1.5 deg elements each (30), hold 1981.2 m split by the two joints:
    # 11,750 - 6500 ft = 1600.2 m (33), 630 ft (4), 620 ft (4)
    assert fem.n_nodes - 1 == 31 + 30 + 33 + 4 + 4
    h = np.diff(fem.node_md)
    assert h.max() <= 50.0 + 1e-9
    assert _turn_per_element(jwell.well, fem.node_md).max() <= math.radians(2.0) + 1e-9
    for j in joints:
        assert np.min(np.abs(fem.node_md - j)) < 1e-6
    # every station where the path turns is a node (kick-off, build, end of build)
    md, inc, _ = _j_well_ft()
    for m in md[(md >= 5000) & (md <= 6500)] * FT:
        assert np.min(np.abs(fem.node_md - m)) < 1e-6
    hyb = jwell.build("hybrid")
    b, c = jwell.wave_points()
    assert (b, c) == pytest.approx((2.0 / 3.0 * 5000 * FT, 5000 * FT))  # C at the kick-off
    assert hyb.node_md[hyb.node_b] == pytest.approx(b)
    assert hyb.node_md[hyb.node_c] == pytest.approx(c)
    assert hyb.info["n_ab"] == 22          # 1016 m in 50 m elements: 21
    assert hyb.info["n_cd"] == fem.n_nodes - 31   # the FEM's nodes from kick-off down
    for j in joints:
        assert np.min(np.abs(hyb.node_md - j)) < 1e-6


def test_100_ft_survey_runs_from_a_scenario_file_with_defaults(tmp_path):
    import tomllib

    from downhole.scenario.system import run_system_scenario, validate_system_scenario

    md, inc, azi = _j_well_ft()
    (tmp_path / "j.csv").write_text("MD,INC,AZI\n" + "".join(
        f"{a:g},{b:g},{c:g}\n" for a, b, c in zip(md, inc, azi)))
    text = """
[model]
fidelity = "fem"
[model.fem]
friction = 0.3
[model.hybrid]
friction = 0.3
[well]
survey = "j.csv"
units = "oilfield"
[string]
mud_density = "1200 kg/m^3"
[[string.segments]]
kind = "pipe"
length = "11750 ft"
outer_diameter = "5 in"
inner_diameter = "4.276 in"
[[string.segments]]
kind = "heavyweight"
length = "630 ft"
outer_diameter = "5 in"
inner_diameter = "3 in"
[[string.segments]]
kind = "collar"
outer_diameter = "6.5 in"
inner_diameter = "2.8125 in"
[operation]
surface_speed = "10 rad/s"
rop = "10 mm/s"
[simulation]
duration = "0.2 s"
"""
    path = tmp_path / "j.toml"
    path.write_text(text)
    data = tomllib.loads(text)
    for fid, nodes in (("fem", 103), ("hybrid", 22 + 72)):
        _, _, _, model = validate_system_scenario(data, str(path), fid)
        assert model.n_nodes == nodes
        r = run_system_scenario(data, str(path), text, fidelity=fid)
        assert r.attrs["fidelity"] == fid
        assert r.time[-1] == pytest.approx(0.2)
        assert np.all(np.isfinite(r["bit_angular_velocity"]))
        assert np.all(np.isfinite(r["wob"]))


def _two_segment_torsional_f1(upper, l1, lower, l2):
    """First torsional frequency (Hz) of two uniform bars in series, top clamped, bottom free:
    Z1 cot(w L1 / c1) = Z2 tan(w L2 / c2), Z = J sqrt(rho G) (continuity of twist and torque)."""
    z1, c1 = upper.torsional_impedance, upper.torsional_wave_speed
    z2, c2 = lower.torsional_impedance, lower.torsional_wave_speed

    def g(w):
        return z1 * math.cos(w * l1 / c1) * math.cos(w * l2 / c2) \
            - z2 * math.sin(w * l1 / c1) * math.sin(w * l2 / c2)

    w_hi = math.pi / 2 / max(l1 / c1, l2 / c2)   # below both quarter-wave limits
    while g(w_hi) > 0:
        w_hi *= 1.05
    return brentq(g, 1e-9, w_hi, xtol=1e-14) / (2 * math.pi)


@pytest.mark.parametrize("with_collars", [False, True])
def test_refinement_converges_to_the_analytic_first_torsional_frequency(with_collars):
    if with_collars:
        ds = DrillString((StringSegment(2800.0, PIPE), StringSegment(200.0, COLLAR, "collar")))
        exact = _two_segment_torsional_f1(PIPE, 2800.0, COLLAR, 200.0)
    else:
        ds = DrillString.uniform(3000.0, PIPE)
        exact = PIPE.torsional_wave_speed / (4 * 3000.0)   # quarter wave
    well = WellPath.from_sections([Vertical(3000.0)])
    errors = []
    for h in (200.0, 100.0, 50.0, 25.0):
        m = fem_model(well, ds, max_element_length=h)
        assert np.diff(m.node_md).max() <= h + 1e-9
        f1 = m.natural_frequencies("torsional", 1, top="fixed")[0]
        errors.append(abs(f1 / exact - 1.0))
    # second order: each halving of the element length divides the error by about 4
    for coarse, fine in itertools.pairwise(errors):
        assert coarse / 4.5 < fine < coarse / 3.5
    assert errors[2] < 5e-5   # 50 m
    # the default mesh is the 50 m one
    default = fem_model(well, ds).natural_frequencies("torsional", 1, top="fixed")[0]
    assert abs(default / exact - 1.0) == pytest.approx(errors[2])


def test_given_counts_keep_the_seed_meshes():
    # Table 5.1: stations 0, 2000, 3000 (kick-off), 5094.4 m; 107 elements spread in proportion
    # to length: 42 on AB, 21 on BC, 44 on the arc (the 432-state FEM)
    m = fem_model(n_elements=107)
    td = 3000.0 + 4000.0 * math.pi / 6
    expected = np.concatenate([np.linspace(0, 2000, 43), np.linspace(2000, 3000, 22)[1:],
                               np.linspace(3000, td, 45)[1:]])
    assert m.node_md == pytest.approx(expected, abs=1e-9)
    h = hybrid_model("hybrid68")
    assert h.node_md == pytest.approx(np.concatenate([np.linspace(0, 2000, 4),
                                                      np.linspace(3000, td, 13)]), abs=1e-9)
    # derived Table 5.1 mesh: nodes at 0, 3000 m and the bit; 60 + 42 elements of <= 50 m
    d = fem_model()
    assert d.node_md == pytest.approx(np.concatenate([np.linspace(0, 3000, 61),
                                                      np.linspace(3000, td, 43)[1:]]), abs=1e-9)


def test_hybrid_counts_also_put_nodes_on_the_joints():
    well = WellPath.from_sections([Vertical(3000.0)])
    ds = DrillString((StringSegment(2500.0, PIPE), StringSegment(350.0, HWDP, "heavyweight"),
                      StringSegment(150.0, COLLAR, "collar")))
    m = hybrid_model("hybrid24", well=well, string=ds, md_b=1000.0, md_c=2000.0)
    assert m.node_md[m.node_c:] == pytest.approx([2000.0, 2500.0, 2850.0, 3000.0])


def test_too_few_elements_name_the_key_and_a_count_that_works(jwell):
    with pytest.raises(DownholeInputError) as info:
        jwell.build("fem", n_elements=107)
    msg = str(info.value)
    # 130 station intervals, two of them split by a joint: 132 sections
    assert "n_elements >= 132" in msg and "model.fem.n_elements" in msg
    assert jwell.build("fem", n_elements=132).n_nodes == 133
    with pytest.raises(DownholeInputError) as info:
        jwell.build("hybrid", preset="hybrid68")
    msg = str(info.value)
    # AB: 0..1016 m holds 33 stations inside (100..3300 ft): 34 sections, 35 nodes
    assert "n_ab >= 35" in msg and "model.hybrid.n_ab" in msg
    assert jwell.build("hybrid", preset="hybrid68", n_ab=35, n_cd=200).info["n_ab"] == 35
    with pytest.raises(DownholeInputError) as info:
        jwell.lumped_derivation(reference_elements=100)
    assert "reference_elements >= 132" in str(info.value)


def test_scenario_mesh_errors_name_the_file_key(tmp_path):
    from downhole.scenario.system import validate_system_scenario

    data = {"model": {"fidelity": "fem", "fem": {"n_elements": 2}},
            "well": {"md": [0, 500, 1000, 1500], "inclination": [0, 0, 10, 20],
                     "azimuth": [0, 0, 0, 0]},
            "string": {"segments": [{"kind": "pipe", "outer_diameter": "5 in",
                                     "inner_diameter": "4.276 in"}]},
            "operation": {"rop": "10 mm/s"}, "simulation": {"duration": "0.1 s"}}
    with pytest.raises(ScenarioError) as info:
        validate_system_scenario(data, "x.toml")
    assert info.value.field == "model.fem.n_elements"
    assert "n_elements >= 2" not in str(info.value) and "n_elements >= 3" in str(info.value)
    data["model"]["fem"]["n_elements"] = 3
    validate_system_scenario(data, "x.toml")
    data["model"] = {"fidelity": "hybrid", "hybrid": {"n_ab": 2, "n_cd": 2}}
    with pytest.raises(ScenarioError) as info:
        validate_system_scenario(data, "x.toml")
    assert info.value.field == "model.hybrid.n_cd" and "n_cd >= 3" in str(info.value)


def test_preset_dialect_meshes_the_described_survey_by_default_too():
    from downhole.scenario.directional import validate_directional_scenario

    md, inc, azi = _j_well_ft()
    base = {"well": {"md": (md * FT).tolist(), "inclination": inc.tolist(),
                     "azimuth": azi.tolist()},
            "operation": {"surface_speed": "10 rad/s", "wob": "80 kN"},
            "simulation": {"duration": "0.1 s", "dt": "1 ms"}}
    for fid, nodes in (("fem", 31 + 30 + 40 + 1), ("hybrid", 22 + 71)):
        data = {**base, "model": {"fidelity": fid, "preset": "table_5_1", "friction": 0.3}}
        _, _, model = validate_directional_scenario(data, "x.toml")
        # the preset's uniform pipe over the whole well: no joints; 40 elements on the hold
        assert model.n_nodes == nodes, fid
    data = {**base, "model": {"fidelity": "fem", "fem": {"n_elements": 107}}}
    with pytest.raises(ScenarioError) as info:
        validate_directional_scenario(data, "x.toml")
    assert info.value.field == "model.fem.n_elements" and "n_elements >= 130" in str(info.value)
