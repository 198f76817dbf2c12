"""Torque-and-drag tables and plots: the broomstick plot, profiles along MD, plan and section views.

:func:`survey_table` gives the survey quantities at the nodes of a
:class:`~downhole.string.torque_drag.TorqueDrag` result (position, inclination, azimuth, dogleg
severity, build and turn rates, vertical section), :func:`torque_drag_table` the whole table that
``downhole torque-drag`` writes as CSV (SI units, the unit of each column in its header).
"""

from __future__ import annotations

import csv
import math

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from downhole.analysis.plots import save_figure

__all__ = [
    "display_table",
    "plot_broomstick",
    "plot_profiles",
    "plot_survey",
    "summary",
    "survey_table",
    "torque_drag_table",
    "write_csv",
]

# the cases of downhole.string.torque_drag.CASES (not imported: the core's sim imports this
# package, so analysis must not import the string package)
CASE_LABELS = {"trip_out": "pick-up (trip out)", "trip_in": "slack-off (trip in)",
               "rotating": "rotating off bottom", "drilling": "drilling (on bottom)"}
CASES = tuple(CASE_LABELS)
_COLORS = {"trip_out": "tab:red", "trip_in": "tab:blue", "rotating": "tab:green",
           "drilling": "black"}
_STYLES = ("-", "--", ":", "-.")
_ROTATING = ("rotating", "drilling")
_FT100 = 30.48  # 100 ft in m


def _units(units, figures: bool = True):
    """The display :class:`~downhole.units.UnitSystem` (None: SI; figures in kN, kN m)."""
    from downhole.units import display_units

    u = display_units(units if units is not None else "si")
    return u.for_figures() if figures else u


def _conv(units, values, si_unit: str):
    """``(values, printed unit)`` of SI ``values`` in ``units`` (pint, downhole.units)."""
    from downhole.units import convert, unit_label

    if si_unit == "deg_per_30m":
        dst = units.kind_unit("curvature")
        return convert(values, si_unit, dst), unit_label(dst)
    v, dst = units.convert("torque_drag_column", values, si_unit)
    return v, unit_label(dst)


def display_table(columns: dict, units=None) -> dict:
    """``columns`` of :func:`torque_drag_table` (SI, ``"name [unit]"``) in the display units
    ``units`` (a name or :class:`~downhole.units.UnitSystem`; None: unchanged): lengths, forces,
    torques, side forces and build/turn rates converted with pint, the header naming the unit;
    inclination and azimuth stay in degrees, and both DLS columns are kept."""
    if units is None:
        return dict(columns)
    u = _units(units, figures=False)
    out = {}
    for name, values in columns.items():
        base, _, unit = name.partition(" [")
        unit = unit.rstrip("]")
        if (unit in ("deg", "deg/100ft") or name.startswith("dls ")
                or (unit == "deg/30m" and u.kind_unit("curvature") == "rad/m")):
            out[name] = values
            continue
        v, label = _conv(u, values, "deg_per_30m" if unit == "deg/30m" else unit)
        out[f"{base} [{label.replace('·', '*')}]"] = v
    return out


def _mu(f: float) -> str:
    return f"mu{f:g}"


def survey_table(well, md, azimuth: float | None = None) -> dict:
    """Survey quantities at measured depths ``md`` (column name with unit -> array).

    Dogleg severity in deg/30 m and deg/100 ft, build and turn rates in deg/30 m, vertical
    section on ``azimuth`` (rad; default the closure azimuth, :meth:`WellPath.closure`)."""
    md = np.asarray(md, float)
    pos = np.atleast_2d(well.position(md))
    return {
        "md [m]": md,
        "tvd [m]": pos[:, 2],
        "north [m]": pos[:, 0],
        "east [m]": pos[:, 1],
        "inclination [deg]": np.degrees(well.inclination(md)),
        "azimuth [deg]": np.degrees(well.azimuth(md)),
        "dls [deg/30m]": well.dogleg_severity(md, 30.0),
        "dls [deg/100ft]": well.dogleg_severity(md, _FT100),
        "build_rate [deg/30m]": np.degrees(well.build_rate(md)) * 30.0,
        "turn_rate [deg/30m]": np.degrees(well.turn_rate(md)) * 30.0,
        "vertical_section [m]": well.vertical_section(md, azimuth),
    }


def torque_drag_table(result, well, azimuth: float | None = None) -> dict:
    """The columns of ``torque_drag.csv``: survey quantities at the nodes, then per case and
    friction factor tension, torque (rotating cases) and side force with the bit at total depth,
    then hook load and surface torque with the bit at the row's MD (0 at the first row; NaN, an
    empty CSV cell, at rows that are not one of the result's bit depths)."""
    cols = survey_table(well, result.md, azimuth)
    for c in CASES:
        for k, f in enumerate(result.friction):
            cols[f"tension_{c}_{_mu(f)} [N]"] = result.tension[c][k]
            if c in _ROTATING:
                cols[f"torque_{c}_{_mu(f)} [N*m]"] = result.torque[c][k]
            cols[f"side_force_{c}_{_mu(f)} [N/m]"] = result.side_force[c][k]
    n = result.md.size
    rows = np.searchsorted(result.md, result.bit_depth)

    def column(values):
        col = np.full(n, np.nan)
        col[0] = 0.0
        col[rows] = values
        return col

    for c in CASES:
        for k, f in enumerate(result.friction):
            cols[f"hook_load_{c}_{_mu(f)} [N]"] = column(result.hook_load[c][k])
    for c in _ROTATING:
        for k, f in enumerate(result.friction):
            cols[f"surface_torque_{c}_{_mu(f)} [N*m]"] = column(result.surface_torque[c][k])
    return cols


def write_csv(path, columns: dict) -> None:
    """Write ``columns`` (name -> equal-length arrays) as CSV to ``path`` (plain write; callers
    wrap it in :func:`downhole._atomic.atomic_path`)."""
    names = list(columns)
    data = np.column_stack([np.asarray(columns[k], float) for k in names])
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(names)
        for row in data:
            w.writerow(["" if math.isnan(x) else f"{x:.10g}" for x in row])


def summary(result, well, azimuth: float | None = None) -> dict:
    """Key numbers: hook loads and surface torques with the bit at total depth per case and
    friction factor, the largest side force, WOB/TOB, total depth, closure, largest DLS."""
    dist, az = well.closure()
    dls = well.dogleg_severity(result.md, 30.0)
    out = {"total_depth_m": float(well.total_depth), "tvd_m": float(well.tvd(well.total_depth)),
           "closure_distance_m": dist, "closure_azimuth_deg": math.degrees(az),
           "vertical_section_azimuth_deg": math.degrees(az if azimuth is None else azimuth),
           "max_dls_deg_per_30m": float(np.max(dls)),
           "wob_N": result.wob, "tob_N_m": result.tob,
           "friction_factors": list(result.friction), "cases": {}}
    for c in CASES:
        rows = {}
        for k, f in enumerate(result.friction):
            rows[_mu(f)] = {"hook_load_N": float(result.tension[c][k, 0]),
                            "surface_torque_N_m": float(result.torque[c][k, 0]),
                            "max_side_force_N_per_m": float(np.max(result.side_force[c][k])),
                            "min_tension_N": float(np.min(result.tension[c][k]))}
        out["cases"][c] = rows
    return out


def _depth_axis(ax, label="measured depth [m]"):
    ax.set_ylabel(label)
    ax.invert_yaxis()
    ax.grid(alpha=0.3)


def plot_broomstick(result, path, title: str | None = None, units=None) -> None:
    """Hook load against bit depth per case and friction factor (the broomstick plot), and the
    surface torque against bit depth rotating off bottom and drilling (``units``: display unit
    system, default SI with kN and kN m)."""
    u = _units(units)
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 6.5), sharey=True,
                                   gridspec_kw={"width_ratios": [3, 2]})
    d, lu = _conv(u, np.concatenate([[0.0], result.bit_depth]), "m")
    _, fu = _conv(u, 1.0, "N")
    _, tu = _conv(u, 1.0, "N*m")
    for c in CASES:
        for k, f in enumerate(result.friction):
            y = np.concatenate([[0.0], result.hook_load[c][k]])
            ls = _STYLES[k % len(_STYLES)]
            lbl = f"{CASE_LABELS[c]}, mu = {f:g}"
            ax1.plot(_conv(u, y, "N")[0], d, ls, color=_COLORS[c], lw=1.3, label=lbl)
            if c in _ROTATING:
                q = np.concatenate([[0.0], result.surface_torque[c][k]])
                ax2.plot(_conv(u, q, "N*m")[0], d, ls, color=_COLORS[c], lw=1.3, label=lbl)
    ax1.set_xlabel(f"hook load [{fu}]")
    _depth_axis(ax1, f"bit depth (MD) [{lu}]")
    ax1.legend(fontsize=7, loc="lower left")
    ax1.set_title("hook load (broomstick)")
    ax2.set_xlabel(f"surface torque [{tu}]")
    ax2.grid(alpha=0.3)
    ax2.set_title("surface torque")
    ax2.legend(fontsize=7, loc="lower right")
    fig.suptitle(title or f"torque and drag: WOB {_conv(u, result.wob, 'N')[0]:.0f} {fu}, "
                 f"TOB {_conv(u, result.tob, 'N*m')[0]:.2f} {tu} while drilling")
    save_figure(fig, path)


def plot_profiles(result, path, title: str | None = None, units=None) -> None:
    """Tension, torque and side force along measured depth with the bit at total depth."""
    u = _units(units)
    md, lu = _conv(u, result.md, "m")
    _, fu = _conv(u, 1.0, "N")
    _, tu = _conv(u, 1.0, "N*m")
    _, su = _conv(u, 1.0, "N/m")
    fig, axes = plt.subplots(1, 3, figsize=(12, 6.5), sharey=True)
    for c in CASES:
        for k, f in enumerate(result.friction):
            ls = _STYLES[k % len(_STYLES)]
            lbl = f"{CASE_LABELS[c]}, mu = {f:g}"
            axes[0].plot(_conv(u, result.tension[c][k], "N")[0], md, ls, color=_COLORS[c],
                         lw=1.2, label=lbl)
            if c in _ROTATING:
                axes[1].plot(_conv(u, result.torque[c][k], "N*m")[0], md, ls,
                             color=_COLORS[c], lw=1.2, label=lbl)
            axes[2].plot(_conv(u, result.side_force[c][k], "N/m")[0], md, ls,
                         color=_COLORS[c], lw=1.2, label=lbl)
    axes[0].axvline(0.0, color="grey", lw=0.8)
    axes[0].set_xlabel(f"effective tension [{fu}]")
    axes[1].set_xlabel(f"torque [{tu}]")
    axes[2].set_xlabel(f"side force [{su}]")
    _depth_axis(axes[0], f"measured depth [{lu}]")
    for ax in axes[1:]:
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7, loc="lower left")
    fig.suptitle(title or "string loads with the bit at total depth")
    save_figure(fig, path)


def plot_survey(well, path, azimuth: float | None = None, title: str | None = None,
                units=None) -> None:
    """Plan view (east against north), section view (TVD against vertical section) and DLS,
    build and turn rates along measured depth."""
    u = _units(units)
    md = np.linspace(well.top_depth, well.total_depth, 1001)
    md = np.unique(np.concatenate([md, well.stations["md"]]))
    cols = survey_table(well, md, azimuth)
    L = lambda v: _conv(u, np.asarray(v, float), "m")[0]
    lu = _conv(u, 1.0, "m")[1]
    K = lambda v: _conv(u, v, "deg_per_30m")[0]
    ku = _conv(u, 1.0, "deg_per_30m")[1]
    st = well.stations
    az = well.closure()[1] if azimuth is None else azimuth
    fig, axes = plt.subplots(1, 3, figsize=(13, 5), layout="constrained")
    ax = axes[0]
    ax.plot(L(cols["east [m]"]), L(cols["north [m]"]), "k-", lw=1.5)
    ax.plot(L(st["east"]), L(st["north"]), "o", ms=3, color="tab:blue", label="stations")
    ax.set_xlabel(f"east [{lu}]")
    ax.set_ylabel(f"north [{lu}]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_title("plan view")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax = axes[1]
    ax.plot(L(cols["vertical_section [m]"]), L(cols["tvd [m]"]), "k-", lw=1.5)
    vs_st = well.vertical_section(st["md"], azimuth)
    ax.plot(L(vs_st), L(st["tvd"]), "o", ms=3, color="tab:blue")
    ax.set_xlabel(f"vertical section at {math.degrees(az):.1f} deg [{lu}]")
    ax.set_ylabel(f"TVD [{lu}]")
    ax.invert_yaxis()
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_title("section view")
    ax.grid(alpha=0.3)
    ax = axes[2]
    ax.plot(K(cols["dls [deg/30m]"]), L(md), "k-", lw=1.2, label="DLS")
    ax.plot(K(cols["build_rate [deg/30m]"]), L(md), "--", color="tab:red", lw=1.2,
            label="build")
    ax.plot(K(cols["turn_rate [deg/30m]"]), L(md), ":", color="tab:blue", lw=1.2, label="turn")
    ax.set_xlabel(ku)
    _depth_axis(ax, f"measured depth [{lu}]")
    ax.legend(fontsize=8)
    ax.set_title("dogleg severity, build and turn")
    fig.suptitle(title or "well path")
    save_figure(fig, path)
