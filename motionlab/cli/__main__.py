"""``python -m motionlab.cli``: the same as the ``motionlab`` command (e.g. from a source tree)."""

from motionlab.cli import main

if __name__ == "__main__":
    main()
