"""Cycles of the mote's per-sample work on the ATmega1281 (avr-gcc -Os, simavr).

Builds tests/c/avr_bench.c with the firmware's plain C (tinyos/*.c), runs it
in simavr with timer 1 at clk/1 and prints each figure next to its goal.
Also builds the portable C kernel (-DNINEDOF_PORTABLE_KERNEL: int32 products
through avr-gcc's __mulhisi3) for comparison.  Exits 0: timing is reported,
never pass/fail.
"""
from __future__ import annotations

import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
import avrsim  # noqa: E402

SOURCES = [avrsim.CSRC / "avr_bench.c"] + [
    avrsim.TINYOS / f for f in ("ninedof_board.c", "ninedof_cal.c", "ninedof_sampling.c",
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
    return out


# I2C time per sample: a model, since no simulator here runs the TWI with
# the three chips.  Event counts follow Adxl345LogicP/Itg3200LogicP/
# Hmc5883lLogicP; the interrupt figures were counted in the disassembly of
# the nesC build for iris (stock Atm128I2CMasterPacketP): 142 cycles from
# TWINT to the next TWCR write while SCL is held low, per byte or START.
SCL_HZ = 400_000
ISR_STALL_CYCLES = 142
CHIP_OVERHEAD_CYCLES = 450      # arbitration, bus power on/off, speed, callbacks
READS = {   # chip: (bytes incl. address bytes, START/repeated START conditions)
    "ADXL345 pointer + 6 bytes": (9, 2),
    "ITG-3200 pointer + 6 bytes": (9, 2),
    "HMC5883L 6 bytes (pointer auto-wraps)": (7, 1),
}
TRIGGER = ("HMC5883L trigger write (MODE = single)", (3, 1))


def i2c_model(n_bytes: int, n_starts: int) -> float:
    """Microseconds on the bus for one chip transaction."""
    bit = 1e6 / SCL_HZ
    cyc = 1e6 / avrsim.F_CPU
    return (n_bytes * (9 * bit + ISR_STALL_CYCLES * cyc)
            + n_starts * (bit + ISR_STALL_CYCLES * cyc)
            + CHIP_OVERHEAD_CYCLES * cyc)


def main() -> int:
    missing = avrsim.missing_tools()
    if missing:
        print(f"bench_cycles: missing {missing} (make sysdeps); nothing measured")
        return 0
    asm = measure()
    c = measure(["NINEDOF_PORTABLE_KERNEL"])
    per_sample = (asm["board_record"] + asm["batch_add"] + asm["batch_pack5"] / BATCH)
    rows = [
        ("correction, 9 axes, one record (ninedof_correct)", asm["correct_9axes"], "<= 1500"),
        ("  same, portable C kernel (__mulhisi3)", c["correct_9axes"], "reference"),
        ("correction per record in a batch of 5", asm["correct_block5"] / BATCH, "<= 1500"),
        ("  same, portable C kernel", c["correct_block5"] / BATCH, "reference"),
        ("correction, shift 13 set (rescaled to Q14)", asm["correct_9axes_q13"], "rare path"),
        ("no sensor corrected (raw copy)", asm["correct_raw"], ""),
        ("chip bytes -> record (3 chips)", asm["board_record"], ""),
        ("batch: add one record", asm["batch_add"], ""),
        ("batch: correct + pack 5 records", asm["batch_pack5"], ""),
        ("per-sample total (record + add + 1/5 pack)", per_sample, ""),
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
    print(f"I2C per sample at {SCL_HZ // 1000} kHz (model, not measured: see the comment in "
          "bench_cycles.py)")
    total = 0.0
    for name, (nb, ns) in READS.items():
        t = i2c_model(nb, ns)
        total += t
        print(f"  {name:48s} {t:7.0f} us")
    print(f"  {'three reads':48s} {total:7.0f} us   goal <= 1200 us")
    t = i2c_model(*TRIGGER[1])
    print(f"  {TRIGGER[0]:48s} {t:7.0f} us   (after the reads)")
    bits = sum(nb * 9 + ns for nb, ns in READS.values()) * 1e6 / SCL_HZ
    print(f"  of the three reads, SCL time alone: {bits:.0f} us")
    period = avrsim.F_CPU / 125
    print(f"per-sample work is {100 * per_sample / period:.1f}% of the 8 ms period "
          f"({period:.0f} cycles); commit status {asm['commit_status']} (0 = accepted)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
