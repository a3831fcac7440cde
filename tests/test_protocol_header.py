"""The host's message layouts must be exactly those of tinyos/NineDofMsg.h."""
import re
import subprocess

import pytest

from motecal.line import protocol as P
from cheader import parse_header

from conftest import REPO

HEADER = REPO / "tinyos" / "NineDofMsg.h"


@pytest.fixture(scope="module")
def hdr():
    return parse_header(HEADER)


def _check_fixed(hdr, spec: P.MessageSpec):
    s = hdr.structs[spec.name]
    assert [f.name for f in s.fields] == [f.name for f in spec.fields], spec.name
    for cf, pf in zip(s.fields, spec.fields):
        assert cf.ctype == pf.ctype, (spec.name, cf.name)
        assert hdr.dim(cf.dim) == pf.count, (spec.name, cf.name)
    assert hdr.sizeof(s.typedef) == spec.size


@pytest.mark.parametrize("spec", P.ALL_SPECS, ids=lambda s: s.name)
def test_fixed_layouts_match_header(hdr, spec):
    if spec.name in ("ninedof_samples_msg", "ninedof_calset"):
        # variable tail checked below: compare the fixed leading fields
        s = hdr.structs[spec.name]
        lead = s.fields[:len(spec.fields)]
        assert [(f.name, f.ctype, f.dim) for f in lead] == \
            [(f.name, f.ctype, None) for f in spec.fields]
    else:
        _check_fixed(hdr, spec)


def test_am_types_match_header(hdr):
    for name, value in vars(P).items():
        if name.startswith("AM_NINEDOF_"):
            assert hdr.constants[name] == value, name
    # every AM type the header defines is known to the host
    header_types = {k: v for k, v in hdr.constants.items() if k.startswith("AM_NINEDOF_")}
    assert set(header_types) == {n for n in vars(P) if n.startswith("AM_NINEDOF_")}
    assert hdr.constants["AM_NINEDOF_SAMPLES"] == 0x60


def test_sample_message_tail_and_sizes(hdr):
    s = hdr.structs["ninedof_samples_msg"]
    tail = s.fields[len(P.SAMPLES_HEADER.fields):]
    assert [(f.name, f.ctype, f.dim) for f in tail] == [P.SAMPLES_ARRAY]
    assert hdr.sizeof("ninedof_record_t") == P.NINEDOF_RECORD_SIZE == P.RECORD.size == 18
    assert hdr.constants["NINEDOF_BATCH"] == P.NINEDOF_BATCH
    assert hdr.sizeof("ninedof_samples_msg_t") == P.samples_payload_size(P.NINEDOF_BATCH)


def test_calset_layout(hdr):
    s = hdr.structs["ninedof_calset"]
    tail = s.fields[len(P.CALSET_HEADER.fields):]
    assert [(f.name, f.ctype, f.dim) for f in tail] == [P.CALSET_ARRAY]
    assert hdr.sizeof("ninedof_calset_t") == P.CALSET_SIZE


def test_calset_temp_layout(hdr):
    """The set with temperature terms: the plain set, then the temperature
    block; its size and format constants."""
    s = hdr.structs["ninedof_calset_temp"]
    assert [(f.name, f.ctype, f.dim) for f in s.fields[:1]] == [P.CALSET_TEMP_BASE]
    lead = s.fields[1:1 + len(P.CALSET_TEMP_HEADER.fields)]
    assert [(f.name, f.ctype) for f in lead] == \
        [(f.name, f.ctype) for f in P.CALSET_TEMP_HEADER.fields]
    tail = s.fields[1 + len(P.CALSET_TEMP_HEADER.fields):]
    assert [(f.name, f.ctype, f.dim) for f in tail] == [P.CALSET_TEMP_ARRAY]
    assert hdr.sizeof("ninedof_calset_temp_t") == P.CALSET_TEMP_SIZE == 164
    assert hdr.sizeof("ninedof_cal_temp_t") == P.CAL_TEMP.size == 20
    assert hdr.constants["NINEDOF_CALSET_PLAIN"] == P.CALSET_PLAIN == 0
    assert hdr.constants["NINEDOF_CALSET_TEMP"] == P.CALSET_TEMP
    assert P.CALSET_SIZES == {P.CALSET_PLAIN: 102, P.CALSET_TEMP: 164}


def test_constants_match_header(hdr):
    for name in ("NINEDOF_RATE_HZ", "NINEDOF_RECORD_SIZE", "NINEDOF_FRAG_DATA",
                 "NINEDOF_STATUS_PERIOD_MS", "NINEDOF_TEMP_PERIOD_MS"):
        assert hdr.constants[name] == getattr(P, name)
    assert hdr.constants["NINEDOF_FLAG_CORRECTED"] == P.FLAG_CORRECTED
    assert hdr.constants["NINEDOF_FLAG_VERSION_SHIFT"] == P.FLAG_VERSION_SHIFT
    assert hdr.constants["NINEDOF_FLAG_VERSION_MASK"] == P.FLAG_VERSION_MASK
    assert hdr.constants["NINEDOF_CAL_APPLY"] == P.CAL_APPLY
    assert hdr.constants["NINEDOF_CAL_RESET"] == P.CAL_RESET
    for code, (name, _) in P.CAL_REASONS.items():
        assert hdr.constants[name] == code
    header_codes = {k for k in hdr.constants if k.startswith("NINEDOF_CAL_E_")}
    assert header_codes == {n for n, _ in P.CAL_REASONS.values()} - {"NINEDOF_CAL_OK"}
    for i, name in enumerate(P.SENSORS):
        assert hdr.constants[f"NINEDOF_SENSOR_{name.upper()}"] == i


def test_c_compiler_agrees_on_sizes(tmp_path):
    """gcc, through nx_plain.h, lays the header out as the host expects."""
    src = tmp_path / "sz.c"
    names = ["ninedof_record_t", "ninedof_samples_msg_t", "ninedof_calset_t",
             "ninedof_calset_temp_t"] + \
        [s.name + "_t" for s in P.FIXED_MESSAGES.values()]
    src.write_text('#include <stdio.h>\n#include "NineDofMsg.h"\nint main(void){\n' +
                   "".join(f'printf("%zu\\n", sizeof({n}));\n' for n in names) + "return 0;}\n")
    exe = tmp_path / "sz"
    subprocess.run(["cc", "-std=c99", "-Wall", "-Werror", "-I", str(REPO / "tinyos"),
                    str(src), "-o", str(exe)], check=True)
    sizes = [int(x) for x in subprocess.run([str(exe)], capture_output=True, text=True,
                                            check=True).stdout.split()]
    expect = [18, P.samples_payload_size(P.NINEDOF_BATCH), P.CALSET_SIZE, P.CALSET_TEMP_SIZE] + \
        [s.size for s in P.FIXED_MESSAGES.values()]
    assert sizes == expect


def _earlier_name(spec: P.MessageSpec, k: int) -> str:
    """ninedof_cal_report_msg -> NINEDOF_CAL_REPORT_SIZE_V1"""
    stem = spec.name.removeprefix("ninedof_").removesuffix("_msg").upper()
    return f"NINEDOF_{stem}_SIZE_V{k}"


def test_earlier_sizes_match_header(hdr):
    """Every size a message had before it grew at its end is declared once,
    in the header (NINEDOF_<NAME>_SIZE_V<n>, oldest first), and protocol.py
    decodes exactly those (MessageSpec.earlier); each ends at a field of the
    header's layout."""
    declared = {k for k in hdr.constants if re.fullmatch(r"NINEDOF_\w+_SIZE_V\d+", k)}
    seen = set()
    for spec in P.FIXED_MESSAGES.values():
        names = [_earlier_name(spec, k + 1) for k in range(len(spec.earlier))]
        assert [hdr.constants[n] for n in names] == list(spec.earlier), spec.name
        assert _earlier_name(spec, len(spec.earlier) + 1) not in hdr.constants, spec.name
        seen.update(names)
        ends, at = set(), 0
        for f in hdr.structs[spec.name].fields:
            at += hdr.sizeof(f.ctype) * hdr.dim(f.dim)
            ends.add(at)
        assert set(spec.earlier) <= ends, spec.name
    assert declared == seen
    assert (P.MOTE_STATUS.earlier, P.CAL_QUERY.earlier, P.CAL_REPORT.earlier) == \
        ((14,), (3,), (28,))


def test_query_flags_and_store_states_match_header(hdr):
    assert hdr.constants["NINEDOF_QUERY_STORED"] == P.QUERY_STORED
    assert (hdr.constants["NINEDOF_STORE_IDLE"], hdr.constants["NINEDOF_STORE_WRITING"],
            hdr.constants["NINEDOF_STORE_FAILED"]) == (P.STORE_IDLE, P.STORE_WRITING,
                                                        P.STORE_FAILED)
