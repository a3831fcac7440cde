"""Calibration engine: the seed paper's evolutionary algorithm on identifiable
models, the whole board (accelerometer, gyroscope, magnetometer) in one run.

* ``models``   -- the ``paper`` (eqs. 1-5) and ``full`` model families with
  analytic Jacobians; the magnetometer gauge.
* ``ga``       -- the project's real-coded GA (vectorised over the population).
* ``fit``      -- GA on a per-pose reduction + least-squares polish on every
  sample; the Levenberg-Marquardt reference.
* ``eq6``      -- the paper's gyroscope fitness, evaluated and minimised exactly.
* ``gyro``     -- gyroscope bias; scale/misalignment from moves between poses.
* ``identify`` -- rank and identifiability from the Jacobian at the optimum.
* ``board``    -- ``calibrate_board``: one mote's session -> ``BoardCalibration``.
* ``result``   -- ``SensorCalibration`` / ``BoardCalibration`` and cal.json.
* ``gate``     -- the quality gate: one accept/reject decision with reasons.
* ``tables``   -- the paper's Tables I-III computed from a session.

The command is ``motecal.commands.calibrate``.
"""
from .board import calibrate_board  # noqa: F401
from .gate import GateDecision, GateLimits, decide  # noqa: F401
from .models import make_model  # noqa: F401
from .result import BoardCalibration, Param, SensorCalibration  # noqa: F401
