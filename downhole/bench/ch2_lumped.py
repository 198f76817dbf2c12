"""Benchmark: the 4th-order model with the delayed depth of cut, compiled vs plain NumPy."""

from __future__ import annotations

from downhole.bench import BenchOutcome, bench_case, timed
from downhole.sim import SurfaceInputs, simulate
from downhole.sim.lumped_model import lumped_model
from downhole.sim.reference_numpy import simulate_lumped4_numpy


@bench_case("lumped4 delayed-doc 60 s dt=5e-4", group="ch2", quick=True)
def lumped4_delayed(quick):
    model = lumped_model("table_2_1")
    inputs = SurfaceInputs.velocity(0.01, 10.0)
    simulate(model, inputs, duration=1.0, dt=5e-4)  # compile outside the timing
    seconds, _ = timed(simulate, model, inputs, duration=60.0, dt=5e-4, repeat=3)
    base_duration = 6.0 if quick else 60.0  # the baseline is linear in duration
    base, _ = timed(simulate_lumped4_numpy, model, 0.01, 10.0, base_duration, 5e-4)
    return BenchOutcome(seconds, "plain NumPy stepping of the same model",
                        base * 60.0 / base_duration,
                        extra={"real_time_factor": 60.0 / seconds,
                               "baseline_measured_duration_s": base_duration})
