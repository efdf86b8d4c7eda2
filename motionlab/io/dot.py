"""Xsens DOT CSV exports (Xsens DOT app / SDK).

Layout: a ``sep=,`` line, ``Key:,value`` header lines (``DeviceTag``, ``FirmwareVersion``,
``OutputRate: 60Hz``, ``FilterProfile``, ``Measurement Mode``, ``StartTime``), a blank line,
then a comma-separated table.

Channels and units (Xsens DOT user manual, "Data export"):

=======================  ===================================  ============================
column(s)                file unit                            motionlab
=======================  ===================================  ============================
``SampleTimeFine``       µs, 32-bit wrap (71.6 min)            ``time`` (s)
``Quat_W..Z``            scalar first, sensor → ENU            ``quat``
``Euler_X..Z``           deg, R = Rz(Z) Ry(Y) Rx(X)            ``quat`` (if no ``Quat_*``)
``FreeAcc_X..Z``         m/s², ENU, gravity removed            ``extra["free_acc"]``
``Acc_X..Z``             m/s² (specific force)                 ``acc``
``Gyr_X..Z``             deg/s                                 ``gyr`` (rad/s)
``Mag_X..Z``             a.u. (1 ≈ local field)                ``mag`` (µT, × ``mag_field_ut``)
=======================  ===================================  ============================

The "sensor fusion" measurement modes export orientation and free acceleration only, without
raw gyroscope: the stream then has ``quat`` and ``extra["free_acc"]`` and no ``acc``/``gyr``.
``serial`` is the device's ``DeviceTag`` (the DOT has no other id in its export).
``SyncStatus: Synced`` (the app synchronised the DOTs' clocks before recording) is kept as
``attrs["vendor_clock_sync"]``: clock sync then checks the clocks and leaves them as recorded.
``OutputRate`` is only compared with the rate the time stamps give: one that is no rate in Hz is
ignored with a note. A ``SampleTimeFine`` outside its 32-bit range, or a ``DeviceTag`` longer
than :data:`TAG_MAX` characters, is refused.

Options: ``mag_field_ut`` (float, default 50), ``label`` (str).
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from motionlab import rotations
from motionlab.errors import InputError, shorten
from motionlab.io import Recording
from motionlab.io.clock import SHARED_CLOCK, checked_counter_time, count_wraps, recording_date
from motionlab.io.delimited import find_line, parse_table, read_lines, require_values, split_fields
from motionlab.io.xsens import read_mag_au
from motionlab.session import SensorStream

FORMAT = "dot"

TICK_HZ = 1e6  # SampleTimeFine in µs
#: longest ``DeviceTag`` read (the tag is the sensor's label and serial)
TAG_MAX = 100

_CHANNELS = {
    # name: (column prefix, file unit, factor to SI)
    "acc": ("Acc", "m/s^2", 1.0),
    "gyr": ("Gyr", "deg/s", np.pi / 180.0),
}


def _xyz(prefix: str, axes: str = "XYZ") -> list[str]:
    return [f"{prefix}_{a}" for a in axes]


def _is_table_header(line: str) -> bool:
    if "SampleTimeFine" not in line or "PacketCounter" not in line:
        return False  # without splitting every line of every file that is sniffed
    fields = split_fields(line, ",")
    return "SampleTimeFine" in fields and "PacketCounter" in fields


def sniff(path: Path, head: bytes) -> bool:
    """A DOT export: ``Key:,value`` lines and a table with ``PacketCounter``, ``SampleTimeFine``
    and DOT channel names (``Quat_W``, ``Euler_X`` or ``FreeAcc_X``; or ``Acc_X`` and ``Gyr_X``
    in the "Inertial data mode – rate quantities" export)."""
    lines = head.decode("utf-8", errors="replace").lstrip("\ufeff").splitlines()
    i = find_line(lines, _is_table_header, limit=40)
    if i < 0:
        return _starts_like_dot(lines)
    fields = split_fields(lines[i], ",")
    dot_cols = {"Quat_W", "Euler_X", "FreeAcc_X"} & set(fields) or (
        {"Acc_X", "Gyr_X"} <= set(fields) and {"Acc_X"}
    )
    keyed = any(re.match(r"^[A-Za-z ]+:\s*,", line) for line in lines[:i])
    return bool(dot_cols) and (keyed or lines[0].strip().lower() == "sep=,")


def _starts_like_dot(lines: list[str]) -> bool:
    """``sep=,`` then ``DeviceTag:,``: a DOT export whose table header is beyond the head read
    (a damaged, overlong header line), for :func:`read` to say what is wrong."""
    first = [line.strip() for line in lines[:2]]
    return len(first) == 2 and first[0].lower() == "sep=," and first[1].startswith("DeviceTag:")


def _header_info(preamble: list[str]) -> dict[str, str]:
    info = {}
    for line in preamble:
        key, sep, value = line.partition(",")
        if sep and key.strip().endswith(":"):
            info[key.strip()[:-1].strip()] = value.strip()
    return info


def _check_tag(path: Path, lines: list[str]) -> None:
    """Refuse a ``DeviceTag`` longer than :data:`TAG_MAX` characters (before the table header is
    looked for: an overlong tag pushes it out of the head that detection reads)."""
    for k, line in enumerate(lines[:200]):
        key, _, tag = line.partition(",")
        if key.strip() == "DeviceTag:" and len(tag.strip()) > TAG_MAX:
            raise InputError(
                f"DeviceTag is {len(tag.strip())} characters long, at most {TAG_MAX} are read: "
                "damaged header?",
                path,
                f"line {k + 1}",
                remedy="export again from the Xsens DOT app, or shorten the tag in that line",
            )


def read(path: str | Path, options: dict[str, Any] | None = None) -> Recording:
    """Read one Xsens DOT CSV export into a :class:`Recording` with one sensor (SI units)."""
    path = Path(path)
    options = options or {}
    lines = read_lines(path)
    _check_tag(path, lines)
    header = find_line(lines, _is_table_header, limit=200)
    if header < 0:
        raise InputError(
            "no DOT table header (PacketCounter,SampleTimeFine,…)",
            path,
            remedy="export again from the Xsens DOT app",
        )
    table = parse_table(path, lines, header, delimiter=",", decimal=".")
    info = _header_info(table.preamble)
    stf = table.column("SampleTimeFine")
    out = np.flatnonzero((stf < 0) | (stf >= 2**32))  # NaN: checked_counter_time says it
    if len(out):
        raise InputError(
            f"column 'SampleTimeFine': tick value {stf[out[0]]:.6g} is out of range (0 to "
            "2^32-1 µs, wrapping)",
            path,
            f"line {table.lines[out[0]]}",
            remedy="repair the row, or export the file again",
        )
    time = checked_counter_time(stf, TICK_HZ, 32, path, "SampleTimeFine", table.lines)
    serial = info.get("DeviceTag", "")
    stream = SensorStream(
        label=str(options.get("label") or serial or path.stem),
        time=time,
        serial=serial,
        vendor="Xsens DOT",
    )
    attrs: dict[str, Any] = {
        "time_source": "SampleTimeFine",
        "clock_wraps": count_wraps(stf, 32),
        "header": info,
        "notes": table.notes,
    }
    if info.get("SyncStatus", "").strip().lower() == "synced":  # the DOT app's sync
        attrs[SHARED_CLOCK] = "Xsens DOT SyncStatus: Synced"
    recorded = recording_date(info.get("StartTime"))
    if recorded:
        attrs["recorded"] = recorded
    stated = info.get("OutputRate", "")
    m = re.fullmatch(r"\s*(\d+(?:\.\d+)?)\s*(?:Hz)?\s*", stated, re.IGNORECASE)
    rate = float(m.group(1)) if m else float("nan")
    if 0 < rate < float("inf"):
        attrs["nominal_rate_hz"] = rate
    elif stated:
        attrs["notes"].append(f"OutputRate '{shorten(stated)}' is no rate in Hz: ignored, the "
                              "rate is the time stamps'")  # fmt: skip
    for channel, (prefix, unit, scale) in _CHANNELS.items():
        if table.has(f"{prefix}_X"):
            require_values(table, _xyz(prefix), channel)
            setattr(stream, channel, table.block(_xyz(prefix)) * scale)
            stream.source_units[channel] = unit
    read_mag_au(table, stream, attrs, options)
    if table.has("Quat_W"):
        names = _xyz("Quat", "WXYZ")
        require_values(table, names, "quat")
        stream.quat = rotations.make_continuous(rotations.normalize(table.block(names)))
        stream.source_units["quat"] = "1"
        attrs["orientation_source"] = "quaternion"
    elif table.has("Euler_X"):
        require_values(table, _xyz("Euler"), "quat")
        e = np.radians(table.block(_xyz("Euler")))
        q = rotations.from_scipy(Rotation.from_euler("ZYX", e[:, ::-1]))
        stream.quat = rotations.make_continuous(q)
        stream.source_units["quat"] = "deg"
        attrs["orientation_source"] = "euler"
    if table.has("FreeAcc_X"):
        require_values(table, _xyz("FreeAcc"), "free_acc")
        stream.extra["free_acc"] = table.columns(_xyz("FreeAcc"))
        stream.source_units["free_acc"] = "m/s^2"
    if not stream.channels and not stream.extra:
        raise InputError(
            "no inertial or orientation columns",
            path,
            f"line {header + 1}",
            remedy="export orientation, free acceleration or inertial data from the DOT app",
        )
    stream.attrs = attrs
    return Recording(sensors=[stream], metadata={"source": str(path)}, format=FORMAT)
