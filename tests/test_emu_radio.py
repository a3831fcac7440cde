"""The emulator's radio and serial models (emu/rf230.c, emu/channel.c,
emu/uart.c) against small AVR programs (emu/tests/rf230_node.c) built with
avr-gcc and run on Debian's libsimavr in the harness, ninedof-emu, as nodes
without a sensor board.  What is planted (frames, sequence numbers, loss
rate, timing) is the truth; the programs report what the chip did.
"""
from __future__ import annotations

import os
import re
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

import emusim

REPO = Path(__file__).resolve().parent.parent
EMU = REPO / "emu"
sys.path.insert(0, str(EMU / "tests"))
import rf230_figures as F  # noqa: E402  (the build/run helpers, one definition)

BYTE_US = F.BYTE_US
fields, lines = F.fields, F.lines


@pytest.fixture(scope="module")
def build(tmp_path_factory):
    """Build the harness and return a function building AVR programs."""
    emusim.skip_or_fail(pytest)
    d = tmp_path_factory.mktemp("emu-radio")

    def elf(name: str, **defines) -> Path:
        return F.build_avr(d, name, **defines)

    elf.exe = emusim.build_harness(d / "build")
    elf.dir = d
    return elf


def run(build, nodes, *, loss=0.0, seed=1, ms=300.0, extra=()):
    """Run nodes [(elf, id)]; return (console text per node, stats text)."""
    return F.run(build.exe, nodes, loss=loss, seed=seed, ms=ms, extra=extra)


def stat(stats: str, node: int) -> dict:
    return F.stat(stats, f"rf230 node {node}:")


def test_bring_up_states_and_pll_lock_irq(build):
    """Reset, sleep/wake, TRX_OFF -> RX_ON with the PLL_LOCK interrupt through
    timer 1's input capture (ICR1 holds the time of the edge)."""
    (con,), _ = run(build, [(build("tx1", ROLE=1, NFRAMES=0), 1)], ms=20)
    init = lines(con, "init")[0]
    assert init == {"part": "02", "man": "1f", "status": "8", "sleep": "0", "awake": "8"}
    rx_on = lines(con, "rx_on")[0]
    assert rx_on["during"] == "1f"                   # STATE_TRANSITION_IN_PROGRESS
    assert rx_on["irq"] == "1" and rx_on["irq_status"] == "01"   # PLL_LOCK
    assert 180 <= int(rx_on["lock_us"]) <= 200       # 180 us + one quantum + SPI
    assert int(rx_on["icr_lag"]) < 20                # ICR1 = the edge, not the ISR
    assert rx_on["status"] == "6"                    # RX_ON


def test_pending_radio_irq_survives_clearing_another_timer1_flag(build):
    (con,), _ = run(build, [(build("tifr", ROLE=4), 1)], ms=20)
    assert lines(con, "tifr")[0] == {"pending": "1", "kept": "1", "isr": "1", "cleared": "1"}


@pytest.mark.parametrize("length", [5, 20, 127])
def test_frames_from_a_to_b(build, length):
    """Every frame arrives once, in order, with a good FCS (computed by the
    chip: TX_AUTO_CRC_ON), after exactly its air time; the sender goes
    PLL_ON -> BUSY_TX -> (RX_ON queued) -> RX_ON with TRX_END."""
    n = 12
    tx = build(f"tx_{length}", ROLE=1, NFRAMES=n, LEN=length, PERIOD_US=10000)
    rx = build("rx_200", ROLE=2, RUN_MS=200)
    (ctx, crx), stats = run(build, [(tx, 1), (rx, 2)], ms=260)
    txs = lines(ctx, "tx")
    assert len(txs) == n
    air = (6 + length) * BYTE_US
    for t in txs:
        assert (t["pll"], t["busy"], t["queued"], t["irq"], t["irq_status"], t["after"]) == \
            ("09", "02", "02", "1", "08", "06"), t
        assert air - 5 <= int(t["air_us"]) <= air + 10, t
    rxs = lines(crx, "rx")
    assert [int(r["seq"]) for r in rxs] == list(range(n))
    for r in rxs:
        assert (r["from"], r["len"], r["crc_ok"], r["lqi"]) == ("1", str(length), "1", "ff"), r
        # RX_START (after SHR + PHR) to TRX_END: the PSDU's air time, or 0
        # when both were pending at one edge (the program was still printing)
        assert int(r["start_to_end_us"]) in (0, *range(length * BYTE_US - 5, length * BYTE_US + 10)), r
    assert lines(crx, "rx_summary")[0] == {"ok": str(n), "bad": "0"}
    starts = lines(crx, "rx_start")         # RX_START alone: BUSY_RX, energy on the air
    assert starts and all(x == {"status": "01", "rssi": "11"} for x in starts)
    st = stat(stats, 0)
    assert st["tx"] == n and st["underrun"] == 0
    assert stat(stats, 1)["rx_ok"] == n


def test_overlapping_frames_collide(build):
    """Two senders 300 us apart (both deaf in PLL_ON): every frame overlaps
    the other's, the receiver gets each pair's first frame with a bad FCS."""
    n = 10
    a = build("txp_a", ROLE=1, TX_IDLE_PLL=1, NFRAMES=n, PERIOD_US=8000)
    b = build("txp_b", ROLE=1, TX_IDLE_PLL=1, NFRAMES=n, PERIOD_US=8000, START_US=3300)
    rx = build("rx_200", ROLE=2, RUN_MS=200)
    (_, _, crx), stats = run(build, [(a, 1), (b, 3), (rx, 2)], ms=260)
    assert lines(crx, "rx_summary")[0] == {"ok": "0", "bad": str(n)}
    assert all(r["crc_ok"] == "0" for r in lines(crx, "rx"))
    assert "collided=%d" % (2 * n) in stats


def test_clear_channel_assessment(build):
    """CCA reports busy while a frame is on the air: with frames of 832 us
    every 8 ms and a 128 us measurement the busy fraction is about 12%;
    PHY_RSSI shows energy too.  (loss 1: the CCA node never syncs, so it
    stays in RX_ON and keeps measuring.)"""
    tx = build("tx_cca", ROLE=1, NFRAMES=25, PERIOD_US=8000)
    cca = build("cca", ROLE=3, RUN_MS=190)
    (_, ccon), stats = run(build, [(tx, 1), (cca, 3)], loss=1.0, ms=260)
    c = lines(ccon, "cca")[0]
    busy, idle = int(c["busy"]), int(c["idle"])
    frac = busy / (busy + idle)
    assert 0.09 < frac < 0.16, c
    assert int(c["rssi_busy"]) > 0
    assert "cca_done_early" not in ccon
    assert stat(stats, 1)["lost"] == 25


def test_loss_rate_over_seeds_and_determinism(build):
    """--loss 0.1 drops about 10% of frames per receiver; a seed gives the
    same run twice, another seed another one."""
    n = 60
    tx = build("tx_loss", ROLE=1, NFRAMES=n, PERIOD_US=6000)
    rx = build("rx_loss", ROLE=2, RUN_MS=400)
    got = {}
    with ThreadPoolExecutor(2) as ex:
        futs = {s: ex.submit(run, build, [(tx, 1), (rx, 2)], loss=0.1, seed=s, ms=420)
                for s in range(1, 9)}
        got = {s: f.result() for s, f in futs.items()}
    lost_total = 0
    for s, ((_, crx), stats) in got.items():
        seqs = [int(r["seq"]) for r in lines(crx, "rx")]
        st = stat(stats, 1)
        assert st["rx_ok"] == len(seqs) and st["rx_ok"] + st["lost"] == n, f"seed {s}"
        assert seqs == sorted(set(seqs)), f"seed {s}"
        lost_total += st["lost"]
    rate = lost_total / (n * len(got))
    assert 0.05 < rate < 0.16, f"loss rate {rate:.3f} over seeds 1..8"
    again = run(build, [(tx, 1), (rx, 2)], loss=0.1, seed=1, ms=420)
    assert again[0] == got[1][0]
    assert got[1][0] != got[2][0] or got[1][0] != got[3][0]


def test_bad_arguments_one_line_exit_2(build):
    res = subprocess.run([str(build.exe), "--loss", "2", "--mote", "x.elf"],
                         capture_output=True, text=True)
    assert res.returncode == 2 and len(res.stderr.strip().splitlines()) == 1
    res = subprocess.run([str(build.exe), "--mote", str(build.dir / "nope.elf")],
                         capture_output=True, text=True)
    assert res.returncode == 2 and len(res.stderr.strip().splitlines()) == 1
    res = subprocess.run([str(build.exe), "--mote", f"{build('tx1', ROLE=1, NFRAMES=0)},"
                          "board=none,serial=bogus"], capture_output=True, text=True)
    assert res.returncode == 2 and len(res.stderr.strip().splitlines()) == 1, res.stderr


# ------------------------------------------------------------------ UART0
def uart_elf(build, name: str, **defines) -> Path:
    return F.build_avr(build.dir, name, "rf230_uart.c", **defines)


def start(build, elf, serial: str, ms: float, *extra: str):
    """The harness in real time with one node's UART0 on `serial` (it ends
    when the program has stopped, or after ms); returns (process, the address
    it printed).  extra: more harness arguments (e.g. an unread fault)."""
    p = subprocess.Popen([str(build.exe), "--realtime", "--seconds", str(ms / 1000),
                          "--report", "text", "--mote", f"{elf},board=none,serial={serial}",
                          *extra], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    url = p.stdout.readline().strip()
    assert url, p.communicate()[1]
    return p, url


def uart_stat(stats: str) -> dict:
    ln = next(ln for ln in stats.splitlines() if ln.startswith("uart node 0:"))
    return {k: v for k, v in (kv.split("=", 1) for kv in ln.split(":", 1)[1].split())}


def report(p) -> str:
    """The harness's text report (stdout) once it has ended."""
    out, err = p.communicate(timeout=30)
    assert p.returncode == 0, err
    return out


def test_uart_tcp_echo_every_byte(build):
    """2048 bytes (all values, so HDLC's 0x7E/0x7D too) into the MCU over
    TCP and back: flow control into simavr's 64-byte FIFO loses none."""
    import socket
    p, url = start(build, uart_elf(build, "echo"), "tcp:0", 1000)
    try:
        assert re.fullmatch(r"socket://127\.0\.0\.1:\d+", url)
        host, port = url[len("socket://"):].split(":")
        with socket.create_connection((host, int(port)), timeout=5) as s:
            data = bytes(range(256)) * 8
            s.sendall(data)
            got = b""
            while not got.endswith(data):
                chunk = s.recv(65536)
                if not chunk:
                    break
                got += chunk
        # "ready\n" too if the client was there before the MCU sent it
        assert got in (data, b"ready\n" + data)
    finally:
        stats = report(p)
    st = uart_stat(stats)
    assert st["in"] == "2048"
    assert int(st["out"]) in (2048, 2054)


def test_uart_pty_echo(build):
    import termios
    import tty
    p, path = start(build, uart_elf(build, "echo"), "pty", 1500)
    try:
        assert path.startswith("/dev/pts/")
        fd = os.open(path, os.O_RDWR | os.O_NOCTTY)
        tty.setraw(fd)
        termios.tcflush(fd, termios.TCIFLUSH)
        os.write(fd, b"\x7e\x45\x00hello\x7d\x5e\x0a\x0d\x7e")
        got = b""
        import select
        while not got.endswith(b"\x0d\x7e") and select.select([fd], [], [], 3)[0]:
            got += os.read(fd, 100)
        os.close(fd)
        assert got.endswith(b"\x7e\x45\x00hello\x7d\x5e\x0a\x0d\x7e")
    finally:
        p.kill()
        p.communicate()


def test_uart_unread_window_drops_what_the_host_misses(build):
    """Host side "not reading" from 400 to 450 ms: exactly the bytes the
    MCU sent then are missing (one contiguous gap), the rest arrive in order;
    sent = received + dropped."""
    import socket
    n = 600
    elf = uart_elf(build, "stream", STREAM=n, STREAM_DELAY_MS=300)
    p, url = start(build, elf, "tcp:0", 3000, "--fault", "unread:0.4:0.05")
    host, port = url[len("socket://"):].split(":")
    got = b""
    with socket.create_connection((host, int(port)), timeout=5) as s:
        while True:
            chunk = s.recv(65536)
            if not chunk:
                break
            got += chunk
    stats = report(p)
    st = uart_stat(stats)
    sent = 6 + 7 * n
    assert len(got) + int(st["dropped_unread"]) + int(st["dropped_noclient"]) == sent
    nums = [int(m) for m in re.findall(rb"L(\d{5})\n", got)]
    assert nums == sorted(nums)
    gaps = [(a, b) for a, b in zip(nums, nums[1:]) if b != a + 1]
    assert len(gaps) == 1, gaps
    missing = gaps[0][1] - gaps[0][0] - 1
    dropped = int(st["dropped_unread"])
    assert abs(missing * 7 - dropped) <= 12      # partial lines at both edges
    # 50 ms at 250000 baud, 10 bits per byte: at most 1250 bytes; the program
    # spends ~1000 cycles formatting each 7-byte line between characters
    assert 800 <= dropped <= 1250
    assert nums[-1] == n - 1
