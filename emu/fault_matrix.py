"""`make fault-matrix TINYOS_ROOT_DIR=...`: the fault cases run on the real
images in the emulator harness (outside CI, which cannot build nesC), one
sensor mote (id 1, 8 MHz, the synthetic board) and the BaseStation, the
BaseStation's serial line read here with the host's decoder
(motecal.line.protocol).  Every case has its expected outcome (EXPECT:
records missing at most N, recovery within T, the counters that must move
and by how much); the run exits 1 when any case does not meet it, and says
which and why.

For every case it prints what the host saw: sample records received, the
sequence numbers missing (samples lost), stale records (a sensor's three
values equal to the record before: a chip in standby or not triggered; the
synthetic board changes every millisecond), the time to recover (from the
fault's start to the end of the last sequence gap or stale record, in
sample periods of 8 ms) and the mote's last status counters; what the
harness saw on the bus and its wires; and the expectation, met or not.

  none                       no fault
  nack itg3200 0.5 s         the gyroscope NACKs its address for 0.5 s
  adxl345 power loss 0.1 s   the accelerometer loses power, back with reset registers
  hmc5883l power loss 0.1 s  the magnetometer likewise
  itg3200 stuck mid-byte     the gyroscope holds SDA over a STOP until 8 clock
                             pulses: the bus stays busy until the firmware's bus
                             clear clocks it free
  SDA shorted 2 s            SDA to ground: every clear fails, the bus is down
                             (reads refused, a clear every 256 ms) until it ends
  SCL shorted 2 s            SCL likewise
  serial unread 3 s          the host does not read the serial line for 3 s
  upload, loss 0.3           `motecal upload` of a calibration with 30 % of the radio
                             frames lost (both directions), then loss 0
  upload --reset             the same with `motecal upload --reset` (a commit of the raw set)

    python3 emu/fault_matrix.py [--src CHECKOUT] [--cflags ...] [--mote-elf E --base-elf E]
                                [--only NAME] [--expect "NAME:FIELD=VALUE"]
"""
from __future__ import annotations

import argparse
import re
import shlex
import socket
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import emulate  # noqa: E402
import release_check as rc  # noqa: E402

PERIOD_S = 0.008


def decode_status(payload: bytes) -> dict | None:
    """The mote's status message, decoded by the host's own decoder
    (motecal.line.protocol, checked against tinyos/NineDofMsg.h): a mote
    built before the fault counters sends the message without them, and
    they are absent; None for a payload that is no layout of the message."""
    from motecal.line import protocol as P
    msg = P.MOTE_STATUS.decode(payload)
    if msg is not None:
        msg.pop("reserved", None)
    return msg


class LineReader:
    """The BaseStation's TCP port read in a thread; the bytes."""

    def __init__(self, url: str):
        host, port = url.split("//")[1].split(":")
        self.sock = socket.create_connection((host, int(port)), timeout=5)
        self.sock.settimeout(0.2)
        self.data = bytearray()
        self.stop_ = False
        self.t = threading.Thread(target=self._run, daemon=True)
        self.t.start()

    def _run(self):
        while not self.stop_:
            try:
                chunk = self.sock.recv(65536)
            except socket.timeout:
                continue
            except OSError:
                break
            if not chunk:
                break
            self.data += chunk

    def close(self) -> bytes:
        self.stop_ = True
        self.t.join(2)
        self.sock.close()
        return bytes(self.data)


class Proxy:
    """A loopback TCP port between the uploader and the BaseStation's port that
    keeps both directions' bytes (to compare the set sent with the set read back)."""

    def __init__(self, url: str):
        host, port = url.split("//")[1].split(":")
        self.up = socket.create_connection((host, int(port)), timeout=5)
        self.ls = socket.socket()
        self.ls.bind(("127.0.0.1", 0))
        self.ls.listen(1)
        self.url = f"socket://127.0.0.1:{self.ls.getsockname()[1]}"
        self.to_host, self.to_mote = bytearray(), bytearray()
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self):
        try:
            c, _ = self.ls.accept()
        except OSError:
            return

        def upstream():
            while True:
                try:
                    d = c.recv(4096)
                except OSError:
                    break
                if not d:
                    break
                self.to_mote.extend(d)
                self.up.sendall(d)
        threading.Thread(target=upstream, daemon=True).start()
        self.up.settimeout(None)
        while True:
            try:
                d = self.up.recv(65536)
            except OSError:
                break
            if not d:
                break
            self.to_host.extend(d)
            try:
                c.sendall(d)
            except OSError:
                pass

    def close(self):
        for s_ in (self.ls, self.up):
            try:
                s_.close()
            except OSError:
                pass


def set_diff(to_mote: bytes, to_host: bytes, version: int) -> list[str]:
    """Bytes of the set that differ between the fragments sent (CAL_FRAG of
    `version`) and the CAL_REPORTs of that version read back."""
    from motecal.line import protocol as P
    sent, back = {}, {}
    for data, want, dst in ((to_mote, P.AM_NINEDOF_CAL_FRAG_MSG, sent),
                            (to_host, P.AM_NINEDOF_CAL_REPORT_MSG, back)):
        for fr in P.decode_stream(bytes(data)):
            am = fr.am()
            if am is None or am.am_type != want:
                continue
            b = am.payload
            if want == P.AM_NINEDOF_CAL_FRAG_MSG:     # mote, version, offset, len, data
                ver, off, n, d = int.from_bytes(b[2:4], "big"), b[4], b[5], b[6:]
            else:                                      # mote, version, crc, offset, len, data
                ver, off, n, d = int.from_bytes(b[2:4], "big"), b[6], b[7], b[8:]
            if ver == version:
                for k in range(min(n, len(d))):
                    dst[off + k] = d[k]
    return [f"set byte {k}: sent 0x{sent[k]:02x}, read back 0x{back[k]:02x}"
            for k in sorted(set(sent) & set(back)) if sent[k] != back[k]]


def analyse(data: bytes, fault_at: float, first_sample_s: float) -> dict:
    """Records per sequence number of mote 1, losses, stale records, recovery."""
    from motecal.line import protocol as P
    recs: dict[int, np.ndarray] = {}
    status = None
    crc = 0
    dec = P.FrameDecoder()
    base = None
    last = None
    for fr in dec.feed(data):
        am = fr.am()
        if am is None or am.src != 1:
            continue
        if am.am_type == P.AM_NINEDOF_SAMPLES_MSG:
            msg = P.unpack_samples(am.payload)
            s = msg.seq
            if last is not None:        # unwrap
                s = last + ((msg.seq - last) & 0xFFFF) if ((msg.seq - last) & 0xFFFF) < 0x8000 \
                    else last - ((last - msg.seq) & 0xFFFF)
            last = s
            for k, r in enumerate(np.asarray(msg.records)):
                recs[s + k] = r
        elif am.am_type == P.AM_NINEDOF_MOTE_STATUS_MSG:
            status = decode_status(am.payload)
    crc = dec.stats.as_dict().get("crc_errors", 0)
    if not recs:
        return {"records": 0, "status": status, "crc_errors": crc}
    seqs = np.array(sorted(recs))
    base = seqs[0]
    vals = np.array([recs[s] for s in seqs])
    full = np.arange(seqs[0], seqs[-1] + 1)
    missing = np.setdiff1d(full, seqs)
    stale = np.zeros(len(seqs), bool)
    same = np.all(vals[1:].reshape(-1, 3, 3) == vals[:-1].reshape(-1, 3, 3), axis=2)
    stale[1:] = np.any(same, axis=1) & (np.diff(seqs) == 1)
    # sample times: the first record at first_sample_s, one per 8 ms
    t = lambda s: first_sample_s + (s - base) * PERIOD_S      # noqa: E731
    bad = sorted(set(missing.tolist()) | set(seqs[stale].tolist()))
    after = [s for s in bad if t(s) >= fault_at - 0.1]
    rec_s = (t(after[-1]) + PERIOD_S - fault_at) if after else 0.0
    return {"records": len(seqs), "missing": len(missing),
            "missing_after_fault": sum(1 for s in missing if t(s) >= fault_at - 0.1),
            "stale": int(stale.sum()), "recover_s": rec_s, "status": status, "crc_errors": crc,
            "first_seq": int(seqs[0]), "last_seq": int(seqs[-1])}


def cal_json(path: Path) -> Path:
    """A calibration of mote 1 as `motecal calibrate` writes it (planted values)."""
    from motecal.calib.result import BoardCalibration, SensorCalibration

    def sensor(name, unit, k, A, c):
        return SensorCalibration(sensor=name, unit=unit, chip="", lsb_per_unit=k, model="full",
                                 params=[], A=np.asarray(A) / k, c=c, mse_before=0.0,
                                 mse_after=0.0, min_before=1.0, max_before=1.0, min_after=1.0,
                                 max_after=1.0)
    g = np.random.default_rng(4)
    M = {n: np.eye(3) + np.tril(g.normal(0, 0.02, (3, 3))) for n in ("accel", "gyro", "mag")}
    BoardCalibration(
        mote=1, session="fault-matrix", created="2026-01-01T00:00:00Z",
        accel=sensor("accel", "g", 256.0, M["accel"], [0.05, -0.02, 0.03]),
        gyro=sensor("gyro", "deg/s", 14.375, M["gyro"], [-11.0, 6.0, 6.5]),
        mag=sensor("mag", "gauss", 1090.0, M["mag"], [-0.06, -0.02, 0.03]),
        gate={"accepted": True, "reasons": [], "warnings": []}).save(path)
    return path


def run_case(exe: Path, mote: Path, base: Path, name: str, faults: list[str], *, seconds: float,
             fault_at: float, out: Path, upload_loss: float | None = None,
             raw_set: bool = False) -> dict:
    args = ["--mote", f"{mote},id=1", "--base", f"{base},id=0", "--serial", "tcp:0",
            "--seconds", "3600", "--settle", "3"]       # stopped at `seconds` below
    for f in faults:
        args += ["--fault", f]
    h = rc.Harness(exe, args, out / f"harness-{re.sub(r'[^a-z0-9]+', '-', name)}.err")
    url = h.wait_line(r"(socket://127\.0\.0\.1:\d+)", 60).group(1)
    up = None
    if upload_loss is None:
        reader = LineReader(url)
        while h.now() < seconds:
            time.sleep(0.3)
        data = reader.close()
    else:
        while h.now() < fault_at:
            time.sleep(0.2)
        h.send(f"loss {upload_loss}")
        t0 = h.now()
        cal = cal_json(out / "cal-mote1.json")
        proxy = Proxy(url)
        what = ["--reset"] if raw_set else [str(cal)]       # --reset: a commit of the raw set
        res = subprocess.run(rc.MOTECAL + ["upload", *what, "--port", proxy.url, "--mote",
                                           "1"], capture_output=True, text=True, timeout=1200)
        proxy.close()
        t1 = h.now()
        h.send("loss 0")
        text = res.stdout + res.stderr
        m = re.search(r"(\d+) messages, (\d+) repeated, (\d+) serial repeats, ([0-9.]+) s", text)
        up = {"exit": res.returncode, "emulated_s": t1 - t0,
              "wall_s": float(m.group(4)) if m else None,
              "messages": int(m.group(1)) if m else None, "repeated": int(m.group(2)) if m else None,
              "serial_repeats": int(m.group(3)) if m else None,
              "tries_lines": len(re.findall(r"sending it again", text)),
              "last_line": text.strip().splitlines()[-1] if text.strip() else ""}
        mv = re.search(r"uploading version (\d+)", text)
        if raw_set:
            mv = None
        up["diff"] = set_diff(bytes(proxy.to_mote), bytes(proxy.to_host),
                              int(mv.group(1))) if mv else []
        (out / "upload.txt").write_text(text)
        if res.returncode != 0:       # what is in force now, decoded (upload --show)
            h.send("loss 0")
            show = subprocess.run(rc.MOTECAL + ["upload", "--show", str(cal), "--port", url,
                                                "--mote", "1"],
                                  capture_output=True, text=True, timeout=600)
            up["show"] = [ln for ln in (show.stdout + show.stderr).strip().splitlines()
                          if "sending it again" not in ln]
        reader = LineReader(url)       # the samples after the upload (3 s: a status too)
        t2 = h.now()
        while h.now() < t2 + 3:
            time.sleep(0.3)
        data = reader.close()
    rep = h.stop()
    if rep is None:
        print(f"  (the harness's report could not be read: exit {h.proc.returncode}, "
              f"{len(h.report)} report lines; stderr in {h.err.name})", flush=True)
    node = next(n for n in rep["nodes"] if n["role"] == "mote") if rep else {}
    res = analyse(data, fault_at, node.get("first_sample_s", 1.0)) if upload_loss is None \
        else {"upload": up, **analyse(data, 0, node.get("first_sample_s", 1.0))}
    res["wires"] = node.get("wires", {})
    res["bus"] = {k: node.get(k) for k in ("addr_nacks", "data_nacks", "arb_lost", "hang_waits",
                                           "missing_periods", "reads_per_s")}
    res["chips"] = {c: {k: v[k] for k in ("nacked", "resets", "stale_reads")}
                    for c, v in node.get("chips", {}).items()}
    return res


@dataclass(frozen=True)
class Expect:
    """What a case must show.  missing: sequence numbers missing from the
    fault on, at most; recover_s: time to recover, at most; stale: stale
    records, at most; status: the mote's last status counters, name (or
    "a+b", a sum) -> (low, high) inclusive; wires: the harness's wire
    counters likewise; records: records the host got, at least; upload: the
    uploader's exit status must be 0."""
    missing: int = 0
    recover_s: float = 0.0
    stale: int = 0
    status: dict = field(default_factory=dict)
    wires: dict = field(default_factory=dict)
    records: int = 1
    upload: bool = False


ZERO = (0, 0)
QUIET = {"i2c_errors": ZERO, "late": ZERO, "i2c_nacks": ZERO, "bus_resets": ZERO,
         "chip_reinits": ZERO, "dropped": ZERO}
# a line shorted for 2 s: one watchdog abort finds it (16-24 ms in), then one
# clear every 256 ms (NINEDOF_BUSDOWN_RETRY_MS) until one finds the line free
# (the ninth, ~2.02 s in): bus_resets 9 (8-10 with the clears' phase), not one
# every 16 ms (~125); the periods meanwhile are refused reads (lean master:
# i2c_errors) or late (stock master: its read cannot be aborted)
DOWN = 2 * 125 + 256 // 8 + 5
SHORT = Expect(missing=DOWN, recover_s=2 + 0.3,
               status={"bus_resets": (8, 10), "i2c_errors+late": (240, DOWN),
                       "i2c_nacks": ZERO, "chip_reinits": ZERO},
               wires={"stuck_holds": ZERO, "sda_held_at_end": ZERO})
# (name, faults, expectation); {T} is the fault's start
CASES = [
    ("none", [], Expect(missing=0, recover_s=0, status=QUIET, wires={"gpio_scl_pulses": ZERO})),
    # 0.5 s of NACKs: 62.5 periods, and the record before each failed read
    ("nack itg3200 0.5 s", ["nack:itg3200:{T}:0.5"],
     Expect(missing=66, recover_s=0.52, status={"i2c_nacks": (60, 66), "i2c_errors": (60, 66),
                                                "bus_resets": ZERO})),
    ("adxl345 power loss 0.1 s", ["power:adxl345:{T}:0.1"],
     Expect(missing=16, recover_s=0.12, status={"i2c_nacks": (11, 16), "chip_reinits": (1, 1),
                                                "bus_resets": ZERO})),
    ("hmc5883l power loss 0.1 s", ["power:hmc5883l:{T}:0.1"],
     Expect(missing=16, recover_s=0.12, status={"i2c_nacks": (11, 16), "chip_reinits": (1, 1),
                                                "bus_resets": ZERO})),
    # the bus stays busy until 8 SCL pulses: only the firmware's bus clear
    # gives them (the watchdog's abort 16-24 ms in), then a STOP
    ("itg3200 stuck mid-byte", ["stuck:itg3200:{T}:8"],
     Expect(missing=5, recover_s=0.04, status={"bus_resets": (1, 1), "i2c_nacks": ZERO,
                                               "i2c_errors+late": (1, 4)},
            wires={"stuck_holds": (1, 1), "stuck_freed": (1, 1), "freed_after_pulses": (8, 8),
                   "gpio_scl_pulses": (9, 9), "gpio_stops": (1, 1), "sda_held_at_end": ZERO})),
    ("SDA shorted 2 s", ["short:sda:{T}:2"], SHORT),
    ("SCL shorted 2 s", ["short:scl:{T}:2"], SHORT),
    # what the MCU sends in 3 s is dropped (375 samples), nothing else
    ("serial unread 3 s", ["unread:{T}:3"],
     Expect(missing=380, recover_s=3.05, status=QUIET)),
]
# the upload verified, the samples go on (3 s read after it: 375 records and a
# status message; a few lost on the air)
UPLOAD = Expect(missing=10, recover_s=1e9, records=330, upload=True,
                status={"dropped": ZERO, "i2c_errors": ZERO})


def _value(table: dict, key: str):
    if "+" in key:
        parts = [table.get(k) for k in key.split("+")]
        return None if any(v is None for v in parts) else sum(parts)
    return table.get(key)


def check(exp: Expect, res: dict) -> list[str]:
    """Where `res` (run_case's result) does not meet `exp`: one line each."""
    bad = []
    if res.get("records", 0) < exp.records:
        bad.append(f"records {res.get('records', 0)} < {exp.records}")
    miss = res.get("missing_after_fault", 0)
    if miss > exp.missing:
        bad.append(f"sequence numbers missing {miss} > {exp.missing}")
    if res.get("stale", 0) > exp.stale:
        bad.append(f"stale records {res['stale']} > {exp.stale}")
    if res.get("recover_s", 0) > exp.recover_s:
        bad.append(f"time to recover {1000 * res['recover_s']:.0f} ms > "
                   f"{1000 * exp.recover_s:.0f} ms")
    for what, want in (("status", exp.status), ("wires", exp.wires)):
        got = res.get(what) or {}
        for key, (lo, hi) in want.items():
            v = _value(got, key)
            if v is None:
                bad.append(f"{what} {key}: not reported")
            elif not lo <= v <= hi:
                bad.append(f"{what} {key} {v}, expected {lo}" + (f"..{hi}" if hi != lo else ""))
    if exp.upload and (res.get("upload") or {}).get("exit") != 0:
        bad.append(f"upload exit {(res.get('upload') or {}).get('exit')}, expected 0")
    return bad


def override(expects: dict, spec: str) -> None:
    """--expect NAME:FIELD=VALUE: change one expectation (NAME a part of a
    case's name; FIELD missing, recover_s, stale, records, or a status /
    wires counter as status.KEY=LO..HI)."""
    m = re.fullmatch(r"(.+?):([a-z_.+]+)=([-0-9.]+?)(?:\.\.([-0-9.]+))?", spec)
    names = [n for n in expects if m and m.group(1) in n]
    if not m or not names:
        raise ValueError(f"--expect {spec!r}: NAME:FIELD=VALUE with NAME part of a case's name")
    fld, lo, hi = m.group(2), m.group(3), m.group(4) or m.group(3)
    for n in names:
        e = expects[n]
        if fld.startswith(("status.", "wires.")):
            what, key = fld.split(".", 1)
            table = dict(getattr(e, what))
            table[key] = (int(lo), int(hi))
            expects[n] = replace(e, **{what: table})
        elif fld in ("missing", "stale", "records"):
            expects[n] = replace(e, **{fld: int(lo)})
        elif fld == "recover_s":
            expects[n] = replace(e, recover_s=float(lo))
        else:
            raise ValueError(f"--expect {spec!r}: no field {fld!r}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--src", default=str(emulate.REPO))
    ap.add_argument("--cflags", default="")
    ap.add_argument("--mote-elf")
    ap.add_argument("--base-elf")
    ap.add_argument("--lean", action="store_true",
                    help="the sensor mote built with the lean TWI master (NINEDOF_LEAN_I2C=1)")
    ap.add_argument("--seconds", type=float, default=14)
    ap.add_argument("--fault-at", type=float, default=6)
    ap.add_argument("--loss", type=float, default=0.3, help="radio loss during the upload")
    ap.add_argument("--only", help="run only the cases whose name contains this")
    ap.add_argument("--expect", action="append", default=[],
                    help="change one expectation: NAME:FIELD=VALUE (e.g. 'none:missing=-1', "
                         "'stuck:status.bus_resets=2')")
    ap.add_argument("--out")
    a = ap.parse_args(argv)
    expects = {n: e for n, _, e in CASES}
    expects[f"upload, radio loss {a.loss:g}"] = UPLOAD
    expects[f"upload --reset (raw set), radio loss {a.loss:g}"] = UPLOAD
    try:
        for spec in a.expect:
            override(expects, spec)
        if not (a.mote_elf and a.base_elf):
            emulate.toolchain()
        if not (2 < a.fault_at < a.seconds - 6):
            raise ValueError("--fault-at must be > 2 and at least 6 s before --seconds")
    except (ValueError, emulate.Unavailable) as e:
        print(f"fault-matrix: {e}", file=sys.stderr)
        return 2
    tmp = tempfile.TemporaryDirectory(prefix="motecal-faults-")
    out = Path(a.out) if a.out else Path(tmp.name)
    out.mkdir(parents=True, exist_ok=True)
    if a.mote_elf and a.base_elf:
        mote, base = Path(a.mote_elf), Path(a.base_elf)
    else:
        mote, base = rc.build_images(Path(a.src), out, a.cflags)
        if a.lean:
            mote = emulate.build_image("tinyos", out / "mote-lean.elf", lean=True)
    exe = emulate.build_harness(out / "emu-build")
    T = a.fault_at
    print(f"one sensor mote (id 1, 8 MHz, {mote.name}) + BaseStation, {a.seconds:g} s "
          f"emulated, fault at {T:g} s; the host reads the BaseStation on TCP (motecal's "
          "decoder)", flush=True)
    cases = [(n, [f.format(T=T) for f in fs], None, False) for n, fs, _ in CASES]
    cases.append((f"upload, radio loss {a.loss:g}", [], a.loss, False))
    cases.append((f"upload --reset (raw set), radio loss {a.loss:g}", [], a.loss, True))
    failed, ran = [], 0
    for name, faults, loss, raw in cases:
        if a.only and a.only not in name:
            continue
        t0 = time.monotonic()
        r = run_case(exe, mote, base, name, faults, seconds=a.seconds, fault_at=T, out=out,
                     upload_loss=loss, raw_set=raw)
        st = r.get("status") or {}
        print(f"\n== {name}  ({' '.join(faults) or 'no --fault'}; {time.monotonic() - t0:.0f} s wall)")
        if r.get("upload"):
            u = r["upload"]
            print(f"  upload: exit {u['exit']}, {u['emulated_s']:.2f} s emulated "
                  f"({u['wall_s']} s by the uploader's clock), {u['messages']} messages, "
                  f"{u['repeated']} repeated, {u['serial_repeats']} serial repeats; "
                  f"last line: {u['last_line']}")
            print("  read back vs sent: " + ("; ".join(u["diff"]) or "no byte differs "
                                             "(in the replies that arrived)"))
            for ln in u.get("show", []):
                print(f"  upload --show: {ln}")
        print(f"  host: {r['records']} records, {r.get('missing', 0)} sequence numbers missing "
              f"({r.get('missing_after_fault', 0)} from the fault on), {r.get('stale', 0)} stale "
              f"records, CRC errors {r['crc_errors']}; time to recover "
              f"{1000 * r.get('recover_s', 0):.0f} ms from the fault's start")
        print("  mote status: " + (" ".join(f"{k} {v}" for k, v in st.items()) or "none received"))
        print(f"  bus: {r['bus']}; chips: {r['chips']}")
        print("  wires: " + " ".join(f"{k} {v}" for k, v in r["wires"].items()))
        bad = check(expects[name], r)
        ran += 1
        print("  expected: " + describe(expects[name]))
        print("  -> " + ("met" if not bad else "NOT MET: " + "; ".join(bad)), flush=True)
        if bad:
            failed.append(name)
    if not a.out:
        tmp.cleanup()
    print(f"\nfault-matrix: {ran} cases, {len(failed)} not as expected"
          + (": " + ", ".join(failed) if failed else ""))
    return 1 if failed else 0


def describe(e: Expect) -> str:
    parts = [f"missing <= {e.missing}", f"stale <= {e.stale}"]
    if e.recover_s < 1e9:
        parts.append(f"recovered within {1000 * e.recover_s:.0f} ms")
    if e.records > 1:
        parts.append(f"records >= {e.records}")
    if e.upload:
        parts.append("upload verified (exit 0)")
    for what, table in (("status", e.status), ("wires", e.wires)):
        parts += [f"{what} {k} " + (f"{lo}" if lo == hi else f"{lo}..{hi}")
                  for k, (lo, hi) in table.items()]
    return ", ".join(parts)


if __name__ == "__main__":
    sys.exit(main())
