"""The emulated iris clocks (emu/node.c): the RC main clock set off nominal
(7.84 / 8.00 / 8.16 MHz) and the 32768 Hz crystal on timer 2 in asynchronous
mode (simavr 1.6's timer 2 with AS2 runs from a virtual 32768 Hz clock, in
emulated time): an avr-gcc program counts CPU cycles over crystal periods
(emu/tests/clock_crystal.c)."""
import pytest

import emusim


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    return emusim.built_program(tmp_path_factory, "emuclk", [emusim.EMU / "tests" / "clock_crystal.c"])


@pytest.mark.parametrize("mhz", [7.84, 8.0, 8.16])
def test_cpu_cycles_per_crystal_time(built, mhz):
    d, exe, elf = built
    con = d / f"clk{mhz}.txt"
    rep = emusim.run(exe, ["--mote", f"{elf},mhz={mhz}", "--seconds", "2", "--console", str(con)])
    assert rep["nodes"][0]["state"] == "done" and rep["nodes"][0]["mhz"] == pytest.approx(mhz)
    text = con.read_text()
    assert text.endswith(";END"), text
    ovf, half = (int(h) * 65536 + int(lo) for h, lo in
                 (x.split(":") for x in text[2:-4].split()))
    f = mhz * 1e6
    # 16 overflows of timer 2 = 16 * 256 crystal ticks = 0.125 s of the crystal
    assert ovf == pytest.approx(f * 16 * 256 / 32768, abs=20)
    # TCNT2 from 0 to 128: 128 ticks, to within one tick (the polling loop)
    assert half == pytest.approx(f * 128 / 32768, abs=f / 32768)


@pytest.mark.parametrize("ppm", [100, -250])
def test_crystal_off_by_ppm(built, ppm):
    # xtal_ppm=: simavr's virtual 32768 Hz clock set to 32768 (1 + ppm 1e-6)
    d, exe, elf = built
    con = d / f"xtal{ppm}.txt"
    emusim.run(exe, ["--mote", f"{elf},xtal_ppm={ppm}", "--seconds", "2", "--console", str(con)])
    text = con.read_text()
    ovf = int(text[2:].split()[0].split(":")[0]) * 65536 + int(text[2:].split()[0].split(":")[1])
    assert ovf == pytest.approx(8e6 * 0.125 / (1 + ppm * 1e-6), abs=20)
    assert abs(ovf - 1_000_000) > 90          # the offset is seen (100 ppm = 100 cycles)
