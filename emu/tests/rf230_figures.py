"""Build the harness (ninedof-emu) and the radio's AVR test programs, run
them, print the figures of docs/emulation-radio.md: frames sent / received /
lost / collided at loss 0 and 10 %, air time, PLL lock time and CCA busy
fraction.

    python emu/tests/rf230_figures.py [--seeds 5] [--frames 100]

Needs gcc, avr-gcc, libsimavr-dev and libelf-dev (make sysdeps).  The same
build and run helpers serve tests/test_emu_radio.py.  The programs run as
nodes without a sensor board (board=none), each UART0 to its own file.
"""
from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

EMU = Path(__file__).resolve().parents[1]
SIMAVR_INC = Path("/usr/include/simavr")
BYTE_US = 32


def build_harness(d: Path) -> Path:
    """ninedof-emu (make -C emu) built into d."""
    res = subprocess.run(["make", "-s", "-C", str(EMU), f"BUILD={d / 'emu-build'}"],
                         capture_output=True, text=True)
    if res.returncode != 0:
        raise RuntimeError(res.stdout + res.stderr)
    return d / "emu-build" / "ninedof-emu"


def build_avr(d: Path, name: str, source: str = "rf230_node.c", **defines) -> Path:
    out = d / f"{name}.elf"
    if not out.exists():
        cmd = ["avr-gcc", "-mmcu=atmega1281", "-DF_CPU=8000000UL", "-Os", "-std=gnu99",
               "-Wall", "-Werror"] + [f"-D{k}={v}" for k, v in defines.items()] + [
               str(EMU / "tests" / source), "-o", str(out)]
        res = subprocess.run(cmd, capture_output=True, text=True)
        if res.returncode != 0:
            raise RuntimeError(res.stderr)
    return out


def run(exe: Path, nodes, *, loss=0.0, seed=1, ms=300.0, extra=()):
    """Run nodes [(elf, id)] for ms emulated ms; return (console text per
    node, the harness's text report: one rf230 line per node, the channel's)."""
    args = [str(exe), "--loss", str(loss), "--seed", str(seed), "--seconds", str(ms / 1000),
            "--report", "text", *extra]
    with tempfile.TemporaryDirectory(prefix="rf230-run-") as td:
        cons = []
        for i, (elf, nid) in enumerate(nodes):
            c = Path(td) / f"console-{i}.txt"
            cons.append(c)
            args += ["--mote", f"{elf},id={nid},board=none,console={c}"]
        res = subprocess.run(args, capture_output=True, text=True, timeout=300)
        if res.returncode != 0:
            raise RuntimeError(res.stderr)
        return [c.read_text() for c in cons], res.stdout


def fields(line: str) -> dict:
    return dict(kv.split("=", 1) for kv in line.split()[1:])


def lines(text: str, tag: str) -> list[dict]:
    return [fields(ln) for ln in text.splitlines() if ln.split()[:1] == [tag]]


def stat(stats: str, prefix: str) -> dict:
    ln = next(ln for ln in stats.splitlines() if ln.startswith(prefix))
    return {k: float(v) if "." in v else int(v, 0)
            for k, v in (kv.split("=", 1) for kv in ln.split(":", 1)[1].split())}


def measure(seeds: int = 5, frames: int = 100, out=print) -> dict:
    """Run everything, print the figures with `out`, return them."""
    fig = {}
    with tempfile.TemporaryDirectory(prefix="rf230-fig-") as td:
        d = Path(td)
        exe = build_harness(d)
        n = frames
        period = 6000
        ms = 10 + n * period / 1000 + 20
        tx = build_avr(d, "tx", ROLE=1, NFRAMES=n, PERIOD_US=period)
        rx = build_avr(d, "rx", ROLE=2, RUN_MS=int(ms))
        out(f"A -> B, {n} frames of 20 bytes (PSDU) every {period} us, seeds 1..{seeds}")
        out("| loss | sent | received, FCS good | lost (loss rate) | lost fraction |")
        out("| ---: | ---: | ---: | ---: | ---: |")
        for loss in (0.0, 0.1):
            sent = got = lost = 0
            for s in range(1, seeds + 1):
                (_, crx), stats = run(exe, [(tx, 1), (rx, 2)], loss=loss, seed=s, ms=ms + 20)
                sent += stat(stats, "rf230 node 0:")["tx"]
                got += int(lines(crx, "rx_summary")[0]["ok"])
                lost += stat(stats, "rf230 node 1:")["lost"]
            fig[f"loss {loss:g}"] = dict(sent=sent, received=got, lost=lost)
            out(f"| {loss:.2f} | {sent} | {got} | {lost} | {lost / sent:.4f} |")

        a1 = build_avr(d, "txp_a", ROLE=1, TX_IDLE_PLL=1, NFRAMES=20, PERIOD_US=8000)
        b1 = build_avr(d, "txp_b", ROLE=1, TX_IDLE_PLL=1, NFRAMES=20, PERIOD_US=8000, START_US=3300)
        rxc = build_avr(d, "rx_c", ROLE=2, RUN_MS=200)
        (_, _, crx), stats = run(exe, [(a1, 1), (b1, 3), (rxc, 2)], ms=260)
        ch = stat(stats, "channel:")
        s = lines(crx, "rx_summary")[0]
        fig["collisions"] = dict(frames=ch["frames"], collided=ch["collided"],
                                 good=int(s["ok"]), bad=int(s["bad"]))
        out(f"collisions: two senders 300 us apart, 20 frames each: {ch['frames']} frames, "
            f"{ch['collided']} collided; receiver: {s['ok']} good FCS, {s['bad']} bad FCS")

        out("| PSDU bytes | air time expected (us) | measured by the sender, timer 1 (us) |")
        out("| ---: | ---: | ---: |")
        fig["air"] = {}
        for length in (5, 20, 127):
            t = build_avr(d, f"tx_{length}", ROLE=1, NFRAMES=10, LEN=length, PERIOD_US=10000)
            (ct,), _ = run(exe, [(t, 1)], ms=130)
            air = [int(x["air_us"]) for x in lines(ct, "tx")]
            fig["air"][length] = ((6 + length) * BYTE_US, min(air), max(air))
            out(f"| {length} | {(6 + length) * BYTE_US} | {min(air)}..{max(air)} |")
        (ct,), _ = run(exe, [(build_avr(d, "tx0", ROLE=1, NFRAMES=0), 1)], ms=20)
        r = lines(ct, "rx_on")[0]
        fig["pll_lock_us"] = int(r["lock_us"])
        out(f"TRX_OFF -> RX_ON: PLL_LOCK interrupt after {r['lock_us']} us (model 180 us + "
            f"SPI + quantum); ICR1 to ISR {r['icr_lag']} us")
        tcc = build_avr(d, "tx_cca", ROLE=1, NFRAMES=25, PERIOD_US=8000)
        cca = build_avr(d, "cca", ROLE=3, RUN_MS=190)
        (_, cc), _ = run(exe, [(tcc, 1), (cca, 3)], loss=1.0, ms=260)
        c = lines(cc, "cca")[0]
        busy, idle = int(c["busy"]), int(c["idle"])
        fig["cca_busy_fraction"] = busy / (busy + idle)
        out(f"CCA during 832 us frames every 8 ms: {busy} busy of {busy + idle} "
            f"({100 * busy / (busy + idle):.1f}%; expected about (832 + 128) / 8000 = 12%)")
    return fig


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--frames", type=int, default=100)
    a = ap.parse_args(argv)
    if a.seeds < 1 or a.frames < 1:
        print("rf230_figures: --seeds and --frames must be >= 1", file=sys.stderr)
        return 2
    measure(a.seeds, a.frames)
    return 0


if __name__ == "__main__":
    sys.exit(main())
