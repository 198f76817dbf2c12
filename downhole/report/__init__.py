"""Reports: the one-command reproduction of the dissertation (parallel runner and
``index.html``) and the benchmark report (``docs/performance.md``)."""

from downhole.report.bench import bench_markdown
from downhole.report.html import CHAPTERS, build_index
from downhole.report.reproduce import machine_description, reproduce, run_one

__all__ = [
    "CHAPTERS",
    "bench_markdown",
    "build_index",
    "machine_description",
    "reproduce",
    "run_one",
]
