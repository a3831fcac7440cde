"""Build plain C for the ATmega1281 with avr-gcc and run it in simavr.

Used by tests/test_avr.py, tests/test_twi.py and bench/bench_cycles.py.
Programs print on UART0 (simavr echoes it on stderr, in colour, wrapped) and
end with ``cli(); sleep_cpu();``, which makes simavr exit.
"""
from __future__ import annotations

import re
import shutil
import subprocess
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
TINYOS = REPO / "tinyos"
BASESTATION = REPO / "basestation"
CSRC = REPO / "tests" / "c"
# the calibration C code: the set, the correction, the upload receiver
CAL_C = ("ninedof_calset.c", "ninedof_correct.c", "ninedof_calrx.c")
MCU = "atmega1281"
F_CPU = 8_000_000
AVR_CFLAGS = ["-mmcu=" + MCU, "-std=gnu99", "-Wall", "-Wextra", "-Werror",
              f"-DF_CPU={F_CPU}UL"]

_ANSI = re.compile(r"\x1b\[[0-9;]*m")


def missing_tools() -> list[str]:
    return [t for t in ("avr-gcc", "simavr") if shutil.which(t) is None]


def build(sources, elf: Path, *, include=(), defines=(), opt="-Os") -> Path:
    cmd = (["avr-gcc"] + AVR_CFLAGS + [opt]
           + [f"-I{p}" for p in (*include, TINYOS)]
           + [f"-D{d}" for d in defines]
           + [str(s) for s in sources] + ["-o", str(elf)])
    res = subprocess.run(cmd, capture_output=True, text=True)
    if res.returncode != 0:
        raise RuntimeError(f"avr-gcc failed: {' '.join(cmd)}\n{res.stderr}")
    return elf


def run(elf: Path, timeout: float = 120) -> str:
    """Everything the program wrote to UART0, newlines and colours removed."""
    res = subprocess.run(["simavr", "-m", MCU, "-f", str(F_CPU), str(elf)],
                         capture_output=True, text=True, timeout=timeout)
    text = _ANSI.sub("", res.stdout + res.stderr)
    lines = [ln for ln in text.splitlines() if not ln.startswith("Loaded ")]
    return "".join(lines)


def size(elf: Path) -> dict:
    """text/data/bss of an ELF (avr-size)."""
    out = subprocess.run(["avr-size", str(elf)], capture_output=True, text=True,
                         check=True).stdout.splitlines()[1].split()
    return {"text": int(out[0]), "data": int(out[1]), "bss": int(out[2])}


def host_and_avr(sources, d: Path, name: str, *, include=()) -> tuple[str, str]:
    """Build a test program with gcc for the host and with avr-gcc for
    simavr, side by side, run both: (host output, AVR output), newlines
    removed.  ``include``: directories besides tinyos/."""
    def host():
        exe = d / f"{name}_host"
        subprocess.run(["cc", "-std=c99", "-O2", "-Wall", "-Wextra", "-Werror"]
                       + [f"-I{p}" for p in (TINYOS, *include)]
                       + [str(s) for s in sources] + ["-o", str(exe)], check=True)
        return subprocess.run([str(exe)], capture_output=True, text=True).stdout.replace("\n", "")

    def avr():
        return run(build(sources, d / f"{name}.elf", include=include))

    with ThreadPoolExecutor(2) as pool:
        jobs = pool.submit(host), pool.submit(avr)
        return tuple(j.result() for j in jobs)


def check_result(text: str) -> tuple[list[str], str]:
    """The output of a C test program (tests/c/test_check.h): the tokens it
    printed, each ended by ';', and the summary "CHECKS <n> FAILED <m>"
    check_summary() prints before ";END"."""
    assert ";END" in text, text[-300:]
    tokens = text[:text.index(";END")].split(";")
    return tokens[:-1], tokens[-1]
