"""Plots of sweep datasets and the drilling stability map.

The stability map classifies each operating point of a 2-D grid (rotary speed x axial feed or
hook load) into *stable*, *stick-slip*, *bit bounce* or *both*, from the ``stick_slip_severity``
and ``bit_bounce_fraction`` metrics, and draws iso-lines of the mean WOB when the sweep recorded
``mean_wob`` -- the chart drilling engineers use to choose an operating point.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from downhole._atomic import atomic_path
from downhole.errors import DownholeInputError

__all__ = ["REGIMES", "classify_regimes", "display_units", "plot_sweep", "stability_map"]

#: Regime codes of :func:`classify_regimes`.
REGIMES = {0: "stable", 1: "stick-slip", 2: "bit bounce", 3: "stick-slip + bit bounce"}

def display_units(units: str, system=None) -> tuple[str, float]:
    """(label, factor) that show SI values of unit ``units`` in the figure units of ``system``.

    The figure units of :func:`downhole.units.display_units` (default ``si``: rpm, mm/s, kN,
    kN·m, MPa). The factor comes from pint.

    Parameters
    ----------
    units : str
        The SI unit of the values (pint string, e.g. ``"rad/s"``).
    system : str or UnitSystem, optional
        Display unit system (default ``"si"``).

    Returns
    -------
    label : str
        Printable display unit (``"rpm"``, ``"kN·m"``; ``""`` or ``"-"`` for dimensionless).
    factor : float
        Multiply an SI value by it to get the value in the display unit.
    """
    from downhole.units import display_units as _system
    from downhole.units import unit_label

    disp = _system(system or "si").for_figures()
    factor, unit = disp.convert("", 1.0, units)
    return unit_label(unit) if unit not in ("", "-") else unit, float(factor)


_FRIENDLY = {"operation.surface_speed": "rotary speed", "operation.rop": "feed velocity",
             "operation.hook_load": "hook load", "operation.surface_torque": "surface torque"}


def _label(ds, name, system=None) -> tuple[str, float]:
    """Axis label with the display unit of variable ``name`` and the factor from SI to it."""
    from downhole.units import display_units as _system

    disp = _system(system or "si").for_figures()
    si = str(ds[name].attrs.get("units", ""))
    factor, unit = disp.convert(name, 1.0, si)
    text = f"{_FRIENDLY[name]}, {name}" if name in _FRIENDLY else name
    label = disp.label(name, si)
    return (f"{text} ({label})" if unit and unit != "-" else text), float(factor)


def _mpl():
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt


def plot_sweep(ds, out_dir: str | Path, units=None) -> list[Path]:
    """One PNG per metric of a sweep, in the display ``units``.

    Lines (1 parameter), heat maps (2), scatter against each parameter (random sweeps);
    further grid dimensions are shown at their first value. Each file is written atomically.

    Parameters
    ----------
    ds : xarray.Dataset
        A sweep dataset (:func:`downhole.sweep.run_sweep`).
    out_dir : str or pathlib.Path
        Output folder (created if needed); files ``sweep_<metric>.png``.
    units : str or UnitSystem, optional
        A system name or :class:`~downhole.units.UnitSystem` (default ``si`` figure units).

    Returns
    -------
    list of pathlib.Path
        The files written.
    """
    plt = _mpl()
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    metrics = [v for v in ds.data_vars if v not in ("error", "case_seconds", "regime")]
    files = []
    for m in metrics:
        da = ds[m]
        mlabel, mf = _label(ds, m, units)
        if "case" in da.dims:
            params = [c for c in ds.coords if c != "case"]
            fig, axes = plt.subplots(1, len(params), figsize=(4.2 * len(params), 3.4),
                                     squeeze=False)
            for ax, p in zip(axes[0], params):
                plabel, pf = _label(ds, p, units)
                ok = np.isfinite(da.values)
                ax.scatter(ds[p].values[ok] * pf, da.values[ok] * mf, s=8)
                ax.scatter(ds[p].values[~ok] * pf, np.zeros((~ok).sum()), marker="x", c="r",
                           label="failed" if (~ok).any() else None)
                ax.set_xlabel(plabel)
                ax.set_ylabel(mlabel)
                ax.grid(alpha=0.3)
                if (~ok).any():
                    ax.legend()
        else:
            sub = da.isel({d: 0 for d in da.dims[2:]})
            fig, ax = plt.subplots(figsize=(5.6, 4.0))
            if sub.ndim == 1:
                d = sub.dims[0]
                plabel, pf = _label(ds, d, units)
                ax.plot(ds[d].values * pf, sub.values * mf, "o-", ms=3)
                ax.set_xlabel(plabel)
                ax.set_ylabel(mlabel)
                ax.grid(alpha=0.3)
            else:
                ydim, xdim = sub.dims[0], sub.dims[1]
                xl, xf = _label(ds, xdim, units)
                yl, yf = _label(ds, ydim, units)
                mesh = ax.pcolormesh(ds[xdim].values * xf, ds[ydim].values * yf,
                                     sub.values * mf, shading="nearest", cmap="viridis")
                fig.colorbar(mesh, ax=ax, label=mlabel)
                ax.set_xlabel(xl)
                ax.set_ylabel(yl)
            if da.ndim > 2:
                ax.set_title("at " + ", ".join(f"{d}={float(ds[d][0]):.4g}"
                                               for d in da.dims[2:]), fontsize=8)
        fig.suptitle(f"sweep: {m}", fontsize=10)
        fig.tight_layout()
        path = out_dir / f"sweep_{m}.png"
        with atomic_path(path) as tmp:
            fig.savefig(tmp, dpi=110)
        plt.close(fig)
        files.append(path)
    return files


def classify_regimes(ds, severity_threshold: float = 0.5, bounce_threshold: float = 0.01):
    """Regime codes (:data:`REGIMES`) per case.

    Stick-slip where ``stick_slip_severity`` > ``severity_threshold`` (or the bit stuck some of
    the time, when ``stuck_fraction`` is recorded), bit bounce where ``bit_bounce_fraction`` >
    ``bounce_threshold``; failed cases give -1.

    Parameters
    ----------
    ds : xarray.Dataset
        A sweep dataset with the metrics ``stick_slip_severity`` and ``bit_bounce_fraction``.
    severity_threshold : float, optional
        Severity above which a case is stick-slip (dimensionless, default 0.5).
    bounce_threshold : float, optional
        Bit-bounce fraction above which a case bounces (dimensionless, default 0.01).

    Returns
    -------
    xarray.DataArray of int
        Codes 0-3 (stable, stick-slip, bit bounce, both) or -1, with the sweep's dimensions.

    Raises
    ------
    DownholeInputError
        If one of the two metrics is missing.
    """
    for m in ("stick_slip_severity", "bit_bounce_fraction"):
        if m not in ds:
            raise DownholeInputError(f"the stability map needs the metric {m!r}; rerun the "
                                     "sweep with --metric stick_slip_severity "
                                     "--metric bit_bounce_fraction")
    sev = ds["stick_slip_severity"]
    stick = sev > severity_threshold
    if "stuck_fraction" in ds:
        stick = stick | (ds["stuck_fraction"] > 0)
    bounce = ds["bit_bounce_fraction"] > bounce_threshold
    code = stick.astype(int) + 2 * bounce.astype(int)
    failed = ~np.isfinite(sev) | ~np.isfinite(ds["bit_bounce_fraction"])
    code = code.where(~failed, -1).astype(int)
    code.attrs = {"description": "operating regime: " + ", ".join(f"{k} {v}" for k, v in
                                                                  REGIMES.items()) + ", -1 failed",
                  "severity_threshold": severity_threshold, "bounce_threshold": bounce_threshold}
    return code


def stability_map(ds, path: str | Path, x: str | None = None, y: str | None = None,
                  severity_threshold: float = 0.5, bounce_threshold: float = 0.01,
                  title: str | None = None, units=None):
    """Draw the drilling stability map of a 2-D grid sweep into ``path`` (PNG).

    Parameters
    ----------
    ds : xarray.Dataset
        A grid sweep with ``stick_slip_severity`` and ``bit_bounce_fraction`` (and optionally
        ``mean_wob`` for WOB iso-lines).
    path : str or pathlib.Path
        PNG file to write.
    x, y : str, optional
        Dimensions on the horizontal and vertical axes; default: a dimension whose name
        contains ``surface_speed`` or ``angular_velocity`` (rotary speed) on x, the other on y.
    severity_threshold, bounce_threshold : float
        Classification thresholds (see :func:`classify_regimes`).
    title : str, optional
        Figure title.
    units : str or UnitSystem, optional
        Display units of the axes (default ``si``: rpm, mm/s, kN).

    Returns
    -------
    xarray.DataArray
        The regime codes (also drawn).

    Raises
    ------
    DownholeInputError
        Not a 2-D grid sweep, an axis that is not a swept parameter, or a missing metric.
    """
    plt = _mpl()
    from matplotlib.colors import BoundaryNorm, ListedColormap
    from matplotlib.patches import Patch

    dims = [d for d in ds["stick_slip_severity"].dims] if "stick_slip_severity" in ds else []
    if "case" in dims or len(dims) != 2:
        raise DownholeInputError("the stability map needs a 2-D grid sweep (two --param "
                                 f"START:STOP:COUNT ranges), got dimensions {dims}")
    if x is None:
        x = next((d for d in dims if "surface_speed" in d or "angular_velocity" in d), dims[1])
    if y is None:
        y = next(d for d in dims if d != x)
    for d in (x, y):
        if d not in dims:
            raise DownholeInputError(f"stability map axis {d!r} is not a swept parameter "
                                     f"(swept: {dims})")
    regimes = classify_regimes(ds, severity_threshold, bounce_threshold).transpose(y, x)
    sev = ds["stick_slip_severity"].transpose(y, x)
    bounce = ds["bit_bounce_fraction"].transpose(y, x)
    xl, xf = _label(ds, x, units)
    yl, yf = _label(ds, y, units)
    xv, yv = ds[x].values * xf, ds[y].values * yf

    fig, axes = plt.subplots(1, 3, figsize=(16.5, 4.6))
    ax = axes[0]
    m0 = ax.pcolormesh(xv, yv, np.clip(sev.values, 0, 2), shading="nearest", cmap="magma_r",
                       vmin=0, vmax=2)
    fig.colorbar(m0, ax=ax, label="stick-slip severity (clipped at 2)")
    if len(xv) > 1 and len(yv) > 1:
        ax.contour(xv, yv, sev.values, levels=[severity_threshold], colors="c", linewidths=1.5)
    ax.set_title(f"stick-slip severity (cyan: {severity_threshold})", fontsize=9)
    ax = axes[1]
    m1 = ax.pcolormesh(xv, yv, bounce.values, shading="nearest", cmap="Blues", vmin=0,
                       vmax=max(0.05, float(np.nanmax(bounce.values)) if np.isfinite(
                           bounce.values).any() else 1.0))
    fig.colorbar(m1, ax=ax, label="bit-bounce fraction")
    ax.set_title("fraction of time off bottom / zero depth of cut", fontsize=9)
    ax = axes[2]
    colors = ["#bbbbbb", "#4caf50", "#e53935", "#1e88e5", "#8e24aa"]
    cmap = ListedColormap(colors)
    norm = BoundaryNorm([-1.5, -0.5, 0.5, 1.5, 2.5, 3.5], cmap.N)
    ax.pcolormesh(xv, yv, regimes.values, shading="nearest", cmap=cmap, norm=norm)
    if "mean_wob" in ds and len(xv) > 1 and len(yv) > 1:
        wl, wf = display_units(ds["mean_wob"].attrs.get("units", "N"), units)
        wob = ds["mean_wob"].transpose(y, x).values * wf
        if np.isfinite(wob).sum() > 3:
            cs = ax.contour(xv, yv, wob, levels=6, colors="k", linewidths=0.8, linestyles="--")
            ax.clabel(cs, fmt=f"%.0f {wl}", fontsize=7)
    present = sorted(set(np.unique(regimes.values).tolist()))
    names = {-1: "failed", **REGIMES}
    ax.legend(handles=[Patch(color=colors[k + 1], label=names[k]) for k in present],
              loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7, framealpha=0.85)
    ax.set_title("operating regime" + (" (dashed: mean WOB)" if "mean_wob" in ds else ""),
                 fontsize=9)
    for ax in axes:
        ax.set_xlabel(xl)
        ax.set_ylabel(yl)
    fig.suptitle(title or "drilling stability map", fontsize=11)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110)
    plt.close(fig)
    return regimes
