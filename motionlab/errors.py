"""Errors that mean "the input is wrong", as opposed to bugs.

The CLI turns an :class:`InputError` into one line on stderr and exit code 2; any other
exception is a bug (exit code 1, traceback with ``--debug``).
"""

from __future__ import annotations

from pathlib import Path


class InputError(Exception):
    """Bad input the user can fix.

    Parameters
    ----------
    message
        What is wrong, e.g. ``"7 columns, expected 10"``.
    path
        The file at fault, if any.
    where
        The place inside the file: ``"line 4812"``, ``"channel Acc_X"``, ``"key joints[0].distal"``.
    remedy
        What to do about it: ``"is the delimiter ';'?"``.
    """

    def __init__(
        self,
        message: str,
        path: str | Path | None = None,
        where: str | None = None,
        remedy: str | None = None,
    ) -> None:
        self.message = message
        self.path = None if path is None else Path(path)
        self.where = where
        self.remedy = remedy
        super().__init__(self.line())

    def line(self) -> str:
        """The one-line message: ``file place: what — remedy``."""
        head = " ".join(p for p in (self.path.name if self.path else None, self.where) if p)
        text = f"{head}: {self.message}" if head else self.message
        if self.remedy:
            text += f" — {self.remedy}"
        return text.replace("\n", " ")
