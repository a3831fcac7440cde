"""A session's data and where it is kept.

* ``session``  -- ``SessionData`` (rows of raw counts, times, labels, scales)
  and the units, chips and labels every later stage uses;
* ``still``    -- still detection and segmentation of a recording;
* ``store``    -- the database (sqlite or PostgreSQL): sessions, samples,
  link statistics, calibrations;
* ``importer`` -- measured data files read (and the project CSV written) as
  sessions.
"""
