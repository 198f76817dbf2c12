"""DHP design scenarios (``[controller] type = "dhp"``): reading (through the one scenario
schema), design and closed-loop runner.

The command ``downhole design dhp SCENARIO.toml --out DIR`` (:mod:`downhole.cli.design_dhp`)
trains a DHP (SNAC) tracking controller from such a file and writes
``DIR/dhp_controller.npz`` + ``DIR/dhp_controller.json`` (load with
:func:`downhole.control.dhp.load_controller`), ``DIR/report.json`` (training diagnostics and,
with a ``[simulation]`` table, the closed-loop summary) and, when simulated,
``DIR/closed_loop.nc`` and ``DIR/closed_loop.png``.

The same file runs with ``downhole simulate SCENARIO.toml --out DIR``: ``[controller] type =
"dhp"`` with a ``[controller.dhp]`` table (the design; or without ``file``) selects this runner.
It trains the controller (or loads ``[controller] file``) and returns the closed loop on the
``[model]`` plant as the run's Result.

The file is validated by the one scenario schema (:func:`downhole.scenario.schema.parse`,
``docs/scenarios.md``); its None defaults take the DHP's values below, and a key of the schema
a DHP design does not read (``simulation.dt``, ``[operation]``, ...) is refused with a line
naming it. Every table and key is optional; numbers are SI, and every physical value also takes
a unit string (``"10 mm/s"``, ``"1 ms"``, ``"60 kN*m"``)::

    title = "..."                 # optional, shown by downhole simulate

    [model]                       # the plant the closed loop is simulated on
    fidelity = "fem"              # fem | hybrid | lumped4 (default: fem for the FEM designs,
                                  #   lumped4 for the lumped design)
    preset = "fem24"              # fem: "fem24" (the 24-state FEM of the Table 5.1 well; the
                                  #   default of design fem24; design fem runs on its own FEM
                                  #   when preset is omitted); hybrid: "hybrid68" (the Ch. 6
                                  #   68-state hybrid); lumped4: a lumped preset (default: the
                                  #   design's); any fidelity: "design" (the control-affine
                                  #   design model itself, at the design's fidelity)

    [bit]                         # optional: any BitParams field over the design's bit (the
    epsilon = "45 MPa"            #   plant's too)

    [controller]
    type = "dhp"
    file = "out/dhp/dhp_controller"     # optional: a trained controller (relative to this
                                        #   file) instead of training (downhole simulate)

    [controller.dhp]              # the design
    design = "fem24"              # "fem24": Table 5.1 well, 24-state FEM (6 nodes, the seed's
                                  #   design model); "fem": Table 5.1 FEM with `elements`;
                                  #   "lumped": 4th-order lumped model (Eq. 2.1)
    elements = 5                  # design fem: elements (4 (elements + 1) states), 3..500
    preset = "table_2_1"          # design lumped: a lumped preset
    dt = "1 ms"
    input_limits = [["-50 kN", "300 kN"], ["-60 kN*m", "60 kN*m"]]  # slack-off force, surface
                                  #   torque (FEM designs)
    friction = 0.5                # FEM designs: wellbore friction coefficient of the design
                                  #   model (default: the well's, 0.5 for Table 5.1; 0: none)
    weights = "robust"            # a named preset (downhole.control.dhp.weight_sets:
                                  #   design, robust, planned) or the table below

    [controller.dhp.weights]      # Eq. 4.45 layout, non-dimensional (PenaltyWeights)
    bit_velocity = [100.0, 100.0]
    bit_position = [0.1, 0.1]
    top_position = [0.0, 0.0]
    node_position = [0.0, 0.0]
    string_velocity = [0.0, 0.0]  # damping injection on the non-bit node velocities
    nodes = []
    final_scale = 1.0
    r = [1.0, 1.0]
    integral = [0.0, 0.0]         # integral action (beyond the seed): > 0 adds integrator states

    [controller.dhp.training]     # DHPSettings + horizon
    horizon = "40 s"
    method = "riccati"            # "riccati" | "algorithm1" (the seed's iteration, NumPy)
    n_samples = 200               # N_S (>= 2 (n + 1) advised)
    n_iterations = 20             # N_I (Algorithm 1)
    threshold = 1e-6
    sample_radius = 0.02
    warm_start = true
    seed = 0
    resample_every = 1
    threads = 1                   # threads for the per-step sample/force fits (riccati)
    use_feed_forward = true
    past_horizon = "stationary"   # or "error"

    [controller.dhp.plan]         # optional (FEM designs): plan the start-up on the design FEM
                                  #   (two degrees of freedom, downhole.control.dhp.plan); any
                                  #   PlanSettings field, e.g.
    duration = "7 s"              # planned segment
    knot_spacing = "0.4 s"
    n_knots = 12
    settle_from = "3 s"           # bit-velocity errors count from here
    max_evaluations = 80          # FEM runs of the least-squares solver

    [reference]
    type = "step"                 # "step" | "ramp" (Eqs. 4.48-4.49) | "sine" (Eq. 4.47) | "user"
    axial_velocity = "10 mm/s"    # step value; ramp low level; sine mean
    angular_velocity = "20 rad/s" # idem
    t_final = "40 s"              # ramp: its t_f (default: the training horizon)
    frequency = "0.314159 rad/s"  # sine
    time = [0.0, 10.0]            # user: s
    axial_velocity_values = ["10 mm/s", "20 mm/s"]     # user
    angular_velocity_values = ["20 rad/s", "30 rad/s"] # user

    [simulation]                  # optional closed-loop check after training (only these
                                  #   two keys: dt, record_dt, ... are refused)
    duration = "20 s"             # default: the training horizon
    depth_of_cut = "approximate"  # or "delayed" (the true plant; the default)

Keys of the older DHP dialect (``[model] type = "dhp"``, ``kind``, ``n_elements``, ``[weights]``,
``[training]``, ``[plan]``, ``simulation.plant``, ``reference.axial``, ...) are refused with one
line naming the key to use (:data:`downhole.scenario.schema.RENAMES`).
"""

from __future__ import annotations

import contextlib
import dataclasses
from pathlib import Path

from pydantic import ValidationError

from downhole._schema import ReferenceTable, Scenario, SimulationTable, parse, raise_validation
from downhole.errors import DownholeInputError, ScenarioError

__all__ = [
    "design_from_scenario",
    "is_dhp_dialect",
    "load_dhp_scenario",
    "parse_dhp_scenario",
    "run_dhp_scenario",
    "run_scenario_simulation",
]

#: Most training steps (horizon / dt) and closed-loop steps (duration / dt) of one file.
MAX_TRAINING_STEPS = 1_000_000
MAX_SIMULATION_STEPS = 20_000_000
#: Longest closed-loop check, s.
MAX_DURATION = 1e5

#: Keys valid elsewhere in the scenario vocabulary whose DHP meaning moved (the global renames
#: are in :data:`downhole.scenario.schema.RENAMES`).
_LOCAL_RENAMES = {"model.friction": "controller.dhp.friction (a coefficient; the design's)"}

#: The DHP's resolution of the one schema's None defaults (docs/dhp.md).
DEFAULT_DESIGN = "fem24"
DEFAULT_HORIZON = 40.0
DEFAULT_REFERENCE = "step"

#: What a DHP design takes of the one schema's choices.
_DESIGNS = ("fem24", "fem", "lumped")
_PLANT_FIDELITIES = ("fem", "hybrid", "lumped4")
_REFERENCE_TYPES = ("step", "ramp", "sine", "user")

#: The tables and keys a DHP design reads (a key of the one schema beyond these is refused
#: with a line naming it, not ignored).
_TABLES = ("title", "description", "model", "bit", "controller", "reference", "simulation")
_USED = {
    "model": ("fidelity", "preset"),
    "controller": ("type", "file"),
    "reference": ("type", "axial_velocity", "angular_velocity", "t_final", "frequency", "time",
                  "axial_velocity_values", "angular_velocity_values"),
    "simulation": ("duration", "depth_of_cut"),
}
_UNUSED_WHY = {
    "model": "[model] is the plant the closed loop runs on (fidelity, preset); the design is "
             "[controller.dhp]",
    "controller": "a DHP design scenario has [controller] type = 'dhp', file and "
                  "[controller.dhp]",
    "reference": "a DHP reference is step | ramp | sine | user (type, axial_velocity, "
                 "angular_velocity, t_final, frequency, time, *_velocity_values)",
    "simulation": "the closed-loop check takes simulation.duration and "
                  "simulation.depth_of_cut",
    "simulation.dt": "the design's step is controller.dhp.dt",
}


def is_dhp_dialect(data: dict) -> bool:
    """True for a file that ``downhole simulate`` runs as a DHP design: ``[controller] type =
    "dhp"`` with the design table ``[controller.dhp]`` (or without a controller ``file``), no
    older ``[model] type`` and no described system (``[well]``, ``[string]``, ``[rig]``,
    ``[operation]``). A file with ``type = "dhp"`` and only a ``file`` runs the trained
    controller on the described system instead."""
    ctl = data.get("controller")
    model = data.get("model", {})
    return (isinstance(ctl, dict) and ctl.get("type") == "dhp"
            and (isinstance(ctl.get("dhp"), dict) or "file" not in ctl)
            and not (isinstance(model, dict) and "type" in model)
            and not any(key in data for key in ("well", "string", "rig", "operation")))


def load_dhp_scenario(path) -> dict:
    """Parse and validate a DHP design scenario file.

    Returns a dict with ``model`` (:class:`~downhole.control.affine.ControlAffineModel`),
    ``plant_source`` (what the simulation plants are built from), ``reference``, ``weights``,
    ``settings``, ``horizon``, ``design`` (extra design kwargs), ``plant`` (the ``[model]``
    plant: fidelity, preset and how it is built) and ``simulation`` (dict or None).

    Raises
    ------
    ScenarioError
        Naming the file, the dotted field and what was expected.
    """
    from downhole.scenario.schema import read_scenario

    data, src, text = read_scenario(path)
    return parse_dhp_scenario(data, src, text, base=Path(path).parent)


def _check_local_renames(data: dict, src: str) -> None:
    for dotted, new in _LOCAL_RENAMES.items():
        table, key = dotted.split(".")
        if isinstance(data.get(table), dict) and key in data[table]:
            raise ScenarioError(src, dotted, f"renamed in a DHP scenario: use {new} "
                                "(see docs/dhp.md)")


def _with_implied(data: dict, src: str) -> dict:
    """``data`` with what a DHP file may leave out and the one schema requires: ``[controller]
    type = "dhp"`` and ``[model] fidelity`` (the design's: fem, or lumped4 for the lumped
    design). A shallow copy; ``data`` is not changed. Refuses another controller type and a
    reference profile ``[[t, value], ...]`` (the DHP tracks constants, ramps, sines or a
    ``user`` table), naming the field."""
    out = dict(data)
    ctl = data.get("controller")
    if ctl is None:
        out["controller"] = {"type": "dhp"}
    elif isinstance(ctl, dict):
        if "type" not in ctl:
            out["controller"] = {"type": "dhp", **ctl}
        elif ctl["type"] != "dhp":
            raise ScenarioError(src, "controller.type", f"a DHP design scenario has type = "
                                f"'dhp', got {ctl['type']!r}")
    ctl = out.get("controller")
    dhp = ctl.get("dhp") if isinstance(ctl, dict) else None
    design = dhp.get("design") if isinstance(dhp, dict) else None
    own = "lumped4" if design == "lumped" else "fem"
    model = data.get("model")
    if model is None:
        out["model"] = {"fidelity": own}
    elif isinstance(model, dict) and "fidelity" not in model:
        out["model"] = {**model, "fidelity": own}
    ref = data.get("reference")
    if isinstance(ref, dict):
        for name in ("axial_velocity", "angular_velocity"):
            if isinstance(ref.get(name), list):
                raise ScenarioError(src, f"reference.{name}", "a DHP reference takes a constant "
                                    "(the step value, the ramp's low level, the sine's mean); "
                                    "for a profile use type = 'user' with time and "
                                    f"{name}_values")
    return out


def _refuse_unused(sc: Scenario, src: str) -> None:
    """Refuse the keys of the one schema a DHP design does not read (one line naming each)."""
    for key in sorted(sc.model_fields_set - set(_TABLES)):
        raise ScenarioError(src, key, "not used by a DHP design scenario (it reads title, "
                            "description, [model], [bit], [controller], [reference] and "
                            "[simulation]; see docs/dhp.md)")
    tables = {"model": sc.model, "controller": sc.controller, "reference": sc.reference,
              "simulation": sc.simulation}
    for name, table in tables.items():
        if table is None:
            continue
        # the declared keys only: the controller type's own keys ([controller.dhp]) are
        # validated by its registered model (DHPOptions)
        given = table.model_fields_set & set(type(table).model_fields)
        for key in sorted(given - set(_USED[name])):
            why = _UNUSED_WHY.get(f"{name}.{key}", _UNUSED_WHY[name])
            raise ScenarioError(src, f"{name}.{key}", f"not used by a DHP design ({why})")


def _checked_choices(sc: Scenario, src: str) -> tuple[str, str]:
    """The design and the reference type, their None resolved to the DHP's defaults; the
    plant's fidelity checked."""
    fid = sc.model.fidelity
    if fid not in _PLANT_FIDELITIES:
        raise ScenarioError(src, "model.fidelity", f"a DHP design's plant is "
                            f"{' | '.join(_PLANT_FIDELITIES)}, got {fid!r}")
    design = sc.controller.options.dhp.design or DEFAULT_DESIGN
    if design not in _DESIGNS:
        raise ScenarioError(src, "controller.dhp.design", f"{design!r} is a SIL design "
                            f"(downhole sil); downhole design dhp trains "
                            f"{' | '.join(_DESIGNS)}")
    rtype = DEFAULT_REFERENCE if sc.reference is None or sc.reference.type is None \
        else sc.reference.type
    if rtype not in _REFERENCE_TYPES:
        raise ScenarioError(src, "reference.type", f"a DHP reference is "
                            f"{' | '.join(_REFERENCE_TYPES)}, got {rtype!r}")
    s = sc.simulation
    if s is not None and s.duration is not None and s.duration > MAX_DURATION:
        raise ScenarioError(src, "simulation.duration", f"expected at most {MAX_DURATION:g} s "
                            f"(got {s.duration:g} s)")
    return design, rtype


def parse_dhp_scenario(data: dict, src: str = "<dict>", text: str = "",
                       base: Path | None = None) -> dict:
    """Validate an already-parsed DHP scenario (see :func:`load_dhp_scenario`).

    The file is validated by the one scenario schema (:func:`downhole._schema.parse`); the
    schema's None defaults take the DHP's (design ``fem24``, horizon 40 s, reference ``step``,
    the plant of the design) and a key of the schema a DHP design does not read is refused.

    Raises
    ------
    ScenarioError
        Naming ``src``, the dotted field and what was expected (an older-dialect key: the key to
        use instead).
    """
    from downhole.control.dhp import DHPSettings
    from downhole.scenario.schema import check_dialect

    check_dialect(data, src)
    _check_local_renames(data, src)
    sc = parse(_with_implied(data, src), src)
    _refuse_unused(sc, src)
    design, rtype = _checked_choices(sc, src)
    d = sc.controller.options.dhp
    controller_file = None
    if sc.controller.file is not None:
        controller_file = Path(sc.controller.file)
        if not controller_file.is_absolute() and base is not None:
            controller_file = base / controller_file

    # --------------------------------------------------------------------- training
    tr = d.training
    horizon = DEFAULT_HORIZON if tr.horizon is None else tr.horizon
    if horizon / d.dt > MAX_TRAINING_STEPS:
        raise ScenarioError(src, "controller.dhp.training.horizon", f"horizon / dt = "
                            f"{horizon / d.dt:.3g} training steps; at most {MAX_TRAINING_STEPS} "
                            f"(horizon <= {MAX_TRAINING_STEPS * d.dt:g} s at dt = {d.dt:g} s)")
    # only the keys the file sets: the rest are DHPSettings' defaults
    kw = {k: v for k, v in tr.model_dump(exclude_unset=True, exclude={
        "horizon", "use_feed_forward", "past_horizon"}).items() if v is not None}
    if isinstance(kw.get("sample_radius"), list):
        kw["sample_radius"] = tuple(kw["sample_radius"])
    try:
        settings = DHPSettings(**kw)
    except (DownholeInputError, TypeError) as exc:
        raise ScenarioError(src, "controller.dhp.training", str(exc)) from None

    # --------------------------------------------------------------------- model
    model, plant_source = _build_design(src, sc, design)
    plant = _resolve_plant(src, sc, design, plant_source)

    # --------------------------------------------------------------------- reference
    ref = _reference(src, sc.reference or ReferenceTable(), rtype, horizon)
    weights = _weights(src, d.weights)

    # --------------------------------------------------------------------- plan
    plan = None
    if d.plan is not None:
        plan = _plan(src, d.plan, plant_source)
        if plan.duration >= horizon:  # checked by the trainer only after the design
            raise ScenarioError(src, "controller.dhp.training.horizon", f"{horizon:g} s: the "
                                f"planned start-up (controller.dhp.plan.duration = "
                                f"{plan.duration:g} s) must be shorter than the trained horizon")

    # --------------------------------------------------------------------- simulation
    sim = None
    if sc.simulation is not None:
        sim = _simulation(src, sc.simulation, horizon, d.dt, plant)
    return {"model": model, "plant_source": plant_source, "reference": ref, "weights": weights,
            "settings": settings, "horizon": horizon,
            "design": {"use_feed_forward": tr.use_feed_forward,
                       "past_horizon": tr.past_horizon},
            "plant": plant, "simulation": sim, "text": text,
            "controller_file": controller_file, "plan": plan, "title": sc.title, "source": src}


def _simulation(src, s: SimulationTable, horizon, dt, plant) -> dict:
    duration = horizon if s.duration is None else s.duration
    if duration / dt > MAX_SIMULATION_STEPS:
        raise ScenarioError(src, "simulation.duration", f"duration / dt = {duration / dt:.3g} "
                            f"steps; at most {MAX_SIMULATION_STEPS:.0e} (duration <= "
                            f"{MAX_SIMULATION_STEPS * dt:g} s at controller.dhp.dt = {dt:g} s)")
    return {"duration": duration, "depth_of_cut": s.depth_of_cut,
            "fidelity": plant["fidelity"], "preset": plant["preset"], "plant": plant["kind"]}


def _reference(src, r: ReferenceTable, rtype: str, horizon):
    from downhole.control.dhp import BitReference

    ax, an = r.axial_velocity, r.angular_velocity
    for name in ("t_final", "frequency", "time", "axial_velocity_values",
                 "angular_velocity_values"):
        used = name in r.model_fields_set
        wanted = {"t_final": "ramp", "frequency": "sine"}.get(name, "user")
        if used and rtype != wanted:
            raise ScenarioError(src, f"reference.{name}", f"used by type = '{wanted}' only; "
                                f"this reference is type = {rtype!r}")
    if rtype == "user":
        for name in ("axial_velocity", "angular_velocity"):
            if name in r.model_fields_set:
                raise ScenarioError(src, f"reference.{name}", "type = 'user' takes "
                                    f"reference.{name}_values (with reference.time)")
    try:
        if rtype == "step":
            return BitReference.step(0.01 if ax is None else ax, 20.0 if an is None else an)
        if rtype == "ramp":
            return BitReference.ramp(horizon if r.t_final is None else r.t_final,
                                     0.01 if ax is None else ax, 20.0 if an is None else an)
        if rtype == "sine":
            return BitReference.sine(0.02 if ax is None else ax, 40.0 if an is None else an,
                                     0.1 * 3.141592653589793 if r.frequency is None
                                     else r.frequency)
        return BitReference.user(r.time, r.axial_velocity_values, r.angular_velocity_values)
    except DownholeInputError as exc:
        raise ScenarioError(src, "reference", str(exc)) from None


def _weights(src, spec):
    from downhole.control.dhp import PenaltyWeights
    from downhole.control.dhp.weight_sets import weight_set

    field = "controller.dhp.weights"
    try:
        if spec is None:
            return PenaltyWeights()
        if isinstance(spec, str):
            return PenaltyWeights(**weight_set(spec))
        return PenaltyWeights.from_dict(spec)
    except (DownholeInputError, TypeError, ValueError) as exc:
        raise ScenarioError(src, field, str(exc)) from None


_PLAN_UNITS = {"duration": "time", "knot_spacing": "time", "settle_from": "time",
               "late_from": "time", "steady_from": "time", "axial_tolerance": "velocity",
               "angular_tolerance": "angular_velocity", "top_drive_inertia": "inertia"}


def _plan(src, spec: dict, plant_source):
    from dataclasses import fields

    from downhole.control.dhp.plan import PlanSettings
    from downhole.units import UnitError, to_si

    known = {f.name for f in fields(PlanSettings)}
    kw = {}
    for key, value in spec.items():
        field = f"controller.dhp.plan.{key}"
        if key not in known:
            raise ScenarioError(src, field, f"unknown key; expected one of {sorted(known)}")
        if key in _PLAN_UNITS:
            try:
                value = to_si(value, _PLAN_UNITS[key])
            except UnitError as exc:
                raise ScenarioError(src, field, str(exc)) from None
        elif isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ScenarioError(src, field, f"expected a number, got {value!r:.40}")
        kw[key] = value
    if plant_source[0] != "directional":
        raise ScenarioError(src, "controller.dhp.plan", "a planned start-up needs a FEM "
                            "design model (controller.dhp.design = 'fem24' or 'fem'), got "
                            "'lumped'")
    try:
        return PlanSettings(**kw)
    except DownholeInputError as exc:
        raise ScenarioError(src, "controller.dhp.plan", str(exc)) from None


def _bit_with(src, base, over: dict):
    from downhole.params import BitParams

    if not over:
        return base
    if "preset" in over:
        raise ScenarioError(src, "bit.preset", "the design brings its bit (Table 5.1's or the "
                            "lumped preset's); give only bit parameters here (epsilon, ...)")
    try:
        return BitParams(**{**base.model_dump(), **over})
    except ValidationError as exc:
        raise_validation(src, exc, "bit.")
    except (ValueError, TypeError) as exc:
        raise ScenarioError(src, "bit", str(exc)) from None


def _lumped_preset(src, name, field):
    from downhole.params import get_preset

    try:
        pre = get_preset(name)
    except KeyError as exc:
        raise ScenarioError(src, field, str(exc.args[0])) from None
    if pre.kind != "lumped":
        raise ScenarioError(src, field, f"{name!r} is a {pre.kind} preset; a lumped model "
                            "needs a lumped one (e.g. table_2_1)")
    return pre


def _build_design(src, sc: Scenario, design: str):
    """The control-affine design model and what the plants are built from."""
    from downhole.control.dhp import lumped_affine_model
    from downhole.control.dhp.directional import directional_affine_model, table_5_1_models

    d = sc.controller.options.dhp
    given = d.model_fields_set
    if d.elements is not None and design != "fem":
        raise ScenarioError(src, "controller.dhp.elements", f"used by design = 'fem' only; "
                            f"this design is {design!r}")
    if d.preset is not None and design != "lumped":
        raise ScenarioError(src, "controller.dhp.preset", f"used by design = 'lumped' only "
                            f"(the FEM designs are the Table 5.1 well); this design is "
                            f"{design!r}")
    for name in ("input_limits", "friction"):
        if name in given and design == "lumped":
            raise ScenarioError(src, f"controller.dhp.{name}", "used by the FEM designs "
                                "(fem24, fem) only; the lumped design has none")
    for (lo, hi), name in zip(d.input_limits, ("force", "torque")):
        if not lo < hi:
            raise ScenarioError(src, "controller.dhp.input_limits", f"{name} limits "
                                f"[{lo:g}, {hi:g}] are empty; expected min < max")
    try:
        if design == "lumped":
            pre = _lumped_preset(src, d.preset or "table_2_1", "controller.dhp.preset")
            bit = _bit_with(src, pre.bit, sc.bit)
            return (lumped_affine_model(pre.string, bit, dt=d.dt),
                    ("lumped", pre.string, bit))
        fem24, hyb68 = table_5_1_models()
        if design == "fem":
            from downhole.string.fem import fem_model

            dm = fem_model(n_elements=5 if d.elements is None else d.elements)
        else:
            dm = fem24
        if sc.bit:
            dm = dataclasses.replace(dm, bit=_bit_with(src, dm.bit, sc.bit))
            hyb68 = dataclasses.replace(hyb68, bit=_bit_with(src, hyb68.bit, sc.bit))
        limits = [list(p) for p in d.input_limits]
        if d.friction is None:
            design_fem = dm
        else:
            design_fem = dataclasses.replace(dm, mu=float(d.friction))
        model = directional_affine_model(design_fem, d.dt, input_limits=limits, friction=True)
        return model, ("directional", dm, hyb68)
    except DownholeInputError as exc:
        if isinstance(exc, ScenarioError):
            raise
        raise ScenarioError(src, "controller.dhp", str(exc)) from None


def _resolve_plant(src, sc: Scenario, design: str, plant_source) -> dict:
    """``[model]``: the plant's fidelity and preset, checked against the design."""
    d = sc.controller.options.dhp
    lumped = plant_source[0] == "lumped"
    own = "lumped4" if lumped else "fem"
    fid = sc.model.fidelity  # a file without it has the design's (_with_implied)
    preset = sc.model.preset
    if lumped and fid != "lumped4":
        raise ScenarioError(src, "model.fidelity", f"the lumped design runs on the 4th-order "
                            f"lumped plant (fidelity = 'lumped4'), got {fid!r}")
    if not lumped and fid == "lumped4":
        raise ScenarioError(src, "model.fidelity", f"a {design!r} design has the FEM's "
                            f"states: it runs on fidelity 'fem' or 'hybrid', got 'lumped4'")
    if preset == "design":
        if fid != own:
            raise ScenarioError(src, "model.preset", f"preset = 'design' is the control-affine "
                                f"design model itself, at the design's fidelity ({own!r}); "
                                f"got fidelity {fid!r}")
        return {"fidelity": fid, "preset": "design", "kind": "design"}
    if fid == "lumped4":
        name = preset or d.preset or "table_2_1"
        pre = _lumped_preset(src, name, "model.preset")
        bit = plant_source[2] if name == (d.preset or "table_2_1") else \
            _bit_with(src, pre.bit, sc.bit)
        return {"fidelity": fid, "preset": name, "kind": "lumped",
                "params": (pre.string, bit)}
    if fid == "hybrid":
        if preset not in (None, "hybrid68"):
            raise ScenarioError(src, "model.preset", f"the hybrid plant is 'hybrid68' (the "
                                f"68-state Ch. 6 hybrid of the Table 5.1 well) or 'design', "
                                f"got {preset!r}")
        return {"fidelity": fid, "preset": "hybrid68", "kind": "hybrid68"}
    if design == "fem24":
        if preset not in (None, "fem24"):
            raise ScenarioError(src, "model.preset", f"the FEM plant of design 'fem24' is "
                                f"'fem24' (the 24-state FEM of Table 5.1) or 'design', got "
                                f"{preset!r}")
        return {"fidelity": fid, "preset": "fem24", "kind": "fem24"}
    if preset is not None:
        raise ScenarioError(src, "model.preset", f"a 'fem' design runs on its own FEM "
                            f"({plant_source[1].name}): omit model.preset (or 'design'), got "
                            f"{preset!r}")
    return {"fidelity": fid, "preset": None, "kind": "fem24"}


def design_from_scenario(sc: dict, progress: bool = False):
    """Train the scenario's controller; with a ``[controller.dhp.plan]`` table, plan the
    start-up on the design FEM and return the two-degree-of-freedom controller (its plan in
    ``ctrl.plan``).

    Parameters
    ----------
    sc : dict
        A parsed scenario (:func:`parse_dhp_scenario`).
    progress : bool
        Show progress bars.

    Returns
    -------
    DHPController
    """
    from downhole.control.dhp import design_dhp
    from downhole.control.dhp.plan import design_dhp_planned

    kw = dict(horizon=sc["horizon"], weights=sc["weights"], settings=sc["settings"],
              progress=progress, **sc["design"])
    with training_errors(sc.get("source", "<dict>")):
        if sc.get("plan") is None:
            return design_dhp(sc["model"], sc["reference"], **kw)
        return design_dhp_planned(sc["model"], sc["plant_source"][1], sc["reference"],
                                  plan_settings=sc["plan"], **kw)


@contextlib.contextmanager
def training_errors(src: str):
    """Turn the trainer's refusal of the file's training settings (``n_samples`` below the
    basis size of the trained model, known only once the model is augmented) into one line
    naming the file and ``controller.dhp.training``."""
    try:
        yield
    except ScenarioError:
        raise
    except DownholeInputError as exc:
        field = "controller.dhp.training" + (".n_samples" if str(exc).startswith("n_samples")
                                             else "")
        raise ScenarioError(src, field, str(exc)) from None


def run_scenario_simulation(sc: dict, ctrl):
    """Closed-loop run of a trained controller on the scenario's ``[model]`` plant, as its
    ``[simulation]`` says; returns the Result."""
    from downhole.control.dhp import lumped_true_plant, run_design_model, run_on_plant
    from downhole.control.dhp.directional import DirectionalStatePlant

    sim = sc["simulation"]
    model = sc["model"]
    src = sc["plant_source"]
    kind = sc["plant"]["kind"]
    attrs = {"scenario": sc["text"]}
    if kind == "design":
        return run_design_model(ctrl, model, sim["duration"], record_every=10, attrs=attrs)
    if kind == "lumped":
        string, bit = sc["plant"]["params"]
        plant, adapter = lumped_true_plant(string, bit, dt=model.dt,
                                           depth_of_cut=sim["depth_of_cut"])
        attrs["bit_radius"] = bit.radius
        return run_on_plant(ctrl, plant, sim["duration"], adapter=adapter, record_every=10,
                            attrs=attrs)
    dm = src[1] if kind == "fem24" else src[2]
    plant = DirectionalStatePlant(dm, model, model.dt, depth_of_cut=sim["depth_of_cut"])
    attrs["bit_radius"] = dm.bit.radius
    return run_on_plant(ctrl, plant, sim["duration"], record_every=10, attrs=attrs)


def run_dhp_scenario(data: dict, source: str = "<dict>", text: str = ""):
    """``downhole simulate`` runner for a DHP scenario: train (or load ``[controller] file``)
    and run the closed loop on the ``[model]`` plant (``[simulation]``; without it the one
    schema's defaults: over the training horizon, delayed depth of cut); returns the Result."""
    from downhole.control.dhp import load_controller

    base = Path(source).parent if not source.startswith("<") else None
    sc = parse_dhp_scenario(data, source, text, base=base)
    if sc["simulation"] is None:
        sc["simulation"] = _simulation(source, SimulationTable(), sc["horizon"],
                                       sc["model"].dt, sc["plant"])
    if sc["controller_file"] is not None:
        try:
            ctrl = load_controller(sc["controller_file"])
        except DownholeInputError as exc:
            raise ScenarioError(source, "controller.file", str(exc)) from None
        try:
            ctrl.attach_model(sc["model"])
        except DownholeInputError as exc:
            raise ScenarioError(source, "controller.file", f"the controller does not fit the "
                                                           f"scenario's model: {exc}") from None
    else:
        ctrl = design_from_scenario(sc)
    return run_scenario_simulation(sc, ctrl)
