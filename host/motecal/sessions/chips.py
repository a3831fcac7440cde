"""The chips an import knows: their scales (LSB per unit), full scale and
names, and ``--chip`` overrides (``motecal.sessions.importer``).
"""
from __future__ import annotations

import re

import numpy as np

from ..errors import UserError
from .options import option_parts
from .ranges import check_scale
from .session import (ADXL345_LSB_PER_G, HMC5883L_LSB_PER_GAUSS, ITG3200_LSB_PER_DPS,
                      NOMINAL_CHIPS, NOMINAL_SCALES)

# LSB per unit (accel LSB/g, gyro LSB/(deg/s), mag LSB/gauss), datasheet nominal
CHIP_SCALES = {
    "accel": {"ADXL345": ADXL345_LSB_PER_G,          # full resolution
              "MPU6050": 16384.0},                   # +-2 g
    "gyro": {"ITG3200": ITG3200_LSB_PER_DPS,         # FS_SEL=3
             "ITG3205": ITG3200_LSB_PER_DPS,
             "MPU6050": 131.0},                      # +-250 deg/s
    "mag": {"HMC5883L": HMC5883L_LSB_PER_GAUSS,      # default gain
            "HMC5843": 1300.0},                      # default gain
}
# a reading at or beyond this many counts (absolute) is the sensor's full scale
CLIP_COUNTS = {"MPU6050": 32767, "ITG3200": 32767, "ITG3205": 32767, "ADXL345": 4095}
SENSOR_ALIASES = {"accel": "accel", "acc": "accel", "a": "accel",
                  "gyro": "gyro", "gyr": "gyro", "g": "gyro",
                  "mag": "mag", "m": "mag", "magnetometer": "mag"}


def normalise_chip(name: str) -> str:
    return re.sub(r"[^A-Z0-9]", "", str(name).upper())


def parse_chip_overrides(chip) -> dict:
    """``{"mag": "hmc5843"}``, ``"mag=hmc5843"``, ``["mag=hmc5843", "gyro=itg3205"]``
    or ``"mag=mychip:1234"`` (explicit LSB per unit) -> ``{sensor: (CHIP, scale)}``.
    A bare chip name (``"hmc5843"``) applies to the sensor it belongs to."""
    out = {}
    for part in option_parts(chip):
        if "=" in part:
            sensor, _, name = part.partition("=")
            sensor = SENSOR_ALIASES.get(sensor.strip().lower())
            if sensor is None:
                raise UserError(f"--chip {part}: sensor must be accel, gyro or mag")
        else:
            sensor, name = None, part
        name, _, scale_text = name.partition(":")
        chipname = normalise_chip(name)
        if scale_text:
            try:
                scale = float(scale_text)
            except ValueError:
                scale = float("nan")
            if not np.isfinite(scale) or scale <= 0:
                raise UserError(f"--chip {part}: scale must be a positive number of LSB per unit")
            if sensor is None:
                raise UserError(f"--chip {part}: give the sensor, e.g. mag={name}:{scale_text}")
            out[sensor] = (chipname, check_scale(sensor, scale, f"--chip {part}"))
            continue
        owners = [s for s, chips in CHIP_SCALES.items() if chipname in chips]
        if sensor is None:
            if len(owners) != 1:
                raise UserError(f"--chip {part}: say which sensor, e.g. mag={name}")
            sensor = owners[0]
        if chipname not in CHIP_SCALES[sensor]:
            known = ", ".join(c.lower() for c in CHIP_SCALES[sensor])
            raise UserError(f"--chip {part}: unknown {sensor} chip (known: {known}; "
                            f"or give the scale: {sensor}={name}:LSB_PER_UNIT)")
        out[sensor] = (chipname, CHIP_SCALES[sensor][chipname])
    return out


def _chips_for(names: dict) -> tuple[dict, dict]:
    chips = dict(NOMINAL_CHIPS)
    scales = dict(NOMINAL_SCALES)
    for sensor, name in names.items():
        chips[sensor] = name
        scales[sensor] = CHIP_SCALES[sensor][name]
    return chips, scales
