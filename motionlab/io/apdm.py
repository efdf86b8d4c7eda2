"""APDM Opal CSV exports (Motion Studio and Mobility Lab).

Two layouts are read:

- **Motion Studio export**: ``Key:,value`` lines (``Test Name:``, ``Sample Rate:,128,Hz``), a
  header row ``Time,<Label>/<Quantity>/<Axis>,…`` (e.g. ``Upper/Angular Velocity/X``), a row of
  units (``s,m/s^2,…,rad/s,…,uT``) and the samples. Time is in s from the start of recording.
- **Mobility Lab "Format=7"**: three header rows — sensor (case id, then label, over each
  sensor's block), quantity (``Accelerometer``, ``Gyroscope``, ``Magnetometer``, ``Barometer``,
  ``Orientation``) and component (``X,Y,Z`` or ``S,X,Y,Z``) — then samples with time in µs since
  the Unix epoch. There is no units row: APDM's documented units (acc m/s², gyr rad/s, mag µT)
  are assumed and recorded as such.

One :class:`~motionlab.session.SensorStream` per sensor, all on the file's one time column (so
on one clock: :func:`motionlab.io.clock.mark_shared_clock`). Columns other than the three
inertial vectors and the orientation (temperature, pressure, the barometer) are ignored and
listed in ``Recording.metadata["ignored_columns"]``. Time is returned in s: a Format=7 file's in
s since the Unix epoch (so that files recorded apart stay apart, and a C3D on its own clock is
told unrelated, :mod:`motionlab.ingest`), its date in ``attrs["recorded"]`` (UTC) and its first
stamp in ``attrs["start_unix_us"]``; a Motion Studio file's as it is written.

Orientation: APDM quaternions are scalar first and map sensor to earth, but APDM's earth frame
is **North-West-Up** (x magnetic north, y west, z up; checked on ``imuData01.csv``: the static
sensor's magnetic field, rotated to earth, points along +x). They are converted to ENU with
:func:`nwu_to_enu`; ``attrs["source_earth_frame"]`` records ``"NWU"``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from motionlab import rotations as rot
from motionlab.errors import InputError
from motionlab.io import Recording
from motionlab.io.clock import mark_shared_clock, unix_date
from motionlab.io.delimited import parse_table, read_lines
from motionlab.session import SensorStream
from motionlab.units import to_si

FORMAT = "apdm"

#: rotation taking NWU earth coordinates to ENU: +90° about the shared up axis
NWU_TO_ENU = np.array([np.sqrt(0.5), 0.0, 0.0, np.sqrt(0.5)])

#: the header rows are looked for among this many first lines
HEADER_LINES = 200

#: APDM's documented units, used when a file has no units row
DEFAULT_UNITS = {"acc": "m/s^2", "gyr": "rad/s", "mag": "uT"}

_QUANTITIES = {
    "acceleration": "acc",
    "accelerometer": "acc",
    "angular velocity": "gyr",
    "gyroscope": "gyr",
    "magnetic field": "mag",
    "magnetometer": "mag",
    "orientation": "quat",
}
_COMPONENTS = {
    "acc": ("x", "y", "z"),
    "gyr": ("x", "y", "z"),
    "mag": ("x", "y", "z"),
    "quat": ("scalar", "x", "y", "z"),
}


def nwu_to_enu(q: np.ndarray) -> np.ndarray:
    """Sensor → NWU quaternions (…, 4) re-expressed as sensor → ENU: ``q_ENU = r ⊗ q_NWU``.

    ``r`` is +90° about z: north (NWU x) becomes ENU y and west (NWU y) becomes ENU −x.
    """
    return rot.mul(NWU_TO_ENU, q)


def convert(values: np.ndarray, unit: str, quantity: str, path: Path, where: str) -> np.ndarray:
    """:func:`~motionlab.units.to_si` with the file and place named in the error."""
    try:
        return to_si(values, unit, quantity)
    except InputError as exc:
        raise InputError(exc.message, path, where, exc.remedy) from None


def sniff(path: Path, head: bytes) -> bool:
    """An APDM CSV starts with ``Format=`` or has ``Sample Rate:`` and ``/Acceleration/`` rows."""
    lines = head.removeprefix(b"\xef\xbb\xbf").decode("latin-1").splitlines()[:10]
    if not lines:
        return False
    if lines[0].startswith("Format="):
        return True
    return any(ln.startswith("Sample Rate:") for ln in lines) and any(
        "/Acceleration/" in ln for ln in lines
    )


def read(path: str | Path, options: dict[str, Any] | None = None) -> Recording:
    """Read an APDM CSV export; one stream per sensor, SI units, quaternions sensor → ENU."""
    path = Path(path)
    text = read_lines(path)
    end = len(text)
    while end and not text[end - 1].strip(","):
        end -= 1  # trailing rows of empty cells
    if not end:
        raise InputError("file is empty", path, remedy="export the recording again")
    lines = text[: min(end, HEADER_LINES)]
    if lines[0].startswith("Format="):
        columns, first_data, time_unit, meta = _format7_header(path, lines)
    else:
        columns, first_data, time_unit, meta = _studio_header(path, lines)
    names = ["Time"] + [f"{c[0]}/{c[2]}/{c[3]}" for c in columns]
    table = parse_table(path, text, first_data, header_rows=0, delimiter=",", names=names, end=end)
    values = table.data
    if len(values) < 2:
        raise InputError(
            f"{len(values)} samples", path, f"line {first_data + 1}", "export a longer recording"
        )

    t_raw = values[:, 0]
    stamped = np.flatnonzero(np.isfinite(t_raw))
    if not len(stamped):  # a blank or NaN stamp is dropped by the ingest, the rest kept
        raise InputError("no row has a time stamp (column 1 is empty or NaN)", path,
                         f"lines {first_data + 1}-{first_data + len(t_raw)} column 1",
                         "export the recording again with its time column")  # fmt: skip
    t0 = t_raw[stamped[0]]  # the first stamp, not row 1's: a NaN there made every time NaN
    time = convert(t_raw, time_unit, "time", path, f"line {first_data} column 1")
    attrs: dict[str, Any] = {"source_earth_frame": "NWU"}
    if lines[0].startswith("Format="):
        attrs["start_unix_us"] = int(t0)
        recorded = unix_date(float(time[stamped[0]]))
        if recorded:
            attrs["recorded"] = recorded
    if "sample_rate_hz" in meta:
        attrs["nominal_rate_hz"] = meta["sample_rate_hz"]

    sensors = _streams(path, columns, values, time, attrs, units_line=first_data)
    mark_shared_clock(sensors, f"one Time column for {len(sensors)} sensors in {path.name}")
    ignored = sorted({f"{c[0]}/{c[2]}" for c in columns if c[2] not in _QUANTITIES})
    meta["ignored_columns"] = ignored
    if table.notes:
        meta["notes"] = table.notes
    return Recording(sensors=sensors, metadata=meta)


# ------------------------------------------------------------------------------------ headers

# A column is (sensor key, serial, quantity name (lower case), component (lower case), unit).
Column = tuple[str, str, str, str, str]


def _cells(line: str) -> list[str]:
    return [c.strip() for c in line.split(",")]


def _studio_header(path: Path, lines: list[str]) -> tuple[list[Column], int, str, dict]:
    meta: dict[str, Any] = {}
    for i, line in enumerate(lines):
        cells = _cells(line)
        if cells[0].lower() == "time":
            header_line = i
            break
        if cells[0].endswith(":"):
            key = cells[0][:-1].strip()
            meta[key] = cells[1] if len(cells) > 1 else ""
            if key.lower() == "sample rate":
                meta["sample_rate_hz"] = _float(path, i, cells[1] if len(cells) > 1 else "")
    else:
        raise InputError(
            "no 'Time,…' header row", path, remedy="export with the APDM CSV header (one per file)"
        )
    header = _cells(lines[header_line])
    units = [""] * len(header)
    first_data = header_line + 1
    if first_data < len(lines) and not _is_number(_cells(lines[first_data])[0]):
        units = _cells(lines[first_data]) + [""] * len(header)
        first_data += 1
    columns = []
    for j, name in enumerate(header[1:], start=1):
        parts = name.split("/")
        if len(parts) != 3:
            raise InputError(
                f"column '{name}' is not <sensor>/<quantity>/<axis>",
                path,
                f"line {header_line + 1} column {j + 1}",
                "export with the default APDM column names",
            )
        columns.append((parts[0], "", parts[1].lower(), parts[2].lower(), units[j]))
    return columns, first_data, units[0] or "s", meta


def _format7_header(path: Path, lines: list[str]) -> tuple[list[Column], int, str, dict]:
    if len(lines) < 4:
        raise InputError(
            "header ends early (needs 3 header rows and samples)",
            path,
            f"line {len(lines)}",
            "the file looks truncated; export it again",
        )
    sensor_row, quantity_row, component_row = (_cells(ln) for ln in lines[:3])
    n = len(quantity_row)
    if len(sensor_row) != n or len(component_row) != n or n < 2:
        raise InputError(
            f"header rows have {len(sensor_row)}, {n} and {len(component_row)} cells",
            path,
            "lines 1-3",
            "export the file again without editing it (comma-delimited)",
        )
    first_quantity = quantity_row[1]
    columns: list[Column] = []
    names: list[str] = []
    quantity = ""
    for j in range(1, n):
        if quantity_row[j] == first_quantity:  # a new sensor's block starts
            names = [c for c in sensor_row[j : j + _block_width(quantity_row, j)] if c]
        if quantity_row[j]:
            quantity = quantity_row[j].lower()
        if not names:
            raise InputError(
                "no sensor id above this column", path, f"line 1 column {j + 1}", "re-export"
            )
        serial, label = names[0], names[-1]
        columns.append((label, serial, quantity, _component(component_row[j]), ""))
    meta = {"format_version": lines[0].split(",")[0].split("=", 1)[1]}
    return columns, 3, "us", meta


def _block_width(quantity_row: list[str], start: int) -> int:
    nxt = [j for j in range(start + 1, len(quantity_row)) if quantity_row[j] == quantity_row[start]]
    return (nxt[0] if nxt else len(quantity_row)) - start


def _component(cell: str) -> str:
    c = cell.lower()
    return {"s": "scalar", "w": "scalar"}.get(c, c)


# --------------------------------------------------------------------------------------- data


def _is_number(cell: str) -> bool:
    try:
        float(cell)
    except ValueError:
        return False
    return True


def _float(path: Path, line_index: int, cell: str) -> float:
    if not _is_number(cell):
        raise InputError(
            f"'{cell}' is not a number", path, f"line {line_index + 1}", "fix or re-export the file"
        )
    return float(cell)


def _streams(
    path: Path,
    columns: list[Column],
    values: np.ndarray,
    time: np.ndarray,
    attrs: dict,
    units_line: int,
) -> list[SensorStream]:
    by_sensor: dict[str, dict[tuple[str, str], tuple[int, str]]] = {}
    serials: dict[str, str] = {}
    for j, (label, serial, quantity, component, unit) in enumerate(columns, start=1):
        by_sensor.setdefault(label, {})[(quantity, component)] = (j, unit)
        serials[label] = serial
    streams = []
    for label, cols in by_sensor.items():
        channels: dict[str, np.ndarray] = {}
        source_units: dict[str, str] = {}
        for quantity, channel in _QUANTITIES.items():
            keys = [(quantity, c) for c in _COMPONENTS[channel]]
            present = [k for k in keys if k in cols]
            if not present:
                continue
            if len(present) != len(keys):
                raise InputError(
                    f"sensor '{label}' has {len(present)} of {len(keys)} {quantity} columns",
                    path,
                    f"column {cols[present[0]][0] + 1}",
                    "export all axes of each quantity",
                )
            idx = [cols[k][0] for k in keys]
            if channel == "quat":
                channels["quat"] = nwu_to_enu(values[:, idx])
                continue
            unit = cols[keys[0]][1] or DEFAULT_UNITS[channel]
            where = f"line {units_line} column {idx[0] + 1}"
            channels[channel] = convert(values[:, idx], unit, channel, path, where)
            source_units[channel] = unit
        if not channels:
            continue
        source_units["time"] = "s" if "start_unix_us" not in attrs else "us (Unix epoch)"
        streams.append(
            SensorStream(
                label=label,
                time=time,
                serial=serials[label],
                vendor="APDM",
                source_units=source_units,
                attrs=dict(attrs),
                **channels,
            )
        )
    if not streams:
        raise InputError(
            "no accelerometer, gyroscope, magnetometer or orientation columns",
            path,
            remedy="export the sensor data (not only derived measures)",
        )
    return streams
