"""Python and files agree (issue 23, item 6): :class:`~downhole.system.DrillingSystem`, its
``build`` options, the builders (``fem_model``, ``hybrid_model``) and ``torque_drag`` have the
names and defaults of the scenario keys, so that a description gives the same model and the same
numbers from Python and from a file."""

import dataclasses
import inspect
import math

import pytest

from downhole._schema import (
    FemOptions,
    HookTable,
    HybridOptions,
    LumpedOptions,
    ModelTable,
    NeutralOptions,
    TopDriveTable,
    TorqueDragTable,
)
from downhole.errors import DownholeInputError
from downhole.params.rig import Hook, TopDrive
from downhole.scenario.system import DESCRIBED
from downhole.string.fem import fem_model
from downhole.string.hybrid import hybrid_model
from downhole.string.torque_drag import torque_drag
from downhole.system import BUILD_OPTIONS, FIDELITIES, DrillingSystem

TABLES = {"lumped4": LumpedOptions, "lumped12": LumpedOptions, "neutral": NeutralOptions,
          "fem": FemOptions, "hybrid": HybridOptions}
#: Keys of [model.<fidelity>] that change the description instead of being build options.
DESCRIPTION_KEYS = {"friction", "lump"}


def _defaults(func):
    return {k: p.default for k, p in inspect.signature(func).parameters.items()
            if p.default is not inspect.Parameter.empty}


def _schema_defaults(model):
    """The one schema's defaults, None resolved as a described system resolves it."""
    return {k: DESCRIBED.get(k) if f.default is None and k in DESCRIBED else f.default
            for k, f in model.model_fields.items()}


def test_drilling_system_defaults_are_the_model_table_defaults():
    schema = _schema_defaults(ModelTable)
    fields = {f.name: f.default for f in dataclasses.fields(DrillingSystem)
              if f.default is not dataclasses.MISSING}
    assert set(fields) == {"friction", "rayleigh_alpha", "rayleigh_beta", "lump_length",
                           "wave_section"}
    for name, value in fields.items():
        assert schema[name] == value, name
    assert fields["friction"] == 0.0   # no wall contact unless asked for, in both


def test_rig_defaults_are_the_rig_table_defaults():
    td, hook = _schema_defaults(TopDriveTable), _schema_defaults(HookTable)
    assert hook.pop("mode") is None   # decided by the set-point (rop: velocity, else force)
    assert set(td) == {"inertia", "kp", "ki"} and set(hook) == {"servo_stiffness",
                                                                "servo_damping", "block_mass"}
    for name, value in td.items():
        assert getattr(TopDrive(), name) == value, name
    for name, value in hook.items():
        assert getattr(Hook(), name) == value, name


@pytest.mark.parametrize("fidelity", FIDELITIES)
def test_build_options_are_the_keys_and_defaults_of_the_fidelity_table(fidelity):
    schema = _schema_defaults(TABLES[fidelity])
    options = BUILD_OPTIONS[fidelity]
    assert set(options) == set(schema) - DESCRIPTION_KEYS
    for name, value in options.items():
        assert schema[name] == value, name


def test_builders_defaults_are_the_build_options():
    fem, hyb = _defaults(fem_model), _defaults(hybrid_model)
    for name, value in BUILD_OPTIONS["fem"].items():
        assert fem[name] == value, name
    for name, value in BUILD_OPTIONS["hybrid"].items():
        assert hyb[name] == value, name
    assert _defaults(DrillingSystem._build_hybrid)["preset"] is None
    assert _defaults(DrillingSystem.lumped_derivation)["reference_elements"] == \
        BUILD_OPTIONS["lumped4"]["reference_elements"]
    assert BUILD_OPTIONS["fem"]["max_element_angle"] == pytest.approx(math.radians(2.0))
    # the builders' damping defaults are the description's
    sysm = DrillingSystem.table_5_1()
    m = fem_model(n_elements=20)
    assert (m.info["rayleigh_alpha"], m.info["rayleigh_beta"]) == (sysm.rayleigh_alpha,
                                                                   sysm.rayleigh_beta)


def test_a_described_well_has_no_wall_contact_unless_asked_for_in_the_builders_too():
    from downhole.string.drillstring import DrillString, pipe_section
    from downhole.well.path import Arc, Vertical, WellPath

    well = WellPath.from_sections([Vertical(1000.0), Arc(1000.0, 0.5)])
    ds = DrillString.uniform(well.total_depth, pipe_section(0.127, 0.1086))
    assert fem_model(well, ds).mu == 0.0
    assert hybrid_model(well=well, string=ds, md_b=300.0, md_c=900.0).mu == 0.0
    # the Table 5.1 setup (no well given) keeps its friction 0.5
    assert fem_model(n_elements=20).mu == 0.5 == DrillingSystem.table_5_1().friction


def test_torque_drag_defaults_are_the_torque_drag_table_defaults():
    schema = _schema_defaults(TorqueDragTable)
    for func in (DrillingSystem.torque_drag, torque_drag):
        d = _defaults(func)
        assert tuple(d["friction"]) == tuple(schema["friction_factors"])
        assert d["step"] == schema["step"]
    assert _defaults(DrillingSystem.torque_drag)["tob"] is None   # the bit law's, as the file's


@pytest.mark.parametrize("fidelity, old, new", [
    ("fem", "elements", "n_elements"),
    ("hybrid", "nodes_ab", "n_ab"),
    ("hybrid", "nodes_cd", "n_cd"),
])
def test_an_old_spelling_is_refused_naming_the_one_name(fidelity, old, new):
    with pytest.raises(DownholeInputError, match=f"unknown option '{old}' .*did you mean "
                                                 f"'{new}'"):
        DrillingSystem.table_5_1().build(fidelity, **{old: 300})


def test_python_torque_and_drag_equals_the_command_line_case():
    """``DrillingSystem.torque_drag`` takes the TOB from the bit law at the WOB, as
    ``downhole torque-drag`` does: same drilling-case surface torque from Python and the file."""
    from pathlib import Path

    from downhole.scenario import load_scenario
    from downhole.scenario.torque_drag import run_torque_drag, torque_drag_case
    from downhole.system import steady_bit_state

    example = Path(__file__).resolve().parents[1] / "examples" / "torque_drag.toml"
    data, source, _ = load_scenario(example)
    case = torque_drag_case(data, source)
    cli = run_torque_drag(case, source)
    sysm = case.system
    py = sysm.torque_drag(friction=case.friction, wob=case.wob, step=case.step)
    assert py.tob == pytest.approx(case.tob, rel=1e-12)
    assert py.torque["drilling"][:, 0] == pytest.approx(cli.torque["drilling"][:, 0],
                                                        rel=1e-12)
    # the TOB is the bit law's at that WOB and the top drive's speed
    _, wob, tob = steady_bit_state(sysm.bit, sysm.rig.top_drive.speed, wob=case.wob)
    assert wob == pytest.approx(case.wob) and tob == pytest.approx(py.tob)
    assert py.tob > 0
    # without friction the string carries the TOB to the surface unchanged (hand value)
    free = sysm.torque_drag(friction=0.0, wob=case.wob, step=case.step, hook_load=False)
    assert free.torque["drilling"][0, 0] == pytest.approx(py.tob, rel=1e-12)
    # tob = 0 drops it (the off-bottom torque at mu = 0 is 0)
    none = sysm.torque_drag(friction=0.0, wob=case.wob, tob=0.0, step=case.step,
                            hook_load=False)
    assert none.torque["drilling"][0, 0] == pytest.approx(0.0, abs=1e-9)
