"""Wall-time helpers shared by benchmarks and the experiments that report speed."""

from __future__ import annotations

import time

__all__ = ["best_time", "timed"]


def timed(fn, *args, repeat: int = 1, **kwargs) -> tuple[float, object]:
    """Best wall time of ``repeat`` calls of ``fn`` (seconds) and the last return value."""
    best, out = float("inf"), None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn(*args, **kwargs)
        best = min(best, time.perf_counter() - t0)
    return best, out


def best_time(fn, *args, repeat=5, budget=1.0, **kwargs):
    """Best wall time and best thread CPU time of at least ``repeat`` calls, more for short
    calls (up to ``budget`` seconds in all, at most 50 calls), after the caller warmed the
    compiled code up: the machine is shared, so the minimum is the least disturbed run."""
    wall, cpu = float("inf"), float("inf")
    done, spent = 0, 0.0
    while done < repeat or (spent < budget and done < 50):
        done += 1
        t0, c0 = time.perf_counter(), time.thread_time()
        fn(*args, **kwargs)
        w = time.perf_counter() - t0
        spent += w
        wall = min(wall, w)
        cpu = min(cpu, time.thread_time() - c0)
    return wall, cpu
