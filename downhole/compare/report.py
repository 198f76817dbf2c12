"""The benchmark's report: ``index.html`` (tables, plots embedded as PNG data) and
``scores.json``, written atomically into the output folder."""

from __future__ import annotations

import base64
import html
import io
import json
import math

from downhole._atomic import OutputFolder, write_text_atomic

__all__ = ["OUTPUT_FILES", "TABLE_COLUMNS", "render_html", "write_report"]

#: Files the command owns in its output folder.
OUTPUT_FILES = ("index.html", "scores.json")

#: (score key, column title, quantity whose display unit the column takes (None: a ratio),
#: format) of the per-case tables.
TABLE_COLUMNS = (
    ("stick_slip_severity", "severity", None, "{:.2f}"),
    ("time_to_suppress", "suppressed after", "time", "{:.1f}"),
    ("stuck_fraction", "stuck", None, "{:.2f}"),
    ("bit_bounce_fraction", "bounce", None, "{:.2f}"),
    ("mean_rop", "ROP", "mean_rop", "{:.3g}"),
    ("mse", "MSE", "mse", "{:.4g}"),
    ("tracking_rms_angular", "speed RMS", "tracking_rms_angular", "{:.3g}"),
    ("tracking_rms_axial", "ROP RMS", "tracking_rms_axial", "{:.3g}"),
    ("peak_surface_torque", "peak torque", "surface_torque", "{:.3g}"),
)


def _units(units):
    """The figure flavour of a display unit system (si: rpm, mm/s, kN, kN·m, MPa)."""
    from downhole.units import display_units

    return display_units(units or "si").for_figures()


def _conv(units, quantity, value):
    """``value`` (SI) of ``quantity`` (a signal/metric name or ``"time"``) in display units."""
    if quantity is None:
        return value
    if quantity == "time":
        return units.convert("time", value, "s")[0]
    return units.convert(quantity, value)[0]


def _title(units, title, quantity):
    if quantity is None:
        return title
    unit = units.label("time", "s") if quantity == "time" else units.label(quantity)
    return f"{title} [{unit}]"


def _fmt(value, quantity, fmt, key, units):
    if value is None:
        return "never" if key == "time_to_suppress" else "-"
    if isinstance(value, float) and not math.isfinite(value):
        return "-"
    return fmt.format(_conv(units, quantity, value))


def _effort_text(scores: dict, units) -> str:
    eff = scores.get("effort", {})
    w = eff.get("top_drive_angular_velocity")
    return "-" if w is None else f"{_conv(units, 'top_drive_angular_velocity', w):.3g}"


def _plot(case: dict, traces: dict, units=None) -> str | None:
    """A PNG (base64) of the bit speed and surface torque of every controller on one case."""
    if not traces:
        return None
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    units = _units(units)
    fig, axes = plt.subplots(2, 1, figsize=(8, 4.6), sharex=True)
    for label, tr in traces.items():
        axes[0].plot(tr["time"], _conv(units, "bit_angular_velocity",
                                       list(tr["bit_angular_velocity"])), lw=0.9, label=label)
        axes[1].plot(tr["time"], _conv(units, "surface_torque", list(tr["surface_torque"])),
                     lw=0.9, label=label)
    axes[0].axhline(_conv(units, "bit_angular_velocity", case["speed"]), color="k", ls="--",
                    lw=0.8)
    t0 = case["pre_time"] if case["start"] == "stick_slip" else 0.0
    for ax in axes:
        if t0 > 0:
            ax.axvline(t0, color="grey", ls=":", lw=1)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel(f"bit speed [{units.label('bit_angular_velocity')}]")
    axes[1].set_ylabel(f"surface torque [{units.label('surface_torque')}]")
    axes[1].set_xlabel("time [s]" + (" (dotted: hand-over)" if t0 > 0 else ""))
    axes[0].legend(fontsize=7, loc="upper right", ncol=3)
    fig.suptitle(case["id"], fontsize=10)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90)
    plt.close(fig)
    return base64.b64encode(buf.getvalue()).decode("ascii")


def _case_line(c: dict, units=None) -> str:
    units = _units(units)

    def q(name, value):
        return f"{_conv(units, name, value):.4g} {units.label(name)}"

    axial = (f"WOB {q('wob', c['wob'])} (force hook)" if c["hook"] == "force"
             else f"ROP set-point {q('bit_axial_velocity', c['rop'])} (velocity hook)")
    start = {"rest": "from rest", "steady": "from steady drilling",
             "stick_slip": f"from a developed stick-slip cycle ({c['pre_time']:g} s of stiff PI)"}
    extra = []
    if c["epsilon_scale"] != 1.0:
        extra.append(f"epsilon {100 * c['epsilon_scale']:.0f} %")
    if c["noise"]:
        extra.append("sensor noise")
    if c["delay"]:
        extra.append(f"{1e3 * c['delay']:.0f} ms actuator delay")
    return (f"system <b>{html.escape(c['system'])}</b>, "
            f"{q('top_drive_angular_velocity', c['speed'])}, {axial}, "
            f"{start[c['start']]}, {c['duration']:g} s controlled"
            + (", " + ", ".join(extra) if extra else "")
            + f"; FEM {c['n_elements']} elements, dt {c['dt'] * 1e3:g} ms; region: "
            f"{html.escape(c['region'] or '?')}")


def render_html(scores: dict, traces: dict | None = None, units=None) -> str:
    """The report page (self-contained: plots are embedded as data URIs), its tables and plots
    in the display ``units`` (a system name or :class:`~downhole.units.UnitSystem`; default
    ``si``, shown with rpm, mm/s, kN·m and MPa). ``scores.json`` stays SI."""
    traces = traces or {}
    disp = _units(units)
    esc = html.escape
    s = scores["suite"]
    parts = [
        "<!doctype html><html><head><meta charset='utf-8'>",
        f"<title>downhole compare-controllers: {esc(s['name'])} v{s['version']}</title>",
        "<style>body{font-family:sans-serif;margin:2em;max-width:1200px}"
        "table{border-collapse:collapse;margin:0.5em 0 1.5em}"
        "td,th{border:1px solid #ccc;padding:3px 7px;text-align:right;font-size:13px}"
        "th{background:#f0f0f0}td.l{text-align:left}.na{color:#888}.fail{color:#b00}"
        "</style></head><body>",
        f"<h1>Controller benchmark: suite {esc(s['name'])} (version {s['version']})</h1>",
        f"<p>downhole {esc(str(scores.get('downhole_version', '')))}; {len(scores['cases'])} "
        f"cases x {len(scores['controllers'])} controllers; "
        f"{scores.get('wall_seconds', 0):g} s on {scores.get('jobs', 1)} job(s). The scores "
        "are computed from the true plant signals (FEM, delayed depth of cut); the controllers "
        "see the noisy measurements of the noisy cases.</p>",
        "<h2>Summary</h2><table><tr><th class='l'>controller</th><th>ok</th><th>n/a</th>"
        "<th>failed</th><th>stick-slip cases</th><th>suppressed</th><th>mean severity "
        "(stick-slip cases)</th><th>mean stuck (stick-slip cases)</th>"
        "<th>speed RMS / set-point (all ok)</th></tr>",
    ]
    for label, row in scores["summary"].items():
        def f(x, p=2):
            return "-" if x is None else f"{x:.{p}f}"
        parts.append(f"<tr><td class='l'>{esc(label)}</td><td>{row['ok']}</td>"
                     f"<td>{row['n/a']}</td><td>{row['failed']}</td>"
                     f"<td>{row['stick_slip_cases']}</td><td>{row['suppressed']}</td>"
                     f"<td>{f(row['mean_severity_stick_slip_cases'])}</td>"
                     f"<td>{f(row['mean_stuck_fraction_stick_slip_cases'])}</td>"
                     f"<td>{f(row['mean_relative_speed_tracking_rms'], 3)}</td></tr>")
    parts.append("</table><h2>Controllers</h2><table><tr><th class='l'>controller</th>"
                 "<th class='l'>source</th><th class='l'>description</th></tr>")
    for label, c in scores["controllers"].items():
        parts.append(f"<tr><td class='l'>{esc(label)}</td><td class='l'>{esc(c['source'])}</td>"
                     f"<td class='l'>{esc(c['description'])}</td></tr>")
    parts.append("</table>")
    for case in scores["cases"]:
        cid = case["id"]
        parts.append(f"<h2 id='{esc(cid)}'>{esc(cid)}</h2><p>{_case_line(case, disp)}</p>")
        head = "".join(f"<th>{esc(_title(disp, t, q))}</th>" for _, t, q, _ in TABLE_COLUMNS)
        parts.append(f"<table><tr><th class='l'>controller</th>{head}"
                     "<th>effort: speed cmd RMS "
                     f"[{esc(disp.label('top_drive_angular_velocity'))}]</th></tr>")
        for label, cell in scores["cells"][cid].items():
            if cell["status"] != "ok":
                cls = "na" if cell["status"] == "n/a" else "fail"
                parts.append(f"<tr><td class='l'>{esc(label)}</td><td class='l {cls}' "
                             f"colspan='{len(TABLE_COLUMNS) + 1}'>{esc(cell['status'])}: "
                             f"{esc(cell['reason'])}</td></tr>")
                continue
            sc = cell["scores"]
            vals = "".join(f"<td>{_fmt(sc.get(k), q, fmt, k, disp)}</td>"
                           for k, _, q, fmt in TABLE_COLUMNS)
            parts.append(f"<tr><td class='l'>{esc(label)}</td>{vals}"
                         f"<td>{_effort_text(sc, disp)}</td></tr>")
        parts.append("</table>")
        png = _plot(case, traces.get(cid, {}), disp)
        if png:
            parts.append(f"<img alt='{esc(cid)}' src='data:image/png;base64,{png}'>")
    parts.append("<h2>Score definitions</h2><table><tr><th class='l'>score</th><th>unit</th>"
                 "<th class='l'>definition</th></tr>")
    for k, d in scores["score_definitions"].items():
        parts.append(f"<tr><td class='l'>{esc(k)}</td><td>{esc(d['unit'])}</td>"
                     f"<td class='l'>{esc(d['definition'])}</td></tr>")
    parts.append("</table><p>Every case's full definition (system description included) is in "
                 "scores.json.</p></body></html>")
    return "\n".join(parts)


def write_report(out, scores: dict, traces: dict | None = None, units=None, *,
                 folder: OutputFolder | None = None) -> None:
    """Write ``out/scores.json`` (SI) and ``out/index.html`` (in the display ``units``)
    atomically (an ``INCOMPLETE`` marker stands in the folder until both are written).

    Parameters
    ----------
    out : path
        The output folder.
    scores : dict
        What :func:`downhole.compare.compare_controllers` returns (keys starting with ``_`` are
        not written).
    traces : dict, optional
        The plotted series (case id -> label -> series).
    units : str or UnitSystem, optional
        Display units of ``index.html``.
    folder : OutputFolder, optional
        The folder of a run that marked (and locked) ``out`` when it started; the caller
        commits it. Default: mark, write and commit here.
    """
    data = {k: v for k, v in scores.items() if not k.startswith("_")}
    if folder is None:
        with OutputFolder(out, OUTPUT_FILES, "compare-controllers") as own:
            _write(own, data, traces, units)
    else:
        _write(folder, data, traces, units)


def _write(folder: OutputFolder, data: dict, traces, units) -> None:
    page = render_html(data, traces, units)
    folder.writing()
    write_text_atomic(folder.path / "scores.json", json.dumps(data, indent=1, allow_nan=False))
    write_text_atomic(folder.path / "index.html", page)
