"""A motecal calibration (``cal.json``) in other tools' forms (``motecal
export-cal``; docs/interop.md):

* ``razor-c``: Razor AHRS firmware constants (a block to paste into
  ``Razor_AHRS.ino``); ``razor-yaml``: the ROS razor_imu_9dof ``my_razor.yaml``
  with the same names;
* ``ardupilot``: an ArduPilot parameter file (``INS_ACC*``, ``INS_GYROFFS_*``,
  ``COMPASS_OFS/DIA/ODI_*``);
* ``imucal``: imucal's ``FerrarisCalibrationInfo`` JSON;
* ``c-header``: the fixed-point set the IRIS firmware applies
  (``motecal.firmware.fixedpoint``, one definition) as a C header.

Each writer returns an :class:`~motecal.targets.common.Export`: the text,
what the target computes from raw counts (``apply``), and the model parts
it cannot hold; :func:`~motecal.targets.common.costs` measures what that
costs on a session's data.
"""
from __future__ import annotations

from . import ardupilot, cheader, imucal, razor

WRITERS = {"razor-c": razor.write_c, "razor-yaml": razor.write_yaml,
           "ardupilot": ardupilot.write, "imucal": imucal.write, "c-header": cheader.write}
FORMATS = tuple(WRITERS)


def export(board, fmt: str):
    return WRITERS[fmt](board)
