"""Score controllers on a suite: :func:`compare_controllers` (cells in parallel processes)."""

from __future__ import annotations

import copy
import math
import pickle
import time
from collections.abc import Callable, Mapping

from downhole.compare.builtin import BUILTIN, Entry, NotApplicable, declared_stand_in
from downhole.compare.runner import case_plant, run_cell
from downhole.compare.suite import SUITE_VERSIONS, get_suite
from downhole.control.base import check_pair
from downhole.errors import DownholeInputError

__all__ = ["FORMAT", "SCORES", "compare_controllers", "resolve_controllers", "summarize_scores"]

FORMAT = "downhole.compare/1"

#: Score name -> (unit, definition). Computed from the true plant signals (not the noisy
#: measurements) over the evaluation window = the second half of the controlled period, unless
#: said otherwise.
SCORES = {
    "stick_slip_severity": ("-", "(max - min) / (2 mean) of the bit angular velocity "
                            "(downhole.analysis.stick_slip_severity); null when the mean is <= 0"),
    "time_to_suppress": ("s", "time after the hand-over (or the start) after which the bit speed "
                         "stays within +/-50 % of the set-point; 0 if it never leaves the band, "
                         "null if it leaves it within the last 5 s"),
    "stuck_fraction": ("-", "fraction of samples with |bit angular velocity| < 0.1 rad/s"),
    "bit_bounce_fraction": ("-", "fraction of samples with WOB = 0 or depth of cut <= 0"),
    "mean_rop": ("m/s", "mean bit axial velocity"),
    "mse": ("Pa", "mechanical specific energy at the bit, WOB/A + 2 pi N TOB/(A ROP) (Teale)"),
    "tracking_rms_angular": ("rad/s", "RMS of bit angular velocity - speed set-point"),
    "tracking_rms_axial": ("m/s", "RMS of bit axial velocity - ROP reference"),
    "peak_surface_torque": ("N m", "max |surface torque| over the whole controlled period"),
    "effort": ("command units", "per command: RMS of the issued command minus its set-point "
               "over the whole controlled period"),
    "command_rate": ("command units/s", "per command: mean |change per step| / dt over the "
                     "whole controlled period (noise amplification shows here)"),
}


class _Spec:
    """One controller of a comparison: a label, where it came from and how to build it."""

    def __init__(self, label, *, entry: Entry | None = None, obj=None, factory=None,
                 source: str = "", description: str = ""):
        self.label, self.entry, self.obj, self.factory = label, entry, obj, factory
        self.source = source
        self.description = description or (entry.description if entry else "")
        self._cache: dict = {}

    def stand_in(self):
        return declared_stand_in(self.entry) if self.entry is not None else None

    def build(self, system, case):
        if self.entry is not None:
            key = self.entry.cache_key(case) if self.entry.cache_key else None
            if key is not None and key in self._cache:
                return self._cache[key]
            ctrl = self.entry.factory(system, case)
            if key is not None:
                self._cache[key] = ctrl
            return ctrl
        if self.obj is not None:
            try:
                return copy.deepcopy(self.obj)  # no state carried from one case to the next
            except Exception:
                return self.obj
        return self.factory(system, case)


def _is_controller(obj) -> bool:
    return callable(getattr(obj, "command", None)) and callable(getattr(obj, "reset", None))


def _one(label, spec) -> _Spec:
    if isinstance(spec, str):
        if spec not in BUILTIN:
            raise DownholeInputError(f"unknown built-in controller {spec!r}; known: "
                                     f"{sorted(BUILTIN)}")
        return _Spec(label, entry=BUILTIN[spec], source=f"builtin:{spec}")
    if isinstance(spec, Entry):
        return _Spec(label, entry=spec, source=f"builtin:{spec.name}")
    if _is_controller(spec):
        return _Spec(label, obj=spec, source=f"object:{type(spec).__name__}",
                     description=getattr(spec, "description", "") or type(spec).__name__)
    if callable(spec):
        return _Spec(label, factory=spec, source=f"factory:{getattr(spec, '__name__', '?')}",
                     description=getattr(spec, "description", "") or "")
    raise DownholeInputError(f"controller {label!r}: expected a built-in name, a controller "
                             f"(reset() and command(t, obs, ref)) or a factory(system, case), "
                             f"got {type(spec).__name__}")


def _label_of(spec) -> str:
    if isinstance(spec, str):
        return spec
    if isinstance(spec, Entry):
        return spec.name
    return str(getattr(spec, "label", None) or getattr(spec, "__name__", None)
               or type(spec).__name__)


def resolve_controllers(controllers) -> list:
    """Normalize ``controllers`` (None: every built-in; a name, object or factory; a list of
    them; or a mapping label -> one of them) to the comparison's specs, labels unique."""
    if controllers is None:
        controllers = list(BUILTIN)
    if isinstance(controllers, Mapping):
        items = [(str(k), v) for k, v in controllers.items()]
    else:
        if isinstance(controllers, (str, Entry)) or _is_controller(controllers) or (
                callable(controllers) and not isinstance(controllers, (list, tuple))):
            controllers = [controllers]
        items, seen = [], {}
        for spec in controllers:
            base = _label_of(spec)
            seen[base] = seen.get(base, 0) + 1
            items.append((base if seen[base] == 1 else f"{base}#{seen[base]}", spec))
    if not items:
        raise DownholeInputError("no controller to compare")
    labels = [k for k, _ in items]
    if len(set(labels)) != len(labels):
        raise DownholeInputError(f"controller labels must be unique, got {labels}")
    return [_one(k, v) for k, v in items]


def _prepare(spec: _Spec, case, system, plant):
    """(controller, None) or (None, n/a cell) for one cell, in the calling process."""
    stand_in = spec.stand_in()
    if stand_in is not None:
        why = check_pair(stand_in, plant.inner)
        if why:
            return None, {"status": "n/a", "reason": why}
    try:
        ctrl = spec.build(system, case)
    except NotApplicable as exc:
        return None, {"status": "n/a", "reason": str(exc)}
    except Exception as exc:
        return None, {"status": "failed", "reason": f"building the controller: "
                                                    f"{type(exc).__name__}: {exc}"}
    why = check_pair(ctrl, plant.inner)
    if why:
        return None, {"status": "n/a", "reason": why}
    return ctrl, None


def _work(args):
    """Worker entry (module level, so that spawned processes can import it)."""
    case, ctrl, trace = args
    return run_cell(case, ctrl, trace=trace)


def _picklable(obj) -> bool:
    try:
        pickle.dumps(obj)
        return True
    except Exception:
        return False


def compare_controllers(controllers=None, suite: str = "standard", out=None, *, jobs: int = 1,
                        progress: Callable | None = None, cases=None,
                        traces: bool = True, units=None) -> dict:
    """Score ``controllers`` on every case of ``suite``.

    Parameters
    ----------
    controllers : see :func:`resolve_controllers`
        Built-in names (:data:`downhole.compare.BUILTIN`), controller objects (the Controller
        contract; copied for every case), factories ``factory(system, case) -> controller``
        (e.g. :func:`downhole.compare.gym_policy`), or a mapping label -> one of these.
        Default: every built-in.
    suite : str
        ``"standard"`` or ``"smoke"`` (:data:`downhole.compare.SUITES`).
    out : path, optional
        Folder to write ``index.html`` and ``scores.json`` into (atomically, see
        :func:`downhole.compare.write_report`).
    jobs : int
        Worker processes for the cells (1: in this process).
    progress : callable, optional
        ``progress(done, total, case_id, label, status)`` after each cell.
    cases : sequence of str, optional
        Only these case ids of the suite.
    traces : bool
        Keep decimated time series of each cell (for the report's plots; not in the scores).
    units : str or UnitSystem, optional
        Display units of ``index.html`` (:func:`downhole.units.display_units`); the scores
        stay SI.

    Returns
    -------
    dict
        The content of ``scores.json``: ``format``, ``suite`` (name, version), ``controllers``,
        ``cases`` (full definitions), ``cells`` (case id -> label -> cell: ``status`` ``ok``
        with ``scores``, ``n/a`` or ``failed`` with ``reason``), ``summary`` and ``score_
        definitions``. With ``traces``, the key ``_traces`` (dropped from the file) holds the
        plotted series.
    """
    if out is not None:
        from downhole._atomic import check_output_path

        check_output_path(out, kind="folder", option="out")  # before any work
    specs = resolve_controllers(controllers)
    all_cases = get_suite(suite)
    if cases:
        known = {c.id for c in all_cases}
        unknown = [c for c in cases if c not in known]
        if unknown:
            raise DownholeInputError(f"unknown case ids {unknown} in suite {suite!r}; known: "
                                     f"{sorted(known)}")
        all_cases = tuple(c for c in all_cases if c.id in set(cases))
    if not (isinstance(jobs, int) and jobs >= 1):
        raise DownholeInputError(f"jobs must be an integer >= 1, got {jobs!r}")
    if jobs > 1:  # before any work: a script without the guard would kill every worker
        from downhole._workers import check_main_guarded

        check_main_guarded(f"compare_controllers(jobs={jobs})", "jobs=1")
    folder = None
    if out is not None:  # marked and locked now: an interrupted run leaves no old scores
        from downhole._atomic import OutputFolder
        from downhole.compare.report import OUTPUT_FILES

        folder = OutputFolder(out, OUTPUT_FILES, "compare-controllers").begin()
    try:
        scores, trace_data = _score(specs, all_cases, suite, jobs, progress, traces)
        if folder is not None:
            from downhole.compare.report import write_report

            write_report(out, scores, trace_data, units, folder=folder)
    except BaseException as exc:
        if folder is not None:
            folder.fail(f"{type(exc).__name__}: {exc}")
        raise
    if folder is not None:
        folder.commit()
    if traces:
        scores["_traces"] = trace_data
    return scores


def _score(specs, all_cases, suite: str, jobs: int, progress, traces: bool):
    """Run every cell; returns (scores without traces, trace data)."""
    from downhole import __version__

    t_start = time.perf_counter()
    cells: dict = {c.id: {} for c in all_cases}
    todo = []  # (case, label, controller)
    total = len(all_cases) * len(specs)
    done = 0

    def _report(case_id, label, cell):
        nonlocal done
        done += 1
        cells[case_id][label] = cell
        if progress is not None:
            progress(done, total, case_id, label, cell["status"])

    for case in all_cases:
        system = case.drilling_system()
        plant = case_plant(case, system)
        for spec in specs:
            ctrl, na = _prepare(spec, case, system, plant)
            if na is not None:
                _report(case.id, spec.label, na)
            else:
                todo.append((case, spec.label, ctrl))
    local = [t for t in todo if jobs == 1 or not _picklable(t[2])]
    remote = [t for t in todo if not any(t is x for x in local)]
    if remote:
        from concurrent.futures import as_completed
        from concurrent.futures.process import BrokenProcessPool

        from downhole._workers import broken_pool_error, worker_pool

        with worker_pool(jobs) as pool:
            futures = {pool.submit(_work, (case, ctrl, traces)): (case.id, label)
                       for case, label, ctrl in remote}
            for fut in as_completed(futures):
                case_id, label = futures[fut]
                try:
                    cell = fut.result()
                except BrokenProcessPool as exc:  # every cell left would fail: stop
                    for other in futures:
                        other.cancel()
                    raise broken_pool_error(f"compare_controllers(jobs={jobs})", "jobs=1",
                                            exc) from None
                except Exception as exc:
                    cell = {"status": "failed", "reason": f"{type(exc).__name__}: {exc}"}
                _report(case_id, label, cell)
    for case, label, ctrl in local:
        try:
            cell = run_cell(case, ctrl, trace=traces)
        except Exception as exc:
            cell = {"status": "failed", "reason": f"{type(exc).__name__}: {exc}"}
        _report(case.id, label, cell)
    # cells in suite order, controllers in the given order
    ordered = {c.id: {s.label: cells[c.id][s.label] for s in specs} for c in all_cases}
    trace_data = {cid: {lab: cell.pop("trace") for lab, cell in row.items() if "trace" in cell}
                  for cid, row in ordered.items()}
    scores = {
        "format": FORMAT,
        "suite": {"name": suite, "version": SUITE_VERSIONS[suite],
                  "cases": [c.id for c in all_cases]},
        "downhole_version": __version__,
        "controllers": {s.label: {"source": s.source, "description": s.description}
                        for s in specs},
        "cases": [c.definition() for c in all_cases],
        "cells": ordered,
        "score_definitions": {k: {"unit": u, "definition": d} for k, (u, d) in SCORES.items()},
    }
    scores["summary"] = summarize_scores(scores)
    scores["wall_seconds"] = round(time.perf_counter() - t_start, 1)
    scores["jobs"] = jobs
    return scores, trace_data


def summarize_scores(scores: dict) -> dict:
    """Per controller over the suite: cells ok / n/a / failed; over the ok cells of the
    stick-slip cases: mean severity, how many suppressed (time_to_suppress not null), mean
    stuck fraction; over all ok cells: mean |tracking RMS angular| / set-point."""
    regions = {c["id"]: c for c in scores["cases"]}
    out = {}
    for label in scores["controllers"]:
        row = {"ok": 0, "n/a": 0, "failed": 0}
        sev, stuck, supp, n_ss, track = [], [], 0, 0, []
        for cid, cells in scores["cells"].items():
            cell = cells[label]
            row[cell["status"]] += 1
            if cell["status"] != "ok":
                continue
            s = cell["scores"]
            track.append(s["tracking_rms_angular"] / regions[cid]["speed"])
            if regions[cid]["region"] == "stick-slip":
                n_ss += 1
                sev.append(s["stick_slip_severity"] if s["stick_slip_severity"] is not None
                           else math.inf)
                stuck.append(s["stuck_fraction"])
                supp += s["time_to_suppress"] is not None
        row["stick_slip_cases"] = n_ss
        row["suppressed"] = supp
        row["mean_severity_stick_slip_cases"] = (_mean(sev) if sev else None)
        row["mean_stuck_fraction_stick_slip_cases"] = (_mean(stuck) if stuck else None)
        row["mean_relative_speed_tracking_rms"] = _mean(track) if track else None
        out[label] = row
    return out


def _mean(xs):
    m = sum(xs) / len(xs)
    return float(m) if math.isfinite(m) else None
