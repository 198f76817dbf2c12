"""Scenario files (TOML): model, bit law, surface inputs, reference and simulation settings.

A scenario is validated completely before anything runs; every error names the file, the dotted
field and what was expected (:class:`downhole.errors.ScenarioError`). Numbers may carry units
("10 rad/s", "120 rpm", "30 m/h", "25 klbf", "0.5 ms"). See ``docs/scenarios.md``.

Model types are pluggable: :func:`register_model_type` adds a runner for ``[model] fidelity =
...``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
from pydantic import ValidationError

from downhole import _schema
from downhole._reader import (  # noqa: F401
    MAX_DEPTH,
    MAX_FILE_BYTES,
    MAX_INTEGER,
    MAX_LIST_LENGTH,
    MAX_NUMBER,
    MAX_STRING_LENGTH,
    _check_numeric_string,
    check_values,
    parse_toml_text,
    read_scenario_text,
    read_toml,
)
from downhole._schema import raise_validation
from downhole.errors import ScenarioError

__all__ = [
    "MODEL_TYPES",
    "Scenario",
    "build_lumped_model",
    "check_step_count",
    "check_values",
    "euler_stable_dt",
    "is_lumped_type",
    "load_scenario",
    "model_type",
    "parse_scenario",
    "read_scenario_text",
    "read_toml",
    "register_model_type",
    "run_scenario",
    "validate_data",
    "validate_lumped",
    "validate_scenario",
]

#: The tables of every scenario file (:mod:`downhole._schema`, public as
#: :mod:`downhole.scenario.schema`).
Scenario = _schema.Scenario
Profile = _schema.Profile
profile_to_signal = _schema.profile_to_signal

#: Lumped presets: the operating point and reference of a file that gives none.
LUMPED_DEFAULTS = {"rop": 0.01, "surface_speed": 10.0}


#: The one error formatter of every scenario runner (:func:`downhole._schema.raise_validation`).
_raise_validation = raise_validation


def preset_params(sc_model, source: str, kind: str, string_cls, example: str = "",
                  bit: dict | None = None, default: str | None = None):
    """The ``[model]`` table's preset with its ``string`` overrides and the ``[bit]`` table
    (``bit``) applied: ``(string parameters, BitParams)``; errors name ``model.preset``,
    ``model.string.*`` or ``bit.*``. ``kind`` is the preset kind the model needs (``example``
    names one)."""
    from downhole.params import BitParams, get_preset

    name = sc_model.preset or default or example
    try:
        preset = get_preset(name)
    except KeyError as exc:
        raise ScenarioError(source, "model.preset", exc.args[0]) from None
    if preset.kind != kind:
        hint = f" ({example})" if example else ""
        raise ScenarioError(source, "model.preset", f"preset {name!r} is a "
                            f"{preset.kind} model, expected a {kind} one{hint}")
    try:
        string = string_cls(**{**preset.string.model_dump(), **sc_model.string})
    except ValidationError as exc:
        _raise_validation(source, exc, "model.string.")
    except ValueError as exc:
        raise ScenarioError(source, "model.string", str(exc)) from None
    try:
        over = dict(bit or {})
        if "preset" in over:
            raise ScenarioError(source, "bit.preset", f"model.preset = {name!r} "
                                "brings its bit; give only bit parameters here (epsilon, ...)")
        bit = BitParams(**{**preset.bit.model_dump(), **over})
    except ValidationError as exc:
        _raise_validation(source, exc, "bit.")
    return string, bit


def build_lumped_model(sc: Scenario, source: str):
    """The lumped chain model of a parsed lumped scenario (raises :class:`ScenarioError`)."""
    from downhole.params import LumpedParams
    from downhole.string.lumped import lumped_model

    string, bit = preset_params(sc.model, source, "lumped", LumpedParams, "table_2_1",
                                bit=sc.bit)
    order = 4 if sc.model.fidelity == "lumped4" else 12
    return lumped_model(string, bit, order=order)


def _chain_state_matrix(f, force_mode: bool) -> np.ndarray:
    """First-order state matrix [[0, I], [-M^-1 K, -M^-1 C]] of one chain field (the top spring
    and damper only in velocity mode, where the top drive moves the string's top)."""
    n = f.n
    k = np.zeros((n, n))
    c = np.diag(np.asarray(f.c_abs, float))
    if not force_mode:
        k[0, 0] += f.k_top
        c[0, 0] += f.c_top
    for i, (kl, cl) in enumerate(zip(f.k_link, f.c_link)):
        for mat, val in ((k, kl), (c, cl)):
            mat[i, i] += val
            mat[i + 1, i + 1] += val
            mat[i, i + 1] -= val
            mat[i + 1, i] -= val
    minv = np.diag(1.0 / np.asarray(f.mass, float))
    return np.block([[np.zeros((n, n)), np.eye(n)], [-minv @ k, -minv @ c]])


def euler_stable_dt(model, force_mode: bool = False) -> tuple[float, dict]:
    """Largest step for which explicit Euler is stable on every mode of a lumped chain.

    Explicit Euler maps a mode ``exp(lambda t)`` to ``(1 + lambda dt)^n``; it decays only if
    ``|1 + lambda dt| < 1``, i.e. ``dt < 2 Re(-lambda) / |lambda|^2``. For a mode of natural
    frequency ``omega`` and damping ratio ``zeta`` that is ``dt < 2 zeta / omega``: the highest,
    least damped mode sets the bound. The bit law is left out (its cutting force damps the axial
    modes, so this is a sufficient bound for the string itself).

    Parameters
    ----------
    model : ChainModel
        A lumped model (:func:`downhole.string.lumped.lumped_model`).
    force_mode : bool
        True when the surface applies forces (no top-drive spring).

    Returns
    -------
    (float, dict)
        The bound in s (0 if a mode is undamped) and the limiting mode: ``field``,
        ``frequency`` (rad/s, undamped natural frequency) and ``damping_ratio``.
    """
    best, info = math.inf, {}
    for name, f in (("axial", model.axial), ("torsional", model.torsional)):
        lam = np.linalg.eigvals(_chain_state_matrix(f, force_mode))
        for lm in lam:
            mag2 = float(abs(lm) ** 2)
            if mag2 < 1e-18:   # a rigid-body mode (force mode): |1 + 0 dt| = 1, neutral
                continue
            bound = max(0.0, -2.0 * float(lm.real) / mag2)
            if bound < best:
                omega = math.sqrt(mag2)
                best, info = bound, {"field": name, "frequency": omega,
                                     "damping_ratio": -float(lm.real) / omega}
    return best, info


#: The keys a lumped preset reads (:func:`downhole._schema.only_keys`).
LUMPED_KEYS = ("title", "description", "model.fidelity", "model.preset", "model.string", "bit",
               "operation.mode", "operation.rop", "operation.surface_speed",
               "operation.hook_load", "operation.surface_torque", "reference.axial_velocity",
               "reference.angular_velocity", "simulation.duration", "simulation.dt",
               "simulation.record_dt", "simulation.depth_of_cut", "simulation.integrator",
               "simulation.rock_memory", "simulation.start")


def _lumped_simulation(sc: Scenario, source: str) -> tuple[float, float]:
    """``(duration, dt)`` of a lumped preset's ``[simulation]`` (required, with duration)."""
    if sc.simulation is None or sc.simulation.duration is None:
        raise ScenarioError(source, "simulation.duration", "required field is missing")
    return sc.simulation.duration, sc.simulation.step(sc.model.fidelity)


def validate_lumped(data: dict, source: str):
    """Validate a lumped scenario for a run without running it: schema, model, step count and,
    for ``integrator = "euler"``, the explicit-Euler stability of the step
    (:func:`euler_stable_dt`). Returns ``(scenario, model)``; raises :class:`ScenarioError`."""
    _schema.only_keys(data, source, LUMPED_KEYS, "a lumped preset")
    sc = parse_scenario(data, source)
    if sc.model.fidelity not in ("lumped4", "lumped12"):
        raise ScenarioError(source, "model.fidelity", "expected lumped4 or lumped12")
    model = build_lumped_model(sc, source)
    sim = sc.simulation
    duration, dt = _lumped_simulation(sc, source)
    if dt > duration:
        raise ScenarioError(source, "simulation.dt", f"dt ({dt} s) exceeds duration "
                            f"({duration} s)")
    check_step_count(source, duration, dt, sim.record_dt)
    nsteps = round(duration / dt)
    if abs(nsteps * dt - duration) > 1e-9 * max(1.0, duration):
        raise ScenarioError(source, "simulation.dt", f"dt = {dt:g} s does not divide the "
                            f"duration ({duration:g} s) into whole steps")
    if sim.record_dt is not None and sim.record_dt < dt:
        raise ScenarioError(source, "simulation.record_dt", f"record_dt ({sim.record_dt:g} s) "
                            f"is below dt ({dt:g} s)")
    if sim.integrator == "euler":
        bound, mode = euler_stable_dt(model, force_mode=sc.operation.mode == "force")
        if dt >= bound:
            if bound == 0.0:
                why = (f"the {mode['field']} mode at {mode['frequency']:.4g} rad/s is undamped, "
                       "so explicit Euler is unstable at any step")
            else:
                why = (f"explicit Euler is stable only for dt < {bound:.4g} s (2 zeta / omega "
                       f"of the {mode['field']} mode at {mode['frequency']:.4g} rad/s, damping "
                       f"ratio {mode['damping_ratio']:.3g})")
            raise ScenarioError(source, "simulation.dt", f"dt = {dt:g} s is too large: "
                                f"{why}; use a smaller dt or integrator = 'newmark'")
    return sc, model


def _run_lumped(data: dict, source: str, text: str):
    from downhole.sim import SurfaceInputs, simulate
    from downhole.sim.inputs import sample_signal

    sc, model = validate_lumped(data, source)
    s = sc.operation
    if s.mode == "force":
        inputs = SurfaceInputs.force(s.hook_load, s.surface_torque)
    else:
        d = LUMPED_DEFAULTS
        inputs = SurfaceInputs.velocity(d["rop"] if s.rop is None else s.rop,
                                        d["surface_speed"] if s.surface_speed is None
                                        else s.surface_speed)
    sim = sc.simulation
    duration, dt = _lumped_simulation(sc, source)
    res = simulate(model, inputs, duration=duration, dt=dt,
                   depth_of_cut=sim.depth_of_cut, integrator=sim.integrator,
                   record_dt=sim.record_dt, rock_memory=sim.rock_memory, start=sim.start,
                   attrs={"scenario": text, "scenario_source": source, "title": sc.title})
    if sc.reference is not None:
        t = res.time
        ds = res.dataset
        from downhole.sim.result import Result

        r, d = sc.reference, LUMPED_DEFAULTS
        chans = {n: ds[n].values for n in ds.data_vars}
        chans["reference_axial_velocity"] = sample_signal(
            d["rop"] if r.axial_velocity is None else r.axial_velocity, t, "reference")
        chans["reference_angular_velocity"] = sample_signal(
            d["surface_speed"] if r.angular_velocity is None else r.angular_velocity, t,
            "reference")
        res = Result(t, chans, attrs=dict(ds.attrs))
    return res


#: Runners by ``[model] fidelity`` of a preset (:func:`model_type`): ``runner(data: dict,
#: source: str, text: str) -> Result``.
MODEL_TYPES: dict[str, Callable] = {"lumped4": _run_lumped, "lumped12": _run_lumped}


def register_model_type(name: str, runner: Callable) -> None:
    """Register a scenario runner for ``[model] fidelity = name`` (a plug-in model)."""
    MODEL_TYPES[name] = runner


def _catalogue_od(name: str) -> float:
    from downhole.string.catalogue import catalogue_section

    return float(catalogue_section(name).outer_diameter)


def parse_scenario(data: dict, source: str) -> Scenario:
    """Validate ``data`` against the one schema (:func:`downhole._schema.parse`); raise
    :class:`ScenarioError` naming the field.

    The geometry is checked as a whole first (:func:`downhole.plausible.check_geometry`, with
    the catalogue's tubulars)."""
    from downhole.plausible import check_geometry

    check_geometry(data, source, catalogue=_catalogue_od)
    return _schema.parse(data, source)


#: Most time steps one run may take.
MAX_STEPS = 200_000_000
#: Most samples one run may record.
MAX_SAMPLES = 10_000_000


def check_step_count(source: str, duration: float, dt: float, record_dt: float | None = None,
                     table: str = "simulation") -> None:
    """Refuse runs whose step or sample count no machine could hold.

    Parameters
    ----------
    source : str
        The file name for messages.
    duration, dt : float
        Simulated time and step, s.
    record_dt : float, optional
        Output sampling, s.
    table : str
        The table holding these fields.

    Raises
    ------
    ScenarioError
        ``duration / dt`` above :data:`MAX_STEPS` (field ``TABLE.dt``) or ``duration /
        record_dt`` above :data:`MAX_SAMPLES` (field ``TABLE.record_dt``).
    """
    steps = duration / dt
    if steps > MAX_STEPS:
        raise ScenarioError(source, f"{table}.dt", f"duration / dt = {steps:.3g} steps; at most "
                            f"{MAX_STEPS:.0e} per run (dt >= {duration / MAX_STEPS:.3g} s for "
                            f"a duration of {duration:g} s)")
    if record_dt is not None and duration / record_dt > MAX_SAMPLES:
        raise ScenarioError(source, f"{table}.record_dt", f"duration / record_dt = "
                            f"{duration / record_dt:.3g} samples; at most {MAX_SAMPLES:.0e} "
                            f"(record_dt >= {duration / MAX_SAMPLES:.3g} s)")


def load_scenario(path: str | Path) -> tuple[dict, str, str]:
    """Read a TOML scenario file: returns ``(data, source, text)`` (see :func:`read_toml`); an
    older-dialect key gets one line naming its replacement
    (:func:`downhole.scenario.schema.read_scenario`)."""
    from downhole.scenario.schema import read_scenario

    return read_scenario(path)


def model_type(data: dict, source: str) -> str:
    """The runner of a scenario, from its ``[model] fidelity`` and what it describes:

    - ``"system"``: a described system (``[well]`` and ``[string]``, no ``[model] preset``, no
      ``[controller]``), run at any fidelity (:mod:`downhole.scenario.system`);
    - ``"lumped4"`` / ``"lumped12"``: a lumped preset (Table 2.1, ...);
    - ``"neutral"``: a neutral preset (Table 3.1), open loop or with the EID controller;
    - ``"fem"`` / ``"hybrid"``: a directional preset (Table 5.1, optionally with a described
      well and string) with its top-drive controller (:mod:`downhole.scenario.directional`);
    - ``"dhp"``: ``[controller] type = "dhp"`` without a saved ``file`` (train, then run);
    - a registered plug-in name (:func:`register_model_type`) given as ``[model] fidelity``.
    """
    from downhole.scenario.schema import check_dialect

    check_dialect(data, source)
    model = data.get("model", {})
    if not isinstance(model, dict):
        raise ScenarioError(source, "model", "expected a table [model]")
    _load_plugins()
    from downhole.scenario.dhp import is_dhp_dialect

    if is_dhp_dialect(data):  # [controller] type = "dhp" with its design: downhole.scenario.dhp
        return "dhp"
    names = [k for k in MODEL_TYPES if k not in ("dhp", "system")]
    if "fidelity" not in model:
        raise ScenarioError(source, "model.fidelity", "required field is missing "
                            f"(one of {', '.join(names)})")
    fid = model["fidelity"]
    if not isinstance(fid, str) or fid not in names:
        raise ScenarioError(source, "model.fidelity", f"unknown fidelity {fid!r}; expected "
                            f"one of {', '.join(names)}")
    described = "well" in data or "string" in data
    if fid in ("lumped4", "lumped12", "neutral"):
        return "system" if described else fid
    if fid in ("fem", "hybrid"):
        rig = data.get("rig")
        hook_mode = isinstance(rig, dict) and isinstance(rig.get("hook"), dict) \
            and "mode" in rig["hook"]
        if described and "preset" not in model and "controller" not in data and not hook_mode:
            return "system"
        return fid
    return fid


def is_lumped_type(mtype: str) -> bool:
    """True for the built-in lumped types, whose full schema is :class:`LumpedScenario` (the
    other types' schemas live with their runners)."""
    return MODEL_TYPES.get(mtype) is _run_lumped


def _check_override(mtype: str, fidelity: str | None, source: str) -> None:
    if fidelity is not None and mtype != "system":
        raise ScenarioError(source, "model.fidelity", f"--fidelity {fidelity} needs a file "
                            "that describes the system ([well] and [string], without [model] "
                            "preset or [controller]); this one runs a preset or a controller "
                            f"at fidelity {mtype!r}")


def validate_data(data: dict, source: str, fidelity: str | None = None) -> str:
    """Validate a parsed scenario without running it: its model type, then the type's full
    schema, model and run settings (system description at its fidelity, lumped, neutral,
    FEM / hybrid, DHP; a registered plug-in type only by name). ``fidelity`` overrides a system
    scenario's ``[model] fidelity``. Returns the model type; raises :class:`ScenarioError`."""
    check_values(data, source)
    mtype = model_type(data, source)
    _check_override(mtype, fidelity, source)
    if mtype == "system":
        from downhole.scenario.system import validate_system_scenario

        validate_system_scenario(data, source, fidelity)
    elif is_lumped_type(mtype):
        validate_lumped(data, source)
    elif mtype in _VALIDATORS:
        import importlib

        module, func = _VALIDATORS[mtype]
        getattr(importlib.import_module(module), func)(data, source)
    return mtype


def _validate_dhp(data: dict, source: str):
    from downhole.scenario.dhp import parse_dhp_scenario

    base = Path(source).parent if not source.startswith("<") else None
    return parse_dhp_scenario(data, source, "", base=base)


#: Validators (without running) of the built-in non-lumped model types: module, function.
_VALIDATORS: dict[str, tuple[str, str]] = {
    "neutral": ("downhole.scenario.neutral", "validate_neutral_scenario"),
    "fem": ("downhole.scenario.directional", "validate_directional_scenario"),
    "hybrid": ("downhole.scenario.directional", "validate_directional_scenario"),
    "dhp": ("downhole.scenario", "_validate_dhp"),
}


def validate_scenario(path: str | Path, fidelity: str | None = None) -> None:
    """Validate a scenario file without running it (raises :class:`ScenarioError`);
    ``fidelity`` overrides a system scenario's ``[model] fidelity``."""
    data, source, _ = load_scenario(path)
    validate_data(data, source, fidelity)


def run_scenario(path_or_data: str | Path | dict, source: str = "<dict>",
                 fidelity: str | None = None) -> Result:
    """Run a scenario file (or an already-parsed dict) and return its Result.

    Parameters
    ----------
    path_or_data : str, Path or dict
        The scenario file, or its parsed content.
    source : str
        Name used in messages for a dict.
    fidelity : str, optional
        Overrides ``[model] fidelity`` of a system scenario (``lumped4``, ``lumped12``,
        ``neutral``, ``fem``, ``hybrid``); refused for the older ``[model] type`` files.
    """
    if isinstance(path_or_data, dict):
        import tomli_w

        check_values(path_or_data, source)
        data, text = path_or_data, tomli_w.dumps(path_or_data)
    else:
        data, source, text = load_scenario(path_or_data)
    mtype = model_type(data, source)
    _check_override(mtype, fidelity, source)
    if mtype == "system":
        from downhole.scenario.system import run_system_scenario

        return run_system_scenario(data, source, text, fidelity)
    return MODEL_TYPES[mtype](data, source, text)


_PLUGINS_LOADED = False


def _load_plugins() -> None:
    """Import the modules that register further model types (neutral, FEM, hybrid, ...)."""
    global _PLUGINS_LOADED
    if _PLUGINS_LOADED:
        return
    _PLUGINS_LOADED = True
    import importlib

    for mod in ("downhole.scenario.types",):
        try:
            importlib.import_module(mod)
        except ModuleNotFoundError as exc:
            if exc.name != mod:
                raise
