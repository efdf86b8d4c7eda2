"""``python -m motionlab.cli``: the same as the ``motionlab`` command (e.g. from a source tree)."""

from motionlab.cli import entry

if __name__ == "__main__":
    entry()
