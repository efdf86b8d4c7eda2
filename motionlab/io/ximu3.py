"""x-IMU3 exports as the x-IMU3 GUI writes them: one folder per device, one CSV per channel.

A **device folder** is named ``<device name> <serial> (<interface>)``, e.g.
``Back B4A2-5410-EC7B-D68C (UDP)/``, and holds:

=========================  ==============================================  =====================
file                       content                                         motionlab
=========================  ==============================================  =====================
``Inertial.csv``           ``Timestamp (us)``, gyroscope deg/s,            ``time`` (s), ``gyr``,
                           accelerometer g                                 ``acc`` (SI)
``Magnetometer.csv``       ``Timestamp (us)``, X/Y/Z (a.u.), own slower    ``mag`` (µT, ×
                           rate                                            ``mag_field_ut``),
                                                                           interpolated onto the
                                                                           inertial time stamps
``Quaternion.csv``         ``Timestamp (us)``, W, X, Y, Z: the device's    ``quat`` (sensor →
                           own fusion, sensor → NWU earth                  ENU), SLERP onto the
                                                                           inertial time stamps
``Command.json``           ``deviceName``, ``serialNumber``                label, serial
``HighGAccelerometer.csv``,                                                ignored (a note in
``Battery.csv``, ``Rssi.csv``,                                             ``attrs["notes"]``)
``Temperature.csv`` …
=========================  ==============================================  =====================

The label is the device name (``Back``, ``Chest``, ``L_arm`` …) from ``Command.json``, else
from the folder name; the serial from ``Command.json``, else the folder name. A **trial
folder** that holds several device folders is read as one recording with one sensor per device
(two devices of one name are refused by ingest unless the sensor map relabels one by serial).
The device's orientation is kept as the vendor's (``--orientation vendor``): the x-IMU3 AHRS
writes it in the North-West-Up earth frame by default, turned here by +90° about the vertical
into motionlab's East-North-Up (the vertical is unchanged; the heading is magnetic north as
the device saw it). The magnetometer's a.u. are scaled by an **assumed** local field
(``mag_field_ut``, default 50 µT; ``attrs["mag_scale_assumed"]``), as for Xsens.

Time is the device's microsecond clock. Inertial time stamps that give a rate outside
:data:`RATE_HZ` (stamps in ms or ns), run backwards or are negative are refused naming
``Inertial.csv``. A magnetometer or quaternion file that stops more than :data:`SPAN_SLACK_S`
before (or starts after) the inertial data is refused as truncated: its channel would otherwise
be held constant over the missing part; so is one without a single usable row, or a channel
file that is a folder, a FIFO, a device or a broken link (never opened).

Options: ``mag_field_ut`` (float), ``label`` (str, a single device folder only).
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import numpy as np

from motionlab import rotations
from motionlab.atomic import special_kind
from motionlab.errors import InputError
from motionlab.io import Recording
from motionlab.io.clock import recording_date
from motionlab.io.delimited import Table, parse_table, read_lines, require_values
from motionlab.io.xsens import DEFAULT_MAG_FIELD_UT
from motionlab.session import SensorStream
from motionlab.timebase import interpolate_rows
from motionlab.units import to_si

FORMAT = "ximu3"

#: ``<name> <serial> (<interface>)``, the x-IMU3 GUI's device folder name
_FOLDER = re.compile(r"^(?P<name>.+?)\s+(?P<serial>[0-9A-Fa-f]{4}(?:-[0-9A-Fa-f]{4}){3})"
                     r"\s+\((?P<interface>[^)]*)\)$")  # fmt: skip
_INERTIAL_HEADER = "Timestamp (us),Gyroscope X (deg/s)"
_INERTIAL = ("Gyroscope X (deg/s)", "Gyroscope Y (deg/s)", "Gyroscope Z (deg/s)",
             "Accelerometer X (g)", "Accelerometer Y (g)", "Accelerometer Z (g)")  # fmt: skip
#: files read; everything else in a device folder is ignored with a note
READ_FILES = ("Inertial.csv", "Magnetometer.csv", "Quaternion.csv", "Command.json")
#: a second stream may start or stop this much (s) away from the inertial data's span
SPAN_SLACK_S = 0.5
#: s: a step of Inertial.csv's clock longer than this is damage, not a pause of the radio
JUMP_S = 3600.0
#: Hz: the rates Inertial.csv's median step may give (the device samples at up to a few kHz;
#: stamps in ms give 1000× the rate, in ns 1/1000 of it)
RATE_HZ = (1.0, 20_000.0)
#: NWU earth (x north, y west, z up) → ENU (x east, y north, z up): +90° about z
_NWU_TO_ENU = np.array([np.sqrt(0.5), 0.0, 0.0, np.sqrt(0.5)])


def is_device_folder(path: Path) -> bool:
    """Whether ``path`` is an x-IMU3 device folder: named like one, or holding
    ``Command.json`` or ``Inertial.csv`` next to another x-IMU3 channel file."""
    if not path.is_dir():
        return False
    if _FOLDER.match(path.name):
        return True
    return (path / "Inertial.csv").is_file() and any(
        (path / f).is_file() for f in ("Command.json", "Quaternion.csv", "Magnetometer.csv")
    )


def device_folders(path: Path) -> list[Path]:
    """The device folders of ``path`` (itself if it is one; else its subfolders that are),
    sorted by name; empty if there are none."""
    if is_device_folder(path):
        return [path]
    if not path.is_dir():
        return []
    return sorted(p for p in path.iterdir() if is_device_folder(p))


def is_export(path: Path) -> bool:
    """Whether the folder ``path`` is an x-IMU3 export (a device folder or a trial folder)."""
    return bool(device_folders(path))


def sniff(path: Path, head: bytes) -> bool:
    """An ``Inertial.csv`` of an x-IMU3 device folder (read as its whole folder)."""
    text = head.decode("utf-8", errors="replace").lstrip("\ufeff")
    return text.startswith(_INERTIAL_HEADER) and is_device_folder(path.parent)


def read(path: str | Path, options: dict[str, Any] | None = None) -> Recording:
    """Read an x-IMU3 device folder, a trial folder of device folders, or a device folder's
    ``Inertial.csv``, into one sensor per device (SI units)."""
    path = Path(path)
    options = options or {}
    folder = path.parent if path.is_file() else path
    devices = device_folders(folder)
    if not devices:
        raise InputError(
            "no x-IMU3 device folder ('<name> <serial> (UDP)' with Inertial.csv) here",
            folder,
            remedy="give the x-IMU3 export's trial folder or one device folder",
        )
    sensors = [_device(d, options if len(devices) == 1 else {**options, "label": None})
               for d in devices]  # fmt: skip
    files = [str(d / f) for d in devices for f in READ_FILES if (d / f).is_file()]
    return Recording(
        sensors=sensors,
        metadata={"source": str(folder), "devices": [d.name for d in devices], "files": files},
        format=FORMAT,
    )


def input_files(path: str | Path) -> list[Path]:
    """The files :func:`read` reads for ``path`` (for the provenance's SHA-256)."""
    path = Path(path)
    folder = path.parent if path.is_file() else path
    return [d / f for d in device_folders(folder) for f in READ_FILES if (d / f).is_file()]


def _identity(folder: Path) -> tuple[str, str, str | None, list[str]]:
    """``(device name, serial, date, notes)`` from ``Command.json`` (the date from the time
    the GUI set on the device, :func:`~motionlab.io.clock.recording_date`), else the folder's
    name and no date."""
    m = _FOLDER.match(folder.name)
    name, serial = (m["name"], m["serial"]) if m else (folder.name, "")
    date = None
    notes: list[str] = []
    cmd = folder / "Command.json"
    if cmd.is_file():
        try:
            entries = json.loads(cmd.read_text(encoding="utf-8", errors="replace"))
        except (ValueError, RecursionError, OSError):  # also too deep, or a 5000-digit number
            notes.append("Command.json is not readable JSON: name and serial from the folder")
            entries = []
        for entry in entries if isinstance(entries, list) else []:
            ping = entry.get("ping") if isinstance(entry, dict) else None
            if isinstance(ping, dict):
                name = str(ping.get("deviceName") or name).strip() or name
                serial = str(ping.get("serialNumber") or serial).strip()
            if isinstance(entry, dict) and date is None:
                date = recording_date(entry.get("time"))
    else:
        notes.append(
            f"no Command.json: device name {name!r}"
            + (f" and serial {serial}" if serial else ", no serial")
            + " from the folder's name, no recording date"
        )
    return name, serial, date, notes


def _table(path: Path, first: str) -> Table:
    lines = read_lines(path)
    if not len(lines):
        raise InputError(
            "file is empty", path, remedy="export the device again from the x-IMU3 GUI"
        )
    if not str(lines[0]).lstrip("\ufeff").startswith(first):
        raise InputError(
            f"not an x-IMU3 {path.stem} file (the header does not start with '{first}')",
            path,
            "line 1",
            remedy="export the device again from the x-IMU3 GUI",
        )
    return parse_table(path, lines, 0, delimiter=",", decimal=".")


def _time(table: Table) -> np.ndarray:
    require_values(table, ["Timestamp (us)"], "time")
    return table.column("Timestamp (us)") * 1e-6


def _channel_file(path: Path, remedy: str) -> bool:
    """Whether the channel file ``path`` is there; a folder, FIFO, device or broken link of its
    name is refused, never opened (a FIFO's read would block)."""
    if path.is_symlink() and not path.exists():
        raise InputError("is a link to no file (missing, or a loop)", path, remedy=remedy)
    if path.is_dir():
        raise InputError("is a folder, expected a CSV file", path, remedy=remedy)
    kind = special_kind(path)
    if kind:
        raise InputError(f"is {kind}, expected a CSV file; it is not read", path, remedy=remedy)
    return path.is_file()


def _without(name: str, what: str) -> str:
    """The remedy for an unusable optional channel file."""
    return f"export the device again, or move {name} out of the folder to read without the {what}"


def _onto(t: np.ndarray, table: Table, values: np.ndarray, name: str, what: str) -> np.ndarray:
    """``values`` (stamped ``Timestamp (us)`` in ``table``) at the inertial instants ``t``; a
    file without a usable row, or that covers the inertial span short of :data:`SPAN_SLACK_S`,
    is refused."""
    ts = _time(table)
    ok = np.isfinite(ts) & np.isfinite(values).all(axis=1)
    if not ok.any():
        zero = ", ±inf or zero" if what == "orientation" else " or ±inf"
        raise InputError(
            f"no row has a time stamp and a whole {what} sample (values missing, NaN{zero})",
            table.path,
            f"lines {int(table.lines[0])}–{int(table.lines[-1])}",
            remedy=_without(name, what),
        )
    order = np.argsort(ts[ok], kind="stable")
    ts, values = ts[ok][order], values[ok][order]
    keep = np.r_[True, np.diff(ts) > 0]
    ts, values = ts[keep], values[keep]
    if len(ts) >= 2 and (ts[-1] < t[0] or ts[0] > t[-1]):  # apart: one clock is wrong
        raise InputError(
            f"{name} ({ts[0]:.6g}–{ts[-1]:.6g} s) and Inertial.csv ({t[0]:.6g}–{t[-1]:.6g} s) do "
            "not overlap in time: one of their Timestamp (us) columns is not the device's clock",
            table.path,
            "column 'Timestamp (us)'",
            remedy="export the device again from the x-IMU3 GUI",
        )
    if len(ts) < 2 or ts[-1] < t[-1] - SPAN_SLACK_S or ts[0] > t[0] + SPAN_SLACK_S:
        span = f"{ts[0] - t[0]:.2f}–{ts[-1] - t[0]:.2f} s" if len(ts) else "nothing"
        raise InputError(
            f"{name} covers {span} of the inertial data's 0–{t[-1] - t[0]:.2f} s: truncated?",
            table.path,
            f"line {int(table.lines[-1]) if len(table.lines) else 1}",
            remedy=_without(name, what),
        )
    tt = np.clip(t, ts[0], ts[-1])
    return interpolate_rows(ts, {"quat" if what == "orientation" else "v": values}, tt).popitem()[1]


def _device(folder: Path, options: dict[str, Any]) -> SensorStream:
    """One device folder → one :class:`SensorStream`; an error names the folder too (every
    device has the same file names)."""
    try:
        return _read_device(folder, options)
    except InputError as exc:
        where = " ".join(filter(None, [f"in '{folder.name}'", exc.where]))
        raise InputError(exc.message, exc.path, where, exc.remedy) from None


def _read_device(folder: Path, options: dict[str, Any]) -> SensorStream:
    inertial = folder / "Inertial.csv"
    if not _channel_file(inertial, "export the device again from the x-IMU3 GUI"):
        raise InputError(
            "no Inertial.csv in the x-IMU3 device folder",
            inertial,
            remedy="export the device again with the inertial data (x-IMU3 GUI: Inertial "
            "message enabled), or move the folder out of the trial",
        )
    name, serial, recorded, notes = _identity(folder)
    table = _table(inertial, "Timestamp (us)")
    t = _time(table)
    require_values(table, list(_INERTIAL), "gyr/acc")
    stream = SensorStream(
        label=str(options.get("label") or name), time=t, serial=serial, vendor="x-io x-IMU3"
    )
    stream.gyr = to_si(table.block(list(_INERTIAL[:3])), "deg/s", "gyr")
    stream.acc = to_si(table.block(list(_INERTIAL[3:])), "g", "acc")
    stream.source_units.update(time="us", gyr="deg/s", acc="g")
    attrs: dict[str, Any] = {"time_source": "Timestamp (us)", "device_folder": str(folder)}
    if recorded:
        attrs["recorded"] = recorded
    notes += [f"Inertial.csv: {n}" for n in table.notes]
    missing = np.flatnonzero(~np.isfinite(t))
    if len(missing) and len(t) >= 2:  # one empty stamp said "fewer than two time-stamped rows"
        raise InputError(
            "no time stamp (empty or not a number)",
            inertial,
            f"line {int(table.lines[missing[0]])}",
            remedy="export the device again, or repair the row",
        )
    if len(t) < 2:
        raise InputError(
            "fewer than two time-stamped rows", inertial, remedy="export the device again"
        )
    _check_clock(t, table)
    step = np.diff(t)
    k = int(np.argmax(np.abs(step)))
    if abs(step[k]) > JUMP_S:  # before the other files are laid onto this clock and blamed
        raise InputError(
            f"the time stamps jump by {step[k]:.6g} s from one row to the next: damaged?",
            inertial,
            f"line {int(table.lines[k + 1])}",
            remedy="export the device again, or cut the file before that line",
        )
    mag_path = folder / "Magnetometer.csv"
    if _channel_file(mag_path, _without(mag_path.name, "magnetometer")):
        mt = _table(mag_path, "Timestamp (us)")
        cols = ["X (a.u.)", "Y (a.u.)", "Z (a.u.)"]
        require_values(mt, cols, "mag")
        field_ut = float(options.get("mag_field_ut", DEFAULT_MAG_FIELD_UT))
        stream.mag = _onto(t, mt, mt.block(cols), mag_path.name, "magnetometer") * field_ut
        stream.source_units["mag"] = "a.u."
        attrs.update(mag_scale_assumed=True, mag_field_ut=field_ut,
                     mag_rate_hz=_rate(_time(mt)))  # fmt: skip
        notes += [f"Magnetometer.csv: {n}" for n in mt.notes]
    quat_path = folder / "Quaternion.csv"
    if _channel_file(quat_path, _without(quat_path.name, "orientation")):
        qt = _table(quat_path, "Timestamp (us)")
        cols = ["W", "X", "Y", "Z"]
        require_values(qt, cols, "quat")
        q = rotations.make_continuous(rotations.normalize(qt.block(cols)))
        q = _onto(t, qt, q, quat_path.name, "orientation")
        stream.quat = rotations.make_continuous(rotations.mul(_NWU_TO_ENU, q))
        stream.source_units["quat"] = "1"
        attrs.update(orientation_source="quaternion", orientation_earth="NWU → ENU",
                     quat_rate_hz=_rate(_time(qt)))  # fmt: skip
        notes += [f"Quaternion.csv: {n}" for n in qt.notes]
    ignored = sorted(p.name for p in folder.iterdir() if p.is_file() and p.name not in READ_FILES)
    if ignored:
        notes.append(f"not read: {', '.join(ignored)}")
    attrs["notes"] = notes
    stream.attrs = attrs
    return stream


def _check_clock(t: np.ndarray, table: Table) -> None:
    """Refuse Inertial.csv time stamps that are negative, run backwards, or give a rate outside
    :data:`RATE_HZ` (not in µs), before the other files are laid onto this clock and blamed."""
    neg = np.flatnonzero(t < 0)
    if len(neg):
        raise InputError(
            f"negative time stamp {t[neg[0]] * 1e6:.6g} µs: the device's clock counts up from 0",
            table.path,
            f"line {int(table.lines[neg[0]])}",
            remedy="export the device again from the x-IMU3 GUI",
        )
    step = float(np.median(np.diff(t)))
    if step <= 0:
        raise InputError(
            f"the time stamps run backwards or stand still (median step {step * 1e6:.6g} µs)",
            table.path,
            "column 'Timestamp (us)'",
            remedy="export the device again from the x-IMU3 GUI, or sort the rows by time",
        )
    if not RATE_HZ[0] <= 1.0 / step <= RATE_HZ[1]:
        raise InputError(
            f"the time stamps give {1.0 / step:.6g} Hz, an x-IMU3 samples at "
            f"{RATE_HZ[0]:g}–{RATE_HZ[1]:g} Hz: not in µs?",
            table.path,
            "column 'Timestamp (us)'",
            remedy="the Timestamp (us) column must be in microseconds: export again from the "
            "x-IMU3 GUI, or convert the column",
        )


def _rate(t: np.ndarray) -> float:
    d = np.diff(t[np.isfinite(t)])
    d = d[d > 0]
    return float(1.0 / np.median(d)) if len(d) else float("nan")
