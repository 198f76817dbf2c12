"""Standard plots of a Result (matplotlib, Agg backend so it works headless)."""

from __future__ import annotations

import json

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

__all__ = ["operating_line", "plot_overview", "save_figure", "severity_window"]

# one colour per quantity, the same in every figure
_COLORS = {"wob": "tab:blue", "tob": "tab:red", "hook_load": "tab:green",
           "surface_torque": "tab:purple", "bit": "tab:blue", "top_drive": "tab:orange",
           "severity": "tab:brown", "depth": "tab:gray"}


def save_figure(fig, path) -> None:
    """Save and close ``fig`` (PNG, 120 dpi).

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure; closed in pyplot after saving.
    path : str or os.PathLike
        Output file.
    """
    fig.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(fig)


def severity_window(t) -> float:
    """Window of the stick-slip severity over time, s.

    5 s (a few stick-slip periods of a kilometre-long string), a quarter of the run when that
    is shorter.

    Parameters
    ----------
    t : array_like
        Sample times of the run, s.

    Returns
    -------
    float
        Window length, s (0 for a run of fewer than two samples or no time span).
    """
    t = np.asarray(t, float)
    span = float(t[-1] - t[0]) if t.size > 1 else 0.0
    return min(5.0, span / 4.0) if span > 0 else 0.0


def _bit_depth(result):
    """(label, SI values) of the depth panel: the bit's measured depth when the run records
    the string's node depths (``node_md``), else the bit's advance from its start."""
    md = result.attrs.get("node_md")
    if isinstance(md, str):
        try:
            md = json.loads(md)
        except ValueError:
            md = None
    pos = result["bit_axial_position"]
    if md is not None and np.size(md):
        return "bit measured depth", float(np.ravel(md)[-1]) + pos, True
    return "bit advance", pos - (pos[0] if np.size(pos) else 0.0), False


def _readable_limits(ax) -> None:
    """Show a (nearly) constant signal as a flat line at its value: without this, matplotlib
    zooms into its rounding noise (an axis of "1e-9 + 1.2e2" for a steady 120 rpm). A span of
    less than 1e-6 of the magnitude gets +-5 % of it; offsets are never used."""
    ys = [np.asarray(line.get_ydata(), float) for line in ax.get_lines()]
    ys = [y[np.isfinite(y)] for y in ys]
    ys = [y for y in ys if y.size]
    if ys:
        lo, hi = min(float(y.min()) for y in ys), max(float(y.max()) for y in ys)
        scale = max(abs(lo), abs(hi))
        if hi - lo < 1e-6 * scale:
            c, half = 0.5 * (lo + hi), 0.05 * scale
            ax.set_ylim(c + half, c - half) if ax.yaxis_inverted() else \
                ax.set_ylim(c - half, c + half)
    fmt = ax.yaxis.get_major_formatter()
    if hasattr(fmt, "set_useOffset"):
        fmt.set_useOffset(False)


def operating_line(result, units) -> str:
    """The operating point of ``result`` over its second half, in the figure ``units``:
    ``"2nd half: surface 120 rpm, bit 120 rpm, WOB 100 kN, ROP 112 m/h"`` (the channels the run
    has). :func:`plot_overview` puts it under the title, so that a figure states its operating
    point in the units of its axes whatever its title says.

    Parameters
    ----------
    result : Result
        The run.
    units : UnitSystem
        The figure's display units.

    Returns
    -------
    str
        One line; empty for an empty run.
    """
    t = np.asarray(result.time, float)
    if t.size == 0:
        return ""
    half = t >= t[0] + 0.5 * (t[-1] - t[0])
    parts = []
    for name, label in (("top_drive_angular_velocity", "surface"), ("bit_angular_velocity", "bit"),
                        ("wob", "WOB"), ("bit_axial_velocity", "ROP")):
        if name in result:
            v, _ = units.convert(name, np.asarray(result[name], float)[half])
            v = float(np.nanmean(v)) if np.size(v) else float("nan")
            parts.append(f"{label} {v:.3g} {units.label(name)}")
    return ("mean over the 2nd half: " + ", ".join(parts)) if parts else ""


def _load_panel(ax, result, t, left: tuple[str, str], right: tuple[str, str], units):
    """``left`` = (channel, label) on ``ax``, ``right`` on a twin axis; missing channels are
    skipped. Returns the axes drawn on."""
    drawn = []
    for which, (name, label) in (("left", left), ("right", right)):
        if name not in result:
            continue
        a = ax if which == "left" else ax.twinx()
        values, unit = units.convert(name, result[name], result.units(name) or None)
        color = _COLORS[name]
        a.plot(t, values, color=color, lw=1.0, label=label)
        a.set_ylabel(f"{label} [{units.label(name, result.units(name) or None)}]",
                     color=color)
        a.tick_params(axis="y", colors=color)
        a.spines[which].set_color(color)
        drawn.append(a)
    return drawn


def plot_overview(result, path=None, title=None, units=None):
    """The run at a glance, in display ``units``.

    Panels over time: axial velocities (bit, reference, top drive); rotary speeds of the bit and
    the top drive (surface) in rpm with stuck intervals shaded; the stick-slip severity over a
    moving window (:func:`~downhole.analysis.metrics.stick_slip_severity_series`); WOB and TOB,
    each on its own axis; hook load and surface torque, each on its own axis; the bit's depth.

    Parameters
    ----------
    result : Result
        The run.
    path : str or os.PathLike, optional
        PNG file to save the figure to (120 dpi); the figure is then closed in pyplot, but can
        still be inspected or saved again.
    title : str, optional
        Figure title; the operating point in the figure's units (:func:`operating_line`) is
        written under it.
    units : str or UnitSystem, optional
        A :class:`~downhole.units.UnitSystem` or a system name; default ``si``, whose figures
        use kN, kN·m, mm/s and rpm.

    Returns
    -------
    matplotlib.figure.Figure
    """
    from downhole.analysis.metrics import STUCK_THRESHOLD, stick_slip_severity_series
    from downhole.units import display_units

    units = display_units(units or "si").for_figures()
    t = result.time
    tu = units.label("time", "s")
    has_depth = "bit_axial_position" in result
    ratios = [1, 1.2, 0.7, 1, 1] + ([0.8] if has_depth else [])
    fig, axes = plt.subplots(len(ratios), 1, figsize=(10, 2.5 * sum(ratios) + 1), sharex=True,
                             gridspec_kw={"height_ratios": ratios})

    # --- axial velocities
    ax = axes[0]
    for name, style, label in (("bit_axial_velocity", "-", "bit"),
                               ("reference_axial_velocity", "k--", "reference"),
                               ("top_drive_axial_velocity", ":", "top drive")):
        if name in result:
            v, _ = units.convert(name, result[name])
            kw = {"color": _COLORS["bit"]} if label == "bit" else (
                {"color": _COLORS["top_drive"]} if label == "top drive" else {})
            ax.plot(t, v, style, lw=1 if label != "bit" else 1.2, label=label, **kw)
    ax.set_ylabel(f"axial velocity [{units.label('bit_axial_velocity')}]")
    if ax.get_lines():
        ax.legend(loc="upper right", fontsize=8)

    # --- stick-slip: rotary speeds, stuck intervals
    ax = axes[1]
    w_bit, wu = units.convert("bit_angular_velocity", result["bit_angular_velocity"])
    ax.plot(t, w_bit, color=_COLORS["bit"], lw=1.2, label="bit")
    if "top_drive_angular_velocity" in result:
        w_td, _ = units.convert("top_drive_angular_velocity",
                                result["top_drive_angular_velocity"])
        ax.plot(t, w_td, color=_COLORS["top_drive"], lw=1.0, label="surface (top drive)")
    if "reference_angular_velocity" in result:
        w_ref, _ = units.convert("reference_angular_velocity",
                                 result["reference_angular_velocity"])
        ax.plot(t, w_ref, "k--", lw=1, label="reference")
    stuck = np.abs(result["bit_angular_velocity"]) < STUCK_THRESHOLD
    if stuck.any():
        ax.fill_between(t, 0, 1, where=stuck, transform=ax.get_xaxis_transform(),
                        color="tab:red", alpha=0.12, lw=0, label="bit stuck")
    ax.set_ylabel(f"rotary speed [{units.label('bit_angular_velocity')}]")
    ax.set_title("stick-slip: bit and surface rotary speed", fontsize=9, loc="left")
    ax.legend(loc="upper right", fontsize=8)

    # --- stick-slip severity over a moving window
    ax = axes[2]
    window = severity_window(t)
    ts, sev = stick_slip_severity_series(t, result["bit_angular_velocity"], window)
    ax.plot(ts, sev, color=_COLORS["severity"], lw=1.2)
    ax.axhline(1.0, color="k", lw=0.6, ls=":")  # severity 1: the bit stops at the minimum
    ax.set_ylabel(f"severity [-]\n({window:g} {tu} window)")
    ax.set_ylim(bottom=0)

    # --- bit loads and surface loads, each quantity on its own axis
    _load_panel(axes[3], result, t, ("wob", "WOB"), ("tob", "TOB"), units)
    _load_panel(axes[4], result, t, ("hook_load", "hook load"),
                ("surface_torque", "surface torque"), units)

    for a in fig.axes:  # the time-series panels and their twin axes, not the depth
        if not has_depth or a is not axes[5]:
            _readable_limits(a)

    # --- depth (where the run records the bit's position)
    if has_depth:
        ax = axes[5]
        label, depth, measured = _bit_depth(result)
        d, du = units.convert("bit_axial_position", depth)
        ax.plot(t, d, color=_COLORS["depth"], lw=1.2)
        ax.set_ylabel(f"{label} [{units.label('bit_axial_position')}]")
        if measured:
            ax.invert_yaxis()
        ax.ticklabel_format(axis="y", useOffset=False, style="plain")  # 8858.4 ft, not 8.858e3
    axes[-1].set_xlabel(f"time [{tu}]")
    for a in axes:
        a.grid(alpha=0.3)
    op = operating_line(result, units)
    if title or op:
        fig.suptitle("\n".join(x for x in (title, op) if x))
    fig.tight_layout()
    if path is not None:
        save_figure(fig, path)
    return fig
