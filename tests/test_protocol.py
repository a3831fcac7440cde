"""Serial framing and message codecs: exact bytes, robustness, tinyos3 cross-check."""
import random

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from motecal.line import protocol as P


def test_crc_is_xmodem():
    assert P.crc16(b"123456789") == 0x31C3


def test_observed_tinyos_frame_decodes():
    # from tinyos-facts.md: a real TinyOS app's frame
    raw = bytes.fromhex("7e4500ffff000002008900 01c0247e".replace(" ", ""))
    frames = P.decode_stream(raw)
    assert len(frames) == 1
    am = frames[0].am()
    assert am == P.AMPacket(0xFFFF, 0x0000, 0x00, 0x89, b"\x00\x01")
    assert P.encode_am(am) == raw


def _sample_frame(seq, recs, src=1, flags=0):
    return P.encode_am(P.AMPacket(0, src, P.DEFAULT_GROUP, P.AM_NINEDOF_SAMPLES_MSG,
                                  P.pack_samples(seq, flags, recs)))


def test_samples_roundtrip_and_escaping():
    recs = np.array([[0x7E7D, -1, 0x7E, 0x7D, 32767, -32768, -4096, 0, 1]] * 3, np.int16)
    fr = _sample_frame(0x7E7D, recs, src=0x7D7E, flags=0x31)
    assert fr.count(b"\x7e") == 2, "inner flags must be escaped"
    (frame,) = P.decode_stream(fr)
    am = frame.am()
    assert am.src == 0x7D7E and am.am_type == 0x60
    s = P.decode_message(am)
    assert s.seq == 0x7E7D and s.flags == 0x31 and s.corrected and s.version_low == 3
    assert np.array_equal(s.records, recs)


def test_length_mismatch_rejected():
    payload = P.pack_samples(1, 0, np.zeros((2, 9), np.int16))
    body = bytes((P.PROTO_PACKET_NOACK, 0)) + P.AM_HEADER.pack(0, 1, len(payload) + 1, 0x22, 0x60) + payload
    dec = P.FrameDecoder()
    assert dec.feed(P.encode_frame(body)) == []
    assert dec.stats.bad_frames == 1
    # count field disagreeing with the length
    bad = bytearray(payload)
    bad[3] = 3
    assert P.unpack_samples(bytes(bad)) is None
    assert P.unpack_samples(payload[:-1]) is None


def test_end_of_stream_in_a_frame_is_cut_off_not_a_crc_error():
    fr = _sample_frame(9, np.arange(18, dtype=np.int16).reshape(2, 9))
    dec = P.FrameDecoder()
    assert len(dec.feed(fr + fr[:-12])) == 1              # the second one is cut short
    assert dec.finish() == [] and dec.finish() == []
    assert (dec.stats.cut_off, dec.stats.crc_errors, dec.stats.bad_frames) == (1, 0, 0)
    dec = P.FrameDecoder()                                  # whole, only the closing flag missing
    assert dec.feed(fr[:-1]) == []
    (f,) = dec.finish()
    assert P.decode_message(f.am()).seq == 9 and dec.stats.cut_off == 0 and dec.stats.frames == 1


def test_ack_and_packet_ack_frames():
    am = P.AMPacket(5, 0, 0x22, P.AM_NINEDOF_CAL_QUERY_MSG, P.CAL_QUERY.pack(mote=5, offset=20))
    fr = P.encode_am(am, ack_seq=0x7E)
    (f,) = P.decode_stream(fr)
    assert f.protocol == P.PROTO_PACKET_ACK and f.seq == 0x7E and f.am() == am
    (a,) = P.decode_stream(P.encode_ack(0x7E))
    assert a.protocol == P.PROTO_ACK and a.seq == 0x7E
    assert P.decode_message(am) == {"mote": 5, "offset": 20, "flags": 0}


def test_fixed_messages_roundtrip():
    data = bytes(range(20))
    v = dict(mote=7, version=513, offset=40, len=20, data=data)
    assert P.CAL_FRAG.unpack(P.CAL_FRAG.pack(**v)) == v
    assert P.CAL_FRAG.size == 26 and P.CAL_REPORT.size == 33 and P.CAL_REPORT.earlier == (28,)
    with pytest.raises(ValueError, match="5 bytes, expected 26 or more"):
        P.CAL_FRAG.unpack(b"\0" * 5)


def _am(spec, payload):
    return P.AMPacket(0, 7, P.DEFAULT_GROUP, spec.am_type, payload)


@pytest.mark.parametrize("spec", [s for s in P.FIXED_MESSAGES.values()], ids=lambda s: s.name)
def test_messages_grow_at_their_end(spec):
    """The rule for every fixed message (NineDofMsg.h, "How messages
    change"): a payload of the current size or of one of its earlier sizes
    decodes, the fields appended since absent; a longer one (a newer image's)
    decodes by the fields known, the rest ignored; any other length is
    refused (None), never raised."""
    values = {f.name: (bytes(range(1, f.count + 1)) if f.fmt == "B" else
                       tuple(range(1, f.count + 1))) if f.count > 1 else i + 1
              for i, f in enumerate(spec.fields)}
    full = spec.pack(**values)
    assert P.decode_message(_am(spec, full)) == values
    assert P.decode_message(_am(spec, full + b"\x99" * 7)) == values      # a newer layout
    sizes = spec.earlier + (spec.size,)
    for n in range(len(full)):
        got = P.decode_message(_am(spec, full[:n]))
        if n in sizes:
            known = {k: v for k, v in values.items() if k not in spec.fields_since(n)}
            assert got == known, n
            assert spec.fields_since(n) and list(got) == [f.name for f in spec.fields][:len(got)]
        else:
            assert got is None, n


def test_an_earlier_size_must_end_at_a_field():
    with pytest.raises(ValueError, match="must end at fields"):
        P.MessageSpec("x", None, (P.Field("a", P.U16), P.Field("b", P.U16)), earlier=(3,))
    with pytest.raises(ValueError, match="oldest first"):
        P.MessageSpec("x", None, (P.Field("a", P.U8), P.Field("b", P.U8), P.Field("c", P.U8)),
                      earlier=(2, 1))


def _stream(n=200, seed=0):
    rng = np.random.default_rng(seed)
    frames = []
    for i in range(n):
        recs = rng.integers(-32768, 32767, size=(int(rng.integers(1, 6)), 9)).astype(np.int16)
        frames.append(_sample_frame(i, recs, src=int(rng.integers(0, 65535))))
    return frames


STREAM = _stream()
WHOLE = b"".join(STREAM)
EXPECTED = P.decode_stream(WHOLE)


def test_stream_decodes_all():
    assert len(EXPECTED) == len(STREAM)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.integers(min_value=0, max_value=len(WHOLE)), max_size=40))
def test_any_chunking_gives_same_frames(cuts):
    cuts = sorted(set(cuts))
    dec = P.FrameDecoder()
    out = []
    prev = 0
    for c in cuts + [len(WHOLE)]:
        out += dec.feed(WHOLE[prev:c])
        prev = c
    out += dec.feed(b"\x7e")
    assert out == EXPECTED


@settings(max_examples=200, deadline=None)
@given(st.integers(min_value=0, max_value=len(WHOLE) - 1), st.integers(min_value=1, max_value=255))
def test_single_byte_corruption_never_yields_wrong_frame(pos, xor):
    data = bytearray(WHOLE)
    data[pos] ^= xor
    got = P.decode_stream(bytes(data))
    good = set(EXPECTED)
    assert all(f in good for f in got)
    assert len(got) >= len(EXPECTED) - 2     # one corrupted byte can break at most 2 frames


@settings(max_examples=100, deadline=None)
@given(st.binary(max_size=300), st.integers(min_value=0, max_value=len(STREAM)))
def test_garbage_between_frames_resyncs(garbage, where):
    data = b"".join(STREAM[:where]) + garbage + b"".join(STREAM[where:])
    got = P.decode_stream(data)
    good = set(EXPECTED)
    assert all(f in good for f in got)
    # garbage can swallow at most the frame right after it
    assert len(got) >= len(EXPECTED) - 1


def test_million_random_bytes_never_raise():
    rng = random.Random(1)
    dec = P.FrameDecoder()
    total = 0
    data = rng.randbytes(1_000_000)
    # sprinkle flags so that many candidate frames are tried
    data = bytearray(data)
    for i in range(0, len(data), 37):
        data[i] = 0x7E
    for i in range(0, len(data), 4093):
        total += len(dec.feed(bytes(data[i:i + 4093])))
    assert dec.stats.crc_errors + dec.stats.bad_frames > 10000
    # a random 16-bit CRC passes about once in 65536 tries; such frames must still be well-formed
    assert total < 10


def test_tinyos3_reads_our_frames_and_we_read_its_frames():
    tos = pytest.importorskip("tinyos3.tos")

    class Src:
        def __init__(self, data):
            self.data, self.i, self._ts, self.debug = data, 0, None, False
            self.out = []

        def getByte(self):
            if self.i >= len(self.data):
                raise tos.Timeout()
            self.i += 1
            return self.data[self.i - 1]

        def putBytes(self, b):
            self.out.extend(b)

        def getTimeout(self):
            return None

        def setTimeout(self, t):
            pass

    src = Src(WHOLE)
    hdlc = tos.HDLC(src)
    theirs = []
    while (pkt := hdlc.read()) is not None:
        theirs.append(bytes(pkt.data))
    # tinyos3 returns protocol..payload without CRC
    ours = [bytes((f.protocol, f.dispatch)) + f.body for f in EXPECTED]
    assert theirs == ours
    # and their encoder's 0x44 frames decode with ours
    am = P.AMPacket(9, 0, 0x22, P.AM_NINEDOF_CAL_QUERY_MSG, P.CAL_QUERY.pack(mote=9, offset=0))
    payload = list(P.AM_HEADER.pack(am.dest, am.src, len(am.payload), am.group, am.am_type) + am.payload)
    hdlc.write(payload, 0x11)
    (f,) = P.decode_stream(bytes(src.out))
    assert f.protocol == P.PROTO_PACKET_ACK and f.seq == 0x11 and f.am() == am
    assert bytes(src.out) == P.encode_am(am, ack_seq=0x11)
