"""A keyed UDP link is replay-proof (issue 24, item 4), on 127.0.0.1.

Real datagrams of a keyed session are captured on the controller's socket (HELLO, AUTH, CMD,
BYE) and on its receiving side (CHALLENGE, LAYOUT, OBS), then replayed (a) from another address
or port, (b) from the owner's own address after the session and (c) within the session
(a counter already used): every one is refused, counted in the link's statistics and changes
nothing; a fresh session still works, a wrong key is refused, and a few hundred truncated or
garbled variants of the captured datagrams are refused. The plant end is driven by hand
(deterministic, bounded loops); only the last test runs the runtime, unpaced and lock-step.
"""

import random
import socket
import struct
import threading
import time
import zlib

import numpy as np
import pytest

from downhole.sil import (
    ControllerClient,
    PlantLink,
    RealTimeRunner,
    build_plant,
    pi_controller_for,
)
from downhole.sil.protocol import (
    KEY_ENV,
    NONCE_SIZE,
    VERSION,
    Layout,
    MsgType,
    pack,
    parse,
)

KEY = b"0123456789abcdef0123456789abcdef"
LAYOUT = Layout(1e-3, "sil", ("time", "bit_angular_velocity"),
                ("hook_load", "top_drive_angular_velocity"),
                {"hook_load": "N", "top_drive_angular_velocity": "rad/s"})


@pytest.fixture(autouse=True)
def _no_key_in_the_environment(monkeypatch):
    monkeypatch.delenv(KEY_ENV, raising=False)


class _Tap:
    """The client's UDP socket, recording every datagram sent and received (the capture)."""

    def __init__(self, sock):
        self.sock = sock
        self.sent: list[bytes] = []
        self.received: list[bytes] = []

    def send(self, data):
        self.sent.append(bytes(data))
        return self.sock.send(data)

    def recv(self, n):
        data = self.sock.recv(n)
        self.received.append(data)
        return data

    def fileno(self):
        return self.sock.fileno()

    def getsockname(self):
        return self.sock.getsockname()

    def close(self):
        self.sock.close()


def _of(captured, mtype):
    return [d for d in captured if parse(d)[0].type == mtype]


def _replayable(cap):
    """The captured datagrams of the controller worth replaying: every HELLO, the AUTH that
    opened the session (a retried handshake may have sent an earlier one), every CMD and BYE."""
    return (*_of(cap, MsgType.HELLO), _of(cap, MsgType.AUTH)[-1], *_of(cap, MsgType.CMD),
            *_of(cap, MsgType.BYE))


def _pump(link, until, timeout=2.0):
    """Poll the link until ``until()`` holds (bounded)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        link.begin_step()
        link.poll()
        if until():
            return True
        time.sleep(0.002)
    return False


def _settle(link, n=20):
    """Poll the link a bounded number of times (what was sent on loopback has arrived)."""
    for _ in range(n):
        link.begin_step()
        link.poll()
        time.sleep(0.002)


def _client(link, key=KEY, **kw):
    client = ControllerClient(*link.address, key=key, **kw)
    client.sock = _Tap(client.sock)
    return client


def _connect(link, client):
    th = threading.Thread(target=client.connect, args=(2.0,), daemon=True)
    th.start()
    assert _pump(link, lambda: not th.is_alive())
    th.join()
    assert client.layout is not None and link.connected
    return client


def _exchange(link, client, values=(1e5, 10.0)):
    """One observation answered by the client's real send path; what the plant accepted."""
    ack = link.send_obs(0.0, np.zeros(2))
    got = client.receive(1.0)
    assert got is not None and got[0] == ack
    client.send_command(ack, 0.0, got[2], list(values))
    return link.wait_command(ack, time.monotonic() + 0.3)


def _sock(host="127.0.0.1", port=0):
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    s.bind((host, port))
    s.settimeout(0.05)
    return s


def _silent(s):
    """True when nothing came back to ``s`` (no challenge, no layout, no session id)."""
    try:
        s.recv(9000)
    except TimeoutError:
        return True
    return False


def _session(link):
    """A keyed session with three commands exchanged; returns the client (its capture)."""
    client = _connect(link, _client(link))
    for v in (1e5, 2e5, 3e5):
        assert _exchange(link, client, (v, 10.0)).tolist() == [v, 10.0]
    return client


# ------------------------------------------------------------------ the handshake
def test_a_keyed_session_is_bound_to_fresh_nonces_from_both_ends():
    link = PlantLink(LAYOUT, key=KEY)
    a = _session(link)
    hello, auth = _of(a.sock.sent, MsgType.HELLO)[-1], _of(a.sock.sent, MsgType.AUTH)[-1]
    challenge = _of(a.sock.received, MsgType.CHALLENGE)[-1]
    layout = _of(a.sock.received, MsgType.LAYOUT)[-1]
    h, c, au = parse(hello)[0], parse(challenge)[0], parse(auth)[0]
    nc = h.values.tobytes()[:NONCE_SIZE]
    assert c.values.tobytes()[:NONCE_SIZE] == nc  # the challenge answers this HELLO
    assert au.values.tobytes() == c.values.tobytes()  # AUTH is over both nonces
    assert h.session == 0 and c.session == au.session == parse(layout)[0].session == a.session
    assert a.session == link.session and link.counters["replayed"] == 0
    # a second session of the same client: new nonces, new session id, new keys
    src = a.sock.getsockname()
    a.close()
    _settle(link)
    b = _connect(link, _client(link, bind=src))
    assert b.session != a.session
    nb = parse(_of(b.sock.sent, MsgType.HELLO)[-1])[0].values.tobytes()[:NONCE_SIZE]
    sb = parse(_of(b.sock.received, MsgType.CHALLENGE)[-1])[0].values.tobytes()[NONCE_SIZE:]
    assert nb != nc and sb != c.values.tobytes()[NONCE_SIZE:]
    assert _exchange(link, b).tolist() == [1e5, 10.0]
    b.close()
    link.close()


def test_a_wrong_key_or_no_key_never_gets_a_session():
    link = PlantLink(LAYOUT, key=KEY)
    for client in (ControllerClient(*link.address, key=b"another key of 32 bytes........"),
                   ControllerClient(*link.address)):
        th = threading.Thread(target=_pump, args=(link, lambda: False, 0.5), daemon=True)
        th.start()
        with pytest.raises(TimeoutError, match="same key"):
            client.connect(0.3)
        th.join()
        client.sock.close()
    assert link.counters["auth_failed"] >= 2 and link.owner is None and not link.connected
    # a keyless attacker who saw a real challenge cannot answer it: a forged AUTH fails
    good = _client(link)
    _connect(link, good)
    thief = _sock("127.0.0.3")
    thief.sendto(pack(MsgType.HELLO, 0, 1, raw=bytes(NONCE_SIZE) + b"x"), link.address)
    forged = bytearray(_of(good.sock.sent, MsgType.AUTH)[-1])
    forged[-1] ^= 1
    thief.sendto(bytes(forged), link.address)
    n = link.counters["auth_failed"]
    _settle(link)
    assert link.counters["auth_failed"] == n + 2  # the untagged HELLO, the forged AUTH
    assert link.counters["replayed"] == 0
    thief.sendto(_of(good.sock.sent, MsgType.AUTH)[-1], link.address)  # the genuine one
    _settle(link)
    assert link.counters["replayed"] == 1  # it opened the live session: a replay
    assert _silent(thief) and link.owner == good.sock.getsockname()
    thief.close()
    good.close()
    link.close()


# ------------------------------------------------------------------ replays
def test_replays_from_another_address_or_port_are_refused_and_counted():
    link = PlantLink(LAYOUT, key=KEY)
    owner = _session(link)
    cap = owner.sock.sent
    session, c0 = link.session, dict(link.counters)
    for host in ("127.0.0.3", "127.0.0.1"):  # another address, then another port
        s = _sock(host)
        for d in _replayable(cap):
            s.sendto(d, link.address)
        ack = link.send_obs(0.0, np.zeros(2))
        assert link.wait_command(ack, time.monotonic() + 0.05) is None
        owner.receive(0.5)  # the owner saw the observation; it does not answer
        _settle(link)
        assert _silent(s)
        s.close()
    c = link.counters
    n_hello = len(_of(cap, MsgType.HELLO))
    assert c["replayed"] - c0["replayed"] == 2 * (n_hello + 1)
    assert c["foreign"] - c0["foreign"] == 2 * 3  # the commands: not from the owner
    assert c["hello"] == c0["hello"] and c["refused"] == c0["refused"]
    assert link.session == session and link.owner == owner.sock.getsockname()
    assert "replay_refused" in [k for k, _ in link.events]
    assert _exchange(link, owner, (4e5, 11.0)).tolist() == [4e5, 11.0]  # the owner drives on
    owner.close()
    link.close()


def test_a_bye_replayed_from_another_address_or_port_changes_nothing():
    link = PlantLink(LAYOUT, key=KEY)
    first = _session(link)
    src = first.sock.getsockname()
    first.close()  # its BYE is captured
    assert _pump(link, lambda: link.counters["bye"] == 1)
    again = _connect(link, _client(link, bind=src))  # the owner's next session
    bye = _of(first.sock.sent, MsgType.BYE)
    assert len(bye) == 1
    c0 = dict(link.counters)
    for host in ("127.0.0.3", "127.0.0.1"):
        s = _sock(host)
        s.sendto(bye[0], link.address)
        _settle(link)
        assert _silent(s)
        s.close()
    c = link.counters
    assert c["foreign"] - c0["foreign"] == 2 and c["bye"] == 1 and link.connected
    assert _exchange(link, again, (8e5, 15.0)).tolist() == [8e5, 15.0]
    again.close()
    link.close()


def test_replays_within_the_session_reuse_a_counter_and_are_refused():
    link = PlantLink(LAYOUT, key=KEY)
    owner = _session(link)
    cap = list(owner.sock.sent)
    cmds = _of(cap, MsgType.CMD)
    session = link.session
    # the last command again, an older one, the session's AUTH and HELLO: from the owner
    ack = link.send_obs(0.0, np.zeros(2))
    owner.receive(0.5)
    for d in (cmds[-1], cmds[0], _of(cap, MsgType.AUTH)[-1], _of(cap, MsgType.HELLO)[-1]):
        owner.sock.sock.send(d)
    link.begin_step()  # a step's read window (4 of the owner's datagrams), as the runtime's
    assert link.wait_command(ack, time.monotonic() + 0.1) is None
    c = link.counters
    # the two commands answer earlier observations: dropped by their header, never parsed
    # (rx_dropped); the AUTH and HELLO are parsed and refused as replays
    assert c["rx_dropped"] == 2
    assert c["replayed"] == 2 and c["duplicates"] == 0 and c["seq_resync"] == 0
    # a replayed command that answers the observation being waited for is still refused
    m = parse(cmds[-1])[0]
    again = pack(MsgType.CMD, m.session, m.seq, [0.0, 60.0], ack=ack)  # untagged: no key
    owner.sock.sock.send(again)
    assert link.wait_command(ack, time.monotonic() + 0.05) is None
    assert c["auth_failed"] == 1
    assert link.session == session and link.connected
    assert _exchange(link, owner, (5e5, 12.0)).tolist() == [5e5, 12.0]
    owner.close()
    link.close()


def test_replays_from_the_owners_address_after_the_session_are_refused():
    # the 6 replays arrive at once: every one handled in a step (not dropped unparsed)
    link = PlantLink(LAYOUT, key=KEY, rx_max_commands=8)
    owner = _session(link)
    src = owner.sock.getsockname()
    owner.close()  # BYE: the session is over
    assert _pump(link, lambda: link.counters["bye"] == 1)
    assert not link.connected and link.owner == src
    cap = owner.sock.sent
    old = link.session
    replays = _replayable(cap)
    assert len(_of(replays, MsgType.BYE)) == 1
    spoof = _sock(*src)  # the owner's address and port, after the session
    for d in replays:
        spoof.sendto(d, link.address)
    _settle(link)
    assert link.counters["replayed"] == len(replays)
    assert _silent(spoof) and not link.connected and link.counters["bye"] == 1
    spoof.close()
    # a fresh legitimate session from the same address works, and the old session's
    # datagrams replayed during it (BYE included) change nothing
    fresh = _connect(link, _client(link, bind=src))
    assert fresh.session != old
    for d in replays:
        fresh.sock.sock.send(d)
    _settle(link)
    assert link.counters["replayed"] == 2 * len(replays) and link.connected
    assert _exchange(link, fresh, (6e5, 13.0)).tolist() == [6e5, 13.0]
    kinds = [k for k, _ in link.events]
    assert kinds.count("controller_bye") == 1 and "controller_reconnected" in kinds
    fresh.close()
    link.close()


def test_the_controller_refuses_replayed_observations_and_bye():
    link = PlantLink(LAYOUT, key=KEY)
    owner = _session(link)
    seen = _of(owner.sock.received, MsgType.OBS)
    # sent from the plant's own address and port (the spoofing socket is closed before the
    # plant must read again: a later bound socket would take its datagrams)
    spoof = _sock(*link.address)
    dst = owner.sock.getsockname()
    for d in seen:  # within the session: counters already used
        spoof.sendto(d, dst)
    spoof.close()
    assert owner.receive(0.2) is None and owner.counters["replayed"] == len(seen)
    link.release_owner()  # the plant ends the session (BYE)
    assert owner.receive(0.5) == "bye"
    bye = _of(owner.sock.received, MsgType.BYE)
    assert owner._rx is None
    fresh = _connect(link, owner)  # the same client, a new session
    n = fresh.counters["replayed"]
    spoof = _sock(*link.address)
    for d in (*seen, *bye):  # the old session's datagrams during the new one
        spoof.sendto(d, dst)
    assert fresh.receive(0.2) is None and fresh.counters["replayed"] == n + len(seen) + 1
    assert _exchange(link, fresh).tolist() == [1e5, 10.0]
    spoof.close()
    fresh.close()
    link.close()


def test_handing_a_keyed_link_to_another_controller_ends_the_old_session():
    link = PlantLink(LAYOUT, key=KEY)
    old = _session(link)
    s0 = link.session
    link.release_owner()  # operator action: BYE to the old owner, the session is over
    assert old.receive(0.5) == "bye" and link.owner is None
    new = _connect(link, _client(link, bind=("127.0.0.3", 0)))
    assert new.session not in (0, s0) and link.owner == new.sock.getsockname()
    # the old owner's session, from its own address: not the owner any more
    ack = link.send_obs(0.0, np.zeros(2))
    new.receive(0.5)
    for d in _replayable(old.sock.sent):
        old.sock.sock.send(d)
    assert link.wait_command(ack, time.monotonic() + 0.1) is None
    c = link.counters
    assert c["foreign"] == len(_of(old.sock.sent, MsgType.CMD))  # not from the owner
    assert c["replayed"] == len(_of(old.sock.sent, MsgType.HELLO)) + 1  # nonces seen; AUTH
    assert _exchange(link, new, (7e5, 14.0)).tolist() == [7e5, 14.0]
    old.sock.close()
    new.close()
    link.close()


# ------------------------------------------------------------------ garbled datagrams
def _recrc(d: bytes, authed: bool) -> bytes:
    """Recompute the CRC of a mutated datagram, so that it reaches the tag check."""
    end = len(d) - (16 if authed else 0)
    body = d[:end - 4]
    return body + struct.pack("<I", zlib.crc32(body)) + d[end:]


def test_truncated_and_garbled_datagrams_are_refused():
    link = PlantLink(LAYOUT, key=KEY)
    owner = _session(link)
    cap = list(owner.sock.sent)
    rng = random.Random(24)
    variants = []
    for d in cap:
        for n in range(0, len(d), 7):  # truncations
            variants.append(d[:n])
        for _ in range(60):  # one byte changed, CRC fixed: must fail the tag
            b = bytearray(d)
            i = rng.randrange(len(b))
            b[i] ^= rng.randrange(1, 256)
            variants.append(_recrc(bytes(b), authed=True) if i < len(b) - 20 else bytes(b))
        variants.append(d + b"\0" * 8)
        variants.append(d[:-16])  # the tag cut off
        variants.append(bytes(rng.randrange(256) for _ in range(len(d))))
    variants = [v for v in variants if v not in cap]
    assert 300 <= len(variants) <= 1000
    before = dict(link.counters)
    session, last = link.session, link._rx_last
    addr = owner.sock.getsockname()
    ack = link.send_obs(0.0, np.zeros(2))
    for v in variants:  # as if received from the owner's address
        link._handle(v, addr)
    c = link.counters
    refused = sum(c[k] - before[k] for k in ("malformed", "auth_failed", "replayed", "foreign"))
    assert refused == len(variants)
    assert c["rx"] == before["rx"]  # none passed its tag
    assert ack not in link._pending and link.session == session and link._rx_last == last
    assert c["bye"] == before["bye"] and link.connected
    owner.receive(0.5)
    assert _exchange(link, owner).tolist() == [1e5, 10.0]
    owner.close()
    link.close()


def test_the_controller_refuses_garbled_observations():
    link = PlantLink(LAYOUT, key=KEY)
    owner = _session(link)
    cap = [d for d in owner.sock.received if parse(d)[0].type in (MsgType.OBS,
                                                                  MsgType.LAYOUT)]
    rng = random.Random(25)
    variants = []
    for d in cap:
        variants += [d[:n] for n in range(0, len(d), 11)]
        for _ in range(30):
            b = bytearray(d)
            i = rng.randrange(len(b))
            b[i] ^= rng.randrange(1, 256)
            variants.append(_recrc(bytes(b), authed=True) if i < len(b) - 20 else bytes(b))
    variants = [v for v in variants if v not in cap]
    assert 150 <= len(variants) <= 600
    before = dict(owner.counters)
    spoof = _sock(*link.address)  # from the plant's address and port
    dst = owner.sock.getsockname()
    for i in range(0, len(variants), 40):  # in batches: the socket buffer holds them all
        for v in variants[i:i + 40]:
            spoof.sendto(v, dst)
        assert owner.receive(0.05) is None  # nothing taken
    spoof.close()
    c = owner.counters
    assert sum(c[k] - before[k] for k in ("malformed", "auth_failed", "replayed",
                                          "foreign")) == len(variants)
    assert c["rx"] == before["rx"] and owner._rx is not None
    assert _exchange(link, owner).tolist() == [1e5, 10.0]
    owner.close()
    link.close()


# ------------------------------------------------------------------ versions
def test_an_old_version_peer_gets_a_one_line_refusal():
    link = PlantLink(LAYOUT, key=KEY)
    old = bytearray(pack(MsgType.HELLO, 0, 1, raw=b"an old client"))
    old[4] = VERSION - 1
    old = _recrc(bytes(old), authed=False)
    s = _sock()
    s.sendto(old, link.address)
    assert _pump(link, lambda: link.counters["version_mismatch"] == 1)
    reply = s.recv(9000)
    assert reply[4] == VERSION  # an older client stops here: "answered in protocol version 3"
    m = parse(reply)[0]
    text = m.values.tobytes().rstrip(b"\0").decode()
    assert m.type == MsgType.REFUSE and "\n" not in text
    assert text.startswith(f"downhole SIL protocol version {VERSION - 1} refused: this end "
                           f"speaks version {VERSION}")
    assert link.owner is None and "refused" in dict(link.events)["version_mismatch"]
    s.close()
    link.close()
    # and this client, facing a plant of another version, says so in its one-line error
    plant = _sock()
    client = ControllerClient(*plant.getsockname(), key=KEY)

    def newer_plant():
        for _ in range(20):
            try:
                _, addr = plant.recvfrom(9000)
            except TimeoutError:
                continue
            v4 = bytearray(pack(MsgType.LAYOUT, 1, 1, raw=b"x"))
            v4[4] = VERSION + 1
            plant.sendto(_recrc(bytes(v4), authed=False), addr)

    th = threading.Thread(target=newer_plant, daemon=True)
    th.start()
    with pytest.raises(TimeoutError, match=f"answered in protocol version {VERSION + 1}, "
                                           f"this end speaks {VERSION}"):
        client.connect(0.4)
    th.join(5)
    client.sock.close()
    plant.close()


# ------------------------------------------------------------------ the keyed loop
def test_the_keyed_lock_step_loop_equals_the_hand_stepped_loop():
    T = 1.0
    plant = build_plant("hybrid68", interface="surface")
    rt = RealTimeRunner(plant, link=("127.0.0.1", 0), link_key=KEY, paced=False,
                        record_every=10, command_timeout=2.0)
    client = ControllerClient(*rt.link.address, key=KEY)
    th = threading.Thread(target=lambda: (client.connect(10.0),
                                          client.serve(pi_controller_for(plant),
                                                       idle_timeout=3.0)), daemon=True)
    th.start()
    assert rt.wait_for_controller(20.0)
    res = rt.run(T)
    rt.close()
    th.join(10)
    assert rt.link.authenticated and rt.stats["late_commands"] == 0
    c = rt.link.counters
    assert c["replayed"] == c["auth_failed"] == c["lost"] == c["malformed"] == 0
    # the same loop by hand: command from observation k, held over step k
    hand = build_plant("hybrid68", interface="surface")
    ctrl = pi_controller_for(hand)
    obs = hand.reset()
    ctrl.reset()
    w = [obs["bit_angular_velocity"]]
    for k in range(int(round(T / hand.dt))):
        o = dict(obs, reference_axial_velocity=0.01, reference_angular_velocity=20.0)
        obs = hand.step(ctrl.command(k * hand.dt, o, {"axial": 0.01, "angular": 20.0}))
        if (k + 1) % 10 == 0:
            w.append(obs["bit_angular_velocity"])
    np.testing.assert_allclose(res["bit_angular_velocity"], np.array(w), rtol=1e-9, atol=1e-12)
