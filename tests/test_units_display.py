"""Display units (docs/units.md): one option turns every output into oilfield units, and the
public Python constructors accept unit strings and pint quantities.

Every conversion is checked against an independent pint registry (a fresh
``pint.UnitRegistry()``, not downhole's), never against factors typed here.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import textwrap

import numpy as np
import pint
import pytest

from downhole.cli import main
from downhole.errors import DownholeInputError
from downhole.sim import load_result

U = pint.UnitRegistry()

#: What the oilfield system shows each standard channel in.
OILFIELD = {"wob": "klbf", "tob": "kft*lbf", "hook_load": "klbf", "surface_torque": "kft*lbf",
            "bit_angular_velocity": "rpm", "top_drive_angular_velocity": "rpm",
            "bit_axial_velocity": "ft/h", "top_drive_axial_velocity": "ft/h",
            "bit_axial_position": "ft", "depth_of_cut": "in", "bit_angle": "deg"}
SI = {"wob": "N", "tob": "N*m", "hook_load": "N", "surface_torque": "N*m",
      "bit_angular_velocity": "rad/s", "top_drive_angular_velocity": "rad/s",
      "bit_axial_velocity": "m/s", "top_drive_axial_velocity": "m/s",
      "bit_axial_position": "m", "depth_of_cut": "m", "bit_angle": "rad"}
METRIC_UNITS = {"mean_rop": ("m/s", "ft/h"), "mean_bit_angular_velocity": ("rad/s", "rpm"),
                "mse": ("Pa", "psi"), "stick_slip_severity": ("-", "-"),
                "stuck_fraction": ("-", "-"), "bit_bounce_fraction": ("-", "-")}


def pint_convert(values, src, dst):
    if src == "-":
        return np.asarray(values, float)
    return U.Quantity(np.asarray(values, float), src).to(dst).magnitude


# ------------------------------------------------------------------ end to end, one option
SURVEY_FT = "MD,INC,AZI\n0,0,0\n3000,0,0\n6000,0,0\n"

SCENARIO = """
title = "oilfield inputs"
[model]
fidelity = "lumped4"
friction = 0.0
[well]
survey = "well_ft.csv"
units = "oilfield"
[string]
mud_density = "10 lb/gal"
[[string.segments]]
kind = "pipe"
length = "5500 ft"
outer_diameter = "5 in"
inner_diameter = "4.276 in"
[[string.segments]]
kind = "collar"
outer_diameter = "6.5 in"
inner_diameter = "2.8125 in"
[bit]
preset = "table_5_1"
[operation]
surface_speed = "120 rpm"
wob = "20 klbf"
[simulation]
duration = "2 s"
record_dt = "10 ms"
"""


@pytest.fixture(scope="module")
def oilfield_run(tmp_path_factory):
    d = tmp_path_factory.mktemp("oilfield")
    (d / "well_ft.csv").write_text(SURVEY_FT)
    scen = d / "s.toml"
    scen.write_text(textwrap.dedent(SCENARIO))
    out = d / "run"
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        rc = main(["simulate", str(scen), "--out", str(out), "--units", "oilfield"])
    assert rc == 0
    return d, out, buf.getvalue()


def test_summary_json_is_in_oilfield_units_with_a_units_object(oilfield_run):
    _, out, _ = oilfield_run
    doc = json.loads((out / "summary.json").read_text())
    si = load_result(out / "result.nc").summary()  # result.nc stays SI
    assert set(doc["units"]) == set(si)
    for k, (src, dst) in METRIC_UNITS.items():
        assert doc["units"][k] == dst, k
        expected = float(pint_convert(si[k], src, dst))
        assert doc[k] == pytest.approx(expected, rel=1e-12), k
    # the inputs were understood: 120 rpm the top drive's PI set-point, in rad/s inside (the top
    # drive, started from rest, spins up towards it over these 2 s)
    res = load_result(out / "result.nc")
    rpm120 = U.Quantity(120, "rpm").to("rad/s").magnitude
    assert res["reference_angular_velocity"][-1] == pytest.approx(rpm120, rel=1e-9)
    assert 0.8 * rpm120 < res["top_drive_angular_velocity"][-1] < 1.2 * rpm120
    assert (out / "overview.png").stat().st_size > 10_000


def test_cli_table_has_a_unit_column_and_oilfield_values(oilfield_run):
    _, out, printed = oilfield_run
    si = load_result(out / "result.nc").summary()
    header = next(line for line in printed.splitlines() if "metric" in line)
    assert [c.strip() for c in header.strip("┃│ ").split("┃")][:2] == ["metric", "unit"]
    for k, (src, dst) in METRIC_UNITS.items():
        row = next(line for line in printed.splitlines() if f" {k} " in line)
        cells = [c.strip() for c in row.strip("│ ").split("│")]
        assert cells[0] == k and cells[1] == dst
        assert cells[2] == f"{float(pint_convert(si[k], src, dst)):.4g}"


def test_export_las_and_csv_in_oilfield_units(oilfield_run):
    import lasio
    import pandas as pd

    from downhole.io import read_las

    d, out, _ = oilfield_run
    res = load_result(out / "result.nc")
    las_path, csv_path = d / "run.las", d / "run.csv"
    assert main(["export", str(out / "result.nc"), "--las", str(las_path), "--csv",
                 str(csv_path), "--units", "oilfield"]) == 0
    las = lasio.read(str(las_path))
    units = {c.mnemonic: c.unit for c in las.curves}
    assert units["TIME"] == "s"
    frame = pd.read_csv(csv_path)
    assert frame.columns[0] == "time [s]"
    for ch, dst in OILFIELD.items():
        assert units[ch.upper()] == dst, ch
        expected = pint_convert(res[ch], SI[ch], dst)
        np.testing.assert_allclose(las[ch.upper()], expected, rtol=1e-9,
                                   atol=1e-9 * np.abs(expected).max())
        np.testing.assert_allclose(frame[f"{ch} [{dst}]"], expected, rtol=1e-9,
                                   atol=1e-12 * np.abs(expected).max())
    s = res.summary()
    assert las.params["MEAN_ROP"].unit == "ft/h"
    assert las.params["MEAN_ROP"].value == pytest.approx(
        float(pint_convert(s["mean_rop"], "m/s", "ft/h")), rel=1e-7)
    assert las.params["MSE"].unit == "psi"
    # reading the oilfield LAS back gives SI again
    back = read_las(las_path)
    np.testing.assert_allclose(back["wob"], res["wob"], rtol=1e-8,
                               atol=1e-8 * np.abs(res["wob"]).max())
    assert back.units("wob") == "N"


def test_per_quantity_override_on_the_command_line(oilfield_run, capsys):
    d, out, _ = oilfield_run
    las_path = d / "override.las"
    assert main(["export", str(out / "result.nc"), "--las", str(las_path), "--units",
                 "oilfield", "--unit", "torque=kN*m", "--unit", "wob=kN"]) == 0
    import lasio

    units = {c.mnemonic: c.unit for c in lasio.read(str(las_path)).curves}
    assert units["TOB"] == units["SURFACE_TORQUE"] == "kN*m"
    assert units["WOB"] == "kN" and units["HOOK_LOAD"] == "klbf"  # the name beats the kind


@pytest.mark.parametrize("args, message", [
    (["--units", "imperial"], "units: expected one of si, metric, oilfield, got 'imperial'"),
    (["--unit", "torque=kN"], "torque=kN: kN is not a unit of torque (SI: N*m)"),
    (["--unit", "torque"], "expected KIND=UNIT"),
    (["--unit", "nonsense=m"], "unknown quantity 'nonsense'"),
    (["--unit", "wob=1 s * 10**10**8"], "expected a unit expression"),
    (["--unit", "speed=flux_capacitor"], "speed=flux_capacitor"),
])
def test_bad_units_options_are_one_line_exit_2_nothing_written(tmp_path, capsys, args,
                                                               message):
    scen = tmp_path / "s.toml"
    scen.write_text("[model]\nfidelity = \"lumped4\"\npreset = \"table_2_1\"\n")
    out = tmp_path / "never"
    assert main(["simulate", str(scen), "--out", str(out), *args]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1 and "Traceback" not in err
    assert not out.exists()


def test_default_stays_si(tmp_path):
    from downhole.cli.simulate import summary_json
    from downhole.units import display_units

    doc = summary_json({"mean_rop": 0.01, "mse": 6.3e7, "stuck_fraction": 0.0,
                        "stick_slip_severity": math.inf}, display_units())
    assert doc["mean_rop"] == 0.01 and doc["mse"] == 6.3e7 and doc["stick_slip_severity"] is None
    assert doc["units"] == {"mean_rop": "m/s", "mse": "Pa", "stuck_fraction": "-",
                            "stick_slip_severity": "-"}


# ------------------------------------------------------------------ the unit systems
@pytest.mark.parametrize("system, name, si_value, unit", [
    ("oilfield", "wob", 1e5, "klbf"),
    ("oilfield", "surface_torque", 2.5e4, "kft*lbf"),
    ("oilfield", "bit_angular_velocity", 10.0, "rpm"),
    ("oilfield", "mean_rop", 0.01, "ft/h"),
    ("oilfield", "mse", 6.3e7, "psi"),
    ("oilfield", "bit_axial_position", 1000.0, "ft"),
    ("metric", "tob", 1.2e4, "kN*m"),
    ("metric", "mean_rop", 0.01, "m/h"),
    ("metric", "mse", 6.3e7, "MPa"),
    ("si", "wob", 1e5, "N"),
])
def test_unit_systems_convert_like_pint(system, name, si_value, unit):
    from downhole.signals import METRICS, SIGNALS
    from downhole.units import display_units

    disp = display_units(system)
    value, got = disp.convert(name, si_value)
    assert got == unit
    src = SIGNALS[name].unit if name in SIGNALS else METRICS[name].unit
    assert value == pytest.approx(U.Quantity(si_value, src).to(unit).magnitude, rel=1e-12)
    arr, _ = disp.convert(name, np.array([si_value, 2 * si_value]))
    np.testing.assert_allclose(arr, U.Quantity(np.array([si_value, 2 * si_value]), src)
                               .to(unit).magnitude, rtol=1e-12)


def test_kinds_overrides_and_api_for_dashboards():
    from downhole.units import display_units, unit_label

    u = display_units("oilfield", {"speed": "rad/s", "mean_rop": "m/h"})
    assert u.unit_of("bit_angular_velocity") == "rad/s"   # alias of a kind
    assert u.unit_of("mean_rop") == "m/h" and u.unit_of("bit_axial_velocity") == "ft/h"
    assert u.kind_unit("diameter") == "in" and u.kind_unit("density") == "lb/gal"
    assert u.kind_unit("curvature") == "deg_per_100ft"
    assert u.label("tob") == "kft·lbf" and unit_label("kg/m**3") == "kg/m³"
    assert u.unit_of("custom", si_unit="m**2") == "in**2"  # an area
    assert u.unit_of("custom", si_unit="1/s") == "1/s"  # no known kind: as stored
    # figures of the si system: rpm and kN, the rest SI
    f = display_units("si").for_figures()
    assert f.unit_of("bit_angular_velocity") == "rpm" and f.unit_of("wob") == "kN"
    assert display_units("si").unit_of("bit_angular_velocity") == "rad/s"
    assert u.to_dict()["system"] == "oilfield"
    kw = display_units("oilfield", torque="kN*m", wob="kN")  # welleng-style keywords
    assert kw.unit_of("tob") == "kN*m" and kw.unit_of("wob") == "kN"
    assert kw.unit_of("hook_load") == "klbf"
    with pytest.raises(DownholeInputError, match="torque=psi: psi is not a unit of torque"):
        display_units("oilfield", torque="psi")
    # DLS through the registry's own definition
    from downhole.units import convert

    assert convert(1.0, "deg_per_100ft", "rad/m") == pytest.approx(
        U.Quantity(1.0, "deg").to("rad").magnitude / U.Quantity(100, "ft").to("m").magnitude)


# ------------------------------------------------------------------ Python inputs
def test_surface_inputs_take_unit_strings_and_pint_quantities():
    from downhole.sim import SurfaceInputs, simulate
    from downhole.sim.lumped_model import lumped_model

    inp = SurfaceInputs.velocity(axial="30 ft/h", angular=U.Quantity(60, "rpm"))
    assert inp.axial == pytest.approx(U.Quantity(30, "ft/h").to("m/s").magnitude, rel=1e-12)
    assert inp.angular == pytest.approx(2 * math.pi, rel=1e-12)
    res = simulate(lumped_model("table_2_1"), inp, duration="0.1 s", dt="0.5 ms",
                   record_dt=U.Quantity(10, "ms"))
    assert res.time[-1] == pytest.approx(0.1)
    assert res["top_drive_axial_velocity"][-1] == pytest.approx(inp.axial, rel=1e-9)
    f = SurfaceInputs.force("250 klbf", U.Quantity(10, "kft*lbf"))
    assert f.axial == pytest.approx(U.Quantity(250, "klbf").to("N").magnitude, rel=1e-12)
    assert f.angular == pytest.approx(U.Quantity(10, "kft*lbf").to("N*m").magnitude, rel=1e-12)
    t = U.Quantity([0.0, 1.0], "s")
    dsp = SurfaceInputs.displacement(t, U.Quantity([0, 1], "ft"), U.Quantity([0, 90], "deg"))
    np.testing.assert_allclose(dsp.axial[1], [0, 0.3048])
    np.testing.assert_allclose(dsp.angular[1], [0, math.pi / 2])
    sampled = SurfaceInputs.velocity((["0 s", "1 s"], ["0 ft/h", "30 ft/h"]), 1.0)
    np.testing.assert_allclose(sampled.axial[1], [0, inp.axial])


@pytest.mark.parametrize("call, message", [
    (lambda S: S.velocity(axial="30 ft"), "velocity input axial: quantity '30 ft' has unit"),
    (lambda S: S.velocity(axial="thirty"), "velocity input axial: cannot parse quantity"),
    (lambda S: S.velocity(angular=[1, 2]), "velocity input angular: expected a number"),
    (lambda S: S.force("1 s * 10**10**8", 0.0), "force input axial: cannot parse"),
    (lambda S: S.velocity(axial=U.Quantity(5, "kg")), "velocity input axial:"),
])
def test_bad_surface_inputs_fail_at_construction(call, message):
    from downhole.sim import SurfaceInputs

    with pytest.raises(DownholeInputError, match=message.replace("(", r"\(").replace("*", r"\*")):
        call(SurfaceInputs)


def test_string_well_and_rig_take_unit_strings():
    from downhole.params import BitParams
    from downhole.params.rig import Hook, TopDrive
    from downhole.string.drillstring import DrillString, Stabilizer, StringSegment, pipe_section
    from downhole.system import DrillingSystem
    from downhole.well import Arc, Vertical, WellPath

    p = pipe_section("5 in", U.Quantity(4.276, "in"), density="65.5 lb/gal")
    assert p.outer_diameter == pytest.approx(U.Quantity(5, "in").to("m").magnitude, rel=1e-12)
    assert p.inner_diameter == pytest.approx(U.Quantity(4.276, "in").to("m").magnitude)
    assert p.density == pytest.approx(U.Quantity(65.5, "lb/gal").to("kg/m**3").magnitude)
    ds = DrillString((StringSegment("9000 ft", p), StringSegment(U.Quantity(600, "ft"), p,
                                                                 "collar")),
                     stabilizers=(Stabilizer("6 ft", "8.5 in"),), mud_density="10 lb/gal")
    assert ds.length == pytest.approx(U.Quantity(9600, "ft").to("m").magnitude, rel=1e-12)
    assert ds.mud_density == pytest.approx(U.Quantity(10, "lb/gal").to("kg/m**3").magnitude)
    assert ds.stabilizers[0].outer_diameter == pytest.approx(0.2159)
    w = WellPath.from_sections([Vertical("8000 ft"), Arc("3000 ft", "20 deg")])
    arc = U.Quantity(3000, "ft").to("m").magnitude * math.radians(20)
    assert w.total_depth == pytest.approx(U.Quantity(8000, "ft").to("m").magnitude + arc)
    assert float(w.tvd("8000 ft")) == pytest.approx(U.Quantity(8000, "ft").to("m").magnitude)
    np.testing.assert_allclose(w.tvd(U.Quantity([1000, 2000], "ft")), [304.8, 609.6])
    s = WellPath.from_survey(U.Quantity([0, 5000, 9600], "ft"), U.Quantity([0, 0, 10], "deg"),
                             [0, 0, 0])
    assert s.total_depth == pytest.approx(U.Quantity(9600, "ft").to("m").magnitude)
    td = TopDrive(speed="120 rpm", inertia=U.Quantity(500, "kg*m**2"))
    assert td.speed == pytest.approx(U.Quantity(120, "rpm").to("rad/s").magnitude)
    assert Hook(wob="25 klbf").wob == pytest.approx(U.Quantity(25, "klbf").to("N").magnitude)
    bit = BitParams(radius=U.Quantity(4.25, "in"))
    assert bit.radius == pytest.approx(U.Quantity(4.25, "in").to("m").magnitude)
    sysm = DrillingSystem(well=s, string=ds, bit=bit, friction=0.0, lump_length="30 ft")
    assert sysm.lump_length == pytest.approx(9.144)


@pytest.mark.parametrize("call, message", [
    (lambda: __import__("downhole.string.drillstring", fromlist=["x"]).pipe_section(
        "5 in of pipe", 0.1), "outer_diameter: cannot parse quantity"),
    (lambda: __import__("downhole.string.drillstring", fromlist=["x"]).pipe_section(
        "5 s", 0.1), "outer_diameter: quantity '5 s' has unit"),
    (lambda: __import__("downhole.string.drillstring", fromlist=["x"]).pipe_section(
        None, 0.1), "outer_diameter: expected a number or a quantity"),
    (lambda: __import__("downhole.string.drillstring", fromlist=["x"]).pipe_section(
        "5 in", "6 in"), "must be smaller than outer_diameter"),
    (lambda: __import__("downhole.well", fromlist=["x"]).Vertical("3 km/h"),
     "Vertical.length: quantity '3 km/h'"),
])
def test_bad_python_quantities_raise_downhole_input_error(call, message):
    with pytest.raises(DownholeInputError, match=message):
        call()


# ------------------------------------------------------------------ figures
@pytest.fixture(scope="module")
def stickslip_result():
    from downhole.sim import SurfaceInputs, simulate
    from downhole.sim.lumped_model import lumped_model

    return simulate(lumped_model("table_2_1"), SurfaceInputs.velocity("10 mm/s", "2 rad/s"),
                    duration=30.0, dt=1e-3, integrator="newmark", record_dt=0.02)


def _axis(fig, text):
    hits = [a for a in fig.axes if text in a.get_ylabel()]
    assert len(hits) == 1, (text, [a.get_ylabel() for a in fig.axes])
    return hits[0]


@pytest.mark.parametrize("system", ["oilfield", "si"])
def test_overview_has_an_own_axis_for_each_load_and_nothing_flat(stickslip_result, tmp_path,
                                                                 system):
    from matplotlib.figure import Figure

    from downhole.analysis.plots import plot_overview

    res = stickslip_result
    fig = plot_overview(res, tmp_path / "o.png", title="t", units=system)
    assert isinstance(fig, Figure) and (tmp_path / "o.png").stat().st_size > 10_000
    force, torque = ("klbf", "kft·lbf") if system == "oilfield" else ("kN", "kN·m")
    pint_units = {"klbf": "klbf", "kft·lbf": "kft*lbf", "kN": "kN", "kN·m": "kN*m"}
    axes = {}
    for name, label, unit in (("wob", "WOB", force), ("tob", "TOB", torque),
                              ("hook_load", "hook load", force),
                              ("surface_torque", "surface torque", torque)):
        ax = _axis(fig, f"{label} [{unit}]")
        axes[name] = ax
        (line,) = ax.get_lines()
        y = np.asarray(line.get_ydata(), float)
        lo, hi = ax.get_ylim()
        assert np.ptp(y) > 0.5 * (hi - lo), name  # fills its own axis: not drawn flat
        np.testing.assert_allclose(y, pint_convert(res[name], SI[name], pint_units[unit]),
                                   rtol=1e-9, atol=1e-12)
    assert len({id(a) for a in axes.values()}) == 4
    speed = _axis(fig, "rotary speed [rpm]")
    bit = next(ln for ln in speed.get_lines() if ln.get_label() == "bit")
    np.testing.assert_allclose(bit.get_ydata(), pint_convert(res["bit_angular_velocity"],
                                                             "rad/s", "rpm"), rtol=1e-9)
    assert any(ln.get_label().startswith("surface") for ln in speed.get_lines())
    sev = _axis(fig, "severity")
    values = np.asarray(sev.get_lines()[0].get_ydata(), float)
    assert np.nanmax(values) > 0.5  # the stick-slip shows over time
    _axis(fig, "bit advance")


def test_severity_series_matches_the_metric_on_each_window():
    from downhole.analysis.metrics import stick_slip_severity, stick_slip_severity_series

    t = np.linspace(0.0, 10.0, 1001)
    w = 5.0 + 4.0 * np.sin(2 * np.pi * t) ** 2 * (t > 5)
    tt, sev = stick_slip_severity_series(t, w, 2.0, points=50)
    assert np.isnan(sev[tt < 2.0 - 1e-9]).all()
    k = np.flatnonzero(np.isfinite(sev))[-1]
    window = (t >= tt[k] - 2.0) & (t <= tt[k])
    assert sev[k] == pytest.approx(stick_slip_severity(w[window]))
    # hand value: omega in [5, 9], mean 7 -> (9 - 5) / (2 * 7)
    assert sev[k] == pytest.approx(4.0 / 14.0, rel=5e-3)  # (201 samples: mean not exactly 7)


def test_sweep_axes_and_csv_in_display_units(tmp_path):
    import pandas as pd
    import xarray as xr

    from downhole.sweep.plots import _label

    speed = np.array([2.0, 5.0, 10.0])
    ds = xr.Dataset({"mean_wob": (("operation.surface_speed",), np.array([1e5, 1.1e5, 1.2e5]),
                                  {"units": "N"}),
                     "stick_slip_severity": (("operation.surface_speed",), np.ones(3),
                                             {"units": "-"}),
                     "error": (("operation.surface_speed",), np.array(["", "", ""]))},
                    coords={"operation.surface_speed": ("operation.surface_speed", speed,
                                                        {"units": "rad/s"})},
                    attrs={"sweep_mode": "grid", "n_cases": 3})
    label, factor = _label(ds, "operation.surface_speed", "oilfield")
    assert label.endswith("(rpm)")
    assert factor == pytest.approx(U.Quantity(1, "rad/s").to("rpm").magnitude)
    label, factor = _label(ds, "mean_wob", None)  # default figures: kN
    assert label == "mean_wob (kN)" and factor == pytest.approx(1e-3)
    ds.to_netcdf(tmp_path / "sweep.nc", engine="h5netcdf")
    assert main(["export", str(tmp_path / "sweep.nc"), "--csv", str(tmp_path / "s.csv"),
                 "--units", "oilfield"]) == 0
    frame = pd.read_csv(tmp_path / "s.csv", keep_default_na=False)
    np.testing.assert_allclose(frame["operation.surface_speed [rpm]"],
                               pint_convert(speed, "rad/s", "rpm"))
    np.testing.assert_allclose(frame["mean_wob [klbf]"],
                               pint_convert([1e5, 1.1e5, 1.2e5], "N", "klbf"))
    assert "stick_slip_severity [-]" in frame.columns and "error" in frame.columns


def test_compare_report_tables_and_plots_in_display_units():
    from downhole.compare.report import render_html

    case = {"id": "c1", "system": "ch3", "speed": 10.0, "hook": "force", "wob": 1e5,
            "rop": 0.01, "start": "rest", "pre_time": 0.0, "epsilon_scale": 1.0, "noise": False,
            "delay": 0.0, "duration": 5.0, "n_elements": 20, "dt": 1e-3, "region": "r"}
    sc = {"stick_slip_severity": 0.5, "time_to_suppress": None, "stuck_fraction": 0.0,
          "bit_bounce_fraction": 0.0, "mean_rop": 0.01, "mse": 6.3e7,
          "tracking_rms_angular": 1.0, "tracking_rms_axial": 1e-3,
          "peak_surface_torque": 2.0e4, "effort": {"top_drive_angular_velocity": 2.0}}
    scores = {"suite": {"name": "x", "version": 1}, "cases": [case],
              "controllers": {"pi": {"source": "builtin", "description": "d"}},
              "summary": {"pi": {"ok": 1, "n/a": 0, "failed": 0, "stick_slip_cases": 0,
                                 "suppressed": 0, "mean_severity_stick_slip_cases": None,
                                 "mean_stuck_fraction_stick_slip_cases": None,
                                 "mean_relative_speed_tracking_rms": 0.1}},
              "cells": {"c1": {"pi": {"status": "ok", "scores": sc}}},
              "score_definitions": {}}
    traces = {"c1": {"pi": {"time": [0.0, 1.0], "bit_angular_velocity": [0.0, 10.0],
                            "surface_torque": [0.0, 2e4]}}}
    page = render_html(scores, traces, "oilfield")
    assert "ROP [ft/h]" in page and "MSE [psi]" in page and "peak torque [kft·lbf]" in page
    rop = U.Quantity(0.01, "m/s").to("ft/h").magnitude
    assert f"<td>{rop:.3g}</td>" in page
    torque = U.Quantity(2e4, "N*m").to("kft*lbf").magnitude
    assert f"<td>{torque:.3g}</td>" in page
    wob = U.Quantity(1e5, "N").to("klbf").magnitude
    assert f"WOB {wob:.4g} klbf" in page and "95.49 rpm" in page
    si = render_html(scores, traces)
    assert "ROP [mm/s]" in si and "MSE [MPa]" in si and "speed RMS [rpm]" in si


def test_optimize_dp_prints_the_final_velocity_in_display_units(tmp_path, capsys):
    scen = tmp_path / "p.toml"
    scen.write_text("[optimize]\nhorizon = 3.0\nstep = 0.25\n")
    assert main(["optimize", "dp", str(scen), "--method", "customized", "--out",
                 str(tmp_path / "o"), "--no-progress", "--no-replay", "--units",
                 "oilfield"]) == 0
    sol = np.load(tmp_path / "o" / "solution.npz")
    v = U.Quantity(float(sol["x2"][-1]), "m/s").to("ft/h").magnitude
    w = U.Quantity(float(sol["x4"][-1]), "rad/s").to("rpm").magnitude
    assert f"{v:.4g} ft/h, {w:.4g} rpm" in capsys.readouterr().out


def test_neutral_simulation_takes_quantity_strings():
    from downhole.sim import simulate
    from downhole.string.neutral import neutral_model

    res = simulate(neutral_model("table_3_1"), duration="20 ms", dt=U.Quantity(0.1, "ms"),
                           record_dt="1 ms")
    assert res.time[-1] == pytest.approx(0.02) and np.diff(res.time)[0] == pytest.approx(1e-3)
    with pytest.raises(DownholeInputError, match="dt: quantity '1 m' has unit"):
        simulate(neutral_model("table_3_1"), duration=0.02, dt="1 m")


def test_overview_of_a_result_without_depth_or_surface_channels():
    from downhole.analysis.plots import plot_overview
    from downhole.sim import Result

    t = np.linspace(0.0, 10.0, 501)
    res = Result(t, {"bit_angular_velocity": 10 + np.sin(t), "wob": 1e5 + 1e4 * np.sin(t),
                     "tob": 5e3 + 1e3 * np.cos(t)})
    fig = plot_overview(res, units="oilfield")
    assert not any("depth" in a.get_ylabel() or "advance" in a.get_ylabel() for a in fig.axes)
    _axis(fig, "WOB [klbf]")
    _axis(fig, "TOB [kft·lbf]")
    assert fig.axes[4].get_xlabel() == "time [s]"


def test_plants_take_unit_strings_and_quantities_for_dt_set_points_and_commands():
    """The Plant contract in driller units: ``dt="0.5 ms"``, ``set_point`` and ``step`` commands
    as unit strings or pint quantities give exactly the run of the SI numbers converted by an
    independent pint registry; a wrong dimension is refused with the signal's name."""
    import pint

    from downhole.errors import DownholeInputError
    from downhole.sim.lumped_model import lumped_model
    from downhole.string.fem import DirectionalPlant
    from downhole.string.neutral import neutral_model

    u = pint.UnitRegistry()
    v = u.Quantity(30.0, "ft/hour").to("m/s").magnitude
    w = u.Quantity(60.0, "rpm").to("rad/s").magnitude
    for make, dt_text, dt in ((lambda d: DirectionalPlant(lumped_model("table_2_1"), dt=d),
                               "0.5 ms", 5e-4),
                              (lambda d: DirectionalPlant(neutral_model("table_3_1"), dt=d), "0.1 ms", 1e-4)):
        a, b = make(dt), make(dt_text)
        assert b.dt == pytest.approx(dt, rel=1e-15)
        oa = a.reset(start="steady", set_point={"top_drive_axial_velocity": v,
                                                "top_drive_angular_velocity": w})
        ob = b.reset(start="steady", set_point={"top_drive_axial_velocity": "30 ft/h",
                                                "top_drive_angular_velocity": "60 rpm"})
        assert ob["bit_angular_velocity"] == pytest.approx(oa["bit_angular_velocity"], rel=1e-12)
        for _ in range(5):
            oa = a.step({"top_drive_axial_velocity": v, "top_drive_angular_velocity": w})
            ob = b.step({"top_drive_axial_velocity": u.Quantity(30.0, "ft/hour"),
                         "top_drive_angular_velocity": "60 rpm"})
        assert ob["bit_axial_velocity"] == pytest.approx(oa["bit_axial_velocity"], rel=1e-12)
        with pytest.raises(DownholeInputError, match="top_drive_axial_velocity"):
            b.step({"top_drive_axial_velocity": "30 ft", "top_drive_angular_velocity": 1.0})
        with pytest.raises(DownholeInputError, match="dt"):
            make("3 m")
