"""Cycles of the mote's per-sample work on the ATmega1281 (avr-gcc -Os, simavr).

Builds tests/c/avr_bench.c with the firmware's plain C (tinyos/*.c), runs it
in simavr with timer 1 at clk/1 and prints each figure next to its goal.
Also builds the portable C kernel (-DNINEDOF_PORTABLE_KERNEL: int32 products
through avr-gcc's __mulhisi3) for comparison.  Timing is reported, never pass/fail; exits non-zero only if
the benchmark did not run through (no END, or the TWI operation it times
did not end exactly once).

The I2C time per sample of the nesC build (both masters, three RC clocks)
comes from the emulator harness (emu/, `make emulate`) when TINYOS_ROOT_DIR
names a TinyOS tree and nesC >= 1.4.0 is on PATH; otherwise it is not
measured here.
"""
from __future__ import annotations

import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
import avrsim  # noqa: E402
from results import record  # noqa: E402

SOURCES = [avrsim.CSRC / "avr_bench.c"] + [
    avrsim.TINYOS / f for f in ("ninedof_board.c", *avrsim.CAL_C, "ninedof_sampling.c",
                                "ninedof_clock.c")]
MHZ = avrsim.F_CPU / 1e6
BATCH = 5


def measure(defines=()) -> dict:
    with tempfile.TemporaryDirectory() as d:
        elf = avrsim.build(SOURCES, Path(d) / "bench.elf", defines=defines)
        text = avrsim.run(elf)
    if "END" not in text:
        raise SystemExit(f"benchmark did not finish: {text[-300:]}")
    out = {}
    for tok in text[:text.index("END")].split(";"):
        if tok.strip():
            name, val = tok.split()
            out[name] = int(val)
    if out.get("twi_done") != 1:      # the timed read ends once, with its call
        raise SystemExit(f"benchmark: TWI operation ended {out.get('twi_done')} times, not 1")
    return out


GOAL = ("all three sensors read, per sample", "<= 1.2 ms (#5)")
TEMP_GOAL = ("I2C time added by the ITG-3200 temperature (8-byte burst from 0x1B)",
             "measured (#16)")
MASTERS = ((False, "stock Atm128I2CMasterC"), (True, "lean NineDofTwiMasterC (NINEDOF_LEAN_I2C=1)"))
CLOCKS = (7.84, 8.0, 8.16)


def emulated_i2c(tmp: Path) -> None:
    """read() -> readDone of the real images, both masters, three RC clocks,
    from the emulator harness (emu/emulate.py): mean, 99th percentile and
    maximum per clock, from the entry of the board's read to its readDone
    signal (the two labels the board marks, NINEDOF_SPAN_MARK); the goal is
    judged on the maximum of the worst clock.  Only with a TinyOS tree
    (TINYOS_ROOT_DIR) and nesC >= 1.4.0."""
    sys.path.insert(0, str(avrsim.REPO / "emu"))
    import emulate  # noqa: E402
    try:
        emulate.toolchain()
    except emulate.Unavailable as e:
        print(f"I2C per sample of the nesC build: not measured here ({e}; "
              "`make emulate` / docs/emulation.md)")
        record(*GOAL, None, note=f"needs the nesC build in the emulator harness ({e}); "
               "run make bench with TINYOS_ROOT_DIR and nesC >= 1.4.0 (docs/emulation.md)")
        record(*TEMP_GOAL, None, note=f"not measured: needs the nesC build in the emulator "
               f"harness ({e}); make bench with TINYOS_ROOT_DIR (docs/emulation.md)")
        return
    print("read() -> readDone of the nesC build (entry of the board's read to its readDone "
          "signal), measured in the emulator harness (ninedof-emu: 1 mote + the BaseStation, "
          "12 s emulated, counted from 4 s; goal <= 1200 us for every sample)")
    got = {}
    base = emulate.build_image("basestation", tmp / "basestation.elf")
    for lean, name in MASTERS:
        elf = emulate.build_image("tinyos", tmp / f"mote-{int(lean)}.elf", lean=lean)
        for mhz in CLOCKS:
            n = emulate.measure(tmp, motes=1, seconds=12, settle=4, mhz=(mhz,), lean=lean,
                                base=base, mote=elf)["nodes"][0]
            if not n["samples"]:
                print(f"  {name} at {mhz:.2f} MHz: no reads")
                continue
            sp = n.get("span")
            if sp and sp["n"]:
                got[lean, mhz] = sp
                print(f"  {name} at {mhz:.2f} MHz: read() -> readDone mean {sp['us_mean']:.1f} "
                      f"us, p99 {sp['us_p99']:.1f}, max {sp['us_max']:.1f} (min "
                      f"{sp['us_min']:.1f}; {sp['n']} reads)")
            print(f"  {name} at {mhz:.2f} MHz: first START -> last STOP {n['i2c_us_mean']:.1f} us "
                  f"(min {n['i2c_us_min']:.1f}, max {n['i2c_us_max']:.1f}), of which on the wire "
                  f"{n['wire_us_mean']:.1f} us and SCL held for the CPU {n['held_us_mean']:.1f} us; "
                  f"{n['reads_per_s']:.3f} reads/s, {n['missing_periods']} periods without a read, "
                  f"CPU load {100 * n['cpu_load']:.1f} %, ROM {n['rom']} B / RAM {n['ram']} B")
    temperature_burst(tmp, emulate, base)
    for lean, name in MASTERS:
        spans = {m: got[lean, m] for m in CLOCKS if (lean, m) in got}
        label = GOAL[0] if not lean else "the same with the lean TWI master (NINEDOF_LEAN_I2C=1)"
        if not spans:
            record(label, GOAL[1], None, note="the emulated mote did not sample, or its image "
                   "has no span labels")
            continue
        worst = max(spans, key=lambda m: spans[m]["us_max"])
        per = "; ".join(f"{m:.2f} MHz {sp['us_mean']:.0f} / {sp['us_p99']:.0f} / "
                        f"{sp['us_max']:.0f}" for m, sp in spans.items())
        top = spans[worst]["us_max"] / 1000
        record(label, GOAL[1], top, "ms", top <= 1.2,
               note=f"the longest read() -> readDone, worst clock {worst:.2f} MHz; "
                    f"{name.split(' (')[0]}; mean / p99 / max us per clock: {per} (entry of the "
                    "board's read to its readDone signal; emulated, ninedof-emu, 1 mote + "
                    "BaseStation, 12 s)")


def temperature_burst(tmp: Path, emulate, base: Path) -> None:
    """The I2C time per sample before (ITG-3200 rates alone, 6 bytes from
    0x1D: the comparison build NINEDOF_ITG_RATES_ONLY=1) and after (8 bytes
    from 0x1B: temperature and rates), both masters, 8.00 MHz, and the
    temperature the emulated chip gave (temp=31.5 C) as the image read it."""
    print("ITG-3200 temperature in the rates' burst: before (6 bytes from 0x1D, "
          "NINEDOF_ITG_RATES_ONLY=1) and after (8 bytes from 0x1B), 8.00 MHz, board at 31.5 C")
    rows = {}
    for lean, name in ((False, "stock"), (True, "lean")):
        for before in (True, False):
            elf = emulate.build_image("tinyos", tmp / f"mote-{int(lean)}-{int(before)}.elf",
                                      lean=lean,
                                      make_vars=["NINEDOF_ITG_RATES_ONLY=1"] if before else [])
            n = emulate.measure(tmp, motes=1, seconds=12, settle=4, mhz=(8.0,), lean=lean,
                                base=base, mote=elf, temp_c=(31.5,))["nodes"][0]
            sp = n.get("span")
            if not n["samples"] or not sp:
                print(f"  {name} {'before' if before else 'after'}: no reads")
                continue
            itg = n["chips"]["itg3200"]
            rows[lean, before] = (sp["us_mean"], n["i2c_us_mean"], n["wire_us_mean"])
            print(f"  {name}, {'before' if before else 'after '}: read() -> readDone "
                  f"{sp['us_mean']:.1f} us, first START -> last STOP {n['i2c_us_mean']:.1f} us "
                  f"(on the wire {n['wire_us_mean']:.1f} us, SCL held for the CPU "
                  f"{n['held_us_mean']:.1f} us); TEMP_OUT read {itg['temp_reads']} times, "
                  f"last {itg['last_temp']}; {n['reads_per_s']:.3f} reads/s, "
                  f"{n['missing_periods']} periods without a read; ROM {n['rom']} B, "
                  f"RAM {n['ram']} B")
    if (False, True) not in rows or (False, False) not in rows:
        record(*TEMP_GOAL, None, note="the emulated mote did not sample")
        return
    b, a = rows[False, True], rows[False, False]
    note = (f"read() -> readDone {b[0]:.0f} -> {a[0]:.0f} us (stock master, 8.00 MHz, "
            f"emulated); I2C {b[1]:.0f} -> {a[1]:.0f} us, on the wire {b[2]:.0f} -> {a[2]:.0f} us")
    if (True, True) in rows and (True, False) in rows:
        lb, la = rows[True, True], rows[True, False]
        note += f"; lean master {lb[0]:.0f} -> {la[0]:.0f} us"
    record(*TEMP_GOAL, (a[0] - b[0]) / 1000, "ms", None, note=note)


def main() -> int:
    missing = avrsim.missing_tools()
    if missing:
        print(f"bench_cycles: missing {missing} (make sysdeps); nothing measured")
        return 0
    asm = measure()
    c = measure(["NINEDOF_PORTABLE_KERNEL"])
    per_sample = (asm["board_record"] + asm["align_push"] + asm["batch_add"]
                  + asm["batch_pack5"] / BATCH + asm["clock_period"] + asm["clock_update"] / 125)
    rows = [
        ("correction, 9 axes, one record (ninedof_correct)", asm["correct_9axes"], "<= 1500"),
        ("  same, portable C kernel (__mulhisi3)", c["correct_9axes"], "reference"),
        ("correction per record in a batch of 5", asm["correct_block5"] / BATCH, "<= 1500"),
        ("  same, portable C kernel", c["correct_block5"] / BATCH, "reference"),
        ("correction, shift 13 set (rescaled to Q14)", asm["correct_9axes_q13"], "rare path"),
        ("correction with temperature terms, 9 axes, one record", asm["correct_9axes_temp"],
         "<= 1500"),
        ("  same, per record in a batch of 5", asm["correct_block5_temp"] / BATCH, "<= 1500"),
        ("  offsets only (no gain change): one record", asm["correct_9axes_temp_offsets"],
         "<= 1500"),
        ("  offsets only, per record in a batch of 5",
         asm["correct_block5_temp_offsets"] / BATCH, "<= 1500"),
        ("temperature terms at a new temperature (once a second)", asm["cal_set_temp"], ""),
        ("no sensor corrected (raw copy)", asm["correct_raw"], ""),
        ("chip bytes -> record (3 chips)", asm["board_record"], ""),
        ("one instant per record (align the magnetometer)", asm["align_push"], ""),
        ("batch: add one record", asm["batch_add"], ""),
        ("batch: correct + pack 5 records", asm["batch_pack5"], ""),
        ("sampling clock: one period", asm["clock_period"], ""),
        ("sampling clock: loop update (once a second)", asm["clock_update"], ""),
        ("per-sample total (record, align, add, 1/5 pack, clock)", per_sample, ""),
        ("upload: one fragment", asm["calrx_fragment"], ""),
        ("upload: commit (CRC + decode + validate)", asm["calrx_commit"], ""),
        ("CRC-16 of the 102-byte set", asm["crc16_set"], ""),
        ("EEPROM: build image", asm["eeprom_image"], ""),
        ("EEPROM: next byte", asm["eeprom_next_byte"], ""),
    ]
    print(f"AVR cycles at {MHZ:.0f} MHz (avr-gcc -Os, ATmega1281, simavr, timer 1 at clk/1)")
    print(f"{'item':50s} {'cycles':>8s} {'us':>8s}  goal")
    for name, cyc, goal in rows:
        print(f"{name:50s} {cyc:8.0f} {cyc / MHZ:8.1f}  {goal}")
    print()
    print("lean master's TWI handler alone, avr-gcc -Os in Debian's simavr (call + reti; "
          "the interrupt itself takes 8): "
          + ", ".join(f"{k[8:]} {asm[k]}" for k in ("twi_isr_start", "twi_isr_addr",
                                                   "twi_isr_byte", "twi_isr_last"))
          + " cycles")
    record("correction of 9 axes, one record", "<= 1500 cycles (#5)", asm["correct_9axes"],
           "cycles", asm["correct_9axes"] <= 1500, digits=4,
           note=f"{asm['correct_block5'] / BATCH:.0f} per record in a batch of {BATCH}; "
                "avr-gcc -Os in Debian's simavr")
    record("correction of 9 axes with temperature offsets (bias vs temperature), one record",
           "<= 1500 cycles (#5)", asm["correct_9axes_temp_offsets"], "cycles",
           asm["correct_9axes_temp_offsets"] <= 1500, digits=4,
           note=f"{asm['correct_block5_temp_offsets'] / BATCH:.0f} per record in a batch of "
                f"{BATCH}: the assembly kernel with c + O(T); new temperature "
                f"{asm['cal_set_temp']} cycles once a second")
    record("correction of 9 axes with temperature gain and offset terms, one record",
           "<= 1500 cycles (#5)", asm["correct_9axes_temp"], "cycles",
           asm["correct_9axes_temp"] <= 1500, digits=4,
           note=f"gain terms on all 9 axes: {asm['correct_block5_temp'] / BATCH:.0f} per record "
                f"in a batch of {BATCH}, the kernel's sums exact, the gain term (G in "
                f"Q30) from twelve 8x8 multiplies, the rounding in C "
                f"({100 * asm['correct_block5_temp'] / BATCH * 125 / avrsim.F_CPU:.1f} % of "
                "the CPU at 125 Hz)")
    period = avrsim.F_CPU / 125
    print(f"per-sample work is {100 * per_sample / period:.1f}% of the 8 ms period "
          f"({period:.0f} cycles); commit status {asm['commit_status']} (0 = accepted)")
    print()
    with tempfile.TemporaryDirectory() as d:
        emulated_i2c(Path(d))
    return 0


if __name__ == "__main__":
    sys.exit(main())
