"""APDM Opal HDF5 recordings (Motion Studio / Mobility Lab ``.h5``).

Layout read (APDM HDF5 format, version 5)::

    /Sensors/<case id>/Accelerometer   (N, 3)  m/s²
    /Sensors/<case id>/Gyroscope       (N, 3)  rad/s
    /Sensors/<case id>/Magnetometer    (N, 3)  µT
    /Sensors/<case id>/Time            (N,)    µs since the Unix epoch
    /Sensors/<case id>/Configuration   attrs: "Label 0" (the sensor's label), "Sample Rate"
    /Processed/<case id>/Orientation   (N, 4)  scalar first, sensor → earth (North-West-Up)

A dataset's ``Units`` attribute, when present, overrides the documented unit. One
:class:`~motionlab.session.SensorStream` per case id, labelled with ``Label 0`` (the case id when
the label is empty), time in s since the Unix epoch (sensors that started apart stay apart; the
first stamp in ``attrs["start_unix_us"]``, the UTC date in ``attrs["recorded"]``), orientations
converted from NWU to ENU as for the CSV export
(:func:`motionlab.io.apdm.nwu_to_enu`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import h5py
import numpy as np

from motionlab.errors import InputError, shorten
from motionlab.io import Recording
from motionlab.io.apdm import DEFAULT_UNITS, convert, nwu_to_enu
from motionlab.io.clock import unix_date
from motionlab.isolated import open_hdf5
from motionlab.session import SensorStream

FORMAT = "apdm_h5"

HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
_DATASETS = {"acc": "Accelerometer", "gyr": "Gyroscope", "mag": "Magnetometer"}


def sniff(path: Path, head: bytes) -> bool:
    """An HDF5 file with a top-level ``Sensors`` group."""
    if not head.startswith(HDF5_SIGNATURE):
        return False
    try:
        with h5py.File(path, "r") as f:
            return isinstance(f.get("Sensors"), h5py.Group)
    except (OSError, RuntimeError, KeyError, UnicodeError):  # damaged metadata: read() says so
        return False


def read(path: str | Path, options: dict[str, Any] | None = None) -> Recording:
    """Read every sensor of an APDM HDF5 file (SI units, quaternions sensor → ENU)."""
    path = Path(path)
    with open_hdf5(path, "not a readable HDF5 file", "export the recording again as .h5") as f:
        sensors = f.get("Sensors")
        if not isinstance(sensors, h5py.Group) or not len(sensors):
            raise InputError(
                "no sensors in the file",
                path,
                "group /Sensors",
                "give an APDM .h5 recording (Motion Studio or Mobility Lab)",
            )
        try:
            processed = f.get("Processed")
            streams = []
            for case_id, g in sensors.items():
                if not isinstance(g, h5py.Group):  # a dangling link or a damaged object header
                    raise InputError(
                        "is not a sensor group: the file is damaged",
                        path,
                        f"key /Sensors/{shorten(case_id)}",
                        "export the recording again as .h5",
                    )
                streams.append(_sensor(path, case_id, g, processed))
            meta = {k: _text(v) for k, v in f.attrs.items() if isinstance(v, (str, bytes))}
        except (UnicodeError, KeyError, ValueError, TypeError, OSError, RuntimeError) as exc:
            # h5py's words for damaged metadata: a name that is not UTF-8, an object header it
            # cannot open, a type description it cannot represent
            raise InputError(
                f"the file is damaged ({shorten(_words(exc))})",
                path,
                remedy="export the recording again as .h5",
            ) from None
    return Recording(sensors=streams, metadata=meta)


def _words(exc: Exception) -> str:
    """What h5py says of damaged metadata, without the quotes a ``KeyError`` adds."""
    if isinstance(exc, UnicodeError):
        return "a name that is not UTF-8"
    return str(exc.args[0]) if exc.args else type(exc).__name__


def _text(value: Any) -> str:
    if isinstance(value, bytes):
        value = value.decode("utf-8", errors="replace")
    if isinstance(value, np.ndarray):
        value = _text(value.flat[0]) if value.size else ""
    text = str(value).encode("utf-8", "replace").decode("utf-8")  # h5py's surrogates for damage
    return text.rstrip("\x00").strip()


def _dataset(path: Path, group: h5py.Group, name: str, width: int | None) -> np.ndarray:
    where = f"{group.name}/{name}"
    ds = group.get(name)
    if not isinstance(ds, h5py.Dataset):
        raise InputError(
            "missing dataset", path, f"key {where}", "export the raw sensor data into the .h5"
        )
    try:
        kind = ds.dtype.kind
    except (ValueError, TypeError):  # h5py: a damaged type description
        kind = "damaged"
    if kind not in "biuf":
        what = "a data type that cannot be read" if kind == "damaged" else str(ds.dtype)
        raise InputError(
            f"holds {what}, expected numbers", path, f"key {where}", "re-export the file"
        )
    try:
        data = np.asarray(ds[()], dtype=float)
    except (OSError, ValueError):
        raise InputError(
            "cannot be read, the data are damaged", path, f"key {where}", "re-export the file"
        ) from None
    shape_ok = data.ndim == 1 if width is None else (data.ndim == 2 and data.shape[1] == width)
    if not shape_ok:
        want = "(N,)" if width is None else f"(N, {width})"
        raise InputError(
            f"shape {data.shape}, expected {want}", path, f"key {where}", "re-export the file"
        )
    return data


def _sensor(path: Path, case_id: str, g: h5py.Group, processed: h5py.Group | None) -> SensorStream:
    time_us = _dataset(path, g, "Time", None)
    n = len(time_us)
    if n < 2:
        raise InputError(f"{n} samples", path, f"key {g.name}/Time", "record a longer trial")
    channels: dict[str, np.ndarray] = {}
    source_units: dict[str, str] = {"time": "us (Unix epoch)"}
    for channel, name in _DATASETS.items():
        if name not in g:
            continue
        data = _dataset(path, g, name, 3)
        unit = _text(g[name].attrs.get("Units", "")) or DEFAULT_UNITS[channel]
        channels[channel] = convert(data, unit, channel, path, f"key {g.name}/{name}")
        source_units[channel] = unit
    if processed is not None and case_id in processed and "Orientation" in processed[case_id]:
        channels["quat"] = nwu_to_enu(_dataset(path, processed[case_id], "Orientation", 4))
    for channel, data in channels.items():
        if len(data) != n:
            raise InputError(
                f"{len(data)} samples but Time has {n}",
                path,
                f"key {g.name}/{_DATASETS.get(channel, 'Orientation')}",
                "re-export the file",
            )
    if not channels:
        raise InputError(
            "no Accelerometer, Gyroscope, Magnetometer or Orientation",
            path,
            f"key {g.name}",
            "export the raw sensor data into the .h5",
        )
    config = g.get("Configuration")
    attrs: dict[str, Any] = {"source_earth_frame": "NWU", "start_unix_us": int(time_us[0])}
    recorded = unix_date(float(time_us[0]) * 1e-6)
    if recorded:
        attrs["recorded"] = recorded
    label = ""
    if config is not None:
        label = _text(config.attrs.get("Label 0", ""))
        if "Sample Rate" in config.attrs:
            rate = np.ravel(config.attrs["Sample Rate"])
            if rate.dtype.kind not in "iuf" or len(rate) != 1 or not np.isfinite(rate[0]):
                raise InputError(
                    f"is {shorten(rate.tolist())!r}, expected one number (Hz)",
                    path,
                    f"key {config.name}/Sample Rate",
                    "re-export the file",
                )
            attrs["nominal_rate_hz"] = float(rate[0])
    return SensorStream(
        label=label or case_id,
        time=np.asarray(time_us, float) * 1e-6,
        serial=case_id,
        vendor="APDM",
        source_units=source_units,
        attrs=attrs,
        **channels,
    )
