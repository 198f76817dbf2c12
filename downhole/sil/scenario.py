"""SIL scenario files (TOML): the plant, the real-time runtime, the controller, the reference,
the link, the safety policy and the dashboard, read with the one scenario schema
(:mod:`downhole.scenario.schema`: :func:`~downhole._schema.parse` and its
:class:`~downhole._schema.Scenario`).

Every table is optional; numbers may carry units ("1 ms", "10 rad/s", "120 kN"). Unknown keys
are errors naming the file and the dotted field; a key of the older SIL dialect (``[plant]``,
``[runtime]``, ``kind``, ``name``, ``reference.axial``) gets one line naming its replacement.
Example (``examples/sil_dhp_hybrid68.toml``)::

    title = "DHP on the 68-state hybrid"

    [model]
    fidelity = "hybrid"         # hybrid | fem | lumped4 | lumped12 | neutral
    preset = "hybrid68"         # hybrid: hybrid24 | hybrid68 | hybrid108; lumped: table_2_1
    interface = "state"         # surface (PI top drive + hook load) | state (DHP)

    [bit]
    epsilon = "45 MPa"          # any bit parameter, over the model's preset

    [operation]
    wob = "120 kN"              # initial commands: wob, surface_speed, surface_torque, rop

    [simulation]
    dt = "1 ms"
    duration = "20 s"
    depth_of_cut = "delayed"

    [realtime]
    paced = true                # pace to the wall clock (max_lag, wait_fraction, ...)

    [controller]
    type = "dhp"                # none | pi | dhp | file (a .py file runs only with --allow-code)
    [controller.dhp]
    design = "hybrid24"         # the 24-state FEM the controller is trained on
    weights = "planned"
    [controller.dhp.training]
    horizon = "30 s"
    n_samples = 50

    [reference]
    type = "step"               # the DHP training reference: step | sine | ramp
    axial_velocity = "10 mm/s"
    angular_velocity = "20 rad/s"

    [link]
    port = 47600

:func:`parse_sil_scenario` returns the one schema's :class:`~downhole._schema.Scenario` with
what that schema leaves to the reading command (its None defaults) resolved to the SIL's:

- ``model.fidelity``: a file without ``[model]``, or whose ``[model]`` gives no fidelity, is
  read as ``fidelity = "hybrid"`` (filled in before parsing: the one schema requires it);
  ``model.preset``: the hybrid's is one of hybrid24 | hybrid68 | hybrid108 (None: hybrid68),
  the fem and neutral plants take none (the seed's), a lumped plant's is a lumped preset (None:
  table_2_1); ``model.fem.n_elements``: 23;
- ``[operation]``: ``wob`` 120 kN, ``surface_speed`` 10 rad/s, ``surface_torque`` 0, ``rop``
  10 mm/s; constants only (a ``[[t, value], ...]`` profile is refused naming the key);
  ``mode`` only ``"velocity"`` of a lumped plant (what it is: velocity-driven);
- ``simulation.integrator``: only ``"euler"`` of a lumped plant (its scheme);
- ``[simulation]``: ``dt`` 1 ms (the real-time period), ``duration`` 20 s, ``record_dt`` 10 ms;
- ``controller.type``: "pi" (the SIL runs none | pi | dhp | file); ``[controller.dhp]``:
  ``design`` hybrid24 (hybrid24 | hybrid68), ``weights`` "robust" (robust | design | planned),
  ``training.horizon`` 8 s, ``training.n_samples`` 50 (at least 2);
- ``[reference]``: ``type`` "step" (step | sine | ramp), ``axial_velocity`` 10 mm/s,
  ``angular_velocity`` 20 rad/s (constants); the ``*_min`` / ``*_max`` bounds the one schema's;
- ``title``: "sil".

A key of the one schema that the SIL does not read (``[well]``, ``[rig]``, ``model.friction``,
``simulation.integrator``, ``controller.dhp.plan``, ...) is refused naming it, not ignored
(:data:`SIL_KEYS` lists what the SIL reads). See ``docs/sil.md`` for every field.
"""

from __future__ import annotations

import math
from pathlib import Path

from pydantic import ValidationError

from downhole._schema import (
    FIDELITIES,
    ReferenceTable,
    Scenario,
    SimulationTable,
    check_dialect,
    parse,
    raise_validation,
)
from downhole.errors import ScenarioError

__all__ = [
    "SIL_KEYS",
    "build_from_scenario",
    "check_code_allowed",
    "dashboard_token",
    "load_sil_scenario",
    "parse_sil_scenario",
]

#: The tables and keys the SIL reads (dotted table -> its keys; "" the top level). A key of the
#: one schema outside these is refused: the SIL would ignore it.
SIL_KEYS: dict[str, tuple[str, ...]] = {
    "": ("title", "description", "model", "bit", "operation", "simulation", "realtime",
         "controller", "reference", "link", "safety", "dashboard"),
    "model": ("fidelity", "preset", "interface", "fem"),
    "model.fem": ("n_elements",),
    "operation": ("wob", "surface_speed", "surface_torque", "rop", "mode"),
    "simulation": ("dt", "duration", "record_dt", "depth_of_cut", "start", "integrator"),
    "controller.dhp": ("design", "weights", "training"),
    "controller.dhp.training": ("horizon", "n_samples"),
    "reference": ("type", "axial_velocity", "angular_velocity", "axial_velocity_min",
                  "axial_velocity_max", "angular_velocity_min", "angular_velocity_max"),
}

#: The SIL's values for what the one schema leaves to the reading command (None there).
_OPERATION = {"wob": 120e3, "surface_speed": 10.0, "surface_torque": 0.0, "rop": 0.01}
_SIMULATION = {"dt": 1e-3, "duration": 20.0, "record_dt": 0.01}
_REFERENCE = {"axial_velocity": 0.01, "angular_velocity": 20.0}
_CONTROLLERS = ("none", "pi", "dhp", "file")
_DHP_DESIGNS = ("hybrid24", "hybrid68")
_DHP_WEIGHTS = ("robust", "design", "planned")
_REFERENCES = ("step", "sine", "ramp")


def _with_fidelity(data: dict) -> dict:
    """``data`` with ``model.fidelity = "hybrid"`` when the file gives none (a copy; the SIL's
    default plant, which the one schema leaves to no command)."""
    model = data.get("model", {})
    if not isinstance(model, dict) or "fidelity" in model:
        return data
    return {**data, "model": {"fidelity": "hybrid", **model}}


#: What the SIL reads besides :data:`SIL_KEYS` of a file that describes its system.
DESCRIBED_KEYS = {"": ("well", "string", "rig", "torque_drag"),
                  "model": ("friction", "rayleigh_alpha", "rayleigh_beta", "lump_length",
                            "wave_section", "lumped4", "lumped12", "neutral", "hybrid")}


def _refuse_unread(sc: Scenario, source: str) -> None:
    """Refuse a key of the one schema that the SIL does not read (:data:`SIL_KEYS`; a
    described system's also :data:`DESCRIBED_KEYS`)."""
    tables = {"": sc, "model": sc.model, "model.fem": sc.model.fem,
              "operation": sc.operation, "simulation": sc.simulation, "reference": sc.reference}
    if sc.controller.type == "dhp":
        tables["controller.dhp"] = sc.controller.options.dhp
        tables["controller.dhp.training"] = sc.controller.options.dhp.training
    for path, table in tables.items():
        if table is None:
            continue
        reads = SIL_KEYS[path] + (DESCRIBED_KEYS.get(path, ()) if sc.described else ())
        for key in type(table).model_fields:  # in the schema's order
            if key in table.model_fields_set and key not in reads:
                where = f"[{path}]" if path else "the top level"
                raise ScenarioError(source, f"{path}.{key}" if path else key,
                                    f"not read by the SIL (it reads {', '.join(reads)} at "
                                    f"{where}; see docs/sil.md)")


def _constant(table, key: str, default: float, source: str, path: str) -> None:
    """Resolve ``table.key`` (None: ``default``); a ``[[t, value], ...]`` profile is refused."""
    value = getattr(table, key)
    if isinstance(value, tuple):
        raise ScenarioError(source, f"{path}.{key}", "a constant here: the SIL takes one value "
                            "(a [[t, value], ...] profile is not supported)")
    if value is None:
        setattr(table, key, default)


def _resolve(sc: Scenario, source: str) -> None:
    """Check what the SIL takes of the one schema and resolve its None defaults to the SIL's
    (the module docstring lists them), in place."""
    from downhole.string.hybrid import HYBRID_PRESETS

    if not sc.title:
        sc.title = "sil"
    m = sc.model
    if m.fidelity not in FIDELITIES:
        raise ScenarioError(source, "model.fidelity", f"expected one of {', '.join(FIDELITIES)}, "
                            f"got {m.fidelity!r}")
    if m.fidelity == "hybrid" and m.preset is not None and m.preset not in HYBRID_PRESETS:
        raise ScenarioError(source, "model.preset", f"the hybrid's preset is one of "
                            f"{', '.join(HYBRID_PRESETS)}, got {m.preset!r}")
    if m.fidelity in ("fem", "neutral") and m.preset is not None:
        raise ScenarioError(source, "model.preset", f"the {m.fidelity} plant is the seed's "
                            f"(Table {'5.1' if m.fidelity == 'fem' else '3.1'}); no preset here")
    if sc.described:
        _described_rules(sc, source)
    elif m.fem.n_elements is None:
        m.fem.n_elements = 23
    if sc.operation.mode is not None and (not m.fidelity.startswith("lumped")
                                          or sc.operation.mode != "velocity"):
        why = ("its lumped plant is velocity-driven (mode = 'velocity' only)"
               if m.fidelity.startswith("lumped") else "a lumped plant's key")
        raise ScenarioError(source, "operation.mode", f"{sc.operation.mode!r} is not read by "
                            f"the SIL at fidelity {m.fidelity!r}: {why} (see docs/sil.md)")
    sim_set = sc.simulation.model_fields_set if sc.simulation is not None else set()
    if "integrator" in sim_set and (not m.fidelity.startswith("lumped") or sc.described
                                    or sc.simulation.integrator != "euler"):
        why = ("its lumped plant steps with explicit Euler (integrator = 'euler' only)"
               if m.fidelity.startswith("lumped") else "each plant has its own scheme")
        raise ScenarioError(source, "simulation.integrator", f"{sc.simulation.integrator!r} is "
                            f"not read by the SIL at fidelity {m.fidelity!r}: {why} (see "
                            "docs/sil.md)")
    for key, default in _OPERATION.items():
        _constant(sc.operation, key, default, source, "operation")
    if sc.simulation is None:
        sc.simulation = SimulationTable()
    for key, default in _SIMULATION.items():
        if getattr(sc.simulation, key) is None:
            setattr(sc.simulation, key, default)
    ctl = sc.controller
    if ctl.type is None:
        ctl.type = "pi"
    if ctl.type not in _CONTROLLERS:
        raise ScenarioError(source, "controller.type", f"the SIL runs {' | '.join(_CONTROLLERS)}"
                            f", got {ctl.type!r}")
    if ctl.type == "dhp":
        d = ctl.options.dhp
        d.design = d.design or "hybrid24"
        if d.design not in _DHP_DESIGNS:
            raise ScenarioError(source, "controller.dhp.design", f"the SIL's DHP designs are "
                                f"{' | '.join(_DHP_DESIGNS)}, got {d.design!r}")
        d.weights = "robust" if d.weights is None else d.weights
        if d.weights not in _DHP_WEIGHTS:
            raise ScenarioError(source, "controller.dhp.weights", f"the SIL's weights are "
                                f"{' | '.join(_DHP_WEIGHTS)} (a named set), got {d.weights!r}")
        t = d.training
        t.horizon = 8.0 if t.horizon is None else t.horizon
        t.n_samples = 50 if t.n_samples is None else t.n_samples
        if t.n_samples < 2:
            raise ScenarioError(source, "controller.dhp.training.n_samples",
                                f"at least 2 samples, got {t.n_samples}")
        if d.weights == "planned":
            from downhole.control.dhp.plan import PlanSettings

            plan = PlanSettings().duration
            if plan >= t.horizon:  # checked by the trainer only after the design
                raise ScenarioError(source, "controller.dhp.training.horizon", f"{t.horizon:g} "
                                    f"s: weights = 'planned' plans a {plan:g} s start-up, which "
                                    "must be shorter than the trained horizon")
    if sc.reference is None:
        sc.reference = ReferenceTable()
    r = sc.reference
    r.type = r.type or "step"
    if r.type not in _REFERENCES:
        raise ScenarioError(source, "reference.type", f"the SIL's references are "
                            f"{' | '.join(_REFERENCES)}, got {r.type!r}")
    for key, default in _REFERENCE.items():
        _constant(r, key, default, source, "reference")


def _described_rules(sc: Scenario, source: str) -> None:
    """What the SIL takes of a described system: its plant is the system's model at
    ``[model] fidelity`` under the rig (the top drive's PI at ``surface_speed``, a force hook
    at ``wob``), the surface interface, no preset."""
    m = sc.model
    if m.preset is not None:
        raise ScenarioError(source, "model.preset", "a described system ([well], [string]) is "
                            "its own plant: no preset")
    if m.interface != "surface":
        raise ScenarioError(source, "model.interface", "a described system's SIL plant has the "
                            "surface interface (the rig's top drive and hook); the state "
                            "interface is the DHP design FEM's (a hybrid preset)")
    if sc.controller.type == "dhp":
        raise ScenarioError(source, "controller.type", "the SIL's DHP runs on a hybrid "
                            "preset's state interface, not on a described system")
    if sc.link.mode == "hil":
        raise ScenarioError(source, "link.mode", "the HIL rig's plant is a preset's; a "
                            "described system runs in software")


def _system_plant(sc: Scenario, source: str):
    """The SIL plant of a described system: its model at ``[model] fidelity`` under the rig."""
    from downhole.errors import DownholeInputError
    from downhole.scenario.system import DESCRIBED, _build_options, build_system
    from downhole.sil.plants import rig_plant

    fid = sc.model.fidelity
    system = build_system(sc, source, fid)
    try:
        model = system.build(fid, **_build_options(sc, fid))
    except DownholeInputError as exc:
        raise ScenarioError(source, "model.fidelity", f"{fid}: {exc}") from None
    td, hk = sc.rig.top_drive, sc.rig.hook
    op, sim = sc.operation, sc.simulation
    return rig_plant(model, sim.dt, inertia=DESCRIBED["inertia"] if td.inertia is None
                     else td.inertia, kp=DESCRIBED["kp"] if td.kp is None else td.kp,
                     ki=DESCRIBED["ki"] if td.ki is None else td.ki,
                     speed=op.surface_speed, wob=op.wob, servo_stiffness=hk.servo_stiffness,
                     servo_damping=hk.servo_damping, block_mass=hk.block_mass,
                     depth_of_cut=sim.depth_of_cut, name=f"{sc.title or 'described'} ({fid})")


def _plant_name(sc: Scenario) -> str:
    """The name :func:`downhole.sil.plants.build_plant` takes for ``[model]``."""
    m = sc.model
    if m.fidelity == "hybrid":
        return m.preset or "hybrid68"
    if m.fidelity.startswith("lumped"):
        return "lumped"
    return m.fidelity


def _dhp_design(sc: Scenario) -> str:
    """The design model a state-interface plant observes: ``[controller.dhp] design`` of a DHP
    controller, else hybrid24."""
    return sc.controller.options.dhp.design if sc.controller.type == "dhp" else "hybrid24"


def parse_sil_scenario(data: dict, source: str = "<dict>") -> Scenario:
    """Validate a parsed SIL scenario with the one schema and resolve the SIL's defaults.

    Parameters
    ----------
    data : dict
        The parsed file (a missing ``model.fidelity`` is read as "hybrid").
    source : str
        The file, for messages.

    Returns
    -------
    Scenario
        The one schema's scenario, its None defaults resolved to the SIL's (module docstring).

    Raises
    ------
    ScenarioError
        Naming the file and the dotted field: an older-dialect, unknown or unread key, a value
        the SIL does not take, an unstable lumped step, an inconsistent controller / interface.
    """
    check_dialect(data, source)
    sc = parse(_with_fidelity(data), source)
    _refuse_unread(sc, source)
    _resolve(sc, source)
    if not sc.described:
        scenario_bit(sc, source)
    if sc.model.fidelity.startswith("lumped") and sc.link.mode != "hil" and not sc.described:
        _check_lumped_step(sc, source)
    if sc.controller.type == "file" and not sc.controller.file:
        raise ScenarioError(source, "controller.file", "type = 'file' needs a file path")
    r = sc.reference
    for name, lo, hi, v in (("axial_velocity", r.axial_velocity_min, r.axial_velocity_max,
                             r.axial_velocity),
                            ("angular_velocity", r.angular_velocity_min,
                             r.angular_velocity_max, r.angular_velocity)):
        if not all(math.isfinite(x) for x in (lo, hi, v)):
            raise ScenarioError(source, f"reference.{name}", "must be finite")
        if not lo < hi:
            raise ScenarioError(source, f"reference.{name}_min",
                                f"must be below {name}_max ({lo:g} >= {hi:g}, SI units)")
        if not lo <= v <= hi:
            raise ScenarioError(source, f"reference.{name}",
                                f"{v:g} is outside [{name}_min, {name}_max] = [{lo:g}, {hi:g}] "
                                "(SI units)")
    d = sc.dashboard
    if d.token is not None and d.token_file is not None:
        raise ScenarioError(source, "dashboard.token_file", "give token or token_file, not both")
    if d.token is not None and (not d.token or any(ch.isspace() for ch in d.token)):
        raise ScenarioError(source, "dashboard.token", "must be non-empty, without whitespace")
    for o in d.allowed_origins:
        if not (o.startswith(("http://", "https://"))) or o.rstrip("/") != o:
            raise ScenarioError(source, "dashboard.allowed_origins",
                                f"{o!r} is not an origin (scheme://host[:port], no path)")
    directional = sc.model.fidelity in ("fem", "hybrid")
    if sc.controller.type == "dhp" and (sc.model.interface != "state" or not directional):
        raise ScenarioError(source, "model.interface",
                            "a DHP controller needs a fem or hybrid plant with interface = "
                            "'state'")
    if sc.controller.type == "pi" and sc.model.interface == "state" and directional:
        raise ScenarioError(source, "controller.type",
                            "the PI needs interface = 'surface' (speed-controlled top drive)")
    return sc


def scenario_bit(sc: Scenario, source: str = "<dict>"):
    """The plant's bit: its preset's (Table 2.1, 3.1 or 5.1) with ``[bit]`` applied, or None
    without a ``[bit]`` table. Raises :class:`ScenarioError` naming ``bit.<field>``."""
    if not sc.bit:
        return None
    from downhole.params import BitParams, get_preset

    if "preset" in sc.bit:
        raise ScenarioError(source, "bit.preset", "the SIL plant's bit is its model's; give bit "
                            "parameters only (epsilon, ...)")
    fid = sc.model.fidelity
    base = {"neutral": "table_3_1", "fem": "table_5_1", "hybrid": "table_5_1"}.get(
        fid, sc.model.preset or "table_2_1")
    try:
        return BitParams(**{**get_preset(base).bit.model_dump(), **sc.bit})
    except ValidationError as exc:
        raise_validation(source, exc, "bit.")
    except (TypeError, ValueError) as exc:
        raise ScenarioError(source, "bit", str(exc)) from None


def _check_lumped_step(sc: Scenario, source: str) -> None:
    """The lumped SIL plant steps with explicit Euler: ``simulation.dt`` must be below its
    stability bound (:func:`downhole.scenario.euler_stable_dt`)."""
    from downhole.params import get_preset
    from downhole.scenario import euler_stable_dt
    from downhole.string.lumped import lumped_model

    name = sc.model.preset or "table_2_1"
    try:
        preset = get_preset(name)
    except KeyError as exc:
        raise ScenarioError(source, "model.preset", str(exc.args[0])) from None
    if preset.kind != "lumped":
        raise ScenarioError(source, "model.preset", f"preset {name!r} is a {preset.kind} "
                            "model, expected a lumped one")
    order = 4 if sc.model.fidelity == "lumped4" else 12
    bit = scenario_bit(sc, source)
    lm = lumped_model(name, order=order) if bit is None else \
        lumped_model(preset.string, bit, order=order)
    bound, mode = euler_stable_dt(lm)
    if sc.simulation.dt >= bound:
        raise ScenarioError(source, "simulation.dt", f"dt = {sc.simulation.dt:g} s is too "
                            f"large for the lumped plant's explicit Euler: stable only for dt "
                            f"< {bound:.4g} s (2 zeta / omega of the {mode['field']} mode at "
                            f"{mode['frequency']:.4g} rad/s)")


def load_sil_scenario(path) -> Scenario:
    """Read and validate a SIL scenario TOML file (:func:`downhole.scenario.schema.
    read_scenario`: an older-dialect key gets one line naming its replacement).

    Parameters
    ----------
    path : str or Path
        The scenario file; ``controller.file``, ``dashboard.token_file`` and a described
        well's ``survey`` are relative to its folder.

    Returns
    -------
    Scenario
        As :func:`parse_sil_scenario` returns it.

    Raises
    ------
    ScenarioError
        An unreadable or invalid file (naming the file and the dotted field).
    """
    from downhole._schema import read_scenario

    path = Path(path)
    data, source, _ = read_scenario(path)
    sc = parse_sil_scenario(data, source)
    if sc.controller.file and not Path(sc.controller.file).is_absolute():
        sc.controller.file = str(path.parent / sc.controller.file)
    if sc.dashboard.token_file and not Path(sc.dashboard.token_file).is_absolute():
        sc.dashboard.token_file = str(path.parent / sc.dashboard.token_file)
    if sc.well is not None and sc.well.survey and not Path(sc.well.survey).is_absolute():
        sc.well.survey = str(path.parent / sc.well.survey)
    return sc


def dashboard_token(sc: Scenario) -> str | None:
    """The dashboard token of ``sc``: ``[dashboard] token``, the first line of ``token_file``,
    or None.

    Raises
    ------
    ScenarioError
        The token file is missing, unreadable or empty.
    """
    d = sc.dashboard
    if d.token_file is None:
        return d.token
    try:
        text = Path(d.token_file).read_text()
    except OSError as exc:
        raise ScenarioError(d.token_file, "", f"cannot read the dashboard token file "
                            f"([dashboard] token_file): {exc.strerror or exc}") from None
    token = text.strip().splitlines()[0].strip() if text.strip() else ""
    if not token or any(ch.isspace() for ch in token):
        raise ScenarioError(d.token_file, "", "the dashboard token file must hold one token "
                            "(a line without spaces)")
    return token


def _dhp(sc: Scenario, plant, progress: bool = False, source: str = "<scenario>"):
    from downhole.scenario.dhp import training_errors

    with training_errors(source):
        return _design_dhp(sc, plant, progress)


def _design_dhp(sc: Scenario, plant, progress: bool = False):
    from downhole.control.dhp import BitReference, DHPSettings, PenaltyWeights, design_dhp
    from downhole.control.dhp.weight_sets import weight_set

    d = sc.controller.options.dhp
    t = d.training
    r = sc.reference
    ref = {"step": BitReference.step(r.axial_velocity, r.angular_velocity),
           "sine": BitReference.sine(), "ramp": BitReference.ramp(t_final=t.horizon)}[r.type]
    if d.weights == "planned":
        # the start-up planned on the design FEM, soft gains about it (docs/dhp.md)
        from downhole.control.dhp.plan import design_dhp_planned
        from downhole.string.hybrid import hybrid_model

        return design_dhp_planned(plant.plant.design, hybrid_model(d.design).design_model(),
                                  ref, horizon=t.horizon,
                                  weights=PenaltyWeights(**weight_set("planned")),
                                  settings=DHPSettings(n_samples=t.n_samples),
                                  progress=progress)
    return design_dhp(plant.plant.design, ref, horizon=t.horizon,
                      weights=PenaltyWeights(**weight_set(d.weights)),
                      settings=DHPSettings(n_samples=t.n_samples), progress=progress)


def scenario_controller_file(sc: Scenario, controller_file: str | None = None) -> str | None:
    """The controller file a run would load: ``controller_file`` (command line) or
    ``[controller] file``."""
    return controller_file or sc.controller.file


def check_code_allowed(sc: Scenario, *, controller_file: str | None = None,
                       allow_code: bool = False) -> None:
    """Refuse, before anything is built, a Python controller file without the opt-in.

    Raises
    ------
    DownholeInputError
        The controller would come from a ``.py`` file and ``allow_code`` is not True (the
        message names ``--allow-code``).
    """
    from downhole.errors import DownholeInputError
    from downhole.sil.controllers import CODE_REFUSED

    file = scenario_controller_file(sc, controller_file)
    if file and Path(file).suffix == ".py" and allow_code is not True:
        raise DownholeInputError(CODE_REFUSED.format(path=file))


def build_from_scenario(sc: Scenario, *, controller_file: str | None = None,
                        with_controller: bool = True, allow_code: bool = False,
                        progress: bool = False, source: str = "<scenario>"):
    """``(plant, controller)`` for a scenario (controller None for ``type = "none"``, for
    ``remote = true`` or when ``with_controller`` is False).

    Parameters
    ----------
    sc : Scenario
        As :func:`load_sil_scenario` returns it (its SIL defaults resolved).
    controller_file : str, optional
        Overrides ``[controller] file``.
    with_controller : bool
        Build the controller (False: the plant only).
    allow_code : bool, keyword-only
        Allow a Python controller file (``type = "file"``, ``file = "x.py"``) to run. Without
        it such a scenario is refused before anything is built: a scenario alone never
        executes code.
    progress : bool
        Show the DHP design's progress bars (``type = "dhp"``).
    source : str
        The file, for messages (a DHP design's training settings the trainer refuses).

    Raises
    ------
    DownholeInputError
        A Python controller file without ``allow_code`` (see :func:`check_code_allowed`).
    """
    from downhole.sil.controllers import load_controller_file, pi_controller_for
    from downhole.sil.plants import build_plant

    building = with_controller and not sc.controller.remote
    if building:
        check_code_allowed(sc, controller_file=controller_file, allow_code=allow_code)
    m, op, sim = sc.model, sc.operation, sc.simulation
    if sc.described:  # the system's model at its fidelity, under the rig
        plant = _system_plant(sc, source)
    elif sc.link.mode == "hil":
        from downhole.sil.hil import build_hil_plant

        plant = build_hil_plant(_plant_name(sc), dt=sim.dt, wob=op.wob,
                                surface_torque=op.surface_torque)
    else:
        plant = build_plant(_plant_name(sc), interface=m.interface, dt=sim.dt,
                            depth_of_cut=sim.depth_of_cut, wob=op.wob,
                            top_drive_speed=op.surface_speed, surface_torque=op.surface_torque,
                            design=_dhp_design(sc), n_elements=m.fem.n_elements,
                            lumped_preset=m.preset or "table_2_1",
                            order=4 if m.fidelity == "lumped4" else 12,
                            axial_velocity=op.rop, bit=scenario_bit(sc))
    if sim.start != "rest" and sc.link.mode != "hil":
        from downhole.errors import DownholeInputError

        # the start is computed for the plant's open-loop commands ([operation])
        plant.default_start = {"start": sim.start, "set_point": plant.default_command()}
        try:
            plant.reset()
        except DownholeInputError as exc:
            raise DownholeInputError(f"simulation.start = {sim.start!r}: {exc}") from None
    ctrl = None
    kind = sc.controller.type
    file = scenario_controller_file(sc, controller_file)
    if building:
        if file:
            ctrl = load_controller_file(file, plant, allow_code=allow_code)
        elif kind == "pi":
            ctrl = pi_controller_for(plant)
        elif kind == "dhp":
            ctrl = _dhp(sc, plant, progress=progress, source=source)
    return plant, ctrl
