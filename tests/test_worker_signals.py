"""No worker outlives an interrupted command: :func:`downhole._workers.worker_pool` kills its
workers on SIGTERM, SIGHUP and SIGINT of the parent, and the kernel kills them when the parent
itself is killed (``kill -9``).

Each case starts a parent process that runs a pool of two workers busy in long tasks, signals the
parent once both workers are running, and waits (bounded) until neither worker exists any more.
The waits are bounds for an event, not timing claims: they only fail when workers are left.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import textwrap
import time

import pytest

PARENT = textwrap.dedent("""
    import os, sys, time
    from downhole._workers import StopRequested, worker_pool

    def busy(i):
        print(f"worker {os.getpid()} ", flush=True)
        time.sleep(600)

    if __name__ == "__main__":
        try:
            with worker_pool(2) as pool:
                futs = [pool.submit(busy, i) for i in range(2)]
                for f in futs:
                    f.result()
        except StopRequested as exc:
            print(f"parent: {exc}", flush=True)
            sys.exit(exc.code)
        except KeyboardInterrupt:
            print("parent: interrupted", flush=True)
            sys.exit(130)
""")

BOUND = 60.0  # s: upper bound of a wait on a loaded machine; normally well under a second


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().rsplit(")", 1)[1].split()[0] != "Z"  # a zombie has ended
    except FileNotFoundError:
        return False


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP, signal.SIGINT, signal.SIGKILL])
def test_no_worker_outlives_its_parent(sig, tmp_path):
    script = tmp_path / "parent.py"
    script.write_text(PARENT)
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    p = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, text=True,
                         env=env, cwd=tmp_path)
    try:
        workers = []
        end = time.monotonic() + BOUND
        while len(workers) < 2 and time.monotonic() < end:
            line = p.stdout.readline()  # the two workers' lines may interleave
            workers += [int(w) for w in re.findall(r"worker (\d+)", line)]
        assert len(workers) == 2, "the workers did not start"
        os.kill(p.pid, sig)
        p.wait(timeout=BOUND)
        rest = p.stdout.read()
        end = time.monotonic() + BOUND
        while any(_alive(w) for w in workers) and time.monotonic() < end:
            time.sleep(0.05)
        assert not any(_alive(w) for w in workers), f"workers left after {sig.name}"
        if sig in (signal.SIGTERM, signal.SIGHUP):
            assert f"parent: stopped by {sig.name}" in rest
            assert p.returncode == 128 + sig
        elif sig == signal.SIGINT:
            assert "parent: interrupted" in rest
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
