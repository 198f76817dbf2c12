"""CLI of the SIL testbed: ``downhole sil``, ``downhole sil-controller``, ``downhole export-fmu``.

- ``downhole sil SCENARIO.toml [--controller FILE] [--dashboard] [--duration S] [--out F.nc]``
  runs the scenario in real time (or unpaced with ``--unpaced``); with ``[controller] remote =
  true`` (or ``--remote``) it waits for a controller on the UDP link.
- ``downhole sil-controller --port P [--host H] (--controller FILE | --scenario S.toml)``
  is the controller end: it connects to a running plant and answers every observation.
- ``downhole export-fmu SCENARIO.toml --out plant.fmu`` builds an FMI 2.0 co-simulation FMU.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

import typer

from downhole.cli import app, fail

__all__ = ["sil", "sil_controller", "export_fmu"]


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
    plant, ctrl = build_from_scenario(sc, controller_file=str(controller) if controller else None)
    rtc = sc.runtime
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
    try:
        if use_link:
            h, p = runner.link.address
            typer.echo(f"plant listening on udp://{h}:{p}; waiting for the "
                       f"{'rig' if hil else 'controller'}...", err=True)
            if not runner.wait_for_controller(sc.link.connect_timeout):
                fail(f"no controller connected within {sc.link.connect_timeout:g} s")
        if dashboard:
            from downhole.sil.dashboard import serve_dashboard

            serve_dashboard(runner, host=sc.dashboard.host, port=sc.dashboard.port,
                            token=sc.dashboard.token, duration=dur,
                            publish_hz=sc.dashboard.publish_hz)
            res = runner.result()
        else:
            res = runner.run(dur)
    finally:
        runner.close()
    typer.echo(json.dumps({"stats": runner.stats, "scheduler": runner.scheduler,
                           "link": runner.link.counters if runner.link else None,
                           "events": runner.event_count}, indent=1))
    if out is not None:
        res.save(out)
        typer.echo(f"wrote {out}", err=True)


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
    sc = None
    if scenario is not None:  # validated before connecting: a bad file fails at once
        from downhole.sil.scenario import load_sil_scenario

        sc = load_sil_scenario(scenario)
    client = ControllerClient(host, port, name="downhole sil-controller")
    layout = client.connect(timeout=30.0)
    if rig:
        from downhole.sil.hil import SoftwareRig
        from downhole.string.hybrid import hybrid_model

        ctrl = SoftwareRig(hybrid_model("hybrid68").bit, layout.dt)
    elif controller is not None:
        ctrl = load_controller_file(controller)
    else:
        from downhole.sil.scenario import build_from_scenario

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

    path = _export(scenario, out)
    typer.echo(f"wrote {path}")
