"""The one scenario schema: the tables and key names every command reads.

(This module sits below every layer, like :mod:`downhole._reader`, so that control code (the DP
problem loader) reads files through it without importing scenario code; its public name is
:mod:`downhole.scenario.schema`.)

Every command that reads a scenario file (``simulate``, ``sil``, ``sil-controller``,
``export-fmu``, ``design eid``, ``design dhp``, ``optimize dp``, ``sweep``) and the Gymnasium
environment (:meth:`downhole.gym.DrillingEnv.from_scenario`) reads it through
:func:`read_scenario`, which

1. reads the file with the hardened reader (:func:`downhole._reader.read_toml`: size, UTF-8,
   NUL, depth, number and list limits; a directory or FIFO refused),
2. refuses a key of an older dialect with one line naming the key to use instead
   (:data:`RENAMES`),
3. refuses a top-level table that no command reads (:data:`TABLES`).

Each command then validates the tables it uses with the pydantic models of its runner, all of
which use the same names for the same things (this module's shared sections, composed there):

========================  ===========================================================
table                     what it holds
========================  ===========================================================
``title``, ``description``  shown in summaries
``[model]``               ``fidelity`` (lumped4 | lumped12 | neutral | fem | hybrid), ``preset``
                          (a seed table: table_2_1, table_3_1, table_5_1, ...) or a described
                          system (``[well]``, ``[string]``), per-fidelity options
``[well]``, ``[string]``  the described well and drill string
``[bit]``                 the bit law and its parameters (``epsilon``, ...), over the preset's
``[rig]``                 ``[rig.top_drive]`` (inertia, kp, ki), ``[rig.hook]`` (servo)
``[operation]``           set-points: ``surface_speed``, ``rop`` or ``wob``, ``surface_torque``,
                          ``hook_load``, ``mode`` (velocity | force)
``[reference]``           the bit-velocity reference: ``axial_velocity``, ``angular_velocity``
``[controller]``          ``type`` (none | pi | eid | dhp | ztorque | file ...), ``file`` and
                          per-type sub-tables (``[controller.dhp]``, ...)
``[simulation]``          ``duration``, ``dt``, ``record_dt``, ``start``, ``depth_of_cut``,
                          ``integrator``, ``[simulation.noise]``
``[realtime]``            the real-time runtime: ``paced``, ``max_lag``, ``ring_seconds``, ...
``[link]``, ``[safety]``  the UDP link and the controller-timeout action
``[dashboard]``           the web dashboard
``[sweep]``               parameter sweeps (``downhole sweep``)
``[optimize]``            the DP problem (``downhole optimize dp``)
========================  ===========================================================

Numbers may carry units (``"10 rad/s"``, ``"120 rpm"``, ``"25 klbf"``); bare numbers are SI.
``docs/scenarios.md`` lists every key.
"""

from __future__ import annotations

import itertools
import math
from pathlib import Path, PurePosixPath
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    PrivateAttr,
    StrictInt,
    ValidationError,
    field_validator,
    model_validator,
)

from downhole._reader import read_toml
from downhole.errors import ScenarioError
from downhole.params.quantity import Q
from downhole.plausible import check_scenario
from downhole.units import UnitError, to_si

__all__ = [
    "CONTROLLER_TYPES",
    "DEFAULT_DT",
    "FIDELITIES",
    "RENAMES",
    "TABLES",
    "VALUE_RENAMES",
    "ControllerTable",
    "ModelTable",
    "OperationTable",
    "OptimizeTable",
    "ReferenceTable",
    "Scenario",
    "SimulationTable",
    "check_dialect",
    "constant",
    "only_keys",
    "parse",
    "profile_to_signal",
    "raise_validation",
    "read_scenario",
    "refuse_keys",
    "register_controller",
]

#: The fidelities of the built-in models.
FIDELITIES = ("lumped4", "lumped12", "neutral", "fem", "hybrid")

#: Every top-level key of a scenario file.
TABLES = ("title", "description", "model", "well", "string", "bit", "rig", "operation",
          "reference", "controller", "simulation", "realtime", "link", "safety", "dashboard",
          "sweep", "optimize", "torque_drag")

#: Keys of the older dialects (dotted) and the key that replaces each. A file using one gets one
#: line naming its replacement; the most precise key is reported first.
RENAMES: dict[str, str] = {
    "name": "title",
    # [model]
    "model.type": "model.fidelity (lumped4 | lumped12 | neutral | fem | hybrid)",
    "model.bit": "[bit] (the bit law's parameters over the preset's, e.g. bit.epsilon)",
    "model.hybrid": "model.hybrid.preset",  # only when a string (see check_dialect)
    "model.elements": "model.fem.n_elements",
    "model.mass": "model.fem.mass / model.hybrid.mass (per fidelity)",
    "model.nodes_ab": "model.hybrid.n_ab",
    "model.nodes_cd": "model.hybrid.n_cd",
    # one name in Python (DrillingSystem.build, fem_model, hybrid_model) and in files
    "model.fem.elements": "model.fem.n_elements",
    "model.hybrid.nodes_ab": "model.hybrid.n_ab",
    "model.hybrid.nodes_cd": "model.hybrid.n_cd",
    "model.n_lags": "model.hybrid.n_lags",
    "model.md_b": "model.wave_section = [B, C]",
    "model.md_c": "model.wave_section = [B, C]",
    # [surface] (lumped and neutral files) -> [operation]
    "surface": "[operation] (surface_speed, rop, mode, hook_load, surface_torque)",
    "surface.mode": "operation.mode",
    "surface.axial_velocity": "operation.rop (a neutral file: operation.axial_command, U_A)",
    "surface.angular_velocity": "operation.surface_speed",
    "surface.hook_load": "operation.hook_load",
    "surface.surface_torque": "operation.surface_torque",
    # [hook] (FEM / hybrid files) -> [rig.hook] and [operation]
    "hook": "[rig.hook] (servo_stiffness, servo_damping, block_mass) and operation.wob / rop",
    "hook.type": "rig.hook.mode",
    "hook.hook_load": "operation.hook_load",
    "hook.wob": "operation.wob",
    "hook.velocity": "operation.rop",
    "hook.servo_stiffness": "rig.hook.servo_stiffness",
    "hook.servo_damping": "rig.hook.servo_damping",
    "hook.block_mass": "rig.hook.block_mass",
    # [controller]
    "controller.kind": "controller.type",
    "controller.speed": "operation.surface_speed",
    "controller.kp": "rig.top_drive.kp",
    "controller.ki": "rig.top_drive.ki",
    "controller.inertia": "rig.top_drive.inertia",
    # [plant] (SIL files) -> [model], [operation], [simulation]
    "plant": "[model] (fidelity, preset, interface), [operation] (wob, surface_speed, "
             "surface_torque, rop) and simulation.depth_of_cut",
    "plant.model": "model.fidelity (lumped4 | lumped12 | neutral | fem | hybrid) and "
                   "model.preset (hybrid24 | hybrid68 | hybrid108 for the hybrid)",
    "plant.interface": "model.interface",
    "plant.depth_of_cut": "simulation.depth_of_cut",
    "plant.wob": "operation.wob",
    "plant.top_drive_speed": "operation.surface_speed",
    "plant.surface_torque": "operation.surface_torque",
    "plant.axial_velocity": "operation.rop",
    "plant.design": "controller.dhp.design",
    "plant.n_elements": "model.fem.n_elements",
    "plant.lumped_preset": "model.preset",
    "plant.order": "model.fidelity (lumped4 | lumped12)",
    # [runtime] (SIL files) -> [simulation] and [realtime]
    "runtime": "[simulation] (dt, duration, record_dt) and [realtime] (paced, max_lag, "
               "ring_seconds, ring_memory_mib, chunk_dir, wait_fraction, enabled)",
    "runtime.dt": "simulation.dt",
    "runtime.duration": "simulation.duration",
    "runtime.record_dt": "simulation.record_dt",
    "runtime.paced": "realtime.paced",
    "runtime.ring_seconds": "realtime.ring_seconds",
    "runtime.chunk_dir": "realtime.chunk_dir",
    "runtime.max_lag": "realtime.max_lag",
    "runtime.wait_fraction": "realtime.wait_fraction",
    "runtime.realtime": "realtime.enabled",
    # [reference] (SIL and DHP files)
    "reference.axial": "reference.axial_velocity",
    "reference.angular": "reference.angular_velocity",
    "reference.axial_min": "reference.axial_velocity_min",
    "reference.axial_max": "reference.axial_velocity_max",
    "reference.angular_min": "reference.angular_velocity_min",
    "reference.angular_max": "reference.angular_velocity_max",
    # [simulation.noise] (neutral files)
    "simulation.noise.axial": "simulation.noise.axial_velocity",
    "simulation.noise.angular": "simulation.noise.angular_velocity",
    # [controller.dhp] (SIL files)
    "controller.dhp.reference": "reference.type",
    "controller.dhp.horizon": "controller.dhp.training.horizon",
    "controller.dhp.samples": "controller.dhp.training.n_samples",
    # ---------------------------------------------------------------- DHP files (design dhp)
    "weights": "[controller.dhp.weights] (DHP files; or weights = \"<named set>\" there) or "
               "[optimize.weights] (DP files)",
    "training": "[controller.dhp.training]",
    "plan": "[controller.dhp.plan]",
    "model.kind": "controller.dhp.design (fem24 | fem | lumped)",
    "model.n_elements": "controller.dhp.elements",
    "model.dt": "controller.dhp.dt (DHP files) or simulation.dt",
    "model.input_limits": "controller.dhp.input_limits",
    "model.epsilon": "bit.epsilon",
    "simulation.plant": "[model] fidelity (fem | hybrid | lumped4) and preset (fem24 | hybrid68 "
                        "| a lumped preset | design): the plant simulated",
    "reference.axial_values": "reference.axial_velocity_values",
    "reference.angular_values": "reference.angular_velocity_values",
    # ---------------------------------------------------------------- DP files (optimize dp)
    "dp": "[optimize] (the DP problem)",
    "horizon": "optimize.horizon",
    "step": "optimize.step",
    "x1_regions": "optimize.x1_regions",
    "x3_regions": "optimize.x3_regions",
    "x2": "[optimize.x2]",
    "x4": "[optimize.x4]",
    "targets": "[optimize.targets]",
    "bounds": "[optimize.bounds]",
    "robust": "[optimize.robust]",
    "standard": "[optimize.standard]",
    # ---------------------------------------------------------------- end of DHP / DP files
}


def _lookup(data: dict, dotted: str):
    node = data
    for p in dotted.split("."):
        if not isinstance(node, dict) or p not in node:
            return False, None
        node = node[p]
    return True, node


#: Older keys whose replacement depends on their value: (dotted key, value) -> replacement.
VALUE_RENAMES: dict[tuple[str, str], str] = {
    ("model.type", "dhp"): 'controller.type = "dhp" and the design in [controller.dhp]',
}


def check_dialect(data: dict, source: str) -> None:
    """Refuse older-dialect keys (one line naming the replacement), unknown top-level keys and
    implausible values (:func:`downhole.plausible.check_scenario`: a rotary speed, WOB, ROP,
    torque, diameter, mud density or length no rig sees, a string wider than the hole).

    Every loader calls this first, so every file gets the same refusals.

    Parameters
    ----------
    data : dict
        The parsed scenario file.
    source : str
        The file, for messages.

    Raises
    ------
    ScenarioError
        Naming the file, the dotted key and its replacement (or the known tables), or the
        implausible value, its range and the likely fix.
    """
    for dotted in sorted(RENAMES, key=lambda k: (-k.count("."), k)):
        found, value = _lookup(data, dotted)
        if not found or (dotted == "model.hybrid" and not isinstance(value, str)):
            continue
        new = VALUE_RENAMES.get((dotted, value), RENAMES[dotted]) if isinstance(value, str) \
            else RENAMES[dotted]
        raise ScenarioError(source, dotted, f"renamed: use {new} (see docs/scenarios.md)")
    for key in data:
        if key not in TABLES:
            raise ScenarioError(source, key, f"unknown table; a scenario has {', '.join(TABLES)}"
                                " (see docs/scenarios.md)")
    check_scenario(data, source)


def read_scenario(path: str | Path) -> tuple[dict, str, str]:
    """Read a scenario file: ``(data, source, text)``, with :func:`check_dialect` applied.

    Raises
    ------
    ScenarioError
        An unreadable or malformed file, or an older-dialect / unknown key.
    """
    data, source, text = read_toml(path)
    check_dialect(data, source)
    return data, source, text


def _loc(loc) -> str:
    """A pydantic error location as messages name fields: dotted keys, list positions 1-based
    in brackets (``("string", "segments", 1, "length")`` -> ``string.segments[2].length``)."""
    out = ""
    for p in loc:
        if isinstance(p, int):
            out += f"[{p + 1}]"
        elif not str(p).startswith("function-"):
            out += f".{p}" if out else str(p)
    return out


def raise_validation(source: str, exc, prefix: str = ""):
    """Raise the first error of a pydantic ``ValidationError`` as a :class:`ScenarioError`
    naming ``source``, the dotted field (``prefix`` + its location) and what was expected."""
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
        got = repr(err["input"])
        msg += f" (got {got[:80] + '...' if len(got) > 80 else got})"
    raise ScenarioError(source, field, msg) from None


# ==================================================================================== tables
# Every table of a scenario file, defined once. A default of None means "the named system's"
# (``[model] preset``) or "derived from the description", as the field's docstring says; the
# command that reads the table resolves it (and says so in docs/scenarios.md).
class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid")


def _not_bool(value):
    if isinstance(value, bool):
        raise ValueError(f"expected a number, a quantity string or [[time, value], ...], got "
                         f"boolean {value}")
    return value


#: A profile: a constant, or breakpoints [[t, value], ...] interpolated linearly.
Profile = Annotated[float | int | str | list, BeforeValidator(_not_bool)]


def profile_to_signal(value, dimension: str, field: str):
    """A scenario profile as a signal: a float (SI) for a constant, ``(times, values)`` arrays
    for ``[[t, value], ...]`` (accepted by :class:`~downhole.sim.SurfaceInputs`).

    Parameters
    ----------
    value : float, str or list
        The file's value.
    dimension : str
        Its physical dimension (``"velocity"``, ...).
    field : str
        The key, for messages.

    Raises
    ------
    ValueError
        An empty profile, a bad pair or decreasing times.
    """
    if isinstance(value, list):
        if not value:
            raise ValueError(f"{field}: empty profile; give a value or [[t, value], ...]")
        ts, vs = [], []
        for i, pair in enumerate(value):
            if not (isinstance(pair, list) and len(pair) == 2):
                raise ValueError(f"{field}[{i}]: expected [time, value], got {pair!r}")
            ts.append(to_si(pair[0], "time"))
            vs.append(to_si(pair[1], dimension))
        if any(b < a for a, b in itertools.pairwise(ts)):
            raise ValueError(f"{field}: breakpoint times must be non-decreasing, got {ts}")
        return (np.array(ts), np.array(vs))
    return to_si(value, dimension)


def _signal(v, dim: str, name: str):
    if v is None:
        return None
    try:
        return profile_to_signal(v, dim, name)
    except UnitError as exc:
        raise ValueError(str(exc)) from None


def _pair(v):
    if not (isinstance(v, (list, tuple)) and len(v) == 2
            and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v)):
        raise ValueError(f"expected two numbers [axial, torsional], got {v!r}")
    return tuple(float(x) for x in v)


Pair = Annotated[tuple[float, float], BeforeValidator(_pair)]


# ------------------------------------------------------------------------------------ [model]
class _FidelityOptions(_Strict):
    friction: float | None = Field(None, ge=0, le=10)


class LumpedOptions(_FidelityOptions):
    """``[model.lumped4]`` / ``[model.lumped12]``: the FEM whose first frequency the chain of a
    described system matches."""

    reference_elements: int = Field(400, ge=20, le=2000)


class NeutralOptions(_FidelityOptions):
    """``[model.neutral]``: segment kinds lumped into the bit besides collars and "bha"."""

    lump: list[Literal["pipe", "heavyweight"]] = Field(default_factory=list, max_length=2)


class _MeshOptions(_FidelityOptions):
    max_element_length: Q["length"] = Field(50.0, ge=0.1, le=1e4)
    max_element_angle: Q["angle"] = Field(math.radians(2.0), gt=0, le=math.pi)
    mass: Literal["consistent", "lumped"] = "consistent"


class FemOptions(_MeshOptions):
    """``[model.fem]``: the FEM mesh (default: derived from the description)."""

    n_elements: int | None = Field(None, ge=1, le=5000)


class HybridOptions(_MeshOptions):
    """``[model.hybrid]``: the hybrid's mesh (a named mesh, node counts, or derived)."""

    preset: Literal["hybrid24", "hybrid68", "hybrid108"] | None = None
    n_ab: int | None = Field(None, ge=2, le=2000)
    n_cd: int | None = Field(None, ge=2, le=2000)
    n_lags: int = Field(0, ge=0, le=8)


class ModelTable(_Strict):
    """``[model]``: the fidelity, a named system (``preset``) or the described one (``[well]``,
    ``[string]``), and the constants of the description. ``None`` means the named system's value
    (a described system: friction 0, Rayleigh 0.05 / 0.03)."""

    fidelity: str
    preset: str | None = Field(None, max_length=64)
    interface: Literal["surface", "state"] = "surface"
    string: dict[str, Any] = Field(default_factory=dict)
    friction: float | None = Field(None, ge=0, le=10)
    friction_velocity: Q["velocity"] = Field(1e-3, gt=0)
    damping: Literal["rayleigh", "modal"] = "rayleigh"
    rayleigh_alpha: float | None = Field(None, ge=0, le=1e3)
    rayleigh_beta: float | None = Field(None, ge=0, le=1e3)
    modal_ratio: float = Field(0.03, gt=0, lt=1)
    lump_length: Q["length"] = Field(10.0, gt=0)
    wave_section: list[Q["length"]] | None = Field(None, min_length=2, max_length=2)
    lumped4: LumpedOptions = LumpedOptions()
    lumped12: LumpedOptions = LumpedOptions()
    neutral: NeutralOptions = NeutralOptions()
    fem: FemOptions = FemOptions()
    hybrid: HybridOptions = HybridOptions()

    @field_validator("fidelity")
    @classmethod
    def _fidelity(cls, v):
        if not v or len(v) > 64:
            raise ValueError(f"expected a fidelity ({', '.join(FIDELITIES)}), got {v!r}")
        return v

    @field_validator("wave_section", mode="after")
    @classmethod
    def _wave_section(cls, ws):
        if ws is not None and not 0 < ws[0] < ws[1]:
            raise ValueError(f"expected [B, C] with 0 < B < C (m), got {ws}")
        return ws

    def options(self, fidelity: str | None = None):
        """The per-fidelity table of ``fidelity`` (default: this table's), or None."""
        return getattr(self, fidelity or self.fidelity, None)

    def friction_at(self, fidelity: str | None = None) -> float | None:
        """The wall friction at ``fidelity``: its table's, else ``friction`` (None: the named
        system's)."""
        own = getattr(self.options(fidelity), "friction", None)
        return self.friction if own is None else own


# ------------------------------------------------------------------------- [well], [string]
class SectionTable(_Strict):
    """One ``[[well.sections]]`` entry."""

    type: Literal["vertical", "tangent", "arc", "build_turn"]
    length: Q["length"] | None = Field(None, gt=0)
    radius: Q["length"] | None = Field(None, gt=0)
    angle: Q["angle"] | None = Field(None, gt=0, lt=math.pi)
    toolface: Q["angle"] = 0.0
    azimuth: Q["angle"] | None = None
    inclination: Q["angle"] | None = Field(None, ge=0, le=math.pi)

    @model_validator(mode="after")
    def _needs(self):
        need = {"vertical": ("length",), "tangent": ("length",), "arc": ("radius", "angle"),
                "build_turn": ("length", "inclination", "azimuth")}[self.type]
        missing = [k for k in need if getattr(self, k) is None]
        if missing:
            raise ValueError(f"a {self.type!r} section needs {', '.join(missing)}")
        return self


class WellTable(_Strict):
    """``[well]``: a survey CSV, survey columns or sections (exactly one), and the hole's
    diameter (default: the bit's)."""

    survey: str | None = None
    units: Literal["si", "oilfield"] = "si"
    hole_diameter: Q["length"] | None = Field(None, gt=0)
    md: list[float] | None = None
    inclination: list[float] | None = None
    azimuth: list[float] | None = None
    sections: list[SectionTable] | None = None

    @model_validator(mode="after")
    def _one_source(self):
        cols = [self.md, self.inclination, self.azimuth]
        given = [self.survey is not None, any(c is not None for c in cols),
                 self.sections is not None]
        if sum(given) != 1:
            raise ValueError("give exactly one of survey (a CSV file), md/inclination/azimuth "
                             "(stations, m and deg) or [[well.sections]]")
        if given[1] and any(c is None for c in cols):
            raise ValueError("stations need all of md, inclination and azimuth")
        if self.sections is not None and not self.sections:
            raise ValueError("sections is empty")
        return self


class SegmentTable(_Strict):
    """One ``[[string.segments]]`` entry (a uniform tubular)."""

    kind: Literal["pipe", "heavyweight", "collar", "bha"] = "pipe"
    length: Q["length"] | None = Field(None, gt=0)
    catalogue: str | None = None
    outer_diameter: Q["length"] | None = Field(None, gt=0)
    inner_diameter: Q["length"] | None = Field(None, ge=0)
    young_modulus: Q["pressure"] = Field(2.1e11, gt=0)
    shear_modulus: Q["pressure"] = Field(8.08e10, gt=0)
    density: Q["density"] = Field(7850.0, gt=0)

    @model_validator(mode="after")
    def _diameters(self):
        if self.catalogue is not None:
            if self.outer_diameter is not None or self.inner_diameter is not None:
                raise ValueError("give either catalogue or outer_diameter/inner_diameter")
            from downhole.string.catalogue import catalogue_section

            try:
                catalogue_section(self.catalogue)
            except Exception as exc:
                raise ValueError(str(exc)) from None
            return self
        if self.outer_diameter is None or self.inner_diameter is None:
            raise ValueError("give outer_diameter and inner_diameter, or a catalogue name "
                             "(e.g. catalogue = \"5in 19.50 S135 NC50\")")
        if self.inner_diameter >= self.outer_diameter:
            raise ValueError(f"inner_diameter ({self.inner_diameter:g} m) must be smaller than "
                             f"outer_diameter ({self.outer_diameter:g} m)")
        return self


class StabilizerTable(_Strict):
    """One ``[[string.stabilizers]]`` entry."""

    distance_from_bit: Q["length"] = Field(..., ge=0)
    outer_diameter: Q["length"] = Field(..., gt=0)


class StringTable(_Strict):
    """``[string]``: segments from surface to bit, stabilizers, mud density."""

    segments: list[SegmentTable] | None = Field(None, max_length=1000)
    stabilizers: list[StabilizerTable] = Field(default_factory=list, max_length=1000)
    mud_density: Q["density"] = Field(0.0, ge=0)

    @field_validator("segments", mode="after")
    @classmethod
    def _lengths(cls, v):
        if v is not None:
            if not v:
                raise ValueError("segments is empty")
            for k, seg in enumerate(v[:-1]):
                if seg.length is None:
                    raise ValueError(f"segment {k + 1}: only the last segment may omit "
                                     "length")
        return v


# ------------------------------------------------------------------------------------ [rig]
class TopDriveTable(_Strict):
    """``[rig.top_drive]``: inertia and PI speed controller (None: the named system's; a
    described system: 500 kg m^2, 1e4 N m s/rad, 2e3 N m/rad)."""

    inertia: Q["inertia"] | None = Field(None, gt=0)
    kp: Q["torsional_damping"] | None = Field(None, ge=0)
    ki: Q["torsional_stiffness"] | None = Field(None, ge=0)


class HookTable(_Strict):
    """``[rig.hook]``: force-driven (hook load) or velocity-driven (block servo); ``mode``
    None: velocity with an ``operation.rop``, force otherwise."""

    mode: Literal["force", "velocity"] | None = None
    servo_stiffness: Q["stiffness"] = Field(1e7, gt=0)
    servo_damping: Q["damping"] = Field(1e6, gt=0)
    block_mass: Q["mass"] = Field(0.0, ge=0)


class RigTable(_Strict):
    """``[rig]``."""

    top_drive: TopDriveTable = TopDriveTable()
    hook: HookTable = HookTable()


# ------------------------------------------------------------------------------ [operation]
_OPERATION_DIMS = {"surface_speed": "angular_velocity", "rop": "velocity", "wob": "force",
                   "hook_load": "force", "surface_torque": "torque",
                   "axial_command": "velocity"}


class OperationTable(_Strict):
    """``[operation]``: the set-points, each a constant or ``[[t, value], ...]``.

    ``mode`` "velocity" drives the top by ``rop`` and ``surface_speed``, "force" by
    ``hook_load`` and ``surface_torque``; ``wob`` is the axial set-point of a force hook (or the
    WOB of the initial state); ``axial_command`` is the neutral model's U_A (seed convention).
    None: the named system's operating point (docs/scenarios.md)."""

    mode: Literal["velocity", "force"] | None = None
    surface_speed: Profile | None = None
    rop: Profile | None = None
    wob: Profile | None = None
    hook_load: Profile | None = None
    surface_torque: Profile | None = None
    axial_command: Profile | None = None

    @field_validator("surface_speed", mode="before")
    @classmethod
    def _plausible_speed(cls, v):
        from downhole.units import check_rotary_speed

        return v if v is None or isinstance(v, list) else check_rotary_speed(v)

    @field_validator(*_OPERATION_DIMS, mode="after")
    @classmethod
    def _profile(cls, v, info):
        v = _signal(v, _OPERATION_DIMS[info.field_name], info.field_name)
        if isinstance(v, float) and info.field_name in ("wob", "rop") and v < 0:
            raise ValueError(f"expected a value >= 0, got {v:g}")
        return v

    @model_validator(mode="after")
    def _force_mode(self):
        if self.mode == "force" and (self.hook_load is None or self.surface_torque is None):
            raise ValueError("mode 'force' needs both hook_load and surface_torque")
        return self


# ------------------------------------------------------------------------------ [reference]
_Velocity = Annotated[Q["velocity"], Field(ge=-1.0, le=1.0)]
_Angular = Annotated[Q["angular_velocity"], Field(ge=-200.0, le=200.0)]

#: The reference types a file may name (the command that reads them says which it takes).
REFERENCE_TYPES = ("constant", "breakpoints", "step", "ramp", "sine", "user", "eq3.34-3.35",
                   "seed_tracking")


class ReferenceTable(_Strict):
    """``[reference]``: the bit-velocity reference.

    ``constant`` / ``step``: ``axial_velocity`` and ``angular_velocity``; ``breakpoints``: the
    same as ``[[t, value], ...]``; ``ramp`` (Eqs. 4.48-4.49, ``t_final``), ``sine`` (Eq. 4.47,
    ``frequency``), ``user`` (``time`` and the ``*_values`` lists); ``eq3.34-3.35`` /
    ``seed_tracking`` (``v``, ``omega``, ``max_depth_of_cut``). ``*_min`` / ``*_max`` bound a
    set-point changed while running (SIL). None: the command's default (docs/scenarios.md)."""

    type: Literal[REFERENCE_TYPES] | None = None
    axial_velocity: Profile | None = None
    angular_velocity: Profile | None = None
    t_final: Q["time"] | None = Field(None, gt=0, le=1e5)
    frequency: Q["angular_velocity"] | None = Field(None, ge=0, le=1e3)
    time: list[Q["time"]] = Field(default_factory=list, max_length=100_000)
    axial_velocity_values: list[_Velocity] = Field(default_factory=list, max_length=100_000)
    angular_velocity_values: list[_Angular] = Field(default_factory=list, max_length=100_000)
    v: Q["velocity"] = Field(0.005, gt=0)
    omega: Q["angular_velocity"] = Field(20.0, gt=0)
    max_depth_of_cut: Q["length"] | bool = 6e-3
    axial_velocity_min: Q["velocity"] = 0.0
    axial_velocity_max: Q["velocity"] = 0.05
    angular_velocity_min: Q["angular_velocity"] = 0.0
    angular_velocity_max: Q["angular_velocity"] = 40.0

    @field_validator("axial_velocity", "angular_velocity", mode="after")
    @classmethod
    def _sig(cls, v, info):
        axial = info.field_name == "axial_velocity"
        v = _signal(v, "velocity" if axial else "angular_velocity", info.field_name)
        bound = 1.0 if axial else 200.0
        if isinstance(v, float) and not abs(v) <= bound:
            raise ValueError(f"expected a value between {-bound:g} and {bound:g} (SI), got "
                             f"{v:g}")
        return v

    @model_validator(mode="after")
    def _consistent(self):
        sigs = (self.axial_velocity, self.angular_velocity)
        if self.type in ("constant", "step"):
            if any(isinstance(s, tuple) for s in sigs):
                raise ValueError(f"type {self.type!r} takes numbers; use type = 'breakpoints' "
                                 "for [[t, value], ...]")
        elif self.type == "breakpoints":
            if any(s is None for s in sigs):
                raise ValueError("type 'breakpoints' needs axial_velocity and angular_velocity")
        elif self.type in ("eq3.34-3.35", "seed_tracking") and any(s is not None for s in sigs):
            raise ValueError(f"type {self.type!r} is fixed by Eqs. 3.34/3.35 (set v, omega, "
                             "max_depth_of_cut); axial_velocity/angular_velocity do not apply")
        if self.max_depth_of_cut is True:
            raise ValueError("max_depth_of_cut: give a length or false")
        return self


# ----------------------------------------------------------------------------- [controller]
def _no_bool(value):
    if isinstance(value, bool):
        raise ValueError(f"expected a friction coefficient (a number >= 0: omit it for the "
                         f"well's own, 0 for none), got boolean {str(value).lower()}")
    return value


class EIDOptions(_Strict):
    """The keys of ``[controller]`` with ``type = "eid"``: design options (or a saved
    ``file``)."""

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

    def design_options(self) -> dict:
        """The design keyword arguments that were set."""
        return {k: v for k, v in self.model_dump().items() if v is not None}


class SoftTorqueOptions(_Strict):
    """The keys of ``[controller]`` with ``type = "soft_torque"``."""

    soft_gain: float = Field(2e-4, ge=0)
    soft_tau: Q["time"] = Field(2.0, gt=0)


class DHPTraining(_Strict):
    """``[controller.dhp.training]``: the horizon and the DHPSettings (None: the design's
    default, docs/dhp.md)."""

    horizon: Q["time"] | None = Field(None, gt=0, le=1e5)
    method: str = Field("riccati", max_length=64)
    n_samples: StrictInt | None = Field(None, ge=1, le=100_000)
    n_iterations: StrictInt = Field(20, ge=1, le=10_000)
    threshold: float = Field(1e-6, gt=0)
    sample_radius: float | list[float] = 0.02
    warm_start: bool = True
    seed: StrictInt = Field(0, ge=0)
    resample_every: StrictInt = Field(1, ge=1, le=100_000)
    threads: StrictInt = Field(1, ge=1, le=1024)
    use_feed_forward: bool = True
    past_horizon: Literal["stationary", "error"] = "stationary"


class DHPDesign(_Strict):
    """``[controller.dhp]``: the design model, the weights, the training and the plan."""

    design: Literal["fem24", "fem", "lumped", "hybrid24", "hybrid68"] | None = None
    elements: StrictInt | None = Field(None, ge=3, le=500)
    preset: str | None = Field(None, max_length=64)
    dt: Q["time"] = Field(1e-3, gt=0, le=0.1)
    input_limits: tuple[tuple[Q["force"], Q["force"]], tuple[Q["torque"], Q["torque"]]] = (
        (-50e3, 300e3), (-60e3, 60e3))
    friction: Annotated[float, BeforeValidator(_no_bool)] | None = Field(None, ge=0, le=10)
    weights: str | dict[str, Any] | None = None
    training: DHPTraining = DHPTraining()
    plan: dict[str, Any] | None = None


class DHPOptions(_Strict):
    """The keys of ``[controller]`` with ``type = "dhp"``: the design table."""

    dhp: DHPDesign = DHPDesign()


class _NoOptions(_Strict):
    pass


#: Controller types a scenario may name, with the model of their own keys of ``[controller]``
#: (beside ``type``, ``file``, ``enabled`` and ``remote``). :func:`register_controller` adds one.
CONTROLLER_TYPES: dict[str, type[BaseModel]] = {
    "none": _NoOptions, "pi": _NoOptions, "file": _NoOptions, "soft_torque": SoftTorqueOptions,
    "eid": EIDOptions, "dhp": DHPOptions,
}


def register_controller(name: str, options: type[BaseModel] | None = None) -> None:
    """Let scenario files name a controller type: ``[controller] type = name``, whose further
    keys are validated by ``options`` (a pydantic model; None: no keys).

    Parameters
    ----------
    name : str
        The type name.
    options : pydantic model class, optional
        Its keys in ``[controller]``.
    """
    CONTROLLER_TYPES[name] = options or _NoOptions


class ControllerTable(BaseModel):
    """``[controller]``: ``type`` (a registered controller, :data:`CONTROLLER_TYPES`; None: the
    command's default), ``file`` (a saved controller), ``enabled``, ``remote`` (over the link) and
    the type's own keys, validated by its registered model (:attr:`options`)."""

    model_config = ConfigDict(extra="allow")

    _options: Any = PrivateAttr(None)
    type: str | None = Field(None, max_length=64)
    file: str | None = Field(None, min_length=1, max_length=4096)
    enabled: bool = True
    remote: bool = False

    @property
    def options(self):
        """The type's keys, validated (set by :func:`parse`)."""
        return self._options


# ------------------------------------------------------------------------------ [simulation]
class NoiseTable(_Strict):
    """``[simulation.noise]``: white-noise standard deviations of the measurements."""

    axial_velocity: Q["velocity"] = Field(0.0, ge=0)
    angular_velocity: Q["angular_velocity"] = Field(0.0, ge=0)
    wob: Q["force"] = Field(0.0, ge=0)
    tob: Q["torque"] = Field(0.0, ge=0)


#: The default step per fidelity, s (the SIL runtime's is its period, 1 ms).
DEFAULT_DT = {"lumped4": 5e-4, "lumped12": 5e-4, "neutral": 1e-4, "fem": 1e-3, "hybrid": 1e-3}


class SimulationTable(_Strict):
    """``[simulation]``: ``duration`` (None: the command's, e.g. the DHP horizon), ``dt``
    (None: :data:`DEFAULT_DT` of the fidelity), ``record_dt`` (None: every step), the depth of
    cut, the integrator, the start, the noise seed and ``[simulation.noise]``."""

    duration: Q["time"] | None = Field(None, gt=0)
    dt: Q["time"] | None = Field(None, gt=0, le=0.1)
    record_dt: Q["time"] | None = Field(None, gt=0)
    depth_of_cut: Literal["delayed", "approximate"] = "delayed"
    integrator: Literal["euler", "newmark"] = "newmark"
    rock_memory: bool = True
    start: Literal["rest", "off_bottom", "steady"] = "rest"
    seed: int = Field(0, ge=0)
    noise: NoiseTable = NoiseTable()

    def step(self, fidelity: str) -> float:
        """``dt``, or the fidelity's default."""
        return self.dt if self.dt is not None else DEFAULT_DT.get(fidelity, 1e-3)


# ----------------------------------------------------------- [realtime] [link] [safety] ...
class RealtimeTable(_Strict):
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


class LinkTable(_Strict):
    """``[link]``: the UDP address the plant binds."""

    host: str = "127.0.0.1"
    port: int = Field(47600, ge=0, le=65535)
    connect_timeout: Q["time"] = Field(300.0, gt=0)
    mode: Literal["sil", "hil"] = "sil"


class SafetyTable(_Strict):
    """``[safety]``: the controller-timeout action."""

    timeout: Q["time"] = Field(0.1, ge=0)
    hold: Q["time"] = Field(0.2, ge=0)
    ramp: Q["time"] = Field(2.0, ge=0)
    resume: Literal["manual", "auto"] = "manual"


class DashboardTable(_Strict):
    """``[dashboard]``."""

    host: str = "127.0.0.1"
    port: int = Field(8765, ge=0, le=65535)
    token: str | None = None
    token_file: str | None = None
    publish_hz: float = Field(20.0, gt=0, le=100)
    allowed_origins: list[str] = []
    allowed_hosts: list[str] = []
    units: Literal["metric", "field", "oilfield", "si"] = "metric"


# ------------------------------------------------------------------------------ [optimize]
#: Largest DP grid (points per state axis, input levels per axis).
MAX_GRID_POINTS = 2001


class _Frozen(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class TargetSpec(_Frozen):
    """``[optimize.targets]``: mean (v_m, w_m) and final (v_d, w_d) bit velocities of
    Eq. 2.13."""

    v_m: Q["velocity"] = 0.01
    w_m: Q["angular_velocity"] = 10.0
    v_d: Q["velocity"] = 0.01
    w_d: Q["angular_velocity"] = 10.0


class WeightSpec(_Frozen):
    """``[optimize.weights]``: lambda1..lambda4 of Eq. 2.13 (docs/dp.md)."""

    lambda1: float = Field(1.0e4, ge=0)
    lambda2: float = Field(1.0e-2, ge=0)
    lambda3: float = Field(1.0e5, ge=0)
    lambda4: float = Field(1.0e-1, ge=0)


class BoundSpec(_Frozen):
    """``[optimize.bounds]``: admissible inputs as string loads (the feasible set of Eq. 2.14).

    ``force`` bounds the string force K_a (u1 - x1) (N, slack-off relative to the hanging
    equilibrium), ``torque`` the string torque K_t (u2 - x3) (N m); both are checked at both ends
    of every DP step. ``top_speed`` / ``rotary_speed`` (optional) bound the mean top-drive axial
    speed (m/s) and rotary speed (rad/s) over each step of the replayed input (the input rates).
    """

    force: tuple[Q["force"], Q["force"]] = (0.0, 200.0e3)
    torque: tuple[Q["torque"], Q["torque"]] = (0.0, 30.0e3)
    top_speed: tuple[Q["velocity"], Q["velocity"]] | None = None
    rotary_speed: tuple[Q["angular_velocity"], Q["angular_velocity"]] | None = None


class RobustSpec(_Frozen):
    """``[optimize.robust]``: the ensemble of epsilon scale factors of the robust DP (Eq. 2.25)
    and the integration substep (the seed states the ensemble three ways, hence a parameter)."""

    epsilon_scales: tuple[float, ...] = Field((0.9, 1.0, 1.1), max_length=100)
    substep: Q["time"] = Field(5e-3, gt=0)


class StandardSpec(_Frozen):
    """``[optimize.standard]``: the standard DP's input grid (force x torque levels) and the
    substep of its forward projection."""

    force_levels: int = Field(21, ge=2, le=MAX_GRID_POINTS)
    torque_levels: int = Field(21, ge=2, le=MAX_GRID_POINTS)
    substep: Q["time"] = Field(5e-3, gt=0)


class VelocityGrid(_Strict):
    """``[optimize.x2]``: bit axial velocity grid."""

    min: Q["velocity"]
    max: Q["velocity"]
    points: StrictInt = Field(..., ge=2, le=MAX_GRID_POINTS)


class AngularGrid(_Strict):
    """``[optimize.x4]``: bit angular velocity grid."""

    min: Q["angular_velocity"]
    max: Q["angular_velocity"]
    points: StrictInt = Field(..., ge=2, le=MAX_GRID_POINTS)


class OptimizeTable(_Strict):
    """``[optimize]``: the DP problem and the solver (``method``; ``--method`` overrides)."""

    method: Literal["customized", "standard", "robust"] | None = None
    horizon: Q["time"] = Field(20.0, gt=0)
    step: Q["time"] = Field(0.25, gt=0)
    x1_regions: StrictInt | None = Field(None, le=MAX_GRID_POINTS)
    x3_regions: StrictInt | None = Field(None, le=MAX_GRID_POINTS)
    x2: VelocityGrid = VelocityGrid(min=0.0, max=0.02, points=21)
    x4: AngularGrid = AngularGrid(min=0.0, max=20.0, points=21)
    targets: TargetSpec = TargetSpec()
    weights: WeightSpec = WeightSpec()
    bounds: BoundSpec = BoundSpec()
    robust: RobustSpec = RobustSpec()
    standard: StandardSpec = StandardSpec()


# ---------------------------------------------------------------------------- [torque_drag]
class TorqueDragTable(_Strict):
    """``[torque_drag]``: settings of ``downhole torque-drag``."""

    friction_factors: list[float] = Field([0.1, 0.2, 0.3], min_length=1, max_length=20)
    step: Q["length"] = Field(10.0, ge=0.1, le=1000.0)
    vertical_section_azimuth: Q["angle"] | None = None
    wob: Q["force"] | None = Field(None, gt=0)
    tob: Q["torque"] | None = Field(None, ge=0)

    @field_validator("friction_factors", mode="before")
    @classmethod
    def _no_bools(cls, v):
        if isinstance(v, list) and any(isinstance(f, bool) for f in v):
            raise ValueError(f"expected numbers (friction factors), got {v!r}")
        return v

    @field_validator("friction_factors")
    @classmethod
    def _factors(cls, v):
        for f in v:
            if not (math.isfinite(f) and 0.0 <= f <= 10.0):
                raise ValueError(f"friction factors must be between 0 and 10, got {f!r}")
        return v


# ------------------------------------------------------------------------------- the file
class Scenario(_Strict):
    """A whole scenario file: every table, each defined once (``docs/scenarios.md``)."""

    title: str = Field("", max_length=400)
    description: str = Field("", max_length=20_000)
    model: ModelTable
    well: WellTable | None = None
    string: StringTable | None = None
    bit: dict[str, Any] = Field(default_factory=dict)
    rig: RigTable = RigTable()
    operation: OperationTable = OperationTable()
    reference: ReferenceTable | None = None
    controller: ControllerTable = ControllerTable()
    simulation: SimulationTable | None = None
    realtime: RealtimeTable = RealtimeTable()
    link: LinkTable = LinkTable()
    safety: SafetyTable = SafetyTable()
    dashboard: DashboardTable = DashboardTable()
    sweep: dict[str, Any] | None = None
    optimize: OptimizeTable | None = None
    torque_drag: TorqueDragTable = TorqueDragTable()

    @property
    def described(self) -> bool:
        """True when the file describes the well and string (``[well]`` / ``[string]``)."""
        return self.well is not None or self.string is not None


def parse(data: dict, source: str) -> Scenario:
    """Validate a parsed scenario (after :func:`check_dialect`): the one :class:`Scenario`,
    with the controller type's own keys validated by its registered model.

    Parameters
    ----------
    data, source : dict, str
        The parsed file and its name (for messages).

    Returns
    -------
    Scenario

    Raises
    ------
    ScenarioError
        Naming the file, the dotted field and what was expected.
    """
    try:
        sc = Scenario.model_validate(data)
    except ValidationError as exc:
        raise_validation(source, exc)
    ctl = sc.controller
    kind = ctl.type or "none"
    if kind not in CONTROLLER_TYPES:
        raise ScenarioError(source, "controller.type", f"unknown controller {kind!r}; "
                            f"expected one of {', '.join(sorted(CONTROLLER_TYPES))} (or "
                            "register one: downhole.scenario.schema.register_controller)")
    try:
        ctl._options = CONTROLLER_TYPES[kind].model_validate(ctl.model_extra or {})
    except ValidationError as exc:
        raise_validation(source, exc, "controller.")
    return sc


def refuse_keys(data: dict, source: str, keys: dict[str, str]) -> None:
    """Refuse keys of the one schema that a command does not use, with one line each.

    Parameters
    ----------
    data, source : dict, str
        The parsed file and its name (for messages).
    keys : dict
        Dotted key -> why it does not apply (and what to use instead).

    Raises
    ------
    ScenarioError
        Naming the first such key present in ``data``.
    """
    for dotted, why in keys.items():
        if _lookup(data, dotted)[0]:
            raise ScenarioError(source, dotted, why)


def constant(value, source: str, field: str, default: float | None = None) -> float | None:
    """``value`` (a parsed profile) as a constant, ``default`` when None.

    Parameters
    ----------
    value : float, tuple or None
        The parsed field (a float, or ``(times, values)`` for a profile).
    source, field : str
        The file and the dotted field, for messages.
    default : float, optional
        The value for None.

    Raises
    ------
    ScenarioError
        A profile (``[[t, value], ...]``) where the command takes a constant.
    """
    if value is None:
        return default
    if isinstance(value, tuple):
        raise ScenarioError(source, field, "a constant here (this command does not take a "
                            "[[t, value], ...] profile)")
    return float(value)


def _leaves(data: dict, prefix: str = ""):
    for key, value in data.items():
        dotted = f"{prefix}{key}"
        if isinstance(value, dict) and value:
            yield from _leaves(value, dotted + ".")
        else:
            yield dotted, isinstance(value, dict)


def only_keys(data: dict, source: str, allowed: tuple[str, ...], what: str) -> None:
    """Refuse every key of ``data`` a command does not read (the one schema holds the keys of
    every command; each command reads some of them).

    Parameters
    ----------
    data, source : dict, str
        The parsed file and its name (for messages).
    allowed : tuple of str
        The dotted keys the command reads; a key also allows every key below it.
    what : str
        The command or runner, for messages (``"a neutral preset"``).

    Raises
    ------
    ScenarioError
        Naming the first key not read, and the keys of its table that are.
    """
    for dotted, table in _leaves(data):
        if any(dotted == a or dotted.startswith(a + ".") or (table and a.startswith(dotted + "."))
               for a in allowed):
            continue
        if not _known(dotted):
            raise ScenarioError(source, dotted, "unknown key (check spelling; see "
                                "docs/scenarios.md)")
        parent = dotted.rsplit(".", 1)[0] if "." in dotted else ""
        near = [a for a in allowed if parent and a.startswith(parent + ".")]
        hint = f"; it reads {', '.join(near)}" if near else ""
        owner = next((cmd for key, cmd in OTHER_COMMANDS.items()
                      if dotted == key or dotted.startswith(key + ".")), None)
        if owner:
            hint += f"; {owner} reads it"
        raise ScenarioError(source, dotted, f"not used by {what}{hint} (see docs/scenarios.md)")


#: Keys that only another command reads (named by :func:`only_keys`' refusal).
OTHER_COMMANDS = {"optimize": "`downhole optimize dp`", "sweep": "`downhole sweep`",
                  "model.interface": "`downhole sil`", "link": "`downhole sil`",
                  "realtime": "`downhole sil`", "safety": "`downhole sil`",
                  "dashboard": "`downhole sil`"}


def _known(dotted: str) -> bool:
    """True when ``dotted`` names a key of the one schema (a registered controller's included)."""
    model: Any = Scenario
    for part in dotted.split("."):
        if model is ControllerTable and part not in ControllerTable.model_fields:
            known = [m for m in CONTROLLER_TYPES.values() if part in m.model_fields]
            if not known:
                return False
            model = known[0].model_fields[part].annotation
        elif isinstance(model, type) and issubclass(model, BaseModel):
            if part not in model.model_fields:
                return False
            model = model.model_fields[part].annotation
        else:
            return True   # below a free table ([bit], model.string, [sweep], a dict)
        model = next((a for a in (*getattr(model, "__args__", ()), model)
                      if isinstance(a, type) and issubclass(a, BaseModel)), dict)
    return True
