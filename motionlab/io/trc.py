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
``NumFrames`` (an excerpt, or a cut copy) is read with a warning in ``attrs["warnings"]``.
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
    data = table.data[~np.isnan(table.data).all(axis=1)]

    warnings = list(table.notes)
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
