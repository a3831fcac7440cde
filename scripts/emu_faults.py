#!/usr/bin/env python3
"""The board's fault handling in the example app tinyos/apps/SampleBoard (the
board read every 8 binary ms with its watchdog, a line of counters a second)
in the emulator (docs/firmware-driver.md, "In the emulator"): builds it with
both masters and runs each fault in ninedof-emu, printing the counter lines.
The full sensor-mote image with the BaseStation is `make fault-matrix`
(emu/fault_matrix.py, docs/emulation.md).

Not part of CI: needs nesC >= 1.4.0 and a TinyOS tree (TINYOS_ROOT_DIR,
docs/toolchain.md), and a built ninedof-emu (make -C emu).

    python3 scripts/emu_faults.py --emu emu/build/ninedof-emu
"""
from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent

BOARD_FAULTS = ["", "nack:itg3200:2:0.5", "power:hmc5883l:2:0.3", "power:adxl345:2:0.3",
                "power:itg3200:2:0.3", "stuck:itg3200:2:8", "short:sda:2:0.2",
                "short:sda:2.003:1", "short:scl:2:0.2"]


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


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--emu", required=True, help="the ninedof-emu binary")
    a = ap.parse_args()
    if not os.environ.get("TINYOS_ROOT_DIR"):
        print("emu_faults: TINYOS_ROOT_DIR is not set (a TinyOS tree is needed)", file=sys.stderr)
        return 2
    if not Path(a.emu).is_file():
        print(f"emu_faults: no emulator at {a.emu}", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory(prefix="emu-faults-") as d:
        board_runs(a.emu, Path(d))
    return 0


if __name__ == "__main__":
    sys.exit(main())
