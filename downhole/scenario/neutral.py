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
from typing import Annotated, Any, Literal

from pydantic import BeforeValidator, Field, field_validator, model_validator

from downhole.errors import DownholeInputError, ScenarioError
from downhole.params.quantity import Q
from downhole.scenario import (
    Profile,
    _Strict,
    check_step_count,
    parse_scenario,
    preset_params,
    profile_to_signal,
)
from downhole.units import UnitError

__all__ = [
    "NeutralScenario",
    "build_controller",
    "build_neutral",
    "build_reference",
    "load_neutral_scenario",
    "run_neutral_scenario",
    "validate_neutral_scenario",
]


def _profile(value, dim, name):
    try:
        return profile_to_signal(value, dim, name)
    except UnitError as exc:
        raise ValueError(str(exc)) from None


class NeutralModelSettings(_Strict):
    """``[model]``: preset plus parameter overrides."""

    fidelity: Literal["neutral"]
    preset: str = "table_3_1"
    string: dict[str, Any] = Field(default_factory=dict)


class NeutralSurface(_Strict):
    """``[operation]``: open-loop commands, the top's axial velocity U_A (``axial_command``,
    m/s, the seed's convention: it includes M_S g / alpha_A) and the top-drive speed U_T
    (``surface_speed``, rad/s)."""

    axial_command: Profile = 1.147224
    surface_speed: Profile = 22.5196

    @field_validator("axial_command", "surface_speed", mode="after")
    @classmethod
    def _sig(cls, v, info):
        dim = "velocity" if info.field_name == "axial_command" else "angular_velocity"
        return _profile(v, dim, info.field_name)


def _pair(v):
    if not (isinstance(v, (list, tuple)) and len(v) == 2
            and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v)):
        raise ValueError(f"expected two numbers [axial, torsional], got {v!r}")
    return tuple(float(x) for x in v)


Pair = Annotated[tuple[float, float], BeforeValidator(_pair)]


class EIDSettings(_Strict):
    """``[controller]`` with ``type = "eid"``: a saved design (``file``) or design options."""

    type: Literal["eid"]
    file: str | None = None
    internal_model_gain: Pair | None = None
    filter_bandwidth: Pair | None = None
    observer_gain: Pair | None = None
    gain_bound: float | None = Field(None, gt=0)
    predictor: bool | None = None
    delayed_input_observer: bool | None = None

    @field_validator("internal_model_gain", "filter_bandwidth", "observer_gain", mode="after")
    @classmethod
    def _positive_pair(cls, v):
        if v is not None and not all(x > 0 for x in v):
            raise ValueError(f"expected two positive numbers [axial, torsional], got {list(v)}")
        return v

    @model_validator(mode="after")
    def _file_or_options(self):
        if self.file is not None and self.design_options():
            raise ValueError("give either 'file' (a saved design) or design options, not both "
                             f"(found {sorted(self.design_options())})")
        return self

    def design_options(self) -> dict:
        """The design keyword arguments that were set."""
        return {k: getattr(self, k) for k in ("internal_model_gain", "filter_bandwidth",
                                              "observer_gain", "gain_bound", "predictor",
                                              "delayed_input_observer")
                if getattr(self, k) is not None}


class NeutralReference(_Strict):
    """``[reference]``: desired bit velocities."""

    type: Literal["constant", "eq3.34-3.35", "seed_tracking", "breakpoints"] = "constant"
    axial_velocity: Profile | None = None
    angular_velocity: Profile | None = None
    v: Q["velocity"] = Field(0.005, gt=0)
    omega: Q["angular_velocity"] = Field(20.0, gt=0)
    max_depth_of_cut: Q["length"] | bool = 6e-3

    @field_validator("axial_velocity", "angular_velocity", mode="after")
    @classmethod
    def _sig(cls, v, info):
        if v is None:
            return v
        dim = "velocity" if info.field_name == "axial_velocity" else "angular_velocity"
        return _profile(v, dim, info.field_name)

    @model_validator(mode="after")
    def _consistent(self):
        sigs = (self.axial_velocity, self.angular_velocity)
        if self.type == "constant":
            if any(isinstance(s, tuple) for s in sigs):
                raise ValueError("type 'constant' takes numbers; use type = 'breakpoints' for "
                                 "[[t, value], ...]")
        elif self.type == "breakpoints":
            if any(s is None for s in sigs):
                raise ValueError("type 'breakpoints' needs axial_velocity and angular_velocity")
        elif any(s is not None for s in sigs):
            raise ValueError(f"type {self.type!r} is fixed by Eqs. 3.34/3.35 (set v, omega, "
                             "max_depth_of_cut); axial_velocity/angular_velocity do not apply")
        if self.max_depth_of_cut is True:
            raise ValueError("max_depth_of_cut: give a length or false")
        return self


class NoiseSettings(_Strict):
    """``[simulation.noise]``: white noise standard deviations."""

    axial_velocity: Q["velocity"] = Field(0.0, ge=0)
    angular_velocity: Q["angular_velocity"] = Field(0.0, ge=0)
    wob: Q["force"] = Field(0.0, ge=0)
    tob: Q["torque"] = Field(0.0, ge=0)


class NeutralSimulation(_Strict):
    """``[simulation]``: duration, step, depth of cut, output sampling, noise."""

    duration: Q["time"] = Field(..., gt=0)
    dt: Q["time"] = Field(1e-4, gt=0)
    depth_of_cut: Literal["delayed", "approximate"] = "delayed"
    record_dt: Q["time"] | None = Field(None, gt=0)
    seed: int = 0
    noise: NoiseSettings = NoiseSettings()
    start: Literal["rest", "off_bottom", "steady"] = "rest"


class NeutralScenario(_Strict):
    """A whole neutral-model scenario file (``simulation`` is needed to run, not to design)."""

    title: str = ""
    description: str = ""
    model: NeutralModelSettings
    bit: dict[str, Any] = Field(default_factory=dict)
    operation: NeutralSurface | None = None
    controller: EIDSettings | None = None
    reference: NeutralReference | None = None
    simulation: NeutralSimulation | None = None


def load_neutral_scenario(data: dict, source: str) -> NeutralScenario:
    """Validate ``data`` (a parsed TOML file) as a :class:`NeutralScenario`."""
    return parse_scenario(data, source, NeutralScenario)


def build_neutral(sc: NeutralScenario, source: str):
    """The :class:`~downhole.string.neutral.NeutralModel` of a scenario (preset + overrides)."""
    from downhole.params import NeutralStringParams
    from downhole.string.neutral import neutral_model

    string, bit = preset_params(sc.model, source, "neutral", NeutralStringParams, "table_3_1",
                                bit=sc.bit)
    try:
        return neutral_model(string, bit)
    except DownholeInputError as exc:
        raise ScenarioError(source, "model.string", str(exc)) from None


def build_reference(sc: NeutralScenario):
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
    if r.type == "constant":
        return constant_reference(0.01 if r.axial_velocity is None else r.axial_velocity,
                                  20.0 if r.angular_velocity is None else r.angular_velocity)
    if r.type == "breakpoints":
        ref = user_reference(r.axial_velocity, r.angular_velocity)
        return ref
    dmax = None if r.max_depth_of_cut is False else float(r.max_depth_of_cut)
    return seed_tracking_reference(r.v, r.omega, dmax)


def build_controller(sc: NeutralScenario, source: str, model, reference=None):
    """The EID controller of a scenario: loaded from ``file`` (relative to the scenario file) or
    designed from the inline options (LMI). ``None`` without ``[controller]``."""
    from downhole.control.eid import design_eid, load_eid

    c = sc.controller
    if c is None:
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
            return design_eid(model, reference=reference, **c.design_options())
        except DownholeInputError as exc:
            raise ScenarioError(source, "controller", str(exc)) from None


def validate_neutral_scenario(data: dict, source: str):
    """Validate a neutral-model scenario for a run without running it: the schema, the model and
    the step settings. Returns ``(scenario, model)``; raises :class:`ScenarioError`."""
    sc = load_neutral_scenario(data, source)
    if sc.simulation is None:
        raise ScenarioError(source, "simulation", "required table is missing (duration, dt, ...)")
    sim = sc.simulation
    if sim.dt > sim.duration:
        raise ScenarioError(source, "simulation.dt", f"dt ({sim.dt} s) exceeds duration "
                            f"({sim.duration} s)")
    model = build_neutral(sc, source)
    if sim.dt > model.tau1:
        raise ScenarioError(source, "simulation.dt", f"dt ({sim.dt} s) exceeds the axial wave "
                            f"delay tau1 = {model.tau1:.6g} s")
    if sim.record_dt is not None and sim.record_dt < sim.dt:
        raise ScenarioError(source, "simulation.record_dt", f"record_dt ({sim.record_dt} s) is "
                            f"below dt ({sim.dt} s)")
    if sc.controller is None and sc.reference is not None:
        raise ScenarioError(source, "reference", "a reference needs a [controller]; open loop "
                            "is driven by [operation]")
    if sc.controller is not None and sc.operation is not None:
        raise ScenarioError(source, "operation", "the [controller] sets U_A/U_T; remove "
                            "[operation] "
                            "(open-loop commands) or [controller]")
    check_step_count(source, sim.duration, sim.dt, sim.record_dt)
    return sc, model


def run_neutral_scenario(data: dict, source: str, text: str):
    """Run a neutral-model scenario (``[model] fidelity = "neutral"`` of a preset); returns a
    :class:`~downhole.sim.Result` with the scenario text in ``attrs["scenario"]``."""
    from downhole.sim import simulate

    sc, model = validate_neutral_scenario(data, source)
    sim = sc.simulation
    reference = build_reference(sc) if sc.controller is not None else None
    ctrl = build_controller(sc, source, model, reference)
    surface = sc.operation or NeutralSurface()
    noise = sim.noise.model_dump()
    noise["axial"] = noise.pop("axial_velocity")
    noise["angular"] = noise.pop("angular_velocity")
    attrs = {"scenario": text, "scenario_source": source, "title": sc.title}
    try:
        return simulate(model, duration=sim.duration, dt=sim.dt, controller=ctrl,
                                inputs=(surface.axial_command, surface.surface_speed),
                                reference=reference, noise=noise,
                                depth_of_cut=sim.depth_of_cut, record_dt=sim.record_dt,
                                seed=sim.seed, attrs=attrs, start=sim.start)
    except DownholeInputError as exc:
        raise ScenarioError(source, "simulation", str(exc)) from None
