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
(scalar first, sensor → earth), read **as stored**, all on the file's one time column (so on one
clock: :func:`motionlab.io.clock.mark_shared_clock`). The files OpenSense's readers write (Xsens,
APDM) keep the IMU system's own Z-up world frame: OpenSim's Y-up ground is reached only inside
OpenSense, by the ``sensor_to_opensim_rotations`` of the IMU placer and IK tools (−90° about X
by default). ``attrs["earth_frame"]`` says so (:data:`EARTH_FRAME`); for Xsens that frame is
ENU, as motionlab's, with the vendor's heading.

:func:`write_sto` writes the same layout, in the same frame (motionlab's ENU earth), with every
number printed in its shortest round-trip form, so :func:`read` gives back the written float64
values exactly. :func:`write_mot` / :func:`read_mot`: OpenSim motion files (joint angles).
"""

from __future__ import annotations

import io
import math
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from motionlab.atomic import atomic_path
from motionlab.errors import InputError, shorten
from motionlab.io import Recording
from motionlab.io.clock import mark_shared_clock
from motionlab.kinematics.segment_types import segment_of_opensim_imu
from motionlab.session import SensorStream, estimate_rate

FORMAT = "opensim"

EARTH_FRAME = (
    "IMU system world frame, Z up (ENU for Xsens and motionlab), as OpenSense's readers write it;"
    " OpenSense rotates it into OpenSim ground (Y up) by sensor_to_opensim_rotations"
)
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
    values = _values(path, rows, first, names)
    time = values[:, 0]
    # OpenSense names each IMU by its body (tibia_r_imu): that is its segment, as a map says
    placed = {name: segment_of_opensim_imu(name) or ("", "") for name in names[1:]}
    sensors = [
        SensorStream(
            label=name.strip(),
            time=time,
            quat=values[:, 1 + 4 * k : 5 + 4 * k].copy(),
            segment=placed[name][0],
            side=placed[name][1],
            vendor="OpenSim",
            source_units={"time": "s", "quat": "1"},
            attrs={"earth_frame": EARTH_FRAME},
        )
        for k, name in enumerate(names[1:])
    ]
    mark_shared_clock(sensors, f"one time column for {len(sensors)} IMUs in {path.name}")
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


def _values(path: Path, rows: list[str], first: int, names: list[str]) -> np.ndarray:
    """The samples as (N, 1 + 4·IMUs) float64: time, then w, x, y, z of each IMU.

    The counts of tabs and commas are checked on every row at once; the numbers are parsed by
    pandas' C parser; only a failure falls back to a cell-by-cell search for the culprit.
    """
    n_imus = len(names) - 1
    text = np.array(rows)
    tabs = np.char.count(text, "\t")
    wrong = np.flatnonzero(tabs != n_imus)
    if wrong.size:
        i = int(wrong[0])
        raise InputError(
            f"{tabs[i] + 1} cells, expected {len(names)}",
            path,
            f"line {first + i + 1}",
            "the file is truncated or edited; export it again",
        )
    wrong = np.flatnonzero(np.char.count(text, ",") != 3 * n_imus)
    if wrong.size:
        i = int(wrong[0])
        cells = rows[i].split("\t")
        j = next(j for j in range(1, len(cells)) if cells[j].count(",") != 3)
        raise InputError(
            f"cell '{shorten(cells[j])}' has {cells[j].count(',') + 1} numbers, expected w,x,y,z",
            path,
            f"line {first + i + 1} column {shorten(names[j])}",
            "each cell must be four comma-separated numbers",
        )
    body = "\n".join(rows).replace("\t", ",")
    try:
        return pd.read_csv(io.StringIO(body), header=None, dtype=np.float64).to_numpy()
    except ValueError:
        table = pd.read_csv(io.StringIO(body), header=None, dtype=str, na_filter=False)
        nan = table.apply(lambda c: c.str.strip().str.lower() == "nan")
        bad = table.where(~nan, "0").apply(pd.to_numeric, errors="coerce").isna()
        # NUL bytes: the C parser stops the cell there, to_numeric alone does not
        bad |= table.apply(lambda c: c.str.contains("\x00", regex=False))
        if not bad.to_numpy().any():
            raise InputError("the quaternion cells cannot be read as numbers", path,
                             remedy="export the file again") from None  # fmt: skip
        i, j = np.argwhere(bad.to_numpy())[0]
        raise InputError(
            f"'{shorten(table.iat[i, j])}' is not a number",
            path,
            f"line {first + i + 1} column {shorten(names[(j + 3) // 4])}",
            "fix the cell or export the file again",
        ) from None


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
        IMU name → (N, 4) quaternions ``w, x, y, z``, sensor → the IMU system's Z-up earth frame
        (ENU), as OpenSense's own readers write them (OpenSense applies its
        ``sensor_to_opensim_rotations``, −90° about X, to reach its Y-up ground). Names must not
        contain tabs or commas.
    force
        Replace an existing file.
    """
    time = np.asarray(time, dtype=float)
    if time.ndim != 1 or len(time) < 1:
        raise InputError(f"time has shape {time.shape}, expected (N,)", path, remedy="pass (N,)")
    if not quats:
        raise InputError("no orientations to write", path, remedy="pass at least one IMU")
    for name, q in quats.items():
        if any(c in name for c in "\t,\n") or not name.strip():
            raise InputError(f"IMU name {name!r}", path, remedy="use names without tab or comma")
        if np.shape(q) != (len(time), 4):
            raise InputError(
                f"'{name}' has shape {np.shape(q)}, expected ({len(time)}, 4)",
                path,
                remedy="give one w,x,y,z row per time sample",
            )
    columns = ["time", *quats]
    values = np.column_stack([time, *(np.asarray(q, dtype=float) for q in quats.values())])
    rate = estimate_rate(time)
    header = [
        f"DataRate={rate if np.isfinite(rate) else 0.0:.6f}",
        "DataType=Quaternion",
        "version=3",
        f"OpenSimVersion={OPENSIM_VERSION}",
        "endheader",
        "\t".join(columns),
    ]
    text = "\n".join(header) + "\n" + _format_rows(values)
    with atomic_path(path, force=force) as tmp:
        tmp.write_text(text, encoding="utf-8")


def _format_rows(values: np.ndarray) -> str:
    """Rows of ``time<TAB>w,x,y,z<TAB>…`` with every float in its shortest round-trip form
    (Python's ``repr``; ``NaN`` for NaN), joined in one pass without a loop over rows."""
    n_rows, n_cols = values.shape
    tokens = np.empty(2 * values.size, dtype=object)
    tokens[0::2] = list(map(repr, values.ravel().tolist()))
    tokens[0::2][np.isnan(values.ravel())] = "NaN"
    separators = np.array(["\t" if c % 4 == 0 else "," for c in range(n_cols - 1)] + ["\n"], object)
    tokens[1::2] = np.tile(separators, n_rows)
    return "".join(tokens.tolist())


def write_mot(
    path: str | Path,
    time: np.ndarray,
    columns: dict[str, np.ndarray],
    force: bool = False,
) -> None:
    """Write an OpenSim motion file (version 1, tab-separated, ``inDegrees=yes``) of angle
    columns in degrees (atomic; ``force`` to replace); numbers in shortest round-trip form;
    ``_deg`` is dropped from the column names."""
    path = Path(path)
    names = [c.removesuffix("_deg") for c in columns]
    values = np.column_stack([time, *columns.values()]) if columns else time[:, None]
    header = [
        path.stem,
        "version=1",
        f"nRows={len(time)}",
        f"nColumns={1 + len(columns)}",
        "inDegrees=yes",
        "endheader",
        "\t".join(["time", *names]),
    ]
    rows = ["\t".join("NaN" if math.isnan(x) else repr(x) for x in row) for row in values.tolist()]
    with atomic_path(path, force=force) as tmp:
        tmp.write_text("\n".join(header + rows) + "\n", encoding="utf-8")


def read_mot(path: str | Path) -> tuple[dict[str, str], pd.DataFrame]:
    """An OpenSim motion (``.mot``) or storage table: its header (``key=value`` lines before
    ``endheader``) and its columns (``time`` first), as float64."""
    path = Path(path)
    lines = path.read_text(encoding="utf-8-sig").splitlines()
    stripped = [ln.strip() for ln in lines]
    if "endheader" not in stripped:
        raise InputError("no 'endheader' line", path, remedy="give an OpenSim .mot/.sto file")
    end = stripped.index("endheader")
    header = dict(
        (k.strip(), v.strip())
        for k, _, v in (ln.partition("=") for ln in stripped[:end] if "=" in ln)
    )
    body = "\n".join(lines[end + 1 :])
    try:
        table = pd.read_csv(io.StringIO(body), sep="\t", dtype=np.float64)
    except ValueError as exc:
        raise InputError(f"not a numeric table ({exc})", path, remedy="export it again") from None
    return header, table
