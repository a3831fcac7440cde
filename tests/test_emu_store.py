"""Issue 29 on the real image: the sensor-mote image in the emulator harness,
through the BaseStation image.  `motecal upload` says "stored" only when the
image reports the set stored in its EEPROM; a reset the moment it says so
keeps the new set (plain, then with temperature terms); a reset while the
image writes the set makes the upload fail, and the previous set comes back.

Needs the nesC build (a TinyOS tree in TINYOS_ROOT_DIR, nesC >= 1.4.0 on
PATH): skipped with one line otherwise, as in CI, which cannot build nesC.
The same logic in plain C is tested in CI (test_avr.py: logic_tests.c's
EEPROM writer, host and AVR; test_upload_stored.py: the simulated mote).
"""
import re
import subprocess
import sys
import time

import numpy as np
import pytest

import emusim
from motecal.calib.result import TempModel
from motecal.sessions.session import NOMINAL_SCALES

sys.path.insert(0, str(emusim.EMU))
import emulate  # noqa: E402
import release_check as rc  # noqa: E402

MOTECAL = [sys.executable, "-m", "motecal"]


@pytest.fixture(scope="module")
def images(tmp_path_factory):
    try:
        emulate.toolchain()
    except emulate.Unavailable as e:
        pytest.skip(f"the nesC build is not available here ({e}): the image's stored-set "
                    "report is not checked (docs/emulation.md)")
    emusim.skip_or_fail(pytest)
    d = tmp_path_factory.mktemp("emustore")
    mote = emulate.build_image("tinyos", d / "mote.elf")
    base = emulate.build_image("basestation", d / "basestation.elf")
    return d, emusim.build_harness(d / "build"), mote, base


def _cal(path, temperature, seed=21):
    from test_upload_stored import _board
    board = _board(seed=seed, temperature=False)
    if temperature:
        rng = np.random.default_rng(3)
        for name in ("gyro", "accel"):
            k = NOMINAL_SCALES[name]
            getattr(board, name).temperature = TempModel(
                t_ref_c=25.0, range_c=(18.0, 41.5),
                offset_per_c=rng.uniform(-3, 3, 3) / k, offset_per_c_std=[0.001] * 3,
                scale_per_c=rng.uniform(-8e-4, 8e-4, 3))
    board.save(path)
    return path


def _motecal(*args, timeout=300):
    return subprocess.run(MOTECAL + [str(a) for a in args], capture_output=True, text=True,
                          timeout=timeout, stdin=subprocess.DEVNULL)


def _show(url):
    r = _motecal("upload", "--show", "--mote", 1, "--port", url)
    assert r.returncode == 0, r.stdout + r.stderr
    return r.stdout.splitlines()


def _wait_emulated(h, seconds):
    end = h.now() + seconds
    while h.now() < end:
        time.sleep(0.2)


def test_the_image_reports_the_set_stored_and_a_reset_keeps_it(images, tmp_path):
    d, exe, mote, base = images
    h = rc.Harness(exe, ["--mote", f"{mote},id=1", "--base", f"{base},id=0", "--serial",
                         "tcp:0", "--seconds", "3600", "--settle", "1"],
                   tmp_path / "harness.err")
    try:
        url = h.wait_line(r"(socket://127\.0\.0\.1:\d+)", 60).group(1)
        _wait_emulated(h, 3.0)                       # booted, radio up, sampling
        lines = []
        for version, temp in ((1, False), (2, True)):
            cal = _cal(tmp_path / f"cal{version}.json", temp, seed=20 + version)
            proc = subprocess.Popen(MOTECAL + ["upload", str(cal), "--port", url],
                                    stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            out = []
            for line in proc.stdout:
                out.append(line.rstrip("\n"))
                if line.startswith("mote 1: calibration version"):
                    h.send("reset 0 0")              # the moment it says stored
                    break
            rest, err = proc.communicate(timeout=300)
            reset = h.wait_line(r"^reset node 0 .*", 120).group(0)
            assert proc.returncode == 0, "\n".join(out) + rest + err
            assert re.fullmatch(rf"mote 1: calibration version {version} \(was {version - 1}\) "
                                r"in force and verified, and stored \(survives a reboot\); .*",
                                out[-1]), out[-1]
            stored = next(x for x in out if x.startswith("  stored: "))
            secs = float(re.search(r"read back, ([0-9.]+) s after", stored).group(1))
            lines.append(f"version {version} ({'164' if temp else '102'} bytes): {stored.strip()}"
                         f"; {reset}")
            _wait_emulated(h, 2.0)                   # the reboot (MeasureClockC, radio)
            show = _show(url)
            assert show[0].startswith(f"mote 1: calibration version {version} in force"), show
            assert not show[1].startswith("  stored in its EEPROM"), show   # in force = stored
            assert secs > 0
        # a reset while the image writes version 3 (another calibration: most of
        # its bytes differ from what slot 0 holds, and the image skips bytes that
        # are already right): the upload fails, version 2 comes back
        cal = _cal(tmp_path / "cal3.json", False, seed=25)
        proc = subprocess.Popen(MOTECAL + ["upload", str(cal), "--port", url],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        for line in proc.stdout:
            if line.startswith("  commit: accepted"):
                h.send("reset 0 0.1")                # 0.1 emulated s after: mid-write
                lines.append(f"commit of version 3 accepted at {h.now():.3f} s emulated")
                break
        out, err = proc.communicate(timeout=300)
        reset = h.wait_line(r"^reset node 0 .*", 120).group(0)
        assert proc.returncode == 1, out + err
        assert err.count("\n") == 1 and "version 2" in err and "Traceback" not in err, err
        lines.append(f"reset 0.1 s after the commit of version 3: {err.strip()}; {reset}")
        _wait_emulated(h, 2.0)
        show = _show(url)
        assert show[0].startswith("mote 1: calibration version 2 in force"), show
        print("\n".join(lines))
    finally:
        h.stop()
