"""Console progress of the SIL commands: a countdown while waiting, a progress line while running.

``downhole sil`` and ``downhole sil-controller`` have three long phases: the controller design
(the DHP trainer's own rich progress bars), waiting for the other end of the UDP link
(:func:`wait_with_countdown`) and the run itself (:class:`RunProgress`, and
:class:`ServeProgress` on the controller's end). These helpers write to
stderr, so that stdout keeps only the JSON summary. On a terminal they redraw one line in place
(``\\r`` and an ANSI erase-line); otherwise (a log file, a pipe, a test) they print a plain line
at the start, every ``every`` seconds and at the end.

The running display is deliberately cheap (one short formatted string, at most twice a second):
it shares the interpreter with a 1 kHz loop, and a heavy redraw would cost deadlines.
"""

from __future__ import annotations

import math
import sys
import threading
import time

__all__ = ["RunProgress", "ServeProgress", "format_seconds", "wait_with_countdown"]


def format_seconds(s: float) -> str:
    """``"4:05"`` for 245 s, ``"1:02:03"`` past an hour, ``"--"`` for non-finite values."""
    if not math.isfinite(s):
        return "--"
    s = max(0, int(math.ceil(s)))
    h, rem = divmod(s, 3600)
    m, sec = divmod(rem, 60)
    return f"{h}:{m:02d}:{sec:02d}" if h else f"{m}:{sec:02d}"


def _is_tty(out) -> bool:
    try:
        return bool(out.isatty())
    except (AttributeError, ValueError):
        return False


def wait_with_countdown(attempt, timeout: float, *, what: str, out=None, slice_s: float = 0.5,
                        every: float = 10.0, clock=time.monotonic,
                        interactive: bool | None = None) -> bool:
    """Call ``attempt(seconds)`` until it returns True or ``timeout`` seconds have passed,
    showing the time left.

    Parameters
    ----------
    attempt : callable
        ``attempt(seconds) -> bool``: try for at most ``seconds`` (e.g. a readiness handshake).
    timeout : float
        Total time to wait, s (> 0).
    what : str
        What is awaited, shown as ``waiting for {what}: 4:32 left``.
    out : file, optional
        Where to write (default ``sys.stderr``).
    slice_s : float
        Longest single attempt, s (the display updates between attempts).
    every : float
        Without a terminal, print a line this often, s.
    clock : callable
        Monotonic clock (tests pass a fake one).
    interactive : bool, optional
        Redraw one line in place (default: ``out`` is a terminal).

    Returns
    -------
    bool
        True when an attempt succeeded, False when the time ran out.
    """
    if not (isinstance(timeout, (int, float)) and math.isfinite(timeout) and timeout > 0):
        raise ValueError(f"timeout must be a positive number of seconds, got {timeout!r}")
    out = sys.stderr if out is None else out
    tty = _is_tty(out) if interactive is None else interactive
    start = clock()
    end = start + timeout
    last_line = None

    def show(left: float, final: str | None = None):
        nonlocal last_line
        text = final or f"waiting for {what}: {format_seconds(left)} left (Ctrl-C to stop)"
        if tty:
            out.write("\r\x1b[K" + text + ("\n" if final else ""))
            out.flush()
        elif final or last_line is None or clock() - last_line >= every:
            out.write(text + "\n")
            out.flush()
            last_line = clock()

    while True:
        now = clock()
        left = end - now
        if left <= 0:
            show(0.0, f"waiting for {what}: gave up after {timeout:g} s")
            return False
        show(left)
        if attempt(min(slice_s, left)):
            show(0.0, f"waiting for {what}: ready after {clock() - start:.1f} s")
            return True


class _Ticker:
    """A progress line redrawn by a daemon thread while the ``with`` body runs."""

    header = ""

    def __init__(self, *, out=None, interval: float = 0.5, every: float = 10.0,
                 interactive: bool | None = None):
        self.out = sys.stderr if out is None else out
        self.tty = _is_tty(self.out) if interactive is None else interactive
        self.interval = max(0.05, float(interval))
        self.every = float(every)
        self._done = threading.Event()
        self._thread: threading.Thread | None = None
        self._t0 = None

    def line(self) -> str:  # pragma: no cover - overridden
        raise NotImplementedError

    def _write(self, final: bool = False) -> None:
        text = self.line()
        if self.tty:
            self.out.write("\r\x1b[K" + text + ("\n" if final else ""))
        else:
            self.out.write(text + "\n")
        self.out.flush()

    def _loop(self) -> None:
        last = time.monotonic()
        while not self._done.wait(self.interval):
            if self.tty or time.monotonic() - last >= self.every:
                self._write()
                last = time.monotonic()

    def __enter__(self):
        self._t0 = time.monotonic()
        if not self.tty and self.header:
            self.out.write(self.header + "\n")
            self.out.flush()
        self._thread = threading.Thread(target=self._loop, name="downhole-sil-progress",
                                        daemon=True)
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._done.set()
        if self._thread is not None:
            self._thread.join(2.0)
        self._write(final=True)
        return False


class RunProgress(_Ticker):
    """A progress line for a running :class:`~downhole.sil.runtime.RealTimeRunner`.

    Use as a context manager around ``runner.run(duration)``: a daemon thread shows simulated
    time (of ``duration``), steps, deadline misses, late commands and the real-time factor.

    Parameters
    ----------
    runner : RealTimeRunner
    duration : float or None
        Simulated seconds of the run (None: open-ended).
    out : file, optional
        Default ``sys.stderr``.
    interval : float
        Seconds between redraws on a terminal (>= 0.5 keeps the cost negligible).
    every : float
        Without a terminal, seconds between lines.
    interactive : bool, optional
        Redraw in place (default: ``out`` is a terminal).
    """

    def __init__(self, runner, duration: float | None, **kw):
        super().__init__(**kw)
        self.runner = runner
        self.duration = duration
        self.header = (f"running {duration:g} s of simulated time" if duration
                       else "running (Ctrl-C to stop)")

    def line(self) -> str:
        """The current progress text."""
        st = self.runner.stats
        steps = int(st.get("steps", 0))
        sim = steps * self.runner.dt
        wall = time.monotonic() - self._t0 if self._t0 is not None else 0.0
        if self.duration:
            frac = min(1.0, sim / self.duration)
            bar = "#" * int(20 * frac) + "." * (20 - int(20 * frac))
            head = f"running [{bar}] {sim:7.2f} / {self.duration:g} s"
        else:
            head = f"running {sim:7.2f} s"
        misses = int(st.get("deadline_misses", 0))
        pct = 100.0 * misses / steps if steps else 0.0
        rtf = st.get("real_time_factor") or (sim / wall if wall > 0 else 0.0)  # final: exact
        return (f"{head}  {steps} steps  misses {misses} ({pct:.2f} %)  late "
                f"{int(st.get('late_commands', 0))}  x{rtf:.2f} real time")


class ServeProgress(_Ticker):
    """A progress line for :meth:`~downhole.sil.link.ControllerClient.serve`: observations
    received, commands sent, and the link's stale / malformed / foreign counters.

    Parameters
    ----------
    client : ControllerClient
    **kw
        As :class:`RunProgress` (``out``, ``interval``, ``every``, ``interactive``).
    """

    header = "serving the plant (until it says BYE)"

    def __init__(self, client, **kw):
        super().__init__(**kw)
        self.client = client

    def line(self) -> str:
        """The current progress text."""
        c = self.client.counters
        wall = time.monotonic() - self._t0 if self._t0 is not None else 0.0
        return (f"serving {wall:6.1f} s  {c.get('rx', 0)} received  {c.get('tx', 0)} sent  "
                f"stale {c.get('stale', 0)}  malformed {c.get('malformed', 0)}  foreign "
                f"{c.get('foreign', 0)}")
