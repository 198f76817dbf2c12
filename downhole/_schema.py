"""The one scenario schema: the tables and key names every command reads.

(This module sits below every layer, like :mod:`downhole._reader`, so that control code (the DP
problem loader) reads files through it without importing scenario code; its public name is
:mod:`downhole.scenario.schema`.)

Every command that reads a scenario file (``simulate``, ``sil``, ``sil-controller``,
``export-fmu``, ``design eid``, ``design dhp``, ``optimize dp``, ``sweep``) and the Gymnasium
environment (:meth:`downhole.gym.DrillingEnv.from_scenario`) reads it through
:func:`read_scenario`, which

1. reads the file with the hardened reader (:func:`downhole._reader.read_toml`: size, UTF-8,
   NUL, depth, number and list limits; a directory or FIFO refused),
2. refuses a key of an older dialect with one line naming the key to use instead
   (:data:`RENAMES`),
3. refuses a top-level table that no command reads (:data:`TABLES`).

Each command then validates the tables it uses with the pydantic models of its runner, all of
which use the same names for the same things (this module's shared sections, composed there):

========================  ===========================================================
table                     what it holds
========================  ===========================================================
``title``, ``description``  shown in summaries
``[model]``               ``fidelity`` (lumped4 | lumped12 | neutral | fem | hybrid), ``preset``
                          (a seed table: table_2_1, table_3_1, table_5_1, ...) or a described
                          system (``[well]``, ``[string]``), per-fidelity options
``[well]``, ``[string]``  the described well and drill string
``[bit]``                 the bit law and its parameters (``epsilon``, ...), over the preset's
``[rig]``                 ``[rig.top_drive]`` (inertia, kp, ki), ``[rig.hook]`` (servo)
``[operation]``           set-points: ``surface_speed``, ``rop`` or ``wob``, ``surface_torque``,
                          ``hook_load``, ``mode`` (velocity | force)
``[reference]``           the bit-velocity reference: ``axial_velocity``, ``angular_velocity``
``[controller]``          ``type`` (none | pi | eid | dhp | ztorque | file ...), ``file`` and
                          per-type sub-tables (``[controller.dhp]``, ...)
``[simulation]``          ``duration``, ``dt``, ``record_dt``, ``start``, ``depth_of_cut``,
                          ``integrator``, ``[simulation.noise]``
``[realtime]``            the real-time runtime: ``paced``, ``max_lag``, ``ring_seconds``, ...
``[link]``, ``[safety]``  the UDP link and the controller-timeout action
``[dashboard]``           the web dashboard
``[sweep]``               parameter sweeps (``downhole sweep``)
``[optimize]``            the DP problem (``downhole optimize dp``)
========================  ===========================================================

Numbers may carry units (``"10 rad/s"``, ``"120 rpm"``, ``"25 klbf"``); bare numbers are SI.
``docs/scenarios.md`` lists every key.
"""

from __future__ import annotations

from pathlib import Path

from downhole._reader import read_toml
from downhole.errors import ScenarioError
from downhole.plausible import check_scenario

__all__ = [
    "RENAMES",
    "TABLES",
    "VALUE_RENAMES",
    "check_dialect",
    "raise_validation",
    "read_scenario",
]

#: Every top-level key of a scenario file.
TABLES = ("title", "description", "model", "well", "string", "bit", "rig", "operation",
          "reference", "controller", "simulation", "realtime", "link", "safety", "dashboard",
          "sweep", "optimize", "torque_drag")

#: Keys of the older dialects (dotted) and the key that replaces each. A file using one gets one
#: line naming its replacement; the most precise key is reported first.
RENAMES: dict[str, str] = {
    "name": "title",
    # [model]
    "model.type": "model.fidelity (lumped4 | lumped12 | neutral | fem | hybrid)",
    "model.bit": "[bit] (the bit law's parameters over the preset's, e.g. bit.epsilon)",
    "model.hybrid": "model.hybrid.preset",  # only when a string (see check_dialect)
    "model.elements": "model.fem.n_elements",
    "model.nodes_ab": "model.hybrid.n_ab",
    "model.nodes_cd": "model.hybrid.n_cd",
    # one name in Python (DrillingSystem.build, fem_model, hybrid_model) and in files
    "model.fem.elements": "model.fem.n_elements",
    "model.hybrid.nodes_ab": "model.hybrid.n_ab",
    "model.hybrid.nodes_cd": "model.hybrid.n_cd",
    "model.n_lags": "model.hybrid.n_lags",
    "model.md_b": "model.wave_section = [B, C]",
    "model.md_c": "model.wave_section = [B, C]",
    # [surface] (lumped and neutral files) -> [operation]
    "surface": "[operation] (surface_speed, rop, mode, hook_load, surface_torque)",
    "surface.mode": "operation.mode",
    "surface.axial_velocity": "operation.rop (a neutral file: operation.axial_command, U_A)",
    "surface.angular_velocity": "operation.surface_speed",
    "surface.hook_load": "operation.hook_load",
    "surface.surface_torque": "operation.surface_torque",
    # [hook] (FEM / hybrid files) -> [rig.hook] and [operation]
    "hook": "[rig.hook] (servo_stiffness, servo_damping, block_mass) and operation.wob / rop",
    "hook.type": "rig.hook.mode",
    "hook.hook_load": "operation.hook_load",
    "hook.wob": "operation.wob",
    "hook.velocity": "operation.rop",
    "hook.servo_stiffness": "rig.hook.servo_stiffness",
    "hook.servo_damping": "rig.hook.servo_damping",
    "hook.block_mass": "rig.hook.block_mass",
    # [controller]
    "controller.kind": "controller.type",
    "controller.speed": "operation.surface_speed",
    "controller.kp": "rig.top_drive.kp",
    "controller.ki": "rig.top_drive.ki",
    "controller.inertia": "rig.top_drive.inertia",
    # [plant] (SIL files) -> [model], [operation], [simulation]
    "plant": "[model] (fidelity, preset, interface), [operation] (wob, surface_speed, "
             "surface_torque, rop) and simulation.depth_of_cut",
    "plant.model": "model.fidelity (lumped4 | lumped12 | neutral | fem | hybrid) and "
                   "model.preset (hybrid24 | hybrid68 | hybrid108 for the hybrid)",
    "plant.interface": "model.interface",
    "plant.depth_of_cut": "simulation.depth_of_cut",
    "plant.wob": "operation.wob",
    "plant.top_drive_speed": "operation.surface_speed",
    "plant.surface_torque": "operation.surface_torque",
    "plant.axial_velocity": "operation.rop",
    "plant.design": "controller.dhp.design",
    "plant.n_elements": "model.fem.n_elements",
    "plant.lumped_preset": "model.preset",
    "plant.order": "model.fidelity (lumped4 | lumped12)",
    # [runtime] (SIL files) -> [simulation] and [realtime]
    "runtime": "[simulation] (dt, duration, record_dt) and [realtime] (paced, max_lag, "
               "ring_seconds, ring_memory_mib, chunk_dir, wait_fraction, enabled)",
    "runtime.dt": "simulation.dt",
    "runtime.duration": "simulation.duration",
    "runtime.record_dt": "simulation.record_dt",
    "runtime.paced": "realtime.paced",
    "runtime.ring_seconds": "realtime.ring_seconds",
    "runtime.chunk_dir": "realtime.chunk_dir",
    "runtime.max_lag": "realtime.max_lag",
    "runtime.wait_fraction": "realtime.wait_fraction",
    "runtime.realtime": "realtime.enabled",
    # [reference] (SIL and DHP files)
    "reference.axial": "reference.axial_velocity",
    "reference.angular": "reference.angular_velocity",
    "reference.axial_min": "reference.axial_velocity_min",
    "reference.axial_max": "reference.axial_velocity_max",
    "reference.angular_min": "reference.angular_velocity_min",
    "reference.angular_max": "reference.angular_velocity_max",
    # [simulation.noise] (neutral files)
    "simulation.noise.axial": "simulation.noise.axial_velocity",
    "simulation.noise.angular": "simulation.noise.angular_velocity",
    # [controller.dhp] (SIL files)
    "controller.dhp.reference": "reference.type",
    "controller.dhp.horizon": "controller.dhp.training.horizon",
    "controller.dhp.samples": "controller.dhp.training.n_samples",
    # ---------------------------------------------------------------- DHP files (design dhp)
    "weights": "[controller.dhp.weights] (DHP files; or weights = \"<named set>\" there) or "
               "[optimize.weights] (DP files)",
    "training": "[controller.dhp.training]",
    "plan": "[controller.dhp.plan]",
    "model.kind": "controller.dhp.design (fem24 | fem | lumped)",
    "model.n_elements": "controller.dhp.elements",
    "model.dt": "controller.dhp.dt (DHP files) or simulation.dt",
    "model.input_limits": "controller.dhp.input_limits",
    "model.epsilon": "bit.epsilon",
    "simulation.plant": "[model] fidelity (fem | hybrid | lumped4) and preset (fem24 | hybrid68 "
                        "| a lumped preset | design): the plant simulated",
    "reference.axial_values": "reference.axial_velocity_values",
    "reference.angular_values": "reference.angular_velocity_values",
    # ---------------------------------------------------------------- DP files (optimize dp)
    "dp": "[optimize] (the DP problem)",
    "horizon": "optimize.horizon",
    "step": "optimize.step",
    "x1_regions": "optimize.x1_regions",
    "x3_regions": "optimize.x3_regions",
    "x2": "[optimize.x2]",
    "x4": "[optimize.x4]",
    "targets": "[optimize.targets]",
    "bounds": "[optimize.bounds]",
    "robust": "[optimize.robust]",
    "standard": "[optimize.standard]",
    # ---------------------------------------------------------------- end of DHP / DP files
}


def _lookup(data: dict, dotted: str):
    node = data
    for p in dotted.split("."):
        if not isinstance(node, dict) or p not in node:
            return False, None
        node = node[p]
    return True, node


#: Older keys whose replacement depends on their value: (dotted key, value) -> replacement.
VALUE_RENAMES: dict[tuple[str, str], str] = {
    ("model.type", "dhp"): 'controller.type = "dhp" and the design in [controller.dhp]',
}


def check_dialect(data: dict, source: str) -> None:
    """Refuse older-dialect keys (one line naming the replacement), unknown top-level keys and
    implausible values (:func:`downhole.plausible.check_scenario`: a rotary speed, WOB, ROP,
    torque, diameter, mud density or length no rig sees, a string wider than the hole).

    Every loader calls this first, so every file gets the same refusals.

    Parameters
    ----------
    data : dict
        The parsed scenario file.
    source : str
        The file, for messages.

    Raises
    ------
    ScenarioError
        Naming the file, the dotted key and its replacement (or the known tables), or the
        implausible value, its range and the likely fix.
    """
    for dotted in sorted(RENAMES, key=lambda k: (-k.count("."), k)):
        found, value = _lookup(data, dotted)
        if not found or (dotted == "model.hybrid" and not isinstance(value, str)):
            continue
        new = VALUE_RENAMES.get((dotted, value), RENAMES[dotted]) if isinstance(value, str) \
            else RENAMES[dotted]
        raise ScenarioError(source, dotted, f"renamed: use {new} (see docs/scenarios.md)")
    for key in data:
        if key not in TABLES:
            raise ScenarioError(source, key, f"unknown table; a scenario has {', '.join(TABLES)}"
                                " (see docs/scenarios.md)")
    check_scenario(data, source)


def read_scenario(path: str | Path) -> tuple[dict, str, str]:
    """Read a scenario file: ``(data, source, text)``, with :func:`check_dialect` applied.

    Raises
    ------
    ScenarioError
        An unreadable or malformed file, or an older-dialect / unknown key.
    """
    data, source, text = read_toml(path)
    check_dialect(data, source)
    return data, source, text


def _loc(loc) -> str:
    """A pydantic error location as messages name fields: dotted keys, list positions 1-based
    in brackets (``("string", "segments", 1, "length")`` -> ``string.segments[2].length``)."""
    out = ""
    for p in loc:
        if isinstance(p, int):
            out += f"[{p + 1}]"
        elif not str(p).startswith("function-"):
            out += f".{p}" if out else str(p)
    return out


def raise_validation(source: str, exc, prefix: str = ""):
    """Raise the first error of a pydantic ``ValidationError`` as a :class:`ScenarioError`
    naming ``source``, the dotted field (``prefix`` + its location) and what was expected."""
    err = exc.errors()[0]
    field = prefix + _loc(err["loc"])
    msg = err["msg"]
    if err["type"] == "extra_forbidden":
        msg = "unknown key (check spelling; see docs/scenarios.md)"
    elif err["type"] == "missing":
        msg = "required field is missing"
    elif msg.startswith("Value error, "):
        msg = msg[len("Value error, "):]
    if "input" in err and err["type"] not in ("missing", "extra_forbidden") \
            and not isinstance(err["input"], (dict, list)):
        got = repr(err["input"])
        msg += f" (got {got[:80] + '...' if len(got) > 80 else got})"
    raise ScenarioError(source, field, msg) from None
