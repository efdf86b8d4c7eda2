"""``python -m motionlab``: the ``motionlab`` command (for a source tree that is not installed)."""

from motionlab.cli import entry

entry()
