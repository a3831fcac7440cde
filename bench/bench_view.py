"""The browser view's cost (issue 18): the page's update rate, and the
logger's CPU with the view open vs closed, with 6 motes at 125 Hz in real
time; the view must not make the logger lose samples.

Twice the same run -- ``motecal sim --serve --realtime --motes 6`` (static80,
same seed) read by ``motecal log --guided static80 --yes --duration D`` --
once without ``--view``, once with ``--view 127.0.0.1:0`` and a viewer reading
the event stream the page reads (Server-Sent Events; each event is a full
state document, what the page draws).  CPU = user + system seconds of the
logging process (``os.wait4``) over its wall time.  Lost = the link counters
the logger stored (a logger too slow to read would show as lost samples and
CRC errors: the paced simulator drops bytes nobody takes).

    .venv/bin/python bench/bench_view.py [--duration 20]
"""
from __future__ import annotations

import argparse
import os
import socket
import subprocess
import sys
import tempfile
import threading
import time

from motecal.sessions.store import open_store
from results import record

MOTES = 6


def viewer(port: int, out: dict, stop: threading.Event) -> None:
    """Read /events as a browser would: count state events, their bytes and gaps."""
    s = socket.create_connection(("127.0.0.1", port), timeout=5)
    s.sendall(b"GET /events HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
    buf, times, size = b"", [], 0
    while not stop.is_set():
        try:
            chunk = s.recv(1 << 16)
        except (socket.timeout, OSError):
            break
        if not chunk:
            break
        buf += chunk
        while b"\n\n" in buf:
            block, buf = buf.split(b"\n\n", 1)
            if block.startswith(b"event: state"):
                times.append(time.monotonic())
                size += len(block)
    s.close()
    out.update(times=times, bytes=size)


def one_run(tmp: str, duration: float, view: bool, seed: int) -> dict:
    sim = subprocess.Popen([sys.executable, "-m", "motecal", "sim", "--serve", "127.0.0.1:0",
                            "--motes", str(MOTES), "--session", "static80", "--seed", str(seed),
                            "--realtime", "--quiet"], stdout=subprocess.PIPE, text=True)
    try:
        url = sim.stdout.readline().strip()
        db = os.path.join(tmp, f"view-{view}.db")
        args = [sys.executable, "-m", "motecal", "log", "--port", url, "--db", db,
                "--session", "s", "--guided", "static80", "--yes", "--duration", str(duration)]
        if view:
            args += ["--view", "127.0.0.1:0"]
        t0 = time.monotonic()
        log = subprocess.Popen(args, stdout=subprocess.PIPE, stdin=subprocess.DEVNULL, text=True)
        seen, stop = {}, threading.Event()
        reader = None
        if view:
            first = log.stdout.readline()
            port = int(first.split()[1].rsplit(":", 1)[1].strip("/"))
            reader = threading.Thread(target=viewer, args=(port, seen, stop), daemon=True)
            reader.start()
        threading.Thread(target=log.stdout.read, daemon=True).start()
        _, status, ru = os.wait4(log.pid, 0)
        wall = time.monotonic() - t0
        log.returncode = os.waitstatus_to_exitcode(status)
        stop.set()
        if reader:
            reader.join(5)
    finally:
        sim.terminate()
        sim.wait()
    with open_store(db) as st:
        stats = st.link_stats("s")
    lost = sum(c["lost"] for c in stats["motes"].values())
    samples = sum(c["samples"] for c in stats["motes"].values())
    out = dict(cpu=(ru.ru_utime + ru.ru_stime) / wall, wall=wall, lost=lost, samples=samples,
               crc=stats["line"]["crc_errors"], rc=log.returncode, motes=len(stats["motes"]))
    if view:
        times = seen.get("times", [])
        span = times[-1] - times[0] if len(times) > 1 else 0
        out.update(events=len(times), rate=(len(times) - 1) / span if span else 0.0,
                   max_gap=max((b - a for a, b in zip(times, times[1:])), default=None),
                   kb_per_event=seen.get("bytes", 0) / max(1, len(times)) / 1024)
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=20.0)
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="bench-view-") as tmp:
        closed = one_run(tmp, a.duration, False, a.seed)
        opened = one_run(tmp, a.duration, True, a.seed)
    for name, r in (("view closed", closed), ("view open", opened)):
        print(f"{name}: {r['samples']} samples from {r['motes']} motes in {r['wall']:.1f} s, "
              f"lost {r['lost']}, CRC errors {r['crc']}, logger CPU {100 * r['cpu']:.1f}% "
              f"of a core, exit {r['rc']}")
    print(f"view: {opened['events']} state events, {opened['rate']:.1f}/s, longest gap "
          f"{opened['max_gap']:.2f} s, {opened['kb_per_event']:.1f} KiB each")
    record("view update rate (events/s at the page, 6 motes)", ">= 2/s (live)",
           opened["rate"], "/s", met=opened["rate"] >= 2.0,
           note=f"longest gap {opened['max_gap']:.2f} s")
    record("logger CPU, view closed (6 motes, 125 Hz)", "(reference)", 100 * closed["cpu"],
           "% of a core")
    record("logger CPU, view open (6 motes, 125 Hz)", "no lost samples (below)",
           100 * opened["cpu"], "% of a core")
    extra = opened["lost"] - closed["lost"] + opened["crc"]
    record("samples lost with the view open (6 motes, 125 Hz)", "0 more than closed",
           extra, "", met=extra <= 0 and opened["motes"] == MOTES,
           note=f"lost {opened['lost']} open, {closed['lost']} closed (radio), "
                f"CRC errors {opened['crc']}")


if __name__ == "__main__":
    main()
