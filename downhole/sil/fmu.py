"""FMU export and import: a downhole plant as an FMI 2.0 co-simulation FMU (pythonfmu), for FMPy,
OpenModelica, Simulink and other FMI tools, and a closed loop that drives such an FMU with any
controller of the :class:`~downhole.control.base.Controller` contract.

:func:`export_fmu` builds the FMU of the plant of a scenario file: a SIL scenario's plant, a
scenario that describes the system at any of its fidelities (``lumped4``, ``lumped12``,
``neutral``, ``fem``, ``hybrid``), or a preset scenario that ``downhole simulate`` runs (lumped,
neutral, FEM or hybrid). The FMU carries data only: the scenario's text (``scenario.toml``), the
data files it names (a survey CSV) and ``fmu.json`` (the fidelity, the display units, the
downhole version that exported it); no pickle, no code but the slave of this package
(:mod:`downhole.sil.fmu_slave`). Every instance rebuilds its plant from that text with the
scenario loader, validated like any file (:func:`load_fmu_plant`).

Inputs: ``command_<name>`` for every command signal of the plant; outputs: every observation
signal, under its name in :mod:`downhole.signals` (the plant's simulated time as ``sim_time``:
no FMU variable is named ``time``), each with its SI unit and description; the default
experiment runs from 0 s to the scenario's duration at the plant's ``dt``. One ``doStep`` may
advance at most :data:`MAX_STEP_SECONDS` of simulated time and :data:`MAX_STEPS_PER_DO_STEP`
plant steps; a larger step is an FMI error, returned at once.

:func:`simulate_fmu` runs an FMU open loop with FMPy's high-level ``simulate_fmu``;
:func:`run_fmu_closed_loop` runs the closed loop through FMPy's low-level API (instantiate,
setupExperiment, enter/exitInitializationMode, setReal inputs, doStep, getReal outputs), calling
the controller's ``reset()`` and ``command(t, observation, reference)`` exactly as the offline
loop (:func:`~downhole.control.base.run_closed_loop`) and the SIL runtime do, so the three agree
(``tests/test_controller_matrix.py``).
"""

from __future__ import annotations

import json
import math
import re
import shutil
import tempfile
from collections import deque
from pathlib import Path, PurePosixPath

import numpy as np

from downhole.errors import DownholeInputError, ScenarioError
from downhole.sim.loop import run_loop
from downhole.sim.result import Result

__all__ = [
    "MAX_STEPS_PER_DO_STEP",
    "MAX_STEP_SECONDS",
    "export_fmu",
    "fmu_signals",
    "load_fmu_plant",
    "run_fmu_closed_loop",
    "scenario_plant",
    "simulate_fmu",
    "system_plant",
]

#: Prefix of the FMU input that carries command signal ``name``.
COMMAND_PREFIX = "command_"
#: FMU output that carries the plant's observation ``time`` (see :mod:`downhole.sil.fmu_slave`).
TIME_OUTPUT = "sim_time"
#: Most simulated time one ``doStep`` may advance, s: a larger communication step is an FMI
#: error naming this bound (it returns at once instead of running for hours).
MAX_STEP_SECONDS = 60.0
#: Most plant steps one ``doStep`` may take (60 s at dt = 0.6 ms; 10 s at the neutral model's
#: 0.1 ms): the other bound of a communication step.
MAX_STEPS_PER_DO_STEP = 100_000
#: Layout version of the FMU's ``resources/fmu.json``.
FMU_FORMAT = 1
#: The scenario text in the FMU's resources.
SCENARIO_FILE = "scenario.toml"
#: The FMU's settings in its resources: format, fidelity, options, downhole version.
META_FILE = "fmu.json"
#: Largest ``fmu.json`` read, bytes.
_MAX_META_BYTES = 64 * 1024
#: Tables and ``[model]`` keys only a SIL scenario has.
_SIL_TABLES = ("realtime", "link", "safety", "dashboard")


def _check_out(out) -> Path:
    out = Path(out)
    if out.suffix != ".fmu":
        raise DownholeInputError(f"--out must end in .fmu, got {out}")
    return out


def _display_option(units) -> dict | None:
    """The display unit system of ``units`` (a name, overrides or a
    :class:`~downhole.units.UnitSystem`) as the ``units`` option of ``fmu.json``; None for SI."""
    if units is None:
        return None
    from downhole.units import display_units

    system = display_units(units)  # DownholeInputError on a bad name or override
    if system.name == "si" and not system.overrides:
        return None
    return {"system": system.name, "overrides": dict(system.overrides)}


def _constant(value, source: str, field: str, command: str) -> float:
    """A constant set-point of the scenario (the start value of an FMU input); a time profile
    is refused: the importing tool drives the input."""
    if isinstance(value, tuple):
        raise ScenarioError(source, field, f"a time profile cannot be exported: the FMU input "
                            f"{COMMAND_PREFIX}{command} is driven by the importing tool; give a "
                            "constant (its start value)")
    return float(value)


def _settings(start: str, command: dict, duration: float) -> dict:
    command = {k: float(v) for k, v in command.items()}
    return {"start": start, "set_point": command, "command_start": command,
            "stop_time": float(duration)}


def _data_files(data: dict, source: str) -> list[str]:
    """The data files a scenario names that the FMU carries beside it (``well.survey``), as
    paths relative to the scenario's folder."""
    well = data.get("well")
    survey = well.get("survey") if isinstance(well, dict) else None
    if not isinstance(survey, str):
        return []
    rel = PurePosixPath(survey.replace("\\", "/"))
    if rel.is_absolute() or ".." in rel.parts or (len(survey) > 1 and survey[1] == ":") \
            or not rel.parts:
        raise ScenarioError(source, "well.survey", f"{survey!r}: an FMU carries the survey "
                            "beside the scenario; give a path relative to the scenario's folder, "
                            "without '..'")
    return [str(rel)]


def _fidelity_of_file(fid: str, fidelity: str | None, source: str) -> None:
    if fidelity is not None and fidelity != fid:
        raise ScenarioError(source, "--fidelity", f"--fidelity applies to a scenario that "
                            f"describes the system ([well], [string]); this file's plant is its "
                            f"[model] fidelity {fid!r}")


def _lumped_plant(data: dict, source: str, fidelity):
    from downhole.scenario import LUMPED_DEFAULTS, validate_lumped
    from downhole.string.fem import DirectionalPlant

    sc, model = validate_lumped(data, source)
    _fidelity_of_file(sc.model.fidelity, fidelity, source)
    sim, s = sc.simulation, sc.operation
    mode = s.mode or "velocity"
    if mode == "velocity":
        s = s.model_copy(update={k: LUMPED_DEFAULTS[k] for k in ("rop", "surface_speed")
                                 if getattr(s, k) is None})
    if not sim.rock_memory:
        raise ScenarioError(source, "simulation.rock_memory", "false is not supported by the "
                            "FMU plant (it keeps the rock-surface memory)")
    plant = DirectionalPlant(model, dt=sim.step(sc.model.fidelity), mode=mode,
                             depth_of_cut=sim.depth_of_cut, integrator=sim.integrator)
    names = plant.command_names
    fields = ("rop", "surface_speed") if mode == "velocity" else ("hook_load",
                                                                  "surface_torque")
    cmd = {n: _constant(getattr(s, f), source, f"operation.{f}", n)
           for n, f in zip(names, fields)}
    return plant, _settings(sim.start, cmd, sim.duration), sc.model.fidelity


def _neutral_plant(data: dict, source: str, fidelity):
    from downhole.scenario.neutral import OPEN_LOOP, validate_neutral_scenario
    from downhole.string.fem import DirectionalPlant

    sc, model = validate_neutral_scenario(data, source)
    _fidelity_of_file("neutral", fidelity, source)
    sim = sc.simulation
    noisy = [k for k, v in sim.noise.model_dump().items() if v > 0]
    if noisy:
        raise ScenarioError(source, f"simulation.noise.{noisy[0]}", "noise is not part of the "
                            "FMU plant; remove [simulation.noise] to export it")
    op = sc.operation
    ua = _constant(OPEN_LOOP["axial_command"] if op.axial_command is None else op.axial_command,
                   source, "operation.axial_command", "top_drive_axial_velocity")
    ut = _constant(OPEN_LOOP["surface_speed"] if op.surface_speed is None else op.surface_speed,
                   source, "operation.surface_speed", "top_drive_angular_velocity")
    plant = DirectionalPlant(model, dt=sim.step("neutral"), depth_of_cut=sim.depth_of_cut)
    # the plant's axial command is relative to the hanging equilibrium (U_A - M_S g / alpha_A)
    cmd = {"top_drive_axial_velocity": ua - model.hang_command,
           "top_drive_angular_velocity": ut}
    return plant, _settings(sim.start, cmd, sim.duration), "neutral"


def _directional_plant(data: dict, source: str, fidelity):
    from downhole.scenario.directional import _hook, _top_drive, validate_directional_scenario
    from downhole.string.fem import DirectionalPlant

    sc, params, model = validate_directional_scenario(data, source)
    fid = sc.model.fidelity
    _fidelity_of_file(fid, fidelity, source)
    if sc.controller.type == "dhp":
        raise ScenarioError(source, "controller.type", "'dhp' is not supported: the plant of a "
                            "saved DHP controller (torque-driven top drive, slack-off hook) is "
                            "exported from a SIL scenario with [model] interface = 'state'")
    op, sim = sc.operation, sc.simulation
    if op.surface_speed is not None:
        _constant(op.surface_speed, source, "operation.surface_speed",
                  "top_drive_angular_velocity")
    hook = _hook(sc)
    if hook.mode == "velocity" and op.rop is not None:
        _constant(op.rop, source, "operation.rop", "top_drive_axial_velocity")
    plant = DirectionalPlant(model, sim.step(fid), top_drive=_top_drive(sc, params), hook=hook,
                             depth_of_cut=sim.depth_of_cut)
    cmd = plant.default_command()
    if hook.mode == "force" and op.hook_load is not None:
        cmd["hook_load"] = _constant(op.hook_load, source, "operation.hook_load", "hook_load")
    return plant, _settings(sim.start, cmd, sim.duration), fid


def _system_plant(data: dict, source: str, fidelity):
    from downhole.scenario.system import DESCRIBED, steady_bit_state, validate_system_scenario

    sc, fid, system, model = validate_system_scenario(data, source, fidelity)
    sim, op = sc.simulation, sc.operation
    dt = sim.step(fid)
    speed = DESCRIBED["surface_speed"] if op.surface_speed is None else op.surface_speed
    rop, _, _ = steady_bit_state(system.bit, speed, op.rop, op.wob)
    plant = system_plant(system, model, fid, dt, surface_speed=speed, rop=rop,
                         depth_of_cut=sim.depth_of_cut, integrator=sim.integrator)
    # the same commands at every fidelity: the block velocity and the PI's set-point
    cmd = {"top_drive_axial_velocity": rop, "top_drive_angular_velocity": speed}
    return plant, _settings(sim.start, cmd, sim.duration), fid


def _sil_plant(data: dict, source: str, fidelity):
    from downhole.sil.scenario import build_from_scenario, parse_sil_scenario

    sc = parse_sil_scenario(data, source)
    if fidelity is not None and fidelity != sc.model.fidelity:
        raise ScenarioError(source, "--fidelity", "--fidelity applies to a scenario that "
                            "describes the system ([well], [string]); a SIL scenario's plant is "
                            "its [model] fidelity and preset")
    if sc.link.mode == "hil":
        raise ScenarioError(source, "link.mode", "'hil' is not supported: the HIL plant takes "
                            "the rig's bit velocities over the link; an FMU plant has no link")
    plant, _ = build_from_scenario(sc, with_controller=False)
    start = dict(getattr(plant, "default_start", None) or {"start": "rest", "set_point": None})
    return plant, {"start": start["start"], "set_point": start["set_point"],
                   "command_start": {}, "stop_time": float(sc.simulation.duration)}, \
        sc.model.fidelity


def _is_sil(data: dict) -> bool:
    model = data.get("model")
    return any(t in data for t in _SIL_TABLES) or (isinstance(model, dict)
                                                   and "interface" in model)


def _build_plant(data: dict, source: str, fidelity: str | None):
    """``(plant, settings, fidelity)`` of a parsed scenario (see :func:`scenario_plant`)."""
    from downhole.scenario import _load_plugins, is_lumped_type, model_type

    if _is_sil(data):
        return _sil_plant(data, source, fidelity)
    try:
        mtype = model_type(data, source)
        if mtype == "system":
            return _system_plant(data, source, fidelity)
        if mtype == "dhp":
            raise ScenarioError(source, "controller.type", "a DHP design scenario trains a "
                                "controller: it has no plant to export (export a SIL scenario "
                                "with [model] interface = 'state')")
        if is_lumped_type(mtype):
            return _lumped_plant(data, source, fidelity)
        if mtype == "neutral":
            return _neutral_plant(data, source, fidelity)
        if mtype in ("fem", "hybrid"):
            return _directional_plant(data, source, fidelity)
        _load_plugins()
        raise ScenarioError(source, "model.fidelity", f"{mtype!r} is a plug-in model type; "
                            "only the built-in plants can be exported as an FMU")
    except ScenarioError as exc:
        if exc.field in ("--fidelity", "controller.type", "simulation.rock_memory",
                         "link.mode") \
                or exc.field.startswith(("simulation.noise", "operation.", "well.survey")):
            raise
        try:  # a SIL scenario without a SIL-only table ([model], [operation], [simulation])
            return _sil_plant(data, source, fidelity)
        except ScenarioError:
            raise exc from None


def _scenario_plant(path: Path, fidelity: str | None):
    """``(plant, settings, info)``: :func:`scenario_plant` and ``info`` = ``{"text", "source",
    "fidelity", "data_files"}``."""
    from downhole.scenario.schema import read_scenario

    data, source, text = read_scenario(path)
    files = _data_files(data, source)
    try:
        plant, settings, fid = _build_plant(data, source, fidelity)
    except ScenarioError:
        raise
    except DownholeInputError as exc:
        raise ScenarioError(source, "model", str(exc)) from None
    from downhole.signals import check_command_value

    for name, value in settings["command_start"].items():
        why = check_command_value(name, value)
        if why is not None:
            raise ScenarioError(source, "operation", f"start value of the FMU input "
                                f"{COMMAND_PREFIX}{name}: {why}")
    try:  # the slave resets the plant like this when it leaves initialization mode
        plant.reset(start=settings["start"], set_point=settings["set_point"])
    except DownholeInputError as exc:
        raise ScenarioError(source, "simulation.start", str(exc)) from None
    return plant, settings, {"text": text, "source": source, "fidelity": fid,
                             "data_files": files}


def scenario_plant(scenario, fidelity: str | None = None):
    """The plant an FMU of ``scenario`` runs, and how it starts.

    The scenario is read and validated as ``downhole simulate`` and ``downhole sil`` read it;
    the plant is built at ``fidelity``: a SIL scenario's plant
    (:func:`~downhole.sil.scenario.build_from_scenario`); a system scenario at any fidelity
    (:func:`system_plant`, velocity-driven); a lumped, neutral, FEM or hybrid preset scenario
    at its own fidelity, with the scenario's rig, step, depth-of-cut model and integrator. The
    ``[operation]`` set-points are the start values of the inputs (a time profile is refused:
    the importing tool drives the inputs); ``[controller]``, ``[reference]`` and the run's
    recording settings are not part of the plant.

    Parameters
    ----------
    scenario : str or os.PathLike
        Scenario TOML file.
    fidelity : str, optional
        Fidelity of a system scenario (default: its ``[model] fidelity``); for other files only
        their own fidelity is accepted.

    Returns
    -------
    (Plant, dict)
        The plant (reset as the FMU starts it) and its settings: ``start``, ``set_point`` (of
        ``plant.reset``), ``command_start`` (start values of the inputs) and ``stop_time``
        (the scenario's duration, s).

    Raises
    ------
    ScenarioError
        One line naming the file and the field: an invalid scenario, or what the FMU plant does
        not support (a DHP design or saved DHP controller, a time profile, noise, a survey
        outside the scenario's folder, a fidelity the file cannot represent).
    """
    plant, settings, _ = _scenario_plant(Path(scenario), fidelity)
    return plant, settings


def _version(text: str) -> tuple:
    return tuple(int(x) for x in re.findall(r"\d+", text)[:3])


def _read_meta(path: Path) -> dict:
    """``fmu.json``, checked: ``format``, ``fidelity``, ``options`` and ``downhole_version``."""
    import downhole
    from downhole._reader import read_regular_file
    from downhole.scenario.system import FIDELITY_NAMES

    try:
        meta = json.loads(read_regular_file(path, _MAX_META_BYTES, "the FMU's settings (JSON)"))
    except (ValueError, UnicodeDecodeError) as exc:
        raise DownholeInputError(f"{path}: not valid JSON ({exc})") from None
    keys = {"format", "fidelity", "options", "downhole_version", "source"}
    if not isinstance(meta, dict) or set(meta) != keys:
        raise DownholeInputError(f"{path}: expected the keys {sorted(keys)}")
    if meta["format"] != FMU_FORMAT:
        raise DownholeInputError(f"{path}: format {meta['format']!r}; this downhole reads "
                                 f"format {FMU_FORMAT}")
    if meta["fidelity"] not in FIDELITY_NAMES:
        raise DownholeInputError(f"{path}: fidelity {meta['fidelity']!r} is not one of "
                                 f"{', '.join(FIDELITY_NAMES)}")
    options = meta["options"]
    if not isinstance(options, dict) or set(options) - {"units"}:
        raise DownholeInputError(f"{path}: options must be a table with at most 'units'")
    units = options.get("units")
    if units is not None and not (isinstance(units, dict) and isinstance(units.get("system"), str)
                                  and isinstance(units.get("overrides", {}), dict)):
        raise DownholeInputError(f"{path}: options.units must be {{'system': name, 'overrides': "
                                 "{...}}")
    need = meta["downhole_version"]
    if not isinstance(need, str) or not _version(need):
        raise DownholeInputError(f"{path}: downhole_version must be a version string")
    if _version(downhole.__version__) < _version(need):
        raise DownholeInputError(f"this FMU was exported by downhole {need}; the installed "
                                 f"downhole {downhole.__version__} is older: install downhole "
                                 f">= {need}")
    return meta


def load_fmu_plant(resources):
    """Rebuild the plant of an FMU from its resources (what every FMU instance does).

    Reads ``fmu.json`` (format, fidelity, options, the downhole version that exported it: the
    installed one must not be older) and rebuilds the plant from ``scenario.toml`` at that
    fidelity with :func:`scenario_plant`, so a tampered or hand-edited scenario is validated
    like any file and refused with its one-line message.

    Parameters
    ----------
    resources : str or os.PathLike
        The FMU's ``resources`` folder.

    Returns
    -------
    (Plant, dict, UnitSystem or None)
        The plant, its settings (see :func:`scenario_plant`) and the display unit system of
        the variables (None: SI).

    Raises
    ------
    DownholeInputError
        A missing or invalid ``fmu.json``, a downhole older than the exporter's;
        :class:`~downhole.errors.ScenarioError` for an invalid scenario.
    """
    resources = Path(resources)
    meta = _read_meta(resources / META_FILE)
    plant, settings, _ = _scenario_plant(resources / SCENARIO_FILE, meta["fidelity"])
    units = meta["options"].get("units")
    system = None
    if units is not None:
        from downhole.units import display_units

        system = display_units(units["system"], units.get("overrides") or {})
    return plant, settings, system


def _build(out: Path, info: dict, scenario: Path, units) -> Path:
    """Build the FMU ``out`` from :mod:`downhole.sil.fmu_slave`, the scenario's text, its data
    files and ``fmu.json``."""
    from pythonfmu.builder import FmuBuilder

    import downhole
    from downhole._atomic import atomic_path

    options = {}
    display = _display_option(units)
    if display is not None:
        options["units"] = display
    meta = {"format": FMU_FORMAT, "fidelity": info["fidelity"], "options": options,
            "downhole_version": downhole.__version__, "source": Path(info["source"]).name}
    out.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="downhole_fmu_") as tmp:
        tmp = Path(tmp)
        script = tmp / "DownholePlant.py"
        shutil.copy2(Path(__file__).with_name("fmu_slave.py"), script)
        res = tmp / "resources"
        res.mkdir()
        (res / SCENARIO_FILE).write_text(info["text"], encoding="utf-8")
        (res / META_FILE).write_text(json.dumps(meta, indent=1))
        files = [res / SCENARIO_FILE, res / META_FILE]
        for rel in info["data_files"]:
            dest = res / rel
            dest.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(scenario.parent / rel, dest)
            files.append(res / PurePosixPath(rel).parts[0])
        built = FmuBuilder.build_FMU(script, dest=tmp / "out", project_files=sorted(set(files)))
        with atomic_path(out) as part:  # the build is in /tmp: copy, fsync, rename
            shutil.copyfile(built, part)
    return out


def export_fmu(scenario, out="plant.fmu", *, fidelity: str | None = None, units=None) -> Path:
    """Build ``out`` (an ``.fmu``) of the plant of a scenario file.

    The scenario is validated and its plant built first (:func:`scenario_plant`), so an
    unsupported file fails here with one line, not inside the FMU. The FMU carries the
    scenario's text, the data files it names (a survey CSV), the fidelity and the options
    (display units) as JSON, and the downhole version that exported it; no pickle and no code
    but the package's FMU slave. Every instance rebuilds the plant with the installed downhole
    (:func:`load_fmu_plant`).

    Parameters
    ----------
    scenario : str or os.PathLike
        A SIL scenario, a scenario that describes the system ([well], [string]) or a lumped,
        neutral, FEM or hybrid preset scenario (``downhole simulate``).
    out : str or os.PathLike, optional
        FMU file to write (default ``"plant.fmu"``, atomically); must end in ``.fmu``.
    fidelity : str, optional
        Fidelity of a system scenario (``lumped4``, ``lumped12``, ``neutral``, ``fem``,
        ``hybrid``; default its ``[model] fidelity``).
    units : str or UnitSystem, optional
        Display unit system of the FMU's variables (FMI 2.0 ``DisplayUnit``, e.g.
        ``"oilfield"``, ``docs/units.md``); the values an importer exchanges stay SI.

    Returns
    -------
    pathlib.Path
        The FMU written.

    Raises
    ------
    ScenarioError
        Invalid scenario, or what the FMU plant does not support (:func:`scenario_plant`).
    DownholeInputError
        ``out`` does not end in ``.fmu``; a bad display unit system.
    """
    scenario = Path(scenario)
    out = _check_out(out)
    _display_option(units)
    _, _, info = _scenario_plant(scenario, fidelity)
    return _build(out, info, scenario, units)


def system_plant(system, model, fidelity: str, dt: float, *, surface_speed: float = 10.0,
                 rop: float = 0.0, depth_of_cut: str = "delayed", integrator: str = "newmark"):
    """The velocity-driven plant of ``model`` that :func:`export_fmu` wraps for a system scenario.

    Commands ``top_drive_axial_velocity`` (m/s) and ``top_drive_angular_velocity`` (rad/s) at
    every fidelity: :class:`~downhole.string.fem.DirectionalPlant` with the rig's PI top drive
    (``surface_speed`` its default set-point) and a velocity-servo hook (block velocity ``rop``)
    on the model's top node (a lumped chain and the neutral line run under the rig's node).

    Parameters
    ----------
    system : DrillingSystem
        The described system (its rig's top drive and hook are used for ``fem`` / ``hybrid``).
    model : object
        ``system.build(fidelity)``.
    fidelity : str
        ``"lumped4"``, ``"lumped12"``, ``"neutral"``, ``"fem"`` or ``"hybrid"``.
    dt : float
        Plant step, s.
    surface_speed : float, optional
        Top-drive speed set-point of the PI drive, rad/s (default 10; fem/hybrid only).
    rop : float, optional
        Hook block velocity, m/s (default 0; fem/hybrid only).
    depth_of_cut : {"delayed", "approximate"}, optional
        Depth-of-cut model (default ``"delayed"``).
    integrator : {"newmark"}, optional
        The rig's node steps with Newmark (the only choice; kept for callers).

    Returns
    -------
    Plant
        A plant of the :class:`~downhole.sim.plant.Plant` contract.
    """
    import dataclasses

    from downhole.params.rig import Hook
    from downhole.string.fem import DirectionalPlant

    top = dataclasses.replace(system.rig.top_drive, mode="pi", speed=surface_speed)
    h = system.rig.hook
    hook = Hook(mode="velocity", velocity=rop, block_mass=h.block_mass,
                servo_stiffness=h.servo_stiffness, servo_damping=h.servo_damping)
    return DirectionalPlant(model, dt, top_drive=top, hook=hook, depth_of_cut=depth_of_cut)




def simulate_fmu(fmu, stop_time: float, step_size: float, start_values: dict | None = None
                 ) -> Result:
    """Run ``fmu`` open loop with FMPy (co-simulation) and return the outputs as a Result.

    Parameters
    ----------
    fmu : str or os.PathLike
        FMI 2.0 co-simulation FMU.
    stop_time : float
        Simulated time, s.
    step_size : float
        Output interval (communication step), s.
    start_values : dict, optional
        Variable name -> start value (e.g. ``command_<name>`` inputs, SI).

    Returns
    -------
    Result
        The FMU's outputs over time (attrs ``runner``, ``fmu`` and exported constants such as
        ``bit_radius``).

    Notes
    -----
    FMPy's own errors pass through (e.g. for a missing or invalid FMU).
    """
    import fmpy

    rec = fmpy.simulate_fmu(str(fmu), stop_time=stop_time, output_interval=step_size,
                            start_values=start_values or {}, fmi_type="CoSimulation")
    names = [n for n in rec.dtype.names if n not in ("time", TIME_OUTPUT)]
    attrs = {"runner": "fmpy", "fmu": str(fmu)}
    attrs.update(_constants(_model_description(Path(fmu))))
    return Result(np.asarray(rec["time"]), {n: np.asarray(rec[n], float) for n in names},
                  attrs=attrs)


def _constants(md) -> dict:
    """The FMU's exported constants that Results keep as attributes (``bit_radius``)."""
    out = {}
    for v in md.modelVariables:
        if v.name == "bit_radius" and v.variability == "constant" and v.start is not None:
            out["bit_radius"] = float(v.start)
    return out


def _model_description(fmu: Path):
    import fmpy

    if not fmu.is_file():
        raise DownholeInputError(f"{fmu}: no such FMU file")
    try:
        md = fmpy.read_model_description(str(fmu))
    except Exception as exc:
        raise DownholeInputError(f"{fmu}: not a readable FMU ({exc})") from None
    if md.fmiVersion != "2.0" or md.coSimulation is None:
        raise DownholeInputError(f"{fmu}: expected an FMI 2.0 co-simulation FMU, got FMI "
                                 f"{md.fmiVersion} without co-simulation"
                                 if md.coSimulation is None else
                                 f"{fmu}: expected FMI 2.0, got FMI {md.fmiVersion}")
    return md


def fmu_signals(fmu) -> dict:
    """The signals an FMU exchanges.

    Parameters
    ----------
    fmu : str or os.PathLike
        FMU file.

    Returns
    -------
    dict
        ``{"commands": {name: start}, "observations": [names], "step_size": default step (s)
        or None}``; commands are the inputs ``command_<name>`` without the prefix.

    Raises
    ------
    DownholeInputError
        Not a readable FMI 2.0 co-simulation FMU.
    """
    return _signals(_model_description(Path(fmu)))


def _signals(md, with_inputs: bool = False) -> dict:
    commands, observations, inputs = {}, [], {}
    for v in md.modelVariables:
        if v.type != "Real":
            continue
        if v.causality == "input":
            name = v.name.removeprefix(COMMAND_PREFIX)
            commands[name] = float(v.start) if v.start is not None else 0.0
            inputs[name] = v.valueReference
        elif v.causality == "output":
            observations.append(v.name)
    de = md.defaultExperiment
    step = float(de.stepSize) if de is not None and de.stepSize is not None else None
    out = {"commands": commands, "observations": observations, "step_size": step}
    if with_inputs:
        out["input_references"] = inputs
    return out


class _Log:
    """FMI logger callback that keeps the FMU's last messages (for the error that names them)."""

    def __init__(self):
        self.messages: deque[str] = deque(maxlen=16)

    def __call__(self, env, instance, status, category, message):
        self.messages.append(message.decode("utf-8", "replace") if isinstance(message, bytes)
                             else str(message))

    def last_line(self) -> str:
        """The last line of the last message (pythonfmu puts the exception there)."""
        for m in reversed(self.messages):
            lines = [ln.strip() for ln in m.splitlines() if ln.strip()]
            if lines:
                return lines[-1]
        return ""


def run_fmu_closed_loop(fmu, controller, duration: float, *, dt: float | None = None,
                        reference=None, record_every: int = 1) -> Result:
    """Run ``controller`` in closed loop on the plant FMU ``fmu`` (FMPy's low-level API).

    Every communication step the loop reads the FMU's outputs as the observation (plus
    ``time``), calls ``controller.command(t, observation, reference(t))``, sets the returned
    commands on the inputs ``command_<name>`` (commands the controller does not set keep the
    FMU's start value, the plant's default command) and calls ``doStep(t, dt)``. This is the
    loop of :func:`~downhole.control.base.run_closed_loop`: with ``dt`` the plant's step the
    two give the same trajectory.

    Parameters
    ----------
    fmu : path
        An FMU written by :func:`export_fmu` (or any FMI 2.0 co-simulation FMU with the same
        signal names).
    controller : Controller
        Any object with ``reset()`` and ``command(t, observation, reference)``; its ``needs``
        and ``commands`` are checked against the FMU's outputs and inputs first. A discrete-time
        controller (``dt`` not None) gets ``dt`` set to the communication step before ``reset``.
    duration : float
        Simulated time, s (rounded to a whole number of communication steps).
    dt : float, optional
        Communication step, s (default: the FMU's default step size, the plant's ``dt``).
    reference : mapping or callable, optional
        Reference signals, constant (mapping) or ``reference(t) -> mapping``.
    record_every : int
        Keep every ``record_every``-th step (the last step is always kept).

    Returns
    -------
    Result
        The observations and the held commands (``command_<name>``) at every recorded step,
        attrs ``runner = "fmu"``, ``fmu``, ``dt``.

    Raises
    ------
    DownholeInputError
        No such file, not an FMI 2.0 co-simulation FMU; the controller needs a signal the FMU
        does not output or sets a command it does not take (named); a bad duration or step; a
        command that is not finite or out of its admissible range (named, with the time); an
        FMU that fails to instantiate (e.g. an invalid scenario in it) or a step it rejects
        (e.g. above :data:`MAX_STEP_SECONDS`), with the FMU's log message.
    """
    from ctypes import byref

    import fmpy
    from fmpy.fmi2 import (
        FMU2Slave,
        fmi2CallbackAllocateMemoryTYPE,
        fmi2CallbackFreeMemoryTYPE,
        fmi2CallbackFunctions,
        fmi2CallbackLoggerTYPE,
    )

    from downhole.signals import check_command_value

    fmu = Path(fmu)
    md = _model_description(fmu)
    sig = _signals(md, with_inputs=True)
    observed, taken = sig["observations"], sig["commands"]
    cname = type(controller).__name__
    needs = tuple(getattr(controller, "needs", None) or ())
    missing = [n for n in needs if n not in observed and n not in ("time", TIME_OUTPUT)]
    if missing:
        raise DownholeInputError(f"{cname} needs {missing}, which the FMU {fmu.name} does not "
                                 f"output (outputs: {observed})")
    extra = [n for n in tuple(getattr(controller, "commands", None) or ()) if n not in taken]
    if extra:
        raise DownholeInputError(f"{cname} sets {extra}; the FMU {fmu.name} takes "
                                 f"{sorted(taken)} (inputs {COMMAND_PREFIX}<name>)")
    if dt is None:
        dt = sig["step_size"]
        if dt is None:
            raise DownholeInputError(f"{fmu.name} declares no default step size: give dt")
    for what, v in (("duration", duration), ("dt", dt)):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) \
                or v <= 0:
            raise DownholeInputError(f"{what} must be a positive number of seconds, got {v!r}")
    if dt > duration:
        raise DownholeInputError(f"dt = {dt:g} s exceeds the duration {duration:g} s")
    if isinstance(record_every, bool) or not isinstance(record_every, int) or record_every < 1:
        raise DownholeInputError(f"record_every must be a positive integer, got "
                                 f"{record_every!r}")
    n = round(duration / dt)
    ref_fn = reference if callable(reference) else (lambda t, r=dict(reference or {}): r)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    out_vr = [vr[n_] for n_ in observed]
    obs_keys = ["time" if n_ == TIME_OUTPUT else n_ for n_ in observed]  # the plant's names
    in_names = list(taken)
    in_vr = [sig["input_references"][c] for c in in_names]
    held = dict(taken)

    log = _Log()
    callbacks = fmi2CallbackFunctions()
    callbacks.logger = fmi2CallbackLoggerTYPE(log)
    callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(fmpy.calloc)
    callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(fmpy.free)
    from fmpy.logging import addLoggerProxy  # the logger is variadic in C

    addLoggerProxy(byref(callbacks))

    unzip = fmpy.extract(str(fmu))
    slave = FMU2Slave(guid=md.guid, unzipDirectory=unzip,
                      modelIdentifier=md.coSimulation.modelIdentifier,
                      instanceName="downhole_closed_loop")
    keep = sorted(set(range(0, n + 1, record_every)) | {n})
    rows = np.empty((len(keep), len(observed)))
    cmds = np.empty((len(keep), len(in_names)))
    instantiated = False
    try:
        try:
            slave.instantiate(callbacks=callbacks, loggingOn=True)
        except Exception as exc:
            said = log.last_line() or str(exc)
            raise DownholeInputError(f"the FMU {fmu.name} failed to instantiate: {said}") \
                from None
        instantiated = True
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        if getattr(controller, "dt", None) is not None:
            controller.dt = float(dt)  # the control step of this loop: every communication step
        controller.reset()
        keep_at = {k: j for j, k in enumerate(keep)}
        clock = {"k": 0}

        def observe():
            obs = dict(zip(obs_keys, slave.getReal(out_vr)))
            obs.setdefault("time", clock["k"] * dt)
            return obs

        def write(out, seen, h):
            unknown = [c for c in out if c not in h]
            if unknown:
                raise DownholeInputError(f"{cname} at t = {seen['time']:g} s sets {unknown}; the "
                                         f"FMU {fmu.name} takes {sorted(taken)}")
            h.update(out)

        def on_sample(k, obs, h):
            j = keep_at.get(k)
            if j is not None:
                rows[j] = [obs[c] for c in obs_keys]
                cmds[j] = [h[c] for c in in_names]

        def step(h):
            t = clock["k"] * dt
            for c in in_names:
                why = check_command_value(c, h[c])
                if why is not None:
                    raise DownholeInputError(f"{cname} at t = {t:g} s: {why}; not applied to "
                                             f"the FMU")
            slave.setReal(in_vr, [float(h[c]) for c in in_names])
            try:
                slave.doStep(currentCommunicationPoint=t, communicationStepSize=dt)
            except Exception as exc:
                said = "; ".join(" ".join(m.split()) for m in list(log.messages)[-3:]) \
                    or str(exc)
                raise DownholeInputError(f"the FMU {fmu.name} rejected the step at t = {t:g} s "
                                         f"(dt = {dt:g} s): {said}") from None
            clock["k"] += 1
            return observe()

        run_loop(step, controller, observe(), n, dt, held=held, write=write,
                 reference=lambda k, t: ref_fn(t), on_sample=on_sample)
        slave.terminate()
    finally:
        if instantiated:
            slave.freeInstance()
        shutil.rmtree(unzip, ignore_errors=True)
    channels = {c: rows[:, i] for i, c in enumerate(obs_keys) if c != "time"}
    channels.update({COMMAND_PREFIX + c: cmds[:, i] for i, c in enumerate(in_names)})
    attrs = {"runner": "fmu", "fmu": str(fmu), "dt": float(dt)}
    attrs.update(_constants(md))
    return Result(np.asarray(keep, float) * dt, channels, attrs=attrs)
