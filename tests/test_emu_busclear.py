"""The harness's I2C wires (emu/bus.c) and the firmware's bus clear on them:
an avr-gcc program (emu/tests/bus_clear.c) reads the ITG-3200 model with the
lean master's state machine and, when a read hangs, first switches the TWI
off and on (no clock pulse: the bus must stay busy), then clocks the pins
with the firmware's own sequence (ninedof_busclear_step on PD0/PD1, as
NineDofBusClearP does).  What is planted: a chip stuck mid-byte holding SDA
until N clock pulses (--fault stuck), and a line shorted to ground (--fault
short).  The clear must free the first after exactly N pulses and must
report the second stuck."""
import pytest

import avrsim
import emusim

DONE, SDA_STUCK, SCL_STUCK = 0x80, 0x04, 0x08
HUNG = 255


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    return emusim.built_program(tmp_path_factory, "busclear", [
        emusim.EMU / "tests" / "bus_clear.c", avrsim.TINYOS / "ninedof_twi.c",
        avrsim.TINYOS / "ninedof_fault.c", avrsim.TINYOS / "ninedof_board.c"])


def run(built, name, *faults):
    d, exe, elf = built
    con, log = d / f"{name}.txt", d / f"{name}.log"
    args = ["--mote", str(elf), "--seconds", "1", "--console", str(con), "--twi-log", str(log)]
    for f in faults:
        args += ["--fault", f]
    node = emusim.run(exe, args)["nodes"][0]
    text = con.read_text()
    assert text.endswith("END"), text[-300:]
    lines = [ln.strip().split() for ln in text[:-3].split(";") if ln.strip()]
    return node, lines, emusim.read_log(log)


@pytest.fixture(scope="module")
def plain(built):
    return run(built, "plain")


def mark(plain):
    """Emulated time (s) of the program's MARK (the write to 0x77), + 5 ms."""
    return next(t for t, _, ev in plain[2] if ev == "Aee n") / 1e9 + 0.005


def test_pind_reads_the_wires(plain):
    node, lines, _ = plain
    # TWI off: released 3 (pull-ups), SDA driven low 1, SCL driven low 2, both 0
    assert lines[0] == ["PINS", "3", "1", "2", "0"]
    assert lines[1] == ["ID", "68"]
    reads = [ln for ln in lines if ln[0] == "R"]
    assert [r[2] for r in reads] == ["0"] * 12 and not any(ln[0] == "CLEAR" for ln in lines)
    # the PINS steps: SCL falls once (SDA released -> SCL low), and releasing
    # both from low (SCL first, then SDA) is a STOP
    w = node["wires"]
    assert (w["gpio_scl_pulses"], w["gpio_stops"], w["stuck_holds"]) == (1, 1, 0)


@pytest.mark.parametrize("pulses", [1, 5, 9])
def test_stuck_slave_holds_the_bus_until_the_clear_clocks_it(built, plain, pulses):
    node, lines, log = run(built, f"stuck{pulses}", f"stuck:itg3200:{mark(plain)}:{pulses}")
    reads = [ln for ln in lines if ln[0] == "R"]
    hung = [int(r[1]) for r in reads if r[2] == str(HUNG)]
    assert len(hung) == 1, lines                          # one read found the bus held
    # the TWI off and on gives no clock pulse: the bus stays busy
    assert next(ln for ln in lines if ln[0] == "OFFON") == ["OFFON", str(HUNG)]
    # the firmware's clear: done, no line stuck
    assert next(ln for ln in lines if ln[0] == "CLEAR") == ["CLEAR", str(DONE)]
    assert all(r[2] == "0" for r in reads if int(r[1]) > hung[0])   # reads go on
    w = node["wires"]
    assert w["stuck_holds"] == 1 and w["stuck_freed"] == 1 and not w["sda_held_at_end"]
    assert w["freed_after_pulses"] == pulses
    # the pins' pulses: 1 from the PINS probe, `pulses` that free SDA, the
    # STOP's own falling edge; then the clear's STOP (and the probe's)
    assert w["gpio_scl_pulses"] == 1 + pulses + 1 and w["gpio_stops"] == 1 + 1
    ev = [e for _, _, e in log]
    stuck = ev.index(f"STUCK itg3200 {pulses}")
    freed = ev.index(f"FREED itg3200 {pulses}")
    assert ev[stuck - 1] == "P (SDA held: no STOP)"
    assert ev[stuck + 1:freed].count("C") == pulses      # nothing else moved SCL
    assert ev[freed + 1:freed + 3] == ["C", "P gpio"]    # the clear's STOP
    assert "S" in ev[freed:]                             # the next START


@pytest.mark.parametrize("line, result, pulses", [("sda", DONE | SDA_STUCK, 10),
                                                   ("scl", DONE | SCL_STUCK, 0)])
def test_a_shorted_line_makes_the_clear_report_it_stuck(built, plain, line, result, pulses):
    node, lines, _ = run(built, f"short{line}", f"short:{line}:{mark(plain)}")
    clears = [int(ln[1]) for ln in lines if ln[0] == "CLEAR"]
    assert clears and all(r == result for r in clears), lines
    # every read from the short on hangs or fails; no clear frees the line
    results = [r[2] for r in lines if r[0] == "R"]
    first = results.index(str(HUNG))
    assert first >= 1 and all(r != "0" for r in results[first:])
    w = node["wires"]
    assert w["gpio_stops"] == 1 and w["stuck_holds"] == 0     # the probe's STOP only
    # 9 pulses and the STOP's attempt per clear on a shorted SDA; none on SCL
    assert w["gpio_scl_pulses"] == 1 + pulses * len(clears)
