"""The lean TWI master's state machine (tinyos/ninedof_twi.c, build option
NINEDOF_LEAN_I2C=1) against a model of the ATmega1281 TWI and one slave
(tests/c/twi_tests.c), built with gcc on the host and with avr-gcc in
simavr: every path's bus events and outcome, the same on both."""
import pytest

import avrsim

SOURCES = [avrsim.CSRC / "twi_tests.c", avrsim.TINYOS / "ninedof_twi.c"]

# scenario -> (outcome, bus events); see the legend in twi_tests.c
EXPECTED = {
    "chipread": (0, "S Aa6a W02a Sr Aa7a Raea Rb5a Rbca Rc3a Rcaa Rd1n P"),
    "write": (0, "S A3ca W03a W5aa P S A3ca W02a W01a Sr A3da R5aa Rbca Rc3a Rcaa Rd1a Rd8n P"),
    "ackend": (0, "S Ad0a W00a Sr Ad1a Ra0a Ra7a Raea Rb5a Rbcn P S Ad1a Rc3n P"),
    "wcont": (0, "S Aa6a W04a W11a W22a P S Aa6a W09a P"),
    "badargs": (5, "S Aa6a W01a P"),
    "addrnack": (1, "S Aa6n P S Aa6a W32a Sr Aa7n P"),
    "datanack": (2, "S Ad0a W05a W66n P"),
    "arb": (3, "S L - S Ad1a Ra0a L -"),
    "buserr": (4, "S Aa6a E r"),
    "abort": (6, "-"),           # ninedof_twi_abort + the bounded STOP wait (no bus events)
}


@pytest.fixture(scope="module")
def outputs(tmp_path_factory):
    if avrsim.missing_tools():
        pytest.fail(f"missing {avrsim.missing_tools()}: run `make sysdeps`")
    return avrsim.host_and_avr(SOURCES, tmp_path_factory.mktemp("twi"), "twi")


def _parse(text):
    tokens, summary = avrsim.check_result(text)
    scen = {}
    for t in tokens:
        assert t.startswith("T"), t                  # a FAIL line would land here
        name, outcome, events = t[1:].split(":")
        scen[name] = (int(outcome), events)
    return scen, summary


def test_every_path_on_host_and_avr(outputs):
    for text in outputs:
        scen, summary = _parse(text)
        n = int(summary.split()[1])
        assert summary == f"CHECKS {n} FAILED 0" and n >= 100
        assert scen == EXPECTED


def test_host_and_avr_agree(outputs):
    assert _parse(outputs[0]) == _parse(outputs[1])


def test_error_paths_end_the_transfer():
    # every failed operation leaves the bus free: a STOP (P), the bus given
    # up after lost arbitration (-), or the TWI recovered (r)
    for name, (outcome, events) in EXPECTED.items():
        if outcome and name != "abort":
            assert events.split()[-1] in ("P", "-", "r"), name


def test_call_saving_keeps_the_interrupted_registers(tmp_path):
    # NINEDOF_TWI_CALL_SAVING in an interrupt handler: a called function that
    # overwrites r0, r18-r27, r30, r31 and RAMPZ, ~58000 times during a
    # computation that keeps values in all of them (twi_isr_test.c); leaving
    # one register out of the macro makes R0 (checked by hand for r18, r24,
    # r30, and Z0 for RAMPZ)
    if avrsim.missing_tools():
        pytest.fail(f"missing {avrsim.missing_tools()}: run `make sysdeps`")
    text = avrsim.run(avrsim.build([avrsim.CSRC / "twi_isr_test.c"], tmp_path / "isr.elf"))
    assert "END" in text, text[-300:]
    hits, same, rampz = text[:text.index(";END")].split()
    assert int(hits[1:]) > 10000 and same == "R1" and rampz == "Z1", text
