"""`make release-check TINYOS_ROOT_DIR=...`: the release check, end to end on
the real iris images in the emulator harness (issue 12 item 3; outside CI,
which cannot build nesC).

  1. build the sensor-mote and BaseStation images (nesC, the TinyOS make
     system) and the harness (emu/);
  2. three sensor motes (7.84 / 8.00 / 8.16 MHz) and the BaseStation in the
     harness, the BaseStation's UART on a loopback TCP port; each mote's
     board follows the project simulator's person doing static80 (its poses
     held 2.5 s, moves of 1-1.5 s; then a second static80) after a first
     pose held for --lead s while the images boot and the logger connects;
  3. `motecal log --guided static80 --yes` over the emulated port: the
     logger's stillness detection takes the poses from the data;
  4. `motecal calibrate --upload` through the BaseStation image into each
     mote image: each upload ends only when its mote reports the set stored
     in its EEPROM (written and read back);
  5. each mote is reset (`reset I 0`: simavr's reset, the EEPROM kept) the
     moment its upload prints that the set is stored, while the command goes
     on with the next mote (any mote without that line: when the command
     exits): no time for a write still under way; the images boot with the
     set from their EEPROM;
  6. `motecal log --guided static80 --yes --poses N` again: the samples must
     come corrected and flagged with the new version; the accelerometer and
     magnetometer magnitudes of the pose means before (raw) and after
     (corrected on the mote), as `make demo` prints them.

Every figure printed comes from this run.  Exit 0 when every step passed.

    python3 emu/release_check.py [--src CHECKOUT] [--cflags "-DSOFTWAREACK_TIMEOUT=2000"]
"""
from __future__ import annotations

import argparse
import json
import os
import queue
import re
import shlex
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import emulate  # noqa: E402  (emu/ is not a package)

MOTECAL = [sys.executable, "-m", "motecal"]
MHZ = (7.84, 8.0, 8.16)


def say(text: str) -> None:
    print(f"\n== {text}", flush=True)


def build_images(src: Path, out: Path, cflags: str) -> tuple[Path, Path]:
    """make -C SRC/tinyos iris and SRC/basestation iris (CFLAGS from the
    environment, as the TinyOS make system takes them); the ELFs, copied."""
    env = dict(os.environ)
    if cflags:
        env["CFLAGS"] = cflags
    elfs = []
    for app, name in (("tinyos", "mote.elf"), ("basestation", "basestation.elf")):
        cmd = ["make", "-C", str(src / app), "iris",
               f"TINYOS_ROOT_DIR={os.environ['TINYOS_ROOT_DIR']}"]
        print("$ " + (f"CFLAGS={shlex.quote(cflags)} " if cflags else "") + " ".join(cmd),
              flush=True)
        res = subprocess.run(cmd, capture_output=True, text=True, env=env)
        if res.returncode != 0:
            raise RuntimeError(f"{' '.join(cmd)} failed:\n{res.stdout[-3000:]}{res.stderr[-3000:]}")
        rom = re.search(r"(\d+) bytes in ROM", res.stdout)
        ram = re.search(r"(\d+) bytes in RAM", res.stdout)
        print(f"  {app}: {rom.group(1) if rom else '?'} bytes in ROM, "
              f"{ram.group(1) if ram else '?'} bytes in RAM", flush=True)
        elf = out / name
        elf.write_bytes((src / app / "build" / "iris" / "main.exe").read_bytes())
        elfs.append(elf)
    return elfs[0], elfs[1]


def board_table(path: Path, mote: int, *, seconds: float, lead: float, session: str,
                seed: int, rate_hz: float = 1000.0) -> float:
    """The board of `mote` (simulator's error model, seed) following `session`,
    the first pose held from -lead s on; written for the harness.  The
    trajectory's length (s)."""
    import board as board_tables
    from motecal.sim.model import load_model
    from motecal.sim.trajectory import make_trajectory
    m = load_model(None)
    traj = make_trajectory(session, seed, rate_hz=m.rate_hz)
    sampler = m.board(mote, seed).sampler(traj, seed)
    t = np.arange(int(round(seconds * rate_hz))) / rate_hz - lead
    board_tables.write(path, np.asarray(sampler.read(t), dtype=np.int64), rate_hz)
    return traj.duration


class Harness:
    """ninedof-emu with --control in the background: its lines, commands."""

    def __init__(self, exe: Path, args: list[str], log: Path):
        cmd = [str(exe), *args, "--control", "--report", "json"]
        print("$ " + " ".join(shlex.quote(a) for a in cmd) + " &", flush=True)
        self.err = open(log, "w")
        self.proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     stderr=self.err, text=True)
        self.lines: queue.Queue = queue.Queue()
        self.report: list[str] = []
        self.t_start = time.monotonic()
        self.reader = threading.Thread(target=self._read, daemon=True)
        self.reader.start()

    def _read(self):
        for line in self.proc.stdout:
            if self.report or line.startswith('{"seconds"'):
                self.report.append(line)
            else:
                self.lines.put(line.rstrip("\n"))
        self.lines.put(None)

    def wait_line(self, pattern: str, timeout: float) -> re.Match:
        end = time.monotonic() + timeout
        while True:
            try:
                line = self.lines.get(timeout=max(0.01, end - time.monotonic()))
            except queue.Empty:
                raise RuntimeError(f"the harness printed no line matching {pattern!r} "
                                   f"within {timeout:.0f} s") from None
            if line is None:
                raise RuntimeError(f"the harness ended (exit {self.proc.wait()}) before "
                                   f"printing {pattern!r}")
            m = re.search(pattern, line)
            if m:
                return m

    def send(self, cmd: str) -> None:
        self.proc.stdin.write(cmd + "\n")
        self.proc.stdin.flush()

    def now(self) -> float:
        """Emulated seconds."""
        self.send("time")
        return float(self.wait_line(r"^time ([0-9.]+)", 60).group(1))

    def stop(self) -> dict | None:
        if self.proc.poll() is None:
            try:
                self.send("stop")
                self.proc.wait(120)
            except (BrokenPipeError, subprocess.TimeoutExpired):
                self.proc.kill()
                self.proc.wait()
        self.reader.join(30)             # every line of the report read
        self.err.close()
        try:
            return json.loads("".join(self.report)) if self.report else None
        except json.JSONDecodeError:
            return None


def motecal(args: list[str], log: Path, timeout: float,
            on_line=None) -> tuple[int, str, float]:
    """Run `motecal ARGS`, its output into log and echoed; (exit, output, wall s).
    ``on_line(line)`` is called with each line as it comes."""
    print("$ motecal " + " ".join(shlex.quote(a) for a in args), flush=True)
    t0 = time.monotonic()
    with open(log, "w") as f:
        proc = subprocess.Popen(MOTECAL + args, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                text=True)
        out = []
        timer = threading.Timer(timeout, proc.terminate)
        timer.start()
        for line in proc.stdout:
            if on_line:
                on_line(line)
            f.write(line)
            out.append(line)
            print("  " + line.rstrip("\n"), flush=True)
        rc = proc.wait()
        timer.cancel()
    return rc, "".join(out), time.monotonic() - t0


def pose_magnitudes(db: Path, session: str) -> dict:
    """Per mote: SessionData.pose_magnitudes (poses, |accel| and |mag| of the
    pose means, flags), the samples and the link statistics."""
    from motecal.sessions.store import open_store
    with open_store(str(db)) as st:
        data = st.load_session(session)
        links = st.link_stats(session)
    out = data.pose_magnitudes()
    for m, v in out.items():
        v.update(samples=len(v["flags"]), link=links["motes"].get(m, {}))
    return out


def rng(a: np.ndarray, digits: int = 4) -> str:
    return f"{a.min():.{digits}f}..{a.max():.{digits}f}" if len(a) else "-"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--src", default=str(emulate.REPO),
                    help="checkout whose tinyos/ and basestation/ are built (default: this one)")
    ap.add_argument("--cflags", default="", help="CFLAGS for both images (e.g. "
                    "-DSOFTWAREACK_TIMEOUT=2000)")
    ap.add_argument("--mote-elf", help="a sensor-mote image instead of building one")
    ap.add_argument("--base-elf", help="a BaseStation image instead of building one")
    ap.add_argument("--seed", type=int, default=1, help="simulator seed (boards, trajectory)")
    ap.add_argument("--lead", type=float, default=6.0,
                    help="emulated s the first pose is held before the trajectory starts")
    ap.add_argument("--poses-after", type=int, default=10,
                    help="poses logged after the reset (default 10)")
    ap.add_argument("--loss", type=float, default=0.0, help="radio loss rate")
    ap.add_argument("--out", help="folder for everything (default: a temp folder)")
    ap.add_argument("--timeout", type=float, default=3600,
                    help="wall seconds each logging step may take")
    a = ap.parse_args(argv)
    try:
        if not (a.mote_elf and a.base_elf):
            emulate.toolchain()
        if not 1 <= a.poses_after <= 40 or not 0 <= a.loss <= 1 or not 1 <= a.lead <= 60:
            raise ValueError("--poses-after must be 1..40, --loss 0..1, --lead 1..60")
    except (ValueError, emulate.Unavailable) as e:
        print(f"release-check: {e}", file=sys.stderr)
        return 2
    t_all = time.monotonic()
    tmp = tempfile.TemporaryDirectory(prefix="motecal-release-")
    out = Path(a.out) if a.out else Path(tmp.name)
    out.mkdir(parents=True, exist_ok=True)
    db = out / "release.db"
    if db.exists():
        db.unlink()
    failures: list[str] = []
    harness = None
    try:
        say("1. the images and the harness")
        if a.mote_elf and a.base_elf:
            mote, base = Path(a.mote_elf), Path(a.base_elf)
        else:
            mote, base = build_images(Path(a.src), out, a.cflags)
        exe = emulate.build_harness(out / "emu-build")
        print(f"  harness {exe}", flush=True)

        say("2. three sensor motes + the BaseStation; boards from the simulator")
        session = "static80,static80"
        seconds = 0.0
        boards = []
        for i in range(3):
            p = out / f"board-{i + 1}.txt"
            dur = board_table(p, i + 1, seconds=a.lead + 640, lead=a.lead, session=session,
                              seed=a.seed)
            boards.append(p)
            seconds = dur
        print(f"  board tables: {session} seed {a.seed}, {seconds:.1f} s of trajectory after "
              f"{a.lead:.0f} s in the first pose (1000 rows/s)", flush=True)
        args = []
        for i in range(3):
            args += ["--mote", f"{mote},id={i + 1},mhz={MHZ[i]},board={boards[i]}"]
        args += ["--base", f"{base},id=0", "--serial", "tcp:0", "--seconds", "3600",
                 "--settle", "5", "--seed", str(a.seed), "--loss", str(a.loss)]
        harness = Harness(exe, args, out / "harness.err")
        url = harness.wait_line(r"(socket://127\.0\.0\.1:\d+)", 60).group(1)
        print(f"  BaseStation serial port: {url}", flush=True)

        say("3. motecal log --guided static80 --yes over the emulated BaseStation")
        t_emu0 = harness.now()
        rc, text, wall = motecal(["log", "--port", url, "--db", str(db), "--session", "before",
                                  "--guided", "static80", "--yes"], out / "log1.txt", a.timeout)
        t_emu1 = harness.now()
        print(f"  logging took {wall:.0f} s wall, {t_emu1 - t_emu0:.1f} s emulated "
              f"({t_emu0:.1f} -> {t_emu1:.1f} s)", flush=True)
        if rc != 0:
            raise RuntimeError(f"motecal log exited {rc}")
        before = pose_magnitudes(db, "before")
        for m, v in sorted(before.items()):
            lk = v["link"]
            print(f"  mote {m}: {v['poses']} poses recorded, {v['samples']} samples, "
                  f"lost {lk.get('lost')}, mote counters: dropped {lk.get('mote_dropped')}, "
                  f"send_fail {lk.get('mote_send_fail')}, i2c_errors {lk.get('mote_i2c_errors')}, "
                  f"late {lk.get('mote_late')}", flush=True)
            if v["poses"] != 80:
                failures.append(f"mote {m}: {v['poses']} poses recorded, not 80")

        say("4. motecal calibrate --upload through the BaseStation image")
        t_emu0 = harness.now()
        # each mote is reset the moment its upload says the set is stored
        # (issue 29: what the word is worth), the others the moment the
        # command exits; mote id N is the harness's node index N - 1
        reset_sent = []

        def reset_when_stored(line):
            m = re.match(r"  mote (\d+): calibration version \d+ \(was \d+\) in force and "
                         r"verified, and stored", line)
            if m and int(m.group(1)) in (1, 2, 3):
                harness.send(f"reset {int(m.group(1)) - 1} 0")
                reset_sent.append(int(m.group(1)))
        rc, text, wall = motecal(["calibrate", "--db", str(db), "--session", "before", "--seed",
                                  "1", "--out", str(out / "cal-mote{mote}.json"), "--upload",
                                  "--port", url], out / "calibrate.txt", a.timeout,
                                 on_line=reset_when_stored)
        for m in (1, 2, 3):
            if m not in reset_sent:
                harness.send(f"reset {m - 1} 0")
        resets = [harness.wait_line(r"^reset node .*", 120).group(0) for _ in range(3)]
        t_emu1 = harness.now()
        print(f"  calibrate + upload took {wall:.0f} s wall, {t_emu1 - t_emu0:.1f} s emulated",
              flush=True)
        uploads = {int(m.group(1)): m.groups()[1:] for m in re.finditer(
            r"mote (\d+): calibration version (\d+) \(was (\d+)\) in force and verified, and "
            r"stored \(survives a reboot\); (\d+) messages, (\d+) repeated, (\d+) serial "
            r"repeats, ([0-9.]+) s", text)}
        stored = {}                 # mote -> s from its commit to the report saying stored
        for part in re.split(r"(?m)^  uploading to mote ", text)[1:]:
            m = re.search(r"stored: version \d+ written to the EEPROM and read back, ([0-9.]+) s "
                          r"after the commit", part)
            if m:
                stored[int(part.split()[0])] = m.group(1)
        for m in sorted(before):
            if m in uploads:
                ver, was, msgs, rep, srep, secs = uploads[m]
                print(f"  mote {m}: version {ver} in force and verified (was {was}), stored "
                      f"{stored.get(m, '?')} s after its commit; upload {secs} s wall, {msgs} "
                      f"messages, {rep} repeated, {srep} serial repeats", flush=True)
            else:
                failures.append(f"mote {m}: no upload verified and stored")
        if rc != 0:
            failures.append(f"motecal calibrate --upload exited {rc}")

        say("5. each mote reset (EEPROM kept) the moment its upload said stored")
        for line in resets:
            print("  " + line, flush=True)

        say(f"6. log {a.poses_after} poses after the reset: corrected on the mote?")
        rc, text, wall = motecal(["log", "--port", url, "--db", str(db), "--session", "after",
                                  "--guided", "static80", "--yes", "--poses",
                                  str(a.poses_after)], out / "log2.txt", a.timeout)
        if rc != 0:
            failures.append(f"motecal log after the reset exited {rc}")
        after = pose_magnitudes(db, "after")
        print(f"{'mote':>4}  {'poses':>5}  {'accel |g| raw':>15}  {'accel |g| on-mote':>17}  "
              f"{'mag gauss raw':>15}  {'mag gauss on-mote':>17}  flagged  lost before/after",
              flush=True)
        for m in sorted(before):
            b, f = before[m], after.get(m)
            if f is None:
                failures.append(f"mote {m}: no samples after the reset")
                continue
            ver = int(uploads[m][0]) if m in uploads else None
            flagged = bool(np.all(f["flags"] & 1))
            vbits = bool(ver is not None and np.all((f["flags"] >> 4) == (ver & 15)))
            print(f"{m:>4}  {f['poses']:>5}  {rng(b['acc'], 3):>15}  {rng(f['acc']):>17}  "
                  f"{rng(b['mag'], 3):>15}  {rng(f['mag']):>17}  "
                  f"{'all' if flagged and vbits else 'NOT ALL'}  "
                  f"{b['link'].get('lost')}/{f['link'].get('lost')}", flush=True)
            if not (flagged and vbits):
                failures.append(f"mote {m}: samples after the reset not all flagged corrected "
                                f"with version {ver}")
            if len(f["acc"]) and abs(f["acc"] - 1).max() > 0.01:
                failures.append(f"mote {m}: corrected |a| {rng(f['acc'])} g, not within 0.01 g of 1")
            if len(f["mag"]) and (f["mag"].max() - f["mag"].min()) > 0.01 * f["mag"].mean():
                failures.append(f"mote {m}: corrected field magnitude {rng(f['mag'])} not "
                                "constant within 1 %")
            if f["poses"] < a.poses_after:
                failures.append(f"mote {m}: {f['poses']} poses after the reset")
    except RuntimeError as e:
        failures.append(str(e))
    finally:
        rep = harness.stop() if harness else None
    if rep:
        say("the harness's report")
        print(f"  emulated {rep['seconds']:.1f} s", flush=True)
        for n in rep["nodes"]:
            if n["role"] != "mote":
                print(f"  BaseStation id {n['id']}: CPU load {100 * n['cpu_load']:.1f} %")
                continue
            print(f"  mote id {n['id']} ({n['mhz']:.2f} MHz): {n['reads_per_s']:.3f} reads/s, "
                  f"periods without a read {n['missing_periods']} in {n['gaps']} gaps "
                  f"(the resets' reboots included), resets {n['resets']}, CPU load "
                  f"{100 * n['cpu_load']:.1f} %", flush=True)
    print(f"\nrelease check done in {time.monotonic() - t_all:.0f} s wall; output in {out}",
          flush=True)
    if failures:
        print("FAILED:\n  " + "\n  ".join(failures), flush=True)
        if not a.out:
            tmp.cleanup()
        return 1
    print("PASSED", flush=True)
    if not a.out:
        tmp.cleanup()
    return 0


if __name__ == "__main__":
    sys.exit(main())
