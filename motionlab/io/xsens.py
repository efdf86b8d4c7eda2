"""Xsens MT Manager text exports (``MT_<...>_<DeviceId>.txt``).

Layouts read (content decides, not the name):

- legacy (MT Manager 4.x, 2018): ``// Start Time``, ``// Update Rate: 100.0Hz`` … lines;
- 2019–2022: ``// General information`` block with ``DeviceId`` and ``Coordinate system``, no
  rate line;
- tab, comma, semicolon or single-space delimiters; empty or ``NaN`` fields read as NaN.

Channels and units (Xsens MT Manager user manual, "Exporting data"):

==================  ==========================  =========================================
column(s)           file unit                   motionlab
==================  ==========================  =========================================
``Acc_*``           m/s² (specific force)       ``acc``
``Gyr_*``           rad/s                       ``gyr``
``Mag_*``           a.u. (1 ≈ local field)      ``mag`` in µT = a.u. × ``mag_field_ut``
``FreeAcc_*``       m/s², earth frame           ``extra["free_acc"]`` (ENU)
``Quat_q0..q3``     scalar first, sensor→earth  ``quat``
``Mat[i][j]``       R_GS, row i = earth axis    ``quat`` (if no ``Quat_*``)
``Roll Pitch Yaw``  deg, R = Rz(yaw)Ry(pitch)Rx(roll)  ``quat`` (if neither of the above)
==================  ==========================  =========================================

Orientation is expressed in ENU: a ``Coordinate system: NED`` or ``NWU`` export is rotated into
ENU. When an export holds two or three orientation representations they are compared and the
largest disagreement is recorded in ``attrs["orientation_agreement_deg"]``.

Magnetometer: Xsens normalises the field to 1 at calibration (a.u.). motionlab scales it by an
**assumed** local field of ``mag_field_ut`` µT (option; default 50 µT, a typical mid-latitude
magnitude). Fusion uses only the field's direction; magnitude-based disturbance checks see the
assumed scale, which is flagged in ``attrs["mag_scale_assumed"]`` and ``source_units["mag"]``.

Time, from the device clock, in order of preference:

1. ``SampleTimeFine``: 10 kHz ticks, 32-bit wrap (:mod:`motionlab.io.clock`);
2. ``UTC_*`` fields with ``UTC_Nano`` (POSIX seconds), when every row has them;
3. ``PacketCounter`` (``Counter`` in older exports; 16-bit wrap) divided by the rate:
   ``// Update Rate`` in the header, else the ``rate_hz`` option, else 100 Hz (MTw default),
   flagged in ``attrs["rate_assumed"]``.

Options: ``rate_hz`` (float), ``mag_field_ut`` (float), ``label`` (str).

MTw Awinda: the MTws of one station sample on the station's clock (the MTw Awinda user manual,
on synchronising two Awinda Stations: each station's MTw data are time synchronised, two
stations in one MT Manager are not tested), and MT Manager writes each file's rows against the
recording's sample counter, so the files of one recording start at one ``PacketCounter`` (the
two MTw2 files ``formats/xsens/MT2022_*`` at 51400). :func:`mark_one_recording` (called by
ingest over the session's Xsens files) marks them as on one clock when every file says it is
an MTw and they start together, or, for a legacy export without a product code, when their
names give one recording of one master device (an Awinda station or an Xbus Master, whose
sensors it samples on its clock) and they start together.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy.spatial.transform import Rotation

from motionlab import rotations
from motionlab.errors import InputError
from motionlab.io import Recording
from motionlab.io.clock import (
    checked_counter_time,
    count_wraps,
    mark_shared_clock,
    recording_date,
)
from motionlab.io.delimited import (
    Table,
    first_content_line,
    parse_table,
    read_lines,
    require_values,
)
from motionlab.session import SensorStream

FORMAT = "xsens"

DEFAULT_MAG_FIELD_UT = 50.0
DEFAULT_RATE_HZ = 100.0
SAMPLE_TIME_FINE_HZ = 10_000.0

#: a SampleTimeFine step of this many 10-kHz ticks or more (under 10 Hz) in a file without MT
#: Manager's '//' header is a DOT table's µs clock (16 667 at the DOT's 60 Hz)
DOT_LIKE_TICKS = 1000
_KNOWN = ("PacketCounter", "SampleTimeFine", "Acc_X", "Gyr_X", "Mag_X", "Quat_q0", "Mat[1][1]")
#: the sample counter's column: ``Counter`` in older MT Software exports (MTx, MTi-G)
_COUNTERS = ("PacketCounter", "Counter")
_QUAT = ["Quat_q0", "Quat_q1", "Quat_q2", "Quat_q3"]
_MAT = [f"Mat[{i}][{j}]" for i in (1, 2, 3) for j in (1, 2, 3)]
_EULER = ["Roll", "Pitch", "Yaw"]
_UTC = ["UTC_Year", "UTC_Month", "UTC_Day", "UTC_Hour", "UTC_Minute", "UTC_Second", "UTC_Nano"]

#: rotation from a file's earth frame into ENU (columns: the file's axes in ENU)
_TO_ENU = {
    "ENU": np.eye(3),
    "NED": np.array([[0.0, 1, 0], [1, 0, 0], [0, 0, -1]]),
    "NWU": np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]]),
}


def _xyz(prefix: str) -> list[str]:
    return [f"{prefix}_{a}" for a in "XYZ"]


def read_mag_au(
    table: Table, stream: SensorStream, attrs: dict[str, Any], options: dict[str, Any]
) -> None:
    """The ``Mag_X..Z`` columns, if any, into ``stream.mag`` (µT): Xsens exports the field in
    arbitrary units normalised to the field at the last calibration, so it is scaled by the
    assumed local field ``options["mag_field_ut"]`` (default :data:`DEFAULT_MAG_FIELD_UT`),
    which ``attrs`` records (``mag_scale_assumed``, ``mag_field_ut``)."""
    if not table.has("Mag_X"):
        return
    require_values(table, _xyz("Mag"), "mag")
    field_ut = float(options.get("mag_field_ut", DEFAULT_MAG_FIELD_UT))
    stream.mag = table.block(_xyz("Mag")) * field_ut
    stream.source_units["mag"] = "a.u."
    attrs.update(mag_scale_assumed=True, mag_field_ut=field_ut)


def _header_line(text: str) -> bool:
    fields = re.split(r"[\t,; ]", text.strip())
    return any(k in fields for k in _KNOWN)


def sniff(path: Path, head: bytes) -> bool:
    """An MT Manager export: its first non-comment line names Xsens columns, and it is not a
    DOT export (which starts with ``sep=,`` and ``Key:,value`` lines)."""
    text = head.decode("utf-8", errors="replace").lstrip("\ufeff")
    lines = text.splitlines()
    if not lines or lines[0].strip().lower().startswith("sep="):
        return False
    i = first_content_line(lines, prefixes=("//",))
    return i < len(lines) and _header_line(lines[i])


def _header_info(preamble: list[str]) -> dict[str, str]:
    info = {}
    for line in preamble:
        body = line.lstrip("/").strip()
        if ":" in body:
            key, _, value = body.partition(":")
            info[key.strip()] = value.strip()
    return info


def _serial(info: dict[str, str], path: Path) -> str:
    if info.get("DeviceId"):
        return info["DeviceId"]
    ids = re.findall(r"_([0-9A-Fa-f]{8})(?=[_.])", path.name)  # MT_<master>_…_<DeviceId>.txt
    return ids[-1].upper() if ids else ""


def _rate(info: dict[str, str], options: dict[str, Any], path: Path) -> tuple[float, bool]:
    text = info.get("Update Rate")
    if text:
        m = re.match(r"\s*([0-9.]+)", text)
        if not m or float(m.group(1)) <= 0:
            raise InputError(
                f"cannot read 'Update Rate: {text}'",
                path,
                "header",
                remedy="fix the header line, e.g. 'Update Rate: 100.0Hz'",
            )
        return float(m.group(1)), False
    if options.get("rate_hz") is not None:
        try:
            rate = float(options["rate_hz"])
        except (TypeError, ValueError):
            rate = -1.0
        if rate <= 0:
            raise InputError(
                f"rate_hz must be a positive number, not {options['rate_hz']!r}",
                path,
                "key rate_hz",
                remedy="give the export's update rate in Hz",
            )
        return rate, False
    return DEFAULT_RATE_HZ, True


def _all_present(table: Table, names: list[str]) -> bool:
    return all(table.has(n) and not np.any(np.isnan(table.column(n))) for n in names)


def _time(table: Table, info: dict[str, str], options: dict[str, Any]) -> tuple:
    """(time s, source name, attrs) from the best device clock in the file."""
    path = table.path
    if _all_present(table, ["SampleTimeFine"]):
        stf = table.column("SampleTimeFine")
        step = np.median(np.diff(stf)) if len(stf) > 1 else 0.0
        if not info and step >= DOT_LIKE_TICKS:  # no '//' header, and µs ticks: a DOT table
            raise InputError(
                f"SampleTimeFine steps by {step:.0f} ticks, {SAMPLE_TIME_FINE_HZ / step:.2g} Hz "
                "at MT Manager's 10 kHz: an Xsens DOT export (ticks in µs) without its 'sep=,' "
                "and 'Key:,value' header lines?",
                path,
                "column 'SampleTimeFine'",
                remedy="export again from the Xsens DOT app, or restore the header lines",
            )
        t = checked_counter_time(stf, SAMPLE_TIME_FINE_HZ, 32, path, "SampleTimeFine", table.lines)
        return t, "SampleTimeFine", {"clock_wraps": count_wraps(stf, 32)}
    if _all_present(table, _UTC):
        cols = table.columns(_UTC)
        parts = pd.DataFrame(
            cols[:, :6].astype(np.int64),
            columns=["year", "month", "day", "hour", "minute", "second"],
        )
        try:
            stamp = pd.to_datetime(parts)
        except (ValueError, OverflowError):
            raise InputError(
                "UTC fields do not form valid dates",
                path,
                "columns UTC_*",
                remedy="export with SampleTimeFine or PacketCounter",
            ) from None
        posix = (stamp - pd.Timestamp("1970-01-01")).dt.total_seconds().to_numpy()
        return posix + cols[:, 6] * 1e-9, "UTC", {}
    counter = next((c for c in _COUNTERS if table.has(c)), None)
    if counter is not None:
        rate, assumed = _rate(info, options, path)
        pc = table.column(counter)
        t = checked_counter_time(pc, rate, 16, path, counter, table.lines)
        attrs = {"clock_wraps": count_wraps(pc, 16), "counter_rate_hz": rate}
        if assumed:
            attrs["rate_assumed"] = True
            attrs["notes_rate"] = (
                f"no 'Update Rate' in the header and no rate_hz option: {rate} Hz assumed"
            )
        return t, counter, attrs
    raise InputError(
        "no time column (SampleTimeFine, UTC_* or PacketCounter)",
        path,
        remedy="export with 'Sample Time Fine' or 'Packet Counter' enabled in MT Manager",
    )


def _orientations(table: Table) -> dict[str, np.ndarray]:
    """Every orientation representation in the file, as quaternions (sensor → file earth)."""
    out = {}
    if all(table.has(n) for n in _QUAT):
        out["quaternion"] = rotations.normalize(table.block(_QUAT))
    if all(table.has(n) for n in _MAT):
        m = table.columns(_MAT).reshape(-1, 3, 3)
        q = np.full((len(m), 4), np.nan)
        ok = np.all(np.isfinite(m), axis=(1, 2))
        with np.errstate(all="ignore"):  # a rotation: orthonormal, det +1 (not all zero)
            gram = np.einsum("nij,nkj->nik", m, m) - np.eye(3)
            ok &= (np.abs(gram).max(axis=(1, 2)) < 0.05) & (np.abs(np.linalg.det(m) - 1) < 0.05)
        if ok.any():
            q[ok] = rotations.from_matrix(m[ok])
        out["matrix"] = q
    if all(table.has(n) for n in _EULER):
        e = np.radians(table.block(_EULER))
        q = np.full((len(e), 4), np.nan)
        ok = np.all(np.isfinite(e), axis=1)
        if ok.any():
            # Xsens: R_GS = Rz(yaw) Ry(pitch) Rx(roll) — intrinsic Z-Y'-X''
            q[ok] = rotations.from_scipy(Rotation.from_euler("ZYX", e[ok][:, ::-1]))
        out["euler"] = q
    return out


def read(path: str | Path, options: dict[str, Any] | None = None) -> Recording:
    """Read one MT Manager text export into a :class:`Recording` with one sensor (SI units)."""
    path = Path(path)
    options = options or {}
    lines = read_lines(path)
    header = first_content_line(lines, prefixes=("//",))
    if header >= len(lines) or not _header_line(lines[header]):
        if lines.unended and header >= len(lines) - 1:
            raise InputError(
                "truncated: the file ends inside its header",
                path,
                f"line {len(lines)}",
                remedy="copy or export the file again",
            )
        raise InputError(
            "no Xsens column header (PacketCounter, Acc_X, …)",
            path,
            f"line {min(header, len(lines)) + 1}",
            remedy="export again from MT Manager with a header row",
        )
    table = parse_table(path, lines, header, comments=("//",))
    info = _header_info(table.preamble)
    frame = info.get("Coordinate system", "ENU").strip().upper() or "ENU"
    if frame not in _TO_ENU:
        raise InputError(
            f"unknown coordinate system '{frame}'",
            path,
            "header",
            remedy="export in ENU, NED or NWU",
        )
    time, time_source, attrs = _time(table, info, options)
    serial = _serial(info, path)
    stream = SensorStream(
        label=str(options.get("label") or serial or path.stem),
        time=time,
        serial=serial,
        vendor="Xsens",
    )
    attrs.update(time_source=time_source, earth_frame=frame, header=info)
    counter = next((c for c in _COUNTERS if table.has(c)), None)
    counts = table.column(counter) if counter else np.empty(0)
    if np.isfinite(counts).any():  # the master's count of the recording: mark_one_recording
        attrs["first_packet_counter"] = int(counts[np.isfinite(counts)][0])
    if recorded := recording_date(info.get("Start Time")):  # legacy exports: may be "Unknown"
        attrs["recorded"] = recorded
    for channel, prefix, unit in (("acc", "Acc", "m/s^2"), ("gyr", "Gyr", "rad/s")):
        if table.has(f"{prefix}_X"):
            require_values(table, _xyz(prefix), channel)
            setattr(stream, channel, table.columns(_xyz(prefix)))
            stream.source_units[channel] = unit
    read_mag_au(table, stream, attrs, options)
    to_enu = _TO_ENU[frame]
    if table.has("FreeAcc_X"):
        require_values(table, _xyz("FreeAcc"), "free_acc")
        stream.extra["free_acc"] = table.block(_xyz("FreeAcc")) @ to_enu.T
        stream.source_units["free_acc"] = "m/s^2"
    reps = _orientations(table)
    if reps:
        first = next(iter(reps))
        for name in reps:
            require_values(
                table,
                {"quaternion": _QUAT, "matrix": _MAT, "euler": _EULER}[name],
                f"orientation ({name})",
            )
        q_frame = rotations.from_matrix(to_enu)
        stream.quat = rotations.make_continuous(rotations.mul(q_frame, reps[first]))
        stream.source_units["quat"] = {"quaternion": "1", "matrix": "1", "euler": "deg"}[first]
        attrs["orientation_source"] = first
        if len(reps) > 1:
            worst = max(
                float(np.nanmax(np.degrees(rotations.angle_between(reps[first], q))))
                for q in list(reps.values())[1:]
            )
            attrs["orientation_agreement_deg"] = worst
    if not stream.channels:
        raise InputError(
            "no inertial or orientation columns",
            path,
            f"line {header + 1}",
            remedy="export Acc, Gyr, Mag or orientation from MT Manager",
        )
    attrs["notes"] = table.notes + ([attrs.pop("notes_rate")] if "notes_rate" in attrs else [])
    stream.attrs = attrs
    return Recording(sensors=[stream], metadata={"source": str(path)}, format=FORMAT)


#: MT Manager's export names of a recording made through a master device (an Awinda station, an
#: Xbus Master): ``MT_<master id>_<recording>_<device id>.txt``, e.g. the OpenSense example
#: ``MT_012005D6_031-000_00B421AF.txt`` (station 012005D6, MTw 00B421AF)
_MASTER_EXPORT = re.compile(r"^(?P<recording>MT_(?P<master>[0-9A-Fa-f]{8})[_-].*)_"
                            r"(?P<device>[0-9A-Fa-f]{8})\.txt$")  # fmt: skip


def mark_one_recording(files: list[tuple[SensorStream, Path]]) -> None:
    """Mark the Xsens exports of one recording on one master's clock as on one clock
    (:func:`motionlab.io.clock.mark_shared_clock`): two or more devices of different ids, every
    file's first ``PacketCounter`` the same and its first stamp the same on the same time source
    (``SampleTimeFine`` ticks, or the counter), and either

    - every header's ``ProductCode`` an MTw's (``MTW2-3A7G6``): one Awinda station's MTws, or
    - a legacy export (no ``ProductCode``) whose file names all name one recording of one master
      device that is none of the sensors (``MT_<master>_<recording>_<device>.txt``,
      :data:`_MASTER_EXPORT`): the master (an Awinda station, an Xbus Master) samples its
      sensors on its own clock and counts the recording's packets, and MT Manager names every
      export after that recording.

    Otherwise none is marked: a legacy export under another name says neither, devices
    connected on their own (MTi) keep their own clocks, and files that start apart may come
    from two recordings or two stations (whose synchronisation the manual leaves untested)."""
    streams = [s for s, _ in files]
    starts = {(s.attrs.get("first_packet_counter"), s.attrs.get("time_source"), float(s.time[0]))
              for s in streams}  # fmt: skip
    counter = next(iter(starts))[0] if len(starts) == 1 else None
    if counter is None or len(streams) < 2 or len({s.serial for s in streams}) < len(streams):
        return
    codes = [s.attrs.get("header", {}).get("ProductCode", "").strip().upper() for s in streams]
    if all(c.startswith("MTW") for c in codes):
        mark_shared_clock(streams, f"Xsens Awinda: {len(streams)} MTw exports starting at "
                                   f"PacketCounter {counter}")  # fmt: skip
        return
    names = [_MASTER_EXPORT.match(p.name) for _, p in files]
    if any(codes) or not all(names):
        return
    recordings = {(m["recording"], m["master"].upper()) for m in names}
    devices = {m["device"].upper() for m in names}
    if len(recordings) == 1 and len(devices) == len(streams):
        recording, master = next(iter(recordings))
        if master not in devices:
            mark_shared_clock(streams, f"Xsens MT Manager: {len(streams)} exports of recording "
                                       f"{recording} of master {master} starting at "
                                       f"PacketCounter {counter}")  # fmt: skip
