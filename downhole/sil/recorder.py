"""Bounded recording for long real-time runs: a preallocated ring buffer, optional chunk files.

:class:`RingRecorder` keeps the last ``capacity`` rows of a fixed set of channels in one
preallocated array (memory is constant however long the run), and, when ``chunk_dir`` is set,
writes every full block of ``chunk_rows`` rows to ``chunk_dir/chunk_000001.npz`` (the whole run
on disk, never in memory). :meth:`RingRecorder.to_result` returns the rows in memory as a
:class:`~downhole.sim.result.Result`; :func:`load_chunks` reassembles a chunked run.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from downhole.errors import DownholeInputError
from downhole.sim.result import Result

__all__ = ["RingRecorder", "load_chunks"]


class RingRecorder:
    """Fixed-memory recorder of named channels.

    Parameters
    ----------
    channels : sequence of str
        Channel names (the first is usually ``time``).
    capacity : int
        Rows kept in memory (older rows are overwritten).
    chunk_dir : path, optional
        Directory for chunk files (created); None keeps only the ring.
    chunk_rows : int
        Rows per chunk file.
    """

    def __init__(self, channels, capacity: int, chunk_dir=None, chunk_rows: int = 10000):
        if capacity < 1:
            raise DownholeInputError(f"recorder capacity must be >= 1 row, got {capacity}")
        self.channels = tuple(channels)
        self.capacity = int(capacity)
        self.buf = np.full((self.capacity, len(self.channels)), np.nan)
        self.count = 0  # rows ever written
        self.chunk_dir = None if chunk_dir is None else Path(chunk_dir)
        self.chunk_rows = int(chunk_rows)
        self.chunks_written = 0
        if self.chunk_dir is not None:
            self.chunk_dir.mkdir(parents=True, exist_ok=True)
            self._chunk = np.empty((self.chunk_rows, len(self.channels)))
            self._chunk_n = 0
            (self.chunk_dir / "channels.json").write_text(json.dumps(list(self.channels)))

    def append(self, row: np.ndarray) -> None:
        """Add one row (values in channel order); copies it."""
        self.buf[self.count % self.capacity] = row
        self.count += 1
        if self.chunk_dir is not None:
            self._chunk[self._chunk_n] = row
            self._chunk_n += 1
            if self._chunk_n == self.chunk_rows:
                self.flush()

    def flush(self) -> None:
        """Write the partial chunk (if any) to disk."""
        if self.chunk_dir is None or self._chunk_n == 0:
            return
        self.chunks_written += 1
        path = self.chunk_dir / f"chunk_{self.chunks_written:06d}.npz"
        np.savez(path, data=self._chunk[:self._chunk_n])
        self._chunk_n = 0

    def rows(self) -> np.ndarray:
        """The rows in memory, oldest first (a copy)."""
        n = min(self.count, self.capacity)
        if self.count <= self.capacity:
            return self.buf[:n].copy()
        i = self.count % self.capacity
        return np.concatenate([self.buf[i:], self.buf[:i]])

    def latest(self) -> dict:
        """The newest row as a dict (empty before the first append)."""
        if self.count == 0:
            return {}
        return dict(zip(self.channels, self.buf[(self.count - 1) % self.capacity].tolist()))

    def to_result(self, units: dict | None = None, attrs: dict | None = None) -> Result:
        """The rows in memory as a Result (``time`` channel as the time axis)."""
        return _to_result(self.channels, self.rows(), units, attrs)


def _to_result(channels, data, units, attrs):
    ti = channels.index("time")
    ch = {n: data[:, i] for i, n in enumerate(channels) if n != "time"}
    return Result(data[:, ti], ch, units=units, attrs=attrs)


def load_chunks(chunk_dir, units: dict | None = None, attrs: dict | None = None) -> Result:
    """Reassemble the chunk files of a run into one Result."""
    chunk_dir = Path(chunk_dir)
    names = json.loads((chunk_dir / "channels.json").read_text())
    parts = [np.load(p)["data"] for p in sorted(chunk_dir.glob("chunk_*.npz"))]
    if not parts:
        raise DownholeInputError(f"no chunk files in {chunk_dir}")
    return _to_result(tuple(names), np.concatenate(parts), units, attrs)
