"""Chapter 4 experiment: open-loop stick-slip and bit bounce on the directional FEM (Fig. 4.4)."""

from __future__ import annotations

from downhole.experiments import experiment

__all__ = ["fig4_4"]


@experiment("fig4.4", title="Open-loop stick-slip on the 432-state directional FEM", chapter=4,
            claim="stick-slip: stuck_fraction > 0.2 and bit speed peaks 1.5-3x the top drive "
                  "speed (10 rad/s), Table 5.1 well, PI top drive, 120 kN WOB",
            caption="Stick-slip and bit-bounce behaviors of the drill bit motions")
def fig4_4(out_dir, quick):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from downhole.sim import simulate
    from downhole.string.fem import fem_model

    duration = 30.0 if quick else 60.0
    m = fem_model(n_elements=107)
    r = simulate(m, duration=duration, dt=1e-3)
    win = (10.0, duration)
    s = r.summary(window=win)
    sel = r.time >= win[0]
    ratio = float(r["bit_angular_velocity"][sel].max() / 10.0)
    fig, ax = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    ax[0].plot(r.time, r["bit_angular_velocity"], label="bit")
    ax[0].plot(r.time, r["top_drive_angular_velocity"], label="top drive")
    ax[0].set_ylabel("angular velocity (rad/s)")
    ax[0].legend()
    ax[1].plot(r.time, 1e3 * r["bit_axial_velocity"])
    ax[1].set_ylabel("bit axial velocity (mm/s)")
    ax[1].set_xlabel("time (s)")
    fig.suptitle(f"Fig. 4.4: {m.n_states}-state FEM, stuck {s['stuck_fraction']:.0%}, "
                 f"peak {ratio:.2f}x top drive")
    fig.tight_layout()
    fig.savefig(out_dir / "fig4.4.png", dpi=110)
    plt.close(fig)
    r.save(out_dir / "fig4.4.nc")
    measured = {"stuck_fraction": s["stuck_fraction"], "peak_ratio": ratio,
                "stick_slip_severity": s["stick_slip_severity"],
                "bit_bounce_fraction": s["bit_bounce_fraction"], "mean_rop": s["mean_rop"],
                "n_states": m.n_states}
    passed = bool(s["stuck_fraction"] > 0.2 and 1.5 <= ratio <= 3.0)
    return {"measured": measured, "passed": passed}
