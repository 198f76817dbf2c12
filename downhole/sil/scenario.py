"""SIL scenario files (TOML): plant, runtime, controller, reference, link, safety, dashboard.

Every section is optional; numbers may carry units ("1 ms", "10 rad/s", "120 kN"). Unknown keys
are errors naming the file and the dotted field. Example (``examples/sil_dhp_hybrid68.toml``)::

    [plant]
    model = "hybrid68"          # hybrid24 | hybrid68 | hybrid108 | fem | lumped
    interface = "state"         # surface (PI top drive + hook load) | state (DHP)
    depth_of_cut = "delayed"

    [runtime]
    dt = "1 ms"
    duration = "20 s"

    [controller]
    kind = "dhp"                # none | pi | dhp | file (a .py file runs only with --allow-code)
    reference = "step"          # dhp training reference: step | sine | ramp

    [link]
    port = 47600

See ``docs/sil.md`` for every field.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from downhole.errors import ScenarioError
from downhole.params.quantity import Q

__all__ = ["SilScenario", "load_sil_scenario", "parse_sil_scenario", "build_from_scenario",
           "check_code_allowed", "dashboard_token"]


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid")


class PlantSection(_Strict):
    """``[plant]``."""

    model: Literal["hybrid24", "hybrid68", "hybrid108", "fem", "lumped"] = "hybrid68"
    interface: Literal["surface", "state"] = "surface"
    depth_of_cut: Literal["delayed", "approximate"] = "delayed"
    wob: Q["force"] = Field(120e3, ge=0)
    top_drive_speed: Q["angular_velocity"] = 10.0
    surface_torque: Q["torque"] = 0.0
    design: Literal["hybrid24", "hybrid68"] = "hybrid24"
    n_elements: int = Field(23, ge=1, le=5000)
    lumped_preset: str = "table_2_1"
    order: Literal[4, 12] = 4
    axial_velocity: Q["velocity"] = 0.01


class RuntimeSection(_Strict):
    """``[runtime]``."""

    dt: Q["time"] = Field(1e-3, gt=0)
    duration: Q["time"] = Field(20.0, gt=0)
    paced: bool = True
    record_dt: Q["time"] = Field(0.01, gt=0)
    ring_seconds: Q["time"] = Field(3600.0, gt=0)
    chunk_dir: str | None = None
    max_lag: Q["time"] = Field(0.05, gt=0)
    wait_fraction: float = Field(0.7, gt=0, lt=1)
    realtime: bool = True


class DHPSection(_Strict):
    """``[controller]`` DHP design settings (used when ``kind = "dhp"`` and no ``file``)."""

    reference: Literal["step", "sine", "ramp"] = "step"
    horizon: Q["time"] = Field(8.0, gt=0)
    samples: int = Field(50, ge=2, le=100_000)
    weights: Literal["robust", "design", "planned"] = "robust"


class ControllerSection(_Strict):
    """``[controller]``."""

    kind: Literal["none", "pi", "dhp", "file"] = "pi"
    file: str | None = None
    enabled: bool = True
    remote: bool = False
    dhp: DHPSection = DHPSection()


class ReferenceSection(_Strict):
    """``[reference]``: bit-velocity reference passed to the controller, and the admissible
    range of a set-point changed while running (the dashboard refuses anything outside)."""

    axial: Q["velocity"] = 0.01
    angular: Q["angular_velocity"] = 20.0
    axial_min: Q["velocity"] = 0.0
    axial_max: Q["velocity"] = 0.05
    angular_min: Q["angular_velocity"] = 0.0
    angular_max: Q["angular_velocity"] = 40.0


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


class SilScenario(_Strict):
    """A whole SIL scenario."""

    name: str = "sil"
    plant: PlantSection = PlantSection()
    runtime: RuntimeSection = RuntimeSection()
    controller: ControllerSection = ControllerSection()
    reference: ReferenceSection = ReferenceSection()
    link: LinkSection = LinkSection()
    safety: SafetySection = SafetySection()
    dashboard: DashboardSection = DashboardSection()


def parse_sil_scenario(data: dict, source: str = "<dict>") -> SilScenario:
    """Validate a scenario dict; raises :class:`~downhole.errors.ScenarioError`."""
    from downhole.scenario import _raise_validation

    try:
        sc = SilScenario.model_validate(data)
    except ValidationError as exc:
        _raise_validation(source, exc)
    if sc.plant.model == "lumped" and sc.link.mode != "hil":
        _check_lumped_step(sc, source)
    if sc.controller.kind == "file" and not sc.controller.file:
        raise ScenarioError(source, "controller.file", "kind = 'file' needs a file path")
    r = sc.reference
    for name, lo, hi, v in (("axial", r.axial_min, r.axial_max, r.axial),
                            ("angular", r.angular_min, r.angular_max, r.angular)):
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
        if not (o.startswith("http://") or o.startswith("https://")) or o.rstrip("/") != o:
            raise ScenarioError(source, "dashboard.allowed_origins",
                                f"{o!r} is not an origin (scheme://host[:port], no path)")
    if sc.controller.kind == "dhp" and sc.plant.interface != "state":
        raise ScenarioError(source, "plant.interface",
                            "a DHP controller needs interface = 'state'")
    if sc.controller.kind == "pi" and sc.plant.interface == "state" \
            and sc.plant.model != "lumped":
        raise ScenarioError(source, "controller.kind",
                            "the PI needs interface = 'surface' (speed-controlled top drive)")
    return sc


def _check_lumped_step(sc: SilScenario, source: str) -> None:
    """The lumped SIL plant steps with explicit Euler: ``runtime.dt`` must be below its stability
    bound (:func:`downhole.scenario.euler_stable_dt`)."""
    from downhole.params import get_preset
    from downhole.scenario import euler_stable_dt
    from downhole.string.lumped import lumped_model

    try:
        preset = get_preset(sc.plant.lumped_preset)
    except KeyError as exc:
        raise ScenarioError(source, "plant.lumped_preset", str(exc.args[0])) from None
    if preset.kind != "lumped":
        raise ScenarioError(source, "plant.lumped_preset", f"preset {sc.plant.lumped_preset!r} "
                            f"is a {preset.kind} model, expected a lumped one")
    bound, mode = euler_stable_dt(lumped_model(sc.plant.lumped_preset, order=sc.plant.order))
    if sc.runtime.dt >= bound:
        raise ScenarioError(source, "runtime.dt", f"dt = {sc.runtime.dt:g} s is too large for "
                            f"the lumped plant's explicit Euler: stable only for dt < "
                            f"{bound:.4g} s (2 zeta / omega of the {mode['field']} mode at "
                            f"{mode['frequency']:.4g} rad/s)")


def load_sil_scenario(path) -> SilScenario:
    """Read and validate a SIL scenario TOML file."""
    from downhole.scenario import read_toml

    path = Path(path)
    data, source, _ = read_toml(path)
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
    ref = {"step": BitReference.step(sc.reference.axial, sc.reference.angular),
           "sine": BitReference.sine(), "ramp": BitReference.ramp(t_final=d.horizon)}[d.reference]
    if d.weights == "planned":
        # the start-up planned on the design FEM, soft gains about it (docs/dhp.md)
        from downhole.control.dhp.plan import design_dhp_planned
        from downhole.string.hybrid import hybrid_model

        return design_dhp_planned(plant.plant.design, hybrid_model(sc.plant.design).design_model(),
                                  ref, horizon=d.horizon,
                                  weights=PenaltyWeights(**weight_set("planned")),
                                  settings=DHPSettings(n_samples=d.samples),
                                  progress=progress)
    return design_dhp(plant.plant.design, ref, horizon=d.horizon,
                      weights=PenaltyWeights(**weight_set(d.weights)),
                      settings=DHPSettings(n_samples=d.samples), progress=progress)


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
    p = sc.plant
    if sc.link.mode == "hil":
        from downhole.sil.hil import build_hil_plant

        plant = build_hil_plant(p.model, dt=sc.runtime.dt, wob=p.wob,
                                surface_torque=p.surface_torque)
    else:
        plant = build_plant(p.model, interface=p.interface, dt=sc.runtime.dt,
                            depth_of_cut=p.depth_of_cut, wob=p.wob,
                            top_drive_speed=p.top_drive_speed, surface_torque=p.surface_torque,
                            design=p.design, n_elements=p.n_elements,
                            lumped_preset=p.lumped_preset, order=p.order,
                            axial_velocity=p.axial_velocity)
    ctrl = None
    kind = sc.controller.kind
    file = scenario_controller_file(sc, controller_file)
    if building:
        if file:
            ctrl = load_controller_file(file, plant, allow_code=allow_code)
        elif kind == "pi":
            ctrl = pi_controller_for(plant)
        elif kind == "dhp":
            ctrl = _dhp(sc, plant, progress=progress)
    return plant, ctrl
