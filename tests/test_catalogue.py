"""Strings as drillers specify them (issue "safe by default", item 2): catalogue tubulars by
nominal size and weight with tool joints, the adjusted weight in hook load, torque and drag and
the models' masses; checked against published weights and a hand calculation."""

from __future__ import annotations

import math

import pytest

from downhole.errors import DownholeInputError
from downhole.string.catalogue import CATALOGUE, catalogue_section
from downhole.string.drillstring import DrillString, StringSegment, pipe_section
from downhole.system import DrillingSystem

LBFT = 0.45359237 / 0.3048  # kg/m per lb/ft
G = 9.81


@pytest.mark.parametrize("name, plain", [
    ("5in 19.50 S135 NC50", 17.932),        # the performance sheet's plain-end weight
    ("5-1/2in 21.90 S135 HT55", 19.814),
    ("8in DC 2-13/16", 150.0),              # API drill-collar table
    ("6-1/2in DC 2-13/16", 91.0),
    ("6-3/4in DC 2-13/16", 100.0),
    ("9-1/2in DC 3", 217.0),
])
def test_body_weights_against_published_values(name, plain):
    # steel 7850 kg/m^3 is 490 lb/ft^3, the API tables' density; the collar table rounds to
    # the pound
    rel = 4e-3 if CATALOGUE[name].kind == "pipe" else 1e-2
    assert CATALOGUE[name].plain_weight() == pytest.approx(plain, rel=rel)


def test_adjusted_weight_is_the_linear_mass():
    sec = catalogue_section("5in 19.50 S135 NC50")
    assert sec.linear_mass == pytest.approx(23.52 * LBFT, rel=1e-12)
    assert sec.outer_diameter == pytest.approx(0.127) and sec.weight_factor == pytest.approx(
        23.52 / 17.932, rel=2e-3)
    # stiffness is the body's; a collar is a plain bar
    assert sec.area == pytest.approx(pipe_section("5 in", "4.276 in").area)
    assert catalogue_section("8in DC 2-13/16").weight_factor == 1.0
    assert catalogue_section('5" 19.50 s135 nc50').linear_mass == sec.linear_mass


def test_hook_load_of_5in_19_5_dp_with_nc50_joints_is_the_hand_calculation():
    """3000 m vertical, all 5" 19.50 lb/ft S-135 NC50, 1200 kg/m^3 mud: by hand, hook load =
    adjusted weight x length x g x buoyancy factor (1 - rho_mud/rho_steel)."""
    L, mud = 3000.0, 1200.0
    hand = 23.52 * LBFT * L * G * (1.0 - mud / 7850.0)
    string = DrillString((StringSegment(L, catalogue_section("5in 19.50 S135 NC50")),),
                         mud_density=mud, g=G)
    system = DrillingSystem.vertical(string)
    td = system.torque_drag(friction=(0.0,), wob=0.0)
    hook_td = float(td.hook_load["trip_out"][0, -1])  # bit at total depth, no friction
    fem = system.build("fem")
    for what, value in (("torque and drag", hook_td), ("FEM hanging weight", fem.buoyed_weight)):
        assert value == pytest.approx(hand, rel=1e-2), what
    # plain OD/ID pipe would weigh 24 % light: the point of the catalogue
    plain = DrillingSystem.vertical(DrillString((StringSegment(L, pipe_section(
        "5 in", "4.276 in")),), mud_density=mud, g=G)).build("fem").buoyed_weight
    assert plain / hand == pytest.approx(17.932 / 23.52, rel=5e-3)


def test_tool_joints_slow_the_waves_but_not_the_stiffness():
    sec = catalogue_section("5in 19.50 S135 NC50")
    plain = pipe_section("5 in", "4.276 in")
    k = sec.weight_factor
    assert sec.axial_wave_speed == pytest.approx(plain.axial_wave_speed / math.sqrt(k))
    assert sec.axial_impedance == pytest.approx(plain.axial_impedance * math.sqrt(k))


def test_unknown_names_are_refused_with_the_closest():
    with pytest.raises(DownholeInputError, match=r"did you mean '5in 19.50 S135 NC50'"):
        catalogue_section("5in 19.5 S135 NC50")


def test_a_scenario_segment_by_catalogue_name(tmp_path):
    from downhole.errors import ScenarioError
    from downhole.scenario import load_scenario, validate_data

    base = """
[model]
fidelity = "fem"
friction = 0.0
[well]
sections = [{type = "vertical", length = "3000 m"}]
[string]
mud_density = "1200 kg/m^3"
[[string.segments]]
{seg}
[bit]
preset = "table_5_1"
[operation]
surface_speed = "100 rpm"
wob = "50 kN"
[simulation]
duration = "1 s"
"""
    p = tmp_path / "s.toml"
    p.write_text(base.replace("{seg}", 'catalogue = "5in 19.50 S135 NC50"'))
    data, source, _ = load_scenario(p)
    validate_data(data, source)
    p.write_text(base.replace("{seg}", 'catalogue = "5in 19.50 S135 NC50"\nouter_diameter = "5 in"'))
    data, source, _ = load_scenario(p)
    with pytest.raises(ScenarioError, match=r"string.segments\[1\].*either catalogue or"):
        validate_data(data, source)
    p.write_text(base.replace("{seg}", 'catalogue = "5in 19 S135"'))
    data, source, _ = load_scenario(p)
    with pytest.raises(ScenarioError, match="no tubular '5in 19 S135' in the catalogue"):
        validate_data(data, source)
