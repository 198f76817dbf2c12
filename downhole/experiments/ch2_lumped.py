"""Chapter 2 lumped-model experiments: delayed vs approximated depth of cut (Figs. 2.3, 2.4),
stick-slip at low rotary speed, and the 4th- vs 12th-order models."""

from __future__ import annotations

import copy

import matplotlib.pyplot as plt
import numpy as np

from downhole.analysis.plots import save_figure
from downhole.experiments import experiment
from downhole.scenario import run_scenario


def _scenario(title, order, v0, w0, duration):
    return {"title": title,
            "model": {"fidelity": f"lumped{order}", "preset": "table_2_1"},
            "operation": {"mode": "velocity", "rop": f"{v0 * 1e3:g} mm/s",
                          "surface_speed": f"{w0:g} rad/s"},
            "simulation": {"duration": f"{duration:g} s", "dt": "0.5 ms", "record_dt": "10 ms",
                           "depth_of_cut": "delayed", "integrator": "euler"}}


#: The scenario of each experiment (``examples/<id>.toml`` holds the same, checked by a test).
SCENARIOS = {
    "fig2.3": _scenario("Fig. 2.3: Table 2.1, 10 mm/s, 10 rad/s", 4, 0.01, 10.0, 60.0),
    "fig2.4": _scenario("Fig. 2.4: Table 2.1, 20 mm/s, 20 rad/s", 4, 0.02, 20.0, 60.0),
    "stickslip-lumped": _scenario("Stick-slip: Table 2.1, 10 mm/s, 2 rad/s", 4, 0.01, 2.0, 100.0),
    "models-4th-vs-12th": _scenario("12th-order model, Table 2.1, 10 mm/s, 10 rad/s", 12, 0.01,
                                    10.0, 60.0),
}


def _run(eid, out_dir, duration=None, **simulation):
    """Run the experiment's scenario with overrides; the scenario used is written next to it."""
    import tomli_w

    data = copy.deepcopy(SCENARIOS[eid])
    if duration is not None:
        data["simulation"]["duration"] = f"{duration:g} s"
    model = simulation.pop("model", {})
    data["model"].update(model)
    data["simulation"].update(simulation)
    tag = "-".join(str(v) for v in (*model.values(), *simulation.values())) or "base"
    (out_dir / f"scenario-{tag}.toml").write_text(tomli_w.dumps(data))
    return run_scenario(data, source=f"<experiment {eid}>")


def _doc_comparison(out_dir, quick, eid, title):
    duration = 40.0 if quick else None
    t_eval = 20.0 if quick else 30.0
    runs = {mode: _run(eid, out_dir, duration, depth_of_cut=mode)
            for mode in ("delayed", "approximate")}
    a, b = runs["delayed"], runs["approximate"]
    sel = a.time >= t_eval
    rel = {}
    for ch in ("bit_axial_velocity", "bit_angular_velocity", "depth_of_cut"):
        x, y = a[ch][sel], b[ch][sel]
        rel[ch] = float(np.max(np.abs(x - y)) / np.mean(np.abs(x)))
    err = (a["depth_of_cut"][sel] - b["depth_of_cut"][sel]) / np.mean(a["depth_of_cut"][sel])
    fig, axes = plt.subplots(2, 2, figsize=(11, 7))
    for ax, ch, scale, unit in ((axes[0, 0], "bit_axial_velocity", 1e3, "mm/s"),
                                (axes[0, 1], "bit_angular_velocity", 1.0, "rad/s"),
                                (axes[1, 0], "depth_of_cut", 1e3, "mm")):
        ax.plot(a.time, a[ch] * scale, label="delayed (Eqs. 2.9-2.10)")
        ax.plot(b.time, b[ch] * scale, "--", label="approximated (Eq. 2.11)")
        ax.set_ylabel(f"{ch.replace('_', ' ')} [{unit}]")
        ax.set_xlabel("time [s]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    axes[1, 1].hist(err * 100, bins=50)
    axes[1, 1].set_xlabel(f"depth-of-cut error after {t_eval:.0f} s [% of mean]")
    axes[1, 1].set_ylabel("samples")
    fig.suptitle(title)
    fig.tight_layout()
    save_figure(fig, out_dir / "comparison.png")
    a.save(out_dir / "delayed.nc")
    b.save(out_dir / "approximate.nc")
    measured = {"max_rel_diff_after_transient": rel, "t_eval": t_eval,
                "doc_error_percent_p99": float(np.percentile(np.abs(err) * 100, 99))}
    passed = all(v < 0.02 for v in rel.values())
    return {"measured": measured, "passed": passed}


@experiment("fig2.3", chapter=2, title="Delayed vs approximated depth of cut, 10 mm/s, 10 rad/s",
            claim="after the transient the approximated depth of cut (Eq. 2.11) tracks the delayed "
                  "one: bit velocities and depth of cut within 2%",
            caption="Case 1: comparison between model using time-delay based depth of cut and "
                    "that with the approximated depth of cut")
def fig2_3(out_dir, quick):
    return _doc_comparison(out_dir, quick, "fig2.3", "Fig. 2.3: the seed's Table 2.1 string "
                           "(787 t), 10 mm/s, 10 rad/s")


@experiment("fig2.4", chapter=2, title="Delayed vs approximated depth of cut, 20 mm/s, 20 rad/s",
            claim="after the transient the approximated depth of cut tracks the delayed one: bit "
                  "velocities and depth of cut within 2%",
            caption="Case 2: comparison between model using time-delay based depth of cut and "
                    "that with the approximated depth of cut")
def fig2_4(out_dir, quick):
    return _doc_comparison(out_dir, quick, "fig2.4", "Fig. 2.4: the seed's Table 2.1 string "
                           "(787 t), 20 mm/s, 20 rad/s")


@experiment("stickslip-lumped", chapter=2,
            title="Stick-slip of the 4th-order model at 2 rad/s (delayed depth of cut only)",
            claim="at 2 rad/s the delayed depth of cut gives stick-slip (stuck_fraction > 0.1) "
                  "while the approximated one converges (severity < 0.2)")
def stickslip_lumped(out_dir, quick):
    duration = 80.0 if quick else None
    a = _run("stickslip-lumped", out_dir, duration, depth_of_cut="delayed")
    b = _run("stickslip-lumped", out_dir, duration, depth_of_cut="approximate")
    sa, sb = a.summary(), b.summary()
    fig, axes = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    axes[0].plot(a.time, a["bit_angular_velocity"], label="delayed depth of cut")
    axes[0].plot(b.time, b["bit_angular_velocity"], "--", label="approximated depth of cut")
    axes[0].axhline(2.0, color="k", lw=0.8, ls=":", label="top drive")
    axes[0].set_ylabel("bit angular velocity [rad/s]")
    axes[0].legend(fontsize=8)
    axes[1].plot(a.time, a["bit_axial_velocity"] * 1e3, label="delayed")
    axes[1].plot(b.time, b["bit_axial_velocity"] * 1e3, "--", label="approximated")
    axes[1].set_ylabel("bit axial velocity [mm/s]")
    axes[1].set_xlabel("time [s]")
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.suptitle("The seed's Table 2.1 string (787 t) at 10 mm/s, 2 rad/s: stick-slip and bit "
                 "bounce")
    fig.tight_layout()
    save_figure(fig, out_dir / "stickslip.png")
    a.save(out_dir / "delayed.nc")
    measured = {"delayed": sa, "approximate": sb}
    passed = sa["stuck_fraction"] > 0.1 and sb["stick_slip_severity"] < 0.2
    return {"measured": measured, "passed": passed}


@experiment("models-4th-vs-12th", chapter=2,
            title="4th- vs 12th-order lumped models under the same top-drive inputs",
            claim="after 20 s the 12th-order bit velocities follow the 4th-order ones within 5% "
                  "(RMS over mean), nominal 10 mm/s, 10 rad/s")
def models_4th_vs_12th(out_dir, quick):
    duration = 40.0 if quick else None
    r12 = _run("models-4th-vs-12th", out_dir, duration)
    r4 = _run("models-4th-vs-12th", out_dir, duration, model={"fidelity": "lumped4"})
    sel = r4.time >= 20.0
    rel = {}
    for ch in ("bit_axial_velocity", "bit_angular_velocity"):
        x, y = r4[ch][sel], r12[ch][sel]
        rel[ch] = float(np.sqrt(np.mean((x - y) ** 2)) / np.mean(np.abs(x)))
    fig, axes = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    axes[0].plot(r4.time, r4["bit_axial_velocity"] * 1e3, label="4th order")
    axes[0].plot(r12.time, r12["bit_axial_velocity"] * 1e3, "--", label="12th order")
    axes[0].set_ylabel("bit axial velocity [mm/s]")
    axes[1].plot(r4.time, r4["bit_angular_velocity"], label="4th order")
    axes[1].plot(r12.time, r12["bit_angular_velocity"], "--", label="12th order")
    axes[1].set_ylabel("bit angular velocity [rad/s]")
    axes[1].set_xlabel("time [s]")
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle("4th- vs 12th-order lumped model of the seed's Table 2.1 string (787 t), "
                 "10 mm/s, 10 rad/s")
    fig.tight_layout()
    save_figure(fig, out_dir / "models.png")
    r12.save(out_dir / "lumped12.nc")
    return {"measured": {"rms_over_mean_after_20s": rel}, "passed": all(v < 0.05 for v in rel.values())}
