"""BROAD benchmark trials (HDF5): one IMU and its aligned optical reference.

Laidig, Caruso, Cereatti, Seel (2021), "BROAD — A Benchmark for Robust Inertial Orientation
Estimation", Data 6(7):72, doi:10.3390/data6070072 (data licence CC BY 4.0).

Each file holds ``imu_acc`` (m/s²), ``imu_gyr`` (rad/s), ``imu_mag`` (µT), ``opt_quat``
(w, x, y, z, IMU → ENU, already aligned to the IMU), ``opt_pos`` (m), ``movement`` (bool) and the
attribute ``sampling_rate`` (Hz); there is no time array, so time is ``k / sampling_rate``.

Returned: the IMU as one :class:`~motionlab.session.SensorStream` (label ``imu``; ``movement``
in ``extra["movement"]``) and the reference as one :class:`~motionlab.session.MarkerSet`
(name ``optical``) on the same timebase, with ``rigid_bodies={"imu": opt_quat}`` and ``opt_pos``
as the single marker ``imu_origin``. Occluded samples (NaN in ``opt_quat``) stay NaN.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import h5py
import numpy as np

from motionlab.errors import InputError, shorten
from motionlab.io import Recording
from motionlab.isolated import open_hdf5
from motionlab.session import MarkerSet, SensorStream

FORMAT = "broad"
#: the highest sampling rate taken as real (Hz); above it the attribute is damaged
MAX_RATE_HZ = 1e5

HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
#: dataset name → expected number of columns (None: one-dimensional)
_DATASETS = {
    "imu_acc": 3,
    "imu_gyr": 3,
    "imu_mag": 3,
    "opt_quat": 4,
    "opt_pos": 3,
    "movement": None,
}


def sniff(path: Path, head: bytes) -> bool:
    """An HDF5 file with top-level ``imu_gyr`` and ``opt_quat`` datasets."""
    if not head.startswith(HDF5_SIGNATURE):
        return False
    try:
        with h5py.File(path, "r") as f:
            return "imu_gyr" in f and "opt_quat" in f
    except (OSError, RuntimeError, KeyError):  # h5py: damaged metadata (read() says so)
        return False


def read(path: str | Path, options: dict[str, Any] | None = None) -> Recording:
    """Read a BROAD trial: the IMU stream and the optical reference on one timebase."""
    path = Path(path)
    with open_hdf5(path, "not a readable HDF5 file", "download the trial again") as f:
        if "sampling_rate" not in f.attrs:
            raise InputError(
                "missing attribute", path, "key /sampling_rate", "give a BROAD trial file"
            )
        rate = _rate(path, f)
        data = {name: _dataset(path, f, name, width) for name, width in _DATASETS.items()}
        try:
            info = f.attrs.get("info", "")
        except (OSError, ValueError, TypeError):  # h5py: a damaged attribute (free text only)
            info = ""
        info = info.decode("utf-8", "replace") if isinstance(info, bytes) else str(info)
        info = info.encode("utf-8", "replace").decode("utf-8")  # damaged bytes: surrogates
    n = len(data["imu_gyr"])
    for name, arr in data.items():
        if len(arr) != n:
            raise InputError(
                f"{len(arr)} samples but imu_gyr has {n}", path, f"key /{name}", "re-download"
            )
    time = np.arange(n) / rate
    units = {"acc": "m/s^2", "gyr": "rad/s", "mag": "uT", "time": "s (from sampling_rate)"}
    imu = SensorStream(
        label="imu",
        time=time,
        acc=data["imu_acc"],
        gyr=data["imu_gyr"],
        mag=data["imu_mag"],
        vendor="myon (BROAD)",
        source_units=units,
        extra={"movement": data["movement"].astype(bool)},
        attrs={"nominal_rate_hz": rate},
    )
    optical = MarkerSet(
        name="optical",
        time=time.copy(),
        labels=["imu_origin"],
        positions=data["opt_pos"][:, None, :],
        rigid_bodies={"imu": data["opt_quat"]},
        source_units={"positions": "m"},
        attrs={"earth_frame": "ENU", "aligned_to": "imu", "nominal_rate_hz": rate},
    )
    meta = {"dataset": "BROAD", "trial": path.stem, "licence": "CC BY 4.0", "info": info}
    return Recording(sensors=[imu], markers=[optical], metadata=meta)


def _rate(path: Path, f: h5py.File) -> float:
    """The ``sampling_rate`` attribute: one positive number (Hz)."""
    where = "key /sampling_rate"
    try:
        value = np.ravel(f.attrs["sampling_rate"])
    except OSError:
        raise InputError("cannot be read (damaged)", path, where, "re-download") from None
    if value.dtype.kind not in "iuf" or len(value) != 1:
        raise InputError(
            f"is {shorten(value.tolist())!r}, expected one number (Hz)", path, where, "re-download"
        )
    rate = float(value[0])
    if not np.isfinite(rate) or not 0 < rate <= MAX_RATE_HZ:
        raise InputError(
            f"sampling_rate {rate:g} Hz", path, where, f"must be > 0 and ≤ {MAX_RATE_HZ:g} Hz"
        )
    return rate


def _dataset(path: Path, f: h5py.File, name: str, width: int | None) -> np.ndarray:
    where = f"key /{name}"
    ds = f.get(name)
    if not isinstance(ds, h5py.Dataset):
        raise InputError("missing dataset", path, where, "give a complete BROAD trial")
    ok = len(ds.shape) == 1 if width is None else (len(ds.shape) == 2 and ds.shape[1] == width)
    if not ok:
        want = "(N,)" if width is None else f"(N, {width})"
        raise InputError(f"shape {ds.shape}, expected {want}", path, where, "re-download")
    try:
        kind = ds.dtype.kind
    except (ValueError, TypeError) as exc:  # h5py: a damaged type description
        raise InputError(
            f"its data type cannot be read, the file is damaged ({shorten(exc)})",
            path,
            where,
            "re-download",
        ) from None
    if kind not in "biuf":
        raise InputError(f"holds {ds.dtype}, expected numbers", path, where, "re-download")
    try:
        data = ds[()]
    except (OSError, ValueError) as exc:
        detail = shorten(str(exc).splitlines()[0] if str(exc) else "damaged")
        raise InputError(
            f"cannot be read, the data are damaged ({detail})", path, where, "re-download"
        ) from None
    return data if name == "movement" else np.asarray(data, dtype=float)
