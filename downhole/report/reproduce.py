"""Run registered experiments in parallel, isolating failures, and record what happened.

:func:`reproduce` runs experiments on a process pool (spawned workers, one BLAS thread each).
An experiment that raises does not stop the others: its ``claim.json`` gets ``passed: false`` and
an ``error`` line, and the traceback goes to ``ID/error.log``. Each experiment's standard output
and error go to ``ID/run.log``. ``OUT/reproduce.json`` summarizes the run and ``OUT/index.html``
(see :mod:`downhole.report.html`) shows it. Experiments whose claim is about speed
(:func:`is_timing`) run after the pool, one at a time, so that parallel jobs do not distort
their timings.

Outputs are never left stale or mixed (see "Outputs" in docs/architecture.md): when the run
starts, every selected experiment's folder ``OUT/ID`` is emptied and marked ``INCOMPLETE`` (and
``OUT`` itself, whose ``reproduce.json`` and ``index.html`` are removed). Each experiment runs in
a hidden staging folder ``OUT/.ID.staging-PID-RANDOM/ID`` that replaces ``OUT/ID`` by a rename
once its ``claim.json`` is written, so ``claim.json`` always sits beside the outputs of the same
run. A killed run leaves the experiments it did not finish marked ``INCOMPLETE`` with no claim.
Staging and old folders are created with :func:`tempfile.mkdtemp` (an exclusive ``mkdir`` under a
random name, readable by this user only): a link planted in a shared ``OUT`` cannot redirect an
experiment's writes.
"""

from __future__ import annotations

import contextlib
import json
import os
import platform
import re
import shutil
import tempfile
import time
import traceback
from collections.abc import Callable
from pathlib import Path

from downhole._atomic import (
    MARKER,
    OutputFolder,
    check_output_path,
    write_json_atomic,
    write_text_atomic,
)
from downhole._workers import StopRequested
from downhole.errors import DownholeInputError

__all__ = ["is_timing", "machine_description", "reproduce", "run_one"]

#: Files that identify a folder as an experiment folder written by :func:`run_one`.
_EXPERIMENT_FILES = ("claim.json", "run.log", "error.log", MARKER)


def _write_json(path: Path, data: dict) -> None:
    write_json_atomic(path, data)


def _new_hidden(out_dir: Path, eid: str, kind: str) -> Path:
    """A new, empty, private folder ``out_dir/.EID.KIND-PID-RANDOM`` (exclusive ``mkdir``)."""
    return Path(tempfile.mkdtemp(prefix=f".{eid}.{kind}-{os.getpid()}-", dir=out_dir))


def _check_experiment_folder(out_dir: Path, eid: str) -> None:
    """Refuse to clear ``out_dir/eid`` unless it is empty or an experiment folder."""
    target = out_dir / eid
    check_output_path(target, option=f"--out {out_dir}: experiment folder", kind="folder")
    if target.is_dir() and any(target.iterdir()) and not any(
            (target / f).exists() for f in _EXPERIMENT_FILES):
        raise DownholeInputError(f"--out {out_dir}: {target} exists and is not an experiment "
                                 "folder (no claim.json, run.log or INCOMPLETE); it is not "
                                 "cleared: choose another --out")


def _mark_experiment(out_dir: Path, eid: str) -> None:
    """Empty ``out_dir/eid`` and leave only the INCOMPLETE marker in it (previous run gone)."""
    target = out_dir / eid
    out_dir.mkdir(parents=True, exist_ok=True)
    if target.is_dir() and not target.is_symlink():
        old = _new_hidden(out_dir, eid, "old")
        os.replace(target, old)  # onto the empty folder just made
        shutil.rmtree(old, ignore_errors=True)
    target.mkdir()  # exclusive: whatever was put in its place meanwhile is not written into
    write_text_atomic(target / MARKER, f"downhole reproduce: experiment {eid} started (pid "
                      f"{os.getpid()}) and has not finished; rerun it.\n")


def _remove_leftovers(out_dir: Path, eid: str) -> None:
    """Staging and old folders of ``eid`` left by killed runs (any process)."""
    if not out_dir.is_dir():
        return
    pattern = re.compile(rf"\.{re.escape(eid)}\.(staging|old)-\d+(-\w+)?")
    for p in out_dir.iterdir():
        if p.is_dir() and pattern.fullmatch(p.name):
            shutil.rmtree(p, ignore_errors=True)


def _publish(stage_parent: Path, out_dir: Path, eid: str) -> None:
    """Replace ``out_dir/eid`` by the finished staging folder (claim.json already in it)."""
    target = out_dir / eid
    if target.exists():
        old = _new_hidden(out_dir, eid, "old")
        os.replace(target, old)
        os.replace(stage_parent / eid, target)
        shutil.rmtree(old, ignore_errors=True)
    else:
        os.replace(stage_parent / eid, target)
    shutil.rmtree(stage_parent, ignore_errors=True)


def run_one(eid: str, out_dir: str | Path, quick: bool) -> dict:
    """Run experiment ``eid`` into ``out_dir/eid``; never raises for the experiment's own errors.

    The run happens in a staging folder that replaces ``out_dir/eid`` when done; stdout and
    stderr go to ``run.log``, a failure's traceback to ``error.log``.

    Parameters
    ----------
    eid : str
        Experiment id.
    out_dir : str or pathlib.Path
        Output folder of the reproduction.
    quick : bool
        Run the experiment's quick variant.

    Returns
    -------
    dict
        The claim dict (as written to ``claim.json``: ``id``, ``claim``, ``measured``,
        ``passed``, ...) plus ``seconds`` (wall time, s), ``quick`` and, on failure, ``error``.

    Raises
    ------
    DownholeInputError
        If ``out_dir/eid`` exists and is not an experiment folder of a reproduction.
    KeyboardInterrupt, downhole._workers.StopRequested
        Passed through (SIGINT; SIGTERM or SIGHUP): the experiment stays marked INCOMPLETE.
    """
    os.environ.setdefault("MPLBACKEND", "Agg")
    from downhole.experiments import get_experiment, run_experiment

    load_plugins()

    out_dir = Path(out_dir)
    if not (out_dir / eid / MARKER).exists():  # called on its own, not from reproduce()
        _check_experiment_folder(out_dir, eid)
        _mark_experiment(out_dir, eid)
    stage_parent = _new_hidden(out_dir, eid, "staging")
    target = stage_parent / eid
    target.mkdir()
    try:
        t0 = time.perf_counter()
        with open(target / "run.log", "w") as log, contextlib.redirect_stdout(log), \
                contextlib.redirect_stderr(log):
            try:
                claim = run_experiment(eid, stage_parent, quick=quick)
                error = None
            except BaseException as exc:
                if isinstance(exc, (KeyboardInterrupt, StopRequested)):  # a stop signal: stop
                    raise
                error = f"{type(exc).__name__}: {exc}"
                write_text_atomic(target / "error.log", traceback.format_exc())
                try:
                    claim_text = get_experiment(eid).claim
                except KeyError:
                    claim_text = ""
                claim = {"id": eid, "claim": claim_text, "measured": {}, "passed": False}
        seconds = time.perf_counter() - t0
        claim = dict(claim)
        claim["seconds"] = round(seconds, 3)
        claim["quick"] = bool(quick)
        if error:
            claim["error"] = error
            claim["log"] = "error.log"
        _write_json(target / "claim.json", claim)
        _publish(stage_parent, out_dir, eid)
    except BaseException:  # stopped (or the disk is full): no half staging folder is left
        shutil.rmtree(stage_parent, ignore_errors=True)
        raise
    return claim


#: Environment variable naming extra modules (comma-separated) that register experiments; they
#: are imported in this process and in every worker, so experiments kept outside the package
#: (a lab's own, or a test's) run like the built-in ones.
PLUGINS_ENV = "DOWNHOLE_EXPERIMENT_PLUGINS"


def load_plugins() -> None:
    """Import the modules named in ``$DOWNHOLE_EXPERIMENT_PLUGINS`` (once each)."""
    import importlib

    for name in filter(None, (m.strip() for m in os.environ.get(PLUGINS_ENV, "").split(","))):
        importlib.import_module(name)


def _previous_seconds(out_dir: Path, eid: str) -> float:
    try:
        return float(json.loads((out_dir / eid / "claim.json").read_text()).get("seconds", 1e9))
    except (OSError, ValueError, TypeError):
        return 1e9  # unknown: schedule first


def reproduce(ids: list[str], out_dir: str | Path, quick: bool = False, jobs: int | None = None,
              progress: Callable[[str, dict], None] | None = None,
              on_start: Callable[[str], None] | None = None) -> dict:
    """Run ``ids`` into ``out_dir`` with ``jobs`` worker processes and write ``index.html``.

    Experiments known to be long (from an earlier run's ``claim.json``) start first; experiments
    whose claim is about speed (:func:`is_timing`) run alone after the others.

    Parameters
    ----------
    ids : list of str
        Experiment ids.
    out_dir : str or pathlib.Path
        Output folder.
    quick : bool, optional
        Run the quick variants (default False).
    jobs : int, optional
        Worker processes (default: the number of cores; 1 runs in this process).
    progress : callable(eid, claim), optional
        Called as each experiment finishes.
    on_start : callable(eid), optional
        Called before each experiment starts (only with ``jobs = 1``).

    Returns
    -------
    dict
        The run summary (also written to ``out_dir/reproduce.json``): ``passed``, ``failed``,
        ``errors``, ``seconds`` per experiment, ``wall_seconds``, ``machine``, ...

    Raises
    ------
    KeyError
        An unknown experiment id (before anything runs).
    DownholeInputError
        An output folder that may not be written (before anything runs), or a script without
        the ``if __name__ == "__main__"`` guard when ``jobs > 1``.
    """
    from downhole.experiments import get_experiment
    from downhole.report.html import build_index

    out_dir = Path(out_dir)
    load_plugins()
    for eid in ids:
        get_experiment(eid)  # unknown ids fail before anything runs
    check_output_path(out_dir, kind="folder")
    for eid in ids:
        _check_experiment_folder(out_dir, eid)
    jobs = max(1, int(jobs or os.cpu_count() or 1))
    if jobs > 1:  # before anything is written: a script without the guard would kill the workers
        from downhole._workers import check_main_guarded

        check_main_guarded(f"reproduce(jobs={jobs})", "jobs=1")
    order = sorted(ids, key=lambda e: -_previous_seconds(out_dir, e))
    # the previous results go before anything runs: a killed run cannot leave them looking fresh
    top = OutputFolder(out_dir, ("reproduce.json", "index.html"), "reproduce").writing()
    try:
        for eid in ids:
            _remove_leftovers(out_dir, eid)
            _mark_experiment(out_dir, eid)
        t0 = time.perf_counter()
        claims: dict[str, dict] = {}

        def _done(eid, claim):
            claims[eid] = claim
            if progress:
                progress(eid, claim)

        timing = [e for e in order if is_timing(get_experiment(e))]
        others = [e for e in order if e not in timing]
        if jobs == 1:
            for eid in others + timing:
                if on_start:
                    on_start(eid)
                _done(eid, run_one(eid, out_dir, quick))
        else:
            _run_pool(others, out_dir, quick, jobs, _done)
            # speed claims are measured alone, after the pool, so parallel jobs do not distort them
            _run_pool(timing, out_dir, quick, 1, _done)
        wall = time.perf_counter() - t0
        summary = {
            "quick": bool(quick), "jobs": jobs, "wall_seconds": round(wall, 2),
            "passed": sorted(e for e, c in claims.items() if c.get("passed")),
            "failed": sorted(e for e, c in claims.items() if not c.get("passed")),
            "errors": {e: c["error"] for e, c in claims.items() if c.get("error")},
            "seconds": {e: c.get("seconds") for e, c in claims.items()},
            "machine": machine_description(),
            "finished": time.strftime("%Y-%m-%d %H:%M:%S %Z"),
        }
        _write_json(out_dir / "reproduce.json", summary)
        build_index(out_dir)
    except BaseException as exc:  # a signal, a full disk, a broken pool: say why in the marker
        top.fail(f"{type(exc).__name__}: {exc}")
        raise
    top.commit()
    return summary


def _run_pool(ids: list[str], out_dir: Path, quick: bool, jobs: int, done) -> None:
    """Run ``ids`` on ``jobs`` spawned worker processes (one BLAS thread each)."""
    if not ids:
        return
    from concurrent.futures import as_completed
    from concurrent.futures.process import BrokenProcessPool

    from downhole._workers import broken_pool_error, worker_pool

    saved = {v: os.environ.get(v) for v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS",
                                             "MKL_NUM_THREADS", "MPLBACKEND")}
    for v in saved:
        os.environ.setdefault(v, "Agg" if v == "MPLBACKEND" else "1")
    try:
        with worker_pool(min(jobs, len(ids))) as pool:
            futs = {pool.submit(run_one, eid, str(out_dir), quick): eid for eid in ids}
            for f in as_completed(futs):
                eid = futs[f]
                try:
                    claim = f.result()
                except BrokenProcessPool as exc:  # every worker is gone: no claim is true
                    for other in futs:
                        other.cancel()
                    _crashed(out_dir, eid, exc, quick)
                    raise broken_pool_error(f"reproduce(jobs={jobs})", "jobs=1", exc) from None
                except (KeyboardInterrupt, SystemExit):  # SIGINT, SIGTERM, SIGHUP: stop
                    raise
                except BaseException as exc:
                    claim = _crashed(out_dir, eid, exc, quick)
                done(eid, claim)
    finally:
        for v, val in saved.items():
            if val is None:
                os.environ.pop(v, None)
            else:
                os.environ[v] = val


_TIMING = re.compile(r"computation(al)? (time|expense)|training time|\bfaster\b|speed-?up|"
                     r"deadline", re.IGNORECASE)


def is_timing(exp) -> bool:
    """True for experiments whose claim is about speed or met deadlines (a paced real-time
    run): they run alone, not beside other jobs.

    Parameters
    ----------
    exp : Experiment
        A registered experiment (its ``title`` and ``claim`` are searched).

    Returns
    -------
    bool
    """
    return bool(_TIMING.search(exp.title) or _TIMING.search(exp.claim))


def _crashed(out_dir: Path, eid: str, exc: BaseException, quick: bool) -> dict:
    from downhole.experiments import get_experiment

    target = out_dir / eid
    _remove_leftovers(out_dir, eid)  # the dead worker's staging folder
    _mark_experiment(out_dir, eid)
    write_text_atomic(target / "error.log",
                      "the worker process running this experiment died:\n" + "".join(
                          traceback.format_exception(type(exc), exc, exc.__traceback__)))
    claim = {"id": eid, "claim": get_experiment(eid).claim, "measured": {}, "passed": False,
             "error": f"worker process died: {type(exc).__name__}: {exc}", "log": "error.log",
             "quick": bool(quick)}
    _write_json(target / "claim.json", claim)
    (target / MARKER).unlink(missing_ok=True)
    return claim


def machine_description() -> dict:
    """CPU model, core count, memory, OS and Python/numpy/numba versions of this machine."""
    cpu = platform.processor() or ""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.lower().startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    mem = None
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemTotal"):
                mem = round(int(line.split()[1]) / 1024**2, 1)
                break
    except OSError:
        pass
    versions = {}
    for mod in ("numpy", "numba", "scipy"):
        try:
            versions[mod] = __import__(mod).__version__
        except ImportError:
            pass
    try:
        affinity = len(os.sched_getaffinity(0))
    except AttributeError:
        affinity = os.cpu_count()
    return {"cpu": cpu, "cores": affinity, "memory_gib": mem, "platform": platform.platform(),
            "python": platform.python_version(), **versions}
