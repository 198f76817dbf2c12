"""FMU export and import: a downhole plant as an FMI 2.0 co-simulation FMU (pythonfmu), for FMPy,
OpenModelica, Simulink and other FMI tools, and a closed loop that drives such an FMU with any
controller of the :class:`~downhole.control.base.Controller` contract.

:func:`export_fmu` builds the FMU of a SIL scenario's plant; :func:`export_plant_fmu` the FMU of
any plant object of the :class:`~downhole.sim.plant.Plant` contract, so every fidelity of one
:class:`~downhole.system.DrillingSystem` (``lumped4``, ``lumped12``, ``neutral``, ``fem``,
``hybrid``) can be exported. Inputs: ``command_<name>`` for every command signal of the plant;
outputs: every observation signal, under its name in :mod:`downhole.signals` (the plant's
simulated time as ``sim_time``: no FMU variable is named ``time``), each with its SI unit and
description; the default experiment runs from 0 s to the scenario's duration at the plant's
``dt``.

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
import pickle
import shutil
import tempfile
from collections import deque
from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np

from downhole.errors import DownholeInputError
from downhole.sim.result import Result

__all__ = [
    "export_fmu",
    "export_plant_fmu",
    "export_system_fmu",
    "fmu_signals",
    "run_fmu_closed_loop",
    "simulate_fmu",
    "system_plant",
]

#: Prefix of the FMU input that carries command signal ``name``.
COMMAND_PREFIX = "command_"
#: FMU output that carries the plant's observation ``time`` (see :mod:`downhole.sil.fmu_slave`).
TIME_OUTPUT = "sim_time"


def _check_out(out) -> Path:
    out = Path(out)
    if out.suffix != ".fmu":
        raise DownholeInputError(f"--out must end in .fmu, got {out}")
    return out


def _display_json(units) -> str | None:
    """The display unit system of ``units`` (a name, overrides or a
    :class:`~downhole.units.UnitSystem`) as the FMU's ``display.json``; None for SI."""
    if units is None:
        return None
    from downhole.units import display_units

    system = display_units(units)  # DownholeInputError on a bad name or override
    if system.name == "si" and not system.overrides:
        return None
    return json.dumps({"system": system.name, "overrides": dict(system.overrides)})


def _build(out: Path, resources: Callable[[Path], list], units=None) -> Path:
    """Build the FMU ``out`` from :mod:`downhole.sil.fmu_slave` and the resource files that
    ``resources(tmp)`` writes into ``tmp`` (their paths); ``units``: the display unit system of
    the variables (FMI ``DisplayUnit``, the values stay SI)."""
    from pythonfmu.builder import FmuBuilder

    from downhole._atomic import atomic_path

    display = _display_json(units)
    out.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="downhole_fmu_") as tmp:
        tmp = Path(tmp)
        script = tmp / "DownholePlant.py"
        shutil.copy2(Path(__file__).with_name("fmu_slave.py"), script)
        res = tmp / "resources"
        res.mkdir()
        files = resources(res)
        if display is not None:
            (res / "display.json").write_text(display)
            files.append(res / "display.json")
        built = FmuBuilder.build_FMU(script, dest=tmp / "out", project_files=files)
        with atomic_path(out) as part:  # the build is in /tmp: copy, fsync, rename
            shutil.copyfile(built, part)
    return out


def export_fmu(scenario, out="plant.fmu", *, units=None) -> Path:
    """Build ``out`` (an ``.fmu``) from a SIL scenario file (validated first).

    The plant is the scenario's ``[plant]`` (``model`` selects the fidelity: ``lumped`` with
    ``order = 4 | 12``, ``fem``, ``hybrid24 | hybrid68 | hybrid108``); for a plant built in
    Python (e.g. any fidelity of a :class:`~downhole.system.DrillingSystem`) use
    :func:`export_plant_fmu`.

    Parameters
    ----------
    scenario : str or os.PathLike
        SIL scenario TOML file (copied into the FMU's resources).
    out : str or os.PathLike, optional
        FMU file to write (default ``"plant.fmu"``); must end in ``.fmu``.
    units : str or UnitSystem, optional
        Display unit system of the FMU's variables (``"oilfield"``, ``docs/units.md``); values
        stay SI.

    Returns
    -------
    pathlib.Path
        The FMU written.

    Raises
    ------
    ScenarioError
        Invalid scenario.
    DownholeInputError
        ``out`` does not end in ``.fmu``.
    """
    from downhole.sil.scenario import build_from_scenario, load_sil_scenario

    scenario = Path(scenario)
    out = _check_out(out)
    sc = load_sil_scenario(scenario)
    build_from_scenario(sc, with_controller=False)  # fail here, not inside the FMU

    def resources(res: Path) -> list:
        shutil.copy2(scenario, res / "scenario.toml")
        return [res / "scenario.toml"]

    return _build(out, resources, units)


def _check_plant(plant) -> None:
    missing = [a for a in ("command_names", "observation_names", "dt", "default_command",
                           "reset", "step") if not hasattr(plant, a)]
    if missing:
        raise DownholeInputError(f"{type(plant).__name__} is not a plant of the Plant contract "
                                 f"(downhole.sim.plant.Plant): it lacks {missing}")
    if not plant.command_names or not plant.observation_names:
        raise DownholeInputError(f"{type(plant).__name__} declares no command or no "
                                 "observation signals; an FMU needs both")
    clash = [n for n in plant.observation_names if n.startswith(COMMAND_PREFIX)
             and n[len(COMMAND_PREFIX):] in plant.command_names]
    if clash:
        raise DownholeInputError(f"observations {clash} would clash with the FMU inputs "
                                 f"{COMMAND_PREFIX}<command>")


def export_plant_fmu(plant, out="plant.fmu", *, start: str = "rest",
                     set_point: Mapping[str, float] | None = None,
                     command_start: Mapping[str, float] | None = None,
                     stop_time: float = 10.0, units=None) -> Path:
    """Build ``out`` (an ``.fmu``) wrapping ``plant``, a plant of the Plant contract.

    The plant is pickled into the FMU's resources as it is now (model, step ``dt``, options such
    as the integrator or the hook mode); every FMU instance unpickles its own copy and starts
    with ``plant.reset(start=start, set_point=set_point)`` when it leaves initialization mode.
    The FMU runs in a Python environment with the same downhole version. A plant that holds
    local functions (the DHP ``state`` interface's design model) cannot be pickled: export its
    SIL scenario with :func:`export_fmu` instead.

    Parameters
    ----------
    plant : downhole.sim.plant.Plant
        E.g. ``DirectionalPlant(system.build("lumped4"), dt=5e-4)`` (any
        :class:`~downhole.string.fem.DirectionalPlant`: lumped, neutral, FEM or hybrid).
    out : path
        The ``.fmu`` file to write (atomically).
    start : {"rest", "off_bottom", "steady"}
        How every run of the FMU starts (:data:`downhole.sim.plant.START_MODES`).
    set_point : mapping, optional
        Set-point of the start (default: the plant's default command).
    command_start : mapping, optional
        Start values of the inputs ``command_<name>`` (default: the plant's default command);
        the command an importing tool applies until it sets the inputs.
    stop_time : float
        Stop time of the FMU's default experiment, s (start 0, step the plant's ``dt``).
    units : str or UnitSystem, optional
        Display units of the variables (FMI 2.0 ``DisplayUnit`` and ``displayUnit``, e.g.
        ``"oilfield"``: rpm, klbf, kft*lbf, ft/h); the values an importer exchanges stay SI.

    Returns
    -------
    Path
        ``out``.

    Raises
    ------
    DownholeInputError
        ``out`` does not end in ``.fmu``; ``plant`` is not a plant of the contract, cannot be
        pickled, or cannot start as asked (the plant's reason); a ``command_start`` entry
        that is not a command of the plant or not admissible.
    """
    import downhole
    from downhole.signals import check_command_value
    from downhole.sim.plant import check_start

    out = _check_out(out)
    _check_plant(plant)
    check_start(start)
    set_point = None if set_point is None else {str(k): float(v) for k, v in set_point.items()}
    command_start = dict(command_start or {})
    unknown = [k for k in command_start if k not in plant.command_names]
    if unknown:
        raise DownholeInputError(f"command_start names {unknown}; {type(plant).__name__} takes "
                                 f"{list(plant.command_names)}")
    for k, v in command_start.items():
        why = check_command_value(k, v)
        if why is not None:
            raise DownholeInputError(f"command_start: {why}")
    command_start = {k: float(v) for k, v in command_start.items()}
    if isinstance(stop_time, bool) or not isinstance(stop_time, (int, float)) \
            or not math.isfinite(stop_time) or stop_time <= 0:
        raise DownholeInputError(f"stop_time must be a positive number of seconds, got "
                                 f"{stop_time!r}")
    try:
        blob = pickle.dumps(plant)
    except Exception as exc:
        raise DownholeInputError(f"{type(plant).__name__} cannot be pickled into the FMU: "
                                 f"{exc}") from None
    copy = pickle.loads(blob)  # fail here, not inside the FMU
    copy.reset(start=start, set_point=set_point)

    def resources(res: Path) -> list:
        (res / "plant.pkl").write_bytes(blob)
        (res / "start.json").write_text(json.dumps({
            "start": start, "set_point": set_point, "command_start": command_start,
            "stop_time": float(stop_time), "plant": type(plant).__name__,
            "downhole_version": downhole.__version__}))
        return [res / "plant.pkl", res / "start.json"]

    return _build(out, resources, units)


def system_plant(system, model, fidelity: str, dt: float, *, surface_speed: float = 10.0,
                 rop: float = 0.0, depth_of_cut: str = "delayed", integrator: str = "newmark"):
    """The velocity-driven plant of ``model`` that :func:`export_system_fmu` wraps.

    Commands ``top_drive_axial_velocity`` (m/s) and ``top_drive_angular_velocity`` (rad/s) at
    every fidelity. ``lumped4`` / ``lumped12``: :class:`~downhole.string.fem.DirectionalPlant`
    (velocity-driven top, the given ``integrator``); ``neutral``:
    the same plant over the neutral model's kernel configuration; ``fem`` / ``hybrid``:
    :class:`~downhole.string.fem.DirectionalPlant` with the rig's PI top drive
    (``surface_speed`` its default set-point) and a velocity-servo hook (block velocity ``rop``).

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
    integrator : {"newmark", "euler"}, optional
        Integrator of the lumped plants (default ``"newmark"``).

    Returns
    -------
    Plant
        A plant of the :class:`~downhole.sim.plant.Plant` contract.
    """
    if fidelity in ("lumped4", "lumped12"):
        from downhole.string.fem import DirectionalPlant

        return DirectionalPlant(model, dt=dt, depth_of_cut=depth_of_cut, integrator=integrator)
    if fidelity == "neutral":
        from downhole.string.fem import DirectionalPlant

        return DirectionalPlant(model, dt=dt, depth_of_cut=depth_of_cut)
    import dataclasses

    from downhole.params.rig import Hook
    from downhole.string.fem import DirectionalPlant

    top = dataclasses.replace(system.rig.top_drive, mode="pi", speed=surface_speed)
    h = system.rig.hook
    hook = Hook(mode="velocity", velocity=rop, block_mass=h.block_mass,
                servo_stiffness=h.servo_stiffness, servo_damping=h.servo_damping)
    return DirectionalPlant(model, dt, top_drive=top, hook=hook, depth_of_cut=depth_of_cut)


def export_system_fmu(scenario, out="plant.fmu", *, fidelity: str | None = None,
                      units=None) -> Path:
    """Build ``out`` from a scenario that describes the system (``[model] fidelity``).

    At ``fidelity`` (default: the file's): the plant of :func:`system_plant` with the scenario's
    ``[simulation] dt`` (default: the fidelity's), ``depth_of_cut``, ``integrator`` and
    ``start``; the inputs start at the scenario's set-points (``[operation] rop`` or the ROP of
    the steady bit state at ``wob``, and ``surface_speed``).

    Parameters
    ----------
    scenario : str or os.PathLike
        System scenario TOML file.
    out : str or os.PathLike, optional
        FMU file to write (default ``"plant.fmu"``); must end in ``.fmu``.
    units : str or UnitSystem, optional
        Display unit system of the FMU's variables (``"oilfield"``, ``docs/units.md``); values
        stay SI.
    fidelity : str, optional
        Fidelity to export (default: the scenario's ``[model] fidelity``).

    Returns
    -------
    pathlib.Path
        The FMU written.

    Raises
    ------
    ScenarioError
        Invalid scenario, or a feature the fidelity cannot represent (naming the field).
    DownholeInputError
        ``out`` does not end in ``.fmu``.
    """
    from downhole.scenario.schema import read_scenario
    from downhole.scenario.system import DEFAULT_DT, steady_bit_state, validate_system_scenario

    out = _check_out(out)
    data, source, _ = read_scenario(Path(scenario))
    sc, fid, system, model = validate_system_scenario(data, source, fidelity)
    sim, op = sc.simulation, sc.operation
    dt = sim.dt if sim.dt is not None else DEFAULT_DT[fid]
    rop, _, _ = steady_bit_state(system.bit, op.surface_speed, op.rop, op.wob)
    plant = system_plant(system, model, fid, dt, surface_speed=op.surface_speed, rop=rop,
                         depth_of_cut=sim.depth_of_cut, integrator=sim.integrator)
    command = {"top_drive_axial_velocity": rop, "top_drive_angular_velocity": op.surface_speed}
    return export_plant_fmu(plant, out, start=sim.start,
                            set_point=None if sim.start == "rest" else command,
                            command_start=command, stop_time=float(sim.duration), units=units)


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
        An FMU written by :func:`export_fmu` or :func:`export_plant_fmu` (or any FMI 2.0
        co-simulation FMU with the same signal names).
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
        command that is not finite or out of its admissible range (named, with the time); a
        step the FMU rejects (with the FMU's log message).
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
        slave.instantiate(callbacks=callbacks, loggingOn=True)
        instantiated = True
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        if getattr(controller, "dt", None) is not None:
            controller.dt = float(dt)  # the control step of this loop: every communication step
        controller.reset()
        j = 0
        for k in range(n + 1):
            t = k * dt
            obs = dict(zip(obs_keys, slave.getReal(out_vr)))
            obs.setdefault("time", t)
            out = controller.command(t, obs, ref_fn(t))
            unknown = [c for c in out if c not in held]
            if unknown:
                raise DownholeInputError(f"{cname} at t = {t:g} s sets {unknown}; the FMU "
                                         f"{fmu.name} takes {sorted(taken)}")
            held.update(out)
            if j < len(keep) and keep[j] == k:
                rows[j] = [obs[c] for c in obs_keys]
                cmds[j] = [held[c] for c in in_names]
                j += 1
            if k == n:
                break
            for c in in_names:
                why = check_command_value(c, held[c])
                if why is not None:
                    raise DownholeInputError(f"{cname} at t = {t:g} s: {why}; not applied to "
                                             f"the FMU")
            slave.setReal(in_vr, [float(held[c]) for c in in_names])
            try:
                slave.doStep(currentCommunicationPoint=t, communicationStepSize=dt)
            except Exception as exc:
                said = "; ".join(list(log.messages)[-3:]) or str(exc)
                raise DownholeInputError(f"the FMU {fmu.name} rejected the step at t = {t:g} s "
                                         f"(dt = {dt:g} s): {said}") from None
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
