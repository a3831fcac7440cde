"""motecal: calibrate 9DOF sensor boards (ADXL345, ITG3200, HMC5883L) on IRIS motes.

Data path, one sub-package per stage: firmware (tinyos/, basestation/) -> serial
line (``line``) -> logging (``capture``) into sessions and their store
(``sessions``) -> calibration (``calib``) -> the mote's fixed point (``firmware``)
-> ``upload`` back to the mote; ``sim`` stands in for the hardware; ``diagnose``
compares measured data with the simulator's model; ``report`` renders the
paper's tables and figures; ``commands`` is the command line.  Layers and the
rule that keeps imports pointing down: docs/CONTRIBUTING.md.
"""
import os as _os

# The linear algebra here is many small problems (9-parameter fits, 3x3
# matrices): OpenBLAS's thread pool makes them 10-20x slower, not faster.
# Only a default: a user's own OPENBLAS_NUM_THREADS wins.
_os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

__version__ = "0.1.0"
