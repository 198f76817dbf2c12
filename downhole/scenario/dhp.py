"""DHP design scenarios (``[model] type = "dhp"``): schema, design and closed-loop runner.

The command ``downhole design dhp SCENARIO.toml --out DIR`` (:mod:`downhole.cli.design_dhp`)
trains a DHP (SNAC) tracking controller from such a file and writes
``DIR/dhp_controller.npz`` + ``DIR/dhp_controller.json`` (load with
:func:`downhole.control.dhp.load_controller`), ``DIR/report.json`` (training diagnostics and,
with a ``[simulation]`` table, the closed-loop summary) and, when simulated,
``DIR/closed_loop.nc`` and ``DIR/closed_loop.png``.

The same file runs with ``downhole simulate SCENARIO.toml --out DIR`` (``[model] type = "dhp"``
selects this runner): it trains the controller (or loads ``[controller] file``) and returns the
``[simulation]`` closed loop as the run's Result.

Scenario schema (every table and key optional; numbers are SI, strings with units accepted
where a unit is shown)::

    title = "..."               # optional, shown by downhole simulate

    [controller]                # optional: use a trained controller instead of training
    file = "out/dhp/dhp_controller"     # relative to the scenario file

    [model]
    type = "dhp"                # required by `downhole simulate`, optional here
    kind = "fem24"              # "fem24": Table 5.1 well, 24-state FEM (6 nodes, the seed's
                                #   design model); "fem": Table 5.1 FEM with n_elements;
                                #   "lumped": 4th-order lumped model (Eq. 2.1)
    n_elements = 5              # kind = "fem": elements (4 (n_elements + 1) states)
    preset = "table_2_1"        # kind = "lumped": a lumped preset
    dt = 0.001                  # s
    epsilon = "45 MPa"          # optional: any BitParams field overrides the bit
    input_limits = [[-50e3, 300e3], [-60e3, 60e3]]   # slack-off N, torque N m (FEM kinds)
    friction = true             # FEM kinds: wellbore friction in the design model

    [reference]
    type = "step"               # "step" | "ramp" (Eqs. 4.48-4.49) | "sine" (Eq. 4.47) | "user"
    axial = "10 mm/s"           # step value; ramp low level; sine mean
    angular = "20 rad/s"        # idem
    t_final = 40.0              # ramp: its t_f, s (default: the training horizon)
    frequency = 0.314159        # sine: rad/s
    time = [0.0, 10.0]          # user: s
    axial_values = [0.01, 0.02]     # user: m/s
    angular_values = [20.0, 30.0]   # user: rad/s

    [weights]                   # Eq. 4.45 layout, non-dimensional (PenaltyWeights)
    bit_velocity = [100.0, 100.0]
    bit_position = [0.1, 0.1]
    top_position = [0.0, 0.0]
    node_position = [0.0, 0.0]
    string_velocity = [0.0, 0.0]  # damping injection on the non-bit node velocities
    nodes = []
    final_scale = 1.0
    r = [1.0, 1.0]
    integral = [0.0, 0.0]       # integral action (beyond the seed): > 0 adds integrator states

    [training]                  # DHPSettings + horizon
    horizon = 40.0              # s
    method = "riccati"          # "riccati" | "closed_form" | "algorithm1" | "algorithm1_numpy"
    n_samples = 200             # N_S (>= 2 (n + 1) advised)
    n_iterations = 20           # N_I (Algorithm 1)
    threshold = 1e-6
    sample_radius = 0.02
    warm_start = true
    seed = 0
    resample_every = 1
    threads = 1                 # threads for the per-step sample/force fits (riccati)
    use_feed_forward = true
    past_horizon = "stationary" # or "error"

    [plan]                      # optional (FEM kinds): plan the start-up on the design FEM
                                #   (two degrees of freedom, downhole.control.dhp.plan); any
                                #   PlanSettings field, e.g.
    duration = 7.0              # s, planned segment
    knot_spacing = 0.4          # s
    n_knots = 12
    settle_from = 3.0           # s, bit-velocity errors count from here
    max_evaluations = 80        # FEM runs of the least-squares solver

    [simulation]                # optional closed-loop check after training
    duration = 20.0             # s
    plant = "fem24"             # "design" (the control-affine model itself), "fem24",
                                #   "hybrid68" (Ch. 6 plant), "lumped" (lumped models only)
    depth_of_cut = "approximate"    # or "delayed" (the true plant)
"""

from __future__ import annotations

from pathlib import Path

from downhole.errors import DownholeInputError, ScenarioError

__all__ = ["load_dhp_scenario", "parse_dhp_scenario", "design_from_scenario",
           "run_scenario_simulation", "run_dhp_scenario"]

_TABLES = {"model", "reference", "weights", "training", "plan", "simulation"}
_MODEL_KEYS = {"kind", "n_elements", "preset", "dt", "input_limits", "friction"}
_TRAIN_KEYS = {"horizon", "method", "n_samples", "n_iterations", "threshold", "sample_radius",
               "warm_start", "seed", "resample_every", "use_feed_forward", "past_horizon",
               "threads"}
_SIM_KEYS = {"duration", "plant", "depth_of_cut"}
_REF_UNITS = {"axial": "velocity", "angular": "angular_velocity", "t_final": "time",
              "frequency": "angular_velocity"}


def _si(src, field, value, dim):
    from downhole.units import to_si

    try:
        return float(to_si(value, dim))
    except Exception as exc:  # UnitError or bad type
        raise ScenarioError(src, field, f"{value!r} is not a valid {dim.replace('_', ' ')}: "
                                        f"{exc}") from None


def _limits(src, value):
    """``model.input_limits``: [[slack-off min, max] (N), [torque min, max] (N m)]."""
    field = "model.input_limits"
    if not (isinstance(value, list) and len(value) == 2
            and all(isinstance(p, list) and len(p) == 2 for p in value)):
        raise ScenarioError(src, field, f"expected [[min, max], [min, max]] (slack-off force N, "
                                        f"surface torque N m), got {value!r:.60}")
    out = []
    for (lo, hi), dim, name in zip(value, ("force", "torque"), ("force", "torque")):
        lo, hi = _si(src, field, lo, dim), _si(src, field, hi, dim)
        if not lo < hi:
            raise ScenarioError(src, field, f"{name} limits [{lo:g}, {hi:g}] are empty; expected "
                                            "min < max")
        out.append([lo, hi])
    return out


def _check_keys(src, table, data, allowed):
    bad = set(data) - allowed
    if bad:
        raise ScenarioError(src, f"{table}.{sorted(bad)[0]}",
                            f"unknown key; expected one of {sorted(allowed)}")


def load_dhp_scenario(path) -> dict:
    """Parse and validate a DHP design scenario file.

    Returns a dict with ``model`` (:class:`~downhole.control.affine.ControlAffineModel`),
    ``plant_source`` (what the simulation plants are built from), ``reference``, ``weights``,
    ``settings``, ``horizon``, ``design`` (extra design kwargs) and ``simulation`` (dict or None).

    Raises
    ------
    ScenarioError
        Naming the file, the field and what was expected.
    """

    from downhole.scenario import read_toml

    data, src, text = read_toml(path)
    return parse_dhp_scenario(data, src, text, base=Path(path).parent)


def parse_dhp_scenario(data: dict, src: str = "<dict>", text: str = "",
                       base: Path | None = None) -> dict:
    """Validate an already-parsed DHP scenario (see :func:`load_dhp_scenario`)."""
    from downhole.control.dhp import BitReference, DHPSettings, PenaltyWeights

    data = dict(data)
    data.pop("title", None)
    ctl = data.pop("controller", None)
    controller_file = None
    if ctl is not None:
        if not isinstance(ctl, dict) or set(ctl) - {"file"} or "file" not in ctl:
            raise ScenarioError(src, "controller", "expected a table with one key: file = "
                                                   "\"path/to/dhp_controller\"")
        controller_file = Path(ctl["file"])
        if not controller_file.is_absolute() and base is not None:
            controller_file = base / controller_file
    bad = set(data) - _TABLES
    if bad:
        raise ScenarioError(src, sorted(bad)[0], f"unknown table; expected {sorted(_TABLES)}")
    for name in sorted(_TABLES):
        if name in data and not isinstance(data[name], dict):
            raise ScenarioError(src, name, f"expected a table [{name}], got "
                                           f"{type(data[name]).__name__} {data[name]!r:.40}")

    # --------------------------------------------------------------------- training
    tt = dict(data.get("training", {}))
    _check_keys(src, "training", tt, _TRAIN_KEYS)
    horizon = _si(src, "training.horizon", tt.pop("horizon", 40.0), "time")
    use_ff = bool(tt.pop("use_feed_forward", True))
    past = tt.pop("past_horizon", "stationary")
    if past not in ("stationary", "error"):
        raise ScenarioError(src, "training.past_horizon", f"expected 'stationary' or 'error', "
                                                          f"got {past!r}")
    for key, most in (("n_samples", 100_000), ("n_iterations", 10_000), ("threads", 1024),
                      ("resample_every", 100_000)):
        value = tt.get(key)
        if isinstance(value, int) and not isinstance(value, bool) and value > most:
            raise ScenarioError(src, f"training.{key}", f"{value} is more than the {most} "
                                                        "this setting accepts")
    if "sample_radius" in tt and isinstance(tt["sample_radius"], list):
        tt["sample_radius"] = tuple(tt["sample_radius"])
    try:
        settings = DHPSettings(**tt)
    except (DownholeInputError, TypeError) as exc:
        raise ScenarioError(src, "training", str(exc)) from None

    # --------------------------------------------------------------------- model
    mt = dict(data.get("model", {}))
    mtype = mt.pop("type", "dhp")
    if mtype != "dhp":
        raise ScenarioError(src, "model.type", f"a DHP scenario has type = 'dhp', got {mtype!r}")
    kind = mt.pop("kind", "fem24")
    dt = _si(src, "model.dt", mt.pop("dt", 1e-3), "time")
    bit_over = {k: mt.pop(k) for k in list(mt) if k not in _MODEL_KEYS}
    limits = _limits(src, mt.pop("input_limits", [[-50e3, 300e3], [-60e3, 60e3]]))
    friction = bool(mt.pop("friction", True))
    model, plant_source = _build_model(src, kind, mt, dt, bit_over, limits, friction)

    # --------------------------------------------------------------------- reference
    rt = dict(data.get("reference", {}))
    rtype = rt.pop("type", "step")
    allowed = {"axial", "angular", "t_final", "frequency", "time", "axial_values",
               "angular_values"}
    _check_keys(src, "reference", rt, allowed)
    for k, dim in _REF_UNITS.items():
        if k in rt:
            rt[k] = _si(src, f"reference.{k}", rt[k], dim)
    try:
        if rtype == "step":
            ref = BitReference.step(rt.get("axial", 0.01), rt.get("angular", 20.0))
        elif rtype == "ramp":
            ref = BitReference.ramp(rt.get("t_final", horizon), rt.get("axial", 0.01),
                                    rt.get("angular", 20.0))
        elif rtype == "sine":
            ref = BitReference.sine(rt.get("axial", 0.02), rt.get("angular", 40.0),
                                    rt.get("frequency", 0.1 * 3.141592653589793))
        elif rtype == "user":
            ref = BitReference.user(rt.get("time", []), rt.get("axial_values", []),
                                    rt.get("angular_values", []))
        else:
            raise ScenarioError(src, "reference.type", f"expected step, ramp, sine or user, "
                                                       f"got {rtype!r}")
    except DownholeInputError as exc:
        if isinstance(exc, ScenarioError):
            raise
        raise ScenarioError(src, "reference", str(exc)) from None

    # --------------------------------------------------------------------- weights
    wt = dict(data.get("weights", {}))
    try:
        weights = PenaltyWeights.from_dict(wt) if wt else PenaltyWeights()
    except (DownholeInputError, TypeError) as exc:
        raise ScenarioError(src, "weights", str(exc)) from None

    # --------------------------------------------------------------------- plan
    plan = data.get("plan")
    if plan is not None:
        from dataclasses import fields

        from downhole.control.dhp.plan import PlanSettings

        if not isinstance(plan, dict):
            raise ScenarioError(src, "plan", "expected a table of PlanSettings fields")
        _check_keys(src, "plan", plan, {f.name for f in fields(PlanSettings)})
        if plant_source[0] != "directional":
            raise ScenarioError(src, "plan", f"a planned start-up needs a FEM design model "
                                             f"(model.kind = 'fem24' or 'fem'), got {kind!r}")
        try:
            plan = PlanSettings(**plan)
        except DownholeInputError as exc:
            raise ScenarioError(src, "plan", str(exc)) from None

    # --------------------------------------------------------------------- simulation
    sim = data.get("simulation")
    if sim is not None:
        sim = dict(sim)
        _check_keys(src, "simulation", sim, _SIM_KEYS)
        sim["duration"] = _si(src, "simulation.duration", sim.get("duration", horizon), "time")
        plants = ("design", "fem24", "hybrid68", "lumped")
        sim.setdefault("plant", "design" if kind == "lumped" else "fem24")
        if sim["plant"] not in plants:
            raise ScenarioError(src, "simulation.plant", f"expected one of {plants}, got "
                                                         f"{sim['plant']!r}")
        if (sim["plant"] == "lumped") != (kind == "lumped") and sim["plant"] != "design":
            raise ScenarioError(src, "simulation.plant", f"plant {sim['plant']!r} does not fit "
                                                         f"a model of kind {kind!r}")
        sim.setdefault("depth_of_cut", "approximate")
        if sim["depth_of_cut"] not in ("approximate", "delayed"):
            raise ScenarioError(src, "simulation.depth_of_cut", "expected 'approximate' or "
                                                                "'delayed'")
    return {"model": model, "plant_source": plant_source, "reference": ref, "weights": weights,
            "settings": settings, "horizon": horizon,
            "design": {"use_feed_forward": use_ff, "past_horizon": past},
            "simulation": sim, "text": text, "controller_file": controller_file,
            "plan": plan}


def design_from_scenario(sc: dict, progress: bool = False):
    """Train the scenario's controller; with a ``[plan]`` table, plan the start-up on the design
    FEM and return the two-degree-of-freedom controller (its plan in ``ctrl.plan``)."""
    from downhole.control.dhp import design_dhp
    from downhole.control.dhp.plan import design_dhp_planned

    kw = dict(horizon=sc["horizon"], weights=sc["weights"], settings=sc["settings"],
              progress=progress, **sc["design"])
    if sc.get("plan") is None:
        return design_dhp(sc["model"], sc["reference"], **kw)
    return design_dhp_planned(sc["model"], sc["plant_source"][1], sc["reference"],
                              plan_settings=sc["plan"], **kw)


def _build_model(src, kind, mt, dt, bit_over, limits, friction):
    from downhole.control.dhp import lumped_affine_model
    from downhole.control.dhp.directional import directional_affine_model, table_5_1_models
    from downhole.params import BitParams, get_preset

    def bit_with(base):
        if not bit_over:
            return base
        try:
            return BitParams(**{**base.model_dump(), **bit_over})
        except ValueError as exc:
            raise ScenarioError(src, "model", f"bad bit override {sorted(bit_over)}: "
                                              f"{str(exc).splitlines()[0]}") from None

    try:
        if kind == "lumped":
            preset = mt.pop("preset", "table_2_1")
            if not isinstance(preset, str):
                raise ScenarioError(src, "model.preset", f"expected a preset name, got "
                                                         f"{preset!r:.40}")
            _check_keys(src, "model", mt, set())
            try:
                pre = get_preset(preset)
            except KeyError as exc:
                raise ScenarioError(src, "model.preset", str(exc.args[0])) from None
            if pre.kind != "lumped":
                raise ScenarioError(src, "model.preset", f"{preset!r} is a {pre.kind} preset; "
                                                         "kind = 'lumped' needs a lumped one")
            bit = bit_with(pre.bit)
            return lumped_affine_model(pre.string, bit, dt=dt), ("lumped", pre.string, bit)
        if kind in ("fem24", "fem"):
            import dataclasses

            fem24, hyb68 = table_5_1_models()
            if kind == "fem":
                from downhole.string.fem import fem_model

                ne = mt.pop("n_elements", 5)
                if not isinstance(ne, int) or isinstance(ne, bool) or not 3 <= ne <= 500:
                    raise ScenarioError(src, "model.n_elements", f"expected an integer from 3 "
                                                                 f"to 500, got {ne!r}")
                dm = fem_model(n_elements=ne)
            else:
                dm = fem24
            _check_keys(src, "model", mt, set())
            if bit_over:
                dm = dataclasses.replace(dm, bit=bit_with(dm.bit))
                hyb68 = dataclasses.replace(hyb68, bit=bit_with(hyb68.bit))
            model = directional_affine_model(dm, dt, input_limits=limits, friction=friction)
            return model, ("directional", dm, hyb68)
    except DownholeInputError as exc:
        if isinstance(exc, ScenarioError):
            raise
        raise ScenarioError(src, "model", str(exc)) from None
    raise ScenarioError(src, "model.kind", f"expected 'fem24', 'fem' or 'lumped', got {kind!r}")


def run_scenario_simulation(sc: dict, ctrl):
    """Closed-loop run of a trained controller as the scenario's ``[simulation]`` says."""
    from downhole.control.dhp import lumped_true_plant, run_design_model, run_on_plant
    from downhole.control.dhp.directional import DirectionalStatePlant

    sim = sc["simulation"]
    model = sc["model"]
    src = sc["plant_source"]
    attrs = {"scenario": sc["text"]}
    if sim["plant"] == "design":
        return run_design_model(ctrl, model, sim["duration"], record_every=10, attrs=attrs)
    if sim["plant"] == "lumped":
        plant, adapter = lumped_true_plant(src[1], src[2], dt=model.dt,
                                           depth_of_cut=sim["depth_of_cut"])
        attrs["bit_radius"] = src[2].radius
        return run_on_plant(ctrl, plant, sim["duration"], adapter=adapter, record_every=10,
                            attrs=attrs)
    dm = src[1] if sim["plant"] == "fem24" else src[2]
    plant = DirectionalStatePlant(dm, model, model.dt, depth_of_cut=sim["depth_of_cut"])
    attrs["bit_radius"] = dm.bit.radius
    return run_on_plant(ctrl, plant, sim["duration"], record_every=10, attrs=attrs)


def run_dhp_scenario(data: dict, source: str = "<dict>", text: str = ""):
    """``downhole simulate`` runner for ``[model] type = "dhp"``: train (or load ``[controller]
    file``) and run the ``[simulation]`` closed loop; returns the Result."""
    from downhole.control.dhp import load_controller

    base = Path(source).parent if source != "<dict>" else None
    sc = parse_dhp_scenario(data, source, text, base=base)
    if sc["simulation"] is None:
        kind = sc["plant_source"][0]
        sc["simulation"] = {"duration": sc["horizon"],
                            "plant": "lumped" if kind == "lumped" else "fem24",
                            "depth_of_cut": "approximate"}
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
