"""Plausibility, not only validity (issue 24, item 1): every physical input has the range of a
real rig, and a value outside it is refused with the field (1-based positions), the value as
written and in the range's unit, the range and the likely fix; the geometry is checked as a
whole (bit in the hole, string ODs below the hole and the bit), survey curvature and units
against the header; a unit typo gets "did you mean". Every refusal is one line and exit 2."""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest

from downhole.cli import main
from downhole.errors import DownholeInputError, ScenarioError
from downhole.plausible import (
    MAX_DEPTH,
    MAX_DOGLEG,
    MAX_HOOK_LOAD,
    PLAUSIBLE,
    check_scenario,
    check_value,
)
from downhole.scenario import load_scenario, validate_data

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _edit(tmp_path, base: str, *subs, extra: str = "", name: str = "s.toml") -> Path:
    """``base`` example with each ``(old, new)`` replaced once (old must be there) and ``extra``
    appended."""
    text = (EXAMPLES / base).read_text()
    for old, new in subs:
        assert old in text, old
        text = text.replace(old, new, 1)
    p = tmp_path / name
    p.write_text(text + extra)
    return p


def _refused(tmp_path, capsys, path: Path) -> str:
    """The one line `downhole simulate` prints for ``path``, which it refuses with exit 2."""
    out = tmp_path / "out"
    assert main(["simulate", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert not out.exists()
    return err


FIRST = "first_run.toml"
OIL = "oilfield_units.toml"

# (base, substitutions, extra, field, the message after "FILE: field: ")
CASES = {
    "rotary speed in rad/s meant as rpm": (
        FIRST, [('surface_speed = "120 rpm"', 'surface_speed = "120 rad/s"')], "",
        "operation.surface_speed",
        '120 rad/s = 1,146 rpm is above 400 rpm, the fastest top drives; did you mean '
        '"120 rpm"?'),
    "bare WOB in kN": (
        FIRST, [('wob = "100 kN"', "wob = 25")], "", "operation.wob",
        '25 (a bare number is N) = 0.025 kN is below 1 kN, a bit needs at least 1 kN to cut; '
        'did you mean "25 kN"?'),
    "bare WOB in an oilfield file is klbf": (
        OIL, [('wob = "20 klbf"', "wob = 25")], "", "operation.wob",
        '25 (a bare number is N) = 0.025 kN is below 1 kN, a bit needs at least 1 kN to cut; '
        'did you mean "25 klbf"?'),
    "bare ROP in m/h": (
        FIRST, [('wob = "100 kN"', "rop = 30")], "", "operation.rop",
        '30 (a bare number is m/s) = 108,000 m/h is above 250 m/h, the fastest drilling in '
        'soft rock; did you mean "30 m/h"?'),
    "bare TOB in kN m": (
        FIRST, [], "\n[torque_drag]\ntob = 5\n", "torque_drag.tob",
        '5 (a bare number is N*m) = 0.005 kN*m is below 0.1 kN*m, a bit or top drive turning '
        'a string needs at least 0.1 kN*m; did you mean "5 kN*m"?'),
    "bare collar OD in inches, the 2nd segment": (
        FIRST, [('outer_diameter = "6.75 in"', "outer_diameter = 6.75")], "",
        "string.segments[2].outer_diameter",
        '6.75 (a bare number is m) = 266 in is above 14 in, the largest drill collars; did '
        'you mean "6.75 in"?'),
    "bare bit radius in inches": (
        FIRST, [('radius = "4.25 in"', "radius = 4.25")], "", "bit.radius",
        '4.25 (a bare number is m) = 167 in is above 18 in, a 36 in bit, the largest; did you '
        'mean "4.25 in"?'),
    "bare mud weight in lb/gal": (
        FIRST, [('mud_density = "1200 kg/m^3"', "mud_density = 10")], "", "string.mud_density",
        '10 (a bare number is kg/m^3) = 10 kg/m^3 is below 500 kg/m^3, the lightest (foamed) '
        'muds; 0 means no mud; did you mean "10 lb/gal"?'),
    "bare depth in feet": (
        FIRST, [('length = "3000 m"', "length = 40000")], "", "well.sections[1].length",
        '40000 (a bare number is m) = 40,000 m is above 15,000 m, the deepest wells drilled '
        '(15 km); did you mean "40000 ft"?'),
    "hole smaller than the bit": (
        FIRST, [("[[well.sections]]", '[well]\nhole_diameter = "8 in"\n\n[[well.sections]]')],
        "", "well.hole_diameter",
        "8 in is below the bit's diameter, 8.5 in (2 x bit.radius (4.25 in)): a bit drills a "
        "hole at least its own size; check hole_diameter and the bit's radius (a radius, not a "
        "diameter?)"),
    "collar wider than the bit": (
        FIRST, [('outer_diameter = "6.75 in"', 'outer_diameter = "9 in"')], "",
        "string.segments[2].outer_diameter",
        "9 in is not below the bit's diameter, 8.5 in (2 x bit.radius (4.25 in)): the string "
        "must pass through the hole the bit drills; check the segment's outer_diameter and the "
        "bit's radius (a radius, not a diameter?)"),
    "pipe as wide as a bit whose radius is given as half its radius": (
        FIRST, [('radius = "4.25 in"', 'radius = "2.5 in"')], "",
        "string.segments[1].outer_diameter",
        "127 mm is not below the bit's diameter, 127 mm (2 x bit.radius (2.5 in)): the string "
        "must pass through the hole the bit drills; check the segment's outer_diameter and the "
        "bit's radius (a radius, not a diameter?)"),
    "stabilizer wider than the hole": (
        FIRST, [], '\n[[string.stabilizers]]\ndistance_from_bit = "10 m"\n'
                   'outer_diameter = "9 in"\n',
        "string.stabilizers[1].outer_diameter",
        "9 in is wider than the hole's diameter, 8.5 in (the bit's diameter, 2 x bit.radius "
        "(4.25 in); [well] hole_diameter unset): a stabilizer is at most full gauge; check its "
        "outer_diameter, the bit's radius or [well] hole_diameter"),
    "unit typo klb": (
        FIRST, [('wob = "100 kN"', 'wob = "30 klb"')], "", "operation.wob",
        "quantity '30 klb' has unit 'kilopound', which cannot be converted to N; did you mean "
        "\"30 klbf\"?"),
    "unit typo ppg": (
        FIRST, [('mud_density = "1200 kg/m^3"', 'mud_density = "10 ppg"')], "",
        "string.mud_density",
        "cannot parse quantity '10 ppg': 'ppg' is not defined in the unit registry; did you "
        "mean \"10 lb/gal\"?"),
    "unit typo rmp": (
        FIRST, [('surface_speed = "120 rpm"', 'surface_speed = "120 rmp"')], "",
        "operation.surface_speed",
        "cannot parse quantity '120 rmp': 'rmp' is not defined in the unit registry; did you "
        "mean \"120 rpm\"?"),
    "arc sharper than any rotating string passes": (
        FIRST, [('type = "vertical"\nlength = "3000 m"',
                 'type = "vertical"\nlength = "2990 m"\n\n[[well.sections]]\ntype = "arc"\n'
                 'radius = "20 m"\nangle = "30 deg"')], "", "well.sections[2]",
        "radius 20 m is a dogleg severity of 85.94 deg/30m (87.32 deg/100ft), above 30 deg/30m, "
        "the sharpest curve a rotating string passes; check the section's radius or length and "
        "its units (a radius of R m curves 1719 / R deg/30m)"),
    "stations with a 60 deg/30m dogleg": (
        FIRST, [('[[well.sections]]\ntype = "vertical"\nlength = "3000 m"',
                 "[well]\nmd = [0, 2990, 3000]\ninclination = [0, 0, 20]\n"
                 "azimuth = [0, 0, 0]")], "", "well.inclination",
        "stations 2 to 3: dogleg severity 60 deg/30m (20 deg over 10 m, MD 2,990 to 3,000 m) "
        "is above 30 deg/30m, the sharpest curve a rotating string passes (medium-radius "
        "wells); check the stations' units (inclination and azimuth in degrees, MD in "
        "metres)"),
    "string longer than the well": (
        FIRST, [('length = "2820 m"', 'length = "3500 m"'),
                ('outer_diameter = "6.75 in"', 'length = "180 m"\nouter_diameter = "6.75 in"')],
        "", "string.segments",
        "the string (3,680 m = 12,073.5 ft, 2 segments) is longer than the well (3,000 m = "
        "9,842.52 ft); check the segments' lengths and the well's depth unit (a survey in feet "
        'needs units = "oilfield")'),
    "stations in feet read as metres": (
        FIRST, [('[[well.sections]]\ntype = "vertical"\nlength = "3000 m"',
                 "[well]\nmd = [0, 5000, 20000]\ninclination = [0, 0, 0]\n"
                 "azimuth = [0, 0, 0]")], "", "well.md",
        'station 3: the deepest station, 20000 m, is beyond any well drilled (15000 m); if '
        'the depths are in feet, say units = "oilfield"'),
}


@pytest.mark.parametrize("case", list(CASES))
def test_each_refusal_is_one_precise_line_and_exit_2(tmp_path, capsys, case):
    base, subs, extra, field, message = CASES[case]
    p = _edit(tmp_path, base, *subs, extra=extra)
    err = _refused(tmp_path, capsys, p)
    assert err.startswith(f"error: {p}: {field}: {message}"), err


def test_survey_csv_dogleg_and_header_units_name_the_line(tmp_path, capsys):
    (tmp_path / "w.csv").write_text("# a survey\nmd,inc,azi\n0,0,0\n2990,0,0\n3000,20,0\n")
    p = _edit(tmp_path, FIRST, ('[[well.sections]]\ntype = "vertical"\nlength = "3000 m"',
                                '[well]\nsurvey = "w.csv"'))
    err = _refused(tmp_path, capsys, p)
    assert err == (f"error: {p}: well.survey: {tmp_path / 'w.csv'}: line 5, column 'inc': "
                   "dogleg severity 60 deg/30m (20 deg over 10 m, MD 2,990 to 3,000 m) is "
                   "above 30 deg/30m, the sharpest curve a rotating string passes "
                   "(medium-radius wells); check the stations' units (inclination and azimuth "
                   "in degrees, MD in metres)"), err
    # a survey whose header says metres, in a file that says feet
    (tmp_path / "ft.csv").write_text((EXAMPLES / "oilfield_survey_ft.csv").read_text()
                                     .replace("MD,INC,AZI", "MD (m),INC,AZI"))
    p = _edit(tmp_path, OIL, ('survey = "oilfield_survey_ft.csv"', 'survey = "ft.csv"'))
    err = _refused(tmp_path, capsys, p)
    assert err == (f"error: {p}: well.survey: {tmp_path / 'ft.csv'}: line 2, column 'MD (m)': "
                   "the header says measured depth in metres, but units = 'oilfield' says "
                   'feet; did you mean units = "si"?'), err
    # without units in the file, the header decides: a 6000 m well
    from downhole._schema import parse
    from downhole.scenario.directional import _well

    p = _edit(tmp_path, OIL, ('survey = "oilfield_survey_ft.csv"', 'survey = "ft.csv"'),
              ('units = "oilfield"\n', ""))
    data, source, _ = load_scenario(p)
    sc = parse(data, source)
    assert _well(sc, source, None).total_depth == pytest.approx(6000.0)


def test_a_profile_names_its_breakpoint_1_based(tmp_path, capsys):
    p = _edit(tmp_path, "fig2.3.toml", ('rop = "10 mm/s"', 'rop = [[0, "10 mm/s"], [5, 30]]'))
    err = _refused(tmp_path, capsys, p)
    assert f"{p}: operation.rop[2]: 30 (a bare number is m/s) = 108,000 m/h is above 250 " \
           'm/h, the fastest drilling in soft rock; did you mean "30 m/h"?' in err, err


def test_schema_errors_name_list_entries_1_based(tmp_path, capsys):
    p = _edit(tmp_path, FIRST, ('outer_diameter = "6.75 in"\n', ""))
    err = _refused(tmp_path, capsys, p)
    assert f"{p}: string.segments[2]: give outer_diameter and inner_diameter" in err, err


def test_sil_files_get_the_same_ranges(tmp_path):
    from downhole.sil.scenario import load_sil_scenario

    p = tmp_path / "sil.toml"
    p.write_text('[model]\nfidelity = "lumped4"\n[operation]\nwob = 25\n')
    with pytest.raises(ScenarioError, match=re.escape(
            'operation.wob: 25 (a bare number is N) = 0.025 kN is below 1 kN, a bit needs at '
            'least 1 kN to cut; did you mean "25 kN"?')):
        load_sil_scenario(p)
    p.write_text('[model]\nfidelity = "lumped4"\n[operation]\nwob = "25 kN"\n')
    load_sil_scenario(p)


def test_plausible_neighbours_pass(tmp_path):
    # the same fields, written right, at the edges of real rigs
    p = _edit(tmp_path, FIRST, ('surface_speed = "120 rpm"', 'surface_speed = "400 rpm"'),
              ('wob = "100 kN"', 'wob = "150 klbf"'),
              ('mud_density = "1200 kg/m^3"', 'mud_density = "18 lb/gal"'),
              ("[[well.sections]]", '[well]\nhole_diameter = "9.875 in"\n\n[[well.sections]]'),
              extra='\n[[string.stabilizers]]\ndistance_from_bit = "10 m"\n'
                    'outer_diameter = "9.875 in"\n')
    data, source, _ = load_scenario(p)
    validate_data(data, source)


def test_every_example_is_plausible():
    files = sorted(EXAMPLES.glob("*.toml"))
    assert len(files) > 20
    for f in files:
        data, source, _ = load_scenario(f)  # check_dialect: the ranges and the geometry
        check_scenario(data, source)


def test_the_table_agrees_with_the_other_limits():
    from downhole.system import MAX_STRING_WEIGHT
    from downhole.units import MAX_ROTARY_SPEED
    from downhole.well.path import MAX_SURVEY_MD

    assert PLAUSIBLE["rotary_speed"].high == MAX_ROTARY_SPEED
    assert MAX_SURVEY_MD == MAX_DEPTH == 15_000.0
    assert MAX_STRING_WEIGHT == MAX_HOOK_LOAD
    assert MAX_DOGLEG == pytest.approx(math.radians(1.0))  # 30 deg per 30 m
    # every range is inside what the units module admits at all, and quoted in a real unit
    from downhole.units import RANGES, to_si

    for kind, rng in PLAUSIBLE.items():
        lo, hi = RANGES[rng.dimension]
        assert lo <= rng.low < rng.high <= hi, kind
        assert to_si(f"1 {rng.unit}", rng.dimension) > 0, kind
        for unit in rng.fixes:
            assert to_si(f"1 {unit}", rng.dimension) > 0, (kind, unit)


@pytest.mark.parametrize("kind, raw, ok", [
    ("rotary_speed", "400 rpm", True), ("rotary_speed", "401 rpm", False),
    ("wob", "0 kN", True), ("wob", "0.9 kN", False), ("wob", "157 klbf", True),
    ("wob", "158 klbf", False), ("mud_density", 0, True), ("mud_density", "2.6 g/cm^3", True),
    ("mud_density", "22 lb/gal", False), ("pipe_od", "14 in", True), ("pipe_od", "15 in", False),
    ("bit_radius", "1.75 in", True), ("bit_radius", "1.7 in", False),
    ("depth", "49000 ft", True), ("depth", "49300 ft", False),
])
def test_range_edges(kind, raw, ok):
    if ok:
        assert check_value(kind, raw) is not None
    else:
        with pytest.raises(ValueError, match=r" is (above|below) "):
            check_value(kind, raw)


def test_a_value_of_another_dimension_is_left_to_the_schema():
    assert check_value("wob", "3 m") is None and check_value("wob", True) is None


def test_survey_reader_refuses_units_against_the_header(tmp_path):
    from downhole.well import read_survey_csv

    f = tmp_path / "s.csv"
    f.write_text("md_ft,inc,azi\n0,0,0\n1000,0,0\n")
    assert read_survey_csv(f).total_depth == pytest.approx(304.8)
    assert read_survey_csv(f, units="oilfield").total_depth == pytest.approx(304.8)
    with pytest.raises(DownholeInputError, match=re.escape(
            "line 1, column 'md_ft': the header says measured depth in feet, but units = 'si' "
            'says metres; did you mean units = "oilfield"?')):
        read_survey_csv(f, units="si")
