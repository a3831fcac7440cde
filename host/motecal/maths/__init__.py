"""Numerics every layer shares, no I/O.

* ``sphere`` -- directions on the unit sphere: unit vectors, angles, evenly
  spread directions, coverage of the sphere, distinct directions.
* ``stats``  -- Allan deviation.
"""
