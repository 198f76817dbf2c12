"""Run a grid or Monte Carlo sweep of a scenario on a process pool or a Dask cluster.

:func:`run_sweep` validates everything first (paths, ranges, metrics, window, the base scenario),
then runs the cases in batches (one task per batch, so the per-task overhead of a pool or a Dask
scheduler is paid once per batch, not per case) and assembles one :class:`xarray.Dataset`:
metrics over the swept parameters as dimensions (grid) or over ``case`` (random), with an
``error`` string per case (empty when it ran) and NaN metrics where a case failed.
"""

from __future__ import annotations

import copy
import itertools
import json
import math
import os
import time
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path

import numpy as np

from downhole._atomic import write_netcdf_atomic
from downhole.errors import DownholeInputError, ScenarioError
from downhole.sweep.spec import (
    METRICS,
    ParamSpec,
    compute_metrics,
    metric_names,
    parse_param,
    parse_window,
    set_path,
    validate_path,
)

__all__ = ["failed_cases", "load_sweep", "load_sweep_file", "run_cases", "run_sweep", "save_sweep"]


def load_sweep_file(path: str | Path) -> tuple[dict, str, dict]:
    """Read a scenario TOML; returns ``(scenario_data, source, sweep_settings)``.

    An optional ``[sweep]`` table (``params``, ``metrics``, ``window``, ``random``, ``seed``,
    ``batch_size``, ``stability_map``) is split off: it configures the sweep and is not part of
    the scenario.

    Parameters
    ----------
    path : str or pathlib.Path
        Scenario TOML file.

    Returns
    -------
    scenario_data : dict
        The parsed scenario without ``[sweep]``.
    source : str
        The file's name, for messages.
    sweep_settings : dict
        The ``[sweep]`` table (empty if absent).

    Raises
    ------
    ScenarioError
        If the file cannot be read or parsed.
    DownholeInputError
        If ``sweep`` is not a table or has an unknown key.
    """
    from downhole.scenario import load_scenario

    data, source, _ = load_scenario(path)
    settings = data.pop("sweep", {}) or {}
    if not isinstance(settings, dict):
        raise DownholeInputError(f"{source}: sweep: expected a table [sweep]")
    known = {"params", "metrics", "window", "random", "seed", "batch_size", "stability_map"}
    extra = set(settings) - known
    if extra:
        raise DownholeInputError(f"{source}: sweep.{min(extra)}: unknown key; expected "
                                 f"one of {sorted(known)}")
    return data, source, settings


def _param_texts(params) -> list[str]:
    if params is None:
        return []
    if isinstance(params, str):
        return [params]
    if isinstance(params, dict):
        out = []
        for name, spec in params.items():
            if isinstance(spec, (list, tuple)) and len(spec) == 3 and isinstance(spec, tuple):
                spec = f"{spec[0]}:{spec[1]}:{spec[2]}"
            elif isinstance(spec, (list, tuple)):
                spec = ",".join(str(v) for v in spec)
            out.append(f"{name}={spec}")
        return out
    return [str(p) for p in params]


def run_cases(base: dict, source: str, paths: Sequence[str], cases: Sequence[Sequence[float]],
              metrics: Sequence[str], window: tuple[float, float] | None):
    """Run ``cases`` (values for ``paths``) one after the other; the task a worker executes.

    A case that raises gives NaN metrics and ``"ExceptionType: message"``.

    Parameters
    ----------
    base : dict
        The parsed base scenario (copied for each case).
    source : str
        Its name, for messages.
    paths : sequence of str
        Dotted scenario paths of the swept parameters.
    cases : sequence of sequence of float
        One row of values (SI, in the order of ``paths``) per case.
    metrics : sequence of str
        Metric names (:data:`downhole.sweep.spec.METRICS`).
    window : (float, float) or None
        Time window of the metrics, s; None for the second half of each run.

    Returns
    -------
    list of tuple
        ``(metric_values, error_text, seconds)`` per case: the metric values (SI), ``""`` or
        the error, and the wall time of the case, s.
    """
    from downhole.scenario import run_scenario

    out = []
    for values in cases:
        t0 = time.perf_counter()
        try:
            data = copy.deepcopy(base)
            for p, v in zip(paths, values):
                set_path(data, p, float(v))
            res = run_scenario(data, source)
            vals = compute_metrics(res, list(metrics), window)
            err = ""
        except Exception as exc:
            vals = [math.nan] * len(metrics)
            err = f"{type(exc).__name__}: {exc}"
        out.append((vals, err, time.perf_counter() - t0))
    return out


def _batches(n: int, size: int) -> list[range]:
    return [range(i, min(i + size, n)) for i in range(0, n, size)]


def _limit_threads_env() -> dict:
    """Environment for worker processes: one BLAS/OpenMP thread each (the pool is the
    parallelism)."""
    saved = {}
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
        saved[var] = os.environ.get(var)
        os.environ.setdefault(var, "1")
    os.environ.setdefault("MPLBACKEND", "Agg")
    return saved


def _restore_env(saved: dict) -> None:
    for var, val in saved.items():
        if val is None:
            os.environ.pop(var, None)
        else:
            os.environ[var] = val


def run_sweep(scenario: str | Path | dict, params=None, metrics=None, *, random: int | None = None,
              seed: int | None = None, window=None, scheduler=None, processes: int | None = None,
              batch_size: int | None = None, progress: Callable[[int, int], None] | None = None,
              source: str = "<dict>", on_start: Callable[[], None] | None = None):
    """Run a parameter sweep and return its results as an :class:`xarray.Dataset`.

    Parameters
    ----------
    scenario : path or dict
        A scenario TOML file (its optional ``[sweep]`` table supplies defaults for the other
        arguments) or an already-parsed scenario dict.
    params : list of str or dict
        ``["operation.surface_speed=2:12:11", "bit.epsilon=60 MPa:90 MPa:4"]`` or
        ``{"operation.surface_speed": "2:12:11"}``; see :mod:`downhole.sweep.spec`.
    metrics : list of str
        Names from :data:`downhole.sweep.spec.METRICS`.
    random : int, optional
        Monte Carlo: draw this many cases uniformly within the parameter ranges (``START:STOP``)
        instead of a grid.
    seed : int, optional
        Seed of the random draw (makes it reproducible).
    window : (float, float) or "START:END", optional
        Time window of the metrics, s; default the second half of each run.
    scheduler : None, "local-cluster", "tcp://HOST:PORT" or distributed.Client
        None: a local process pool (``processes`` workers; 1 runs in this process).
        "local-cluster": a :class:`dask.distributed.LocalCluster` of ``processes`` workers.
        An address or a Client: that Dask cluster (its workers must have downhole installed).
    processes : int, optional
        Worker count for the pool or the local cluster; default the number of cores.
    batch_size : int, optional
        Cases per task; default about four tasks per worker, at most 64 cases per task.
    progress : callable(done, total), optional
        Called as cases complete.
    source : str, optional
        Name of a scenario given as a dict, used in messages (default ``"<dict>"``; a file's
        own name otherwise).
    on_start : callable(), optional
        Called once, after every input was validated and before the first case runs (the CLI
        marks its output folder incomplete there).

    Returns
    -------
    xarray.Dataset
        Grid: one dimension per swept parameter (named by its dotted path, SI values); random:
        dimension ``case`` with the parameters as coordinates. Variables: each metric, ``error``
        (empty string where the case ran) and ``case_seconds``.

    Raises
    ------
    DownholeInputError
        Unknown parameter path, empty or malformed range, unknown metric, bad window, an invalid
        base scenario -- all before any case runs.
    """
    settings: dict = {}
    if isinstance(scenario, dict):
        base = copy.deepcopy(scenario)
        settings = base.pop("sweep", {}) or {}
    else:
        base, source, settings = load_sweep_file(scenario)
    # options not given as arguments come from the file's [sweep] table; their errors name it
    from_file = {k for k, v in (("params", params), ("metrics", metrics), ("random", random),
                                ("seed", seed), ("window", window), ("batch_size", batch_size))
                 if (v is None or (k in ("params", "metrics") and not v))
                 and (k in settings or not isinstance(scenario, dict))}
    params = params if params else settings.get("params")
    metrics = metrics if metrics else settings.get("metrics")
    random = random if random is not None else settings.get("random")
    seed = seed if seed is not None else settings.get("seed")
    window = window if window is not None else settings.get("window")
    batch_size = batch_size if batch_size is not None else settings.get("batch_size")

    def _checked(key, func, *args, **kwargs):
        try:
            return func(*args, **kwargs)
        except ScenarioError:
            raise
        except (DownholeInputError, TypeError, ValueError) as exc:
            if key in from_file:
                raise ScenarioError(source, f"sweep.{key}", str(exc)) from None
            if isinstance(exc, DownholeInputError):
                raise
            raise DownholeInputError(f"{key}: {exc}") from None

    def _check_random():
        if random is not None and (not isinstance(random, int) or isinstance(random, bool)
                                   or random < 1):
            raise DownholeInputError(f"--random must be a positive whole number of cases, got "
                                     f"{random!r}")

    def _check_seed():
        if seed is not None and (not isinstance(seed, int) or isinstance(seed, bool)
                                 or seed < 0):
            raise DownholeInputError(f"seed must be a non-negative whole number, got {seed!r}")

    def _check_batch():
        if batch_size is not None and (not isinstance(batch_size, int)
                                       or isinstance(batch_size, bool) or batch_size < 1):
            raise DownholeInputError(f"batch_size must be a positive whole number, got "
                                     f"{batch_size!r}")

    # ---- validation: nothing runs before all of this passed ---------------------------------
    _checked("random", _check_random)
    _checked("seed", _check_seed)
    texts = _checked("params", _param_texts, params)
    if not texts:
        if not isinstance(scenario, dict):
            raise ScenarioError(source, "sweep.params", "no parameter to sweep; give --param "
                                "NAME=START:STOP:COUNT or params in the [sweep] table")
        raise DownholeInputError("no parameter to sweep; give --param NAME=START:STOP:COUNT")
    specs = [_checked("params", parse_param, t, random=random is not None) for t in texts]
    names = [s.path for s in specs]
    dup = {n for n in names if names.count(n) > 1}
    if dup:
        raise DownholeInputError(f"--param {min(dup)} given more than once")
    metrics = _checked("metrics", metric_names, metrics)
    window = _checked("window", parse_window, window)
    _validate_base(base, source)
    for s in specs:
        _checked("params", validate_path, base, source, s)
    if processes is not None and (not isinstance(processes, int) or processes < 1):
        raise DownholeInputError(f"processes must be a positive whole number, got {processes!r}")
    _checked("batch_size", _check_batch)

    # ---- cases --------------------------------------------------------------------------------
    if random is None:
        grid = [s.values for s in specs]
        cases = np.array(list(itertools.product(*grid)), dtype=float).reshape(-1, len(specs))
    else:
        rng = np.random.default_rng(seed)
        cases = np.column_stack([rng.uniform(s.low, s.high, size=random) for s in specs])
    n = len(cases)
    workers = processes or _cluster_workers(scheduler) or os.cpu_count() or 1
    if batch_size is None:
        batch_size = max(1, min(64, math.ceil(n / (4 * workers))))
    batches = _batches(n, batch_size)

    t0 = time.perf_counter()
    results: list = [None] * n
    done = 0

    def _store(batch: range, out):
        nonlocal done
        for i, r in zip(batch, out):
            results[i] = r
        done += len(batch)
        if progress:
            progress(done, n)

    def _fail_batch(batch: range, exc: BaseException):
        err = f"{type(exc).__name__}: {exc}"
        _store(batch, [([math.nan] * len(metrics), err, math.nan)] * len(batch))

    args = (base, source, names)
    if (scheduler is None and workers != 1) or scheduler in ("local", "local-cluster"):
        from downhole._workers import check_main_guarded

        check_main_guarded(f"run_sweep(processes={workers})", "processes=1")
    if on_start is not None:
        on_start()
    executor_desc = _execute(args, cases, batches, metrics, window, scheduler, processes,
                             workers, _store, _fail_batch)
    wall = time.perf_counter() - t0
    return _assemble(specs, cases, results, metrics, window, base, source, random, seed,
                     executor_desc, wall, batch_size)


def _cluster_workers(scheduler) -> int | None:
    """Worker count of an existing Dask client (for batch sizing), else None."""
    try:
        from distributed import Client
    except ImportError:  # pragma: no cover
        return None
    if isinstance(scheduler, Client):
        try:
            return len(scheduler.scheduler_info()["workers"]) or None
        except Exception:
            return None
    return None


def _validate_base(base: dict, source: str) -> None:
    """Validate the unswept scenario (lumped types fully; others by their model type only)."""
    from downhole.scenario import validate_data

    validate_data(base, source)


def _execute(args, cases, batches, metrics, window, scheduler, processes, workers, store,
             fail_batch) -> str:
    base, source, names = args
    if scheduler is None and workers == 1:
        for b in batches:
            store(b, run_cases(base, source, names, cases[b.start:b.stop], metrics, window))
        return "serial (this process)"
    if scheduler is None:
        from concurrent.futures import as_completed
        from concurrent.futures.process import BrokenProcessPool

        from downhole._workers import broken_pool_error, worker_pool

        saved = _limit_threads_env()
        try:
            with worker_pool(min(workers, len(batches))) as pool:
                futs = {pool.submit(run_cases, base, source, names, cases[b.start:b.stop],
                                    metrics, window): b for b in batches}
                for f in as_completed(futs):
                    try:
                        store(futs[f], f.result())
                    except BrokenProcessPool as exc:  # every batch left would fail: stop
                        for other in futs:
                            other.cancel()
                        raise broken_pool_error(f"run_sweep(processes={workers})",
                                                "processes=1", exc) from None
                    except Exception as exc:  # the batch's task raised: reported failed
                        fail_batch(futs[f], exc)
        finally:
            _restore_env(saved)
        return f"process pool ({min(workers, len(batches))} processes)"
    return _execute_dask(args, cases, batches, metrics, window, scheduler, workers, store,
                         fail_batch)


def _execute_dask(args, cases, batches, metrics, window, scheduler, workers, store,
                  fail_batch) -> str:
    import logging

    from distributed import Client, LocalCluster, as_completed

    base, source, names = args
    cluster = None
    own_client = True
    saved = _limit_threads_env()
    try:
        if isinstance(scheduler, Client):
            client, own_client = scheduler, False
            desc = f"dask cluster {client.scheduler.address}"
        elif scheduler in ("local", "local-cluster"):
            cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                   dashboard_address=None, silence_logs=logging.ERROR)
            client = Client(cluster)
            desc = f"dask LocalCluster ({workers} workers)"
        elif isinstance(scheduler, str) and "://" in scheduler:
            try:
                client = Client(scheduler, timeout="20s")
            except OSError as exc:
                raise DownholeInputError(f"--scheduler {scheduler}: cannot reach the Dask "
                                         f"scheduler ({exc})") from None
            desc = f"dask cluster {scheduler}"
        else:
            raise DownholeInputError(f"scheduler must be None, 'local-cluster', an address "
                                     f"tcp://HOST:PORT or a distributed.Client, got {scheduler!r}")
        try:
            futs = [client.submit(run_cases, base, source, names, cases[b.start:b.stop],
                                  metrics, window, pure=False) for b in batches]
            index = {f.key: b for f, b in zip(futs, batches)}
            for f in as_completed(futs):
                try:
                    store(index[f.key], f.result())
                except Exception as exc:  # a worker died or the task was lost
                    fail_batch(index[f.key], exc)
        finally:
            if own_client:
                client.close()
            if cluster is not None:
                cluster.close()
    finally:
        _restore_env(saved)
    return desc


def _assemble(specs: list[ParamSpec], cases, results, metrics, window, base, source, random,
              seed, executor_desc, wall, batch_size):
    import tomli_w
    import xarray as xr

    from downhole import __version__

    n = len(cases)
    vals = np.array([r[0] for r in results], dtype=float).reshape(n, len(metrics))
    errs = np.array([r[1] for r in results], dtype=object)
    secs = np.array([r[2] for r in results], dtype=float)
    data_vars = {}
    if random is None:
        shape = tuple(len(s.values) for s in specs)
        dims = tuple(s.path for s in specs)
        coords = {s.path: (s.path, s.values, {"units": s.units, "spec": s.text}) for s in specs}

        def reshape(a):
            return a.reshape(shape)
    else:
        dims = ("case",)
        coords = {"case": ("case", np.arange(n))}
        for j, s in enumerate(specs):
            coords[s.path] = ("case", cases[:, j], {"units": s.units, "spec": s.text,
                                                    "low": s.low, "high": s.high})

        def reshape(a):
            return a
    for j, m in enumerate(metrics):
        data_vars[m] = (dims, reshape(vals[:, j]), {"units": METRICS[m].units,
                                                    "description": METRICS[m].description})
    data_vars["error"] = (dims, reshape(errs.astype(str)),
                          {"description": "exception of a failed case ('' if it ran)"})
    data_vars["case_seconds"] = (dims, reshape(secs), {"units": "s",
                                                      "description": "wall time of the case"})
    try:
        scenario_text = tomli_w.dumps(base)
    except Exception:
        scenario_text = json.dumps(base, default=str)
    n_failed = int(np.sum(errs != ""))
    attrs = {
        "title": "downhole sweep",
        "sweep_mode": "grid" if random is None else "random",
        "source": source,
        "scenario": scenario_text,
        "params": json.dumps({s.path: s.text for s in specs}),
        "metrics": json.dumps(list(metrics)),
        "window": json.dumps(list(window) if window else "second half of each run"),
        "n_cases": n,
        "n_failed": n_failed,
        "executor": executor_desc,
        "batch_size": batch_size,
        "wall_seconds": wall,
        "downhole_version": __version__,
    }
    if random is not None:
        attrs["random_cases"] = int(random)
        attrs["seed"] = -1 if seed is None else int(seed)
    return xr.Dataset(data_vars, coords=coords, attrs=attrs)


def save_sweep(ds, path: str | Path) -> Path:
    """Write a sweep dataset as NetCDF (h5netcdf), atomically.

    Serialized in memory, then a temporary file in the same folder, fsync, rename
    (:func:`downhole._atomic.write_netcdf_atomic`): a full disk is one clean :class:`OSError`.

    Parameters
    ----------
    ds : xarray.Dataset
        The dataset of :func:`run_sweep`.
    path : str or pathlib.Path
        Output file.

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    return write_netcdf_atomic(path, ds)


def load_sweep(path: str | Path):
    """Load a sweep dataset written by :func:`save_sweep`.

    Parameters
    ----------
    path : str or pathlib.Path
        NetCDF file.

    Returns
    -------
    xarray.Dataset
        The dataset, fully loaded in memory (the file is closed).
    """
    import xarray as xr

    with xr.open_dataset(path, engine="h5netcdf") as ds:
        return ds.load()


def failed_cases(ds) -> list[dict]:
    """The failed cases of a sweep: ``[{"params": {path: value}, "error": text}, ...]``.

    Parameters
    ----------
    ds : xarray.Dataset
        A sweep dataset (with its ``error`` variable).

    Returns
    -------
    list of dict
        One entry per failed case: the swept parameter values (SI) and the error text.
    """
    err = ds["error"]
    out = []
    flat = err.stack(_c=err.dims) if err.ndim > 1 else err
    for item in flat:
        text = str(item.values)
        if text:
            params = {}
            for c in ds.coords:
                if c in ("case", "_c") or c not in item.coords:
                    continue
                v = item.coords[c].values
                if np.ndim(v) == 0 and c != "case":
                    params[c] = float(v)
            out.append({"params": params, "error": text})
    return out


def iter_param_names(ds) -> Iterable[str]:
    """Swept parameter names of a sweep dataset."""
    return list(json.loads(ds.attrs["params"]))
