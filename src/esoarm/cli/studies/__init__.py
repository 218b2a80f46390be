"""The commands that study a loop beyond one run: ``sweep`` and ``tune``, ``analyze``,
``arm-study``, ``compare`` (the ADRC forms side by side) and ``learn-map``."""
