"""A motecal calibration (``cal.json``) in other tools' forms (``motecal
export-cal``; docs/interop.md).  ``TARGETS`` is the registry: each module
lists its targets (``common.Target``: the ``--to`` name, one line saying what
the file is, the writer, the options it takes); the command's choices and
help, docs/interop.md's table and the tests are derived from it.

* ``razor``: Razor AHRS firmware constants (``razor-c``) and the ROS
  razor_imu_9dof ``my_razor.yaml`` (``razor-yaml``), in the firmware's board
  frame;
* ``ardupilot``: an ArduPilot parameter file (``INS_ACC*``, ``INS_GYROFFS_*``,
  ``COMPASS_*``), the compass in the frame after ``AHRS_ORIENTATION``;
* ``imucal``: imucal's ``FerrarisCalibrationInfo`` JSON;
* ``c-header``: the fixed-point set the IRIS firmware applies
  (``motecal.firmware.fixedpoint``, one definition) as a C header.

Each writer returns an :class:`~motecal.targets.common.Export`: the text,
what the target computes from raw counts (``apply``), and the model parts
it cannot hold; :func:`~motecal.targets.common.costs` measures what that
costs on a session's data.  docs/CONTRIBUTING.md says how to add a target.
"""
from __future__ import annotations

import dataclasses

from . import ardupilot, cheader, imucal, razor
from .common import ExportOptions

TARGETS = {t.name: t for m in (razor, ardupilot, imucal, cheader) for t in m.TARGETS}
FORMATS = tuple(TARGETS)


def described() -> str:
    """The targets in words, for the command's help."""
    return "; ".join(f"{t.name}: {t.what}" for t in TARGETS.values())


def export(board, fmt: str, opts: ExportOptions = ExportOptions()):
    """``board`` written as ``fmt``; the axes, unless ``opts`` says, as the
    calibration records them (``settings["axis_frame"]``)."""
    if opts.axis_frame is None:
        opts = dataclasses.replace(opts, axis_frame=(board.settings or {}).get("axis_frame"))
    return TARGETS[fmt].write(board, opts)
