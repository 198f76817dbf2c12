"""CLI of the SIL testbed: ``downhole sil``, ``downhole sil-controller``, ``downhole export-fmu``.

- ``downhole sil SCENARIO.toml [--controller FILE] [--dashboard] [--duration S] [--out F.nc]``
  runs the scenario in real time (or unpaced with ``--unpaced``); with ``[controller] remote =
  true`` (or ``--remote``) it waits for a controller on the UDP link, with a countdown, for
  ``[link] connect_timeout`` (or ``--wait``) seconds. With ``--dashboard`` the run waits for
  the operator's Start on the page (``--autostart``: at once) and the dashboard stays up after
  the run until Ctrl-C (``--exit-after-run``: the command ends with the run); ``--http-port``
  is the dashboard's port (``--port`` is the UDP link's). With ``--out``, a dashboard run that
  has used up its duration is written to ``--out`` at once (atomically), not when the
  dashboard is closed.
- ``downhole sil-controller (--scenario S.toml | --controller FILE | --rig) [--port P]``
  is the controller end: it builds (designs) its controller first, then connects to the plant
  (the scenario's ``[link]`` address by default) and answers every observation.
- ``downhole export-fmu SCENARIO.toml [--fidelity NAME] --out plant.fmu`` builds an FMI 2.0
  co-simulation FMU (a SIL scenario's plant, or a system scenario at any fidelity).

A Python controller file is code: both commands run one only with ``--allow-code``. Every long
phase (design, waiting, running) shows progress on stderr (``--no-progress`` to silence it).

``downhole sil`` checks ``--out`` and ``[realtime] chunk_dir`` before it builds anything. SIGINT
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

import typer

from downhole._atomic import OutputFile, check_output_path
from downhole.cli import app, fail
from downhole.cli._units import UNIT_OPTION, UNITS_OPTION, resolve_units

__all__ = ["export_fmu", "sil", "sil_controller"]


def _positive_seconds(value: float | None, option: str) -> float | None:
    import math

    if value is not None and not (math.isfinite(value) and value > 0):
        fail(f"{option} must be a positive number of seconds, got {value:g}")
    return value


def _design_note(sc, what: str) -> None:
    """Say that a long design starts (the trainer's rich bars follow on a terminal)."""
    if sc.controller.type == "dhp" and not sc.controller.file:
        d = sc.controller.options.dhp
        typer.echo(f"{what}: designing the DHP controller ({d.training.n_samples} samples, "
                   f"horizon {d.training.horizon:g} s, weights {d.weights}); this can take a "
                   "minute or more",
                   err=True)


class _Interrupted(Exception):
    """A stop signal arrived before the real-time loop started."""


class _NeverStarted(Exception):
    """The dashboard closed before the operator started the run (args: the signal or None)."""


class _StopOnSignal:
    """SIGINT/SIGTERM/SIGHUP handler of ``downhole sil``: stop the loop, never lose the recording.

    ``phase`` is ``"waiting"`` (before the loop: raise :class:`_Interrupted`), ``"running"``
    (ask the runner to stop after the current step), ``"browsing"`` (the run has ended and
    the dashboard shows it: the signal only ends the server, the result is complete) or
    ``"writing"`` (remember the signal and let the result be written).
    """

    def __init__(self, runner):
        self.runner = runner
        self.signum: int | None = None
        self.stopped_run = False  # the signal ended the loop early
        self.phase = "waiting"
        self._previous: dict = {}

    def install(self) -> _StopOnSignal:
        if threading.current_thread() is threading.main_thread():
            # SIGHUP (a closed terminal, a dropped SSH session) is a stop like SIGTERM: the
            # recording so far is written to --out
            for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
                self._previous[sig] = signal.signal(sig, self)
        return self

    def restore(self) -> None:
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)
        self._previous.clear()

    def __call__(self, signum, frame) -> None:
        if self.phase == "browsing":  # the run is over, the dashboard shows it: just quit
            return
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
        controller: Path | None = typer.Option(None, "--controller",
                                                  help="controller file (DHP .json/.npz, or a "
                                                       ".py with --allow-code)"),
        dashboard: bool = typer.Option(False, "--dashboard", help="serve the live dashboard"),
        http_port: int | None = typer.Option(
            None, "--http-port", help="the dashboard's HTTP port (overrides [dashboard] port; "
                                      "0: any free port)"),
        autostart: bool = typer.Option(
            False, "--autostart", help="with --dashboard: start the run at once instead of "
                                       "waiting for Start on the page"),
        exit_after_run: bool = typer.Option(
            False, "--exit-after-run", help="with --dashboard: end the command when the run "
                                            "ends instead of keeping the dashboard up until "
                                            "Ctrl-C"),
        duration: float | None = typer.Option(None, "--duration", help="simulated s"),
        out: Path | None = typer.Option(None, "--out", help="write the Result (NetCDF)"),
        remote: bool = typer.Option(False, "--remote", help="controller over the UDP link"),
        port: int | None = typer.Option(None, "--port", help="UDP port (overrides [link])"),
        wait: float | None = typer.Option(
            None, "--wait", help="seconds to wait for the remote controller, with a countdown "
                                 "(overrides [link] connect_timeout, default 300)"),
        allow_code: bool = typer.Option(
            False, "--allow-code", help="allow a Python controller file to run (it is code; a "
                                        "scenario alone never runs code)"),
        progress: bool = typer.Option(True, "--progress/--no-progress",
                                      help="progress of design, waiting and run (stderr)"),
        unpaced: bool = typer.Option(False, "--unpaced", help="as fast as possible"),
        link_key_file: Path | None = typer.Option(
            None, "--link-key-file", help="shared key of the UDP link (chmod 600; default: "
            "$DOWNHOLE_LINK_KEY); required beyond loopback"),
        units: str = UNITS_OPTION, unit: list[str] | None = UNIT_OPTION):
    """Run a scenario in the real-time SIL runtime."""
    from downhole.sil.console import RunProgress, wait_with_countdown
    from downhole.sil.runtime import RealTimeRunner, SafetyPolicy
    from downhole.sil.scenario import build_from_scenario, check_code_allowed, load_sil_scenario

    _positive_seconds(duration, "--duration")
    _positive_seconds(wait, "--wait")
    if not dashboard:
        for given, option in ((http_port is not None, "--http-port"),
                              (autostart, "--autostart"), (exit_after_run, "--exit-after-run")):
            if given:
                fail(f"{option} applies to the dashboard: add --dashboard")
    if http_port is not None and not 0 <= http_port <= 65535:
        fail(f"--http-port must be a port number 0..65535, got {http_port}")
    display = resolve_units(units, unit)
    sc = load_sil_scenario(scenario)
    if http_port is not None:
        sc.dashboard.port = http_port
    if remote:
        sc.controller.remote = True
    if port is not None:
        sc.link.port = port
    rtc, sim = sc.realtime, sc.simulation
    # output paths first: a bad --out must not cost a controller design and a whole run
    if out is not None:
        check_output_path(out, kind="file")
    chunk_dir = None
    if rtc.chunk_dir is not None:  # beside the result, never elsewhere on the host
        if out is None:
            fail(f"{scenario}: realtime.chunk_dir = {rtc.chunk_dir!r} needs --out: the chunk "
                 "folder lives beside the run's result")
        chunk_dir = Path(out).parent / rtc.chunk_dir
        check_output_path(chunk_dir, option=f"{scenario}: realtime.chunk_dir", kind="folder")
    cfile = str(controller) if controller else None
    _check_controller_choice(sc, scenario, cfile)
    token = None
    if dashboard:  # refuse bad dashboard settings now, not after the design and the wait
        from downhole.sil.dashboard import check_dashboard_settings
        from downhole.sil.scenario import dashboard_token

        token = dashboard_token(sc)
        check_dashboard_settings(sc.dashboard.host, token)
    if not sc.controller.remote:
        check_code_allowed(sc, controller_file=cfile, allow_code=allow_code)
        if progress and not cfile:
            _design_note(sc, "plant")
    plant, ctrl = build_from_scenario(sc, controller_file=cfile, allow_code=allow_code,
                                      progress=progress, source=str(scenario))
    hil = sc.link.mode == "hil"
    use_link = sc.controller.remote or hil
    every = max(1, int(round(sim.record_dt / sim.dt)))
    runner = RealTimeRunner(
        plant, ctrl, link=(sc.link.host, sc.link.port) if use_link else None, hil=hil,
        reference={"axial": sc.reference.axial_velocity,
                   "angular": sc.reference.angular_velocity},
        paced=rtc.paced and not unpaced, record_every=every,
        ring_rows=max(1, int(rtc.ring_seconds / sim.record_dt)), chunk_dir=chunk_dir,
        ring_bytes=int(rtc.ring_memory_mib * 2**20),
        max_lag=rtc.max_lag, wait_fraction=rtc.wait_fraction,
        safety=SafetyPolicy(sc.safety.timeout, sc.safety.hold, sc.safety.ramp, sc.safety.resume),
        controller_enabled=sc.controller.enabled and sc.controller.type != "none",
        realtime=rtc.enabled, link_key_file=link_key_file)
    dur = duration if duration is not None else sim.duration
    kept = runner.recorder.capacity * sim.record_dt
    streamed = None  # a chunk folder of this run's own, removed once --out holds the run
    if chunk_dir is None and out is not None and dur > kept * (1 + 1e-9):
        # the run is longer than the ring keeps in memory: stream it to disk beside --out
        streamed = Path(out).parent / f"{Path(out).name}.chunks"
        check_output_path(streamed, option=f"{scenario}: the run's chunk folder", kind="folder")
        runner.stream_to(streamed)
    if runner.ring_capped is not None or streamed is not None:
        where = (f"; the whole run streams to {streamed}/ and goes into {out}"
                 if streamed is not None else
                 "" if chunk_dir is not None else
                 "; give --out to keep the whole run on disk")
        typer.echo(f"note: the recording keeps the last {kept:g} s in memory "
                   f"([realtime] ring_memory_mib = {rtc.ring_memory_mib:g}, ring_seconds = "
                   f"{rtc.ring_seconds:g}, {len(runner.channels)} channels every "
                   f"{sim.record_dt:g} s){where}", err=True)
    patience = wait if wait is not None else sc.link.connect_timeout
    stopper = _StopOnSignal(runner).install()
    out_file = OutputFile(out, "sil") if out is not None else None
    end_write = threading.Lock()  # held while the dashboard's ended run is written
    written = False  # --out holds the whole run already (written when the run ended)
    try:
        if use_link:
            h, p = runner.link.address
            peer = "rig" if hil else "controller"
            how = (f"--rig --port {p}" if hil else f"--scenario {scenario}"
                   + ("" if port is None else f" --port {p}"))
            typer.echo(f"plant listening on udp://{h}:{p}; start the {peer} now, e.g. "
                       f"`downhole sil-controller {how}`", err=True)
            if progress:
                ok = wait_with_countdown(runner.wait_for_controller, patience,
                                         what=f"the {peer} on udp://{h}:{p}")
            else:
                ok = runner.wait_for_controller(patience)
            if not ok:
                fail(f"no {peer} answered on udp://{h}:{p} within {patience:g} s "
                     "([link] connect_timeout or --wait)")
        if out_file is not None and not dashboard:
            out_file.begin()  # the previous result goes now: a killed run leaves none
        stopper.phase = "running"
        if dashboard:
            from downhole.sil.dashboard import serve_dashboard

            d = sc.dashboard

            def run_ended():
                """The run has used up its duration: write --out now (the dashboard may stay
                up for hours), then only browsing is left."""
                nonlocal written
                # the run is complete: a signal from now on only ends the dashboard, once
                # this write is done (the command waits for it)
                stopper.phase = "browsing"
                with end_write:
                    if out_file is not None:
                        try:
                            runner.recorder.finish()
                            runner.result().save(out)
                            out_file.commit()
                            written = True
                            typer.echo(f"wrote {out} (the run has ended)", err=True)
                        except Exception as exc:  # tried again when the command ends
                            typer.echo(f"error: writing {out} when the run ended failed "
                                       f"({type(exc).__name__}: {exc}); it is written again "
                                       "when the command ends", err=True)

            session = serve_dashboard(
                runner, host=d.host, port=d.port, token=token, duration=dur,
                publish_hz=d.publish_hz, allowed_origins=d.allowed_origins,
                allowed_hosts=d.allowed_hosts,
                token_source=d.token_file or f"{scenario} [dashboard] token",
                reference_limits=_reference_limits(sc), autostart=autostart,
                exit_after_run=exit_after_run,
                units=display if (units != "si" or unit) else d.units,
                on_run_start=out_file.begin if out_file is not None else None,
                on_run_end=run_ended)
            with end_write:  # a write of the ended run under way completes first
                pass
            if not session.started:
                raise _NeverStarted(stopper.signum)
            res = runner.result()
        elif progress:
            with RunProgress(runner, dur):
                res = runner.run(dur)
        else:
            res = runner.run(dur)
    except _NeverStarted as exc:
        stopper.restore()
        code = 128 + exc.args[0] if exc.args[0] is not None else 1
        typer.echo("error: the dashboard closed before the run was started (Start on the page, "
                   "or --autostart); nothing recorded or written", err=True)
        raise typer.Exit(code) from None
    except _Interrupted as exc:
        stopper.restore()
        typer.echo(f"error: interrupted ({signal.Signals(exc.args[0]).name}) while waiting for "
                   f"the {'rig' if hil else 'controller'}; nothing recorded or written",
                   err=True)
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
    _write_sil_result(res, out, None if written else out_file, stopper)
    if streamed is not None and (written or out_file is not None) and Path(out).exists():
        import shutil

        shutil.rmtree(streamed, ignore_errors=True)  # --out holds the whole run now


def _check_controller_choice(sc, scenario, cfile: str | None) -> None:
    """A controller file that would be loaded and never run is refused (one line): the
    scenario's controller is ``none`` (open loop) or remote (it connects over the link)."""
    file = cfile or sc.controller.file
    if not file:
        return
    given = f"--controller {cfile}" if cfile else f"[controller] file = {file!r}"
    if sc.controller.type == "none":
        fail(f"{given}, but {scenario} sets [controller] type = \"none\" (open loop): the "
             "controller would never run; set type = \"file\" in the scenario to run it "
             "closed loop, or drop the file to run open loop")
    if cfile and sc.controller.remote:
        fail(f"{given} runs in this process, but the controller of this run is remote "
             "(--remote or [controller] remote = true): give the file to the other end, "
             f"`downhole sil-controller --controller {cfile}`")


def _write_sil_result(res, out, out_file, stopper) -> None:
    """Write ``--out`` (the handlers still installed), then act on a signal that came."""
    try:
        if stopper.stopped_run:
            res.dataset.attrs["stopped_by"] = signal.Signals(stopper.signum).name
        if out_file is not None:
            try:
                res.save(out)  # a full disk: one line (main), the marker says why
            except BaseException as exc:
                out_file.fail(f"{type(exc).__name__}: {exc}")
                raise
            out_file.commit()
            typer.echo(f"wrote {out}", err=True)
    finally:
        stopper.restore()
    if stopper.signum is not None:
        typer.echo(f"stopped by {signal.Signals(stopper.signum).name} after "
                   f"{stopper.runner.stats.get('sim_s', 0.0):g} s simulated", err=True)
        raise typer.Exit(128 + stopper.signum)


def _reference_limits(sc) -> dict:
    r = sc.reference
    return {"axial": (r.axial_velocity_min, r.axial_velocity_max),
            "angular": (r.angular_velocity_min, r.angular_velocity_max)}


@app.command("sil-controller")
def sil_controller(port: int | None = typer.Option(
                       None, "--port", help="plant's UDP port (default: the scenario's [link] "
                                            "port, else 47600)"),
                   host: str | None = typer.Option(
                       None, "--host", help="plant's address (default: the scenario's [link] "
                                            "host, else 127.0.0.1)"),
                   controller: Path | None = typer.Option(
                       None, "--controller", help="DHP .json/.npz, or a .py with --allow-code"),
                   scenario: Path | None = typer.Option(
                       None, "--scenario", help="build the controller from this scenario"),
                   rig: bool = typer.Option(False, "--rig",
                                            help="act as the software HIL rig (bit + rock)"),
                   idle_timeout: float = typer.Option(5.0, "--idle-timeout",
                                                      help="stop after this long without data"),
                   wait: float | None = typer.Option(
                       None, "--wait", help="seconds to keep trying to reach the plant, with a "
                                            "countdown (default: the scenario's [link] "
                                            "connect_timeout, else 300)"),
                   allow_code: bool = typer.Option(
                       False, "--allow-code", help="allow a Python controller file to run"),
                   progress: bool = typer.Option(True, "--progress/--no-progress",
                                                 help="progress of design and waiting (stderr)"),
                   realtime: bool = typer.Option(True, "--realtime/--no-realtime",
                                                 help="try SCHED_FIFO while serving"),
                   link_key_file: Path | None = typer.Option(
                       None, "--link-key-file", help="the plant's shared link key (default: "
                       "$DOWNHOLE_LINK_KEY)")):
    """Run a controller (or the software rig) against a plant over the UDP link.

    The controller is built (a DHP scenario is designed, with progress) before the plant is
    contacted, so that it answers the plant's first observation at once."""
    from downhole.errors import DownholeInputError
    from downhole.sil.console import ServeProgress, wait_with_countdown
    from downhole.sil.controllers import load_controller_file
    from downhole.sil.link import ControllerClient

    if sum(x is not None for x in (controller, scenario)) + rig != 1:
        raise DownholeInputError("give exactly one of --controller FILE, --scenario FILE, --rig")
    _positive_seconds(wait, "--wait")
    _positive_seconds(idle_timeout, "--idle-timeout")
    sc = None
    if scenario is not None:
        from downhole.sil.scenario import build_from_scenario, check_code_allowed, load_sil_scenario

        sc = load_sil_scenario(scenario)  # validated before connecting: a bad file fails at once
        sc.controller.remote = False
        check_code_allowed(sc, allow_code=allow_code)
    if port is None:
        port = sc.link.port if sc is not None else 47600
    if host is None:
        host = sc.link.host if sc is not None else "127.0.0.1"
    if wait is None:
        wait = sc.link.connect_timeout if sc is not None else 300.0
    # 1. the controller first: a DHP design takes about a minute
    if rig:
        ctrl = None
    elif controller is not None:
        ctrl = load_controller_file(controller, allow_code=allow_code)
    else:
        if progress:
            _design_note(sc, "controller")
        _, ctrl = build_from_scenario(sc, allow_code=allow_code, progress=progress,
                                      source=str(scenario))
        if ctrl is None:
            raise DownholeInputError(f"{scenario}: the scenario defines no controller "
                                     f"([controller] type = {sc.controller.type!r})")
    # 2. then the plant
    client = ControllerClient(host, port, name="downhole sil-controller",
                              key_file=link_key_file)

    def attempt(seconds: float) -> bool:
        try:
            client.connect(timeout=seconds)
        except TimeoutError:
            return False
        return True

    try:
        try:
            if progress:
                ok = wait_with_countdown(attempt, wait, what=f"the plant on udp://{host}:{port}")
            else:
                ok = attempt(wait)
        except KeyboardInterrupt:
            fail("interrupted while waiting for the plant", code=130)
        if not ok:
            fail(f"no plant answered on udp://{host}:{port} within {wait:g} s (start `downhole "
                 "sil SCENARIO --remote` first, or give --wait)")
        layout = client.layout
        if rig:
            from downhole.sil.hil import SoftwareRig
            from downhole.string.hybrid import hybrid_model

            ctrl = SoftwareRig(hybrid_model("hybrid68").bit, layout.dt)
        # warm up (compile) before the first observation arrives
        try:
            ctrl.command(0.0, {n: 0.0 for n in layout.observations}, None)
        except Exception:
            pass
        ctrl.reset()
        typer.echo(f"connected: {len(layout.observations)} observations, commands "
                   f"{', '.join(layout.commands)}, dt = {layout.dt:g} s; serving...", err=True)
        if progress:
            with ServeProgress(client):
                n = client.serve(ctrl, idle_timeout=idle_timeout, realtime=realtime)
        else:
            n = client.serve(ctrl, idle_timeout=idle_timeout, realtime=realtime)
    finally:
        client.close()
    typer.echo(json.dumps({"commands_sent": n, "counters": client.counters}))
    if n == 0:
        fail(f"the plant sent no observation within --idle-timeout {idle_timeout:g} s: no "
             "command was sent", code=1)


@app.command("export-fmu")
def export_fmu(scenario: Path = typer.Argument(..., help="scenario TOML: a SIL scenario, a "
                                                     "scenario that describes the system ([well], "
                                                     "[string]) or a preset scenario that "
                                                     "`downhole simulate` runs"),
               out: Path = typer.Option(Path("plant.fmu"), "--out", help="FMU file to write"),
               fidelity: str | None = typer.Option(
                   None, "--fidelity", help="system scenarios: lumped4 | lumped12 | neutral | "
                   "fem | hybrid (default: the file's model.fidelity)"),
               units: str = UNITS_OPTION, unit: list[str] | None = UNIT_OPTION):
    """Build an FMI 2.0 co-simulation FMU of the scenario's plant (pythonfmu).

    The FMU carries the scenario's text, the fidelity and the options as JSON (no pickle, no
    code but downhole's FMU slave); every instance rebuilds the plant with the installed
    downhole and validates the scenario like any file. A doStep advances at most 60 s of
    simulated time (docs/sil.md).

    Every variable carries its SI unit and description; --units/--unit add FMI display units
    (e.g. rpm, klbf, kft*lbf with --units oilfield) that an importing tool shows; the values it
    exchanges stay SI.

    A SIL scenario's plant is its model.fidelity and model.preset; a preset scenario's plant is
    its model at its fidelity; a scenario that describes the system ([well], [string]) is
    exported at its model.fidelity or --fidelity, velocity-driven at every fidelity (inputs
    command_top_drive_axial_velocity and command_top_drive_angular_velocity).
    """
    from downhole.sil.fmu import export_fmu as _export

    check_output_path(out, kind="file")
    display = resolve_units(units, unit)
    path = _export(scenario, out, fidelity=fidelity, units=display)
    typer.echo(f"wrote {path}")
