"""Benchmark of the emulator's radio model (emu/rf230.c, emu/channel.c):
the figures of docs/emulation-radio.md from the AVR test programs
(emu/tests/rf230_figures.py), each recorded next to its goal.
"""
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "emu" / "tests"))

import rf230_figures  # noqa: E402
from results import record  # noqa: E402

SEEDS, FRAMES = 5, 100


def main() -> int:
    f = rf230_figures.measure(SEEDS, FRAMES)
    l0, l1 = f["loss 0"], f["loss 0.1"]
    record("emulated radio: frames lost at --loss 0", "0", l0["lost"] + l0["sent"] - l0["received"],
           "frames", l0["lost"] == 0 and l0["received"] == l0["sent"],
           note=f"{l0['sent']} frames A -> B, seeds 1..{SEEDS}")
    frac = l1["lost"] / l1["sent"]
    record("emulated radio: lost fraction at --loss 0.1", "0.1 +- 0.03", frac, "",
           abs(frac - 0.1) <= 0.03, note=f"{l1['lost']} of {l1['sent']} frames, seeds 1..{SEEDS}")
    c = f["collisions"]
    record("emulated radio: overlapping frames corrupted", "all", c["collided"], "frames",
           c["collided"] == c["frames"] and c["good"] == 0,
           note=f"of {c['frames']}; the receiver got {c['bad']} with a bad FCS")
    exp, lo, hi = f["air"][127]
    record("emulated radio: air time of a 127-byte PSDU", f"{exp} us", hi, "us",
           exp - 5 <= lo and hi <= exp + 8, note=f"{lo}..{hi} us over 10 frames, timer 1")
    record("emulated radio: CCA busy during 832 us frames every 8 ms", "about 12 %",
           100 * f["cca_busy_fraction"], "%", 9 <= 100 * f["cca_busy_fraction"] <= 16)
    return 0


if __name__ == "__main__":
    sys.exit(main())
