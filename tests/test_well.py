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
