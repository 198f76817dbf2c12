"""Every example through every command (issue 23): ``simulate``, ``export-fmu``, the Gymnasium
environment (``DrillingEnv.from_scenario`` + ``reset`` + a few ``step``) and, for a file with a
``[controller]``, ``sil`` in process; a described system (``[well]`` + ``[string]``) also through
``simulate --fidelity F`` and ``export-fmu --fidelity F`` at all five fidelities.

Each case either runs (exit 0, its output written) on a SHORT copy of the example (``[simulation]
duration`` 0.1 s, DHP training horizons cut) or is refused with exit code 2 and ONE line
``error: FILE: dotted.field: ...`` (the environment: a ``ScenarioError`` whose one line is
``FILE: dotted.field: ...``) -- never a traceback, never exit 1. The expected outcome of every
(file, command) is written below, with the reason of every refusal, so that a change shows.
docs/scenarios.md ("Which command runs which example") is this table in prose. The UDP recipe
(``sil --remote`` + ``sil-controller``) runs on one PI example and on the HIL example
(marker ``realtime``).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest
import tomli_w

from downhole.cli import main
from downhole.errors import DownholeInputError

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
RUN = "runs"
SLOW = "slow"  # runs, but designs or trains for more than a few seconds: @pytest.mark.slow
RIG = "with a rig"  # runs with a rig on the HIL link: test_udp_recipe
FIDELITIES = ("lumped4", "lumped12", "neutral", "fem", "hybrid")

# Expected outcome per example and command: RUN, SLOW (runs; marked slow), RIG or the dotted field
# of the one-line refusal. "sil" only for files with a [controller].
MATRIX: dict[str, dict[str, str]] = {
    # DHP design files: simulate trains, then runs the closed loop (slow). No plant to export;
    # the SIL's DHP reads design/weights/training only, its fem plant takes no preset.
    "dhp_lumped.toml": {"simulate": SLOW, "export-fmu": "controller.type",
                        "gym": "reference.t_final",  # a ramp's end: the SIL's references are fixed
                        "sil": "reference.t_final"},
    "dhp_sine_fem24.toml": {"simulate": SLOW, "export-fmu": "controller.type",
                            "gym": "model.preset",  # the SIL's fem plant is Table 5.1's, no preset
                            "sil": "model.preset"},
    "dhp_step_fem24.toml": {"simulate": SLOW, "export-fmu": "controller.type",
                            "gym": "controller.dhp.dt",  # the SIL's DHP steps at simulation.dt
                            "sil": "controller.dhp.dt"},
    "dhp_step_hybrid68.toml": {"simulate": SLOW, "export-fmu": "controller.type",
                               "gym": "controller.dhp.plan",  # the SIL plans with weights only
                               "sil": "controller.dhp.plan"},
    # FEM / hybrid presets with their top-drive PI; the SIL's plants have their own top drive
    "directional_fem_stickslip.toml": {"simulate": RUN, "export-fmu": RUN,
                                       "gym": "rig", "sil": "rig"},
    "directional_hybrid68_stickslip.toml": {
        "simulate": RUN,
        "export-fmu": "operation.surface_speed",  # a profile: the importer drives the input
        "gym": "model.wave_section", "sil": "model.wave_section"},  # SIL hybrids are presets
    # described systems: the SIL (and so the environment) runs the system's model at its
    # fidelity under the rig; a FEM preset with a described well is the preset's runner's
    "directional_survey.toml": {"simulate": RUN, "export-fmu": RUN, "gym": RUN},
    "directional_survey_soft_torque.toml": {"simulate": RUN, "export-fmu": RUN,
                                            "gym": "model.preset", "sil": "model.preset"},
    # DP problems: only `downhole optimize dp` reads [optimize]
    "dp_customized.toml": {"simulate": "optimize.method", "export-fmu": "optimize.method",
                           "gym": "optimize"},
    # a DP problem on a described string: `optimize dp` derives its model (test_dp_described)
    "dp_described.toml": {"simulate": "optimize.method", "export-fmu": "optimize.method",
                          "gym": "optimize"},
    "dp_robust.toml": {"simulate": "optimize.method", "export-fmu": "optimize.method",
                       "gym": "optimize"},
    "dp_seed_regions.toml": {"simulate": "optimize.method", "export-fmu": "optimize.method",
                             "gym": "optimize"},
    # neutral presets with EID: the SIL's neutral plant is Table 3.1's, named by no preset
    "eid_nominal.toml": {"simulate": RUN, "export-fmu": RUN, "gym": "model.preset",
                         "sil": "model.preset"},
    "eid_tracking.toml": {"simulate": RUN,
                          "export-fmu": "simulation.noise.axial_velocity",  # not in a plant
                          "gym": "simulation.noise", "sil": "simulation.noise"},
    # lumped presets (velocity mode, explicit Euler: what the SIL's lumped plant is)
    "fig2.3.toml": {"simulate": RUN, "export-fmu": RUN, "gym": RUN},
    "fig2.4.toml": {"simulate": RUN, "export-fmu": RUN, "gym": RUN},
    "first_run.toml": {"simulate": RUN, "export-fmu": RUN, "gym": RUN},
    "first_run_stickslip.toml": {"simulate": RUN, "export-fmu": RUN, "gym": RUN},
    "models-4th-vs-12th.toml": {"simulate": RUN, "export-fmu": RUN, "gym": RUN},
    "neutral_open_loop.toml": {"simulate": RUN, "export-fmu": RUN,
                               "gym": "operation.axial_command"},  # the SIL's neutral: U_T, WOB
    "nominal_table_2_1.toml": {"simulate": RUN, "export-fmu": RUN, "gym": RUN},
    "oilfield_units.toml": {"simulate": RUN, "export-fmu": RUN, "gym": RUN},
    # SIL files: simulate runs no SIL controller / interface / link
    "sil_dashboard_lumped.toml": {"simulate": "controller.type",  # a lumped preset: open loop
                                  "export-fmu": RUN, "gym": RUN, "sil": RUN},
    "sil_dhp_hybrid68.toml": {"simulate": "link", "export-fmu": RUN,
                              "gym": "model.interface",  # 'state': the env drives the surface
                              "sil": SLOW},
    "sil_hil.toml": {"simulate": "operation.surface_torque",
                     "export-fmu": "link.mode", "gym": "link.mode",  # HIL: bit from the rig
                     "sil": RIG},  # needs the rig on the link: test_udp_recipe below
    "sil_open_loop.toml": {"simulate": "model.interface", "export-fmu": RUN,
                           "gym": "model.interface", "sil": RUN},
    "sil_pi_hybrid68.toml": {"simulate": "model.interface", "export-fmu": RUN, "gym": RUN,
                             "sil": RUN},
    "stickslip-lumped.toml": {"simulate": RUN, "export-fmu": RUN, "gym": RUN},
    # sweeps: only `downhole sweep` reads [sweep]
    "sweep_montecarlo.toml": {"simulate": "sweep.metrics", "export-fmu": "sweep.metrics",
                              "gym": "sweep"},
    "sweep_stability_map.toml": {"simulate": "sweep.metrics", "export-fmu": "sweep.metrics",
                                 "gym": "sweep"},
    "table_5_1.toml": {"simulate": RUN, "export-fmu": RUN, "gym": RUN},
    "torque_drag.toml": {"simulate": RUN, "export-fmu": RUN, "gym": RUN},
}

# `simulate --fidelity F` and `export-fmu --fidelity F` of the files that describe a well and a
# string; a missing entry runs. SLOW: runs, slow (matching a long string's lumped chain). A
# (simulate, export-fmu) pair when the two name the refused field differently.
_OVERRIDE = "model.fidelity"  # --fidelity needs a described system without a controller
FIDELITY_MATRIX: dict[str, dict[str, str]] = {
    "directional_survey.toml": {"lumped4": SLOW, "lumped12": SLOW},
    # export-fmu names its option: --fidelity applies to a described system without [controller]
    # (its own fidelity, fem, is accepted by export-fmu)
    "directional_survey_soft_torque.toml": {**dict.fromkeys(FIDELITIES, (_OVERRIDE, "--fidelity")),
                                            "fem": (_OVERRIDE, RUN)},
    "dp_described.toml": dict.fromkeys(FIDELITIES, "optimize.method"),
    "first_run.toml": {},
    "first_run_stickslip.toml": {},
    "oilfield_units.toml": {},
    "table_5_1.toml": {"lumped12": SLOW},
    # the neutral model's wave segment is one uniform pipe: pipe and heavyweight above the BHA
    "torque_drag.toml": {"lumped4": SLOW, "lumped12": SLOW, "neutral": "--fidelity"},
}


def test_the_tables_name_every_example():
    assert sorted(MATRIX) == sorted(p.name for p in EXAMPLES.glob("*.toml"))
    for name, row in MATRIX.items():
        data = tomllib.loads((EXAMPLES / name).read_text())
        want = {"simulate", "export-fmu", "gym"} | ({"sil"} if "controller" in data else set())
        assert set(row) == want, name
    described = sorted(p.name for p in EXAMPLES.glob("*.toml")
                       if {"well", "string"} <= set(tomllib.loads(p.read_text())))
    assert sorted(FIDELITY_MATRIX) == described
    assert not list(EXAMPLES.glob("research/*.toml"))  # research/ holds scripts, no scenarios


def short_copy(name: str, folder: Path) -> Path:
    """A copy of example ``name`` in ``folder`` (with the data files it names) that runs for
    0.1 s and trains DHP controllers over short horizons."""
    for csv in EXAMPLES.glob("*.csv"):
        shutil.copy(csv, folder / csv.name)
    data = tomllib.loads((EXAMPLES / name).read_text())
    if isinstance(data.get("simulation"), dict):
        data["simulation"]["duration"] = "0.1 s"
    dhp = data.get("controller", {}).get("dhp")
    if dhp is not None:
        # a planned start-up (7 s, the examples' and the default) must fit in the horizon
        planned = "plan" in dhp or dhp.get("weights") == "planned"
        dhp.setdefault("training", {})["horizon"] = "7.5 s" if planned else "0.5 s"
    path = folder / name
    path.write_text(tomli_w.dumps(data))
    return path


def _argv(command: str, path: Path, out: Path, fidelity: str | None = None) -> list[str]:
    fid = ["--fidelity", fidelity] if fidelity else []
    if command == "simulate":
        return ["simulate", str(path), "--out", str(out / "run"), *fid]
    if command == "export-fmu":
        return ["export-fmu", str(path), "--out", str(out / "plant.fmu"), *fid]
    return ["sil", str(path), "--unpaced", "--no-progress", "--out", str(out / "sil.nc")]


def _written(command: str, out: Path) -> bool:
    return {"simulate": (out / "run" / "result.nc"), "export-fmu": out / "plant.fmu",
            "sil": out / "sil.nc"}[command].is_file()


def check_cli(command, path, out, expected, capsys, fidelity=None):
    rc = main(_argv(command, path, out, fidelity))
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    if expected in (RUN, SLOW):
        assert rc == 0, err
        assert _written(command, out)
    else:
        assert rc == 2 and len(lines) == 1, err
        assert lines[0].startswith(f"error: {path}: {expected}: "), lines[0]
        assert not _written(command, out)


def check_gym(path, expected):
    from downhole.gym import DrillingEnv

    if expected in (RUN, SLOW):
        env = DrillingEnv.from_scenario(path)
        obs, _ = env.reset(seed=0)
        for _ in range(3):
            obs, *_ = env.step(np.zeros(2))
        assert np.all(np.isfinite(obs))
        return
    with pytest.raises(DownholeInputError) as info:
        DrillingEnv.from_scenario(path)
    line = str(info.value)
    assert "\n" not in line and line.startswith(f"{path}: {expected}: "), line


def _cases():
    for name, row in MATRIX.items():
        for command, expected in row.items():
            if expected == RIG:
                continue
            marks = [pytest.mark.slow] if expected == SLOW else []
            yield pytest.param(name, command, expected, marks=marks, id=f"{name}-{command}")


@pytest.mark.parametrize("name, command, expected", list(_cases()))
def test_example_runs_or_is_refused_in_one_line(name, command, expected, tmp_path, capsys):
    path = short_copy(name, tmp_path)
    if command == "gym":
        check_gym(path, expected)
    else:
        check_cli(command, path, tmp_path, expected, capsys)


def _fidelity_cases():
    for name, row in FIDELITY_MATRIX.items():
        for fid in FIDELITIES:
            for command in ("simulate", "export-fmu"):
                expected = row.get(fid, RUN)
                if isinstance(expected, tuple):
                    expected = expected[command == "export-fmu"]
                # the FMU's plant is the one simulate steps: export-fmu at every fidelity is slow
                slow = expected == SLOW or (command == "export-fmu" and expected == RUN)
                marks = [pytest.mark.slow] if slow else []
                yield pytest.param(name, fid, command, expected, marks=marks,
                                   id=f"{name}-{fid}-{command}")


@pytest.mark.parametrize("name, fidelity, command, expected", list(_fidelity_cases()))
def test_described_system_at_every_fidelity(name, fidelity, command, expected, tmp_path,
                                            capsys):
    path = short_copy(name, tmp_path)
    check_cli(command, path, tmp_path, expected, capsys, fidelity=fidelity)


def test_training_settings_the_trainer_refuses_name_the_file_and_field(tmp_path, capsys):
    """n_samples below the basis size of the trained model (known only once it is built) and a
    horizon shorter than the planned start-up: one line naming the key, no training first."""
    data = tomllib.loads((EXAMPLES / "dhp_step_fem24.toml").read_text())
    data["controller"]["dhp"]["training"].update(n_samples=2, horizon="0.5 s")
    data["simulation"]["duration"] = "0.1 s"
    path = tmp_path / "few.toml"
    path.write_text(tomli_w.dumps(data))
    assert main(["simulate", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"error: {path}: controller.dhp.training.n_samples: n_samples = 2 "
                          "is fewer than"), err
    for name in ("dhp_step_hybrid68.toml", "sil_dhp_hybrid68.toml"):
        path = short_copy(name, tmp_path)
        data = tomllib.loads(path.read_text())
        data["controller"]["dhp"]["training"]["horizon"] = "2 s"
        path.write_text(tomli_w.dumps(data))
        command = "simulate" if name.startswith("dhp") else "sil"
        assert main(_argv(command, path, tmp_path)) == 2
        err = capsys.readouterr().err.strip()
        assert err.startswith(f"error: {path}: controller.dhp.training.horizon: 2 s: "), err
        assert "\n" not in err


# ----------------------------------------------------------------------------- the UDP recipe
CLI = [sys.executable, "-c", "import sys; from downhole.cli import main; "
       "sys.exit(main(sys.argv[1:]))"]


def _start(*args):
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    return subprocess.Popen([*CLI, *map(str, args)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env)


def _finish(proc, timeout=180):
    try:
        out, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        out, err = proc.communicate()
        raise AssertionError(f"timed out:\n{err[-3000:]}") from None
    return proc.returncode, out, err


@pytest.mark.realtime
@pytest.mark.parametrize("name, other", [
    ("sil_pi_hybrid68.toml", ["--scenario"]),  # the PI over the link
    ("sil_hil.toml", ["--rig"]),               # the software rig on the HIL link
])
def test_udp_recipe(name, other, tmp_path):
    """``sil --remote`` (HIL: the link of the file) with ``sil-controller`` on a free port; only
    exit codes and outputs are checked, nothing that depends on the machine's load."""
    import json

    from downhole.sil.testing import free_port

    path = short_copy(name, tmp_path)
    port = free_port()
    plant_args = ["--remote"] if "--scenario" in other else []
    plant = _start("sil", path, *plant_args, "--port", port, "--no-progress", "--wait", "60",
                   "--out", tmp_path / "run.nc")
    ctrl_args = [*other, path] if "--scenario" in other else other
    ctrl = _start("sil-controller", *ctrl_args, "--port", port, "--idle-timeout", "3",
                  "--no-progress", "--wait", "60")
    rc_p, out_p, err_p = _finish(plant)
    rc_c, _, err_c = _finish(ctrl)
    assert rc_p == 0, err_p
    assert rc_c == 0, err_c
    assert json.loads(out_p)["stats"]["steps"] == 100  # 0.1 s at 1 ms
    assert (tmp_path / "run.nc").is_file()
