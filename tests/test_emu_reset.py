"""The harness's reset (emu/node.c node_reset, `ninedof-emu --reset T[@I]`
and the `reset` control command): the MCU restarts (its start-up code runs
again) and keeps its EEPROM, as an ATmega1281 does after a reset.  An avr-gcc
program (emu/tests/eeprom_reset.c) counts its boots in EEPROM and prints
what it finds at each boot."""
import subprocess

import pytest

import emusim


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    return emusim.built_program(tmp_path_factory, "emureset", [emusim.EMU / "tests" / "eeprom_reset.c"])


def boots(text):
    """[(boots, data_var, eeprom hex)] per boot printed."""
    out = []
    for part in text.split(";")[:-1]:
        b, dv, e = part.split()
        out.append((int(b[1:]), int(dv[1:]), e[1:]))
    return out


def test_eeprom_survives_reset(built):
    d, exe, elf = built
    con = d / "ee.txt"
    rep = emusim.run(exe, ["--mote", str(elf), "--seconds", "0.5", "--reset", "0.1",
                           "--reset", "0.2@0", "--console", str(con)])
    seen = boots(con.read_text())
    # three boots: the EEPROM counts them and holds what the boot before wrote;
    # the initialised variable is 7 at every boot (the program changed it to 9)
    assert seen == [(0, 7, "ffffffff"), (1, 7, "a0b0c0d0"), (2, 7, "a1b1c1d1")], seen
    assert rep["nodes"][0]["resets"] == 2
    assert rep["nodes"][0]["state"] == "done"


def test_no_reset_one_boot(built):
    # the same program without a reset boots once (the test above can fail)
    d, exe, elf = built
    con = d / "ee0.txt"
    emusim.run(exe, ["--mote", str(elf), "--seconds", "0.3", "--console", str(con)])
    assert boots(con.read_text()) == [(0, 7, "ffffffff")]


def test_control_reset_and_stop(built):
    # --control: commands on stdin while the harness runs
    d, exe, elf = built
    con = d / "ee1.txt"
    proc = subprocess.Popen([str(exe), "--mote", str(elf), "--seconds", "600", "--control",
                             "--console", str(con), "--report", "json"],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    proc.stdin.write("reset 0 0.01\nreset motes 0.02\ntime\nbogus\n")
    proc.stdin.flush()
    lines = []
    while sum(ln.startswith("reset node") for ln in lines) < 2:
        line = proc.stdout.readline()
        assert line, lines
        lines.append(line)
    out, _ = proc.communicate("stop\n", timeout=60)
    assert proc.returncode == 0
    lines += out.splitlines()
    out = "".join(lines)
    assert sum(ln.startswith("reset node 0 (id 1) at ") for ln in lines) == 2, out
    assert any(ln.startswith("error: bad control command: bogus") for ln in lines), out
    assert [b for b, _, _ in boots(con.read_text())] == [0, 1, 2]


@pytest.mark.parametrize("spec", ["x", "0.1@", "0.1@5", "-1"])
def test_bad_reset(built, spec):
    d, exe, elf = built
    res = subprocess.run([str(exe), "--mote", str(elf), "--reset", spec], capture_output=True,
                         text=True)
    assert res.returncode == 2
    assert res.stderr.count("\n") == 1 and "--reset" in res.stderr
