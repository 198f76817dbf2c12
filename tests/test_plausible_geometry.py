"""Ordinary slips of the pen give a precise refusal, not silent nonsense (issue "safe by
default"): a survey in feet read as metres, a survey file that is some other file of the host
(its contents never echoed), an azimuth of 721 deg, title lines and semicolons in a survey."""

from __future__ import annotations

from pathlib import Path

import pytest

from downhole.cli import main
from downhole.errors import DownholeInputError
from downhole.well import read_survey_csv

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _oilfield(tmp_path, survey_text, units_line='units = "oilfield"'):
    (tmp_path / "survey.csv").write_text(survey_text)
    text = (EXAMPLES / "oilfield_units.toml").read_text()
    text = text.replace('survey = "oilfield_survey_ft.csv"', 'survey = "survey.csv"')
    text = text.replace('units = "oilfield"\n', units_line + "\n", 1)
    p = tmp_path / "s.toml"
    p.write_text(text)
    return p


def test_a_survey_in_feet_read_as_metres_is_refused_by_the_strings_weight(tmp_path, capsys):
    # 13,000 ft J-well written in feet, without units = "oilfield": 13,000 m of well, and the
    # collars "to the rest of the well" would be 11,300 m of 6.5 in collars (~11,000 kN)
    survey = "md,inc,azi\n" + "".join(f"{md},{0 if md < 5000 else min(60, (md - 5000) / 100 * 3)},45\n"
                                      for md in range(0, 13001, 100))
    p = _oilfield(tmp_path, survey, units_line="")
    assert main(["simulate", str(p), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "beyond any rig's hook capacity" in err and "a survey in feet read as metres?" in err
    assert not (tmp_path / "out").exists()
    # the same file with its units said runs the check clean (the string weighs ~1,100 kN)
    p = _oilfield(tmp_path, survey)
    from downhole.scenario import load_scenario, validate_data

    data, source, _ = load_scenario(p)
    validate_data(data, source)


def test_a_survey_path_naming_another_file_never_echoes_it(tmp_path):
    secret = tmp_path / "secret.txt"
    secret.write_text("root:SECRET-HASH:19000:0:99999:7:::\nmore secret lines\n")
    with pytest.raises(DownholeInputError) as info:
        read_survey_csv(secret)
    msg = str(info.value).replace(str(secret), "<path>")
    assert msg.startswith("<path>: no survey header")
    assert "SECRET-HASH" not in msg and "19000" not in msg and "more secret" not in msg


def test_survey_with_title_lines_semicolons_and_tabs(tmp_path):
    rows = [(0, 0, 0), (500, 0, 0), (800, 9, 30), (1100, 18, 30)]
    ref = tmp_path / "ref.csv"
    ref.write_text("md,inc,azi\n" + "".join(f"{a},{b},{c}\n" for a, b, c in rows))
    expected = read_survey_csv(ref).stations
    for name, text in {
        "titled": "Well A-1 definitive survey\nCompany X, 2026\n\nMD,INC,AZI\n"
                  + "".join(f"{a},{b},{c}\n" for a, b, c in rows),
        "semicolon": "MD;Inc;Azi\n" + "".join(f"{a};{b};{c}\n" for a, b, c in rows),
        "tab": "md\tinc\tazi\n" + "".join(f"{a}\t{b}\t{c}\n" for a, b, c in rows),
        "spaces": "MD   INC   AZI\n" + "".join(f"{a}   {b}   {c}\n" for a, b, c in rows),
    }.items():
        f = tmp_path / f"{name}.csv"
        f.write_text(text)
        st = read_survey_csv(f).stations
        for k in ("md", "inclination", "azimuth", "north", "east", "tvd"):
            assert st[k] == pytest.approx(expected[k], abs=1e-9), (name, k)


@pytest.mark.parametrize("row, words", [
    ("800,9,721", "line 4, column 'azi': azimuth 721 deg is outside 0 to 360 deg"),
    ("800,9,1e300", "line 4, column 'azi': azimuth 1e+300 deg is outside 0 to 360 deg"),
    ("800,190,0", "line 4, column 'inc': inclination 190 deg is outside 0 to 180 deg"),
    ("800,nan,0", "line 4, column 'inc': is not a finite number"),
    ("800,,0", "line 4, column 'inc': is missing"),
    ("400,9,0", "line 4, column 'md': measured depth 400 m does not increase (line 3: 500 m)"),
    ("40000,9,0", "line 4, column 'md': the deepest station, 40000 m, is beyond any well "
                  "drilled (15000 m); if the depths are in feet"),
])
def test_bad_stations_name_the_file_line_and_column(tmp_path, row, words):
    f = tmp_path / "s.csv"
    f.write_text(f"# comment line\nmd,inc,azi\n0,0,0\n500,0,0\n{row}\n".replace(
        "0,0,0\n500,0,0\n", "500,0,0\n"))
    with pytest.raises(DownholeInputError) as info:
        read_survey_csv(f)
    assert f"{f}: {words}" in str(info.value)
