"""export-cal does not trust its input (issue 28, item 4): one validation of
cal.json (``calib.result.check_document``) for ``upload`` and ``export-cal``.

NaN and infinities, a mote id beyond 16 bits, a singular matrix, deep JSON,
a zero or missing ``lsb_per_unit``, ``format_version`` 0 or "1", ``true``
as a matrix entry: one line naming the field, exit 2, from both commands,
with the same words.  Names that would be source lines stay comments.  A
hypothesis fuzz over cal.json documents: every run exits 0, 2 or 3, never a
traceback, one line on failure, and an export that exits 0 is whole: its
lines are the target's grammar, its numbers finite, its mote the
calibration's (no silent corruption).
"""
import json
import re
import struct
import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from clirun import motecal
from motecal.targets import FORMATS
from test_safety_fuzz import real_cal


def _doc():
    return json.loads(real_cal())


def _write(tmp, d, name="c.json") -> Path:
    p = Path(tmp) / name
    p.write_text(d if isinstance(d, str) else json.dumps(d, allow_nan=True))
    return p


def _set(d, path, value):
    *head, last = path
    for k in head:
        d = d[k]
    if value is _DELETE:
        del d[last]
    else:
        d[last] = value


_DELETE = object()
CASES = [
    (("accel", "A", 0, 0), float("nan"), "missing or infinite"),
    (("gyro", "c", 2), float("inf"), "missing or infinite"),
    (("mag", "A", 1, 2), float("-inf"), "missing or infinite"),
    (("accel", "lsb_per_unit"), float("nan"), "lsb_per_unit"),
    (("gyro", "lsb_per_unit"), 0, "lsb_per_unit"),
    (("mag", "lsb_per_unit"), -1090, "lsb_per_unit"),
    (("accel", "lsb_per_unit"), "256", "lsb_per_unit"),
    (("mote",), 70000, "mote id"),
    (("mote",), -1, "mote id"),
    (("mote",), 1.5, "mote id"),
    (("mote",), True, "mote id"),
    (("format_version",), 0, "format_version 0"),
    (("format_version",), "1", "format_version '1'"),
    (("format_version",), True, "format_version True"),
    (("format_version",), 3, "format_version 3"),
    (("accel", "A", 1, 1), True, "not a list of numbers"),
    (("accel", "A"), [[0, 0, 0], [0, 1, 0], [0, 0, 1]], "singular"),
    (("mag", "A"), [[1, 2, 3], [2, 4, 6], [0, 0, 1]], "singular"),
    (("gyro", "c"), [0, 0], "must be 3"),
    (("mag", "field_gauss"), "x", "field_gauss"),
    (("session",), ["x"], "'session' is not a text"),
    (("accel", "sensor"), "gyro", "\"sensor\" says"),
    (("gyro",), 5, "gyro is not an object"),
]


@pytest.mark.parametrize("path,value,words", CASES, ids=[" ".join(map(str, c[0])) + f"={c[1]!r}"
                                                         for c in CASES])
def test_export_cal_and_upload_refuse_the_same_documents(tmp_path, path, value, words):
    d = _doc()
    _set(d, path, value)
    cal = _write(tmp_path, d)
    errors = set()
    for fmt in FORMATS:
        out = tmp_path / f"o.{fmt}"
        rc, so, se = motecal("export-cal", cal, "--to", fmt, "--out", out)
        assert rc == 2 and words in se and se.count("\n") == 1, (fmt, se)
        assert not out.exists()
        errors.add(se)
    rc, so, se = motecal("upload", "--dry-run", cal)
    assert rc == 2 and se.count("\n") == 1 and "Traceback" not in se, se
    assert errors == {se}, (errors, se)               # one validation: the same line


def test_deep_json_and_broken_json(tmp_path):
    for text, words in (("[" * 100000 + "]" * 100000, "not JSON"), ("{" * 3 + "}", "not JSON"),
                        ('{"format_version": 1, "mote": 1, "accel": ' * 2000, "not JSON"),
                        ("[]", "no format_version"), ("null", "no format_version")):
        cal = _write(tmp_path, text)
        for argv in (("export-cal", cal, "--to", "c-header"), ("upload", "--dry-run", cal)):
            rc, so, se = motecal(*argv)
            assert rc == 2 and words in se and se.count("\n") == 1, (argv[0], se)


def test_mote_ids_a_header_holds(tmp_path):
    """70000 is refused (it became mote 4464 in the set); 0 and 65535 are
    written as they are, in the header and in the set's mote field."""
    d = _doc()
    for mote in (0, 65535):
        d["mote"] = mote
        out = tmp_path / "h.h"
        rc, so, se = motecal("export-cal", _write(tmp_path, d), "--to", "c-header", "--out", out)
        assert rc == 0, se
        text = out.read_text()
        assert f"#define MOTECAL_CAL_MOTE {mote}\n" in text
        from motecal.targets import cheader
        assert struct.unpack(">H", cheader.parse(text)[:2])[0] == mote


def test_a_hostile_session_name_stays_a_comment(tmp_path):
    d = _doc()
    d["session"] = "s\n#error injected\n*/ int x = 1; /*"
    d["created"] = "now\n#define ACCEL_X_MIN ((float) 0)"
    cal = _write(tmp_path, d)
    for fmt in FORMATS:
        out = tmp_path / f"o.{fmt}"
        rc, so, se = motecal("export-cal", cal, "--to", fmt, "--out", out)
        assert rc == 0, se
        whole(fmt, out.read_text(), d["mote"])


# ---------------------------------------------------------------- what a whole export is

NUM = r"-?\d+(?:\.\d+)?(?:e[-+]?\d+)?"
NUMS3 = rf"{NUM}, {NUM}, {NUM}"
GRAMMAR = {
    "razor-c": [r"#define (ACCEL|MAGN)_[XYZ]_(MIN|MAX) \(\(float\) " + NUM + r"\)",
                r"#define GYRO_AVERAGE_OFFSET_[XYZ] \(\(float\) " + NUM + r"\)",
                r"#define CALIBRATION__MAGN_USE_EXTENDED true",
                r"const float magn_ellipsoid_center\[3\] = \{" + NUMS3 + r"\};",
                r"const float magn_ellipsoid_transform\[3\]\[3\] = \{\{" + NUMS3 + r"\}, \{"
                + NUMS3 + r"\}, \{" + NUMS3 + r"\}\};"],
    "razor-yaml": [r"#[ -~]*", r"(accel|magn)_[xyz]_(min|max): -?\d+(\.\d+)?",
                   r"gyro_average_offset_[xyz]: -?\d+(\.\d+)?",
                   r"calibration_magn_use_extended: true",
                   r"magn_ellipsoid_center: \[[-\d., ]+\]",
                   r"magn_ellipsoid_transform: \[\[[-\d., ]+\], \[[-\d., ]+\], \[[-\d., ]+\]\]"],
    "ardupilot": [r"# [ -~]*", r"(INS_ACCSCAL|INS_ACCOFFS|INS_GYROFFS|COMPASS_OFS|COMPASS_DIA|"
                  r"COMPASS_ODI)_[XYZ]," + NUM, r"COMPASS_SCALE,1", r"AHRS_ORIENTATION,\d+"],
    "c-header": [r"#ifndef MOTECAL_CAL_MOTE\d+_H", r"#define MOTECAL_CAL_MOTE\d+_H",
                 r"#include <stdint.h>", r"#define MOTECAL_CAL_MOTE \d+",
                 r"#define MOTECAL_CAL_VERSION \d+", r"#define MOTECAL_(ACCEL|GYRO|MAG)_SHIFT \d+",
                 r"static const int16_t motecal_(accel|gyro|mag)_a\[9\] = \{(-?\d+, ){8}-?\d+\};",
                 r"static const int32_t motecal_(accel|gyro|mag)_c\[3\] = \{(-?\d+, ){2}-?\d+\};",
                 r"static const uint8_t motecal_calset\[\d+\] = \{(0x[0-9a-f]{2}, )*0x[0-9a-f]{2}\};",
                 r"#endif"],
}


def whole(fmt: str, text: str, mote: int) -> None:
    """The export is the target's grammar, line for line (comments removed
    for C: printable ASCII only, each closed where it began), every number
    finite, and the mote the calibration's."""
    assert text.endswith("\n") and all(" " <= ch <= "~" or ch == "\n" for ch in text), fmt
    if fmt == "imucal":
        d = json.loads(text, parse_constant=lambda c: pytest.fail(f"imucal: {c} in the JSON"))
        assert d["_format_version"] == "2.0" and d["cal_type"] == "Ferraris"
        return
    code = text
    if fmt in ("razor-c", "c-header"):
        code = re.sub(r"/\*.*?\*/", "", code, flags=re.S)
        code = re.sub(r"//[^\n]*", "", code)
        assert "/*" not in code and "*/" not in code, fmt
    for line in code.splitlines():
        line = line.strip()
        if line:
            assert any(re.fullmatch(g, line) for g in GRAMMAR[fmt]), (fmt, line)
    assert not re.search(r"\b(nan|inf|infinity)\b", code, re.I), fmt
    if fmt == "c-header":
        from motecal.targets import cheader
        assert f"#define MOTECAL_CAL_MOTE {mote}\n" in text
        assert struct.unpack(">H", cheader.parse(text)[:2])[0] == mote


# ---------------------------------------------------------------- the fuzz

PATHS = [("format_version",), ("mote",), ("session",), ("created",), ("settings",),
         ("settings", "axis_frame"), ("accel",), ("gyro",), ("mag",),
         ("accel", "A"), ("accel", "A", 0), ("accel", "A", 2, 1), ("accel", "c"),
         ("accel", "c", 0), ("accel", "lsb_per_unit"), ("accel", "sensor"),
         ("gyro", "A", 1, 1), ("gyro", "c", 2), ("gyro", "lsb_per_unit"), ("gyro", "temperature"),
         ("mag", "A", 0, 2), ("mag", "c"), ("mag", "lsb_per_unit"), ("mag", "field_gauss"),
         ("accel", "params"), ("accel", "n_samples"), ("gate",), ("mag", "notes")]
VALUES = [_DELETE, None, True, False, 0, -1, 1, 0.5, 1e-320, 1e308, -1e308, 2 ** 63, 70000,
          65535, float("nan"), float("inf"), float("-inf"), "", "1", "x\n#error e */", [], {},
          [0, 0, 0], [[1, 0, 0], [0, 1, 0], [0, 0, 1]], [[1e30, 0, 0], [0, 1e30, 0], [0, 0, 1e30]],
          [[1e-30, 0, 0], [0, 1e-30, 0], [0, 0, 1e-30]], [1e9, -1e9, 1e9], [[[]]],
          {"t_ref_c": 25, "range_c": [20, 30], "offset_per_c": [0.01, None, 0.02]},
          {"t_ref_c": 25, "range_c": [30, 20], "offset_per_c": [0, 0, 0]},
          {"t_ref_c": float("nan"), "range_c": [20, 30], "offset_per_c": [0, 0, 0]}]


# edges a calibration may really have, which the export must then write whole
EDGY = [(("mote",), 0), (("mote",), 65535), (("session",), "x\n#error e */ \\"),
        (("created",), "é\r\n#define X"), (("session",), ""), (("accel", "c", 0), 0.0),
        (("gyro", "c", 1), 1e-320), (("gyro", "c", 2), 50.0), (("mag", "c", 0), -3.0),
        (("accel", "A", 0, 1), 0.0), (("mag", "A", 2, 0), 1e-12), (("accel", "A", 1, 0), 1e-3),
        (("mag", "field_gauss"), None), (("mag", "field_gauss"), 1e-3), (("mag",), None),
        (("gyro",), None), (("accel", "lsb_per_unit"), 1.0), (("gyro", "lsb_per_unit"), 131.0),
        (("settings", "axis_frame"), "as recorded: imucal's sensor frame (x_p: the x axis reads "
                                     "+1 g)"),
        (("settings", "axis_frame"), None), (("format_version",), 2),
        (("gyro", "temperature"), {"t_ref_c": 25.0, "range_c": [18.0, 41.0],
                                   "offset_per_c": [0.02, None, -0.03], "scale_per_c": [1e-4, 0, 0]})]


@st.composite
def documents(draw):
    d = _doc()
    pairs = [draw(st.sampled_from(EDGY)) for _ in range(draw(st.integers(1, 4)))]
    if draw(st.booleans()):
        pairs += [(draw(st.sampled_from(PATHS)), draw(st.sampled_from(VALUES)))
                  for _ in range(draw(st.integers(1, 2)))]
    for path, value in pairs:
        try:
            _set(d, path, json.loads(json.dumps(value, allow_nan=True))
                 if isinstance(value, (list, dict)) else value)
        except (KeyError, IndexError, TypeError):
            pass                                   # a path a previous change removed
    return d, draw(st.sampled_from(FORMATS))


@pytest.mark.slow
@settings(max_examples=60, deadline=None, database=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(documents())
def test_fuzz_export_cal_inputs(case):
    """Hostile cal.json documents through every target and the upload's
    check: exit 0, 2 or 3; no traceback; one line on failure; an export that
    says it worked is whole (``whole``)."""
    d, fmt = case
    with tempfile.TemporaryDirectory(prefix="motecal-fuzz-export-") as tmp:
        cal = _write(tmp, d)
        out = Path(tmp) / "out"
        rc, so, se = motecal("export-cal", cal, "--to", fmt, "--out", out)
        where = f"export-cal --to {fmt} {json.dumps(d, allow_nan=True)[:300]}"
        assert rc in (0, 2, 3), f"{where}: exit {rc}: {se}"
        assert "Traceback" not in se, where
        if rc:
            assert se.count("\n") == 1 and not out.exists(), f"{where}: {se!r}"
        else:
            whole(fmt, out.read_text(), d["mote"])
            assert not re.search(r"\b(nan|inf)\b", so, re.I), f"{where}: costs {so}"
        rc2, so2, se2 = motecal("upload", "--dry-run", cal)
        assert rc2 in (0, 2, 3) and "Traceback" not in se2, f"upload {where}: {se2}"
        if rc2:
            assert se2.count("\n") == 1, se2


def test_a_null_temperature_coefficient_is_zero(tmp_path):
    """A coefficient that was not fitted (null in cal.json) is 0, as on the
    mote: the costs printed are numbers, never NaN."""
    d = _doc()
    d["gyro"]["temperature"] = {"t_ref_c": 25.0, "range_c": [18.0, 41.0],
                                "offset_per_c": [0.02, None, -0.03], "scale_per_c": [1e-4, 0, 0]}
    cal = _write(tmp_path, d)
    for fmt in FORMATS:
        rc, so, se = motecal("export-cal", cal, "--to", fmt, "--out", tmp_path / "o")
        assert rc == 0 and not re.search(r"\bnan\b", so, re.I), so
        gyro = next(line for line in so.splitlines() if line.startswith("gyro:"))
        held = fmt == "c-header"
        assert ("temperature terms held" in gyro) == held, gyro
        assert ("temperature model dropped" in gyro) == (not held), gyro
