"""motecal: calibrate 9DOF sensor boards (ADXL345, ITG3200, HMC5883L) on IRIS motes.

Data path: firmware (tinyos/, basestation/) -> serial line -> protocol -> logger
-> store -> calib -> upload back to the mote; sim stands in for the hardware;
diagnose compares measured data with the simulator's model; report renders
the paper's tables and figures.
"""
import os as _os

# The linear algebra here is many small problems (9-parameter fits, 3x3
# matrices): OpenBLAS's thread pool makes them 10-20x slower, not faster.
# Only a default: a user's own OPENBLAS_NUM_THREADS wins.
_os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

__version__ = "0.1.0"
