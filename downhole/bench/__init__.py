"""Benchmark registry: speed measured as ratios against a baseline run in the same process.

Each module of this package registers cases with :func:`bench_case`. A case function receives
``quick: bool`` and returns a :class:`BenchOutcome`; :func:`run_bench` turns outcomes into
``{"cases": [{"name", "seconds", "baseline", "baseline_seconds", "ratio", "seed_seconds"}]}``
where ``ratio = baseline_seconds / seconds`` (how many times faster than the baseline).
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Callable
from dataclasses import dataclass, field

from downhole._timing import timed

__all__ = ["BenchOutcome", "all_cases", "bench_case", "run_bench", "timed"]


@dataclass
class BenchOutcome:
    """Timing of one case: downhole's seconds and the in-run baseline's."""

    seconds: float
    baseline: str
    baseline_seconds: float | None
    extra: dict = field(default_factory=dict)


@dataclass(frozen=True)
class _Case:
    name: str
    func: Callable
    seed_seconds: float | None
    quick: bool
    group: str


_CASES: dict[str, _Case] = {}
_LOADED = False


def bench_case(name: str, *, seed_seconds: float | None = None, quick: bool = True,
               group: str = ""):
    """Decorator registering a benchmark case.

    ``seed_seconds`` is the dissertation's published time for the same work (None if none);
    ``quick`` cases run under ``downhole bench --quick``.
    """

    def deco(func):
        if name in _CASES:
            raise ValueError(f"bench case {name!r} registered twice")
        _CASES[name] = _Case(name, func, seed_seconds, quick, group)
        return func

    return deco


def _load_all():
    global _LOADED
    if not _LOADED:
        for mod in pkgutil.iter_modules(__path__):
            if not mod.name.startswith("_"):
                importlib.import_module(f"{__name__}.{mod.name}")
        _LOADED = True


def all_cases() -> list[_Case]:
    _load_all()
    return list(_CASES.values())


def run_bench(quick: bool = False, names: list[str] | None = None, progress=None) -> dict:
    """Run the cases (all, quick ones, or ``names``) and return the report dict."""
    cases = [c for c in all_cases() if (names is None or c.name in names)
             and (not quick or c.quick)]
    if names:
        unknown = set(names) - {c.name for c in all_cases()}
        if unknown:
            raise KeyError(f"unknown bench cases {sorted(unknown)}")
    rows = []
    for case in cases:
        if progress:
            progress(case.name)
        out: BenchOutcome = case.func(quick)
        ratio = (out.baseline_seconds / out.seconds) if out.baseline_seconds else None
        rows.append({"name": case.name, "group": case.group, "seconds": out.seconds,
                     "baseline": out.baseline, "baseline_seconds": out.baseline_seconds,
                     "ratio": ratio, "seed_seconds": case.seed_seconds,
                     "ratio_to_seed": (case.seed_seconds / out.seconds) if case.seed_seconds
                     else None, **({"extra": out.extra} if out.extra else {})})
    import os
    import platform

    return {"machine": {"platform": platform.platform(), "processor": platform.processor(),
                        "cpus": os.cpu_count(), "python": platform.python_version()},
            "cases": rows}
