"""A calibration to a mote (``motecal upload``): cal.json -> the mote's
fixed-point set -> fragments, commit, read-back, sample check and the wait
until the mote reports the set stored in its EEPROM, over the BaseStation.

* ``calfile``  -- cal.json read and checked (``CalFile``, ``load_cal``), the
  set built and checked by the mote's own C code (``build_set``, ``check_set``);
* ``link``     -- one mote over a source: serial acks, replies, repeats;
* ``uploader`` -- the protocol steps (``Uploader``, ``upload_cal``) and the
  verification;
* ``describe`` -- the set in force and a dry run as text lines.
"""
from .calfile import (CalFile, build_set, cal_from_board, check_set, load_cal,  # noqa: F401
                      mote_check)
from .describe import dry_run_lines, show_lines  # noqa: F401
from .link import (SERIAL_ACK_TIMEOUT, SERIAL_RETRIES, Link, LinkStats,  # noqa: F401
                   NoAnswer, NullProgress, PortLost, Rejected, UploadFailed)
from .uploader import (MAX_VERSION, OLD_IMAGE_WAIT, STORE_WAIT, VERIFY_MESSAGES,  # noqa: F401
                       CommittedNotFinished, InForce, InForceChanged, NoTemperature,
                       NotStored, Options, Result, StoreCheck,
                       Uploader, check_cal, describe_flags, flags_for, fragments, next_version,
                       sensor_names, summary, upload_cal)
