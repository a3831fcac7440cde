"""The mote's rules on the host.

* ``fixedpoint`` -- a physical calibration -> the mote's fixed-point
  calibration set, and its checks;
* ``mote_c``     -- the firmware's plain C (``tinyos/ninedof_*.c``) built and
  loaded with ctypes: the correction, the calibration receiver, EEPROM.
"""
