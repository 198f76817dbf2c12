"""Standard plots of a Result (matplotlib, Agg backend so it works headless)."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

__all__ = ["plot_overview", "save_figure"]


def save_figure(fig, path) -> None:
    """Save and close ``fig`` (PNG, 120 dpi)."""
    fig.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(fig)


def plot_overview(result, path=None, title=None):
    """Four panels: bit axial velocity, bit angular velocity, WOB/TOB, surface signals."""
    t = result.time
    fig, axes = plt.subplots(4, 1, figsize=(9, 10), sharex=True)
    ax = axes[0]
    ax.plot(t, result["bit_axial_velocity"] * 1e3, label="bit")
    if "reference_axial_velocity" in result:
        ax.plot(t, result["reference_axial_velocity"] * 1e3, "k--", lw=1, label="reference")
    if "top_drive_axial_velocity" in result:
        ax.plot(t, result["top_drive_axial_velocity"] * 1e3, ":", lw=1, label="top drive")
    ax.set_ylabel("axial velocity [mm/s]")
    ax.legend(loc="upper right", fontsize=8)
    ax = axes[1]
    ax.plot(t, result["bit_angular_velocity"], label="bit")
    if "reference_angular_velocity" in result:
        ax.plot(t, result["reference_angular_velocity"], "k--", lw=1, label="reference")
    if "top_drive_angular_velocity" in result:
        ax.plot(t, result["top_drive_angular_velocity"], ":", lw=1, label="top drive")
    ax.set_ylabel("angular velocity [rad/s]")
    ax.legend(loc="upper right", fontsize=8)
    ax = axes[2]
    ax.plot(t, result["wob"] / 1e3, label="WOB [kN]")
    ax.plot(t, result["tob"] / 1e3, label="TOB [kN m]")
    ax.set_ylabel("bit loads")
    ax.legend(loc="upper right", fontsize=8)
    ax = axes[3]
    if "hook_load" in result:
        ax.plot(t, result["hook_load"] / 1e3, label="hook load [kN]")
    if "surface_torque" in result:
        ax.plot(t, result["surface_torque"] / 1e3, label="surface torque [kN m]")
    ax.set_ylabel("surface")
    ax.set_xlabel("time [s]")
    ax.legend(loc="upper right", fontsize=8)
    for a in axes:
        a.grid(alpha=0.3)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    if path is not None:
        save_figure(fig, path)
        return None
    return fig
