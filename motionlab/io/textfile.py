"""A text file read once as bytes and seen as a sequence of lines (:class:`TextFile`), with the
array operations over its bytes that the table parser (:mod:`motionlab.io.delimited`) needs: blank
and comment lines, and counts of a character per line — no Python loop over the lines.

Conventions: line indices are 0-based here (messages add 1); a line is what lies between two
``\\n`` (a ``\\r`` before it belongs to the line ending); ``rows`` arguments are ascending
arrays of line indices.
"""

from __future__ import annotations

import io
import operator
import os
from collections.abc import Iterator, Sequence
from pathlib import Path

import numpy as np

from motionlab.errors import InputError

_NEWLINE = 10
HEAD_CHECK = 65536  # bytes looked at for NUL before the whole file is read
_BLANK = np.zeros(256, dtype=bool)  # bytes skipped at the start of a line: space, tab, CR
_BLANK[[9, 13, 32]] = True
_SPACE = _BLANK.copy()  # bytes that separate fields of a "whitespace" delimited line
_SPACE[_NEWLINE] = True


class TextFile(Sequence[str]):
    """A text file held as bytes and seen as a sequence of lines, decoded when asked for.

    ``bytes`` is the content (uint8 array) without byte-order mark, ending with ``\\n``;
    ``starts``/``ends`` the offsets of every line's first byte and of its ``\\n``;
    ``unended`` whether the file's last line had no line end (as in a file cut short).
    ``text[i]`` is line ``i`` without its line ending; slices decode their lines in one go.
    """

    def __init__(self, path: str | Path, data: bytes | np.ndarray, encoding: str = "utf-8") -> None:
        b = np.frombuffer(data, dtype=np.uint8) if isinstance(data, bytes) else data
        ends = _positions(b, _NEWLINE)
        if not len(ends) and (b == 13).any():  # classic Mac line ends
            b = np.where(b == 13, np.uint8(_NEWLINE), b)
            ends = _positions(b, _NEWLINE)
        self.unended = bool(len(b)) and bool(b[-1] != _NEWLINE)
        if self.unended:  # a copy, but only for a file cut short (or written without one)
            b = np.append(b, np.uint8(_NEWLINE))
            ends = np.append(ends, len(b) - 1)
        self.path = Path(path)
        self.bytes = b
        self.encoding = encoding
        self.ends = ends
        self.starts = np.concatenate(([0], ends[:-1] + 1)).astype(np.int64)[: len(ends)]

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
            chunk = self._text(self.starts[rows.start], self.ends[rows.stop - 1])
            return [s.rstrip("\r") for s in chunk.split("\n")]
        i = operator.index(i)
        if i < 0:
            i += len(self)
        if not 0 <= i < len(self):
            raise IndexError("line index out of range")
        return self._text(self.starts[i], self.ends[i]).rstrip("\r")

    def __iter__(self) -> Iterator[str]:
        return (self[i] for i in range(len(self)))

    def _text(self, start: int, stop: int) -> str:
        return self.bytes[start:stop].tobytes().decode(self.encoding)

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

    def stream(self, rows: np.ndarray) -> io.RawIOBase:
        """The bytes of the lines ``rows`` as a binary file: without a copy when they follow
        each other, else joined."""
        b, breaks = self.bytes, np.flatnonzero(np.diff(rows) != 1)
        if not len(breaks):
            return _ArrayFile(b[self.starts[rows[0]] : self.ends[rows[-1]] + 1])
        firsts = self.starts[rows[np.r_[0, breaks + 1]]].tolist()
        lasts = (self.ends[rows[np.r_[breaks, len(rows) - 1]]] + 1).tolist()
        return _ArrayFile(np.concatenate([b[i:j] for i, j in zip(firsts, lasts, strict=True)]))


def _positions(b: np.ndarray, byte: int, block: int = 1 << 20) -> np.ndarray:
    """Offsets of ``byte`` in ``b``, a block at a time (the comparison stays in the cache)."""
    found = [np.flatnonzero(b[i : i + block] == byte) + i for i in range(0, len(b), block)]
    return np.concatenate(found) if found else np.zeros(0, dtype=np.intp)


class _ArrayFile(io.RawIOBase):
    """A read-only binary file over a uint8 array, for pandas to parse without a copy."""

    def __init__(self, data: np.ndarray) -> None:
        self._data, self._pos = data, 0

    def readable(self) -> bool:
        return True

    def readinto(self, buffer: bytearray | memoryview) -> int:
        n = min(len(buffer), len(self._data) - self._pos)
        memoryview(buffer).cast("B")[:n] = self._data[self._pos : self._pos + n]
        self._pos += n
        return n


def read_lines(path: str | Path) -> TextFile:
    """The file's lines (UTF-8 with or without BOM, else Latin-1; ``\\r\\n``, ``\\n`` or
    ``\\r`` line ends) as a :class:`TextFile`.

    Raises :class:`InputError` for a binary file (NUL bytes).
    """
    path = Path(path)
    binary = InputError(
        "binary file, not delimited text", path, remedy="export the recording as text (CSV)"
    )
    try:
        with open(path, "rb", buffering=0) as f:
            head = f.read(HEAD_CHECK)
            if head.startswith((b"\xff\xfe", b"\xfe\xff")):  # UTF-16's byte-order mark
                raise InputError("text in UTF-16, which motionlab does not read", path,
                                 remedy="save or export it as UTF-8 text (CSV)")  # fmt: skip
            if b"\x00" in head:  # the head first: never read a binary body
                raise binary
            f.seek(0)
            b = np.empty(os.fstat(f.fileno()).st_size, dtype=np.uint8)  # no bytes object
            view, n = memoryview(b), 0
            while n < len(b) and (got := f.readinto(view[n:])):  # a read may stop at 2 GiB
                n += got
            b = b[:n]
    except OSError as exc:
        raise InputError(
            f"cannot read the file ({exc.strerror})", path, remedy="check the path"
        ) from None
    nul = _positions(b, 0)
    if len(nul):  # text, then binary data: name the line where it starts
        line = int(np.count_nonzero(b[: nul[0]] == _NEWLINE)) + 1
        raise InputError(
            f"binary data (NUL bytes) from byte {nul[0]}",
            path,
            f"line {line}",
            "the file is damaged: copy or export it again",
        )
    if b[:3].tobytes() == b"\xef\xbb\xbf":
        b = b[3:]
    encoding = "utf-8"
    if len(b) and b.max() >= 0x80:
        try:
            b.tobytes().decode("utf-8")
        except UnicodeDecodeError:
            encoding = "latin-1"
    return TextFile(path, b, encoding)
