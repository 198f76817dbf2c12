"""SIL scenario files (TOML): the plant, the real-time runtime, the controller, the reference,
the link, the safety policy and the dashboard, in the tables every scenario uses
(:mod:`downhole.scenario.schema`).

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

See ``docs/sil.md`` for every field.
"""

from __future__ import annotations

import math
from pathlib import Path, PurePosixPath
from typing import Any, Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    field_validator,
    model_validator,
)

from downhole.errors import ScenarioError
from downhole.params.quantity import Q

__all__ = [
    "SilScenario",
    "build_from_scenario",
    "check_code_allowed",
    "dashboard_token",
    "load_sil_scenario",
    "parse_sil_scenario",
]


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid")


class FemSection(_Strict):
    """``[model.fem]``."""

    n_elements: int = Field(23, ge=1, le=5000)


class ModelSection(_Strict):
    """``[model]``: the plant."""

    fidelity: Literal["lumped4", "lumped12", "neutral", "fem", "hybrid"] = "hybrid"
    preset: str | None = None   # hybrid: hybrid24 | hybrid68 | hybrid108; lumped: table_2_1
    interface: Literal["surface", "state"] = "surface"
    fem: FemSection = FemSection()

    @model_validator(mode="after")
    def _preset(self):
        from downhole.string.hybrid import HYBRID_PRESETS

        p = self.preset
        if self.fidelity == "hybrid" and p is not None and p not in HYBRID_PRESETS:
            raise ValueError(f"preset: the hybrid's preset is one of {', '.join(HYBRID_PRESETS)}"
                             f", got {p!r}")
        if self.fidelity in ("fem", "neutral") and p is not None:
            raise ValueError(f"preset: the {self.fidelity} plant is the seed's (Table "
                             f"{'5.1' if self.fidelity == 'fem' else '3.1'}); no preset here")
        return self

    @property
    def plant_name(self) -> str:
        """The name :func:`downhole.sil.plants.build_plant` takes."""
        if self.fidelity == "hybrid":
            return self.preset or "hybrid68"
        if self.fidelity.startswith("lumped"):
            return "lumped"
        return self.fidelity


class OperationSection(_Strict):
    """``[operation]``: the plant's initial commands (set-points)."""

    wob: Q["force"] = Field(120e3, ge=0)
    surface_speed: Q["angular_velocity"] = 10.0
    surface_torque: Q["torque"] = 0.0
    rop: Q["velocity"] = 0.01

    @field_validator("surface_speed", mode="before")
    @classmethod
    def _plausible_speed(cls, v):
        from downhole.units import check_rotary_speed

        return check_rotary_speed(v)


class SimulationSection(_Strict):
    """``[simulation]``: step, duration, output sampling, depth of cut, start."""

    dt: Q["time"] = Field(1e-3, gt=0)
    duration: Q["time"] = Field(20.0, gt=0)
    record_dt: Q["time"] = Field(0.01, gt=0)
    depth_of_cut: Literal["delayed", "approximate"] = "delayed"
    start: Literal["rest", "off_bottom", "steady"] = "rest"


class RealtimeSection(_Strict):
    """``[realtime]``: the real-time runtime."""

    enabled: bool = True
    paced: bool = True
    ring_seconds: Q["time"] = Field(3600.0, gt=0)
    ring_memory_mib: float = Field(256.0, gt=0, le=65536)
    chunk_dir: str | None = None
    max_lag: Q["time"] = Field(0.05, gt=0)
    wait_fraction: float = Field(0.7, gt=0, lt=1)

    @field_validator("chunk_dir")
    @classmethod
    def _chunk_dir_under_the_output(cls, v):
        # the recorder owns its chunk folder (it removes the previous run's chunks there): it
        # may only be a folder beside the run's --out, never any folder of the host
        if v is None:
            return v
        parts = PurePosixPath(v.replace("\\", "/")).parts
        if not v.strip() or "\x00" in v or v.startswith(("/", "~")) or ".." in parts \
                or (len(v) > 1 and v[1] == ":"):
            raise ValueError(f"{v!r} is not a folder name relative to the run's --out (e.g. "
                             "\"chunks\"): the chunk folder lives beside the result")
        return v


class TrainingSection(_Strict):
    """``[controller.dhp.training]``."""

    horizon: Q["time"] = Field(8.0, gt=0)
    n_samples: int = Field(50, ge=2, le=100_000)


class DHPSection(_Strict):
    """``[controller.dhp]``: the DHP design (used when ``type = "dhp"`` and no ``file``)."""

    design: Literal["hybrid24", "hybrid68"] = "hybrid24"
    weights: Literal["robust", "design", "planned"] = "robust"
    training: TrainingSection = TrainingSection()


class ControllerSection(_Strict):
    """``[controller]``."""

    type: Literal["none", "pi", "dhp", "file"] = "pi"
    file: str | None = None
    enabled: bool = True
    remote: bool = False
    dhp: DHPSection = DHPSection()


class ReferenceSection(_Strict):
    """``[reference]``: bit-velocity reference passed to the controller, and the admissible
    range of a set-point changed while running (the dashboard refuses anything outside)."""

    type: Literal["step", "sine", "ramp"] = "step"
    axial_velocity: Q["velocity"] = 0.01
    angular_velocity: Q["angular_velocity"] = 20.0
    axial_velocity_min: Q["velocity"] = 0.0
    axial_velocity_max: Q["velocity"] = 0.05
    angular_velocity_min: Q["angular_velocity"] = 0.0
    angular_velocity_max: Q["angular_velocity"] = 40.0


class LinkSection(_Strict):
    """``[link]``: the UDP address the plant binds."""

    host: str = "127.0.0.1"
    port: int = Field(47600, ge=0, le=65535)
    connect_timeout: Q["time"] = Field(300.0, gt=0)  # the plant waits this long (countdown)
    mode: Literal["sil", "hil"] = "sil"


class SafetySection(_Strict):
    """``[safety]``: controller-timeout action."""

    timeout: Q["time"] = Field(0.1, ge=0)
    hold: Q["time"] = Field(0.2, ge=0)
    ramp: Q["time"] = Field(2.0, ge=0)
    resume: Literal["manual", "auto"] = "manual"


class DashboardSection(_Strict):
    """``[dashboard]``."""

    host: str = "127.0.0.1"
    port: int = Field(8765, ge=0, le=65535)
    token: str | None = None
    token_file: str | None = None
    publish_hz: float = Field(20.0, gt=0, le=100)
    allowed_origins: list[str] = []
    allowed_hosts: list[str] = []
    units: Literal["metric", "field", "oilfield", "si"] = "metric"  # trends and set-points


class SilScenario(_Strict):
    """A whole SIL scenario (the tables of every scenario, :mod:`downhole.scenario.schema`)."""

    title: str = "sil"
    description: str = ""
    model: ModelSection = ModelSection()
    bit: dict[str, Any] = Field(default_factory=dict)
    operation: OperationSection = OperationSection()
    simulation: SimulationSection = SimulationSection()
    realtime: RealtimeSection = RealtimeSection()
    controller: ControllerSection = ControllerSection()
    reference: ReferenceSection = ReferenceSection()
    link: LinkSection = LinkSection()
    safety: SafetySection = SafetySection()
    dashboard: DashboardSection = DashboardSection()

    @property
    def name(self) -> str:
        """The title (shown by the console and the dashboard)."""
        return self.title


def parse_sil_scenario(data: dict, source: str = "<dict>") -> SilScenario:
    """Validate a scenario dict; raises :class:`~downhole.errors.ScenarioError`."""
    from downhole.scenario import _raise_validation
    from downhole.scenario.schema import check_dialect

    check_dialect(data, source)
    try:
        sc = SilScenario.model_validate(data)
    except ValidationError as exc:
        _raise_validation(source, exc)
    scenario_bit(sc, source)
    if sc.model.fidelity.startswith("lumped") and sc.link.mode != "hil":
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


def scenario_bit(sc: SilScenario, source: str = "<dict>"):
    """The plant's bit: its preset's (Table 2.1, 3.1 or 5.1) with ``[bit]`` applied, or None
    without a ``[bit]`` table. Raises :class:`ScenarioError` naming ``bit.<field>``."""
    if not sc.bit:
        return None
    from downhole.params import BitParams, get_preset
    from downhole.scenario import _raise_validation

    if "preset" in sc.bit:
        raise ScenarioError(source, "bit.preset", "the SIL plant's bit is its model's; give bit "
                            "parameters only (epsilon, ...)")
    fid = sc.model.fidelity
    base = {"neutral": "table_3_1", "fem": "table_5_1", "hybrid": "table_5_1"}.get(
        fid, sc.model.preset or "table_2_1")
    try:
        return BitParams(**{**get_preset(base).bit.model_dump(), **sc.bit})
    except ValidationError as exc:
        _raise_validation(source, exc, "bit.")
    except (TypeError, ValueError) as exc:
        raise ScenarioError(source, "bit", str(exc)) from None


def _check_lumped_step(sc: SilScenario, source: str) -> None:
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


def load_sil_scenario(path) -> SilScenario:
    """Read and validate a SIL scenario TOML file (:func:`downhole.scenario.schema.
    read_scenario`: an older-dialect key gets one line naming its replacement)."""
    from downhole.scenario.schema import read_scenario

    path = Path(path)
    data, source, _ = read_scenario(path)
    sc = parse_sil_scenario(data, source)
    if sc.controller.file and not Path(sc.controller.file).is_absolute():
        sc.controller.file = str(path.parent / sc.controller.file)
    if sc.dashboard.token_file and not Path(sc.dashboard.token_file).is_absolute():
        sc.dashboard.token_file = str(path.parent / sc.dashboard.token_file)
    return sc


def dashboard_token(sc: SilScenario) -> str | None:
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


def _dhp(sc: SilScenario, plant, progress: bool = False):
    from downhole.control.dhp import BitReference, DHPSettings, PenaltyWeights, design_dhp
    from downhole.control.dhp.weight_sets import weight_set

    d = sc.controller.dhp
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


def scenario_controller_file(sc: SilScenario, controller_file: str | None = None) -> str | None:
    """The controller file a run would load: ``controller_file`` (command line) or
    ``[controller] file``."""
    return controller_file or sc.controller.file


def check_code_allowed(sc: SilScenario, *, controller_file: str | None = None,
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


def build_from_scenario(sc: SilScenario, *, controller_file: str | None = None,
                        with_controller: bool = True, allow_code: bool = False,
                        progress: bool = False):
    """``(plant, controller)`` for a scenario (controller None for ``kind = "none"``, for
    ``remote = true`` or when ``with_controller`` is False).

    Parameters
    ----------
    sc : SilScenario
    controller_file : str, optional
        Overrides ``[controller] file``.
    with_controller : bool
        Build the controller (False: the plant only).
    allow_code : bool, keyword-only
        Allow a Python controller file (``kind = "file"``, ``file = "x.py"``) to run. Without
        it such a scenario is refused before anything is built: a scenario alone never
        executes code.
    progress : bool
        Show the DHP design's progress bars (``kind = "dhp"``).

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
    if sc.link.mode == "hil":
        from downhole.sil.hil import build_hil_plant

        plant = build_hil_plant(m.plant_name, dt=sim.dt, wob=op.wob,
                                surface_torque=op.surface_torque)
    else:
        plant = build_plant(m.plant_name, interface=m.interface, dt=sim.dt,
                            depth_of_cut=sim.depth_of_cut, wob=op.wob,
                            top_drive_speed=op.surface_speed, surface_torque=op.surface_torque,
                            design=sc.controller.dhp.design, n_elements=m.fem.n_elements,
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
            ctrl = _dhp(sc, plant, progress=progress)
    return plant, ctrl
