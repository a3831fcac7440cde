"""``motecal upload`` as a user runs it (subprocesses): --dry-run output, bad
input (one line on stderr, the documented exit status, no traceback), and a
real upload, --show and --reset against a simulated world served over TCP in
real time, a mote that does not answer and a mote that rejects the set."""
import json
import os
import socket
import subprocess
import sys

import numpy as np
import pytest

from motecal import upload as U
from motecal.calib.result import BoardCalibration, SensorCalibration
from motecal.commands.main import main
from motecal.firmware import fixedpoint as FP
from motecal.firmware import mote_c
from motecal.line import protocol as P
from motecal.sim.serve import serve_in_thread
from motecal.sim.world import World

CMD = [sys.executable, "-m", "motecal", "upload"]


def _upload(*args, timeout=120, env=None):
    return subprocess.run(CMD + [str(a) for a in args], capture_output=True, text=True,
                          timeout=timeout, stdin=subprocess.DEVNULL, env=env)


def _sensor(name, unit, k, A, c):
    return SensorCalibration(sensor=name, unit=unit, chip="", lsb_per_unit=k, model="full",
                             params=[], A=np.asarray(A) / k, c=c, mse_before=0.0,
                             mse_after=0.0, min_before=1.0, max_before=1.0, min_after=1.0,
                             max_after=1.0)


@pytest.fixture(scope="module")
def cal_path(tmp_path_factory):
    """A cal.json as `motecal calibrate` writes it (mote 1, all three sensors)."""
    rng = np.random.default_rng(4)
    M = {n: np.eye(3) + np.tril(rng.normal(0, 0.02, (3, 3))) for n in P.SENSORS}
    board = BoardCalibration(
        mote=1, session="s80", created="2026-01-01T00:00:00Z",
        accel=_sensor("accel", "g", 256.0, M["accel"], [0.05, -0.02, 0.03]),
        gyro=_sensor("gyro", "deg/s", 14.375, M["gyro"], [-11.0, 6.0, 6.5]),
        mag=_sensor("mag", "gauss", 1090.0, M["mag"], [-0.06, -0.02, 0.03]),
        gate={"accepted": True, "reasons": [], "warnings": []})
    path = tmp_path_factory.mktemp("cli") / "cal.json"
    board.save(path)
    return path


def test_dry_run_prints_the_fixed_point_values_and_their_error(cal_path):
    r = _upload(cal_path, "--dry-run", "--version", 7)
    assert r.returncode == 0 and r.stderr == ""
    cal = U.load_cal(cal_path)
    calset, report = U.build_set(cal, 1, 7)
    lines = r.stdout.splitlines()
    assert lines[0] == f"{cal_path}: mote 1, session s80"
    assert lines[1] == (f"set for mote 1, version 7: 102 bytes in 6 fragments, "
                        f"CRC 0x{P.crc16(calset):04x}")
    assert lines[2:8] == FP.format_report(report)
    assert lines[8] == "the mote's checks (tinyos/ninedof_calset.c): accepted"
    # the numbers are the set's: shift, A_q and c_q per sensor, as the mote will hold them
    cs = FP.unpack_calset(calset)
    a = cs.sensors["accel"]
    assert lines[2] == (f"accel: Q{a.shift}  matrix a = {a.a.reshape(9).tolist()}  "
                        f"offset c = {a.c.tolist()}")
    assert a.shift == 14 and a.a[0, 0] == round(cal.physical["accel"][0][0, 0] * 256 * 2**14)
    assert "LSB (" in lines[3] and " g)" in lines[3]

def test_dry_run_without_version(cal_path, capsys):
    assert main(["upload", str(cal_path), "--dry-run"]) == 0
    assert "version 1 (at upload: the version in force + 1)" in capsys.readouterr().out


@pytest.fixture(scope="module")
def bad_files(tmp_path_factory, cal_path):
    d = json.loads(cal_path.read_text())
    tmp = tmp_path_factory.mktemp("bad")
    content = {
        "notjson.json": "{nope",
        "noA.json": {**d, "accel": {k: v for k, v in d["accel"].items() if k != "A"}},
        "badc.json": {**d, "gyro": {**d["gyro"], "c": [1, 2]}},
        "nothing.json": {"format_version": 1, "mote": 1},
        "nomote.json": {k: v for k, v in d.items() if k != "mote"},
        "range.json": {**d, "accel": {**d["accel"],
                                      "A": (np.array(d["accel"]["A"]) * 2.5).tolist()}},
        "refused.json": {**d, "gate": {"accepted": False, "reasons": ["too few poses"]}},
        "recording.bin": "",
    }
    for name, c in content.items():
        (tmp / name).write_text(c if isinstance(c, str) else json.dumps(c))
    return tmp


def _closed_port():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def _bad_cases(tmp, cal_path):
    """(arguments, exit status, text of the one stderr line)"""
    return [
        ([tmp / "missing.json", "--dry-run"], 2, "cannot read"),
        ([tmp / "notjson.json", "--dry-run"], 2, "is not JSON"),
        ([tmp / "noA.json", "--dry-run"], 2, "noA.json: accel: no 'A'"),
        ([tmp / "badc.json", "--dry-run"], 2, "badc.json: gyro: 'c' must be 3, not 2"),
        ([tmp / "nothing.json", "--dry-run"], 2, "no calibrated sensor"),
        ([tmp / "nomote.json", "--dry-run"], 2, "no mote id"),
        ([tmp / "range.json", "--dry-run"], 3, "the mote would reject this calibration: "
                                               "parameters outside plausibility limits "
                                               "(NINEDOF_CAL_E_RANGE)"),
        ([tmp / "range.json", "--port", "socket://127.0.0.1:9"], 3, "would reject"),
        ([tmp / "refused.json", "--port", "socket://127.0.0.1:9"], 3,
         "refused by the quality gate (too few poses); --force uploads it anyway"),
        ([cal_path, "--dry-run", "--mote", 2], 2, "calibrates the board of mote 1, not mote 2"),
        ([], 2, "give a calibration file (cal.json), or --reset / --show"),
        (["--show", "--port", "socket://127.0.0.1:9"], 2, "--mote is needed"),
        ([cal_path, "--reset", "--mote", 1], 2, "--reset takes no calibration file"),
        ([cal_path, "--dry-run", "--version", 0], 2, "version must be 1..65535"),
        ([cal_path, "--dry-run", "--reset"], 2, "not allowed with argument"),
        ([cal_path, "--timeout", "-1"], 2, "must be > 0"),
        ([cal_path], 2, "no port: give --port"),
        ([cal_path, "--port", tmp / "recording.bin"], 2, "is a recorded file"),
        ([cal_path, "--port", f"socket://127.0.0.1:{_closed_port()}"], 2, "cannot open port"),
        (["--show", "--mote", 0, "--port", "socket://127.0.0.1:9"], 2, "mote id must be"),
    ]


# the ones also run as real processes (each start costs ~1.5 s of imports)
IN_SUBPROCESS = (0, 2, 6, 16)


def test_bad_input_in_process(bad_files, cal_path, capsys, monkeypatch):
    monkeypatch.delenv("MOTECOM", raising=False)
    for args, rc, text in _bad_cases(bad_files, cal_path):
        assert main(["upload"] + [str(a) for a in args]) == rc, args
        out, err = capsys.readouterr()
        assert len(err.splitlines()) == 1 and err.startswith("motecal"), (args, err)
        assert text in err, (args, err)


def test_bad_input_is_one_line_without_traceback(bad_files, cal_path):
    env = {k: v for k, v in os.environ.items() if k != "MOTECOM"}
    cases = [c for i, c in enumerate(_bad_cases(bad_files, cal_path)) if i in IN_SUBPROCESS]
    procs = [subprocess.Popen(CMD + [str(a) for a in args], stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True, stdin=subprocess.DEVNULL,
                              env=env) for args, _, _ in cases]
    for (args, rc, text), p in zip(cases, procs):
        out, err = p.communicate(timeout=120)
        assert p.returncode == rc, (args, out, err)
        assert len(err.splitlines()) == 1 and "Traceback" not in err, (args, err)
        assert err.startswith("motecal") and text in err, (args, err)


@pytest.fixture
def served():
    world = World(motes=1, session="idle", seed=7, duration=3600.0)
    server, port = serve_in_thread(world, speed=1.0)
    yield world, f"socket://127.0.0.1:{port}"
    server.stop()
    server.close()


def _in_process(capsys, *args):
    rc = main(["upload"] + [str(a) for a in args])
    out, err = capsys.readouterr()
    assert rc == 0, err
    return out.splitlines()


def test_upload_show_reset_and_a_silent_mote_over_tcp(served, cal_path, capsys):
    world, url = served
    r = _upload(cal_path, "--port", url)
    assert r.returncode == 0, r.stdout + r.stderr
    calset, _ = U.build_set(U.load_cal(cal_path), 1, 1)
    crc = P.crc16(calset)
    out = r.stdout.splitlines()
    assert out[0].startswith("mote 1: version 0 in force (CRC 0x")
    assert out[0].endswith(f"uploading version 1 (102 bytes, 6 fragments, CRC 0x{crc:04x})")
    assert out[1] == "  fragment 1/6 (offset 0): 20 bytes acked"
    assert out[6] == "  fragment 6/6 (offset 100): 2 bytes acked"
    assert out[7] == (f"  commit: accepted, mote CRC 0x{crc:04x} = ours, version 1 in force, "
                      "corrected: accel, gyro, mag")
    assert f"  read-back: 102 bytes identical, CRC 0x{crc:04x}" in out
    assert "  samples: 3 messages in a row flagged corrected, version low bits 1" in out[-3]
    assert out[-2].startswith("  stored: version 1 written to the EEPROM and read back, ")
    assert out[-2].endswith(" s after the commit; a reset keeps it")
    polls = int(out[-1].split("; ")[1].split()[0]) - 14
    assert 1 <= polls <= 8
    assert out[-1].startswith("mote 1: calibration version 1 (was 0) in force and verified, and "
                              f"stored (survives a reboot); {14 + polls} messages, 0 repeated, "
                              "0 serial repeats, ")
    assert world.motes[1].cal.active_calset() == calset
    assert world.motes[1].cal.stored_version == 1

    show = _in_process(capsys, "--show", cal_path, "--port", url)
    assert show[0] == (f"mote 1: calibration version 1 in force (CRC 0x{crc:04x}), corrected: "
                       "accel, gyro, mag")
    assert "  accel (Q14): calibrated [g] = A @ raw [counts] + c" in show
    assert show[-1] == f"  equals {cal_path} (quantised for mote 1, version 1)"

    out = _in_process(capsys, "--reset", "--mote", 1, "--port", url)
    assert "  reset: accepted, raw output, version 2 in force" in out
    assert out[-1].startswith("mote 1: raw output version 2 (was 1) in force and verified, and "
                              "stored (survives a reboot); ")
    assert world.motes[1].cal.stored_version == 2
    out = _in_process(capsys, "--show", "--mote", 1, "--port", url)
    assert out[0] == (f"mote 1: calibration version 2 in force (CRC "
                      f"0x{world.motes[1].cal.crc:04x}), corrected: none (raw output)")

    r = _upload("--show", "--mote", 9, "--port", url, "--timeout", 0.1, "--retries", 2)
    assert r.returncode == 1 and "Traceback" not in r.stderr
    assert r.stderr == ("motecal: error: no answer from mote 9 to read-back 1 (offset 0) "
                        "after 3 tries of 0.1 s: is it switched on, in range of the "
                        "BaseStation and running the motecal firmware with ID 9?\n")
    assert r.stdout.splitlines() == [
        f"  no answer to read-back 1 (offset 0) within 0.1 s; sending it again (try {k} of 3)"
        for k in (2, 3)]


class _NoStorage(mote_c.CalReceiver):
    """A mote whose EEPROM write fails: an APPLY is answered E_STORAGE (the
    firmware here never does, but the protocol has the code)."""

    def handle(self, am_type, payload):
        if am_type == P.AM_NINEDOF_CAL_COMMIT_MSG:
            m = P.CAL_COMMIT.unpack(bytes(payload))
            if m["action"] == P.CAL_APPLY:
                return P.AM_NINEDOF_CAL_COMMIT_ACK_MSG, P.CAL_COMMIT_ACK.pack(
                    mote=self.mote_id, version=self.version, crc=m["crc"], status=8,
                    sensors=self.sensors)
        return super().handle(am_type, payload)


def test_a_rejected_set_is_one_clear_line(cal_path):
    world = World(motes=1, session="idle", seed=8, duration=3600.0, cal_factory=_NoStorage)
    server, port = serve_in_thread(world, speed=1.0)
    try:
        r = _upload(cal_path, "--port", f"socket://127.0.0.1:{port}")
    finally:
        server.stop()
        server.close()
    assert r.returncode == 1
    assert r.stderr == ("motecal: error: mote 1 rejected calibration version 1: the mote could "
                        "not persist the set (NINEDOF_CAL_E_STORAGE); version 0 stays in "
                        "force\n")
    assert "fragment 6/6 (offset 100): 2 bytes acked" in r.stdout
    assert world.motes[1].cal.version == 0


def test_calibrate_upload_options_are_checked_before_calibrating(tmp_path, capsys,
                                                                 monkeypatch):
    monkeypatch.delenv("MOTECOM", raising=False)
    rec = tmp_path / "rec.bin"
    rec.write_bytes(b"")
    base = ["calibrate", "--db", str(tmp_path / "none.db"), "--session", "s", "--out",
            str(tmp_path / "cal.json")]
    for extra, text in ((["--port", "socket://127.0.0.1:9"], "--port and --baud go with "
                                                             "--upload"),
                        (["--upload"], "no port: give --port"),
                        (["--upload", "--port", str(rec)], "is a recorded file"),
                        (["--upload", "--port", "sf@host:notaport"], "bad TCP port")):
        assert main(base + extra) == 2, extra
        err = capsys.readouterr().err
        assert len(err.splitlines()) == 1 and text in err, (extra, err)
    assert not (tmp_path / "none.db").exists()           # nothing was opened or calibrated
