"""Razor AHRS recordings: raw text logs (``#A-R=``, ``#M-R=``, ``#G-R=`` lines) and
the magnetometer's big-endian float32 logs (``magnetom.float``)
(``motecal.sessions.importer``).
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..errors import UserError
from ..inputs import check_input_file
from .cells import BLOCK_BYTES, Rows, _count, _fail, byte_blocks, numbered_lines
from .imported import SOURCE_SEP, _session, add_note
from .labelling import _finish
from .ranges import ZERO_RUN, check_zero_runs
from .session import SENSOR_SLICES, SessionData

RAZOR_RATE_HZ = 50.0            # Razor AHRS firmware output: one sample every 20 ms
RAZOR_FRAME = ("as recorded: Razor AHRS firmware board frame (accel x = chip y, "
               "accel y = chip x; gyroscope and magnetometer sign flips)")
RAZOR_FLOAT_FRAME = "as recorded: Razor AHRS firmware board frame (magnetometer x, y, z)"


_RAZOR_LINE = re.compile(r"^#([AMG])-R=(.*)$")
_RAZOR_ORDER = ("A", "M", "G")
_RAZOR_COLS = {"A": slice(0, 3), "G": slice(3, 6), "M": slice(6, 9)}


def _parse_razor_text(path) -> tuple[np.ndarray, int | None]:
    samples = Rows(9)
    cur = [np.nan] * 9
    expect = 0                        # index into A, M, G
    start_line = None
    for lineno, line in numbered_lines(path):
        s = line.strip()
        if not s:
            continue
        m = _RAZOR_LINE.match(s)
        if not m:
            raise _fail(path, lineno, f"not a Razor AHRS raw line (#A-R=, #M-R=, #G-R=): "
                        f"{s[:60]!r}")
        key, rest = m.group(1), m.group(2)
        if key != _RAZOR_ORDER[expect]:
            raise _fail(path, lineno, f"expected #{_RAZOR_ORDER[expect]}-R= (samples are A, M, G "
                        f"lines in turn), found #{key}-R=")
        parts = rest.split(",")
        if len(parts) != 3:
            raise _fail(path, lineno, f"expected 3 values after #{key}-R=, found {len(parts)}")
        vals = [_count(p, path, lineno, f"#{key}-R value {j + 1}") for j, p in enumerate(parts)]
        if expect == 0:
            start_line = lineno
        cur[_RAZOR_COLS[key]] = vals
        expect += 1
        if expect == 3:
            samples.add(cur)
            cur = [np.nan] * 9
            expect = 0
    if not len(samples):
        raise _fail(path, 1, "no complete Razor AHRS sample (#A-R=, #M-R=, #G-R= lines)")
    raw = samples.array()
    # an incomplete last sample (capture stopped mid-sample) is dropped, noted by caller
    return raw, (start_line if expect else None)


def read_razor_text(paths, chip=None, kind="auto") -> SessionData:
    """Razor AHRS raw text logs: ``#A-R=``, ``#M-R=``, ``#G-R=`` lines, one sample
    = A, M, G; 50 Hz without timestamps, so ``t = row / 50``.

    Several files form one session (rows in the order given); each file is a
    separate recording for stillness, and with a static kind one pose per file.
    Chips: ADXL345, ITG3205, HMC5883L (SparkFun 9DOF Sensor Stick).
    """
    if isinstance(paths, (str, Path)):
        paths = [paths]
    paths = list(paths)
    if not paths:
        raise UserError("no Razor AHRS text file given")
    blocks, files, notes, pos = [], [], [], 0
    for p in paths:
        raw, partial = _parse_razor_text(p)
        if partial:
            notes.append(f"{p}: incomplete last sample from line {partial} dropped")
        blocks.append(raw)
        files.append({"file": str(p), "rows": [pos, pos + len(raw)], "samples": len(raw)})
        pos += len(raw)
    raw = np.vstack(blocks)
    n = len(raw)
    meta = {"format": "razor-text", "source": SOURCE_SEP.join(map(str, paths)), "files": files,
            "rate_hz": RAZOR_RATE_HZ, "rates_hz": {s: RAZOR_RATE_HZ for s in SENSOR_SLICES},
            "clocks": "shared (one A, M, G sample every 20 ms; t = row / 50)",
            "axis_frame": RAZOR_FRAME}
    for note in notes:
        add_note(meta, note)
    data = _session(Path(paths[0]).stem if len(paths) == 1 else Path(paths[0]).parent.name
                    or Path(paths[0]).stem, raw, np.arange(n) / RAZOR_RATE_HZ,
                    chips={"accel": "ADXL345", "gyro": "ITG3205", "mag": "HMC5883L"}, meta=meta)
    return _finish(data, chip, kind, [tuple(f["rows"]) for f in files], pose_per_part=True)


# ------------------------------------------------------------------ Razor float (magnetometer)

def _be_float32(buf: bytes) -> np.ndarray:
    """Big-endian float32 values of ``buf`` as float64; any bit pattern (a
    signalling NaN in random bytes warns when cast) without a warning."""
    with np.errstate(invalid="ignore"):
        return np.frombuffer(buf, ">f4").astype(np.float64)


SAMPLE_BYTES = 12                   # x, y, z big-endian float32


def _float_values(path) -> np.ndarray:
    """The (x, y, z) counts of a float log, read in blocks: a value that is not
    an integer count, or a run of ``ranges.ZERO_RUN`` samples of exactly zero
    (120 MB of zero bytes is no magnetometer log), stops at once with the
    sample and byte."""
    if Path(path).is_dir():
        raise UserError(f"{path}: is a directory, expected a file")
    check_input_file(path)
    size = Path(path).stat().st_size
    if size == 0:
        raise UserError(f"{path}: empty file: no float32 samples")
    whole = size // SAMPLE_BYTES
    if size % SAMPLE_BYTES:
        raise UserError(f"{path}: sample {whole + 1} (byte {whole * 12}): truncated float file, "
                        f"{size} bytes is not a whole number of 12-byte samples "
                        f"(3 big-endian float32)")
    out, carry, k0, tail = Rows(3), b"", 0, np.empty((0, 3))
    for buf in byte_blocks(path, BLOCK_BYTES - BLOCK_BYTES % SAMPLE_BYTES):
        buf = carry + buf
        cut = len(buf) - len(buf) % SAMPLE_BYTES
        buf, carry = buf[:cut], buf[cut:]
        x = _be_float32(buf).reshape(-1, 3)
        with np.errstate(invalid="ignore"):
            bad = ~np.isfinite(x).all(axis=1) | (np.abs(x) > 32768).any(axis=1) \
                | (x != np.round(x)).any(axis=1)
        if bad.any():
            k = int(np.flatnonzero(bad)[0])
            raise UserError(f"{path}: sample {k0 + k + 1} (byte {(k0 + k) * 12}): not raw integer "
                            f"counts ({', '.join(f'{v:g}' for v in x[k])}); not a big-endian "
                            f"float32 triplet file?")
        joined = np.vstack([tail, x])
        first = k0 - len(tail)
        check_zero_runs(joined, "mag", lambda j: f"{path}: sample {first + j + 1} "
                        f"(byte {(first + j) * 12})")
        tail = joined[-(ZERO_RUN - 1):]
        out.extend(x)
        k0 += len(x)
    return out.array()


def read_razor_float(path, chip="hmc5883l", kind="auto") -> SessionData:
    """Headerless big-endian float32 triplets (x, y, z magnetometer counts), the
    Razor AHRS ``magnetom.float`` logs: 50 Hz, no timestamps (t = row / 50).
    ``chip`` is the magnetometer (``hmc5883l`` 1090 LSB/gauss, ``hmc5843`` 1300)
    or any override accepted by ``--chip``.  Accelerometer and gyroscope are NaN."""
    x = _float_values(path)
    n = len(x)
    raw = np.full((n, 9), np.nan)
    raw[:, 6:9] = x
    meta = {"format": "razor-float", "source": str(path),
            "files": [{"file": str(path), "rows": [0, n], "samples": n}],
            "rate_hz": RAZOR_RATE_HZ, "rates_hz": {"mag": RAZOR_RATE_HZ},
            "clocks": "magnetometer only, 50 Hz stream (t = row / 50)",
            "axis_frame": RAZOR_FLOAT_FRAME}
    data = _session(Path(path).parent.name or Path(path).stem, raw, np.arange(n) / RAZOR_RATE_HZ,
                    meta=meta)
    data.chips = {"accel": None, "gyro": None, "mag": "HMC5883L"}
    if chip is None:
        chip = "hmc5883l"
    if isinstance(chip, str) and "=" not in chip:
        chip = f"mag={chip}"
    return _finish(data, chip, kind, None)
