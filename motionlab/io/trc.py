"""TRC marker files (Motion Analysis / OpenSim track row column), tab- or comma-separated.

Layout::

    PathFileType  4  (X/Y/Z)  <name>
    DataRate  CameraRate  NumFrames  NumMarkers  Units  OrigDataRate  …
    100       100         652        51          mm     100           …
    Frame#    Time  ASISl  <empty>  <empty>  ASISr  …
                    X1     Y1       Z1       X2     …
    <optional blank line>
    1         0     733.7  80.98    191.87   651.7  …

Returned: one :class:`~motionlab.session.MarkerSet` named after the file with positions
(N, M, 3) in m (``Units`` ``mm``, ``cm`` or ``m``), NaN for empty or ``NaN`` cells (markers not
seen), time from the ``Time`` column in s, no residuals. A file with fewer rows than
``NumFrames`` (an excerpt, or a cut copy) is read with a warning in ``attrs["warnings"]``; a
last row the file ends inside (no line end, cells or decimals missing) is dropped with one.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from motionlab.errors import InputError
from motionlab.io import Recording
from motionlab.io.delimited import parse_table, read_lines, split_fields
from motionlab.session import MarkerSet
from motionlab.units import factor

FORMAT = "trc"

_HEADER_LINES = 5


def sniff(path: Path, head: bytes) -> bool:
    """A TRC file's first line starts with ``PathFileType``."""
    return head.lstrip(b"\xef\xbb\xbf").startswith(b"PathFileType")


def read(path: str | Path, options: dict[str, Any] | None = None) -> Recording:
    """Read the marker trajectories of a TRC file (m, NaN where missing)."""
    path = Path(path)
    lines = read_lines(path)
    if len(lines) <= _HEADER_LINES:
        raise InputError(
            f"the header ends after {len(lines)} lines (needs {_HEADER_LINES} and samples)",
            path,
            f"line {len(lines)}",
            "the file is truncated: export it again",
        )
    delim = "\t" if "\t" in lines[0] else ","
    keys = split_fields(lines[1], delim)
    values = split_fields(lines[2], delim)
    info = {k: v for k, v in zip(keys, values, strict=False) if k}
    for key in ("DataRate", "Units"):
        if not info.get(key):
            raise InputError(
                f"no {key} in the header", path, "lines 2-3", "export the TRC with its full header"
            )
    rate = _number(path, info["DataRate"], "DataRate")
    try:
        scale = factor(info["Units"], "length")
    except InputError as exc:
        raise InputError(exc.message, path, "line 3 (Units)", exc.remedy) from None

    names_row = split_fields(lines[3], delim)
    if len(names_row) < 5 or names_row[1].lower() != "time":
        raise InputError(
            "expected 'Frame#, Time, <marker names>'",
            path,
            "line 4",
            "export the TRC with its marker names row",
        )
    n_markers = len(names_row) // 3  # 2 + 3·M cells, the last two may be omitted
    while n_markers > 0 and not any(names_row[2 + 3 * (n_markers - 1) :]):
        n_markers -= 1  # trailing empty cells after the last marker
    labels = [names_row[2 + 3 * k] or f"M{k + 1:03d}" for k in range(n_markers)]
    table = parse_table(
        path, lines, _HEADER_LINES, header_rows=0, delimiter=delim, names=_names(labels),
        ragged=True,
    )  # fmt: skip
    # rows whose last markers are missing may stop early or carry empty trailing cells;
    # a row of nothing but delimiters is no frame
    framed = ~np.isnan(table.data).all(axis=1)
    data, rows = table.data[framed], table.lines[framed]
    warnings = list(table.notes)
    cut = _cut_last_row(lines, rows, delim)
    if cut:
        data = data[:-1]
        warnings.append(f"line {rows[-1]}: truncated last line ({cut}) dropped")
    n_frames = len(data)
    if "NumFrames" in info and _number(path, info["NumFrames"], "NumFrames") > n_frames:
        warnings.append(f"header announces {info['NumFrames']} frames, the file holds {n_frames}")
    if "NumMarkers" in info and _number(path, info["NumMarkers"], "NumMarkers") != n_markers:
        warnings.append(f"header announces {info['NumMarkers']} markers, names row has {n_markers}")
    time = data[:, 1]
    if np.isnan(time).any():
        time = (data[:, 0] - data[0, 0]) / rate
    attrs: dict[str, Any] = {"nominal_rate_hz": rate, "header": info}
    if warnings:
        attrs["warnings"] = warnings
    markers = MarkerSet(
        name=(options or {}).get("name") or path.stem,
        time=time,
        labels=labels,
        positions=data[:, 2:].reshape(n_frames, n_markers, 3) * scale,
        source_units={"positions": info["Units"]},
        attrs=attrs,
    )
    return Recording(markers=[markers], metadata={"trc_units": info["Units"]})


def _cut_last_row(lines: Any, rows: np.ndarray, delim: str) -> str:
    """How the file's last row is cut short when the file ends inside it (no line end): fewer
    cells than the row before, or its last cell with fewer decimals than that row's ("55,0."
    of "55,0.54", a time going backwards); ``""`` for a whole last row or a file that ends
    with a line end (a row that stops early there only lacks its last markers)."""
    if not lines.unended or len(rows) < 2 or rows[-1] != len(lines):
        return ""
    before, last = (split_fields(lines[int(k) - 1], delim) for k in rows[-2:])
    if len(last) < len(before):
        return f"{len(last)} of {len(before)} cells"
    a, b = last[-1], before[len(last) - 1]
    if a and b and len(a.partition(".")[2]) < len(b.partition(".")[2]):
        return f"'{a}' at the end of the file"
    return ""


def _names(labels: list[str]) -> list[str]:
    return ["Frame#", "Time"] + [f"{name}_{axis}" for name in labels for axis in "XYZ"]


def _number(path: Path, text: str, key: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not np.isfinite(value) or value <= 0:
        raise InputError(f"{key}={text!r}", path, "line 3", f"{key} must be a positive number")
    return value
