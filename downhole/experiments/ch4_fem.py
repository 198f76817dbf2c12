"""Chapter 4 experiment: open-loop stick-slip and bit bounce on the directional FEM (Fig. 4.4)."""

from __future__ import annotations

from downhole.experiments import experiment
from downhole.experiments._plots import plot_stick_slip

__all__ = ["fig4_4"]


@experiment("fig4.4", title="Open-loop stick-slip on the 432-state directional FEM", chapter=4,
            claim="stick-slip: stuck_fraction > 0.2 and bit speed peaks 1.5-3x the top drive "
                  "speed (10 rad/s), Table 5.1 well, PI top drive, 120 kN WOB",
            caption="Stick-slip and bit-bounce behaviors of the drill bit motions")
def fig4_4(out_dir, quick):
    from downhole.sim import simulate
    from downhole.string.fem import fem_model

    duration = 30.0 if quick else 60.0
    m = fem_model(n_elements=107)
    r = simulate(m, duration=duration, dt=1e-3)
    win = (10.0, duration)
    s = r.summary(window=win)
    sel = r.time >= win[0]
    ratio = float(r["bit_angular_velocity"][sel].max() / 10.0)
    plot_stick_slip(r, out_dir / "fig4.4.png",
                    f"Fig. 4.4: {m.n_states}-state FEM, stuck {s['stuck_fraction']:.0%}, "
                    f"peak {ratio:.2f}x top drive")
    r.save(out_dir / "fig4.4.nc")
    measured = {"stuck_fraction": s["stuck_fraction"], "peak_ratio": ratio,
                "stick_slip_severity": s["stick_slip_severity"],
                "bit_bounce_fraction": s["bit_bounce_fraction"], "mean_rop": s["mean_rop"],
                "n_states": m.n_states}
    passed = bool(s["stuck_fraction"] > 0.2 and 1.5 <= ratio <= 3.0)
    return {"measured": measured, "passed": passed}
