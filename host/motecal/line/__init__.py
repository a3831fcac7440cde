"""The serial line from the BaseStation: bytes -> frames -> messages.

* ``protocol`` -- framing (HDLC-like, CRC), the AM messages of
  ``tinyos/NineDofMsg.h``, encoders and decoders;
* ``samples``  -- many sample messages decoded at once into arrays;
* ``sources``  -- where bytes come from: serial ports, pyserial URLs,
  SerialForwarder, recorded files (``parse_port``, ``open_source``).
"""
