"""Real-time runtime over the UDP link with the controller in its own process.

Checks against independent references: the offline closed loop run by the DHP package's own
``run_on_plant`` (or the plant stepped by hand for the PI), the safety action's documented
timing, and counters for injected bad packets. Timing figures (deadline-miss fraction, late
commands) are printed and asserted only against the issue's bound (< 5 % misses)."""

import socket
import threading
import time

import numpy as np
import pytest

from downhole.sil import (
    ControllerClient,
    RealTimeRunner,
    SafetyPolicy,
    build_plant,
    pi_controller_for,
)
from downhole.sil.protocol import MsgType, pack
from downhole.sil.testing import ControllerProcess, ch6_dhp, free_port

#: Paced wall-clock tests: `make test` runs them alone after the parallel run (a loaded core
#: misses deadlines).
pytestmark = pytest.mark.realtime


def _nrms(a, b):
    n = min(a.size, b.size)
    return float(np.sqrt(np.mean((a[:n] - b[:n]) ** 2)) / np.sqrt(np.mean(b[:n] ** 2)))


def _offline_pi(plant, ctrl, duration, every=10):
    """The same loop stepped by hand (no runtime): command from obs k, held over step k."""
    obs = plant.reset()
    ctrl.reset()
    out = {"bit_axial_velocity": [obs["bit_axial_velocity"]],
           "bit_angular_velocity": [obs["bit_angular_velocity"]]}
    ref = {"axial": 0.01, "angular": 20.0}
    for k in range(int(round(duration / plant.dt))):
        o = dict(obs, reference_axial_velocity=0.01, reference_angular_velocity=20.0)
        obs = plant.step(ctrl.command(k * plant.dt, o, ref))
        if (k + 1) % every == 0:
            for c, trace in out.items():
                trace.append(obs[c])
    return {c: np.array(v) for c, v in out.items()}


def _write_pi_file(tmp_path):
    f = tmp_path / "pi_ctrl.py"
    f.write_text("from downhole.sil import build_plant, pi_controller_for\n"
                 "def make_controller(plant):\n"
                 "    return pi_controller_for(plant or build_plant('hybrid68'))\n")
    return f


def test_lock_step_3s_pi_over_udp_in_a_separate_process_equals_the_offline_loop(tmp_path):
    """The UDP path without the wall clock: the controller in its own process, the runner
    unpaced and waiting up to 2 s for each command (lock-step). No command is late, and the
    loop equals the plant and controller stepped by hand (the same command from the same
    observation) to round-off. The paced run with its deadline bound is the next test."""
    T = 3.0
    plant = build_plant("hybrid68", interface="surface")
    port = free_port()
    rt = RealTimeRunner(plant, link=("127.0.0.1", port), record_every=10, paced=False,
                        command_timeout=2.0)
    with ControllerProcess(port, ["--controller", _write_pi_file(tmp_path)]) as cp:
        assert rt.wait_for_controller(120.0), "controller process did not connect"
        res = rt.run(T)
        rt.close()
        cp.wait(20)
    st = rt.stats
    assert st["steps"] == 3000 and res.time[-1] == pytest.approx(T)
    assert st["late_commands"] == 0  # every step waited for its own command
    assert rt.link.counters["malformed"] == 0 and rt.link.counters["lost"] == 0
    off = _offline_pi(build_plant("hybrid68", interface="surface"),
                      pi_controller_for(plant), T)
    for ch in ("bit_axial_velocity", "bit_angular_velocity"):
        np.testing.assert_allclose(res[ch], off[ch], rtol=1e-9, atol=1e-12)


@pytest.mark.slow  # paced on the wall clock: a loaded 2-core machine misses deadlines
def test_realtime_3s_pi_over_udp_in_a_separate_process(tmp_path):
    """Fast variant of the 20 s test: same properties, PI controller (no DHP training)."""
    T = 3.0
    plant = build_plant("hybrid68", interface="surface")
    port = free_port()
    rt = RealTimeRunner(plant, link=("127.0.0.1", port), record_every=10)
    with ControllerProcess(port, ["--controller", _write_pi_file(tmp_path)]) as cp:
        assert rt.wait_for_controller(120.0), "controller process did not connect"
        res = rt.run(T)
        rt.close()
        cp.wait(20)
    st = rt.stats
    print(f"\n3 s PI over UDP: steps {st['steps']}, deadline misses {st['deadline_misses']} "
          f"({100 * st['deadline_miss_fraction']:.2f} %), overruns {st['overruns']}, late "
          f"commands {st['late_commands']}, max lag {1e3 * st['max_lag_s']:.2f} ms, "
          f"scheduler {rt.scheduler}, link {rt.link.counters}")
    assert st["steps"] == 3000 and res.time[-1] == pytest.approx(T)
    assert st["deadline_miss_fraction"] < 0.05
    off = _offline_pi(build_plant("hybrid68", interface="surface"),
                      pi_controller_for(plant), T)
    for ch in ("bit_axial_velocity", "bit_angular_velocity"):
        err = _nrms(res[ch], off[ch])
        print(f"{ch}: normalized RMS difference to offline {err:.2e}")
        assert err < 0.02


@pytest.mark.slow
def test_realtime_20s_dhp_on_hybrid68_over_udp(tmp_path):
    """Done-means: 20 s at 1 kHz, 68-state hybrid, 24-state DHP in a separate process."""
    from downhole.control.dhp import run_on_plant
    from downhole.control.dhp.directional import DirectionalStatePlant
    from downhole.string.hybrid import hybrid_model

    T = 20.0
    design, ctrl = ch6_dhp("step", horizon=T)
    ctrl.save(tmp_path / "dhp")
    plant = build_plant("hybrid68", interface="state", design_model=design)
    port = free_port()
    rt = RealTimeRunner(plant, link=("127.0.0.1", port), record_every=10)
    with ControllerProcess(port, ["--controller", tmp_path / "dhp.json"]) as cp:
        assert rt.wait_for_controller(120.0)
        res = rt.run(T)
        rt.close()
        cp.wait(20)
    st = rt.stats
    print(f"\n20 s DHP over UDP: deadline misses {st['deadline_misses']} / {st['steps']} "
          f"({100 * st['deadline_miss_fraction']:.2f} %), late commands {st['late_commands']}, "
          f"max lag {1e3 * st['max_lag_s']:.2f} ms, scheduler {rt.scheduler}")
    assert st["steps"] == 20000
    assert st["deadline_miss_fraction"] < 0.05
    off = run_on_plant(ctrl, DirectionalStatePlant(hybrid_model("hybrid68"), design, 1e-3), T,
                       record_every=10)
    for ch in ("bit_axial_velocity", "bit_angular_velocity"):
        err = _nrms(res[ch], off[ch])
        print(f"{ch}: normalized RMS difference to offline {err:.2e}")
        assert err < 0.02
        sel = res.time >= 10.0
        assert abs(res[ch][sel].mean() / off[ch][sel].mean() - 1) < 0.02


def test_killed_controller_triggers_the_safe_action_and_the_plant_keeps_running(tmp_path):
    plant = build_plant("hybrid68", interface="surface")
    port = free_port()
    pol = SafetyPolicy(timeout=0.1, hold=0.2, ramp=0.5)
    rt = RealTimeRunner(plant, link=("127.0.0.1", port), record_every=10, safety=pol)
    with ControllerProcess(port, ["--controller", _write_pi_file(tmp_path)]) as cp:
        assert rt.wait_for_controller(120.0)
        killed = {}

        def killer():
            time.sleep(1.0)
            killed["wall"] = time.monotonic()
            cp.proc.kill()

        th = threading.Thread(target=killer)
        th.start()
        res = rt.run(2.5)
        th.join()
        rt.close()
    ev = list(rt.events)
    kinds = [e["kind"] for e in ev]
    assert rt.stats["steps"] == 2500, "the plant must keep running"
    assert kinds.count("controller_timeout") == 1 and "safe_state_reached" in kinds
    to = next(e for e in ev if e["kind"] == "controller_timeout")
    detect = to["wall"] - killed["wall"]
    print(f"\ncontroller killed -> timeout detected after {1e3 * detect:.1f} ms "
          f"(timeout {1e3 * pol.timeout:.0f} ms) at t = {to['time']:.3f} s")
    assert 0 < detect <= pol.timeout + 0.05
    reached = next(e for e in ev if e["kind"] == "safe_state_reached")
    assert reached["time"] == pytest.approx(to["time"] + pol.hold + pol.ramp, abs=0.01)
    safe = plant.safe_command()
    t = res.time
    last = t > reached["time"] + 0.02
    assert np.all(res["safe_action"][last] == 1.0)
    assert np.allclose(res["command_hook_load"][last], safe["hook_load"])
    assert np.allclose(res["command_top_drive_angular_velocity"][last], 0.0)
    # during the hold the last command is kept, then a linear ramp
    hold = (t > to["time"] + 0.01) & (t < to["time"] + pol.hold - 0.01)
    held = res["command_hook_load"][hold]
    assert np.ptp(held) == 0.0
    mid = np.argmin(np.abs(t - (to["time"] + pol.hold + pol.ramp / 2)))
    assert res["command_hook_load"][mid] == pytest.approx(0.5 * (held[0] + safe["hook_load"]),
                                                         rel=1e-3)
    assert "safe_action" in res and "events" in res.attrs


def test_malformed_duplicated_reordered_packets_are_counted_and_ignored():
    plant = build_plant("lumped")
    port = free_port()
    rt = RealTimeRunner(plant, link=("127.0.0.1", port), record_every=10,
                        safety=SafetyPolicy(timeout=1.0))
    client = ControllerClient("127.0.0.1", port)
    ctrl = pi_controller_for(plant)
    stop = threading.Event()
    sent = {"garbage": 0, "again": 0}

    def bad_client():
        client.connect(10.0)
        junk = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        held = None
        i = 0
        while not stop.is_set():
            got = client.receive(0.5)
            if got is None or got == "bye":
                continue
            seq, t, stamp, vals = got
            obs = dict(zip(client.layout.observations, vals.tolist()))
            cmd = ctrl.command(max(t, 0.0), obs, None)
            out = [cmd[c] for c in client.layout.commands]
            i += 1
            pkt = pack(MsgType.CMD, client.session, client._next(), out, ack=seq, sim_time=t,
                       echo=stamp)
            if i % 10 == 0 and held is None:  # hold this one back: it arrives after the next
                held = pkt
                continue
            client.sock.send(pkt)
            if held is not None:
                client.sock.send(held)  # reordered: older sequence number than the last
                held = None
                sent["again"] += 1
            if i % 7 == 0:
                client.sock.send(pkt)  # duplicate
                sent["again"] += 1
            if i % 5 == 0:
                for bad in (b"garbage", b"DHSL" + bytes(60), np.random.bytes(100)):
                    junk.sendto(bad, ("127.0.0.1", port))
                    sent["garbage"] += 1
        junk.close()

    th = threading.Thread(target=bad_client, daemon=True)
    th.start()
    assert rt.wait_for_controller(10.0)
    rt.run(1.0)
    stop.set()
    th.join(5)
    rt.close()
    c = rt.link.counters
    print("\nlink counters:", c)
    assert c["malformed"] >= 0.9 * sent["garbage"] > 0
    # the duplicates and the reordered commands: counted as such when they are parsed, or, as
    # they answer an earlier observation than the one awaited by the time they are read,
    # dropped unparsed by their header (rx_dropped; issue 27)
    again = c["duplicates"] + c["reordered"] + c["stale"] + c["rx_dropped"]
    assert again >= 0.8 * sent["again"] > 0
    assert rt.stats["steps"] == 1000 and rt.stats["safe_actions"] == 0


def test_in_process_dhp_runs_unchanged_and_matches_run_on_plant():
    """The same controller object offline (run_on_plant) and in the runtime (unpaced)."""
    from downhole.control.dhp import run_on_plant
    from downhole.control.dhp.directional import DirectionalStatePlant
    from downhole.string.hybrid import hybrid_model

    design, ctrl = ch6_dhp("step", horizon=2.0, samples=50)
    plant = build_plant("hybrid68", interface="state", design_model=design)
    res = RealTimeRunner(plant, ctrl, paced=False, record_every=10).run(2.0)
    off = run_on_plant(ctrl, DirectionalStatePlant(hybrid_model("hybrid68"), design, 1e-3), 2.0,
                       record_every=10)
    for ch in ("bit_axial_velocity", "bit_angular_velocity", "wob"):
        np.testing.assert_allclose(res[ch], off[ch], rtol=1e-12, atol=1e-12)
