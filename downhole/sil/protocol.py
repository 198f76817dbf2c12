"""The downhole SIL link protocol: a small, versioned binary format over UDP (struct-packed).

Every datagram is ``header | payload | crc32``, little-endian:

====== ==== ======= =====================================================================
offset size type    field
====== ==== ======= =====================================================================
0      4    4s      magic ``b"DHSL"``
4      1    B       protocol version (:data:`VERSION` = 1)
5      1    B       message type (:class:`MsgType`)
6      2    H       payload count (number of float64 values, or of layout bytes / 8 rounded up)
8      4    I       session id (chosen by the plant at connect; 0 in HELLO)
12     4    I       sequence number of this message (per sender, +1 per message)
16     4    I       acknowledged sequence (CMD: the OBS it answers; others: 0)
20     8    d       simulated time, s (OBS/CMD: the plant time the values belong to)
28     8    d       sender's send timestamp, s (its ``time.monotonic()``)
36     8    d       echoed timestamp, s (CMD: the OBS's send timestamp, for round-trip time)
44     n*8  d...    payload (OBS/CMD: ``count`` float64 values in layout order)
44+8n  4    I       CRC-32 (zlib) of all preceding bytes
====== ==== ======= =====================================================================

Message types: ``HELLO`` (controller -> plant, asks for the layout; its payload may carry a
UTF-8 client name), ``LAYOUT`` (plant -> controller, the named-signal layout, see
:func:`pack_layout`), ``OBS`` (plant -> controller, one per step), ``CMD`` (controller ->
plant, the answer to an OBS), ``BYE`` (either side, closing). A datagram with a wrong magic,
version, length or CRC is *malformed*: counted and dropped, never raised.
"""

from __future__ import annotations

import enum
import struct
import zlib
from dataclasses import dataclass

import numpy as np

__all__ = ["VERSION", "MAGIC", "HEADER", "HEADER_SIZE", "MsgType", "Message", "MalformedPacket",
           "pack", "unpack", "pack_layout", "unpack_layout", "Layout", "MAX_DATAGRAM"]

MAGIC = b"DHSL"
VERSION = 1
HEADER = struct.Struct("<4sBBHIIIddd")
HEADER_SIZE = HEADER.size  # 44
_CRC = struct.Struct("<I")
#: Largest datagram the link sends or accepts (bytes).
MAX_DATAGRAM = 8192


class MsgType(enum.IntEnum):
    """Message types of protocol version 1."""

    HELLO = 1
    LAYOUT = 2
    OBS = 3
    CMD = 4
    BYE = 5


class MalformedPacket(ValueError):
    """A datagram that is not a valid version-1 message (the reason is the message)."""


@dataclass(frozen=True)
class Message:
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
         sent: float = 0.0, echo: float = 0.0, raw: bytes | None = None) -> bytes:
    """Encode one message. ``values`` are float64 (OBS/CMD); ``raw`` bytes for HELLO/LAYOUT
    (padded to a multiple of 8 bytes with zeros; ``count`` = number of 8-byte words)."""
    if raw is not None:
        pad = (-len(raw)) % 8
        body = raw + b"\0" * pad
        count = len(body) // 8
    else:
        body = np.asarray(values, dtype="<f8").tobytes()
        count = len(body) // 8
    if count > 0xFFFF:
        raise ValueError(f"payload of {count} words exceeds the protocol's 65535")
    head = HEADER.pack(MAGIC, VERSION, int(type_), count, session & 0xFFFFFFFF,
                       seq & 0xFFFFFFFF, ack & 0xFFFFFFFF, float(sim_time), float(sent),
                       float(echo))
    msg = head + body
    return msg + _CRC.pack(zlib.crc32(msg))


def unpack(data: bytes) -> Message:
    """Decode one datagram; raises :class:`MalformedPacket` with the reason."""
    n = len(data)
    if n < HEADER_SIZE + 4:
        raise MalformedPacket(f"datagram of {n} bytes is shorter than header + crc")
    magic, ver, typ, count, session, seq, ack, t, sent, echo = HEADER.unpack_from(data)
    if magic != MAGIC:
        raise MalformedPacket(f"bad magic {magic!r}")
    if ver != VERSION:
        raise MalformedPacket(f"protocol version {ver}, this end speaks {VERSION}")
    if n != HEADER_SIZE + 8 * count + 4:
        raise MalformedPacket(f"length {n} does not match count {count}")
    (crc,) = _CRC.unpack_from(data, n - 4)
    if crc != zlib.crc32(data[:n - 4]):
        raise MalformedPacket("crc mismatch")
    try:
        mtype = MsgType(typ)
    except ValueError:
        raise MalformedPacket(f"unknown message type {typ}") from None
    body = data[HEADER_SIZE:n - 4]
    if mtype in (MsgType.OBS, MsgType.CMD):
        values = np.frombuffer(body, dtype="<f8")
    else:
        values = np.frombuffer(body, dtype=np.uint8)
    return Message(mtype, session, seq, ack, t, sent, echo, values)


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
