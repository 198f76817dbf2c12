"""The downhole SIL link protocol: a small, versioned binary format over UDP (struct-packed).

Every datagram is ``header | payload | crc32 [| tag]``, little-endian:

====== ==== ======= =====================================================================
offset size type    field
====== ==== ======= =====================================================================
0      4    4s      magic ``b"DHSL"``
4      1    B       protocol version (:data:`VERSION` = 3)
5      1    B       message type (:class:`MsgType`, low 7 bits) | :data:`FLAG_AUTH` (bit 7)
6      2    H       payload count (number of float64 values, or of raw bytes / 8 rounded up)
8      4    I       session id (chosen by the plant; 0 in HELLO)
12     4    I       sequence number (counter) of this message (per sender, +1 per message)
16     4    I       acknowledged sequence (CMD: the OBS it answers; others: 0)
20     8    d       simulated time, s (OBS/CMD: the plant time the values belong to)
28     8    d       sender's send timestamp, s (its ``time.monotonic()``)
36     8    d       echoed timestamp, s (CMD: the OBS's send timestamp, for round-trip time)
44     n*8  d...    payload (OBS/CMD: ``count`` float64 values in layout order)
44+8n  4    I       CRC-32 (zlib) of all preceding bytes
48+8n  16   16s     only with :data:`FLAG_AUTH`: HMAC-SHA256 tag of all preceding bytes,
                    truncated to :data:`TAG_SIZE` bytes (under which key: see below)
====== ==== ======= =====================================================================

Message types: ``HELLO`` (controller -> plant; payload: a fresh :data:`NONCE_SIZE`-byte nonce,
then the UTF-8 client name), ``CHALLENGE`` (plant -> controller, keyed links only; payload: the
client's nonce, then the plant's fresh nonce; header: the new session id), ``AUTH`` (controller
-> plant, keyed links only; payload: both nonces), ``LAYOUT`` (plant -> controller, the
named-signal layout, see :func:`pack_layout`), ``OBS`` (plant -> controller, one per step),
``CMD`` (controller -> plant, the answer to an OBS), ``BYE`` (either side, closing), ``REFUSE``
(plant -> a peer of another protocol version; payload: the reason, UTF-8). A datagram with a
wrong magic, version, length or CRC is *malformed*: counted and dropped, never raised.

Keyed links (a shared key, :func:`load_key`): every datagram carries the flag
:data:`FLAG_AUTH` and a tag. HELLO and CHALLENGE are tagged under the shared key; the
controller's AUTH proves the key over both nonces and the session id, and from AUTH on every
datagram of the session is tagged under a *session key* derived from the shared key, both
nonces and the session id (:func:`session_signers`; one key per direction, so that a datagram
cannot be reflected back to its sender). A datagram of an earlier session therefore fails, and
within a session the receiver accepts only counters above the last one it accepted (see
:mod:`downhole.sil.link`). The tags give integrity, authenticity and freshness, not
confidentiality: the values travel in clear.

Keyless links (loopback development): no tag, no challenge; HELLO is answered by LAYOUT at
once. An end without a key refuses tagged datagrams; an end with one refuses untagged ones
(:class:`AuthenticationFailed`).

Versions: 1 had no tag; 2 tagged every datagram under the shared key itself (no nonces, so a
captured datagram could be replayed); 3 adds the handshake, the nonce in HELLO and the types
CHALLENGE, AUTH and REFUSE. An end refuses another version with :class:`VersionMismatch` (a
:class:`MalformedPacket` naming both versions); the plant answers such a datagram with a
REFUSE in its own version, which an older client reports as "the plant answered in protocol
version 3" instead of waiting silently.
"""

from __future__ import annotations

import enum
import hashlib
import hmac
import os
import stat
import struct
import zlib
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from downhole.errors import DownholeInputError

__all__ = [
    "FLAG_AUTH",
    "HEADER",
    "HEADER_SIZE",
    "KEY_ENV",
    "MAGIC",
    "MAX_DATAGRAM",
    "MIN_KEY_BYTES",
    "NONCE_SIZE",
    "TAG_SIZE",
    "VERSION",
    "AuthenticationFailed",
    "Layout",
    "MalformedPacket",
    "Message",
    "MsgType",
    "Signer",
    "VersionMismatch",
    "check_tag",
    "load_key",
    "pack",
    "pack_hello",
    "pack_layout",
    "parse",
    "refusal",
    "session_signers",
    "split_hello",
    "unpack",
    "unpack_layout",
]

MAGIC = b"DHSL"
VERSION = 3
#: Bit of the type byte marking an authenticated datagram (tag appended).
FLAG_AUTH = 0x80
#: Bytes of the truncated HMAC-SHA256 tag.
TAG_SIZE = 16
#: Environment variable holding the shared key (when no key or key file is given).
KEY_ENV = "DOWNHOLE_LINK_KEY"
#: Shortest accepted shared key, bytes.
MIN_KEY_BYTES = 16
_MAX_KEY_FILE = 4096
#: Bytes of the handshake nonces (HELLO, CHALLENGE).
NONCE_SIZE = 16
HEADER = struct.Struct("<4sBBHIIIddd")
HEADER_SIZE = HEADER.size  # 44
_CRC = struct.Struct("<I")
#: Largest datagram the link sends or accepts (bytes).
MAX_DATAGRAM = 8192


class MsgType(enum.IntEnum):
    """Message types (1-5 since protocol version 1; 6-8 since version 3)."""

    HELLO = 1
    LAYOUT = 2
    OBS = 3
    CMD = 4
    BYE = 5
    CHALLENGE = 6
    AUTH = 7
    REFUSE = 8


_TYPES = {int(m): m for m in MsgType}


class MalformedPacket(ValueError):
    """A datagram that is not a valid message of this protocol version (the reason is the
    message)."""


class VersionMismatch(MalformedPacket):
    """A well-framed datagram of another protocol version (``version``: the sender's)."""

    def __init__(self, version: int):
        super().__init__(f"protocol version {version}, this end speaks {VERSION}")
        self.version = version


class AuthenticationFailed(MalformedPacket):
    """A datagram whose tag is missing, wrong, or present where no key is configured."""


class Signer:
    """HMAC-SHA256 tags under one shared key (truncated to :data:`TAG_SIZE` bytes).

    Parameters
    ----------
    key : bytes
        The shared key (at least :data:`MIN_KEY_BYTES` bytes).
    """

    def __init__(self, key: bytes):
        if not isinstance(key, (bytes, bytearray)) or len(key) < MIN_KEY_BYTES:
            raise ValueError(f"the link key must be at least {MIN_KEY_BYTES} bytes")
        self._base = hmac.new(bytes(key), digestmod=hashlib.sha256)

    def tag(self, data: bytes) -> bytes:
        """The tag of ``data``."""
        h = self._base.copy()
        h.update(data)
        return h.digest()[:TAG_SIZE]

    def verify(self, data: bytes, tag: bytes) -> bool:
        """True when ``tag`` is the tag of ``data`` (constant-time comparison)."""
        return hmac.compare_digest(self.tag(data), tag)


def load_key(key=None, key_file=None, *, env: bool = True) -> bytes | None:
    """The shared link key: ``key`` itself, else the contents of ``key_file``, else the
    environment variable :data:`KEY_ENV` (when ``env``), else None (no authentication).

    A key file holds the key as text (surrounding whitespace stripped) and must not be readable
    by group or others (POSIX); keys shorter than :data:`MIN_KEY_BYTES` bytes are refused.

    Raises
    ------
    DownholeInputError
        Unreadable or too permissive key file, or a key that is too short (the message names
        the source).
    """
    if key is not None:
        src = "the given key"
        raw = key.encode("utf-8") if isinstance(key, str) else bytes(key)
    elif key_file is not None:
        src = f"key file {key_file}"
        try:
            st = os.stat(key_file)
            if not stat.S_ISREG(st.st_mode):  # a FIFO or a device would block or never end
                raise DownholeInputError(f"the link {src} is not a regular file")
            with open(key_file, "rb") as fh:
                raw = fh.read(_MAX_KEY_FILE + 1)
        except OSError as exc:
            raise DownholeInputError(f"cannot read the link {src}: {exc.strerror}") from None
        if len(raw) > _MAX_KEY_FILE:
            raise DownholeInputError(f"the link {src} is larger than {_MAX_KEY_FILE} bytes; a "
                                     "key is one line")
        raw = raw.strip()
        if os.name == "posix" and st.st_mode & 0o077:
            raise DownholeInputError(f"the link {src} is readable by other users (mode "
                                     f"{st.st_mode & 0o777:o}); run chmod 600 on it")
    elif env and os.environ.get(KEY_ENV):
        src = f"environment variable {KEY_ENV}"
        raw = os.environ[KEY_ENV].strip().encode("utf-8")
    else:
        return None
    if len(raw) < MIN_KEY_BYTES:
        raise DownholeInputError(f"the link key from {src} has {len(raw)} bytes; at least "
                                 f"{MIN_KEY_BYTES} are needed (e.g. `openssl rand -hex 32`)")
    return raw


class Message(NamedTuple):
    """One decoded datagram."""

    type: MsgType
    session: int
    seq: int
    ack: int
    sim_time: float
    sent: float
    echo: float
    values: np.ndarray  # float64 payload (OBS/CMD) or raw bytes as uint8 (HELLO/LAYOUT)


def pack(type_: int, session: int, seq: int, values=(), *, ack: int = 0, sim_time: float = 0.0,
         sent: float = 0.0, echo: float = 0.0, raw: bytes | None = None,
         signer: Signer | None = None) -> bytes:
    """Encode one message. ``values`` are float64 (OBS/CMD); ``raw`` bytes for HELLO/LAYOUT
    (padded to a multiple of 8 bytes with zeros; ``count`` = number of 8-byte words). With a
    ``signer`` the datagram is flagged :data:`FLAG_AUTH` and its tag appended."""
    if raw is not None:
        pad = (-len(raw)) % 8
        body = raw + b"\0" * pad
        count = len(body) // 8
    else:
        body = np.asarray(values, dtype="<f8").tobytes()
        count = len(body) // 8
    if count > 0xFFFF:
        raise ValueError(f"payload of {count} words exceeds the protocol's 65535")
    flags = FLAG_AUTH if signer is not None else 0
    head = HEADER.pack(MAGIC, VERSION, int(type_) | flags, count, session & 0xFFFFFFFF,
                       seq & 0xFFFFFFFF, ack & 0xFFFFFFFF, float(sim_time), float(sent),
                       float(echo))
    msg = head + body
    msg += _CRC.pack(zlib.crc32(msg))
    return msg + signer.tag(msg) if signer is not None else msg


def parse(data: bytes) -> tuple[Message, bool, int]:
    """Check a datagram's framing (length, magic, version, CRC, type) without its tag.

    Returns ``(message, tagged, end)``: the decoded message, whether it carries the flag
    :data:`FLAG_AUTH`, and the offset where its tag starts (the tagged bytes are
    ``data[:end]``, the tag ``data[end:]``). Nothing in the message is trusted until the tag
    is checked (:func:`check_tag`).

    Parameters
    ----------
    data : bytes
        A received datagram.

    Returns
    -------
    tuple of (Message, bool, int)
        The message, whether it is tagged and where the tag starts.

    Raises
    ------
    MalformedPacket
        With the reason (:class:`VersionMismatch` for another protocol version).
    """
    n = len(data)
    if n < HEADER_SIZE + 4:
        raise MalformedPacket(f"datagram of {n} bytes is shorter than header + crc")
    magic, ver, typ, count, session, seq, ack, t, sent, echo = HEADER.unpack_from(data)
    if magic != MAGIC:
        raise MalformedPacket(f"bad magic {magic!r}")
    if ver != VERSION:
        raise VersionMismatch(ver)
    authed = bool(typ & FLAG_AUTH)
    typ &= ~FLAG_AUTH
    end = HEADER_SIZE + 8 * count + 4  # end of the CRC
    if n != end + (TAG_SIZE if authed else 0):
        raise MalformedPacket(f"length {n} does not match count {count}"
                              + (" and tag" if authed else ""))
    (crc,) = _CRC.unpack_from(data, end - 4)
    if crc != zlib.crc32(data[:end - 4]):
        raise MalformedPacket("crc mismatch")
    mtype = _TYPES.get(typ)
    if mtype is None:
        raise MalformedPacket(f"unknown message type {typ}")
    body = data[HEADER_SIZE:end - 4]
    if mtype in (MsgType.OBS, MsgType.CMD):
        values = np.frombuffer(body, dtype="<f8")
    else:
        values = np.frombuffer(body, dtype=np.uint8)
    return Message(mtype, session, seq, ack, t, sent, echo, values), authed, end


def check_tag(data: bytes, authed: bool, end: int, signer: Signer | None) -> None:
    """Raise :class:`AuthenticationFailed` unless the tag of a parsed datagram (:func:`parse`)
    is what ``signer`` expects: present and right with a signer, absent without one.

    Parameters
    ----------
    data : bytes
        The whole datagram.
    authed : bool
        Whether it carries the authentication flag (from :func:`parse`).
    end : int
        Offset where its tag starts (from :func:`parse`).
    signer : Signer or None
        The key this end expects the datagram under; None for a keyless link.

    Raises
    ------
    AuthenticationFailed
        A tag is missing, wrong, or present on a keyless link.
    """
    if signer is not None:
        if not authed:
            raise AuthenticationFailed("datagram without the authentication tag this end "
                                       "requires")
        if not signer.verify(data[:end], data[end:]):
            raise AuthenticationFailed("authentication tag mismatch (wrong key?)")
    elif authed:
        raise AuthenticationFailed("authenticated datagram, but this end has no key")


def unpack(data: bytes, signer: Signer | None = None) -> Message:
    """Decode one datagram and check its tag against ``signer``; raises
    :class:`MalformedPacket` with the reason (:class:`VersionMismatch` for another protocol
    version, :class:`AuthenticationFailed` when the tag does not match ``signer``, is missing
    although a ``signer`` is given, or is present without one). Nothing about the values is
    trusted before these checks pass."""
    msg, authed, end = parse(data)
    check_tag(data, authed, end, signer)
    return msg


def session_signers(key: bytes, client_nonce: bytes, server_nonce: bytes,
                    session: int) -> tuple[Signer, Signer]:
    """The two session keys of a keyed session, as signers: ``(controller_to_plant,
    plant_to_controller)``, each ``HMAC-SHA256(key, label | client_nonce | server_nonce |
    session)`` with the label ``b"DHSL3 c2p"`` or ``b"DHSL3 p2c"`` and the session id as 4
    little-endian bytes. Fresh nonces from both ends make every session's keys new, so no
    datagram of another session verifies; the direction in the label keeps a datagram from
    being reflected to its sender.

    Parameters
    ----------
    key : bytes
        The link key shared by both ends.
    client_nonce, server_nonce : bytes
        The HELLO's and the CHALLENGE's fresh nonces (:data:`NONCE_SIZE` bytes each).
    session : int
        The session id the plant drew.

    Returns
    -------
    tuple of (Signer, Signer)
        Controller-to-plant and plant-to-controller signers.

    Raises
    ------
    ValueError
        A nonce has the wrong length.
    """
    if len(client_nonce) != NONCE_SIZE or len(server_nonce) != NONCE_SIZE:
        raise ValueError(f"nonces must have {NONCE_SIZE} bytes")
    tail = bytes(client_nonce) + bytes(server_nonce) + struct.pack("<I", session & 0xFFFFFFFF)
    out = []
    for label in (b"DHSL3 c2p", b"DHSL3 p2c"):
        out.append(Signer(hmac.new(bytes(key), label + tail, hashlib.sha256).digest()))
    return out[0], out[1]


def pack_hello(seq: int, nonce: bytes, name: str = "", *, signer: Signer | None = None) -> bytes:
    """A HELLO: ``nonce`` (:data:`NONCE_SIZE` fresh random bytes), then the UTF-8 ``name``
    (at most 255 bytes).

    Parameters
    ----------
    seq : int
        The sender's counter.
    nonce : bytes
        :data:`NONCE_SIZE` fresh random bytes (new on every try).
    name : str
        The controller's name, shown by the plant (cut to 255 bytes).
    signer : Signer, optional
        The link key (keyed links), else untagged.

    Returns
    -------
    bytes
        The datagram.

    Raises
    ------
    ValueError
        ``nonce`` has the wrong length.
    """
    if len(nonce) != NONCE_SIZE:
        raise ValueError(f"the HELLO nonce must have {NONCE_SIZE} bytes")
    return pack(MsgType.HELLO, 0, seq, raw=bytes(nonce) + name.encode("utf-8")[:255],
                signer=signer)


def split_hello(msg: Message) -> tuple[bytes, str] | None:
    """``(nonce, name)`` of a HELLO, or None when its payload is shorter than a nonce.

    Parameters
    ----------
    msg : Message
        A parsed HELLO.

    Returns
    -------
    tuple of (bytes, str) or None
        The client nonce and the controller's name.
    """
    raw = msg.values.tobytes()
    if len(raw) < NONCE_SIZE:
        return None
    return raw[:NONCE_SIZE], raw[NONCE_SIZE:].rstrip(b"\0").decode("utf-8", "replace")


def refusal(version: int) -> bytes:
    """The REFUSE this end sends to a peer speaking protocol ``version``: an untagged datagram
    of this end's version whose payload says why (an older peer stops at the version byte and
    reports it).

    Parameters
    ----------
    version : int
        The protocol version the peer spoke.

    Returns
    -------
    bytes
        The datagram.
    """
    text = (f"downhole SIL protocol version {version} refused: this end speaks version "
            f"{VERSION}; run the same downhole release on both ends")
    return pack(MsgType.REFUSE, 0, 0, raw=text.encode("utf-8"))


@dataclass(frozen=True)
class Layout:
    """The named-signal layout the plant announces at connect.

    Attributes
    ----------
    dt : float
        Plant step, s.
    mode : str
        ``"sil"`` (the controller gets observations, returns surface commands) or ``"hil"``
        (the rig gets the last string node's velocities, returns bit velocities).
    observations, commands : tuple of str
        Names, in payload order, of OBS and CMD values.
    units : dict
        Unit of each name ("" when unknown).
    """

    dt: float
    mode: str
    observations: tuple
    commands: tuple
    units: dict


_LAYOUT_HEAD = struct.Struct("<dBHH")  # dt, mode (0 sil, 1 hil), n_obs, n_cmd


def _pstr(s: str) -> bytes:
    b = s.encode("utf-8")
    if len(b) > 255:
        raise ValueError(f"name {s!r} is longer than 255 bytes")
    return bytes([len(b)]) + b


def pack_layout(layout: Layout) -> bytes:
    """Layout payload: ``<d B H H`` (dt, mode 0=sil/1=hil, n_obs, n_cmd), then for every
    observation and then every command: u8 length + UTF-8 name, u8 length + UTF-8 unit."""
    out = [_LAYOUT_HEAD.pack(layout.dt, 1 if layout.mode == "hil" else 0,
                             len(layout.observations), len(layout.commands))]
    for name in (*layout.observations, *layout.commands):
        out.append(_pstr(name))
        out.append(_pstr(layout.units.get(name, "")))
    return b"".join(out)


def unpack_layout(raw: bytes) -> Layout:
    """Inverse of :func:`pack_layout` (trailing zero padding ignored)."""
    try:
        dt, mode, n_obs, n_cmd = _LAYOUT_HEAD.unpack_from(raw)
        pos = _LAYOUT_HEAD.size
        names, units = [], {}
        for _ in range(n_obs + n_cmd):
            ln = raw[pos]
            name = raw[pos + 1:pos + 1 + ln].decode("utf-8")
            pos += 1 + ln
            lu = raw[pos]
            unit = raw[pos + 1:pos + 1 + lu].decode("utf-8")
            pos += 1 + lu
            names.append(name)
            units[name] = unit
    except (struct.error, IndexError, UnicodeDecodeError) as exc:
        raise MalformedPacket(f"bad layout payload: {exc}") from None
    return Layout(dt, "hil" if mode == 1 else "sil", tuple(names[:n_obs]), tuple(names[n_obs:]),
                  units)
