"""`make emulate`: build the sensor-mote and BaseStation images with nesC and
TinyOS, build the harness (emu/, ninedof-emu), run N sensor motes and the
BaseStation in it and print what the emulated hardware measured: reads per
second, periods without a read, I2C time per sample on the emulated bus,
CPU load, ROM/RAM of the images, and the BaseStation's serial port.

    make emulate TINYOS_ROOT_DIR=/path/to/tinyos-main [EMULATE_ARGS="--motes 3 --seconds 30"]
    python3 emu/emulate.py --help

Needs a TinyOS 2.x tree (TINYOS_ROOT_DIR) and nesC >= 1.4.0 on PATH
(docs/emulation.md).  Also used by bench/bench_cycles.py (measure()).
"""
from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
EMU = REPO / "emu"
MHZ_DEFAULT = "8.0"
# read() to readDone in the firmware: two global labels the board puts in its
# code (NINEDOF_SPAN_MARK in sensorboards/ninedof/NineDofBoard.h), no
# instruction of their own: the entry of NineDofBoardP's ReadNow.read and the
# point where readEnd signals ReadNow.readDone (after the bus release)
SPAN = "ninedof_span_read:ninedof_span_readdone"


class Unavailable(Exception):
    """The TinyOS tree or nesC is missing: one line for the user."""


def toolchain() -> Path:
    """TINYOS_ROOT_DIR, checked, and nesC >= 1.4.0 on PATH."""
    root = os.environ.get("TINYOS_ROOT_DIR")
    if not root:
        raise Unavailable("TINYOS_ROOT_DIR is not set (a TinyOS 2.x tree, tinyos-main)")
    if not (Path(root) / "Makefile.include").is_file():
        raise Unavailable(f"TINYOS_ROOT_DIR={root} has no Makefile.include (not a TinyOS 2.x tree)")
    if shutil.which("nescc") is None:
        raise Unavailable("nescc is not on PATH (nesC >= 1.4.0; Debian's 1.3.5 crashes)")
    out = subprocess.run(["nescc", "--version"], capture_output=True, text=True).stdout
    m = re.search(r"nescc: (\d+)\.(\d+)\.(\d+)", out)
    if not m or tuple(map(int, m.groups())) < (1, 4, 0):
        raise Unavailable(f"nescc is {m.group(0) if m else 'of unknown version'}; "
                          "nesC >= 1.4.0 is needed")
    return Path(root)


def build_image(app: str, out: Path, *, lean: bool = False, make_vars=()) -> Path:
    """`make -C <app> iris` (the TinyOS make system, build/iris in the app's
    folder), the ELF copied to out.  make_vars: more VAR=value settings
    (e.g. NINEDOF_ITG_RATES_ONLY=1)."""
    cmd = ["make", "-C", str(REPO / app), "iris", f"TINYOS_ROOT_DIR={os.environ['TINYOS_ROOT_DIR']}"]
    if lean:
        cmd.append("NINEDOF_LEAN_I2C=1")
    cmd += list(make_vars)
    res = subprocess.run(cmd, capture_output=True, text=True)
    if res.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed:\n{res.stdout[-3000:]}{res.stderr[-3000:]}")
    out.parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(REPO / app / "build" / "iris" / "main.exe", out)
    return out


def build_harness(build_dir: Path) -> Path:
    res = subprocess.run(["make", "-s", "-C", str(EMU), f"BUILD={build_dir}"],
                         capture_output=True, text=True)
    if res.returncode != 0:
        raise RuntimeError(f"building the harness failed:\n{res.stdout}{res.stderr}")
    return build_dir / "ninedof-emu"


def run_harness(exe: Path, args: list[str], echo=None) -> dict:
    """Run ninedof-emu --report json; lines before the report (the serial
    port) go to echo as they come.  The report."""
    proc = subprocess.Popen([str(exe), *args, "--report", "json"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    report = []
    for line in proc.stdout:
        if report or line.startswith('{"seconds"'):
            report.append(line)
        elif echo:
            echo(line.rstrip("\n"))
    err = proc.stderr.read()
    if proc.wait() != 0:
        raise RuntimeError(f"ninedof-emu {' '.join(args)}: exit {proc.returncode}\n{err}")
    return json.loads("".join(report))


def measure(out: Path, *, motes: int = 1, seconds: float = 20, settle: float = 5,
            mhz=(8.0,), lean: bool = False, base: bool | Path = True, serial: str = "null",
            faults=(), boards=(), echo=None, mote: Path | None = None, xtal_ppm=(0.0,),
            temp_c=()) -> dict:
    """Build both images (the mote's unless given; base: True to build the
    BaseStation's, a Path to use that image, False for none) and the harness
    into out, run; the report.  mhz: one clock per mote (cycled); temp_c:
    each mote's board temperature in C (cycled; none: the board's own)."""
    if mote is None:
        mote = build_image("tinyos", out / ("mote-lean.elf" if lean else "mote.elf"), lean=lean)
    exe = build_harness(out / "emu-build")
    args = []
    for i in range(motes):
        spec = f"{mote},id={i + 1},mhz={mhz[i % len(mhz)]}"
        if xtal_ppm[i % len(xtal_ppm)]:
            spec += f",xtal_ppm={xtal_ppm[i % len(xtal_ppm)]}"
        if i < len(boards):
            spec += f",board={boards[i]}"
        if temp_c:
            spec += f",temp={temp_c[i % len(temp_c)]}"
        args += ["--mote", spec]
    if base:
        bs = base if isinstance(base, Path) else build_image("basestation", out / "basestation.elf")
        args += ["--base", f"{bs},id=0", "--serial", serial]
    args += ["--seconds", str(seconds), "--settle", str(settle)]
    for f in faults:
        args += ["--fault", f]
    try:
        return run_harness(exe, args + ["--span", SPAN], echo)
    except RuntimeError as e:
        if "has no function" not in str(e):
            raise
        return run_harness(exe, args, echo)     # an image without those functions


def print_report(rep: dict, master: str) -> None:
    print(f"emulated {rep['seconds']:.1f} s; rates, gaps and CPU load from {rep['settle']:.1f} s on")
    for n in rep["nodes"]:
        print(f"{'BaseStation' if n['role'] == 'base' else 'sensor mote'} id {n['id']}: "
              f"{n['elf']}  ROM {n['rom']} B, RAM {n['ram']} B, {n['mhz']:.2f} MHz, "
              f"CPU load {100 * n['cpu_load']:.1f} % (cycles not asleep), {n['state']}")
        if n["role"] != "mote":
            continue
        if not n["samples"] and not n["radio"]:
            print("  no reads: this harness has no RF230 model (emu/rf230.c), and the app starts "
                  "sampling only when its radio has started")
        print(f"  reads/s {n['reads_per_s']:.3f} ({n['samples_after_settle']} samples), "
              f"periods without a read {n['missing_periods']} in {n['gaps']} gaps, "
              f"first read at {n['first_sample_s']:.3f} s")
        ps = n.get("per_second", [])
        if ps:
            print(f"  reads in each emulated second: {' '.join(str(x) for x in ps[:12])}"
                  + (" ..." if len(ps) > 12 else ""))
        if n.get("span"):
            sp = n["span"]
            print(f"  read() -> readDone ({sp['n']} reads): mean {sp['us_mean']:.1f} us, "
                  f"p99 {sp['us_p99']:.1f}, max {sp['us_max']:.1f} (min {sp['us_min']:.1f})")
        print(f"  I2C per sample ({master}, SCL {n['scl_hz'] / 1e3:.0f} kHz, first START asked "
              f"-> last STOP sent): mean {n['i2c_us_mean']:.1f} us (min {n['i2c_us_min']:.1f}, "
              f"max {n['i2c_us_max']:.1f}); on the wire {n['wire_us_mean']:.1f} us, "
              f"SCL held low for the CPU {n['held_us_mean']:.1f} us")
        bad = {k: n[k] for k in ("addr_nacks", "data_nacks", "arb_lost", "hang_waits") if n[k]}
        bad.update({k: v for k, v in n.get("wires", {}).items() if v})
        itg = n.get("chips", {}).get("itg3200", {})
        if itg.get("temp_reads"):
            print(f"  ITG-3200 TEMP_OUT read {itg['temp_reads']} times (in the rates' burst), "
                  f"last {itg['last_temp']} = {35 + (itg['last_temp'] + 13200) / 280:.2f} C")
        chips = ", ".join(f"{c} {v['data_reads']} reads ({v['stale_reads']} stale, "
                          f"{v['nacked']} NACKed, {v['resets']} power-on resets)"
                          for c, v in n["chips"].items())
        print(f"  chips: {chips}" + (f"; bus: {bad}" if bad else ""))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--motes", type=int, default=3, help="sensor motes, ids 1..N (default 3)")
    ap.add_argument("--seconds", type=float, default=20, help="emulated seconds (default 20)")
    ap.add_argument("--settle", type=float, default=5,
                    help="rates and loads count from here (default 5 s: boot + clock loop)")
    ap.add_argument("--mhz", default=MHZ_DEFAULT,
                    help="RC clock of each mote in MHz, comma-separated, cycled (default 8.0)")
    ap.add_argument("--xtal-ppm", default="0",
                    help="32768 Hz crystal error of each mote in ppm, comma-separated, cycled")
    ap.add_argument("--lean", action="store_true", help="build with NINEDOF_LEAN_I2C=1")
    ap.add_argument("--serial", default="pty",
                    help="BaseStation UART0: pty (default), tcp:PORT (127.0.0.1) or null")
    ap.add_argument("--fault", action="append", default=[],
                    help="nack:CHIP:T:D, power:CHIP:T:D, short:sda|scl:T[:D], stuck:CHIP:T[:N] "
                         "or unread:T:D [@NODE] (emu/faults.h)")
    ap.add_argument("--board", action="append", default=[],
                    help="board table for mote i (i-th use; emu/board.py writes them)")
    ap.add_argument("--session", help="boards from the simulator (emu/board.py): every mote "
                    "without --board follows this session's trajectory (static80, rotation, ...)")
    ap.add_argument("--seed", type=int, default=1, help="simulator seed for --session")
    ap.add_argument("--model", help="simulator error model for --session (file or name)")
    ap.add_argument("--out", help="folder for images and the harness (default: a temp folder)")
    ap.add_argument("--temp", default="",
                    help="board temperature of each mote in C, comma-separated, cycled "
                         "(what the ITG-3200 model's TEMP_OUT reads; default: the board's, 25 C)")
    ap.add_argument("--json", action="store_true", help="print the harness's JSON report")
    a = ap.parse_args(argv)
    try:
        if not 1 <= a.motes <= 30:
            raise ValueError(f"--motes must be 1..30, not {a.motes}")
        if not 0 < a.seconds <= 3600 or not 0 <= a.settle < a.seconds:
            raise ValueError("--seconds must be in (0, 3600] and --settle in [0, seconds)")
        mhz = [float(x) for x in a.mhz.split(",")]
        if not all(1 <= m <= 20 for m in mhz):
            raise ValueError(f"--mhz must be 1..20 MHz, not {a.mhz}")
        xtal = [float(x) for x in a.xtal_ppm.split(",")]
        if not all(-1000 <= x <= 1000 for x in xtal):
            raise ValueError(f"--xtal-ppm must be -1000..1000, not {a.xtal_ppm}")
        temps = [float(x) for x in a.temp.split(",")] if a.temp else []
        if not all(-40 <= x <= 125 for x in temps):
            raise ValueError(f"--temp must be -40..125 C, not {a.temp}")
        toolchain()
    except (ValueError, Unavailable) as e:
        print(f"emulate: {e}", file=sys.stderr)
        return 2
    watch = None
    with tempfile.TemporaryDirectory(prefix="motecal-emu-") as tmp:
        out = Path(a.out) if a.out else Path(tmp)
        print(f"building the images ({'lean TWI master' if a.lean else 'Atm128I2CMasterC'}) "
              "and the harness ...", flush=True)
        try:
            boards = list(a.board)
            if a.session:
                import board as board_tables
                for i in range(len(boards), a.motes):
                    path = out / f"board-{i + 1}.txt"
                    out.mkdir(parents=True, exist_ok=True)
                    board_tables.write(path, board_tables.counts(
                        i + 1, seconds=a.seconds, session=a.session, seed=a.seed, model=a.model),
                        1000.0)
                    boards.append(str(path))
            watch = None

            def echo(line):
                nonlocal watch
                print(f"BaseStation serial: {line}", flush=True)
                if a.serial == "pty" and line.startswith("/dev/") and watch is None:
                    try:         # count what arrives, as the host would see it
                        import serial_watch
                        watch = serial_watch.SerialWatch()
                        watch.open(line.strip())
                    except (ImportError, OSError) as e:
                        print(f"  (not read here: {e})", flush=True)
                        watch = None

            rep = measure(out, motes=a.motes, seconds=a.seconds, settle=a.settle, mhz=mhz,
                          lean=a.lean, serial=a.serial, faults=a.fault, boards=boards,
                          echo=echo, xtal_ppm=xtal, temp_c=temps)
        except RuntimeError as e:
            print(f"emulate: {e}", file=sys.stderr)
            return 1
        except Exception as e:        # the simulator's checks of --session/--model
            print(f"emulate: {e}", file=sys.stderr)
            return 2
    if a.json:
        print(json.dumps(rep, indent=1))
    else:
        print_report(rep, "NineDofTwiMasterC" if a.lean else "Atm128I2CMasterC")
    if watch is not None:
        watch.close()
        print("\n".join(watch.summary()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
