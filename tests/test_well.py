"""Well path: minimum curvature against a published example, section geometry, validation."""

import math

import numpy as np
import pytest

from downhole.errors import DownholeInputError
from downhole.well import Arc, BuildTurn, Tangent, Vertical, WellPath, read_survey_csv

FT = 0.3048


def test_survey_csv_oilfield_matches_published_minimum_curvature(tmp_path):
    # Published example: drillingformulas.com, "Minimum Curvature Method" (after Lyons,
    # "Formulas and Calculations for Drilling, Production and Workover", 2nd ed.):
    # stations 3500 ft / 15 deg / 20 deg and 3600 ft / 25 deg / 45 deg give
    # North = 27.22 ft, East = 19.45 ft, TVD = 94.01 ft (dogleg 12.95 deg, RF 1.00408).
    f = tmp_path / "survey.csv"
    f.write_text("MD,INC,AZI\n3500,15,20\n3600,25,45\n")
    w = read_survey_csv(f, units="oilfield")
    st = w.stations
    d = np.array([st["north"][1] - st["north"][0], st["east"][1] - st["east"][0],
                  st["tvd"][1] - st["tvd"][0]])
    ref = np.array([27.22, 19.45, 94.01]) * FT
    assert np.max(np.abs(d - ref)) < 0.1          # the acceptance bar (m)
    assert np.max(np.abs(d / FT - ref / FT)) < 0.01  # and the published rounding (ft)
    # the same survey in SI with an explicit md_ft header gives the same path
    f2 = tmp_path / "survey_si.csv"
    f2.write_text("md_ft,inclination,azimuth\n3500,15,20\n3600,25,45\n")
    assert np.allclose(read_survey_csv(f2).stations["north"], st["north"])


def _iscwsa1_stations():
    """ISCWSA test well #1 (Williamson, SPE-67616-PA, 2000) surveyed every 30 m: vertical to
    1200 m, build 2 deg/30 m to 60 deg at 2100 m, hold to 5100 m, build 3 deg/30 m to 90 deg at
    5400 m, hold to 8000 m, azimuth 75 deg."""
    md = np.concatenate([np.arange(0.0, 8000.0, 30.0), [8000.0]])
    inc = np.interp(md, [0, 1200, 2100, 5100, 5400, 8000], [0, 0, 60, 60, 90, 90])
    azi = np.where(md > 1200, 75.0, 0.0)
    return md, inc, azi


def test_survey_csv_matches_published_iscwsa_well_1(tmp_path):
    # Published minimum-curvature positions (north, east, TVD in m) of ISCWSA well #1 from the
    # ISCWSA MWD error-model example workbook (error-model-example-mwdrev5-1-iscwsa-1.xlsx),
    # as tabulated in github.com/jonnymaserati/welleng tests/ISCWSA_code_ex1.csv.
    published = {1500.0: (13.415, 50.064, 1493.945), 2100.0: (111.219, 415.076, 1944.294),
                 3000.0: (312.949, 1167.941, 2394.294), 5100.0: (783.651, 2924.625, 3444.294),
                 5250.0: (819.416, 3058.103, 3501.533), 5400.0: (857.797, 3201.342, 3521.056),
                 8000.0: (1530.727, 5712.749, 3521.056)}
    md, inc, azi = _iscwsa1_stations()
    f = tmp_path / "iscwsa1.csv"
    f.write_text("MD,INC,AZI\n" + "".join(f"{a:.1f},{b:.6f},{c:.1f}\n"
                                          for a, b, c in zip(md, inc, azi)))
    w = read_survey_csv(f)                       # SI: metres and degrees
    for m, ref in published.items():
        got = w.position(m)
        assert np.max(np.abs(got - np.array(ref))) < 0.1, (m, got, ref)   # acceptance bar
        assert np.max(np.abs(got - np.array(ref))) < 2e-3, (m, got, ref)  # published rounding
    # and the stations' inclination / azimuth come back
    assert math.degrees(float(w.inclination(3000.0))) == pytest.approx(60.0)
    assert math.degrees(float(w.azimuth(3000.0))) == pytest.approx(75.0)


def test_table_5_1_arc_geometry_is_analytic():
    R, th = 4000.0, math.radians(30)
    w = WellPath.from_sections([Vertical(2000), Vertical(1000), Arc(R, th)])
    assert w.total_depth == pytest.approx(3000 + R * th)
    s = 3000 + R * th * np.array([0.25, 0.5, 1.0])
    ang = th * np.array([0.25, 0.5, 1.0])
    assert np.allclose(w.tvd(s), 3000 + R * np.sin(ang), atol=1e-6)
    assert np.allclose(w.position(s)[:, 0], R * (1 - np.cos(ang)), atol=1e-6)
    assert np.allclose(w.inclination(s), ang)
    assert np.allclose(w.curvature(s), 1 / R)
    assert np.allclose(w.curvature(1500.0), 0.0)


def test_build_and_turn_positions_equal_integrated_tangent():
    w = WellPath.from_sections([Vertical(300), Arc(600, 0.6, azimuth=0.4),
                                BuildTurn(500, math.radians(70), math.radians(120)),
                                Tangent(200)])
    md = np.linspace(0, w.total_depth, 20001)
    t = w.tangent(md)
    pos = np.concatenate([[np.zeros(3)], np.cumsum(0.5 * (t[1:] + t[:-1]) * np.diff(md)[:, None],
                                                     axis=0)])
    assert np.max(np.abs(pos - w.position(md))) < 1e-3
    st = w.stations
    assert math.degrees(st["inclination"][-1]) == pytest.approx(70)
    assert math.degrees(st["azimuth"][-1]) == pytest.approx(120)
    # dt/ds equals the finite-difference derivative of the tangent inside an interval
    s0 = 700.0
    fd = (w.tangent(s0 + 1e-3) - w.tangent(s0 - 1e-3)) / 2e-3
    assert np.allclose(w.curvature_vector(s0), fd, atol=1e-7)


@pytest.mark.parametrize("md,inc,azi,msg", [
    ([0, 100, 90], [0, 5, 10], [0, 0, 0], "must increase"),
    ([0, 100], [0, 190], [0, 0], "inclination"),
    ([0], [0], [0], "at least 2"),
])
def test_bad_surveys_are_rejected_precisely(md, inc, azi, msg):
    with pytest.raises(DownholeInputError, match=msg):
        WellPath.from_survey(md, inc, azi)


def test_bad_sections_and_csv(tmp_path):
    with pytest.raises(DownholeInputError, match="length must be > 0"):
        WellPath.from_sections([Vertical(-5)])
    with pytest.raises(DownholeInputError, match="radius must be > 0"):
        WellPath.from_sections([Vertical(5), Arc(-1, 0.1)])
    f = tmp_path / "bad.csv"
    f.write_text("MD,INC,AZI\n0,0,0\n100,abc,0\n")
    with pytest.raises(DownholeInputError, match="line 3, column 'INC'"):
        read_survey_csv(f)
    with pytest.raises(DownholeInputError, match="outside the path"):
        WellPath.from_sections([Vertical(100)]).tvd(150.0)
