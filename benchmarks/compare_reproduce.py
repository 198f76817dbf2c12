"""Compare ``downhole reproduce`` claims of this checkout against a baseline commit.

Runs ``downhole reproduce`` (all experiments, or the given ids) in a temporary git worktree of
the baseline commit and in this checkout, then compares every experiment's ``passed`` flag and
every number in its ``measured`` block. A number agrees when it is within ``--rtol`` (1 % by
default) of the baseline's, or both are below ``--atol`` in magnitude; timing entries (keys
containing ``second``, ``time_s``, ``speed``, real-time statistics such as deadline misses and
link counters, and every number of the speed experiments ``TIMING_EXPERIMENTS``) are reported
but not judged, since the machine is shared; a speed experiment's pass/fail is reported too.

Usage (from the repository root)::

    .venv/bin/python benchmarks/compare_reproduce.py --quick
    .venv/bin/python benchmarks/compare_reproduce.py fig2.3 fig5.4 --jobs 2

Exit status 0 when every claim that passes on the baseline passes now and every judged number
agrees; 1 otherwise. The report is printed and, with ``--out FILE``, written as JSON.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
_TIMING = ("second", "time_s", "speed", "wall", "ratio_to_seed", "x_seed", "x_baseline",
           "real_time", "elapsed", "timing", "overrun", "deadline", "lag_ms", "runtime.",
           "link.")
#: Experiments whose claims are about speed (their numbers are timings, reported not judged).
TIMING_EXPERIMENTS = ("table2.2", "table4.2", "table5.2", "fig4.13", "fig5.9")


def _git(*args: str) -> str:
    return subprocess.run(["git", *args], cwd=ROOT, check=True, capture_output=True,
                          text=True).stdout.strip()


def _reproduce(tree: Path, out: Path, args) -> dict[str, dict]:
    cmd = [sys.executable, "-c", "from downhole.cli import main; main()", "reproduce",
           "--out", str(out), "--jobs", str(args.jobs)]
    cmd += ["--quick"] if args.quick else []
    cmd += list(args.ids) if args.ids else ["--all"]
    env = dict(os.environ, PYTHONPATH=str(tree))
    subprocess.run(cmd, cwd=tree, env=env, capture_output=True, text=True)
    claims = {}
    for f in sorted(out.glob("*/claim.json")):
        c = json.loads(f.read_text())
        claims[c.get("id", f.parent.name)] = c
    return claims


def _flatten(value, prefix=""):
    if isinstance(value, dict):
        for k, v in value.items():
            yield from _flatten(v, f"{prefix}.{k}" if prefix else str(k))
    elif isinstance(value, (list, tuple)):
        for i, v in enumerate(value):
            yield from _flatten(v, f"{prefix}[{i}]")
    elif isinstance(value, bool) or value is None or isinstance(value, str):
        yield prefix, value
    elif isinstance(value, (int, float)):
        yield prefix, float(value)


def compare(base: dict, cur: dict, rtol: float, atol: float) -> tuple[list[dict], bool]:
    rows, ok = [], True
    for eid in sorted(set(base) | set(cur)):
        b, c = base.get(eid), cur.get(eid)
        if b is None or c is None:
            rows.append({"id": eid, "problem": "only in one tree"})
            ok &= b is None or not b.get("passed")
            continue
        if b.get("passed") and not c.get("passed") and eid not in TIMING_EXPERIMENTS:
            rows.append({"id": eid, "problem": "passed on the baseline, fails now",
                         "error": c.get("error")})
            ok = False
        bm, cm = dict(_flatten(b.get("measured", {}))), dict(_flatten(c.get("measured", {})))
        for key in sorted(set(bm) | set(cm)):
            x, y = bm.get(key), cm.get(key)
            timing = eid in TIMING_EXPERIMENTS or any(t in key.lower() for t in _TIMING)
            if not isinstance(x, float) or not isinstance(y, float):
                if x != y and not timing:
                    rows.append({"id": eid, "key": key, "baseline": x, "current": y,
                                 "problem": "differs"})
                    ok = False
                continue
            if math.isnan(x) and math.isnan(y):
                continue
            close = (abs(x) < atol and abs(y) < atol) or abs(y - x) <= rtol * abs(x)
            if not close:
                rel = abs(y - x) / abs(x) if x else float("inf")
                rows.append({"id": eid, "key": key, "baseline": x, "current": y,
                             "relative": rel, "judged": not timing,
                             "problem": "timing (not judged)" if timing else "differs"})
                ok &= timing
    return rows, ok


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("ids", nargs="*", help="experiment ids (default: all)")
    ap.add_argument("--baseline", default="2e4bc36")
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--rtol", type=float, default=0.01)
    ap.add_argument("--atol", type=float, default=1e-9)
    ap.add_argument("--out", type=Path, help="write the comparison as JSON")
    args = ap.parse_args(argv)
    commit = _git("rev-parse", args.baseline)
    with tempfile.TemporaryDirectory(prefix="downhole-repro-") as tmp:
        wt = Path(tmp) / "baseline"
        _git("worktree", "add", "--detach", "-q", str(wt), commit)
        try:
            print(f"baseline {commit[:7]} ...", flush=True)
            base = _reproduce(wt, Path(tmp) / "base", args)
            print("current ...", flush=True)
            cur = _reproduce(ROOT, Path(tmp) / "cur", args)
        finally:
            _git("worktree", "remove", "--force", str(wt))
    rows, ok = compare(base, cur, args.rtol, args.atol)
    npass_b = sum(bool(c.get("passed")) for c in base.values())
    npass_c = sum(bool(c.get("passed")) for c in cur.values())
    print(f"experiments: baseline {len(base)} ({npass_b} passed), current {len(cur)} "
          f"({npass_c} passed)")
    for r in rows:
        print("  " + json.dumps(r, default=str))
    print("agree" if ok else "DIFFER")
    if args.out:
        args.out.write_text(json.dumps({"baseline_commit": commit, "rows": rows, "ok": ok,
                                        "passed": {"baseline": npass_b, "current": npass_c}},
                                       indent=1, default=str))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
