"""A driller's "120" means rpm; downhole's bare numbers are SI (rad/s), so 120 would be 1146 rpm.
A rotary-speed set-point above any top drive's 400 rpm is refused naming the field, the value
in rpm and the likely fix, in the system scenario (every fidelity) and in SIL files."""

from __future__ import annotations

from pathlib import Path

import pytest

from downhole.cli import main
from downhole.errors import ScenarioError
from downhole.units import MAX_ROTARY_SPEED, check_rotary_speed

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def test_the_limit_is_400_rpm():
    assert MAX_ROTARY_SPEED == pytest.approx(41.8879, rel=1e-5)
    assert check_rotary_speed(41.8) == 41.8 and check_rotary_speed("400 rpm") == "400 rpm"
    with pytest.raises(ValueError, match=r'^120 \(a bare number is rad/s\) = 1,146 rpm is above '
                                         r'400 rpm, the fastest top drives; did you mean "120 '
                                         r'rpm"\?$'):
        check_rotary_speed(120)
    with pytest.raises(ValueError, match=r"^500 rpm = 500 rpm is above 400 rpm"):
        check_rotary_speed("500 rpm")


def _first_run(tmp_path, speed_line):
    text = (EXAMPLES / "first_run.toml").read_text()
    lines = [ln for ln in text.splitlines() if not ln.strip().startswith("surface_speed")]
    i = lines.index("[operation]")
    lines.insert(i + 1, speed_line)
    p = tmp_path / "s.toml"
    p.write_text("\n".join(lines) + "\n")
    return p


def test_a_bare_120_in_a_scenario_is_refused_with_the_fix(tmp_path, capsys):
    p = _first_run(tmp_path, "surface_speed = 120")
    assert main(["simulate", str(p), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert f"{p}: operation.surface_speed: " in err and 'did you mean "120 rpm"?' in err
    assert not (tmp_path / "out").exists()
    from downhole.scenario import load_scenario, validate_data

    data, source, _ = load_scenario(_first_run(tmp_path, 'surface_speed = "120 rpm"'))
    validate_data(data, source)  # the same number with its unit is fine


def test_sil_files_are_checked_too(tmp_path):
    from downhole.sil.scenario import load_sil_scenario

    p = tmp_path / "sil.toml"
    p.write_text('[model]\nfidelity = "lumped4"\n[operation]\nsurface_speed = 95.5\n')
    with pytest.raises(ScenarioError, match=r"operation.surface_speed: 95.5 \(a bare number is "
                                            r"rad/s\) = 912 rpm .*did you mean \"95.5 rpm\""):
        load_sil_scenario(p)
    p.write_text('[model]\nfidelity = "lumped4"\n[operation]\nsurface_speed = "95.5 rpm"\n')
    load_sil_scenario(p)
