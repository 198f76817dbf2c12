"""Real-time scheduling helpers of the SIL loops: SCHED_FIFO for the calling thread and a
sleep-then-spin wait on the monotonic clock.

Used by both ends of the loop, the in-process runner (:mod:`downhole.sil.runtime`) and the
controller client of the UDP link (:mod:`downhole.sil.link`), so neither has to import the other.
"""

from __future__ import annotations

import os
import time

__all__ = ["elevate_priority", "sleep_until"]


def elevate_priority(priority: int = 50):
    """Try SCHED_FIFO for the calling thread (Linux, needs CAP_SYS_NICE / root).

    Returns a callable that restores the previous policy, and the policy name obtained
    (``"fifo"`` or ``"normal"``). Never raises: without the privilege the loop runs at normal
    priority (and misses more deadlines on a loaded machine)."""
    try:
        old = os.sched_getscheduler(0)
        old_param = os.sched_getparam(0)
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except (AttributeError, OSError, PermissionError):
        return (lambda: None), "normal"

    def restore():
        try:
            os.sched_setscheduler(0, old, old_param)
        except OSError:
            pass

    return restore, "fifo"


def sleep_until(t: float, spin: float) -> None:
    """Wait until ``time.monotonic() >= t``: sleep to ``spin`` seconds before, then spin."""
    remaining = t - time.monotonic()
    if remaining > spin:
        time.sleep(remaining - spin)
    while time.monotonic() < t:
        pass
