"""The sensor-mote image in the emulator harness sends the board temperature
that the emulated ITG-3200 reads (ninedof_mote_temp_msg through the
BaseStation image, decoded with the host's protocol).

Needs the nesC build (a TinyOS tree in TINYOS_ROOT_DIR, nesC >= 1.4.0 on
PATH): skipped with one line otherwise, as in CI, which cannot build nesC.
The harness's temp= option itself is tested in CI (test_emu_chips.py).
"""
import re
import socket
import subprocess
import sys
import threading

import pytest

import emusim
from motecal.line import protocol as P

sys.path.insert(0, str(emusim.EMU))
import emulate  # noqa: E402

TEMPS = {1: 31.5, 2: 18.0}          # C per mote; TEMP_OUT -14180, -17960


@pytest.fixture(scope="module")
def images(tmp_path_factory):
    try:
        emulate.toolchain()
    except emulate.Unavailable as e:
        pytest.skip(f"the nesC build is not available here ({e}): the emulated image's "
                    "temperature messages are not checked (docs/emulation.md)")
    emusim.skip_or_fail(pytest)
    d = tmp_path_factory.mktemp("emutemp")
    mote = emulate.build_image("tinyos", d / "mote.elf")
    base = emulate.build_image("basestation", d / "basestation.elf")
    return d, emusim.build_harness(d / "build"), mote, base


def _run(args):
    """Run the harness with the BaseStation's UART on a TCP port: the bytes
    of the serial line and what the harness printed after it."""
    proc = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    port = None
    for line in proc.stdout:
        m = re.search(r"socket://127\.0\.0\.1:(\d+)", line)
        if m:
            port = int(m.group(1))
            break
    assert port, proc.stderr.read()
    sock = socket.create_connection(("127.0.0.1", port), timeout=60)
    data = bytearray()

    def read():
        while True:
            try:
                chunk = sock.recv(65536)
            except OSError:
                return
            if not chunk:
                return
            data.extend(chunk)

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    rest = proc.stdout.read()
    assert proc.wait(timeout=600) == 0, proc.stderr.read()
    reader.join(5)
    sock.close()
    return bytes(data), rest


def test_temperature_messages_carry_the_emulated_chips_temperature(images):
    d, exe, mote, base = images
    data, rest = _run([str(exe), "--mote", f"{mote},id=1,temp={TEMPS[1]}",
                       "--mote", f"{mote},id=2,mhz=7.84,temp={TEMPS[2]}",
                       "--base", f"{base},id=0", "--serial", "tcp:0", "--seconds", "7.5",
                       "--settle", "3", "--report", "json"])
    temps, samples = {}, {}
    for fr in P.FrameDecoder().feed(bytes(data)):
        am = fr.am()
        msg = P.decode_message(am) if am is not None else None
        if msg is None:
            continue
        if am.am_type == P.AM_NINEDOF_MOTE_TEMP_MSG:
            temps.setdefault(am.src, []).append(msg)
        elif am.am_type == P.AM_NINEDOF_SAMPLES_MSG:
            samples[am.src] = samples.get(am.src, 0) + len(msg.records)
    for mote_id, celsius in TEMPS.items():
        msgs = temps.get(mote_id, [])
        print(f"mote {mote_id} at {celsius} C: {len(msgs)} temperature messages "
              + ", ".join(f"seq {m['seq']} count {m['count']} sum {m['temp_sum']}" for m in msgs))
        assert len(msgs) >= 5, temps                          # one a second, 7.5 s
        raw = int(P.temp_raw(celsius))
        for m in msgs:
            assert m["count"] > 0 and m["temp_sum"] == raw * m["count"]
            assert abs(float(P.temp_c(m["temp_sum"] / m["count"])) - celsius) < 0.01
        full = [m["count"] for m in msgs[1:]]
        assert all(124 <= c <= 126 for c in full), full        # 125 readings a second
        seqs = [m["seq"] for m in msgs]
        assert all(0 < (b - a) & 0xFFFF <= 130 for a, b in zip(seqs, seqs[1:])), seqs
        assert samples.get(mote_id, 0) > 500                  # the samples went on
    rep = rest[rest.index('{"seconds"'):]
    import json
    for n in json.loads(rep)["nodes"]:
        if n["role"] == "mote":
            itg = n["chips"]["itg3200"]
            assert itg["temp_reads"] == itg["data_reads"] > 800   # every read, one burst
            assert itg["last_temp"] == int(P.temp_raw(TEMPS[n["id"]]))
            assert n["missing_periods"] == 0 and n["reads_per_s"] > 124.9


def test_first_second_corrected_at_the_boards_temperature(images, tmp_path):
    """A mote image booting with a set with temperature terms in its EEPROM
    (the gyroscope's offset moves ~600 counts from t_ref = 20 C to the
    board's 31.5 C): the samples of the first second, before the first
    temperature message's mean is in force, are corrected at the latest
    TEMP_OUT reading already (NineDofAppP), so they agree with the later
    ones instead of being ~600 counts off."""
    import binascii
    import numpy as np
    from motecal.firmware import fixedpoint as FP
    from motecal.firmware import mote_c as M
    d, exe, mote, base = images
    ft = FP.FixedTemp(int(P.temp_raw(20.0)), int(P.temp_raw(0.0)), int(P.temp_raw(60.0)),
                      [12200, -12200, 6100], [0, 0, 0], 16, 30)
    fs = FP.FixedSensor(np.eye(3, dtype=np.int64) << 14, [0, 0, 0], 14)
    tset = FP.pack_calset(1, 1, {"gyro": fs}, {"gyro": ft})
    rx = M.CalReceiver(1)
    for o in range(0, len(tset), P.NINEDOF_FRAG_DATA):
        rx.handle(P.AM_NINEDOF_CAL_FRAG_MSG, P.CAL_FRAG.pack(
            mote=1, version=1, offset=o, len=len(tset[o:o + 20]), data=tset[o:o + 20]))
    rx.handle(P.AM_NINEDOF_CAL_COMMIT_MSG, P.CAL_COMMIT.pack(
        mote=1, version=1, length=len(tset), action=P.CAL_APPLY,
        crc=binascii.crc_hqx(tset, 0)))
    assert rx.version == 1
    ee = bytearray(b"\xff" * 4096)
    img = rx.image(1)
    at = M.library().ninedof_slot_addr(0)
    ee[at:at + len(img)] = img
    (tmp_path / "ee.bin").write_bytes(bytes(ee))
    elf = tmp_path / "mote-ee.elf"         # the image with its EEPROM preloaded
    subprocess.run(["avr-objcopy", "--add-section", f".eeprom={tmp_path / 'ee.bin'}",
                    "--set-section-flags", ".eeprom=alloc,load",
                    "--change-section-address", ".eeprom=0x810000", str(mote), str(elf)],
                   check=True, capture_output=True)
    data, _ = _run([str(exe), "--mote", f"{elf},id=1,temp=31.5", "--base", f"{base},id=0",
                    "--serial", "tcp:0", "--seconds", "4", "--settle", "0.5",
                    "--report", "json"])
    first_mean, rows = None, []
    for fr in P.FrameDecoder().feed(data):
        am = fr.am()
        msg = P.decode_message(am) if am is not None else None
        if msg is None or am.src != 1:
            continue
        if am.am_type == P.AM_NINEDOF_MOTE_TEMP_MSG and first_mean is None and msg["count"]:
            first_mean = msg["seq"]
        elif am.am_type == P.AM_NINEDOF_SAMPLES_MSG:
            assert msg.flags & P.FLAG_CORRECTED
            for i, r in enumerate(msg.records):
                rows.append((msg.seq + i, *r[3:6]))
    assert first_mean is not None and rows
    rows = np.array(rows, np.int64)
    early = rows[rows[:, 0] < first_mean - 5, 1:]
    late = rows[rows[:, 0] > first_mean + 130, 1:]
    O = ft.offset_per_count * (int(P.temp_raw(31.5)) - ft.t_ref)
    print(f"first mean at sample {first_mean}; gyro mean of {len(early)} samples before it "
          f"{early.mean(0).round(1)}, of {len(late)} after {late.mean(0).round(1)}; "
          f"O at 31.5 C {O.round(1)} counts")
    assert len(early) >= 50 and len(late) >= 100 and np.all(np.abs(O) > 250)
    assert np.all(np.abs(early.mean(0) - late.mean(0)) < 20)
