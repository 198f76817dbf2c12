"""The optimal drilling control problem of seed Eqs. 2.12-2.14 as a validated, immutable object.

A :class:`DPProblem` holds the horizon and DP step, the (x2, x4) search grids (bit axial and
angular velocity), the optional x1/x3 index regions of the seed's Table 2.2, the cost weights
lambda1..4 and targets (v_m, w_m, v_d, w_d) of Eq. 2.13, the string force/torque bounds (and
optional top-drive speed bounds), the 4th-order model parameters (a preset, e.g. ``table_2_1``,
with optional bit-parameter overrides) and the settings of the standard and robust DP. Every
inconsistency is rejected with a precise :class:`~downhole.errors.DownholeInputError` (or
:class:`~downhole.errors.ScenarioError` when loaded from a TOML file) before any search.

A problem file (:func:`load_problem`, ``docs/dp.md``) uses the tables of every scenario
(:mod:`downhole.scenario.schema`): ``[model]`` (``fidelity = "lumped4"``, ``preset``), ``[bit]``
(``epsilon`` and any other bit parameter over the preset's) and ``[optimize]`` (the problem:
``method``, ``horizon``, ``step``, ``x1_regions``, ``x3_regions`` and the tables
``[optimize.x2]``, ``[optimize.x4]``, ``[optimize.targets]``, ``[optimize.weights]``,
``[optimize.bounds]``, ``[optimize.robust]``, ``[optimize.standard]``). Physical values take
unit strings ("36 m/h", "20 s", "200 kN"); bare numbers are SI.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError

# the specs of [optimize] are the one scenario schema's (defined once there; DPProblem holds
# them, and they stay importable from here)
from downhole._schema import (
    MAX_GRID_POINTS,
    BoundSpec,
    OptimizeTable,
    RobustSpec,
    Scenario,
    StandardSpec,
    TargetSpec,
    WeightSpec,
    check_dialect,
    parse,
)
from downhole.errors import DownholeInputError, ScenarioError
from downhole.params import BitParams, LumpedParams, get_preset
from downhole.params.quantity import Q

__all__ = [
    "METHOD_NAMES",
    "BoundSpec",
    "DPProblem",
    "GridSpec",
    "ModelArrays",
    "ModelSpec",
    "RobustSpec",
    "StandardSpec",
    "TargetSpec",
    "WeightSpec",
    "dp_problem_of",
    "load_dp_scenario",
    "load_problem",
    "problem_from_dict",
]

#: The solvers a problem file may name in ``optimize.method``.
METHOD_NAMES = ("customized", "standard", "robust")

_TOL = 1e-9


#: Most DP steps / substeps (the largest grid, MAX_GRID_POINTS, is the schema's).
MAX_DP_STEPS = 100_000


class _ProblemError(DownholeInputError):
    """An inconsistent problem; ``field`` is the :class:`DPProblem` field it concerns."""

    def __init__(self, field: str, message: str):
        self.field = field
        super().__init__(message)


class GridSpec(BaseModel):
    """A uniform grid of ``points`` values from ``min`` to ``max`` (both included).

    Parameters
    ----------
    min, max : float
        First and last value, in the grid's SI unit (m/s for x2, rad/s for x4).
    points : int
        Number of values (at most :data:`MAX_GRID_POINTS`).
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    min: float
    max: float
    points: int = Field(..., le=MAX_GRID_POINTS)

    def values(self) -> np.ndarray:
        """The grid values (``points`` floats from ``min`` to ``max``)."""
        return np.linspace(self.min, self.max, self.points)


class ModelSpec(BaseModel):
    """The 4th-order model: a lumped preset, an optional epsilon override (Pa) and further
    bit-parameter overrides (``bit``: BitParams fields over the preset's, SI or unit strings).
    ``lumped``: the 4th-order parameters of a described system (LumpedParams fields, derived
    by :meth:`downhole.system.DrillingSystem.build` at ``lumped4``), instead of the preset's."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    preset: str = "table_2_1"
    epsilon: Q["pressure"] | None = None
    bit: dict[str, Any] = Field(default_factory=dict)
    lumped: dict[str, Any] | None = None


class DPProblem(BaseModel):
    """Optimal control problem of seed Eqs. 2.12-2.14 on the 4th-order model.

    Attributes
    ----------
    horizon : float
        Total time T, s.
    step : float
        DP step Delta t, s; must divide ``horizon``.
    x2, x4 : GridSpec
        Search grids of the bit axial velocity (m/s) and angular velocity (rad/s). The initial
        state (0, 0) and the targets must lie on them.
    x1_regions, x3_regions : int or None
        Number of x1 / x3 index regions of the seed's customized DP (Eqs. 2.19-2.20, the "index
        grid" of Table 2.2). None: the DP runs over (x2, x4) only; the optimum is the same.
    targets, weights, bounds, model, robust, standard
        See :class:`TargetSpec`, :class:`WeightSpec`, :class:`BoundSpec`, :class:`ModelSpec`,
        :class:`RobustSpec`, :class:`StandardSpec`.

    Examples
    --------
    >>> p = DPProblem(horizon=5.0, step=0.25)
    >>> p.steps
    20
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    horizon: Q["time"] = 20.0
    step: Q["time"] = 0.25
    x2: GridSpec = GridSpec(min=0.0, max=0.02, points=21)
    x4: GridSpec = GridSpec(min=0.0, max=20.0, points=21)
    x1_regions: int | None = Field(None, le=MAX_GRID_POINTS)
    x3_regions: int | None = Field(None, le=MAX_GRID_POINTS)
    targets: TargetSpec = TargetSpec()
    weights: WeightSpec = WeightSpec()
    bounds: BoundSpec = BoundSpec()
    model: ModelSpec = ModelSpec()
    robust: RobustSpec = RobustSpec()
    standard: StandardSpec = StandardSpec()

    def __init__(self, **data):
        try:
            super().__init__(**data)
        except ValidationError as exc:
            field, msg = _flatten_error(exc)
            raise _ProblemError(field, f"{field}: {msg}" if field else msg) from None

    # ------------------------------------------------------------------ derived
    @property
    def steps(self) -> int:
        """Number of DP steps N = T / Delta t."""
        return int(round(self.horizon / self.step))

    @property
    def times(self) -> np.ndarray:
        """Sample times k Delta t, k = 0..N (s)."""
        return np.arange(self.steps + 1) * self.step

    def grid2(self) -> np.ndarray:
        """x2 grid values, m/s."""
        return self.x2.values()

    def grid4(self) -> np.ndarray:
        """x4 grid values, rad/s."""
        return self.x4.values()

    def params(self) -> tuple[LumpedParams, BitParams]:
        """The lumped and bit parameters (preset with the epsilon override applied)."""
        preset = get_preset(self.model.preset)
        bit = preset.bit
        if self.model.bit:
            bit = BitParams(**{**bit.model_dump(), **self.model.bit})
        if self.model.epsilon is not None:
            bit = bit.model_copy(update={"epsilon": float(self.model.epsilon)})
        string = preset.string if self.model.lumped is None else LumpedParams(
            **self.model.lumped)
        return string, bit

    def arrays(self, epsilon_scale: float = 1.0) -> ModelArrays:
        """Plain arrays for the compiled kernels, with epsilon scaled by ``epsilon_scale``.

        Parameters
        ----------
        epsilon_scale : float, optional
            Factor on the rock's intrinsic specific energy epsilon (dimensionless, default 1; the
            robust DP uses it for its uncertain-rock scenarios).

        Returns
        -------
        ModelArrays
            The lumped constants of the preset and the compiled bit parameters.
        """
        string, bit = self.params()
        p = bit.kernel_params()
        p = p._replace(epsilon=p.epsilon * epsilon_scale)
        return ModelArrays(mass=string.mass, inertia=string.inertia,
                           ka=string.axial_stiffness, ca=string.axial_damping,
                           kt=string.torsional_stiffness, ct=string.torsional_damping, bit=p)

    def target_indices(self) -> dict[str, int]:
        """Grid indices of the targets and of the initial state (all lie on the grids)."""
        g2, g4 = self.grid2(), self.grid4()
        out = {}
        for name, val, grid in (("v_m", self.targets.v_m, g2), ("v_d", self.targets.v_d, g2),
                                ("w_m", self.targets.w_m, g4), ("w_d", self.targets.w_d, g4),
                                ("x2_0", 0.0, g2), ("x4_0", 0.0, g4)):
            out[name] = int(np.argmin(np.abs(grid - val)))
        return out

    # ------------------------------------------------------------------ validation
    def model_post_init(self, __context) -> None:
        """Pydantic hook after field validation (``__context`` unused): a
        :class:`DownholeInputError` naming the field of an inconsistent problem."""
        self._check()

    def _check(self) -> None:
        err = _ProblemError
        if not self.horizon > 0:
            raise err("horizon", f"horizon must be > 0 s, got {self.horizon!r}")
        if not self.step > 0:
            raise err("step", f"step must be > 0 s, got {self.step!r}")
        ratio = self.horizon / self.step
        if ratio > MAX_DP_STEPS:
            raise err("step",
                      f"step {self.step} s gives horizon/step = {ratio:.3g} DP steps; at most "
                      f"{MAX_DP_STEPS} (step >= {self.horizon / MAX_DP_STEPS:.3g} s)")
        if abs(ratio - round(ratio)) > 1e-6 * max(1.0, ratio) or round(ratio) < 1:
            raise err("step", f"step {self.step} s does not divide horizon {self.horizon} s "
                      f"(horizon/step = {ratio:.6g}; expected a positive integer)")
        for name, grid, unit in (("x2", self.x2, "m/s"), ("x4", self.x4, "rad/s")):
            if grid.points < 2:
                raise err(f"{name}.points",
                          f"grid {name} needs at least 2 points, got points={grid.points}")
            if not (math.isfinite(grid.min) and math.isfinite(grid.max)) or grid.max <= grid.min:
                raise err(f"{name}.max",
                          f"grid {name} is empty or inverted: min={grid.min} {unit} must be < "
                          f"max={grid.max} {unit}")
            vals = grid.values()
            spacing = vals[1] - vals[0]
            for tname, tval in ((("x2 initial state", 0.0), ("v_m", self.targets.v_m),
                                 ("v_d", self.targets.v_d)) if name == "x2" else
                                (("x4 initial state", 0.0), ("w_m", self.targets.w_m),
                                 ("w_d", self.targets.w_d))):
                label = tname if tname.endswith("state") else f"targets.{tname}"
                field = f"{name}.min" if tname.endswith("state") else f"targets.{tname}"
                if tval < grid.min - _TOL * spacing or tval > grid.max + _TOL * spacing:
                    raise err(field, f"{label} = {tval} {unit} is outside the {name} grid "
                              f"[{grid.min}, {grid.max}] {unit}")
                off = np.min(np.abs(vals - tval))
                if off > 1e-6 * spacing:
                    raise err(field, f"{label} = {tval} {unit} is not on the {name} grid "
                              f"(spacing {spacing:.6g} {unit}, nearest point off by {off:.3g}); "
                              f"choose min/max/points so that it is a grid point")
        for name in ("x1_regions", "x3_regions"):
            val = getattr(self, name)
            if val is not None and val < 1:
                raise err(name,
                          f"{name} must be a positive number of regions or omitted, got {val}")
        if (self.x1_regions is None) != (self.x3_regions is None):
            raise err("x3_regions",
                      "x1_regions and x3_regions must be given together (or both omitted), got "
                      f"x1_regions={self.x1_regions}, x3_regions={self.x3_regions}")
        for name, pair, unit in (("force", self.bounds.force, "N"),
                                 ("torque", self.bounds.torque, "N m"),
                                 ("top_speed", self.bounds.top_speed, "m/s"),
                                 ("rotary_speed", self.bounds.rotary_speed, "rad/s")):
            if pair is None:
                continue
            if not (pair[0] < pair[1]):
                raise err(f"bounds.{name}",
                          f"bounds.{name} = {list(pair)} {unit} is empty: expected [min, max] "
                          f"with min < max")
        scales = self.robust.epsilon_scales
        if len(scales) < 1 or any(not (s > 0) for s in scales):
            raise err("robust.epsilon_scales",
                      f"robust.epsilon_scales must be positive factors, got {list(scales)}")
        for name in ("substep",):
            for spec, label in ((self.robust, "robust"), (self.standard, "standard")):
                if self.step / getattr(spec, name) > MAX_DP_STEPS:
                    raise err(f"{label}.{name}",
                              f"{label}.{name} = {getattr(spec, name)} s is below "
                              f"{self.step / MAX_DP_STEPS:.3g} s (at most {MAX_DP_STEPS} "
                              "substeps per DP step)")
                if getattr(spec, name) > self.step:
                    raise err(f"{label}.{name}",
                              f"{label}.{name} = {getattr(spec, name)} s exceeds the DP step "
                              f"{self.step} s")
        try:
            self.params()
        except ValidationError as exc:
            e = exc.errors()[0]
            where = ".".join(str(p) for p in e.get("loc", ()))
            msg = e.get("msg", str(exc)).removeprefix("Value error, ")
            if e.get("type") == "extra_forbidden":
                msg = "unknown bit parameter"
            raise err(f"model.bit.{where}", f"model.bit.{where}: {msg}") from None
        except KeyError as exc:
            raise err("model.preset", f"model.preset: {exc.args[0]}") from None
        preset = get_preset(self.model.preset)
        if preset.kind != "lumped":
            raise err("model.preset",
                      f"model.preset {self.model.preset!r} is a {preset.kind} preset; the DP "
                      "needs a lumped one (e.g. table_2_1, plausible_lumped)")
        self._check_hold_feasible()

    def _check_hold_feasible(self) -> None:
        """The targets must be holdable: steady force/torque at (v_d, w_d) within the bounds."""
        from downhole.control.dp.kernels import steady_loads

        a = self.arrays()
        for label, v, w in (("final target (v_d, w_d)", self.targets.v_d, self.targets.w_d),
                            ("mean target (v_m, w_m)", self.targets.v_m, self.targets.w_m)):
            f, t = steady_loads(v, w, a.ca, a.ct, a.bit)
            lo, hi = self.bounds.force
            if not lo <= f <= hi:
                raise _ProblemError(
                    "bounds.force",
                    f"infeasible bounds: holding the {label} = ({v} m/s, {w} rad/s) needs a "
                    f"string force of {f:.4g} N, outside bounds.force = [{lo:.4g}, {hi:.4g}] N")
            lo, hi = self.bounds.torque
            if not lo <= t <= hi:
                raise _ProblemError(
                    "bounds.torque",
                    f"infeasible bounds: holding the {label} = ({v} m/s, {w} rad/s) needs a "
                    f"string torque of {t:.4g} N m, outside bounds.torque = [{lo:.4g}, {hi:.4g}] "
                    "N m")

    def with_updates(self, **changes) -> DPProblem:
        """A validated copy with top-level fields replaced (nested specs as dicts or objects).

        Parameters
        ----------
        **changes
            Field name -> new value (a plain value, a dict or a pydantic spec object).

        Returns
        -------
        DPProblem
            The new problem.

        Raises
        ------
        ScenarioError
            If the updated problem fails validation (via :func:`problem_from_dict`).
        """
        data = self.model_dump()
        for k, v in changes.items():
            data[k] = v.model_dump() if isinstance(v, BaseModel) else v
        return problem_from_dict(data)


class ModelArrays:
    """Plain floats and the bit law's :class:`~downhole.params.bit.BitKernelParams` handed to the
    compiled kernels.

    Parameters
    ----------
    mass : float
        Equivalent axial mass M of the 4th-order lumped model, kg.
    inertia : float
        Equivalent moment of inertia I, kg m^2.
    ka : float
        Axial stiffness, N/m.
    ca : float
        Axial damping, N s/m.
    kt : float
        Torsional stiffness, N m/rad.
    ct : float
        Torsional damping, N m s/rad.
    bit : BitKernelParams
        Compiled bit parameters.
    """

    __slots__ = ("bit", "ca", "ct", "inertia", "ka", "kt", "mass")

    def __init__(self, mass, inertia, ka, ca, kt, ct, bit):
        self.mass, self.inertia = float(mass), float(inertia)
        self.ka, self.ca, self.kt, self.ct = float(ka), float(ca), float(kt), float(ct)
        self.bit = bit  # a BitKernelParams

    def lumped(self):
        """The kernels' :class:`~downhole.control.dp.kernels.LumpedKernelParams`."""
        from downhole.control.dp.kernels import LumpedKernelParams

        return LumpedKernelParams(mass=float(self.mass), inertia=float(self.inertia),
                                  ka=float(self.ka), ca=float(self.ca), kt=float(self.kt),
                                  ct=float(self.ct))


def _flatten_error(exc: ValidationError) -> tuple[str, str]:
    e = exc.errors()[0]
    inner = (e.get("ctx") or {}).get("error")
    if isinstance(inner, _ProblemError) and not e.get("loc"):
        # raised by DPProblem.__init__ / _check (pydantic wraps it when validating a dict)
        msg = str(inner)
        return inner.field, msg[len(inner.field) + 2:] if inner.field and msg.startswith(
            f"{inner.field}: ") else msg
    field = ".".join(str(p) for p in e.get("loc", ()))
    msg = e.get("msg", str(exc))
    msg = msg.removeprefix("Value error, ")
    if "input" in e and field and not isinstance(e["input"], dict):
        msg += f" (got {e['input']!r})"
    return field, msg


def problem_from_dict(data: dict, source: str = "<dict>") -> DPProblem:
    """Build a :class:`DPProblem` from a plain dict of its fields.

    The dict is ``DPProblem.model_dump()``, as stored in a solution's JSON; a problem *file* is
    read by :func:`load_problem`.

    Parameters
    ----------
    data : dict
        Field name -> value (nested specs as dicts).
    source : str, optional
        Name of the origin of ``data``, used in error messages (default ``"<dict>"``).

    Returns
    -------
    DPProblem

    Raises
    ------
    ScenarioError
        Naming the source, the offending field and what was expected.
    """
    try:
        return DPProblem.model_validate(data)
    except ValidationError as exc:
        field, msg = _flatten_error(exc)
        raise ScenarioError(source, field, msg) from None
    except ScenarioError:
        raise
    except _ProblemError as exc:
        raise ScenarioError(source, exc.field, str(exc)) from None
    except DownholeInputError as exc:
        raise ScenarioError(source, "", str(exc)) from None


# ------------------------------------------------------------------------------ problem files
#: The tables a problem file has (the one schema's other tables are not the DP's).
_TABLES = ("title", "description", "model", "bit", "optimize")
#: The DP's model: the 4th-order lumped model of Eq. 2.1 (``[model]`` may be left out).
_FIDELITY = "lumped4"
_DEFAULT_PRESET = "table_2_1"


def _with_model(data: dict) -> dict:
    """``data`` with the ``[model] fidelity`` the one schema requires and a problem file may
    leave out (the DP's, lumped4); a shallow copy."""
    model = data.get("model")
    if model is None:
        return {**data, "model": {"fidelity": _FIDELITY}}
    if isinstance(model, dict) and "fidelity" not in model:
        return {**data, "model": {**model, "fidelity": _FIDELITY}}
    return data


#: What a problem file that describes its system ([well], [string]) may hold besides _TABLES.
_DESCRIBED_TABLES = ("well", "string", "rig")
_DESCRIBED_MODEL = ("friction", "rayleigh_alpha", "rayleigh_beta", "lumped4")


def _check_dp_tables(sc: Scenario, source: str, described: bool = False) -> None:
    """Refuse what the one schema holds and a problem file does not (one line naming it)."""
    tables = set(_TABLES) | (set(_DESCRIBED_TABLES) if described else set())
    for key in sorted(sc.model_fields_set - tables):
        raise ScenarioError(source, key, "unknown key in a DP problem file (it has title, "
                            "description, [model], [bit] and [optimize], and may describe its "
                            "system with [well] and [string]; see docs/dp.md)")
    own = {"fidelity", "preset"} if not described else {"fidelity", *_DESCRIBED_MODEL}
    for key in sorted(sc.model.model_fields_set - own):
        raise ScenarioError(source, f"model.{key}", "unknown key in a DP problem file ([model] "
                            "has fidelity = 'lumped4' and preset; see docs/dp.md)")
    if sc.model.fidelity != _FIDELITY:
        raise ScenarioError(source, "model.fidelity", f"the DP optimizes the 4th-order lumped "
                            f"model (Eqs. 2.12-2.14): expected 'lumped4', got "
                            f"{sc.model.fidelity!r}")


def _file_field(field: str) -> str:
    """A :class:`DPProblem` field as the problem file names it."""
    if field == "model.preset":
        return field
    if field.startswith("model.bit."):
        return "bit." + field[len("model.bit."):]
    if field == "model.epsilon":
        return "bit.epsilon"
    return f"optimize.{field}" if field else ""


def dp_problem_of(data: dict, source: str = "<dict>", described: tuple | None = None
                  ) -> tuple[DPProblem, str | None]:
    """Validate a parsed problem file: ``(problem, method or None)``.

    The file is validated by the one scenario schema (:func:`downhole._schema.parse`) and read
    from its ``[optimize]`` (absent: the table's defaults), ``[model]`` (absent, or without
    ``fidelity``: lumped4; ``preset`` None: table_2_1) and ``[bit]``; the schema's other
    tables are refused.

    Parameters
    ----------
    data : dict
        The parsed TOML tables (``model``, ``bit``, ``optimize``, ...).
    source : str, optional
        Name of the file (or origin), used in error messages (default ``"<dict>"``).
    described : (dict, dict), optional
        For a file that describes its system: the 4th-order parameters (LumpedParams fields)
        and the bit (BitParams fields) derived from it
        (:func:`downhole.scenario.system.lumped_design_model`); the file's [well], [string],
        [rig] and description keys of [model] are then read there, not here.

    Returns
    -------
    problem : DPProblem
    method : str or None
        ``optimize.method`` if given (one of :data:`METHOD_NAMES`).

    Raises
    ------
    ScenarioError
        Naming the source, the dotted field of the file (``optimize.x2.points``,
        ``bit.epsilon``, ...) and what was expected; a key of the older DP dialect (top-level
        ``horizon``, ``[x2]``, ``[dp]``, ``model.epsilon``, ...) gets the key to use instead.
    """
    check_dialect(data, source)
    sc = parse(_with_model(data), source)
    _check_dp_tables(sc, source, described is not None)
    preset = sc.model.preset or _DEFAULT_PRESET
    bit = dict(sc.bit)
    if described is not None:  # the system's bit (its preset and overrides) and 4th-order model
        bit = dict(described[1])
    if "preset" in bit and described is None:
        raise ScenarioError(source, "bit.preset", f"model.preset = {preset!r} brings "
                            "its bit; give only bit parameters here (epsilon, ...)")
    epsilon = bit.pop("epsilon", None)
    optimize = sc.optimize or OptimizeTable()
    opt = optimize.model_dump(exclude={"method"})
    opt["model"] = {"preset": preset, "epsilon": epsilon, "bit": bit,
                    "lumped": None if described is None else dict(described[0])}
    try:
        problem = DPProblem.model_validate(opt)
    except ValidationError as exc:
        field, msg = _flatten_error(exc)
        raise ScenarioError(source, _file_field(field), msg) from None
    except ScenarioError:
        raise
    except _ProblemError as exc:
        raise ScenarioError(source, _file_field(exc.field), str(exc)) from None
    except DownholeInputError as exc:
        raise ScenarioError(source, "", str(exc)) from None
    return problem, optimize.method


def load_dp_scenario(path: str | Path) -> tuple[DPProblem, str | None]:
    """Read a problem file: ``(problem, optimize.method or None)``.

    Schema in docs/dp.md; examples in ``examples/dp_*.toml``.

    Parameters
    ----------
    path : str or pathlib.Path
        TOML problem file.

    Returns
    -------
    problem : DPProblem
    method : str or None
        ``optimize.method`` if the file gives one.

    Raises
    ------
    ScenarioError
        If the file is unreadable, is not valid TOML or fails validation (one line naming the
        file, the dotted field and what was expected).
    """
    from downhole._schema import read_scenario

    data, source, _ = read_scenario(path)
    if "well" in data or "string" in data:
        raise ScenarioError(source, "well", "this problem file describes its system: "
                            "`downhole optimize dp` derives the 4th-order model from it "
                            "(downhole.scenario.system.lumped_design_model)")
    return dp_problem_of(data, source)


def load_problem(path: str | Path) -> DPProblem:
    """Read a problem file: its :class:`DPProblem` (see :func:`load_dp_scenario`).

    Parameters
    ----------
    path : str or pathlib.Path
        TOML problem file.

    Returns
    -------
    DPProblem

    Raises
    ------
    ScenarioError
        If the file is unreadable, is not valid TOML or fails validation.
    """
    return load_dp_scenario(path)[0]
