"""The commands that take the controller onto a board: ``codegen``, ``pil``, ``hil``, ``flash``
and ``commission`` (the rig's whole path, excite to on-board run)."""
