"""SIL link protocol: byte layout, round trips, and every malformed case rejected (not raised)."""

import struct
import zlib

import numpy as np
import pytest

from downhole.sil.protocol import (
    HEADER_SIZE,
    MAGIC,
    VERSION,
    Layout,
    MalformedPacket,
    MsgType,
    pack,
    pack_layout,
    unpack,
    unpack_layout,
)


def test_header_byte_layout_matches_the_documented_offsets():
    data = pack(MsgType.CMD, 0xDEADBEEF, 7, [1.5, -2.0], ack=6, sim_time=0.25, sent=3.0,
                echo=2.5)
    assert HEADER_SIZE == 44 and len(data) == 44 + 16 + 4
    assert data[0:4] == MAGIC and data[4] == VERSION and data[5] == 4
    assert struct.unpack_from("<H", data, 6)[0] == 2
    assert struct.unpack_from("<III", data, 8) == (0xDEADBEEF, 7, 6)
    assert struct.unpack_from("<ddd", data, 20) == (0.25, 3.0, 2.5)
    assert struct.unpack_from("<dd", data, 44) == (1.5, -2.0)
    assert struct.unpack_from("<I", data, 60)[0] == zlib.crc32(data[:60])
    m = unpack(data)
    assert (m.type, m.session, m.seq, m.ack) == (MsgType.CMD, 0xDEADBEEF, 7, 6)
    assert m.values.tolist() == [1.5, -2.0] and m.echo == 2.5


def test_layout_round_trip():
    lay = Layout(1e-3, "hil", ("time", "last_node_axial_velocity"),
                 ("bit_axial_velocity", "bit_angular_velocity"),
                 {"time": "s", "last_node_axial_velocity": "m/s", "bit_axial_velocity": "m/s",
                  "bit_angular_velocity": "rad/s"})
    msg = unpack(pack(MsgType.LAYOUT, 1, 1, raw=pack_layout(lay)))
    back = unpack_layout(msg.values.tobytes())
    assert back == lay


@pytest.mark.parametrize("mutate, reason", [
    (lambda d: d[:10], "shorter"),
    (lambda d: b"XXXX" + d[4:], "magic"),
    (lambda d: d[:4] + bytes([9]) + d[5:], "version"),
    (lambda d: d[:-5] + bytes([d[-5] ^ 0xFF]) + d[-4:], "crc"),
    (lambda d: d + b"\0" * 8, "length"),
    (lambda d: _recrc(d[:5] + bytes([77]) + d[6:-4]), "unknown message type"),
])
def test_malformed_datagrams_raise_malformed_packet(mutate, reason):
    good = pack(MsgType.OBS, 3, 9, np.arange(5.0))
    with pytest.raises(MalformedPacket, match=reason):
        unpack(mutate(good))


def _recrc(body):
    return body + struct.pack("<I", zlib.crc32(body))


def test_authenticated_datagram_carries_a_truncated_hmac_sha256_tag():
    import hashlib
    import hmac

    from downhole.sil.protocol import FLAG_AUTH, TAG_SIZE, AuthenticationFailed, Signer

    key = b"k" * 32
    plain = pack(MsgType.CMD, 5, 7, [1.5, -2.0], ack=6)
    data = pack(MsgType.CMD, 5, 7, [1.5, -2.0], ack=6, signer=Signer(key))
    assert len(data) == len(plain) + TAG_SIZE == 44 + 16 + 4 + 16
    assert data[5] == MsgType.CMD | FLAG_AUTH and data[6:-20] == plain[6:-4]
    body = data[:-16]
    assert struct.unpack_from("<I", body, len(body) - 4)[0] == zlib.crc32(body[:-4])
    assert data[-16:] == hmac.new(key, body, hashlib.sha256).digest()[:16]
    assert unpack(data, Signer(key)).values.tolist() == [1.5, -2.0]
    with pytest.raises(AuthenticationFailed, match="mismatch"):
        unpack(data, Signer(b"x" * 32))
    with pytest.raises(ValueError, match="at least 16"):
        Signer(b"short")


def test_session_keys_are_fresh_per_nonce_session_and_direction():
    import hashlib
    import hmac
    import os

    from downhole.sil.protocol import (
        NONCE_SIZE,
        AuthenticationFailed,
        pack_hello,
        refusal,
        session_signers,
        split_hello,
    )

    key, nc, ns = b"k" * 32, os.urandom(NONCE_SIZE), os.urandom(NONCE_SIZE)
    c2p, p2c = session_signers(key, nc, ns, 7)
    data = pack(MsgType.CMD, 7, 3, [1.0, 2.0], signer=c2p)
    body = data[:-16]
    expect = hmac.new(hmac.new(key, b"DHSL3 c2p" + nc + ns + struct.pack("<I", 7),
                               hashlib.sha256).digest(), body, hashlib.sha256).digest()[:16]
    assert data[-16:] == expect
    assert unpack(data, c2p).values.tolist() == [1.0, 2.0]
    others = (p2c, session_signers(key, nc, ns, 8)[0], session_signers(key, ns, nc, 7)[0],
              session_signers(key, nc, os.urandom(NONCE_SIZE), 7)[0],
              session_signers(b"x" * 32, nc, ns, 7)[0])
    for other in others:  # the other direction, session, nonces or key: refused
        with pytest.raises(AuthenticationFailed):
            unpack(data, other)
    hello = unpack(pack_hello(1, nc, "plc-7"))
    assert hello.type == MsgType.HELLO and hello.session == 0
    assert split_hello(hello) == (nc, "plc-7")
    assert split_hello(unpack(pack(MsgType.HELLO, 0, 1, raw=b"short"))) is None
    r = unpack(refusal(2))
    assert r.type == MsgType.REFUSE and VERSION == 3
    assert r.values.tobytes().rstrip(b"\0").decode().startswith(
        "downhole SIL protocol version 2 refused: this end speaks version 3")
