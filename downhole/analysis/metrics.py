"""Drilling metrics: stick-slip severity, stuck and bit-bounce fractions, ROP, MSE, tracking."""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "STUCK_THRESHOLD",
    "SUMMARY_KEYS",
    "stick_slip_severity",
    "stick_slip_severity_series",
    "summarize",
]

#: |bit angular velocity| below this counts as stuck, rad/s.
STUCK_THRESHOLD = 0.1

SUMMARY_KEYS = ("stick_slip_severity", "stuck_fraction", "bit_bounce_fraction", "mean_rop",
                "mean_bit_angular_velocity", "mse")


def stick_slip_severity(omega: np.ndarray) -> float:
    """(max - min) / (2 mean) of the bit angular velocity; inf if the mean is <= 0.

    Parameters
    ----------
    omega : array_like
        Bit angular velocity samples, rad/s (non-empty).

    Returns
    -------
    float
        The severity (dimensionless), or ``math.inf``.
    """
    omega = np.asarray(omega, float)
    mean = float(np.mean(omega))
    if mean <= 0:
        return math.inf
    return float((omega.max() - omega.min()) / (2.0 * mean))


def stick_slip_severity_series(t, omega, window: float, points: int = 400):
    """Stick-slip severity over time in a trailing window.

    :func:`stick_slip_severity` of the bit angular velocity in a trailing window of ``window`` s,
    evaluated at up to ``points`` times.

    Parameters
    ----------
    t : array_like, shape (n,)
        Sample times, s, increasing.
    omega : array_like, shape (n,)
        Bit angular velocity, rad/s.
    window : float
        Window length, s (> 0; otherwise empty arrays are returned).
    points : int, optional
        Most evaluation times, spread evenly over the samples (default 400).

    Returns
    -------
    times : ndarray
        Evaluation times, s.
    severity : ndarray
        Severity (dimensionless); NaN where the window's mean speed is <= 0 (severity infinite)
        and where less than a full window has elapsed.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.linspace(0, 20, 2001)
    >>> tt, s = stick_slip_severity_series(t, 10 + 5 * np.sin(2 * np.pi * t), 2.0)
    >>> round(float(np.nanmax(s)), 2)
    0.5
    """
    t = np.asarray(t, float)
    omega = np.asarray(omega, float)
    if t.size == 0 or not window > 0:
        return t[:0], t[:0]
    idx = np.unique(np.linspace(0, t.size - 1, min(points, t.size)).round().astype(int))
    starts = np.searchsorted(t, t[idx] - window, side="left")
    sev = np.full(idx.size, np.nan)
    for k, (i, j) in enumerate(zip(idx, starts)):
        if t[i] - t[0] < window * (1 - 1e-9):
            continue
        s = stick_slip_severity(omega[j:i + 1])
        sev[k] = s if math.isfinite(s) else np.nan
    return t[idx], sev


def summarize(result, window: tuple[float, float] | None = None) -> dict:
    """Metrics of ``result`` over ``window`` = (t_start, t_end), default the second half.

    Parameters
    ----------
    result : Result
        The run; it needs the channels ``bit_angular_velocity``, ``bit_axial_velocity``,
        ``wob``, ``tob`` and ``depth_of_cut`` (and the attribute ``bit_radius``, m, for the MSE).
    window : (float, float), optional
        ``(t_start, t_end)``, s, inclusive.

    Returns
    -------
    dict
        Exactly the keys ``stick_slip_severity``, ``stuck_fraction`` (fraction of samples with
        |omega_bit| < 0.1 rad/s), ``bit_bounce_fraction`` (WOB <= 0 or depth of cut <= 0),
        ``mean_rop`` (m/s), ``mean_bit_angular_velocity`` (rad/s), ``mse`` (mechanical specific
        energy at the bit, Pa: (WOB/A + 2 pi N TOB/(A ROP)) with means over the window, Teale;
        NaN without a bit radius or a positive ROP), and, when reference channels exist,
        ``tracking_rms_axial`` (m/s) and ``tracking_rms_angular`` (rad/s).

    Raises
    ------
    ValueError
        If the result is empty or the window holds no samples.
    """
    t = result.time
    if t.size == 0:
        raise ValueError("empty result: nothing to summarize")
    if window is None:
        window = (t[0] + 0.5 * (t[-1] - t[0]), t[-1])
    lo, hi = window
    sel = (t >= lo) & (t <= hi)
    if not np.any(sel):
        raise ValueError(f"summary window {window} contains no samples (run spans "
                         f"{t[0]:.3g}..{t[-1]:.3g} s)")
    omega = result["bit_angular_velocity"][sel]
    v = result["bit_axial_velocity"][sel]
    wob = result["wob"][sel]
    tob = result["tob"][sel]
    d = result["depth_of_cut"][sel]
    out = {
        "stick_slip_severity": stick_slip_severity(omega),
        "stuck_fraction": float(np.mean(np.abs(omega) < STUCK_THRESHOLD)),
        "bit_bounce_fraction": float(np.mean((wob <= 0.0) | (d <= 0.0))),
        "mean_rop": float(np.mean(v)),
        "mean_bit_angular_velocity": float(np.mean(omega)),
    }
    radius = float(result.attrs.get("bit_radius", 0.0) or 0.0)
    rop = out["mean_rop"]
    if radius > 0 and rop > 0:
        area = math.pi * radius**2
        out["mse"] = float(np.mean(wob) / area + np.mean(tob * omega) / (area * rop))
    else:
        out["mse"] = math.nan
    if "reference_axial_velocity" in result:
        ref_v = result["reference_axial_velocity"][sel]
        out["tracking_rms_axial"] = float(np.sqrt(np.mean((v - ref_v) ** 2)))
    if "reference_angular_velocity" in result:
        ref_w = result["reference_angular_velocity"][sel]
        out["tracking_rms_angular"] = float(np.sqrt(np.mean((omega - ref_w) ** 2)))
    return out
