"""Benchmark of the emulator's radio model (prints figures next to the
goals; exit 0): the figures of docs/emulation-radio.md from the AVR test
programs (emu/tests/rf230_figures.py).  Goals: no frame lost at loss 0;
the lost fraction at --loss 0.1 near 0.1; every overlapping frame
collided; air time (6 + PSDU) x 32 us; CCA busy about 12 %.
"""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "emu" / "tests"))

import rf230_figures  # noqa: E402

if __name__ == "__main__":
    print("emulated RF230 + channel (goals: loss 0 -> 0 lost; loss 0.1 -> about 0.1 lost; "
          "overlaps collide; air time (6 + n) x 32 us)")
    sys.exit(rf230_figures.main(sys.argv[1:]))
