"""Benchmarks of the SIL runtime: unpaced real-time factor of the 68-state hybrid with the
24-state DHP in-process and over the UDP link (controller in its own process, lock-step).

Baseline: the DHP package's own closed loop (:func:`downhole.control.dhp.run_on_plant`, the
same plant and controller stepped in a plain Python loop) over the same simulated time; the
real-time factor (simulated s per wall s) is in ``extra``. The seed's LabVIEW testbed ran at
real time (factor 1) by construction; it published no unpaced figure.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from downhole.bench import BenchOutcome, bench_case, timed


def _setup(T):
    from downhole.sil import build_plant
    from downhole.sil.testing import ch6_dhp

    design, ctrl = ch6_dhp("step", horizon=T, samples=50)
    return design, ctrl, build_plant("hybrid68", interface="state", design_model=design)


def _baseline(design, ctrl, T):
    from downhole.control.dhp import run_on_plant
    from downhole.control.dhp.directional import DirectionalStatePlant
    from downhole.string.hybrid import hybrid_model

    plant = DirectionalStatePlant(hybrid_model("hybrid68"), design, 1e-3)
    return timed(run_on_plant, ctrl, plant, T, record_every=10)[0]


@bench_case("sil hybrid68 + DHP in-process, unpaced", group="ch6", quick=True)
def _in_process(quick):
    from downhole.sil import RealTimeRunner

    T = 2.0 if quick else 10.0
    design, ctrl, plant = _setup(T)
    rt = RealTimeRunner(plant, ctrl, paced=False, record_every=10)
    rt.run(0.05)  # warm up
    seconds, _ = timed(rt.run, T)
    base = _baseline(design, ctrl, T)
    return BenchOutcome(seconds, "run_on_plant (plain loop, same plant and controller)", base,
                        extra={"real_time_factor": T / seconds, "simulated_s": T,
                               "mean_step_us": 1e6 * seconds / (T / 1e-3)})


@bench_case("sil hybrid68 + DHP over UDP (separate process), unpaced", group="ch6", quick=True)
def _over_udp(quick):
    from downhole.sil import RealTimeRunner
    from downhole.sil.testing import ControllerProcess, free_port

    T = 2.0 if quick else 10.0
    design, ctrl, plant = _setup(T)
    with tempfile.TemporaryDirectory() as tmp:
        ctrl.save(Path(tmp) / "dhp")
        port = free_port()
        rt = RealTimeRunner(plant, link=("127.0.0.1", port), paced=False, record_every=10,
                            command_timeout=1.0)
        with ControllerProcess(port, ["--controller", Path(tmp) / "dhp.json"]) as cp:
            if not rt.wait_for_controller(120.0):
                raise RuntimeError("controller process did not connect")
            t0 = time.perf_counter()
            rt.run(T)
            seconds = time.perf_counter() - t0
            rt.close()
            cp.wait(20)
    base = _baseline(design, ctrl, T)
    return BenchOutcome(seconds, "run_on_plant (plain loop, in-process)", base,
                        extra={"real_time_factor": T / seconds, "simulated_s": T,
                               "mean_round_trip_us": 1e6 * seconds / (T / 1e-3),
                               "late_commands": rt.stats["late_commands"]})
