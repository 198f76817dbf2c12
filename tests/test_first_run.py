"""A plausible first run (issue 24, item 7): ``make run`` (``downhole demo``) drills a real-size
well and string, described once, and its numbers are those of a real rig: hook load = buoyed
string weight - WOB, WOB ~100 kN, TOB a few kN*m, surface torque below 40 kN*m, rotary speeds
of 50 and 120 rpm; the nominal case drills smoothly and the low-speed case sticks and slips.
examples/first_run.toml and examples/first_run_stickslip.toml are the same two cases."""

import json
import re
import tomllib
from pathlib import Path

import numpy as np
import pytest

from downhole.cli.simulate import DEMO_CASES, demo_scenario, operating_point
from downhole.sim.result import load_result
from downhole.units import display_units

ROOT = Path(__file__).resolve().parents[1]
RPM = 2 * np.pi / 60


@pytest.mark.parametrize("name, file", [("nominal", "first_run.toml"),
                                        ("stickslip", "first_run_stickslip.toml")])
def test_the_example_files_are_the_demo_cases(name, file):
    from downhole.scenario.schema import read_scenario

    data, _, _ = read_scenario(ROOT / "examples" / file)
    assert data == demo_scenario(name)
    with open(ROOT / "examples" / file, "rb") as fh:
        assert tomllib.load(fh) == demo_scenario(name)


def test_titles_give_the_operating_point_in_the_display_units():
    data = demo_scenario("nominal")
    assert operating_point(data, display_units("metric")) == "120 rpm, WOB 100 kN"
    assert operating_point(data, display_units("si")) == "120 rpm, WOB 100 kN"  # figures
    assert operating_point(data, display_units("oilfield")) == "120 rpm, WOB 22.48 klbf"
    for name in DEMO_CASES:
        assert "rad/s" not in demo_scenario(name)["title"]


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    from downhole.cli import main

    out = tmp_path_factory.mktemp("demo") / "out"
    assert main(["demo", "--out", str(out)]) == 0
    return out


def _second_half(res, ch):
    t = res.time
    return res[ch][t >= t[-1] / 2]


def test_demo_numbers_are_those_of_a_real_rig(demo):
    from downhole.scenario.system import build_system, parse_system

    data = demo_scenario("nominal")
    system = build_system(parse_system(data, "<demo>"), "<demo>", "lumped4")
    weight = system.hanging_weight()
    assert 800e3 < weight < 900e3  # 102 t of steel in 1200 kg/m^3 mud
    nom = load_result(demo / "nominal" / "result.nc")
    ss = load_result(demo / "stickslip" / "result.nc")
    # nominal: the steady state at 120 rpm, 100 kN holds
    assert np.allclose(_second_half(nom, "hook_load"), weight - 100e3, rtol=1e-3)
    # the hook is a force servo at 100 kN below the hanging weight: the bit gets 100 kN less the
    # string's ground damping alpha0 M v at the ROP (the same balance as the FEM's)
    mass = system.lumped_derivation().string_mass[0]
    rop = _second_half(nom, "bit_axial_velocity").mean()
    assert np.allclose(_second_half(nom, "wob"), 100e3 - 0.05 * mass * rop, rtol=1e-4)
    tob = _second_half(nom, "tob")
    assert 2e3 < tob.mean() < 10e3
    assert _second_half(nom, "surface_torque").max() < 40e3
    assert np.allclose(_second_half(nom, "bit_angular_velocity"), 120 * RPM, rtol=1e-3)
    s = json.loads((demo / "nominal" / "summary.json").read_text())
    assert s["stick_slip_severity"] < 0.01 and s["stuck_fraction"] == 0
    assert 20 < s["mean_rop"] < 200 and s["units"]["mean_rop"] == "m/h"  # metric by default
    # stick-slip at 50 rpm: the bit stops and runs at up to three times the surface speed
    s = json.loads((demo / "stickslip" / "summary.json").read_text())
    assert s["stick_slip_severity"] > 1 and s["stuck_fraction"] > 0.05
    w = _second_half(ss, "bit_angular_velocity")
    assert w.min() < 0.1 and w.max() > 2 * 50 * RPM
    # the top drive is the rig's (inertia and PI, as at every fidelity): it holds 50 rpm on
    # average and gives way a little as the string's torque swings
    top = _second_half(ss, "top_drive_angular_velocity")
    assert top.mean() == pytest.approx(50 * RPM, rel=0.02) and np.ptp(top) > 0
    # the surface sees plausible loads; the mean WOB and TOB are the set-point's
    hook = _second_half(ss, "hook_load")
    assert weight - 200e3 < hook.min() and hook.max() < weight
    assert 0 < _second_half(ss, "surface_torque").max() < 40e3
    assert 50e3 < _second_half(ss, "wob").mean() < 150e3
    assert 2e3 < _second_half(ss, "tob").mean() < 10e3
    assert s["mean_rop"] > 0  # the bit drills down, not up
    assert (demo / "stickslip" / "overview.png").stat().st_size > 10_000


def test_overview_states_the_operating_point_in_its_axes_units_and_shows_steady_lines(demo):
    """The figure's title gives the operating point in the axes' units (rpm, kN, m/h, not
    rad/s), and a steady 120 rpm is a flat line at 120 on a readable axis, not rounding noise
    around an offset ("1e-9 + 1.2e2")."""
    from downhole.analysis.plots import plot_overview

    res = load_result(demo / "nominal" / "result.nc")
    fig = plot_overview(res, title="nominal", units="metric")
    title = fig._suptitle.get_text()
    assert "surface 120 rpm" in title and "m/h" in title
    assert re.search(r"WOB (99\.\d|100) kN", title), title
    assert "rad/s" not in title
    fig.canvas.draw()
    for ax in fig.axes:
        assert ax.yaxis.get_offset_text().get_text() == "", ax.get_ylabel()
        lo, hi = ax.get_ylim()
        if "measured depth" in ax.get_ylabel():
            # 30 s at 111 m/h drill about 0.9 m at 3000 m: a metre-scale axis, not noise
            assert abs(hi - lo) > 0.5, ax.get_ylabel()  # (a depth axis points down)
        else:
            assert hi - lo > 1e-3 * max(abs(lo), abs(hi)), ax.get_ylabel()
    speed = next(a for a in fig.axes if a.get_ylabel() == "rotary speed [rpm]")
    lo, hi = speed.get_ylim()
    assert lo < 120 < hi and hi - lo > 5
