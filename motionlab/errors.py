"""Errors that mean "the input is wrong", as opposed to bugs.

The CLI turns an :class:`InputError` into one line on stderr and exit code 2; any other
exception is a bug (exit code 1, traceback with ``--debug``).
"""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path

#: longest part of a message (what, place, remedy, file name) before it is cut with "…"
PART_MAX = 1000
#: longest echo of a cell or value from the input (see :func:`shorten`)
CELL_MAX = 80
_UNPRINTABLE = re.compile(r"[\x00-\x1f\x7f-\x9f\u2028\u2029\ufeff]")


def shorten(value: object, limit: int = CELL_MAX) -> str:
    """``value`` as text fit to echo in a one-line message: non-printable characters escaped
    (``\\x00``) and cut to ``limit`` characters with ``…``."""
    text = _UNPRINTABLE.sub(lambda m: repr(m.group())[1:-1], str(value))
    return text if len(text) <= limit else text[: limit - 1] + "…"


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
        What to do about it: ``"is the delimiter ';'?"``. The library names its own function
        arguments here (``"pass force=True to replace it"``), never a command-line flag.
    argument
        The function argument(s) the error or its remedy is about (``"force"``, ``("duration",
        "rate")``), spelled in the text as ``name=value``, ``name=True`` or ``argument name``;
        the CLI rewrites those into its flags (``motionlab.cli.flags``).
    """

    def __init__(
        self,
        message: str,
        path: str | Path | None = None,
        where: str | None = None,
        remedy: str | None = None,
        argument: str | tuple[str, ...] | None = None,
    ) -> None:
        self.message = message
        self.arguments: tuple[str, ...] = (
            () if argument is None else (argument,) if isinstance(argument, str) else argument
        )
        self.path = None if path is None else Path(path)
        self.where = where
        self.remedy = remedy
        super().__init__(self.line())

    def respelled(self, spell: Callable[[str, str | None], str | None]) -> InputError:
        """The error with each of its arguments spelled for another interface: ``name=value``,
        ``name=True`` and ``argument name`` become ``spell(name, value)`` (``value`` ``None``
        for ``argument name``); where ``spell`` returns ``None`` the text is kept. The CLI
        spells flags (``motionlab.cli.flags``), ``batch`` its manifest keys."""
        if not self.arguments:
            return self

        def fix(text: str | None) -> str | None:
            for name in self.arguments if text else ():
                text = re.sub(
                    rf"\b{name}=('[^']*'|[^\s,;)]*)",
                    lambda m, name=name: spell(name, m.group(1)) or m.group(0),
                    text,
                )
                text = re.sub(
                    rf"\bargument {name}\b",
                    lambda m, name=name: spell(name, None) or m.group(0),
                    text,
                )
            return text

        return InputError(fix(self.message) or self.message, self.path, fix(self.where),
                          fix(self.remedy))  # fmt: skip

    def __reduce__(self) -> tuple:
        """Pickled with its parts (raised in a child process, :mod:`motionlab.isolated`)."""
        parts = (self.message, self.path, self.where, self.remedy, self.arguments or None)
        return (type(self), parts)

    def line(self) -> str:
        """The one-line message: ``file place: what — remedy``."""
        name = self.path.name if self.path else None
        head = " ".join(shorten(p, PART_MAX) for p in (name, self.where) if p)
        message = shorten(self.message, PART_MAX)
        text = f"{head}: {message}" if head else message
        if self.remedy:
            text += f" — {shorten(self.remedy, PART_MAX)}"
        return text
