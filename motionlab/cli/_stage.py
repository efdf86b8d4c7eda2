"""What the stage commands (sync, calibrate, angles, metrics, validate) share."""

from __future__ import annotations

from motionlab.errors import InputError
from motionlab.session import Session


def refuse_to_redo(session: Session, path: str, stage: str, what: str, force: bool) -> None:
    """Raise when ``session`` (read from ``path``) already holds ``results[stage]`` and not
    ``force``: a stage is redone only on request."""
    if stage in session.results and not force:
        raise InputError(
            f"already holds {what}", path, f"results/{stage}", "add --force to redo it"
        )
