"""Sweep specifications: swept parameters (dotted scenario paths), metrics, validation.

Everything here is checked before a single case runs: an unknown parameter path, an empty or
malformed range, mismatched units or an unknown metric raise
:class:`~downhole.errors.DownholeInputError` naming the offending option and value.

Parameter specs (the text after ``NAME=`` in ``--param NAME=SPEC``):

* ``START:STOP:COUNT`` -- COUNT evenly spaced values from START to STOP (grid);
* ``START:STOP`` -- the bounds of a uniform draw (Monte Carlo, ``--random N``);
* ``V1,V2,...`` -- an explicit list of values (grid);
* ``V`` -- a single value (a fixed override, a grid dimension of length 1).

Values are bare numbers (SI) or quantities with units (``"20 rpm"``, ``"5 mm/s"``, ``"25 klbf"``);
when only one of START and STOP carries a unit, both use it (``2:12 rad/s``), and a unit written
after COUNT applies to both ends (``2:20:10 mm/s``).
"""

from __future__ import annotations

import copy
import math
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from downhole.errors import DownholeInputError, ScenarioError
from downhole.signals import METRICS as _REGISTERED_METRICS

__all__ = [
    "METRICS",
    "ParamSpec",
    "compute_metrics",
    "get_path",
    "metric_names",
    "parse_param",
    "parse_window",
    "set_path",
    "validate_path",
]


# --- metrics -----------------------------------------------------------------------------------

@dataclass(frozen=True)
class _Metric:
    units: str
    description: str
    func: Callable | None = None  # func(result, sel) -> float; None: from summarize()


def _mean(ch):
    return lambda res, sel: float(np.mean(res[ch][sel]))


def _max(ch):
    return lambda res, sel: float(np.max(res[ch][sel]))


def _min(ch):
    return lambda res, sel: float(np.min(res[ch][sel]))


#: How a sweep computes a metric that :func:`downhole.analysis.metrics.summarize` does not give:
#: plain means/extremes of channels over the same window.
_CHANNEL_METRICS = {
    "mean_wob": _mean("wob"), "max_wob": _max("wob"), "mean_tob": _mean("tob"),
    "max_tob": _max("tob"), "mean_hook_load": _mean("hook_load"),
    "mean_surface_torque": _mean("surface_torque"), "max_surface_torque": _max("surface_torque"),
    "min_bit_angular_velocity": _min("bit_angular_velocity"),
    "max_bit_angular_velocity": _max("bit_angular_velocity"),
}

#: Metrics a sweep can record: name -> (units, description, how), units and descriptions from
#: the one registry :data:`downhole.signals.METRICS`.
METRICS: dict[str, _Metric] = {
    name: _Metric(m.unit, m.description, _CHANNEL_METRICS.get(name))
    for name, m in _REGISTERED_METRICS.items()
}


def metric_names(metrics) -> list[str]:
    """Validate metric names (order kept, duplicates dropped); raise on unknown ones.

    Parameters
    ----------
    metrics : str or iterable of str
        One metric name or several (keys of :data:`METRICS`).

    Returns
    -------
    list of str
        The names, first occurrence order, without duplicates.

    Raises
    ------
    DownholeInputError
        If no metric is given or a name is unknown (the message lists the known metrics).
    """
    if isinstance(metrics, str):
        metrics = [metrics]
    metrics = list(metrics or [])
    if not metrics:
        raise DownholeInputError("no metric given; name at least one with --metric "
                                 f"(known: {', '.join(METRICS)})")
    out = []
    for m in metrics:
        if not isinstance(m, str) or m not in METRICS:
            raise DownholeInputError(f"unknown metric {m!r}; known metrics: {', '.join(METRICS)}")
        if m not in out:
            out.append(m)
    return out


def compute_metrics(result, metrics: list[str], window: tuple[float, float] | None) -> list[float]:
    """Values of ``metrics`` for one Result over ``window`` (default: second half of the run).

    Parameters
    ----------
    result : Result
        The run.
    metrics : list of str
        Metric names (validated by :func:`metric_names`).
    window : (float, float) or None
        ``(start, end)`` time window, s (inclusive); None for the second half of the run.

    Returns
    -------
    list of float
        One value per metric, in its SI unit (``METRICS[name].units``); NaN where
        :func:`~downhole.analysis.metrics.summarize` gives none.

    Raises
    ------
    ValueError
        If a channel metric's window holds no samples.
    """
    from downhole.analysis.metrics import summarize

    summary = None
    t = result.time
    lo, hi = window if window is not None else (t[0] + 0.5 * (t[-1] - t[0]), t[-1])
    sel = (t >= lo) & (t <= hi)
    out = []
    for m in metrics:
        spec = METRICS[m]
        if spec.func is None:
            if summary is None:
                summary = summarize(result, (lo, hi))
            out.append(float(summary.get(m, math.nan)))
        else:
            if not np.any(sel):
                raise ValueError(f"metric window {lo}..{hi} s holds no samples")
            out.append(spec.func(result, sel))
    return out


def parse_window(window) -> tuple[float, float] | None:
    """``None``, ``(start, end)`` or ``"START:END"`` (seconds, units allowed) -> tuple or None.

    Parameters
    ----------
    window : None, str or pair
        ``"START:END"`` or a pair of numbers (s) or quantity strings (``"10 s"``, ``"1 min"``).

    Returns
    -------
    (float, float) or None
        ``(start, end)`` in s with ``0 <= start < end``, or None.

    Raises
    ------
    DownholeInputError
        A malformed window, a value that is not a time, or bounds out of order.
    """
    from downhole.units import UnitError, to_si

    if window is None:
        return None
    if isinstance(window, str):
        parts = window.split(":")
        if len(parts) != 2:
            raise DownholeInputError(f"window must be START:END in seconds, got {window!r}")
        window = parts
    def _sec(v):
        if isinstance(v, str):
            v = v.strip()
            try:
                return float(v)
            except ValueError:
                pass
        return to_si(v, "time")

    try:
        if len(window) != 2:
            raise ValueError("expected two values (start, end)")
        lo, hi = (_sec(v) for v in window)
    except (UnitError, TypeError, ValueError) as exc:
        raise DownholeInputError(f"window {window!r}: {exc}") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and 0 <= lo < hi):
        raise DownholeInputError(f"window must satisfy 0 <= START < END, got {lo}:{hi} s")
    return (lo, hi)


# --- parameter specs -----------------------------------------------------------------------------

@dataclass(frozen=True)
class ParamSpec:
    """One swept parameter.

    Attributes
    ----------
    path : str
        Dotted scenario path, e.g. ``operation.surface_speed`` or ``bit.epsilon``.
    values : ndarray or None
        Grid values in SI (None for a pure random range).
    low, high : float
        Range bounds in SI (for ``--random``); for grids the first and last value.
    units : str
        SI unit of the values (from the quantity typed; "" for bare numbers).
    text : str
        The spec as typed.
    """

    path: str
    values: np.ndarray | None
    low: float
    high: float
    units: str = ""
    text: str = ""
    count: int | None = field(default=None)


_UNIT_LABELS = {
    "[length] / [time]": "m/s", "1 / [time]": "rad/s", "[length]": "m", "[time]": "s",
    "[mass]": "kg", "[length] * [mass] / [time] ** 2": "N",
    "[length] ** 2 * [mass] / [time] ** 2": "N*m", "[mass] / [length] / [time] ** 2": "Pa",
    "[mass] / [time] ** 2": "N/m", "[mass] / [time]": "N*s/m",
    "[length] ** 2 * [mass] / [time]": "N*m*s/rad", "[length] ** 2 * [mass]": "kg*m**2",
    "[length] / [time] ** 2": "m/s**2", "[mass] / [length] ** 3": "kg/m**3",
}


def _quantity(text: str, what: str, default_unit: str | None = None):
    """Parse ``text`` -> (SI magnitude, SI unit label, had_unit)."""
    from downhole.units import _registry

    s = text.strip()
    if not s:
        raise DownholeInputError(f"{what}: empty value")
    try:
        return float(s), "", False
    except ValueError:
        pass
    ureg = _registry()
    try:
        q = ureg.Quantity(s)
    except Exception as exc:  # pint raises several types
        raise DownholeInputError(f"{what}: cannot parse {s!r} as a number or quantity "
                                 f"({exc})") from None
    if not isinstance(q, ureg.Quantity):
        return float(q), "", False
    base = q.to_base_units()
    dim = str(base.dimensionality)
    label = _UNIT_LABELS.get(dim, "" if dim == "dimensionless" else str(base.units))
    return float(base.magnitude), label, True


#: SI units of scenario paths typed as bare numbers (the last path component, or the full path).
KNOWN_UNITS = {
    "operation.rop": "m/s", "operation.axial_command": "m/s", "operation.surface_speed": "rad/s",
    "operation.hook_load": "N", "operation.surface_torque": "N*m", "operation.wob": "N",
    "reference.axial_velocity": "m/s", "reference.angular_velocity": "rad/s",
    "duration": "s", "dt": "s", "record_dt": "s",
    "mass": "kg", "inertia": "kg*m**2", "axial_stiffness": "N/m", "axial_damping": "N*s/m",
    "torsional_stiffness": "N*m/rad", "torsional_damping": "N*m*s/rad", "g": "m/s**2",
    "epsilon": "Pa", "sigma": "Pa", "radius": "m", "wear_length": "m", "d_star": "m",
    "contact_stiffness": "N/m", "omega_reg": "rad/s", "omega_floor": "rad/s",
}


def known_units(path: str) -> str:
    """SI unit of a scenario path when known (for labelling bare-number sweeps), else ''."""
    return KNOWN_UNITS.get(path, KNOWN_UNITS.get(path.rsplit(".", 1)[-1], ""))


def _split_unit(text: str) -> tuple[str, str]:
    """'12 rad/s' -> ('12', 'rad/s'); '12' -> ('12', '')."""
    m = re.match(r"^\s*([-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?)\s*(.*)$", text)
    if not m:
        return text, ""
    return m.group(1), m.group(4).strip()


def parse_param(text: str, random: bool = False) -> ParamSpec:
    """Parse ``NAME=SPEC`` (see the module docstring) into a :class:`ParamSpec`.

    The path is checked for syntax here; whether the scenario knows it is checked by
    :func:`validate_path`.

    Parameters
    ----------
    text : str
        ``NAME=START:STOP:COUNT`` (grid), ``NAME=START:STOP`` (with ``random``) or
        ``NAME=V1,V2,...`` (list); values are bare numbers (SI) or quantities (``"2 mm/s"``),
        converted to SI.
    random : bool, optional
        The spec is a range for random sampling (``--random``), default False.

    Returns
    -------
    ParamSpec
        The parsed spec, values in SI.

    Raises
    ------
    DownholeInputError
        A malformed NAME or SPEC, an empty range, mixed or inconsistent units, a non-finite value,
        or a grid/random form that does not fit ``random``.
    """
    if not isinstance(text, str) or "=" not in text:
        raise DownholeInputError(f"--param {text!r}: expected NAME=START:STOP:COUNT "
                                 "(e.g. operation.surface_speed=2:12:11)")
    name, spec = (s.strip() for s in text.split("=", 1))
    what = f"--param {name}"
    if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)+", name):
        raise DownholeInputError(f"--param {text!r}: NAME must be a dotted scenario path such as "
                                 "bit.epsilon or operation.surface_speed")
    if not spec:
        raise DownholeInputError(f"{what}: empty range; expected START:STOP:COUNT")
    if ":" in spec:
        parts = spec.split(":")
        if len(parts) not in (2, 3):
            raise DownholeInputError(f"{what}={spec}: expected START:STOP:COUNT or START:STOP")
        start_s, stop_s = parts[0], parts[1]
        count = None
        if len(parts) == 3:
            # a unit after COUNT ("2:20:10 mm/s") applies to START and STOP
            n3, u3 = _split_unit(parts[2])
            if u3:
                parts[2] = n3
                if not _split_unit(start_s)[1]:
                    start_s = f"{start_s} {u3}"
                if not _split_unit(stop_s)[1]:
                    stop_s = f"{stop_s} {u3}"
            try:
                count = int(parts[2])
            except ValueError:
                raise DownholeInputError(f"{what}={spec}: COUNT must be a whole number, got "
                                         f"{parts[2]!r}") from None
            if count < 1:
                raise DownholeInputError(f"{what}={spec}: empty range (COUNT = {count}); COUNT "
                                         "must be at least 1")
            if random:
                raise DownholeInputError(f"{what}={spec}: with --random give START:STOP only "
                                         "(the number of cases is --random N)")
        elif not random:
            raise DownholeInputError(f"{what}={spec}: a grid needs START:STOP:COUNT")
        # a unit written once applies to both ends
        (n1, u1), (n2, u2) = _split_unit(start_s), _split_unit(stop_s)
        if u1 and not u2:
            stop_s = f"{n2} {u1}"
        elif u2 and not u1:
            start_s = f"{n1} {u2}"
        lo, ulo, _ = _quantity(start_s, f"{what} START")
        hi, uhi, _ = _quantity(stop_s, f"{what} STOP")
        if ulo != uhi:
            raise DownholeInputError(f"{what}={spec}: START is in {ulo or 'plain numbers'} but "
                                     f"STOP in {uhi or 'plain numbers'}")
        for v, w in ((lo, "START"), (hi, "STOP")):
            if not math.isfinite(v):
                raise DownholeInputError(f"{what}={spec}: {w} is not finite")
        if count is not None and count > 1 and lo == hi:
            raise DownholeInputError(f"{what}={spec}: empty range (START == STOP with "
                                     f"COUNT = {count})")
        if random and lo == hi:
            raise DownholeInputError(f"{what}={spec}: empty range (START == STOP)")
        values = None if count is None else np.linspace(lo, hi, count)
        return ParamSpec(name, values, lo, hi, ulo or known_units(name), spec, count)
    if random:
        raise DownholeInputError(f"{what}={spec}: with --random give a range START:STOP")
    items = [s for s in spec.split(",")]
    if any(not s.strip() for s in items):
        raise DownholeInputError(f"{what}={spec}: empty item in the value list")
    parsed = [_quantity(s, f"{what} value") for s in items]
    units = {u for _, u, _ in parsed}
    if len(units) > 1:
        raise DownholeInputError(f"{what}={spec}: values mix units {sorted(units)}")
    values = np.array([v for v, _, _ in parsed])
    return ParamSpec(name, values, float(values.min()), float(values.max()),
                     units.pop() or known_units(name), spec, len(values))


# --- scenario paths ----------------------------------------------------------------------------

def get_path(data: dict, path: str, default=KeyError):
    """The value at dotted ``path`` of a nested dict (``data[a][b][c]`` for ``"a.b.c"``).

    Parameters
    ----------
    data : dict
        Nested tables (a parsed scenario).
    path : str
        Dotted path.
    default : object, optional
        Returned when the path is absent; by default an absent path raises.

    Returns
    -------
    object
        The value, or ``default``.

    Raises
    ------
    KeyError
        If the path is absent and no ``default`` is given.
    """
    node: Any = data
    for key in path.split("."):
        if not isinstance(node, dict) or key not in node:
            if default is KeyError:
                raise KeyError(path)
            return default
        node = node[key]
    return node


def set_path(data: dict, path: str, value) -> None:
    """Set ``data[a][b][c] = value`` for ``path = "a.b.c"``, creating tables as needed.

    Parameters
    ----------
    data : dict
        Nested tables, modified in place.
    path : str
        Dotted path.
    value : object
        The value to set.

    Raises
    ------
    DownholeInputError
        If a component on the way is a value, not a table.
    """
    keys = path.split(".")
    node = data
    for i, key in enumerate(keys[:-1]):
        nxt = node.get(key)
        if nxt is None:
            nxt = node[key] = {}
        elif not isinstance(nxt, dict):
            raise DownholeInputError(f"--param {path}: {'.'.join(keys[:i + 1])} is a value "
                                     f"({nxt!r}), not a table")
        node = nxt
    node[keys[-1]] = value


def validate_path(base: dict, source: str, spec: ParamSpec) -> None:
    """Check that the scenario accepts ``spec.path`` at the range ends.

    Lumped scenarios are validated against their full schema (so a path need not be written in
    the file, e.g. ``model.string.mass`` set by the preset). Other model types accept only paths
    already present in the file (their schemas live with their runners).

    Parameters
    ----------
    base : dict
        The parsed base scenario.
    source : str
        Its name (file path), used in messages.
    spec : ParamSpec
        The swept parameter; its ``low`` and ``high`` are probed.

    Raises
    ------
    DownholeInputError
        A renamed key of an older dialect, an unknown path, or a value the scenario rejects.
    """
    from downhole.scenario import is_lumped_type, model_type
    from downhole.scenario.schema import RENAMES

    parts = spec.path.split(".")
    for n in range(len(parts), 0, -1):  # an older dialect's key: name the one to use
        old = ".".join(parts[:n])
        if old in RENAMES and old != "model.hybrid":  # model.hybrid.* is today's table
            raise DownholeInputError(f"--param {spec.path}: renamed: use {RENAMES[old]} "
                                     "(see docs/scenarios.md)")
    mtype = model_type(base, source)
    probe_values = [spec.low, spec.high]
    if not is_lumped_type(mtype):
        if get_path(base, spec.path, None) is None:
            raise DownholeInputError(
                f"--param {spec.path}: unknown parameter path: {source} has no key "
                f"{spec.path!r} (for model type {mtype!r} only keys written in the scenario "
                "can be swept)")
        return
    from downhole.scenario import build_lumped_model, parse_scenario

    for value in probe_values:
        data = copy.deepcopy(base)
        set_path(data, spec.path, value)
        try:
            sc = parse_scenario(data, source)
            build_lumped_model(sc, source)
        except ScenarioError as exc:
            if "unknown key" in exc.message and spec.path.startswith(exc.field):
                raise DownholeInputError(f"--param {spec.path}: unknown parameter path "
                                         f"({exc.field}: {exc.message})") from None
            raise DownholeInputError(f"--param {spec.path}={spec.text}: value {value!r} is "
                                     f"rejected by the scenario: {exc.field}: {exc.message}"
                                     ) from None
