"""Helpers shared by the SIL tests, experiments and benchmarks: a trained Ch. 6 DHP controller
and a controller process started with ``downhole sil-controller``."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

__all__ = ["ControllerProcess", "ch6_dhp", "free_port"]

_CACHE: dict = {}


def ch6_dhp(reference: str = "step", horizon: float = 8.0, samples: int = 50, dt: float = 1e-3):
    """``(design, controller)``: DHP trained on the 24-state FEM (hybrid24's design FEM) for a
    step / sine / ramp bit reference (Table 4.1 set-up, robust weights), cached per process."""
    key = (reference, horizon, samples, dt)
    if key not in _CACHE:
        from downhole.control.dhp import BitReference, DHPSettings, PenaltyWeights, design_dhp
        from downhole.control.dhp.directional import directional_affine_model
        from downhole.control.dhp.weight_sets import weight_set
        from downhole.string.hybrid import hybrid_model

        design = _CACHE.get(("design", dt))
        if design is None:
            design = directional_affine_model(hybrid_model("hybrid24").design_model(), dt)
            _CACHE[("design", dt)] = design
        ref = {"step": BitReference.step(), "sine": BitReference.sine(),
               "ramp": BitReference.ramp(t_final=horizon)}[reference]
        ctrl = design_dhp(design, ref, horizon=horizon, weights=PenaltyWeights(**weight_set("robust")),
                          settings=DHPSettings(n_samples=samples))
        _CACHE[key] = (design, ctrl)
    return _CACHE[key]


def free_port() -> int:
    """A free UDP port on 127.0.0.1."""
    import socket

    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class ControllerProcess:
    """``downhole sil-controller`` in its own process (context manager; killed on exit).

    Parameters
    ----------
    port : int
        The plant's UDP port on 127.0.0.1.
    args : list of str
        Extra arguments (``["--controller", path]`` or ``["--rig"]``). A ``.py`` controller
        (a test's own file) gets ``--allow-code``.
    """

    def __init__(self, port: int, args, idle_timeout: float = 3.0, log: Path | None = None):
        args = [str(a) for a in args]
        if any(a.endswith(".py") for a in args) and "--allow-code" not in args:
            args.append("--allow-code")
        cmd = [sys.executable, "-c", "import sys; from downhole.cli import main; "
               "sys.exit(main(sys.argv[1:]))", "sil-controller", "--port", str(port),
               "--idle-timeout", str(idle_timeout), *args]
        env = dict(os.environ)
        env.setdefault("OMP_NUM_THREADS", "1")
        env.setdefault("OPENBLAS_NUM_THREADS", "1")
        self._log = open(log, "w") if log else subprocess.DEVNULL  # noqa: SIM115 (closed in kill)
        self.proc = subprocess.Popen(cmd, stdout=self._log, stderr=subprocess.STDOUT, env=env)

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait(timeout=10)

    def wait(self, timeout: float = 30.0) -> int:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if self.proc.poll() is not None:
                return self.proc.returncode
            time.sleep(0.05)
        self.kill()
        return -9

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.kill()
        if self._log is not subprocess.DEVNULL:
            self._log.close()


class ServerThread:
    """An ASGI ``app`` served by uvicorn on 127.0.0.1:``port`` in a daemon thread, as a context
    manager (for the dashboard's browser and HTTP tests): started on enter (20 s at most),
    stopped on exit. A dashboard app (:func:`~downhole.sil.dashboard.make_app`) is served
    with its limits (:func:`~downhole.sil.dashboard.server_config`)."""

    def __init__(self, app, port: int):
        import threading

        import uvicorn

        if hasattr(getattr(app, "state", None), "dashboard_limits"):
            from downhole.sil.dashboard import server_config

            config = server_config(app, "127.0.0.1", port)
        else:
            config = uvicorn.Config(app, host="127.0.0.1", port=port, log_level="warning")
        self.server = uvicorn.Server(config)
        self.thread = threading.Thread(target=self.server.run, daemon=True)

    def __enter__(self):
        import time

        self.thread.start()
        end = time.monotonic() + 20
        while not self.server.started and time.monotonic() < end:
            time.sleep(0.05)
        assert self.server.started, "uvicorn did not start"
        return self

    def __exit__(self, *exc):
        self.server.should_exit = True
        self.thread.join(10)
