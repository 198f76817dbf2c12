"""Layering: the mechanics core runs without control code, the compiled-controller extension
point of the neutral model, and the named DHP weight presets (library data, not experiment
data)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from downhole.control.dhp.weight_sets import weight_set, weight_set_names
from downhole.errors import DownholeInputError
from downhole.sim import simulate
from downhole.string.neutral import (
    NOMINAL_U_A,
    NOMINAL_U_T,
    NeutralPack,
    neutral_model,
)

UPPER = ("control", "sil", "cli", "experiments", "report", "bench", "sweep", "gym")


def test_core_imports_and_runs_without_upper_layers():
    # import-linter checks the static imports; this checks what a run actually loads
    code = (
        "import sys\n"
        "from downhole.sim import simulate\n"
        "from downhole.string.neutral import neutral_model\n"
        "from downhole.string.fem import fem_model\n"
        "import downhole.string.hybrid, downhole.sim, downhole.well, downhole.contact\n"
        "simulate(neutral_model('table_3_1'), duration=0.05, dt=1e-4)\n"
        "m = fem_model(n_elements=5)\n"
        "m.linear_model(1e-3)\n"
        f"bad = sorted(m for m in sys.modules if m.startswith('downhole.') and "
        f"m.split('.')[1] in {UPPER!r})\n"
        "print(bad)\n"
        "assert not bad, bad\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.strip().splitlines()[-1] == "[]"


class _ConstantFastPath:
    """A third-party controller that supplies a compiled runner through the hook: it holds the
    nominal commands, so the closed loop must equal the open loop with those inputs."""

    label = "constant-fast-path"

    def __init__(self):
        self.calls = 0

    def reset(self):
        pass

    def command(self, t, observation, reference):
        self.calls += 1
        # the Plant contract's commands: the axial one relative to the hanging equilibrium
        hang = neutral_model("table_3_1").hang_command
        return {"top_drive_axial_velocity": NOMINAL_U_A - hang,
                "top_drive_angular_velocity": NOMINAL_U_T}

    def kernel_runner(self, pack):
        def runner(pack, st, ref, mnoise, cmd_noise, nsteps, every, rec):
            # the one kernel, stepped by the controller's own code through the pack
            assert isinstance(pack, NeutralPack)
            cmd = np.empty((nsteps + 1, 2))
            cmd[:, 0] = NOMINAL_U_A - pack.model.hang_command
            cmd[:, 1] = NOMINAL_U_T
            n_main = (nsteps // every) * every
            status, rows = pack.run(st, cmd[:n_main + 1], rec, every, 1)
            if status == 0 and n_main < nsteps:
                status, _ = pack.run(st, cmd[n_main:], rec, nsteps - n_main, 1 + rows)
            return status, nsteps, {"measured_axial_velocity": rec[:, 1] + 0.0}

        return runner


class _NoFastPath(_ConstantFastPath):
    def kernel_runner(self, pack):
        return None


def test_controller_fast_path_hook_is_used_and_falls_back():
    model = neutral_model("table_3_1")
    kw = dict(duration=0.5, dt=2e-4, depth_of_cut="approximate")
    ol = simulate(model, **kw)
    fast = _ConstantFastPath()
    res = simulate(model, controller=fast, reference=(0.01, 20.0), **kw)
    assert fast.calls == 0  # the compiled runner ran the loop
    assert res.attrs["controller"] == "constant-fast-path"
    for ch in ("bit_axial_velocity", "bit_angular_velocity", "hook_load", "surface_torque"):
        assert np.array_equal(res[ch], ol[ch]), ch
    assert np.array_equal(res["measured_axial_velocity"], ol["bit_axial_velocity"])
    assert np.all(res["reference_angular_velocity"] == 20.0)
    # no runner (None) or python_loop=True: the same controller through the Python loop
    slow = _NoFastPath()
    res2 = simulate(model, controller=slow, reference=(0.01, 20.0), **kw)
    assert slow.calls == 2501  # one command per step, t_0 .. t_2500
    assert np.allclose(res2["bit_angular_velocity"], ol["bit_angular_velocity"], atol=1e-9)
    forced = _ConstantFastPath()
    simulate(model, controller=forced, reference=(0.01, 20.0), python_loop=True, **kw)
    assert forced.calls > 0


def test_controller_without_contract_is_rejected():
    with pytest.raises(DownholeInputError, match="reset"):
        simulate(neutral_model("table_3_1"), duration=0.01, dt=1e-4, controller=object())


def test_weight_presets_and_the_experiments_names_for_them():
    assert set(weight_set_names()) == {"design", "robust", "planned"}
    assert weight_set("robust") == dict(bit_velocity=(10.0, 10.0), bit_position=(1.0, 10.0),
                                        r=(1.0, 1.0))
    planned = weight_set("planned")
    assert planned["integral"] == (87.1, 287.0) and planned["r"] == (1.0, 2.07)
    from downhole.control.dhp import PenaltyWeights
    from downhole.experiments import ch4_dhp

    # the Ch. 4 claims' weights are the library defaults
    assert PenaltyWeights(**weight_set("design")) == PenaltyWeights()
    # the experiments' names are views of the presets, not second copies
    assert ch4_dhp.PLANNED_WEIGHTS == planned and ch4_dhp.ROBUST_WEIGHTS == weight_set("robust")
    for name in weight_set_names():
        PenaltyWeights(**weight_set(name))  # every preset is a valid PenaltyWeights
    PenaltyWeights(**ch4_dhp.HYBRID_WEIGHTS)
    weight_set("planned")["r"] = (0.0, 0.0)  # a fresh dict: the preset is not changed
    assert weight_set("planned") == planned


def test_weight_preset_unknown_name():
    with pytest.raises(DownholeInputError, match=r"no weight set 'nope'; known: \["):
        weight_set("nope")
    with pytest.raises(DownholeInputError, match="no weight set 'hybrid'"):
        weight_set("hybrid")  # a research record of the experiments (ch4_dhp.HYBRID_WEIGHTS)


def test_every_top_drive_inertia_default_is_the_one_named_default():
    import inspect

    from downhole.bench.ch5_models import _ode_rhs
    from downhole.control.affine import from_directional
    from downhole.control.dhp.directional import DirectionalStatePlant, directional_affine_model
    from downhole.control.dhp.plan import PlanSettings
    from downhole.params.rig import DEFAULT_TOP_DRIVE_INERTIA, TopDrive
    from downhole.params.strings import DirectionalWellParams
    from downhole.sil.hil import HILStringPlant
    from downhole.string.fem import DirectionalModel

    assert TopDrive().inertia == DEFAULT_TOP_DRIVE_INERTIA
    assert PlanSettings().top_drive_inertia == DEFAULT_TOP_DRIVE_INERTIA
    assert DirectionalWellParams.model_fields["top_drive_inertia"].default \
        == DEFAULT_TOP_DRIVE_INERTIA
    funcs = [DirectionalModel.continuous_linear_model, DirectionalModel.linear_model,
             DirectionalModel.nodal_force_map, from_directional, directional_affine_model,
             DirectionalStatePlant.__init__, HILStringPlant.__init__]
    for f in funcs:
        assert inspect.signature(f).parameters["top_drive_inertia"].default \
            == DEFAULT_TOP_DRIVE_INERTIA, f.__qualname__
    assert inspect.signature(_ode_rhs).parameters["j_td"].default == DEFAULT_TOP_DRIVE_INERTIA
