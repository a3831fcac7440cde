"""Run the real iris images (sensor motes + BaseStation, built with nesC
outside the repo) in the emulator with the radio and UART models, read the
BaseStation's serial line from its pseudo-terminal with the project's own
decoder, and print what got through: per mote the sample messages and
records on the line against the samples the mote generated (its own status
counters), the BaseStation's counters, and the radio's frame counts.

    python emu/tests/rf230_images.py --emu emu/build/ninedof-emu \\
        --mote tinyos/build/iris/main.exe --base basestation/build/iris/main.exe \\
        [--motes 1] [--seconds 20] [--loss 0.0] [--seed 1] [--json]

Needs the full harness (ninedof-emu: main.c, TWI and chip models, so the
motes' sensors answer) and images built with `make iris` (docs/emulation-radio.md).
"""
from __future__ import annotations

import argparse
import json
import os
import re
import select
import subprocess
import sys
import termios
import tty
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "host"))
from motecal.line import protocol as P  # noqa: E402


def run(emu: str, mote: str, base: str, motes: int, seconds: float, loss: float,
        seed: int) -> dict:
    cmd = [emu]
    for i in range(motes):
        cmd += ["--mote", f"{mote},id={i + 1}"]
    cmd += ["--base", base, "--serial", "pty", "--loss", str(loss), "--seed", str(seed),
            "--seconds", str(seconds), "--report", "text"]
    err_path = Path(os.environ.get("TMPDIR", "/tmp")) / f"rf230-images-{os.getpid()}.err"
    with open(err_path, "w") as err:
        p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=err, text=True)
        path = p.stdout.readline().strip()
        if not path.startswith("/dev/"):
            p.wait()
            raise SystemExit(f"rf230_images: the emulator printed no pty ({err_path})")
        fd = os.open(path, os.O_RDONLY | os.O_NOCTTY)
        tty.setraw(fd)
        dec = P.FrameDecoder()
        frames = []
        while True:
            r, _, _ = select.select([fd], [], [], 0.2)
            chunk = b""
            if r:
                try:
                    chunk = os.read(fd, 65536)
                except OSError:            # EIO: the emulator closed the pty
                    chunk = b""
            if chunk:
                frames += dec.feed(chunk)
            elif p.poll() is not None:
                break
        os.close(fd)
        frames += dec.finish()
    stderr = p.stdout.read() + err_path.read_text()
    err_path.unlink()
    if p.returncode != 0:
        raise SystemExit(f"rf230_images: emulator exit {p.returncode}: {stderr.strip()[-400:]}")

    out = {"seconds": seconds, "loss": loss, "seed": seed, "motes": {},
           "decoder": {"frames": dec.stats.frames, "crc_errors": dec.stats.crc_errors,
                       "bad_frames": dec.stats.bad_frames}}
    recs: dict[int, set[int]] = {}
    msgs: dict[int, int] = {}
    status: dict[int, dict] = {}
    bs = None
    for fr in frames:
        am = fr.am()
        if am is None:
            continue
        m = P.decode_message(am)
        if am.am_type == P.AM_NINEDOF_SAMPLES_MSG and m is not None:
            msgs[am.src] = msgs.get(am.src, 0) + 1
            s = recs.setdefault(am.src, set())
            s.update((m.seq + k) & 0xFFFF for k in range(len(m.records)))
        elif am.am_type == P.AM_NINEDOF_MOTE_STATUS_MSG and m is not None:
            status[am.src] = dict(m)
        elif am.am_type == P.AM_NINEDOF_BS_STATUS_MSG and m is not None:
            bs = dict(m)
    for i in range(1, motes + 1):
        st = status.get(i)
        gen = st["seq"] if st else None
        got = {s for s in recs.get(i, set()) if gen is None or s < gen}
        out["motes"][i] = {"sample_msgs": msgs.get(i, 0), "records": len(got),
                           "generated": gen, "status": st,
                           "delivered": (len(got) / gen) if gen else None}
    out["basestation"] = bs
    radio = {}
    for ln in stderr.splitlines():
        m = re.match(r"rf230 node (\d+): (.*)", ln)
        if m:
            radio[int(m.group(1))] = {k: int(v, 0) for k, v in
                                      (kv.split("=") for kv in m.group(2).split())}
    out["radio"] = radio
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--emu", required=True)
    ap.add_argument("--mote", required=True)
    ap.add_argument("--base", required=True)
    ap.add_argument("--motes", type=int, default=1)
    ap.add_argument("--seconds", type=float, default=20.0)
    ap.add_argument("--loss", type=float, default=0.0)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args(argv)
    for f in (a.emu, a.mote, a.base):
        if not os.access(f, os.R_OK):
            print(f"rf230_images: cannot read {f}", file=sys.stderr)
            return 2
    if not 0 <= a.loss <= 1 or a.motes < 1:
        print("rf230_images: --loss must be in 0..1 and --motes >= 1", file=sys.stderr)
        return 2
    r = run(a.emu, a.mote, a.base, a.motes, a.seconds, a.loss, a.seed)
    if a.json:
        print(json.dumps(r, indent=1, sort_keys=True))
        return 0
    print(f"{a.motes} mote(s) + BaseStation, {a.seconds:g} emulated s, loss {a.loss:g}, seed {a.seed}")
    d = r["decoder"]
    print(f"serial line: {d['frames']} frames decoded, {d['crc_errors']} CRC errors, "
          f"{d['bad_frames']} bad frames")
    for i, m in r["motes"].items():
        st = m["status"] or {}
        deliv = f"{100 * m['delivered']:.2f}%" if m["delivered"] is not None else "n/a"
        print(f"mote {i}: {m['sample_msgs']} sample messages, {m['records']} of "
              f"{m['generated']} samples on the line ({deliv}); mote counters: "
              f"dropped {st.get('dropped')}, send_fail {st.get('send_fail')}, "
              f"i2c_errors {st.get('i2c_errors')}, late {st.get('late')}")
    print(f"basestation counters: {r['basestation']}")
    for n, s in sorted(r["radio"].items()):
        print(f"radio node {n}: frames sent {s['tx']}, received {s['rx_ok']}, "
              f"bad FCS {s['rx_crc_bad']}, lost (loss rate) {s['lost']}, "
              f"missed (not listening) {s['missed']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
