"""The release check and the fault matrix (emu/release_check.py,
emu/fault_matrix.py) run the real images outside CI; here, without nesC:
bad input gives one line and exit 2, and the fault matrix's analysis of
what the host received (losses, stale records, time to recover, status
counters) on a planted stream."""
import os
import subprocess
import sys

import numpy as np
import pytest

import emusim
from motecal.line import protocol as P

sys.path.insert(0, str(emusim.EMU))
import fault_matrix as FM  # noqa: E402


def _run(script, *args, env_root=None):
    env = {k: v for k, v in os.environ.items() if k != "TINYOS_ROOT_DIR"}
    if env_root:
        env["TINYOS_ROOT_DIR"] = env_root
    return subprocess.run([sys.executable, str(emusim.EMU / script), *args], capture_output=True,
                          text=True, env=env, timeout=60)


@pytest.mark.parametrize("script,args,needle", [
    ("release_check.py", [], "TINYOS_ROOT_DIR is not set"),
    ("release_check.py", ["--mote-elf", "x", "--base-elf", "y", "--loss", "2"], "--loss"),
    ("fault_matrix.py", [], "TINYOS_ROOT_DIR is not set"),
    ("fault_matrix.py", ["--mote-elf", "x", "--base-elf", "y", "--fault-at", "1"], "--fault-at"),
    ("fault_matrix.py", ["--mote-elf", "x", "--base-elf", "y", "--expect", "nosuch:missing=1"],
     "--expect"),
    ("fault_matrix.py", ["--mote-elf", "x", "--base-elf", "y", "--expect", "none:colour=1"],
     "--expect"),
])
def test_bad_input_one_line(script, args, needle, tmp_path):
    res = _run(script, *args)
    assert res.returncode == 2, res.stderr
    assert len(res.stderr.strip().splitlines()) == 1 and needle in res.stderr
    assert "Traceback" not in res.stderr


def _samples(seq, recs):
    return P.encode_am(P.AMPacket(0xFFFF, 1, 0x22, P.AM_NINEDOF_SAMPLES_MSG,
                                  P.pack_samples(seq, 0, np.asarray(recs))))


def _status(vals):
    payload = (vals[0].to_bytes(2, "big") + vals[1].to_bytes(2, "big") + bytes((vals[2], 0))
               + b"".join(v.to_bytes(2, "big") for v in vals[3:]))
    return P.encode_am(P.AMPacket(0xFFFF, 1, 0x22, P.AM_NINEDOF_MOTE_STATUS_MSG, payload))


def test_analysis_of_a_planted_stream():
    # 400 samples from t = 1 s at 8 ms; samples 250..254 lost (t 3.0-3.04 s),
    # the accelerometer stale for samples 260..269; the rest change every sample
    recs = np.arange(400 * 9).reshape(400, 9) % 3000
    recs[260:270, 0:3] = recs[259, 0:3]
    data = b""
    for s in range(0, 400, 5):
        if 250 <= s < 255:
            continue
        data += _samples(s, recs[s:s + 5])
    data += _status([400, 0, 0, 1, 2, 3, 4, 5, 6, 7])
    r = FM.analyse(data, fault_at=3.0, first_sample_s=1.0)
    assert r["records"] == 395 and r["missing"] == 5 and r["stale"] == 10
    # last bad sample 269 at 1 + 269 * 0.008 = 3.152 s; recovered at its end
    assert r["recover_s"] == pytest.approx(3.152 + 0.008 - 3.0)
    assert r["status"] == {"seq": 400, "version": 0, "sensors": 0, "dropped": 1, "send_fail": 2,
                           "i2c_errors": 3, "late": 4, "i2c_nacks": 5, "bus_resets": 6,
                           "chip_reinits": 7}
    # a 14-byte status (firmware without the fault counters) has only the first four
    assert set(FM.decode_status(bytes(14))) == {"seq", "version", "sensors", "dropped",
                                                "send_fail", "i2c_errors", "late"}
    # the host's decoder (checked against the header), not a field list of its own:
    # a length that is no layout of the message is refused, as the logger refuses it
    payload = P.MOTE_STATUS.pack(seq=1, late=9, chip_reinits=3)
    want = P.decode_message(P.AMPacket(0, 1, 0x22, P.AM_NINEDOF_MOTE_STATUS_MSG, payload))
    assert FM.decode_status(payload) == {k: v for k, v in want.items() if k != "reserved"}
    assert FM.decode_status(payload[:16]) is None and not hasattr(FM, "STATUS")


def test_analysis_clean_stream():
    recs = np.arange(100 * 9).reshape(100, 9)
    data = b"".join(_samples(s, recs[s:s + 5]) for s in range(0, 100, 5))
    r = FM.analyse(data, fault_at=1.2, first_sample_s=1.0)
    assert r["missing"] == 0 and r["stale"] == 0 and r["recover_s"] == 0


def test_set_diff_names_the_bytes_that_changed():
    frag = P.encode_am(P.AMPacket(1, 0, 0x22, P.AM_NINEDOF_CAL_FRAG_MSG,
                                  bytes.fromhex("0001000314140031") + bytes(18)))
    back = bytes.fromhex("00010003116f14140031") + bytes([0, 0, 10]) + bytes(17)
    rep = P.encode_am(P.AMPacket(0, 1, 0x22, P.AM_NINEDOF_CAL_REPORT_MSG, back))
    old = P.encode_am(P.AMPacket(0, 1, 0x22, P.AM_NINEDOF_CAL_REPORT_MSG,
                                 bytes.fromhex("00010002116f1414ff") + bytes(19)))
    assert FM.set_diff(frag, rep + old, 3) == ["set byte 24: sent 0x00, read back 0x0a"]
    assert FM.set_diff(frag, old, 3) == []


STUCK = next(e for n, _, e in FM.CASES if "stuck" in n)


def _stuck_result(**change):
    """A result that meets the stuck-slave case's expectation exactly."""
    r = {"records": 1200, "missing_after_fault": 3, "stale": 0, "recover_s": 0.027,
         "status": {"bus_resets": 1, "i2c_nacks": 0, "i2c_errors": 0, "late": 2},
         "wires": {"stuck_holds": 1, "stuck_freed": 1, "freed_after_pulses": 8,
                   "gpio_scl_pulses": 9, "gpio_stops": 1, "sda_held_at_end": 0}}
    for k, v in change.items():
        where, _, key = k.partition("__")
        if key:
            r[where] = {**r[where], key: v}
        else:
            r[where] = v
    return r


def test_every_case_has_an_expectation_that_can_fail():
    assert FM.check(STUCK, _stuck_result()) == []
    # each kind of figure, broken on its own, is reported on its own line
    for change, word in [({"missing_after_fault": 6}, "missing 6 > 5"),
                         ({"recover_s": 0.2}, "time to recover 200 ms > 40 ms"),
                         ({"stale": 1}, "stale records 1 > 0"),
                         ({"records": 0}, "records 0 < 1"),
                         ({"status__bus_resets": 3}, "status bus_resets 3, expected 1"),
                         ({"status__late": 9}, "status i2c_errors+late 9, expected 1..4"),
                         ({"wires__freed_after_pulses": 9}, "wires freed_after_pulses 9"),
                         ({"wires__sda_held_at_end": 1}, "wires sda_held_at_end 1"),
                         ({"status": {}}, "status bus_resets: not reported")]:
        bad = FM.check(STUCK, _stuck_result(**change))
        assert bad and any(word in b for b in bad), (change, bad)
    # every case says what it expects of the counters or the wires
    assert all(e.status or e.wires for _, _, e in FM.CASES)
    assert FM.check(FM.UPLOAD, {"records": 400, "upload": {"exit": 1}, "status": {
        "dropped": 0, "i2c_errors": 0}}) == ["upload exit 1, expected 0"]


def test_an_expectation_can_be_changed_from_the_command_line():
    ex = {n: e for n, _, e in FM.CASES}
    FM.override(ex, "stuck:status.bus_resets=2..3")
    FM.override(ex, "none:missing=-1")
    FM.override(ex, "nack:recover_s=0.5")
    assert ex["itg3200 stuck mid-byte"].status["bus_resets"] == (2, 3)
    assert ex["none"].missing == -1 and ex["nack itg3200 0.5 s"].recover_s == 0.5
    assert FM.check(ex["none"], {"records": 10, "missing_after_fault": 0, "status": {
        k: 0 for k in ex["none"].status}, "wires": {"gpio_scl_pulses": 0}}) == [
        "sequence numbers missing 0 > -1"]
