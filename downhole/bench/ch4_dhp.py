"""Benchmarks of the DHP trainer: the Table 4.2 rows (40 s horizon, dt = 1e-3).

Each case times the compiled Riccati form (``method="riccati"``, fresh random samples at every
step as in the seed's Algorithm 1) against a plain-NumPy version of the same trainer (same
random stream, same samples, same gains; :func:`downhole.control.dhp.trainer.riccati_numpy`)
in the same run, and against the seed's published seconds (MATLAB, i7-9750H). The extra fields
give the time with the sample sets re-used for 40 steps (``resample_every=40``) and, for the
quick case, the plain-NumPy Algorithm 1.
"""

from __future__ import annotations

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


def _case(n_states, n_samples, horizon, with_alg1=False):
    from downhole.control.dhp import BitReference, DHPSettings, PenaltyWeights, build_problem
    from downhole.control.dhp.trainer import riccati_numpy, train_dhp

    model = _design(n_states)
    pb = build_problem(model, BitReference.step(), horizon, PenaltyWeights())
    warm = build_problem(model, BitReference.step(), 0.01, PenaltyWeights())
    st = DHPSettings(n_samples=n_samples, method="riccati")
    train_dhp(warm, st)  # numba compilation outside the timing
    seconds, tr = timed(train_dhp, pb, st)
    base, (kc, kd, _) = timed(riccati_numpy, pb, st)
    agree = float(np.max(np.abs(kd - tr.kd)) / max(np.max(np.abs(tr.kd)), 1e-300))
    reuse, _ = timed(train_dhp, pb, DHPSettings(n_samples=n_samples, resample_every=40))
    extra = {"horizon_s": horizon, "states": n_states, "samples": n_samples,
             "max_relative_gain_difference_vs_numpy": agree,
             "seconds_resample_every_40": reuse}
    if with_alg1:
        a1, _ = timed(train_dhp, pb, DHPSettings(n_samples=n_samples,
                                                 method="algorithm1_numpy"))
        extra["seconds_algorithm1_numpy"] = a1
        a1s = DHPSettings(n_samples=n_samples, method="algorithm1")
        train_dhp(warm, a1s)
        c1, _ = timed(train_dhp, pb, a1s)
        extra["seconds_algorithm1_compiled"] = c1
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
