"""A text file read once as bytes and seen as a sequence of lines (:class:`TextFile`), with the
array operations over its bytes that the table parser (:mod:`motionlab.io.text`) needs: blank
and comment lines, and counts of a character per line — no Python loop over the lines.

Conventions: line indices are 0-based here (messages add 1); a line is what lies between two
``\\n`` (a ``\\r`` before it belongs to the line ending); ``rows`` arguments are ascending
arrays of line indices.
"""

from __future__ import annotations

import io
import operator
from collections.abc import Iterator, Sequence
from pathlib import Path

import numpy as np

from motionlab.errors import InputError

_NEWLINE = 10
_BLANK = np.zeros(256, dtype=bool)  # bytes skipped at the start of a line: space, tab, CR
_BLANK[[9, 13, 32]] = True
_SPACE = _BLANK.copy()  # bytes that separate fields of a "whitespace" delimited line
_SPACE[_NEWLINE] = True


class TextFile(Sequence[str]):
    """A text file held as bytes and seen as a sequence of lines, decoded when asked for.

    ``raw`` is the content without byte-order mark, ending with ``\\n``; ``starts``/``ends``
    the byte offsets of every line's first byte and of its ``\\n``; ``unended`` whether the
    file's last line had no line end (as in a file cut short). ``text[i]`` is line ``i``
    without its line ending; slices decode their lines in one go.
    """

    def __init__(self, path: str | Path, raw: bytes, encoding: str = "utf-8") -> None:
        self.unended = bool(raw) and not raw.endswith(b"\n")
        if self.unended:
            raw += b"\n"
        self.path = Path(path)
        self.raw = raw
        self.encoding = encoding
        self.bytes = np.frombuffer(raw, dtype=np.uint8)
        self.ends = np.flatnonzero(self.bytes == _NEWLINE)
        self.starts = np.concatenate(([0], self.ends[:-1] + 1)).astype(np.int64)

    @classmethod
    def from_lines(cls, path: str | Path, lines: Sequence[str]) -> TextFile:
        """A :class:`TextFile` of ``lines`` (strings without line endings)."""
        return cls(path, "\n".join(lines).encode("utf-8"), "utf-8")

    def __len__(self) -> int:
        return len(self.ends)

    def __getitem__(self, i: int | slice) -> str | list[str]:  # type: ignore[override]
        if isinstance(i, slice):
            rows = range(len(self))[i]
            if rows.step != 1 or not rows:
                return [self[k] for k in rows]
            chunk = self.raw[self.starts[rows.start] : self.ends[rows.stop - 1]]
            return [s.rstrip("\r") for s in chunk.decode(self.encoding).split("\n")]
        i = operator.index(i)
        if i < 0:
            i += len(self)
        if not 0 <= i < len(self):
            raise IndexError("line index out of range")
        return self.raw[self.starts[i] : self.ends[i]].decode(self.encoding).rstrip("\r")

    def __iter__(self) -> Iterator[str]:
        return (self[i] for i in range(len(self)))

    def blank_or_comment(self, rows: np.ndarray, prefixes: Sequence[str]) -> np.ndarray:
        """Which of the lines ``rows`` are blank or start (after blanks) with one of
        ``prefixes``; only lines whose first byte is a blank or a prefix's first byte are
        looked into further."""
        out = np.zeros(len(rows), dtype=bool)
        if not len(rows):
            return out
        codes = [np.frombuffer(p.encode(self.encoding, "replace"), np.uint8) for p in prefixes]
        codes = [c for c in codes if len(c)]
        lead = _SPACE.copy()
        lead[[c[0] for c in codes]] = True
        b = self.bytes
        suspect = np.flatnonzero(lead[b[self.starts[rows]]])
        if not len(suspect):
            return out
        pos = self.starts[rows[suspect]]
        moving = np.flatnonzero(_BLANK[b[pos]])
        while len(moving):  # step over the indentation, one byte per round for all lines
            pos[moving] += 1
            moving = moving[_BLANK[b[pos[moving]]]]
        hit = b[pos] == _NEWLINE
        last = len(b) - 1
        for c in codes:
            match = np.ones(len(pos), dtype=bool)
            for k, byte in enumerate(c):
                match &= b[np.minimum(pos + k, last)] == byte
            hit |= match
        out[suspect[hit]] = True
        return out

    def marks(self, rows: np.ndarray, char: str) -> np.ndarray:
        """Byte offsets of ``char`` (for ``"whitespace"``: of the first byte of every field
        separated by blanks) in the lines ``rows[0]`` to ``rows[-1]``, in one pass."""
        lo, hi = self.starts[rows[0]], self.ends[rows[-1]] + 1
        chunk = self.bytes[lo:hi]
        if char == "whitespace":
            space = _SPACE[chunk]
            return np.flatnonzero(~space & np.r_[True, space[:-1]]) + lo
        return np.flatnonzero(chunk == ord(char)) + lo

    def count_per_line(self, rows: np.ndarray, char: str) -> np.ndarray:
        """How many :meth:`marks` of ``char`` each line of ``rows`` holds."""
        marks = self.marks(rows, char)
        return np.searchsorted(marks, self.ends[rows]) - np.searchsorted(marks, self.starts[rows])

    def stream(self, rows: np.ndarray) -> io.BytesIO:
        """The bytes of the lines ``rows`` as a file: without a copy when they run to the end
        of the file, as one slice when they follow each other, else joined."""
        breaks = np.flatnonzero(np.diff(rows) != 1)
        if not len(breaks):
            if rows[-1] == len(self) - 1:
                f = io.BytesIO(self.raw)  # shares the bytes
                f.seek(self.starts[rows[0]])
                return f
            return io.BytesIO(self.raw[self.starts[rows[0]] : self.ends[rows[-1]] + 1])
        firsts = self.starts[rows[np.r_[0, breaks + 1]]].tolist()
        lasts = (self.ends[rows[np.r_[breaks, len(rows) - 1]]] + 1).tolist()
        return io.BytesIO(b"".join(self.raw[a:b] for a, b in zip(firsts, lasts, strict=True)))


def read_lines(path: str | Path) -> TextFile:
    """The file's lines (UTF-8 with or without BOM, else Latin-1; ``\\r\\n``, ``\\n`` or
    ``\\r`` line ends) as a :class:`TextFile`.

    Raises :class:`InputError` for a binary file (NUL bytes).
    """
    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise InputError(
            f"cannot read the file ({exc.strerror})", path, remedy="check the path"
        ) from None
    if b"\0" in raw[:65536]:
        raise InputError(
            "binary file, not delimited text", path, remedy="export the recording as text (CSV)"
        )
    raw = raw.removeprefix(b"\xef\xbb\xbf")
    encoding = "utf-8"
    if not raw.isascii():
        try:
            raw.decode("utf-8")
        except UnicodeDecodeError:
            encoding = "latin-1"
    if b"\n" not in raw and b"\r" in raw:  # classic Mac line ends
        raw = raw.replace(b"\r", b"\n")
    return TextFile(path, raw, encoding)
