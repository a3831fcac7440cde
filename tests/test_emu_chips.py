"""The emulator harness's TWI model and chip models (emu/twi.c, emu/chips.c)
against an AVR program built with avr-gcc from the project's own C: the lean
TWI master's state machine (tinyos/ninedof_twi.c) in the TWI interrupt,
reading the ADXL345, ITG-3200 and HMC5883L models through ninedof-emu's bus
(emu/tests/twi_chips.c).  Values are judged against the planted synthetic
board (emusim.synthetic), at the data-ready instants the datasheets give,
timed from the transaction log."""
import subprocess
import sys

import numpy as np
import pytest

import emusim

sys.path.insert(0, str(emusim.EMU))
import board  # noqa: E402  (emu/board.py)

@pytest.fixture(scope="module")
def built(tmp_path_factory):
    return emusim.built_program(tmp_path_factory, "emu", emusim.TWI_PROGRAM)


def run_program(built, name, *args, mhz=8.0, board=None, temp=None):
    d, exe, elf = built
    con, log = d / f"{name}.txt", d / f"{name}.log"
    spec = f"{elf},mhz={mhz}" + (f",board={board}" if board else "") + \
        (f",temp={temp}" if temp is not None else "")
    rep = emusim.run(exe, ["--mote", spec, "--seconds", "3", "--console", str(con),
                           "--twi-log", str(log), *args])
    text = con.read_text()
    assert text.endswith("END"), text[-200:]
    lines = [ln.strip() for ln in text[:-3].split(";") if ln.strip()]
    return rep["nodes"][0], lines, emusim.read_log(log)


@pytest.fixture(scope="module")
def plain(built):
    return run_program(built, "plain")


def transactions(log):
    """[(addr byte, [(time, event)...])] per address byte, bytes that follow"""
    out = []
    for t, _, ev in log:
        if ev.startswith("A"):
            out.append((int(ev[1:3], 16), [(t, ev)]))
        elif ev[0] in "WR" and out:
            out[-1][1].append((t, ev))
    return out


def le(b, i):
    v = b[i] | b[i + 1] << 8
    return v - 65536 if v >= 32768 else v


def be(b, i):
    v = b[i] << 8 | b[i + 1]
    return v - 65536 if v >= 32768 else v


def test_ids_and_configuration(plain):
    _, lines, _ = plain
    assert lines[0] == "ID e5 68 483433"          # DEVID, WHO_AM_I, 'H' '4' '3'
    assert lines[1] == "CFG " + "0" * 11          # every register write ACKed


def check_reads(run, truth):
    """Every sample's 20 bytes against truth(t_ns) (9 counts) at the instant
    the chip's data registers were filled."""
    node, lines, log = run
    samples = [ln.split() for ln in lines if ln.startswith("S ")]
    assert len(samples) == 20 and all(s[5] == "000" for s in samples)
    tr = transactions(log)
    # ADXL345 measuring since POWER_CTL = 0x08; 200 Hz (BW_RATE 0x0B)
    t_on = next(evs[2][0] for a, evs in tr if a == 0xA6 and len(evs) > 2
                and evs[1][1] == "W2d a" and evs[2][1] == "W08 a")
    adxl_reads = [evs[0][0] for a, evs in tr if a == 0xA7 and len(evs) == 7]
    # ITG-3200 awake from power-on, data 50 ms later, 1 kHz / (3 + 1)
    itg_reads = [evs[0][0] for a, evs in tr if a == 0xD1 and len(evs) == 9]
    # HMC5883L: every MODE = single write starts a measurement
    triggers = [evs[2][0] for a, evs in tr if a == 0x3C and len(evs) >= 3
                and evs[1][1] == "W02 a" and evs[2][1] == "W01 a"]
    assert len(adxl_reads) == len(itg_reads) == 20 and len(triggers) >= 22
    for i, s in enumerate(samples):
        a, g, m = (bytes.fromhex(x) for x in s[2:5])
        ta = t_on + (adxl_reads[i] - t_on) // 5_000_000 * 5_000_000
        assert [le(a, 0), le(a, 2), le(a, 4)] == truth(ta)[0:3], i
        tg = 50_000_000 + (itg_reads[i] - 50_000_000) // 4_000_000 * 4_000_000
        assert be(g, 0) == -13200 + 280 * (25 - 35)            # 25 C
        assert [be(g, 2), be(g, 4), be(g, 6)] == truth(tg)[3:6], i
        # the read in the same transaction as trigger i gets trigger i - 1
        mx, mz, my = be(m, 0), be(m, 2), be(m, 4)
        assert [mx, my, mz] == truth(triggers[i])[6:9], i
    assert node["chips"]["adxl345"]["data_reads"] == 20


def test_burst_reads_follow_the_board_at_the_data_ready_instants(plain):
    check_reads(plain, emusim.synthetic)


def test_settable_temperature_in_the_itg3200_burst(built, plain):
    """temp=C sets what TEMP_OUT (0x1B-0x1C) reads: the 8-byte burst from
    0x1B carries it before the rates; the report counts the reads."""
    assert plain[0]["chips"]["itg3200"]["temp_reads"] == 20
    assert plain[0]["chips"]["itg3200"]["last_temp"] == -16000          # the board's 25 C
    for temp, raw in ((31.5, -14180), (-10.0, -25800), (60.25, -6130)):
        node, lines, _ = run_program(built, f"temp{raw}", temp=temp)
        samples = [ln.split() for ln in lines if ln.startswith("S ")]
        assert len(samples) == 20
        assert {be(bytes.fromhex(s[3]), 0) for s in samples} == {raw}
        itg = node["chips"]["itg3200"]
        assert (itg["temp_reads"], itg["last_temp"], itg["data_reads"]) == (20, raw, 20)
    d, exe, elf = built
    res = subprocess.run([str(exe), "--mote", f"{elf},temp=200", "--seconds", "1"],
                         capture_output=True, text=True)
    assert res.returncode == 2 and "bad" in res.stderr


def test_board_table_from_the_simulator(built):
    # a table written by emu/board.py from motecal.sim (error model general,
    # static80 trajectory): the chips report its rows
    d = built[0]
    table = d / "board.txt"
    res = subprocess.run([sys.executable, str(emusim.EMU / "board.py"), "--out", str(table),
                          "--mote", "2", "--seed", "5", "--seconds", "1", "--rate", "2000"],
                         capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    rate, rows = board.read(table)
    assert rate == 2000 and rows.shape == (2000, 9) and len(np.unique(rows[:, 0])) > 5

    def truth(t_ns):
        return [int(v) for v in rows[min(t_ns * 2000 // 1_000_000_000, len(rows) - 1)]]

    check_reads(run_program(built, "table", board=table), truth)


def test_hmc5883l_single_measurement_takes_6_ms(plain):
    _, lines, log = plain
    tr = transactions(log)
    triggers = [evs[2][0] for a, evs in tr if a == 0x3C and len(evs) >= 3
                and evs[1][1] == "W02 a" and evs[2][1] == "W01 a"]
    hmc2 = bytes.fromhex(next(ln for ln in lines if ln.startswith("HMC2")).split()[1])
    hmc8 = bytes.fromhex(next(ln for ln in lines if ln.startswith("HMC8")).split()[1])
    # the trigger before HMC2 is the last one; 2 ms after it: the one before
    before, last = triggers[-2], triggers[-1]
    assert [be(hmc2, 0), be(hmc2, 4), be(hmc2, 2)] == emusim.synthetic(before)[6:9]
    assert [be(hmc8, 0), be(hmc8, 4), be(hmc8, 2)] == emusim.synthetic(last)[6:9]
    assert hmc2 != hmc8


def test_hmc5883l_pointer_rolls_back_to_the_data(plain):
    # HMC5883L datasheet rev. E, "I2C Communication Protocol": the pointer
    # moves on by one after each register, except that from 08 (Y LSB, the
    # last data byte) it rolls back to 03 (X MSB) and from 12 or above it
    # goes to 00.  So a read without a pointer write after a read of the six
    # data registers gets them again (a seventh byte is X MSB again), and
    # after the identification registers (0x0A..0x0C) it reads CRA, CRB.
    _, lines, _ = plain
    hmc8 = next(ln for ln in lines if ln.startswith("HMC8")).split()[1]
    r1, six, r2, seven, r3, two = next(ln for ln in lines if ln.startswith("HMCP")).split()[1:]
    assert (r1, r2, r3) == ("0", "0", "0")
    assert six == hmc8 and seven == hmc8 + hmc8[:2]
    assert two == "1820"                     # CRA, CRB of tinyos/ninedof_board.c


def test_bus_timing_follows_twbr(plain):
    # TWBR = 3, no prescaler: SCL period 16 + 2 * 3 = 22 cycles; a byte is 9
    # periods, so no two bytes end closer than 198 cycles = 24.75 us at 8 MHz
    node, _, log = plain
    times = [t for t, _, ev in log if ev[0] in "AWR"]
    assert min(b - a for a, b in zip(times, times[1:])) >= 24_750
    assert node["scl_hz"] == pytest.approx(8e6 / 22, abs=1)
    assert node["i2c_us_min"] > node["wire_us_mean"] > 0


def test_faults_off_reads_succeed(plain):
    _, lines, _ = plain
    assert next(ln for ln in lines if ln.startswith("MARK")) == "MARK 1"   # 0x77 NACKs
    f = [ln for ln in lines if ln.startswith("F ")]
    assert len(f) == 40 and all(ln.split()[2:] == ["0", "08", "0", "68"] for ln in f)


def mark_time(log):
    return next(t for t, _, ev in log if ev == "Aee n")


def fault_lines(lines):
    return [ln.split() for ln in lines if ln.startswith("F ")]


def test_nack_fault(built, plain):
    t0 = mark_time(plain[2]) + 50_000_000
    node, lines, log = run_program(built, "nack", "--fault", f"nack:itg3200:{t0 / 1e9}:0.05")
    f = fault_lines(lines)
    failed = [int(x[1]) for x in f if x[4] == "1"]
    assert len(failed) >= 5 and failed == list(range(failed[0], failed[-1] + 1))
    assert all(x[4] == "0" for x in f if int(x[1]) not in failed)
    for t, _, ev in log:                          # NACKs exactly inside the window
        if ev.startswith("Ad0"):
            assert (ev == "Ad0 n") == (t0 <= t < t0 + 50_000_000), (t, ev)
    assert node["chips"]["itg3200"]["nacked"] == len(failed)
    assert all(x[2] == "0" for x in f)            # the other chip is unaffected


def test_power_loss_fault(built, plain):
    t0 = mark_time(plain[2]) + 50_000_000
    node, lines, log = run_program(built, "power", "--fault", f"power:adxl345:{t0 / 1e9}:0.03")
    f = fault_lines(lines)
    off = [int(x[1]) for x in f if x[2] == "1"]
    assert len(off) >= 3
    assert all(x[3] == "08" for x in f if int(x[1]) < off[0])    # measuring before
    assert all(x[2] == "0" and x[3] == "00" for x in f if int(x[1]) > off[-1])  # reset values
    assert node["chips"]["adxl345"]["resets"] == 1


def test_sda_short_fault(built, plain):
    # SDA shorted to ground for 50 ms (the wires, emu/bus.c): STARTs wait
    # for a free bus, a 1 bit on the held line loses arbitration, nothing
    # completes on the bus meanwhile, and the waiting START goes first after
    t0 = mark_time(plain[2]) + 50_000_000
    t1 = t0 + 50_000_000
    node, lines, log = run_program(built, "short", "--fault", f"short:sda:{t0 / 1e9}:0.05")
    f = fault_lines(lines)
    assert len(f) == 40
    # at most the transfer on the wire when SDA went low loses arbitration
    assert sum(x[2] == "3" or x[4] == "3" for x in f) <= 1
    assert all(x[2] in "03" and x[4] in "03" for x in f)
    assert node["hang_waits"] >= 1
    busy = [(t, ev) for t, _, ev in log if t0 <= t < t1 and ev[0] in "SAWRP" and " L" not in ev]
    assert busy == []
    assert any(ev == "HANG-WAIT" for _, _, ev in log)
    assert [ev for t, _, ev in log if t >= t1][0] == "S"
