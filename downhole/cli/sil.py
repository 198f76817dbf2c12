"""CLI of the SIL testbed: ``downhole sil``, ``downhole sil-controller``, ``downhole export-fmu``.

- ``downhole sil SCENARIO.toml [--controller FILE] [--dashboard] [--duration S] [--out F.nc]``
  runs the scenario in real time (or unpaced with ``--unpaced``); with ``[controller] remote =
  true`` (or ``--remote``) it waits for a controller on the UDP link.
- ``downhole sil-controller --port P [--host H] (--controller FILE | --scenario S.toml)``
  is the controller end: it connects to a running plant and answers every observation.
- ``downhole export-fmu SCENARIO.toml --out plant.fmu`` builds an FMI 2.0 co-simulation FMU.

``downhole sil`` checks ``--out`` and ``[runtime] chunk_dir`` before it builds anything. SIGINT
and SIGTERM end a running loop after the current step: the recording is flushed, ``--out`` is
written with the rows recorded so far (attribute ``stopped_by``) and the command exits with
128 + the signal number. A signal while waiting for the controller ends the command with
nothing written; one while the result is written is acted on once it is written.
"""

from __future__ import annotations

import json
import signal
import threading
import time
from pathlib import Path
from typing import Optional

import typer

from downhole._atomic import OutputFile, check_output_path
from downhole.cli import app, fail

__all__ = ["sil", "sil_controller", "export_fmu"]


class _Interrupted(Exception):
    """A stop signal arrived before the real-time loop started."""


class _StopOnSignal:
    """SIGINT/SIGTERM handler of ``downhole sil``: stop the loop, never lose the recording.

    ``phase`` is ``"waiting"`` (before the loop: raise :class:`_Interrupted`), ``"running"``
    (ask the runner to stop after the current step) or ``"writing"`` (remember the signal and
    let the result be written).
    """

    def __init__(self, runner):
        self.runner = runner
        self.signum: int | None = None
        self.stopped_run = False  # the signal ended the loop early
        self.phase = "waiting"
        self._previous: dict = {}

    def install(self) -> "_StopOnSignal":
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                self._previous[sig] = signal.signal(sig, self)
        return self

    def restore(self) -> None:
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)
        self._previous.clear()

    def __call__(self, signum, frame) -> None:
        first = self.signum is None
        if first:
            self.signum = signum
        if self.phase == "waiting":
            if first:
                raise _Interrupted(signum)
        elif self.phase == "running":
            self.stopped_run = True
            self.runner.stop()
            if not self.runner.running:  # still warming up: stop as soon as the loop starts
                threading.Thread(target=self._stop_when_running, daemon=True).start()

    def _stop_when_running(self) -> None:
        while self.phase == "running" and not self.runner.running:
            time.sleep(0.005)
        self.runner.stop()


@app.command("sil")
def sil(scenario: Path = typer.Argument(..., help="SIL scenario TOML (docs/sil.md)"),
        controller: Optional[Path] = typer.Option(None, "--controller",
                                                  help="controller file (.py, or DHP .json)"),
        dashboard: bool = typer.Option(False, "--dashboard", help="serve the live dashboard"),
        duration: Optional[float] = typer.Option(None, "--duration", help="simulated s"),
        out: Optional[Path] = typer.Option(None, "--out", help="write the Result (NetCDF)"),
        remote: bool = typer.Option(False, "--remote", help="controller over the UDP link"),
        port: Optional[int] = typer.Option(None, "--port", help="UDP port (overrides [link])"),
        unpaced: bool = typer.Option(False, "--unpaced", help="as fast as possible")):
    """Run a scenario in the real-time SIL runtime."""
    from downhole.sil.runtime import RealTimeRunner, SafetyPolicy
    from downhole.sil.scenario import build_from_scenario, load_sil_scenario

    sc = load_sil_scenario(scenario)
    if remote:
        sc.controller.remote = True
    if port is not None:
        sc.link.port = port
    rtc = sc.runtime
    # output paths first: a bad --out must not cost a controller design and a whole run
    if out is not None:
        check_output_path(out, kind="file")
    if rtc.chunk_dir is not None:
        check_output_path(rtc.chunk_dir, option=f"{scenario}: runtime.chunk_dir", kind="folder")
    plant, ctrl = build_from_scenario(sc, controller_file=str(controller) if controller else None)
    hil = sc.link.mode == "hil"
    use_link = sc.controller.remote or hil
    every = max(1, int(round(rtc.record_dt / rtc.dt)))
    runner = RealTimeRunner(
        plant, ctrl, link=(sc.link.host, sc.link.port) if use_link else None, hil=hil,
        reference={"axial": sc.reference.axial, "angular": sc.reference.angular},
        paced=rtc.paced and not unpaced, record_every=every,
        ring_rows=max(1, int(rtc.ring_seconds / rtc.record_dt)), chunk_dir=rtc.chunk_dir,
        max_lag=rtc.max_lag, wait_fraction=rtc.wait_fraction,
        safety=SafetyPolicy(sc.safety.timeout, sc.safety.hold, sc.safety.ramp, sc.safety.resume),
        controller_enabled=sc.controller.enabled and sc.controller.kind != "none",
        realtime=rtc.realtime)
    dur = duration if duration is not None else rtc.duration
    stopper = _StopOnSignal(runner).install()
    out_file = OutputFile(out, "sil") if out is not None else None
    try:
        if use_link:
            h, p = runner.link.address
            typer.echo(f"plant listening on udp://{h}:{p}; waiting for the "
                       f"{'rig' if hil else 'controller'}...", err=True)
            if not runner.wait_for_controller(sc.link.connect_timeout):
                fail(f"no controller connected within {sc.link.connect_timeout:g} s")
        if out_file is not None:
            out_file.begin()  # the previous result goes now: a killed run leaves none
        stopper.phase = "running"
        if dashboard:
            from downhole.sil.dashboard import serve_dashboard

            serve_dashboard(runner, host=sc.dashboard.host, port=sc.dashboard.port,
                            token=sc.dashboard.token, duration=dur,
                            publish_hz=sc.dashboard.publish_hz)
            res = runner.result()
        else:
            res = runner.run(dur)
    except _Interrupted as exc:
        stopper.restore()
        typer.echo(f"error: {signal.Signals(exc.args[0]).name} before the run started; nothing "
                   "recorded or written", err=True)
        raise typer.Exit(128 + exc.args[0]) from None
    except BaseException as exc:
        stopper.restore()
        if out_file is not None and out_file.marker.exists():
            out_file.fail(f"{type(exc).__name__}: {exc}")
        raise
    finally:
        stopper.phase = "writing"  # a signal from now on is acted on once the result is written
        runner.close()
        runner.recorder.finish()
    typer.echo(json.dumps({"stats": runner.stats, "scheduler": runner.scheduler,
                           "link": runner.link.counters if runner.link else None,
                           "events": runner.event_count}, indent=1))
    _write_sil_result(res, out, out_file, stopper)


def _write_sil_result(res, out, out_file, stopper) -> None:
    """Write ``--out`` (the handlers still installed), then act on a signal that came."""
    try:
        if stopper.stopped_run:
            res.dataset.attrs["stopped_by"] = signal.Signals(stopper.signum).name
        if out_file is not None:
            res.save(out)
            out_file.commit()
            typer.echo(f"wrote {out}", err=True)
    finally:
        stopper.restore()
    if stopper.signum is not None:
        typer.echo(f"stopped by {signal.Signals(stopper.signum).name} after "
                   f"{stopper.runner.stats.get('sim_s', 0.0):g} s simulated", err=True)
        raise typer.Exit(128 + stopper.signum)


@app.command("sil-controller")
def sil_controller(port: int = typer.Option(..., "--port", help="plant's UDP port"),
                   host: str = typer.Option("127.0.0.1", "--host", help="plant's address"),
                   controller: Optional[Path] = typer.Option(None, "--controller",
                                                             help=".py or DHP .json file"),
                   scenario: Optional[Path] = typer.Option(
                       None, "--scenario", help="build the controller from this scenario"),
                   rig: bool = typer.Option(False, "--rig",
                                            help="act as the software HIL rig (bit + rock)"),
                   idle_timeout: float = typer.Option(5.0, "--idle-timeout",
                                                      help="stop after this long without data"),
                   realtime: bool = typer.Option(True, "--realtime/--no-realtime",
                                                 help="try SCHED_FIFO while serving")):
    """Run a controller (or the software rig) against a plant over the UDP link."""
    from downhole.errors import DownholeInputError
    from downhole.sil.controllers import load_controller_file
    from downhole.sil.link import ControllerClient

    if sum(x is not None for x in (controller, scenario)) + rig != 1:
        raise DownholeInputError("give exactly one of --controller FILE, --scenario FILE, --rig")
    client = ControllerClient(host, port, name="downhole sil-controller")
    layout = client.connect(timeout=30.0)
    if rig:
        from downhole.sil.hil import SoftwareRig
        from downhole.string.hybrid import hybrid_model

        ctrl = SoftwareRig(hybrid_model("hybrid68").bit, layout.dt)
    elif controller is not None:
        ctrl = load_controller_file(controller)
    else:
        from downhole.sil.scenario import build_from_scenario, load_sil_scenario

        sc = load_sil_scenario(scenario)
        sc.controller.remote = False
        _, ctrl = build_from_scenario(sc)
        if ctrl is None:
            raise DownholeInputError(f"{scenario}: the scenario defines no controller")
    # warm up (compile) before the first observation arrives
    try:
        ctrl.command(0.0, {n: 0.0 for n in layout.observations}, None)
    except Exception:  # noqa: BLE001 - a warm-up failure shows up again, properly, below
        pass
    ctrl.reset()
    typer.echo(f"connected: {len(layout.observations)} observations, commands "
               f"{', '.join(layout.commands)}, dt = {layout.dt:g} s", err=True)
    try:
        n = client.serve(ctrl, idle_timeout=idle_timeout, realtime=realtime)
    finally:
        client.close()
    typer.echo(json.dumps({"commands_sent": n, "counters": client.counters}))


@app.command("export-fmu")
def export_fmu(scenario: Path = typer.Argument(..., help="SIL scenario TOML"),
               out: Path = typer.Option(Path("plant.fmu"), "--out", help="FMU file to write")):
    """Build an FMI 2.0 co-simulation FMU of the scenario's plant (pythonfmu)."""
    from downhole.sil.fmu import export_fmu as _export

    check_output_path(out, kind="file")
    path = _export(scenario, out)
    typer.echo(f"wrote {path}")
