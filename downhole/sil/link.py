"""UDP link between a plant (server) and a controller, rig or PLC (client), protocol version 3.

:class:`PlantLink` is the plant's end: it binds a UDP port, answers ``HELLO`` (keyed: after a
challenge) with the layout, sends one ``OBS`` per step and collects the ``CMD`` that answers
it. :class:`ControllerClient` is the controller's end (the client library): it connects,
receives observations as named dicts, calls any controller's ``command(t, observation,
reference)`` and sends the answer.

Session ownership: the first client whose session the plant opens owns it - its address *and*
port. A ``HELLO`` from any other address or port is refused - no challenge, no layout, no
session id - and counted (``refused``, event ``controller_refused``); so are its other
datagrams (``foreign``). The owner may open a new session (a restarted PLC reusing its source
port; event ``controller_reconnected``); a ``BYE`` from the owner keeps the ownership (only the
owner can come back). Handing the session to another client is an operator action,
:meth:`PlantLink.release_owner` (the runtime's
:meth:`~downhole.sil.runtime.RealTimeRunner.replace_controller` applies the safe action first).

Keyed link (a shared key, :func:`~downhole.sil.protocol.load_key`; required beyond loopback):
replay-proof. The controller's ``HELLO`` carries a fresh random nonce and is tagged under the
key; the plant answers with a ``CHALLENGE`` (the client's nonce, its own fresh nonce, a new
session id), and the controller proves the key with ``AUTH``, tagged under the session key
derived from the key, both nonces and the session id
(:func:`~downhole.sil.protocol.session_signers`); only then does the plant open the session
and send the layout. Every later datagram of the session in either direction carries the
session id and the sender's counter under a tag of the session key of its direction, and the
receiver accepts only a counter above the last one it accepted. Refused and counted as
``replayed``: a ``HELLO`` whose nonce the plant has seen before (the last 4096), the ``AUTH``
of an open session, any datagram of an ended session (the last 1024 session ids; an older one
is refused as ``foreign``), and a counter not above the last accepted. A HELLO
changes nothing until its AUTH proves the key, so a replayed or forged one cannot disturb the
owner's session. Counters are 32-bit: a session lasts at most 2^32 - 1 datagrams per direction
(49 days at 1 kHz).

Keyless link (loopback development, as in version 2): ``HELLO`` is answered with the layout at
once, nothing is tagged and a datagram is not bound to a fresh session; the owner saying
``HELLO`` again re-synchronises the sequence tracking. It keeps apart well-behaved programs (a
stale controller of an earlier run, another plant's traffic) and refuses malformed or
out-of-range input, but anybody who can send to the port can forge or replay datagrams.

Once a client owns the session the plant reads it on a second socket *connected* to the
owner's address (bound to the same port): the kernel delivers the owner's datagrams there and
everybody else's to the listening socket, so a flood from elsewhere neither delays nor drops
the owner's commands. Every read is bounded (:meth:`PlantLink.poll`), per window of one plant
step:

- the owner's socket: at most ``rx_max_commands`` datagrams (default 4) are handled (parsed,
  authenticated, validated). A command whose header (read, not trusted) says it answers an
  earlier observation than the one awaited is dropped unparsed (:meth:`wait_command` would
  drop it as stale anyway). Once the count is reached, further datagrams waiting there are
  read and dropped unparsed, at most ``rx_max_datagrams`` (default 32) of them - except one
  whose header claims to answer the awaited observation, which waits for the next step.
  Dropped datagrams are counted (``rx_dropped``), so that an owner sending more than it
  should - keyed or not, its datagrams valid or not - neither costs the step more than these
  bounds nor builds a backlog that would delay its next answers. Handling also stops once it
  has cost ``rx_owner_budget`` seconds of this thread's CPU time (default 5 % of the step)
  after the first datagram, which is always handled; what is left then waits for the next
  step;
- the listening socket: at most ``rx_max_datagrams`` datagrams and ``rx_budget`` seconds (wall
  clock, default 2 % of the step) after its first datagram, which is always read; the rest
  waits for the next step (or is dropped by the kernel).

A step that hits a bound is counted (``rx_capped``, event ``receive_bound``).

A datagram changes no state before it is fully validated, in this order: framing and CRC,
(keyed) sender, session and authentication tag (the key or the session key), counter, message
type, value count, finiteness, admissible range of every command
(:data:`~downhole.sil.plants.COMMAND_RANGES`); only then does its counter reach the sequence
tracking and its values the plant.

Robustness (all counted in ``counters``, none raises): malformed datagrams (bad magic,
length, CRC, unknown type), another protocol version (``version_mismatch``, also counted as
malformed; the plant answers with a one-line ``REFUSE`` in its own version, at most one a
second after the first from each address), failed authentication (``auth_failed``), replays
(``replayed``, keyed), datagrams from another session or peer (``foreign``), refused HELLOs
(``refused``), wrong value count (``wrong_size``), non-finite or out-of-range commands
(``non_finite``, ``out_of_range``), and on a keyless link duplicates (a sequence number already
seen), reordered datagrams (older than the newest seen), a sender whose sequence restarted far
behind (``seq_resync``: after 8 such datagrams in a row the tracker follows it, so a forged jump
cannot lock the owner out); on both, stale commands (answering an earlier observation than the
one being waited for), lost commands (gaps in the sequence; the owner's datagrams dropped by the read bound show
up as gaps too), late commands (none within the step's wait budget), capped reads
(``rx_capped``) and the owner's datagrams dropped unread by the bound (``rx_dropped``).
"""

from __future__ import annotations

import ipaddress
import math
import os
import random
import select
import socket
import time
from collections import deque

import numpy as np

from downhole.errors import DownholeInputError
from downhole.sil.protocol import (
    FLAG_AUTH,
    HEADER,
    HEADER_SIZE,
    KEY_ENV,
    MAGIC,
    MAX_DATAGRAM,
    NONCE_SIZE,
    Layout,
    MalformedPacket,
    Message,
    MsgType,
    Signer,
    VersionMismatch,
    load_key,
    pack,
    pack_hello,
    pack_layout,
    parse,
    refusal,
    session_signers,
    split_hello,
    unpack_layout,
)

__all__ = ["LINK_COUNTERS", "ControllerClient", "PlantLink", "is_loopback"]

#: Counter names kept by both ends.
LINK_COUNTERS = ("rx", "tx", "malformed", "foreign", "duplicates", "reordered", "stale",
                 "lost", "late", "hello", "bye", "wrong_size", "refused", "auth_failed",
                 "version_mismatch", "non_finite", "out_of_range", "rx_capped", "seq_resync",
                 "replayed", "rx_dropped")

#: Keyed links: HELLO nonces remembered (a HELLO reusing one is a replay), session ids of ended
#: sessions remembered (their datagrams are counted as replays), challenges outstanding at once.
_MAX_NONCES = 4096
_MAX_ENDED = 1024
_MAX_CHALLENGES = 16


def _remember(seen: set, order: deque, item) -> None:
    """Add ``item`` to the bounded memory ``seen`` (oldest forgotten first)."""
    if len(order) == order.maxlen:
        seen.discard(order.popleft())
    order.append(item)
    seen.add(item)


def is_loopback(host: str) -> bool:
    """True when ``host`` names only loopback addresses (127.0.0.0/8, ::1, ``localhost``);
    ``""`` and ``0.0.0.0`` (every interface) are not loopback."""
    if host in ("", "0.0.0.0", "::"):
        return False
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        pass
    try:
        infos = socket.getaddrinfo(host, None, socket.AF_INET, socket.SOCK_DGRAM)
    except OSError:
        return False
    return bool(infos) and all(ipaddress.ip_address(i[4][0]).is_loopback for i in infos)


def _require_key_beyond_loopback(host: str, signer, what: str) -> None:
    if signer is None and not is_loopback(host):
        raise DownholeInputError(
            f"{what} {host or '0.0.0.0'} is beyond loopback: the UDP link then needs a shared "
            f"key, so that nobody else on the network can drive the plant; give one with "
            f"--link-key-file FILE (chmod 600), the environment variable {KEY_ENV}, or key= / "
            f"key_file= (docs/sil.md, 'Security: the UDP link')")


def _shared_key(key, key_file, host, what):
    """The shared key (:func:`load_key`) and its :class:`Signer` (None without a key), refused
    beyond the loopback without one (:func:`_require_key_beyond_loopback`, ``what``)."""
    k = load_key(key, key_file)
    signer = Signer(k) if k is not None else None
    _require_key_beyond_loopback(host, signer, what)
    return k, signer


class _SeqTracker:
    """Classifies incoming sequence numbers: new, duplicate or reordered; counts gaps.

    Call :meth:`classify` only for a fully validated datagram: it changes the tracker's state.
    A sender whose numbers restarted behind the newest seen (``resync_after`` datagrams in a
    row older than the newest, none newer in between) is followed (counted ``seq_resync``):
    ordinary reordering moves one datagram, not eight in a row."""

    def __init__(self, window: int = 256, resync_after: int = 8):
        self.window = window
        self.resync_after = resync_after
        self.max_seq = -1
        self.recent: set[int] = set()
        self._behind = 0

    def reset(self):
        self.max_seq = -1
        self.recent.clear()
        self._behind = 0

    def classify(self, seq: int, counters: dict) -> bool:
        """True when ``seq`` is new and in order (or a late fill of a gap: still usable)."""
        if seq in self.recent:
            counters["duplicates"] += 1
            return False
        if seq < self.max_seq:
            self._behind += 1
            if self._behind >= self.resync_after:  # the sender restarted: follow it
                counters["seq_resync"] += 1
                self.reset()
                self.max_seq = seq
                self.recent.add(seq)
                return True
        self.recent.add(seq)
        if len(self.recent) > self.window:
            lo = self.max_seq - self.window
            self.recent = {s for s in self.recent if s > lo}
        if seq > self.max_seq:
            if self.max_seq >= 0 and seq > self.max_seq + 1:
                counters["lost"] += seq - self.max_seq - 1
            self.max_seq = seq
            self._behind = 0
            return True
        counters["reordered"] += 1
        counters["lost"] = max(0, counters["lost"] - 1)  # the gap it left is filled
        return False


class _SelectPoller:
    """``select.poll`` stand-in where the platform lacks it (readability only)."""

    def __init__(self):
        self.fds: list[int] = []

    def register(self, fd, _mask=None):
        self.fds.append(fd)

    def unregister(self, fd):
        self.fds.remove(fd)

    def poll(self, _timeout=0):
        return [(fd, 1) for fd in select.select(self.fds, [], [], 0)[0]]


def _addr(a) -> str:
    return f"{a[0]}:{a[1]}"


class PlantLink:
    """The plant's end of the link (see the module's description of keyed and keyless links).

    Parameters
    ----------
    layout : Layout
        Names announced to the client.
    host : str
        Address to bind (default loopback). Any other address needs a key.
    port : int
        UDP port (0: any free port; see :attr:`address`).
    key, key_file : bytes or str, path, optional
        Shared key for HMAC authentication of every datagram (see
        :func:`~downhole.sil.protocol.load_key`; default: the environment variable
        ``DOWNHOLE_LINK_KEY`` if set, else no authentication).
    command_ranges : dict, optional
        ``{command: (low, high)}``; default :data:`~downhole.sil.plants.COMMAND_RANGES` for
        the layout's commands (every command needs a range).
    rx_max_datagrams : int
        Per read window (one plant step), the most datagrams read from the listening socket,
        and the most datagrams of the owner read and dropped unparsed beyond
        ``rx_max_commands`` (default 32).
    rx_budget : float, optional
        Per read window, the most seconds (wall clock) spent reading the listening socket
        (default 2 % of the step).
    rx_max_commands : int
        Per read window, the most datagrams from the owner's socket that are handled (parsed,
        authenticated, validated; default 4); the excess is dropped and counted as
        ``rx_dropped``.
    rx_owner_budget : float, optional
        Per read window, the most seconds of this thread's CPU time spent handling the owner's
        datagrams after the first, which is always handled (default 5 % of the step); what is
        left waits for the next window.

    Attributes
    ----------
    counters : dict
        See :data:`LINK_COUNTERS`.
    owner : (str, int) or None
        The address and port owning the session.
    last_rx : float or None
        ``time.monotonic()`` of the last valid command (liveness for the safety timeout).
    rtt : float
        Last round-trip time (OBS sent -> its CMD received), s.
    step_rx_s, step_rx_n : float, int
        CPU time (of the calling thread, so that time the scheduler gives to other processes
        is not counted) spent reading and validating datagrams, and datagrams handled, since
        the last :meth:`begin_step` (the runtime records them per step).
    step_dropped : int
        The owner's datagrams dropped unparsed since the last :meth:`begin_step`.
    step_listen_s : float
        The part of :attr:`step_rx_s` spent on the listening socket: what datagrams from
        anybody but the owner (a flood) cost this step.

    Raises
    ------
    DownholeInputError
        Cannot bind, ``host`` beyond loopback without a key, bad key, or a command without an
        admissible range, or a read bound below 1.
    """

    def __init__(self, layout: Layout, host: str = "127.0.0.1", port: int = 0, *,
                 key=None, key_file=None, command_ranges: dict | None = None,
                 rx_max_datagrams: int = 32, rx_budget: float | None = None,
                 rx_max_commands: int = 4, rx_owner_budget: float | None = None):
        from downhole.sil.plants import resolve_ranges

        self.layout = layout
        self._layout_raw = pack_layout(layout)
        # the shared key and its signer: HELLO, CHALLENGE
        self._key, self._signer = _shared_key(key, key_file, host,
                                              "binding the plant's UDP link to")
        # keyed sessions: the session keys (controller -> plant, plant -> controller), the last
        # counter accepted from the controller, the challenges outstanding, and bounded
        # memories of HELLO nonces and ended sessions (keyless: _rx and _tx stay None)
        self._rx: Signer | None = None
        self._tx: Signer | None = None
        self._rx_last = 0
        self._challenges: dict = {}
        self._nonces: set = set()
        self._nonce_order: deque = deque(maxlen=_MAX_NONCES)
        self._ended: set = set()
        self._ended_order: deque = deque(maxlen=_MAX_ENDED)
        self.command_ranges = resolve_ranges(layout.commands, command_ranges, "link commands")
        self._lo = [self.command_ranges[c][0] for c in layout.commands]
        self._hi = [self.command_ranges[c][1] for c in layout.commands]
        for name, v in (("rx_max_datagrams", rx_max_datagrams),
                        ("rx_max_commands", rx_max_commands)):
            if int(v) < 1:
                raise DownholeInputError(f"{name} must be >= 1, got {v}")
        self.rx_max_datagrams = int(rx_max_datagrams)
        self.rx_max_commands = int(rx_max_commands)
        self.rx_budget = float(rx_budget) if rx_budget is not None else 0.02 * layout.dt
        self.rx_owner_budget = (float(rx_owner_budget) if rx_owner_budget is not None
                                else 0.05 * layout.dt)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            self.sock.bind((host, int(port)))
        except (OSError, OverflowError) as exc:
            self.sock.close()
            raise DownholeInputError(f"cannot bind UDP {host}:{port}: {exc}") from None
        self.sock.setblocking(False)
        self._lobby_fd = self.sock.fileno()
        self._poller = select.poll() if hasattr(select, "poll") else _SelectPoller()
        self._poller.register(self._lobby_fd, select.POLLIN)
        self._own: socket.socket | None = None  # connected to the owner
        self.session = random.randrange(1, 2**32)
        self.owner = None
        self._gone = False  # the owner said BYE (keeps the ownership)
        self.seq = 0
        self.counters = {k: 0 for k in LINK_COUNTERS}
        self.last_rx: float | None = None
        self.rtt = float("nan")
        self.events: list[tuple[str, str]] = []  # drained by the runtime
        self._noted: dict[str, float] = {}
        self._noted_addrs: set = set()
        self._cmd_seq = _SeqTracker()
        self._n_cmd = len(layout.commands)
        self._pending: dict[int, np.ndarray] = {}
        self._awaited = 0  # the observation whose command is waited for (wait_command)
        self._cmds_since_hello = 0
        self.begin_step()

    # ------------------------------------------------------------------ state
    @property
    def address(self) -> tuple[str, int]:
        return self.sock.getsockname()

    @property
    def peer(self):
        """The owner's address while it is connected (None before HELLO and after BYE)."""
        return None if self._gone else self.owner

    @property
    def connected(self) -> bool:
        return self.owner is not None and not self._gone

    @property
    def authenticated(self) -> bool:
        """True when every datagram carries an HMAC tag (a key is configured)."""
        return self._signer is not None

    def close(self) -> None:
        if self.connected:
            self._send(pack(MsgType.BYE, self.session, self._next(), signer=self._tx))
            self._end_session()
        self._close_own()
        self.sock.close()

    def _next(self) -> int:
        self.seq = (self.seq + 1) & 0xFFFFFFFF
        return self.seq

    def _close_own(self) -> None:
        if self._own is not None:
            self._poller.unregister(self._own.fileno())
            self._own.close()
            self._own = None

    def _send(self, data: bytes) -> None:
        try:
            if self._own is not None:
                self._own.send(data)
            else:
                self.sock.sendto(data, self.owner)
            self.counters["tx"] += 1
        except OSError:
            pass

    def _reply(self, addr, data: bytes) -> None:
        """Send to ``addr`` (not necessarily the owner) from the listening socket."""
        try:
            self.sock.sendto(data, addr)
            self.counters["tx"] += 1
        except OSError:
            pass

    def _note(self, kind: str, addr, detail: str) -> bool:
        """An event, at most one per second per kind, except the first from a new address.
        Returns True when the event was recorded."""
        now = time.monotonic()
        new = addr is not None and addr not in self._noted_addrs and len(self._noted_addrs) < 64
        if new:
            self._noted_addrs.add(addr)
        if new or now - self._noted.get(kind, -1e9) >= 1.0:
            self._noted[kind] = now
            self.events.append((kind, detail))
            return True
        return False

    def _take_owner(self, addr) -> None:
        self.owner = addr
        self._gone = False
        self._cmd_seq.reset()
        self._pending.clear()
        self._cmds_since_hello = 0
        own = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            own.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            own.bind(self.sock.getsockname())
            own.connect(addr)
            own.setblocking(False)
            self._own = own
            self._poller.register(own.fileno(), select.POLLIN)
        except OSError as exc:  # the owner is then read on the listening socket
            own.close()
            self._own = None
            self.events.append(("owner_socket_unavailable", str(exc)))
        self.events.append(("controller_connected", _addr(addr)))

    def release_owner(self) -> None:
        """Operator action: end the current owner's session (BYE to it) and draw a new session
        id; the next HELLO from any address takes the session. The runtime's
        :meth:`~downhole.sil.runtime.RealTimeRunner.replace_controller` wraps this in the safe
        action; call this directly only when the plant is not running."""
        old = self.owner
        if old is None:
            return
        if not self._gone:
            self._send(pack(MsgType.BYE, self.session, self._next(), signer=self._tx))
        self._end_session()
        self._challenges.clear()
        self._close_own()
        self.owner = None
        self._gone = False
        self._cmd_seq.reset()
        self._pending.clear()
        self.session = self._new_session_id()
        self.events.append(("controller_released", _addr(old)))

    def _new_session_id(self) -> int:
        """A random session id other than the current, an ended or a challenged one."""
        taken = {self.session, *(ch[0] for ch in self._challenges.values())}
        while True:
            sid = random.randrange(1, 2**32)
            if sid not in taken and sid not in self._ended:
                return sid

    def _end_session(self) -> None:
        """Keyed: forget the session keys; the session id is remembered as ended."""
        if self._rx is not None:
            _remember(self._ended, self._ended_order, self.session)
        self._rx = self._tx = None

    # ------------------------------------------------------------------ receive
    def _handle(self, data: bytes, addr) -> None:
        c = self.counters
        try:
            msg, tagged, end = parse(data)
        except VersionMismatch as exc:
            c["malformed"] += 1
            c["version_mismatch"] += 1
            if self._note("version_mismatch", addr, f"{_addr(addr)}: {exc}; refused"):
                self._reply(addr, refusal(exc.version))  # its own one-line reason
            return
        except MalformedPacket:
            c["malformed"] += 1
            return
        if self._signer is None:
            if tagged:
                self._auth_failed(addr, "authenticated datagram, but this end has no key")
                return
            c["rx"] += 1
            self._handle_open(msg, addr)
        elif not tagged:
            self._auth_failed(addr, "datagram without the authentication tag this end requires")
        else:
            self._handle_keyed(msg, data, end, addr)

    def _auth_failed(self, addr, why: str) -> None:
        self.counters["auth_failed"] += 1
        self._note("auth_failed", addr, f"{_addr(addr)}: {why}")

    def _replayed(self, addr, msg: Message, why: str) -> None:
        c = self.counters
        c["replayed"] += 1
        self._note("replay_refused", addr, f"{msg.type.name} from {_addr(addr)} refused as a "
                   f"replay: {why} ({c['replayed']} refused)")

    def _refuse(self, addr) -> None:
        c = self.counters
        c["refused"] += 1
        self._note("controller_refused", addr, f"HELLO from {_addr(addr)} refused: "
                   f"{_addr(self.owner)} owns the session ({c['refused']} refused)")

    def _handle_open(self, msg: Message, addr) -> None:
        """Keyless link (loopback development): ownership by address, no freshness."""
        c = self.counters
        if addr != self.owner:
            if msg.type != MsgType.HELLO:
                c["foreign"] += 1
            elif self.owner is None:
                c["hello"] += 1
                self._take_owner(addr)
                self._send(pack(MsgType.LAYOUT, self.session, self._next(),
                                raw=self._layout_raw))
            else:
                self._refuse(addr)
            return
        if msg.type == MsgType.HELLO:  # the owner again (restarted, or its HELLO repeated)
            c["hello"] += 1
            if self._gone or self._cmds_since_hello:
                self.events.append(("controller_reconnected", _addr(addr)))
            self._gone = False
            self._cmd_seq.reset()
            self._pending.clear()
            self._cmds_since_hello = 0
            self._send(pack(MsgType.LAYOUT, self.session, self._next(), raw=self._layout_raw))
            return
        if msg.session != self.session:
            c["foreign"] += 1
            return
        if msg.type == MsgType.BYE:
            c["bye"] += 1
            if not self._gone:
                self.events.append(("controller_bye", _addr(addr)))
            self._gone = True
            return
        if msg.type != MsgType.CMD:
            c["foreign"] += 1
            return
        if not self._valid_command(msg.values):
            return
        if not self._cmd_seq.classify(msg.seq, c):  # only a valid command reaches the tracker
            return
        self._accept_command(msg)

    def _handle_keyed(self, msg: Message, data: bytes, end: int, addr) -> None:
        """Keyed link: the challenge handshake, then session keys and a strict counter."""
        c = self.counters
        signed, tag = data[:end], data[end:]
        if msg.type == MsgType.HELLO:
            if not self._signer.verify(signed, tag):
                self._auth_failed(addr, "authentication tag mismatch (wrong key?)")
                return
            c["rx"] += 1
            hello = split_hello(msg)
            if hello is None:
                c["malformed"] += 1
                return
            nonce = hello[0]
            if nonce in self._nonces:
                self._replayed(addr, msg, "its nonce was used before")
                return
            _remember(self._nonces, self._nonce_order, nonce)
            if self.owner is not None and addr != self.owner:
                self._refuse(addr)
                return
            c["hello"] += 1
            sid = self._new_session_id()
            server_nonce = os.urandom(NONCE_SIZE)
            c2p, p2c = session_signers(self._key, nonce, server_nonce, sid)
            self._challenges.pop(addr, None)  # one outstanding challenge per address
            self._challenges[addr] = (sid, nonce + server_nonce, c2p, p2c)
            while len(self._challenges) > _MAX_CHALLENGES:
                del self._challenges[next(iter(self._challenges))]
            self._reply(addr, pack(MsgType.CHALLENGE, sid, self._next(),
                                   raw=nonce + server_nonce, signer=self._signer))
            return
        if msg.type == MsgType.AUTH:
            ch = self._challenges.get(addr)
            if ch is None or msg.session != ch[0]:
                self._stale_session(msg, addr, signed, tag)
                return
            sid, nonces, c2p, p2c = ch
            if not c2p.verify(signed, tag) or msg.values.tobytes() != nonces:
                self._auth_failed(addr, "AUTH does not prove the key over the nonces (wrong "
                                  "key?)")
                return
            c["rx"] += 1
            del self._challenges[addr]
            if self.owner is not None and addr != self.owner:
                self._refuse(addr)
                return
            self._begin_session(addr, sid, c2p, p2c, msg.seq)
            self._send(pack(MsgType.LAYOUT, sid, self._next(), raw=self._layout_raw,
                            signer=p2c))
            return
        if addr != self.owner:
            c["foreign"] += 1
            return
        if self._rx is None or msg.session != self.session:
            self._stale_session(msg, addr, signed, tag)
            return
        if not self._rx.verify(signed, tag):
            self._auth_failed(addr, "authentication tag mismatch (wrong key?)")
            return
        c["rx"] += 1
        if msg.seq <= self._rx_last:
            self._replayed(addr, msg, f"counter {msg.seq} is not above {self._rx_last}, the "
                           "last accepted")
            return
        if msg.type == MsgType.BYE:
            self._rx_last = msg.seq
            c["bye"] += 1
            self.events.append(("controller_bye", _addr(addr)))
            self._end_session()
            self._gone = True
            return
        if msg.type != MsgType.CMD:
            c["foreign"] += 1
            return
        if not self._valid_command(msg.values):
            return
        if msg.seq > self._rx_last + 1:
            c["lost"] += msg.seq - self._rx_last - 1
        self._rx_last = msg.seq
        self._accept_command(msg)

    def _stale_session(self, msg: Message, addr, signed: bytes, tag: bytes) -> None:
        """A datagram for no session this end expects: a replay when it names an ended
        session (whose keys are forgotten) or is the AUTH of the current one (its tag checked),
        else foreign."""
        sid = msg.session
        if msg.type == MsgType.AUTH and self._rx is not None and sid == self.session:
            if not self._rx.verify(signed, tag):
                self._auth_failed(addr, "authentication tag mismatch (wrong key?)")
            else:
                self._replayed(addr, msg, "the session it opened is established")
        elif sid in self._ended:
            self._replayed(addr, msg, f"session {sid:#010x} is over")
        else:
            self.counters["foreign"] += 1

    def _begin_session(self, addr, sid: int, c2p: Signer, p2c: Signer, seq: int) -> None:
        if self.owner is None:
            self._take_owner(addr)
        else:  # the owner again, with a fresh handshake: its new session replaces the old
            if self._gone or self._cmds_since_hello:
                self.events.append(("controller_reconnected", _addr(addr)))
            self._pending.clear()
            self._cmds_since_hello = 0
        self._end_session()
        self.session = sid
        self._rx, self._tx = c2p, p2c
        self._rx_last = seq
        self._gone = False

    def _valid_command(self, vals) -> bool:
        """Value count, finiteness and admissible range of a command (counted when not)."""
        c = self.counters
        if vals.size != self._n_cmd:
            c["wrong_size"] += 1
            return False
        vl = vals.tolist()
        for v, lo, hi in zip(vl, self._lo, self._hi):
            if not lo <= v <= hi:  # False for NaN too
                break
        else:
            return True
        if not all(map(math.isfinite, vl)):
            c["non_finite"] += 1
            self._note("command_rejected", None, f"non-finite command {vl}")
        else:
            c["out_of_range"] += 1
            bad = [f"{n} = {v:g} not in [{lo:g}, {hi:g}]" for n, v, lo, hi in
                   zip(self.layout.commands, vl, self._lo, self._hi) if not lo <= v <= hi]
            self._note("command_rejected", None, "; ".join(bad))
        return False

    def _accept_command(self, msg: Message) -> None:
        self._cmds_since_hello += 1
        self.last_rx = time.monotonic()
        if msg.echo > 0:
            self.rtt = self.last_rx - msg.echo
        self._pending[msg.ack] = msg.values.copy()
        if len(self._pending) > 8:
            for k in sorted(self._pending)[:-8]:
                del self._pending[k]

    def begin_step(self, budget: float | None = None) -> None:
        """Start a read window (the runtime calls this once per step): resets the per-window
        bounds and :attr:`step_rx_s`, :attr:`step_rx_n`. ``budget`` overrides
        :attr:`rx_budget` for this window. A window also restarts by itself after one plant
        step."""
        self._win_start = time.monotonic()
        self._left_own = self.rx_max_commands
        self._left_drop = self._left_lobby = self.rx_max_datagrams
        self._own_s = 0.0  # CPU time spent on the owner's datagrams after the first
        self._own_held = False  # the awaited answer (by its header) waits for the next window
        self._left_s = self.rx_budget if budget is None else float(budget)
        self._win_capped = False
        self.step_rx_s = 0.0
        self.step_listen_s = 0.0
        self.step_rx_n = 0
        self.step_dropped = 0

    def _capped(self, where: str) -> None:
        """A bound stopped the reading with data left waiting: count the window."""
        if not self._win_capped:
            self._win_capped = True
            self.counters["rx_capped"] += 1
            self._note("receive_bound", None, f"read bound reached on the {where} socket "
                       f"({self.counters['rx_capped']} steps capped)")

    def _room(self) -> bool:
        """True while the listening socket may still be read in this window."""
        return self._left_lobby > 0 and (self._left_s > 0
                                         or self._left_lobby == self.rx_max_datagrams)

    def _own_room(self) -> bool:
        """True while the owner's datagrams may still be handled in this window."""
        return self._left_own > 0 and (self._left_own == self.rx_max_commands
                                       or self._own_s < self.rx_owner_budget)

    def _drop_room(self) -> bool:
        """True while the owner's datagrams beyond the count may still be read and dropped in
        this window."""
        return self._left_own == 0 and self._left_drop > 0 and not self._own_held

    def _claim(self, data: bytes) -> int:
        """What the header of a datagram of the owner claims, read without parsing or trusting
        anything: -1 a command of the current session answering an earlier observation than
        the one awaited (useless: :meth:`wait_command` would drop it as stale), 1 a command
        answering the awaited observation, 0 anything else. A datagram that claims a current
        answer is handled, and validated, as any other."""
        if len(data) < HEADER_SIZE or self._awaited == 0 or not self.connected:
            return 0
        magic, _ver, typ, _count, session, _seq, ack = HEADER.unpack_from(data)[:7]
        if magic != MAGIC or typ & ~FLAG_AUTH != MsgType.CMD or session != self.session:
            return 0
        return -1 if 0 < ack < self._awaited else int(ack == self._awaited)

    def _drop_own(self) -> None:
        """Count one of the owner's datagrams read and dropped unparsed."""
        if self._left_drop > 0:
            self._left_drop -= 1
        else:
            self._left_own -= 1
        self.counters["rx_dropped"] += 1
        self.step_dropped += 1

    def poll(self) -> None:
        """Read and handle the datagrams waiting (non-blocking), within the window's bounds.

        The owner's socket first: at most ``rx_max_commands`` datagrams handled, within
        ``rx_owner_budget`` s of CPU time after the first; a command whose header says it
        answers an earlier observation than the one awaited is dropped unparsed; once the
        count is reached, at most ``rx_max_datagrams`` more are read and dropped unparsed
        (counted as ``rx_dropped``), except one whose header claims to answer the awaited
        observation, which waits for the next window. Then the listening socket: at most
        ``rx_max_datagrams`` and ``rx_budget`` s of wall time. What is left waits for the next
        window. The CPU time this thread spends here is added to :attr:`step_rx_s`."""
        c0 = time.thread_time()
        t0 = time.monotonic()
        if t0 - self._win_start >= self.layout.dt:
            self.begin_step()
        own = self._own
        own_fd = own.fileno() if own is not None else -1
        lobby, lobby_fd = self.sock, self._lobby_fd
        own_ok, lobby_ok = own is not None, True
        stop = t0 + self._left_s
        n = 0
        while own_ok or lobby_ok:
            ready = self._poller.poll(0)
            if not ready:
                break
            fds = {fd for fd, _ in ready}
            progressed = False
            for ok, fd, sock in ((own_ok, own_fd, own), (lobby_ok, lobby_fd, lobby)):
                if not ok or fd not in fds:
                    continue
                if sock is own:
                    handle = self._own_room()  # the first datagram of a window always is
                    room = handle or self._drop_room()
                else:  # the first datagram of a window is always read (progress)
                    room = self._left_lobby > 0 and (
                        self._left_lobby == self.rx_max_datagrams or time.monotonic() < stop)
                if room and sock is own and not handle:
                    try:  # beyond the count: look at the header before dropping
                        head = sock.recv(HEADER_SIZE, socket.MSG_PEEK)
                    except OSError:
                        head = b""
                    if self._claim(head) == 1:  # the awaited answer (it says): next window
                        self._own_held = True
                        room = False
                if not room:
                    self._capped("owner's" if sock is own else "listening")
                    if sock is own:
                        own_ok = False
                    else:
                        lobby_ok = False
                    continue
                progressed = True
                c1 = time.thread_time()
                try:
                    data, addr = sock.recvfrom(MAX_DATAGRAM)
                except OSError:  # nothing after all, or ICMP port unreachable (owner gone)
                    continue
                first_own = False
                if sock is own:
                    if not handle:  # more than a step may handle: dropped, never parsed
                        self._drop_own()
                        continue
                    if self._claim(data) == -1:  # a stale answer: dropped, never parsed
                        self._drop_own()
                        continue
                    first_own = self._left_own == self.rx_max_commands
                    self._left_own -= 1
                else:
                    self._left_lobby -= 1
                n += 1
                self._handle(data, addr)
                if sock is lobby:
                    self.step_listen_s += time.thread_time() - c1
                elif not first_own:
                    self._own_s += time.thread_time() - c1
            if not progressed:
                break
        self._left_s = max(0.0, stop - time.monotonic())
        self.step_rx_s += time.thread_time() - c0
        self.step_rx_n += n

    def send_obs(self, sim_time: float, values) -> int:
        """Send one observation to the owner (if connected); returns its sequence number (0
        if none)."""
        if not self.connected:
            return 0
        seq = self._awaited = self._next()
        self._send(pack(MsgType.OBS, self.session, seq, values, sim_time=sim_time,
                        sent=time.monotonic(), signer=self._tx))
        return seq

    def probe(self, values, timeout: float, interval: float = 0.05) -> bool:
        """Readiness handshake before the clock starts: send ``values`` as a probe observation
        (sim_time = -1) every ``interval`` s until the owner answers one (True) or ``timeout``
        s pass (False). The client warms its controller up on a probe and resets it."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            self.begin_step()
            self.poll()
            if not self.connected:
                self._wait_readable(min(end, time.monotonic() + 0.005))
                continue
            seq = self._awaited = self._next()
            self._send(pack(MsgType.OBS, self.session, seq, values, sim_time=-1.0,
                            sent=time.monotonic(), signer=self._tx))
            got = self.wait_command(seq, min(end, time.monotonic() + interval), count=False)
            if got is not None:
                self._pending.clear()
                return True
        return False

    def _wait_readable(self, deadline: float) -> None:
        """Sleep until a socket that may still be read has data, or ``deadline``."""
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            return
        socks = []
        if self._own is not None and (self._own_room() or self._drop_room()):
            socks.append(self._own)
        if self._room():
            socks.append(self.sock)
        if len(socks) < 1 + (self._own is not None):
            # a socket waits for the next window: wake up when it starts
            remaining = min(remaining, max(self._win_start + self.layout.dt - time.monotonic(),
                                           1e-5))
        if socks:
            select.select(socks, [], [], remaining)
        else:
            time.sleep(remaining)

    def wait_command(self, ack: int, deadline: float, count: bool = True):
        """Wait until ``deadline`` (monotonic) for the command answering observation ``ack``.

        Returns the command values (ndarray) or None (counted as ``late``). Commands answering
        other observations are counted as ``stale`` and dropped."""
        self._awaited = ack
        while True:
            self.poll()
            if ack in self._pending:
                vals = self._pending.pop(ack)
                stale = [k for k in self._pending if k < ack]
                for k in stale:
                    del self._pending[k]
                self.counters["stale"] += len(stale)
                return vals
            if deadline - time.monotonic() <= 0:
                self.counters["late"] += count
                return None
            self._wait_readable(deadline)


class ControllerClient:
    """The controller's end of the link (client library).

    Parameters
    ----------
    host, port : str, int
        The plant's address.
    name : str
        Sent in HELLO (shown in the plant's events).
    key, key_file : bytes or str, path, optional
        The plant's shared key (see :func:`~downhole.sil.protocol.load_key`; default: the
        environment variable ``DOWNHOLE_LINK_KEY`` if set). Required when the plant is not on
        loopback.
    bind : (str, int), optional
        Local address and port to send from (a PLC with a fixed source port; default: any).

    Raises
    ------
    DownholeInputError
        A plant beyond loopback without a key, a bad key, or a local address that cannot be
        bound.

    Examples
    --------
    >>> client = ControllerClient("127.0.0.1", 47600)          # doctest: +SKIP
    >>> layout = client.connect()                              # doctest: +SKIP
    >>> client.serve(my_controller)                            # doctest: +SKIP
    """

    def __init__(self, host: str, port: int, name: str = "controller", *, key=None,
                 key_file=None, bind: tuple | None = None):
        # the shared key and its signer: HELLO, CHALLENGE
        self._key, self._signer = _shared_key(key, key_file, host, "the plant at")
        # keyed: the session keys (controller -> plant, plant -> controller) and the last
        # counter accepted from the plant; ended sessions of this client (keyless: None)
        self._tx: Signer | None = None
        self._rx: Signer | None = None
        self._rx_last = 0
        self._ended: set = set()
        self._ended_order: deque = deque(maxlen=64)
        self.addr = (host, int(port))
        self.name = name
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            if bind is not None:
                self.sock.bind((bind[0], int(bind[1])))
            self.sock.connect(self.addr)
        except OSError as exc:
            self.sock.close()
            raise DownholeInputError(f"cannot open the UDP link to {host}:{port}"
                                     + (f" from {bind[0]}:{bind[1]}" if bind else "")
                                     + f": {exc}") from None
        self.layout: Layout | None = None
        self.session = 0
        self.seq = 0
        self.counters = {k: 0 for k in LINK_COUNTERS}
        self._obs_seq = _SeqTracker()

    def _next(self) -> int:
        self.seq = (self.seq + 1) & 0xFFFFFFFF
        return self.seq

    @property
    def authenticated(self) -> bool:
        """True when the link is keyed (HMAC tags, challenge handshake)."""
        return self._signer is not None

    def connect(self, timeout: float = 10.0) -> Layout:
        """Say HELLO (a fresh nonce each time, repeated until answered) and, on a keyed link,
        answer the plant's challenge; returns the plant's layout.

        Raises
        ------
        TimeoutError
            No layout within ``timeout`` seconds (the message says what was heard instead: a
            plant of another protocol version, failed authentication).
        """
        end = time.monotonic() + timeout
        heard = ""
        wait = 0.1
        while time.monotonic() < end:
            nonce = os.urandom(NONCE_SIZE)
            try:
                self.sock.send(pack_hello(self._next(), nonce, self.name, signer=self._signer))
            except OSError:
                pass
            layout, what = self._handshake(nonce, min(end, time.monotonic() + wait))
            heard = what or heard
            if layout is not None:
                return layout
            if self._signer is not None:  # a slow plant: give the challenge more time
                wait = min(1.0, 1.5 * wait)
        raise TimeoutError(f"no layout from the plant at {self.addr[0]}:{self.addr[1]} within "
                           f"{timeout} s{heard} (is it running, on this port, free - another "
                           f"controller may own the session - and with the same key?)")

    def _handshake(self, nonce: bytes, deadline: float):
        """Wait until ``deadline`` for the answer to the HELLO with ``nonce``: ``(layout or
        None, what was heard instead or "")``."""
        c = self.counters
        heard = ""
        pending = None  # (session, c2p, p2c) once the plant's challenge is answered
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return None, heard
            if not select.select([self.sock], [], [], remaining)[0]:
                return None, heard
            try:
                data = self.sock.recv(MAX_DATAGRAM)
            except OSError:  # ICMP port unreachable: no plant yet
                time.sleep(min(0.05, max(0.0, deadline - time.monotonic())))
                return None, heard
            try:
                msg, tagged, end = parse(data)
            except VersionMismatch as exc:
                c["malformed"] += 1
                c["version_mismatch"] += 1
                heard = f"; the plant answered in {exc}"
                continue
            except MalformedPacket:
                c["malformed"] += 1
                continue
            signed, tag = data[:end], data[end:]
            if msg.type == MsgType.REFUSE and not tagged:
                text = msg.values.tobytes().rstrip(b"\0").decode("utf-8", "replace")[:200]
                heard = f"; the plant refused: {text}"
                continue
            if tagged != (self._signer is not None):
                c["auth_failed"] += 1
                heard = ("; its answers fail authentication: "
                         + ("datagram without the authentication tag this end requires"
                            if self._signer is not None else
                            "authenticated datagram, but this end has no key"))
                continue
            if self._signer is None:
                if msg.type == MsgType.LAYOUT and self._open(msg, None, None) is not None:
                    return self.layout, ""
                continue
            if msg.type == MsgType.CHALLENGE:
                if not self._signer.verify(signed, tag):
                    c["auth_failed"] += 1
                    heard = "; its answers fail authentication: tag mismatch (wrong key?)"
                    continue
                raw = msg.values.tobytes()
                if len(raw) != 2 * NONCE_SIZE or raw[:NONCE_SIZE] != nonce:
                    c["foreign"] += 1  # the answer to an earlier HELLO, or a replay
                    continue
                c2p, p2c = session_signers(self._key, nonce, raw[NONCE_SIZE:], msg.session)
                pending = (msg.session, c2p, p2c)
                try:
                    self.sock.send(pack(MsgType.AUTH, msg.session, self._next(), raw=raw,
                                        signer=c2p))
                except OSError:
                    pass
                continue
            if (msg.type == MsgType.LAYOUT and pending is not None
                    and msg.session == pending[0]):
                if not pending[2].verify(signed, tag):
                    c["auth_failed"] += 1
                    continue
                if self._open(msg, pending[1], pending[2]) is not None:
                    return self.layout, ""
                continue
            c["foreign"] += 1

    def _open(self, msg: Message, c2p, p2c) -> Layout | None:
        """Start the session the plant's LAYOUT ``msg`` announces (None, counted as malformed,
        when its payload is not a layout)."""
        try:
            layout = unpack_layout(msg.values.tobytes())
        except MalformedPacket:
            self.counters["malformed"] += 1
            return None
        self._close_session()
        self.layout = layout
        self.session = msg.session
        self._tx, self._rx = c2p, p2c
        self._rx_last = msg.seq
        self._obs_seq.reset()
        return layout

    def _close_session(self) -> None:
        if self._rx is not None:
            _remember(self._ended, self._ended_order, self.session)
        self._tx = self._rx = None

    def receive(self, timeout: float):
        """Next in-order observation as ``(seq, sim_time, sent, values)``; None on timeout;
        ``"bye"`` when the plant closed."""
        c = self.counters
        keyed = self._signer is not None
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
                msg, tagged, dend = parse(data)
            except VersionMismatch:
                c["malformed"] += 1
                c["version_mismatch"] += 1
                continue
            except MalformedPacket:
                c["malformed"] += 1
                continue
            if tagged != keyed:
                c["auth_failed"] += 1
                continue
            if keyed:
                if self._rx is None or msg.session != self.session:
                    c["replayed" if msg.session in self._ended else "foreign"] += 1
                    continue
                if not self._rx.verify(data[:dend], data[dend:]):
                    c["auth_failed"] += 1
                    continue
                if msg.seq <= self._rx_last:
                    c["replayed"] += 1
                    continue
            c["rx"] += 1
            if msg.session != self.session:
                c["foreign"] += 1
                continue
            if msg.type == MsgType.BYE:
                c["bye"] += 1
                if keyed:
                    self._rx_last = msg.seq
                    self._close_session()
                return "bye"
            if msg.type != MsgType.OBS:
                continue
            if msg.values.size != len(self.layout.observations):
                c["wrong_size"] += 1
                continue
            if keyed:
                if msg.seq > self._rx_last + 1:
                    c["lost"] += msg.seq - self._rx_last - 1
                self._rx_last = msg.seq
            elif not self._obs_seq.classify(msg.seq, c):
                continue
            if msg.sim_time >= 0 and select.select([self.sock], [], [], 0)[0]:
                c["stale"] += 1  # a newer observation is waiting: answer that one
                end = time.monotonic() + timeout
                continue
            return msg.seq, msg.sim_time, msg.sent, msg.values

    def send_command(self, ack: int, sim_time: float, echo: float, values) -> None:
        """Send the command answering observation ``ack`` (values in layout order)."""
        self.sock.send(pack(MsgType.CMD, self.session, self._next(), values, ack=ack,
                            sim_time=sim_time, sent=time.monotonic(), echo=echo,
                            signer=self._tx))
        self.counters["tx"] += 1

    def serve(self, controller, *, idle_timeout: float = 5.0, max_steps: int | None = None,
              reference: dict | None = None, realtime: bool = False,
              hold: dict | None = None) -> int:
        """Answer observations with ``controller.command(t, observation, reference)`` until the
        plant says BYE, nothing arrives for ``idle_timeout`` s, or ``max_steps`` answers.

        ``observation`` is a dict of the layout's names; ``reference`` is the ``reference``
        argument if given, else built from the observations ``reference_axial_velocity`` and
        ``reference_angular_velocity`` when the plant sends them. The command dict names the
        layout's commands; a command the controller does not set (a rotary controller on a plant
        that also takes an axial command) is sent at its ``hold`` value, and its absence without
        one is an error. ``realtime``: try SCHED_FIFO for this thread while serving. Returns the
        number of commands sent.
        """
        from downhole.sil.scheduling import elevate_priority

        restore = elevate_priority()[0] if realtime else (lambda: None)
        try:
            return self._serve(controller, idle_timeout, max_steps, reference, dict(hold or {}))
        finally:
            restore()

    def _serve(self, controller, idle_timeout, max_steps, reference, hold) -> int:
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
                ref = {"reference_axial_velocity": obs["reference_axial_velocity"],
                       "reference_angular_velocity": obs["reference_angular_velocity"]}
            probe = t < 0
            cmd = controller.command(max(t, 0.0), obs, ref)
            try:
                out = [float(cmd[c] if c in cmd else hold[c]) for c in cnames]
            except KeyError as exc:
                raise DownholeInputError(f"controller command lacks {exc.args[0]!r}; the plant "
                                         f"expects {cnames} (give hold= for the commands the "
                                         "controller does not set)") from None
            if probe:  # readiness probe: the call above warmed the controller up
                controller.reset()
                self.send_command(seq, t, stamp, out)
                continue
            self.send_command(seq, t, stamp, out)
            sent += 1
        return sent

    def close(self) -> None:
        """Say BYE to the plant and close the socket."""
        try:
            if self._signer is None or self._tx is not None:  # keyed: only in a session
                self.sock.send(pack(MsgType.BYE, self.session, self._next(), signer=self._tx))
        except OSError:
            pass
        self._close_session()
        self.sock.close()
