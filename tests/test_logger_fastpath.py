"""The logger's fast path (``FrameDecoder.feed_block``: every frame of a read
split, unescaped and checked together; sample messages decoded from the block)
gives the same frames, rows and counters as the simple path: a frame-by-frame
deframer (the decoder as it was before the fast path, written out here) with
``protocol.parse_frame_body`` and ``protocol.decode_message`` per frame, on
streams with random corruption (several seeds) and on hand-made malformed
frames of every kind."""
import re

import numpy as np
import pytest

from motecal.capture.link import LinkTracker
from motecal.capture.logger import Logger
from motecal.line import protocol as P
from motecal.line import sources as S
from motecal.line.samples import SampleBatch, decode_sample_frames
from motecal.sessions.store import open_store

SEEDS = range(6)


# --------------------------------------------------------------------------
# the simple path
# --------------------------------------------------------------------------
_UNESCAPE_RE = re.compile(rb"\x7d(.)", re.S)


def simple_unescape(data: bytes) -> bytes:
    """The general rule only (0x7D, b -> b ^ 0x20), one escape at a time."""
    return _UNESCAPE_RE.sub(lambda m: bytes((m.group(1)[0] ^ 0x20,)), data)


class SimpleDecoder:
    """One frame at a time: split on the flag, unescape, ``parse_frame_body``."""

    def __init__(self):
        self.buf = b""
        self.synced = False
        self.stats = P.DecoderStats()

    def feed(self, data: bytes) -> list[P.Frame]:
        out = []
        if not data:
            return out
        parts = (self.buf + data).split(b"\x7e")
        tail = parts.pop()
        if not self.synced:
            if parts:
                self.stats.garbage_bytes += len(parts[0])
                parts = parts[1:]
                self.synced = True
            else:
                self.stats.garbage_bytes += len(tail)
                tail = b""
        for p in parts:
            if not p:
                continue
            if len(p) > 2 * P.MAX_FRAME + 2:
                self.stats.garbage_bytes += len(p)
                continue
            raw = simple_unescape(p)
            frame = P.parse_frame_body(raw)
            if frame is None:
                if len(raw) >= 4 and P.crc16(raw[:-2]) != (raw[-2] | (raw[-1] << 8)):
                    self.stats.crc_errors += 1
                else:
                    self.stats.bad_frames += 1
                continue
            out.append(frame)
        self.stats.frames += len(out)
        if len(tail) > 2 * P.MAX_FRAME + 2:
            self.stats.garbage_bytes += len(tail)
            tail = b""
            self.synced = False
        self.buf = tail
        return out

    def finish(self) -> list[P.Frame]:
        tail, self.buf = self.buf, b""
        if not tail:
            return []
        frame = P.parse_frame_body(simple_unescape(tail))
        if frame is None:
            self.stats.cut_off += 1
            return []
        self.stats.frames += 1
        return [frame]


def simple_samples(frames: list[P.Frame]) -> tuple[SampleBatch, list[P.Frame]]:
    """``decode_message`` frame by frame, gathered into a ``SampleBatch``."""
    src, seq, flags, count, recs, others, bad = [], [], [], [], [], [], 0
    for f in frames:
        am = f.am()
        if am is None or am.am_type != P.AM_NINEDOF_SAMPLES_MSG:
            others.append(f)
            continue
        s = P.decode_message(am)
        if s is None:
            bad += 1
            continue
        src.append(am.src)
        seq.append(s.seq)
        flags.append(s.flags)
        count.append(len(s.records))
        recs.append(s.records)
    cnt = np.array(count, np.int64)
    rec_msg = np.repeat(np.arange(len(cnt)), cnt)
    rec_index = np.concatenate([np.arange(c) for c in count]) if count else np.zeros(0, int)
    batch = SampleBatch(np.array(src, np.int64), np.array(seq, np.int64),
                        np.array(flags, np.int64), cnt,
                        np.vstack(recs) if recs else np.zeros((0, 9), np.int16),
                        rec_msg, rec_index.astype(np.int64), bad=bad)
    return batch, others


def simple_log(data: bytes):
    """What the logger does with a recorded file, on the simple path: rows
    (mote, seq, flags, 9 values), temperature readings (mote, seq, count) and
    the tracker (its counters)."""
    dec, tr = SimpleDecoder(), LinkTracker()
    rows, temps = [], []

    def handle(frames):
        batch, others = simple_samples(frames)
        if others:
            tr.other(others)
        r = tr.samples(batch)
        temps.extend((m, u, n) for m, u, _, n in tr.take_temps())
        rows.extend(zip(r.mote.tolist(), r.seq.tolist(), r.flags.tolist(),
                        map(tuple, r.raw.tolist())))

    for i in range(0, len(data), S.READ_SIZE):
        handle(dec.feed(data[i:i + S.READ_SIZE]))
        tr.decoder(dec.stats)
    handle(dec.finish())
    tr.decoder(dec.stats, closed=True)
    return rows, temps, tr


def fast_log(data: bytes, tmp_path):
    """The same file through ``motecal log``'s own loop into sqlite."""
    rec = tmp_path / "line.bin"
    rec.write_bytes(data)
    with open_store(str(tmp_path / "fast.db"), create=True) as st:
        w = st.open_session("s", kind="free")
        lg = Logger(S.parse_port(str(rec)), w, LinkTracker())
        lg.run()
        rows = [(m, q, f, tuple(v)) for m, q, f, *v in st._query(
            "SELECT mote, seq, flags, ax, ay, az, gx, gy, gz, mx, my, mz FROM samples")]
        temps = [(int(m), int(q), int(n)) for m, q, _, _, n in st.temps("s")]
        stats = st.link_stats("s")
    return rows, temps, lg.tracker, stats


# --------------------------------------------------------------------------
# streams
# --------------------------------------------------------------------------
def _samples(rng, mote, seq, n, flags=0):
    rec = rng.integers(-32768, 32768, (n, 9))
    # the bytes that need escaping, often (a real line has them in ~1 frame in 4)
    rec[rng.random(rec.shape) < 0.05] = 0x7E7D
    return P.encode_am(P.AMPacket(0xFFFF, mote, 0x22, P.AM_NINEDOF_SAMPLES_MSG,
                                  P.pack_samples(seq, flags, rec)))


def malformed(rng) -> list[bytes]:
    """One frame of each kind the decoder must count and skip, CRC intact."""
    am_len = P.AM_HEADER.pack(0xFFFF, 2, 9, 0x22, 0x60) + b"\x00" * 4   # length byte says 9
    count_bad = P.pack_samples(1, 0, np.ones((3, 9))) + b"\x00"
    return [
        P.encode_frame(bytes((P.PROTO_PACKET_NOACK, 0)) + am_len),          # AM length wrong
        P.encode_frame(bytes((0x99, 0)) + b"unknown protocol byte"),
        P.encode_frame(bytes((P.PROTO_ACK, 1, 2))),                          # ack of wrong length
        P.encode_frame(bytes((P.PROTO_PACKET_NOACK, 0, 1, 2))),              # too short
        P.encode_frame(bytes((P.PROTO_PACKET_NOACK, 0x42, 1, 2))),           # too short, not AM
        P.encode_frame(bytes((P.PROTO_PACKET_ACK, 5, 0))),                   # 0x44, empty AM
        P.encode_frame(bytes((P.PROTO_PACKET_ACK, 5, 0x42))),                # 0x44, empty, not AM
        P.encode_frame(b"\x45"),                                             # shorter than a CRC
        P.encode_frame(bytes((P.PROTO_PACKET_NOACK, 0x42)) + b"not an AM packet"),
        P.encode_frame(bytes((P.PROTO_PACKET_ACK, 9, 0x42)) + b"x"),         # non-AM 0x44
        P.encode_ack(int(rng.integers(0, 256))),
        P.encode_am(P.AMPacket(0xFFFF, 2, 0x22, P.AM_NINEDOF_SAMPLES_MSG, count_bad)),
        P.encode_am(P.AMPacket(0xFFFF, 2, 0x22, 0x5F, b"unknown AM type")),
        P.encode_am(P.AMPacket(0xFFFF, 2, 0x22, P.AM_NINEDOF_MOTE_TEMP_MSG, b"short")),
        P.message_frame(P.MOTE_STATUS, dest=0xFFFF, src=3, seq=1, dropped=4, version=2),
        P.message_frame(P.BS_STATUS, dest=0, radio_rx=int(rng.integers(0, 9999))),
        P.encode_am(P.AMPacket(5, 0, 0x22, P.AM_NINEDOF_CAL_QUERY_MSG,
                               P.CAL_QUERY.pack(mote=5, offset=20)), ack_seq=0x7E),
        b"\x7e" + b"\x7d" * 3 + b"\x7e",                                     # escapes only
        P.encode_am(P.AMPacket(0xFFFF, 2, 0x22, 0x5F, bytes(250))),          # over MAX_FRAME
        b"\x7e" + bytes(rng.integers(0, 256, 600, dtype=np.uint8)).replace(b"\x7e", b"") + b"\x7e",
    ]


def line(rng, motes=(1, 2, 3), n_msgs=900) -> bytes:
    """Several motes' sample messages (batches of 1 to 5, gaps, duplicates, late
    ones, a reboot), their temperature messages and every malformed kind."""
    frames = []
    seq = {m: int(rng.integers(0, 65536)) for m in motes}
    for i in range(n_msgs):
        m = motes[i % len(motes)]
        n = int(rng.integers(1, 6))
        r = rng.random()
        if r < 0.03:
            seq[m] += int(rng.integers(1, 40))                    # lost messages
        frames.append(_samples(rng, m, seq[m] & 0xFFFF, n, flags=int(rng.integers(0, 256))))
        if r > 0.97:
            frames.append(frames[-1])                              # heard twice
        if 0.5 < r < 0.51 and len(frames) > 8:
            frames.append(frames[-7])                              # late
        seq[m] += n
        if i % 60 == 59:
            frames.append(P.message_frame(P.MOTE_TEMP, dest=0xFFFF, src=m, seq=(seq[m] - 1) & 0xFFFF,
                                          count=125, temp_sum=-12000 * 125))
        if i == n_msgs // 2:
            seq[m] = 3                                             # a reboot
        if i % 97 == 0:
            frames += malformed(rng)
    return b"".join(frames)


def corrupt(rng, data: bytes, rate: float) -> bytes:
    """Flip, drop, insert and duplicate bytes at ``rate``, insert flags and escapes."""
    b = bytearray(data)
    for _ in range(int(len(b) * rate)):
        i = int(rng.integers(0, len(b)))
        k = rng.integers(0, 6)
        if k == 0:
            b[i] ^= int(rng.integers(1, 256))
        elif k == 1:
            del b[i]
        elif k == 2:
            b[i:i] = bytes(rng.integers(0, 256, int(rng.integers(1, 30)), dtype=np.uint8))
        elif k == 3:
            b[i:i] = b"\x7e"
        elif k == 4:
            b[i:i] = b"\x7d"
        else:
            b[i:i] = b[max(0, i - 40):i]
    return bytes(b)


# --------------------------------------------------------------------------
# the tests
# --------------------------------------------------------------------------
@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("reads", ["whole", "random", "small"])
def test_frames_and_counters_equal_the_simple_deframer(seed, reads):
    # "whole": every frame checked together; "small": reads of a few frames
    # (checked one by one, FEW_FRAMES); "random": both
    rng = np.random.default_rng(seed)
    data = corrupt(rng, line(rng, n_msgs=300), rate=0.004 * (seed + 1))
    if reads == "whole":
        cuts = []
    elif reads == "small":
        cuts = np.cumsum(rng.integers(1, 400, len(data)))
        cuts = cuts[cuts < len(data)]
    else:
        cuts = np.sort(rng.integers(0, len(data), int(rng.integers(1, 60))))
    fast, simple = P.FrameDecoder(), SimpleDecoder()
    got, want = [], []
    prev = 0
    for c in list(cuts) + [len(data)]:
        got += fast.feed(data[prev:c])
        want += simple.feed(data[prev:c])
        prev = c
    got += fast.finish()
    want += simple.finish()
    assert got == want, f"seed {seed}"
    assert fast.stats == simple.stats, f"seed {seed}"
    s = fast.stats
    assert s.crc_errors > 0 and s.bad_frames > 0 and s.garbage_bytes > 0, f"seed {seed}"


@pytest.mark.parametrize("seed", SEEDS)
def test_sample_decoding_from_a_block_equals_decode_message(seed):
    rng = np.random.default_rng(100 + seed)
    data = corrupt(rng, line(rng, n_msgs=300), rate=0.002)
    dec = P.FrameDecoder()
    block = dec.feed_block(data + b"\x7e")
    batch, others = decode_sample_frames(block)
    want, want_others = simple_samples(block.frames())
    for f in ("src", "seq", "flags", "count", "records", "rec_msg", "rec_index"):
        np.testing.assert_array_equal(getattr(batch, f), getattr(want, f), err_msg=f"seed {seed}")
    assert batch.records.dtype == np.int16
    assert batch.bad == want.bad > 0 and others == want_others, f"seed {seed}"
    assert len(batch) > 100


def test_unescape_takes_a_corrupted_escape_as_the_general_rule_does():
    for data in (b"\x7d\x5e\x7d\x5d", b"\x7d\x7d\x5d", b"a\x7d", b"\x7d\x7d\x7d", b"\x7d\x00x",
                 b"\x7d\x5e\x7d", b"", b"plain", b"\x7d\x5d\x5e\x7d\x5e"):
        assert P.unescape(data) == simple_unescape(data), data
    rng = np.random.default_rng(7)
    for _ in range(2000):
        data = bytes(rng.choice([0x7D, 0x5D, 0x5E, 0x41], int(rng.integers(0, 12))).astype(np.uint8))
        assert P.unescape(data) == simple_unescape(data), data


def test_an_escape_never_reaches_into_the_next_run():
    # a run ending in 0x7D, the next one (CRC intact) starting with 0x5E or 0x5D
    good = P.encode_am(P.AMPacket(0xFFFF, 1, 0x22, 0x5F, b"payload"))
    for first in (0x5E, 0x5D):
        data = good + b"AB\x7d" + P.encode_frame(bytes((first,)) + b"xyz") + good
        fast, simple = P.FrameDecoder(), SimpleDecoder()
        assert fast.feed(data) == simple.feed(data)
        assert fast.stats == simple.stats and fast.stats.frames == 2, fast.stats
        assert fast.stats.bad_frames == 2 and fast.stats.crc_errors == 0


@pytest.mark.parametrize("seed", SEEDS)
def test_logged_rows_and_counters_equal_the_simple_path(seed, tmp_path):
    rng = np.random.default_rng(200 + seed)
    # long enough for several reads of the logger (READ_SIZE each)
    data = corrupt(rng, line(rng, n_msgs=3000), rate=0.001 * (seed + 1))
    assert len(data) > 2 * S.READ_SIZE
    want_rows, want_temps, want = simple_log(data)
    rows, temps, got, stored = fast_log(data, tmp_path)
    assert sorted(rows) == sorted(want_rows), f"seed {seed}"
    assert len(rows) == len(set((m, q) for m, q, *_ in rows)) > 5000
    first = {}                          # the store keeps a reading's first copy
    for m, u, n in want_temps:
        first.setdefault((m, u), n)
    assert sorted(temps) == sorted((m, u, n) for (m, u), n in first.items()) and temps, \
        f"seed {seed}"
    assert got.line == want.line, f"seed {seed}"
    assert {m: k.c for m, k in got.motes.items()} == {m: k.c for m, k in want.motes.items()}
    assert stored["line"] == {k: v for k, v in want.line.items()}, f"seed {seed}"
    assert stored["motes"] == {m: k.c for m, k in want.seen().items()}, f"seed {seed}"
    ln = want.line
    assert min(ln["crc_errors"], ln["bad_frames"], ln["garbage_bytes"], ln["unknown_msgs"],
               ln["bad_msgs"], ln["acks"], ln["bs_status_msgs"]) > 0, f"seed {seed}: {ln}"
    c = {m: k.c for m, k in want.motes.items()}
    assert sum(k["duplicates"] for k in c.values()) > 0 and sum(k["lost"] for k in c.values()) > 0
