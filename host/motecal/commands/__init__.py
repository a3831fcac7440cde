"""The ``motecal`` command line: the edge of the package.

* ``main``  -- the dispatcher (``motecal`` / ``python -m motecal``);
* ``args``  -- argument types and help text the subcommands share;
* one module per subcommand, each providing ``register(subparsers)``:
  ``sim``, ``log``, ``sessions``, ``export``, ``import_``, ``calibrate``,
  ``upload``, ``diagnose``, ``report``;
* screens: ``log_screen`` (the logger's display and key reader),
  ``upload_screen`` (upload progress).

Engines never import from here; modules here import the engines.
"""
