"""Model discrepancy: what the simulation gets wrong, the cause, the extended
model and its gain (``motecal diagnose``; see the README's section "Diagnosis").

* ``engine``     -- ``diagnose``: one function per stage (observe, screen,
  structure, test, name, extend, compare) and the state between them;
* ``result``     -- ``Finding`` and ``Diagnosis`` and their JSON;
* ``prepare``    -- per sensor: rows, still segments (poses), time blocks, noise;
* ``regimes``    -- what a sensor's observations allow (poses, sweep, single,
  still) and the plan of tests;
* ``screens``    -- raw-reading causes: stale samples, saturation, motion;
* ``fitting``    -- nested models (calib's magnitude models + simulator terms),
  least squares, F / robust Wald tests;
* ``structure``  -- calibration-type causes: greedy nested selection, held-out gains;
* ``turns``      -- the gyroscope's hold means with the tremor's turn taken out;
* ``terms``      -- a kept fitted term as a finding (evidence, simulator parameters);
* ``randomwalk`` -- a bias random walk: kriged drift gain, or a bias_drift of its own;
* ``leftover``   -- the scatter left after the kept terms (field disturbance,
  unexplained, a sweep's outliers);
* ``tilt``       -- a drift in one orientation: the board tilting or a bias drift;
* ``thermal``    -- temperature or time;
* ``causes``     -- the documented vocabulary and detectability thresholds;
* ``gain``       -- the criterion (Bonferroni level, held-out check);
* ``extend``     -- the starting and extended models as simulator model files;
* ``compare``    -- the same session re-simulated, statistics side by side;
* ``summary``    -- the text summary of a diagnosis;
* ``plots``      -- the ``--report`` pictures.

The command is ``motecal.commands.diagnose``; the hidden effects the tests and
the bench plant are in ``tests/plant.py``.
"""
from .causes import CAUSES  # noqa: F401
from .engine import Diagnosis, Finding, diagnose  # noqa: F401
