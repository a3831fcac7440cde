"""motecal: calibrate 9DOF sensor boards (ADXL345, ITG3200, HMC5883L) on IRIS motes.

Data path: firmware (tinyos/, basestation/) -> serial line -> protocol -> logger
-> store -> calib -> upload back to the mote; sim stands in for the hardware;
diagnose compares measured data with the simulator's model; report renders
the paper's tables and figures.
"""
__version__ = "0.1.0"
