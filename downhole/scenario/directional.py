"""Scenario files for the directional FEM and hybrid models of a preset (``[model] fidelity =
"fem" | "hybrid"``, ``preset = "table_5_1"``, optionally with a described ``[well]`` and
``[string]``): schema, validation and the runner behind ``downhole simulate``.

Everything is validated before anything runs; an error names the file and the dotted field
(``ScenarioError``, exit code 2 from the CLI) and nothing is written. Numbers may carry units.
Schema (only ``[model]`` and ``[simulation]`` are required; the table names are those of every
scenario, :mod:`downhole.scenario.schema`)::

    title = "..."
    [model]
    fidelity = "fem"                # or "hybrid"
    preset = "table_5_1"            # a 'directional' preset: well, pipe, bit, damping, friction
    wave_section = ["2000 m", "3000 m"]  # B and C: ends of the hybrid's wave segment (BC must
                                    #   be straight, vertical, one pipe); FEM: where force_b/c are;
                                    #   default: the preset's, with a described [well] its
                                    #   vertical part above the kick-off (as DrillingSystem)
    damping = "rayleigh"            # or "modal"
    rayleigh_alpha = 0.05           # 1/s  (default: the preset)
    rayleigh_beta = 0.03            # s
    modal_ratio = 0.03              # of critical, every mode (damping = "modal")
    friction = 0.5                  # wellbore friction coefficient (0: no contact)
    friction_velocity = "1 mm/s"    # regularization velocity v_eps
    mass = "consistent"             # or "lumped"
    [model.fem]
    n_elements = 107                # fem: number of elements (4 (n_elements + 1) states);
                                    #   default: the mesh derived from the description (a node
                                    #   at every joint and survey station where the path turns)
    max_element_length = "50 m"     # the derived mesh's longest element
    max_element_angle = "2 deg"     #   and largest turn per element
    [model.hybrid]
    preset = "hybrid68"             # "hybrid24" | "hybrid68" | "hybrid108" (seed sizes), or
    n_ab = 4                        # FEM nodes on AB / on CD (override the preset);
    n_cd = 13                       #   default: the derived mesh (also max_element_length /
    n_lags = 0                      #   max_element_angle here)
    [model.string]                  # DirectionalWellParams overrides (length_ab, pipe, ...)
    [bit]                           # BitParams overrides (epsilon = "45 MPa", ...)

    [well]                          # optional (default: the preset's Table 5.1 well); one of:
    survey = "well_survey.csv"      # MD, INC, AZI columns; path relative to this file
    units = "si"                    # survey MD in m ("si") or ft ("oilfield"); default: the
                                    #   CSV header's unit ("MD (ft)"), else m; must agree with it
    hole_diameter = "8.5 in"        # default: the bit's diameter (checked against bit and string)
    # md = [0, 500, 1000] ; inclination = [0, 10, 30] ; azimuth = [0, 45, 45]  (m, deg)
    # [[well.sections]]             # surface first
    # type = "vertical" | "tangent" (length) | "arc" (radius, angle, toolface, azimuth)
    #        | "build_turn" (length, inclination, azimuth)

    [string]                        # optional (default: the preset's pipe over the whole well)
    mud_density = "1200 kg/m^3"
    [[string.segments]]             # surface first; the last may omit length (= the rest)
    kind = "pipe"                   # pipe | heavyweight | collar | bha
    length = "4000 m"
    outer_diameter = "5 in"
    inner_diameter = "4.276 in"
    # young_modulus, shear_modulus, density (defaults: steel)
    [[string.stabilizers]]
    distance_from_bit = "15 m"
    outer_diameter = "8.5 in"

    [controller]                    # top drive (default: PI, Table 5.1 gains)
    type = "pi"                     # "pi" | "soft_torque" | "dhp"
    soft_gain = 2e-4                # soft_torque: rad/s per N m of high-passed string torque
    soft_tau = "2 s"
    # type = "dhp": file = "out/dhp/dhp_controller" (a `downhole design dhp` controller,
    # relative to this file); it commands slack-off force and surface torque

    [rig.top_drive]                 # default: the preset's
    inertia = "500 kg*m**2"
    kp = 1e4                        # N m s/rad
    ki = 2e3                        # N m/rad
    [rig.hook]                      # default: constant hook load = buoyed weight - WOB
    mode = "force"                  # "force" (hook load) or "velocity" (block velocity servo)
    servo_stiffness = "1e7 N/m"
    servo_damping = "1e6 N*s/m"
    block_mass = "0 kg"

    [operation]
    surface_speed = "10 rad/s"      # top-drive set-point: a constant or [[t, value], ...]
    wob = "120 kN"                  # static WOB of the initial state (force: sets hook load)
    hook_load = [[0, "380 kN"], [20, "360 kN"]]   # force hook: optional profile overriding it
    rop = "5 mm/s"                  # velocity hook: block velocity, constant or [[t, value], ...]

    [reference]                     # optional desired bit velocities (reference_* channels)
    axial_velocity = "10 mm/s"
    angular_velocity = "10 rad/s"

    [simulation]
    duration = "30 s"
    dt = "1 ms"
    depth_of_cut = "delayed"        # or "approximate" (Eq. 4.16)
    record_dt = "10 ms"
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from downhole import _schema
from downhole.errors import DownholeInputError, ScenarioError
from downhole.scenario import (
    Scenario,
    check_step_count,
    parse_scenario,
    preset_params,
    read_scenario_text,
)

__all__ = ["DIRECTIONAL_KEYS", "build_directional",
           "run_directional_scenario", "validate_directional_scenario"]


#: The keys a FEM / hybrid preset reads (:func:`downhole._schema.only_keys`).
DIRECTIONAL_KEYS = (
    "title", "description", "model.fidelity", "model.preset", "model.string", "model.fem",
    "model.hybrid", "model.wave_section", "model.damping", "model.rayleigh_alpha",
    "model.rayleigh_beta", "model.modal_ratio", "model.friction", "model.friction_velocity",
    "well", "string", "bit", "rig", "controller.type", "controller.file",
    "controller.soft_gain", "controller.soft_tau", "operation.surface_speed", "operation.wob",
    "operation.hook_load", "operation.rop", "reference.axial_velocity",
    "reference.angular_velocity", "simulation.duration", "simulation.dt",
    "simulation.depth_of_cut", "simulation.record_dt", "simulation.start")

#: The operating point of a FEM / hybrid preset without [operation]: top-drive speed (rad/s)
#: and the WOB of the initial state (N); block velocity 0 (a force hook).
OPERATION = {"surface_speed": 10.0, "wob": 120e3, "rop": 0.0}


def _hook_mode(sc: Scenario) -> str:
    """``rig.hook.mode``, or velocity with an ``operation.rop``, force otherwise."""
    if sc.rig.hook.mode is not None:
        return sc.rig.hook.mode
    return "velocity" if sc.operation.rop is not None else "force"


def _simulation(sc: Scenario, source: str):
    """``(duration, dt, record_dt)``: duration required, dt 1 ms and record_dt 10 ms by
    default."""
    sim = sc.simulation
    if sim is None or sim.duration is None:
        raise ScenarioError(source, "simulation.duration", "required field is missing")
    dt = sim.step(sc.model.fidelity)
    rec = sim.record_dt if sim.record_dt is not None else max(dt, 0.01)
    if dt > sim.duration:
        raise ScenarioError(source, "simulation.dt", f"dt ({dt:g} s) exceeds duration "
                            f"({sim.duration:g} s)")
    if rec < dt:
        raise ScenarioError(source, "simulation.record_dt", f"record_dt ({rec:g} s) is shorter "
                            f"than dt ({dt:g} s)")
    return sim.duration, dt, rec


def _parse_directional(data: dict, source: str) -> Scenario:
    """The FEM / hybrid preset ``data`` validated: the keys it reads, the one schema and its
    rules (a controller pi, soft_torque or a saved dhp ``file``; a velocity hook takes
    ``rop``)."""
    _schema.only_keys(data, source, DIRECTIONAL_KEYS, "a FEM / hybrid preset")
    sc = parse_scenario(data, source)
    if sc.model.fidelity not in ("fem", "hybrid"):
        raise ScenarioError(source, "model.fidelity", "expected fem or hybrid")
    c = sc.controller
    kind = c.type or "pi"
    if kind not in ("pi", "soft_torque", "dhp"):
        raise ScenarioError(source, "controller.type", f"a FEM / hybrid preset runs pi, "
                            f"soft_torque or a saved dhp controller, got {kind!r}")
    if kind == "dhp" and not c.file:
        raise ScenarioError(source, "controller", "type 'dhp' needs file = a controller saved "
                            "by `downhole design dhp`")
    if kind != "dhp" and c.file is not None:
        raise ScenarioError(source, "controller", f"file is only used with type = 'dhp' (type "
                            f"is {kind!r})")
    if _hook_mode(sc) == "velocity" and sc.operation.hook_load is not None:
        raise ScenarioError(source, "operation.hook_load", "operation.hook_load is for "
                            "rig.hook.mode = 'force'; a velocity hook takes operation.rop")
    _schema.constant(sc.operation.wob, source, "operation.wob")
    return sc


# ---------------------------------------------------------------------------------- build
def _wrap(source: str, field: str):
    """Context manager turning a DownholeInputError into a ScenarioError naming ``field``."""
    from contextlib import contextmanager

    @contextmanager
    def cm():
        try:
            yield
        except ScenarioError:
            raise
        except DownholeInputError as exc:
            raise ScenarioError(source, field, str(exc)) from None

    return cm()


def _base_dir(source: str) -> Path:
    p = Path(source)
    return p.parent if p.suffix else Path.cwd()


def _params(sc: Scenario, source: str):
    from downhole.params import DirectionalWellParams

    return preset_params(sc.model, source, "directional", DirectionalWellParams, "table_5_1",
                         bit=sc.bit)


#: Admissible survey stations: measured depth (m), inclination and azimuth (deg).
SURVEY_RANGES = {"md": (0.0, 1e5), "inclination": (0.0, 180.0), "azimuth": (-360.0, 720.0)}


def _check_stations(source: str, prefix: str, md, inc, azi, length_unit: str) -> None:
    """Every station finite and inside :data:`SURVEY_RANGES` (MD in ``length_unit``), and no
    interval sharper than :data:`downhole.plausible.MAX_DOGLEG`; stations are named 1-based."""
    scale = 0.3048 if length_unit == "ft" else 1.0
    for name, values, k in (("md", md, scale), ("inclination", inc, 1.0),
                            ("azimuth", azi, 1.0)):
        lo, hi = SURVEY_RANGES[name]
        unit = "m" if name == "md" else "deg"
        field = prefix if prefix.endswith("survey") else f"{prefix}.{name}"
        for i, v in enumerate(np.asarray(values, float)):
            if not (np.isfinite(v) and lo <= v * k <= hi):
                raise ScenarioError(source, field, f"station {i + 1}: {name} {v:g} "
                                    f"{'ft' if (name == 'md' and k != 1.0) else unit} is outside "
                                    f"the admissible range {lo:g} to {hi:g} {unit}")
    if prefix.endswith("survey"):
        return  # read_survey_csv checks the dogleg severity by the file's lines
    from downhole.plausible import MAX_DEPTH, check_dogleg

    if len(md) and md[-1] * scale > MAX_DEPTH:
        hint = ("; if the depths are in feet, say units = \"oilfield\""
                if length_unit == "m" and md[-1] * 0.3048 <= MAX_DEPTH else "")
        raise ScenarioError(source, f"{prefix}.md", f"station {len(md)}: the deepest station, "
                            f"{md[-1]:g} {length_unit}, is beyond any well drilled "
                            f"({MAX_DEPTH:g} m){hint}")
    bad = check_dogleg(md, inc, azi, length_unit=length_unit)
    if bad is not None:
        raise ScenarioError(source, f"{prefix}.inclination", f"stations {bad[0]} to "
                            f"{bad[0] + 1}: {bad[1]}")


def _well(sc: Scenario, source: str, params):
    from downhole.well import WellPath, read_survey_csv

    w = sc.well
    if w is None:
        return WellPath.table_5_1(params)
    if w.survey is not None:
        path = Path(w.survey)
        if not path.is_absolute():
            path = _base_dir(source) / path
        try:
            read_scenario_text(path)  # a regular UTF-8 file of sane size (no FIFO, no device)
        except ScenarioError as exc:
            raise ScenarioError(source, "well.survey", f"{path}: {exc.message}") from None
        with _wrap(source, "well.survey"):
            # units said in the file must agree with the CSV's header ("MD (ft)")
            well = read_survey_csv(path, units=w.units if "units" in w.model_fields_set
                                   else None)
        st = well.stations
        _check_stations(source, "well.survey", st["md"], np.degrees(st["inclination"]),
                        np.degrees(st["azimuth"]), "m")
        return well
    if w.md is not None:
        if len(w.md) != len(w.inclination) or len(w.md) != len(w.azimuth):
            raise ScenarioError(source, "well.md",
                                f"md, inclination and azimuth differ in length ({len(w.md)}, "
                                f"{len(w.inclination)}, {len(w.azimuth)})")
        _check_stations(source, "well", w.md, w.inclination, w.azimuth,
                        "ft" if w.units == "oilfield" else "m")
        try:
            return WellPath.from_survey(w.md, w.inclination, w.azimuth,
                                        length_unit="ft" if w.units == "oilfield" else "m")
        except DownholeInputError as exc:
            msg = str(exc)
            field = ("well.inclination" if "inclination" in msg else
                     "well.azimuth" if "azimuth" in msg else "well.md")
            raise ScenarioError(source, field, msg) from None
    with _wrap(source, "well.sections"):
        well = WellPath.from_sections([_section(s) for s in w.sections])
    _check_sections(source, w.sections, well)
    return well


def _section(s):
    """The well-path section of a ``[[well.sections]]`` entry."""
    from downhole.well import Arc, BuildTurn, Tangent, Vertical

    if s.type == "vertical":
        return Vertical(s.length)
    if s.type == "tangent":
        return Tangent(s.length)
    if s.type == "arc":
        return Arc(s.radius, s.angle, s.toolface, s.azimuth)
    return BuildTurn(s.length, s.inclination, s.azimuth)


def _check_sections(source: str, sections, well) -> None:
    """No section curves sharper than :data:`downhole.plausible.MAX_DOGLEG` (an arc's radius
    or a build-and-turn's change of direction over its length); named 1-based."""
    from downhole.plausible import MAX_DOGLEG, format_value

    top = 0.0
    limit = format_value(MAX_DOGLEG, "deg_per_30m", "curvature")
    for k, sec in enumerate(sections, start=1):
        length = sec.length if sec.length is not None else sec.radius * sec.angle
        mid = min(top + 0.5 * length, well.total_depth)
        top += length
        dls = float(well.curvature(mid))
        if dls > MAX_DOGLEG * (1 + 1e-9):
            what = (f"radius {sec.radius:g} m" if sec.type == "arc" else
                    f"a turn of {math.degrees(dls * length):.3g} deg over {length:g} m")
            raise ScenarioError(source, f"well.sections[{k}]", (
                f"{what} is a dogleg severity of "
                f"{format_value(dls, 'deg_per_30m', 'curvature')} "
                f"({format_value(dls, 'deg_per_100ft', 'curvature')}), above {limit}, the "
                "sharpest curve a rotating string passes; check the section's radius or length "
                "and its units (a radius of R m curves 1719 / R deg/30m)"))


def _string(sc: Scenario, source: str, params, well):
    from downhole.string.drillstring import DrillString, Stabilizer, StringSegment, pipe_section

    st = sc.string
    if st is None:
        return DrillString.uniform(well.total_depth, params.pipe, g=params.g)
    with _wrap(source, "string.segments"):
        if st.segments is None:
            segs = [StringSegment(well.total_depth, params.pipe)]
        else:
            segs = []
            used = 0.0
            for k, s in enumerate(st.segments):
                length = s.length
                if length is None:
                    length = well.total_depth - used
                    if length <= 0:
                        raise ScenarioError(source, f"string.segments[{k + 1}].length",
                                            f"the segments above fill the well "
                                            f"({used:g} m of {well.total_depth:g} m); "
                                            "give a length")
                used += length
                if s.catalogue is not None:
                    from downhole.string.catalogue import catalogue_section

                    sec = catalogue_section(s.catalogue, young_modulus=s.young_modulus,
                                            shear_modulus=s.shear_modulus, density=s.density)
                else:
                    sec = pipe_section(s.outer_diameter, s.inner_diameter,
                                       young_modulus=s.young_modulus,
                                       shear_modulus=s.shear_modulus, density=s.density)
                segs.append(StringSegment(float(length), sec, s.kind))
    with _wrap(source, "string"):
        stabs = tuple(Stabilizer(x.distance_from_bit, x.outer_diameter) for x in st.stabilizers)
        ds = DrillString(tuple(segs), stabs, mud_density=st.mud_density, g=params.g)
    if ds.length > well.total_depth + 1e-6:
        ft = 1.0 / 0.3048
        raise ScenarioError(source, "string.segments",
                            f"the string ({ds.length:,.6g} m = {ds.length * ft:,.6g} ft, "
                            f"{len(segs)} segments) is longer than the well "
                            f"({well.total_depth:,.6g} m = {well.total_depth * ft:,.6g} ft); "
                            "check the segments' lengths and the well's depth unit (a survey "
                            "in feet needs units = \"oilfield\")")
    return ds


def build_directional(sc: Scenario, source: str = "<dict>"):
    """The :class:`~downhole.string.fem.DirectionalModel` a validated scenario describes.

    Raises
    ------
    ScenarioError
        Naming the field: bad preset or overrides, a bad well (non-monotonic MD, inclination
        outside 0-180 deg, ...), string (ID >= OD, too long, ...) or discretization (too few
        nodes or elements for the well's sections, a curved BC for a hybrid, ...).
    """
    from downhole.string.fem import fem_model
    from downhole.string.hybrid import hybrid_model

    params, bit = _params(sc, source)
    well = _well(sc, source, params)
    string = _string(sc, source, params, well)
    m = sc.model
    opts = m.options()
    ws = m.wave_section or (None, None)
    friction = m.friction_at()
    common = dict(damping=m.damping, rayleigh_alpha=m.rayleigh_alpha,
                  rayleigh_beta=m.rayleigh_beta, modal_ratio=m.modal_ratio, friction=friction,
                  v_eps=m.friction_velocity, mass=opts.mass, md_b=ws[0], md_c=ws[1])
    mesh = {"max_element_length": opts.max_element_length,
            "max_element_angle": opts.max_element_angle}
    if m.rayleigh_alpha is None:
        common["rayleigh_alpha"] = params.rayleigh_alpha
    if m.rayleigh_beta is None:
        common["rayleigh_beta"] = params.rayleigh_beta
    if friction is None:
        common["friction"] = params.wellbore_friction
    if m.fidelity == "fem":
        if ws[0] is None:
            common["md_b"] = min(params.length_ab, well.total_depth)
        if ws[1] is None:
            common["md_c"] = min(params.length_ab + params.length_bc, well.total_depth)
        field = "model.fem.n_elements"
        with _wrap(source, field):
            return fem_model(well, string, bit, n_elements=opts.n_elements, **mesh, **common)
    preset = opts.preset
    if sc.well is not None and m.wave_section is None:
        # a described well: B and C in its vertical part above the kick-off point, as the
        # system dialect (DrillingSystem.wave_points)
        from downhole.system import wave_points

        common["md_b"], common["md_c"] = wave_points(well, string)
    if common["md_b"] is None:
        common["md_b"] = params.length_ab
    if common["md_c"] is None:
        common["md_c"] = params.length_ab + params.length_bc
    try:
        return hybrid_model(preset, n_ab=opts.n_ab, n_cd=opts.n_cd, well=well, string=string,
                            bit=bit, n_lags=opts.n_lags, **mesh, **common)
    except DownholeInputError as exc:
        msg = str(exc)
        if msg.startswith("n_ab"):
            field = "model.hybrid.n_ab" if opts.n_ab is not None else "model.hybrid.preset"
        elif msg.startswith("n_cd"):
            field = "model.hybrid.n_cd" if opts.n_cd is not None else "model.hybrid.preset"
        elif "section BC" in msg or "md_b" in msg:
            field = "model.wave_section"
        elif "lags" in msg:
            field = "model.hybrid.n_lags"
        else:
            field = "model"
        raise ScenarioError(source, field, msg) from None


def _top_drive(sc: Scenario, params):
    from downhole.control.topdrive import TopDrive

    c, r = sc.controller, sc.rig.top_drive
    sp = OPERATION["surface_speed"] if sc.operation.surface_speed is None \
        else sc.operation.surface_speed
    speed = sp if not isinstance(sp, tuple) else float(sp[1][-1])
    soft = c.options if c.type == "soft_torque" else _schema.SoftTorqueOptions()
    return TopDrive(inertia=r.inertia if r.inertia is not None else params.top_drive_inertia,
                    mode="soft_torque" if c.type == "soft_torque" else "pi", speed=speed,
                    kp=r.kp if r.kp is not None else params.top_drive_kp,
                    ki=r.ki if r.ki is not None else params.top_drive_ki,
                    soft_gain=soft.soft_gain, soft_tau=soft.soft_tau)


def _hook(sc: Scenario):
    from downhole.control.topdrive import Hook

    h, op = sc.rig.hook, sc.operation
    rop = OPERATION["rop"] if op.rop is None else op.rop
    vel = rop if not isinstance(rop, tuple) else float(rop[1][0])
    wob = OPERATION["wob"] if op.wob is None else op.wob
    return Hook(mode=_hook_mode(sc), wob=wob, velocity=vel, block_mass=h.block_mass,
                servo_stiffness=h.servo_stiffness, servo_damping=h.servo_damping)


def _dhp_design_depths(ctrl, model, n_design):
    """Node depths of the controller's design FEM, re-meshed on this scenario's well.

    ``downhole design dhp`` kind ``fem24`` designs on a hybrid preset's design FEM (AB and CD
    nodes, one BC element; its name says "(a+b nodes) design FEM"), kind ``fem`` on
    ``fem_model(n_elements=...)`` ("fem N elements")."""
    import re

    from downhole.string.fem import fem_model
    from downhole.string.hybrid import hybrid_model

    name = str(ctrl.meta.get("model", {}).get("name", ""))
    hit = re.search(r"\((\d+)\+(\d+) nodes\) design FEM", name)
    if hit:
        md_b, md_c = (float(model.node_md[model.node_b]), float(model.node_md[model.node_c]))
        dm = hybrid_model(None, n_ab=int(hit.group(1)), n_cd=int(hit.group(2)), well=model.well,
                          string=model.string, bit=model.bit, md_b=md_b, md_c=md_c)
        return dm.design_model().node_md
    return fem_model(model.well, model.string, model.bit, n_elements=n_design - 1).node_md


def _run_dhp(sc, source, text, model, attrs):
    """Closed loop with a saved DHP controller (torque-driven top drive, force hook)."""
    from types import SimpleNamespace

    from downhole.control.dhp import load_controller, run_on_plant
    from downhole.control.dhp.directional import DirectionalStatePlant

    path = Path(sc.controller.file)
    if not path.is_absolute():
        path = _base_dir(source) / path
    try:
        ctrl = load_controller(path)
    except (OSError, KeyError, ValueError, DownholeInputError) as exc:
        raise ScenarioError(source, "controller.file",
                            f"cannot load a DHP controller from {str(path)!r}: {exc}") from None
    sim = sc.simulation
    duration, dt, rec = _simulation(sc, source)
    if abs(ctrl.dt - dt) > 1e-12:
        raise ScenarioError(source, "simulation.dt", f"the DHP controller runs at dt = "
                            f"{ctrl.dt:g} s; set simulation.dt to it (got {dt:g} s)")
    n_design = ctrl.n_states // 4
    if ctrl.n_states % 4 or n_design < 2 or not ctrl.state_names or \
            ctrl.state_names[0] != "x_1":
        raise ScenarioError(source, "controller.file", "not a directional DHP controller "
                            "(designed with `downhole design dhp`, model kind fem24 / fem)")
    design = SimpleNamespace(node_depths=_dhp_design_depths(ctrl, model, n_design))
    with _wrap(source, "controller"):
        plant = DirectionalStatePlant(model, design, dt, depth_of_cut=sim.depth_of_cut)
        every = max(1, int(round(rec / dt)))
        res = run_on_plant(ctrl, plant, duration, record_every=every, attrs=attrs)
    return res


def validate_directional_scenario(data: dict, source: str):
    """Validate a directional scenario for a run without running it: the schema, the well, the
    string, the model and the step settings. Returns ``(scenario, params, model)``.

    Raises
    ------
    ScenarioError
        Naming the file and the dotted field.
    """
    sc = _parse_directional(data, source)
    params, _ = _params(sc, source)
    duration, dt, rec = _simulation(sc, source)
    model = build_directional(sc, source)
    check_step_count(source, duration, dt, rec)
    return sc, params, model


def run_directional_scenario(data: dict, source: str, text: str):
    """Validate and run a directional scenario; returns the :class:`~downhole.sim.Result`
    (the TOML text in ``attrs["scenario"]``)."""
    from downhole.sim import simulate
    from downhole.sim.inputs import sample_signal
    from downhole.sim.result import Result

    sc, params, model = validate_directional_scenario(data, source)
    sim = sc.simulation
    duration, dt, rec = _simulation(sc, source)
    attrs = {"scenario": text, "scenario_source": source, "title": sc.title}
    if sc.controller.type == "dhp":
        res = _run_dhp(sc, source, text, model, attrs)
    else:
        td = _top_drive(sc, params)
        hook = _hook(sc)
        inputs = {}
        op = sc.operation
        if isinstance(op.surface_speed, tuple):
            inputs["surface_torque" if td.mode == "torque"
                   else "top_drive_angular_velocity"] = op.surface_speed
        if hook.mode == "force" and op.hook_load is not None:
            inputs["hook_load"] = op.hook_load
        if hook.mode == "velocity" and isinstance(op.rop, tuple):
            inputs["top_drive_axial_velocity"] = op.rop
        try:
            res = simulate(model, inputs, duration=duration, dt=dt, top_drive=td,
                           hook=hook, depth_of_cut=sim.depth_of_cut, record_dt=rec,
                           attrs=attrs, start=sim.start)
        except ScenarioError:
            raise
        except DownholeInputError as exc:
            msg = str(exc)
            field = ("simulation.dt" if "delay" in msg or "dt" in msg.split(":")[0] else
                     "operation.wob" if "WOB" in msg else "simulation")
            raise ScenarioError(source, field, msg) from None
    if sc.reference is not None and (sc.reference.axial_velocity is not None
                                     or sc.reference.angular_velocity is not None):
        ds = res.dataset
        chans = {n: ds[n].values for n in ds.data_vars}
        units = {n: ds[n].attrs.get("units", "") for n in ds.data_vars}
        if sc.reference.axial_velocity is not None:
            chans["reference_axial_velocity"] = sample_signal(sc.reference.axial_velocity,
                                                              res.time, "reference")
        if sc.reference.angular_velocity is not None:
            chans["reference_angular_velocity"] = sample_signal(sc.reference.angular_velocity,
                                                                res.time, "reference")
        res = Result(res.time, chans, units=units, attrs=dict(ds.attrs))
    return res
