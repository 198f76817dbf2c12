"""The SIL reads the one scenario schema (downhole/_schema.py): its loader returns the one
``Scenario`` with the SIL's defaults resolved, and defines no schema of its own."""

from __future__ import annotations

import inspect
from pathlib import Path

import pytest
from pydantic import BaseModel

import downhole.sil.scenario as sil_scenario
from downhole._schema import Scenario
from downhole.errors import ScenarioError
from downhole.sil.scenario import load_sil_scenario, parse_sil_scenario

EXAMPLES = sorted((Path(__file__).resolve().parents[1] / "examples").glob("sil_*.toml"))


def test_the_sil_module_defines_no_schema():
    own = [name for name, obj in vars(sil_scenario).items()
           if inspect.isclass(obj) and issubclass(obj, BaseModel)
           and obj.__module__ == sil_scenario.__name__]
    assert own == []
    for gone in ("SilScenario", "ModelSection", "ControllerSection", "DHPSection"):
        assert not hasattr(sil_scenario, gone)


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.name)
def test_every_sil_example_reads_as_the_one_scenario(path):
    sc = load_sil_scenario(path)
    assert type(sc) is Scenario
    assert sc.simulation.dt == pytest.approx(1e-3)
    assert sc.simulation.record_dt == pytest.approx(0.01)  # given, or the SIL's default
    assert sc.controller.type in ("none", "pi", "dhp", "file")
    assert sc.reference.type == "step"
    for key in ("wob", "surface_speed", "surface_torque", "rop"):
        assert isinstance(getattr(sc.operation, key), float), key
    assert sc.model.fem.n_elements == 23
    if sc.controller.type == "dhp":
        assert sc.controller.options.dhp.design in ("hybrid24", "hybrid68")
        assert sc.controller.options.dhp.training.n_samples >= 2


def test_the_none_defaults_resolve_to_the_sils():
    sc = parse_sil_scenario({})  # no [model]: the hybrid plant
    assert (sc.title, sc.model.fidelity, sc.model.interface) == ("sil", "hybrid", "surface")
    assert (sc.simulation.dt, sc.simulation.duration, sc.simulation.record_dt) == (1e-3, 20.0,
                                                                                  0.01)
    op = sc.operation
    assert (op.wob, op.surface_speed, op.surface_torque, op.rop) == (120e3, 10.0, 0.0, 0.01)
    assert sc.controller.type == "pi"
    r = sc.reference
    assert (r.type, r.axial_velocity, r.angular_velocity) == ("step", 0.01, 20.0)
    assert (r.axial_velocity_max, r.angular_velocity_max) == (0.05, 40.0)
    fem = parse_sil_scenario({"model": {"fidelity": "fem"}, "controller": {"type": "none"}})
    assert fem.model.fem.n_elements == 23 and fem.simulation.dt == 1e-3
    dhp = parse_sil_scenario({"model": {"interface": "state"}, "controller": {"type": "dhp"}})
    d = dhp.controller.options.dhp
    assert (d.design, d.weights, d.training.horizon, d.training.n_samples) == (
        "hybrid24", "robust", 8.0, 50)
    assert parse_sil_scenario({"title": "rig 7"}).title == "rig 7"


@pytest.mark.parametrize("data, field", [
    ({"operation": {"wob": [[0, "100 kN"], [5, "120 kN"]]}}, "operation.wob"),
    ({"operation": {"surface_speed": [[0, 5.0], [5, 10.0]]}}, "operation.surface_speed"),
    ({"reference": {"axial_velocity": [[0, 0.01], [5, 0.02]]}}, "reference.axial_velocity"),
])
def test_a_profile_is_refused_where_the_sil_needs_a_constant(data, field):
    with pytest.raises(ScenarioError, match="a constant here") as info:
        parse_sil_scenario(data, "s.toml")
    assert info.value.field == field


@pytest.mark.parametrize("data, field", [
    ({"controller": {"type": "eid"}}, "controller.type"),
    ({"model": {"interface": "state"},
      "controller": {"type": "dhp", "dhp": {"design": "fem24"}}}, "controller.dhp.design"),
    ({"model": {"interface": "state"},
      "controller": {"type": "dhp", "dhp": {"weights": "heavy"}}}, "controller.dhp.weights"),
    ({"model": {"interface": "state"},
      "controller": {"type": "dhp", "dhp": {"training": {"n_samples": 1}}}},
     "controller.dhp.training.n_samples"),
    ({"reference": {"type": "user"}}, "reference.type"),
    ({"model": {"fidelity": "beam"}}, "model.fidelity"),
    ({"model": {"fidelity": "hybrid", "preset": "hybrid99"}}, "model.preset"),
    ({"model": {"fidelity": "fem", "preset": "table_5_1"}}, "model.preset"),
    # keys of the one schema the SIL does not read are refused, not ignored
    ({"model": {"fidelity": "hybrid", "friction": 0.2}}, "model.friction"),
    ({"simulation": {"integrator": "euler"}}, "simulation.integrator"),
    ({"rig": {"top_drive": {"kp": 1e4}}}, "rig"),
    ({"model": {"interface": "state"},
      "controller": {"type": "dhp", "dhp": {"plan": {}}}}, "controller.dhp.plan"),
])
def test_what_the_sil_does_not_take_is_refused_by_name(data, field):
    with pytest.raises(ScenarioError) as info:
        parse_sil_scenario(data, "s.toml")
    assert info.value.field == field, str(info.value)
