"""Logging a session: what arrives on the line, checked per mote and stored,
optionally guiding a person through poses or a rotation.

* ``link``   -- per-mote sequence tracking (gaps, duplicates, reordering,
  restarts) and the link counters;
* ``logger`` -- the logger loop: source -> decoded samples -> tracker ->
  store, reconnects, the guided flow's stop;
* ``guide``  -- the guided flows (80 static poses, rotation sweep) as state
  machines fed with samples.
"""
