"""The owner's receive work is bounded per step, keyed or not (issue 27, item 1), on 127.0.0.1.

A controller that owns the session and sends 10 valid commands per observation gets at most
``rx_max_commands`` (4) of them handled per step; the excess is read, dropped unparsed and
counted (``rx_dropped``, in the link's counters, the runtime's stats and the result's attrs).
The plant end is driven by hand and the checks are counts, not times.
"""

import threading
import time

import numpy as np
import pytest

from downhole.errors import DownholeInputError
from downhole.sil import ControllerClient, PlantLink, RealTimeRunner, build_plant
from downhole.sil.protocol import KEY_ENV, Layout, MsgType, pack

KEY = b"0123456789abcdef0123456789abcdef"
LAYOUT = Layout(1e-3, "sil", ("time", "bit_angular_velocity"),
                ("hook_load", "top_drive_angular_velocity"),
                {"hook_load": "N", "top_drive_angular_velocity": "rad/s"})


@pytest.fixture(autouse=True)
def _no_key_in_the_environment(monkeypatch):
    monkeypatch.delenv(KEY_ENV, raising=False)


def _connect(link, client):
    th = threading.Thread(target=client.connect, args=(5.0,), daemon=True)
    th.start()
    end = time.monotonic() + 10
    while th.is_alive() and time.monotonic() < end:  # hang guard only
        link.begin_step()
        link.poll()
        time.sleep(0.001)
    th.join()
    assert client.layout is not None and link.connected
    return client


def _burst(link, client, n):
    """One step: the plant sends an observation, the client answers it ``n`` times with valid
    commands (each with its own counter), then the plant reads its window."""
    ack = link.send_obs(0.0, np.zeros(2))
    got = client.receive(5.0)
    assert got is not None and got[0] == ack
    for i in range(n):
        client.sock.send(pack(MsgType.CMD, client.session, client._next(),
                              [1e5 + i, 10.0], ack=ack, signer=client._tx))
    link.begin_step()
    return link.wait_command(ack, time.monotonic() + 0.5)


@pytest.mark.parametrize("key", [KEY, None], ids=["keyed", "keyless"])
def test_an_owner_sending_ten_valid_commands_per_step_gets_four_handled(key):
    link = PlantLink(LAYOUT, key=key, rx_owner_budget=1.0)  # only the count binds here
    assert link.rx_max_commands == 4
    client = _connect(link, ControllerClient(*link.address, key=key))
    rx0 = link.counters["rx"]
    steps = 20
    handled = []
    for _ in range(steps):
        got = _burst(link, client, 10)
        assert got is not None  # the owner's answer is among the first handled
        assert link.step_rx_n <= 4
        handled.append(link.step_rx_n)
    # every datagram is accounted for: handled (at most 4 a step) or dropped unparsed
    for _ in range(3):  # whatever arrived after a window closed
        link.begin_step()
        link.poll()
        assert link.step_rx_n <= 4
        handled.append(link.step_rx_n)
    c = link.counters
    assert sum(handled) + c["rx_dropped"] == 10 * steps
    assert c["rx_dropped"] >= 6 * steps - 3 * 4
    assert c["rx"] - rx0 == sum(handled)  # a dropped datagram was never parsed
    assert c["rx_capped"] >= steps - 3
    assert c["auth_failed"] == c["malformed"] == 0
    client.close()
    link.close()


def test_a_well_behaved_owner_loses_nothing():
    link = PlantLink(LAYOUT, key=KEY)
    client = _connect(link, ControllerClient(*link.address, key=KEY))
    capped0 = link.counters["rx_capped"]  # the handshake may have hit the listening bound
    for i in range(20):
        got = _burst(link, client, 1)
        assert got.tolist() == [1e5, 10.0], i
    assert link.counters["rx_dropped"] == 0 and link.counters["rx_capped"] == capped0
    client.close()
    link.close()


def test_junk_from_the_owner_beyond_the_count_is_dropped_and_the_answer_still_taken():
    link = PlantLink(LAYOUT, key=KEY, rx_owner_budget=1.0)
    client = _connect(link, ControllerClient(*link.address, key=KEY))
    ack = link.send_obs(0.0, np.zeros(2))
    assert client.receive(5.0)[0] == ack
    for _ in range(20):  # not even framed: parsed only if within the count
        client.sock.send(b"x" * 64)
    client.sock.send(pack(MsgType.CMD, client.session, client._next(), [2e5, 11.0], ack=ack,
                          signer=client._tx))
    link.begin_step()
    link.poll()
    # 4 handled (malformed), the other 16 read and dropped unparsed, the answer, claimed by
    # its header, left for the next window
    c = link.counters
    assert link.step_rx_n == 4 and c["malformed"] == 4 and c["rx_dropped"] == 16
    link.begin_step()
    assert link.wait_command(ack, time.monotonic() + 0.5).tolist() == [2e5, 11.0]
    client.close()
    link.close()


def test_the_read_bounds_are_checked():
    for kw in ({"rx_max_commands": 0}, {"rx_max_datagrams": 0}):
        with pytest.raises(DownholeInputError, match=next(iter(kw))):
            PlantLink(LAYOUT, **kw)


class _Chatty(ControllerClient):
    """A keyed controller that sends every command 10 times (valid each time)."""

    def send_command(self, ack, sim_time, echo, values):
        for _ in range(10):
            super().send_command(ack, sim_time, echo, values)


def test_the_runtime_reports_the_dropped_commands_in_stats_and_result():
    plant = build_plant("lumped")
    rt = RealTimeRunner(plant, link=("127.0.0.1", 0), link_key=KEY, paced=False,
                        record_every=10, command_timeout=0.5)
    client = _Chatty(*rt.link.address, key=KEY)
    from downhole.sil import pi_controller_for

    th = threading.Thread(target=lambda: (client.connect(10.0),
                                          client.serve(pi_controller_for(plant),
                                                       idle_timeout=60.0)), daemon=True)
    th.start()
    assert rt.wait_for_controller(20.0)
    # the client waits out the plant's warm-up (which compiles its kernel on a first run: an
    # idle timeout of a few seconds once ended the client there, and every step was late)
    res = rt.run(0.2)
    rt.close()
    th.join(10)
    import json

    stats = json.loads(res.dataset.attrs["stats"])
    counters = json.loads(res.dataset.attrs["link_counters"])
    assert stats["steps"] == 200
    # the copies of an answer that arrive after it are dropped by their header in the next
    # step: the chatty owner's next answers still get through (a late one waits 0.5 s)
    assert stats["late_commands"] < 20
    assert stats["rx_dropped"] > 0
    assert stats["rx_dropped"] == rt.stats["rx_dropped"] <= counters["rx_dropped"]
    # at most 4 of the owner's datagrams handled per step: the rest dropped
    assert counters["rx"] <= 4 * (stats["steps"] + 100)
