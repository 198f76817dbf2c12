"""Runtime properties without a network: bounded memory, chunked recording, pacing arithmetic,
HIL coupling (in-process and over the link), scenario validation."""

import threading
import tracemalloc

import numpy as np
import pytest

from downhole.errors import DownholeInputError, ScenarioError
from downhole.sil import (
    ControllerClient,
    RealTimeRunner,
    RingRecorder,
    build_plant,
    load_chunks,
    pi_controller_for,
)
from downhole.sil.scenario import parse_sil_scenario


def test_ring_recorder_keeps_the_newest_rows_and_chunks_everything(tmp_path):
    rec = RingRecorder(("time", "x"), capacity=5, chunk_dir=tmp_path, chunk_rows=4)
    for i in range(13):
        rec.append(np.array([i * 0.1, i]))
    rec.flush()
    assert rec.rows()[:, 1].tolist() == [8, 9, 10, 11, 12]
    full = load_chunks(tmp_path)
    assert full["x"].tolist() == list(range(13))


def test_long_unpaced_run_does_not_grow_memory():
    plant = build_plant("lumped")
    rt = RealTimeRunner(plant, pi_controller_for(plant), paced=False, record_every=1,
                        ring_rows=2000)
    rt.run(1.0)  # warm: ring filled, caches built
    tracemalloc.start()
    rt.run(2.0, reset=False)
    a = tracemalloc.get_traced_memory()[0]
    rt.run(8.0, reset=False)  # 4x more steps
    b = tracemalloc.get_traced_memory()[0]
    tracemalloc.stop()
    print(f"\nmemory after 3 s: {a / 1e3:.1f} kB, after 8 s more: {b / 1e3:.1f} kB")
    assert b - a < 50e3
    assert rt.recorder.rows().shape[0] == 2000
    assert rt.stats["steps"] == round(11 / plant.dt)  # stats accumulate over run(reset=False)


def test_unpaced_real_time_factor_and_consistent_time():
    plant = build_plant("hybrid68")
    rt = RealTimeRunner(plant, pi_controller_for(plant), paced=False, record_every=100)
    res = rt.run(1.0)
    np.testing.assert_allclose(np.diff(res.time), 0.1, rtol=1e-9)
    assert rt.stats["real_time_factor"] > 0 and rt.stats["deadline_misses"] == 0


def test_hil_rig_over_the_link_matches_the_rig_in_process():
    """Fig. 6.9: the rig gets the last node's velocity and returns the bit's. Over the link,
    unpaced, lock-step, it must give the same run as the rig called directly; the coupled
    string and bit move together on average (spring coupling: no drift)."""
    from downhole.sil.hil import SoftwareRig, build_hil_plant

    T = 8.0
    plant = build_hil_plant("hybrid24", surface_torque=15e3)
    # direct: plant and rig stepped by hand
    rig = SoftwareRig(plant.rig_bit, plant.dt)
    obs = plant.reset()
    ref_v = []
    for k in range(int(T / plant.dt)):
        b = rig.command(k * plant.dt, obs)
        cmd = dict(plant.default_command(), **b)
        obs = plant.step(cmd)
        ref_v.append((obs["bit_axial_velocity"], obs["last_node_axial_velocity"],
                      obs["bit_angular_velocity"], obs["last_node_angular_velocity"]))
    ref_v = np.array(ref_v)
    # over the link
    T = 2.0
    rt = RealTimeRunner(plant, link=("127.0.0.1", 0), hil=True, paced=False, record_every=1,
                        command_timeout=1.0)
    client = ControllerClient(*rt.link.address)
    th = threading.Thread(target=lambda: (client.connect(5.0),
                                          client.serve(SoftwareRig(plant.rig_bit, plant.dt),
                                                       idle_timeout=2.0)), daemon=True)
    th.start()
    assert rt.wait_for_controller(10.0)
    res = rt.run(T)  # unpaced, lock-step (1 s wait budget per command)
    rt.close()
    th.join(5)
    assert rt.link.counters["late"] == 0
    n = res.time.size - 1
    np.testing.assert_allclose(res["bit_axial_velocity"][1:], ref_v[:n, 0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(res["bit_angular_velocity"][1:], ref_v[:n, 2], rtol=0, atol=1e-12)
    late = slice(len(ref_v) // 4, None)
    assert ref_v[late, 2].mean() == pytest.approx(ref_v[late, 3].mean(), rel=0.02)
    assert ref_v[late, 2].mean() > 1.0  # the torque turns the bit


def test_scenario_errors_name_the_field():
    with pytest.raises(ScenarioError, match="simulation.dt"):
        parse_sil_scenario({"simulation": {"dt": "-1 ms"}})
    with pytest.raises(ScenarioError, match="model.interface"):
        parse_sil_scenario({"controller": {"type": "dhp"}})
    with pytest.raises(ScenarioError, match="model.colour"):
        parse_sil_scenario({"model": {"colour": "red"}})
    sc = parse_sil_scenario({"simulation": {"dt": "0.5 ms", "duration": "2 s"},
                             "reference": {"angular_velocity": "120 rpm"}})
    assert sc.simulation.dt == 5e-4
    assert sc.reference.angular_velocity == pytest.approx(4 * np.pi)
    # the older dialect: one line naming the key that replaces it
    for old, new in ((({"runtime": {"dt": 1e-3}}), "simulation.dt"),
                     (({"plant": {"model": "hybrid68"}}), "model.fidelity"),
                     (({"controller": {"kind": "pi"}}), "controller.type"),
                     (({"name": "x"}), "title"),
                     (({"reference": {"axial": 0.01}}), "reference.axial_velocity")):
        with pytest.raises(ScenarioError, match=f"renamed: use {new}"):
            parse_sil_scenario(old)
    # epsilon can be set in a SIL file: the plant's bit is the preset's with [bit] over it
    from downhole.sil.scenario import build_from_scenario

    sc = parse_sil_scenario({"model": {"fidelity": "lumped4"}, "bit": {"epsilon": "90 MPa"},
                             "controller": {"type": "none"}})
    plant, _ = build_from_scenario(sc)
    assert plant.plant.model.bit.epsilon == pytest.approx(90e6)
    with pytest.raises(ScenarioError, match="bit.epsilon"):
        parse_sil_scenario({"bit": {"epsilon": "-1 MPa"}})
    with pytest.raises(DownholeInputError, match="wait_fraction"):
        RealTimeRunner(build_plant("lumped"), wait_fraction=1.5)


class _Stall:
    """PI that stalls once for ``stall`` s at step ``at`` (a GC pause, a slow solver...)."""

    def __init__(self, inner, at, stall):
        self.inner, self.at, self.stall = inner, at, stall

    def reset(self):
        self.inner.reset()

    def command(self, t, obs, ref):
        import time

        if abs(t - self.at) < 1e-9:
            time.sleep(self.stall)
        return self.inner.command(t, obs, ref)


class _VirtualClock:
    """A deterministic stand-in for the runtime's wall clock: time advances only when the loop
    waits (``sleep_until``) or when the controller spends time (``spend``)."""

    def __init__(self):
        self.now = 1000.0

    def monotonic(self):
        return self.now

    def sleep_until(self, t, spin):
        self.now = max(self.now, t)

    def spend(self, s):
        self.now += s


class _VirtualStall:
    """PI that costs ``cost`` s of virtual time per step and ``stall`` s once at ``at``."""

    def __init__(self, inner, clock, at, stall, cost=2e-4):
        self.inner, self.clock, self.at, self.stall, self.cost = inner, clock, at, stall, cost

    def reset(self):
        self.inner.reset()

    def command(self, t, obs, ref):
        self.clock.spend(self.stall if abs(t - self.at) < 1e-9 else self.cost)
        return self.inner.command(t, obs, ref)


@pytest.mark.parametrize("stall, resyncs", [(0.02, 0), (0.12, 1)])
def test_falling_behind_catches_up_or_resyncs_on_a_virtual_clock(stall, resyncs, monkeypatch):
    """The pacing logic, deterministic: the runtime's clock is replaced by a virtual one in which
    each step costs 0.2 ms and the step at 0.3 s stalls. A 20 ms stall (below max_lag = 50 ms)
    is caught up in stall / (dt - cost) = 25 steps and later steps are on time, wall = simulated
    time; a 120 ms stall re-anchors the clock once, wall = simulated time + stall. The same
    properties on the real clock are the paced test below (make test-slow)."""
    import types

    from downhole.sil import runtime as rt_mod

    clock = _VirtualClock()
    monkeypatch.setattr(rt_mod, "time", types.SimpleNamespace(monotonic=clock.monotonic))
    monkeypatch.setattr(rt_mod, "sleep_until", clock.sleep_until)
    plant = build_plant("lumped")
    rt = RealTimeRunner(plant, _VirtualStall(pi_controller_for(plant), clock, 0.3, stall),
                        record_every=1, max_lag=0.05, realtime=False)
    res = rt.run(0.8)
    st = rt.stats
    np.testing.assert_allclose(res.time, np.arange(801) * 1e-3, atol=1e-12)  # no step skipped
    assert st["steps"] == 800 and st["resyncs"] == resyncs
    lag = res["wall_lag"]
    # the stalled step (the 301st) finished late by the stall less the rest of its period
    assert lag[301] == pytest.approx(stall - 1e-3, abs=1e-9)
    assert st["overruns"] == 1
    if resyncs == 0:
        # caught up at 0.8 ms per step: ceil(19 ms / 0.8 ms) = 24 late steps, then on time
        assert st["deadline_misses"] == 24
        assert np.all(lag[301 + 24:] <= 0) and np.all(lag[:301] <= 0)
        assert st["wall_s"] == pytest.approx(0.8 - 1e-3 + 2e-4, abs=1e-9)
    else:  # re-anchored once by the lag (stall - dt): wall time = last start + cost + lag
        assert st["deadline_misses"] == 1
        assert [e["kind"] for e in rt.events].count("resync") == 1
        assert np.all(lag[302:] <= 0)
        assert st["wall_s"] == pytest.approx(0.8 - 1e-3 + 2e-4 + (stall - 1e-3), abs=1e-9)


@pytest.mark.slow  # paced on the wall clock: a loaded 2-core machine misses deadlines
@pytest.mark.realtime
@pytest.mark.parametrize("stall, resyncs", [(0.02, 0), (0.12, 1)])
def test_falling_behind_catches_up_or_resyncs_and_keeps_simulated_time(stall, resyncs):
    plant = build_plant("lumped")
    rt = RealTimeRunner(plant, _Stall(pi_controller_for(plant), 0.3, stall), record_every=1,
                        max_lag=0.05)
    res = rt.run(0.8)
    st = rt.stats
    print(f"\nstall {stall * 1e3:.0f} ms: misses {st['deadline_misses']}, resyncs "
          f"{st['resyncs']}, max lag {1e3 * st['max_lag_s']:.1f} ms, wall {st['wall_s']:.3f} s")
    np.testing.assert_allclose(res.time, np.arange(801) * 1e-3, atol=1e-12)  # no step skipped
    assert st["steps"] == 800 and st["resyncs"] == resyncs
    assert st["overruns"] >= 1 and st["deadline_misses"] >= 1
    lag = res["wall_lag"]
    assert lag[301] >= stall - 2e-3  # the stalled step finished late by the stall
    if resyncs == 0:  # caught up: later steps on time again, wall time = simulated time
        assert np.all(lag[-100:] <= 0) and st["wall_s"] == pytest.approx(0.8, abs=0.02)
    else:  # re-anchored: a constant offset, wall time longer by the stall
        assert [e["kind"] for e in rt.events].count("resync") == 1
        assert st["wall_s"] == pytest.approx(0.8 + stall, abs=0.03)
