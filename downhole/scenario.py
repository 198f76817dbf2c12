"""Scenario files (TOML): model, bit law, surface inputs, reference and simulation settings.

A scenario is validated completely before anything runs; every error names the file, the dotted
field and what was expected (:class:`downhole.errors.ScenarioError`). Numbers may carry units
("10 rad/s", "120 rpm", "30 m/h", "25 klbf", "0.5 ms"). See ``docs/scenarios.md``.

Model types are pluggable: :func:`register_model_type` adds a runner for ``[model] type = ...``.
"""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any, Callable, Literal, Union

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from downhole.errors import ScenarioError
from downhole.params.quantity import Q
from downhole.units import UnitError, to_si

__all__ = ["load_scenario", "parse_scenario", "run_scenario", "register_model_type",
           "LumpedScenario", "MODEL_TYPES", "model_type", "is_lumped_type", "validate_data",
           "validate_scenario", "build_lumped_model"]

#: A profile: a constant, or breakpoints [[t, value], ...] interpolated linearly.
Profile = Union[float, int, str, list]


def profile_to_signal(value: Profile, dimension: str, field: str):
    """Convert a scenario profile into a signal accepted by :class:`~downhole.sim.SurfaceInputs`."""
    if isinstance(value, list):
        if not value:
            raise ValueError(f"{field}: empty profile; give a value or [[t, value], ...]")
        ts, vs = [], []
        for i, pair in enumerate(value):
            if not (isinstance(pair, list) and len(pair) == 2):
                raise ValueError(f"{field}[{i}]: expected [time, value], got {pair!r}")
            ts.append(to_si(pair[0], "time"))
            vs.append(to_si(pair[1], dimension))
        if any(b < a for a, b in zip(ts, ts[1:])):
            raise ValueError(f"{field}: breakpoint times must be non-decreasing, got {ts}")
        return (np.array(ts), np.array(vs))
    return to_si(value, dimension)


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid")


class SimulationSettings(_Strict):
    """``[simulation]``: duration, step, depth-of-cut model, integrator, output sampling."""

    duration: Q["time"] = Field(..., gt=0)
    dt: Q["time"] = Field(5e-4, gt=0)
    depth_of_cut: Literal["delayed", "approximate"] = "delayed"
    integrator: Literal["euler", "newmark"] = "euler"
    record_dt: Q["time"] | None = Field(None, gt=0)
    rock_memory: bool = True


class SurfaceSettings(_Strict):
    """``[surface]``: how the top drive drives the string."""

    mode: Literal["velocity", "force"] = "velocity"
    axial_velocity: Profile = "10 mm/s"
    angular_velocity: Profile = "10 rad/s"
    hook_load: Profile | None = None
    surface_torque: Profile | None = None

    @field_validator("axial_velocity", "angular_velocity", "hook_load", "surface_torque",
                     mode="after")
    @classmethod
    def _profile(cls, v, info):
        if v is None:
            return v
        dim = {"axial_velocity": "velocity", "angular_velocity": "angular_velocity",
               "hook_load": "force", "surface_torque": "torque"}[info.field_name]
        try:
            return profile_to_signal(v, dim, info.field_name)
        except UnitError as exc:
            raise ValueError(str(exc)) from None

    def model_post_init(self, __context) -> None:
        if self.mode == "force" and (self.hook_load is None or self.surface_torque is None):
            raise ValueError("mode 'force' needs both hook_load and surface_torque")


class ReferenceSettings(_Strict):
    """``[reference]``: desired bit velocities (recorded as reference channels)."""

    axial_velocity: Profile = "10 mm/s"
    angular_velocity: Profile = "10 rad/s"

    @field_validator("axial_velocity", "angular_velocity", mode="after")
    @classmethod
    def _profile(cls, v, info):
        dim = "velocity" if info.field_name == "axial_velocity" else "angular_velocity"
        try:
            return profile_to_signal(v, dim, info.field_name)
        except UnitError as exc:
            raise ValueError(str(exc)) from None


class LumpedModelSettings(_Strict):
    """``[model]`` for ``type = "lumped4" | "lumped12"``."""

    type: Literal["lumped4", "lumped12"]
    preset: str = "table_2_1"
    string: dict[str, Any] = Field(default_factory=dict)
    bit: dict[str, Any] = Field(default_factory=dict)


class LumpedScenario(_Strict):
    """A whole lumped-model scenario file."""

    title: str = ""
    description: str = ""
    model: LumpedModelSettings
    surface: SurfaceSettings = SurfaceSettings()
    reference: ReferenceSettings | None = None
    simulation: SimulationSettings


def _loc(loc) -> str:
    return ".".join(str(p) for p in loc if not str(p).startswith("function-"))


def _raise_validation(source: str, exc: ValidationError, prefix: str = ""):
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
        msg += f" (got {err['input']!r})"
    raise ScenarioError(source, field, msg) from None


def build_lumped_model(sc: LumpedScenario, source: str):
    """The lumped chain model of a parsed lumped scenario (raises :class:`ScenarioError`)."""
    from downhole.params import BitParams, LumpedParams, get_preset
    from downhole.string.lumped import lumped_model

    try:
        preset = get_preset(sc.model.preset)
    except KeyError as exc:
        raise ScenarioError(source, "model.preset", exc.args[0]) from None
    if preset.kind != "lumped":
        raise ScenarioError(source, "model.preset",
                            f"preset {sc.model.preset!r} is a {preset.kind} model, expected a lumped one")
    try:
        string = LumpedParams(**{**preset.string.model_dump(), **sc.model.string})
    except ValidationError as exc:
        _raise_validation(source, exc, "model.string.")
    except ValueError as exc:
        raise ScenarioError(source, "model.string", str(exc)) from None
    try:
        bit = BitParams(**{**preset.bit.model_dump(), **sc.model.bit})
    except ValidationError as exc:
        _raise_validation(source, exc, "model.bit.")
    order = 4 if sc.model.type == "lumped4" else 12
    return lumped_model(string, bit, order=order)


def _run_lumped(data: dict, source: str, text: str):
    from downhole.sim import SurfaceInputs, simulate
    from downhole.sim.inputs import sample_signal

    sc = parse_scenario(data, source, LumpedScenario)
    model = build_lumped_model(sc, source)
    s = sc.surface
    if s.mode == "velocity":
        inputs = SurfaceInputs.velocity(s.axial_velocity, s.angular_velocity)
    else:
        inputs = SurfaceInputs.force(s.hook_load, s.surface_torque)
    sim = sc.simulation
    if sim.dt > sim.duration:
        raise ScenarioError(source, "simulation.dt", f"dt ({sim.dt} s) exceeds duration ({sim.duration} s)")
    res = simulate(model, inputs, duration=sim.duration, dt=sim.dt,
                   depth_of_cut=sim.depth_of_cut, integrator=sim.integrator,
                   record_dt=sim.record_dt, rock_memory=sim.rock_memory,
                   attrs={"scenario": text, "scenario_source": source, "title": sc.title})
    if sc.reference is not None:
        t = res.time
        ds = res.dataset
        from downhole.sim.result import Result

        chans = {n: ds[n].values for n in ds.data_vars}
        chans["reference_axial_velocity"] = sample_signal(sc.reference.axial_velocity, t, "reference")
        chans["reference_angular_velocity"] = sample_signal(sc.reference.angular_velocity, t, "reference")
        res = Result(t, chans, attrs=dict(ds.attrs))
    return res


#: Runners by ``[model] type``: ``runner(data: dict, source: str, text: str) -> Result``.
MODEL_TYPES: dict[str, Callable] = {"lumped4": _run_lumped, "lumped12": _run_lumped}


def register_model_type(name: str, runner: Callable) -> None:
    """Register a scenario runner for ``[model] type = name``."""
    MODEL_TYPES[name] = runner


def parse_scenario(data: dict, source: str, schema=LumpedScenario):
    """Validate ``data`` against ``schema``; raise :class:`ScenarioError` naming the field."""
    try:
        return schema.model_validate(data)
    except ValidationError as exc:
        _raise_validation(source, exc)


def load_scenario(path: str | Path) -> tuple[dict, str, str]:
    """Read a TOML scenario file: returns ``(data, source, text)``."""
    path = Path(path)
    source = str(path)
    if not path.is_file():
        raise ScenarioError(source, "", "file not found")
    text = path.read_text()
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(source, "", f"not valid TOML: {exc}") from None
    return data, source, text


def model_type(data: dict, source: str) -> str:
    """The scenario's ``[model] type``, checked against the registered types."""
    model = data.get("model", {})
    if not isinstance(model, dict):
        raise ScenarioError(source, "model", "expected a table [model]")
    _load_plugins()
    if "type" not in model:
        raise ScenarioError(source, "model.type", "required field is missing "
                            f"(one of {sorted(MODEL_TYPES)})")
    mtype = model["type"]
    if mtype not in MODEL_TYPES:
        raise ScenarioError(source, "model.type",
                            f"unknown model type {mtype!r}; expected one of {sorted(MODEL_TYPES)}")
    return mtype


def is_lumped_type(mtype: str) -> bool:
    """True for the built-in lumped types, whose full schema is :class:`LumpedScenario` (the
    other types' schemas live with their runners)."""
    return MODEL_TYPES.get(mtype) is _run_lumped


def validate_data(data: dict, source: str) -> str:
    """Validate a parsed scenario without running it: its model type always, lumped scenarios
    against their full schema and model. Returns the model type."""
    mtype = model_type(data, source)
    if is_lumped_type(mtype):
        build_lumped_model(parse_scenario(data, source, LumpedScenario), source)
    return mtype


def validate_scenario(path: str | Path) -> None:
    """Validate a scenario file without running it (raises :class:`ScenarioError`)."""
    data, source, _ = load_scenario(path)
    validate_data(data, source)


def run_scenario(path_or_data: str | Path | dict, source: str = "<dict>") -> "Result":  # noqa: F821
    """Run a scenario file (or an already-parsed dict) and return its Result."""
    if isinstance(path_or_data, dict):
        import tomli_w

        data, text = path_or_data, tomli_w.dumps(path_or_data)
    else:
        data, source, text = load_scenario(path_or_data)
    mtype = model_type(data, source)
    return MODEL_TYPES[mtype](data, source, text)


_PLUGINS_LOADED = False


def _load_plugins() -> None:
    """Import the modules that register further model types (neutral, FEM, hybrid, ...)."""
    global _PLUGINS_LOADED
    if _PLUGINS_LOADED:
        return
    _PLUGINS_LOADED = True
    import importlib

    for mod in ("downhole.scenario_types",):
        try:
            importlib.import_module(mod)
        except ModuleNotFoundError as exc:
            if exc.name != mod:
                raise
