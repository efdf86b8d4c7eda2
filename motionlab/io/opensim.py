"""OpenSim / OpenSense orientation tables (``.sto``): read and write.

File layout (OpenSim Storage version 3, ``DataType=Quaternion``)::

    DataRate=100.000000
    DataType=Quaternion
    version=3
    OpenSimVersion=4.1
    endheader
    time<TAB>pelvis_imu<TAB>tibia_r_imu ...
    0<TAB>w,x,y,z<TAB>w,x,y,z ...

Each IMU column becomes a :class:`~motionlab.session.SensorStream` with only ``quat``
(scalar first, sensor → earth), read **as stored**: OpenSense's earth frame is OpenSim's ground,
which is Y up (its readers rotate the vendor's Z-up world frame by −90° about X by default), not
ENU. ``attrs["earth_frame"]`` records this; convert before mixing with ENU orientations.

:func:`write_sto` writes the same layout with every number printed in its shortest round-trip
form, so :func:`read` gives back the written float64 values exactly.
"""

from __future__ import annotations

import functools
import io
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from motionlab.atomic import atomic_path
from motionlab.errors import InputError
from motionlab.io import Recording
from motionlab.session import SensorStream, estimate_rate

FORMAT = "opensim"

EARTH_FRAME = "OpenSim ground (Y up; heading from the source IMU system), not ENU"
OPENSIM_VERSION = "4.1"


def sniff(path: Path, head: bytes) -> bool:
    """An OpenSim header (``DataType=Quaternion`` or ``OpenSimVersion=`` before ``endheader``),
    or an ``endheader`` line followed by ``w,x,y,z`` cells."""
    stripped = [ln.strip() for ln in head.decode("latin-1").splitlines()]
    end = stripped.index("endheader") if "endheader" in stripped else min(len(stripped), 20)
    header = [ln.lower() for ln in stripped[:end]]
    if "datatype=quaternion" in header or any(ln.startswith("opensimversion=") for ln in header):
        return True
    data = stripped[end + 2 : end + 3]
    return bool(data) and "\t" in data[0] and data[0].split("\t")[1].count(",") == 3


def read(path: str | Path, options: dict[str, Any] | None = None) -> Recording:
    """Read an OpenSense orientation ``.sto``: one quaternion-only stream per IMU column."""
    path = Path(path)
    try:
        lines = path.read_text(encoding="utf-8-sig").splitlines()
    except UnicodeDecodeError as exc:
        raise InputError(
            f"not a text file (byte {exc.start})", path, remedy="give an OpenSim .sto file"
        ) from None
    stripped = [ln.strip() for ln in lines]
    if "endheader" not in stripped:
        raise InputError(
            "no 'endheader' line", path, f"line {len(lines)}", "add the line that ends the header"
        )
    end = stripped.index("endheader")
    header, line_of = {}, {}
    for i, ln in enumerate(stripped[:end]):
        if "=" in ln:
            key, value = (x.strip() for x in ln.split("=", 1))
            header[key], line_of[key] = value, i + 1
    datatype = header.get("DataType", "Quaternion")
    if datatype.lower() != "quaternion":
        raise InputError(
            f"DataType={datatype}",
            path,
            f"line {line_of['DataType']}",
            "only orientation (Quaternion) tables are read",
        )
    if end + 1 >= len(lines) or not stripped[end + 1]:
        raise InputError(
            "no column names after 'endheader'", path, f"line {end + 2}", "export the table again"
        )
    names = lines[end + 1].rstrip("\r\n").split("\t")
    if names[0].strip().lower() != "time" or len(names) < 2:
        raise InputError(
            "first column must be 'time', then one column per IMU",
            path,
            f"line {end + 2}",
            "is the file tab-separated?",
        )
    first = end + 2
    while len(lines) > first and not lines[-1].strip():
        lines.pop()
    rows = lines[first:]
    if len(rows) < 1:
        raise InputError("no samples after the header", path, f"line {first + 1}", "re-export")
    table = _cells(path, rows, first, len(names))
    time = _numbers(path, table[:, :1], first, names[:1])[:, 0]
    sensors = []
    for j, name in enumerate(names[1:], start=1):
        counts = np.char.count(table[:, j], ",") + 1
        wrong = np.flatnonzero(counts != 4)
        if wrong.size:
            i = int(wrong[0])
            raise InputError(
                f"cell '{table[i, j]}' has {counts[i]} numbers, expected w,x,y,z",
                path,
                f"line {first + i + 1} column {name}",
                "each cell must be four comma-separated numbers",
            )
        parts = pd.Series(table[:, j]).str.split(",", expand=True).to_numpy(dtype=str)
        quat = _numbers(path, parts, first, [name] * 4)
        sensors.append(
            SensorStream(
                label=name.strip(),
                time=time,
                quat=quat,
                vendor="OpenSim",
                source_units={"time": "s", "quat": "1"},
                attrs={"earth_frame": EARTH_FRAME},
            )
        )
    meta: dict[str, Any] = {"header": header}
    if "DataRate" in header:
        try:
            meta["nominal_rate_hz"] = float(header["DataRate"])
        except ValueError:
            raise InputError(
                f"DataRate={header['DataRate']} is not a number",
                path,
                f"line {line_of['DataRate']}",
                "write the rate in Hz, e.g. DataRate=100",
            ) from None
    return Recording(sensors=sensors, metadata=meta)


def _cells(path: Path, rows: list[str], first: int, n_cols: int) -> np.ndarray:
    """Tab-separated cells of ``rows`` as an (N, n_cols) string array; a wrong count is an error."""
    n_fields = np.char.count(np.array(rows), "\t") + 1
    wrong = np.flatnonzero(n_fields != n_cols)
    if wrong.size:
        i = int(wrong[0])
        raise InputError(
            f"{n_fields[i]} cells, expected {n_cols}",
            path,
            f"line {first + i + 1}",
            "the file is truncated or edited; export it again",
        )
    table = pd.read_csv(
        io.StringIO("\n".join(rows)), sep="\t", header=None, dtype=str, na_filter=False
    )
    return table.to_numpy(dtype=str)


def _numbers(path: Path, text: np.ndarray, first: int, names: list[str]) -> np.ndarray:
    """Parse a string array as float64; name the first bad cell's line and column."""
    values = pd.DataFrame(text).apply(pd.to_numeric, errors="coerce").to_numpy(dtype=float)
    bad = np.isnan(values) & (np.char.lower(np.char.strip(text)) != "nan")
    if bad.any():
        i, j = np.argwhere(bad)[0]
        raise InputError(
            f"'{text[i, j]}' is not a number",
            path,
            f"line {first + i + 1} column {names[j]}",
            "fix the cell or export the file again",
        )
    return values


def write_sto(
    path: str | Path,
    time: np.ndarray,
    quats: dict[str, np.ndarray],
    force: bool = False,
) -> None:
    """Write orientations as an OpenSense quaternion ``.sto`` (atomic; ``force`` to replace).

    Parameters
    ----------
    path
        Output file; an existing file is replaced only with ``force=True``.
    time
        Sample times (N,) in s.
    quats
        IMU name → (N, 4) quaternions ``w, x, y, z`` in the frame the caller chose (OpenSense
        expects sensor → OpenSim ground, Y up). Names must not contain tabs or commas.
    force
        Replace an existing file.
    """
    time = np.asarray(time, dtype=float)
    if time.ndim != 1 or len(time) < 1:
        raise InputError(f"time has shape {time.shape}, expected (N,)", path, remedy="pass (N,)")
    if not quats:
        raise InputError("no orientations to write", path, remedy="pass at least one IMU")
    columns = ["time"]
    cells = [_shortest(time)]
    for name, q in quats.items():
        q = np.asarray(q, dtype=float)
        if any(c in name for c in "\t,\n") or not name.strip():
            raise InputError(f"IMU name {name!r}", path, remedy="use names without tab or comma")
        if q.shape != (len(time), 4):
            raise InputError(
                f"'{name}' has shape {q.shape}, expected ({len(time)}, 4)",
                path,
                remedy="give one w,x,y,z row per time sample",
            )
        s = _shortest(q)
        cells.append(s[:, 0] + "," + s[:, 1] + "," + s[:, 2] + "," + s[:, 3])
        columns.append(name)
    rate = estimate_rate(time)
    header = [
        f"DataRate={rate if np.isfinite(rate) else 0.0:.6f}",
        "DataType=Quaternion",
        "version=3",
        f"OpenSimVersion={OPENSIM_VERSION}",
        "endheader",
        "\t".join(columns),
    ]
    rows = functools.reduce(lambda a, b: a + "\t" + b, cells)
    text = "\n".join(header + list(rows)) + "\n"
    with atomic_path(path, force=force) as tmp:
        tmp.write_text(text, encoding="utf-8")


def _shortest(values: np.ndarray) -> np.ndarray:
    """Shortest decimal strings that read back to the same float64 (``NaN`` for NaN)."""
    s = np.asarray(values, dtype=float).astype(str)
    return np.where(np.isnan(values), "NaN", s).astype(object)
