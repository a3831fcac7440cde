"""The chips' output ranges and overflow code have one definition
(``sessions.session``: ``CHIP_RANGES``, ``CHIP_LIMITS``,
``HMC5883L_OVERFLOW``; issue 24.5): it agrees with the C headers' macros,
every user reads it, and no other module of the package writes the codes
down again."""
from __future__ import annotations

import ast
import re
from pathlib import Path

from motecal.sessions import session as S

REPO = Path(__file__).resolve().parent.parent
PACKAGE = REPO / "host" / "motecal"
# the chips' codes that must not be written down outside sessions/session.py
CODES = {-4096, 4095, -2048, 2047}


def _c_value(path: Path, pattern: str) -> int:
    m = re.search(pattern, path.read_text())
    assert m, (path, pattern)
    return int(m.group(1))


def test_the_definition_agrees_with_the_c_headers():
    assert _c_value(REPO / "tinyos" / "ninedof_correct.h",
                    r"#define\s+NINEDOF_MAG_OVERFLOW\s+\((-?\d+)\)") == S.HMC5883L_OVERFLOW
    assert _c_value(REPO / "tinyos" / "ninedof_board.h",
                    r"NINEDOF_HMC5883L_OVERFLOW\s*=\s*(-?\d+)") == S.HMC5883L_OVERFLOW
    # the overflow code lies outside the HMC5883L's range; the sensors' limits are their chips'
    lo, hi = S.CHIP_RANGES["HMC5883L"]
    assert S.HMC5883L_OVERFLOW < lo and (lo, hi) == (-2048, 2047)
    assert S.CHIP_RANGES["ADXL345"] == (-4096, 4095)
    assert S.CHIP_RANGES["ITG3200"] == (-32768, 32767)
    assert all(S.CHIP_LIMITS[s] == S.CHIP_RANGES[c] for s, c in S.NOMINAL_CHIPS.items())


def test_every_user_reads_the_one_definition():
    from motecal.capture import guide
    from motecal.diagnose import extend, screens
    from motecal.firmware import fixedpoint
    from motecal.sessions import importer
    from motecal.sim import physics
    assert physics.CHIP_LIMITS is S.CHIP_LIMITS
    assert extend.SIM_LIMITS == {s: (float(lo), float(hi)) for s, (lo, hi) in S.CHIP_LIMITS.items()}
    ends = {float(v) for lo, hi in S.CHIP_LIMITS.values() for v in (lo, hi)}
    assert ends | {float(S.HMC5883L_OVERFLOW)} <= set(screens.FULL_SCALE_CODES)
    assert importer.CLIP_COUNTS["ADXL345"] == S.CHIP_RANGES["ADXL345"][1]
    assert importer.CLIP_COUNTS["ITG3200"] == S.CHIP_RANGES["ITG3200"][1]
    assert fixedpoint.MAG_LIMIT == -S.HMC5883L_OVERFLOW - 1
    assert fixedpoint.INPUT_RANGE == {s: -lo for s, (lo, _) in S.CHIP_LIMITS.items()}
    assert guide.MAG_OVERFLOW == S.HMC5883L_OVERFLOW


def _literal(node):
    if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)):
        return node.value
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
        v = _literal(node.operand)
        return None if v is None else -v
    return None


def test_no_module_writes_the_codes_down_again():
    """No module-level name of the package is given one of the chips' codes
    as a literal (a constant, or inside a tuple, list or dict), except in
    sessions/session.py."""
    bad = []
    for path in sorted(PACKAGE.rglob("*.py")):
        if path == PACKAGE / "sessions" / "session.py":
            continue
        for node in ast.parse(path.read_text()).body:
            if not isinstance(node, (ast.Assign, ast.AnnAssign)) or node.value is None:
                continue
            for sub in ast.walk(node.value):
                v = _literal(sub)
                if v is not None and v in CODES:
                    bad.append(f"{path.relative_to(REPO)}:{node.lineno} ({v})")
    assert not bad, bad
