"""Atomic output files and folders, and output paths checked before any work starts.

Every file a ``downhole`` command writes goes through :func:`atomic_path` (or the
``write_*_atomic`` helpers built on it): the writer fills a temporary file in the same folder
(``.NAME.part-PID-RANDOM.SUFFIX``, hidden, same suffix so that format-sniffing writers such as
matplotlib and :func:`numpy.savez` behave), the file is flushed to disk (``fsync``) and then
renamed onto its final name with :func:`os.replace`. A final name therefore always holds a
complete file; a failed write leaves only the (removed, or after ``kill -9`` stale) temporary.

Temporaries are created by :func:`new_temp` with an exclusive, non-following open
(``O_CREAT | O_EXCL | O_NOFOLLOW``) under a name with 64 random bits: a symbolic link planted in a
shared output folder cannot redirect a write (the name cannot be guessed, and an existing entry of
that name is never opened), and :func:`replace_atomic` renames only a regular file owned by this
process's user. A symbolic link given as ``--out`` itself is refused by
:func:`check_output_path`.

A command that writes a *set* of files that belong together (``result.nc`` + ``summary.json`` +
``overview.png``; ``solution.npz`` + ``solution.json``; ...) uses :class:`OutputFolder`: before
the work starts it writes an ``INCOMPLETE`` marker into an existing output folder and removes the
previous run's files of that set (and stale temporaries); a folder that does not exist is
created, with the marker, only when the first file is written. Each file is written atomically
and the marker is removed only when the whole set is written. A killed or failed run thus leaves
the marker, some complete files of the new run at most, and never the previous run's files
looking fresh or mixed with the new ones. :class:`OutputFile` does the same for a single
``--out FILE`` with a ``FILE.INCOMPLETE`` marker beside it.

:func:`check_output_path` finds ``--out`` problems (an existing file where a folder is expected
or a folder where a file is, a path under a file, a missing parent folder of an output file, a
folder that is not writable) before a command does any work, as a
:class:`~downhole.errors.DownholeInputError` (one line, exit code 2).

Test hook: with ``DOWNHOLE_TEST_PAUSE_BEFORE_RENAME=SECONDS`` (or ``NAME:SECONDS``, only for the
final file name ``NAME``) the writer prints ``downhole-test: paused before rename <final>`` on
standard error and sleeps between the fsync of the temporary and its rename, so that tests can
kill a command deterministically mid-write. It costs one environment lookup per file otherwise.

This module is part of the core: it imports nothing of downhole but :mod:`downhole.errors`.
"""

from __future__ import annotations

import contextlib
import fcntl
import fnmatch
import json
import os
import secrets
import stat
import sys
import time
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Self

from downhole.errors import DownholeInputError

__all__ = [
    "LOCK_NAME",
    "MARKER",
    "PAUSE_ENV",
    "OutputFile",
    "OutputFolder",
    "atomic_path",
    "check_output_path",
    "is_incomplete",
    "new_temp",
    "replace_atomic",
    "sync_files",
    "temp_path",
    "write_bytes_atomic",
    "write_json_atomic",
    "write_netcdf_atomic",
    "write_text_atomic",
]

#: Name of the marker file of an output folder whose run has not finished.
MARKER = "INCOMPLETE"
#: Environment variable of the test-only pause between the temporary write and the rename.
PAUSE_ENV = "DOWNHOLE_TEST_PAUSE_BEFORE_RENAME"
#: Name of the lock file of an output folder (a file's lock is ``.NAME.lock`` beside it).
LOCK_NAME = ".downhole.lock"
_TEMP_GLOB = ".*.part-*"
_NOFOLLOW = getattr(os, "O_NOFOLLOW", 0)


def temp_path(final: str | os.PathLike) -> Path:
    """A fresh temporary name, in the same folder, under which ``final`` can be written.

    ``out/result.nc`` becomes ``out/.result.part-PID-RANDOM.nc``: hidden, with 64 random bits
    (unguessable, so that nobody can plant a link under it in advance) and the final suffix
    (writers that pick the format from the suffix keep working). Each call gives a new name; use
    :func:`new_temp` to also create the file safely.
    """
    final = Path(final)
    suffix = final.suffix if final.suffix != final.name else ""
    stem = final.name[: len(final.name) - len(suffix)] if suffix else final.name
    return final.with_name(f".{stem}.part-{os.getpid()}-{secrets.token_hex(8)}{suffix}")


def new_temp(final: str | os.PathLike) -> Path:
    """Create the temporary file of ``final`` exclusively, without following links.

    The file is created empty with ``O_CREAT | O_EXCL | O_NOFOLLOW`` (permissions from the
    umask) under a fresh :func:`temp_path` name; writers then fill it by path.

    Raises
    ------
    OSError
        The folder does not exist or is not writable (or, with odds of 2**-64, the name exists).
    """
    tmp = temp_path(final)
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | _NOFOLLOW, 0o666)
    os.close(fd)
    return tmp


def _check_own_regular(tmp: Path, final: Path, allow_empty: bool = False) -> None:
    """Refuse to rename anything but a regular file of this user (never a planted link), and an
    empty one unless ``allow_empty`` (a writer that wrote elsewhere, e.g. under another suffix,
    leaves the exclusive temporary empty)."""
    try:
        st = os.lstat(tmp)
    except FileNotFoundError:
        raise RuntimeError(f"the writer of {final} produced no file {tmp.name}") from None
    if not stat.S_ISREG(st.st_mode):
        raise RuntimeError(f"the temporary {tmp} of {final} is not a regular file (a link or "
                           "another kind of file was put in its place): not renamed")
    if hasattr(os, "geteuid") and st.st_uid != os.geteuid():
        raise RuntimeError(f"the temporary {tmp} of {final} belongs to another user: not renamed")
    if st.st_size == 0 and not allow_empty:
        raise RuntimeError(f"the writer of {final} produced no file {tmp.name} (it is empty)")


def _fsync_path(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _fsync_dir(folder: Path) -> None:
    """Make a rename in ``folder`` durable (best effort: not every file system allows it)."""
    try:
        fd = os.open(folder, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def sync_files(paths: Iterable[str | os.PathLike]) -> None:
    """Fsync files written with ``durable=False`` (and their folders), e.g. at the end of a run."""
    folders = set()
    for p in map(Path, paths):
        with contextlib.suppress(FileNotFoundError):
            _fsync_path(p)
            folders.add(p.parent)
    for folder in folders:
        _fsync_dir(folder)


def _test_pause(final: Path) -> None:
    spec = os.environ.get(PAUSE_ENV)
    if not spec:
        return
    name, _, seconds = spec.rpartition(":")
    if name and name != final.name:
        return
    try:
        delay = float(seconds)
    except ValueError:
        return
    # the process's own stderr, also where a caller redirected sys.stderr (reproduce's run.log)
    print(f"downhole-test: paused before rename {final}", file=sys.__stderr__ or sys.stderr,
          flush=True)
    time.sleep(delay)


def replace_atomic(tmp: str | os.PathLike, final: str | os.PathLike, *,
                   durable: bool = True, allow_empty: bool = False) -> Path:
    """Fsync the written temporary ``tmp`` and rename it onto ``final`` (same folder).

    For writers that must order several renames themselves (a pair of files); the usual way is
    :func:`atomic_path`. ``durable=False`` skips the fsyncs: the rename still happens only after
    the whole file was written, so a killed process never exposes a partial file; only a power
    loss could (used inside real-time loops, where an fsync would cost deadlines).
    """
    tmp, final = Path(tmp), Path(final)
    _check_own_regular(tmp, final, allow_empty)
    if durable:
        _fsync_path(tmp)
    _test_pause(final)
    os.replace(tmp, final)
    if durable:
        _fsync_dir(final.parent)
    return final


@contextlib.contextmanager
def atomic_path(final: str | os.PathLike, *, durable: bool = True,
                allow_empty: bool = False) -> Iterator[Path]:
    """Context manager: yields a temporary path to write ``final``'s content to.

    On a normal exit the temporary is fsynced and renamed onto ``final``; on an exception it is
    removed and ``final`` is left as it was. ``durable=False``: no fsync (see
    :func:`replace_atomic`).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> d = pathlib.Path(tempfile.mkdtemp())
    >>> with atomic_path(d / "a.txt") as tmp:
    ...     _ = tmp.write_text("hello")
    >>> (d / "a.txt").read_text()
    'hello'
    """
    final = Path(final)
    tmp = new_temp(final)
    try:
        yield tmp
        replace_atomic(tmp, final, durable=durable, allow_empty=allow_empty)
    finally:
        with contextlib.suppress(FileNotFoundError):
            if tmp.is_file() or tmp.is_symlink():
                tmp.unlink()


def write_bytes_atomic(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (temporary file, fsync, rename)."""
    path = Path(path)
    try:
        with atomic_path(path, allow_empty=True) as tmp:
            fd = os.open(tmp, os.O_WRONLY | os.O_TRUNC | _NOFOLLOW)
            with os.fdopen(fd, "wb") as f:
                f.write(data)
    except OSError as exc:  # name the file the user asked for, not the temporary
        if exc.filename is None or ".part-" in str(exc.filename):
            raise OSError(exc.errno, exc.strerror or str(exc), str(path)) from None
        raise
    return path


def write_text_atomic(path: str | os.PathLike, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    return write_bytes_atomic(path, text.encode("utf-8"))


def write_netcdf_atomic(path: str | os.PathLike, dataset) -> Path:
    """Write an :class:`xarray.Dataset` as NetCDF-4 (h5netcdf) to ``path`` atomically.

    The file is serialized in memory first and written with plain file I/O, so that a full disk
    (``ENOSPC``) or any other write error is one clean :class:`OSError` with the temporary
    removed (HDF5 writing straight to a file on a full disk leaves a broken file object that
    can crash the interpreter at exit).

    Parameters
    ----------
    path : path
        Final file name (``.nc``).
    dataset : xarray.Dataset
        What to write.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    OSError
        The write failed (no space left, quota, read-only file system, ...); ``path`` is left as
        it was.
    """
    data = dataset.to_netcdf(engine="h5netcdf")
    return write_bytes_atomic(path, bytes(data))


def write_json_atomic(path: str | os.PathLike, data, **kwargs) -> Path:
    """Write ``data`` as JSON (``indent=2`` unless given) to ``path`` atomically."""
    kwargs.setdefault("indent", 2)
    return write_text_atomic(path, json.dumps(data, **kwargs))


def is_incomplete(folder: str | os.PathLike) -> bool:
    """True when ``folder`` carries the ``INCOMPLETE`` marker of an unfinished run."""
    return (Path(folder) / MARKER).exists()


def check_output_path(path: str | os.PathLike, *, option: str = "--out",
                      kind: str = "folder", parents: bool | None = None) -> Path:
    """Check an output path before any work starts; returns it as a Path.

    Parameters
    ----------
    path : path
        The output folder (``kind="folder"``, created with its missing parents when the run
        writes) or file (``kind="file"``, whose folder must exist).
    option : str
        The command-line option named in the message (``--out``, ``--csv``, ...).
    kind : {"folder", "file"}
        What the command writes at ``path``.
    parents : bool, optional
        Whether missing parent folders are acceptable (the command creates them). Default: yes
        for a folder, no for a file.

    Raises
    ------
    DownholeInputError
        ``path`` is an existing file where a folder is expected (or a folder where a file is),
        lies under a file, has a missing parent folder (files), or its nearest existing folder
        is not writable.
    """
    if kind not in ("folder", "file"):
        raise ValueError(f"kind must be 'folder' or 'file', got {kind!r}")
    p = Path(path)
    where = f"{option} {path}"
    if not str(path).strip():
        raise DownholeInputError(f"{option}: empty path")
    if "\x00" in str(path):
        raise DownholeInputError(f"{option} {path!r}: NUL character in the path")
    if p.is_symlink():
        target = os.readlink(p)
        raise DownholeInputError(
            f"{where}: is a symbolic link (to {target}); give the {kind} itself (a link in a "
            "shared folder could redirect the run's writes)")
    if p.exists():
        if kind == "folder" and not p.is_dir():
            raise DownholeInputError(f"{where}: is an existing file, expected a folder")
        if kind == "file" and p.is_dir():
            raise DownholeInputError(f"{where}: is an existing folder, expected a file name")
        folder = p if kind == "folder" else (p.parent if str(p.parent) else Path("."))
        if not os.access(folder, os.W_OK | os.X_OK):
            raise DownholeInputError(f"{where}: folder {folder} is not writable")
        return p
    parent = p.parent
    anc = parent
    while not anc.exists() and anc != anc.parent:
        anc = anc.parent
    if anc.exists() and not anc.is_dir():
        raise DownholeInputError(f"{where}: {anc} is a file, not a folder")
    if parents is None:
        parents = kind == "folder"
    if not parents and anc != parent:
        raise DownholeInputError(f"{where}: folder {parent} does not exist")
    if not os.access(anc, os.W_OK | os.X_OK):
        raise DownholeInputError(f"{where}: folder {anc} is not writable")
    return p


class _Lock:
    """An exclusive, non-blocking ``flock`` on one lock file, held until :meth:`release` or the
    end of the process (the kernel drops it whatever kills the process)."""

    def __init__(self, path: Path, what: str):
        self.path = path
        self.what = what
        self.fd: int | None = None

    def acquire(self) -> None:
        if self.fd is not None:
            return
        for _ in range(5):
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT | _NOFOLLOW, 0o666)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                try:
                    holder = os.pread(fd, 64, 0).decode("ascii", "replace").strip() or "?"
                except OSError:
                    holder = "?"
                os.close(fd)
                raise DownholeInputError(
                    f"{self.what}: another downhole run (pid {holder}) is writing it; wait for "
                    "that run to end or choose another output") from None
            except BaseException:
                os.close(fd)
                raise
            # the previous owner unlinks the file as it releases: lock the file that is there
            try:
                same = os.fstat(fd).st_ino == os.lstat(self.path).st_ino
            except FileNotFoundError:
                same = False
            if same:
                with contextlib.suppress(OSError):
                    os.ftruncate(fd, 0)
                    os.pwrite(fd, str(os.getpid()).encode("ascii"), 0)
                self.fd = fd
                return
            os.close(fd)
        raise DownholeInputError(f"{self.what}: could not lock it (its lock file keeps changing)")

    def release(self) -> None:
        if self.fd is not None:
            with contextlib.suppress(OSError):
                os.unlink(self.path)
            os.close(self.fd)  # closing the last descriptor drops the flock
            self.fd = None


def _marker_text(command: str, state: str) -> str:
    stamp = time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime())
    return (f"downhole {command}: {state} (pid {os.getpid()}, {stamp}).\n"
            "The files beside this marker are not a complete result of one run: rerun the "
            "command. The marker is removed when a run finishes writing.\n")


class OutputFolder:
    """The output folder of one command run: marker first, stale files out, marker removed last.

    :meth:`begin` (before the work starts): create the folder if needed, lock it (a second run
    on it raises :class:`~downhole.errors.DownholeInputError`), write the ``INCOMPLETE`` marker,
    then remove the previous run's files (``owned``) and stale temporaries. :meth:`writing`
    (before the first file is written) does the same if :meth:`begin` was not called.
    :meth:`commit` removes the marker when every file is written and releases the lock.
    Used as a context manager: ``begin`` on entry; ``commit`` on a normal exit, :meth:`fail`
    (the reason goes into the marker, when there is one) on an exception.

    Parameters
    ----------
    path : path
        The folder (created with its parents by :meth:`writing`).
    owned : iterable of str
        File names or glob patterns (relative to ``path``) that the command writes: the previous
        run's files matching them are removed by :meth:`begin`.
    command : str
        Named in the marker file (``simulate``, ``optimize dp``, ...).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> d = pathlib.Path(tempfile.mkdtemp()) / "run"
    >>> with OutputFolder(d, ["a.txt"], "demo") as out:
    ...     _ = out.writing()
    ...     _ = write_text_atomic(d / "a.txt", "1")
    ...     marked = is_incomplete(d)
    >>> marked, is_incomplete(d), (d / "a.txt").read_text()
    (True, False, '1')
    """

    def __init__(self, path: str | os.PathLike, owned: Iterable[str], command: str = ""):
        self.path = Path(path)
        self.owned = tuple(owned)
        self.command = command or "run"
        self._marked = False
        self._created = False
        self._lock = _Lock(self.path / LOCK_NAME, f"output folder {self.path}")

    @property
    def marker(self) -> Path:
        return self.path / MARKER

    def _mark(self) -> None:
        self._created = not self.path.exists()
        self.path.mkdir(parents=True, exist_ok=True)
        self._lock.acquire()
        write_text_atomic(self.marker, _marker_text(self.command, "started"))
        self._marked = True
        for entry in list(self.path.iterdir()):
            name = entry.name
            stale = fnmatch.fnmatchcase(name, _TEMP_GLOB) or any(
                fnmatch.fnmatchcase(name, pat) for pat in self.owned)
            if stale and name != MARKER and (entry.is_file() or entry.is_symlink()):
                with contextlib.suppress(FileNotFoundError):
                    entry.unlink()
        _fsync_dir(self.path)

    def begin(self) -> OutputFolder:
        """Before the work: create and lock the folder, mark it incomplete, remove stale files.

        Stopped on the way (a signal, a full disk) once the folder is locked, the marker says why
        and the lock goes (a ``with`` block's ``__exit__`` does not run when its entry fails).
        """
        if not self._marked:
            try:
                self._mark()
            except BaseException as exc:
                if self._lock.fd is not None:
                    self._marked = self.marker.exists()
                    self.fail(f"{type(exc).__name__}: {exc}".strip().rstrip(":"))
                raise
        return self

    def writing(self) -> OutputFolder:
        """Before the first file: :meth:`begin` if it was not called."""
        return self.begin()

    def fail(self, reason: str) -> None:
        """Record why the run did not finish in the marker (the marker stays); unlock."""
        if self._marked:
            with contextlib.suppress(OSError):
                write_text_atomic(self.marker, _marker_text(self.command, f"failed: {reason}"))
        self._lock.release()

    def commit(self) -> None:
        """Every file is written: remove the marker and unlock."""
        _fsync_dir(self.path)
        with contextlib.suppress(FileNotFoundError):
            self.marker.unlink()
        _fsync_dir(self.path)
        self._marked = False
        self._lock.release()

    def __enter__(self) -> Self:
        return self.begin()

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.writing()
            self.commit()
        elif (self._created and issubclass(exc_type, DownholeInputError)
              and self._only_marker()):
            # refused for its input before it wrote anything: leave no trace of a folder that
            # did not exist
            with contextlib.suppress(OSError):
                self.marker.unlink()
            self._lock.release()
            with contextlib.suppress(OSError):
                self.path.rmdir()
            self._marked = False
        else:
            self.fail(f"{exc_type.__name__}: {exc}".strip().rstrip(":"))

    def _only_marker(self) -> bool:
        try:
            return {e.name for e in self.path.iterdir()} <= {MARKER, LOCK_NAME}
        except OSError:
            return False


class OutputFile:
    """A single output file written by a long run: ``FILE.INCOMPLETE`` beside it until done.

    :meth:`begin` writes the marker and removes the previous ``FILE`` (so that a killed run does
    not leave the previous result looking fresh); :meth:`commit` removes the marker once ``FILE``
    was written (atomically, with :func:`atomic_path`).
    """

    def __init__(self, path: str | os.PathLike, command: str = ""):
        self.path = Path(path)
        self.command = command or "run"
        self._lock = _Lock(self.path.with_name(f".{self.path.name}.lock"),
                           f"output file {self.path}")

    @property
    def marker(self) -> Path:
        return self.path.with_name(self.path.name + "." + MARKER)

    def begin(self) -> OutputFile:
        """Before the work: lock, mark, remove the previous ``FILE`` and stale temporaries."""
        self._lock.acquire()
        try:
            self._mark()
        except BaseException as exc:  # stopped on the way: say why, unlock
            self.fail(f"{type(exc).__name__}: {exc}".strip().rstrip(":"))
            raise
        return self

    def _mark(self) -> None:
        write_text_atomic(self.marker, _marker_text(self.command, f"writing {self.path.name}"))
        folder = self.path.parent
        stem = temp_path(self.path).name.rsplit(".part-", 1)[0]
        for entry in list(folder.iterdir()):
            if entry.name.startswith(stem + ".part-") and entry.is_file():
                with contextlib.suppress(FileNotFoundError):
                    entry.unlink()
        with contextlib.suppress(FileNotFoundError):
            if self.path.is_file() or self.path.is_symlink():
                self.path.unlink()
        _fsync_dir(folder)

    def fail(self, reason: str) -> None:
        with contextlib.suppress(OSError):
            write_text_atomic(self.marker, _marker_text(self.command, f"failed: {reason}"))
        self._lock.release()

    def commit(self) -> None:
        with contextlib.suppress(FileNotFoundError):
            self.marker.unlink()
        _fsync_dir(self.path.parent)
        self._lock.release()
