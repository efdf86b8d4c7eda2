"""C3D marker files (Vicon, OptiTrack, Qualisys, …) read with ezc3d.

Returned: one :class:`~motionlab.session.MarkerSet` named after the file, with

- ``labels`` from ``POINT:LABELS`` (continued in ``LABELS2``, ``LABELS3``… past 255 markers),
- ``positions`` (N, M, 3) in m (``POINT:UNITS`` ``mm``, ``cm`` or ``m``; ``mm`` assumed, with a
  warning, when the parameter is absent),
- ``residuals`` (N, M) in m,
- ``time`` = frame index / ``POINT:RATE`` in s (the first frame number in ``attrs``).

The C3D header block is compared with the frames ezc3d could read, to refuse a truncated
file. A point is invalid — NaN in ``positions`` and ``residuals`` — when its residual is negative
(the C3D "not seen" flag) or all three coordinates are exactly zero (how some exporters write
a gap). Analog channels are not read; their count is kept in ``attrs["n_analog_channels"]``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from motionlab.errors import InputError
from motionlab.io import Recording
from motionlab.session import MarkerSet
from motionlab.units import factor

FORMAT = "c3d"


def sniff(path: Path, head: bytes) -> bool:
    """C3D: the second byte of the header block is the key 0x50, and the parameter section
    (block ``head[0]``) names a processor type 84–86 (Intel, DEC, MIPS) in its fourth byte."""
    if len(head) < 512 or head[1] != 0x50:
        return False
    processor = (max(head[0], 1) - 1) * 512 + 3
    return processor < len(head) and head[processor] in (84, 85, 86)


def read(path: str | Path, options: dict[str, Any] | None = None) -> Recording:
    """Read the marker trajectories of a C3D file (m, NaN where not seen)."""
    import ezc3d

    path = Path(path)
    try:
        c3d = ezc3d.c3d(str(path))
    except (RuntimeError, OSError, ValueError) as exc:
        raise InputError(
            f"ezc3d cannot open it ({str(exc).splitlines()[0] if str(exc) else 'damaged'})",
            path,
            remedy="export the C3D again from the capture software",
        ) from None
    point = c3d["parameters"].get("POINT", {})
    header = c3d["header"]["points"]
    points = c3d["data"]["points"]  # (4, M, N)
    n_markers, n_frames = points.shape[1], points.shape[2]
    expected = _announced_frames(path)
    if n_markers and n_frames < expected:
        raise InputError(
            f"truncated: the header announces {expected} frames, the file holds {n_frames}",
            path,
            f"frame {n_frames + 1}",
            "copy or export the file again",
        )
    rate = _value(point, "RATE", float(header["frame_rate"]))
    if not np.isfinite(rate) or rate <= 0:
        raise InputError(f"point rate {rate} Hz", path, "parameter POINT:RATE", "fix the rate")
    warnings: list[str] = []
    unit = _value(point, "UNITS", "").strip()
    if not unit:
        unit = "mm"
        warnings.append("POINT:UNITS absent; mm assumed")
    try:
        scale = factor(unit, "length")
    except InputError as exc:
        raise InputError(exc.message, path, "parameter POINT:UNITS", exc.remedy) from None

    labels = _labels(point, n_markers)
    xyz = np.transpose(points[:3], (2, 1, 0)).astype(float)  # (N, M, 3)
    residuals = np.asarray(c3d["data"]["meta_points"]["residuals"][0], dtype=float).T
    invalid = (residuals < 0) | np.all(xyz == 0.0, axis=2) | np.isnan(xyz).any(axis=2)
    xyz[invalid] = np.nan
    residuals[invalid] = np.nan

    analogs = c3d["parameters"].get("ANALOG", {})
    attrs: dict[str, Any] = {
        "first_frame": int(header["first_frame"]),
        "nominal_rate_hz": rate,
        "n_analog_channels": int(c3d["header"]["analogs"]["size"]),
        "analog_rate_hz": _value(analogs, "RATE", 0.0),
    }
    if warnings:
        attrs["warnings"] = warnings
    markers = MarkerSet(
        name=(options or {}).get("name") or path.stem,
        time=np.arange(n_frames) / rate,
        labels=labels,
        positions=xyz * scale,
        residuals=residuals * scale,
        source_units={"positions": unit, "residuals": unit},
        attrs=attrs,
    )
    return Recording(markers=[markers], metadata={"c3d_unit": unit})


def _announced_frames(path: Path) -> int:
    """Frame count written in the C3D header block (ezc3d reports what it could read instead).

    Header words 4 and 5 are the first and last frame (uint16, 1-based); integers are
    big-endian only on MIPS files (processor type 86, byte 4 of the parameter section).
    """
    with open(path, "rb") as f:
        head = f.read(512)
        f.seek((max(head[0], 1) - 1) * 512 + 3)
        processor = f.read(1)
    order = ">" if processor == bytes([86]) else "<"
    first, last = np.frombuffer(head[6:10], dtype=f"{order}u2")
    return int(last) - int(first) + 1


def _value(group: dict, name: str, default: Any) -> Any:
    """First value of a C3D parameter, or ``default`` when absent or empty."""
    values = group.get(name, {}).get("value", [])
    if len(values) == 0:
        return default
    value = values[0]
    return value if isinstance(value, str) else float(value)


def _labels(point: dict, n_markers: int) -> list[str]:
    """``LABELS`` then ``LABELS2``, ``LABELS3``… stripped; missing names become ``M001``…"""
    labels: list[str] = []
    for key in ["LABELS"] + [f"LABELS{k}" for k in range(2, 100)]:
        if key not in point or len(labels) >= n_markers:
            break
        labels += [str(s).strip() for s in point[key]["value"]]
    labels += [""] * (n_markers - len(labels))
    return [name or f"M{k + 1:03d}" for k, name in enumerate(labels[:n_markers])]
