"""DHP design scenarios in the one scenario vocabulary: rename hints for every older key, unit
strings on every physical value, the [model] plant resolved against the design, routing of
`downhole simulate`, and the migrated examples against the models they always built."""

from pathlib import Path

import numpy as np
import pytest

from downhole.cli import main
from downhole.errors import ScenarioError
from downhole.scenario.dhp import load_dhp_scenario, parse_dhp_scenario

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def write(tmp_path, text, name="s.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


# ------------------------------------------------------------------------------ older keys
@pytest.mark.parametrize("text, field, hint", [
    ('[model]\ntype = "dhp"\n', "model.type", 'controller.type = "dhp"'),
    ('[model]\nkind = "fem24"\n', "model.kind", "controller.dhp.design"),
    ("[model]\nn_elements = 5\n", "model.n_elements", "controller.dhp.elements"),
    ("[model]\ndt = 0.001\n", "model.dt", "controller.dhp.dt"),
    ("[model]\ninput_limits = [[-5e4, 3e5], [-6e4, 6e4]]\n", "model.input_limits",
     "controller.dhp.input_limits"),
    ("[model]\nfriction = true\n", "model.friction", "controller.dhp.friction"),
    ('[model]\nepsilon = "45 MPa"\n', "model.epsilon", "bit.epsilon"),
    ("[weights]\nbit_velocity = [1.0, 1.0]\n", "weights", "[controller.dhp.weights] (DHP"),
    ("[training]\nhorizon = 8.0\n", "training", "[controller.dhp.training]"),
    ("[plan]\nduration = 7.0\n", "plan", "[controller.dhp.plan]"),
    ('[simulation]\nplant = "fem24"\n', "simulation.plant", "[model] fidelity"),
    ('[reference]\naxial = "10 mm/s"\n', "reference.axial", "reference.axial_velocity"),
    ("[reference]\nangular = 20.0\n", "reference.angular", "reference.angular_velocity"),
    ('[reference]\ntype = "user"\naxial_values = [0.01]\n', "reference.axial_values",
     "reference.axial_velocity_values"),
    ('[reference]\ntype = "user"\nangular_values = [20.0]\n', "reference.angular_values",
     "reference.angular_velocity_values"),
])
def test_every_older_dhp_key_gets_a_one_line_hint(tmp_path, capsys, text, field, hint):
    p = write(tmp_path, text)
    with pytest.raises(ScenarioError) as info:
        load_dhp_scenario(p)
    assert info.value.field == field, str(info.value)
    assert info.value.message.startswith("renamed") and hint in info.value.message
    assert main(["design", "dhp", str(p), "--out", str(tmp_path / "o"), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{field}: renamed" in err and hint in err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("name", ["dhp_lumped", "dhp_sine_fem24", "dhp_step_fem24",
                                  "dhp_step_hybrid68"])
def test_an_older_dialect_example_names_a_key_and_simulate_refuses_it(tmp_path, capsys, name):
    """The pre-migration form of each example (the older dialect, as shipped before) gets one
    line naming a key to rename, in `design dhp` and in `simulate`."""
    old = OLD_EXAMPLES[name]
    p = write(tmp_path, old)
    for argv in (["design", "dhp", str(p), "--out", str(tmp_path / "o"), "--no-progress"],
                 ["simulate", str(p), "--out", str(tmp_path / "o")]):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "renamed: use" in err, err
    assert not (tmp_path / "o").exists()


OLD_EXAMPLES = {
    "dhp_lumped": '[model]\ntype = "dhp"\nkind = "lumped"\npreset = "table_2_1"\n'
                  '[reference]\ntype = "ramp"\nt_final = 20.0\n[training]\nhorizon = 20.0\n',
    "dhp_sine_fem24": '[model]\ntype = "dhp"\nkind = "fem24"\n[reference]\ntype = "sine"\n'
                      '[training]\nhorizon = 20.0\nn_samples = 50\n',
    "dhp_step_fem24": '[model]\ntype = "dhp"\nkind = "fem24"\ndt = 0.001\n'
                      '[reference]\naxial = "10 mm/s"\nangular = "20 rad/s"\n'
                      '[weights]\nbit_velocity = [100.0, 100.0]\n',
    "dhp_step_hybrid68": '[model]\ntype = "dhp"\nkind = "fem24"\n[plan]\nduration = 7.0\n'
                         '[simulation]\nduration = 20.0\nplant = "hybrid68"\n',
}


# ------------------------------------------------------------------------------ units
SI = """
[bit]
epsilon = 45e6
[controller]
type = "dhp"
[controller.dhp]
design = "fem24"
dt = 0.002
input_limits = [[-40e3, 250e3], [-50e3, 50e3]]
friction = 0.3
[controller.dhp.training]
horizon = 4.0
[controller.dhp.plan]
duration = 3.0
knot_spacing = 0.5
n_knots = 5
settle_from = 2.0
late_from = 2.5
steady_from = 2.5
axial_tolerance = 0.0005
angular_tolerance = 1.0
top_drive_inertia = 500.0
[reference]
type = "{type}"
{reference}
[simulation]
duration = 2.0
depth_of_cut = "approximate"
"""
UNITS = {"epsilon = 45e6": 'epsilon = "45 MPa"', "dt = 0.002": 'dt = "2 ms"',
         "input_limits = [[-40e3, 250e3], [-50e3, 50e3]]":
             'input_limits = [["-40 kN", "250 kN"], ["-50 kN*m", "50000 N*m"]]',
         "horizon = 4.0": 'horizon = "4 s"', "duration = 3.0": 'duration = "3000 ms"',
         "knot_spacing = 0.5": 'knot_spacing = "0.5 s"', "settle_from = 2.0":
             'settle_from = "2 s"', "late_from = 2.5": 'late_from = "2.5 s"',
         "steady_from = 2.5": 'steady_from = "2.5 s"',
         "axial_tolerance = 0.0005": 'axial_tolerance = "0.5 mm/s"',
         "angular_tolerance = 1.0": 'angular_tolerance = "1 rad/s"',
         "top_drive_inertia = 500.0": 'top_drive_inertia = "500 kg*m^2"',
         "duration = 2.0": 'duration = "2 s"',
         "axial_velocity = 0.01": 'axial_velocity = "36 m/h"',
         "angular_velocity = 20.0": 'angular_velocity = "20 rad/s"',
         "t_final = 3.0": 't_final = "3 s"', "frequency = 0.5": 'frequency = "0.5 rad/s"',
         "time = [0.0, 1.0]": 'time = ["0 s", "1000 ms"]',
         "axial_velocity_values = [0.01, 0.02]":
             'axial_velocity_values = ["10 mm/s", "72 m/h"]',
         "angular_velocity_values = [20.0, 30.0]":
             'angular_velocity_values = ["20 rad/s", "30 rad/s"]'}
REFERENCES = {
    "ramp": "axial_velocity = 0.01\nangular_velocity = 20.0\nt_final = 3.0",
    "sine": "axial_velocity = 0.01\nangular_velocity = 20.0\nfrequency = 0.5",
    "user": "time = [0.0, 1.0]\naxial_velocity_values = [0.01, 0.02]\n"
            "angular_velocity_values = [20.0, 30.0]",
}


def _with_units(text: str) -> str:
    for si, unit in UNITS.items():
        text = text.replace(si, unit)
    return text


@pytest.mark.parametrize("rtype", sorted(REFERENCES))
def test_unit_strings_are_accepted_on_every_physical_value(tmp_path, rtype):
    """Every physical value in units gives the same design as the bare SI numbers."""
    si = SI.format(type=rtype, reference=REFERENCES[rtype])
    units = _with_units(si)
    changed = sum(1 for k in UNITS if k in si)
    assert changed >= 15 and all(k not in units for k in UNITS)
    a = load_dhp_scenario(write(tmp_path, si, "si.toml"))
    b = load_dhp_scenario(write(tmp_path, units, "units.toml"))
    ma, mb = a["model"], b["model"]
    assert ma.dt == mb.dt == pytest.approx(2e-3)
    np.testing.assert_array_equal(ma.A_d, mb.A_d)
    np.testing.assert_allclose(ma.input_limits, [[-40e3, 250e3], [-50e3, 50e3]])
    np.testing.assert_allclose(mb.input_limits, ma.input_limits)
    assert mb.bit.epsilon == pytest.approx(45e6) == ma.bit.epsilon
    assert a["reference"].kind == b["reference"].kind == rtype
    t = np.linspace(0, 3, 7)
    np.testing.assert_allclose(a["reference"].velocities(t), b["reference"].velocities(t))
    assert a["horizon"] == b["horizon"] == 4.0
    assert a["plan"] == b["plan"] and b["plan"].duration == 3.0
    assert a["simulation"]["duration"] == b["simulation"]["duration"] == 2.0


def test_friction_is_the_design_models_coefficient(tmp_path):
    """controller.dhp.friction sets the design model's wellbore friction (0: none; omitted:
    the well's own, 0.5 for Table 5.1); the plant keeps the well's."""
    base = '[controller.dhp]\ndesign = "fem24"\n'
    own = load_dhp_scenario(write(tmp_path, base, "a.toml"))
    none = load_dhp_scenario(write(tmp_path, base + "friction = 0\n", "b.toml"))
    same = load_dhp_scenario(write(tmp_path, base + "friction = 0.5\n", "c.toml"))
    z = np.random.default_rng(1).normal(size=(4, own["model"].n_states)) * 0.3
    f_own, f_same = own["model"].forces(z), same["model"].forces(z)
    np.testing.assert_array_equal(f_own, f_same)
    # without friction the design has only the bit's force pair
    assert none["model"].forces(z).shape[1] == 2 < f_own.shape[1]
    assert none["plant_source"][1].mu == own["plant_source"][1].mu == 0.5


# ------------------------------------------------------------------------------ the plant
@pytest.mark.parametrize("text, kind, preset", [
    ("", "fem24", "fem24"),
    ('[model]\nfidelity = "fem"\npreset = "design"\n', "design", "design"),
    ('[model]\nfidelity = "hybrid"\n', "hybrid68", "hybrid68"),
    ('[controller.dhp]\ndesign = "lumped"\n', "lumped", "table_2_1"),
    ('[controller.dhp]\ndesign = "lumped"\n[model]\npreset = "plausible_lumped"\n', "lumped",
     "plausible_lumped"),
    ('[controller.dhp]\ndesign = "lumped"\n[model]\nfidelity = "lumped4"\npreset = "design"\n',
     "design", "design"),
    ('[controller.dhp]\ndesign = "fem"\nelements = 4\n', "fem24", None),
])
def test_model_table_chooses_the_plant(text, kind, preset, tmp_path):
    sc = load_dhp_scenario(write(tmp_path, text))
    assert sc["plant"]["kind"] == kind and sc["plant"]["preset"] == preset


def test_a_lumped_plant_of_another_preset_runs_that_preset():
    from downhole.params import get_preset

    sc = parse_dhp_scenario({"controller": {"dhp": {"design": "lumped"}},
                             "model": {"preset": "plausible_lumped"},
                             "bit": {"epsilon": "60 MPa"}})
    string, bit = sc["plant"]["params"]
    assert string == get_preset("plausible_lumped").string
    assert bit.epsilon == 60e6 and sc["plant_source"][2].epsilon == 60e6


def test_simulate_routes_controller_type_dhp_to_the_dhp_runner():
    from downhole.scenario import model_type

    assert model_type({"controller": {"type": "dhp"}}, "<t>") == "dhp"
    assert model_type({"model": {"fidelity": "fem"}, "controller": {"type": "dhp", "dhp": {}}},
                      "<t>") == "dhp"
    # a trained controller file without a design table runs on the FEM of the preset (or of a
    # described well and string) with its top-drive controller: downhole.scenario.directional
    assert model_type({"model": {"fidelity": "fem"},
                       "controller": {"type": "dhp", "file": "c"}}, "<t>") == "fem"


def test_the_migrated_examples_validate_through_simulate():
    from downhole.scenario import load_scenario, validate_data

    files = sorted(EXAMPLES.glob("dhp_*.toml"))
    assert len(files) == 4
    for f in files:
        data, source, _ = load_scenario(f)
        assert validate_data(data, source) == "dhp", f
        sc = load_dhp_scenario(f)
        assert sc["simulation"] is not None and sc["title"]


def test_simulate_runs_a_migrated_design_quick(tmp_path):
    """A short copy of examples/dhp_step_fem24.toml (2 s horizon) trains and runs on the
    24-state FEM through `downhole simulate`: the step reference is recorded and the
    controller turns the string."""
    from downhole.sim import load_result

    text = (EXAMPLES / "dhp_step_fem24.toml").read_text()
    assert 'horizon = "20 s"' in text and 'duration = "20 s"' in text
    text = text.replace('horizon = "20 s"', 'horizon = "2 s"').replace('duration = "20 s"',
                                                                       'duration = "2 s"')
    p = write(tmp_path, text)
    assert main(["simulate", str(p), "--out", str(tmp_path / "r")]) == 0
    res = load_result(tmp_path / "r" / "result.nc")
    assert res.time[-1] == pytest.approx(2.0, abs=0.02)
    assert res["reference_angular_velocity"][-1] == pytest.approx(20.0)
    assert res["reference_axial_velocity"][-1] == pytest.approx(0.01)
    assert res["surface_torque"].max() > 1e3
    assert np.isfinite(res["bit_angular_velocity"]).all()


def test_a_described_system_with_a_dhp_controller_is_not_a_dhp_design():
    from downhole.scenario.dhp import is_dhp_dialect

    assert is_dhp_dialect({"controller": {"type": "dhp", "dhp": {}}})
    assert not is_dhp_dialect({"controller": {"type": "dhp"}, "model": {"fidelity": "fem"},
                               "well": {}, "string": {}, "operation": {}})
    assert not is_dhp_dialect({"controller": {"type": "pi"}})
    assert not is_dhp_dialect({"controller": {"type": "dhp"}, "model": {"type": "hybrid"}})


# ------------------------------------------------------------------------------ one schema
@pytest.mark.parametrize("text, field, msg", [
    ('[simulation]\ndt = "1 ms"\n', "simulation.dt",
     "not used by a DHP design (the design's step is controller.dhp.dt)"),
    ('[simulation]\nrecord_dt = "10 ms"\n', "simulation.record_dt", "not used by a DHP design"),
    ('[simulation]\nintegrator = "euler"\n', "simulation.integrator", "not used by a DHP"),
    ('[model]\ninterface = "state"\n', "model.interface", "not used by a DHP design"),
    ("[controller]\nenabled = false\n", "controller.enabled", "not used by a DHP design"),
    ("[reference]\nv = 0.01\n", "reference.v", "not used by a DHP design"),
    ("[realtime]\npaced = false\n", "realtime", "not used by a DHP design scenario"),
    ('[controller.dhp]\ndesign = "hybrid24"\n', "controller.dhp.design", "a SIL design"),
    ('[model]\nfidelity = "lumped12"\n', "model.fidelity", "fem | hybrid | lumped4"),
    ('[reference]\ntype = "breakpoints"\naxial_velocity = [[0, 0.01], [1, 0.02]]\n'
     'angular_velocity = 20.0\n', "reference.axial_velocity", "takes a constant"),
    ('[reference]\ntype = "ramp"\nangular_velocity = [[0, 10.0], [1, 20.0]]\n',
     "reference.angular_velocity", "takes a constant"),
    ('[reference]\ntype = "constant"\n', "reference.type", "step | ramp | sine | user"),
    ("[controller]\ntype = \"eid\"\n", "controller.type", "type = 'dhp'"),
    ('[simulation]\nduration = "2e5 s"\n', "simulation.duration", "at most 100000 s"),
])
def test_keys_of_the_one_schema_a_dhp_design_does_not_read_are_refused(tmp_path, text, field,
                                                                        msg):
    """The one schema has more keys than a DHP design reads: each is refused with one line
    naming it (never silently ignored)."""
    with pytest.raises(ScenarioError) as info:
        load_dhp_scenario(write(tmp_path, text))
    assert info.value.field == field, str(info.value)
    assert msg in info.value.message, str(info.value)


def test_the_one_schemas_none_defaults_take_the_dhp_defaults():
    """No [model], [controller] type, design, horizon, reference type: the DHP's (fem plant of
    the fem24 design, 40 s, a step); n_samples left to DHPSettings; the depth of cut is the one
    schema's default (delayed) unless the file says approximate."""
    from downhole.control.dhp import DHPSettings

    sc = parse_dhp_scenario({"controller": {"dhp": {"design": "lumped"}},
                             "simulation": {"duration": 1.0}})
    assert sc["plant"]["fidelity"] == "lumped4" and sc["horizon"] == 40.0
    assert sc["reference"].kind == "step"
    assert sc["settings"].n_samples == DHPSettings().n_samples
    assert sc["simulation"]["depth_of_cut"] == "delayed"
    sc = parse_dhp_scenario({"controller": {"dhp": {"design": "lumped", "training": {
        "n_samples": 30}}}, "simulation": {"depth_of_cut": "approximate"}})
    assert sc["settings"].n_samples == 30 and sc["simulation"]["depth_of_cut"] == "approximate"
    assert sc["simulation"]["duration"] == 40.0
    assert parse_dhp_scenario({"controller": {"dhp": {"design": "lumped"}}})["simulation"] \
        is None
