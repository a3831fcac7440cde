"""``motecal report``: the seed paper's tables and figures for one session.

    motecal report --db FILE --session NAME --out DIR [--mote ID] [--cal cal.json] [--seed N]
                   [--diagnosis-report DIR]

writes into ``DIR``:

* ``table1_accel.{csv,md}``, ``table2_gyro.{csv,md}``, ``table3_mag.{csv,md}``
  -- the paper's Tables I-III computed from the session through the
  calibration engine (``motecal.calib``), our identifiable full model's rows
  beside the paper model's;
* PNG figures per mote (magnitude per sample, 3D and three-plane scatter,
  residual against direction, coverage of directions, gyroscope Allan
  deviation, GA convergence);
* what the calibration did, per mote (``choices``, ``temperature``,
  ``poses``, ``diagnosis``, put together by ``calsections``): the model of
  each sensor and why, the quality gate's verdict and metrics, the
  temperature terms against the session's still data, the promised error
  against the number of poses, the diagnosis kept with the session -- tables
  and figures, the charts described once (``charts``) and drawn by matplotlib
  and by view.html;
* ``view.html``: the 3D views of ``motecal log --view`` for the stored session
  (``motecal.view``; one self-contained file, the data embedded) with those
  charts;
* ``index.html`` tying them together (relative links only; opens from disk).

The report is built in a temporary directory beside ``DIR`` and renamed into
place at the end, so a failure leaves nothing half-written; an existing
``DIR`` is replaced only when it is empty or holds an earlier report.

``write_report(store, session, out_dir, mote=None)`` is the same as a
function (for ``make demo``); it returns the path of ``index.html``.
"""
from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

from ..errors import UserError

INDEX = "index.html"


def _is_report_dir(path: Path) -> bool:
    """An empty directory, or one holding an earlier motecal report."""
    try:
        entries = list(path.iterdir())
    except OSError:
        return False
    if not entries:
        return True
    idx = path / INDEX
    if not idx.is_file():
        return False
    try:
        head = idx.read_text(encoding="utf-8", errors="replace")[:2000]
    except OSError:
        return False
    from .html import GENERATOR
    return f'content="{GENERATOR}"' in head


def _prepare_out(out_dir) -> tuple[Path, Path]:
    """Check ``out_dir`` can take a report; returns (final path, temporary dir)."""
    out = Path(out_dir).expanduser()
    if out.exists() and not out.is_dir():
        raise UserError(f"--out {out}: exists and is not a directory")
    if out.is_dir() and not _is_report_dir(out):
        raise UserError(f"--out {out}: directory is not empty and holds no earlier motecal "
                        f"report; choose a new or empty directory")
    parent = out.resolve().parent
    if not parent.is_dir():
        raise UserError(f"--out {out}: parent directory {parent} does not exist")
    try:
        tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.tmp-", dir=parent))
    except OSError as e:
        raise UserError(f"--out {out}: cannot write in {parent}: {e.strerror or e}") from None
    return out, tmp


def _commit_out(tmp: Path, out: Path) -> None:
    """Rename the finished temporary directory to ``out`` (replacing an earlier
    report: old moved aside, new renamed in, old removed)."""
    os.chmod(tmp, 0o755)
    old = None
    try:
        if out.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{out.name}.old-", dir=out.resolve().parent))
            os.rmdir(old)
            os.rename(out, old)
        os.rename(tmp, out)
    except OSError as e:
        if old is not None and old.exists() and not out.exists():
            os.rename(old, out)
        raise UserError(f"--out {out}: cannot move the report into place: "
                        f"{e.strerror or e}") from None
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


def write_report(store, session, out_dir, mote: int | None = None, *, cal=None,
                 seed: int = 0, log=None, diagnosis_report=None) -> Path:
    """Write the report of ``session`` (a name in ``store``, or a SessionData
    with ``store`` None) into ``out_dir``; returns the path of index.html.

    ``cal`` is a calibration to show (a ``BoardCalibration``, its JSON dict or
    a cal.json path); without it the latest calibration stored for the mote is
    used, and without that the board is calibrated now (full model, ``seed``).
    ``log`` is called with one-line progress messages.  ``diagnosis_report``
    is a ``motecal diagnose --report`` folder whose evidence pictures the
    diagnosis section shows (copied into the report).
    """
    from .build import build_report
    out, tmp = _prepare_out(out_dir)
    try:
        build_report(store, session, tmp, mote=mote, cal=cal, seed=seed, log=log,
                     diagnosis_report=diagnosis_report)
        _commit_out(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return out / INDEX
