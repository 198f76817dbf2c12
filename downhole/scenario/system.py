"""Scenario files that describe the drilling system once and choose the model fidelity.

``[model] fidelity = "lumped4" | "lumped12" | "neutral" | "fem" | "hybrid"`` selects this dialect
(``downhole simulate FILE --fidelity NAME`` overrides the file's choice). The well, the string,
the bit and the rig are described once and turned into a :class:`~downhole.system.DrillingSystem`,
which builds the model of the chosen fidelity; the run uses that fidelity's simulate function with
the scenario's set-points. Schema (``docs/scenarios.md``, "Describing the system")::

    title = "..."
    [model]
    fidelity = "fem"              # lumped4 | lumped12 | neutral | fem | hybrid
    friction = 0.0                # wellbore friction; > 0 in a deviated well: fem / hybrid only
    rayleigh_alpha = 0.05         # 1/s   string damping alpha0 M + beta0 K
    rayleigh_beta = 0.03          # s
    lump_length = "10 m"          # neutral, no BHA: bottom length lumped into the bit
    wave_section = ["2000 m", "3000 m"]   # hybrid: MD of B and C (default: DrillingSystem's)
    [model.fem]                   # per-fidelity options (each table optional)
    n_elements = 107              # default: the mesh derived from the description (nodes at
    max_element_length = "50 m"   #   every joint and survey station where the path turns,
    max_element_angle = "2 deg"   #   elements <= 50 m and turning by <= 2 deg)
    mass = "consistent"           # or "lumped"
    [model.hybrid]
    preset = "hybrid68"           # or n_ab / n_cd (nodes on AB / CD); default: derived mesh
    n_lags = 0                    # also max_element_length, max_element_angle, mass
    [model.lumped4]               # and [model.lumped12]
    reference_elements = 400      # FEM whose first frequency the chain matches
    [model.neutral]
    lump = ["heavyweight"]        # kinds lumped into the bit besides collars / bha
    # every per-fidelity table also takes `friction`, overriding [model] friction there

    [well]                        # sections, md/inclination/azimuth lists or a survey CSV
    [string]                      # mud_density, [[string.segments]] (required), stabilizers
    [bit]                         # preset = "table_5_1" (default) + BitParams fields, law = ...
    [rig.top_drive]               # inertia, kp, ki (PI speed controller)
    [rig.hook]                    # servo_stiffness, servo_damping, block_mass

    [operation]
    surface_speed = "10 rad/s"    # top-drive speed set-point
    rop = "10 mm/s"               # or wob = "80 kN" (exactly one)

    [torque_drag]                 # optional: `downhole torque-drag` (docs/torque-drag.md)
    friction_factors = [0.1, 0.2, 0.3]
    step = "10 m"                 # largest element length
    vertical_section_azimuth = "30 deg"   # default: the closure azimuth
    wob = "100 kN"                # drilling case; default: the [operation] set-point's WOB
    tob = "5 kN*m"                # default: the bit law's TOB at that WOB and surface speed

    [simulation]
    duration = "10 s"
    dt = "1 ms"                   # default per fidelity (lumped 0.5 ms, neutral 0.1 ms, FEM 1 ms)
    record_dt = "10 ms"
    depth_of_cut = "delayed"      # or "approximate"
    start = "rest"                # rest | off_bottom | steady (where the fidelity supports it)
    integrator = "newmark"        # the only scheme of a described system (the rig's node)

The rig is the same actuator at every fidelity: the PI top drive at ``surface_speed`` and the
hook (a velocity servo at ``rop``, or a force servo at ``wob``) act on the model's top node;
the lumped chains and the neutral line run under the rig's node (docs/scenarios.md, "The rig
at every fidelity"). A ``wob`` set-point gives the ROP of the steady bit state and a ``rop`` the
steady WOB for the initial state.
"""

from __future__ import annotations

from types import SimpleNamespace

from pydantic import ValidationError

from downhole import _schema
from downhole._schema import DEFAULT_DT  # noqa: F401 -- re-exported (sil.fmu)
from downhole.errors import DownholeInputError, ScenarioError
from downhole.scenario import _raise_validation, check_step_count
from downhole.scenario.directional import _string, _well
from downhole.system import steady_bit_state

__all__ = [
    "FIDELITY_NAMES",
    "RENAMED",
    "SYSTEM_KEYS",
    "build_system",
    "check_fidelity",
    "is_system_dialect",
    "load_dp_problem",
    "lumped_design_model",
    "neutral_design_model",
    "parse_system",
    "run_system_scenario",
    "steady_bit_state",
    "validate_system_scenario",
]

#: The fidelities a system scenario can run at (:data:`downhole.system.FIDELITIES`).
FIDELITY_NAMES = ("lumped4", "lumped12", "neutral", "fem", "hybrid")

#: Keys of a preset file that a described system replaces (the older dialects' keys are
#: refused for every file by :func:`downhole.scenario.schema.check_dialect`).
RENAMED = {
    "model.preset": "bit.preset (the bit) and [well] / [string] (the well and string); a preset "
                    "file has no [well] / [string]",
    "model.string": "[string] (segments) and [rig]",
}


def check_fidelity(name, source: str, field: str = "model.fidelity") -> str:
    """``name`` if it is a fidelity, else :class:`ScenarioError` naming ``field``."""
    if not isinstance(name, str) or name not in FIDELITY_NAMES:
        raise ScenarioError(source, field, f"unknown fidelity {name!r}; expected one of "
                            f"{', '.join(FIDELITY_NAMES)}")
    return name


def is_system_dialect(data: dict) -> bool:
    """True for a file that describes the system (``[model] fidelity``)."""
    model = data.get("model")
    return isinstance(model, dict) and "fidelity" in model


#: The keys a described system reads (:func:`downhole._schema.only_keys`).
SYSTEM_KEYS = (
    "title", "description", "model.fidelity", "model.friction", "model.rayleigh_alpha",
    "model.rayleigh_beta", "model.lump_length", "model.wave_section", "model.lumped4",
    "model.lumped12", "model.neutral", "model.fem", "model.hybrid", "well", "string", "bit",
    "rig.top_drive", "rig.hook.servo_stiffness", "rig.hook.servo_damping",
    "rig.hook.block_mass", "operation.surface_speed", "operation.rop", "operation.wob",
    "simulation.duration", "simulation.dt", "simulation.record_dt", "simulation.depth_of_cut",
    "simulation.start", "simulation.integrator", "torque_drag")

#: A described system's values where the file gives none: Rayleigh damping (1/s, s), wall
#: friction, the top drive (kg m^2, N m s/rad, N m/rad), the speed set-point (rad/s) and the
#: output sampling (s).
DESCRIBED = {"rayleigh_alpha": 0.05, "rayleigh_beta": 0.03, "friction": 0.0,
             "inertia": 500.0, "kp": 1e4, "ki": 2e3, "surface_speed": 10.0, "record_dt": 0.01}


def _or(value, key):
    return DESCRIBED[key] if value is None else value


def parse_system(data: dict, source: str):
    """Validate a described system: the keys it reads, the one schema and its own rules
    (``[well]`` and ``[string]`` segments, ``[simulation]`` duration, exactly one of rop and
    wob, each a constant).

    Parameters
    ----------
    data, source : dict, str
        The parsed file and its name (for messages).

    Returns
    -------
    Scenario
    """
    from downhole.scenario import parse_scenario

    _schema.only_keys(data, source, SYSTEM_KEYS, "a described system")
    sc = parse_scenario(data, source)
    check_fidelity(sc.model.fidelity, source)
    if sc.well is None:
        raise ScenarioError(source, "well", "required table is missing (sections, stations or "
                            "a survey CSV)")
    if sc.string is None or sc.string.segments is None:
        raise ScenarioError(source, "string.segments", "required field is missing")
    if sc.simulation is None or sc.simulation.duration is None:
        raise ScenarioError(source, "simulation.duration", "required field is missing")
    op = sc.operation
    rop = _schema.constant(op.rop, source, "operation.rop")
    wob = _schema.constant(op.wob, source, "operation.wob")
    _schema.constant(op.surface_speed, source, "operation.surface_speed")
    if (rop is None) == (wob is None):
        raise ScenarioError(source, "operation", "give exactly one of rop and wob (the axial "
                            "set-point)")
    if rop is not None and not 0 < rop <= 1.0:
        raise ScenarioError(source, "operation.rop", f"expected 0 < rop <= 1 m/s, got {rop:g}")
    if wob is not None and wob <= 0:
        raise ScenarioError(source, "operation.wob", f"expected a WOB > 0, got {wob:g}")
    td = sc.rig.top_drive
    if td.kp is not None and td.kp <= 0:
        raise ScenarioError(source, "rig.top_drive.kp", f"expected kp > 0, got {td.kp:g}")
    return sc


def _check_renames(data: dict, source: str) -> None:
    for dotted in sorted(RENAMED, key=lambda k: -k.count(".")):  # the most precise key first
        new = RENAMED[dotted]
        node = data
        parts = dotted.split(".")
        for p in parts[:-1]:
            node = node.get(p) if isinstance(node, dict) else None
        if isinstance(node, dict) and parts[-1] in node:
            raise ScenarioError(source, dotted, f"not in a described system ([well], "
                                f"[string]): use {new} (see docs/scenarios.md)")


# ---------------------------------------------------------------------------------- build
def _bit(sc, source: str):
    from downhole.params import BitParams, get_preset

    over = dict(sc.bit)
    name = over.pop("preset", "table_5_1")
    try:
        preset = get_preset(name)
    except (KeyError, TypeError) as exc:
        raise ScenarioError(source, "bit.preset", str(exc.args[0] if exc.args else exc)
                            ) from None
    try:
        return BitParams(**{**preset.bit.model_dump(), **over})
    except ValidationError as exc:
        _raise_validation(source, exc, "bit.")
    except (ValueError, TypeError, DownholeInputError) as exc:
        raise ScenarioError(source, "bit", str(exc)) from None


def build_system(sc, source: str, fidelity: str):
    """The :class:`~downhole.system.DrillingSystem` a parsed system scenario describes, with the
    friction that applies at ``fidelity`` (raises :class:`ScenarioError` naming the field)."""
    from downhole.params.rig import Hook, TopDrive
    from downhole.system import DrillingSystem, Rig

    bit = _bit(sc, source)
    well = _well(SimpleNamespace(well=sc.well), source, None)
    string = _string(SimpleNamespace(string=sc.string), source,
                     SimpleNamespace(pipe=None, g=9.81), well)
    td, hk = sc.rig.top_drive, sc.rig.hook
    try:
        rig = Rig(TopDrive(inertia=_or(td.inertia, "inertia"),
                           speed=_or(sc.operation.surface_speed, "surface_speed"),
                           kp=_or(td.kp, "kp"), ki=_or(td.ki, "ki")),
                  Hook(servo_stiffness=hk.servo_stiffness, servo_damping=hk.servo_damping,
                       block_mass=hk.block_mass))
    except DownholeInputError as exc:
        raise ScenarioError(source, "rig", str(exc)) from None
    if fidelity == "neutral" and sc.model.neutral.lump:
        from downhole.string.drillstring import DrillString, StringSegment

        segs = tuple(StringSegment(s.length, s.section, "bha")
                     if s.kind in sc.model.neutral.lump else s for s in string.segments)
        string = DrillString(segs, string.stabilizers, mud_density=string.mud_density,
                             g=string.g)
    ws = sc.model.wave_section
    try:
        return DrillingSystem(well=well, string=string, bit=bit, rig=rig,
                              friction=_or(sc.model.friction_at(fidelity), "friction"),
                              rayleigh_alpha=_or(sc.model.rayleigh_alpha, "rayleigh_alpha"),
                              rayleigh_beta=_or(sc.model.rayleigh_beta, "rayleigh_beta"),
                              lump_length=sc.model.lump_length,
                              wave_section=tuple(ws) if ws is not None else None)
    except DownholeInputError as exc:
        raise ScenarioError(source, "string", str(exc)) from None


def _build_options(sc, fidelity: str) -> dict:
    """The keywords of ``DrillingSystem.build(fidelity, ...)``: the keys of the file's
    ``[model.<fidelity>]`` table, by the same names (:data:`downhole.system.BUILD_OPTIONS`;
    ``friction`` and the neutral model's ``lump`` change the description instead)."""
    from downhole.system import BUILD_OPTIONS

    table = getattr(sc.model, fidelity)
    return {k: getattr(table, k) for k in BUILD_OPTIONS[fidelity]}


def _mesh_field(fid: str, msg: str) -> str | None:
    """The ``[model.<fid>]`` key a mesh error message names (None: not a mesh error)."""
    for key in ("n_elements", "n_ab", "n_cd", "n_lags", "max_element_length",
                "max_element_angle", "reference_elements"):
        if msg.startswith(key) or f"model.{fid}.{key}" in msg:
            return f"model.{fid}.{key}"
    return None


def validate_system_scenario(data: dict, source: str, fidelity: str | None = None):
    """Validate a system scenario for a run at ``fidelity`` (default: the file's) without
    running it: schema, renamed keys, the description, the model and the step settings.

    Returns
    -------
    (SystemScenario, str, DrillingSystem, model)
        The parsed file, the fidelity, the description and the built model.

    Raises
    ------
    ScenarioError
        Naming the file and the dotted field (``model.fidelity`` for a feature the fidelity
        cannot represent, ``--fidelity`` for a bad override).
    """
    _check_renames(data, source)
    if fidelity is not None:
        check_fidelity(fidelity, source, "--fidelity")
    sc = parse_system(data, source)
    fid = fidelity or sc.model.fidelity
    system = build_system(sc, source, fid)
    try:
        model = system.build(fid, **_build_options(sc, fid))
    except DownholeInputError as exc:
        field = _mesh_field(fid, str(exc)) or ("model.fidelity" if fidelity is None
                                               else "--fidelity")
        raise ScenarioError(source, field, f"{fid}: {exc}") from None
    sim = sc.simulation
    dt = sim.step(fid)
    if dt > sim.duration:
        raise ScenarioError(source, "simulation.dt", f"dt ({dt:g} s) exceeds duration "
                            f"({sim.duration:g} s)")
    rec = _or(sim.record_dt, "record_dt")
    check_step_count(source, sim.duration, dt, rec)
    if rec < dt:
        raise ScenarioError(source, "simulation.record_dt", f"record_dt ({rec:g} s) "
                            f"is below dt ({dt:g} s)")
    if sim.integrator == "euler":
        raise ScenarioError(source, "simulation.integrator", "'euler' is the seed's scheme for "
                            "the lumped presets' ideal top drive (Table 2.1); a described "
                            "system's rig (top-drive inertia and PI, hook servo) steps with "
                            "'newmark' at every fidelity")
    if fid == "neutral" and dt > min(model.tau1, model.tau2):
        raise ScenarioError(source, "simulation.dt", f"dt = {dt:g} s exceeds the neutral "
                            f"model's wave delay {min(model.tau1, model.tau2):.4g} s")
    try:
        steady_bit_state(system.bit, _or(sc.operation.surface_speed, "surface_speed"),
                         sc.operation.rop, sc.operation.wob)
    except DownholeInputError as exc:
        raise ScenarioError(source, "operation.wob", str(exc)) from None
    return sc, fid, system, model


def run_system_scenario(data: dict, source: str, text: str, fidelity: str | None = None):
    """Validate and run a system scenario at ``fidelity`` (default: the file's ``[model]
    fidelity``); returns the :class:`~downhole.sim.Result` (attrs ``fidelity``, ``scenario``)."""
    from downhole.params.rig import Hook, TopDrive

    sc, fid, system, model = validate_system_scenario(data, source, fidelity)
    sim, op = sc.simulation, sc.operation
    dt = sim.step(fid)
    speed = _or(op.surface_speed, "surface_speed")
    attrs = {"scenario": text, "scenario_source": source, "title": sc.title, "fidelity": fid}
    rop, wob, tob = steady_bit_state(system.bit, speed, op.rop, op.wob)
    from downhole.sim import simulate

    kw = dict(duration=sim.duration, dt=dt, depth_of_cut=sim.depth_of_cut,
              record_dt=_or(sim.record_dt, "record_dt"), attrs=attrs, start=sim.start)
    try:
        td = sc.rig.top_drive
        top = TopDrive(inertia=_or(td.inertia, "inertia"), mode="pi", speed=speed,
                       kp=_or(td.kp, "kp"), ki=_or(td.ki, "ki"))
        hk = sc.rig.hook
        if op.rop is not None:
            hook = Hook(mode="velocity", wob=wob, velocity=rop, block_mass=hk.block_mass,
                        servo_stiffness=hk.servo_stiffness, servo_damping=hk.servo_damping)
        else:
            hook = Hook(mode="force", wob=op.wob, block_mass=hk.block_mass,
                        servo_stiffness=hk.servo_stiffness, servo_damping=hk.servo_damping)
        # the same rig at every fidelity: the top drive and the hook act on the model's top
        # node (a lumped chain and the neutral line run under the rig's node)
        return simulate(model, top_drive=top, hook=hook, **kw)
    except ScenarioError:
        raise
    except DownholeInputError as exc:
        raise ScenarioError(source, "simulation", f"{fid}: {exc}") from None


def lumped_design_model(data: dict, source: str) -> tuple[dict, dict]:
    """The 4th-order model a design derives from a file that describes its system ([well],
    [string], [bit], [model] friction and damping): the ``lumped4`` chain's parameters
    (:meth:`downhole.system.DrillingSystem.build`: stiffness, first-frequency mass, Rayleigh
    ground damping) and the bit, as plain dicts (``downhole optimize dp`` passes them to
    :func:`downhole.control.dp.problem.dp_problem_of`).

    Parameters
    ----------
    data, source : dict, str
        The parsed file and its name (for messages).

    Returns
    -------
    (dict, dict)
        LumpedParams and BitParams fields.

    Raises
    ------
    ScenarioError
        Naming the file and the field of a bad description, or the fidelity's refusal (wall
        contact in a deviated well, ...).
    """
    from downhole.scenario import parse_scenario

    _check_renames(data, source)
    probe = dict(data)
    probe["model"] = {**(data.get("model") or {}), "fidelity": "lumped4"}
    sc = parse_scenario(probe, source)
    system = build_system(sc, source, "lumped4")
    try:
        chain = system.build("lumped4", **_build_options(sc, "lumped4"))
    except DownholeInputError as exc:
        raise ScenarioError(source, "model", f"lumped4: {exc}") from None
    return chain.params.model_dump(), system.bit.model_dump()


#: The keys an EID design on a described system reads besides the description's.
_EID_DESIGN_KEYS = ("controller.type", "reference", "operation", "simulation")


def neutral_design_model(data: dict, source: str):
    """The EID design of a file that describes its system: the system's neutral-type model
    (:meth:`downhole.system.DrillingSystem.build` at ``neutral``: the pipe above the BHA as the
    wave line, the BHA lumped into the bit, the rig's top gains as the model's top dampers),
    the ``[controller] type = "eid"`` design options and the ``[reference]``.

    Parameters
    ----------
    data, source : dict, str
        The parsed file and its name (for messages).

    Returns
    -------
    (NeutralModel, dict, Reference)
        The design model, the design keyword arguments and the reference.

    Raises
    ------
    ScenarioError
        Naming the file and the field (a description the neutral model cannot represent:
        several pipe sections, wall contact in a deviated well, ...).
    """
    from downhole.scenario import parse_scenario
    from downhole.scenario.neutral import build_reference

    _check_renames(data, source)
    eid_keys = tuple(f"controller.{k}" for k in _schema.EIDOptions.model_fields)
    _schema.only_keys(data, source, SYSTEM_KEYS + _EID_DESIGN_KEYS + eid_keys + ("rig",),
                      "an EID design on a described system")
    probe = dict(data)
    probe["model"] = {**(data.get("model") or {}), "fidelity": "neutral"}
    sc = parse_scenario(probe, source)
    if sc.controller.type != "eid":
        raise ScenarioError(source, "controller.type", 'design eid needs [controller] type = '
                            f'"eid" with the design options, got {sc.controller.type!r}')
    system = build_system(sc, source, "neutral")
    try:
        model = system.build("neutral", **_build_options(sc, "neutral"))
    except DownholeInputError as exc:
        raise ScenarioError(source, "model", f"neutral: {exc}") from None
    return model, sc.controller.options.design_options(), build_reference(sc)


def load_dp_problem(path):
    """Read a DP problem file, a preset's or a described system's: ``(problem, method)`` (what
    ``downhole optimize dp`` reads; :func:`lumped_design_model` derives the model of a file with
    [well] and [string]).

    Parameters
    ----------
    path : str or Path
        The problem file.

    Returns
    -------
    (DPProblem, str or None)
        The problem and ``optimize.method``.

    Raises
    ------
    ScenarioError
        Naming the file and the field.
    """
    from downhole.control.dp.problem import dp_problem_of
    from downhole.scenario.schema import read_scenario

    data, source, _ = read_scenario(path)
    described = None
    if "well" in data or "string" in data:
        described = lumped_design_model(data, source)
    return dp_problem_of(data, source, described)
