"""Model discrepancy: what the simulation gets wrong, the cause, the extended
model and its gain (``motecal diagnose``; see the README's section "Diagnosis").

* ``prepare``   -- per sensor: rows, still segments (poses), time blocks, noise;
* ``fitting``   -- nested models (calib's magnitude models + simulator terms),
  least squares, F / robust Wald tests;
* ``structure`` -- calibration-type causes: greedy nested selection, held-out gains;
* ``screens``   -- raw-reading causes: stale samples, saturation, motion;
* ``causes``    -- the documented vocabulary and detectability thresholds;
* ``gain``      -- the criterion (Bonferroni level, held-out check);
* ``extend``    -- the extended model as a simulator model file;
* ``compare``   -- the same session re-simulated, statistics side by side;
* ``regimes``   -- what a sensor's observations allow (poses, sweep, single, still);
* ``engine``    -- the four questions in order (``diagnose``);
* ``summary``   -- the text summary of a diagnosis;
* ``plots``     -- the ``--report`` pictures.

The command is ``motecal.commands.diagnose``; the hidden effects the tests and
the bench plant are in ``tests/plant.py``.
"""
from .causes import CAUSES  # noqa: F401
from .engine import Diagnosis, Finding, diagnose  # noqa: F401
