"""x-io Technologies style CSV (NGIMU / x-IMU / Fusion examples): one header row whose column
names carry their units, e.g.::

    Time (s),Gyroscope X (deg/s),Gyroscope Y (deg/s),Gyroscope Z (deg/s),
    Accelerometer X (g),…,Magnetometer X (uT),…

Recognised columns (case-insensitive): ``Time`` or ``Timestamp`` (s, ms or us), ``Gyroscope
X/Y/Z`` (deg/s or rad/s), ``Accelerometer X/Y/Z`` (g, m/s^2), ``Magnetometer X/Y/Z`` (uT,
gauss, …). Every value is converted to SI with :func:`motionlab.units.to_si` and the file's
unit kept in ``source_units``. Other numeric columns (barometer, temperature …) go to ``extra``
under a lower-case name (``barometer_hpa``).

Options: ``label`` (str).
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np

from motionlab.errors import InputError
from motionlab.io import Recording
from motionlab.io.delimited import first_content_line, parse_table, read_lines, split_fields
from motionlab.session import SensorStream
from motionlab.units import to_si

FORMAT = "xio"

_COLUMN = re.compile(r"^\s*([A-Za-z][A-Za-z ]*?)\s*\(([^)]+)\)\s*$")
_CHANNELS = {"gyroscope": ("gyr", "gyr"), "accelerometer": ("acc", "acc"),
             "magnetometer": ("mag", "mag")}  # fmt: skip


def _parse_name(name: str) -> tuple[str, str, str] | None:
    """``'Gyroscope X (deg/s)'`` → ``('gyroscope', 'x', 'deg/s')``; ``'Time (s)'`` →
    ``('time', '', 's')``; ``None`` without a unit in parentheses."""
    m = _COLUMN.match(name)
    if not m:
        return None
    words = m.group(1).lower().split()
    axis = words[-1] if len(words) > 1 and words[-1] in ("x", "y", "z") else ""
    base = " ".join(words[:-1] if axis else words)
    return base, axis, m.group(2).strip()


def _header(lines: list[str]) -> int:
    return first_content_line(lines)


def sniff(path: Path, head: bytes) -> bool:
    """The first content line names time, gyroscope and accelerometer columns with units."""
    lines = head.decode("utf-8", errors="replace").lstrip("\ufeff").splitlines()
    i = _header(lines)
    if i >= len(lines):
        return False
    parsed = [_parse_name(f) for f in split_fields(lines[i], ",")]
    bases = {p[0] for p in parsed if p}
    return {"gyroscope", "accelerometer"} <= bases and bool({"time", "timestamp"} & bases)


def read(path: str | Path, options: dict[str, Any] | None = None) -> Recording:
    """Read an x-io style CSV into a :class:`Recording` with one sensor (SI units)."""
    path = Path(path)
    options = options or {}
    lines = read_lines(path)
    header = _header(lines)
    table = parse_table(path, lines, header, delimiter=",", decimal=".")
    groups: dict[str, dict[str, tuple[int, str]]] = {}
    extra: dict[str, int] = {}
    time_col = None
    for j, name in enumerate(table.names):
        parsed = _parse_name(name)
        if parsed is None:
            continue
        base, axis, unit = parsed
        if base in ("time", "timestamp"):
            time_col = (j, unit)
        elif base in _CHANNELS and axis:
            groups.setdefault(base, {})[axis] = (j, unit)
        else:
            key = re.sub(r"\W+", "_", f"{base} {axis} {unit}".lower()).strip("_")
            extra[key] = j
    if time_col is None:
        raise InputError(
            "no 'Time (s)' column", path, f"line {header + 1}", remedy="export with timestamps"
        )
    stream = SensorStream(
        label=str(options.get("label") or path.stem), time=np.empty(0), vendor="x-io"
    )
    j, unit = time_col
    stream.time = _si(table.data[:, j], unit, "time", path, table.names[j])
    stream.source_units["time"] = unit
    for base, axes in groups.items():
        channel, quantity = _CHANNELS[base]
        missing = [a for a in "xyz" if a not in axes]
        if missing:
            raise InputError(
                f"no column '{base.capitalize()} {missing[0].upper()}'",
                path,
                f"line {header + 1}",
                remedy="export all three axes",
            )
        units = {axes[a][1] for a in "xyz"}
        if len(units) > 1:
            raise InputError(
                f"{base} axes have different units {sorted(units)}",
                path,
                f"line {header + 1}",
                remedy="export all axes in one unit",
            )
        cols = [axes[a][0] for a in "xyz"]
        for c in cols:
            if not np.isfinite(table.data[:, c]).any():
                raise InputError(
                    f"column '{table.names[c]}' has no values",
                    path,
                    f"column '{table.names[c]}'",
                    remedy="re-export with this channel enabled",
                )
        unit = units.pop()
        setattr(stream, channel, _si(table.block(cols), unit, quantity, path, base))
        stream.source_units[channel] = unit
    for key, j in extra.items():
        stream.extra[key] = table.data[:, j]
    if not stream.channels:
        raise InputError(
            "no gyroscope, accelerometer or magnetometer columns",
            path,
            f"line {header + 1}",
            remedy="export the inertial channels",
        )
    stream.attrs = {"time_source": table.names[time_col[0]], "notes": table.notes}
    return Recording(sensors=[stream], metadata={"source": str(path)}, format=FORMAT)


def _si(values: np.ndarray, unit: str, quantity: str, path: Path, column: str) -> np.ndarray:
    try:
        return to_si(values, unit, quantity)
    except InputError as exc:
        raise InputError(exc.message, path, f"column '{column}'", exc.remedy) from None
