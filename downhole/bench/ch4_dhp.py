"""Benchmarks of the DHP trainer: the Table 4.2 rows (40 s horizon, dt = 1e-3).

Each case times the compiled Riccati form (``method="riccati"``: exact, the fixed point of the
seed's Algorithm 1, with N_S *fresh* random samples at every step) on the two cores of the
machine (``threads=2``: the per-step sample/force/fit work split over two threads, the
sequential backward pass overlapped with it; BLAS pinned to one thread per worker) against

- the seed's published seconds (MATLAB, i7-9750H),
- a plain-NumPy version of the same trainer in the same run
  (:func:`downhole.control.dhp.baseline.riccati_numpy`: same SFC64 sample streams, same samples,
  same gains to ~1e-12; BLAS pinned to one thread, which is its fastest setting here).

Extra fields: the single-thread time (``seconds_1_thread``), the CPU seconds, the largest
relative gain difference against the NumPy version, and the time with the sample offsets
re-used for 40 steps (``resample_every=40``, not the seed's setting). The quick case (2 s
horizon) also times the seed's Algorithm 1 (the NumPy reference) on the same samples.
"""

from __future__ import annotations

import time

import numpy as np

from downhole.bench import BenchOutcome, bench_case, timed

_MODELS: dict = {}


def _design(n_states: int):
    if n_states not in _MODELS:
        from downhole.control.dhp.directional import directional_affine_model, table_5_1_models
        from downhole.string.fem import fem_model

        dm = table_5_1_models()[0] if n_states == 24 else fem_model(n_elements=n_states // 4 - 1)
        _MODELS[n_states] = directional_affine_model(dm)
    return _MODELS[n_states]


def _numpy_baseline(pb, st):
    from threadpoolctl import threadpool_limits

    from downhole.control.dhp.baseline import riccati_numpy

    with threadpool_limits(limits=1, user_api="blas"):
        return riccati_numpy(pb, st)


def _case(n_states, n_samples, horizon, with_alg1=False, threads=2):
    from downhole.control.dhp import BitReference, DHPSettings, PenaltyWeights, build_problem
    from downhole.control.dhp.trainer import train_dhp

    model = _design(n_states)
    pb = build_problem(model, BitReference.step(), horizon, PenaltyWeights())
    warm = build_problem(model, BitReference.step(), 0.05, PenaltyWeights())
    st = DHPSettings(n_samples=n_samples, method="riccati", threads=threads)
    st1 = DHPSettings(n_samples=n_samples, method="riccati", threads=1)
    train_dhp(warm, st)  # numba compilation outside the timing
    train_dhp(warm, st1)
    cpu0 = time.process_time()
    seconds, tr = timed(train_dhp, pb, st)
    cpu = time.process_time() - cpu0
    one, tr1 = timed(train_dhp, pb, st1)
    base, (kc, kd, _) = timed(_numpy_baseline, pb, st)
    scale = max(float(np.max(np.abs(tr.kd))), 1e-300)
    agree = float(np.max(np.abs(kd - tr.kd)) / scale)
    reuse, _ = timed(train_dhp, pb, DHPSettings(n_samples=n_samples, resample_every=40,
                                                 threads=threads))
    extra = {"horizon_s": horizon, "states": n_states, "samples": n_samples, "threads": threads,
             "seconds_1_thread": one, "cpu_seconds": cpu,
             "threads_agree": bool(np.array_equal(tr.kd, tr1.kd)),
             "max_relative_gain_difference_vs_numpy": agree,
             "seconds_resample_every_40": reuse}
    if with_alg1:
        a1, a1r = timed(train_dhp, pb, DHPSettings(n_samples=n_samples, method="algorithm1"))
        extra["seconds_algorithm1"] = a1
        extra["max_relative_gain_difference_algorithm1_vs_riccati"] = float(
            np.max(np.abs(a1r.kd - tr.kd)) / scale)
    return BenchOutcome(seconds, "plain-NumPy Riccati form of the same trainer", base, extra)


@bench_case("DHP train 24 states 100 samples 2 s (dt=1e-3)", seed_seconds=148.69 / 20,
            quick=True, group="ch4")
def _quick(quick):
    """Quick case: a 2 s horizon (the seed's 40 s time scaled by 1/20 for reference)."""
    return _case(24, 100, 2.0, with_alg1=True)


@bench_case("DHP train 24 states 100 samples 40 s (Table 4.2)", seed_seconds=148.69,
            quick=False, group="ch4")
def _t24_100(quick):
    return _case(24, 100, 40.0)


@bench_case("DHP train 24 states 200 samples 40 s (Table 4.2)", seed_seconds=157.30,
            quick=False, group="ch4")
def _t24_200(quick):
    return _case(24, 200, 40.0)


@bench_case("DHP train 80 states 200 samples 40 s (Table 4.2)", seed_seconds=233.68,
            quick=False, group="ch4")
def _t80_200(quick):
    return _case(80, 200, 40.0)
