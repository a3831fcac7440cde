"""The board's fault handling (tinyos/ninedof_fault.c: watchdog, bus clear,
configuration check, counters) and the chip descriptors it reads
(tinyos/ninedof_board.c), run by tests/c/fault_tests.c with gcc on the host
and with avr-gcc in simavr: the same decisions on both."""
import pytest

import avrsim

SOURCES = [avrsim.CSRC / "fault_tests.c", avrsim.TINYOS / "ninedof_fault.c",
           avrsim.TINYOS / "ninedof_board.c"]
DONE, SDA_STUCK, SCL_STUCK = 0x80, 0x04, 0x08

# bus clear: case -> (SCL falling edges, result, STOPs on the bus)
BUSCLEAR = {"free": (1, DONE, 1), "mixed": (5, DONE, 1), "stretch": (5, DONE, 1),
            "sdashort": (10, DONE | SDA_STUCK, 0), "sclshort": (0, DONE | SCL_STUCK, 0)}
# a slave with k low bits left of the byte it was sending: k pulses free
# SDA, the STOP's falling edge makes k + 1; 9 cover a byte and its ACK
BUSCLEAR.update({f"low{k}": (k + 1, DONE, 1) for k in range(1, 10)})


@pytest.fixture(scope="module")
def outputs(tmp_path_factory):
    if avrsim.missing_tools():
        pytest.fail(f"missing {avrsim.missing_tools()}: run `make sysdeps`")
    return avrsim.host_and_avr(SOURCES, tmp_path_factory.mktemp("fault"), "fault")


def _words(hexs):
    v = bytes.fromhex(hexs)
    return [int.from_bytes(v[i:i + 2], "big") for i in range(0, len(v), 2)]


def _parse(text):
    tokens, summary = avrsim.check_result(text)
    clear, scen, short = {}, None, {}
    for t in tokens:
        if t.startswith("B"):
            name, pulses, result, stops = t[1:].split(":")
            clear[name] = (int(pulses), int(result), int(stops))
        elif t.startswith("D"):
            master, words = t[1:].split(":")
            short[{"L": "lean", "S": "stock"}[master]] = _words(words)
        else:
            assert t.startswith("S"), t                  # a FAIL line lands here
            scen = _words(t[1:])
    return clear, scen, short, summary


def test_checks_pass_on_host_and_avr(outputs):
    for text in outputs:
        clear, scen, short, summary = _parse(text)
        n = int(summary.split()[1])
        assert summary == f"CHECKS {n} FAILED 0" and n >= 1000
        assert clear == BUSCLEAR


def test_host_and_avr_agree(outputs):
    assert _parse(outputs[0]) == _parse(outputs[1])


def test_scenario_keeps_sampling_and_counts_every_event(outputs):
    """2400 periods: the gyroscope resets silently at 300, the magnetometer
    NACKs from 900 to 949 and comes back reset, the bus hangs at 1500 until a
    bus clear works (1507), the accelerometer resets at 2000."""
    _, scen, _, _ = _parse(outputs[0])
    good, bad, late, wrong, nacks, resets, reinits, d_acc, d_gyro, d_mag = scen
    assert good + bad + late == 2400
    assert bad == 50 + 1 and late == 7                # NACKed reads, the aborted one
    assert (nacks, resets, reinits) == (50, 4, 3)
    assert d_mag <= 3                                 # checked right after the NACKs
    assert d_gyro <= 375 and d_acc <= 375             # within one round of the schedule
    # records of a reset chip: from its reset to the read that checked it
    assert wrong == (d_gyro + 1) + (d_acc + 1) + (d_mag + 1)


def test_a_failed_bus_clear_puts_the_bus_down_until_a_clear_works(outputs):
    """SDA shorted to ground from period 200 to 600 (8 ms each, 1200 in all):
    the watchdog's clear at 16 ms (period 202) fails, the bus goes down,
    reads are refused at once (lean: the aborted read ends) or the read under
    way stays late (stock: it cannot be aborted), the bus is cleared every
    256 ms (32 periods), not every 16 ms, and the first clear after the short
    (202 + 13 * 32 = 618) brings it up; sampling goes on with that period."""
    _, _, short, _ = _parse(outputs[0])
    assert set(short) == {"lean", "stock"}
    retry, up_at = 32, 202 + 13 * 32
    for master, w in short.items():
        good, refused, bad, late, resets, clears_down, apart, up, first_good, reinits = w
        assert good + refused + bad + late == 1200, master
        assert good == 1200 - 400 - (up_at - 600), master
        assert apart == retry and up == first_good == up_at - 600, master
        # one clear finds the short, 12 fail while it lasts, one brings the bus up
        assert resets == 14 and clears_down == 13 and bad == 1 and reinits == 0, master
    assert short["lean"][1:4] == [up_at - 202, 1, 1]      # refused, ended, late
    assert short["stock"][1:4] == [up_at - 600, 1, 399]
