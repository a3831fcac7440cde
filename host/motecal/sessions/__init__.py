"""A session's data and where it is kept.

* ``session``  -- ``SessionData`` (rows of raw counts, times, labels, scales)
  and the units, chips and labels every later stage uses;
* ``still``    -- still detection and segmentation of a recording;
* ``store``    -- the database (sqlite, PostgreSQL, MySQL/MariaDB): sessions,
  samples, link statistics, calibrations; ``store_*`` its parts (the backend
  interface, one module per backend, the schema, the live writer);
* ``importer`` -- measured data files read (and the project CSV written) as
  sessions.
"""
