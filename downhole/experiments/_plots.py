"""Plotting pieces shared by the experiments (not an experiment module: its name starts with _)."""

from __future__ import annotations


def pyplot():
    """``matplotlib.pyplot`` on the non-interactive Agg backend (imported on first use)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_stick_slip(r, path, title, w=None):
    """Bit and top-drive angular velocity over the bit axial velocity of the run ``r``.

    Saved to ``path`` (110 dpi) under the title ``title``; ``w`` is the bit angular velocity
    (default: ``r["bit_angular_velocity"]``).
    """
    plt = pyplot()
    fig, ax = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    ax[0].plot(r.time, r["bit_angular_velocity"] if w is None else w, label="bit")
    ax[0].plot(r.time, r["top_drive_angular_velocity"], label="top drive")
    ax[0].set_ylabel("angular velocity (rad/s)")
    ax[0].legend()
    ax[1].plot(r.time, 1e3 * r["bit_axial_velocity"])
    ax[1].set_ylabel("bit axial velocity (mm/s)")
    ax[1].set_xlabel("time (s)")
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
