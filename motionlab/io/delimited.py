"""Shared helpers for delimited text files: header/comment skipping, delimiter detection,
decimal comma, and numeric parsing that names the first bad line and column.

Conventions: line numbers in messages are 1-based, as an editor shows them; a parsed
:class:`Table` holds one float64 row per data line (empty and ``NaN`` fields → NaN) and the
file line number of every row, so readers can point at the line a problem comes from.

Speed: a file is read once, as bytes (:class:`~motionlab.io.textfile.TextFile`); only the
lines a reader looks at are decoded. :func:`parse_table` finds blank and comment lines with
array operations over the first byte of every line, and parses the numeric body with ONE
pandas C-parser call. Only when that call fails, or a row comes out short, are the fields of
the lines counted (again with array operations) to name the first bad line.
"""

from __future__ import annotations

import re
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from motionlab.errors import InputError, shorten
from motionlab.io.textfile import TextFile, read_lines

__all__ = [
    "COMMENT_PREFIXES", "DELIMITERS", "Table", "TextFile", "detect_delimiter", "find_line",
    "first_content_line", "is_comment", "nan_only", "parse_table", "read_lines",
    "require_values", "show_delimiter", "split_fields",
]  # fmt: skip

#: delimiters tried by :func:`detect_delimiter`, in order of preference
DELIMITERS = ("\t", ";", ",", " ")
COMMENT_PREFIXES = ("#", "//")


def show_delimiter(delimiter: str) -> str:
    """Printable name of a delimiter for messages (``'\\t'`` → ``tab``)."""
    return {"\t": "tab", " ": "space"}.get(delimiter, f"'{delimiter}'")


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


def detect_delimiter(header: str, rows: Sequence[str]) -> str:
    """The delimiter that splits ``header`` and every sample row into the same number (> 1)
    of fields; tab, semicolon, comma, then space are tried in that order. The last row may
    have fewer fields (a file cut short: the field check names it).

    A delimiter ending a line (``t;ax;ay;az;``, as some exporters write) does not count.
    Raises ``ValueError`` when none fits (the caller turns it into an :class:`InputError`).
    """
    for d in DELIMITERS:
        n = _n_fields(header, d)
        if max(n) > 1 and all(n & _n_fields(r, d) for r in rows[:-1]):
            if not rows or min(_n_fields(rows[-1], d)) <= max(n):
                return d
    # a damaged sample row must not hide the delimiter: the header and most rows agree on it
    for d in DELIMITERS:
        n = _n_fields(header, d)
        if max(n) > 1 and sum(bool(n & _n_fields(r, d)) for r in rows) > len(rows) / 2:
            return d
    raise ValueError("no delimiter fits")


def _n_fields(line: str, delimiter: str) -> set[int]:
    """Field counts of ``line`` split by ``delimiter``: as written, and without a delimiter that
    ends the line (an empty last field or not: a two-row header's first row may end in empty
    cells that mean something)."""
    line = line.rstrip("\r\n")
    if delimiter != " ":
        line = line.rstrip(" ")
    n = line.count(delimiter) + 1
    return {n, n - 1} if n > 1 and line.endswith(delimiter) else {n}


def ends_with_delimiter(line: str, delimiter: str) -> bool:
    """Whether ``line`` ends with ``delimiter`` (not a space: spaces are trimmed)."""
    return delimiter not in (" ", "whitespace") and line.rstrip().endswith(delimiter)


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
                f"no column '{shorten(name)}' (the header has "
                f"{shorten(', '.join(self.names), 160)})",
                self.path,
                f"line {len(self.preamble) + 1}",  # the header
                remedy="export the file again with the vendor's column names, or correct the "
                "header",
            ) from None

    def column(self, name: str) -> np.ndarray:
        return self.data[:, self.index(name)]

    def columns(self, names: Sequence[str]) -> np.ndarray:
        return self.data[:, [self.index(n) for n in names]]

    def block(self, columns: Sequence[str | int]) -> np.ndarray:
        """The columns (names or indices) as a view of ``data`` when they are adjacent and
        in order, else a copy: for arithmetic that makes its own copy anyway."""
        j = [c if isinstance(c, int) else self.index(c) for c in columns]
        if j == list(range(j[0], j[0] + len(j))):
            return self.data[:, j[0] : j[0] + len(j)]
        return self.data[:, j]


def _cut_short(last: str, before: str, delimiter: str, decimal: str) -> str:
    """The last field of ``last``, the final line of a file that ends without a line end,
    when it has fewer decimals than the same field of the line ``before`` (a file cut inside a
    number: "0." where the column writes "0.556448"); else ``""``. Files that end without a
    line end but whole (the DOT app's exports) keep their last line."""
    split = (lambda x: x.split()) if delimiter == "whitespace" else (lambda x: x.split(delimiter))
    a, b = split(last.strip()), split(before.strip())
    number = re.compile(rf"[-+]?\d+({re.escape(decimal)}\d*)?")  # no exponent, no NaN
    if not a or len(a) != len(b) or not all(number.fullmatch(f) for f in (a[-1], b[-1])):
        return ""
    digits = [len(f.partition(decimal)[2]) if decimal in f else 0 for f in (a[-1], b[-1])]
    return a[-1] if digits[0] < digits[1] else ""


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
    ragged: bool = False,
    end: int | None = None,
) -> Table:
    """Parse the numeric table of ``lines`` whose header starts at index ``header``.

    Parameters
    ----------
    path
        The file (for messages).
    lines
        The file's lines: a :class:`TextFile` (:func:`read_lines`, fast) or a list of strings.
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
    ragged
        Rows may stop early (missing trailing fields are NaN) or end with empty fields
        beyond the last column, as in TRC files.
    end
        0-based index of the line after the last one read (default: the end of the file).

    Raises :class:`InputError` naming the line and column for: no data rows, a wrong number
    of fields, text in a numeric column, a quote left open. A last line cut short — fewer
    fields, or a value cut off at the end of a file without a final line end — is dropped
    and noted instead; if it was the only data row, the error says the file is truncated.
    """
    path = Path(path)
    text = lines if isinstance(lines, TextFile) else TextFile.from_lines(path, lines)
    start = header + header_rows
    stop = len(text) if end is None else min(end, len(text))
    rows = np.arange(start, max(stop, start))
    rows = rows[~text.blank_or_comment(rows, comments)]
    if not len(rows):
        where = f"line {header + 1}" if header < len(text) else None
        if text.unended and start >= len(text):
            raise InputError(
                "no data rows after the header, which has no line end: truncated?",
                path,
                where,
                remedy="copy or export the file again",
            )
        raise InputError(
            "no data rows after the header",
            path,
            where,
            remedy="the export is empty: record again or check the export settings",
        )
    head = text[header : header + header_rows]
    sample = [text[i] for i in rows[:50].tolist()]
    if delimiter is None:
        try:
            delimiter = detect_delimiter(head[0] if head else sample[0], sample[:20])
        except ValueError:
            raise InputError(
                "cannot tell the delimiter (tab, ';', ',' or space)",
                path,
                f"line {header + 1}",
                remedy="give 'delimiter' in a column map",
            ) from None
    col_names = _column_names(head, sample[0], delimiter, names)
    # a header or rows ending in the delimiter ("t;ax;ay;az;"): an empty last field, not a column
    trailing = ends_with_delimiter(sample[0], delimiter) or any(
        ends_with_delimiter(h, delimiter) for h in head
    )
    if trailing and len(col_names) > 2 and not col_names[-1]:
        col_names = col_names[:-1]
    ncol = len(col_names)
    if ncol < 2:
        first = head[0] if head else sample[0]
        alt = next((d for d in DELIMITERS if d != delimiter and d in first.strip()), None)
        remedy = f"is the delimiter {show_delimiter(alt)}?" if alt else "give 'delimiter'"
        raise InputError(
            f"only 1 column with delimiter {show_delimiter(delimiter)}",
            path,
            f"line {header + 1}",
            remedy=remedy,
        )
    if decimal is None:
        decimal = "," if delimiter != "," and any("," in t for t in sample) else "."
    if decimal == delimiter:
        raise InputError(
            f"the decimal mark and the delimiter are both '{decimal}'",
            path,
            f"line {header + 1}",
            remedy="give 'decimal' or 'delimiter' in a column map",
        )
    parse = _Parse(text, delimiter, decimal, ncol, ragged, trailing)
    rows, df, notes = parse.checked(rows)
    data, text_cell = _to_float(df, decimal)
    if text_cell is not None:
        k, j, value = text_cell
        line = rows[k] + 1
        if k < len(rows) - 1 or not text.unended or line < len(text):
            raise InputError(
                f"'{shorten(value)}' in numeric column '{shorten(col_names[j])}'",
                path,
                f"line {line}",
                remedy="fix or delete the line, or check that the header matches the data",
            )
        # the file stops inside the last value ("-", "1.5e"): a truncated last line
        if k == 0:
            raise InputError(
                f"truncated: the only data row ends inside a value ('{shorten(value)}')",
                path,
                f"line {line}",
                remedy="the file ends inside its first data row: copy or export it again",
            )
        notes.append(f"line {line}: truncated last line ('{value}') dropped")
        rows, data = rows[:-1], data[:-1]
    elif text.unended and len(rows) > 1 and rows[-1] + 1 == len(text) and not notes:
        cut = _cut_short(text[rows[-1]], text[rows[-2]], delimiter, decimal)
        if cut:  # a number cut short still reads as one: "0." of "0.556448"
            notes.append(f"line {rows[-1] + 1}: truncated last line ('{cut}' at the end of the "
                         "file) dropped")  # fmt: skip
            rows, data = rows[:-1], data[:-1]
    return Table(path, col_names, data, rows + 1, delimiter, decimal, text[:header], notes)


def _column_names(
    head: list[str], first_row: str, delimiter: str, names: Sequence[str] | None
) -> list[str]:
    if not head:
        ncol = len(split_fields(first_row, delimiter))
        return list(names) if names is not None else [f"col{k}" for k in range(ncol)]
    cells = [split_fields(h, delimiter) for h in head]
    if len(cells) == 1:
        return cells[0]
    top, run = [], ""
    for cell in cells[0] + [""] * (len(cells[1]) - len(cells[0])):
        run = cell or run
        top.append(run)
    return [f"{a} {b}".strip() for a, b in zip(top, cells[1], strict=False)]


class _Parse:
    """The numeric body of a :class:`TextFile` through one pandas C-parser call, and the
    field counts that name a bad line when the parse fails or a row is short."""

    def __init__(
        self,
        text: TextFile,
        delimiter: str,
        decimal: str,
        ncol: int,
        ragged: bool,
        trailing: bool = False,
    ) -> None:
        self.text, self.delimiter, self.decimal = text, delimiter, decimal
        self.ncol, self.ragged, self.trailing = ncol, ragged, trailing

    def checked(self, rows: np.ndarray) -> tuple[np.ndarray, pd.DataFrame, list[str]]:
        """(rows kept, their values, notes); a short last row is dropped and noted."""
        if self.ragged:  # short rows are fine, longer ones only if their extra cells are empty
            counts = self.field_counts(rows)
            counts[(counts <= self.ncol) | self.empty_tails(rows, counts)] = self.ncol
            self.check_counts(rows, counts)
            return rows, self.read_or_fail(rows), []
        if self.trailing:  # lines may end in the delimiter: one empty field more is fine
            counts = self.field_counts(rows)
            counts[(counts == self.ncol + 1) & self.empty_tails(rows, counts)] = self.ncol
            rows, notes = self.check_counts(rows, counts)
            return rows, self.read_or_fail(rows), notes
        try:
            df = self.read(rows)
        except ValueError:  # pandas' ParserError: too many fields, a stray quote
            df = None
        if df is None or df.shape != (len(rows), self.ncol):
            rows, notes = self.check_counts(rows, self.field_counts(rows))
            return rows, self.read_or_fail(rows), notes
        short = np.flatnonzero(df.iloc[:, -1].isna().to_numpy())
        if not len(short):
            return rows, df, []
        counts = np.full(len(rows), self.ncol)
        counts[short] = self.field_counts(rows[short])
        kept, notes = self.check_counts(rows, counts)
        return kept, df.iloc[: len(kept)], notes

    def read_or_fail(self, rows: np.ndarray) -> pd.DataFrame:
        """:meth:`read` of rows whose fields were counted: a failure is named at its line."""
        try:
            df = self.read(rows)
        except ValueError as exc:
            raise self.unparsable(rows, str(exc)) from None
        if df.shape != (len(rows), self.ncol):
            raise self.unparsable(rows, "")
        return df

    def read(self, rows: np.ndarray) -> pd.DataFrame:
        ragged = {}
        if self.ragged or self.trailing:
            ragged = {"names": range(self.ncol), "usecols": range(self.ncol)}
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", pd.errors.DtypeWarning)
            return pd.read_csv(
                self.text.stream(rows),
                sep=r"\s+" if self.delimiter == "whitespace" else self.delimiter,
                header=None,
                decimal=self.decimal,
                quotechar='"',
                skip_blank_lines=False,
                encoding=self.text.encoding,
                engine="c",
                **ragged,
            )

    def field_counts(self, rows: np.ndarray) -> np.ndarray:
        """Number of fields of each line of ``rows``."""
        return self.text.count_per_line(rows, self.delimiter) + (self.delimiter != "whitespace")

    def empty_tails(self, rows: np.ndarray, counts: np.ndarray) -> np.ndarray:
        """Whether the fields after the first ``ncol`` of each line are all empty: the line
        ends with nothing but delimiters (and a CR) after its ``ncol``-th delimiter."""
        out = np.zeros(len(rows), dtype=bool)
        long = np.flatnonzero(counts > self.ncol)
        if not len(long) or self.delimiter == "whitespace":
            return out
        t, marks = self.text, self.text.marks(rows, self.delimiter)
        ends = t.ends[rows[long]]
        cut = marks[np.searchsorted(marks, t.starts[rows[long]]) + self.ncol - 1]
        cr = t.bytes[ends - 1] == 13
        out[long] = ends - cut - 1 == counts[long] - 1 - self.ncol + cr
        return out

    def check_counts(self, rows: np.ndarray, counts: np.ndarray) -> tuple[np.ndarray, list[str]]:
        bad = np.flatnonzero(counts != self.ncol)
        if not len(bad):
            return rows, []
        k = bad[0]
        line = int(rows[k]) + 1
        if k == len(rows) - 1 and counts[k] < self.ncol:
            if len(rows) == 1:
                raise InputError(
                    f"truncated: the only data row has {counts[k]} of {self.ncol} fields "
                    "(fewer than the header)",
                    self.text.path,
                    f"line {line}",
                    remedy="the file ends inside its first data row: copy or export it again",
                )
            note = f"line {line}: truncated last line ({counts[k]} of {self.ncol} columns) dropped"
            return rows[:-1], [note]
        alt = _suggest_delimiter(self.text[rows[k]], self.ncol, self.delimiter)
        if alt is not None:
            remedy = f"is the delimiter {show_delimiter(alt)}?"
        else:
            remedy = "the line is damaged: repair or delete it, or export the file again"
        raise InputError(
            f"{counts[k]} columns, expected {self.ncol}",
            self.text.path,
            f"line {line}",
            remedy=remedy,
        )

    def unparsable(self, rows: np.ndarray, message: str) -> InputError:
        """The error for a body that pandas cannot parse although every line has the right
        number of fields: at the first line with an odd number of quotes (a quote left open
        joins lines), else at the line pandas names."""
        odd = np.flatnonzero(self.text.count_per_line(rows, '"') % 2)
        m = re.search(r"line (\d+)", message)
        k = odd[0] if len(odd) else min(int(m.group(1)), len(rows)) - 1 if m else 0
        return InputError(
            "cannot split the line into fields (a quote left open?)",
            self.text.path,
            f"line {int(rows[k]) + 1}",
            remedy="repair the line, or export the file again",
        )


def _to_float(df: pd.DataFrame, decimal: str) -> tuple[np.ndarray, tuple[int, int, str] | None]:
    """The values as float64 (text → NaN), and (row, column, text) of the first cell that
    holds text instead of a number, if any."""
    first: tuple[int, int, str] | None = None
    for j in range(df.shape[1]):
        col = df.iloc[:, j]
        if col.dtype.kind in "fiub":
            continue
        raw = col.astype("string").str.strip()
        if decimal == ",":
            raw = raw.str.replace(",", ".", regex=False)
        num = pd.to_numeric(raw, errors="coerce")
        wrong = np.flatnonzero(raw.notna().to_numpy() & num.isna().to_numpy())
        if len(wrong) and (first is None or wrong[0] < first[0]):
            first = (int(wrong[0]), j, str(col.iloc[wrong[0]]))
        df.isetitem(j, num.to_numpy(dtype=float, na_value=np.nan))
    return df.to_numpy(dtype=float), first


def nan_only(table: Table, names: Sequence[str]) -> str | None:
    """The first of ``names`` whose column holds no number at all, or ``None``."""
    for n in names:
        if not np.isfinite(table.column(n)).any():
            return n
    return None


def require_values(table: Table, names: Sequence[str], channel: str) -> None:
    """Raise :class:`InputError` if any column of ``names`` (one channel) is NaN-only."""
    empty = nan_only(table, names)
    if empty is not None:
        raise InputError(
            f"channel {channel}: column '{empty}' has no values (all empty, NaN or ±inf)",
            table.path,
            f"column '{empty}'",
            remedy="re-export with this channel enabled, or leave it out of the column map",
        )
