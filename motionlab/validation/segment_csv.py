"""A reference of segment orientations from a CSV file (optical rigid bodies, another system's
model output), read as a :class:`~motionlab.session.MarkerSet` of rigid bodies.

Format (comma, semicolon or tab separated; ``#`` comment lines allowed)::

    time,thigh_r_qw,thigh_r_qx,thigh_r_qy,thigh_r_qz,shank_r_qw,shank_r_qx,shank_r_qy,shank_r_qz
    0.000,0.9990,0.0100,0.0400,0.0020,0.9950,...

- ``time`` (or ``time_s``) in seconds on the reference's own clock: any origin and rate (the
  validation's sync finds the offset and drift to the IMU clock); strictly increasing.
- Per segment four columns ``<segment>_qw``, ``_qx``, ``_qy``, ``_qz`` (the order in the file
  does not matter): a Hamilton quaternion mapping the segment frame into the reference's lab
  frame (any lab frame: the alignment finds it). The segment is named as in the protocol
  (``thigh_r``) or as the IMU label. Quaternions are normalised; an empty cell or a zero
  quaternion is a gap (NaN).
- The segment frames are the anatomical ones (ISB: x anterior, y up along the segment, z to
  the right) unless ``frames="body"``: then they are arbitrary body frames, and the angles of
  the reference are built with the IMU calibration's segment frames (as for rigid bodies of
  a marker map without ``segment_frame``).
"""

from __future__ import annotations

import csv
import re
from pathlib import Path

import numpy as np
import pandas as pd

from motionlab import rotations as rot
from motionlab.errors import InputError
from motionlab.session import MarkerSet
from motionlab.validation.markermap import MarkerMap, SegmentMap

COMPONENTS = ("qw", "qx", "qy", "qz")
_QUAT = re.compile(r"^(?P<seg>.+)_(?P<c>q[wxyz])$", re.IGNORECASE)
FRAMES = ("anatomical", "body")
#: the median time step (s) of a reference: a camera at 10 kHz to 1 Hz
MIN_STEP_S, MAX_STEP_S = 1e-4, 1.0


def is_segment_csv(path: str | Path) -> bool:
    """Whether ``path`` is a text file whose header names ``<segment>_qw`` columns."""
    path = Path(path)
    if path.suffix.lower() not in (".csv", ".txt", ".tsv"):
        return False
    try:
        with path.open(encoding="utf-8-sig", errors="replace") as f:
            for line in f:
                if line.strip() and not line.lstrip().startswith("#"):
                    return bool(re.search(r"_qw\b", line, re.IGNORECASE))
    except OSError:
        return False
    return False


def read_segment_csv(path: str | Path, name: str = "segments") -> MarkerSet:
    """The segment orientations of ``path`` (see the module docstring) as rigid bodies named
    after the segments (``rigid_bodies[segment]`` (N, 4), segment → lab)."""
    path = Path(path)
    if not path.is_file():
        raise InputError("no such reference file", path, remedy="check the path")
    try:
        table = pd.read_csv(
            path,
            sep=None,
            engine="python",
            comment="#",
            skipinitialspace=True,
            encoding="utf-8-sig",
        )  # as Excel saves it, with a byte-order mark
    except (pd.errors.ParserError, pd.errors.EmptyDataError, csv.Error, UnicodeDecodeError) as exc:
        raise InputError(
            f"cannot be read as CSV ({exc})".splitlines()[0],
            path,
            remedy="write one header line and comma-separated numbers",
        ) from None
    columns = {str(c).strip(): c for c in table.columns}
    # pandas reads a repeated header name as name.1: two columns claim one quantity
    twice = [c for c in columns if re.fullmatch(r".+\.\d+", c) and c.rsplit(".", 1)[0] in columns]
    if twice:
        raise InputError(
            f"column {twice[0].rsplit('.', 1)[0]} appears more than once",
            path,
            "header",
            "keep one column per name",
        )
    tcol = next((columns[c] for c in ("time", "time_s", "Time") if c in columns), None)
    if tcol is None:
        raise InputError(
            "has no time column", path, "header", "name the first column 'time' (seconds)"
        )
    found: dict[str, dict[str, str]] = {}
    for c in columns:
        m = _QUAT.match(c)
        if m:
            found.setdefault(m["seg"], {})[m["c"].lower()] = columns[c]
    if not found:
        raise InputError(
            "has no quaternion columns",
            path,
            "header",
            "name them <segment>_qw, <segment>_qx, <segment>_qy, <segment>_qz",
        )
    for seg, comps in found.items():
        missing = [c for c in COMPONENTS if c not in comps]
        if missing:
            raise InputError(
                f"segment '{seg}' lacks {', '.join(f'{seg}_{c}' for c in missing)}",
                path,
                "header",
                "give all four components qw, qx, qy, qz",
            )
    time = pd.to_numeric(table[tcol], errors="coerce").to_numpy(float)
    bad = np.flatnonzero(~np.isfinite(time))
    if len(bad):
        raise InputError(
            "time is not a number",
            path,
            f"data row {bad[0] + 1}",
            "every row needs a time in seconds",
        )
    steps = np.diff(time)
    if len(time) < 10 or (steps <= 0).any():
        row = int(np.argmax(steps <= 0)) + 2 if len(steps) and (steps <= 0).any() else 1
        raise InputError(
            "time must increase strictly over at least 10 rows",
            path,
            f"data row {row}",
            "sort the rows by time; drop repeats",
        )
    step = float(np.median(steps))
    if not MIN_STEP_S <= step <= MAX_STEP_S:  # a camera samples at 1 Hz-10 kHz
        raise InputError(
            f"time steps {step:g} per row (a {1 / step:.3g} Hz camera?)",
            path,
            "column time",
            "give the time in seconds (a column in ms or ns: divide it)",
        )
    bodies = {}
    for seg, comps in found.items():
        q = np.column_stack([_numbers(table[comps[c]], path) for c in COMPONENTS])
        norm = np.linalg.norm(q, axis=1)
        ok = np.isfinite(q).all(axis=1) & (norm > 1e-6)
        if ok.sum() < 10:  # NaN, zeros, text: no orientation to compare with
            raise InputError(
                f"segment '{seg}' has {int(ok.sum())} rows with a quaternion (not all zero, all "
                "numbers)", path, f"columns {seg}_qw-{seg}_qz",
                "give unit quaternions w, x, y, z (not Euler angles)",
            )  # fmt: skip
        out = np.full_like(q, np.nan)
        out[ok] = rot.make_continuous(q[ok] / norm[ok, None])
        bodies[seg] = out
    return MarkerSet(
        name=name,
        time=time,
        rigid_bodies=bodies,
        source_units={"time": "s", "quaternion": "segment → lab"},
        attrs={"source_file": str(path), "reference_kind": "segments"},
    )


def _numbers(column: pd.Series, path: Path) -> np.ndarray:
    """A quaternion column as floats; an empty cell is a gap (NaN, as Motive leaves a lost
    body), a cell of text is refused (it was read as a gap: a typo went unnoticed)."""
    values = pd.to_numeric(column, errors="coerce")
    text = np.flatnonzero(values.isna().to_numpy() & column.notna().to_numpy())
    if len(text):
        raise InputError(
            f"'{column.iloc[text[0]]}' is not a number",
            path,
            f"data row {text[0] + 1}, column {str(column.name).strip()}",
            "leave a lost frame's cells empty; write numbers elsewhere",
        )
    return values.to_numpy(float)


def segment_map(
    markers: MarkerSet, segments: list[str], sensors: list[str], frames: str = "anatomical"
) -> MarkerMap:
    """The marker map of a segment CSV: each of its segments (protocol segment or sensor label)
    a rigid body, its frame the anatomical one unless ``frames="body"``."""
    if frames not in FRAMES:
        raise InputError(f"unknown reference frames '{frames}'", remedy="use anatomical or body")
    wanted = [s for s in [*segments, *sensors] if s in markers.rigid_bodies]
    if not wanted:
        raise InputError(
            f"names segments {', '.join(markers.rigid_bodies)}, none of the protocol's or the "
            "session's",
            markers.attrs.get("source_file"),
            "header",
            f"name the columns after {', '.join(segments or sensors)} (<segment>_qw, ...)",
        )
    out = {
        s: SegmentMap(s, rigid_body=s, segment_frame=frames == "anatomical")
        for s in dict.fromkeys(wanted)
    }
    return MarkerMap(segments=out, marker_set=markers.name)
