"""A rich progress bar for long DP searches that can be switched off (tests, batch runs)."""

from __future__ import annotations

from contextlib import contextmanager


@contextmanager
def progress_bar(total: int, description: str, enabled: bool = True):
    """Yield ``advance(n=1)``; shows a transient rich bar when ``enabled`` and on a terminal."""
    if not enabled:
        yield lambda n=1: None
        return
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    console = Console(stderr=True)
    with Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                  TimeElapsedColumn(), console=console, transient=True,
                  disable=not console.is_terminal) as prog:
        task = prog.add_task(description, total=total)
        yield lambda n=1: prog.advance(task, n)


def chunks(n_steps: int, parts: int = 50):
    """Split backward steps N..0 into about ``parts`` (k_hi, k_lo) chunks."""
    size = max(1, n_steps // parts)
    k = n_steps
    while k > 0:
        lo = max(0, k - size)
        yield k, lo
        k = lo
