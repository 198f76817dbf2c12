"""Exceptions with precise messages; the CLI turns :class:`DownholeInputError` into exit code 2."""

from __future__ import annotations

__all__ = ["DownholeError", "DownholeInputError", "ScenarioError", "SimulationDiverged",
           "WorkerProcessError", "positive_number"]


class DownholeError(Exception):
    """Base class of downhole's own errors."""


class DownholeInputError(DownholeError, ValueError):
    """Bad user input (file, field, value); reported as one line, exit code 2."""


class ScenarioError(DownholeInputError):
    """A scenario file or value is invalid.

    Parameters
    ----------
    source : str
        The file (or "<dict>") the scenario came from.
    field : str
        Dotted path of the offending field, e.g. ``model.bit.n_blades``.
    message : str
        What was wrong and what was expected.
    """

    def __init__(self, source: str, field: str, message: str):
        self.source, self.field, self.message = source, field, message
        where = f"{source}: {field}: " if field else f"{source}: "
        super().__init__(where + message)


class SimulationDiverged(DownholeError, FloatingPointError):
    """A run produced a non-finite value; names the simulated time and the channel."""

    def __init__(self, time: float, channel: str):
        self.time, self.channel = time, channel
        super().__init__(f"simulation went non-finite at t = {time:.6g} s in channel '{channel}'")


class WorkerProcessError(DownholeError, RuntimeError):
    """A pool of worker processes broke (a worker died: killed by the system, out of memory, or
    a script that starts workers without the ``if __name__ == "__main__":`` guard); raised
    instead of reporting every remaining task as failed (see :mod:`downhole._workers`)."""


def positive_number(name: str, value, allow_zero: bool = False) -> float:
    """``value`` as a finite float > 0 (>= 0 with ``allow_zero``); DownholeInputError naming
    ``name`` otherwise."""
    import math

    try:
        x = float(value)
    except (TypeError, ValueError):
        raise DownholeInputError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(x) or x < 0 or (x == 0 and not allow_zero):
        raise DownholeInputError(f"{name} must be {'>= 0' if allow_zero else '> 0'} and "
                                 f"finite, got {value!r}")
    return x
