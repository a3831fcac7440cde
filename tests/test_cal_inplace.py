"""The correction kernel (sensor_q14, inline AVR assembly, now in
tinyos/ninedof_correct_avr.h) run in place, in one translation unit, as the
nesC image runs it (NineDofAppP's flush -> ninedof_batch_pack corrects its
batch in place).

Found by the release check (docs/emulation.md, End to end and Faults): with
in == out visible to the compiler, avr-gcc gives the asm's `out` operand the
register of its `p` operand (X), so `movw r26, %[out]` becomes `movw r26,
r26`, the results are stored 6 bytes late and the last record's
magnetometer 6 bytes past the batch (in the image: NineDofAppP__heartbeat,
SchedulerBasicP__m_tail, SoftwareAckLayerC__0__txMsg).  The image built by
`make iris` had that instruction three times.  Fixed in the correction (now
tinyos/ninedof_correct.c and ninedof_correct_avr.h): ninedof_correct_block
is never inlined on the AVR, so raw and out are two parameters the compiler
cannot prove equal.  The program calls it the way the image does, inlined
whole (flatten); without the fix this test fails."""
import pytest

import avrsim
import emusim


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    emusim.skip_or_fail(pytest)
    d = tmp_path_factory.mktemp("calinplace")
    exe = emusim.build_harness(d / "build")
    elf = avrsim.build([avrsim.CSRC / "avr_cal_inplace.c"], d / "inplace.elf",
                       include=[avrsim.CSRC])
    return d, exe, elf


def test_correction_in_place(built):
    d, exe, elf = built
    con = d / "out.txt"
    emusim.run(exe, ["--mote", str(elf), "--seconds", "0.5", "--console", str(con)])
    text = con.read_text()
    assert text.endswith("END"), text
    vals, canary = text[:-3].split("|")
    got = [int(v) for v in vals.split()]
    want = [100 * r + k + k + 1 for r in range(5) for k in range(9)]
    assert [int(v) for v in canary.split()] == [0x5A5A] * 9, "written past the buffer"
    assert got == want

