"""Build and run the emulator harness (emu/, ninedof-emu) for the tests and
benchmarks: the harness binary (gcc + Debian's libsimavr-dev), AVR programs
(avr-gcc, tests/avrsim.py), and the harness's outputs (UART0 text, the
transaction log, the JSON report).  docs/emulation.md."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path

import avrsim

REPO = avrsim.REPO
EMU = REPO / "emu"
PACKAGES = ("libsimavr-dev", "libelf-dev", "pkg-config", "gcc-avr", "avr-libc")


def missing() -> list[str]:
    """What the harness needs and this machine lacks (tools and headers)."""
    out = [t for t in ("cc", "avr-gcc", "pkg-config") if shutil.which(t) is None]
    if shutil.which("pkg-config") and subprocess.run(
            ["pkg-config", "--exists", "simavr"]).returncode != 0:
        out.append("libsimavr-dev")
    if not Path("/usr/include/libelf.h").exists() and not Path("/usr/include/gelf.h").exists():
        out.append("libelf-dev")
    return out


def skip_or_fail(pytest):
    """Skip with one line when the Debian packages are missing, unless under
    CI (CI=true), where the harness tests must run."""
    miss = missing()
    if not miss:
        return
    msg = f"emulator harness needs {', '.join(miss)} (make sysdeps)"
    if os.environ.get("CI", "").lower() == "true":
        pytest.fail(msg)
    pytest.skip(msg)


_BUILT: list[Path] = []

# the harness's bus from the AVR side: the lean master's state machine in the
# TWI interrupt (emu/tests/twi_chips.c), test_emu_chips.py and test_emu_cli.py
TWI_PROGRAM = (EMU / "tests" / "twi_chips.c", avrsim.TINYOS / "ninedof_twi.c",
               avrsim.TINYOS / "ninedof_board.c")


def build_harness(build_dir: Path) -> Path:
    """emu/ built into build_dir (make -C emu BUILD=...): the binary.  Built
    once per test session; later calls get the first build (the test modules
    each ask, in their own temp folders)."""
    if _BUILT and _BUILT[0].exists():
        return _BUILT[0]
    build_dir.mkdir(parents=True, exist_ok=True)
    res = subprocess.run(["make", "-s", "-C", str(EMU), f"BUILD={build_dir}"],
                         capture_output=True, text=True)
    if res.returncode != 0:
        raise RuntimeError(f"building the harness failed:\n{res.stdout}{res.stderr}")
    _BUILT.append(build_dir / "ninedof-emu")
    return _BUILT[0]


def built_program(tmp_path_factory, name: str, sources) -> tuple[Path, Path, Path]:
    """A test module's harness and avr-gcc program (sources: the program and
    the project's C it runs): (its temp folder, ninedof-emu, the ELF).  Skips
    with one line when the Debian packages are missing (fails under CI)."""
    import pytest
    skip_or_fail(pytest)
    d = tmp_path_factory.mktemp(name)
    exe = build_harness(d / "build")
    elf = avrsim.build(list(sources), d / f"{name}.elf", include=[avrsim.CSRC])
    return d, exe, elf


def run(exe: Path, args: list[str], *, timeout: float = 300) -> dict:
    """Run the harness with --report json: the report."""
    res = subprocess.run([str(exe), *args, "--report", "json"], capture_output=True,
                         text=True, timeout=timeout)
    if res.returncode != 0:
        raise RuntimeError(f"ninedof-emu {' '.join(args)}: exit {res.returncode}\n{res.stderr}")
    out = res.stdout
    return json.loads(out[out.index('{"seconds"'):])     # lines before it: resets


def read_log(path: Path) -> list[tuple[int, int, str]]:
    """The transaction log: (time ns, node index, event) per line."""
    out = []
    for line in Path(path).read_text().splitlines():
        t, node, ev = line.split(" ", 2)
        out.append((int(t), int(node), ev))
    return out


# the synthetic board (emu/board.c, board_synthetic): axis i at time t
SYN_BASE = (0, 40, 200, -300, 100, 0, 100, -200, -500)
SYN_SIGN = (1, -1, 1, 1, -1, 1, 1, 1, -1)


def synthetic(t_ns: int) -> list[int]:
    k = t_ns // 1_000_000
    return [SYN_BASE[i] + SYN_SIGN[i] * ((k * (i + 1)) % 512) for i in range(9)]
