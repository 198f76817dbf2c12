"""UDP link between a plant (server) and a controller, rig or PLC (client), protocol version 1.

:class:`PlantLink` is the plant's end: it binds a UDP port, answers ``HELLO`` with the layout,
sends one ``OBS`` per step and collects the ``CMD`` that answers it. :class:`ControllerClient`
is the controller's end (the client library): it connects, receives observations as named
dicts, calls any controller's ``command(t, observation, reference)`` and sends the answer.

Robustness (all counted in ``counters``, none raises): malformed datagrams (bad magic,
version, length, CRC, unknown type, wrong value count), datagrams from another session or an
unknown peer, duplicates (a sequence number already seen), reordered datagrams (older than the
newest seen), stale commands (answering an earlier observation than the one being waited for),
lost commands (gaps in the sequence) and late commands (none within the step's wait budget).
"""

from __future__ import annotations

import random
import select
import socket
import time

import numpy as np

from downhole.errors import DownholeInputError
from downhole.sil.protocol import (MAX_DATAGRAM, Layout, MalformedPacket, MsgType, pack,
                                   pack_layout, unpack, unpack_layout)

__all__ = ["PlantLink", "ControllerClient", "LINK_COUNTERS"]

#: Counter names kept by both ends.
LINK_COUNTERS = ("rx", "tx", "malformed", "foreign", "duplicates", "reordered", "stale",
                 "lost", "late", "hello", "bye", "wrong_size")


class _SeqTracker:
    """Classifies incoming sequence numbers: new, duplicate or reordered; counts gaps."""

    def __init__(self, window: int = 256):
        self.window = window
        self.max_seq = -1
        self.recent: set[int] = set()

    def reset(self):
        self.max_seq = -1
        self.recent.clear()

    def classify(self, seq: int, counters: dict) -> bool:
        """True when ``seq`` is new and in order (or a late fill of a gap: still usable)."""
        if seq in self.recent:
            counters["duplicates"] += 1
            return False
        self.recent.add(seq)
        if len(self.recent) > self.window:
            lo = self.max_seq - self.window
            self.recent = {s for s in self.recent if s > lo}
        if seq > self.max_seq:
            if self.max_seq >= 0 and seq > self.max_seq + 1:
                counters["lost"] += seq - self.max_seq - 1
            self.max_seq = seq
            return True
        counters["reordered"] += 1
        counters["lost"] = max(0, counters["lost"] - 1)  # the gap it left is filled
        return False


class PlantLink:
    """The plant's end of the link.

    Parameters
    ----------
    layout : Layout
        Names announced to the client.
    host : str
        Address to bind (default loopback).
    port : int
        UDP port (0: any free port; see :attr:`address`).

    Attributes
    ----------
    counters : dict
        See :data:`LINK_COUNTERS`.
    last_rx : float or None
        ``time.monotonic()`` of the last valid command (liveness for the safety timeout).
    rtt : float
        Last round-trip time (OBS sent -> its CMD received), s.
    """

    def __init__(self, layout: Layout, host: str = "127.0.0.1", port: int = 0):
        self.layout = layout
        self._layout_raw = pack_layout(layout)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            self.sock.bind((host, int(port)))
        except OSError as exc:
            raise DownholeInputError(f"cannot bind UDP {host}:{port}: {exc}") from None
        self.sock.setblocking(False)
        self.session = random.randrange(1, 2**32)
        self.peer = None
        self.seq = 0
        self.counters = {k: 0 for k in LINK_COUNTERS}
        self.last_rx: float | None = None
        self.rtt = float("nan")
        self.events: list[tuple[str, str]] = []  # drained by the runtime
        self._cmd_seq = _SeqTracker()
        self._n_cmd = len(layout.commands)
        self._pending: dict[int, np.ndarray] = {}

    @property
    def address(self) -> tuple[str, int]:
        return self.sock.getsockname()

    @property
    def connected(self) -> bool:
        return self.peer is not None

    def close(self) -> None:
        if self.peer is not None:
            try:
                self.sock.sendto(pack(MsgType.BYE, self.session, self._next()), self.peer)
            except OSError:
                pass
        self.sock.close()

    def _next(self) -> int:
        self.seq = (self.seq + 1) & 0xFFFFFFFF
        return self.seq

    def _handle(self, data: bytes, addr) -> None:
        c = self.counters
        try:
            msg = unpack(data)
        except MalformedPacket:
            c["malformed"] += 1
            return
        c["rx"] += 1
        if msg.type == MsgType.HELLO:
            c["hello"] += 1
            if self.peer != addr:
                self.events.append(("controller_connected", f"{addr[0]}:{addr[1]}"))
                self._cmd_seq.reset()
                self._pending.clear()
            self.peer = addr
            self.sock.sendto(pack(MsgType.LAYOUT, self.session, self._next(),
                                  raw=self._layout_raw), addr)
            c["tx"] += 1
            return
        if addr != self.peer or msg.session != self.session:
            c["foreign"] += 1
            return
        if msg.type == MsgType.BYE:
            c["bye"] += 1
            self.events.append(("controller_bye", f"{addr[0]}:{addr[1]}"))
            self.peer = None
            return
        if msg.type != MsgType.CMD:
            c["foreign"] += 1
            return
        if msg.values.size != self._n_cmd:
            c["wrong_size"] += 1
            return
        if not self._cmd_seq.classify(msg.seq, c):
            return
        if not np.all(np.isfinite(msg.values)):
            c["malformed"] += 1
            return
        self.last_rx = time.monotonic()
        if msg.echo > 0:
            self.rtt = self.last_rx - msg.echo
        self._pending[msg.ack] = msg.values.copy()
        if len(self._pending) > 8:
            for k in sorted(self._pending)[:-8]:
                del self._pending[k]

    def poll(self) -> None:
        """Drain every datagram waiting on the socket (non-blocking)."""
        while True:
            try:
                data, addr = self.sock.recvfrom(MAX_DATAGRAM)
            except (BlockingIOError, InterruptedError):
                return
            except OSError:  # e.g. ICMP port unreachable reported on Linux
                return
            self._handle(data, addr)

    def send_obs(self, sim_time: float, values) -> int:
        """Send one observation to the peer (if any); returns its sequence number (0 if none)."""
        if self.peer is None:
            return 0
        seq = self._next()
        try:
            self.sock.sendto(pack(MsgType.OBS, self.session, seq, values, sim_time=sim_time,
                                  sent=time.monotonic()), self.peer)
            self.counters["tx"] += 1
        except OSError:
            pass
        return seq

    def probe(self, values, timeout: float, interval: float = 0.05) -> bool:
        """Readiness handshake before the clock starts: send ``values`` as a probe observation
        (sim_time = -1) every ``interval`` s until the peer answers one (True) or ``timeout``
        s pass (False). The client warms its controller up on a probe and resets it."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            self.poll()
            if self.peer is None:
                time.sleep(0.005)
                continue
            seq = self._next()
            try:
                self.sock.sendto(pack(MsgType.OBS, self.session, seq, values, sim_time=-1.0,
                                      sent=time.monotonic()), self.peer)
                self.counters["tx"] += 1
            except OSError:
                pass
            got = self.wait_command(seq, min(end, time.monotonic() + interval), count=False)
            if got is not None:
                self._pending.clear()
                return True
        return False

    def wait_command(self, ack: int, deadline: float, count: bool = True):
        """Wait until ``deadline`` (monotonic) for the command answering observation ``ack``.

        Returns the command values (ndarray) or None (counted as ``late``). Commands answering
        other observations are counted as ``stale`` and dropped."""
        while True:
            self.poll()
            if ack in self._pending:
                vals = self._pending.pop(ack)
                stale = [k for k in self._pending if k < ack]
                for k in stale:
                    del self._pending[k]
                self.counters["stale"] += len(stale)
                return vals
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                self.counters["late"] += count
                return None
            select.select([self.sock], [], [], remaining)


class ControllerClient:
    """The controller's end of the link (client library).

    Parameters
    ----------
    host, port : str, int
        The plant's address.
    name : str
        Sent in HELLO (shown in the plant's events).

    Examples
    --------
    >>> client = ControllerClient("127.0.0.1", 47600)          # doctest: +SKIP
    >>> layout = client.connect()                              # doctest: +SKIP
    >>> client.serve(my_controller)                            # doctest: +SKIP
    """

    def __init__(self, host: str, port: int, name: str = "controller"):
        self.addr = (host, int(port))
        self.name = name
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.connect(self.addr)
        self.layout: Layout | None = None
        self.session = 0
        self.seq = 0
        self.counters = {k: 0 for k in LINK_COUNTERS}
        self._obs_seq = _SeqTracker()

    def _next(self) -> int:
        self.seq = (self.seq + 1) & 0xFFFFFFFF
        return self.seq

    def connect(self, timeout: float = 10.0) -> Layout:
        """Send HELLO until the plant answers with its layout; returns it.

        Raises
        ------
        TimeoutError
            No layout within ``timeout`` seconds.
        """
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            try:
                self.sock.send(pack(MsgType.HELLO, 0, self._next(), raw=self.name.encode()))
            except OSError:
                pass
            r, _, _ = select.select([self.sock], [], [], 0.1)
            if not r:
                continue
            try:
                msg = unpack(self.sock.recv(MAX_DATAGRAM))
            except MalformedPacket:
                self.counters["malformed"] += 1
                continue
            except OSError:
                time.sleep(0.05)
                continue
            if msg.type == MsgType.LAYOUT:
                self.layout = unpack_layout(msg.values.tobytes())
                self.session = msg.session
                return self.layout
        raise TimeoutError(f"no layout from the plant at {self.addr[0]}:{self.addr[1]} within "
                           f"{timeout} s")

    def receive(self, timeout: float):
        """Next in-order observation as ``(seq, sim_time, sent, values)``; None on timeout;
        ``"bye"`` when the plant closed."""
        end = time.monotonic() + timeout
        while True:
            remaining = end - time.monotonic()
            if remaining <= 0:
                return None
            r, _, _ = select.select([self.sock], [], [], remaining)
            if not r:
                return None
            try:
                data = self.sock.recv(MAX_DATAGRAM)
            except OSError:
                return None
            try:
                msg = unpack(data)
            except MalformedPacket:
                self.counters["malformed"] += 1
                continue
            self.counters["rx"] += 1
            if msg.session != self.session:
                self.counters["foreign"] += 1
                continue
            if msg.type == MsgType.BYE:
                self.counters["bye"] += 1
                return "bye"
            if msg.type != MsgType.OBS:
                continue
            if msg.values.size != len(self.layout.observations):
                self.counters["wrong_size"] += 1
                continue
            if not self._obs_seq.classify(msg.seq, self.counters):
                continue
            if msg.sim_time >= 0 and select.select([self.sock], [], [], 0)[0]:
                self.counters["stale"] += 1  # a newer observation is waiting: answer that one
                end = time.monotonic() + timeout
                continue
            return msg.seq, msg.sim_time, msg.sent, msg.values

    def send_command(self, ack: int, sim_time: float, echo: float, values) -> None:
        self.sock.send(pack(MsgType.CMD, self.session, self._next(), values, ack=ack,
                            sim_time=sim_time, sent=time.monotonic(), echo=echo))
        self.counters["tx"] += 1

    def serve(self, controller, *, idle_timeout: float = 5.0, max_steps: int | None = None,
              reference: dict | None = None, realtime: bool = False) -> int:
        """Answer observations with ``controller.command(t, observation, reference)`` until the
        plant says BYE, nothing arrives for ``idle_timeout`` s, or ``max_steps`` answers.

        ``observation`` is a dict of the layout's names; ``reference`` is the ``reference``
        argument if given, else built from the observations ``reference_axial_velocity`` and
        ``reference_angular_velocity`` when the plant sends them. The command dict must name
        every layout command. ``realtime``: try SCHED_FIFO for this thread while serving.
        Returns the number of commands sent.
        """
        from downhole.sil.runtime import elevate_priority

        restore = elevate_priority()[0] if realtime else (lambda: None)
        try:
            return self._serve(controller, idle_timeout, max_steps, reference)
        finally:
            restore()

    def _serve(self, controller, idle_timeout, max_steps, reference) -> int:
        if self.layout is None:
            self.connect()
        names = self.layout.observations
        cnames = self.layout.commands
        has_ref = ("reference_axial_velocity" in names and "reference_angular_velocity" in names)
        controller.reset()
        sent = 0
        while max_steps is None or sent < max_steps:
            got = self.receive(idle_timeout)
            if got is None or got == "bye":
                break
            seq, t, stamp, vals = got
            obs = dict(zip(names, vals.tolist()))
            ref = reference
            if ref is None and has_ref:
                ref = {"axial": obs["reference_axial_velocity"],
                       "angular": obs["reference_angular_velocity"]}
            probe = t < 0
            cmd = controller.command(max(t, 0.0), obs, ref)
            if probe:  # readiness probe: the call above warmed the controller up
                controller.reset()
                out = [float(cmd[c]) for c in cnames]
                self.send_command(seq, t, stamp, out)
                continue
            try:
                out = [float(cmd[c]) for c in cnames]
            except KeyError as exc:
                raise DownholeInputError(f"controller command lacks {exc.args[0]!r}; the plant "
                                         f"expects {cnames}") from None
            self.send_command(seq, t, stamp, out)
            sent += 1
        return sent

    def close(self) -> None:
        try:
            self.sock.send(pack(MsgType.BYE, self.session, self._next()))
        except OSError:
            pass
        self.sock.close()
