"""Scenario files for the neutral-type model (``[model] fidelity = "neutral"`` with a preset):
schema, validation and the runner behind ``downhole simulate`` (open loop or with an EID
controller); the same file drives ``downhole design eid``.

Schema (every table but ``[model]`` and ``[simulation]`` optional; numbers may carry units)::

    title = "..."
    [model]
    fidelity = "neutral"
    preset = "table_3_1"                # a 'neutral' preset
    [model.string]                      # NeutralStringParams overrides, e.g. length = "1200 m"
    [bit]                               # BitParams overrides, e.g. epsilon = "90 MPa"

    [operation]                         # open loop (not with a controller)
    axial_command = 1.147224            # U_A, m/s (seed convention: includes M_S g/alpha_A)
    surface_speed = "22.5196 rad/s"     # U_T; each a constant or [[t, value], ...]

    [controller]
    type = "eid"
    file = "out/eid"                    # a directory written by `downhole design eid`, or:
    internal_model_gain = [10.0, 1.0]   # B_R (axial, torsional)
    filter_bandwidth = [20.0, 2.0]      # rad/s, F(s) = bf/(s + bf)
    observer_gain = [20.0, 7.0]         # L
    gain_bound = 5.0
    predictor = true
    delayed_input_observer = true

    [reference]                         # bit velocities
    type = "constant"                   # "constant" | "eq3.34-3.35" | "breakpoints"
    axial_velocity = "10 mm/s"          # constant, or [[t, v], ...] for "breakpoints"
    angular_velocity = "20 rad/s"
    # "eq3.34-3.35": v = "5 mm/s", omega = "20 rad/s", max_depth_of_cut = "6 mm" (or false)

    [simulation]
    duration = "60 s"
    dt = "0.1 ms"
    depth_of_cut = "delayed"            # or "approximate"
    record_dt = "10 ms"
    seed = 0
    [simulation.noise]                  # white noise (standard deviation per sample)
    axial_velocity = "1 mm/s"
    angular_velocity = "1 rad/s"
    wob = 0.0                           # N (bit-force noise)
    tob = 0.0                           # N m
"""

from __future__ import annotations

import warnings
from pathlib import Path

from downhole import _schema
from downhole.errors import DownholeInputError, ScenarioError
from downhole.scenario import Scenario, check_step_count, parse_scenario, preset_params

__all__ = [
    "NEUTRAL_KEYS",
    "build_controller",
    "build_neutral",
    "build_reference",
    "has_controller",
    "load_neutral_scenario",
    "run_neutral_scenario",
    "validate_neutral_scenario",
]


#: The keys a neutral preset reads (:func:`downhole._schema.only_keys`).
NEUTRAL_KEYS = ("title", "description", "model.fidelity", "model.preset", "model.string", "bit",
                "operation.axial_command", "operation.surface_speed", "controller.type",
                "controller.file", *(f"controller.{k}" for k in _schema.EIDOptions.model_fields),
                "reference.type", "reference.axial_velocity", "reference.angular_velocity",
                "reference.v", "reference.omega", "reference.max_depth_of_cut",
                "simulation.duration", "simulation.dt", "simulation.depth_of_cut",
                "simulation.record_dt", "simulation.seed", "simulation.noise", "simulation.start")

#: The open-loop commands of a neutral preset without [operation]: U_A (m/s, the seed's
#: convention, M_S g / alpha_A included) and U_T (rad/s): 10 mm/s and 20 rad/s at the bit.
OPEN_LOOP = {"axial_command": 1.147224, "surface_speed": 22.5196}


def has_controller(sc: Scenario) -> bool:
    """True when the file names a controller (``[controller] type``).

    Parameters
    ----------
    sc : Scenario
        The parsed file.
    """
    return sc.controller.type not in (None, "none")


def load_neutral_scenario(data: dict, source: str) -> Scenario:
    """Validate ``data`` (a parsed TOML file) as a neutral preset: the keys it reads
    (:data:`NEUTRAL_KEYS`), the one schema, then the neutral model's own rules (an EID
    controller, its file or its design options, the reference types of Ch. 3)."""
    _schema.only_keys(data, source, NEUTRAL_KEYS, "a neutral preset")
    sc = parse_scenario(data, source)
    c = sc.controller
    if has_controller(sc):
        if c.type != "eid":
            raise ScenarioError(source, "controller.type", f"the neutral model runs the EID "
                                f"controller (type = \"eid\"), got {c.type!r}")
        if c.file is not None and c.options.design_options():
            raise ScenarioError(source, "controller", "give either 'file' (a saved design) or "
                                "design options, not both (found "
                                f"{sorted(c.options.design_options())})")
    r = sc.reference
    if r is not None and r.type not in (None, "constant", "eq3.34-3.35", "seed_tracking",
                                        "breakpoints"):
        raise ScenarioError(source, "reference.type", f"the neutral model takes constant, "
                            f"breakpoints, eq3.34-3.35 or seed_tracking, got {r.type!r}")
    return sc


def build_neutral(sc: Scenario, source: str):
    """The :class:`~downhole.string.neutral.NeutralModel` of a scenario (preset + overrides)."""
    from downhole.params import NeutralStringParams
    from downhole.string.neutral import neutral_model

    string, bit = preset_params(sc.model, source, "neutral", NeutralStringParams, "table_3_1",
                                bit=sc.bit)
    try:
        return neutral_model(string, bit)
    except DownholeInputError as exc:
        raise ScenarioError(source, "model.string", str(exc)) from None


def build_reference(sc: Scenario):
    """The :class:`~downhole.control.eid.references.Reference` of a scenario (default constant
    10 mm/s, 20 rad/s)."""
    from downhole.control.eid.references import (
        constant_reference,
        seed_tracking_reference,
        user_reference,
    )

    r = sc.reference
    if r is None:
        return constant_reference()
    if r.type in (None, "constant"):
        return constant_reference(0.01 if r.axial_velocity is None else r.axial_velocity,
                                  20.0 if r.angular_velocity is None else r.angular_velocity)
    if r.type == "breakpoints":
        ref = user_reference(r.axial_velocity, r.angular_velocity)
        return ref
    dmax = None if r.max_depth_of_cut is False else float(r.max_depth_of_cut)
    return seed_tracking_reference(r.v, r.omega, dmax)


def build_controller(sc: Scenario, source: str, model, reference=None):
    """The EID controller of a scenario: loaded from ``file`` (relative to the scenario file) or
    designed from the inline options (LMI). ``None`` without ``[controller]``."""
    from downhole.control.eid import design_eid, load_eid

    c = sc.controller
    if not has_controller(sc):
        return None
    if c.file is not None:
        path = Path(c.file)
        if not path.is_absolute() and source and not source.startswith("<"):
            path = Path(source).parent / path
        try:
            ctrl = load_eid(path)
        except DownholeInputError as exc:
            raise ScenarioError(source, "controller.file", str(exc)) from None
        except (KeyError, TypeError, ValueError) as exc:
            raise ScenarioError(source, "controller.file", f"{path}: not a saved EID design "
                                f"({exc})") from None
        mine = model.ndde()
        for i, ch in enumerate(ctrl.model_coeffs):
            if abs(ch["tau"] - mine.channel(i)["tau"]) > 1e-9 * max(1.0, ch["tau"]):
                raise ScenarioError(source, "controller.file", f"{path} was designed for another "
                                    f"string (delay {ch['tau']:.6g} s vs {mine.channel(i)['tau']:.6g} s)")
        if reference is not None:
            from dataclasses import replace

            ctrl = replace(ctrl, reference=reference)
        return ctrl
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            return design_eid(model, reference=reference, **c.options.design_options())
        except DownholeInputError as exc:
            raise ScenarioError(source, "controller", str(exc)) from None


def validate_neutral_scenario(data: dict, source: str):
    """Validate a neutral-model scenario for a run without running it: the schema, the model and
    the step settings. Returns ``(scenario, model)``; raises :class:`ScenarioError`."""
    sc = load_neutral_scenario(data, source)
    if sc.simulation is None:
        raise ScenarioError(source, "simulation", "required table is missing (duration, dt, ...)")
    sim = sc.simulation
    if sim.duration is None:
        raise ScenarioError(source, "simulation.duration", "required field is missing")
    dt = sim.step("neutral")
    if dt > sim.duration:
        raise ScenarioError(source, "simulation.dt", f"dt ({dt} s) exceeds duration "
                            f"({sim.duration} s)")
    model = build_neutral(sc, source)
    if dt > model.tau1:
        raise ScenarioError(source, "simulation.dt", f"dt ({dt} s) exceeds the axial wave "
                            f"delay tau1 = {model.tau1:.6g} s")
    if sim.record_dt is not None and sim.record_dt < dt:
        raise ScenarioError(source, "simulation.record_dt", f"record_dt ({sim.record_dt} s) is "
                            f"below dt ({dt} s)")
    if not has_controller(sc) and sc.reference is not None:
        raise ScenarioError(source, "reference", "a reference needs a [controller]; open loop "
                            "is driven by [operation]")
    if has_controller(sc) and "operation" in data:
        raise ScenarioError(source, "operation", "the [controller] sets U_A/U_T; remove "
                            "[operation] "
                            "(open-loop commands) or [controller]")
    check_step_count(source, sim.duration, dt, sim.record_dt)
    return sc, model


def run_neutral_scenario(data: dict, source: str, text: str):
    """Run a neutral-model scenario (``[model] fidelity = "neutral"`` of a preset); returns a
    :class:`~downhole.sim.Result` with the scenario text in ``attrs["scenario"]``."""
    from downhole.sim import simulate

    sc, model = validate_neutral_scenario(data, source)
    sim = sc.simulation
    reference = build_reference(sc) if has_controller(sc) else None
    ctrl = build_controller(sc, source, model, reference)
    op = sc.operation
    commands = (OPEN_LOOP["axial_command"] if op.axial_command is None else op.axial_command,
                OPEN_LOOP["surface_speed"] if op.surface_speed is None else op.surface_speed)
    noise = sim.noise.model_dump()
    noise["axial"] = noise.pop("axial_velocity")
    noise["angular"] = noise.pop("angular_velocity")
    attrs = {"scenario": text, "scenario_source": source, "title": sc.title}
    try:
        return simulate(model, duration=sim.duration, dt=sim.step("neutral"), controller=ctrl,
                                inputs=commands,
                                reference=reference, noise=noise,
                                depth_of_cut=sim.depth_of_cut, record_dt=sim.record_dt,
                                seed=sim.seed, attrs=attrs, start=sim.start)
    except DownholeInputError as exc:
        raise ScenarioError(source, "simulation", str(exc)) from None
