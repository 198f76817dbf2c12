"""The FMU's model description: every variable has a unit and a description, the units are
declared with their SI base units, a default experiment, no variable named ``time``; FMPy runs
the default experiment and the Results keep the bit radius (finite MSE)."""

import math

import fmpy
import numpy as np
import pytest

from downhole.cli import main
from downhole.signals import SIGNALS

#: SI base-unit exponents by hand (kg, m, s, rad), the reference for <UnitDefinitions>
BASE = {"N": {"kg": 1, "m": 1, "s": -2}, "N*m": {"kg": 1, "m": 2, "s": -2}, "m": {"m": 1},
        "m/s": {"m": 1, "s": -1}, "rad": {"rad": 1}, "rad/s": {"rad": 1, "s": -1}, "s": {"s": 1}}


@pytest.fixture(scope="module")
def lumped_fmu(tmp_path_factory):
    from downhole.sil.fmu import export_fmu

    folder = tmp_path_factory.mktemp("fmu")
    scenario = folder / "lumped.toml"  # Table 2.1, 4th order, 0.5 ms, 10 mm/s and 10 rad/s
    scenario.write_text('[model]\nfidelity = "lumped4"\npreset = "table_2_1"\n\n'
                        '[operation]\nrop = "10 mm/s"\nsurface_speed = "10 rad/s"\n\n'
                        '[simulation]\nduration = "2 s"\ndt = "0.5 ms"\n')
    return export_fmu(scenario, folder / "lumped.fmu")


def _check_description(md, stop_time, step):
    names = [v.name for v in md.modelVariables]
    assert "time" not in names and "sim_time" in names
    units = {u.name: u for u in md.unitDefinitions}
    for v in md.modelVariables:
        assert v.description, v.name
        assert v.unit, v.name
        assert v.unit in units, v.name
        signal = v.name.removeprefix("command_")
        if v.name == "sim_time":
            signal = "time"
        if signal in SIGNALS:
            assert v.unit == SIGNALS[signal].unit, v.name
    for name, u in units.items():
        b = u.baseUnit
        got = {k: getattr(b, k) for k in ("kg", "m", "s", "A", "K", "mol", "cd", "rad")
               if getattr(b, k)}
        assert got == BASE[name], name
        assert b.factor == 1.0
    de = md.defaultExperiment
    assert float(de.startTime) == 0.0
    assert float(de.stopTime) == pytest.approx(stop_time)
    assert float(de.stepSize) == pytest.approx(step)


def test_plant_fmu_variables_have_units_descriptions_and_a_default_experiment(lumped_fmu):
    md = fmpy.read_model_description(str(lumped_fmu), validate=True)  # FMI 2.0 schema
    _check_description(md, 2.0, 5e-4)
    byname = {v.name: v for v in md.modelVariables}
    assert byname["wob"].description == "weight on bit"
    assert byname["command_top_drive_angular_velocity"].unit == "rad/s"
    assert float(byname["command_top_drive_angular_velocity"].start) == 10.0
    assert byname["bit_radius"].variability == "constant"
    assert float(byname["bit_radius"].start) == 0.15  # Table 2.1


def test_scenario_fmu_default_experiment_is_the_scenario_duration(tmp_path):
    fmu = tmp_path / "p.fmu"
    assert main(["export-fmu", "examples/table_5_1.toml", "--fidelity", "lumped4",
                 "--out", str(fmu)]) == 0
    md = fmpy.read_model_description(str(fmu))
    # examples/table_5_1.toml: [simulation] duration = "10 s"; lumped default dt 0.5 ms
    _check_description(md, 10.0, 5e-4)


def test_fmpy_runs_the_default_experiment_and_results_keep_the_bit_radius(lumped_fmu):
    from downhole.control.base import Controller
    from downhole.sil.fmu import run_fmu_closed_loop

    rec = fmpy.simulate_fmu(str(lumped_fmu), fmi_type="CoSimulation", output_interval=0.01)
    assert rec["time"][-1] == pytest.approx(2.0)  # the default experiment's stop time
    assert np.allclose(rec["sim_time"], rec["time"], atol=1e-9)

    class Hold(Controller):
        needs = ("time",)
        commands = ()

        def command(self, t, obs, ref):
            assert obs["time"] == pytest.approx(t)  # sim_time reaches controllers as time
            return {}

    res = run_fmu_closed_loop(lumped_fmu, Hold(), 2.0, record_every=20)
    assert "sim_time" not in res and res.attrs["bit_radius"] == 0.15
    s = res.summary()
    area = math.pi * 0.15 ** 2
    sel = res.time >= res.time[-1] / 2
    power = (res["tob"][sel] * res["bit_angular_velocity"][sel]).mean()
    ref = res["wob"][sel].mean() / area + power / (area * res["bit_axial_velocity"][sel].mean())
    assert math.isfinite(s["mse"]) and s["mse"] == pytest.approx(ref, rel=1e-12)


def test_state_interface_fmu_gives_the_design_states_their_units(tmp_path):
    """The DHP ``state`` interface outputs the design model's states (x_i, alpha_i, v_i,
    omega_i): their units come from the state kinds (m, rad, m/s, rad/s)."""
    from downhole.sil.fmu import export_fmu

    fmu = export_fmu("examples/sil_dhp_hybrid68.toml", tmp_path / "dhp_plant.fmu")
    md = fmpy.read_model_description(str(fmu), validate=True)
    byname = {v.name: v for v in md.modelVariables}
    expected = {"x_": "m", "alpha_": "rad", "v_": "m/s", "omega_": "rad/s"}
    states = [n for n in byname if n.split("_")[0] + "_" in expected and n[-1].isdigit()]
    assert len(states) == 24  # the 24-state design model
    for n in states:
        assert byname[n].unit == expected[n.split("_")[0] + "_"], n
        assert "design model" in byname[n].description
    for v in md.modelVariables:
        assert v.unit and v.description, v.name
    assert "time" not in byname
    assert float(md.defaultExperiment.stopTime) > 0


def test_oilfield_display_units_are_declared_for_the_importing_tool(tmp_path):
    """``export-fmu --units oilfield``: the values stay SI (unit rad/s, N, N*m) and every variable
    names its display unit, declared in <UnitDefinitions> with the factor an importer applies
    (display = factor * value), checked against an independent pint registry; FMI 2.0 schema
    valid; the SI export has no display units."""
    import pint

    ureg = pint.UnitRegistry()
    fmu = tmp_path / "ft.fmu"
    assert main(["export-fmu", "examples/table_5_1.toml", "--fidelity", "lumped4",
                 "--units", "oilfield", "--unit", "wob=kN", "--out", str(fmu)]) == 0
    md = fmpy.read_model_description(str(fmu), validate=True)
    _check_description(md, 10.0, 5e-4)
    byname = {v.name: v for v in md.modelVariables}
    display = {(u.name, d.name): d for u in md.unitDefinitions for d in u.displayUnits}
    expect = {"command_top_drive_angular_velocity": "rpm", "bit_angular_velocity": "rpm",
              "bit_axial_velocity": "ft/h", "surface_torque": "kft*lbf", "tob": "kft*lbf",
              "hook_load": "klbf", "wob": "kN", "bit_radius": "in"}
    for name, disp in expect.items():
        if name not in byname:
            continue
        v = byname[name]
        assert v.displayUnit == disp, name
        names = {"kft*lbf": "kilofoot * force_pound", "klbf": "kip", "ft/h": "foot / hour",
                 "rpm": "revolution / minute", "in": "inch", "kN": "kilonewton"}
        ref = ureg.Quantity(1.0, v.unit.replace("*", " * ")).to(names[disp]).magnitude
        assert display[(v.unit, disp)].factor == pytest.approx(ref, rel=1e-12), name
    assert sum(n in byname for n in expect) >= 5
    si = tmp_path / "si.fmu"
    assert main(["export-fmu", "examples/table_5_1.toml", "--fidelity", "lumped4",
                 "--out", str(si)]) == 0
    md = fmpy.read_model_description(str(si), validate=True)
    assert all(not v.displayUnit for v in md.modelVariables)
    assert not any(u.displayUnits for u in md.unitDefinitions)
    assert main(["export-fmu", "examples/table_5_1.toml", "--fidelity", "lumped4", "--units",
                 "furlongs", "--out", str(tmp_path / "bad.fmu")]) == 2
    assert not (tmp_path / "bad.fmu").exists()
