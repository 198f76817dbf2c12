"""Worker processes started from a script: refuse an unguarded script, and never turn a dead pool
into a normal return.

downhole's parallel entry points (``run_sweep(..., processes=N)``, ``reproduce(..., jobs=N)``,
``compare_controllers(..., jobs=N)``, a Dask ``LocalCluster``) start their workers with the
``spawn`` method: every worker imports the main script again (as ``__mp_main__``). A script
that calls such an entry point at its top level, not under ``if __name__ == "__main__":``,
would call it again in every worker while the worker is still starting; Python then refuses to
start processes from it, every worker dies, and the pool breaks
(:class:`~concurrent.futures.process.BrokenProcessPool`).

:func:`check_main_guarded` finds that case *before* any process starts: it looks up the
statement of the main script that is running now (the frame of ``__main__``'s top-level code) and
raises :class:`~downhole.errors.DownholeInputError` unless that statement is an
``if __name__ == "__main__":`` block. In a worker re-importing the script it raises too (the
parent then sees a broken pool). Interactive sessions, ``python -c`` and notebooks have no main
script to re-import and pass (the rule of ``multiprocessing.spawn``: a script run by path, or a
module run with ``python -m``, is imported again; a package's ``__main__`` is not). :func:`broken_pool_error` is the error a caller raises when a pool
breaks anyway (a worker killed by the OS, out of memory, ...), instead of reporting every
remaining task as failed and returning normally.

:func:`worker_pool` is the one way these entry points start a local process pool: ``spawn``
workers that the kernel kills when their parent ends, however it ends (Linux
``prctl(PR_SET_PDEATHSIG, SIGKILL)``, set by the worker initializer; a worker whose parent is
already gone exits at once); SIGTERM and SIGHUP (a closed terminal, a dropped SSH session) in the
parent become :class:`StopRequested` (a ``SystemExit`` with code 128 + signal) while the pool
runs, and any exception, SIGINT's ``KeyboardInterrupt`` included, kills the workers instead of
waiting for their tasks, so no worker outlives an interrupted command.

This module imports nothing of downhole but :mod:`downhole.errors`.
"""

from __future__ import annotations

import ast
import contextlib
import os
import signal
import sys
import threading
from collections.abc import Iterator
from functools import lru_cache

from downhole.errors import DownholeInputError, WorkerProcessError

__all__ = ["GUARD", "StopRequested", "WorkerProcessError", "broken_pool_error",
           "check_main_guarded", "stop_on_signals", "worker_pool"]

GUARD = 'if __name__ == "__main__":'


def _is_main_test(test: ast.expr) -> bool:
    if not (isinstance(test, ast.Compare) and len(test.ops) == 1
            and isinstance(test.ops[0], ast.Eq)):
        return False
    sides = (test.left, test.comparators[0])
    names = [s for s in sides if isinstance(s, ast.Name) and s.id == "__name__"]
    consts = [s for s in sides if isinstance(s, ast.Constant) and s.value == "__main__"]
    return len(names) == 1 and len(consts) == 1


@lru_cache(maxsize=8)
def _guarded_lines(path: str, mtime_ns: int) -> tuple[tuple[int, int], ...] | None:
    """Line ranges of the bodies of the top-level ``if __name__ == "__main__":`` blocks of
    ``path``; None if it cannot be read or parsed."""
    try:
        with open(path, "rb") as fh:
            tree = ast.parse(fh.read(), filename=path)
    except (OSError, SyntaxError, ValueError):
        return None
    out = []
    for node in tree.body:
        if isinstance(node, ast.If) and _is_main_test(node.test) and node.body:
            out.append((node.body[0].lineno, node.body[-1].end_lineno or node.body[-1].lineno))
    return tuple(out)


def _main_frame():
    """The (innermost) frame running the main module's top-level code, or None."""
    main = sys.modules.get("__main__")
    main_vars = vars(main) if main is not None else None
    frame = sys._getframe(2)
    while frame is not None:
        if frame.f_code.co_name == "<module>" and (
                frame.f_globals is main_vars or frame.f_globals.get("__name__") == "__mp_main__"):
            return frame
        frame = frame.f_back
    return None


def _spawn_reimports_main() -> bool:
    """Whether a ``spawn`` worker runs the main module again (the rule of
    :func:`multiprocessing.spawn.get_preparation_data`): a script run by path, or a module run
    with ``python -m NAME`` (not a package's ``__main__``); not a notebook or ``python -c``."""
    main = sys.modules.get("__main__")
    if main is None:
        return False
    name = getattr(getattr(main, "__spec__", None), "name", None)
    if name is not None:
        return not (name == "__main__" or name.endswith(".__main__"))
    path = getattr(main, "__file__", None)
    return bool(path) and os.path.splitext(os.path.basename(path))[0] != "ipython"


def check_main_guarded(what: str, serial: str) -> None:
    """Raise unless starting spawned worker processes from here is safe.

    Parameters
    ----------
    what : str
        The call, for the message (``"run_sweep(processes=2)"``).
    serial : str
        How to run without worker processes (``"processes=1"``).

    Raises
    ------
    DownholeInputError
        The main script calls ``what`` at its top level without the ``__main__`` guard (every
        worker would run it again), or this is a worker re-importing such a script.
    """
    frame = _main_frame()
    if frame is None:
        return  # no main script running (an interactive session, python -c, a notebook)
    name = frame.f_globals.get("__name__")
    path = frame.f_globals.get("__file__")
    fix = (f"put the call under `{GUARD}` (worker processes import the script again), or "
           f"use {serial}")
    if name == "__mp_main__":  # a spawned worker importing the main script runs the call again
        raise DownholeInputError(f"{path}: {what} ran again while a worker process imported "
                                 f"the script: {fix}")
    if name != "__main__" or not path or not os.path.isfile(path) \
            or not _spawn_reimports_main():
        return
    try:
        mtime = os.stat(path).st_mtime_ns
    except OSError:
        return
    guarded = _guarded_lines(os.path.abspath(path), mtime)
    if guarded is None:
        return  # cannot tell; the pool error below still names the cause
    line = frame.f_lineno
    if not any(lo <= line <= hi for lo, hi in guarded):
        raise DownholeInputError(f"{path}, line {line}: {what} starts worker processes from "
                                 f"the script's top level: {fix}")


def broken_pool_error(what: str, serial: str, exc: BaseException) -> WorkerProcessError:
    """The error to raise when a process pool broke (a worker died)."""
    return WorkerProcessError(
        f"{what}: a worker process died and the process pool broke "
        f"({type(exc).__name__}: {exc}); nothing was returned. If this runs from a script, put "
        f"the call under `{GUARD}`; else the operating system may have killed a worker (memory), "
        f"or use {serial}")


class StopRequested(SystemExit):
    """SIGTERM or SIGHUP arrived while a :func:`worker_pool` ran (exit code 128 + signal)."""

    def __init__(self, signum: int):
        super().__init__(128 + signum)
        self.signum = signum

    def __str__(self) -> str:
        return f"stopped by {signal.Signals(self.signum).name}"


def _die_with_parent(parent: int) -> None:
    """Worker initializer: the kernel kills this worker when its parent ends (Linux), and the
    terminal's signals to the whole process group (SIGINT from Ctrl-C, SIGHUP from a closed
    terminal) are left to the parent, which stops the pool (no traceback from every worker)."""
    armed = False
    if sys.platform.startswith("linux"):
        import ctypes

        with contextlib.suppress(OSError, AttributeError):
            armed = ctypes.CDLL(None, use_errno=True).prctl(
                1, int(signal.SIGKILL)) == 0  # PR_SET_PDEATHSIG
    if os.getppid() != parent:  # the parent ended before the line above took effect
        os._exit(1)
    if armed:  # the kernel ends this worker with its parent: the parent decides
        for sig in (signal.SIGINT, signal.SIGHUP):
            with contextlib.suppress(OSError, ValueError):
                signal.signal(sig, signal.SIG_IGN)


_stopping = False  # a stop signal was turned into StopRequested (a second one is ignored)


def _raise_stop(signum, frame) -> None:
    global _stopping
    if _stopping:  # already unwinding: let the cleanup (killing workers, the marker) finish
        return
    _stopping = True
    raise StopRequested(signum)


@contextlib.contextmanager
def stop_on_signals() -> Iterator[None]:
    """Within the block, SIGTERM and SIGHUP raise :class:`StopRequested` in the main thread.

    A command run this way unwinds like on SIGINT's ``KeyboardInterrupt``: ``finally`` blocks
    and context managers run (an :class:`~downhole._atomic.OutputFolder` records why the run
    stopped in its ``INCOMPLETE`` marker, a :func:`worker_pool` kills its workers), and the
    caller prints one line. A second SIGTERM or SIGHUP while unwinding is ignored (SIGKILL still
    ends the process). Outside the main thread this does nothing. The previous handlers come
    back on exit.

    Python acts on a signal between bytecodes: a long call into compiled code (a closed loop
    running inside one numba call) stops when that call returns.
    """
    global _stopping
    handlers = {}
    if threading.current_thread() is threading.main_thread():
        _stopping = False
        for sig in (signal.SIGTERM, signal.SIGHUP):
            handlers[sig] = signal.signal(sig, _raise_stop)
    try:
        yield
    finally:
        for sig, h in handlers.items():
            signal.signal(sig, h)


def _kill_workers(pool) -> None:
    procs = list((getattr(pool, "_processes", None) or {}).values())
    for p in procs:
        with contextlib.suppress(Exception):
            p.kill()
    for p in procs:
        with contextlib.suppress(Exception):
            p.join(timeout=5.0)


def _start_resource_tracker() -> None:
    """Start multiprocessing's resource tracker with SIGHUP blocked (it blocks SIGINT and
    SIGTERM itself): a SIGHUP to the whole process group (a closed terminal) would kill it, and
    the parent's cleanup would then relaunch it and print warnings and tracebacks. It ends by
    itself when the parent and the workers have ended. SIGHUP to this process is only delayed
    until the tracker has started."""
    if not hasattr(signal, "pthread_sigmask"):
        return
    from multiprocessing import resource_tracker

    old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGHUP})
    try:
        resource_tracker.ensure_running()
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


@contextlib.contextmanager
def worker_pool(max_workers: int) -> Iterator:
    """A ``spawn`` process pool whose workers never outlive the command that started them.

    Parameters
    ----------
    max_workers : int
        Number of worker processes.

    Yields
    ------
    concurrent.futures.ProcessPoolExecutor
        The pool. On a normal exit it is shut down waiting for its tasks; on any exception
        (SIGINT's ``KeyboardInterrupt``, :class:`StopRequested` from SIGTERM or SIGHUP, a
        failure) its workers are killed and the exception propagates.
    """
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor

    with stop_on_signals():
        _start_resource_tracker()
        pool = ProcessPoolExecutor(max_workers=max_workers, mp_context=mp.get_context("spawn"),
                                   initializer=_die_with_parent, initargs=(os.getpid(),))
        try:
            yield pool
            pool.shutdown(wait=True)
        except BaseException:  # including a signal while waiting for the last tasks
            _kill_workers(pool)
            pool.shutdown(wait=False, cancel_futures=True)
            raise
