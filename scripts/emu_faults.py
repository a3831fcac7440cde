#!/usr/bin/env python3
"""The firmware's fault cases in the emulator (docs/firmware-driver.md, "In the
emulator"): builds tinyos/apps/SampleBoard (both masters) and runs each fault
in ninedof-emu, printing the SampleBoard counter lines; with --base, also the
full sensor mote image beside the BaseStation image, decoding the status
messages from the BaseStation's serial line.

Not part of CI: needs nesC >= 1.4.0 and a TinyOS tree (TINYOS_ROOT_DIR), and
a built ninedof-emu (emu/, with the RF230 model for --base).

    python3 scripts/emu_faults.py --emu emu/build/ninedof-emu [--base]
"""
from __future__ import annotations

import argparse
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "host"))

BOARD_FAULTS = ["", "nack:itg3200:2:0.5", "power:hmc5883l:2:0.3", "power:adxl345:2:0.3",
                "power:itg3200:2:0.3", "hang:2:0.05", "hang:2:0.2", "hang:2.003:1"]
IMAGE_FAULTS = [(), ("nack:itg3200:2:0.5", "power:hmc5883l:4:0.3"), ("hang:2:0.3",),
                ("hang:4:1",), ("nack:adxl345:0:10",)]


def build(app: Path, lean: int, out: Path) -> Path:
    res = subprocess.run(["make", "-C", str(app), "iris", f"NINEDOF_LEAN_I2C={lean}"],
                         capture_output=True, text=True)
    if res.returncode != 0:
        sys.exit(f"emu_faults: building {app} failed:\n{res.stdout[-2000:]}{res.stderr[-2000:]}")
    shutil.copy(app / "build" / "iris" / "main.exe", out)
    return out


def board_runs(emu: str, tmp: Path) -> None:
    for lean, name in ((0, "stock"), (1, "lean")):
        elf = build(REPO / "tinyos" / "apps" / "SampleBoard", lean, tmp / f"sb-{name}.elf")
        for fault in BOARD_FAULTS:
            con = tmp / "console.txt"
            cmd = [emu, "--mote", f"{elf},id=1", "--seconds", "5", "--console", str(con)]
            if fault:
                cmd += ["--fault", fault]
            subprocess.run(cmd, capture_output=True, text=True, timeout=600)
            lines = [ln for ln in con.read_text().splitlines() if ln.startswith("board ")]
            print(f"== SampleBoard, {name} master, fault {fault or 'none'}")
            for ln in lines[-3:]:
                print("   " + ln.split(" last ")[0])


def image_run(emu: str, mote: Path, base: Path, seconds: float, faults) -> None:
    from motecal.line import protocol as P
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    cmd = [emu, "--mote", f"{mote},id=1", "--base", f"{base},id=0", "--serial", f"tcp:{port}",
           "--seconds", str(seconds), "--report", "text"]
    for f in faults:
        cmd += ["--fault", f]
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    for _ in range(200):
        try:
            conn = socket.create_connection(("127.0.0.1", port), timeout=1)
            break
        except OSError:
            time.sleep(0.05)
    else:
        p.kill()
        sys.exit("emu_faults: no serial port from ninedof-emu")
    data = bytearray()
    conn.settimeout(0.5)
    with conn:
        while p.poll() is None:
            try:
                chunk = conn.recv(65536)
            except socket.timeout:
                continue
            if not chunk:
                break
            data += chunk
    report = p.communicate()[0]
    print(f"== sensor mote + BaseStation, {mote.stem}, faults {' '.join(faults) or 'none'}")
    print("   " + next((ln.strip() for ln in report.splitlines() if ln.strip().startswith("samples")), ""))
    records = 0
    for fr in P.decode_stream(bytes(data)):
        am = fr.am()
        if am is None or am.src != 1:
            continue
        if am.am_type == P.AM_NINEDOF_SAMPLES_MSG:
            records += len(P.unpack_samples(am.payload).records)
        elif am.am_type == P.AM_NINEDOF_MOTE_STATUS_MSG:
            st = P.decode_message(am)
            keys = ("seq", "i2c_errors", "late") + tuple(k for k in P.MOTE_STATUS_FAULTS if k in st)
            print(f"   status ({len(am.payload)} bytes): " + " ".join(f"{k} {st[k]}" for k in keys))
    print(f"   records received by the host: {records}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--emu", required=True, help="the ninedof-emu binary")
    ap.add_argument("--base", action="store_true",
                    help="also the full mote + BaseStation images (needs the RF230 model)")
    a = ap.parse_args()
    if not os.environ.get("TINYOS_ROOT_DIR"):
        print("emu_faults: TINYOS_ROOT_DIR is not set (a TinyOS tree is needed)", file=sys.stderr)
        return 2
    if not Path(a.emu).is_file():
        print(f"emu_faults: no emulator at {a.emu}", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory(prefix="emu-faults-") as d:
        tmp = Path(d)
        board_runs(a.emu, tmp)
        if a.base:
            base = build(REPO / "basestation", 0, tmp / "base.elf")
            for lean, name in ((0, "stock"), (1, "lean")):
                mote = build(REPO / "tinyos", lean, tmp / f"mote-{name}.elf")
                for faults in IMAGE_FAULTS:
                    image_run(a.emu, mote, base, {(): 6, ("hang:2:0.3",): 5, ("nack:adxl345:0:10",): 6}.get(faults, 7),
                              faults)
    return 0


if __name__ == "__main__":
    sys.exit(main())
