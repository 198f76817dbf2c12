"""The reproduction report: ``OUT/index.html``, a static page over the experiments' outputs.

Per chapter, each experiment shows its figure(s) beside the dissertation's caption and the claim
checked, the measured numbers, pass/fail (or the error with a link to its traceback), and links
to its data files. The page is self-contained HTML + CSS with relative links, so the whole
folder can be copied or served as it is.
"""

from __future__ import annotations

import html
import json
import math
from pathlib import Path

__all__ = ["CHAPTERS", "build_index"]

#: Chapter titles of the dissertation (the dissertation's chapters).
CHAPTERS = {
    2: "Lumped axial-torsional models and dynamic programming",
    3: "Neutral-type distributed model and EID control",
    4: "Directional FEM model and DHP (SNAC) control",
    5: "Hybrid FEM + transfer-matrix models",
    6: "Software-in-the-loop testbed",
    7: "Beyond the dissertation: output feedback from surface measurements",
}

_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;margin:0;color:#1d2327;
background:#f6f7f8}
header{background:#1f3a4d;color:#fff;padding:18px 28px}
header h1{margin:0 0 6px;font-size:22px}
header p{margin:2px 0;font-size:13px;opacity:.9}
main{padding:12px 28px 40px;max-width:1500px}
h2{border-bottom:2px solid #1f3a4d;padding-bottom:4px;margin-top:34px}
.summary{border-collapse:collapse;font-size:13px;margin:12px 0}
.summary td,.summary th{border:1px solid #d0d4d8;padding:3px 8px;text-align:left}
.summary th{background:#e8ecef}
.exp{background:#fff;border:1px solid #d0d4d8;border-radius:6px;margin:16px 0;padding:12px 16px}
.exp h3{margin:0 0 8px;font-size:17px}
.badge{display:inline-block;border-radius:10px;padding:1px 10px;font-size:12px;
font-weight:600;color:#fff;margin-left:8px;vertical-align:middle}
.pass{background:#2e7d32}.fail{background:#c62828}.norun{background:#8a9299}
.row{display:flex;gap:18px;flex-wrap:wrap}
.figs{flex:3 1 560px;display:flex;flex-direction:column;gap:10px}
.figs img{max-width:100%;border:1px solid #e1e4e6}
.text{flex:2 1 360px;font-size:14px}
.caption{background:#f3f5f7;border-left:4px solid #1f3a4d;padding:6px 10px;margin:0 0 10px}
.claim{border-left:4px solid #8a9299;padding:6px 10px;margin:0 0 10px}
.measured{border-collapse:collapse;font-size:13px;margin:6px 0 10px}
.measured td{border-bottom:1px solid #e1e4e6;padding:2px 10px 2px 0;vertical-align:top}
.measured td:first-child{font-family:ui-monospace,monospace;color:#37474f}
.error{background:#fdecea;border-left:4px solid #c62828;padding:6px 10px;
font-family:ui-monospace,monospace;font-size:12px;white-space:pre-wrap;word-break:break-word}
.files a{margin-right:10px;font-size:13px}
.nofig{color:#8a9299;font-style:italic}
"""


def _fmt(v) -> str:
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        if not math.isfinite(v):
            return str(v)
        return f"{v:.4g}"
    if isinstance(v, list):
        if len(v) > 8:
            return "[" + ", ".join(_fmt(x) for x in v[:8]) + f", ... ({len(v)} values)]"
        return "[" + ", ".join(_fmt(x) for x in v) + "]"
    if v is None:
        return "-"
    return str(v)


def _flatten(d: dict, prefix: str = "") -> list[tuple[str, object]]:
    out = []
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out += _flatten(v, key + ".")
        else:
            out.append((key, v))
    return out


def _load_claim(folder: Path) -> dict | None:
    try:
        return json.loads((folder / "claim.json").read_text())
    except (OSError, ValueError):
        return None


def _experiment_html(exp, folder: Path) -> tuple[str, str]:
    """(card html, status) for one experiment."""
    e = html.escape
    claim = _load_claim(folder)
    if claim is None:
        status, badge = "not run", '<span class="badge norun">not run</span>'
    elif claim.get("passed"):
        status, badge = "passed", '<span class="badge pass">PASS</span>'
    else:
        status, badge = "failed", '<span class="badge fail">FAIL</span>'
    figs = sorted(folder.glob("*.png")) if folder.is_dir() else []
    files = sorted(p for p in folder.iterdir() if p.is_file() and not p.name.endswith(".part")) \
        if folder.is_dir() else []
    parts = [f'<section class="exp" id="{e(exp.id)}">',
             f"<h3>{e(exp.id)}: {e(exp.title)}{badge}</h3>", '<div class="row">',
             '<div class="figs">']
    if figs:
        for f in figs:
            rel = f"{folder.name}/{f.name}"
            parts.append(f'<a href="{e(rel)}"><img src="{e(rel)}" alt="{e(exp.id)} figure '
                         f'{e(f.stem)}" loading="lazy"></a>')
    else:
        parts.append('<p class="nofig">no figure written</p>')
    parts.append("</div><div class=\"text\">")
    if exp.caption:
        parts.append(f'<p class="caption"><b>Dissertation caption.</b> {e(exp.caption)}</p>')
    parts.append(f'<p class="claim"><b>Claim checked.</b> {e(exp.claim)}</p>')
    if claim is not None:
        if claim.get("error"):
            log = claim.get("log", "error.log")
            parts.append(f'<div class="error">{e(claim["error"])}</div>'
                         f'<p><a href="{e(folder.name)}/{e(log)}">traceback</a></p>')
        rows = _flatten(claim.get("measured") or {})
        if rows:
            parts.append('<table class="measured">')
            for k, v in rows:
                parts.append(f"<tr><td>{e(k)}</td><td>{e(_fmt(v))}</td></tr>")
            parts.append("</table>")
        if claim.get("seconds") is not None:
            mode = "quick" if claim.get("quick") else "full"
            parts.append(f"<p>ran in {claim['seconds']:.1f} s ({mode} mode)</p>")
    if files:
        parts.append('<p class="files"><b>Files:</b> ' + " ".join(
            f'<a href="{e(folder.name)}/{e(p.name)}">{e(p.name)}</a>' for p in files) + "</p>")
    parts.append("</div></div></section>")
    return "\n".join(parts), status


def build_index(out_dir: str | Path, title: str = "downhole: reproduction of the dissertation"
                ) -> Path:
    """Write ``out_dir/index.html`` over every registered experiment (run or not) and return it.

    Parameters
    ----------
    out_dir : str or pathlib.Path
        Reproduction output folder (its ``reproduce.json`` and each experiment's folder are
        read when present).
    title : str, optional
        Page title.

    Returns
    -------
    pathlib.Path
        The page written (atomically).
    """
    from downhole import __version__
    from downhole.experiments import all_experiments

    out_dir = Path(out_dir)
    e = html.escape
    try:
        run = json.loads((out_dir / "reproduce.json").read_text())
    except (OSError, ValueError):
        run = {}
    by_chapter: dict[int, list] = {}
    for exp in all_experiments():
        by_chapter.setdefault(exp.chapter, []).append(exp)
    cards, rows, counts = [], [], {"passed": 0, "failed": 0, "not run": 0}
    for ch in sorted(by_chapter):
        cards.append(f'<h2 id="ch{ch}">Chapter {ch}: {e(CHAPTERS.get(ch, ""))}</h2>')
        for exp in by_chapter[ch]:
            card, status = _experiment_html(exp, out_dir / exp.id)
            counts[status] += 1
            cards.append(card)
            cls = {"passed": "pass", "failed": "fail"}.get(status, "norun")
            claim = _load_claim(out_dir / exp.id) or {}
            secs = claim.get("seconds")
            rows.append(f'<tr><td><a href="#{e(exp.id)}">{e(exp.id)}</a></td><td>{ch}</td>'
                        f"<td>{e(exp.title)}</td><td><span class=\"badge {cls}\">{e(status)}"
                        f"</span></td><td>{'-' if secs is None else f'{secs:.1f}'}</td></tr>")
    machine = run.get("machine", {})
    meta = []
    if run:
        meta.append(f"{'quick' if run.get('quick') else 'full'} mode, {run.get('jobs')} parallel "
                    f"jobs, {run.get('wall_seconds')} s wall time, finished "
                    f"{e(str(run.get('finished', '')))}")
    if machine:
        meta.append(f"machine: {e(str(machine.get('cpu', '')))}, {machine.get('cores')} cores, "
                    f"{machine.get('memory_gib')} GiB, Python {e(str(machine.get('python')))}")
    page = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{e(title)}</title><style>{_CSS}</style></head>
<body><header><h1>{e(title)}</h1>
<p>downhole {e(__version__)}: {counts['passed']} passed, {counts['failed']} failed,
{counts['not run']} not run. Rerun with <code>downhole reproduce --all --out DIR</code>.</p>
{''.join(f'<p>{m}</p>' for m in meta)}
</header><main>
<table class="summary"><tr><th>id</th><th>chapter</th><th>title</th><th>status</th>
<th>seconds</th></tr>
{''.join(rows)}
</table>
{''.join(cards)}
</main></body></html>
"""
    path = out_dir / "index.html"
    from downhole._atomic import write_text_atomic

    write_text_atomic(path, page)
    return path
