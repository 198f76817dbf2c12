"""Bounded recording for long real-time runs: a preallocated ring buffer, optional chunk files.

:class:`RingRecorder` keeps the last ``capacity`` rows of a fixed set of channels in one
preallocated array (memory is constant however long the run), and, when ``chunk_dir`` is set,
writes every full block of ``chunk_rows`` rows to ``chunk_dir/chunk_000001.npz`` (the whole run
on disk, never in memory). :meth:`RingRecorder.to_result` returns the rows in memory as a
:class:`~downhole.sim.result.Result`; :func:`load_chunks` reassembles a chunked run.

Chunk files are written atomically (temporary name, fsync, rename), so every ``chunk_*.npz``
loads even after ``kill -9``. A chunk that cannot be written (a full disk) raises its
:class:`OSError` once: the chunks written before it stay readable, the folder keeps its
``INCOMPLETE`` marker with the reason (when the disk still takes that much), and the recorder writes
no further chunk (the ring goes on). A recorder owns its chunk folder: when it starts it writes an
``INCOMPLETE`` marker there and removes the previous run's chunks (they would otherwise be
reassembled with the new ones); :meth:`RingRecorder.finish` flushes and removes the marker.
:func:`load_chunks` of a folder still marked (a killed run) loads the rows on disk and sets the
``incomplete`` attribute of the Result.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from downhole._atomic import MARKER, OutputFolder, atomic_path, sync_files, write_json_atomic
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
        Directory for chunk files (created; the previous run's chunks in it are removed);
        None keeps only the ring.
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
        self.disk_error: OSError | None = None  # why chunk writing stopped (a full disk)
        self._folder = None
        if self.chunk_dir is not None:
            self._folder = OutputFolder(self.chunk_dir, ("chunk_*.npz", "channels.json"),
                                        "sil recording").writing()
            self._chunk = np.empty((self.chunk_rows, len(self.channels)))
            self._chunk_n = 0
            write_json_atomic(self.chunk_dir / "channels.json", list(self.channels), indent=None)

    def append(self, row: np.ndarray) -> None:
        """Add one row (values in channel order); copies it.

        A full chunk is written to disk (:meth:`flush`) when the recorder has a chunk folder.

        Parameters
        ----------
        row : ndarray, shape (len(channels),)
            One sample of every channel, SI.
        """
        self.buf[self.count % self.capacity] = row
        self.count += 1
        if self.chunk_dir is not None:
            self._chunk[self._chunk_n] = row
            self._chunk_n += 1
            if self._chunk_n == self.chunk_rows:
                self.flush()

    def flush(self) -> None:
        """Write the partial chunk (if any) to disk (atomically; without an fsync, which could
        cost a real-time loop its deadlines: :meth:`finish` makes the folder durable)."""
        if self.chunk_dir is None or self._chunk_n == 0 or self.disk_error is not None:
            return
        path = self.chunk_dir / f"chunk_{self.chunks_written + 1:06d}.npz"
        try:
            with atomic_path(path, durable=False) as tmp:
                np.savez(tmp, data=self._chunk[:self._chunk_n])
        except OSError as exc:  # a full disk: stop chunking, keep what is on disk readable
            if exc.filename is None or ".part-" in str(exc.filename):
                exc = OSError(exc.errno, exc.strerror or str(exc), str(path))
            self.disk_error = exc
            self._chunk_n = 0
            self._folder.fail(f"OSError: {exc}; chunks 1 to {self.chunks_written} are complete")
            raise exc from None
        self.chunks_written += 1
        self._chunk_n = 0

    def finish(self) -> None:
        """The recording is over: flush, sync the chunks to disk, mark the folder complete."""
        self.flush()
        if self._folder is not None and self.disk_error is None:
            sync_files(sorted(self.chunk_dir.glob("chunk_*.npz")))
            self._folder.commit()

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
        """The rows in memory as a Result (``time`` channel as the time axis).

        Parameters
        ----------
        units : dict, optional
            Units of channels not declared in :mod:`downhole.signals` (name -> pint unit string).
        attrs : dict, optional
            Metadata of the Result.

        Returns
        -------
        Result

        Raises
        ------
        ValueError
            If there is no ``time`` channel.
        """
        return _to_result(self.channels, self.rows(), units, attrs)


def _to_result(channels, data, units, attrs):
    ti = channels.index("time")
    ch = {n: data[:, i] for i, n in enumerate(channels) if n != "time"}
    return Result(data[:, ti], ch, units=units, attrs=attrs)


def load_chunks(chunk_dir, units: dict | None = None, attrs: dict | None = None) -> Result:
    """Reassemble the chunk files of a run into one Result.

    Parameters
    ----------
    chunk_dir : str or os.PathLike
        Folder with ``channels.json`` and ``chunk_*.npz``.
    units : dict, optional
        Units of channels not declared in :mod:`downhole.signals` (name -> pint unit string).
    attrs : dict, optional
        Metadata of the Result; ``incomplete = 1`` is added when the folder is still
        marked as being written.

    Returns
    -------
    Result

    Raises
    ------
    DownholeInputError
        If the folder has no ``channels.json`` or no chunk files.
    """
    import json

    chunk_dir = Path(chunk_dir)
    try:
        names = json.loads((chunk_dir / "channels.json").read_text())
    except OSError:
        raise DownholeInputError(f"{chunk_dir}: no channels.json (not a chunk folder)") from None
    parts = []
    for p in sorted(chunk_dir.glob("chunk_*.npz")):
        with np.load(p, allow_pickle=False) as z:
            parts.append(z["data"])
    if not parts:
        raise DownholeInputError(f"no chunk files in {chunk_dir}")
    attrs = dict(attrs or {})
    if (chunk_dir / MARKER).exists():
        attrs["incomplete"] = 1
    return _to_result(tuple(names), np.concatenate(parts), units, attrs)
