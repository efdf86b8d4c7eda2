"""Shared helpers for delimited text files: header/comment skipping, delimiter detection,
decimal comma, and numeric parsing that names the first bad line and column.

Conventions: line numbers in messages are 1-based, as an editor shows them; a parsed
:class:`Table` holds one float64 row per data line (empty and ``NaN`` fields → NaN) and the
file line number of every row, so readers can point at the line a problem comes from.
"""

from __future__ import annotations

import io
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from motionlab.errors import InputError

#: delimiters tried by :func:`detect_delimiter`, in order of preference
DELIMITERS = ("\t", ";", ",", " ")
COMMENT_PREFIXES = ("#", "//")


def show_delimiter(delimiter: str) -> str:
    """Printable name of a delimiter for messages (``'\\t'`` → ``tab``)."""
    return {"\t": "tab", " ": "space"}.get(delimiter, f"'{delimiter}'")


def read_lines(path: str | Path) -> list[str]:
    """The file's lines without line endings (UTF-8 with or without BOM, else Latin-1).

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
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        text = raw.decode("latin-1")
    return text.splitlines()


def is_comment(line: str, prefixes: Sequence[str] = COMMENT_PREFIXES) -> bool:
    """Whether ``line`` is blank or starts (after spaces) with one of ``prefixes``."""
    s = line.strip()
    return not s or any(s.startswith(p) for p in prefixes)


def first_content_line(
    lines: Sequence[str], start: int = 0, prefixes: Sequence[str] = COMMENT_PREFIXES
) -> int:
    """Index of the first line at or after ``start`` that is neither blank nor a comment."""
    for i in range(start, len(lines)):
        if not is_comment(lines[i], prefixes):
            return i
    return len(lines)


def find_line(lines: Sequence[str], predicate: Callable[[str], bool], limit: int = 200) -> int:
    """Index of the first of the first ``limit`` lines satisfying ``predicate``, or -1."""
    for i, line in enumerate(lines[:limit]):
        if predicate(line):
            return i
    return -1


def split_fields(line: str, delimiter: str) -> list[str]:
    """Fields of one line, stripped of surrounding spaces and quotes.

    ``delimiter="whitespace"`` splits on runs of spaces and tabs.
    """
    parts = line.split() if delimiter == "whitespace" else line.split(delimiter)
    return [p.strip().strip('"').strip() for p in parts]


def _count_fields(texts: Sequence[str], delimiter: str) -> np.ndarray:
    if delimiter == "whitespace":
        return np.fromiter((len(t.split()) for t in texts), int, len(texts))
    return np.fromiter((t.count(delimiter) for t in texts), int, len(texts)) + 1


def detect_delimiter(header: str, rows: Sequence[str]) -> str:
    """The delimiter that splits ``header`` and every sample row into the same number (> 1)
    of fields; tab, semicolon, comma, then space are tried in that order.

    Raises ``ValueError`` when none fits (the caller turns it into an :class:`InputError`).
    """
    for d in DELIMITERS:
        n = header.count(d) + 1
        if n > 1 and all(r.count(d) + 1 == n for r in rows):
            return d
    # a damaged sample row must not hide the delimiter: the header and most rows agree on it
    for d in DELIMITERS:
        n = header.count(d) + 1
        if n > 1 and sum(r.count(d) + 1 == n for r in rows) > len(rows) / 2:
            return d
    raise ValueError("no delimiter fits")


def _suggest_delimiter(line: str, ncol: int, current: str) -> str | None:
    for d in DELIMITERS:
        if d != current and line.count(d) + 1 == ncol:
            return d
    return None


@dataclass
class Table:
    """Numeric content of a delimited text file.

    ``data`` is (N, C) float64 with NaN for empty or ``NaN`` fields; ``lines`` the 1-based file
    line of each row; ``preamble`` the lines before the header; ``notes`` what was repaired
    (e.g. a truncated last line dropped).
    """

    path: Path
    names: list[str]
    data: np.ndarray
    lines: np.ndarray
    delimiter: str
    decimal: str = "."
    preamble: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    def has(self, name: str) -> bool:
        return name in self.names

    def index(self, name: str) -> int:
        try:
            return self.names.index(name)
        except ValueError:
            raise InputError(
                f"no column '{name}'",
                self.path,
                remedy=f"columns are {', '.join(self.names)}",
            ) from None

    def column(self, name: str) -> np.ndarray:
        return self.data[:, self.index(name)]

    def columns(self, names: Sequence[str]) -> np.ndarray:
        return self.data[:, [self.index(n) for n in names]]


def parse_table(
    path: str | Path,
    lines: Sequence[str],
    header: int,
    *,
    header_rows: int = 1,
    delimiter: str | None = None,
    decimal: str | None = None,
    names: Sequence[str] | None = None,
    comments: Sequence[str] = COMMENT_PREFIXES,
) -> Table:
    """Parse the numeric table of ``lines`` whose header starts at index ``header``.

    Parameters
    ----------
    path
        The file (for messages).
    lines
        All lines of the file (:func:`read_lines`).
    header
        0-based index of the first header line (of the first data line if ``header_rows=0``).
    header_rows
        0 (no header: ``names`` or ``col0, col1, …``), 1, or 2 (names joined as
        ``"<row 1> <row 2>"``, the first row carried forward over empty cells, as in
        exports that write a sensor name above its channels).
    delimiter
        One of ``"\\t" ";" "," " "`` or ``"whitespace"``; detected when ``None``.
    decimal
        ``"."`` or ``","``; ``None`` detects a decimal comma when the delimiter is not a comma.
    comments
        Line prefixes of comment lines skipped among the data rows.

    Raises :class:`InputError` naming the line and column for: no data rows, a wrong number
    of fields (a short last line is dropped and noted instead), text in a numeric column.
    """
    path = Path(path)
    start = header + header_rows
    body = [(i + 1, t) for i, t in enumerate(lines[start:], start) if not is_comment(t, comments)]
    if not body:
        where = f"line {header + 1}" if header < len(lines) else None
        raise InputError(
            "no data rows after the header",
            path,
            where,
            remedy="the export is empty: record again or check the export settings",
        )
    lineno = np.array([b[0] for b in body])
    texts = [b[1].rstrip("\r") for b in body]
    head = [lines[header + k] for k in range(header_rows)]
    if delimiter is None:
        try:
            delimiter = detect_delimiter(head[0] if head else texts[0], texts[:20])
        except ValueError:
            raise InputError(
                "cannot tell the delimiter (tab, ';', ',' or space)",
                path,
                f"line {header + 1}",
                remedy="give 'delimiter' in a column map",
            ) from None
    if head:
        rows = [split_fields(h, delimiter) for h in head]
        if len(rows) == 2:
            top, run = [], ""
            for cell in rows[0] + [""] * (len(rows[1]) - len(rows[0])):
                run = cell or run
                top.append(run)
            col_names = [f"{a} {b}".strip() for a, b in zip(top, rows[1], strict=False)]
        else:
            col_names = rows[0]
    else:
        ncol0 = len(split_fields(texts[0], delimiter))
        col_names = list(names) if names is not None else [f"col{k}" for k in range(ncol0)]
    ncol = len(col_names)
    if ncol < 2:
        first = head[0] if head else texts[0]
        alt = next((d for d in DELIMITERS if d != delimiter and d in first.strip()), None)
        remedy = f"is the delimiter {show_delimiter(alt)}?" if alt else "give 'delimiter'"
        raise InputError(
            f"only 1 column with delimiter {show_delimiter(delimiter)}",
            path,
            f"line {header + 1}",
            remedy=remedy,
        )
    notes: list[str] = []
    counts = _count_fields(texts, delimiter)
    bad = np.flatnonzero(counts != ncol)
    if len(bad) and bad[0] == len(texts) - 1 and counts[-1] < ncol:
        notes.append(
            f"line {lineno[-1]}: truncated last line ({counts[-1]} of {ncol} columns) dropped"
        )
        texts, lineno, bad = texts[:-1], lineno[:-1], bad[:-1]
        if not texts:
            raise InputError(
                "no complete data row after the header",
                path,
                f"line {header + 1}",
                remedy="the export is empty or damaged: export it again",
            )
    if len(bad):
        k = bad[0]
        alt = _suggest_delimiter(texts[k], ncol, delimiter)
        if alt is not None:
            remedy = f"is the delimiter {show_delimiter(alt)}?"
        else:
            remedy = "the line is damaged: repair or delete it, or export the file again"
        raise InputError(
            f"{counts[k]} columns, expected {ncol}", path, f"line {lineno[k]}", remedy=remedy
        )
    if decimal is None:
        decimal = "," if delimiter != "," and any("," in t for t in texts[:50]) else "."
    data = _to_float(path, texts, lineno, col_names, delimiter, decimal)
    return Table(path, col_names, data, lineno, delimiter, decimal, list(lines[:header]), notes)


def _to_float(
    path: Path,
    texts: list[str],
    lineno: np.ndarray,
    col_names: list[str],
    delimiter: str,
    decimal: str,
) -> np.ndarray:
    """Vectorised numeric parse (pandas C parser); text in a numeric column → InputError."""
    sep = r"\s+" if delimiter == "whitespace" else delimiter
    df = pd.read_csv(
        io.StringIO("\n".join(texts)),
        sep=sep,
        header=None,
        names=range(len(col_names)),
        decimal=decimal,
        skip_blank_lines=False,
        quotechar='"',
        engine="c",
        low_memory=False,
    )
    for j in range(df.shape[1]):
        col = df[j]
        if col.dtype.kind in "fiub":
            continue
        raw = col.astype("string").str.strip()
        if decimal == ",":
            raw = raw.str.replace(",", ".", regex=False)
        num = pd.to_numeric(raw, errors="coerce")
        wrong = np.flatnonzero(raw.notna().to_numpy() & num.isna().to_numpy())
        if len(wrong):
            k = wrong[0]
            raise InputError(
                f"'{col.iloc[k]}' in numeric column '{col_names[j]}'",
                path,
                f"line {lineno[k]}",
                remedy="fix or delete the line, or check that the header matches the data",
            )
        df[j] = num
    return df.to_numpy(dtype=float)


def nan_only(table: Table, names: Sequence[str]) -> str | None:
    """The first of ``names`` whose column holds no number at all, or ``None``."""
    for n in names:
        if np.all(np.isnan(table.column(n))):
            return n
    return None


def require_values(table: Table, names: Sequence[str], channel: str) -> None:
    """Raise :class:`InputError` if any column of ``names`` (one channel) is NaN-only."""
    empty = nan_only(table, names)
    if empty is not None:
        raise InputError(
            f"channel {channel}: column '{empty}' has no values (all empty or NaN)",
            table.path,
            f"column '{empty}'",
            remedy="re-export with this channel enabled, or leave it out of the column map",
        )
