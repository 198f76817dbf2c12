"""The one scenario vocabulary (issue 15, item 2) for the lumped, neutral and directional files.

Every older-dialect key of those files (an entry of :data:`downhole.scenario.schema.RENAMES`)
makes ``downhole simulate`` stop with exit code 2 and one line that names the file, the dotted
key and the key to use instead, before anything is written; and every shipped example of these
families (and of the described system, the EID design and the sweeps) validates as it stands.
"""

from __future__ import annotations

import copy
import os
import tomllib
from pathlib import Path
from unittest import mock

import pytest
import tomli_w

from downhole.cli import main
from downhole.scenario.schema import RENAMES

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"

#: Short valid files of each dialect, into which one older key is written.
LUMPED = {"title": "renames, lumped", "model": {"fidelity": "lumped4", "preset": "table_2_1"},
          "operation": {"rop": "10 mm/s", "surface_speed": "10 rad/s"},
          "simulation": {"duration": "0.2 s", "dt": "0.5 ms"}}
NEUTRAL = {"title": "renames, neutral", "model": {"fidelity": "neutral", "preset": "table_3_1"},
           "operation": {"axial_command": "1.147224 m/s", "surface_speed": "22.5196 rad/s"},
           "simulation": {"duration": "0.2 s", "dt": "0.1 ms"}}
FEM = {"title": "renames, FEM", "model": {"fidelity": "fem", "preset": "table_5_1",
                                          "fem": {"n_elements": 20}},
       "operation": {"surface_speed": "10 rad/s", "wob": "120 kN"},
       "simulation": {"duration": "0.2 s", "dt": "1 ms"}}
HYBRID = {"title": "renames, hybrid", "model": {"fidelity": "hybrid", "preset": "table_5_1"},
          "simulation": {"duration": "0.2 s", "dt": "1 ms"}}

#: Each older key of these dialects: (base file, a value it had there).
OLD_KEYS = {
    "name": (LUMPED, "a title"),
    "model.type": (LUMPED, "lumped4"),
    "model.bit": (LUMPED, {"epsilon": "60 MPa"}),
    "model.hybrid": (HYBRID, "hybrid68"),
    "model.elements": (FEM, 50),
    "model.mass": (FEM, "lumped"),
    "model.nodes_ab": (HYBRID, 4),
    "model.nodes_cd": (HYBRID, 13),
    "model.fem.elements": (FEM, 50),
    "model.hybrid.nodes_ab": (HYBRID, 4),
    "model.hybrid.nodes_cd": (HYBRID, 13),
    "model.n_lags": (HYBRID, 1),
    "model.md_b": (HYBRID, "2000 m"),
    "model.md_c": (HYBRID, "3000 m"),
    "surface": (LUMPED, {}),
    "surface.mode": (LUMPED, "velocity"),
    "surface.axial_velocity": (NEUTRAL, 1.147224),
    "surface.angular_velocity": (LUMPED, "10 rad/s"),
    "surface.hook_load": (LUMPED, "100 kN"),
    "surface.surface_torque": (LUMPED, "5 kN*m"),
    "hook": (FEM, {}),
    "hook.type": (FEM, "force"),
    "hook.hook_load": (FEM, [[0, "380 kN"], [20, "360 kN"]]),
    "hook.wob": (FEM, "120 kN"),
    "hook.velocity": (FEM, "5 mm/s"),
    "hook.servo_stiffness": (FEM, "1e7 N/m"),
    "hook.servo_damping": (FEM, "1e6 N*s/m"),
    "hook.block_mass": (FEM, "0 kg"),
    "controller.speed": (FEM, "10 rad/s"),
    "controller.kp": (FEM, 1e4),
    "controller.ki": (FEM, 2e3),
    "controller.inertia": (FEM, "500 kg*m**2"),
    "simulation.noise.axial": (NEUTRAL, "1 mm/s"),
    "simulation.noise.angular": (NEUTRAL, "1 rad/s"),
}

#: Older keys of the other dialects (SIL: [plant], [runtime], controller.kind and
#: [controller.dhp]; SIL / DHP: the short [reference] names; DHP: [model] kind ..., [weights],
#: [training], [plan], simulation.plant; DP: the top-level problem tables), tested with those
#: commands (tests/test_sil_runtime.py, test_dhp_scenario_schema.py, test_dp_problem.py).
OTHER_DIALECTS = ("plant", "runtime", "reference.", "controller.kind", "controller.dhp.",
                  "weights", "training", "plan", "model.kind", "model.n_elements", "model.dt",
                  "model.input_limits", "model.epsilon", "simulation.plant", "dp", "horizon",
                  "step", "x1_regions", "x3_regions", "x2", "x4", "targets", "bounds", "robust",
                  "standard")


def _is_other(key: str) -> bool:
    return any(key == p or key.startswith(p if p.endswith(".") else p + ".")
               for p in OTHER_DIALECTS)


def test_every_rename_of_these_dialects_is_covered():
    """A rename added to the schema for these files is added here too (and no key here is
    invented: each is a real entry)."""
    ours = {k for k in RENAMES if not _is_other(k)}
    assert ours == set(OLD_KEYS)
    # the replacement named is a key of today's vocabulary, not another older one
    for old in OLD_KEYS:
        new = RENAMES[old].split()[0].strip("[]")
        assert new not in RENAMES, (old, new)


@pytest.mark.parametrize("dotted", sorted(RENAMES))
def test_every_rename_is_refused_by_the_one_reader(dotted, tmp_path):
    """Every entry of the table, of every dialect (SIL and DHP included), through the reader
    every command uses: one line naming the file, the key and its replacement."""
    from downhole.errors import ScenarioError
    from downhole.scenario.schema import read_scenario

    value = "hybrid68" if dotted == "model.hybrid" else ({} if "." not in dotted and
                                                          dotted != "name" else 1.0)
    path = tmp_path / "old.toml"
    path.write_text(tomli_w.dumps(_with_old_key({}, dotted, value)))
    with pytest.raises(ScenarioError) as info:
        read_scenario(path)
    assert info.value.field == dotted
    assert str(info.value) == f"{path}: {dotted}: renamed: use {RENAMES[dotted]} " \
                              "(see docs/scenarios.md)"


def _with_old_key(base: dict, dotted: str, value) -> dict:
    data = copy.deepcopy(base)
    *tables, key = dotted.split(".")
    node = data
    for t in tables:
        node = node.setdefault(t, {})
    node[key] = value
    return data


@pytest.mark.parametrize("dotted", sorted(OLD_KEYS))
def test_older_key_gets_one_line_naming_its_replacement(dotted, tmp_path, capsys):
    base, value = OLD_KEYS[dotted]
    path = tmp_path / "old.toml"
    path.write_text(tomli_w.dumps(_with_old_key(base, dotted, value)))
    out = tmp_path / "out"
    before = sorted(os.listdir(tmp_path))
    rc = main(["simulate", str(path), "--out", str(out)])
    err = capsys.readouterr().err.strip()
    assert rc == 2, err
    assert "Traceback" not in err and len(err.splitlines()) == 1, err
    assert err == f"error: {path}: {dotted}: renamed: use {RENAMES[dotted]} " \
                  "(see docs/scenarios.md)", err
    assert sorted(os.listdir(tmp_path)) == before and not out.exists()  # nothing written


def test_the_base_files_themselves_run(tmp_path):
    """The files the older keys are written into are valid as they are: the refusal above is
    the older key's alone."""
    from downhole.scenario import validate_data

    for base in (LUMPED, NEUTRAL, FEM, HYBRID):
        data = copy.deepcopy(base)
        validate_data(data, f"<{base['title']}>")
    path = tmp_path / "lumped.toml"
    path.write_text(tomli_w.dumps(LUMPED))
    assert main(["simulate", str(path), "--out", str(tmp_path / "out")]) == 0
    assert (tmp_path / "out" / "result.nc").exists()


def test_most_precise_key_is_named_first(tmp_path, capsys):
    """A whole older table is reported at its most precise key (``surface.angular_velocity``,
    not ``surface``), so the line names the exact replacement."""
    data = _with_old_key(LUMPED, "surface.angular_velocity", "10 rad/s")
    data["surface"]["axial_velocity"] = "10 mm/s"
    path = tmp_path / "old.toml"
    path.write_text(tomli_w.dumps(data))
    assert main(["simulate", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    # deepest keys first, then in name order: angular_velocity before axial_velocity
    assert f": surface.angular_velocity: renamed: use {RENAMES['surface.angular_velocity']}" \
        in err, err
    assert ": surface: " not in err


def test_today_model_hybrid_table_is_not_an_older_key(tmp_path):
    """``model.hybrid`` is an older key only as a string (``hybrid = "hybrid68"``); the table
    ``[model.hybrid]`` is today's."""
    from downhole.scenario import load_scenario, validate_data

    path = tmp_path / "h.toml"
    path.write_text(tomli_w.dumps(_with_old_key(HYBRID, "model.hybrid", {"preset": "hybrid24"})))
    data, source, _ = load_scenario(path)
    assert validate_data(data, source) == "hybrid"


# ------------------------------------------------------------------ the examples validate
def _families():
    skip = ("dhp_", "dp_", "sil_")
    return sorted(p for p in EXAMPLES.glob("*.toml") if not p.name.startswith(skip))


def test_the_examples_of_these_families_are_found():
    names = {p.name for p in _families()}
    for n in ("nominal_table_2_1.toml", "neutral_open_loop.toml", "eid_nominal.toml",
              "directional_fem_stickslip.toml", "directional_hybrid68_stickslip.toml",
              "table_5_1.toml", "sweep_stability_map.toml", "sweep_montecarlo.toml"):
        assert n in names, n


@pytest.mark.parametrize("example", _families(), ids=lambda p: p.name)
def test_example_validates_in_the_one_vocabulary(example):
    """Each example: no older key anywhere in it, and it validates with the loader of the
    command that reads it (``simulate``; ``sweep`` for the sweep files, whose cases are not
    run; ``design eid`` too for the EID files)."""
    from downhole.scenario import load_scenario, validate_data
    from downhole.scenario.schema import check_dialect

    data = tomllib.loads(example.read_text())
    check_dialect(data, str(example))  # raises on any older key
    if example.name.startswith("sweep_"):
        from downhole.sweep import runner

        class _Validated(Exception):
            pass

        with mock.patch.object(runner, "_execute", side_effect=_Validated), \
                pytest.raises(_Validated):
            runner.run_sweep(example, processes=1)
        # the swept parameters are today's paths too
        for path in data["sweep"]["params"]:
            assert not any(path == k or path.startswith(k + ".") for k in RENAMES
                           if k != "model.hybrid"), path
        return
    data, source, _ = load_scenario(example)
    mtype = validate_data(data, source)
    fid = data["model"]["fidelity"]
    assert mtype in ("system", fid, "dhp"), (mtype, fid)
    if example.name.startswith("eid_"):
        from downhole.cli.design_eid import load_eid_scenario

        model, options, reference = load_eid_scenario(example)
        assert model.bit.epsilon > 0 and reference is not None and isinstance(options, dict)
