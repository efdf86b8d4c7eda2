"""Calibration files, one per device serial, and their application to a :class:`SensorStream`.

A calibration file ``<caldir>/<serial>.yaml`` (``.yml`` and ``.json`` are read too) holds, per
channel (``gyr`` rad/s, ``acc`` m/s², ``mag`` µT), an offset ``o`` (3,) and a matrix ``C``
(3, 3) applied as ``v = C (y − o)``, with the method, date and quality figures, and optionally
the Allan noise figures per channel (``noise``)::

    format: motionlab-sensor-calibration
    version: 1
    serial: 00B421AF
    channels:
      gyr: {offset: [...], matrix: [[...]], unit: rad/s, method: rest-windows, date: ...,
            quality: {...}}
      mag: {...}
    noise:
      gyr: {white_density: [...], bias_instability: [...], rate_random_walk: [...], ...}

A sensor is matched by its serial, or by its label when it has none (:func:`calibration_key`).
Applying a calibration returns a new stream whose ``attrs["calibration"]`` records what was done;
a stream already calibrated is refused, so a calibration is never applied twice.
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import json
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from motionlab.atomic import atomic_path
from motionlab.errors import InputError
from motionlab.plain import plain
from motionlab.session import SensorStream
from motionlab.yamlsafe import BoundedSafeLoader, load_yaml, read_yaml_text

FORMAT = "motionlab-sensor-calibration"
VERSION = 1
CHANNELS = ("gyr", "acc", "mag")
UNITS = {"gyr": "rad/s", "acc": "m/s^2", "mag": "uT"}
SUFFIXES = (".yaml", ".yml", ".json")


def now() -> str:
    """The current UTC time, ISO 8601 to the second."""
    return _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")


@dataclass
class ChannelCalibration:
    """Correction ``v = matrix @ (y − offset)`` of one triaxial channel."""

    offset: np.ndarray
    matrix: np.ndarray
    method: str
    date: str = field(default_factory=now)
    quality: dict[str, Any] = field(default_factory=dict)

    def apply(self, y: np.ndarray) -> np.ndarray:
        """Corrected samples (N, 3) from raw samples (N, 3)."""
        return (np.asarray(y, dtype=float) - self.offset) @ self.matrix.T


@dataclass
class SensorCalibration:
    """Everything calibrated for one device: channel corrections and noise figures."""

    serial: str
    channels: dict[str, ChannelCalibration] = field(default_factory=dict)
    noise: dict[str, dict[str, Any]] = field(default_factory=dict)
    vendor: str = ""
    source: str = ""

    def to_dict(self) -> dict[str, Any]:
        """The file content as plain Python."""
        channels = {
            ch: {
                "offset": c.offset,
                "matrix": c.matrix,
                "unit": UNITS[ch],
                "method": c.method,
                "date": c.date,
                "quality": c.quality,
            }
            for ch, c in self.channels.items()
        }
        return plain(
            {
                "format": FORMAT,
                "version": VERSION,
                "serial": self.serial,
                "vendor": self.vendor,
                "source": self.source,
                "channels": channels,
                "noise": self.noise,
            }
        )


#: what to do about a calibration file that does not read
REMEDY = "recreate the file with 'motionlab sensorcal'"


def _vector(value: Any, path: Path, where: str, shape: tuple[int, ...]) -> np.ndarray:
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        arr = None
    if arr is None or arr.shape != shape or not np.isfinite(arr).all():
        raise InputError(
            f"expected {'×'.join(map(str, shape))} finite numbers",
            path,
            f"key {where}",
            REMEDY,
        )
    return arr


def from_dict(data: Any, path: Path) -> SensorCalibration:
    """Validate the parsed content of a calibration file; :class:`InputError` names the key."""
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise InputError(
            "not a motionlab sensor calibration", path, "key format", f"expected '{FORMAT}'"
        )
    version = data.get("version", 0)
    if isinstance(version, bool) or not isinstance(version, int):  # abc, [1], .inf
        raise InputError(
            f"version is {version!r}, expected a whole number", path, "key version", REMEDY
        )
    if version > VERSION:
        raise InputError(
            f"calibration version {data.get('version')} is newer than {VERSION}",
            path,
            "key version",
            "upgrade motionlab",
        )
    serial = data.get("serial")
    if not isinstance(serial, str) or not serial:
        raise InputError("missing serial", path, "key serial", "give the device serial")
    raw = data.get("channels") or {}
    if not isinstance(raw, dict):
        raise InputError("expected a mapping", path, "key channels", REMEDY)
    channels = {}
    for ch, entry in raw.items():
        where = f"channels.{ch}"
        if ch not in CHANNELS:
            raise InputError(f"unknown channel {ch!r}", path, f"key {where}", "gyr, acc or mag")
        if not isinstance(entry, dict):
            raise InputError("expected a mapping", path, f"key {where}", REMEDY)
        if entry.get("unit", UNITS[ch]) != UNITS[ch]:
            raise InputError(
                f"unit {entry.get('unit')!r}, expected {UNITS[ch]}", path, f"key {where}.unit",
                f"give {UNITS[ch]}, or recreate the file with 'motionlab sensorcal'",
            )  # fmt: skip
        matrix = _vector(entry.get("matrix"), path, f"{where}.matrix", (3, 3))
        if abs(np.linalg.det(matrix)) < 1e-6:
            raise InputError("matrix is singular", path, f"key {where}.matrix", REMEDY)
        quality = entry.get("quality") or {}
        if not isinstance(quality, dict):
            raise InputError("expected a mapping", path, f"key {where}.quality", REMEDY)
        channels[ch] = ChannelCalibration(
            offset=_vector(entry.get("offset"), path, f"{where}.offset", (3,)),
            matrix=matrix,
            method=str(entry.get("method", "")),
            date=str(entry.get("date", "")),
            quality=dict(quality),
        )
    noise = data.get("noise") or {}
    if not isinstance(noise, dict):
        raise InputError("expected a mapping", path, "key noise", REMEDY)
    return SensorCalibration(
        serial=serial,
        channels=channels,
        noise=noise,
        vendor=str(data.get("vendor", "")),
        source=str(data.get("source", "")),
    )


def calibration_key(stream: SensorStream) -> str:
    """The name a sensor's calibration is filed under: its serial, else the label its file
    gives it (not the one a sensor map gives it: APDM's serial-less ``Upper`` mapped to
    ``thigh_r`` was filed as ``thigh_r.yaml`` and not found when ingested without that map)."""
    return stream.serial or str(stream.attrs.get("file_label") or stream.label)


def calibration_path(caldir: str | Path, key: str, suffix: str = ".yaml") -> Path:
    """``<caldir>/<key><suffix>``, with characters unsafe in file names replaced by ``_``."""
    return Path(caldir) / (re.sub(r"[^A-Za-z0-9._-]", "_", key) + suffix)


def load_calibration(path: str | Path) -> SensorCalibration:
    """Read and validate a calibration file (YAML or JSON)."""
    path = Path(path)
    if not path.is_file():
        raise InputError("no such calibration file", path, remedy="check the path")
    text = read_yaml_text(path, "sensor calibration", "fix or recreate it")
    if path.suffix != ".json":  # aliases bounded: a small file cannot expand without limit
        return from_dict(load_yaml(text, BoundedSafeLoader, path, "fix or recreate it"), path)
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        where = f"line {exc.lineno}"
        raise InputError("not valid JSON", path, where, "fix or recreate it") from None
    return from_dict(data, path)


def find_calibration(caldir: str | Path, key: str) -> SensorCalibration | None:
    """The calibration filed under ``key`` in ``caldir``, or None."""
    for suffix in SUFFIXES:
        path = calibration_path(caldir, key, suffix)
        if path.is_file():
            return load_calibration(path)
    return None


def save_calibration(cal: SensorCalibration, caldir: str | Path, force: bool = False) -> Path:
    """Write ``cal`` atomically as ``<caldir>/<serial>.yaml`` (replace one only with ``force``)."""
    caldir = Path(caldir)
    if not caldir.is_dir():
        if not caldir.parent.is_dir():
            raise InputError("folder does not exist", caldir.parent, remedy="create it first")
        caldir.mkdir()
    path = calibration_path(caldir, cal.serial)
    with atomic_path(path, force=force) as tmp:
        tmp.write_text(yaml.safe_dump(cal.to_dict(), sort_keys=False), encoding="utf-8")
    return path


def apply_calibration(stream: SensorStream, cal: SensorCalibration) -> SensorStream:
    """A copy of ``stream`` with ``cal``'s corrections applied to the channels it records.

    Raises :class:`InputError` if the serials differ, if the stream is already calibrated, or
    if ``cal`` corrects none of the stream's channels.
    """
    where = f"sensor {stream.label}"
    if stream.serial and stream.serial != cal.serial:
        raise InputError(
            f"calibration is for serial {cal.serial}, the sensor is {stream.serial}",
            where=where,
            remedy="use the calibration file of this device",
        )
    done = stream.attrs.get("calibration")
    if done:
        raise InputError(
            f"already calibrated (serial {done.get('serial')})",
            where=where,
            remedy="apply a calibration once, at ingest or at fuse, not both",
        )
    changes = {}
    for ch, c in cal.channels.items():
        data = getattr(stream, ch)
        if data is not None:
            changes[ch] = c.apply(data)
    if not changes:
        raise InputError(
            f"the calibration of {cal.serial} covers none of {', '.join(stream.channels)}",
            where=where,
        )
    record = {
        "serial": cal.serial,
        "channels": {
            ch: {"method": cal.channels[ch].method, "date": cal.channels[ch].date} for ch in changes
        },  # fmt: skip
        "source": cal.source,
    }
    attrs = {**stream.attrs, "calibration": record}
    return dataclasses.replace(stream, **changes, attrs=attrs)


def apply_calibration_dir(
    streams: Mapping[str, SensorStream], caldir: str | Path, labels: Iterable[str]
) -> tuple[dict[str, SensorStream], dict[str, str]]:
    """Calibrate the sensors ``labels`` of ``streams`` from the files in ``caldir``.

    Returns the calibrated streams (only those with a file) and a one-line note per label.
    Raises :class:`InputError` if ``caldir`` is not a folder or holds no file for any of them.
    """
    caldir = Path(caldir)
    if not caldir.is_dir():
        raise InputError("no such calibration folder", caldir, remedy="run 'motionlab sensorcal'")
    done, notes = {}, {}
    for label in labels:
        stream = streams[label]
        cal = find_calibration(caldir, calibration_key(stream))
        if cal is None:
            notes[label] = f"no calibration for {calibration_key(stream)}"
            continue
        done[label] = apply_calibration(stream, cal)
        notes[label] = f"calibrated ({', '.join(done[label].attrs['calibration']['channels'])})"
    if not done:  # name what was looked for: the folder may hold another set's files
        wanted = [calibration_path(caldir, calibration_key(streams[k])).name for k in labels]
        shown = ", ".join(wanted[:4]) + (f" and {len(wanted) - 4} more" if len(wanted) > 4 else "")
        raise InputError(
            "holds no calibration for these sensors",
            caldir,
            remedy=f"looked for {shown}: run 'motionlab sensorcal' on these sensors' recording",
        )
    return done, notes
