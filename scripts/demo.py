"""`make demo`: the main job end to end on the simulator, with the commands a
user runs, into one sqlite database.

  1. three simulated motes (IRIS + 9DOF board, radio, BaseStation, 250000 baud)
     on a TCP port; `motecal log` guides them through 80 static poses, then a
     rotation sweep (a second simulator run on the same boards);
  2. `motecal calibrate ... --upload`: accelerometer, gyroscope and
     magnetometer of every board in one run, gated, uploaded to each mote
     and verified, each upload done when its mote reports the set stored in
     its EEPROM (so the simulator can stop the moment the command exits);
  3. the motes reboot with the set in force; a second static session is logged:
     its samples arrive corrected, and the script prints the accelerometer and
     magnetometer magnitudes before and after;
  4. `motecal diagnose` names what the paper's model gets wrong on mote 1;
  5. `motecal report` writes the paper's tables and figures.
"""
from __future__ import annotations

import argparse
import shlex
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

MOTECAL = [sys.executable, "-m", "motecal"]


def say(text: str) -> None:
    print(f"\n\033[1m== {text}\033[0m" if sys.stdout.isatty() else f"\n== {text}", flush=True)


def run(*args: str) -> None:
    print("$ motecal " + " ".join(shlex.quote(a) for a in args), flush=True)
    res = subprocess.run(MOTECAL + list(args))
    if res.returncode != 0:
        sys.exit(f"demo: `motecal {args[0]}` failed with exit status {res.returncode}")


class Simulator:
    """`motecal sim --serve` in the background; the URL it prints."""

    def __init__(self, *args: str):
        cmd = ["sim", "--serve", "127.0.0.1:0", "--quiet"] + list(args)
        print("$ motecal " + " ".join(shlex.quote(a) for a in cmd) + " &", flush=True)
        self.proc = subprocess.Popen(MOTECAL + cmd, stdout=subprocess.PIPE, text=True)
        self.url = (self.proc.stdout.readline() or "").strip()
        if not self.url.startswith("socket://"):
            self.stop()
            sys.exit("demo: the simulator did not start")

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.stop()


def magnitudes(db: Path, session: str) -> dict:
    """Per mote: accel (g) and mag (gauss) magnitude of each static pose's mean,
    with the nominal datasheet scales (what the mote sends, raw or corrected),
    and whether every sample is flagged corrected."""
    from motecal.sessions.store import open_store
    with open_store(str(db)) as st:
        data = st.load_session(session)
    return {m: (v["acc"], v["mag"], bool(np.all(v["flags"] & 1)))
            for m, v in data.pose_magnitudes().items()}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="demo-out", help="directory for everything (demo-out)")
    ap.add_argument("--motes", type=int, default=3)
    args = ap.parse_args()
    out = Path(args.out)
    if out.exists():
        shutil.rmtree(out)
    out.mkdir(parents=True)
    db, truth, eeprom = out / "motecal.db", out / "truth.json", out / "eeprom.json"
    motes = str(args.motes)
    t_start = time.monotonic()

    say(f"1. {motes} simulated motes: 80 static poses, then a rotation sweep")
    with Simulator("--motes", motes, "--session", "static80", "--seed", "1",
                   "--truth", str(truth), "--eeprom", str(eeprom)) as sim:
        run("log", "--port", sim.url, "--db", str(db), "--session", "board",
            "--guided", "static80", "--yes")
    with Simulator("--motes", motes, "--session", "rotation", "--seed", "2",
                   "--model", str(truth), "--eeprom", str(eeprom)) as sim:
        run("log", "--port", sim.url, "--db", str(db), "--session", "board", "--append",
            "--guided", "rotation", "--yes")

    say("2. calibrate every board (GA + polish), gate, upload to the motes, verify, stored")
    with Simulator("--motes", motes, "--session", "idle", "--duration", "3600", "--seed", "3",
                   "--model", str(truth), "--eeprom", str(eeprom)) as sim:
        run("calibrate", "--db", str(db), "--session", "board", "--seed", "1",
            "--out", str(out / "cal-mote{mote}.json"), "--upload", "--port", sim.url)

    say("3. the motes reboot with the set from their EEPROM; log again: corrected samples")
    with Simulator("--motes", motes, "--session", "static80", "--seed", "4",
                   "--model", str(truth), "--eeprom", str(eeprom)) as sim:
        run("log", "--port", sim.url, "--db", str(db), "--session", "board-corrected",
            "--guided", "static80", "--yes")
    before, after = magnitudes(db, "board"), magnitudes(db, "board-corrected")
    print(f"{'mote':>4}  {'accel |g| raw':>18}  {'accel |g| on-mote':>18}  "
          f"{'mag gauss raw':>16}  {'mag gauss on-mote':>17}  flagged")
    for m in sorted(after):
        a0, m0, _ = before[m]
        a1, m1, flagged = after[m]
        print(f"{m:>4}  {a0.min():.3f}..{a0.max():.3f} g  {a1.min():.4f}..{a1.max():.4f} g"
              f"  {m0.min():.3f}..{m0.max():.3f}  {m1.min():.4f}..{m1.max():.4f}  "
              f"{'all' if flagged else 'NOT ALL'}")
        if not flagged or abs(a1 - 1).max() > 0.01:
            sys.exit(f"demo: mote {m} does not send corrected samples as computed")

    say("4. what the paper's model gets wrong (mote 1)")
    run("diagnose", "--db", str(db), "--session", "board", "--mote", "1",
        "--json", str(out / "diagnosis.json"), "--model-out", str(out / "extended-model.json"))

    say("5. the paper's tables and figures")
    run("report", "--db", str(db), "--session", "board", "--out", str(out / "report"))
    print(f"\ndemo done in {time.monotonic() - t_start:.0f} s; open {out / 'report' / 'index.html'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
